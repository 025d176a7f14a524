use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context as _;
use clap::Args;
use glint::gpu::DeviceSelector;
use glint::render::RenderOptions;
use glint::suites::accuracy;

use super::EffectArgs;

mod reference;
mod sweep;

#[derive(Args, Debug)]
pub struct AccuracyArgs {
    /// Scene file in the classic format.
    pub(super) scene: PathBuf,
    /// Directory for accuracy.csv, accuracy.md, accuracy.svg, accuracy.png and the cached
    /// reference.
    #[arg(long, default_value = "accuracy")]
    pub(super) out: PathBuf,
    /// Where to sweep: both = the GPU (when a Vulkan device is found) and
    /// the CPU reference.
    #[arg(long, value_enum, default_value = "both")]
    pub(super) backend: Which,
    /// Vulkan device by index or name (see `glint devices`).
    #[arg(long)]
    pub(super) device: Option<String>,
    /// Seconds the whole sweep may take; points not started by then are
    /// left out (and the report says so).
    #[arg(long, value_name = "SECONDS", value_parser = parse_positive)]
    pub(super) budget: Option<f64>,
    /// Ground truth (.exr, or .png/.jpg) of the same size; default: a CPU
    /// f64 progressive render, cached in the output directory.
    #[arg(long, value_name = "IMG")]
    pub(super) reference: Option<PathBuf>,
    /// FLIP mean the "cheapest setting" line asks for.
    #[arg(long, default_value_t = 0.01, value_parser = parse_positive)]
    pub(super) target: f64,
    #[arg(long, default_value_t = 320, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub(super) width: u32,
    #[arg(long, default_value_t = 240, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub(super) height: u32,
    /// Renders per point; the time is their median.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub(super) repeat: u32,
    #[command(flatten)]
    pub(super) effects: EffectArgs,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(super) enum Which {
    Both,
    Gpu,
    Cpu,
}

fn parse_positive(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("expected a number above 0, found `{s}`")),
    }
}

pub fn run(args: AccuracyArgs) -> anyhow::Result<ExitCode> {
    let start = Instant::now();
    let bytes = std::fs::read(&args.scene).map_err(|error| glint::Error::ReadScene {
        path: args.scene.clone(),
        error,
    })?;
    let scene = glint::scene::read_scene(&args.scene)?;
    super::print_warnings(&scene);
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating the output directory {}", args.out.display()))?;
    let base = RenderOptions {
        width: args.width,
        height: args.height,
        device: args.device.as_deref().map(DeviceSelector::parse),
        settings: args.effects.settings(),
        ..RenderOptions::default()
    };

    let (reference, about_reference) = reference::get(&scene, &bytes, &base, &args)?;
    eprintln!("{about_reference}");
    let sweep = sweep::run(&args, &scene, &base, &reference, start)?;
    reports(&args, &sweep, &about_reference)?;
    let rows = &sweep.rows;
    for backend in ["gpu", "cpu"] {
        if !rows.iter().any(|m| m.point.target.backend() == backend) {
            continue;
        }
        match accuracy::cheapest(rows, backend, args.target) {
            Some(m) => println!(
                "{backend}: cheapest with FLIP mean <= {}: {}={} ({}), {:.1} ms (FLIP {:.4}, RMSE {:.5})",
                args.target,
                m.point.knob,
                m.point.value,
                m.point.target.precision(),
                m.time.as_secs_f64() * 1e3,
                m.errors.flip,
                m.errors.rmse
            ),
            None => println!(
                "{backend}: no setting measured reaches FLIP mean <= {}",
                args.target
            ),
        }
    }
    println!(
        "wrote {}/accuracy.csv, accuracy.md, accuracy.svg, accuracy.png ({} points, {:.1} s)",
        args.out.display(),
        rows.len(),
        start.elapsed().as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}

/// accuracy.csv, .md, .svg and .png in the output directory.
fn reports(args: &AccuracyArgs, sweep: &sweep::Sweep, about_reference: &str) -> anyhow::Result<()> {
    let sweep::Sweep {
        rows,
        notes,
        dispatch_clock,
        left_out,
        points,
    } = sweep;
    let clock = match *dispatch_clock {
        Some(true) => "Vulkan timestamps around each dispatch",
        _ => "host clock around each pass",
    };
    let mut header = format!(
        "Scene `{}` at {}x{}; {about_reference}; {}; time = median of {} renders (BVH, upload, dispatch, readback), dispatch = the GPU's dispatches alone ({clock}).",
        args.scene.display(),
        args.width,
        args.height,
        notes.join("; "),
        args.repeat
    );
    if *left_out > 0 {
        header.push_str(&format!(
            " The budget left out {left_out} of {} points.",
            points
        ));
    }
    let write = |name: &str, text: String| -> anyhow::Result<PathBuf> {
        let path = args.out.join(name);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
        Ok(path)
    };
    write("accuracy.csv", accuracy::csv(rows))?;
    write(
        "accuracy.md",
        accuracy::markdown(rows, &header, args.target),
    )?;
    let title = format!(
        "{}: RMSE against render time",
        args.scene
            .file_name()
            .map_or("scene".into(), |n| n.to_string_lossy())
    );
    write("accuracy.svg", accuracy::svg(rows, &title))?;
    glint::images::framebuffer::write_image(
        &accuracy::png_image(rows, &title),
        &args.out.join("accuracy.png"),
        95,
    )?;
    Ok(())
}
