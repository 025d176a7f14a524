//! `glint render --part` and `glint stitch --parts`, through the binary as a
//! cluster's tasks run it: parts join to the single render bit for bit (on
//! the CPU reference and on the GPU), a re-run task keeps a finished part,
//! parts of another render are refused by index, missing parts are named
//! and waited for, the index comes from Slurm's or Kubernetes' variable.

mod common;

use std::path::Path;
use std::process::{Command, Output};

use common::cli::{glint, showcase, stderr, stdout, tmp};

fn glint_env(args: &[&str], dir: &Path, env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_glint"));
    c.args(args).current_dir(dir);
    c.env_remove("SLURM_ARRAY_TASK_ID")
        .env_remove("JOB_COMPLETION_INDEX");
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().expect("run glint")
}

fn ok(o: &Output) {
    assert!(o.status.success(), "{}\n{}", stdout(o), stderr(o));
}

const SIZE: [&str; 4] = ["--width", "24", "--height", "16"];

/// Renders OUT whole and in `n` parts with `extra` options, stitches, and
/// checks the two images are the same file (PNG) or the same floats (EXR).
fn parts_equal_whole(dir: &Path, n: u32, ext: &str, extra: &[&str]) {
    let scene = showcase();
    let whole = format!("whole-{n}.{ext}");
    let joined = format!("joined-{n}.{ext}");
    let mut args = vec!["render", &scene, &whole];
    args.extend(SIZE);
    args.extend(extra);
    ok(&glint(&args, dir));
    for i in 0..n {
        let part = format!("{i}/{n}");
        let mut args = vec!["render", &scene, &joined, "--part", &part];
        args.extend(SIZE);
        args.extend(extra);
        ok(&glint(&args, dir));
    }
    let count = n.to_string();
    ok(&glint(&["stitch", &joined, "--parts", &count], dir));
    let a = glint::images::framebuffer::read_framebuffer(&dir.join(&whole)).expect("whole");
    let b = glint::images::framebuffer::read_framebuffer(&dir.join(&joined)).expect("joined");
    assert_eq!(a, b, "{n} parts of {ext} with {extra:?}");
}

/// One part, a few strips, and more parts than rows (runs of pixels that
/// end mid-row), in 8-bit and float.
#[test]
fn parts_join_to_the_single_render_bit_for_bit() {
    let dir = tmp();
    for n in [1, 3, 40] {
        parts_equal_whole(dir.path(), n, "png", &["--backend", "cpu"]);
    }
    parts_equal_whole(dir.path(), 5, "exr", &["--backend", "cpu", "--spp", "4"]);
}

#[test]
fn gpu_parts_join_to_the_single_gpu_render_bit_for_bit() {
    if common::gpu().is_none() {
        common::notice("SKIPPED gpu parts: no Vulkan device");
        assert!(!common::in_ci(), "CI has lavapipe: the GPU must be found");
        return;
    }
    let dir = tmp();
    parts_equal_whole(dir.path(), 7, "exr", &["--backend", "gpu"]);
}

#[test]
fn a_rerun_keeps_a_finished_part_and_other_renders_are_refused() {
    let dir = tmp();
    let d = dir.path();
    let scene = showcase();
    let run = |i: u32, extra: &[&str]| {
        let part = format!("{i}/3");
        let mut args = vec![
            "render",
            scene.as_str(),
            "out.png",
            "--part",
            &part,
            "--backend",
            "cpu",
        ];
        args.extend(SIZE);
        args.extend(extra);
        glint(&args, d)
    };
    for i in 0..3 {
        ok(&run(i, &[]));
    }
    let part1 = d.join("out.part1-of-3.png");
    let before = std::fs::read(&part1).expect("part");
    let again = run(1, &[]);
    ok(&again);
    assert!(
        stdout(&again).contains("part 1 of 3 is already done"),
        "{}",
        stdout(&again)
    );
    // A part of another render (here another spp) is replaced on a re-run
    // with those settings, and stitch refuses to mix the two.
    let other = run(1, &["--spp", "2"]);
    ok(&other);
    assert!(
        stderr(&other).contains("another render"),
        "{}",
        stderr(&other)
    );
    assert_ne!(std::fs::read(&part1).expect("part"), before);
    let mixed = glint(&["stitch", "out.png", "--parts", "3"], d);
    assert_eq!(mixed.status.code(), Some(2));
    assert!(
        stderr(&mixed).contains("different renders"),
        "{}",
        stderr(&mixed)
    );
    assert!(
        stderr(&mixed).contains("part 1 of render"),
        "{}",
        stderr(&mixed)
    );
    assert!(!d.join("out.png").exists());
    // A part file that is not what its name says is refused too.
    std::fs::copy(d.join("out.part0-of-3.png"), d.join("out.part2-of-3.png")).expect("copy");
    let renamed = glint(&["stitch", "out.png", "--parts", "3"], d);
    assert!(
        stderr(&renamed).contains("not part 2 of 3"),
        "{}",
        stderr(&renamed)
    );
}

#[test]
fn missing_parts_are_named_and_can_be_waited_for() {
    let dir = tmp();
    let d = dir.path();
    let scene = showcase();
    for i in [0, 2, 3] {
        let part = format!("{i}/4");
        let mut args = vec![
            "render",
            scene.as_str(),
            "o.exr",
            "--part",
            &part,
            "--backend",
            "cpu",
        ];
        args.extend(SIZE);
        ok(&glint(&args, d));
    }
    let missing = glint(&["stitch", "o.exr", "--parts", "4"], d);
    assert_eq!(missing.status.code(), Some(2));
    assert!(
        stderr(&missing).contains("part 1 of 4 missing"),
        "{}",
        stderr(&missing)
    );
    assert!(
        stderr(&missing).contains("--array=1"),
        "{}",
        stderr(&missing)
    );
    // The missing part arrives while stitch waits.
    let late = std::thread::spawn({
        let (d, scene) = (d.to_path_buf(), scene.clone());
        move || {
            std::thread::sleep(std::time::Duration::from_millis(1500));
            let mut args = vec![
                "render",
                scene.as_str(),
                "o.exr",
                "--part",
                "1/4",
                "--backend",
                "cpu",
            ];
            args.extend(SIZE);
            glint(&args, &d)
        }
    });
    let waited = glint(&["stitch", "o.exr", "--parts", "4", "--wait", "60"], d);
    ok(&late.join().expect("late part"));
    ok(&waited);
    assert!(
        stderr(&waited).contains("waiting for 1 of 4 parts: 1"),
        "{}",
        stderr(&waited)
    );
}

#[test]
fn the_index_comes_from_slurm_or_kubernetes() {
    let dir = tmp();
    let d = dir.path();
    let scene = showcase();
    let args = |part: &'static str| -> Vec<String> {
        let mut a: Vec<String> = [
            "render",
            scene.as_str(),
            "k.png",
            "--part",
            part,
            "--backend",
            "cpu",
        ]
        .map(String::from)
        .to_vec();
        a.extend(SIZE.map(String::from));
        a
    };
    let run = |part, env: &[(&str, &str)]| {
        let a = args(part);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        glint_env(&a, d, env)
    };
    ok(&run("slurm/2", &[("SLURM_ARRAY_TASK_ID", "1")]));
    assert!(d.join("k.part1-of-2.png").exists());
    ok(&run("k8s/2", &[("JOB_COMPLETION_INDEX", "0")]));
    assert!(d.join("k.part0-of-2.png").exists());
    ok(&glint(&["stitch", "k.png", "--parts", "2"], d));
    let unset = run("slurm/2", &[]);
    assert_eq!(unset.status.code(), Some(2));
    assert!(
        stderr(&unset).contains("SLURM_ARRAY_TASK_ID, which is not set"),
        "{}",
        stderr(&unset)
    );
    let past = run("k8s/2", &[("JOB_COMPLETION_INDEX", "2")]);
    assert_eq!(past.status.code(), Some(2));
    assert!(
        stderr(&past).contains("JOB_COMPLETION_INDEX is 2"),
        "{}",
        stderr(&past)
    );
}

/// Frames in shares: every frame once, a re-run keeps what is there, and a
/// directory of another render's frames is refused.
#[test]
fn frames_are_shared_out_and_resumed() {
    let dir = tmp();
    let d = dir.path();
    let scene = showcase();
    let run = |i: u32, frames: &str| {
        let part = format!("{i}/3");
        let mut args = vec![
            "render",
            scene.as_str(),
            "anim",
            "--frames",
            frames,
            "--frame-format",
            "png",
        ];
        args.extend(["--part", &part, "--backend", "cpu"]);
        args.extend(SIZE);
        glint(&args, d)
    };
    for i in 0..3 {
        ok(&run(i, "4"));
    }
    let names: Vec<String> = (0..4).map(|f| format!("{f:03}.png")).collect();
    for n in &names {
        assert!(d.join("anim").join(n).exists(), "{n}");
    }
    let again = run(2, "4");
    ok(&again);
    assert!(
        stdout(&again).contains("2 of them were already there and kept"),
        "{}",
        stdout(&again)
    );
    let other = run(0, "5");
    assert_eq!(other.status.code(), Some(2), "{}", stderr(&other));
    assert!(
        stderr(&other).contains("frames of another render"),
        "{}",
        stderr(&other)
    );
}
