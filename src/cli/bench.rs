use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;
use glint::bench::{default_scenes, run as run_bench, BenchOptions};
use glint::gpu::DeviceSelector;

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Scene files; default: the classic scenes in ../shared/scenes/classic
    /// (when present) and every scene in scenes/.
    scenes: Vec<PathBuf>,
    /// Renders per scene and backend; the report gives the median.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    repeat: u32,
    #[arg(long, default_value_t = glint::camera::DEFAULT_WIDTH)]
    width: u32,
    #[arg(long, default_value_t = glint::camera::DEFAULT_HEIGHT)]
    height: u32,
    /// Skip the GPU.
    #[arg(long)]
    no_gpu: bool,
    /// Skip the CPU reference (both precisions).
    #[arg(long)]
    no_cpu: bool,
    /// Also time the CPU reference in f64.
    #[arg(long)]
    f64: bool,
    /// Vulkan device by index or name (see `glint devices`).
    #[arg(long)]
    device: Option<String>,
}

pub fn run(args: BenchArgs) -> anyhow::Result<ExitCode> {
    let scenes = if args.scenes.is_empty() {
        default_scenes(&mut |note| eprintln!("note: {note}"))
    } else {
        args.scenes
    };
    anyhow::ensure!(
        !scenes.is_empty(),
        "no scenes to benchmark: name some scene files"
    );
    let options = BenchOptions {
        scenes,
        width: args.width,
        height: args.height,
        repeat: args.repeat as usize,
        gpu: !args.no_gpu,
        cpu_f32: !args.no_cpu,
        cpu_f64: !args.no_cpu && args.f64,
        device: args.device.as_deref().map(DeviceSelector::parse),
    };
    let report = run_bench(&options, &mut |line| eprintln!("{line}"))?;
    println!("{}", report.to_markdown());
    Ok(ExitCode::SUCCESS)
}
