//! `render --frames`: an animation's frames rendered one after the other
//! on one `Renderer`, each encoded and written on a worker while the next
//! renders (`glint::images::write_queue`).

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use anyhow::Context as _;
use glint::render::RenderOutput;
use glint::render::{Frames, Job, Renderer, Sink, Target, Watch};
use indicatif::{ProgressBar, ProgressStyle};

use super::RenderArgs;
use crate::cli::{print_warnings, read_scene};

/// `--frames N`: checks the range and OUT (the frames' directory, by
/// default `<scene stem>_frames`) before any work, then renders the
/// frames with one `Renderer` (device and pipelines built once) as one
/// job, a progress bar over them.
pub(super) fn run(
    args: &RenderArgs,
    count: u32,
    out: &Path,
    defaulted: bool,
) -> anyhow::Result<ExitCode> {
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
    let part = args
        .part
        .as_ref()
        .map(crate::cli::part::resolve)
        .transpose()?;
    let frames = Frames {
        count,
        range: args.frame_range,
        part,
    };
    let format = args.frame_format.kind();
    let sink = Sink::Frames {
        dir: dir.clone(),
        format,
        encode: args.encode_options(),
    };
    sink.check(&Target::Frames(frames))?;
    let Some([first, last]) = frames.share()? else {
        if let Some(part) = part {
            println!(
                "{part} has no frames ({} parts share {count} frames); nothing to do",
                part.count
            );
        }
        return Ok(ExitCode::SUCCESS);
    };
    let mut scene = read_scene(&args.scene)?;
    args.camera.apply(&mut scene)?;
    print_warnings(&scene);
    let options = args.options()?;
    let renderer = Renderer::new(&options)?;
    if let Some(note) = renderer.note() {
        eprintln!("note: {note}");
    }
    if !scene.has_motion() {
        eprintln!(
            "note: nothing in {} moves (no `vel:`); every frame is the same image",
            args.scene.display()
        );
    }
    let watch = FrameBar::new(u64::from(last - first + 1), args.verbose);
    let start = Instant::now();
    let job = Job::new(&scene).frames(frames);
    let result = renderer.run(&job, &sink, &watch);
    let done = result.context("rendering the frames")?;
    let Some(f) = &done.frames else {
        unreachable!("a frames job reports its frames");
    };
    if args.verbose {
        watch.bar.suspend(|| {
            eprintln!(
                "all frames, rendered:\n{}\nencoded and written on the writers beside the renders:\n{}",
                f.render_timings, f.write_timings
            )
        });
    }
    watch.bar.finish_and_clear();
    let shown = |i| frames.path(Path::new(""), i, format);
    println!(
        "wrote frames {}..{} to {} ({}x{}, {}, {:.2} s, {} fps scene time)",
        shown(first).with_extension("").display(),
        shown(last).display(),
        dir.display(),
        args.image.width,
        args.image.height,
        renderer.name(),
        start.elapsed().as_secs_f64(),
        options.effects(&scene).fps
    );
    if let Some(part) = part {
        println!(
            "({part} of the frames; {} of them were already there and kept)",
            f.kept
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// Frames done (kept, or written behind the renders) over all of them;
/// with -v, each frame's timings.
struct FrameBar {
    bar: ProgressBar,
    kept: AtomicU64,
    verbose: bool,
}

impl FrameBar {
    fn new(frames: u64, verbose: bool) -> FrameBar {
        let bar = ProgressBar::new(frames);
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} frames [{bar:30}] {pos}/{len} {elapsed} (eta {eta})",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
        FrameBar {
            bar,
            kept: AtomicU64::new(0),
            verbose,
        }
    }
}

impl Watch for FrameBar {
    fn frame(&self, index: u32, output: Option<&RenderOutput>) {
        match output {
            None => {
                let kept = self.kept.fetch_add(1, Ordering::Relaxed) + 1;
                self.bar.set_position(kept);
            }
            Some(o) if self.verbose => {
                self.bar
                    .suspend(|| eprintln!("frame {index}:\n{}", o.timings));
            }
            Some(_) => {}
        }
    }

    fn frames_written(&self, count: u32) {
        self.bar
            .set_position(self.kept.load(Ordering::Relaxed) + u64::from(count));
    }
}
