//! The packet traversal: the wide tree opened once for all the packet's
//! rays, compiled for SSE, AVX2 or AVX-512 and chosen at run time.

#[cfg(target_arch = "x86_64")]
use super::avx2::{children_avx2, hit_block_octet, hit_triangle_octet};
#[cfg(target_arch = "x86_64")]
use super::avx512::{children_avx512, hit_block_sixteen};
use super::lanes::*;
use super::sse::children_sse;
use crate::bvh::wide;
use crate::cpu::simd::prefetch_child;
use crate::cpu::trace::{hit_leaf, hit_triangle, CpuScene, Hit, Ray, NO_HIT};
use crate::cpu::Real;
use crate::layout::SPHERE_BIT;
use crate::methods::Methods;
use glam::Vec4;

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
    let soa = Soa::new(rays);
    let query = Query {
        soa: &soa,
        active,
        t_max,
        at_origin: false,
    };
    run(scene, query, any_hit)
}

/// `traverse` for the rays `make_rays` made, already in lanes; when
/// `at_origin`, every ray's origin is (+0, +0, +0).
pub(super) fn traverse_packet(
    scene: &CpuScene<f32>,
    soa: &Soa,
    active: u32,
    t_max: f32,
    any_hit: bool,
    at_origin: bool,
) -> [Hit<f32>; WIDTH] {
    debug_assert!(!at_origin || soa.o.iter().all(|o| o.0.iter().all(|x| x.to_bits() == 0)));
    let query = Query {
        soa,
        active,
        t_max,
        at_origin,
    };
    run(scene, query, any_hit)
}

/// `query` through the traversal compiled for the widest instructions
/// the CPU has.
fn run(scene: &CpuScene<f32>, query: Query, any_hit: bool) -> [Hit<f32>; WIDTH] {
    // Rays from the origin skip subtracting it (closest hits only: the
    // packets that start there are the primary rays).
    let at_origin = query.at_origin && !any_hit;
    #[cfg(target_arch = "x86_64")]
    if crate::cpu::simd::has_avx512() {
        // SAFETY: the CPU has AVX-512F and the bit instructions
        // (`has_avx512`), checked just above.
        return unsafe {
            match (any_hit, at_origin) {
                (true, _) => traverse_avx512::<true, false>(scene, query),
                (false, true) => traverse_avx512::<false, true>(scene, query),
                (false, false) => traverse_avx512::<false, false>(scene, query),
            }
        };
    }
    #[cfg(target_arch = "x86_64")]
    if crate::cpu::simd::has_avx2() {
        // SAFETY: the CPU has AVX2 and the bit instructions (`has_avx2`),
        // checked just above.
        return unsafe {
            match (any_hit, at_origin) {
                (true, _) => traverse_avx2::<true, false>(scene, query),
                (false, true) => traverse_avx2::<false, true>(scene, query),
                (false, false) => traverse_avx2::<false, false>(scene, query),
            }
        };
    }
    match (any_hit, at_origin) {
        (true, _) => traverse_with::<SSE, true, false>(scene, query),
        (false, true) => traverse_with::<SSE, false, true>(scene, query),
        (false, false) => traverse_with::<SSE, false, false>(scene, query),
    }
}

/// `traverse_with`'s instruction sets, least first.
pub(super) const SSE: u8 = 0;
pub(super) const AVX2: u8 = 1;
pub(super) const AVX512: u8 = 2;

/// `traverse_with` compiled for AVX2, so its box tests inline.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
pub(super) fn traverse_avx2<const ANY_HIT: bool, const AT_ORIGIN: bool>(
    scene: &CpuScene<f32>,
    query: Query,
) -> [Hit<f32>; WIDTH] {
    traverse_with::<AVX2, ANY_HIT, AT_ORIGIN>(scene, query)
}

/// `traverse_with` compiled for AVX-512: its box tests take sixteen rays a
/// register, and its leaf tests too where two octets share an axis order.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,bmi1,bmi2,lzcnt,popcnt")]
pub(super) fn traverse_avx512<const ANY_HIT: bool, const AT_ORIGIN: bool>(
    scene: &CpuScene<f32>,
    query: Query,
) -> [Hit<f32>; WIDTH] {
    traverse_with::<AVX512, ANY_HIT, AT_ORIGIN>(scene, query)
}

/// `traverse`, its box tests 8 rays at a time with AVX2 when `SIMD` is
/// `AVX2` and 16 with AVX-512 when it is `AVX512` (only ever so inside
/// `traverse_avx2` and `traverse_avx512`), for blockers when `ANY_HIT`.
///
/// An any-hit ray's limit stays `t_max` until it is blocked and leaves, so
/// no box it passed can later lie beyond its limit, and whether it is
/// blocked does not depend on the order it meets leaves in: there the
/// entry t that order and dropping need is not computed.
///
/// `AT_ORIGIN` (every ray leaves from (+0, +0, +0), as primary rays do):
/// the box and triangle tests skip subtracting the origin, since x - 0
/// is x to the bit. 2M grid, callgrind, one render: 1,122.8 M -> 1,090.9
/// M instructions.
#[inline(always)]
pub(super) fn traverse_with<const SIMD: u8, const ANY_HIT: bool, const AT_ORIGIN: bool>(
    scene: &CpuScene<f32>,
    query: Query,
) -> [Hit<f32>; WIDTH] {
    let Query {
        soa, active, t_max, ..
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
                let ray = soa.ray(r);
                crate::cpu::trace::traverse_below(scene, &ray, index, &mut best[r], ANY_HIT);
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
        // where `has_avx512` holds, and AVX2 only in `traverse_avx2`, which
        // runs only where `has_avx2` does.
        if SIMD == AVX512 {
            unsafe { children_avx512::<ANY_HIT, AT_ORIGIN>(node, soa, mask, &best_t, &mut kids) }
        } else if SIMD == AVX2 {
            unsafe { children_avx2::<ANY_HIT, AT_ORIGIN>(node, soa, mask, &best_t, &mut kids) }
        } else {
            children_sse::<ANY_HIT, AT_ORIGIN>(node, soa, mask, &best_t, &mut kids)
        };
        #[cfg(not(target_arch = "x86_64"))]
        children_sse::<ANY_HIT, AT_ORIGIN>(node, soa, mask, &best_t, &mut kids);
        let Children {
            hits,
            ref near,
            nearest,
        } = kids;
        let (order, n) = if ANY_HIT {
            hit_lanes_in_order(hits)
        } else {
            hit_lanes_nearest_first(hits, nearest)
        };
        // Nodes onto the stack first, farthest first, so the nearest is
        // next, and each starts loading with its own leaf blocks, nearest
        // first (the loads queue behind one another; 2M grid, thread CPU
        // 146.3-147.6 -> 143.0-145.5 ms): the next node arrives while this
        // one's leaves are tested, and its leaves with it (this node's
        // were started when it was pushed). The leaves cannot see the
        // stack, so the order of work is as if they came first.
        for &lane in order[..n].iter().rev() {
            let child = node.child[lane];
            if child & wide::LEAF == 0 {
                // Indexed with a bounds check: `wide::STACK` bounds the depth.
                stack[len] = std::mem::MaybeUninit::new((child, hits[lane], nearest[lane]));
                len += 1;
            }
        }
        for &lane in &order[..n] {
            if node.child[lane] & wide::LEAF == 0 {
                prefetch_child(scene.wide, node, lane);
            }
        }
        // Leaves are tested as they come, nearest first.
        for &lane in &order[..n] {
            let child = node.child[lane];
            if child & wide::LEAF == 0 {
                continue;
            }
            let index = (child & !wide::LEAF) as usize;
            // The rays that reached it and have not found a hit nearer than
            // their entry since.
            let mut rays_in = hits[lane] & live;
            if !ANY_HIT {
                for h in 0..QUADS {
                    let late = near[lane].quad(h).cmpgt(best_t.quad(h) * scale).bitmask();
                    rays_in &= !(late << (4 * h));
                }
            }
            let packet = Packet {
                soa,
                best: &mut best,
                best_t: &mut best_t,
                live: &mut live,
            };
            test_leaf::<SIMD, ANY_HIT, AT_ORIGIN>(scene, index, rays_in, simd_leaves, packet);
            if live == 0 {
                return best;
            }
        }
    }
    best
}

/// The lanes some ray hit, nearest first (by their nearest ray, then by
/// lane; in lane order for any-hit rays, whose entries stay +inf), and
/// how many there are. A sorting network on keys that order as (missed,
/// nearest, lane) do: whether a box was hit is the branch the predictor
/// missed most in the walk, and the network has none.
#[inline(always)]
pub(super) fn hit_lanes_nearest_first(hits: [u32; 4], nearest: [f32; 4]) -> ([usize; 4], usize) {
    // A nearest entry is never negative or NaN (`t_near` is at least 0,
    // and a NaN is never chosen), so its bits order as its value.
    let mut key: [u64; 4] = std::array::from_fn(|lane| {
        (u64::from(hits[lane] == 0) << 40) | (u64::from(nearest[lane].to_bits()) << 2) | lane as u64
    });
    for (a, b) in [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)] {
        let (lo, hi) = (key[a].min(key[b]), key[a].max(key[b]));
        key[a] = lo;
        key[b] = hi;
    }
    let n = hits.iter().filter(|&&h| h != 0).count();
    (key.map(|k| (k & 3) as usize), n)
}

/// `hit_lanes_nearest_first` where every entry is +inf (an any-hit walk):
/// the hit lanes in lane order, then the others, from a table on the
/// four-bit mask of hit lanes instead of the sorting network (1.1% of
/// the packets' instructions on the 240k grid, by callgrind).
#[inline(always)]
pub(super) fn hit_lanes_in_order(hits: [u32; 4]) -> ([usize; 4], usize) {
    const ORDER: [[u8; 4]; 16] = {
        let mut table = [[0u8; 4]; 16];
        let mut mask = 0;
        while mask < 16 {
            let mut at = 0;
            // The hit lanes, then the missed ones, each in lane order.
            let mut pass = 0;
            while pass < 2 {
                let mut lane = 0;
                while lane < 4 {
                    if (mask >> lane & 1 == 1) == (pass == 0) {
                        table[mask][at] = lane as u8;
                        at += 1;
                    }
                    lane += 1;
                }
                pass += 1;
            }
            mask += 1;
        }
        table
    };
    let mask = usize::from(hits[0] != 0)
        | usize::from(hits[1] != 0) << 1
        | usize::from(hits[2] != 0) << 2
        | usize::from(hits[3] != 0) << 3;
    (ORDER[mask].map(usize::from), mask.count_ones() as usize)
}

/// One packet's state as a leaf is tested: its rays, their lanes, each
/// ray's hit so far (and its distance in lanes), and the rays still looking.
struct Packet<'a> {
    soa: &'a Soa,
    best: &'a mut [Hit<f32>; WIDTH],
    best_t: &'a mut Lanes,
    live: &'a mut u32,
}

/// The rays `rays_in` against leaf `index`'s primitives: as one SIMD block
/// where `simd_leaves` and the leaf is one (an octet of rays at a time
/// where they share an axis order, else ray by ray), each ray alone where
/// not `simd_leaves`, else primitive by primitive for all of them.
#[inline(always)]
fn test_leaf<const SIMD: u8, const ANY_HIT: bool, const AT_ORIGIN: bool>(
    scene: &CpuScene<f32>,
    index: usize,
    mut rays_in: u32,
    simd_leaves: bool,
    p: Packet,
) {
    let leaf = &scene.wide.leaves[index];
    if !simd_leaves {
        // As a single ray's, one ray at a time.
        while rays_in != 0 {
            let r = rays_in.trailing_zeros() as usize;
            rays_in &= rays_in - 1;
            let ray = p.soa.ray(r);
            let done = hit_leaf(scene, &ray, index, &mut p.best[r], ANY_HIT, &[], 0.0);
            p.best_t.0[r] = p.best[r].t;
            if done {
                *p.live &= !(1 << r);
            }
        }
    } else if leaf.simd() {
        // `hit_leaf`'s own first branch, inlined here: across an
        // octet's rays where they share an axis order and enough
        // of them came, else ray by ray.
        #[cfg(target_arch = "x86_64")]
        if SIMD >= AVX2 {
            let soa = p.soa;
            if SIMD == AVX512 {
                soa.take_sixteens(&mut rays_in, |h, k, m16| {
                    // SAFETY: SIMD is AVX512 only in `traverse_avx512`,
                    // which runs only where `has_avx512` holds.
                    let found = unsafe {
                        hit_block_sixteen::<AT_ORIGIN>(leaf, soa, k, h, m16, p.best, p.best_t)
                    };
                    if ANY_HIT {
                        *p.live &= !found;
                    }
                });
            }
            soa.take_octets(&mut rays_in, |g, k, m8| {
                // SAFETY: SIMD is AVX2 or more only in
                // `traverse_avx2` and `traverse_avx512`, which run
                // only where `has_avx2` holds (`has_avx512` implies it).
                let found =
                    unsafe { hit_block_octet::<AT_ORIGIN>(leaf, soa, k, g, m8, p.best, p.best_t) };
                if ANY_HIT {
                    *p.live &= !found;
                }
            });
        }
        while rays_in != 0 {
            let r = rays_in.trailing_zeros() as usize;
            rays_in &= rays_in - 1;
            let ray = p.soa.ray(r);
            if let Some((k, t, b1, b2)) =
                crate::cpu::simd::hit_block_f32(ray.origin, ray.k, ray.shear, leaf, p.best[r].t)
            {
                let prim = leaf.prims[k];
                p.best[r] = Hit { t, prim, b1, b2 };
                p.best_t.0[r] = t;
                if ANY_HIT {
                    *p.live &= !(1 << r);
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
                let t = hit_sphere_rays(p.soa, &scene.spheres[index], p.best_t);
                let mut hit = rays_in;
                while hit != 0 {
                    let r = hit.trailing_zeros() as usize;
                    hit &= hit - 1;
                    if t.0[r] < p.best[r].t {
                        p.best[r] = Hit {
                            t: t.0[r],
                            prim,
                            b1: 0.0,
                            b2: 0.0,
                        };
                        p.best_t.0[r] = t.0[r];
                        if ANY_HIT {
                            *p.live &= !(1 << r);
                            rays_in &= !(1 << r);
                        }
                    }
                }
            } else {
                let tri = &scene.triangles[index];
                let mut each = rays_in;
                // Across an octet's rays where they share an axis order and
                // enough of them came, as a SIMD block's triangles.
                #[cfg(target_arch = "x86_64")]
                if SIMD >= AVX2 {
                    let soa = p.soa;
                    soa.take_octets(&mut each, |g, k, m8| {
                        // SAFETY: SIMD is AVX2 or more only in
                        // `traverse_avx2` and `traverse_avx512`, which run
                        // only where `has_avx2` holds.
                        let found = unsafe {
                            hit_triangle_octet::<AT_ORIGIN>(
                                tri,
                                prim,
                                soa,
                                (k, g, m8),
                                p.best,
                                p.best_t,
                            )
                        };
                        if ANY_HIT {
                            *p.live &= !found;
                            rays_in &= !found;
                        }
                    });
                }
                while each != 0 {
                    let r = each.trailing_zeros() as usize;
                    each &= each - 1;
                    let (t, b1, b2) = hit_triangle(&p.soa.ray(r), tri, p.best[r].t);
                    if t < p.best[r].t {
                        p.best[r] = Hit { t, prim, b1, b2 };
                        p.best_t.0[r] = t;
                        if ANY_HIT {
                            *p.live &= !(1 << r);
                            rays_in &= !(1 << r);
                        }
                    }
                }
            }
        }
    }
}
