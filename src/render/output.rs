//! What a render gives back: the image, and how it was made.

use crate::images::framebuffer::{Framebuffer, Image};
use crate::memory::MemoryNeed;
use crate::timing::Timings;

/// A finished render (or pass) and what it took.
pub struct RenderOutput {
    /// Float values, or 8-bit pixels where the render was asked for them
    /// (`RenderOptions::pixels`).
    pub image: Image,
    /// Each phase's time and the counts (rays, bytes read back, ...).
    pub timings: Timings,
    /// What rendered it, e.g. "GPU: llvmpipe (LLVM 15.0.6, 256 bits)" or "CPU reference (f32)".
    pub renderer: String,
    /// Something the user should know, e.g. why `auto` fell back to the CPU.
    pub note: Option<String>,
    /// Vulkan validation warnings and errors seen (GPU renders with validation on).
    pub validation_messages: u32,
    /// Host memory the render needed beyond the scene and its BVH (checked
    /// against what was available before it started).
    pub memory: MemoryNeed,
    /// The tree it traversed.
    pub bvh: crate::bvh::BvhStats,
    /// Samples it took, over all pixels it rendered.
    pub samples: u64,
}

impl RenderOutput {
    /// The float image (8-bit pixels as v / 255).
    pub fn framebuffer(&self) -> std::borrow::Cow<'_, Framebuffer> {
        self.image.to_float()
    }

    /// The float image, without a copy where it is one.
    pub fn into_framebuffer(self) -> Framebuffer {
        self.image.into_float()
    }
}
