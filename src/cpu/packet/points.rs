//! A packet's shading in lanes: its triangles' surface points, their
//! shadow rays' origins and the point lights' terms, one f32 array per
//! component with a ray to each element, in loops the compiler turns into
//! whole registers of rays (eight under AVX2, sixteen under AVX-512). Each
//! lane takes the single ray's operations (`trace::surface_point`,
//! `shadow_origin`, `point_shading`) in the same order on the same values:
//! multiplies, adds, divisions, square roots and the same `f32::max`, each
//! correctly rounded whatever the width, and no fused multiply-add (Rust
//! never contracts). So every lane is the single ray's to the bit (tested
//! at each width). `powf` stays one call a lane, the libm one the single
//! ray calls.
//!
//! Shading a pixel at a time in SSE (a vector's three components in one
//! register) was 40% of `table`'s render: each step waited on the one
//! before, and the horizontal sums of its dot products wasted the
//! register's width.

use super::lanes::{lane, set_lane, Lanes, V3s, WIDTH, ZEROS};
use crate::cpu::simd::prefetch;
use crate::cpu::trace::{pow_c, CpuScene, Hit, SurfacePoint};
use glam::Vec3;

/// A packet's surface points (`SurfacePoint`), by component.
#[derive(Clone, Copy)]
pub(super) struct Points {
    pub(super) p: V3s,
    pub(super) n: V3s,
    pub(super) ng: V3s,
    pub(super) scale: V3s,
    pub(super) kd: V3s,
    pub(super) ks: V3s,
    pub(super) shininess: Lanes,
}

impl Points {
    pub(super) const ZERO: Points = Points {
        p: ZEROS,
        n: ZEROS,
        ng: ZEROS,
        scale: ZEROS,
        kd: ZEROS,
        ks: ZEROS,
        shininess: Lanes::ZERO,
    };

    /// Lane `i`'s point.
    #[inline(always)]
    pub(super) fn get(&self, i: usize) -> SurfacePoint<f32> {
        SurfacePoint {
            p: lane(&self.p, i),
            n: lane(&self.n, i),
            ng: lane(&self.ng, i),
            scale: lane(&self.scale, i),
            kd: lane(&self.kd, i),
            ks: lane(&self.ks, i),
            shininess: self.shininess.0[i],
        }
    }

    /// Sets lane `i` to `sp`.
    #[inline(always)]
    pub(super) fn set(&mut self, i: usize, sp: &SurfacePoint<f32>) {
        set_lane(&mut self.p, i, sp.p);
        set_lane(&mut self.n, i, sp.n);
        set_lane(&mut self.ng, i, sp.ng);
        set_lane(&mut self.scale, i, sp.scale);
        set_lane(&mut self.kd, i, sp.kd);
        set_lane(&mut self.ks, i, sp.ks);
        self.shininess.0[i] = sp.shininess;
    }
}

/// What `trace::surface_point` reads of a triangle hit, gathered by lane:
/// the corners, their shading normals and materials, and the barycentrics.
/// Scratch space, kept from packet to packet: lanes without a triangle
/// hold whatever an earlier packet left (made once, its 6 KB were a
/// `memset` a packet).
pub(super) struct Corners {
    pos: [V3s; 3],
    normal: [V3s; 3],
    kd: [V3s; 3],
    ks: [V3s; 3],
    shininess: [Lanes; 3],
    b1: Lanes,
    b2: Lanes,
}

impl Corners {
    pub(super) const ZERO: Corners = Corners {
        pos: [ZEROS; 3],
        normal: [ZEROS; 3],
        kd: [ZEROS; 3],
        ks: [ZEROS; 3],
        shininess: [Lanes::ZERO; 3],
        b1: Lanes::ZERO,
        b2: Lanes::ZERO,
    };
}

/// `trace::safe_normalize` of lane `i` (its dot product left to right,
/// then one division by the square root), `fallback` where `v` has no
/// length.
#[inline(always)]
fn safe_normalize(v: [f32; 3], fallback: [f32; 3]) -> [f32; 3] {
    let len2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    let s = 1.0 / len2.sqrt();
    let n = [v[0] * s, v[1] * s, v[2] * s];
    if len2 > 0.0 {
        n
    } else {
        fallback
    }
}

#[inline(always)]
fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Bytes of triangle corners and shading above which `triangle_points`
/// prefetches its hits' before reading them: 1 MiB, a core's L2 on the
/// CPUs measured (AMD Zen 4 and 5), below which they are likely cached.
const PREFETCH_ABOVE: usize = 1 << 20;

/// The surface points of the triangle hits in `lanes` (each the robust
/// method's `surface_point`, nothing moving), every lane of `points`
/// written: the others from whatever `c` held there, for the caller to
/// overwrite or ignore (a store in every lane is what lets the loop fill
/// whole registers).
#[inline(always)]
pub(super) fn triangle_points(
    scene: &CpuScene<f32>,
    hits: &[Hit<f32>; WIDTH],
    lanes: u32,
    c: &mut Corners,
    points: &mut Points,
) {
    // Every hit's corners and shading asked for at once before any is
    // read: on a large mesh each is a cache miss, and the gather loop
    // below, waiting on them one lane at a time, was half of the packets'
    // shading (perf, 2M grid: the render 2-4% faster). Where both lists fit
    // a core's L2 (`table`'s 182 triangles) the prefetches only cost (1.5%).
    let large = std::mem::size_of_val(scene.triangles) + std::mem::size_of_val(scene.shading)
        > PREFETCH_ABOVE;
    let mut each = if large { lanes } else { 0 };
    while each != 0 {
        let i = each.trailing_zeros() as usize;
        each &= each - 1;
        let index = hits[i].prim as usize;
        if let (Some(tri), Some(shading)) = (scene.triangles.get(index), scene.shading.get(index)) {
            prefetch(std::slice::from_ref(tri));
            prefetch(std::slice::from_ref(shading));
        }
    }
    // The corners' materials are written after the loop: most packets
    // meet one material alone (a tile on one object), and then whole
    // registers take it instead of 21 stores a lane (one thread,
    // fastest of 11, four alternations: the 2M grid 154.8-156.9 ->
    // 150.1-154.8 ms, `table` 19.6-20.4 -> 18.8-19.1, the 22k grid
    // 49.7-50.0 -> 48.8-49.4). `test2`'s corners differ, and `table`'s
    // objects: both ways are in `tests/packets.rs`.
    let first = hits[lanes.trailing_zeros() as usize % WIDTH].prim as usize;
    let one = scene.shading.get(first).map_or(u32::MAX, |s| s[0].material);
    let mut uniform = true;
    let mut each = lanes;
    while each != 0 {
        let i = each.trailing_zeros() as usize;
        each &= each - 1;
        let index = hits[i].prim as usize;
        let tri = &scene.triangles[index];
        let shading = &scene.shading[index];
        for k in 0..3 {
            set_lane(&mut c.pos[k], i, tri[k]);
            set_lane(&mut c.normal[k], i, shading[k].normal);
            uniform &= shading[k].material == one;
        }
        c.b1.0[i] = hits[i].b1;
        c.b2.0[i] = hits[i].b2;
    }
    if uniform {
        let m = &scene.materials[one as usize];
        for k in 0..3 {
            for a in 0..3 {
                c.kd[k][a] = Lanes([m.kd[a]; WIDTH]);
                c.ks[k][a] = Lanes([m.ks[a]; WIDTH]);
            }
            c.shininess[k] = Lanes([m.shininess; WIDTH]);
        }
    } else {
        let mut each = lanes;
        while each != 0 {
            let i = each.trailing_zeros() as usize;
            each &= each - 1;
            // The record the loop above read, still in the cache.
            let shading = &scene.shading[hits[i].prim as usize];
            for (k, corner) in shading.iter().enumerate() {
                let m = &scene.materials[corner.material as usize];
                set_lane(&mut c.kd[k], i, m.kd);
                set_lane(&mut c.ks[k], i, m.ks);
                c.shininess[k].0[i] = m.shininess;
            }
        }
    }
    for i in 0..WIDTH {
        let (b1, b2) = (c.b1.0[i], c.b2.0[i]);
        let w = [1.0 - b1 - b2, b1, b2];
        let t = [at(&c.pos[0], i), at(&c.pos[1], i), at(&c.pos[2], i)];
        let (e1, e2) = (sub(t[1], t[0]), sub(t[2], t[0]));
        // glam's `Vec3::cross`, component by component.
        let cross = [
            e1[1] * e2[2] - e2[1] * e1[2],
            e1[2] * e2[0] - e2[2] * e1[0],
            e1[0] * e2[1] - e2[0] * e1[1],
        ];
        let ng = safe_normalize(cross, [0.0, 0.0, 1.0]);
        let n = safe_normalize(mix(&c.normal, w, i), ng);
        let (kd, ks) = (mix(&c.kd, w, i), mix(&c.ks, w, i));
        for a in 0..3 {
            let tw = [t[0][a] * w[0], t[1][a] * w[1], t[2][a] * w[2]];
            points.p[a].0[i] = tw[0] + tw[1] + tw[2];
            points.n[a].0[i] = n[a];
            points.ng[a].0[i] = ng[a];
            points.scale[a].0[i] = tw[0].abs() + tw[1].abs() + tw[2].abs();
            points.kd[a].0[i] = kd[a];
            points.ks[a].0[i] = ks[a];
        }
        points.shininess.0[i] =
            w[0] * c.shininess[0].0[i] + w[1] * c.shininess[1].0[i] + w[2] * c.shininess[2].0[i];
    }
}

/// Lane `i` of `v`. (Helpers on `[f32; 3]`, not `Vec3` or `map`: the
/// generic array `map` was left uninlined inside the AVX2 loops, which
/// then ran a lane at a time.)
#[inline(always)]
fn at(v: &V3s, i: usize) -> [f32; 3] {
    [v[0].0[i], v[1].0[i], v[2].0[i]]
}

#[inline(always)]
fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Lane `i` of the three corners' `v` weighted by `w`, left to right.
#[inline(always)]
fn mix(v: &[V3s; 3], w: [f32; 3], i: usize) -> [f32; 3] {
    let m = |a: usize| v[0][a].0[i] * w[0] + v[1][a].0[i] * w[1] + v[2][a].0[i] * w[2];
    [m(0), m(1), m(2)]
}

/// `trace::shadow_origin` (robust) of every lane towards `target`, and the
/// direction from it to `target`: the shadow rays of a point light, into
/// `origin` and `dir`.
#[inline(always)]
pub(super) fn shadow_rays(points: &Points, target: Vec3, origin: &mut V3s, dir: &mut V3s) {
    // The side of the surface the light is on.
    let mut side = ZEROS;
    for i in 0..WIDTH {
        let (p, ng) = (at(&points.p, i), at(&points.ng, i));
        let toward = dot(ng, sub(target.to_array(), p)) >= 0.0;
        for (a, side) in side.iter_mut().enumerate() {
            side.0[i] = if toward { ng[a] } else { -ng[a] };
        }
    }
    for a in 0..3 {
        offset_lanes(&points.p[a], &side[a], &points.scale[a], &mut origin[a]);
        for i in 0..WIDTH {
            dir[a].0[i] = target[a] - origin[a].0[i];
        }
    }
}

/// `Real::offset_ray` of one coordinate of every lane, four at a time
/// (`real::offset_sse2`).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn offset_lanes(p: &Lanes, n: &Lanes, scale: &Lanes, out: &mut Lanes) {
    use std::arch::x86_64::*;
    for q in 0..WIDTH / 4 {
        // SAFETY: `Lanes` is 64-byte aligned and holds `WIDTH` f32, a
        // multiple of four, as the aligned loads and stores at every
        // fourth one need.
        unsafe {
            let load = |l: &Lanes| _mm_load_ps(l.0.as_ptr().add(4 * q));
            let o = crate::cpu::real::offset_sse2(load(p), load(n), load(scale));
            _mm_store_ps(out.0.as_mut_ptr().add(4 * q), o);
        }
    }
}

/// `Real::offset_ray` of one coordinate of every lane, one at a time.
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn offset_lanes(p: &Lanes, n: &Lanes, scale: &Lanes, out: &mut Lanes) {
    for i in 0..WIDTH {
        out.0[i] = crate::cpu::real::offset_f32_scalar(p.0[i], n.0[i], scale.0[i]);
    }
}

/// How each point of a packet faces a point light: per lane L·N and
/// max(R·V, 0) (`trace::point_shading`'s `ln` and `rv`).
pub(super) struct Facing {
    ln: Lanes,
    rv: Lanes,
}

/// `Facing` of the points seen along `dir` towards a light at `target`.
#[inline(always)]
pub(super) fn facing(points: &Points, dir: &V3s, target: Vec3) -> Facing {
    let mut f = Facing {
        ln: Lanes::ZERO,
        rv: Lanes::ZERO,
    };
    for i in 0..WIDTH {
        let (p, n, dir) = (at(&points.p, i), at(&points.n, i), at(dir, i));
        let view = [-dir[0], -dir[1], -dir[2]];
        let l = safe_normalize(sub(target.to_array(), p), n);
        let d = dot(l, n);
        let r = [
            n[0] * (2.0 * d) - l[0],
            n[1] * (2.0 * d) - l[1],
            n[2] * (2.0 * d) - l[2],
        ];
        f.ln.0[i] = d;
        f.rv.0[i] = dot(r, view).max(0.0);
    }
    f
}

/// The lanes of `lit` whose highlight is 0 without asking `powf`: R·V
/// is 0 and the shininess is not (C's `pow` has 0^0 = 1).
#[inline(always)]
pub(super) fn no_highlight(f: &Facing, points: &Points, lit: u32) -> u32 {
    let mut dark = 0u32;
    for i in 0..WIDTH {
        let zero = f.rv.0[i] == 0.0 && points.shininess.0[i] != 0.0;
        dark |= u32::from(zero) << i;
    }
    dark & lit
}

/// Writes into `terms`, in the lanes of `on`, what an unblocked point
/// light of colour `color` gives each point (`trace::point_shading`'s
/// contribution, `powf` only for these lanes); the other lanes keep what
/// they held.
#[inline(always)]
pub(super) fn fill_terms(points: &Points, f: &Facing, on: u32, color: Vec3, terms: &mut V3s) {
    let mut spec = Lanes::ZERO;
    let mut each = on;
    while each != 0 {
        let i = each.trailing_zeros() as usize;
        each &= each - 1;
        spec.0[i] = pow_c(f.rv.0[i], points.shininess.0[i]);
    }
    for i in 0..WIDTH {
        let lane_on = on >> i & 1 != 0;
        let diffuse = f.ln.0[i].max(0.0);
        for (a, term) in terms.iter_mut().enumerate() {
            let t = color[a] * (points.kd[a].0[i] * diffuse + points.ks[a].0[i] * spec.0[i]);
            term.0[i] = if lane_on { t } else { term.0[i] };
        }
    }
}

/// The lanes of `lit` where adding `terms` changes `colour`'s bits in
/// some channel. In the others the sum is the same whether the light is
/// blocked or not (its term is 0, or too small to move the sum), so their
/// shadow rays need not be traced.
#[inline(always)]
pub(super) fn changed_by(colour: &V3s, terms: &V3s, lit: u32) -> u32 {
    let mut changed = 0u32;
    for i in 0..WIDTH {
        let mut moved = false;
        for a in 0..3 {
            let c = colour[a].0[i];
            moved |= (c + terms[a].0[i]).to_bits() != c.to_bits();
        }
        changed |= u32::from(moved) << i;
    }
    changed & lit
}

/// `Real::clamp01` of every lane: glam's `Vec3::clamp`, a max with 0 and
/// then a min with 1, each the select it is written as (so NaN and -0
/// fall as there), whole registers at a time.
#[inline(always)]
pub(super) fn clamp01(colour: &mut V3s) {
    for channel in colour {
        for x in &mut channel.0 {
            let above = if *x > 0.0 { *x } else { 0.0 };
            *x = if above < 1.0 { above } else { 1.0 };
        }
    }
}

/// Adds `terms` to `colour` in the lanes of `on`.
#[inline(always)]
pub(super) fn add_terms(colour: &mut V3s, terms: &V3s, on: u32) {
    for i in 0..WIDTH {
        let lane_on = on >> i & 1 != 0;
        for a in 0..3 {
            let sum = colour[a].0[i] + terms[a].0[i];
            colour[a].0[i] = if lane_on { sum } else { colour[a].0[i] };
        }
    }
}
