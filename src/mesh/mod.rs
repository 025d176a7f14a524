//! Triangle meshes from model files (Wavefront OBJ with its MTL materials,
//! PLY in ASCII and binary, OFF), for the scene format's `mesh` block.
//!
//! Every reader produces a `Mesh`: positions, optional per-vertex normals
//! and colours, and faces as triangles (polygons fanned from their first
//! corner, which is right for the convex polygons these formats hold).
//! Errors name the file and the line (byte offset in binary PLY).

mod obj;
mod off;
mod ply;

use std::fmt;
use std::path::{Path, PathBuf};

use glam::DVec3;

use crate::scene::Material;

/// One triangle of a mesh: indices into the mesh's positions, and where the
/// file gives them per corner, into its normals; its material, if the file
/// assigns one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Face {
    pub positions: [u32; 3],
    pub normals: Option<[u32; 3]>,
    pub material: Option<u32>,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<DVec3>,
    /// The file's normals (OBJ `vn`, PLY `nx ny nz`, OFF `NOFF`).
    pub normals: Vec<DVec3>,
    /// Per position, linear [0, 1] RGB, when the file has vertex colours.
    pub colors: Vec<DVec3>,
    pub faces: Vec<Face>,
    /// Materials the file defines (OBJ `usemtl` from its `mtllib`).
    pub materials: Vec<Material>,
}

/// What is wrong in a model file, and where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MeshError {
    pub path: PathBuf,
    /// "line 12" or "byte 4096".
    pub at: Option<String>,
    pub message: String,
}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.at {
            Some(at) => write!(f, "{}, {at}: {}", self.path.display(), self.message),
            None => write!(f, "{}: {}", self.path.display(), self.message),
        }
    }
}

impl std::error::Error for MeshError {}

/// The model formats, by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Obj,
    Ply,
    Off,
}

impl Format {
    pub fn of(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(Format::Obj),
            "ply" => Some(Format::Ply),
            "off" => Some(Format::Off),
            _ => None,
        }
    }
}

/// Reads a model file, its format chosen by extension.
pub fn load(path: &Path) -> Result<Mesh, MeshError> {
    let error = |message: String| MeshError {
        path: path.to_path_buf(),
        at: None,
        message,
    };
    let format = Format::of(path)
        .ok_or_else(|| error("unknown model format; use an .obj, .ply or .off file".to_string()))?;
    let bytes = std::fs::read(path).map_err(|e| error(format!("cannot read it: {e}")))?;
    let mesh = match format {
        Format::Obj => obj::parse(&bytes, path)?,
        Format::Ply => ply::parse(&bytes, path)?,
        Format::Off => off::parse(&bytes, path)?,
    };
    mesh.check(path)?;
    Ok(mesh)
}

impl Mesh {
    /// Every index in range (the readers check as they go; this is the
    /// last word).
    fn check(&self, path: &Path) -> Result<(), MeshError> {
        let np = self.positions.len() as u32;
        let nn = self.normals.len() as u32;
        let nm = self.materials.len() as u32;
        for (i, f) in self.faces.iter().enumerate() {
            let bad = f.positions.iter().any(|&p| p >= np)
                || f.normals.is_some_and(|n| n.iter().any(|&k| k >= nn))
                || f.material.is_some_and(|m| m >= nm);
            if bad {
                return Err(MeshError {
                    path: path.to_path_buf(),
                    at: None,
                    message: format!(
                        "face {i} refers to a vertex, normal or material it does not define"
                    ),
                });
            }
        }
        if !self.colors.is_empty() && self.colors.len() != self.positions.len() {
            return Err(MeshError {
                path: path.to_path_buf(),
                at: None,
                message: "some vertices have colours and others not".into(),
            });
        }
        Ok(())
    }

    /// Smooth normals per position, for files that bring none: each face's
    /// unit normal weighted by the angle of its corner at the vertex
    /// (Thürmer and Wüthrich), which, unlike area weights, does not depend
    /// on how a surface is cut into triangles. Zero where every face at a
    /// vertex is degenerate (the renderers then use the flat normal).
    pub fn smooth_normals(&self) -> Vec<DVec3> {
        let mut sums = vec![DVec3::ZERO; self.positions.len()];
        for f in &self.faces {
            let p = f.positions.map(|i| self.positions[i as usize]);
            let n = (p[1] - p[0]).cross(p[2] - p[0]);
            let len = n.length();
            if len == 0.0 || !len.is_finite() {
                continue;
            }
            let n = n / len;
            for k in 0..3 {
                let a = p[(k + 1) % 3] - p[k];
                let b = p[(k + 2) % 3] - p[k];
                let angle = a.angle_between(b);
                if angle.is_finite() {
                    sums[f.positions[k] as usize] += n * angle;
                }
            }
        }
        sums.into_iter()
            .map(|s| s.try_normalize().unwrap_or(DVec3::ZERO))
            .collect()
    }

    /// The mesh as scene triangles, each vertex placed by `place` and its
    /// normal turned by `turn` (then normalized as the classic parser
    /// does, `unit`). A face's material is
    /// `material` if given, else the file's for it, else (a file with
    /// vertex colours only) black with no highlight; a vertex colour, where
    /// the file has them, is the diffuse colour. Normals are the file's,
    /// else `smooth_normals`. Callers check that every face has a material
    /// (`missing_material`). `material_id` gives a material's index in the
    /// scene's table (`Scene::add_material`, `MaterialIds`).
    pub fn triangles(
        &self,
        material: Option<Material>,
        place: impl Fn(DVec3) -> DVec3,
        turn: impl Fn(DVec3) -> DVec3,
        mut material_id: impl FnMut(Material) -> u32,
    ) -> Vec<crate::scene::Triangle> {
        use crate::scene::{Triangle, Vertex};
        let smooth = if self.normals.is_empty() {
            self.smooth_normals()
        } else {
            Vec::new()
        };
        self.faces
            .iter()
            .map(|f| {
                let base = material
                    .or_else(|| f.material.map(|m| self.materials[m as usize]))
                    .unwrap_or(Material {
                        kd: DVec3::ZERO,
                        ks: DVec3::ZERO,
                        shininess: 1.0,
                    });
                let vertices = [0, 1, 2].map(|k| {
                    let p = f.positions[k] as usize;
                    let n = match f.normals {
                        Some(ns) => self.normals[ns[k] as usize],
                        None => smooth[p],
                    };
                    let mut m = base;
                    if let Some(c) = self.colors.get(p) {
                        m.kd = *c;
                    }
                    Vertex {
                        position: place(self.positions[p]),
                        normal: unit(turn(n)),
                        material: material_id(m),
                    }
                });
                Triangle {
                    vertices,
                    velocity: DVec3::ZERO,
                }
            })
            .collect()
    }

    /// Whether some face would have no material without one given: the
    /// file has no vertex colours and no material for it.
    pub fn missing_material(&self) -> bool {
        self.colors.is_empty() && self.faces.iter().any(|f| f.material.is_none())
    }

    pub fn bounds(&self) -> crate::scene::Bounds {
        self.positions
            .iter()
            .fold(crate::scene::Bounds::EMPTY, |b, &p| b.grow(p))
    }
}

/// A normal as the classic parser keeps one: as written when it is unit to
/// within 1e-3 (so a mesh and the same triangles written as classic blocks
/// render bit for bit alike), else normalized; zero stays zero (the flat
/// normal is used there).
fn unit(n: DVec3) -> DVec3 {
    if (n.length() - 1.0).abs() <= 1e-3 {
        n
    } else {
        n.try_normalize().unwrap_or(DVec3::ZERO)
    }
}

/// A cursor over a text model file: whitespace-separated tokens, `#`
/// comments to the end of the line, line numbers for messages.
pub(crate) struct Text<'a> {
    src: &'a [u8],
    pos: usize,
    line: usize,
    path: &'a Path,
}

impl<'a> Text<'a> {
    pub fn new(src: &'a [u8], path: &'a Path) -> Text<'a> {
        Text {
            src,
            pos: 0,
            line: 1,
            path,
        }
    }

    pub fn error(&self, message: impl Into<String>) -> MeshError {
        MeshError {
            path: self.path.to_path_buf(),
            at: Some(format!("line {}", self.line)),
            message: message.into(),
        }
    }

    /// The next token, crossing line ends; None at the end of the file.
    pub fn token(&mut self) -> Option<&'a [u8]> {
        loop {
            self.skip_blanks();
            match self.src.get(self.pos) {
                None => return None,
                Some(b'\n') => {
                    self.pos += 1;
                    self.line += 1;
                }
                Some(_) => return self.word(),
            }
        }
    }

    /// The next token on this line; None at its end (the line end is not
    /// consumed).
    pub fn token_on_line(&mut self) -> Option<&'a [u8]> {
        self.skip_blanks();
        match self.src.get(self.pos) {
            None | Some(b'\n') => None,
            Some(_) => self.word(),
        }
    }

    /// Moves past the end of the current line.
    pub fn next_line(&mut self) {
        while let Some(&c) = self.src.get(self.pos) {
            self.pos += 1;
            if c == b'\n' {
                self.line += 1;
                return;
            }
        }
    }

    /// Where the cursor is, in bytes (binary PLY data starts here).
    pub fn offset(&self) -> usize {
        self.pos
    }

    /// The rest of the line, trimmed (for names with spaces).
    pub fn rest_of_line(&mut self) -> &'a [u8] {
        let start = self.pos;
        while let Some(&c) = self.src.get(self.pos) {
            if c == b'\n' || c == b'#' {
                break;
            }
            self.pos += 1;
        }
        self.src[start..self.pos].trim_ascii()
    }

    fn skip_blanks(&mut self) {
        while let Some(&c) = self.src.get(self.pos) {
            match c {
                b' ' | b'\t' | b'\r' | b'\x0c' | b'\x0b' => self.pos += 1,
                b'#' => {
                    while self.src.get(self.pos).is_some_and(|&c| c != b'\n') {
                        self.pos += 1;
                    }
                }
                _ => return,
            }
        }
    }

    fn word(&mut self) -> Option<&'a [u8]> {
        let start = self.pos;
        while let Some(&c) = self.src.get(self.pos) {
            if c.is_ascii_whitespace() || c == b'#' {
                break;
            }
            self.pos += 1;
        }
        Some(&self.src[start..self.pos])
    }

    /// A finite number token, or an error saying what was expected.
    pub fn number(&mut self, tok: Option<&[u8]>, what: &str) -> Result<f64, MeshError> {
        let Some(t) = tok else {
            return Err(self.error(format!("expected {what}, found the end of the line")));
        };
        match crate::scene::number::parse_f64(t) {
            Some(v) if v.is_finite() && v.abs() <= f64::from(f32::MAX) => Ok(v),
            _ => Err(self.error(format!(
                "expected {what}, found `{}`",
                String::from_utf8_lossy(t)
            ))),
        }
    }

    /// A whole number token.
    pub fn integer(&mut self, tok: Option<&[u8]>, what: &str) -> Result<i64, MeshError> {
        let Some(t) = tok else {
            return Err(self.error(format!("expected {what}, found the end of the file")));
        };
        std::str::from_utf8(t)
            .ok()
            .and_then(|s| s.parse::<i64>().ok())
            .ok_or_else(|| {
                self.error(format!(
                    "expected {what}, found `{}`",
                    String::from_utf8_lossy(t)
                ))
            })
    }
}

/// Fans a polygon's corners into triangles (corner 0, k, k + 1).
pub(crate) fn fan<T: Copy>(corners: &[T], mut emit: impl FnMut([T; 3])) {
    for k in 1..corners.len().saturating_sub(1) {
        emit([corners[0], corners[k], corners[k + 1]]);
    }
}

/// The faces the file defines, for writing a scene back as OBJ
/// (`glint convert`): see `write_obj`.
pub use obj::write_obj;
