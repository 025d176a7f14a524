//! Rays and what they meet: the camera's rays, the robust (and naive)
//! sphere and triangle tests, and the traversal of the wide tree for the
//! closest hit or any blocker.

use crate::bvh::wide::{self};
use crate::cpu::real::Real;
use crate::cpu::simd::prefetch_child;
use crate::layout::SPHERE_BIT;
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

/// For a sphere through the light a shadow ray ends at (`skip`): the crossing
/// that is not the light's own, when it lies in (0, 1 - TANGENT_BAND), else
/// T_INF (the shader's `hit_sphere_through_end`).
pub fn hit_sphere_through_end<R: Real>(ray: &Ray<R>, s: &Sphere<R>, band: R) -> R {
    let [t0, t1] = sphere_roots(ray, s, band);
    // The root nearer 1 is the light's own (a miss gives T_INF either way).
    let other = if (t0 - R::ONE).abs() > (t1 - R::ONE).abs() {
        t0
    } else {
        t1
    };
    if other > R::ZERO && other < R::ONE - R::from_f64(crate::bvh::lights_on_surfaces::TANGENT_BAND)
    {
        other
    } else {
        R::T_INF
    }
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

/// A leaf's primitives: true when an any-hit query found its hit. Up to
/// four static triangles meet the robust test in SIMD lanes where `R` has
/// them; the rest one by one.
pub(crate) fn hit_leaf<R: Real>(
    scene: &CpuScene<R>,
    ray: &Ray<R>,
    leaf: usize,
    best: &mut Hit<R>,
    any_hit: bool,
    skip: &[u32],
    graze: R,
) -> bool {
    let robust = scene.methods == Methods::Robust;
    let block = &scene.wide.leaves[leaf];
    if block.simd() && robust && !scene.motion_blur && skip.is_empty() {
        if let Some((lane, t, b1, b2)) = R::hit_block(ray, block, best.t) {
            let prim = block.prims[lane];
            *best = Hit { t, prim, b1, b2 };
            return any_hit;
        }
        return false;
    }
    for &prim in &scene.prim_refs[scene.wide.spans[leaf].range()] {
        if hit_prim(scene, ray, prim, best, any_hit, skip, graze) {
            return true;
        }
    }
    false
}

/// The primitive `prim` (a reference): true when `any_hit` and it blocks,
/// so the traversal can stop. The shader's `hit_prim`, which its traversal
/// calls for every reference of a node's hit leaves in one loop.
fn hit_prim<R: Real>(
    scene: &CpuScene<R>,
    ray: &Ray<R>,
    prim: u32,
    best: &mut Hit<R>,
    any_hit: bool,
    skip: &[u32],
    graze: R,
) -> bool {
    // The shader branches on ROBUST inside hit_sphere and hit_triangle.
    let robust = scene.methods == Methods::Robust;
    let index = (prim & !SPHERE_BIT) as usize;
    if any_hit && skip.contains(&prim) {
        // A surface through the light: triangles never block it, a
        // sphere only with its other crossing.
        if prim & SPHERE_BIT != 0 {
            let sphere = &sphere_at(scene, index, ray.time);
            let t = hit_sphere_through_end(ray, sphere, graze_band(graze, sphere.radius));
            if t < best.t {
                *best = Hit {
                    t,
                    prim,
                    b1: R::ZERO,
                    b2: R::ZERO,
                };
                return true;
            }
        }
        return false;
    }
    if prim & SPHERE_BIT != 0 {
        let sphere = &sphere_at(scene, index, ray.time);
        let t = if robust {
            let band = if any_hit {
                graze_band(graze, sphere.radius)
            } else {
                R::ZERO
            };
            hit_sphere(ray, sphere, best.t, band)
        } else {
            hit_sphere_naive(ray, sphere, best.t)
        };
        if t < best.t {
            *best = Hit {
                t,
                prim,
                b1: R::ZERO,
                b2: R::ZERO,
            };
            return any_hit;
        }
    } else {
        let tri = &triangle_at(scene, index, ray.time);
        let (t, b1, b2) = if robust {
            hit_triangle(ray, tri, best.t)
        } else {
            hit_triangle_naive(ray, tri, best.t)
        };
        if t < best.t {
            *best = Hit { t, prim, b1, b2 };
            return any_hit;
        }
    }
    false
}

/// With `any_hit`, `skip` names the surfaces through the light the ray ends
/// at and `graze` is the height of the ray's grazing band (`graze_band`).
///
/// Nearest child first: of the lanes a node's test hits, the nearest is
/// entered next and the others wait on the stack with their entry t, to be
/// dropped unopened if a hit closer than that has been found meanwhile
/// (the box test they would fail).
pub fn traverse<R: Real>(
    scene: &CpuScene<R>,
    ray: &Ray<R>,
    t_max: R,
    any_hit: bool,
    skip: &[u32],
    graze: R,
) -> Hit<R> {
    let mut best = Hit {
        t: t_max,
        prim: NO_HIT,
        b1: R::ZERO,
        b2: R::ZERO,
    };
    if scene.wide.nodes.is_empty() {
        return best;
    }
    let mut stack = Stack::new();
    stack.push(0, R::ZERO);
    traverse_from(scene, ray, &mut best, any_hit, skip, graze, &mut stack);
    best
}

/// `traverse`'s stack: nodes to visit with their entry t. Left
/// uninitialised, because clearing a fresh array per ray cost a tenth of
/// the render, and a stack kept per thread cost its lookups.
struct Stack<R: Real> {
    items: [std::mem::MaybeUninit<(u32, R)>; wide::STACK],
    len: usize,
}

impl<R: Real> Stack<R> {
    fn new() -> Self {
        Stack {
            items: [std::mem::MaybeUninit::uninit(); wide::STACK],
            len: 0,
        }
    }

    #[inline(always)]
    fn push(&mut self, node: u32, t: R) {
        // Indexed with a bounds check: `wide::STACK` bounds the depth.
        self.items[self.len] = std::mem::MaybeUninit::new((node, t));
        self.len += 1;
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, R)> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: items[..len] were all written by `push`.
        Some(unsafe { self.items[self.len].assume_init() })
    }
}

/// `traverse` from `node` down, keeping `best` unless it finds nearer.
pub(crate) fn traverse_below<R: Real>(
    scene: &CpuScene<R>,
    ray: &Ray<R>,
    node: u32,
    best: &mut Hit<R>,
    any_hit: bool,
) {
    let mut stack = Stack::new();
    stack.push(node, R::ZERO);
    traverse_from(scene, ray, best, any_hit, &[], R::ZERO, &mut stack);
}

#[allow(clippy::too_many_arguments)]
fn traverse_from<R: Real>(
    scene: &CpuScene<R>,
    ray: &Ray<R>,
    best: &mut Hit<R>,
    any_hit: bool,
    skip: &[u32],
    graze: R,
    stack: &mut Stack<R>,
) {
    while let Some((entry, t_entry)) = stack.pop() {
        if t_entry > best.t * R::BOX_T_SCALE {
            continue;
        }
        let node = &scene.wide.nodes[entry as usize];
        let (mut mask, t) = R::hit_boxes(ray, node, best.t);
        // Hit lanes onto the stack, farthest first, so the nearest is
        // popped next; the order is fixed by t, then lane. The shader's
        // `traverse` keeps the same order (its `order`, `append_hit`).
        let mut lanes = [0usize; 4];
        let mut n = 0;
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            // A ray with a NaN direction passes every box test, even an
            // unused lane's (and then hits no primitive).
            if node.child[lane] == wide::EMPTY {
                continue;
            }
            let mut i = n;
            while i > 0 && t[lanes[i - 1]] < t[lane] {
                lanes[i] = lanes[i - 1];
                i -= 1;
            }
            lanes[i] = lane;
            n += 1;
        }
        // The child nodes, and their leaf blocks, start loading before this
        // node's leaves are tested, as in the packets' walk (2M grid: the
        // render 2-3% faster, a fifth of it being rays handed off alone).
        for &lane in &lanes[..n] {
            if node.child[lane] & wide::LEAF == 0 {
                prefetch_child(scene.wide, node, lane);
            }
        }
        // Leaves are tested as they come, nearest first; nodes are stacked.
        for &lane in lanes[..n].iter().rev() {
            let child = node.child[lane];
            if child & wide::LEAF == 0 {
                continue;
            }
            if t[lane] > best.t * R::BOX_T_SCALE {
                continue;
            }
            let leaf = (child & !wide::LEAF) as usize;
            if hit_leaf(scene, ray, leaf, best, any_hit, skip, graze) {
                return;
            }
        }
        for &lane in &lanes[..n] {
            let child = node.child[lane];
            if child & wide::LEAF == 0 {
                stack.push(child, t[lane]);
            }
        }
    }
}

/// The closest hit of `ray` with t > 0, or `NO_HIT`.
pub fn trace_closest<R: Real>(scene: &CpuScene<R>, ray: &Ray<R>) -> Hit<R> {
    count_ray(0);
    traverse(scene, ray, R::T_INF, false, &[], R::ZERO)
}

/// `skip`, `graze`: the surfaces through the light and the grazing band's
/// height (`lights_on_surfaces`; empty and 0 for other lights).
pub fn occluder<R: Real>(scene: &CpuScene<R>, ray: &Ray<R>, skip: &[u32], graze: R) -> Hit<R> {
    count_ray(1);
    traverse(scene, ray, R::ONE, true, skip, graze)
}

/// The least discriminant r^2 - |l|^2 at which a shadow ray whose line may
/// lie up to `h` off its true one still meets a sphere of radius `r`
/// (`h` = 0: any). Moving a line by h changes |l|^2 by at most
/// 2 r h + h^2, so within the band it may only graze the sphere; the
/// sphere's own rounding adds ON_SURFACE r to h. The shader's `graze_band`.
pub fn graze_band<R: Real>(h: R, r: R) -> R {
    if h <= R::ZERO {
        return R::ZERO;
    }
    let h = h + R::from_f64(crate::bvh::lights_on_surfaces::ON_SURFACE) * r;
    h * (R::TWO * r + h)
}

/// For a shadow ray towards a point light on a surface: when the light lies
/// in the plane of the surface the ray leaves (within the ray's own lift off
/// it and the light's rounding), the height of the band within which the
/// ray's true line runs inside that plane, else 0. Such a line can only
/// touch a sphere resting on the plane, so lifted by the origin offset it
/// must not be blocked by clipping one (`lights_on_surfaces`).
pub fn in_plane_graze<R: Real>(sp: &SurfacePoint<R>, origin: R::V3, target: R::V3) -> R {
    let length = |v: R::V3| R::dot(v, v).sqrt();
    let to_light = target - sp.p;
    let t = R::vabs(target);
    let h = R::TWO * length(origin - sp.p)
        + R::from_f64(crate::bvh::lights_on_surfaces::ON_SURFACE)
            * (t[0].max(t[1]).max(t[2]) + length(to_light));
    if R::dot(sp.ng, to_light).abs() <= h {
        R::TWO * h
    } else {
        R::ZERO
    }
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
