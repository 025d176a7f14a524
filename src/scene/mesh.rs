//! A model file's mesh (`crate::mesh`) as the scene's triangles: placed,
//! its normals turned and kept as the classic parser keeps them, its
//! materials entered in the scene's table.

use glam::DVec3;
use rayon::prelude::*;

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
    place: impl Fn(DVec3) -> DVec3 + Sync,
    turn: impl Fn(DVec3) -> DVec3 + Sync,
    material_id: impl FnMut(Material) -> u32,
) -> Vec<Triangle> {
    let smooth = if mesh.needs_smooth_normals() {
        mesh.smooth_normals()
    } else {
        Vec::new()
    };
    let ids = Ids::of(mesh, material, material_id);
    mesh.faces
        .par_iter()
        .enumerate()
        .map(|(i, f)| {
            let vertices = [0, 1, 2].map(|k| {
                let p = f.positions[k] as usize;
                let n = match f.normals {
                    Some(ns) if ns[k] != SMOOTH => mesh.normals[ns[k] as usize],
                    _ => smooth[p],
                };
                Vertex {
                    position: place(mesh.positions[p]),
                    normal: unit(turn(n)),
                    material: ids.get(mesh, material, i, k),
                }
            });
            Triangle {
                vertices,
                velocity: DVec3::ZERO,
            }
        })
        .collect()
}

/// Each corner's index in the scene's material table, found before the
/// triangles are made on every thread: the table takes materials in the
/// order corners first use them, as a corner-by-corner pass would.
enum Ids {
    /// Without vertex colours: by the face's base material (`base`).
    PerBase(Vec<u32>),
    /// With them (each vertex's colour its diffuse one): per corner.
    PerCorner(Vec<[u32; 3]>),
}

impl Ids {
    fn of(mesh: &Mesh, material: Option<Material>, mut id: impl FnMut(Material) -> u32) -> Ids {
        const UNSEEN: u32 = u32::MAX;
        if mesh.colors.is_empty() {
            let mut ids = vec![UNSEEN; mesh.materials.len() + 1];
            for f in &mesh.faces {
                let b = base(material, f.material);
                if ids[b] == UNSEEN {
                    ids[b] = id(base_material(mesh, material, f.material));
                }
            }
            return Ids::PerBase(ids);
        }
        // A vertex's material is its face's base with its colour: the last
        // (base, id) seen at each vertex saves finding it again.
        let mut seen = vec![(UNSEEN, UNSEEN); mesh.positions.len()];
        let ids = mesh
            .faces
            .iter()
            .map(|f| {
                let b = base(material, f.material) as u32;
                f.positions.map(|p| {
                    let (sb, sid) = seen[p as usize];
                    if sb == b {
                        return sid;
                    }
                    let mut m = base_material(mesh, material, f.material);
                    m.kd = mesh.colors[p as usize];
                    let new = id(m);
                    seen[p as usize] = (b, new);
                    new
                })
            })
            .collect();
        Ids::PerCorner(ids)
    }

    fn get(&self, mesh: &Mesh, material: Option<Material>, face: usize, corner: usize) -> u32 {
        match self {
            Ids::PerBase(ids) => ids[base(material, mesh.faces[face].material)],
            Ids::PerCorner(ids) => ids[face][corner],
        }
    }
}

/// Which base material a face takes, as an index: 0 for the block's (or
/// the default), 1 + the file's otherwise.
fn base(material: Option<Material>, file: Option<u32>) -> usize {
    match (material, file) {
        (None, Some(m)) => m as usize + 1,
        _ => 0,
    }
}

/// A face's material before vertex colours: the block's, else the file's,
/// else `DEFAULT_MATERIAL` (with vertex colours: black with no highlight,
/// the colour being the diffuse one).
fn base_material(mesh: &Mesh, material: Option<Material>, file: Option<u32>) -> Material {
    material
        .or_else(|| file.map(|m| mesh.materials[m as usize]))
        .unwrap_or(if mesh.colors.is_empty() {
            DEFAULT_MATERIAL
        } else {
            Material {
                kd: DVec3::ZERO,
                ks: DVec3::ZERO,
                shininess: 1.0,
            }
        })
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
