use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;
use glint::images::compare::{compare_framebuffers, compare_images};
use glint::images::framebuffer::{read_framebuffer, read_image, write_image, ImageFile};

#[derive(Args, Debug)]
pub struct CompareArgs {
    /// Reference image (.png, .jpg, .ppm or float .exr).
    a: PathBuf,
    /// Image to check against it.
    b: PathBuf,
    /// Write a difference image here (.png recommended): the reference
    /// faded to grey, differences as a heat map, lone bad pixels ringed.
    #[arg(long)]
    diff: Option<PathBuf>,
    /// Per-channel difference (0-255 levels) above which a pixel counts as differing.
    #[arg(long, default_value_t = 1.0)]
    threshold: f64,
    /// Exit with status 1 when any pixel exceeds the threshold.
    #[arg(long)]
    fail: bool,
}

pub fn run(args: CompareArgs) -> anyhow::Result<ExitCode> {
    // Float files compare on their values; two 8-bit files on their levels
    // exactly (v / 255 in f32 would blur a threshold of whole levels).
    let float = ImageFile::of(&args.a)?.is_float() || ImageFile::of(&args.b)?.is_float();
    let cmp = if float {
        let a = read_framebuffer(&args.a)?;
        let b = read_framebuffer(&args.b)?;
        compare_framebuffers(&a, &b, args.threshold)?
    } else {
        compare_images(&read_image(&args.a)?, &read_image(&args.b)?, args.threshold)?
    };
    println!("{cmp}");
    if let Some(path) = &args.diff {
        write_image(&cmp.diff_image(&read_image(&args.a)?), path, 95)?;
        println!(
            "wrote {}: {} faded to grey, differing pixels coloured dark purple (smallest) to pale \
             yellow ({:.3} levels){}",
            path.display(),
            args.a.display(),
            cmp.diff_scale(),
            if cmp.over_threshold > 0 {
                ", each pixel over the threshold ringed when they are few"
            } else {
                ""
            }
        );
    }
    if args.fail && cmp.over_threshold > 0 {
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}
