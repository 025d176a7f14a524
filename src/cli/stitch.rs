use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use glint::images::framebuffer::{check_output, write_framebuffer, ImageFile};

#[derive(clap::Args, Debug)]
pub struct StitchArgs {
    /// The joined image (.png, .jpg, .ppm or .exr).
    out: PathBuf,
    /// Parts written by `glint render --crop` or `--part` (.png or .exr),
    /// joined in order; where parts overlap, the later one wins.
    #[arg(required_unless_present = "parts", conflicts_with = "parts")]
    files: Vec<PathBuf>,
    /// Join the N parts `glint render OUT --part I/N` wrote beside OUT
    /// (out.part00-of-N.png, ...); missing ones are named by index.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=i64::from(glint::parts::MAX_PARTS)))]
    parts: Option<u32>,
    /// With --parts: wait up to this many seconds for missing parts (tasks
    /// still running, or requeued) before giving up.
    #[arg(long, value_name = "SECONDS", requires = "parts", value_parser = super::values::parse_seconds)]
    wait: Option<f64>,
    /// JPEG quality (1-100).
    #[arg(long, default_value_t = glint::images::framebuffer::DEFAULT_JPEG_QUALITY, value_parser = clap::value_parser!(u8).range(1..=100))]
    quality: u8,
}

pub fn run(args: StitchArgs) -> anyhow::Result<ExitCode> {
    check_output(&args.out)?;
    let (paths, count) = match args.parts {
        Some(n) => {
            let wait = Duration::from_secs_f64(args.wait.unwrap_or(0.0));
            let mut waiting = |missing: &[u32]| {
                eprintln!(
                    "waiting for {} of {n} parts: {} (up to {:.0} s)",
                    missing.len(),
                    glint::parts::index_list(missing),
                    wait.as_secs_f64()
                );
            };
            let poll = Duration::from_secs(1);
            (
                glint::parts::find_parts(&args.out, n, wait, poll, &mut waiting)?,
                Some(n),
            )
        }
        None => (args.files.clone(), None),
    };
    let vetted = glint::parts::vet(&paths, count)?;
    let parts: Vec<&std::path::Path> = paths.iter().map(PathBuf::as_path).collect();
    let s = glint::parts::crop::stitch(&parts)?;
    if ImageFile::of(&args.out)?.is_float() && !s.float {
        eprintln!(
            "note: some parts are 8-bit, so {} holds their 8-bit values; render every part as .exr to keep floats",
            args.out.display()
        );
    }
    if !vetted.renderers.is_empty() {
        let who: Vec<String> = vetted
            .renderers
            .iter()
            .map(|(r, v)| format!("{} by {r}", glint::parts::index_list(v)))
            .collect();
        eprintln!(
            "note: the parts come from different renderers ({}); they agree within `glint \
             compare`'s tolerances, not bit for bit, so seams may differ by a level",
            who.join("; ")
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
