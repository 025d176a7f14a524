//! A renderer's cancel flag (`Renderer::set_cancel`, which `glint view`
//! sets when the view changes) ends a render mid-pass on either backend:
//! the render says so (`Error::Cancelled`) instead of returning a partial
//! image, starts no GPU tile after the flag, keeps the progressive passes
//! that finished before it, and leaves the renderer as it was for the next
//! render.

mod common;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use common::*;
use glint::render::passes::{StopAt, Stopped};
use glint::render::{Backend, RenderOptions, Renderer};
use glint::scene::Scene;
use glint::Error;

fn soft_shadows() -> Scene {
    glint::scene::read_scene(&repo_path("scenes/effects/soft_shadows.scene"))
        .expect("effect scene parses")
}

fn backends() -> Vec<Backend> {
    let mut b = vec![Backend::Cpu];
    if gpu().is_some() {
        b.push(Backend::Gpu);
    }
    b
}

/// A renderer of small tiles (80 at 160x120 on the GPU), so a render has
/// many tiles for the flag to fall between.
fn renderer(backend: Backend, size: [u32; 2], flag: &Arc<AtomicBool>) -> Renderer {
    let mut r = Renderer::new(&RenderOptions {
        width: size[0],
        height: size[1],
        backend,
        tile: Some(16),
        validation: backend == Backend::Gpu && in_ci(),
        ..RenderOptions::default()
    })
    .expect("renderer");
    r.set_cancel(flag.clone());
    r
}

#[test]
fn a_flag_set_mid_render_ends_it_and_the_next_render_is_whole() {
    let scene = soft_shadows();
    for backend in backends() {
        let flag = Arc::new(AtomicBool::new(false));
        let r = renderer(backend, [160, 120], &flag);
        let quiet = |_: u64, _: u64| {};
        let whole = r.render(&scene, &quiet).expect("render").into_framebuffer();
        let most = AtomicU64::new(0);
        let total = AtomicU64::new(0);
        let cut = r.render(&scene, &|done, all| {
            flag.store(true, Ordering::SeqCst);
            most.fetch_max(done, Ordering::SeqCst);
            total.store(all, Ordering::SeqCst);
        });
        assert!(
            matches!(cut, Err(Error::Cancelled)),
            "{backend:?}: {:?}",
            cut.map(|o| o.image.width())
        );
        let (most, total) = (most.into_inner(), total.into_inner());
        if backend == Backend::Gpu {
            // The tiles in flight when the flag fell finish unread; no
            // other starts.
            assert!(most < total / 2, "{backend:?}: {most} of {total} pixels");
        }
        flag.store(false, Ordering::SeqCst);
        let again = r.render(&scene, &quiet).expect("render after a cancel");
        assert_eq!(
            again.framebuffer().pixels,
            whole.pixels,
            "{backend:?}: the render after a cancelled one differs"
        );
        assert_eq!(again.validation_messages, 0, "Vulkan validation messages");
    }
}

#[test]
fn a_flag_set_between_passes_keeps_the_passes_before_it() {
    let scene = soft_shadows();
    let stop = StopAt {
        target_rmse: Some(1e-9),
        time_limit: Some(Duration::from_secs(300)),
        adaptive: false,
    };
    for backend in backends() {
        let flag = Arc::new(AtomicBool::new(false));
        let r = renderer(backend, [64, 48], &flag);
        let done = r
            .render_progressive_watched(&scene, &stop, &mut |report, _| {
                if report.passes == 2 {
                    flag.store(true, Ordering::SeqCst);
                }
                true
            })
            .expect("two passes finished");
        assert_eq!(done.stopped, Stopped::Cancelled, "{backend:?}");
        assert_eq!(done.history.len(), 2, "{backend:?}");
        // The same two passes, ended by the watcher instead.
        flag.store(false, Ordering::SeqCst);
        let watched = r
            .render_progressive_watched(&scene, &stop, &mut |report, _| report.passes < 2)
            .expect("render");
        assert_eq!(watched.history.len(), 2, "{backend:?}");
        assert_eq!(
            done.output.framebuffer().pixels,
            watched.output.framebuffer().pixels,
            "{backend:?}: the image of the passes before the flag"
        );
        // A flag already set cuts the first pass: no image at all.
        flag.store(true, Ordering::SeqCst);
        let none = r.render_progressive_watched(&scene, &stop, &mut |_, _| true);
        assert!(matches!(none, Err(Error::Cancelled)), "{backend:?}");
    }
}
