// A tile's finished texels as the 8-bit pixels of a PNG, JPEG or PPM
// (src/gpu/render/passes.rs runs it after each pass, so the host reads 4
// bytes a pixel instead of 16): R, G, B and 255, each channel the host's
// `framebuffer::to_u8`, with the same operations in f32: clamp, scale,
// and the whole part plus one where the fraction is at least a half (the
// fraction is exact; `floor(y + 0.5)` would round 0.5 - 2^-25 up). The
// SPIR-V is NoContraction, as the trace shader's. The trace shader clamps
// its colours, so no NaN reaches here.

@group(0) @binding(0) var<storage, read> texels: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> packed: array<u32>;

fn level(v: f32) -> u32 {
    let y = min(max(v, 0.0), 1.0) * 255.0;
    let t = floor(y);
    return u32(t) + select(0u, 1u, y - t >= 0.5);
}

@compute @workgroup_size(256)
fn pack(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= arrayLength(&packed) || i >= arrayLength(&texels) {
        return;
    }
    let p = texels[i];
    packed[i] = level(p.x) | (level(p.y) << 8u) | (level(p.z) << 16u) | (255u << 24u);
}
