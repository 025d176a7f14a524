//! What a scene holds and what it calls for (`glint info`).

use std::fmt;

use crate::bvh::Bvh;
use crate::scene::Scene;

/// The effects and primitive kinds a scene needs the renderer to simulate.
/// Today the classic format calls only for what the base shader does; this
/// is where area lights, reflection, motion and sampling will be detected.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Features {
    pub spheres: bool,
    pub triangles: bool,
    pub shadows: bool,
}

impl Features {
    pub fn of(scene: &Scene) -> Features {
        Features {
            spheres: !scene.spheres.is_empty(),
            triangles: !scene.triangles.is_empty(),
            shadows: !scene.lights.is_empty() && scene.primitive_count() > 0,
        }
    }
}

pub struct SceneInfo<'a> {
    pub scene: &'a Scene,
    pub bvh: &'a Bvh,
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
        for (i, l) in s.lights.iter().enumerate() {
            writeln!(
                f,
                "light {i:<5} at ({}, {}, {}) colour ({}, {}, {})",
                l.position.x, l.position.y, l.position.z, l.color.x, l.color.y, l.color.z
            )?;
        }
        writeln!(
            f,
            "bvh         {} nodes, depth {}",
            self.bvh.nodes.len(),
            self.bvh.depth
        )?;
        let feat = Features::of(s);
        let mut calls: Vec<&str> = Vec::new();
        if feat.spheres {
            calls.push("spheres");
        }
        if feat.triangles {
            calls.push("triangles");
        }
        if feat.shadows {
            calls.push("point-light shadows");
        }
        calls.push("Phong shading");
        write!(f, "calls for   {}", calls.join(", "))?;
        if !s.warnings.is_empty() {
            write!(f, "\nwarnings    {}", s.warnings.len())?;
        }
        Ok(())
    }
}
