//! The device limits glint plans renders against, read once per device.

/// The device limits a render must stay within.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeviceLimits {
    /// `maxStorageBufferRange`: the largest storage binding, in bytes.
    pub max_storage_range: u64,
    /// `maxUniformBufferRange`.
    pub max_uniform_range: u64,
    /// `maxMemoryAllocationSize` (Vulkan 1.1; the spec's minimum, 1 GiB,
    /// where the device does not say).
    pub max_allocation: u64,
    /// `maxComputeWorkGroupCount`.
    pub max_group_count: [u32; 3],
    /// `maxPerStageDescriptorStorageBuffers`.
    pub max_storage_buffers: u32,
    /// `maxPerStageDescriptorUniformBuffers`.
    pub max_uniform_buffers: u32,
    /// The device is a CPU (`VK_PHYSICAL_DEVICE_TYPE_CPU`: lavapipe,
    /// SwiftShader), which reads uniform buffers faster than storage ones.
    pub cpu: bool,
    /// `minStorageBufferOffsetAlignment`: where a split list's chunks may start.
    pub storage_offset_alignment: u64,
    /// `timestampPeriod`: nanoseconds a timestamp tick lasts.
    pub timestamp_period: f32,
    /// The compute queue's `timestampValidBits`; 0: no timestamps, so GPU
    /// time is the host's clock around each pass.
    pub timestamp_bits: u32,
    /// Buffer device addresses and 64-bit integers are enabled
    /// (`VK_KHR_buffer_device_address`, `shaderInt64`): only where loads
    /// through them are the device's fastest divergent loads
    /// (`DriverProfile::address_lists`), so that the shader reads its hot lists that
    /// way (`Lists::Address`).
    pub device_addresses: bool,
    /// `subgroupSize` (Vulkan 1.1; 0 where the device does not say): for
    /// reports, as llvmpipe's 8 lanes are what its measurements assume.
    pub subgroup_size: u32,
}
