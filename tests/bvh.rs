//! The BVH: structural invariants on random and degenerate scenes, and
//! traversal equivalence: rendering through the BVH gives the same image as
//! brute force (one leaf holding every primitive), on the CPU and the GPU.

mod common;

use common::*;
use glam::DVec3;
use glint::bvh::Bvh;
use glint::camera::Camera;
use glint::cpu::Precision;
use glint::gpu::GpuRenderOptions;
use glint::images::compare::compare_framebuffers;
use glint::images::framebuffer::Framebuffer;
use glint::layout::{GpuBvhNode, GpuScene, BVH_MAX_DEPTH, SPHERE_BIT};
use glint::scene::{Bounds, Light, Material, Scene, Sphere, Triangle, Vertex};

/// A small deterministic generator (64-bit LCG, top bits), so failures replay.
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn in_range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
    fn point(&mut self) -> DVec3 {
        DVec3::new(
            self.in_range(-4.0, 4.0),
            self.in_range(-3.0, 3.0),
            self.in_range(-14.0, -5.0),
        )
    }
}

fn material(rng: &mut Lcg) -> Material {
    Material {
        kd: DVec3::new(rng.next(), rng.next(), rng.next()) * 0.7,
        ks: DVec3::splat(0.3),
        shininess: rng.in_range(1.0, 50.0),
    }
}

fn random_scene(seed: u64, spheres: usize, triangles: usize) -> Scene {
    let mut rng = Lcg(seed);
    let mut scene = Scene {
        ambient: DVec3::splat(0.1),
        ..Scene::default()
    };
    for _ in 0..spheres {
        scene.spheres.push(Sphere {
            center: rng.point(),
            radius: rng.in_range(0.05, 0.5),
            material: material(&mut rng),
            velocity: DVec3::ZERO,
        });
    }
    for _ in 0..triangles {
        let c = rng.point();
        let m = material(&mut rng);
        let m = scene.add_material(m);
        let v = |rng: &mut Lcg| Vertex {
            position: c + DVec3::new(
                rng.in_range(-0.6, 0.6),
                rng.in_range(-0.6, 0.6),
                rng.in_range(-0.6, 0.6),
            ),
            normal: DVec3::new(rng.in_range(-1.0, 1.0), rng.in_range(-1.0, 1.0), 1.0),
            material: m,
        };
        scene.triangles.push(Triangle {
            vertices: [v(&mut rng), v(&mut rng), v(&mut rng)],
            velocity: DVec3::ZERO,
        });
    }
    for p in [DVec3::new(-5.0, 6.0, 0.0), DVec3::new(4.0, 2.0, -3.0)] {
        scene.lights.push(Light::point(p, DVec3::splat(0.6)));
    }
    scene
}

fn contains(node: &GpuBvhNode, b: &Bounds) -> bool {
    (0..3).all(|i| f64::from(node.min[i]) <= b.min[i] && f64::from(node.max[i]) >= b.max[i])
}

/// Checks every structural invariant; returns (leaf count, largest leaf).
fn check_invariants(scene: &Scene, bvh: &Bvh) -> (usize, u32) {
    let n = scene.primitive_count();
    let mut seen = vec![0u32; n];
    let mut leaves = 0;
    let mut largest = 0;
    // (node index, depth), walked from the root with an explicit stack.
    let mut stack = vec![(0usize, 0u32)];
    while let Some((i, depth)) = stack.pop() {
        let node = &bvh.nodes[i];
        assert!(depth < BVH_MAX_DEPTH, "node {i} at depth {depth}");
        if node.count > 0 {
            leaves += 1;
            largest = largest.max(node.count);
            let first = node.right_or_first as usize;
            for &r in &bvh.prim_refs[first..first + node.count as usize] {
                let index = (r & !SPHERE_BIT) as usize;
                let (slot, bounds) = if r & SPHERE_BIT != 0 {
                    (index, scene.spheres[index].bounds())
                } else {
                    (scene.spheres.len() + index, scene.triangles[index].bounds())
                };
                seen[slot] += 1;
                assert!(
                    contains(node, &bounds),
                    "leaf {i} does not contain primitive {r:#x}"
                );
            }
        } else {
            let (l, r) = (i + 1, node.right_or_first as usize);
            assert!(r > l && r < bvh.nodes.len(), "node {i}: children {l}, {r}");
            for c in [l, r] {
                let child = &bvh.nodes[c];
                let b = Bounds {
                    min: DVec3::from_array(child.min.map(f64::from)),
                    max: DVec3::from_array(child.max.map(f64::from)),
                };
                assert!(contains(node, &b), "node {i} does not contain child {c}");
                stack.push((c, depth + 1));
            }
        }
    }
    assert!(
        seen.iter().all(|&s| s == 1),
        "every primitive exactly once: {seen:?}"
    );
    (leaves, largest)
}

#[test]
fn random_scenes_satisfy_the_invariants() {
    for seed in 1..=5 {
        let scene = random_scene(seed, 150, 350);
        let bvh = Bvh::build(&scene);
        let (leaves, largest) = check_invariants(&scene, &bvh);
        assert!(leaves > 500 / 4 / 2, "seed {seed}: only {leaves} leaves");
        assert!(largest <= 4, "seed {seed}: a leaf of {largest}");
    }
}

#[test]
fn coincident_primitives_still_split_into_small_leaves() {
    // All centroids equal: no SAH plane separates them; the builder must
    // still split by count rather than make one huge leaf.
    let mut scene = random_scene(7, 0, 0);
    let s = Sphere {
        center: DVec3::new(0.0, 0.0, -5.0),
        radius: 1.0,
        material: material(&mut Lcg(1)),
        velocity: DVec3::ZERO,
    };
    scene.spheres = vec![s; 200];
    let bvh = Bvh::build(&scene);
    let (_, largest) = check_invariants(&scene, &bvh);
    assert!(largest <= 4, "a leaf of {largest}");
}

/// The same scene with one leaf holding everything: brute-force traversal.
fn single_leaf(scene: &Scene, real: &Bvh) -> Bvh {
    let mut nodes = vec![real.nodes[0]];
    nodes[0].right_or_first = 0;
    nodes[0].count = scene.primitive_count() as u32;
    let mut prim_refs: Vec<u32> = (0..scene.spheres.len() as u32)
        .map(|i| i | SPHERE_BIT)
        .collect();
    prim_refs.extend(0..scene.triangles.len() as u32);
    Bvh {
        nodes,
        prim_refs,
        depth: 0,
        scale: real.scale,
        surfaces_at_lights: real.surfaces_at_lights.clone(),
    }
}

/// Traversal order decides which of two hits at exactly equal t is kept; such
/// ties (shared edges of the random triangles) may shade a little differently.
fn assert_same_image(what: &str, a: &Framebuffer, b: &Framebuffer) {
    let cmp = compare_framebuffers(a, b, 0.25).expect("same size");
    assert_within(what, a, b, &cmp, 0);
}

/// `scene` rendered through its BVH and through one leaf holding
/// everything gives the same image, on the CPU in both precisions and on
/// the GPU.
fn assert_bvh_equals_brute_force(name: &str, scene: &Scene) {
    let (w, h) = (160, 120);
    let camera = Camera::new(w, h);
    let bvh = Bvh::build(scene);
    let brute = single_leaf(scene, &bvh);
    for precision in [Precision::F32, Precision::F64] {
        let options = glint::cpu::CpuOptions {
            background: WHITE,
            precision,
            ..Default::default()
        };
        let a = glint::cpu::render(scene, &bvh, &camera, &options, &|_, _| {});
        let b = glint::cpu::render(scene, &brute, &camera, &options, &|_, _| {});
        assert_same_image(&format!("{name}-cpu-{precision:?}"), &a, &b);
    }
    if let Some(gpu) = gpu() {
        let gpu = gpu.lock().unwrap_or_else(|e| e.into_inner());
        let render = |bvh: &Bvh| {
            let packed = GpuScene::pack(scene, bvh);
            let options = GpuRenderOptions {
                tile_size: 64,
                ..Default::default()
            };
            gpu.renderer
                .render(&packed, &camera, WHITE, &options, &|_, _| {})
                .expect("GPU render")
                .0
        };
        assert_same_image(&format!("{name}-gpu"), &render(&bvh), &render(&brute));
    }
}

#[test]
fn bvh_traversal_equals_brute_force() {
    for seed in [11, 12] {
        let scene = random_scene(seed, 120, 300);
        assert_bvh_equals_brute_force(&format!("bvh-vs-brute-{seed}"), &scene);
    }
}

/// Spheres each 0.7 times the size of the last and as much nearer one
/// point: the SAH peels a few off a level, so the tree (binned on f32
/// centroids, distinct down to 0.7^250) runs to the depth cap, where the
/// rest share one leaf: walks 64 levels deep, into a leaf of many
/// references. The smallest spheres are below f32's range and render as
/// points, on both sides alike.
#[test]
fn a_tree_at_the_depth_cap_equals_brute_force() {
    let mut scene = random_scene(5, 0, 0);
    let material = material(&mut Lcg(3));
    for i in 0..300 {
        let s = 0.7f64.powi(i);
        scene.spheres.push(Sphere {
            center: DVec3::new(s, s, -4.0),
            radius: 0.3 * s,
            material,
            velocity: DVec3::ZERO,
        });
    }
    let bvh = Bvh::build(&scene);
    assert!(
        bvh.depth + 1 >= BVH_MAX_DEPTH,
        "depth {}: not at the cap",
        bvh.depth
    );
    assert_bvh_equals_brute_force("depth-cap", &scene);
}
