//! The CPU reference renderer: the shader's algorithm (`trace.rs`, same
//! function names), parallel over rows with rayon, in f32 (the shader's twin)
//! or f64 (ground truth).

mod options;
pub mod packet;
mod real;
pub mod sample;
mod simd;
pub mod trace;

pub use options::{CpuOptions, Precision};
pub use real::Real;

use std::time::Duration;

use rayon::prelude::*;

use crate::bvh::Bvh;
use crate::camera::Camera;
use crate::images::framebuffer::{to_u8, Framebuffer, Image};
use crate::probe::{PathLight, PathRecord, PathSurface, ProbeImage, ProbePixel};
use crate::scene::Scene;
use image::RgbImage;
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
        &|_, _| true,
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
    keep: &(dyn Fn(u32, u32) -> bool + Sync),
    progress: &(dyn Fn(u64, u64) + Sync),
) -> (Framebuffer, Work) {
    let rows = 0..camera.height;
    let (image, work) = render_rows(
        scene, bvh, geometry, camera, options, rows, keep, progress, false,
    );
    (image.into_float(), work)
}

/// As `render_where`, knowing that every pixel `keep` takes lies in `rows`
/// (the others are not visited at all: a part of a large image pays for its
/// own rows only, not for asking `keep` of every pixel), into the 8-bit
/// image when `eight_bit` (each band turned to bytes on its own thread as
/// soon as it is rendered, `to_u8`: the float image is never whole, and at
/// 1080p the separate conversion's 6 ms and 24 MB are gone), else into the
/// float one.
#[allow(clippy::too_many_arguments)]
pub fn render_rows(
    scene: &Scene,
    bvh: &Bvh,
    geometry: &Geometry,
    camera: &Camera,
    options: &CpuOptions,
    rows: std::ops::Range<u32>,
    keep: &(dyn Fn(u32, u32) -> bool + Sync),
    progress: &(dyn Fn(u64, u64) + Sync),
    eight_bit: bool,
) -> (Image, Work) {
    fn colour<R: Real>(s: &CpuScene<R>, x: u32, y: u32) -> [f32; 3] {
        R::v3_to_f32(R::clamp01(pixel_color(s, x, y)))
    }
    fn pixels<'k, R: Real>(
        s: &CpuScene<R>,
        keep: &'k (dyn Fn(u32, u32) -> bool + Sync),
    ) -> impl Fn(&CpuScene<R>, u32, &mut [[f32; 3]]) + Sync + 'k {
        let w = s.size[0] as usize;
        move |s, y, row| {
            for (x, px) in row[..w].iter_mut().enumerate() {
                let x = x as u32;
                *px = if keep(x, y) {
                    colour(s, x, y)
                } else {
                    [0.0; 3]
                };
            }
        }
    }
    let to = Bands {
        progress,
        active: rows,
        eight_bit,
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

/// Which rows a render's bands cover, who hears of them, and what they
/// become.
struct Bands<'a> {
    progress: &'a (dyn Fn(u64, u64) + Sync),
    active: std::ops::Range<u32>,
    eight_bit: bool,
}

impl Bands<'_> {
    /// The image `fill(scene, y0, band)` makes, `rows` rows a band.
    fn render<R: Real>(
        &self,
        scene: &CpuScene<R>,
        rows: u32,
        fill: impl Fn(&CpuScene<R>, u32, &mut [[f32; 3]]) + Sync,
    ) -> (Image, Work) {
        let [width, height] = scene.size;
        if !self.eight_bit {
            let (pixels, work) = per_band(scene, self.progress, rows, self.active.clone(), fill);
            let fb = Framebuffer {
                width,
                height,
                pixels,
            };
            return (Image::Float(fb), work);
        }
        let mut bytes = vec![0u8; 3 * width as usize * height as usize];
        let work = for_bands(
            scene,
            self.progress,
            rows,
            self.active.clone(),
            &mut bytes,
            3,
            |scene, y0, out: &mut [u8]| {
                let mut band = vec![[0.0f32; 3]; out.len() / 3];
                fill(scene, y0, &mut band);
                for (o, &v) in out.iter_mut().zip(bytemuck::cast_slice::<_, f32>(&band)) {
                    *o = to_u8(v);
                }
            },
        );
        let image = RgbImage::from_raw(width, height, bytes).expect("3 bytes a pixel");
        (Image::Rgb8(image), work)
    }
}

/// What a render's threads did besides their pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Work {
    /// Closest-hit and shadow rays cast.
    pub rays: [u64; 2],
    /// CPU time the threads spent on the pixels, summed over threads
    /// (`timing::thread_cpu_time`); None where the system cannot say.
    pub cpu_time: Option<Duration>,
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

/// `f(scene, x, y)` for every pixel, rows in parallel (`per_band`). Also
/// returns what the threads did (`Work`).
fn per_pixel<R: Real, T: Send + Default + Clone>(
    scene: &CpuScene<R>,
    progress: &(dyn Fn(u64, u64) + Sync),
    active: std::ops::Range<u32>,
    f: impl Fn(&CpuScene<R>, u32, u32) -> T + Sync,
) -> (Vec<T>, Work) {
    let w = scene.size[0] as usize;
    per_band(scene, progress, 1, active, |scene, y, row| {
        for (x, px) in row[..w].iter_mut().enumerate() {
            *px = f(scene, x as u32, y);
        }
    })
}

/// `f(scene, y0, band)` fills each band of `rows` rows from row `y0` (the
/// last may have fewer; `T::default()` to start with), bands in parallel,
/// taken in `spread_order` so that `progress(rows_done, rows)` advances at
/// an even pace: rows in order would finish the cheap sky first and the
/// costly floor last, and an ETA from them would be wrong by the ratio.
/// Bands that miss the rows `active` are left as they start.
/// Also returns the rays `f` cast and the threads' CPU time (`Work`).
fn per_band<R: Real, T: Send + Default + Clone>(
    scene: &CpuScene<R>,
    progress: &(dyn Fn(u64, u64) + Sync),
    rows: u32,
    active: std::ops::Range<u32>,
    f: impl Fn(&CpuScene<R>, u32, &mut [T]) + Sync,
) -> (Vec<T>, Work) {
    let [w, h] = scene.size;
    let mut out = vec![T::default(); w as usize * h as usize];
    let work = for_bands(scene, progress, rows, active, &mut out, 1, f);
    (out, work)
}

/// `per_band`'s bands over `out`, which holds `per_pixel` elements a pixel.
fn for_bands<R: Real, U: Send>(
    scene: &CpuScene<R>,
    progress: &(dyn Fn(u64, u64) + Sync),
    rows: u32,
    active: std::ops::Range<u32>,
    out: &mut [U],
    per_pixel: usize,
    f: impl Fn(&CpuScene<R>, u32, &mut [U]) + Sync,
) -> Work {
    use std::sync::atomic::{AtomicU64, Ordering};
    let [w, h] = scene.size;
    let rows = rows.max(1);
    let done = AtomicU64::new(0);
    let rays = [AtomicU64::new(0), AtomicU64::new(0)];
    let cpu_ns = AtomicU64::new(0);
    let row_len = w as usize * per_pixel;
    let mut bands: Vec<Option<&mut [U]>> = out
        .chunks_mut((row_len * rows as usize).max(1))
        .map(Some)
        .collect();
    let ordered: Vec<(u32, &mut [U])> = spread_order(bands.len() as u32)
        .into_iter()
        .filter(|&b| b * rows < active.end && (b + 1) * rows > active.start)
        .filter_map(|b| Some((b * rows, bands[b as usize].take()?)))
        .collect();
    let visited =
        ordered.iter().map(|(_, b)| b.len() as u64).sum::<u64>() / (row_len.max(1) as u64);
    done.store(u64::from(h) - visited, Ordering::Relaxed);
    ordered.into_par_iter().for_each(|(y0, band)| {
        // A band runs on one thread from start to end, so the thread's
        // counters moved by this band's rays alone.
        let before = trace::rays_cast();
        let started = crate::timing::thread_cpu_time();
        let n = band.len() as u64 / (row_len.max(1) as u64);
        f(scene, y0, band);
        if let (Some(a), Some(b)) = (started, crate::timing::thread_cpu_time()) {
            cpu_ns.fetch_add(b.saturating_sub(a).as_nanos() as u64, Ordering::Relaxed);
        }
        let after = trace::rays_cast();
        for k in 0..2 {
            rays[k].fetch_add(after[k] - before[k], Ordering::Relaxed);
        }
        let finished = done.fetch_add(n, Ordering::Relaxed) + n;
        progress(finished, u64::from(h));
    });
    Work {
        rays: rays.map(AtomicU64::into_inner),
        // The clock is the system's: there for every band or for none.
        cpu_time: crate::timing::thread_cpu_time()
            .map(|_| Duration::from_nanos(cpu_ns.into_inner())),
    }
}

/// The rows 0..n in an order whose every stretch is spread over the whole
/// image: row (i * s) mod n, with the stride s near n / golden ratio and
/// coprime to n (so each row comes once).
pub fn spread_order(n: u32) -> Vec<u32> {
    if n < 3 {
        return (0..n).collect();
    }
    let gcd = |mut a: u64, mut b: u64| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let mut stride = ((f64::from(n) * 0.618_033_988_75) as u64).max(1);
    while gcd(stride, u64::from(n)) != 1 {
        stride += 1;
    }
    (0..u64::from(n))
        .map(|i| ((i * stride) % u64::from(n)) as u32)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::spread_order;

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
                &|_, _| true,
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

    /// Each row once, and any stretch of the order is spread evenly: the
    /// first eighth of the work touches every eighth of the image.
    #[test]
    fn spread_order_is_a_permutation_spread_over_the_image() {
        for n in [0, 1, 2, 3, 7, 30, 240, 480, 1000, 1024, 16384] {
            let order = spread_order(n);
            let mut seen = order.clone();
            seen.sort_unstable();
            assert_eq!(seen, (0..n).collect::<Vec<_>>(), "n = {n}");
            if n >= 64 {
                let eighth = (n / 8) as usize;
                for start in [0, eighth, 3 * eighth] {
                    let mut bands = [0u32; 8];
                    for &y in &order[start..start + eighth] {
                        bands[(y * 8 / n) as usize] += 1;
                    }
                    let (lo, hi) = (bands.iter().min().unwrap(), bands.iter().max().unwrap());
                    assert!(
                        *lo > 0 && hi - lo <= eighth as u32 / 4 + 2,
                        "n = {n}: {bands:?}"
                    );
                }
            }
        }
    }
}
