//! PLY (Stanford polygon files), ASCII and binary of either byte order:
//! the `vertex` element's `x y z`, optional `nx ny nz` and `red green blue`
//! (integers 0-255 or floats 0-1), the `face` element's
//! `vertex_indices` (or `vertex_index`) lists, and the `tristrips`
//! element's strips (`-1` restarting one), in which some scanned models
//! ship. Other elements and properties are read past. Normals that are
//! not finite are repaired (`build`), as are degenerate faces; a file of
//! points only loads with a warning from the scene. Binary files in the
//! layout most tools write are read by `ply_fast`, which gives the same
//! mesh.

use std::path::Path;

use glam::DVec3;

use super::build::{Builder, Loc};
use super::ply_layout::{Element, Property, Roles, Scalar};
use super::text::Text;
use super::{Mesh, MeshError};

#[derive(Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Little,
    Big,
}

/// Where values come from: ASCII tokens or binary bytes.
enum Reader<'a> {
    Ascii(Text<'a>),
    Binary {
        src: &'a [u8],
        pos: usize,
        big: bool,
        path: &'a Path,
    },
}

impl Reader<'_> {
    /// The next value; a float that is not finite is an error unless
    /// `any` (normals, which are repaired instead).
    fn value(&mut self, ty: Scalar, what: &str, any: bool) -> Result<f64, MeshError> {
        match self {
            Reader::Ascii(t) => {
                let tok = t.token();
                if !any {
                    return t.number(tok, what);
                }
                match tok.and_then(crate::number::parse_f64) {
                    Some(v) => Ok(v),
                    None if tok.is_some() => Ok(f64::NAN),
                    None => t.number(tok, what),
                }
            }
            Reader::Binary {
                src,
                pos,
                big,
                path,
            } => {
                let n = ty.size();
                let Some(bytes) = src.get(*pos..*pos + n) else {
                    return Err(MeshError {
                        path: path.to_path_buf(),
                        at: Some(format!("byte {pos}")),
                        message: format!("the file ends inside {what}"),
                    });
                };
                *pos += n;
                let v = ty.decode(bytes, *big);
                if !v.is_finite() && !any {
                    return Err(self.error(format!("{what} is not a finite number")));
                }
                Ok(v)
            }
        }
    }

    fn loc(&mut self) -> Loc {
        match self {
            Reader::Ascii(t) => Loc::Line(t.next_token_line() as u64),
            Reader::Binary { pos, .. } => Loc::Byte(*pos as u64),
        }
    }

    fn error(&self, message: String) -> MeshError {
        match self {
            Reader::Ascii(t) => t.error(message),
            Reader::Binary { pos, path, .. } => MeshError {
                path: path.to_path_buf(),
                at: Some(format!("byte {pos}")),
                message,
            },
        }
    }
}

pub fn parse(src: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    parse_with(src, path, true)
}

/// `parse` by the general reader alone, for the tests that hold the fast
/// one to it.
#[cfg(test)]
pub(super) fn parse_general(src: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    parse_with(src, path, false)
}

/// Whether the fast reader took this file (for the tests).
#[cfg(test)]
pub(super) fn fast_took(src: &[u8], path: &Path) -> bool {
    let mut t = Text::new(src, path);
    t.token();
    match header(&mut t) {
        Ok((Encoding::Ascii, _)) | Err(_) => false,
        Ok((e, elements)) => {
            super::ply_fast::read(src, t.offset(), e == Encoding::Big, &elements).is_some()
        }
    }
}

fn parse_with(src: &[u8], path: &Path, fast: bool) -> Result<Mesh, MeshError> {
    let mut t = Text::new(src, path);
    if t.token() != Some(b"ply") {
        return Err(t.error("expected the header `ply`"));
    }
    let (encoding, elements) = header(&mut t)?;
    if fast && encoding != Encoding::Ascii {
        if let Some(mesh) =
            super::ply_fast::read(src, t.offset(), encoding == Encoding::Big, &elements)
        {
            return Ok(mesh);
        }
    }
    let mut r = match encoding {
        Encoding::Ascii => Reader::Ascii(t),
        e => Reader::Binary {
            src,
            pos: t.offset(),
            big: e == Encoding::Big,
            path,
        },
    };
    let mut b = Builder::new(path);
    for element in elements.iter().filter(|e| !e.properties.is_empty()) {
        read_element(&mut r, element, &mut b)?;
    }
    // PLY normals are per vertex: a face's corners use their vertices' own.
    if !b.mesh.normals.is_empty() {
        b.corner_normals_are_positions();
    }
    b.finish()
}

/// The header after `ply`, through `end_header`: the encoding and the
/// elements with their properties.
fn header(t: &mut Text) -> Result<(Encoding, Vec<Element>), MeshError> {
    t.next_line();
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let Some(key) = t.token() else {
            return Err(t.error("the header has no `end_header`"));
        };
        match key {
            b"format" => {
                encoding = Some(match t.token_on_line() {
                    Some(b"ascii") => Encoding::Ascii,
                    Some(b"binary_little_endian") => Encoding::Little,
                    Some(b"binary_big_endian") => Encoding::Big,
                    other => {
                        return Err(t.error(format!(
                            "unknown format `{}`",
                            String::from_utf8_lossy(other.unwrap_or_default())
                        )))
                    }
                });
            }
            b"element" => {
                let name = t.token_on_line().unwrap_or_default().to_vec();
                let tok = t.token_on_line();
                let count = t.integer(tok, "the element count")?;
                let count = usize::try_from(count)
                    .map_err(|_| t.error("an element count must not be negative"))?;
                elements.push(Element {
                    name,
                    count,
                    properties: Vec::new(),
                });
            }
            b"property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(t.error("a property before any element"));
                };
                let ty_name = t.token_on_line().unwrap_or_default();
                let unknown = |t: &Text, n: &[u8]| {
                    t.error(format!(
                        "unknown property type `{}`",
                        String::from_utf8_lossy(n)
                    ))
                };
                let property = if ty_name == b"list" {
                    let count_ty = t.token_on_line().unwrap_or_default();
                    let count = Scalar::parse(count_ty).ok_or_else(|| unknown(t, count_ty))?;
                    let item_ty = t.token_on_line().unwrap_or_default();
                    let item = Scalar::parse(item_ty).ok_or_else(|| unknown(t, item_ty))?;
                    Property {
                        name: t.token_on_line().unwrap_or_default().to_vec(),
                        list: Some(count),
                        ty: item,
                    }
                } else {
                    let ty = Scalar::parse(ty_name).ok_or_else(|| unknown(t, ty_name))?;
                    Property {
                        name: t.token_on_line().unwrap_or_default().to_vec(),
                        list: None,
                        ty,
                    }
                };
                element.properties.push(property);
            }
            b"end_header" => {
                t.next_line();
                break;
            }
            _ => {}
        }
        t.next_line();
    }
    let Some(encoding) = encoding else {
        return Err(t.error("the header has no `format` line"));
    };
    Ok((encoding, elements))
}

/// Every item of `element`: vertices' positions, normals and colours
/// into the mesh, faces' corner lists as polygons.
fn read_element(r: &mut Reader, element: &Element, b: &mut Builder) -> Result<(), MeshError> {
    let mut corners: Vec<u32> = Vec::new();
    let Roles {
        is_vertex,
        is_face,
        xyz,
        nxyz,
        rgb,
        indices,
        has_normals,
        has_colors,
        color_levels,
        repaired,
    } = Roles::of(element);
    if is_vertex && xyz.iter().any(Option::is_none) {
        return Err(r.error("the vertex element has no x, y and z".into()));
    }
    let is_strips = element.name == b"tristrips";
    if (is_face || is_strips) && indices.is_none() {
        let name = String::from_utf8_lossy(&element.name);
        return Err(r.error(format!("the {name} element has no vertex_indices list")));
    }
    let names: Vec<String> = element
        .properties
        .iter()
        .map(|p| String::from_utf8_lossy(&p.name).into_owned())
        .collect();
    let mut values = vec![0.0; element.properties.len()];
    for _ in 0..element.count {
        let at = r.loc();
        for (k, p) in element.properties.iter().enumerate() {
            let name = &names[k];
            match p.list {
                None => values[k] = r.value(p.ty, name, repaired[k])?,
                Some(count_ty) => {
                    let n = r.value(count_ty, &format!("the length of {name}"), false)?;
                    // A strip list holds a whole model; each item it
                    // claims must still be in the file, so memory stays
                    // bounded by the file's size.
                    let most = if is_strips { 4e9 } else { 1e6 };
                    if !(0.0..=most).contains(&n) || n.fract() != 0.0 {
                        return Err(r.error(format!("a list of {n} items in {name}")));
                    }
                    let take = (is_face || is_strips) && Some(k) == indices;
                    corners.clear();
                    for _ in 0..n as usize {
                        let v = r.value(p.ty, name, false)?;
                        if take && is_strips && v == -1.0 {
                            corners.push(RESTART);
                        } else if take {
                            if v < 0.0 || v.fract() != 0.0 {
                                return Err(r.error(format!(
                                    "vertex index {v} is not a whole number from 0"
                                )));
                            }
                            corners.push(v.min(f64::from(RESTART - 1)) as u32);
                        }
                    }
                    if take && is_strips {
                        if !strips(&corners, b, at) {
                            return Err(r.error("more than 4 billion face corners".into()));
                        }
                    } else if take {
                        if b.corner_count() + corners.len() >= u32::MAX as usize {
                            return Err(r.error("more than 4 billion face corners".into()));
                        }
                        b.polygon(corners.iter().map(|&c| (c, None)), None, at);
                    }
                }
            }
        }
        if is_vertex {
            let get = |i: [Option<usize>; 3]| i.map(|k| values[k.unwrap_or(0)]);
            b.mesh.positions.push(DVec3::from(get(xyz)));
            if has_normals {
                b.mesh.normals.push(DVec3::from(get(nxyz)));
            }
            if has_colors {
                b.mesh.colors.push(DVec3::from(get(rgb)) / color_levels);
            }
        }
    }
    Ok(())
}

/// A `tristrips` list's restart (its `-1`).
const RESTART: u32 = u32::MAX;

/// A `tristrips` list as triangles: each run between restarts makes one
/// from every three vertices in a row, every second one turned so that all
/// wind alike. Triangles that repeat a vertex are how strips turn corners
/// and join: they are skipped without a warning. False past 4 billion
/// corners.
fn strips(items: &[u32], b: &mut Builder, at: Loc) -> bool {
    for run in items.split(|&i| i == RESTART) {
        for (k, w) in run.windows(3).enumerate() {
            let t = if k % 2 == 0 {
                [w[0], w[1], w[2]]
            } else {
                [w[1], w[0], w[2]]
            };
            if t[0] == t[1] || t[1] == t[2] || t[2] == t[0] {
                continue;
            }
            if b.corner_count() + 3 >= u32::MAX as usize {
                return false;
            }
            b.polygon(t.map(|c| (c, None)), None, at);
        }
    }
    true
}
