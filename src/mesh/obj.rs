//! Wavefront OBJ: `v x y z [r g b]`, `vn`, `f` with `v`, `v/vt`, `v//vn` or
//! `v/vt/vn` corners (negative indices count back from the last), polygons
//! fanned; `mtllib` and `usemtl` with MTL's `Kd`, `Ks` and `Ns`. Texture
//! coordinates, groups and smoothing groups are read past.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use glam::DVec3;

use super::{fan, Face, Mesh, MeshError, Text};
use crate::scene::{Material, Scene};

pub fn parse(src: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    let mut t = Text::new(src, path);
    let mut mesh = Mesh::default();
    let mut names: HashMap<String, u32> = HashMap::new();
    let mut current: Option<u32> = None;
    let mut corners: Vec<(u32, Option<u32>)> = Vec::new();
    let mut colored = 0usize;
    while let Some(key) = t.token() {
        match key {
            b"v" => {
                let mut v = [0.0; 3];
                for (k, c) in v.iter_mut().enumerate() {
                    let tok = t.token_on_line();
                    *c = t.number(tok, ["x", "y", "z"][k])?;
                }
                mesh.positions.push(DVec3::from(v));
                // `v x y z r g b`: a vertex colour (a fourth value alone is w).
                let extra: Vec<&[u8]> = std::iter::from_fn(|| t.token_on_line()).collect();
                if extra.len() >= 3 {
                    let mut rgb = [0.0; 3];
                    for (c, tok) in rgb.iter_mut().zip(&extra) {
                        *c = t.number(Some(tok), "a colour component")?;
                    }
                    mesh.colors.push(DVec3::from(rgb));
                    colored += 1;
                }
            }
            b"vn" => {
                let mut n = [0.0; 3];
                for c in &mut n {
                    let tok = t.token_on_line();
                    *c = t.number(tok, "a normal component")?;
                }
                mesh.normals.push(DVec3::from(n));
            }
            b"f" => {
                corners.clear();
                while let Some(tok) = t.token_on_line() {
                    corners.push(corner(&t, tok, &mesh)?);
                }
                if corners.len() < 3 {
                    return Err(t.error(format!(
                        "a face needs at least 3 corners, found {}",
                        corners.len()
                    )));
                }
                let with_normals = corners.iter().all(|c| c.1.is_some());
                fan(&corners, |c| {
                    mesh.faces.push(Face {
                        positions: c.map(|k| k.0),
                        normals: with_normals.then(|| c.map(|k| k.1.unwrap_or(0))),
                        material: current,
                    });
                });
            }
            b"mtllib" => {
                let name = String::from_utf8_lossy(t.rest_of_line()).into_owned();
                let file = path.parent().unwrap_or(Path::new(".")).join(&name);
                let text = std::fs::read(&file).map_err(|e| {
                    t.error(format!(
                        "cannot read its material library {}: {e}",
                        file.display()
                    ))
                })?;
                read_mtl(&text, &file, &mut mesh.materials, &mut names)?;
            }
            b"usemtl" => {
                let name = String::from_utf8_lossy(t.rest_of_line()).into_owned();
                current = Some(*names.get(&name).ok_or_else(|| {
                    t.error(format!(
                        "material `{name}` is not defined by any `mtllib` before it"
                    ))
                })?);
            }
            _ => {}
        }
        t.next_line();
    }
    if colored != 0 && colored != mesh.positions.len() {
        return Err(MeshError {
            path: path.to_path_buf(),
            at: None,
            message: format!(
                "{colored} of {} vertices have colours (`v x y z r g b`); give all or none",
                mesh.positions.len()
            ),
        });
    }
    Ok(mesh)
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
                    "expected a {what} index in the face corner `{}`",
                    String::from_utf8_lossy(tok)
                ))
            })?;
        let index = if i < 0 { count as i64 + i } else { i - 1 };
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

/// `newmtl`, `Kd`, `Ks`, `Ns` of an MTL file; other statements are read
/// past. A material without `Ks` or `Ns` takes 0 for them (MTL's defaults).
fn read_mtl(
    src: &[u8],
    path: &Path,
    materials: &mut Vec<Material>,
    names: &mut HashMap<String, u32>,
) -> Result<(), MeshError> {
    let mut t = Text::new(src, path);
    let mut current: Option<usize> = None;
    while let Some(key) = t.token() {
        let key = key.to_ascii_lowercase();
        if key == b"newmtl" {
            let name = String::from_utf8_lossy(t.rest_of_line()).into_owned();
            names.insert(name, materials.len() as u32);
            materials.push(Material {
                kd: DVec3::splat(0.8),
                ks: DVec3::ZERO,
                shininess: 0.0,
            });
            current = Some(materials.len() - 1);
        } else if matches!(key.as_slice(), b"kd" | b"ks" | b"ns") {
            let Some(m) = current.map(|i| &mut materials[i]) else {
                return Err(t.error("a material property before any `newmtl`"));
            };
            if key == b"ns" {
                let tok = t.token_on_line();
                m.shininess = t.number(tok, "the shininess").and_then(|v| {
                    if v < 0.0 {
                        Err(t.error("shininess must be zero or more"))
                    } else {
                        Ok(v)
                    }
                })?;
            } else {
                let mut c = [0.0; 3];
                for v in &mut c {
                    let tok = t.token_on_line();
                    *v = t.number(tok, "a colour component")?;
                }
                if key == b"kd" {
                    m.kd = DVec3::from(c);
                } else {
                    m.ks = DVec3::from(c);
                }
            }
        }
        t.next_line();
    }
    Ok(())
}

/// What `write_obj` wrote, and what OBJ could not hold.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjWritten {
    pub triangles: usize,
    pub materials: usize,
    /// Triangles whose corners have different materials: OBJ gives a face
    /// one, so the first corner's was written.
    pub mixed_materials: usize,
    pub spheres_skipped: usize,
    pub lights_skipped: usize,
}

/// The scene's triangles as OBJ text (positions shared where equal, a
/// normal per corner) and its materials as MTL text named `mtl_name`.
pub fn write_obj(scene: &Scene, mtl_name: &str) -> (String, String, ObjWritten) {
    let mut obj = format!(
        "# written by glint convert: {} triangles\nmtllib {mtl_name}\n",
        scene.triangles.len()
    );
    let mut mtl = String::from("# written by glint convert\n");
    let mut info = ObjWritten {
        triangles: scene.triangles.len(),
        spheres_skipped: scene.spheres.len(),
        lights_skipped: scene.lights.len(),
        ..ObjWritten::default()
    };
    let key = |v: DVec3| v.to_array().map(f64::to_bits);
    let mut positions: HashMap<[u64; 3], usize> = HashMap::new();
    let mut materials: HashMap<[u64; 7], usize> = HashMap::new();
    let mut faces = String::new();
    let mut normals = 0usize;
    let mut current: Option<usize> = None;
    for t in &scene.triangles {
        let m = *scene.material(&t.vertices[0]);
        if t.vertices.iter().any(|v| *scene.material(v) != m) {
            info.mixed_materials += 1;
        }
        let mkey = m.key();
        let next = materials.len();
        let id = *materials.entry(mkey).or_insert_with(|| {
            let _ = writeln!(
                mtl,
                "newmtl m{next}\nKd {} {} {}\nKs {} {} {}\nNs {}",
                m.kd.x, m.kd.y, m.kd.z, m.ks.x, m.ks.y, m.ks.z, m.shininess
            );
            next
        });
        if current != Some(id) {
            let _ = writeln!(faces, "usemtl m{id}");
            current = Some(id);
        }
        let mut corner = [(0usize, 0usize); 3];
        for (c, v) in corner.iter_mut().zip(&t.vertices) {
            let next = positions.len();
            let p = *positions.entry(key(v.position)).or_insert_with(|| {
                let q = v.position;
                let _ = writeln!(obj, "v {} {} {}", q.x, q.y, q.z);
                next
            });
            let n = v.normal;
            let _ = writeln!(obj, "vn {} {} {}", n.x, n.y, n.z);
            normals += 1;
            *c = (p + 1, normals);
        }
        let _ = writeln!(
            faces,
            "f {}//{} {}//{} {}//{}",
            corner[0].0, corner[0].1, corner[1].0, corner[1].1, corner[2].0, corner[2].1
        );
    }
    obj.push_str(&faces);
    info.materials = materials.len();
    (obj, mtl, info)
}
