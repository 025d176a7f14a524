//! The packet's box tests sixteen rays a register (AVX-512F), and its
//! leaf blocks' tests where sixteen rays share an axis order.

#[cfg(target_arch = "x86_64")]
use super::avx2::{box_entry_exit, crossing, keep_hits};
use super::lanes::*;
use crate::bvh::wide;
use crate::cpu::trace::Hit;
use crate::cpu::Real;

/// `children_sse` with AVX-512, sixteen rays at a time: the same
/// operations lane for lane as `children_avx2` (`vminps` and `vmaxps` treat
/// NaNs alike at every width, and `<=` is the same ordered compare, here
/// into a mask register), so each ray gets the same answer to the bit. The
/// nearest entry is a masked minimum over rays that passed, whose entries
/// are never NaN, so its order does not matter: folded over the sixteens
/// and reduced once for all four children, with no branch on a box's hit
/// (per child and sixteen, a branch and a reduction before).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,bmi1,bmi2,lzcnt,popcnt")]
#[inline]
pub(super) fn children_avx512<const ANY_HIT: bool, const AT_ORIGIN: bool>(
    node: &wide::Node4,
    soa: &Soa,
    mask: u32,
    best_t: &Lanes,
    out: &mut Children,
) {
    use std::arch::x86_64::*;
    // SAFETY: `Lanes` is 64-byte aligned and holds `WIDTH` f32, a multiple
    // of sixteen, as the aligned loads and stores at every sixteenth one
    // need; the rest is arithmetic on registers.
    unsafe {
        let scale = _mm512_set1_ps(f32::BOX_T_SCALE);
        let zero = _mm512_setzero_ps();
        let inf = _mm512_set1_ps(f32::INFINITY);
        // Per child, the entries of the rays that hit it (the others at
        // +inf), folded over the sixteens by lane and across lanes once at
        // the end, as `children_avx2`'s.
        let mut entries = [inf; 4];
        let mut hits = [0u32; 4];
        for g in 0..WIDTH / 16 {
            let m16 = (mask >> (16 * g) & 0xffff) as u16;
            if m16 == 0 {
                continue;
            }
            let load = |l: &Lanes| _mm512_load_ps(l.0.as_ptr().add(16 * g));
            let o = [load(&soa.o[0]), load(&soa.o[1]), load(&soa.o[2])];
            let inv = [load(&soa.inv[0]), load(&soa.inv[1]), load(&soa.inv[2])];
            let bt = load(best_t);
            #[allow(clippy::needless_range_loop)]
            for lane in 0..4 {
                if node.child[lane] == wide::EMPTY {
                    continue;
                }
                let (t_near, t_far) = box_entry_exit!(
                    node, lane, o, inv, bt, zero, scale, AT_ORIGIN;
                    _mm512_set1_ps, _mm512_sub_ps, _mm512_mul_ps, _mm512_min_ps, _mm512_max_ps
                );
                let hit = _mm512_mask_cmp_ps_mask::<_CMP_LE_OS>(m16, t_near, t_far);
                // No branch on `hit`, as in `children_avx2`.
                hits[lane] |= u32::from(hit) << (16 * g);
                if !ANY_HIT {
                    _mm512_store_ps(out.near[lane].0.as_mut_ptr().add(16 * g), t_near);
                    entries[lane] = _mm512_mask_min_ps(entries[lane], hit, entries[lane], t_near);
                }
            }
        }
        out.hits = hits;
        if !ANY_HIT {
            out.nearest = min_across_four(entries);
        } else {
            out.nearest = [f32::INFINITY; 4];
        }
    }
}

/// The least lane of each of four registers (none NaN), folded together:
/// the four children's halves, then quarters, then within each quarter.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,bmi1,bmi2,lzcnt,popcnt")]
#[inline]
fn min_across_four(v: [std::arch::x86_64::__m512; 4]) -> [f32; 4] {
    use std::arch::x86_64::*;
    // Quarters (q0 q1 of a, q0 q1 of b) against (q2 q3 of a, q2 q3 of b).
    let halves = |a, b| {
        _mm512_min_ps(
            _mm512_shuffle_f32x4::<0b01_00_01_00>(a, b),
            _mm512_shuffle_f32x4::<0b11_10_11_10>(a, b),
        )
    };
    let m01 = halves(v[0], v[1]);
    let m23 = halves(v[2], v[3]);
    // Each quarter one child's four lanes: v0, v1, v2, v3.
    let m = _mm512_min_ps(
        _mm512_shuffle_f32x4::<0b10_00_10_00>(m01, m23),
        _mm512_shuffle_f32x4::<0b11_01_11_01>(m01, m23),
    );
    let m = _mm512_min_ps(m, _mm512_permute_ps::<0b01_00_11_10>(m));
    let m = _mm512_min_ps(m, _mm512_permute_ps::<0b10_11_00_01>(m));
    let mut lanes = [0.0f32; 16];
    // SAFETY: `lanes` holds sixteen f32, written unaligned.
    unsafe { _mm512_storeu_ps(lanes.as_mut_ptr(), m) };
    [lanes[0], lanes[4], lanes[8], lanes[12]]
}

/// `avx2::hit_block_octet` sixteen rays a register: a leaf block's
/// triangles against the rays of sixteen `h` (rays `16h..16h + 16`) in
/// `m16`, which share the axis order `k`. The same operations lane for
/// lane (`crossing!`, with the compares' answers in mask registers where
/// AVX2 keeps them in vectors: the same predicates), so each ray gets
/// `hit_block_f32`'s answer to the bit. Writes the rays' new hits and
/// returns the bits of the rays that found one.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,bmi1,bmi2,lzcnt,popcnt")]
#[inline]
pub(super) fn hit_block_sixteen<const AT_ORIGIN: bool>(
    block: &wide::LeafBlock,
    soa: &Soa,
    k: [usize; 3],
    h: usize,
    m16: u32,
    best: &mut [Hit<f32>; WIDTH],
    best_t: &mut Lanes,
) -> u32 {
    use std::arch::x86_64::*;
    let [kx, ky, kz] = k;
    let mut out = [[0.0f32; 16]; 3];
    let mut which = [0i32; 16];
    // SAFETY: `Lanes` is 64-byte aligned and holds `WIDTH` f32, a multiple
    // of sixteen, as the aligned loads at every sixteenth one need; the
    // outputs are sixteen lanes each, written unaligned; the rest is
    // arithmetic on registers.
    let found = unsafe {
        let load = |l: &Lanes| _mm512_load_ps(l.0.as_ptr().add(16 * h));
        let [ox, oy, oz] = [load(&soa.o[kx]), load(&soa.o[ky]), load(&soa.o[kz])];
        let [s0, s1, s2] = [
            load(&soa.shear[0]),
            load(&soa.shear[1]),
            load(&soa.shear[2]),
        ];
        let t_max = load(best_t);
        let zero = _mm512_setzero_ps();
        let one = _mm512_set1_ps(1.0);
        let lt = |a, b| _mm512_cmp_ps_mask::<_CMP_LT_OS>(a, b);
        let mut run_t = t_max;
        let mut run_b1 = zero;
        let mut run_b2 = zero;
        let mut run_k = _mm512_set1_epi32(-1);
        let lanes = block.lanes();
        for j in 0..4 {
            if lanes & 1 << j == 0 {
                continue;
            }
            let at = |corner: usize, axis: usize| block.p[[kx, ky, kz][axis]][corner].as_ref()[j];
            let (hit, t_scaled, det, v, w) = crossing!(
                [ox, oy, oz], [s0, s1, s2], at, t_max, AT_ORIGIN;
                _mm512_set1_ps, _mm512_sub_ps, _mm512_mul_ps, _mm512_add_ps, zero,
                lt,
                |a, b| _mm512_cmp_ps_mask::<_CMP_GT_OS>(a, b),
                |a, b| _mm512_cmp_ps_mask::<_CMP_NEQ_UQ>(a, b),
                |a: u16, b: u16| a | b,
                |a: u16, b: u16| a & b,
                |a: u16, b: u16| !a & b
            );
            if u32::from(hit) & m16 == 0 {
                continue;
            }
            let inv_det = _mm512_div_ps(one, det);
            let t = _mm512_mul_ps(t_scaled, inv_det);
            let keep = hit & lt(t, run_t);
            run_t = _mm512_mask_blend_ps(keep, run_t, t);
            run_b1 = _mm512_mask_blend_ps(keep, run_b1, _mm512_mul_ps(v, inv_det));
            run_b2 = _mm512_mask_blend_ps(keep, run_b2, _mm512_mul_ps(w, inv_det));
            run_k = _mm512_mask_blend_epi32(keep, run_k, _mm512_set1_epi32(j as i32));
        }
        let found = u32::from(_mm512_cmpge_epi32_mask(run_k, _mm512_setzero_si512())) & m16;
        if found != 0 {
            _mm512_storeu_ps(out[0].as_mut_ptr(), run_t);
            _mm512_storeu_ps(out[1].as_mut_ptr(), run_b1);
            _mm512_storeu_ps(out[2].as_mut_ptr(), run_b2);
            _mm512_storeu_si512(which.as_mut_ptr().cast(), run_k);
        }
        found
    };
    let prim = |i: usize| block.prims[which[i] as usize];
    keep_hits((h, found), &out, prim, best, best_t)
}
