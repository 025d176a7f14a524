//! Writing a `Scene` back in the classic format, with numbers that parse to
//! the same f64 values (Rust's shortest round-trip formatting).

use std::fmt::Write as _;

use glam::DVec3;

use super::{Material, Scene};

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

/// The scene in the classic format: count, ambient, lights, spheres, triangles.
pub fn to_classic_text(scene: &Scene) -> String {
    let mut out = String::new();
    let count = scene.lights.len() + scene.spheres.len() + scene.triangles.len();
    let _ = writeln!(out, "{count}");
    let _ = writeln!(out, "amb: {}", v3(scene.ambient));
    for l in &scene.lights {
        let _ = writeln!(out, "light\npos: {}\ncol: {}", v3(l.position), v3(l.color));
    }
    for s in &scene.spheres {
        let _ = writeln!(out, "sphere\npos: {}\nrad: {}", v3(s.center), num(s.radius));
        material(&mut out, &s.material);
    }
    for t in &scene.triangles {
        out.push_str("triangle\n");
        for v in &t.vertices {
            let _ = writeln!(out, "pos: {}\nnor: {}", v3(v.position), v3(v.normal));
            material(&mut out, &v.material);
        }
    }
    out
}
