//! Triangle meshes from model files, for the scene format's `mesh` block:
//! Wavefront OBJ with its MTL materials, PLY (ASCII and binary), OFF, STL
//! (ASCII and binary) and glTF 2.0 (`.gltf` and `.glb`).
//!
//! Every reader produces a `Mesh`: positions, optional per-vertex normals
//! and colours, and faces as triangles (`build`: convex polygons fanned
//! from their first corner, concave ones ear clipped). Input is read with
//! bounded memory (`source`). Errors name the file and the line (byte
//! offset in binary files, JSON path in glTF); what a reader tolerates
//! instead of refusing, as mainstream importers do, is in the mesh's
//! `report`, never silent.

mod build;
mod gltf;
mod mtl;
mod obj;
mod obj_fast;
mod off;
mod ply;
mod ply_fast;
mod ply_layout;
mod polygon;
pub mod report;
mod source;
mod stl;
mod text;

use std::fmt;
use std::path::{Path, PathBuf};

use glam::DVec3;

use crate::material::Material;
pub use report::{Report, Tolerance, Warning};

/// A face corner's normal index meaning "the smooth normal": the file's
/// normal there is unusable (not finite, no length).
pub const SMOOTH: u32 = u32::MAX;

/// The material of faces that neither the file nor the `mesh` block gives
/// one: a mid grey, no highlight (MTL's own default diffuse colour).
pub const DEFAULT_MATERIAL: Material = Material {
    kd: DVec3::splat(0.8),
    ks: DVec3::ZERO,
    shininess: 1.0,
};

/// One triangle of a mesh: indices into the mesh's positions, and where the
/// file gives them per corner, into its normals (`SMOOTH` where that one is
/// unusable); its material, if the file assigns one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Face {
    /// Indices into `Mesh::positions`.
    pub positions: [u32; 3],
    /// Indices into `Mesh::normals`, where the file gives them.
    pub normals: Option<[u32; 3]>,
    /// Index into `Mesh::materials`, where the file assigns one.
    pub material: Option<u32>,
}

/// A model file as read: positions, normals, colours, faces and materials,
/// before it becomes scene triangles (`scene::mesh`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<DVec3>,
    /// The file's normals (OBJ `vn`, PLY `nx ny nz`, OFF `NOFF`).
    pub normals: Vec<DVec3>,
    /// Per position, linear [0, 1] RGB, when the file has vertex colours.
    pub colors: Vec<DVec3>,
    /// The triangles (convex polygons fanned into them).
    pub faces: Vec<Face>,
    /// Materials the file defines (OBJ `usemtl` from its `mtllib`, glTF's).
    pub materials: Vec<Material>,
    /// What was tolerated in reading it.
    pub report: Report,
    /// The file's own view, where it has one (glTF's first perspective
    /// camera in the scene's nodes), as the file places it: it may not
    /// see (a view along its up, a field of view out of range).
    pub camera: Option<FileCamera>,
}

/// A view a model file gives: where from, which way, and how wide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FileCamera {
    /// Where the camera is.
    pub eye: DVec3,
    /// A point it looks at (along its view).
    pub look: DVec3,
    /// Its up direction.
    pub up: DVec3,
    /// Vertical field of view, degrees.
    pub fov: f64,
}

/// What is wrong in a model file, and where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MeshError {
    /// The model file.
    pub path: PathBuf,
    /// "line 12" or "byte 4096".
    pub at: Option<String>,
    /// What is wrong, and what to do.
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

/// The model formats, by extension (and for STL and glTF, by content).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Wavefront OBJ (with its MTL libraries).
    Obj,
    /// Stanford PLY, ASCII or binary.
    Ply,
    /// OFF (with `COFF`, `NOFF` and `CNOFF`).
    Off,
    /// Binary STL (`read` tells it from ASCII by content).
    Stl,
    /// ASCII STL.
    StlAscii,
    /// glTF 2.0 JSON (with its buffers).
    Gltf,
    /// Binary glTF.
    Glb,
}

impl Format {
    /// The format its extension names; None for other extensions.
    pub fn of(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(Format::Obj),
            "ply" => Some(Format::Ply),
            "off" => Some(Format::Off),
            "stl" => Some(Format::Stl),
            "gltf" => Some(Format::Gltf),
            "glb" => Some(Format::Glb),
            _ => None,
        }
    }

    /// What messages call it.
    pub fn name(self) -> &'static str {
        match self {
            Format::Obj => "OBJ",
            Format::Ply => "PLY",
            Format::Off => "OFF",
            Format::Stl | Format::StlAscii => "STL",
            Format::Gltf | Format::Glb => "glTF",
        }
    }
}

/// Whether a loader reads the files a model refers to (MTL libraries,
/// glTF buffers), or treats them as missing (fuzzing, and models that
/// did not come from a file).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refs {
    /// Read them from the file's directory.
    Disk,
    /// Treat them as missing.
    None,
}

/// The extensions `load` reads, for messages.
pub const EXTENSIONS: &str = ".obj, .ply, .off, .stl, .gltf or .glb";

/// Reads a model file, its format chosen by extension (STL's encoding and
/// GLB by content), with bounded memory whatever the file is.
pub fn load(path: &Path) -> Result<Mesh, MeshError> {
    load_timed(path).map(|loaded| loaded.mesh)
}

/// A model `load_timed` read, with what `-v` and the scene cache want to
/// know of its reading.
pub(crate) struct Loaded {
    pub(crate) mesh: Mesh,
    /// How long reading the file's bytes took (the rest is parsing).
    pub(crate) read_time: std::time::Duration,
    /// Every file it came from: the model file, then those it refers to
    /// that were tried (MTL libraries, glTF buffers), found or not.
    pub(crate) files: Vec<std::path::PathBuf>,
}

/// `load`, and what `Loaded` tells of it.
pub(crate) fn load_timed(path: &Path) -> Result<Loaded, MeshError> {
    let (mesh, referenced) = source::referenced_during(|| load_here(path));
    let (mesh, read_time) = mesh?;
    let mut files = vec![path.to_path_buf()];
    for f in referenced {
        if !files.contains(&f) {
            files.push(f);
        }
    }
    Ok(Loaded {
        mesh,
        read_time,
        files,
    })
}

fn load_here(path: &Path) -> Result<(Mesh, std::time::Duration), MeshError> {
    let format = Format::of(path).ok_or_else(|| MeshError {
        path: path.to_path_buf(),
        at: None,
        message: format!("unknown model format; use an {EXTENSIONS} file"),
    })?;
    let start = std::time::Instant::now();
    let src = source::read(path, format)?;
    let read = start.elapsed();
    let mut mesh = parse(&src.bytes, src.format, path, Refs::Disk)?;
    let mut report = src.report;
    report.merge(std::mem::take(&mut mesh.report));
    mesh.report = report;
    Ok((mesh, read))
}

/// Parses a model from its bytes; `path` names it in messages and is where
/// files it refers to (MTL libraries, glTF buffers) are looked for, if
/// `refs` says so. For fuzzing and for callers that hold the bytes already.
pub fn parse(bytes: &[u8], format: Format, path: &Path, refs: Refs) -> Result<Mesh, MeshError> {
    let mesh = match format {
        Format::Obj => obj::parse(bytes, path, refs)?,
        Format::Ply => ply::parse(bytes, path)?,
        Format::Off => off::parse(bytes, path)?,
        Format::Stl => stl::parse_binary(bytes, path)?,
        Format::StlAscii => stl::parse_ascii(bytes, path)?,
        Format::Gltf | Format::Glb => gltf::parse(bytes, path, refs)?,
    };
    mesh.check(path)?;
    Ok(mesh)
}

/// Reads a model from any reader (standard input, a pipe), with the same
/// bounds as `load`; files it refers to are not read.
pub fn read(reader: impl std::io::Read, format: Format, path: &Path) -> Result<Mesh, MeshError> {
    let src = source::read_from(reader, path, format)?;
    let mut mesh = parse(&src.bytes, src.format, path, Refs::None)?;
    let mut report = src.report;
    report.merge(std::mem::take(&mut mesh.report));
    mesh.report = report;
    Ok(mesh)
}

/// An MTL library's materials, by name, for fuzzing the MTL reader alone.
pub fn parse_mtl(bytes: &[u8], path: &Path) -> Result<(Vec<Material>, Report), MeshError> {
    let mut materials = Vec::new();
    let mut names = std::collections::HashMap::new();
    let mut report = Report::default();
    mtl::read(bytes, path, &mut materials, &mut names, &mut report)?;
    Ok((materials, report))
}

impl Mesh {
    /// Every index in range (the readers check as they go; this is the
    /// last word).
    fn check(&self, path: &Path) -> Result<(), MeshError> {
        use rayon::prelude::*;
        let np = self.positions.len() as u32;
        let nn = self.normals.len() as u32;
        let nm = self.materials.len() as u32;
        let bad = |f: &Face| {
            f.positions.iter().any(|&p| p >= np)
                || f.normals
                    .is_some_and(|n| n.iter().any(|&k| k >= nn && k != SMOOTH))
                || f.material.is_some_and(|m| m >= nm)
        };
        // The first bad face, as a loop would name it.
        if let Some(i) = self.faces.par_iter().position_first(bad) {
            return Err(MeshError {
                path: path.to_path_buf(),
                at: None,
                message: format!(
                    "face {i} refers to a vertex, normal or material it does not define"
                ),
            });
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
        use rayon::prelude::*;
        // Each thread owns a range of vertices and walks every face for the
        // corners in it, so each vertex sums its faces in file order, as one
        // thread would: the same bits on any number of threads.
        let n = self.positions.len();
        let span = n.div_ceil(rayon::current_num_threads().max(1)).max(1 << 12);
        let mut sums = vec![DVec3::ZERO; n];
        sums.par_chunks_mut(span).enumerate().for_each(|(k, sums)| {
            let lo = (k * span) as u32;
            let hi = lo + sums.len() as u32;
            let mine = |i: u32| (lo..hi).contains(&i);
            for f in &self.faces {
                if !f.positions.iter().any(|&i| mine(i)) {
                    continue;
                }
                let p = f.positions.map(|i| self.positions[i as usize]);
                let n = (p[1] - p[0]).cross(p[2] - p[0]);
                let len = n.length();
                if len == 0.0 || !len.is_finite() {
                    continue;
                }
                let n = n / len;
                for k in 0..3 {
                    if !mine(f.positions[k]) {
                        continue;
                    }
                    let a = p[(k + 1) % 3] - p[k];
                    let b = p[(k + 2) % 3] - p[k];
                    let angle = a.angle_between(b);
                    if angle.is_finite() {
                        sums[(f.positions[k] - lo) as usize] += n * angle;
                    }
                }
            }
        });
        sums.into_par_iter()
            .map(|s| s.try_normalize().unwrap_or(DVec3::ZERO))
            .collect()
    }

    /// Whether some corner takes the smooth normal: its face has no
    /// normals from the file, or that normal is unusable.
    pub fn needs_smooth_normals(&self) -> bool {
        self.faces
            .iter()
            .any(|f| f.normals.is_none_or(|n| n.contains(&SMOOTH)))
    }

    /// Whether some face would have no material without one given: the
    /// file has no vertex colours and no material for it.
    pub fn missing_material(&self) -> bool {
        self.colors.is_empty() && self.faces.iter().any(|f| f.material.is_none())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The angle-weighted sums one face after another, as one thread
    /// would make them.
    fn sequential(mesh: &Mesh) -> Vec<DVec3> {
        let mut sums = vec![DVec3::ZERO; mesh.positions.len()];
        for f in &mesh.faces {
            let p = f.positions.map(|i| mesh.positions[i as usize]);
            let n = (p[1] - p[0]).cross(p[2] - p[0]);
            let len = n.length();
            if len == 0.0 || !len.is_finite() {
                continue;
            }
            for k in 0..3 {
                let angle = (p[(k + 1) % 3] - p[k]).angle_between(p[(k + 2) % 3] - p[k]);
                if angle.is_finite() {
                    sums[f.positions[k] as usize] += n / len * angle;
                }
            }
        }
        sums.into_iter()
            .map(|s| s.try_normalize().unwrap_or(DVec3::ZERO))
            .collect()
    }

    #[test]
    fn smooth_normals_are_the_same_bits_on_any_number_of_threads() {
        // A bumpy 120x120 height field, its faces in a shuffled order so
        // that faces cross the threads' vertex ranges.
        let n = 120u32;
        let mut mesh = Mesh::default();
        for j in 0..n {
            for i in 0..n {
                let (x, y) = (f64::from(i), f64::from(j));
                mesh.positions
                    .push(DVec3::new(x, y, (x * 0.37).sin() * (y * 0.21).cos()));
            }
        }
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let v = j * n + i;
                for positions in [[v, v + 1, v + n + 1], [v, v + n + 1, v + n]] {
                    mesh.faces.push(Face {
                        positions,
                        normals: None,
                        material: None,
                    });
                }
            }
        }
        let len = mesh.faces.len();
        for k in 0..len {
            mesh.faces.swap(k, (k * 7919) % len);
        }
        let want = sequential(&mesh);
        for threads in [1, 2, 3, 8] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let got = pool.install(|| mesh.smooth_normals());
            assert!(
                got.iter()
                    .zip(&want)
                    .all(|(a, b)| a.to_array().map(f64::to_bits) == b.to_array().map(f64::to_bits)),
                "{threads} threads"
            );
        }
    }
}
