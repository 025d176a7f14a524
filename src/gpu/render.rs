//! Rendering a packed scene on the GPU, tile by tile.
//!
//! Each tile is one submit with its own fence, so no single submission runs
//! long enough to trip a driver watchdog and the host can report progress.
//! Two tile slots alternate: while the GPU renders one tile, the host reads
//! the previous one back. A tile is dispatched into a device-local buffer and
//! copied into a host-visible one, so shaders never write across PCIe.

use std::sync::Arc;
use std::time::{Duration, Instant};

use ash::vk;
use gpu_allocator::MemoryLocation;

use super::buffer::Buffer;
use super::context::{Context, Shared};
use super::error::{GpuError, VkResultExt};
use super::pipeline::{Kernel, PipelineKey, TracePipeline, BINDINGS};
use crate::camera::Camera;
use crate::framebuffer::Framebuffer;
use crate::info::Features;
use crate::layout::{padded, GpuScene, GpuTile, PATH_HEADER, PATH_PER_LIGHT, WORKGROUP_SIZE};
use crate::methods::Methods;
use crate::probe::{PathRecord, ProbeImage};
use crate::scene::Effects;
use crate::timing::Timings;

fn key(options: &GpuRenderOptions, kernel: Kernel) -> PipelineKey {
    PipelineKey {
        methods: options.methods,
        features: options.features,
        kernel,
    }
}

/// Tiles in flight at once.
const SLOTS: usize = 2;
/// Output texels are `vec4<f32>`.
const TEXEL_BYTES: u64 = 16;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuRenderOptions {
    /// Tile edge in pixels; bounds the work in one submit.
    pub tile_size: u32,
    /// Longest wait for one tile before giving up with an error.
    pub tile_timeout: Duration,
    /// Intersection and offset methods (robust unless measuring them).
    pub methods: Methods,
    /// Sample counts, reflection depth, shutter and seed.
    pub effects: Effects,
    /// What the shader is specialised for: `Features::of` the scene, or
    /// `Features::ALL` for the generic shader.
    pub features: Features,
}

impl Default for GpuRenderOptions {
    fn default() -> Self {
        GpuRenderOptions {
            // Measured on lavapipe (2 cores), 640x480, median of 5 dispatch
            // times: SIGGRAPH 548/511/413/359 ms at tiles of 128/256/512/1024,
            // table flat (~330-350 ms): each tile ends with one core idle.
            // 512^2 = 262k invocations also comes closer to filling a large
            // GPU than 256^2 while keeping each submit short.
            tile_size: 512,
            tile_timeout: Duration::from_secs(60),
            methods: Methods::Robust,
            effects: Effects::default(),
            features: Features::ALL,
        }
    }
}

/// Most lights a `--pixel` path record lists (a 1 MiB output buffer).
const PATH_MAX_LIGHTS: u32 = 21_000;

/// What one run of the tile loop computes.
#[derive(Clone, Copy, Debug)]
enum Job {
    /// `Kernel::Render` or `Kernel::ProbeTile` over the whole image.
    Image(Kernel),
    /// The path record of one pixel.
    Pixel([u32; 2]),
}

/// A device with the trace pipeline built; renders any number of scenes.
pub struct GpuRenderer {
    ctx: Context,
    pipeline: TracePipeline,
}

#[derive(Clone, Copy, Debug)]
struct TileRect {
    origin: [u32; 2],
    size: [u32; 2],
}

/// Per-render Vulkan objects that are not buffers, destroyed on drop.
struct Pools {
    shared: Arc<Shared>,
    command_pool: vk::CommandPool,
    descriptor_pool: vk::DescriptorPool,
    fences: Vec<vk::Fence>,
}

impl Drop for Pools {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        let device = &self.shared.device;
        // SAFETY: every fence was waited on (or never submitted) before drop;
        // destroying the pools frees their command buffers and sets.
        unsafe {
            for &f in &self.fences {
                device.destroy_fence(f, None);
            }
            device.destroy_descriptor_pool(self.descriptor_pool, None);
            device.destroy_command_pool(self.command_pool, None);
        }
    }
}

struct Slot {
    tile: Buffer,
    output: Buffer,
    readback: Buffer,
    command: vk::CommandBuffer,
    fence: vk::Fence,
    set: vk::DescriptorSet,
}

impl GpuRenderer {
    pub fn new(ctx: &Context) -> Result<GpuRenderer, GpuError> {
        let pipeline = TracePipeline::new(ctx)?;
        Ok(GpuRenderer {
            ctx: ctx.clone(),
            pipeline,
        })
    }

    /// Time to build the pipeline `options` call for from scratch (no cache).
    pub fn measure_build(
        &self,
        options: &GpuRenderOptions,
        kernel: Kernel,
    ) -> Result<Duration, GpuError> {
        self.pipeline.measure_build(key(options, kernel))
    }

    /// Builds (or finds in the cache) the pipeline `options` call for;
    /// returns the build time, zero when it was cached.
    pub fn prepare(
        &self,
        options: &GpuRenderOptions,
        kernel: Kernel,
    ) -> Result<Duration, GpuError> {
        Ok(self.pipeline.get(key(options, kernel))?.1)
    }

    /// Renders `scene` as seen by `camera`. `progress(tiles_done, tiles_total)`
    /// is called after each tile is read back.
    pub fn render(
        &self,
        scene: &GpuScene,
        camera: &Camera,
        background: [f32; 3],
        options: &GpuRenderOptions,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<(Framebuffer, Timings), GpuError> {
        let job = Job::Image(Kernel::Render);
        let (texels, timings) = self.run(scene, camera, background, options, job, progress)?;
        let pixels = texels.iter().map(|t| [t[0], t[1], t[2]]).collect();
        let fb = Framebuffer {
            width: camera.width,
            height: camera.height,
            pixels,
        };
        Ok((fb, timings))
    }

    /// Each pixel's primary hit and shadow verdicts (the shader's `probe_tile`).
    pub fn probe(
        &self,
        scene: &GpuScene,
        camera: &Camera,
        options: &GpuRenderOptions,
    ) -> Result<ProbeImage, GpuError> {
        let job = Job::Image(Kernel::ProbeTile);
        let (texels, _) = self.run(scene, camera, [0.0; 3], options, job, &|_, _| {})?;
        Ok(ProbeImage::from_texels(
            camera.width,
            camera.height,
            &texels,
        ))
    }

    /// The path of pixel (x, y) (the shader's `probe_pixel`).
    pub fn pixel_path(
        &self,
        scene: &GpuScene,
        camera: &Camera,
        background: [f32; 3],
        pixel: [u32; 2],
        options: &GpuRenderOptions,
    ) -> Result<PathRecord, GpuError> {
        let job = Job::Pixel(pixel);
        let (texels, _) = self.run(scene, camera, background, options, job, &|_, _| {})?;
        Ok(PathRecord::from_texels(&texels))
    }

    fn run(
        &self,
        scene: &GpuScene,
        camera: &Camera,
        background: [f32; 3],
        options: &GpuRenderOptions,
        job: Job,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<(Vec<[f32; 4]>, Timings), GpuError> {
        let shared = &self.ctx.shared;
        let device = &shared.device;
        let mut timings = Timings::default();
        let tile_edge = options.tile_size.max(WORKGROUP_SIZE);
        let (kernel, tiles, out_texels) = match job {
            Job::Image(kernel) => (
                kernel,
                tiles(camera.width, camera.height, tile_edge),
                u64::from(tile_edge) * u64::from(tile_edge),
            ),
            Job::Pixel(origin) => {
                let lights = (scene.lights.len() as u32).min(PATH_MAX_LIGHTS);
                let rect = TileRect {
                    origin,
                    size: [1, 1],
                };
                (
                    Kernel::ProbePixel,
                    vec![rect],
                    u64::from(PATH_HEADER + PATH_PER_LIGHT * lights),
                )
            }
        };
        let (pipeline, build_time) = self.pipeline.get(key(options, kernel))?;
        if !build_time.is_zero() {
            timings.add("pipeline", build_time);
        }

        let mut pools = self.create_pools()?;
        let upload_start = Instant::now();
        let frame = scene.frame(camera, background, &options.effects, &options.features);
        // (binding, name, contents) of everything uploaded once per render.
        let scene_buffers = self.upload(
            &pools,
            &[
                (0, "frame", bytemuck::bytes_of(&frame).into()),
                (2, "spheres", padded(&scene.spheres)),
                (3, "triangles", padded(&scene.triangles)),
                (4, "shading", padded(&scene.shading)),
                (5, "lights", padded(&scene.lights)),
                (6, "bvh nodes", padded(&scene.nodes)),
                (7, "primitive refs", padded(&scene.prim_refs)),
                (9, "velocities", padded(&scene.velocities)),
            ],
        )?;
        let tile_bytes = out_texels * TEXEL_BYTES;
        let mut slots = Vec::with_capacity(SLOTS);
        for i in 0..SLOTS {
            slots.push(self.create_slot(&mut pools, i, tile_bytes, &scene_buffers)?);
        }
        timings.add("upload", upload_start.elapsed());

        let mut image = match job {
            Job::Image(_) => vec![[0.0; 4]; camera.width as usize * camera.height as usize],
            Job::Pixel(_) => vec![[0.0; 4]; out_texels as usize],
        };
        let mut in_flight: std::collections::VecDeque<(usize, TileRect)> = Default::default();
        let mut done = 0u64;
        let mut dispatch = Duration::ZERO;
        let mut readback = Duration::ZERO;
        let dispatch_start = Instant::now();
        for (i, &rect) in tiles.iter().enumerate() {
            if in_flight.len() == SLOTS {
                let (s, r) = in_flight.pop_front().expect("queue is full");
                readback += self.finish_tile(&slots[s], r, job, &mut image, camera, options)?;
                done += 1;
                progress(done, tiles.len() as u64);
            }
            let slot = &mut slots[i % SLOTS];
            self.submit_tile(slot, pipeline, job, rect, out_texels)?;
            in_flight.push_back((i % SLOTS, rect));
        }
        while let Some((s, r)) = in_flight.pop_front() {
            readback += self.finish_tile(&slots[s], r, job, &mut image, camera, options)?;
            done += 1;
            progress(done, tiles.len() as u64);
        }
        dispatch += dispatch_start.elapsed().saturating_sub(readback);
        timings.add("dispatch", dispatch);
        timings.add("readback", readback);
        // SAFETY: all submitted work was waited for above.
        let _ = unsafe { device.device_wait_idle() };
        Ok((image, timings))
    }

    fn create_pools(&self) -> Result<Pools, GpuError> {
        let shared = self.ctx.shared.clone();
        let device = &shared.device;
        let mut pools = Pools {
            shared: shared.clone(),
            command_pool: vk::CommandPool::null(),
            descriptor_pool: vk::DescriptorPool::null(),
            fences: Vec::new(),
        };
        let uniform = BINDINGS
            .iter()
            .filter(|&&t| t == vk::DescriptorType::UNIFORM_BUFFER)
            .count() as u32;
        let sizes = [
            vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::UNIFORM_BUFFER)
                .descriptor_count(uniform * SLOTS as u32),
            vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count((BINDINGS.len() as u32 - uniform) * SLOTS as u32),
        ];
        // SAFETY: valid create infos on a live device; handles owned by `pools`.
        unsafe {
            pools.command_pool = device
                .create_command_pool(
                    &vk::CommandPoolCreateInfo::default()
                        .queue_family_index(shared.queue_family)
                        .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                    None,
                )
                .call("vkCreateCommandPool")?;
            pools.descriptor_pool = device
                .create_descriptor_pool(
                    &vk::DescriptorPoolCreateInfo::default()
                        .max_sets(SLOTS as u32)
                        .pool_sizes(&sizes),
                    None,
                )
                .call("vkCreateDescriptorPool")?;
        }
        Ok(pools)
    }

    fn command_buffer(&self, pools: &Pools) -> Result<vk::CommandBuffer, GpuError> {
        let info = vk::CommandBufferAllocateInfo::default()
            .command_pool(pools.command_pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the pool is live and owned by this thread.
        Ok(
            unsafe { self.ctx.shared.device.allocate_command_buffers(&info) }
                .call("vkAllocateCommandBuffers")?[0],
        )
    }

    fn fence(&self, pools: &mut Pools) -> Result<vk::Fence, GpuError> {
        // SAFETY: plain creation on a live device; destroyed with `pools`.
        let fence = unsafe {
            self.ctx
                .shared
                .device
                .create_fence(&vk::FenceCreateInfo::default(), None)
        }
        .call("vkCreateFence")?;
        pools.fences.push(fence);
        Ok(fence)
    }

    /// Copies each list into a new device-local buffer through one staging
    /// buffer and one submit.
    fn upload(
        &self,
        pools: &Pools,
        items: &[(u32, &str, std::borrow::Cow<'_, [u8]>)],
    ) -> Result<Vec<(u32, Buffer)>, GpuError> {
        let shared = &self.ctx.shared;
        let device = &shared.device;
        let total: u64 = items.iter().map(|(_, _, b)| b.len() as u64).sum();
        let mut staging = Buffer::new(
            shared,
            "staging",
            total,
            vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::CpuToGpu,
        )?;
        let mut bytes = Vec::with_capacity(total as usize);
        let mut buffers = Vec::with_capacity(items.len());
        let mut regions = Vec::with_capacity(items.len());
        for (binding, name, data) in items {
            let size = data.len() as u64;
            regions.push(vk::BufferCopy {
                src_offset: bytes.len() as u64,
                dst_offset: 0,
                size,
            });
            bytes.extend_from_slice(data);
            let usage = usage_for(BINDINGS[*binding as usize]);
            buffers.push((
                *binding,
                Buffer::new(
                    shared,
                    name,
                    size,
                    usage | vk::BufferUsageFlags::TRANSFER_DST,
                    MemoryLocation::GpuOnly,
                )?,
            ));
        }
        staging.write(&bytes);
        let cmd = self.command_buffer(pools)?;
        // SAFETY: recording into a fresh command buffer; every buffer lives
        // until the wait below returns.
        unsafe {
            device
                .begin_command_buffer(
                    cmd,
                    &vk::CommandBufferBeginInfo::default()
                        .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )
                .call("vkBeginCommandBuffer")?;
            for ((_, buffer), region) in buffers.iter().zip(&regions) {
                device.cmd_copy_buffer(cmd, staging.raw, buffer.raw, &[*region]);
            }
            let barrier = vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
                .dst_access_mask(vk::AccessFlags::SHADER_READ | vk::AccessFlags::UNIFORM_READ);
            device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::DependencyFlags::empty(),
                &[barrier],
                &[],
                &[],
            );
            device.end_command_buffer(cmd).call("vkEndCommandBuffer")?;
            let cmds = [cmd];
            let submit = vk::SubmitInfo::default().command_buffers(&cmds);
            device
                .queue_submit(shared.queue, &[submit], vk::Fence::null())
                .call("vkQueueSubmit")?;
            device
                .queue_wait_idle(shared.queue)
                .call("vkQueueWaitIdle")?;
            device.free_command_buffers(pools.command_pool, &cmds);
        }
        Ok(buffers)
    }

    fn create_slot(
        &self,
        pools: &mut Pools,
        index: usize,
        tile_bytes: u64,
        scene: &[(u32, Buffer)],
    ) -> Result<Slot, GpuError> {
        let shared = &self.ctx.shared;
        let tile = Buffer::new(
            shared,
            &format!("tile {index}"),
            std::mem::size_of::<GpuTile>() as u64,
            vk::BufferUsageFlags::UNIFORM_BUFFER,
            MemoryLocation::CpuToGpu,
        )?;
        let output = Buffer::new(
            shared,
            &format!("tile output {index}"),
            tile_bytes,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::GpuOnly,
        )?;
        let readback = Buffer::new(
            shared,
            &format!("tile readback {index}"),
            tile_bytes,
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )?;
        let set_layouts = [self.pipeline.set_layout];
        // SAFETY: the pool was sized for SLOTS sets of this layout.
        let set = unsafe {
            shared.device.allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default()
                    .descriptor_pool(pools.descriptor_pool)
                    .set_layouts(&set_layouts),
            )
        }
        .call("vkAllocateDescriptorSets")?[0];
        let mut bound: Vec<(u32, &Buffer)> = scene.iter().map(|(b, buf)| (*b, buf)).collect();
        bound.push((1, &tile));
        bound.push((8, &output));
        bound.sort_by_key(|(b, _)| *b);
        debug_assert!(bound.iter().map(|(b, _)| *b as usize).eq(0..BINDINGS.len()));
        let infos: Vec<[vk::DescriptorBufferInfo; 1]> = bound
            .iter()
            .map(|(_, b)| {
                [vk::DescriptorBufferInfo::default()
                    .buffer(b.raw)
                    .range(vk::WHOLE_SIZE)]
            })
            .collect();
        let writes: Vec<vk::WriteDescriptorSet> = bound
            .iter()
            .zip(&infos)
            .map(|((binding, _), info)| {
                vk::WriteDescriptorSet::default()
                    .dst_set(set)
                    .dst_binding(*binding)
                    .descriptor_type(BINDINGS[*binding as usize])
                    .buffer_info(info)
            })
            .collect();
        // SAFETY: every write names a live buffer of the right usage.
        unsafe { shared.device.update_descriptor_sets(&writes, &[]) };
        let command = self.command_buffer(pools)?;
        let fence = self.fence(pools)?;
        Ok(Slot {
            tile,
            output,
            readback,
            command,
            fence,
            set,
        })
    }

    fn submit_tile(
        &self,
        slot: &mut Slot,
        pipeline: vk::Pipeline,
        job: Job,
        rect: TileRect,
        out_texels: u64,
    ) -> Result<(), GpuError> {
        let shared = &self.ctx.shared;
        let device = &shared.device;
        slot.tile.write(bytemuck::bytes_of(&GpuTile {
            origin: rect.origin,
            size: rect.size,
        }));
        let (groups, texels) = match job {
            Job::Image(_) => (
                [
                    rect.size[0].div_ceil(WORKGROUP_SIZE),
                    rect.size[1].div_ceil(WORKGROUP_SIZE),
                ],
                u64::from(rect.size[0]) * u64::from(rect.size[1]),
            ),
            Job::Pixel(_) => ([1, 1], out_texels),
        };
        let bytes = texels * TEXEL_BYTES;
        // SAFETY: the slot's previous submission was waited for (finish_tile)
        // before this reuse; all handles are live.
        unsafe {
            device.reset_fences(&[slot.fence]).call("vkResetFences")?;
            device
                .reset_command_buffer(slot.command, vk::CommandBufferResetFlags::empty())
                .call("vkResetCommandBuffer")?;
            device
                .begin_command_buffer(
                    slot.command,
                    &vk::CommandBufferBeginInfo::default()
                        .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )
                .call("vkBeginCommandBuffer")?;
            device.cmd_bind_pipeline(slot.command, vk::PipelineBindPoint::COMPUTE, pipeline);
            device.cmd_bind_descriptor_sets(
                slot.command,
                vk::PipelineBindPoint::COMPUTE,
                self.pipeline.layout,
                0,
                &[slot.set],
                &[],
            );
            device.cmd_dispatch(slot.command, groups[0], groups[1], 1);
            let to_copy = vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::SHADER_WRITE)
                .dst_access_mask(vk::AccessFlags::TRANSFER_READ);
            device.cmd_pipeline_barrier(
                slot.command,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::PipelineStageFlags::TRANSFER,
                vk::DependencyFlags::empty(),
                &[to_copy],
                &[],
                &[],
            );
            device.cmd_copy_buffer(
                slot.command,
                slot.output.raw,
                slot.readback.raw,
                &[vk::BufferCopy {
                    src_offset: 0,
                    dst_offset: 0,
                    size: bytes,
                }],
            );
            let to_host = vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
                .dst_access_mask(vk::AccessFlags::HOST_READ);
            device.cmd_pipeline_barrier(
                slot.command,
                vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::HOST,
                vk::DependencyFlags::empty(),
                &[to_host],
                &[],
                &[],
            );
            device
                .end_command_buffer(slot.command)
                .call("vkEndCommandBuffer")?;
            let cmds = [slot.command];
            let submit = vk::SubmitInfo::default().command_buffers(&cmds);
            device
                .queue_submit(shared.queue, &[submit], slot.fence)
                .map_err(|r| self.fail(r, rect, "vkQueueSubmit", 0))?;
        }
        Ok(())
    }

    /// Waits for a tile and copies it into `image`; returns the copy time.
    fn finish_tile(
        &self,
        slot: &Slot,
        rect: TileRect,
        job: Job,
        image: &mut [[f32; 4]],
        camera: &Camera,
        options: &GpuRenderOptions,
    ) -> Result<Duration, GpuError> {
        let timeout = options.tile_timeout.as_nanos().min(u128::from(u64::MAX)) as u64;
        // SAFETY: the fence belongs to this device and was submitted.
        unsafe {
            self.ctx
                .shared
                .device
                .wait_for_fences(&[slot.fence], true, timeout)
        }
        .map_err(|r| self.fail(r, rect, "vkWaitForFences", options.tile_timeout.as_secs()))?;
        let start = Instant::now();
        let texels: &[[f32; 4]] = bytemuck::cast_slice(slot.readback.mapped());
        if let Job::Pixel(_) = job {
            image.copy_from_slice(&texels[..image.len()]);
            return Ok(start.elapsed());
        }
        let [x0, y0] = rect.origin;
        let [w, h] = rect.size;
        for row in 0..h {
            let src = &texels[(row * w) as usize..((row + 1) * w) as usize];
            let start_px = ((y0 + row) * camera.width + x0) as usize;
            image[start_px..start_px + w as usize].copy_from_slice(src);
        }
        Ok(start.elapsed())
    }

    fn fail(
        &self,
        result: vk::Result,
        rect: TileRect,
        call: &'static str,
        seconds: u64,
    ) -> GpuError {
        let [x, y] = rect.origin;
        match result {
            vk::Result::TIMEOUT => {
                self.ctx.shared.poison();
                GpuError::Timeout { x, y, seconds }
            }
            vk::Result::ERROR_DEVICE_LOST => {
                self.ctx.shared.poison();
                GpuError::DeviceLost { x, y }
            }
            result => GpuError::Vk { call, result },
        }
    }
}

fn usage_for(ty: vk::DescriptorType) -> vk::BufferUsageFlags {
    if ty == vk::DescriptorType::UNIFORM_BUFFER {
        vk::BufferUsageFlags::UNIFORM_BUFFER
    } else {
        vk::BufferUsageFlags::STORAGE_BUFFER
    }
}

fn tiles(width: u32, height: u32, edge: u32) -> Vec<TileRect> {
    let mut out = Vec::new();
    for y in (0..height).step_by(edge as usize) {
        for x in (0..width).step_by(edge as usize) {
            out.push(TileRect {
                origin: [x, y],
                size: [edge.min(width - x), edge.min(height - y)],
            });
        }
    }
    out
}
