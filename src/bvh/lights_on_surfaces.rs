//! The rule for a point light that lies on a surface (a lamp standing on a
//! floor, a light on a sphere, in a wall's plane, on a shared edge or at a
//! vertex): **a surface through the light's own position does not shadow
//! that light**. Every shadow ray towards such a light ends exactly on that
//! surface, so without a rule whether the surface "occludes" its own end
//! point is decided by rounding, pixel by pixel, on every backend (f64
//! included): salt-and-pepper noise on everything the light reaches.
//!
//! The surfaces through each light are found once, in f64, on the host:
//! those that pass within `ON_SURFACE` (relative to the coordinates
//! involved) of the light, the bound on where their f32 and f64 roundings
//! put them. Shadow rays towards that light then treat them so:
//! - a triangle is ignored: its plane meets the segment to the light only at
//!   the light (a ray inside the plane grazes it and, by the same rule, is
//!   not blocked);
//! - a sphere blocks only with its other crossing: the line to the light
//!   meets the sphere at the light and at one more point, which blocks when
//!   it lies strictly between the shading point and the light, farther than
//!   `TANGENT_BAND` (of the way) from the light, so a ray that only touches
//!   the sphere at the light is not blocked by rounding;
//! - a shadow ray leaving a surface whose plane holds the light runs inside
//!   that plane, so it can only touch a sphere resting on it; lifted off
//!   the plane by the origin offset it would clip one. Such a ray (found per
//!   ray: `cpu::trace::in_plane_graze`) meets a sphere only outside a
//!   grazing band (`cpu::trace::graze_band`) as wide as the lift and the
//!   roundings involved.
//!
//! Both renderers read the same lists (`Bvh::surfaces_at_lights`); the
//! shader only when some light has one (its `LIGHT_SKIPS` variant). Moving
//! lights and moving primitives are left out: their contact changes over the
//! shutter interval.

use glam::DVec3;

use crate::bvh::node::{GpuBvhNode, SPHERE_BIT};
use crate::scene::{LightShape, Scene};

/// A surface within this fraction of the coordinates' magnitude of a light
/// passes through it: 16 f32 ulps, far above what parsing and f32 rounding
/// move a surface, far below any gap a scene means.
pub const ON_SURFACE: f64 = 1.0 / 1_048_576.0;

/// A sphere's other crossing this close to the light (as a fraction of the
/// way there) counts as the light's own (the ray is tangent there). The
/// shader and the CPU compare against `1 - TANGENT_BAND`.
pub const TANGENT_BAND: f64 = 1.0 / 4096.0;

/// Per light, the primitive references (bit 31: sphere) whose surface passes
/// through it; `scene` in the render space of the BVH whose `nodes` and
/// `refs` these are.
pub fn find(scene: &Scene, nodes: &[GpuBvhNode], refs: &[u32]) -> Vec<Vec<u32>> {
    scene
        .lights
        .iter()
        .map(|light| {
            if light.shape != LightShape::Point || light.velocity != DVec3::ZERO {
                return Vec::new();
            }
            let p = light.position;
            let mut found: Vec<u32> = candidates(nodes, refs, p)
                .into_iter()
                .filter(|&prim| through(scene, prim, p))
                .collect();
            found.sort_unstable();
            found
        })
        .collect()
}

/// Primitives in leaves whose (outward-rounded) box holds `p`, widened by
/// the tolerance.
fn candidates(nodes: &[GpuBvhNode], refs: &[u32], p: DVec3) -> Vec<u32> {
    let mut out = Vec::new();
    if nodes.is_empty() {
        return out;
    }
    let slack = DVec3::splat(p.abs().max_element() * ON_SURFACE);
    let (lo, hi) = (p - slack, p + slack);
    let mut stack = vec![0usize];
    while let Some(i) = stack.pop() {
        let n = &nodes[i];
        let min = DVec3::from_array(n.min.map(f64::from));
        let max = DVec3::from_array(n.max.map(f64::from));
        if hi.cmplt(min).any() || lo.cmpgt(max).any() {
            continue;
        }
        if n.count > 0 {
            let first = n.right_or_first as usize;
            out.extend_from_slice(&refs[first..first + n.count as usize]);
        } else {
            stack.push(i + 1);
            stack.push(n.right_or_first as usize);
        }
    }
    out
}

/// Whether primitive `prim`'s surface passes through `p` (static ones only).
fn through(scene: &Scene, prim: u32, p: DVec3) -> bool {
    let index = (prim & !SPHERE_BIT) as usize;
    if prim & SPHERE_BIT != 0 {
        let s = &scene.spheres[index];
        if s.velocity != DVec3::ZERO {
            return false;
        }
        let m = s.center.abs().max_element() + s.radius + p.abs().max_element();
        ((p - s.center).length() - s.radius).abs() <= ON_SURFACE * m
    } else {
        let t = &scene.triangles[index];
        if t.velocity != DVec3::ZERO {
            return false;
        }
        let [a, b, c] = t.vertices.map(|v| v.position);
        let m = a.abs().max(b.abs()).max(c.abs()).max(p.abs()).max_element();
        (closest_on_triangle(p, a, b, c) - p).length() <= ON_SURFACE * m
    }
}

/// The point of triangle abc nearest to p (Ericson, Real-Time Collision
/// Detection, 5.1.5); degenerate triangles reduce to their edges.
fn closest_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    if denom == 0.0 {
        // Collinear corners: the nearest of the three edges.
        let on = |u: DVec3, v: DVec3| {
            let e = v - u;
            let len2 = e.length_squared();
            let s = if len2 > 0.0 {
                ((p - u).dot(e) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            u + e * s
        };
        return [on(a, b), on(b, c), on(c, a)]
            .into_iter()
            .min_by(|x, y| (*x - p).length().total_cmp(&(*y - p).length()))
            .unwrap_or(a);
    }
    a + ab * (vb / denom) + ac * (vc / denom)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_points_on_a_triangle() {
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        let p = DVec3::new(0.25, 0.25, 3.0);
        assert_eq!(closest_on_triangle(p, a, b, c), DVec3::new(0.25, 0.25, 0.0));
        assert_eq!(closest_on_triangle(DVec3::new(-1.0, -1.0, 0.0), a, b, c), a);
        let edge = closest_on_triangle(DVec3::new(0.5, -2.0, 0.0), a, b, c);
        assert_eq!(edge, DVec3::new(0.5, 0.0, 0.0));
        let hyp = closest_on_triangle(DVec3::new(1.0, 1.0, 0.0), a, b, c);
        assert!((hyp - DVec3::new(0.5, 0.5, 0.0)).length() < 1e-15);
    }
}
