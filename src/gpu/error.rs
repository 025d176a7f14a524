use ash::vk;

/// What went wrong on the Vulkan side, naming the call and its `vk::Result`.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// The Vulkan loader could not be loaded (its message).
    #[error(
        "cannot load the Vulkan library ({0}); install a Vulkan driver \
         (e.g. `apt-get install mesa-vulkan-drivers` for the lavapipe software device)"
    )]
    Loader(String),
    /// No device offers a compute queue.
    #[error(
        "no Vulkan device with a compute queue was found; install a driver \
         (e.g. `apt-get install mesa-vulkan-drivers` for lavapipe)"
    )]
    NoDevice,
    /// Validation was asked for and the layer is not installed.
    #[error(
        "the Vulkan validation layer (VK_LAYER_KHRONOS_validation) is not installed; \
         install it (`apt-get install vulkan-validationlayers` on Debian/Ubuntu) or drop \
         --validation / GLINT_VALIDATION"
    )]
    NoValidationLayer,
    /// `--device` names no device (what it said).
    #[error("no Vulkan device matches `{0}`; `glint devices` lists the devices and their indices")]
    DeviceNotFound(String),
    /// A Vulkan call failed.
    #[error("{call} failed: {result}")]
    Vk {
        /// The call, as Vulkan names it.
        call: &'static str,
        /// What it returned.
        result: vk::Result,
    },
    /// The allocator could not place a buffer or image.
    #[error("GPU memory allocation for {what} failed: {message}")]
    Alloc {
        /// What the memory was for.
        what: String,
        /// The allocator's message.
        message: String,
    },
    /// A pass did not finish within `--pass-timeout`.
    #[error(
        "the GPU did not finish pass {pass} of the tile at pixel ({x}, {y}) within {seconds} s \
         (at most {budget} loop iterations per pixel); the device may be hung or very busy: \
         shrink the pass with a smaller --pass-budget or --tile, allow more time with \
         --pass-timeout, or use another device"
    )]
    Timeout {
        /// The tile's left edge, in pixels.
        x: u32,
        /// The tile's top edge, in pixels.
        y: u32,
        /// The pass that did not finish (0: the first).
        pass: u32,
        /// Loop iterations a pixel could start in the pass.
        budget: u32,
        /// The timeout waited.
        seconds: u64,
    },
    /// Invocations were cut short even at the smallest pass budget: the
    /// image would be wrong.
    #[error(
        "the shader could not finish {what} pixel ({x}, {y}) ({cut} invocations cut short{retried}): \
         a ray took more than {max} BVH steps, or the driver ended a loop early; the image would \
         be wrong, so nothing was written. Render with --backend cpu, or report the scene",
        what = if *probe { "probing" } else { "rendering" },
        retried = if *probe { "" } else { ", even at a pass budget of 1" },
        max = crate::layout::MAX_TRAVERSAL_STEPS
    )]
    Incomplete {
        /// The first cut pixel's column.
        x: u32,
        /// The first cut pixel's row.
        y: u32,
        /// Invocations cut short.
        cut: u32,
        /// Whether a probe (`glint check`'s, or `--path`) was running.
        probe: bool,
    },
    /// The scene needs more than a device limit allows.
    #[error(
        "{what} needs {needed}{unit} but this device allows {limit}{unit} ({limit_name}); \
         nothing was rendered: {hint}"
    )]
    Limit {
        /// What needs it (a buffer, a binding count).
        what: String,
        /// How much it needs.
        needed: u64,
        /// The limit's name in `VkPhysicalDeviceLimits`.
        limit_name: &'static str,
        /// The device's value of the limit.
        limit: u64,
        /// " bytes", or "" for counts.
        unit: &'static str,
        /// What to do about it.
        hint: String,
    },
    /// The device was lost mid-render.
    #[error(
        "the Vulkan device was lost ({call} returned VK_ERROR_DEVICE_LOST) while rendering \
         the tile at pixel ({x}, {y}) (the driver reset it or it crashed)"
    )]
    DeviceLost {
        /// The call that returned `VK_ERROR_DEVICE_LOST`.
        call: &'static str,
        /// The tile's left edge, in pixels.
        x: u32,
        /// The tile's top edge, in pixels.
        y: u32,
    },
    /// The renderer's cancel flag was set (`GpuRenderer::set_cancel`): the
    /// tiles in flight were waited for, no others were started.
    #[error("the render was cancelled before it finished")]
    Cancelled,
    /// The device cannot present to the window (`gpu::present`); the
    /// window then draws the image through the host.
    #[error("the Vulkan device cannot present to the window: {0}")]
    NoPresent(String),
    /// The shader did not compile (a bug in glint).
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
    /// Which shader (its specialisation).
    pub what: String,
    /// naga's or the driver's message.
    pub message: String,
}
