use std::collections::HashMap;
use std::hash::{Hash, Hasher};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use clap::Args;
use glint::cpu::Precision;
use glint::gpu::DeviceSelector;
use glint::images::framebuffer::{read_framebuffer, Framebuffer};
use glint::methods::Methods;
use glint::render::passes::StopAt;
use glint::render::{Backend, Job, RenderOptions, Renderer, Sink};
use glint::scene::Scene;
use glint::suites::accuracy::{self, Measured, Target};
use glint::timing::GPU_TIME_NS;

use super::EffectArgs;

#[derive(Args, Debug)]
pub struct AccuracyArgs {
    /// Scene file in the classic format.
    scene: PathBuf,
    /// Directory for accuracy.csv, accuracy.md, accuracy.svg, accuracy.png and the cached
    /// reference.
    #[arg(long, default_value = "accuracy")]
    out: PathBuf,
    /// Where to sweep: both = the GPU (when a Vulkan device is found) and
    /// the CPU reference.
    #[arg(long, value_enum, default_value = "both")]
    backend: Which,
    /// Vulkan device by index or name (see `glint devices`).
    #[arg(long)]
    device: Option<String>,
    /// Seconds the whole sweep may take; points not started by then are
    /// left out (and the report says so).
    #[arg(long, value_name = "SECONDS", value_parser = parse_positive)]
    budget: Option<f64>,
    /// Ground truth (.exr, or .png/.jpg) of the same size; default: a CPU
    /// f64 progressive render, cached in the output directory.
    #[arg(long, value_name = "IMG")]
    reference: Option<PathBuf>,
    /// FLIP mean the "cheapest setting" line asks for.
    #[arg(long, default_value_t = 0.01, value_parser = parse_positive)]
    target: f64,
    #[arg(long, default_value_t = 320, value_parser = clap::value_parser!(u32).range(1..=16384))]
    width: u32,
    #[arg(long, default_value_t = 240, value_parser = clap::value_parser!(u32).range(1..=16384))]
    height: u32,
    /// Renders per point; the time is their median.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    repeat: u32,
    #[command(flatten)]
    effects: EffectArgs,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Which {
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

/// The reference's estimated RMSE: errors much below it are not measured.
const REFERENCE_RMSE: f64 = 0.0005;

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
    let effects = base.effects(&scene);

    let (reference, about_reference) = match &args.reference {
        Some(path) => {
            let r = read_framebuffer(path)?;
            if (r.width, r.height) != (args.width, args.height) {
                anyhow::bail!(glint::Error::InvalidOption(format!(
                    "the reference {} is {}x{}, the sweep renders {}x{}; pass --width {} --height {}",
                    path.display(),
                    r.width,
                    r.height,
                    args.width,
                    args.height,
                    r.width,
                    r.height
                )));
            }
            (r, format!("reference: {}", path.display()))
        }
        None => reference(&scene, &bytes, &base, &args)?,
    };
    eprintln!("{about_reference}");

    let mut renderers: HashMap<(Target, Methods), Renderer> = HashMap::new();
    let mut targets = Vec::new();
    let mut notes = Vec::new();
    if args.backend != Which::Cpu {
        let options = RenderOptions {
            backend: Backend::Gpu,
            ..base.clone()
        };
        match Renderer::new(&options) {
            Ok(r) => {
                notes.push(r.name());
                renderers.insert((Target::Gpu, Methods::Robust), r);
                targets.push(Target::Gpu);
            }
            Err(e) if args.backend == Which::Both => {
                eprintln!("note: no GPU in the sweep ({e})");
                notes.push(format!("no GPU ({e})"));
            }
            Err(e) => return Err(e.into()),
        }
    }
    if args.backend != Which::Gpu {
        targets.push(Target::Cpu(Precision::F32));
        notes.push(format!(
            "CPU reference: {} threads",
            rayon::current_num_threads()
        ));
    }
    let points = accuracy::plan(&scene, &effects, &targets);
    let budget = args.budget.map(Duration::from_secs_f64);
    let mut rows: Vec<Measured> = Vec::new();
    // Whether every GPU point was timed by the device (None: no GPU point).
    let mut dispatch_clock: Option<bool> = None;
    let mut left_out = 0;
    for (i, point) in points.iter().enumerate() {
        if budget.is_some_and(|b| start.elapsed() > b) {
            left_out = points.len() - i;
            eprintln!(
                "note: the budget of {:.0} s is spent; {left_out} of {} points left out",
                budget.unwrap_or_default().as_secs_f64(),
                points.len()
            );
            break;
        }
        let renderer = match renderers.entry((point.target, point.methods)) {
            std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::hash_map::Entry::Vacant(e) => {
                let options = RenderOptions {
                    backend: match point.target {
                        Target::Gpu => Backend::Gpu,
                        Target::Cpu(_) => Backend::Cpu,
                    },
                    precision: match point.target {
                        Target::Cpu(p) => p,
                        Target::Gpu => Precision::F32,
                    },
                    methods: point.methods,
                    device: match point.target {
                        Target::Gpu => base.device.clone(),
                        Target::Cpu(_) => None,
                    },
                    ..base.clone()
                };
                e.insert(Renderer::new(&options)?)
            }
        };
        let mut at = scene.clone();
        at.settings = point.settings();
        if renderer.prepare_pipeline(&at)? > Duration::ZERO {
            // A new pipeline: drivers may compile it at its first dispatch
            // (lavapipe does), which no point should be charged for.
            renderer.render(&at, &|_, _| {})?;
        }
        let mut times = Vec::new();
        let mut dispatches = Vec::new();
        let mut by_device = true;
        let mut image: Option<Framebuffer> = None;
        for _ in 0..args.repeat {
            let t = Instant::now();
            let out = renderer.render(&at, &|_, _| {})?;
            times.push(t.elapsed());
            // The device's own clock where it has timestamps, else the
            // host's around the passes.
            let t = &out.timings;
            if t.has_count(GPU_TIME_NS) {
                dispatches.push(Duration::from_nanos(t.counted(GPU_TIME_NS)));
            } else if let Some(d) = t.phases.iter().find(|p| p.0 == "dispatch") {
                dispatches.push(d.1);
                by_device = false;
            }
            image = Some(out.into_framebuffer());
        }
        let image = image.expect("at least one render");
        if !dispatches.is_empty() {
            dispatch_clock = Some(dispatch_clock.unwrap_or(true) && by_device);
        }
        let m = Measured {
            point: point.clone(),
            time: accuracy::median(times),
            dispatch: (!dispatches.is_empty()).then(|| accuracy::median(dispatches)),
            errors: accuracy::errors(&image, &reference),
        };
        eprintln!(
            "[{}/{}] {}={} on {} {} {}: {:.1} ms, RMSE {:.5}, FLIP {:.4}",
            i + 1,
            points.len(),
            point.knob,
            point.value,
            point.target.backend(),
            point.target.precision(),
            point.methods,
            m.time.as_secs_f64() * 1e3,
            m.errors.rmse,
            m.errors.flip
        );
        rows.push(m);
    }

    let clock = match dispatch_clock {
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
    if left_out > 0 {
        header.push_str(&format!(
            " The budget left out {left_out} of {} points.",
            points.len()
        ));
    }
    let write = |name: &str, text: String| -> anyhow::Result<PathBuf> {
        let path = args.out.join(name);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
        Ok(path)
    };
    write("accuracy.csv", accuracy::csv(&rows))?;
    write(
        "accuracy.md",
        accuracy::markdown(&rows, &header, args.target),
    )?;
    let title = format!(
        "{}: RMSE against render time",
        args.scene
            .file_name()
            .map_or("scene".into(), |n| n.to_string_lossy())
    );
    write("accuracy.svg", accuracy::svg(&rows, &title))?;
    glint::images::framebuffer::write_image(
        &accuracy::png_image(&rows, &title),
        &args.out.join("accuracy.png"),
        95,
    )?;
    for backend in ["gpu", "cpu"] {
        if !rows.iter().any(|m| m.point.target.backend() == backend) {
            continue;
        }
        match accuracy::cheapest(&rows, backend, args.target) {
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

/// The cached CPU f64 reference, or a new one: a progressive render to an
/// estimated RMSE of `REFERENCE_RMSE`, with seeds the sweep does not use.
fn reference(
    scene: &Scene,
    bytes: &[u8],
    base: &RenderOptions,
    args: &AccuracyArgs,
) -> anyhow::Result<(Framebuffer, String)> {
    let effects = base.effects(scene);
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    bytes.hash(&mut hasher);
    let key = format!(
        "glint {} reference v1: scene {} ({} bytes, hash {:016x}), {}x{}, {:?}\n",
        env!("CARGO_PKG_VERSION"),
        args.scene.display(),
        bytes.len(),
        hasher.finish(),
        args.width,
        args.height,
        effects
    );
    let image_path = args.out.join("reference.exr");
    let key_path = args.out.join("reference.key");
    if let Ok(cached) = std::fs::read_to_string(&key_path) {
        if let Some(about) = cached.strip_prefix(key.as_str()) {
            if let Ok(r) = read_framebuffer(&image_path) {
                return Ok((r, format!("{} (cached)", about.trim())));
            }
        }
    }
    let options = RenderOptions {
        backend: Backend::Cpu,
        device: None,
        precision: Precision::F64,
        settings: glint::scene::Settings {
            // Other seeds than every point's: a reference that shares a
            // render's samples hides part of its error.
            seed: Some(effects.seed ^ 0x5eed_0000),
            ..base.settings
        },
        ..base.clone()
    };
    let stop = StopAt {
        target_rmse: Some(REFERENCE_RMSE),
        time_limit: Some(args.budget.map_or(Duration::from_secs(600), |b| {
            Duration::from_secs_f64(b / 2.0)
        })),
        adaptive: false,
    };
    eprintln!(
        "rendering the reference: CPU f64 to an estimated RMSE of {REFERENCE_RMSE} (cached in {})",
        image_path.display()
    );
    let renderer = Renderer::new(&options)?;
    let job = Job::new(scene).until(stop);
    let done = renderer.run(&job, &Sink::file(&image_path), &PassLine::new())?;
    let Some(passes) = &done.passes else {
        unreachable!("a progressive job reports its passes");
    };
    if PassLine::new().terminal {
        eprintln!();
    }
    let about = format!(
        "reference: CPU f64, {} passes, {} samples per pixel, estimated RMSE {}, {:.1} s",
        passes.report.passes,
        passes.report.samples_per_pixel,
        passes
            .report
            .estimated_rmse
            .map_or("none".into(), |e| format!("{e:.5}")),
        passes.report.elapsed.as_secs_f64()
    );
    std::fs::write(&key_path, format!("{key}{about}\n"))
        .with_context(|| format!("writing {}", key_path.display()))?;
    Ok((done.output.into_framebuffer(), about))
}

/// The reference's passes, one line rewritten in place on a terminal.
struct PassLine {
    terminal: bool,
}

impl PassLine {
    fn new() -> PassLine {
        PassLine {
            terminal: std::io::IsTerminal::is_terminal(&std::io::stderr()),
        }
    }
}

impl glint::render::Watch for PassLine {
    fn pass(&self, r: &glint::render::passes::PassReport) {
        if self.terminal {
            eprint!(
                "\r  pass {}, {} samples per pixel, estimate {}   ",
                r.passes,
                r.samples_per_pixel,
                r.estimated_rmse.map_or("-".into(), |e| format!("{e:.5}"))
            );
        }
    }
}
