//! The CPU reference renderer: the shader's algorithm (`trace.rs`, same
//! function names), parallel over rows with rayon, in f32 (the shader's twin)
//! or f64 (ground truth).

mod bands;
mod options;
pub mod packet;
mod real;
pub mod sample;
mod simd;
pub mod trace;

use bands::Bands;
pub use bands::{spread_order, Keep, Out, Work};
pub use options::{CpuOptions, Precision};
pub use real::Real;

use rayon::prelude::*;

use crate::bvh::Bvh;
use crate::camera::Camera;
use crate::images::framebuffer::{Framebuffer, Image};
use crate::probe::{PathLight, PathRecord, PathSurface, ProbeImage, ProbePixel};
use crate::scene::Scene;
use trace::{
    centre_key, light_term, pixel_color, pixel_ray, surface_point, trace_primary, CpuGeometry,
    CpuScene,
};

/// Renders the whole image on the CPU. `progress(rows_done, rows_total)` is
/// called from worker threads as rows finish. The BVH must be built for the
/// shutter interval when the scene has motion blur (`Bvh::build_swept`).
pub fn render(
    scene: &Scene,
    bvh: &Bvh,
    camera: &Camera,
    options: &CpuOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Framebuffer {
    let geometry = prepare(scene, bvh, options);
    render_where(
        scene,
        bvh,
        &geometry,
        camera,
        options,
        Keep::EVERY,
        progress,
    )
    .0
}

/// As `render`, only the pixels `keep` says (the others are 0): the CPU
/// twin of the GPU's `render_rects`. Also returns the rays cast and the
/// threads' CPU time (`Work`). `geometry` is `prepare`'s for this scene and BVH; its
/// precision is the render's.
pub fn render_where(
    scene: &Scene,
    bvh: &Bvh,
    geometry: &Geometry,
    camera: &Camera,
    options: &CpuOptions,
    keep: Keep,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> (Framebuffer, Work) {
    let rows = 0..camera.height;
    let (image, work) = render_rows(
        scene,
        bvh,
        geometry,
        camera,
        options,
        rows,
        keep,
        progress,
        Out::Float,
    );
    (image.into_float(), work)
}

/// As `render_where`, knowing that every pixel `keep` takes lies in `rows`
/// (the others are not visited at all: a part of a large image pays for its
/// own rows only, not for asking `keep` of every pixel), into what `out`
/// says: the float image, or the 8-bit one with each band turned to bytes
/// on its own thread as soon as it is rendered (`to_u8`: the float image is
/// never whole, and at 1080p the separate conversion's 6 ms and 24 MB are
/// gone).
#[allow(clippy::too_many_arguments)]
pub fn render_rows(
    scene: &Scene,
    bvh: &Bvh,
    geometry: &Geometry,
    camera: &Camera,
    options: &CpuOptions,
    rows: std::ops::Range<u32>,
    keep: Keep,
    progress: &(dyn Fn(u64, u64) + Sync),
    out: Out,
) -> (Image, Work) {
    fn pixels<'k, R: Real>(
        s: &CpuScene<R>,
        keep: Keep<'k>,
    ) -> impl Fn(&CpuScene<R>, u32, &mut [[f32; 3]]) + Sync + 'k {
        let w = s.size[0] as usize;
        move |s, y, row| {
            for (x, px) in row[..w].iter_mut().enumerate() {
                let x = x as u32;
                *px = if keep.pixel(x, y) {
                    R::v3_to_f32(R::clamp01(pixel_color(s, x, y)))
                } else {
                    [0.0; 3]
                };
            }
        }
    }
    let to = Bands {
        progress,
        active: rows,
        keep,
        out,
    };
    match geometry {
        Geometry::F32(g) => {
            let s = CpuScene::new(scene, bvh, g, camera, options);
            if options.packets && packet::applies(&s) {
                to.render(&s, packet::TILE[1], |s, y0, band| {
                    packet::fill_band(s, y0, band, keep);
                })
            } else {
                to.render(&s, 1, pixels(&s, keep))
            }
        }
        Geometry::F64(g) => {
            let s = CpuScene::new(scene, bvh, g, camera, options);
            to.render(&s, 1, pixels(&s, keep))
        }
    }
}

/// A scene's primitives and wide tree as the CPU reference reads them, in
/// the precision it renders in: built once per prepared scene, as the GPU
/// packs its buffers once, so that a render (or a progressive pass) pays
/// only for its rays.
pub enum Geometry {
    /// In f32, the shader's twin.
    F32(CpuGeometry<f32>),
    /// In f64, the ground truth.
    F64(CpuGeometry<f64>),
}

impl Geometry {
    /// The geometry of the same primitives moved (`Scene::at_time` of the
    /// scene it was made for, in view space), `bvh` refitted to them
    /// (`Bvh::refit`): see `CpuGeometry::refit`.
    pub(crate) fn refit(&mut self, scene: &Scene, bvh: &Bvh) {
        match self {
            Geometry::F32(g) => g.refit(scene, bvh),
            Geometry::F64(g) => g.refit(scene, bvh),
        }
    }
}

/// `scene` (in view space) and its BVH, for renders with `options`.
pub fn prepare(scene: &Scene, bvh: &Bvh, options: &CpuOptions) -> Geometry {
    match options.precision {
        Precision::F32 => Geometry::F32(CpuGeometry::new(scene, bvh, &options.effects)),
        Precision::F64 => Geometry::F64(CpuGeometry::new(scene, bvh, &options.effects)),
    }
}

/// Rays cast (closest-hit and shadow, all samples) by the pixels `xs` x
/// `ys`, row-major: the cost estimate behind `parts::cut`. Counted in f32
/// whatever the render's precision, so every node of a cluster gets the
/// same counts from the same binary.
pub fn ray_costs(
    scene: &Scene,
    bvh: &Bvh,
    geometry: &CpuGeometry<f32>,
    camera: &Camera,
    options: &CpuOptions,
    xs: &[u32],
    ys: &[u32],
) -> Vec<u64> {
    let s = CpuScene::new(scene, bvh, geometry, camera, options);
    ys.par_iter()
        .flat_map_iter(|&y| {
            let s = &s;
            xs.iter().map(move |&x| {
                let before = trace::rays_cast();
                std::hint::black_box(pixel_color(s, x, y));
                let after = trace::rays_cast();
                (after[0] - before[0]) + (after[1] - before[1])
            })
        })
        .collect()
}

/// Each pixel's primary hit and shadow verdicts, as the shader's `probe_tile`.
pub fn probe(scene: &Scene, bvh: &Bvh, camera: &Camera, options: &CpuOptions) -> ProbeImage {
    fn record<R: Real>(s: &CpuScene<R>, x: u32, y: u32) -> ProbePixel {
        let r = trace_primary(s, &pixel_ray(s, x, y), &centre_key(s, x, y));
        ProbePixel {
            prim: r.hit.prim,
            shadow_mask: r.shadow_mask,
            flags: r.flags,
            t: r.hit.t.to_f64() as f32,
        }
    }
    let none = &|_, _| {};
    let options = CpuOptions {
        background: [0.0; 3],
        ..*options
    };
    let (pixels, _) = match &prepare(scene, bvh, &options) {
        Geometry::F32(g) => per_pixel(
            &CpuScene::new(scene, bvh, g, camera, &options),
            none,
            0..camera.height,
            record,
        ),
        Geometry::F64(g) => per_pixel(
            &CpuScene::new(scene, bvh, g, camera, &options),
            none,
            0..camera.height,
            record,
        ),
    };
    ProbeImage {
        width: camera.width,
        height: camera.height,
        pixels,
    }
}

/// The path of pixel (x, y), as the shader's `probe_pixel` reports it.
pub fn pixel_path(
    scene: &Scene,
    bvh: &Bvh,
    camera: &Camera,
    options: &CpuOptions,
    pixel: [u32; 2],
) -> PathRecord {
    match &prepare(scene, bvh, options) {
        Geometry::F32(g) => path_in(&CpuScene::new(scene, bvh, g, camera, options), pixel),
        Geometry::F64(g) => path_in(&CpuScene::new(scene, bvh, g, camera, options), pixel),
    }
}

fn path_in<R: Real>(scene: &CpuScene<R>, [x, y]: [u32; 2]) -> PathRecord {
    let ray = pixel_ray(scene, x, y);
    let key = centre_key(scene, x, y);
    let r = trace_primary(scene, &ray, &key);
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
    record.lights = (0..scene.lights.len())
        .map(|i| {
            let term = light_term(scene, &sp, -ray.dir, i, 0, &key);
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

/// `f(scene, x, y)` for every pixel, rows in parallel (`Bands::per_band`). Also
/// returns what the threads did (`Work`).
fn per_pixel<R: Real, T: Send + Default + Clone>(
    scene: &CpuScene<R>,
    progress: &(dyn Fn(u64, u64) + Sync),
    active: std::ops::Range<u32>,
    f: impl Fn(&CpuScene<R>, u32, u32) -> T + Sync,
) -> (Vec<T>, Work) {
    let w = scene.size[0] as usize;
    let bands = Bands {
        progress,
        active,
        keep: Keep::EVERY,
        out: Out::Float,
    };
    bands.per_band(scene, 1, |scene, y, row| {
        for (x, px) in row[..w].iter_mut().enumerate() {
            *px = f(scene, x as u32, y);
        }
    })
}

#[cfg(test)]
mod tests {

    /// A render says how much CPU time its threads spent where the system
    /// has a thread clock: some, and no more than all its threads could
    /// have run in the wall time it took; and the rays it counted.
    #[test]
    fn a_render_reports_its_threads_cpu_time() {
        let scene = crate::bvh::wide::tests::scene(300);
        let bvh = crate::bvh::Bvh::build(&scene);
        let camera = crate::camera::Camera::new(64, 48);
        for packets in [true, false] {
            let options = super::CpuOptions {
                packets,
                ..Default::default()
            };
            let geometry = super::prepare(&scene, &bvh, &options);
            let wall = std::time::Instant::now();
            let (_, work) = super::render_where(
                &scene,
                &bvh,
                &geometry,
                &camera,
                &options,
                super::Keep::EVERY,
                &|_, _| {},
            );
            let wall = wall.elapsed();
            assert!(work.rays[0] >= 64 * 48, "{:?}", work.rays);
            match work.cpu_time {
                Some(t) => {
                    let threads = rayon::current_num_threads() as u32;
                    assert!(
                        t > std::time::Duration::ZERO && t <= wall * threads,
                        "{t:?} in {wall:?}"
                    );
                }
                None if cfg!(unix) => panic!("no CPU time where unix has a thread clock"),
                None => {}
            }
        }
    }
}
