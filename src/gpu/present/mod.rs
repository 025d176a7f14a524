//! The window's image from the device (`glint view` on a Vulkan device
//! that can present to it): `mean` keeps a progressive render's running
//! sums on the device and packs their mean into the 8-bit pixels `render`
//! writes (`shaders/resolve.wgsl`), and `swapchain` copies those, or an
//! image the host made (a preview, the CPU reference's, a difference),
//! into a swapchain image of a UNORM format and presents it. The passes
//! are still read back, for the error estimate, `S` and OUT; the image the
//! window shows is not.

mod mean;
mod swapchain;

pub use mean::{DeviceMean, FrameTarget};
pub use swapchain::Presenter;
