//! The five effects (reflection, antialiasing, area lights, motion, motion
//! blur): GPU against the CPU twin with the same sample sequence, analytic
//! checks, Monte Carlo convergence against a CPU f64 reference, and the
//! specialised shader against the generic one.

mod common;

use common::*;
use glint::cpu::Precision;
use glint::features::Features;
use glint::images::compare::compare_framebuffers;
use glint::images::framebuffer::Framebuffer;
use glint::scene::{Effects, LightShape, Scene};

fn effect_scene(name: &str) -> Scene {
    let path = repo_path(&format!("scenes/effects/{name}.scene"));
    glint::scene::read_scene(&path).expect("effect scene parses")
}

const EFFECT_SCENES: [&str; 5] = [
    "reflect",
    "soft_shadows",
    "antialias",
    "motion_blur",
    "all_effects",
];

/// The foundation's GPU-vs-CPU tolerance; at least one pixel may differ,
/// since one flipped sample can move a small image's only marginal pixel.
fn check_agree(name: &str, scene: &Scene, w: u32, h: u32) {
    assert_backends_agree(&format!("effects-{name}"), scene, w, h, 1);
}

#[test]
fn every_effect_scene_agrees_across_backends() {
    for name in EFFECT_SCENES {
        let scene = effect_scene(name);
        // all_effects samples 16 x 16 x 2 shadow rays per pixel: smaller.
        let (w, h) = if name == "all_effects" {
            (160, 120)
        } else {
            (320, 240)
        };
        check_agree(name, &scene, w, h);
    }
}

#[test]
fn animation_frames_agree_across_backends() {
    let scene = effect_scene("motion_blur");
    let effects = Effects::resolve(&scene.settings);
    for frame in [0, 5, 11] {
        let at = scene.at_time(effects.frame_time(frame));
        check_agree(&format!("motion_blur-frame{frame}"), &at, 160, 120);
    }
}

/// The generic shader (every effect compiled in, switched off by the
/// settings) renders what the specialised one does: on classic files, and
/// on every effect scene.
#[test]
fn generic_shader_renders_what_the_specialised_one_does() {
    let mut scenes: Vec<(String, Scene, u32, u32)> = Vec::new();
    for name in CLASSIC {
        if let Some(s) = classic_scene(name) {
            scenes.push((name.to_string(), s, 320, 240));
        }
    }
    for name in EFFECT_SCENES {
        let (w, h) = if name == "all_effects" {
            (96, 72)
        } else {
            (160, 120)
        };
        scenes.push((name.to_string(), effect_scene(name), w, h));
    }
    for (name, scene, w, h) in scenes {
        let Some(special) = render_gpu(&scene, w, h, WHITE) else {
            return;
        };
        let generic = render_gpu_with(&scene, w, h, WHITE, Features::ALL).expect("GPU");
        let cmp = compare_framebuffers(&special, &generic, THRESHOLD_LEVELS).expect("size");
        let allowed = (((w * h) as f64 * MAX_DIFFERING_FRACTION).floor() as usize).max(1);
        assert_within(
            &format!("generic-{name}"),
            &generic,
            &special,
            &cmp,
            allowed,
        );
    }
}

/// Reflection depth 0 is the plain image, bit for bit: on the CPU, and on
/// the GPU with reflection compiled in and switched off at run time.
#[test]
fn reflection_depth_zero_equals_the_plain_image_exactly() {
    let mut scene = effect_scene("reflect");
    scene.settings.reflect = Some(0);
    let plain = render_cpu(&scene, 160, 120, Precision::F32, WHITE);
    let mut deep = scene.clone();
    deep.settings.reflect = Some(4);
    let reflected = render_cpu(&deep, 160, 120, Precision::F32, WHITE);
    assert_ne!(
        plain.pixels, reflected.pixels,
        "reflection changes the image"
    );
    // The same scene with no ks anywhere: reflection has nothing to add.
    let mut matte = deep.clone();
    for s in &mut matte.spheres {
        s.material.ks = glam::DVec3::ZERO;
    }
    for m in &mut matte.materials {
        m.ks = glam::DVec3::ZERO;
    }
    let mut matte_plain = matte.clone();
    matte_plain.settings.reflect = Some(0);
    assert_eq!(
        render_cpu(&matte, 160, 120, Precision::F32, WHITE).pixels,
        render_cpu(&matte_plain, 160, 120, Precision::F32, WHITE).pixels
    );
    let Some(gpu_plain) = render_gpu(&scene, 160, 120, WHITE) else {
        return;
    };
    let generic = render_gpu_with(&scene, 160, 120, WHITE, Features::ALL).expect("GPU");
    let special = Features {
        reflection: true,
        ..Features::of(&scene, &Effects::resolve(&scene.settings))
    };
    let compiled_in = render_gpu_with(&scene, 160, 120, WHITE, special).expect("GPU");
    assert_eq!(
        compiled_in.pixels, gpu_plain.pixels,
        "reflection compiled in, depth 0"
    );
    assert_eq!(generic.pixels, gpu_plain.pixels, "generic shader, depth 0");
}

/// A ground lit by a small sphere light, half of it under a large occluder
/// between ground and light. Returns (scene, pixels fully in the umbra,
/// pixels fully outside the penumbra), picked from the geometry.
type Pixels = Vec<(u32, u32)>;

fn umbra_scene(radius: f64) -> (Scene, Pixels, Pixels) {
    let text = format!(
        "4\namb: 0.1 0.12 0.14\nshadow_samples: 16\n\
         light\npos: 0 4 -8\ncol: 0.9 0.85 0.8\nrad: {radius}\n\
         triangle\n\
         pos: -40 -1 0 nor: 0 1 0 dif: 0.8 0.7 0.6 spe: 0 0 0 shi: 10\n\
         pos: 40 -1 0 nor: 0 1 0 dif: 0.8 0.7 0.6 spe: 0 0 0 shi: 10\n\
         pos: 0 -1 -80 nor: 0 1 0 dif: 0.8 0.7 0.6 spe: 0 0 0 shi: 10\n\
         triangle\n\
         pos: -40 1 -1 nor: 0 -1 0 dif: 0.5 0.5 0.5 spe: 0 0 0 shi: 1\n\
         pos: 0 1 -1 nor: 0 -1 0 dif: 0.5 0.5 0.5 spe: 0 0 0 shi: 1\n\
         pos: 0 1 -40 nor: 0 -1 0 dif: 0.5 0.5 0.5 spe: 0 0 0 shi: 1\n\
         triangle\n\
         pos: -40 1 -1 nor: 0 -1 0 dif: 0.5 0.5 0.5 spe: 0 0 0 shi: 1\n\
         pos: 0 1 -40 nor: 0 -1 0 dif: 0.5 0.5 0.5 spe: 0 0 0 shi: 1\n\
         pos: -40 1 -40 nor: 0 -1 0 dif: 0.5 0.5 0.5 spe: 0 0 0 shi: 1\n"
    );
    let scene = scene_from(&text);
    let (w, h) = (160u32, 120u32);
    let camera = glint::camera::Camera::new(w, h);
    let (mut umbra, mut lit) = (Vec::new(), Vec::new());
    for y in 0..h {
        for x in 0..w {
            let nx = (2.0 * (f64::from(x) + 0.5) / f64::from(w) - 1.0) * camera.half_extent[0];
            let ny = (1.0 - 2.0 * (f64::from(y) + 0.5) / f64::from(h)) * camera.half_extent[1];
            if ny >= -0.05 {
                continue;
            }
            // Ground point along the pixel-centre ray (y = -1).
            let t = -1.0 / ny;
            let (gx, gz) = (t * nx, -t);
            if !(-30.0..-2.0).contains(&gz) || gx.abs() > 30.0 {
                continue;
            }
            // The occluder's edge (x = 0 at y = 1) seen from the ground point
            // sweeps x_light in [-r, r] at y = 4: fully blocked when even
            // x = +r is hidden, fully lit when even x = -r is visible (the
            // occluder spans z in (-40, -1) along the whole path here).
            let at_occluder = |lx: f64| gx + (lx - gx) * (2.0 / 5.0);
            let lz = |frac: f64| gz + (-8.0 - gz) * frac;
            if !(-39.0..-1.5).contains(&lz(0.4)) {
                continue;
            }
            let margin = 0.05;
            if at_occluder(radius) < -margin {
                umbra.push((x, y));
            } else if at_occluder(-radius) > margin {
                lit.push((x, y));
            }
        }
    }
    (scene, umbra, lit)
}

fn pixel(fb: &Framebuffer, (x, y): (u32, u32)) -> [f32; 3] {
    fb.pixels[(y * fb.width + x) as usize]
}

#[test]
fn umbra_is_ambient_and_outside_the_penumbra_is_the_point_light_value() {
    let (scene, umbra, lit) = umbra_scene(0.3);
    assert!(
        umbra.len() > 500 && lit.len() > 500,
        "{} {}",
        umbra.len(),
        lit.len()
    );
    let ambient = scene.ambient.as_vec3().to_array();
    let mut point = scene.clone();
    point.lights[0].shape = LightShape::Point;
    // Outside the penumbra the occluder hides no sample: the image equals
    // the one without the occluder exactly, and the point light's to within
    // the sampling of L.N across the light: it varies by about r/d (4-6%)
    // over the disc, and 16 stratified samples average that to ~0.7%
    // (measured worst: 1.05 levels); 3 levels bound it. The ground is
    // matte: a highlight spreads with the light's size by design.
    let mut open = scene.clone();
    open.triangles.truncate(1);
    for precision in [Precision::F64, Precision::F32] {
        let area = render_cpu(&scene, 160, 120, precision, WHITE);
        let unblocked = render_cpu(&open, 160, 120, precision, WHITE);
        let pt = render_cpu(&point, 160, 120, precision, WHITE);
        for &p in &umbra {
            assert_eq!(
                pixel(&area, p),
                ambient,
                "umbra pixel {p:?} ({precision:?})"
            );
        }
        for &p in &lit {
            assert_eq!(pixel(&area, p), pixel(&unblocked, p), "lit pixel {p:?}");
            let (a, b) = (pixel(&area, p), pixel(&pt, p));
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() < 3.0 / 255.0, "{p:?}: {a:?} vs {b:?}");
            }
        }
    }
    let Some(gpu) = render_gpu(&scene, 160, 120, WHITE) else {
        return;
    };
    for &p in &umbra {
        assert_eq!(pixel(&gpu, p), ambient, "GPU umbra pixel {p:?}");
    }
    let unblocked = render_gpu(&open, 160, 120, WHITE).expect("GPU");
    for &p in &lit {
        let (a, b) = (pixel(&gpu, p), pixel(&unblocked, p));
        for c in 0..3 {
            assert!(
                (a[c] - b[c]).abs() < 1e-5,
                "GPU lit pixel {p:?}: {a:?} vs {b:?}"
            );
        }
    }
}

/// Same seed, same image (run after run, and the GPU twice); another seed,
/// another noise pattern.
#[test]
fn sampling_is_deterministic_per_seed() {
    let mut scene = effect_scene("soft_shadows");
    scene.settings.spp = Some(2);
    scene.settings.shadow_samples = Some(2);
    let a = render_cpu(&scene, 96, 72, Precision::F32, WHITE);
    let b = render_cpu(&scene, 96, 72, Precision::F32, WHITE);
    assert_eq!(a.pixels, b.pixels);
    let mut other = scene.clone();
    other.settings.seed = Some(7);
    let c = render_cpu(&other, 96, 72, Precision::F32, WHITE);
    assert_ne!(a.pixels, c.pixels, "the seed changes the samples");
    let Some(g1) = render_gpu(&scene, 96, 72, WHITE) else {
        return;
    };
    let g2 = render_gpu(&scene, 96, 72, WHITE).expect("GPU");
    assert_eq!(g1.pixels, g2.pixels, "GPU run to run");
}

/// Objects that do not move look the same with the shutter open or closed
/// (same pixel samples; only moving things take a time).
#[test]
fn motion_blur_leaves_static_objects_alone() {
    // A moving sphere on the left, a static one on the right, lit from the
    // camera so no shadow crosses between the halves.
    let text = "4\namb: 0.1 0.1 0.1\nspp: 4\nshutter: 1\n\
        light\npos: 0 0 0\ncol: 0.8 0.8 0.8\n\
        sphere\npos: -2 0 -8\nrad: 1\ndif: 0.8 0.2 0.2\nspe: 0.3 0.3 0.3\nshi: 20\nvel: 0 12 0\n\
        sphere\npos: 2 0 -8\nrad: 1\ndif: 0.2 0.8 0.2\nspe: 0.3 0.3 0.3\nshi: 20\n\
        sphere\npos: 2.5 1.2 -7\nrad: 0.3\ndif: 0.2 0.2 0.8\nspe: 0.3 0.3 0.3\nshi: 20\n";
    let blurred = scene_from(text);
    let mut still = blurred.clone();
    still.settings.shutter = Some(0.0);
    let (w, h) = (96u32, 72u32);
    let a = render_cpu(&blurred, w, h, Precision::F32, WHITE);
    let b = render_cpu(&still, w, h, Precision::F32, WHITE);
    let half = |fb: &Framebuffer, right: bool| -> Vec<[f32; 3]> {
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, _)| (x >= w / 2) == right)
            .map(|p| pixel(fb, p))
            .collect()
    };
    assert_eq!(half(&a, true), half(&b, true), "static half unchanged");
    assert_ne!(half(&a, false), half(&b, false), "moving half blurred");
    let Some(ga) = render_gpu(&blurred, w, h, WHITE) else {
        return;
    };
    let gb = render_gpu(&still, w, h, WHITE).expect("GPU");
    for (p, q) in half(&ga, true).iter().zip(half(&gb, true)) {
        for c in 0..3 {
            assert!(
                (p[c] - q[c]).abs() < 1e-5,
                "GPU static half: {p:?} vs {q:?}"
            );
        }
    }
}

/// Least-squares slope of log(err) against log(n).
fn slope(points: &[(f64, f64)]) -> f64 {
    let xs: Vec<f64> = points.iter().map(|p| p.0.ln()).collect();
    let ys: Vec<f64> = points.iter().map(|p| p.1.ln()).collect();
    let (mx, my) = (
        xs.iter().sum::<f64>() / xs.len() as f64,
        ys.iter().sum::<f64>() / ys.len() as f64,
    );
    let num: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let den: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    num / den
}

/// The Monte Carlo rate: with one shadow sample per pixel sample, the
/// `stratified` sampler's pixel estimate averages independent draws over
/// light area and shutter time (the pixel area stratified), so its RMS
/// error against a converged CPU f64 image falls as n^-1/2 (`sobol`, the
/// default, faster: tests/samplers.rs). A biased sampler (a wrong pdf, a stratum never drawn,
/// samples correlated across n) levels off instead and flattens the slope.
/// Tolerance: the fitted slope lies in [-0.65, -0.4] (stratifying the pixel
/// may steepen it a little; four points of noise move it by ~0.05).
#[test]
fn error_falls_at_the_monte_carlo_rate() {
    let mut base = scene_from(CONVERGENCE_SCENE);
    base.settings.sampler = Some(glint::scene::Sampler::Stratified);
    let (w, h) = (40u32, 30u32);
    let mut reference = base.clone();
    reference.settings.spp = Some(4096);
    reference.settings.seed = Some(1_000_003);
    let truth = render_cpu(&reference, w, h, Precision::F64, WHITE);
    let mut cpu_points = Vec::new();
    let mut gpu_points = Vec::new();
    for n in [4u32, 16, 64, 256] {
        let mut s = base.clone();
        s.settings.spp = Some(n);
        let cpu = render_cpu(&s, w, h, Precision::F32, WHITE);
        cpu_points.push((f64::from(n), rms(&cpu, &truth)));
        if let Some(gpu) = render_gpu(&s, w, h, WHITE) {
            gpu_points.push((f64::from(n), rms(&gpu, &truth)));
        }
    }
    let cpu_slope = slope(&cpu_points);
    eprintln!("convergence: CPU f32 {cpu_points:?} slope {cpu_slope:.3}");
    assert!((-0.65..=-0.4).contains(&cpu_slope), "CPU slope {cpu_slope}");
    if !gpu_points.is_empty() {
        let gpu_slope = slope(&gpu_points);
        eprintln!("convergence: GPU {gpu_points:?} slope {gpu_slope:.3}");
        assert!((-0.65..=-0.4).contains(&gpu_slope), "GPU slope {gpu_slope}");
        // Same samples: the same error, not merely the same rate.
        for (c, g) in cpu_points.iter().zip(&gpu_points) {
            assert!(
                (c.1 - g.1).abs() <= 0.02 * c.1,
                "n = {}: {} vs {}",
                c.0,
                c.1,
                g.1
            );
        }
    }
}

/// One pipeline per (methods, feature set, entry point): built once, then
/// taken from the cache; another feature set builds its own.
#[test]
fn pipelines_are_cached_by_feature_set() {
    use glint::gpu::{GpuRenderOptions, Kernel};
    let Some(gpu) = gpu() else {
        return;
    };
    let gpu = gpu.lock().unwrap_or_else(|e| e.into_inner());
    // Naive methods: a variant no other test in this binary builds.
    let options = |features| GpuRenderOptions {
        methods: glint::methods::Methods::Naive,
        features,
        ..Default::default()
    };
    let a = options(Features {
        triangles: true,
        area_lights: true,
        ..Features::default()
    });
    let b = options(Features {
        triangles: true,
        multisample: true,
        ..Features::default()
    });
    let scene = glint::layout::GpuScene::pack(&Scene::default(), &glint::bvh::Bvh::default());
    let first = gpu
        .renderer
        .prepare(&scene, &a, Kernel::Render)
        .expect("build");
    assert!(!first.is_zero(), "first use builds");
    let again = gpu
        .renderer
        .prepare(&scene, &a, Kernel::Render)
        .expect("cached");
    assert!(again.is_zero(), "second use is cached");
    let other = gpu
        .renderer
        .prepare(&scene, &b, Kernel::Render)
        .expect("build");
    assert!(!other.is_zero(), "another feature set builds its own");
}
