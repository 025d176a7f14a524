//! Progressive renders (`--target-error`): the error estimated from the
//! even and odd passes tracks the true error against a converged f64
//! reference, on the CPU f32 twin and the GPU, and a render that stops on
//! its target is below it.

mod common;

use std::time::Duration;

use common::*;
use glint::cpu::Precision;
use glint::framebuffer::Framebuffer;
use glint::progressive::{Progressive, StopAt, Stopped};
use glint::render::{Backend, RenderOptions, Renderer};
use glint::scene::Scene;

const W: u32 = 64;
const H: u32 = 48;

fn effect_scene(name: &str) -> Scene {
    let path = repo_path(&format!("scenes/effects/{name}.scene"));
    glint::scene::read_scene(&path).expect("effect scene parses")
}

fn progressive(
    scene: &Scene,
    backend: Backend,
    precision: Precision,
    target: f64,
    seed: Option<u32>,
) -> Progressive {
    let options = RenderOptions {
        width: W,
        height: H,
        backend,
        precision,
        settings: glint::scene::Settings {
            seed,
            ..Default::default()
        },
        validation: backend == Backend::Gpu && in_ci(),
        ..RenderOptions::default()
    };
    let stop = StopAt {
        target_rmse: Some(target),
        time_limit: Some(Duration::from_secs(300)),
    };
    let renderer = Renderer::new(&options).expect("renderer");
    let done = renderer
        .render_progressive(scene, &stop, &mut |_| {})
        .expect("progressive render");
    assert_eq!(
        done.output.validation_messages, 0,
        "Vulkan validation messages"
    );
    done
}

fn rmse(a: &Framebuffer, b: &Framebuffer) -> f64 {
    let sq: f64 = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(p, q)| (0..3).map(move |c| f64::from(p[c] - q[c]).powi(2)))
        .sum();
    (sq / (a.pixels.len() * 3) as f64).sqrt()
}

#[test]
fn estimated_error_tracks_the_true_error() {
    let target = 0.004;
    let mut backends = vec![Backend::Cpu];
    if gpu().is_some() {
        backends.push(Backend::Gpu);
    }
    for name in ["soft_shadows", "motion_blur", "antialias"] {
        let scene = effect_scene(name);
        // A tenth of the target: it adds under 1% to the measured error.
        // Other seeds than the render's: sharing its first passes' samples
        // would hide part of its error (measured: 0.66 of the estimate).
        let reference = progressive(
            &scene,
            Backend::Cpu,
            Precision::F64,
            target / 10.0,
            Some(1 << 20),
        );
        assert_eq!(
            reference.stopped,
            Stopped::Target,
            "{name}: reference converged"
        );
        for &backend in &backends {
            let done = progressive(&scene, backend, Precision::F32, target, None);
            let estimate = done.report.estimated_rmse.expect("two passes at least");
            let truth = rmse(&done.output.framebuffer, &reference.output.framebuffer);
            eprintln!(
                "{name} on {backend:?}: {} passes, estimate {estimate:.5}, true {truth:.5} (ratio {:.3}); reference {} passes",
                done.report.passes,
                truth / estimate,
                reference.report.passes
            );
            assert_eq!(done.stopped, Stopped::Target, "{name} on {backend:?}");
            assert!(estimate <= target);
            assert!(
                (1.0 / 1.5..=1.5).contains(&(truth / estimate)),
                "{name} on {backend:?}: true RMSE {truth} against the estimate {estimate}"
            );
            assert!(
                truth <= target,
                "{name} on {backend:?}: true RMSE {truth} above the target {target}"
            );
        }
    }
}

/// A scene with nothing random stops after two identical passes with the
/// single-pass image.
#[test]
fn a_noiseless_scene_stops_after_two_passes() {
    let scene = effect_scene("reflect");
    let done = progressive(&scene, Backend::Cpu, Precision::F32, 1e-6, None);
    assert_eq!(done.stopped, Stopped::Noiseless);
    assert_eq!(done.report.passes, 2);
    assert_eq!(
        done.output.framebuffer,
        render_cpu(&scene, W, H, Precision::F32, WHITE)
    );
}
