use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use clap::{Args, Subcommand};
use glint::gpu::DeviceSelector;
use glint::suites::bench::{default_scenes, run as run_bench, BenchOptions};

#[derive(Args, Debug)]
#[command(args_conflicts_with_subcommands = true)]
pub struct BenchArgs {
    #[command(subcommand)]
    command: Option<BenchCommand>,
    #[command(flatten)]
    scenes: SceneArgs,
}

impl BenchArgs {
    pub fn no_device_hint(&self) -> &'static str {
        match self.command {
            Some(BenchCommand::Specialize(_)) => {
                "`glint bench specialize` measures GPU shaders only; it needs a Vulkan device"
            }
            Some(BenchCommand::Embree(_)) => "or compare the CPU reference alone: `--no-gpu`",
            _ => "or time the CPU reference alone: `--no-gpu`",
        }
    }
}

#[derive(Subcommand, Debug)]
enum BenchCommand {
    /// The hard-case suite (scenes/hard): failure counts per case, backend and
    /// methods, and what the robust methods cost in time.
    Hard(HardArgs),
    /// Each scene's specialised shader against the generic one (every effect
    /// compiled in, switched off by the settings): SPIR-V size, pipeline
    /// build time and render time, as a markdown table.
    Specialize(SpecializeArgs),
    /// glint against an Embree renderer of the same spec, alternating: per
    /// scene and round, glint's CPU reference, glint's GPU, then the
    /// harness's single rays and 8-wide packets, on the same threads; the
    /// medians and the speed ratios (Embree time / glint time) as a
    /// markdown table.
    Embree(EmbreeArgs),
    /// Each sampler's mean squared error against an f64 reference of the
    /// same integral, and its render time, at the scenes' own sample
    /// counts; the ratios against `stratified`, as a markdown table.
    Samplers(SamplersArgs),
    /// What each scene costs before its first ray: the BVH build and the
    /// CPU's and GPU's packing on 1 thread and on every thread (and
    /// Embree's upload + commit beside them, with `--embree`), as a
    /// markdown table.
    Build(BuildArgs),
    /// How fast each scene or model arrives: reading, parsing, normals,
    /// the view, the BVH and the CPU's packing, and the load's MB/s, as a
    /// markdown table.
    Load(LoadArgs),
}

#[derive(Args, Debug)]
pub struct LoadArgs {
    /// Scene or model files (e.g. ../shared/tools/gen_mesh.py's).
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Rounds per input; each cell is their median.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    rounds: u32,
}

#[derive(Args, Debug)]
pub struct BuildArgs {
    /// Scene files (e.g. ../shared/tools/gen_spheregrid.py --seg 142).
    #[arg(required = true)]
    scenes: Vec<PathBuf>,
    /// Rounds per scene and thread count; each cell is their median.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    rounds: u32,
    /// An Embree harness (../shared/tools/embree_bench.cpp), run between
    /// glint's rounds on the same threads for its `build:` line.
    #[arg(long)]
    embree: Option<PathBuf>,
    /// The harness's `--quality`: medium is Embree's default builder.
    #[arg(long, default_value = "medium", value_parser = ["low", "medium", "high"])]
    quality: String,
}

#[derive(Args, Debug)]
pub struct SamplersArgs {
    /// Scene files; default: scenes/effects/ soft_shadows, antialias,
    /// motion_blur and all_effects.
    scenes: Vec<PathBuf>,
    /// Renders per sampler and scene, each with its own seed.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    seeds: u32,
    /// CPU f64 renders averaged into each scene's reference.
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    reference_passes: u32,
    #[arg(long, default_value_t = 160, value_parser = clap::value_parser!(u32).range(1..=16384))]
    width: u32,
    #[arg(long, default_value_t = 120, value_parser = clap::value_parser!(u32).range(1..=16384))]
    height: u32,
    /// Where the measured renders run.
    #[arg(long, value_enum, default_value = "cpu")]
    backend: MeasuredOn,
    /// Vulkan device by index or name (see `glint devices`).
    #[arg(long)]
    device: Option<String>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum MeasuredOn {
    Cpu,
    Gpu,
}

#[derive(Args, Debug)]
pub struct EmbreeArgs {
    /// The harness program, run as `HARNESS SCENE --width W --height H
    /// --threads T --runs R --mode single|packet8`, ending its output with a
    /// `RESULT ... render_med_s=SECONDS rays=N` line
    /// (../shared/tools/embree_bench.cpp is one).
    harness: PathBuf,
    /// Scene files; default: the classic scenes (when present) and every
    /// scene in scenes/.
    scenes: Vec<PathBuf>,
    /// Rounds of all four programs per scene.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    rounds: u32,
    /// Renders per program and round; each cell is their median.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    repeat: u32,
    #[command(flatten)]
    timed: Timed,
}

/// The image size and backends a timing benchmark renders with.
#[derive(Args, Debug)]
pub struct Timed {
    #[arg(long, default_value_t = glint::camera::DEFAULT_WIDTH)]
    width: u32,
    #[arg(long, default_value_t = glint::camera::DEFAULT_HEIGHT)]
    height: u32,
    /// Skip the GPU.
    #[arg(long)]
    no_gpu: bool,
    /// Skip the CPU reference.
    #[arg(long)]
    no_cpu: bool,
    /// Vulkan device by index or name (see `glint devices`).
    #[arg(long)]
    device: Option<String>,
    /// GPU: read every list from its storage buffer even on a CPU device
    /// (the shader a GPU runs), not through device addresses or from
    /// uniform copies.
    #[arg(long)]
    storage_lists: bool,
}

impl Timed {
    /// An error when nothing is left to time or the image is empty.
    fn check(&self) -> anyhow::Result<()> {
        if self.no_gpu && self.no_cpu {
            return Err(glint::Error::InvalidOption(
                "--no-gpu and --no-cpu together leave nothing to time; drop one".into(),
            )
            .into());
        }
        anyhow::ensure!(self.width > 0 && self.height > 0, "the image needs pixels");
        Ok(())
    }

    fn device(&self) -> Option<DeviceSelector> {
        self.device.as_deref().map(DeviceSelector::parse)
    }
}

/// `scenes`, or the default set when none are named; an error when that is
/// empty too.
fn scenes_or_default(scenes: Vec<PathBuf>) -> anyhow::Result<Vec<PathBuf>> {
    let scenes = if scenes.is_empty() {
        default_scenes(&mut |note| eprintln!("note: {note}"))
    } else {
        scenes
    };
    anyhow::ensure!(
        !scenes.is_empty(),
        "no scenes to benchmark: name some scene files"
    );
    Ok(scenes)
}

#[derive(Args, Debug)]
pub struct SpecializeArgs {
    /// Scene files; default: the classic scenes (when present),
    /// scenes/*.scene and scenes/effects/*.scene.
    scenes: Vec<PathBuf>,
    /// Renders per variant; the report gives the median.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    repeat: u32,
    #[arg(long, default_value_t = 320)]
    width: u32,
    #[arg(long, default_value_t = 240)]
    height: u32,
    /// Vulkan device by index or name (see `glint devices`).
    #[arg(long)]
    device: Option<String>,
}

#[derive(Args, Debug)]
pub struct HardArgs {
    /// Renders per timing; the report gives the median.
    #[arg(long, default_value_t = 7, value_parser = clap::value_parser!(u32).range(1..=1000))]
    repeat: u32,
    /// Skip the GPU.
    #[arg(long)]
    no_gpu: bool,
    /// Vulkan device by index or name (see `glint devices`).
    #[arg(long)]
    device: Option<String>,
    /// Counts only, no timings.
    #[arg(long)]
    no_timing: bool,
    /// List the first N pixels behind every robust count that is not zero,
    /// as `glint render ... --pixel X,Y` commands.
    #[arg(long, value_name = "N", default_value_t = 0)]
    pixels: usize,
    /// Write the suite's scene files into DIR (default scenes/hard) and exit.
    #[arg(long, value_name = "DIR", num_args = 0..=1, default_missing_value = glint::suites::hard::SCENE_DIR)]
    write_scenes: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct SceneArgs {
    /// Scene files; default: the classic scenes in ../shared/scenes/classic
    /// (when present) and every scene in scenes/.
    scenes: Vec<PathBuf>,
    /// Renders per scene and backend; the report gives the median.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    repeat: u32,
    #[command(flatten)]
    timed: Timed,
    /// Also time the CPU reference in f64.
    #[arg(long)]
    f64: bool,
    /// Also draw render time against primitive count, one line per
    /// backend, into this file (.svg, or .png drawn by glint itself).
    #[arg(long, value_name = "FILE")]
    plot: Option<PathBuf>,
    /// Leave out the end-to-end column (`glint render SCENE out.jpg` as a
    /// process on each backend, start to file written, after one untimed
    /// run that warms the pipeline cache).
    #[arg(long)]
    no_end_to_end: bool,
}

pub fn run(args: BenchArgs) -> anyhow::Result<ExitCode> {
    match args.command {
        Some(BenchCommand::Hard(hard)) => run_hard(hard),
        Some(BenchCommand::Specialize(args)) => run_specialize(args),
        Some(BenchCommand::Embree(args)) => run_embree(args),
        Some(BenchCommand::Samplers(args)) => run_samplers(args),
        Some(BenchCommand::Build(args)) => run_build(args),
        Some(BenchCommand::Load(args)) => {
            let options = glint::suites::bench::LoadOptions {
                inputs: args.inputs,
                rounds: args.rounds as usize,
            };
            let report = glint::suites::bench::run_load(&options, &mut |l| eprintln!("{l}"))?;
            println!("{}", report.to_markdown());
            Ok(ExitCode::SUCCESS)
        }
        None => run_scenes(args.scenes),
    }
}

fn run_hard(args: HardArgs) -> anyhow::Result<ExitCode> {
    if let Some(dir) = args.write_scenes {
        let written = glint::suites::hard::write_scenes(&dir)?;
        println!("wrote {written} scenes to {}", dir.display());
        return Ok(ExitCode::SUCCESS);
    }
    let options = glint::suites::bench::HardOptions {
        gpu: !args.no_gpu,
        device: args.device.as_deref().map(DeviceSelector::parse),
        repeat: args.repeat as usize,
        timing: !args.no_timing,
        examples: args.pixels,
    };
    let report = glint::suites::bench::run_hard(&options, &mut |line| eprintln!("{line}"))?;
    println!("{}", report.markdown);
    if report.robust_failures > 0 {
        eprintln!(
            "error: {} checked count(s) are not zero with the robust methods (bold above)",
            report.robust_failures
        );
        return Ok(ExitCode::FAILURE);
    }
    Ok(ExitCode::SUCCESS)
}

fn run_specialize(args: SpecializeArgs) -> anyhow::Result<ExitCode> {
    let scenes = if args.scenes.is_empty() {
        glint::suites::bench::specialize_scenes(&mut |note| eprintln!("note: {note}"))
    } else {
        args.scenes
    };
    anyhow::ensure!(
        !scenes.is_empty(),
        "no scenes to benchmark: name some scene files"
    );
    anyhow::ensure!(args.width > 0 && args.height > 0, "the image needs pixels");
    let options = glint::suites::bench::SpecializeOptions {
        scenes,
        width: args.width,
        height: args.height,
        repeat: args.repeat as usize,
        device: args.device.as_deref().map(DeviceSelector::parse),
    };
    let table = glint::suites::bench::run_specialize(&options, &mut |line| eprintln!("{line}"))?;
    println!("{table}");
    Ok(ExitCode::SUCCESS)
}

fn run_samplers(args: SamplersArgs) -> anyhow::Result<ExitCode> {
    let scenes = if args.scenes.is_empty() {
        glint::suites::bench::sampler_scenes()
    } else {
        args.scenes
    };
    let options = glint::suites::bench::SamplersOptions {
        scenes,
        width: args.width,
        height: args.height,
        seeds: args.seeds,
        reference_passes: args.reference_passes,
        backend: match args.backend {
            MeasuredOn::Cpu => glint::render::Backend::Cpu,
            MeasuredOn::Gpu => glint::render::Backend::Gpu,
        },
        device: args.device.as_deref().map(DeviceSelector::parse),
    };
    let report = glint::suites::bench::run_samplers(&options, &mut |line| eprintln!("{line}"))?;
    println!("{}", report.to_markdown());
    Ok(ExitCode::SUCCESS)
}

fn run_build(args: BuildArgs) -> anyhow::Result<ExitCode> {
    if let Some(harness) = args.embree.as_ref().filter(|h| !h.is_file()) {
        return Err(glint::Error::InvalidOption(format!(
            "{}: no such harness program; build one with `make -C ../shared/tools`",
            harness.display()
        ))
        .into());
    }
    let all = rayon::current_num_threads();
    let options = glint::suites::bench::BuildOptions {
        scenes: args.scenes,
        threads: if all > 1 { vec![1, all] } else { vec![1] },
        rounds: args.rounds as usize,
        embree: args.embree.map(|h| (h, args.quality)),
    };
    let report = glint::suites::bench::run_build(&options, &mut |line| eprintln!("{line}"))?;
    println!("{}", report.to_markdown());
    Ok(ExitCode::SUCCESS)
}

fn run_embree(args: EmbreeArgs) -> anyhow::Result<ExitCode> {
    // Checked before any work: a wrong path fails in a second, not after
    // the first scene's renders.
    if !args.harness.is_file() {
        return Err(glint::Error::InvalidOption(format!(
            "{}: no such harness program; build one with `make -C ../shared/tools`",
            args.harness.display()
        ))
        .into());
    }
    args.timed.check()?;
    let scenes = scenes_or_default(args.scenes)?;
    let options = glint::suites::bench::EmbreeOptions {
        harness: args.harness,
        scenes,
        width: args.timed.width,
        height: args.timed.height,
        repeat: args.repeat as usize,
        rounds: args.rounds as usize,
        gpu: !args.timed.no_gpu,
        cpu: !args.timed.no_cpu,
        device: args.timed.device(),
        uniform_lists: !args.timed.storage_lists,
    };
    let report = glint::suites::bench::run_embree(&options, &mut |line| eprintln!("{line}"))?;
    println!("{}", report.to_markdown());
    Ok(ExitCode::SUCCESS)
}

fn run_scenes(args: SceneArgs) -> anyhow::Result<ExitCode> {
    args.timed.check()?;
    let scenes = scenes_or_default(args.scenes)?;
    let options = BenchOptions {
        scenes,
        width: args.timed.width,
        height: args.timed.height,
        repeat: args.repeat as usize,
        gpu: !args.timed.no_gpu,
        cpu_f32: !args.timed.no_cpu,
        cpu_f64: !args.timed.no_cpu && args.f64,
        device: args.timed.device(),
        uniform_lists: !args.timed.storage_lists,
        end_to_end: match args.no_end_to_end {
            true => None,
            false => Some(
                std::env::current_exe()
                    .context("cannot find glint's own binary for the end-to-end column")?,
            ),
        },
    };
    if let Some(plot) = &args.plot {
        // Before the work, not after it: a bad path fails in a second.
        let ext = plot
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        if !matches!(ext.as_deref(), Some("svg" | "png")) {
            return Err(glint::Error::InvalidOption(format!(
                "--plot {}: name an .svg or .png file",
                plot.display()
            ))
            .into());
        }
        glint::images::framebuffer::check_writable(plot)?;
    }
    let report = run_bench(&options, &mut |line| eprintln!("{line}"))?;
    println!("{}", report.to_markdown());
    if let Some(path) = &args.plot {
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
        {
            std::fs::write(path, report.plot().to_svg())
                .with_context(|| format!("cannot write {}", path.display()))?;
        } else {
            glint::images::framebuffer::write_image(&report.plot().to_image(2.0), path, 95)?;
        }
        eprintln!("wrote {}", path.display());
    }
    Ok(ExitCode::SUCCESS)
}
