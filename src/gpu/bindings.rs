//! The shader's bindings (group 0, in the order its header lists them) and
//! the ways a render binds the scene's lists to them: the plain storage
//! bindings, split chunks, uniform copies or device addresses.

use ash::vk;

use crate::layout::UNIFORM_FIRST;

/// How a render binds the scene's lists: the descriptor set layout, and
/// the shader variant that reads it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Lists {
    /// One storage binding per list: the first `PLAIN_BINDINGS`.
    #[default]
    Plain,
    /// Big lists span several bindings (`layout::SPLIT_LISTS`): the plain
    /// bindings and the extra chunks.
    Split,
    /// The plain bindings, and uniform copies of spheres, triangles and
    /// nodes (`layout::UNIFORM_LISTS`), which the shader reads instead.
    Uniform,
    /// The plain bindings; the shader reads the `layout::ADDRESS_LISTS`
    /// through their device addresses (`GpuFrame::addresses`) instead.
    Address,
}

impl Lists {
    pub const ALL: [Lists; 4] = [Lists::Plain, Lists::Split, Lists::Uniform, Lists::Address];

    /// The layout's bindings, in order.
    pub fn bindings(self) -> impl Iterator<Item = usize> + Clone {
        let extra = match self {
            Lists::Plain | Lists::Address => 0..0,
            Lists::Split => PLAIN_BINDINGS..UNIFORM_FIRST,
            Lists::Uniform => UNIFORM_FIRST..BINDINGS.len(),
        };
        (0..PLAIN_BINDINGS).chain(extra)
    }

    /// Its place in `Lists::ALL` (and in each slot's descriptor sets).
    pub fn index(self) -> usize {
        self as usize
    }
}

/// Descriptor types of bindings 0.. of group 0, in the shader's order; each
/// layout has those `Lists::bindings` names.
pub const BINDINGS: [vk::DescriptorType; 30] = [
    vk::DescriptorType::UNIFORM_BUFFER, // frame
    vk::DescriptorType::UNIFORM_BUFFER, // tile
    vk::DescriptorType::STORAGE_BUFFER, // spheres
    vk::DescriptorType::STORAGE_BUFFER, // triangles
    vk::DescriptorType::STORAGE_BUFFER, // shading
    vk::DescriptorType::STORAGE_BUFFER, // lights
    vk::DescriptorType::STORAGE_BUFFER, // nodes
    vk::DescriptorType::STORAGE_BUFFER, // prim_refs
    vk::DescriptorType::STORAGE_BUFFER, // output
    vk::DescriptorType::STORAGE_BUFFER, // velocities
    vk::DescriptorType::STORAGE_BUFFER, // pixel state
    vk::DescriptorType::STORAGE_BUFFER, // status
    vk::DescriptorType::STORAGE_BUFFER, // materials
    vk::DescriptorType::STORAGE_BUFFER, // light skips
    // Chunks 1-3 of triangles, normals, materials and nodes
    // (layout::SPLIT_LISTS).
    vk::DescriptorType::STORAGE_BUFFER,
    vk::DescriptorType::STORAGE_BUFFER,
    vk::DescriptorType::STORAGE_BUFFER,
    vk::DescriptorType::STORAGE_BUFFER,
    vk::DescriptorType::STORAGE_BUFFER,
    vk::DescriptorType::STORAGE_BUFFER,
    vk::DescriptorType::STORAGE_BUFFER,
    vk::DescriptorType::STORAGE_BUFFER,
    vk::DescriptorType::STORAGE_BUFFER,
    vk::DescriptorType::STORAGE_BUFFER,
    vk::DescriptorType::STORAGE_BUFFER,
    vk::DescriptorType::STORAGE_BUFFER,
    // Uniform copies of spheres, triangles, nodes and primitive references
    // (layout::UNIFORM_LISTS).
    vk::DescriptorType::UNIFORM_BUFFER,
    vk::DescriptorType::UNIFORM_BUFFER,
    vk::DescriptorType::UNIFORM_BUFFER,
    vk::DescriptorType::UNIFORM_BUFFER,
];
/// Bindings of the plain layout (no split lists).
pub const PLAIN_BINDINGS: usize = 14;
