//! The window's mean on the device (`gpu::present::DeviceMean`, what
//! `glint view` presents on a Vulkan device): a progressive render's
//! passes, copied tile by tile on the device and folded in by
//! `shaders/resolve.wgsl`, give after every pass the 8-bit pixels of the
//! host's mean (the image `S` and OUT write), for full passes and for the
//! adaptive passes that render only some blocks, and a new view (another
//! size) starts over. The presenting itself is tested in a real window
//! (`tests/view.rs`).

mod common;

use common::*;
use glint::gpu::present::DeviceMean;
use glint::images::framebuffer::to_u8;
use glint::render::passes::StopAt;
use glint::render::{Backend, RenderOptions, Renderer};

/// Most levels apart and how many pixels differ at all.
fn apart(device: &[[u8; 3]], host: &glint::images::framebuffer::Framebuffer) -> (u8, usize) {
    assert_eq!(device.len(), host.pixels.len(), "same size");
    let mut most = 0;
    let mut differ = 0;
    for (d, h) in device.iter().zip(&host.pixels) {
        let h = h.map(to_u8);
        let off = (0..3).map(|c| d[c].abs_diff(h[c])).max().unwrap_or(0);
        most = most.max(off);
        differ += usize::from(off > 0);
    }
    (most, differ)
}

#[test]
fn the_devices_mean_is_the_hosts_after_every_pass() {
    let Some(gpu) = gpu() else { return };
    let ctx = gpu.lock().expect("gpu").ctx.clone();
    let scene = glint::scene::read_scene(&repo_path("scenes/effects/soft_shadows.scene"))
        .expect("effect scene parses");
    for bgra in [true, false] {
        let mut mean = DeviceMean::new(&ctx, bgra).expect("resolve pipeline");
        for (size, stop) in [
            // Adaptive: after its first passes, only the noisy blocks.
            (
                [96, 72],
                StopAt {
                    target_rmse: Some(0.0003),
                    time_limit: None,
                    adaptive: true,
                },
            ),
            // Another size: the sums start over.
            (
                [64, 40],
                StopAt {
                    target_rmse: Some(0.001),
                    time_limit: None,
                    adaptive: false,
                },
            ),
        ] {
            let renderer = Renderer::on(
                &RenderOptions {
                    width: size[0],
                    height: size[1],
                    backend: Backend::Gpu,
                    tile: Some(32),
                    ..RenderOptions::default()
                },
                ctx.clone(),
            )
            .expect("renderer on the shared device");
            let target = mean.start(size[0], size[1]).expect("buffers");
            renderer
                .gpu()
                .expect("on the GPU")
                .copy_passes_to(Some(target));
            let mut checked = 0;
            let mut partial = 0;
            let done = renderer
                .render_progressive_watched(&scene, &stop, &mut |report, acc| {
                    mean.add_pass(report.passes == 1).expect("resolve");
                    let (most, differ) = apart(&mean.read().expect("read back"), &acc.mean());
                    assert!(
                        most <= 1,
                        "pass {}: {differ} pixels differ, by up to {most} levels",
                        report.passes
                    );
                    checked += 1;
                    partial += usize::from(report.active_blocks[0] < report.active_blocks[1]);
                    true
                })
                .expect("progressive render");
            assert_eq!(checked, done.history.len(), "every pass checked");
            assert!(checked >= 2, "{checked} passes");
            if stop.adaptive {
                assert!(partial > 0, "no pass was adaptive: {:?}", done.history);
            }
            let (most, differ) =
                apart(&mean.read().expect("read back"), &done.output.framebuffer());
            assert!(most <= 1, "final: {differ} pixels by up to {most} levels");
        }
        assert_eq!(ctx.validation_messages(), 0, "validation messages");
    }
}
