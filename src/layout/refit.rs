//! A packed scene moved to the next frame of its animation: the same
//! primitives, moved, with the tree refitted to them (`Bvh::refit`). What
//! moving changes is written again (corners, sphere centres, the tree's
//! quantised boxes, the lights and the surfaces through them); what it
//! cannot change is kept (normals, materials, velocities, the leaves'
//! references), so the next upload sends only the lists that changed.

use rayon::prelude::*;

use super::pack::{f3, f4, pack_lights, wide_nodes};
use super::GpuScene;
use crate::bvh::Bvh;
use crate::scene::Scene;

impl GpuScene {
    /// Moves this packing to `scene`, the primitives it was packed from
    /// moved along their velocities (`Scene::at_time` of the same scene, in
    /// view space), with `bvh` the tree it was packed with, refitted to
    /// them. The result is what `GpuScene::pack(scene, bvh)` makes, up to
    /// the four-wide tree's shape, which is collapsed afresh from the
    /// refitted boxes.
    pub(crate) fn refit(&mut self, scene: &Scene, bvh: &Bvh) {
        let scene = &*scene.in_render_space(bvh.scale);
        for (packed, s) in self.spheres.iter_mut().zip(&scene.spheres) {
            packed.center = f3(s.center);
        }
        let order = &self.scene_triangles;
        self.triangles
            .par_iter_mut()
            .enumerate()
            .with_min_len(1 << 12)
            .for_each(|(i, packed)| {
                let t = &scene.triangles[order.get(i).map_or(i, |&t| t as usize)];
                for (corner, v) in packed.v.iter_mut().zip(&t.vertices) {
                    // The material's index rides in w.
                    let w = corner[3];
                    *corner = f4(v.position);
                    corner[3] = w;
                }
            });
        self.nodes = wide_nodes(bvh, self.leaf_order());
        (self.lights, self.skips) = pack_lights(scene, bvh, &self.scene_triangles);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::wide::tests::scene;
    use glam::DVec3;

    /// Every list the shader reads, as the bytes uploaded.
    fn lists(g: &GpuScene) -> Vec<Vec<u8>> {
        use crate::layout::padded;
        [
            padded(&g.spheres),
            padded(&g.triangles),
            padded(&g.normals),
            padded(&g.materials),
            padded(&g.lights),
            padded(&g.nodes),
            padded(&g.prim_refs),
            padded(&g.skips),
            padded(&g.velocities),
        ]
        .map(|l| l.into_owned())
        .into()
    }

    /// Moved and refitted, the packing equals a fresh packing of the moved
    /// scene with the refitted tree, list for list.
    #[test]
    fn a_refitted_packing_is_a_fresh_one() {
        let mut scene = scene(3000);
        for (i, t) in scene.triangles.iter_mut().enumerate() {
            t.velocity = DVec3::new((i % 5) as f64 - 2.0, (i % 3) as f64 - 1.0, 0.5);
        }
        scene.lights.push(crate::scene::Light {
            position: DVec3::new(1.0, 5.0, -3.0),
            color: DVec3::ONE,
            shape: crate::scene::LightShape::Point,
            velocity: DVec3::new(0.5, 0.0, 0.0),
        });
        let mut bvh = Bvh::build(&scene);
        let mut packed = GpuScene::pack(&scene, &bvh);
        assert!(
            packed.leaf_order(),
            "the triangles-only scene packs in leaf order"
        );
        for time in [0.25, 1.5] {
            let moved = scene.at_time(time);
            assert!(bvh.refit(&moved, 0.0));
            packed.refit(&moved, &bvh);
            let fresh = GpuScene::pack(&moved, &bvh);
            assert_eq!(lists(&packed), lists(&fresh), "at {time} s");
            assert_eq!(packed.scene_triangles, fresh.scene_triangles);
        }
    }
}
