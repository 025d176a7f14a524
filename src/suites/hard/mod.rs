//! The hard-case suite: scenes that break naive ray tracers (cracks between
//! triangles, shadow acne, light leaking at contact, cancellation in small
//! far spheres, undefined maths), and the counts that show whether a backend
//! survives them.
//!
//! `cases` generates the scenes (also written to `scenes/hard/`); `metrics`
//! counts failures against the CPU f64 reference; `run` measures every case on
//! every backend and both `Methods`, for `glint bench hard` and the tests.

mod cases;
pub mod metrics;

use std::fmt::Write as _;
use std::time::{Duration, Instant};

use crate::bvh::Bvh;
use crate::camera::Camera;
use crate::cpu::{self, CpuOptions, Precision};
use crate::features::Features;
use crate::gpu::{GpuRenderOptions, GpuRenderer};
use crate::layout::GpuScene;
use crate::methods::Methods;
use crate::probe::ProbeImage;
use crate::scene::{parse_scene, to_classic_text, Effects, Scene};
use crate::Error;
pub use metrics::{count, Counts, Metric};

/// Where the suite's scene files live, relative to the repository root.
pub const SCENE_DIR: &str = "scenes/hard";

/// One scene of the hard-cases suite and what it checks.
#[derive(Clone, Debug)]
pub struct Case {
    /// The scene's name (its file's stem).
    pub name: String,
    /// One line: what makes it hard.
    pub what: String,
    /// The scene file's text (`scenes/hard/<name>.scene`).
    pub text: String,
    /// As parsed from `text` (so normals are renormalized and warnings
    /// recorded exactly as for the file).
    pub scene: Scene,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// The counts that must be zero with the robust methods.
    pub checks: Vec<Metric>,
}

impl Case {
    /// The classic camera at the case's size.
    pub fn camera(&self) -> Camera {
        Camera::new(self.width, self.height)
    }

    /// The command that prints pixel (x, y)'s path in this case.
    pub fn pixel_command(&self, [x, y]: [u32; 2]) -> String {
        format!(
            "glint render {SCENE_DIR}/{}.scene --width {} --height {} --pixel {x},{y}",
            self.name, self.width, self.height
        )
    }

    /// The ground truth: the CPU reference in f64 with the robust methods.
    pub fn reference(&self) -> ProbeImage {
        let bvh = Bvh::build(&self.scene);
        let options = CpuOptions {
            precision: Precision::F64,
            ..CpuOptions::default()
        };
        cpu::probe(&self.scene, &bvh, &self.camera(), &options)
    }
}

/// Every case, in a fixed order. Every number is rounded to f32 first, so
/// the f32 backends and the f64 reference see the same geometry and the
/// counts measure arithmetic, not the rounding of the input.
pub fn cases() -> Vec<Case> {
    cases::all()
        .into_iter()
        .map(|mut c| {
            c.scene = representable_in_f32(&c.scene);
            c.text = to_classic_text(&c.scene);
            c.scene = parse_scene(c.text.as_bytes(), &format!("{SCENE_DIR}/{}.scene", c.name))
                .expect("generated hard-case scenes parse");
            c
        })
        .collect()
}

fn representable_in_f32(scene: &Scene) -> Scene {
    use glam::DVec3;
    struct F32;
    impl crate::scene::SpaceMap for F32 {
        fn point(&self, p: DVec3, _: DVec3) -> DVec3 {
            p.as_vec3().as_dvec3()
        }
        fn normal(&self, n: DVec3) -> DVec3 {
            n.as_vec3().as_dvec3()
        }
        fn length(&self, r: f64) -> f64 {
            f64::from(r as f32)
        }
    }
    let mut s = scene.mapped(&F32);
    s.ambient = s.ambient.as_vec3().as_dvec3();
    for l in &mut s.lights {
        l.color = l.color.as_vec3().as_dvec3();
    }
    s
}

/// Writes every case's scene file into `dir` (created if missing); returns
/// how many. Each file is written whole to a temporary name, then renamed.
pub fn write_scenes(dir: &std::path::Path) -> Result<usize, Error> {
    let io = |path: &std::path::Path, error: std::io::Error| Error::WriteFile {
        path: path.to_path_buf(),
        error,
    };
    std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
    let cases = cases();
    for c in &cases {
        let path = dir.join(format!("{}.scene", c.name));
        let tmp = dir.join(format!(".{}.scene.tmp", c.name));
        std::fs::write(&tmp, &c.text).map_err(|e| io(&tmp, e))?;
        std::fs::rename(&tmp, &path).map_err(|e| io(&path, e))?;
    }
    Ok(cases.len())
}

/// What rendered a probe image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Runner {
    /// The Vulkan device.
    Gpu,
    /// The CPU reference in f32.
    CpuF32,
}

impl Runner {
    /// How the report names it.
    pub fn name(self) -> &'static str {
        match self {
            Runner::Gpu => "GPU",
            Runner::CpuF32 => "CPU f32",
        }
    }
}

/// The GPU (when there is one), then the CPU f32 reference.
pub fn runners(gpu: Option<&GpuRenderer>) -> Vec<Runner> {
    gpu.map(|_| Runner::Gpu)
        .into_iter()
        .chain([Runner::CpuF32])
        .collect()
}

/// Probes `case` on `runner` with `methods`; also returns the time taken.
pub fn probe(
    case: &Case,
    runner: Runner,
    methods: Methods,
    gpu: Option<&GpuRenderer>,
) -> Result<(ProbeImage, Duration), Error> {
    let bvh = Bvh::build(&case.scene);
    let camera = case.camera();
    let start = Instant::now();
    let image = match runner {
        Runner::Gpu => {
            let gpu =
                gpu.ok_or_else(|| Error::InvalidOption("no GPU for the GPU runner".into()))?;
            let options = GpuRenderOptions {
                methods,
                features: Features::of(&case.scene, &Effects::default()),
                ..Default::default()
            };
            gpu.probe(&GpuScene::pack(&case.scene, &bvh), &camera, &options)?
        }
        Runner::CpuF32 => {
            let options = CpuOptions {
                methods,
                ..CpuOptions::default()
            };
            cpu::probe(&case.scene, &bvh, &camera, &options)
        }
    };
    Ok((image, start.elapsed()))
}

/// One row of the suite's report.
pub struct Row {
    /// The case's name.
    pub case: String,
    /// What rendered it.
    pub runner: Runner,
    /// Robust or naive ray offsets and intersection.
    pub methods: Methods,
    /// How many pixels each metric counted.
    pub counts: Counts,
    /// The metrics that must be zero with the robust methods.
    pub checks: Vec<Metric>,
    /// Per metric with a count, the `--pixel` commands of its first pixels.
    pub examples: Vec<(Metric, Vec<String>)>,
}

impl Row {
    /// The checked counts that are not zero.
    pub fn failures(&self) -> Vec<(Metric, usize)> {
        self.checks
            .iter()
            .map(|&m| (m, self.counts.get(m)))
            .filter(|&(_, n)| n > 0)
            .collect()
    }
}

/// Runs every case on the GPU (when given) and the CPU f32 reference, with
/// each of `methods`; `progress` gets a line per case.
/// `examples`: how many failing pixels per metric each row keeps.
pub fn run(
    gpu: Option<&GpuRenderer>,
    methods: &[Methods],
    examples: usize,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<Row>, Error> {
    let mut rows = Vec::new();
    let runners = runners(gpu);
    for case in cases() {
        let reference = case.reference();
        for &m in methods {
            for &runner in &runners {
                let (image, _) = probe(&case, runner, m, gpu)?;
                let counts = count(&image, &reference);
                let examples = Metric::ALL
                    .iter()
                    .filter(|&&metric| examples > 0 && counts.get(metric) > 0)
                    .map(|&metric| {
                        let mut pixels = metrics::failing_pixels(&image, &reference, metric);
                        pixels.truncate(examples);
                        let commands = pixels.iter().map(|&p| case.pixel_command(p)).collect();
                        (metric, commands)
                    })
                    .collect();
                rows.push(Row {
                    case: case.name.clone(),
                    runner,
                    methods: m,
                    counts,
                    checks: case.checks.clone(),
                    examples,
                });
            }
        }
        progress(&format!("{}: done", case.name));
    }
    Ok(rows)
}

/// A markdown table: one line per case and runner, a column per metric,
/// each cell `robust / naive` (for the methods run). A count the case checks
/// is plain, and bold when not zero; one it does not check is in parentheses.
pub fn to_markdown(rows: &[Row], methods: &[Methods]) -> String {
    let mut out = String::new();
    let names: Vec<&str> = methods.iter().map(|m| m.name()).collect();
    let _ = write!(out, "| case | backend |");
    for metric in Metric::ALL {
        let _ = write!(out, " {metric} |");
    }
    let _ = writeln!(out);
    let _ = write!(out, "|---|---|");
    for _ in Metric::ALL {
        out.push_str("---:|");
    }
    let _ = writeln!(out);
    let mut keys: Vec<(String, Runner)> = Vec::new();
    for r in rows {
        if !keys.contains(&(r.case.clone(), r.runner)) {
            keys.push((r.case.clone(), r.runner));
        }
    }
    for (case, runner) in keys {
        let _ = write!(out, "| {case} | {} |", runner.name());
        for metric in Metric::ALL {
            let cells: Vec<String> = methods
                .iter()
                .map(|&m| {
                    let row = rows
                        .iter()
                        .find(|r| r.case == case && r.runner == runner && r.methods == m);
                    match row {
                        Some(r) => {
                            let n = r.counts.get(metric);
                            if !r.checks.contains(&metric) {
                                format!("({n})")
                            } else if n > 0 {
                                format!("**{n}**")
                            } else {
                                "0".into()
                            }
                        }
                        None => "?".into(),
                    }
                })
                .collect();
            let _ = write!(out, " {} |", cells.join(" / "));
        }
        let _ = writeln!(out);
    }
    let _ = writeln!(out, "\nEach cell: {}.", names.join(" / "));
    out
}
