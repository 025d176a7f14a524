//! The binary BVH's node, as both backends and the GPU packing read it,
//! and the constants of its primitive references.

use bytemuck::{Pod, Zeroable};

/// Bit 31 of a primitive reference marks a sphere; the rest is the index.
pub const SPHERE_BIT: u32 = 0x8000_0000;
/// Deepest BVH the builder makes, and so the traversal stack size.
pub const BVH_MAX_DEPTH: u32 = 64;

/// A node of the binary BVH (32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuBvhNode {
    /// The box's low corner.
    pub min: [f32; 3],
    /// Interior: index of the right child (the left one is the next node).
    /// Leaf: index of the first primitive reference.
    pub right_or_first: u32,
    /// The box's high corner.
    pub max: [f32; 3],
    /// Primitive count of a leaf; 0 marks an interior node.
    pub count: u32,
}
