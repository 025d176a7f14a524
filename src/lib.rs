//! glint: a ray tracer for the classic CSCI 420 scene format whose hot path is
//! a Vulkan compute shader (WGSL compiled by naga, driven with ash), with a CPU
//! reference renderer of the same algorithm for shader-vs-CPU comparison.
//!
//! ```text
//! scene::read_scene -> Scene --bvh::Bvh::build--> Bvh
//!   GPU: layout::GpuScene::pack -> gpu::GpuRenderer::render -> Framebuffer
//!   CPU: cpu::render (f32 twin of the shader, or f64 ground truth) -> Framebuffer
//! framebuffer::write_image; compare::compare_images
//! ```

pub mod accuracy;
pub mod bench;
pub mod bvh;
pub mod camera;
pub mod check;
pub mod compare;
pub mod cpu;
pub mod encode;
mod error;
pub mod features;
pub mod framebuffer;
pub mod gpu;
pub mod hard;
pub mod hash;
pub mod info;
pub mod input;
pub mod layout;
pub mod lights_on_surfaces;
pub mod memory;
pub mod mesh;
pub mod methods;
pub mod output;
pub mod parts;
pub mod plot;
pub mod probe;
pub mod progressive;
pub mod region;
pub mod render;
pub mod scene;
pub mod timing;
pub mod units;
pub mod view;
pub mod write_queue;

pub use error::Error;
