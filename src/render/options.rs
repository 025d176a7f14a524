//! What a render is asked for: the backend, the image, the methods and the
//! overrides of the scene's settings.

use crate::camera::{DEFAULT_HEIGHT, DEFAULT_WIDTH};
use crate::cpu::Precision;
use crate::features::Features;
use crate::gpu::{DeviceSelector, GpuRenderOptions};
use crate::methods::Methods;
use crate::scene::{Effects, Scene, Settings};

/// Where a render runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Backend {
    /// The best hardware Vulkan device; the CPU reference when there is
    /// none, or only a software one such as lavapipe, which is slower than
    /// the CPU reference on the same cores (with a note saying why).
    /// A `device` asked for is always used.
    #[default]
    Auto,
    /// A Vulkan device (`RenderOptions::device`, else the best one found); an error where there is none.
    Gpu,
    /// The CPU reference, in `RenderOptions::precision`.
    Cpu,
}

/// How to render: the image, the backend and device, the methods, overrides
/// of the scene's settings, and the GPU's tiles and passes.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Colour of rays that hit nothing, linear [0, 1].
    pub background: [f32; 3],
    /// Where to render (`Auto`: a hardware GPU, else the CPU reference).
    pub backend: Backend,
    /// The Vulkan device, by index or name; `None`: the best one found.
    pub device: Option<DeviceSelector>,
    /// CPU reference only.
    pub precision: Precision,
    /// Enable the Vulkan validation layer when it is installed.
    pub validation: bool,
    /// Intersection and offset methods on either backend; overrides
    /// `gpu.methods`.
    pub methods: Methods,
    /// Overrides of the scene's own settings (`--spp`, `--reflect`, ...).
    pub settings: Settings,
    /// GPU: compile every effect in and switch them by the settings alone
    /// (the generic shader), instead of specialising for the scene.
    pub generic: bool,
    /// GPU tile edge and pass budget; `None`: the device's driver profile
    /// (`gpu::driver`), which `gpu` then holds once a device is chosen.
    pub tile: Option<u32>,
    /// Loop iterations one invocation may run per pass.
    pub pass_budget: Option<u32>,
    /// Most passes of a tile queued before the host waits
    /// (`GpuRenderOptions::chain_passes`).
    pub chain_passes: Option<u32>,
    /// CPU f32: trace pixels in packets where they apply (`cpu::packet`);
    /// off, every ray alone, which keeps the shader's choice between two
    /// surfaces a ray meets at exactly one t (`glint check`'s twin).
    pub packets: bool,
    /// Keep built GPU pipelines on disk here (`gpu::cache::default_dir`);
    /// `None`: compile them every run.
    pub pipeline_cache: Option<std::path::PathBuf>,
    /// Keep built trees on disk here and read them back for the same
    /// geometry (`SceneCache::from_env`); `None`: build every render.
    pub scene_cache: Option<crate::scene_cache::SceneCache>,
    /// The GPU's own options (pass timeout, list forms, ...).
    pub gpu: GpuRenderOptions,
    /// What the image is for: float values, or the 8-bit pixels of a PNG,
    /// JPEG or PPM, converted where they are made (by the device's pack
    /// shader, which then reads back 3 bytes a pixel instead of 12).
    pub pixels: PixelFormat,
}

/// The pixels a render hands back (`RenderOutput::image`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PixelFormat {
    /// Linear f32 RGB, unclamped as rendered (`Image::Float`).
    #[default]
    Float,
    /// `framebuffer::to_u8` of each channel (`Image::Rgb8`).
    Rgb8,
}

impl PixelFormat {
    /// What a file of `kind` holds.
    pub fn for_file(kind: crate::images::framebuffer::ImageFile) -> PixelFormat {
        if kind.is_float() {
            PixelFormat::Float
        } else {
            PixelFormat::Rgb8
        }
    }
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
            settings: Settings::default(),
            generic: false,
            tile: None,
            pass_budget: None,
            chain_passes: None,
            packets: true,
            pipeline_cache: None,
            scene_cache: None,
            gpu: GpuRenderOptions::default(),
            pixels: PixelFormat::Float,
        }
    }
}

impl RenderOptions {
    /// The scene's settings with these options' overrides applied.
    pub fn effects(&self, scene: &Scene) -> Effects {
        Effects::resolve(&self.settings.or(scene.settings))
    }

    /// What the GPU shader is specialised for when rendering `scene`.
    pub fn features(&self, scene: &Scene) -> Features {
        if self.generic {
            Features::ALL
        } else {
            Features::of(scene, &self.effects(scene))
        }
    }
}
