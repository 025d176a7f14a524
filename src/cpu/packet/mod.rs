//! Thirty-two rays through the wide tree together: the CPU reference's fast
//! path for a tile's primary rays and for their shadow rays towards each
//! point light. Neighbouring pixels' rays open mostly the same nodes, so
//! one pop, one child sort and one push serve them all, where a single ray
//! pays them alone; that bookkeeping, not the box arithmetic, was most of a
//! single ray's cost.
//!
//! Each ray's box tests are `wide::hit_boxes_f32`'s arithmetic lane for
//! lane (the rays, not the boxes, fill the SIMD lanes here), with the ray's
//! own nearest hit so far as its limit, and a leaf meets only the rays whose
//! own test reached it, tested exactly as a single ray's (`hit_leaf`). So
//! each ray gets a single ray's shadow verdict, and its closest hit but
//! where two surfaces meet it at the same t or within an ulp or two (as at
//! a mesh's vertices): the triangle test checks a candidate against the hit
//! found so far, so which of such near-equals is kept follows the order
//! leaves are opened in, here the packet's nearest ray's. That order is as
//! deterministic as the single ray's (tests/packets.rs bounds where and how
//! far the images differ).

mod avx2;
mod avx512;
#[cfg(test)]
mod lane_tests;
mod lanes;
mod points;
mod shade;
mod sse;
#[cfg(test)]
mod tests;
mod walk;

pub use lanes::WIDTH;
pub use shade::{fill_band, TILE};
pub use walk::traverse;

use crate::cpu::trace::CpuScene;
use crate::methods::Methods;

/// Whether a render of `scene` may take its pixels in packets: one sample
/// a pixel, at its centre, with nothing moving, so every primary ray
/// starts at the same time from the camera; and the robust methods, whose
/// tests never find a hit outside its leaf's box, so that which hit a ray
/// keeps cannot depend on the order leaves are opened in beyond near-ties
/// (the naive test can, and its renders show the single ray's order).
pub fn applies(scene: &CpuScene<f32>) -> bool {
    scene.spp <= 1 && !scene.motion_blur && scene.methods == Methods::Robust
}
