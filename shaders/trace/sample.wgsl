// shaders/trace/sample.wgsl: rays, the camera's rays, random numbers and
// sample patterns. CPU twin: src/cpu/trace/hit.rs (rays), src/cpu/sample.rs.

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

// The `sobol` sampler: Owen-scrambled Sobol points (Burley, "Practical
// Hash-based Owen Scrambling", JCGT 9(4) 2020). A 2D dimension of a pixel
// (its position, an area light's point at one bounce) takes Sobol's first
// two coordinates, a (0,2)-sequence, so every power-of-two run of a pixel's
// indices is stratified at every scale at once; each coordinate is
// Owen-scrambled with a seed of its own, per pixel and dimension (unbiased,
// and no two pixels share a pattern), and the index is Owen-scrambled too,
// so that two dimensions read from the same index are not correlated (the
// time/position trap of docs/effects.md). Scrambling an index below 2^k
// permutes its low k bits and sets the others to one constant, so the first
// 2^k samples are still one aligned run: progressive. A 1D dimension (the
// time) takes the first coordinate alone.

// Laine and Karras's hash: each output bit depends only on the input bits at
// and below it, which makes reverseBits(laine_karras(reverseBits(x))) a
// nested uniform (Owen) scramble. Burley's constants.
fn laine_karras(x: u32, seed: u32) -> u32 {
    var v = x + seed;
    v ^= v * 0x6c50b47cu;
    v ^= v * 0xb82f1e52u;
    v ^= v * 0xc7afe638u;
    v ^= v * 0x8d22f6e6u;
    return v;
}

fn owen_scramble(x: u32, seed: u32) -> u32 {
    return reverseBits(laine_karras(reverseBits(x), seed));
}

// Sobol's second coordinate of index i, bit-reversed: its direction numbers
// (from the primitive polynomial x + 1) make output bit j (from the top) the
// xor of the bits k of i with k a superset of j's bits (Pascal's triangle mod
// 2), a sum over supersets that five shifts compute. The first coordinate
// is reverseBits(i).
fn sobol_second_reversed(i: u32) -> u32 {
    var x = i;
    x ^= (x >> 1u) & 0x55555555u;
    x ^= (x >> 2u) & 0x33333333u;
    x ^= (x >> 4u) & 0x0f0f0f0fu;
    x ^= (x >> 8u) & 0x00ff00ffu;
    x ^= (x >> 16u) & 0x0000ffffu;
    return x;
}

// The randomisation of one dimension of one pixel: its index shuffle's seed;
// the coordinates' seeds are hashed from it.
fn sobol_key(pixel: u32, stream: u32) -> u32 {
    return rng(pixel, ROTATION, stream, SOBOL_KEY);
}

// Point i of a pixel's 2D dimension `key`, in [0, 1)^2: each coordinate
// owen_scramble(Sobol's coordinate of j), written without the two bit
// reversals that cancel.
fn sobol_2d(key: u32, i: u32) -> vec2<f32> {
    return sobol_2d_seeded(key, sobol_seeds(key), i);
}

// The seeds of a 2D dimension's two coordinates, from its key.
fn sobol_seeds(key: u32) -> vec2<u32> {
    return vec2(hash_u32(key ^ SOBOL_X), hash_u32(key ^ SOBOL_Y));
}

// sobol_2d with its coordinates' seeds drawn already (an area light's
// samples share them).
fn sobol_2d_seeded(key: u32, seeds: vec2<u32>, i: u32) -> vec2<f32> {
    let j = owen_scramble(i, key);
    let x = reverseBits(laine_karras(j, seeds.x));
    let y = reverseBits(laine_karras(sobol_second_reversed(j), seeds.y));
    return vec2(unit_float(x), unit_float(y));
}

// Point i of a pixel's 1D dimension `key`, in [0, 1).
fn sobol_1d(key: u32, i: u32) -> f32 {
    let j = owen_scramble(i, key);
    return unit_float(reverseBits(laine_karras(j, hash_u32(key ^ SOBOL_X))));
}

// What an area light's samples at one sample of a pixel share, drawn once
// for all of them (the CPU's AreaPattern).
struct AreaPattern {
    pixel: u32,
    sample: u32,
    stream: u32,
    // sobol: the dimension's key; stratified: the grid's rotation.
    base: u32,
    // sobol: the coordinates' seeds.
    seeds: vec2<u32>,
}

fn area_pattern(pixel: u32, sample: u32, stream: u32) -> AreaPattern {
    if (frame.sampling == SAMPLER_SOBOL) {
        let key = sobol_key(pixel, stream);
        return AreaPattern(pixel, sample, stream, key, sobol_seeds(key));
    }
    return AreaPattern(pixel, sample, stream, rng(pixel, sample, stream, ROTATION), vec2(0u));
}

// Sample m of the n an area light takes, in [0, 1)^2: points sample * n + m
// of its Sobol dimension, so that all of a pixel's samples together are
// stratified over the light, not only each sample's n; or cell m of the
// stratified grid.
fn area_uv(p: AreaPattern, m: u32, n: u32) -> vec2<f32> {
    if (frame.sampling == SAMPLER_SOBOL) {
        return sobol_2d_seeded(p.base, p.seeds, p.sample * n + m);
    }
    let jitter = vec2(unit_float(rng(p.pixel, p.sample, p.stream, 2u * m)),
                      unit_float(rng(p.pixel, p.sample, p.stream, 2u * m + 1u)));
    return stratified_2d(m, n, p.base, jitter);
}
