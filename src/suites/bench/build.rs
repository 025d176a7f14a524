//! `glint bench build`: what a scene costs before its first ray, per
//! thread count. For each scene and round: glint's BVH build, the CPU
//! reference's packing and the GPU's packing on 1 thread and on every
//! thread, then (with a harness) Embree's geometry upload and
//! `rtcCommitScene` on the same threads, alternating, so that both meet the
//! machine in the same state. Rates are primitives a second through the
//! BVH and the CPU packing, what a CPU render waits for.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use super::common::Stat;
use crate::bvh::Bvh;
use crate::layout::GpuScene;
use crate::render::RenderOptions;
use crate::Error;

/// What `run_build` measures.
#[derive(Clone, Debug)]
pub struct BuildOptions {
    /// The scenes (classic files, with or without meshes).
    pub scenes: Vec<PathBuf>,
    /// Thread counts to build on, each in a pool of its own.
    pub threads: Vec<usize>,
    /// Rounds of every measurement per scene; each cell is their median.
    pub rounds: usize,
    /// An Embree harness (`../shared/tools/embree_bench.cpp`) whose `build:`
    /// line gives its upload and commit times, and the `--quality` it is
    /// run with.
    pub embree: Option<(PathBuf, String)>,
}

/// One scene on one thread count.
#[derive(Clone, Debug)]
pub struct BuildRow {
    /// The scene's file name.
    pub scene: String,
    /// Spheres and triangles.
    pub primitives: usize,
    /// Threads the pool had.
    pub threads: usize,
    /// `Bvh::for_render`.
    pub bvh: Stat,
    /// `cpu::prepare` in f32.
    pub cpu_pack: Stat,
    /// `GpuScene::pack`.
    pub gpu_pack: Stat,
    /// The built tree's SAH cost.
    pub sah_cost: f64,
    /// Embree's upload + commit, where a harness ran.
    pub embree: Option<Stat>,
}

impl BuildRow {
    /// Millions of primitives a second through the BVH and the CPU packing.
    pub fn rate(&self) -> f64 {
        let t = (self.bvh.median + self.cpu_pack.median).as_secs_f64();
        self.primitives as f64 / t.max(1e-9) / 1e6
    }
}

/// Every scene's rows, thread count by thread count.
#[derive(Clone, Debug, Default)]
pub struct BuildReport {
    /// The rows, scene by scene.
    pub rows: Vec<BuildRow>,
}

impl BuildReport {
    /// A markdown table; times in ms as "median (min-max)".
    pub fn to_markdown(&self) -> String {
        let mut out = String::from(
            "| scene | primitives | threads | bvh ms | CPU pack ms | GPU pack ms | M prims/s (bvh + CPU pack) | SAH cost | Embree upload + commit ms | Embree / glint |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        );
        for r in &self.rows {
            let (embree, ratio) = match r.embree {
                Some(e) => (
                    e.to_string(),
                    format!(
                        "{:.2}",
                        e.median.as_secs_f64()
                            / (r.bvh.median + r.cpu_pack.median).as_secs_f64().max(1e-9)
                    ),
                ),
                None => ("-".into(), "-".into()),
            };
            out += &format!(
                "| {} | {} | {} | {} | {} | {} | {:.2} | {:.2} | {embree} | {ratio} |\n",
                r.scene,
                r.primitives,
                r.threads,
                r.bvh,
                r.cpu_pack,
                r.gpu_pack,
                r.rate(),
                r.sah_cost
            );
        }
        out
    }
}

/// Measures every scene of `options`; `log` gets a line per scene and
/// thread count as it finishes.
pub fn run_build(options: &BuildOptions, log: &mut dyn FnMut(&str)) -> Result<BuildReport, Error> {
    let mut report = BuildReport::default();
    for path in &options.scenes {
        let scene = crate::scene::read_scene(path)?;
        let scene = scene.in_view_space().into_owned();
        let render = RenderOptions::default();
        let effects = render.effects(&scene);
        let cpu = crate::cpu::CpuOptions {
            effects,
            ..Default::default()
        };
        let name = path.file_name().map_or_else(
            || path.display().to_string(),
            |n| n.to_string_lossy().into(),
        );
        for &threads in &options.threads {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(|e| Error::InvalidOption(format!("a pool of {threads} threads: {e}")))?;
            let (mut bvh_t, mut cpu_t, mut gpu_t, mut embree_t) = (vec![], vec![], vec![], vec![]);
            let mut sah_cost = 0.0;
            for _ in 0..options.rounds.max(1) {
                pool.install(|| {
                    let start = Instant::now();
                    let bvh = Bvh::for_render(&scene, &effects);
                    bvh_t.push(start.elapsed());
                    let start = Instant::now();
                    drop(crate::cpu::prepare(&scene, &bvh, &cpu));
                    cpu_t.push(start.elapsed());
                    let start = Instant::now();
                    drop(GpuScene::pack(&scene, &bvh));
                    gpu_t.push(start.elapsed());
                    sah_cost = bvh.stats().sah_cost;
                });
                if let Some((harness, quality)) = &options.embree {
                    embree_t.push(embree_build(harness, quality, path, threads)?);
                }
            }
            let stat = |v: Vec<Duration>| Stat::of(v).expect("at least one round");
            let row = BuildRow {
                scene: name.clone(),
                primitives: scene.primitive_count(),
                threads,
                bvh: stat(bvh_t),
                cpu_pack: stat(cpu_t),
                gpu_pack: stat(gpu_t),
                sah_cost,
                embree: Stat::of(embree_t),
            };
            log(&format!(
                "{name}, {threads} threads: bvh {}, CPU pack {}, GPU pack {} ms; {:.2} M prims/s{}",
                row.bvh,
                row.cpu_pack,
                row.gpu_pack,
                row.rate(),
                row.embree
                    .map(|e| format!("; Embree {e} ms"))
                    .unwrap_or_default()
            ));
            report.rows.push(row);
        }
    }
    Ok(report)
}

/// Embree's upload + commit for `scene` on `threads` threads: the
/// harness's `build:` line, from one tiny render.
fn embree_build(
    harness: &Path,
    quality: &str,
    scene: &Path,
    threads: usize,
) -> Result<Duration, Error> {
    let fail = |reason: String| Error::Harness {
        harness: harness.to_path_buf(),
        scene: scene.to_path_buf(),
        reason,
    };
    let output = Command::new(harness)
        .arg(scene)
        .args(["--width", "8", "--height", "8", "--runs", "1"])
        .args(["--threads", &threads.to_string(), "--quality", quality])
        .output()
        .map_err(|e| fail(format!("cannot run it: {e}")))?;
    let stdout = String::from_utf8_lossy(&output.stdout);
    if !output.status.success() {
        return Err(fail(format!("{}", output.status)));
    }
    parse_build(&stdout).ok_or_else(|| fail("no `build: SECONDS s` line in its output".into()))
}

/// The seconds of a harness's `build: 0.4759 s (geometry upload ...` line.
pub fn parse_build(stdout: &str) -> Option<Duration> {
    let line = stdout.lines().find(|l| l.starts_with("build:"))?;
    let seconds: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    (seconds.is_finite() && seconds >= 0.0).then(|| Duration::from_secs_f64(seconds))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_build_line_is_read() {
        let out = "scene x: 2 triangles\nbuild: 0.4759 s (geometry upload 0.0517 s + rtcCommitScene 0.4243 s), quality=medium\n";
        assert_eq!(parse_build(out), Some(Duration::from_secs_f64(0.4759)));
        assert_eq!(parse_build("build: soon\n"), None);
        assert_eq!(parse_build("build: -1 s\n"), None);
        assert_eq!(parse_build("nothing\n"), None);
    }

    /// A scene of the project's measured on one thread and two: every row
    /// there, with its primitives and a positive rate.
    #[test]
    fn a_scene_is_measured_on_each_thread_count() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("s.scene");
        std::fs::write(
            &path,
            "2\namb: 0 0 0\nsphere\npos: 0 0 -3\nrad: 1\ndif: 1 1 1\nspe: 0 0 0\nshi: 1\nlight\npos: 0 5 0\ncol: 1 1 1\n",
        )
        .expect("write");
        let options = BuildOptions {
            scenes: vec![path],
            threads: vec![1, 2],
            rounds: 2,
            embree: None,
        };
        let mut lines = 0;
        let report = run_build(&options, &mut |_| lines += 1).expect("measures");
        assert_eq!(lines, 2);
        assert_eq!(report.rows.len(), 2);
        assert!(report
            .rows
            .iter()
            .all(|r| r.primitives == 1 && r.rate() > 0.0));
        assert!(report.to_markdown().lines().count() == 4);
    }
}
