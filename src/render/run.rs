//! `Renderer::run`: a job carried out, its image handed to its sink.

use super::job::{Done, Job, Passes, Quiet, Stop, Target, Watch};
use super::options::RenderOptions;
use super::region::Region;
use super::renderer::Renderer;
use super::sink::Sink;
use crate::Error;

impl Renderer {
    /// Carries out `job`, handing the image to `sink`. Nothing is written
    /// when the Vulkan validation layer reported messages: the image may be
    /// wrong (`Error::Validation`).
    pub fn run(&self, job: &Job, sink: &Sink, watch: &dyn Watch) -> Result<Done, Error> {
        job.check(&self.options)?;
        sink.check(&job.target)?;
        if let (
            Target::Frames(frames),
            Sink::Frames {
                dir,
                format,
                encode,
            },
        ) = (job.target, sink)
        {
            return self.run_frames(job, frames, dir, *format, encode, watch);
        }
        let pixels = sink.pixels(&job.target);
        let progress = |done: u64, total: u64| watch.progress(done, total);
        let (mut output, span, passes) = match (job.target, job.stop) {
            (Target::Image, Stop::Once) => {
                let out = self.render_region_as(job.scene, Region::All, pixels, &progress)?;
                (out, None, None)
            }
            (Target::Crop(c), _) => {
                let out = self.render_region_as(job.scene, Region::Crop(c), pixels, &progress)?;
                (out, None, None)
            }
            (Target::Part(p), _) => {
                let (out, span) =
                    self.render_part_as(job.scene, p.index, p.count, pixels, &progress)?;
                (out, Some(span), None)
            }
            (Target::Frames(_), _) => unreachable!("`Sink::check` pairs frames with their sink"),
            (Target::Image, Stop::Passes(stop)) => {
                let done = self.render_progressive(job.scene, &stop, &mut |r| watch.pass(r))?;
                let passes = Passes {
                    report: done.report,
                    stopped: done.stopped,
                    history: done.history,
                };
                (done.output, None, Some(passes))
            }
        };
        if output.validation_messages > 0 {
            return Err(Error::Validation(output.validation_messages));
        }
        let stamp = match (job.target, span) {
            (Target::Part(p), Some(span)) => Some(crate::parts::stamp::Stamp {
                render: job.digest(&self.options),
                index: p.index,
                count: p.count,
                span,
                height: self.options.height,
                renderer: output.renderer.clone(),
            }),
            _ => None,
        };
        let written = sink.write(
            &output.image,
            &job.target,
            stamp.as_ref(),
            &mut output.timings,
        )?;
        Ok(Done {
            output,
            written,
            span,
            passes,
            frames: None,
        })
    }
}

/// Carries out `job` on a `Renderer` set up for this call only.
pub fn run(options: &RenderOptions, job: &Job, sink: &Sink) -> Result<Done, Error> {
    Renderer::new(options)?.run(job, sink, &Quiet)
}
