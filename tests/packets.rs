//! The CPU reference's packets (`cpu::packet`): a render whose pixels go
//! in packets (`packet::WIDTH` rays, `packet::TILE` pixels) gives the image
//! every ray traced alone gives, on every scene the packets take: the
//! classic scenes, the project's own, the hard cases (any scale, lights on
//! surfaces), reflections and area lights (which packets hand to single
//! rays past the first hit); and the shadow rays they leave untraced,
//! with those they cast, are the shader's.

mod common;

use common::cli::*;
use common::*;
use glint::bvh::Bvh;
use glint::camera::Camera;
use glint::cpu::packet::{self, WIDTH};
use glint::cpu::trace::{pixel_ray, traverse, CpuScene, Ray};
use glint::cpu::{CpuOptions, Geometry, Keep};
use glint::methods::Methods;
use glint::scene::{Effects, Scene};

/// Renders `scene` with and without packets and asserts the images are the
/// same, bit for bit, but at a few pixels whose primary ray meets two
/// surfaces at the same t or an ulp or two apart (a tie, which each breaks
/// by the order it opens leaves in, both deterministic); also that the packets took the render (so the
/// comparison means something).
///
/// Returns the shadow rays cast (alone, in packets) with every pixel kept.
fn assert_packets_agree(
    name: &str,
    scene: &Scene,
    camera: &Camera,
    methods: Methods,
) -> (u64, u64) {
    let mut effects = Effects::resolve(&scene.settings);
    // One sample a pixel, the packets' case; the rest of the scene's
    // settings (reflections, area lights) stay.
    effects.spp = 1;
    let bvh = Bvh::build(scene);
    let options = |packets| CpuOptions {
        methods,
        effects,
        packets,
        ..CpuOptions::default()
    };
    let geometry = glint::cpu::prepare(scene, &bvh, &options(true));
    let Geometry::F32(g) = &geometry else {
        panic!("f32 geometry")
    };
    let taken = glint::cpu::packet::applies(&CpuScene::new(scene, &bvh, g, camera, &options(true)));
    assert!(taken, "{name}: the packets do not take this scene");
    // Some pixels left out, as a crop or a progressive pass leaves them.
    let some = &|x: u32, y: u32| !(x * 7 + y * 3).is_multiple_of(5);
    let mut shadow_rays = (0, 0);
    for keep in [Keep::EVERY, Keep::Where(some)] {
        let render = |packets| {
            glint::cpu::render_where(
                scene,
                &bvh,
                &geometry,
                camera,
                &options(packets),
                keep,
                &|_, _| {},
            )
        };
        let (alone, alone_work) = render(false);
        let (packed, packed_work) = render(true);
        let width = camera.width as usize;
        let differ: Vec<usize> = (0..alone.pixels.len())
            .filter(|&i| alone.pixels[i] != packed.pixels[i])
            .collect();
        assert!(
            differ.len() * 200 <= alone.pixels.len(),
            "{name} ({methods:?}): {} pixels differ",
            differ.len()
        );
        // Only where a primary ray meets two surfaces at exactly the same
        // t, and the packet kept the other one.
        let s = CpuScene::new(scene, &bvh, g, camera, &options(true));
        for &i in &differ {
            let (x, y) = ((i % width) as u32, (i / width) as u32);
            // The packet as the render cast it: the kept pixels of the
            // tile, in rows.
            let [tw, th] = packet::TILE;
            let (x0, y0) = (x - x % tw, y - y % th);
            let pixels: Vec<[u32; 2]> = (y0..(y0 + th).min(camera.height))
                .flat_map(|py| (x0..(x0 + tw).min(camera.width)).map(move |px| [px, py]))
                .filter(|&[px, py]| keep.pixel(px, py))
                .collect();
            let lane = pixels.iter().position(|&p| p == [x, y]).expect("kept");
            let rays: [Ray<f32>; WIDTH] = std::array::from_fn(|k| {
                let [px, py] = pixels[k.min(pixels.len() - 1)];
                pixel_ray(&s, px, py)
            });
            let active = u32::MAX >> (32 - pixels.len());
            let packed_hit = packet::traverse(&s, &rays, active, f32::MAX, false)[lane];
            let alone_hit = traverse(&s, &rays[lane], f32::MAX, false, &[], 0.0);
            // The same t, or within the rounding of the triangle test's
            // range check, which tests a candidate against the hit found so
            // far: at a vertex several triangles meet the ray within an ulp,
            // and which of them is found first decides which is kept.
            let ulps = (i64::from(packed_hit.t.to_bits() as i32)
                - i64::from(alone_hit.t.to_bits() as i32))
            .abs();
            assert!(
                ulps <= 2,
                "{name} ({methods:?}): pixel {x},{y}: {ulps} ulps apart"
            );
            assert_ne!(
                packed_hit.prim, alone_hit.prim,
                "{name}: pixel {x},{y} is no tie"
            );
        }
        if !differ.is_empty() {
            notice(&format!(
                "{name} ({methods:?}): {} pixels keep the other of two hits at (nearly) one t",
                differ.len()
            ));
        }
        // The packets trace only the shadow rays whose answer can change a
        // pixel (`points::changed_by`), so at most as many.
        assert_eq!(alone_work.rays[0], packed_work.rays[0], "{name}: rays cast");
        assert!(
            packed_work.rays[1] <= alone_work.rays[1],
            "{name}: {} shadow rays in packets, {} alone",
            packed_work.rays[1],
            alone_work.rays[1]
        );
        if matches!(keep, Keep::All(_)) {
            shadow_rays = (alone_work.rays[1], packed_work.rays[1]);
        }
    }
    shadow_rays
}

#[test]
fn classic_scenes_render_the_same_in_packets() {
    let Some(dir) = classic_dir() else { return };
    for name in ["test1", "test2", "spheres", "table", "SIGGRAPH"] {
        let scene = glint::scene::read_scene(&dir.join(format!("{name}.scene"))).expect("parses");
        // 641 x 241: the last tile of each band is one pixel wide, the
        // last band one row high.
        let (alone, packed) =
            assert_packets_agree(name, &scene, &Camera::new(641, 241), Methods::Robust);
        // Most of the spheres' points facing away from a light see it at
        // no angle that shades them: no shadow ray to trace.
        if name == "spheres" {
            assert!(
                packed < alone,
                "spheres: {packed} shadow rays in packets, {alone} alone"
            );
        }
    }
}

#[test]
fn own_and_effect_scenes_render_the_same_in_packets() {
    let mut paths = own_scenes();
    for effect in ["reflect", "soft_shadows", "all_effects"] {
        paths.push(repo_path(&format!("scenes/effects/{effect}.scene")));
    }
    for path in paths {
        let scene = glint::scene::read_scene(&path).expect("parses");
        if scene.has_motion() {
            continue;
        }
        let name = path.display().to_string();
        let _ = assert_packets_agree(&name, &scene, &Camera::new(203, 150), Methods::Robust);
    }
}

/// The naive methods' renders never take packets: their triangle test can
/// find a hit outside its leaf's box, so the order leaves are opened in may
/// change which hit is kept by more than a tie.
#[test]
fn naive_renders_take_no_packets() {
    let case = &glint::suites::hard::cases()[0];
    let bvh = Bvh::build(&case.scene);
    let options = CpuOptions {
        methods: Methods::Naive,
        ..CpuOptions::default()
    };
    let Geometry::F32(g) = glint::cpu::prepare(&case.scene, &bvh, &options) else {
        panic!("f32 geometry")
    };
    let s = CpuScene::new(&case.scene, &bvh, &g, &case.camera(), &options);
    assert!(!packet::applies(&s));
    let robust = CpuScene::new(
        &case.scene,
        &bvh,
        &g,
        &case.camera(),
        &CpuOptions::default(),
    );
    assert!(packet::applies(&robust));
}

#[test]
fn hard_cases_render_the_same_in_packets() {
    let mut on_surfaces = 0;
    for case in glint::suites::hard::cases() {
        on_surfaces += usize::from(
            !Bvh::build(&case.scene)
                .surfaces_at_lights
                .iter()
                .all(Vec::is_empty),
        );
        let _ = assert_packets_agree(&case.name, &case.scene, &case.camera(), Methods::Robust);
    }
    assert!(on_surfaces > 0, "no hard case has a light on a surface");
}

/// The CPU's packets leave untraced the shadow rays whose answer could not
/// change a pixel and say how many; cast and untraced together are the
/// shadow rays the shader casts, which traces them all.
#[test]
fn untraced_shadow_rays_add_up_to_the_shaders() {
    let Some(dir) = classic_dir() else { return };
    let d = tmp();
    let scene = dir.join("spheres.scene").display().to_string();
    let run = |backend: &str| {
        let args = [
            "render",
            &scene,
            "s.png",
            "--backend",
            backend,
            "--stats",
            "--width",
            "160",
            "--height",
            "120",
        ];
        let o = glint(&args, d.path());
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        stdout(&o)
    };
    let cpu = run("cpu");
    let untraced: u64 = cpu
        .lines()
        .find_map(|l| l.trim_start().strip_prefix("untraced"))
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no untraced line in\n{cpu}"));
    let [_, primary, _, shadow] = stats_rays(&cpu);
    assert_eq!(primary, 160 * 120, "{cpu}");
    assert!(untraced > 0 && shadow > 0, "{cpu}");
    if gpu().is_some() {
        let gpu_out = run("gpu");
        let [_, _, _, gpu_shadow] = stats_rays(&gpu_out);
        assert!(
            gpu_shadow.abs_diff(shadow + untraced) * 1000 <= gpu_shadow,
            "GPU {gpu_shadow} shadow rays; CPU {shadow} and {untraced} untraced"
        );
    }
}
