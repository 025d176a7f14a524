//! Image comparison: max and mean absolute difference (in 8-bit levels,
//! 0-255), pixels over a threshold, PSNR, NVIDIA FLIP (mean), the worst
//! pixels, and a difference image.

use std::fmt;

use image::RgbImage;

use crate::images::framebuffer::Framebuffer;
use crate::Error;

/// How many of the worst pixels a comparison keeps.
pub const WORST_PIXELS: usize = 10;

/// One pixel where two images differ.
#[derive(Clone, Debug, PartialEq)]
pub struct PixelDiff {
    /// Column, from 0 at the left.
    pub x: u32,
    /// Row, from 0 at the top.
    pub y: u32,
    /// Both values in levels (0-255; fractional for float images).
    pub a: [f64; 3],
    /// The second image's value, as `a`.
    pub b: [f64; 3],
    /// Largest channel difference.
    pub diff: f64,
}

/// How two images of one size differ.
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Largest per-channel absolute difference, in levels.
    pub max_abs: f64,
    /// Mean per-channel absolute difference, in levels.
    pub mean_abs: f64,
    /// The threshold asked for, in levels.
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

/// The mean FLIP error (perceived difference, 0-1) of two 8-bit images of one size.
pub fn flip_mean(a: &RgbImage, b: &RgbImage) -> f32 {
    if a.width() == 0 || a.height() == 0 {
        return 0.0;
    }
    let reference = nv_flip::FlipImageRgb8::with_data(a.width(), a.height(), a.as_raw());
    let test = nv_flip::FlipImageRgb8::with_data(b.width(), b.height(), b.as_raw());
    let error = nv_flip::flip(reference, test, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    nv_flip::FlipPool::from_image(&error).mean()
}

/// The inferno colour map (as FLIP's error maps use): dark purple through
/// red and orange to pale yellow, at `t` in [0, 1].
fn inferno(t: f64) -> [u8; 3] {
    const STOPS: [[f64; 3]; 5] = [
        [0.0, 0.0, 4.0],
        [87.0, 16.0, 110.0],
        [188.0, 55.0, 84.0],
        [249.0, 142.0, 9.0],
        [252.0, 255.0, 164.0],
    ];
    let x = t.clamp(0.0, 1.0) * 4.0;
    let i = (x.floor() as usize).min(3);
    let f = x - i as f64;
    [0, 1, 2].map(|c| (STOPS[i][c] + (STOPS[i + 1][c] - STOPS[i][c]) * f).round() as u8)
}

/// Pixels over the threshold are ringed only while they are this share of
/// the image or less: a few lone pixels are then found at a glance, and many
/// would only be cluttered by rings.
const RING_SHARE: f64 = 0.01;
const RING_RADIUS: i64 = 3;

impl Comparison {
    /// Differences made visible: the reference `a` faded to grey beneath,
    /// every differing pixel in the inferno colour map by its difference
    /// (from dark purple for the smallest to pale yellow at `diff_scale`),
    /// and, when few pixels are over the threshold, a ring around each.
    pub fn diff_image(&self, a: &RgbImage) -> RgbImage {
        let (w, h) = (self.width, self.height);
        let mut img = RgbImage::new(w, h);
        let per_pixel = |d: &[f64; 3]| d[0].max(d[1]).max(d[2]);
        let scale = self.diff_scale();
        for ((px, d), src) in img.pixels_mut().zip(&self.diffs).zip(a.pixels()) {
            let m = per_pixel(d);
            px.0 = if m > 0.0 {
                // The smallest difference still stands out from the grey.
                inferno(0.3 + 0.7 * (m / scale))
            } else {
                let [r, g, b] = src.0.map(f64::from);
                let luma = 0.2126 * r + 0.7152 * g + 0.0722 * b;
                [(40.0 + 0.3 * luma).round() as u8; 3]
            };
        }
        let over = self.over_threshold as f64;
        if over > 0.0 && over <= RING_SHARE * f64::from(w) * f64::from(h) {
            let ring = inferno(1.0);
            for (i, d) in self.diffs.iter().enumerate() {
                if per_pixel(d) <= self.threshold {
                    continue;
                }
                let (x, y) = ((i as u32 % w) as i64, (i as u32 / w) as i64);
                for dy in -RING_RADIUS..=RING_RADIUS {
                    for dx in -RING_RADIUS..=RING_RADIUS {
                        if dx.abs().max(dy.abs()) != RING_RADIUS {
                            continue;
                        }
                        let (u, v) = (x + dx, y + dy);
                        if u < 0 || v < 0 || u >= i64::from(w) || v >= i64::from(h) {
                            continue;
                        }
                        let j = v as usize * w as usize + u as usize;
                        if per_pixel(&self.diffs[j]) == 0.0 {
                            img.put_pixel(u as u32, v as u32, image::Rgb(ring));
                        }
                    }
                }
            }
        }
        img
    }

    /// The difference (levels) shown at the top of the colour map: the
    /// largest, or the threshold when that is larger.
    pub fn diff_scale(&self) -> f64 {
        self.max_abs.max(self.threshold).max(1e-9)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Equal pixels show the reference as grey, differing ones are coloured
    /// by their difference (larger: brighter), and a lone pixel over the
    /// threshold is ringed so it is seen at 1:1.
    #[test]
    fn diff_image_fades_the_reference_and_colours_differences() {
        let mut a = RgbImage::from_pixel(40, 30, image::Rgb([200, 100, 50]));
        a.put_pixel(0, 0, image::Rgb([0, 0, 0]));
        let mut b = a.clone();
        b.put_pixel(10, 10, image::Rgb([200, 100, 52])); // 2 levels: over 1
        b.put_pixel(30, 20, image::Rgb([201, 100, 50])); // 1 level: not over
        let c = compare_images(&a, &b, 1.0).expect("same size");
        let img = c.diff_image(&a);
        let grey = |p: &image::Rgb<u8>| p.0[0] == p.0[1] && p.0[1] == p.0[2];
        // The reference, faded: grey, darker where it is darker.
        assert!(grey(img.get_pixel(5, 25)) && grey(img.get_pixel(0, 0)));
        assert!(img.get_pixel(0, 0).0[0] < img.get_pixel(5, 25).0[0]);
        assert!(img.get_pixel(5, 25).0[0] < 128, "faded");
        // Differences in colour, the larger brighter.
        let big = img.get_pixel(10, 10).0;
        let small = img.get_pixel(30, 20).0;
        assert!(!grey(img.get_pixel(10, 10)) && !grey(img.get_pixel(30, 20)));
        let sum = |p: [u8; 3]| p.iter().map(|&v| u32::from(v)).sum::<u32>();
        assert!(sum(big) > sum(small), "{big:?} {small:?}");
        // A ring around the pixel over the threshold, none around the other.
        assert_eq!(img.get_pixel(13, 10).0, inferno(1.0));
        assert_eq!(img.get_pixel(7, 7).0, inferno(1.0));
        assert!(grey(img.get_pixel(33, 20)));
        assert!(
            grey(img.get_pixel(12, 10)),
            "inside the ring: the reference"
        );
    }
}
