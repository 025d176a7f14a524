// The window's image on the device (src/gpu/present.rs): adds a progressive
// pass (the trace shader's tiles, copied into `pass_image`; w is 1 where the
// pass rendered the pixel, 0 where an adaptive pass left it out) to the
// running sums, clears the pass for the next, and packs the mean as the
// 8-bit pixels `glint render` writes: value * 255 rounded half away from
// zero, no gamma. The swapchain image is a UNORM format, so these bytes are
// what the window shows.

struct Resolve {
    size: vec2<u32>,
    reset: u32,
    bgra: u32,
}

@group(0) @binding(0) var<storage, read_write> pass_image: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> sums: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> shown: array<u32>;
@group(0) @binding(3) var<storage, read> params: Resolve;

// The host's `(v.clamp(0, 1) * 255).round()`; WGSL's round() would go to
// even at .5.
fn level(v: f32) -> u32 {
    return u32(floor(clamp(v, 0.0, 1.0) * 255.0 + 0.5));
}

@compute @workgroup_size(8, 8)
fn resolve(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.size.x || id.y >= params.size.y {
        return;
    }
    let i = id.y * params.size.x + id.x;
    var sum = sums[i];
    if params.reset != 0u {
        sum = vec4(0.0);
    }
    let p = pass_image[i];
    if p.w != 0.0 {
        sum += vec4(p.xyz, 1.0);
    }
    sums[i] = sum;
    pass_image[i] = vec4(0.0);
    let m = sum.xyz / max(sum.w, 1.0);
    let r = level(m.x);
    let g = level(m.y);
    let b = level(m.z);
    if params.bgra != 0u {
        shown[i] = b | (g << 8u) | (r << 16u) | (255u << 24u);
    } else {
        shown[i] = r | (g << 8u) | (b << 16u) | (255u << 24u);
    }
}
