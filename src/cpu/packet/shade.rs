//! Packets of pixels shaded: a tile's primary rays traced together, their
//! surface points, and the shadow rays towards each point light traced
//! together too; the shading itself one pixel at a time in SSE, each value
//! the single ray's to the bit.

use super::lanes::*;
use super::walk::traverse;
use crate::cpu::trace::{
    centre_key, count_ray, light_at, light_term, pow_c, reflect_path, shadow_origin, surface_point,
    CpuScene, Hit, Ray, SurfacePoint, NO_HIT,
};
use crate::cpu::Real;
use crate::layout::{LIGHT_POINT, SPHERE_BIT};
use crate::methods::Methods;
use glam::{Vec3, Vec3A, Vec3Swizzles};

/// A packet's pixels: a block `TILE[0]` wide and `TILE[1]` high, whose
/// rays stay closer together than a row's. Measured against 4 x 4 tiles of
/// sixteen rays and 8 x 4 ones: taller tiles were faster, most on the big
/// grids.
pub const TILE: [u32; 2] = [4, 8];

// A tile's pixels fit one packet (`fill_band` gathers them into one).
const _: () = assert!(TILE[0] * TILE[1] <= WIDTH as u32);

/// Fills a band of `TILE[1]` rows (fewer for the last) from row `y0`, each
/// `TILE`-sized tile's pixels that `keep` says as one packet (`colours`),
/// the others left as they are.
pub fn fill_band(
    scene: &CpuScene<f32>,
    y0: u32,
    band: &mut [[f32; 3]],
    keep: &(dyn Fn(u32, u32) -> bool + Sync),
) {
    let [tw, _] = TILE;
    let w = scene.size[0];
    let rows = band.len() as u32 / w.max(1);
    for x0 in (0..w).step_by(tw as usize) {
        let mut pixels = [[0u32; 2]; WIDTH];
        let mut n = 0;
        for y in y0..y0 + rows {
            for x in x0..(x0 + tw).min(w) {
                if keep(x, y) {
                    pixels[n] = [x, y];
                    n += 1;
                }
            }
        }
        for (&[x, y], c) in pixels[..n].iter().zip(colours(scene, &pixels[..n])) {
            band[((y - y0) * w + x) as usize] = c;
        }
    }
}

/// `trace::safe_normalize` in an SSE register: the dot product left to
/// right, as glam's `Vec3A::dot` adds it, so the same bits.
#[inline(always)]
pub(super) fn safe_normalize_a(v: Vec3A, fallback: Vec3A) -> Vec3A {
    let len2 = v.dot(v);
    if len2 > 0.0 {
        v * (1.0 / len2.sqrt())
    } else {
        fallback
    }
}

/// `trace::surface_point` for the packets' f32 scene, a triangle's vectors
/// in SSE registers (glam's `Vec3A`) instead of three scalars each: per
/// lane the same operations in the same order on the same values, only
/// multiplies, adds, subtracts and sign clears (whose results do not depend
/// on the width, where `min` and `max` would differ on NaN), so the same
/// bits (tested). Spheres, motion and the naive methods take the generic
/// path. On the 240k grid (cachegrind) the generic one took 300
/// instructions a hit, a tenth of the render.
#[inline(always)]
pub(super) fn surface_point_f32(
    scene: &CpuScene<f32>,
    ray: &Ray<f32>,
    hit: &Hit<f32>,
) -> SurfacePoint<f32> {
    if hit.prim & SPHERE_BIT != 0 || scene.motion_blur || scene.methods != Methods::Robust {
        return surface_point(scene, ray, hit);
    }
    let index = hit.prim as usize;
    let tri = scene.triangles[index].map(Vec3A::from);
    let w = [1.0 - hit.b1 - hit.b2, hit.b1, hit.b2];
    let tw = [tri[0] * w[0], tri[1] * w[1], tri[2] * w[2]];
    // `Real::cross` (glam's scalar one), written out so that no fused
    // multiply-subtract can enter where the target has FMA.
    let cross = |a: Vec3A, b: Vec3A| (a.zxy() * b - a * b.zxy()).zxy();
    let ng = safe_normalize_a(cross(tri[1] - tri[0], tri[2] - tri[0]), Vec3A::Z);
    let s = &scene.shading[index];
    let n = safe_normalize_a(
        Vec3A::from(s[0].normal) * w[0]
            + Vec3A::from(s[1].normal) * w[1]
            + Vec3A::from(s[2].normal) * w[2],
        ng,
    );
    let m = s.map(|c| &scene.materials[c.material as usize]);
    let mix = |f: fn(&crate::cpu::trace::SurfaceMaterial<f32>) -> Vec3| {
        Vec3A::from(f(m[0])) * w[0] + Vec3A::from(f(m[1])) * w[1] + Vec3A::from(f(m[2])) * w[2]
    };
    SurfacePoint {
        p: (tw[0] + tw[1] + tw[2]).into(),
        n: n.into(),
        ng: ng.into(),
        scale: (tw[0].abs() + tw[1].abs() + tw[2].abs()).into(),
        kd: mix(|m| m.kd).into(),
        ks: mix(|m| m.ks).into(),
        shininess: w[0] * m[0].shininess + w[1] * m[1].shininess + w[2] * m[2].shininess,
    }
}

/// What an unblocked point light adds at `sp` (`trace::point_shading`'s
/// contribution), in SSE registers as `surface_point_f32` computes: the
/// same bits (tested).
#[inline(always)]
pub(super) fn point_contribution_f32(
    sp: &SurfacePoint<f32>,
    view: Vec3,
    target: Vec3,
    color: Vec3,
) -> Vec3A {
    let n = Vec3A::from(sp.n);
    let l = safe_normalize_a(Vec3A::from(target) - Vec3A::from(sp.p), n);
    let ln = l.dot(n);
    let r = n * (2.0 * ln) - l;
    // Scalar `max`, as there: a NaN gives 0.
    let rv = r.dot(Vec3A::from(view)).max(0.0);
    let spec = pow_c(rv, sp.shininess);
    Vec3A::from(color) * (Vec3A::from(sp.kd) * ln.max(0.0) + Vec3A::from(sp.ks) * spec)
}

/// The colours `pixel_color` gives `pixels` (up to `WIDTH`), clamped: the
/// primary rays as a packet, then per point light the shadow rays of the
/// pixels that hit something; area lights, lights on surfaces and
/// reflections one pixel at a time, as `shade_phong` and `radiance` take
/// them.
pub fn colours(scene: &CpuScene<f32>, pixels: &[[u32; 2]]) -> [[f32; 3]; WIDTH] {
    let mut out = [[0.0; 3]; WIDTH];
    let n = pixels.len().min(WIDTH);
    if n == 0 {
        return out;
    }
    let active = u32::MAX >> (32 - n);
    // Lanes past the last pixel repeat it, unused.
    let rays = pixel_rays(scene, &std::array::from_fn(|i| pixels[i.min(n - 1)]));
    for _ in 0..n {
        count_ray(0);
    }
    let hits = traverse(scene, &rays, active, f32::T_INF, false);
    let mut lit = 0u32;
    let mut points: [Option<SurfacePoint<f32>>; WIDTH] = [None; WIDTH];
    let mut colour = [Vec3A::from(scene.background); WIDTH];
    for (i, hit) in hits.iter().enumerate() {
        if active & (1 << i) != 0 && hit.prim != NO_HIT {
            points[i] = Some(surface_point_f32(scene, &rays[i], hit));
            colour[i] = scene.ambient.into();
            lit |= 1 << i;
        }
    }
    let key = |i: usize| centre_key(scene, pixels[i][0], pixels[i][1]);
    for l in 0..scene.lights.len() {
        let light = light_at(scene, l, 0.0);
        let on_surface = scene
            .surfaces_at_lights
            .get(l)
            .is_some_and(|s| !s.is_empty());
        if light.kind != LIGHT_POINT || on_surface {
            for (i, sp) in points.iter().enumerate() {
                if let Some(sp) = sp {
                    let term = light_term(scene, sp, -rays[i].dir, l, 0, &key(i));
                    colour[i] += Vec3A::from(term.contribution);
                }
            }
            continue;
        }
        // `point_shadow_ray`'s rays (no surfaces at this light, so no
        // grazing band). Lanes without a surface carry the primary ray,
        // unused.
        let mut origins = [Vec3::ZERO; WIDTH];
        let mut dirs = [Vec3::ZERO; WIDTH];
        for (i, sp) in points.iter().enumerate() {
            (origins[i], dirs[i]) = match sp {
                Some(sp) => {
                    let origin = shadow_origin(scene, sp, light.position);
                    (origin, light.position - origin)
                }
                None => (rays[i].origin, rays[i].dir),
            };
        }
        let shadows = make_rays(&origins, &dirs);
        for _ in 0..lit.count_ones() {
            count_ray(1);
        }
        let blockers = traverse(scene, &shadows, lit, 1.0, true);
        for (i, sp) in points.iter().enumerate() {
            if let Some(sp) = sp {
                if blockers[i].prim == NO_HIT {
                    colour[i] +=
                        point_contribution_f32(sp, -rays[i].dir, light.position, light.color);
                }
            }
        }
    }
    for (i, px) in out.iter_mut().enumerate().take(n) {
        let local = f32::clamp01(colour[i].into());
        let c = if lit & (1 << i) != 0 && scene.reflect_depth > 0 {
            reflect_path(scene, &rays[i], hits[i], local, &key(i))
        } else {
            local
        };
        *px = f32::v3_to_f32(f32::clamp01(c));
    }
    out
}
