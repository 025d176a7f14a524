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

use super::bindings::{Lists, BINDINGS};
use super::context::{Context, Shared};
use super::error::{GpuError, VkResultExt};
use crate::features::Features;
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
