//! What accuracy costs in time (`glint accuracy`): every knob the scene
//! calls for swept one at a time (the others at the scene's values), on
//! each backend, each point timed and measured against a reference.

use std::fmt::Write as _;
use std::time::Duration;

use crate::cpu::Precision;
use crate::features::Features;
use crate::images::compare::flip_mean;
use crate::images::framebuffer::Framebuffer;
use crate::methods::Methods;
use crate::scene::{Effects, Sampler, Scene, Settings};
#[cfg(feature = "plots")]
use crate::suites::plot::LogLog;

/// Where a point renders.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Target {
    /// The Vulkan device.
    Gpu,
    /// The CPU reference, in this precision.
    Cpu(Precision),
}

impl Target {
    /// The CSV's `backend` column: "gpu" or "cpu".
    pub fn backend(self) -> &'static str {
        match self {
            Target::Gpu => "gpu",
            Target::Cpu(_) => "cpu",
        }
    }

    /// The CSV's `precision` column: "f32" or "f64".
    pub fn precision(self) -> &'static str {
        match self {
            Target::Cpu(Precision::F64) => "f64",
            _ => "f32",
        }
    }
}

/// One setting to measure: `knob` at `value`, everything else at the
/// scene's values.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    /// Which setting changes ("scene" for none, "spp", "shadow_samples", ...).
    pub knob: &'static str,
    /// Its value, as the CSV writes it.
    pub value: String,
    /// Where it renders.
    pub target: Target,
    /// Robust or naive ray offsets and intersection.
    pub methods: Methods,
    /// The scene's settings with this point's change.
    pub effects: Effects,
}

impl Point {
    /// `knob` at `value` on `target` with the robust methods.
    fn robust(knob: &'static str, value: String, target: Target, effects: Effects) -> Point {
        Point {
            knob,
            value,
            target,
            methods: Methods::Robust,
            effects,
        }
    }

    /// The settings that make a render this point.
    pub fn settings(&self) -> Settings {
        Settings {
            reflect: Some(self.effects.reflect_depth),
            spp: Some(self.effects.spp),
            shadow_samples: Some(self.effects.shadow_samples),
            shutter: Some(self.effects.shutter),
            seed: Some(self.effects.seed),
            fps: Some(self.effects.fps),
            sampler: Some(self.effects.sampler),
        }
    }
}

/// The points of `plan` that a sampler changes: the scene's own setting,
/// and the spp and shadow-sample sweeps.
fn sampled(out: &mut Vec<Point>, features: &Features, effects: &Effects, target: Target) {
    let point = |knob, value, effects| Point::robust(knob, value, target, effects);
    out.push(point("scene", "scene".into(), *effects));
    if features.multisample || features.motion_blur {
        let top = (effects.spp * 4).clamp(16, Effects::MAX_SPP);
        for spp in doublings(top) {
            out.push(point("spp", spp.to_string(), Effects { spp, ..*effects }));
        }
    }
    if features.area_lights {
        let top = (effects.shadow_samples * 4).clamp(16, Effects::MAX_SHADOW_SAMPLES);
        for shadow_samples in doublings(top) {
            out.push(point(
                "shadow_samples",
                shadow_samples.to_string(),
                Effects {
                    shadow_samples,
                    ..*effects
                },
            ));
        }
    }
}

/// Powers of two from 1 to `top`, with `top` itself.
fn doublings(top: u32) -> Vec<u32> {
    let mut v: Vec<u32> = std::iter::successors(Some(1u32), |&x| x.checked_mul(2))
        .take_while(|&x| x < top)
        .collect();
    v.push(top);
    v
}

/// The sweep for `scene` on `targets` (GPU and/or CPU f32): the scene's
/// own setting on each; spp when the scene samples pixels or time, shadow
/// samples when it has area lights, reflection depth when it reflects, each
/// from 1 (0 for reflection) to 4x the scene's value (at least 16); the CPU
/// in f64 as well; the naive methods. The scene's setting and the sample
/// sweeps are made with each of `samplers` when the scene samples anything
/// (the rest with the first); a scene that samples nothing is the same
/// image with any sampler, and is made with the first.
pub fn plan(
    scene: &Scene,
    effects: &Effects,
    targets: &[Target],
    samplers: &[Sampler],
) -> Vec<Point> {
    let features = Features::of(scene, effects);
    let samples = features.multisample || features.motion_blur || features.area_lights;
    let first = samplers.first().copied().unwrap_or(effects.sampler);
    let samplers: Vec<Sampler> = if samples {
        samplers.to_vec()
    } else {
        vec![first]
    };
    let mut out = Vec::new();
    for &target in targets {
        for &sampler in &samplers {
            let effects = &Effects {
                sampler,
                ..*effects
            };
            sampled(&mut out, &features, effects, target);
        }
        let effects = &Effects {
            sampler: first,
            ..*effects
        };
        let point = |knob, value, effects| Point::robust(knob, value, target, effects);
        if features.reflection {
            for reflect_depth in 0..=effects.reflect_depth {
                out.push(point(
                    "reflect",
                    reflect_depth.to_string(),
                    Effects {
                        reflect_depth,
                        ..*effects
                    },
                ));
            }
        }
        out.push(Point {
            methods: Methods::Naive,
            ..point("methods", "naive".into(), *effects)
        });
        if target == Target::Cpu(Precision::F32) {
            out.push(Point {
                target: Target::Cpu(Precision::F64),
                ..point("precision", "f64".into(), *effects)
            });
        }
    }
    out
}

/// Errors of an image against the reference, on linear values (both
/// clamped to [0, 1]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Errors {
    /// Root mean squared error.
    pub rmse: f64,
    /// Mean of (x - r)^2 / (r^2 + 0.01) per channel.
    pub relmse: f64,
    /// dB; infinite for an exact image.
    pub psnr: f64,
    /// Mean NVIDIA FLIP (LDR, on the 8-bit conversions).
    pub flip: f64,
    /// 99th percentile of the per-pixel largest channel error.
    pub p99: f64,
    /// Pixels with NaN or infinity.
    pub nan: usize,
}

/// The errors of `image` against `reference` (same size), each channel
/// clamped to [0, 1]; a non-finite value counts as an error of 1.
pub fn errors(image: &Framebuffer, reference: &Framebuffer) -> Errors {
    let clamp = |v: f32| f64::from(v).clamp(0.0, 1.0);
    let mut sq = 0.0;
    let mut rel = 0.0;
    let mut worst: Vec<f64> = Vec::with_capacity(image.pixels.len());
    for (p, r) in image.pixels.iter().zip(&reference.pixels) {
        let mut m: f64 = 0.0;
        for c in 0..3 {
            let (x, y) = (clamp(p[c]), clamp(r[c]));
            let d = if p[c].is_finite() { x - y } else { 1.0 };
            sq += d * d;
            rel += d * d / (y * y + 0.01);
            m = m.max(d.abs());
        }
        worst.push(m);
    }
    let values = (image.pixels.len() * 3).max(1) as f64;
    worst.sort_by(f64::total_cmp);
    let p99 = worst
        .get(((worst.len() as f64 * 0.99) as usize).min(worst.len().saturating_sub(1)))
        .copied()
        .unwrap_or(0.0);
    let mse = sq / values;
    Errors {
        rmse: mse.sqrt(),
        relmse: rel / values,
        psnr: if mse == 0.0 {
            f64::INFINITY
        } else {
            -10.0 * mse.log10()
        },
        flip: f64::from(flip_mean(&reference.to_rgb8(), &image.to_rgb8())),
        p99,
        nan: image.non_finite_count(),
    }
}

/// A point rendered and measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Measured {
    /// What was rendered.
    pub point: Point,
    /// Median wall time of one render (BVH, upload, dispatch, readback).
    pub time: Duration,
    /// Median time of the GPU's dispatches alone (GPU points).
    pub dispatch: Option<Duration>,
    /// Its errors against the reference.
    pub errors: Errors,
}

/// The first line of `csv`'s output.
pub const CSV_HEADER: &str = "knob,value,backend,precision,methods,sampler,spp,shadow_samples,reflect,time_ms,dispatch_ms,rmse,relmse,psnr,flip,p99,nan";

/// The rows as CSV, under `CSV_HEADER`.
pub fn csv(rows: &[Measured]) -> String {
    let mut s = format!("{CSV_HEADER}\n");
    for m in rows {
        let p = &m.point;
        let e = &m.errors;
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{:.3},{},{:.6e},{:.6e},{:.3},{:.6},{:.6},{}",
            p.knob,
            p.value,
            p.target.backend(),
            p.target.precision(),
            p.methods,
            p.effects.sampler,
            p.effects.spp,
            p.effects.shadow_samples,
            p.effects.reflect_depth,
            ms(m.time),
            m.dispatch
                .map_or(String::new(), |d| format!("{:.3}", ms(d))),
            e.rmse,
            e.relmse,
            e.psnr,
            e.flip,
            e.p99,
            e.nan
        );
    }
    s
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Settings a user would choose: the naive methods are there to show what
/// the robust ones fix (they fail the hard cases), never to recommend.
fn recommendable(m: &Measured, backend: &str) -> bool {
    m.point.target.backend() == backend && m.point.methods == Methods::Robust
}

/// The points no other point on the same backend beats in both time and
/// RMSE, fastest first: what an equal-time comparison keeps.
pub fn pareto(rows: &[Measured], backend: &str) -> Vec<Measured> {
    let mut on: Vec<&Measured> = rows.iter().filter(|m| recommendable(m, backend)).collect();
    on.sort_by(|a, b| {
        a.time
            .cmp(&b.time)
            .then(a.errors.rmse.total_cmp(&b.errors.rmse))
    });
    let mut out: Vec<Measured> = Vec::new();
    for m in on {
        if out.last().is_none_or(|l| m.errors.rmse < l.errors.rmse) {
            out.push(m.clone());
        }
    }
    out
}

/// The fastest point on `backend` (robust methods) whose FLIP mean is at
/// most `target`.
pub fn cheapest(rows: &[Measured], backend: &str, target: f64) -> Option<Measured> {
    rows.iter()
        .filter(|m| recommendable(m, backend) && m.errors.flip <= target)
        .min_by_key(|m| m.time)
        .cloned()
}

fn label(m: &Measured) -> String {
    let p = &m.point;
    let mut s = format!("{}={}", p.knob, p.value);
    if p.knob == "scene" {
        s = "scene's settings".into();
    }
    format!("{s}, {}", p.effects.sampler)
}

/// Each sampler against `stratified` at the scene's own settings, per
/// backend: the ratio of their mean squared errors and of their times.
pub fn sampler_ratios(rows: &[Measured]) -> Vec<SamplerRatio> {
    let scene_point = |backend: &str, sampler: Sampler| {
        rows.iter().find(|m| {
            m.point.knob == "scene"
                && m.point.target.backend() == backend
                && m.point.effects.sampler == sampler
        })
    };
    let mut out = Vec::new();
    for backend in ["gpu", "cpu"] {
        let Some(base) = scene_point(backend, Sampler::Stratified) else {
            continue;
        };
        for sampler in Sampler::ALL
            .into_iter()
            .filter(|&s| s != Sampler::Stratified)
        {
            if let Some(m) = scene_point(backend, sampler) {
                out.push(SamplerRatio {
                    backend,
                    sampler,
                    mse: m.errors.rmse.powi(2),
                    stratified_mse: base.errors.rmse.powi(2),
                    time_ratio: m.time.as_secs_f64() / base.time.as_secs_f64().max(1e-9),
                });
            }
        }
    }
    out
}

/// One line of `sampler_ratios`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SamplerRatio {
    /// "gpu" or "cpu".
    pub backend: &'static str,
    /// The sampler compared.
    pub sampler: Sampler,
    /// Its mean squared error at the scene's settings.
    pub mse: f64,
    /// `stratified`'s at the same settings.
    pub stratified_mse: f64,
    /// Its time over `stratified`'s.
    pub time_ratio: f64,
}

fn samplers_section(s: &mut String, rows: &[Measured]) {
    let ratios = sampler_ratios(rows);
    if ratios.is_empty() {
        return;
    }
    let _ = write!(
        s,
        "\n## Samplers\n\nAt the scene's own settings, against `stratified`: the mean squared error (MSE) and the time of one render.\n\n| backend | sampler | MSE | stratified MSE | stratified / sampler MSE | time / stratified's |\n|---|---|---:|---:|---:|---:|\n"
    );
    for r in ratios {
        let _ = writeln!(
            s,
            "| {} | {} | {:.3e} | {:.3e} | {:.2} | {:.2} |",
            r.backend,
            r.sampler,
            r.mse,
            r.stratified_mse,
            r.stratified_mse / r.mse.max(f64::MIN_POSITIVE),
            r.time_ratio
        );
    }
}

/// The report: a table per knob (equal samples: value by backend), the
/// Pareto front per backend (equal time), the cheapest setting reaching
/// `target`.
pub fn markdown(rows: &[Measured], header: &str, target: f64) -> String {
    let mut s = format!("# Accuracy against time\n\n{header}\n");
    let mut knobs: Vec<&str> = Vec::new();
    for m in rows {
        if !knobs.contains(&m.point.knob) {
            knobs.push(m.point.knob);
        }
    }
    for knob in knobs {
        let _ = write!(
            s,
            "\n## {knob}\n\n| value | backend | precision | methods | sampler | time (ms) | dispatch (ms) | RMSE | relMSE | PSNR (dB) | FLIP | p99 | NaN |\n|---|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n"
        );
        for m in rows.iter().filter(|m| m.point.knob == knob) {
            let e = &m.errors;
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {:.1} | {} | {:.5} | {:.2e} | {:.1} | {:.4} | {:.4} | {} |",
                m.point.value,
                m.point.target.backend(),
                m.point.target.precision(),
                m.point.methods,
                m.point.effects.sampler,
                ms(m.time),
                m.dispatch.map_or("-".into(), |d| format!("{:.1}", ms(d))),
                e.rmse,
                e.relmse,
                e.psnr,
                e.flip,
                e.p99,
                e.nan
            );
        }
    }
    samplers_section(&mut s, rows);
    let _ = write!(
        s,
        "\n## Equal time\n\nPer backend, the settings (robust methods) no other beats in both time and RMSE, fastest first: at a given time, the best error to be had.\n"
    );
    for backend in ["gpu", "cpu"] {
        let front = pareto(rows, backend);
        if front.is_empty() {
            continue;
        }
        let _ = write!(
            s,
            "\n| {backend}: setting | time (ms) | RMSE | FLIP |\n|---|---:|---:|---:|\n"
        );
        for m in &front {
            let _ = writeln!(
                s,
                "| {} ({}) | {:.1} | {:.5} | {:.4} |",
                label(m),
                m.point.target.precision(),
                ms(m.time),
                m.errors.rmse,
                m.errors.flip
            );
        }
    }
    let _ = write!(
        s,
        "\n## Cheapest setting with FLIP mean at most {target}\n\n"
    );
    for backend in ["gpu", "cpu"] {
        if !rows.iter().any(|m| m.point.target.backend() == backend) {
            continue;
        }
        let _ = match cheapest(rows, backend, target) {
            Some(m) => writeln!(
                s,
                "- {backend}: {} ({}), {:.1} ms, FLIP {:.4}, RMSE {:.5}",
                label(&m),
                m.point.target.precision(),
                ms(m.time),
                m.errors.flip,
                m.errors.rmse
            ),
            None => writeln!(s, "- {backend}: no setting measured reaches it"),
        };
    }
    s
}

#[cfg(feature = "plots")]
/// A log-log plot of RMSE against time, one line per knob and backend
/// (`LogLog::to_svg`, `LogLog::to_image`).
pub fn plot(rows: &[Measured], title: &str) -> LogLog {
    let mut series: Vec<(String, Vec<[f64; 2]>)> = Vec::new();
    for m in rows.iter().filter(|m| m.errors.rmse > 0.0) {
        let name = format!(
            "{} ({}, {})",
            m.point.knob,
            m.point.target.backend(),
            m.point.effects.sampler
        );
        let point = [ms(m.time).max(1e-3), m.errors.rmse];
        match series.iter_mut().find(|(n, _)| *n == name) {
            Some((_, v)) => v.push(point),
            None => series.push((name, vec![point])),
        }
    }
    crate::suites::plot::log_log(title, "render time (ms)", "RMSE", &series)
}

#[cfg(feature = "plots")]
/// `plot` as SVG (text is drawn by whatever shows it).
pub fn svg(rows: &[Measured], title: &str) -> String {
    plot(rows, title).to_svg()
}

#[cfg(feature = "plots")]
/// `plot` drawn at twice its size (text in the embedded DejaVu Sans).
pub fn png_image(rows: &[Measured], title: &str) -> image::RgbImage {
    plot(rows, title).to_image(2.0)
}

/// The median of `times` (the upper one of an even count).
pub fn median(mut times: Vec<Duration>) -> Duration {
    times.sort();
    times.get(times.len() / 2).copied().unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fb(v: f32) -> Framebuffer {
        Framebuffer {
            width: 10,
            height: 10,
            pixels: vec![[v; 3]; 100],
        }
    }

    #[test]
    fn errors_of_a_uniform_offset() {
        let e = errors(&fb(0.6), &fb(0.5));
        assert!((e.rmse - 0.1).abs() < 1e-6, "{e:?}");
        assert!((e.psnr - 20.0).abs() < 1e-4, "{e:?}");
        assert!((e.relmse - 0.01 / 0.26).abs() < 1e-6, "{e:?}");
        assert!((e.p99 - 0.1).abs() < 1e-6, "{e:?}");
        assert_eq!(e.nan, 0);
        let same = errors(&fb(0.5), &fb(0.5));
        assert_eq!((same.rmse, same.flip, same.psnr), (0.0, 0.0, f64::INFINITY));
        let mut bad = fb(0.5);
        bad.pixels[3] = [f32::NAN; 3];
        assert_eq!(errors(&bad, &fb(0.5)).nan, 1);
    }

    #[test]
    fn plan_sweeps_what_the_scene_calls_for() {
        let text = "2\namb: 0 0 0\nspp: 4\nsphere pos: 0 0 -3 rad: 1 dif: 1 1 1 spe: 0 0 0 shi: 1\nlight pos: 0 2 0 col: 1 1 1\n";
        let scene = crate::scene::parse_scene(text.as_bytes(), "t.scene").expect("parses");
        let effects = Effects::resolve(&scene.settings);
        let both = [Sampler::Sobol, Sampler::Stratified];
        let points = plan(&scene, &effects, &[Target::Cpu(Precision::F32)], &both);
        let knobs: Vec<(&str, &str, Sampler)> = points
            .iter()
            .map(|p| (p.knob, p.value.as_str(), p.effects.sampler))
            .collect();
        // spp 1..16 (4x the scene's 4, at least 16) with each sampler; no
        // area lights, no reflection (ks is 0); the rest with the first.
        let mut expected = Vec::new();
        for sampler in both {
            expected.push(("scene", "scene", sampler));
            for spp in ["1", "2", "4", "8", "16"] {
                expected.push(("spp", spp, sampler));
            }
        }
        expected.push(("methods", "naive", Sampler::Sobol));
        expected.push(("precision", "f64", Sampler::Sobol));
        assert_eq!(knobs, expected);
        assert_eq!(points[3].effects.spp, 4);
        assert_eq!(points[13].target, Target::Cpu(Precision::F64));

        // Nothing sampled: one sampler is the same image as the other.
        let plain = text.replace("spp: 4\n", "");
        let scene = crate::scene::parse_scene(plain.as_bytes(), "t.scene").expect("parses");
        let effects = Effects::resolve(&scene.settings);
        let points = plan(&scene, &effects, &[Target::Cpu(Precision::F32)], &both);
        assert!(points.iter().all(|p| p.effects.sampler == Sampler::Sobol));
        assert_eq!(points.len(), 3, "scene, naive, f64");
    }

    #[test]
    fn pareto_keeps_what_nothing_beats() {
        let m = |t: u64, rmse: f64| Measured {
            point: Point {
                knob: "spp",
                value: t.to_string(),
                target: Target::Gpu,
                methods: Methods::Robust,
                effects: Effects::default(),
            },
            time: Duration::from_millis(t),
            dispatch: None,
            errors: Errors {
                rmse,
                flip: rmse,
                ..Errors::default()
            },
        };
        let rows = [m(10, 0.1), m(20, 0.2), m(30, 0.05), m(40, 0.01)];
        let front: Vec<u64> = pareto(&rows, "gpu")
            .iter()
            .map(|m| m.time.as_millis() as u64)
            .collect();
        assert_eq!(front, [10, 30, 40]);
        assert_eq!(
            cheapest(&rows, "gpu", 0.06).map(|m| m.time),
            Some(Duration::from_millis(30))
        );
        assert_eq!(cheapest(&rows, "cpu", 0.06), None);
        assert!(csv(&rows).starts_with("knob,value,backend,precision,methods,"));
    }
}
