//! The CPU render's parallel loop: the image in bands of rows, taken by
//! rayon's threads in runs spread over the image, each band filled by
//! one thread and, for an 8-bit image, turned to bytes while it is in that
//! thread's cache.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use image::RgbImage;
use rayon::prelude::*;

use super::real::Real;
use super::trace::{self, CpuScene};
use crate::images::framebuffer::{to_u8, Framebuffer, Image};

/// Which pixels a render traces; the others are left 0.
#[derive(Clone, Copy)]
pub enum Keep<'a> {
    /// Every pixel, until `stop()` says the render is cancelled: it is
    /// asked once a band, so a render of every pixel pays nothing a pixel.
    All(&'a (dyn Fn() -> bool + Sync)),
    /// The pixels `f(x, y)` says, asked pixel by pixel.
    Where(&'a (dyn Fn(u32, u32) -> bool + Sync)),
}

impl Keep<'_> {
    /// Every pixel, never cancelled.
    pub const EVERY: Keep<'static> = Keep::All(&|| false);

    /// Whether the band is skipped whole (a cancelled render).
    pub(super) fn stopped(&self) -> bool {
        match self {
            Keep::All(stop) => stop(),
            Keep::Where(_) => false,
        }
    }

    /// Whether pixel (x, y) of a band not `stopped` is traced.
    #[inline]
    pub fn pixel(&self, x: u32, y: u32) -> bool {
        match self {
            Keep::All(_) => true,
            Keep::Where(f) => f(x, y),
        }
    }
}

/// What a render's bands become.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Out {
    /// The float image, unclamped as rendered.
    Float,
    /// 8-bit pixels (`to_u8`), each band converted on the thread that
    /// rendered it: the float image is never whole.
    Rgb8,
}

/// What a render's threads did besides their pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Work {
    /// Closest-hit and shadow rays cast.
    pub rays: [u64; 2],
    /// Shadow rays left untraced: their answer could not change a pixel.
    pub untraced: u64,
    /// CPU time the threads spent on the pixels, summed over threads
    /// (`timing::thread_cpu_time`); None where the system cannot say.
    pub cpu_time: Option<Duration>,
}

/// Which rows a render's bands cover, who hears of them, and what they
/// become.
pub(super) struct Bands<'a> {
    pub progress: &'a (dyn Fn(u64, u64) + Sync),
    pub active: std::ops::Range<u32>,
    pub keep: Keep<'a>,
    pub out: Out,
}

impl Bands<'_> {
    /// The image `fill(scene, y0, band)` makes, `rows` rows a band.
    pub fn render<R: Real>(
        &self,
        scene: &CpuScene<R>,
        rows: u32,
        fill: impl Fn(&CpuScene<R>, u32, &mut [[f32; 3]]) + Sync,
    ) -> (Image, Work) {
        let [width, height] = scene.size;
        if let Out::Float = self.out {
            let (pixels, work) = self.per_band(scene, rows, fill);
            let fb = Framebuffer {
                width,
                height,
                pixels,
            };
            return (Image::Float(fb), work);
        }
        let mut bytes = vec![0u8; 3 * width as usize * height as usize];
        let work = self.for_bands(scene, rows, &mut bytes, 3, |scene, y0, out| {
            let mut band = vec![[0.0f32; 3]; out.len() / 3];
            fill(scene, y0, &mut band);
            for (o, &v) in out.iter_mut().zip(bytemuck::cast_slice::<_, f32>(&band)) {
                *o = to_u8(v);
            }
        });
        let image = RgbImage::from_raw(width, height, bytes).expect("3 bytes a pixel");
        (Image::Rgb8(image), work)
    }

    /// `f(scene, y0, band)` fills each band of `rows` rows from row `y0`
    /// (the last may have fewer; `T::default()` to start with), bands in
    /// parallel (`for_bands`). Also returns the rays `f` cast and the
    /// threads' CPU time (`Work`).
    pub fn per_band<R: Real, T: Send + Default + Clone>(
        &self,
        scene: &CpuScene<R>,
        rows: u32,
        f: impl Fn(&CpuScene<R>, u32, &mut [T]) + Sync,
    ) -> (Vec<T>, Work) {
        let [w, h] = scene.size;
        let mut out = vec![T::default(); w as usize * h as usize];
        let work = self.for_bands(scene, rows, &mut out, 1, f);
        (out, work)
    }

    /// The bands of `out`, `per_pixel` elements a pixel, taken in
    /// `band_order` so that `progress(rows_done, rows)` advances at an
    /// even pace: rows in order would finish the cheap sky first and the
    /// costly floor last, and an ETA from them would be wrong by the ratio.
    /// Bands that miss the rows `active`, and those begun after `keep` says
    /// stop, are left as they start.
    fn for_bands<R: Real, U: Send>(
        &self,
        scene: &CpuScene<R>,
        rows: u32,
        out: &mut [U],
        per_pixel: usize,
        f: impl Fn(&CpuScene<R>, u32, &mut [U]) + Sync,
    ) -> Work {
        let [w, h] = scene.size;
        let rows = rows.max(1);
        let row_len = (w as usize * per_pixel).max(1);
        let mut bands: Vec<Option<&mut [U]>> =
            out.chunks_mut(row_len * rows as usize).map(Some).collect();
        let active = &self.active;
        let ordered: Vec<(u32, &mut [U])> = band_order(bands.len() as u32, rows)
            .into_iter()
            .filter(|&b| b * rows < active.end && (b + 1) * rows > active.start)
            .filter_map(|b| Some((b * rows, bands[b as usize].take()?)))
            .collect();
        let tally = Tally::new();
        // The rows of the bands no thread takes are done from the start.
        let skipped: usize = bands.iter().flatten().map(|b| b.len()).sum();
        tally
            .done
            .store((skipped / row_len) as u64, Ordering::Relaxed);
        // A band a job: by default rayon hands each thread a few long
        // stretches, and a thread done with its own cannot take a band from
        // a stretch under way (2M grid, 2 threads: one thread idle at the
        // end for 0.5-4 ms of a 78 ms render, 11-13 ms where another
        // process took a core, against at most one band's 2.5 ms now).
        ordered
            .into_par_iter()
            .with_max_len(1)
            .for_each(|(y0, band)| {
                let n = (band.len() / row_len) as u64;
                if !self.keep.stopped() {
                    tally.band(|| f(scene, y0, band));
                }
                let finished = tally.done.fetch_add(n, Ordering::Relaxed) + n;
                (self.progress)(finished, u64::from(h));
            });
        tally.work()
    }
}

/// What a render's bands did, summed over threads as they finish.
struct Tally {
    done: AtomicU64,
    /// Closest-hit, shadow and untraced shadow rays (`trace::rays_cast`).
    rays: [AtomicU64; 3],
    cpu_ns: AtomicU64,
}

impl Tally {
    fn new() -> Tally {
        Tally {
            done: AtomicU64::new(0),
            rays: [AtomicU64::new(0), AtomicU64::new(0), AtomicU64::new(0)],
            cpu_ns: AtomicU64::new(0),
        }
    }

    /// Runs one band's `fill`, counting its rays and its thread's CPU time.
    fn band(&self, fill: impl FnOnce()) {
        // A band runs on one thread from start to end, so the thread's
        // counters moved by this band's rays alone.
        let before = trace::rays_cast();
        let started = crate::timing::thread_cpu_time();
        fill();
        if let (Some(a), Some(b)) = (started, crate::timing::thread_cpu_time()) {
            let ns = b.saturating_sub(a).as_nanos() as u64;
            self.cpu_ns.fetch_add(ns, Ordering::Relaxed);
        }
        let after = trace::rays_cast();
        for k in 0..3 {
            self.rays[k].fetch_add(after[k] - before[k], Ordering::Relaxed);
        }
    }

    fn work(self) -> Work {
        let [closest, shadow, untraced] = self.rays.map(AtomicU64::into_inner);
        Work {
            rays: [closest, shadow],
            untraced,
            // The clock is the system's: there for every band or for none.
            cpu_time: crate::timing::thread_cpu_time()
                .map(|_| Duration::from_nanos(self.cpu_ns.into_inner())),
        }
    }
}

/// Rows a run of bands covers (`band_order`). Runs of 24 and 96 rows
/// were slower at 2 threads (the 2M grid's fastest of 11, four
/// alternations: 80.5-81.9 and 78.7-79.8 ms against 77.6-78.2; the 240k
/// grid 42.1-43.0 and 41.4-42.4 against 40.9-41.7).
const RUN_ROWS: u32 = 48;

/// The bands 0..n of `rows` rows each in runs of adjacent bands, each run
/// in order and the runs in `spread_order`: a run's bands meet the same
/// parts of the scene, which the band before left in the caches, and the
/// runs keep the pace even at a run's grain (ten at 480 rows). rayon
/// hands each thread a stretch of this order, so a thread too walks a run
/// top to bottom. Against the bands in `spread_order` alone, at 2
/// threads, the fastest of 11 renders, five alternations (`benches/
/// history.md`): the 2M grid 82.2-83.2 -> 79.1-81.2 ms, the 240k grid
/// 42.9-45.4 -> 41.6-42.8 (one noisy round aside), SIGGRAPH 13.3-13.5 ->
/// 13.0-13.2. All rows in order gave the same as runs.
fn band_order(n: u32, rows: u32) -> Vec<u32> {
    let run = (RUN_ROWS / rows.max(1)).max(1);
    spread_order(n.div_ceil(run))
        .into_iter()
        .flat_map(|r| r * run..((r + 1) * run).min(n))
        .collect()
}

/// The rows 0..n in an order whose every stretch is spread over the whole
/// image: row (i * s) mod n, with the stride s near n / golden ratio and
/// coprime to n (so each row comes once).
pub fn spread_order(n: u32) -> Vec<u32> {
    if n < 3 {
        return (0..n).collect();
    }
    let gcd = |mut a: u64, mut b: u64| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let mut stride = ((f64::from(n) * 0.618_033_988_75) as u64).max(1);
    while gcd(stride, u64::from(n)) != 1 {
        stride += 1;
    }
    (0..u64::from(n))
        .map(|i| ((i * stride) % u64::from(n)) as u32)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::{band_order, spread_order, RUN_ROWS};

    /// Each band once, in runs of adjacent bands covering `RUN_ROWS` rows
    /// (the last run may be shorter), the runs in `spread_order`.
    #[test]
    fn band_order_is_runs_in_spread_order() {
        for (n, rows) in [
            (0, 8),
            (1, 8),
            (5, 8),
            (60, 8),
            (61, 8),
            (135, 8),
            (480, 1),
            (7, 100),
        ] {
            let order = band_order(n, rows);
            let mut seen = order.clone();
            seen.sort_unstable();
            assert_eq!(seen, (0..n).collect::<Vec<_>>(), "n = {n}");
            let run = (RUN_ROWS / rows).max(1);
            // Each run's bands together, from its first, one after another.
            let mut runs: Vec<u32> = Vec::new();
            for (i, &b) in order.iter().enumerate() {
                if runs.last() != Some(&(b / run)) {
                    assert_eq!(b % run, 0, "a run starts at its first band: {order:?}");
                    runs.push(b / run);
                } else {
                    assert_eq!(b, order[i - 1] + 1, "{order:?}");
                }
            }
            assert_eq!(runs, spread_order(n.div_ceil(run)), "n = {n}");
        }
    }

    /// Each row once, and any stretch of the order is spread evenly: the
    /// first eighth of the work touches every eighth of the image.
    #[test]
    fn spread_order_is_a_permutation_spread_over_the_image() {
        for n in [0, 1, 2, 3, 7, 30, 240, 480, 1000, 1024, 16384] {
            let order = spread_order(n);
            let mut seen = order.clone();
            seen.sort_unstable();
            assert_eq!(seen, (0..n).collect::<Vec<_>>(), "n = {n}");
            if n >= 64 {
                let eighth = (n / 8) as usize;
                for start in [0, eighth, 3 * eighth] {
                    let mut bands = [0u32; 8];
                    for &y in &order[start..start + eighth] {
                        bands[(y * 8 / n) as usize] += 1;
                    }
                    let (lo, hi) = (bands.iter().min().unwrap(), bands.iter().max().unwrap());
                    assert!(
                        *lo > 0 && hi - lo <= eighth as u32 / 4 + 2,
                        "n = {n}: {bands:?}"
                    );
                }
            }
        }
    }
}
