//! A model file's mesh (`crate::mesh`) as the scene's triangles: placed,
//! its normals turned and kept as the classic parser keeps them, its
//! materials entered in the scene's table.

use glam::DVec3;

use super::model::{Bounds, Material, Triangle, Vertex};
use crate::mesh::{Mesh, DEFAULT_MATERIAL, SMOOTH};

/// The mesh as scene triangles, each vertex placed by `place` and its
/// normal turned by `turn` (then normalized as the classic parser
/// does, `unit`). A face's material is `material` if given, else the
/// file's for it, else `DEFAULT_MATERIAL` (with vertex colours: black
/// with no highlight, the colour being the diffuse one); callers warn
/// when the default is used (`missing_material`). Normals are the
/// file's, else `smooth_normals`. `material_id` gives a material's
/// index in the scene's table (`Scene::add_material`, `MaterialIds`).
pub fn triangles(
    mesh: &Mesh,
    material: Option<Material>,
    place: impl Fn(DVec3) -> DVec3,
    turn: impl Fn(DVec3) -> DVec3,
    mut material_id: impl FnMut(Material) -> u32,
) -> Vec<Triangle> {
    let smooth = if mesh.needs_smooth_normals() {
        mesh.smooth_normals()
    } else {
        Vec::new()
    };
    mesh.faces
        .iter()
        .map(|f| {
            let base = material
                .or_else(|| f.material.map(|m| mesh.materials[m as usize]))
                .unwrap_or(if mesh.colors.is_empty() {
                    DEFAULT_MATERIAL
                } else {
                    // Vertex colours give the diffuse colour.
                    Material {
                        kd: DVec3::ZERO,
                        ks: DVec3::ZERO,
                        shininess: 1.0,
                    }
                });
            let vertices = [0, 1, 2].map(|k| {
                let p = f.positions[k] as usize;
                let n = match f.normals {
                    Some(ns) if ns[k] != SMOOTH => mesh.normals[ns[k] as usize],
                    _ => smooth[p],
                };
                let mut m = base;
                if let Some(c) = mesh.colors.get(p) {
                    m.kd = *c;
                }
                Vertex {
                    position: place(mesh.positions[p]),
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

/// The bounds of the vertices faces use (a file's unused or
/// non-finite vertices do not count).
pub fn bounds(mesh: &Mesh) -> Bounds {
    mesh.faces
        .iter()
        .flat_map(|f| f.positions)
        .fold(Bounds::EMPTY, |b, p| b.grow(mesh.positions[p as usize]))
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
