//! Argument definitions (clap) and dispatch to one module per subcommand.

mod bench;
mod compare;
mod devices;
mod info;
mod render;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};

#[derive(Parser, Debug)]
#[command(
    name = "glint",
    version,
    about = "Ray traces classic CSCI 420 scenes on any Vulkan device, with a CPU reference"
)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a scene to a JPEG or PNG image.
    Render(render::RenderArgs),
    /// Compare two images: max/mean abs diff, pixels over a threshold, PSNR, FLIP.
    Compare(compare::CompareArgs),
    /// Time renders per scene and backend (medians).
    Bench(bench::BenchArgs),
    /// List the Vulkan devices found.
    Devices,
    /// Show what a scene holds and what it calls for.
    Info {
        /// Scene file in the classic format.
        scene: PathBuf,
    },
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum BackendArg {
    Auto,
    Gpu,
    Cpu,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum MethodsArg {
    Robust,
    Naive,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum PrecisionArg {
    F32,
    F64,
}

pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Render(args) => render::run(args),
        Command::Compare(args) => compare::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Devices => devices::run(),
        Command::Info { scene } => info::run(&scene),
    }
}

/// Prints the scene's warnings (with their source lines) to stderr.
pub fn print_warnings(scene: &glint::scene::Scene) {
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
}
