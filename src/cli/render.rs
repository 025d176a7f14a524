use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use clap::Args;
use glint::framebuffer::{check_output, DEFAULT_JPEG_QUALITY};
use glint::gpu::DeviceSelector;
use glint::methods::Methods;
use glint::progressive::{PassReport, StopAt, Stopped};
use glint::render::{pixel_path, RenderOptions, Renderer};
use glint::scene::Scene;
use indicatif::{ProgressBar, ProgressStyle};

use glint::encode::{EncodeOptions, PngCompression};
use glint::framebuffer::{Image, ImageFile};
use glint::region::Crop;

mod frames;

use super::values::{parse_error_target, parse_pixel, parse_range, parse_rgb, parse_seconds};
use super::{
    print_warnings, read_scene, validation_verdict, BackendArg, EffectArgs, MethodsArg,
    PrecisionArg,
};

/// Where a render's messages go: stdout, unless the image goes there.
#[derive(Clone, Copy)]
struct Say {
    to_stderr: bool,
}

impl Say {
    fn line(self, s: impl std::fmt::Display) {
        if self.to_stderr {
            eprintln!("{s}");
        } else {
            println!("{s}");
        }
    }
}

/// Where the image goes.
enum Out {
    File(PathBuf),
    /// `-`: PNG on standard output.
    Stdout,
}

impl Out {
    fn path(&self) -> &Path {
        match self {
            Out::File(p) => p,
            Out::Stdout => Path::new("standard output"),
        }
    }

    /// Encodes and writes `image`, adding the two phases' times to
    /// `timings` as `encode` and `write`.
    fn write(
        &self,
        image: &Image,
        crop: Option<&Crop>,
        options: &EncodeOptions,
        timings: &mut glint::timing::Timings,
    ) -> Result<(), glint::Error> {
        let fb = || image.to_float();
        match (self, crop) {
            (Out::File(p), Some(c)) => {
                return timings.time("write", || glint::region::write_part(&fb(), c, p))
            }
            (Out::Stdout, Some(c)) => {
                return timings.time("write", || glint::region::write_part_to_stdout(&fb(), c))
            }
            _ => {}
        }
        let kind = match self {
            Out::File(p) => ImageFile::of(p)?,
            Out::Stdout => ImageFile::Png,
        };
        let bytes = timings
            .time("encode", || image.encode(kind, options))
            .map_err(|e| glint::Error::WriteImage {
                path: self.path().to_path_buf(),
                error: std::io::Error::other(e),
            })?;
        timings.time("write", || match self {
            Out::File(p) => glint::framebuffer::write_bytes(p, &bytes),
            Out::Stdout => glint::framebuffer::write_bytes_to_stdout(&bytes),
        })
    }
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Scene file in the classic format; `-` reads it from standard input.
    scene: PathBuf,
    /// Output image (.jpg, .jpeg, .png, .ppm, or .exr for float values);
    /// `-` writes PNG to standard output; default: <scene stem>.jpg here.
    out: Option<PathBuf>,
    /// Output image, as an option.
    #[arg(short, long, conflicts_with = "out")]
    output: Option<PathBuf>,
    #[arg(long, default_value_t = glint::camera::DEFAULT_WIDTH, value_parser = clap::value_parser!(u32).range(1..=16384))]
    width: u32,
    #[arg(long, default_value_t = glint::camera::DEFAULT_HEIGHT, value_parser = clap::value_parser!(u32).range(1..=16384))]
    height: u32,
    /// auto: the best hardware Vulkan device; the CPU reference when there is
    /// none or only a software one such as lavapipe (with a note).
    #[arg(long, value_enum, default_value = "auto")]
    backend: BackendArg,
    /// Vulkan device by index or name (see `glint devices`).
    #[arg(long)]
    device: Option<String>,
    /// CPU reference arithmetic: f32 follows the shader, f64 is ground truth.
    #[arg(long, value_enum, default_value = "f32")]
    precision: PrecisionArg,
    /// Colour of rays that hit nothing, as R,G,B in [0, 1].
    #[arg(long, default_value = "1,1,1", value_parser = parse_rgb)]
    background: [f32; 3],
    /// JPEG quality (1-100).
    #[arg(long, default_value_t = DEFAULT_JPEG_QUALITY, value_parser = clap::value_parser!(u8).range(1..=100))]
    quality: u8,
    /// PNG deflate effort: fast (fdeflate, a few ms at 1080p), default
    /// (balanced, about 8x the time), best (smallest); pixels are the same.
    #[arg(long, value_enum, default_value = "fast")]
    png_compression: PngCompression,
    /// Enable the Vulkan validation layer (when installed) and report its messages.
    #[arg(long)]
    validation: bool,
    /// Tile edge in pixels for the GPU (work per submit), 8-2048.
    /// Default: the device's driver profile (`glint devices`): 512 on
    /// lavapipe and unknown devices, up to 2048 on GPUs.
    #[arg(long, value_parser = clap::value_parser!(u32).range(8..=2048))]
    tile: Option<u32>,
    /// GPU: loop iterations one shader invocation may run per pass (a pass
    /// is one dispatch per tile); a pixel needing more continues in further
    /// passes, with the same image. Bounds every dispatch's work whatever
    /// the scene asks for. Default: the device's driver profile (2048).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pass_budget: Option<u32>,
    /// GPU: seconds to wait for one pass before failing (exit 1).
    #[arg(long, value_name = "SECONDS", default_value_t = glint::gpu::GpuRenderOptions::default().pass_timeout.as_secs_f64(), value_parser = parse_seconds)]
    pass_timeout: f64,
    /// Print timings (parse, BVH build, pipeline, upload, dispatch, readback).
    #[arg(short, long)]
    verbose: bool,
    /// Trace only pixel X,Y (0,0 = top left) and print its path: the hit,
    /// point, normals, material, and each light's shadow verdict and Phong
    /// terms, on the chosen backend. Writes no image.
    #[arg(long, value_name = "X,Y", value_parser = parse_pixel)]
    pixel: Option<[u32; 2]>,
    /// Intersection and offset methods. naive: Möller-Trumbore, the
    /// quadratic sphere test and a fixed 1e-4 offset, to see what the robust
    /// methods fix.
    #[arg(long, value_enum, default_value = "robust")]
    methods: MethodsArg,
    #[command(flatten)]
    effects: EffectArgs,
    /// Render an animation of N frames (frame i at time i / fps) into the
    /// directory OUT (default: <scene stem>_frames), as 000.jpg, 001.jpg, ...
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1_000_000), conflicts_with = "pixel")]
    frames: Option<u32>,
    /// With --frames: only frames FIRST to LAST (inclusive, counted from 0),
    /// to split an animation across machines.
    #[arg(long, value_name = "FIRST-LAST", value_parser = parse_range, requires = "frames")]
    frame_range: Option<[u32; 2]>,
    /// Image format of animation frames.
    #[arg(long, value_enum, default_value = "jpg", requires = "frames")]
    frame_format: FrameFormat,
    /// GPU: use the generic shader (every effect compiled in, switched by the
    /// settings) instead of one specialised for the scene; for comparisons.
    #[arg(long)]
    generic_shader: bool,
    /// Also show the finished image in a window (`glint view` refines one
    /// as it renders); the image is written first.
    #[arg(long, conflicts_with_all = ["frames", "pixel"])]
    show: bool,
    /// GPU: read every list from its storage buffer even on a CPU device
    /// (the shader a GPU runs), not through device addresses or from
    /// uniform copies; for comparisons.
    #[arg(long)]
    storage_lists: bool,
    /// Render in passes of the scene's samples per pixel (each with its own
    /// seed) until the estimated RMSE of the image (linear values, 0-1,
    /// from the difference of the even and odd passes) is at most E. Exit 1
    /// if the sample cap comes first (the image is still written).
    #[arg(long, value_name = "E", value_parser = parse_error_target, conflicts_with_all = ["pixel", "frames"])]
    target_error: Option<f64>,
    /// Render in passes (as --target-error) until the next pass would end
    /// after S seconds; with --target-error, whichever comes first.
    #[arg(long, value_name = "S", value_parser = parse_seconds, conflicts_with_all = ["pixel", "frames"])]
    time_limit: Option<f64>,
    /// With --target-error: after 4 passes over the whole image, spend
    /// passes only on the 16x16 blocks whose own estimate is still above
    /// the target.
    #[arg(long, requires = "target_error")]
    adaptive: bool,
    /// Render only the pixels X0..X1-1 by Y0..Y1-1 (pbrt's --pixelbounds);
    /// the output is a full-size .png or .exr whose alpha marks them, for
    /// `glint stitch` to join with the other parts, bit for bit.
    #[arg(long, value_name = "X0,Y0,X1,Y1", value_parser = Crop::parse, conflicts_with_all = ["pixel", "frames", "target_error", "time_limit"])]
    crop: Option<Crop>,
    /// One task's share of a render spread over machines: part I of N
    /// (counted from 0), or slurm/N, k8s/N, env/N to read I from
    /// SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX. Writes OUT's part file
    /// (out.png -> out.part03-of-16.png) for `glint stitch OUT --parts N`;
    /// with --frames, the I-th share of the frames. A part already done for
    /// the same render is kept, so a requeued task redoes only what is missing.
    #[arg(long, value_name = "I/N", value_parser = glint::parts::PartArg::parse, conflicts_with_all = ["pixel", "crop", "frame_range", "target_error", "time_limit", "show"])]
    part: Option<glint::parts::PartArg>,
    /// Preview: 1 sample per pixel, 1 shadow sample, no reflection, half
    /// the width and height; flags given beside it win.
    #[arg(long)]
    quick: bool,
    /// After the render: rays cast by kind and per second, samples, the
    /// BVH, time per phase, peak memory (also with -v).
    #[arg(long)]
    stats: bool,
}

impl RenderArgs {
    fn encode_options(&self) -> EncodeOptions {
        EncodeOptions {
            jpeg_quality: self.quality,
            png: self.png_compression,
        }
    }

    /// `--quick` applied: the preview's settings where no flag sets them.
    fn resolved(mut self) -> RenderArgs {
        if self.quick {
            self.width = self.width.div_ceil(2);
            self.height = self.height.div_ceil(2);
            let e = &mut self.effects;
            e.spp = e.spp.or(Some(1));
            e.shadow_samples = e.shadow_samples.or(Some(1));
            e.reflect = e.reflect.or(Some(0));
        }
        self
    }
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum FrameFormat {
    Jpg,
    Png,
    Ppm,
    Exr,
}

impl FrameFormat {
    fn kind(self) -> ImageFile {
        match self {
            FrameFormat::Jpg => ImageFile::Jpeg,
            FrameFormat::Png => ImageFile::Png,
            FrameFormat::Ppm => ImageFile::Ppm,
            FrameFormat::Exr => ImageFile::Exr,
        }
    }
}

/// `<scene stem>.jpg`, or `stdin.jpg` for a scene read from standard input.
fn default_output(scene: &Path) -> PathBuf {
    if scene == Path::new("-") {
        return PathBuf::from("stdin.jpg");
    }
    let stem = scene.file_stem().unwrap_or(scene.as_os_str());
    PathBuf::from(stem).with_extension("jpg")
}

pub fn run(args: RenderArgs) -> anyhow::Result<ExitCode> {
    let args = args.resolved();
    let (out, defaulted) = match args.out.clone().or(args.output.clone()) {
        Some(p) => (p, false),
        None => (default_output(&args.scene), true),
    };
    let out = if out == Path::new("-") {
        Out::Stdout
    } else {
        Out::File(out)
    };
    let say = Say {
        to_stderr: matches!(out, Out::Stdout),
    };
    // Everything the arguments alone decide is checked before any work.
    match (&out, args.frames) {
        (Out::File(dir), Some(frames)) => check_frames(&args, frames, dir, defaulted)?,
        (Out::Stdout, Some(_)) => {
            return Err(glint::Error::InvalidOption(
                "--frames writes a directory of images; `-` (standard output) holds one image"
                    .into(),
            )
            .into())
        }
        (Out::Stdout, None) => {
            use std::io::IsTerminal;
            if args.pixel.is_none() && std::io::stdout().is_terminal() {
                return Err(glint::Error::InvalidOption(
                    "`-` writes a PNG to standard output, which is a terminal here; \
                     redirect it (`> out.png`) or pipe it to a program"
                        .into(),
                )
                .into());
            }
        }
        (Out::File(path), None) if args.pixel.is_none() => match (&args.crop, &args.part) {
            (Some(_), _) => {
                glint::region::check_part_format(path)?;
                check_output(path)?;
            }
            (None, Some(part)) => {
                let part = super::part::resolve(part)?;
                glint::framebuffer::ImageFile::of(path)?;
                check_output(&glint::parts::part_path(path, part.index, part.count))?;
            }
            (None, None) => check_output(path)?,
        },
        _ => {}
    }
    if let (Out::Stdout, Some(_)) = (&out, &args.part) {
        return Err(glint::Error::InvalidOption(
            "--part writes a part file beside OUT for `glint stitch`; name OUT, not `-`".into(),
        )
        .into());
    }
    if let Some(crop) = &args.crop {
        crop.check(args.width, args.height)?;
    }
    if let Some([x, y]) = args.pixel {
        if x >= args.width || y >= args.height {
            return Err(glint::Error::InvalidOption(format!(
                "pixel {x},{y} is outside the {}x{} image (x counts from 0 at the left, y from 0 at the top)",
                args.width, args.height
            ))
            .into());
        }
    }
    let parse_start = Instant::now();
    let scene = read_scene(&args.scene)?;
    let parse_time = parse_start.elapsed();
    print_warnings(&scene);

    let options = RenderOptions {
        width: args.width,
        height: args.height,
        background: args.background,
        backend: args.backend.into(),
        device: args.device.as_deref().map(DeviceSelector::parse),
        precision: args.precision.into(),
        validation: args.validation || std::env::var_os("GLINT_VALIDATION").is_some(),
        methods: match args.methods {
            MethodsArg::Robust => Methods::Robust,
            MethodsArg::Naive => Methods::Naive,
        },
        settings: args.effects.settings(),
        generic: args.generic_shader,
        packets: true,
        pipeline_cache: glint::gpu::cache::default_dir(),
        tile: args.tile,
        pass_budget: args.pass_budget,
        gpu: glint::gpu::GpuRenderOptions {
            pass_timeout: Duration::from_secs_f64(args.pass_timeout),
            uniform_lists: !args.storage_lists,
            ..Default::default()
        },
        // What the file holds, converted where it is made; a crop's part
        // file, a pixel's path and the window take floats.
        pixels: match (&out, &args.crop, args.pixel, args.show, args.frames) {
            (_, None, None, false, Some(_)) => {
                glint::render::PixelFormat::for_file(args.frame_format.kind())
            }
            (Out::Stdout, None, None, false, None) => glint::render::PixelFormat::Rgb8,
            (Out::File(p), None, None, false, None) if args.part.is_none() => {
                ImageFile::of(p).map_or(Default::default(), glint::render::PixelFormat::for_file)
            }
            _ => glint::render::PixelFormat::Float,
        },
    };
    if let Some(frames) = args.frames {
        let dir = if defaulted {
            let stem = match args.scene.to_str() {
                Some("-") => "stdin".into(),
                _ => args
                    .scene
                    .file_stem()
                    .unwrap_or(args.scene.as_os_str())
                    .to_string_lossy(),
            };
            PathBuf::from(format!("{stem}_frames"))
        } else {
            out.path().to_path_buf()
        };
        return frames::animate(&scene, &options, &args, frames, &dir);
    }
    if let Some(pixel) = args.pixel {
        let start = Instant::now();
        let probed = pixel_path(&scene, &options, pixel)?;
        if let Some(note) = &probed.note {
            eprintln!("note: {note}");
        }
        println!(
            "pixel {},{} of {}x{} on {} ({} methods)",
            pixel[0], pixel[1], args.width, args.height, probed.renderer, options.methods
        );
        print!("{}", probed.value);
        let listed = probed.value.lights.len();
        if probed.value.surface.is_some() && listed < scene.lights.len() {
            println!(
                "({} more lights not listed; the colour includes them all)",
                scene.lights.len() - listed
            );
        }
        let rgb = probed.value.color.map(|c| c.clamp(0.0, 1.0));
        println!(
            "8-bit value ({}, {}, {})",
            glint::framebuffer::to_u8(rgb[0] as f32),
            glint::framebuffer::to_u8(rgb[1] as f32),
            glint::framebuffer::to_u8(rgb[2] as f32)
        );
        validation_verdict(probed.validation_messages)?;
        if args.verbose {
            println!("took {:.1} ms", start.elapsed().as_secs_f64() * 1e3);
        }
        return Ok(ExitCode::SUCCESS);
    }

    if let Some(part) = &args.part {
        let part = super::part::resolve(part)?;
        return super::part::render(
            &args.scene,
            &scene,
            &options,
            part,
            out.path(),
            args.verbose,
        );
    }

    if args.target_error.is_some() || args.time_limit.is_some() {
        return render_progressive(&scene, &options, &args, &out, defaulted, parse_time, say);
    }

    let bar = ProgressBar::new(0);
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} rendering [{bar:30}] {percent:>3}% {elapsed} (eta {eta})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    // Short renders finish before the bar would be useful; only show it later.
    let started = Instant::now();
    let progress = |done: u64, total: u64| {
        if started.elapsed() > Duration::from_millis(500) {
            bar.set_length(total);
            bar.set_position(done);
        }
    };
    let result = Renderer::new(&options).and_then(|r| match &args.crop {
        Some(crop) => r.render_crop(&scene, *crop, &progress),
        None => r.render(&scene, &progress),
    });
    bar.finish_and_clear();
    let output = result?;
    if let Some(note) = &output.note {
        eprintln!("note: {note}");
    }
    validation_verdict(output.validation_messages)?;
    let mut timings = output.timings.clone();
    timings.phases.insert(0, ("parse", parse_time));
    out.write(
        &output.image,
        args.crop.as_ref(),
        &args.encode_options(),
        &mut timings,
    )
    .with_context(|| format!("rendering {}", args.scene.display()))?;
    let what = match &args.crop {
        Some(c) => format!(
            "pixels {c} of {}x{}, a part for `glint stitch`",
            args.width, args.height
        ),
        None => format!("{}x{}", args.width, args.height),
    };
    say.line(format!(
        "wrote {}{} ({what}, {}, {:.1} ms)",
        out.path().display(),
        if defaulted {
            " (default name: <scene>.jpg)"
        } else {
            ""
        },
        output.renderer,
        timings.total().as_secs_f64() * 1e3
    ));
    if args.verbose {
        say.line(format!("timings:\n{timings}"));
        say.line(format!(
            "memory:\n  {} beyond the scene and its BVH",
            output.memory
        ));
    }
    if args.show {
        let title = format!("{} ({})", out.path().display(), output.renderer);
        glint::view::show(output.framebuffer().into_owned(), title)?;
    }
    if args.stats || args.verbose {
        say.line(super::summary::stats(&output, &timings));
    }
    Ok(ExitCode::SUCCESS)
}

/// `--frames`: the range fits and OUT can be the frames' directory.
fn check_frames(args: &RenderArgs, frames: u32, out: &Path, defaulted: bool) -> anyhow::Result<()> {
    let invalid = |m: String| -> anyhow::Error { glint::Error::InvalidOption(m).into() };
    if let Some([first, last]) = args.frame_range {
        if last >= frames {
            return Err(invalid(format!(
                "--frame-range {first}-{last} goes past the last frame of --frames {frames} \
                 (frames count from 0, so the last is {})",
                frames - 1
            )));
        }
    }
    if defaulted {
        return Ok(());
    }
    let bad = |reason: String| -> anyhow::Error {
        glint::Error::BadOutput {
            path: out.to_path_buf(),
            reason,
        }
        .into()
    };
    if glint::framebuffer::ImageFile::of(out).is_ok() {
        return Err(bad(
            "with --frames, the output is a directory for 000.jpg, 001.jpg, ...; this is an image name".into(),
        ));
    }
    if out.exists() && !out.is_dir() {
        return Err(bad(
            "with --frames, the output is a directory for 000.jpg, 001.jpg, ...; this is a file"
                .into(),
        ));
    }
    Ok(())
}

/// `--target-error` / `--time-limit`: passes until one of them says stop.
fn render_progressive(
    scene: &Scene,
    options: &RenderOptions,
    args: &RenderArgs,
    out: &Out,
    defaulted: bool,
    parse_time: Duration,
    say: Say,
) -> anyhow::Result<ExitCode> {
    let stop = StopAt {
        target_rmse: args.target_error,
        time_limit: args.time_limit.map(Duration::from_secs_f64),
        adaptive: args.adaptive,
    };
    let renderer = Renderer::new(options)?;
    if let Some(note) = renderer.note() {
        eprintln!("note: {note}");
    }
    let bar = ProgressBar::new_spinner();
    bar.set_style(
        ProgressStyle::with_template("{spinner} {msg} {elapsed}").expect("valid template"),
    );
    let verbose = args.verbose;
    let mut on_pass = |r: &PassReport| {
        let estimate = r
            .estimated_rmse
            .map_or_else(|| "-".to_string(), |e| format!("{e:.5}"));
        let mut line = format!(
            "pass {}, {} samples per pixel, estimated RMSE {estimate}",
            r.passes, r.samples_per_pixel
        );
        if r.active_blocks[0] < r.active_blocks[1] {
            line.push_str(&format!(
                " ({:.1} samples per pixel on average; next pass: {} of {} blocks)",
                r.mean_samples, r.active_blocks[0], r.active_blocks[1]
            ));
        }
        if verbose {
            bar.suspend(|| eprintln!("{line}, {:.2} s", r.elapsed.as_secs_f64()));
        }
        bar.set_message(line);
        bar.tick();
    };
    let result = renderer.render_progressive(scene, &stop, &mut on_pass);
    bar.finish_and_clear();
    let done = result?;
    validation_verdict(done.output.validation_messages)?;
    let mut write_timings = glint::timing::Timings::default();
    out.write(
        &done.output.image,
        None,
        &args.encode_options(),
        &mut write_timings,
    )
    .with_context(|| format!("rendering {}", args.scene.display()))?;
    let r = done.report;
    let estimate = r
        .estimated_rmse
        .map_or_else(|| "none (one pass)".to_string(), |e| format!("{e:.5}"));
    let samples = if args.adaptive {
        format!(
            "{:.1} samples per pixel on average, at most {}",
            r.mean_samples, r.samples_per_pixel
        )
    } else {
        format!("{} samples per pixel", r.samples_per_pixel)
    };
    say.line(format!(
        "wrote {}{} ({}x{}, {}, {} passes, {samples}, estimated RMSE {estimate}, {:.2} s)",
        out.path().display(),
        if defaulted {
            " (default name: <scene>.jpg)"
        } else {
            ""
        },
        args.width,
        args.height,
        done.output.renderer,
        r.passes,
        (r.elapsed + parse_time).as_secs_f64()
    ));
    if args.verbose {
        say.line(format!("timings (all passes):\n{}", done.output.timings));
    }
    if args.stats || args.verbose {
        say.line(super::summary::stats(&done.output, &done.output.timings));
    }
    let reached = match (args.target_error, r.estimated_rmse) {
        (Some(t), Some(e)) => e <= t,
        (Some(_), None) => false,
        (None, _) => true,
    };
    match done.stopped {
        Stopped::Target => say.line("stopped: the estimate reached the target"),
        Stopped::Noiseless => say.line(
            "stopped: two passes came out identical (nothing in the scene is random), so the image is converged"
        ),
        Stopped::TimeLimit if reached => say.line("stopped: the time limit"),
        Stopped::TimeLimit => say.line(format!(
            "stopped: the time limit, before the target {} was reached",
            args.target_error.unwrap_or_default()
        )),
        Stopped::MaxSamples => {
            if !reached {
                eprintln!(
                    "error: stopped at the cap of {} samples per pixel with the estimate above the target {}; \
                     the image was written, but is not as accurate as asked (raise --spp for larger passes, or a larger target)",
                    glint::scene::Effects::MAX_SPP,
                    args.target_error.unwrap_or_default()
                );
                return Ok(ExitCode::from(1));
            }
            say.line(format!("stopped: the cap of {} samples per pixel", glint::scene::Effects::MAX_SPP));
        }
        // Only a watcher of the passes ends a render so (`glint view`).
        Stopped::Cancelled => say.line("stopped: cancelled"),
    }
    if out_is_8_bit(out) && r.estimated_rmse.is_some_and(|e| e < 0.002) {
        say.line(
            "note: 8-bit output adds about 0.0011 RMSE of rounding; write .exr to keep the float image"
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn out_is_8_bit(out: &Out) -> bool {
    match out {
        Out::File(p) => ImageFile::of(p).is_ok_and(|f| !f.is_float()),
        Out::Stdout => true,
    }
}
