//! `glint render --pixel X,Y`: one pixel's path on the chosen backend,
//! printed; no image.

use std::process::ExitCode;
use std::time::Instant;

use glint::render::pixel_path;

use super::RenderArgs;
use crate::cli::{print_warnings, read_scene};

pub(super) fn run(args: &RenderArgs, pixel: [u32; 2]) -> anyhow::Result<ExitCode> {
    let (w, h) = (args.image.width, args.image.height);
    if pixel[0] >= w || pixel[1] >= h {
        return Err(glint::Error::InvalidOption(format!(
            "pixel {},{} is outside the {w}x{h} image (x counts from 0 at the left, y from 0 at the top)",
            pixel[0], pixel[1]
        ))
        .into());
    }
    let mut scene = read_scene(&args.scene)?;
    args.camera.apply(&mut scene)?;
    print_warnings(&scene);
    let options = args.options()?;
    let start = Instant::now();
    let probed = pixel_path(&scene, &options, pixel)?;
    if let Some(note) = &probed.note {
        eprintln!("note: {note}");
    }
    println!(
        "pixel {},{} of {w}x{h} on {} ({} methods)",
        pixel[0], pixel[1], probed.renderer, options.methods
    );
    print!("{}", probed.value);
    let listed = probed.value.lights.len();
    if probed.value.surface.is_some() && listed < scene.lights.len() {
        println!(
            "({} more lights not listed; the colour includes them all)",
            scene.lights.len() - listed
        );
    }
    let rgb = probed.value.color.map(|c| c.clamp(0.0, 1.0) as f32);
    let [r, g, b] = rgb.map(glint::images::framebuffer::to_u8);
    println!("8-bit value ({r}, {g}, {b})");
    if probed.validation_messages > 0 {
        return Err(glint::Error::Validation(probed.validation_messages).into());
    }
    if args.verbose {
        println!("took {:.1} ms", start.elapsed().as_secs_f64() * 1e3);
    }
    Ok(ExitCode::SUCCESS)
}
