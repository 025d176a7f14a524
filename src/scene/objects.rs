//! The scene format's objects and settings, one parser method each:
//! `sphere`, `triangle`, `light`, `camera`, `mesh` (with its placement
//! steps), the settings lines and materials.

use glam::DVec3;
use rayon::prelude::*;

use std::path::Path;

use super::model::{
    Bounds, CameraSpec, Effects, Light, LightShape, Material, MeshInfo, Sphere, Triangle, Vertex,
};
use super::parse::{PResult, Parser, Token};
use super::settings::Sampler;

/// A `mesh` block's placement step.
#[derive(Clone, Copy, Debug)]
pub(super) enum Transform {
    Scale(f64),
    Translate(DVec3),
    Rotate(glam::DQuat),
}

impl Transform {
    pub(super) fn point(&self, p: DVec3) -> DVec3 {
        match self {
            Transform::Scale(s) => p * *s,
            Transform::Translate(t) => p + *t,
            Transform::Rotate(q) => *q * p,
        }
    }

    /// Normals turn with rotations only (scales are uniform and positive).
    pub(super) fn direction(&self, n: DVec3) -> DVec3 {
        match self {
            Transform::Rotate(q) => *q * n,
            _ => n,
        }
    }
}

impl<'a> Parser<'a> {
    pub(super) fn sphere(&mut self) -> PResult<Sphere> {
        self.tag("pos:")?;
        let center = self.vec3("the sphere centre")?;
        self.tag("rad:")?;
        let (radius, tok) = self.number("the sphere radius")?;
        if radius <= 0.0 {
            return Err(self.error_at(
                &tok,
                format!("sphere radius must be positive, found {}", tok.show()),
                None,
            ));
        }
        let material = self.material()?;
        let velocity = self.velocity()?;
        Ok(Sphere {
            center,
            radius,
            material,
            velocity,
        })
    }

    pub(super) fn triangle(&mut self) -> PResult<Triangle> {
        // The classic files' normals are unit to within 2e-5; anything
        // further off was not meant to be interpolated as written.
        const NORMAL_LENGTH_TOLERANCE: f64 = 1e-3;
        let mut vertices = [Vertex {
            position: DVec3::ZERO,
            normal: DVec3::ZERO,
            material: 0,
        }; 3];
        for v in &mut vertices {
            self.tag("pos:")?;
            v.position = self.vec3("the vertex position")?;
            let nor = self.tag("nor:")?;
            v.normal = self.vec3("the vertex normal")?;
            if v.normal == DVec3::ZERO {
                let d = self.diagnostic(
                    &nor,
                    "zero-length vertex normal: it adds nothing to the interpolated normal"
                        .to_string(),
                    Some("where all three are zero the flat (geometric) normal is used"),
                );
                self.warn(d);
            } else if (v.normal.length() - 1.0).abs() > NORMAL_LENGTH_TOLERANCE
                || !v.normal.length().is_finite()
            {
                // Interpolating unnormalized normals would weight the corners
                // by their lengths; a 1e30 normal would also overflow f32.
                let d = self.diagnostic(
                    &nor,
                    format!(
                        "vertex normal has length {:e}, not 1: glint renormalizes it",
                        v.normal.length()
                    ),
                    Some("write unit normals to silence this warning"),
                );
                self.warn(d);
                // Scaled first so that even 1e300 has a finite length.
                v.normal = (v.normal / v.normal.abs().max_element()).normalize();
            }
            let m = self.material()?;
            let state = &mut self.state;
            v.material = state.material_ids.id(&mut state.scene.materials, m);
        }
        let velocity = self.velocity()?;
        Ok(Triangle { vertices, velocity })
    }

    pub(super) fn light(&mut self) -> PResult<Light> {
        self.tag("pos:")?;
        let position = self.vec3("the light position")?;
        self.tag("col:")?;
        let color = self.vec3("the light colour")?;
        let mut shape = LightShape::Point;
        if self.optional_tag("rad:") {
            let (radius, tok) = self.number("the light radius")?;
            if radius < 0.0 {
                return Err(self.error_at(
                    &tok,
                    format!("light radius must be zero or more, found {}", tok.show()),
                    Some("rad: 0 (or no rad:) makes a point light"),
                ));
            }
            if radius > 0.0 {
                shape = LightShape::Sphere { radius };
            }
        } else if self.optional_tag("edge_u:") {
            let edge_u = self.vec3("the rectangle light's first edge")?;
            self.tag("edge_v:")?;
            let edge_v = self.vec3("the rectangle light's second edge")?;
            shape = LightShape::Rect { edge_u, edge_v };
        }
        let velocity = self.velocity()?;
        Ok(Light {
            position,
            color,
            shape,
            velocity,
        })
    }

    /// `camera` with `eye:`, `look:`, `up:`, `fov:` in any order, each
    /// optional (the classic camera's values where left out); at most one.
    pub(super) fn camera(&mut self, tok: &Token<'a>) -> PResult<()> {
        if self.state.scene.camera.is_some() {
            return Err(self.error_at(
                tok,
                "a second `camera` block; a scene has at most one".into(),
                None,
            ));
        }
        let mut cam = CameraSpec::CLASSIC;
        loop {
            if self.optional_tag("eye:") {
                cam.eye = self.vec3("the camera position")?;
            } else if self.optional_tag("look:") {
                cam.look = self.vec3("the point the camera looks at")?;
            } else if self.optional_tag("up:") {
                cam.up = self.vec3("the camera's up direction")?;
            } else if self.optional_tag("fov:") {
                let (fov, t) = self.number("the vertical field of view in degrees")?;
                if !(fov > 0.0 && fov < 180.0) {
                    return Err(self.expected(&t, "a field of view above 0 and below 180 degrees"));
                }
                cam.fov = fov;
            } else {
                break;
            }
        }
        if cam.basis().is_none() {
            return Err(self.error_at(
                tok,
                "this camera has no view: `look:` is its `eye:`, or `up:` points along the view"
                    .into(),
                Some("look at a point other than the eye, with an up direction across the view"),
            ));
        }
        self.state.scene.camera = Some(cam);
        Ok(())
    }

    /// `mesh` with `file:` (relative to the scene file), an optional
    /// material, and `scale:`, `translate:`, `rotate:` applied in the order
    /// written; its triangles join the scene's.
    pub(super) fn mesh(&mut self) -> PResult<()> {
        let file_tag = self.tag("file:")?;
        let name_tok = self.require("a model file name (.obj, .ply or .off)")?;
        let name = String::from_utf8_lossy(name_tok.text).into_owned();
        let mut material = None;
        let mut transforms: Vec<Transform> = Vec::new();
        loop {
            let saved = self.at();
            if self.optional_tag("dif:") {
                self.go(saved);
                material = Some(self.material()?);
            } else if self.optional_tag("scale:") {
                let (s, t) = self.number("the mesh's scale factor")?;
                if s <= 0.0 {
                    return Err(self.expected(&t, "a scale above 0"));
                }
                transforms.push(Transform::Scale(s));
            } else if self.optional_tag("translate:") {
                transforms.push(Transform::Translate(self.vec3("the mesh's translation")?));
            } else if self.optional_tag("rotate:") {
                let axis = self.vec3("the rotation axis")?;
                let (degrees, _) = self.number("the rotation angle in degrees")?;
                let Some(axis) = axis.try_normalize() else {
                    return Err(self.error_at(
                        &name_tok,
                        "the rotation axis of this mesh has no direction (0 0 0)".into(),
                        None,
                    ));
                };
                transforms.push(Transform::Rotate(glam::DQuat::from_axis_angle(
                    axis,
                    degrees.to_radians(),
                )));
            } else {
                break;
            }
        }
        let start = std::time::Instant::now();
        let file = self.base_dir().join(&name);
        let crate::mesh::Loaded {
            mesh,
            read_time,
            files,
        } = crate::mesh::load_timed(&file).map_err(|e| {
            self.error_at(
                &name_tok,
                format!("cannot load this mesh: {e}"),
                Some("the path is relative to the scene file"),
            )
        })?;
        if material.is_none() && mesh.missing_material() && !mesh.faces.is_empty() {
            let what = if mesh.materials.is_empty() {
                format!("{name} brings no materials, and this mesh block gives none")
            } else {
                format!(
                    "some faces of {name} have no material (no `usemtl` before them, or one \
                     no library defines), and this mesh block gives none"
                )
            };
            let d = crate::mesh::DEFAULT_MATERIAL;
            let diagnostic = self.diagnostic(
                &file_tag,
                format!(
                    "{what}: they take the default material (dif: {} {} {} spe: 0 0 0 shi: {})",
                    d.kd.x, d.kd.y, d.kd.z, d.shininess
                ),
                Some("add `dif: r g b  spe: r g b  shi: s` after the file name"),
            );
            self.warn(diagnostic);
        }
        if mesh.faces.is_empty() {
            let diagnostic = self.diagnostic(
                &name_tok,
                format!(
                    "{name} holds no triangles ({}): it adds nothing",
                    mesh.report.why_no_triangles()
                ),
                Some("check the file: glint renders surfaces (faces, triangles)"),
            );
            self.warn(diagnostic);
        }
        let state = &mut self.state;
        let normals_start = std::time::Instant::now();
        let triangles = super::mesh::triangles(
            &mesh,
            material,
            |p| transforms.iter().fold(p, |p, t| t.point(p)),
            |n| transforms.iter().fold(n, |n, t| t.direction(n)),
            |m| state.material_ids.id(&mut state.scene.materials, m),
        );
        let bounds = triangles
            .par_iter()
            .map(Triangle::bounds)
            .reduce(|| Bounds::EMPTY, Bounds::union);
        let normals_time = normals_start.elapsed();
        let before = self.state.scene.triangles.len();
        if before == 0 {
            // A big mesh's triangles are not copied again.
            self.state.scene.triangles = triangles;
        } else {
            self.state.scene.triangles.extend(triangles);
        }
        let count = self.state.scene.triangles.len() - before;
        if self.state.nothing_from_meshes.is_none() && count == 0 {
            self.state.nothing_from_meshes = Some(self.diagnostic(
                &name_tok,
                format!(
                    "nothing to render: the scene has no spheres or triangles, and {name} \
                     brought none{}",
                    mesh.report
                        .dropped_faces()
                        .map_or(String::new(), |d| format!(" ({d})"))
                ),
                Some("check the model file, or add objects to the scene"),
            ));
        }
        self.state.scene.meshes.push(MeshInfo {
            file: name,
            triangles: count,
            bounds,
            load_time: start.elapsed(),
            read_time,
            normals_time,
            report: mesh.report,
            files,
        });
        Ok(())
    }

    /// The directory `mesh` file names are relative to.
    pub(super) fn base_dir(&self) -> std::path::PathBuf {
        match Path::new(self.path).parent() {
            Some(d) if self.path != "<stdin>" => d.to_path_buf(),
            _ => std::path::PathBuf::from("."),
        }
    }

    /// An optional `vel: x y z` (scene units per second).
    pub(super) fn velocity(&mut self) -> PResult<DVec3> {
        if self.optional_tag("vel:") {
            self.vec3("the velocity")
        } else {
            Ok(DVec3::ZERO)
        }
    }

    /// Consumes the next token if it is `tag`.
    pub(super) fn optional_tag(&mut self, tag: &str) -> bool {
        let saved = self.at();
        match self.next_token() {
            Some(tok) if tok.is(tag) => true,
            _ => {
                self.go(saved);
                false
            }
        }
    }

    /// Parses a setting directive if `tok` starts one.
    pub(super) fn setting(&mut self, tok: &Token<'a>) -> PResult<bool> {
        if tok.is("reflect:") {
            let v = self.integer("the reflection depth", 0, Effects::MAX_REFLECT)?;
            self.state.scene.settings.reflect = Some(v);
        } else if tok.is("spp:") {
            let v = self.integer("samples per pixel", 1, Effects::MAX_SPP)?;
            self.state.scene.settings.spp = Some(v);
        } else if tok.is("shadow_samples:") {
            let what = "shadow samples per area light";
            let v = self.integer(what, 1, Effects::MAX_SHADOW_SAMPLES)?;
            self.state.scene.settings.shadow_samples = Some(v);
        } else if tok.is("seed:") {
            let v = self.integer("the random seed", 0, u32::MAX)?;
            self.state.scene.settings.seed = Some(v);
        } else if tok.is("shutter:") {
            let (v, t) = self.number("the shutter, a fraction of the frame interval")?;
            if !(0.0..=1.0).contains(&v) {
                return Err(self.expected(&t, "a shutter between 0 (no blur) and 1"));
            }
            self.state.scene.settings.shutter = Some(v);
        } else if tok.is("sampler:") {
            let what = "a sampler: `sobol` or `stratified`";
            let name = self.require_with(|| what.to_string())?;
            let sampler = std::str::from_utf8(name.text)
                .ok()
                .and_then(Sampler::from_name);
            match sampler {
                Some(v) => self.state.scene.settings.sampler = Some(v),
                None => return Err(self.expected(&name, what)),
            }
        } else if tok.is("fps:") {
            let (v, t) = self.number("frames per second")?;
            if v <= 0.0 {
                return Err(self.expected(&t, "a positive number of frames per second"));
            }
            self.state.scene.settings.fps = Some(v);
        } else {
            return Ok(false);
        }
        Ok(true)
    }

    pub(super) fn integer(&mut self, what: &str, min: u32, max: u32) -> PResult<u32> {
        let (v, tok) = self.number(what)?;
        if v.fract() != 0.0 || v < f64::from(min) || v > f64::from(max) {
            return Err(self.expected(
                &tok,
                &format!("a whole number from {min} to {max} ({what})"),
            ));
        }
        Ok(v as u32)
    }

    pub(super) fn material(&mut self) -> PResult<Material> {
        self.tag("dif:")?;
        let kd = self.vec3("the diffuse colour")?;
        self.tag("spe:")?;
        let ks = self.vec3("the specular colour")?;
        self.tag("shi:")?;
        let (shininess, tok) = self.number("the shininess")?;
        if shininess < 0.0 {
            return Err(self.error_at(
                &tok,
                format!("shininess must be zero or more, found {}", tok.show()),
                None,
            ));
        }
        Ok(Material { kd, ks, shininess })
    }
}
