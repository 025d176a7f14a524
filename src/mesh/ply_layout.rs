//! What a PLY header declares: elements, their properties and the scalar
//! types of both, and what each property is for (`Roles`), shared by the
//! general reader (`ply`) and the one for the common binary layout
//! (`ply_fast`).

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Scalar {
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
    pub(super) fn parse(name: &[u8]) -> Option<Scalar> {
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

    pub(super) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// The value in the first `size()` bytes of `bytes` (which holds at
    /// least that many), as f64: exact for every type.
    #[inline]
    pub(super) fn decode(self, bytes: &[u8], big: bool) -> f64 {
        let mut b = [0u8; 8];
        let n = self.size();
        b[..n].copy_from_slice(&bytes[..n]);
        if big {
            b[..n].reverse();
        }
        match self {
            Scalar::I8 => f64::from(b[0] as i8),
            Scalar::U8 => f64::from(b[0]),
            Scalar::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            Scalar::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            Scalar::I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::F64 => f64::from_le_bytes(b),
        }
    }

    pub(super) fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

#[derive(Clone, Debug)]
pub(super) struct Property {
    pub name: Vec<u8>,
    /// For a list: the count's type, then the items' type.
    pub list: Option<Scalar>,
    pub ty: Scalar,
}

#[derive(Clone, Debug)]
pub(super) struct Element {
    pub name: Vec<u8>,
    pub count: usize,
    pub properties: Vec<Property>,
}

/// What each property of an element is for: which hold a vertex's
/// position, normal and colour, and which list a face's corners.
pub(super) struct Roles {
    pub is_vertex: bool,
    pub is_face: bool,
    pub xyz: [Option<usize>; 3],
    pub nxyz: [Option<usize>; 3],
    pub rgb: [Option<usize>; 3],
    pub indices: Option<usize>,
    pub has_normals: bool,
    pub has_colors: bool,
    /// Integer colours are 0-255 levels, float ones 0-1.
    pub color_levels: f64,
    /// Per property: non-finite values are repaired or dropped by `build`
    /// with warnings (normals, positions); other values must be finite.
    pub repaired: Vec<bool>,
}

impl Roles {
    pub fn of(element: &Element) -> Roles {
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
        let has_normals = is_vertex && nxyz.iter().all(Option::is_some);
        let repaired = (0..element.properties.len())
            .map(|k| {
                (has_normals && nxyz.contains(&Some(k))) || (is_vertex && xyz.contains(&Some(k)))
            })
            .collect();
        let color_levels = rgb[0].map_or(1.0, |i| {
            if element.properties[i].ty.is_integer() {
                255.0
            } else {
                1.0
            }
        });
        Roles {
            is_vertex,
            is_face,
            xyz,
            nxyz,
            rgb,
            indices: find(&[b"vertex_indices", b"vertex_index"]),
            has_normals,
            has_colors: is_vertex && rgb.iter().all(Option::is_some),
            color_levels,
            repaired,
        }
    }
}
