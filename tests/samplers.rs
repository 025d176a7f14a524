//! The samplers (`sobol`, the default, and `stratified`): each is unbiased
//! on scenes whose answer is known (its mean over many seeds matches an f64
//! quadrature of the same integral), the GPU renders what the CPU twin does
//! with either, the same seed gives the same image, and `sobol` reaches a
//! lower error than `stratified` from the same samples.

mod common;

use common::*;
use glam::DVec3;
use glint::camera::Camera;
use glint::cpu::Precision;
use glint::images::framebuffer::Framebuffer;
use glint::scene::{Effects, Sampler, Scene};

/// Gauss-Legendre nodes and weights on [0, 1]: exact for polynomials of
/// degree below 2n, so the smooth integrands below come out to ~1e-12.
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        // Newton's method on P_n from the Chebyshev guess of root i.
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut derivative = 0.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let k = k as f64;
                (p0, p1) = (p1, ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k);
            }
            derivative = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let step = p1 / derivative;
            x -= step;
            if step.abs() < 1e-15 {
                break;
            }
        }
        let weight = 2.0 / ((1.0 - x * x) * derivative * derivative);
        out.push((0.5 * (x + 1.0), 0.5 * weight));
    }
    out
}

/// A plane at y = -1 (kd 0.8, no specular) and `lights`; nothing else.
fn plane_scene(lights: &str, settings: &str) -> Scene {
    let corner =
        |x: f64, z: f64| format!("pos: {x} -1 {z} nor: 0 1 0 dif: 0.8 0.8 0.8 spe: 0 0 0 shi: 1\n");
    let count = lights.matches("light").count() + 2;
    let text = format!(
        "{count}\namb: 0 0 0\n{settings}{lights}triangle\n{}{}{}triangle\n{}{}{}",
        corner(-100.0, 10.0),
        corner(100.0, 10.0),
        corner(100.0, -100.0),
        corner(-100.0, 10.0),
        corner(100.0, -100.0),
        corner(-100.0, -100.0),
    );
    scene_from(&text)
}

/// Where the ray through (x + u, y + v) of a `w` x `h` image meets the plane
/// y = -1 (the classic camera, as `cpu::trace::camera_ray` builds it).
fn on_plane(camera: &Camera, x: u32, y: u32, u: f64, v: f64) -> DVec3 {
    let (w, h) = (f64::from(camera.width), f64::from(camera.height));
    let ndc_x = (2.0 * (f64::from(x) + u) / w - 1.0) * camera.half_extent[0];
    let ndc_y = (1.0 - 2.0 * (f64::from(y) + v) / h) * camera.half_extent[1];
    let dir = DVec3::new(ndc_x, ndc_y, -1.0).normalize();
    dir * (-1.0 / dir.y)
}

/// The diffuse term the plane shows at `p` for a light point `q`.
fn diffuse(p: DVec3, q: DVec3) -> f64 {
    0.8 * (q - p).normalize().y.max(0.0)
}

/// The image size of the known-answer tests, and the rows whose pixels see
/// only the plane (the middle row holds the horizon).
const W: u32 = 4;
const H: u32 = 5;
const PLANE_ROWS: [u32; 2] = [3, 4];
const SEEDS: u32 = 256;

/// Renders `scene` in f64 with `SEEDS` seeds and checks every plane pixel's
/// mean (red channel; the scene is grey) against `truth(x, y)` within four
/// standard errors of that mean, plus 1e-6 for the samples' 24-bit grid.
fn assert_unbiased(what: &str, scene: &Scene, truth: impl Fn(u32, u32) -> f64) {
    for sampler in Sampler::ALL {
        let renders: Vec<Framebuffer> = (0..SEEDS)
            .map(|seed| {
                let mut s = scene.clone();
                s.settings.seed = Some(1000 + seed);
                s.settings.sampler = Some(sampler);
                render_cpu(&s, W, H, Precision::F64, WHITE)
            })
            .collect();
        for y in PLANE_ROWS {
            for x in 0..W {
                let values: Vec<f64> = renders
                    .iter()
                    .map(|r| f64::from(r.pixels[(y * W + x) as usize][0]))
                    .collect();
                let n = values.len() as f64;
                let mean = values.iter().sum::<f64>() / n;
                let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
                let standard_error = (var / n).sqrt();
                let expected = truth(x, y);
                eprintln!(
                    "{what}, {sampler}, pixel ({x}, {y}): mean {mean:.7} truth {expected:.7} (standard error {standard_error:.1e})"
                );
                assert!(
                    (mean - expected).abs() <= 4.0 * standard_error + 1e-6,
                    "{what}, {sampler}, pixel ({x}, {y}): mean {mean} over {SEEDS} seeds, truth {expected}, standard error {standard_error}"
                );
            }
        }
    }
}

/// A rectangle light and a sphere light over a plane, one sample per pixel
/// at its centre: the pixel is the light's mean diffuse term over its area
/// (a rectangle's, or the disc a sphere light shows the point).
#[test]
fn area_lights_are_unbiased() {
    let camera = Camera::new(W, H);
    let nodes = gauss_legendre(48);
    let settings = "shadow_samples: 16\n";

    let (centre, eu, ev) = (
        DVec3::new(0.5, 1.0, -4.0),
        DVec3::new(3.0, 0.0, 0.0),
        DVec3::new(0.0, 0.5, 2.5),
    );
    let rect = plane_scene(
        "light\npos: 0.5 1 -4\ncol: 1 1 1\nedge_u: 3 0 0\nedge_v: 0 0.5 2.5\n",
        settings,
    );
    assert_unbiased("rectangle light", &rect, |x, y| {
        let p = on_plane(&camera, x, y, 0.5, 0.5);
        let mut sum = 0.0;
        for &(s, ws) in &nodes {
            for &(t, wt) in &nodes {
                sum += ws * wt * diffuse(p, centre + eu * (s - 0.5) + ev * (t - 0.5));
            }
        }
        sum
    });

    let (centre, radius) = (DVec3::new(-0.5, 0.5, -3.5), 0.8);
    let sphere = plane_scene(
        "light\npos: -0.5 0.5 -3.5\ncol: 1 1 1\nrad: 0.8\n",
        settings,
    );
    assert_unbiased("sphere light", &sphere, |x, y| {
        let p = on_plane(&camera, x, y, 0.5, 0.5);
        // The disc facing p: any orthonormal pair across the line to p (the
        // disc is round, so its turn about that line does not matter).
        let w = (centre - p).normalize();
        let u = w.any_orthonormal_vector();
        let v = w.cross(u);
        let turns = 96;
        let mut sum = 0.0;
        for &(r, wr) in &nodes {
            for k in 0..turns {
                let phi = std::f64::consts::TAU * (k as f64 + 0.5) / turns as f64;
                let q = centre + (u * phi.cos() + v * phi.sin()) * (r * radius);
                // Area element r dr dphi over the disc's area pi R^2, with
                // r in [0, 1] scaled by R: 2 r dr dphi / (2 pi).
                sum += wr * 2.0 * r / turns as f64 * diffuse(p, q);
            }
        }
        sum
    });
}

/// A point light moving across the plane during the shutter, 16 samples
/// over the pixel: the pixel is the diffuse term's mean over its area and
/// the shutter time. Samples whose time followed their place in the pixel
/// would converge to another value (the trap of docs/effects.md).
#[test]
fn pixel_and_time_samples_are_unbiased() {
    let camera = Camera::new(W, H);
    let scene = plane_scene(
        "light\npos: -2 1 -4\ncol: 1 1 1\nvel: 96 0 0\n",
        "spp: 16\nshutter: 1\n",
    );
    let effects = Effects::resolve(&scene.settings);
    // The renderers hold the shutter's length in f32, as the shader does.
    let shutter = f64::from(effects.shutter_seconds() as f32);
    let (start, velocity) = (DVec3::new(-2.0, 1.0, -4.0), DVec3::new(96.0, 0.0, 0.0));
    let nodes = gauss_legendre(24);
    assert_unbiased("moving light", &scene, |x, y| {
        let mut sum = 0.0;
        for &(u, wu) in &nodes {
            for &(v, wv) in &nodes {
                let p = on_plane(&camera, x, y, u, v);
                for &(t, wt) in &nodes {
                    sum += wu * wv * wt * diffuse(p, start + velocity * (t * shutter));
                }
            }
        }
        sum
    });
}

/// The GPU renders what the CPU twin does with `stratified` too (the
/// default sampler is checked on every effect scene in tests/effects.rs).
#[test]
fn the_stratified_sampler_agrees_across_backends() {
    for name in ["soft_shadows", "antialias", "motion_blur", "all_effects"] {
        let path = repo_path(&format!("scenes/effects/{name}.scene"));
        let mut scene = glint::scene::read_scene(&path).expect("effect scene parses");
        scene.settings.sampler = Some(Sampler::Stratified);
        let (w, h) = if name == "all_effects" {
            (96, 72)
        } else {
            (160, 120)
        };
        assert_backends_agree(&format!("stratified-{name}"), &scene, w, h, 1);
    }
}

/// Same seed, same image, with either sampler, run after run and on the
/// GPU; another seed or the other sampler, another image.
#[test]
fn each_sampler_gives_the_same_image_for_a_seed() {
    let path = repo_path("scenes/effects/all_effects.scene");
    let base = glint::scene::read_scene(&path).expect("effect scene parses");
    let mut images = Vec::new();
    for sampler in Sampler::ALL {
        let mut scene = base.clone();
        scene.settings.spp = Some(2);
        scene.settings.shadow_samples = Some(2);
        scene.settings.sampler = Some(sampler);
        let a = render_cpu(&scene, 48, 36, Precision::F32, WHITE);
        let b = render_cpu(&scene, 48, 36, Precision::F32, WHITE);
        assert_eq!(a.pixels, b.pixels, "{sampler}: CPU run to run");
        let mut other = scene.clone();
        other.settings.seed = Some(7);
        let c = render_cpu(&other, 48, 36, Precision::F32, WHITE);
        assert_ne!(
            a.pixels, c.pixels,
            "{sampler}: the seed changes the samples"
        );
        if let Some(g1) = render_gpu(&scene, 48, 36, WHITE) {
            let g2 = render_gpu(&scene, 48, 36, WHITE).expect("GPU");
            assert_eq!(g1.pixels, g2.pixels, "{sampler}: GPU run to run");
        }
        images.push(a);
    }
    assert_ne!(images[0].pixels, images[1].pixels, "the samplers differ");
}

/// From the same samples, `sobol`'s error is below `stratified`'s on a
/// scene with antialiasing, a sphere light and motion blur (five
/// dimensions a sample), at every count from 16 on, and it keeps falling
/// (a sampler that stopped covering a dimension would level off).
#[test]
fn sobol_reaches_a_lower_error_from_the_same_samples() {
    let base = scene_from(CONVERGENCE_SCENE);
    let (w, h) = (40u32, 30u32);
    let mut reference = base.clone();
    reference.settings.spp = Some(4096);
    reference.settings.seed = Some(1_000_003);
    let truth = render_cpu(&reference, w, h, Precision::F64, WHITE);
    let error = |sampler: Sampler, n: u32| {
        let mut s = base.clone();
        s.settings.spp = Some(n);
        s.settings.sampler = Some(sampler);
        rms(&render_cpu(&s, w, h, Precision::F32, WHITE), &truth)
    };
    let counts = [16u32, 64, 256];
    let sobol: Vec<f64> = counts.iter().map(|&n| error(Sampler::Sobol, n)).collect();
    let stratified: Vec<f64> = counts
        .iter()
        .map(|&n| error(Sampler::Stratified, n))
        .collect();
    eprintln!("RMSE at {counts:?} samples: sobol {sobol:?}, stratified {stratified:?}");
    for i in 0..counts.len() {
        assert!(
            sobol[i] < stratified[i],
            "{} samples: sobol {} against stratified {}",
            counts[i],
            sobol[i],
            stratified[i]
        );
        if i > 0 {
            assert!(
                sobol[i] < 0.6 * sobol[i - 1],
                "sobol levels off: {sobol:?} at {counts:?}"
            );
        }
    }
}
