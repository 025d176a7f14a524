//! The scene model: what a classic CSCI 420 scene file describes, in f64.
//!
//! Values are kept exactly as parsed (f64), so the CPU f64 reference sees the
//! file's own numbers; the GPU packing (`layout`) and the CPU f32 path round
//! them to f32 once, in one place each.

use glam::DVec3;

pub use super::diagnostic::Diagnostic;
pub use super::settings::{Effects, Settings};

pub use crate::material::Material;

/// A sphere (classic `sphere` block).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Its centre at the frame's time.
    pub center: DVec3,
    /// Its radius.
    pub radius: f64,
    /// Its material.
    pub material: Material,
    /// Scene units per second (extension `vel:`); zero for static spheres.
    pub velocity: DVec3,
}

/// One corner of a triangle: position, shading normal (as written, not
/// normalized: interpolation happens before normalization) and material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vertex {
    /// The corner's position.
    pub position: DVec3,
    /// The corner's shading normal, as written.
    pub normal: DVec3,
    /// Index into `Scene::materials`: a table, because a material per
    /// corner would be most of a big scene's memory (56 of 112 bytes).
    pub material: u32,
}

/// A triangle (classic `triangle` block, or a mesh's face).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// Its three corners, in the file's order.
    pub vertices: [Vertex; 3],
    /// Scene units per second, the same for all three corners (extension `vel:`).
    pub velocity: DVec3,
}

/// What a light emits from (extensions `rad:`, `edge_u:`/`edge_v:`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum LightShape {
    /// The classic point light: one shadow ray.
    #[default]
    Point,
    /// A sphere of this radius about `position`, sampled as the disc it
    /// shows the shaded point.
    Sphere {
        /// Its radius.
        radius: f64,
    },
    /// A parallelogram centred on `position` with these two edge vectors.
    Rect {
        /// One edge, centred on `position`.
        edge_u: DVec3,
        /// The other edge.
        edge_v: DVec3,
    },
}

impl LightShape {
    /// Whether it is an area light (sampled by several shadow rays).
    pub fn is_area(&self) -> bool {
        !matches!(self, LightShape::Point)
    }
}

/// A light (classic `light` block): a point, or an area light (extensions).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Its position (an area light's centre).
    pub position: DVec3,
    /// Its colour, per channel.
    pub color: DVec3,
    /// What it emits from.
    pub shape: LightShape,
    /// Scene units per second (extension `vel:`).
    pub velocity: DVec3,
}

impl Light {
    /// The light in a space `factor` times larger (`Scene::scaled`).
    pub fn scaled(&self, factor: f64) -> Light {
        Light {
            position: self.position * factor,
            velocity: self.velocity * factor,
            shape: match self.shape {
                LightShape::Point => LightShape::Point,
                LightShape::Sphere { radius } => LightShape::Sphere {
                    radius: radius * factor,
                },
                LightShape::Rect { edge_u, edge_v } => LightShape::Rect {
                    edge_u: edge_u * factor,
                    edge_v: edge_v * factor,
                },
            },
            ..*self
        }
    }

    /// A classic point light.
    pub fn point(position: DVec3, color: DVec3) -> Light {
        Light {
            position,
            color,
            shape: LightShape::Point,
            velocity: DVec3::ZERO,
        }
    }
}

/// Where the image is taken from (extension `camera`): without one, the
/// classic camera (`Camera::CLASSIC`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraSpec {
    /// Where the camera is.
    pub eye: DVec3,
    /// A point the camera looks at.
    pub look: DVec3,
    /// Which way is up (need not be perpendicular to the view).
    pub up: DVec3,
    /// Vertical field of view, degrees.
    pub fov: f64,
}

impl CameraSpec {
    /// The classic camera: at the origin, looking down -z, +y up, 60°.
    pub const CLASSIC: CameraSpec = CameraSpec {
        eye: DVec3::ZERO,
        look: DVec3::new(0.0, 0.0, -1.0),
        up: DVec3::Y,
        fov: crate::camera::FOV_Y_DEGREES,
    };

    /// The view's right, up and backward axes (a right-handed basis; the
    /// camera looks down -backward). None when `look` is `eye` or `up`
    /// is along the view.
    pub fn basis(&self) -> Option<[DVec3; 3]> {
        let forward = (self.look - self.eye).try_normalize()?;
        let right = forward.cross(self.up).try_normalize()?;
        let up = right.cross(forward);
        Some([right, up, -forward])
    }

    /// Whether the view is the classic one's placement (origin, -z, +y),
    /// whatever its field of view: then no transform is needed.
    pub fn is_classic_placement(&self) -> bool {
        self.eye == DVec3::ZERO && self.basis() == Some([DVec3::X, DVec3::Y, DVec3::Z])
    }

    /// A world point in view space (camera at the origin looking down -z).
    pub fn to_view(&self, basis: &[DVec3; 3], p: DVec3) -> DVec3 {
        let d = p - self.eye;
        DVec3::new(d.dot(basis[0]), d.dot(basis[1]), d.dot(basis[2]))
    }

    /// A world direction in view space.
    pub fn dir_to_view(basis: &[DVec3; 3], v: DVec3) -> DVec3 {
        DVec3::new(v.dot(basis[0]), v.dot(basis[1]), v.dot(basis[2]))
    }

    /// A view-space point back in the world.
    pub fn to_world(&self, basis: &[DVec3; 3], p: DVec3) -> DVec3 {
        self.eye + Self::dir_to_world(basis, p)
    }

    /// Direction `v` in camera space, in the world (`basis`: the camera's axes).
    pub fn dir_to_world(basis: &[DVec3; 3], v: DVec3) -> DVec3 {
        basis[0] * v.x + basis[1] * v.y + basis[2] * v.z
    }
}

/// A `mesh` block as loaded, for `glint info`.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshInfo {
    /// The file as the scene names it.
    pub file: String,
    /// Triangles it brought.
    pub triangles: usize,
    /// After its transforms.
    pub bounds: Bounds,
    /// How long loading it took, all together.
    pub load_time: std::time::Duration,
    /// Of `load_time`, reading the file's bytes (and the files it names).
    pub read_time: std::time::Duration,
    /// Of `load_time`, smooth normals and the mesh made the scene's
    /// triangles (placed, materials entered).
    pub normals_time: std::time::Duration,
    /// What its loader tolerated (printed as warnings, counted by `info`).
    pub report: crate::mesh::report::Report,
    /// Every file it came from: the model file, then those it refers to
    /// that were tried (MTL libraries, glTF buffers), found or not; what
    /// the scene cache checks for changes.
    pub files: Vec<std::path::PathBuf>,
}

/// A parsed scene, in f64, as the file wrote it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Scene {
    /// The global ambient colour, added once.
    pub ambient: DVec3,
    /// Its spheres.
    pub spheres: Vec<Sphere>,
    /// Its triangles, a mesh's included.
    pub triangles: Vec<Triangle>,
    /// The triangles' materials, indexed by `Vertex::material`.
    pub materials: Vec<Material>,
    /// Its lights.
    pub lights: Vec<Light>,
    /// Render settings the file asks for (extensions; classic files have none).
    pub settings: Settings,
    /// Questionable but renderable input (e.g. a zero-length normal), with
    /// its location, for the CLI to print: the first `WARNINGS_KEPT` of each
    /// kind.
    pub warnings: Vec<Diagnostic>,
    /// Warnings past the first few of their kind: counted, not kept.
    pub more_warnings: usize,
    /// The `camera` block, if any (extension).
    pub camera: Option<CameraSpec>,
    /// The `mesh` blocks, whose triangles are in `triangles` (extension).
    pub meshes: Vec<MeshInfo>,
}

/// Finds materials in a scene's table by their exact bits, adding the new
/// ones: a parsed scene keeps one entry per distinct material.
#[derive(Debug, Default)]
pub struct MaterialIds {
    index: std::collections::HashMap<[u64; 7], u32>,
    /// Corners in a row mostly share a material: no hashing for those.
    last: Option<([u64; 7], u32)>,
}

impl MaterialIds {
    /// `m`'s index in `materials`, adding it where it is new.
    pub fn id(&mut self, materials: &mut Vec<Material>, m: Material) -> u32 {
        let key = m.key();
        if let Some((k, id)) = self.last {
            if k == key {
                return id;
            }
        }
        let id = *self.index.entry(key).or_insert_with(|| {
            materials.push(m);
            (materials.len() - 1) as u32
        });
        self.last = Some((key, id));
        id
    }
}

/// Warnings of one kind kept with their location; the rest are counted.
pub const WARNINGS_KEPT: usize = 5;

/// The smallest size, relative to its coordinates, at which a primitive is
/// rendered right in f32 with a margin (`Scene::unresolvable`): 2^-20.
pub const RESOLVABLE: f64 = 1.0 / 1_048_576.0;

/// Geometry extents the renderers take as they are (`Scene::render_scale`):
/// the smallest.
pub const RENDER_SCALE_MIN: f64 = 1.0 / 1024.0;
/// The largest extent taken as it is.
pub const RENDER_SCALE_MAX: f64 = 16384.0;

/// Axis-aligned bounds of a set of points, in f64.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// The least corner.
    pub min: DVec3,
    /// The greatest corner.
    pub max: DVec3,
}

impl Bounds {
    /// Bounds of nothing: any point grows them to itself.
    pub const EMPTY: Bounds = Bounds {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    /// Whether they hold no point.
    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    /// Bounds of both.
    pub fn union(self, other: Bounds) -> Bounds {
        Bounds {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// These bounds and `p`.
    pub fn grow(self, p: DVec3) -> Bounds {
        Bounds {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// The centre of the box.
    pub fn centroid(&self) -> DVec3 {
        (self.min + self.max) * 0.5
    }

    /// The box's surface area (the SAH's cost measure).
    pub fn surface_area(&self) -> f64 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.max - self.min;
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }
}

impl Sphere {
    /// Its bounds at the frame's time.
    pub fn bounds(&self) -> Bounds {
        Bounds {
            min: self.center - DVec3::splat(self.radius),
            max: self.center + DVec3::splat(self.radius),
        }
    }

    /// Bounds of everywhere the sphere is during the next `span` seconds.
    pub fn swept_bounds(&self, span: f64) -> Bounds {
        let mut later = *self;
        later.center += self.velocity * span;
        self.bounds().union(later.bounds())
    }
}

impl Triangle {
    /// Its bounds at the frame's time.
    pub fn bounds(&self) -> Bounds {
        self.vertices
            .iter()
            .fold(Bounds::EMPTY, |b, v| b.grow(v.position))
    }

    /// Bounds of everywhere the triangle is during the next `span` seconds
    /// (linear motion: the swept volume lies in the hull of both ends).
    pub fn swept_bounds(&self, span: f64) -> Bounds {
        let shift = self.velocity * span;
        self.vertices
            .iter()
            .fold(self.bounds(), |b, v| b.grow(v.position + shift))
    }
}

impl Scene {
    /// The material of a triangle's corner.
    pub fn material(&self, v: &Vertex) -> &Material {
        &self.materials[v.material as usize]
    }

    /// The index of `m` in `materials`: the last entry when it is `m`,
    /// else a new one. Builders that reuse materials in runs get a small
    /// table; the parser finds repeats anywhere (`MaterialIds`).
    pub fn add_material(&mut self, m: Material) -> u32 {
        if self.materials.last() != Some(&m) {
            self.materials.push(m);
        }
        (self.materials.len() - 1) as u32
    }

    /// Bounds of all geometry (lights excluded); empty for an empty scene.
    pub fn bounds(&self) -> Bounds {
        use rayon::prelude::*;
        // On every thread (unions are exact: the same box in any order).
        let s = self
            .spheres
            .par_iter()
            .with_min_len(1 << 15)
            .map(Sphere::bounds);
        let t = self
            .triangles
            .par_iter()
            .with_min_len(1 << 15)
            .map(Triangle::bounds);
        s.chain(t).reduce(|| Bounds::EMPTY, Bounds::union)
    }

    /// Largest coordinate magnitude of the geometry (0 when there is none).
    pub fn extent(&self) -> f64 {
        let b = self.bounds();
        if b.min.x > b.max.x {
            return 0.0;
        }
        b.min.abs().max(b.max.abs()).max_element()
    }

    /// The power of two the renderers scale the scene by (about the camera,
    /// which the image does not notice) before converting it to f32: 1 when
    /// the geometry's extent is within [2^-10, 2^14], the range the
    /// hard-case suite verifies f32 in, else the one that brings the extent
    /// to [16, 32). Scaling by a power of two is exact, so it changes no
    /// bit of what the scene means, only where f32's fixed constants (ray
    /// offsets, t = infinity) and squares (sphere tests) meet it. Lights are
    /// kept below 2^100 after scaling.
    pub fn render_scale(&self) -> f64 {
        let m = self.extent();
        if m == 0.0 || !m.is_finite() || (RENDER_SCALE_MIN..=RENDER_SCALE_MAX).contains(&m) {
            return 1.0;
        }
        let mut k = 4 - m.log2().floor() as i32;
        let lights = self
            .lights
            .iter()
            .map(|l| {
                let reach = match l.shape {
                    LightShape::Point => 0.0,
                    LightShape::Sphere { radius } => radius,
                    LightShape::Rect { edge_u, edge_v } => edge_u.length() + edge_v.length(),
                };
                l.position.abs().max_element() + reach
            })
            .fold(0.0, f64::max);
        if lights > 0.0 {
            k = k.min(100 - lights.log2().ceil() as i32);
        }
        2f64.powi(k)
    }

    /// The scene as the renderers see it: scaled by `scale` (a
    /// `render_scale`), borrowed when that is 1.
    pub fn in_render_space(&self, scale: f64) -> std::borrow::Cow<'_, Scene> {
        if scale == 1.0 {
            std::borrow::Cow::Borrowed(self)
        } else {
            std::borrow::Cow::Owned(self.scaled(scale))
        }
    }

    /// Primitives too small for f32 where they are: a sphere whose radius,
    /// or a triangle whose longest edge, is under `RESOLVABLE` of its largest
    /// coordinate in view space (its distance from the camera, per axis). No scaling helps
    /// these: f32 keeps 24 bits relative to the coordinate. Measured on a
    /// sphere seen head-on: mis-shaded in f32 from 2^-22, missed at 2^-24.
    /// Each entry: (what and where, for a message).
    pub fn unresolvable(&self) -> Vec<String> {
        // Coordinates as the camera sees them (`in_view_space`), point by
        // point, so a big scene is not copied for its warnings.
        let view = self
            .camera
            .filter(|c| !c.is_classic_placement())
            .and_then(|c| Some((c, c.basis()?)));
        let seen = |p: DVec3| match &view {
            Some((cam, basis)) => cam.to_view(basis, p),
            None => p,
        };
        let mut out = Vec::new();
        for (i, s) in self.spheres.iter().enumerate() {
            let m = seen(s.center).abs().max_element() + s.radius;
            if s.radius < RESOLVABLE * m {
                let c = s.center;
                out.push(format!(
                    "sphere {i} at ({:e}, {:e}, {:e}), radius {:e}",
                    c.x, c.y, c.z, s.radius
                ));
            }
        }
        use rayon::prelude::*;
        let triangles = self.triangles.par_iter().enumerate().filter_map(|(i, t)| {
            let [a, b, c] = t.vertices.map(|v| v.position);
            let m = seen(a)
                .abs()
                .max(seen(b).abs())
                .max(seen(c).abs())
                .max_element();
            let edge = (b - a).length().max((c - b).length()).max((a - c).length());
            // Degenerate triangles are never hit; the parser warns of them.
            (edge > 0.0 && edge < RESOLVABLE * m).then(|| {
                format!(
                    "triangle {i} at ({:e}, {:e}, {:e}), longest edge {:e}",
                    a.x, a.y, a.z, edge
                )
            })
        });
        out.par_extend(triangles);
        out
    }

    /// `total`, the time this scene took to read, split as `-v` shows it:
    /// (`read`: model files' bytes, `parse`: what the others leave,
    /// `normals`: smooth normals and meshes made the scene's triangles).
    pub fn load_phases(
        &self,
        total: std::time::Duration,
    ) -> [(&'static str, std::time::Duration); 3] {
        let read = self.meshes.iter().map(|m| m.read_time).sum();
        let normals = self.meshes.iter().map(|m| m.normals_time).sum();
        let parse = total.saturating_sub(read + normals);
        [("read", read), ("parse", parse), ("normals", normals)]
    }

    /// `load_phases` as `-v` shows them: `read` and `normals` only where
    /// the scene names model files.
    pub fn shown_load_phases(
        &self,
        total: std::time::Duration,
    ) -> Vec<(&'static str, std::time::Duration)> {
        let phases = self.load_phases(total);
        if self.meshes.is_empty() {
            return vec![phases[1]];
        }
        phases.into()
    }

    /// Spheres and triangles together.
    pub fn primitive_count(&self) -> usize {
        self.spheres.len() + self.triangles.len()
    }

    /// Whether anything (geometry or light) has a velocity.
    pub fn has_motion(&self) -> bool {
        self.spheres.iter().any(|s| s.velocity != DVec3::ZERO)
            || self.triangles.iter().any(|t| t.velocity != DVec3::ZERO)
            || self.lights.iter().any(|l| l.velocity != DVec3::ZERO)
    }

    /// The vertical field of view the image is taken with, degrees.
    pub fn fov(&self) -> f64 {
        self.camera.map_or(crate::camera::FOV_Y_DEGREES, |c| c.fov)
    }
}
