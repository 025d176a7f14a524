//! A render's BVH kept in the cache: keyed by what the builder reads,
//! checked as a tree over the scene at hand before it is used.

use glam::DVec3;
use xxhash_rust::xxh3::Xxh3;

use super::codec::{self, hash_items, Reader, Writer};
use super::store::{Found, Kind};
use super::{SceneCache, MIN_PRIMITIVES};
use crate::bvh::{Bvh, GpuBvhNode, BVH_MAX_DEPTH, SPHERE_BIT};
use crate::features::Features;
use crate::scene::{Effects, LightShape, Scene};
use crate::timing::Timings;

/// The body's layout; a new one is a new key.
const FORMAT: u32 = 1;

/// The builder's source: a change to how trees are made is a new key, so
/// a cache never hands back a tree the running glint would not build.
const BUILDER: [&[u8]; 6] = [
    include_bytes!("../bvh/mod.rs"),
    include_bytes!("../bvh/build.rs"),
    include_bytes!("../bvh/node.rs"),
    include_bytes!("../bvh/lights_on_surfaces.rs"),
    include_bytes!("../scene/space.rs"),
    include_bytes!("bvh.rs"),
];

/// What `-v` counts: a tree read from the cache, or built (and stored).
pub(crate) const HIT: &str = "bvh cache hit";
/// See `HIT`.
pub(crate) const MISS: &str = "bvh cache miss";
/// An entry found but not used (damaged, or not a tree of this scene).
pub(crate) const IGNORED: &str = "bvh cache entries ignored";

impl SceneCache {
    /// `Bvh::for_render(scene, effects)`, read from the cache where an
    /// entry for the same geometry is there and sound, else built and
    /// stored. `timings` gets `bvh key` and `bvh from cache` (hashing,
    /// reading), or `bvh` and `bvh cache write`, and a hit or a miss.
    pub(crate) fn bvh_for_render(
        &self,
        scene: &Scene,
        effects: &Effects,
        timings: &mut Timings,
    ) -> Bvh {
        let build = |timings: &mut Timings| timings.time("bvh", || Bvh::for_render(scene, effects));
        if scene.spheres.len() + scene.triangles.len() < MIN_PRIMITIVES {
            return build(timings);
        }
        let span = if Features::of(scene, effects).motion_blur {
            effects.shutter_seconds()
        } else {
            0.0
        };
        let key = timings.time("bvh key", || key(scene, span));
        let found = timings.time("bvh from cache", || {
            match self.store.load(Kind::Bvh, key, max_body(scene)) {
                Found::Body(body) => decode(body.bytes(), scene).map(Some),
                Found::Missing => Ok(None),
                Found::Ignored(why) => Err(why),
            }
        });
        match found {
            Ok(Some(bvh)) => {
                timings.count(HIT, 1);
                return bvh;
            }
            Ok(None) => {}
            Err(_) => timings.count(IGNORED, 1),
        }
        timings.count(MISS, 1);
        let bvh = build(timings);
        timings.time("bvh cache write", || {
            // A cache that cannot be written costs the next run a build,
            // nothing more.
            let _ = self.store.store(Kind::Bvh, key, &encode(&bvh));
        });
        bvh
    }
}

/// An xxh3-128 of everything `Bvh::for_render` reads of `scene` (in the
/// space the render gives it) with the motion-blur `span`, and of the
/// builder itself.
pub(super) fn key(scene: &Scene, span: f64) -> u128 {
    let mut h = Xxh3::new();
    h.update(b"glint bvh");
    h.update(env!("CARGO_PKG_VERSION").as_bytes());
    h.update(&FORMAT.to_le_bytes());
    for source in BUILDER {
        h.update(&xxhash_rust::xxh3::xxh3_64(source).to_le_bytes());
    }
    h.update(&span.to_bits().to_le_bytes());
    let v3 = |w: &mut Writer, v: DVec3| v.to_array().map(|x| w.f64(x));
    hash_items(&mut h, &scene.spheres, |s, w| {
        v3(w, s.center);
        w.f64(s.radius);
        v3(w, s.velocity);
    });
    hash_items(&mut h, &scene.triangles, |t, w| {
        // One copy of twelve numbers, not twelve: most of the key's time.
        let [a, b, c] = t.vertices.map(|v| v.position.to_array());
        let v = t.velocity.to_array();
        let all: [[f64; 3]; 4] = [a, b, c, v];
        w.0.extend_from_slice(bytemuck::bytes_of(&all));
    });
    hash_items(&mut h, &scene.lights, |l, w| {
        v3(w, l.position);
        v3(w, l.velocity);
        match l.shape {
            LightShape::Point => w.u32(0),
            LightShape::Sphere { radius } => {
                w.u32(1);
                w.f64(radius);
            }
            LightShape::Rect { edge_u, edge_v } => {
                w.u32(2);
                v3(w, edge_u);
                v3(w, edge_v);
            }
        }
    });
    h.digest128()
}

/// The most bytes a sound tree of `scene` could take: two nodes and one
/// reference a primitive, and per light a reference a primitive.
fn max_body(scene: &Scene) -> u64 {
    let prims = (scene.spheres.len() + scene.triangles.len()) as u64;
    let lights = scene.lights.len() as u64;
    1024 + prims * (2 * 32 + 4) + lights * (8 + prims * 4)
}

pub(super) fn encode(bvh: &Bvh) -> Vec<u8> {
    let mut w = Writer(Vec::with_capacity(
        64 + bvh.nodes.len() * 32 + bvh.prim_refs.len() * 4,
    ));
    w.f64(bvh.scale);
    w.u32(bvh.depth);
    w.array(&bvh.nodes);
    w.array(&bvh.prim_refs);
    w.u64(bvh.surfaces_at_lights.len() as u64);
    for s in &bvh.surfaces_at_lights {
        w.array(s);
    }
    w.0
}

/// The tree in `body`, if it is a sound tree over `scene`'s primitives.
pub(super) fn decode(body: &[u8], scene: &Scene) -> codec::Result<Bvh> {
    let mut r = Reader::new(body);
    let scale = r.f64()?;
    let depth = r.u32()?;
    let nodes: Vec<GpuBvhNode> = r.array()?;
    let prim_refs: Vec<u32> = r.array()?;
    let lights = r.count(8)?;
    let surfaces_at_lights = (0..lights)
        .map(|_| r.array::<u32>())
        .collect::<codec::Result<Vec<_>>>()?;
    r.end()?;
    let bvh = Bvh {
        nodes,
        prim_refs,
        depth,
        scale,
        surfaces_at_lights,
    };
    sound(&bvh, scene)?;
    Ok(bvh)
}

/// Whether `bvh` is a tree every traversal can walk over `scene`: every
/// node reached once from the root in the depth-first layout, within the
/// depth it claims and `BVH_MAX_DEPTH`; every leaf's references inside
/// the list, each primitive referenced once; the lights' lists naming
/// primitives that exist. Its boxes are the checksum's and the key's to
/// vouch for.
fn sound(bvh: &Bvh, scene: &Scene) -> codec::Result<()> {
    let (spheres, triangles) = (scene.spheres.len(), scene.triangles.len());
    let prims = spheres + triangles;
    // The scale follows from the geometry the key holds; an entry whose
    // scale is not a scale at all is damaged.
    if !(bvh.scale.is_finite() && bvh.scale > 0.0) {
        return Err("a tree in no render scale".into());
    }
    if bvh.depth > BVH_MAX_DEPTH || bvh.prim_refs.len() != prims || bvh.nodes.is_empty() {
        return Err("a tree of another size".into());
    }
    let valid = |r: u32| {
        if r & SPHERE_BIT != 0 {
            ((r & !SPHERE_BIT) as usize) < spheres
        } else {
            (r as usize) < triangles
        }
    };
    let index = |r: u32| {
        if r & SPHERE_BIT != 0 {
            (r & !SPHERE_BIT) as usize
        } else {
            spheres + r as usize
        }
    };
    let mut seen = vec![0u64; prims.div_ceil(64)];
    for &r in &bvh.prim_refs {
        let (i, bit) = (index(r) / 64, 1u64 << (index(r) % 64));
        if !valid(r) || seen[i] & bit != 0 {
            return Err("a tree whose leaves do not hold each primitive once".into());
        }
        seen[i] |= bit;
    }
    // Depth first: node i's left child is i + 1, and its subtree ends
    // where its right child begins.
    let mut next = 0usize;
    let mut covered = 0usize;
    let mut stack = vec![(0usize, 0u32)];
    while let Some((i, d)) = stack.pop() {
        if i != next || i >= bvh.nodes.len() || d > bvh.depth {
            return Err("a tree not laid out depth first within its depth".into());
        }
        next += 1;
        let n = &bvh.nodes[i];
        if n.count > 0 {
            let first = n.right_or_first as usize;
            if first != covered || n.count as usize > prims - covered {
                return Err("a leaf outside the reference list".into());
            }
            covered += n.count as usize;
        } else {
            let right = n.right_or_first as usize;
            if right <= i + 1 || right >= bvh.nodes.len() {
                return Err("an interior node whose children are out of place".into());
            }
            stack.push((right, d + 1));
            stack.push((i + 1, d + 1));
        }
    }
    if next != bvh.nodes.len() || covered != prims {
        return Err("a tree with nodes or references no leaf reaches".into());
    }
    if bvh.surfaces_at_lights.len() != scene.lights.len()
        || bvh.surfaces_at_lights.iter().flatten().any(|&r| !valid(r))
    {
        return Err("lights' surfaces that do not match the scene".into());
    }
    Ok(())
}
