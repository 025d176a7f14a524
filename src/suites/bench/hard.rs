//! The hard-case suite as a benchmark (`glint bench hard`): failure counts
//! per case, backend and methods, and what the robust methods cost. It gets
//! its device from a `render::Renderer` and drives that renderer's
//! `GpuRenderer` directly: probe kernels and per-methods pipelines sit below
//! a render.

use std::fmt::Write as _;
use std::time::Instant;

use super::common::{Stat, CLASSIC_DIR};
use crate::bvh::Bvh;
use crate::camera::Camera;
use crate::cpu::{self, CpuOptions};
use crate::features::Features;
use crate::gpu::{DeviceSelector, GpuRenderOptions};
use crate::layout::GpuScene;
use crate::methods::Methods;
use crate::render::{Backend, RenderOptions, Renderer};
use crate::scene::{read_scene, Effects};
use crate::Error;

/// What `glint bench hard` runs.
#[derive(Clone, Debug)]
pub struct HardOptions {
    /// Render on the Vulkan device too.
    pub gpu: bool,
    /// Which Vulkan device (`--device`); None: the first.
    pub device: Option<DeviceSelector>,
    /// Renders per timing (median).
    pub repeat: usize,
    /// Also time robust vs naive methods.
    pub timing: bool,
    /// Failing pixels to list per case, backend and metric (robust methods).
    pub examples: usize,
}

/// What `glint bench hard` found.
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
    use crate::suites::hard;
    let mut out = String::new();
    let device = if options.gpu {
        let r = Renderer::new(&RenderOptions {
            backend: Backend::Gpu,
            device: options.device.clone(),
            ..RenderOptions::default()
        })?;
        let _ = writeln!(out, "{}", r.name());
        Some(r)
    } else {
        None
    };
    let renderer = device.as_ref().and_then(Renderer::gpu);
    let _ = writeln!(
        out,
        "CPU reference: {} threads. Counts are pixels, against the CPU f64 reference with \
         robust methods; `-`: not checked for that case.\n",
        rayon::current_num_threads()
    );
    let rows = hard::run(renderer, &Methods::ALL, options.examples, progress)?;
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
            for runner in hard::runners(renderer) {
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
