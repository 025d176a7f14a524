//! A model file alone as a scene, framed as model viewers (f3d, MeshLab,
//! Blender's importers) frame what they open: the camera fitted to the
//! model's bounds, a light beside the camera, the classic dim ambient.
//! `render`, `view`, `info` and the library's `read_scene` take a model
//! where a scene is expected this way, and `glint convert` writes the same
//! scene, so what it writes renders as the model did.

use std::path::Path;
use std::time::Instant;

use glam::DVec3;

use super::model::{Bounds, CameraSpec, Light, Material, MaterialIds, MeshInfo, Scene};
use crate::mesh::{self, MeshError};

/// The material of a model whose file gives none (`convert`'s `--dif`,
/// `--spe`, `--shi` defaults): a light grey with a soft highlight.
pub const MODEL_MATERIAL: Material = Material {
    kd: DVec3::splat(0.7),
    ks: DVec3::splat(0.3),
    shininess: 20.0,
};

/// The ambient colour of a framed model: the course's scenes' usual one.
pub(crate) const MODEL_AMBIENT: DVec3 = DVec3::splat(0.1);

/// Where the framing camera looks from, relative to the model's centre:
/// in front (+z, as OBJ and glTF face), a little above and to the right,
/// so that a box shows three faces and a height field its relief.
const VIEW_FROM: DVec3 = DVec3::new(0.35, 0.45, 1.0);

/// The model in `path` (any format `mesh::load` reads) as a scene, its
/// faces without a material taking `material`, framed by `framing` (seen
/// through the file's own camera where it has one, as glTF can; the light
/// stays where the framing puts it).
pub fn model_scene(path: &Path, material: Material) -> Result<Scene, MeshError> {
    let start = Instant::now();
    let mesh::Loaded {
        mut mesh,
        read_time,
        files,
    } = mesh::load_timed(path)?;
    if mesh.faces.is_empty() {
        return Err(MeshError {
            path: path.to_path_buf(),
            at: None,
            message: format!(
                "nothing to render: it holds no triangles ({})",
                mesh.report.why_no_triangles()
            ),
        });
    }
    // The file's materials where it has them for every face; vertex
    // colours, where it has them, are the diffuse colour either way.
    let material = (mesh.materials.is_empty() || mesh.missing_material()).then_some(material);
    let mut scene = Scene {
        ambient: MODEL_AMBIENT,
        ..Default::default()
    };
    let normals_start = Instant::now();
    let mut ids = MaterialIds::default();
    scene.triangles = super::mesh::triangles(
        &mesh,
        material,
        |p| p,
        |n| n,
        |m| ids.id(&mut scene.materials, m),
    );
    let bounds = scene.bounds();
    let normals_time = normals_start.elapsed();
    let (framed, light) = framing(bounds);
    // The file's own view where it can see, as a camera block must.
    let own = mesh.camera.map(|c| CameraSpec {
        eye: c.eye,
        look: c.look,
        up: c.up,
        fov: c.fov,
    });
    let sees = |c: &CameraSpec| c.fov > 0.0 && c.fov < 180.0 && c.basis().is_some();
    scene.camera = Some(own.filter(sees).unwrap_or(framed));
    scene.lights.push(light);
    scene.meshes.push(MeshInfo {
        file: path.display().to_string(),
        triangles: scene.triangles.len(),
        bounds,
        load_time: start.elapsed(),
        read_time,
        normals_time,
        report: std::mem::take(&mut mesh.report),
        files,
    });
    Ok(scene)
}

/// A camera that sees all of `bounds` (its bounding sphere inside the
/// classic 60° vertical field of view, with a margin), looking at its
/// centre with +y up, and a white light above and beside the camera.
pub(crate) fn framing(bounds: Bounds) -> (CameraSpec, Light) {
    let centre = bounds.centroid();
    let radius = (bounds.max - bounds.min).length() / 2.0;
    // A point, or bounds no f64 can measure, still gets a usable view.
    let radius = if radius.is_finite() && radius > 0.0 {
        radius
    } else {
        1.0
    };
    let fov = crate::camera::FOV_Y_DEGREES;
    let distance = 1.1 * radius / (fov.to_radians() / 2.0).sin();
    let toward_eye = VIEW_FROM.normalize();
    let eye = centre + toward_eye * distance;
    let camera = CameraSpec {
        eye,
        look: centre,
        up: DVec3::Y,
        fov,
    };
    // Above and to the right of the eye, so that shading shows the shape
    // (a light at the eye lights everything head-on).
    let right = -toward_eye
        .cross(DVec3::Y)
        .try_normalize()
        .unwrap_or(DVec3::NEG_X);
    let light = Light::point(eye + (right + DVec3::Y) * radius, DVec3::ONE);
    (camera, light)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every corner of `bounds` is inside the camera's vertical field of
    /// view (the narrower one at 4:3 and wider images) with a margin.
    #[test]
    fn framing_sees_every_corner_of_the_bounds() {
        let cases = [
            (DVec3::splat(-1.0), DVec3::splat(1.0)),
            (DVec3::new(40.0, -25.0, 90.0), DVec3::new(44.0, -22.0, 92.0)),
            (DVec3::new(-1e-6, 0.0, 0.0), DVec3::new(1e-6, 1e-6, 0.0)),
            (DVec3::new(0.0, 0.0, 0.0), DVec3::new(1000.0, 1.0, 1.0)),
            (DVec3::new(0.0, 0.0, 0.0), DVec3::new(1.0, 1000.0, 1.0)),
            (DVec3::new(0.0, 0.0, 0.0), DVec3::new(1.0, 1.0, 1000.0)),
            (DVec3::splat(3.0), DVec3::splat(3.0)),
        ];
        for (min, max) in cases {
            let (camera, light) = framing(Bounds { min, max });
            let [right, up, back] = camera.basis().expect("the framing camera sees");
            let half = (camera.fov / 2.0).to_radians().tan();
            for k in 0..8 {
                let pick = |bit: usize, a: f64, b: f64| if k >> bit & 1 == 1 { b } else { a };
                let corner = DVec3::new(
                    pick(0, min.x, max.x),
                    pick(1, min.y, max.y),
                    pick(2, min.z, max.z),
                );
                let v = corner - camera.eye;
                let depth = -v.dot(back);
                assert!(
                    depth > 0.0,
                    "{min} {max}: corner {corner} behind the camera"
                );
                assert!(
                    v.dot(up).abs() < 0.95 * half * depth,
                    "{min} {max}: {corner} above or below"
                );
                assert!(
                    v.dot(right).abs() < 0.95 * half * depth,
                    "{min} {max}: {corner} beside"
                );
            }
            assert!(light.position.is_finite() && light.position != camera.eye);
        }
    }
}
