//! The packing of a `Scene` and its `Bvh` into the GPU's buffers, in f32:
//! the 4-wide tree quantised, triangles in leaf order where that pays,
//! materials in a table, lights with their surface skips.

use std::collections::HashMap;

use bytemuck::Pod;

use super::types::*;
use crate::bvh::Bvh;
use crate::camera::Camera;
use crate::features::Features;
use crate::scene::{Effects, LightShape, Sampler, Scene};

/// A scene packed into the buffers the shader reads, in f32.
///
/// Vulkan forbids zero-sized buffers, so `padded` gives each list at least one
/// (zeroed) element; counts that matter travel in `GpuFrame` and the BVH.
#[derive(Clone, Debug, Default)]
pub struct GpuScene {
    /// The spheres.
    pub spheres: Vec<GpuSphere>,
    /// The triangles, with their normals, velocities and every reference
    /// to them, in the order `scene_triangles` gives.
    pub triangles: Vec<GpuTriangle>,
    /// Per triangle, its corners' normals.
    pub normals: Vec<GpuTriangleNormals>,
    /// The distinct materials of the triangle corners.
    pub materials: Vec<GpuMaterial>,
    /// The lights.
    pub lights: Vec<GpuLight>,
    /// The BVH collapsed to four children a node.
    pub nodes: Vec<GpuWideNode>,
    /// `Bvh::prim_refs`, the last of each leaf marked with `LEAF_END`.
    pub prim_refs: Vec<u32>,
    /// The surfaces through point lights, each light's run at its
    /// `skip_first`; empty when no light lies on a surface.
    pub skips: Vec<u32>,
    /// xyz = velocity of each sphere, then each triangle; empty when
    /// nothing moves.
    pub velocities: Vec<[f32; 4]>,
    /// The ambient colour.
    pub ambient: [f32; 3],
    /// Empty: the triangles are in the scene's order. Otherwise (a scene
    /// without spheres, of at most 2^28 - 8 triangles, no leaf over 8)
    /// they are in leaf order, and packed triangle i is the scene's
    /// triangle `scene_triangles[i]`: reference slot r (`prim_refs[r]`) is
    /// then triangle r and each leaf word holds its count
    /// (`LEAF_COUNT_SHIFT`), so a leaf's triangles lie together and the
    /// shader (`LEAF_ORDER`) reads them without reading references. Ids
    /// leaving the GPU go back to the scene's (`scene_prim`).
    pub scene_triangles: Vec<u32>,
}

/// The binary tree collapsed and quantised for the shader: a leaf lane
/// names its first primitive reference (`leaf_runs` marks where each run
/// ends).
pub(super) fn wide_nodes(bvh: &Bvh, leaf_order: bool) -> Vec<GpuWideNode> {
    use rayon::prelude::*;
    crate::bvh::wide::collapse_nodes(bvh, |leaf| leaf_word(leaf, leaf_order))
        .par_iter()
        .with_min_len(1 << 12)
        .map(quantise)
        .collect()
}

/// The child word of a leaf lane (`WIDE_LEAF`, `LEAF_COUNT_SHIFT`).
fn leaf_word(leaf: &GpuBvhNode, leaf_order: bool) -> u32 {
    let count = if leaf_order {
        (leaf.count - 1) << LEAF_COUNT_SHIFT
    } else {
        0
    };
    WIDE_LEAF | count | leaf.right_or_first
}

/// `n`'s boxes in 8 bits an axis, each holding the f32 box it replaces.
fn quantise(n: &crate::bvh::wide::Node4) -> GpuWideNode {
    // An array, not a vector: one per node of a tree of millions.
    let mut lanes = [0usize; 4];
    let mut count = 0;
    for l in 0..4 {
        if n.child[l] != WIDE_EMPTY {
            lanes[count] = l;
            count += 1;
        }
    }
    let used = &lanes[..count];
    let mut origin = [0.0f32; 4];
    let mut exps = 0u32;
    // Bytes by bound (lo x y z, hi x y z) and lane.
    let mut q = [[0u32; 4]; 6];
    for a in 0..3 {
        let lo = used
            .iter()
            .map(|&l| n.lo[a][l])
            .fold(f32::INFINITY, f32::min);
        let hi = used
            .iter()
            .map(|&l| n.hi[a][l])
            .fold(f32::NEG_INFINITY, f32::max);
        let axis = QuantAxis::new(lo, hi);
        origin[a] = axis.origin;
        exps |= axis.biased << (8 * a);
        for &l in used {
            q[a][l] = axis.below(n.lo[a][l]);
            q[3 + a][l] = axis.above(n.hi[a][l]);
        }
    }
    origin[3] = f32::from_bits(exps);
    let pack = |b: [u32; 4]| b[0] | b[1] << 8 | b[2] << 16 | b[3] << 24;
    GpuWideNode {
        origin,
        lo_hi: [pack(q[0]), pack(q[1]), pack(q[2]), pack(q[3])],
        hi_yz: [pack(q[4]), pack(q[5]), 0, 0],
        child: n.child,
    }
}

/// One axis of a node's quantisation: bound = `origin + q * 2^(biased - 127)`
/// for a byte q, computed in f32 as the shader does.
#[derive(Clone, Copy, Debug)]
struct QuantAxis {
    origin: f32,
    biased: u32,
}

impl QuantAxis {
    /// Steps small enough that 255 of them reach from `lo` to `hi`.
    /// Render-space boxes are finite (`Scene::render_scale`); a non-finite
    /// one gets the widest range there is, never a smaller one.
    fn new(lo: f32, hi: f32) -> QuantAxis {
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            return QuantAxis {
                origin: -f32::MAX,
                biased: 254,
            };
        }
        let span = (f64::from(hi) - f64::from(lo)) / 255.0;
        let e = if span > 0.0 {
            span.log2().ceil() as i32
        } else {
            -126
        };
        let mut axis = QuantAxis {
            origin: lo,
            biased: (e.clamp(-126, 127) + 127) as u32,
        };
        // log2 in f64 may round a power of two's neighbour onto it.
        while axis.biased < 254 && axis.at(255) < hi {
            axis.biased += 1;
        }
        axis
    }

    /// The power of two one byte stands for.
    fn step(self) -> f32 {
        f32::from_bits(self.biased << 23)
    }

    /// The bound byte `k` stands for. `k * step` is exact (8 bits times a
    /// power of two), so a fused multiply-add gives the same.
    fn at(self, k: u32) -> f32 {
        self.origin + k as f32 * self.step()
    }

    /// The largest byte whose bound is at most `x`.
    fn below(self, x: f32) -> u32 {
        let step = f64::from(self.step());
        let guess = ((f64::from(x) - f64::from(self.origin)) / step).floor();
        let mut k = guess.clamp(0.0, 255.0) as u32;
        while k > 0 && self.at(k) > x {
            k -= 1;
        }
        k
    }

    /// The smallest byte whose bound is at least `x` (255 where none is).
    fn above(self, x: f32) -> u32 {
        let step = f64::from(self.step());
        let guess = ((f64::from(x) - f64::from(self.origin)) / step).ceil();
        let mut k = guess.clamp(0.0, 255.0) as u32;
        while k < 255 && self.at(k) < x {
            k += 1;
        }
        while k > 0 && self.at(k - 1) >= x {
            k -= 1;
        }
        k
    }
}

/// The primitive references with the last of each leaf marked, so that a
/// leaf lane needs no count; in leaf order slot r's reference is r.
fn leaf_runs(bvh: &Bvh, leaf_order: bool) -> Vec<u32> {
    let mut refs = if leaf_order {
        (0..bvh.prim_refs.len() as u32).collect()
    } else {
        bvh.prim_refs.clone()
    };
    for n in bvh.nodes.iter().filter(|n| n.count > 0) {
        refs[(n.right_or_first + n.count - 1) as usize] |= LEAF_END;
    }
    refs
}

pub(super) fn f3(v: glam::DVec3) -> [f32; 3] {
    v.as_vec3().to_array()
}

pub(super) fn f4(v: glam::DVec3) -> [f32; 4] {
    v.as_vec3().extend(0.0).to_array()
}

/// The lights, and the surfaces through each (`skips`, each light's run at
/// its `skip_first`), as packed triangle indices where the triangles are in
/// leaf order (`scene_triangles`).
pub(super) fn pack_lights(
    scene: &Scene,
    bvh: &Bvh,
    scene_triangles: &[u32],
) -> (Vec<GpuLight>, Vec<u32>) {
    // A scene triangle's packed index (only the skips need it).
    let mut packed_index = Vec::new();
    if !scene_triangles.is_empty() && !bvh.surfaces_at_lights.iter().all(Vec::is_empty) {
        packed_index = vec![0; scene_triangles.len()];
        for (i, &t) in scene_triangles.iter().enumerate() {
            packed_index[t as usize] = i as u32;
        }
    }
    let packed = |r: u32| packed_index.get(r as usize).copied().unwrap_or(r);
    let mut skips = Vec::new();
    let lights = scene
        .lights
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let through = bvh.surfaces_at_lights.get(i).map_or(&[][..], Vec::as_slice);
            let skip_first = skips.len() as u32;
            skips.extend(through.iter().map(|&r| packed(r)));
            let mut g = GpuLight {
                skip_first,
                skip_count: through.len() as u32,
                position: f3(l.position),
                color: f3(l.color),
                velocity: f3(l.velocity),
                ..GpuLight::default()
            };
            match l.shape {
                LightShape::Point => g.kind = LIGHT_POINT,
                LightShape::Sphere { radius } => {
                    g.kind = LIGHT_SPHERE;
                    g.radius = radius as f32;
                }
                LightShape::Rect { edge_u, edge_v } => {
                    g.kind = LIGHT_RECT;
                    g.edge_u = f3(edge_u);
                    g.edge_v = f3(edge_v);
                }
            }
            g
        })
        .collect();
    (lights, skips)
}

impl GpuScene {
    /// Packs `scene` and its tree, in render space (`bvh.scale`).
    pub fn pack(scene: &Scene, bvh: &Bvh) -> GpuScene {
        let scene = &*scene.in_render_space(bvh.scale);
        let spheres = scene
            .spheres
            .iter()
            .map(|s| GpuSphere {
                center: f3(s.center),
                radius: s.radius as f32,
                kd: f3(s.material.kd),
                shininess: s.material.shininess as f32,
                ks: f3(s.material.ks),
                _pad: 0.0,
            })
            .collect();
        // Materials are told apart by their f32 bits: the table holds exactly
        // the values per-corner attributes would.
        let mut materials: Vec<GpuMaterial> = Vec::new();
        let mut index_of: HashMap<[u32; 7], u32> = HashMap::new();
        let mut material_index = |m: &crate::scene::Material| {
            let material = GpuMaterial {
                kd: f3(m.kd),
                shininess: m.shininess as f32,
                ks: f3(m.ks),
                _pad: 0.0,
            };
            let [r, g, b] = material.kd;
            let [sr, sg, sb] = material.ks;
            let key = [r, g, b, sr, sg, sb, material.shininess].map(f32::to_bits);
            *index_of.entry(key).or_insert_with(|| {
                materials.push(material);
                (materials.len() - 1) as u32
            })
        };
        let ids: Vec<u32> = scene.materials.iter().map(&mut material_index).collect();
        // Leaf order where every reference is to a triangle (each one's
        // slot is then its index: the tree references every primitive
        // once) and every leaf's count fits its word.
        let leaf_order = scene.spheres.is_empty()
            && bvh.prim_refs.len() == scene.triangles.len()
            && scene.triangles.len() <= LEAF_ORDER_MAX
            && bvh.nodes.iter().all(|n| n.count <= LEAF_COUNT_MASK + 1);
        let scene_triangles = if leaf_order {
            bvh.prim_refs.clone()
        } else {
            Vec::new()
        };
        // Packed triangle i.
        let triangle =
            |i: usize| &scene.triangles[scene_triangles.get(i).map_or(i, |&t| t as usize)];
        let ordered = || (0..scene.triangles.len()).map(triangle);
        // The tree beside the triangles, each on every thread it can use.
        use rayon::prelude::*;
        // One pass over the scene's triangles for both lists: in leaf
        // order each read is a miss.
        let ((triangles, normals), (nodes, prim_refs)) = rayon::join(
            || -> (Vec<_>, Vec<_>) {
                (0..scene.triangles.len())
                    .into_par_iter()
                    .with_min_len(1 << 12)
                    .map(|i| {
                        let t = triangle(i);
                        let n = t.vertices.map(|v| f3(v.normal));
                        (
                            GpuTriangle {
                                v: t.vertices.map(|v| {
                                    let mut p = f4(v.position);
                                    p[3] = f32::from_bits(ids[v.material as usize]);
                                    p
                                }),
                            },
                            GpuTriangleNormals {
                                n: *n.as_flattened().first_chunk().expect("9 values"),
                            },
                        )
                    })
                    .unzip()
            },
            || (wide_nodes(bvh, leaf_order), leaf_runs(bvh, leaf_order)),
        );
        let (lights, skips) = pack_lights(scene, bvh, &scene_triangles);
        let velocities = if scene.has_motion() {
            let s = scene.spheres.iter().map(|s| f4(s.velocity));
            s.chain(ordered().map(|t| f4(t.velocity))).collect()
        } else {
            Vec::new()
        };
        GpuScene {
            spheres,
            triangles,
            normals,
            materials,
            lights,
            nodes,
            prim_refs,
            skips,
            velocities,
            ambient: f3(scene.ambient),
            scene_triangles,
        }
    }

    /// Whether the triangles are in leaf order (`scene_triangles`).
    pub fn leaf_order(&self) -> bool {
        !self.scene_triangles.is_empty()
    }

    /// The scene's id of the primitive the shader calls `prim` (a
    /// reference without `LEAF_END`, or `NO_HIT`).
    pub fn scene_prim(&self, prim: u32) -> u32 {
        if prim & SPHERE_BIT != 0 {
            return prim;
        }
        self.scene_triangles
            .get(prim as usize)
            .copied()
            .unwrap_or(prim)
    }

    /// Bytes of each list, as uploaded.
    pub fn list_bytes(&self) -> [u64; 9] {
        let b = |len: usize, size: usize| (len.max(1) * size) as u64;
        use std::mem::size_of;
        [
            b(self.spheres.len(), size_of::<GpuSphere>()),
            b(self.triangles.len(), size_of::<GpuTriangle>()),
            b(self.normals.len(), size_of::<GpuTriangleNormals>()),
            b(self.materials.len(), size_of::<GpuMaterial>()),
            b(self.lights.len(), size_of::<GpuLight>()),
            b(self.nodes.len(), size_of::<GpuWideNode>()),
            b(self.prim_refs.len(), 4),
            b(self.velocities.len(), 16),
            b(self.skips.len(), 4),
        ]
    }

    /// `effects` as resolved for the scene; `features` decides whether the
    /// shutter is open (only a scene with motion blur sees a non-zero one).
    pub fn frame(
        &self,
        camera: &Camera,
        background: [f32; 3],
        effects: &Effects,
        features: &Features,
    ) -> GpuFrame {
        GpuFrame {
            background: [background[0], background[1], background[2], 1.0],
            ambient: [self.ambient[0], self.ambient[1], self.ambient[2], 0.0],
            half_extent: camera.half_extent_f32(),
            size: [camera.width, camera.height],
            node_count: self.nodes.len() as u32,
            light_count: self.lights.len() as u32,
            sphere_count: self.spheres.len() as u32,
            seed: effects.seed,
            spp: effects.spp,
            shadow_samples: effects.shadow_samples,
            reflect_depth: effects.reflect_depth,
            shutter: if features.motion_blur {
                effects.shutter_seconds() as f32
            } else {
                0.0
            },
            chunk_shift: [0; 4],
            addresses: [[0; 4]; 3],
            sampling: match effects.sampler {
                Sampler::Stratified => SAMPLER_STRATIFIED,
                Sampler::Sobol => SAMPLER_SOBOL,
            },
            _pad0: 0,
            _pad: [0; 2],
        }
    }
}

/// `items` as bytes, or one zeroed element's bytes when empty.
pub fn padded<T: Pod + Default>(items: &[T]) -> std::borrow::Cow<'_, [u8]> {
    if items.is_empty() {
        std::borrow::Cow::Owned(bytemuck::bytes_of(&T::default()).to_vec())
    } else {
        std::borrow::Cow::Borrowed(bytemuck::cast_slice(items))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::wide::{collapse_nodes, tests::scene, Node4};
    use glam::Vec4;

    #[test]
    fn a_list_address_is_low_then_high_word_two_lists_to_an_element() {
        let mut frame = GpuFrame::default();
        frame.set_address(3, 0x1234_5678_9abc_def0);
        frame.set_address(4, 7);
        assert_eq!(
            frame.addresses,
            [[0; 4], [0, 0, 0x9abc_def0, 0x1234_5678], [7, 0, 0, 0]]
        );
    }

    /// (low, high) of each lane's box by axis, as the shader decodes them.
    fn decoded(g: &GpuWideNode) -> [[(f32, f32); 4]; 3] {
        let exps = g.origin[3].to_bits();
        let highs = [g.lo_hi[3], g.hi_yz[0], g.hi_yz[1]];
        std::array::from_fn(|a| {
            let step = f32::from_bits(((exps >> (8 * a)) & 0xff) << 23);
            let at =
                |word: u32, lane: usize| g.origin[a] + ((word >> (8 * lane)) & 0xff) as f32 * step;
            std::array::from_fn(|l| (at(g.lo_hi[a], l), at(highs[a], l)))
        })
    }

    #[test]
    fn quantised_boxes_hold_their_children_tightly() {
        let mut state = 11u32;
        let mut unit = || {
            state = crate::hash::hash_u32(state);
            state as f32 / u32::MAX as f32
        };
        for case in 0..4000 {
            // Scales from 2^-10 to 2^14 (render space), flat boxes, one to
            // four lanes in use.
            let scale = 2f32.powi((case % 25) - 10);
            let used = 1 + case as usize % 4;
            let mut n = Node4 {
                lo: [Vec4::INFINITY; 3],
                hi: [Vec4::INFINITY; 3],
                child: [WIDE_EMPTY; 4],
                leaves: [0; 4],
            };
            let centre = [unit(), unit(), unit()].map(|c| (c - 0.5) * 4.0 * scale);
            for l in 0..used {
                n.child[l] = l as u32 + 1;
                for (a, c) in centre.iter().enumerate() {
                    let lo = c + (unit() - 0.5) * scale;
                    let size = if case % 7 == 0 { 0.0 } else { unit() * scale };
                    n.lo[a][l] = lo;
                    n.hi[a][l] = lo + size;
                }
            }
            let g = quantise(&n);
            assert_eq!(g.child, n.child);
            let boxes = decoded(&g);
            for (a, axis) in boxes.iter().enumerate() {
                let span = (0..used).map(|l| n.hi[a][l]).fold(f32::MIN, f32::max)
                    - (0..used).map(|l| n.lo[a][l]).fold(f32::MAX, f32::min);
                // One step is at most span / 127.5 (a power of two at most
                // twice span / 255), or the least step when span is 0.
                let step = (span / 127.5).max(f32::from_bits(1 << 23));
                for (l, &(lo, hi)) in axis.iter().enumerate().take(used) {
                    let (want_lo, want_hi) = (n.lo[a][l], n.hi[a][l]);
                    assert!(
                        lo <= want_lo && hi >= want_hi,
                        "case {case} axis {a} lane {l}"
                    );
                    assert!(
                        want_lo - lo <= 1.01 * step,
                        "case {case}: low {lo} for {want_lo}"
                    );
                    assert!(
                        hi - want_hi <= 1.01 * step,
                        "case {case}: high {hi} for {want_hi}"
                    );
                }
            }
        }
    }

    #[test]
    fn every_leaf_lane_runs_over_one_binary_leaf() {
        for n in [1, 2, 5, 100, 3000] {
            let scene = scene(n);
            let bvh = Bvh::build(&scene);
            let gpu = GpuScene::pack(&scene, &bvh);
            let wide = collapse_nodes(&bvh, |leaf| WIDE_LEAF | leaf.right_or_first);
            assert_eq!(gpu.nodes.len(), wide.len());
            assert!(gpu.leaf_order());
            let mut runs = Vec::new();
            for (g, w) in gpu.nodes.iter().zip(&wide) {
                let first_of = |c: u32| c & ((1 << LEAF_COUNT_SHIFT) - 1);
                let plain = g.child.map(|c| match c {
                    WIDE_EMPTY => c,
                    c if c & WIDE_LEAF != 0 => WIDE_LEAF | first_of(c),
                    c => c,
                });
                assert_eq!(plain, w.child);
                for &c in g
                    .child
                    .iter()
                    .filter(|&&c| c != WIDE_EMPTY && c & WIDE_LEAF != 0)
                {
                    let first = first_of(c) as usize;
                    let len = gpu.prim_refs[first..]
                        .iter()
                        .position(|r| r & LEAF_END != 0)
                        .expect("every run ends")
                        + 1;
                    // The word's count is the run's.
                    assert_eq!((c >> LEAF_COUNT_SHIFT & LEAF_COUNT_MASK) as usize + 1, len);
                    runs.push((first as u32, len as u32));
                }
            }
            runs.sort();
            let mut want: Vec<_> = bvh
                .nodes
                .iter()
                .filter(|n| n.count > 0)
                .map(|n| (n.right_or_first, n.count))
                .collect();
            want.sort();
            assert_eq!(runs, want, "{n} triangles");
            // In leaf order (a scene of triangles only), slot r is triangle r.
            let refs: Vec<u32> = gpu.prim_refs.iter().map(|r| r & !LEAF_END).collect();
            assert_eq!(refs, (0..n as u32).collect::<Vec<_>>());
            let ids: Vec<u32> = refs.iter().map(|&r| gpu.scene_prim(r)).collect();
            assert_eq!(ids, bvh.prim_refs);
        }
    }

    #[test]
    fn triangles_go_in_leaf_order_with_everything_that_names_them() {
        let mut scene = scene(300);
        for (i, t) in scene.triangles.iter_mut().enumerate() {
            t.velocity = glam::DVec3::new(i as f64, 0.0, 0.0);
            t.vertices[1].normal = glam::DVec3::new(0.0, 1.0, i as f64).normalize();
        }
        let moving = Scene {
            lights: vec![crate::scene::Light::point(
                glam::DVec3::ZERO,
                glam::DVec3::ONE,
            )],
            ..scene.clone()
        };
        let mut bvh = Bvh::build(&moving);
        assert_ne!(
            bvh.prim_refs,
            (0..300).collect::<Vec<u32>>(),
            "a shuffled order"
        );
        bvh.surfaces_at_lights = vec![vec![5, 17, 299]];
        let gpu = GpuScene::pack(&moving, &bvh);
        assert!(gpu.leaf_order());
        for (r, &t) in bvh.prim_refs.iter().enumerate() {
            let want = &moving.triangles[t as usize];
            assert_eq!(gpu.triangles[r].v[2][2], want.vertices[2].position.z as f32);
            assert_eq!(gpu.normals[r].n[5], want.vertices[1].normal.z as f32);
            assert_eq!(gpu.velocities[r][0], t as f32);
            assert_eq!(gpu.scene_prim(r as u32), t);
        }
        let skipped: Vec<u32> = gpu.skips.iter().map(|&r| gpu.scene_prim(r)).collect();
        assert_eq!(skipped, [5, 17, 299]);
        assert_eq!(gpu.scene_prim(crate::probe::NO_HIT), crate::probe::NO_HIT);
        // A sphere among them: every list stays in the scene's order.
        let mut mixed = moving.clone();
        mixed.spheres.push(crate::scene::Sphere {
            center: glam::DVec3::new(0.0, 0.0, -5.0),
            radius: 1.0,
            material: scene.materials[0],
            velocity: glam::DVec3::ZERO,
        });
        let bvh = Bvh::build(&mixed);
        let gpu = GpuScene::pack(&mixed, &bvh);
        assert!(!gpu.leaf_order());
        let refs: Vec<u32> = gpu.prim_refs.iter().map(|r| r & !LEAF_END).collect();
        assert_eq!(refs, bvh.prim_refs);
        for i in 0..300 {
            assert_eq!(gpu.velocities[1 + i][0], i as f32);
        }
        assert_eq!(gpu.scene_prim(7), 7);
    }
}
