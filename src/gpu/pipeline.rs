//! The trace compute pipelines: three descriptor set layouts (bindings as
//! listed in the shader's header: the plain one, one with the extra chunks
//! of split lists, one with the uniform copies of the hot lists) with their
//! pipeline layouts, and a pipeline per (methods, feature set, lists, entry
//! point), its SPIR-V specialised by `shader`, built on first use and kept
//! for the renderer's lifetime.

use std::collections::HashMap;
use std::ffi::CStr;
use std::sync::atomic::{AtomicU64, Ordering};
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
    /// Pipelines the driver compiled, and found in the disk cache.
    compiled: AtomicU64,
    from_disk: AtomicU64,
}

/// How a pipeline `TracePipeline::get` had to build came to be.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Built {
    /// The driver compiled it.
    Compiled,
    /// The driver found it in the pipeline cache from disk.
    FromDisk,
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
            compiled: AtomicU64::new(0),
            from_disk: AtomicU64::new(0),
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
    /// built it, zero when it was built already, and how it was built.
    pub fn get(
        &self,
        key: PipelineKey,
    ) -> Result<(vk::Pipeline, Duration, Option<Built>), GpuError> {
        let mut pipelines = self.pipelines.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(&p) = pipelines.get(&key) {
            return Ok((p, Duration::ZERO, None));
        }
        let start = Instant::now();
        let (pipeline, built) = self.build_cached(key)?;
        pipelines.insert(key, pipeline);
        match built {
            Built::Compiled => &self.compiled,
            Built::FromDisk => &self.from_disk,
        }
        .fetch_add(1, Ordering::Relaxed);
        Ok((pipeline, start.elapsed(), Some(built)))
    }

    /// Pipelines built so far: (compiled by the driver, found on disk).
    pub fn builds(&self) -> (u64, u64) {
        (
            self.compiled.load(Ordering::Relaxed),
            self.from_disk.load(Ordering::Relaxed),
        )
    }

    /// `build`, through the disk cache where there is one: its data for
    /// this shader goes to the driver, and what the driver built is written
    /// back when the driver did not find it there.
    fn build_cached(&self, key: PipelineKey) -> Result<(vk::Pipeline, Built), GpuError> {
        let Some(disk) = &self.shared.pipeline_cache else {
            return Ok((self.build(key)?, Built::Compiled));
        };
        let words = self.words(key)?;
        let shader = super::cache::shader_hash(&words, key.kernel.entry_point().to_bytes());
        let initial = match disk.load(shader) {
            super::cache::Loaded::Data(d) => d,
            _ => Vec::new(),
        };
        let device = &self.shared.device;
        // SAFETY: a plain creation on a live device, destroyed below.
        let cache = unsafe {
            device.create_pipeline_cache(
                &vk::PipelineCacheCreateInfo::default().initial_data(&initial),
                None,
            )
        }
        .call("vkCreatePipelineCache")?;
        let built = self.create(key, &words, cache);
        let result = built.map(|(pipeline, hit)| {
            let from_disk = hit.unwrap_or(!initial.is_empty());
            if !from_disk {
                // SAFETY: the cache is live; the driver fills the data.
                if let Ok(data) = unsafe { device.get_pipeline_cache_data(cache) } {
                    // A failed write costs the next run a compile, no more.
                    let _ = disk.store(shader, &data);
                }
            }
            (
                pipeline,
                if from_disk {
                    Built::FromDisk
                } else {
                    Built::Compiled
                },
            )
        });
        // SAFETY: the pipeline no longer needs its cache.
        unsafe { device.destroy_pipeline_cache(cache, None) };
        result
    }

    fn words(&self, key: PipelineKey) -> Result<Vec<u32>, GpuError> {
        let variant = super::shader::Variant {
            lists: key.lists,
            light_skips: key.light_skips,
            corners: key.corners,
            leaf_order: key.leaf_order,
            one_pass: key.one_pass,
        };
        Ok(super::shader::spirv(key.methods, key.features, variant)?)
    }

    /// Creates the pipeline from `words` with `cache`; whether the driver
    /// found it in the cache, where it can say
    /// (`VK_EXT_pipeline_creation_feedback`).
    fn create(
        &self,
        key: PipelineKey,
        words: &[u32],
        cache: vk::PipelineCache,
    ) -> Result<(vk::Pipeline, Option<bool>), GpuError> {
        let device = &self.shared.device;
        let mut feedback = vk::PipelineCreationFeedback::default();
        let mut stages = [vk::PipelineCreationFeedback::default()];
        let mut feedback_info = vk::PipelineCreationFeedbackCreateInfo::default()
            .pipeline_creation_feedback(&mut feedback)
            .pipeline_stage_creation_feedbacks(&mut stages);
        // SAFETY: valid create infos on a live device; the module is
        // destroyed once the pipeline exists, the pipeline is owned by `self`.
        let pipeline = unsafe {
            let module = device
                .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(words), None)
                .call("vkCreateShaderModule")?;
            let stage = vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(module)
                .name(key.kernel.entry_point());
            let mut info = vk::ComputePipelineCreateInfo::default()
                .stage(stage)
                .layout(self.layout(key.lists).pipeline);
            if self.shared.feedback {
                info = info.push_next(&mut feedback_info);
            }
            let created = device.create_compute_pipelines(cache, &[info], None);
            device.destroy_shader_module(module, None);
            created
                .map_err(|(_, r)| r)
                .call("vkCreateComputePipelines")?[0]
        };
        let valid = self.shared.feedback
            && feedback
                .flags
                .contains(vk::PipelineCreationFeedbackFlags::VALID);
        let hit = valid.then(|| {
            feedback
                .flags
                .contains(vk::PipelineCreationFeedbackFlags::APPLICATION_PIPELINE_CACHE_HIT)
        });
        Ok((pipeline, hit))
    }

    /// The pipeline for `key`, compiled without any cache.
    fn build(&self, key: PipelineKey) -> Result<vk::Pipeline, GpuError> {
        let words = self.words(key)?;
        Ok(self.create(key, &words, vk::PipelineCache::null())?.0)
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
