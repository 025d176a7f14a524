//! `glint view` in a real window on an X server this test starts (Xvfb):
//! the window's pixels, read back from the server, are the image `render`
//! writes, presented by the Vulkan device (its passes averaged there) or
//! drawn by the host; the title reports samples and error; a drag moves the camera
//! and restarts the refinement; `C` prints the camera block and `S` saves
//! what `render` makes with it; a heavy scene shows a preview first and
//! the report on exit says so; without a display, one line and exit 2.

mod common;

use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::*;

const SCENE: &str = "4
amb: 0.1 0.1 0.12
sphere pos: -0.6 0 -3 rad: 0.6 dif: 0.8 0.3 0.2 spe: 0.5 0.5 0.5 shi: 30
sphere pos: 0.7 -0.2 -3.5 rad: 0.5 dif: 0.2 0.5 0.8 spe: 0.3 0.3 0.3 shi: 10
triangle
pos: -3 -0.7 -1 nor: 0 1 0 dif: 0.7 0.7 0.6 spe: 0 0 0 shi: 1
pos: 3 -0.7 -1 nor: 0 1 0 dif: 0.7 0.7 0.6 spe: 0 0 0 shi: 1
pos: 0 -0.7 -8 nor: 0 1 0 dif: 0.7 0.7 0.6 spe: 0 0 0 shi: 1
light pos: 2 3 0 col: 0.8 0.8 0.8
";

/// An Xvfb of this test's own, on a display number no one else uses.
struct Xvfb {
    child: Child,
    display: String,
}

impl Xvfb {
    fn start() -> Option<Xvfb> {
        let have = |tool: &str| {
            Command::new("sh")
                .args(["-c", &format!("command -v {tool}")])
                .output()
                .is_ok_and(|o| o.status.success())
        };
        let missing: Vec<&str> = ["Xvfb", "xdotool", "import"]
            .into_iter()
            .filter(|t| !have(t))
            .collect();
        if !missing.is_empty() {
            let msg = format!("SKIPPED: the window tests need {missing:?} (apt-get install xvfb xdotool imagemagick)");
            assert!(!in_ci(), "{msg}");
            notice(&msg);
            return None;
        }
        // A display per test of this process (they run in parallel).
        static NEXT: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        let k = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let n = 100 + (std::process::id() % 400) * 4 + k;
        let display = format!(":{n}");
        let child = Command::new("Xvfb")
            // -noreset: an X server resets when its last client leaves, and
            // a client that connects meanwhile is refused (each xdotool
            // call here is such a client).
            .args([
                &display,
                "-screen",
                "0",
                "1024x768x24",
                "-nolisten",
                "tcp",
                "-noreset",
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start Xvfb");
        let x = Xvfb { child, display };
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(10) {
            if x.tool("xdotool", &["getdisplaygeometry"]).status.success() {
                return Some(x);
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        panic!("Xvfb did not start on {}", x.display);
    }

    fn tool(&self, tool: &str, args: &[&str]) -> Output {
        Command::new(tool)
            .args(args)
            .env("DISPLAY", &self.display)
            .output()
            .expect("run an X tool")
    }

    /// The viewer's window, once it exists; if the viewer ends first, or
    /// no window shows in time, what it printed says why.
    fn window(&self, viewer: &mut Viewer) -> String {
        let start = Instant::now();
        loop {
            let o = self.tool("xdotool", &["search", "--name", "glint view"]);
            let id = String::from_utf8_lossy(&o.stdout)
                .lines()
                .next()
                .map(str::to_string);
            if let Some(id) = id {
                return id;
            }
            if let Some(status) = viewer.ended() {
                panic!(
                    "glint view ended ({status}) before its window showed: {}",
                    viewer.stderr()
                );
            }
            assert!(
                start.elapsed() < Duration::from_secs(20),
                "no window after 20 s; glint view printed: {}",
                viewer.stderr()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    fn title(&self, id: &str) -> String {
        String::from_utf8_lossy(&self.tool("xdotool", &["getwindowname", id]).stdout)
            .trim()
            .to_string()
    }

    /// Waits until the title says the refinement is done, returning it.
    fn done(&self, id: &str, after: &str) -> String {
        self.done_within(id, after, Duration::from_secs(60))
            .unwrap_or_else(|t| panic!("never done: {t}"))
    }

    /// As `done`, the last title seen as the error after `limit`.
    fn done_within(&self, id: &str, after: &str, limit: Duration) -> Result<String, String> {
        let start = Instant::now();
        loop {
            let t = self.title(id);
            if t.contains("[done") && t != after {
                return Ok(t);
            }
            if start.elapsed() >= limit {
                return Err(t);
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// A left-button drag of 40 pixels across the window, as a user makes
    /// one: the window focused, the pointer in it before the button goes
    /// down.
    fn drag(&self, id: &str) {
        self.tool("xdotool", &["windowfocus", "--sync", id]);
        self.tool("xdotool", &["mousemove", "--window", id, "60", "60"]);
        std::thread::sleep(Duration::from_millis(200));
        self.tool("xdotool", &["mousedown", "1"]);
        for step in 1..=4 {
            let to = (60 + 10 * step).to_string();
            self.tool("xdotool", &["mousemove", "--window", id, &to, "70"]);
            std::thread::sleep(Duration::from_millis(30));
        }
        self.tool("xdotool", &["mouseup", "1"]);
    }

    /// Types `key` into the window as a user would (XTEST input to the
    /// focused window: winit ignores sent events).
    fn key(&self, id: &str, key: &str) {
        self.tool("xdotool", &["windowfocus", "--sync", id]);
        self.tool("xdotool", &["key", key]);
    }

    /// The window's pixels as the X server holds them.
    fn capture(&self, id: &str, to: &Path) {
        let o = self.tool("import", &["-window", id, &to.display().to_string()]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn glint(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_glint"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run glint")
}

fn levels_off(a: &Path, b: &Path, dir: &Path) -> String {
    let o = glint(
        &[
            "compare",
            &a.display().to_string(),
            &b.display().to_string(),
        ],
        dir,
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The viewer, killed if the test ends (or fails) before it does. Its
/// stderr goes to a file, so a test can say why it failed while it runs.
struct Viewer {
    child: Option<Child>,
    stderr: std::path::PathBuf,
}

impl Viewer {
    fn ended(&mut self) -> Option<std::process::ExitStatus> {
        self.child.as_mut()?.try_wait().ok().flatten()
    }

    fn stderr(&self) -> String {
        std::fs::read_to_string(&self.stderr).unwrap_or_default()
    }

    /// `finish`, and it exited 0.
    fn finish_ok(self) -> Output {
        let out = self.finish();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        out
    }

    fn finish(mut self) -> Output {
        let mut out = self
            .child
            .take()
            .expect("running")
            .wait_with_output()
            .expect("glint view ends");
        out.stderr = self.stderr().into_bytes();
        out
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        if let Some(c) = &mut self.child {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

fn view(x: &Xvfb, dir: &Path, backend: &str, extra: &[&str]) -> Viewer {
    let stderr = dir.join(format!("view-{backend}.stderr"));
    let file = std::fs::File::create(&stderr).expect("stderr file");
    let child = Command::new(env!("CARGO_BIN_EXE_glint"))
        .args([
            "view", "s.scene", "out.png", "--width", "160", "--height", "120",
        ])
        .args(["--backend", backend])
        .args(extra)
        .env("DISPLAY", &x.display)
        .env_remove("WAYLAND_DISPLAY")
        .env("GLINT_PIPELINE_CACHE", "off")
        // On the device, every Vulkan call is checked (`no_vulkan_messages`).
        .env("GLINT_VALIDATION", "1")
        .current_dir(dir)
        .stdout(Stdio::piped())
        .stderr(file)
        .spawn()
        .expect("run glint view");
    Viewer {
        child: Some(child),
        stderr,
    }
}

/// On the CPU reference and on the Vulkan device (presenting, and with
/// `--host-draws` drawn by the host): the window shows, pixel for pixel,
/// what `render` writes; the title has the samples and the
/// error; OUT is written; `Q` closes it.
#[test]
fn the_window_shows_the_image_render_writes() {
    let Some(x) = Xvfb::start() else { return };
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    std::fs::write(d.join("s.scene"), SCENE).expect("scene");
    let mut backends = vec!["cpu"];
    if gpu().is_some() {
        backends.push("gpu");
    }
    for backend in backends {
        let reference = d.join(format!("render-{backend}.png"));
        let o = glint(
            &[
                "render",
                "s.scene",
                &reference.display().to_string(),
                "--width",
                "160",
                "--height",
                "120",
                "--backend",
                backend,
            ],
            d,
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let mut child = view(&x, d, backend, &[]);
        let id = x.window(&mut child);
        let title = x.done(&id, "");
        assert!(title.contains(" spp") && title.contains("RMSE"), "{title}");
        let shot = d.join(format!("window-{backend}.png"));
        x.capture(&id, &shot);
        let cmp = levels_off(&shot, &reference, d);
        assert!(cmp.contains("over threshold  0 pixels"), "{backend}: {cmp}");
        x.key(&id, "q");
        let out = child.finish_ok();
        let cmp = levels_off(&d.join("out.png"), &reference, d);
        assert!(cmp.contains("over threshold  0 pixels"), "OUT: {cmp}");
        if backend == "gpu" {
            presented_by_the_device(&out);
        }
        let report = report(&out);
        assert!(
            !report.contains("preview"),
            "a classic scene needs no preview: {report}"
        );
    }
    if gpu().is_some() {
        // `--host-draws`: the device renders, the host draws the same pixels.
        let mut child = view(&x, d, "gpu", &["--host-draws"]);
        let id = x.window(&mut child);
        x.done(&id, "");
        let shot = d.join("window-host-draws.png");
        x.capture(&id, &shot);
        x.key(&id, "q");
        let out = child.finish_ok();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("the device presents"), "{err}");
        let cmp = levels_off(&shot, &d.join("render-gpu.png"), d);
        assert!(
            cmp.contains("over threshold  0 pixels"),
            "host draws: {cmp}"
        );
    }
}

/// The device presented the window, from a UNORM swapchain (the bytes
/// `render` writes, no sRGB encoding), and the validation layer had
/// nothing to say.
fn presented_by_the_device(out: &Output) {
    let err = String::from_utf8_lossy(&out.stderr);
    let line = err
        .lines()
        .find(|l| l.starts_with("view: the device presents the window ("))
        .unwrap_or_else(|| panic!("the host drew the window: {err}"));
    assert!(line.contains("8A8_UNORM, "), "{line}");
    assert!(
        !err.lines().any(|l| l.starts_with("vulkan ")),
        "validation messages: {err}"
    );
}

/// On the device, an adaptive refinement's passes (some cover only the
/// noisy blocks) are averaged on the device for the window: the window
/// shows what OUT, the host's mean of the same passes, holds.
#[test]
fn the_device_shows_the_mean_the_host_writes() {
    if gpu().is_none() {
        return;
    }
    let Some(x) = Xvfb::start() else { return };
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let soft = std::fs::read_to_string(repo_path("scenes/effects/soft_shadows.scene"))
        .expect("effect scene");
    std::fs::write(d.join("s.scene"), soft).expect("scene");
    let mut child = view(
        &x,
        d,
        "gpu",
        &[
            "--target-error",
            "0.0003",
            "--adaptive",
            "--time-limit",
            "20",
        ],
    );
    let id = x.window(&mut child);
    let title = x.done(&id, "");
    assert!(title.contains("[done: target error reached]"), "{title}");
    let shot = d.join("window.png");
    x.capture(&id, &shot);
    x.key(&id, "q");
    let out = child.finish_ok();
    presented_by_the_device(&out);
    let cmp = levels_off(&shot, &d.join("out.png"), d);
    assert!(cmp.contains("over threshold  0 pixels"), "{cmp}");
}

/// `glint view`'s report on exit.
fn report(out: &Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr);
    err.lines()
        .find(|l| l.starts_with("view: first image "))
        .unwrap_or_else(|| panic!("no report: {err}"))
        .to_string()
}

/// A scene heavier than `render --quick` shows the quick image first, and
/// the report tells it from the first pass.
#[test]
fn a_heavy_scene_shows_a_preview_first_and_says_so() {
    let Some(x) = Xvfb::start() else { return };
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let heavy = SCENE.replacen("amb: 0.1 0.1 0.12\n", "amb: 0.1 0.1 0.12\nspp: 4\n", 1);
    std::fs::write(d.join("s.scene"), heavy).expect("scene");
    let mut child = view(&x, d, "cpu", &["--time-limit", "1"]);
    let id = x.window(&mut child);
    let title = x.done(&id, "");
    assert!(
        title.contains(" spp") && !title.contains("preview"),
        "{title}"
    );
    x.key(&id, "q");
    let out = child.finish_ok();
    let report = report(&out);
    assert!(report.contains("(a preview; the first pass "), "{report}");
}

/// A drag turns the camera and starts the refinement over; `C` prints the
/// camera block, `S` saves the image, which `render` with that block
/// makes too.
#[test]
fn a_drag_moves_the_camera_and_s_saves_what_render_makes() {
    let Some(x) = Xvfb::start() else { return };
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    std::fs::write(d.join("s.scene"), SCENE).expect("scene");
    let mut child = view(&x, d, "cpu", &[]);
    let id = x.window(&mut child);
    let first = x.done(&id, "");
    // Once in CI (2026-12-06) the title never changed after the drag, and
    // six runs alone could not repeat it: whether X or the window lost it
    // is not known. The drag is made again, twice at most, and said so; a
    // window that takes no drag still fails.
    let mut moved = Err(String::new());
    for attempt in 1..=3 {
        x.drag(&id);
        moved = x.done_within(&id, &first, Duration::from_secs(20));
        if moved.is_ok() {
            break;
        }
        eprintln!("drag {attempt}: the title did not change in 20 s");
    }
    let moved = moved.unwrap_or_else(|t| panic!("the title never changed after three drags: {t}"));
    assert!(moved.contains("[done"), "{moved}");
    for key in ["c", "s", "q"] {
        x.key(&id, key);
        std::thread::sleep(Duration::from_millis(300));
    }
    let out = child.finish();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let block = stdout
        .lines()
        .find(|l| l.starts_with("camera eye:"))
        .unwrap_or_else(|| panic!("no camera block: {stdout}"))
        .to_string();
    assert_ne!(
        block, "camera eye: 0 0 0 look: 0 0 -1 up: 0 1 0 fov: 60",
        "the drag moved nothing"
    );
    let saved = d.join("s-view-1.png");
    assert!(
        saved.is_file() && d.join("s-view-1.exr").is_file(),
        "{stdout}"
    );
    let moved_scene = SCENE.replacen(
        "amb: 0.1 0.1 0.12\n",
        &format!("amb: 0.1 0.1 0.12\n{block}\n"),
        1,
    );
    std::fs::write(d.join("moved.scene"), &moved_scene).expect("scene");
    let o = glint(
        &[
            "render",
            "moved.scene",
            "moved.png",
            "--width",
            "160",
            "--height",
            "120",
            "--backend",
            "cpu",
        ],
        d,
    );
    assert!(
        o.status.success(),
        "{}\n{moved_scene}",
        String::from_utf8_lossy(&o.stderr)
    );
    let cmp = levels_off(&saved, &d.join("moved.png"), d);
    assert!(cmp.contains("over threshold  0 pixels"), "{cmp}");
}

#[test]
fn without_a_display_it_says_so_and_exits_2() {
    let dir = tempfile::tempdir().expect("temp dir");
    std::fs::write(dir.path().join("s.scene"), SCENE).expect("scene");
    let o = Command::new(env!("CARGO_BIN_EXE_glint"))
        .args(["view", "s.scene", "out.png"])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .current_dir(dir.path())
        .output()
        .expect("run glint");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(
        err.lines().filter(|l| l.starts_with("error:")).count(),
        1,
        "{err}"
    );
    assert!(
        err.contains("cannot open a window")
            && err.contains("DISPLAY")
            && err.contains("glint render")
            && !err.contains("invalid option"),
        "{err}"
    );
    assert!(!dir.path().join("out.png").exists());
}
