//! Writing a `Scene` back in the classic format, with numbers that parse to
//! the same f64 values (Rust's shortest round-trip formatting).

use std::fmt::Write as _;

use glam::DVec3;

use super::model::{LightShape, Material, Scene};

/// Shortest text that parses back to `x`: plain decimals for ordinary
/// magnitudes, exponent form (`1e-16`) otherwise, both accepted by the parser.
fn num(x: f64) -> String {
    let a = x.abs();
    if x == 0.0 || (1e-4..1e7).contains(&a) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

fn v3(v: DVec3) -> String {
    format!("{} {} {}", num(v.x), num(v.y), num(v.z))
}

fn material(out: &mut String, m: &Material) {
    let _ = writeln!(out, "dif: {}", v3(m.kd));
    let _ = writeln!(out, "spe: {}", v3(m.ks));
    let _ = writeln!(out, "shi: {}", num(m.shininess));
}

fn velocity(out: &mut String, v: DVec3) {
    if v != DVec3::ZERO {
        let _ = writeln!(out, "vel: {}", v3(v));
    }
}

/// The scene in the classic format: count, ambient, lights, spheres,
/// triangles (a mesh's among them). Extensions (settings, camera, area
/// lights, velocities) are written only where the scene has them, so a
/// classic scene stays classic.
pub fn to_classic_text(scene: &Scene) -> String {
    let mut out = String::new();
    let count = scene.lights.len() + scene.spheres.len() + scene.triangles.len();
    let _ = writeln!(out, "{count}");
    let _ = writeln!(out, "amb: {}", v3(scene.ambient));
    let st = &scene.settings;
    let ints = [
        ("reflect", st.reflect),
        ("spp", st.spp),
        ("shadow_samples", st.shadow_samples),
        ("seed", st.seed),
    ];
    for (name, value) in ints {
        if let Some(v) = value {
            let _ = writeln!(out, "{name}: {v}");
        }
    }
    for (name, value) in [("shutter", st.shutter), ("fps", st.fps)] {
        if let Some(v) = value {
            let _ = writeln!(out, "{name}: {}", num(v));
        }
    }
    if let Some(sampler) = st.sampler {
        let _ = writeln!(out, "sampler: {sampler}");
    }
    if let Some(c) = &scene.camera {
        let _ = writeln!(
            out,
            "camera\neye: {}\nlook: {}\nup: {}\nfov: {}",
            v3(c.eye),
            v3(c.look),
            v3(c.up),
            num(c.fov)
        );
    }
    for l in &scene.lights {
        let _ = writeln!(out, "light\npos: {}\ncol: {}", v3(l.position), v3(l.color));
        match l.shape {
            LightShape::Point => {}
            LightShape::Sphere { radius } => {
                let _ = writeln!(out, "rad: {}", num(radius));
            }
            LightShape::Rect { edge_u, edge_v } => {
                let _ = writeln!(out, "edge_u: {}\nedge_v: {}", v3(edge_u), v3(edge_v));
            }
        }
        velocity(&mut out, l.velocity);
    }
    for s in &scene.spheres {
        let _ = writeln!(out, "sphere\npos: {}\nrad: {}", v3(s.center), num(s.radius));
        material(&mut out, &s.material);
        velocity(&mut out, s.velocity);
    }
    for t in &scene.triangles {
        out.push_str("triangle\n");
        for v in &t.vertices {
            let _ = writeln!(out, "pos: {}\nnor: {}", v3(v.position), v3(v.normal));
            material(&mut out, scene.material(v));
        }
        velocity(&mut out, t.velocity);
    }
    out
}
