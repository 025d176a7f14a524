//! The packet's box tests eight rays a register (AVX2), and a leaf
//! block's triangles against an octet of rays (`hit_block_octet`), each
//! lane the single ray's arithmetic to the bit.

use super::lanes::*;
use crate::bvh::wide;
use crate::cpu::trace::Hit;
use crate::cpu::Real;

/// One child box (`lane` of `node`) against a register of rays (origins
/// `o`, inverse directions `inv`, limits `bt`), as `(t_near, t_far)`:
/// `children_sse`'s arithmetic, in the intrinsics of the register's width
/// (broadcast, sub, mul, min, max), for the AVX2 and AVX-512 tests alike.
/// A macro, not a function over the intrinsics, so that each expands inside
/// its caller's `target_feature` and inlines as written.
#[cfg(target_arch = "x86_64")]
macro_rules! box_entry_exit {
    ($node:expr, $lane:expr, $o:expr, $inv:expr, $bt:expr, $zero:expr, $scale:expr, $at_origin:expr;
     $set1:ident, $sub:ident, $mul:ident, $min:ident, $max:ident) => {{
        // x - 0 is x, to the bit: rays from the origin skip the subtraction.
        let rel = |x: f32, o| {
            if $at_origin {
                $set1(x)
            } else {
                $sub($set1(x), o)
            }
        };
        // A lane read through the array: glam's `Vec4` index is a match,
        // a jump table where the lane is not known when compiling, and
        // its indirect branch mispredicts (callgrind's predictor: 86% of a
        // 240k grid render's indirect misses, in the leaf tests' `[j]`).
        let slab = |axis: usize| {
            let t0 = $mul(rel($node.lo[axis].as_ref()[$lane], $o[axis]), $inv[axis]);
            let t1 = $mul(rel($node.hi[axis].as_ref()[$lane], $o[axis]), $inv[axis]);
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
#[cfg(target_arch = "x86_64")]
pub(super) use box_entry_exit;

/// `children_sse` with AVX2, eight rays at a time: the same operations
/// lane for lane (`_mm256_min_ps` and `_mm256_max_ps` take their operands
/// in `Vec4::min`'s and `max`'s order, so NaNs fall the same way; `<=` is
/// the same ordered compare), so each ray gets the same answer to the bit.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
#[inline]
pub(super) fn children_avx2<const ANY_HIT: bool, const AT_ORIGIN: bool>(
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
        // Per child, the entries of the rays that hit it (the others at
        // +inf), folded over the octets by lane and across lanes once at
        // the end: min is exact and sees no NaN (a NaN entry fails `<=`
        // and is never chosen), so the order does not change the answer.
        let mut entries = [inf; 4];
        // Kept in registers over the octets, stored once.
        let mut hits = [0u32; 4];
        for g in 0..WIDTH / 8 {
            let m8 = mask >> (8 * g) & 255;
            if m8 == 0 {
                continue;
            }
            let load = |l: &Lanes| _mm256_load_ps(l.0.as_ptr().add(8 * g));
            let o = [load(&soa.o[0]), load(&soa.o[1]), load(&soa.o[2])];
            let inv = [load(&soa.inv[0]), load(&soa.inv[1]), load(&soa.inv[2])];
            let bt = load(best_t);
            // `lane` picks the child in the node's arrays and in `out`'s.
            #[allow(clippy::needless_range_loop)]
            for lane in 0..4 {
                if node.child[lane] == wide::EMPTY {
                    continue;
                }
                let (t_near, t_far) = box_entry_exit!(
                    node, lane, o, inv, bt, zero, scale, AT_ORIGIN;
                    _mm256_set1_ps, _mm256_sub_ps, _mm256_mul_ps, _mm256_min_ps, _mm256_max_ps
                );
                let passed = _mm256_cmp_ps::<_CMP_LE_OS>(t_near, t_far);
                let hit = _mm256_movemask_ps(passed) as u32 & m8;
                // No branch on `hit`: whether an octet meets a box is what
                // the predictor guesses worst, and with no ray in it the
                // stores below are never read and the min keeps +inf.
                hits[lane] |= hit << (8 * g);
                if !ANY_HIT {
                    _mm256_store_ps(out.near[lane].0.as_mut_ptr().add(8 * g), t_near);
                    let chosen = _mm256_cmpeq_epi32(
                        _mm256_and_si256(_mm256_set1_epi32(hit as i32), bits),
                        bits,
                    );
                    let t = _mm256_blendv_ps(inf, t_near, _mm256_castsi256_ps(chosen));
                    entries[lane] = _mm256_min_ps(entries[lane], t);
                }
            }
        }
        out.hits = hits;
        if !ANY_HIT {
            // A box no ray hit folds to the +inf it was reset to: no branch.
            for (nearest, &t) in out.nearest.iter_mut().zip(&entries) {
                *nearest = min_across(t);
            }
        }
    }
}

/// The least of a register's eight lanes (none NaN).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
#[inline]
fn min_across(t: std::arch::x86_64::__m256) -> f32 {
    use std::arch::x86_64::*;
    let m = _mm_min_ps(_mm256_castps256_ps128(t), _mm256_extractf128_ps::<1>(t));
    let m = _mm_min_ps(m, _mm_movehl_ps(m, m));
    let m = _mm_min_ss(m, _mm_shuffle_ps::<1>(m, m));
    _mm_cvtss_f32(m)
}

/// An octet's rays in the axis order `k` they share: origins along kx,
/// ky, kz, and their shears.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Octet {
    o: [std::arch::x86_64::__m256; 3],
    s: [std::arch::x86_64::__m256; 3],
}

#[cfg(target_arch = "x86_64")]
impl Octet {
    /// Octet `g`'s rays of `soa`, in the order `k`.
    #[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    fn load(soa: &Soa, k: [usize; 3], g: usize) -> Octet {
        use std::arch::x86_64::*;
        // SAFETY: `Lanes` is 64-byte aligned (32 would do here) and holds
        // `WIDTH` f32, a multiple of eight, as the aligned loads at every
        // eighth one need.
        let load = |l: &Lanes| unsafe { _mm256_load_ps(l.0.as_ptr().add(8 * g)) };
        let [kx, ky, kz] = k;
        Octet {
            o: [load(&soa.o[kx]), load(&soa.o[ky]), load(&soa.o[kz])],
            s: [
                load(&soa.shear[0]),
                load(&soa.shear[1]),
                load(&soa.shear[2]),
            ],
        }
    }
}

/// The watertight test of one triangle against a register of rays, with
/// origins `o` and shears `s` along the rays' axes (kx, ky, kz), and
/// their limits `t_max`, `at(c, a)` giving corner `c` on axis `a`: per ray
/// `trace::hit_triangle`'s operations in its order on the same values.
/// The operations come from the caller, for its width: `set1`, `sub`,
/// `mul`, `add` and `zero` on floats; `lt`, `gt` (ordered) and `neq`
/// (unordered) compares; `or`, `and` and `andnot` (not the first, and the
/// second) on their answers, vectors for AVX2, masks for AVX-512. Gives
/// the rays it hits, the scaled t, the determinant and the unscaled second
/// and third barycentrics (t is `t_scaled / det`). A macro, as
/// `box_entry_exit`, so that it expands inside its caller's
/// `target_feature`; one macro, so that every width runs the same
/// arithmetic.
#[cfg(target_arch = "x86_64")]
macro_rules! crossing {
    ($o:expr, $s:expr, $at:expr, $t_max:expr, $at_origin:expr;
     $set1:expr, $sub:expr, $mul:expr, $add:expr, $zero:expr,
     $lt:expr, $gt:expr, $neq:expr, $or:expr, $and:expr, $andnot:expr) => {{
        let [ox, oy, oz] = $o;
        let [s0, s1, s2] = $s;
        let (sub, mul, add, zero) = ($sub, $mul, $add, $zero);
        let (lt, gt, or, and, andnot) = ($lt, $gt, $or, $and, $andnot);
        // Corner minus origin; x - 0 is x, to the bit, so rays from the
        // origin skip the subtraction.
        let p = |corner: usize, axis: usize, o| {
            let x = $set1($at(corner, axis));
            if $at_origin {
                x
            } else {
                sub(x, o)
            }
        };
        let a_z = p(0, 2, oz);
        let b_z = p(1, 2, oz);
        let c_z = p(2, 2, oz);
        let ax = sub(p(0, 0, ox), mul(s0, a_z));
        let ay = sub(p(0, 1, oy), mul(s1, a_z));
        let bx = sub(p(1, 0, ox), mul(s0, b_z));
        let by = sub(p(1, 1, oy), mul(s1, b_z));
        let cx = sub(p(2, 0, ox), mul(s0, c_z));
        let cy = sub(p(2, 1, oy), mul(s1, c_z));
        let u = sub(mul(cx, by), mul(cy, bx));
        let v = sub(mul(ax, cy), mul(ay, cx));
        let w = sub(mul(bx, ay), mul(by, ax));
        let some_negative = or(or(lt(u, zero), lt(v, zero)), lt(w, zero));
        let some_positive = or(or(gt(u, zero), gt(v, zero)), gt(w, zero));
        let det = add(add(u, v), w);
        let t_scaled = add(
            add(mul(u, mul(s2, a_z)), mul(v, mul(s2, b_z))),
            mul(w, mul(s2, c_z)),
        );
        let end = mul($t_max, det);
        let positive = and(gt(t_scaled, zero), lt(t_scaled, end));
        let negative = and(lt(t_scaled, zero), gt(t_scaled, end));
        let det_positive = gt(det, zero);
        let inside = or(and(det_positive, positive), andnot(det_positive, negative));
        let hit = andnot(
            and(some_negative, some_positive),
            and($neq(det, zero), inside),
        );
        (hit, t_scaled, det, v, w)
    }};
}
#[cfg(target_arch = "x86_64")]
pub(super) use crossing;

/// `crossing!` on an octet's rays (`Octet`), eight a register with AVX2.
#[cfg(target_arch = "x86_64")]
macro_rules! crossing_octet {
    ($rays:expr, $at:expr, $t_max:expr, $at_origin:expr) => {
        crossing!(
            $rays.o, $rays.s, $at, $t_max, $at_origin;
            _mm256_set1_ps, _mm256_sub_ps, _mm256_mul_ps, _mm256_add_ps, _mm256_setzero_ps(),
            |a, b| _mm256_cmp_ps::<_CMP_LT_OS>(a, b),
            |a, b| _mm256_cmp_ps::<_CMP_GT_OS>(a, b),
            |a, b| _mm256_cmp_ps::<_CMP_NEQ_UQ>(a, b),
            _mm256_or_ps, _mm256_and_ps, _mm256_andnot_ps
        )
    };
}

/// The new hits of the `N` rays from ray `N * g` in `found` (an octet's
/// or a sixteen's): lane i's t, b1 and b2 at `out[..][i]` and its
/// primitive `prim(i)`. Returns `found` as the packet's ray bits.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) fn keep_hits<const N: usize>(
    (g, found): (usize, u32),
    out: &[[f32; N]; 3],
    prim: impl Fn(usize) -> u32,
    best: &mut [Hit<f32>; WIDTH],
    best_t: &mut Lanes,
) -> u32 {
    let mut each = found;
    while each != 0 {
        let i = each.trailing_zeros() as usize;
        each &= each - 1;
        let r = N * g + i;
        best[r] = Hit {
            t: out[0][i],
            prim: prim(i),
            b1: out[1][i],
            b2: out[2][i],
        };
        best_t.0[r] = out[0][i];
    }
    found << (N * g)
}

/// One triangle (`tri`, primitive `prim`) against the rays of octet `g`
/// in `m8` that share the axis order `k`, eight at a time with AVX2: each
/// ray `trace::hit_triangle`'s answer against its own nearest hit so far,
/// to the bit, kept where nearer (as the single ray's primitive loop
/// keeps it). Writes the rays' new hits and returns the bits of the rays
/// that found one. For leaves that are no SIMD block (spheres among the
/// triangles), whose triangles each ray tested alone.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
#[inline]
pub(super) fn hit_triangle_octet<const AT_ORIGIN: bool>(
    tri: &[glam::Vec3; 3],
    prim: u32,
    soa: &Soa,
    (k, g, m8): ([usize; 3], usize, u32),
    best: &mut [Hit<f32>; WIDTH],
    best_t: &mut Lanes,
) -> u32 {
    use std::arch::x86_64::*;
    let rays = Octet::load(soa, k, g);
    // SAFETY: as `Octet::load`'s loads; the outputs are eight lanes each,
    // written unaligned.
    let t_max = unsafe { _mm256_load_ps(best_t.0.as_ptr().add(8 * g)) };
    let [kx, ky, kz] = k;
    let at = |corner: usize, axis: usize| tri[corner].as_ref()[[kx, ky, kz][axis]];
    let (hit, t_scaled, det, v, w) = crossing_octet!(rays, at, t_max, AT_ORIGIN);
    if _mm256_movemask_ps(hit) as u32 & m8 == 0 {
        return 0;
    }
    let inv_det = _mm256_div_ps(_mm256_set1_ps(1.0), det);
    let t = _mm256_mul_ps(t_scaled, inv_det);
    let keep = _mm256_and_ps(hit, _mm256_cmp_ps::<_CMP_LT_OS>(t, t_max));
    let found = _mm256_movemask_ps(keep) as u32 & m8;
    let mut out = [[0.0f32; 8]; 3];
    for (out, x) in out
        .iter_mut()
        .zip([t, _mm256_mul_ps(v, inv_det), _mm256_mul_ps(w, inv_det)])
    {
        // SAFETY: eight f32 written unaligned into eight.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), x) };
    }
    keep_hits((g, found), &out, |_| prim, best, best_t)
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
#[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
#[inline]
pub(super) fn hit_block_octet<const AT_ORIGIN: bool>(
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
    // The octet's nearest hits (t, b1, b2) and their triangles, lane i
    // for ray 8g + i.
    let mut out = [[0.0f32; 8]; 3];
    let mut which = [0i32; 8];
    let rays = Octet::load(soa, k, g);
    // SAFETY: `Lanes` is 64-byte aligned (32 would do here) and holds
    // `WIDTH` f32, a multiple of eight, as the aligned load at every
    // eighth one needs; the outputs are eight lanes each, written
    // unaligned; the rest is arithmetic on registers.
    let found = unsafe {
        let t_max = _mm256_load_ps(best_t.0.as_ptr().add(8 * g));
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
            let at = |corner: usize, axis: usize| block.p[[kx, ky, kz][axis]][corner].as_ref()[j];
            let (hit, t_scaled, det, v, w) = crossing_octet!(rays, at, t_max, AT_ORIGIN);
            if _mm256_movemask_ps(hit) as u32 & m8 == 0 {
                continue;
            }
            let inv_det = _mm256_div_ps(one, det);
            let t = _mm256_mul_ps(t_scaled, inv_det);
            let keep = _mm256_and_ps(hit, _mm256_cmp_ps::<_CMP_LT_OS>(t, run_t));
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
            _mm256_storeu_ps(out[0].as_mut_ptr(), run_t);
            _mm256_storeu_ps(out[1].as_mut_ptr(), run_b1);
            _mm256_storeu_ps(out[2].as_mut_ptr(), run_b2);
            _mm256_storeu_si256(which.as_mut_ptr().cast(), run_k);
        }
        found
    };
    let prim = |i: usize| block.prims[which[i] as usize];
    keep_hits((g, found), &out, prim, best, best_t)
}
