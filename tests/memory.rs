//! A renderer's memory over many frames, in a test binary of its own: the
//! process's resident memory is the measure, which other tests running
//! alongside in the same process would move (it failed once that way, 18 MB
//! of another test's allocations in 300 frames).

mod common;

use common::*;
use glint::bvh::Bvh;
use glint::camera::Camera;
use glint::features::Features;
use glint::gpu::{GpuError, GpuRenderOptions};
use glint::images::framebuffer::Framebuffer;
use glint::layout::GpuScene;
use glint::scene::{Effects, Scene};

/// Renders test1 on the shared test GPU in 8x8 tiles; `None` without a
/// device (which fails in CI, see `gpu()`).
fn render(scene: &Scene, w: u32, h: u32) -> Option<Result<Framebuffer, GpuError>> {
    let gpu = gpu()?.lock().unwrap_or_else(|e| e.into_inner());
    let effects = Effects::resolve(&scene.settings);
    let packed = GpuScene::pack(scene, &Bvh::for_render(scene, &effects));
    let options = GpuRenderOptions {
        tile_size: 8,
        effects,
        features: Features::of(scene, &effects),
        ..Default::default()
    };
    let result = gpu
        .renderer
        .render(&packed, &Camera::new(w, h), WHITE, &options, &|_, _| {});
    Some(result.map(|(image, _)| image))
}

/// Resident memory of this process, from /proc (Linux).
fn rss_bytes() -> Option<u64> {
    let statm = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: u64 = statm.split_whitespace().nth(1)?.parse().ok()?;
    Some(pages * 4096)
}

/// One renderer over many frames and tiles keeps its memory: command
/// buffers, sets and buffers are reused (it grew ~650 KB a frame).
#[test]
fn memory_stays_flat_over_many_frames() {
    let Some(scene) = classic_scene("test1") else {
        return;
    };
    if rss_bytes().is_none() {
        notice("SKIPPED: memory check: no /proc/self/statm");
        return;
    }
    let frame = |i: u32| {
        // 48x40 in 8x8 tiles: 30 passes a frame.
        render(&scene, 48, 40).map(|r| r.unwrap_or_else(|e| panic!("frame {i}: {e}")))
    };
    // The allocator and the driver settle over the first frames; a leak
    // of the old kind (~650 KB a frame) would add ~190 MB after them.
    for i in 0..100 {
        if frame(i).is_none() {
            return;
        }
    }
    let settled = rss_bytes().expect("statm");
    for i in 100..400 {
        frame(i);
    }
    let grown = rss_bytes().expect("statm").saturating_sub(settled);
    eprintln!("RSS grew {} KB over 300 frames of 30 tiles", grown / 1024);
    assert!(
        grown < 16 << 20,
        "RSS grew {} KB over 300 frames",
        grown / 1024
    );
}
