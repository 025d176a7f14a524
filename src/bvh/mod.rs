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

mod build;
pub mod lights_on_surfaces;
pub mod node;
pub(crate) mod refit;
pub mod wide;

use glam::{DVec3, Vec3A};
use rayon::prelude::*;

use self::build::Box3;
use crate::features::Features;
use crate::scene::{Bounds, Effects, Scene};
pub use node::{GpuBvhNode, BVH_MAX_DEPTH, SPHERE_BIT};

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
        // Spheres, then triangles; on every thread (a fifth of a 2M-triangle
        // build on one).
        let spheres = scene.spheres.len();
        let (boxes, refs) = rayon::join(
            || prim_boxes(scene, span),
            || {
                (0..spheres as u32)
                    .map(|i| i | SPHERE_BIT)
                    .chain(0..scene.triangles.len() as u32)
                    .collect()
            },
        );
        let tree = build::build(boxes, refs, parallel_min);
        let mut bvh = Bvh {
            scale,
            nodes: tree.nodes,
            prim_refs: tree.refs,
            depth: tree.depth,
            ..Bvh::default()
        };
        bvh.surfaces_at_lights =
            crate::bvh::lights_on_surfaces::find(scene, &bvh.nodes, &bvh.prim_refs);
        bvh
    }
}

/// Subtrees of at least this many primitives build on their own threads.
const PARALLEL_MIN: usize = 4096;
/// Primitives a thread takes at a time where the boxes are made.
const PAR_CHUNK: usize = 1 << 15;

impl Box3 {
    /// `b` rounded outward.
    fn outward(b: Bounds) -> Box3 {
        Box3 {
            min: Vec3A::from_array(b.min.to_array().map(round_down)),
            max: Vec3A::from_array(b.max.to_array().map(round_up)),
        }
    }
}

/// Sphere `i`'s box over the next `span` seconds, with `widen`'s slack.
fn sphere_box(scene: &Scene, i: usize, span: f64) -> Box3 {
    Box3::outward(widen(scene.spheres[i].swept_bounds(span)))
}

/// Triangle `i`'s box over the next `span` seconds; a moving one with
/// `widen`'s slack.
fn triangle_box(scene: &Scene, i: usize, span: f64) -> Box3 {
    let t = &scene.triangles[i];
    Box3::outward(if span > 0.0 && t.velocity != DVec3::ZERO {
        widen(t.swept_bounds(span))
    } else {
        t.bounds()
    })
}

/// Every primitive's box, spheres then triangles; on every thread (a fifth
/// of a 2M-triangle build on one).
fn prim_boxes(scene: &Scene, span: f64) -> Vec<Box3> {
    let spheres = scene.spheres.len();
    (0..spheres + scene.triangles.len())
        .into_par_iter()
        .with_min_len(PAR_CHUNK)
        .map(|i| {
            if i < spheres {
                sphere_box(scene, i, span)
            } else {
                triangle_box(scene, i - spheres, span)
            }
        })
        .collect()
}

/// The box of primitive reference `r` (`SPHERE_BIT` set for a sphere).
#[cfg(test)]
fn prim_box(scene: &Scene, r: u32, span: f64) -> Box3 {
    if r & SPHERE_BIT != 0 {
        sphere_box(scene, (r & !SPHERE_BIT) as usize, span)
    } else {
        triangle_box(scene, r as usize, span)
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

/// `x` rounded to f32 towards -infinity. Without branches: whether the
/// nearest f32 lies above `x` is a coin toss, which a branch mispredicts
/// half the time (a third of a refit's time on the 239k-triangle wave).
fn round_down(x: f64) -> f32 {
    let f = x as f32;
    let bits = f.to_bits();
    let down = if f > 0.0 {
        bits - 1
    } else if f < 0.0 {
        bits + 1
    } else {
        // Below zero: the negative number nearest it.
        0x8000_0001
    };
    f32::from_bits(if f64::from(f) > x { down } else { bits })
}

/// `x` rounded to f32 towards +infinity (`round_down`'s mirror).
fn round_up(x: f64) -> f32 {
    let f = x as f32;
    let bits = f.to_bits();
    let up = if f > 0.0 {
        bits + 1
    } else if f < 0.0 {
        bits - 1
    } else {
        1
    };
    f32::from_bits(if f64::from(f) < x { up } else { bits })
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
        for x in [
            0.1, -0.1, 1e-30, -1e-50, 1e-50, -3.3e7, 123.456, 1e39, -1e39, 0.0, -0.0, 0.5,
        ] {
            let (down, up) = (round_down(x), round_up(x));
            assert!((down as f64) <= x && (up as f64) >= x, "{x}");
            // The nearest such f32: one step further crosses `x`.
            assert!(down == f32::MAX || down.next_up() as f64 > x, "{x}: {down}");
            assert!(up == f32::MIN || (up.next_down() as f64) < x, "{x}: {up}");
        }
        assert_eq!(round_down(f64::INFINITY), f32::INFINITY);
        assert_eq!(round_up(f64::NEG_INFINITY), f32::NEG_INFINITY);
        assert_eq!(round_down(0.5), 0.5);
    }
}
