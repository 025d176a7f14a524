//! The binned-SAH builder behind `Bvh`: primitives' f32 boxes in, the
//! depth-first binary tree and its leaf order out.
//!
//! Each level reads the primitives from one buffer and partitions them,
//! stably, into the other (the children then read that one): a node's
//! halves know their sizes from the bins before anything moves, so a large
//! node is partitioned on every thread, chunk by chunk, each chunk writing
//! its own stretch of both halves. Subtrees of at least `parallel_min`
//! primitives build on their own threads, each into its own list, placed
//! once into the final array at the end. Every step is exact in any order
//! (unions of boxes, counts, a stable partition), so the tree is the same
//! node for node on any number of threads (tested).

use glam::Vec3A;
use rayon::prelude::*;

use super::node::{GpuBvhNode, BVH_MAX_DEPTH};

/// Primitives a leaf holds: any set this small is a leaf, larger ones
/// split. The CPU reference tests up to four triangles in one SIMD test, so
/// splitting them only adds node visits (the 2M-triangle grid renders 28%
/// faster than when the SAH split them down to single triangles, and its
/// tree has 40% fewer nodes); the shader, which tests them one by one,
/// measured the same either way on lavapipe.
pub(super) const MAX_LEAF_SIZE: usize = 4;
/// Binning the widest axis alone was a third cheaper to build, but its
/// trees cost 1.1-1.4x more by the SAH (sphere grid 22k: 12.36 against
/// 8.46; table: 5.57 against 4.50) and rendered up to a fifth slower: every
/// axis is binned, in one pass.
const BIN_COUNT: usize = 16;
/// Primitives a thread takes at a time where one node is binned or
/// partitioned on every thread.
const PAR_CHUNK: usize = 1 << 15;

/// An f32 box in SIMD lanes (32 bytes: what the builder moves for each
/// primitive); min > max when empty.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Box3 {
    pub min: Vec3A,
    pub max: Vec3A,
}

// SAFETY: two `Vec3A`s, for which all zero bytes are the vector zero.
unsafe impl bytemuck::Zeroable for Box3 {}

impl Box3 {
    pub const EMPTY: Box3 = Box3 {
        min: Vec3A::splat(f32::INFINITY),
        max: Vec3A::splat(f32::NEG_INFINITY),
    };

    #[inline(always)]
    pub fn union(self, o: Box3) -> Box3 {
        Box3 {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    #[inline(always)]
    fn grow(self, p: Vec3A) -> Box3 {
        Box3 {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// The centre, halved before adding so that no box in f32's range
    /// overflows.
    #[inline(always)]
    fn centroid(&self) -> Vec3A {
        self.min * 0.5 + self.max * 0.5
    }

    /// In f64: an f32 area could overflow.
    pub fn surface_area(&self) -> f64 {
        if self.min.cmpgt(self.max).any() {
            return 0.0;
        }
        let e = (self.max - self.min).as_dvec3();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }
}

/// A node's box and the box of its primitives' centroids (where the SAH
/// bins go).
#[derive(Clone, Copy)]
struct Extent {
    bounds: Box3,
    centroids: Box3,
}

impl Extent {
    const EMPTY: Extent = Extent {
        bounds: Box3::EMPTY,
        centroids: Box3::EMPTY,
    };

    #[inline(always)]
    fn add(self, b: &Box3) -> Extent {
        Extent {
            bounds: self.bounds.union(*b),
            centroids: self.centroids.grow(b.centroid()),
        }
    }

    fn union(self, o: Extent) -> Extent {
        Extent {
            bounds: self.bounds.union(o.bounds),
            centroids: self.centroids.union(o.centroids),
        }
    }

    /// On every thread for a large set: unions are exact, so the same
    /// extent in any order.
    fn of(boxes: &[Box3]) -> Extent {
        if boxes.len() < 2 * PAR_CHUNK {
            return boxes.iter().fold(Extent::EMPTY, Extent::add);
        }
        boxes
            .par_chunks(PAR_CHUNK)
            .map(|c| c.iter().fold(Extent::EMPTY, Extent::add))
            .reduce(|| Extent::EMPTY, Extent::union)
    }
}

/// The built tree: nodes depth-first (root at 0, each left child right
/// after its parent), the primitive references in leaf order, the deepest
/// leaf's level.
pub(super) struct Tree {
    pub nodes: Vec<GpuBvhNode>,
    pub refs: Vec<u32>,
    pub depth: u32,
}

/// The tree over `boxes`, whose references are `refs` (one each). Subtrees
/// of at least `parallel_min` primitives, and nodes of 16 times that, use
/// every thread; the tree does not depend on it.
pub(super) fn build(mut boxes: Vec<Box3>, mut refs: Vec<u32>, parallel_min: usize) -> Tree {
    debug_assert_eq!(boxes.len(), refs.len());
    if boxes.is_empty() {
        return Tree {
            nodes: Vec::new(),
            refs,
            depth: 0,
        };
    }
    let extent = Extent::of(&boxes);
    let n = boxes.len();
    // Zeroed memory comes from the system already zeroed: no pass of
    // writes before the partitions write it (64 MB at 2M primitives).
    let (mut spare, mut spare_refs) = (bytemuck::zeroed_vec::<Box3>(n), vec![0u32; n]);
    let at = Slices {
        cur: &mut boxes,
        cur_refs: &mut refs,
        other: &mut spare,
        other_refs: &mut spare_refs,
        primary: true,
    };
    let builder = Builder {
        parallel_min: parallel_min.max(MAX_LEAF_SIZE),
    };
    let piece = builder.subtree(at, extent, 0, 0);
    let mut nodes = vec![GpuBvhNode::default(); piece.len];
    let depth = piece.place(&mut nodes, 0);
    Tree { nodes, refs, depth }
}

/// A node's primitives: where they are now (`cur`) and the other buffer's
/// same stretch, where its children will find them. `primary`: whether
/// `cur` is the buffer the final references are read from.
struct Slices<'a> {
    cur: &'a mut [Box3],
    cur_refs: &'a mut [u32],
    other: &'a mut [Box3],
    other_refs: &'a mut [u32],
    primary: bool,
}

impl<'a> Slices<'a> {
    fn len(&self) -> usize {
        self.cur.len()
    }

    /// The children's view: the primitives now lie in `other`.
    fn swapped(self) -> Slices<'a> {
        Slices {
            cur: self.other,
            cur_refs: self.other_refs,
            other: self.cur,
            other_refs: self.cur_refs,
            primary: !self.primary,
        }
    }

    fn split_at(self, mid: usize) -> (Slices<'a>, Slices<'a>) {
        let (a, b) = self.cur.split_at_mut(mid);
        let (ar, br) = self.cur_refs.split_at_mut(mid);
        let (c, d) = self.other.split_at_mut(mid);
        let (cr, dr) = self.other_refs.split_at_mut(mid);
        (
            Slices {
                cur: a,
                cur_refs: ar,
                other: c,
                other_refs: cr,
                primary: self.primary,
            },
            Slices {
                cur: b,
                cur_refs: br,
                other: d,
                other_refs: dr,
                primary: self.primary,
            },
        )
    }

    /// A leaf's references end in the primary buffer.
    fn finish_leaf(self) {
        if !self.primary {
            self.other_refs.copy_from_slice(self.cur_refs);
        }
    }
}

/// A subtree as built: one list (child indices relative to its start), or
/// a node whose halves were built on their own threads.
struct Piece {
    len: usize,
    kind: PieceKind,
}

enum PieceKind {
    Flat(Vec<GpuBvhNode>, u32),
    Split(GpuBvhNode, Box<[Piece; 2]>),
}

impl Piece {
    /// Writes the subtree into `out` (its exact length), whose first node
    /// is the tree's node `base`; returns its deepest level.
    fn place(self, out: &mut [GpuBvhNode], base: u32) -> u32 {
        match self.kind {
            PieceKind::Flat(nodes, depth) => {
                for (o, n) in out.iter_mut().zip(nodes) {
                    *o = n;
                    if n.count == 0 {
                        o.right_or_first += base;
                    }
                }
                depth
            }
            PieceKind::Split(mut parent, halves) => {
                let [left, right] = *halves;
                parent.right_or_first = base + 1 + left.len as u32;
                out[0] = parent;
                let (l, r) = out[1..].split_at_mut(left.len);
                let right_base = parent.right_or_first;
                let (a, b) = rayon::join(|| left.place(l, base + 1), || right.place(r, right_base));
                a.max(b)
            }
        }
    }
}

struct Builder {
    parallel_min: usize,
}

impl Builder {
    fn subtree(&self, mut at: Slices, extent: Extent, first: usize, depth: u32) -> Piece {
        let n = at.len();
        if n < self.parallel_min.saturating_mul(2) || depth + 1 >= BVH_MAX_DEPTH {
            let mut nodes = Vec::with_capacity(n / 2 + 1);
            let mut bins = Bins::EMPTY;
            let deepest = self.in_place(&mut nodes, at, extent, first as u32, depth, &mut bins);
            return Piece {
                len: nodes.len(),
                kind: PieceKind::Flat(nodes, deepest),
            };
        }
        let (mid, [le, re]) = self.split(&mut at.parts(), extent, true);
        let (left, right) = at.swapped().split_at(mid);
        let (a, b) = rayon::join(
            || self.subtree(left, le, first, depth + 1),
            || self.subtree(right, re, first + mid, depth + 1),
        );
        let parent = node(extent.bounds, 0, 0);
        Piece {
            len: 1 + a.len + b.len,
            kind: PieceKind::Split(parent, Box::new([a, b])),
        }
    }

    /// The subtree appended to `nodes` (child indices relative to the
    /// list's start); returns its deepest level.
    fn in_place(
        &self,
        nodes: &mut Vec<GpuBvhNode>,
        mut at: Slices,
        extent: Extent,
        first: u32,
        depth: u32,
        bins: &mut Bins,
    ) -> u32 {
        let index = nodes.len();
        let n = at.len();
        nodes.push(node(extent.bounds, first, n as u32));
        if n <= MAX_LEAF_SIZE || depth + 1 >= BVH_MAX_DEPTH {
            at.finish_leaf();
            return depth;
        }
        let (mid, [le, re]) = self.split_with(&mut at.parts(), extent, false, bins);
        let (left, right) = at.swapped().split_at(mid);
        let left_depth = self.in_place(nodes, left, le, first, depth + 1, bins);
        let right_index = nodes.len();
        let right_depth = self.in_place(nodes, right, re, first + mid as u32, depth + 1, bins);
        nodes[index].right_or_first = right_index as u32;
        nodes[index].count = 0;
        left_depth.max(right_depth)
    }

    fn split(&self, parts: &mut Parts, extent: Extent, parallel: bool) -> (usize, [Extent; 2]) {
        let mut bins = Bins::EMPTY;
        self.split_with(parts, extent, parallel, &mut bins)
    }

    /// Chooses a binned-SAH split of more than `MAX_LEAF_SIZE` primitives,
    /// the cheapest plane of all three axes, and partitions them into the
    /// other buffer; returns where the right half starts and both halves'
    /// extents.
    fn split_with(
        &self,
        parts: &mut Parts,
        extent: Extent,
        parallel: bool,
        bins: &mut Bins,
    ) -> (usize, [Extent; 2]) {
        let n = parts.src.len();
        debug_assert!(n > MAX_LEAF_SIZE);
        let binning = Binning::new(extent.centroids);
        let chunk = PAR_CHUNK.min(self.parallel_min.saturating_mul(4));
        let wide = parallel && n >= self.parallel_min.saturating_mul(16);
        // Per chunk: its bins' counts on the chosen plane say where its
        // share of each half goes.
        let chunk_bins: Vec<Bins> = if wide {
            parts
                .src
                .par_chunks(chunk)
                .map(|c| {
                    let mut b = Bins::EMPTY;
                    binning.bin(c, &mut b);
                    b
                })
                .collect()
        } else {
            *bins = Bins::EMPTY;
            binning.bin(parts.src, bins);
            Vec::new()
        };
        if wide {
            *bins = Bins::EMPTY;
            for b in &chunk_bins {
                bins.add(b);
            }
        }
        let Some((axis, plane)) = bins.best(n) else {
            // All centroids coincide (or no plane separates them): split by
            // count, so that oversized leaves cannot happen.
            let mid = n / 2;
            parts.dst.copy_from_slice(parts.src);
            parts.dst_refs.copy_from_slice(parts.src_refs);
            return (
                mid,
                [Extent::of(&parts.src[..mid]), Extent::of(&parts.src[mid..])],
            );
        };
        // The bins' own arithmetic, so that each half gets what its count said.
        let left = |b: &Box3| binning.bins_of(b)[axis] <= plane;
        let mid = bins.count[axis][..=plane].iter().map(|&c| c as usize).sum();
        let (dst_left, dst_right) = parts.dst.split_at_mut(mid);
        let (refs_left, refs_right) = parts.dst_refs.split_at_mut(mid);
        if !wide {
            let sides = partition(
                parts.src,
                parts.src_refs,
                [dst_left, dst_right],
                [refs_left, refs_right],
                left,
            );
            return (mid, sides);
        }
        // Each chunk's stretch of both halves, in chunk order: the same
        // stable partition as one thread makes.
        let mut jobs = Vec::with_capacity(chunk_bins.len());
        let (mut dl, mut dr, mut rl, mut rr) = (dst_left, dst_right, refs_left, refs_right);
        for ((src, src_refs), b) in parts
            .src
            .chunks(chunk)
            .zip(parts.src_refs.chunks(chunk))
            .zip(&chunk_bins)
        {
            let l: usize = b.count[axis][..=plane].iter().map(|&c| c as usize).sum();
            let (a, rest) = std::mem::take(&mut dl).split_at_mut(l);
            dl = rest;
            let (c, rest) = std::mem::take(&mut rl).split_at_mut(l);
            rl = rest;
            let (bb, rest) = std::mem::take(&mut dr).split_at_mut(src.len() - l);
            dr = rest;
            let (d, rest) = std::mem::take(&mut rr).split_at_mut(src.len() - l);
            rr = rest;
            jobs.push((src, src_refs, [a, bb], [c, d]));
        }
        let sides = jobs
            .into_par_iter()
            .map(|(src, src_refs, dst, dst_refs)| partition(src, src_refs, dst, dst_refs, left))
            .reduce(
                || [Extent::EMPTY; 2],
                |a, b| [a[0].union(b[0]), a[1].union(b[1])],
            );
        (mid, sides)
    }
}

/// A node's source and destination buffers for one split.
struct Parts<'a> {
    src: &'a [Box3],
    src_refs: &'a [u32],
    dst: &'a mut [Box3],
    dst_refs: &'a mut [u32],
}

impl Slices<'_> {
    /// The buffers as a split reads and writes them.
    fn parts(&mut self) -> Parts<'_> {
        Parts {
            src: self.cur,
            src_refs: self.cur_refs,
            dst: self.other,
            dst_refs: self.other_refs,
        }
    }
}

/// Moves the boxes `left` takes, in order, into `dst[0]`, the others into
/// `dst[1]` (each exactly that long), their references alike; returns both
/// sides' extents, gathered on the way.
#[inline(always)]
fn partition(
    src: &[Box3],
    src_refs: &[u32],
    dst: [&mut [Box3]; 2],
    dst_refs: [&mut [u32]; 2],
    left: impl Fn(&Box3) -> bool,
) -> [Extent; 2] {
    let [dl, dr] = dst;
    let [rl, rr] = dst_refs;
    let (mut l, mut r) = (0usize, 0usize);
    let (mut el, mut er) = (Extent::EMPTY, Extent::EMPTY);
    for (b, &reference) in src.iter().zip(src_refs) {
        if left(b) {
            dl[l] = *b;
            rl[l] = reference;
            l += 1;
            el = el.add(b);
        } else {
            dr[r] = *b;
            rr[r] = reference;
            r += 1;
            er = er.add(b);
        }
    }
    debug_assert!(l == dl.len() && r == dr.len());
    [el, er]
}

/// Where centroids fall among a node's bins on each axis.
#[derive(Clone, Copy)]
struct Binning {
    /// The least centroid.
    min: Vec3A,
    /// Bins per unit of each axis (0 where the centroids do not spread,
    /// or spread too little to scale: see `peel`).
    scale: Vec3A,
    /// Axes whose centroids spread less than about 5e-38, where 16 divided
    /// by the width overflows: such centroids are all that small themselves
    /// (f32's spacing is coarser anywhere else), as where spheres shrink
    /// towards a point. The least of them go to the first bin and the rest
    /// to the last, so each level peels the least off (which takes the
    /// tests' such tree to the depth cap).
    peel: glam::BVec3A,
}

/// Adding 2^23 leaves a value's nearest integer in the low mantissa bits:
/// no saturating casts, and the same bins for binning and partitioning
/// (all that matters; the halves' boxes are their members' unions whatever
/// the bins are).
const ROUND: f32 = 8_388_608.0;

impl Binning {
    fn new(centroids: Box3) -> Binning {
        let width = centroids.max - centroids.min;
        let scale = Vec3A::splat(BIN_COUNT as f32) / width;
        let spread = width.cmpgt(Vec3A::ZERO);
        let finite = scale.is_finite_mask();
        Binning {
            min: centroids.min,
            scale: Vec3A::select(spread & finite, scale, Vec3A::ZERO),
            peel: spread & !finite,
        }
    }

    /// Each axis's bin of `b`'s centroid.
    #[inline(always)]
    fn bins_of(&self, b: &Box3) -> [usize; 3] {
        let d = b.centroid() - self.min;
        let last = Vec3A::splat((BIN_COUNT - 1) as f32);
        let x = (d * self.scale - Vec3A::splat(0.5))
            .max(Vec3A::ZERO)
            .min(last);
        let peeled = Vec3A::select(d.cmpgt(Vec3A::ZERO), last, Vec3A::ZERO);
        let x = Vec3A::select(self.peel, peeled, x) + Vec3A::splat(ROUND);
        let [a, b, c] = x.to_array().map(|x| (x.to_bits() & 0xff) as usize);
        [a, b, c]
    }

    fn bin(&self, boxes: &[Box3], bins: &mut Bins) {
        for b in boxes {
            let at = self.bins_of(b);
            for (axis, &k) in at.iter().enumerate() {
                // `bins_of` clamps to the bins; the mask only lets the
                // compiler see it.
                let k = k & (BIN_COUNT - 1);
                let bin = &mut bins.boxes[axis][k];
                *bin = bin.union(*b);
                bins.count[axis][k] += 1;
            }
        }
    }
}

/// Per axis and bin: the union of the boxes whose centroid falls there,
/// and their count.
#[derive(Clone)]
struct Bins {
    boxes: [[Box3; BIN_COUNT]; 3],
    count: [[u32; BIN_COUNT]; 3],
}

impl Bins {
    const EMPTY: Bins = Bins {
        boxes: [[Box3::EMPTY; BIN_COUNT]; 3],
        count: [[0; BIN_COUNT]; 3],
    };

    fn add(&mut self, o: &Bins) {
        for axis in 0..3 {
            for k in 0..BIN_COUNT {
                self.boxes[axis][k] = self.boxes[axis][k].union(o.boxes[axis][k]);
                self.count[axis][k] += o.count[axis][k];
            }
        }
    }

    /// The cheapest (axis, last bin of the left half) by the SAH among the
    /// planes that leave both halves something; the first of equals.
    fn best(&self, n: usize) -> Option<(usize, usize)> {
        let mut best: Option<(f64, usize, usize)> = None;
        for axis in 0..3 {
            let (boxes, count) = (&self.boxes[axis], &self.count[axis]);
            // Sweep from the right once, then from the left, pricing each plane.
            // Only the planes after a bin that holds something: a plane
            // after an empty bin prices the same as the one before it, and
            // the first of equals wins. A small node (most of a tree) has
            // few such planes.
            let mut right_cost = [0.0; BIN_COUNT];
            let (mut acc, mut k) = (Box3::EMPTY, 0u32);
            for i in (1..BIN_COUNT).rev() {
                if count[i] > 0 {
                    acc = acc.union(boxes[i]);
                    k += count[i];
                    right_cost[i] = acc.surface_area() * f64::from(k);
                } else if i + 1 < BIN_COUNT {
                    right_cost[i] = right_cost[i + 1];
                }
            }
            let (mut acc, mut k) = (Box3::EMPTY, 0u32);
            for i in 0..BIN_COUNT - 1 {
                if count[i] == 0 {
                    continue;
                }
                acc = acc.union(boxes[i]);
                k += count[i];
                if k as usize >= n {
                    break;
                }
                let cost = acc.surface_area() * f64::from(k) + right_cost[i + 1];
                if best.is_none_or(|(c, _, _)| cost < c) {
                    best = Some((cost, axis, i));
                }
            }
        }
        best.map(|(_, axis, plane)| (axis, plane))
    }
}

fn node(b: Box3, first: u32, count: u32) -> GpuBvhNode {
    GpuBvhNode {
        min: b.min.to_array(),
        right_or_first: first,
        max: b.max.to_array(),
        count,
    }
}
