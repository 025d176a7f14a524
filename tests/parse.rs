//! The classic-format parser: the course's files, a table of malformed inputs
//! with their exact locations, and "never panics" on arbitrary bytes.

mod common;

use common::*;
use glint::scene::parse_scene;
use proptest::prelude::*;

#[test]
fn classic_scenes_parse_with_the_right_counts() {
    // (name, spheres, triangles, lights): counted independently with `grep -ci "^sphere"` etc.
    let expected = [
        ("test1", 1, 0, 1),
        ("test2", 1, 3, 1),
        ("spheres", 5, 2, 1),
        ("table", 0, 182, 2),
        ("SIGGRAPH", 0, 1482, 3),
    ];
    for (name, s, t, l) in expected {
        let Some(scene) = classic_scene(name) else {
            return;
        };
        assert_eq!(
            (
                scene.spheres.len(),
                scene.triangles.len(),
                scene.lights.len()
            ),
            (s, t, l),
            "{name}"
        );
        assert!(scene.warnings.is_empty(), "{name}: {:?}", scene.warnings);
    }
}

#[test]
fn classic_values_are_read_exactly() {
    let Some(scene) = classic_scene("test2") else {
        return;
    };
    assert_eq!(scene.ambient.x, 0.05);
    // `dif: .44 .40 .16` -- a leading-dot number.
    assert_eq!(scene.spheres[0].material.kd.x, 0.44);
    // `nor: 0 0.9878    0.1556` -- runs of spaces.
    assert_eq!(scene.triangles[1].vertices[0].normal.y, 0.9878);
    assert_eq!(scene.material(&scene.triangles[2].vertices[2]).ks.x, 0.5);
}

const SPHERE: &str = "sphere pos: 0 0 -3 rad: 1 dif: 1 1 1 spe: 1 1 1 shi: 1\n";
const LIGHT: &str = "light pos: 0 0 0 col: 1 1 1\n";

#[test]
fn malformed_inputs_report_line_col_and_what_was_expected() {
    let cases: Vec<(String, usize, usize, &str)> = vec![
        (
            "".into(),
            1,
            1,
            "expected the object count, found end of file",
        ),
        (
            "  two\n".into(),
            1,
            3,
            "expected the object count (a whole number) as the first token, found `two`",
        ),
        ("-1\namb: 0 0 0\n".into(), 1, 1, "found `-1`"),
        (
            "99999999999999999999999\n".into(),
            1,
            1,
            "expected the object count",
        ),
        (
            "1\nambient: 0 0 0\n".into(),
            2,
            1,
            "expected `amb:`, found `ambient:`",
        ),
        (
            "1\namb: 0 0 nan\n".into(),
            2,
            10,
            "expected a finite number (the ambient colour), found `nan`",
        ),
        ("1\namb: 0 inf 0\n".into(), 2, 8, "expected a finite number"),
        (
            "1\namb: 0 0 1e999\n".into(),
            2,
            10,
            "expected a finite number",
        ),
        (
            "1\namb: 0 0 0x1\n".into(),
            2,
            10,
            "expected a number (the ambient colour), found `0x1`",
        ),
        (
            "1\namb: 0 0 0\ncone\n".into(),
            3,
            1,
            "expected `sphere`, `triangle`, `light`, `mesh`, `camera` or a setting (`reflect:`, `spp:`, `shadow_samples:`, `shutter:`, `seed:`, `fps:`, `sampler:`), found `cone`",
        ),
        (
            "1\namb: 0 0 0\nsphere\npos: 0 0 -3\nradius: 1\n".into(),
            5,
            1,
            "expected `rad:`, found `radius:`",
        ),
        (
            "1\namb: 0 0 0\nsphere pos: 0 0 -3 rad: -1\n".into(),
            3,
            25,
            "sphere radius must be positive, found `-1`",
        ),
        (
            "1\namb: 0 0 0\nsphere pos: 0 0 -3 rad: 0\n".into(),
            3,
            25,
            "sphere radius must be positive",
        ),
        (
            "1\namb: 0 0 0\nsphere pos: 0 0 -3 rad: 1 dif: 1 1 1 spe: 1 1 1 shi: -2\n".into(),
            3,
            54,
            "shininess must be zero or more",
        ),
        (
            "1\namb: 0 0 0\nsphere\npos: 0 0".into(),
            4,
            9,
            "expected a number (the sphere centre), found end of file",
        ),
        (
            format!("1\namb: 0 0 0\n{LIGHT}{LIGHT}"),
            4,
            1,
            "the file declares 1 object(s) on its first line, but object 2 starts here",
        ),
        (
            format!("3\namb: 0 0 0\n{SPHERE}{LIGHT}"),
            5,
            1,
            "the file declares 3 object(s) on its first line, but ends after 2",
        ),
        // A hostile count must not allocate: it simply disagrees with the blocks.
        (
            format!("1000000000000\namb: 0 0 0\n{LIGHT}"),
            4,
            1,
            "declares 1000000000000 object(s)",
        ),
        (
            "1\namb: 0 0 0\ntriangle pos: 0 0 0 nor: 0 0 1 dif: 0 0 0 spe: 0 0 0 shi: 1\n".into(),
            4,
            1,
            "expected `pos:`, found end of file",
        ),
        ("\u{feff}1\n".into(), 1, 1, "expected the object count"),
        (
            "1\namb: 0 0 0\nsph\u{e9}re\n".into(),
            3,
            1,
            "found `sph\u{e9}re`",
        ),
    ];
    for (src, line, col, message) in cases {
        let err = parse_scene(src.as_bytes(), "case.scene").expect_err(&src);
        let d = err.diagnostic();
        assert_eq!((d.line, d.col), (line, col), "for {src:?}: {err}");
        assert!(
            d.message.contains(message),
            "for {src:?}:\n{err}\nwanted: {message}"
        );
        let shown = err.to_string();
        assert!(
            shown.starts_with(&format!("case.scene:{line}:{col}: ")),
            "{shown}"
        );
        assert!(shown.contains('^'), "no caret in:\n{shown}");
    }
}

#[test]
fn zero_normals_warn_with_their_location() {
    let src = "1\namb: 0 0 0\ntriangle\n\
               pos: 0 0 -1 nor: 0 0 0 dif: 1 1 1 spe: 0 0 0 shi: 1\n\
               pos: 1 0 -1 nor: 0 0 1 dif: 1 1 1 spe: 0 0 0 shi: 1\n\
               pos: 0 1 -1 nor: 0 0 1 dif: 1 1 1 spe: 0 0 0 shi: 1\n";
    let scene = parse_scene(src.as_bytes(), "w.scene").expect("renderable");
    assert_eq!(scene.warnings.len(), 1);
    assert_eq!((scene.warnings[0].line, scene.warnings[0].col), (4, 13));
    assert!(scene.warnings[0]
        .message
        .contains("zero-length vertex normal"));
}

#[test]
fn every_prefix_of_a_classic_file_parses_or_errors_cleanly() {
    let Some(dir) = classic_dir() else {
        return;
    };
    let bytes = std::fs::read(dir.join("test2.scene")).expect("read test2");
    let mut ok = 0;
    for end in 0..=bytes.len() {
        match parse_scene(&bytes[..end], "prefix") {
            Ok(_) => ok += 1,
            Err(e) => assert!(e.diagnostic().line >= 1 && e.diagnostic().col >= 1),
        }
    }
    // Only the whole file (and the whole file minus trailing whitespace or a
    // final number's later digits, which still parse) is a complete scene.
    assert!((1..5).contains(&ok), "{ok} prefixes parsed");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let _ = parse_scene(&bytes, "fuzz");
    }

    #[test]
    fn token_soup_never_panics(tokens in proptest::collection::vec(
        prop_oneof![
            Just("1".to_string()), Just("3".to_string()), Just("amb:".to_string()),
            Just("sphere".to_string()), Just("triangle".to_string()), Just("light".to_string()),
            Just("pos:".to_string()), Just("nor:".to_string()), Just("rad:".to_string()),
            Just("dif:".to_string()), Just("spe:".to_string()), Just("shi:".to_string()),
            Just("col:".to_string()), Just("NaN".to_string()), Just("-0".to_string()),
            Just("1e-16".to_string()), Just(".44".to_string()), Just("\n".to_string()),
            any::<f64>().prop_map(|f| f.to_string()),
        ],
        0..80,
    )) {
        let text = tokens.join(" ");
        if let Ok(scene) = parse_scene(text.as_bytes(), "soup") {
            // Whatever parses must hold only finite numbers and positive radii.
            prop_assert!(scene.spheres.iter().all(|s| s.radius > 0.0 && s.center.is_finite()));
            prop_assert!(scene.ambient.is_finite());
        }
    }
}

#[test]
fn non_unit_normals_are_renormalized_with_a_warning() {
    let src = "1\namb: 0 0 0\ntriangle\n\
               pos: 0 0 -1 nor: 0 0 1e30 dif: 1 1 1 spe: 0 0 0 shi: 1\n\
               pos: 1 0 -1 nor: 0 0 2 dif: 1 1 1 spe: 0 0 0 shi: 1\n\
               pos: 0 1 -1 nor: 0 0 1.00001 dif: 1 1 1 spe: 0 0 0 shi: 1\n";
    let scene = parse_scene(src.as_bytes(), "n.scene").expect("renderable");
    let normals = scene.triangles[0].vertices.map(|v| v.normal);
    assert_eq!(normals[0], glam::DVec3::Z);
    assert_eq!(normals[1], glam::DVec3::Z);
    // Within the classic files' 2e-5 of unit length: kept as written.
    assert_eq!(normals[2].z, 1.00001);
    assert_eq!(scene.warnings.len(), 2);
    assert_eq!((scene.warnings[0].line, scene.warnings[0].col), (4, 13));
    assert!(scene.warnings[0].message.contains("length 1e30"));
    assert!(scene.warnings[1].message.contains("length 2e0"));
}

#[test]
fn numbers_beyond_f32_are_located_errors() {
    let src = "1\namb: 0 0 0\nsphere\npos: 0 0 -1e39\nrad: 1\n\
               dif: 1 1 1\nspe: 0 0 0\nshi: 1\n";
    let e = parse_scene(src.as_bytes(), "big.scene").expect_err("1e39 overflows f32");
    let text = e.to_string();
    assert!(text.contains("big.scene:4:10"), "{text}");
    assert!(text.contains("f32 limit"), "{text}");
}

#[test]
fn extensions_parse_and_round_trip() {
    use glint::scene::{to_classic_text, LightShape};
    let text = "5\nAMB: 0.1 0.1 0.1\nreflect: 3\nSPP: 16\nshadow_samples: 8\nshutter: .5\nseed: 42\nfps: 30\nSampler: Stratified\n\
        light\npos: 0 5 0\ncol: 1 1 1\nrad: .25\nvel: 1 0 0\n\
        light\npos: 0 5 -5\ncol: 1 1 1\nedge_u: 1 0 0\nedge_v: 0 0 2\n\
        light\npos: 0 5 -9\ncol: 1 1 1\n\
        sphere\npos: 0 0 -5\nrad: 1\ndif: 1 0 0\nspe: 0 0 0\nshi: 1\nVEL: 0 2 0\n\
        triangle\n\
        pos: 0 0 -3 nor: 0 0 1 dif: 1 1 1 spe: 0 0 0 shi: 1\n\
        pos: 1 0 -3 nor: 0 0 1 dif: 1 1 1 spe: 0 0 0 shi: 1\n\
        pos: 0 1 -3 nor: 0 0 1 dif: 1 1 1 spe: 0 0 0 shi: 1\n\
        vel: 0 0 -1\n";
    let scene = scene_from(text);
    let st = scene.settings;
    assert_eq!(
        (
            st.reflect,
            st.spp,
            st.shadow_samples,
            st.shutter,
            st.seed,
            st.fps,
            st.sampler
        ),
        (
            Some(3),
            Some(16),
            Some(8),
            Some(0.5),
            Some(42),
            Some(30.0),
            Some(glint::scene::Sampler::Stratified)
        )
    );
    assert_eq!(scene.lights[0].shape, LightShape::Sphere { radius: 0.25 });
    assert_eq!(scene.lights[0].velocity, glam::DVec3::X);
    assert!(matches!(scene.lights[1].shape, LightShape::Rect { .. }));
    assert_eq!(scene.lights[2].shape, LightShape::Point);
    assert_eq!(scene.spheres[0].velocity, glam::DVec3::new(0.0, 2.0, 0.0));
    assert_eq!(
        scene.triangles[0].velocity,
        glam::DVec3::new(0.0, 0.0, -1.0)
    );
    let again = scene_from(&to_classic_text(&scene));
    assert_eq!(again, scene);
    // A classic scene written back stays classic: no extension appears.
    if let Some(classic) = classic_scene("test2") {
        let text = to_classic_text(&classic);
        for word in [
            "reflect:", "spp:", "vel:", "rad: 0", "edge_u:", "shutter:", "sampler:",
        ] {
            assert!(!text.contains(word), "{word}");
        }
    }
}

#[test]
fn bad_extension_values_are_located() {
    let cases = [
        (
            "1\namb: 0 0 0\nspp: 0\n",
            "3:6",
            "a whole number from 1 to 65536",
        ),
        (
            "1\namb: 0 0 0\nreflect: 1.5\n",
            "3:10",
            "a whole number from 0 to 64",
        ),
        (
            "1\namb: 0 0 0\nshutter: 2\n",
            "3:10",
            "a shutter between 0 (no blur) and 1",
        ),
        (
            "1\namb: 0 0 0\nsampler: halton\n",
            "3:10",
            "expected a sampler: `sobol` or `stratified`, found `halton`",
        ),
        (
            "1\namb: 0 0 0\nsampler:",
            "3:9",
            "a sampler: `sobol` or `stratified`",
        ),
        (
            "1\namb: 0 0 0\nfps: 0\n",
            "3:6",
            "a positive number of frames per second",
        ),
        (
            "1\namb: 0 0 0\nlight\npos: 0 0 0\ncol: 1 1 1\nrad: -1\n",
            "6:6",
            "light radius must be zero or more",
        ),
        (
            "1\namb: 0 0 0\nlight\npos: 0 0 0\ncol: 1 1 1\nedge_u: 1 0 0\nedge_w: 0 1 0\n",
            "7:1",
            "expected `edge_v:`",
        ),
    ];
    for (text, at, wanted) in cases {
        let err = parse_scene(text.as_bytes(), "x.scene")
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with(&format!("x.scene:{at}:")),
            "{text:?}: {err}"
        );
        assert!(err.contains(wanted), "{text:?}: {err}");
    }
}
