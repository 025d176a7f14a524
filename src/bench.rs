//! Render-time benchmarks: each scene on each backend, repeated, reported as
//! medians (`glint bench`, `cargo bench`). Device creation and pipeline build
//! happen once and are reported apart from the per-scene render times.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use crate::bvh::Bvh;
use crate::camera::Camera;
use crate::cpu::{self, CpuOptions, Precision};
use crate::gpu::{
    Context, ContextOptions, DeviceSelector, GpuError, GpuRenderOptions, GpuRenderer, Kernel,
};
use crate::info::Features;
use crate::layout::GpuScene;
use crate::methods::Methods;
use crate::scene::{read_scene, Effects};
use crate::Error;

#[derive(Clone, Debug)]
pub struct BenchOptions {
    pub scenes: Vec<PathBuf>,
    pub width: u32,
    pub height: u32,
    pub repeat: usize,
    pub gpu: bool,
    pub cpu_f32: bool,
    pub cpu_f64: bool,
    pub device: Option<DeviceSelector>,
}

/// Median and spread of repeated timings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stat {
    pub median: Duration,
    pub min: Duration,
    pub max: Duration,
}

/// "median (min-max)" in milliseconds.
impl std::fmt::Display for Stat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        write!(
            f,
            "{:.1} ({:.1}-{:.1})",
            ms(self.median),
            ms(self.min),
            ms(self.max)
        )
    }
}

impl Stat {
    pub fn of(mut samples: Vec<Duration>) -> Option<Stat> {
        if samples.is_empty() {
            return None;
        }
        samples.sort();
        let n = samples.len();
        let median = if n % 2 == 1 {
            samples[n / 2]
        } else {
            (samples[n / 2 - 1] + samples[n / 2]) / 2
        };
        Some(Stat {
            median,
            min: samples[0],
            max: samples[n - 1],
        })
    }
}

#[derive(Clone, Debug)]
pub struct SceneResult {
    pub name: String,
    pub primitives: usize,
    pub bvh: Stat,
    /// Upload + dispatch + readback, per render.
    pub gpu: Option<Stat>,
    pub cpu_f32: Option<Stat>,
    pub cpu_f64: Option<Stat>,
}

#[derive(Clone, Debug)]
pub struct BenchReport {
    pub device: Option<String>,
    pub device_creation: Option<Duration>,
    pub pipeline_build: Option<Duration>,
    pub cpu_threads: usize,
    pub width: u32,
    pub height: u32,
    pub repeat: usize,
    pub scenes: Vec<SceneResult>,
}

/// Where the course's classic scenes live, relative to the repository root.
pub const CLASSIC_DIR: &str = "../shared/scenes/classic";
pub const CLASSIC_SCENES: [&str; 5] = ["test1", "test2", "spheres", "table", "SIGGRAPH"];

/// The default scene set, relative to the repository root: the classic scenes
/// (when `CLASSIC_DIR` exists; otherwise `note` is told) and every `*.scene`
/// directly in `scenes/`, sorted.
pub fn default_scenes(note: &mut dyn FnMut(&str)) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let classic = std::path::Path::new(CLASSIC_DIR);
    if classic.is_dir() {
        out.extend(
            CLASSIC_SCENES
                .iter()
                .map(|n| classic.join(format!("{n}.scene"))),
        );
    } else {
        note(&format!("{CLASSIC_DIR} not found: classic scenes skipped"));
    }
    out.extend(scene_files("scenes"));
    out
}

/// The `*.scene` files directly in `dir`, sorted; none if it is missing.
fn scene_files(dir: &str) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "scene"))
        .collect();
    files.sort();
    files
}

fn repeat(n: usize, mut f: impl FnMut() -> Result<(), Error>) -> Result<Option<Stat>, Error> {
    let mut samples = Vec::with_capacity(n);
    for _ in 0..n {
        let start = Instant::now();
        f()?;
        samples.push(start.elapsed());
    }
    Ok(Stat::of(samples))
}

/// Runs the benchmark; `progress` receives one line per finished measurement.
pub fn run(options: &BenchOptions, progress: &mut dyn FnMut(&str)) -> Result<BenchReport, Error> {
    let camera = Camera::new(options.width, options.height);
    let bg = [1.0; 3];
    let n = options.repeat.max(1);
    let mut gpu = None;
    let mut report = BenchReport {
        device: None,
        device_creation: None,
        pipeline_build: None,
        cpu_threads: rayon::current_num_threads(),
        width: options.width,
        height: options.height,
        repeat: n,
        scenes: Vec::new(),
    };
    if options.gpu {
        let start = Instant::now();
        let ctx = Context::new(&ContextOptions {
            device: options.device.clone(),
            validation: false,
        })?;
        report.device_creation = Some(start.elapsed());
        let renderer = GpuRenderer::new(&ctx)?;
        let plain = GpuRenderOptions {
            features: Features {
                spheres: true,
                triangles: true,
                ..Features::default()
            },
            ..GpuRenderOptions::default()
        };
        report.pipeline_build = Some(renderer.prepare(&plain, Kernel::Render)?);
        report.device = Some(format!("{} ({})", ctx.info().name, ctx.info().driver));
        gpu = Some(renderer);
    }
    for path in &options.scenes {
        let scene = read_scene(path)?;
        let name = path.file_stem().map_or_else(
            || path.display().to_string(),
            |s| s.to_string_lossy().into_owned(),
        );
        let mut bvh = Bvh::default();
        let bvh_stat = repeat(n, || {
            bvh = Bvh::build(&scene);
            Ok(())
        })?
        .expect("n >= 1");
        let mut result = SceneResult {
            name: name.clone(),
            primitives: scene.primitive_count(),
            bvh: bvh_stat,
            gpu: None,
            cpu_f32: None,
            cpu_f64: None,
        };
        if let Some(renderer) = &gpu {
            let packed = GpuScene::pack(&scene, &bvh);
            let effects = Effects::resolve(&scene.settings);
            let opts = GpuRenderOptions {
                effects,
                features: Features::of(&scene, &effects),
                ..GpuRenderOptions::default()
            };
            // One untimed render first: drivers compile lazily on first use.
            renderer.render(&packed, &camera, bg, &opts, &|_, _| {})?;
            result.gpu = repeat(n, || {
                renderer.render(&packed, &camera, bg, &opts, &|_, _| {})?;
                Ok(())
            })?;
            progress(&format!("{name}: gpu {:.1} ms", ms(result.gpu)));
        }
        for (enabled, precision, slot) in [
            (options.cpu_f32, Precision::F32, &mut result.cpu_f32),
            (options.cpu_f64, Precision::F64, &mut result.cpu_f64),
        ] {
            if enabled {
                *slot = repeat(n, || {
                    let o = CpuOptions {
                        background: bg,
                        precision,
                        effects: Effects::resolve(&scene.settings),
                        ..CpuOptions::default()
                    };
                    cpu::render(&scene, &bvh, &camera, &o, &|_, _| {});
                    Ok(())
                })?;
                progress(&format!("{name}: cpu {precision:?} {:.1} ms", ms(*slot)));
            }
        }
        report.scenes.push(result);
    }
    Ok(report)
}

fn ms(s: Option<Stat>) -> f64 {
    s.map_or(f64::NAN, |s| s.median.as_secs_f64() * 1e3)
}

impl BenchReport {
    /// A Markdown table of medians (min-max in brackets), in milliseconds.
    pub fn to_markdown(&self) -> String {
        let mut out = String::new();
        let cell = |s: Option<Stat>| s.map_or_else(|| "-".into(), |s| s.to_string());
        let _ = writeln!(
            out,
            "{}x{}, median of {} runs (min-max), milliseconds; CPU reference on {} threads",
            self.width, self.height, self.repeat, self.cpu_threads
        );
        if let Some(device) = &self.device {
            let _ = writeln!(
                out,
                "GPU: {device}; device creation {:.1} ms, pipeline build {:.1} ms (once)",
                self.device_creation.unwrap_or_default().as_secs_f64() * 1e3,
                self.pipeline_build.unwrap_or_default().as_secs_f64() * 1e3
            );
        }
        let _ = writeln!(out);
        let _ = writeln!(
            out,
            "| scene | primitives | BVH build | GPU render | CPU f32 | CPU f64 |"
        );
        let _ = writeln!(out, "|---|---:|---:|---:|---:|---:|");
        for s in &self.scenes {
            let _ = writeln!(
                out,
                "| {} | {} | {} | {} | {} | {} |",
                s.name,
                s.primitives,
                cell(Some(s.bvh)),
                cell(s.gpu),
                cell(s.cpu_f32),
                cell(s.cpu_f64)
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_and_even_counts() {
        let d = Duration::from_millis;
        assert_eq!(Stat::of(vec![d(3), d(1), d(2)]).unwrap().median, d(2));
        assert_eq!(
            Stat::of(vec![d(4), d(1), d(2), d(3)]).unwrap().median,
            Duration::from_micros(2500)
        );
        assert!(Stat::of(vec![]).is_none());
    }
}

#[derive(Clone, Debug)]
pub struct HardOptions {
    pub gpu: bool,
    pub device: Option<DeviceSelector>,
    /// Renders per timing (median).
    pub repeat: usize,
    /// Also time robust vs naive methods.
    pub timing: bool,
    /// Failing pixels to list per case, backend and metric (robust methods).
    pub examples: usize,
}

pub struct HardReport {
    /// Counts table, then (with timing) the cost table, in markdown.
    pub markdown: String,
    /// Checked counts that are not zero with the robust methods.
    pub robust_failures: usize,
}

/// The hard-case suite (`glint bench hard`): failure counts for every case on
/// every backend with robust and naive methods, and the render time of each
/// methods variant on SIGGRAPH (when the classic scenes are present) and on
/// the `quad_grid` hard case.
pub fn run_hard(
    options: &HardOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<HardReport, Error> {
    use crate::hard;
    let mut out = String::new();
    let renderer = if options.gpu {
        let ctx = Context::new(&ContextOptions {
            device: options.device.clone(),
            validation: false,
        })?;
        let _ = writeln!(out, "GPU: {} ({})", ctx.info().name, ctx.info().driver);
        Some(GpuRenderer::new(&ctx)?)
    } else {
        None
    };
    let _ = writeln!(
        out,
        "CPU reference: {} threads. Counts are pixels, against the CPU f64 reference with \
         robust methods; `-`: not checked for that case.\n",
        rayon::current_num_threads()
    );
    let rows = hard::run(renderer.as_ref(), &Methods::ALL, options.examples, progress)?;
    let robust_failures = rows
        .iter()
        .filter(|r| r.methods == Methods::Robust)
        .map(|r| r.failures().len())
        .sum();
    out.push_str(&hard::to_markdown(&rows, &Methods::ALL));
    let robust_examples: Vec<&hard::Row> = rows
        .iter()
        .filter(|r| r.methods == Methods::Robust && !r.examples.is_empty())
        .collect();
    if !robust_examples.is_empty() {
        let _ = writeln!(
            out,
            "\nFirst pixels behind each robust count (write the scenes first: \
             `glint bench hard --write-scenes`):\n"
        );
        for r in robust_examples {
            for (metric, commands) in &r.examples {
                let _ = writeln!(out, "- {} on {}, {metric}:", r.case, r.runner.name());
                for c in commands {
                    let _ = writeln!(out, "  - `{c}`");
                }
            }
        }
    }
    if options.timing {
        let mut subjects: Vec<(String, crate::scene::Scene, Camera)> = Vec::new();
        let classic = std::path::Path::new(CLASSIC_DIR).join("SIGGRAPH.scene");
        if classic.is_file() {
            subjects.push((
                "SIGGRAPH".into(),
                read_scene(&classic)?,
                Camera::new(640, 480),
            ));
        } else {
            progress(&format!("{CLASSIC_DIR} not found: SIGGRAPH timing skipped"));
        }
        if let Some(case) = hard::cases().into_iter().find(|c| c.name == "quad_grid") {
            let camera = case.camera();
            subjects.push((case.name, case.scene, camera));
        }
        let _ = writeln!(
            out,
            "\nRender time, median of {} (min-max), milliseconds:\n",
            options.repeat
        );
        let _ = writeln!(out, "| scene | backend | robust | naive | robust / naive |");
        let _ = writeln!(out, "|---|---|---:|---:|---:|");
        for (name, scene, camera) in &subjects {
            let bvh = Bvh::build(scene);
            let packed = GpuScene::pack(scene, &bvh);
            let bg = [1.0; 3];
            for runner in hard::runners(renderer.as_ref()) {
                // Interleaved so that drift (thermal, other load) hits both alike.
                let mut samples = [Vec::new(), Vec::new()];
                for i in 0..=options.repeat {
                    for (k, &methods) in Methods::ALL.iter().enumerate() {
                        let start = Instant::now();
                        match (runner, &renderer) {
                            (hard::Runner::Gpu, Some(r)) => {
                                let opts = GpuRenderOptions {
                                    methods,
                                    features: Features::of(scene, &Effects::default()),
                                    ..Default::default()
                                };
                                r.render(&packed, camera, bg, &opts, &|_, _| {})?;
                            }
                            _ => {
                                let o = CpuOptions {
                                    background: bg,
                                    methods,
                                    ..CpuOptions::default()
                                };
                                cpu::render(scene, &bvh, camera, &o, &|_, _| {});
                            }
                        }
                        // The first round warms caches and lazy compiles.
                        if i > 0 {
                            samples[k].push(start.elapsed());
                        }
                    }
                }
                let [robust, naive] = samples.map(|s| Stat::of(s).expect("repeat >= 1"));
                let ratio = robust.median.as_secs_f64() / naive.median.as_secs_f64();
                let _ = writeln!(
                    out,
                    "| {name} ({}x{}) | {} | {robust} | {naive} | {ratio:.2} |",
                    camera.width,
                    camera.height,
                    runner.name()
                );
                progress(&format!("{name}: {} timed", runner.name()));
            }
        }
    }
    Ok(HardReport {
        markdown: out,
        robust_failures,
    })
}

/// `glint bench specialize`: per scene, the shader specialised for its
/// feature set against the generic one (every effect compiled in, switched
/// by the settings), in SPIR-V size, pipeline build time and render time.
pub struct SpecializeOptions {
    pub scenes: Vec<PathBuf>,
    pub width: u32,
    pub height: u32,
    pub repeat: usize,
    pub device: Option<DeviceSelector>,
}

/// The default subjects: the classic scenes (when present), the showcase,
/// and every effect scene.
pub fn specialize_scenes(note: &mut dyn FnMut(&str)) -> Vec<PathBuf> {
    let mut out = default_scenes(note);
    out.extend(scene_files("scenes/effects"));
    out
}

pub fn run_specialize(
    options: &SpecializeOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<String, Error> {
    use crate::gpu::shader;
    let ctx = Context::new(&ContextOptions {
        device: options.device.clone(),
        validation: false,
    })?;
    let renderer = GpuRenderer::new(&ctx)?;
    let camera = Camera::new(options.width, options.height);
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Device: {} ({}). {}x{}; build: median of 3 uncached pipeline builds \
         (naga specialisation + SPIR-V + driver compile); render: median of {} \
         renders, specialised and generic interleaved, after one warm-up each.\n",
        ctx.info().name,
        ctx.info().driver,
        options.width,
        options.height,
        options.repeat
    );
    let _ = writeln!(
        out,
        "| scene | feature set | SPIR-V words spec. / generic | build spec. | build generic | render spec. | render generic | generic / spec. |"
    );
    let _ = writeln!(out, "|---|---|---:|---:|---:|---:|---:|---:|");
    let generic_words = shader::spirv(Methods::Robust, Features::ALL, Default::default())
        .map_err(GpuError::from)?
        .len();
    for path in &options.scenes {
        let scene = read_scene(path)?;
        let name = path.file_stem().map_or_else(
            || path.display().to_string(),
            |s| s.to_string_lossy().into_owned(),
        );
        let effects = Effects::resolve(&scene.settings);
        let features = Features::of(&scene, &effects);
        let packed = GpuScene::pack(&scene, &Bvh::for_render(&scene, &effects));
        let variants = [features, Features::ALL].map(|features| GpuRenderOptions {
            effects,
            features,
            ..GpuRenderOptions::default()
        });
        let mut builds = [Vec::new(), Vec::new()];
        for _ in 0..3 {
            for (k, v) in variants.iter().enumerate() {
                builds[k].push(renderer.measure_build(v, Kernel::Render)?);
            }
        }
        let mut renders = [Vec::new(), Vec::new()];
        for i in 0..=options.repeat.max(1) {
            for (k, v) in variants.iter().enumerate() {
                let start = Instant::now();
                renderer.render(&packed, &camera, [1.0; 3], v, &|_, _| {})?;
                if i > 0 {
                    renders[k].push(start.elapsed());
                }
            }
        }
        let [bs, bg] = builds.map(|b| Stat::of(b).expect("3 builds").median);
        let [rs, rg] = renders.map(|r| Stat::of(r).expect("repeat >= 1").median);
        let words = shader::spirv(Methods::Robust, features, Default::default())
            .map_err(GpuError::from)?
            .len();
        let line = format!(
            "| {name} | {} | {words} / {generic_words} | {:.1} ms | {:.1} ms | {:.1} ms | {:.1} ms | {:.2} |",
            features.label(),
            ms(bs),
            ms(bg),
            ms(rs),
            ms(rg),
            rg.as_secs_f64() / rs.as_secs_f64()
        );
        progress(&line);
        let _ = writeln!(out, "{line}");
    }
    Ok(out)
}
