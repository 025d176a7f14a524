//! Every GPU-visible struct and shared constant, defined once here
//! (`#[repr(C)]`, `bytemuck`). `shaders/trace/layout.wgsl` declares the same
//! structs by hand (WGSL has no include); `tests/layout.rs` reads the
//! shader's member offsets, struct sizes and shared constants from naga and
//! compares them with these, so the two cannot drift apart silently. Fields
//! are grouped as `vec3 + scalar` so WGSL's 16-byte `vec3` alignment leaves
//! no hidden padding.

use bytemuck::{Pod, Zeroable};

pub use crate::bvh::node::{GpuBvhNode, BVH_MAX_DEPTH, SPHERE_BIT};
pub use crate::bvh::wide::{EMPTY as WIDE_EMPTY, LEAF as WIDE_LEAF};

/// Compute workgroup edge: workgroups are `WORKGROUP_SIZE x WORKGROUP_SIZE`.
pub const WORKGROUP_SIZE: u32 = 8;
// The shader's block_pixel lays 4x2 blocks over an 8x8 workgroup: any other
// size would leave pixels unrendered.
const _: () = assert!(WORKGROUP_SIZE == 8);
/// `probe_tile` flag: the unclamped colour has an infinite or NaN component.
pub const FLAG_NONFINITE_COLOR: u32 = 1;
/// `probe_tile` flag: the surface point or normal has an infinite or NaN
/// component.
pub const FLAG_NONFINITE_SURFACE: u32 = 2;
/// `probe_pixel` record: `PATH_HEADER` texels, then `PATH_PER_LIGHT` per
/// light (decoded by `probe::PathRecord::from_texels`).
pub const PATH_HEADER: u32 = 8;
/// Texels a light adds to a `probe_pixel` record.
pub const PATH_PER_LIGHT: u32 = 3;

/// Per-image constants (uniform, binding 0).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuFrame {
    /// The background colour (rgb; w unused).
    pub background: [f32; 4],
    /// The scene's ambient colour (rgb; w unused).
    pub ambient: [f32; 4],
    /// `Camera::half_extent` in f32.
    pub half_extent: [f32; 2],
    /// Image width and height in pixels.
    pub size: [u32; 2],
    /// Nodes of the BVH the shader traverses.
    pub node_count: u32,
    /// Lights in the light list.
    pub light_count: u32,
    /// Where triangles start in the velocity buffer.
    pub sphere_count: u32,
    /// Seed of the per-pixel sample hash.
    pub seed: u32,
    /// Samples per pixel, shadow samples per area light, reflection bounces.
    pub spp: u32,
    /// Shadow samples per area light.
    pub shadow_samples: u32,
    /// Reflection bounces after the primary hit.
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
    /// `SAMPLER_SOBOL` or `SAMPLER_STRATIFIED`.
    pub sampling: u32,
    /// Padding to a 16-byte multiple.
    pub _pad0: u32,
    /// Padding to a 16-byte multiple.
    pub _pad: [u32; 2],
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

/// `GpuFrame::sampling` of `scene::Sampler::Stratified`.
pub const SAMPLER_STRATIFIED: u32 = 0;
/// `GpuFrame::sampling` of `scene::Sampler::Sobol`.
pub const SAMPLER_SOBOL: u32 = 1;

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
    /// Padding to a 16-byte multiple.
    pub _pad: [u32; 2],
}

/// One pixel's place in its work between passes (storage, binding 10); only
/// the shader reads and writes it, the host sizes it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuPixelState {
    /// Sum of the finished samples.
    pub sum: [f32; 3],
    /// The next sample to take.
    pub sample: u32,
    /// The sample in progress: its colour so far.
    pub color: [f32; 3],
    /// The sample in progress: its bounce.
    pub bounce: u32,
    /// What the current bounce's colour is weighted by.
    pub weight: [f32; 3],
    /// The next light to shade at the current hit.
    pub light: u32,
    /// Phong shading's running sum at the current hit.
    pub shade: [f32; 3],
    /// The next sample of the area light `light`.
    pub area_sample: u32,
    /// The area light's running sum for light `light`.
    pub area: [f32; 3],
    /// The current hit's primitive.
    pub prim: u32,
    /// The current ray's origin.
    pub origin: [f32; 3],
    /// The current hit's distance along the ray.
    pub t: f32,
    /// The current ray's direction.
    pub dir: [f32; 3],
    /// The current hit's first barycentric coordinate.
    pub b1: f32,
    /// The sample's time within the shutter (motion blur).
    pub time: f32,
    /// The current hit's second barycentric coordinate.
    pub b2: f32,
    /// `PHASE_START`, `PHASE_TRACE` or `PHASE_SHADE` of the shader.
    pub phase: u32,
    /// Padding to a 16-byte multiple.
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
    /// Padding to a 16-byte multiple.
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

/// A sphere as the shader reads it (48 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuSphere {
    /// The centre.
    pub center: [f32; 3],
    /// The radius.
    pub radius: f32,
    /// Diffuse colour.
    pub kd: [f32; 3],
    /// Phong exponent.
    pub shininess: f32,
    /// Specular colour.
    pub ks: [f32; 3],
    /// Padding to a 16-byte multiple.
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
    /// The three corners' normals, xyz after xyz.
    pub n: [f32; 9],
}

/// One distinct (kd, ks, shininess) of the scene's triangle corners; scenes
/// share a few materials among many corners, so a table indexed from the
/// triangle replaces 96 bytes of per-corner material a triangle.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMaterial {
    /// Diffuse colour.
    pub kd: [f32; 3],
    /// Phong exponent.
    pub shininess: f32,
    /// Specular colour.
    pub ks: [f32; 3],
    /// Padding to a 16-byte multiple.
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
/// shaders/trace/layout.wgsl).
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

/// `GpuLight::kind` of a point light.
pub const LIGHT_POINT: u32 = 0;
/// `GpuLight::kind` of a sphere light.
pub const LIGHT_SPHERE: u32 = 1;
/// `GpuLight::kind` of a rectangle light.
pub const LIGHT_RECT: u32 = 2;

/// A light as the shader reads it (80 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLight {
    /// Point lights: the light; area lights: the centre.
    pub position: [f32; 3],
    /// `LIGHT_POINT`, `LIGHT_SPHERE` or `LIGHT_RECT`.
    pub kind: u32,
    /// The light's colour.
    pub color: [f32; 3],
    /// Sphere lights only.
    pub radius: f32,
    /// Rectangle lights only: the two edges, centred on `position`.
    pub edge_u: [f32; 3],
    /// Point lights: where the surfaces through the light start in the skip
    /// list (binding 13), and how many (`lights_on_surfaces`).
    pub skip_first: u32,
    /// Rectangle lights only: the second edge.
    pub edge_v: [f32; 3],
    /// Point lights: how many surfaces through the light (see `skip_first`).
    pub skip_count: u32,
    /// Scene units a second the light moves (motion blur).
    pub velocity: [f32; 3],
    /// Padding to a 16-byte multiple.
    pub _pad2: f32,
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
    /// The node box's low corner (xyz) and the three exponents' bits (w).
    pub origin: [f32; 4],
    /// The children's low bytes (words 0-2) and the x high bytes (word 3).
    pub lo_hi: [u32; 4],
    /// The children's y and z high bytes (words 0-1); words 2-3 unused.
    pub hi_yz: [u32; 4],
    /// Per child lane: a node index, `WIDE_LEAF | first`, or `WIDE_EMPTY`.
    pub child: [u32; 4],
}

/// In leaf order (`GpuScene::scene_triangles`) a leaf lane's word holds
/// its count less one in the bits `LEAF_COUNT_MASK` from this one, its
/// first reference below them: the shader's leaf loop then finds where a
/// leaf ends without loading a reference.
pub const LEAF_COUNT_SHIFT: u32 = 28;
/// See `LEAF_COUNT_SHIFT`: leaves of up to 8 primitives.
pub const LEAF_COUNT_MASK: u32 = 7;
/// Most triangles a leaf-ordered scene holds: every first reference fits
/// below `LEAF_COUNT_SHIFT`, and no leaf word reads as `WIDE_EMPTY`.
pub(super) const LEAF_ORDER_MAX: usize = (1 << LEAF_COUNT_SHIFT) - (LEAF_COUNT_MASK as usize + 1);
/// Bit 30 of the shader's primitive references: the last of its leaf.
pub const LEAF_END: u32 = 1 << 30;
/// Groups the shader's traversal stack holds: a node visited stores at most
/// one (the entries it leaves for later), and the collapsed tree is no
/// deeper than the binary one.
pub const TRAVERSAL_STACK: u32 = BVH_MAX_DEPTH;

/// `shaders/resolve.wgsl`'s parameters (`gpu::present`): the view's size,
/// whether this pass is its first (the sums start over) and the byte order
/// of the swapchain's format.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuResolve {
    /// The view's width and height in pixels.
    pub size: [u32; 2],
    /// 1 on the view's first pass: the sums start over.
    pub reset: u32,
    /// 1: pack B, G, R, A (`B8G8R8A8_UNORM`); 0: R, G, B, A.
    pub bgra: u32,
}
