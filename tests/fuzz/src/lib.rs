//! What each fuzz target runs: a reader of glint's input on arbitrary
//! bytes, then what the renderer does with a model that loads (triangles,
//! smooth normals, bounds), so a bad value that gets through is found where
//! it would be used. Files a model refers to are never read here.

use std::path::Path;

use glint::mesh::{self, Format, Refs};

/// A model of `format`: through the bounded stream reader, as `glint`
/// reads a pipe, then from the bytes in hand.
pub fn model(format: Format, data: &[u8]) {
    let path = Path::new("fuzz");
    if let Ok(m) = mesh::read(data, format, path) {
        use_mesh(&m);
    }
    if let Ok(m) = mesh::parse(data, format, path, Refs::None) {
        use_mesh(&m);
    }
}

fn use_mesh(m: &mesh::Mesh) {
    let tris = glint::scene::mesh::triangles(&m, None, |p| p, |n| n, |_| 0);
    assert_eq!(tris.len(), m.faces.len());
    for t in &tris {
        for v in &t.vertices {
            assert!(v.position.is_finite(), "a non-finite position got through");
        }
    }
    let _ = glint::scene::mesh::bounds(&m);
    let _ = m.report.summary();
}

/// A scene: the parser on the whole text, and the windowed reader.
pub fn scene(data: &[u8]) {
    let _ = glint::scene::parse_scene(data, "fuzz");
    let _ = glint::scene::parse_reader(data, Path::new("fuzz"));
}
