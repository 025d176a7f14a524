// A tile's finished texels as the 8-bit pixels of a PNG, JPEG or PPM
// (src/gpu/render/passes.rs runs it after each pass): R, G, B of each
// pixel in turn, tightly packed, four bytes a word, so the host reads 3
// bytes a pixel instead of a texel's 16 and copies each row as it is.
// Each channel is the host's `framebuffer::to_u8`, with the same
// operations in f32: clamp, scale, and the whole part plus one where the
// fraction is at least a half (the fraction is exact; `floor(y + 0.5)`
// would round 0.5 - 2^-25 up). The SPIR-V is NoContraction, as the trace
// shader's. The trace shader clamps its colours, so no NaN reaches here.

@group(0) @binding(0) var<storage, read> texels: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> packed: array<u32>;

fn level(v: f32) -> u32 {
    let y = min(max(v, 0.0), 1.0) * 255.0;
    let t = floor(y);
    return u32(t) + select(0u, 1u, y - t >= 0.5);
}

// One word: bytes 4k to 4k + 3 of the RGB stream.
@compute @workgroup_size(256)
fn pack(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = id.x;
    let n = arrayLength(&texels);
    if k >= arrayLength(&packed) || k >= (3u * n + 3u) / 4u {
        return;
    }
    var word = 0u;
    for (var j = 0u; j < 4u; j = j + 1u) {
        let b = 4u * k + j;
        let t = b / 3u;
        if t < n {
            word = word | (level(texels[t][b % 3u]) << (8u * j));
        }
    }
    packed[k] = word;
}
