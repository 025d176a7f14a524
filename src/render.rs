//! Rendering a parsed scene with a chosen backend: the library's front door.

use std::time::Instant;

use crate::bvh::Bvh;
use crate::camera::{Camera, DEFAULT_HEIGHT, DEFAULT_WIDTH};
use crate::cpu::{self, Precision};
use crate::framebuffer::Framebuffer;
use crate::gpu::{Context, ContextOptions, DeviceSelector, GpuRenderOptions, GpuRenderer};
use crate::layout::GpuScene;
use crate::methods::Methods;
use crate::probe::{PathRecord, ProbeImage};
use crate::scene::Scene;
use crate::timing::Timings;
use crate::Error;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Backend {
    /// The best Vulkan device, else the CPU reference (with a note saying why).
    #[default]
    Auto,
    Gpu,
    Cpu,
}

#[derive(Clone, Debug)]
pub struct RenderOptions {
    pub width: u32,
    pub height: u32,
    /// Colour of rays that hit nothing, linear [0, 1].
    pub background: [f32; 3],
    pub backend: Backend,
    pub device: Option<DeviceSelector>,
    /// CPU reference only.
    pub precision: Precision,
    /// Enable the Vulkan validation layer when it is installed.
    pub validation: bool,
    /// Intersection and offset methods on either backend; overrides
    /// `gpu.methods`.
    pub methods: Methods,
    pub gpu: GpuRenderOptions,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: DEFAULT_WIDTH,
            height: DEFAULT_HEIGHT,
            background: [1.0; 3],
            backend: Backend::Auto,
            device: None,
            precision: Precision::F32,
            validation: false,
            methods: Methods::Robust,
            gpu: GpuRenderOptions::default(),
        }
    }
}

pub struct RenderOutput {
    pub framebuffer: Framebuffer,
    pub timings: Timings,
    /// What rendered it, e.g. "GPU: llvmpipe (LLVM 15.0.6, 256 bits)" or "CPU reference (f32)".
    pub renderer: String,
    /// Something the user should know, e.g. why `auto` fell back to the CPU.
    pub note: Option<String>,
    /// Vulkan validation warnings and errors seen (GPU renders with validation on).
    pub validation_messages: u32,
}

/// Where the work runs, chosen once per call from `RenderOptions`.
enum Engine {
    Gpu {
        ctx: Context,
        renderer: GpuRenderer,
        options: GpuRenderOptions,
    },
    Cpu(Precision),
}

struct Setup {
    camera: Camera,
    bvh: Bvh,
    engine: Engine,
    timings: Timings,
    note: Option<String>,
}

impl Setup {
    fn new(scene: &Scene, options: &RenderOptions) -> Result<Setup, Error> {
        if options.width == 0 || options.height == 0 {
            return Err(Error::InvalidOption(format!(
                "image size {}x{} has no pixels",
                options.width, options.height
            )));
        }
        if options.backend == Backend::Gpu && options.precision == Precision::F64 {
            return Err(Error::InvalidOption(
                "--precision f64 exists on the CPU reference only; use --backend cpu".into(),
            ));
        }
        let camera = Camera::new(options.width, options.height);
        let mut timings = Timings::default();
        let bvh = timings.time("bvh", || Bvh::build(scene));
        let want_gpu = match (options.backend, options.precision) {
            (Backend::Cpu, _) | (Backend::Auto, Precision::F64) => false,
            (Backend::Gpu, _) | (Backend::Auto, Precision::F32) => true,
        };
        let mut note = None;
        if options.backend == Backend::Auto && !want_gpu {
            note = Some("--precision f64 exists on the CPU reference only; rendered there".into());
        }
        let mut engine = Engine::Cpu(options.precision);
        if want_gpu {
            let context_options = ContextOptions {
                device: options.device.clone(),
                validation: options.validation,
            };
            let start = Instant::now();
            match Context::new(&context_options) {
                Ok(ctx) => {
                    timings.add("device", start.elapsed());
                    let renderer = GpuRenderer::new(&ctx)?;
                    timings.add("pipeline", renderer.pipeline_time);
                    let gpu_options = GpuRenderOptions {
                        methods: options.methods,
                        ..options.gpu
                    };
                    engine = Engine::Gpu {
                        ctx,
                        renderer,
                        options: gpu_options,
                    };
                }
                Err(e) if options.backend == Backend::Auto => {
                    note = Some(format!(
                        "no usable Vulkan device ({e}); rendered on the CPU reference"
                    ));
                }
                Err(e) => return Err(e.into()),
            }
        }
        Ok(Setup {
            camera,
            bvh,
            engine,
            timings,
            note,
        })
    }

    fn renderer_name(&self) -> String {
        match &self.engine {
            Engine::Gpu { ctx, .. } => {
                let info = ctx.info();
                format!("GPU: {} ({}, {})", info.name, info.device_type, info.driver)
            }
            Engine::Cpu(precision) => {
                let bits = match precision {
                    Precision::F32 => "f32",
                    Precision::F64 => "f64",
                };
                format!(
                    "CPU reference ({bits}, {} threads)",
                    rayon::current_num_threads()
                )
            }
        }
    }

    fn probed<T>(self, value: T) -> Probed<T> {
        Probed {
            value,
            renderer: self.renderer_name(),
            validation_messages: self.validation_messages(),
            note: self.note,
        }
    }

    fn validation_messages(&self) -> u32 {
        match &self.engine {
            Engine::Gpu { ctx, .. } => ctx.validation_messages(),
            Engine::Cpu(_) => 0,
        }
    }
}

/// Renders `scene`; `progress(done, total)` counts tiles (GPU) or rows (CPU).
pub fn render(
    scene: &Scene,
    options: &RenderOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<RenderOutput, Error> {
    let mut setup = Setup::new(scene, options)?;
    let framebuffer = match &setup.engine {
        Engine::Gpu {
            renderer,
            options: gpu_options,
            ..
        } => {
            let packed = setup
                .timings
                .time("pack", || GpuScene::pack(scene, &setup.bvh));
            let (framebuffer, gpu_timings) = renderer.render(
                &packed,
                &setup.camera,
                options.background,
                gpu_options,
                progress,
            )?;
            setup.timings.extend(&gpu_timings);
            framebuffer
        }
        Engine::Cpu(precision) => {
            let start = Instant::now();
            let framebuffer = cpu::render(
                scene,
                &setup.bvh,
                &setup.camera,
                options.background,
                *precision,
                options.methods,
                progress,
            );
            setup.timings.add("cpu render", start.elapsed());
            framebuffer
        }
    };
    Ok(RenderOutput {
        framebuffer,
        renderer: setup.renderer_name(),
        validation_messages: setup.validation_messages(),
        timings: setup.timings,
        note: setup.note,
    })
}

/// A probe result and what produced it.
pub struct Probed<T> {
    pub value: T,
    /// As `RenderOutput::renderer`.
    pub renderer: String,
    pub note: Option<String>,
    pub validation_messages: u32,
}

/// Every pixel's primary hit and shadow verdicts on the chosen backend.
pub fn probe(scene: &Scene, options: &RenderOptions) -> Result<Probed<ProbeImage>, Error> {
    let setup = Setup::new(scene, options)?;
    let value = match &setup.engine {
        Engine::Gpu {
            renderer,
            options: gpu_options,
            ..
        } => renderer.probe(
            &GpuScene::pack(scene, &setup.bvh),
            &setup.camera,
            gpu_options,
        )?,
        Engine::Cpu(precision) => cpu::probe(
            scene,
            &setup.bvh,
            &setup.camera,
            *precision,
            options.methods,
        ),
    };
    Ok(setup.probed(value))
}

/// The path of pixel (x, y) on the chosen backend: hit, surface, each light's
/// shadow verdict and Phong terms.
pub fn pixel_path(
    scene: &Scene,
    options: &RenderOptions,
    pixel: [u32; 2],
) -> Result<Probed<PathRecord>, Error> {
    if pixel[0] >= options.width || pixel[1] >= options.height {
        return Err(Error::InvalidOption(format!(
            "pixel {},{} is outside the {}x{} image (x counts from 0 at the left, y from 0 at the top)",
            pixel[0], pixel[1], options.width, options.height
        )));
    }
    let setup = Setup::new(scene, options)?;
    let value = match &setup.engine {
        Engine::Gpu {
            renderer,
            options: gpu_options,
            ..
        } => renderer.pixel_path(
            &GpuScene::pack(scene, &setup.bvh),
            &setup.camera,
            options.background,
            pixel,
            gpu_options,
        )?,
        Engine::Cpu(precision) => cpu::pixel_path(
            scene,
            &setup.bvh,
            &setup.camera,
            options.background,
            *precision,
            options.methods,
            pixel,
        ),
    };
    Ok(setup.probed(value))
}
