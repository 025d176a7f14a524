//! Renders in sample passes that stop at an estimated error or a time
//! budget (`glint render --target-error E`, `--time-limit S`).
//!
//! Pass k renders the scene's own samples per pixel with seed `seed + k`,
//! so the passes are independent draws of the same image and their mean
//! converges to what the scene's sampling integrates (pixel area, shutter,
//! area lights). The passes go alternately into two halves, A (even) and
//! B (odd). With n_a and n_b passes and per-pass variance v at a value,
//! Var(A - B) = v / n_a + v / n_b while the mean of all passes has variance
//! v / (n_a + n_b), so
//!
//!   RMSE(mean) ~ sqrt(mean((A - B)^2) * n_a n_b / (n_a + n_b)^2),
//!
//! over every pixel and channel: an estimate of the error against the
//! converged image that needs no reference. A scene whose passes agree
//! exactly (nothing random in it) has estimate 0 after two passes.

use std::time::Duration;

use super::output::RenderOutput;
use crate::images::framebuffer::Framebuffer;
use crate::scene::Effects;

/// The fewest passes whose estimate a target trusts: with one pass per
/// half the estimate rests on a single difference image, and where the
/// noise lives in few pixels (a penumbra) that is itself noisy.
pub const MIN_PASSES_FOR_TARGET: u32 = 4;

/// Passes over the whole image before adaptive passes choose blocks: two,
/// one per half, give each 16x16 block a difference image of 768 values,
/// enough for its own estimate; waiting for `MIN_PASSES_FOR_TARGET` would
/// spend two more passes on blocks that need none (measured on
/// soft_shadows at 320x240, target 0.0005: 5.2 samples per pixel on
/// average after 4 first passes, 3.9 after 2, the true error the same).
pub const ADAPTIVE_FIRST_PASSES: u32 = 2;

/// When a progressive render stops; at least one of the two is set.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StopAt {
    /// Stop once the estimated RMSE (linear values, 0-1) is at most this.
    pub target_rmse: Option<f64>,
    /// Stop before a pass would end after this much time.
    pub time_limit: Option<Duration>,
    /// After the first `MIN_PASSES_FOR_TARGET` passes, render only the
    /// blocks (`BLOCK_EDGE` square) whose own estimate is above the target
    /// (needs `target_rmse`).
    pub adaptive: bool,
}

/// Why a progressive render stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stopped {
    /// The estimate reached the target.
    Target,
    /// Two passes came out identical: nothing in the scene is random, so
    /// more passes would not change the image.
    Noiseless,
    /// The next pass would have ended after the time limit.
    TimeLimit,
    /// Another pass would exceed `Effects::MAX_SPP` samples per pixel.
    MaxSamples,
    /// Whoever watched the passes ended it (`glint view`'s camera moved).
    Cancelled,
}

/// Where a progressive render stands after a pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassReport {
    /// Passes so far.
    pub passes: u32,
    /// The most samples any pixel has (all have as many without
    /// `adaptive`).
    pub samples_per_pixel: u32,
    /// Samples per pixel on average over the image.
    pub mean_samples: f64,
    /// Blocks the next pass renders, of how many (all without `adaptive`).
    pub active_blocks: [usize; 2],
    /// Since the render began (setup and BVH included).
    pub elapsed: Duration,
    /// None until there are two passes.
    pub estimated_rmse: Option<f64>,
}

/// A progressive render's result.
pub struct Progressive {
    /// The mean of every pass; timings summed over the passes.
    pub output: RenderOutput,
    /// The last pass's report.
    pub report: PassReport,
    /// Why the passes stopped.
    pub stopped: Stopped,
    /// Every pass's report, in order.
    pub history: Vec<PassReport>,
}

/// What adaptive passes aim at, as a fraction of the target. A block sits
/// out once its own estimate is low, and a noisy estimate is low by chance
/// as often as not, so the blocks that sit out are, on average, noisier
/// than their estimates say: measured, the true error of an adaptive
/// render ran up to 8% above its estimate (motion_blur, 96x64).
pub const ADAPTIVE_AIM: f64 = 0.9;

impl StopAt {
    /// The estimate to stop at: the target, or `ADAPTIVE_AIM` of it.
    pub fn aim(&self) -> Option<f64> {
        let factor = if self.adaptive { ADAPTIVE_AIM } else { 1.0 };
        self.target_rmse.map(|t| t * factor)
    }

    /// Whether to stop after the passes in `history` (each of `spp`
    /// samples), and why.
    pub fn verdict(&self, history: &[PassReport], spp: u32) -> Option<Stopped> {
        let last = history.last()?;
        if last.estimated_rmse == Some(0.0) {
            return Some(Stopped::Noiseless);
        }
        if let (Some(target), Some(estimate)) = (self.aim(), last.estimated_rmse) {
            if estimate <= target && last.passes >= MIN_PASSES_FOR_TARGET {
                return Some(Stopped::Target);
            }
        }
        if u64::from(last.samples_per_pixel) + u64::from(spp) > u64::from(Effects::MAX_SPP) {
            return Some(Stopped::MaxSamples);
        }
        if let Some(limit) = self.time_limit {
            // The next pass is predicted to take as long as the last one.
            let previous = history
                .len()
                .checked_sub(2)
                .map_or(Duration::ZERO, |i| history[i].elapsed);
            let pass = last.elapsed.saturating_sub(previous);
            if last.elapsed + pass > limit {
                return Some(Stopped::TimeLimit);
            }
        }
        None
    }
}

/// Edge in pixels of the squares adaptive passes choose among: a multiple
/// of the shader's workgroup, small enough to follow a penumbra, large
/// enough (768 values) for a steady estimate of its own.
pub const BLOCK_EDGE: u32 = 16;

/// The image cut into `BLOCK_EDGE` squares, and which of them the next pass
/// renders.
#[derive(Clone, Debug, PartialEq)]
pub struct Blocks {
    width: u32,
    height: u32,
    cols: u32,
    /// Per block, row by row: whether the next pass renders it.
    pub active: Vec<bool>,
}

impl Blocks {
    /// Every block of a `width` x `height` image, all active.
    pub fn all(width: u32, height: u32) -> Blocks {
        let cols = width.div_ceil(BLOCK_EDGE);
        let rows = height.div_ceil(BLOCK_EDGE);
        Blocks {
            width,
            height,
            cols,
            active: vec![true; cols as usize * rows as usize],
        }
    }

    fn index(&self, x: u32, y: u32) -> usize {
        ((y / BLOCK_EDGE) * self.cols + x / BLOCK_EDGE) as usize
    }

    /// Whether pixel (x, y)'s block is active.
    pub fn is_active(&self, x: u32, y: u32) -> bool {
        self.active[self.index(x, y)]
    }

    /// Whether every block is active.
    pub fn all_active(&self) -> bool {
        self.active.iter().all(|&a| a)
    }

    /// Pixels per block.
    pub fn weights(&self) -> Vec<f64> {
        let mut w = vec![0.0; self.active.len()];
        for y in 0..self.height {
            for x in 0..self.width {
                w[self.index(x, y)] += 1.0;
            }
        }
        w
    }

    /// How many blocks are active.
    pub fn active_count(&self) -> usize {
        self.active.iter().filter(|&&a| a).count()
    }

    /// The active blocks as (x, y, width, height), clipped to the image; a
    /// run of them along a row is one rectangle (fewer, larger dispatches).
    pub fn rects(&self) -> Vec<[u32; 4]> {
        let mut out: Vec<[u32; 4]> = Vec::new();
        for (i, &on) in self.active.iter().enumerate() {
            if !on {
                continue;
            }
            let (col, row) = (i as u32 % self.cols, i as u32 / self.cols);
            let (x, y) = (col * BLOCK_EDGE, row * BLOCK_EDGE);
            let (w, h) = (
                BLOCK_EDGE.min(self.width - x),
                BLOCK_EDGE.min(self.height - y),
            );
            match out.last_mut() {
                Some(r) if col > 0 && self.active[i - 1] && r[1] == y && r[0] + r[2] == x => {
                    r[2] += w;
                }
                _ => out.push([x, y, w, h]),
            }
        }
        out
    }
}

/// The running sums of the two halves, per pixel (pixels of blocks that
/// sat out passes have fewer).
pub struct Accumulator {
    width: u32,
    height: u32,
    halves: [Vec<[f64; 3]>; 2],
    counts: Vec<[u32; 2]>,
    passes: u32,
}

impl Accumulator {
    /// No passes yet, for a `width` x `height` image.
    pub fn new(width: u32, height: u32) -> Accumulator {
        let n = width as usize * height as usize;
        Accumulator {
            width,
            height,
            halves: [vec![[0.0; 3]; n], vec![[0.0; 3]; n]],
            counts: vec![[0; 2]; n],
            passes: 0,
        }
    }

    /// Passes rendered (over all blocks or some).
    pub fn passes(&self) -> u32 {
        self.passes
    }

    /// The most passes any pixel has.
    pub fn max_passes(&self) -> u32 {
        self.counts.iter().map(|c| c[0] + c[1]).max().unwrap_or(0)
    }

    /// Passes per pixel on average.
    pub fn mean_passes(&self) -> f64 {
        let total: u64 = self.counts.iter().map(|c| u64::from(c[0] + c[1])).sum();
        total as f64 / self.counts.len().max(1) as f64
    }

    /// Adds the next pass over every pixel.
    pub fn add(&mut self, pass: &Framebuffer) {
        self.add_where(pass, &|_, _| true);
    }

    /// Adds the next pass's pixels that `rendered` says it holds; each
    /// pixel's passes alternate between its halves A and B.
    pub fn add_where(&mut self, pass: &Framebuffer, rendered: &dyn Fn(u32, u32) -> bool) {
        assert_eq!(
            (pass.width, pass.height),
            (self.width, self.height),
            "pass of another size"
        );
        for (i, p) in pass.pixels.iter().enumerate() {
            let (x, y) = (i as u32 % self.width, i as u32 / self.width);
            if !rendered(x, y) {
                continue;
            }
            let c = &mut self.counts[i];
            let half = ((c[0] + c[1]) % 2) as usize;
            for (sum, v) in self.halves[half][i].iter_mut().zip(p) {
                *sum += f64::from(*v);
            }
            c[half] += 1;
        }
        self.passes += 1;
    }

    /// Pixel i's squared error estimate, summed over its channels; None
    /// before both its halves have a pass.
    fn pixel_sq(&self, i: usize) -> Option<f64> {
        let [na, nb] = self.counts[i].map(f64::from);
        if na == 0.0 || nb == 0.0 {
            return None;
        }
        let (a, b) = (&self.halves[0][i], &self.halves[1][i]);
        let d: f64 = (0..3).map(|c| (a[c] / na - b[c] / nb).powi(2)).sum();
        Some(d * na * nb / ((na + nb) * (na + nb)))
    }

    /// The estimated RMSE of `mean()` against the converged image; None
    /// before every pixel has a pass in both halves.
    pub fn estimated_rmse(&self) -> Option<f64> {
        let mut sq = 0.0;
        for i in 0..self.counts.len() {
            sq += self.pixel_sq(i)?;
        }
        Some((sq / (self.counts.len() * 3).max(1) as f64).sqrt())
    }

    /// Which blocks the next adaptive pass renders to reach `target` in the
    /// least time. With `sigma_b` a block's noise per pass (its estimate
    /// times the square root of its passes) and `w_b` its pixels, the
    /// passes that reach `sum_b w_b sigma_b^2 / n_b = W target^2` at the
    /// least total `sum_b w_b n_b` are `n_b = s sigma_b` for a common `s`
    /// (Lagrange: each block's last pass buys the same error per sample),
    /// and a block keeps the passes it has: `n_b = max(passes_b, s sigma_b)`.
    /// The blocks below their `n_b` render. Equalising the blocks' errors
    /// instead (water-filling) spends samples as sigma^2, not sigma, and
    /// takes as many as a uniform render wherever every block is noisy.
    /// Recomputed every pass from the sharper estimates. None when the
    /// estimate already meets the target.
    pub fn adaptive_blocks(&self, blocks: &Blocks, target: f64) -> Option<Vec<bool>> {
        let estimates = self.block_rmse(blocks);
        let passes = self.block_passes(blocks);
        let weights = blocks.weights();
        let total: f64 = weights.iter().sum();
        let budget = total * target * target;
        let sigma: Vec<f64> = estimates
            .iter()
            .zip(&passes)
            .map(|(e, n)| e * n.sqrt())
            .collect();
        let error_at = |s: f64| -> f64 {
            (0..sigma.len())
                .map(|b| {
                    let n = passes[b].max(s * sigma[b]).max(1.0);
                    weights[b] * sigma[b] * sigma[b] / n
                })
                .sum()
        };
        if !error_at(0.0).is_finite() {
            // A block without an estimate yet: every block goes on.
            return Some(vec![true; estimates.len()]);
        }
        if error_at(0.0) <= budget {
            return None;
        }
        // error_at falls as s grows; bracket the budget, then bisect.
        let mut hi = 1.0;
        while error_at(hi) > budget && hi < 1e30 {
            hi *= 2.0;
        }
        let mut lo = 0.0;
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if error_at(mid) > budget {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let active: Vec<bool> = (0..sigma.len())
            .map(|b| hi * sigma[b] > passes[b])
            .collect();
        active.iter().any(|&a| a).then_some(active)
    }

    /// Per block, the passes its pixels have.
    fn block_passes(&self, blocks: &Blocks) -> Vec<f64> {
        let mut n = vec![0.0; blocks.active.len()];
        for i in 0..self.counts.len() {
            let (x, y) = (i as u32 % self.width, i as u32 / self.width);
            let c = self.counts[i];
            n[blocks.index(x, y)] = f64::from(c[0] + c[1]);
        }
        n
    }

    /// Per block of `blocks`, the estimated RMSE of its pixels (infinite
    /// where some pixel has no estimate yet).
    pub fn block_rmse(&self, blocks: &Blocks) -> Vec<f64> {
        let mut sums = vec![(0.0, 0usize); blocks.active.len()];
        for i in 0..self.counts.len() {
            let (x, y) = (i as u32 % self.width, i as u32 / self.width);
            let s = &mut sums[blocks.index(x, y)];
            s.0 += self.pixel_sq(i).unwrap_or(f64::INFINITY);
            s.1 += 3;
        }
        sums.into_iter()
            .map(|(sq, n)| (sq / n.max(1) as f64).sqrt())
            .collect()
    }

    /// The mean of every pixel's passes so far.
    pub fn mean(&self) -> Framebuffer {
        let pixels = (0..self.counts.len())
            .map(|i| {
                let n = f64::from((self.counts[i][0] + self.counts[i][1]).max(1));
                let (a, b) = (&self.halves[0][i], &self.halves[1][i]);
                [0, 1, 2].map(|c| ((a[c] + b[c]) / n) as f32)
            })
            .collect();
        Framebuffer {
            width: self.width,
            height: self.height,
            pixels,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(passes: u32, ms: u64, estimate: Option<f64>) -> PassReport {
        PassReport {
            passes,
            samples_per_pixel: passes * 4,
            mean_samples: f64::from(passes * 4),
            active_blocks: [1, 1],
            elapsed: Duration::from_millis(ms),
            estimated_rmse: estimate,
        }
    }

    /// Passes of known noise: the estimate follows sigma / sqrt(passes).
    #[test]
    fn estimate_tracks_the_error_of_the_mean() {
        let (w, h) = (64, 64);
        let sigma = 0.1;
        let mut acc = Accumulator::new(w, h);
        let mut state = 12345u32;
        let mut noise = || {
            // A sum of uniforms: mean 0, standard deviation sigma.
            let mut s = 0.0;
            for _ in 0..12 {
                state = crate::hash::hash_u32(state);
                s += f64::from(state) / f64::from(u32::MAX) - 0.5;
            }
            (0.5 + sigma * s) as f32
        };
        for passes in 1..=16u32 {
            let fb = Framebuffer {
                width: w,
                height: h,
                pixels: (0..w * h).map(|_| [noise(), noise(), noise()]).collect(),
            };
            acc.add(&fb);
            let estimate = acc.estimated_rmse();
            if passes == 1 {
                assert_eq!(estimate, None);
                continue;
            }
            let expected = sigma / f64::from(passes).sqrt();
            let e = estimate.expect("two halves");
            assert!(
                (e / expected - 1.0).abs() < 0.1,
                "{passes} passes: estimate {e}, expected {expected}"
            );
        }
        let truth: f64 = acc
            .mean()
            .pixels
            .iter()
            .flatten()
            .map(|&v| (f64::from(v) - 0.5).powi(2))
            .sum::<f64>()
            / f64::from(w * h * 3);
        let e = acc.estimated_rmse().expect("estimate");
        assert!(
            (truth.sqrt() / e - 1.0).abs() < 0.1,
            "{} vs {e}",
            truth.sqrt()
        );
    }

    #[test]
    fn identical_passes_estimate_zero() {
        let fb = Framebuffer {
            width: 2,
            height: 1,
            pixels: vec![[0.25, 0.5, 1.0], [0.0, 0.1, 0.2]],
        };
        let mut acc = Accumulator::new(2, 1);
        acc.add(&fb);
        acc.add(&fb);
        assert_eq!(acc.estimated_rmse(), Some(0.0));
        assert_eq!(acc.mean(), fb);
        let stop = StopAt {
            target_rmse: None,
            time_limit: Some(Duration::from_secs(100)),
            adaptive: false,
        };
        let h = [report(1, 10, None), report(2, 20, Some(0.0))];
        assert_eq!(stop.verdict(&h, 1), Some(Stopped::Noiseless));
    }

    /// Blocks cover the image, clipped at its edges; a pass over some of
    /// them adds to those pixels only, and their estimate is per block.
    #[test]
    fn blocks_split_the_image_and_passes_follow_them() {
        let (w, h) = (40, 20);
        let mut blocks = Blocks::all(w, h);
        assert_eq!(blocks.active.len(), 3 * 2);
        // Rows of blocks are one rectangle each, clipped to the image.
        assert_eq!(blocks.rects(), [[0, 0, 40, 16], [0, 16, 40, 4]]);
        blocks.active = vec![true, false, true, false, true, true];
        assert_eq!(
            blocks.rects(),
            [[0, 0, 16, 16], [32, 0, 8, 16], [16, 16, 24, 4]]
        );
        let flat = |v: f32| Framebuffer {
            width: w,
            height: h,
            pixels: vec![[v; 3]; (w * h) as usize],
        };
        let mut acc = Accumulator::new(w, h);
        acc.add(&flat(0.4));
        acc.add(&flat(0.6));
        // Only block 0 goes on: its pixels get 0.5 twice more.
        blocks.active = vec![true, false, false, false, false, false];
        for _ in 0..2 {
            acc.add_where(&flat(0.5), &|x, y| blocks.is_active(x, y));
        }
        assert_eq!(acc.passes(), 4);
        assert_eq!(acc.max_passes(), 4);
        assert!((acc.mean_passes() - (2.0 + 2.0 * 256.0 / 800.0)).abs() < 1e-12);
        let mean = acc.mean();
        assert!((mean.pixels[0][0] - 0.5).abs() < 1e-6);
        assert!((mean.pixels[39][0] - 0.5).abs() < 1e-6);
        let per_block = acc.block_rmse(&Blocks::all(w, h));
        // Halves 0.45 and 0.55 (two passes each): |d| = 0.1, n_a n_b / n^2
        // = 1/4; the others 0.4 and 0.6 with one pass each.
        assert!((per_block[0] - 0.05).abs() < 1e-6, "{per_block:?}");
        assert!((per_block[1] - 0.1).abs() < 1e-6, "{per_block:?}");
        // Block 0 (256 of 800 pixels) is at 0.05 after 4 passes (sigma
        // 0.1), the rest at 0.1 after 2 (sigma 0.141): for a target of 0.08,
        // 256 * 0.05^2 + 544 * 0.141^2 / (0.141 s) = 800 * 0.08^2 at
        // s = 17.2, so the others want 2.4 passes and go on, while block 0
        // wants 1.7 and sits out; at 0.1 nothing needs more.
        let all = Blocks::all(w, h);
        let next = acc.adaptive_blocks(&all, 0.08).expect("some blocks");
        assert_eq!(next, [false, true, true, true, true, true]);
        assert_eq!(acc.adaptive_blocks(&all, 0.1), None);
    }

    #[test]
    fn stops_at_the_target_the_time_or_the_sample_cap() {
        let target = StopAt {
            target_rmse: Some(0.01),
            time_limit: None,
            adaptive: false,
        };
        assert_eq!(target.verdict(&[report(1, 10, None)], 4), None);
        assert_eq!(target.verdict(&[report(2, 20, Some(0.02))], 4), None);
        assert_eq!(target.verdict(&[report(2, 20, Some(0.01))], 4), None);
        assert_eq!(
            target.verdict(&[report(MIN_PASSES_FOR_TARGET, 20, Some(0.01))], 4),
            Some(Stopped::Target)
        );
        let cap = report(Effects::MAX_SPP / 4, 20, Some(0.02));
        assert_eq!(target.verdict(&[cap], 4), Some(Stopped::MaxSamples));
        let time = StopAt {
            target_rmse: None,
            time_limit: Some(Duration::from_millis(100)),
            adaptive: false,
        };
        // Passes of 30 ms after 40 ms of setup: 70 ends at 100, fits.
        let h = [report(1, 40, None), report(2, 70, Some(0.1))];
        assert_eq!(time.verdict(&h, 4), None);
        let h = [
            report(1, 40, None),
            report(2, 70, Some(0.1)),
            report(3, 100, Some(0.1)),
        ];
        assert_eq!(time.verdict(&h, 4), Some(Stopped::TimeLimit));
    }
}
