//! Every GPU-visible struct, defined once here (`#[repr(C)]`, `bytemuck`), and
//! the packing of a `Scene` + `Bvh` into those buffers.
//!
//! `shaders/trace/layout.wgsl` declares the same structs by hand (WGSL has no
//! include); `tests/layout.rs` reads the shader's member offsets, struct sizes
//! and shared constants from naga and compares them with these, so the two
//! cannot drift apart silently. Fields are grouped as `vec3 + scalar` so WGSL's
//! 16-byte `vec3` alignment leaves no hidden padding.

mod pack;
mod refit;
mod types;

pub use pack::{padded, GpuScene};
pub use types::*;
