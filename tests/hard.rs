//! The hard-case suite (src/hard, scenes/hard): every case on the GPU and the
//! CPU f32 reference, against the CPU f64 reference; the counts each case
//! checks must be zero. Also: the scene files match their generator, the
//! naive methods fail the same suite (so it can fail), and classic scenes
//! scaled about the camera render the same image.

mod common;

use common::{gpu, repo_path};
use glint::bvh::Bvh;
use glint::camera::Camera;
use glint::cpu::CpuOptions;
use glint::cpu::Precision;
use glint::images::compare::compare_framebuffers;
use glint::methods::Methods;
use glint::suites::hard::metrics::{failing_pixels, lone_pixels};
use glint::suites::hard::{self, count, Case, Metric, Runner};

fn case(name: &str) -> Case {
    hard::cases()
        .into_iter()
        .find(|c| c.name == name)
        .unwrap_or_else(|| panic!("no hard case {name}"))
}

/// Probes `name` on each backend and asserts its checked counts are zero,
/// listing the first failing pixels with the command that explains each.
fn check(name: &str) {
    let case = case(name);
    let reference = case.reference();
    let gpu = gpu().map(|g| g.lock().unwrap_or_else(|e| e.into_inner()));
    let mut runners = vec![Runner::CpuF32];
    if gpu.is_some() {
        runners.insert(0, Runner::Gpu);
    }
    let mut failures = Vec::new();
    for runner in runners {
        let before = gpu.as_ref().map_or(0, |g| g.ctx.validation_messages());
        let (image, _) = hard::probe(
            &case,
            runner,
            Methods::Robust,
            gpu.as_ref().map(|g| &g.renderer),
        )
        .expect("probe runs");
        if let Some(g) = &gpu {
            assert_eq!(
                g.ctx.validation_messages(),
                before,
                "Vulkan validation messages"
            );
        }
        let counts = count(&image, &reference);
        let shown: Vec<String> = Metric::ALL
            .iter()
            .map(|&m| format!("{m} {}", counts.get(m)))
            .collect();
        eprintln!("{name} on {}: {}", runner.name(), shown.join(", "));
        for &m in &case.checks {
            let pixels = failing_pixels(&image, &reference, m);
            if !pixels.is_empty() {
                let first: Vec<String> = pixels
                    .iter()
                    .take(5)
                    .map(|&p| format!("\n    {}", case.pixel_command(p)))
                    .collect();
                failures.push(format!(
                    "{} {m} pixels on {}; first (after `glint bench hard --write-scenes`):{}",
                    pixels.len(),
                    runner.name(),
                    first.concat()
                ));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{name} ({}):\n  {}",
        case.what,
        failures.join("\n  ")
    );
}

macro_rules! cases {
    ($($test:ident => $name:literal),* $(,)?) => {
        $(#[test] fn $test() { check($name); })*

        #[test]
        fn every_case_has_a_test() {
            let tested = [$($name),*];
            for c in hard::cases() {
                assert!(tested.contains(&c.name.as_str()), "hard case {} has no test", c.name);
            }
        }
    };
}

cases! {
    sphere_inside => "sphere_inside",
    quad_grid => "quad_grid",
    vertex_rays => "vertex_rays",
    grazing => "grazing",
    grazing_light_0_1deg => "grazing_light_0.1deg",
    far_spheres => "far_spheres",
    acne_scale_1e_3 => "acne_scale_1e-3",
    acne_scale_1 => "acne_scale_1",
    acne_scale_1e3 => "acne_scale_1e3",
    acne_offset_1e3 => "acne_offset_1e3",
    acne_offset_1e4 => "acne_offset_1e4",
    contact_box => "contact_box",
    contact_box_1e_3 => "contact_box_1e-3",
    lights_on_surfaces => "lights_on_surfaces",
    lights_on_surfaces_ii => "lights_on_surfaces_ii",
    camera_inside_sphere => "camera_inside_sphere",
    shininess_extremes => "shininess_extremes",
    hundred_lights => "hundred_lights",
    degenerate_triangles => "degenerate_triangles",
    bvh_faces => "bvh_faces",
}

/// The scene files `glint bench hard --write-scenes` writes parse back to
/// the scenes the suite renders, with the parser's warnings for the inputs
/// that deserve one.
#[test]
fn written_scene_files_parse_to_the_suite() {
    let dir = tempfile::tempdir().expect("temp dir");
    let written = hard::write_scenes(dir.path()).expect("write scenes");
    let cases = hard::cases();
    assert_eq!(written, cases.len());
    for c in &cases {
        let path = dir.path().join(format!("{}.scene", c.name));
        let parsed = glint::scene::read_scene(&path).expect("written scene parses");
        assert_eq!(parsed.spheres, c.scene.spheres, "{}", c.name);
        assert_eq!(parsed.triangles, c.scene.triangles, "{}", c.name);
        assert_eq!(parsed.lights, c.scene.lights, "{}", c.name);
    }
    let degenerate = cases
        .iter()
        .find(|c| c.name == "degenerate_triangles")
        .expect("case exists");
    let text: Vec<String> = degenerate
        .scene
        .warnings
        .iter()
        .map(|w| w.to_string())
        .collect();
    assert!(
        text.iter().any(|w| w.contains("zero-length vertex normal")),
        "{text:?}"
    );
    assert!(
        text.iter()
            .any(|w| w.contains("length 1.0000000150474662e30")),
        "{text:?}"
    );
}

/// The suite can fail: the textbook methods, on the CPU f32 twin of the
/// shader, fail the counts the robust methods pass.
#[test]
fn naive_methods_fail_the_suite() {
    let expect = [
        ("vertex_rays", Metric::Crack),
        ("acne_scale_1e3", Metric::Acne),
        ("acne_offset_1e3", Metric::Acne),
        ("contact_box_1e-3", Metric::Leak),
        ("acne_offset_1e3", Metric::Speckle),
        ("acne_scale_1e-3", Metric::Crack),
    ];
    for (name, metric) in expect {
        let c = case(name);
        let (image, _) = hard::probe(&c, Runner::CpuF32, Methods::Naive, None).expect("CPU probe");
        let n = count(&image, &c.reference()).get(metric);
        eprintln!("{name}, naive methods: {n} {metric} pixels");
        assert!(
            n > 0,
            "{name}: naive methods show no {metric}; the case lost its edge"
        );
    }
}

/// The showcase and every classic scene.
fn scale_test_scenes() -> Vec<(String, glint::scene::Scene)> {
    let mut scenes = vec![(
        "showcase".to_string(),
        glint::scene::read_scene(&repo_path("scenes/showcase.scene")).expect("showcase parses"),
    )];
    if common::classic_dir().is_some() {
        for name in common::CLASSIC {
            scenes.push((
                name.to_string(),
                common::classic_scene(name).expect("classic"),
            ));
        }
    }
    scenes
}

/// Asserts that each scene scaled about the camera by each factor renders
/// the image of the unscaled scene on each backend, within the GPU-vs-CPU
/// test's tolerance (0.25 levels; at most 5e-5 of the pixels over it);
/// `rescaled`: whether the factors take the scene out of the range rendered
/// as it is (`Scene::render_scale`).
fn assert_scaled_images_match(factors: &[f64], (w, h): (u32, u32), rescaled: bool) {
    let allowed = (5e-5 * f64::from(w * h)).floor() as usize;
    for (name, scene) in &scale_test_scenes() {
        if rescaled {
            assert_eq!(scene.render_scale(), 1.0, "{name} is rendered as it is");
        }
        let base_gpu = common::render_gpu(scene, w, h, common::WHITE);
        let base_cpu = common::render_cpu(scene, w, h, Precision::F32, common::WHITE);
        for &factor in factors {
            let scaled = scene.scaled(factor);
            if rescaled {
                assert_ne!(scaled.render_scale(), 1.0, "{name} at {factor:e}");
            }
            let label = format!("{name}-scaled-{factor:e}");
            let cpu = common::render_cpu(&scaled, w, h, Precision::F32, common::WHITE);
            let cmp = compare_framebuffers(&cpu, &base_cpu, 0.25).expect("same size");
            common::assert_within(&format!("{label}-cpu"), &cpu, &base_cpu, &cmp, allowed);
            if let (Some(base), Some(img)) =
                (&base_gpu, common::render_gpu(&scaled, w, h, common::WHITE))
            {
                let cmp = compare_framebuffers(&img, base, 0.25).expect("same size");
                common::assert_within(&format!("{label}-gpu"), &img, base, &cmp, allowed);
            }
        }
    }
}

/// Scenes scaled about the camera by 1e-3, 1e3 and 1e4 render the image of
/// the unscaled scene on each backend.
#[test]
fn scale_invariance() {
    assert_scaled_images_match(&[1e-3, 1e3, 1e4], (320, 240), false);
}

/// Far outside f32's comfortable range (where the textbook f32 renderer
/// loses triangles from 1e13 and spheres from 1e20): the scene is brought
/// back by a power of two (`Scene::render_scale`), so scaled by 1e-30 to
/// 1e30 about the camera it renders its unscaled image on each f32 backend.
#[test]
fn extreme_scales_render_the_unscaled_image() {
    assert_scaled_images_match(&[1e-30, 1e-20, 1e-10, 1e10, 1e20, 1e30], (160, 120), true);
}

/// A primitive too small for f32 where it is gets named (no scaling helps
/// it); the same primitive near the camera does not.
#[test]
fn primitives_f32_cannot_resolve_are_named() {
    let text = |z: f64, r: f64| {
        format!(
            "2\namb: 0.1 0.1 0.1\nsphere pos: 0 0 {z} rad: {r:e} dif: 0.5 0.5 0.5 spe: 0 0 0 shi: 1\n\
             light pos: 0 5 0 col: 1 1 1\n"
        )
    };
    let far = glint::scene::parse_scene(text(-10.0, 10.0 * 2f64.powi(-22)).as_bytes(), "far")
        .expect("parses");
    let listed = far.unresolvable();
    assert_eq!(listed.len(), 1, "{listed:?}");
    assert!(
        listed[0].starts_with("sphere 0 at (0e0, 0e0, -1e1)"),
        "{listed:?}"
    );
    let near = glint::scene::parse_scene(text(-1e-5, 1e-6).as_bytes(), "near").expect("parses");
    assert!(near.unresolvable().is_empty());
}

/// A ray with NaN in it (never formed by the renderer, but guarded against)
/// ends traversal without a hit instead of looping.
#[test]
fn nan_ray_terminates() {
    use glint::cpu::trace::{make_ray, traverse, CpuGeometry, CpuScene, NO_HIT};
    let c = case("quad_grid");
    let bvh = Bvh::build(&c.scene);
    let geometry = CpuGeometry::<f32>::new(&c.scene, &bvh, &Default::default());
    let camera = Camera::new(8, 8);
    let scene = CpuScene::new(&c.scene, &bvh, &geometry, &camera, &Default::default());
    for dir in [
        glam::Vec3::new(f32::NAN, 0.0, -1.0),
        glam::Vec3::NAN,
        glam::Vec3::ZERO,
    ] {
        let hit = traverse(
            &scene,
            &make_ray(glam::Vec3::ZERO, dir, 0.0),
            f32::MAX,
            false,
            &[],
            0.0,
        );
        assert_eq!(hit.prim, NO_HIT, "direction {dir:?}");
    }
}

/// The GPU's `probe_pixel` record and the CPU f32 twin's path agree: same
/// primitives and verdicts, values within f32 rounding.
#[test]
fn pixel_paths_agree_across_backends() {
    let Some(gpu) = gpu() else {
        return;
    };
    let gpu = gpu.lock().unwrap_or_else(|e| e.into_inner());
    for name in ["acne_scale_1", "hundred_lights", "far_spheres"] {
        let c = case(name);
        let bvh = Bvh::build(&c.scene);
        let packed = glint::layout::GpuScene::pack(&c.scene, &bvh);
        let camera = c.camera();
        for pixel in [[160, 120], [40, 200], [300, 30], [100, 150]] {
            let g = gpu
                .renderer
                .pixel_path(&packed, &camera, [1.0; 3], pixel, &Default::default())
                .expect("GPU path");
            let cpu = glint::cpu::pixel_path(&c.scene, &bvh, &camera, &Default::default(), pixel);
            let at = format!("{name} {pixel:?}");
            assert_eq!(g.prim, cpu.prim, "{at}");
            assert_eq!(g.shadow_mask, cpu.shadow_mask, "{at}");
            assert_eq!(g.lights.len(), cpu.lights.len(), "{at}");
            assert!(
                (g.t - cpu.t).abs() <= 1e-5 * cpu.t.abs(),
                "{at}: t {} vs {}",
                g.t,
                cpu.t
            );
            for (a, b) in g.lights.iter().zip(&cpu.lights) {
                assert_eq!(a.blocker, b.blocker, "{at}");
            }
            for k in 0..3 {
                assert!(
                    (g.color[k] - cpu.color[k]).abs() < 1e-4,
                    "{at}: {:?} vs {:?}",
                    g.color,
                    cpu.color
                );
            }
        }
    }
}

/// Zero-area and collinear triangles are never hit, on any backend (the
/// watertight test's determinant is exactly 0 for them).
#[test]
fn degenerate_triangles_are_never_hit() {
    let c = case("degenerate_triangles");
    // The generator's first three: a point, two equal corners, collinear.
    let degenerate = [0u32, 1, 2];
    let gpu = gpu().map(|g| g.lock().unwrap_or_else(|e| e.into_inner()));
    let mut images = vec![("CPU f64", c.reference())];
    images.push((
        "CPU f32",
        hard::probe(&c, Runner::CpuF32, Methods::Robust, None)
            .expect("probe")
            .0,
    ));
    if let Some(g) = &gpu {
        let (image, _) =
            hard::probe(&c, Runner::Gpu, Methods::Robust, Some(&g.renderer)).expect("probe");
        images.push(("GPU", image));
    }
    for (name, image) in images {
        let hits = image
            .pixels
            .iter()
            .filter(|p| degenerate.contains(&p.prim))
            .count();
        assert_eq!(hits, 0, "{name}: degenerate triangles hit");
        // Their neighbours with zero, huge, flipped and cancelling normals
        // (generator order 5..=9) are hit.
        for prim in 5..=9 {
            assert!(
                image.pixels.iter().any(|p| p.prim == prim),
                "{name}: triangle {prim} missed"
            );
        }
    }
}

/// `--pixel` on a rescaled scene reports the scene's own units.
#[test]
fn pixel_paths_of_rescaled_scenes_are_in_scene_units() {
    let scene = glint::scene::read_scene(&repo_path("scenes/showcase.scene")).expect("parses");
    let options = glint::render::RenderOptions {
        width: 64,
        height: 48,
        backend: glint::render::Backend::Cpu,
        ..Default::default()
    };
    let path = |s: &glint::scene::Scene| {
        glint::render::pixel_path(s, &options, [32, 30])
            .expect("path")
            .value
    };
    let base = path(&scene);
    let far = path(&scene.scaled(1e20));
    assert!(base.surface.is_some());
    assert!(
        (far.t / base.t / 1e20 - 1.0).abs() < 1e-6,
        "{} vs {}",
        far.t,
        base.t
    );
    let (a, b) = (
        base.surface.expect("hit").point,
        far.surface.expect("hit").point,
    );
    for k in 0..3 {
        assert!(
            (b[k] - a[k] * 1e20).abs() <= 1e-5 * (a[k].abs() * 1e20 + 1e15),
            "{a:?} {b:?}"
        );
    }
}

/// The surfaces through each light of `lights_on_surfaces_ii`: one floor
/// triangle, the two beside a shared edge, the six around a vertex, the wall,
/// the sphere twice.
#[test]
fn surfaces_through_lights_are_found() {
    let c = case("lights_on_surfaces_ii");
    let bvh = Bvh::build(&c.scene);
    let counts: Vec<usize> = bvh.surfaces_at_lights.iter().map(Vec::len).collect();
    assert_eq!(counts, [1, 2, 6, 1, 1, 1]);
}

/// Where lights lie on surfaces the f64 reference itself is noise-free: no
/// pixel stands alone against its four neighbours. Without the rule the same
/// f64 render is salt and pepper, so the count can fail.
#[test]
fn f64_is_noise_free_where_lights_lie_on_surfaces() {
    for name in ["lights_on_surfaces", "lights_on_surfaces_ii"] {
        let c = case(name);
        let with_rule = lone_pixels(&c.reference());
        let mut bvh = Bvh::build(&c.scene);
        bvh.surfaces_at_lights.iter_mut().for_each(Vec::clear);
        let options = CpuOptions {
            precision: Precision::F64,
            ..CpuOptions::default()
        };
        let without = lone_pixels(&glint::cpu::probe(&c.scene, &bvh, &c.camera(), &options));
        eprintln!("{name}: f64 lone pixels {with_rule} with the rule, {without} without");
        assert_eq!(with_rule, 0, "{name}: lone pixels in the f64 reference");
        assert!(
            without > 100,
            "{name}: without the rule f64 shows only {without} lone pixels"
        );
    }
}
