//! Rendering a packed scene on the GPU, tile by tile and pass by pass.
//!
//! A tile's work is split into passes of bounded size (the shader's
//! `render_tile` runs each pixel's work as a resumable state machine with a
//! budget of loop iterations per pass), so no invocation runs into a driver's
//! loop limit and no submission runs long enough to trip a watchdog, whatever
//! the scene asks for. Each pass is one submit with its own fence; after it the
//! host reads the pass's status: pixels left (another pass), or pixels cut
//! short (the tile is redone with a smaller budget, or the render fails naming
//! the pixel). A tile's first pass runs a shader that keeps no pixel state;
//! a tile with pixels left after it is redone with the resumable one
//! (`TileWork::resumable`). Two tile slots alternate, so the GPU works on
//! one while the host reads the other back. A tile is dispatched into a
//! device-local buffer and copied into a host-visible one, so shaders never
//! write across PCIe.
//!
//! Everything a render needs on the device (command buffers, descriptor sets,
//! fences, scene, tile and staging buffers) is created once per renderer and
//! reused by every tile, pass and frame; a buffer is recreated only when a
//! scene needs a larger one, so memory stays flat over an animation.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use ash::vk;
use gpu_allocator::MemoryLocation;

use super::buffer::Buffer;
use super::context::DeviceLimits;
use super::context::{Context, Shared};
use super::error::{GpuError, VkResultExt};
use super::pipeline::{Kernel, Lists, PipelineKey, TracePipeline, BINDINGS};
use crate::camera::Camera;
use crate::framebuffer::Framebuffer;
use crate::info::Features;
use crate::layout::{
    padded, uniform_copy, uniform_copy_bytes, uniform_copy_form, CopyForm, GpuMaterial,
    GpuPixelState, GpuScene, GpuStatus, GpuTile, GpuTriangle, GpuTriangleNormals, GpuWideNode,
    ADDRESS_LISTS, PATH_HEADER, PATH_PER_LIGHT, SPLIT_CHUNKS, SPLIT_FIRST, SPLIT_LISTS,
    UNIFORM_FIRST, UNIFORM_LISTS, UNIFORM_LIST_BYTES, WORKGROUP_SIZE,
};
use crate::methods::Methods;
use crate::probe::{PathRecord, ProbeImage};
use crate::scene::Effects;
use crate::timing::{Timings, CLOSEST_RAYS, GPU_TIME_NS, SHADOW_RAYS};

/// The pipeline for `kernel` over `scene`; a render's is its tiles' first
/// pass without pixel state unless `resumable` (`TileWork::resumable`).
fn key(
    options: &GpuRenderOptions,
    kernel: Kernel,
    lists: Lists,
    scene: &GpuScene,
    uploads: &[Upload],
    resumable: bool,
) -> PipelineKey {
    let triangles = uploads
        .iter()
        .find(|u| u.binding == UNIFORM_LISTS[1].0)
        .map_or(0, |u| u.bytes.len() as u64);
    PipelineKey {
        methods: options.methods,
        features: options.features,
        lists,
        light_skips: !scene.skips.is_empty(),
        corners: lists == Lists::Uniform && uniform_copy_form(1, triangles) == CopyForm::Corners,
        leaf_order: scene.leaf_order(),
        one_pass: kernel == Kernel::Render && !resumable,
        kernel,
    }
}

/// Element sizes of the `SPLIT_LISTS`, in their order.
const SPLIT_STRIDES: [u64; 4] = [
    std::mem::size_of::<GpuTriangle>() as u64,
    std::mem::size_of::<GpuTriangleNormals>() as u64,
    std::mem::size_of::<GpuMaterial>() as u64,
    std::mem::size_of::<GpuWideNode>() as u64,
];

/// How one render lays the `SPLIT_LISTS` over bindings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Split {
    /// Some list exceeds one binding: the split layout and shader.
    split: bool,
    /// Per list: log2 of the elements per chunk (0 when not split).
    shifts: [u32; 4],
    /// Per list: bytes per chunk (the whole list when not split).
    chunk_bytes: [u64; 4],
}

impl Split {
    /// The chunking of lists of `lens` bytes under `limits`; an error when a
    /// list needs more than `SPLIT_CHUNKS` bindings.
    fn plan(lens: [u64; 4], limits: &DeviceLimits) -> Result<Split, GpuError> {
        let range = limits.max_storage_range;
        if lens.iter().all(|&len| len <= range) {
            return Ok(Split {
                split: false,
                shifts: [0; 4],
                chunk_bytes: lens,
            });
        }
        let mut plan = Split {
            split: true,
            shifts: [0; 4],
            chunk_bytes: [0; 4],
        };
        for (j, (&len, &stride)) in lens.iter().zip(&SPLIT_STRIDES).enumerate() {
            let (binding, name) = SPLIT_LISTS[j];
            // A power of two of elements, so the shader finds the chunk with a
            // shift; at least one element, at most 2^31.
            let elems = (range / stride).max(1);
            let shift = elems.ilog2().min(31);
            let chunk = stride << shift;
            let alignment = limits.storage_offset_alignment;
            if !chunk.is_multiple_of(alignment) {
                return Err(GpuError::Limit {
                    what: format!("a chunk of the {name} buffer (binding {binding})"),
                    needed: chunk,
                    limit_name: "minStorageBufferOffsetAlignment, a multiple of",
                    limit: alignment,
                    unit: " bytes",
                    hint: "render fewer primitives on this device, or use --backend cpu".into(),
                });
            }
            let capacity = chunk * SPLIT_CHUNKS as u64;
            if len > capacity {
                return Err(GpuError::Limit {
                    what: format!(
                        "the {name} buffer (binding {binding}, split over {SPLIT_CHUNKS} bindings)"
                    ),
                    needed: len,
                    limit_name: "maxStorageBufferRange per binding",
                    limit: capacity,
                    unit: " bytes",
                    hint: "render fewer primitives on this device, or use --backend cpu".into(),
                });
            }
            plan.shifts[j] = shift;
            plan.chunk_bytes[j] = chunk;
        }
        Ok(plan)
    }

    /// (list, chunk) when `binding` shows a chunk of a split list.
    fn chunk_of(binding: usize) -> Option<(usize, usize)> {
        if let Some(j) = SPLIT_LISTS.iter().position(|&(b, _)| b == binding) {
            return Some((j, 0));
        }
        let extra = binding.checked_sub(SPLIT_FIRST)?;
        let per = SPLIT_CHUNKS - 1;
        (extra < per * SPLIT_LISTS.len()).then(|| (extra / per, extra % per + 1))
    }

    /// The (offset, range) chunk `k` of list `j` of `len` bytes is bound to.
    /// A chunk past the list's end repeats chunk 0: the shader never reads it,
    /// but Vulkan wants every binding of the layout written.
    fn range(&self, j: usize, k: usize, len: u64) -> (u64, u64) {
        let chunk = self.chunk_bytes[j];
        let offset = chunk * k as u64;
        if offset < len {
            (offset, chunk.min(len - offset))
        } else {
            (0, chunk.min(len))
        }
    }
}

/// Tiles in flight at once.
const SLOTS: usize = 2;
/// Output texels are `vec4<f32>`.
const TEXEL_BYTES: u64 = 16;
/// Binding indices (the shader's header lists them).
const B_FRAME: usize = 0;
const B_TILE: usize = 1;
const B_OUTPUT: usize = 8;
const B_STATE: usize = 10;
const B_STATUS: usize = 11;
const B_MATERIALS: usize = 12;
const B_SKIPS: usize = 13;
/// `Timings` count: tiles whose one-pass try left pixels unfinished and
/// that were redone with the resumable shader (`TileWork::resumable`).
pub const RESUMABLE_REDOS: &str = "resumable redos";

/// A cut tile is redone with its budget divided by this.
const BUDGET_BACKOFF: u32 = 8;

/// The default loop iterations per invocation per pass. llvmpipe ends every
/// loop of an invocation once it has run 65535 iterations of all its loops
/// together (counted per 8-lane vector, so divergent lanes can add up to 8
/// times one lane's count); 2048 per lane plus one traversal stays below that
/// in the worst case. Measured on lavapipe: SIGGRAPH needs one pass at
/// 640x480, and passes add under 3% where one would do.
pub const DEFAULT_PASS_BUDGET: u32 = 2048;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuRenderOptions {
    /// Tile edge in pixels; bounds the pixels in one submit.
    pub tile_size: u32,
    /// Loop iterations one shader invocation may run per pass; bounds the
    /// work per pixel in one submit.
    pub pass_budget: u32,
    /// Longest wait for one pass before giving up with an error.
    pub pass_timeout: Duration,
    /// Intersection and offset methods (robust unless measuring them).
    pub methods: Methods,
    /// Sample counts, reflection depth, shutter and seed.
    pub effects: Effects,
    /// What the shader is specialised for: `Features::of` the scene, or
    /// `Features::ALL` for the generic shader.
    pub features: Features,
    /// A cap on every storage binding below the device's own
    /// `maxStorageBufferRange` (tests use it to reach the limit cheaply).
    pub storage_limit: Option<u64>,
    /// Where the device is a CPU, read the hot lists through their device
    /// addresses (`Lists::Address`, where the driver gathers those loads)
    /// or, where they fit, from uniform copies (`Lists::Uniform`); false:
    /// always the storage lists, as on a GPU.
    pub uniform_lists: bool,
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
            pass_budget: DEFAULT_PASS_BUDGET,
            // A pass is bounded (pass_budget x tile pixels): on lavapipe,
            // 2 cores, a full-budget 512^2 pass takes about 10 s, so 120 s
            // leaves room for a machine that is busy with other work.
            pass_timeout: Duration::from_secs(120),
            methods: Methods::Robust,
            effects: Effects::default(),
            features: Features::ALL,
            storage_limit: None,
            uniform_lists: true,
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
    /// `Kernel::Render` over the rectangles `run` is given (none larger
    /// than a tile).
    Rects,
    /// The path record of one pixel.
    Pixel([u32; 2]),
}

/// A device with the trace pipeline built; renders any number of scenes.
pub struct GpuRenderer {
    ctx: Context,
    pipeline: TracePipeline,
    /// Reused by every render; `None` until the first.
    resources: Mutex<Option<Resources>>,
    /// Whether the last render had a tile that needed more than one pass:
    /// the next starts its tiles resumable (`TileWork::resumable`), so a
    /// run of renders of such work (progressive passes, animation frames)
    /// redoes tiles only in its first. A wrong guess costs time, never
    /// the image.
    needed_passes: AtomicBool,
}

#[derive(Clone, Copy, Debug)]
struct TileRect {
    origin: [u32; 2],
    size: [u32; 2],
}

/// A tile's progress through its passes.
#[derive(Clone, Copy, Debug)]
struct TileWork {
    rect: TileRect,
    /// Passes submitted so far (the one in flight included).
    pass: u32,
    budget: u32,
    /// Pixels whose work is not finished, as of the last pass read.
    left: u32,
    /// Closest-hit and shadow rays the tile's passes cast so far.
    rays: [u64; 2],
    /// Whether its passes keep the pixels' state. A render's tiles start
    /// without (`ONE_PASS`): most finish in one pass, and the state's
    /// loads and stores cost Mesa 22.3 up to an eighth of a render's
    /// instructions (test1) even where no pixel pauses. A tile that has pixels left after that
    /// pass is redone from its start with the resumable shader (same
    /// image: the passes are deterministic), and the render's later tiles
    /// start resumable, as do the next render's
    /// (`GpuRenderer::needed_passes`).
    resumable: bool,
}

/// The Vulkan objects of a renderer that are not buffers, destroyed on drop.
struct Pools {
    shared: Arc<Shared>,
    command_pool: vk::CommandPool,
    descriptor_pool: vk::DescriptorPool,
    fences: Vec<vk::Fence>,
    /// Two timestamps per slot, around its dispatch (null when the queue
    /// has none).
    queries: vk::QueryPool,
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
struct Reusable {
    name: String,
    usage: vk::BufferUsageFlags,
    location: MemoryLocation,
    buffer: Option<Buffer>,
}

impl Reusable {
    fn new(name: &str, usage: vk::BufferUsageFlags, location: MemoryLocation) -> Reusable {
        Reusable {
            name: name.to_string(),
            usage,
            location,
            buffer: None,
        }
    }

    /// The buffer, recreated first when it holds fewer than `size` bytes.
    fn at_least(&mut self, shared: &Arc<Shared>, size: u64) -> Result<&mut Buffer, GpuError> {
        let size = size.max(16);
        if self.buffer.as_ref().is_none_or(|b| b.size < size) {
            self.buffer = None; // free before allocating the larger one
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

    fn get(&self) -> &Buffer {
        self.buffer.as_ref().expect("allocated before use")
    }
}

struct Slot {
    tile: Buffer,
    status: Buffer,
    output: Reusable,
    readback: Reusable,
    state: Reusable,
    command: vk::CommandBuffer,
    fence: vk::Fence,
    /// A descriptor set of each layout, in `Lists::ALL` order.
    sets: [vk::DescriptorSet; 4],
    /// Its two timestamps in `Pools::queries` (null pool: none).
    queries: vk::QueryPool,
    first_query: u32,
}

/// Everything a render needs on the device, kept across renders.
struct Resources {
    // Buffers and sets before pools: drop order frees buffers first.
    slots: Vec<Slot>,
    /// Device-local scene buffers by binding (frame and scene lists).
    scene: Vec<(usize, Reusable)>,
    staging: Reusable,
    upload_command: vk::CommandBuffer,
    upload_fence: vk::Fence,
    /// Held for its drop: frees the command buffers, sets and fences.
    _pools: Pools,
}

/// One binding's contents for a render.
struct Upload<'a> {
    binding: usize,
    name: &'static str,
    bytes: std::borrow::Cow<'a, [u8]>,
}

impl GpuRenderer {
    pub fn new(ctx: &Context) -> Result<GpuRenderer, GpuError> {
        let pipeline = TracePipeline::new(ctx)?;
        Ok(GpuRenderer {
            ctx: ctx.clone(),
            pipeline,
            resources: Mutex::new(None),
            needed_passes: AtomicBool::new(false),
        })
    }

    /// The device's limits, storage bindings capped at `storage_limit`.
    fn limits(&self, storage_limit: Option<u64>) -> DeviceLimits {
        let mut limits = self.ctx.shared.limits;
        if let Some(cap) = storage_limit {
            limits.max_storage_range = limits.max_storage_range.min(cap);
        }
        limits
    }

    /// Time to build the pipeline `options` call for from scratch (no
    /// cache), with the plain lists.
    pub fn measure_build(
        &self,
        options: &GpuRenderOptions,
        kernel: Kernel,
    ) -> Result<Duration, GpuError> {
        self.pipeline.measure_build(key(
            options,
            kernel,
            Lists::Plain,
            &GpuScene::default(),
            &[],
            false,
        ))
    }

    /// Builds (or finds in the cache) the pipeline a render of `scene` with
    /// `options` starts with (resumable if the last render needed passes:
    /// `TileWork::resumable`); returns the build time, zero when it was
    /// cached.
    pub fn prepare(
        &self,
        scene: &GpuScene,
        options: &GpuRenderOptions,
        kernel: Kernel,
    ) -> Result<Duration, GpuError> {
        let limits = self.limits(options.storage_limit);
        // A plan that fails fails the render too, which then says why.
        let uploads = scene_uploads(scene);
        let lists = plan_lists(&uploads, &limits, options.uniform_lists)
            .map_or(Lists::Plain, |(_, lists)| lists);
        Ok(self
            .pipeline
            .get(key(
                options,
                kernel,
                lists,
                scene,
                &uploads,
                self.needed_passes.load(Ordering::Relaxed),
            ))?
            .1)
    }

    /// Renders `scene` as seen by `camera`. `progress(pixels_done,
    /// pixels_total)` is called after every pass: a pixel is done when its
    /// last pass has run.
    pub fn render(
        &self,
        scene: &GpuScene,
        camera: &Camera,
        background: [f32; 3],
        options: &GpuRenderOptions,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<(Framebuffer, Timings), GpuError> {
        let job = Job::Image(Kernel::Render);
        self.render_job(scene, camera, background, options, job, &[], progress)
    }

    /// Renders only the rectangles `rects` (x, y, width, height) of the
    /// image, each as its own tile (split where larger than one); the rest
    /// of the framebuffer is left 0. For progressive renders that spend
    /// passes where the noise is.
    pub fn render_rects(
        &self,
        scene: &GpuScene,
        camera: &Camera,
        background: [f32; 3],
        options: &GpuRenderOptions,
        rects: &[[u32; 4]],
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<(Framebuffer, Timings), GpuError> {
        let edge = tile_edge(options.tile_size);
        let mut parts = Vec::new();
        for &[x, y, w, h] in rects {
            let w = w.min(camera.width.saturating_sub(x));
            let h = h.min(camera.height.saturating_sub(y));
            for t in tiles(w, h, edge) {
                parts.push(TileRect {
                    origin: [x + t.origin[0], y + t.origin[1]],
                    size: t.size,
                });
            }
        }
        self.render_job(
            scene,
            camera,
            background,
            options,
            Job::Rects,
            &parts,
            progress,
        )
    }

    /// The colour image of a `Kernel::Render` job (`rects` for `Job::Rects`).
    #[allow(clippy::too_many_arguments)]
    fn render_job(
        &self,
        scene: &GpuScene,
        camera: &Camera,
        background: [f32; 3],
        options: &GpuRenderOptions,
        job: Job,
        rects: &[TileRect],
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<(Framebuffer, Timings), GpuError> {
        let width = camera.width as usize;
        let mut pixels = vec![[0.0f32; 3]; width * camera.height as usize];
        let timings = self.run(
            scene,
            camera,
            background,
            options,
            job,
            rects,
            progress,
            &mut |rect, texels| {
                place_tile(rect, texels, width, &mut pixels, |t| [t[0], t[1], t[2]])
            },
        )?;
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
        let width = camera.width as usize;
        let mut image = vec![[0.0f32; 4]; width * camera.height as usize];
        self.run(
            scene,
            camera,
            [0.0; 3],
            options,
            job,
            &[],
            &|_, _| {},
            &mut |rect, texels| place_tile(rect, texels, width, &mut image, |t| *t),
        )?;
        let mut probe = ProbeImage::from_texels(camera.width, camera.height, &image);
        for p in &mut probe.pixels {
            p.prim = scene.scene_prim(p.prim);
        }
        Ok(probe)
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
        let mut record = Vec::new();
        self.run(
            scene,
            camera,
            background,
            options,
            job,
            &[],
            &|_, _| {},
            &mut |_, texels| record = texels.to_vec(),
        )?;
        let mut path = PathRecord::from_texels(&record);
        path.prim = scene.scene_prim(path.prim);
        for light in &mut path.lights {
            light.blocker = scene.scene_prim(light.blocker);
        }
        Ok(path)
    }

    /// The bytes each binding of a render would hold, checked against the
    /// device's limits before anything is allocated; how the big lists are
    /// split over bindings to fit, and how the lists are bound.
    fn check_limits(
        &self,
        uploads: &[Upload],
        slot_bytes: &[(usize, u64)],
        storage_limit: Option<u64>,
        uniform_lists: bool,
    ) -> Result<(Split, Lists), GpuError> {
        let limits = self.limits(storage_limit);
        let (split, lists) = plan_lists(uploads, &limits, uniform_lists)?;
        let storage = lists
            .bindings()
            .filter(|&b| BINDINGS[b] == vk::DescriptorType::STORAGE_BUFFER)
            .count() as u32;
        if storage > limits.max_storage_buffers {
            return Err(GpuError::Limit {
                what: if split.split {
                    "storage buffers per shader stage (with the big lists split)".into()
                } else {
                    "storage buffers per shader stage".into()
                },
                needed: u64::from(storage),
                limit_name: "maxPerStageDescriptorStorageBuffers",
                limit: u64::from(limits.max_storage_buffers),
                unit: "",
                hint: "use another device or --backend cpu".into(),
            });
        }
        let sizes = uploads
            .iter()
            .map(|u| (u.binding, u.name, u.bytes.len() as u64))
            .chain(slot_bytes.iter().map(|&(b, n)| (b, binding_name(b), n)));
        for (binding, name, bytes) in sizes {
            let uniform = BINDINGS[binding] == vk::DescriptorType::UNIFORM_BUFFER;
            let (limit_name, limit) = if uniform {
                ("maxUniformBufferRange", limits.max_uniform_range)
            } else {
                ("maxStorageBufferRange", limits.max_storage_range)
            };
            let hint = match binding {
                B_OUTPUT | B_STATE => "use a smaller --tile".to_string(),
                _ => "render fewer primitives or lights on this device, or use --backend cpu"
                    .to_string(),
            };
            // A split list's chunks fit by construction (Split::plan).
            let bound = match Split::chunk_of(binding) {
                Some((j, _)) => split.chunk_bytes[j].min(bytes),
                None => bytes,
            };
            if bound > limit {
                return Err(GpuError::Limit {
                    what: format!("the {name} buffer (binding {binding})"),
                    needed: bytes,
                    limit_name,
                    limit,
                    unit: " bytes",
                    hint,
                });
            }
            if bytes > limits.max_allocation {
                return Err(GpuError::Limit {
                    what: format!("the {name} buffer (binding {binding})"),
                    needed: bytes,
                    limit_name: "maxMemoryAllocationSize",
                    limit: limits.max_allocation,
                    unit: " bytes",
                    hint,
                });
            }
        }
        Ok((split, lists))
    }

    #[allow(clippy::too_many_arguments)]
    fn run(
        &self,
        scene: &GpuScene,
        camera: &Camera,
        background: [f32; 3],
        options: &GpuRenderOptions,
        job: Job,
        rects: &[TileRect],
        progress: &(dyn Fn(u64, u64) + Sync),
        sink: &mut dyn FnMut(TileRect, &[[f32; 4]]),
    ) -> Result<Timings, GpuError> {
        let mut timings = Timings::default();
        let tile_edge = tile_edge(options.tile_size);
        let (kernel, tiles, out_texels) = match job {
            Job::Image(kernel) => (
                kernel,
                tiles(camera.width, camera.height, tile_edge),
                tile_texels(options.tile_size, camera.width, camera.height),
            ),
            Job::Rects => (
                Kernel::Render,
                rects.to_vec(),
                tile_texels(options.tile_size, camera.width, camera.height),
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
        let state_bytes = match kernel {
            Kernel::Render => out_texels * std::mem::size_of::<GpuPixelState>() as u64,
            _ => std::mem::size_of::<GpuPixelState>() as u64,
        };
        let out_bytes = out_texels * TEXEL_BYTES;
        let mut frame = scene.frame(camera, background, &options.effects, &options.features);
        let mut uploads = vec![upload(
            B_FRAME,
            "frame",
            bytemuck::bytes_of(&frame).to_vec().into(),
        )];
        uploads.extend(scene_uploads(scene));
        let (split, lists) = self.check_limits(
            &uploads,
            &[(B_OUTPUT, out_bytes), (B_STATE, state_bytes)],
            options.storage_limit,
            options.uniform_lists,
        )?;
        frame.chunk_shift = split.shifts;
        uploads[0].bytes = bytemuck::bytes_of(&frame).to_vec().into();
        if lists == Lists::Uniform {
            for (j, (binding, name)) in UNIFORM_LISTS.into_iter().enumerate() {
                let list = &uploads
                    .iter()
                    .find(|u| u.binding == binding)
                    .expect("uploaded")
                    .bytes;
                let copy = uniform_copy(j, list).expect("choose_lists checked that it fits");
                uploads.push(upload(UNIFORM_FIRST + j, name, copy.into()));
            }
        }
        let key = key(options, kernel, lists, scene, &uploads, false);
        // Each pipeline is built when a tile first needs it: the one-pass
        // shader for a tile's first try, the resumable one after it
        // (`TileWork::resumable`); a probe's is `key`'s.
        let mut built: [Option<vk::Pipeline>; 2] = [None; 2];
        let mut pipeline_for = |work: &TileWork, timings: &mut Timings| {
            let slot = &mut built[usize::from(work.resumable)];
            if let Some(p) = *slot {
                return Ok(p);
            }
            let (p, build_time) = self.pipeline.get(PipelineKey {
                one_pass: key.one_pass && !work.resumable,
                ..key
            })?;
            if !build_time.is_zero() {
                timings.add("pipeline", build_time);
            }
            *slot = Some(p);
            Ok::<_, GpuError>(p)
        };

        let mut guard = self.resources.lock().unwrap_or_else(|e| e.into_inner());
        if guard.is_none() {
            *guard = Some(self.create_resources()?);
        }
        let res = guard.as_mut().expect("just created");
        let upload_start = Instant::now();
        if lists == Lists::Address {
            // The frame carries the lists' addresses: size their buffers
            // first (the upload then reuses them).
            for (j, (binding, _)) in ADDRESS_LISTS.into_iter().enumerate() {
                let size = uploads
                    .iter()
                    .find(|u| u.binding == binding)
                    .map_or(0, |u| u.bytes.len() as u64);
                let address = scene_buffer(&mut res.scene, &self.ctx.shared, binding, size)?
                    .address()
                    .expect("address lists need the lists' device addresses");
                frame.set_address(j, address);
            }
            uploads[0].bytes = bytemuck::bytes_of(&frame).to_vec().into();
        }
        self.upload(res, &uploads)?;
        for slot in &mut res.slots {
            self.bind_slot(
                slot,
                &res.scene,
                &uploads,
                &split,
                lists,
                out_bytes,
                state_bytes,
            )?;
        }
        timings.add("upload", upload_start.elapsed());

        let mut in_flight: VecDeque<(usize, TileWork)> = VecDeque::new();
        let total_pixels: u64 = tiles.iter().map(|t| u64::from(t.size[0] * t.size[1])).sum();
        let mut done_pixels = 0u64;
        let mut rays = [0u64; 2];
        let mut device_time = Duration::ZERO;
        let mut timed_by_device = true;
        let mut readback = Duration::ZERO;
        let mut passes = 0u64;
        let mut retries = 0u64;
        let mut redone = 0u64;
        // Probes keep no state and run once: they never start resumable.
        let start_resumable =
            kernel == Kernel::Render && self.needed_passes.load(Ordering::Relaxed);
        let mut needed_passes = false;
        let dispatch_start = Instant::now();
        let mut next_tile = tiles.iter();
        let mut free: Vec<usize> = (0..SLOTS).rev().collect();
        loop {
            // Fill every free slot with a new tile.
            while let Some(&s) = free.last() {
                let Some(&rect) = next_tile.next() else {
                    break;
                };
                free.pop();
                let work = TileWork {
                    rect,
                    pass: 1,
                    budget: options.pass_budget.max(1),
                    left: rect.size[0] * rect.size[1],
                    rays: [0; 2],
                    // A tile of this render needed passes: so will this.
                    resumable: start_resumable || needed_passes,
                };
                let p = pipeline_for(&work, &mut timings)?;
                self.submit_pass(&mut res.slots[s], p, lists, job, work, out_texels)?;
                passes += 1;
                in_flight.push_back((s, work));
            }
            let Some((s, mut work)) = in_flight.pop_front() else {
                break;
            };
            let slot = &res.slots[s];
            self.wait(slot, work, options)?;
            match self.dispatch_time(slot) {
                Some(t) => device_time += t,
                None => timed_by_device = false,
            }
            let status: GpuStatus =
                *bytemuck::from_bytes(&slot.status.mapped()[..std::mem::size_of::<GpuStatus>()]);
            if status.cut > 0 {
                let width = camera.width.max(1);
                let [x, y] = [status.first_cut % width, status.first_cut / width];
                if kernel != Kernel::Render || work.budget == 1 {
                    return Err(GpuError::Incomplete {
                        x,
                        y,
                        cut: status.cut,
                        probe: kernel != Kernel::Render,
                    });
                }
                // Redo the tile from its start with less work per pass: the
                // passes are deterministic, so the image is the same.
                work.budget = (work.budget / BUDGET_BACKOFF).max(1);
                work.pass = 1;
                let size = work.rect.size[0] * work.rect.size[1];
                done_pixels -= u64::from(size - work.left);
                work.left = size;
                work.rays = [0; 2];
                retries += 1;
            } else if status.remaining > 0 && kernel == Kernel::Render && !work.resumable {
                // The pass kept no state to resume from: redo the tile.
                work.resumable = true;
                needed_passes = true;
                work.pass = 1;
                work.left = work.rect.size[0] * work.rect.size[1];
                work.rays = [0; 2];
                redone += 1;
                // Every pass reports, this one with no pixel finished.
                progress(done_pixels, total_pixels);
            } else if status.remaining > 0 && kernel == Kernel::Render {
                needed_passes = true;
                work.rays[0] += u64::from(status.closest_rays);
                work.rays[1] += u64::from(status.shadow_rays);
                work.pass += 1;
                done_pixels += u64::from(work.left.saturating_sub(status.remaining));
                work.left = status.remaining.min(work.left);
                progress(done_pixels, total_pixels);
            } else {
                let start = Instant::now();
                let texels: &[[f32; 4]] = bytemuck::cast_slice(slot.readback.get().mapped());
                let n = match job {
                    Job::Image(_) | Job::Rects => (work.rect.size[0] * work.rect.size[1]) as usize,
                    Job::Pixel(_) => out_texels as usize,
                };
                sink(work.rect, &texels[..n]);
                readback += start.elapsed();
                rays[0] += work.rays[0] + u64::from(status.closest_rays);
                rays[1] += work.rays[1] + u64::from(status.shadow_rays);
                done_pixels += u64::from(work.left);
                progress(done_pixels, total_pixels);
                free.push(s);
                continue;
            }
            let p = pipeline_for(&work, &mut timings)?;
            self.submit_pass(&mut res.slots[s], p, lists, job, work, out_texels)?;
            passes += 1;
            in_flight.push_back((s, work));
        }
        if kernel == Kernel::Render {
            self.needed_passes.store(needed_passes, Ordering::Relaxed);
        }
        timings.add(
            "dispatch",
            dispatch_start.elapsed().saturating_sub(readback),
        );
        timings.add("readback", readback);
        timings.count("passes", passes);
        if timed_by_device {
            timings.count(GPU_TIME_NS, device_time.as_nanos() as u64);
        }
        // A pass's counters are 32-bit: counts that may have wrapped are
        // left out rather than shown wrong.
        let most_per_pass =
            u64::from(tile_edge) * u64::from(tile_edge) * u64::from(options.pass_budget);
        if kernel == Kernel::Render && most_per_pass <= u64::from(u32::MAX) {
            timings.count(CLOSEST_RAYS, rays[0]);
            timings.count(SHADOW_RAYS, rays[1]);
        }
        match lists {
            Lists::Split => timings.count("split lists", 1),
            Lists::Uniform => timings.count("uniform lists", 1),
            Lists::Address => timings.count("address lists", 1),
            Lists::Plain => {}
        }
        if key.corners {
            timings.count("uniform corners", 1);
        }
        if retries > 0 {
            // Tiles redone with a smaller budget after a pass was cut short.
            timings.count("retries", retries);
        }
        if redone > 0 {
            // Tiles redone with the resumable shader after a one-pass try.
            timings.count(RESUMABLE_REDOS, redone);
        }
        Ok(timings)
    }

    fn create_resources(&self) -> Result<Resources, GpuError> {
        let shared = self.ctx.shared.clone();
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
                            .query_count(2 * SLOTS as u32),
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
            if self.ctx.limits().device_addresses && ADDRESS_LISTS.iter().any(|l| l.0 == binding) {
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
            upload_command,
            upload_fence,
            _pools: pools,
        })
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

    /// Copies each list into its device-local buffer through the staging
    /// buffer, one list per submit so staging never exceeds the largest list.
    fn upload(&self, res: &mut Resources, uploads: &[Upload]) -> Result<(), GpuError> {
        let shared = &self.ctx.shared;
        let device = &shared.device;
        for u in uploads {
            let size = u.bytes.len() as u64;
            let dst = scene_buffer(&mut res.scene, shared, u.binding, size)?.raw;
            let staging = res.staging.at_least(shared, size)?;
            staging.write(&u.bytes);
            let cmd = res.upload_command;
            // SAFETY: the previous upload was waited for, so the command
            // buffer, staging buffer and fence are free; every buffer lives
            // until the wait below returns.
            unsafe {
                device
                    .reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())
                    .call("vkResetCommandBuffer")?;
                device
                    .begin_command_buffer(
                        cmd,
                        &vk::CommandBufferBeginInfo::default()
                            .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                    )
                    .call("vkBeginCommandBuffer")?;
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
                    .reset_fences(&[res.upload_fence])
                    .call("vkResetFences")?;
                device
                    .queue_submit(shared.queue, &[submit], res.upload_fence)
                    .call("vkQueueSubmit")?;
                device
                    .wait_for_fences(&[res.upload_fence], true, u64::MAX)
                    .call("vkWaitForFences")?;
            }
        }
        Ok(())
    }

    fn create_slot(&self, pools: &mut Pools, index: usize) -> Result<Slot, GpuError> {
        let shared = &self.ctx.shared;
        let tile = Buffer::new(
            shared,
            &format!("tile {index}"),
            std::mem::size_of::<GpuTile>() as u64,
            vk::BufferUsageFlags::UNIFORM_BUFFER,
            MemoryLocation::CpuToGpu,
        )?;
        // Read by the host after every pass; reset by the pass itself.
        let status = Buffer::new(
            shared,
            &format!("status {index}"),
            std::mem::size_of::<GpuStatus>() as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST,
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
        let command = self.command_buffer(pools)?;
        let fence = self.fence(pools)?;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        Ok(Slot {
            tile,
            status,
            output: Reusable::new(
                &format!("tile output {index}"),
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
            command,
            fence,
            sets,
            queries: pools.queries,
            first_query: 2 * index as u32,
        })
    }

    /// The device time of the slot's last dispatch, from its timestamps.
    fn dispatch_time(&self, slot: &Slot) -> Option<Duration> {
        if slot.queries == vk::QueryPool::null() {
            return None;
        }
        let mut ticks = [0u64; 2];
        // SAFETY: both queries were written by the pass just waited for.
        unsafe {
            self.ctx.shared.device.get_query_pool_results(
                slot.queries,
                slot.first_query,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64,
            )
        }
        .ok()?;
        let limits = &self.ctx.shared.limits;
        let mask = if limits.timestamp_bits >= 64 {
            u64::MAX
        } else {
            (1u64 << limits.timestamp_bits) - 1
        };
        let elapsed = ticks[1].wrapping_sub(ticks[0]) & mask;
        Some(Duration::from_secs_f64(
            elapsed as f64 * f64::from(limits.timestamp_period) * 1e-9,
        ))
    }

    /// Points the slot's descriptor set of the render's layout (`lists`) at
    /// its buffers, each bound with exactly its contents' size (the shader's
    /// `arrayLength` sees it), a split list chunk by chunk.
    #[allow(clippy::too_many_arguments)]
    fn bind_slot(
        &self,
        slot: &mut Slot,
        scene: &[(usize, Reusable)],
        uploads: &[Upload],
        split: &Split,
        lists: Lists,
        out_bytes: u64,
        state_bytes: u64,
    ) -> Result<(), GpuError> {
        let shared = &self.ctx.shared;
        slot.output.at_least(shared, out_bytes)?;
        slot.readback.at_least(shared, out_bytes)?;
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

    #[allow(clippy::too_many_arguments)]
    fn submit_pass(
        &self,
        slot: &mut Slot,
        pipeline: vk::Pipeline,
        lists: Lists,
        job: Job,
        work: TileWork,
        out_texels: u64,
    ) -> Result<(), GpuError> {
        let shared = &self.ctx.shared;
        let device = &shared.device;
        let rect = work.rect;
        let tile = GpuTile {
            origin: rect.origin,
            size: rect.size,
            budget: work.budget,
            first: u32::from(work.pass == 1),
            _pad: [0; 2],
        };
        slot.tile.write(bytemuck::bytes_of(&tile));
        let (groups, texels) = match job {
            Job::Image(_) | Job::Rects => (
                [
                    rect.size[0].div_ceil(WORKGROUP_SIZE),
                    rect.size[1].div_ceil(WORKGROUP_SIZE),
                ],
                u64::from(rect.size[0]) * u64::from(rect.size[1]),
            ),
            Job::Pixel(_) => ([1, 1], out_texels),
        };
        let max = shared.limits.max_group_count;
        if groups[0] > max[0] || groups[1] > max[1] {
            return Err(GpuError::Limit {
                what: "workgroups per dispatch".into(),
                needed: u64::from(groups[0].max(groups[1])),
                limit_name: "maxComputeWorkGroupCount",
                limit: u64::from(max[0].min(max[1])),
                unit: "",
                hint: "use a smaller --tile".into(),
            });
        }
        let reset = GpuStatus::RESET;
        let words: [u32; std::mem::size_of::<GpuStatus>() / 4] = bytemuck::cast(reset);
        let bytes = texels * TEXEL_BYTES;
        // SAFETY: the slot's previous submission was waited for before this
        // reuse; all handles are live.
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
            // The status starts each pass at RESET: the counters at 0 and
            // first_cut at u32::MAX (a fill per word).
            for (i, &w) in words.iter().enumerate() {
                device.cmd_fill_buffer(slot.command, slot.status.raw, 4 * i as u64, 4, w);
            }
            let to_shader = vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
                .dst_access_mask(vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE);
            device.cmd_pipeline_barrier(
                slot.command,
                vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::DependencyFlags::empty(),
                &[to_shader],
                &[],
                &[],
            );
            device.cmd_bind_pipeline(slot.command, vk::PipelineBindPoint::COMPUTE, pipeline);
            device.cmd_bind_descriptor_sets(
                slot.command,
                vk::PipelineBindPoint::COMPUTE,
                self.pipeline.layout(lists).pipeline,
                0,
                &[slot.sets[lists.index()]],
                &[],
            );
            if slot.queries != vk::QueryPool::null() {
                device.cmd_reset_query_pool(slot.command, slot.queries, slot.first_query, 2);
                device.cmd_write_timestamp(
                    slot.command,
                    vk::PipelineStageFlags::TOP_OF_PIPE,
                    slot.queries,
                    slot.first_query,
                );
            }
            device.cmd_dispatch(slot.command, groups[0], groups[1], 1);
            if slot.queries != vk::QueryPool::null() {
                device.cmd_write_timestamp(
                    slot.command,
                    vk::PipelineStageFlags::COMPUTE_SHADER,
                    slot.queries,
                    slot.first_query + 1,
                );
            }
            let to_copy = vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::SHADER_WRITE)
                .dst_access_mask(vk::AccessFlags::TRANSFER_READ | vk::AccessFlags::HOST_READ);
            device.cmd_pipeline_barrier(
                slot.command,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::HOST,
                vk::DependencyFlags::empty(),
                &[to_copy],
                &[],
                &[],
            );
            device.cmd_copy_buffer(
                slot.command,
                slot.output.get().raw,
                slot.readback.get().raw,
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
                .map_err(|r| self.fail(r, work, "vkQueueSubmit", 0))?;
        }
        Ok(())
    }

    /// Waits for the slot's pass.
    fn wait(
        &self,
        slot: &Slot,
        work: TileWork,
        options: &GpuRenderOptions,
    ) -> Result<(), GpuError> {
        let timeout = options.pass_timeout.as_nanos().min(u128::from(u64::MAX)) as u64;
        // SAFETY: the fence belongs to this device and was submitted.
        unsafe {
            self.ctx
                .shared
                .device
                .wait_for_fences(&[slot.fence], true, timeout)
        }
        .map_err(|r| self.fail(r, work, "vkWaitForFences", options.pass_timeout.as_secs()))
    }

    fn fail(
        &self,
        result: vk::Result,
        work: TileWork,
        call: &'static str,
        seconds: u64,
    ) -> GpuError {
        let [x, y] = work.rect.origin;
        match result {
            vk::Result::TIMEOUT => {
                self.ctx.shared.poison();
                GpuError::Timeout {
                    x,
                    y,
                    pass: work.pass,
                    budget: work.budget,
                    seconds,
                }
            }
            vk::Result::ERROR_DEVICE_LOST => {
                self.ctx.shared.poison();
                GpuError::DeviceLost { x, y }
            }
            result => GpuError::Vk { call, result },
        }
    }
}

/// Copies a tile's texels (row-major, `rect.size[0]` wide) into their place
/// in an image `width` pixels wide, converting each with `f`.
fn place_tile<T>(
    rect: TileRect,
    texels: &[[f32; 4]],
    width: usize,
    image: &mut [T],
    f: impl Fn(&[f32; 4]) -> T,
) {
    let [x0, y0] = rect.origin.map(|v| v as usize);
    let w = rect.size[0] as usize;
    for (row, src) in texels.chunks_exact(w).enumerate() {
        let start = (y0 + row) * width + x0;
        for (dst, t) in image[start..start + w].iter_mut().zip(src) {
            *dst = f(t);
        }
    }
}

fn upload<'a>(binding: usize, name: &'static str, bytes: std::borrow::Cow<'a, [u8]>) -> Upload<'a> {
    Upload {
        binding,
        name,
        bytes,
    }
}

/// The scene's lists as uploaded, one per binding (the frame and the
/// uniform copies are added by the render).
fn scene_uploads(scene: &GpuScene) -> Vec<Upload<'_>> {
    vec![
        upload(2, "spheres", padded(&scene.spheres)),
        upload(3, "triangles", padded(&scene.triangles)),
        upload(4, "normals", padded(&scene.normals)),
        upload(5, "lights", padded(&scene.lights)),
        upload(6, "bvh nodes", padded(&scene.nodes)),
        upload(7, "primitive refs", padded(&scene.prim_refs)),
        upload(9, "velocities", padded(&scene.velocities)),
        upload(B_MATERIALS, "materials", padded(&scene.materials)),
        upload(B_SKIPS, "light skips", padded(&scene.skips)),
    ]
}

/// How a render with `uploads` binds its lists: split over bindings where
/// one cannot hold them, else as `choose_lists` says.
fn plan_lists(
    uploads: &[Upload],
    limits: &DeviceLimits,
    uniform_lists: bool,
) -> Result<(Split, Lists), GpuError> {
    let len_of = |binding: usize| {
        uploads
            .iter()
            .find(|u| u.binding == binding)
            .map_or(0, |u| u.bytes.len() as u64)
    };
    let split = Split::plan(SPLIT_LISTS.map(|(b, _)| len_of(b)), limits)?;
    let lists = choose_lists(
        split.split,
        UNIFORM_LISTS.map(|(b, _)| len_of(b)),
        ADDRESS_LISTS.map(|(b, _)| len_of(b)),
        limits,
        uniform_lists,
    );
    Ok((split, lists))
}

/// The largest list the shader reads through its device address: it
/// indexes a list by 4-byte words with a 32-bit index, which SPIR-V's
/// access chains take as signed.
const ADDRESS_LIST_MAX_BYTES: u64 = 1 << 33;

/// Address lists (see "Address lists" in shaders/trace.wgsl) where they are
/// `allowed`, no list is split, the device is a CPU with device addresses
/// (enabled where they pay: `context::address_loads_pay`) and each of
/// `layout::ADDRESS_LISTS` (`address_lens` bytes) is at most
/// `ADDRESS_LIST_MAX_BYTES`.
/// Otherwise uniform lists (see "Uniform lists" in shaders/trace.wgsl) where they are
/// `allowed`, the device is a CPU, no list is split, each of
/// `layout::UNIFORM_LISTS` (`lens` bytes) fits its copy, and the device
/// binds copies that large and that many uniform buffers; else the plain or
/// split layout.
fn choose_lists(
    split: bool,
    lens: [u64; 4],
    address_lens: [u64; 6],
    limits: &DeviceLimits,
    allowed: bool,
) -> Lists {
    if split {
        return Lists::Split;
    }
    if allowed
        && limits.cpu
        && limits.device_addresses
        && address_lens.iter().all(|&n| n <= ADDRESS_LIST_MAX_BYTES)
    {
        return Lists::Address;
    }
    // frame, tile and the copies.
    let uniform_buffers = 2 + UNIFORM_LISTS.len() as u32;
    let fits = (0..lens.len()).all(|j| uniform_copy_bytes(j, lens[j]) <= UNIFORM_LIST_BYTES);
    if allowed
        && limits.cpu
        && fits
        && limits.max_uniform_range >= UNIFORM_LIST_BYTES
        && limits.max_uniform_buffers >= uniform_buffers
    {
        Lists::Uniform
    } else {
        Lists::Plain
    }
}

/// The scene buffer of `binding`, holding at least `size` bytes.
fn scene_buffer<'a>(
    scene: &'a mut [(usize, Reusable)],
    shared: &Arc<Shared>,
    binding: usize,
    size: u64,
) -> Result<&'a mut Buffer, GpuError> {
    scene
        .iter_mut()
        .find(|(b, _)| *b == binding)
        .map(|(_, r)| r)
        .expect("every upload has a scene buffer")
        .at_least(shared, size)
}

fn binding_name(binding: usize) -> &'static str {
    match binding {
        B_OUTPUT => "tile output",
        B_STATE => "pixel state",
        _ => "buffer",
    }
}

fn usage_for(ty: vk::DescriptorType) -> vk::BufferUsageFlags {
    if ty == vk::DescriptorType::UNIFORM_BUFFER {
        vk::BufferUsageFlags::UNIFORM_BUFFER
    } else {
        vk::BufferUsageFlags::STORAGE_BUFFER
    }
}

/// Texels of the largest tile of a `width` x `height` image rendered with
/// `--tile tile_size`: what each slot's tile buffers hold.
pub fn tile_texels(tile_size: u32, width: u32, height: u32) -> u64 {
    let edge = tile_edge(tile_size);
    u64::from(edge.min(width)) * u64::from(edge.min(height))
}

/// The tile edge a `tile_size` gives: at least one workgroup.
fn tile_edge(tile_size: u32) -> u32 {
    tile_size.max(WORKGROUP_SIZE)
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

#[cfg(test)]
mod tests {
    use super::*;

    fn lavapipe() -> DeviceLimits {
        DeviceLimits {
            max_storage_range: 1 << 27,
            max_uniform_range: 65536,
            max_allocation: 1 << 30,
            max_group_count: [65535; 3],
            max_storage_buffers: 1_000_000,
            max_uniform_buffers: 15,
            cpu: true,
            storage_offset_alignment: 16,
            timestamp_period: 1.0,
            timestamp_bits: 64,
            device_addresses: false,
        }
    }

    const SMALL: [u64; 6] = [48, 48, 64, 16, 36, 32];

    #[test]
    fn uniform_lists_only_on_a_cpu_device_where_every_copy_fits() {
        let fits = [48, UNIFORM_LIST_BYTES, 64, 16];
        let cpu = lavapipe();
        assert_eq!(choose_lists(false, fits, SMALL, &cpu, true), Lists::Uniform);
        assert_eq!(choose_lists(false, fits, SMALL, &cpu, false), Lists::Plain);
        assert_eq!(choose_lists(true, fits, SMALL, &cpu, true), Lists::Split);
        for j in 0..fits.len() {
            let mut lens = fits;
            // Too big in any form (triangles fit past 64 KiB as corners).
            lens[j] = 2 * UNIFORM_LIST_BYTES;
            assert_eq!(
                choose_lists(false, lens, SMALL, &cpu, true),
                Lists::Plain,
                "list {j}"
            );
        }
        let gpu = DeviceLimits { cpu: false, ..cpu };
        assert_eq!(choose_lists(false, fits, SMALL, &gpu, true), Lists::Plain);
        let small = DeviceLimits {
            max_uniform_range: 16384,
            ..cpu
        };
        assert_eq!(choose_lists(false, fits, SMALL, &small, true), Lists::Plain);
        let few = DeviceLimits {
            // frame, tile and four copies: one short.
            max_uniform_buffers: 5,
            ..cpu
        };
        assert_eq!(choose_lists(false, fits, SMALL, &few, true), Lists::Plain);
    }

    #[test]
    fn address_lists_only_where_a_cpu_device_gathers_them_and_indices_reach() {
        let fits = [48, UNIFORM_LIST_BYTES, 64, 16];
        let mesa25 = DeviceLimits {
            device_addresses: true,
            ..lavapipe()
        };
        assert_eq!(
            choose_lists(false, fits, SMALL, &mesa25, true),
            Lists::Address
        );
        // Even where the uniform copies would not fit.
        let big = [1 << 30; 4];
        assert_eq!(
            choose_lists(false, big, SMALL, &mesa25, true),
            Lists::Address
        );
        assert_eq!(
            choose_lists(false, fits, SMALL, &mesa25, false),
            Lists::Plain
        );
        assert_eq!(choose_lists(true, fits, SMALL, &mesa25, true), Lists::Split);
        for j in 0..SMALL.len() {
            let mut lens = SMALL;
            lens[j] = ADDRESS_LIST_MAX_BYTES + 4;
            assert_eq!(
                choose_lists(false, fits, lens, &mesa25, true),
                Lists::Uniform,
                "list {j}"
            );
        }
        let disabled = DeviceLimits {
            device_addresses: false,
            ..mesa25
        };
        assert_eq!(
            choose_lists(false, fits, SMALL, &disabled, true),
            Lists::Uniform
        );
        let gpu = DeviceLimits {
            cpu: false,
            ..mesa25
        };
        assert_eq!(choose_lists(false, fits, SMALL, &gpu, true), Lists::Plain);
    }

    #[test]
    fn a_uniform_copy_is_its_list_zero_padded_to_the_fixed_length() {
        let copy = uniform_copy(0, &[1, 2, 3]).expect("fits");
        assert_eq!(copy.len() as u64, UNIFORM_LIST_BYTES);
        assert_eq!(&copy[..3], &[1, 2, 3]);
        assert!(copy[3..].iter().all(|&b| b == 0));
    }

    /// Triangles past 1,365 go as their corners' nine words back to back,
    /// up to 1,820; more have no copy.
    #[test]
    fn triangles_past_a_whole_copy_go_as_corners() {
        let triangles = |n: usize| -> Vec<GpuTriangle> {
            (0..n)
                .map(|i| GpuTriangle {
                    v: [0, 1, 2].map(|c| [0, 1, 2, 3].map(|k| (100 * i + 10 * c + k) as f32)),
                })
                .collect()
        };
        let whole = triangles(1365);
        let bytes: &[u8] = bytemuck::cast_slice(&whole);
        assert_eq!(uniform_copy_form(1, bytes.len() as u64), CopyForm::Whole);
        assert_eq!(&uniform_copy(1, bytes).expect("fits")[..bytes.len()], bytes);
        let many = triangles(1820);
        let bytes: &[u8] = bytemuck::cast_slice(&many);
        assert_eq!(uniform_copy_form(1, bytes.len() as u64), CopyForm::Corners);
        let copy = uniform_copy(1, bytes).expect("fits as corners");
        let words: &[f32] = bytemuck::cast_slice(&copy);
        for (i, t) in many.iter().enumerate() {
            for c in 0..3 {
                assert_eq!(&words[9 * i + 3 * c..9 * i + 3 * c + 3], &t.v[c][..3]);
            }
        }
        let lens = |triangles: usize| [0, 48 * triangles as u64, 64, 16];
        let cpu = lavapipe();
        assert_eq!(
            choose_lists(false, lens(1820), SMALL, &cpu, true),
            Lists::Uniform
        );
        assert_eq!(
            choose_lists(false, lens(1821), SMALL, &cpu, true),
            Lists::Plain
        );
        let too_many = triangles(1821);
        assert!(uniform_copy(1, bytemuck::cast_slice(&too_many)).is_none());
    }
}
