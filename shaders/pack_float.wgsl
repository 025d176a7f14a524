// A tile's finished texels as the f32 RGB of an EXR (or of any float
// render: a crop, a part, a progressive pass): the alpha word of each
// vec4 dropped, so the host reads 12 bytes a pixel instead of 16
// (src/gpu/render/passes.rs runs it after each pass). The texels are read
// as bits, not floats, so every value (a NaN's payload too) crosses
// unchanged.

@group(0) @binding(0) var<storage, read> texels: array<vec4<u32>>;
@group(0) @binding(1) var<storage, read_write> packed: array<u32>;

@compute @workgroup_size(256)
fn pack_float(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= arrayLength(&texels) || i >= arrayLength(&packed) / 3u {
        return;
    }
    let p = texels[i];
    packed[3u * i] = p.x;
    packed[3u * i + 1u] = p.y;
    packed[3u * i + 2u] = p.z;
}
