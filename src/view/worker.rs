//! The viewer's render thread: refines the current view pass by pass
//! (`Renderer::render_progressive_watched`), hands each pass's image to
//! the window, and starts over when the view changes. The window thread
//! never waits for a pass.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::compare::compare_framebuffers;
use crate::cpu::Precision;
use crate::framebuffer::Framebuffer;
use crate::progressive::{PassReport, StopAt, Stopped};
use crate::render::{Backend, RenderOptions, Renderer};
use crate::scene::{CameraSpec, Scene};
use crate::timing::{CLOSEST_RAYS, SHADOW_RAYS};
use crate::Error;

/// Which image the window shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Show {
    /// The chosen backend's image, refining.
    Main,
    /// The CPU reference's image of the same view (`Tab`).
    Reference,
    /// The difference of the two as a heat map (`D`).
    Difference,
}

/// What to render: sent to the thread, which drops a job the moment a
/// newer one arrives.
#[derive(Clone, Debug)]
pub struct Job {
    pub camera: CameraSpec,
    pub width: u32,
    pub height: u32,
    pub show: Show,
    pub serial: u64,
}

/// What the thread sends back.
pub enum Update {
    /// A pass's image and where the refinement stands.
    Frame {
        serial: u64,
        image: Arc<Framebuffer>,
        report: PassReport,
        /// Rays per second over the render so far, where counted.
        rays_per_second: Option<f64>,
        label: String,
    },
    /// The refinement of job `serial` ended, and why.
    Stopped {
        serial: u64,
        why: Stopped,
    },
    Failed(String),
}

/// Shared with the window: a job waiting, whether to pause, whether the
/// current job is superseded.
#[derive(Default)]
pub struct Control {
    pub next: Mutex<Option<Job>>,
    pub paused: AtomicBool,
    pub cancel: AtomicBool,
    pub quit: AtomicBool,
}

impl Control {
    pub fn submit(&self, job: Job) {
        *self.next.lock().unwrap_or_else(|e| e.into_inner()) = Some(job);
        self.cancel.store(true, Ordering::SeqCst);
    }
}

/// The render thread's body: runs until `control.quit`.
pub fn run(
    scene: Scene,
    options: RenderOptions,
    stop: StopAt,
    control: Arc<Control>,
    tx: Sender<Update>,
    wake: Box<dyn Fn() + Send>,
) {
    let mut renderers: HashMap<(Backend, u32, u32), Renderer> = HashMap::new();
    let send = |u: Update| {
        let _ = tx.send(u);
        wake();
    };
    loop {
        if control.quit.load(Ordering::SeqCst) {
            return;
        }
        let job = control
            .next
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take();
        let Some(job) = job else {
            std::thread::sleep(Duration::from_millis(10));
            continue;
        };
        control.cancel.store(false, Ordering::SeqCst);
        let mut view = scene.clone();
        view.camera = Some(job.camera);
        let main = options.backend;
        let needed: &[Backend] = match job.show {
            Show::Main => &[main],
            Show::Reference => &[Backend::Cpu],
            Show::Difference => &[main, Backend::Cpu],
        };
        let mut made = Ok(());
        for &backend in needed {
            let key = (backend, job.width, job.height);
            if renderers.contains_key(&key) {
                continue;
            }
            let cpu = backend == Backend::Cpu;
            match Renderer::new(&RenderOptions {
                width: job.width,
                height: job.height,
                backend,
                precision: if cpu {
                    Precision::F32
                } else {
                    options.precision
                },
                device: if cpu { None } else { options.device.clone() },
                ..options.clone()
            }) {
                Ok(r) => {
                    renderers.insert(key, r);
                }
                Err(e) => made = Err(e),
            }
        }
        let get = |b: Backend| &renderers[&(b, job.width, job.height)];
        let result = made.and_then(|()| match job.show {
            Show::Main => refine(get(main), &view, &stop, &job, &control, &send),
            Show::Reference => refine(get(Backend::Cpu), &view, &stop, &job, &control, &send),
            Show::Difference => difference(get(main), get(Backend::Cpu), &view, &job, &send),
        });
        if let Err(e) = result {
            send(Update::Failed(e.to_string()));
        }
    }
}

fn refine(
    renderer: &Renderer,
    scene: &Scene,
    stop: &StopAt,
    job: &Job,
    control: &Control,
    send: &dyn Fn(Update),
) -> Result<(), Error> {
    let label = renderer.name();
    let done = renderer.render_progressive_watched(scene, stop, &mut |report, acc| {
        while control.paused.load(Ordering::SeqCst) && !control.cancel.load(Ordering::SeqCst) {
            std::thread::sleep(Duration::from_millis(20));
        }
        if control.cancel.load(Ordering::SeqCst) {
            return false;
        }
        send(Update::Frame {
            serial: job.serial,
            image: Arc::new(acc.mean()),
            report: *report,
            rays_per_second: None,
            label: label.clone(),
        });
        true
    })?;
    let t = &done.output.timings;
    let counted = t.counted(CLOSEST_RAYS) + t.counted(SHADOW_RAYS);
    let seconds = done.report.elapsed.as_secs_f64();
    if done.stopped != Stopped::Cancelled {
        send(Update::Frame {
            serial: job.serial,
            image: Arc::new(done.output.framebuffer),
            report: done.report,
            rays_per_second: (counted > 0 && seconds > 0.0).then(|| counted as f64 / seconds),
            label,
        });
    }
    send(Update::Stopped {
        serial: job.serial,
        why: done.stopped,
    });
    Ok(())
}

/// One render of the view on each backend, shown as `compare --diff`'s
/// heat map over the reference.
fn difference(
    a: &Renderer,
    b: &Renderer,
    scene: &Scene,
    job: &Job,
    send: &dyn Fn(Update),
) -> Result<(), Error> {
    let quiet = |_: u64, _: u64| {};
    let start = std::time::Instant::now();
    let main = a.render(scene, &quiet)?.framebuffer;
    let reference = b.render(scene, &quiet)?.framebuffer;
    let cmp = compare_framebuffers(&reference, &main, 1.0)?;
    let heat = cmp.diff_image(&reference.to_rgb8());
    let image = Framebuffer {
        width: heat.width(),
        height: heat.height(),
        pixels: heat
            .pixels()
            .map(|p| p.0.map(|c| f32::from(c) / 255.0))
            .collect(),
    };
    send(Update::Frame {
        serial: job.serial,
        image: Arc::new(image),
        report: PassReport {
            passes: 1,
            samples_per_pixel: 0,
            mean_samples: 0.0,
            active_blocks: [0, 0],
            elapsed: start.elapsed(),
            estimated_rmse: None,
        },
        rays_per_second: None,
        label: format!(
            "difference, {} against {}: max {:.0} levels, {} pixels over 1, FLIP {:.4}",
            a.name(),
            b.name(),
            cmp.max_abs,
            cmp.over_threshold,
            cmp.flip_mean
        ),
    });
    send(Update::Stopped {
        serial: job.serial,
        why: Stopped::Noiseless,
    });
    Ok(())
}

/// Waits for the thread's updates without blocking (the window polls).
pub fn drain(rx: &Receiver<Update>) -> Vec<Update> {
    rx.try_iter().collect()
}
