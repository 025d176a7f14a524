//! How a device's image is judged against the CPU reference, and what is
//! written when it fails: shared by the suite and `image_test`.

use std::path::PathBuf;

use super::suite::Tolerance;
use crate::images::compare::Comparison;
use crate::images::framebuffer::{write_image, Framebuffer};
use crate::Error;

/// What is wrong with a device's image against the CPU twin and truth, by
/// `t` (nothing: it passes), and how many pixels may be off.
pub(super) fn judge(
    t: &Tolerance,
    pixels: usize,
    against_twin: &Comparison,
    against_truth: &Comparison,
) -> (Vec<String>, usize) {
    let allowed = ((pixels as f64 * t.f32_fraction) as usize).max(t.f32_min_pixels);
    let mut why = Vec::new();
    if against_twin.over_threshold > allowed {
        why.push(format!(
            "{} pixels more than 1 level off the CPU f32 twin (allowed {allowed}; worst {:.0} levels at {})",
            against_twin.over_threshold,
            against_twin.max_abs,
            against_twin
                .worst
                .first()
                .map_or(String::new(), |w| format!("{},{}", w.x, w.y))
        ));
    }
    if against_twin.flip_mean > t.f32_flip {
        why.push(format!(
            "FLIP {:.5} against the f32 twin (allowed {})",
            against_twin.flip_mean, t.f32_flip
        ));
    }
    if let Some(limit) = t.f64_flip {
        if against_truth.flip_mean > limit {
            why.push(format!(
                "FLIP {:.4} against the f64 reference (allowed {limit})",
                against_truth.flip_mean
            ));
        }
    }
    (why, allowed)
}

/// Writes a failed image beside the CPU twin's and their difference as a
/// heat map (`NAME.device.png`, `NAME.cpu.png`, `NAME.diff.png`).
pub(super) fn write_failure(
    dir: &std::path::Path,
    name: &str,
    image: &Framebuffer,
    twin: &Framebuffer,
    cmp: &Comparison,
) -> Result<Vec<PathBuf>, Error> {
    std::fs::create_dir_all(dir).map_err(|error| Error::WriteFile {
        path: dir.to_path_buf(),
        error,
    })?;
    let base = dir.join(name);
    let twin8 = twin.to_rgb8();
    let paths = ["device.png", "cpu.png", "diff.png"].map(|e| base.with_extension(e));
    write_image(&image.to_rgb8(), &paths[0], 95)?;
    write_image(&twin8, &paths[1], 95)?;
    write_image(&cmp.diff_image(&twin8), &paths[2], 95)?;
    Ok(paths.to_vec())
}
