//! Probes of a scene below a render: every pixel's primary hit and shadow
//! verdicts (`probe`), and one pixel's whole path (`pixel_path`), on the
//! renderer's backend, with what produced them.

use super::options::RenderOptions;
use super::renderer::{Engine, Renderer};
use crate::layout::GpuScene;
use crate::probe::{PathRecord, ProbeImage};
use crate::scene::Scene;
use crate::timing::Timings;
use crate::{cpu, Error};

impl Renderer {
    /// Every pixel's primary hit and shadow verdicts (pixel centres, sample 0).
    pub fn probe(&self, scene: &Scene) -> Result<ProbeImage, Error> {
        let scene = &*scene.in_view_space();
        let p = self.prepare(scene, &mut Timings::default());
        Ok(match &self.engine {
            Engine::Gpu { renderer, .. } => renderer.probe(
                &GpuScene::pack(scene, &p.bvh),
                &p.camera,
                &self.gpu_options(&p),
            )?,
            Engine::Cpu(precision) => {
                cpu::probe(scene, &p.bvh, &p.camera, &self.cpu_options(&p, *precision))
            }
        })
    }

    /// The path of pixel (x, y): hit, surface, each light's shadow verdict
    /// and Phong terms.
    pub fn pixel_path(&self, scene: &Scene, pixel: [u32; 2]) -> Result<PathRecord, Error> {
        let o = &self.options;
        if pixel[0] >= o.width || pixel[1] >= o.height {
            return Err(Error::InvalidOption(format!(
                "pixel {},{} is outside the {}x{} image (x counts from 0 at the left, y from 0 at the top)",
                pixel[0], pixel[1], o.width, o.height
            )));
        }
        let world = scene;
        let scene = &*scene.in_view_space();
        let p = self.prepare(scene, &mut Timings::default());
        let record = match &self.engine {
            Engine::Gpu { renderer, .. } => renderer.pixel_path(
                &GpuScene::pack(scene, &p.bvh),
                &p.camera,
                o.background,
                pixel,
                &self.gpu_options(&p),
            )?,
            Engine::Cpu(precision) => cpu::pixel_path(
                scene,
                &p.bvh,
                &p.camera,
                &self.cpu_options(&p, *precision),
                pixel,
            ),
        };
        let record = record.in_scene_units(p.bvh.scale);
        Ok(match world.camera {
            Some(cam) if !cam.is_classic_placement() => record.in_world(&cam),
            _ => record,
        })
    }

    fn probed<T>(&self, value: T) -> Probed<T> {
        Probed {
            value,
            renderer: self.name(),
            validation_messages: self.validation_messages(),
            note: self.note().map(str::to_string),
        }
    }
}

/// A probe result and what produced it.
pub struct Probed<T> {
    /// What the probe found.
    pub value: T,
    /// As `RenderOutput::renderer`.
    pub renderer: String,
    /// As `RenderOutput::note`.
    pub note: Option<String>,
    /// As `RenderOutput::validation_messages`.
    pub validation_messages: u32,
}

/// Every pixel's primary hit and shadow verdicts on the chosen backend.
pub fn probe(scene: &Scene, options: &RenderOptions) -> Result<Probed<ProbeImage>, Error> {
    let r = Renderer::new(options)?;
    let value = r.probe(scene)?;
    Ok(r.probed(value))
}

/// The path of pixel (x, y) on the chosen backend.
pub fn pixel_path(
    scene: &Scene,
    options: &RenderOptions,
    pixel: [u32; 2],
) -> Result<Probed<PathRecord>, Error> {
    let r = Renderer::new(options)?;
    let value = r.pixel_path(scene, pixel)?;
    Ok(r.probed(value))
}
