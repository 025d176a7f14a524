//! `glint render`: the flags become a `Job` and a `Sink`, `Renderer::run`
//! carries them out, and what it did is reported here. Animations
//! (`frames`) and a pixel's path (`pixel`) are their own ideas.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use glint::render::passes::{PassReport, StopAt};
use glint::render::{Job, Renderer, Sink, Stop, Target, Watch};
use indicatif::{ProgressBar, ProgressStyle};

mod args;
mod frames;
mod pixel;
mod report;

pub use args::RenderArgs;

use super::print_warnings;

/// Where a render's messages go: stdout, unless the image goes there.
#[derive(Clone, Copy)]
struct Say {
    to_stderr: bool,
}

impl Say {
    fn line(self, s: impl std::fmt::Display) {
        if self.to_stderr {
            eprintln!("{s}");
        } else {
            println!("{s}");
        }
    }
}

/// `<scene stem>.jpg`, or `stdin.jpg` for a scene read from standard input.
fn default_output(scene: &Path) -> PathBuf {
    if scene == Path::new("-") {
        return PathBuf::from("stdin.jpg");
    }
    let stem = scene.file_stem().unwrap_or(scene.as_os_str());
    PathBuf::from(stem).with_extension("jpg")
}

pub fn run(args: RenderArgs) -> anyhow::Result<ExitCode> {
    let args = args.resolved();
    let (out, defaulted) = match args.out.clone().or(args.output.clone()) {
        Some(p) => (p, false),
        None => (default_output(&args.scene), true),
    };
    let to_stdout = out == Path::new("-");
    if let Some(frames) = args.frames {
        if to_stdout {
            return Err(glint::Error::InvalidOption(
                "--frames writes a directory of images; `-` (standard output) holds one image"
                    .into(),
            )
            .into());
        }
        return frames::run(&args, frames, &out, defaulted);
    }
    if let Some(pixel) = args.pixel {
        return pixel::run(&args, pixel);
    }
    let sink = if to_stdout {
        use std::io::IsTerminal;
        if std::io::stdout().is_terminal() {
            return Err(glint::Error::InvalidOption(
                "`-` writes a PNG to standard output, which is a terminal here; \
                 redirect it (`> out.png`) or pipe it to a program"
                    .into(),
            )
            .into());
        }
        Sink::Stdout(args.encode_options())
    } else {
        Sink::File {
            path: out,
            encode: args.encode_options(),
        }
    };
    let target = match (&args.crop, &args.part) {
        (Some(crop), _) => Target::Crop(*crop),
        (None, Some(part)) => Target::Part(super::part::resolve(part)?),
        (None, None) => Target::Image,
    };
    // Everything the arguments alone decide is checked before any work.
    sink.check(&target)?;
    if let Target::Crop(crop) = &target {
        crop.check(args.image.width, args.image.height)?;
    }
    let parse_start = Instant::now();
    let (mut scene, arrival) = super::read_scene_timed(&args.scene)?;
    args.camera.apply(&mut scene)?;
    let parse_time = parse_start.elapsed();
    print_warnings(&scene);
    let options = args.options()?;
    let stop = match (args.target_error, args.time_limit) {
        (None, None) => Stop::Once,
        (target_rmse, time_limit) => Stop::Passes(StopAt {
            target_rmse,
            time_limit: time_limit.map(Duration::from_secs_f64),
            adaptive: args.adaptive,
        }),
    };
    let job = Job {
        scene: &scene,
        target,
        stop,
    };
    if let (Target::Part(part), Sink::File { path, .. }) = (&target, &sink) {
        if super::part::already_done(&job, &options, *part, path) {
            return Ok(ExitCode::SUCCESS);
        }
    }
    let start = Instant::now();
    let renderer = Renderer::new(&options)?;
    if let Some(note) = renderer.note() {
        eprintln!("note: {note}");
    }
    let watch = Bar::new(stop, args.verbose);
    let result = renderer.run(&job, &sink, &watch);
    watch.bar.finish_and_clear();
    let mut done = result.with_context(|| format!("rendering {}", args.scene.display()))?;
    let timings = &mut done.output.timings;
    timings.phases.splice(0..0, arrival.phases);
    timings.counts.splice(0..0, arrival.counts);
    let say = Say {
        to_stderr: to_stdout,
    };
    let code = report::report(
        &args,
        &job,
        &done,
        defaulted,
        start.elapsed() + parse_time,
        say,
    );
    if args.show {
        let shown = done.written.as_deref().unwrap_or(Path::new("-"));
        let title = format!("{} ({})", shown.display(), done.output.renderer);
        glint::view::show(done.output.framebuffer().into_owned(), title)?;
    }
    Ok(code)
}

/// The progress bar: a bar over pixels for one render (shown once it has
/// run half a second, as short renders finish before it would help), a
/// spinner over passes.
struct Bar {
    bar: ProgressBar,
    started: Instant,
    verbose: bool,
}

impl Bar {
    fn new(stop: Stop, verbose: bool) -> Bar {
        let (bar, template) = match stop {
            Stop::Once => (
                ProgressBar::new(0),
                "{spinner} rendering [{bar:30}] {percent:>3}% {elapsed} (eta {eta})",
            ),
            Stop::Passes(_) => (ProgressBar::new_spinner(), "{spinner} {msg} {elapsed}"),
        };
        bar.set_style(
            ProgressStyle::with_template(template)
                .expect("valid template")
                .progress_chars("=> "),
        );
        Bar {
            bar,
            started: Instant::now(),
            verbose,
        }
    }
}

impl Watch for Bar {
    fn progress(&self, done: u64, total: u64) {
        if self.started.elapsed() > Duration::from_millis(500) {
            self.bar.set_length(total);
            self.bar.set_position(done);
        }
    }

    fn pass(&self, r: &PassReport) {
        let estimate = r
            .estimated_rmse
            .map_or_else(|| "-".to_string(), |e| format!("{e:.5}"));
        let mut line = format!(
            "pass {}, {} samples per pixel, estimated RMSE {estimate}",
            r.passes, r.samples_per_pixel
        );
        if r.active_blocks[0] < r.active_blocks[1] {
            line.push_str(&format!(
                " ({:.1} samples per pixel on average; next pass: {} of {} blocks)",
                r.mean_samples, r.active_blocks[0], r.active_blocks[1]
            ));
        }
        if self.verbose {
            self.bar
                .suspend(|| eprintln!("{line}, {:.2} s", r.elapsed.as_secs_f64()));
        }
        self.bar.set_message(line);
        self.bar.tick();
    }
}
