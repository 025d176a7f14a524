// glint's ray tracing kernel: one invocation per pixel of a tile. It is
// written in pieces by concept, each beside its CPU twin, joined in this
// order before naga reads them (src/gpu/shader.rs: TRACE_PIECES): layout
// (this file: structs, bindings, constants, feature overrides), sample,
// hit, scene, traverse, shade, kernel.
//
//
// Bindings (group 0); the structs mirror src/layout/types.rs and tests/layout.rs
// checks every offset and size against it:
//   0  uniform            Frame          per-image constants
//   1  uniform            Tile           the tile this dispatch renders
//   2  storage, read      array<Sphere>
//   3  storage, read      array<Triangle>          positions (w: material index bits)
//   4  storage, read      array<TriangleNormals>   the 3 vertex normals of each triangle
//   5  storage, read      array<Light>
//   6  storage, read      array<WideNode>          four children a node, root first (src/layout/)
//   7  storage, read      array<u32>               primitive refs (bit 31: sphere, bit 30: last of its leaf)
//   8  storage, rw        array<vec4<f32>>         tile output, linear RGB, row-major
//   9  storage, read      array<vec4<f32>>         velocities: spheres, then triangles
//  10  storage, rw        array<PixelState>        render_tile: each pixel's place in its work
//  11  storage, rw        Status                   per pass: pixels unfinished, invocations cut
//  12  storage, read      array<Material>          the distinct triangle-corner materials
//  13  storage, read      array<u32>               light skips: surfaces through point lights
//  14.. storage, read     chunks 1-3 of triangles, normals, materials, nodes (SPLIT only)
//  26-29 uniform          spheres, triangle corners, nodes, primitive references again,
//                         fixed length (UNIFORM_LISTS only; layout::CopyForm)
//  30  never bound        device_memory: marks the loads through device addresses
//
// Split lists. A list larger than one binding may hold (maxStorageBufferRange)
// is bound as up to SPLIT_CHUNKS consecutive ranges of 2^frame.chunk_shift[j]
// elements each, and read through load_triangle, load_normals, load_material
// and load_node. Only a shader built with SPLIT reads the extra chunks; every
// other one reads binding 0 of each list directly.
//
// Uniform lists. On a CPU device (llvmpipe) a storage load is a loop over the
// eight lanes, each with a test of its mask and of the binding's size, a
// scalar load and a blend; a uniform load is a branch-free gather with the
// index clamped. The lists a traversal reads most (spheres, triangles, nodes,
// primitive references) are therefore also bound as uniform buffers of
// UNIFORM_LIST_BYTES each where they fit (triangles past 1,365 as their
// corners only: UNIFORM_CORNERS), and a shader built with UNIFORM_LISTS reads
// those instead (src/gpu/render/plan.rs; src/layout/: CopyForm). GPUs keep the storage lists: their
// uniform (constant) caches serialise lanes that read different addresses.
//
// Address lists. Mesa 25's llvmpipe turns a load through a device address
// (SPV_KHR_physical_storage_buffer) into one AVX gather instruction for the
// eight lanes, where a storage load is the per-lane loop above and a
// uniform one a per-lane extract, load and insert. WGSL has no such
// pointers, so a shader built with ADDRESSES reads the six lists of
// layout::ADDRESS_LISTS (the traversal's four, and the normals and
// materials shading reads) through device_load4 and device_load1, whose bodies (a read of the
// never-bound device_memory) src/gpu/shader.rs replaces in the SPIR-V by a
// load from the address they are given (src/gpu/rewrite.rs: device_loads;
// src/gpu/render/plan.rs). The lists stay bound as storage
// buffers for everything else.
//
// Bounded work. render_tile does not render a pixel in one go: it runs the
// pixel's work (samples, bounces, one light term or one area-light sample at
// a time) as steps of a resumable state machine, and stops when the pass's
// budget of loop iterations (tile.budget) is spent, saving its place in
// `state`. The host dispatches passes until no pixel is left. Each step
// computes what the uninterrupted algorithm (src/cpu/trace/: pixel_color,
// radiance, reflect_path, shade_phong, area_term) computes, in the same
// order, and every partial sum is stored as the f32 it is, so the image does
// not depend on where passes split the work. This keeps every invocation
// below any driver's loop-iteration limit (llvmpipe ends loops early once an
// invocation has run 65535 iterations of all its loops together) and every
// dispatch short enough for a watchdog. A loop that ends without its own exit
// (a driver cut it, or a ray exceeded MAX_TRAVERSAL_STEPS) marks the
// invocation as cut in `status`: the host retries with a smaller budget or
// fails naming the pixel, so a truncated result is never taken for an image.
//
// Entry points: render_tile (colour), probe_tile (per-pixel hit and shadow
// verdicts, for the robustness suite) and probe_pixel (one pixel's whole
// path, for `glint render --pixel`). Record layouts: src/probe.rs.
//
// The CPU reference (src/cpu/trace/) implements the same functions under
// the same names; keep them in step.
//
// Effects are compiled in only when the scene calls for them: each feature
// is an `override` (SPHERES, TRIANGLES, REFLECTION, AREA_LIGHTS, MOTION_BLUR,
// MULTISAMPLE; src/info.rs decides them), resolved by naga's
// process_overrides at pipeline build, after which src/gpu/shader.rs deletes
// every `if (FEATURE)` whose feature is off. Feature tests therefore stand
// alone in their own `if`, never inside a larger condition.

struct Frame {
    background: vec4<f32>,
    ambient: vec4<f32>,
    half_extent: vec2<f32>,
    size: vec2<u32>,
    node_count: u32,
    light_count: u32,
    sphere_count: u32,
    seed: u32,
    spp: u32,
    shadow_samples: u32,
    reflect_depth: u32,
    // Seconds the shutter stays open (0 without motion blur).
    shutter: f32,
    // log2 of the elements per chunk: triangles, normals, materials, nodes.
    chunk_shift: vec4<u32>,
    // Device addresses of spheres, triangles, nodes, primitive references,
    // normals and materials (layout::ADDRESS_LISTS), two to a vec4 as (low,
    // high) words; only a shader built with ADDRESSES reads them.
    addresses: array<vec4<u32>, 3>,
    // SAMPLER_SOBOL or SAMPLER_STRATIFIED (see sample.wgsl).
    sampling: u32,
    _pad0: u32,
    _pad: vec2<u32>,
}

struct Tile {
    origin: vec2<u32>,
    size: vec2<u32>,
    // Loop iterations an invocation may start in this pass (at least 1).
    budget: u32,
    // 1 on a tile's first pass: state is initialised, not read.
    first: u32,
    _pad: vec2<u32>,
}

// Where a pixel stands in its work between passes (render_tile).
struct PixelState {
    // Sum of the finished samples; `sample` is the next one.
    sum: vec3<f32>,
    sample: u32,
    // The sample in progress: reflect_path's colour and bounce.
    color: vec3<f32>,
    bounce: u32,
    weight: vec3<f32>,
    // Next light to shade at the current hit.
    light: u32,
    // shade_phong's running sum at the current hit.
    shade: vec3<f32>,
    // Next sample of the area light `light`.
    area_sample: u32,
    // area_term's running sum for light `light`.
    area: vec3<f32>,
    // The current hit (prim, t, b1, b2) of the current ray.
    prim: u32,
    origin: vec3<f32>,
    t: f32,
    dir: vec3<f32>,
    b1: f32,
    time: f32,
    b2: f32,
    // PHASE_START, PHASE_TRACE or PHASE_SHADE.
    phase: u32,
    _pad: u32,
}

struct Status {
    // Pixels with work left after this pass.
    remaining: atomic<u32>,
    // Invocations whose work was cut short, and the smallest such pixel
    // index (y * width + x).
    cut: atomic<u32>,
    first_cut: atomic<u32>,
    // Rays this pass cast: closest-hit (primary and reflected) and shadow
    // (one per point light, or per area-light sample); for `--stats`.
    closest_rays: atomic<u32>,
    shadow_rays: atomic<u32>,
    _pad: u32,
}

struct Sphere {
    center: vec3<f32>,
    radius: f32,
    kd: vec3<f32>,
    shininess: f32,
    ks: vec3<f32>,
    _pad: f32,
}

struct Triangle {
    v: array<vec4<f32>, 3>,
}

struct TriangleNormals {
    n: array<f32, 9>,
}

struct Material {
    kd: vec3<f32>,
    shininess: f32,
    ks: vec3<f32>,
    _pad: f32,
}

struct Light {
    position: vec3<f32>,
    // LIGHT_POINT, LIGHT_SPHERE or LIGHT_RECT.
    kind: u32,
    color: vec3<f32>,
    radius: f32,
    edge_u: vec3<f32>,
    // Point lights: the run of `skips` naming the surfaces through the light.
    skip_first: u32,
    edge_v: vec3<f32>,
    skip_count: u32,
    velocity: vec3<f32>,
    _pad2: f32,
}

// Four child boxes quantised within the node's box (src/layout/pack.rs:
// GpuWideNode), and per lane a node index, WIDE_LEAF | first primitive
// reference (see leaf_first), or WIDE_EMPTY.
struct WideNode {
    origin: vec4<f32>,
    lo_hi: vec4<u32>,
    hi_yz: vec4<u32>,
    child: vec4<u32>,
}

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> tile: Tile;
@group(0) @binding(2) var<storage, read> spheres: array<Sphere>;
@group(0) @binding(3) var<storage, read> triangles: array<Triangle>;
@group(0) @binding(4) var<storage, read> normals: array<TriangleNormals>;
@group(0) @binding(5) var<storage, read> lights: array<Light>;
@group(0) @binding(6) var<storage, read> nodes: array<WideNode>;
@group(0) @binding(7) var<storage, read> prim_refs: array<u32>;
@group(0) @binding(8) var<storage, read_write> output: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read> velocities: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read_write> state: array<PixelState>;
@group(0) @binding(11) var<storage, read_write> status: Status;
@group(0) @binding(12) var<storage, read> materials: array<Material>;
@group(0) @binding(13) var<storage, read> skips: array<u32>;
@group(0) @binding(14) var<storage, read> triangles1: array<Triangle>;
@group(0) @binding(15) var<storage, read> triangles2: array<Triangle>;
@group(0) @binding(16) var<storage, read> triangles3: array<Triangle>;
@group(0) @binding(17) var<storage, read> normals1: array<TriangleNormals>;
@group(0) @binding(18) var<storage, read> normals2: array<TriangleNormals>;
@group(0) @binding(19) var<storage, read> normals3: array<TriangleNormals>;
@group(0) @binding(20) var<storage, read> materials1: array<Material>;
@group(0) @binding(21) var<storage, read> materials2: array<Material>;
@group(0) @binding(22) var<storage, read> materials3: array<Material>;
@group(0) @binding(23) var<storage, read> nodes1: array<WideNode>;
@group(0) @binding(24) var<storage, read> nodes2: array<WideNode>;
@group(0) @binding(25) var<storage, read> nodes3: array<WideNode>;
// See "Uniform lists" above; lengths are src/layout/types.rs's uniform_list_len.
@group(0) @binding(26) var<uniform> spheres_u: array<Sphere, 1365>;
// Triangles as three vec4 each (1,365), or with UNIFORM_CORNERS the corners
// only, the nine position words of each back to back (1,820; the hit test
// reads them, shading then reads the list for the material bits).
@group(0) @binding(27) var<uniform> triangles_u: array<vec4<f32>, 4096>;
@group(0) @binding(28) var<uniform> nodes_u: array<WideNode, 1024>;
// Primitive references, four to an element.
@group(0) @binding(29) var<uniform> prim_refs_u: array<vec4<u32>, 4096>;
// Never bound: it marks the device-address loads (see "Address lists"
// above), whose bodies src/gpu/shader.rs replaces.
@group(0) @binding(30) var<storage, read> device_memory: array<vec4<u32>>;

// Loop iterations this invocation has run (every loop counts, as drivers
// count them), and whether any of its loops ended without its own exit.
var<private> work: u32;
var<private> cut: bool;

const SPHERE_BIT: u32 = 0x80000000u;
const BVH_MAX_DEPTH: u32 = 64u;
const TRAVERSAL_STACK: u32 = 64u;
const WIDE_LEAF: u32 = 0x80000000u;
const WIDE_EMPTY: u32 = 0xffffffffu;
const LEAF_END: u32 = 0x40000000u;
const LEAF_COUNT_SHIFT: u32 = 28u;
const LEAF_COUNT_MASK: u32 = 7u;
const WORKGROUP_SIZE: u32 = 8u;
const NO_HIT: u32 = 0xffffffffu;
// Most iterations one BVH traversal may take; a ray that needs more is cut
// (reported, never rendered short). Far above any measured traversal (the
// hard cases and 2M-triangle scenes stay below a few hundred), and far below
// llvmpipe's 65535.
const MAX_TRAVERSAL_STEPS: u32 = 16384u;
// render_tile's phases: what the next step of a pixel does.
const PHASE_START: u32 = 0u;
const PHASE_TRACE: u32 = 1u;
const PHASE_SHADE: u32 = 2u;
// Largest finite f32: "no limit" for t without producing inf * 0 anywhere.
const T_INF: f32 = 3.40282347e38;
// Robust BVH traversal (Ize 2013, "Robust BVH Ray Traversal", JCGT 2(2)):
// scaling t_far by 1 + 2*gamma(3), gamma(n) = n*eps / (1 - n*eps), eps = 2^-24,
// makes the slab test conservative under f32 rounding.
const BOX_T_SCALE: f32 = 1.0000003576;
// Direction components smaller than this are replaced by it (keeping their
// sign) before taking reciprocals, so the slab test never forms 0 * inf = NaN
// for axis-aligned rays; the resulting boxes can only be too large, never miss.
const MIN_DIR: f32 = 1e-30;
// Wächter and Binder, "A Fast and Robust Method for Avoiding Self-Intersection",
// Ray Tracing Gems ch. 6: offset in integer ulps, except near the origin.
// Their near-origin region and fallback offset are absolute (1/32, 1/65536),
// which is a scene-scale epsilon: a scene 1e-3 across lies wholly inside it
// and its shadow rays start 1.5% of the scene above the surface (measured:
// 4 acne and 54 seam pixels in the acne_scale_1e-3 hard case; 0 and 0 now).
// glint scales both per axis by the magnitude that bounds the rounding error
// of the hit point: sum |b_i v_i| for a triangle (Pharr, Jakob and Humphreys,
// PBR 3rd ed. sec. 3.9), |c| + r for a sphere; so the method holds at every
// scale. (The largest |v_i| instead is too coarse: on a 2e5-wide triangle
// near the camera it lifted shadow rays by 3e-3: 196 acne pixels in a
// grazing case, against 12.)
const OFFSET_ORIGIN: f32 = 0.03125;
const OFFSET_FLOAT_SCALE: f32 = 1.52587890625e-05;
const OFFSET_INT_SCALE: f32 = 256.0;

// true: the robust methods cited below. false: the textbook methods with one
// scene-scale epsilon (Möller-Trumbore with a determinant epsilon, the
// quadratic-formula sphere test, a fixed origin offset), compiled only into
// the "naive" variant that `glint bench hard` measures against. Resolved like
// the feature overrides (src/gpu/shader.rs), so each variant carries one branch.
override ROBUST: bool = true;
// The scene's feature set (see the header).
override SPHERES: bool = true;
override TRIANGLES: bool = true;
override REFLECTION: bool = true;
override AREA_LIGHTS: bool = true;
override MOTION_BLUR: bool = true;
override MULTISAMPLE: bool = true;
// Big lists span several bindings (see "Split lists" above).
override SPLIT: bool = false;
// Some point light lies on a surface: shadow rays towards it treat the
// surfaces through it by the rule of src/bvh/lights_on_surfaces.rs.
override LIGHT_SKIPS: bool = false;
// Spheres, triangles, nodes and primitive references are read from their
// uniform copies (see "Uniform lists" above).
override UNIFORM_LISTS: bool = false;
// The uniform triangle copy holds corners only (layout::CopyForm::Corners):
// a scene of 1,366 to 1,820 triangles. Each word then has its own address,
// 5% more instructions than the whole form on `table`, so only where that
// does not fit.
override UNIFORM_CORNERS: bool = false;
// Read spheres, triangles, nodes, primitive references, normals and
// materials through their device addresses (see "Address lists" above).
override ADDRESSES: bool = false;
// Reference slot r holds triangle r (a scene without spheres, its
// triangles in leaf order: layout::GpuScene::scene_triangles), and a leaf
// lane's word holds its count (layout::LEAF_COUNT_SHIFT): the leaf loop
// reads no references.
override LEAF_ORDER: bool = false;
// A tile's first pass that keeps no state: no pixel state is read or
// written, and a pixel that runs out of budget only counts itself in
// `status.remaining`, whereupon the host redoes the tile with the
// resumable shader (src/gpu/driver.rs, src/gpu/render/passes.rs). Measured on
// Mesa 22.3, whose llvmpipe runs a branch's loads and stores lane by lane
// even when no lane takes it: the state's words in and out were 12.6% of
// test1's render instructions, 3.8% of `table`'s.
override ONE_PASS: bool = false;
const TANGENT_BAND: f32 = 0.000244140625;
const ON_SURFACE: f32 = 0.00000095367431640625;
const SPLIT_CHUNKS: u32 = 4u;
const LIGHT_POINT: u32 = 0u;
const LIGHT_SPHERE: u32 = 1u;
const LIGHT_RECT: u32 = 2u;
// Random number streams (see rng): one per purpose, area lights one per
// (bounce, light).
const STREAM_PIXEL: u32 = 0u;
const STREAM_TIME: u32 = 1u;
const STREAM_LIGHT: u32 = 2u;
// The index that draws a per-stream value (a stratum rotation) rather than a
// per-sample one.
const ROTATION: u32 = 0xffffffffu;
// Frame.sampling: the samplers of src/scene/settings.rs's Sampler.
const SAMPLER_STRATIFIED: u32 = 0u;
const SAMPLER_SOBOL: u32 = 1u;
// The sobol sampler's index that draws a dimension's key (with ROTATION as
// the sample), and what tells its coordinates' seeds apart.
const SOBOL_KEY: u32 = 0xfffffffeu;
const SOBOL_X: u32 = 0x68bc21ebu;
const SOBOL_Y: u32 = 0x02e5be93u;
const PI: f32 = 3.14159265358979;
// The naive variant's magic numbers: a distance and Möller-Trumbore's
// determinant epsilon (Möller and Trumbore 1997).
const NAIVE_OFFSET: f32 = 1e-4;
const NAIVE_DET_EPSILON: f32 = 1e-6;
// probe_tile flag bits.
const FLAG_NONFINITE_COLOR: u32 = 1u;
const FLAG_NONFINITE_SURFACE: u32 = 2u;
// probe_pixel record: PATH_HEADER vec4s, then PATH_PER_LIGHT per light.
const PATH_HEADER: u32 = 8u;
const PATH_PER_LIGHT: u32 = 3u;

