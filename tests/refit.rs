//! An animation of moving primitives refits its tree from frame to frame
//! (`Bvh::refit`) instead of building it again: each frame equals the same
//! frame rendered alone to within one 8-bit level (a refitted tree may keep
//! the other of two hits at exactly the same t), on the CPU reference and,
//! where there is one, on a Vulkan device; and `-v` says which frames were
//! refitted.

mod common;

use common::cli::{glint, tmp};
use common::*;
use glint::render::{Backend, PixelFormat, RenderOptions, Renderer};

/// Spheres and triangles, each moving its own way, under motion blur (so
/// the refitted boxes are swept ones).
fn moving_scene() -> String {
    let mut objects = Vec::new();
    for i in 0..12 {
        let x = -3.0 + 0.55 * f64::from(i);
        let (vx, vy) = ((0.7 * f64::from(i)).sin(), (0.9 * f64::from(i)).cos());
        objects.push(format!(
            "sphere\npos: {x} {} -6\nrad: 0.35\ndif: 0.7 0.3 0.2\nspe: 0.3 0.3 0.3\nshi: 12\nvel: {vx} {vy} 0\n",
            0.8 * (f64::from(i)).sin()
        ));
        let corner = |dx: f64, dy: f64| {
            format!(
                "pos: {} {} -5\nnor: 0 0 1\ndif: 0.2 0.6 0.8\nspe: 0.2 0.2 0.2\nshi: 8\n",
                x + dx,
                -1.0 + dy
            )
        };
        objects.push(format!(
            "triangle\n{}{}{}vel: {} {} 0.5\n",
            corner(0.0, 0.0),
            corner(0.5, 0.0),
            corner(0.2, 0.6),
            -vy,
            vx
        ));
    }
    objects.push("light\npos: 2 5 0\ncol: 0.9 0.9 0.9\n".into());
    format!(
        "{}\namb: 0.1 0.1 0.1\nspp: 4\nshutter: 0.5\nfps: 8\n{}",
        objects.len(),
        objects.concat()
    )
}

/// Small triangles bunched about a point, each flying off its own way
/// fast: refitted, the tree's boxes soon overlap everywhere, and its SAH
/// cost passes the rebuild bound within a few frames.
fn exploding_scene() -> String {
    let mut state = 9u32;
    let mut next = || {
        state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        f64::from(state >> 8) / f64::from(1u32 << 24) - 0.5
    };
    let mut objects = Vec::new();
    for _ in 0..60 {
        let (x, y, z) = (next(), next(), next() - 6.0);
        let corner = |dx: f64, dy: f64| {
            format!(
                "pos: {} {} {z}\nnor: 0 0 1\ndif: 0.8 0.5 0.2\nspe: 0.1 0.1 0.1\nshi: 4\n",
                x + dx,
                y + dy
            )
        };
        objects.push(format!(
            "triangle\n{}{}{}vel: {} {} {}\n",
            corner(0.0, 0.0),
            corner(0.1, 0.0),
            corner(0.0, 0.1),
            12.0 * next(),
            12.0 * next(),
            6.0 * next()
        ));
    }
    objects.push("light\npos: 0 4 0\ncol: 1 1 1\n".into());
    format!(
        "{}\namb: 0.1 0.1 0.1\nfps: 8\n{}",
        objects.len(),
        objects.concat()
    )
}

/// Renders `text`'s first `frames` frames as one animation on `backend`
/// and checks each against the same frame rendered alone; returns the
/// run's `-v` log.
fn frames_equal_single_renders(text: &str, frames: u32, backend: Backend, flag: &str) -> String {
    let dir = tmp();
    let path = dir.path().join("moving.scene");
    std::fs::write(&path, text).expect("write scene");
    let scene = glint::scene::read_scene(&path).expect("parses");
    let out = glint(
        &[
            "render",
            path.to_str().expect("utf-8"),
            "frames",
            "--frames",
            &frames.to_string(),
            "--frame-format",
            "png",
            "--backend",
            flag,
            "--width",
            "80",
            "--height",
            "60",
            "-v",
        ],
        dir.path(),
    );
    let log = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{log}");
    // Frame 0 builds the tree; every later one refits it.
    let refits = log
        .lines()
        .filter(|l| l.trim_start().starts_with("refit "))
        .count();
    assert!(
        refits >= frames as usize - 1,
        "refitted frames: {refits}\n{log}"
    );
    let renderer = Renderer::new(&RenderOptions {
        width: 80,
        height: 60,
        backend,
        pixels: PixelFormat::Float,
        ..Default::default()
    })
    .expect("renderer");
    let effects = renderer.options().effects(&scene);
    let mut moved = std::collections::HashSet::new();
    for i in 0..frames {
        let alone = renderer
            .render(&scene.at_time(effects.frame_time(i)), &|_, _| {})
            .expect("renders")
            .framebuffer()
            .to_rgb8();
        let file = dir.path().join(format!("frames/{i:03}.png"));
        let got = glint::images::framebuffer::read_image(&file).expect("reads");
        let worst = got
            .as_raw()
            .iter()
            .zip(alone.as_raw())
            .map(|(a, b)| a.abs_diff(*b))
            .max();
        assert!(
            worst <= Some(1),
            "frame {i}: {worst:?} levels from its render alone"
        );
        moved.insert(got.into_raw());
    }
    assert_eq!(moved.len(), frames as usize, "every frame should differ");
    log
}

/// Each frame's phases in a `-v` log: whether it built its tree (`bvh`)
/// or refitted it (`refit` alone), frame by frame.
fn built_frames(log: &str) -> Vec<bool> {
    let mut built = Vec::new();
    // Up to the totals over all frames, which follow the last.
    for line in log.lines().take_while(|l| !l.starts_with("all frames")) {
        if line.starts_with("frame ") {
            built.push(false);
        } else if line.trim_start().starts_with("bvh ") {
            if let Some(b) = built.last_mut() {
                *b = true;
            }
        }
    }
    built
}

fn refits_a_moving_scene(backend: Backend, flag: &str) {
    let log = frames_equal_single_renders(&moving_scene(), 6, backend, flag);
    // Frame 0 builds the tree; every later one refits it.
    let built = built_frames(&log);
    assert_eq!(built, [true, false, false, false, false, false], "{log}");
    let refits = log
        .lines()
        .filter(|l| l.trim_start().starts_with("refit "))
        .count();
    assert!(refits >= 5, "refitted frames: {refits}\n{log}");
}

/// A scene flying apart: a later frame finds its refitted tree past the
/// bound and builds it again, and still equals its render alone.
#[test]
fn a_tree_grown_past_the_bound_is_built_again() {
    let log = frames_equal_single_renders(&exploding_scene(), 8, Backend::Cpu, "cpu");
    let built = built_frames(&log);
    assert_eq!(built.len(), 8, "{log}");
    assert!(built[0], "{log}");
    assert!(
        built[1..].contains(&true),
        "no frame built its tree again: {built:?}\n{log}"
    );
    assert!(
        built[1..].contains(&false),
        "no frame refitted: {built:?}\n{log}"
    );
}

#[test]
fn refitted_frames_equal_single_renders_on_the_cpu() {
    refits_a_moving_scene(Backend::Cpu, "cpu");
}

#[test]
fn refitted_frames_equal_single_renders_on_a_vulkan_device() {
    if gpu().is_none() {
        return;
    }
    refits_a_moving_scene(Backend::Gpu, "gpu");
}
