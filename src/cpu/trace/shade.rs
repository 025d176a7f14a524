//! What a hit looks like: the surface point and its offsets, each light's
//! term with its shadow rays (point and area lights), reflection, and a
//! pixel's samples.

use crate::cpu::real::Real;
use crate::cpu::sample::{
    rng, sobol_1d, sobol_2d, sobol_key, stratified_2d, unit_float, AreaPattern, ROTATION,
    STREAM_LIGHT, STREAM_PIXEL, STREAM_TIME,
};
use crate::layout::{
    FLAG_NONFINITE_COLOR, FLAG_NONFINITE_SURFACE, LIGHT_POINT, LIGHT_RECT, SPHERE_BIT,
};
use crate::methods::Methods;
use crate::scene::Sampler;

use super::hit::*;
use super::scene::*;
use super::traverse::*;
use crate::cpu::real::Ray;

/// What shading needs of `hit`, a hit of `ray`: the point, its normals and
/// material (a triangle's interpolated barycentrically).
pub fn surface_point<R: Real>(scene: &CpuScene<R>, ray: &Ray<R>, hit: &Hit<R>) -> SurfacePoint<R> {
    let index = (hit.prim & !SPHERE_BIT) as usize;
    if hit.prim & SPHERE_BIT != 0 {
        let s = &sphere_at(scene, index, ray.time);
        let p = ray.origin + ray.dir * hit.t;
        let n = (p - s.center) * (R::ONE / s.radius);
        return SurfacePoint {
            p,
            n,
            ng: n,
            scale: R::vabs(s.center) + R::v3(s.radius, s.radius, s.radius),
            kd: s.kd,
            ks: s.ks,
            shininess: s.shininess,
        };
    }
    let tri = &triangle_at(scene, index, ray.time);
    let b0 = R::ONE - hit.b1 - hit.b2;
    let w = [b0, hit.b1, hit.b2];
    let p = match scene.methods {
        Methods::Robust => tri[0] * w[0] + tri[1] * w[1] + tri[2] * w[2],
        Methods::Naive => ray.origin + ray.dir * hit.t,
    };
    let up = R::v3(R::ZERO, R::ZERO, R::ONE);
    let ng = safe_normalize::<R>(R::cross(tri[1] - tri[0], tri[2] - tri[0]), up);
    let s = &scene.shading[index];
    let n = safe_normalize::<R>(
        s[0].normal * w[0] + s[1].normal * w[1] + s[2].normal * w[2],
        ng,
    );
    let m = s.map(|c| &scene.materials[c.material as usize]);
    SurfacePoint {
        p,
        n,
        ng,
        scale: R::vabs(tri[0] * w[0]) + R::vabs(tri[1] * w[1]) + R::vabs(tri[2] * w[2]),
        kd: m[0].kd * w[0] + m[1].kd * w[1] + m[2].kd * w[2],
        ks: m[0].ks * w[0] + m[1].ks * w[1] + m[2].ks * w[2],
        shininess: w[0] * m[0].shininess + w[1] * m[1].shininess + w[2] * m[2].shininess,
    }
}

/// One light's share at a shaded point, and what `glint render --path` shows
/// of it.
#[derive(Clone, Copy, Debug)]
pub struct LightTerm<R: Real> {
    /// Where the shadow ray started.
    pub origin: R::V3,
    /// What blocked it (`prim == NO_HIT`: nothing).
    pub blocker: Hit<R>,
    /// L·N (unclamped; 0 when blocked).
    pub ln: R,
    /// max(R·V, 0) (0 when blocked).
    pub rv: R,
    /// `rv` to the power shininess (0 when blocked).
    pub spec: R,
    /// The light's colour times the Phong terms (zero when blocked).
    pub contribution: R::V3,
}

/// `skip`: the surfaces through `target` when it is a point light's
/// position (`lights_on_surfaces`), else empty.
#[allow(clippy::too_many_arguments)]
pub fn point_term<R: Real>(
    scene: &CpuScene<R>,
    sp: &SurfacePoint<R>,
    view: R::V3,
    target: R::V3,
    color: R::V3,
    time: R,
    skip: &[u32],
) -> LightTerm<R> {
    let (origin, ray, graze) = point_shadow_ray(scene, sp, target, time, skip);
    let blocker = occluder(scene, &ray, skip, graze);
    point_shading(sp, view, target, color, origin, blocker)
}

/// The shadow ray `point_term` casts from `sp` towards `target`: its
/// origin, the ray (t = 1 at the target) and its grazing band.
#[inline(always)]
pub fn point_shadow_ray<R: Real>(
    scene: &CpuScene<R>,
    sp: &SurfacePoint<R>,
    target: R::V3,
    time: R,
    skip: &[u32],
) -> (R::V3, Ray<R>, R) {
    let origin = shadow_origin(scene, sp, target);
    let graze = if skip.is_empty() {
        R::ZERO
    } else {
        in_plane_graze(sp, origin, target)
    };
    (origin, make_ray(origin, target - origin, time), graze)
}

/// Where the shadow ray from `sp` towards `target` starts: `sp` moved off
/// its surface to the side `target` is on.
#[inline(always)]
pub fn shadow_origin<R: Real>(scene: &CpuScene<R>, sp: &SurfacePoint<R>, target: R::V3) -> R::V3 {
    let to_light = target - sp.p;
    let side = if R::dot(sp.ng, to_light) >= R::ZERO {
        sp.ng
    } else {
        -sp.ng
    };
    offset_ray(scene, sp.p, side, sp.scale)
}

/// `point_term` once its shadow ray from `origin` found `blocker`.
#[inline(always)]
pub fn point_shading<R: Real>(
    sp: &SurfacePoint<R>,
    view: R::V3,
    target: R::V3,
    color: R::V3,
    origin: R::V3,
    blocker: Hit<R>,
) -> LightTerm<R> {
    let zero = R::v3(R::ZERO, R::ZERO, R::ZERO);
    let mut term = LightTerm {
        origin,
        blocker,
        ln: R::ZERO,
        rv: R::ZERO,
        spec: R::ZERO,
        contribution: zero,
    };
    if term.blocker.prim != NO_HIT {
        return term;
    }
    let to_light = target - sp.p;
    let l = safe_normalize::<R>(to_light, sp.n);
    term.ln = R::dot(l, sp.n);
    let r = sp.n * (R::TWO * term.ln) - l;
    term.rv = R::dot(r, view).max(R::ZERO);
    term.spec = pow_c(term.rv, sp.shininess);
    term.contribution = color * (sp.kd * term.ln.max(R::ZERO) + sp.ks * term.spec);
    term
}

/// Which sample of which pixel is being shaded: the random streams' key.
#[derive(Clone, Copy, Debug)]
pub struct SampleKey<R: Real> {
    /// `y * width + x`.
    pub pixel: u32,
    /// The sample's index within the pixel.
    pub sample: u32,
    /// The sample's time within the shutter (motion blur).
    pub time: R,
}

fn basis_u<R: Real>(w: R::V3) -> R::V3 {
    let s = w[2].sign_nonzero();
    let a = -R::ONE / (s + w[2]);
    R::v3(R::ONE + s * w[0] * w[0] * a, s * w[0] * w[1] * a, -s * w[0])
}

fn basis_v<R: Real>(w: R::V3) -> R::V3 {
    let s = w[2].sign_nonzero();
    let a = -R::ONE / (s + w[2]);
    R::v3(w[0] * w[1] * a, s + w[1] * w[1] * a, -w[1])
}

/// The point of `light` that sample `uv` (in [0,1)²) picks as seen from `p`:
/// rectangle lights by area, sphere lights uniformly over the disc they show
/// facing `p` (polar for `Stratified`, concentric for `Sobol`; the shader's
/// `light_sample_point`).
pub fn light_sample_point<R: Real>(
    sampler: Sampler,
    light: &Light<R>,
    p: R::V3,
    uv: [R; 2],
) -> R::V3 {
    if light.kind == LIGHT_RECT {
        return light.position
            + light.edge_u * (uv[0] - R::HALF)
            + light.edge_v * (uv[1] - R::HALF);
    }
    let up = R::v3(R::ZERO, R::ZERO, R::ONE);
    let w = safe_normalize::<R>(light.position - p, up);
    if sampler == Sampler::Sobol {
        let [dx, dy] = concentric_disc(uv).map(|d| light.radius * d);
        return light.position + basis_u::<R>(w) * dx + basis_v::<R>(w) * dy;
    }
    let r = light.radius * uv[0].sqrt();
    let phi = R::TWO * R::PI * uv[1];
    light.position + basis_u::<R>(w) * (r * phi.cos()) + basis_v::<R>(w) * (r * phi.sin())
}

/// `uv` in [0,1)² onto the unit disc, uniformly by area (Shirley and Chiu's
/// concentric map; the shader's `concentric_disc`).
pub fn concentric_disc<R: Real>(uv: [R; 2]) -> [R; 2] {
    let a = uv.map(|u| R::TWO * u - R::ONE);
    if a[0] == R::ZERO && a[1] == R::ZERO {
        return [R::ZERO, R::ZERO];
    }
    let quarter = R::from_f64(0.25) * R::PI;
    let (r, phi) = if a[0].abs() > a[1].abs() {
        (a[0], quarter * (a[1] / a[0]))
    } else {
        (a[1], R::HALF * R::PI - quarter * (a[0] / a[1]))
    };
    [r * phi.cos(), r * phi.sin()]
}

/// The share of area `light` at `sp`: the mean of its shadow samples, each
/// a point term towards a point of the light (`stream` keys their draws).
pub fn area_term<R: Real>(
    scene: &CpuScene<R>,
    sp: &SurfacePoint<R>,
    view: R::V3,
    light: &Light<R>,
    stream: u32,
    key: &SampleKey<R>,
) -> LightTerm<R> {
    let n = scene.shadow_samples.max(1);
    let pattern = AreaPattern::new(scene.sampler, scene.seed, key.pixel, key.sample, stream);
    let color = light.color * (R::ONE / R::from_u32(n));
    let zero = R::v3(R::ZERO, R::ZERO, R::ZERO);
    let no_hit = Hit {
        t: R::ZERO,
        prim: NO_HIT,
        b1: R::ZERO,
        b2: R::ZERO,
    };
    let mut total = LightTerm {
        origin: zero,
        blocker: no_hit,
        ln: R::ZERO,
        rv: R::ZERO,
        spec: R::ZERO,
        contribution: zero,
    };
    let mut blocked = 0;
    for m in 0..n {
        let uv = pattern.uv(m, n);
        let target = light_sample_point(scene.sampler, light, sp.p, uv);
        let term = point_term(scene, sp, view, target, color, key.time, &[]);
        total.contribution = total.contribution + term.contribution;
        total.origin = term.origin;
        if term.blocker.prim != NO_HIT {
            if blocked == 0 {
                total.blocker = term.blocker;
            }
            blocked += 1;
        } else {
            total.ln = term.ln;
            total.rv = term.rv;
            total.spec = term.spec;
        }
    }
    if blocked < n {
        total.blocker = no_hit;
    }
    total
}

/// The share of light `i` at `sp`, seen along `view`, on reflection bounce
/// `bounce`.
pub fn light_term<R: Real>(
    scene: &CpuScene<R>,
    sp: &SurfacePoint<R>,
    view: R::V3,
    i: usize,
    bounce: u32,
    key: &SampleKey<R>,
) -> LightTerm<R> {
    let light = light_at(scene, i, key.time);
    if light.kind != LIGHT_POINT {
        let stream = STREAM_LIGHT
            .wrapping_add(bounce << 24)
            .wrapping_add(i as u32);
        return area_term(scene, sp, view, &light, stream, key);
    }
    let skip = scene
        .surfaces_at_lights
        .get(i)
        .map_or(&[][..], Vec::as_slice);
    point_term(scene, sp, view, light.position, light.color, key.time, skip)
}

/// Phong shading of a point: its colour and which lights it saw.
#[derive(Clone, Copy, Debug)]
pub struct Shading<R: Real> {
    /// Ambient plus every light's share, not yet clamped.
    pub color: R::V3,
    /// Bit i set: light i's shadow ray was blocked (lights past 31 set bit 31).
    pub shadow_mask: u32,
}

/// Ambient plus every light's share at `sp` seen along `view`.
pub fn shade_phong<R: Real>(
    scene: &CpuScene<R>,
    sp: &SurfacePoint<R>,
    view: R::V3,
    bounce: u32,
    key: &SampleKey<R>,
) -> Shading<R> {
    let mut out = Shading {
        color: scene.ambient,
        shadow_mask: 0,
    };
    for i in 0..scene.lights.len() {
        let term = light_term(scene, sp, view, i, bounce, key);
        out.color = out.color + term.contribution;
        if term.blocker.prim != NO_HIT {
            out.shadow_mask |= 1 << i.min(31);
        }
    }
    out
}

/// A primary ray's hit and its colour before reflections.
#[derive(Clone, Copy, Debug)]
pub struct PixelResult<R: Real> {
    /// What the ray hit (`NO_HIT`: the background).
    pub hit: Hit<R>,
    /// Not yet clamped.
    pub color: R::V3,
    /// Bit i set: light i's shadow ray was blocked (lights past 31 set bit 31).
    pub shadow_mask: u32,
    /// `FLAG_NONFINITE_COLOR` and `FLAG_NONFINITE_SURFACE`, as the shader's probe.
    pub flags: u32,
}

/// Traces `ray` and shades what it hits (the background where nothing).
pub fn trace_primary<R: Real>(
    scene: &CpuScene<R>,
    ray: &Ray<R>,
    key: &SampleKey<R>,
) -> PixelResult<R> {
    let hit = trace_closest(scene, ray);
    if hit.prim == NO_HIT {
        return PixelResult {
            hit,
            color: scene.background,
            shadow_mask: 0,
            flags: 0,
        };
    }
    let sp = surface_point(scene, ray, &hit);
    let shading = shade_phong(scene, &sp, -ray.dir, 0, key);
    let mut flags = 0;
    if R::nonfinite(shading.color) {
        flags |= FLAG_NONFINITE_COLOR;
    }
    if R::nonfinite(sp.p) || R::nonfinite(sp.n) {
        flags |= FLAG_NONFINITE_SURFACE;
    }
    PixelResult {
        hit,
        color: shading.color,
        shadow_mask: shading.shadow_mask,
        flags,
    }
}

/// The colour one sample's primary ray brings back: the first hit shaded,
/// clamped, then its reflections.
pub fn radiance<R: Real>(scene: &CpuScene<R>, primary: &Ray<R>, key: &SampleKey<R>) -> R::V3 {
    let first = trace_primary(scene, primary, key);
    let local = R::clamp01(first.color);
    if first.hit.prim != NO_HIT && scene.reflect_depth > 0 {
        return reflect_path(scene, primary, first.hit, local, key);
    }
    local
}

pub(crate) fn reflect_path<R: Real>(
    scene: &CpuScene<R>,
    primary: &Ray<R>,
    first_hit: Hit<R>,
    first_local: R::V3,
    key: &SampleKey<R>,
) -> R::V3 {
    let mut ray = *primary;
    let mut sp = surface_point(scene, primary, &first_hit);
    let mut local = first_local;
    let mut color = R::v3(R::ZERO, R::ZERO, R::ZERO);
    let one = R::v3(R::ONE, R::ONE, R::ONE);
    let mut weight = one;
    for bounce in 0..scene.reflect_depth {
        if (0..3).all(|i| sp.ks[i] == R::ZERO) {
            break;
        }
        color = color + weight * (one - sp.ks) * local;
        weight = weight * sp.ks;
        let dir = safe_normalize::<R>(ray.dir - sp.n * (R::TWO * R::dot(ray.dir, sp.n)), sp.n);
        let side = if R::dot(sp.ng, dir) >= R::ZERO {
            sp.ng
        } else {
            -sp.ng
        };
        ray = make_ray(offset_ray(scene, sp.p, side, sp.scale), dir, ray.time);
        let hit = trace_closest(scene, &ray);
        if hit.prim == NO_HIT {
            local = scene.background;
            break;
        }
        sp = surface_point(scene, &ray, &hit);
        local = R::clamp01(shade_phong(scene, &sp, -ray.dir, bounce + 1, key).color);
    }
    color + weight * local
}

/// Sample `s` of `n` of pixel (x, y): the pixel position, time and lights
/// sampled as the shader samples them.
pub fn sample_color<R: Real>(scene: &CpuScene<R>, x: u32, y: u32, s: u32, n: u32) -> R::V3 {
    let pixel = y.wrapping_mul(scene.size[0]).wrapping_add(x);
    let draw = |sample, stream, index| rng(scene.seed, pixel, sample, stream, index);
    let mut offset = [R::HALF, R::HALF];
    let mut time = R::ZERO;
    let sobol = scene.sampler == Sampler::Sobol;
    if n > 1 && sobol {
        offset = sobol_2d(sobol_key(scene.seed, pixel, STREAM_PIXEL), s);
    } else if n > 1 {
        let rotation = draw(ROTATION, STREAM_PIXEL, ROTATION);
        let jitter = [
            unit_float(draw(s, STREAM_PIXEL, 0)),
            unit_float(draw(s, STREAM_PIXEL, 1)),
        ];
        offset = stratified_2d(s, n, rotation, jitter);
    }
    if scene.motion_blur && sobol {
        time = scene.shutter * sobol_1d(sobol_key(scene.seed, pixel, STREAM_TIME), s);
    } else if scene.motion_blur {
        time = scene.shutter * unit_float(draw(s, STREAM_TIME, 0));
    }
    let key = SampleKey {
        pixel,
        sample: s,
        time,
    };
    radiance(scene, &camera_ray(scene, x, y, offset, time), &key)
}

/// Pixel (x, y)'s colour: the mean of its `spp` samples.
pub fn pixel_color<R: Real>(scene: &CpuScene<R>, x: u32, y: u32) -> R::V3 {
    let n = scene.spp.max(1);
    if n == 1 {
        return sample_color(scene, x, y, 0, 1);
    }
    let mut sum = R::v3(R::ZERO, R::ZERO, R::ZERO);
    for s in 0..n {
        sum = sum + sample_color(scene, x, y, s, n);
    }
    sum * (R::ONE / R::from_u32(n))
}

/// The key of a pixel's first sample at time 0 (for probes).
pub fn centre_key<R: Real>(scene: &CpuScene<R>, x: u32, y: u32) -> SampleKey<R> {
    SampleKey {
        pixel: y.wrapping_mul(scene.size[0]).wrapping_add(x),
        sample: 0,
        time: R::ZERO,
    }
}
