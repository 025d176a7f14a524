//! What `glint render` says of a finished job: where the image went, how
//! long it took, and for passes why they stopped.

use std::path::Path;
use std::process::ExitCode;
use std::time::Duration;

use glint::images::framebuffer::ImageFile;
use glint::render::passes::Stopped;
use glint::render::{Done, Job, Passes, Target};

use super::{RenderArgs, Say};

/// Prints the report; exit 1 where passes stopped at the sample cap short
/// of the target (the image is written, but not as accurate as asked).
pub(super) fn report(
    args: &RenderArgs,
    job: &Job,
    done: &Done,
    defaulted: bool,
    elapsed: Duration,
    say: Say,
) -> ExitCode {
    let out = &done.output;
    let written = done.written.as_deref().unwrap_or(Path::new("-"));
    let default_name = if defaulted {
        " (default name: <scene>.jpg)"
    } else {
        ""
    };
    let (w, h) = (args.image.width, args.image.height);
    let mut code = ExitCode::SUCCESS;
    match (&done.passes, done.span, job.target) {
        (Some(passes), ..) => {
            say.line(passes_line(
                args,
                passes,
                written,
                default_name,
                &out.renderer,
                elapsed,
            ));
        }
        (None, Some(span), Target::Part(part)) => {
            let whole = args.out.clone().or(args.output.clone());
            let whole = whole.unwrap_or_else(|| super::default_output(&args.scene));
            say.line(format!(
                "wrote {} ({part} of {w}x{h}: {span}, {} pixels; {}, {:.1} ms); join with `glint stitch {} --parts {}`",
                written.display(),
                span.pixels(),
                out.renderer,
                elapsed.as_secs_f64() * 1e3,
                whole.display(),
                part.count
            ));
        }
        (None, _, target) => {
            let what = match target {
                Target::Crop(c) => format!("pixels {c} of {w}x{h}, a part for `glint stitch`"),
                _ => format!("{w}x{h}"),
            };
            say.line(format!(
                "wrote {}{default_name} ({what}, {}, {:.1} ms)",
                written.display(),
                out.renderer,
                out.timings.total().as_secs_f64() * 1e3
            ));
        }
    }
    if args.verbose {
        let label = if done.passes.is_some() {
            "timings (all passes)"
        } else {
            "timings"
        };
        say.line(format!("{label}:\n{}", out.timings));
        say.line(format!(
            "memory:\n  {} beyond the scene and its BVH",
            out.memory
        ));
    }
    if args.stats || args.verbose {
        say.line(crate::cli::summary::stats(out, &out.timings));
    }
    if let Some(passes) = &done.passes {
        if !stopped(args, passes, say) {
            code = ExitCode::from(1);
        }
        let eight_bit = ImageFile::of(written).map_or(true, |f| !f.is_float());
        if eight_bit && passes.report.estimated_rmse.is_some_and(|e| e < 0.002) {
            say.line(
                "note: 8-bit output adds about 0.0011 RMSE of rounding; write .exr to keep the float image"
            );
        }
    }
    code
}

fn passes_line(
    args: &RenderArgs,
    passes: &Passes,
    written: &Path,
    default_name: &str,
    renderer: &str,
    elapsed: Duration,
) -> String {
    let r = &passes.report;
    let estimate = r
        .estimated_rmse
        .map_or_else(|| "none (one pass)".to_string(), |e| format!("{e:.5}"));
    let samples = if args.adaptive {
        format!(
            "{:.1} samples per pixel on average, at most {}",
            r.mean_samples, r.samples_per_pixel
        )
    } else {
        format!("{} samples per pixel", r.samples_per_pixel)
    };
    format!(
        "wrote {}{default_name} ({}x{}, {renderer}, {} passes, {samples}, estimated RMSE {estimate}, {:.2} s)",
        written.display(),
        args.image.width,
        args.image.height,
        r.passes,
        elapsed.as_secs_f64()
    )
}

/// Says why the passes stopped; false where the target was asked for and
/// the sample cap came first.
fn stopped(args: &RenderArgs, passes: &Passes, say: Say) -> bool {
    let reached = match (args.target_error, passes.report.estimated_rmse) {
        (Some(t), Some(e)) => e <= t,
        (Some(_), None) => false,
        (None, _) => true,
    };
    let target = args.target_error.unwrap_or_default();
    let cap = glint::scene::Effects::MAX_SPP;
    match passes.stopped {
        Stopped::Target => say.line("stopped: the estimate reached the target"),
        Stopped::Noiseless => say.line(
            "stopped: two passes came out identical (nothing in the scene is random), so the image is converged"
        ),
        Stopped::TimeLimit if reached => say.line("stopped: the time limit"),
        Stopped::TimeLimit => say.line(format!(
            "stopped: the time limit, before the target {target} was reached"
        )),
        Stopped::MaxSamples if !reached => {
            eprintln!(
                "error: stopped at the cap of {cap} samples per pixel with the estimate above the target {target}; \
                 the image was written, but is not as accurate as asked (raise --spp for larger passes, or a larger target)"
            );
            return false;
        }
        Stopped::MaxSamples => say.line(format!("stopped: the cap of {cap} samples per pixel")),
        // Only a watcher of the passes ends a render so (`glint view`).
        Stopped::Cancelled => say.line("stopped: cancelled"),
    }
    true
}
