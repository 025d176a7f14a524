//! Refitting: the tree of a scene whose primitives moved, but whose
//! primitives are the same ones (an animation's next frame), keeps its
//! shape and takes new boxes, bottom up, instead of being built again.
//! Traversal stays exact whatever the boxes' quality (every box still holds
//! its primitives, rounded outward as a build rounds them), so a refitted
//! tree finds the hits a fresh one finds, up to which of two hits at
//! exactly the same t is kept; only its speed can suffer, which
//! `REFIT_LIMIT` bounds.

use rayon::prelude::*;

use super::build::Box3;
use super::{Bvh, SPHERE_BIT};
use crate::features::Features;
use crate::scene::{Effects, Scene};

/// A refitted tree whose SAH cost has grown past this factor of the cost
/// the tree had when it was built is built again. Moving the 239k
/// triangles of `gen_mesh.py 346` as a wave for a second (24 frames) grows
/// it by less than a percent a frame, so the wave never rebuilds; a scene
/// whose parts fly apart crosses it within a few frames, when each
/// further frame would trace through ever larger boxes.
pub(crate) const REFIT_LIMIT: f64 = 1.5;

impl Bvh {
    /// Refits the tree `Bvh::for_render(earlier, effects)` built to
    /// `scene`, the same primitives moved (`Scene::at_time` of the same
    /// scene, in the same space); false, with the tree unchanged, where
    /// that cannot be done: a different primitive count, or a scene whose
    /// extent moved it to another render scale. Then build afresh.
    pub fn refit_for_render(&mut self, scene: &Scene, effects: &Effects) -> bool {
        let span = if Features::of(scene, effects).motion_blur {
            effects.shutter_seconds()
        } else {
            0.0
        };
        self.refit(scene, span)
    }

    /// `refit_for_render` with boxes swept over the next `span` seconds
    /// (`Bvh::build_swept`).
    pub fn refit(&mut self, scene: &Scene, span: f64) -> bool {
        if self.prim_refs.len() != scene.primitive_count()
            || scene.render_scale() != self.scale
            || self.nodes.is_empty()
        {
            return false;
        }
        let scene = &*scene.in_render_space(self.scale);
        // The boxes in the scene's order first, streaming through it on
        // every thread; the leaves then read 32 bytes a primitive in their
        // order instead of a 192-byte triangle.
        let boxes = super::prim_boxes(scene, span);
        let index = |r: u32| {
            if r & SPHERE_BIT != 0 {
                (r & !SPHERE_BIT) as usize
            } else {
                scene.spheres.len() + r as usize
            }
        };
        let refs = &self.prim_refs;
        // Leaves from their primitives, on every thread; then each interior
        // node, children before parents (they come after it depth-first).
        self.nodes
            .par_iter_mut()
            .with_min_len(1 << 12)
            .for_each(|n| {
                if n.count > 0 {
                    let first = n.right_or_first as usize;
                    let b = refs[first..first + n.count as usize]
                        .iter()
                        .fold(Box3::EMPTY, |b, &r| b.union(boxes[index(r)]));
                    n.min = b.min.to_array();
                    n.max = b.max.to_array();
                }
            });
        for i in (0..self.nodes.len()).rev() {
            let n = self.nodes[i];
            if n.count == 0 {
                let (l, r) = (&self.nodes[i + 1], &self.nodes[n.right_or_first as usize]);
                let min = [0, 1, 2].map(|a| l.min[a].min(r.min[a]));
                let max = [0, 1, 2].map(|a| l.max[a].max(r.max[a]));
                self.nodes[i].min = min;
                self.nodes[i].max = max;
            }
        }
        self.surfaces_at_lights =
            crate::bvh::lights_on_surfaces::find(scene, &self.nodes, &self.prim_refs);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::prim_box;
    use crate::bvh::wide::tests::scene;
    use glam::DVec3;

    /// Every node's box holds its children's, and every leaf's its
    /// primitives' (as the builder rounds them): the tree is exact.
    fn assert_bounds_everything(scene: &Scene, bvh: &Bvh, span: f64) {
        let holds = |outer: ([f32; 3], [f32; 3]), inner: ([f32; 3], [f32; 3])| {
            (0..3).all(|a| outer.0[a] <= inner.0[a] && outer.1[a] >= inner.1[a])
        };
        let mut seen = vec![0u32; scene.primitive_count()];
        for (i, n) in bvh.nodes.iter().enumerate() {
            if n.count > 0 {
                let first = n.right_or_first as usize;
                for &r in &bvh.prim_refs[first..first + n.count as usize] {
                    let b = prim_box(scene, r, span);
                    assert!(
                        holds((n.min, n.max), (b.min.to_array(), b.max.to_array())),
                        "leaf {i} does not hold primitive {r}"
                    );
                    seen[r as usize] += 1;
                }
            } else {
                for c in [i + 1, n.right_or_first as usize] {
                    let c = &bvh.nodes[c];
                    assert!(holds((n.min, n.max), (c.min, c.max)), "node {i}");
                }
            }
        }
        assert!(seen.iter().all(|&k| k == 1), "every primitive once");
    }

    /// After every triangle moved, each its own way, the refitted tree
    /// bounds every primitive, keeps its shape, and costs more by the SAH
    /// than a fresh tree of the moved scene (which it is not).
    #[test]
    fn a_refitted_tree_bounds_every_moved_primitive() {
        let mut state = 3u32;
        let mut next = || {
            state = crate::hash::hash_u32(state);
            f64::from(state) / f64::from(u32::MAX) - 0.5
        };
        let mut scene = scene(5000);
        for t in &mut scene.triangles {
            t.velocity = DVec3::new(next(), next(), next()) * 8.0;
        }
        let mut bvh = Bvh::build(&scene);
        for (frame, span) in [(1.0, 0.0), (2.5, 0.0), (3.0, 0.1)] {
            let moved = scene.at_time(frame);
            let shape: Vec<_> = bvh
                .nodes
                .iter()
                .map(|n| (n.right_or_first, n.count))
                .collect();
            assert!(bvh.refit(&moved, span));
            assert_eq!(
                shape,
                bvh.nodes
                    .iter()
                    .map(|n| (n.right_or_first, n.count))
                    .collect::<Vec<_>>()
            );
            assert_bounds_everything(&moved, &bvh, span);
            let fresh = Bvh::build_swept(&moved, span);
            assert!(
                bvh.stats().sah_cost > fresh.stats().sah_cost,
                "frame {frame}"
            );
        }
    }

    /// Refitting to the scene the tree was built for gives the tree a build
    /// gives, node for node.
    #[test]
    fn refitting_in_place_changes_nothing() {
        let scene = scene(3000);
        let built = Bvh::build(&scene);
        let mut refitted = built.clone();
        assert!(refitted.refit(&scene, 0.0));
        assert_eq!(refitted.nodes, built.nodes);
    }

    /// A scene of other primitives is refused, the tree kept.
    #[test]
    fn another_scene_is_refused() {
        let mut bvh = Bvh::build(&scene(100));
        let before = bvh.nodes.clone();
        assert!(!bvh.refit(&scene(101), 0.0));
        assert_eq!(bvh.nodes, before);
    }
}
