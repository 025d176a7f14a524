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
// The shader's block_pixel lays 4x2 blocks over an 8x8 workgroup: any other
// size would leave pixels unrendered.
const _: () = assert!(WORKGROUP_SIZE == 8);
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
    /// Device addresses of the `ADDRESS_LISTS`, two to an element as (low,
    /// high) words (`set_address`); only a shader built for address lists
    /// reads them.
    pub addresses: [[u32; 4]; 3],
}

impl GpuFrame {
    /// Sets the device address of `ADDRESS_LISTS[j]`: (low, high) words,
    /// two lists to an element, as the shader's `list_address` reads them.
    pub fn set_address(&mut self, j: usize, address: u64) {
        let lanes = 2 * (j % 2);
        self.addresses[j / 2][lanes..lanes + 2]
            .copy_from_slice(&[address as u32, (address >> 32) as u32]);
    }
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

/// Lists a shader with uniform lists reads from uniform buffers instead of
/// their storage bindings: (storage binding, name), the uniform copy of list
/// j at binding `UNIFORM_FIRST + j` (see "Uniform lists" in
/// shaders/trace.wgsl).
pub const UNIFORM_LISTS: [(usize, &str); 4] = [
    (2, "spheres"),
    (3, "triangles"),
    (6, "bvh nodes"),
    (7, "primitive references"),
];
/// The first binding of the uniform copies.
pub const UNIFORM_FIRST: usize = 26;

/// The lists a shader built for address lists (`Lists::Address`) reads
/// through their device addresses, by binding, in the order of
/// `GpuFrame::addresses`: those a traversal reads most, and those shading
/// reads per hit.
pub const ADDRESS_LISTS: [(usize, &str); 6] = [
    (2, "spheres"),
    (3, "triangles"),
    (6, "bvh nodes"),
    (7, "primitive refs"),
    (4, "normals"),
    (12, "materials"),
];
/// Bytes of each uniform copy: its fixed-length array in the shader
/// (elements: this over the element's size, rounded down). Four times
/// Vulkan's guaranteed `maxUniformBufferRange`; lavapipe offers it.
pub const UNIFORM_LIST_BYTES: u64 = 65536;

/// How the uniform copy of a list of `UNIFORM_LISTS` holds it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CopyForm {
    /// Element for element (triangles: three `vec4<f32>` each).
    Whole,
    /// 32-bit words four to a `vec4<u32>` (a uniform array's stride is a
    /// multiple of 16 bytes): the primitive references.
    Packed,
    /// The nine position words of each triangle back to back in `vec4<f32>`
    /// elements, without the material bits (only shading reads those, from
    /// the list): 1,820 triangles in 64 KiB instead of 1,365, which brings
    /// SIGGRAPH (1,482) under it. The shader's `UNIFORM_CORNERS`.
    Corners,
}

/// Bytes of a triangle in `CopyForm::Corners`: nine position words.
const CORNER_BYTES: usize = 9 * 4;

/// Storage element bytes of the lists of `UNIFORM_LISTS`.
const LIST_STRIDES: [usize; 4] = [
    std::mem::size_of::<GpuSphere>(),
    std::mem::size_of::<GpuTriangle>(),
    std::mem::size_of::<GpuWideNode>(),
    std::mem::size_of::<u32>(),
];

/// The form of list j's uniform copy for a list of `list_bytes`: the
/// triangles whole where they fit, else as corners.
pub const fn uniform_copy_form(j: usize, list_bytes: u64) -> CopyForm {
    match j {
        1 if list_bytes > UNIFORM_LIST_BYTES => CopyForm::Corners,
        3 => CopyForm::Packed,
        _ => CopyForm::Whole,
    }
}

/// Bytes of one element of list j's uniform copy, its array's stride: the
/// list's element, or a `vec4` of 32-bit words (triangles: three a
/// triangle, or the corners' words back to back; the references).
pub const fn uniform_copy_element_bytes(j: usize) -> usize {
    match j {
        1 | 3 => 16,
        _ => LIST_STRIDES[j],
    }
}

/// Elements of the uniform copy of list j of `UNIFORM_LISTS` (its
/// fixed-length array in the shader).
pub const fn uniform_list_len(j: usize) -> u64 {
    UNIFORM_LIST_BYTES / uniform_copy_element_bytes(j) as u64
}

/// Bytes the uniform copy of list j needs for a list of `list_bytes`.
pub const fn uniform_copy_bytes(j: usize, list_bytes: u64) -> u64 {
    match uniform_copy_form(j, list_bytes) {
        CopyForm::Corners => list_bytes / LIST_STRIDES[j] as u64 * CORNER_BYTES as u64,
        CopyForm::Whole | CopyForm::Packed => list_bytes,
    }
}

/// List j's uniform copy of `list` (its storage bytes), zero-padded to the
/// shader's fixed-length array; None where it does not fit.
pub fn uniform_copy(j: usize, list: &[u8]) -> Option<Vec<u8>> {
    let bytes = list.len() as u64;
    if uniform_copy_bytes(j, bytes) > UNIFORM_LIST_BYTES {
        return None;
    }
    let mut copy = match uniform_copy_form(j, bytes) {
        CopyForm::Whole | CopyForm::Packed => list.to_vec(),
        CopyForm::Corners => list
            .chunks_exact(LIST_STRIDES[j])
            // Each corner's xyz, the first 12 bytes of its vec4.
            .flat_map(|t| [0, 16, 32].map(|c| &t[c..c + 12]))
            .flatten()
            .copied()
            .collect(),
    };
    copy.resize(UNIFORM_LIST_BYTES as usize, 0);
    Some(copy)
}

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

/// The shader's BVH node: the binary tree (`GpuBvhNode`) collapsed to four
/// children a node (`cpu::wide::collapse_nodes`, the CPU reference's tree),
/// each child's box quantised to 8 bits an axis within the node's box, then
/// per lane a child word: a node index, `WIDE_LEAF | first` (a leaf whose
/// primitive references start at `first` and run to the one marked
/// `LEAF_END`), or `WIDE_EMPTY` (an unused lane). 64 bytes, four `vec4`
/// loads a node.
///
/// `origin` xyz is the node box's low corner and w the bits of three
/// biased exponents `e` (x | y << 8 | z << 16); a child's box on axis a is
/// `origin[a] + q * 2^(e[a] - 127)` for its low and high bytes q
/// (`lo`: x y z lanes in bytes 0-3 of words 0-2; `hi` x in word 3 of
/// `lo_hi`, y z in words 0-1 of `hi_yz`). The product is exact, so the box
/// is the same with or without a fused multiply-add, and the bytes are
/// rounded outwards until it holds the child's f32 box.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuWideNode {
    pub origin: [f32; 4],
    pub lo_hi: [u32; 4],
    pub hi_yz: [u32; 4],
    pub child: [u32; 4],
}

/// `GpuWideNode::child` of a leaf lane: this bit plus its first primitive
/// reference (and in leaf order its count, `LEAF_COUNT_SHIFT`).
pub const WIDE_LEAF: u32 = 1 << 31;
/// In leaf order (`GpuScene::scene_triangles`) a leaf lane's word holds
/// its count less one in the bits `LEAF_COUNT_MASK` from this one, its
/// first reference below them: the shader's leaf loop then finds where a
/// leaf ends without loading a reference.
pub const LEAF_COUNT_SHIFT: u32 = 28;
/// See `LEAF_COUNT_SHIFT`: leaves of up to 8 primitives.
pub const LEAF_COUNT_MASK: u32 = 7;
/// Most triangles a leaf-ordered scene holds: every first reference fits
/// below `LEAF_COUNT_SHIFT`, and no leaf word reads as `WIDE_EMPTY`.
const LEAF_ORDER_MAX: usize = (1 << LEAF_COUNT_SHIFT) - (LEAF_COUNT_MASK as usize + 1);
/// `GpuWideNode::child` of an unused lane.
pub const WIDE_EMPTY: u32 = u32::MAX;
/// Bit 30 of the shader's primitive references: the last of its leaf.
pub const LEAF_END: u32 = 1 << 30;
/// Groups the shader's traversal stack holds: a node visited stores at most
/// one (the entries it leaves for later), and the collapsed tree is no
/// deeper than the binary one.
pub const TRAVERSAL_STACK: u32 = BVH_MAX_DEPTH;

/// A scene packed into the buffers the shader reads, in f32.
///
/// Vulkan forbids zero-sized buffers, so `padded` gives each list at least one
/// (zeroed) element; counts that matter travel in `GpuFrame` and the BVH.
#[derive(Clone, Debug, Default)]
pub struct GpuScene {
    pub spheres: Vec<GpuSphere>,
    /// The triangles, with their normals, velocities and every reference
    /// to them, in the order `scene_triangles` gives.
    pub triangles: Vec<GpuTriangle>,
    pub normals: Vec<GpuTriangleNormals>,
    pub materials: Vec<GpuMaterial>,
    pub lights: Vec<GpuLight>,
    pub nodes: Vec<GpuWideNode>,
    /// `Bvh::prim_refs`, the last of each leaf marked with `LEAF_END`.
    pub prim_refs: Vec<u32>,
    /// The surfaces through point lights, each light's run at its
    /// `skip_first`; empty when no light lies on a surface.
    pub skips: Vec<u32>,
    /// xyz = velocity of each sphere, then each triangle; empty when
    /// nothing moves.
    pub velocities: Vec<[f32; 4]>,
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
fn wide_nodes(bvh: &Bvh, leaf_order: bool) -> Vec<GpuWideNode> {
    crate::cpu::wide::collapse_nodes(bvh, |leaf| leaf_word(leaf, leaf_order))
        .iter()
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
fn quantise(n: &crate::cpu::wide::Node4) -> GpuWideNode {
    let used: Vec<usize> = (0..4).filter(|&l| n.child[l] != WIDE_EMPTY).collect();
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
        for &l in &used {
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
        let ordered = || {
            (0..scene.triangles.len())
                .map(|i| &scene.triangles[scene_triangles.get(i).map_or(i, |&t| t as usize)])
        };
        let mut triangles = Vec::with_capacity(scene.triangles.len());
        let mut normals = Vec::with_capacity(scene.triangles.len());
        for t in ordered() {
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
            nodes: wide_nodes(bvh, leaf_order),
            prim_refs: leaf_runs(bvh, leaf_order),
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
    use crate::cpu::wide::{collapse_nodes, tests::scene, Node4};
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
            state = crate::cpu::sample::hash_u32(state);
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
