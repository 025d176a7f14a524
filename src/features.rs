//! What a scene, with its settings, calls for: the primitive kinds and
//! effects the shader is specialised for.

use glam::DVec3;

use crate::scene::{Effects, Scene};

/// The effects and primitive kinds a scene, with its settings, needs the
/// shader to simulate. It is also the key of the pipeline cache: each field
/// is a WGSL `override` of the same name in upper case, resolved before
/// SPIR-V is written, so a feature that is off is not in the shader at all.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Features {
    /// The scene has spheres.
    pub spheres: bool,
    /// The scene has triangles.
    pub triangles: bool,
    /// Reflection depth > 0 and some surface has a non-zero ks.
    pub reflection: bool,
    /// A light with a radius or edges: shadow rays sample its area.
    pub area_lights: bool,
    /// Something moves and the shutter is open: rays carry a time.
    pub motion_blur: bool,
    /// More than one primary sample per pixel (antialiasing, motion blur).
    pub multisample: bool,
}

impl Features {
    /// Every feature compiled in; effects are then switched by the run-time
    /// settings alone (the "generic" shader the benchmarks compare against).
    pub const ALL: Features = Features {
        spheres: true,
        triangles: true,
        reflection: true,
        area_lights: true,
        motion_blur: true,
        multisample: true,
    };

    /// What `scene` with `effects` calls for.
    pub fn of(scene: &Scene, effects: &Effects) -> Features {
        let sphere_ks = scene.spheres.iter().any(|s| s.material.ks != DVec3::ZERO);
        let triangle_ks = scene.triangles.iter().any(|t| {
            t.vertices
                .iter()
                .any(|v| scene.material(v).ks != DVec3::ZERO)
        });
        Features {
            spheres: !scene.spheres.is_empty(),
            triangles: !scene.triangles.is_empty(),
            reflection: effects.reflect_depth > 0 && (sphere_ks || triangle_ks),
            area_lights: scene.lights.iter().any(|l| l.shape.is_area()),
            motion_blur: effects.shutter > 0.0 && scene.has_motion(),
            multisample: effects.spp > 1,
        }
    }

    /// (override name, value) for naga's `process_overrides`.
    pub fn overrides(&self) -> [(&'static str, bool); 6] {
        [
            ("SPHERES", self.spheres),
            ("TRIANGLES", self.triangles),
            ("REFLECTION", self.reflection),
            ("AREA_LIGHTS", self.area_lights),
            ("MOTION_BLUR", self.motion_blur),
            ("MULTISAMPLE", self.multisample),
        ]
    }

    /// Names of the features that are on, e.g. "spheres+reflection".
    pub fn label(&self) -> String {
        let on: Vec<String> = self
            .overrides()
            .iter()
            .filter(|(_, on)| *on)
            .map(|(name, _)| name.to_ascii_lowercase())
            .collect();
        if on.is_empty() {
            "none".into()
        } else {
            on.join("+")
        }
    }
}
