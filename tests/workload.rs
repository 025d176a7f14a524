//! The GPU image is right at any workload, or glint says why not: sample
//! counts, light counts and shadow samples far past what one shader
//! invocation can run on lavapipe (whose loops stop after 65535 iterations),
//! passes that do not change the image, device limits refused before any
//! work, and memory that stays flat over many frames.

mod common;

use common::*;
use glint::bvh::Bvh;
use glint::camera::Camera;
use glint::features::Features;
use glint::gpu::{GpuError, GpuRenderOptions};
use glint::images::framebuffer::Framebuffer;
use glint::layout::GpuScene;
use glint::scene::{Effects, Scene, Settings};
use glint::timing::Timings;

/// Renders on the shared test GPU with these pass settings; `None` without a
/// device (which fails in CI, see `gpu()`).
fn render_passes(
    scene: &Scene,
    w: u32,
    h: u32,
    tweak: impl FnOnce(&mut GpuRenderOptions),
) -> Option<Result<(Framebuffer, Timings), GpuError>> {
    let gpu = gpu()?.lock().unwrap_or_else(|e| e.into_inner());
    Some(render_locked(&gpu, scene, w, h, tweak))
}

/// `render_passes` on a GPU the caller holds locked: for a sequence of
/// renders with no other test's in between.
fn render_locked(
    gpu: &Gpu,
    scene: &Scene,
    w: u32,
    h: u32,
    tweak: impl FnOnce(&mut GpuRenderOptions),
) -> Result<(Framebuffer, Timings), GpuError> {
    let before = gpu.ctx.validation_messages();
    let effects = Effects::resolve(&scene.settings);
    let packed = GpuScene::pack(scene, &Bvh::for_render(scene, &effects));
    let mut options = GpuRenderOptions {
        tile_size: 64,
        effects,
        features: Features::of(scene, &effects),
        ..Default::default()
    };
    tweak(&mut options);
    let result = gpu
        .renderer
        .render(&packed, &Camera::new(w, h), WHITE, &options, &|_, _| {});
    let messages = gpu.ctx.validation_messages() - before;
    assert_eq!(
        messages, 0,
        "Vulkan validation reported {messages} message(s)"
    );
    result
}

fn with_settings(mut scene: Scene, settings: Settings) -> Scene {
    scene.settings = settings.or(scene.settings);
    scene
}

fn effect_scene(name: &str) -> Scene {
    glint::scene::read_scene(&repo_path(&format!("scenes/effects/{name}.scene")))
        .expect("effect scene parses")
}

/// `count` white point lights of total intensity ~1 on a ring above a
/// sphere, plus `spheres` small spheres: every shading point loops over all
/// the lights.
fn many_lights(count: usize, spheres: usize) -> Scene {
    let mut text = format!("{}\namb: 0.05 0.05 0.05\n", count + spheres + 1);
    text.push_str("sphere pos: 0 0 -4 rad: 1.2 dif: 0.6 0.5 0.4 spe: 0.3 0.3 0.3 shi: 20\n");
    for i in 0..spheres {
        let a = i as f64 / spheres as f64 * std::f64::consts::TAU;
        text.push_str(&format!(
            "sphere pos: {:.4} {:.4} -3 rad: 0.15 dif: 0.2 0.6 0.3 spe: 0.1 0.1 0.1 shi: 5\n",
            1.6 * a.cos(),
            1.2 * a.sin()
        ));
    }
    let c = 1.5 / count as f64;
    for i in 0..count {
        let a = i as f64 / count as f64 * std::f64::consts::TAU;
        text.push_str(&format!(
            "light pos: {:.5} 3 {:.5} col: {c:e} {c:e} {c:e}\n",
            4.0 * a.cos(),
            -4.0 + 4.0 * a.sin()
        ));
    }
    scene_from(&text)
}

/// test2 at 8192 samples per pixel: ~240k loop iterations per pixel, which
/// rendered 464 of 768 pixels wrong (up to 96 levels) in one invocation.
#[test]
fn spp_8192_matches_the_cpu() {
    let Some(scene) = classic_scene("test2") else {
        return;
    };
    let settings = Settings {
        spp: Some(8192),
        ..Settings::default()
    };
    assert_backends_agree(
        "workload-spp8192",
        &with_settings(scene, settings),
        32,
        24,
        1,
    );
}

/// Every effect at 256 samples (reflection bounces x area samples x pixel
/// samples): 205 of 768 pixels were wrong at 64 samples.
#[test]
fn all_effects_at_spp_256_match_the_cpu() {
    let settings = Settings {
        spp: Some(256),
        ..Settings::default()
    };
    let scene = with_settings(effect_scene("all_effects"), settings);
    assert_backends_agree("workload-all-effects-spp256", &scene, 16, 12, 1);
}

#[test]
fn shadow_samples_4096_match_the_cpu() {
    let settings = Settings {
        shadow_samples: Some(4096),
        ..Settings::default()
    };
    let scene = with_settings(effect_scene("soft_shadows"), settings);
    assert_backends_agree("workload-shadow-samples-4096", &scene, 24, 18, 1);
}

#[test]
fn ten_thousand_lights_match_the_cpu() {
    assert_backends_agree("workload-10k-lights", &many_lights(10_000, 0), 32, 24, 1);
}

#[test]
fn five_thousand_lights_and_forty_spheres_match_the_cpu() {
    assert_backends_agree(
        "workload-5k-lights-40-spheres",
        &many_lights(5_000, 40),
        32,
        24,
        1,
    );
}

/// Where the passes split a pixel's work does not change a bit of the
/// image: every partial sum is kept as the f32 it is. Nor does queueing a
/// tile's passes back to back with one wait (`chain_passes`), which waits
/// fewer times and counts the same rays.
#[test]
fn passes_do_not_change_the_image() {
    use glint::timing::{CLOSEST_RAYS, PASS_WAITS, SHADOW_RAYS};
    let settings = Settings {
        spp: Some(4),
        ..Settings::default()
    };
    let scene = with_settings(effect_scene("all_effects"), settings);
    let Some(one) = render_passes(&scene, 12, 10, |o| o.tile_size = 8) else {
        return;
    };
    let (one, t_one) = one.expect("render succeeds");
    for budget in [1, 7, 300] {
        let render = |chain_passes: u32| {
            render_passes(&scene, 12, 10, |o| {
                o.tile_size = 8;
                o.pass_budget = budget;
                o.chain_passes = chain_passes;
            })
            .expect("device")
            .expect("render succeeds")
        };
        let (many, t_many) = render(1);
        let (chained, t_chained) = render(glint::gpu::MAX_CHAIN);
        assert!(
            t_many.counted("passes") > t_one.counted("passes"),
            "budget {budget}: {} passes, default {}",
            t_many.counted("passes"),
            t_one.counted("passes")
        );
        assert_eq!(t_many.counted(PASS_WAITS), t_many.counted("passes"));
        assert!(
            t_chained.counted(PASS_WAITS) < t_many.counted(PASS_WAITS),
            "budget {budget}: chained passes waited {} times, one by one {}",
            t_chained.counted(PASS_WAITS),
            t_many.counted(PASS_WAITS)
        );
        for kind in [CLOSEST_RAYS, SHADOW_RAYS] {
            assert_eq!(t_chained.counted(kind), t_many.counted(kind), "{kind}");
        }
        for (i, ((a, b), c)) in one
            .pixels
            .iter()
            .zip(&many.pixels)
            .zip(&chained.pixels)
            .enumerate()
        {
            assert_eq!(
                a.map(f32::to_bits),
                b.map(f32::to_bits),
                "pixel {i} at pass budget {budget}"
            );
            assert_eq!(
                a.map(f32::to_bits),
                c.map(f32::to_bits),
                "pixel {i} at pass budget {budget}, chained"
            );
        }
    }
}

/// A tile's first pass keeps no pixel state; a tile that needs more passes
/// is redone with the resumable shader, and so start the render's later
/// tiles and the next render's, until a render needs only one pass a tile.
/// With passes queued (`chain_passes`), a render after one whose tiles
/// needed passes queues that many at each tile's start, so where no tile
/// needs more than `MAX_CHAIN` it waits once a tile.
#[test]
fn tiles_that_need_passes_are_redone_resumable_and_remembered() {
    use glint::timing::PASS_WAITS;
    let Some(gpu) = gpu() else {
        return;
    };
    // One lock for the whole sequence: the renderer remembers the last render.
    let gpu = gpu.lock().unwrap_or_else(|e| e.into_inner());
    let render_queued = |scene: &Scene, pass_budget: u32, chain_passes: u32| {
        render_locked(&gpu, scene, 12, 10, |o| {
            o.tile_size = 8;
            o.pass_budget = pass_budget;
            o.chain_passes = chain_passes;
        })
        .expect("GPU render succeeds")
    };
    let render = |scene: &Scene, pass_budget: u32| render_queued(scene, pass_budget, 1);
    let redos = |t: &Timings| t.counted(glint::gpu::RESUMABLE_REDOS);
    let simple = bowl(3);
    let heavy = effect_scene("soft_shadows");
    // One pass a tile: nothing redone, and the next render tries one pass.
    let (_, t) = render(&simple, glint::gpu::DEFAULT_PASS_BUDGET);
    assert_eq!(redos(&t), 0);
    let (first, t) = render(&heavy, 4);
    // 12x10 in 8x8 tiles: four, of which only the two in flight at the
    // first redo tried one pass.
    assert!((1..4).contains(&redos(&t)), "{} tiles redone", redos(&t));
    let (again, t) = render(&heavy, 4);
    assert_eq!(redos(&t), 0, "the render after one that needed passes");
    assert_eq!(first, again);
    let (_, t) = render(&simple, glint::gpu::DEFAULT_PASS_BUDGET);
    assert_eq!(redos(&t), 0);
    let (_, t) = render(&heavy, 4);
    assert!(redos(&t) > 0, "after a one-pass render, tiles try one pass");
    // Up to five passes a tile at a budget of 128.
    let tiles = 4;
    render(&simple, glint::gpu::DEFAULT_PASS_BUDGET);
    let (first, t_first) = render_queued(&heavy, 128, glint::gpu::MAX_CHAIN);
    let (second, t_second) = render_queued(&heavy, 128, glint::gpu::MAX_CHAIN);
    assert_eq!(first, second);
    let waits = [&t_first, &t_second].map(|t| t.counted(PASS_WAITS));
    assert!(waits[0] > tiles, "{waits:?}");
    assert_eq!(waits[1], tiles);
    assert!(t_second.counted("passes") > tiles);
}

/// A budget too large for the driver is caught, not rendered short: the
/// cut pass is detected and the tile redone with less work per pass. On
/// Mesa 22's llvmpipe the loop limit is real (65535 iterations an
/// invocation), so the retry must happen there; Mesa 25 has no such limit.
#[test]
fn a_cut_pass_is_detected_and_redone() {
    let Some(scene) = classic_scene("test2") else {
        return;
    };
    let settings = Settings {
        spp: Some(4096),
        ..Settings::default()
    };
    let scene = with_settings(scene, settings);
    let Some(result) = render_passes(&scene, 16, 8, |o| o.pass_budget = u32::MAX) else {
        return;
    };
    let (gpu, timings) = result.expect("render succeeds after retries");
    let driver = gpu_driver();
    eprintln!("{driver}: {} retries", timings.counted("retries"));
    if driver.contains("Mesa 22.") {
        assert!(
            timings.counted("retries") > 0,
            "llvmpipe's loop limit went unseen"
        );
    }
    let cpu = render_cpu(&scene, 16, 8, glint::cpu::Precision::F32, WHITE);
    let cmp =
        glint::images::compare::compare_framebuffers(&cpu, &gpu, THRESHOLD_LEVELS).expect("size");
    assert_within("workload-cut-retry", &gpu, &cpu, &cmp, 1);
}

fn gpu_driver() -> String {
    gpu().map_or(String::new(), |g| {
        let g = g.lock().unwrap_or_else(|e| e.into_inner());
        format!("{} {}", g.ctx.info().name, g.ctx.info().driver)
    })
}

/// A scene whose buffers exceed a storage-binding limit is refused before
/// any work, naming the limit, instead of rendering a truncated buffer.
#[test]
fn a_buffer_past_the_device_limit_is_refused() {
    let scene = many_lights(100, 0);
    let Some(result) = render_passes(&scene, 8, 8, |o| o.storage_limit = Some(4096)) else {
        return;
    };
    match result {
        Err(e @ GpuError::Limit { .. }) => {
            let text = e.to_string();
            assert!(text.contains("lights"), "{text}");
            assert!(text.contains("maxStorageBufferRange"), "{text}");
        }
        Err(e) => panic!("expected a limit error, got {e}"),
        Ok(_) => panic!("8000 bytes of lights rendered past a 4096-byte limit"),
    }
}

/// An `n` x `n` grid of quads (2 n^2 triangles) bent into a bowl in front
/// of the camera, with smooth normals and a different material at every
/// vertex, so every per-triangle list grows with `n`.
fn bowl(n: usize) -> Scene {
    let vertex = |i: usize, j: usize| {
        let (u, v) = (i as f64 / n as f64 - 0.5, j as f64 / n as f64 - 0.5);
        let z = -3.0 + 1.5 * (u * u + v * v);
        let normal = glam::DVec3::new(3.0 * u, 3.0 * v, 1.0).normalize();
        format!(
            "pos: {:.6} {:.6} {z:.6} nor: {:.6} {:.6} {:.6} dif: {:.4} {:.4} 0.3 spe: 0.2 0.2 0.2 shi: {}\n",
            3.0 * u,
            2.2 * v,
            normal.x,
            normal.y,
            normal.z,
            0.2 + 0.7 * (u + 0.5),
            0.2 + 0.7 * (v + 0.5),
            1 + (i + j) % 40
        )
    };
    let mut text = format!("{}\namb: 0.1 0.1 0.1\n", 2 * n * n + 2);
    text.push_str("light pos: -2 3 1 col: 0.6 0.6 0.6\nlight pos: 2 -1 0 col: 0.3 0.3 0.4\n");
    for i in 0..n {
        for j in 0..n {
            for tri in [
                [(i, j), (i + 1, j), (i + 1, j + 1)],
                [(i, j), (i + 1, j + 1), (i, j + 1)],
            ] {
                text.push_str("triangle\n");
                for (a, b) in tri {
                    text.push_str(&vertex(a, b));
                }
            }
        }
    }
    glint::scene::parse_scene(text.as_bytes(), "bowl.scene").expect("bowl parses")
}

/// On a CPU device the shader reads its hot lists another way than a GPU:
/// through their device addresses where the driver gathers those loads
/// ("Address lists" in the shader: llvmpipe from Mesa 25), else from
/// uniform copies where they fit ("Uniform lists": triangles whole or, past
/// 1,365, as corners). Either way the image is the storage lists' bit for
/// bit; lists too big for a copy, and GPUs, keep the storage lists.
#[test]
fn cpu_list_forms_render_the_storage_lists_image() {
    // 800 triangles fit a copy whole (1,365 of 48 bytes), 1,458 as corners
    // (1,820 of 36 bytes); 3,200 do not.
    for (n, copy, corners) in [(20, true, false), (27, true, true), (40, false, false)] {
        let scene = bowl(n);
        let Some(fast) = render_passes(&scene, 32, 24, |o| o.tile_size = 16) else {
            return;
        };
        let (fast, t_fast) = fast.expect("render with the CPU list forms");
        let (storage, t_storage) = render_passes(&scene, 32, 24, |o| {
            o.tile_size = 16;
            o.uniform_lists = false;
        })
        .expect("device")
        .expect("render with storage lists");
        let limits = *gpu()
            .expect("device")
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .ctx
            .limits();
        let addresses = limits.cpu && limits.device_addresses;
        let uniform = limits.cpu && !addresses && copy;
        assert_eq!(t_fast.counted("address lists"), u64::from(addresses), "{n}");
        assert_eq!(t_fast.counted("uniform lists"), u64::from(uniform), "{n}");
        assert_eq!(
            t_fast.counted("uniform corners"),
            u64::from(uniform && corners),
            "{n}"
        );
        for form in ["address lists", "uniform lists"] {
            assert_eq!(t_storage.counted(form), 0, "{n}: {form}");
        }
        for (i, (a, b)) in fast.pixels.iter().zip(&storage.pixels).enumerate() {
            assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits), "{n}: pixel {i}");
        }
    }
}

/// `prepare` builds the pipeline a render of the scene then takes from the
/// cache, whichever lists the scene gets, and whether the render before
/// needed passes (the next then starts resumable) or not.
#[test]
fn prepare_builds_the_pipeline_the_render_uses() {
    for (n, uniform_lists, after_passes) in [
        (6, true, false),
        (6, false, true),
        (27, true, true),
        (30, true, false),
    ] {
        let scene = bowl(n);
        let Some(gpu) = gpu() else {
            return;
        };
        let gpu = gpu.lock().unwrap_or_else(|e| e.into_inner());
        // A render before, with the robust methods' pipelines, that needs
        // passes or not.
        let before = if after_passes {
            effect_scene("soft_shadows")
        } else {
            bowl(3)
        };
        let (_, t) = render_locked(&gpu, &before, 12, 10, |o| {
            o.tile_size = 8;
            o.pass_budget = if after_passes { 4 } else { 1 << 16 };
        })
        .expect("render succeeds");
        // 12x10 in 8x8 tiles: four.
        assert_eq!(t.counted("passes") > 4, after_passes);
        let effects = Effects::resolve(&scene.settings);
        let packed = GpuScene::pack(&scene, &Bvh::for_render(&scene, &effects));
        let options = GpuRenderOptions {
            tile_size: 16,
            effects,
            features: Features::of(&scene, &effects),
            uniform_lists,
            // Pipelines no other test in this binary builds.
            methods: glint::methods::Methods::Naive,
            ..Default::default()
        };
        gpu.renderer
            .prepare(&packed, &options, glint::gpu::Kernel::Render)
            .expect("pipeline builds");
        let (_, timings) = gpu
            .renderer
            .render(&packed, &Camera::new(8, 6), WHITE, &options, &|_, _| {})
            .expect("render succeeds");
        assert_eq!(
            timings.phase("pipeline"),
            None,
            "{} triangles, uniform lists {uniform_lists}, after passes {after_passes}: \
             the render built its pipeline",
            packed.triangles.len()
        );
    }
}

/// Lists larger than one binding are split over several, and the image is
/// the same bit for bit; past what the split bindings hold, the render is
/// refused before any work.
#[test]
fn big_lists_split_over_bindings_render_the_same_image() {
    let scene = bowl(40);
    let packed = GpuScene::pack(&scene, &Bvh::for_render(&scene, &Effects::default()));
    // 3,200 triangles of 48 bytes need 4 chunks of 1,024 under a 64 KiB
    // limit (the last one partial), the normals too.
    assert_eq!(packed.triangles.len(), 3200);
    assert!(
        packed.materials.len() > 1000,
        "{} materials",
        packed.materials.len()
    );
    let Some(plain) = render_passes(&scene, 32, 24, |o| o.tile_size = 16) else {
        return;
    };
    let (plain, t_plain) = plain.expect("plain render");
    assert_eq!(t_plain.counted("split lists"), 0);
    let (split, t_split) = render_passes(&scene, 32, 24, |o| {
        o.tile_size = 16;
        o.storage_limit = Some(65536);
    })
    .expect("device")
    .expect("split render");
    assert_eq!(t_split.counted("split lists"), 1);
    for (i, (a, b)) in plain.pixels.iter().zip(&split.pixels).enumerate() {
        assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits), "pixel {i}");
    }
    let cpu = render_cpu(&scene, 32, 24, glint::cpu::Precision::F32, WHITE);
    let cmp =
        glint::images::compare::compare_framebuffers(&cpu, &split, THRESHOLD_LEVELS).expect("size");
    assert_within("workload-split-lists", &split, &cpu, &cmp, 1);
    // 512 triangles a chunk: 7 chunks would be needed.
    match render_passes(&scene, 32, 24, |o| {
        o.tile_size = 16;
        o.storage_limit = Some(32768);
    })
    .expect("device")
    {
        Err(e @ GpuError::Limit { .. }) => {
            let text = e.to_string();
            assert!(text.contains("triangles"), "{text}");
            assert!(text.contains("split over 4 bindings"), "{text}");
        }
        Err(e) => panic!("expected a limit error, got {e}"),
        Ok(_) => panic!("triangles rendered past 4 bindings of their limit"),
    }
}

/// Progress is reported after every pass, in pixels finished: it never goes
/// back, moves within a tile (not only when the tile ends), and ends at
/// every pixel. Rays are counted per pass, each pass's counts once.
#[test]
fn progress_counts_pixels_pass_by_pass() {
    let Some(gpu) = gpu() else {
        return;
    };
    let gpu = gpu.lock().unwrap_or_else(|e| e.into_inner());
    let scene = effect_scene("soft_shadows");
    let effects = Effects::resolve(&scene.settings);
    let packed = GpuScene::pack(&scene, &Bvh::for_render(&scene, &effects));
    let (w, h) = (48, 40);
    let calls = std::sync::Mutex::new(Vec::new());
    let record = |done: u64, total: u64| {
        calls
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push((done, total));
    };
    let run = |pass_budget: u32, chain_passes: u32, progress: &(dyn Fn(u64, u64) + Sync)| {
        let options = GpuRenderOptions {
            tile_size: 32,
            pass_budget,
            chain_passes,
            effects,
            features: Features::of(&scene, &effects),
            ..Default::default()
        };
        gpu.renderer
            .render(&packed, &Camera::new(w, h), WHITE, &options, progress)
            .expect("GPU render succeeds")
    };
    let (fb, timings) = run(64, 1, &record);
    let calls = calls.into_inner().unwrap_or_else(|e| e.into_inner());
    let total = u64::from(w * h);
    assert!(calls.iter().all(|&(_, t)| t == total), "{calls:?}");
    assert!(calls.windows(2).all(|p| p[0].0 <= p[1].0), "{calls:?}");
    assert_eq!(calls.last().map(|c| c.0), Some(total));
    let tiles = 4; // 48x40 in 32x32 tiles
    assert!(
        calls.len() > tiles && calls.len() as u64 == timings.counted("passes"),
        "one call per pass: {} calls, {} passes",
        calls.len(),
        timings.counted("passes")
    );
    // Passes do not change the image, nor the rays counted.
    let (one, one_timings) = run(1 << 20, 1, &|_, _| {});
    assert_eq!(fb, one);
    // Chained passes report each pass that did work, in order.
    let chained_calls = std::sync::Mutex::new(Vec::new());
    let (chained, chained_timings) = run(64, glint::gpu::MAX_CHAIN, &|done, _| {
        chained_calls
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(done)
    });
    let chained_calls = chained_calls
        .into_inner()
        .unwrap_or_else(|e| e.into_inner());
    assert_eq!(fb, chained);
    assert!(
        chained_calls.windows(2).all(|p| p[0] <= p[1]),
        "{chained_calls:?}"
    );
    assert_eq!(chained_calls.last(), Some(&total));
    assert!(chained_calls.len() as u64 <= chained_timings.counted("passes"));
    for kind in [glint::timing::CLOSEST_RAYS, glint::timing::SHADOW_RAYS] {
        assert!(timings.has_count(kind), "{kind}");
        assert_eq!(timings.counted(kind), one_timings.counted(kind), "{kind}");
    }
    assert_eq!(
        timings.counted(glint::timing::CLOSEST_RAYS),
        total * u64::from(effects.spp)
    );
}
