//! Meshes and cameras: each model format loads to exactly the triangles it
//! describes (and renders as the same triangles written as classic blocks
//! do), `glint convert` round-trips, errors are located, the identity
//! camera is the classic one bit for bit, a moved camera sees what the
//! scene moved the other way shows, and the GPU agrees with the CPU on
//! real scanned models.

mod common;

use std::path::{Path, PathBuf};

use common::*;
use glam::DVec3;
use glint::scene::{parse_scene, read_scene, to_classic_text, Material, Scene, Vertex};

/// A 2x2 grid of quads (9 vertices) at z = -3, each vertex with a tilted
/// unit normal and a colour: the data every format below writes.
struct Grid {
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    colors: Vec<[u8; 3]>,
    quads: Vec<[u32; 4]>,
}

fn grid() -> Grid {
    let mut g = Grid {
        positions: Vec::new(),
        normals: Vec::new(),
        colors: Vec::new(),
        quads: Vec::new(),
    };
    for j in 0..3 {
        for i in 0..3 {
            let (x, y) = (f64::from(i) - 1.0, f64::from(j) - 1.0);
            g.positions
                .push(DVec3::new(x * 1.5, y * 1.25, -3.0 - 0.25 * x * y));
            g.normals
                .push(DVec3::new(x * 0.25, y * 0.5, 1.0).normalize());
            g.colors.push([40 * i as u8 + 60, 50 * j as u8 + 80, 200]);
        }
    }
    for j in 0..2 {
        for i in 0..2 {
            let v = j * 3 + i;
            g.quads.push([v, v + 1, v + 4, v + 3]);
        }
    }
    g
}

const MATERIAL: &str = "dif: 0.6 0.5 0.4 spe: 0.3 0.3 0.3 shi: 12";

fn material() -> Material {
    Material {
        kd: DVec3::new(0.6, 0.5, 0.4),
        ks: DVec3::splat(0.3),
        shininess: 12.0,
    }
}

/// The grid's triangles as the loaders should make them: quads fanned from
/// their first corner; `normals`: the file's, else the flat (0, 0, 1)-ish
/// smooth normals are not checked here; `colors`: kd from the vertex.
fn expected(g: &Grid, normals: bool, colors: bool) -> Vec<Corners> {
    let mut out = Vec::new();
    for q in &g.quads {
        for tri in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
            let vertices = tri.map(|i| {
                let i = i as usize;
                let mut m = material();
                if colors {
                    m.kd = DVec3::from(g.colors[i].map(|c| f64::from(c) / 255.0));
                }
                (
                    g.positions[i],
                    if normals { g.normals[i] } else { DVec3::ZERO },
                    m,
                )
            });
            out.push(vertices);
        }
    }
    out
}

/// A triangle's corners with their materials looked up: position, normal,
/// material.
type Corners = [(DVec3, DVec3, Material); 3];

fn corners(scene: &Scene) -> Vec<Corners> {
    let corner = |v: &Vertex| (v.position, v.normal, *scene.material(v));
    scene
        .triangles
        .iter()
        .map(|t| [0, 1, 2].map(|c| corner(&t.vertices[c])))
        .collect()
}

fn obj(g: &Grid) -> String {
    let mut s = String::from("# a grid\no grid\n");
    for p in &g.positions {
        s += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for n in &g.normals {
        s += &format!("vn {} {} {}\n", n.x, n.y, n.z);
    }
    s += "vt 0 0\n";
    for q in &g.quads {
        let c: Vec<String> = q
            .iter()
            .map(|&i| format!("{}/1/{}", i + 1, i + 1))
            .collect();
        s += &format!("f {}\n", c.join(" "));
    }
    s
}

fn off(g: &Grid) -> String {
    let mut s = format!("OFF\n# a grid\n{} {} 0\n", g.positions.len(), g.quads.len());
    for p in &g.positions {
        s += &format!("{} {} {}\n", p.x, p.y, p.z);
    }
    for q in &g.quads {
        s += &format!("4 {} {} {} {}\n", q[0], q[1], q[2], q[3]);
    }
    s
}

fn ply_header(g: &Grid, format: &str, xyz: &str) -> String {
    format!(
        "ply\nformat {format} 1.0\ncomment a grid\nelement vertex {}\nproperty {xyz} x\nproperty {xyz} y\nproperty {xyz} z\nproperty {xyz} nx\nproperty {xyz} ny\nproperty {xyz} nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        g.positions.len(),
        g.quads.len()
    )
}

fn ply_ascii(g: &Grid) -> Vec<u8> {
    let mut s = ply_header(g, "ascii", "double");
    for ((p, n), c) in g.positions.iter().zip(&g.normals).zip(&g.colors) {
        s += &format!(
            "{} {} {} {} {} {} {} {} {}\n",
            p.x, p.y, p.z, n.x, n.y, n.z, c[0], c[1], c[2]
        );
    }
    for q in &g.quads {
        s += &format!("4 {} {} {} {}\n", q[0], q[1], q[2], q[3]);
    }
    s.into_bytes()
}

fn ply_binary(g: &Grid, big: bool) -> Vec<u8> {
    let format = if big {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let mut b = ply_header(g, format, "double").into_bytes();
    let f = |v: f64| {
        if big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let i = |v: i32| {
        if big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    for ((p, n), c) in g.positions.iter().zip(&g.normals).zip(&g.colors) {
        for v in [p.x, p.y, p.z, n.x, n.y, n.z] {
            b.extend(f(v));
        }
        b.extend(c);
    }
    for q in &g.quads {
        b.push(4);
        for &k in q {
            b.extend(i(k as i32));
        }
    }
    b
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).expect("write test file");
    path
}

const LIGHT: &str = "light pos: 2 3 1 col: 0.9 0.9 0.9";

/// Each format loads to exactly the triangles it describes, and a scene
/// with the mesh renders bit for bit as the same triangles written as
/// classic blocks, on the CPU f32 twin and the GPU.
#[test]
fn every_format_loads_its_triangles_exactly() {
    let dir = tempfile::tempdir().expect("temp dir");
    let g = grid();
    let cases: Vec<(&str, Vec<u8>, bool, bool)> = vec![
        ("grid.obj", obj(&g).into_bytes(), true, false),
        ("grid.off", off(&g).into_bytes(), false, false),
        ("grid.ply", ply_ascii(&g), true, true),
        ("grid_le.ply", ply_binary(&g, false), true, true),
        ("grid_be.ply", ply_binary(&g, true), true, true),
    ];
    for (name, bytes, normals, colors) in cases {
        write(dir.path(), name, &bytes);
        let text = format!("2\namb: 0.1 0.1 0.1\n{LIGHT}\nmesh\nfile: {name}\n{MATERIAL}\n");
        let scene_path = write(dir.path(), "s.scene", text.as_bytes());
        let scene = read_scene(&scene_path).unwrap_or_else(|e| panic!("{name}: {e}"));
        let want = expected(&g, normals, colors);
        assert_eq!(scene.triangles.len(), want.len(), "{name}");
        for (k, (got, want)) in corners(&scene).iter().zip(&want).enumerate() {
            for c in 0..3 {
                let (a, b) = (&got[c], &want[c]);
                assert_eq!(a.0, b.0, "{name}: triangle {k} corner {c}");
                assert_eq!(a.2, b.2, "{name}: triangle {k} corner {c}");
                if normals {
                    assert!(
                        (a.1 - b.1).length() < 1e-15,
                        "{name}: triangle {k} corner {c}: {} vs {}",
                        a.1,
                        b.1
                    );
                } else {
                    // Smooth normals of a gently curved grid: unit, facing +z.
                    assert!((a.1.length() - 1.0).abs() < 1e-12 && a.1.z > 0.9);
                }
            }
        }
        assert_eq!(scene.meshes.len(), 1);
        assert_eq!(scene.meshes[0].triangles, 8);

        // The same triangles as classic blocks render bit for bit alike.
        let classic = parse_scene(to_classic_text(&scene).as_bytes(), "classic").expect("parses");
        assert_eq!(
            classic.triangles, scene.triangles,
            "{name}: classic text round trip"
        );
        let (w, h) = (48, 36);
        assert_eq!(
            render_cpu(&scene, w, h, glint::cpu::Precision::F32, WHITE),
            render_cpu(&classic, w, h, glint::cpu::Precision::F32, WHITE),
            "{name}"
        );
        if let Some(gpu) = render_gpu(&scene, w, h, WHITE) {
            assert_eq!(Some(gpu), render_gpu(&classic, w, h, WHITE), "{name}");
        }
    }
}

/// Transforms apply in the order written; OBJ materials come from its MTL;
/// a mesh counts as one object.
#[test]
fn transforms_materials_and_counts() {
    let dir = tempfile::tempdir().expect("temp dir");
    let g = grid();
    write(
        dir.path(),
        "m.mtl",
        b"newmtl red\nKd 0.9 0.1 0.1\nKs 0.2 0.2 0.2\nNs 30\nnewmtl blue\nKd 0.1 0.1 0.9\n",
    );
    let mut text = format!("mtllib m.mtl\n{}", obj(&g));
    // The first two quads red, the others blue.
    let at = text.find("f ").expect("faces");
    text.insert_str(at, "usemtl red\n");
    let third = text.match_indices("\nf ").nth(1).expect("third face").0;
    text.insert_str(third + 1, "usemtl blue\n");
    write(dir.path(), "m.obj", text.as_bytes());
    let scene = parse_scene(
        format!(
            "2\namb: 0 0 0\n{LIGHT}\nmesh file: m.obj scale: 2 translate: 1 0 0 rotate: 0 0 1 90\n"
        )
        .as_bytes(),
        &dir.path().join("s.scene").display().to_string(),
    )
    .expect("parses");
    let t = &scene.triangles;
    assert_eq!(t.len(), 8);
    let m = |k: usize| *scene.material(&t[k].vertices[0]);
    assert_eq!(m(0).kd, DVec3::new(0.9, 0.1, 0.1));
    assert_eq!(m(0).shininess, 30.0);
    assert_eq!(m(7).kd, DVec3::new(0.1, 0.1, 0.9));
    assert_eq!(m(7).ks, DVec3::ZERO, "MTL's default Ks");
    // (x, y, z) -> scale 2 -> +1 in x -> 90 degrees about z: (-y', x', z').
    let p = g.positions[0];
    let want = DVec3::new(-(2.0 * p.y), 2.0 * p.x + 1.0, 2.0 * p.z);
    assert!((t[0].vertices[0].position - want).length() < 1e-12);
    let n = g.normals[0];
    assert!((t[0].vertices[0].normal - DVec3::new(-n.y, n.x, n.z)).length() < 1e-12);
    // The block's own material wins over the file's.
    let scene = parse_scene(
        format!("1\namb: 0 0 0\nmesh file: m.obj {MATERIAL}\n").as_bytes(),
        &dir.path().join("s.scene").display().to_string(),
    )
    .expect("parses");
    assert!(scene
        .triangles
        .iter()
        .all(|t| *scene.material(&t.vertices[0]) == material()));
}

fn error_of(dir: &Path, scene: &str) -> String {
    let path = write(dir, "e.scene", scene.as_bytes());
    match read_scene(&path) {
        Ok(_) => panic!("{scene} parsed"),
        Err(e) => e.to_string(),
    }
}

/// Errors name the scene's mesh block (file:line:col) and the place in the
/// model file: its line, or for binary PLY its byte.
#[test]
fn mesh_and_camera_errors_are_located() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    write(d, "bad.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 zero\nf 1 2 3\n");
    write(d, "far.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
    for (block, wants) in [
        (
            "mesh\nfile: nope.obj",
            ["e.scene:4:7", "nope.obj", "cannot read"],
        ),
        (
            "mesh file: bad.obj",
            ["e.scene:3:12", "bad.obj, line 3", "`zero`"],
        ),
        (
            "mesh file: far.obj",
            ["e.scene:3:12", "far.obj, line 4", "index 4"],
        ),
    ] {
        let e = error_of(
            d,
            &format!("1\namb: 0 0 0\n{block} dif: 1 1 1 spe: 0 0 0 shi: 1\n"),
        );
        for want in wants {
            assert!(e.contains(want), "{block}: no {want:?} in {e}");
        }
    }
    let g = grid();
    let mut cut = ply_binary(&g, false);
    cut.truncate(cut.len() - 3);
    write(d, "cut.ply", &cut);
    let e = error_of(
        d,
        "1\namb: 0 0 0\nmesh file: cut.ply dif: 1 1 1 spe: 0 0 0 shi: 1\n",
    );
    assert!(
        e.contains("cut.ply, byte ") && e.contains("ends inside"),
        "{e}"
    );
    // A model without materials in a block without one: the default
    // material, and a warning at the block saying how to give one.
    write(d, "plain.off", off(&g).as_bytes());
    let path = write(d, "plain.scene", b"1\namb: 0 0 0\nmesh file: plain.off\n");
    let scene = read_scene(&path).expect("a model without materials loads");
    let w = scene
        .warnings
        .iter()
        .map(ToString::to_string)
        .collect::<String>();
    assert!(
        w.contains("plain.scene:3:6") && w.contains("brings no materials") && w.contains("dif:"),
        "{w}"
    );
    let default = glint::mesh::DEFAULT_MATERIAL;
    assert!(scene
        .triangles
        .iter()
        .all(|t| *scene.material(&t.vertices[0]) == default));
    for (camera, want) in [
        ("camera eye: 1 1 1 look: 1 1 1", "no view"),
        ("camera up: 0 0 1", "no view"),
        ("camera fov: 180", "below 180"),
        ("camera fov: 30 camera fov: 40", "at most one"),
    ] {
        let e = error_of(d, &format!("0\namb: 0 0 0\n{camera}\n"));
        assert!(e.contains(want), "{camera}: {e}");
    }
}

/// A camera block placed as the classic camera renders the classic image
/// bit for bit; a moved camera renders what the scene moved the other way
/// renders with the classic camera; a camera's field of view is its own.
#[test]
fn cameras_see_what_the_scene_moved_the_other_way_shows() {
    let base = read_scene(&repo_path("scenes/showcase.scene")).expect("showcase");
    let text = to_classic_text(&base);
    let with_camera = |camera: &str| {
        // The camera goes after the ambient line; it is not counted.
        let (head, rest) = text.split_once('\n').expect("count line");
        let (amb, rest) = rest.split_once('\n').expect("ambient line");
        parse_scene(format!("{head}\n{amb}\n{camera}\n{rest}").as_bytes(), "cam").expect("parses")
    };
    let (w, h) = (64, 48);
    let f32_ = glint::cpu::Precision::F32;
    let render = |s: &Scene| {
        let options = glint::render::RenderOptions {
            width: w,
            height: h,
            backend: glint::render::Backend::Cpu,
            ..Default::default()
        };
        glint::render::render(s, &options, &|_, _| {})
            .expect("renders")
            .into_framebuffer()
    };
    let classic = render_cpu(&base, w, h, f32_, WHITE);
    let identity = with_camera("camera eye: 0 0 0 look: 0 0 -1 up: 0 1 0 fov: 60");
    assert_eq!(render(&identity), classic, "identity camera");

    // Eye at (2, 0, 0) looking down -x: a view point (x, y, z) is the
    // world point (z + 2, y, -x). Move the scene there and look back.
    let moved = |p: DVec3| DVec3::new(p.z + 2.0, p.y, -p.x);
    let turned = |n: DVec3| DVec3::new(n.z, n.y, -n.x);
    let mut world = base.clone();
    for s in &mut world.spheres {
        s.center = moved(s.center);
    }
    for t in &mut world.triangles {
        for v in &mut t.vertices {
            v.position = moved(v.position);
            v.normal = turned(v.normal);
        }
    }
    for l in &mut world.lights {
        l.position = moved(l.position);
    }
    world.camera = Some(glint::scene::CameraSpec {
        eye: DVec3::new(2.0, 0.0, 0.0),
        look: DVec3::new(1.0, 0.0, 0.0),
        up: DVec3::Y,
        fov: 60.0,
    });
    let seen = render(&world);
    let cmp =
        glint::images::compare::compare_framebuffers(&seen, &classic, 1.0).expect("same size");
    assert_within(
        "moved camera",
        &seen,
        &classic,
        &cmp,
        (w * h / 500) as usize,
    );
    if gpu().is_some() {
        let options = glint::render::RenderOptions {
            width: w,
            height: h,
            backend: glint::render::Backend::Gpu,
            ..Default::default()
        };
        let on_gpu = glint::render::render(&world, &options, &|_, _| {})
            .expect("renders")
            .into_framebuffer();
        let cmp =
            glint::images::compare::compare_framebuffers(&on_gpu, &seen, 1.0).expect("same size");
        assert_within(
            "moved camera, GPU vs CPU",
            &on_gpu,
            &seen,
            &cmp,
            (w * h / 500) as usize,
        );
    }

    // `--pixel` on the moved camera reports world points: the classic
    // scene's point, moved.
    let cpu_options = glint::render::RenderOptions {
        width: w,
        height: h,
        backend: glint::render::Backend::Cpu,
        ..Default::default()
    };
    let path_of = |s: &Scene| {
        glint::render::pixel_path(s, &cpu_options, [w / 2, h / 2 + 6])
            .expect("pixel path")
            .value
    };
    let (here, there) = (path_of(&base), path_of(&world));
    let (p, q) = (
        here.surface.expect("a hit").point,
        there.surface.expect("a hit").point,
    );
    let want = moved(DVec3::from(p));
    assert!((DVec3::from(q) - want).length() < 1e-5, "{q:?} vs {want}");
    assert_eq!(here.prim, there.prim);

    // A narrower field of view magnifies: the centre pixel's neighbourhood
    // at 30 degrees covers what half as many pixels do at 60.
    let narrow = render(&with_camera("camera fov: 30"));
    assert_ne!(narrow, classic);
    let glint_wide = render(&with_camera("camera fov: 60"));
    assert_eq!(glint_wide, classic);
}

/// `glint convert`: a model to a scene (with the camera that frames it)
/// and back to OBJ keeps every triangle, bit for bit.
#[test]
fn convert_round_trips() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let g = grid();
    write(d, "grid.ply", &ply_ascii(&g));
    write(d, "grid.obj", obj(&g).as_bytes());
    let bin = env!("CARGO_BIN_EXE_glint");
    let run = |args: &[&str]| {
        let o = std::process::Command::new(bin)
            .args(args)
            .current_dir(d)
            .output()
            .expect("run glint");
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    // A model with vertex colours: they are the diffuse colours, the
    // flags give the rest.
    let out = run(&[
        "convert",
        "grid.ply",
        "ply.scene",
        "--spe",
        "0.3,0.3,0.3",
        "--shi",
        "12",
    ]);
    assert!(out.contains("8 triangles"), "{out}");
    let scene = read_scene(&d.join("ply.scene")).expect("converted scene parses");
    assert_eq!(corners(&scene), expected(&g, true, true));
    assert_eq!(scene.lights.len(), 1, "a light beside the camera");
    let camera = scene.camera.expect("the framing camera, as a block");
    let centre = scene.bounds().centroid();
    assert!(
        (camera.look - centre).length() < 1e-9,
        "{camera:?} looks at {centre}"
    );
    // Model -> classic scene -> OBJ -> mesh block: every bit kept.
    run(&[
        "convert",
        "grid.obj",
        "obj.scene",
        "--dif",
        "0.6,0.5,0.4",
        "--spe",
        "0.3,0.3,0.3",
        "--shi",
        "12",
    ]);
    let scene = read_scene(&d.join("obj.scene")).expect("converted scene parses");
    assert_eq!(corners(&scene), expected(&g, true, false));
    run(&["convert", "obj.scene", "back.obj"]);
    let again = parse_scene(
        b"1\namb: 0 0 0\nmesh file: back.obj\n",
        &d.join("x.scene").display().to_string(),
    )
    .expect("OBJ written by convert loads");
    assert_eq!(again.triangles, scene.triangles, "scene -> OBJ -> mesh");
}

/// Real scanned models (Debian's libcgal-demo): they load, and the GPU
/// renders them as the CPU f32 twin does.
#[test]
fn real_models_render_alike_on_gpu_and_cpu() {
    let data = Path::new("/usr/share/doc/libcgal-dev/data.tar.gz");
    if !data.is_file() {
        assert!(
            !in_ci(),
            "CI is set but libcgal-demo's {} is missing",
            data.display()
        );
        notice(&format!(
            "SKIPPED: real models: {} not found (apt-get install libcgal-demo)",
            data.display()
        ));
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let status = std::process::Command::new("tar")
        .args(["-xzf", &data.display().to_string(), "-C"])
        .arg(dir.path())
        .args([
            "--strip-components=2",
            "data/meshes/bunny00.off",
            "data/meshes/ChineseDragon-10kv.off",
        ])
        .status()
        .expect("run tar");
    assert!(status.success(), "tar failed");
    for (file, triangles) in [("bunny00.off", 75_408), ("ChineseDragon-10kv.off", 19_994)] {
        let text = format!(
            "3\namb: 0.1 0.1 0.1\ncamera eye: 0.3 0.5 1.8 look: 0 0 0 fov: 40\n{LIGHT}\nlight pos: -2 1 2 col: 0.3 0.3 0.4\nmesh file: {file} {MATERIAL}\n"
        );
        let scene = parse_scene(
            text.as_bytes(),
            &dir.path().join("s.scene").display().to_string(),
        )
        .unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(scene.triangles.len(), triangles, "{file}");
        assert_backends_agree(file, &scene.in_view_space(), 96, 72, 5);
    }
}

/// PLY's `tristrips` (as some scanned models ship): each run between `-1`s
/// makes a triangle of every three vertices in a row, every second one
/// turned so all wind alike; the repeated vertices that join strips make
/// no triangle and no warning.
#[test]
fn ply_triangle_strips_wind_alike() {
    let dir = tempfile::tempdir().expect("temp dir");
    let g = grid();
    let row = |j: u32| (0..3).flat_map(move |i| [3 * (j + 1) + i, 3 * j + i]);
    let restarted: Vec<i64> = row(0)
        .map(i64::from)
        .chain([-1])
        .chain(row(1).map(i64::from))
        .collect();
    let stitched: Vec<i64> = row(0).chain([2, 6]).chain(row(1)).map(i64::from).collect();
    for (name, strip) in [("restarted", restarted), ("stitched", stitched)] {
        let mut s = format!(
            "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\n\
             property double z\nelement tristrips 1\nproperty list int int vertex_indices\n\
             end_header\n",
            g.positions.len()
        );
        for p in &g.positions {
            s += &format!("{} {} {}\n", p.x, p.y, p.z);
        }
        s += &format!("{}", strip.len());
        for i in &strip {
            s += &format!(" {i}");
        }
        s += "\n";
        let file = format!("{name}.ply");
        write(dir.path(), &file, s.as_bytes());
        let scene_path = write(
            dir.path(),
            &format!("{name}.scene"),
            format!("1\namb: 0 0 0\nmesh file: {file} dif: 1 1 1 spe: 0 0 0 shi: 1\n").as_bytes(),
        );
        let scene = read_scene(&scene_path).expect("strips load");
        assert_eq!(scene.triangles.len(), 8, "{name}: two rows of two quads");
        assert!(
            scene.meshes[0].report.is_empty(),
            "{name}: {:?}",
            scene.meshes[0].report
        );
        let mut area = 0.0;
        for t in &scene.triangles {
            let [a, b, c] = t.vertices.map(|v| v.position);
            let n = (b - a).cross(c - a);
            assert!(
                n.z > 0.0,
                "{name}: a triangle winds the other way: {a} {b} {c}"
            );
            area += n.length() / 2.0;
        }
        // The grid bends a little out of its plane: a few percent more.
        assert!(
            (7.5..7.8).contains(&area),
            "{name}: covers {area}, not the grid"
        );
    }
}
