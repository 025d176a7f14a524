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

use super::node::{GpuBvhNode, BVH_MAX_DEPTH};
use super::Bvh;

/// `Node4::child` of a lane that holds a leaf: this bit plus the index of
/// its `LeafBlock` (the shader's tree, collapsed by the same code, puts its
/// first primitive reference there instead). One constant for both trees:
/// `layout::GpuScene::pack` copies the child words as they are.
pub const LEAF: u32 = 1 << 31;
/// `Node4::child` of an unused lane (its box is at +infinity, so no ray
/// hits it; see `Node4::EMPTY`); the shader's `WIDE_EMPTY`.
pub const EMPTY: u32 = u32::MAX;

/// Four children: their boxes by axis and lane (`lo[axis][lane]`), then per
/// lane a node index, `LEAF | block`, or `EMPTY`, and, for a node child,
/// where that child's own leaf blocks lie (`Node4::leaf_run`). 128 bytes,
/// two whole cache lines.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Node4 {
    /// The four children's boxes' low corners, by axis then lane.
    pub lo: [Vec4; 3],
    /// The four children's boxes' high corners, by axis then lane.
    pub hi: [Vec4; 3],
    /// Per lane: a node index, `LEAF | block`, or `EMPTY`.
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
    /// Corners by axis, corner and lane: `p[axis][corner][lane]`.
    pub p: [[Vec4; 3]; 3],
    /// The lanes' primitive references (`NONE`: unused).
    pub prims: [u32; 4],
}

/// `LeafBlock::prims` of an unused lane.
pub const NONE: u32 = u32::MAX;

/// A leaf's primitive references: `prim_refs[first..first + count]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LeafSpan {
    /// The first of the leaf's references.
    pub first: u32,
    /// How many references it has.
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
    /// The nodes, root first.
    pub nodes: Vec<Node4>,
    /// Per leaf, its triangles for the SIMD test.
    pub leaves: Vec<LeafBlock>,
    /// Per leaf, its primitive references.
    pub spans: Vec<LeafSpan>,
    /// Per node, the binary node each lane took its box from (`EMPTY`
    /// for an unused lane): what `refit` reads the boxes from again.
    pub sources: Vec<[u32; 4]>,
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

    /// A bit per lane that holds a triangle. One SSE2 compare where the
    /// CPU is x86_64: glam's `UVec4` compares lane by lane, and this mask,
    /// asked at every leaf test, was 2% of the packets' instructions on the
    /// 240k grid (callgrind).
    #[inline(always)]
    pub fn lanes(&self) -> u32 {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::*;
            // SAFETY: SSE2 is part of x86_64; the load is unaligned and
            // reads the four u32 of `prims`.
            unsafe {
                let prims = _mm_loadu_si128(self.prims.as_ptr().cast());
                let unused = _mm_cmpeq_epi32(prims, _mm_set1_epi32(NONE as i32));
                !(_mm_movemask_ps(_mm_castsi128_ps(unused)) as u32) & 15
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            glam::UVec4::from_array(self.prims)
                .cmpne(glam::UVec4::splat(NONE))
                .bitmask()
        }
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

    /// Lane `lane`'s box: its low and high corners.
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
pub const STACK: usize = 3 * BVH_MAX_DEPTH as usize + 4;

/// The binary tree collapsed: each node takes the two children of a binary
/// node and keeps opening the child with the largest box (the likeliest to
/// be entered) until it has four or only leaves. Node 0 is the root; empty
/// for an empty tree. `corners` gives a primitive reference's triangle in
/// f32, None for a sphere (or always None where leaves are not tested in
/// SIMD).
pub fn collapse(bvh: &Bvh, corners: impl Fn(u32) -> Option<[[f32; 3]; 3]> + Sync) -> WideBvh {
    let mut out = WideBvh::shape(bvh);
    out.fill_leaves(bvh, corners);
    out
}

impl WideBvh {
    /// The tree's shape alone (`collapse` less the leaf blocks' corners,
    /// which `fill_leaves` adds): a caller can make the corners' source
    /// beside it.
    pub(crate) fn shape(bvh: &Bvh) -> WideBvh {
        let mut spans = Vec::with_capacity(bvh.nodes.len() / 2 + 1);
        let (nodes, sources) = collapse_with_sources(bvh, |n| {
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
            sources,
        };
        // A tree too big for the words (over 2^29 leaves) keeps no runs:
        // they only start loads early.
        if out.leaves.len() < (u32::MAX as usize + 1) / RUN_LEN {
            set_leaf_runs(&mut out.nodes);
        }
        out
    }

    /// Each leaf of up to four triangles as a block for the SIMD test,
    /// `corners` giving a reference's triangle in f32 (None: a sphere, or
    /// no SIMD leaves).
    pub(crate) fn fill_leaves(
        &mut self,
        bvh: &Bvh,
        corners: impl Fn(u32) -> Option<[[f32; 3]; 3]> + Sync,
    ) {
        // On every thread: each block reads its triangles from wherever the
        // tree put them.
        use rayon::prelude::*;
        self.leaves
            .par_iter_mut()
            .zip(&self.spans)
            .with_min_len(1 << 10)
            .for_each(|(leaf, span)| {
                let refs = &bvh.prim_refs[span.range()];
                if refs.len() > 4 {
                    return;
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
            });
    }

    /// New boxes and corners for a tree whose binary tree was refitted
    /// (`Bvh::refit`): each lane takes its binary node's box again, each
    /// leaf block its triangles' corners, in the shape it has.
    pub(crate) fn refit(
        &mut self,
        bvh: &Bvh,
        corners: impl Fn(u32) -> Option<[[f32; 3]; 3]> + Sync,
    ) {
        use rayon::prelude::*;
        let bin = &bvh.nodes;
        self.nodes
            .par_iter_mut()
            .zip(&self.sources)
            .with_min_len(1 << 10)
            .for_each(|(node, sources)| {
                for (lane, &k) in sources.iter().enumerate() {
                    if k != EMPTY {
                        let k = &bin[k as usize];
                        for a in 0..3 {
                            node.lo[a][lane] = k.min[a];
                            node.hi[a][lane] = k.max[a];
                        }
                    }
                }
            });
        // The spans are the shape's, so each block takes the same lanes.
        self.fill_leaves(bvh, corners);
    }
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
pub fn collapse_nodes(bvh: &Bvh, leaf: impl FnMut(&GpuBvhNode) -> u32) -> Vec<Node4> {
    collapse_with_sources(bvh, leaf).0
}

/// `collapse_nodes`, and per node the binary node of each lane.
fn collapse_with_sources(
    bvh: &Bvh,
    mut leaf: impl FnMut(&GpuBvhNode) -> u32,
) -> (Vec<Node4>, Vec<[u32; 4]>) {
    let mut out = Collapsed {
        nodes: Vec::with_capacity(bvh.nodes.len() / 3 + 1),
        sources: Vec::with_capacity(bvh.nodes.len() / 3 + 1),
    };
    if !bvh.nodes.is_empty() {
        collapse_node(&bvh.nodes, 0, &mut out, &mut leaf);
    }
    (out.nodes, out.sources)
}

struct Collapsed {
    nodes: Vec<Node4>,
    sources: Vec<[u32; 4]>,
}

fn collapse_node(
    bin: &[GpuBvhNode],
    index: usize,
    out: &mut Collapsed,
    leaf: &mut impl FnMut(&GpuBvhNode) -> u32,
) -> u32 {
    let slot = out.nodes.len();
    out.nodes.push(Node4::EMPTY);
    out.sources.push([EMPTY; 4]);
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
        out.sources[slot][lane] = k as u32;
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
    out.nodes[slot] = node;
    slot as u32
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
            state = crate::hash::hash_u32(state);
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

    pub(crate) fn corners(scene: &Scene) -> impl Fn(u32) -> Option<[[f32; 3]; 3]> + '_ {
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

    /// After the binary tree is refitted to moved triangles, each lane
    /// holds its source node's new box and each leaf block the moved
    /// corners, in the shape the tree had.
    #[test]
    fn refit_takes_the_moved_boxes_and_corners() {
        let mut scene = scene(2000);
        for (i, t) in scene.triangles.iter_mut().enumerate() {
            t.velocity = DVec3::new((i % 7) as f64 - 3.0, (i % 5) as f64 - 2.0, 1.0);
        }
        let mut bvh = Bvh::build(&scene);
        let mut wide = collapse(&bvh, corners(&scene));
        let (shape, spans) = (
            wide.nodes.iter().map(|n| n.child).collect::<Vec<_>>(),
            wide.spans.clone(),
        );
        let moved = scene.at_time(0.75);
        assert!(bvh.refit(&moved, 0.0));
        wide.refit(&bvh, corners(&moved));
        assert_eq!(
            shape,
            wide.nodes.iter().map(|n| n.child).collect::<Vec<_>>()
        );
        assert_eq!(spans, wide.spans);
        for (node, sources) in wide.nodes.iter().zip(&wide.sources) {
            for (lane, &k) in sources.iter().enumerate() {
                if k != EMPTY {
                    let b = &bvh.nodes[k as usize];
                    assert_eq!(node.lane_box(lane), (b.min, b.max));
                }
            }
        }
        for block in &wide.leaves {
            for lane in 0..4 {
                let r = block.prims[lane];
                if r == NONE {
                    continue;
                }
                let want = corners(&moved)(r).expect("a triangle");
                for (corner, q) in want.iter().enumerate() {
                    for (axis, &x) in q.iter().enumerate() {
                        assert_eq!(block.p[axis][corner][lane], x);
                    }
                }
            }
        }
    }

    /// The lane mask is the lanes whose reference is not `NONE`, for every
    /// pattern of used and unused lanes (not only the filled-in-order ones
    /// `collapse` makes).
    #[test]
    fn lanes_are_the_used_references() {
        for pattern in 0..16u32 {
            let mut block = LeafBlock::EMPTY;
            for lane in 0..4 {
                if pattern >> lane & 1 == 1 {
                    block.prims[lane] = [0, 7, NONE - 1, 1 << 31][lane];
                }
            }
            assert_eq!(block.lanes(), pattern, "pattern {pattern:#06b}");
        }
    }
}
