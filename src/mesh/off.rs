//! OFF (Geomview's Object File Format, as CGAL writes it): a header `OFF`
//! (`COFF` with vertex colours, `NOFF` with normals, `CNOFF` both, `ST`
//! texture coordinates read past), the counts of vertices, faces and
//! edges, one vertex per line, then one face per line as its corner count
//! and indices. Per-face colours are read past and not used.

use std::path::Path;

use glam::DVec3;

use super::build::{Builder, Loc};
use super::text::{show, Text};
use super::{Mesh, MeshError};

pub fn parse(src: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    let mut t = Text::new(src, path);
    let header = t.token().unwrap_or_default();
    let name = String::from_utf8_lossy(header).to_ascii_uppercase();
    let Some(flags) = name.strip_suffix("OFF") else {
        return Err(t.error(format!("expected the header `OFF`, found {}", show(header))));
    };
    let flags = flags.strip_prefix("ST").unwrap_or(flags);
    let (has_colors, has_normals) = (flags.contains('C'), flags.contains('N'));
    if flags.chars().any(|c| !matches!(c, 'C' | 'N')) {
        return Err(t.error(format!(
            "unsupported OFF variant `{name}` (read: OFF, COFF, NOFF, CNOFF)"
        )));
    }
    let count = |t: &mut Text, what: &str| -> Result<usize, MeshError> {
        let tok = t.token();
        let v = t.integer(tok, what)?;
        usize::try_from(v).map_err(|_| t.error(format!("{what} must not be negative, found {v}")))
    };
    let nv = count(&mut t, "the vertex count")?;
    let nf = count(&mut t, "the face count")?;
    let _edges = count(&mut t, "the edge count")?;
    t.next_line();
    let mut b = Builder::new(path);
    // Counts come from the file: reserve no more than its size can hold.
    b.mesh.positions.reserve(nv.min(src.len() / 6));
    for _ in 0..nv {
        let mut v = [0.0; 3];
        for (k, c) in v.iter_mut().enumerate() {
            let tok = t.token();
            *c = t.number(tok, ["x", "y", "z"][k])?;
        }
        b.mesh.positions.push(DVec3::from(v));
        if has_normals {
            let n = [0, 1, 2].map(|_| Text::number_or_nan(t.token_on_line()));
            b.mesh.normals.push(DVec3::from(n));
        }
        if has_colors {
            let mut rgb = [0.0; 3];
            for c in &mut rgb {
                let tok = t.token_on_line();
                *c = t.number(tok, "a colour component")?;
            }
            b.mesh.colors.push(DVec3::from(rgb));
        }
        t.next_line();
    }
    // Colours are 0-255 integers or 0-1 floats; one value above 1 says which.
    if b.mesh.colors.iter().any(|c| c.max_element() > 1.0) {
        for c in &mut b.mesh.colors {
            *c /= 255.0;
        }
    }
    let mut corners: Vec<u32> = Vec::new();
    for _ in 0..nf {
        let tok = t.token();
        let n = t.integer(tok, "a face's corner count")?;
        if !(0..=1_000_000).contains(&n) {
            return Err(t.error(format!(
                "a face of {n} corners (from 0 to a million are read)"
            )));
        }
        let at = Loc::Line(t.line() as u64);
        corners.clear();
        for _ in 0..n {
            let tok = t.token_on_line();
            let i = t.integer(tok, "a vertex index")?;
            if i < 0 || i as usize >= nv {
                return Err(t.error(format!("vertex index {i} is outside 0..{nv}")));
            }
            corners.push(i as u32);
        }
        if b.corner_count() + corners.len() >= u32::MAX as usize {
            return Err(t.error("more than 4 billion face corners"));
        }
        b.polygon(corners.iter().map(|&c| (c, None)), None, at);
        t.next_line();
    }
    if has_normals {
        b.corner_normals_are_positions();
    }
    // Trailing data (some writers append edges) is not read.
    b.finish()
}
