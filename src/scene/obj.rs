//! Writing a scene's triangles back as OBJ with an MTL library (`glint
//! convert`).

use std::collections::HashMap;
use std::fmt::Write as _;

use glam::DVec3;

use crate::scene::model::Scene;

/// What `write_obj` wrote, and what OBJ could not hold.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjWritten {
    /// Triangles written.
    pub triangles: usize,
    /// Materials written to the MTL file.
    pub materials: usize,
    /// Triangles whose corners have different materials: OBJ gives a face
    /// one, so the first corner's was written.
    pub mixed_materials: usize,
    /// Spheres, which OBJ cannot hold.
    pub spheres_skipped: usize,
    /// Lights, which OBJ cannot hold.
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
