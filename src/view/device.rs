//! The window's image from the Vulkan device, where it can present
//! (`gpu::present`): one device, made with the window's surface, renders
//! every GPU view; their passes are averaged on it and presented from it,
//! and the images the host makes (previews, the CPU reference's,
//! differences) are copied in. Where the device cannot present, or a
//! present fails, the window draws through the host (softbuffer) and a
//! note says why.

use super::renderers::Renderers;
use crate::gpu::present::Presenter;
use crate::gpu::{Context, ContextOptions, GpuError, WindowTarget};
use crate::images::framebuffer::Framebuffer;
use crate::render::{Backend, Renderer};

/// Who draws the window.
#[derive(Debug)]
pub enum Drawing {
    /// The device presents it (what, e.g. the device and format).
    Device(String),
    /// The host does (softbuffer); why, where a device was asked for.
    Host(Option<String>),
}

/// The presenter, while the device draws the window.
pub(super) struct Screen {
    presenter: Option<Presenter>,
}

impl Screen {
    /// A screen for `window`: the device presents where the renders are on
    /// a Vulkan device that can; `renderers` then make their GPU renderers
    /// on that device.
    pub(super) fn open(
        window: Option<WindowTarget>,
        renderers: &mut Renderers,
    ) -> (Screen, Drawing) {
        let none = Screen { presenter: None };
        let o = renderers.options().clone();
        let Some(window) = window.filter(|_| o.backend != Backend::Cpu) else {
            return (none, Drawing::Host(None));
        };
        let ctx = match Context::new(&ContextOptions {
            device: o.device.clone(),
            validation: o.validation,
            pipeline_cache: o.pipeline_cache.clone(),
            window: Some(window),
        }) {
            Ok(ctx) => ctx,
            // `--backend auto` with no presenting device: whatever
            // `Renderer::new` picks renders, and the host draws.
            Err(_) if o.backend == Backend::Auto => return (none, Drawing::Host(None)),
            Err(e) => return (none, Drawing::Host(Some(e.to_string()))),
        };
        if o.backend == Backend::Auto
            && o.device.is_none()
            && ctx.info().profile.prefer_cpu_reference
        {
            // The CPU reference renders (`Renderer::new`'s choice).
            return (none, Drawing::Host(None));
        }
        match Presenter::new(&ctx) {
            Ok(p) => {
                let what = format!("{}, {}", ctx.info().name, p.describe());
                renderers.use_context(ctx);
                (Screen { presenter: Some(p) }, Drawing::Device(what))
            }
            Err(e) => (none, Drawing::Host(Some(e.to_string()))),
        }
    }

    /// Presents an image the host made.
    pub(super) fn host(&mut self, image: &Framebuffer) -> Result<(), String> {
        let Some(p) = &mut self.presenter else {
            return Ok(());
        };
        p.show_host(image).map_err(|e| self.give_up(e))
    }

    /// Starts a view on `renderer`: its passes go to the device's mean, if
    /// it is the presenting device's. Whether they do.
    pub(super) fn start(
        &mut self,
        renderer: &Renderer,
        width: u32,
        height: u32,
    ) -> Result<bool, String> {
        let (Some(p), Some(gpu)) = (&mut self.presenter, renderer.gpu()) else {
            return Ok(false);
        };
        let target = p.mean().start(width, height).map_err(|e| self.give_up(e))?;
        gpu.copy_passes_to(Some(target));
        Ok(true)
    }

    /// The view's pass (its first: the sums start over) is in: fold it into
    /// the mean and present.
    pub(super) fn pass(&mut self, first: bool) -> Result<(), String> {
        let Some(p) = &mut self.presenter else {
            return Ok(());
        };
        p.mean()
            .add_pass(first)
            .and_then(|()| p.show_device())
            .map_err(|e| self.give_up(e))
    }

    /// The view ended: `renderer` stops copying its passes.
    pub(super) fn stop(&self, renderer: &Renderer) {
        if let Some(gpu) = renderer.gpu() {
            gpu.copy_passes_to(None);
        }
    }

    /// Presents the last image again where it is due (`again`) or was not
    /// presented yet.
    pub(super) fn again(&mut self, due: bool) -> Result<(), String> {
        let Some(p) = &mut self.presenter else {
            return Ok(());
        };
        if due || p.pending() {
            p.again().map_err(|e| self.give_up(e))?;
        }
        Ok(())
    }

    /// From now on the host draws; what to tell the user.
    fn give_up(&mut self, e: GpuError) -> String {
        self.presenter = None;
        format!("presenting from the device failed ({e}); the window draws through the host from now on")
    }
}
