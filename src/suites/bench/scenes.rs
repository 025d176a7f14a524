//! Render times per scene and backend, as medians (`glint bench`, `cargo
//! bench`), through `render::Renderer` like every render: device creation
//! and pipeline builds happen once and are reported apart; each scene is
//! prepared once (BVH, packed data) and its renders are timed.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use super::common::{base_options, repeat, scene_name, Stat};
use super::process::{end_to_end, Setup, Via};
use crate::bvh::Bvh;
use crate::cpu::Precision;
use crate::gpu::DeviceSelector;
use crate::render::{Backend, RenderOptions, Renderer};
use crate::scene::read_scene;
use crate::timing::{CPU_TIME_NS, GPU_TIME_NS};
use crate::Error;

/// What `glint bench` measures: which scenes, at what size, how often, on
/// which backends.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// The scene files, in order.
    pub scenes: Vec<PathBuf>,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Renders per scene and backend (their median and spread are reported).
    pub repeat: usize,
    /// Render on the Vulkan device.
    pub gpu: bool,
    /// Render on the CPU reference in f32.
    pub cpu_f32: bool,
    /// Render on the CPU reference in f64.
    pub cpu_f64: bool,
    /// Which Vulkan device (`--device`); None: the first.
    pub device: Option<DeviceSelector>,
    /// `GpuRenderOptions::uniform_lists`.
    pub uniform_lists: bool,
    /// The glint binary to time end to end (`glint render SCENE out.jpg`
    /// on each backend, process start to file written); None: no such
    /// column (`cargo bench`, whose own binary is not glint).
    pub end_to_end: Option<PathBuf>,
}

/// One scene's measurements.
#[derive(Clone, Debug)]
pub struct SceneResult {
    /// The scene file's name.
    pub name: String,
    /// Spheres plus triangles.
    pub primitives: usize,
    /// Time to build the BVH.
    pub bvh: Stat,
    /// Per backend ("GPU", "f32", "f64"), the one-off time to put the
    /// scene in the form it renders from (the GPU's packed buffers, the
    /// CPU's primitives in its precision and its wide tree), which the
    /// render times leave out.
    pub pack: Vec<(&'static str, Duration)>,
    /// Rays one render calls for (closest-hit and shadow), as counted by
    /// the last backend that rendered it: the same on every backend,
    /// though the CPU's packets leave some shadow rays untraced
    /// (`timing::UNTRACED_SHADOW_RAYS`), counted here as the others cast
    /// them.
    pub rays: Option<u64>,
    /// Upload + dispatch + readback, per render.
    pub gpu: Option<Stat>,
    /// The device's own time in the dispatches per render (Vulkan
    /// timestamps, `timing::GPU_TIME_NS`), where the queue has them: the
    /// share of `gpu`'s wall clock the device was busy.
    pub gpu_time: Option<Stat>,
    /// Wall time per render on the CPU reference in f32.
    pub cpu_f32: Option<Stat>,
    /// Wall time per render on the CPU reference in f64.
    pub cpu_f64: Option<Stat>,
    /// The CPU renders' thread CPU time (`timing::CPU_TIME_NS`) per
    /// render, where the system reports it: what the wall times above
    /// leave in (time the threads waited for a core, a virtual machine's
    /// stolen time) it leaves out.
    pub cpu_f32_time: Option<Stat>,
    /// As `cpu_f32_time`, for f64.
    pub cpu_f64_time: Option<Stat>,
    /// Per backend ("GPU", "f32", "f64"), `glint render SCENE out.jpg` as
    /// a process, from its start to the file written
    /// (`BenchOptions::end_to_end`).
    pub end_to_end: Vec<(&'static str, Stat)>,
}

/// What `glint bench` measured, and on what.
#[derive(Clone, Debug)]
pub struct BenchReport {
    /// The Vulkan device's name, where the GPU rendered.
    pub device: Option<String>,
    /// Time to create the Vulkan device.
    pub device_creation: Option<Duration>,
    /// Time to build the trace pipeline.
    pub pipeline_build: Option<Duration>,
    /// Threads the CPU reference rendered on.
    pub cpu_threads: usize,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Renders per scene and backend.
    pub repeat: usize,
    /// Per scene, in the order given.
    pub scenes: Vec<SceneResult>,
}

/// Runs the benchmark; `progress` receives one line per finished measurement.
pub fn run(options: &BenchOptions, progress: &mut dyn FnMut(&str)) -> Result<BenchReport, Error> {
    let n = options.repeat.max(1);
    let base = base_options(
        options.width,
        options.height,
        options.device.clone(),
        options.uniform_lists,
    );
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
    let gpu = if options.gpu {
        let start = Instant::now();
        let r = Renderer::new(&RenderOptions {
            backend: Backend::Gpu,
            ..base.clone()
        })?;
        report.device_creation = Some(start.elapsed());
        report.device = Some(r.name());
        Some(r)
    } else {
        None
    };
    let cpu = |precision| {
        Renderer::new(&RenderOptions {
            backend: Backend::Cpu,
            device: None,
            precision,
            ..base.clone()
        })
    };
    let cpu_f32 = options.cpu_f32.then(|| cpu(Precision::F32)).transpose()?;
    let cpu_f64 = options.cpu_f64.then(|| cpu(Precision::F64)).transpose()?;
    let mut pipelines = Duration::ZERO;
    // Where the end-to-end runs write their JPEG, made only for them.
    let dir = options
        .end_to_end
        .as_ref()
        .map(|_| tempfile::tempdir())
        .transpose()
        .map_err(|e| Error::WriteFile {
            path: std::env::temp_dir(),
            error: e,
        })?;
    let setup = options
        .end_to_end
        .as_deref()
        .zip(dir.as_ref())
        .map(|(glint, dir)| Setup {
            glint,
            width: options.width,
            height: options.height,
            device: options.device.as_ref(),
            uniform_lists: options.uniform_lists,
            dir: dir.path(),
        });
    for path in &options.scenes {
        let scene = read_scene(path)?;
        let name = scene_name(path);
        let bvh_stat = repeat(n, || {
            Bvh::build(&scene);
            Ok(())
        })?
        .expect("n >= 1");
        let mut result = SceneResult {
            name: name.clone(),
            primitives: scene.primitive_count(),
            bvh: bvh_stat,
            pack: Vec::new(),
            gpu: None,
            gpu_time: None,
            cpu_f32: None,
            cpu_f64: None,
            cpu_f32_time: None,
            cpu_f64_time: None,
            rays: None,
            end_to_end: Vec::new(),
        };
        if let Some(r) = &gpu {
            pipelines += r.prepare_pipeline(&scene)?;
            let ready = r.prepare_scene(&scene);
            result
                .pack
                .extend(ready.timings.phase("pack").map(|d| ("GPU", d)));
            // One untimed render first: drivers compile lazily on first use.
            let first = r.render_prepared_scene(&scene, &ready, &|_, _| {})?;
            result.rays = first.timings.rays_called_for().or(result.rays);
            let mut times = Vec::with_capacity(n);
            result.gpu = repeat(n, || {
                let out = r.render_prepared_scene(&scene, &ready, &|_, _| {})?;
                if out.timings.has_count(GPU_TIME_NS) {
                    times.push(Duration::from_nanos(out.timings.counted(GPU_TIME_NS)));
                }
                Ok(())
            })?;
            result.gpu_time = (times.len() == n).then(|| Stat::of(times)).flatten();
            progress(&format!("{name}: gpu {:.1} ms", ms(result.gpu)));
        }
        for (renderer, slot, time_slot, label) in [
            (
                cpu_f32.as_ref(),
                &mut result.cpu_f32,
                &mut result.cpu_f32_time,
                "f32",
            ),
            (
                cpu_f64.as_ref(),
                &mut result.cpu_f64,
                &mut result.cpu_f64_time,
                "f64",
            ),
        ] {
            if let Some(r) = renderer {
                let ready = r.prepare_scene(&scene);
                result
                    .pack
                    .extend(ready.timings.phase("pack").map(|d| (label, d)));
                let mut rays = None;
                let mut times = Vec::with_capacity(n);
                *slot = repeat(n, || {
                    let out = r.render_prepared_scene(&scene, &ready, &|_, _| {})?;
                    rays = out.timings.rays_called_for();
                    if out.timings.has_count(CPU_TIME_NS) {
                        times.push(Duration::from_nanos(out.timings.counted(CPU_TIME_NS)));
                    }
                    Ok(())
                })?;
                result.rays = rays.or(result.rays);
                // All or nothing: a median of some renders would mislead.
                *time_slot = (times.len() == n).then(|| Stat::of(times)).flatten();
                progress(&format!("{name}: {} {:.1} ms", r.name(), ms(*slot)));
            }
        }
        if let Some(setup) = &setup {
            let on = [gpu.is_some(), cpu_f32.is_some(), cpu_f64.is_some()];
            result.end_to_end = time_end_to_end(setup, path, on, n, progress)?;
        }
        report.scenes.push(result);
    }
    if gpu.is_some() {
        report.pipeline_build = Some(pipelines);
    }
    Ok(report)
}

/// `scene` rendered by glint as a process on each backend `on` says (GPU,
/// f32, f64), `n` times after one untimed run; each backend's median.
fn time_end_to_end(
    setup: &Setup,
    scene: &std::path::Path,
    on: [bool; 3],
    n: usize,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<(&'static str, Stat)>, Error> {
    let mut times = Vec::new();
    for (on, via) in on.into_iter().zip([Via::Gpu, Via::CpuF32, Via::CpuF64]) {
        if on {
            let t = end_to_end(setup, scene, via, n)?;
            let name = scene_name(scene);
            progress(&format!(
                "{name}: {} end to end {:.1} ms",
                via.label(),
                ms(Some(t))
            ));
            times.push((via.label(), t));
        }
    }
    Ok(times)
}

/// The end-to-end medians as `pack`'s cells take them.
fn end_to_end_ms(times: &[(&'static str, Stat)]) -> Vec<(&'static str, Duration)> {
    times.iter().map(|(l, t)| (*l, t.median)).collect()
}

fn ms(s: Option<Stat>) -> f64 {
    s.map_or(f64::NAN, |s| s.median.as_secs_f64() * 1e3)
}

impl BenchReport {
    /// Render time against primitive count, log-log, one line per backend
    /// (`glint bench --plot`): how each one's cost grows with the scene.
    #[cfg(feature = "plots")]
    pub fn plot(&self) -> crate::suites::plot::LogLog {
        type Column = fn(&SceneResult) -> Option<Stat>;
        let columns: [(&str, Column); 3] = [
            ("GPU", |s| s.gpu),
            ("CPU f32", |s| s.cpu_f32),
            ("CPU f64", |s| s.cpu_f64),
        ];
        let series: Vec<(String, Vec<[f64; 2]>)> = columns
            .iter()
            .map(|(name, column)| {
                let mut points: Vec<[f64; 2]> = self
                    .scenes
                    .iter()
                    .filter_map(|s| column(s).map(|t| [s.primitives as f64, ms(Some(t))]))
                    .collect();
                points.sort_by(|a, b| a[0].total_cmp(&b[0]));
                (name.to_string(), points)
            })
            .collect();
        let title = format!(
            "render time against primitives, {}x{}, median of {}",
            self.width, self.height, self.repeat
        );
        crate::suites::plot::log_log(&title, "primitives", "render time (ms)", &series)
    }

    /// A Markdown table of medians (min-max in brackets), in milliseconds,
    /// with the rays per second each median gives.
    pub fn to_markdown(&self) -> String {
        let mut out = String::new();
        let cell = |s: Option<Stat>| s.map_or_else(|| "-".into(), |s| s.to_string());
        let pack = |p: &[(&str, Duration)]| {
            let cells: Vec<String> = p
                .iter()
                .map(|(label, d)| format!("{label} {:.1}", d.as_secs_f64() * 1e3))
                .collect();
            if cells.is_empty() {
                "-".into()
            } else {
                cells.join(" · ")
            }
        };
        let timed = |s: Option<Stat>, rays: Option<u64>| match (s, rays) {
            (Some(s), Some(r)) => format!(
                "{s} · {:.2} Mray/s",
                r as f64 / s.median.as_secs_f64().max(1e-9) / 1e6
            ),
            _ => cell(s),
        };
        // The GPU column's wall time, then the device's and their ratio.
        let gpu_cell = |s: Option<Stat>, time: Option<Stat>, rays: Option<u64>| match (s, time) {
            (Some(wall), Some(t)) => format!(
                "{} · GPU {:.2} ms, wall {:.1}x",
                timed(s, rays),
                t.median.as_secs_f64() * 1e3,
                wall.median.as_secs_f64() / t.median.as_secs_f64().max(1e-12)
            ),
            _ => timed(s, rays),
        };
        // The CPU column's wall time, then its threads' CPU time.
        let cpu_cell = |s: Option<Stat>, time: Option<Stat>, rays: Option<u64>| match time {
            Some(t) => format!(
                "{} · CPU {:.1} ms",
                timed(s, rays),
                t.median.as_secs_f64() * 1e3
            ),
            None => timed(s, rays),
        };
        let _ = writeln!(
            out,
            "{}x{}, median of {} runs (min-max), milliseconds; CPU reference on {} threads",
            self.width, self.height, self.repeat, self.cpu_threads
        );
        if let Some(device) = &self.device {
            let _ = writeln!(
                out,
                "{device}; device creation {:.1} ms, pipeline builds {:.1} ms (each feature set once); \
                 GPU renders as for an 8-bit file (pixels packed on the device), with the \
                 device's time in the dispatches and the wall clock's multiple of it",
                self.device_creation.unwrap_or_default().as_secs_f64() * 1e3,
                self.pipeline_build.unwrap_or_default().as_secs_f64() * 1e3
            );
        }
        if self.scenes.iter().any(|s| !s.end_to_end.is_empty()) {
            let _ = writeln!(
                out,
                "end to end: `glint render SCENE out.jpg` as a process on each backend, from its \
                 start to the file written (scene read, device, cached pipeline, upload, render, \
                 encode, write), median after one untimed run"
            );
        }
        let _ = writeln!(out);
        let _ = writeln!(
            out,
            "| scene | primitives | rays | BVH build | pack, once | GPU render | CPU f32 | CPU f64 | end to end, .jpg |"
        );
        let _ = writeln!(out, "|---|---:|---:|---:|---:|---:|---:|---:|---:|");
        for s in &self.scenes {
            let _ = writeln!(
                out,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                s.name,
                s.primitives,
                s.rays.map_or_else(|| "-".into(), |r| r.to_string()),
                cell(Some(s.bvh)),
                pack(&s.pack),
                gpu_cell(s.gpu, s.gpu_time, s.rays),
                cpu_cell(s.cpu_f32, s.cpu_f32_time, s.rays),
                cpu_cell(s.cpu_f64, s.cpu_f64_time, s.rays),
                pack(&end_to_end_ms(&s.end_to_end))
            );
        }
        out
    }
}
