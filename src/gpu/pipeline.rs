//! The trace compute pipeline: SPIR-V compiled from shaders/trace.wgsl by
//! build.rs, its descriptor set layout (bindings as listed in the shader's
//! header) and pipeline layout.

use std::sync::Arc;

use ash::vk;

use super::context::{Context, Shared};
use super::error::{GpuError, VkResultExt};

const TRACE_SPIRV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/trace.spv"));
const ENTRY_POINT: &std::ffi::CStr = c"render_tile";

/// Descriptor types of bindings 0.. of group 0, in the shader's order.
pub const BINDINGS: [vk::DescriptorType; 9] = [
    vk::DescriptorType::UNIFORM_BUFFER, // frame
    vk::DescriptorType::UNIFORM_BUFFER, // tile
    vk::DescriptorType::STORAGE_BUFFER, // spheres
    vk::DescriptorType::STORAGE_BUFFER, // triangles
    vk::DescriptorType::STORAGE_BUFFER, // shading
    vk::DescriptorType::STORAGE_BUFFER, // lights
    vk::DescriptorType::STORAGE_BUFFER, // nodes
    vk::DescriptorType::STORAGE_BUFFER, // prim_refs
    vk::DescriptorType::STORAGE_BUFFER, // output
];

pub struct TracePipeline {
    shared: Arc<Shared>,
    pub(crate) set_layout: vk::DescriptorSetLayout,
    pub(crate) layout: vk::PipelineLayout,
    pub(crate) pipeline: vk::Pipeline,
}

impl TracePipeline {
    pub fn new(ctx: &Context) -> Result<TracePipeline, GpuError> {
        let shared = ctx.shared.clone();
        let device = &shared.device;
        let words = ash::util::read_spv(&mut std::io::Cursor::new(TRACE_SPIRV))
            .expect("build.rs writes whole SPIR-V words");
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
            pipeline: vk::Pipeline::null(),
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
            let module = device
                .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None)
                .call("vkCreateShaderModule")?;
            let stage = vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(module)
                .name(ENTRY_POINT);
            let info = vk::ComputePipelineCreateInfo::default()
                .stage(stage)
                .layout(p.layout);
            let created = device.create_compute_pipelines(vk::PipelineCache::null(), &[info], None);
            device.destroy_shader_module(module, None);
            p.pipeline = created
                .map_err(|(_, r)| r)
                .call("vkCreateComputePipelines")?[0];
        }
        Ok(p)
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
            device.destroy_pipeline(self.pipeline, None);
            device.destroy_pipeline_layout(self.layout, None);
            device.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}
