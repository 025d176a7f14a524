//! The `glint` binary: exit codes, messages, output files.

mod common;

use std::path::Path;
use std::process::{Command, Output};

use common::*;

fn glint(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_glint"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run glint")
}

/// As `glint`, with the Vulkan loader pointed at no driver at all.
fn glint_without_vulkan(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_glint"))
        .args(args)
        .current_dir(dir)
        .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
        .env("VK_DRIVER_FILES", "/nonexistent/icd.json")
        .output()
        .expect("run glint")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

fn showcase() -> String {
    repo_path("scenes/showcase.scene").display().to_string()
}

const SMALL: [&str; 4] = ["--width", "40", "--height", "30"];

#[test]
fn missing_scene_file_exits_2_naming_the_path() {
    let d = tmp();
    let o = glint(&["render", "nope.scene"], d.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("cannot read scene file nope.scene"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn bad_scene_exits_2_with_location_and_caret() {
    let d = tmp();
    std::fs::write(
        d.path().join("bad.scene"),
        "1\namb: 0 0 0\nsphere pos: 0 0 -3 rad: x\n",
    )
    .unwrap();
    let o = glint(&["render", "bad.scene"], d.path());
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.contains("bad.scene:3:25: expected a number (the sphere radius), found `x`"),
        "{err}"
    );
    assert!(err.contains("^"), "{err}");
    assert!(
        !d.path().join("bad.jpg").exists(),
        "no image for a bad scene"
    );
}

#[test]
fn bad_flags_exit_2() {
    let d = tmp();
    for args in [
        vec!["render", "x.scene", "--bogus"],
        vec!["render", "x.scene", "--background", "2,0,0"],
        vec!["render", "x.scene", "--backend", "quantum"],
        vec!["render", "x.scene", "--width", "0"],
        vec!["frobnicate"],
    ] {
        let o = glint(&args, d.path());
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("error"), "{args:?}: {}", stderr(&o));
    }
}

#[test]
fn render_defaults_to_scene_stem_jpg_in_the_current_directory() {
    let d = tmp();
    let mut args = vec!["render", "--backend", "cpu"];
    let scene = showcase();
    args.push(&scene);
    args.extend(SMALL);
    let o = glint(&args, d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("wrote showcase.jpg"), "{}", stdout(&o));
    let img = image::open(d.path().join("showcase.jpg")).expect("a readable JPEG");
    assert_eq!((img.width(), img.height()), (40, 30));
    let leftovers: Vec<_> = std::fs::read_dir(d.path()).unwrap().flatten().collect();
    assert_eq!(
        leftovers.len(),
        1,
        "temporary files left behind: {leftovers:?}"
    );
}

#[test]
fn png_output_by_option_and_verbose_timings() {
    let d = tmp();
    let scene = showcase();
    let mut args = vec!["render", &scene, "-o", "out.png", "--backend", "cpu", "-v"];
    args.extend(SMALL);
    let o = glint(&args, d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    for phase in ["parse", "bvh", "cpu render", "write", "total"] {
        assert!(
            stdout(&o).contains(phase),
            "missing {phase} in:\n{}",
            stdout(&o)
        );
    }
    let bytes = std::fs::read(d.path().join("out.png")).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
}

#[test]
fn failed_render_leaves_an_existing_image_untouched() {
    let d = tmp();
    std::fs::write(d.path().join("keep.png"), b"precious").unwrap();
    std::fs::write(d.path().join("bad.scene"), "2\namb: 0 0 0\n").unwrap();
    let o = glint(&["render", "bad.scene", "keep.png"], d.path());
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(
        std::fs::read(d.path().join("keep.png")).unwrap(),
        b"precious"
    );
}

#[test]
fn unsupported_output_type_exits_2_and_says_which_types_work() {
    let d = tmp();
    let scene = showcase();
    let mut args = vec!["render", &scene, "out.bmp", "--backend", "cpu"];
    args.extend(SMALL);
    let o = glint(&args, d.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("use a .png, .jpg, .jpeg, .ppm or .exr file name"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 0);
}

#[test]
fn f64_on_the_gpu_is_refused() {
    let d = tmp();
    let scene = showcase();
    let o = glint(
        &["render", &scene, "--backend", "gpu", "--precision", "f64"],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("CPU reference only"), "{}", stderr(&o));
}

#[test]
fn no_vulkan_device_exits_3_for_gpu_and_falls_back_for_auto() {
    let d = tmp();
    let scene = showcase();
    let mut args = vec!["render", &scene, "--backend", "gpu"];
    args.extend(SMALL);
    let o = glint_without_vulkan(&args, d.path());
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(stderr(&o).contains("--backend cpu"), "{}", stderr(&o));

    let mut args = vec!["render", &scene, "--backend", "auto"];
    args.extend(SMALL);
    let o = glint_without_vulkan(&args, d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("note: no usable Vulkan device"),
        "{}",
        stderr(&o)
    );
    assert!(stdout(&o).contains("CPU reference"), "{}", stdout(&o));

    let o = glint_without_vulkan(&["devices"], d.path());
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(!stderr(&o).contains("--backend"), "{}", stderr(&o));
    // Each command's hint names a flag it accepts.
    let o = glint_without_vulkan(&["bench", "--repeat", "1", &scene], d.path());
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("`--no-gpu`") && !stderr(&o).contains("--backend"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn gpu_render_devices_and_unknown_device() {
    if gpu().is_none() {
        return;
    }
    let d = tmp();
    let o = glint(&["devices"], d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("index"), "{}", stdout(&o));

    let scene = showcase();
    let mut args = vec![
        "render",
        &scene,
        "g.png",
        "--backend",
        "gpu",
        "--device",
        "0",
        "--validation",
    ];
    args.extend(SMALL);
    let o = glint(&args, d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("GPU:"), "{}", stdout(&o));
    assert!(
        !stderr(&o).contains("validation layer reported"),
        "{}",
        stderr(&o)
    );

    let o = glint(
        &[
            "render",
            &scene,
            "--backend",
            "gpu",
            "--device",
            "no such gpu",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("`glint devices` lists"),
        "{}",
        stderr(&o)
    );
    // With auto, a device that is not found is as much an error: no quiet
    // CPU render in its place.
    let o = glint(
        &["render", &scene, "a.png", "--device", "no such gpu"],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(!d.path().join("a.png").exists());
}

/// `--device` with `--backend cpu` says it has no effect (exit 2).
#[test]
fn device_with_the_cpu_backend_is_refused() {
    let d = tmp();
    let o = glint(
        &[
            "render",
            &showcase(),
            "a.png",
            "--backend",
            "cpu",
            "--device",
            "0",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("no effect with --backend cpu"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn info_reports_counts_and_features() {
    let d = tmp();
    let o = glint(&["info", &showcase()], d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("spheres     6"), "{out}");
    assert!(out.contains("lights      2"), "{out}");
    assert!(
        out.contains("calls for   spheres, triangles, shadow rays, Phong shading\n"),
        "{out}"
    );
    assert!(out.contains("shader      spheres+triangles\n"), "{out}");
    // Command-line settings turn effects on, and the shader follows.
    let o = glint(
        &["info", &showcase(), "--spp", "4", "--reflect", "2"],
        d.path(),
    );
    let out = stdout(&o);
    assert!(out.contains("reflection (depth 2)"), "{out}");
    assert!(out.contains("antialiasing (4 samples per pixel)"), "{out}");
    assert!(
        out.contains("shader      spheres+triangles+reflection+multisample\n"),
        "{out}"
    );
}

#[test]
fn compare_reports_metrics_and_fails_on_request() {
    let d = tmp();
    let scene = showcase();
    for (name, bg) in [("a.png", "1,1,1"), ("b.png", "1,1,1"), ("c.png", "0,0,0")] {
        let mut args = vec![
            "render",
            &scene,
            name,
            "--backend",
            "cpu",
            "--background",
            bg,
        ];
        args.extend(SMALL);
        assert_eq!(glint(&args, d.path()).status.code(), Some(0));
    }
    let o = glint(&["compare", "a.png", "b.png", "--fail"], d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("PSNR            inf dB"),
        "{}",
        stdout(&o)
    );
    let o = glint(
        &["compare", "a.png", "c.png", "--diff", "d.png", "--fail"],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stdout(&o).contains("worst pixels"), "{}", stdout(&o));
    assert!(d.path().join("d.png").exists());
}

/// `--pixel` prints the pixel's path on the chosen backend and writes no image.
#[test]
fn pixel_path_is_printed_on_each_backend() {
    let d = tmp();
    let scene = showcase();
    let mut backends = vec!["cpu"];
    if gpu().is_some() {
        backends.push("gpu");
    }
    for backend in backends {
        let o = glint(
            &["render", &scene, "--pixel", "320,300", "--backend", backend],
            d.path(),
        );
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let out = stdout(&o);
        for want in [
            "pixel 320,300 of 640x480",
            "hit sphere 2 at t = ",
            "geometric normal",
            "light 0: shadow ray from",
            "light 1: shadow ray from",
            "colour before clamping",
            "8-bit value",
        ] {
            assert!(out.contains(want), "{backend}: no `{want}` in\n{out}");
        }
        assert!(std::fs::read_dir(d.path()).expect("dir").next().is_none());
    }
    let o = glint(&["render", &scene, "--pixel", "640,0"], d.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("outside the 640x480 image"),
        "{}",
        stderr(&o)
    );
    let o = glint(&["render", &scene, "--pixel", "3"], d.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("expected X,Y"), "{}", stderr(&o));
}

#[test]
fn hard_scenes_are_written_and_render_with_naive_methods_too() {
    let d = tmp();
    let o = glint(&["bench", "hard", "--write-scenes", "hard"], d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let written = std::fs::read_dir(d.path().join("hard"))
        .expect("dir")
        .count();
    assert_eq!(written, glint::hard::cases().len());
    let o = glint(
        &[
            "render",
            "hard/contact_box.scene",
            "c.png",
            "--methods",
            "naive",
            "--backend",
            "cpu",
            "--width",
            "32",
            "--height",
            "24",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(d.path().join("c.png").is_file());
}

/// `glint bench hard` end to end (CPU only here; tests/hard.rs covers the
/// GPU): the table, a pixel list, and exit 0 since every robust count passes.
#[test]
fn bench_hard_prints_counts_and_pixels() {
    let d = tmp();
    let o = glint(
        &["bench", "hard", "--no-gpu", "--no-timing", "--pixels", "1"],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains("| case | backend | NaN | crack | acne |"),
        "{out}"
    );
    assert!(
        out.contains("| vertex_rays | CPU f32 | 0 / 0 | 0 / **"),
        "{out}"
    );
    assert!(out.contains("--pixel "), "{out}");
}

#[test]
fn bench_plots_render_time_against_primitives() {
    let d = tmp();
    let scenes = [
        repo_path("scenes/empty.scene"),
        repo_path("scenes/showcase.scene"),
    ];
    let scenes: Vec<String> = scenes.iter().map(|p| p.display().to_string()).collect();
    let mut args = vec!["bench", "--no-gpu", "--repeat", "1", "--plot", "t.svg"];
    args.extend(scenes.iter().map(String::as_str));
    args.extend(SMALL);
    let o = glint(&args, d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let svg = std::fs::read_to_string(d.path().join("t.svg")).expect("plot written");
    assert!(svg.starts_with("<svg") && svg.contains("CPU f32"), "{svg}");
    assert!(!svg.contains(">GPU<"), "no GPU line without GPU times");
    args[5] = "t.png";
    let o = glint(&args, d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let png = image::open(d.path().join("t.png")).expect("a PNG");
    assert_eq!((png.width(), png.height()), (1440, 960));
    // Refused before any work: a type glint does not draw.
    args[5] = "t.pdf";
    let o = glint(&args, d.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("name an .svg or .png file"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn frames_are_numbered_and_split_by_range() {
    let d = tmp();
    let scene = repo_path("scenes/effects/motion_blur.scene")
        .display()
        .to_string();
    let small = ["--width", "32", "--height", "24", "--spp", "2"];
    let mut args = vec!["render", &scene, "anim", "--frames", "3"];
    args.extend(small);
    let o = glint(&args, d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let names: Vec<String> = {
        let mut v: Vec<String> = std::fs::read_dir(d.path().join("anim"))
            .expect("frame directory")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    assert_eq!(names, ["000.jpg", "001.jpg", "002.jpg"]);
    let frame = |n: &str| std::fs::read(d.path().join("anim").join(n)).expect("frame");
    assert_ne!(frame("000.jpg"), frame("002.jpg"), "the scene moves");

    // A range renders only its frames, the same images as the full run.
    let mut args = vec![
        "render",
        &scene,
        "part",
        "--frames",
        "3",
        "--frame-range",
        "1-2",
    ];
    args.extend(small);
    let o = glint(&args, d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!d.path().join("part/000.jpg").exists());
    let part = std::fs::read(d.path().join("part/002.jpg")).expect("frame 2");
    assert_eq!(part, frame("002.jpg"));

    let mut args = vec![
        "render",
        &scene,
        "bad",
        "--frames",
        "3",
        "--frame-range",
        "2-5",
    ];
    args.extend(small);
    let o = glint(&args, d.path());
    assert_ne!(o.status.code(), Some(0));
    assert!(
        stderr(&o).contains("goes past the last frame"),
        "{}",
        stderr(&o)
    );
    let o = glint(&["render", &scene, "x.jpg", "--frames", "2"], d.path());
    assert_ne!(o.status.code(), Some(0));
    assert!(stderr(&o).contains("is a directory"), "{}", stderr(&o));
}

#[test]
fn effect_overrides_are_checked() {
    let d = tmp();
    for bad in [
        ["--spp", "0"],
        ["--shutter", "1.5"],
        ["--reflect", "65"],
        ["--fps", "0"],
    ] {
        let mut args = vec!["render", "missing.scene"];
        args.extend(bad);
        let o = glint(&args, d.path());
        assert_eq!(o.status.code(), Some(2), "{bad:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(bad[0]), "{bad:?}: {}", stderr(&o));
    }
}

/// A signal while the image is being encoded removes the temporary file and
/// leaves no image: the handler runs where drops cannot.
#[test]
fn an_interrupted_write_leaves_nothing_behind() {
    for signal in ["-INT", "-TERM"] {
        let d = tmp();
        std::fs::write(
            d.path().join("empty.scene"),
            "1\namb: 0.1 0.1 0.1\nlight\npos: 0 0 0\ncol: 1 1 1\n",
        )
        .expect("write scene");
        // 6144^2 JPEG: about 2 s of encoding on a 2-core machine, a wide
        // window to interrupt.
        let mut child = Command::new(env!("CARGO_BIN_EXE_glint"))
            .args(["render", "empty.scene", "out.jpg", "--backend", "cpu"])
            .args(["--width", "6144", "--height", "6144"])
            .current_dir(d.path())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("start glint");
        let parts = || {
            std::fs::read_dir(d.path())
                .expect("list dir")
                .filter_map(Result::ok)
                .filter(|e| e.file_name().to_string_lossy().ends_with(".part"))
                .count()
        };
        let start = std::time::Instant::now();
        while parts() == 0 {
            assert!(
                child.try_wait().expect("poll").is_none(),
                "glint ended before writing (signal {signal})"
            );
            assert!(start.elapsed().as_secs() < 120, "no .part file appeared");
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        let killed = Command::new("kill")
            .args([signal, &child.id().to_string()])
            .status()
            .expect("run kill");
        assert!(killed.success());
        let status = child.wait().expect("wait for glint");
        assert_eq!(status.code(), Some(130), "signal {signal}: {status:?}");
        assert_eq!(parts(), 0, "a .part file was left after {signal}");
        assert!(!d.path().join("out.jpg").exists());
    }
}

/// Output into a pipe that closes early (`glint info S | head -1`) ends
/// glint quietly, never with a panic.
#[test]
fn a_closed_pipe_ends_quietly() {
    for _ in 0..3 {
        let mut child = Command::new(env!("CARGO_BIN_EXE_glint"))
            .args(["info", &showcase()])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("start glint");
        // Close the read end before glint writes its first line.
        drop(child.stdout.take());
        let out = child.wait_with_output().expect("wait");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("panicked"), "{err}");
        assert_ne!(out.status.code(), Some(101), "{err}");
    }
}

/// `--target-error` renders passes until the estimate reaches the target,
/// says so, and writes a float EXR that `compare` reads on its values.
#[test]
fn target_error_stops_on_its_estimate_and_writes_exr() {
    let d = tmp();
    let scene = repo_path("scenes/effects/soft_shadows.scene")
        .display()
        .to_string();
    let o = glint(
        &[
            "render",
            &scene,
            "a.exr",
            "--backend",
            "cpu",
            "--width",
            "32",
            "--height",
            "24",
            "--target-error",
            "0.01",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains("samples per pixel, estimated RMSE 0.0")
            && out.contains("stopped: the estimate reached the target"),
        "{out}"
    );
    let o = glint(
        &[
            "render",
            &scene,
            "b.png",
            "--backend",
            "cpu",
            "--width",
            "32",
            "--height",
            "24",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = glint(&["compare", "a.exr", "b.png"], d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("RMSE "), "{}", stdout(&o));
    // A target outside (0, 1) is bad input.
    let o = glint(
        &[
            "render",
            &scene,
            "c.exr",
            "--backend",
            "cpu",
            "--target-error",
            "0",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!d.path().join("c.exr").exists());
}

/// A scene with nothing random converges at two identical passes, even
/// with only a time limit.
#[test]
fn time_limit_on_a_noiseless_scene_stops_at_two_passes() {
    let d = tmp();
    let o = glint(
        &[
            "render",
            &showcase(),
            "a.png",
            "--backend",
            "cpu",
            "--width",
            "40",
            "--height",
            "30",
            "--time-limit",
            "100",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("2 passes") && stdout(&o).contains("two passes came out identical"),
        "{}",
        stdout(&o)
    );
}

/// `glint accuracy` sweeps what the scene calls for, writes the CSV (its
/// header as documented, a row per point), the Markdown report and the
/// plot, and reuses its cached reference on a second run.
#[test]
fn accuracy_sweeps_and_caches_its_reference() {
    let d = tmp();
    let scene = repo_path("scenes/effects/soft_shadows.scene")
        .display()
        .to_string();
    let args = [
        "accuracy",
        &scene,
        "--out",
        "acc",
        "--backend",
        "cpu",
        "--width",
        "24",
        "--height",
        "16",
        "--repeat",
        "1",
    ];
    let o = glint(&args, d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("cpu: cheapest with FLIP mean <= 0.01"),
        "{}",
        stdout(&o)
    );
    let csv = std::fs::read_to_string(d.path().join("acc/accuracy.csv")).expect("csv");
    let mut lines = csv.lines();
    let header = lines.next().expect("header");
    assert!(
        header.starts_with("knob,value,backend,precision,"),
        "{header}"
    );
    for column in ["time_ms", "rmse", "flip"] {
        assert!(header.split(',').any(|c| c == column), "{header}");
    }
    let rows: Vec<&str> = lines.collect();
    // scene, shadow samples 1..128, naive, f64.
    assert_eq!(rows.len(), 11, "{csv}");
    assert!(
        rows.iter()
            .any(|r| r.starts_with("shadow_samples,1,cpu,f32,")),
        "{csv}"
    );
    let md = std::fs::read_to_string(d.path().join("acc/accuracy.md")).expect("md");
    assert!(
        md.contains("## shadow_samples") && md.contains("## Equal time"),
        "{md}"
    );
    let svg = std::fs::read_to_string(d.path().join("acc/accuracy.svg")).expect("svg");
    assert!(
        svg.starts_with("<svg") && svg.contains("<polyline"),
        "{svg}"
    );
    // The PNG is the same plot at twice the size, drawn here.
    let png = image::open(d.path().join("acc/accuracy.png"))
        .expect("png")
        .to_rgb8();
    assert_eq!((png.width(), png.height()), (1440, 960));
    let coloured = png
        .pixels()
        .filter(|p| p.0.iter().max() != p.0.iter().min())
        .count();
    assert!(
        coloured > 500,
        "plot lines drawn: {coloured} coloured pixels"
    );
    assert!(
        stderr(&o).contains("rendering the reference"),
        "{}",
        stderr(&o)
    );
    let again = glint(&args, d.path());
    assert_eq!(again.status.code(), Some(0), "{}", stderr(&again));
    assert!(
        stderr(&again).contains("(cached)") && !stderr(&again).contains("rendering the reference"),
        "{}",
        stderr(&again)
    );
}

/// `--adaptive` needs a target; with one it reports the mean samples.
#[test]
fn adaptive_needs_a_target_and_reports_mean_samples() {
    let d = tmp();
    let scene = repo_path("scenes/effects/soft_shadows.scene")
        .display()
        .to_string();
    let o = glint(&["render", &scene, "a.exr", "--adaptive"], d.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = glint(
        &[
            "render",
            &scene,
            "a.exr",
            "--backend",
            "cpu",
            "--width",
            "64",
            "--height",
            "48",
            "--target-error",
            "0.002",
            "--adaptive",
        ],
        d.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("samples per pixel on average, at most"),
        "{}",
        stdout(&o)
    );
}

/// Outputs that cannot be written are refused before any work, with exit 2
/// and one line that says why (a scene that would take long to render is
/// never rendered for nothing).
#[test]
fn unwritable_outputs_are_refused_before_rendering() {
    let d = tmp();
    std::fs::create_dir(d.path().join("adir")).expect("mkdir");
    std::fs::write(d.path().join("afile"), b"x").expect("write");
    // all_effects takes seconds at this size: a refusal must come at once.
    let scene = repo_path("scenes/effects/all_effects.scene")
        .display()
        .to_string();
    let cases: [(&[&str], &str); 6] = [
        (
            &["nodir/sub/out.png"],
            "the directory nodir/sub does not exist; create it first",
        ),
        (
            &["adir"],
            "it is a directory; name an image file, e.g. adir/out.png",
        ),
        (&["out.bmp"], "unsupported image type"),
        (&["afile", "--frames", "2"], "this is a file"),
        (&["x.png", "--frames", "2"], "this is an image name"),
        (
            &["fr", "--frames", "12", "--frame-range", "10-14"],
            "goes past the last frame",
        ),
    ];
    for (extra, want) in cases {
        let mut args = vec!["render", scene.as_str()];
        args.extend_from_slice(extra);
        args.extend(["--backend", "cpu"]);
        let start = std::time::Instant::now();
        let o = glint(&args, d.path());
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        let err = stderr(&o);
        assert!(err.contains(want), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: one line, got {err}");
        assert!(!err.contains(".part"), "{args:?}: {err}");
        assert!(
            start.elapsed() < std::time::Duration::from_secs(5),
            "{args:?}: refused only after {:?}",
            start.elapsed()
        );
    }
    assert!(!d.path().join("fr").exists());
    let o = glint(&["compare", "missing.png", "afile.png"], d.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = glint(&["bench", "--no-gpu", "--no-cpu", &scene], d.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("leave nothing to time"),
        "{}",
        stderr(&o)
    );
}

fn glint_with_stdin(args: &[&str], dir: &Path, input: &[u8]) -> Output {
    use std::io::Write;
    let mut child = Command::new(env!("CARGO_BIN_EXE_glint"))
        .args(args)
        .current_dir(dir)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("start glint");
    // glint may refuse the arguments and exit before reading a byte.
    let _ = child.stdin.take().expect("stdin").write_all(input);
    child.wait_with_output().expect("wait")
}

/// `-` reads the scene from standard input and writes a PNG to standard
/// output; the messages then go to stderr, so the PNG stays clean.
#[test]
fn dash_reads_the_scene_from_stdin_and_writes_png_to_stdout() {
    let d = tmp();
    let text = std::fs::read(repo_path("scenes/showcase.scene")).expect("scene");
    let mut args = vec!["render", "-", "-", "--backend", "cpu"];
    args.extend(SMALL);
    let o = glint_with_stdin(&args, d.path(), &text);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(o.stdout.starts_with(b"\x89PNG\r\n\x1a\n"), "not a PNG");
    assert!(
        stderr(&o).contains("wrote standard output"),
        "{}",
        stderr(&o)
    );
    let piped = image::load_from_memory(&o.stdout).expect("PNG").to_rgb8();

    let scene = showcase();
    let mut args = vec!["render", &scene, "f.png", "--backend", "cpu"];
    args.extend(SMALL);
    let o = glint(&args, d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let file = image::open(d.path().join("f.png")).expect("png").to_rgb8();
    assert_eq!(piped, file);

    // A scene from stdin is named <stdin> in its errors.
    let o = glint_with_stdin(
        &["render", "-", "x.png"],
        d.path(),
        b"1\nsphere\npos: 0 0\n",
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("<stdin>:2:1"), "{}", stderr(&o));
    let o = glint_with_stdin(&["info", "-"], d.path(), &text);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("spheres     6"), "{}", stdout(&o));
    // One image on stdout: frames are refused before any work.
    let o = glint_with_stdin(&["render", "-", "-", "--frames", "2"], d.path(), &text);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// `--crop` parts, rendered on either backend and in either format, stitch
/// to exactly the image one render makes; a gap or a bad crop is refused.
#[test]
fn crop_parts_stitch_to_the_full_image() {
    let d = tmp();
    let scene = repo_path("scenes/effects/all_effects.scene")
        .display()
        .to_string();
    let size = ["--width", "48", "--height", "36", "--spp", "2"];
    let backends: Vec<&str> = if gpu().is_some() {
        vec!["cpu", "gpu"]
    } else {
        vec!["cpu"]
    };
    for backend in backends {
        let run = |extra: &[&str]| {
            let mut args = vec!["render", &scene, "--backend", backend];
            args.extend(size);
            args.extend(extra);
            let o = glint(&args, d.path());
            assert_eq!(o.status.code(), Some(0), "{backend}: {}", stderr(&o));
        };
        run(&["full.exr"]);
        run(&["full.png"]);
        run(&["top.exr", "--crop", "0,0,48,20"]);
        run(&["left.png", "--crop", "0,20,17,36"]);
        run(&["right.exr", "--crop", "17,20,48,36"]);
        let o = glint(
            &["stitch", "joined.exr", "top.exr", "left.png", "right.exr"],
            d.path(),
        );
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let o = glint(
            &["stitch", "j.png", "top.exr", "right.exr", "left.png"],
            d.path(),
        );
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let png = |n: &str| image::open(d.path().join(n)).expect(n).to_rgb8();
        assert_eq!(png("j.png"), png("full.png"), "{backend}: 8-bit join");
        // All-float parts keep every float bit.
        run(&["left.exr", "--crop", "0,20,17,36"]);
        let o = glint(
            &["stitch", "f.exr", "top.exr", "left.exr", "right.exr"],
            d.path(),
        );
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let float = |n: &str| image::open(d.path().join(n)).expect(n).to_rgb32f();
        assert_eq!(float("f.exr"), float("full.exr"), "{backend}: float join");

        let o = glint(&["stitch", "gap.png", "top.exr", "right.exr"], d.path());
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(
            stderr(&o).contains("leave 272 of the 48x36 pixels uncovered, within 0,20,17,36"),
            "{}",
            stderr(&o)
        );
        assert!(!d.path().join("gap.png").exists());
    }
    for (crop, out, want) in [
        ("0,0,49,10", "x.png", "reaches outside the 48x36 image"),
        ("0,0,10,10", "x.jpg", "write .png or .exr"),
        ("5,5,5,9", "x.png", "X0 < X1"),
    ] {
        let mut args = vec!["render", &scene, out, "--crop", crop];
        args.extend(size);
        let o = glint(&args, d.path());
        assert_eq!(o.status.code(), Some(2), "{crop}: {}", stderr(&o));
        assert!(stderr(&o).contains(want), "{crop}: {}", stderr(&o));
    }
    let o = glint(&["stitch", "x.png", "full.png"], d.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("no alpha channel"), "{}", stderr(&o));
}

/// The rays line of `--stats`: closest-hit and shadow counts.
fn stats_rays(out: &str) -> [u64; 4] {
    let line = out
        .lines()
        .find(|l| l.trim_start().starts_with("rays "))
        .unwrap_or_else(|| panic!("no rays line in\n{out}"));
    let numbers: Vec<u64> = line
        .split(|c: char| !c.is_ascii_digit() && c != '.')
        .filter_map(|w| w.parse().ok())
        .collect();
    [numbers[0], numbers[1], numbers[2], numbers[3]]
}

/// `--stats` counts rays by kind, and the shader counts the same rays as
/// the CPU reference; `--quick` is the documented preview; `--threads`
/// sizes the CPU pool.
#[test]
fn stats_quick_and_threads() {
    let d = tmp();
    let scene = repo_path("scenes/effects/all_effects.scene")
        .display()
        .to_string();
    let run = |backend: &str, extra: &[&str]| {
        let mut args = vec!["render", &scene, "s.png", "--backend", backend, "--stats"];
        args.extend(extra);
        let o = glint(&args, d.path());
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        stdout(&o)
    };
    let size = ["--width", "40", "--height", "30", "--spp", "2"];
    let cpu = run("cpu", &size);
    let [all, primary, reflected, shadow] = stats_rays(&cpu);
    assert_eq!(primary, 40 * 30 * 2, "{cpu}");
    assert!(reflected > 0 && shadow > primary, "{cpu}");
    assert_eq!(all, primary + reflected + shadow, "{cpu}");
    assert!(cpu.contains("samples     2400"), "{cpu}");
    assert!(cpu.contains("SAH cost"), "{cpu}");
    assert!(cpu.contains("peak memory"), "{cpu}");
    if gpu().is_some() {
        let gpu_out = run("gpu", &size);
        let g = stats_rays(&gpu_out);
        // The twins trace the same rays; a pixel whose f32 hit differs
        // could change a few.
        for (a, b) in g.iter().zip([all, primary, reflected, shadow]) {
            assert!(a.abs_diff(b) * 1000 <= b, "GPU {g:?} vs CPU {cpu}");
        }
    }

    // --quick: half size, 1 sample, 1 shadow sample, no reflection.
    let quick = run("cpu", &["--quick"]);
    assert!(quick.contains("(320x240,"), "{quick}");
    let [_, primary, reflected, _] = stats_rays(&quick);
    assert_eq!((primary, reflected), (320 * 240, 0), "{quick}");
    // Flags beside it win.
    let quick = run(
        "cpu",
        &["--quick", "--spp", "3", "--width", "64", "--height", "48"],
    );
    assert!(quick.contains("(32x24,"), "{quick}");
    assert_eq!(stats_rays(&quick)[1], 32 * 24 * 3, "{quick}");

    let one = run("cpu", &["--threads", "1", "--width", "8", "--height", "8"]);
    assert!(one.contains("1 threads"), "{one}");
    let o = Command::new(env!("CARGO_BIN_EXE_glint"))
        .args([
            "render",
            &scene,
            "e.png",
            "--backend",
            "cpu",
            "--width",
            "8",
            "--height",
            "8",
        ])
        .env("RAYON_NUM_THREADS", "3")
        .current_dir(d.path())
        .output()
        .expect("run glint");
    assert!(stdout(&o).contains("3 threads"), "{}", stdout(&o));
    let o = glint(&["render", &scene, "--threads", "0"], d.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// PPM is written (binary P6) and read back by compare.
#[test]
fn ppm_is_written_and_compared() {
    let d = tmp();
    for out in ["a.ppm", "a.png"] {
        let scene = showcase();
        let mut args = vec!["render", &scene, out, "--backend", "cpu"];
        args.extend(SMALL);
        let o = glint(&args, d.path());
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    }
    let bytes = std::fs::read(d.path().join("a.ppm")).expect("ppm");
    assert!(bytes.starts_with(b"P6"), "binary PPM");
    let o = glint(&["compare", "a.ppm", "a.png", "--fail"], d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stdout(&o));
    assert!(
        stdout(&o).contains("max abs diff    0.000"),
        "{}",
        stdout(&o)
    );
}

/// With only a software Vulkan device, auto renders on the CPU reference
/// (faster there) and says so; a hardware device is used.
#[test]
fn auto_prefers_the_cpu_reference_over_a_software_device() {
    let Some(g) = gpu() else {
        return;
    };
    let software = g
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .ctx
        .info()
        .device_type
        == "CPU";
    let d = tmp();
    let scene = showcase();
    let mut args = vec!["render", &scene, "a.png"];
    args.extend(SMALL);
    let o = glint(&args, d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    if software {
        assert!(stdout(&o).contains("CPU reference"), "{}", stdout(&o));
        assert!(
            stderr(&o).contains("software one") && stderr(&o).contains("`--backend gpu`"),
            "{}",
            stderr(&o)
        );
        // A device asked for is used.
        args.extend(["--device", "0"]);
        let o = glint(&args, d.path());
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        assert!(stdout(&o).contains("GPU:"), "{}", stdout(&o));
    } else {
        assert!(stdout(&o).contains("GPU:"), "{}", stdout(&o));
    }
}

/// An I/O error is said once, not once more by the error chain.
#[test]
fn an_os_error_is_printed_once() {
    let d = tmp();
    std::fs::create_dir(d.path().join("adir")).expect("mkdir");
    let o = glint(&["render", "adir", "x.png", "--backend", "cpu"], d.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("cannot read scene file adir"), "{err}");
    assert_eq!(err.matches("os error").count(), 1, "{err}");
}

/// A stand-in for the Embree harness: a shell script that appends its
/// arguments to `calls` and prints what `body` prints.
#[cfg(unix)]
fn fake_harness(dir: &Path, body: &str) -> std::path::PathBuf {
    use std::os::unix::fs::PermissionsExt;
    let path = dir.join("harness.sh");
    std::fs::write(
        &path,
        format!(
            "#!/bin/sh\necho \"$@\" >> \"{}\"\n{body}\n",
            dir.join("calls").display()
        ),
    )
    .expect("write the fake harness");
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).expect("chmod");
    path
}

#[cfg(unix)]
#[test]
fn bench_embree_alternates_with_the_harness_and_reports_its_ratios() {
    let d = tmp();
    let harness = fake_harness(
        d.path(),
        "echo 'throughput: 1 Mrays/s'\n\
         echo 'RESULT scene=x W=16 H=12 render_med_s=0.0040 rays=4242 mrays_s=1'",
    );
    let scene = showcase();
    let o = glint(
        &[
            "--threads",
            "1",
            "bench",
            "embree",
            harness.to_str().unwrap(),
            &scene,
            "--no-gpu",
            "--rounds",
            "2",
            "--repeat",
            "1",
            "--width",
            "16",
            "--height",
            "12",
        ],
        d.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let row = out
        .lines()
        .find(|l| l.starts_with("| showcase |"))
        .unwrap_or_else(|| panic!("no showcase row in\n{out}"));
    let cells: Vec<&str> = row.split('|').map(str::trim).collect();
    // scene, rays, glint CPU, single, CPU/single, packet8, CPU/packet8, GPU, GPU/packet8
    // The fake's ray count is not glint's: flagged in the cell, below the
    // table and on stderr.
    assert!(cells[2].contains("/ 4242 (**differ**"), "{row}");
    assert!(out.contains("cast different rays on showcase"), "{out}");
    assert!(stderr(&o).contains("warning: showcase"), "{}", stderr(&o));
    assert_eq!(cells[4], "4.0 / 4.0", "{row}");
    assert_eq!(cells[6], "4.0 / 4.0", "{row}");
    assert_eq!(cells[3].split(" / ").count(), 2, "{row}");
    assert_ne!(cells[5], "-", "{row}");
    assert_eq!(cells[8], "-", "{row}");
    // Per round: single, then packet8, each with the render's settings.
    let calls = std::fs::read_to_string(d.path().join("calls")).expect("the harness ran");
    let calls: Vec<&str> = calls.lines().collect();
    assert_eq!(calls.len(), 4, "{calls:?}");
    for (call, mode) in calls.iter().zip(["single", "packet8", "single", "packet8"]) {
        assert_eq!(
            *call,
            format!("{scene} --width 16 --height 12 --threads 1 --runs 1 --mode {mode}"),
        );
    }
}

#[cfg(unix)]
#[test]
fn bench_embree_reports_a_failing_or_silent_harness() {
    let d = tmp();
    let scene = showcase();
    let args = |h: &Path| -> Vec<String> {
        [
            "bench",
            "embree",
            h.to_str().unwrap(),
            &scene,
            "--no-gpu",
            "--rounds",
            "1",
            "--repeat",
            "1",
        ]
        .into_iter()
        .chain(SMALL)
        .map(String::from)
        .collect()
    };
    let run = |h: &Path| {
        let a = args(h);
        glint(&a.iter().map(String::as_str).collect::<Vec<_>>(), d.path())
    };
    let failing = fake_harness(d.path(), "echo 'cannot open scene' >&2\nexit 3");
    let o = run(&failing);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("cannot open scene"), "{}", stderr(&o));
    assert!(stderr(&o).contains(&scene), "{}", stderr(&o));
    let silent = fake_harness(d.path(), "echo 'done'");
    let o = run(&silent);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("no `RESULT"), "{}", stderr(&o));
    let o = run(&d.path().join("missing"));
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("no such harness program"),
        "{}",
        stderr(&o)
    );
}
