//! The pass loop: a render's tiles, two in flight, each through as many
//! passes of bounded work as its pixels need (the shader's `render_tile` is
//! a resumable state machine with a budget of loop iterations a pass), so
//! no invocation meets a driver's loop limit and no submission trips a
//! watchdog. After each pass the host reads its status: pixels left
//! (another pass), or pixels cut short (the tile is redone with a smaller
//! budget, or the render fails naming the pixel).

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use ash::vk;

use super::job::{
    tile_edge, tile_texels, tiles, GpuRenderOptions, Job, Packing, TileRect, TileWork,
    BUDGET_BACKOFF, B_FRAME, B_OUTPUT, B_STATE, PATH_MAX_LIGHTS, RESUMABLE_REDOS, SLOTS,
    TEXEL_BYTES,
};
use super::plan::{capped, check_limits, key, scene_uploads, upload};
use super::resources::{scene_buffer, Gpu, Resources};
use crate::camera::Camera;
use crate::gpu::bindings::Lists;
use crate::gpu::error::GpuError;
use crate::gpu::pipeline::{Kernel, PipelineKey};
use crate::gpu::present::FrameTarget;

use crate::layout::{
    uniform_copy, GpuPixelState, GpuScene, GpuStatus, ADDRESS_LISTS, PATH_HEADER, PATH_PER_LIGHT,
    UNIFORM_FIRST, UNIFORM_LISTS,
};
use crate::timing::{
    Timings, CLOSEST_RAYS, GPU_TIME_NS, READBACK_BYTES, SHADOW_RAYS, UPLOADED_BYTES,
};

/// One run of the pass loop: what to render, how, and whether its tiles
/// start with the resumable shader (`TileWork::resumable`).
#[derive(Clone, Copy)]
pub(super) struct Work<'a> {
    pub(super) scene: &'a GpuScene,
    pub(super) camera: &'a Camera,
    pub(super) background: [f32; 3],
    pub(super) options: &'a GpuRenderOptions,
    pub(super) job: Job,
    pub(super) rects: &'a [TileRect],
    pub(super) start_resumable: bool,
    /// Set: start no more tiles or passes, and end with `Cancelled`.
    pub(super) cancel: Option<&'a AtomicBool>,
    /// Each pass's tiles are also copied here (`GpuRenderer::copy_passes_to`).
    pub(super) frame: Option<FrameTarget>,
}

impl Gpu<'_> {
    /// Runs `work`'s tiles through their passes on `res`, two slots in
    /// flight, handing each finished tile's texels to `sink`; whether a
    /// tile needed passes (for the renderer's next start, `Render` only).
    pub(super) fn run(
        &self,
        work: &Work,
        res: &mut Resources,
        progress: &(dyn Fn(u64, u64) + Sync),
        sink: &mut dyn FnMut(TileRect, &[u8]),
    ) -> Result<(Timings, Option<bool>), GpuError> {
        let Work {
            scene,
            camera,
            options,
            job,
            rects,
            start_resumable,
            cancel,
            frame: target,
            ..
        } = *work;
        let mut timings = Timings::default();
        let tile_edge = tile_edge(options.tile_size);
        let (kernel, tiles, out_texels) = job_tiles(job, scene, camera, options, rects);
        let pack = Packing::of(job, options);
        let texel_bytes = pack.map_or(TEXEL_BYTES, Packing::bytes);
        let (lists, key) = self.upload_job(work, res, kernel, out_texels, pack, &mut timings)?;
        // Each pipeline is built when a tile first needs it: the one-pass
        // shader for a tile's first try, the resumable one after it
        // (`TileWork::resumable`); a probe's is `key`'s.
        let mut built: [Option<vk::Pipeline>; 2] = [None; 2];
        let mut pipeline_for = |work: &TileWork, timings: &mut Timings| {
            let slot = &mut built[usize::from(work.resumable)];
            if let Some(p) = *slot {
                return Ok(p);
            }
            let (p, build_time, _) = self.pipeline.get(PipelineKey {
                one_pass: key.one_pass && !work.resumable,
                ..key
            })?;
            if !build_time.is_zero() {
                timings.add("pipeline", build_time);
            }
            *slot = Some(p);
            Ok::<_, GpuError>(p)
        };

        let mut in_flight: VecDeque<(usize, TileWork)> = VecDeque::new();
        let total_pixels: u64 = tiles.iter().map(|t| u64::from(t.size[0] * t.size[1])).sum();
        let mut tally = Tally::default();
        // Probes keep no state and run once: they never start resumable.
        let start_resumable =
            kernel == Kernel::Render && (start_resumable || !options.one_pass_first);
        let mut needed_passes = false;
        let dispatch_start = Instant::now();
        let mut next_tile = tiles.iter();
        let mut free: Vec<usize> = (0..SLOTS).rev().collect();
        let cancelled = || cancel.is_some_and(|c| c.load(Ordering::Relaxed));
        // A tile whose pass just ended and needs another, submitted first.
        let mut again: Option<(usize, TileWork)> = None;
        loop {
            // Then every free slot takes a new tile (none once cancelled:
            // the tiles in flight are only waited for).
            loop {
                let (s, work) = match again.take() {
                    Some(a) => a,
                    None => {
                        let (false, Some(&s)) = (cancelled(), free.last()) else {
                            break;
                        };
                        let Some(&rect) = next_tile.next() else {
                            break;
                        };
                        free.pop();
                        let work = TileWork {
                            rect,
                            pass: 1,
                            budget: options.pass_budget.max(1),
                            left: rect.size[0] * rect.size[1],
                            rays: [0; 2],
                            // A tile of this render needed passes: so will this.
                            resumable: start_resumable || needed_passes,
                        };
                        (s, work)
                    }
                };
                let p = pipeline_for(&work, &mut timings)?;
                let packing = pack.map(|k| {
                    let p = res.pack[k.index()].as_ref().expect("bound by upload_job");
                    (p, s, k)
                });
                self.submit_pass(
                    &mut res.slots[s],
                    p,
                    (lists, job),
                    work,
                    out_texels,
                    (target, packing),
                )?;
                tally.passes += 1;
                in_flight.push_back((s, work));
            }
            let Some((s, mut work)) = in_flight.pop_front() else {
                break;
            };
            let slot = &res.slots[s];
            self.wait(slot, work, options)?;
            if cancelled() {
                free.push(s);
                continue;
            }
            match self.dispatch_time(slot) {
                Some(t) => tally.device_time += t,
                None => tally.timed_by_device = false,
            }
            let status: GpuStatus =
                *bytemuck::from_bytes(&slot.status.mapped()[..std::mem::size_of::<GpuStatus>()]);
            if let Some(needs) = next_pass(&mut work, &status, kernel, camera.width, &mut tally)? {
                needed_passes |= needs;
                // Every pass reports, a redone tile's with no pixel finished.
                if kernel == Kernel::Render && status.cut == 0 {
                    progress(tally.done_pixels, total_pixels);
                }
            } else {
                let start = Instant::now();
                let n = match job {
                    Job::Image(_) | Job::Rects => u64::from(work.rect.size[0] * work.rect.size[1]),
                    Job::Pixel(_) => out_texels,
                };
                let bytes = (n * texel_bytes) as usize;
                sink(work.rect, &slot.readback.get().mapped()[..bytes]);
                tally.readback += start.elapsed();
                tally.readback_bytes += bytes as u64;
                tally.rays[0] += work.rays[0] + u64::from(status.closest_rays);
                tally.rays[1] += work.rays[1] + u64::from(status.shadow_rays);
                tally.done_pixels += u64::from(work.left);
                progress(tally.done_pixels, total_pixels);
                free.push(s);
                continue;
            }
            again = Some((s, work));
        }
        if cancelled() {
            return Err(GpuError::Cancelled);
        }
        // A pass's counters are 32-bit: counts that may have wrapped are
        // left out rather than shown wrong.
        let most_per_pass =
            u64::from(tile_edge) * u64::from(tile_edge) * u64::from(options.pass_budget);
        let rays_counted = kernel == Kernel::Render && most_per_pass <= u64::from(u32::MAX);
        tally.report(
            &mut timings,
            dispatch_start.elapsed(),
            rays_counted,
            lists,
            key.corners,
        );
        Ok((timings, (kernel == Kernel::Render).then_some(needed_passes)))
    }

    /// Uploads what `work` reads that the device does not hold yet, binds
    /// it to every slot (and the pack's buffers where `pack`), and says how
    /// the lists are bound and which pipeline renders them.
    fn upload_job(
        &self,
        work: &Work,
        res: &mut Resources,
        kernel: Kernel,
        out_texels: u64,
        pack: Option<Packing>,
        timings: &mut Timings,
    ) -> Result<(Lists, PipelineKey), GpuError> {
        let Work {
            scene,
            camera,
            background,
            options,
            ..
        } = *work;
        let state_bytes = match kernel {
            Kernel::Render => out_texels * std::mem::size_of::<GpuPixelState>() as u64,
            _ => std::mem::size_of::<GpuPixelState>() as u64,
        };
        let out_bytes = out_texels * TEXEL_BYTES;
        let mut frame = scene.frame(camera, background, &options.effects, &options.features);
        let mut uploads = vec![upload(
            B_FRAME,
            "frame",
            bytemuck::bytes_of(&frame).to_vec().into(),
        )];
        uploads.extend(scene_uploads(scene));
        let (split, lists) = check_limits(
            &capped(self.shared.limits, options.storage_limit),
            &uploads,
            &[(B_OUTPUT, out_bytes), (B_STATE, state_bytes)],
            self.forms(options),
        )?;
        frame.chunk_shift = split.shifts;
        uploads[0].bytes = bytemuck::bytes_of(&frame).to_vec().into();
        if lists == Lists::Uniform {
            for (j, (binding, name)) in UNIFORM_LISTS.into_iter().enumerate() {
                let list = &uploads
                    .iter()
                    .find(|u| u.binding == binding)
                    .expect("uploaded")
                    .bytes;
                let copy = uniform_copy(j, list).expect("choose_lists checked that it fits");
                uploads.push(upload(UNIFORM_FIRST + j, name, copy.into()));
            }
        }
        let key = key(options, kernel, lists, scene, &uploads, false);
        let upload_start = Instant::now();
        if lists == Lists::Address {
            // The frame carries the lists' addresses: size their buffers
            // first (the upload then reuses them).
            for (j, (binding, _)) in ADDRESS_LISTS.into_iter().enumerate() {
                let size = uploads
                    .iter()
                    .find(|u| u.binding == binding)
                    .map_or(0, |u| u.bytes.len() as u64);
                let address = scene_buffer(&mut res.scene, self.shared, binding, size)?
                    .address()
                    .expect("address lists need the lists' device addresses");
                frame.set_address(j, address);
            }
            uploads[0].bytes = bytemuck::bytes_of(&frame).to_vec().into();
        }
        let uploaded = self.upload(res, &uploads)?;
        for slot in &mut res.slots {
            self.bind_slot(
                slot,
                &res.scene,
                &uploads,
                &split,
                lists,
                out_bytes,
                state_bytes,
            )?;
        }
        if let Some(packing) = pack {
            self.bind_pack(res, packing, out_texels)?;
        }
        timings.add("upload", upload_start.elapsed());
        timings.count(UPLOADED_BYTES, uploaded);
        Ok((lists, key))
    }
}

/// What a job runs: its kernel, its tiles, and the texels of output a tile
/// slot holds.
fn job_tiles(
    job: Job,
    scene: &GpuScene,
    camera: &Camera,
    options: &GpuRenderOptions,
    rects: &[TileRect],
) -> (Kernel, Vec<TileRect>, u64) {
    match job {
        Job::Image(kernel) => (
            kernel,
            tiles(camera.width, camera.height, tile_edge(options.tile_size)),
            tile_texels(options.tile_size, camera.width, camera.height),
        ),
        Job::Rects => (
            Kernel::Render,
            rects.to_vec(),
            tile_texels(options.tile_size, camera.width, camera.height),
        ),
        Job::Pixel(origin) => {
            let lights = (scene.lights.len() as u32).min(PATH_MAX_LIGHTS);
            let rect = TileRect {
                origin,
                size: [1, 1],
            };
            (
                Kernel::ProbePixel,
                vec![rect],
                u64::from(PATH_HEADER + PATH_PER_LIGHT * lights),
            )
        }
    }
}

/// What the pass loop counts on its way.
struct Tally {
    done_pixels: u64,
    rays: [u64; 2],
    device_time: Duration,
    timed_by_device: bool,
    readback: Duration,
    /// What the host reads of finished tiles (status words left out).
    readback_bytes: u64,
    passes: u64,
    retries: u64,
    redone: u64,
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
            passes: 0,
            retries: 0,
            redone: 0,
        }
    }
}

impl Tally {
    /// The loop's phases and counts: `dispatch` is the loop's time less
    /// the readback's; rays where `rays_counted`.
    fn report(
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
        timings.count("passes", self.passes);
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
