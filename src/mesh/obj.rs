//! Wavefront OBJ: `v x y z [w | r g b]`, `vn`, `f` with `v`, `v/vt`,
//! `v//vn` or `v/vt/vn` corners (negative indices count back from the
//! last), `mtllib` and `usemtl` (`mtl`). Texture coordinates, groups and
//! smoothing groups are read past; points and lines (`p`, `l`) are not
//! surfaces and are skipped with a warning.
//!
//! Tolerated, with a warning: a material no library defines or a library
//! that cannot be read (the `mesh` block's material, else the default),
//! normals given but never used, faces that give normals for some corners
//! only, vertex colours on some vertices only.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::DVec3;

use super::build::{Builder, Loc};
use super::report::Tolerance;
use super::text::{show, Text};
use super::{Mesh, MeshError, Refs};

pub fn parse(src: &[u8], path: &Path, refs: Refs) -> Result<Mesh, MeshError> {
    if let Some(p) = super::obj_fast::read(src) {
        let mesh = Mesh {
            positions: p.positions,
            normals: p.normals,
            ..Mesh::default()
        };
        return Builder::from_polygons(path, mesh, p.corners, &p.polygons).finish();
    }
    parse_general(src, path, refs)
}

/// `parse` by the general reader alone: every line in turn.
pub(super) fn parse_general(src: &[u8], path: &Path, refs: Refs) -> Result<Mesh, MeshError> {
    let mut t = Text::new(src, path);
    let mut b = Builder::new(path);
    let mut names: HashMap<String, u32> = HashMap::new();
    let mut current: Option<u32> = None;
    let mut corners: Vec<(u32, Option<u32>)> = Vec::new();
    let mut colors: Vec<Option<DVec3>> = Vec::new();
    let mut colored = 0usize;
    while let Some(key) = t.token() {
        match key {
            b"v" => {
                let mut v = [0.0; 3];
                for (k, c) in v.iter_mut().enumerate() {
                    let tok = t.token_on_line();
                    // `nan` and `inf` are numbers too: their faces are
                    // dropped by `build`, with a warning.
                    if let Some(v) = tok
                        .and_then(crate::number::parse_f64)
                        .filter(|v| !v.is_finite())
                    {
                        *c = v;
                        continue;
                    }
                    let (value, cut) = t.number_lenient(tok, ["x", "y", "z"][k])?;
                    if cut {
                        b.warn(
                            Tolerance::Number,
                            t.at(),
                            format!(
                                "the malformed number {} is read as {value}",
                                show(tok.unwrap_or_default())
                            ),
                        );
                    }
                    *c = value;
                }
                b.mesh.positions.push(DVec3::from(v));
                // `v x y z r g b`: a vertex colour (a fourth value alone is w).
                let extra: Vec<&[u8]> = std::iter::from_fn(|| t.token_on_line()).take(4).collect();
                if extra.len() >= 3 {
                    let mut rgb = [0.0; 3];
                    for (c, tok) in rgb.iter_mut().zip(&extra) {
                        *c = t.number(Some(tok), "a colour component")?;
                    }
                    colors.push(Some(DVec3::from(rgb)));
                    colored += 1;
                } else {
                    colors.push(None);
                }
            }
            b"vn" => {
                // Repaired rather than refused: a normal that is not a
                // finite number becomes the smooth normal (`build`).
                let n = [0, 1, 2].map(|_| Text::number_or_nan(t.token_on_line()));
                b.mesh.normals.push(DVec3::from(n));
            }
            b"f" | b"fo" => {
                corners.clear();
                while let Some(tok) = t.token_on_line() {
                    corners.push(corner(&t, tok, &b.mesh)?);
                }
                b.polygon(corners.iter().copied(), current, Loc::Line(t.line() as u64));
            }
            b"p" | b"l" => {
                let what = if key == b"p" { "points" } else { "a line" };
                b.warn(
                    Tolerance::NotSurface,
                    t.at(),
                    format!("{what} (`{}`), not a surface, skipped", key[0] as char),
                );
            }
            b"mtllib" => {
                let line = String::from_utf8_lossy(t.rest_of_line()).into_owned();
                read_libraries(&mut b, &t, &line, refs, &mut names)?;
            }
            b"usemtl" => {
                let name = String::from_utf8_lossy(t.rest_of_line()).into_owned();
                current = names.get(&name).copied();
                if current.is_none() {
                    b.warn(
                        Tolerance::UndefinedMaterial,
                        t.at(),
                        format!(
                            "material `{name}` is defined by no material library read before \
                             it; its faces take the mesh block's material, else the default"
                        ),
                    );
                }
            }
            _ => {}
        }
        t.next_line();
    }
    if colored == colors.len() {
        b.mesh.colors = colors.into_iter().flatten().collect();
    } else if colored > 0 {
        b.warn(
            Tolerance::PartialColors,
            None,
            format!(
                "{colored} of {} vertices have colours (`v x y z r g b`); vertex colours are \
                 ignored",
                colors.len()
            ),
        );
    }
    b.finish()
}

/// `mtllib` names one library, or several separated by spaces (a name
/// with spaces is tried whole first). Windows paths (`..\mat\a.mtl`) are
/// tried with `/` too.
fn read_libraries(
    b: &mut Builder,
    t: &Text,
    line: &str,
    refs: Refs,
    names: &mut HashMap<String, u32>,
) -> Result<(), MeshError> {
    let base = b.path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let whole = vec![line.to_string()];
    let split: Vec<String> = line.split_whitespace().map(str::to_string).collect();
    let mut last_error = String::from("no file name");
    for group in [whole, split] {
        let mut read = 0;
        for name in &group {
            match read_library(&base, name, refs) {
                Ok((file, text)) => {
                    let mut report = std::mem::take(&mut b.mesh.report);
                    super::mtl::read(&text, &file, &mut b.mesh.materials, names, &mut report)?;
                    b.mesh.report = report;
                    read += 1;
                }
                Err(e) => last_error = e,
            }
        }
        if read > 0 {
            return Ok(());
        }
    }
    b.warn(
        Tolerance::MissingLibrary,
        t.at(),
        format!(
            "cannot read the material library `{line}` ({last_error}); faces using its \
             materials take the mesh block's material, else the default"
        ),
    );
    Ok(())
}

fn read_library(base: &Path, name: &str, refs: Refs) -> Result<(PathBuf, Vec<u8>), String> {
    if name.is_empty() {
        return Err("no file name".into());
    }
    if refs == Refs::None {
        return Err("files a model refers to are not read here".into());
    }
    let mut candidates = vec![base.join(name)];
    if name.contains('\\') {
        candidates.push(base.join(name.replace('\\', "/")));
    }
    let mut last = String::new();
    for file in candidates {
        let kind = crate::input::Kind::Text {
            what: "material library",
        };
        match super::source::read_referenced(&file, kind) {
            Ok(bytes) => return Ok((file, bytes)),
            Err(e) => last = format!("{}: {e}", file.display()),
        }
    }
    Err(last)
}

/// One `f` corner: `v`, `v/vt`, `v//vn` or `v/vt/vn`, 1-based or negative.
fn corner(t: &Text, tok: &[u8], mesh: &Mesh) -> Result<(u32, Option<u32>), MeshError> {
    let mut parts = tok.split(|&c| c == b'/');
    let resolve = |part: &[u8], count: usize, what: &str| -> Result<u32, MeshError> {
        let i: i64 = std::str::from_utf8(part)
            .ok()
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| {
                t.error(format!(
                    "expected a {what} index in the face corner {}",
                    show(tok)
                ))
            })?;
        let index = if i < 0 {
            (count as i64).saturating_add(i)
        } else {
            i - 1
        };
        if i == 0 || index < 0 || index >= count as i64 {
            return Err(t.error(format!(
                "{what} index {i} refers to none of the {count} defined so far"
            )));
        }
        Ok(index as u32)
    };
    let v = resolve(
        parts.next().unwrap_or_default(),
        mesh.positions.len(),
        "vertex",
    )?;
    let _texture = parts.next();
    let n = match parts.next() {
        Some(p) if !p.is_empty() => Some(resolve(p, mesh.normals.len(), "normal")?),
        _ => None,
    };
    Ok((v, n))
}
