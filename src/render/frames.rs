//! An animation's frames as one job: rendered one after the other on one
//! `Renderer` (device and pipelines built once), each encoded and written
//! on a worker while the next renders (`write_queue`); a scene with no
//! motion is rendered and encoded once and written N times.

use std::path::Path;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;

use super::job::{settings_text, Done, Frames, FramesDone, Job, Watch};
use super::options::PixelFormat;
use super::output::RenderOutput;
use super::renderer::Renderer;
use crate::images::encode::EncodeOptions;
use crate::images::framebuffer::{Image, ImageFile};
use crate::images::write_queue::{Encoded, WriteQueue};
use crate::Error;

/// Threads that encode and write frames: two keep one frame encoding while
/// the next is handed over; JPEG's strips run on the render's thread pool
/// beside the render, so more writers add no cores.
const WRITERS: usize = 2;

impl Renderer {
    /// `Renderer::run` of a `Target::Frames` job into `dir`.
    pub(super) fn run_frames(
        &self,
        job: &Job,
        frames: Frames,
        dir: &Path,
        format: ImageFile,
        encode: &EncodeOptions,
        watch: &dyn Watch,
    ) -> Result<Done, Error> {
        let scene = job.scene;
        let Some([first, last]) = frames.share()? else {
            return Ok(Done::frames(self.name(), FramesDone::default(), None));
        };
        std::fs::create_dir_all(dir).map_err(|error| Error::WriteFile {
            path: dir.to_path_buf(),
            error,
        })?;
        if frames.part.is_some() {
            let digest = crate::parts::stamp::render_digest(
                scene,
                &format!(
                    "{} frames {}",
                    settings_text(&self.options, scene),
                    frames.count
                ),
            );
            crate::parts::frames::claim_frames(dir, &digest)?;
        }
        let effects = self.options.effects(scene);
        let pixels = PixelFormat::for_file(format);
        let written = Arc::new(AtomicU32::new(0));
        let counter = written.clone();
        let queue = WriteQueue::new(WRITERS, move |_| {
            counter.fetch_add(1, Ordering::Relaxed);
        });
        let mut done = FramesDone {
            first,
            last,
            ..FramesDone::default()
        };
        let mut last_output: Option<RenderOutput> = None;
        // Nothing moves: one render and one encode serve every frame.
        let mut still: Option<Arc<Encoded>> = None;
        // The moving scene's tree and packing, refitted from frame to frame.
        let mut moving = None;
        for i in first..=last {
            let path = frames.path(dir, i, format);
            // A requeued task of an array keeps the frames it finished.
            if frames.part.is_some() && crate::parts::frames::frame_done(&path) {
                done.kept += 1;
                watch.frame(i, None);
                continue;
            }
            let frame = match &still {
                Some(frame) => frame.clone(),
                None => {
                    let rendered =
                        self.render_moving_frame(scene, effects.frame_time(i), &mut moving, pixels);
                    // Frames already handed over are still written whole
                    // (the queue's drop waits for them).
                    let mut output = rendered.map_err(|e| e.in_frame(i))?;
                    if output.validation_messages > 0 {
                        return Err(Error::Validation(output.validation_messages).in_frame(i));
                    }
                    watch.frame(i, Some(&output));
                    done.render_timings.extend(&output.timings);
                    // The image goes to the writers; the rest is kept for `Done`.
                    let image =
                        std::mem::replace(&mut output.image, Image::Float(Default::default()));
                    let frame = Encoded::new(image, format, *encode);
                    if !scene.has_motion() {
                        still = Some(frame.clone());
                    }
                    last_output = Some(output);
                    frame
                }
            };
            queue.push(&frame, path).map_err(|e| e.in_frame(i))?;
            watch.frames_written(written.load(Ordering::Relaxed));
        }
        done.write_timings = queue.finish()?;
        done.written = written.load(Ordering::Relaxed);
        watch.frames_written(done.written);
        done.rendered = (last - first + 1) - done.kept;
        Ok(Done::frames(self.name(), done, last_output))
    }
}
