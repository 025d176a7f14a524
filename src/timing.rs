//! Wall-clock phases of a render (parse, BVH build, pipeline, upload,
//! dispatch, readback), for `-v` and for benchmarks.

use std::fmt;
use std::time::{Duration, Instant};

/// The count of closest-hit rays (primary and reflected) a render cast.
pub const CLOSEST_RAYS: &str = "closest rays";
/// The count of shadow rays a render cast.
pub const SHADOW_RAYS: &str = "shadow rays";
/// The count of shadow rays a render left untraced because whether they
/// were blocked could not change a pixel (the light's term leaves the
/// colour's bits as they are); the CPU's packets count them.
pub const UNTRACED_SHADOW_RAYS: &str = "untraced shadow rays";
/// Bytes of finished pixels a GPU render read back to the host.
pub const READBACK_BYTES: &str = "readback bytes";
/// Times a GPU render's host read finished pixels back: once where the
/// tiles were gathered on the device, else once a tile.
pub const READBACK_READS: &str = "readback reads";
/// Times a GPU render's host waited for a tile's passes: once a pass,
/// or once for a chain of them (`GpuRenderOptions::chain_passes`).
pub const PASS_WAITS: &str = "pass waits";
/// Bytes a GPU render copied to the device (scene lists and the frame);
/// a list the device already holds from the last render is not copied.
pub const UPLOADED_BYTES: &str = "uploaded bytes";
/// Nanoseconds the device spent in a render's dispatches, from Vulkan
/// timestamps around each (absent where the queue has none).
pub const GPU_TIME_NS: &str = "gpu ns";
/// Nanoseconds of CPU time a CPU render's threads spent on its pixels,
/// summed over the threads (absent where the system cannot say). Unlike
/// wall time it leaves out what the machine took elsewhere: time the
/// threads waited for a core, and a virtual machine's stolen time.
pub const CPU_TIME_NS: &str = "cpu ns";

/// The CPU time the calling thread has run for (steal excluded where the
/// kernel accounts it), or None where the system has no such clock.
pub fn thread_cpu_time() -> Option<Duration> {
    #[cfg(unix)]
    {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: `ts` is a valid timespec for the call to write.
        let ok = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) } == 0;
        ok.then(|| Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32))
    }
    #[cfg(not(unix))]
    None
}

/// Where a render's time went, by phase, and what it counted.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Timings {
    /// (phase, time), in the order first recorded.
    pub phases: Vec<(&'static str, Duration)>,
    /// Counts that go with the phases (e.g. GPU passes), shown after them.
    pub counts: Vec<(&'static str, u64)>,
}

impl Timings {
    /// Adds `d` to phase `name`.
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

    /// All phases together.
    pub fn total(&self) -> Duration {
        self.phases.iter().map(|p| p.1).sum()
    }

    /// Adds `n` to count `name`.
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

    /// The rays the image calls for: those cast and the shadow rays left
    /// untraced, the count a renderer that traces them all casts.
    pub fn rays_called_for(&self) -> Option<u64> {
        self.rays()
            .map(|cast| cast + self.counted(UNTRACED_SHADOW_RAYS))
    }

    /// Adds `other`'s phases and counts.
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The thread clock moves with this thread's work, no faster than the
    /// wall clock, and not while the thread sleeps.
    #[test]
    fn thread_cpu_time_counts_this_threads_work() {
        // The wall clock starts first and is read last, so that its
        // interval holds the thread clock's (read the other way round, a
        // busy thread's CPU time exceeded it by the gap between them in a
        // loaded CI run: 30.0046 ms); the two clocks have different
        // sources, hence the 0.1 ms of slack below.
        let wall = Instant::now();
        let Some(start) = thread_cpu_time() else {
            if cfg!(unix) {
                panic!("no thread CPU clock where unix has one");
            }
            eprintln!("SKIPPED: thread_cpu_time_counts_this_threads_work: no thread CPU clock");
            return;
        };
        let mut x = 1u64;
        while wall.elapsed() < Duration::from_millis(30) {
            x = std::hint::black_box(x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1));
        }
        let busy = thread_cpu_time().expect("the clock stays") - start;
        let elapsed = wall.elapsed();
        assert!(
            busy > Duration::ZERO && busy <= elapsed + Duration::from_micros(100),
            "{busy:?} of CPU time in {elapsed:?}"
        );
        let before_sleep = thread_cpu_time().expect("the clock stays");
        std::thread::sleep(Duration::from_millis(50));
        let asleep = thread_cpu_time().expect("the clock stays") - before_sleep;
        assert!(
            asleep < Duration::from_millis(20),
            "{asleep:?} while asleep"
        );
    }
}
