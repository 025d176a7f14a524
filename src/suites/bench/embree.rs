//! glint against an Embree renderer of the same spec (`glint bench
//! embree`): per scene, rounds of glint's CPU reference, glint's GPU, and the
//! harness's single rays and eight-wide packets, one program after the
//! other, so each ratio compares programs measured seconds apart on the same
//! machine and threads. The harness is a separate program, not part of glint
//! (`../shared/tools/embree_bench.cpp` builds one); glint runs it with
//! `SCENE --width W --height H --threads T --runs R --mode single|packet8`
//! and reads the last line of its output that starts with `RESULT`, whose
//! `render_med_s=` and `rays=` fields give its median render and rays cast.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use super::common::{base_options, repeat, scene_name, Stat};
use crate::cpu::Precision;
use crate::gpu::DeviceSelector;
use crate::render::{Backend, RenderOptions, Renderer};
use crate::scene::read_scene;
use crate::Error;

/// What `glint bench embree` measures: glint against the Embree harness.
#[derive(Clone, Debug)]
pub struct EmbreeOptions {
    /// The harness program.
    pub harness: PathBuf,
    /// The scene files, in order.
    pub scenes: Vec<PathBuf>,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Renders per measurement (glint's, and the harness's `--runs`).
    pub repeat: usize,
    /// Rounds of all four programs per scene.
    pub rounds: usize,
    /// Render glint on the Vulkan device.
    pub gpu: bool,
    /// Render glint on the CPU reference (f32).
    pub cpu: bool,
    /// Which Vulkan device (`--device`); None: the first.
    pub device: Option<DeviceSelector>,
    /// `GpuRenderOptions::uniform_lists`.
    pub uniform_lists: bool,
}

/// The harness's two traversal modes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// One ray at a time (`rtcIntersect1`, `rtcOccluded1`).
    Single,
    /// Eight rays at a time (`rtcIntersect8`, `rtcOccluded8`).
    Packet8,
}

impl Mode {
    fn arg(self) -> &'static str {
        match self {
            Mode::Single => "single",
            Mode::Packet8 => "packet8",
        }
    }
}

/// What one harness run reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HarnessRun {
    /// Median render time.
    pub median: Duration,
    /// Rays one render casts (primary and shadow).
    pub rays: Option<u64>,
}

/// The last `RESULT` line of a harness's output, if it has a
/// `render_med_s=` field that is a time.
pub fn parse_result(stdout: &str) -> Option<HarnessRun> {
    let line = stdout.lines().rev().find(|l| l.starts_with("RESULT "))?;
    let field = |key: &str| {
        line.split_whitespace()
            .find_map(|kv| kv.strip_prefix(key)?.strip_prefix('='))
    };
    let seconds: f64 = field("render_med_s")?.parse().ok()?;
    let median = Duration::try_from_secs_f64(seconds).ok()?;
    let rays = field("rays").and_then(|r| r.parse().ok());
    Some(HarnessRun { median, rays })
}

/// Runs the harness once on `scene`.
pub fn run_harness(
    options: &EmbreeOptions,
    scene: &Path,
    mode: Mode,
    threads: usize,
) -> Result<HarnessRun, Error> {
    let fail = |reason: String| Error::Harness {
        harness: options.harness.clone(),
        scene: scene.to_path_buf(),
        reason,
    };
    let output = Command::new(&options.harness)
        .arg(scene)
        .args(["--width", &options.width.to_string()])
        .args(["--height", &options.height.to_string()])
        .args(["--threads", &threads.to_string()])
        .args(["--runs", &options.repeat.max(1).to_string()])
        .args(["--mode", mode.arg()])
        .output()
        .map_err(|e| fail(format!("cannot run it: {e}")))?;
    let stdout = String::from_utf8_lossy(&output.stdout);
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr);
        return Err(fail(format!(
            "{} ({})",
            output.status,
            last_lines(&stderr, 3).as_deref().unwrap_or("no message")
        )));
    }
    parse_result(&stdout).ok_or_else(|| {
        fail(format!(
            "no `RESULT ... render_med_s=SECONDS` line in its output (it ended: {})",
            last_lines(&stdout, 2).as_deref().unwrap_or("nothing")
        ))
    })
}

/// The last `n` lines of `text` (trailing blank ones dropped), joined by
/// " / " to fit an error message's line.
fn last_lines(text: &str, n: usize) -> Option<String> {
    let lines: Vec<&str> = text.trim_end().lines().collect();
    if lines.iter().all(|l| l.trim().is_empty()) {
        return None;
    }
    Some(lines[lines.len().saturating_sub(n)..].join(" / "))
}

/// One scene's medians, one per round.
#[derive(Clone, Debug, Default)]
pub struct EmbreeScene {
    /// The scene file's name.
    pub name: String,
    /// Rays one render calls for, glint's count: those it casts and the
    /// shadow rays it leaves untraced (`untraced`).
    pub rays: Option<u64>,
    /// Of `rays`, the shadow rays glint's CPU reference left untraced:
    /// their answer could not change a pixel.
    pub untraced: Option<u64>,
    /// Rays one render casts, as the harness counts them.
    pub harness_rays: Option<u64>,
    /// Per round, glint's CPU reference.
    pub cpu: Vec<Duration>,
    /// Per round, glint on the Vulkan device.
    pub gpu: Vec<Duration>,
    /// Per round, the harness with single rays.
    pub single: Vec<Duration>,
    /// Per round, the harness with 8-ray packets.
    pub packet8: Vec<Duration>,
}

impl EmbreeScene {
    /// How far the harness's ray count is from glint's, as a fraction of
    /// glint's, when it is more than 0.1%: then the two did not render the
    /// same work and their ratio compares different renders.
    pub fn rays_differ(&self) -> Option<f64> {
        let (Some(ours), Some(theirs)) = (self.rays, self.harness_rays) else {
            return None;
        };
        let off = (theirs as f64 - ours as f64).abs() / (ours as f64).max(1.0);
        (off > 1e-3).then_some(off)
    }
}

/// What `glint bench embree` measured, and on what.
#[derive(Clone, Debug)]
pub struct EmbreeReport {
    /// The harness program.
    pub harness: PathBuf,
    /// The Vulkan device's name, where glint rendered on it.
    pub device: Option<String>,
    /// Threads both renderers used.
    pub threads: usize,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Renders per measurement.
    pub repeat: usize,
    /// Rounds of all programs per scene.
    pub rounds: usize,
    /// Per scene, in the order given.
    pub scenes: Vec<EmbreeScene>,
}

/// Runs the comparison; `progress` receives a line per finished round.
pub fn run_embree(
    options: &EmbreeOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<EmbreeReport, Error> {
    let n = options.repeat.max(1);
    let threads = rayon::current_num_threads();
    let base = base_options(
        options.width,
        options.height,
        options.device.clone(),
        options.uniform_lists,
    );
    let gpu = options
        .gpu
        .then(|| {
            Renderer::new(&RenderOptions {
                backend: Backend::Gpu,
                ..base.clone()
            })
        })
        .transpose()?;
    let cpu = options
        .cpu
        .then(|| {
            Renderer::new(&RenderOptions {
                backend: Backend::Cpu,
                device: None,
                precision: Precision::F32,
                ..base.clone()
            })
        })
        .transpose()?;
    let mut report = EmbreeReport {
        harness: options.harness.clone(),
        device: gpu.as_ref().map(Renderer::name),
        threads,
        width: options.width,
        height: options.height,
        repeat: n,
        rounds: options.rounds.max(1),
        scenes: Vec::new(),
    };
    for path in &options.scenes {
        let scene = read_scene(path)?;
        let mut result = EmbreeScene {
            name: scene_name(path),
            ..EmbreeScene::default()
        };
        let cpu_ready = match &cpu {
            Some(r) => {
                let ready = r.prepare_scene(&scene);
                // Untimed, as the GPU's: the first render also faults in
                // its buffers and wakes the thread pool.
                r.render_prepared_scene(&scene, &ready, &|_, _| {})?;
                Some(ready)
            }
            None => None,
        };
        let gpu_ready = match &gpu {
            Some(r) => {
                r.prepare_pipeline(&scene)?;
                let ready = r.prepare_scene(&scene);
                // Untimed: drivers compile lazily on first use.
                r.render_prepared_scene(&scene, &ready, &|_, _| {})?;
                Some(ready)
            }
            None => None,
        };
        for round in 1..=report.rounds {
            let mut timed = |r: &Renderer, ready| -> Result<Duration, Error> {
                let (mut rays, mut untraced) = (None, None);
                let stat = repeat(n, || {
                    let out = r.render_prepared_scene(&scene, ready, &|_, _| {})?;
                    rays = out.timings.rays_called_for();
                    let left = out.timings.counted(crate::timing::UNTRACED_SHADOW_RAYS);
                    untraced = (left > 0).then_some(left);
                    Ok(())
                })?;
                result.rays = rays.or(result.rays);
                result.untraced = untraced.or(result.untraced);
                Ok(stat.map_or(Duration::ZERO, |s: Stat| s.median))
            };
            if let (Some(r), Some(ready)) = (&cpu, &cpu_ready) {
                let t = timed(r, ready)?;
                result.cpu.push(t);
            }
            if let (Some(r), Some(ready)) = (&gpu, &gpu_ready) {
                let t = timed(r, ready)?;
                result.gpu.push(t);
            }
            for (mode, times) in [
                (Mode::Single, &mut result.single),
                (Mode::Packet8, &mut result.packet8),
            ] {
                let run = run_harness(options, path, mode, threads)?;
                result.harness_rays = run.rays.or(result.harness_rays);
                times.push(run.median);
            }
            progress(&format!(
                "{} round {round}: glint CPU {} GPU {}, Embree single {} packet8 {} (ms)",
                result.name,
                ms_last(&result.cpu),
                ms_last(&result.gpu),
                ms_last(&result.single),
                ms_last(&result.packet8)
            ));
        }
        if let Some(off) = result.rays_differ() {
            progress(&format!(
                "warning: {}: the harness cast {} rays and glint {} ({:.1}% apart), so they \
                 did not render the same work",
                result.name,
                result.harness_rays.unwrap_or_default(),
                result.rays.unwrap_or_default(),
                off * 100.0
            ));
        }
        report.scenes.push(result);
    }
    Ok(report)
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

fn ms_last(times: &[Duration]) -> String {
    times
        .last()
        .map_or_else(|| "-".into(), |&d| format!("{:.1}", ms(d)))
}

/// "a / b / c" in milliseconds, or "-".
fn rounds_cell(times: &[Duration]) -> String {
    if times.is_empty() {
        return "-".into();
    }
    let cells: Vec<String> = times.iter().map(|&d| format!("{:.1}", ms(d))).collect();
    cells.join(" / ")
}

/// The range over rounds of Embree's time / glint's time, round by round,
/// or "-".
fn ratio_cell(embree: &[Duration], glint: &[Duration]) -> String {
    let ratios: Vec<f64> = embree
        .iter()
        .zip(glint)
        .filter(|(_, g)| !g.is_zero())
        .map(|(e, g)| e.as_secs_f64() / g.as_secs_f64())
        .collect();
    let lo = ratios.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = ratios.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if ratios.is_empty() {
        "-".into()
    } else if format!("{lo:.2}") == format!("{hi:.2}") {
        format!("{lo:.2}")
    } else {
        format!("{lo:.2}-{hi:.2}")
    }
}

impl EmbreeReport {
    /// Per scene, each program's medians round by round and the ratios
    /// (Embree time / glint time, so above 1 glint is faster), as Markdown.
    pub fn to_markdown(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{}x{}, {} threads each, median of {} renders per program and round, {} round(s) \
             (ms, round 1 / round 2 / ...); ratio = Embree time / glint time, its range over \
             the rounds; rays: those the image calls for, \"untraced\" the shadow rays of them \
             glint's CPU reference did not trace because their answer could not change a pixel; \
             Embree: {}",
            self.width,
            self.height,
            self.threads,
            self.repeat,
            self.rounds,
            self.harness.display()
        );
        if let Some(device) = &self.device {
            let _ = writeln!(out, "{device}");
        }
        let _ = writeln!(out);
        let _ = writeln!(
            out,
            "| scene | rays (glint / Embree) | glint CPU | Embree single | **CPU / single** | \
             Embree packet8 | CPU / packet8 | glint GPU | **GPU / packet8** |"
        );
        let _ = writeln!(out, "|---|---:|---:|---:|---:|---:|---:|---:|---:|");
        let count = |r: Option<u64>| r.map_or_else(|| "-".into(), |r| r.to_string());
        for s in &self.scenes {
            let differ = s.rays_differ().map_or_else(String::new, |off| {
                format!(" (**differ**, {:.1}%)", off * 100.0)
            });
            let untraced = s
                .untraced
                .map_or_else(String::new, |u| format!(" ({u} untraced)"));
            let _ = writeln!(
                out,
                "| {} | {}{} / {}{} | {} | {} | {} | {} | {} | {} | {} |",
                s.name,
                count(s.rays),
                untraced,
                count(s.harness_rays),
                differ,
                rounds_cell(&s.cpu),
                rounds_cell(&s.single),
                ratio_cell(&s.single, &s.cpu),
                rounds_cell(&s.packet8),
                ratio_cell(&s.packet8, &s.cpu),
                rounds_cell(&s.gpu),
                ratio_cell(&s.packet8, &s.gpu),
            );
        }
        let differing: Vec<&str> = self
            .scenes
            .iter()
            .filter(|s| s.rays_differ().is_some())
            .map(|s| s.name.as_str())
            .collect();
        if !differing.is_empty() {
            let _ = writeln!(
                out,
                "\nThe two cast different rays on {}: their ratios there compare different work.",
                differing.join(", ")
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const OUTPUT: &str = "scene x.scene: 182 triangles\n\
        throughput: 48.34 Mrays/s\n\
        RESULT scene=x.scene tris=182 spheres=0 W=640 H=480 mode=packet8 threads=2 \
        build_s=0.0174 render_med_s=0.0143 rays=689666 mrays_s=48.34\n";

    #[test]
    fn reads_the_median_and_rays_of_the_result_line() {
        let run = parse_result(OUTPUT).expect("a RESULT line");
        assert_eq!(run.median, Duration::from_secs_f64(0.0143));
        assert_eq!(run.rays, Some(689_666));
    }

    #[test]
    fn output_without_a_usable_result_line_is_none() {
        assert_eq!(parse_result("throughput: 1 Mrays/s\n"), None);
        assert_eq!(parse_result("RESULT scene=x rays=5\n"), None);
        assert_eq!(parse_result("RESULT render_med_s=fast\n"), None);
        assert_eq!(parse_result("RESULT render_med_s=-1\n"), None);
    }

    #[test]
    fn ratios_are_embree_over_glint_round_by_round() {
        let d = Duration::from_millis;
        assert_eq!(ratio_cell(&[d(20), d(30)], &[d(10), d(10)]), "2.00-3.00");
        assert_eq!(ratio_cell(&[d(10)], &[d(40)]), "0.25");
        assert_eq!(ratio_cell(&[d(10)], &[]), "-");
        assert_eq!(rounds_cell(&[d(1), d(2)]), "1.0 / 2.0");
    }

    #[test]
    fn ray_counts_more_than_a_thousandth_apart_differ() {
        let scene = |ours, theirs| EmbreeScene {
            rays: Some(ours),
            harness_rays: Some(theirs),
            ..EmbreeScene::default()
        };
        assert_eq!(scene(100_000, 100_000).rays_differ(), None);
        assert_eq!(scene(100_000, 100_050).rays_differ(), None);
        let off = scene(100_000, 100_200).rays_differ().expect("0.2% apart");
        assert!((off - 0.002).abs() < 1e-9, "{off}");
        assert_eq!(EmbreeScene::default().rays_differ(), None);
    }

    #[test]
    fn last_lines_keeps_the_tail() {
        assert_eq!(last_lines("a\nb\nc\n", 2).as_deref(), Some("b / c"));
        assert_eq!(last_lines("only", 3).as_deref(), Some("only"));
        assert_eq!(last_lines("\n", 1), None);
    }
}
