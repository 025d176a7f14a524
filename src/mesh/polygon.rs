//! Polygons into triangles. A convex polygon is fanned from its first
//! corner (what every importer does, and what glint always did, so the
//! triangles of existing files do not change); a concave one is cut by ear
//! clipping in its own plane, since a fan covers area outside a concave
//! polygon and misses area inside it.

use glam::{DVec2, DVec3};

/// How a polygon was cut.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cut {
    /// Convex (or a triangle): fanned from corner 0.
    Fan,
    /// Concave: ear clipped.
    Ears,
    /// No ear left to clip (the polygon crosses itself), or too many
    /// corners to clip in reasonable time: fanned.
    Tangled,
}

/// Ear clipping costs up to the cube of the corner count; past this a
/// concave polygon is fanned (and reported), so no file can make loading
/// take hours. Real concave polygons have a handful of corners.
pub const MAX_EAR_CORNERS: usize = 256;

/// Cuts the polygon with corners `points` (in order, no two consecutive
/// equal) into triangles of corner indices, appended to `out`.
pub fn triangulate(points: &[DVec3], out: &mut Vec<[usize; 3]>) -> Cut {
    let n = points.len();
    if n < 3 {
        return Cut::Fan;
    }
    if n == 3 {
        out.push([0, 1, 2]);
        return Cut::Fan;
    }
    let normal = newell(points);
    if is_convex(points, normal) {
        fan(n, out);
        return Cut::Fan;
    }
    if n > MAX_EAR_CORNERS {
        fan(n, out);
        return Cut::Tangled;
    }
    let flat = project(points, normal);
    let before = out.len();
    if clip_ears(&flat, out) {
        Cut::Ears
    } else {
        out.truncate(before);
        fan(n, out);
        Cut::Tangled
    }
}

fn fan(n: usize, out: &mut Vec<[usize; 3]>) {
    for k in 1..n - 1 {
        out.push([0, k, k + 1]);
    }
}

/// The polygon's normal by Newell's method: robust for any planar or
/// nearly planar polygon, convex or not.
fn newell(points: &[DVec3]) -> DVec3 {
    let mut n = DVec3::ZERO;
    for (i, p) in points.iter().enumerate() {
        let q = points[(i + 1) % points.len()];
        n += DVec3::new(
            (p.y - q.y) * (p.z + q.z),
            (p.z - q.z) * (p.x + q.x),
            (p.x - q.x) * (p.y + q.y),
        );
    }
    n
}

/// Every corner turns the same way about `normal` (straight corners allowed).
fn is_convex(points: &[DVec3], normal: DVec3) -> bool {
    let n = points.len();
    (0..n).all(|i| {
        let a = points[(i + n - 1) % n];
        let b = points[i];
        let c = points[(i + 1) % n];
        (b - a).cross(c - b).dot(normal) >= 0.0
    })
}

/// The points in the plane across `normal`'s largest axis, turned so the
/// polygon winds counter-clockwise.
fn project(points: &[DVec3], normal: DVec3) -> Vec<DVec2> {
    let a = normal.abs();
    let (flip, pick): (bool, fn(DVec3) -> DVec2) = if a.x >= a.y && a.x >= a.z {
        (normal.x < 0.0, |p| DVec2::new(p.y, p.z))
    } else if a.y >= a.z {
        (normal.y < 0.0, |p| DVec2::new(p.z, p.x))
    } else {
        (normal.z < 0.0, |p| DVec2::new(p.x, p.y))
    };
    points
        .iter()
        .map(|&p| {
            let q = pick(p);
            if flip {
                DVec2::new(q.y, q.x)
            } else {
                q
            }
        })
        .collect()
}

fn cross(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    (b - a).perp_dot(c - a)
}

/// Ear clipping of a counter-clockwise polygon; false when no ear is left
/// before the last triangle (a polygon that crosses itself).
fn clip_ears(p: &[DVec2], out: &mut Vec<[usize; 3]>) -> bool {
    let mut idx: Vec<usize> = (0..p.len()).collect();
    while idx.len() > 3 {
        let m = idx.len();
        let ear = (0..m)
            .find(|&i| is_ear(p, &idx, i, false))
            // Only straight corners left somewhere: clip one (its triangle
            // has no area and is dropped later) to go on.
            .or_else(|| (0..m).find(|&i| is_ear(p, &idx, i, true)));
        let Some(i) = ear else {
            return false;
        };
        out.push([idx[(i + m - 1) % m], idx[i], idx[(i + 1) % m]]);
        idx.remove(i);
    }
    out.push([idx[0], idx[1], idx[2]]);
    true
}

fn is_ear(p: &[DVec2], idx: &[usize], i: usize, straight: bool) -> bool {
    let m = idx.len();
    let (a, b, c) = (idx[(i + m - 1) % m], idx[i], idx[(i + 1) % m]);
    let turn = cross(p[a], p[b], p[c]);
    if straight {
        if turn != 0.0 {
            return false;
        }
    } else if turn <= 0.0 {
        return false;
    }
    // No other corner inside or on the ear.
    idx.iter().all(|&k| {
        k == a
            || k == b
            || k == c
            || p[k] == p[a]
            || p[k] == p[b]
            || p[k] == p[c]
            || !inside(p[k], p[a], p[b], p[c])
    })
}

fn inside(q: DVec2, a: DVec2, b: DVec2, c: DVec2) -> bool {
    cross(a, b, q) >= 0.0 && cross(b, c, q) >= 0.0 && cross(c, a, q) >= 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(points: &[DVec3], tris: &[[usize; 3]]) -> f64 {
        tris.iter()
            .map(|t| {
                (points[t[1]] - points[t[0]])
                    .cross(points[t[2]] - points[t[0]])
                    .length()
                    / 2.0
            })
            .sum()
    }

    #[test]
    fn convex_polygons_are_fanned_from_their_first_corner() {
        let square = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let mut out = Vec::new();
        assert_eq!(triangulate(&square, &mut out), Cut::Fan);
        assert_eq!(out, vec![[0, 1, 2], [0, 2, 3]]);
    }

    /// An L (concave at corner 3) and an arrow whose fan from corner 0
    /// would cover area outside it: the ears cover exactly the polygon.
    #[test]
    fn concave_polygons_are_ear_clipped_to_their_own_area() {
        let l = [
            (0.0, 0.0),
            (2.0, 0.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ];
        // Start the L at its reflex corner: a fan from there is wrong.
        for start in 0..l.len() {
            for z_up in [true, false] {
                let pts: Vec<DVec3> = (0..l.len())
                    .map(|k| {
                        let (x, y) = l[(start + k) % l.len()];
                        if z_up {
                            DVec3::new(x, y, 5.0)
                        } else {
                            // Clockwise seen from +z, in a tilted plane.
                            DVec3::new(y, x, x + y)
                        }
                    })
                    .collect();
                let mut out = Vec::new();
                assert_eq!(triangulate(&pts, &mut out), Cut::Ears);
                assert_eq!(out.len(), 4);
                let planar_area = if z_up { 3.0 } else { 3.0 * 3f64.sqrt() };
                assert!((area(&pts, &out) - planar_area).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn a_bow_tie_is_fanned_and_reported() {
        let bow = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let mut out = Vec::new();
        let cut = triangulate(&bow, &mut out);
        assert_ne!(cut, Cut::Ears);
        assert_eq!(out.len(), 2);
    }
}
