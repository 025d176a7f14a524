//! `glint bench`'s end-to-end column: the glint binary run as a user runs
//! it, `glint render SCENE out.jpg`, timed from the moment the process is
//! started to the moment it has exited with the file written. Besides the
//! render it pays for everything a render in the bench loop does not:
//! starting the process, reading and parsing the scene, building the BVH,
//! creating the device, loading the pipeline (from the disk cache, warmed
//! by one untimed run first), uploading the scene, encoding and writing
//! the JPEG.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Instant;

use super::common::Stat;
use crate::gpu::DeviceSelector;
use crate::Error;

/// What every timed process is given besides its scene and backend.
pub(crate) struct Setup<'a> {
    /// The glint binary.
    pub(crate) glint: &'a Path,
    /// Image width in pixels.
    pub(crate) width: u32,
    /// Image height in pixels.
    pub(crate) height: u32,
    /// `--device` for the GPU runs.
    pub(crate) device: Option<&'a DeviceSelector>,
    /// False: `--storage-lists` for the GPU runs.
    pub(crate) uniform_lists: bool,
    /// Where each run writes its JPEG.
    pub(crate) dir: &'a Path,
}

/// Which renderer a timed process uses, by its `glint render` flags.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Via {
    /// `--backend gpu` (and the bench's `--device`).
    Gpu,
    /// `--backend cpu --precision f32`.
    CpuF32,
    /// `--backend cpu --precision f64`.
    CpuF64,
}

impl Via {
    /// The column's label.
    pub(crate) fn label(self) -> &'static str {
        match self {
            Via::Gpu => "GPU",
            Via::CpuF32 => "f32",
            Via::CpuF64 => "f64",
        }
    }
}

/// The median of `n` runs of glint rendering `scene` to a JPEG through
/// `via`, after one untimed run; an error naming the command when a run
/// fails or writes no file.
pub(crate) fn end_to_end(setup: &Setup, scene: &Path, via: Via, n: usize) -> Result<Stat, Error> {
    let glint = setup.glint;
    let out = setup.dir.join("end-to-end.jpg");
    let mut command = Command::new(glint);
    command
        .arg("render")
        .arg(scene)
        .arg(&out)
        .args(["--width", &setup.width.to_string()])
        .args(["--height", &setup.height.to_string()])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    match via {
        Via::Gpu => {
            command.args(["--backend", "gpu"]);
            if let Some(d) = setup.device {
                command.args(["--device", &d.to_string()]);
            }
            if !setup.uniform_lists {
                command.arg("--storage-lists");
            }
        }
        Via::CpuF32 => {
            command.args(["--backend", "cpu", "--precision", "f32"]);
        }
        Via::CpuF64 => {
            command.args(["--backend", "cpu", "--precision", "f64"]);
        }
    }
    let fail = |reason: String| Error::Harness {
        harness: glint.to_path_buf(),
        scene: scene.to_path_buf(),
        reason,
    };
    let mut times = Vec::with_capacity(n);
    for run in 0..=n {
        // A file left by the last run must not pass for this one's.
        let _ = std::fs::remove_file(&out);
        let start = Instant::now();
        let done = command
            .output()
            .map_err(|e| fail(format!("cannot start it: {e}")))?;
        let took = start.elapsed();
        if !done.status.success() {
            let said = String::from_utf8_lossy(&done.stderr);
            let last = said.lines().last().unwrap_or("").trim();
            return Err(fail(format!("`glint render` {}: {last}", done.status)));
        }
        if !out.is_file() {
            return Err(fail(format!("`glint render` wrote no {}", out.display())));
        }
        if run > 0 {
            times.push(took);
        }
    }
    Ok(Stat::of(times).expect("n >= 1"))
}
