//! The command line's modes beyond a plain render: pixel paths, the hard
//! cases, benchmarks (Embree's included), animation frames, effect
//! overrides, renders that stop at an error or a time, accuracy sweeps,
//! cropped parts and statistics.

mod common;

use std::path::Path;
use std::process::Command;

use common::cli::*;
use common::*;

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
    assert_eq!(written, glint::suites::hard::cases().len());
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
    assert_eq!((png.width(), png.height()), (1520, 960));
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

/// `glint bench`'s end-to-end column times `glint render SCENE out.jpg`
/// as a process on each backend it runs: a time in milliseconds;
/// `--no-end-to-end` leaves it out.
#[test]
fn bench_times_the_render_command_end_to_end() {
    let d = tmp();
    let scene = repo_path("scenes/showcase.scene").display().to_string();
    let mut args = vec!["bench", "--no-gpu", "--repeat", "1", scene.as_str()];
    args.extend(SMALL);
    let o = glint(&args, d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    let row = out
        .lines()
        .find(|l| l.starts_with("| showcase |"))
        .unwrap_or_else(|| panic!("no showcase row: {out}"));
    let cells: Vec<&str> = row.split('|').map(str::trim).collect();
    let number = |cell: &str, after: &str| -> f64 {
        let rest = cell
            .strip_prefix(after)
            .unwrap_or_else(|| panic!("{cell:?}"));
        let first = rest.split_whitespace().next().expect("a number");
        first.parse().unwrap_or_else(|_| panic!("{cell:?}"))
    };
    assert!(number(cells[7], "") > 0.0, "{row}");
    assert!(number(cells[9], "f32 ") > 0.0, "{row}");
    assert!(
        stderr(&o).contains("showcase: f32 end to end"),
        "{}",
        stderr(&o)
    );
    args.push("--no-end-to-end");
    let o = glint(&args, d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let row = stdout(&o)
        .lines()
        .find(|l| l.starts_with("| showcase |"))
        .map(str::to_string)
        .expect("a row");
    assert!(row.trim_end().ends_with("| - |"), "{row}");
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
    for column in ["sampler", "time_ms", "rmse", "flip"] {
        assert!(header.split(',').any(|c| c == column), "{header}");
    }
    let rows: Vec<&str> = lines.collect();
    // scene and shadow samples 1..128 with each sampler, naive, f64.
    assert_eq!(rows.len(), 20, "{csv}");
    for sampler in ["sobol", "stratified"] {
        assert!(
            rows.iter()
                .any(|r| r.starts_with(&format!("shadow_samples,1,cpu,f32,robust,{sampler},"))),
            "{csv}"
        );
    }
    let md = std::fs::read_to_string(d.path().join("acc/accuracy.md")).expect("md");
    assert!(
        md.contains("## shadow_samples")
            && md.contains("## Equal time")
            && md.contains("## Samplers"),
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
    assert_eq!((png.width(), png.height()), (1520, 960));
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
    // --sampler sweeps that one alone.
    let one: Vec<&str> = args
        .iter()
        .copied()
        .chain(["--sampler", "stratified"])
        .collect();
    let o = glint(&one, d.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let csv = std::fs::read_to_string(d.path().join("acc/accuracy.csv")).expect("csv");
    assert_eq!(csv.lines().count(), 12, "{csv}");
    assert!(
        csv.lines().skip(1).all(|r| r.contains(",stratified,")),
        "{csv}"
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
