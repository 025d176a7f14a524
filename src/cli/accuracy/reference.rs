//! The sweep's ground truth: an image given (`--reference`), or a CPU f64
//! progressive render cached in the output directory.

use std::hash::{Hash, Hasher};
use std::time::Duration;

use anyhow::Context as _;
use glint::cpu::Precision;
use glint::images::framebuffer::{read_framebuffer, Framebuffer};
use glint::render::passes::StopAt;
use glint::render::{Backend, Job, RenderOptions, Renderer, Sink};
use glint::scene::Scene;

use super::AccuracyArgs;

/// The reference's estimated RMSE: errors much below it are not measured.
/// At 0.0005 the default sampler's soft_shadows sweep (160x120) ran into it
/// from 64 shadow samples on, its curve flattening there.
const REFERENCE_RMSE: f64 = 0.00025;

/// The reference and a line saying what it is.
pub(super) fn get(
    scene: &Scene,
    bytes: &[u8],
    base: &RenderOptions,
    args: &AccuracyArgs,
) -> anyhow::Result<(Framebuffer, String)> {
    match &args.reference {
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
            Ok((r, format!("reference: {}", path.display())))
        }
        None => rendered(scene, bytes, base, args),
    }
}

/// The cached CPU f64 reference, or a new one: a progressive render to an
/// estimated RMSE of `REFERENCE_RMSE`, with seeds the sweep does not use.
fn rendered(
    scene: &Scene,
    bytes: &[u8],
    base: &RenderOptions,
    args: &AccuracyArgs,
) -> anyhow::Result<(Framebuffer, String)> {
    let effects = base.effects(scene);
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    bytes.hash(&mut hasher);
    let key = format!(
        "glint {} reference v2 (RMSE {REFERENCE_RMSE}): scene {} ({} bytes, hash {:016x}), {}x{}, {:?}\n",
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
