//! `glint bench load`: how fast a scene arrives, phase by phase, up to its
//! first pixel on the CPU reference: reading the files' bytes, parsing
//! (the scene and its models), smooth normals and the scene's triangles,
//! moving it into the camera's view, the BVH and the CPU's packing. The
//! load rate is the input's bytes (the scene file and every model it
//! names, or the model given alone) over read + parse + normals.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use super::common::Stat;
use crate::bvh::Bvh;
use crate::render::RenderOptions;
use crate::Error;

/// What `run_load` measures.
#[derive(Clone, Debug)]
pub struct LoadOptions {
    /// Scene or model files.
    pub inputs: Vec<PathBuf>,
    /// Rounds per input; each cell is their median.
    pub rounds: usize,
}

/// One input's phases.
#[derive(Clone, Debug)]
pub struct LoadRow {
    /// The file's name.
    pub input: String,
    /// Bytes of the input: the file and the models it names.
    pub bytes: u64,
    /// Spheres and triangles.
    pub primitives: usize,
    /// Reading model files' bytes (zero for a scene without models:
    /// its reading and parsing overlap, and count as parse).
    pub read: Stat,
    /// Parsing the scene and its models.
    pub parse: Stat,
    /// Smooth normals and the models' triangles made the scene's.
    pub normals: Stat,
    /// Into the camera's view.
    pub view: Stat,
    /// `Bvh::for_render`.
    pub bvh: Stat,
    /// `cpu::prepare` in f32.
    pub pack: Stat,
    /// All of it, round by round.
    pub total: Stat,
}

impl LoadRow {
    /// MB (10^6 bytes) a second through read, parse and normals, medians.
    pub fn load_rate(&self) -> f64 {
        let t = (self.read.median + self.parse.median + self.normals.median).as_secs_f64();
        self.bytes as f64 / t.max(1e-9) / 1e6
    }
}

/// Every input's row.
#[derive(Clone, Debug, Default)]
pub struct LoadReport {
    /// Input by input.
    pub rows: Vec<LoadRow>,
}

impl LoadReport {
    /// A markdown table; times in ms as "median (min-max)".
    pub fn to_markdown(&self) -> String {
        let mut out = String::from(
            "| input | bytes | primitives | read ms | parse ms | normals ms | view ms | bvh ms | CPU pack ms | before the first pixel ms | load MB/s |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        );
        for r in &self.rows {
            out += &format!(
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.0} |\n",
                r.input,
                r.bytes,
                r.primitives,
                r.read,
                r.parse,
                r.normals,
                r.view,
                r.bvh,
                r.pack,
                r.total,
                r.load_rate()
            );
        }
        out
    }
}

/// Measures every input of `options`; `log` gets a line per input.
pub fn run_load(options: &LoadOptions, log: &mut dyn FnMut(&str)) -> Result<LoadReport, Error> {
    let mut report = LoadReport::default();
    for path in &options.inputs {
        let mut times: [Vec<Duration>; 7] = Default::default();
        let (mut bytes, mut primitives) = (0, 0);
        for _ in 0..options.rounds.max(1) {
            let start = Instant::now();
            let scene = crate::scene::read_scene(path)?;
            let loaded = start.elapsed();
            let [(_, read), (_, parse), (_, normals)] = scene.load_phases(loaded);
            let at = Instant::now();
            let view = scene.in_view_space().into_owned();
            let view_t = at.elapsed();
            let effects = RenderOptions::default().effects(&view);
            let at = Instant::now();
            let bvh = Bvh::for_render(&view, &effects);
            let bvh_t = at.elapsed();
            let at = Instant::now();
            let cpu = crate::cpu::CpuOptions {
                effects,
                ..Default::default()
            };
            drop(crate::cpu::prepare(&view, &bvh, &cpu));
            let pack_t = at.elapsed();
            let total = start.elapsed();
            for (v, t) in times
                .iter_mut()
                .zip([read, parse, normals, view_t, bvh_t, pack_t, total])
            {
                v.push(t);
            }
            bytes = input_bytes(path, &scene);
            primitives = view.primitive_count();
        }
        let [read, parse, normals, view, bvh, pack, total] =
            times.map(|v| Stat::of(v).expect("at least one round"));
        let row = LoadRow {
            input: path.file_name().map_or_else(
                || path.display().to_string(),
                |n| n.to_string_lossy().into(),
            ),
            bytes,
            primitives,
            read,
            parse,
            normals,
            view,
            bvh,
            pack,
            total,
        };
        log(&format!(
            "{}: read {}, parse {}, normals {}, view {}, bvh {}, pack {} ms; {:.0} MB/s loaded",
            row.input,
            row.read,
            row.parse,
            row.normals,
            row.view,
            row.bvh,
            row.pack,
            row.load_rate()
        ));
        report.rows.push(row);
    }
    Ok(report)
}

/// The bytes of `path` and of every model file its scene names.
fn input_bytes(path: &std::path::Path, scene: &crate::scene::Scene) -> u64 {
    let size = |p: &std::path::Path| std::fs::metadata(p).map_or(0, |m| m.len());
    let models: u64 = if crate::mesh::Format::of(path).is_some() {
        0
    } else {
        let dir = path.parent().unwrap_or(std::path::Path::new("."));
        scene.meshes.iter().map(|m| size(&dir.join(&m.file))).sum()
    };
    size(path) + models
}
