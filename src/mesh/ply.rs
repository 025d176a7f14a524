//! PLY (Stanford polygon files), ASCII and binary of either byte order:
//! the `vertex` element's `x y z`, optional `nx ny nz` and `red green blue`
//! (integers 0-255 or floats 0-1), and the `face` element's
//! `vertex_indices` (or `vertex_index`) lists. Other elements and
//! properties are read past. Normals that are not finite are repaired
//! (`build`), as are degenerate faces; a file of points only loads with a
//! warning from the scene.

use std::path::Path;

use glam::DVec3;

use super::build::{Builder, Loc};
use super::text::Text;
use super::{Mesh, MeshError};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &[u8]) -> Option<Scalar> {
        Some(match name {
            b"char" | b"int8" => Scalar::I8,
            b"uchar" | b"uint8" => Scalar::U8,
            b"short" | b"int16" => Scalar::I16,
            b"ushort" | b"uint16" => Scalar::U16,
            b"int" | b"int32" => Scalar::I32,
            b"uint" | b"uint32" => Scalar::U32,
            b"float" | b"float32" => Scalar::F32,
            b"double" | b"float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

#[derive(Clone, Debug)]
struct Property {
    name: Vec<u8>,
    /// For a list: the count's type, then the items' type.
    list: Option<Scalar>,
    ty: Scalar,
}

#[derive(Clone, Debug)]
struct Element {
    name: Vec<u8>,
    count: usize,
    properties: Vec<Property>,
}

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
                let mut b = [0u8; 8];
                b[..n].copy_from_slice(bytes);
                if *big {
                    b[..n].reverse();
                }
                *pos += n;
                let v = match ty {
                    Scalar::I8 => f64::from(b[0] as i8),
                    Scalar::U8 => f64::from(b[0]),
                    Scalar::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
                    Scalar::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
                    Scalar::I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                    Scalar::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                    Scalar::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                    Scalar::F64 => f64::from_le_bytes(b),
                };
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
    let mut t = Text::new(src, path);
    if t.token() != Some(b"ply") {
        return Err(t.error("expected the header `ply`"));
    }
    let (encoding, elements) = header(&mut t)?;
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
    let is_vertex = element.name == b"vertex";
    let is_face = element.name == b"face";
    let find = |n: &[&[u8]]| {
        element
            .properties
            .iter()
            .position(|p| n.contains(&p.name.as_slice()))
    };
    let xyz = [find(&[b"x"]), find(&[b"y"]), find(&[b"z"])];
    let nxyz = [find(&[b"nx"]), find(&[b"ny"]), find(&[b"nz"])];
    let rgb = [
        find(&[b"red", b"r", b"diffuse_red"]),
        find(&[b"green", b"g", b"diffuse_green"]),
        find(&[b"blue", b"b", b"diffuse_blue"]),
    ];
    let indices = find(&[b"vertex_indices", b"vertex_index"]);
    if is_vertex && xyz.iter().any(Option::is_none) {
        return Err(r.error("the vertex element has no x, y and z".into()));
    }
    if is_face && indices.is_none() {
        return Err(r.error("the face element has no vertex_indices list".into()));
    }
    let has_normals = is_vertex && nxyz.iter().all(Option::is_some);
    let has_colors = is_vertex && rgb.iter().all(Option::is_some);
    // Non-finite normals and positions are repaired or dropped by
    // `build`, with warnings; other values must be finite.
    let repaired: Vec<bool> = (0..element.properties.len())
        .map(|k| (has_normals && nxyz.contains(&Some(k))) || (is_vertex && xyz.contains(&Some(k))))
        .collect();
    // Integer colours are 0-255 levels, float ones 0-1.
    let color_levels = rgb[0].map_or(1.0, |i| {
        if element.properties[i].ty.is_integer() {
            255.0
        } else {
            1.0
        }
    });
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
                    if !(0.0..=1e6).contains(&n) || n.fract() != 0.0 {
                        return Err(r.error(format!("a list of {n} items in {name}")));
                    }
                    let take = is_face && Some(k) == indices;
                    corners.clear();
                    for _ in 0..n as usize {
                        let v = r.value(p.ty, name, false)?;
                        if take {
                            if v < 0.0 || v.fract() != 0.0 {
                                return Err(r.error(format!(
                                    "vertex index {v} is not a whole number from 0"
                                )));
                            }
                            corners.push(v.min(f64::from(u32::MAX)) as u32);
                        }
                    }
                    if take {
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
