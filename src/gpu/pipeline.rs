//! The trace compute pipelines: three descriptor set layouts (bindings as
//! listed in the shader's header: the plain one, one with the extra chunks
//! of split lists, one with the uniform copies of the hot lists) with their
//! pipeline layouts, and a pipeline per (methods, feature set, lists, entry
//! point), its SPIR-V specialised by `shader`, built on first use and kept
//! for the renderer's lifetime.

use std::collections::HashMap;
use std::ffi::CStr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use ash::vk;

use super::context::{Context, Shared};
use super::error::{GpuError, VkResultExt};
use crate::info::Features;
use crate::layout::UNIFORM_FIRST;
use crate::methods::Methods;

/// The shader's entry points.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kernel {
    /// Colour, one texel per pixel.
    Render,
    /// (primitive, shadow mask, flags, t) per pixel.
    ProbeTile,
    /// One pixel's path record.
    ProbePixel,
}

impl Kernel {
    fn entry_point(self) -> &'static CStr {
        match self {
            Kernel::Render => c"render_tile",
            Kernel::ProbeTile => c"probe_tile",
            Kernel::ProbePixel => c"probe_pixel",
        }
    }
}

/// What a pipeline is specialised for: the cache key.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PipelineKey {
    pub methods: Methods,
    pub features: Features,
    /// How the scene's lists are bound.
    pub lists: Lists,
    /// Some light lies on a surface (`lights_on_surfaces`): the shader that
    /// reads the skip lists.
    pub light_skips: bool,
    /// The uniform triangle copy holds corners only (`CopyForm::Corners`).
    pub corners: bool,
    /// The triangles are in leaf order (`GpuScene::scene_triangles`).
    pub leaf_order: bool,
    /// `Kernel::Render` only: a tile's first pass without pixel state
    /// (`ONE_PASS` in the shader); false for the probes.
    pub one_pass: bool,
    pub kernel: Kernel,
}

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

/// A descriptor set layout and the pipeline layout over it.
#[derive(Clone, Copy)]
pub(crate) struct Layout {
    pub(crate) set: vk::DescriptorSetLayout,
    pub(crate) pipeline: vk::PipelineLayout,
}

pub struct TracePipeline {
    shared: Arc<Shared>,
    /// One per `Lists::ALL`.
    layouts: [Layout; 4],
    pipelines: Mutex<HashMap<PipelineKey, vk::Pipeline>>,
}

impl TracePipeline {
    /// The layouts; pipelines are built by `get`.
    pub fn new(ctx: &Context) -> Result<TracePipeline, GpuError> {
        let shared = ctx.shared.clone();
        let null = Layout {
            set: vk::DescriptorSetLayout::null(),
            pipeline: vk::PipelineLayout::null(),
        };
        // Build into a partially filled struct so that Drop cleans up whatever
        // was created before a failure.
        let mut p = TracePipeline {
            shared: shared.clone(),
            layouts: [null; 4],
            pipelines: Mutex::new(HashMap::new()),
        };
        for lists in Lists::ALL {
            let bindings: Vec<_> = lists
                .bindings()
                .map(|i| {
                    vk::DescriptorSetLayoutBinding::default()
                        .binding(i as u32)
                        .descriptor_type(BINDINGS[i])
                        .descriptor_count(1)
                        .stage_flags(vk::ShaderStageFlags::COMPUTE)
                })
                .collect();
            let layout = &mut p.layouts[lists.index()];
            // SAFETY: valid create infos on a live device; handles are owned
            // by `p`.
            unsafe {
                layout.set = shared
                    .device
                    .create_descriptor_set_layout(
                        &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                        None,
                    )
                    .call("vkCreateDescriptorSetLayout")?;
                let set_layouts = [layout.set];
                layout.pipeline = shared
                    .device
                    .create_pipeline_layout(
                        &vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts),
                        None,
                    )
                    .call("vkCreatePipelineLayout")?;
            }
        }
        Ok(p)
    }

    pub(crate) fn layout(&self, lists: Lists) -> Layout {
        self.layouts[lists.index()]
    }

    /// How long building `key`'s pipeline takes from scratch (specialising
    /// the WGSL, writing SPIR-V, the driver's compile), bypassing the cache;
    /// the pipeline is destroyed again.
    pub fn measure_build(&self, key: PipelineKey) -> Result<Duration, GpuError> {
        let start = Instant::now();
        let pipeline = self.build(key)?;
        let elapsed = start.elapsed();
        // SAFETY: the pipeline was never used.
        unsafe { self.shared.device.destroy_pipeline(pipeline, None) };
        Ok(elapsed)
    }

    /// The pipeline for `key`, built on first use; the duration is the
    /// build time (specialisation, SPIR-V and driver compile) when this call
    /// built it, zero when it came from the cache.
    pub fn get(&self, key: PipelineKey) -> Result<(vk::Pipeline, Duration), GpuError> {
        let mut pipelines = self.pipelines.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(&p) = pipelines.get(&key) {
            return Ok((p, Duration::ZERO));
        }
        let start = Instant::now();
        let pipeline = self.build(key)?;
        pipelines.insert(key, pipeline);
        Ok((pipeline, start.elapsed()))
    }

    fn build(&self, key: PipelineKey) -> Result<vk::Pipeline, GpuError> {
        let variant = super::shader::Variant {
            lists: key.lists,
            light_skips: key.light_skips,
            corners: key.corners,
            leaf_order: key.leaf_order,
            one_pass: key.one_pass,
        };
        let words = super::shader::spirv(key.methods, key.features, variant)?;
        let device = &self.shared.device;
        // SAFETY: valid create infos on a live device; the module is destroyed
        // once the pipeline exists, the pipeline is owned by `self`.
        let pipeline = unsafe {
            let module = device
                .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None)
                .call("vkCreateShaderModule")?;
            let stage = vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(module)
                .name(key.kernel.entry_point());
            let info = vk::ComputePipelineCreateInfo::default()
                .stage(stage)
                .layout(self.layout(key.lists).pipeline);
            let created = device.create_compute_pipelines(vk::PipelineCache::null(), &[info], None);
            device.destroy_shader_module(module, None);
            created
                .map_err(|(_, r)| r)
                .call("vkCreateComputePipelines")?[0]
        };
        Ok(pipeline)
    }
}

impl Drop for TracePipeline {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        let device = &self.shared.device;
        // SAFETY: renders wait for their work before returning, so nothing
        // uses these handles; null handles are ignored by Vulkan.
        unsafe {
            let pipelines = self.pipelines.get_mut().unwrap_or_else(|e| e.into_inner());
            for (_, p) in pipelines.drain() {
                device.destroy_pipeline(p, None);
            }
            for layout in &self.layouts {
                device.destroy_pipeline_layout(layout.pipeline, None);
                device.destroy_descriptor_set_layout(layout.set, None);
            }
        }
    }
}
