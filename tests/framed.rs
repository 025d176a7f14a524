//! A model file given where a scene is expected: it renders framed, as
//! model viewers show what they open (the camera fitted to its bounds, a
//! light beside it), `convert` writes the same view into the scene it
//! makes, and `--eye`, `--look`, `--up`, `--fov` set the view over any
//! scene's, refusing one that cannot see.

mod common;

use std::path::Path;

use common::cli::*;

/// A box of 4 x 3 x 2 units, far from the origin (the classic camera
/// would see none of it), as OBJ quads.
fn box_obj(dir: &Path) {
    let (c, h) = ([40.0, -25.0, 90.0], [2.0, 1.5, 1.0]);
    let mut s = String::new();
    for k in 0..8 {
        let sign = |bit: usize| if k >> bit & 1 == 1 { 1.0 } else { -1.0 };
        s += &format!(
            "v {} {} {}\n",
            c[0] + sign(0) * h[0],
            c[1] + sign(1) * h[1],
            c[2] + sign(2) * h[2]
        );
    }
    // Corners by bits (x, y, z) + 1; each face counter-clockwise from outside.
    s += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
    std::fs::write(dir.join("box.obj"), s).unwrap();
}

fn pixels(path: &Path) -> image::RgbImage {
    image::open(path).expect("a readable PNG").to_rgb8()
}

/// The rows and columns where the image is not the white background:
/// (top, bottom, left, right), None for an empty image.
fn extent(img: &image::RgbImage) -> Option<(u32, u32, u32, u32)> {
    let mut e: Option<(u32, u32, u32, u32)> = None;
    for (x, y, p) in img.enumerate_pixels() {
        if p.0 != [255, 255, 255] {
            e = Some(match e {
                None => (y, y, x, x),
                Some((t, b, l, r)) => (t.min(y), b.max(y), l.min(x), r.max(x)),
            });
        }
    }
    e
}

#[test]
fn a_model_renders_framed_and_convert_keeps_its_view() {
    let d = tmp();
    box_obj(d.path());
    let size = ["--width", "160", "--height", "120", "--backend", "cpu"];
    let o = glint(
        &[&["render", "box.obj", "direct.png"][..], &size].concat(),
        d.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let direct = pixels(&d.path().join("direct.png"));
    let (top, bottom, left, right) = extent(&direct).expect("the box is seen");
    // Inside the frame, with a margin, and not a speck.
    assert!(
        top > 0 && left > 0 && bottom < 119 && right < 159,
        "cut off: {top} {bottom} {left} {right}"
    );
    assert!(bottom - top > 30, "too small to see: rows {top}..{bottom}");
    // Lit, with shading: at least three tones of grey on the box.
    let mut tones: Vec<[u8; 3]> = direct.pixels().map(|p| p.0).collect();
    tones.sort_unstable();
    tones.dedup();
    assert!(tones.len() > 3, "{tones:?}");

    let o = glint(&["convert", "box.obj", "box.scene"], d.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let o = glint(
        &[&["render", "box.scene", "converted.png"][..], &size].concat(),
        d.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let converted = pixels(&d.path().join("converted.png"));
    let worst = direct
        .pixels()
        .zip(converted.pixels())
        .flat_map(|(a, b)| (0..3).map(move |c| a.0[c].abs_diff(b.0[c])))
        .max();
    assert!(
        worst <= Some(1),
        "the converted scene renders {worst:?} levels apart"
    );
}

#[test]
fn camera_flags_set_the_view_and_refuse_one_that_cannot_see() {
    let d = tmp();
    box_obj(d.path());
    let size = ["--width", "80", "--height", "60", "--backend", "cpu"];
    // From straight above and near: the top face (4 x 2) fills most of it.
    let o = glint(
        &[
            &[
                "render",
                "box.obj",
                "above.png",
                "--eye",
                "40,-21,90",
                "--look",
                "40,-25,90",
                "--up",
                "0,0,-1",
            ][..],
            &size,
        ]
        .concat(),
        d.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (top, bottom, _, _) = extent(&pixels(&d.path().join("above.png"))).expect("seen");
    assert!(bottom - top > 30, "rows {top}..{bottom}");
    for (flags, says) in [
        (
            vec!["--eye", "40,-25,90", "--look", "40,-25,90"],
            "cannot see",
        ),
        (vec!["--eye", "0,0,0", "--look", "0,1,0"], "cannot see"),
        (vec!["--fov", "180"], "--fov must be"),
        (vec!["--eye", "1,2"], "X,Y,Z"),
    ] {
        let o = glint(
            &[&["render", "box.obj", "x.png"][..], &size, &flags].concat(),
            d.path(),
        );
        assert_eq!(o.status.code(), Some(2), "{flags:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(says), "{flags:?}: {}", stderr(&o));
        assert!(!d.path().join("x.png").exists());
    }
}

#[test]
fn a_model_without_triangles_is_an_error_naming_it() {
    let d = tmp();
    std::fs::write(d.path().join("points.obj"), "v 0 0 0\nv 1 0 0\n").unwrap();
    let o = glint(
        &["render", "points.obj", "x.png", "--backend", "cpu"],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("points.obj"), "{}", stderr(&o));
    assert!(stderr(&o).contains("no triangles"), "{}", stderr(&o));
}

/// A glTF file's own perspective camera is the view it renders with,
/// placed by its node's transform (glTF cameras look down their -z).
#[test]
fn a_gltf_camera_is_the_view() {
    let d = tmp();
    let mut bin = Vec::new();
    for v in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        for c in v {
            bin.extend(c.to_le_bytes());
        }
    }
    std::fs::write(d.path().join("tri.bin"), &bin).unwrap();
    let json = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0,1]}],
        "nodes":[{"mesh":0},{"camera":0,"translation":[0.5,0.5,4],"rotation":[0,0.0871557,0,0.9961947]}],
        "cameras":[{"type":"perspective","perspective":{"yfov":0.5,"znear":0.1}}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
        "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3",
                      "min":[0,0,0],"max":[1,1,0]}],
        "bufferViews":[{"buffer":0,"byteLength":36}],
        "buffers":[{"byteLength":36,"uri":"tri.bin"}]}"#;
    std::fs::write(d.path().join("cam.gltf"), json).unwrap();
    let scene = glint::scene::read_scene(&d.path().join("cam.gltf")).expect("loads");
    let camera = scene.camera.expect("a camera");
    assert!(
        (camera.eye - glam::DVec3::new(0.5, 0.5, 4.0)).length() < 1e-6,
        "{camera:?}"
    );
    assert!(
        (camera.fov - 0.5f64.to_degrees()).abs() < 1e-4,
        "{camera:?}"
    );
    // Turned 10 degrees about +y: it looks down -z, a little toward -x.
    let view = (camera.look - camera.eye).normalize();
    let want = glam::DVec3::new(
        -(10f64.to_radians().sin()),
        0.0,
        -(10f64.to_radians().cos()),
    );
    assert!((view - want).length() < 1e-5, "{view} vs {want}");
    // Without the camera node the framing's view.
    let framed = json.replace(r#""nodes":[0,1]"#, r#""nodes":[0]"#);
    std::fs::write(d.path().join("plain.gltf"), framed).unwrap();
    let scene = glint::scene::read_scene(&d.path().join("plain.gltf")).expect("loads");
    assert_eq!(scene.camera.map(|c| c.fov), Some(60.0));
}
