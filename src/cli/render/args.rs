//! `glint render`'s flags.

use std::path::PathBuf;
use std::time::Duration;

use clap::Args;
use glint::images::encode::{EncodeOptions, PngCompression};
use glint::images::framebuffer::{ImageFile, DEFAULT_JPEG_QUALITY};
use glint::methods::Methods;
use glint::parts::crop::Crop;
use glint::render::RenderOptions;

use crate::cli::values::{parse_error_target, parse_pixel, parse_range, parse_seconds};
use crate::cli::{CameraArgs, DeviceArgs, EffectArgs, ImageArgs, MethodsArg};

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Scene file in the classic format, or a model file (.obj, .ply, .off, .stl, .gltf,
    /// .glb) seen alone, framed; `-` reads a scene from standard input.
    pub scene: PathBuf,
    /// Output image (.jpg, .jpeg, .png, .ppm, or .exr for float values);
    /// `-` writes PNG to standard output; default: <scene stem>.jpg here.
    pub out: Option<PathBuf>,
    /// Output image, as an option.
    #[arg(short, long, conflicts_with = "out")]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub image: ImageArgs,
    #[command(flatten)]
    pub device: DeviceArgs,
    #[command(flatten)]
    pub camera: CameraArgs,
    /// JPEG quality (1-100).
    #[arg(long, default_value_t = DEFAULT_JPEG_QUALITY, value_parser = clap::value_parser!(u8).range(1..=100))]
    pub quality: u8,
    /// PNG deflate effort: fast (fdeflate, a few ms at 1080p), default
    /// (balanced, about 8x the time), best (smallest); pixels are the same.
    #[arg(long, value_enum, default_value = "fast")]
    pub png_compression: PngCompression,
    /// Tile edge in pixels for the GPU (work per submit), 8-2048.
    /// Default: the device's driver profile (`glint devices`): 512 on
    /// lavapipe and unknown devices, up to 2048 on GPUs.
    #[arg(long, value_parser = clap::value_parser!(u32).range(8..=2048))]
    pub tile: Option<u32>,
    /// GPU: loop iterations one shader invocation may run per pass (a pass
    /// is one dispatch per tile); a pixel needing more continues in further
    /// passes, with the same image. Bounds every dispatch's work whatever
    /// the scene asks for. Default: the device's driver profile (2048).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub pass_budget: Option<u32>,
    /// GPU: seconds to wait for one pass before failing (exit 1).
    #[arg(long, value_name = "SECONDS", default_value_t = glint::gpu::GpuRenderOptions::default().pass_timeout.as_secs_f64(), value_parser = parse_seconds)]
    pub pass_timeout: f64,
    /// Print timings (parse, BVH build, pipeline, upload, dispatch, readback).
    #[arg(short, long)]
    pub verbose: bool,
    /// Trace only pixel X,Y (0,0 = top left) and print its path: the hit,
    /// point, normals, material, and each light's shadow verdict and Phong
    /// terms, on the chosen backend. Writes no image.
    #[arg(long, value_name = "X,Y", value_parser = parse_pixel)]
    pub pixel: Option<[u32; 2]>,
    /// Intersection and offset methods. naive: Möller-Trumbore, the
    /// quadratic sphere test and a fixed 1e-4 offset, to see what the robust
    /// methods fix.
    #[arg(long, value_enum, default_value = "robust")]
    pub methods: MethodsArg,
    #[command(flatten)]
    pub effects: EffectArgs,
    /// Render an animation of N frames (frame i at time i / fps) into the
    /// directory OUT (default: <scene stem>_frames), as 000.jpg, 001.jpg, ...
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1_000_000), conflicts_with = "pixel")]
    pub frames: Option<u32>,
    /// With --frames: only frames FIRST to LAST (inclusive, counted from 0),
    /// to split an animation across machines.
    #[arg(long, value_name = "FIRST-LAST", value_parser = parse_range, requires = "frames")]
    pub frame_range: Option<[u32; 2]>,
    /// Image format of animation frames.
    #[arg(long, value_enum, default_value = "jpg", requires = "frames")]
    pub frame_format: FrameFormat,
    /// GPU: use the generic shader (every effect compiled in, switched by the
    /// settings) instead of one specialised for the scene; for comparisons.
    #[arg(long)]
    pub generic_shader: bool,
    /// Also show the finished image in a window (`glint view` refines one
    /// as it renders); the image is written first.
    #[arg(long, conflicts_with_all = ["frames", "pixel"])]
    pub show: bool,
    /// GPU: read every list from its storage buffer even on a CPU device
    /// (the shader a GPU runs), not through device addresses or from
    /// uniform copies; for comparisons.
    #[arg(long)]
    pub storage_lists: bool,
    /// Render in passes of the scene's samples per pixel (each with its own
    /// seed) until the estimated RMSE of the image (linear values, 0-1,
    /// from the difference of the even and odd passes) is at most E. Exit 1
    /// if the sample cap comes first (the image is still written).
    #[arg(long, value_name = "E", value_parser = parse_error_target, conflicts_with_all = ["pixel", "frames"])]
    pub target_error: Option<f64>,
    /// Render in passes (as --target-error) until the next pass would end
    /// after S seconds; with --target-error, whichever comes first.
    #[arg(long, value_name = "S", value_parser = parse_seconds, conflicts_with_all = ["pixel", "frames"])]
    pub time_limit: Option<f64>,
    /// With --target-error: after 4 passes over the whole image, spend
    /// passes only on the 16x16 blocks whose own estimate is still above
    /// the target.
    #[arg(long, requires = "target_error")]
    pub adaptive: bool,
    /// Render only the pixels X0..X1-1 by Y0..Y1-1 (pbrt's --pixelbounds);
    /// the output is a full-size .png or .exr whose alpha marks them, for
    /// `glint stitch` to join with the other parts, bit for bit.
    #[arg(long, value_name = "X0,Y0,X1,Y1", value_parser = Crop::parse, conflicts_with_all = ["pixel", "frames", "target_error", "time_limit"])]
    pub crop: Option<Crop>,
    /// One task's share of a render spread over machines: part I of N
    /// (counted from 0), or slurm/N, k8s/N, env/N to read I from
    /// SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX. Writes OUT's part file
    /// (out.png -> out.part03-of-16.png) for `glint stitch OUT --parts N`;
    /// with --frames, the I-th share of the frames. A part already done for
    /// the same render is kept, so a requeued task redoes only what is missing.
    #[arg(long, value_name = "I/N", value_parser = glint::parts::PartArg::parse, conflicts_with_all = ["pixel", "crop", "frame_range", "target_error", "time_limit", "show"])]
    pub part: Option<glint::parts::PartArg>,
    /// Preview: 1 sample per pixel, 1 shadow sample, no reflection, half
    /// the width and height; flags given beside it win.
    #[arg(long)]
    pub quick: bool,
    /// After the render: rays cast by kind and per second, samples, the
    /// BVH, time per phase, peak memory (also with -v).
    #[arg(long)]
    pub stats: bool,
}

impl RenderArgs {
    pub fn encode_options(&self) -> EncodeOptions {
        EncodeOptions {
            jpeg_quality: self.quality,
            png: self.png_compression,
        }
    }

    /// `--quick` applied: the preview's settings where no flag sets them.
    pub fn resolved(mut self) -> RenderArgs {
        if self.quick {
            self.image.width = self.image.width.div_ceil(2);
            self.image.height = self.image.height.div_ceil(2);
            let e = &mut self.effects;
            e.spp = e.spp.or(Some(1));
            e.shadow_samples = e.shadow_samples.or(Some(1));
            e.reflect = e.reflect.or(Some(0));
        }
        self
    }
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum FrameFormat {
    Jpg,
    Png,
    Ppm,
    Exr,
}

impl FrameFormat {
    pub fn kind(self) -> ImageFile {
        match self {
            FrameFormat::Jpg => ImageFile::Jpeg,
            FrameFormat::Png => ImageFile::Png,
            FrameFormat::Ppm => ImageFile::Ppm,
            FrameFormat::Exr => ImageFile::Exr,
        }
    }
}

impl RenderArgs {
    /// The render options the flags decide.
    pub fn options(&self) -> anyhow::Result<RenderOptions> {
        let base = crate::cli::flags::render_options(&self.image, &self.device, &self.effects)?;
        Ok(RenderOptions {
            methods: match self.methods {
                MethodsArg::Robust => Methods::Robust,
                MethodsArg::Naive => Methods::Naive,
            },
            generic: self.generic_shader,
            tile: self.tile,
            pass_budget: self.pass_budget,
            gpu: glint::gpu::GpuRenderOptions {
                pass_timeout: Duration::from_secs_f64(self.pass_timeout),
                uniform_lists: !self.storage_lists,
                ..Default::default()
            },
            ..base
        })
    }
}
