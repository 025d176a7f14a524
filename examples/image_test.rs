//! An image test of one's own scene, as `glint check` tests its suite: the
//! scene on the Vulkan device (lavapipe in CI) and on the CPU reference,
//! held to `glint check`'s tolerances; on failure the device's image, the
//! CPU's and their difference are written for a person to look at, and
//! the process exits 1.
//!
//! `cargo run --release --example image_test`

use std::process::ExitCode;

use glint::suites::check::{image_test, ImageTest};

/// Two spheres over a ground of two triangles with per-vertex normals, a
/// point light casting one sphere's shadow on the other and the ground.
const SCENE: &str = "\
5
amb: 0.2 0.2 0.2
sphere
pos: -0.6 0 -3.5
rad: 0.6
dif: 0.2 0.5 0.9
spe: 0.4 0.4 0.4
shi: 30
sphere
pos: 0.8 0.3 -4.5
rad: 0.8
dif: 0.9 0.6 0.2
spe: 0.2 0.2 0.2
shi: 8
triangle
pos: -4 -0.6 -1
nor: 0 1 0
dif: 0.6 0.6 0.6
spe: 0.1 0.1 0.1
shi: 4
pos: 4 -0.6 -1
nor: 0.1 1 0
dif: 0.6 0.6 0.6
spe: 0.1 0.1 0.1
shi: 4
pos: 4 -0.6 -9
nor: 0 1 0.1
dif: 0.6 0.6 0.6
spe: 0.1 0.1 0.1
shi: 4
triangle
pos: -4 -0.6 -1
nor: 0 1 0
dif: 0.6 0.6 0.6
spe: 0.1 0.1 0.1
shi: 4
pos: 4 -0.6 -9
nor: 0 1 0.1
dif: 0.6 0.6 0.6
spe: 0.1 0.1 0.1
shi: 4
pos: -4 -0.6 -9
nor: -0.1 1 0
dif: 0.6 0.6 0.6
spe: 0.1 0.1 0.1
shi: 4
light
pos: -3 4 0
col: 0.8 0.8 0.8
";

fn main() -> Result<ExitCode, glint::Error> {
    let scene = glint::scene::parse_scene(SCENE.as_bytes(), "<string>")?;
    let out = std::env::temp_dir().join("glint-image-test");
    let test = ImageTest {
        out: Some(out.clone()),
        ..ImageTest::new("two_spheres", 320, 240)
    };
    let verdict = image_test(&scene, &test)?;
    println!(
        "{} on {}: {} pixels more than one level off the CPU f32 twin (allowed {}), \
         FLIP {:.5} against it and {:.4} against the f64 truth",
        test.name,
        verdict.device,
        verdict.against_twin.over_threshold,
        verdict.allowed,
        verdict.against_twin.flip_mean,
        verdict.against_truth.flip_mean
    );
    match &verdict.failure {
        None => {
            println!("passed");
            Ok(ExitCode::SUCCESS)
        }
        Some(why) => {
            println!("FAILED: {why}");
            for path in &verdict.written {
                println!("  wrote {}", path.display());
            }
            Ok(ExitCode::from(1))
        }
    }
}
