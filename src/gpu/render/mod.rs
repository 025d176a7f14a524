//! Rendering a packed scene on the GPU, tile by tile and pass by pass:
//! `job` (what is asked), `plan` (where each list goes), `resources` (what
//! stays on the device), `passes` (the loop), `record` (a pass's commands),
//! `status` (what a pass's status says), and here the renderer.
//!
//! A tile's work is split into passes of bounded size (the shader's
//! `render_tile` runs each pixel's work as a resumable state machine with a
//! budget of loop iterations per pass), so no invocation runs into a driver's
//! loop limit and no submission runs long enough to trip a watchdog, whatever
//! the scene asks for. Each pass is one submit with its own fence; the host
//! reads each pass's status: pixels left (another pass), or pixels cut short
//! (the tile is redone with a smaller budget, or the render fails naming the
//! pixel). A tile's later passes are queued several at a time, and the host
//! waits once for them (`GpuRenderOptions::chain_passes`). A tile's first
//! pass runs a shader that keeps no pixel state; a tile with pixels left
//! after it is redone with the resumable one (`TileWork::resumable`). Two
//! tile slots alternate, so the GPU works on one while the host reads the
//! other back. A tile is dispatched into device-local buffers (its output
//! and its status) and copied into host-visible ones, so shaders never write
//! across PCIe; a packed render's tiles are copied into their places in one
//! image the host reads once (`GpuRenderOptions::gather`).
//!
//! Everything a render needs on the device (command buffers, descriptor sets,
//! fences, scene, tile and staging buffers) is created once per renderer and
//! reused by every tile, pass and frame; a buffer is recreated only when a
//! scene needs a larger one, so memory stays flat over an animation.

mod job;
mod passes;
mod plan;
mod record;
mod resources;
mod status;

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

pub use job::{
    gathered_image_bytes, tile_texels, GpuRenderOptions, DEFAULT_PASS_BUDGET, MAX_CHAIN,
    RESUMABLE_REDOS,
};
use job::{place_rows, place_tile, tile_edge, tiles, Job, TileRect, TileSink};
use passes::Work;
use plan::{capped, key, plan_lists, scene_uploads};
use resources::{Gpu, Resources};

use super::bindings::Lists;
use super::context::Context;
use super::error::GpuError;
use super::pipeline::{Kernel, TracePipeline};
use super::present::FrameTarget;
use crate::camera::Camera;
use crate::images::framebuffer::{Framebuffer, Image};
use crate::layout::GpuScene;
use crate::probe::{PathRecord, ProbeImage};
use crate::timing::Timings;

/// A device with the trace pipeline built; renders any number of scenes.
pub struct GpuRenderer {
    ctx: Context,
    pipeline: TracePipeline,
    /// Reused by every render; `None` until the first.
    resources: Mutex<Option<Resources>>,
    /// The most passes a tile of the last render needed (0 before the
    /// first). Over one, the next starts its tiles resumable
    /// (`TileWork::resumable`), with that many passes queued at once (up to
    /// `chain_passes`), so a run of renders of such work (progressive
    /// passes, animation frames) redoes tiles only in its first and waits
    /// about once a tile. A wrong guess costs time, never the image.
    passes_needed: AtomicU32,
    /// Set by whoever renders (`glint view`, when the view changes): the
    /// render in flight ends after its tiles in flight.
    cancel: Option<Arc<AtomicBool>>,
    /// Where each colour pass's tiles are also copied, on the device (the
    /// window's running mean: `gpu::present`).
    frame: Mutex<Option<FrameTarget>>,
}

impl GpuRenderer {
    /// A renderer on `ctx`'s device, with its trace pipeline built.
    pub fn new(ctx: &Context) -> Result<GpuRenderer, GpuError> {
        let pipeline = TracePipeline::new(ctx)?;
        Ok(GpuRenderer {
            ctx: ctx.clone(),
            pipeline,
            resources: Mutex::new(None),
            passes_needed: AtomicU32::new(0),
            cancel: None,
            frame: Mutex::new(None),
        })
    }

    /// Renders from now on end with `GpuError::Cancelled` once `flag` is
    /// set, starting no tile or pass after it.
    pub fn set_cancel(&mut self, flag: Arc<AtomicBool>) {
        self.cancel = Some(flag);
    }

    /// From now on, each colour render of `target`'s size also copies its
    /// tiles into `target` on the device (`DeviceMean::start`); `None`
    /// stops it. A target of another device is ignored.
    pub fn copy_passes_to(&self, target: Option<FrameTarget>) {
        let target = target.filter(|t| t.device == self.ctx.shared.device.handle());
        *self.frame.lock().unwrap_or_else(|e| e.into_inner()) = target;
    }

    fn gpu(&self) -> Gpu<'_> {
        Gpu {
            shared: &self.ctx.shared,
            pipeline: &self.pipeline,
        }
    }

    /// Runs `work` on this renderer's resources (created on first use),
    /// starting resumable if the last render needed passes.
    fn run(
        &self,
        work: Work,
        progress: &(dyn Fn(u64, u64) + Sync),
        sink: &mut TileSink,
    ) -> Result<Timings, GpuError> {
        let mut guard = self.resources.lock().unwrap_or_else(|e| e.into_inner());
        if guard.is_none() {
            *guard = Some(self.gpu().create_resources()?);
        }
        let res = guard.as_mut().expect("just created");
        let frame = *self.frame.lock().unwrap_or_else(|e| e.into_inner());
        let colour = matches!(work.job, Job::Image(Kernel::Render) | Job::Rects);
        let work = Work {
            start_passes: self.passes_needed.load(Ordering::Relaxed),
            cancel: self.cancel.as_deref(),
            frame: frame.filter(|f| {
                colour && [f.width, f.height] == [work.camera.width, work.camera.height]
            }),
            ..work
        };
        let result = self.gpu().run(&work, res, progress, sink);
        if result.is_err() {
            self.gpu().settle(&mut res.slots, work.options);
        }
        let (timings, passes_needed) = result?;
        if let Some(needed) = passes_needed {
            self.passes_needed.store(needed, Ordering::Relaxed);
        }
        Ok(timings)
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
        let limits = capped(self.ctx.shared.limits, options.storage_limit);
        // A plan that fails fails the render too, which then says why.
        let uploads = scene_uploads(scene);
        let lists = plan_lists(&uploads, &limits, self.gpu().forms(options))
            .map_or(Lists::Plain, |(_, lists)| lists);
        Ok(self
            .pipeline
            .get(key(
                options,
                kernel,
                lists,
                scene,
                &uploads,
                self.passes_needed.load(Ordering::Relaxed) > 1 || !options.one_pass_first,
            ))?
            .1)
    }

    /// Pipelines built so far: (compiled by the driver, found in the disk
    /// cache).
    pub fn pipeline_builds(&self) -> (u64, u64) {
        self.pipeline.builds()
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
        self.render_float(scene, camera, background, options, None, progress)
    }

    /// Renders `scene` (only the rectangles `rects` (x, y, width, height)
    /// where given, the rest 0) into float values, or into 8-bit pixels
    /// packed on the device where `options.pack_rgb8` asks.
    pub fn render_image(
        &self,
        scene: &GpuScene,
        camera: &Camera,
        background: [f32; 3],
        options: &GpuRenderOptions,
        rects: Option<&[[u32; 4]]>,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<(Image, Timings), GpuError> {
        let Some(rects) = rects else {
            let job = Job::Image(Kernel::Render);
            return self.render_job(scene, camera, background, options, job, &[], progress);
        };
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
        self.render_float(scene, camera, background, options, Some(rects), progress)
    }

    /// `render_image` into float values, whatever `options.pack_rgb8` says.
    fn render_float(
        &self,
        scene: &GpuScene,
        camera: &Camera,
        background: [f32; 3],
        options: &GpuRenderOptions,
        rects: Option<&[[u32; 4]]>,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<(Framebuffer, Timings), GpuError> {
        let options = &GpuRenderOptions {
            pack_rgb8: false,
            ..*options
        };
        let (image, timings) =
            self.render_image(scene, camera, background, options, rects, progress)?;
        Ok((image.into_float(), timings))
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
    ) -> Result<(Image, Timings), GpuError> {
        let width = camera.width as usize;
        let count = width * camera.height as usize;
        let work = Work {
            scene,
            camera,
            background,
            options,
            job,
            rects,
            start_passes: 0,
            cancel: None,
            frame: None,
        };
        if options.pack_rgb8 {
            // R, G, B per texel, tightly packed (`shaders/pack.wgsl`): each
            // row is copied as it is.
            let mut bytes = vec![0u8; count * 3];
            let pixels: &mut [[u8; 3]] = bytemuck::cast_slice_mut(&mut bytes);
            let timings = self.run(work, progress, &mut |rect, read, stride| {
                place_rows(rect, (bytemuck::cast_slice(read), stride), width, pixels)
            })?;
            let image = image::RgbImage::from_raw(camera.width, camera.height, bytes)
                .expect("pixel count matches width * height");
            return Ok((Image::Rgb8(image), timings));
        }
        // f32 R, G, B per texel (`shaders/pack_float.wgsl`), or the whole
        // texels where `read_texels` asks.
        let mut pixels = vec![[0.0f32; 3]; count];
        let timings = self.run(work, progress, &mut |rect, bytes, stride| {
            if options.read_texels {
                let rgba = |t: &[f32; 4]| [t[0], t[1], t[2]];
                let texels = (bytemuck::cast_slice(bytes), stride);
                place_tile(rect, texels, width, &mut pixels, rgba)
            } else {
                place_rows(
                    rect,
                    (bytemuck::cast_slice(bytes), stride),
                    width,
                    &mut pixels,
                )
            }
        })?;
        let fb = Framebuffer {
            width: camera.width,
            height: camera.height,
            pixels,
        };
        Ok((Image::Float(fb), timings))
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
            Work {
                scene,
                camera,
                background: [0.0; 3],
                options,
                job,
                rects: &[],
                start_passes: 0,
                cancel: None,
                frame: None,
            },
            &|_, _| {},
            &mut |rect, bytes, stride| {
                let texels = (bytemuck::cast_slice(bytes), stride);
                place_tile(rect, texels, width, &mut image, |t| *t)
            },
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
            Work {
                scene,
                camera,
                background,
                options,
                job,
                rects: &[],
                start_passes: 0,
                cancel: None,
                frame: None,
            },
            &|_, _| {},
            &mut |_, bytes, _| record = bytemuck::cast_slice(bytes).to_vec(),
        )?;
        let mut path = PathRecord::from_texels(&record);
        path.prim = scene.scene_prim(path.prim);
        for light in &mut path.lights {
            light.blocker = scene.scene_prim(light.blocker);
        }
        Ok(path)
    }
}
