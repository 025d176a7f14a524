// shaders/trace/kernel.wgsl: a pixel's samples and bounces as resumable
// steps, and the entry points render_tile, probe_tile and probe_pixel.
// CPU twin: src/cpu/trace/shade.rs (pixel_color) and src/cpu/mod.rs.

// The camera ray of sample `s` of `n` of pixel (x, y): a position in the
// pixel (centre when n = 1) and a time in the shutter interval, each from
// the frame's sampler (the CPU's sample_color).
fn sample_ray(x: u32, y: u32, s: u32, n: u32) -> Ray {
    if (frame.sampling == SAMPLER_SOBOL) {
        return sobol_sample_ray(x, y, s, n);
    }
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

// sample_ray for the sobol sampler: the position and the time are two
// dimensions of their own, their indices scrambled apart, so the trap
// above does not arise.
fn sobol_sample_ray(x: u32, y: u32, s: u32, n: u32) -> Ray {
    let pixel = y * frame.size.x + x;
    var offset = vec2(0.5);
    var time = 0.0;
    if (MULTISAMPLE) {
        if (n > 1u) {
            offset = sobol_2d(sobol_key(pixel, STREAM_PIXEL), s);
        }
    }
    if (MOTION_BLUR) {
        time = frame.shutter * sobol_1d(sobol_key(pixel, STREAM_TIME), s);
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
            let color = light.color * (1.0 / f32(n));
            let uv = area_uv(area_pattern(key.pixel, key.sample, stream), m, n);
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
// 8x8 workgroup; src/layout/types.rs asserts the size).
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
