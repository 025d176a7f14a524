//! `glint view SCENE [OUT]`: the render refining in a window, as the course
//! program showed it on screen; OUT, when given, is written too.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use glint::progressive::StopAt;
use glint::render::RenderOptions;

use super::values::{parse_error_target, parse_rgb, parse_seconds};
use super::{BackendArg, EffectArgs, PrecisionArg};

#[derive(clap::Args, Debug)]
pub struct ViewArgs {
    /// Scene file in the classic format; `-` reads it from standard input.
    scene: PathBuf,
    /// Also write the image here when the refinement stops (and when the
    /// window closes): .png, .jpg, .ppm or .exr.
    out: Option<PathBuf>,
    #[arg(long, default_value_t = glint::camera::DEFAULT_WIDTH, value_parser = clap::value_parser!(u32).range(1..=16384))]
    width: u32,
    #[arg(long, default_value_t = glint::camera::DEFAULT_HEIGHT, value_parser = clap::value_parser!(u32).range(1..=16384))]
    height: u32,
    /// auto: the best hardware Vulkan device, else the CPU reference.
    #[arg(long, value_enum, default_value = "auto")]
    backend: BackendArg,
    /// Vulkan device by index or name (see `glint devices`).
    #[arg(long)]
    device: Option<String>,
    /// CPU reference arithmetic.
    #[arg(long, value_enum, default_value = "f32")]
    precision: PrecisionArg,
    /// Colour of rays that hit nothing, as R,G,B in [0, 1].
    #[arg(long, default_value = "1,1,1", value_parser = parse_rgb)]
    background: [f32; 3],
    /// Stop refining once the estimated RMSE (linear, 0-1) is at most E.
    #[arg(long, value_name = "E", value_parser = parse_error_target)]
    target_error: Option<f64>,
    /// Stop refining before a pass would end after S seconds.
    #[arg(long, value_name = "S", value_parser = parse_seconds)]
    time_limit: Option<f64>,
    /// With --target-error: passes only where the noise is.
    #[arg(long, requires = "target_error")]
    adaptive: bool,
    /// Draw the window through the host (softbuffer), even where the
    /// Vulkan device can present to it: the image is read back and drawn
    /// by the CPU, as on the CPU reference.
    #[arg(long)]
    host_draws: bool,
    /// Enable the Vulkan validation layer (when installed); its messages
    /// are printed as they come.
    #[arg(long)]
    validation: bool,
    /// GPU tile edge, fixed (default: the driver profile's, made smaller by the window where a view
    /// change would wait over 100 ms for the tiles in flight)
    #[arg(long, value_parser = clap::value_parser!(u32).range(8..=2048))]
    tile: Option<u32>,
    #[command(flatten)]
    effects: EffectArgs,
}

pub fn run(args: ViewArgs) -> anyhow::Result<ExitCode> {
    let scene = super::read_scene(&args.scene)?;
    super::print_warnings(&scene);
    if let Some(out) = &args.out {
        glint::framebuffer::check_output(out)?;
    }
    let render = RenderOptions {
        width: args.width,
        height: args.height,
        background: args.background,
        backend: args.backend.into(),
        device: args
            .device
            .as_deref()
            .map(glint::gpu::DeviceSelector::parse),
        precision: args.precision.into(),
        settings: args.effects.settings(),
        tile: args.tile,
        validation: args.validation || std::env::var_os("GLINT_VALIDATION").is_some(),
        pipeline_cache: glint::gpu::cache::default_dir(),
        ..RenderOptions::default()
    };
    let stem = match args.scene.file_stem() {
        Some(s) if args.scene.as_os_str() != "-" => PathBuf::from(s),
        _ => PathBuf::from("stdin"),
    };
    glint::view::view(
        scene,
        glint::view::ViewOptions {
            render,
            stop: StopAt {
                target_rmse: args.target_error,
                time_limit: args.time_limit.map(Duration::from_secs_f64),
                adaptive: args.adaptive,
            },
            out: args.out,
            save_stem: stem,
            host_draws: args.host_draws,
        },
    )?;
    Ok(ExitCode::SUCCESS)
}
