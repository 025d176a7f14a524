//! The `Renderer`: a backend chosen and set up once (device, pipelines),
//! then any number of scenes made ready and rendered on it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::bvh::Bvh;
use crate::camera::Camera;
use crate::cpu::{self, CpuOptions, Precision};
use crate::features::Features;
use crate::gpu::{Context, ContextOptions, GpuRenderOptions, GpuRenderer};
use crate::layout::GpuScene;
use crate::memory::{self, MemoryNeed};
use crate::parts::cut::{Costs, Span};
use crate::scene::{Effects, Scene};
use crate::timing::Timings;
use crate::Error;

use super::options::{Backend, PixelFormat, RenderOptions};
use super::output::RenderOutput;
use super::region::Region;

// A part's ends fall between the CPU's packet bands and the GPU's
// workgroups (`parts::cut::GRAIN_ROWS`).
const _: () = assert!(crate::parts::cut::GRAIN_ROWS.is_multiple_of(cpu::packet::TILE[1]));
const _: () = assert!(crate::parts::cut::GRAIN_ROWS.is_multiple_of(crate::layout::WORKGROUP_SIZE));

/// Where the work runs, chosen once from `RenderOptions`.
pub(super) enum Engine {
    Gpu {
        ctx: Context,
        renderer: Box<GpuRenderer>,
    },
    Cpu(Precision),
}

/// A backend set up once (device, pipeline cache) that renders any number of
/// scenes: the frames of an animation reuse its pipelines.
pub struct Renderer {
    pub(super) options: RenderOptions,
    pub(super) engine: Engine,
    /// Device creation, reported with the first render.
    setup_timings: std::sync::Mutex<Option<Timings>>,
    note: Option<String>,
    /// Set: the render in flight ends with `Error::Cancelled`.
    cancel: Option<Arc<AtomicBool>>,
}

/// A scene made ready for rendering on one `Renderer` (`prepare_scene`).
pub struct PreparedScene {
    prepared: Prepared,
    packed: Packed,
    /// The scene in view space, when its camera moved it.
    view: Option<Scene>,
    /// What preparing took (BVH build, packing).
    pub timings: Timings,
}

/// The scene as the backend reads it, built once per prepared scene: the
/// GPU's buffers or the CPU reference's geometry.
pub(super) enum Packed {
    Gpu(GpuScene),
    Cpu(cpu::Geometry),
}

/// Per scene: the camera and the BVH (over the shutter interval when the
/// scene has motion blur).
pub(super) struct Prepared {
    pub(super) camera: Camera,
    pub(super) bvh: Bvh,
    pub(super) effects: Effects,
    pub(super) features: Features,
}

impl Renderer {
    /// Sets up the backend `options` chooses: the Vulkan device and its
    /// pipeline cache, or the CPU reference; an error where `options` cannot
    /// be met (no device for `Backend::Gpu`, f64 on a GPU, no pixels).
    pub fn new(options: &RenderOptions) -> Result<Renderer, Error> {
        Self::made(options, None)
    }

    /// A renderer whose GPU work runs on `ctx` (`glint view`'s renderers
    /// share the one device that presents to the window); the CPU
    /// reference ignores it.
    pub fn on(options: &RenderOptions, ctx: Context) -> Result<Renderer, Error> {
        Self::made(options, Some(ctx))
    }

    fn made(options: &RenderOptions, context: Option<Context>) -> Result<Renderer, Error> {
        if options.width == 0 || options.height == 0 {
            return Err(Error::InvalidOption(format!(
                "image size {}x{} has no pixels",
                options.width, options.height
            )));
        }
        if options.backend == Backend::Cpu && options.device.is_some() {
            return Err(Error::InvalidOption(
                "--device chooses a Vulkan device; it has no effect with --backend cpu".into(),
            ));
        }
        if options.backend == Backend::Gpu && options.precision == Precision::F64 {
            return Err(Error::InvalidOption(
                "--precision f64 exists on the CPU reference only; use --backend cpu".into(),
            ));
        }
        let mut timings = Timings::default();
        let want_gpu = match (options.backend, options.precision) {
            (Backend::Cpu, _) | (Backend::Auto, Precision::F64) => false,
            (Backend::Gpu, _) | (Backend::Auto, Precision::F32) => true,
        };
        let mut note = None;
        if options.backend == Backend::Auto && !want_gpu {
            note = Some("--precision f64 exists on the CPU reference only; rendered there".into());
        }
        let mut engine = Engine::Cpu(options.precision);
        let mut options = options.clone();
        if want_gpu {
            let context_options = ContextOptions {
                device: options.device.clone(),
                validation: options.validation,
                pipeline_cache: options.pipeline_cache.clone(),
                window: None,
            };
            let start = Instant::now();
            let made = match context {
                Some(ctx) => Ok(ctx),
                None => Context::new(&context_options),
            };
            match made {
                // Lavapipe renders the same image as the CPU reference, only
                // slower on the same cores (docs/cli.md, "Choosing a device").
                Ok(ctx)
                    if options.backend == Backend::Auto
                        && options.device.is_none()
                        && ctx.info().profile.prefer_cpu_reference =>
                {
                    note = Some(format!(
                        "the only Vulkan device is a software one ({}), slower than the CPU \
                         reference on the same cores; rendered on the CPU reference \
                         (`--backend gpu` uses the device)",
                        ctx.info().name
                    ));
                }
                Ok(ctx) => {
                    timings.add("device", start.elapsed());
                    let profile = &ctx.info().profile;
                    options.gpu.tile_size = options.tile.unwrap_or(profile.tile_size);
                    options.gpu.pass_budget = options.pass_budget.unwrap_or(profile.pass_budget);
                    options.gpu.one_pass_first = profile.one_pass_first;
                    options.gpu.chain_passes = options.chain_passes.unwrap_or(profile.chain_passes);
                    let renderer = Box::new(GpuRenderer::new(&ctx)?);
                    engine = Engine::Gpu { ctx, renderer };
                }
                // A device asked for by name or index is a request for the
                // GPU: not finding it is an error (exit 3), not a fallback.
                Err(e) if options.backend == Backend::Auto && options.device.is_none() => {
                    note = Some(format!(
                        "no usable Vulkan device ({e}); rendered on the CPU reference"
                    ));
                }
                Err(e) => return Err(e.into()),
            }
        }
        Ok(Renderer {
            options,
            engine,
            setup_timings: std::sync::Mutex::new(Some(timings)),
            note,
            cancel: None,
        })
    }

    /// From now on, a render in flight when `flag` is set ends with
    /// `Error::Cancelled`: on the GPU once its tiles in flight are done, on
    /// the CPU once its bands in flight are. `glint view` sets it when the
    /// view changes, so a new view never waits for the old one's pass.
    pub fn set_cancel(&mut self, flag: Arc<AtomicBool>) {
        if let Engine::Gpu { renderer, .. } = &mut self.engine {
            renderer.set_cancel(flag.clone());
        }
        self.cancel = Some(flag);
    }

    pub(super) fn cancelled(&self) -> bool {
        self.cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed))
    }

    /// The options it was made with, the driver profile's tile and budget filled in.
    pub fn options(&self) -> &RenderOptions {
        &self.options
    }

    /// Something the user should know of the backend's choice (why `auto`
    /// rendered on the CPU reference).
    pub fn note(&self) -> Option<&str> {
        self.note.as_deref()
    }

    /// Whether it renders on a Vulkan device.
    pub fn is_gpu(&self) -> bool {
        matches!(self.engine, Engine::Gpu { .. })
    }

    /// The GPU renderer this one drives (None on the CPU), for benchmarks
    /// that measure below a render (probe kernels, uncached pipeline
    /// builds) on the device the `Renderer` chose.
    pub fn gpu(&self) -> Option<&GpuRenderer> {
        match &self.engine {
            Engine::Gpu { renderer, .. } => Some(renderer),
            Engine::Cpu(_) => None,
        }
    }

    /// What renders, e.g. "GPU: llvmpipe (cpu, ...)" or "CPU reference (f32, 2 threads)".
    pub fn name(&self) -> String {
        match &self.engine {
            Engine::Gpu { ctx, .. } => {
                let info = ctx.info();
                format!("GPU: {} ({}, {})", info.name, info.device_type, info.driver)
            }
            Engine::Cpu(precision) => {
                let bits = match precision {
                    Precision::F32 => "f32",
                    Precision::F64 => "f64",
                };
                format!(
                    "CPU reference ({bits}, {} threads)",
                    rayon::current_num_threads()
                )
            }
        }
    }

    /// The device's limits (None on the CPU).
    pub fn device_limits(&self) -> Option<crate::gpu::DeviceLimits> {
        match &self.engine {
            Engine::Gpu { ctx, .. } => Some(*ctx.limits()),
            Engine::Cpu(_) => None,
        }
    }

    /// Vulkan validation messages seen so far (0 without validation).
    pub fn validation_messages(&self) -> u32 {
        match &self.engine {
            Engine::Gpu { ctx, .. } => ctx.validation_messages(),
            Engine::Cpu(_) => 0,
        }
    }

    /// `scene` must be in view space (`Scene::in_view_space`).
    pub(super) fn prepare(&self, scene: &Scene, timings: &mut Timings) -> Prepared {
        let effects = self.options.effects(scene);
        let features = self.options.features(scene);
        let bvh = match &self.options.scene_cache {
            Some(cache) => cache.bvh_for_render(scene, &effects, timings),
            None => timings.time("bvh", || Bvh::for_render(scene, &effects)),
        };
        Prepared {
            camera: Camera::with_fov(self.options.width, self.options.height, scene.fov()),
            bvh,
            effects,
            features,
        }
    }

    pub(super) fn gpu_options(&self, p: &Prepared) -> GpuRenderOptions {
        GpuRenderOptions {
            methods: self.options.methods,
            effects: p.effects,
            features: p.features,
            ..self.options.gpu
        }
    }

    pub(super) fn cpu_options(&self, p: &Prepared, precision: Precision) -> CpuOptions {
        CpuOptions {
            background: self.options.background,
            precision,
            methods: self.options.methods,
            effects: p.effects,
            packets: self.options.packets,
        }
    }

    /// Builds the GPU pipeline `scene` calls for (no-op on the CPU); returns
    /// its build time, zero when it was already built.
    pub fn prepare_pipeline(&self, scene: &Scene) -> Result<Duration, Error> {
        match &self.engine {
            Engine::Gpu { renderer, .. } => {
                let scene = scene.in_view_space();
                let p = self.prepare(&scene, &mut Timings::default());
                let packed = GpuScene::pack(&scene, &p.bvh);
                Ok(renderer.prepare(&packed, &self.gpu_options(&p), crate::gpu::Kernel::Render)?)
            }
            Engine::Cpu(_) => Ok(Duration::ZERO),
        }
    }

    /// Renders `scene`; `progress(done, total)` counts pixels finished (GPU)
    /// or rows (CPU, taken in runs spread over the image, so that the
    /// share done tracks the share of time spent).
    pub fn render(
        &self,
        scene: &Scene,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<RenderOutput, Error> {
        self.render_region(scene, Region::All, progress)
    }

    /// Part `index` of `count` (`parts::cut`, balanced by a cost estimate
    /// from a CPU probe of a few pixels), each pixel with the value a full
    /// render gives it; returns its pixels too. Every task of an array
    /// cuts alike, from the same scene and settings.
    pub(super) fn render_part_as(
        &self,
        scene: &Scene,
        index: u32,
        count: u32,
        pixels: PixelFormat,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<(RenderOutput, Span), Error> {
        let (w, h) = (self.options.width, self.options.height);
        if u64::from(count) > u64::from(w) * u64::from(h) || index >= count {
            return Err(Error::InvalidOption(format!(
                "part {index} of {count}: a {w}x{h} image has {} pixels, and each part holds one at least",
                u64::from(w) * u64::from(h)
            )));
        }
        let mut timings = self.take_setup_timings();
        let scene = &*in_view_space(scene, &mut timings);
        let p = self.prepare(scene, &mut timings);
        let packed = self.pack(scene, &p, &mut timings);
        let start = Instant::now();
        let spans = crate::parts::cut::cut(&self.part_costs(scene, &p, &packed, count), count);
        timings.add("part cut", start.elapsed());
        let span = spans[index as usize];
        let region = Region::Span(span);
        let out = self.render_prepared_as(scene, &p, &packed, timings, region, pixels, progress)?;
        Ok((out, span))
    }

    /// Rays cast by a sparse grid of pixels as costs per row: 1/512 of the
    /// image split over the parts, so the parts' probes together trace
    /// 1/512 of its pixels. The probe traces them one by one from a cold
    /// cache, 3 (test1) to 10 (the 2M grid) times a packet's cost a pixel:
    /// at 1/64 the probes of 16 parts of test1 at 1920x1080 cost 4.6% of
    /// the whole render, at 1/256 the 2M grid's cost 4%. Eight columns a
    /// row: the cut needs each row's cost, not where in the row it lies.
    fn part_costs(&self, scene: &Scene, p: &Prepared, packed: &Packed, count: u32) -> Costs {
        let (w, h) = (p.camera.width, p.camera.height);
        let budget = (u64::from(w) * u64::from(h) / (512 * u64::from(count))).clamp(64, 1 << 12);
        let cols = w.min(8);
        let rows = (budget / u64::from(cols)).clamp(1, u64::from(h)) as u32;
        let at = |i: u32, n: u32, of: u32| {
            ((2 * u64::from(i) + 1) * u64::from(of) / (2 * u64::from(n))) as u32
        };
        let xs: Vec<u32> = (0..cols).map(|i| at(i, cols, w)).collect();
        let ys: Vec<u32> = (0..rows).map(|j| at(j, rows, h)).collect();
        let options = self.cpu_options(p, Precision::F32);
        let built;
        let geometry = match packed {
            Packed::Cpu(cpu::Geometry::F32(g)) => g,
            _ => {
                built = crate::cpu::trace::CpuGeometry::new(scene, &p.bvh, &p.effects);
                &built
            }
        };
        let probe = cpu::ray_costs(scene, &p.bvh, geometry, &p.camera, &options, &xs, &ys);
        Costs::from_probe(w, h, &probe, cols)
    }

    fn render_region(
        &self,
        scene: &Scene,
        region: Region,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<RenderOutput, Error> {
        self.render_region_as(scene, region, self.options.pixels, progress)
    }

    pub(super) fn render_region_as(
        &self,
        scene: &Scene,
        region: Region,
        pixels: PixelFormat,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<RenderOutput, Error> {
        let mut timings = self.take_setup_timings();
        let scene = &*in_view_space(scene, &mut timings);
        let p = self.prepare(scene, &mut timings);
        let packed = self.pack(scene, &p, &mut timings);
        self.render_prepared_as(scene, &p, &packed, timings, region, pixels, progress)
    }

    /// Makes `scene` ready for repeated renders (camera, BVH, packed data),
    /// so that timing them measures the render alone.
    pub fn prepare_scene(&self, scene: &Scene) -> PreparedScene {
        let mut timings = Timings::default();
        let view = match scene.in_view_space() {
            std::borrow::Cow::Owned(s) => Some(s),
            std::borrow::Cow::Borrowed(_) => None,
        };
        let seen = view.as_ref().unwrap_or(scene);
        let prepared = self.prepare(seen, &mut timings);
        let packed = self.pack(seen, &prepared, &mut timings);
        PreparedScene {
            prepared,
            packed,
            view,
            timings,
        }
    }

    /// Renders a scene `prepare_scene` made ready (the same `scene`).
    pub fn render_prepared_scene(
        &self,
        scene: &Scene,
        ready: &PreparedScene,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<RenderOutput, Error> {
        let timings = self.take_setup_timings();
        self.render_prepared(
            ready.view.as_ref().unwrap_or(scene),
            &ready.prepared,
            &ready.packed,
            timings,
            Region::All,
            progress,
        )
    }

    pub(super) fn take_setup_timings(&self) -> Timings {
        self.setup_timings
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take()
            .unwrap_or_default()
    }

    /// The scene as the backend reads it: packed into the GPU's buffers, or
    /// the CPU reference's geometry in its precision.
    pub(super) fn pack(&self, scene: &Scene, p: &Prepared, timings: &mut Timings) -> Packed {
        match &self.engine {
            Engine::Gpu { .. } => {
                Packed::Gpu(timings.time("pack", || GpuScene::pack(scene, &p.bvh)))
            }
            Engine::Cpu(precision) => {
                let options = self.cpu_options(p, *precision);
                Packed::Cpu(timings.time("pack", || cpu::prepare(scene, &p.bvh, &options)))
            }
        }
    }

    fn render_prepared(
        &self,
        scene: &Scene,
        p: &Prepared,
        packed: &Packed,
        timings: Timings,
        region: Region,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<RenderOutput, Error> {
        self.render_prepared_as(
            scene,
            p,
            packed,
            timings,
            region,
            self.options.pixels,
            progress,
        )
    }

    /// `render_prepared` into `pixels` (progressive passes accumulate
    /// floats whatever the options ask for).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn render_prepared_as(
        &self,
        scene: &Scene,
        p: &Prepared,
        packed: &Packed,
        mut timings: Timings,
        region: Region,
        pixels: PixelFormat,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<RenderOutput, Error> {
        let mut need = MemoryNeed::image(p.camera.width, p.camera.height);
        let image = match (&self.engine, packed) {
            (Engine::Gpu { renderer, ctx }, Packed::Gpu(packed)) => {
                let host_device = ctx.info().profile.host_memory;
                let texels = crate::gpu::tile_texels(
                    self.options.gpu.tile_size,
                    p.camera.width,
                    p.camera.height,
                );
                need.add_gpu(packed, texels, host_device);
                if self.options.gpu.gather {
                    let rgb8 = pixels == PixelFormat::Rgb8;
                    let [w, h] = [p.camera.width, p.camera.height];
                    need.add_gathered(crate::gpu::gathered_image_bytes(w, h, rgb8));
                }
                need.check(memory::available())?;
                let options = GpuRenderOptions {
                    pack_rgb8: pixels == PixelFormat::Rgb8,
                    ..self.gpu_options(p)
                };
                let bg = self.options.background;
                let rects = match region {
                    Region::All => None,
                    Region::Blocks(b) => Some(b.rects()),
                    Region::Crop(c) => Some(vec![c.rect()]),
                    Region::Span(s) => Some(s.rects()),
                };
                let rendered = renderer.render_image(
                    packed,
                    &p.camera,
                    bg,
                    &options,
                    rects.as_deref(),
                    progress,
                );
                let (image, gpu_timings) = match rendered {
                    Err(crate::gpu::GpuError::Cancelled) => return Err(Error::Cancelled),
                    r => r?,
                };
                timings.extend(&gpu_timings);
                // Over the renderer's life: how its pipelines came to be.
                let (compiled, from_disk) = renderer.pipeline_builds();
                timings.count("pipelines compiled", compiled);
                if from_disk > 0 {
                    timings.count("pipelines from disk", from_disk);
                }
                image
            }
            (Engine::Cpu(precision), Packed::Cpu(geometry)) => self.render_on_cpu(
                scene,
                p,
                geometry,
                *precision,
                region,
                pixels,
                progress,
                &mut timings,
                &mut need,
            )?,
            // `pack` makes each engine its own.
            _ => unreachable!("a scene packed for another backend"),
        };
        Ok(RenderOutput {
            image,
            renderer: self.name(),
            validation_messages: self.validation_messages(),
            timings,
            note: self.note.clone(),
            memory: need,
            bvh: p.bvh.stats(),
            samples: region.pixels(p.camera.width, p.camera.height) * u64::from(p.effects.spp),
        })
    }
}

/// `scene.in_view_space()`, timed as `view` where its camera moved it (a
/// copy of every primitive: 2M triangles take a tenth of a second).
fn in_view_space<'s>(scene: &'s Scene, timings: &mut Timings) -> std::borrow::Cow<'s, Scene> {
    let start = Instant::now();
    let view = scene.in_view_space();
    if matches!(view, std::borrow::Cow::Owned(_)) {
        timings.add("view", start.elapsed());
    }
    view
}

/// Renders `scene` once (a `Renderer` set up for this call only).
pub fn render(
    scene: &Scene,
    options: &RenderOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<RenderOutput, Error> {
    Renderer::new(options)?.render(scene, progress)
}
