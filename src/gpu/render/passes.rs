//! The pass loop: a render's tiles, two in flight, each through as many
//! passes of bounded work as its pixels need (the shader's `render_tile` is
//! a resumable state machine with a budget of loop iterations a pass), so
//! no invocation meets a driver's loop limit and no submission trips a
//! watchdog. A tile's passes after its first are queued several at a time
//! (`GpuRenderOptions::chain_passes`), each its own submission, and the host
//! waits once for them; then it reads each pass's status (`status`): pixels
//! left (more passes), or pixels cut short (the tile is redone with a
//! smaller budget, or the render fails naming the pixel). A finished tile's
//! texels are read at once, or gathered on the device into one image the
//! host reads at the end.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use ash::vk;

use super::job::{
    gather_bytes, tile_edge, tile_texels, tiles, GpuRenderOptions, Job, Packing, TileRect,
    TileSink, TileWork, B_FRAME, B_OUTPUT, B_STATE, MAX_CHAIN, PATH_MAX_LIGHTS, SLOTS, TEXEL_BYTES,
};
use super::plan::{capped, check_limits, key, scene_uploads, upload};
use super::record::{Copies, Gather};
use super::resources::{scene_buffer, Gpu, Resources, Slot};
use super::status::{after_passes, Starts, Tally};
use crate::camera::Camera;
use crate::gpu::bindings::Lists;
use crate::gpu::error::GpuError;
use crate::gpu::pipeline::{Kernel, PipelineKey};
use crate::gpu::present::FrameTarget;

use crate::layout::{
    uniform_copy, GpuPixelState, GpuScene, ADDRESS_LISTS, PATH_HEADER, PATH_PER_LIGHT,
    UNIFORM_FIRST, UNIFORM_LISTS,
};
use crate::timing::{Timings, UPLOADED_BYTES};

/// One run of the pass loop: what to render, how, and how its tiles start
/// (`start_passes`).
#[derive(Clone, Copy)]
pub(super) struct Work<'a> {
    pub(super) scene: &'a GpuScene,
    pub(super) camera: &'a Camera,
    pub(super) background: [f32; 3],
    pub(super) options: &'a GpuRenderOptions,
    pub(super) job: Job,
    pub(super) rects: &'a [TileRect],
    /// The most passes a tile of the renderer's last render needed (0:
    /// none rendered): over one, tiles start resumable, with as many
    /// passes queued.
    pub(super) start_passes: u32,
    /// Set: start no more tiles or passes, and end with `Cancelled`.
    pub(super) cancel: Option<&'a AtomicBool>,
    /// Each pass's tiles are also copied here (`GpuRenderer::copy_passes_to`).
    pub(super) frame: Option<FrameTarget>,
}

impl Gpu<'_> {
    /// Runs `work`'s tiles through their passes on `res`, two slots in
    /// flight, handing each finished tile's texels to `sink` (the rect, its
    /// texels, and the texels from one row's start to the next): as each
    /// tile finishes, or all at the end where they are gathered on the
    /// device (`job::gather_bytes`). Returns the most passes a tile needed
    /// (for the renderer's next start, `Render` only). A failed run can
    /// leave passes in flight: `settle` waits for them.
    pub(super) fn run(
        &self,
        work: &Work,
        res: &mut Resources,
        progress: &(dyn Fn(u64, u64) + Sync),
        sink: &mut TileSink,
    ) -> Result<(Timings, Option<u32>), GpuError> {
        let Work {
            scene,
            camera,
            options,
            job,
            rects,
            start_passes,
            cancel,
            frame: target,
            ..
        } = *work;
        let mut timings = Timings::default();
        let tile_edge = tile_edge(options.tile_size);
        let (kernel, tiles, out_texels) = job_tiles(job, scene, camera, options, rects);
        let pack = Packing::of(job, options);
        let texel_bytes = pack.map_or(TEXEL_BYTES, Packing::bytes);
        let size = [camera.width, camera.height];
        let gather = self.gather(res, job, pack, options, camera)?;
        let (lists, key) = self.upload_job(work, res, kernel, out_texels, pack, &mut timings)?;
        // Tiles finished whose texels wait in the gathered image.
        let mut gathered: Vec<TileRect> = Vec::new();
        let mut pipelines = TilePipelines {
            key,
            built: [None; 2],
        };
        let mut in_flight: VecDeque<(usize, TileWork)> = VecDeque::new();
        let total_pixels: u64 = tiles.iter().map(|t| u64::from(t.size[0] * t.size[1])).sum();
        let mut tally = Tally::default();
        let mut starts = Starts {
            // Probes keep no state and run once: they never start resumable.
            resumable: kernel == Kernel::Render && (start_passes > 1 || !options.one_pass_first),
            last: start_passes,
            // The window cancels between passes: it keeps a wait a pass.
            max_chain: match cancel {
                Some(_) => 1,
                None => options.chain_passes.clamp(1, MAX_CHAIN),
            },
            budget: options.pass_budget,
            needed: false,
            most: 0,
        };
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
                        (s, starts.tile(rect))
                    }
                };
                let p = pipelines.get(self, &work, &mut timings)?;
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
                    Copies {
                        target,
                        pack: packing,
                        gather,
                    },
                )?;
                tally.passes += u64::from(work.chain);
                in_flight.push_back((s, work));
            }
            let Some((s, mut work)) = in_flight.pop_front() else {
                break;
            };
            self.wait(&mut res.slots[s], work, options)?;
            let slot = &res.slots[s];
            tally.waits += 1;
            if cancelled() {
                free.push(s);
                continue;
            }
            match self.dispatch_time(slot, work.chain) {
                Some(t) => tally.device_time += t,
                None => tally.timed_by_device = false,
            }
            let report = |t: &Tally| progress(t.done_pixels, total_pixels);
            let (done, needs) = after_passes(
                &mut work,
                slot,
                (kernel, camera.width),
                starts.max_chain,
                &mut tally,
                &report,
            )?;
            starts.needed |= needs;
            if !done {
                again = Some((s, work));
                continue;
            }
            if gather.is_some() {
                gathered.push(work.rect);
            } else {
                let n = match job {
                    Job::Image(_) | Job::Rects => u64::from(work.rect.size[0] * work.rect.size[1]),
                    Job::Pixel(_) => out_texels,
                };
                read_tile(slot, work.rect, n * texel_bytes, sink, &mut tally);
            }
            tally.rays[0] += work.rays[0];
            tally.rays[1] += work.rays[1];
            tally.done_pixels += u64::from(work.left);
            starts.most = starts.most.max(work.pass);
            report(&tally);
            free.push(s);
        }
        if cancelled() {
            return Err(GpuError::Cancelled);
        }
        if gather.is_some() {
            read_gathered(res, (job, size, texel_bytes), &gathered, sink, &mut tally);
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
        let needed = starts.passes_needed();
        Ok((timings, (kernel == Kernel::Render).then_some(needed)))
    }

    /// The image-sized readback buffer `job`'s tiles are gathered into,
    /// where they are (`job::gather_bytes`).
    fn gather(
        &self,
        res: &mut Resources,
        job: Job,
        pack: Option<Packing>,
        options: &GpuRenderOptions,
        camera: &Camera,
    ) -> Result<Option<Gather>, GpuError> {
        let size = [camera.width, camera.height];
        let Some(bytes) = gather_bytes(job, pack, options, size, self.shared.limits.max_allocation)
        else {
            return Ok(None);
        };
        Ok(Some(Gather {
            buffer: res.gathered.at_least(self.shared, bytes)?.raw,
            width: camera.width,
        }))
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
        // A tile's texels cross to the host as `pack` makes them.
        let readback = pack.map_or(out_bytes, |p| p.buffer_bytes(out_texels));
        for slot in &mut res.slots {
            slot.readback.at_least(self.shared, readback)?;
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

/// Each pipeline is built when a tile first needs it: the one-pass shader
/// for a tile's first try, the resumable one after it
/// (`TileWork::resumable`); a probe's is `key`'s.
struct TilePipelines {
    key: PipelineKey,
    built: [Option<vk::Pipeline>; 2],
}

impl TilePipelines {
    fn get(
        &mut self,
        gpu: &Gpu,
        work: &TileWork,
        timings: &mut Timings,
    ) -> Result<vk::Pipeline, GpuError> {
        let slot = &mut self.built[usize::from(work.resumable)];
        if let Some(p) = *slot {
            return Ok(p);
        }
        let (p, build_time, _) = gpu.pipeline.get(PipelineKey {
            one_pass: self.key.one_pass && !work.resumable,
            ..self.key
        })?;
        if !build_time.is_zero() {
            timings.add("pipeline", build_time);
        }
        *slot = Some(p);
        Ok(p)
    }
}

/// Hands a finished tile's `bytes` of texels, as its slot read them back,
/// to `sink`.
fn read_tile(slot: &Slot, rect: TileRect, bytes: u64, sink: &mut TileSink, tally: &mut Tally) {
    tally.read(|| {
        let texels = &slot.readback.get().mapped()[..bytes as usize];
        sink(rect, texels, rect.size[0] as usize);
        bytes
    });
}

/// Hands the gathered image to `sink`: whole for a whole image, else each
/// finished tile in its place (the buffer outside them holds older
/// renders).
fn read_gathered(
    res: &Resources,
    (job, [width, height], texel_bytes): (Job, [u32; 2], u64),
    tiles: &[TileRect],
    sink: &mut TileSink,
    tally: &mut Tally,
) {
    tally.read(|| {
        let image = u64::from(width) * u64::from(height) * texel_bytes;
        let mapped = &res.gathered.get().mapped()[..image as usize];
        let stride = width as usize;
        if matches!(job, Job::Image(_)) {
            let whole = TileRect {
                origin: [0, 0],
                size: [width, height],
            };
            sink(whole, mapped, stride);
            return image;
        }
        let mut read = 0;
        for &rect in tiles {
            let [x, y] = rect.origin.map(u64::from);
            let at = ((y * u64::from(width) + x) * texel_bytes) as usize;
            sink(rect, &mapped[at..], stride);
            read += u64::from(rect.size[0] * rect.size[1]) * texel_bytes;
        }
        read
    });
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
