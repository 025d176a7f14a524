//! `glint check`: the built-in suite passes on the device CI has, a
//! planted wrong result fails it (exit 1, naming the scene, with its
//! difference image), its JUnit XML has the shape CI systems read, no
//! device is exit 3, and pipelines kept on disk spare the next run's
//! compiles where the driver keeps them.

mod common;

use std::path::Path;
use std::process::{Command, Output};

use common::*;

fn check(args: &[&str], dir: &Path, cache: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_glint"))
        .arg("check")
        .args(args)
        .current_dir(dir)
        .env("XDG_CACHE_HOME", cache)
        .env_remove("GLINT_PIPELINE_CACHE")
        .output()
        .expect("run glint")
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// The quick suite passes, every scene reported, and the JUnit file reads
/// back with a test case per scene and no failures.
#[test]
fn the_quick_suite_passes_and_writes_junit() {
    if gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let o = check(&["--quick", "--junit", "j.xml"], dir.path(), dir.path());
    let out = text(&o);
    assert_eq!(o.status.code(), Some(0), "{out}");
    assert!(
        out.contains("profile: ") && out.contains("limits: "),
        "{out}"
    );
    let rows = out.lines().filter(|l| l.contains(" PASS ")).count();
    assert!(rows >= 25, "{rows} scenes: {out}");
    let xml = std::fs::read_to_string(dir.path().join("j.xml")).expect("junit written");
    let report = quick_junit::Report::deserialize_from_str(&xml).expect("valid JUnit XML");
    assert_eq!(report.test_suites.len(), 1);
    let suite = &report.test_suites[0];
    assert_eq!(suite.test_cases.len(), rows);
    assert_eq!(suite.failures, 0);
    assert!(suite
        .test_cases
        .iter()
        .any(|c| c.name.as_str() == "split_bindings"));
}

/// A wrong image (the test-only option perturbs one scene's device
/// output) fails the check: exit 1, the scene named, its images written,
/// a JUnit failure with the reason.
#[test]
fn a_planted_error_fails_the_check_naming_the_scene() {
    if gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let o = check(
        &[
            "--only",
            "reflection",
            "--plant-error",
            "reflection",
            "--out",
            "diffs",
            "--junit",
            "j.xml",
        ],
        dir.path(),
        dir.path(),
    );
    let out = text(&o);
    assert_eq!(o.status.code(), Some(1), "{out}");
    assert!(
        out.contains("FAIL: 1 of 1") && out.contains("reflection: "),
        "{out}"
    );
    assert!(
        out.contains("more than 1 level off the CPU f32 twin"),
        "{out}"
    );
    for f in [
        "reflection.diff.png",
        "reflection.device.png",
        "reflection.cpu.png",
    ] {
        assert!(dir.path().join("diffs").join(f).is_file(), "{f}: {out}");
    }
    let xml = std::fs::read_to_string(dir.path().join("j.xml")).expect("junit written");
    let report = quick_junit::Report::deserialize_from_str(&xml).expect("valid JUnit XML");
    assert_eq!(report.test_suites[0].failures, 1);
    assert!(xml.contains("<failure") && xml.contains("twin"), "{xml}");
}

#[test]
fn no_device_is_exit_3() {
    let dir = tempfile::tempdir().expect("temp dir");
    let o = Command::new(env!("CARGO_BIN_EXE_glint"))
        .args(["check", "--quick"])
        .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
        .env("VK_DRIVER_FILES", "/nonexistent/icd.json")
        .current_dir(dir.path())
        .output()
        .expect("run glint");
    assert_eq!(o.status.code(), Some(3), "{}", text(&o));
}

/// Pipelines go to the disk cache and the next run takes them from there,
/// compiling nothing, where the driver keeps pipeline data; lavapipe keeps
/// none (its cache data is a bare header), which this says.
#[test]
fn a_second_run_compiles_nothing_where_the_driver_keeps_pipelines() {
    if gpu().is_none() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let first = check(&["--only", "phong"], dir.path(), dir.path());
    assert!(
        text(&first).contains("1 pipelines compiled, 0 from the disk cache"),
        "{}",
        text(&first)
    );
    let kept = std::fs::read_dir(dir.path().join("glint/pipelines"))
        .map(|d| d.count())
        .unwrap_or(0);
    let second = check(&["--only", "phong"], dir.path(), dir.path());
    if kept == 0 {
        notice("SKIPPED: a second run from the disk cache: this driver keeps no pipeline data");
        assert!(
            text(&second).contains("1 pipelines compiled"),
            "{}",
            text(&second)
        );
        return;
    }
    assert!(
        text(&second).contains("0 pipelines compiled, 1 from the disk cache"),
        "{}",
        text(&second)
    );
}

/// `check::image_test`, the suite's judging as one library call: a scene
/// of one's own passes on the device CI has, and a tolerance nothing can
/// meet fails it, naming why and writing the device's image, the CPU
/// twin's and their difference.
#[test]
fn an_image_test_of_ones_own_scene_passes_and_fails_visibly() {
    if gpu().is_none() {
        return;
    }
    let scene = scene_from(
        "2\namb: 0.1 0.1 0.1\n\
         sphere pos: 0 0 -3 rad: 1 dif: 0.2 0.6 0.9 spe: 0.3 0.3 0.3 shi: 16\n\
         light pos: 2 3 0 col: 1 1 1\n",
    );
    let dir = tempfile::tempdir().expect("temp dir");
    let test = glint::suites::check::ImageTest {
        out: Some(dir.path().join("failures")),
        ..glint::suites::check::ImageTest::new("ball", 96, 72)
    };
    let v = glint::suites::check::image_test(&scene, &test).expect("renders on both");
    assert!(v.passed(), "{:?}", v.failure);
    assert!(v.device.starts_with("GPU"), "{}", v.device);
    assert!(v.written.is_empty());
    let strict = glint::suites::check::ImageTest {
        tolerance: glint::suites::check::Tolerance {
            f32_flip: -1.0,
            ..glint::suites::check::Tolerance::TIGHT
        },
        ..test
    };
    let v = glint::suites::check::image_test(&scene, &strict).expect("renders on both");
    let why = v.failure.as_deref().unwrap_or_default();
    assert!(why.contains("FLIP") && why.contains("f32 twin"), "{why}");
    assert_eq!(v.written.len(), 3);
    for path in &v.written {
        let image = glint::images::framebuffer::open(path).expect("a readable image");
        assert_eq!(
            (image.width(), image.height()),
            (96, 72),
            "{}",
            path.display()
        );
    }
}
