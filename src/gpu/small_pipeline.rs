//! A compute pipeline of one small WGSL shader whose bindings are all
//! storage buffers (the window's resolve, the render's 8-bit pack): its
//! SPIR-V, layouts, pipeline and descriptor sets, destroyed on drop.

use std::ffi::CStr;
use std::sync::Arc;

use ash::vk;

use crate::gpu::context::Shared;
use crate::gpu::error::{GpuError, ShaderError, VkResultExt};

pub(crate) struct SmallPipeline {
    shared: Arc<Shared>,
    set_layout: vk::DescriptorSetLayout,
    pub(crate) layout: vk::PipelineLayout,
    pub(crate) pipeline: vk::Pipeline,
    pool: vk::DescriptorPool,
    pub(crate) sets: Vec<vk::DescriptorSet>,
}

/// `wgsl` as SPIR-V 1.0, without contraction (as the trace shader: a fused
/// multiply-add would move an 8-bit level's rounding edges).
fn spirv(what: &str, wgsl: &str) -> Result<Vec<u32>, ShaderError> {
    use naga::back::spv;
    let fail = |message: String| ShaderError {
        what: what.into(),
        message,
    };
    let module = naga::front::wgsl::parse_str(wgsl).map_err(|e| fail(e.emit_to_string(wgsl)))?;
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .map_err(|e| fail(e.emit_to_string(wgsl)))?;
    let options = spv::Options {
        lang_version: (1, 0),
        flags: spv::WriterFlags::empty(),
        fake_missing_bindings: true,
        ..spv::Options::default()
    };
    let words = spv::write_vec(&module, &info, &options, None)
        .map_err(|e| fail(format!("SPIR-V generation: {e}")))?;
    Ok(crate::gpu::rewrite::no_contraction(&words))
}

impl SmallPipeline {
    /// `entry` of `wgsl` (named `what` in errors) with `bindings` storage
    /// buffers in group 0, and `sets` descriptor sets of that layout.
    pub(crate) fn new(
        shared: &Arc<Shared>,
        what: &str,
        wgsl: &str,
        entry: &CStr,
        bindings: u32,
        sets: u32,
    ) -> Result<SmallPipeline, GpuError> {
        let words = spirv(what, wgsl)?;
        let device = &shared.device;
        let layout_bindings: Vec<_> = (0..bindings)
            .map(|b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        let mut made = SmallPipeline {
            shared: shared.clone(),
            set_layout: vk::DescriptorSetLayout::null(),
            layout: vk::PipelineLayout::null(),
            pipeline: vk::Pipeline::null(),
            pool: vk::DescriptorPool::null(),
            sets: Vec::new(),
        };
        // SAFETY: valid create infos on a live device; each object is owned
        // by `made`, whose drop destroys what was created if a later step
        // fails.
        unsafe {
            made.set_layout = device
                .create_descriptor_set_layout(
                    &vk::DescriptorSetLayoutCreateInfo::default().bindings(&layout_bindings),
                    None,
                )
                .call("vkCreateDescriptorSetLayout")?;
            let layouts = [made.set_layout];
            made.layout = device
                .create_pipeline_layout(
                    &vk::PipelineLayoutCreateInfo::default().set_layouts(&layouts),
                    None,
                )
                .call("vkCreatePipelineLayout")?;
            let module = device
                .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None)
                .call("vkCreateShaderModule")?;
            let stage = vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(module)
                .name(entry);
            let created = device.create_compute_pipelines(
                vk::PipelineCache::null(),
                &[vk::ComputePipelineCreateInfo::default()
                    .stage(stage)
                    .layout(made.layout)],
                None,
            );
            device.destroy_shader_module(module, None);
            made.pipeline = created
                .map_err(|(_, r)| r)
                .call("vkCreateComputePipelines")?[0];
            let sizes = [vk::DescriptorPoolSize {
                ty: vk::DescriptorType::STORAGE_BUFFER,
                descriptor_count: bindings * sets,
            }];
            made.pool = device
                .create_descriptor_pool(
                    &vk::DescriptorPoolCreateInfo::default()
                        .max_sets(sets)
                        .pool_sizes(&sizes),
                    None,
                )
                .call("vkCreateDescriptorPool")?;
            let all = vec![made.set_layout; sets as usize];
            made.sets = device
                .allocate_descriptor_sets(
                    &vk::DescriptorSetAllocateInfo::default()
                        .descriptor_pool(made.pool)
                        .set_layouts(&all),
                )
                .call("vkAllocateDescriptorSets")?;
        }
        Ok(made)
    }

    /// Points set `set`'s bindings at `buffers` (binding i: buffer, range).
    /// The set must not be in use by a submission still running.
    pub(crate) fn bind(&self, set: usize, buffers: &[(vk::Buffer, u64)]) {
        let infos: Vec<[vk::DescriptorBufferInfo; 1]> = buffers
            .iter()
            .map(|&(buffer, range)| {
                [vk::DescriptorBufferInfo::default()
                    .buffer(buffer)
                    .range(range)]
            })
            .collect();
        let writes: Vec<_> = infos
            .iter()
            .enumerate()
            .map(|(i, info)| {
                vk::WriteDescriptorSet::default()
                    .dst_set(self.sets[set])
                    .dst_binding(i as u32)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .buffer_info(info)
            })
            .collect();
        // SAFETY: the caller waited for every submission using the set.
        unsafe { self.shared.device.update_descriptor_sets(&writes, &[]) };
    }

    /// Records a dispatch of `groups` with set `set` bound.
    ///
    /// # Safety
    /// `cmd` is recording, on this pipeline's device.
    pub(crate) unsafe fn dispatch(&self, cmd: vk::CommandBuffer, set: usize, groups: [u32; 2]) {
        let device = &self.shared.device;
        device.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, self.pipeline);
        device.cmd_bind_descriptor_sets(
            cmd,
            vk::PipelineBindPoint::COMPUTE,
            self.layout,
            0,
            &[self.sets[set]],
            &[],
        );
        device.cmd_dispatch(cmd, groups[0], groups[1], 1);
    }
}

impl Drop for SmallPipeline {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        let device = &self.shared.device;
        // SAFETY: the owner waited for every submission using these; null
        // handles (a failed creation) are ignored by Vulkan.
        unsafe {
            device.destroy_descriptor_pool(self.pool, None);
            device.destroy_pipeline(self.pipeline, None);
            device.destroy_pipeline_layout(self.layout, None);
            device.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}
