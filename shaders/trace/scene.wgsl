// shaders/trace/scene.wgsl: reading the scene's lists (split, uniform or
// through device addresses) and moving primitives and lights to a time.
// CPU twin: src/cpu/trace/scene.rs.

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

