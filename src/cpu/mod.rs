//! The CPU reference renderer: the shader's algorithm (`trace.rs`, same
//! function names), parallel over rows with rayon, in f32 (the shader's twin)
//! or f64 (ground truth).

mod real;
pub mod trace;

pub use real::Real;

use rayon::prelude::*;

use crate::bvh::Bvh;
use crate::camera::Camera;
use crate::framebuffer::Framebuffer;
use crate::scene::Scene;
use trace::{pixel_ray, trace_primary, CpuScene};

/// Arithmetic precision of the CPU reference.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Precision {
    /// Follows the shader's f32 arithmetic, operation for operation.
    #[default]
    F32,
    /// Ground truth for accuracy measurements and golden images.
    F64,
}

/// Renders the whole image on the CPU. `progress(rows_done, rows_total)` is
/// called from worker threads as rows finish.
pub fn render(
    scene: &Scene,
    bvh: &Bvh,
    camera: &Camera,
    background: [f32; 3],
    precision: Precision,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Framebuffer {
    match precision {
        Precision::F32 => render_in::<f32>(scene, bvh, camera, background, progress),
        Precision::F64 => render_in::<f64>(scene, bvh, camera, background, progress),
    }
}

fn render_in<R: Real>(
    scene: &Scene,
    bvh: &Bvh,
    camera: &Camera,
    background: [f32; 3],
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Framebuffer {
    let cpu_scene = CpuScene::<R>::new(scene, bvh, camera, background);
    let (w, h) = (camera.width, camera.height);
    let done = std::sync::atomic::AtomicU64::new(0);
    let mut pixels = vec![[0.0f32; 3]; w as usize * h as usize];
    pixels
        .par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, px) in row.iter_mut().enumerate() {
                let ray = pixel_ray(&cpu_scene, x as u32, y as u32);
                *px = R::v3_to_f32(trace_primary(&cpu_scene, &ray));
            }
            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(n, u64::from(h));
        });
    Framebuffer {
        width: w,
        height: h,
        pixels,
    }
}
