//! Wall-clock phases of a render (parse, BVH build, pipeline, upload,
//! dispatch, readback), for `-v` and for benchmarks.

use std::fmt;
use std::time::{Duration, Instant};

/// The count of closest-hit rays (primary and reflected) a render cast.
pub const CLOSEST_RAYS: &str = "closest rays";
/// The count of shadow rays a render cast.
pub const SHADOW_RAYS: &str = "shadow rays";
/// Nanoseconds the device spent in a render's dispatches, from Vulkan
/// timestamps around each (absent where the queue has none).
pub const GPU_TIME_NS: &str = "gpu ns";

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Timings {
    pub phases: Vec<(&'static str, Duration)>,
    /// Counts that go with the phases (e.g. GPU passes), shown after them.
    pub counts: Vec<(&'static str, u64)>,
}

impl Timings {
    pub fn add(&mut self, name: &'static str, d: Duration) {
        match self.phases.iter_mut().find(|(n, _)| *n == name) {
            Some((_, total)) => *total += d,
            None => self.phases.push((name, d)),
        }
    }

    /// Runs `f`, adding its duration under `name`.
    pub fn time<T>(&mut self, name: &'static str, f: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let out = f();
        self.add(name, start.elapsed());
        out
    }

    /// The time recorded under `name`, if any.
    pub fn phase(&self, name: &str) -> Option<Duration> {
        self.phases.iter().find(|(n, _)| *n == name).map(|p| p.1)
    }

    pub fn total(&self) -> Duration {
        self.phases.iter().map(|p| p.1).sum()
    }

    pub fn count(&mut self, name: &'static str, n: u64) {
        match self.counts.iter_mut().find(|(c, _)| *c == name) {
            Some((_, total)) => *total += n,
            None => self.counts.push((name, n)),
        }
    }

    /// Whether a count was recorded under `name`.
    pub fn has_count(&self, name: &str) -> bool {
        self.counts.iter().any(|(c, _)| *c == name)
    }

    /// The count recorded under `name`, 0 if none.
    pub fn counted(&self, name: &str) -> u64 {
        self.counts
            .iter()
            .find(|(c, _)| *c == name)
            .map_or(0, |c| c.1)
    }

    /// Closest-hit and shadow rays together, if the render counted them.
    pub fn rays(&self) -> Option<u64> {
        self.has_count(CLOSEST_RAYS)
            .then(|| self.counted(CLOSEST_RAYS) + self.counted(SHADOW_RAYS))
    }

    pub fn extend(&mut self, other: &Timings) {
        for &(name, d) in &other.phases {
            self.add(name, d);
        }
        for &(name, n) in &other.counts {
            self.count(name, n);
        }
    }
}

impl fmt::Display for Timings {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (name, d) in &self.phases {
            writeln!(f, "  {name:<10} {:>10.3} ms", d.as_secs_f64() * 1e3)?;
        }
        write!(
            f,
            "  {:<10} {:>10.3} ms",
            "total",
            self.total().as_secs_f64() * 1e3
        )?;
        for (name, n) in &self.counts {
            write!(f, "\n  {name:<10} {n:>10}")?;
        }
        Ok(())
    }
}
