//! Argument definitions (clap) and dispatch to one module per subcommand.

mod accuracy;
mod bench;
mod check;
mod compare;
mod convert;
mod devices;
mod flags;
mod info;
mod part;
mod render;
mod stitch;
mod summary;
mod values;
mod view;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
pub use flags::{CameraArgs, DeviceArgs, EffectArgs, ImageArgs, MethodsArg};

#[derive(Parser, Debug)]
#[command(
    name = "glint",
    version,
    about = "Ray traces classic CSCI 420 scenes on any Vulkan device, with a CPU reference"
)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Threads for the CPU reference and for lavapipe (sets LP_NUM_THREADS
    /// unless it is set); default: RAYON_NUM_THREADS, else every core.
    #[arg(long, global = true, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=4096))]
    threads: Option<u32>,
    /// The most bytes any one input (a scene, a model, standard input, a
    /// pipe) may have; a stream that goes on past it ends with exit 2.
    /// K, M, G or T for powers of 1024 [default: 16G]
    #[arg(long, global = true, value_name = "BYTES", value_parser = glint::input::parse_size)]
    max_input: Option<u64>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a scene to a JPEG or PNG image.
    Render(render::RenderArgs),
    /// Show a scene refining in a window, pass by pass; keys and the mouse
    /// move the camera (see docs/cli.md).
    View(view::ViewArgs),
    /// Compare two images: max/mean abs diff, pixels over a threshold, PSNR, FLIP.
    Compare(compare::CompareArgs),
    /// Time renders per scene and backend (medians).
    Bench(bench::BenchArgs),
    /// What accuracy costs in time: every knob the scene calls for swept,
    /// each point timed and measured against a reference.
    Accuracy(accuracy::AccuracyArgs),
    /// Join the parts of an image rendered with `render --crop` or `--part` (.png or
    /// .exr, alpha marking each part's pixels) into OUT, bit for bit the
    /// image one render would have made.
    Stitch(stitch::StitchArgs),
    /// Write a model (.obj, .ply, .off, .stl, .gltf, .glb) or a scene with `mesh` blocks as a
    /// classic scene, or a scene's triangles as OBJ (with an MTL file).
    Convert(convert::ConvertArgs),
    /// Is this Vulkan device rendering right? The built-in suite on the
    /// device and the CPU reference, a verdict per scene.
    Check(check::CheckArgs),
    /// List the Vulkan devices found, and the driver profile each gets.
    Devices,
    /// Show what a scene holds, what it calls for and the shader it gets.
    Info {
        /// Scene file in the classic format; `-` reads standard input.
        scene: PathBuf,
        #[command(flatten)]
        effects: EffectArgs,
        /// Image size the memory estimate is for.
        #[arg(long, default_value_t = glint::camera::DEFAULT_WIDTH)]
        width: u32,
        #[arg(long, default_value_t = glint::camera::DEFAULT_HEIGHT)]
        height: u32,
    },
}

impl Cli {
    /// What this command can do without a Vulkan device (printed after an
    /// error with exit 3); each names a flag the command accepts.
    pub fn no_device_hint(&self) -> Option<&'static str> {
        match &self.command {
            Command::Render(_) | Command::View(_) => {
                Some("or render on the CPU reference: `--backend cpu`")
            }
            Command::Accuracy(_) => Some("or sweep the CPU reference alone: `--backend cpu`"),
            Command::Bench(b) => Some(b.no_device_hint()),
            Command::Devices
            | Command::Check(_)
            | Command::Compare(_)
            | Command::Stitch(_)
            | Command::Convert(_)
            | Command::Info { .. } => None,
        }
    }
}

pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    set_threads(cli.threads)?;
    if let Some(bytes) = cli.max_input {
        glint::input::set_max_input(bytes);
    }
    match cli.command {
        Command::Render(args) => render::run(args),
        Command::View(args) => view::run(args),
        Command::Compare(args) => compare::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Accuracy(args) => accuracy::run(args),
        Command::Stitch(args) => stitch::run(args),
        Command::Convert(args) => convert::run(args),
        Command::Check(args) => check::run(args),
        Command::Devices => devices::run(),
        Command::Info {
            scene,
            effects,
            width,
            height,
        } => info::run(&scene, &effects, [width, height]),
    }
}

/// `--threads N`, else `RAYON_NUM_THREADS`: the CPU reference's thread
/// pool, and lavapipe's (`LP_NUM_THREADS`, read when its device is
/// created) unless that is set already.
fn set_threads(threads: Option<u32>) -> anyhow::Result<()> {
    let from_env = || {
        std::env::var("RAYON_NUM_THREADS")
            .ok()?
            .trim()
            .parse::<u32>()
            .ok()
            .filter(|&n| n > 0)
    };
    let Some(n) = threads.or_else(from_env) else {
        return Ok(());
    };
    rayon::ThreadPoolBuilder::new()
        .num_threads(n as usize)
        .build_global()
        .map_err(|e| anyhow::anyhow!("setting up {n} threads: {e}"))?;
    if std::env::var_os("LP_NUM_THREADS").is_none() {
        // Before any Vulkan instance exists; the only other thread (the
        // signal handler's) reads no environment.
        std::env::set_var("LP_NUM_THREADS", n.to_string());
    }
    Ok(())
}

/// Files at least this large show a parsing progress bar (on a terminal):
/// about a quarter of a second of parsing.
const PARSE_BAR_BYTES: u64 = 64 << 20;

/// Reads a scene file, or standard input for `-` (named `<stdin>` in
/// messages). A big file shows how much of it is parsed: a 2.7 GB scene
/// takes ten seconds.
pub fn read_scene(path: &std::path::Path) -> anyhow::Result<glint::scene::Scene> {
    read_scene_timed(path).map(|(scene, _)| scene)
}

/// `read_scene`, through the scene cache the environment names
/// (`SceneCache::from_env`), with `-v`'s phases of it: the load's own, or
/// the cache's and a hit or a miss.
pub fn read_scene_timed(
    path: &std::path::Path,
) -> anyhow::Result<(glint::scene::Scene, glint::timing::Timings)> {
    let cache = glint::scene_cache::SceneCache::from_env().map_err(anyhow::Error::msg)?;
    match cache {
        Some(cache) if path != std::path::Path::new("-") => {
            Ok(cache.read_scene_with(path, load_scene)?)
        }
        _ => {
            let start = std::time::Instant::now();
            let scene = load_scene(path)?;
            let mut timings = glint::timing::Timings::default();
            for (name, d) in scene.shown_load_phases(start.elapsed()) {
                timings.add(name, d);
            }
            Ok((scene, timings))
        }
    }
}

/// Reads a scene without the cache: standard input for `-`, a model file
/// framed, a scene file with a progress bar where it is big.
fn load_scene(path: &std::path::Path) -> Result<glint::scene::Scene, glint::Error> {
    use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
    if path == std::path::Path::new("-") {
        return glint::scene::parse_reader(
            std::io::stdin().lock(),
            std::path::Path::new("<stdin>"),
        );
    }
    if glint::mesh::Format::of(path).is_some() {
        return glint::scene::read_scene(path);
    }
    let file = std::fs::File::open(path).map_err(|error| glint::Error::ReadScene {
        path: path.to_path_buf(),
        error,
    })?;
    let size = file.metadata().map_or(0, |m| m.len());
    // Every file goes through the bar, hidden for small ones, so the path
    // that big files take is the one every test takes.
    let bar = ProgressBar::with_draw_target(Some(size), ProgressDrawTarget::hidden());
    if size >= PARSE_BAR_BYTES {
        bar.set_draw_target(ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} parsing [{bar:30}] {percent:>3}% {bytes}/{total_bytes} (eta {eta})",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
    }
    let scene = glint::scene::parse_reader(bar.wrap_read(file), path);
    bar.finish_and_clear();
    scene
}

/// Prints the scene's warnings (with their source lines) to stderr.
pub fn print_warnings(scene: &glint::scene::Scene) {
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    if scene.more_warnings > 0 {
        eprintln!(
            "warning: {} more warnings like the above (only the first {} of each kind are shown)",
            scene.more_warnings,
            glint::scene::WARNINGS_KEPT
        );
    }
    for m in &scene.meshes {
        for w in &m.report.kept {
            eprintln!("warning: {w}");
        }
        let more = m.report.more();
        if more > 0 {
            eprintln!(
                "warning: {}: {more} more tolerated like the above ({})",
                m.file,
                m.report.summary()
            );
        }
    }
    let small = scene.unresolvable();
    if !small.is_empty() {
        let shown = glint::scene::WARNINGS_KEPT.min(small.len());
        eprintln!(
            "warning: {} primitive(s) are smaller than f32 resolves where they are (under 2^-20 of \
             their distance from the camera); the GPU and CPU f32 renders may miss or mis-shade \
             them, `--backend cpu --precision f64` renders them right:",
            small.len()
        );
        for s in &small[..shown] {
            eprintln!("  {s}");
        }
        if small.len() > shown {
            eprintln!("  and {} more", small.len() - shown);
        }
    }
}
