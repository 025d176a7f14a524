//! An animation's frames as one job: rendered one after the other on one
//! `Renderer` (device and pipelines built once), each encoded and written
//! on a worker while the next renders (`write_queue`); a scene with no
//! motion is rendered and encoded once and written N times.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;

use super::job::{Done, FramesDone, Job, Watch};
use super::{PixelFormat, Region, Renderer};
use crate::encode::EncodeOptions;
use crate::framebuffer::{Framebuffer, Image, ImageFile};
use crate::output::RenderOutput;
use crate::parts::PartOf;
use crate::write_queue::{Encoded, WriteQueue};
use crate::Error;

/// Threads that encode and write frames: two keep one frame encoding while
/// the next is handed over; JPEG's strips run on the render's thread pool
/// beside the render, so more writers add no cores.
const WRITERS: usize = 2;

/// Which frames of an animation a job renders (frame i shows the scene at
/// time i / fps).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frames {
    /// Frames in the whole animation; the file names have as many digits
    /// as the last one's number (three at least).
    pub count: u32,
    /// Only frames FIRST to LAST (inclusive, counted from 0).
    pub range: Option<[u32; 2]>,
    /// One task's share of the frames (`parts::cut::frame_share`): the
    /// directory is claimed for this render, and frames already there
    /// whole are kept, so a requeued task does only what is missing.
    pub part: Option<PartOf>,
}

impl Frames {
    /// The frames this job renders, or `None` for a part that has none.
    pub fn share(&self) -> Result<Option<[u32; 2]>, Error> {
        let last = self
            .count
            .checked_sub(1)
            .ok_or_else(|| Error::InvalidOption("an animation has one frame at least".into()))?;
        match (self.part, self.range) {
            (Some(p), _) => Ok(crate::parts::cut::frame_share(self.count, p.index, p.count)),
            (None, Some([first, end])) if first <= end && end <= last => Ok(Some([first, end])),
            (None, Some([first, end])) => Err(Error::InvalidOption(format!(
                "--frame-range {first}-{end} goes past the last frame of --frames {} \
                 (frames count from 0, so the last is {last})",
                self.count
            ))),
            (None, None) => Ok(Some([0, last])),
        }
    }

    /// Frame `i`'s file in `dir`.
    pub fn path(&self, dir: &Path, i: u32, format: ImageFile) -> PathBuf {
        let digits = self.count.saturating_sub(1).to_string().len().max(3);
        dir.join(format!("{i:0digits$}.{}", format.extension()))
    }
}

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
            return Ok(Done::frames(self.name(), FramesDone::default()));
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
                    super::settings_text(&self.options, scene),
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
                    let at = scene.at_time(effects.frame_time(i));
                    let rendered = self.render_region_as(&at, Region::All, pixels, &|_, _| {});
                    // Frames already handed over are still written whole
                    // (the queue's drop waits for them).
                    let mut output = rendered.map_err(|e| e.in_frame(i))?;
                    if output.validation_messages > 0 {
                        return Err(Error::Validation(output.validation_messages).in_frame(i));
                    }
                    watch.frame(i, Some(&output));
                    done.render_timings.extend(&output.timings);
                    let empty = Image::Float(Framebuffer {
                        width: 0,
                        height: 0,
                        pixels: Vec::new(),
                    });
                    let image = std::mem::replace(&mut output.image, empty);
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
        let mut out = Done::frames(self.name(), done);
        if let Some(output) = last_output {
            let timings = out.output.timings.clone();
            out.output = RenderOutput { timings, ..output };
        }
        Ok(out)
    }
}
