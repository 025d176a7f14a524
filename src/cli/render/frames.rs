//! `render --frames`: an animation's frames rendered one after the other
//! on one `Renderer`, each encoded and written on a worker while the next
//! renders (`glint::write_queue`).

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

use anyhow::Context as _;
use glint::render::{RenderOptions, Renderer};
use glint::scene::Scene;
use glint::write_queue::{Encoded, WriteQueue};
use indicatif::{ProgressBar, ProgressStyle};

use super::RenderArgs;
use crate::cli::{print_warnings, read_scene, validation_verdict};

/// Threads that encode and write frames: two keep one frame encoding while
/// the next is handed over; JPEG's strips run on the render's thread pool
/// beside the render, so more writers add no cores.
const WRITERS: usize = 2;

/// `--frames N`: checks the range and OUT (the frames' directory, by
/// default `<scene stem>_frames`), then renders the animation.
pub(super) fn run(
    args: &RenderArgs,
    frames: u32,
    out: &Path,
    defaulted: bool,
) -> anyhow::Result<ExitCode> {
    check_frames(args, frames, out, defaulted)?;
    let scene = read_scene(&args.scene)?;
    print_warnings(&scene);
    let dir = if defaulted {
        let stem = match args.scene.to_str() {
            Some("-") => "stdin".into(),
            _ => args
                .scene
                .file_stem()
                .unwrap_or(args.scene.as_os_str())
                .to_string_lossy(),
        };
        PathBuf::from(format!("{stem}_frames"))
    } else {
        out.to_path_buf()
    };
    let options = RenderOptions {
        pixels: glint::render::PixelFormat::for_file(args.frame_format.kind()),
        ..args.options()
    };
    animate(&scene, &options, args, frames, &dir)
}

/// `--frames`: the range fits and OUT can be the frames' directory.
fn check_frames(args: &RenderArgs, frames: u32, out: &Path, defaulted: bool) -> anyhow::Result<()> {
    let invalid = |m: String| -> anyhow::Error { glint::Error::InvalidOption(m).into() };
    if let Some([first, last]) = args.frame_range {
        if last >= frames {
            return Err(invalid(format!(
                "--frame-range {first}-{last} goes past the last frame of --frames {frames} \
                 (frames count from 0, so the last is {})",
                frames - 1
            )));
        }
    }
    if defaulted {
        return Ok(());
    }
    let bad = |reason: String| -> anyhow::Error {
        glint::Error::BadOutput {
            path: out.to_path_buf(),
            reason,
        }
        .into()
    };
    if glint::framebuffer::ImageFile::of(out).is_ok() {
        return Err(bad(
            "with --frames, the output is a directory for 000.jpg, 001.jpg, ...; this is an image name".into(),
        ));
    }
    if out.exists() && !out.is_dir() {
        return Err(bad(
            "with --frames, the output is a directory for 000.jpg, 001.jpg, ...; this is a file"
                .into(),
        ));
    }
    Ok(())
}

/// Renders frames of an animation with one `Renderer` (device and pipelines
/// built once), a progress bar over frames, each frame written as it is done.
fn animate(
    scene: &Scene,
    options: &RenderOptions,
    args: &RenderArgs,
    frames: u32,
    dir: &Path,
) -> anyhow::Result<ExitCode> {
    let share = match &args.part {
        Some(part) => {
            let part = crate::cli::part::resolve(part)?;
            match glint::parts::cut::frame_share(frames, part.index, part.count) {
                Some(share) => Some((part, share)),
                None => {
                    println!(
                        "{part} has no frames ({} parts share {frames} frames); nothing to do",
                        part.count
                    );
                    return Ok(ExitCode::SUCCESS);
                }
            }
        }
        None => None,
    };
    let [first, last] = share.map_or(args.frame_range.unwrap_or([0, frames - 1]), |s| s.1);
    std::fs::create_dir_all(dir)
        .with_context(|| format!("creating the frame directory {}", dir.display()))?;
    if share.is_some() {
        let settings = format!(
            "{} frames {frames}",
            glint::render::settings_text(options, scene)
        );
        let digest = glint::parts::stamp::render_digest(scene, &settings);
        crate::cli::part::claim_frames(dir, &digest)?;
    }
    let renderer = Renderer::new(options)?;
    if let Some(note) = renderer.note() {
        eprintln!("note: {note}");
    }
    let effects = options.effects(scene);
    if !scene.has_motion() {
        eprintln!(
            "note: nothing in {} moves (no `vel:`); every frame is the same image",
            args.scene.display()
        );
    }
    let digits = (frames - 1).to_string().len().max(3);
    let ext = args.frame_extension();
    let bar = ProgressBar::new(u64::from(last - first + 1));
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} frames [{bar:30}] {pos}/{len} {elapsed} (eta {eta})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    let start = Instant::now();
    let mut kept = 0;
    // Frames are encoded and written on workers while the next renders.
    let written = bar.clone();
    let queue = WriteQueue::new(WRITERS, move |_| written.inc(1));
    let kind = args.frame_format.kind();
    // Nothing moves: one render and one encode serve every frame.
    let mut still: Option<Arc<Encoded>> = None;
    let mut render_timings = glint::timing::Timings::default();
    for i in first..=last {
        let path = dir.join(format!("{i:0digits$}.{ext}"));
        // A requeued task of an array keeps the frames it finished.
        if share.is_some() && crate::cli::part::frame_done(&path) {
            kept += 1;
            bar.inc(1);
            continue;
        }
        let frame = match &still {
            Some(frame) => frame.clone(),
            None => {
                let at = scene.at_time(effects.frame_time(i));
                let output = match renderer.render(&at, &|_, _| {}) {
                    Ok(output) => output,
                    // Frames already handed over are still written whole.
                    Err(e) => {
                        let _ = queue.finish();
                        return Err(anyhow::Error::from(e).context(format!("rendering frame {i}")));
                    }
                };
                validation_verdict(renderer.validation_messages())
                    .with_context(|| format!("rendering frame {i}"))?;
                if args.verbose {
                    bar.suspend(|| eprintln!("frame {i}:\n{}", output.timings));
                }
                render_timings.extend(&output.timings);
                let frame = Encoded::new(output.image, kind, args.encode_options());
                if !scene.has_motion() {
                    still = Some(frame.clone());
                }
                frame
            }
        };
        queue
            .push(&frame, path)
            .with_context(|| format!("writing frame {i}"))?;
    }
    let write_timings = queue.finish().context("writing the frames")?;
    if args.verbose {
        bar.suspend(|| {
            eprintln!(
                "all frames, rendered:\n{render_timings}\nencoded and written on {WRITERS} workers beside the renders:\n{write_timings}"
            )
        });
    }
    bar.finish_and_clear();
    println!(
        "wrote frames {first:0digits$}..{last:0digits$}.{ext} to {} ({}x{}, {}, {:.2} s, {} fps scene time)",
        dir.display(),
        args.image.width,
        args.image.height,
        renderer.name(),
        start.elapsed().as_secs_f64(),
        effects.fps
    );
    if let Some((part, _)) = share {
        println!("({part} of the frames; {kept} of them were already there and kept)");
    }
    Ok(ExitCode::SUCCESS)
}
