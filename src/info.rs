//! What a scene holds and what it calls for (`glint info`).

use std::fmt;

use glam::DVec3;

use crate::bvh::Bvh;
use crate::features::Features;
use crate::scene::{Effects, LightShape, Scene};

/// What `glint info` prints of a scene: counts, bounds, lights, the tree
/// and the effects (its `Display`).
pub struct SceneInfo<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its BVH.
    pub bvh: &'a Bvh,
    /// The scene's settings with any command-line overrides applied.
    pub effects: Effects,
}

impl fmt::Display for SceneInfo<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.scene;
        writeln!(f, "spheres     {}", s.spheres.len())?;
        writeln!(f, "triangles   {}", s.triangles.len())?;
        writeln!(f, "lights      {}", s.lights.len())?;
        let a = s.ambient;
        writeln!(f, "ambient     {} {} {}", a.x, a.y, a.z)?;
        let b = s.bounds();
        if b.is_empty() {
            writeln!(f, "bounds      (no geometry)")?;
        } else {
            writeln!(
                f,
                "bounds      ({}, {}, {}) .. ({}, {}, {})",
                b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z
            )?;
        }
        for m in &s.meshes {
            let b = m.bounds;
            writeln!(
                f,
                "mesh        {}: {} triangles, bounds ({}, {}, {}) .. ({}, {}, {}), {}",
                m.file,
                m.triangles,
                b.min.x,
                b.min.y,
                b.min.z,
                b.max.x,
                b.max.y,
                b.max.z,
                // A load takes time; a scene read back from the cache
                // loaded nothing, and says so.
                if m.load_time.is_zero() {
                    "from the scene cache".to_string()
                } else {
                    format!("loaded in {:.1} ms", m.load_time.as_secs_f64() * 1e3)
                }
            )?;
            if !m.report.is_empty() {
                writeln!(f, "  tolerated {}", m.report.summary())?;
            }
        }
        if let Some(c) = &s.camera {
            writeln!(
                f,
                "camera      eye ({}, {}, {}), looking at ({}, {}, {}), up ({}, {}, {}), {}° vertical field of view",
                c.eye.x, c.eye.y, c.eye.z, c.look.x, c.look.y, c.look.z, c.up.x, c.up.y, c.up.z, c.fov
            )?;
        }
        if self.bvh.scale != 1.0 {
            writeln!(
                f,
                "render scale 2^{}: the geometry's extent {:e} is outside [2^-10, 2^14], so \
                 every renderer works on the scene scaled by it (exact; the image does not change)",
                self.bvh.scale.log2(),
                s.extent()
            )?;
        }
        for (i, l) in s.lights.iter().enumerate() {
            let shape = match l.shape {
                LightShape::Point => "point".to_string(),
                LightShape::Sphere { radius } => format!("sphere radius {radius}"),
                LightShape::Rect { edge_u, edge_v } => {
                    format!("rectangle {} x {}", edge_u.length(), edge_v.length())
                }
            };
            write!(
                f,
                "light {i:<5} {shape} at ({}, {}, {}) colour ({}, {}, {})",
                l.position.x, l.position.y, l.position.z, l.color.x, l.color.y, l.color.z
            )?;
            if l.velocity != DVec3::ZERO {
                let v = l.velocity;
                write!(f, " moving ({}, {}, {})/s", v.x, v.y, v.z)?;
            }
            let on = self.bvh.surfaces_at_lights.get(i).map_or(0, Vec::len);
            if on > 0 {
                write!(f, ", on {on} surface(s), which do not shadow it")?;
            }
            writeln!(f)?;
        }
        writeln!(f, "bvh         {}", self.bvh.stats())?;
        let e = &self.effects;
        writeln!(
            f,
            "settings    reflect {}, spp {}, shadow samples {}, shutter {}, seed {}, fps {}, sampler {}",
            e.reflect_depth, e.spp, e.shadow_samples, e.shutter, e.seed, e.fps, e.sampler
        )?;
        let feat = Features::of(s, e);
        let mut calls: Vec<String> = Vec::new();
        if feat.spheres {
            calls.push("spheres".into());
        }
        if feat.triangles {
            calls.push("triangles".into());
        }
        if !s.lights.is_empty() && s.primitive_count() > 0 {
            calls.push("shadow rays".into());
        }
        calls.push("Phong shading".into());
        if feat.reflection {
            calls.push(format!("reflection (depth {})", e.reflect_depth));
        }
        if feat.area_lights {
            calls.push(format!("area lights ({} shadow samples)", e.shadow_samples));
        }
        if feat.multisample {
            calls.push(format!("antialiasing ({} samples per pixel)", e.spp));
        }
        if feat.motion_blur {
            calls.push(format!("motion blur (shutter {})", e.shutter));
        } else if s.has_motion() {
            calls.push("motion (animation only: the shutter is closed)".into());
        }
        writeln!(f, "calls for   {}", calls.join(", "))?;
        write!(f, "shader      {}", feat.label())?;
        if !s.warnings.is_empty() {
            write!(f, "\nwarnings    {}", s.warnings.len())?;
        }
        Ok(())
    }
}
