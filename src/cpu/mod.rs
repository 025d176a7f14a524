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
use crate::methods::Methods;
use crate::probe::{PathLight, PathRecord, PathSurface, ProbeImage, ProbePixel};
use crate::scene::Scene;
use trace::{light_term, pixel_ray, surface_point, trace_primary, CpuScene};

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
    methods: Methods,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Framebuffer {
    let pixels = match precision {
        Precision::F32 => {
            let s = CpuScene::<f32>::new(scene, bvh, camera, background, methods);
            per_pixel(&s, progress, |r| f32::v3_to_f32(f32::clamp01(r.color)))
        }
        Precision::F64 => {
            let s = CpuScene::<f64>::new(scene, bvh, camera, background, methods);
            per_pixel(&s, progress, |r| f64::v3_to_f32(f64::clamp01(r.color)))
        }
    };
    Framebuffer {
        width: camera.width,
        height: camera.height,
        pixels,
    }
}

/// Each pixel's primary hit and shadow verdicts, as the shader's `probe_tile`.
pub fn probe(
    scene: &Scene,
    bvh: &Bvh,
    camera: &Camera,
    precision: Precision,
    methods: Methods,
) -> ProbeImage {
    fn record<R: Real>(r: &trace::PixelResult<R>) -> ProbePixel {
        ProbePixel {
            prim: r.hit.prim,
            shadow_mask: r.shadow_mask,
            flags: r.flags,
            t: r.hit.t.to_f64() as f32,
        }
    }
    let none = &|_, _| {};
    let pixels = match precision {
        Precision::F32 => {
            let s = CpuScene::<f32>::new(scene, bvh, camera, [0.0; 3], methods);
            per_pixel(&s, none, record)
        }
        Precision::F64 => {
            let s = CpuScene::<f64>::new(scene, bvh, camera, [0.0; 3], methods);
            per_pixel(&s, none, record)
        }
    };
    ProbeImage {
        width: camera.width,
        height: camera.height,
        pixels,
    }
}

/// The path of pixel (x, y), as the shader's `probe_pixel` reports it.
#[allow(clippy::too_many_arguments)]
pub fn pixel_path(
    scene: &Scene,
    bvh: &Bvh,
    camera: &Camera,
    background: [f32; 3],
    precision: Precision,
    methods: Methods,
    pixel: [u32; 2],
) -> PathRecord {
    match precision {
        Precision::F32 => path_in(
            &CpuScene::<f32>::new(scene, bvh, camera, background, methods),
            pixel,
        ),
        Precision::F64 => path_in(
            &CpuScene::<f64>::new(scene, bvh, camera, background, methods),
            pixel,
        ),
    }
}

fn path_in<R: Real>(scene: &CpuScene<R>, [x, y]: [u32; 2]) -> PathRecord {
    let ray = pixel_ray(scene, x, y);
    let r = trace_primary(scene, &ray);
    let v = R::v3_to_f64;
    let mut record = PathRecord {
        dir: v(ray.dir),
        prim: r.hit.prim,
        t: r.hit.t.to_f64(),
        b1: r.hit.b1.to_f64(),
        b2: r.hit.b2.to_f64(),
        color: v(r.color),
        shadow_mask: r.shadow_mask,
        flags: r.flags,
        surface: None,
        lights: Vec::new(),
    };
    if r.hit.prim == trace::NO_HIT {
        return record;
    }
    let sp = surface_point(scene, &ray, &r.hit);
    record.surface = Some(PathSurface {
        point: v(sp.p),
        normal: v(sp.n),
        geometric_normal: v(sp.ng),
        kd: v(sp.kd),
        ks: v(sp.ks),
        shininess: sp.shininess.to_f64(),
    });
    record.lights = scene
        .lights
        .iter()
        .map(|light| {
            let term = light_term(scene, &sp, -ray.dir, light);
            PathLight {
                origin: v(term.origin),
                blocker: term.blocker.prim,
                blocker_t: term.blocker.t.to_f64(),
                ln: term.ln.to_f64(),
                rv: term.rv.to_f64(),
                spec: term.spec.to_f64(),
                contribution: v(term.contribution),
            }
        })
        .collect();
    record
}

/// `f(trace_primary(pixel))` for every pixel, rows in parallel.
fn per_pixel<R: Real, T: Send + Default + Clone>(
    scene: &CpuScene<R>,
    progress: &(dyn Fn(u64, u64) + Sync),
    f: impl Fn(&trace::PixelResult<R>) -> T + Sync,
) -> Vec<T> {
    let [w, h] = scene.size;
    let done = std::sync::atomic::AtomicU64::new(0);
    let mut out = vec![T::default(); w as usize * h as usize];
    out.par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, px) in row.iter_mut().enumerate() {
                let ray = pixel_ray(scene, x as u32, y as u32);
                *px = f(&trace_primary(scene, &ray));
            }
            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(n, u64::from(h));
        });
    out
}
