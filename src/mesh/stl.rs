//! STL, ASCII and binary (told apart by content in `source`: binary files
//! often begin with `solid` too). Triangles only, no materials; vertices
//! at the same position are joined, and normals come from the vertices
//! (`smooth_normals`), never from the facet normals, which writers often
//! get wrong. An ASCII file may hold several solids, and a facet with more
//! than three vertices is read as a polygon.

use std::collections::HashMap;
use std::path::Path;

use glam::DVec3;

use super::build::{Builder, Loc};
use super::text::Text;
use super::{Mesh, MeshError};

/// Joins vertices at the same position (bit for bit), so faces share
/// corners and smooth normals span them.
/// Hashed with foldhash, not SipHash: the keys are a file's own
/// coordinates, and welding 6M corners with SipHash took most of a 2M
/// triangle file's load (1.0 s of 1.3 s, 2 cores).
struct Weld {
    index: HashMap<[u64; 3], u32, foldhash::fast::RandomState>,
}

impl Weld {
    /// Room for `vertices` (a guess: a closed mesh has about half as
    /// many vertices as triangles), so the table is not grown and rehashed
    /// as it fills.
    fn new(vertices: usize) -> Weld {
        let mut index = HashMap::with_hasher(foldhash::fast::RandomState::default());
        index.reserve(vertices);
        Weld { index }
    }

    fn vertex(&mut self, b: &mut Builder, p: DVec3) -> u32 {
        let next = b.mesh.positions.len() as u32;
        *self
            .index
            .entry(p.to_array().map(f64::to_bits))
            .or_insert_with(|| {
                b.mesh.positions.push(p);
                next
            })
    }
}

/// Binary STL: an 80-byte header, a little-endian triangle count, then per
/// triangle a normal, three vertices (f32 each) and a 2-byte attribute.
pub fn parse_binary(src: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    let error = |at: usize, message: String| MeshError {
        path: path.to_path_buf(),
        at: Some(format!("byte {at}")),
        message,
    };
    let Some(count) = src.get(80..84) else {
        return Err(error(src.len(), "too short for a binary STL header".into()));
    };
    let count = u32::from_le_bytes([count[0], count[1], count[2], count[3]]) as usize;
    let mut b = Builder::new(path);
    // The count is the file's word: room only for what the bytes hold.
    let triangles = count.min(src.len().saturating_sub(84) / 50);
    let mut weld = Weld::new(triangles / 2 + 3);
    for i in 0..count {
        let at = 84 + 50 * i;
        let Some(tri) = src.get(at..at + 50) else {
            return Err(error(
                src.len(),
                format!("the file ends inside triangle {} of {count}", i + 1),
            ));
        };
        let f = |k: usize| {
            let o = 12 + 4 * k;
            f64::from(f32::from_le_bytes([
                tri[o],
                tri[o + 1],
                tri[o + 2],
                tri[o + 3],
            ]))
        };
        let mut corners = [0u32; 3];
        for (v, c) in corners.iter_mut().enumerate() {
            // A vertex that is not finite drops its face in `build`.
            let p = DVec3::new(f(3 * v), f(3 * v + 1), f(3 * v + 2));
            *c = weld.vertex(&mut b, p);
        }
        b.polygon(corners.map(|c| (c, None)), None, Loc::Byte(at as u64));
    }
    b.finish()
}

/// ASCII STL: `solid`, then `facet normal ...`, `outer loop`, `vertex x y
/// z` three times, `endloop`, `endfacet`, ..., `endsolid`; repeated for
/// each solid.
pub fn parse_ascii(src: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    let mut t = Text::new(src, path);
    let mut b = Builder::new(path);
    let mut weld = Weld::new(0);
    let mut corners: Vec<(u32, Option<u32>)> = Vec::new();
    let mut facet_line = 0u64;
    while let Some(key) = t.token() {
        let key = key.to_ascii_lowercase();
        match key.as_slice() {
            b"solid" | b"endsolid" => {
                t.rest_of_line();
            }
            b"facet" => {
                facet_line = t.line() as u64;
                corners.clear();
                // The facet normal is not used.
                t.rest_of_line();
            }
            b"vertex" => {
                let mut v = [0.0; 3];
                for (k, c) in v.iter_mut().enumerate() {
                    let tok = t.token_on_line();
                    *c = t.number(tok, ["x", "y", "z"][k])?;
                }
                if corners.len() >= 1 << 20 {
                    return Err(t.error("a facet of over a million vertices"));
                }
                corners.push((weld.vertex(&mut b, DVec3::from(v)), None));
            }
            b"endfacet" => {
                if b.corner_count() + corners.len() >= u32::MAX as usize {
                    return Err(t.error("more than 4 billion corners"));
                }
                b.polygon(corners.drain(..), None, Loc::Line(facet_line));
            }
            _ => {}
        }
    }
    b.finish()
}
