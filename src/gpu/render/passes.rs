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
    tile_edge, tile_texels, tiles, GpuRenderOptions, Job, TileRect, TileWork, BUDGET_BACKOFF,
    B_FRAME, B_OUTPUT, B_STATE, PACKED_BYTES, PATH_MAX_LIGHTS, RESUMABLE_REDOS, SLOTS, TEXEL_BYTES,
};
use super::plan::{capped, check_limits, key, scene_uploads, upload};
use super::resources::{scene_buffer, Gpu, Resources, Slot};
use crate::camera::Camera;
use crate::gpu::bindings::Lists;
use crate::gpu::commands::memory_barrier;
use crate::gpu::error::{GpuError, VkResultExt};
use crate::gpu::pipeline::{Kernel, PipelineKey};
use crate::gpu::present::FrameTarget;
use crate::gpu::small_pipeline::SmallPipeline;

/// `shaders/pack.wgsl`'s workgroup size: 2048^2 texels, the largest tile,
/// stay within 65,535 workgroups.
const PACK_GROUP: u64 = 256;
use crate::layout::{
    uniform_copy, GpuPixelState, GpuScene, GpuStatus, GpuTile, ADDRESS_LISTS, PATH_HEADER,
    PATH_PER_LIGHT, UNIFORM_FIRST, UNIFORM_LISTS, WORKGROUP_SIZE,
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
            background,
            options,
            job,
            rects,
            start_resumable,
            cancel,
            frame: target,
        } = *work;
        let mut timings = Timings::default();
        let tile_edge = tile_edge(options.tile_size);
        let (kernel, tiles, out_texels) = match job {
            Job::Image(kernel) => (
                kernel,
                tiles(camera.width, camera.height, tile_edge),
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
        };
        let state_bytes = match kernel {
            Kernel::Render => out_texels * std::mem::size_of::<GpuPixelState>() as u64,
            _ => std::mem::size_of::<GpuPixelState>() as u64,
        };
        let out_bytes = out_texels * TEXEL_BYTES;
        // 8-bit pixels packed on the device, for colour jobs that ask.
        let pack = options.pack_rgb8 && matches!(job, Job::Image(Kernel::Render) | Job::Rects);
        let texel_bytes = if pack { PACKED_BYTES } else { TEXEL_BYTES };
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
        if pack {
            self.bind_pack(res, out_texels)?;
        }
        timings.add("upload", upload_start.elapsed());
        timings.count(UPLOADED_BYTES, uploaded);

        let mut in_flight: VecDeque<(usize, TileWork)> = VecDeque::new();
        let total_pixels: u64 = tiles.iter().map(|t| u64::from(t.size[0] * t.size[1])).sum();
        let mut done_pixels = 0u64;
        let mut rays = [0u64; 2];
        let mut device_time = Duration::ZERO;
        let mut timed_by_device = true;
        let mut readback = Duration::ZERO;
        // What the host reads of finished tiles (status words left out).
        let mut readback_bytes = 0u64;
        let mut passes = 0u64;
        let mut retries = 0u64;
        let mut redone = 0u64;
        // Probes keep no state and run once: they never start resumable.
        let start_resumable =
            kernel == Kernel::Render && (start_resumable || !options.one_pass_first);
        let mut needed_passes = false;
        let dispatch_start = Instant::now();
        let mut next_tile = tiles.iter();
        let mut free: Vec<usize> = (0..SLOTS).rev().collect();
        let cancelled = || cancel.is_some_and(|c| c.load(Ordering::Relaxed));
        loop {
            // Fill every free slot with a new tile (none once cancelled:
            // the tiles in flight are only waited for).
            while let (false, Some(&s)) = (cancelled(), free.last()) {
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
                let p = pipeline_for(&work, &mut timings)?;
                let packing = res.pack.as_ref().filter(|_| pack).map(|p| (p, s));
                self.submit_pass(
                    &mut res.slots[s],
                    p,
                    (lists, job),
                    work,
                    out_texels,
                    (target, packing),
                )?;
                passes += 1;
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
                Some(t) => device_time += t,
                None => timed_by_device = false,
            }
            let status: GpuStatus =
                *bytemuck::from_bytes(&slot.status.mapped()[..std::mem::size_of::<GpuStatus>()]);
            if status.cut > 0 {
                let width = camera.width.max(1);
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
                done_pixels -= u64::from(size - work.left);
                work.left = size;
                work.rays = [0; 2];
                retries += 1;
            } else if status.remaining > 0 && kernel == Kernel::Render && !work.resumable {
                // The pass kept no state to resume from: redo the tile.
                work.resumable = true;
                needed_passes = true;
                work.pass = 1;
                work.left = work.rect.size[0] * work.rect.size[1];
                work.rays = [0; 2];
                redone += 1;
                // Every pass reports, this one with no pixel finished.
                progress(done_pixels, total_pixels);
            } else if status.remaining > 0 && kernel == Kernel::Render {
                needed_passes = true;
                work.rays[0] += u64::from(status.closest_rays);
                work.rays[1] += u64::from(status.shadow_rays);
                work.pass += 1;
                done_pixels += u64::from(work.left.saturating_sub(status.remaining));
                work.left = status.remaining.min(work.left);
                progress(done_pixels, total_pixels);
            } else {
                let start = Instant::now();
                let n = match job {
                    Job::Image(_) | Job::Rects => u64::from(work.rect.size[0] * work.rect.size[1]),
                    Job::Pixel(_) => out_texels,
                };
                let bytes = (n * texel_bytes) as usize;
                sink(work.rect, &slot.readback.get().mapped()[..bytes]);
                readback += start.elapsed();
                readback_bytes += bytes as u64;
                rays[0] += work.rays[0] + u64::from(status.closest_rays);
                rays[1] += work.rays[1] + u64::from(status.shadow_rays);
                done_pixels += u64::from(work.left);
                progress(done_pixels, total_pixels);
                free.push(s);
                continue;
            }
            let p = pipeline_for(&work, &mut timings)?;
            let packing = res.pack.as_ref().filter(|_| pack).map(|p| (p, s));
            self.submit_pass(
                &mut res.slots[s],
                p,
                (lists, job),
                work,
                out_texels,
                (target, packing),
            )?;
            passes += 1;
            in_flight.push_back((s, work));
        }
        if cancelled() {
            return Err(GpuError::Cancelled);
        }
        timings.add(
            "dispatch",
            dispatch_start.elapsed().saturating_sub(readback),
        );
        timings.add("readback", readback);
        timings.count(READBACK_BYTES, readback_bytes);
        timings.count("passes", passes);
        if timed_by_device {
            timings.count(GPU_TIME_NS, device_time.as_nanos() as u64);
        }
        // A pass's counters are 32-bit: counts that may have wrapped are
        // left out rather than shown wrong.
        let most_per_pass =
            u64::from(tile_edge) * u64::from(tile_edge) * u64::from(options.pass_budget);
        if kernel == Kernel::Render && most_per_pass <= u64::from(u32::MAX) {
            timings.count(CLOSEST_RAYS, rays[0]);
            timings.count(SHADOW_RAYS, rays[1]);
        }
        match lists {
            Lists::Split => timings.count("split lists", 1),
            Lists::Uniform => timings.count("uniform lists", 1),
            Lists::Address => timings.count("address lists", 1),
            Lists::Plain => {}
        }
        if key.corners {
            timings.count("uniform corners", 1);
        }
        if retries > 0 {
            // Tiles redone with a smaller budget after a pass was cut short.
            timings.count("retries", retries);
        }
        if redone > 0 {
            // Tiles redone with the resumable shader after a one-pass try.
            timings.count(RESUMABLE_REDOS, redone);
        }
        Ok((timings, (kernel == Kernel::Render).then_some(needed_passes)))
    }

    /// The device time of the slot's last dispatch, from its timestamps.
    pub(super) fn dispatch_time(&self, slot: &Slot) -> Option<Duration> {
        if slot.queries == vk::QueryPool::null() {
            return None;
        }
        let mut ticks = [0u64; 2];
        // SAFETY: both queries were written by the pass just waited for.
        unsafe {
            self.shared.device.get_query_pool_results(
                slot.queries,
                slot.first_query,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64,
            )
        }
        .ok()?;
        let limits = &self.shared.limits;
        let mask = if limits.timestamp_bits >= 64 {
            u64::MAX
        } else {
            (1u64 << limits.timestamp_bits) - 1
        };
        let elapsed = ticks[1].wrapping_sub(ticks[0]) & mask;
        Some(Duration::from_secs_f64(
            elapsed as f64 * f64::from(limits.timestamp_period) * 1e-9,
        ))
    }

    pub(super) fn submit_pass(
        &self,
        slot: &mut Slot,
        pipeline: vk::Pipeline,
        (lists, job): (Lists, Job),
        work: TileWork,
        out_texels: u64,
        (target, pack): (Option<FrameTarget>, Option<(&SmallPipeline, usize)>),
    ) -> Result<(), GpuError> {
        let shared = &self.shared;
        let device = &shared.device;
        let rect = work.rect;
        let tile = GpuTile {
            origin: rect.origin,
            size: rect.size,
            budget: work.budget,
            first: u32::from(work.pass == 1),
            _pad: [0; 2],
        };
        slot.tile.write(bytemuck::bytes_of(&tile));
        let (groups, texels) = match job {
            Job::Image(_) | Job::Rects => (
                [
                    rect.size[0].div_ceil(WORKGROUP_SIZE),
                    rect.size[1].div_ceil(WORKGROUP_SIZE),
                ],
                u64::from(rect.size[0]) * u64::from(rect.size[1]),
            ),
            Job::Pixel(_) => ([1, 1], out_texels),
        };
        let max = shared.limits.max_group_count;
        if groups[0] > max[0] || groups[1] > max[1] {
            return Err(GpuError::Limit {
                what: "workgroups per dispatch".into(),
                needed: u64::from(groups[0].max(groups[1])),
                limit_name: "maxComputeWorkGroupCount",
                limit: u64::from(max[0].min(max[1])),
                unit: "",
                hint: "use a smaller --tile".into(),
            });
        }
        let reset = GpuStatus::RESET;
        let words: [u32; std::mem::size_of::<GpuStatus>() / 4] = bytemuck::cast(reset);
        let bytes = texels * TEXEL_BYTES;
        // SAFETY: the slot's previous submission was waited for before this
        // reuse; all handles are live.
        unsafe {
            device.reset_fences(&[slot.fence]).call("vkResetFences")?;
            device
                .reset_command_buffer(slot.command, vk::CommandBufferResetFlags::empty())
                .call("vkResetCommandBuffer")?;
            device
                .begin_command_buffer(
                    slot.command,
                    &vk::CommandBufferBeginInfo::default()
                        .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )
                .call("vkBeginCommandBuffer")?;
            // The status starts each pass at RESET: the counters at 0 and
            // first_cut at u32::MAX (a fill per word).
            for (i, &w) in words.iter().enumerate() {
                device.cmd_fill_buffer(slot.command, slot.status.raw, 4 * i as u64, 4, w);
            }
            memory_barrier(
                device,
                slot.command,
                (
                    vk::PipelineStageFlags::TRANSFER,
                    vk::AccessFlags::TRANSFER_WRITE,
                ),
                (
                    vk::PipelineStageFlags::COMPUTE_SHADER,
                    vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
                ),
            );
            device.cmd_bind_pipeline(slot.command, vk::PipelineBindPoint::COMPUTE, pipeline);
            device.cmd_bind_descriptor_sets(
                slot.command,
                vk::PipelineBindPoint::COMPUTE,
                self.pipeline.layout(lists).pipeline,
                0,
                &[slot.sets[lists.index()]],
                &[],
            );
            if slot.queries != vk::QueryPool::null() {
                device.cmd_reset_query_pool(slot.command, slot.queries, slot.first_query, 2);
                device.cmd_write_timestamp(
                    slot.command,
                    vk::PipelineStageFlags::TOP_OF_PIPE,
                    slot.queries,
                    slot.first_query,
                );
            }
            device.cmd_dispatch(slot.command, groups[0], groups[1], 1);
            if slot.queries != vk::QueryPool::null() {
                device.cmd_write_timestamp(
                    slot.command,
                    vk::PipelineStageFlags::COMPUTE_SHADER,
                    slot.queries,
                    slot.first_query + 1,
                );
            }
            memory_barrier(
                device,
                slot.command,
                (
                    vk::PipelineStageFlags::COMPUTE_SHADER,
                    vk::AccessFlags::SHADER_WRITE,
                ),
                (
                    vk::PipelineStageFlags::COMPUTE_SHADER
                        | vk::PipelineStageFlags::TRANSFER
                        | vk::PipelineStageFlags::HOST,
                    vk::AccessFlags::SHADER_READ
                        | vk::AccessFlags::TRANSFER_READ
                        | vk::AccessFlags::HOST_READ,
                ),
            );
            let (read_from, size) = match pack {
                Some((pipeline, set)) => {
                    // The tile's texels as 8-bit pixels: a quarter of the
                    // bytes cross to the host.
                    let groups = texels.div_ceil(PACK_GROUP).min(u64::from(u32::MAX)) as u32;
                    pipeline.dispatch(slot.command, set, [groups, 1]);
                    memory_barrier(
                        device,
                        slot.command,
                        (
                            vk::PipelineStageFlags::COMPUTE_SHADER,
                            vk::AccessFlags::SHADER_WRITE,
                        ),
                        (
                            vk::PipelineStageFlags::TRANSFER,
                            vk::AccessFlags::TRANSFER_READ,
                        ),
                    );
                    (slot.packed.get().raw, texels * PACKED_BYTES)
                }
                None => (slot.output.get().raw, bytes),
            };
            device.cmd_copy_buffer(
                slot.command,
                read_from,
                slot.readback.get().raw,
                &[vk::BufferCopy {
                    src_offset: 0,
                    dst_offset: 0,
                    size,
                }],
            );
            if let Some(target) = target {
                // Row by row into the window's image (`gpu::present`): a
                // copy on the device, so the window's mean never crosses
                // to the host. The tile's last pass copies its final texels.
                let rows: Vec<vk::BufferCopy> = (0..rect.size[1])
                    .map(|row| vk::BufferCopy {
                        src_offset: u64::from(row * rect.size[0]) * TEXEL_BYTES,
                        dst_offset: (u64::from(rect.origin[1] + row) * u64::from(target.width)
                            + u64::from(rect.origin[0]))
                            * TEXEL_BYTES,
                        size: u64::from(rect.size[0]) * TEXEL_BYTES,
                    })
                    .collect();
                device.cmd_copy_buffer(slot.command, slot.output.get().raw, target.buffer, &rows);
            }
            memory_barrier(
                device,
                slot.command,
                (
                    vk::PipelineStageFlags::TRANSFER,
                    vk::AccessFlags::TRANSFER_WRITE,
                ),
                (vk::PipelineStageFlags::HOST, vk::AccessFlags::HOST_READ),
            );
            device
                .end_command_buffer(slot.command)
                .call("vkEndCommandBuffer")?;
            let cmds = [slot.command];
            let submit = vk::SubmitInfo::default().command_buffers(&cmds);
            if let Some(r) = crate::gpu::fault::at_submit() {
                // Test-only (`GLINT_FAULT`): the command buffer is left
                // recorded and unsubmitted, as after a real failure.
                return Err(self.fail(r, work, "vkQueueSubmit", 0));
            }
            device
                .queue_submit(shared.queue, &[submit], slot.fence)
                .map_err(|r| self.fail(r, work, "vkQueueSubmit", 0))?;
        }
        Ok(())
    }

    /// Waits for the slot's pass.
    pub(super) fn wait(
        &self,
        slot: &Slot,
        work: TileWork,
        options: &GpuRenderOptions,
    ) -> Result<(), GpuError> {
        let timeout = options.pass_timeout.as_nanos().min(u128::from(u64::MAX)) as u64;
        // SAFETY: the fence belongs to this device and was submitted.
        unsafe {
            self.shared
                .device
                .wait_for_fences(&[slot.fence], true, timeout)
        }
        .map_err(|r| self.fail(r, work, "vkWaitForFences", options.pass_timeout.as_secs()))
    }

    pub(super) fn fail(
        &self,
        result: vk::Result,
        work: TileWork,
        call: &'static str,
        seconds: u64,
    ) -> GpuError {
        let [x, y] = work.rect.origin;
        match result {
            vk::Result::TIMEOUT => {
                self.shared.poison();
                GpuError::Timeout {
                    x,
                    y,
                    pass: work.pass,
                    budget: work.budget,
                    seconds,
                }
            }
            vk::Result::ERROR_DEVICE_LOST => {
                self.shared.poison();
                GpuError::DeviceLost { call, x, y }
            }
            result => GpuError::Vk { call, result },
        }
    }
}
