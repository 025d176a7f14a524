//! The scene model: what a classic CSCI 420 scene file describes, in f64.
//!
//! Values are kept exactly as parsed (f64), so the CPU f64 reference sees the
//! file's own numbers; the GPU packing (`layout`) and the CPU f32 path round
//! them to f32 once, in one place each.

mod parse;
mod write;

pub use parse::{parse_scene, read_scene, Diagnostic, ParseError};
pub use write::to_classic_text;

use glam::DVec3;

/// Diffuse and specular reflectance with a Phong exponent, per channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub kd: DVec3,
    pub ks: DVec3,
    pub shininess: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub center: DVec3,
    pub radius: f64,
    pub material: Material,
}

/// One corner of a triangle: position, shading normal (as written, not
/// normalized: interpolation happens before normalization) and material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vertex {
    pub position: DVec3,
    pub normal: DVec3,
    pub material: Material,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    pub vertices: [Vertex; 3],
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    pub position: DVec3,
    pub color: DVec3,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Scene {
    pub ambient: DVec3,
    pub spheres: Vec<Sphere>,
    pub triangles: Vec<Triangle>,
    pub lights: Vec<Light>,
    /// Questionable but renderable input (e.g. a zero-length normal), with
    /// its location, for the CLI to print.
    pub warnings: Vec<Diagnostic>,
}

/// Axis-aligned bounds of a set of points, in f64.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub min: DVec3,
    pub max: DVec3,
}

impl Bounds {
    pub const EMPTY: Bounds = Bounds {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    pub fn union(self, other: Bounds) -> Bounds {
        Bounds {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    pub fn grow(self, p: DVec3) -> Bounds {
        Bounds {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    pub fn centroid(&self) -> DVec3 {
        (self.min + self.max) * 0.5
    }

    pub fn surface_area(&self) -> f64 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.max - self.min;
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }
}

impl Sphere {
    pub fn bounds(&self) -> Bounds {
        Bounds {
            min: self.center - DVec3::splat(self.radius),
            max: self.center + DVec3::splat(self.radius),
        }
    }
}

impl Triangle {
    pub fn bounds(&self) -> Bounds {
        self.vertices
            .iter()
            .fold(Bounds::EMPTY, |b, v| b.grow(v.position))
    }
}

impl Scene {
    /// Bounds of all geometry (lights excluded); empty for an empty scene.
    pub fn bounds(&self) -> Bounds {
        let s = self.spheres.iter().map(Sphere::bounds);
        let t = self.triangles.iter().map(Triangle::bounds);
        s.chain(t).fold(Bounds::EMPTY, Bounds::union)
    }

    pub fn primitive_count(&self) -> usize {
        self.spheres.len() + self.triangles.len()
    }

    /// The scene scaled by `factor` about the camera (the origin): positions,
    /// radii and light positions; the image is unchanged in exact arithmetic.
    pub fn scaled(&self, factor: f64) -> Scene {
        let mut s = self.clone();
        for sphere in &mut s.spheres {
            sphere.center *= factor;
            sphere.radius *= factor;
        }
        for t in &mut s.triangles {
            for v in &mut t.vertices {
                v.position *= factor;
            }
        }
        for l in &mut s.lights {
            l.position *= factor;
        }
        s
    }
}
