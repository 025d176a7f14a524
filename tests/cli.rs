//! The `glint` binary: exit codes, messages, output files.

mod common;

use std::path::Path;
use std::process::{Command, Output};

use common::cli::*;
use common::*;

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
        // The image is encoded in memory, then written: a 6144^2 PPM is
        // 113 MB to write and sync, a wide window to interrupt.
        let mut child = Command::new(env!("CARGO_BIN_EXE_glint"))
            .args(["render", "empty.scene", "out.ppm", "--backend", "cpu"])
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
        assert!(!d.path().join("out.ppm").exists());
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
