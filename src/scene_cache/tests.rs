//! The cache's trees: a hit is the tree a build makes, any change to what
//! the builder reads is a miss, and an entry that is damaged or not a
//! sound tree of the scene is ignored and made again.

use glam::DVec3;

use super::bvh::{decode, encode, key, HIT, IGNORED, MISS};
use super::store::Kind;
use super::{SceneCache, MIN_PRIMITIVES};
use crate::bvh::Bvh;
use crate::scene::{Effects, Light, LightShape, Scene};
use crate::timing::Timings;

/// `n` random triangles (the wide tree's test scene) and a light on a
/// corner of the first, which its shadow rays treat as on that surface.
fn field(n: usize) -> Scene {
    let mut scene = crate::bvh::wide::tests::scene(n);
    scene.lights.push(Light {
        position: scene.triangles[0].vertices[0].position,
        color: DVec3::ONE,
        shape: LightShape::Point,
        velocity: DVec3::ZERO,
    });
    scene
}

fn cache(dir: &std::path::Path) -> SceneCache {
    SceneCache::new(dir.join("scenes"), 1 << 30)
}

fn effects() -> Effects {
    Effects::resolve(&Default::default())
}

/// The tree the cache hands back, and what it counted.
fn through(cache: &SceneCache, scene: &Scene) -> (Bvh, Timings) {
    let mut t = Timings::default();
    let bvh = cache.bvh_for_render(scene, &effects(), &mut t);
    (bvh, t)
}

fn same(a: &Bvh, b: &Bvh) {
    assert_eq!(a.nodes, b.nodes);
    assert_eq!(a.prim_refs, b.prim_refs);
    assert_eq!(a.depth, b.depth);
    assert_eq!(a.scale.to_bits(), b.scale.to_bits());
    assert_eq!(a.surfaces_at_lights, b.surfaces_at_lights);
}

#[test]
fn a_hit_is_the_tree_a_build_makes() {
    let dir = tempfile::tempdir().expect("temp dir");
    let c = cache(dir.path());
    let scene = field(MIN_PRIMITIVES + 1);
    let built = Bvh::for_render(&scene, &effects());
    assert!(!built.surfaces_at_lights[0].is_empty());
    let (first, t) = through(&c, &scene);
    assert_eq!((t.counted(MISS), t.counted(HIT)), (1, 0));
    same(&first, &built);
    let (second, t) = through(&c, &scene);
    assert_eq!((t.counted(MISS), t.counted(HIT)), (0, 1));
    assert!(t.phase("bvh").is_none());
    same(&second, &built);
    // A normal or a material is not the builder's: still a hit.
    let mut shaded = scene.clone();
    shaded.triangles[5].vertices[1].normal = DVec3::X;
    assert_eq!(through(&c, &shaded).1.counted(HIT), 1);
}

#[test]
fn what_the_builder_reads_changes_the_key() {
    let scene = field(100);
    let k = key(&scene, 0.0);
    assert_eq!(k, key(&scene.clone(), 0.0));
    let mut moved = scene.clone();
    let p = &mut moved.triangles[99].vertices[2].position.x;
    *p = p.next_up();
    assert_ne!(key(&moved, 0.0), k);
    let mut fast = scene.clone();
    fast.triangles[0].velocity = DVec3::X;
    assert_ne!(key(&fast, 0.0), k);
    assert_ne!(key(&scene, 0.5), k);
    let mut lit = scene.clone();
    lit.lights[0].shape = LightShape::Sphere { radius: 0.1 };
    assert_ne!(key(&lit, 0.0), k);
    let mut fewer = scene.clone();
    fewer.triangles.pop();
    assert_ne!(key(&fewer, 0.0), k);
}

#[test]
fn a_damaged_entry_is_ignored_and_made_again() {
    let dir = tempfile::tempdir().expect("temp dir");
    let c = cache(dir.path());
    let scene = field(MIN_PRIMITIVES);
    let built = through(&c, &scene).0;
    let path = std::fs::read_dir(c.dir())
        .expect("dir")
        .map(|e| e.expect("entry").path())
        .find(|p| p.extension().is_some_and(|e| e == "bin"))
        .expect("an entry");
    let good = std::fs::read(&path).expect("read");
    let damaged: [Vec<u8>; 3] = [
        {
            let mut b = good.clone();
            let mid = b.len() / 2;
            b[mid] ^= 0x10;
            b
        },
        good[..good.len() - 100].to_vec(),
        Vec::new(),
    ];
    for bytes in damaged {
        std::fs::write(&path, &bytes).expect("write");
        let (bvh, t) = through(&c, &scene);
        assert_eq!((t.counted(IGNORED), t.counted(MISS)), (1, 1));
        same(&bvh, &built);
        // Replaced: the next render reads it.
        assert_eq!(through(&c, &scene).1.counted(HIT), 1);
    }
}

#[test]
fn a_tree_that_is_not_sound_is_never_used() {
    let scene = field(MIN_PRIMITIVES);
    let built = Bvh::for_render(&scene, &effects());
    assert!(decode(&encode(&built), &scene).is_ok());
    let leaf = built
        .nodes
        .iter()
        .position(|n| n.count > 0)
        .expect("a leaf");
    let interior = 0;
    let mut bad: Vec<(Bvh, &str)> = Vec::new();
    let mut b = built.clone();
    b.nodes[leaf].count += 1;
    bad.push((b, "a leaf one reference longer"));
    let mut b = built.clone();
    b.nodes[interior].right_or_first = u32::MAX;
    bad.push((b, "a child out of the list"));
    let mut b = built.clone();
    b.prim_refs.swap(0, 1);
    b.prim_refs[0] = b.prim_refs[1];
    bad.push((b, "a primitive twice"));
    let mut b = built.clone();
    b.depth = 1;
    bad.push((b, "deeper than it says"));
    let mut b = built.clone();
    b.surfaces_at_lights[0].push(u32::MAX >> 1);
    bad.push((b, "a light's surface that is not there"));
    let mut b = built.clone();
    b.scale = f64::NAN;
    bad.push((b, "no scale"));
    for (b, what) in &bad {
        assert!(decode(&encode(b), &scene).is_err(), "{what}");
    }
    // Sound, but for another scene.
    assert!(decode(&encode(&built), &field(MIN_PRIMITIVES + 1)).is_err());
    // Stored with a valid checksum under the scene's key: ignored, rebuilt.
    let dir = tempfile::tempdir().expect("temp dir");
    let c = cache(dir.path());
    let k = key(&scene, 0.0);
    c.store
        .store(Kind::Bvh, k, &encode(&bad[0].0))
        .expect("stored");
    let (bvh, t) = through(&c, &scene);
    assert_eq!(t.counted(IGNORED), 1);
    same(&bvh, &built);
}

#[test]
fn small_scenes_are_built_not_cached() {
    let dir = tempfile::tempdir().expect("temp dir");
    let c = cache(dir.path());
    let (_, t) = through(&c, &field(MIN_PRIMITIVES - 1));
    assert_eq!((t.counted(HIT), t.counted(MISS)), (0, 0));
    assert!(!c.dir().exists());
}
