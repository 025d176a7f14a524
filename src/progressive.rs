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

use crate::framebuffer::Framebuffer;
use crate::render::RenderOutput;
use crate::scene::Effects;

/// The fewest passes whose estimate a target trusts: with one pass per
/// half the estimate rests on a single difference image, and where the
/// noise lives in few pixels (a penumbra) that is itself noisy.
pub const MIN_PASSES_FOR_TARGET: u32 = 4;

/// When a progressive render stops; at least one of the two is set.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StopAt {
    /// Stop once the estimated RMSE (linear values, 0-1) is at most this.
    pub target_rmse: Option<f64>,
    /// Stop before a pass would end after this much time.
    pub time_limit: Option<Duration>,
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
}

/// Where a progressive render stands after a pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassReport {
    pub passes: u32,
    pub samples_per_pixel: u32,
    /// Since the render began (setup and BVH included).
    pub elapsed: Duration,
    /// None until there are two passes.
    pub estimated_rmse: Option<f64>,
}

pub struct Progressive {
    /// The mean of every pass; timings summed over the passes.
    pub output: RenderOutput,
    /// The last pass's report.
    pub report: PassReport,
    pub stopped: Stopped,
    pub history: Vec<PassReport>,
}

impl StopAt {
    /// Whether to stop after the passes in `history` (each of `spp`
    /// samples), and why.
    pub fn verdict(&self, history: &[PassReport], spp: u32) -> Option<Stopped> {
        let last = history.last()?;
        if last.estimated_rmse == Some(0.0) {
            return Some(Stopped::Noiseless);
        }
        if let (Some(target), Some(estimate)) = (self.target_rmse, last.estimated_rmse) {
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

/// The running sums of the two halves.
pub struct Accumulator {
    width: u32,
    height: u32,
    halves: [Vec<[f64; 3]>; 2],
    counts: [u32; 2],
}

impl Accumulator {
    pub fn new(width: u32, height: u32) -> Accumulator {
        let n = width as usize * height as usize;
        Accumulator {
            width,
            height,
            halves: [vec![[0.0; 3]; n], vec![[0.0; 3]; n]],
            counts: [0; 2],
        }
    }

    pub fn passes(&self) -> u32 {
        self.counts[0] + self.counts[1]
    }

    /// Adds the next pass (even passes to half A, odd ones to half B).
    pub fn add(&mut self, pass: &Framebuffer) {
        assert_eq!(
            (pass.width, pass.height),
            (self.width, self.height),
            "pass of another size"
        );
        let half = (self.passes() % 2) as usize;
        for (sum, p) in self.halves[half].iter_mut().zip(&pass.pixels) {
            for c in 0..3 {
                sum[c] += f64::from(p[c]);
            }
        }
        self.counts[half] += 1;
    }

    /// The estimated RMSE of `mean()` against the converged image; None
    /// before both halves have a pass.
    pub fn estimated_rmse(&self) -> Option<f64> {
        let [na, nb] = self.counts.map(f64::from);
        if na == 0.0 || nb == 0.0 {
            return None;
        }
        let mut sq = 0.0;
        for (a, b) in self.halves[0].iter().zip(&self.halves[1]) {
            for c in 0..3 {
                let d = a[c] / na - b[c] / nb;
                sq += d * d;
            }
        }
        let values = (self.halves[0].len() * 3).max(1) as f64;
        Some((sq / values * na * nb / ((na + nb) * (na + nb))).sqrt())
    }

    /// The mean of every pass so far.
    pub fn mean(&self) -> Framebuffer {
        let n = f64::from(self.passes().max(1));
        let pixels = self.halves[0]
            .iter()
            .zip(&self.halves[1])
            .map(|(a, b)| [0, 1, 2].map(|c| ((a[c] + b[c]) / n) as f32))
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
                state = crate::cpu::sample::hash_u32(state);
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
        };
        let h = [report(1, 10, None), report(2, 20, Some(0.0))];
        assert_eq!(stop.verdict(&h, 1), Some(Stopped::Noiseless));
    }

    #[test]
    fn stops_at_the_target_the_time_or_the_sample_cap() {
        let target = StopAt {
            target_rmse: Some(0.01),
            time_limit: None,
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
