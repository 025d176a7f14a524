//! A render as one value and one call: a `Job` says what to render and
//! when to stop, a `Sink` where the image goes, and `Renderer::run` carries
//! it out. Every command that renders an image builds a `Job`; a project of
//! its own can do the same (`examples/`).

use std::path::{Path, PathBuf};

use super::options::RenderOptions;
use super::output::RenderOutput;
use super::passes::{PassReport, StopAt, Stopped};
use crate::images::framebuffer::ImageFile;
use crate::parts::crop::Crop;
use crate::parts::cut::Span;
use crate::parts::PartOf;
use crate::scene::Scene;
use crate::Error;

/// Which pixels of the image a job renders.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// Every pixel.
    Image,
    /// Only the pixels inside the rectangle, each with the value a full
    /// render gives it; the others are 0.
    Crop(Crop),
    /// One task's share of a render spread over machines (`parts`), cut
    /// alike by every task from the same scene and settings.
    Part(PartOf),
    /// An animation's frames, each a whole image, into a directory
    /// (`Sink::Frames`).
    Frames(Frames),
}

/// When a job is done.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Stop {
    /// One render of the scene's samples per pixel.
    Once,
    /// Passes of the scene's samples per pixel, each with its own seed,
    /// until the rule says stop (`progressive`).
    Passes(StopAt),
}

/// What to render of a scene, and when to stop.
#[derive(Clone, Copy, Debug)]
pub struct Job<'a> {
    /// The scene to render.
    pub scene: &'a Scene,
    /// Which pixels, or frames.
    pub target: Target,
    /// Once, or passes until a rule says stop.
    pub stop: Stop,
}

impl<'a> Job<'a> {
    /// The whole image, rendered once.
    pub fn new(scene: &'a Scene) -> Job<'a> {
        Job {
            scene,
            target: Target::Image,
            stop: Stop::Once,
        }
    }

    /// Only the pixels of `crop`.
    pub fn crop(self, crop: Crop) -> Job<'a> {
        Job {
            target: Target::Crop(crop),
            ..self
        }
    }

    /// The frames `frames` says.
    pub fn frames(self, frames: Frames) -> Job<'a> {
        Job {
            target: Target::Frames(frames),
            ..self
        }
    }

    /// Part `part.index` of `part.count`.
    pub fn part(self, part: PartOf) -> Job<'a> {
        Job {
            target: Target::Part(part),
            ..self
        }
    }

    /// In passes until `stop` says so.
    pub fn until(self, stop: StopAt) -> Job<'a> {
        Job {
            stop: Stop::Passes(stop),
            ..self
        }
    }

    /// What a part file records of the render it belongs to: the scene and
    /// every setting that decides its pixels. The backend is not in it: a
    /// part from a GPU and one from the CPU reference belong to one render
    /// (`glint stitch` says when they are mixed).
    pub fn digest(&self, options: &RenderOptions) -> String {
        crate::parts::stamp::render_digest(self.scene, &settings_text(options, self.scene))
    }

    /// Settings a job cannot have, found before any work.
    pub(super) fn check(&self, options: &RenderOptions) -> Result<(), Error> {
        let (w, h) = (options.width, options.height);
        match (self.target, self.stop) {
            (Target::Crop(c), _) => c.check(w, h)?,
            (Target::Part(p), _) => {
                if u64::from(p.count) > u64::from(w) * u64::from(h) || p.index >= p.count {
                    return Err(Error::InvalidOption(format!(
                        "part {} of {}: a {w}x{h} image has {} pixels, and each part holds one at least",
                        p.index,
                        p.count,
                        u64::from(w) * u64::from(h)
                    )));
                }
            }
            (Target::Frames(f), _) => {
                f.share()?;
            }
            (Target::Image, _) => {}
        }
        if let (Target::Crop(_) | Target::Part(_) | Target::Frames(_), Stop::Passes(_)) =
            (self.target, self.stop)
        {
            return Err(Error::InvalidOption(
                "progressive passes render one whole image; a crop, a part or frames are rendered once"
                    .into(),
            ));
        }
        Ok(())
    }
}

/// Everything beside the scene that decides a render's pixels.
pub fn settings_text(options: &RenderOptions, scene: &Scene) -> String {
    format!(
        "{}x{} background {:?} precision {:?} methods {:?} effects {:?}",
        options.width,
        options.height,
        options.background.map(f32::to_bits),
        options.precision,
        options.methods,
        options.effects(scene)
    )
}

/// Who hears how a job goes; every method does nothing unless overridden.
pub trait Watch: Sync {
    /// Pixels (GPU) or rows (CPU) finished of a render: `done` of `total`.
    fn progress(&self, _done: u64, _total: u64) {}
    /// A progressive pass finished.
    fn pass(&self, _report: &PassReport) {}
    /// Frame `index` was rendered (its output, before its image goes to
    /// the writers), or was already there and is kept (`None`).
    fn frame(&self, _index: u32, _output: Option<&RenderOutput>) {}
    /// Frames written so far (on the writers, behind the renders).
    fn frames_written(&self, _count: u32) {}
}

/// Hears nothing.
pub struct Quiet;

impl Watch for Quiet {}

/// What a progressive job's passes came to.
#[derive(Clone, Debug)]
pub struct Passes {
    /// The last pass's report.
    pub report: PassReport,
    /// Why the passes stopped.
    pub stopped: Stopped,
    /// Every pass's report, in order.
    pub history: Vec<PassReport>,
}

/// A job carried out.
pub struct Done {
    /// The image (as the sink asked for it) and how it was made; its
    /// timings include `encode` and `write` where the sink wrote a file.
    pub output: RenderOutput,
    /// Where the image was written: the file, or the part file beside it;
    /// `None` for a memory sink.
    pub written: Option<PathBuf>,
    /// A part's pixels, in the image's row-major order.
    pub span: Option<Span>,
    /// A progressive job's passes.
    pub passes: Option<Passes>,
    /// An animation's frames.
    pub frames: Option<FramesDone>,
}

/// What an animation job did.
#[derive(Clone, Debug, Default)]
pub struct FramesDone {
    /// The first frame it was to render; `first`, `last` and every count
    /// are 0 where a part had no frame to render.
    pub first: u32,
    /// The last frame to render (inclusive).
    pub last: u32,
    /// Frames this job made, not kept: rendered, or (a scene with no
    /// motion) the one image rendered for them all.
    pub rendered: u32,
    /// Frames written by this job.
    pub written: u32,
    /// Frames already there whole, kept (a requeued task of an array).
    pub kept: u32,
    /// The renders' timings, summed over the frames.
    pub render_timings: crate::timing::Timings,
    /// The writers' encode and write times, summed over them.
    pub write_timings: crate::timing::Timings,
}

impl Done {
    /// An animation's result: `output` is the last frame rendered (`last`;
    /// a default one where every frame was kept) with the renders' summed
    /// timings; its image is empty (0x0), as the frames are in their files.
    pub(super) fn frames(renderer: String, frames: FramesDone, last: Option<RenderOutput>) -> Done {
        let empty = crate::images::framebuffer::Image::Float(Default::default());
        let output = match last {
            Some(last) => RenderOutput {
                image: empty,
                timings: frames.render_timings.clone(),
                ..last
            },
            None => RenderOutput {
                image: empty,
                timings: frames.render_timings.clone(),
                renderer,
                note: None,
                validation_messages: 0,
                memory: Default::default(),
                bvh: Default::default(),
                samples: 0,
            },
        };
        Done {
            output,
            written: None,
            span: None,
            passes: None,
            frames: Some(frames),
        }
    }
}

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
