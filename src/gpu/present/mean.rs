//! A progressive render's mean, kept on the device: the renderer copies
//! each pass's tiles into `pass_image` (`GpuRenderer::copy_passes_to`),
//! and `add_pass` folds them into the sums and packs the mean.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;

use crate::gpu::buffer::Buffer;
use crate::gpu::commands::{command_and_fence, memory_barrier, submit_and_wait};
use crate::gpu::context::{Context, Shared};
use crate::gpu::error::GpuError;
use crate::gpu::small_pipeline::SmallPipeline;
use crate::layout::{GpuResolve, WORKGROUP_SIZE};

/// The window's work (a resolve, a copy) is milliseconds; a device that
/// takes this long has hung, and the window says so instead of waiting.
pub(super) const WINDOW_WAIT_NS: u64 = 10_000_000_000;

pub const RESOLVE_WGSL: &str = include_str!("../../../shaders/resolve.wgsl");

/// Where a renderer copies each pass's tiles: a `width` x `height` image
/// of texels (RGB and 1 where rendered) on the device `device`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameTarget {
    pub(crate) device: vk::Device,
    pub(crate) buffer: vk::Buffer,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

/// The buffers of one view size.
struct Images {
    size: [u32; 2],
    pass: Buffer,
    sums: Buffer,
    shown: Buffer,
}

/// A progressive render's running mean on the device, packed to the
/// swapchain's bytes each pass (`gpu::present`).
pub struct DeviceMean {
    shared: Arc<Shared>,
    resolve: SmallPipeline,
    commands: vk::CommandPool,
    command: vk::CommandBuffer,
    fence: vk::Fence,
    params: Buffer,
    images: Option<Images>,
    bgra: bool,
}

impl DeviceMean {
    /// The resolve pipeline on `ctx`'s device; `bgra` is the swapchain's
    /// byte order.
    pub fn new(ctx: &Context, bgra: bool) -> Result<DeviceMean, GpuError> {
        let shared = ctx.shared.clone();
        let resolve = SmallPipeline::new(&shared, "resolve", RESOLVE_WGSL, c"resolve", 4, 1)?;
        let params = Buffer::new(
            &shared,
            "resolve parameters",
            std::mem::size_of::<GpuResolve>() as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryLocation::CpuToGpu,
        )?;
        let (commands, command, fence) = command_and_fence(&shared)?;
        Ok(DeviceMean {
            shared,
            resolve,
            commands,
            command,
            fence,
            params,
            images: None,
            bgra,
        })
    }

    /// Starts a view of `width` x `height`: buffers of its size, the pass
    /// cleared. The renderer copies its passes into the target returned.
    pub fn start(&mut self, width: u32, height: u32) -> Result<FrameTarget, GpuError> {
        let size = [width, height];
        if self.images.as_ref().is_none_or(|i| i.size != size) {
            self.images = None;
            let texels = u64::from(width) * u64::from(height);
            let usage = vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::TRANSFER_DST
                | vk::BufferUsageFlags::TRANSFER_SRC;
            let make = |name, bytes| {
                Buffer::new(&self.shared, name, bytes, usage, MemoryLocation::GpuOnly)
            };
            let images = Images {
                size,
                pass: make("the window's pass", texels * 16)?,
                sums: make("the window's sums", texels * 16)?,
                shown: make("the window's pixels", texels * 4)?,
            };
            let bound: Vec<(vk::Buffer, u64)> =
                [&images.pass, &images.sums, &images.shown, &self.params]
                    .iter()
                    .map(|b| (b.raw, b.size))
                    .collect();
            // The set is not in use: every submit was waited for.
            self.resolve.bind(0, &bound);
            self.images = Some(images);
        }
        let images = self.images.as_ref().expect("just made");
        let (pass, device) = (images.pass.raw, &self.shared.device);
        self.submit(|cmd| {
            // SAFETY: recording into the mean's own command buffer.
            unsafe { device.cmd_fill_buffer(cmd, pass, 0, vk::WHOLE_SIZE, 0) };
        })?;
        Ok(FrameTarget {
            device: self.shared.device.handle(),
            buffer: pass,
            width,
            height,
        })
    }

    /// Folds the pass the renderer copied in into the sums (`first`: the
    /// view's first pass, the sums start over) and packs the mean.
    pub fn add_pass(&mut self, first: bool) -> Result<(), GpuError> {
        let Some(images) = &self.images else {
            return Ok(());
        };
        let params = GpuResolve {
            size: images.size,
            reset: u32::from(first),
            bgra: u32::from(self.bgra),
        };
        self.params.write(bytemuck::bytes_of(&params));
        let groups = images.size.map(|v| v.div_ceil(WORKGROUP_SIZE));
        let (device, resolve) = (&self.shared.device, &self.resolve);
        self.submit(|cmd| {
            // SAFETY: recording into the mean's own command buffer; the
            // barrier orders the renderer's tile copies before the shader.
            unsafe {
                memory_barrier(
                    device,
                    cmd,
                    (
                        vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::COMPUTE_SHADER,
                        vk::AccessFlags::TRANSFER_WRITE | vk::AccessFlags::SHADER_WRITE,
                    ),
                    (
                        vk::PipelineStageFlags::COMPUTE_SHADER,
                        vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
                    ),
                );
                resolve.dispatch(cmd, 0, groups);
            }
        })
    }

    /// The packed pixels' byte order: B, G, R (true) or R, G, B.
    pub fn bgra(&self) -> bool {
        self.bgra
    }

    /// The packed pixels on the device and their size, for a copy.
    pub(super) fn shown(&self) -> Option<(vk::Buffer, [u32; 2])> {
        self.images.as_ref().map(|i| (i.shown.raw, i.size))
    }

    /// The packed pixels, read back (tests: the window's image against
    /// the host's mean): R, G, B per pixel.
    pub fn read(&self) -> Result<Vec<[u8; 3]>, GpuError> {
        let Some((shown, size)) = self.shown() else {
            return Ok(Vec::new());
        };
        let bytes = u64::from(size[0]) * u64::from(size[1]) * 4;
        let staging = Buffer::new(
            &self.shared,
            "the window's pixels, read back",
            bytes,
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )?;
        let device = &self.shared.device;
        self.submit(|cmd| {
            // SAFETY: recording into the mean's own command buffer.
            unsafe {
                memory_barrier(
                    device,
                    cmd,
                    (
                        vk::PipelineStageFlags::COMPUTE_SHADER,
                        vk::AccessFlags::SHADER_WRITE,
                    ),
                    (
                        vk::PipelineStageFlags::TRANSFER,
                        vk::AccessFlags::TRANSFER_READ,
                    ),
                );
                device.cmd_copy_buffer(
                    cmd,
                    shown,
                    staging.raw,
                    &[vk::BufferCopy::default().size(bytes)],
                );
                memory_barrier(
                    device,
                    cmd,
                    (
                        vk::PipelineStageFlags::TRANSFER,
                        vk::AccessFlags::TRANSFER_WRITE,
                    ),
                    (vk::PipelineStageFlags::HOST, vk::AccessFlags::HOST_READ),
                );
            }
        })?;
        let bgra = self.bgra;
        Ok(staging
            .mapped()
            .chunks_exact(4)
            .map(|p| {
                if bgra {
                    [p[2], p[1], p[0]]
                } else {
                    [p[0], p[1], p[2]]
                }
            })
            .collect())
    }

    /// Records `record` into the command buffer, submits it and waits.
    fn submit(&self, record: impl FnOnce(vk::CommandBuffer)) -> Result<(), GpuError> {
        submit_and_wait(
            &self.shared,
            (self.command, self.fence),
            (&[], &[]),
            WINDOW_WAIT_NS,
            record,
        )
    }
}

impl Drop for DeviceMean {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        let device = &self.shared.device;
        // SAFETY: every submit was waited for; nothing uses these now.
        unsafe {
            device.destroy_fence(self.fence, None);
            device.destroy_command_pool(self.commands, None);
        }
    }
}
