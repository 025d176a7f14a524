//! What every benchmark shares: the scenes it runs by default, medians,
//! names and the options it starts from.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use crate::gpu::{DeviceSelector, GpuRenderOptions};
use crate::render::RenderOptions;
use crate::Error;

/// Median and spread of repeated timings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stat {
    /// The median.
    pub median: Duration,
    /// The fastest.
    pub min: Duration,
    /// The slowest.
    pub max: Duration,
}

/// "median (min-max)" in milliseconds.
impl std::fmt::Display for Stat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        write!(
            f,
            "{:.1} ({:.1}-{:.1})",
            ms(self.median),
            ms(self.min),
            ms(self.max)
        )
    }
}

impl Stat {
    /// The statistics of `samples`; None when there are none.
    pub fn of(mut samples: Vec<Duration>) -> Option<Stat> {
        if samples.is_empty() {
            return None;
        }
        samples.sort();
        let n = samples.len();
        let median = if n % 2 == 1 {
            samples[n / 2]
        } else {
            (samples[n / 2 - 1] + samples[n / 2]) / 2
        };
        Some(Stat {
            median,
            min: samples[0],
            max: samples[n - 1],
        })
    }
}

/// Where the course's classic scenes live, relative to the repository root.
pub const CLASSIC_DIR: &str = "../shared/scenes/classic";
/// The classic scenes' file stems, in the order reports list them.
pub const CLASSIC_SCENES: [&str; 5] = ["test1", "test2", "spheres", "table", "SIGGRAPH"];

/// The default scene set, relative to the repository root: the classic scenes
/// (when `CLASSIC_DIR` exists; otherwise `note` is told) and every `*.scene`
/// directly in `scenes/`, sorted.
pub fn default_scenes(note: &mut dyn FnMut(&str)) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let classic = std::path::Path::new(CLASSIC_DIR);
    if classic.is_dir() {
        out.extend(
            CLASSIC_SCENES
                .iter()
                .map(|n| classic.join(format!("{n}.scene"))),
        );
    } else {
        note(&format!("{CLASSIC_DIR} not found: classic scenes skipped"));
    }
    out.extend(scene_files("scenes"));
    out
}

/// What a timing benchmark's renderers share: the image size, the device,
/// and whether a CPU device may read the uniform list copies
/// (`GpuRenderOptions::uniform_lists`).
pub(crate) fn base_options(
    width: u32,
    height: u32,
    device: Option<DeviceSelector>,
    uniform_lists: bool,
) -> RenderOptions {
    RenderOptions {
        width,
        height,
        device,
        gpu: GpuRenderOptions {
            uniform_lists,
            ..GpuRenderOptions::default()
        },
        ..RenderOptions::default()
    }
}

/// A scene's name in reports: its file's stem (the whole path if none).
pub(crate) fn scene_name(path: &std::path::Path) -> String {
    path.file_stem().map_or_else(
        || path.display().to_string(),
        |s| s.to_string_lossy().into_owned(),
    )
}

/// The `*.scene` files directly in `dir`, sorted; none if it is missing.
pub(crate) fn scene_files(dir: &str) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "scene"))
        .collect();
    files.sort();
    files
}

pub(crate) fn repeat(
    n: usize,
    mut f: impl FnMut() -> Result<(), Error>,
) -> Result<Option<Stat>, Error> {
    let mut samples = Vec::with_capacity(n);
    for _ in 0..n {
        let start = Instant::now();
        f()?;
        samples.push(start.elapsed());
    }
    Ok(Stat::of(samples))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_and_even_counts() {
        let d = Duration::from_millis;
        assert_eq!(Stat::of(vec![d(3), d(1), d(2)]).unwrap().median, d(2));
        assert_eq!(
            Stat::of(vec![d(4), d(1), d(2), d(3)]).unwrap().median,
            Duration::from_micros(2500)
        );
        assert!(Stat::of(vec![]).is_none());
    }
}
