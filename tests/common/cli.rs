//! Running the `glint` binary from tests, shared by the CLI test files.

use std::path::Path;
use std::process::{Command, Output};

/// Runs glint in `dir`, the scene cache off: a test's scene is loaded and
/// built by the run itself, whatever ran before it (`glint_env` turns
/// the cache on).
pub fn glint(args: &[&str], dir: &Path) -> Output {
    glint_env(args, dir, &[("GLINT_SCENE_CACHE", "off")])
}

/// As `glint`, with `env` set.
pub fn glint_env(args: &[&str], dir: &Path, env: &[(&str, &str)]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_glint"))
        .args(args)
        .current_dir(dir)
        .envs(env.iter().copied())
        .output()
        .expect("run glint")
}

/// As `glint`, with the Vulkan loader pointed at no driver at all.
pub fn glint_without_vulkan(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_glint"))
        .args(args)
        .current_dir(dir)
        .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
        .env("VK_DRIVER_FILES", "/nonexistent/icd.json")
        .output()
        .expect("run glint")
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

pub fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

pub fn showcase() -> String {
    super::repo_path("scenes/showcase.scene")
        .display()
        .to_string()
}

pub const SMALL: [&str; 4] = ["--width", "40", "--height", "30"];

pub fn glint_with_stdin(args: &[&str], dir: &Path, input: &[u8]) -> Output {
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

/// The rays line of `--stats`: all, primary, reflected and shadow rays.
pub fn stats_rays(out: &str) -> [u64; 4] {
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
