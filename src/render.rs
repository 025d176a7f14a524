//! Rendering a parsed scene with a chosen backend: the library's front door.

use std::time::Instant;

use crate::bvh::Bvh;
use crate::camera::{Camera, DEFAULT_HEIGHT, DEFAULT_WIDTH};
use crate::cpu::{self, Precision};
use crate::framebuffer::Framebuffer;
use crate::gpu::{Context, ContextOptions, DeviceSelector, GpuRenderOptions, GpuRenderer};
use crate::layout::GpuScene;
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

/// Renders `scene`; `progress(done, total)` counts tiles (GPU) or rows (CPU).
pub fn render(
    scene: &Scene,
    options: &RenderOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<RenderOutput, Error> {
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
                let packed = timings.time("pack", || GpuScene::pack(scene, &bvh));
                let (framebuffer, gpu_timings) = renderer.render(
                    &packed,
                    &camera,
                    options.background,
                    &options.gpu,
                    progress,
                )?;
                timings.extend(&gpu_timings);
                let info = ctx.info();
                return Ok(RenderOutput {
                    framebuffer,
                    timings,
                    renderer: format!("GPU: {} ({}, {})", info.name, info.device_type, info.driver),
                    note,
                    validation_messages: ctx.validation_messages(),
                });
            }
            Err(e) if options.backend == Backend::Auto => {
                note = Some(format!(
                    "no usable Vulkan device ({e}); rendered on the CPU reference"
                ));
            }
            Err(e) => return Err(e.into()),
        }
    }
    let start = Instant::now();
    let framebuffer = cpu::render(
        scene,
        &bvh,
        &camera,
        options.background,
        options.precision,
        progress,
    );
    timings.add("cpu render", start.elapsed());
    let bits = match options.precision {
        Precision::F32 => "f32",
        Precision::F64 => "f64",
    };
    Ok(RenderOutput {
        framebuffer,
        timings,
        renderer: format!(
            "CPU reference ({bits}, {} threads)",
            rayon::current_num_threads()
        ),
        note,
        validation_messages: 0,
    })
}
