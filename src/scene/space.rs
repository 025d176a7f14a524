//! Moving a whole scene to another space, in one place: the camera's view
//! space, a power-of-two scale, a moment of its motion. `SpaceMap` says
//! what happens to a position, a direction, a normal and a length;
//! `Scene::mapped` applies it to everything that has one.

use std::borrow::Cow;

use glam::{DQuat, DVec3};

use super::model::{CameraSpec, LightShape, Scene};

/// A change of space for `Scene::mapped`.
pub trait SpaceMap {
    /// A position, given the velocity of what it belongs to.
    fn point(&self, p: DVec3, velocity: DVec3) -> DVec3;
    /// A direction that lives in space: a velocity, a rect light's edge.
    fn vector(&self, v: DVec3) -> DVec3 {
        v
    }
    /// A shading normal, as written (not normalized again).
    fn normal(&self, n: DVec3) -> DVec3 {
        n
    }
    /// A length: a sphere's radius, a sphere light's.
    fn length(&self, r: f64) -> f64 {
        r
    }
}

impl Scene {
    /// The scene with every position, direction, normal and length moved by
    /// `map`; materials, settings and the camera block as they are.
    pub fn mapped(&self, map: &(impl SpaceMap + Sync)) -> Scene {
        let mut s = Scene::default();
        self.mapped_into(map, &mut s);
        s
    }

    /// `mapped`, written over `out`, whose lists keep their memory: an
    /// animation's frames reuse one scene's instead of faulting in fresh
    /// pages for each (a moving 2M-triangle scene is 400 MB a frame).
    pub(crate) fn mapped_into(&self, map: &(impl SpaceMap + Sync), out: &mut Scene) {
        use rayon::prelude::*;
        // Every field named, so that a new one is not forgotten here; the
        // primitives mapped as they are copied, on every thread.
        let Scene {
            ambient,
            spheres,
            triangles,
            materials,
            lights,
            settings,
            warnings,
            more_warnings,
            camera,
            meshes,
        } = self;
        out.spheres.clear();
        out.spheres
            .par_extend(spheres.par_iter().with_min_len(1 << 12).map(|sphere| {
                let mut sphere = *sphere;
                sphere.center = map.point(sphere.center, sphere.velocity);
                sphere.radius = map.length(sphere.radius);
                sphere.velocity = map.vector(sphere.velocity);
                sphere
            }));
        out.triangles.clear();
        out.triangles
            .par_extend(triangles.par_iter().with_min_len(1 << 12).map(|t| {
                let mut t = *t;
                for v in &mut t.vertices {
                    v.position = map.point(v.position, t.velocity);
                    v.normal = map.normal(v.normal);
                }
                t.velocity = map.vector(t.velocity);
                t
            }));
        out.lights.clear();
        out.lights.extend(lights.iter().map(|l| {
            let mut l = *l;
            l.position = map.point(l.position, l.velocity);
            l.velocity = map.vector(l.velocity);
            l.shape = match l.shape {
                LightShape::Point => LightShape::Point,
                LightShape::Sphere { radius } => LightShape::Sphere {
                    radius: map.length(radius),
                },
                LightShape::Rect { edge_u, edge_v } => LightShape::Rect {
                    edge_u: map.vector(edge_u),
                    edge_v: map.vector(edge_v),
                },
            };
            l
        }));
        out.ambient = *ambient;
        out.materials.clone_from(materials);
        out.settings = *settings;
        out.warnings.clone_from(warnings);
        out.more_warnings = *more_warnings;
        out.camera = *camera;
        out.meshes.clone_from(meshes);
    }

    /// The scene at `time` seconds: everything moved along its velocity.
    /// Velocities are kept, so motion blur can sample the shutter from there.
    pub fn at_time(&self, time: f64) -> Scene {
        if time == 0.0 {
            return self.clone();
        }
        struct At(f64);
        impl SpaceMap for At {
            fn point(&self, p: DVec3, velocity: DVec3) -> DVec3 {
                p + velocity * self.0
            }
        }
        self.mapped(&At(time))
    }

    /// The scene in view space: what the renderers trace, with the camera
    /// at the origin looking down -z (the classic camera) and the field of
    /// view kept. Borrowed when there is no camera block or it is placed
    /// as the classic one, so classic scenes are not touched. Positions
    /// are moved and rotated in f64 (normals, velocities and light edges
    /// rotated), once, before anything is rounded to f32.
    pub fn in_view_space(&self) -> Cow<'_, Scene> {
        self.at_time_in_view_space(0.0)
    }

    /// `self.at_time(time).in_view_space()`, bit for bit, in one pass over
    /// the primitives instead of two copies.
    pub fn at_time_in_view_space(&self, time: f64) -> Cow<'_, Scene> {
        if self.view_basis().is_none() && time == 0.0 {
            return Cow::Borrowed(self);
        }
        let mut s = Scene::default();
        self.at_time_in_view_space_into(time, &mut s);
        Cow::Owned(s)
    }

    /// `at_time_in_view_space`, written over `out` (`mapped_into`): what an
    /// animation's frame renders.
    pub(crate) fn at_time_in_view_space_into(&self, time: f64, out: &mut Scene) {
        struct View(f64, Option<(CameraSpec, [DVec3; 3])>);
        impl SpaceMap for View {
            fn point(&self, p: DVec3, velocity: DVec3) -> DVec3 {
                // `at_time`'s step, then the view's: the same operations.
                let p = if self.0 == 0.0 {
                    p
                } else {
                    p + velocity * self.0
                };
                match &self.1 {
                    Some((cam, basis)) => cam.to_view(basis, p),
                    None => p,
                }
            }
            fn vector(&self, v: DVec3) -> DVec3 {
                match &self.1 {
                    Some((_, basis)) => CameraSpec::dir_to_view(basis, v),
                    None => v,
                }
            }
            fn normal(&self, n: DVec3) -> DVec3 {
                self.vector(n)
            }
        }
        let view = self.view_basis();
        self.mapped_into(&View(time, view), out);
        if let Some((cam, _)) = view {
            out.camera = Some(CameraSpec {
                fov: cam.fov,
                ..CameraSpec::CLASSIC
            });
        }
    }

    /// The camera block and its basis where it moves the scene (not placed
    /// as the classic camera). The parser refuses a camera without a
    /// basis; such a scene is kept as it is.
    fn view_basis(&self) -> Option<(CameraSpec, [DVec3; 3])> {
        self.camera
            .filter(|cam| !cam.is_classic_placement())
            .and_then(|cam| Some((cam, cam.basis()?)))
    }

    /// The scene scaled by `factor` about the camera (the origin): positions,
    /// radii, light shapes and velocities; the image is unchanged in exact
    /// arithmetic. Normals keep their length (the shading normalizes them).
    pub fn scaled(&self, factor: f64) -> Scene {
        struct Scale(f64);
        impl SpaceMap for Scale {
            fn point(&self, p: DVec3, _: DVec3) -> DVec3 {
                p * self.0
            }
            fn vector(&self, v: DVec3) -> DVec3 {
                v * self.0
            }
            fn length(&self, r: f64) -> f64 {
                r * self.0
            }
        }
        self.mapped(&Scale(factor))
    }

    /// The scene turned by `turn` about the origin (the camera).
    pub fn turned(&self, turn: DQuat) -> Scene {
        struct Turn(DQuat);
        impl SpaceMap for Turn {
            fn point(&self, p: DVec3, _: DVec3) -> DVec3 {
                self.0 * p
            }
            fn vector(&self, v: DVec3) -> DVec3 {
                self.0 * v
            }
            fn normal(&self, n: DVec3) -> DVec3 {
                self.0 * n
            }
        }
        self.mapped(&Turn(turn))
    }
}
