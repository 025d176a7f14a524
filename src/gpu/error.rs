use ash::vk;

/// What went wrong on the Vulkan side, naming the call and its `vk::Result`.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "cannot load the Vulkan library ({0}); install a Vulkan driver \
         (e.g. `apt-get install mesa-vulkan-drivers` for the lavapipe software device) \
         or use `--backend cpu`"
    )]
    Loader(String),
    #[error(
        "no Vulkan device with a compute queue was found; install a driver \
         (e.g. `apt-get install mesa-vulkan-drivers` for lavapipe) or use `--backend cpu`"
    )]
    NoDevice,
    #[error("no Vulkan device matches `{0}`; `glint devices` lists the devices and their indices")]
    DeviceNotFound(String),
    #[error("{call} failed: {result}")]
    Vk {
        call: &'static str,
        result: vk::Result,
    },
    #[error("GPU memory allocation for {what} failed: {message}")]
    Alloc { what: String, message: String },
    #[error(
        "the GPU did not finish the tile at pixel ({x}, {y}) within {seconds} s; the device \
         may be hung or very slow: try a smaller tile size or another device"
    )]
    Timeout { x: u32, y: u32, seconds: u64 },
    #[error(
        "the Vulkan device was lost while rendering the tile at pixel ({x}, {y}) \
         (the driver reset it or it crashed)"
    )]
    DeviceLost { x: u32, y: u32 },
    #[error(transparent)]
    Shader(#[from] super::shader::ShaderError),
}

pub(crate) trait VkResultExt<T> {
    /// Names the Vulkan call in the error.
    fn call(self, name: &'static str) -> Result<T, GpuError>;
}

impl<T> VkResultExt<T> for Result<T, vk::Result> {
    fn call(self, name: &'static str) -> Result<T, GpuError> {
        self.map_err(|result| GpuError::Vk { call: name, result })
    }
}
