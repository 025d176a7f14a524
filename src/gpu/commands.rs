//! One-off command submission: a command buffer of its own pool with a
//! fence, and a record-submit-wait round for work the host waits for.

use ash::vk;

use super::context::Shared;
use super::error::{GpuError, VkResultExt};

/// A pool of resettable command buffers on the device's queue family; the
/// caller destroys it.
pub(crate) fn command_pool(shared: &Shared) -> Result<vk::CommandPool, GpuError> {
    // SAFETY: a valid create info on a live device.
    unsafe {
        shared.device.create_command_pool(
            &vk::CommandPoolCreateInfo::default()
                .queue_family_index(shared.queue_family)
                .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
            None,
        )
    }
    .call("vkCreateCommandPool")
}

/// A resettable command buffer of its own pool, and a fence.
pub(crate) fn command_and_fence(
    shared: &Shared,
) -> Result<(vk::CommandPool, vk::CommandBuffer, vk::Fence), GpuError> {
    let device = &shared.device;
    let pool = command_pool(shared)?;
    // SAFETY: valid create infos on a live device; the caller destroys them.
    unsafe {
        let command = device
            .allocate_command_buffers(
                &vk::CommandBufferAllocateInfo::default()
                    .command_pool(pool)
                    .level(vk::CommandBufferLevel::PRIMARY)
                    .command_buffer_count(1),
            )
            .call("vkAllocateCommandBuffers")?[0];
        let fence = device
            .create_fence(&vk::FenceCreateInfo::default(), None)
            .call("vkCreateFence")?;
        Ok((pool, command, fence))
    }
}

/// Records, submits (waiting on `wait` at the transfer stage, signalling
/// `signal`) and waits for the fence: for small work whose buffers the
/// next use needs free (uploads, the window's resolve and copies).
pub(crate) fn submit_and_wait(
    shared: &Shared,
    (command, fence): (vk::CommandBuffer, vk::Fence),
    (wait, signal): (&[vk::Semaphore], &[vk::Semaphore]),
    timeout_ns: u64,
    record: impl FnOnce(vk::CommandBuffer),
) -> Result<(), GpuError> {
    let device = &shared.device;
    let stages = vec![vk::PipelineStageFlags::TRANSFER; wait.len()];
    // SAFETY: the command buffer and fence are idle (the last submit was
    // waited for); every handle is live.
    unsafe {
        begin(device, command)?;
        record(command);
        device
            .end_command_buffer(command)
            .call("vkEndCommandBuffer")?;
        let commands = [command];
        let submit = vk::SubmitInfo::default()
            .command_buffers(&commands)
            .wait_semaphores(wait)
            .wait_dst_stage_mask(&stages)
            .signal_semaphores(signal);
        device.reset_fences(&[fence]).call("vkResetFences")?;
        device
            .queue_submit(shared.queue, &[submit], fence)
            .call("vkQueueSubmit")?;
        device
            .wait_for_fences(&[fence], true, timeout_ns)
            .call("vkWaitForFences")?;
    }
    Ok(())
}

/// Resets `command` and begins recording it for one submission.
///
/// # Safety
/// `command` is idle (its last submission waited for) and its pool is used
/// by this thread alone.
pub(crate) unsafe fn begin(
    device: &ash::Device,
    command: vk::CommandBuffer,
) -> Result<(), GpuError> {
    // SAFETY: as the caller promises.
    unsafe {
        device
            .reset_command_buffer(command, vk::CommandBufferResetFlags::empty())
            .call("vkResetCommandBuffer")?;
        device
            .begin_command_buffer(
                command,
                &vk::CommandBufferBeginInfo::default()
                    .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )
            .call("vkBeginCommandBuffer")
    }
}

/// A global memory barrier in `cmd`: the writes `src` (stages, accesses)
/// made before it, visible to `dst`'s after it.
///
/// # Safety
/// `cmd` is a command buffer of `device` in the recording state.
pub(crate) unsafe fn memory_barrier(
    device: &ash::Device,
    cmd: vk::CommandBuffer,
    (src_stages, src_access): (vk::PipelineStageFlags, vk::AccessFlags),
    (dst_stages, dst_access): (vk::PipelineStageFlags, vk::AccessFlags),
) {
    let barrier = vk::MemoryBarrier::default()
        .src_access_mask(src_access)
        .dst_access_mask(dst_access);
    device.cmd_pipeline_barrier(
        cmd,
        src_stages,
        dst_stages,
        vk::DependencyFlags::empty(),
        &[barrier],
        &[],
        &[],
    );
}
