//! The shader against its CPU twin (f32) on every classic scene and every
//! scene in `scenes/`, compared before 8-bit rounding.

mod common;

use common::*;
use glint::scene::Scene;

fn check(name: &str, scene: &Scene, w: u32, h: u32) {
    assert_backends_agree(&format!("gpu_vs_cpu-{name}"), scene, w, h, 0);
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
