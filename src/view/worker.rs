//! The viewer's render thread: refines the current view pass by pass
//! (`Renderer::render_progressive_watched`), hands each pass's image to
//! the window, and starts over when the view changes. The window thread
//! never waits for a pass.

use std::cell::RefCell;
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::device::{Drawing, Screen};
use super::renderers::{heavier_than_preview, Key, Renderers};
use crate::gpu::WindowTarget;
use crate::images::compare::compare_framebuffers;
use crate::images::framebuffer::Framebuffer;
use crate::render::passes::{PassReport, StopAt, Stopped};
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
    /// Where the camera is.
    pub camera: CameraSpec,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Which image to show.
    pub show: Show,
    /// Counts jobs: updates name the job they belong to.
    pub serial: u64,
}

/// What the thread sends back.
pub enum Update {
    /// A pass's image and where the refinement stands.
    Frame {
        /// The job it belongs to.
        serial: u64,
        /// The image so far.
        image: Arc<Framebuffer>,
        /// Passes, samples and error estimate so far.
        report: PassReport,
        /// Rays per second over the render so far, where counted.
        rays_per_second: Option<f64>,
        /// What the title bar says of it.
        label: String,
        /// A preview (`PREVIEW_ABOVE`): not the view's image, never saved.
        preview: bool,
        /// The device presented it already (`device::Screen`).
        drawn: bool,
    },
    /// Who draws the window: sent once, before the first image.
    Drawing(Drawing),
    /// Something the user should know that is not an image (printed).
    Note(String),
    /// The refinement of job `serial` ended, and why.
    Stopped {
        /// The job that stopped.
        serial: u64,
        /// Why it stopped.
        why: Stopped,
    },
    /// The render failed (the error's message).
    Failed(String),
}

/// Shared with the window: a job waiting, whether to pause, whether the
/// current job is superseded.
#[derive(Default)]
pub struct Control {
    /// The job to start next; the thread takes it.
    pub next: Mutex<Option<Job>>,
    /// Whether refinement waits.
    pub paused: AtomicBool,
    /// Also every renderer's cancel flag (`Renderer::set_cancel`): a new
    /// job ends the pass in flight, not only the passes after it.
    pub cancel: Arc<AtomicBool>,
    /// When `cancel` was first set since the job in flight began: how long
    /// the render took to answer.
    cancelled_at: Mutex<Option<Instant>>,
    /// The window closed: the thread ends.
    pub quit: AtomicBool,
    /// The window, set before the first job: the device presents to it
    /// where it can (`device::Screen`).
    pub window: Mutex<Option<WindowTarget>>,
    /// The window was exposed or resized: present the last image again.
    pub repaint: AtomicBool,
}

impl Control {
    /// Hands `job` to the thread, cancelling the one in flight.
    pub fn submit(&self, job: Job) {
        *self.next.lock().unwrap_or_else(|e| e.into_inner()) = Some(job);
        self.cancelled_at
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get_or_insert_with(Instant::now);
        self.cancel.store(true, Ordering::SeqCst);
    }

    /// The job waiting, if any, now in flight: nothing cancels it yet.
    fn take(&self) -> Option<Job> {
        let job = self.next.lock().unwrap_or_else(|e| e.into_inner()).take()?;
        *self.cancelled_at.lock().unwrap_or_else(|e| e.into_inner()) = None;
        self.cancel.store(false, Ordering::SeqCst);
        // A job submitted meanwhile may have set the flag before it was
        // cleared: it must still end this one.
        if self
            .next
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .is_some()
        {
            self.cancel.store(true, Ordering::SeqCst);
        }
        Some(job)
    }

    /// Since the render in flight was told to end, if it was.
    fn since_cancel(&self) -> Option<Duration> {
        if !self.cancel.load(Ordering::SeqCst) {
            return None;
        }
        let at = *self.cancelled_at.lock().unwrap_or_else(|e| e.into_inner());
        at.map(|t| t.elapsed())
    }
}

/// Where a view's first pass keeps the window waiting longer than this,
/// each new view shows a preview first: `render --quick`'s settings (half
/// the width and height, 1 sample per pixel, 1 shadow sample, no
/// reflection), so a drag is followed at the preview's pace and the
/// refinement follows it. 100 ms: the 10 images a second a smooth view
/// needs.
pub const PREVIEW_ABOVE: Duration = Duration::from_millis(100);

/// The render thread's body: runs until `control.quit`.
pub fn run(
    scene: Scene,
    options: RenderOptions,
    stop: StopAt,
    control: Arc<Control>,
    tx: Sender<Update>,
    wake: Box<dyn Fn() + Send>,
) {
    let heavy = heavier_than_preview(&scene, &options);
    let mut renderers = Renderers::new(options, control.cancel.clone());
    // How long each view's first pass took, per renderer: whether the
    // next view on it needs a preview.
    let mut first_pass: HashMap<Key, Duration> = HashMap::new();
    let screen: RefCell<Option<Screen>> = RefCell::new(None);
    let post = |u: Update| {
        let _ = tx.send(u);
        wake();
    };
    // Images the host made go to the device's screen first, where it
    // draws the window.
    let send = |u: Update| {
        if let Update::Frame {
            image,
            drawn: false,
            ..
        } = &u
        {
            if let Some(Err(note)) = screen.borrow_mut().as_mut().map(|s| s.host(image)) {
                host_draws_now(&post, note);
            }
        }
        post(u);
    };
    loop {
        if control.quit.load(Ordering::SeqCst) {
            return;
        }
        let Some(job) = control.take() else {
            repaint(&screen, &control, &post);
            std::thread::sleep(Duration::from_millis(10));
            continue;
        };
        if screen.borrow().is_none() {
            let window = control
                .window
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .take();
            let (opened, drawing) = Screen::open(window, &mut renderers);
            *screen.borrow_mut() = Some(opened);
            post(Update::Drawing(drawing));
        }
        let mut view = scene.clone();
        view.camera = Some(job.camera);
        let key = |backend: Backend| Key {
            backend,
            width: job.width,
            height: job.height,
            preview: false,
        };
        let main = key(renderers.options().backend);
        let reference = key(Backend::Cpu);
        let result = match job.show {
            Show::Main | Show::Reference => {
                let full = if job.show == Show::Main {
                    main
                } else {
                    reference
                };
                let slow = first_pass.get(&full).map_or(heavy, |t| *t > PREVIEW_ABOVE);
                let preview = Key {
                    width: job.width.div_ceil(2),
                    height: job.height.div_ceil(2),
                    preview: true,
                    ..full
                };
                let shown = if slow {
                    renderers
                        .make(preview)
                        .and_then(|()| show_preview(renderers.get(preview), &view, &job, &send))
                        .map(|traced| {
                            let size = (job.width, job.height);
                            if let Some(note) = renderers.previewed(preview, traced, size) {
                                send(Update::Note(note));
                            }
                        })
                } else {
                    Ok(())
                };
                shown.and_then(|()| renderers.make(full)).and_then(|()| {
                    let mut first = None;
                    let r = refine(
                        renderers.get(full),
                        &view,
                        &stop,
                        (&job, &control),
                        (&send, &post, &screen),
                        &mut first,
                    );
                    if let Some(t) = first {
                        first_pass.insert(full, t);
                    }
                    let answered = control.since_cancel();
                    if let Some(note) = answered.and_then(|d| renderers.answered(full, d)) {
                        send(Update::Note(note));
                    }
                    r
                })
            }
            Show::Difference => renderers
                .make(main)
                .and_then(|()| renderers.make(reference))
                .and_then(|()| {
                    difference(
                        renderers.get(main),
                        renderers.get(reference),
                        &view,
                        &job,
                        &send,
                    )
                }),
        };
        match result {
            // A newer job (or closing the window) cut the render short.
            Err(Error::Cancelled) => send(Update::Stopped {
                serial: job.serial,
                why: Stopped::Cancelled,
            }),
            Err(e) => send(Update::Failed(e.to_string())),
            Ok(()) => {}
        }
    }
}

/// The view at the preview's settings and size, scaled up to the job's
/// (nearest pixel) and sent as a preview. Returns how long it traced
/// (without building pipelines).
fn show_preview(
    renderer: &Renderer,
    scene: &Scene,
    job: &Job,
    send: &dyn Fn(Update),
) -> Result<Duration, Error> {
    let start = Instant::now();
    let out = renderer.render(scene, &|_, _| {})?;
    let t = &out.timings;
    let traced = t
        .phase("dispatch")
        .unwrap_or_default()
        .saturating_sub(t.phase("pipeline").unwrap_or_default());
    let small = out.into_framebuffer();
    let (w, h) = (job.width as usize, job.height as usize);
    let (sw, sh) = (small.width as usize, small.height as usize);
    let pixels = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| small.pixels[(y * sh / h).min(sh - 1) * sw + (x * sw / w).min(sw - 1)])
        .collect();
    send(Update::Frame {
        serial: job.serial,
        image: Arc::new(Framebuffer {
            width: job.width,
            height: job.height,
            pixels,
        }),
        report: not_a_pass(0, start),
        rays_per_second: None,
        label: format!(
            "{}, preview: half size, 1 sample per pixel, 1 shadow sample, no reflection",
            renderer.name()
        ),
        preview: true,
        drawn: false,
    });
    Ok(traced)
}

/// Where the window's images go: to the window thread (`send` presents
/// a host image on the device's screen first, `post` does not) and the
/// screen.
type Outlets<'a> = (
    &'a dyn Fn(Update),
    &'a dyn Fn(Update),
    &'a RefCell<Option<Screen>>,
);

/// Presents the last image again where the window asked for it, or where
/// it was not presented yet.
fn repaint(screen: &RefCell<Option<Screen>>, control: &Control, post: &dyn Fn(Update)) {
    let due = control.repaint.swap(false, Ordering::SeqCst);
    if let Some(Err(note)) = screen.borrow_mut().as_mut().map(|s| s.again(due)) {
        host_draws_now(post, note);
    }
}

/// The device stopped presenting (`note` says why): the host draws the
/// window from now on.
fn host_draws_now(post: &dyn Fn(Update), note: String) {
    post(Update::Note(note));
    post(Update::Drawing(Drawing::Host(None)));
}

/// The view's refinement, pass by pass; `first` gets how long its first
/// pass kept the window waiting. On the presenting device, the passes are
/// averaged and presented there (`device::Screen`).
fn refine(
    renderer: &Renderer,
    scene: &Scene,
    stop: &StopAt,
    (job, control): (&Job, &Control),
    (send, post, screen): Outlets,
    first: &mut Option<Duration>,
) -> Result<(), Error> {
    let label = renderer.name();
    let started = screen
        .borrow_mut()
        .as_mut()
        .map_or(Ok(false), |s| s.start(renderer, job.width, job.height));
    let mut on_device = started.unwrap_or_else(|note| {
        host_draws_now(post, note);
        false
    });
    let done = renderer.render_progressive_watched(scene, stop, &mut |report, acc| {
        first.get_or_insert(report.elapsed);
        while control.paused.load(Ordering::SeqCst) && !control.cancel.load(Ordering::SeqCst) {
            repaint(screen, control, post);
            std::thread::sleep(Duration::from_millis(20));
        }
        if control.cancel.load(Ordering::SeqCst) {
            return false;
        }
        if on_device {
            let shown = screen
                .borrow_mut()
                .as_mut()
                .map_or(Ok(()), |s| s.pass(report.passes == 1));
            if let Err(note) = shown {
                host_draws_now(post, note);
                on_device = false;
            }
        }
        send(Update::Frame {
            serial: job.serial,
            image: Arc::new(acc.mean()),
            report: *report,
            rays_per_second: None,
            label: label.clone(),
            preview: false,
            drawn: on_device,
        });
        true
    });
    if let Some(s) = screen.borrow().as_ref() {
        s.stop(renderer);
    }
    let done = done?;
    let t = &done.output.timings;
    let counted = t.counted(CLOSEST_RAYS) + t.counted(SHADOW_RAYS);
    let seconds = done.report.elapsed.as_secs_f64();
    if done.stopped != Stopped::Cancelled {
        // The last pass's image, already shown: now with the render's rate.
        post(Update::Frame {
            serial: job.serial,
            image: Arc::new(done.output.into_framebuffer()),
            report: done.report,
            rays_per_second: (counted > 0 && seconds > 0.0).then(|| counted as f64 / seconds),
            label,
            preview: false,
            drawn: on_device,
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
    let start = Instant::now();
    let main = a.render(scene, &quiet)?.into_framebuffer();
    let reference = b.render(scene, &quiet)?.into_framebuffer();
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
        report: not_a_pass(1, start),
        rays_per_second: None,
        label: format!(
            "difference, {} against {}: max {:.0} levels, {} pixels over 1, FLIP {:.4}",
            a.name(),
            b.name(),
            cmp.max_abs,
            cmp.over_threshold,
            cmp.flip_mean
        ),
        preview: false,
        drawn: false,
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

/// The report of an image that is no pass of a progressive render (a
/// preview, a difference): no samples, no error estimate.
fn not_a_pass(passes: u32, start: Instant) -> PassReport {
    PassReport {
        passes,
        samples_per_pixel: 0,
        mean_samples: 0.0,
        active_blocks: [0, 0],
        elapsed: start.elapsed(),
        estimated_rmse: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::view::orbit::Orbit;

    const BODY: &str = "2
amb: 0.1 0.1 0.1
sphere pos: 0 0 -3 rad: 0.8 dif: 0.8 0.3 0.2 spe: 0.5 0.5 0.5 shi: 30
light pos: 2 3 0 col: 0.8 0.8 0.8
";

    /// The updates of one job on the CPU reference at 40x30, until it stops.
    fn updates_of(scene_text: &str) -> Vec<Update> {
        let scene = crate::scene::parse_scene(scene_text.as_bytes(), "test.scene").expect("scene");
        let control = Arc::new(Control::default());
        let (tx, rx) = std::sync::mpsc::channel();
        let options = RenderOptions {
            width: 40,
            height: 30,
            backend: Backend::Cpu,
            ..RenderOptions::default()
        };
        let stop = StopAt {
            target_rmse: None,
            time_limit: Some(Duration::from_secs(60)),
            adaptive: false,
        };
        let thread = {
            let (scene, control) = (scene.clone(), control.clone());
            std::thread::spawn(move || run(scene, options, stop, control, tx, Box::new(|| {})))
        };
        control.submit(Job {
            camera: Orbit::of(&scene).camera,
            width: 40,
            height: 30,
            show: Show::Main,
            serial: 1,
        });
        let mut got = Vec::new();
        while let Ok(u) = rx.recv_timeout(Duration::from_secs(60)) {
            let stopped = matches!(u, Update::Stopped { .. } | Update::Failed(_));
            got.push(u);
            if stopped {
                break;
            }
        }
        control.quit.store(true, Ordering::SeqCst);
        thread.join().expect("worker ends");
        got
    }

    fn previews(updates: &[Update]) -> Vec<bool> {
        updates
            .iter()
            .filter_map(|u| match u {
                Update::Frame { preview, image, .. } => {
                    assert_eq!(
                        (image.width, image.height),
                        (40, 30),
                        "every image at the view's size"
                    );
                    Some(*preview)
                }
                _ => None,
            })
            .collect()
    }

    #[test]
    fn a_scene_heavier_than_the_preview_shows_one_first() {
        let updates =
            updates_of(&BODY.replacen("amb: 0.1 0.1 0.1\n", "amb: 0.1 0.1 0.1\nspp: 4\n", 1));
        let kinds = previews(&updates);
        assert_eq!(kinds.first(), Some(&true), "{kinds:?}");
        assert!(
            kinds[1..].iter().all(|p| !p) && kinds.len() > 1,
            "{kinds:?}"
        );
        assert!(matches!(
            updates.last(),
            Some(Update::Stopped { serial: 1, .. })
        ));
    }

    #[test]
    fn a_classic_scene_needs_no_preview() {
        let updates = updates_of(BODY);
        let kinds = previews(&updates);
        assert!(!kinds.is_empty() && kinds.iter().all(|p| !p), "{kinds:?}");
        assert!(matches!(
            updates.last(),
            Some(Update::Stopped {
                serial: 1,
                why: Stopped::Noiseless
            })
        ));
    }

    #[test]
    fn a_cancel_is_timed_from_the_first_change_since_the_job_began() {
        let control = Control::default();
        let job = |serial| Job {
            camera: Orbit::of(&Scene::default()).camera,
            width: 4,
            height: 3,
            show: Show::Main,
            serial,
        };
        control.submit(job(1));
        assert_eq!(control.take().map(|j| j.serial), Some(1));
        assert_eq!(
            control.since_cancel(),
            None,
            "nothing cancels the job taken"
        );
        control.submit(job(2));
        std::thread::sleep(Duration::from_millis(30));
        control.submit(job(3));
        let waited = control.since_cancel().expect("cancelled");
        assert!(waited >= Duration::from_millis(30), "{waited:?}");
        assert_eq!(control.take().map(|j| j.serial), Some(3), "the newest job");
        assert_eq!(control.since_cancel(), None);
        assert!(control.take().is_none());
    }
}
