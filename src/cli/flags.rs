//! Flags more than one command declares, declared once here and
//! flattened into each (`#[command(flatten)]`).

use clap::{Args, ValueEnum};
use glint::gpu::DeviceSelector;
use glint::render::RenderOptions;
use glint::scene::{CameraSpec, Effects, Sampler, Scene, Settings};

use super::values::{parse_rgb, parse_xyz};

/// The image: its size and what rays that hit nothing show.
#[derive(Args, Clone, Copy, Debug)]
pub struct ImageArgs {
    #[arg(long, default_value_t = glint::camera::DEFAULT_WIDTH, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub width: u32,
    #[arg(long, default_value_t = glint::camera::DEFAULT_HEIGHT, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub height: u32,
    /// Colour of rays that hit nothing, as R,G,B in [0, 1].
    #[arg(long, default_value = "1,1,1", value_parser = parse_rgb)]
    pub background: [f32; 3],
}

/// The view, set over the scene's own camera (or the classic one, or a
/// model's framing): each flag given replaces that part of it.
#[derive(Args, Clone, Copy, Debug)]
pub struct CameraArgs {
    /// Where the camera is, as X,Y,Z in the scene's units.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_xyz)]
    pub eye: Option<[f64; 3]>,
    /// A point the camera looks at, as X,Y,Z.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_xyz)]
    pub look: Option<[f64; 3]>,
    /// Which way is up, as X,Y,Z (need not be perpendicular to the view).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_xyz)]
    pub up: Option<[f64; 3]>,
    /// Vertical field of view, degrees (above 0, below 180).
    #[arg(long, value_name = "DEGREES")]
    pub fov: Option<f64>,
}

impl CameraArgs {
    /// The scene's camera with the flags given put in; an error where the
    /// result cannot see (eye at look, up along the view, a bad angle).
    pub fn apply(&self, scene: &mut Scene) -> Result<(), glint::Error> {
        if self.eye.is_none() && self.look.is_none() && self.up.is_none() && self.fov.is_none() {
            return Ok(());
        }
        let mut camera = scene.camera.unwrap_or(CameraSpec::CLASSIC);
        camera.eye = self.eye.map_or(camera.eye, glam::DVec3::from);
        camera.look = self.look.map_or(camera.look, glam::DVec3::from);
        camera.up = self.up.map_or(camera.up, glam::DVec3::from);
        camera.fov = self.fov.unwrap_or(camera.fov);
        if !(camera.fov > 0.0 && camera.fov < 180.0) {
            return Err(glint::Error::InvalidOption(format!(
                "--fov must be above 0 and below 180 degrees, found {}",
                camera.fov
            )));
        }
        if camera.basis().is_none() {
            return Err(glint::Error::InvalidOption(format!(
                "the camera cannot see: eye {} looks at {} with up {}; move --look off the \
                 eye, or give an --up that is not along the view",
                camera.eye, camera.look, camera.up
            )));
        }
        scene.camera = Some(camera);
        Ok(())
    }
}

/// Where the render runs.
#[derive(Args, Clone, Debug)]
pub struct DeviceArgs {
    /// auto: the best hardware Vulkan device; the CPU reference when there is
    /// none or only a software one such as lavapipe (with a note).
    #[arg(long, value_enum, default_value = "auto")]
    pub backend: BackendArg,
    /// Vulkan device by index or name (see `glint devices`).
    #[arg(long)]
    pub device: Option<String>,
    /// CPU reference arithmetic: f32 follows the shader, f64 is ground truth.
    #[arg(long, value_enum, default_value = "f32")]
    pub precision: PrecisionArg,
    /// Enable the Vulkan validation layer (when installed) and report its messages.
    #[arg(long)]
    pub validation: bool,
}

/// The render options these flags (and `GLINT_VALIDATION`) decide; the
/// rest are the defaults, with the pipeline and scene caches where the
/// environment puts them.
pub fn render_options(
    image: &ImageArgs,
    device: &DeviceArgs,
    effects: &EffectArgs,
) -> anyhow::Result<RenderOptions> {
    let scene_cache = glint::scene_cache::SceneCache::from_env().map_err(anyhow::Error::msg)?;
    Ok(RenderOptions {
        width: image.width,
        height: image.height,
        background: image.background,
        backend: device.backend.into(),
        device: device.device.as_deref().map(DeviceSelector::parse),
        precision: device.precision.into(),
        validation: device.validation || std::env::var_os("GLINT_VALIDATION").is_some(),
        settings: effects.settings(),
        pipeline_cache: glint::gpu::cache::default_dir(),
        scene_cache,
        ..RenderOptions::default()
    })
}

/// Overrides of a scene's render settings (its `reflect:`, `spp:`, ...
/// lines); see docs/scene-format.md.
#[derive(Args, Clone, Copy, Debug, Default)]
pub struct EffectArgs {
    /// Reflection depth in bounces; 0 turns reflection off.
    #[arg(long, value_name = "D", value_parser = clap::value_parser!(u32).range(0..=Effects::MAX_REFLECT as i64))]
    pub reflect: Option<u32>,
    /// Samples per pixel (antialiasing; also motion-blur time samples).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=Effects::MAX_SPP as i64))]
    pub spp: Option<u32>,
    /// Shadow rays per area light per shaded point (default 16).
    #[arg(long, value_name = "M", value_parser = clap::value_parser!(u32).range(1..=Effects::MAX_SHADOW_SAMPLES as i64))]
    pub shadow_samples: Option<u32>,
    /// Fraction of the frame interval the shutter is open: 0 (no motion
    /// blur) to 1.
    #[arg(long, value_name = "S", value_parser = parse_shutter)]
    pub shutter: Option<f64>,
    /// Seed of every random sample; the same seed gives the same image.
    #[arg(long, value_name = "K")]
    pub seed: Option<u32>,
    /// Frames per second: frame i shows the scene at time i / fps.
    #[arg(long, value_name = "F", value_parser = parse_fps)]
    pub fps: Option<f64>,
    /// How samples are drawn: sobol (the default; Owen-scrambled Sobol
    /// points) or stratified (jittered grids, glint's images before sobol).
    #[arg(long, value_name = "NAME", value_parser = parse_sampler)]
    pub sampler: Option<Sampler>,
}

impl EffectArgs {
    pub fn settings(&self) -> Settings {
        Settings {
            reflect: self.reflect,
            spp: self.spp,
            shadow_samples: self.shadow_samples,
            shutter: self.shutter,
            seed: self.seed,
            fps: self.fps,
            sampler: self.sampler,
        }
    }
}

fn parse_sampler(s: &str) -> Result<Sampler, String> {
    Sampler::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = Sampler::ALL.iter().map(|s| s.name()).collect();
        format!(
            "unknown sampler `{s}`; the samplers are {}",
            names.join(", ")
        )
    })
}

fn parse_shutter(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        _ => Err(format!("expected a fraction from 0 to 1, found `{s}`")),
    }
}

fn parse_fps(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
        _ => Err(format!(
            "expected a positive number of frames per second, found `{s}`"
        )),
    }
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum BackendArg {
    Auto,
    Gpu,
    Cpu,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum MethodsArg {
    Robust,
    Naive,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum PrecisionArg {
    F32,
    F64,
}

impl From<BackendArg> for glint::render::Backend {
    fn from(b: BackendArg) -> Self {
        match b {
            BackendArg::Auto => Self::Auto,
            BackendArg::Gpu => Self::Gpu,
            BackendArg::Cpu => Self::Cpu,
        }
    }
}

impl From<PrecisionArg> for glint::cpu::Precision {
    fn from(p: PrecisionArg) -> Self {
        match p {
            PrecisionArg::F32 => Self::F32,
            PrecisionArg::F64 => Self::F64,
        }
    }
}
