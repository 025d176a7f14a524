//! `glint bench samplers`: each sampler's mean squared error against an f64
//! reference of the same integral, and its time, at a scene's own sample
//! counts: what a sampler buys at equal samples, and what it costs.
//!
//! The reference is the mean of `reference_passes` CPU f64 renders with
//! seeds no measured render uses (the default sampler; both samplers are
//! unbiased, tests/samplers.rs), so its own error adds about
//! 1/`reference_passes` of one default render's MSE to every row. Each
//! sampler renders the scene with `seeds` seeds, the samplers alternating
//! render by render; its MSE is the mean over the seeds, its time the
//! median.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use crate::cpu::Precision;
use crate::gpu::DeviceSelector;
use crate::images::framebuffer::Framebuffer;
use crate::render::{Backend, RenderOptions, Renderer};
use crate::scene::{read_scene, Sampler, Scene, Settings};
use crate::suites::accuracy::errors;
use crate::Error;

use super::common::{scene_name, Stat};

/// Seeds of the reference's passes: far from any seed a measured render
/// uses (0, 1, ... and the scene's own).
const REFERENCE_SEED: u32 = 0x5eed_0000;

/// What `glint bench samplers` measures.
#[derive(Clone, Debug)]
pub struct SamplersOptions {
    /// The scene files, in order.
    pub scenes: Vec<PathBuf>,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Renders per sampler and scene, each with its own seed.
    pub seeds: u32,
    /// CPU f64 renders averaged into the reference.
    pub reference_passes: u32,
    /// Where the measured renders run (the reference is always the CPU's).
    pub backend: Backend,
    /// Which Vulkan device (`--device`); None: the first.
    pub device: Option<DeviceSelector>,
}

/// The scenes `glint bench samplers` measures unless told: the effect
/// scenes that sample something.
pub fn sampler_scenes() -> Vec<PathBuf> {
    ["soft_shadows", "antialias", "motion_blur", "all_effects"]
        .iter()
        .map(|n| PathBuf::from(format!("scenes/effects/{n}.scene")))
        .collect()
}

/// One scene and sampler measured.
#[derive(Clone, Debug, PartialEq)]
pub struct SamplerRow {
    /// The scene file's name.
    pub scene: String,
    /// The sampler.
    pub sampler: Sampler,
    /// Mean over the seeds of the MSE against the reference (clamped to
    /// [0, 1] as the image is).
    pub mse: f64,
    /// The renders' median wall time (setup, BVH and all).
    pub time: Stat,
}

/// What `glint bench samplers` found.
#[derive(Clone, Debug)]
pub struct SamplersReport {
    /// The measured renders' backend, as `Renderer::name` says.
    pub renderer: String,
    /// What was asked for.
    pub options: SamplersOptions,
    /// Per scene, every sampler in `Sampler::ALL` order.
    pub rows: Vec<SamplerRow>,
}

impl SamplersReport {
    /// The report as a markdown table: per scene, each sampler's MSE and
    /// time, and the default's against `stratified`'s.
    pub fn to_markdown(&self) -> String {
        let o = &self.options;
        let mut s = format!(
            "{}. {}x{}, the scenes' own sample counts; MSE: mean of {} seeds against the mean of {} CPU f64 renders (other seeds); time: median render.\n\n",
            self.renderer, o.width, o.height, o.seeds, o.reference_passes
        );
        s.push_str("| scene | sampler | MSE | time (ms) | stratified MSE / this | this time / stratified's |\n|---|---|---:|---:|---:|---:|\n");
        for row in &self.rows {
            let Some(base) = self
                .rows
                .iter()
                .find(|r| r.scene == row.scene && r.sampler == Sampler::Stratified)
            else {
                continue;
            };
            let _ = writeln!(
                s,
                "| {} | {} | {:.3e} | {:.1} | {:.2} | {:.2} |",
                row.scene,
                row.sampler,
                row.mse,
                row.time.median.as_secs_f64() * 1e3,
                base.mse / row.mse.max(f64::MIN_POSITIVE),
                row.time.median.as_secs_f64() / base.time.median.as_secs_f64().max(1e-9)
            );
        }
        s
    }
}

/// Runs `glint bench samplers`; `progress` hears one line per measurement.
pub fn run_samplers(
    options: &SamplersOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<SamplersReport, Error> {
    if options.seeds == 0 || options.reference_passes == 0 {
        return Err(Error::InvalidOption(
            "--seeds and --reference-passes need at least 1".into(),
        ));
    }
    let base = RenderOptions {
        width: options.width,
        height: options.height,
        ..RenderOptions::default()
    };
    let reference_renderer = Renderer::new(&RenderOptions {
        backend: Backend::Cpu,
        precision: Precision::F64,
        ..base.clone()
    })?;
    let renderer = Renderer::new(&RenderOptions {
        backend: options.backend,
        device: options.device.clone(),
        ..base
    })?;
    let mut rows = Vec::new();
    for path in &options.scenes {
        let scene = read_scene(path)?;
        let name = scene_name(path);
        let started = Instant::now();
        let reference = reference_image(&reference_renderer, &scene, options.reference_passes)?;
        progress(&format!(
            "{name}: reference of {} f64 renders in {:.1} s",
            options.reference_passes,
            started.elapsed().as_secs_f64()
        ));
        // One render first: pipelines and caches warm for every sampler.
        renderer.render(&with(&scene, 0, Sampler::default()), &|_, _| {})?;
        let mut squared = [0.0; Sampler::ALL.len()];
        let mut times: [Vec<Duration>; Sampler::ALL.len()] = Default::default();
        for seed in 0..options.seeds {
            // Alternating which sampler goes first, so neither always runs
            // on a machine the other has just warmed.
            let mut order: Vec<usize> = (0..Sampler::ALL.len()).collect();
            if seed % 2 == 1 {
                order.reverse();
            }
            for k in order {
                let at = with(&scene, seed, Sampler::ALL[k]);
                let start = Instant::now();
                let image = renderer.render(&at, &|_, _| {})?.into_framebuffer();
                times[k].push(start.elapsed());
                squared[k] += errors(&image, &reference).rmse.powi(2);
            }
        }
        for (k, sampler) in Sampler::ALL.into_iter().enumerate() {
            let row = SamplerRow {
                scene: name.clone(),
                sampler,
                mse: squared[k] / f64::from(options.seeds),
                time: Stat::of(std::mem::take(&mut times[k])).expect("at least one seed"),
            };
            progress(&format!(
                "{name}, {sampler}: MSE {:.3e}, {:.1} ms",
                row.mse,
                row.time.median.as_secs_f64() * 1e3
            ));
            rows.push(row);
        }
    }
    Ok(SamplersReport {
        renderer: renderer.name(),
        options: options.clone(),
        rows,
    })
}

/// `scene` with seed `seed` and `sampler`, its other settings its own.
fn with(scene: &Scene, seed: u32, sampler: Sampler) -> Scene {
    let mut at = scene.clone();
    at.settings = Settings {
        seed: Some(scene.settings.seed.unwrap_or(0).wrapping_add(seed)),
        sampler: Some(sampler),
        ..scene.settings
    };
    at
}

/// The mean of `passes` f64 renders of `scene` with the default sampler
/// and seeds of their own.
fn reference_image(renderer: &Renderer, scene: &Scene, passes: u32) -> Result<Framebuffer, Error> {
    let mut sum: Vec<[f64; 3]> = Vec::new();
    let mut size = (0, 0);
    for pass in 0..passes {
        let mut at = scene.clone();
        at.settings.seed = Some(REFERENCE_SEED.wrapping_add(pass));
        at.settings.sampler = Some(Sampler::default());
        let image = renderer.render(&at, &|_, _| {})?.into_framebuffer();
        size = (image.width, image.height);
        sum.resize(image.pixels.len(), [0.0; 3]);
        for (s, p) in sum.iter_mut().zip(&image.pixels) {
            for c in 0..3 {
                s[c] += f64::from(p[c]);
            }
        }
    }
    let n = f64::from(passes);
    Ok(Framebuffer {
        width: size.0,
        height: size.1,
        pixels: sum.iter().map(|s| s.map(|v| (v / n) as f32)).collect(),
    })
}
