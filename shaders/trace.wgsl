// glint's ray tracing kernel: one invocation per pixel of a tile.
//
// Bindings (group 0); the structs mirror src/layout.rs and tests/layout.rs
// checks every offset and size against it:
//   0  uniform            Frame          per-image constants
//   1  uniform            Tile           the tile this dispatch renders
//   2  storage, read      array<Sphere>
//   3  storage, read      array<Triangle>          positions (w: material index bits)
//   4  storage, read      array<TriangleNormals>   the 3 vertex normals of each triangle
//   5  storage, read      array<Light>
//   6  storage, read      array<WideNode>          four children a node, root first (src/layout.rs)
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
// those instead (src/gpu/render.rs: choose_lists; src/layout.rs: CopyForm). GPUs keep the storage lists: their
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
// load from the address they are given (src/gpu/shader.rs: device_loads;
// src/gpu/render.rs: choose_lists). The lists stay bound as storage
// buffers for everything else.
//
// Bounded work. render_tile does not render a pixel in one go: it runs the
// pixel's work (samples, bounces, one light term or one area-light sample at
// a time) as steps of a resumable state machine, and stops when the pass's
// budget of loop iterations (tile.budget) is spent, saving its place in
// `state`. The host dispatches passes until no pixel is left. Each step
// computes what the uninterrupted algorithm (src/cpu/trace.rs: pixel_color,
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
// The CPU reference (src/cpu/trace.rs) implements the same functions under
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

// Four child boxes quantised within the node's box (src/layout.rs:
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
// See "Uniform lists" above; lengths are src/layout.rs's uniform_list_len.
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
// surfaces through it by the rule of src/lights_on_surfaces.rs.
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
// resumable shader (src/gpu/render.rs: TileWork::resumable). Measured on
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

// A ray with what every intersection test needs precomputed once.
struct Ray {
    origin: vec3<f32>,
    dir: vec3<f32>,
    inv_dir: vec3<f32>,
    // Watertight triangle test: axis permutation (kx, ky, kz) and shear.
    k: vec3<u32>,
    shear: vec3<f32>,
    // Seconds after the frame's time (motion blur).
    time: f32,
}

struct Hit {
    t: f32,
    // Primitive reference as stored in prim_refs, or NO_HIT.
    prim: u32,
    // Barycentric weights of vertices 1 and 2 (triangles only).
    b1: f32,
    b2: f32,
}

fn sign_nonzero(x: f32) -> f32 {
    return select(-1.0, 1.0, x >= 0.0);
}

fn make_ray(origin: vec3<f32>, dir: vec3<f32>, time: f32) -> Ray {
    let safe = select(dir, vec3(sign_nonzero(dir.x), sign_nonzero(dir.y), sign_nonzero(dir.z)) * MIN_DIR,
                      abs(dir) < vec3(MIN_DIR));
    // Woop, Benthin and Wald, "Watertight Ray/Triangle Intersection", JCGT 2(1)
    // 2013: z is the dominant axis; swapping x and y when dir[kz] < 0 keeps
    // the winding, so the edge functions keep their signs.
    let a = abs(dir);
    var kz = 2u;
    if (a.x > a.y && a.x > a.z) {
        kz = 0u;
    } else if (a.y > a.z) {
        kz = 1u;
    }
    var kx = (kz + 1u) % 3u;
    var ky = (kx + 1u) % 3u;
    if (dir[kz] < 0.0) {
        let tmp = kx;
        kx = ky;
        ky = tmp;
    }
    let sz = 1.0 / dir[kz];
    return Ray(origin, dir, 1.0 / safe, vec3(kx, ky, kz), vec3(dir[kx] * sz, dir[ky] * sz, sz), time);
}

// Primary ray through `offset` within pixel (x, y) ((0.5, 0.5) is the
// centre); row 0 is the top.
fn camera_ray(x: u32, y: u32, offset: vec2<f32>, time: f32) -> Ray {
    let size = vec2<f32>(frame.size);
    let ndc_x = (2.0 * (f32(x) + offset.x) / size.x - 1.0) * frame.half_extent.x;
    let ndc_y = (1.0 - 2.0 * (f32(y) + offset.y) / size.y) * frame.half_extent.y;
    return make_ray(vec3(0.0), normalize(vec3(ndc_x, ndc_y, -1.0)), time);
}

fn pixel_ray(x: u32, y: u32) -> Ray {
    return camera_ray(x, y, vec2(0.5), 0.0);
}

// Counter-based random numbers: a pure function of (seed, pixel, sample,
// stream, index), so every pixel and sample draws the same numbers on any
// device, in any tile order, and on the CPU (src/cpu/sample.rs). The mixer
// is Wellons' "lowbias32" integer hash, chained over the key.
fn hash_u32(x: u32) -> u32 {
    var h = x;
    h ^= h >> 16u;
    h *= 0x7feb352du;
    h ^= h >> 15u;
    h *= 0x846ca68bu;
    h ^= h >> 16u;
    return h;
}

fn rng(pixel: u32, sample: u32, stream: u32, index: u32) -> u32 {
    var h = hash_u32(frame.seed ^ 0x9e3779b9u);
    h = hash_u32(h ^ pixel);
    h = hash_u32(h ^ sample);
    h = hash_u32(h ^ stream);
    return hash_u32(h ^ index);
}

// [0, 1) from the top 24 bits: exact in f32, so CPU and GPU agree bit for bit.
fn unit_float(x: u32) -> f32 {
    return f32(x >> 8u) * 5.9604644775390625e-8;
}

// ceil(sqrt(n)) in integers (a float sqrt may be off by one ulp).
fn grid_columns(n: u32) -> u32 {
    var c = u32(sqrt(f32(n)));
    if (c * c < n) {
        c += 1u;
    }
    if (c > 1u && (c - 1u) * (c - 1u) >= n) {
        c -= 1u;
    }
    return max(c, 1u);
}

// Sample k of n in [0, 1)^2, stratified: the cols x rows grid (cols =
// ceil(sqrt n)) has at least n cells; sample k takes cell (k + rotation) mod
// cells, jittered within it. The rotation is random per pixel (or shading
// point), so every cell is equally likely for every k (unbiased) and no two
// samples share a cell (stratified). n a perfect square: a jittered grid.
fn stratified_2d(k: u32, n: u32, rotation: u32, jitter: vec2<f32>) -> vec2<f32> {
    let cols = grid_columns(n);
    let rows = (n + cols - 1u) / cols;
    let cell = (k + rotation % (cols * rows)) % (cols * rows);
    return vec2((f32(cell % cols) + jitter.x) / f32(cols), (f32(cell / cols) + jitter.y) / f32(rows));
}

// Entry distance of the ray into the box within [0, t_max], or T_INF if it misses.
fn hit_aabb(ray: Ray, bmin: vec3<f32>, bmax: vec3<f32>, t_max: f32) -> f32 {
    let t0 = (bmin - ray.origin) * ray.inv_dir;
    let t1 = (bmax - ray.origin) * ray.inv_dir;
    let tn = min(t0, t1);
    let tf = max(t0, t1);
    let t_near = max(max(tn.x, tn.y), max(tn.z, 0.0));
    let t_far = min(min(tf.x, tf.y), min(tf.z, t_max)) * BOX_T_SCALE;
    return select(T_INF, t_near, t_near <= t_far);
}

// Both t where the ray's line meets the sphere (unordered), or T_INF twice
// when it misses, or only grazes it: its discriminant is below `band` (see
// graze_band; 0 but for some shadow rays). Ray Tracing Gems ch. 7 (Haines et al.): the discriminant
// from the perpendicular distance to the centre and the stable root pair
// avoid catastrophic cancellation for small or distant spheres.
fn sphere_roots(ray: Ray, s: Sphere, band: f32) -> vec2<f32> {
    let f = ray.origin - s.center;
    let a = dot(ray.dir, ray.dir);
    let b = -dot(f, ray.dir);
    let c = dot(f, f) - s.radius * s.radius;
    let l = f + (b / a) * ray.dir;
    let disc = s.radius * s.radius - dot(l, l);
    if (disc < band) {
        return vec2(T_INF);
    }
    let q = b + sign_nonzero(b) * sqrt(a * disc);
    return vec2(c / q, q / a);
}

// Nearest t in (0, t_max) where the ray meets the sphere, or T_INF.
fn hit_sphere(ray: Ray, s: Sphere, t_max: f32, band: f32) -> f32 {
    if (!ROBUST) {
        return hit_sphere_naive(ray, s, t_max);
    }
    let roots = sphere_roots(ray, s, band);
    let t_lo = min(roots.x, roots.y);
    let t_hi = max(roots.x, roots.y);
    if (t_lo > 0.0 && t_lo < t_max) {
        return t_lo;
    }
    if (t_hi > 0.0 && t_hi < t_max) {
        return t_hi;
    }
    return T_INF;
}

// The textbook quadratic: b^2 - 4ac cancels catastrophically when the sphere
// is small against its distance.
fn hit_sphere_naive(ray: Ray, s: Sphere, t_max: f32) -> f32 {
    let oc = ray.origin - s.center;
    let a = dot(ray.dir, ray.dir);
    let b = 2.0 * dot(oc, ray.dir);
    let c = dot(oc, oc) - s.radius * s.radius;
    let disc = b * b - 4.0 * a * c;
    if (disc < 0.0) {
        return T_INF;
    }
    let root = sqrt(disc);
    let t0 = (-b - root) / (2.0 * a);
    let t1 = (-b + root) / (2.0 * a);
    if (t0 > 0.0 && t0 < t_max) {
        return t0;
    }
    if (t1 > 0.0 && t1 < t_max) {
        return t1;
    }
    return T_INF;
}

// Möller and Trumbore 1997, as most ray tracers of this assignment write it:
// barycentric bounds tested per triangle (shared edges can fall between two
// neighbours) and an absolute determinant epsilon (small triangles vanish).
fn hit_triangle_naive(ray: Ray, tri: Triangle, t_max: f32) -> vec3<f32> {
    let e1 = tri.v[1].xyz - tri.v[0].xyz;
    let e2 = tri.v[2].xyz - tri.v[0].xyz;
    let pv = cross(ray.dir, e2);
    let det = dot(e1, pv);
    if (abs(det) < NAIVE_DET_EPSILON) {
        return vec3(T_INF, 0.0, 0.0);
    }
    let inv_det = 1.0 / det;
    let tv = ray.origin - tri.v[0].xyz;
    let u = dot(tv, pv) * inv_det;
    if (u < 0.0 || u > 1.0) {
        return vec3(T_INF, 0.0, 0.0);
    }
    let qv = cross(tv, e1);
    let v = dot(ray.dir, qv) * inv_det;
    if (v < 0.0 || u + v > 1.0) {
        return vec3(T_INF, 0.0, 0.0);
    }
    let t = dot(e2, qv) * inv_det;
    if (t <= 0.0 || t >= t_max) {
        return vec3(T_INF, 0.0, 0.0);
    }
    return vec3(t, u, v);
}

// Watertight ray/triangle test (Woop, Benthin, Wald 2013). Edges count as
// inside for both neighbours, so a ray through a shared edge or vertex hits
// at least one of them; there is no epsilon on the determinant.
// Returns (t, b1, b2) with t = T_INF for a miss.
fn hit_triangle(ray: Ray, tri: Triangle, t_max: f32) -> vec3<f32> {
    if (!ROBUST) {
        return hit_triangle_naive(ray, tri, t_max);
    }
    let a = tri.v[0].xyz - ray.origin;
    let b = tri.v[1].xyz - ray.origin;
    let c = tri.v[2].xyz - ray.origin;
    let k = ray.k;
    let s = ray.shear;
    let ax = a[k.x] - s.x * a[k.z];
    let ay = a[k.y] - s.y * a[k.z];
    let bx = b[k.x] - s.x * b[k.z];
    let by = b[k.y] - s.y * b[k.z];
    let cx = c[k.x] - s.x * c[k.z];
    let cy = c[k.y] - s.y * c[k.z];
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if ((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) {
        return vec3(T_INF, 0.0, 0.0);
    }
    let det = u + v + w;
    if (det == 0.0) {
        return vec3(T_INF, 0.0, 0.0);
    }
    let az = s.z * a[k.z];
    let bz = s.z * b[k.z];
    let cz = s.z * c[k.z];
    let t_scaled = u * az + v * bz + w * cz;
    // t = t_scaled / det must lie in (0, t_max); compare without dividing.
    let positive = (t_scaled > 0.0) && (t_scaled < t_max * det);
    let negative = (t_scaled < 0.0) && (t_scaled > t_max * det);
    let inside = select(negative, positive, det > 0.0);
    if (!inside) {
        return vec3(T_INF, 0.0, 0.0);
    }
    let inv_det = 1.0 / det;
    return vec3(t_scaled * inv_det, v * inv_det, w * inv_det);
}

// Sphere `index` where it is `time` seconds after the frame's time.
fn sphere_at(index: u32, time: f32) -> Sphere {
    var s: Sphere;
    if (UNIFORM_LISTS) {
        s = spheres_u[index];
    } else {
        if (ADDRESSES) {
            let a = list_address(0u);
            let k = 3u * min(index, arrayLength(&spheres) - 1u);
            let w0 = bitcast<vec4<f32>>(device_load4(a, k));
            let w1 = bitcast<vec4<f32>>(device_load4(a, k + 1u));
            let w2 = bitcast<vec4<f32>>(device_load4(a, k + 2u));
            s = Sphere(w0.xyz, w0.w, w1.xyz, w1.w, w2.xyz, w2.w);
        } else {
            s = spheres[index];
        }
    }
    if (MOTION_BLUR) {
        s.center += velocities[index].xyz * time;
    }
    return s;
}

// The split-list readers: element `i` of a list, from the chunk that holds
// it (a shader without SPLIT reads the first binding only), or from its
// uniform copy (UNIFORM_LISTS).
fn load_triangle(i: u32) -> Triangle {
    // if/else on one override at a time: specialisation keeps one branch,
    // and only a uniform-lists shader names the copies (tested).
    if (UNIFORM_LISTS) {
        if (UNIFORM_CORNERS) {
            return load_triangle_list(i);
        } else {
            let b = 3u * i;
            return Triangle(array(triangles_u[b], triangles_u[b + 1u], triangles_u[b + 2u]));
        }
    } else {
        if (ADDRESSES) {
            let a = list_address(1u);
            let k = 3u * min(i, arrayLength(&triangles) - 1u);
            return Triangle(array(
                bitcast<vec4<f32>>(device_load4(a, k)),
                bitcast<vec4<f32>>(device_load4(a, k + 1u)),
                bitcast<vec4<f32>>(device_load4(a, k + 2u)),
            ));
        } else {
            return load_triangle_list(i);
        }
    }
}

fn load_triangle_list(i: u32) -> Triangle {
    if (SPLIT) {
        let shift = frame.chunk_shift.x;
        let j = i & ((1u << shift) - 1u);
        switch (i >> shift) {
            case 0u: { return triangles[j]; }
            case 1u: { return triangles1[j]; }
            case 2u: { return triangles2[j]; }
            default: { return triangles3[j]; }
        }
    }
    return triangles[i];
}

// Triangle i's corners for a hit test (w = 0 with UNIFORM_CORNERS: only
// shading reads the material bits, from the list).
fn load_corners(i: u32) -> Triangle {
    if (UNIFORM_CORNERS) {
        let k = 9u * i;
        // Written out: a loop here is a loop in llvmpipe's code.
        return Triangle(array(
            vec4(corner_word(k), corner_word(k + 1u), corner_word(k + 2u), 0.0),
            vec4(corner_word(k + 3u), corner_word(k + 4u), corner_word(k + 5u), 0.0),
            vec4(corner_word(k + 6u), corner_word(k + 7u), corner_word(k + 8u), 0.0),
        ));
    } else {
        return load_triangle(i);
    }
}

fn corner_word(w: u32) -> f32 {
    return triangles_u[w >> 2u][w & 3u];
}

fn load_normals(i: u32) -> TriangleNormals {
    if (ADDRESSES) {
        let a = list_address(4u);
        let k = 9u * min(i, arrayLength(&normals) - 1u);
        // Written out, as in load_corners.
        return TriangleNormals(array(
            bitcast<f32>(device_load1(a, k)), bitcast<f32>(device_load1(a, k + 1u)),
            bitcast<f32>(device_load1(a, k + 2u)), bitcast<f32>(device_load1(a, k + 3u)),
            bitcast<f32>(device_load1(a, k + 4u)), bitcast<f32>(device_load1(a, k + 5u)),
            bitcast<f32>(device_load1(a, k + 6u)), bitcast<f32>(device_load1(a, k + 7u)),
            bitcast<f32>(device_load1(a, k + 8u)),
        ));
    } else {
        if (SPLIT) {
            let shift = frame.chunk_shift.y;
            let j = i & ((1u << shift) - 1u);
            switch (i >> shift) {
                case 0u: { return normals[j]; }
                case 1u: { return normals1[j]; }
                case 2u: { return normals2[j]; }
                default: { return normals3[j]; }
            }
        }
        return normals[i];
    }
}

fn load_material(i: u32) -> Material {
    if (ADDRESSES) {
        let a = list_address(5u);
        let k = 2u * min(i, arrayLength(&materials) - 1u);
        let w0 = bitcast<vec4<f32>>(device_load4(a, k));
        let w1 = bitcast<vec4<f32>>(device_load4(a, k + 1u));
        return Material(w0.xyz, w0.w, w1.xyz, w1.w);
    } else {
        if (SPLIT) {
            let shift = frame.chunk_shift.z;
            let j = i & ((1u << shift) - 1u);
            switch (i >> shift) {
                case 0u: { return materials[j]; }
                case 1u: { return materials1[j]; }
                case 2u: { return materials2[j]; }
                default: { return materials3[j]; }
            }
        }
        return materials[i];
    }
}

fn load_node(i: u32) -> WideNode {
    if (UNIFORM_LISTS) {
        return nodes_u[i];
    } else {
        if (ADDRESSES) {
            let a = list_address(2u);
            let k = 4u * min(i, arrayLength(&nodes) - 1u);
            return WideNode(
                bitcast<vec4<f32>>(device_load4(a, k)),
                device_load4(a, k + 1u),
                device_load4(a, k + 2u),
                device_load4(a, k + 3u),
            );
        } else {
            if (SPLIT) {
                let shift = frame.chunk_shift.w;
                let j = i & ((1u << shift) - 1u);
                switch (i >> shift) {
                    case 0u: { return nodes[j]; }
                    case 1u: { return nodes1[j]; }
                    case 2u: { return nodes2[j]; }
                    default: { return nodes3[j]; }
                }
            }
            return nodes[i];
        }
    }
}

// List j's device address (ADDRESSES), as (low, high) words. Its readers
// clamp their index to the list's binding, as naga's bounds checks do for
// the bindings' own reads, so that a builder bug cannot read past the list.
fn list_address(j: u32) -> vec2<u32> {
    let w = frame.addresses[j >> 1u];
    return select(w.xy, w.zw, (j & 1u) != 0u);
}

// Element i of the array of vec4<u32> at device address `base` (low, high
// words). The body here only marks the function: src/gpu/shader.rs
// (device_loads) replaces it by a load through a PhysicalStorageBuffer
// pointer, with the address arithmetic in 64 bits.
fn device_load4(base: vec2<u32>, i: u32) -> vec4<u32> {
    return device_memory[base.x ^ base.y ^ i];
}

// Element i of the array of u32 at device address `base`; see device_load4.
fn device_load1(base: vec2<u32>, i: u32) -> u32 {
    return device_memory[base.x ^ base.y ^ i].x;
}

fn triangle_at(index: u32, time: f32) -> Triangle {
    return moved(load_triangle(index), index, time);
}

// triangle_at for a hit test (load_corners).
fn corners_at(index: u32, time: f32) -> Triangle {
    return moved(load_corners(index), index, time);
}

// Triangle `index`, `tri`, where it is `time` seconds after the frame's time.
fn moved(tri_in: Triangle, index: u32, time: f32) -> Triangle {
    var tri = tri_in;
    if (MOTION_BLUR) {
        // xyz only: w holds material index bits, which arithmetic could
        // flush (they read as denormals).
        let shift = velocities[frame.sphere_count + index].xyz * time;
        tri.v[0] = vec4(tri.v[0].xyz + shift, tri.v[0].w);
        tri.v[1] = vec4(tri.v[1].xyz + shift, tri.v[1].w);
        tri.v[2] = vec4(tri.v[2].xyz + shift, tri.v[2].w);
    }
    return tri;
}

fn light_at(index: u32, time: f32) -> Light {
    var light = lights[index];
    if (MOTION_BLUR) {
        light.position += light.velocity * time;
    }
    return light;
}

// The run of `skips` (first, count) for the shadow ray being traced, set by
// point_term (the only caller of occluder); read only by any-hit traversal.
var<private> skip_range: vec2<u32>;
// The grazing band's height for that shadow ray (in_plane_graze), set and
// read alike.
var<private> graze_h: f32;

// The least discriminant r^2 - |l|^2 at which a shadow ray whose line may
// lie up to h off its true one still meets a sphere of radius r (h = 0:
// any). Moving a line by h changes |l|^2 by at most 2 r h + h^2, so within
// the band it may only graze the sphere; the sphere's own rounding adds
// ON_SURFACE r to h.
fn graze_band(h: f32, r: f32) -> f32 {
    if (h <= 0.0) {
        return 0.0;
    }
    let hr = h + ON_SURFACE * r;
    return hr * (2.0 * r + hr);
}

// For a shadow ray towards a point light on a surface: when the light lies
// in the plane of the surface the ray leaves (within the ray's own lift off
// it and the light's rounding), the height of the band within which the
// ray's true line runs inside that plane, else 0. Such a line can only
// touch a sphere resting on the plane, so lifted by the origin offset it
// must not be blocked by clipping one.
fn in_plane_graze(sp: SurfacePoint, origin: vec3<f32>, light_pos: vec3<f32>) -> f32 {
    let to_light = light_pos - sp.p;
    let t = abs(light_pos);
    let h = 2.0 * length(origin - sp.p) + ON_SURFACE * (max(max(t.x, t.y), t.z) + length(to_light));
    return select(0.0, 2.0 * h, abs(dot(sp.ng, to_light)) <= h);
}

fn skipped(prim: u32) -> bool {
    var found = false;
    var k = 0u;
    for (; k < skip_range.y; k++) {
        work += 1u;
        if (skips[skip_range.x + k] == prim) {
            found = true;
        }
    }
    if (k < skip_range.y) {
        cut = true;
    }
    return found;
}

// For a sphere through the light a shadow ray ends at: the crossing that is
// not the light's own, when it lies in (0, 1 - TANGENT_BAND), else T_INF.
fn hit_sphere_through_end(ray: Ray, s: Sphere) -> f32 {
    let roots = sphere_roots(ray, s, graze_band(graze_h, s.radius));
    // The root nearer 1 is the light's own (a miss gives T_INF either way).
    let other = select(roots.y, roots.x, abs(roots.x - 1.0) > abs(roots.y - 1.0));
    if (other > 0.0 && other < 1.0 - TANGENT_BAND) {
        return other;
    }
    return T_INF;
}

// Tests the primitive `prim` (a reference without its LEAF_END bit); true
// when `any_hit` and it blocks, so the traversal can stop.
fn hit_prim(ray: Ray, prim: u32, best: ptr<function, Hit>, any_hit: bool) -> bool {
    let index = prim & ~SPHERE_BIT;
    if (LIGHT_SKIPS) {
        if (any_hit && skipped(prim)) {
            // A surface through the light: triangles never block it, a
            // sphere only with its other crossing.
            if ((prim & SPHERE_BIT) != 0u) {
                let t = hit_sphere_through_end(ray, sphere_at(index, ray.time));
                if (t < (*best).t) {
                    *best = Hit(t, prim, 0.0, 0.0);
                    return true;
                }
            }
            return false;
        }
    }
    if ((prim & SPHERE_BIT) != 0u) {
        if (SPHERES) {
            let s = sphere_at(index, ray.time);
            var band = 0.0;
            if (LIGHT_SKIPS) {
                band = select(0.0, graze_band(graze_h, s.radius), any_hit);
            }
            let t = hit_sphere(ray, s, (*best).t, band);
            if (t < (*best).t) {
                *best = Hit(t, prim, 0.0, 0.0);
                return any_hit;
            }
        }
    } else {
        if (TRIANGLES) {
            let h = hit_triangle(ray, corners_at(index, ray.time), (*best).t);
            if (h.x < (*best).t) {
                *best = Hit(h.x, prim, h.y, h.z);
                return any_hit;
            }
        }
    }
    return false;
}

// The four bytes of w, lowest first.
fn unpack_bytes(w: u32) -> vec4<f32> {
    return vec4<f32>((vec4(w) >> vec4(0u, 8u, 16u, 24u)) & vec4(0xffu));
}

// Entry distances of the ray into a node's four child boxes within
// [0, t_max]: each box decoded (it holds the binary tree's f32 box; see
// GpuWideNode), then hit_aabb's arithmetic lane by lane; T_INF where it
// misses and in unused lanes (which a NaN ray would otherwise pass).
fn hit_boxes(ray: Ray, node: WideNode, t_max: f32) -> vec4<f32> {
    let o = ray.origin;
    let d = ray.inv_dir;
    let e = bitcast<u32>(node.origin.w);
    let s = vec3(bitcast<f32>((e & 0xffu) << 23u), bitcast<f32>(((e >> 8u) & 0xffu) << 23u),
        bitcast<f32>(((e >> 16u) & 0xffu) << 23u));
    let lo_x = node.origin.x + unpack_bytes(node.lo_hi.x) * s.x;
    let lo_y = node.origin.y + unpack_bytes(node.lo_hi.y) * s.y;
    let lo_z = node.origin.z + unpack_bytes(node.lo_hi.z) * s.z;
    let hi_x = node.origin.x + unpack_bytes(node.lo_hi.w) * s.x;
    let hi_y = node.origin.y + unpack_bytes(node.hi_yz.x) * s.y;
    let hi_z = node.origin.z + unpack_bytes(node.hi_yz.y) * s.z;
    let x0 = (lo_x - o.x) * d.x;
    let x1 = (hi_x - o.x) * d.x;
    let y0 = (lo_y - o.y) * d.y;
    let y1 = (hi_y - o.y) * d.y;
    let z0 = (lo_z - o.z) * d.z;
    let z1 = (hi_z - o.z) * d.z;
    let t_near = max(max(min(x0, x1), min(y0, y1)), max(min(z0, z1), vec4(0.0)));
    let t_far = min(min(max(x0, x1), max(y0, y1)), min(max(z0, z1), vec4(t_max))) * BOX_T_SCALE;
    let hit = (t_near <= t_far) & (node.child != vec4(WIDE_EMPTY));
    return select(vec4(T_INF), t_near, hit);
}

// A child lane of a node: its entry distance (T_INF: missed), its word
// (WideNode.child) and its lane.
struct Child {
    t: f32,
    word: u32,
    lane: u32,
}

// Puts a and b in visiting order: nearer first, the later lane first at
// equal t (the CPU reference's order).
fn order(a: ptr<function, Child>, b: ptr<function, Child>) {
    let x = *a;
    let y = *b;
    if (y.t < x.t || (y.t == x.t && y.lane > x.lane)) {
        *a = y;
        *b = x;
    }
}

// A leaf lane's first reference slot (its word less WIDE_LEAF, and with
// LEAF_ORDER less its count: layout::LEAF_COUNT_SHIFT).
fn leaf_first(word: u32) -> u32 {
    if (LEAF_ORDER) {
        return word & ((1u << LEAF_COUNT_SHIFT) - 1u);
    }
    return word & ~WIDE_LEAF;
}

// With LEAF_ORDER: the slot after a leaf lane's last.
fn leaf_end(word: u32) -> u32 {
    return leaf_first(word) + ((word >> LEAF_COUNT_SHIFT) & LEAF_COUNT_MASK) + 1u;
}

// Appends c's word to out[k] when c was hit and is a leaf (kind WIDE_LEAF)
// or a node (kind 0).
fn append_hit(out: ptr<function, vec4<u32>>, k: ptr<function, u32>, c: Child, kind: u32) {
    let take = c.t < T_INF && (c.word & WIDE_LEAF) == kind;
    *out = select(*out, vec4(c.word), vec4(take) & (vec4(*k) == vec4(0u, 1u, 2u, 3u)));
    *k += u32(take);
}

// Walks the four-wide BVH. Closest hit in (0, t_max), or with `any_hit` the
// first hit found (shadow rays stop at the first blocker).
//
// A node's hit children are taken in the CPU reference's order
// (src/cpu/trace.rs: traverse_from): its leaves at once, then its inner
// nodes from the stack, each nearest first and, at equal entry distance,
// the later lane first. The distances are to the decoded boxes, a little larger than the
// CPU's, so the order may differ from the CPU's where two entries are
// close; which of two hits at exactly the same t is kept depends only on
// the tree, never on the run.
fn traverse(ray: Ray, t_max: f32, any_hit: bool) -> Hit {
    var best = Hit(t_max, NO_HIT, 0.0, 0.0);
    if (frame.node_count == 0u) {
        return best;
    }
    // Nodes still to visit, in groups of up to three, one group per node
    // that left any: `top` holds the newest (indices in xyz, how many in
    // w), `groups` the older ones. A node stores at most one group, and the
    // tree is at most BVH_MAX_DEPTH deep, so TRAVERSAL_STACK groups cannot
    // overflow. Groups rather than single entries: one vec4 store a node
    // instead of up to three scattered ones.
    var groups: array<vec4<u32>, TRAVERSAL_STACK>;
    var gsp = 0u;
    var top = vec4(0u);
    var entry = 0u;
    var steps = 0u;
    var finished = false;
    loop {
        if (steps >= MAX_TRAVERSAL_STEPS) {
            break;
        }
        steps += 1u;
        work += 1u;
        let node = load_node(entry);
        let t4 = hit_boxes(ray, node, best.t);
        var a = Child(t4.x, node.child.x, 0u);
        var b = Child(t4.y, node.child.y, 1u);
        var c = Child(t4.z, node.child.z, 2u);
        var d = Child(t4.w, node.child.w, 3u);
        // Five compare-exchanges order any four.
        order(&a, &b);
        order(&c, &d);
        order(&a, &c);
        order(&b, &d);
        order(&b, &c);
        // The hit leaves are tested here, nearest first (measured a little
        // faster on lavapipe than stacking them as entries).
        var leaves = vec4(0u);
        var kl = 0u;
        append_hit(&leaves, &kl, a, WIDE_LEAF);
        append_hit(&leaves, &kl, b, WIDE_LEAF);
        append_hit(&leaves, &kl, c, WIDE_LEAF);
        append_hit(&leaves, &kl, d, WIDE_LEAF);
        // One loop over all their primitives, leaf after leaf (each run ends
        // at its LEAF_END): a lane steps through its own run, instead of
        // every lane waiting out the most leaves and then the longest leaf
        // in two nested loops (4-10% faster on Mesa 22.3, whose loops run
        // their body once even when no lane enters; level on Mesa 25).
        var li = 0u;
        var r = leaf_first(leaves.x);
        var end = leaf_end(leaves.x);
        for (; li < kl && r < arrayLength(&prim_refs);) {
            work += 1u;
            var prim: u32;
            var last: bool;
            if (LEAF_ORDER) {
                // Slot r is triangle r, and the leaf's word says where it
                // ends: no load stands between one triangle and the next.
                prim = r;
                last = r + 1u == end;
            } else {
                var word: u32;
                if (UNIFORM_LISTS) {
                    word = prim_refs_u[r >> 2u][r & 3u];
                } else {
                    if (ADDRESSES) {
                        // Unclamped: the loop's condition bounds r by the
                        // binding's length.
                        word = device_load1(list_address(3u), r);
                    } else {
                        word = prim_refs[r];
                    }
                }
                prim = word & ~LEAF_END;
                last = (word & LEAF_END) != 0u;
            }
            if (hit_prim(ray, prim, &best, any_hit)) {
                return best;
            }
            if (last) {
                li += 1u;
                let next = leaves[min(li, 3u)];
                r = leaf_first(next);
                end = leaf_end(next);
            } else {
                r += 1u;
            }
        }
        if (li < kl) {
            cut = true;
        }
        // The hit inner nodes, farthest first: the nearest is visited next,
        // the rest wait as a group.
        var nodes = vec4(0u);
        var k = 0u;
        append_hit(&nodes, &k, d, 0u);
        append_hit(&nodes, &k, c, 0u);
        append_hit(&nodes, &k, b, 0u);
        append_hit(&nodes, &k, a, 0u);
        if (k > 0u) {
            entry = nodes[k - 1u];
            if (k > 1u) {
                if (top.w > 0u) {
                    groups[gsp] = top;
                    gsp += 1u;
                }
                top = vec4(nodes.xyz, k - 1u);
            }
            continue;
        }
        if (top.w == 0u) {
            if (gsp == 0u) {
                finished = true;
                break;
            }
            gsp -= 1u;
            top = groups[gsp];
        }
        top.w -= 1u;
        entry = top[top.w];
    }
    if (!finished) {
        cut = true;
    }
    return best;
}

fn trace_closest(ray: Ray) -> Hit {
    return traverse(ray, T_INF, false);
}

// The first blocker found strictly between the ray origin (t = 0) and the
// light (t = 1; the direction is unnormalized and ends at the light), or a
// Hit with prim NO_HIT.
fn occluder(ray: Ray) -> Hit {
    return traverse(ray, 1.0, true);
}

// Origin for a ray leaving p on the side n points to; `scale` bounds, per
// axis, the magnitudes p was computed from (SurfacePoint.scale).
fn offset_ray(p: vec3<f32>, n: vec3<f32>, scale: vec3<f32>) -> vec3<f32> {
    if (!ROBUST) {
        return p + NAIVE_OFFSET * n;
    }
    let of_i = vec3<i32>(OFFSET_INT_SCALE * n);
    let p_i = bitcast<vec3<f32>>(bitcast<vec3<i32>>(p) + select(of_i, -of_i, p < vec3(0.0)));
    return select(p_i, p + OFFSET_FLOAT_SCALE * scale * n, abs(p) < OFFSET_ORIGIN * scale);
}

fn safe_normalize(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let len2 = dot(v, v);
    if (len2 > 0.0) {
        return v * inverseSqrt(len2);
    }
    return fallback;
}

// C's pow for the specular base x >= 0: pow(x, 0) = 1 (also for x = 0), and
// 0^y = 0 for y > 0; WGSL leaves pow(0, y) undefined.
fn pow_c(x: f32, y: f32) -> f32 {
    if (y == 0.0) {
        return 1.0;
    }
    if (x <= 0.0) {
        return 0.0;
    }
    return pow(x, y);
}

struct SurfacePoint {
    p: vec3<f32>,
    // Shading normal (interpolated for triangles).
    n: vec3<f32>,
    // Geometric normal, for offsetting secondary rays.
    ng: vec3<f32>,
    // Per-axis magnitude of the primitive's coordinates (see offset_ray).
    scale: vec3<f32>,
    kd: vec3<f32>,
    ks: vec3<f32>,
    shininess: f32,
}

fn surface_point(ray: Ray, hit: Hit) -> SurfacePoint {
    let index = hit.prim & ~SPHERE_BIT;
    if ((hit.prim & SPHERE_BIT) != 0u) {
        if (SPHERES) {
            return sphere_surface(ray, hit, index);
        }
    }
    if (TRIANGLES) {
        return triangle_surface(ray, hit, index);
    }
    // Unreachable: no primitive of a kind the feature set leaves out exists.
    return SurfacePoint(vec3(0.0), vec3(0.0, 0.0, 1.0), vec3(0.0, 0.0, 1.0), vec3(1.0), vec3(0.0), vec3(0.0), 0.0);
}

fn sphere_surface(ray: Ray, hit: Hit, index: u32) -> SurfacePoint {
    let s = sphere_at(index, ray.time);
    let p = ray.origin + hit.t * ray.dir;
    let n = (p - s.center) * (1.0 / s.radius);
    return SurfacePoint(p, n, n, abs(s.center) + s.radius, s.kd, s.ks, s.shininess);
}

fn triangle_surface(ray: Ray, hit: Hit, index: u32) -> SurfacePoint {
    let tri = triangle_at(index, ray.time);
    let b0 = 1.0 - hit.b1 - hit.b2;
    let w = vec3(b0, hit.b1, hit.b2);
    // The point from barycentrics, not origin + t * dir: its error does not
    // grow with the distance travelled (Ray Tracing Gems ch. 6).
    var p = w.x * tri.v[0].xyz + w.y * tri.v[1].xyz + w.z * tri.v[2].xyz;
    if (!ROBUST) {
        p = ray.origin + hit.t * ray.dir;
    }
    let ng = safe_normalize(cross(tri.v[1].xyz - tri.v[0].xyz, tri.v[2].xyz - tri.v[0].xyz), vec3(0.0, 0.0, 1.0));
    let nn = load_normals(index).n;
    let n0 = vec3(nn[0], nn[1], nn[2]);
    let n1 = vec3(nn[3], nn[4], nn[5]);
    let n2 = vec3(nn[6], nn[7], nn[8]);
    let s0 = load_material(bitcast<u32>(tri.v[0].w));
    let s1 = load_material(bitcast<u32>(tri.v[1].w));
    let s2 = load_material(bitcast<u32>(tri.v[2].w));
    let n = safe_normalize(w.x * n0 + w.y * n1 + w.z * n2, ng);
    let kd = w.x * s0.kd + w.y * s1.kd + w.z * s2.kd;
    let ks = w.x * s0.ks + w.y * s1.ks + w.z * s2.ks;
    let shininess = w.x * s0.shininess + w.y * s1.shininess + w.z * s2.shininess;
    // Pharr et al.'s bound on the rounding of p: sum |b_i v_i|, per axis.
    let scale = abs(w.x * tri.v[0].xyz) + abs(w.y * tri.v[1].xyz) + abs(w.z * tri.v[2].xyz);
    return SurfacePoint(p, n, ng, scale, kd, ks, shininess);
}

// One light's part in the Phong sum at a surface point.
struct LightTerm {
    // Where the shadow ray starts.
    origin: vec3<f32>,
    // The first blocker found; prim NO_HIT when the light is visible.
    blocker: Hit,
    // The Phong factors, left zero when the light is blocked.
    ln: f32,
    rv: f32,
    spec: f32,
    contribution: vec3<f32>,
}

// light * (kd * max(L.N, 0) + ks * max(R.V, 0)^shininess) if nothing lies
// between the point and the light at `light_pos`. The specular term is not
// gated by L.N.
// `skip`: the run of `skips` naming the surfaces through light_pos when it
// is a point light's position, else (0, 0).
fn point_term(sp: SurfacePoint, view: vec3<f32>, light_pos: vec3<f32>, color: vec3<f32>, time: f32, skip: vec2<u32>) -> LightTerm {
    let to_light = light_pos - sp.p;
    // Leave from the side of the surface that faces the light.
    let side = select(-sp.ng, sp.ng, dot(sp.ng, to_light) >= 0.0);
    let origin = offset_ray(sp.p, side, sp.scale);
    if (LIGHT_SKIPS) {
        skip_range = skip;
        graze_h = select(0.0, in_plane_graze(sp, origin, light_pos), skip.y > 0u);
    }
    var term = LightTerm(origin, occluder(make_ray(origin, light_pos - origin, time)), 0.0, 0.0, 0.0, vec3(0.0));
    if (term.blocker.prim != NO_HIT) {
        return term;
    }
    let l = safe_normalize(to_light, sp.n);
    term.ln = dot(l, sp.n);
    let r = 2.0 * term.ln * sp.n - l;
    term.rv = max(dot(r, view), 0.0);
    term.spec = pow_c(term.rv, sp.shininess);
    term.contribution = color * (sp.kd * max(term.ln, 0.0) + sp.ks * term.spec);
    return term;
}

// Where a shading sample is drawn for: which pixel, which of its samples,
// and the sample's time.
struct SampleKey {
    pixel: u32,
    sample: u32,
    time: f32,
}

// Two unit vectors completing w (unit) to an orthonormal basis (Duff et al.,
// "Building an Orthonormal Basis, Revisited", JCGT 6(1) 2017).
fn basis_u(w: vec3<f32>) -> vec3<f32> {
    let s = sign_nonzero(w.z);
    let a = -1.0 / (s + w.z);
    return vec3(1.0 + s * w.x * w.x * a, s * w.x * w.y * a, -s * w.x);
}

fn basis_v(w: vec3<f32>) -> vec3<f32> {
    let s = sign_nonzero(w.z);
    let a = -1.0 / (s + w.z);
    return vec3(w.x * w.y * a, s + w.y * w.y * a, -w.y);
}

// The point of area light `light` that sample uv in [0, 1)^2 picks, seen
// from p. A sphere light is sampled over the disc it shows p (its outline
// from p, for lights small against their distance), uniformly by area.
fn light_sample_point(light: Light, p: vec3<f32>, uv: vec2<f32>) -> vec3<f32> {
    if (light.kind == LIGHT_RECT) {
        return light.position + (uv.x - 0.5) * light.edge_u + (uv.y - 0.5) * light.edge_v;
    }
    let w = safe_normalize(light.position - p, vec3(0.0, 0.0, 1.0));
    let r = light.radius * sqrt(uv.x);
    let phi = 2.0 * PI * uv.y;
    return light.position + r * cos(phi) * basis_u(w) + r * sin(phi) * basis_v(w);
}

// An area light as frame.shadow_samples point lights of colour / count on
// a stratified pattern over its area. The blocker reported is the first one
// found when every sample is blocked (the point is in the umbra).
fn area_term(sp: SurfacePoint, view: vec3<f32>, light: Light, stream: u32, key: SampleKey) -> LightTerm {
    let n = max(frame.shadow_samples, 1u);
    let rotation = rng(key.pixel, key.sample, stream, ROTATION);
    let color = light.color * (1.0 / f32(n));
    var total = LightTerm(vec3(0.0), Hit(0.0, NO_HIT, 0.0, 0.0), 0.0, 0.0, 0.0, vec3(0.0));
    var blocked = 0u;
    var m = 0u;
    for (; m < n; m++) {
        work += 1u;
        let jitter = vec2(unit_float(rng(key.pixel, key.sample, stream, 2u * m)),
                          unit_float(rng(key.pixel, key.sample, stream, 2u * m + 1u)));
        let uv = stratified_2d(m, n, rotation, jitter);
        let term = point_term(sp, view, light_sample_point(light, sp.p, uv), color, key.time, vec2(0u));
        total.contribution += term.contribution;
        total.origin = term.origin;
        if (term.blocker.prim != NO_HIT) {
            if (blocked == 0u) {
                total.blocker = term.blocker;
            }
            blocked += 1u;
        } else {
            total.ln = term.ln;
            total.rv = term.rv;
            total.spec = term.spec;
        }
    }
    if (m < n) {
        cut = true;
    }
    if (blocked < n) {
        total.blocker = Hit(0.0, NO_HIT, 0.0, 0.0);
    }
    return total;
}

// Light `i`'s part in the Phong sum at sp, seen along `view`, on bounce
// `bounce` of sample `key`.
fn light_term(sp: SurfacePoint, view: vec3<f32>, i: u32, bounce: u32, key: SampleKey) -> LightTerm {
    let light = light_at(i, key.time);
    if (AREA_LIGHTS) {
        if (light.kind != LIGHT_POINT) {
            let stream = STREAM_LIGHT + (bounce << 24u) + i;
            return area_term(sp, view, light, stream, key);
        }
    }
    return point_term(sp, view, light.position, light.color, key.time, vec2(light.skip_first, light.skip_count));
}

struct Shading {
    // Ambient once plus every visible light's term, not yet clamped.
    color: vec3<f32>,
    // Bit i: light i is blocked (lights from 31 on share bit 31).
    shadow_mask: u32,
}

fn shade_phong(sp: SurfacePoint, view: vec3<f32>, bounce: u32, key: SampleKey) -> Shading {
    var out = Shading(frame.ambient.xyz, 0u);
    var i = 0u;
    for (; i < frame.light_count; i++) {
        work += 1u;
        let term = light_term(sp, view, i, bounce, key);
        out.color += term.contribution;
        if (term.blocker.prim != NO_HIT) {
            out.shadow_mask |= 1u << min(i, 31u);
        }
    }
    if (i < frame.light_count) {
        cut = true;
    }
    return out;
}

struct PixelResult {
    hit: Hit,
    color: vec3<f32>,
    shadow_mask: u32,
    flags: u32,
}

fn nonfinite(v: vec3<f32>) -> bool {
    // Exponent bits all set: inf or NaN. A bit test, because fast-math
    // compilers may fold x != x away.
    let e = bitcast<vec3<u32>>(v) & vec3(0x7f800000u);
    return any(e == vec3(0x7f800000u));
}

fn trace_primary(ray: Ray, key: SampleKey) -> PixelResult {
    let hit = trace_closest(ray);
    if (hit.prim == NO_HIT) {
        return PixelResult(hit, frame.background.xyz, 0u, 0u);
    }
    let sp = surface_point(ray, hit);
    let shading = shade_phong(sp, -ray.dir, 0u, key);
    var flags = select(0u, FLAG_NONFINITE_COLOR, nonfinite(shading.color));
    flags |= select(0u, FLAG_NONFINITE_SURFACE, nonfinite(sp.p) || nonfinite(sp.n));
    return PixelResult(hit, shading.color, shading.shadow_mask, flags);
}

// The camera ray of sample `s` of `n` of pixel (x, y): a stratified
// position in the pixel (centre when n = 1) and a uniform time in the
// shutter interval (the CPU's sample_color).
fn sample_ray(x: u32, y: u32, s: u32, n: u32) -> Ray {
    let pixel = y * frame.size.x + x;
    var offset = vec2(0.5);
    var time = 0.0;
    if (MULTISAMPLE) {
        if (n > 1u) {
            let rotation = rng(pixel, ROTATION, STREAM_PIXEL, ROTATION);
            let jitter = vec2(unit_float(rng(pixel, s, STREAM_PIXEL, 0u)), unit_float(rng(pixel, s, STREAM_PIXEL, 1u)));
            offset = stratified_2d(s, n, rotation, jitter);
        }
    }
    if (MOTION_BLUR) {
        // Uniform, not stratified: strata indexed by s as the pixel's are
        // would tie each sample's time to its place in the pixel (time ~ the
        // row), and the estimate would converge to a per-pixel sheared slice
        // of the (x, y, t) integral, not the integral (measured: the error
        // stopped falling at ~0.012 RMS from 256 samples on).
        time = frame.shutter * unit_float(rng(pixel, s, STREAM_TIME, 0u));
    }
    return camera_ray(x, y, offset, time);
}

fn samples_per_pixel() -> u32 {
    if (MULTISAMPLE) {
        return max(frame.spp, 1u);
    }
    return 1u;
}

fn fresh_state() -> PixelState {
    return PixelState(vec3(0.0), 0u, vec3(0.0), 0u, vec3(1.0), 0u, vec3(0.0), 0u, vec3(0.0), NO_HIT,
                      vec3(0.0), 0.0, vec3(0.0), 0.0, 0.0, 0.0, PHASE_START, 0u);
}

// One term of shade_phong at sp: light `light`, or one sample of it when it
// is an area light (area_term's loop body), summed as they sum.
fn shade_step(st: ptr<function, PixelState>, sp: SurfacePoint, view: vec3<f32>, key: SampleKey) {
    let i = (*st).light;
    let light = light_at(i, key.time);
    if (AREA_LIGHTS) {
        if (light.kind != LIGHT_POINT) {
            let stream = STREAM_LIGHT + ((*st).bounce << 24u) + i;
            let n = max(frame.shadow_samples, 1u);
            let m = (*st).area_sample;
            let rotation = rng(key.pixel, key.sample, stream, ROTATION);
            let color = light.color * (1.0 / f32(n));
            let jitter = vec2(unit_float(rng(key.pixel, key.sample, stream, 2u * m)),
                              unit_float(rng(key.pixel, key.sample, stream, 2u * m + 1u)));
            let uv = stratified_2d(m, n, rotation, jitter);
            let term = point_term(sp, view, light_sample_point(light, sp.p, uv), color, key.time, vec2(0u));
            (*st).area += term.contribution;
            (*st).area_sample = m + 1u;
            if (m + 1u >= n) {
                (*st).shade += (*st).area;
                (*st).area = vec3(0.0);
                (*st).area_sample = 0u;
                (*st).light = i + 1u;
            }
            return;
        }
    }
    let term = point_term(sp, view, light.position, light.color, key.time, vec2(light.skip_first, light.skip_count));
    (*st).shade += term.contribution;
    (*st).light = i + 1u;
}

// The sample's ray leaves sp, whose clamped colour is `local`, in the mirror
// direction: reflect_path's loop body.
fn reflect_off(st: ptr<function, PixelState>, sp: SurfacePoint, local: vec3<f32>) {
    (*st).color += (*st).weight * (vec3(1.0) - sp.ks) * local;
    (*st).weight *= sp.ks;
    // Mirror direction about the shading normal; leave from the side of the
    // surface it goes to, offset as shadow rays are.
    let d = (*st).dir;
    let dir = safe_normalize(d - 2.0 * dot(d, sp.n) * sp.n, sp.n);
    let side = select(-sp.ng, sp.ng, dot(sp.ng, dir) >= 0.0);
    (*st).origin = offset_ray(sp.p, side, sp.scale);
    (*st).dir = dir;
    (*st).bounce += 1u;
    (*st).phase = PHASE_TRACE;
}

// The pixel of the tile that invocation `lane` of workgroup `group`
// renders: each run of eight invocations (llvmpipe's eight SIMD lanes)
// takes a 4x2 block of pixels rather than a row of eight, so that the rays
// a SIMD instruction traces together lie closer. A warp of 32 still covers
// 8x4 pixels. Written for WORKGROUP_SIZE 8 (eight runs of eight cover the
// 8x8 workgroup; src/layout.rs asserts the size).
fn block_pixel(group: vec3<u32>, lane: u32) -> vec2<u32> {
    let run = lane >> 3u;
    let i = lane & 7u;
    return vec2(
        group.x * WORKGROUP_SIZE + (run & 1u) * 4u + (i & 3u),
        group.y * WORKGROUP_SIZE + (run >> 1u) * 2u + (i >> 2u),
    );
}

// The pixel's work from where the last pass left it, until it is done or
// this pass's budget is spent. Box filter over the pixel's samples; each
// sample is radiance() along its camera ray. The loops nest as the CPU's
// functions do (samples, bounces, lights), so the lanes of a SIMD device
// step through the same code together; each loop starts where the saved
// state says. Every statement costs on SIMD CPUs such as llvmpipe even where
// no lane takes it, so the hot loops hold no save or resume code: a spent
// budget only breaks out, and the state is saved once at the end.
@compute @workgroup_size(WORKGROUP_SIZE, WORKGROUP_SIZE)
fn render_tile(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let id = block_pixel(group, lane);
    if (id.x >= tile.size.x || id.y >= tile.size.y) {
        return;
    }
    let x = tile.origin.x + id.x;
    let y = tile.origin.y + id.y;
    let slot = id.y * tile.size.x + id.x;
    let n = samples_per_pixel();
    var st = fresh_state();
    if (!ONE_PASS) {
        if (tile.first == 0u) {
            st = state[slot];
            if (st.sample >= n) {
                return;
            }
        }
    }
    let pixel = y * frame.size.x + x;
    work = 0u;
    cut = false;
    var paused = false;
    var closest_rays = 0u;
    var shadow_rays = 0u;
    loop {
        if (st.sample >= n || paused || cut) {
            break;
        }
        if (st.phase == PHASE_START) {
            let primary = sample_ray(x, y, st.sample, n);
            st.origin = primary.origin;
            st.dir = primary.dir;
            st.time = primary.time;
            st.color = vec3(0.0);
            st.weight = vec3(1.0);
            st.bounce = 0u;
            st.phase = PHASE_TRACE;
        }
        // The sample's bounces: trace, then shade every light at the hit.
        loop {
            let ray = make_ray(st.origin, st.dir, st.time);
            if (st.phase == PHASE_TRACE) {
                if (work >= tile.budget) {
                    paused = true;
                    break;
                }
                work += 1u;
                closest_rays += 1u;
                let hit = trace_closest(ray);
                st.prim = hit.prim;
                st.t = hit.t;
                st.b1 = hit.b1;
                st.b2 = hit.b2;
                st.shade = frame.ambient.xyz;
                st.light = 0u;
                st.area = vec3(0.0);
                st.area_sample = 0u;
                st.phase = PHASE_SHADE;
            }
            if (cut) {
                break;
            }
            // trace_primary's background is clamped as every local colour
            // is; a reflected ray's is not (reflect_path).
            var local = frame.background.xyz;
            if (st.bounce == 0u) {
                local = clamp(local, vec3(0.0), vec3(1.0));
            }
            if (st.prim != NO_HIT) {
                let sp = surface_point(ray, Hit(st.t, st.prim, st.b1, st.b2));
                let key = SampleKey(pixel, st.sample, st.time);
                loop {
                    if (st.light >= frame.light_count || work >= tile.budget || cut) {
                        break;
                    }
                    work += 1u;
                    shadow_rays += 1u;
                    shade_step(&st, sp, -ray.dir, key);
                }
                if (st.light < frame.light_count) {
                    if (work >= tile.budget && !cut) {
                        paused = true;
                    } else {
                        cut = true;
                    }
                    break;
                }
                local = clamp(st.shade, vec3(0.0), vec3(1.0));
                if (REFLECTION) {
                    if (st.bounce < frame.reflect_depth && !all(sp.ks == vec3(0.0))) {
                        reflect_off(&st, sp, local);
                        continue;
                    }
                }
            }
            // The sample ends with `local` as its last surface's colour (or
            // the background): reflect_path's return, added to the sum.
            st.sum += st.color + st.weight * local;
            st.sample += 1u;
            st.phase = PHASE_START;
            break;
        }
    }
    if (st.sample < n && !paused) {
        cut = true;
    }
    // One atomic per invocation and pass; a cut pass is redone from its
    // tile's start, and the host drops its counts with it.
    if (closest_rays > 0u) {
        atomicAdd(&status.closest_rays, closest_rays);
    }
    if (shadow_rays > 0u) {
        atomicAdd(&status.shadow_rays, shadow_rays);
    }
    if (cut) {
        atomicAdd(&status.cut, 1u);
        atomicMin(&status.first_cut, pixel);
        return;
    }
    if (paused) {
        if (!ONE_PASS) {
            state[slot] = st;
        }
        atomicAdd(&status.remaining, 1u);
        return;
    }
    // Later passes of this tile skip the pixel; without this they would
    // read whatever an earlier tile left in its state slot.
    if (!ONE_PASS) {
        state[slot].sample = st.sample;
    }
    var color = st.sum;
    if (MULTISAMPLE) {
        color = st.sum * (1.0 / f32(n));
    }
    output[slot] = vec4(clamp(color, vec3(0.0), vec3(1.0)), 1.0);
}

// Probes run in one invocation per pixel; a cut one is reported like
// render_tile's.
fn report_cut(x: u32, y: u32) {
    if (cut) {
        atomicAdd(&status.cut, 1u);
        atomicMin(&status.first_cut, y * frame.size.x + x);
    }
}

fn centre_key(x: u32, y: u32) -> SampleKey {
    return SampleKey(y * frame.size.x + x, 0u, 0.0);
}

// Per pixel: (primitive, shadow mask, flags, t), integers bit-cast to f32.
// Probes trace the pixel centre at the frame's time, sample 0.
@compute @workgroup_size(WORKGROUP_SIZE, WORKGROUP_SIZE)
fn probe_tile(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= tile.size.x || id.y >= tile.size.y) {
        return;
    }
    let x = tile.origin.x + id.x;
    let y = tile.origin.y + id.y;
    work = 0u;
    cut = false;
    let r = trace_primary(pixel_ray(x, y), centre_key(x, y));
    output[id.y * tile.size.x + id.x] =
        vec4(bitcast<f32>(r.hit.prim), bitcast<f32>(r.shadow_mask), bitcast<f32>(r.flags), r.hit.t);
    report_cut(x, y);
}

// The path of pixel tile.origin, as many lights as the output holds. One
// invocation of a full-size workgroup does the work: lavapipe (Mesa 22.3)
// returns wrong shadow verdicts from a workgroup of size 1.
@compute @workgroup_size(WORKGROUP_SIZE, WORKGROUP_SIZE)
fn probe_pixel(@builtin(local_invocation_index) lane: u32) {
    if (lane != 0u) {
        return;
    }
    let key = centre_key(tile.origin.x, tile.origin.y);
    let ray = pixel_ray(tile.origin.x, tile.origin.y);
    work = 0u;
    cut = false;
    let r = trace_primary(ray, key);
    output[0] = vec4(bitcast<f32>(r.hit.prim), r.hit.t, r.hit.b1, r.hit.b2);
    output[1] = vec4(ray.dir, bitcast<f32>(r.flags));
    output[2] = vec4(r.color, bitcast<f32>(r.shadow_mask));
    if (r.hit.prim == NO_HIT) {
        report_cut(tile.origin.x, tile.origin.y);
        return;
    }
    let room = (arrayLength(&output) - PATH_HEADER) / PATH_PER_LIGHT;
    let shown = min(frame.light_count, room);
    let sp = surface_point(ray, r.hit);
    output[3] = vec4(sp.p, sp.shininess);
    output[4] = vec4(sp.n, bitcast<f32>(shown));
    output[5] = vec4(sp.ng, 0.0);
    output[6] = vec4(sp.kd, 0.0);
    output[7] = vec4(sp.ks, 0.0);
    var i = 0u;
    for (; i < shown; i++) {
        let term = light_term(sp, -ray.dir, i, 0u, key);
        let base = PATH_HEADER + PATH_PER_LIGHT * i;
        output[base] = vec4(term.origin, bitcast<f32>(term.blocker.prim));
        output[base + 1u] = vec4(term.ln, term.rv, term.spec, term.blocker.t);
        output[base + 2u] = vec4(term.contribution, 0.0);
    }
    if (i < shown) {
        cut = true;
    }
    report_cut(tile.origin.x, tile.origin.y);
}
