use ash::vk;

/// What went wrong on the Vulkan side, naming the call and its `vk::Result`.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "cannot load the Vulkan library ({0}); install a Vulkan driver \
         (e.g. `apt-get install mesa-vulkan-drivers` for the lavapipe software device)"
    )]
    Loader(String),
    #[error(
        "no Vulkan device with a compute queue was found; install a driver \
         (e.g. `apt-get install mesa-vulkan-drivers` for lavapipe)"
    )]
    NoDevice,
    #[error(
        "the Vulkan validation layer (VK_LAYER_KHRONOS_validation) is not installed; \
         install it (`apt-get install vulkan-validationlayers` on Debian/Ubuntu) or drop \
         --validation / GLINT_VALIDATION"
    )]
    NoValidationLayer,
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
        "the GPU did not finish pass {pass} of the tile at pixel ({x}, {y}) within {seconds} s \
         (at most {budget} loop iterations per pixel); the device may be hung or very busy: \
         shrink the pass with a smaller --pass-budget or --tile, allow more time with \
         --pass-timeout, or use another device"
    )]
    Timeout {
        x: u32,
        y: u32,
        pass: u32,
        budget: u32,
        seconds: u64,
    },
    #[error(
        "the shader could not finish {what} pixel ({x}, {y}) ({cut} invocations cut short{retried}): \
         a ray took more than {max} BVH steps, or the driver ended a loop early; the image would \
         be wrong, so nothing was written. Render with --backend cpu, or report the scene",
        what = if *probe { "probing" } else { "rendering" },
        retried = if *probe { "" } else { ", even at a pass budget of 1" },
        max = crate::layout::MAX_TRAVERSAL_STEPS
    )]
    Incomplete {
        x: u32,
        y: u32,
        cut: u32,
        probe: bool,
    },
    #[error(
        "{what} needs {needed}{unit} but this device allows {limit}{unit} ({limit_name}); \
         nothing was rendered: {hint}"
    )]
    Limit {
        what: String,
        needed: u64,
        limit_name: &'static str,
        limit: u64,
        /// " bytes", or "" for counts.
        unit: &'static str,
        hint: String,
    },
    #[error(
        "the Vulkan device was lost ({call} returned VK_ERROR_DEVICE_LOST) while rendering \
         the tile at pixel ({x}, {y}) (the driver reset it or it crashed)"
    )]
    DeviceLost { call: &'static str, x: u32, y: u32 },
    /// The renderer's cancel flag was set (`GpuRenderer::set_cancel`): the
    /// tiles in flight were waited for, no others were started.
    #[error("the render was cancelled before it finished")]
    Cancelled,
    /// The device cannot present to the window (`gpu::present`); the
    /// window then draws the image through the host.
    #[error("the Vulkan device cannot present to the window: {0}")]
    NoPresent(String),
    #[error(transparent)]
    Shader(#[from] ShaderError),
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

/// The shader failed to compile: a bug in glint, not in the user's input.
#[derive(Debug, Clone, thiserror::Error)]
#[error("building the trace shader ({what}) failed: {message}; this is a bug in glint, please report it")]
pub struct ShaderError {
    pub what: String,
    pub message: String,
}
