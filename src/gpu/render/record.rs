//! A pass's command buffer: the status reset, the tile's dispatch between
//! timestamps, the pack to 8-bit pixels, the copies to the readback buffer
//! and the window, its submission, and waiting for it.

use std::time::Duration;

use ash::vk;

use super::job::{GpuRenderOptions, Job, Packing, TileRect, TileWork, TEXEL_BYTES};
use super::resources::{Gpu, Slot};
use crate::gpu::bindings::Lists;
use crate::gpu::commands::{begin, memory_barrier};
use crate::gpu::error::{GpuError, VkResultExt};
use crate::gpu::present::FrameTarget;
use crate::gpu::small_pipeline::SmallPipeline;
use crate::layout::{GpuStatus, GpuTile, WORKGROUP_SIZE};

/// Where a pass's texels go after its dispatch.
#[derive(Clone, Copy)]
pub(super) struct Copies<'a> {
    /// The window's image (`gpu::present`).
    pub(super) target: Option<FrameTarget>,
    /// The pack's shader, its set (the slot's index) and what it makes.
    pub(super) pack: Option<(&'a SmallPipeline, usize, Packing)>,
    /// The image the tile is copied into its place in.
    pub(super) gather: Option<Gather>,
}

/// The image-sized readback buffer a render's tiles are copied into
/// (`job::gather_bytes`), and the image's width.
#[derive(Clone, Copy)]
pub(super) struct Gather {
    pub(super) buffer: vk::Buffer,
    pub(super) width: u32,
}

impl Gather {
    /// The copies that put a packed tile's rows (`bytes` a pixel) in their
    /// place: one where the tile spans the image's width.
    pub(super) fn regions(self, rect: TileRect, bytes: u64) -> Vec<vk::BufferCopy> {
        let [x0, y0] = rect.origin.map(u64::from);
        let [w, h] = rect.size.map(u64::from);
        let width = u64::from(self.width);
        let (rows, row_bytes) = if x0 == 0 && w == width {
            (1, w * h * bytes)
        } else {
            (h, w * bytes)
        };
        (0..rows)
            .map(|row| vk::BufferCopy {
                src_offset: row * row_bytes,
                dst_offset: ((y0 + row) * width + x0) * bytes,
                size: row_bytes,
            })
            .collect()
    }
}

/// `shaders/pack.wgsl`'s workgroup size: 2048^2 texels, the largest tile,
/// stay within 65,535 workgroups.
const PACK_GROUP: u64 = 256;

impl Gpu<'_> {
    /// The device time of the slot's last `chain` dispatches, from their
    /// timestamps.
    pub(super) fn dispatch_time(&self, slot: &Slot, chain: u32) -> Option<Duration> {
        if slot.queries == vk::QueryPool::null() {
            return None;
        }
        (0..chain).map(|i| self.one_dispatch_time(slot, i)).sum()
    }

    fn one_dispatch_time(&self, slot: &Slot, i: u32) -> Option<Duration> {
        let mut ticks = [0u64; 2];
        // SAFETY: both queries were written by a pass just waited for.
        unsafe {
            self.shared.device.get_query_pool_results(
                slot.queries,
                slot.first_query + 2 * i,
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
        copies: Copies,
    ) -> Result<(), GpuError> {
        let shared = &self.shared;
        let device = &shared.device;
        let rect = work.rect;
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
        // The tile's passes in flight, each its own submission (so none
        // runs longer than one pass's budget) with its own fence, queued
        // back to back: the host waits once for all of them (`wait`).
        let chain = work.chain as usize;
        // SAFETY: the slot's previous submissions were waited for before
        // this reuse; all handles are live.
        unsafe {
            device
                .reset_fences(&slot.fences[..chain])
                .call("vkResetFences")?;
            for i in 0..chain {
                let command = slot.commands[i];
                begin(device, command)?;
                let tile = GpuTile {
                    origin: rect.origin,
                    size: rect.size,
                    budget: work.budget,
                    first: u32::from(work.pass + i as u32 == 1),
                    _pad: [0; 2],
                };
                self.record_dispatch(slot, (i, tile), pipeline, lists, groups);
                // Only the last pass's texels are read: a pixel finished in
                // an earlier one is left as it is by the passes after it.
                if i + 1 == chain {
                    self.record_readback(slot, command, copies, texels, rect);
                }
                device
                    .end_command_buffer(command)
                    .call("vkEndCommandBuffer")?;
                let cmds = [command];
                let submit = vk::SubmitInfo::default().command_buffers(&cmds);
                if let Some(r) = crate::gpu::fault::at_submit() {
                    // Test-only (`GLINT_FAULT`): the command buffer is left
                    // recorded and unsubmitted, as after a real failure.
                    return Err(self.fail(r, work, "vkQueueSubmit", 0));
                }
                device
                    .queue_submit(shared.queue, &[submit], slot.fences[i])
                    .map_err(|r| self.fail(r, work, "vkQueueSubmit", 0))?;
                slot.submitted = i + 1;
            }
        }
        Ok(())
    }

    /// Records into the slot's command buffer for its `i`th pass in
    /// flight: the wait for the passes before it, the status reset and the
    /// pass's `tile` uniform, the tile's dispatch between timestamps (where
    /// the device has them), and the copy of its status into the slot's log.
    fn record_dispatch(
        &self,
        slot: &Slot,
        (i, tile): (usize, GpuTile),
        pipeline: vk::Pipeline,
        lists: Lists,
        groups: [u32; 2],
    ) {
        let device = &self.shared.device;
        let command = slot.commands[i];
        let reset = GpuStatus::RESET;
        let words: [u32; std::mem::size_of::<GpuStatus>() / 4] = bytemuck::cast(reset);
        let status_bytes = std::mem::size_of::<GpuStatus>() as u64;
        let queries = slot.first_query + 2 * i as u32;
        let compute = vk::PipelineStageFlags::COMPUTE_SHADER;
        let transfer = vk::PipelineStageFlags::TRANSFER;
        // SAFETY: the command buffer is recording (`submit_pass`), the
        // slot's earlier submissions waited for or queued before it; every
        // handle is live.
        unsafe {
            // The pass before it in the queue (this tile's, chained) wrote
            // the pixel state and read the status and the tile.
            memory_barrier(
                device,
                command,
                (
                    compute | transfer,
                    vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE,
                ),
                (
                    compute | transfer,
                    vk::AccessFlags::SHADER_READ
                        | vk::AccessFlags::SHADER_WRITE
                        | vk::AccessFlags::TRANSFER_WRITE,
                ),
            );
            // The status starts each pass at RESET: the counters at 0 and
            // first_cut at u32::MAX (a fill per word). The tile is written
            // here, not by the host: chained passes differ in `first`.
            for (k, &w) in words.iter().enumerate() {
                device.cmd_fill_buffer(command, slot.status.raw, 4 * k as u64, 4, w);
            }
            device.cmd_update_buffer(command, slot.tile.raw, 0, bytemuck::bytes_of(&tile));
            memory_barrier(
                device,
                command,
                (transfer, vk::AccessFlags::TRANSFER_WRITE),
                (
                    compute,
                    vk::AccessFlags::SHADER_READ
                        | vk::AccessFlags::SHADER_WRITE
                        | vk::AccessFlags::UNIFORM_READ,
                ),
            );
            device.cmd_bind_pipeline(command, vk::PipelineBindPoint::COMPUTE, pipeline);
            device.cmd_bind_descriptor_sets(
                command,
                vk::PipelineBindPoint::COMPUTE,
                self.pipeline.layout(lists).pipeline,
                0,
                &[slot.sets[lists.index()]],
                &[],
            );
            if slot.queries != vk::QueryPool::null() {
                device.cmd_reset_query_pool(command, slot.queries, queries, 2);
                device.cmd_write_timestamp(
                    command,
                    vk::PipelineStageFlags::TOP_OF_PIPE,
                    slot.queries,
                    queries,
                );
            }
            device.cmd_dispatch(command, groups[0], groups[1], 1);
            if slot.queries != vk::QueryPool::null() {
                device.cmd_write_timestamp(command, compute, slot.queries, queries + 1);
            }
            memory_barrier(
                device,
                command,
                (compute, vk::AccessFlags::SHADER_WRITE),
                (
                    compute | transfer,
                    vk::AccessFlags::SHADER_READ | vk::AccessFlags::TRANSFER_READ,
                ),
            );
            device.cmd_copy_buffer(
                command,
                slot.status.raw,
                slot.log.raw,
                &[vk::BufferCopy {
                    src_offset: 0,
                    dst_offset: i as u64 * status_bytes,
                    size: status_bytes,
                }],
            );
            memory_barrier(
                device,
                command,
                (transfer, vk::AccessFlags::TRANSFER_WRITE),
                (vk::PipelineStageFlags::HOST, vk::AccessFlags::HOST_READ),
            );
        }
    }

    /// Records the copy of the tile's texels (packed first where `pack`:
    /// 8-bit pixels or f32 RGB) into the slot's readback buffer, or row by
    /// row into their place in the image's (`gather`); row by row into the
    /// window's image where there is one; then the barrier before the host
    /// reads.
    fn record_readback(
        &self,
        slot: &Slot,
        command: vk::CommandBuffer,
        Copies {
            target,
            pack,
            gather,
        }: Copies,
        texels: u64,
        rect: TileRect,
    ) {
        let device = &self.shared.device;
        let bytes = texels * TEXEL_BYTES;
        // SAFETY: as `record_dispatch`.
        unsafe {
            let (read_from, size) = match pack {
                Some((pipeline, set, packing)) => {
                    // The tile's texels as the file needs them: 3 (8-bit)
                    // or 12 (f32 RGB) bytes a pixel cross to the host, not
                    // a texel's 16.
                    let groups = packing
                        .invocations(texels)
                        .div_ceil(PACK_GROUP)
                        .min(u64::from(u32::MAX)) as u32;
                    pipeline.dispatch(command, set, [groups, 1]);
                    memory_barrier(
                        device,
                        command,
                        (
                            vk::PipelineStageFlags::COMPUTE_SHADER,
                            vk::AccessFlags::SHADER_WRITE,
                        ),
                        (
                            vk::PipelineStageFlags::TRANSFER,
                            vk::AccessFlags::TRANSFER_READ,
                        ),
                    );
                    (slot.packed.get().raw, packing.buffer_bytes(texels))
                }
                None => (slot.output.get().raw, bytes),
            };
            match (gather, pack) {
                (Some(gather), Some((_, _, packing))) => {
                    let regions = gather.regions(rect, packing.bytes());
                    device.cmd_copy_buffer(command, read_from, gather.buffer, &regions);
                }
                _ => device.cmd_copy_buffer(
                    command,
                    read_from,
                    slot.readback.get().raw,
                    &[vk::BufferCopy {
                        src_offset: 0,
                        dst_offset: 0,
                        size,
                    }],
                ),
            }
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
                device.cmd_copy_buffer(command, slot.output.get().raw, target.buffer, &rows);
            }
            memory_barrier(
                device,
                command,
                (
                    vk::PipelineStageFlags::TRANSFER,
                    vk::AccessFlags::TRANSFER_WRITE,
                ),
                (vk::PipelineStageFlags::HOST, vk::AccessFlags::HOST_READ),
            );
        }
    }

    /// Waits, once, for the slot's passes in flight: each may take
    /// `options.pass_timeout`.
    pub(super) fn wait(
        &self,
        slot: &mut Slot,
        work: TileWork,
        options: &GpuRenderOptions,
    ) -> Result<(), GpuError> {
        let (limit, waited) = self.wait_submitted(slot, options);
        waited.map_err(|r| self.fail(r, work, "vkWaitForFences", limit.as_secs()))
    }

    /// After a failed render, waits for the passes it left in flight (the
    /// other slot's, or those queued before a failed submission), so that
    /// the next render may reset their fences; errors are the failure's
    /// own, already reported.
    pub(super) fn settle(&self, slots: &mut [Slot], options: &GpuRenderOptions) {
        if self.shared.is_poisoned() {
            return;
        }
        for slot in slots.iter_mut().filter(|s| s.submitted > 0) {
            if self.wait_submitted(slot, options).1.is_err() {
                // Not waited for: the device is no longer trusted.
                self.shared.poison();
            }
        }
    }

    /// Waits for the slot's submitted passes, `options.pass_timeout` each:
    /// the time allowed, and the wait's result.
    fn wait_submitted(
        &self,
        slot: &mut Slot,
        options: &GpuRenderOptions,
    ) -> (Duration, Result<(), vk::Result>) {
        let n = slot.submitted;
        let limit = options.pass_timeout.saturating_mul(n as u32);
        let timeout = limit.as_nanos().min(u128::from(u64::MAX)) as u64;
        // SAFETY: the fences belong to this device and were submitted.
        let waited = unsafe {
            self.shared
                .device
                .wait_for_fences(&slot.fences[..n], true, timeout)
        };
        if waited.is_ok() {
            slot.submitted = 0;
        }
        (limit, waited)
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
