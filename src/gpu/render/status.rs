//! What the pass loop reads after each wait: each pass's status, which
//! says whether a tile is done, goes on, or starts again with less work a
//! pass; and what the loop counts on its way, for `-v` and `--stats`.

use std::time::{Duration, Instant};

use super::job::{TileRect, TileWork, BUDGET_BACKOFF, RESUMABLE_REDOS};
use super::resources::Slot;
use crate::gpu::bindings::Lists;
use crate::gpu::error::GpuError;
use crate::gpu::pipeline::Kernel;
use crate::layout::GpuStatus;
use crate::timing::{
    Timings, CLOSEST_RAYS, GPU_TIME_NS, PASS_WAITS, READBACK_BYTES, READBACK_READS, SHADOW_RAYS,
};

/// How a render's tiles start, from what its finished tiles and the
/// renderer's last render needed.
pub(super) struct Starts {
    /// Tiles start resumable (`TileWork::resumable`).
    pub(super) resumable: bool,
    /// The most passes a tile of the renderer's last render needed.
    pub(super) last: u32,
    /// The most passes queued at once (`GpuRenderOptions::chain_passes`).
    pub(super) max_chain: u32,
    pub(super) budget: u32,
    /// A tile of this render needed passes.
    pub(super) needed: bool,
    /// The most passes a finished tile of this render needed (0: none
    /// finished yet).
    pub(super) most: u32,
}

impl Starts {
    /// A new tile: resumable once a tile of this render needed passes
    /// (so will this), with as many queued as the most a tile of this
    /// render or the last needed.
    pub(super) fn tile(&self, rect: TileRect) -> TileWork {
        let resumable = self.resumable || self.needed;
        let chain = match resumable {
            true => self.most.max(self.last).clamp(1, self.max_chain),
            false => 1,
        };
        TileWork::new(rect, self.budget, resumable, chain)
    }

    /// What the renderer remembers for its next render: the most passes a
    /// tile needed (1: none needed more).
    pub(super) fn passes_needed(&self) -> u32 {
        if self.needed {
            self.most.max(2)
        } else {
            1
        }
    }
}

/// What the pass loop counts on its way.
pub(super) struct Tally {
    pub(super) done_pixels: u64,
    pub(super) rays: [u64; 2],
    pub(super) device_time: Duration,
    pub(super) timed_by_device: bool,
    pub(super) readback: Duration,
    /// What the host reads of finished tiles (status words left out).
    pub(super) readback_bytes: u64,
    /// Times the host read texels: a tile's, or the gathered image.
    pub(super) reads: u64,
    pub(super) passes: u64,
    /// Times the host waited for a tile's passes in flight.
    pub(super) waits: u64,
    pub(super) retries: u64,
    pub(super) redone: u64,
}

impl Default for Tally {
    fn default() -> Tally {
        Tally {
            done_pixels: 0,
            rays: [0; 2],
            device_time: Duration::ZERO,
            timed_by_device: true,
            readback: Duration::ZERO,
            readback_bytes: 0,
            reads: 0,
            passes: 0,
            waits: 0,
            retries: 0,
            redone: 0,
        }
    }
}

impl Tally {
    /// One read of finished texels by the host: `read` returns the bytes
    /// it read, and its time goes to `readback`.
    pub(super) fn read(&mut self, read: impl FnOnce() -> u64) {
        let start = Instant::now();
        self.readback_bytes += read();
        self.readback += start.elapsed();
        self.reads += 1;
    }

    /// The loop's phases and counts: `dispatch` is the loop's time less
    /// the readback's; rays where `rays_counted`.
    pub(super) fn report(
        &self,
        timings: &mut Timings,
        looped: Duration,
        rays_counted: bool,
        lists: Lists,
        corners: bool,
    ) {
        timings.add("dispatch", looped.saturating_sub(self.readback));
        timings.add("readback", self.readback);
        timings.count(READBACK_BYTES, self.readback_bytes);
        timings.count(READBACK_READS, self.reads);
        timings.count("passes", self.passes);
        timings.count(PASS_WAITS, self.waits);
        if self.timed_by_device {
            timings.count(GPU_TIME_NS, self.device_time.as_nanos() as u64);
        }
        if rays_counted {
            timings.count(CLOSEST_RAYS, self.rays[0]);
            timings.count(SHADOW_RAYS, self.rays[1]);
        }
        match lists {
            Lists::Split => timings.count("split lists", 1),
            Lists::Uniform => timings.count("uniform lists", 1),
            Lists::Address => timings.count("address lists", 1),
            Lists::Plain => {}
        }
        if corners {
            timings.count("uniform corners", 1);
        }
        if self.retries > 0 {
            // Tiles redone with a smaller budget after a pass was cut short.
            timings.count("retries", self.retries);
        }
        if self.redone > 0 {
            // Tiles redone with the resumable shader after a one-pass try.
            timings.count(RESUMABLE_REDOS, self.redone);
        }
    }
}

/// After the passes of `work` just waited for, read in order: whether the
/// tile is done (its rays added to `work.rays`), or set up for its next
/// passes (the chain doubled, up to `max_chain`, where it goes on; one
/// where it starts again); and whether it needs passes.
pub(super) fn after_passes(
    work: &mut TileWork,
    slot: &Slot,
    (kernel, width): (Kernel, u32),
    max_chain: u32,
    tally: &mut Tally,
    report: &dyn Fn(&Tally),
) -> Result<(bool, bool), GpuError> {
    let mut needed = false;
    for i in 0..work.chain {
        let status = slot.status(i);
        let Some(needs) = next_pass(work, &status, kernel, width, tally)? else {
            // The passes after it found every pixel finished.
            work.rays[0] += u64::from(status.closest_rays);
            work.rays[1] += u64::from(status.shadow_rays);
            return Ok((true, needed));
        };
        needed |= needs;
        // Every pass reports, a redone tile's with no pixel finished.
        if kernel == Kernel::Render && status.cut == 0 {
            report(tally);
        }
        if work.pass == 1 {
            // Redone from its start: the passes after it are void.
            work.chain = 1;
            return Ok((false, needed));
        }
    }
    work.chain = (work.chain * 2).min(max_chain);
    Ok((false, needed))
}

/// After a pass of `work` that did not finish it: the tile set up for its
/// next pass (`Some`, with whether it needs passes), or `None` when it is
/// done; an error when it was cut short with no smaller budget to try.
fn next_pass(
    work: &mut TileWork,
    status: &GpuStatus,
    kernel: Kernel,
    width: u32,
    tally: &mut Tally,
) -> Result<Option<bool>, GpuError> {
    if status.cut > 0 {
        let width = width.max(1);
        let [x, y] = [status.first_cut % width, status.first_cut / width];
        if kernel != Kernel::Render || work.budget == 1 {
            return Err(GpuError::Incomplete {
                x,
                y,
                cut: status.cut,
                probe: kernel != Kernel::Render,
            });
        }
        // Redo the tile from its start with less work per pass: the
        // passes are deterministic, so the image is the same.
        work.budget = (work.budget / BUDGET_BACKOFF).max(1);
        work.pass = 1;
        let size = work.rect.size[0] * work.rect.size[1];
        tally.done_pixels -= u64::from(size - work.left);
        work.left = size;
        work.rays = [0; 2];
        tally.retries += 1;
        Ok(Some(false))
    } else if status.remaining > 0 && kernel == Kernel::Render && !work.resumable {
        // The pass kept no state to resume from: redo the tile.
        work.resumable = true;
        work.pass = 1;
        work.left = work.rect.size[0] * work.rect.size[1];
        work.rays = [0; 2];
        tally.redone += 1;
        Ok(Some(true))
    } else if status.remaining > 0 && kernel == Kernel::Render {
        work.rays[0] += u64::from(status.closest_rays);
        work.rays[1] += u64::from(status.shadow_rays);
        work.pass += 1;
        tally.done_pixels += u64::from(work.left.saturating_sub(status.remaining));
        work.left = status.remaining.min(work.left);
        Ok(Some(true))
    } else {
        Ok(None)
    }
}
