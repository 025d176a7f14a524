//! The scenes `glint check` renders, generated here so the suite travels
//! inside the binary (the course's scenes are not ours to ship): classic
//! Phong scenes, each effect and all at once, the hard cases, a mesh, a big
//! BVH, heavy per-pixel work and many lights, and a scene whose lists are
//! split over bindings. Each states what it exercises and how close the
//! device must come to the CPU reference.

use std::fmt::Write as _;
use std::path::Path;

use glam::DVec3;

use crate::mesh::{self, Format, Refs};
use crate::scene::{parse_scene, Scene};

/// How close a device's image must be to the CPU reference's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerance {
    /// Against the f32 twin, which follows the shader's arithmetic
    /// operation for operation: pixels more than one 8-bit level off, as a
    /// fraction of the image (at least `min_pixels` allowed), and the FLIP
    /// mean. What is left is where a rounding difference (a fused
    /// multiply-add, another `pow`) flips a hit or shadow verdict exactly on
    /// an edge.
    pub f32_fraction: f64,
    /// At least this many pixels may be off, whatever the fraction.
    pub f32_min_pixels: usize,
    /// The FLIP mean allowed against the twin.
    pub f32_flip: f32,
    /// Against the f64 reference (ground truth): the FLIP mean, or `None`
    /// where the case is about f32's limits and the difference is reported,
    /// not judged.
    pub f64_flip: Option<f32>,
}

impl Tolerance {
    /// Every classic and effect scene: one pixel in 20,000 (the test
    /// suite's allowance for devices that contract to FMA where lavapipe
    /// does not), at least 4; FLIP 0.001 against the twin. Against f64,
    /// FLIP 0.01: f32's rounding moves edges by a pixel here and there.
    pub const TIGHT: Tolerance = Tolerance {
        f32_fraction: 5e-5,
        f32_min_pixels: 4,
        f32_flip: 1e-3,
        f64_flip: Some(0.01),
    };
    /// The hard cases are judged as the hard-case suite judges them: none
    /// of the failures each is built to provoke (cracks, acne, lost
    /// shadows, ...) on the device, counted by its probes against the
    /// analytic f64 reference (`hard::metrics`). Their images against the
    /// twin are reported, not judged: several put pixel rays exactly
    /// through vertices and edges, where which of the surfaces met at one
    /// t is kept is a tie each device's rounding breaks its own way
    /// (`vertex_rays`: 56 of 19,200 pixels on Mesa 22.3), or at exponents
    /// where a device's `pow` parts from the CPU's (`shininess_extremes`).
    pub const HARD: Tolerance = Tolerance {
        f32_fraction: 1.0,
        f32_min_pixels: usize::MAX,
        f32_flip: 1.0,
        f64_flip: None,
    };
}

/// One scene of the suite.
#[derive(Clone, Debug)]
pub struct Case {
    /// The case's name.
    pub name: String,
    /// What it exercises, in a few words.
    pub exercises: String,
    /// The scene.
    pub scene: Scene,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// How close the device must come.
    pub tolerance: Tolerance,
    /// Cap each storage binding at this many bytes (the split-binding
    /// case where the device's own limits are beyond the suite's sizes).
    pub storage_limit: Option<u64>,
    /// A hard case, also probed and held to its failure counts.
    pub hard: Option<crate::suites::hard::Case>,
}

/// How much of the suite, and how large.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    /// About a minute on lavapipe with 2 cores.
    Quick,
    /// Larger images, the million-triangle BVH, heavier workloads.
    Full,
}

const MAT: &str = "dif: 0.7 0.6 0.5 spe: 0.3 0.3 0.3 shi: 24";

/// A ground of `n` x `n` quads (two triangles each, sharing edges) at
/// y = -1, with unit normals tilted a little per vertex, as classic blocks.
fn ground(out: &mut String, n: usize, count: &mut usize) {
    let at = |i: usize, j: usize| {
        let x = -6.0 + 12.0 * i as f64 / n as f64;
        let z = -2.0 - 14.0 * j as f64 / n as f64;
        let tilt = 0.05 * ((i * 7 + j * 3) % 5) as f64 - 0.1;
        let nrm = DVec3::new(tilt, 1.0, -tilt).normalize();
        (DVec3::new(x, -1.0, z), nrm)
    };
    for j in 0..n {
        for i in 0..n {
            let c = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
            for t in [[0, 1, 2], [0, 2, 3]] {
                out.push_str("triangle\n");
                for k in t {
                    let (p, nn) = c[k];
                    let shade = if (i + j) % 2 == 0 {
                        "0.8 0.8 0.75"
                    } else {
                        "0.3 0.35 0.45"
                    };
                    let _ = writeln!(
                        out,
                        "pos: {} {} {} nor: {} {} {} dif: {shade} spe: 0.2 0.2 0.2 shi: 12",
                        p.x, p.y, p.z, nn.x, nn.y, nn.z
                    );
                }
                *count += 1;
            }
        }
    }
}

/// The classic-style base: a checker ground, four spheres, two lights,
/// and whatever `extra` adds (settings, lights, motion).
fn base(extra: &str, extra_objects: usize, sphere_tail: &str) -> Scene {
    let mut body = String::new();
    let mut count = 0;
    ground(&mut body, 6, &mut count);
    for (k, (x, y, z, r)) in [
        (-1.6, -0.2, -5.0, 0.8),
        (0.4, 0.0, -6.5, 1.0),
        (2.0, -0.4, -4.5, 0.6),
        (-0.2, 1.4, -8.0, 0.7),
    ]
    .into_iter()
    .enumerate()
    {
        let tail = if k == 0 { sphere_tail } else { "" };
        let _ = writeln!(body, "sphere pos: {x} {y} {z} rad: {r} {MAT} {tail}");
        count += 1;
    }
    body.push_str("light pos: -3 5 -2 col: 0.6 0.6 0.55\nlight pos: 4 3 0 col: 0.3 0.3 0.35\n");
    count += 2 + extra_objects;
    let text = format!("{count}\namb: 0.08 0.08 0.1\n{extra}\n{body}");
    parse_scene(text.as_bytes(), "check").expect("the check suite's scenes parse")
}

/// A tessellated sphere as OBJ text, loaded through the model loader
/// (smooth normals from the vertices, polygons cut into triangles).
fn mesh_scene() -> Scene {
    let (stacks, slices) = (24, 48);
    let mut obj = String::new();
    for s in 0..=stacks {
        let th = std::f64::consts::PI * s as f64 / stacks as f64;
        for k in 0..slices {
            let ph = 2.0 * std::f64::consts::PI * k as f64 / slices as f64;
            let _ = writeln!(
                obj,
                "v {} {} {}",
                th.sin() * ph.cos(),
                th.cos(),
                th.sin() * ph.sin()
            );
        }
    }
    for s in 0..stacks {
        for k in 0..slices {
            let a = s * slices + k + 1;
            let b = s * slices + (k + 1) % slices + 1;
            let _ = writeln!(obj, "f {a} {b} {} {}", b + slices, a + slices);
        }
    }
    let m = mesh::parse(
        obj.as_bytes(),
        Format::Obj,
        Path::new("check.obj"),
        Refs::None,
    )
    .expect("the check mesh loads");
    let mut scene = base("", 0, "");
    let kd = DVec3::new(0.3, 0.6, 0.8);
    let material = crate::scene::Material {
        kd,
        ks: DVec3::splat(0.5),
        shininess: 40.0,
    };
    let mut ids = crate::scene::MaterialIds::default();
    let tris = crate::scene::mesh::triangles(
        &m,
        Some(material),
        |p| p * 1.2 + DVec3::new(0.8, 0.4, -7.0),
        |n| n,
        |mat| ids.id(&mut scene.materials, mat),
    );
    scene.triangles.extend(tris);
    scene
}

/// A wall of `k` x `k` tessellated spheres: `k^2 * seg^2` triangles, the shape of the scale benchmarks' grids.
fn sphere_grid(k: usize, seg: usize) -> Scene {
    let mut scene = base("", 0, "");
    scene.triangles.clear();
    scene.spheres.clear();
    let material = crate::scene::Material {
        kd: DVec3::new(0.6, 0.5, 0.4),
        ks: DVec3::splat(0.3),
        shininess: 20.0,
    };
    let m = scene.add_material(material);
    let rings = seg / 2;
    for gy in 0..k {
        for gx in 0..k {
            let c = DVec3::new(
                -4.0 + 8.0 * (gx as f64 + 0.5) / k as f64,
                -3.0 + 6.0 * (gy as f64 + 0.5) / k as f64,
                -9.0,
            );
            let r = 3.6 / k as f64;
            let at = |i: usize, j: usize| {
                let th = std::f64::consts::PI * i as f64 / rings as f64;
                let ph = 2.0 * std::f64::consts::PI * j as f64 / seg as f64;
                DVec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin())
            };
            for i in 0..rings {
                for j in 0..seg {
                    let q = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                    for t in [[0, 1, 2], [0, 2, 3]] {
                        let vertices = t.map(|v| crate::scene::Vertex {
                            position: c + q[v] * r,
                            normal: q[v],
                            material: m,
                        });
                        scene.triangles.push(crate::scene::Triangle {
                            vertices,
                            velocity: DVec3::ZERO,
                        });
                    }
                }
            }
        }
    }
    scene
}

/// `n` point lights on a dome, dim enough to sum below white.
fn many_lights(n: usize) -> Scene {
    let mut lights = String::new();
    for i in 0..n {
        let a = i as f64 * 2.399_963;
        let h = 1.0 + 4.0 * (i as f64 / n as f64);
        let c = 1.5 / n as f64;
        let _ = writeln!(
            lights,
            "light pos: {} {h} {} col: {c} {c} {c}",
            5.0 * a.cos(),
            -6.0 + 5.0 * a.sin()
        );
    }
    base(&lights, n, "")
}

/// The suite at `level`. `storage_range` is the device's
/// `maxStorageBufferRange`: the split-binding case is sized to pass it
/// where that is cheap, else it caps the bindings (documented there).
pub fn cases(level: Level, storage_range: Option<u64>) -> Vec<Case> {
    let (w, h) = match level {
        Level::Quick => (96, 72),
        Level::Full => (320, 240),
    };
    let full = level == Level::Full;
    let case = |name: &str, exercises: &str, scene: Scene| Case {
        name: name.into(),
        exercises: exercises.into(),
        scene,
        width: w,
        height: h,
        tolerance: Tolerance::TIGHT,
        storage_limit: None,
        hard: None,
    };
    let mut out = vec![
        case(
            "phong",
            "spheres, shared-edge triangles, shadows, Phong",
            base("", 0, ""),
        ),
        case(
            "reflection",
            "recursive reflection, 3 bounces",
            base("reflect: 3", 0, ""),
        ),
        case(
            "soft_shadows",
            "sphere and rect area lights, 16 shadow rays",
            base(
                "shadow_samples: 16\nlight pos: 0 4 -6 col: 0.3 0.3 0.3 rad: 0.6\nlight pos: -2 3 -3 col: 0.2 0.2 0.25 edge_u: 1 0 0 edge_v: 0 0 1",
                2,
                "",
            ),
        ),
        case("antialiasing", "16 stratified samples a pixel", base("spp: 16", 0, "")),
        case(
            "motion_blur",
            "moving sphere, open shutter, 8 time samples",
            base("spp: 8\nshutter: 1\nfps: 24", 0, "vel: 12 0 0"),
        ),
        case(
            "all_effects",
            "reflection, area lights, antialiasing and motion together",
            base(
                "reflect: 2\nspp: 8\nshadow_samples: 8\nshutter: 0.5\nlight pos: 0 4 -6 col: 0.3 0.3 0.3 rad: 0.5",
                1,
                "vel: 8 0 0",
            ),
        ),
        case("mesh", "an OBJ model loaded, smooth normals", mesh_scene()),
        case(
            "far_camera",
            "a camera block far from the origin, moved into view space",
            {
                let mut s = base("", 0, "");
                let far = DVec3::new(3e5, -2e5, 4e5);
                s = s.mapped(&Shift(far));
                s.camera = Some(crate::scene::CameraSpec {
                    eye: far + DVec3::new(0.0, 0.5, 1.0),
                    look: far + DVec3::new(0.0, 0.0, -6.0),
                    up: DVec3::Y,
                    fov: 55.0,
                });
                s
            },
        ),
    ];
    for hard in crate::suites::hard::cases() {
        // Their own sizes: several are built around where pixel rays fall.
        let (hw, hh) = match level {
            Level::Quick => (hard.width / 2, hard.height / 2),
            Level::Full => (hard.width, hard.height),
        };
        out.push(Case {
            name: format!("hard_{}", hard.name),
            exercises: hard.what.clone(),
            scene: hard.scene.clone(),
            width: hw.max(1),
            height: hh.max(1),
            tolerance: Tolerance::HARD,
            storage_limit: None,
            hard: Some(hard),
        });
    }
    // A big tree: k^2 * seg^2 triangles.
    let (k, seg) = if full { (25, 40) } else { (10, 24) };
    out.push(case(
        "big_bvh",
        &format!(
            "a BVH of {} triangles",
            crate::units::thousands(k * k * seg * seg)
        ),
        sphere_grid(k, seg),
    ));
    let (spp, small) = if full {
        (2048, (64, 48))
    } else {
        (1024, (24, 18))
    };
    out.push(Case {
        width: small.0,
        height: small.1,
        ..case(
            "many_samples",
            &format!("{spp} samples a pixel with area lights: many passes a pixel"),
            base(
                &format!(
                    "spp: {spp}\nshadow_samples: 4\nlight pos: 0 4 -6 col: 0.3 0.3 0.3 rad: 0.6"
                ),
                1,
                "",
            ),
        )
    });
    let lights = if full { 4000 } else { 1000 };
    out.push(Case {
        width: small.0 * 2,
        height: small.1 * 2,
        ..case(
            "many_lights",
            &format!("{lights} point lights: long shading loops"),
            many_lights(lights),
        )
    });
    // Split bindings: the triangle list (48 bytes a triangle, with its
    // normals and materials beside it) past one storage binding. Where the
    // device's own limit is within reach (lavapipe's 128 MiB), the scene
    // passes it; elsewhere the bindings are capped so that a mid-size
    // scene splits the same way.
    let triangles_for = |bytes: u64| (bytes / 48 + 1) as usize;
    let (split_scene, cap) = match storage_range {
        Some(range) if full && range <= 128 << 20 => {
            let n = triangles_for(range);
            let seg = ((n as f64).sqrt() as usize).max(4) + 2;
            (sphere_grid(1, seg), None)
        }
        _ => {
            // The cap must hold the image's pixel state (128 bytes a
            // pixel) and output; the triangles then take two or three
            // chunks of it.
            let cap = (u64::from(w * h) * 128).next_power_of_two().max(1 << 20);
            let seg = ((triangles_for(cap * 5 / 2) as f64 / 36.0).sqrt() as usize).max(4);
            (sphere_grid(6, seg), Some(cap))
        }
    };
    out.push(Case {
        storage_limit: cap,
        ..case(
            "split_bindings",
            &match cap {
                Some(c) => format!("lists split over bindings (capped at {} KiB)", c >> 10),
                None => "lists split over bindings (past the device's own limit)".into(),
            },
            split_scene,
        )
    });
    out
}

/// Moves a scene by a fixed offset (the far-camera case).
struct Shift(DVec3);

impl crate::scene::SpaceMap for Shift {
    fn point(&self, p: DVec3, _: DVec3) -> DVec3 {
        p + self.0
    }
}
