//! A node's four boxes against a packet with SSE (glam's `Vec4`), four
//! rays a register: the instruction set every x86-64 CPU has, and the
//! arithmetic the wider ones repeat lane for lane.

use super::lanes::*;
use crate::bvh::wide;
use crate::cpu::Real;
use glam::Vec4;

/// `Children` with SSE (glam's `Vec4`), four rays at a time: each lane is
/// `wide::hit_boxes_f32`'s arithmetic for its ray, operation for operation.
#[inline(always)]
pub(super) fn children_sse<const ANY_HIT: bool, const AT_ORIGIN: bool>(
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
                // x - 0 is x, to the bit: rays from the origin skip it.
                let rel = |x: f32| {
                    if AT_ORIGIN {
                        Vec4::splat(x)
                    } else {
                        Vec4::splat(x) - o
                    }
                };
                let t0 = rel(node.lo[axis].as_ref()[lane]) * inv;
                let t1 = rel(node.hi[axis].as_ref()[lane]) * inv;
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
