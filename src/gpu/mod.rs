//! The Vulkan backend (ash, loaded at run time; memory through gpu-allocator).
//!
//! `context` creates the instance and device and owns the allocator; `shader`
//! specialises the WGSL per feature set; `buffer` and `pipeline` wrap one
//! Vulkan concept each; `render` runs the trace
//! pipeline over a packed scene in tiles; `present` shows its passes in a
//! window (`glint view`); `commands` submits one-off work and waits for it;
//! `debug` counts validation messages.
//! Every wrapper holds an `Arc` of the context's shared state, so Vulkan
//! objects are destroyed after the work using them, and the device last.

mod bindings;
mod buffer;
pub mod cache;
mod commands;
mod context;
mod debug;
pub mod driver;
mod error;
mod fault;
mod limits;
mod pipeline;
pub mod present;
mod render;
mod rewrite;
pub mod shader;
mod small_pipeline;
mod surface;

pub use bindings::BINDINGS;
pub use context::{
    list_devices, Context, ContextOptions, DeviceInfo, DeviceLimits, DeviceSelector, WindowTarget,
};
pub use error::GpuError;
pub use pipeline::Kernel;
pub use render::{
    gathered_image_bytes, tile_texels, GpuRenderOptions, GpuRenderer, DEFAULT_PASS_BUDGET,
    MAX_CHAIN, RESUMABLE_REDOS,
};
