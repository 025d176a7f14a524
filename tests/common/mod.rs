//! Helpers shared by the integration tests: scene lookup, one GPU renderer per
//! test binary, rendering on each backend, and failure artefacts.
#![allow(dead_code)] // each test binary uses a different subset

pub mod cli;

use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

use glint::bvh::Bvh;
use glint::camera::Camera;
use glint::cpu::{CpuOptions, Precision};
use glint::features::Features;
use glint::gpu::{Context, ContextOptions, GpuRenderOptions, GpuRenderer};
use glint::images::compare::Comparison;
use glint::images::framebuffer::{write_image, Framebuffer};
use glint::layout::GpuScene;
use glint::scene::{parse_scene, Effects, Scene};

pub const CLASSIC: [&str; 5] = glint::suites::bench::CLASSIC_SCENES;

/// Prints past libtest's output capture (which only intercepts the print
/// macros), so that a skip is visible in a plain `cargo test` run.
pub fn notice(message: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "{message}");
}

pub fn in_ci() -> bool {
    std::env::var_os("CI").is_some_and(|v| !v.is_empty() && v != "false")
}

pub fn repo_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// `../shared/scenes/classic`, or `None` with a visible message when absent
/// (a user's clone has none). In CI its absence is a failure.
pub fn classic_dir() -> Option<PathBuf> {
    let dir = repo_path(glint::suites::bench::CLASSIC_DIR);
    if dir.is_dir() {
        return Some(dir);
    }
    assert!(
        !in_ci(),
        "CI is set but the classic scenes are missing at {}",
        dir.display()
    );
    notice(&format!(
        "SKIPPED: classic scenes not found at {} (they live outside this repository)",
        dir.display()
    ));
    None
}

pub fn classic_scene(name: &str) -> Option<Scene> {
    let path = classic_dir()?.join(format!("{name}.scene"));
    Some(glint::scene::read_scene(&path).expect("classic scene parses"))
}

/// Every `*.scene` under the project's `scenes/` (recursively, except the
/// generated `scenes/hard/`, which tests/hard.rs covers, the sampled
/// `scenes/effects/`, which tests/effects.rs covers at smaller sizes, and
/// `scenes/real/`, whose models are not in the repository: tests/mesh.rs
/// covers real models), sorted.
pub fn own_scenes() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
            let p = entry.path();
            if p.is_dir() {
                if !p.ends_with("hard") && !p.ends_with("effects") && !p.ends_with("real") {
                    walk(&p, out);
                }
            } else if p.extension().is_some_and(|e| e == "scene") {
                out.push(p);
            }
        }
    }
    let mut out = Vec::new();
    walk(&repo_path("scenes"), &mut out);
    out.sort();
    out
}

pub fn scene_from(text: &str) -> Scene {
    parse_scene(text.as_bytes(), "<test>").expect("test scene parses")
}

pub struct Gpu {
    pub ctx: Context,
    pub renderer: GpuRenderer,
}

/// One GPU renderer per test binary, serialised (a Vulkan queue may not be
/// used from two threads at once). `None` (with a message) when there is no
/// Vulkan device, which fails the test in CI. The validation layer is on
/// whenever it is installed, and required in CI.
pub fn gpu() -> Option<&'static Mutex<Gpu>> {
    static GPU: OnceLock<Option<Mutex<Gpu>>> = OnceLock::new();
    GPU.get_or_init(|| {
        let options = ContextOptions {
            device: None,
            validation: true,
            pipeline_cache: None,
            window: None,
        };
        let created = match Context::new(&options) {
            Err(glint::gpu::GpuError::NoValidationLayer) if !in_ci() => {
                Context::new(&ContextOptions {
                    validation: false,
                    ..options
                })
            }
            other => other,
        };
        match created {
            Ok(ctx) => {
                assert!(
                    ctx.validation_active() || !in_ci(),
                    "CI is set but VK_LAYER_KHRONOS_validation is not installed"
                );
                notice(&format!(
                    "GPU tests on: {} ({}), validation {}",
                    ctx.info().name,
                    ctx.info().driver,
                    if ctx.validation_active() {
                        "on"
                    } else {
                        "off (layer not installed)"
                    }
                ));
                let renderer = GpuRenderer::new(&ctx).expect("trace pipeline builds");
                Some(Mutex::new(Gpu { ctx, renderer }))
            }
            Err(e) => {
                assert!(!in_ci(), "CI is set but no Vulkan device is usable: {e}");
                notice(&format!(
                    "SKIPPED: GPU parts of these tests: no Vulkan device ({e})"
                ));
                None
            }
        }
    })
    .as_ref()
}

/// Renders on the CPU with the scene's own settings.
pub fn render_cpu(
    scene: &Scene,
    w: u32,
    h: u32,
    precision: Precision,
    bg: [f32; 3],
) -> Framebuffer {
    let effects = Effects::resolve(&scene.settings);
    let options = CpuOptions {
        background: bg,
        precision,
        effects,
        ..CpuOptions::default()
    };
    let bvh = Bvh::for_render(scene, &effects);
    glint::cpu::render(
        scene,
        &bvh,
        &Camera::with_fov(w, h, scene.fov()),
        &options,
        &|_, _| {},
    )
}

/// Renders on the GPU with the scene's own settings, the shader specialised
/// for it, and asserts the validation layer stayed silent.
pub fn render_gpu(scene: &Scene, w: u32, h: u32, bg: [f32; 3]) -> Option<Framebuffer> {
    let effects = Effects::resolve(&scene.settings);
    render_gpu_with(scene, w, h, bg, Features::of(scene, &effects))
}

/// As `render_gpu`, with the shader built for `features` (a superset of
/// what the scene calls for, e.g. `Features::ALL`).
pub fn render_gpu_with(
    scene: &Scene,
    w: u32,
    h: u32,
    bg: [f32; 3],
    features: Features,
) -> Option<Framebuffer> {
    let gpu = gpu()?.lock().unwrap_or_else(|e| e.into_inner());
    let before = gpu.ctx.validation_messages();
    let effects = Effects::resolve(&scene.settings);
    let packed = GpuScene::pack(scene, &Bvh::for_render(scene, &effects));
    let options = GpuRenderOptions {
        // Small tiles so that even small test images cross tile borders.
        tile_size: 64,
        effects,
        features,
        ..Default::default()
    };
    let (fb, _) = gpu
        .renderer
        .render(
            &packed,
            &Camera::with_fov(w, h, scene.fov()),
            bg,
            &options,
            &|_, _| {},
        )
        .expect("GPU render succeeds");
    let messages = gpu.ctx.validation_messages() - before;
    assert_eq!(
        messages, 0,
        "Vulkan validation reported {messages} message(s) (printed above)"
    );
    Some(fb)
}

pub const WHITE: [f32; 3] = [1.0; 3];

/// Prints the comparison's summary; when more than `allowed` pixels exceed
/// its threshold, writes the failure artefacts and fails naming them.
pub fn assert_within(
    name: &str,
    actual: &Framebuffer,
    expected: &Framebuffer,
    cmp: &Comparison,
    allowed: usize,
) {
    eprintln!(
        "{name}: max {:.4} levels, mean {:.6}, {} pixel(s) over {}, PSNR {:.1} dB, FLIP {:.6}",
        cmp.max_abs, cmp.mean_abs, cmp.over_threshold, cmp.threshold, cmp.psnr, cmp.flip_mean
    );
    if cmp.over_threshold > allowed {
        let dir = write_artifacts(name, actual, expected, cmp);
        panic!(
            "{name}: {} pixels differ by more than {} levels (allowed {allowed}); \
             images in {}\n{cmp}",
            cmp.over_threshold,
            cmp.threshold,
            dir.display()
        );
    }
}

/// Writes `<name>-actual.png`, `-expected.png` and `-diff.png` under
/// `target/test-artifacts/` and returns where.
pub fn write_artifacts(
    name: &str,
    actual: &Framebuffer,
    expected: &Framebuffer,
    cmp: &Comparison,
) -> PathBuf {
    let dir = repo_path("target/test-artifacts");
    std::fs::create_dir_all(&dir).expect("create target/test-artifacts");
    let save = |suffix: &str, img: &image::RgbImage| {
        write_image(img, &dir.join(format!("{name}-{suffix}.png")), 95).expect("write artefact");
    };
    let expected = expected.to_rgb8();
    save("actual", &actual.to_rgb8());
    save("diff", &cmp.diff_image(&expected));
    save("expected", &expected);
    dir
}

/// Pixels whose value is NaN or infinite on any channel.
pub fn assert_finite(name: &str, fb: &Framebuffer) {
    assert_eq!(fb.non_finite_count(), 0, "{name}: NaN/Inf pixels");
}

/// Per-channel difference (levels, 0-255) above which a pixel counts as differing.
///
/// Set on lavapipe (Mesa 22.3.6, LLVM 15.0.6) on 2026-11-22: the measured
/// worst pixel over all classic scenes at 640x480 is 0.0032 levels (spheres,
/// shininess 200), from the device's own pow/inverseSqrt and rounding. The
/// threshold leaves ~80x room for other drivers' pow (exp2(y*log2 x) with
/// approximate log2) and FMA contraction, yet is well under one 8-bit step.
pub const THRESHOLD_LEVELS: f64 = 0.25;
/// Pixels allowed over the threshold: where a rounding difference flips a
/// hit/miss or shadow decision exactly on a silhouette or shadow edge.
/// Measured on lavapipe: none. Allowed: 1 in 20,000 pixels (15 at 640x480),
/// for devices that contract to FMA where lavapipe does not.
pub const MAX_DIFFERING_FRACTION: f64 = 5e-5;

/// Renders `scene` on the CPU f32 twin and the GPU and holds them to the
/// tolerance above; `min_allowed` pixels may differ whatever the image size.
pub fn assert_backends_agree(name: &str, scene: &Scene, w: u32, h: u32, min_allowed: usize) {
    let cpu = render_cpu(scene, w, h, Precision::F32, WHITE);
    assert_finite(name, &cpu);
    let Some(gpu) = render_gpu(scene, w, h, WHITE) else {
        return;
    };
    assert_finite(name, &gpu);
    let cmp = glint::images::compare::compare_framebuffers(&cpu, &gpu, THRESHOLD_LEVELS)
        .expect("same size");
    let allowed = (((w * h) as f64 * MAX_DIFFERING_FRACTION).floor() as usize).max(min_allowed);
    assert_within(name, &gpu, &cpu, &cmp, allowed);
}

/// A scene with antialiasing, a sphere light sampled once per pixel sample
/// and motion blur: five random dimensions a sample, for convergence tests
/// (tests/effects.rs, tests/samplers.rs).
pub const CONVERGENCE_SCENE: &str = "4\namb: 0.05 0.05 0.05\nshadow_samples: 1\nshutter: 1\n\
    light\npos: 0 5 -6\ncol: 0.9 0.9 0.9\nrad: 1.5\n\
    sphere\npos: 0 0 -6\nrad: 0.8\ndif: 0.7 0.3 0.2\nspe: 0.3 0.3 0.3\nshi: 20\nvel: 12 0 0\n\
    triangle\n\
    pos: -20 -1 0 nor: 0 1 0 dif: 0.8 0.8 0.8 spe: 0 0 0 shi: 1\n\
    pos: 20 -1 0 nor: 0 1 0 dif: 0.8 0.8 0.8 spe: 0 0 0 shi: 1\n\
    pos: 0 -1 -40 nor: 0 1 0 dif: 0.8 0.8 0.8 spe: 0 0 0 shi: 1\n\
    sphere\npos: -1.6 0.4 -5\nrad: 0.4\ndif: 0.2 0.5 0.8\nspe: 0.3 0.3 0.3\nshi: 20\n";

/// Root mean squared difference of two images of one size, over every
/// channel.
pub fn rms(a: &Framebuffer, b: &Framebuffer) -> f64 {
    let sum: f64 = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(p, q)| (0..3).map(move |c| f64::from(p[c] - q[c]).powi(2)))
        .sum();
    (sum / (a.pixels.len() * 3) as f64).sqrt()
}
