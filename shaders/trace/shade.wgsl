// shaders/trace/shade.wgsl: surface points and offsets, each light's term
// with its shadow rays (point and area lights), Phong. CPU twin:
// src/cpu/trace/shade.rs.

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
// from p, for lights small against their distance), uniformly by area:
// stratified maps uv onto it in polar coordinates (r = sqrt(u), angle
// 2 pi v), sobol with Shirley and Chiu's concentric map, which keeps a
// stratum compact (a square's strata become pieces of rings, not the polar
// map's long thin wedges), so the points' stratification reaches the disc.
fn light_sample_point(light: Light, p: vec3<f32>, uv: vec2<f32>) -> vec3<f32> {
    if (light.kind == LIGHT_RECT) {
        return light.position + (uv.x - 0.5) * light.edge_u + (uv.y - 0.5) * light.edge_v;
    }
    let w = safe_normalize(light.position - p, vec3(0.0, 0.0, 1.0));
    if (frame.sampling == SAMPLER_SOBOL) {
        let d = light.radius * concentric_disc(uv);
        return light.position + d.x * basis_u(w) + d.y * basis_v(w);
    }
    let r = light.radius * sqrt(uv.x);
    let phi = 2.0 * PI * uv.y;
    return light.position + r * cos(phi) * basis_u(w) + r * sin(phi) * basis_v(w);
}

// uv in [0, 1)^2 onto the unit disc, uniformly by area (Shirley and Chiu,
// "A Low Distortion Map Between Disk and Square", 1997).
fn concentric_disc(uv: vec2<f32>) -> vec2<f32> {
    let a = 2.0 * uv - vec2(1.0);
    if (a.x == 0.0 && a.y == 0.0) {
        return vec2(0.0);
    }
    if (abs(a.x) > abs(a.y)) {
        let phi = 0.25 * PI * (a.y / a.x);
        return a.x * vec2(cos(phi), sin(phi));
    }
    let phi = 0.5 * PI - 0.25 * PI * (a.x / a.y);
    return a.y * vec2(cos(phi), sin(phi));
}

// An area light as frame.shadow_samples point lights of colour / count on
// a stratified pattern over its area. The blocker reported is the first one
// found when every sample is blocked (the point is in the umbra).
fn area_term(sp: SurfacePoint, view: vec3<f32>, light: Light, stream: u32, key: SampleKey) -> LightTerm {
    let n = max(frame.shadow_samples, 1u);
    let pattern = area_pattern(key.pixel, key.sample, stream);
    let color = light.color * (1.0 / f32(n));
    var total = LightTerm(vec3(0.0), Hit(0.0, NO_HIT, 0.0, 0.0), 0.0, 0.0, 0.0, vec3(0.0));
    var blocked = 0u;
    var m = 0u;
    for (; m < n; m++) {
        work += 1u;
        let uv = area_uv(pattern, m, n);
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

