//! Binary PLY in the layout nearly every tool writes (a `vertex` element of
//! fixed-size properties, a `face` element whose only list is the corners,
//! three of them every time) read straight from the bytes on every thread:
//! each record is at a known offset, so there is nothing to parse.
//!
//! It gives exactly the mesh the general reader (`ply::read_element` and
//! `build`) would, or nothing: anything that reader would refuse, repair
//! or warn of (an index out of range, a repeated corner, a face without
//! area, a value that is not finite, a polygon, a short file) sends the
//! whole file to it instead, so every error and warning keeps its place.

use std::sync::atomic::{AtomicBool, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use super::ply_layout::{Element, Roles, Scalar};
use super::{Face, Mesh};

/// Where a fixed-size property sits in its element's records.
#[derive(Clone, Copy)]
struct Field {
    offset: usize,
    ty: Scalar,
}

/// An element's records: where they start, their stride, and each
/// property's place (lists have none).
struct Records<'a> {
    bytes: &'a [u8],
    stride: usize,
    fields: Vec<Option<Field>>,
}

impl Records<'_> {
    fn count(&self) -> usize {
        self.bytes.len().checked_div(self.stride).unwrap_or(0)
    }

    fn get(&self, record: &[u8], k: Option<usize>, big: bool) -> f64 {
        match k.and_then(|k| self.fields[k]) {
            Some(f) => f.ty.decode(&record[f.offset..], big),
            None => 0.0,
        }
    }
}

/// The mesh of a binary PLY whose data start at `start`, if it has the
/// common layout and nothing in it needs the general reader's care.
pub(super) fn read(src: &[u8], start: usize, big: bool, elements: &[Element]) -> Option<Mesh> {
    let mut at = start;
    let mut vertices = None;
    let mut faces = None;
    for element in elements.iter().filter(|e| !e.properties.is_empty()) {
        let roles = Roles::of(element);
        let records = layout(src, at, element, &roles)?;
        at += records.bytes.len();
        finite_fields(&records, element, &roles, big)?;
        match (roles.is_vertex, roles.is_face) {
            (true, _) if vertices.is_none() => vertices = Some((records, roles)),
            (_, true) if faces.is_none() => faces = Some((records, roles, element)),
            (false, false) => {}
            _ => return None,
        }
    }
    let ((vertex_records, vertex_roles), (face_records, face_roles, face)) = (vertices?, faces?);
    if vertex_records.count() >= u32::MAX as usize {
        return None;
    }
    let mut mesh = Mesh {
        positions: decode(&vertex_records, vertex_roles.xyz, big, 1.0),
        ..Mesh::default()
    };
    if !mesh.positions.par_iter().all(|p| p.is_finite()) {
        return None;
    }
    if vertex_roles.has_normals {
        mesh.normals = decode(&vertex_records, vertex_roles.nxyz, big, 1.0);
        let usable = |n: &DVec3| n.is_finite() && n.length_squared() != 0.0;
        if !mesh.normals.par_iter().all(usable) {
            return None;
        }
    }
    if vertex_roles.has_colors {
        let levels = vertex_roles.color_levels;
        mesh.colors = decode(&vertex_records, vertex_roles.rgb, big, levels);
    }
    let item = face.properties[face_roles.indices?].ty;
    mesh.faces = triangles(&face_records, &face_roles, item, big, &mesh)?;
    Some(mesh)
}

/// Each record's three values at `k`, divided by `levels` (as the general
/// reader divides colours).
fn decode(records: &Records, k: [Option<usize>; 3], big: bool, levels: f64) -> Vec<DVec3> {
    records
        .bytes
        .par_chunks_exact(records.stride)
        .map(|r| {
            let v = DVec3::new(
                records.get(r, k[0], big),
                records.get(r, k[1], big),
                records.get(r, k[2], big),
            );
            if levels == 1.0 {
                v
            } else {
                v / levels
            }
        })
        .collect()
}

/// The element's records at `at`, if every one has the same size: fixed
/// properties only, or for faces one corner list of three items.
fn layout<'a>(src: &'a [u8], at: usize, element: &Element, roles: &Roles) -> Option<Records<'a>> {
    let mut stride = 0usize;
    let mut fields = Vec::with_capacity(element.properties.len());
    for (k, p) in element.properties.iter().enumerate() {
        match p.list {
            None => {
                fields.push(Some(Field {
                    offset: stride,
                    ty: p.ty,
                }));
                stride += p.ty.size();
            }
            Some(count) if roles.is_face && roles.indices == Some(k) && p.ty.is_integer() => {
                fields.push(Some(Field {
                    offset: stride,
                    ty: count,
                }));
                stride += count.size() + 3 * p.ty.size();
            }
            Some(_) => return None,
        }
    }
    if roles.is_vertex && roles.xyz.iter().any(Option::is_none) {
        return None;
    }
    let len = element.count.checked_mul(stride)?;
    let bytes = src.get(at..at.checked_add(len)?)?;
    Some(Records {
        bytes,
        stride,
        fields,
    })
}

/// Whether every value the general reader requires finite is (it refuses
/// the file otherwise); None if not.
fn finite_fields(records: &Records, element: &Element, roles: &Roles, big: bool) -> Option<()> {
    let checked: Vec<Field> = element
        .properties
        .iter()
        .enumerate()
        .filter(|(k, p)| p.list.is_none() && !p.ty.is_integer() && !roles.repaired[*k])
        .filter_map(|(k, _)| records.fields[k])
        .collect();
    if checked.is_empty() || records.stride == 0 {
        return Some(());
    }
    let ok = records.bytes.par_chunks_exact(records.stride).all(|r| {
        checked
            .iter()
            .all(|f| f.ty.decode(&r[f.offset..], big).is_finite())
    });
    ok.then_some(())
}

/// The faces as triangles, if every one lists three distinct vertices that
/// exist and span some area.
fn triangles(
    records: &Records,
    roles: &Roles,
    item: Scalar,
    big: bool,
    mesh: &Mesh,
) -> Option<Vec<Face>> {
    let list = records.fields[roles.indices?]?;
    let np = mesh.positions.len() as f64;
    let count = records.count();
    if count == 0 || count.checked_mul(3)? >= u32::MAX as usize {
        return None;
    }
    let normals = !mesh.normals.is_empty();
    // Collected straight into place (a fallible collect would gather
    // pieces and copy them); one refused face refuses them all.
    let refused = AtomicBool::new(false);
    let faces: Vec<Face> = records
        .bytes
        .par_chunks_exact(records.stride)
        .map(|r| {
            face(r, list, item, big, np, mesh).unwrap_or_else(|| {
                refused.store(true, Ordering::Relaxed);
                Face {
                    positions: [0; 3],
                    normals: None,
                    material: None,
                }
            })
        })
        .collect();
    (!refused.into_inner()).then_some(faces).map(|mut faces| {
        if normals {
            faces
                .par_iter_mut()
                .for_each(|f| f.normals = Some(f.positions));
        }
        faces
    })
}

/// One face record's triangle, if the general reader would keep it as is.
#[inline]
fn face(r: &[u8], list: Field, item: Scalar, big: bool, np: f64, mesh: &Mesh) -> Option<Face> {
    if list.ty.decode(&r[list.offset..], big) != 3.0 {
        return None;
    }
    let first = list.offset + list.ty.size();
    let mut corners = [0u32; 3];
    for (k, c) in corners.iter_mut().enumerate() {
        let v = item.decode(&r[first + k * item.size()..], big);
        if !(0.0..np).contains(&v) {
            return None;
        }
        *c = v as u32;
    }
    let [a, b, c] = corners;
    if a == b || b == c || c == a {
        return None;
    }
    let [pa, pb, pc] = corners.map(|i| mesh.positions[i as usize]);
    if (pb - pa).cross(pc - pa).length_squared() == 0.0 {
        return None;
    }
    Some(Face {
        positions: corners,
        normals: None,
        material: None,
    })
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::super::ply;

    /// A binary PLY: `header` lines between `format` and `end_header`,
    /// then `body`.
    fn file(big: bool, header: &str, body: &[u8]) -> Vec<u8> {
        let order = if big { "big" } else { "little" };
        let mut out =
            format!("ply\nformat binary_{order}_endian 1.0\n{header}end_header\n").into_bytes();
        out.extend_from_slice(body);
        out
    }

    struct Body {
        big: bool,
        bytes: Vec<u8>,
    }

    impl Body {
        fn put<const N: usize>(&mut self, le: [u8; N], be: [u8; N]) -> &mut Self {
            self.bytes
                .extend_from_slice(if self.big { &be } else { &le });
            self
        }
        fn f32(&mut self, v: f32) -> &mut Self {
            self.put(v.to_le_bytes(), v.to_be_bytes())
        }
        fn f64(&mut self, v: f64) -> &mut Self {
            self.put(v.to_le_bytes(), v.to_be_bytes())
        }
        fn u8(&mut self, v: u8) -> &mut Self {
            self.put([v], [v])
        }
        fn u16(&mut self, v: u16) -> &mut Self {
            self.put(v.to_le_bytes(), v.to_be_bytes())
        }
        fn i32(&mut self, v: i32) -> &mut Self {
            self.put(v.to_le_bytes(), v.to_be_bytes())
        }
    }

    const GRID: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.5],
        [0.0, 1.0, 0.25],
    ];

    /// The fast reader's mesh (None where it declined) and both readers'
    /// results, which must be equal.
    fn both(bytes: &[u8]) -> (bool, Result<super::Mesh, crate::mesh::MeshError>) {
        let path = Path::new("t.ply");
        let general = ply::parse_general(bytes, path);
        let chosen = ply::parse(bytes, path);
        // Compared as printed: a NaN position equals itself there.
        assert_eq!(format!("{chosen:?}"), format!("{general:?}"));
        let took = chosen.is_ok() && ply::fast_took(bytes, path);
        (took, chosen)
    }

    /// Four vertices (float xyz), and faces as (count, corners) with
    /// uchar counts and int corners.
    fn simple(big: bool, faces: &[&[i32]]) -> Vec<u8> {
        let mut b = Body {
            big,
            bytes: Vec::new(),
        };
        for p in GRID {
            b.f32(p[0]).f32(p[1]).f32(p[2]);
        }
        for f in faces {
            b.u8(f.len() as u8);
            for &c in *f {
                b.i32(c);
            }
        }
        let header = format!(
            "element vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
             element face {}\nproperty list uchar int vertex_indices\n",
            faces.len()
        );
        file(big, &header, &b.bytes)
    }

    #[test]
    fn the_common_layout_reads_fast_and_as_the_general_reader_does() {
        for big in [false, true] {
            let (took, mesh) = both(&simple(big, &[&[0, 1, 2], &[0, 2, 3]]));
            assert!(took, "big endian {big}: the fast reader declined");
            let mesh = mesh.unwrap();
            assert_eq!(mesh.faces.len(), 2);
            assert_eq!(mesh.positions[2], glam::DVec3::new(1.0, 1.0, 0.5));
        }
    }

    #[test]
    fn normals_colours_other_properties_and_elements_read_fast() {
        for big in [false, true] {
            let mut b = Body {
                big,
                bytes: Vec::new(),
            };
            for (i, p) in GRID.iter().enumerate() {
                b.f64(f64::from(p[0]))
                    .f64(f64::from(p[1]))
                    .f64(f64::from(p[2]));
                b.f32(0.0).f32(0.6).f32(0.8);
                b.u8(10 * i as u8).u8(200).u8(255);
                b.f32(0.5);
            }
            for f in [[0u16, 1, 2], [0, 2, 3]] {
                b.u8(7);
                b.u16(3);
                for c in f {
                    b.u16(c);
                }
            }
            b.f32(1.0).f32(2.0);
            let header = "element vertex 4\nproperty double x\nproperty double y\n\
                          property double z\nproperty float nx\nproperty float ny\n\
                          property float nz\nproperty uchar red\nproperty uchar green\n\
                          property uchar blue\nproperty float quality\nelement face 2\n\
                          property uchar flags\nproperty list ushort ushort vertex_indices\n\
                          element extra 1\nproperty float a\nproperty float b\n";
            let (took, mesh) = both(&file(big, header, &b.bytes));
            assert!(took, "big endian {big}: the fast reader declined");
            let mesh = mesh.unwrap();
            assert_eq!(mesh.normals.len(), 4);
            assert_eq!(mesh.colors[1].x, 10.0 / 255.0);
            assert_eq!(mesh.faces[1].normals, Some([0, 2, 3]));
        }
    }

    #[test]
    fn what_needs_care_goes_to_the_general_reader() {
        let cases: [&[&[i32]]; 6] = [
            &[&[0, 1, 2, 3]],          // a quad
            &[&[0, 1, 1]],             // a repeated corner
            &[&[0, 1, 2], &[0, 1, 4]], // out of range
            &[&[0, -1, 2]],            // negative
            &[&[0, 1]],                // too few corners
            &[],                       // no faces
        ];
        for faces in cases {
            let (took, _) = both(&simple(false, faces));
            assert!(!took, "{faces:?}: the fast reader should decline");
        }
        // Truncated data, and a face without area.
        let whole = simple(false, &[&[0, 1, 2]]);
        for cut in [whole.len() - 1, whole.len() - 13] {
            let (took, result) = both(&whole[..cut]);
            assert!(!took && result.is_err());
        }
        let mut b = Body {
            big: false,
            bytes: Vec::new(),
        };
        for p in [[0.0f32; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]] {
            b.f32(p[0]).f32(p[1]).f32(p[2]);
        }
        b.u8(3).i32(0).i32(1).i32(2);
        let header = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                      element face 1\nproperty list uchar int vertex_indices\n";
        let (took, mesh) = both(&file(false, header, &b.bytes));
        assert!(!took);
        assert!(
            !mesh.unwrap().report.is_empty(),
            "the flat face is warned of"
        );
    }

    #[test]
    fn values_that_are_not_finite_keep_their_errors_and_warnings() {
        for (x, quality) in [(f32::NAN, 0.5), (0.0, f32::INFINITY)] {
            let mut b = Body {
                big: false,
                bytes: Vec::new(),
            };
            for (i, p) in GRID.iter().enumerate() {
                b.f32(if i == 1 { x } else { p[0] })
                    .f32(p[1])
                    .f32(p[2])
                    .f32(quality);
            }
            b.u8(3).i32(0).i32(2).i32(3);
            b.u8(3).i32(0).i32(1).i32(2);
            let header = "element vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
                          property float quality\nelement face 2\n\
                          property list uchar int vertex_indices\n";
            let (took, _) = both(&file(false, header, &b.bytes));
            assert!(!took);
        }
    }
}
