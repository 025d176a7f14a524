//! The sweep itself: every point of the plan rendered `--repeat` times on
//! its backend, timed, and measured against the reference.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use glint::cpu::Precision;
use glint::images::framebuffer::Framebuffer;
use glint::methods::Methods;
use glint::render::{Backend, RenderOptions, Renderer};
use glint::scene::{Sampler, Scene};
use glint::suites::accuracy::{self, Measured, Target};
use glint::timing::GPU_TIME_NS;

use super::{AccuracyArgs, Which};

/// What the sweep measured.
pub(super) struct Sweep {
    pub rows: Vec<Measured>,
    /// What rendered it ("GPU: ...", "CPU reference: N threads").
    pub notes: Vec<String>,
    /// Whether every GPU point was timed by the device (None: no GPU point).
    pub dispatch_clock: Option<bool>,
    /// Points the budget left out, of `points`.
    pub left_out: usize,
    pub points: usize,
}

pub(super) fn run(
    args: &AccuracyArgs,
    scene: &Scene,
    base: &RenderOptions,
    reference: &Framebuffer,
    start: Instant,
) -> anyhow::Result<Sweep> {
    let effects = base.effects(scene);
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
    // Every sampler unless one was named: the comparison is the point.
    let samplers = match args.effects.sampler {
        Some(sampler) => vec![sampler],
        None => Sampler::ALL.to_vec(),
    };
    let points = accuracy::plan(scene, &effects, &targets, &samplers);
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
                    // Each point's settings are whole (`Point::settings`);
                    // the command line's overrides are in them already and
                    // must not override the sweep's values.
                    settings: Default::default(),
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
            errors: accuracy::errors(&image, reference),
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

    Ok(Sweep {
        rows,
        notes,
        dispatch_clock,
        left_out,
        points: points.len(),
    })
}
