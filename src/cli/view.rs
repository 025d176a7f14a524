//! `glint view SCENE [OUT]`: the render refining in a window, as the course
//! program showed it on screen; OUT, when given, is written too.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use glint::render::passes::StopAt;
use glint::render::RenderOptions;

use super::values::{parse_error_target, parse_seconds};
use super::{CameraArgs, DeviceArgs, EffectArgs, ImageArgs};

#[derive(clap::Args, Debug)]
pub struct ViewArgs {
    /// Scene file in the classic format, or a model file (.obj, .ply, .off, .stl, .gltf,
    /// .glb) seen alone, framed; `-` reads a scene from standard input.
    scene: PathBuf,
    /// Also write the image here when the refinement stops (and when the
    /// window closes): .png, .jpg, .ppm or .exr.
    out: Option<PathBuf>,
    #[command(flatten)]
    image: ImageArgs,
    #[command(flatten)]
    device: DeviceArgs,
    #[command(flatten)]
    camera: CameraArgs,
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
    /// GPU tile edge, fixed (default: the driver profile's, made smaller by the window where a view
    /// change would wait over 100 ms for the tiles in flight)
    #[arg(long, value_parser = clap::value_parser!(u32).range(8..=2048))]
    tile: Option<u32>,
    #[command(flatten)]
    effects: EffectArgs,
}

pub fn run(args: ViewArgs) -> anyhow::Result<ExitCode> {
    let mut scene = super::read_scene(&args.scene)?;
    args.camera.apply(&mut scene)?;
    super::print_warnings(&scene);
    if let Some(out) = &args.out {
        glint::images::framebuffer::check_output(out)?;
    }
    let render = RenderOptions {
        tile: args.tile,
        ..super::flags::render_options(&args.image, &args.device, &args.effects)?
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
