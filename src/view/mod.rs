//! `glint view`: a window that shows a render refining pass by pass (the
//! course program's screen output), on any backend. The render thread
//! (`worker`) refines the current view; this thread owns the window
//! (winit), draws each pass's image into it (softbuffer: 8-bit, no gamma,
//! the very bytes `render` writes), and turns keys and the mouse into new
//! views (`orbit`).
//!
//! Keys: drag to orbit, right-drag (or shift-drag) to pan, wheel to zoom;
//! `S` saves the image (PNG and EXR) and prints its camera block, `C`
//! prints the camera block, `Space` pauses, `Tab` flips to the CPU
//! reference's image of the same view and back, `D` shows the difference
//! of the two as `compare --diff`'s heat map, `Q` or `Esc` quits.

mod device;
pub mod orbit;
mod renderers;
pub mod worker;

use std::num::NonZeroU32;
use std::path::PathBuf;
use std::rc::Rc;
use std::sync::atomic::Ordering;
use std::sync::mpsc::Receiver;
use std::sync::Arc;
use std::time::{Duration, Instant};

use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, ModifiersState, NamedKey};
use winit::window::{Window, WindowId};

use crate::images::framebuffer::{to_u8, write_framebuffer, Framebuffer};
use crate::render::passes::{PassReport, StopAt, Stopped};
use crate::render::RenderOptions;
use crate::scene::Scene;
use crate::Error;
use device::Drawing;
use orbit::Orbit;
use worker::{Control, Job, Show, Update};

/// The window's raw handles, for a Vulkan surface on it.
fn window_target(window: &Window) -> Option<crate::gpu::WindowTarget> {
    use raw_window_handle::{HasDisplayHandle, HasWindowHandle};
    Some(crate::gpu::WindowTarget {
        display: window.display_handle().ok()?.as_raw(),
        window: window.window_handle().ok()?.as_raw(),
    })
}

/// What `glint view` was asked for.
pub struct ViewOptions {
    /// Image size, backend, device, effects.
    pub render: RenderOptions,
    /// When refinement stops.
    pub stop: StopAt,
    /// Written when the refinement stops, and when the window closes.
    pub out: Option<PathBuf>,
    /// Where `S` saves (`<stem>-view-N.png` and `.exr`).
    pub save_stem: PathBuf,
    /// The host draws the window even where the device can present.
    pub host_draws: bool,
}

/// Why no window could open: no display, or the display refused.
pub fn display_error(why: impl std::fmt::Display) -> Error {
    let why = why.to_string();
    // winit's OS errors lead with the winit source line that raised them,
    // which tells a user nothing.
    let why = why
        .strip_prefix("os error at ")
        .and_then(|rest| rest.split_once(": "))
        .map_or(why.as_str(), |(_, reason)| reason);
    Error::NoWindow(why.to_string())
}

fn check_display() -> Result<(), Error> {
    let set = |v: &str| std::env::var_os(v).is_some_and(|d| !d.is_empty());
    if set("DISPLAY") || set("WAYLAND_DISPLAY") {
        Ok(())
    } else {
        Err(display_error(
            "no display (neither DISPLAY nor WAYLAND_DISPLAY is set)",
        ))
    }
}

/// Opens the window and refines `scene` in it until it is closed.
pub fn view(scene: Scene, options: ViewOptions) -> Result<(), Error> {
    check_display()?;
    let event_loop = EventLoop::<()>::with_user_event()
        .build()
        .map_err(display_error)?;
    let proxy = event_loop.create_proxy();
    let control = Arc::new(Control::default());
    let (tx, rx) = std::sync::mpsc::channel();
    let thread = {
        let (scene, render, stop, control) = (
            scene.clone(),
            options.render.clone(),
            options.stop,
            control.clone(),
        );
        std::thread::spawn(move || {
            worker::run(
                scene,
                render,
                stop,
                control,
                tx,
                Box::new(move || {
                    let _ = proxy.send_event(());
                }),
            );
        })
    };
    let mut app = App::new(&scene, options, control.clone(), Some(rx));
    let result = event_loop.run_app(&mut app).map_err(display_error);
    control.quit.store(true, Ordering::SeqCst);
    control.cancel.store(true, Ordering::SeqCst);
    let _ = thread.join();
    result?;
    app.finish()
}

/// Shows a finished image (`glint render --show`) until the window closes.
pub fn show(image: Framebuffer, title: String) -> Result<(), Error> {
    check_display()?;
    let event_loop = EventLoop::<()>::with_user_event()
        .build()
        .map_err(display_error)?;
    let options = ViewOptions {
        render: RenderOptions {
            width: image.width,
            height: image.height,
            ..RenderOptions::default()
        },
        stop: StopAt::default(),
        out: None,
        save_stem: PathBuf::from("glint"),
        host_draws: true,
    };
    let mut app = App::new(
        &Scene::default(),
        options,
        Arc::new(Control::default()),
        None,
    );
    app.image = Some(Arc::new(image));
    app.label = title;
    app.state = "finished".into();
    event_loop.run_app(&mut app).map_err(display_error)?;
    app.error.map_or(Ok(()), Err)
}

struct App {
    options: ViewOptions,
    control: Arc<Control>,
    updates: Option<Receiver<Update>>,
    window: Option<Rc<Window>>,
    /// The host's drawing surface, where the host draws the window.
    surface: Option<softbuffer::Surface<Rc<Window>, Rc<Window>>>,
    /// The device presents the window (`device::Screen`); the host draws
    /// it where false.
    device_draws: bool,
    orbit: Orbit,
    show: Show,
    serial: u64,
    size: (u32, u32),
    aspect: f64,
    image: Option<Arc<Framebuffer>>,
    report: Option<PassReport>,
    rays_per_second: Option<f64>,
    label: String,
    state: String,
    started: Instant,
    drag: Option<(MouseButton, f64, f64)>,
    modifiers: ModifiersState,
    saves: u32,
    error: Option<Error>,
    /// When the window opened, when its first image came, and how many
    /// images it has shown since (`glint view`'s own report on exit).
    opened: Option<Instant>,
    first_image: Option<Instant>,
    /// The first image that was a pass, not a preview.
    first_pass: Option<Instant>,
    images: u64,
    /// The image shown is a preview (`worker::PREVIEW_ABOVE`).
    preview: bool,
    /// From each change of the view (a drag, a resize) to its first image.
    after_change: Vec<Duration>,
    /// The current view has shown no image yet.
    awaiting: bool,
}

impl App {
    fn new(
        scene: &Scene,
        options: ViewOptions,
        control: Arc<Control>,
        updates: Option<Receiver<Update>>,
    ) -> App {
        let size = (options.render.width, options.render.height);
        App {
            orbit: Orbit::of(scene),
            aspect: f64::from(size.0) / f64::from(size.1.max(1)),
            options,
            control,
            updates,
            window: None,
            surface: None,
            device_draws: false,
            show: Show::Main,
            serial: 0,
            size,
            image: None,
            report: None,
            rays_per_second: None,
            label: String::new(),
            state: "starting".into(),
            started: Instant::now(),
            drag: None,
            modifiers: ModifiersState::empty(),
            saves: 0,
            error: None,
            opened: None,
            first_image: None,
            first_pass: None,
            images: 0,
            preview: false,
            after_change: Vec::new(),
            awaiting: false,
        }
    }

    /// Starts refining the current view afresh.
    fn restart(&mut self) {
        if self.updates.is_none() {
            return;
        }
        self.serial += 1;
        self.started = Instant::now();
        self.awaiting = true;
        self.report = None;
        self.rays_per_second = None;
        self.state = "refining".into();
        self.control.submit(Job {
            camera: self.orbit.camera,
            width: self.size.0,
            height: self.size.1,
            show: self.show,
            serial: self.serial,
        });
    }

    fn title(&self) -> String {
        let mut t = format!("glint view: {}", self.label);
        if let (Some(r), false) = (&self.report, self.preview) {
            t += &format!(", {} spp", r.samples_per_pixel);
            if let Some(e) = r.estimated_rmse {
                t += &format!(", RMSE {e:.4}");
            }
            t += &format!(", {:.1} s", r.elapsed.as_secs_f64());
        }
        if let Some(rps) = self.rays_per_second {
            t += &format!(", {:.1} M rays/s", rps / 1e6);
        }
        if self.control.paused.load(Ordering::SeqCst) {
            t += " [paused]";
        } else {
            t += &format!(" [{}]", self.state);
        }
        t
    }

    fn redraw(&mut self) {
        let title = self.title();
        if let Some(window) = &self.window {
            window.set_title(&title);
        }
        if self.device_draws {
            self.control.repaint.store(true, Ordering::SeqCst);
            return;
        }
        let (Some(window), Some(surface)) = (&self.window, &mut self.surface) else {
            return;
        };
        let size = window.inner_size();
        let (Some(w), Some(h)) = (NonZeroU32::new(size.width), NonZeroU32::new(size.height)) else {
            return;
        };
        if surface.resize(w, h).is_err() {
            return;
        }
        let Ok(mut buffer) = surface.buffer_mut() else {
            return;
        };
        buffer.fill(0);
        if let Some(img) = &self.image {
            // The image centred, 1:1 where it fits (the window's pixels
            // are the image's), nearest-neighbour scaled where it does not.
            let (ww, wh) = (size.width as usize, size.height as usize);
            let (iw, ih) = (img.width as usize, img.height as usize);
            let scale = (ww as f64 / iw as f64).min(wh as f64 / ih as f64).min(1.0);
            let (dw, dh) = (
                ((iw as f64 * scale) as usize).max(1),
                ((ih as f64 * scale) as usize).max(1),
            );
            let (x0, y0) = ((ww - dw.min(ww)) / 2, (wh - dh.min(wh)) / 2);
            for y in 0..dh.min(wh) {
                let sy = (y * ih / dh).min(ih - 1);
                for x in 0..dw.min(ww) {
                    let sx = (x * iw / dw).min(iw - 1);
                    let [r, g, b] = img.pixels[sy * iw + sx].map(to_u8);
                    buffer[(y0 + y) * ww + x0 + x] =
                        (u32::from(r) << 16) | (u32::from(g) << 8) | u32::from(b);
                }
            }
        }
        let _ = buffer.present();
    }

    /// The host draws the window from now on; false (the error kept)
    /// where it cannot.
    fn open_host_surface(&mut self) -> bool {
        let Some(window) = &self.window else {
            return false;
        };
        let surface = softbuffer::Context::new(window.clone())
            .and_then(|c| softbuffer::Surface::new(&c, window.clone()));
        match surface {
            Ok(s) => self.surface = Some(s),
            Err(e) => self.error = Some(display_error(e)),
        }
        self.surface.is_some()
    }

    /// Takes the render thread's updates; true where the window must close
    /// (nothing can draw it).
    fn take_updates(&mut self) -> bool {
        let mut closing = false;
        let Some(rx) = &self.updates else {
            return closing;
        };
        for u in worker::drain(rx) {
            match u {
                Update::Frame {
                    serial,
                    image,
                    report,
                    rays_per_second,
                    label,
                    preview,
                    ..
                } if serial == self.serial => {
                    self.images += 1;
                    // One instant for both: the report tells a preview
                    // from a pass by whether they differ.
                    let now = Instant::now();
                    self.first_image.get_or_insert(now);
                    if !preview {
                        self.first_pass.get_or_insert(now);
                    }
                    self.preview = preview;
                    if std::mem::take(&mut self.awaiting) && self.serial > 1 {
                        self.after_change.push(self.started.elapsed());
                    }
                    self.image = Some(image);
                    self.report = Some(report);
                    if rays_per_second.is_some() {
                        self.rays_per_second = rays_per_second;
                    }
                    self.label = label;
                }
                Update::Stopped { serial, why } if serial == self.serial => {
                    self.state = match why {
                        Stopped::Target => "done: target error reached",
                        Stopped::Noiseless => "done: converged",
                        Stopped::TimeLimit => "done: time limit",
                        Stopped::MaxSamples => "done: sample cap",
                        Stopped::Cancelled => "cancelled",
                    }
                    .into();
                    if self.show == Show::Main {
                        self.write_out();
                    }
                }
                Update::Failed(e) => {
                    self.state = format!("failed: {e}");
                    eprintln!("error: {e}");
                }
                Update::Note(note) => eprintln!("note: {note}"),
                Update::Drawing(Drawing::Device(what)) => {
                    eprintln!("view: the device presents the window ({what})");
                    self.device_draws = true;
                }
                Update::Drawing(Drawing::Host(why)) => {
                    if let Some(why) = why {
                        eprintln!("note: {why}; the window draws through the host");
                    }
                    self.device_draws = false;
                    if self.surface.is_none() && !self.open_host_surface() {
                        closing = true;
                    }
                }
                _ => {}
            }
        }
        closing
    }

    fn write_out(&mut self) {
        let (Some(out), Some(img)) = (&self.options.out, &self.image) else {
            return;
        };
        if self.preview {
            eprintln!(
                "{} not written: the window shows only a preview of this view",
                out.display()
            );
            return;
        }
        match write_framebuffer(img, out, 95) {
            Ok(()) => eprintln!("wrote {}", out.display()),
            Err(e) => {
                eprintln!("error: {e}");
                self.error = Some(e);
            }
        }
    }

    fn save(&mut self) {
        let Some(img) = self.image.clone() else {
            return;
        };
        if self.preview {
            eprintln!(
                "nothing saved: the window shows a preview (half size, 1 sample per pixel); \
                 press S again once the first pass lands"
            );
            return;
        }
        self.saves += 1;
        let stem = self.options.save_stem.display().to_string();
        for ext in ["png", "exr"] {
            let path = PathBuf::from(format!("{stem}-view-{}.{ext}", self.saves));
            match write_framebuffer(&img, &path, 95) {
                Ok(()) => println!("saved {}", path.display()),
                Err(e) => eprintln!("error: {e}"),
            }
        }
        println!("{}", self.orbit.block());
    }

    fn key(&mut self, event_loop: &ActiveEventLoop, key: &Key) {
        match key {
            Key::Named(NamedKey::Escape) => event_loop.exit(),
            Key::Named(NamedKey::Space) => {
                let p = !self.control.paused.load(Ordering::SeqCst);
                self.control.paused.store(p, Ordering::SeqCst);
            }
            Key::Named(NamedKey::Tab) => {
                self.show = if self.show == Show::Reference {
                    Show::Main
                } else {
                    Show::Reference
                };
                self.restart();
            }
            Key::Character(c) => match c.to_lowercase().as_str() {
                "q" => event_loop.exit(),
                "s" => self.save(),
                "c" => println!("{}", self.orbit.block()),
                "d" => {
                    self.show = if self.show == Show::Difference {
                        Show::Main
                    } else {
                        Show::Difference
                    };
                    self.restart();
                }
                _ => {}
            },
            _ => {}
        }
        self.redraw();
    }

    /// The render size for a window of `size`: the largest that keeps the
    /// first image's aspect.
    fn fit(&self, size: PhysicalSize<u32>) -> (u32, u32) {
        let (w, h) = (f64::from(size.width.max(1)), f64::from(size.height.max(1)));
        if w / h > self.aspect {
            (((h * self.aspect) as u32).max(1), h as u32)
        } else {
            (w as u32, ((w / self.aspect) as u32).max(1))
        }
    }

    fn finish(&mut self) -> Result<(), Error> {
        self.take_updates();
        if let (Some(open), Some(first)) = (self.opened, self.first_image) {
            let since = first.elapsed().as_secs_f64();
            let pass = match self.first_pass {
                Some(p) if p != first => {
                    format!(
                        " (a preview; the first pass {:.0} ms)",
                        (p - open).as_secs_f64() * 1e3
                    )
                }
                Some(_) => String::new(),
                None => " (a preview; no pass finished)".to_string(),
            };
            let mut changes = self.after_change.clone();
            changes.sort();
            let changed = match changes.get(changes.len() / 2) {
                Some(median) => format!(
                    "; {} view changes, each showing its first image in {:.0} ms (median), {:.0} ms at most",
                    changes.len(),
                    median.as_secs_f64() * 1e3,
                    changes.last().map_or(0.0, |d| d.as_secs_f64() * 1e3)
                ),
                None => String::new(),
            };
            eprintln!(
                "view: first image {:.0} ms after the window opened{pass}; {} images in {:.1} s since ({:.1} a second){changed}",
                (first - open).as_secs_f64() * 1e3,
                self.images,
                since,
                if since > 0.0 { (self.images.saturating_sub(1)) as f64 / since } else { 0.0 }
            );
        }
        if self.show == Show::Main {
            self.write_out();
        }
        self.error.take().map_or(Ok(()), Err)
    }
}

impl ApplicationHandler<()> for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let attributes = Window::default_attributes()
            .with_title("glint view")
            .with_inner_size(PhysicalSize::new(self.size.0, self.size.1));
        let window = match event_loop.create_window(attributes) {
            Ok(w) => Rc::new(w),
            Err(e) => {
                self.error = Some(display_error(e));
                event_loop.exit();
                return;
            }
        };
        // The render thread presents from the device where it can
        // (`device::Screen`) and says so before its first image; a finished
        // image (`render --show`) is the host's to draw.
        match window_target(&window) {
            Some(target) if self.updates.is_some() && !self.options.host_draws => {
                *self
                    .control
                    .window
                    .lock()
                    .unwrap_or_else(|e| e.into_inner()) = Some(target);
            }
            _ => {}
        }
        self.window = Some(window);
        if self.updates.is_none() && !self.open_host_surface() {
            event_loop.exit();
            return;
        }
        self.opened = Some(Instant::now());
        self.restart();
        self.redraw();
    }

    fn user_event(&mut self, event_loop: &ActiveEventLoop, (): ()) {
        if self.take_updates() {
            event_loop.exit();
            return;
        }
        self.redraw();
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::RedrawRequested => self.redraw(),
            WindowEvent::Resized(size) => {
                let fit = self.fit(size);
                if fit != self.size && self.updates.is_some() {
                    self.size = fit;
                    self.restart();
                }
                self.redraw();
            }
            WindowEvent::ModifiersChanged(m) => self.modifiers = m.state(),
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                self.key(event_loop, &event.logical_key);
            }
            WindowEvent::MouseInput { state, button, .. } => match state {
                ElementState::Pressed => self.drag = Some((button, f64::NAN, f64::NAN)),
                ElementState::Released => self.drag = None,
            },
            WindowEvent::CursorMoved { position, .. } => {
                let Some((button, x0, y0)) = self.drag else {
                    return;
                };
                self.drag = Some((button, position.x, position.y));
                if x0.is_nan() || self.updates.is_none() {
                    return;
                }
                let (dx, dy) = (position.x - x0, position.y - y0);
                if button == MouseButton::Right || self.modifiers.shift_key() {
                    self.orbit.pan(dx, dy, self.size.1);
                } else {
                    self.orbit.orbit(dx, dy);
                }
                self.restart();
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => f64::from(y),
                    MouseScrollDelta::PixelDelta(p) => p.y / 40.0,
                };
                if self.updates.is_some() {
                    self.orbit.zoom(lines);
                    self.restart();
                }
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_refused_display_is_named_without_winits_source_line() {
        let e = display_error(
            "os error at /home/u/.cargo/src/winit-0.30/src/platform_impl/linux/mod.rs:788: \
             Failed to open connection to X server",
        );
        let msg = e.to_string();
        assert!(
            msg.starts_with(
                "cannot open a window: Failed to open connection to X server; set DISPLAY"
            ),
            "{msg}"
        );
        assert_eq!(e.exit_code(), 2);
        let plain = display_error("no display").to_string();
        assert!(
            plain.starts_with("cannot open a window: no display;"),
            "{plain}"
        );
    }
}
