//! The CPU reference's view of the BVH: the shared binary tree collapsed to
//! four children a node, whose four boxes one SIMD test checks at once (on
//! f32; f64 tests them one by one, with the same arithmetic).
//!
//! The boxes are the binary tree's own f32 boxes, tested with the same
//! formula as `trace::hit_aabb`, so a ray reaches exactly the leaves it
//! would reach there: closest and any hits are the ones the shader finds,
//! up to which of two hits at exactly the same t is kept (the earlier in a
//! fixed order, so still deterministic).

use glam::Vec4;

use crate::bvh::Bvh;
use crate::layout::GpuBvhNode;

/// `Node4::child` of a lane that holds a leaf: this bit plus the index of
/// its first primitive reference.
pub const LEAF: u32 = 1 << 31;
/// `Node4::child` of an unused lane (its box is at +infinity, so no ray
/// hits it; see `Node4::EMPTY`).
pub const EMPTY: u32 = u32::MAX;

/// Four children: their boxes by axis and lane (`lo[axis][lane]`), then per
/// lane a node index, `LEAF | first`, or `EMPTY`, and a leaf's primitive
/// count. 128 bytes, two cache lines.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Node4 {
    pub lo: [Vec4; 3],
    pub hi: [Vec4; 3],
    pub child: [u32; 4],
    pub count: [u32; 4],
}

impl Node4 {
    /// A box at +infinity on every axis: t = ±inf on each slab, which
    /// either puts the entry at +inf or the exit at -inf, a miss for any
    /// ray whose inverse direction is finite and non-zero (`make_ray`).
    const EMPTY: Node4 = Node4 {
        lo: [Vec4::INFINITY; 3],
        hi: [Vec4::INFINITY; 3],
        child: [EMPTY; 4],
        count: [0; 4],
    };

    pub fn lane_box(&self, lane: usize) -> ([f32; 3], [f32; 3]) {
        (
            [0, 1, 2].map(|a| self.lo[a][lane]),
            [0, 1, 2].map(|a| self.hi[a][lane]),
        )
    }
}

/// Deepest a collapsed tree's stack gets: each node visited pushes at most
/// four entries and pops one, and the tree is no deeper than the binary one.
pub const STACK: usize = 3 * crate::layout::BVH_MAX_DEPTH as usize + 4;

/// The binary tree collapsed: each node takes the two children of a binary
/// node and keeps opening the child with the largest box (the likeliest to
/// be entered) until it has four or only leaves. Node 0 is the root; empty
/// for an empty tree.
pub fn collapse(bvh: &Bvh) -> Vec<Node4> {
    let mut out = Vec::with_capacity(bvh.nodes.len() / 3 + 1);
    if !bvh.nodes.is_empty() {
        collapse_node(&bvh.nodes, 0, &mut out);
    }
    out
}

fn collapse_node(bin: &[GpuBvhNode], index: usize, out: &mut Vec<Node4>) -> u32 {
    let slot = out.len();
    out.push(Node4::EMPTY);
    let interior = |i: usize| bin[i].count == 0;
    let area = |i: usize| {
        let n = &bin[i];
        let d = [0, 1, 2].map(|a| f64::from(n.max[a] - n.min[a]).max(0.0));
        d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
    };
    let mut kids: Vec<usize> = if interior(index) {
        vec![index + 1, bin[index].right_or_first as usize]
    } else {
        // A tree that is one leaf.
        vec![index]
    };
    while kids.len() < 4 {
        let widest = kids
            .iter()
            .enumerate()
            .filter(|&(_, &k)| interior(k))
            .max_by(|a, b| area(*a.1).total_cmp(&area(*b.1)))
            .map(|(lane, _)| lane);
        let Some(lane) = widest else { break };
        let k = kids[lane];
        // In place, so the children keep the binary tree's left-right order.
        kids.splice(lane..=lane, [k + 1, bin[k].right_or_first as usize]);
    }
    let mut node = Node4::EMPTY;
    for (lane, &k) in kids.iter().enumerate() {
        for a in 0..3 {
            node.lo[a][lane] = bin[k].min[a];
            node.hi[a][lane] = bin[k].max[a];
        }
        if interior(k) {
            node.child[lane] = collapse_node(bin, k, out);
        } else {
            node.child[lane] = LEAF | bin[k].right_or_first;
            node.count[lane] = bin[k].count;
        }
    }
    out[slot] = node;
    slot as u32
}

/// The four boxes of `node` against a ray from `origin` with `inv_dir`,
/// in f32 SIMD lanes: a bit per lane hit before `t_max`, and the entry t
/// per lane. Operation for operation `trace::hit_aabb`.
#[inline(always)]
pub fn hit_boxes_f32(
    origin: glam::Vec3,
    inv_dir: glam::Vec3,
    node: &Node4,
    t_max: f32,
    box_t_scale: f32,
) -> (u32, [f32; 4]) {
    let slab = |axis: usize, o: f32, inv: f32| {
        let t0 = (node.lo[axis] - Vec4::splat(o)) * Vec4::splat(inv);
        let t1 = (node.hi[axis] - Vec4::splat(o)) * Vec4::splat(inv);
        (t0.min(t1), t0.max(t1))
    };
    let (nx, fx) = slab(0, origin.x, inv_dir.x);
    let (ny, fy) = slab(1, origin.y, inv_dir.y);
    let (nz, fz) = slab(2, origin.z, inv_dir.z);
    let t_near = nx.max(ny).max(nz.max(Vec4::ZERO));
    let t_far = fx.min(fy).min(fz.min(Vec4::splat(t_max))) * Vec4::splat(box_t_scale);
    (t_near.cmple(t_far).bitmask(), t_near.to_array())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Material, Scene, Triangle, Vertex};
    use glam::DVec3;

    fn scene(n: usize) -> Scene {
        let mut state = 7u32;
        let mut next = || {
            state = crate::cpu::sample::hash_u32(state);
            f64::from(state) / f64::from(u32::MAX) * 20.0 - 10.0
        };
        let mut scene = Scene::default();
        let m = scene.add_material(Material {
            kd: DVec3::ONE,
            ks: DVec3::ZERO,
            shininess: 1.0,
        });
        for _ in 0..n {
            let c = DVec3::new(next(), next(), next() - 20.0);
            let vertices = [0.0, 0.5, 1.0].map(|d| Vertex {
                position: c + DVec3::new(d * next(), d * next(), d),
                normal: DVec3::Z,
                material: m,
            });
            scene.triangles.push(Triangle {
                vertices,
                velocity: DVec3::ZERO,
            });
        }
        scene
    }

    /// Every binary leaf appears once, under boxes that are the binary
    /// tree's own.
    #[test]
    fn collapse_keeps_every_leaf_and_box() {
        for n in [1, 2, 3, 5, 100, 3000] {
            let bvh = Bvh::build(&scene(n));
            let wide = collapse(&bvh);
            let mut leaves: Vec<(u32, u32, [f32; 3], [f32; 3])> = Vec::new();
            for node in &wide {
                for lane in 0..4 {
                    let (lo, hi) = node.lane_box(lane);
                    match node.child[lane] {
                        EMPTY => assert!(lo[0].is_infinite() && node.count[lane] == 0),
                        c if c & LEAF != 0 => leaves.push((c & !LEAF, node.count[lane], lo, hi)),
                        c => {
                            // The child's lanes fit inside this lane's box.
                            let child = &wide[c as usize];
                            for l in 0..4 {
                                if child.child[l] == EMPTY {
                                    continue;
                                }
                                let (clo, chi) = child.lane_box(l);
                                for a in 0..3 {
                                    assert!(clo[a] >= lo[a] && chi[a] <= hi[a]);
                                }
                            }
                        }
                    }
                }
            }
            leaves.sort_by_key(|l| l.0);
            let mut want: Vec<_> = bvh
                .nodes
                .iter()
                .filter(|n| n.count > 0)
                .map(|n| (n.right_or_first, n.count, n.min, n.max))
                .collect();
            want.sort_by_key(|l| l.0);
            assert_eq!(leaves, want, "{n} triangles");
            assert!(wide.len() <= bvh.nodes.len() / 2 + 1);
        }
    }

    /// Closest and any hits through the collapsed tree are those of testing
    /// every primitive, in both precisions.
    #[test]
    fn traversal_finds_what_testing_everything_finds() {
        use crate::cpu::trace::{hit_triangle, make_ray, traverse, CpuScene};
        use crate::cpu::{CpuOptions, Real};
        fn check<R: Real>(scene: &Scene, bvh: &Bvh) {
            let camera = crate::camera::Camera::new(64, 48);
            let cpu = CpuScene::<R>::new(scene, bvh, &camera, &CpuOptions::default());
            let mut state = 11u32;
            let mut next = || {
                state = crate::cpu::sample::hash_u32(state);
                R::from_f64(f64::from(state) / f64::from(u32::MAX) * 2.0 - 1.0)
            };
            let (mut hits, mut blocked) = (0, 0);
            for _ in 0..3000 {
                let origin = R::v3(next(), next(), next() * R::from_f64(4.0));
                let dir = R::normalize(R::v3(next(), next(), next() - R::ONE));
                let ray = make_ray(origin, dir, R::ZERO);
                let brute = cpu
                    .triangles
                    .iter()
                    .map(|t| hit_triangle(&ray, t, R::T_INF).0)
                    .fold(R::T_INF, |a, b| if b < a { b } else { a });
                let hit = traverse(&cpu, &ray, R::T_INF, false, &[], R::ZERO);
                assert_eq!(hit.t.to_f64(), brute.to_f64());
                hits += usize::from(hit.prim != u32::MAX);
                // A shadow ray of a random length up to 40.
                let end = (next() + R::ONE) * R::from_f64(20.0);
                let shadow = make_ray(origin, dir * end, R::ZERO);
                let any = traverse(&cpu, &shadow, R::ONE, true, &[], R::ZERO);
                let brute_any = cpu
                    .triangles
                    .iter()
                    .any(|t| hit_triangle(&shadow, t, R::ONE).0 < R::ONE);
                assert_eq!(any.prim != u32::MAX, brute_any);
                blocked += usize::from(brute_any);
            }
            assert!(hits > 300 && blocked > 30, "{hits} hits, {blocked} blocked");
            // NaN directions pass every box test, unused lanes included.
            let nan = R::from_f64(f64::NAN);
            let ray = make_ray(R::v3(R::ZERO, R::ZERO, R::ZERO), R::v3(nan, nan, nan), R::ZERO);
            assert_eq!(traverse(&cpu, &ray, R::T_INF, false, &[], R::ZERO).prim, u32::MAX);
        }
        let scene = scene(2000);
        let bvh = Bvh::build(&scene);
        check::<f32>(&scene, &bvh);
        check::<f64>(&scene, &bvh);
    }

    /// The SIMD test gives each lane what the scalar test gives its box.
    #[test]
    fn simd_boxes_match_the_scalar_test() {
        use crate::cpu::trace::{hit_aabb, make_ray};
        use crate::cpu::Real;
        let wide = collapse(&Bvh::build(&scene(500)));
        let mut state = 3u32;
        let mut next = || {
            state = crate::cpu::sample::hash_u32(state);
            f32::from_bits(state >> 9 | 0x3f80_0000) * 2.0 - 3.0
        };
        for _ in 0..2000 {
            let origin = glam::Vec3::new(next(), next(), next()) * 4.0;
            let dir = glam::Vec3::new(next(), next(), next() - 1.0).normalize();
            let ray = make_ray::<f32>(origin, dir, 0.0);
            let t_max = if next() > 0.0 {
                f32::MAX
            } else {
                next() + 20.0
            };
            for node in &wide {
                let (mask, t) =
                    hit_boxes_f32(ray.origin, ray.inv_dir, node, t_max, f32::BOX_T_SCALE);
                for (lane, t) in t.iter().enumerate() {
                    let (lo, hi) = node.lane_box(lane);
                    let scalar = hit_aabb(&ray, lo, hi, t_max);
                    let hit = scalar != f32::T_INF;
                    assert_eq!(mask & (1 << lane) != 0, hit, "lane {lane}");
                    if hit {
                        assert_eq!(*t, scalar);
                    }
                }
            }
        }
    }
}
