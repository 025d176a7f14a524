//! From the polygons a loader read to a `Mesh` of triangles: one place for
//! what every format needs checked and repaired (repeated corners,
//! faces without area, normals that are missing, partial, not finite or
//! never used), so each loader only reads.

use std::path::Path;

use glam::DVec3;
use rayon::prelude::*;

use super::polygon::{triangulate, Cut};
use super::report::Tolerance;
use super::{Face, Mesh, MeshError, SMOOTH};

/// Where a polygon came from, for warnings.
#[derive(Clone, Copy, Debug)]
pub enum Loc {
    Line(u64),
    Byte(u64),
    /// An index into `Builder::labels` (glTF's JSON paths).
    Label(u32),
}

/// Which normals and positions of the file are unusable (not finite, or a
/// normal of no length).
struct Unusable {
    normal: Vec<bool>,
    position: Vec<bool>,
}

/// Space reused from polygon to polygon.
#[derive(Default)]
struct Scratch {
    ring: Vec<(u32, Option<u32>)>,
    points: Vec<DVec3>,
    tris: Vec<[usize; 3]>,
}

struct Poly {
    start: u32,
    len: u32,
    material: Option<u32>,
    at: Loc,
}

/// A mesh being read: vertices, normals, colours and materials as the
/// file gives them, and polygons as corner lists.
pub struct Builder<'a> {
    pub mesh: Mesh,
    pub path: &'a Path,
    pub labels: Vec<String>,
    corners: Vec<(u32, Option<u32>)>,
    polys: Vec<Poly>,
}

impl<'a> Builder<'a> {
    pub fn new(path: &'a Path) -> Builder<'a> {
        Builder {
            mesh: Mesh::default(),
            path,
            labels: Vec::new(),
            corners: Vec::new(),
            polys: Vec::new(),
        }
    }

    /// A builder holding polygons read elsewhere (`obj_fast`): corners as
    /// (position, optional normal) indices, polygons as (first corner,
    /// count, line).
    pub fn from_polygons(
        path: &'a Path,
        mesh: Mesh,
        corners: Vec<(u32, Option<u32>)>,
        polygons: &[(u32, u32, u64)],
    ) -> Builder<'a> {
        Builder {
            mesh,
            path,
            labels: Vec::new(),
            corners,
            polys: polygons
                .par_iter()
                .map(|&(start, len, line)| Poly {
                    start,
                    len,
                    material: None,
                    at: Loc::Line(line),
                })
                .collect(),
        }
    }

    pub fn warn(&mut self, kind: Tolerance, at: Option<String>, message: impl Into<String>) {
        self.mesh.report.warn(kind, self.path, at, message);
    }

    fn show(&self, at: Loc) -> Option<String> {
        match at {
            Loc::Line(l) => Some(format!("line {l}")),
            Loc::Byte(b) => Some(format!("byte {b}")),
            Loc::Label(i) => self.labels.get(i as usize).cloned(),
        }
    }

    /// One polygon: its corners as (position, optional normal) indices,
    /// already checked against what the file defines.
    pub fn polygon(
        &mut self,
        corners: impl IntoIterator<Item = (u32, Option<u32>)>,
        material: Option<u32>,
        at: Loc,
    ) {
        let start = self.corners.len();
        self.corners.extend(corners);
        let len = self.corners.len() - start;
        self.polys.push(Poly {
            start: start as u32,
            len: len as u32,
            material,
            at,
        });
    }

    /// Every corner's normal is its vertex's own (PLY and OFF give normals
    /// per vertex).
    pub fn corner_normals_are_positions(&mut self) {
        for c in &mut self.corners {
            c.1 = Some(c.0);
        }
    }

    /// How many corners are held: loaders with untrusted counts stop
    /// before `u32` offsets overflow.
    pub fn corner_count(&self) -> usize {
        self.corners.len()
    }

    /// Checks and cuts every polygon into the mesh's faces.
    pub fn finish(self) -> Result<Mesh, MeshError> {
        self.finish_with(true)
    }

    fn finish_with(mut self, at_once: bool) -> Result<Mesh, MeshError> {
        if self.corners.len() >= u32::MAX as usize {
            return Err(MeshError {
                path: self.path.to_path_buf(),
                at: None,
                message: "more than 4 billion polygon corners; split the model".into(),
            });
        }
        let nn = self.mesh.normals.len();
        let bad = Unusable {
            normal: self
                .mesh
                .normals
                .par_iter()
                .map(|n| !n.is_finite() || n.length_squared() == 0.0)
                .collect(),
            position: self
                .mesh
                .positions
                .par_iter()
                .map(|p| !p.is_finite())
                .collect(),
        };
        let mut used_normals = false;
        if let Some(faces) = at_once.then(|| self.simple_triangles(&bad)).flatten() {
            used_normals = faces.par_iter().any(|f| f.normals.is_some());
            self.mesh.faces = faces;
            self.polys.clear();
        }
        let mut scratch = Scratch::default();
        let polys = std::mem::take(&mut self.polys);
        self.mesh.faces.reserve(polys.len());
        for poly in &polys {
            self.add_polygon(poly, &bad, &mut scratch, &mut used_normals)?;
        }
        if nn > 0 && !used_normals {
            self.warn(
                Tolerance::UnusedNormals,
                None,
                format!(
                    "the file gives {nn} normals but no face refers to them; smooth normals \
                     are used"
                ),
            );
        }
        Ok(self.mesh)
    }

    /// Every polygon as its face, on every thread, when every one is a
    /// triangle that `add_polygon` would keep as it is: three distinct
    /// corners in range at finite positions spanning some area, normals on
    /// all corners or none, each usable. None otherwise (`add_polygon`
    /// then takes them one by one, with its warnings and errors).
    fn simple_triangles(&self, bad: &Unusable) -> Option<Vec<Face>> {
        let np = self.mesh.positions.len();
        let nn = self.mesh.normals.len();
        let nm = self.mesh.materials.len() as u32;
        let simple = |poly: &Poly| -> Option<Face> {
            if poly.len != 3 || poly.material.is_some_and(|m| m >= nm) {
                return None;
            }
            let c = &self.corners[poly.start as usize..poly.start as usize + 3];
            let positions = [c[0].0, c[1].0, c[2].0];
            let [a, b, d] = positions;
            if a == b || b == d || d == a || positions.iter().any(|&p| p as usize >= np) {
                return None;
            }
            if positions.iter().any(|&p| bad.position[p as usize]) {
                return None;
            }
            let [pa, pb, pd] = positions.map(|p| self.mesh.positions[p as usize]);
            if (pb - pa).cross(pd - pa).length_squared() == 0.0 {
                return None;
            }
            let normals = match (c[0].1, c[1].1, c[2].1) {
                (None, None, None) => None,
                (Some(x), Some(y), Some(z)) => {
                    let n = [x, y, z];
                    if n.iter()
                        .any(|&k| k as usize >= nn || bad.normal[k as usize])
                    {
                        return None;
                    }
                    Some(n)
                }
                _ => return None,
            };
            Some(Face {
                positions,
                normals,
                material: poly.material,
            })
        };
        // Straight into place; one polygon that needs care refuses all.
        let refused = std::sync::atomic::AtomicBool::new(false);
        let faces: Vec<Face> = self
            .polys
            .par_iter()
            .map(|poly| {
                simple(poly).unwrap_or_else(|| {
                    refused.store(true, std::sync::atomic::Ordering::Relaxed);
                    Face {
                        positions: [0; 3],
                        normals: None,
                        material: None,
                    }
                })
            })
            .collect();
        (!refused.into_inner()).then_some(faces)
    }

    /// One polygon's triangles into the mesh, or a warning saying why it
    /// was dropped; an error where it refers to what the file lacks.
    /// `used_normals` is set where it names file normals.
    fn add_polygon(
        &mut self,
        poly: &Poly,
        bad: &Unusable,
        s: &mut Scratch,
        used_normals: &mut bool,
    ) -> Result<(), MeshError> {
        let np = self.mesh.positions.len() as u32;
        let nn = self.mesh.normals.len();
        let nm = self.mesh.materials.len() as u32;
        let corners = &self.corners[poly.start as usize..(poly.start + poly.len) as usize];
        if let Some(&(p, _)) = corners.iter().find(|c| c.0 >= np) {
            return Err(MeshError {
                path: self.path.to_path_buf(),
                at: self.show(poly.at),
                message: format!("a face refers to vertex {p}, but there are {np}"),
            });
        }
        if let Some(m) = poly.material.filter(|&m| m >= nm) {
            return Err(MeshError {
                path: self.path.to_path_buf(),
                at: self.show(poly.at),
                message: format!("a face refers to material {m}, but there are {nm}"),
            });
        }
        if corners.iter().any(|c| bad.position[c.0 as usize]) {
            let at = self.show(poly.at);
            self.warn(
                Tolerance::BadPosition,
                at,
                "a face with a vertex that is not finite (NaN or infinite) dropped",
            );
            return Ok(());
        }
        // Repeated corners (consecutive, or the last equal to the first) go.
        s.ring.clear();
        for &c in corners {
            if s.ring.last().map(|l| l.0) != Some(c.0) {
                s.ring.push(c);
            }
        }
        while s.ring.len() > 1 && s.ring.first().map(|f| f.0) == s.ring.last().map(|l| l.0) {
            s.ring.pop();
        }
        if s.ring.len() < 3 {
            let at = self.show(poly.at);
            let message = if corners.len() < 3 {
                format!("a face with {} corner(s) dropped", corners.len())
            } else {
                "a face whose corners repeat one vertex dropped".to_string()
            };
            self.warn(Tolerance::DegenerateFace, at, message);
            return Ok(());
        }
        let with = s.ring.iter().filter(|c| c.1.is_some()).count();
        let normals_usable = if with == s.ring.len() {
            *used_normals = true;
            true
        } else {
            if with > 0 {
                *used_normals = true;
                let at = self.show(poly.at);
                self.warn(
                    Tolerance::PartialNormals,
                    at,
                    format!(
                        "a face gives normals for {with} of its {} corners; smooth normals \
                             are used for all of them",
                        s.ring.len()
                    ),
                );
            }
            false
        };
        if let Some(k) = s
            .ring
            .iter()
            .filter_map(|c| c.1)
            .find(|&k| k as usize >= nn)
        {
            return Err(MeshError {
                path: self.path.to_path_buf(),
                at: self.show(poly.at),
                message: format!("a face refers to normal {k}, but there are {nn}"),
            });
        }
        s.points.clear();
        s.points
            .extend(s.ring.iter().map(|c| self.mesh.positions[c.0 as usize]));
        s.tris.clear();
        let cut = triangulate(&s.points, &mut s.tris);
        if cut == Cut::Tangled {
            let at = self.show(poly.at);
            self.warn(
                Tolerance::TangledPolygon,
                at,
                format!(
                    "a concave polygon of {} corners that ear clipping cannot cut (it \
                         crosses itself, or has over {} corners) is fanned from its first corner",
                    s.ring.len(),
                    super::polygon::MAX_EAR_CORNERS
                ),
            );
        }
        let before = self.mesh.faces.len();
        for t in &s.tris {
            let [a, b, c] = t.map(|k| s.points[k]);
            if (b - a).cross(c - a).length_squared() == 0.0 {
                continue;
            }
            let normals = normals_usable.then(|| {
                t.map(|k| {
                    let n = s.ring[k].1.unwrap_or(SMOOTH);
                    if n != SMOOTH && bad.normal[n as usize] {
                        SMOOTH
                    } else {
                        n
                    }
                })
            });
            self.mesh.faces.push(Face {
                positions: t.map(|k| s.ring[k].0),
                normals,
                material: poly.material,
            });
        }
        if self.mesh.faces.len() == before {
            let at = self.show(poly.at);
            self.warn(
                Tolerance::DegenerateFace,
                at,
                "a face without area (its corners lie on one line) dropped",
            );
        } else if normals_usable {
            self.note_bad_normals(&s.ring, &bad.normal, poly.at);
        }
        Ok(())
    }

    fn note_bad_normals(&mut self, ring: &[(u32, Option<u32>)], bad: &[bool], at: Loc) {
        for &(_, n) in ring {
            let Some(n) = n.filter(|&n| bad[n as usize]) else {
                continue;
            };
            let v = self.mesh.normals[n as usize];
            let at = self.show(at);
            self.warn(
                Tolerance::BadNormal,
                at,
                format!(
                    "a normal ({} {} {}) is not finite or has no length; the smooth normal is \
                     used there",
                    v.x, v.y, v.z
                ),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A builder of a 30x30 grid's triangles, with normals on every
    /// corner or none, and `extra` polygons after them.
    fn grid(normals: bool, extra: &[&[u32]]) -> Builder<'static> {
        let mut b = Builder::new(Path::new("t"));
        for j in 0..30 {
            for i in 0..30 {
                let (x, y) = (f64::from(i), f64::from(j));
                b.mesh.positions.push(DVec3::new(x, y, (x * y).sin()));
                b.mesh.normals.push(DVec3::new(0.0, (x * 0.1).sin(), 1.0));
            }
        }
        for j in 0..29 {
            for i in 0..29 {
                let v = j * 30 + i;
                for t in [[v, v + 1, v + 31], [v, v + 31, v + 30]] {
                    let n = |k: u32| normals.then_some(k);
                    b.polygon(t.map(|k| (k, n(k))), None, Loc::Line(u64::from(v)));
                }
            }
        }
        for e in extra {
            b.polygon(e.iter().map(|&k| (k, None)), None, Loc::Line(9999));
        }
        b
    }

    #[test]
    fn triangles_at_once_are_the_faces_one_by_one_gives() {
        let cases: [(bool, &[&[u32]]); 5] = [
            (true, &[]),
            (false, &[]),
            (false, &[&[0, 1, 2, 3]]),
            (true, &[&[0, 1, 1]]),
            (false, &[&[0, 1, 2000]]),
        ];
        for (normals, extra) in cases {
            let one_by_one = grid(normals, extra).finish_with(false);
            let at_once = grid(normals, extra).finish_with(true);
            assert_eq!(at_once, one_by_one, "normals {normals}, extra {extra:?}");
        }
        // Unused normals are still said.
        let mesh = grid(false, &[]).finish().unwrap();
        assert!(!mesh.report.is_empty());
    }
}
