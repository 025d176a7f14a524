//! What a render needs on the device, created once per renderer and reused
//! by every tile, pass and frame: command buffers, descriptor sets, fences,
//! timestamp queries, and the scene, tile and staging buffers, each
//! recreated only when a scene needs a larger one.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;

use super::job::{
    Packing, B_FRAME, B_MATERIALS, B_OUTPUT, B_SKIPS, B_STATE, B_STATUS, B_TILE, MAX_CHAIN, SLOTS,
    TEXEL_BYTES,
};

use super::plan::{ListForms, Split, Upload};
use crate::gpu::bindings::{Lists, BINDINGS};
use crate::gpu::buffer::Buffer;
use crate::gpu::commands::{command_pool, memory_barrier, submit_and_wait};
use crate::gpu::context::Shared;
use crate::gpu::error::{GpuError, VkResultExt};
use crate::gpu::pipeline::TracePipeline;
use crate::gpu::small_pipeline::SmallPipeline;
use crate::layout::{GpuStatus, GpuTile, ADDRESS_LISTS, SPLIT_LISTS, UNIFORM_FIRST};

/// The device a render runs on: its shared state and the trace pipeline.
#[derive(Clone, Copy)]
pub(super) struct Gpu<'a> {
    pub(super) shared: &'a Arc<Shared>,
    pub(super) pipeline: &'a TracePipeline,
}

impl Gpu<'_> {
    /// The list forms a render with `options` may use on this device.
    pub(super) fn forms(&self, options: &super::job::GpuRenderOptions) -> ListForms {
        let profile = &self.shared.info.profile;
        ListForms {
            address: options.uniform_lists && profile.address_lists,
            uniform: options.uniform_lists && profile.uniform_copies,
        }
    }
}

/// The Vulkan objects of a renderer that are not buffers, destroyed on drop.
pub(super) struct Pools {
    pub(super) shared: Arc<Shared>,
    pub(super) command_pool: vk::CommandPool,
    pub(super) descriptor_pool: vk::DescriptorPool,
    pub(super) fences: Vec<vk::Fence>,
    /// Two timestamps per pass a slot can have in flight, around its
    /// dispatch (null when the queue has none).
    pub(super) queries: vk::QueryPool,
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
            let _ = device.device_wait_idle();
            for &f in &self.fences {
                device.destroy_fence(f, None);
            }
            device.destroy_descriptor_pool(self.descriptor_pool, None);
            device.destroy_command_pool(self.command_pool, None);
            if self.queries != vk::QueryPool::null() {
                device.destroy_query_pool(self.queries, None);
            }
        }
    }
}

/// A buffer that is reused while it is large enough.
pub(super) struct Reusable {
    pub(super) name: String,
    pub(super) usage: vk::BufferUsageFlags,
    pub(super) location: MemoryLocation,
    pub(super) buffer: Option<Buffer>,
    /// What was last uploaded into `buffer`: its length and xxh3 digest
    /// (None once the buffer is recreated), so that a render whose list
    /// did not change (an animation's static triangles) uploads nothing.
    pub(super) holds: Option<(usize, u64)>,
}

impl Reusable {
    pub(super) fn new(
        name: &str,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Reusable {
        Reusable {
            name: name.to_string(),
            usage,
            location,
            buffer: None,
            holds: None,
        }
    }

    /// The buffer, recreated first when it holds fewer than `size` bytes.
    pub(super) fn at_least(
        &mut self,
        shared: &Arc<Shared>,
        size: u64,
    ) -> Result<&mut Buffer, GpuError> {
        let size = size.max(16);
        if self.buffer.as_ref().is_none_or(|b| b.size < size) {
            self.buffer = None; // free before allocating the larger one
            self.holds = None;
            self.buffer = Some(Buffer::new(
                shared,
                &self.name,
                size,
                self.usage,
                self.location,
            )?);
        }
        Ok(self.buffer.as_mut().expect("just ensured"))
    }

    pub(super) fn get(&self) -> &Buffer {
        self.buffer.as_ref().expect("allocated before use")
    }
}

pub(super) struct Slot {
    pub(super) tile: Buffer,
    /// A pass's status, counted by the shader's atomics in device memory.
    pub(super) status: Buffer,
    /// Each pass in flight's status, copied after it, as the host reads
    /// them.
    pub(super) log: Buffer,
    pub(super) output: Reusable,
    /// The output's texels as the host reads them (`Packing`).
    pub(super) packed: Reusable,
    pub(super) readback: Reusable,
    pub(super) state: Reusable,
    /// A command buffer and a fence for each pass it can have in flight
    /// (`MAX_CHAIN`).
    pub(super) commands: Vec<vk::CommandBuffer>,
    pub(super) fences: Vec<vk::Fence>,
    /// Its passes submitted and not yet waited for.
    pub(super) submitted: usize,
    /// A descriptor set of each layout, in `Lists::ALL` order.
    pub(super) sets: [vk::DescriptorSet; 4],
    /// Its first timestamp in `Pools::queries` (null pool: none); two a
    /// pass in flight.
    pub(super) queries: vk::QueryPool,
    pub(super) first_query: u32,
}

/// Everything a render needs on the device, kept across renders.
pub(super) struct Resources {
    // Buffers and sets before pools: drop order frees buffers first.
    pub(super) slots: Vec<Slot>,
    /// Device-local scene buffers by binding (frame and scene lists).
    pub(super) scene: Vec<(usize, Reusable)>,
    pub(super) staging: Reusable,
    /// The whole image, packed, as the host reads it: each tile's copy
    /// lands in its place (`job::gather_bytes`).
    pub(super) gathered: Reusable,
    pub(super) upload_command: vk::CommandBuffer,
    pub(super) upload_fence: vk::Fence,
    /// Each `Packing`'s shader, one set per slot; built when a render
    /// first packs so.
    pub(super) pack: [Option<SmallPipeline>; 2],
    /// Held for its drop: frees the command buffers, sets and fences.
    pub(super) _pools: Pools,
}

impl Slot {
    /// The status of its `i`th pass in flight, once waited for.
    pub(super) fn status(&self, i: u32) -> GpuStatus {
        let size = std::mem::size_of::<GpuStatus>();
        let at = i as usize * size;
        bytemuck::pod_read_unaligned(&self.log.mapped()[at..at + size])
    }
}

impl Gpu<'_> {
    pub(super) fn create_resources(&self) -> Result<Resources, GpuError> {
        let shared = self.shared.clone();
        let device = &shared.device;
        let mut pools = Pools {
            shared: shared.clone(),
            command_pool: vk::CommandPool::null(),
            descriptor_pool: vk::DescriptorPool::null(),
            fences: Vec::new(),
            queries: vk::QueryPool::null(),
        };
        // Each slot has a set of each layout.
        let all = Lists::ALL.iter().flat_map(|l| l.bindings());
        let uniform = all
            .clone()
            .filter(|&b| BINDINGS[b] == vk::DescriptorType::UNIFORM_BUFFER)
            .count() as u32;
        let storage = all.count() as u32 - uniform;
        let sizes = [
            vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::UNIFORM_BUFFER)
                .descriptor_count(uniform * SLOTS as u32),
            vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(storage * SLOTS as u32),
        ];
        // SAFETY: valid create infos on a live device; handles owned by `pools`.
        unsafe {
            pools.command_pool = command_pool(&shared)?;
            pools.descriptor_pool = device
                .create_descriptor_pool(
                    &vk::DescriptorPoolCreateInfo::default()
                        .max_sets((Lists::ALL.len() * SLOTS) as u32)
                        .pool_sizes(&sizes),
                    None,
                )
                .call("vkCreateDescriptorPool")?;
            if shared.limits.timestamp_bits > 0 {
                pools.queries = device
                    .create_query_pool(
                        &vk::QueryPoolCreateInfo::default()
                            .query_type(vk::QueryType::TIMESTAMP)
                            .query_count(2 * MAX_CHAIN * SLOTS as u32),
                        None,
                    )
                    .call("vkCreateQueryPool")?;
            }
        }
        let upload_command = self.command_buffer(&pools)?;
        let upload_fence = self.fence(&mut pools)?;
        let mut slots = Vec::with_capacity(SLOTS);
        for i in 0..SLOTS {
            slots.push(self.create_slot(&mut pools, i)?);
        }
        let scene = [
            (B_FRAME, "frame"),
            (2, "spheres"),
            (3, "triangles"),
            (4, "normals"),
            (5, "lights"),
            (6, "bvh nodes"),
            (7, "primitive refs"),
            (9, "velocities"),
            (B_MATERIALS, "materials"),
            (B_SKIPS, "light skips"),
            (UNIFORM_FIRST, "spheres (uniform copy)"),
            (UNIFORM_FIRST + 1, "triangles (uniform copy)"),
            (UNIFORM_FIRST + 2, "bvh nodes (uniform copy)"),
            (UNIFORM_FIRST + 3, "primitive refs (uniform copy)"),
        ]
        .into_iter()
        .map(|(binding, name)| {
            let mut usage = usage_for(BINDINGS[binding]) | vk::BufferUsageFlags::TRANSFER_DST;
            if self.shared.limits.device_addresses && ADDRESS_LISTS.iter().any(|l| l.0 == binding) {
                usage |= vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
            }
            (binding, Reusable::new(name, usage, MemoryLocation::GpuOnly))
        })
        .collect();
        Ok(Resources {
            slots,
            scene,
            staging: Reusable::new(
                "staging",
                vk::BufferUsageFlags::TRANSFER_SRC,
                MemoryLocation::CpuToGpu,
            ),
            // Host-visible, coherent and, where the device has it, cached:
            // the host reads it once a render.
            gathered: Reusable::new(
                "image readback",
                vk::BufferUsageFlags::TRANSFER_DST,
                MemoryLocation::GpuToCpu,
            ),
            upload_command,
            upload_fence,
            pack: [None, None],
            _pools: pools,
        })
    }

    pub(super) fn command_buffer(&self, pools: &Pools) -> Result<vk::CommandBuffer, GpuError> {
        let info = vk::CommandBufferAllocateInfo::default()
            .command_pool(pools.command_pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the pool is live and owned by this thread.
        Ok(
            unsafe { self.shared.device.allocate_command_buffers(&info) }
                .call("vkAllocateCommandBuffers")?[0],
        )
    }

    pub(super) fn fence(&self, pools: &mut Pools) -> Result<vk::Fence, GpuError> {
        // SAFETY: plain creation on a live device; destroyed with `pools`.
        let fence = unsafe {
            self.shared
                .device
                .create_fence(&vk::FenceCreateInfo::default(), None)
        }
        .call("vkCreateFence")?;
        pools.fences.push(fence);
        Ok(fence)
    }

    /// Copies each list into its device-local buffer through the staging
    /// buffer, one list per submit so staging never exceeds the largest
    /// list; a list whose buffer already holds the same bytes is skipped.
    /// Returns the bytes uploaded.
    pub(super) fn upload(&self, res: &mut Resources, uploads: &[Upload]) -> Result<u64, GpuError> {
        let shared = &self.shared;
        let device = &shared.device;
        let mut uploaded = 0;
        for u in uploads {
            let size = u.bytes.len() as u64;
            let holds = (u.bytes.len(), xxhash_rust::xxh3::xxh3_64(&u.bytes));
            let reusable = scene_reusable(&mut res.scene, u.binding);
            let dst = reusable.at_least(shared, size)?.raw;
            if reusable.holds == Some(holds) {
                continue;
            }
            // Unknown until the copy below is waited for.
            reusable.holds = None;
            uploaded += size;
            let staging = res.staging.at_least(shared, size)?;
            staging.write(&u.bytes);
            // The previous upload was waited for, so the command buffer,
            // staging buffer and fence are free; every buffer lives until
            // the wait returns.
            submit_and_wait(
                shared,
                (res.upload_command, res.upload_fence),
                (&[], &[]),
                u64::MAX,
                |cmd| {
                    // SAFETY: recording into the upload's own command buffer;
                    // both buffers are live.
                    unsafe {
                        device.cmd_copy_buffer(
                            cmd,
                            staging.raw,
                            dst,
                            &[vk::BufferCopy {
                                src_offset: 0,
                                dst_offset: 0,
                                size,
                            }],
                        );
                        memory_barrier(
                            device,
                            cmd,
                            (
                                vk::PipelineStageFlags::TRANSFER,
                                vk::AccessFlags::TRANSFER_WRITE,
                            ),
                            (
                                vk::PipelineStageFlags::COMPUTE_SHADER,
                                vk::AccessFlags::SHADER_READ | vk::AccessFlags::UNIFORM_READ,
                            ),
                        );
                    }
                },
            )?;
            scene_reusable(&mut res.scene, u.binding).holds = Some(holds);
        }
        Ok(uploaded)
    }

    /// Points each slot's `packing` set at its output (`out_texels`
    /// texels) and its packed texels, building that shader the first time.
    pub(super) fn bind_pack(
        &self,
        res: &mut Resources,
        packing: Packing,
        out_texels: u64,
    ) -> Result<(), GpuError> {
        let built = &mut res.pack[packing.index()];
        if built.is_none() {
            let (what, wgsl, entry) = packing.shader();
            *built = Some(SmallPipeline::new(
                self.shared,
                what,
                wgsl,
                entry,
                2,
                SLOTS as u32,
            )?);
        }
        let pack = built.as_ref().expect("just built");
        let bytes = packing.buffer_bytes(out_texels);
        for (i, slot) in res.slots.iter_mut().enumerate() {
            let packed = slot.packed.at_least(self.shared, bytes)?;
            let output = slot.output.get();
            pack.bind(
                i,
                &[(output.raw, out_texels * TEXEL_BYTES), (packed.raw, bytes)],
            );
        }
        Ok(())
    }

    pub(super) fn create_slot(&self, pools: &mut Pools, index: usize) -> Result<Slot, GpuError> {
        let shared = &self.shared;
        let tile = Buffer::new(
            shared,
            &format!("tile {index}"),
            std::mem::size_of::<GpuTile>() as u64,
            vk::BufferUsageFlags::UNIFORM_BUFFER | vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuOnly,
        )?;
        // Reset by each pass, and copied after it into the log the host
        // reads: the shader's atomics stay in device memory.
        let status_bytes = std::mem::size_of::<GpuStatus>() as u64;
        let status = Buffer::new(
            shared,
            &format!("status {index}"),
            status_bytes,
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::TRANSFER_DST
                | vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::GpuOnly,
        )?;
        let log = Buffer::new(
            shared,
            &format!("status log {index}"),
            status_bytes * u64::from(MAX_CHAIN),
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )?;
        let set_layouts = Lists::ALL.map(|l| self.pipeline.layout(l).set);
        // SAFETY: the pool was sized for SLOTS sets of each layout.
        let sets = unsafe {
            shared.device.allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default()
                    .descriptor_pool(pools.descriptor_pool)
                    .set_layouts(&set_layouts),
            )
        }
        .call("vkAllocateDescriptorSets")?;
        let sets = [sets[0], sets[1], sets[2], sets[3]];
        let mut commands = Vec::new();
        let mut fences = Vec::new();
        for _ in 0..MAX_CHAIN {
            commands.push(self.command_buffer(pools)?);
            fences.push(self.fence(pools)?);
        }
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        Ok(Slot {
            tile,
            status,
            log,
            output: Reusable::new(
                &format!("tile output {index}"),
                storage | vk::BufferUsageFlags::TRANSFER_SRC,
                MemoryLocation::GpuOnly,
            ),
            packed: Reusable::new(
                &format!("tile pixels {index}"),
                storage | vk::BufferUsageFlags::TRANSFER_SRC,
                MemoryLocation::GpuOnly,
            ),
            readback: Reusable::new(
                &format!("tile readback {index}"),
                vk::BufferUsageFlags::TRANSFER_DST,
                MemoryLocation::GpuToCpu,
            ),
            state: Reusable::new(
                &format!("pixel state {index}"),
                storage,
                MemoryLocation::GpuOnly,
            ),
            commands,
            fences,
            submitted: 0,
            sets,
            queries: pools.queries,
            first_query: 2 * MAX_CHAIN * index as u32,
        })
    }

    /// Points the slot's descriptor set of the render's layout (`lists`) at
    /// its buffers, each bound with exactly its contents' size (the shader's
    /// `arrayLength` sees it), a split list chunk by chunk.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn bind_slot(
        &self,
        slot: &mut Slot,
        scene: &[(usize, Reusable)],
        uploads: &[Upload],
        split: &Split,
        lists: Lists,
        out_bytes: u64,
        state_bytes: u64,
    ) -> Result<(), GpuError> {
        let shared = &self.shared;
        slot.output.at_least(shared, out_bytes)?;
        slot.state.at_least(shared, state_bytes)?;
        let scene_list = |binding: usize| {
            let buffer = scene
                .iter()
                .find(|(b, _)| *b == binding)
                .map(|(_, r)| r.get().raw)
                .expect("uploaded");
            let len = uploads
                .iter()
                .find(|u| u.binding == binding)
                .map(|u| u.bytes.len() as u64)
                .expect("uploaded");
            (buffer, len)
        };
        let bound: Vec<(usize, vk::Buffer, u64, u64)> = lists
            .bindings()
            .map(|binding| match binding {
                B_TILE => (binding, slot.tile.raw, 0, slot.tile.size),
                B_OUTPUT => (binding, slot.output.get().raw, 0, out_bytes),
                B_STATE => (binding, slot.state.get().raw, 0, state_bytes),
                B_STATUS => (binding, slot.status.raw, 0, slot.status.size),
                _ => match Split::chunk_of(binding) {
                    Some((j, k)) => {
                        let (buffer, len) = scene_list(SPLIT_LISTS[j].0);
                        let (offset, range) = split.range(j, k, len);
                        (binding, buffer, offset, range)
                    }
                    None => {
                        let (buffer, len) = scene_list(binding);
                        (binding, buffer, 0, len)
                    }
                },
            })
            .collect();
        let infos: Vec<[vk::DescriptorBufferInfo; 1]> = bound
            .iter()
            .map(|&(_, buffer, offset, range)| {
                [vk::DescriptorBufferInfo::default()
                    .buffer(buffer)
                    .offset(offset)
                    .range(range)]
            })
            .collect();
        let set = slot.sets[lists.index()];
        let writes: Vec<vk::WriteDescriptorSet> = infos
            .iter()
            .zip(&bound)
            .map(|(info, &(binding, ..))| {
                vk::WriteDescriptorSet::default()
                    .dst_set(set)
                    .dst_binding(binding as u32)
                    .descriptor_type(BINDINGS[binding])
                    .buffer_info(info)
            })
            .collect();
        // SAFETY: every write names a live buffer of the right usage, and no
        // submission using the set is pending (all were waited for).
        unsafe { shared.device.update_descriptor_sets(&writes, &[]) };
        Ok(())
    }
}

/// The scene buffer of `binding`, holding at least `size` bytes.
pub(super) fn scene_buffer<'a>(
    scene: &'a mut [(usize, Reusable)],
    shared: &Arc<Shared>,
    binding: usize,
    size: u64,
) -> Result<&'a mut Buffer, GpuError> {
    scene_reusable(scene, binding).at_least(shared, size)
}

fn scene_reusable(scene: &mut [(usize, Reusable)], binding: usize) -> &mut Reusable {
    scene
        .iter_mut()
        .find(|(b, _)| *b == binding)
        .map(|(_, r)| r)
        .expect("every upload has a scene buffer")
}

pub(super) fn usage_for(ty: vk::DescriptorType) -> vk::BufferUsageFlags {
    if ty == vk::DescriptorType::UNIFORM_BUFFER {
        vk::BufferUsageFlags::UNIFORM_BUFFER
    } else {
        vk::BufferUsageFlags::STORAGE_BUFFER
    }
}
