//! glint: a ray tracer for the classic CSCI 420 scene format whose hot path is
//! a Vulkan compute shader (WGSL compiled by naga, driven with ash), with a CPU
//! reference renderer of the same algorithm for shader-vs-CPU comparison.
//!
//! A render is one call: a [`render::Job`] says what to render (the image,
//! a crop, a part) and when to stop (once, or passes until an error or a
//! time), a [`render::Sink`] where the image goes (memory, a file, standard
//! output), and [`render::Renderer::run`] carries it out on the backend
//! its [`render::RenderOptions`] chose.
//!
//! ```
//! use glint::render::{Backend, Job, PixelFormat, Quiet, RenderOptions, Renderer, Sink};
//!
//! let scene = glint::scene::parse_scene(
//!     b"2\namb: 0 0 0\n\
//!       sphere pos: 0 0 -3 rad: 1 dif: 1 0 0 spe: 0 0 0 shi: 1\n\
//!       light pos: 0 0 0 col: 1 1 1\n",
//!     "<string>",
//! )?;
//! let options = RenderOptions {
//!     width: 64,
//!     height: 48,
//!     backend: Backend::Cpu,
//!     ..RenderOptions::default()
//! };
//! let done = Renderer::new(&options)?.run(&Job::new(&scene), &Sink::Memory(PixelFormat::Float), &Quiet)?;
//! let image = done.output.framebuffer();
//! // Near the centre the sphere faces the light head-on: nearly full red.
//! let [r, g, b] = image.pixels[24 * 64 + 32];
//! assert!(r > 0.99 && g == 0.0 && b == 0.0);
//! // Rays that miss show the white background.
//! assert_eq!(image.pixels[0], [1.0, 1.0, 1.0]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! The same scene on a Vulkan device against the CPU reference, judged as
//! `glint check` judges its suite, is [`suites::check::image_test`].
//!
//! ```text
//! scene::read_scene -> Scene --bvh::Bvh::build--> Bvh
//!   GPU: layout::GpuScene::pack -> gpu::GpuRenderer -> Image
//!   CPU: cpu::render_rows (f32 twin of the shader, or f64 ground truth) -> Image
//! render::Sink: images::encode, images::framebuffer::write_bytes; images::compare
//! ```

#![warn(missing_docs)]

pub mod bvh;
pub mod camera;
pub mod cpu;
mod error;
pub mod features;
pub mod gpu;
pub mod hash;
pub mod images;
pub mod info;
pub mod input;
pub mod layout;
pub mod material;
pub mod memory;
pub mod mesh;
pub mod methods;
pub mod number;
pub mod parts;
pub mod probe;
pub mod render;
pub mod scene;
pub mod scene_cache;
pub mod suites;
pub mod timing;
pub mod units;
#[cfg(feature = "window")]
pub mod view;

pub use error::Error;
