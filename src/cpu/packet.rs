//! Thirty-two rays through the wide tree together: the CPU reference's fast
//! path for a tile's primary rays and for their shadow rays towards each
//! point light. Neighbouring pixels' rays open mostly the same nodes, so
//! one pop, one child sort and one push serve them all, where a single ray
//! pays them alone; that bookkeeping, not the box arithmetic, was most of a
//! single ray's cost.
//!
//! Each ray's box tests are `wide::hit_boxes_f32`'s arithmetic lane for
//! lane (the rays, not the boxes, fill the SIMD lanes here), with the ray's
//! own nearest hit so far as its limit, and a leaf meets only the rays whose
//! own test reached it, tested exactly as a single ray's (`hit_leaf`). So
//! each ray gets a single ray's shadow verdict, and its closest hit but
//! where two surfaces meet it at the same t or within an ulp or two (as at
//! a mesh's vertices): the triangle test checks a candidate against the hit
//! found so far, so which of such near-equals is kept follows the order
//! leaves are opened in, here the packet's nearest ray's. That order is as
//! deterministic as the single ray's (tests/packets.rs bounds where and how
//! far the images differ).

use glam::{BVec4A, Vec3, Vec3A, Vec3Swizzles, Vec4};

use super::trace::{
    centre_key, count_ray, hit_leaf, hit_triangle, light_at, light_term, pow_c, ray_with_inverse,
    reflect_path, shadow_origin, surface_point, CpuScene, Hit, Ray, Sphere, SurfacePoint, NO_HIT,
};
use super::wide;
use super::Real;
use crate::layout::{LIGHT_POINT, SPHERE_BIT};
use crate::methods::Methods;

/// A node that at most this many of a packet's rays reach is walked by each
/// of them alone. Low in a big tree most packet visits carry one or two rays
/// (the 2M grid: 111,054 of the primary packets' 319,602 node visits), and
/// each paid the whole packet's pops, sorts and masks. Thread CPU time,
/// alternating, medians of 7, five rounds on a quiet machine: the 2M grid
/// 3-4% faster at 2 (1.5-3% at 3, 1-2.5% at 1), the other scenes within
/// 1%. (In stop 31, on the same machine in a noisy hour, it did not show.)
const HAND_OFF: u32 = 2;

/// Rays in a packet.
pub const WIDTH: usize = 32;

/// Fewer of an octet's rays than this meet a leaf block one by one: by
/// operation count the octet test (four triangles of about 45 operations)
/// costs what about three single rays' block tests do; 1 and 5 measured
/// level with 3 within this machine's noise.
const OCTET_MIN_RAYS: u32 = 3;

// A packet's rays are bits of a u32 mask, taken eight (AVX2) or sixteen
// (AVX-512) at a time.
const _: () = assert!(WIDTH <= 32 && WIDTH.is_multiple_of(16));

/// SSE vectors (quads of rays) in a packet.
const QUADS: usize = WIDTH / 4;

/// One f32 per ray of a packet, aligned for its loads in quads (SSE),
/// octets (AVX2) and sixteens (AVX-512).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Lanes([f32; WIDTH]);

impl Lanes {
    #[inline(always)]
    fn quad(&self, h: usize) -> Vec4 {
        Vec4::from_slice(&self.0[4 * h..4 * h + 4])
    }

    #[inline(always)]
    fn set_quad(&mut self, h: usize, v: Vec4) {
        v.write_to_slice(&mut self.0[4 * h..4 * h + 4]);
    }
}

/// A packet's rays by component.
struct Soa {
    o: [Lanes; 3],
    dir: [Lanes; 3],
    inv: [Lanes; 3],
    /// The rays' `shear`, for the triangle test.
    shear: [Lanes; 3],
    /// Per octet of rays, their axis order `k` where all eight share it
    /// (the octet's triangle tests can then run across its rays).
    k: [Option<[usize; 3]>; WIDTH / 8],
}

impl Soa {
    #[inline(always)]
    fn new(rays: &[Ray<f32>; WIDTH]) -> Self {
        let mut soa = Soa {
            o: [Lanes([0.0; WIDTH]); 3],
            dir: [Lanes([0.0; WIDTH]); 3],
            inv: [Lanes([0.0; WIDTH]); 3],
            shear: [Lanes([0.0; WIDTH]); 3],
            k: [None; WIDTH / 8],
        };
        for (r, ray) in rays.iter().enumerate() {
            for axis in 0..3 {
                soa.o[axis].0[r] = ray.origin[axis];
                soa.dir[axis].0[r] = ray.dir[axis];
                soa.inv[axis].0[r] = ray.inv_dir[axis];
                soa.shear[axis].0[r] = ray.shear[axis];
            }
        }
        for (g, k) in soa.k.iter_mut().enumerate() {
            let octet = &rays[8 * g..8 * g + 8];
            if octet.iter().all(|r| r.k == octet[0].k) {
                *k = Some(octet[0].k);
            }
        }
        soa
    }
}

/// `trace::hit_sphere` (robust, no grazing band, the sphere where it
/// stands) for every ray of a packet, four at a time: the same operations
/// in the same order per lane, `f32::min` and `max` included (a NaN root
/// gives way to the other), so each ray gets the scalar test's t to the
/// bit. Each ray's limit is its own `best_t`; a miss is `T_INF`.
#[inline(always)]
fn hit_sphere_rays(soa: &Soa, s: &Sphere<f32>, best_t: &Lanes) -> Lanes {
    let mut out = Lanes([f32::T_INF; WIDTH]);
    let rr = s.radius * s.radius;
    let dot = |a: [Vec4; 3], b: [Vec4; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let fmin = |a: Vec4, b: Vec4| {
        Vec4::select(
            a.is_nan_mask(),
            b,
            Vec4::select(b.is_nan_mask(), a, a.min(b)),
        )
    };
    let fmax = |a: Vec4, b: Vec4| {
        Vec4::select(
            a.is_nan_mask(),
            b,
            Vec4::select(b.is_nan_mask(), a, a.max(b)),
        )
    };
    for h in 0..QUADS {
        let d = [0, 1, 2].map(|axis| soa.dir[axis].quad(h));
        let f = [0, 1, 2].map(|axis| soa.o[axis].quad(h) - Vec4::splat(s.center[axis]));
        let a = dot(d, d);
        let b = -dot(f, d);
        let c = dot(f, f) - Vec4::splat(rr);
        let ba = b / a;
        let l = [0, 1, 2].map(|axis| f[axis] + d[axis] * ba);
        let disc = Vec4::splat(rr) - dot(l, l);
        let sign = Vec4::select(b.cmpge(Vec4::ZERO), Vec4::ONE, Vec4::NEG_ONE);
        let q = b + sign * (a * disc).sqrt();
        let miss = disc.cmplt(Vec4::ZERO);
        let t0 = Vec4::select(miss, Vec4::splat(f32::T_INF), c / q);
        let t1 = Vec4::select(miss, Vec4::splat(f32::T_INF), q / a);
        let (t_lo, t_hi) = (fmin(t0, t1), fmax(t0, t1));
        let t_max = best_t.quad(h);
        let zero = Vec4::ZERO;
        let lo_ok = t_lo.cmpgt(zero) & t_lo.cmplt(t_max);
        let hi_ok = t_hi.cmpgt(zero) & t_hi.cmplt(t_max);
        let t = Vec4::select(
            lo_ok,
            t_lo,
            Vec4::select(hi_ok, t_hi, Vec4::splat(f32::T_INF)),
        );
        out.set_quad(h, t);
    }
    out
}

/// A node's four children against a packet: per child lane, the rays
/// (of `mask`) whose box test it passes, their entry t, and the nearest of
/// those (the last two left at 0 and +inf in an any-hit traversal, which
/// does not need them). One per traversal, rewritten at each node (`reset`)
/// rather than made and returned per node: its 544 bytes were a `memset`
/// and a `memcpy` at every node visit (7% of the traversal's instructions
/// on the 22k grid, by callgrind).
struct Children {
    hits: [u32; 4],
    near: [Lanes; 4],
    nearest: [f32; 4],
}

impl Children {
    /// No ray in any box yet.
    const NONE: Children = Children {
        hits: [0; 4],
        near: [Lanes([0.0; WIDTH]); 4],
        nearest: [f32::INFINITY; 4],
    };

    /// No ray in any box, for the next node. `near` keeps what it held:
    /// only the entries of rays in `hits` are read, and a node's test
    /// writes those (a whole octet or quad of them wherever one ray hit).
    #[inline(always)]
    fn reset(&mut self) {
        self.hits = [0; 4];
        self.nearest = [f32::INFINITY; 4];
    }
}

/// `Children` with SSE (glam's `Vec4`), four rays at a time: each lane is
/// `wide::hit_boxes_f32`'s arithmetic for its ray, operation for operation.
#[inline(always)]
fn children_sse<const ANY_HIT: bool>(
    node: &wide::Node4,
    soa: &Soa,
    mask: u32,
    best_t: &Lanes,
    out: &mut Children,
) {
    let scale = Vec4::splat(f32::BOX_T_SCALE);
    out.reset();
    for lane in 0..4 {
        if node.child[lane] == wide::EMPTY {
            continue;
        }
        for h in 0..QUADS {
            let m = mask >> (4 * h) & 15;
            if m == 0 {
                continue;
            }
            let slab = |axis: usize| {
                let (o, inv) = (soa.o[axis].quad(h), soa.inv[axis].quad(h));
                let t0 = (Vec4::splat(node.lo[axis][lane]) - o) * inv;
                let t1 = (Vec4::splat(node.hi[axis][lane]) - o) * inv;
                (t0.min(t1), t0.max(t1))
            };
            let (nx, fx) = slab(0);
            let (ny, fy) = slab(1);
            let (nz, fz) = slab(2);
            let t_near = nx.max(ny).max(nz.max(Vec4::ZERO));
            let t_far = fx.min(fy).min(fz.min(best_t.quad(h))) * scale;
            let hit = t_near.cmple(t_far).bitmask() & m;
            if hit != 0 {
                out.hits[lane] |= hit << (4 * h);
                if !ANY_HIT {
                    out.near[lane].set_quad(h, t_near);
                    out.nearest[lane] = out.nearest[lane].min(
                        Vec4::select(LANES[hit as usize], t_near, Vec4::INFINITY).min_element(),
                    );
                }
            }
        }
    }
}

/// One child box (`lane` of `node`) against a register of rays (origins
/// `o`, inverse directions `inv`, limits `bt`), as `(t_near, t_far)`:
/// `children_sse`'s arithmetic, in the intrinsics of the register's width
/// (broadcast, sub, mul, min, max), for the AVX2 and AVX-512 tests alike.
/// A macro, not a function over the intrinsics, so that each expands inside
/// its caller's `target_feature` and inlines as written.
#[cfg(target_arch = "x86_64")]
macro_rules! box_entry_exit {
    ($node:expr, $lane:expr, $o:expr, $inv:expr, $bt:expr, $zero:expr, $scale:expr;
     $set1:ident, $sub:ident, $mul:ident, $min:ident, $max:ident) => {{
        let slab = |axis: usize| {
            let t0 = $mul($sub($set1($node.lo[axis][$lane]), $o[axis]), $inv[axis]);
            let t1 = $mul($sub($set1($node.hi[axis][$lane]), $o[axis]), $inv[axis]);
            ($min(t0, t1), $max(t0, t1))
        };
        let (nx, fx) = slab(0);
        let (ny, fy) = slab(1);
        let (nz, fz) = slab(2);
        let t_near = $max($max(nx, ny), $max(nz, $zero));
        let t_far = $mul($min($min(fx, fy), $min(fz, $bt)), $scale);
        (t_near, t_far)
    }};
}

/// `children_sse` with AVX2, eight rays at a time: the same operations
/// lane for lane (`_mm256_min_ps` and `_mm256_max_ps` take their operands
/// in `Vec4::min`'s and `max`'s order, so NaNs fall the same way; `<=` is
/// the same ordered compare), so each ray gets the same answer to the bit.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn children_avx2<const ANY_HIT: bool>(
    node: &wide::Node4,
    soa: &Soa,
    mask: u32,
    best_t: &Lanes,
    out: &mut Children,
) {
    use std::arch::x86_64::*;
    out.reset();
    // SAFETY: `Lanes` is 64-byte aligned (32 would do here) and holds
    // `WIDTH` f32, a multiple of eight, as the aligned loads and stores at
    // every eighth one need; the rest is arithmetic on registers.
    unsafe {
        let scale = _mm256_set1_ps(f32::BOX_T_SCALE);
        let zero = _mm256_setzero_ps();
        let inf = _mm256_set1_ps(f32::INFINITY);
        let bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        for g in 0..WIDTH / 8 {
            let m8 = mask >> (8 * g) & 255;
            if m8 == 0 {
                continue;
            }
            let load = |l: &Lanes| _mm256_load_ps(l.0.as_ptr().add(8 * g));
            let o = [load(&soa.o[0]), load(&soa.o[1]), load(&soa.o[2])];
            let inv = [load(&soa.inv[0]), load(&soa.inv[1]), load(&soa.inv[2])];
            let bt = load(best_t);
            for lane in 0..4 {
                if node.child[lane] == wide::EMPTY {
                    continue;
                }
                let (t_near, t_far) = box_entry_exit!(
                    node, lane, o, inv, bt, zero, scale;
                    _mm256_set1_ps, _mm256_sub_ps, _mm256_mul_ps, _mm256_min_ps, _mm256_max_ps
                );
                let passed = _mm256_cmp_ps::<_CMP_LE_OS>(t_near, t_far);
                let hit = _mm256_movemask_ps(passed) as u32 & m8;
                if hit == 0 {
                    continue;
                }
                out.hits[lane] |= hit << (8 * g);
                if !ANY_HIT {
                    _mm256_store_ps(out.near[lane].0.as_mut_ptr().add(8 * g), t_near);
                    // The nearest entry among the rays that hit: the others
                    // at +inf, then a min across the lanes.
                    let chosen = _mm256_cmpeq_epi32(
                        _mm256_and_si256(_mm256_set1_epi32(hit as i32), bits),
                        bits,
                    );
                    let t = _mm256_blendv_ps(inf, t_near, _mm256_castsi256_ps(chosen));
                    let m = _mm_min_ps(_mm256_castps256_ps128(t), _mm256_extractf128_ps::<1>(t));
                    let m = _mm_min_ps(m, _mm_movehl_ps(m, m));
                    let m = _mm_min_ss(m, _mm_shuffle_ps::<1>(m, m));
                    out.nearest[lane] = out.nearest[lane].min(_mm_cvtss_f32(m));
                }
            }
        }
    }
}

/// `children_sse` with AVX-512, sixteen rays at a time: the same
/// operations lane for lane as `children_avx2` (`vminps` and `vmaxps` treat
/// NaNs alike at every width, and `<=` is the same ordered compare, here
/// into a mask register), so each ray gets the same answer to the bit. The
/// nearest entry is a masked reduction over rays that passed, whose entries
/// are never NaN, so its order does not matter.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
fn children_avx512<const ANY_HIT: bool>(
    node: &wide::Node4,
    soa: &Soa,
    mask: u32,
    best_t: &Lanes,
    out: &mut Children,
) {
    use std::arch::x86_64::*;
    out.reset();
    // SAFETY: `Lanes` is 64-byte aligned and holds `WIDTH` f32, a multiple
    // of sixteen, as the aligned loads and stores at every sixteenth one
    // need; the rest is arithmetic on registers.
    unsafe {
        let scale = _mm512_set1_ps(f32::BOX_T_SCALE);
        let zero = _mm512_setzero_ps();
        for g in 0..WIDTH / 16 {
            let m16 = (mask >> (16 * g) & 0xffff) as u16;
            if m16 == 0 {
                continue;
            }
            let load = |l: &Lanes| _mm512_load_ps(l.0.as_ptr().add(16 * g));
            let o = [load(&soa.o[0]), load(&soa.o[1]), load(&soa.o[2])];
            let inv = [load(&soa.inv[0]), load(&soa.inv[1]), load(&soa.inv[2])];
            let bt = load(best_t);
            for lane in 0..4 {
                if node.child[lane] == wide::EMPTY {
                    continue;
                }
                let (t_near, t_far) = box_entry_exit!(
                    node, lane, o, inv, bt, zero, scale;
                    _mm512_set1_ps, _mm512_sub_ps, _mm512_mul_ps, _mm512_min_ps, _mm512_max_ps
                );
                let hit = _mm512_mask_cmp_ps_mask::<_CMP_LE_OS>(m16, t_near, t_far);
                if hit == 0 {
                    continue;
                }
                out.hits[lane] |= (hit as u32) << (16 * g);
                if !ANY_HIT {
                    _mm512_store_ps(out.near[lane].0.as_mut_ptr().add(16 * g), t_near);
                    let m = _mm512_mask_reduce_min_ps(hit, t_near);
                    out.nearest[lane] = out.nearest[lane].min(m);
                }
            }
        }
    }
}

/// A leaf block's triangles against the rays of octet `g` in `m8` that
/// share the axis order `k`, eight rays at a time with AVX2: per ray
/// `wide::hit_block_f32`'s operations in its order on the same values (the
/// vertices broadcast where it loads them four triangles wide; ordered
/// compares as `cmplt` and `cmpgt`, unordered as `cmpne`), each triangle
/// against the ray's limit at the block's start, and its hit kept, as
/// there, only when nearer than the block's hits before it. So each ray
/// gets `hit_block_f32`'s answer to the bit. Writes the rays' new hits
/// and returns the bits of the rays that found one.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn hit_block_octet(
    block: &wide::LeafBlock,
    soa: &Soa,
    k: [usize; 3],
    g: usize,
    m8: u32,
    best: &mut [Hit<f32>; WIDTH],
    best_t: &mut Lanes,
) -> u32 {
    use std::arch::x86_64::*;
    let [kx, ky, kz] = k;
    // The octet's nearest hits, lane i for ray 8g + i.
    let mut t_out = [0.0f32; 8];
    let mut b1_out = [0.0f32; 8];
    let mut b2_out = [0.0f32; 8];
    let mut which = [0i32; 8];
    // SAFETY: `Lanes` is 64-byte aligned (32 would do here) and holds
    // `WIDTH` f32, a multiple of eight, as the aligned loads at every
    // eighth one need; the outputs are eight lanes each, written
    // unaligned; the rest is arithmetic on registers.
    let found = unsafe {
        let load = |l: &Lanes| _mm256_load_ps(l.0.as_ptr().add(8 * g));
        let (ox, oy, oz) = (load(&soa.o[kx]), load(&soa.o[ky]), load(&soa.o[kz]));
        let (s0, s1, s2) = (
            load(&soa.shear[0]),
            load(&soa.shear[1]),
            load(&soa.shear[2]),
        );
        let t_max = load(best_t);
        let zero = _mm256_setzero_ps();
        let one = _mm256_set1_ps(1.0);
        let mut run_t = t_max;
        let mut run_b1 = zero;
        let mut run_b2 = zero;
        let mut run_k = _mm256_set1_epi32(-1);
        let lanes = block.lanes();
        for j in 0..4 {
            if lanes & 1 << j == 0 {
                continue;
            }
            let p = |axis: usize, corner: usize| _mm256_set1_ps(block.p[axis][corner][j]);
            let a_z = _mm256_sub_ps(p(kz, 0), oz);
            let b_z = _mm256_sub_ps(p(kz, 1), oz);
            let c_z = _mm256_sub_ps(p(kz, 2), oz);
            let ax = _mm256_sub_ps(_mm256_sub_ps(p(kx, 0), ox), _mm256_mul_ps(s0, a_z));
            let ay = _mm256_sub_ps(_mm256_sub_ps(p(ky, 0), oy), _mm256_mul_ps(s1, a_z));
            let bx = _mm256_sub_ps(_mm256_sub_ps(p(kx, 1), ox), _mm256_mul_ps(s0, b_z));
            let by = _mm256_sub_ps(_mm256_sub_ps(p(ky, 1), oy), _mm256_mul_ps(s1, b_z));
            let cx = _mm256_sub_ps(_mm256_sub_ps(p(kx, 2), ox), _mm256_mul_ps(s0, c_z));
            let cy = _mm256_sub_ps(_mm256_sub_ps(p(ky, 2), oy), _mm256_mul_ps(s1, c_z));
            let u = _mm256_sub_ps(_mm256_mul_ps(cx, by), _mm256_mul_ps(cy, bx));
            let v = _mm256_sub_ps(_mm256_mul_ps(ax, cy), _mm256_mul_ps(ay, cx));
            let w = _mm256_sub_ps(_mm256_mul_ps(bx, ay), _mm256_mul_ps(by, ax));
            let lt = |a, b| _mm256_cmp_ps::<_CMP_LT_OS>(a, b);
            let gt = |a, b| _mm256_cmp_ps::<_CMP_GT_OS>(a, b);
            let or = |a, b| _mm256_or_ps(a, b);
            let and = |a, b| _mm256_and_ps(a, b);
            let some_negative = or(or(lt(u, zero), lt(v, zero)), lt(w, zero));
            let some_positive = or(or(gt(u, zero), gt(v, zero)), gt(w, zero));
            let det = _mm256_add_ps(_mm256_add_ps(u, v), w);
            let t_scaled = _mm256_add_ps(
                _mm256_add_ps(
                    _mm256_mul_ps(u, _mm256_mul_ps(s2, a_z)),
                    _mm256_mul_ps(v, _mm256_mul_ps(s2, b_z)),
                ),
                _mm256_mul_ps(w, _mm256_mul_ps(s2, c_z)),
            );
            let end = _mm256_mul_ps(t_max, det);
            let positive = and(gt(t_scaled, zero), lt(t_scaled, end));
            let negative = and(lt(t_scaled, zero), gt(t_scaled, end));
            let det_positive = gt(det, zero);
            let inside = or(
                and(det_positive, positive),
                _mm256_andnot_ps(det_positive, negative),
            );
            let hit = _mm256_andnot_ps(
                and(some_negative, some_positive),
                and(_mm256_cmp_ps::<_CMP_NEQ_UQ>(det, zero), inside),
            );
            if _mm256_movemask_ps(hit) as u32 & m8 == 0 {
                continue;
            }
            let inv_det = _mm256_div_ps(one, det);
            let t = _mm256_mul_ps(t_scaled, inv_det);
            let keep = and(hit, lt(t, run_t));
            run_t = _mm256_blendv_ps(run_t, t, keep);
            run_b1 = _mm256_blendv_ps(run_b1, _mm256_mul_ps(v, inv_det), keep);
            run_b2 = _mm256_blendv_ps(run_b2, _mm256_mul_ps(w, inv_det), keep);
            run_k = _mm256_blendv_epi8(
                run_k,
                _mm256_set1_epi32(j as i32),
                _mm256_castps_si256(keep),
            );
        }
        let found = !(_mm256_movemask_ps(_mm256_castsi256_ps(run_k)) as u32) & m8;
        if found != 0 {
            _mm256_storeu_ps(t_out.as_mut_ptr(), run_t);
            _mm256_storeu_ps(b1_out.as_mut_ptr(), run_b1);
            _mm256_storeu_ps(b2_out.as_mut_ptr(), run_b2);
            _mm256_storeu_si256(which.as_mut_ptr().cast(), run_k);
        }
        found
    };
    let mut each = found;
    while each != 0 {
        let i = each.trailing_zeros() as usize;
        each &= each - 1;
        let r = 8 * g + i;
        best[r] = Hit {
            t: t_out[i],
            prim: block.prims[which[i] as usize],
            b1: b1_out[i],
            b2: b2_out[i],
        };
        best_t.0[r] = t_out[i];
    }
    found << (8 * g)
}

/// The lanes of a 4-bit mask, for selects.
const LANES: [BVec4A; 16] = {
    let mut out = [BVec4A::FALSE; 16];
    let mut m = 0;
    while m < 16 {
        out[m] = BVec4A::new(m & 1 != 0, m & 2 != 0, m & 4 != 0, m & 8 != 0);
        m += 1;
    }
    out
};

/// A node to open: its index, the rays whose box test reached it, and the
/// nearest of their entry t.
type Entry = (u32, u32, f32);

/// What a traversal is asked: the closest hit (or, in an any-hit
/// traversal, a blocker) before `t_max` of each ray whose bit is set in
/// `active`.
#[derive(Clone, Copy)]
struct Query<'a> {
    rays: &'a [Ray<f32>; WIDTH],
    active: u32,
    t_max: f32,
}

/// The closest hit (`any_hit`: a blocker) before `t_max` of each ray whose
/// bit is set in `active`; the other rays' hits say `NO_HIT`. As
/// `trace::traverse` with no surfaces to skip and no grazing band. Tests a
/// node's boxes eight rays at a time where the CPU has AVX2, else four.
pub fn traverse(
    scene: &CpuScene<f32>,
    rays: &[Ray<f32>; WIDTH],
    active: u32,
    t_max: f32,
    any_hit: bool,
) -> [Hit<f32>; WIDTH] {
    let query = Query {
        rays,
        active,
        t_max,
    };
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU has AVX-512F (and so AVX2), checked just above.
        return unsafe {
            if any_hit {
                traverse_avx512::<true>(scene, query)
            } else {
                traverse_avx512::<false>(scene, query)
            }
        };
    }
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above.
        return unsafe {
            if any_hit {
                traverse_avx2::<true>(scene, query)
            } else {
                traverse_avx2::<false>(scene, query)
            }
        };
    }
    if any_hit {
        traverse_with::<SSE, true>(scene, query)
    } else {
        traverse_with::<SSE, false>(scene, query)
    }
}

/// `traverse_with`'s instruction sets, least first.
const SSE: u8 = 0;
const AVX2: u8 = 1;
const AVX512: u8 = 2;

/// `traverse_with` compiled for AVX2, so its box tests inline.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn traverse_avx2<const ANY_HIT: bool>(scene: &CpuScene<f32>, query: Query) -> [Hit<f32>; WIDTH] {
    traverse_with::<AVX2, ANY_HIT>(scene, query)
}

/// `traverse_with` compiled for AVX-512: its box tests take sixteen rays a
/// register, its leaf tests stay AVX2's octets.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn traverse_avx512<const ANY_HIT: bool>(scene: &CpuScene<f32>, query: Query) -> [Hit<f32>; WIDTH] {
    traverse_with::<AVX512, ANY_HIT>(scene, query)
}

/// `traverse`, its box tests 8 rays at a time with AVX2 when `SIMD` is
/// `AVX2` and 16 with AVX-512 when it is `AVX512` (only ever so inside
/// `traverse_avx2` and `traverse_avx512`), for blockers when `ANY_HIT`.
///
/// An any-hit ray's limit stays `t_max` until it is blocked and leaves, so
/// no box it passed can later lie beyond its limit, and whether it is
/// blocked does not depend on the order it meets leaves in: there the
/// entry t that order and dropping need is not computed.
#[inline(always)]
fn traverse_with<const SIMD: u8, const ANY_HIT: bool>(
    scene: &CpuScene<f32>,
    query: Query,
) -> [Hit<f32>; WIDTH] {
    let Query {
        rays,
        active,
        t_max,
    } = query;
    let mut best = [Hit {
        t: t_max,
        prim: NO_HIT,
        b1: 0.0,
        b2: 0.0,
    }; WIDTH];
    if scene.wide.nodes.is_empty() || active == 0 {
        return best;
    }
    let soa = Soa::new(rays);
    // Where `hit_leaf` tests a leaf's triangles as one SIMD block (a packet
    // never skips surfaces); with `applies`, always.
    let simd_leaves = scene.methods == Methods::Robust && !scene.motion_blur;
    let mut best_t = Lanes([t_max; WIDTH]);
    let scale = Vec4::splat(f32::BOX_T_SCALE);
    // Rays still looking: an any-hit ray leaves once blocked.
    let mut live = active;
    // Uninitialised, as `trace::traverse`'s: clearing it per packet showed
    // in profiles.
    let mut stack = [std::mem::MaybeUninit::<Entry>::uninit(); wide::STACK];
    stack[0] = std::mem::MaybeUninit::new((0, active, 0.0));
    let mut len = 1;
    let mut kids = Children::NONE;
    while len > 0 {
        len -= 1;
        // SAFETY: stack[..len + 1] were all written before `len` grew past them.
        let (index, entered, t_entry) = unsafe { stack[len].assume_init() };
        let mask = entered & live;
        if mask == 0 {
            continue;
        }
        // Dropped unopened when no ray that entered it could find a hit
        // nearer than its entry any more (the box test they would fail).
        if !ANY_HIT {
            let farthest = (0..QUADS)
                .map(|h| {
                    Vec4::select(
                        LANES[(mask >> (4 * h) & 15) as usize],
                        best_t.quad(h),
                        Vec4::NEG_INFINITY,
                    )
                    .max_element()
                })
                .fold(f32::NEG_INFINITY, f32::max);
            if t_entry > farthest * f32::BOX_T_SCALE {
                continue;
            }
        }
        // Few rays left: each walks the subtree alone (`trace::traverse`'s
        // walk from this node, its own hit so far as its limit), without
        // the packet's bookkeeping.
        if mask.count_ones() <= HAND_OFF {
            let mut each = mask;
            while each != 0 {
                let r = each.trailing_zeros() as usize;
                each &= each - 1;
                super::trace::traverse_below(scene, &rays[r], index, &mut best[r], ANY_HIT);
                best_t.0[r] = best[r].t;
                if ANY_HIT && best[r].prim != NO_HIT {
                    live &= !(1 << r);
                }
            }
            if live == 0 {
                return best;
            }
            continue;
        }
        let node = &scene.wide.nodes[index as usize];
        #[cfg(target_arch = "x86_64")]
        // SAFETY: SIMD is AVX512 only in `traverse_avx512`, which runs only
        // where the CPU has AVX-512F, and AVX2 only in `traverse_avx2`,
        // which runs only where it has AVX2.
        if SIMD == AVX512 {
            unsafe { children_avx512::<ANY_HIT>(node, &soa, mask, &best_t, &mut kids) }
        } else if SIMD == AVX2 {
            unsafe { children_avx2::<ANY_HIT>(node, &soa, mask, &best_t, &mut kids) }
        } else {
            children_sse::<ANY_HIT>(node, &soa, mask, &best_t, &mut kids)
        };
        #[cfg(not(target_arch = "x86_64"))]
        children_sse::<ANY_HIT>(node, &soa, mask, &best_t, &mut kids);
        let Children {
            hits,
            ref near,
            nearest,
        } = kids;
        // Hit lanes nearest first (by their nearest ray, then lane; in
        // lane order for any-hit rays, whose entries are not computed).
        let mut order = [0usize; 4];
        let mut n = 0;
        for lane in 0..4 {
            if hits[lane] == 0 {
                continue;
            }
            let mut i = n;
            while i > 0 && nearest[order[i - 1]] > nearest[lane] {
                order[i] = order[i - 1];
                i -= 1;
            }
            order[i] = lane;
            n += 1;
        }
        // Nodes onto the stack first, farthest first, so the nearest is
        // next, and each starts loading with its own leaf blocks: the next
        // node arrives while this one's leaves are tested, and its leaves
        // with it (this node's were started when it was pushed). The
        // leaves cannot see the stack, so the order of work is as if they
        // came first.
        for &lane in order[..n].iter().rev() {
            let child = node.child[lane];
            if child & wide::LEAF == 0 {
                // Indexed with a bounds check: `wide::STACK` bounds the depth.
                stack[len] = std::mem::MaybeUninit::new((child, hits[lane], nearest[lane]));
                len += 1;
                prefetch(std::slice::from_ref(&scene.wide.nodes[child as usize]));
                prefetch(&scene.wide.leaves[node.leaf_run(lane)]);
            }
        }
        // Leaves are tested as they come, nearest first.
        for &lane in &order[..n] {
            let child = node.child[lane];
            if child & wide::LEAF == 0 {
                continue;
            }
            let index = (child & !wide::LEAF) as usize;
            let leaf = &scene.wide.leaves[index];
            // The rays that reached it and have not found a hit nearer than
            // their entry since.
            let mut rays_in = hits[lane] & live;
            if !ANY_HIT {
                for h in 0..QUADS {
                    let late = near[lane].quad(h).cmpgt(best_t.quad(h) * scale).bitmask();
                    rays_in &= !(late << (4 * h));
                }
            }
            if !simd_leaves {
                // As a single ray's, one ray at a time.
                while rays_in != 0 {
                    let r = rays_in.trailing_zeros() as usize;
                    rays_in &= rays_in - 1;
                    let done = hit_leaf(scene, &rays[r], index, &mut best[r], ANY_HIT, &[], 0.0);
                    best_t.0[r] = best[r].t;
                    if done {
                        live &= !(1 << r);
                    }
                }
            } else if leaf.simd() {
                // `hit_leaf`'s own first branch, inlined here: across an
                // octet's rays where they share an axis order and enough
                // of them came, else ray by ray.
                #[cfg(target_arch = "x86_64")]
                if SIMD >= AVX2 {
                    for (g, k) in soa.k.iter().enumerate() {
                        let m8 = rays_in >> (8 * g) & 255;
                        let Some(k) = *k else { continue };
                        if m8.count_ones() < OCTET_MIN_RAYS {
                            continue;
                        }
                        rays_in &= !(m8 << (8 * g));
                        // SAFETY: SIMD is AVX2 or more only in
                        // `traverse_avx2` and `traverse_avx512`, which run
                        // only where the CPU has AVX2 (AVX-512F implies it).
                        let found = unsafe {
                            hit_block_octet(leaf, &soa, k, g, m8, &mut best, &mut best_t)
                        };
                        if ANY_HIT {
                            live &= !found;
                        }
                    }
                }
                while rays_in != 0 {
                    let r = rays_in.trailing_zeros() as usize;
                    rays_in &= rays_in - 1;
                    if let Some((k, t, b1, b2)) = wide::hit_block_f32(&rays[r], leaf, best[r].t) {
                        let prim = leaf.prims[k];
                        best[r] = Hit { t, prim, b1, b2 };
                        best_t.0[r] = t;
                        if ANY_HIT {
                            live &= !(1 << r);
                        }
                    }
                }
            } else {
                // `hit_leaf`'s loop over the primitives, robust, taken
                // primitive by primitive for all the rays (each ray still
                // meets them in order): spheres four rays at a time.
                for &prim in &scene.prim_refs[scene.wide.spans[index].range()] {
                    if rays_in == 0 {
                        break;
                    }
                    let index = (prim & !SPHERE_BIT) as usize;
                    if prim & SPHERE_BIT != 0 {
                        let t = hit_sphere_rays(&soa, &scene.spheres[index], &best_t);
                        let mut hit = rays_in;
                        while hit != 0 {
                            let r = hit.trailing_zeros() as usize;
                            hit &= hit - 1;
                            if t.0[r] < best[r].t {
                                best[r] = Hit {
                                    t: t.0[r],
                                    prim,
                                    b1: 0.0,
                                    b2: 0.0,
                                };
                                best_t.0[r] = t.0[r];
                                if ANY_HIT {
                                    live &= !(1 << r);
                                    rays_in &= !(1 << r);
                                }
                            }
                        }
                    } else {
                        let tri = &scene.triangles[index];
                        let mut each = rays_in;
                        while each != 0 {
                            let r = each.trailing_zeros() as usize;
                            each &= each - 1;
                            let (t, b1, b2) = hit_triangle(&rays[r], tri, best[r].t);
                            if t < best[r].t {
                                best[r] = Hit { t, prim, b1, b2 };
                                best_t.0[r] = t;
                                if ANY_HIT {
                                    live &= !(1 << r);
                                    rays_in &= !(1 << r);
                                }
                            }
                        }
                    }
                }
            }
            if live == 0 {
                return best;
            }
        }
    }
    best
}

/// Starts loading what will be read soon: every cache line `items` (side
/// by side in memory) touch, with a counted loop over the lines (a
/// `step_by` per item took a twentieth of the traversal's instructions on
/// the 240k grid, by cachegrind).
#[inline(always)]
fn prefetch<T>(items: &[T]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let range = items.as_ptr_range();
        // From the line holding the first byte to the one holding the
        // last: an item need not start on a line.
        let mut line = range.start as usize & !63;
        while line < range.end as usize {
            // SAFETY: prefetching has no effect on memory, and never faults.
            unsafe { _mm_prefetch(line as *const i8, _MM_HINT_T0) };
            line += 64;
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = items;
}

/// `trace::make_ray` (at time 0) for a packet's rays, their divisions four
/// rays at a time: per lane the same operations on the same values, so
/// each ray is `make_ray`'s to the bit.
#[inline(always)]
fn make_rays(origins: &[Vec3; WIDTH], dirs: &[Vec3; WIDTH]) -> [Ray<f32>; WIDTH] {
    let mut inv = [Lanes([0.0; WIDTH]); 3];
    for (axis, inv) in inv.iter_mut().enumerate() {
        for h in 0..QUADS {
            let d = Vec4::from_array(std::array::from_fn(|i| dirs[4 * h + i][axis]));
            // `trace::safe_dir`, lane by lane.
            let sign = Vec4::select(d.cmpge(Vec4::ZERO), Vec4::ONE, Vec4::NEG_ONE);
            let tiny = d.abs().cmplt(Vec4::splat(f32::MIN_DIR));
            let safe = Vec4::select(tiny, sign * Vec4::splat(f32::MIN_DIR), d);
            inv.set_quad(h, Vec4::ONE / safe);
        }
    }
    std::array::from_fn(|i| {
        let inv_dir = Vec3::new(inv[0].0[i], inv[1].0[i], inv[2].0[i]);
        ray_with_inverse(origins[i], dirs[i], inv_dir, 0.0)
    })
}

/// `trace::pixel_ray` for each of `pixels`, four at a time: the same
/// operations in the same order per lane (`camera_ray`'s, the
/// normalisation's, `make_ray`'s), so each ray is `pixel_ray`'s to the bit.
fn pixel_rays(scene: &CpuScene<f32>, pixels: &[[u32; 2]; WIDTH]) -> [Ray<f32>; WIDTH] {
    let (w, h) = (scene.size[0] as f32, scene.size[1] as f32);
    let [hx, hy] = scene.half_extent;
    let mut dirs = [Vec3::ZERO; WIDTH];
    for q in 0..QUADS {
        let x = Vec4::from_array(std::array::from_fn(|i| pixels[4 * q + i][0] as f32));
        let y = Vec4::from_array(std::array::from_fn(|i| pixels[4 * q + i][1] as f32));
        let two = Vec4::splat(2.0);
        let ndc_x = (two * (x + Vec4::splat(0.5)) / Vec4::splat(w) - Vec4::ONE) * Vec4::splat(hx);
        let ndc_y = (Vec4::ONE - two * (y + Vec4::splat(0.5)) / Vec4::splat(h)) * Vec4::splat(hy);
        // `Real::normalize` of (x, y, -1): its dot product, left to right.
        let len2 = ndc_x * ndc_x + ndc_y * ndc_y + Vec4::ONE;
        let s = Vec4::ONE / len2.sqrt();
        let (dx, dy, dz) = (ndc_x * s, ndc_y * s, Vec4::NEG_ONE * s);
        for i in 0..4 {
            dirs[4 * q + i] = Vec3::new(dx[i], dy[i], dz[i]);
        }
    }
    make_rays(&[Vec3::ZERO; WIDTH], &dirs)
}

/// Whether a render of `scene` may take its pixels in packets: one sample
/// a pixel, at its centre, with nothing moving, so every primary ray
/// starts at the same time from the camera; and the robust methods, whose
/// tests never find a hit outside its leaf's box, so that which hit a ray
/// keeps cannot depend on the order leaves are opened in beyond near-ties
/// (the naive test can, and its renders show the single ray's order).
pub fn applies(scene: &CpuScene<f32>) -> bool {
    scene.spp <= 1 && !scene.motion_blur && scene.methods == Methods::Robust
}

/// A packet's pixels: a block `TILE[0]` wide and `TILE[1]` high, whose
/// rays stay closer together than a row's. Measured against 4 x 4 tiles of
/// sixteen rays and 8 x 4 ones: taller tiles were faster, most on the big
/// grids.
pub const TILE: [u32; 2] = [4, 8];

// A tile's pixels fit one packet (`fill_band` gathers them into one).
const _: () = assert!(TILE[0] * TILE[1] <= WIDTH as u32);

/// Fills a band of `TILE[1]` rows (fewer for the last) from row `y0`, each
/// `TILE`-sized tile's pixels that `keep` says as one packet (`colours`),
/// the others left as they are.
pub fn fill_band(
    scene: &CpuScene<f32>,
    y0: u32,
    band: &mut [[f32; 3]],
    keep: &(dyn Fn(u32, u32) -> bool + Sync),
) {
    let [tw, _] = TILE;
    let w = scene.size[0];
    let rows = band.len() as u32 / w.max(1);
    for x0 in (0..w).step_by(tw as usize) {
        let mut pixels = [[0u32; 2]; WIDTH];
        let mut n = 0;
        for y in y0..y0 + rows {
            for x in x0..(x0 + tw).min(w) {
                if keep(x, y) {
                    pixels[n] = [x, y];
                    n += 1;
                }
            }
        }
        for (&[x, y], c) in pixels[..n].iter().zip(colours(scene, &pixels[..n])) {
            band[((y - y0) * w + x) as usize] = c;
        }
    }
}

/// `trace::safe_normalize` in an SSE register: the dot product left to
/// right, as glam's `Vec3A::dot` adds it, so the same bits.
#[inline(always)]
fn safe_normalize_a(v: Vec3A, fallback: Vec3A) -> Vec3A {
    let len2 = v.dot(v);
    if len2 > 0.0 {
        v * (1.0 / len2.sqrt())
    } else {
        fallback
    }
}

/// `trace::surface_point` for the packets' f32 scene, a triangle's vectors
/// in SSE registers (glam's `Vec3A`) instead of three scalars each: per
/// lane the same operations in the same order on the same values, only
/// multiplies, adds, subtracts and sign clears (whose results do not depend
/// on the width, where `min` and `max` would differ on NaN), so the same
/// bits (tested). Spheres, motion and the naive methods take the generic
/// path. On the 240k grid (cachegrind) the generic one took 300
/// instructions a hit, a tenth of the render.
#[inline(always)]
fn surface_point_f32(scene: &CpuScene<f32>, ray: &Ray<f32>, hit: &Hit<f32>) -> SurfacePoint<f32> {
    if hit.prim & SPHERE_BIT != 0 || scene.motion_blur || scene.methods != Methods::Robust {
        return surface_point(scene, ray, hit);
    }
    let index = hit.prim as usize;
    let tri = scene.triangles[index].map(Vec3A::from);
    let w = [1.0 - hit.b1 - hit.b2, hit.b1, hit.b2];
    let tw = [tri[0] * w[0], tri[1] * w[1], tri[2] * w[2]];
    // `Real::cross` (glam's scalar one), written out so that no fused
    // multiply-subtract can enter where the target has FMA.
    let cross = |a: Vec3A, b: Vec3A| (a.zxy() * b - a * b.zxy()).zxy();
    let ng = safe_normalize_a(cross(tri[1] - tri[0], tri[2] - tri[0]), Vec3A::Z);
    let s = &scene.shading[index];
    let n = safe_normalize_a(
        Vec3A::from(s[0].normal) * w[0]
            + Vec3A::from(s[1].normal) * w[1]
            + Vec3A::from(s[2].normal) * w[2],
        ng,
    );
    let m = s.map(|c| &scene.materials[c.material as usize]);
    let mix = |f: fn(&super::trace::SurfaceMaterial<f32>) -> Vec3| {
        Vec3A::from(f(m[0])) * w[0] + Vec3A::from(f(m[1])) * w[1] + Vec3A::from(f(m[2])) * w[2]
    };
    SurfacePoint {
        p: (tw[0] + tw[1] + tw[2]).into(),
        n: n.into(),
        ng: ng.into(),
        scale: (tw[0].abs() + tw[1].abs() + tw[2].abs()).into(),
        kd: mix(|m| m.kd).into(),
        ks: mix(|m| m.ks).into(),
        shininess: w[0] * m[0].shininess + w[1] * m[1].shininess + w[2] * m[2].shininess,
    }
}

/// What an unblocked point light adds at `sp` (`trace::point_shading`'s
/// contribution), in SSE registers as `surface_point_f32` computes: the
/// same bits (tested).
#[inline(always)]
fn point_contribution_f32(sp: &SurfacePoint<f32>, view: Vec3, target: Vec3, color: Vec3) -> Vec3A {
    let n = Vec3A::from(sp.n);
    let l = safe_normalize_a(Vec3A::from(target) - Vec3A::from(sp.p), n);
    let ln = l.dot(n);
    let r = n * (2.0 * ln) - l;
    // Scalar `max`, as there: a NaN gives 0.
    let rv = r.dot(Vec3A::from(view)).max(0.0);
    let spec = pow_c(rv, sp.shininess);
    Vec3A::from(color) * (Vec3A::from(sp.kd) * ln.max(0.0) + Vec3A::from(sp.ks) * spec)
}

/// The colours `pixel_color` gives `pixels` (up to `WIDTH`), clamped: the
/// primary rays as a packet, then per point light the shadow rays of the
/// pixels that hit something; area lights, lights on surfaces and
/// reflections one pixel at a time, as `shade_phong` and `radiance` take
/// them.
pub fn colours(scene: &CpuScene<f32>, pixels: &[[u32; 2]]) -> [[f32; 3]; WIDTH] {
    let mut out = [[0.0; 3]; WIDTH];
    let n = pixels.len().min(WIDTH);
    if n == 0 {
        return out;
    }
    let active = u32::MAX >> (32 - n);
    // Lanes past the last pixel repeat it, unused.
    let rays = pixel_rays(scene, &std::array::from_fn(|i| pixels[i.min(n - 1)]));
    for _ in 0..n {
        count_ray(0);
    }
    let hits = traverse(scene, &rays, active, f32::T_INF, false);
    let mut lit = 0u32;
    let mut points: [Option<SurfacePoint<f32>>; WIDTH] = [None; WIDTH];
    let mut colour = [Vec3A::from(scene.background); WIDTH];
    for (i, hit) in hits.iter().enumerate() {
        if active & (1 << i) != 0 && hit.prim != NO_HIT {
            points[i] = Some(surface_point_f32(scene, &rays[i], hit));
            colour[i] = scene.ambient.into();
            lit |= 1 << i;
        }
    }
    let key = |i: usize| centre_key(scene, pixels[i][0], pixels[i][1]);
    for l in 0..scene.lights.len() {
        let light = light_at(scene, l, 0.0);
        let on_surface = scene
            .surfaces_at_lights
            .get(l)
            .is_some_and(|s| !s.is_empty());
        if light.kind != LIGHT_POINT || on_surface {
            for (i, sp) in points.iter().enumerate() {
                if let Some(sp) = sp {
                    let term = light_term(scene, sp, -rays[i].dir, l, 0, &key(i));
                    colour[i] += Vec3A::from(term.contribution);
                }
            }
            continue;
        }
        // `point_shadow_ray`'s rays (no surfaces at this light, so no
        // grazing band). Lanes without a surface carry the primary ray,
        // unused.
        let mut origins = [Vec3::ZERO; WIDTH];
        let mut dirs = [Vec3::ZERO; WIDTH];
        for (i, sp) in points.iter().enumerate() {
            (origins[i], dirs[i]) = match sp {
                Some(sp) => {
                    let origin = shadow_origin(scene, sp, light.position);
                    (origin, light.position - origin)
                }
                None => (rays[i].origin, rays[i].dir),
            };
        }
        let shadows = make_rays(&origins, &dirs);
        for _ in 0..lit.count_ones() {
            count_ray(1);
        }
        let blockers = traverse(scene, &shadows, lit, 1.0, true);
        for (i, sp) in points.iter().enumerate() {
            if let Some(sp) = sp {
                if blockers[i].prim == NO_HIT {
                    colour[i] +=
                        point_contribution_f32(sp, -rays[i].dir, light.position, light.color);
                }
            }
        }
    }
    for (i, px) in out.iter_mut().enumerate().take(n) {
        let local = f32::clamp01(colour[i].into());
        let c = if lit & (1 << i) != 0 && scene.reflect_depth > 0 {
            reflect_path(scene, &rays[i], hits[i], local, &key(i))
        } else {
            local
        };
        *px = f32::v3_to_f32(f32::clamp01(c));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::Bvh;
    use crate::cpu::trace::{make_ray, traverse as single, CpuGeometry};
    use crate::cpu::CpuOptions;
    use crate::scene::Scene;
    use glam::Vec3;

    /// `n` random triangles in front of the camera, their tree, and their
    /// f32 geometry.
    fn fixture(n: usize) -> (Scene, Bvh, CpuGeometry<f32>) {
        let scene = wide::tests::scene(n);
        let bvh = Bvh::build(&scene);
        let geometry = CpuGeometry::new(&scene, &bvh, &Default::default());
        (scene, bvh, geometry)
    }

    /// Uniform numbers in [-1, 1), replayable from `seed`.
    fn uniform(seed: u32) -> impl FnMut() -> f32 {
        let mut state = seed;
        move || {
            state = crate::cpu::sample::hash_u32(state);
            f32::from_bits(state >> 9 | 0x3f80_0000) * 2.0 - 3.0
        }
    }

    /// Every ray of a packet gets the single ray's closest hit (the same
    /// t to the bit; a different primitive only at that same t) and the
    /// single ray's shadow verdict, packets coherent or not, some lanes off.
    #[test]
    fn packets_find_what_single_rays_find() {
        let (scene, bvh, geometry) = fixture(3000);
        let camera = crate::camera::Camera::new(64, 48);
        let cpu = CpuScene::new(&scene, &bvh, &geometry, &camera, &CpuOptions::default());
        let mut next = uniform(17);
        let (mut hits, mut blocked, mut ties) = (0, 0, 0);
        for p in 0..600 {
            // Coherent packets (one origin, close directions), scattered
            // ones, and ones whose rays share a direction from many origins
            // (shadow rays towards one light).
            let origin = Vec3::new(next(), next(), next()) * 2.0;
            let dir = Vec3::new(next(), next(), next() - 1.0);
            let spread = [0.01, 1.0, 0.0][p % 3];
            let rays: [Ray<f32>; WIDTH] = std::array::from_fn(|_| {
                let o = if p % 3 == 2 {
                    origin + Vec3::new(next(), next(), next())
                } else {
                    origin
                };
                let d = dir + Vec3::new(next(), next(), next()) * spread;
                make_ray::<f32>(o, d.normalize(), 0.0)
            });
            let all = u32::MAX >> (32 - WIDTH);
            let active = if p % 5 == 0 { 0xb6b6_b6b6 & all } else { all };
            let got = traverse(&cpu, &rays, active, f32::MAX, false);
            for (r, ray) in rays.iter().enumerate() {
                if active & (1 << r) == 0 {
                    assert_eq!(got[r].prim, NO_HIT);
                    continue;
                }
                let want = single(&cpu, ray, f32::MAX, false, &[], 0.0);
                assert_eq!(got[r].t.to_bits(), want.t.to_bits(), "packet {p} ray {r}");
                if got[r].prim != want.prim {
                    ties += 1;
                } else {
                    assert_eq!(
                        (got[r].b1.to_bits(), got[r].b2.to_bits()),
                        (want.b1.to_bits(), want.b2.to_bits())
                    );
                }
                hits += usize::from(want.prim != NO_HIT);
            }
            // Shadow rays of random lengths.
            let shadows: [Ray<f32>; WIDTH] = std::array::from_fn(|r| {
                let end = (next() + 1.0) * 20.0;
                make_ray::<f32>(rays[r].origin, rays[r].dir * end, 0.0)
            });
            let got = traverse(&cpu, &shadows, active, 1.0, true);
            for (r, ray) in shadows.iter().enumerate() {
                if active & (1 << r) == 0 {
                    continue;
                }
                let want = single(&cpu, ray, 1.0, true, &[], 0.0);
                assert_eq!(got[r].prim != NO_HIT, want.prim != NO_HIT, "packet {p}");
                blocked += usize::from(want.prim != NO_HIT);
            }
        }
        assert!(
            hits > 1000 && blocked > 300,
            "{hits} hits, {blocked} blocked"
        );
        assert!(ties < hits / 100, "{ties} ties");
    }

    /// The SIMD surface point is the generic one to the bit, field by
    /// field: on triangles of every size (1e-20 to 1e20 across, so that
    /// products overflow and underflow), flat ones (whose geometric normal
    /// falls back), zero and opposed shading normals (whose sum falls back),
    /// a different material at each corner, and barycentrics inside, on
    /// the edges and outside.
    #[test]
    fn simd_surface_point_is_the_generic_one_to_the_bit() {
        use crate::scene::{Material, Triangle, Vertex};
        use glam::DVec3;
        let mut next = uniform(5);
        let mut scene = Scene::default();
        let materials: Vec<u32> = (0..8)
            .map(|_| {
                let mut c =
                    || DVec3::new(f64::from(next()), f64::from(next()), f64::from(next())).abs();
                scene.add_material(Material {
                    kd: c(),
                    ks: c(),
                    shininess: f64::from(next().abs()) * 100.0,
                })
            })
            .collect();
        for i in 0..4000usize {
            let size = 10f64.powi((i % 41) as i32 - 20);
            let c = DVec3::new(
                f64::from(next()),
                f64::from(next()),
                f64::from(next()) - 2.0,
            ) * size;
            let flat = i % 7 == 0;
            let vertices = [0usize, 1, 2].map(|k| {
                let d = DVec3::new(f64::from(next()), f64::from(next()), f64::from(next()));
                let position = if flat {
                    c + DVec3::X * (k as f64 + 0.5) * size
                } else {
                    c + d * size
                };
                let normal = match (i + k) % 5 {
                    0 => DVec3::ZERO,
                    1 if k > 0 => -DVec3::Y,
                    1 => DVec3::Y,
                    _ => DVec3::new(f64::from(next()), f64::from(next()), f64::from(next())),
                };
                Vertex {
                    position,
                    normal,
                    material: materials[(i + 3 * k) % materials.len()],
                }
            });
            scene.triangles.push(Triangle {
                vertices,
                velocity: DVec3::ZERO,
            });
        }
        let bvh = Bvh::build(&scene);
        let geometry = CpuGeometry::new(&scene, &bvh, &Default::default());
        let camera = crate::camera::Camera::new(64, 48);
        let cpu = CpuScene::new(&scene, &bvh, &geometry, &camera, &CpuOptions::default());
        let ray = make_ray::<f32>(Vec3::ZERO, Vec3::NEG_Z, 0.0);
        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
        for prim in 0..scene.triangles.len() as u32 {
            for k in 0..8 {
                let (b1, b2) = match k {
                    0 => (0.0, 0.0),
                    1 => (1.0, 0.0),
                    2 => (0.5, 0.5),
                    3 => (1.5, -0.25),
                    _ => ((next() + 1.0) * 0.5, (next() + 1.0) * 0.25),
                };
                let hit = Hit {
                    t: 1.0,
                    prim,
                    b1,
                    b2,
                };
                let want = surface_point(&cpu, &ray, &hit);
                let got = surface_point_f32(&cpu, &ray, &hit);
                let fields = |s: &SurfacePoint<f32>| {
                    (
                        [s.p, s.n, s.ng, s.scale, s.kd, s.ks].map(bits),
                        s.shininess.to_bits(),
                    )
                };
                assert_eq!(fields(&got), fields(&want), "triangle {prim}, b {b1} {b2}");
            }
        }
    }

    /// The SIMD point-light term is the generic one's contribution to the
    /// bit: lights at the point itself (no direction), behind the surface,
    /// shininess 0 (0^0 = 1) and large, views along and against the normal.
    #[test]
    fn simd_point_term_is_the_generic_one_to_the_bit() {
        use crate::cpu::trace::point_shading;
        let mut next = uniform(9);
        let mut v = || Vec3::new(next(), next(), next());
        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
        for i in 0..200_000 {
            let p = v() * 10.0;
            let n = if i % 9 == 0 {
                Vec3::ZERO
            } else {
                v().normalize_or_zero()
            };
            let sp = SurfacePoint {
                p,
                n,
                ng: n,
                scale: p.abs(),
                kd: v().abs(),
                ks: v().abs(),
                shininess: [0.0, 1.0, 0.5, 100.0][i % 4] * (1.0 + v().x),
            };
            let target = match i % 7 {
                0 => p,
                1 => p - n,
                _ => v() * 20.0,
            };
            let view = match i % 5 {
                0 => n,
                1 => -n,
                _ => v().normalize_or_zero(),
            };
            let color = v().abs();
            let blocker = Hit {
                t: 0.0,
                prim: NO_HIT,
                b1: 0.0,
                b2: 0.0,
            };
            let want = point_shading(&sp, view, target, color, p, blocker).contribution;
            let got = point_contribution_f32(&sp, view, target, color);
            assert_eq!(bits(got.into()), bits(want), "case {i}");
        }
    }

    /// The AVX2 and AVX-512 box tests give every ray what the SSE one gives
    /// it, to the bit: which children it passes and its entry t, including
    /// rays along an axis plane (either sign of zero) and rays with a NaN
    /// direction. Each is checked where the CPU has it, and says so where
    /// it has not.
    #[test]
    fn avx_boxes_match_sse() {
        #[cfg(target_arch = "x86_64")]
        {
            if !std::arch::is_x86_feature_detected!("avx2") {
                eprintln!("SKIPPED: avx_boxes_match_sse: this CPU has no AVX2");
                return;
            }
            let avx512 = std::arch::is_x86_feature_detected!("avx512f");
            if !avx512 {
                eprintln!("SKIPPED: avx_boxes_match_sse's AVX-512 half: this CPU has no AVX-512F");
            }
            let (scene, bvh, geometry) = fixture(500);
            let camera = crate::camera::Camera::new(64, 48);
            let cpu = CpuScene::new(&scene, &bvh, &geometry, &camera, &CpuOptions::default());
            let mut next = uniform(23);
            let mut passed = 0;
            for p in 0..300 {
                let nodes = &cpu.wide.nodes;
                let rays: [Ray<f32>; WIDTH] = std::array::from_fn(|r| {
                    let mut o = Vec3::new(next(), next(), next()) * 4.0;
                    let mut d = Vec3::new(next(), next(), next() - 1.0);
                    match (p + r) % 8 {
                        1 => d.x = 0.0,
                        2 => d.y = -0.0,
                        3 if p % 16 == 3 => d = Vec3::NAN,
                        _ => {}
                    }
                    if p % 4 == 1 {
                        // On a box's faces: a ray leaving through a face
                        // meets its box at t_near = t_far = 0, which only
                        // `<=` passes.
                        let node = &nodes[(next().abs() * 1e4) as usize % nodes.len()];
                        let lane = r % 4;
                        for axis in 0..3 {
                            if (p / 4 + r + axis) % 3 != 0 {
                                o[axis] = [node.lo, node.hi][(r + axis) % 2][axis][lane];
                                d[axis] = [0.0, 1.0, -1.0][(p / 4 + axis) % 3];
                            }
                        }
                    }
                    let d = if d.is_nan() { d } else { d.normalize() };
                    make_ray::<f32>(o, d, 0.0)
                });
                let soa = Soa::new(&rays);
                let best_t = Lanes(std::array::from_fn(|_| {
                    if next() > 0.0 {
                        f32::MAX
                    } else {
                        next() + 20.0
                    }
                }));
                let all = u32::MAX >> (32 - WIDTH);
                let mask = if p % 3 == 0 { 0x6d6d_6d6d & all } else { all };
                // Reused from node to node, as a traversal does.
                let [mut a, mut b, mut c, mut d, mut e, mut f] = [0; 6].map(|_| Children::NONE);
                for node in &cpu.wide.nodes {
                    children_sse::<false>(node, &soa, mask, &best_t, &mut a);
                    // SAFETY: the CPU has AVX2, checked above.
                    unsafe { children_avx2::<false>(node, &soa, mask, &best_t, &mut b) };
                    assert_eq!(a.hits, b.hits);
                    // The any-hit tests find the same rays in each box.
                    children_sse::<true>(node, &soa, mask, &best_t, &mut d);
                    assert_eq!(d.hits, a.hits);
                    // SAFETY: as above.
                    unsafe { children_avx2::<true>(node, &soa, mask, &best_t, &mut c) };
                    assert_eq!(c.hits, a.hits);
                    // The closest-hit tests' entries, where a ray passed.
                    let same_entries = |x: &Children| {
                        for lane in 0..4 {
                            for r in 0..WIDTH {
                                if a.hits[lane] & (1 << r) != 0 {
                                    let near = a.near[lane].0[r].to_bits();
                                    assert_eq!(near, x.near[lane].0[r].to_bits());
                                }
                            }
                            if a.hits[lane] != 0 {
                                let nearest = a.nearest[lane].to_bits();
                                assert_eq!(nearest, x.nearest[lane].to_bits());
                            }
                        }
                    };
                    same_entries(&b);
                    if avx512 {
                        // SAFETY: the CPU has AVX-512F, checked above.
                        unsafe {
                            children_avx512::<false>(node, &soa, mask, &best_t, &mut e);
                            children_avx512::<true>(node, &soa, mask, &best_t, &mut f);
                        }
                        assert_eq!(e.hits, a.hits);
                        assert_eq!(f.hits, a.hits);
                        same_entries(&e);
                    }
                    passed += a.hits.iter().map(|h| h.count_ones()).sum::<u32>();
                }
            }
            assert!(passed > 1000, "{passed} box hits");
        }
    }

    /// The packet's sphere test gives each ray the scalar test's t to the
    /// bit: hits from outside and inside, misses, grazing rays, rays from
    /// the centre, and rays with a NaN direction.
    #[test]
    fn sphere_rays_match_the_scalar_test() {
        use crate::cpu::trace::hit_sphere;
        let mut next = uniform(29);
        let (mut hits, mut misses) = (0, 0);
        for p in 0..2000 {
            let s = Sphere {
                center: Vec3::new(next(), next(), next() - 4.0),
                radius: next().abs() + 0.01,
                kd: Vec3::ONE,
                ks: Vec3::ZERO,
                shininess: 1.0,
                velocity: Vec3::ZERO,
            };
            let rays: [Ray<f32>; WIDTH] = std::array::from_fn(|r| {
                let o = match (p + r) % 5 {
                    0 => s.center,
                    1 => s.center + Vec3::new(next(), next(), next()) * s.radius * 0.5,
                    _ => Vec3::new(next(), next(), next()),
                };
                let target = s.center + Vec3::new(next(), next(), next()) * s.radius;
                let d = if (p + r) % 97 == 3 {
                    Vec3::NAN
                } else {
                    (target - o).normalize()
                };
                make_ray::<f32>(o, d, 0.0)
            });
            let best_t = Lanes(std::array::from_fn(|_| {
                if next() > 0.0 {
                    f32::MAX
                } else {
                    next() + 4.0
                }
            }));
            let got = hit_sphere_rays(&Soa::new(&rays), &s, &best_t);
            for (r, ray) in rays.iter().enumerate() {
                let want = hit_sphere(ray, &s, best_t.0[r], 0.0);
                assert_eq!(got.0[r].to_bits(), want.to_bits(), "sphere {p} ray {r}");
                if want < best_t.0[r] {
                    hits += 1;
                } else {
                    misses += 1;
                }
            }
        }
        assert!(hits > 3000 && misses > 1000, "{hits} hits, {misses} misses");
    }

    /// The octet triangle test gives each ray `wide::hit_block_f32`'s
    /// answer to the bit (which triangle, t, barycentrics), over blocks
    /// with empty lanes, degenerate and edge-sharing triangles, rays on
    /// every axis order and limits that cut hits off.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn octet_triangle_test_matches_the_block_test() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            eprintln!("skipped: this CPU has no AVX2, so the octet test never runs");
            return;
        }
        let mut next = uniform(41);
        let (mut hits, mut misses, mut octets) = (0, 0, 0);
        for b in 0..3000 {
            let mut corners = [[Vec3::ZERO; 3]; 4];
            for j in 0..4 {
                let mut tri = [0; 3].map(|_| Vec3::new(next(), next(), next() - 3.0));
                match (b + j) % 7 {
                    // Degenerate: two corners the same, or all in a line.
                    0 => tri[1] = tri[0],
                    1 => tri[2] = tri[0] + (tri[1] - tri[0]) * 0.5,
                    // An edge shared with the triangle before.
                    2 if j > 0 => [tri[0], tri[1]] = [corners[j - 1][1], corners[j - 1][2]],
                    _ => {}
                }
                corners[j] = tri;
            }
            let used = 1 + b % 4;
            let block = wide::LeafBlock {
                p: std::array::from_fn(|axis| {
                    std::array::from_fn(|corner| {
                        Vec4::from_array(std::array::from_fn(|j| corners[j][corner][axis]))
                    })
                }),
                prims: std::array::from_fn(|j| if j < used { 10 + j as u32 } else { wide::NONE }),
            };
            // Rays aimed at the triangles, mostly along one axis so that
            // octets share an axis order; every few packets a mixed one.
            let axis = b % 3;
            let rays: [Ray<f32>; WIDTH] = std::array::from_fn(|r| {
                let tri = corners[r % used];
                let (u, v) = (next().abs(), next().abs());
                let target = tri[0] + (tri[1] - tri[0]) * u * 0.7 + (tri[2] - tri[0]) * v * 0.7;
                let mut d = Vec3::new(next(), next(), next()) * 0.3;
                d[axis] = if b % 2 == 0 { 1.0 } else { -1.0 };
                if b % 11 == 5 {
                    d = Vec3::new(next(), next(), next());
                }
                let o = target - d * (2.0 + next().abs());
                make_ray::<f32>(o, d.normalize(), 0.0)
            });
            let soa = Soa::new(&rays);
            let limit: [f32; WIDTH] = std::array::from_fn(|_| {
                if next() > -0.3 {
                    f32::MAX
                } else {
                    next().abs() * 3.0
                }
            });
            for (g, k) in soa.k.iter().enumerate() {
                let Some(k) = *k else { continue };
                octets += 1;
                let m8 = (next().to_bits() >> 3 | 0x11) & 255;
                let mut best = [Hit {
                    t: 0.0,
                    prim: NO_HIT,
                    b1: 0.0,
                    b2: 0.0,
                }; WIDTH];
                let mut best_t = Lanes(limit);
                for (r, h) in best.iter_mut().enumerate() {
                    h.t = limit[r];
                }
                // SAFETY: the CPU has AVX2, checked above.
                let found =
                    unsafe { hit_block_octet(&block, &soa, k, g, m8, &mut best, &mut best_t) };
                for i in 0..8 {
                    let r = 8 * g + i;
                    let want = if m8 & 1 << i == 0 {
                        None
                    } else {
                        wide::hit_block_f32(&rays[r], &block, limit[r])
                    };
                    assert_eq!(found >> r & 1 == 1, want.is_some(), "block {b} ray {r}");
                    match want {
                        Some((j, t, b1, b2)) => {
                            hits += 1;
                            let h = best[r];
                            assert_eq!(h.prim, block.prims[j], "block {b} ray {r}");
                            let got = [h.t, h.b1, h.b2, best_t.0[r]].map(f32::to_bits);
                            assert_eq!(got, [t, b1, b2, t].map(f32::to_bits), "block {b} ray {r}");
                        }
                        None => {
                            misses += 1;
                            assert_eq!(best[r].prim, NO_HIT, "block {b} ray {r}");
                            assert_eq!(best_t.0[r].to_bits(), limit[r].to_bits());
                        }
                    }
                }
            }
        }
        assert!(
            hits > 20_000 && misses > 20_000 && octets > 8_000,
            "{hits} hits, {misses} misses, {octets} octets"
        );
    }

    /// Every field of a ray, as bits.
    fn bits(r: &Ray<f32>) -> ([u32; 12], [usize; 3]) {
        let v = |v: Vec3| v.to_array().map(f32::to_bits);
        let [o, d, i, s] = [v(r.origin), v(r.dir), v(r.inv_dir), v(r.shear)];
        let mut out = [0; 12];
        for (k, x) in [o, d, i, s].iter().flatten().enumerate() {
            out[k] = *x;
        }
        assert_eq!(r.time, 0.0);
        (out, r.k)
    }

    /// The packet's rays are `make_ray`'s to the bit, for directions of
    /// every kind: components zero of either sign, below, at and above
    /// `MIN_DIR`, all three tiny, infinite, NaN.
    #[test]
    fn packet_rays_match_make_ray() {
        let mut next = uniform(31);
        let specials = [
            0.0,
            -0.0,
            1e-31,
            -1e-31,
            f32::MIN_DIR,
            -f32::MIN_DIR,
            2e-30,
            f32::INFINITY,
            f32::NAN,
            1.0,
        ];
        let mut special = 0;
        for p in 0..500 {
            let origins: [Vec3; WIDTH] =
                std::array::from_fn(|_| Vec3::new(next(), next(), next()) * 8.0);
            let dirs: [Vec3; WIDTH] = std::array::from_fn(|r| {
                let mut d = Vec3::new(next(), next(), next());
                if (p + r) % 3 == 0 {
                    special += 1;
                    d[special % 3] = specials[special % specials.len()];
                    if p % 7 == 0 {
                        d[(special + 1) % 3] = specials[(special / 3) % specials.len()];
                    }
                }
                if p % 50 == 0 && r == 3 {
                    d = Vec3::splat(1e-31);
                }
                d
            });
            let got = make_rays(&origins, &dirs);
            for r in 0..WIDTH {
                let want = make_ray(origins[r], dirs[r], 0.0);
                assert_eq!(bits(&got[r]), bits(&want), "{:?}", dirs[r]);
            }
        }
    }

    /// The packet's primary rays are `pixel_ray`'s to the bit, on images of
    /// odd and even sizes.
    #[test]
    fn packet_pixel_rays_match_pixel_ray() {
        let (scene, bvh, geometry) = fixture(10);
        for [w, h] in [[640, 480], [641, 241], [1, 1], [3, 7]] {
            let camera = crate::camera::Camera::new(w, h);
            let cpu = CpuScene::new(&scene, &bvh, &geometry, &camera, &CpuOptions::default());
            let pixels: Vec<[u32; 2]> = (0..h)
                .flat_map(|y| (0..w).map(move |x| [x, y]))
                .filter(|&[x, y]| w < 100 || (x * 7 + y * 3) % 5 == 0)
                .collect();
            for chunk in pixels.chunks(WIDTH) {
                let tile = std::array::from_fn(|i| chunk[i.min(chunk.len() - 1)]);
                for (r, ray) in pixel_rays(&cpu, &tile).iter().enumerate() {
                    let [x, y] = tile[r];
                    let want = crate::cpu::trace::pixel_ray(&cpu, x, y);
                    assert_eq!(bits(ray), bits(&want), "{w}x{h} pixel {x},{y}");
                }
            }
        }
    }
}
