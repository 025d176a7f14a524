//! The wide tree's traversal for the closest hit or any blocker (the
//! shader's `traverse.wgsl`): a leaf's primitives, the walk with its
//! stack, and the grazing band of shadow rays towards lights on surfaces.

use crate::bvh::wide::{self};
use crate::cpu::real::Real;
use crate::cpu::simd::prefetch_child;
use crate::layout::SPHERE_BIT;
use crate::methods::Methods;

use super::hit::*;
use super::scene::*;
use crate::cpu::real::Ray;

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

/// The lanes of `node` in `hits` that hold a child, farthest first (and
/// at equal entries `t`, the lower lane first), and how many: the order
/// the hit lanes go onto the stack, so that the nearest is popped next.
/// The shader's `traverse` keeps the same order (its `order`,
/// `append_hit`). In f32, a sorting network on keys that order as (hit,
/// t, 3 - lane) do, largest first: which boxes a ray hits is the branch
/// an insertion sort mispredicts.
#[inline(always)]
fn nearest_last<R: Real>(node: &wide::Node4, hits: u32, t: &[R; 4]) -> ([usize; 4], usize) {
    // A ray with a NaN direction passes every box test, even an unused
    // lane's (and then hits no primitive).
    let mut used = 0;
    for (lane, &child) in node.child.iter().enumerate() {
        used |= u32::from(child != wide::EMPTY) << lane;
    }
    let hits = hits & used;
    let n = hits.count_ones() as usize;
    if let [Some(k0), Some(k1), Some(k2), Some(k3)] = t.map(R::entry_key) {
        let mut key = [k0, k1, k2, k3];
        for (lane, key) in key.iter_mut().enumerate() {
            *key = u64::from(hits >> lane & 1) << 40 | *key << 2 | (3 - lane) as u64;
        }
        for (a, b) in [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)] {
            let (hi, lo) = (key[a].max(key[b]), key[a].min(key[b]));
            key[a] = hi;
            key[b] = lo;
        }
        return (key.map(|k| 3 - (k & 3) as usize), n);
    }
    let mut lanes = [0usize; 4];
    let mut n = 0;
    let mut mask = hits;
    while mask != 0 {
        let lane = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        let mut i = n;
        while i > 0 && t[lanes[i - 1]] < t[lane] {
            lanes[i] = lanes[i - 1];
            i -= 1;
        }
        lanes[i] = lane;
        n += 1;
    }
    (lanes, n)
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
        let (mask, t) = R::hit_boxes(ray, node, best.t);
        let (lanes, n) = nearest_last(node, mask, &t);
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

#[cfg(test)]
mod tests {
    use super::nearest_last;
    use crate::bvh::wide::{Node4, EMPTY, LEAF};
    use glam::Vec4;

    /// The f32 sorting network stacks a node's lanes in the insertion
    /// sort's order (f64's, the shader's): every hit mask, unused lanes,
    /// and entries drawn from few values, so that ties are common.
    #[test]
    fn the_sorting_network_keeps_the_insertion_sorts_order() {
        let values = [0.0f32, 0.5, 0.5, 3.0, f32::INFINITY];
        let mut ties = 0;
        let mut checked = 0;
        for code in 0..5u32.pow(4) {
            let t: [f32; 4] =
                std::array::from_fn(|i| values[(code / 5u32.pow(i as u32) % 5) as usize]);
            for unused in 0..16u32 {
                let node = Node4 {
                    lo: [Vec4::ZERO; 3],
                    hi: [Vec4::ONE; 3],
                    child: std::array::from_fn(|i| {
                        if unused >> i & 1 == 1 {
                            EMPTY
                        } else {
                            LEAF | i as u32
                        }
                    }),
                    leaves: [0; 4],
                };
                for hits in 0..16u32 {
                    let (lanes, n) = nearest_last(&node, hits, &t);
                    let (want, m) = nearest_last(&node, hits, &t.map(f64::from));
                    assert_eq!(n, m, "t {t:?} hits {hits:04b} unused {unused:04b}");
                    assert_eq!(
                        lanes[..n],
                        want[..m],
                        "t {t:?} hits {hits:04b} unused {unused:04b}"
                    );
                    let used: Vec<f32> = lanes[..n].iter().map(|&l| t[l]).collect();
                    ties += used.windows(2).filter(|w| w[0] == w[1]).count();
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 625 * 16 * 16);
        // Ties were there to be broken.
        assert!(ties > 10_000, "{ties} ties");
    }
}
