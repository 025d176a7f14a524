//! The shader against its CPU twin (f32) on every classic scene and every
//! scene in `scenes/`, compared before 8-bit rounding.

mod common;

use common::*;
use glint::compare::compare_framebuffers;
use glint::cpu::Precision;
use glint::scene::Scene;

fn check(name: &str, scene: &Scene, w: u32, h: u32) {
    let cpu = render_cpu(scene, w, h, Precision::F32, WHITE);
    assert_finite(name, &cpu);
    let Some(gpu) = render_gpu(scene, w, h, WHITE) else {
        return;
    };
    assert_finite(name, &gpu);
    let cmp = compare_framebuffers(&cpu, &gpu, THRESHOLD_LEVELS).expect("same size");
    let allowed = ((w * h) as f64 * MAX_DIFFERING_FRACTION).floor() as usize;
    assert_within(&format!("gpu_vs_cpu-{name}"), &gpu, &cpu, &cmp, allowed);
}

#[test]
fn classic_scenes_agree() {
    for name in CLASSIC {
        let Some(scene) = classic_scene(name) else {
            return;
        };
        check(name, &scene, 640, 480);
    }
}

#[test]
fn own_scenes_agree() {
    let scenes = own_scenes();
    assert!(!scenes.is_empty(), "scenes/ holds no .scene files");
    for path in scenes {
        let scene = glint::scene::read_scene(&path).expect("own scene parses");
        let name = path.file_stem().unwrap().to_string_lossy();
        check(&name, &scene, 640, 480);
    }
}

#[test]
fn odd_sizes_and_tile_edges_agree() {
    let Some(scene) = classic_scene("test2") else {
        return;
    };
    // Sizes that are not multiples of the workgroup (8) or the test tile (64).
    for (w, h) in [(1, 1), (67, 13), (130, 129)] {
        check(&format!("test2-{w}x{h}"), &scene, w, h);
    }
}
