//! Image comparison: max and mean absolute difference (in 8-bit levels,
//! 0-255), pixels over a threshold, PSNR, NVIDIA FLIP (mean), the worst
//! pixels, and a difference image.

use std::fmt;

use image::RgbImage;

use crate::framebuffer::Framebuffer;
use crate::Error;

/// How many of the worst pixels a comparison keeps.
pub const WORST_PIXELS: usize = 10;

#[derive(Clone, Debug, PartialEq)]
pub struct PixelDiff {
    pub x: u32,
    pub y: u32,
    /// Both values in levels (0-255; fractional for float images).
    pub a: [f64; 3],
    pub b: [f64; 3],
    /// Largest channel difference.
    pub diff: f64,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    pub width: u32,
    pub height: u32,
    /// Largest per-channel absolute difference, in levels.
    pub max_abs: f64,
    /// Mean per-channel absolute difference, in levels.
    pub mean_abs: f64,
    pub threshold: f64,
    /// Pixels whose largest channel difference exceeds `threshold`.
    pub over_threshold: usize,
    /// Root mean square of the per-channel differences on linear values
    /// (0-1, not levels).
    pub rmse: f64,
    /// Peak signal-to-noise ratio in dB (infinite for identical images).
    pub psnr: f64,
    /// Mean NVIDIA FLIP error (0 = identical, 1 = maximal), LDR, default viewing conditions.
    pub flip_mean: f32,
    /// The worst pixels, worst first.
    pub worst: Vec<PixelDiff>,
    diffs: Vec<[f64; 3]>,
}

fn levels_of_rgb8(img: &RgbImage) -> Vec<[f64; 3]> {
    img.pixels().map(|p| p.0.map(f64::from)).collect()
}

fn levels_of_framebuffer(fb: &Framebuffer) -> Vec<[f64; 3]> {
    fb.pixels
        .iter()
        .map(|p| p.map(|c| f64::from(c.clamp(0.0, 1.0)) * 255.0))
        .collect()
}

/// Compares two 8-bit images; `threshold` is in levels.
pub fn compare_images(a: &RgbImage, b: &RgbImage, threshold: f64) -> Result<Comparison, Error> {
    check_size(a.width(), a.height(), b.width(), b.height())?;
    let mut c = compare_levels(
        a.width(),
        a.height(),
        &levels_of_rgb8(a),
        &levels_of_rgb8(b),
        threshold,
    );
    c.flip_mean = flip_mean(a, b);
    Ok(c)
}

/// Compares two float renders before 8-bit rounding (values clamped to
/// [0, 1]); `threshold` is in levels. FLIP is computed on their 8-bit
/// conversions.
pub fn compare_framebuffers(
    a: &Framebuffer,
    b: &Framebuffer,
    threshold: f64,
) -> Result<Comparison, Error> {
    check_size(a.width, a.height, b.width, b.height)?;
    let mut c = compare_levels(
        a.width,
        a.height,
        &levels_of_framebuffer(a),
        &levels_of_framebuffer(b),
        threshold,
    );
    c.flip_mean = flip_mean(&a.to_rgb8(), &b.to_rgb8());
    Ok(c)
}

fn check_size(aw: u32, ah: u32, bw: u32, bh: u32) -> Result<(), Error> {
    if (aw, ah) != (bw, bh) {
        return Err(Error::SizeMismatch(aw, ah, bw, bh));
    }
    Ok(())
}

fn compare_levels(
    width: u32,
    height: u32,
    a: &[[f64; 3]],
    b: &[[f64; 3]],
    threshold: f64,
) -> Comparison {
    let diffs: Vec<[f64; 3]> = a
        .iter()
        .zip(b)
        .map(|(p, q)| [0, 1, 2].map(|i| (p[i] - q[i]).abs()))
        .collect();
    let per_pixel = |d: &[f64; 3]| d[0].max(d[1]).max(d[2]);
    let channels = (diffs.len() * 3).max(1) as f64;
    let sum: f64 = diffs.iter().flatten().sum();
    let sq: f64 = diffs.iter().flatten().map(|d| d * d).sum();
    let mse = sq / channels;
    let mut order: Vec<usize> = (0..diffs.len())
        .filter(|&i| per_pixel(&diffs[i]) > 0.0)
        .collect();
    order.sort_by(|&i, &j| per_pixel(&diffs[j]).total_cmp(&per_pixel(&diffs[i])));
    let worst = order
        .iter()
        .take(WORST_PIXELS)
        .map(|&i| PixelDiff {
            x: i as u32 % width,
            y: i as u32 / width,
            a: a[i],
            b: b[i],
            diff: per_pixel(&diffs[i]),
        })
        .collect();
    Comparison {
        width,
        height,
        max_abs: diffs.iter().map(per_pixel).fold(0.0, f64::max),
        mean_abs: sum / channels,
        threshold,
        over_threshold: diffs.iter().filter(|d| per_pixel(d) > threshold).count(),
        rmse: mse.sqrt() / 255.0,
        psnr: if mse == 0.0 {
            f64::INFINITY
        } else {
            10.0 * (255.0 * 255.0 / mse).log10()
        },
        flip_mean: 0.0,
        worst,
        diffs,
    }
}

pub fn flip_mean(a: &RgbImage, b: &RgbImage) -> f32 {
    if a.width() == 0 || a.height() == 0 {
        return 0.0;
    }
    let reference = nv_flip::FlipImageRgb8::with_data(a.width(), a.height(), a.as_raw());
    let test = nv_flip::FlipImageRgb8::with_data(b.width(), b.height(), b.as_raw());
    let error = nv_flip::flip(reference, test, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    nv_flip::FlipPool::from_image(&error).mean()
}

impl Comparison {
    /// Differences made visible: black where equal, brighter with the
    /// difference (x16), pure red where a pixel exceeds the threshold.
    pub fn diff_image(&self) -> RgbImage {
        let mut img = RgbImage::new(self.width, self.height);
        for (px, d) in img.pixels_mut().zip(&self.diffs) {
            let m = d[0].max(d[1]).max(d[2]);
            px.0 = if m > self.threshold {
                [255, 0, 0]
            } else {
                d.map(|c| (c * 16.0).min(255.0) as u8)
            };
        }
        img
    }
}

impl fmt::Display for Comparison {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "size            {}x{}", self.width, self.height)?;
        writeln!(f, "max abs diff    {:.3} levels (0-255)", self.max_abs)?;
        writeln!(f, "mean abs diff   {:.5} levels", self.mean_abs)?;
        writeln!(
            f,
            "over threshold  {} pixels (> {} levels)",
            self.over_threshold, self.threshold
        )?;
        writeln!(f, "RMSE            {:.6} (linear, 0-1)", self.rmse)?;
        writeln!(f, "PSNR            {:.2} dB", self.psnr)?;
        write!(f, "FLIP mean       {:.6}", self.flip_mean)?;
        if !self.worst.is_empty() {
            write!(f, "\nworst pixels (x, y: a -> b, max channel diff):")?;
            for p in &self.worst {
                let show = |v: [f64; 3]| format!("({:.1}, {:.1}, {:.1})", v[0], v[1], v[2]);
                write!(
                    f,
                    "\n  {:>4}, {:>4}: {} -> {}  {:.2}",
                    p.x,
                    p.y,
                    show(p.a),
                    show(p.b),
                    p.diff
                )?;
            }
        }
        Ok(())
    }
}
