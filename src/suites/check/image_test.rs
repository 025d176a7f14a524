//! An image test of one's own scene, as `glint check` tests its suite: the
//! scene rendered on a Vulkan device and on the CPU reference (the f32 twin
//! and the f64 truth), the device's image held to a `Tolerance`, and where
//! it fails, the images and their difference written for a person to see.
//! This is glint's software-Vulkan image test (lavapipe in CI) as one call.

use std::path::PathBuf;

use super::judge::{judge, write_failure};
use super::suite::Tolerance;
use crate::cpu::Precision;
use crate::gpu::DeviceSelector;
use crate::images::compare::{compare_framebuffers, Comparison};
use crate::render::{Backend, Job, Quiet, RenderOptions, Renderer, Sink};
use crate::scene::Scene;
use crate::Error;

/// How to test: on which device, how close, and where a failure's images go.
#[derive(Clone, Debug)]
pub struct ImageTest {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// The Vulkan device; `None`: the best one found (lavapipe counts).
    pub device: Option<DeviceSelector>,
    /// How close the device must come to the CPU reference.
    pub tolerance: Tolerance,
    /// Where a failure's images go, named after `name`; `None`: nowhere.
    pub out: Option<PathBuf>,
    /// The test's name: the failure images' file names start with it.
    pub name: String,
}

impl ImageTest {
    /// A `width` x `height` test held to `Tolerance::TIGHT`, the classic
    /// and effect scenes' tolerance, its failures kept nowhere.
    pub fn new(name: &str, width: u32, height: u32) -> ImageTest {
        ImageTest {
            width,
            height,
            device: None,
            tolerance: Tolerance::TIGHT,
            out: None,
            name: name.to_string(),
        }
    }
}

/// What the test found.
#[derive(Debug)]
pub struct Verdict {
    /// The device that rendered it ("GPU: llvmpipe ...").
    pub device: String,
    /// The device's image against the f32 twin, which follows the shader
    /// operation for operation, and against the f64 truth.
    pub against_twin: Comparison,
    /// The device's image against the f64 truth.
    pub against_truth: Comparison,
    /// Pixels that may be more than one 8-bit level off the twin.
    pub allowed: usize,
    /// Why it failed; `None`: it passed.
    pub failure: Option<String>,
    /// The failure's images (device, CPU twin, difference), where written.
    pub written: Vec<PathBuf>,
}

impl Verdict {
    /// Whether the device's image met the tolerance.
    pub fn passed(&self) -> bool {
        self.failure.is_none()
    }
}

/// Renders `scene` on the device and on the CPU reference and judges the
/// device's image by `test.tolerance`.
pub fn image_test(scene: &Scene, test: &ImageTest) -> Result<Verdict, Error> {
    let options = |backend, precision, device| RenderOptions {
        width: test.width,
        height: test.height,
        backend,
        precision,
        device,
        // The twin traces every ray alone, as `glint check`'s does.
        packets: false,
        ..RenderOptions::default()
    };
    let render = |o: RenderOptions| -> Result<_, Error> {
        let job = Job::new(scene);
        let sink = Sink::Memory(crate::render::PixelFormat::Float);
        let done = Renderer::new(&o)?.run(&job, &sink, &Quiet)?;
        Ok((done.output.renderer.clone(), done.output.into_framebuffer()))
    };
    let (device, image) = render(options(Backend::Gpu, Precision::F32, test.device.clone()))?;
    let (_, twin) = render(options(Backend::Cpu, Precision::F32, None))?;
    let (_, truth) = render(options(Backend::Cpu, Precision::F64, None))?;
    let against_twin = compare_framebuffers(&twin, &image, 1.0)?;
    let against_truth = compare_framebuffers(&truth, &image, 1.0)?;
    let pixels = (test.width as usize) * (test.height as usize);
    let (why, allowed) = judge(&test.tolerance, pixels, &against_twin, &against_truth);
    let failure = (!why.is_empty()).then(|| why.join("; "));
    let written = match (&test.out, &failure) {
        (Some(dir), Some(_)) => write_failure(dir, &test.name, &image, &twin, &against_twin)?,
        _ => Vec::new(),
    };
    Ok(Verdict {
        device,
        against_twin,
        against_truth,
        allowed,
        failure,
        written,
    })
}
