//! One bounding volume hierarchy over spheres and triangles together, built
//! once on the host with binned SAH and flattened into the layout that both
//! the shader and the CPU reference traverse (`layout::GpuBvhNode`).
//!
//! Nodes are stored depth-first: an interior node's left child is the next
//! node, its right child is at `right_or_first`. A leaf's primitives are
//! `prim_refs[first .. first + count]`, each a `PrimRef` (sphere bit + index).
//! Each primitive's box is computed in f64 and rounded outward to f32 (with
//! a few ulps of slack for spheres, whose f32 centre and radius round
//! independently), so it contains both the f64 geometry and its f32
//! rounding; node boxes are unions of those, exact in f32.

pub mod lights_on_surfaces;
pub mod node;
pub mod wide;

use glam::{DVec3, Vec3A};
use rayon::prelude::*;

use crate::features::Features;
use crate::scene::{Bounds, Effects, Scene};
pub use node::{GpuBvhNode, BVH_MAX_DEPTH, SPHERE_BIT};

/// Primitives a leaf holds: any set this small is a leaf, larger ones
/// split. The CPU reference tests up to four triangles in one SIMD test, so
/// splitting them only adds node visits (the 2M-triangle grid renders 28%
/// faster than when the SAH split them down to single triangles, and its
/// tree has 40% fewer nodes); the shader, which tests them one by one,
/// measured the same either way on lavapipe.
const MAX_LEAF_SIZE: usize = 4;
const BIN_COUNT: usize = 16;
/// Relative SAH cost of a primitive test against a node visit.
const INTERSECT_COST: f64 = 1.0;
const TRAVERSAL_COST: f64 = 1.0;

/// The scene's binary BVH, built once and shared by every backend (the GPU
/// and the CPU reference collapse it to four children a node).
#[derive(Clone, Debug)]
pub struct Bvh {
    /// The nodes, root first, each left child right after its parent.
    pub nodes: Vec<GpuBvhNode>,
    /// Primitive references in leaf order; bit 31 set for spheres.
    pub prim_refs: Vec<u32>,
    /// Deepest leaf (root = 0); traversal stacks need at most this many slots.
    pub depth: u32,
    /// The scene's `render_scale`: boxes (and every renderer's copy of the
    /// scene, see `Scene::in_render_space`) are in the scene scaled by it.
    pub scale: f64,
    /// Per light, the primitives whose surface passes through it, which its
    /// shadow rays treat by the rule in `lights_on_surfaces`.
    pub surfaces_at_lights: Vec<Vec<u32>>,
}

impl Default for Bvh {
    /// An empty tree, in the scene's own units.
    fn default() -> Bvh {
        Bvh {
            nodes: Vec::new(),
            prim_refs: Vec::new(),
            depth: 0,
            scale: 1.0,
            surfaces_at_lights: Vec::new(),
        }
    }
}

/// How good a tree is: what `glint info` and `render --stats` print.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhStats {
    /// Node count.
    pub nodes: usize,
    /// Leaf count.
    pub leaves: usize,
    /// Deepest leaf (root = 0).
    pub depth: u32,
    /// Primitives per leaf: mean and most.
    pub mean_leaf: f64,
    /// See `mean_leaf`.
    pub max_leaf: u32,
    /// The surface area heuristic's expected cost of a ray through the
    /// root box, in node visits and primitive tests (each counted 1): the
    /// lower, the faster traversal should be.
    pub sah_cost: f64,
}

impl std::fmt::Display for BvhStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} nodes, {} leaves, depth {}, {:.2} primitives a leaf (at most {}), SAH cost {:.2}",
            self.nodes, self.leaves, self.depth, self.mean_leaf, self.max_leaf, self.sah_cost
        )
    }
}

/// A primitive as the builder sorts it: its box already rounded outward to
/// f32 (the min of rounded-down values is the rounded-down min, so node
/// boxes are those of rounding each node's f64 box) and its centroid in
/// f32, in SIMD lanes, so binning on three axes stays cheap.
struct Prim {
    bounds: Box3,
    centroid: Vec3A,
    reference: u32,
}

/// An f32 box in SIMD lanes; min > max when empty.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Box3 {
    min: Vec3A,
    max: Vec3A,
}

impl Box3 {
    const EMPTY: Box3 = Box3 {
        min: Vec3A::splat(f32::INFINITY),
        max: Vec3A::splat(f32::NEG_INFINITY),
    };

    /// `b` rounded outward.
    fn outward(b: Bounds) -> Box3 {
        Box3 {
            min: Vec3A::from_array(b.min.to_array().map(round_down)),
            max: Vec3A::from_array(b.max.to_array().map(round_up)),
        }
    }

    fn union(self, o: Box3) -> Box3 {
        Box3 {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    fn grow(self, p: Vec3A) -> Box3 {
        Box3 {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// In f64: an f32 area could overflow.
    fn surface_area(&self) -> f64 {
        if self.min.cmpgt(self.max).any() {
            return 0.0;
        }
        let e = (self.max - self.min).as_dvec3();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }
}

impl Bvh {
    /// The tree's statistics.
    pub fn stats(&self) -> BvhStats {
        let area = |n: &GpuBvhNode| {
            let d = [0, 1, 2].map(|i| f64::from((n.max[i] - n.min[i]).max(0.0)));
            2.0 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])
        };
        let Some(root) = self.nodes.first() else {
            return BvhStats::default();
        };
        let root_area = area(root);
        let mut stats = BvhStats {
            nodes: self.nodes.len(),
            depth: self.depth,
            ..BvhStats::default()
        };
        let mut prims = 0u64;
        for n in &self.nodes {
            // A flat root box (one triangle) makes every ratio 1.
            let p = if root_area > 0.0 {
                area(n) / root_area
            } else {
                1.0
            };
            if n.count > 0 {
                stats.leaves += 1;
                prims += u64::from(n.count);
                stats.max_leaf = stats.max_leaf.max(n.count);
                stats.sah_cost += p * INTERSECT_COST * f64::from(n.count);
            } else {
                stats.sah_cost += p * TRAVERSAL_COST;
            }
        }
        stats.mean_leaf = prims as f64 / stats.leaves.max(1) as f64;
        stats
    }

    /// A binned-SAH tree of the scene's spheres and triangles, at time 0.
    pub fn build(scene: &Scene) -> Bvh {
        Bvh::build_swept(scene, 0.0)
    }

    /// The BVH a render of `scene` with `effects` traverses: swept over the
    /// shutter interval when the scene has motion blur.
    pub fn for_render(scene: &Scene, effects: &Effects) -> Bvh {
        if Features::of(scene, effects).motion_blur {
            Bvh::build_swept(scene, effects.shutter_seconds())
        } else {
            Bvh::build(scene)
        }
    }

    /// A BVH whose boxes hold every primitive wherever it is during the
    /// next `span` seconds (motion blur traces rays at times in the shutter
    /// interval against this one tree). A moving primitive's box also gets
    /// the f32 slack spheres have: the shader computes its position at a
    /// time in f32, which can round past the f64 box.
    pub fn build_swept(scene: &Scene, span: f64) -> Bvh {
        Bvh::build_swept_with(scene, span, PARALLEL_MIN)
    }

    fn build_swept_with(scene: &Scene, span: f64, parallel_min: usize) -> Bvh {
        let scale = scene.render_scale();
        let scene = &*scene.in_render_space(scale);
        let sphere_prim = |i: usize| {
            let s = &scene.spheres[i];
            let bounds = widen(s.swept_bounds(span));
            Prim {
                bounds: Box3::outward(bounds),
                centroid: (s.center + s.velocity * (0.5 * span)).as_vec3a(),
                reference: i as u32 | SPHERE_BIT,
            }
        };
        let triangle_prim = |i: usize| {
            let t = &scene.triangles[i];
            let bounds = if span > 0.0 && t.velocity != DVec3::ZERO {
                widen(t.swept_bounds(span))
            } else {
                t.bounds()
            };
            Prim {
                bounds: Box3::outward(bounds),
                centroid: bounds.centroid().as_vec3a(),
                reference: i as u32,
            }
        };
        // Spheres, then triangles; on every thread (a fifth of a 2M-triangle
        // build on one).
        let spheres = scene.spheres.len();
        let mut prims: Vec<Prim> = (0..spheres + scene.triangles.len())
            .into_par_iter()
            .with_min_len(PAR_CHUNK)
            .map(|i| {
                if i < spheres {
                    sphere_prim(i)
                } else {
                    triangle_prim(i - spheres)
                }
            })
            .collect();
        let mut bvh = Bvh {
            scale,
            ..Bvh::default()
        };
        if !prims.is_empty() {
            let extent = Extent::of(&prims);
            let (nodes, depth) = build_tree(&mut prims, extent, 0, 0, parallel_min);
            bvh.nodes = nodes;
            bvh.depth = depth;
        }
        bvh.prim_refs = prims.iter().map(|p| p.reference).collect();
        bvh.surfaces_at_lights =
            crate::bvh::lights_on_surfaces::find(scene, &bvh.nodes, &bvh.prim_refs);
        bvh
    }
}

/// The top `PARALLEL_LEVELS` levels of the tree build their two halves on
/// two threads (rayon) where a half holds at least `PARALLEL_MIN`
/// primitives, each subtree into its own list, joined after; below, one
/// thread builds a subtree in place. Joining copies a level's nodes once,
/// so only a few levels do it (enough subtrees for 32 threads). The split
/// decisions do not depend on it: the tree is the same node for node
/// (tested).
const PARALLEL_LEVELS: u32 = 5;
const PARALLEL_MIN: usize = 4096;
/// Primitives a thread takes at a time where one set is gathered or
/// binned on every thread (the root and the levels just below it).
const PAR_CHUNK: usize = 1 << 15;

/// The subtree over `prims` (which start at `first` in the final order),
/// flattened depth-first with its root at index 0 and child indices
/// relative to it, and its depth below `depth`.
fn build_tree(
    prims: &mut [Prim],
    extent: Extent,
    first: usize,
    depth: u32,
    parallel_min: usize,
) -> (Vec<GpuBvhNode>, u32) {
    if depth >= PARALLEL_LEVELS || prims.len() < 2 * parallel_min.max(MAX_LEAF_SIZE) {
        let mut nodes = Vec::with_capacity(2 * prims.len());
        let deepest = build_in_place(&mut nodes, prims, extent, first, depth);
        return (nodes, deepest);
    }
    let mut parent = node(extent.bounds, first as u32, prims.len() as u32);
    let (mid, [left_extent, right_extent]) = split(prims, extent, parallel_min);
    let (left, right) = prims.split_at_mut(mid);
    let ((mut nodes, left_depth), (right_nodes, right_depth)) = rayon::join(
        || build_tree(left, left_extent, first, depth + 1, parallel_min),
        || build_tree(right, right_extent, first + mid, depth + 1, parallel_min),
    );
    // Parent, then the left subtree, then the right: shift each subtree's
    // child indices by where it lands.
    parent.count = 0;
    parent.right_or_first = (1 + nodes.len()) as u32;
    shift(&mut nodes, 1);
    let right_at = 1 + nodes.len() as u32;
    let mut out = Vec::with_capacity(1 + nodes.len() + right_nodes.len());
    out.push(parent);
    out.append(&mut nodes);
    let start = out.len();
    out.extend(right_nodes);
    shift(&mut out[start..], right_at);
    (out, left_depth.max(right_depth))
}

/// The subtree over `prims` appended to `nodes` (child indices relative to
/// the list's start); returns its deepest level.
fn build_in_place(
    nodes: &mut Vec<GpuBvhNode>,
    prims: &mut [Prim],
    extent: Extent,
    first: usize,
    depth: u32,
) -> u32 {
    let index = nodes.len();
    nodes.push(node(extent.bounds, first as u32, prims.len() as u32));
    if prims.len() <= MAX_LEAF_SIZE || depth + 1 >= BVH_MAX_DEPTH {
        return depth;
    }
    let (mid, [left_extent, right_extent]) = split(prims, extent, usize::MAX);
    let (left, right) = prims.split_at_mut(mid);
    let left_depth = build_in_place(nodes, left, left_extent, first, depth + 1);
    let right_index = nodes.len();
    let right_depth = build_in_place(nodes, right, right_extent, first + mid, depth + 1);
    nodes[index].right_or_first = right_index as u32;
    nodes[index].count = 0;
    left_depth.max(right_depth)
}

/// Adds `by` to the child indices of the interior nodes (leaves hold
/// primitive offsets, which are global already).
fn shift(nodes: &mut [GpuBvhNode], by: u32) {
    for n in nodes {
        if n.count == 0 {
            n.right_or_first += by;
        }
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

    fn add(self, p: &Prim) -> Extent {
        Extent {
            bounds: self.bounds.union(p.bounds),
            centroids: self.centroids.grow(p.centroid),
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
    fn of(prims: &[Prim]) -> Extent {
        if prims.len() < 2 * PAR_CHUNK {
            return prims.iter().fold(Extent::EMPTY, Extent::add);
        }
        prims
            .par_chunks(PAR_CHUNK)
            .map(|c| c.iter().fold(Extent::EMPTY, Extent::add))
            .reduce(|| Extent::EMPTY, Extent::union)
    }
}

/// Chooses a binned-SAH split of more than `MAX_LEAF_SIZE` primitives,
/// the cheapest plane of all three axes, and partitions them; returns where
/// the right half starts and both halves' extents. Binning the widest axis
/// alone was a third cheaper to build, but its trees cost 1.1-1.4x more
/// by the SAH (sphere grid 22k: 12.36 against 8.46; table: 5.57 against
/// 4.50) and rendered up to a fifth slower.
///
/// A set of at least 16 `parallel_min` primitives (the top of the tree) is
/// binned on every thread, in chunks of up to `PAR_CHUNK`: unions and
/// counts are exact, so the bins are the same in any order.
fn split(prims: &mut [Prim], extent: Extent, parallel_min: usize) -> (usize, [Extent; 2]) {
    debug_assert!(prims.len() > MAX_LEAF_SIZE);
    let centroids = extent.centroids;
    let width = centroids.max - centroids.min;
    // Bins per unit of each axis (0 where the centroids do not spread).
    let scale = Vec3A::select(
        width.cmpgt(Vec3A::ZERO),
        Vec3A::splat(BIN_COUNT as f32) / width,
        Vec3A::ZERO,
    );
    // Each axis's bin of a centroid. Adding 2^23 leaves a value's nearest
    // integer in the low mantissa bits: no saturating casts, and the same
    // bins for binning and partitioning (all that matters; the halves'
    // boxes are their members' unions whatever the bins are).
    let top = Vec3A::splat((BIN_COUNT - 1) as f32);
    let bins_of = |c: Vec3A| {
        let x = ((c - centroids.min) * scale - Vec3A::splat(0.5))
            .max(Vec3A::ZERO)
            .min(top)
            + Vec3A::splat(8_388_608.0);
        x.to_array().map(|x| (x.to_bits() & 0xff) as usize)
    };
    // Binned on every axis the centroids spread along, in one pass.
    let spread = [0, 1, 2].map(|a| width[a] > 0.0);
    let axes = || (0..3).filter(|&a| spread[a]);
    type Bins = [[(Box3, usize); BIN_COUNT]; 3];
    const EMPTY_BINS: Bins = [[(Box3::EMPTY, 0usize); BIN_COUNT]; 3];
    let bin = |chunk: &[Prim]| {
        let mut bins = EMPTY_BINS;
        for p in chunk {
            let at = bins_of(p.centroid);
            for axis in axes() {
                let b = &mut bins[axis][at[axis]];
                b.0 = b.0.union(p.bounds);
                b.1 += 1;
            }
        }
        bins
    };
    let bins = if prims.len() < parallel_min.saturating_mul(16) {
        bin(prims)
    } else {
        let chunk = PAR_CHUNK.min(4 * parallel_min);
        prims.par_chunks(chunk).map(bin).reduce(
            || EMPTY_BINS,
            |mut a, b| {
                for (a, b) in a.iter_mut().flatten().zip(b.iter().flatten()) {
                    *a = (a.0.union(b.0), a.1 + b.1);
                }
                a
            },
        )
    };
    let mut best: Option<(f64, usize, usize)> = None;
    for axis in axes() {
        let bins = &bins[axis];
        // Sweep from the right once, then from the left, pricing each split plane.
        let mut right_area = [0.0; BIN_COUNT];
        let mut acc = (Box3::EMPTY, 0usize);
        for i in (1..BIN_COUNT).rev() {
            acc = (acc.0.union(bins[i].0), acc.1 + bins[i].1);
            right_area[i] = acc.0.surface_area() * acc.1 as f64;
        }
        let mut acc = (Box3::EMPTY, 0usize);
        for i in 0..BIN_COUNT - 1 {
            acc = (acc.0.union(bins[i].0), acc.1 + bins[i].1);
            let cost = acc.0.surface_area() * acc.1 as f64 + right_area[i + 1];
            if acc.1 > 0 && acc.1 < prims.len() && best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, i));
            }
        }
    }
    match best {
        Some((_, axis, plane)) => partition(prims, |p| bins_of(p.centroid)[axis] <= plane),
        // All centroids coincide (or no plane separates them): split by count so
        // that oversized leaves cannot happen.
        None => {
            let mid = prims.len() / 2;
            (mid, [Extent::of(&prims[..mid]), Extent::of(&prims[mid..])])
        }
    }
}

/// Moves the primitives `left` takes before the others; returns where the
/// others start and both sides' extents, gathered on the way.
fn partition(prims: &mut [Prim], left: impl Fn(&Prim) -> bool) -> (usize, [Extent; 2]) {
    let mut mid = 0;
    let (mut l, mut r) = (Extent::EMPTY, Extent::EMPTY);
    for i in 0..prims.len() {
        if left(&prims[i]) {
            l = l.add(&prims[i]);
            prims.swap(i, mid);
            mid += 1;
        } else {
            r = r.add(&prims[i]);
        }
    }
    (mid, [l, r])
}

fn node(b: Box3, first: u32, count: u32) -> GpuBvhNode {
    GpuBvhNode {
        min: b.min.to_array(),
        right_or_first: first,
        max: b.max.to_array(),
        count,
    }
}

/// Slack for spheres: their f32 centre and radius each round on their own, so
/// the f32 sphere can poke out of the f64 one by a few ulps of its extent.
fn widen(b: Bounds) -> Bounds {
    let slack = (b.min.abs().max(b.max.abs())) * (4.0 * f32::EPSILON as f64);
    Bounds {
        min: b.min - slack,
        max: b.max + slack,
    }
}

fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x {
        f.next_down()
    } else {
        f
    }
}

fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x {
        f.next_up()
    } else {
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Building subtrees on several threads makes the same tree, node for
    /// node, as building them one after the other.
    #[test]
    fn parallel_build_is_the_sequential_tree() {
        use crate::scene::{Material, Triangle, Vertex};
        let mut state = 7u32;
        let mut next = || {
            state = crate::hash::hash_u32(state);
            f64::from(state) / f64::from(u32::MAX) * 20.0 - 10.0
        };
        let material = Material {
            kd: DVec3::ONE,
            ks: DVec3::ZERO,
            shininess: 1.0,
        };
        let mut scene = Scene::default();
        let material = scene.add_material(material);
        for _ in 0..20_000 {
            let c = DVec3::new(next(), next(), next() - 20.0);
            let vertices = [0.0, 0.1, 0.2].map(|d| Vertex {
                position: c + DVec3::new(d * next(), d * next(), d),
                normal: DVec3::Z,
                material,
            });
            scene.triangles.push(Triangle {
                vertices,
                velocity: DVec3::ZERO,
            });
        }
        let parallel = Bvh::build_swept_with(&scene, 0.0, 64);
        let sequential = Bvh::build_swept_with(&scene, 0.0, usize::MAX);
        assert!(parallel.nodes.len() > 10_000);
        assert_eq!(parallel.nodes, sequential.nodes);
        assert_eq!(parallel.prim_refs, sequential.prim_refs);
        assert_eq!(parallel.depth, sequential.depth);
    }

    #[test]
    fn outward_rounding_contains_the_f64_value() {
        for x in [0.1, -0.1, 1e-30, -3.3e7, 123.456] {
            assert!((round_down(x) as f64) <= x && (round_up(x) as f64) >= x);
        }
    }
}
