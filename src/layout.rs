//! Every GPU-visible struct, defined once here (`#[repr(C)]`, `bytemuck`), and
//! the packing of a `Scene` + `Bvh` into those buffers.
//!
//! `shaders/trace.wgsl` declares the same structs by hand (WGSL has no
//! include); `tests/layout.rs` reads the shader's member offsets, struct sizes
//! and shared constants from naga and compares them with these, so the two
//! cannot drift apart silently. Fields are grouped as `vec3 + scalar` so WGSL's
//! 16-byte `vec3` alignment leaves no hidden padding.

use std::collections::HashMap;

use bytemuck::{Pod, Zeroable};

use crate::bvh::Bvh;
use crate::camera::Camera;
use crate::info::Features;
use crate::scene::{Effects, LightShape, Scene};

/// Bit 31 of a primitive reference marks a sphere; the rest is the index.
pub const SPHERE_BIT: u32 = 0x8000_0000;
/// Deepest BVH the builder makes, and so the traversal stack size.
pub const BVH_MAX_DEPTH: u32 = 64;
/// Compute workgroup edge: workgroups are `WORKGROUP_SIZE x WORKGROUP_SIZE`.
pub const WORKGROUP_SIZE: u32 = 8;
/// `probe_tile` flags: the unclamped colour, or the surface point or normal,
/// has an infinite or NaN component.
pub const FLAG_NONFINITE_COLOR: u32 = 1;
pub const FLAG_NONFINITE_SURFACE: u32 = 2;
/// `probe_pixel` record: `PATH_HEADER` texels, then `PATH_PER_LIGHT` per
/// light (decoded by `probe::PathRecord::from_texels`).
pub const PATH_HEADER: u32 = 8;
pub const PATH_PER_LIGHT: u32 = 3;

/// Per-image constants (uniform, binding 0).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuFrame {
    pub background: [f32; 4],
    pub ambient: [f32; 4],
    /// `Camera::half_extent` in f32.
    pub half_extent: [f32; 2],
    /// Image width and height in pixels.
    pub size: [u32; 2],
    pub node_count: u32,
    pub light_count: u32,
    /// Where triangles start in the velocity buffer.
    pub sphere_count: u32,
    pub seed: u32,
    /// Samples per pixel, shadow samples per area light, reflection bounces.
    pub spp: u32,
    pub shadow_samples: u32,
    pub reflect_depth: u32,
    /// Seconds the shutter is open; 0 unless the scene calls for motion blur.
    pub shutter: f32,
    /// log2 of the elements per binding of each split list (triangles,
    /// normals, materials, BVH nodes; see `SPLIT_LISTS`); only a shader built
    /// for split lists reads them.
    pub chunk_shift: [u32; 4],
}

/// Per-dispatch constants (uniform, binding 1): the tile this dispatch
/// renders, and how much of its work one pass may do.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuTile {
    /// Pixel coordinates of the tile's top-left corner.
    pub origin: [u32; 2],
    /// Tile width and height (edge tiles are smaller).
    pub size: [u32; 2],
    /// Loop iterations one invocation may start in this pass (at least 1).
    pub budget: u32,
    /// 1 on the tile's first pass: the shader initialises the pixel state.
    pub first: u32,
    pub _pad: [u32; 2],
}

/// One pixel's place in its work between passes (storage, binding 10); only
/// the shader reads and writes it, the host sizes it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuPixelState {
    pub sum: [f32; 3],
    pub sample: u32,
    pub color: [f32; 3],
    pub bounce: u32,
    pub weight: [f32; 3],
    pub light: u32,
    pub shade: [f32; 3],
    pub area_sample: u32,
    pub area: [f32; 3],
    pub prim: u32,
    pub origin: [f32; 3],
    pub t: f32,
    pub dir: [f32; 3],
    pub b1: f32,
    pub time: f32,
    pub b2: f32,
    pub phase: u32,
    pub _pad: u32,
}

/// What a pass reports (storage, binding 11), reset before each pass.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct GpuStatus {
    /// Pixels with work left after the pass.
    pub remaining: u32,
    /// Invocations whose work was cut short (a driver ended a loop early,
    /// or a ray exceeded `MAX_TRAVERSAL_STEPS`).
    pub cut: u32,
    /// The smallest cut pixel index, `y * width + x` (`u32::MAX`: none).
    pub first_cut: u32,
    /// Closest-hit rays (primary and reflected) cast in the pass.
    pub closest_rays: u32,
    /// Shadow rays cast in the pass (one per point light, or per
    /// area-light sample, at every shaded point).
    pub shadow_rays: u32,
    pub _pad: u32,
}

impl GpuStatus {
    /// The value a pass starts from.
    pub const RESET: GpuStatus = GpuStatus {
        remaining: 0,
        cut: 0,
        first_cut: u32::MAX,
        closest_rays: 0,
        shadow_rays: 0,
        _pad: 0,
    };
}

/// Most iterations one BVH traversal may take in the shader.
pub const MAX_TRAVERSAL_STEPS: u32 = 16384;

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuSphere {
    pub center: [f32; 3],
    pub radius: f32,
    pub kd: [f32; 3],
    pub shininess: f32,
    pub ks: [f32; 3],
    pub _pad: f32,
}

/// Triangle positions, what intersection reads (48 bytes a triangle). The w
/// of each corner holds the bits of that corner's index into the material
/// table, which intersection ignores and shading reads with the normals.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuTriangle {
    /// xyz = vertex position, w = `f32::from_bits(material index)`.
    pub v: [[f32; 4]; 3],
}

/// A triangle's three vertex normals, packed (36 bytes a triangle).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuTriangleNormals {
    pub n: [f32; 9],
}

/// One distinct (kd, ks, shininess) of the scene's triangle corners; scenes
/// share a few materials among many corners, so a table indexed from the
/// triangle replaces 96 bytes of per-corner material a triangle.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMaterial {
    pub kd: [f32; 3],
    pub shininess: f32,
    pub ks: [f32; 3],
    pub _pad: f32,
}

/// Lists that may span several bindings when one binding cannot hold them
/// (`maxStorageBufferRange`), in `GpuFrame::chunk_shift` order, with their
/// first binding; chunk k > 0 of list j is binding
/// `SPLIT_FIRST + (SPLIT_CHUNKS - 1) j + k - 1`.
pub const SPLIT_LISTS: [(usize, &str); 4] = [
    (3, "triangles"),
    (4, "normals"),
    (12, "materials"),
    (6, "bvh nodes"),
];
/// Bindings a split list may span (the shader declares that many).
pub const SPLIT_CHUNKS: usize = 4;
/// The first binding of the extra chunks.
pub const SPLIT_FIRST: usize = 14;

/// `GpuLight::kind` values.
pub const LIGHT_POINT: u32 = 0;
pub const LIGHT_SPHERE: u32 = 1;
pub const LIGHT_RECT: u32 = 2;

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLight {
    pub position: [f32; 3],
    /// `LIGHT_POINT`, `LIGHT_SPHERE` or `LIGHT_RECT`.
    pub kind: u32,
    pub color: [f32; 3],
    /// Sphere lights only.
    pub radius: f32,
    /// Rectangle lights only: the two edges, centred on `position`.
    pub edge_u: [f32; 3],
    /// Point lights: where the surfaces through the light start in the skip
    /// list (binding 13), and how many (`lights_on_surfaces`).
    pub skip_first: u32,
    pub edge_v: [f32; 3],
    pub skip_count: u32,
    pub velocity: [f32; 3],
    pub _pad2: f32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuBvhNode {
    pub min: [f32; 3],
    /// Interior: index of the right child (the left one is the next node).
    /// Leaf: index of the first primitive reference.
    pub right_or_first: u32,
    pub max: [f32; 3],
    /// Primitive count of a leaf; 0 marks an interior node.
    pub count: u32,
}

/// A scene packed into the buffers the shader reads, in f32.
///
/// Vulkan forbids zero-sized buffers, so `padded` gives each list at least one
/// (zeroed) element; counts that matter travel in `GpuFrame` and the BVH.
#[derive(Clone, Debug, Default)]
pub struct GpuScene {
    pub spheres: Vec<GpuSphere>,
    pub triangles: Vec<GpuTriangle>,
    pub normals: Vec<GpuTriangleNormals>,
    pub materials: Vec<GpuMaterial>,
    pub lights: Vec<GpuLight>,
    pub nodes: Vec<GpuBvhNode>,
    pub prim_refs: Vec<u32>,
    /// The surfaces through point lights, each light's run at its
    /// `skip_first`; empty when no light lies on a surface.
    pub skips: Vec<u32>,
    /// xyz = velocity of each sphere, then each triangle; empty when
    /// nothing moves.
    pub velocities: Vec<[f32; 4]>,
    pub ambient: [f32; 3],
}

fn f3(v: glam::DVec3) -> [f32; 3] {
    v.as_vec3().to_array()
}

fn f4(v: glam::DVec3) -> [f32; 4] {
    v.as_vec3().extend(0.0).to_array()
}

impl GpuScene {
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
        let mut triangles = Vec::with_capacity(scene.triangles.len());
        let mut normals = Vec::with_capacity(scene.triangles.len());
        for t in &scene.triangles {
            triangles.push(GpuTriangle {
                v: t.vertices.map(|v| {
                    let mut p = f4(v.position);
                    p[3] = f32::from_bits(ids[v.material as usize]);
                    p
                }),
            });
            let n = t.vertices.map(|v| f3(v.normal));
            normals.push(GpuTriangleNormals {
                n: *n.as_flattened().first_chunk().expect("9 values"),
            });
        }
        let mut skips = Vec::new();
        let lights = scene
            .lights
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let through = bvh.surfaces_at_lights.get(i).map_or(&[][..], Vec::as_slice);
                let skip_first = skips.len() as u32;
                skips.extend_from_slice(through);
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
        let velocities = if scene.has_motion() {
            let s = scene.spheres.iter().map(|s| f4(s.velocity));
            s.chain(scene.triangles.iter().map(|t| f4(t.velocity)))
                .collect()
        } else {
            Vec::new()
        };
        GpuScene {
            spheres,
            triangles,
            normals,
            materials,
            lights,
            nodes: bvh.nodes.clone(),
            prim_refs: bvh.prim_refs.clone(),
            skips,
            velocities,
            ambient: f3(scene.ambient),
        }
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
            b(self.nodes.len(), size_of::<GpuBvhNode>()),
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
