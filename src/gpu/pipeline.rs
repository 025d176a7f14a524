//! The trace compute pipelines: one descriptor set layout (bindings as
//! listed in the shader's header) and pipeline layout, and a pipeline per
//! (methods, feature set, entry point), its SPIR-V specialised by `shader`,
//! built on first use and kept for the renderer's lifetime.

use std::collections::HashMap;
use std::ffi::CStr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use ash::vk;

use super::context::{Context, Shared};
use super::error::{GpuError, VkResultExt};
use crate::info::Features;
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
    pub kernel: Kernel,
}

/// Descriptor types of bindings 0.. of group 0, in the shader's order.
pub const BINDINGS: [vk::DescriptorType; 12] = [
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
];

pub struct TracePipeline {
    shared: Arc<Shared>,
    pub(crate) set_layout: vk::DescriptorSetLayout,
    pub(crate) layout: vk::PipelineLayout,
    pipelines: Mutex<HashMap<PipelineKey, vk::Pipeline>>,
}

impl TracePipeline {
    /// The layouts; pipelines are built by `get`.
    pub fn new(ctx: &Context) -> Result<TracePipeline, GpuError> {
        let shared = ctx.shared.clone();
        let device = &shared.device;
        let bindings: Vec<_> = BINDINGS
            .iter()
            .enumerate()
            .map(|(i, &ty)| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(i as u32)
                    .descriptor_type(ty)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        // Build into a partially filled struct so that Drop cleans up whatever
        // was created before a failure.
        let mut p = TracePipeline {
            shared: shared.clone(),
            set_layout: vk::DescriptorSetLayout::null(),
            layout: vk::PipelineLayout::null(),
            pipelines: Mutex::new(HashMap::new()),
        };
        // SAFETY: valid create infos on a live device; handles are owned by `p`.
        unsafe {
            p.set_layout = device
                .create_descriptor_set_layout(
                    &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                    None,
                )
                .call("vkCreateDescriptorSetLayout")?;
            let set_layouts = [p.set_layout];
            p.layout = device
                .create_pipeline_layout(
                    &vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts),
                    None,
                )
                .call("vkCreatePipelineLayout")?;
        }
        Ok(p)
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
        let words = super::shader::spirv(key.methods, key.features)?;
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
                .layout(self.layout);
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
            device.destroy_pipeline_layout(self.layout, None);
            device.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}
