//! Model files as they are found in the wild: every repair a loader makes
//! instead of refusing is a warning naming the file and place, never a
//! silent change; STL and glTF load the same triangles as OBJ; endless or
//! binary input is refused early, with bounded memory. Each case is a small
//! file written here.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use common::*;
use glam::DVec3;
use glint::cpu::Precision;
use glint::mesh::{self, Format, Mesh, Refs, Tolerance};
use glint::scene::{read_scene, Scene};

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).expect("write test file");
    path
}

fn load(dir: &Path, name: &str, bytes: &[u8]) -> Mesh {
    let path = write(dir, name, bytes);
    mesh::load(&path).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn count(m: &Mesh, kind: Tolerance) -> usize {
    m.report.counts.get(&kind).copied().unwrap_or(0)
}

fn warnings(m: &Mesh) -> String {
    m.report.kept.iter().map(|w| format!("{w}\n")).collect()
}

fn glint(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_glint"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run glint")
}

const MATERIAL: &str = "dif: 0.6 0.5 0.4 spe: 0.3 0.3 0.3 shi: 12";

/// The exact panic of the issue: normals given, faces that do not use
/// them. It loads with smooth normals and says so; `convert` too.
#[test]
fn normals_that_no_face_uses_do_not_panic() {
    let dir = tempfile::tempdir().expect("temp dir");
    let obj = b"# 13 lines\nv -1 -1 -3\nv 1 -1 -3\nv 1 1 -3\nv -1 1 -3\n\
vn 0 1 0\nvn 0 1 0\nvn 0 1 0\nvn 0 1 0\n\ng quad\ns off\nf 1 2 3 4\n";
    let m = load(dir.path(), "quad.obj", obj);
    assert_eq!(m.faces.len(), 2);
    assert_eq!(count(&m, Tolerance::UnusedNormals), 1, "{}", warnings(&m));
    assert!(warnings(&m).contains("quad.obj"), "{}", warnings(&m));
    write(
        dir.path(),
        "quad.scene",
        format!("1\namb: 0 0 0\nmesh file: quad.obj {MATERIAL}\n").as_bytes(),
    );
    let o = glint(&["convert", "quad.scene", "out.scene"], dir.path());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no face refers to them"));
    let o = glint(&["info", "quad.scene"], dir.path());
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("tolerated 1 normals never used"));
}

/// Materials a file names but nobody defines, a library that is missing,
/// and MTL statements without values: the block's material or the
/// field's default, each with a warning at its line.
#[test]
fn missing_materials_and_libraries_fall_back_with_warnings() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let tri = "v 0 0 -3\nv 1 0 -3\nv 0 1 -3\n";
    let m = load(
        d,
        "default.obj",
        format!("{tri}usemtl Default\nf 1 2 3\n").as_bytes(),
    );
    assert_eq!(count(&m, Tolerance::UndefinedMaterial), 1);
    assert!(
        warnings(&m).contains("default.obj, line 4"),
        "{}",
        warnings(&m)
    );
    assert_eq!(m.faces[0].material, None);

    let m = load(
        d,
        "nolib.obj",
        format!("mtllib gone.mtl\n{tri}usemtl red\nf 1 2 3\n").as_bytes(),
    );
    assert_eq!(count(&m, Tolerance::MissingLibrary), 1);
    assert_eq!(count(&m, Tolerance::UndefinedMaterial), 1);
    assert!(
        warnings(&m).contains("nolib.obj, line 1"),
        "{}",
        warnings(&m)
    );

    write(
        d,
        "lib.mtl",
        b"newmtl red\nKd\nKs 0.5\nNs -3\nmap_Kd red.png\nKd 0.9\n",
    );
    let m = load(
        d,
        "lib.obj",
        format!("mtllib lib.mtl\n{tri}usemtl red\nf 1 2 3\n").as_bytes(),
    );
    assert_eq!(count(&m, Tolerance::MaterialValue), 2, "{}", warnings(&m));
    assert_eq!(count(&m, Tolerance::TextureIgnored), 1);
    assert!(warnings(&m).contains("lib.mtl, line 2"), "{}", warnings(&m));
    // `Ks 0.5` alone is grey 0.5; the later `Kd 0.9` is grey 0.9.
    let red = m.materials[0];
    assert_eq!(red.ks, DVec3::splat(0.5));
    assert_eq!(red.kd, DVec3::splat(0.9));
    assert_eq!(red.shininess, 0.0);

    // Through a scene: the block's material where the file has none.
    write(
        d,
        "s.scene",
        format!("1\namb: 0 0 0\nmesh file: default.obj {MATERIAL}\n").as_bytes(),
    );
    let scene = read_scene(&d.join("s.scene")).expect("loads");
    assert_eq!(
        scene.material(&scene.triangles[0].vertices[0]).shininess,
        12.0
    );
}

/// Normals that are not finite or have no length, faces with normals on
/// some corners only: the smooth normal there, and a warning.
#[test]
fn bad_and_partial_normals_are_recomputed() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let m = load(
        d,
        "bad.obj",
        b"v 0 0 -3\nv 1 0 -3\nv 0 1 -3\nvn nan 0 1\nvn 0 0 0\nvn 0 0 1\nf 1//1 2//2 3//3\nf 1//3 2 3//3\n",
    );
    assert_eq!(count(&m, Tolerance::BadNormal), 2, "{}", warnings(&m));
    assert_eq!(count(&m, Tolerance::PartialNormals), 1, "{}", warnings(&m));
    assert_eq!(m.faces[0].normals, Some([mesh::SMOOTH, mesh::SMOOTH, 2]));
    assert_eq!(m.faces[1].normals, None);
    // Every normal the renderer gets is unit: the smooth one is (0, 0, 1).
    let tris = glint::scene::mesh::triangles(&m, None, |p| p, |n| n, |_| 0);
    for v in tris.iter().flat_map(|t| t.vertices) {
        assert!((v.normal - DVec3::Z).length() < 1e-12, "{:?}", v.normal);
    }

    let ply = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face 1\n\
property list uchar int vertex_indices\nend_header\n0 0 -3 nan 0 1\n1 0 -3 0 0 1\n0 1 -3 0 0 1\n3 0 1 2\n";
    let m = load(d, "nan.ply", ply);
    assert_eq!(count(&m, Tolerance::BadNormal), 1, "{}", warnings(&m));
    assert!(
        warnings(&m).contains("nan.ply, line 16"),
        "{}",
        warnings(&m)
    );
}

/// Repeated corners, too few corners and no area: dropped and counted.
/// A concave polygon is cut by ear clipping, so its triangles cover
/// exactly its area (a fan from the reflex corner would not).
#[test]
fn degenerate_faces_drop_and_concave_polygons_cut_right() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let m = load(
        d,
        "degenerate.obj",
        b"v 0 0 -3\nv 1 0 -3\nv 0 1 -3\nv 2 0 -3\nf 1 1 2\nf 1 2\nf 1 2 4\nf 1 2 3\n",
    );
    assert_eq!(m.faces.len(), 1);
    assert_eq!(count(&m, Tolerance::DegenerateFace), 3, "{}", warnings(&m));

    // An L whose first corner is the reflex one.
    let m = load(
        d,
        "l.obj",
        b"v 1 1 -3\nv 1 2 -3\nv 0 2 -3\nv 0 0 -3\nv 2 0 -3\nv 2 1 -3\nf 1 2 3 4 5 6\n",
    );
    assert_eq!(m.faces.len(), 4);
    let area: f64 = m
        .faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.positions.map(|i| m.positions[i as usize]);
            (b - a).cross(c - a).length() / 2.0
        })
        .sum();
    assert!((area - 3.0).abs() < 1e-12, "area {area}");
    assert!(m.report.is_empty(), "{}", warnings(&m));
}

/// A byte-order mark is skipped and UTF-16 decoded, each said; a file of
/// points only is a warning naming it, and a scene left with nothing to
/// render is an error.
#[test]
fn encodings_and_empty_models_are_never_silent() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let text = "v 0 0 -3\nv 1 0 -3\nv 0 1 -3\nf 1 2 3\n";
    let m = load(d, "bom.obj", format!("\u{feff}{text}").as_bytes());
    assert_eq!((m.faces.len(), count(&m, Tolerance::Encoding)), (1, 1));
    for big in [false, true] {
        let mut bytes: Vec<u8> = if big {
            vec![0xFE, 0xFF]
        } else {
            vec![0xFF, 0xFE]
        };
        for u in text.encode_utf16() {
            bytes.extend(if big {
                u.to_be_bytes()
            } else {
                u.to_le_bytes()
            });
        }
        let m = load(d, "utf16.obj", &bytes);
        assert_eq!(m.faces.len(), 1);
        assert!(warnings(&m).contains("UTF-16"), "{}", warnings(&m));
    }

    let cloud = b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
property float z\nend_header\n0 0 0\n1 1 1\n";
    write(d, "cloud.ply", cloud);
    write(
        d,
        "cloud.scene",
        format!("2\namb: 0 0 0\nmesh file: cloud.ply {MATERIAL}\nsphere pos: 0 0 -3 rad: 1 {MATERIAL}\n")
            .as_bytes(),
    );
    let scene = read_scene(&d.join("cloud.scene")).expect("a sphere is left to render");
    let w: String = scene.warnings.iter().map(ToString::to_string).collect();
    assert!(
        w.contains("cloud.scene:3:12") && w.contains("no triangles"),
        "{w}"
    );
    write(
        d,
        "empty.scene",
        format!("1\namb: 0 0 0\nmesh file: cloud.ply {MATERIAL}\n").as_bytes(),
    );
    let e = read_scene(&d.join("empty.scene")).expect_err("nothing to render");
    assert!(e.to_string().contains("nothing to render"), "{e}");
    assert!(e.to_string().contains("empty.scene:3:12"), "{e}");
}

/// A model whose every face was dropped says why it brought nothing: the
/// scene's error, its warning and `convert` count the dropped faces.
#[test]
fn a_model_of_dropped_faces_counts_them() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    write(
        d,
        "line.obj",
        b"v 0 0 -2\nv 1 0 -2\nv 2 0 -2\nv 3 0 -2\nf 1 2 3\nf 2 3 4\n",
    );
    write(
        d,
        "alone.scene",
        format!("1\namb: 0 0 0\nmesh file: line.obj {MATERIAL}\n").as_bytes(),
    );
    let e = read_scene(&d.join("alone.scene")).expect_err("nothing to render");
    assert!(
        e.to_string()
            .contains("2 degenerate faces (corners on one line or point) dropped"),
        "{e}"
    );
    write(
        d,
        "beside.scene",
        format!(
            "2\namb: 0 0 0\nmesh file: line.obj {MATERIAL}\nsphere pos: 0 0 -3 rad: 1 {MATERIAL}\n"
        )
        .as_bytes(),
    );
    let scene = read_scene(&d.join("beside.scene")).expect("the sphere renders");
    let w: String = scene.warnings.iter().map(ToString::to_string).collect();
    assert!(w.contains("2 degenerate faces"), "{w}");
    let o = glint(&["convert", "line.obj", "out.scene"], d);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("2 degenerate faces"),
        "{err}"
    );
}

/// The help names every model format the loader reads.
#[test]
fn help_lists_every_model_format() {
    let dir = tempfile::tempdir().expect("temp dir");
    let formats: Vec<&str> = glint::mesh::EXTENSIONS
        .split([',', ' '])
        .filter(|w| w.starts_with('.'))
        .collect();
    assert!(formats.len() >= 6, "{formats:?}");
    for args in [&["--help"][..], &["convert", "--help"]] {
        let o = glint(args, dir.path());
        let help = String::from_utf8_lossy(&o.stdout);
        for f in &formats {
            assert!(
                help.contains(f),
                "`glint {}` does not name {f}:\n{help}",
                args.join(" ")
            );
        }
    }
    for f in &formats {
        assert!(
            glint::mesh::Format::of(Path::new(&format!("m{f}"))).is_some(),
            "the help names {f}, which the loader does not read"
        );
    }
}

/// A few triangles with exact f32 coordinates and unit normals, for the
/// formats to carry alike.
struct Shape {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    faces: Vec<[u32; 3]>,
}

fn shape() -> Shape {
    let positions = vec![
        [-1.0, -0.75, -3.0],
        [1.0, -0.75, -3.5],
        [0.0, 1.0, -3.25],
        [0.5, 0.25, -2.5],
    ];
    let normals: Vec<[f32; 3]> = vec![
        [0.0, 0.0, 1.0],
        [0.6, 0.0, 0.8],
        [0.0, 0.6, 0.8],
        [0.0, -0.6, 0.8],
    ];
    Shape {
        positions,
        normals,
        faces: vec![[0, 1, 3], [1, 2, 3], [2, 0, 3], [0, 2, 1]],
    }
}

fn obj_of(s: &Shape, normals: bool) -> String {
    let mut out = String::new();
    for p in &s.positions {
        out += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for n in &s.normals {
        out += &format!("vn {} {} {}\n", n[0], n[1], n[2]);
    }
    for f in &s.faces {
        let c = f.map(|i| i + 1);
        if normals {
            out += &format!("f {0}//{0} {1}//{1} {2}//{2}\n", c[0], c[1], c[2]);
        } else {
            out += &format!("f {} {} {}\n", c[0], c[1], c[2]);
        }
    }
    out
}

fn stl_binary(s: &Shape, header: &[u8]) -> Vec<u8> {
    let mut out = vec![b' '; 80];
    out[..header.len()].copy_from_slice(header);
    out.extend((s.faces.len() as u32).to_le_bytes());
    for f in &s.faces {
        // A wrong facet normal: never used.
        for v in [9.0f32, 9.0, 9.0] {
            out.extend(v.to_le_bytes());
        }
        for &i in f {
            for v in s.positions[i as usize] {
                out.extend(v.to_le_bytes());
            }
        }
        out.extend([0, 0]);
    }
    out
}

fn stl_ascii(s: &Shape) -> String {
    // Two solids, to check both are read.
    let mut out = String::new();
    for (k, part) in s.faces.chunks(2).enumerate() {
        out += &format!("solid part{k}\n");
        for f in part {
            out += "  facet normal 0 0 0\n    outer loop\n";
            for &i in f {
                let p = s.positions[i as usize];
                out += &format!("      vertex {} {} {}\n", p[0], p[1], p[2]);
            }
            out += "    endloop\n  endfacet\n";
        }
        out += &format!("endsolid part{k}\n");
    }
    out
}

/// The shape as one glTF buffer: positions, normals, u16 indices.
fn gltf_buffer(s: &Shape) -> Vec<u8> {
    let mut buf = Vec::new();
    for v in s.positions.iter().chain(&s.normals).flatten() {
        buf.extend(v.to_le_bytes());
    }
    for i in s.faces.iter().flatten() {
        buf.extend((*i as u16).to_le_bytes());
    }
    buf
}

/// glTF JSON for `gltf_buffer`, with `buffer` the buffer's JSON object and
/// `node` the scene's one node.
fn gltf_json(s: &Shape, buffer: &str, node: &str, material: &str) -> String {
    let n = s.positions.len();
    let (pos_len, idx_len) = (n * 12, s.faces.len() * 6);
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{node}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1}},"indices":2{material}}}]}}],
"materials":[{{"pbrMetallicRoughness":{{"baseColorFactor":[0.5,0.25,1,1],"metallicFactor":0,"roughnessFactor":0.5}}}}],
"buffers":[{buffer}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{}}},{{"buffer":0,"byteOffset":{},"byteLength":{idx_len}}}],
"accessors":[
{{"bufferView":0,"byteOffset":0,"componentType":5126,"count":{n},"type":"VEC3","min":[-1,-0.75,-3.5],"max":[1,1,-2.5]}},
{{"bufferView":0,"byteOffset":{pos_len},"componentType":5126,"count":{n},"type":"VEC3"}},
{{"bufferView":1,"componentType":5123,"count":{},"type":"SCALAR"}}]}}"#,
        2 * pos_len,
        2 * pos_len,
        s.faces.len() * 3
    )
}

fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((j.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(j);
    out.extend((b.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(b);
    out
}

fn data_uri(bytes: &[u8]) -> String {
    use base64::Engine as _;
    format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

fn scene_with(dir: &Path, file: &str) -> Scene {
    let text = format!(
        "2\namb: 0.1 0.1 0.1\nlight pos: 2 3 1 col: 0.9 0.9 0.9\nmesh file: {file} {MATERIAL}\n"
    );
    let path = write(dir, &format!("{file}.scene"), text.as_bytes());
    read_scene(&path).unwrap_or_else(|e| panic!("{file}: {e}"))
}

/// STL (binary, including one whose header begins with `solid`, and ASCII
/// with two solids) renders bit for bit as the OBJ without normals; glTF
/// (embedded, external buffer, GLB) as the OBJ with them.
#[test]
fn stl_and_gltf_render_bit_for_bit_like_obj() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let s = shape();
    write(d, "plain.obj", obj_of(&s, false).as_bytes());
    write(d, "normals.obj", obj_of(&s, true).as_bytes());
    write(d, "a.stl", &stl_binary(&s, b"binary"));
    write(d, "solid.stl", &stl_binary(&s, b"solid but binary"));
    write(d, "ascii.stl", stl_ascii(&s).as_bytes());
    let node = r#"{"mesh":0}"#;
    let buf = gltf_buffer(&s);
    let embedded = format!(
        r#"{{"byteLength":{},"uri":"{}"}}"#,
        buf.len(),
        data_uri(&buf)
    );
    write(
        d,
        "embedded.gltf",
        gltf_json(&s, &embedded, node, "").as_bytes(),
    );
    write(d, "shape.bin", &buf);
    let external = format!(r#"{{"byteLength":{},"uri":"shape.bin"}}"#, buf.len());
    write(
        d,
        "external.gltf",
        gltf_json(&s, &external, node, "").as_bytes(),
    );
    let inner = format!(r#"{{"byteLength":{}}}"#, buf.len());
    write(d, "shape.glb", &glb(&gltf_json(&s, &inner, node, ""), &buf));

    let render = |file: &str| {
        let scene = scene_with(d, file);
        assert_eq!(scene.triangles.len(), 4, "{file}");
        render_cpu(&scene, 48, 36, Precision::F32, WHITE)
    };
    let plain = render("plain.obj");
    let normals = render("normals.obj");
    assert_ne!(plain.pixels, normals.pixels, "the two references differ");
    for stl in ["a.stl", "solid.stl", "ascii.stl"] {
        assert!(
            render(stl).pixels == plain.pixels,
            "{stl} differs from the OBJ"
        );
    }
    for gltf in ["embedded.gltf", "external.gltf", "shape.glb"] {
        assert!(
            render(gltf).pixels == normals.pixels,
            "{gltf} differs from the OBJ"
        );
    }
    // And on the GPU, as every scene: the CPU f32 twin's image.
    for file in ["a.stl", "shape.glb"] {
        assert_backends_agree(file, &scene_with(d, file).in_view_space(), 48, 36, 1);
    }
}

/// glTF's node hierarchy places meshes (TRS and matrices compose), its
/// material maps to the classic one, strips and fans are cut, and what is
/// wrong is refused with the JSON path.
#[test]
fn gltf_nodes_materials_modes_and_errors() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let s = shape();
    let buf = gltf_buffer(&s);
    let uri = format!(
        r#"{{"byteLength":{},"uri":"{}"}}"#,
        buf.len(),
        data_uri(&buf)
    );
    let with = |name: &str, json: String| {
        let path = write(d, name, json.as_bytes());
        mesh::load(&path)
    };
    // A parent translating by (0, 0, -1) and a child scaling by 2 and
    // given as a matrix translating by (1, 0, 0): p -> 2p + (1, 0, -1).
    let nodes = r#"{"children":[1],"translation":[0,0,-1]},
        {"mesh":0,"matrix":[2,0,0,0, 0,2,0,0, 0,0,2,0, 1,0,0,1]}"#;
    let json = gltf_json(&s, &uri, nodes, r#","material":0"#);
    let m = with("nodes.gltf", json).expect("loads");
    let p0 = DVec3::from(s.positions[0].map(f64::from));
    assert_eq!(m.positions[0], 2.0 * p0 + DVec3::new(1.0, 0.0, -1.0));
    let mat = m.materials[0];
    assert_eq!(mat.kd, DVec3::new(0.5, 0.25, 1.0));
    assert!((mat.ks - DVec3::splat(0.04)).length() < 1e-9);
    // roughness 0.5: alpha 0.25, (2 / 0.0625 - 2) / 4 = 7.5.
    assert!((mat.shininess - 7.5).abs() < 1e-9);
    assert!(m.faces.iter().all(|f| f.material == Some(0)));

    // A cycle in the node hierarchy.
    let cycle = r#"{"children":[1]},{"mesh":0,"children":[0]}"#;
    let e = with("cycle.gltf", gltf_json(&s, &uri, cycle, "")).expect_err("cycle");
    assert!(
        e.to_string().contains("nodes[") && e.to_string().contains("cycle"),
        "{e}"
    );

    // An index past the vertices, with the JSON path.
    let mut bad = buf.clone();
    let at = bad.len() - 2;
    bad[at..].copy_from_slice(&9u16.to_le_bytes());
    let uri_bad = format!(
        r#"{{"byteLength":{},"uri":"{}"}}"#,
        bad.len(),
        data_uri(&bad)
    );
    let e = with("index.gltf", gltf_json(&s, &uri_bad, r#"{"mesh":0}"#, "")).expect_err("index 9");
    assert!(
        e.to_string().contains("meshes[0].primitives[0].indices"),
        "{e}"
    );

    // An accessor past its buffer view.
    let json = gltf_json(&s, &uri, r#"{"mesh":0}"#, "").replace(r#""count":12"#, r#""count":13"#);
    let e = with("range.gltf", json).expect_err("past the view");
    assert!(e.to_string().contains("accessors[2]"), "{e}");

    // POSITION naming an accessor that does not exist (a panic inside the
    // glTF crate's validation, found by fuzzing): refused with the path.
    let e = with(
        "noaccessor.gltf",
        r#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}]}"#
            .to_string(),
    )
    .expect_err("no accessors");
    assert!(
        e.to_string()
            .contains("meshes[0].primitives[0].attributes.POSITION"),
        "{e}"
    );

    // Compressed meshes: refused, saying what to do.
    let json = gltf_json(&s, &uri, r#"{"mesh":0}"#, "").replacen(
        '{',
        r#"{"extensionsUsed":["KHR_draco_mesh_compression"],"extensionsRequired":["KHR_draco_mesh_compression"],"#,
        1,
    );
    let e = with("draco.gltf", json).expect_err("draco");
    assert!(
        e.to_string().contains("extensionsRequired[0]")
            && e.to_string().contains("without mesh compression"),
        "{e}"
    );

    // Strips and fans of the same quad cover it; points are skipped.
    for (mode, count) in [(5, 2), (6, 2), (0, 0)] {
        let json = gltf_json(&s, &uri, r#"{"mesh":0}"#, &format!(r#","mode":{mode}"#))
            .replace(r#""indices":2,"#, "")
            .replace(r#""indices":2"#, "");
        let m = with("mode.gltf", json).expect("loads");
        assert_eq!(m.faces.len(), count, "mode {mode}");
        assert_eq!(
            count == 0,
            m.report.counts.contains_key(&Tolerance::NotSurface)
        );
    }
}

/// Endless and binary input is refused early: no read to the end, no
/// memory growing without bound; `--max-input` ends a valid stream.
#[test]
fn endless_and_binary_input_is_refused_early() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let zero = "/dev/zero";
    if !Path::new(zero).exists() {
        notice("SKIPPED: no /dev/zero");
        return;
    }
    // A scene that is a device, standard input of zeros, a mesh that is one.
    let o = glint(&["info", zero], d);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("byte 0: binary data"));
    let o = Command::new(env!("CARGO_BIN_EXE_glint"))
        .args(["info", "-"])
        .stdin(std::fs::File::open(zero).expect("open /dev/zero"))
        .output()
        .expect("run glint");
    assert_eq!(o.status.code(), Some(2));
    #[cfg(unix)]
    std::os::unix::fs::symlink(zero, d.join("zero.obj")).expect("link");
    write(
        d,
        "z.scene",
        format!("1\namb: 0 0 0\nmesh file: zero.obj {MATERIAL}\n").as_bytes(),
    );
    let o = glint(&["info", "z.scene"], d);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("zero.obj, byte 0"));
    // The same through every model loader, directly.
    for ext in ["obj", "ply", "off", "stl", "gltf", "glb"] {
        let format = Format::of(Path::new(&format!("x.{ext}"))).expect("known");
        let r = mesh::read(
            std::io::repeat(0),
            format,
            Path::new(&format!("zero.{ext}")),
        );
        match r {
            Err(e) => assert!(e.to_string().contains("zero."), "{ext}: {e}"),
            // Binary STL of zeros: a header claiming 0 triangles, the rest
            // not read (and reported).
            Ok(m) => {
                assert_eq!(ext, "stl");
                assert!(m.faces.is_empty());
                assert_eq!(m.report.counts.get(&Tolerance::TrailingData), Some(&1));
            }
        }
    }
    // A stream of valid spheres that never ends stops at --max-input.
    let mut child = Command::new(env!("CARGO_BIN_EXE_glint"))
        .args(["--max-input", "1M", "info", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run glint");
    let mut stdin = child.stdin.take().expect("stdin");
    let writer = std::thread::spawn(move || {
        use std::io::Write;
        let _ = stdin.write_all(b"999999999\namb: 0 0 0\n");
        let line = format!("sphere pos: 0 0 -3 rad: 1 {MATERIAL}\n");
        while stdin.write_all(line.as_bytes()).is_ok() {}
    });
    let o = child.wait_with_output().expect("glint ends");
    writer.join().expect("writer");
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--max-input (1.0 MiB)"), "{err}");
}

/// Garbage at the start of any model format is refused at its first line
/// or byte, naming it; nothing in the fuzz seed corpus panics.
#[test]
fn the_fuzz_seed_corpus_loads_or_errors_without_panic() {
    let root = repo_path("tests/fuzz/corpus");
    let Ok(dirs) = std::fs::read_dir(&root) else {
        panic!("no seed corpus at {}", root.display());
    };
    let mut seen = 0;
    for dir in dirs.flatten() {
        let target = dir.file_name().to_string_lossy().into_owned();
        for file in std::fs::read_dir(dir.path()).expect("corpus dir").flatten() {
            let bytes = std::fs::read(file.path()).expect("seed");
            seen += 1;
            let path = Path::new("seed");
            match target.as_str() {
                "scene" => drop(glint::scene::parse_scene(&bytes, "seed")),
                "mtl" => drop(mesh::parse_mtl(&bytes, path)),
                t => {
                    let format = match t {
                        "obj" => Format::Obj,
                        "ply" => Format::Ply,
                        "off" => Format::Off,
                        "stl" => Format::Stl,
                        "gltf" => Format::Gltf,
                        _ => continue,
                    };
                    drop(mesh::read(&bytes[..], format, path));
                    drop(mesh::parse(&bytes, format, path, Refs::None));
                }
            }
        }
    }
    assert!(seen >= 20, "only {seen} seeds");
}
