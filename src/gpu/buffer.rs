//! A Vulkan buffer with its gpu-allocator allocation, freed on drop.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::context::Shared;
use super::error::{GpuError, VkResultExt};

pub struct Buffer {
    shared: Arc<Shared>,
    pub raw: vk::Buffer,
    pub size: u64,
    usage: vk::BufferUsageFlags,
    allocation: Option<Allocation>,
}

impl Buffer {
    pub(crate) fn new(
        shared: &Arc<Shared>,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<Buffer, GpuError> {
        let device = &shared.device;
        let info = vk::BufferCreateInfo::default()
            .size(size.max(4))
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: valid create info on a live device.
        let raw = unsafe { device.create_buffer(&info, None) }.call("vkCreateBuffer")?;
        // SAFETY: `raw` was just created on this device.
        let requirements = unsafe { device.get_buffer_memory_requirements(raw) };
        let allocated = shared.allocator().allocate(&AllocationCreateDesc {
            name,
            requirements,
            location,
            linear: true,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        });
        let allocation = match allocated {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: the buffer is unused and unbound.
                unsafe { device.destroy_buffer(raw, None) };
                return Err(GpuError::Alloc {
                    what: format!("{name} ({size} bytes)"),
                    message: e.to_string(),
                });
            }
        };
        // SAFETY: memory and offset come from an allocation made for these requirements.
        unsafe { device.bind_buffer_memory(raw, allocation.memory(), allocation.offset()) }
            .call("vkBindBufferMemory")?;
        Ok(Buffer {
            shared: shared.clone(),
            raw,
            size,
            usage,
            allocation: Some(allocation),
        })
    }

    /// The buffer's device address, where the device has them enabled and the
    /// buffer was made with `SHADER_DEVICE_ADDRESS`; else `None`.
    pub fn address(&self) -> Option<u64> {
        let ext = self.shared.addresses.as_ref()?;
        if !self
            .usage
            .contains(vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS)
        {
            return None;
        }
        let info = vk::BufferDeviceAddressInfo::default().buffer(self.raw);
        // SAFETY: a live buffer of this device, made with the usage the
        // query needs, on a device with the feature enabled.
        Some(unsafe { ext.get_buffer_device_address(&info) })
    }

    /// The mapped bytes of a host-visible buffer.
    pub fn mapped(&self) -> &[u8] {
        let slice = self.allocation.as_ref().and_then(|a| a.mapped_slice());
        &slice.expect("buffer is host-visible")[..self.size as usize]
    }

    pub fn write(&mut self, bytes: &[u8]) {
        let slice = self
            .allocation
            .as_mut()
            .and_then(|a| a.mapped_slice_mut())
            .expect("buffer is host-visible");
        slice[..bytes.len()].copy_from_slice(bytes);
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return; // the GPU may still use it; leaking beats a use-after-free
        }
        if let Some(allocation) = self.allocation.take() {
            // An error here only means the allocator already lost track of it.
            let _ = self.shared.allocator().free(allocation);
        }
        // SAFETY: the owner waited for all work using this buffer to finish.
        unsafe { self.shared.device.destroy_buffer(self.raw, None) };
    }
}
