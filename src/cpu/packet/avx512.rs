//! The packet's box tests sixteen rays a register (AVX-512F); its leaf
//! tests stay AVX2's octets.

#[cfg(target_arch = "x86_64")]
use super::avx2::box_entry_exit;
use super::lanes::*;
use crate::bvh::wide;
use crate::cpu::Real;

/// `children_sse` with AVX-512, sixteen rays at a time: the same
/// operations lane for lane as `children_avx2` (`vminps` and `vmaxps` treat
/// NaNs alike at every width, and `<=` is the same ordered compare, here
/// into a mask register), so each ray gets the same answer to the bit. The
/// nearest entry is a masked reduction over rays that passed, whose entries
/// are never NaN, so its order does not matter.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
pub(super) fn children_avx512<const ANY_HIT: bool>(
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
