//! Rays and what they meet: the camera's rays and the robust (and naive)
//! sphere and triangle tests (the traversal that calls them:
//! `traverse`).

use crate::cpu::real::Real;
use crate::methods::Methods;

use super::scene::*;
use crate::cpu::real::Ray;

thread_local! {
    /// Closest-hit and shadow rays this thread has cast (`rays_cast`), as
    /// the shader's status counts them, and the shadow rays it left
    /// untraced (`UNTRACED`); a thread-local, so counting costs no shared
    /// cache line.
    static RAYS: std::cell::Cell<[u64; 3]> = const { std::cell::Cell::new([0; 3]) };
}

#[inline]
pub(crate) fn count_ray(kind: usize) {
    count_rays(kind, 1);
}

/// `count_ray` for `n` rays at once (a packet's).
#[inline]
pub(crate) fn count_rays(kind: usize, n: u64) {
    RAYS.with(|r| {
        let mut v = r.get();
        v[kind] += n;
        r.set(v);
    });
}

/// `count_rays`'s kind for shadow rays left untraced because their answer
/// could not change a pixel (the packets' `points::changed_by`).
pub(crate) const UNTRACED: usize = 2;

/// Closest-hit and shadow rays cast on this thread so far, and shadow
/// rays left untraced; the difference of two readings around some work
/// is what that work cast.
pub fn rays_cast() -> [u64; 3] {
    RAYS.with(std::cell::Cell::get)
}

/// A ray from `origin` along `dir` at `time`, with what the tests precompute.
#[inline(always)]
pub fn make_ray<R: Real>(origin: R::V3, dir: R::V3, time: R) -> Ray<R> {
    let inv_dir = R::v3(
        R::ONE / safe_dir(dir[0]),
        R::ONE / safe_dir(dir[1]),
        R::ONE / safe_dir(dir[2]),
    );
    ray_with_inverse(origin, dir, inv_dir, time)
}

/// A direction component as `make_ray` divides by it: one too near zero
/// for its inverse to stay finite moved off to `MIN_DIR`, with its sign.
#[inline(always)]
pub fn safe_dir<R: Real>(d: R) -> R {
    if d.abs() < R::MIN_DIR {
        d.sign_nonzero() * R::MIN_DIR
    } else {
        d
    }
}

/// `make_ray` once its inverse direction is known (`packet::make_rays`
/// takes the divisions for many rays at once).
#[inline(always)]
pub fn ray_with_inverse<R: Real>(origin: R::V3, dir: R::V3, inv_dir: R::V3, time: R) -> Ray<R> {
    let a = R::vabs(dir);
    let kz = if a[0] > a[1] && a[0] > a[2] {
        0
    } else if a[1] > a[2] {
        1
    } else {
        2
    };
    let mut kx = (kz + 1) % 3;
    let mut ky = (kx + 1) % 3;
    if dir[kz] < R::ZERO {
        std::mem::swap(&mut kx, &mut ky);
    }
    let sz = R::ONE / dir[kz];
    Ray {
        origin,
        dir,
        inv_dir,
        k: [kx, ky, kz],
        shear: R::v3(dir[kx] * sz, dir[ky] * sz, sz),
        time,
    }
}

/// The camera ray through pixel (x, y) at `offset` within it ([0,1)², from
/// its top-left corner), at `time`; the classic camera at the origin.
pub fn camera_ray<R: Real>(scene: &CpuScene<R>, x: u32, y: u32, offset: [R; 2], time: R) -> Ray<R> {
    let (w, h) = (R::from_u32(scene.size[0]), R::from_u32(scene.size[1]));
    let ndc_x = (R::TWO * (R::from_u32(x) + offset[0]) / w - R::ONE) * scene.half_extent[0];
    let ndc_y = (R::ONE - R::TWO * (R::from_u32(y) + offset[1]) / h) * scene.half_extent[1];
    let zero = R::v3(R::ZERO, R::ZERO, R::ZERO);
    make_ray(zero, R::normalize(R::v3(ndc_x, ndc_y, -R::ONE)), time)
}

/// The camera ray through pixel (x, y)'s centre at time 0.
pub fn pixel_ray<R: Real>(scene: &CpuScene<R>, x: u32, y: u32) -> Ray<R> {
    camera_ray(scene, x, y, [R::HALF, R::HALF], R::ZERO)
}

/// Sphere `index` where it is at `time` (with motion blur).
pub fn sphere_at<R: Real>(scene: &CpuScene<R>, index: usize, time: R) -> Sphere<R> {
    let mut s = scene.spheres[index];
    if scene.motion_blur {
        s.center = s.center + s.velocity * time;
    }
    s
}

/// Triangle `index`'s corners where they are at `time` (with motion blur).
pub fn triangle_at<R: Real>(scene: &CpuScene<R>, index: usize, time: R) -> [R::V3; 3] {
    let mut tri = scene.triangles[index];
    if scene.motion_blur {
        let shift = scene.triangle_velocity[index] * time;
        tri = tri.map(|v| v + shift);
    }
    tri
}

/// Light `index` where it is at `time` (with motion blur).
pub fn light_at<R: Real>(scene: &CpuScene<R>, index: usize, time: R) -> Light<R> {
    let mut light = scene.lights[index];
    if scene.motion_blur {
        light.position = light.position + light.velocity * time;
    }
    light
}

/// Where the ray enters the box, conservatively (the box scaled by
/// `BOX_T_SCALE`), clamped to 0; `T_INF` when it misses or starts past `t_max`.
pub fn hit_aabb<R: Real>(ray: &Ray<R>, bmin: [f32; 3], bmax: [f32; 3], t_max: R) -> R {
    let t0 = (R::v3_from_f32(bmin) - ray.origin) * ray.inv_dir;
    let t1 = (R::v3_from_f32(bmax) - ray.origin) * ray.inv_dir;
    let tn = R::vmin(t0, t1);
    let tf = R::vmax(t0, t1);
    let t_near = tn[0].max(tn[1]).max(tn[2].max(R::ZERO));
    let t_far = tf[0].min(tf[1]).min(tf[2].min(t_max)) * R::BOX_T_SCALE;
    if t_near <= t_far {
        t_near
    } else {
        R::T_INF
    }
}

/// Both t where the ray's line meets the sphere (unordered), or T_INF twice
/// when it misses, or only grazes it: its discriminant r^2 - |l|^2 is below
/// `band` (0 but for shadow rays inside a plane through the light; see
/// `graze_band`). The shader's `sphere_roots`.
pub fn sphere_roots<R: Real>(ray: &Ray<R>, s: &Sphere<R>, band: R) -> [R; 2] {
    let f = ray.origin - s.center;
    let a = R::dot(ray.dir, ray.dir);
    let b = -R::dot(f, ray.dir);
    let c = R::dot(f, f) - s.radius * s.radius;
    let l = f + ray.dir * (b / a);
    let disc = s.radius * s.radius - R::dot(l, l);
    if disc < band {
        return [R::T_INF; 2];
    }
    let q = b + b.sign_nonzero() * (a * disc).sqrt();
    [c / q, q / a]
}

/// The nearest root in (0, `t_max`), or `T_INF` (the robust method).
pub fn hit_sphere<R: Real>(ray: &Ray<R>, s: &Sphere<R>, t_max: R, band: R) -> R {
    let [t0, t1] = sphere_roots(ray, s, band);
    let t_lo = t0.min(t1);
    let t_hi = t0.max(t1);
    if t_lo > R::ZERO && t_lo < t_max {
        return t_lo;
    }
    if t_hi > R::ZERO && t_hi < t_max {
        return t_hi;
    }
    R::T_INF
}

/// The textbook quadratic's nearest root in (0, `t_max`), or `T_INF`: the
/// naive method, kept to show what the robust one fixes.
pub fn hit_sphere_naive<R: Real>(ray: &Ray<R>, s: &Sphere<R>, t_max: R) -> R {
    let oc = ray.origin - s.center;
    let a = R::dot(ray.dir, ray.dir);
    let b = R::TWO * R::dot(oc, ray.dir);
    let c = R::dot(oc, oc) - s.radius * s.radius;
    let disc = b * b - R::from_f64(4.0) * a * c;
    if disc < R::ZERO {
        return R::T_INF;
    }
    let root = disc.sqrt();
    let t0 = (-b - root) / (R::TWO * a);
    let t1 = (-b + root) / (R::TWO * a);
    if t0 > R::ZERO && t0 < t_max {
        return t0;
    }
    if t1 > R::ZERO && t1 < t_max {
        return t1;
    }
    R::T_INF
}

/// Möller-Trumbore with an epsilon on the determinant: the naive method.
/// (t, b1, b2), t = `T_INF` on a miss.
pub fn hit_triangle_naive<R: Real>(ray: &Ray<R>, tri: &[R::V3; 3], t_max: R) -> (R, R, R) {
    let miss = (R::T_INF, R::ZERO, R::ZERO);
    let e1 = tri[1] - tri[0];
    let e2 = tri[2] - tri[0];
    let pv = R::cross(ray.dir, e2);
    let det = R::dot(e1, pv);
    if det.abs() < R::NAIVE_DET_EPSILON {
        return miss;
    }
    let inv_det = R::ONE / det;
    let tv = ray.origin - tri[0];
    let u = R::dot(tv, pv) * inv_det;
    if u < R::ZERO || u > R::ONE {
        return miss;
    }
    let qv = R::cross(tv, e1);
    let v = R::dot(ray.dir, qv) * inv_det;
    if v < R::ZERO || u + v > R::ONE {
        return miss;
    }
    let t = R::dot(e2, qv) * inv_det;
    if t <= R::ZERO || t >= t_max {
        return miss;
    }
    (t, u, v)
}

/// Returns (t, b1, b2), t = `T_INF` for a miss.
pub fn hit_triangle<R: Real>(ray: &Ray<R>, tri: &[R::V3; 3], t_max: R) -> (R, R, R) {
    let miss = (R::T_INF, R::ZERO, R::ZERO);
    let a = tri[0] - ray.origin;
    let b = tri[1] - ray.origin;
    let c = tri[2] - ray.origin;
    let [kx, ky, kz] = ray.k;
    let s = ray.shear;
    let ax = a[kx] - s[0] * a[kz];
    let ay = a[ky] - s[1] * a[kz];
    let bx = b[kx] - s[0] * b[kz];
    let by = b[ky] - s[1] * b[kz];
    let cx = c[kx] - s[0] * c[kz];
    let cy = c[ky] - s[1] * c[kz];
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    let zero = R::ZERO;
    if (u < zero || v < zero || w < zero) && (u > zero || v > zero || w > zero) {
        return miss;
    }
    let det = u + v + w;
    if det == zero {
        return miss;
    }
    let az = s[2] * a[kz];
    let bz = s[2] * b[kz];
    let cz = s[2] * c[kz];
    let t_scaled = u * az + v * bz + w * cz;
    let positive = t_scaled > zero && t_scaled < t_max * det;
    let negative = t_scaled < zero && t_scaled > t_max * det;
    let inside = if det > zero { positive } else { negative };
    if !inside {
        return miss;
    }
    let inv_det = R::ONE / det;
    (t_scaled * inv_det, v * inv_det, w * inv_det)
}

/// `p` moved off its surface along `n`: whole ulps (robust) or a fixed
/// distance (naive).
pub fn offset_ray<R: Real>(scene: &CpuScene<R>, p: R::V3, n: R::V3, scale: R::V3) -> R::V3 {
    match scene.methods {
        Methods::Robust => R::offset_ray(p, n, scale),
        Methods::Naive => p + n * R::NAIVE_OFFSET,
    }
}

/// `v` at unit length, or `fallback` where it has none.
pub fn safe_normalize<R: Real>(v: R::V3, fallback: R::V3) -> R::V3 {
    let len2 = R::dot(v, v);
    if len2 > R::ZERO {
        v * len2.inverse_sqrt()
    } else {
        fallback
    }
}

/// `x` to the power `y` as the Phong term needs it: 1 when `y` is 0 (C's `pow`
/// gives 0^0 = 1), 0 for a base of 0 or below (never NaN).
pub fn pow_c<R: Real>(x: R, y: R) -> R {
    if y == R::ZERO {
        return R::ONE;
    }
    if x <= R::ZERO {
        return R::ZERO;
    }
    x.powf(y)
}
