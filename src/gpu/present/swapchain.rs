//! Presenting to the window: a swapchain of a UNORM format (the bytes
//! `render` writes reach the window unchanged; an sRGB format would encode
//! them again), into whose images the window's pixels are copied, centred,
//! on black. Acquiring never waits: where no image is free (a FIFO queue
//! full at the display's rate), the image is presented later
//! (`Presenter::again`), so the render never waits for the display.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;

use super::mean::{DeviceMean, WINDOW_WAIT_NS};
use crate::gpu::buffer::Buffer;
use crate::gpu::commands::{command_and_fence, submit_and_wait};
use crate::gpu::context::{Context, Shared};
use crate::gpu::error::{GpuError, VkResultExt};
use crate::images::framebuffer::{to_u8, Framebuffer};

/// What the window shows last: the device's mean, or a host image.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Source {
    Device,
    Host([u32; 2]),
}

struct Chain {
    raw: vk::SwapchainKHR,
    images: Vec<vk::Image>,
    extent: vk::Extent2D,
    /// Signalled when image i's copy is done; its present waits on it.
    done: Vec<vk::Semaphore>,
}

/// The window's swapchain: copies packed pixels into its images and
/// presents them.
pub struct Presenter {
    shared: Arc<Shared>,
    loader: ash::khr::swapchain::Device,
    format: vk::SurfaceFormatKHR,
    mode: vk::PresentModeKHR,
    chain: Option<Chain>,
    /// The swapchain no longer matches the window (resized, suboptimal).
    stale: bool,
    acquired: vk::Semaphore,
    commands: vk::CommandPool,
    command: vk::CommandBuffer,
    fence: vk::Fence,
    staging: Option<Buffer>,
    mean: DeviceMean,
    last: Option<Source>,
    /// The last image could not be presented yet.
    pending: bool,
}

/// The first 8-bit UNORM format the surface offers, with its byte order
/// (B, G, R: true).
fn unorm(formats: &[vk::SurfaceFormatKHR]) -> Option<(vk::SurfaceFormatKHR, bool)> {
    formats.iter().find_map(|f| match f.format {
        vk::Format::B8G8R8A8_UNORM => Some((*f, true)),
        vk::Format::R8G8B8A8_UNORM => Some((*f, false)),
        _ => None,
    })
}

impl Presenter {
    /// Presents to the window of `ctx` (made with `ContextOptions::window`).
    pub fn new(ctx: &Context) -> Result<Presenter, GpuError> {
        let shared = ctx.shared.clone();
        let Some(surface) = &shared.surface else {
            return Err(GpuError::NoPresent(
                "the device was made without the window".into(),
            ));
        };
        // SAFETY: plain queries on this context's physical device and surface.
        let (formats, modes) = unsafe {
            (
                surface
                    .loader
                    .get_physical_device_surface_formats(shared.physical, surface.raw)
                    .call("vkGetPhysicalDeviceSurfaceFormatsKHR")?,
                surface
                    .loader
                    .get_physical_device_surface_present_modes(shared.physical, surface.raw)
                    .call("vkGetPhysicalDeviceSurfacePresentModesKHR")?,
            )
        };
        let (format, bgra) = unorm(&formats).ok_or_else(|| {
            GpuError::NoPresent(format!(
                "the window offers no 8-bit UNORM format (only {:?}), and an sRGB one would \
                 change the pixels",
                formats.iter().map(|f| f.format).collect::<Vec<_>>()
            ))
        })?;
        // Mailbox or immediate never hold the render to the display's rate;
        // FIFO, always there, is paced by `again`.
        let mode = [vk::PresentModeKHR::MAILBOX, vk::PresentModeKHR::IMMEDIATE]
            .into_iter()
            .find(|m| modes.contains(m))
            .unwrap_or(vk::PresentModeKHR::FIFO);
        let mean = DeviceMean::new(ctx, bgra)?;
        let (commands, command, fence) = command_and_fence(&shared)?;
        // SAFETY: a valid create info on a live device; destroyed in drop.
        let acquired = unsafe {
            shared
                .device
                .create_semaphore(&vk::SemaphoreCreateInfo::default(), None)
        }
        .call("vkCreateSemaphore")?;
        Ok(Presenter {
            loader: ash::khr::swapchain::Device::new(&shared.instance, &shared.device),
            shared,
            format,
            mode,
            chain: None,
            stale: true,
            acquired,
            commands,
            command,
            fence,
            staging: None,
            mean,
            last: None,
            pending: false,
        })
    }

    /// E.g. "B8G8R8A8_UNORM, MAILBOX".
    pub fn describe(&self) -> String {
        format!("{:?}, {:?}", self.format.format, self.mode)
    }

    /// The running mean a GPU view's passes go to.
    pub fn mean(&mut self) -> &mut DeviceMean {
        &mut self.mean
    }

    /// Shows the device's mean (after `DeviceMean::add_pass`).
    pub fn show_device(&mut self) -> Result<(), GpuError> {
        self.last = Some(Source::Device);
        self.pending = true;
        self.again()
    }

    /// Shows an image the host made (a preview, the CPU reference's, a
    /// difference): its 8-bit pixels, as `render` writes them.
    pub fn show_host(&mut self, image: &Framebuffer) -> Result<(), GpuError> {
        let bytes = u64::from(image.width) * u64::from(image.height) * 4;
        if self.staging.as_ref().is_none_or(|s| s.size < bytes) {
            self.staging = None;
            self.staging = Some(Buffer::new(
                &self.shared,
                "the window's host image",
                bytes,
                vk::BufferUsageFlags::TRANSFER_SRC,
                MemoryLocation::CpuToGpu,
            )?);
        }
        let bgra = self.mean.bgra();
        let packed: Vec<u8> = image
            .pixels
            .iter()
            .flat_map(|p| {
                let [r, g, b] = p.map(to_u8);
                if bgra {
                    [b, g, r, 255]
                } else {
                    [r, g, b, 255]
                }
            })
            .collect();
        self.staging.as_mut().expect("just made").write(&packed);
        self.last = Some(Source::Host([image.width, image.height]));
        self.pending = true;
        self.again()
    }

    /// Whether an image waits to be presented (`again` presents it).
    pub fn pending(&self) -> bool {
        self.pending
    }

    /// Presents the last image again (the window was exposed, or no
    /// swapchain image was free when it came).
    pub fn again(&mut self) -> Result<(), GpuError> {
        let (buffer, size) = match self.last {
            None => return Ok(()),
            Some(Source::Device) => match self.mean.shown() {
                Some(s) => s,
                None => return Ok(()),
            },
            Some(Source::Host(size)) => match &self.staging {
                Some(s) => (s.raw, size),
                None => return Ok(()),
            },
        };
        self.pending = !self.present(buffer, size)?;
        Ok(())
    }

    /// Copies the `size` pixels of `buffer` into a swapchain image and
    /// presents it; false where none was free or the window has no area.
    fn present(&mut self, buffer: vk::Buffer, size: [u32; 2]) -> Result<bool, GpuError> {
        if (self.stale || self.chain.is_none()) && !self.recreate()? {
            return Ok(false);
        }
        let chain = self.chain.as_ref().expect("made");
        // SAFETY: a live swapchain; the semaphore is unsignalled (the last
        // acquire's wait was waited for by its fence).
        let acquired = unsafe {
            self.loader
                .acquire_next_image(chain.raw, 0, self.acquired, vk::Fence::null())
        };
        let index = match acquired {
            Ok((i, suboptimal)) => {
                self.stale |= suboptimal;
                i as usize
            }
            Err(vk::Result::NOT_READY | vk::Result::TIMEOUT) => return Ok(false),
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => {
                self.stale = true;
                return Ok(false);
            }
            Err(r) => {
                return Err(GpuError::Vk {
                    call: "vkAcquireNextImageKHR",
                    result: r,
                })
            }
        };
        let (image, extent, done) = (chain.images[index], chain.extent, chain.done[index]);
        let device = &self.shared.device;
        submit_and_wait(
            &self.shared,
            (self.command, self.fence),
            (&[self.acquired], &[done]),
            WINDOW_WAIT_NS,
            |cmd| record_copy(device, cmd, (buffer, size), (image, extent)),
        )?;
        let (chains, waits, indices) = ([chain.raw], [done], [index as u32]);
        let info = vk::PresentInfoKHR::default()
            .wait_semaphores(&waits)
            .swapchains(&chains)
            .image_indices(&indices);
        // SAFETY: the image was acquired and its copy submitted, signalling
        // `done`.
        match unsafe { self.loader.queue_present(self.shared.queue, &info) } {
            Ok(suboptimal) => self.stale |= suboptimal,
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => self.stale = true,
            Err(r) => {
                return Err(GpuError::Vk {
                    call: "vkQueuePresentKHR",
                    result: r,
                })
            }
        }
        Ok(true)
    }

    /// A swapchain of the window's current size; false where it has none
    /// (minimised).
    fn recreate(&mut self) -> Result<bool, GpuError> {
        let surface = self.shared.surface.as_ref().expect("checked in new");
        // SAFETY: a plain query on this context's physical device and surface.
        let caps = unsafe {
            surface
                .loader
                .get_physical_device_surface_capabilities(self.shared.physical, surface.raw)
        }
        .call("vkGetPhysicalDeviceSurfaceCapabilitiesKHR")?;
        let extent = caps.current_extent;
        if extent.width == 0 || extent.height == 0 || extent.width == u32::MAX {
            return Ok(false);
        }
        if !caps
            .supported_usage_flags
            .contains(vk::ImageUsageFlags::TRANSFER_DST)
        {
            return Err(GpuError::NoPresent(
                "the window's images cannot be copied into".into(),
            ));
        }
        let count = if caps.max_image_count > 0 {
            (caps.min_image_count + 1).min(caps.max_image_count)
        } else {
            caps.min_image_count + 1
        };
        let alpha = [
            vk::CompositeAlphaFlagsKHR::OPAQUE,
            vk::CompositeAlphaFlagsKHR::INHERIT,
            vk::CompositeAlphaFlagsKHR::PRE_MULTIPLIED,
            vk::CompositeAlphaFlagsKHR::POST_MULTIPLIED,
        ]
        .into_iter()
        .find(|a| caps.supported_composite_alpha.contains(*a))
        .unwrap_or(vk::CompositeAlphaFlagsKHR::OPAQUE);
        let old = self.chain.take();
        let info = vk::SwapchainCreateInfoKHR::default()
            .surface(surface.raw)
            .min_image_count(count)
            .image_format(self.format.format)
            .image_color_space(self.format.color_space)
            .image_extent(extent)
            .image_array_layers(1)
            .image_usage(vk::ImageUsageFlags::TRANSFER_DST)
            .image_sharing_mode(vk::SharingMode::EXCLUSIVE)
            .pre_transform(caps.current_transform)
            .composite_alpha(alpha)
            .present_mode(self.mode)
            .clipped(true)
            .old_swapchain(old.as_ref().map_or(vk::SwapchainKHR::null(), |c| c.raw));
        // SAFETY: valid create info; the old swapchain is retired by it and
        // destroyed once the queue is idle.
        let raw = unsafe { self.loader.create_swapchain(&info, None) };
        if let Some(old) = old {
            self.destroy(old);
        }
        let raw = raw.call("vkCreateSwapchainKHR")?;
        // SAFETY: the swapchain was just made.
        let images =
            unsafe { self.loader.get_swapchain_images(raw) }.call("vkGetSwapchainImagesKHR")?;
        let done = images
            .iter()
            .map(|_| {
                // SAFETY: a valid create info on a live device.
                unsafe {
                    self.shared
                        .device
                        .create_semaphore(&vk::SemaphoreCreateInfo::default(), None)
                }
                .call("vkCreateSemaphore")
            })
            .collect::<Result<Vec<_>, _>>()?;
        self.chain = Some(Chain {
            raw,
            images,
            extent,
            done,
        });
        self.stale = false;
        Ok(true)
    }

    fn destroy(&self, chain: Chain) {
        // SAFETY: the queue is idle, so no present still waits on these.
        unsafe {
            let _ = self.shared.device.queue_wait_idle(self.shared.queue);
            for s in chain.done {
                self.shared.device.destroy_semaphore(s, None);
            }
            self.loader.destroy_swapchain(chain.raw, None);
        }
    }
}

impl Drop for Presenter {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        if let Some(chain) = self.chain.take() {
            self.destroy(chain);
        }
        // SAFETY: every submit was waited for and the queue is idle.
        unsafe {
            let device = &self.shared.device;
            device.destroy_semaphore(self.acquired, None);
            device.destroy_fence(self.fence, None);
            device.destroy_command_pool(self.commands, None);
        }
    }
}

/// Records the copy of the `size` image in `buffer` into the swapchain
/// `image` of `extent`: cleared to black, the image centred (where it is
/// larger than the window, which shrank and whose view at its new size is
/// on its way, its centre), then made ready to present.
fn record_copy(
    device: &ash::Device,
    cmd: vk::CommandBuffer,
    (buffer, size): (vk::Buffer, [u32; 2]),
    (image, extent): (vk::Image, vk::Extent2D),
) {
    let fit = |img: u32, win: u32| {
        let n = img.min(win);
        ((img - n) / 2, (win - n) / 2, n)
    };
    let (sx, dx, w) = fit(size[0], extent.width);
    let (sy, dy, h) = fit(size[1], extent.height);
    let range = vk::ImageSubresourceRange::default()
        .aspect_mask(vk::ImageAspectFlags::COLOR)
        .level_count(1)
        .layer_count(1);
    let barrier = |from, to, src, dst| {
        vk::ImageMemoryBarrier::default()
            .old_layout(from)
            .new_layout(to)
            .src_access_mask(src)
            .dst_access_mask(dst)
            .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .image(image)
            .subresource_range(range)
    };
    // SAFETY: recording into the presenter's own command buffer;
    // the image was acquired and its layout is set here.
    unsafe {
        // The mean's shader and the host's writes before the copy.
        let written = vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::SHADER_WRITE)
            .dst_access_mask(vk::AccessFlags::TRANSFER_READ);
        device.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
            vk::PipelineStageFlags::TRANSFER,
            vk::DependencyFlags::empty(),
            &[written],
            &[],
            &[barrier(
                vk::ImageLayout::UNDEFINED,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                vk::AccessFlags::empty(),
                vk::AccessFlags::TRANSFER_WRITE,
            )],
        );
        device.cmd_clear_color_image(
            cmd,
            image,
            vk::ImageLayout::TRANSFER_DST_OPTIMAL,
            &vk::ClearColorValue {
                float32: [0.0, 0.0, 0.0, 1.0],
            },
            &[range],
        );
        device.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::TRANSFER,
            vk::PipelineStageFlags::TRANSFER,
            vk::DependencyFlags::empty(),
            &[],
            &[],
            &[barrier(
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                vk::AccessFlags::TRANSFER_WRITE,
                vk::AccessFlags::TRANSFER_WRITE,
            )],
        );
        if w > 0 && h > 0 {
            let region = vk::BufferImageCopy::default()
                .buffer_offset((u64::from(sy) * u64::from(size[0]) + u64::from(sx)) * 4)
                .buffer_row_length(size[0])
                .buffer_image_height(size[1])
                .image_subresource(
                    vk::ImageSubresourceLayers::default()
                        .aspect_mask(vk::ImageAspectFlags::COLOR)
                        .layer_count(1),
                )
                .image_offset(vk::Offset3D {
                    x: dx as i32,
                    y: dy as i32,
                    z: 0,
                })
                .image_extent(vk::Extent3D {
                    width: w,
                    height: h,
                    depth: 1,
                });
            device.cmd_copy_buffer_to_image(
                cmd,
                buffer,
                image,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &[region],
            );
        }
        device.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::TRANSFER,
            vk::PipelineStageFlags::BOTTOM_OF_PIPE,
            vk::DependencyFlags::empty(),
            &[],
            &[],
            &[barrier(
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                vk::ImageLayout::PRESENT_SRC_KHR,
                vk::AccessFlags::TRANSFER_WRITE,
                vk::AccessFlags::empty(),
            )],
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_an_8_bit_unorm_format_is_taken() {
        let f = |format| vk::SurfaceFormatKHR {
            format,
            color_space: vk::ColorSpaceKHR::SRGB_NONLINEAR,
        };
        assert_eq!(unorm(&[f(vk::Format::B8G8R8A8_SRGB)]), None);
        assert_eq!(
            unorm(&[f(vk::Format::B8G8R8A8_SRGB), f(vk::Format::R8G8B8A8_UNORM)]),
            Some((f(vk::Format::R8G8B8A8_UNORM), false))
        );
        assert_eq!(
            unorm(&[f(vk::Format::B8G8R8A8_UNORM), f(vk::Format::R8G8B8A8_UNORM)]),
            Some((f(vk::Format::B8G8R8A8_UNORM), true))
        );
    }
}
