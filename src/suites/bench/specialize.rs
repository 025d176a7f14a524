//! Each scene's specialised shader against the generic one (`glint bench
//! specialize`): SPIR-V size, uncached pipeline build time and render time.
//! It gets its device from a `render::Renderer` and drives that renderer's
//! `GpuRenderer` directly, since uncached builds of chosen feature sets are
//! what it measures.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use super::common::{default_scenes, scene_files, Stat};
use crate::bvh::Bvh;
use crate::camera::Camera;
use crate::features::Features;
use crate::gpu::{DeviceSelector, GpuError, GpuRenderOptions, Kernel};
use crate::layout::GpuScene;
use crate::methods::Methods;
use crate::render::{Backend, RenderOptions, Renderer};
use crate::scene::{read_scene, Effects};
use crate::Error;

/// `glint bench specialize`: per scene, the shader specialised for its
/// feature set against the generic one (every effect compiled in, switched
/// by the settings), in SPIR-V size, pipeline build time and render time.
pub struct SpecializeOptions {
    /// The scene files, in order.
    pub scenes: Vec<PathBuf>,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Renders per measurement (the median is reported).
    pub repeat: usize,
    /// Which Vulkan device (`--device`); None: the first.
    pub device: Option<DeviceSelector>,
}

/// The default subjects: the classic scenes (when present), the showcase,
/// and every effect scene.
pub fn specialize_scenes(note: &mut dyn FnMut(&str)) -> Vec<PathBuf> {
    let mut out = default_scenes(note);
    out.extend(scene_files("scenes/effects"));
    out
}

/// Runs `glint bench specialize`; the report in markdown.
pub fn run_specialize(
    options: &SpecializeOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<String, Error> {
    use crate::gpu::shader;
    let device = Renderer::new(&RenderOptions {
        backend: Backend::Gpu,
        device: options.device.clone(),
        ..RenderOptions::default()
    })?;
    let renderer = device
        .gpu()
        .ok_or_else(|| Error::InvalidOption("no GPU for the specialisation benchmark".into()))?;
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{}. {}x{}; build: median of 3 uncached pipeline builds \
         (naga specialisation + SPIR-V + driver compile); render: median of {} \
         renders, specialised and generic interleaved, after one warm-up each.\n",
        device.name(),
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
        let scene = read_scene(path)?.in_view_space().into_owned();
        let camera = Camera::with_fov(options.width, options.height, scene.fov());
        let name = super::common::scene_name(path);
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
