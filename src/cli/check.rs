//! `glint check`: the built-in suite on the chosen devices, a table per
//! device, JUnit XML on request; exit 0 when every scene passes, 1 when
//! any fails, 3 without a device.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use glint::gpu::{DeviceSelector, GpuError};
use glint::suites::check::{check_device, report, CheckOptions, Level};

#[derive(clap::Args, Debug)]
pub struct CheckArgs {
    /// The Vulkan device to check, by index or name (see `glint devices`);
    /// default: the best one.
    #[arg(long, conflicts_with = "all_devices")]
    device: Option<String>,
    /// Check every Vulkan device, software ones included.
    #[arg(long)]
    all_devices: bool,
    /// The quick suite (about a minute on lavapipe with 2 cores; the
    /// default).
    #[arg(long, conflicts_with = "full")]
    quick: bool,
    /// The full suite: larger images, a BVH of a million triangles, heavier
    /// workloads.
    #[arg(long)]
    full: bool,
    /// Also write the verdicts as JUnit XML here.
    #[arg(long, value_name = "FILE")]
    junit: Option<PathBuf>,
    /// Write each failed scene's images here: the device's, the CPU twin's
    /// and their difference as a heat map.
    #[arg(long, value_name = "DIR", default_value = "glint-check")]
    out: PathBuf,
    /// Only the scenes whose name contains this.
    #[arg(long, value_name = "TEXT")]
    only: Option<String>,
    /// Test only: perturb this scene's device image, to see the check fail.
    #[arg(long, value_name = "SCENE", hide = true)]
    plant_error: Option<String>,
}

pub fn run(args: CheckArgs) -> anyhow::Result<ExitCode> {
    let devices = glint::gpu::list_devices().map_err(glint::Error::from)?;
    let chosen: Vec<_> = if args.all_devices {
        devices
    } else {
        let selector = args.device.as_deref().map(DeviceSelector::parse);
        let ctx = glint::gpu::Context::new(&glint::gpu::ContextOptions {
            device: selector,
            validation: false,
            pipeline_cache: None,
            window: None,
        })
        .map_err(glint::Error::from)?;
        let index = ctx.info().index;
        drop(ctx);
        devices.into_iter().filter(|d| d.index == index).collect()
    };
    if chosen.is_empty() {
        return Err(glint::Error::from(GpuError::NoDevice).into());
    }
    let options = CheckOptions {
        level: if args.full { Level::Full } else { Level::Quick },
        out: Some(args.out.clone()),
        plant_error: args.plant_error.clone(),
        pipeline_cache: glint::gpu::cache::default_dir(),
        only: args.only.clone(),
    };
    let mut reports = Vec::new();
    for device in &chosen {
        let r = glint::suites::check::DeviceReport {
            device: device.clone(),
            limits: glint::suites::check::device_limits(device)?,
            cases: Vec::new(),
            total: Default::default(),
            pipelines: (0, 0),
        };
        print!("{}", report::header(&r));
        println!("{}", report::columns());
        let done = check_device(device, &options, &mut |c| println!("{}", report::row(c)))?;
        print!("{}", report::verdict(&done));
        println!();
        reports.push(done);
    }
    if let Some(path) = &args.junit {
        std::fs::write(path, report::junit(&reports))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let failed = reports.iter().any(|r| !r.passed());
    if failed {
        eprintln!(
            "the difference images of the failed scenes are in {}",
            args.out.display()
        );
    }
    Ok(if failed {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}
