//! `glint check`: is this Vulkan device rendering right? The built-in suite
//! (`suite`) rendered on each chosen device and on the CPU reference (the
//! f32 twin and the f64 truth), each image held to its case's tolerance,
//! with what glint chose for the device, the time and the rays per second.
//! `report` prints the table and writes JUnit XML.

mod image_test;
mod judge;
pub mod report;
pub mod suite;

use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Duration;

use crate::cpu::Precision;
use crate::gpu::{DeviceInfo, DeviceLimits, DeviceSelector};
use crate::images::compare::compare_framebuffers;
use crate::images::framebuffer::Framebuffer;
use crate::render::{Backend, RenderOptions, Renderer};
use crate::timing::{CLOSEST_RAYS, SHADOW_RAYS};
use crate::Error;
pub use image_test::{image_test, ImageTest, Verdict};
use judge::{judge, write_failure};
pub use suite::{Case, Level, Tolerance};

/// What `glint check` was asked for.
#[derive(Clone, Debug)]
pub struct CheckOptions {
    /// How much of the suite, and how large.
    pub level: Level,
    /// Where the images of failed cases go (device image, CPU twin's image,
    /// and the difference as a heat map).
    pub out: Option<PathBuf>,
    /// Test only: perturbs this case's device image, so a test can see
    /// that a wrong result fails the check.
    pub plant_error: Option<String>,
    /// Only the cases whose name contains this.
    pub only: Option<String>,
    /// Where built pipelines are kept between runs (`gpu::cache`).
    pub pipeline_cache: Option<PathBuf>,
}

/// The three renders of a case.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Kind {
    Device,
    Twin,
    Truth,
}

/// One case on one device.
#[derive(Clone, Debug)]
pub struct CaseResult {
    /// The case's name.
    pub name: String,
    /// What it exercises, in a few words.
    pub exercises: String,
    /// The shader variant: its feature set and how its lists were bound.
    pub variant: String,
    /// Pixels more than one level off the f32 twin, and how many may be.
    pub off: usize,
    /// How many pixels may be more than one level off the twin.
    pub allowed: usize,
    /// The largest difference from the twin, in 8-bit levels.
    pub worst: f64,
    /// FLIP mean against the f32 twin.
    pub flip_f32: f32,
    /// FLIP mean against the f64 truth.
    pub flip_f64: f32,
    /// The device's render: dispatch time, and rays per second over it.
    pub time: Duration,
    /// Rays a second on the device, where its time and rays were counted.
    pub rays_per_second: Option<f64>,
    /// Why it failed; `None`: it passed.
    pub failure: Option<String>,
}

impl CaseResult {
    /// Whether the case met its tolerance.
    pub fn passed(&self) -> bool {
        self.failure.is_none()
    }
}

/// Everything checked on one device.
#[derive(Clone, Debug)]
pub struct DeviceReport {
    /// The device checked.
    pub device: DeviceInfo,
    /// Its limits, as glint reads them.
    pub limits: Option<DeviceLimits>,
    /// Every case's result, in the suite's order.
    pub cases: Vec<CaseResult>,
    /// Time for the whole suite on this device, references included.
    pub total: Duration,
    /// Pipelines the driver compiled, and found in the disk cache.
    pub pipelines: (u64, u64),
}

impl DeviceReport {
    /// Whether every case passed.
    pub fn passed(&self) -> bool {
        self.cases.iter().all(CaseResult::passed)
    }
}

/// The limits of `device`, as a render sees them.
pub fn device_limits(device: &DeviceInfo) -> Result<Option<DeviceLimits>, Error> {
    let renderer = Renderer::new(&RenderOptions {
        width: 8,
        height: 8,
        backend: Backend::Gpu,
        device: Some(DeviceSelector::Index(device.index)),
        ..RenderOptions::default()
    })?;
    Ok(renderer.device_limits())
}

/// Renders the suite on `device` and the CPU reference; `note` hears of
/// each case as it finishes.
pub fn check_device(
    device: &DeviceInfo,
    options: &CheckOptions,
    note: &mut dyn FnMut(&CaseResult),
) -> Result<DeviceReport, Error> {
    let start = std::time::Instant::now();
    let make = |kind: Kind, w: u32, h: u32, storage_limit: Option<u64>| {
        let (backend, precision, selector) = match kind {
            Kind::Device => (
                Backend::Gpu,
                Precision::F32,
                Some(DeviceSelector::Index(device.index)),
            ),
            Kind::Twin => (Backend::Cpu, Precision::F32, None),
            Kind::Truth => (Backend::Cpu, Precision::F64, None),
        };
        let mut render = RenderOptions {
            width: w,
            height: h,
            backend,
            precision,
            device: selector,
            // The twin traces every ray alone: packets keep another of two
            // surfaces met at exactly one t (as at a mesh's vertices).
            packets: false,
            pipeline_cache: options.pipeline_cache.clone(),
            ..RenderOptions::default()
        };
        render.gpu.storage_limit = storage_limit;
        Renderer::new(&render)
    };
    let limits = make(Kind::Device, 8, 8, None)?.device_limits();
    let all = suite::cases(options.level, limits.map(|l| l.max_storage_range));
    let chosen: Vec<Case> = all
        .into_iter()
        .filter(|c| {
            options
                .only
                .as_ref()
                .is_none_or(|o| c.name.contains(o.as_str()))
        })
        .collect();
    // One renderer per backend, image size and binding cap: a device's
    // context and pipelines serve every case of that size.
    let mut renderers: HashMap<(Kind, u32, u32, Option<u64>), Renderer> = HashMap::new();
    for c in &chosen {
        for kind in [Kind::Device, Kind::Twin, Kind::Truth] {
            let cap = if kind == Kind::Device {
                c.storage_limit
            } else {
                None
            };
            let key = (kind, c.width, c.height, cap);
            if let std::collections::hash_map::Entry::Vacant(e) = renderers.entry(key) {
                e.insert(make(kind, c.width, c.height, cap)?);
            }
        }
    }
    let mut cases = Vec::new();
    for case in &chosen {
        let get = |kind: Kind| {
            let cap = if kind == Kind::Device {
                case.storage_limit
            } else {
                None
            };
            &renderers[&(kind, case.width, case.height, cap)]
        };
        let result = check_case(
            case,
            get(Kind::Device),
            get(Kind::Twin),
            get(Kind::Truth),
            options,
        )?;
        note(&result);
        cases.push(result);
    }
    let mut pipelines = (0, 0);
    for ((kind, ..), r) in &renderers {
        if let (Kind::Device, Some(gpu)) = (kind, r.gpu()) {
            let (c, d) = gpu.pipeline_builds();
            pipelines = (pipelines.0 + c, pipelines.1 + d);
        }
    }
    Ok(DeviceReport {
        device: device.clone(),
        limits,
        cases,
        total: start.elapsed(),
        pipelines,
    })
}

fn check_case(
    case: &Case,
    gpu: &Renderer,
    cpu32: &Renderer,
    cpu64: &Renderer,
    options: &CheckOptions,
) -> Result<CaseResult, Error> {
    let quiet = |_: u64, _: u64| {};
    let on_device = gpu.render(&case.scene, &quiet)?;
    let mut image = on_device.framebuffer().into_owned();
    if options.plant_error.as_deref() == Some(case.name.as_str()) {
        plant(&mut image);
    }
    let twin_output = cpu32.render(&case.scene, &quiet)?;
    // The twin calls for exactly the shader's rays (the same algorithm,
    // ray for ray; its packets leave some shadow rays untraced, counted
    // apart); the device counts its own only where a pass's 32-bit
    // counters cannot wrap, which large tiles can.
    let twin_rays = twin_output.timings.rays_called_for().unwrap_or(0);
    let twin = twin_output.framebuffer().into_owned();
    let truth = cpu64.render(&case.scene, &quiet)?.into_framebuffer();
    let against_twin = compare_framebuffers(&twin, &image, 1.0)?;
    let against_truth = compare_framebuffers(&truth, &image, 1.0)?;
    let pixels = (case.width * case.height) as usize;
    let (mut why, allowed) = judge(&case.tolerance, pixels, &against_twin, &against_truth);
    if let Some(hard) = &case.hard {
        let (probe, _) = crate::suites::hard::probe(
            hard,
            crate::suites::hard::Runner::Gpu,
            crate::methods::Methods::Robust,
            gpu.gpu(),
        )?;
        let counts = crate::suites::hard::metrics::count(&probe, &hard.reference());
        for &m in &hard.checks {
            let n = counts.get(m);
            if n > 0 {
                why.push(format!("{n} {m} pixels (the hard-case suite allows none)"));
            }
        }
    }
    let failure = (!why.is_empty()).then(|| why.join("; "));
    if let (Some(dir), Some(_)) = (&options.out, &failure) {
        write_failure(dir, &case.name, &image, &twin, &against_twin)?;
    }
    let timings = &on_device.timings;
    // The pass loop builds a pipeline when a tile first needs it; its build
    // time is the pipeline's, not the render's.
    let time = timings
        .phase("dispatch")
        .unwrap_or_default()
        .saturating_sub(timings.phase("pipeline").unwrap_or_default());
    let rays = match timings.counted(CLOSEST_RAYS) + timings.counted(SHADOW_RAYS) {
        0 => twin_rays,
        n => n,
    };
    let lists = ["split lists", "uniform lists", "address lists"]
        .into_iter()
        .find(|l| timings.has_count(l))
        .unwrap_or("storage lists");
    Ok(CaseResult {
        name: case.name.clone(),
        exercises: case.exercises.clone(),
        variant: format!("{}, {lists}", gpu.options().features(&case.scene).label()),
        off: against_twin.over_threshold,
        allowed,
        worst: against_twin.max_abs,
        flip_f32: against_twin.flip_mean,
        flip_f64: against_truth.flip_mean,
        time,
        rays_per_second: (rays > 0 && !time.is_zero()).then(|| rays as f64 / time.as_secs_f64()),
        failure,
    })
}

/// The planted error: a block of wrong pixels in the middle of the image.
fn plant(image: &mut Framebuffer) {
    let (w, h) = (image.width as usize, image.height as usize);
    for y in h / 2..(h / 2 + 4).min(h) {
        for x in w / 2..(w / 2 + 4).min(w) {
            image.pixels[y * w + x] = [1.0, 0.0, 1.0];
        }
    }
}
