use std::path::PathBuf;
use std::process::ExitCode;

use glint::framebuffer::{check_output, write_framebuffer, ImageFile};

#[derive(clap::Args, Debug)]
pub struct StitchArgs {
    /// The joined image (.png, .jpg, .ppm or .exr).
    out: PathBuf,
    /// Parts written by `glint render --crop` (.png or .exr), joined in
    /// order; where parts overlap, the later one wins.
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// JPEG quality (1-100).
    #[arg(long, default_value_t = glint::framebuffer::DEFAULT_JPEG_QUALITY, value_parser = clap::value_parser!(u8).range(1..=100))]
    quality: u8,
}

pub fn run(args: StitchArgs) -> anyhow::Result<ExitCode> {
    check_output(&args.out)?;
    let parts: Vec<&std::path::Path> = args.parts.iter().map(PathBuf::as_path).collect();
    let s = glint::region::stitch(&parts)?;
    if ImageFile::of(&args.out)?.is_float() && !s.float {
        eprintln!(
            "note: some parts are 8-bit, so {} holds their 8-bit values; render every part as .exr to keep floats",
            args.out.display()
        );
    }
    write_framebuffer(&s.image, &args.out, args.quality)?;
    println!(
        "wrote {} ({}x{}, from {} parts)",
        args.out.display(),
        s.image.width,
        s.image.height,
        parts.len()
    );
    if s.overlapping > 0 {
        println!(
            "note: {} pixels are held by more than one part ({} of them with other values; the later part won)",
            s.overlapping, s.disagreeing
        );
    }
    Ok(ExitCode::SUCCESS)
}
