//! A pass's command buffer: the status reset, the tile's dispatch between
//! timestamps, the pack to 8-bit pixels, the copies to the readback buffer
//! and the window, its submission, and waiting for it.

use std::time::Duration;

use ash::vk;

use super::job::{GpuRenderOptions, Job, Packing, TileRect, TileWork, TEXEL_BYTES};
use super::resources::{Gpu, Slot};
use crate::gpu::bindings::Lists;
use crate::gpu::commands::memory_barrier;
use crate::gpu::error::{GpuError, VkResultExt};
use crate::gpu::present::FrameTarget;
use crate::gpu::small_pipeline::SmallPipeline;
use crate::layout::{GpuStatus, GpuTile, WORKGROUP_SIZE};

/// `shaders/pack.wgsl`'s workgroup size: 2048^2 texels, the largest tile,
/// stay within 65,535 workgroups.
const PACK_GROUP: u64 = 256;

impl Gpu<'_> {
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
        (target, pack): (
            Option<FrameTarget>,
            Option<(&SmallPipeline, usize, Packing)>,
        ),
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
            self.record_dispatch(slot, pipeline, lists, groups);
            self.record_readback(slot, pack, texels, target, rect);
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

    /// Records into the slot's command buffer: the status reset, the
    /// tile's dispatch between timestamps (where the device has them), and
    /// the barrier that lets the copies and the host read its output.
    fn record_dispatch(&self, slot: &Slot, pipeline: vk::Pipeline, lists: Lists, groups: [u32; 2]) {
        let device = &self.shared.device;
        let reset = GpuStatus::RESET;
        let words: [u32; std::mem::size_of::<GpuStatus>() / 4] = bytemuck::cast(reset);
        // SAFETY: the slot's command buffer is recording (`submit_pass`),
        // its previous submission waited for; every handle is live.
        unsafe {
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
        }
    }

    /// Records the copy of the tile's texels (packed first where `pack`:
    /// 8-bit pixels or f32 RGB) into the slot's readback buffer, and row by row into
    /// the window's image where there is one, then the barrier before the
    /// host reads.
    fn record_readback(
        &self,
        slot: &Slot,
        pack: Option<(&SmallPipeline, usize, Packing)>,
        texels: u64,
        target: Option<FrameTarget>,
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
                    (slot.packed.get().raw, packing.buffer_bytes(texels))
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
        }
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
