//! What a loader tolerated in a model file: each kind of repair is counted,
//! and the first few of each kind keep their place in the file (line, byte
//! or JSON path), so a user sees every change glint made to what the file
//! says, never a silent one.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

/// The repairs a loader makes instead of refusing a file, as mainstream
/// importers do.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Tolerance {
    /// A byte-order mark skipped, or UTF-16 text decoded.
    Encoding,
    /// `usemtl` names a material no library defines.
    UndefinedMaterial,
    /// A material library that is missing or cannot be read.
    MissingLibrary,
    /// A material statement without its values, or with values out of
    /// range: that field's default.
    MaterialValue,
    /// A normal that is not finite or has no length: the smooth normal.
    BadNormal,
    /// A face that gives normals for some corners and not others: smooth
    /// normals for it.
    PartialNormals,
    /// Normals in the file that no face refers to.
    UnusedNormals,
    /// A face with a repeated corner, fewer than three corners, or no
    /// area: dropped.
    DegenerateFace,
    /// A face with a vertex that is not finite (NaN, infinite): dropped.
    BadPosition,
    /// A polygon that ear clipping could not cut (it crosses itself): fanned.
    TangledPolygon,
    /// Points, lines or other primitives that are not surfaces: skipped.
    NotSurface,
    /// Vertex colours on some vertices and not others: all ignored.
    PartialColors,
    /// Textures, which glint does not render: the material's own colour.
    TextureIgnored,
    /// A glTF structure mainstream importers accept though the
    /// specification does not (a scene without `nodes`, a default scene
    /// that does not exist).
    Structure,
    /// A required glTF extension glint does not implement, that changes
    /// materials only: the geometry is read without it.
    Extension,
    /// A malformed number (`3.1+e2`) read as the number it starts with.
    Number,
    /// Data after the end the file declares (binary STL, PLY): not read.
    TrailingData,
}

impl Tolerance {
    /// Every kind, in declaration order (the scene cache writes a kind
    /// as its index here).
    pub(crate) const ALL: [Tolerance; 17] = [
        Tolerance::Encoding,
        Tolerance::UndefinedMaterial,
        Tolerance::MissingLibrary,
        Tolerance::MaterialValue,
        Tolerance::BadNormal,
        Tolerance::PartialNormals,
        Tolerance::UnusedNormals,
        Tolerance::DegenerateFace,
        Tolerance::BadPosition,
        Tolerance::TangledPolygon,
        Tolerance::NotSurface,
        Tolerance::PartialColors,
        Tolerance::TextureIgnored,
        Tolerance::Structure,
        Tolerance::Extension,
        Tolerance::Number,
        Tolerance::TrailingData,
    ];

    /// A short name for `glint info`'s counts.
    pub fn label(self) -> &'static str {
        match self {
            Tolerance::Encoding => "encoding",
            Tolerance::UndefinedMaterial => "undefined material",
            Tolerance::MissingLibrary => "missing material library",
            Tolerance::MaterialValue => "material value defaulted",
            Tolerance::BadNormal => "bad normal recomputed",
            Tolerance::PartialNormals => "face with partial normals",
            Tolerance::UnusedNormals => "normals never used",
            Tolerance::DegenerateFace => "degenerate face dropped",
            Tolerance::BadPosition => "face with a non-finite vertex dropped",
            Tolerance::TangledPolygon => "self-crossing polygon fanned",
            Tolerance::NotSurface => "non-surface primitive skipped",
            Tolerance::PartialColors => "partial vertex colours ignored",
            Tolerance::TextureIgnored => "texture ignored",
            Tolerance::Structure => "structure repaired",
            Tolerance::Extension => "unimplemented extension",
            Tolerance::Number => "malformed number",
            Tolerance::TrailingData => "trailing data ignored",
        }
    }
}

/// One tolerated thing, and where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Warning {
    /// What kind of thing was tolerated.
    pub kind: Tolerance,
    /// The model file.
    pub path: PathBuf,
    /// "line 12", "byte 4096" or a JSON path such as `meshes[0].primitives[1]`.
    pub at: Option<String>,
    /// What was tolerated.
    pub message: String,
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.at {
            Some(at) => write!(f, "{}, {at}: {}", self.path.display(), self.message),
            None => write!(f, "{}: {}", self.path.display(), self.message),
        }
    }
}

/// Warnings kept per kind; the rest are counted.
pub const KEPT_PER_KIND: usize = 3;

/// Everything one model file needed tolerated.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Report {
    /// The first `KEPT_PER_KIND` warnings of each kind.
    pub kept: Vec<Warning>,
    /// How many of each kind there were.
    pub counts: BTreeMap<Tolerance, usize>,
}

impl Report {
    /// Records a warning of `kind` at `at` in `path`.
    pub fn warn(
        &mut self,
        kind: Tolerance,
        path: &Path,
        at: Option<String>,
        message: impl Into<String>,
    ) {
        let count = self.counts.entry(kind).or_insert(0);
        *count = count.saturating_add(1);
        if *count <= KEPT_PER_KIND {
            self.kept.push(Warning {
                kind,
                path: path.to_path_buf(),
                at,
                message: message.into(),
            });
        }
    }

    /// Whether nothing was tolerated.
    pub fn is_empty(&self) -> bool {
        self.counts.is_empty()
    }

    /// How many were tolerated beyond those kept.
    pub fn more(&self) -> usize {
        let total: usize = self.counts.values().sum();
        total.saturating_sub(self.kept.len())
    }

    /// "3 degenerate face dropped, 1 undefined material", for `glint info`.
    pub fn summary(&self) -> String {
        self.counts
            .iter()
            .map(|(k, n)| format!("{n} {}", k.label()))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Why a model brought no triangles: the faces dropped and why, else
    /// that it holds none to begin with.
    pub(crate) fn why_no_triangles(&self) -> String {
        self.dropped_faces()
            .unwrap_or_else(|| "points, lines or nothing".into())
    }

    /// The faces read but dropped ("2 degenerate faces (corners on one
    /// line or point), 1 face with a non-finite vertex"), for a mesh that
    /// brought no triangles: the reason it is empty.
    pub fn dropped_faces(&self) -> Option<String> {
        let count = |k| self.counts.get(&k).copied().unwrap_or(0);
        let plural = |n: usize| if n == 1 { "" } else { "s" };
        let mut parts = Vec::new();
        let n = count(Tolerance::DegenerateFace);
        if n > 0 {
            parts.push(format!(
                "{n} degenerate face{} (corners on one line or point)",
                plural(n)
            ));
        }
        let n = count(Tolerance::BadPosition);
        if n > 0 {
            parts.push(format!("{n} face{} with a non-finite vertex", plural(n)));
        }
        (!parts.is_empty()).then(|| format!("{} dropped", parts.join(", ")))
    }

    /// Adds `other`'s warnings and counts (another file of the same model).
    pub fn merge(&mut self, other: Report) {
        for w in other.kept {
            if self.kept.iter().filter(|k| k.kind == w.kind).count() < KEPT_PER_KIND {
                self.kept.push(w);
            }
        }
        for (k, n) in other.counts {
            *self.counts.entry(k).or_insert(0) += n;
        }
    }
}
