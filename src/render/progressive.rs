//! A `Renderer`'s progressive renders: passes of the scene's own samples
//! per pixel until a stop rule (`crate::render::passes`) or whoever watches
//! the passes says so.

use std::time::Instant;

use super::options::PixelFormat;
use super::output::RenderOutput;
use super::passes::{
    Accumulator, Blocks, PassReport, Progressive, StopAt, Stopped, ADAPTIVE_FIRST_PASSES,
    MIN_PASSES_FOR_TARGET,
};
use super::region::Region;
use super::renderer::Renderer;
use crate::images::framebuffer::Image;
use crate::scene::Scene;
use crate::timing::Timings;
use crate::Error;

impl Renderer {
    /// Renders `scene` in passes of its own samples per pixel, each with a
    /// seed of its own, until `stop` says so (`progressive`); `on_pass`
    /// hears of every pass. The BVH and the packed scene are built once.
    pub(super) fn render_progressive(
        &self,
        scene: &Scene,
        stop: &StopAt,
        on_pass: &mut dyn FnMut(&PassReport),
    ) -> Result<Progressive, Error> {
        self.render_progressive_watched(scene, stop, &mut |report, _| {
            on_pass(report);
            true
        })
    }

    /// `render_progressive`, showing each pass's image as it lands:
    /// `on_pass` gets the report and the passes so far (their `mean()` is
    /// the image), and ends the render early by returning false
    /// (`Stopped::Cancelled`). `glint view` refines its window this way.
    /// The cancel flag (`set_cancel`) ends it mid-pass: with the passes
    /// before that one (`Stopped::Cancelled`), or `Error::Cancelled` when
    /// the first was cut short.
    pub fn render_progressive_watched(
        &self,
        scene: &Scene,
        stop: &StopAt,
        on_pass: &mut dyn FnMut(&PassReport, &crate::render::passes::Accumulator) -> bool,
    ) -> Result<Progressive, Error> {
        let start = Instant::now();
        let scene = &*scene.in_view_space();
        let mut timings = self.take_setup_timings();
        let mut p = self.prepare(scene, &mut timings);
        let packed = self.pack(scene, &p, &mut timings);
        let base_seed = p.effects.seed;
        let spp = p.effects.spp;
        let mut acc = Accumulator::new(p.camera.width, p.camera.height);
        let mut blocks = Blocks::all(p.camera.width, p.camera.height);
        let mut history: Vec<PassReport> = Vec::new();
        let mut last: Option<RenderOutput> = None;
        let stopped = loop {
            let pass = acc.passes();
            p.effects.seed = base_seed.wrapping_add(pass);
            let pass_timings = if pass == 0 {
                std::mem::take(&mut timings)
            } else {
                Timings::default()
            };
            let region = if blocks.all_active() {
                Region::All
            } else {
                Region::Blocks(&blocks)
            };
            let out = match self.render_prepared_as(
                scene,
                &p,
                &packed,
                pass_timings,
                region,
                PixelFormat::Float,
                &|_, _| {},
            ) {
                Err(Error::Cancelled) if last.is_some() => break Stopped::Cancelled,
                out => out?,
            };
            acc.add_where(&out.framebuffer(), &|x, y| blocks.is_active(x, y));
            match last.as_mut() {
                None => last = Some(out),
                Some(l) => {
                    l.timings.extend(&out.timings);
                    l.samples += out.samples;
                }
            }
            let mut done_blocks = false;
            if let (true, Some(target)) = (stop.adaptive, stop.aim()) {
                if acc.passes() >= ADAPTIVE_FIRST_PASSES {
                    match acc.adaptive_blocks(&blocks, target) {
                        Some(active) => blocks.active = active,
                        None if acc.passes() >= MIN_PASSES_FOR_TARGET => done_blocks = true,
                        // Met already, but too early to trust: the stop
                        // rule waits for its passes.
                        None => {}
                    }
                }
            }
            let report = PassReport {
                passes: acc.passes(),
                samples_per_pixel: acc.max_passes() * spp,
                mean_samples: acc.mean_passes() * f64::from(spp),
                active_blocks: [blocks.active_count(), blocks.active.len()],
                elapsed: start.elapsed(),
                estimated_rmse: acc.estimated_rmse(),
            };
            let go_on = on_pass(&report, &acc);
            history.push(report);
            if !go_on {
                break Stopped::Cancelled;
            }
            if done_blocks {
                break Stopped::Target;
            }
            if let Some(reason) = stop.verdict(&history, spp) {
                break reason;
            }
        };
        let mut output = last.expect("at least one pass");
        output.image = match self.options.pixels {
            PixelFormat::Float => Image::Float(acc.mean()),
            PixelFormat::Rgb8 => Image::Rgb8(acc.mean().to_rgb8()),
        };
        let report = *history.last().expect("at least one pass");
        Ok(Progressive {
            output,
            report,
            stopped,
            history,
        })
    }
}
