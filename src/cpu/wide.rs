//! The CPU reference's view of the BVH: the shared binary tree collapsed to
//! four children a node, whose four boxes one SIMD test checks at once
//! (`Vec4` lanes in f32, `DVec4` in f64, each lane `hit_aabb`'s arithmetic),
//! and its leaves, whose up to four triangles meet one SIMD watertight test
//! in f32.
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
/// its `LeafBlock` (the shader's tree, collapsed by the same code, puts its
/// first primitive reference there instead). One constant for both trees:
/// `layout::GpuScene::pack` copies the child words as they are.
pub const LEAF: u32 = crate::layout::WIDE_LEAF;
/// `Node4::child` of an unused lane (its box is at +infinity, so no ray
/// hits it; see `Node4::EMPTY`); the shader's `WIDE_EMPTY`.
pub const EMPTY: u32 = crate::layout::WIDE_EMPTY;

/// Four children: their boxes by axis and lane (`lo[axis][lane]`), then per
/// lane a node index, `LEAF | block`, or `EMPTY`, and, for a node child,
/// where that child's own leaf blocks lie (`Node4::leaf_run`). 128 bytes,
/// two whole cache lines.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Node4 {
    pub lo: [Vec4; 3],
    pub hi: [Vec4; 3],
    pub child: [u32; 4],
    /// Per node lane: the first of the child's leaf blocks, times
    /// `RUN_LEN`, plus how many there are (they lie together, `collapse`).
    /// So a traversal that pushes the child can start loading its leaves
    /// with it, and meets them loaded when it opens the child, instead of
    /// waiting on one load after the other. 0 elsewhere, and in the
    /// shader's tree, which does not use it.
    pub leaves: [u32; 4],
}

/// A leaf's triangles for the SIMD test, when it holds up to four
/// triangles: their corners by axis, corner and lane (`p[axis][corner]
/// [lane]`, f32), so that one SIMD watertight test meets all four
/// (`hit_block_f32`), and their primitive references, so that a hit needs
/// no other load. Unused lanes' references are `NONE`, and all are in a
/// leaf the SIMD test does not take (`simd`). 160 bytes, aligned to 32
/// so that every block lies on three cache lines: aligned to 16, as its
/// vectors alone ask, a list of them can start 16 bytes into a line (as
/// glibc's large allocations do), and then every other block spans four
/// (cachegrind, 2M grid: the traversal's D1 read misses 2.9 -> 2.7 M).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct LeafBlock {
    pub p: [[Vec4; 3]; 3],
    pub prims: [u32; 4],
}

/// `LeafBlock::prims` of an unused lane.
pub const NONE: u32 = u32::MAX;

/// A leaf's primitive references: `prim_refs[first..first + count]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LeafSpan {
    pub first: u32,
    pub count: u32,
}

impl LeafSpan {
    /// The leaf's indices into `prim_refs`.
    #[inline(always)]
    pub fn range(self) -> std::ops::Range<usize> {
        self.first as usize..(self.first + self.count) as usize
    }
}

/// The collapsed tree: nodes (root first) and their leaves, each a block
/// and a span at the same index.
#[derive(Clone, Debug, Default)]
pub struct WideBvh {
    pub nodes: Vec<Node4>,
    pub leaves: Vec<LeafBlock>,
    pub spans: Vec<LeafSpan>,
}

impl LeafBlock {
    const EMPTY: LeafBlock = LeafBlock {
        p: [[Vec4::ZERO; 3]; 3],
        prims: [NONE; 4],
    };

    /// Whether the SIMD test takes this leaf.
    #[inline(always)]
    pub fn simd(&self) -> bool {
        self.prims[0] != NONE
    }

    /// A bit per lane that holds a triangle.
    #[inline(always)]
    pub fn lanes(&self) -> u32 {
        glam::UVec4::from_array(self.prims)
            .cmpne(glam::UVec4::splat(NONE))
            .bitmask()
    }
}

impl Node4 {
    /// A box at +infinity on every axis: t = ±inf on each slab, which
    /// either puts the entry at +inf or the exit at -inf, a miss for any
    /// ray whose inverse direction is finite and non-zero (`make_ray`).
    const EMPTY: Node4 = Node4 {
        lo: [Vec4::INFINITY; 3],
        hi: [Vec4::INFINITY; 3],
        child: [EMPTY; 4],
        leaves: [0; 4],
    };

    /// The leaf blocks of this node's own leaf lanes, in lane order.
    pub fn leaf_blocks(&self) -> impl Iterator<Item = usize> + '_ {
        self.child
            .iter()
            .filter(|&&c| c != EMPTY && c & LEAF != 0)
            .map(|&c| (c & !LEAF) as usize)
    }

    /// The leaf blocks of the node in `lane` (a node child): their indices.
    #[inline(always)]
    pub fn leaf_run(&self, lane: usize) -> std::ops::Range<usize> {
        let word = self.leaves[lane] as usize;
        let first = word / RUN_LEN;
        first..first + word % RUN_LEN
    }

    pub fn lane_box(&self, lane: usize) -> ([f32; 3], [f32; 3]) {
        (
            [0, 1, 2].map(|a| self.lo[a][lane]),
            [0, 1, 2].map(|a| self.hi[a][lane]),
        )
    }
}

const _: () = assert!(std::mem::size_of::<Node4>() == 128);
const _: () = assert!(std::mem::size_of::<LeafBlock>() == 160);

/// `Node4::leaves` packs a run's length (0 to 4) below this multiple of its
/// first block: runs for a tree of up to 2^32 / 8 leaf blocks.
const RUN_LEN: usize = 8;

/// Deepest a collapsed tree's stack gets: each node visited pushes at most
/// four entries and pops one, and the tree is no deeper than the binary one.
pub const STACK: usize = 3 * crate::layout::BVH_MAX_DEPTH as usize + 4;

/// The binary tree collapsed: each node takes the two children of a binary
/// node and keeps opening the child with the largest box (the likeliest to
/// be entered) until it has four or only leaves. Node 0 is the root; empty
/// for an empty tree. `corners` gives a primitive reference's triangle in
/// f32, None for a sphere (or always None where leaves are not tested in
/// SIMD).
pub fn collapse(bvh: &Bvh, corners: impl Fn(u32) -> Option<[[f32; 3]; 3]>) -> WideBvh {
    let mut spans = Vec::with_capacity(bvh.nodes.len() / 2 + 1);
    let nodes = collapse_nodes(bvh, |n| {
        spans.push(LeafSpan {
            first: n.right_or_first,
            count: n.count,
        });
        LEAF | (spans.len() - 1) as u32
    });
    let leaves = vec![LeafBlock::EMPTY; spans.len()];
    let mut out = WideBvh {
        nodes,
        leaves,
        spans,
    };
    // A tree too big for the words (over 2^29 leaves) keeps no runs: they
    // only start loads early.
    if out.leaves.len() < (u32::MAX as usize + 1) / RUN_LEN {
        set_leaf_runs(&mut out.nodes);
    }
    for (leaf, span) in out.leaves.iter_mut().zip(&out.spans) {
        let refs = &bvh.prim_refs[span.range()];
        if refs.len() > 4 {
            continue;
        }
        let mut block = LeafBlock::EMPTY;
        let simd = refs.iter().enumerate().all(|(lane, &r)| {
            let Some(tri) = corners(r) else {
                return false;
            };
            for (corner, q) in tri.iter().enumerate() {
                for (axis, &x) in q.iter().enumerate() {
                    block.p[axis][corner][lane] = x;
                }
            }
            block.prims[lane] = r;
            true
        });
        if simd {
            *leaf = block;
        }
    }
    out
}

/// Fills `Node4::leaves`: each node's leaves were numbered together
/// (`collapse_node`), so a child's run is its least block and its count.
fn set_leaf_runs(nodes: &mut [Node4]) {
    for i in 0..nodes.len() {
        for lane in 0..4 {
            let child = nodes[i].child[lane];
            if child & LEAF != 0 {
                continue;
            }
            let (first, count) = nodes[child as usize]
                .leaf_blocks()
                .fold((usize::MAX, 0), |(f, n), b| (f.min(b), n + 1));
            if count > 0 {
                nodes[i].leaves[lane] = (first * RUN_LEN + count) as u32;
            }
        }
    }
}

/// The collapsed nodes alone (root first; empty for an empty tree), each
/// leaf lane holding the word `leaf` makes of the binary leaf: the CPU's
/// `LeafBlock` index, or the shader's primitive-reference run
/// (`layout::GpuScene::pack`).
pub fn collapse_nodes(bvh: &Bvh, mut leaf: impl FnMut(&GpuBvhNode) -> u32) -> Vec<Node4> {
    let mut nodes = Vec::with_capacity(bvh.nodes.len() / 3 + 1);
    if !bvh.nodes.is_empty() {
        collapse_node(&bvh.nodes, 0, &mut nodes, &mut leaf);
    }
    nodes
}

fn collapse_node(
    bin: &[GpuBvhNode],
    index: usize,
    out: &mut Vec<Node4>,
    leaf: &mut impl FnMut(&GpuBvhNode) -> u32,
) -> u32 {
    let slot = out.len();
    out.push(Node4::EMPTY);
    let interior = |i: usize| bin[i].count == 0;
    let area = |i: usize| {
        let n = &bin[i];
        let d = [0, 1, 2].map(|a| f64::from(n.max[a] - n.min[a]).max(0.0));
        d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
    };
    // An array, not a vector: one per node of a tree of millions.
    let mut kids = [0usize; 4];
    let mut n = if interior(index) {
        kids[..2].copy_from_slice(&[index + 1, bin[index].right_or_first as usize]);
        2
    } else {
        // A tree that is one leaf.
        kids[0] = index;
        1
    };
    while n < 4 {
        let widest = kids[..n]
            .iter()
            .enumerate()
            .filter(|&(_, &k)| interior(k))
            .max_by(|a, b| area(*a.1).total_cmp(&area(*b.1)))
            .map(|(lane, _)| lane);
        let Some(lane) = widest else { break };
        let k = kids[lane];
        // In place, so the children keep the binary tree's left-right order.
        kids.copy_within(lane + 1..n, lane + 2);
        kids[lane] = k + 1;
        kids[lane + 1] = bin[k].right_or_first as usize;
        n += 1;
    }
    let mut node = Node4::EMPTY;
    for (lane, &k) in kids[..n].iter().enumerate() {
        for a in 0..3 {
            node.lo[a][lane] = bin[k].min[a];
            node.hi[a][lane] = bin[k].max[a];
        }
    }
    // The node's own leaves first, so they are numbered together (the
    // CPU's blocks lie side by side, `Node4::leaves`); then its subtrees.
    for (lane, &k) in kids[..n].iter().enumerate() {
        if !interior(k) {
            node.child[lane] = leaf(&bin[k]);
        }
    }
    for (lane, &k) in kids[..n].iter().enumerate() {
        if interior(k) {
            node.child[lane] = collapse_node(bin, k, out, leaf);
        }
    }
    out[slot] = node;
    slot as u32
}

/// The watertight test (`trace::hit_triangle`) on a block's triangles, one
/// per SIMD lane, operation for operation as the scalar one, so each lane
/// gives the scalar test's t and barycentrics to the bit. Returns the lane
/// of the nearest hit before `t_max` (the first of equal ones, as a scalar
/// loop keeping strictly nearer hits would) with its t, b1, b2.
#[inline(always)]
pub fn hit_block_f32(
    ray: &crate::cpu::trace::Ray<f32>,
    block: &LeafBlock,
    t_max: f32,
) -> Option<(usize, f32, f32, f32)> {
    let [kx, ky, kz] = ray.k;
    let o = ray.origin.to_array();
    let rel = |axis: usize, corner: usize| block.p[axis][corner] - Vec4::splat(o[axis]);
    let (s0, s1, s2) = (
        Vec4::splat(ray.shear.x),
        Vec4::splat(ray.shear.y),
        Vec4::splat(ray.shear.z),
    );
    let (a_z, b_z, c_z) = (rel(kz, 0), rel(kz, 1), rel(kz, 2));
    let ax = rel(kx, 0) - s0 * a_z;
    let ay = rel(ky, 0) - s1 * a_z;
    let bx = rel(kx, 1) - s0 * b_z;
    let by = rel(ky, 1) - s1 * b_z;
    let cx = rel(kx, 2) - s0 * c_z;
    let cy = rel(ky, 2) - s1 * c_z;
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    let zero = Vec4::ZERO;
    let some_negative = u.cmplt(zero) | v.cmplt(zero) | w.cmplt(zero);
    let some_positive = u.cmpgt(zero) | v.cmpgt(zero) | w.cmpgt(zero);
    let det = u + v + w;
    let t_scaled = u * (s2 * a_z) + v * (s2 * b_z) + w * (s2 * c_z);
    let end = Vec4::splat(t_max) * det;
    let positive = t_scaled.cmpgt(zero) & t_scaled.cmplt(end);
    let negative = t_scaled.cmplt(zero) & t_scaled.cmpgt(end);
    let det_positive = det.cmpgt(zero);
    let inside = (det_positive & positive) | (!det_positive & negative);
    let hit = !(some_negative & some_positive) & det.cmpne(zero) & inside;
    let mut mask = hit.bitmask() & block.lanes();
    if mask == 0 {
        return None;
    }
    let inv_det = Vec4::ONE / det;
    let (t, b1, b2) = (t_scaled * inv_det, v * inv_det, w * inv_det);
    let mut best: Option<(usize, f32, f32, f32)> = None;
    while mask != 0 {
        let lane = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        let limit = best.map_or(t_max, |b| b.1);
        if t[lane] < limit {
            best = Some((lane, t[lane], b1[lane], b2[lane]));
        }
    }
    best
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

/// `hit_boxes_f32` in f64 (the ground-truth reference): the f32 boxes
/// widened exactly, each lane `trace::hit_aabb`'s arithmetic in f64.
#[inline(always)]
pub fn hit_boxes_f64(
    origin: glam::DVec3,
    inv_dir: glam::DVec3,
    node: &Node4,
    t_max: f64,
    box_t_scale: f64,
) -> (u32, [f64; 4]) {
    use glam::DVec4;
    let slab = |axis: usize, o: f64, inv: f64| {
        let t0 = (node.lo[axis].as_dvec4() - DVec4::splat(o)) * DVec4::splat(inv);
        let t1 = (node.hi[axis].as_dvec4() - DVec4::splat(o)) * DVec4::splat(inv);
        (t0.min(t1), t0.max(t1))
    };
    let (nx, fx) = slab(0, origin.x, inv_dir.x);
    let (ny, fy) = slab(1, origin.y, inv_dir.y);
    let (nz, fz) = slab(2, origin.z, inv_dir.z);
    let t_near = nx.max(ny).max(nz.max(DVec4::ZERO));
    let t_far = fx.min(fy).min(fz.min(DVec4::splat(t_max))) * DVec4::splat(box_t_scale);
    (t_near.cmple(t_far).bitmask(), t_near.to_array())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::scene::{Material, Scene, Triangle, Vertex};
    use glam::DVec3;

    /// `n` random triangles in front of the camera.
    pub(crate) fn scene(n: usize) -> Scene {
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

    fn corners(scene: &Scene) -> impl Fn(u32) -> Option<[[f32; 3]; 3]> + '_ {
        |r| {
            Some(
                scene.triangles[r as usize]
                    .vertices
                    .map(|v| v.position.as_vec3().to_array()),
            )
        }
    }

    /// Every binary leaf appears once, under boxes that are the binary
    /// tree's own.
    #[test]
    fn collapse_keeps_every_leaf_and_box() {
        for n in [1, 2, 3, 5, 100, 3000] {
            let scene = scene(n);
            let bvh = Bvh::build(&scene);
            let wide = collapse(&bvh, corners(&scene));
            let mut leaves: Vec<(u32, u32, [f32; 3], [f32; 3])> = Vec::new();
            for node in &wide.nodes {
                for lane in 0..4 {
                    let (lo, hi) = node.lane_box(lane);
                    match node.child[lane] {
                        EMPTY => assert!(lo[0].is_infinite()),
                        c if c & LEAF != 0 => {
                            let index = (c & !LEAF) as usize;
                            let (leaf, span) = (&wide.leaves[index], wide.spans[index]);
                            assert!(leaf.simd(), "triangles only");
                            let refs = &bvh.prim_refs[span.range()];
                            assert_eq!(&leaf.prims[..refs.len()], refs);
                            assert!(leaf.prims[refs.len()..].iter().all(|&p| p == NONE));
                            leaves.push((span.first, span.count, lo, hi));
                        }
                        c => {
                            // The child's lanes fit inside this lane's box.
                            let child = &wide.nodes[c as usize];
                            // Its leaf blocks are the run this lane names.
                            let mut own: Vec<usize> = child.leaf_blocks().collect();
                            own.sort_unstable();
                            assert_eq!(own, node.leaf_run(lane).collect::<Vec<_>>());
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
            assert_eq!(wide.leaves.len(), leaves.len(), "one block a leaf");
            assert!(wide.nodes.len() <= bvh.nodes.len() / 2 + 1);
        }
    }

    /// Closest and any hits through the collapsed tree are those of testing
    /// every primitive, in both precisions.
    #[test]
    fn traversal_finds_what_testing_everything_finds() {
        use crate::cpu::trace::{hit_triangle, make_ray, traverse, CpuGeometry, CpuScene};
        use crate::cpu::{CpuOptions, Real};
        fn check<R: Real>(scene: &Scene, bvh: &Bvh) {
            let camera = crate::camera::Camera::new(64, 48);
            let geometry = CpuGeometry::<R>::new(scene, bvh, &Default::default());
            let cpu = CpuScene::new(scene, bvh, &geometry, &camera, &CpuOptions::default());
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
            let ray = make_ray(
                R::v3(R::ZERO, R::ZERO, R::ZERO),
                R::v3(nan, nan, nan),
                R::ZERO,
            );
            assert_eq!(
                traverse(&cpu, &ray, R::T_INF, false, &[], R::ZERO).prim,
                u32::MAX
            );
        }
        let scene = scene(2000);
        let bvh = Bvh::build(&scene);
        check::<f32>(&scene, &bvh);
        check::<f64>(&scene, &bvh);
    }

    /// Each lane of the SIMD triangle test gives the scalar test's t and
    /// barycentrics to the bit, and the block's answer is the nearest hit
    /// (the first of equal ones), as testing the leaf's triangles in order.
    #[test]
    fn simd_triangles_match_the_scalar_test() {
        use crate::cpu::trace::{hit_triangle, make_ray};
        use glam::Vec3;
        let scene = scene(3000);
        let bvh = Bvh::build(&scene);
        let wide = collapse(&bvh, corners(&scene));
        let tri = |r: u32| corners(&scene)(r).expect("triangle").map(Vec3::from);
        let mut state = 5u32;
        let mut next = || {
            state = crate::cpu::sample::hash_u32(state);
            f32::from_bits(state >> 9 | 0x3f80_0000) * 2.0 - 3.0
        };
        let mut hits = 0;
        for (leaf, span) in wide.leaves.iter().zip(&wide.spans) {
            let refs = &bvh.prim_refs[span.range()];
            for _ in 0..20 {
                // Rays from near the camera towards a point of the leaf's
                // first triangle, so many hit, some on edges and corners.
                let target = tri(refs[0])[0] * (1.0 + next().abs() * 1e-3);
                let origin = Vec3::new(next(), next(), next()) * 3.0;
                let ray = make_ray::<f32>(origin, (target - origin).normalize(), 0.0);
                let t_max = if next() > 0.0 { f32::MAX } else { 18.0 };
                let mut want = None;
                let mut limit = t_max;
                for (lane, &r) in refs.iter().enumerate() {
                    let (t, b1, b2) = hit_triangle(&ray, &tri(r), limit);
                    if t < limit {
                        limit = t;
                        want = Some((lane, t, b1, b2));
                    }
                }
                let got = hit_block_f32(&ray, leaf, t_max);
                assert_eq!(
                    got.map(|g| (g.0, g.1.to_bits(), g.2.to_bits(), g.3.to_bits())),
                    want.map(|g| (g.0, g.1.to_bits(), g.2.to_bits(), g.3.to_bits()))
                );
                hits += usize::from(want.is_some());
            }
        }
        assert!(hits > wide.leaves.len() * 3, "{hits} hits");
    }

    /// The SIMD test gives each lane what the scalar test gives its box, in
    /// both precisions.
    #[test]
    fn simd_boxes_match_the_scalar_test() {
        use crate::cpu::trace::{hit_aabb, make_ray};
        use crate::cpu::Real;
        let scene = scene(500);
        let wide = collapse(&Bvh::build(&scene), corners(&scene));
        let mut state = 3u32;
        let mut next = || {
            state = crate::cpu::sample::hash_u32(state);
            f32::from_bits(state >> 9 | 0x3f80_0000) * 2.0 - 3.0
        };
        for i in 0..2000 {
            let origin = glam::Vec3::new(next(), next(), next()) * 4.0;
            let mut dir = glam::Vec3::new(next(), next(), next() - 1.0);
            // Some rays along an axis plane, of either sign of zero, and
            // some with a NaN direction.
            match i % 8 {
                1 => dir.x = 0.0,
                2 => dir.y = -0.0,
                3 => dir = glam::Vec3::new(0.0, -0.0, dir.z),
                4 if i % 64 == 4 => dir = glam::Vec3::NAN,
                _ => {}
            }
            let dir = if dir.is_nan() { dir } else { dir.normalize() };
            let ray = make_ray::<f32>(origin, dir, 0.0);
            let t_max = if next() > 0.0 {
                f32::MAX
            } else {
                next() + 20.0
            };
            for node in &wide.nodes {
                let (mask, t) =
                    hit_boxes_f32(ray.origin, ray.inv_dir, node, t_max, f32::BOX_T_SCALE);
                for (lane, t) in t.iter().enumerate() {
                    let (lo, hi) = node.lane_box(lane);
                    let scalar = hit_aabb(&ray, lo, hi, t_max);
                    let hit = scalar != f32::T_INF;
                    assert_eq!(mask & (1 << lane) != 0, hit, "lane {lane}");
                    if hit {
                        assert_eq!(t.to_bits(), scalar.to_bits());
                    }
                }
                let ray64 = make_ray::<f64>(origin.as_dvec3(), dir.as_dvec3(), 0.0);
                let t_max64 = f64::from(t_max);
                let (mask, t) =
                    hit_boxes_f64(ray64.origin, ray64.inv_dir, node, t_max64, f64::BOX_T_SCALE);
                for (lane, t) in t.iter().enumerate() {
                    let (lo, hi) = node.lane_box(lane);
                    let scalar = hit_aabb(&ray64, lo, hi, t_max64);
                    let hit = scalar != f64::T_INF;
                    assert_eq!(mask & (1 << lane) != 0, hit, "f64 lane {lane}");
                    if hit {
                        assert_eq!(t.to_bits(), scalar.to_bits());
                    }
                }
            }
        }
    }
}
