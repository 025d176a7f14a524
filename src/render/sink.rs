//! Where a job's image goes: kept in memory, an image file (written
//! atomically, encoded as its extension says), a part file for `glint
//! stitch`, or PNG on standard output.

use std::path::{Path, PathBuf};

use super::job::Target;
use super::options::PixelFormat;
use crate::images::encode::EncodeOptions;
use crate::images::framebuffer::{check_output, Image, ImageFile};
use crate::parts::stamp::Stamp;
use crate::timing::Timings;
use crate::Error;

/// Where a job's image goes.
#[derive(Clone, Debug, PartialEq)]
pub enum Sink {
    /// Kept in `Done::output.image`, as floats or 8-bit pixels.
    Memory(PixelFormat),
    /// An image file, its format by its extension (.jpg, .png, .ppm, .exr).
    /// A crop is written as a full-size .png or .exr whose alpha marks its
    /// pixels, a part as its stamped part file beside `path`
    /// (`out.part03-of-16.png`), each for `glint stitch`.
    File {
        /// The image file.
        path: PathBuf,
        /// JPEG quality and PNG compression.
        encode: EncodeOptions,
    },
    /// PNG on standard output (a crop as its part image).
    Stdout(EncodeOptions),
    /// An animation's frames, `000.jpg`, `001.jpg`, ... in `dir` (made
    /// when missing), each written atomically.
    Frames {
        /// The frame directory.
        dir: PathBuf,
        /// The frames' image format.
        format: ImageFile,
        /// JPEG quality and PNG compression.
        encode: EncodeOptions,
    },
}

impl Sink {
    /// An image file with the default encoder settings.
    pub fn file(path: impl Into<PathBuf>) -> Sink {
        Sink::File {
            path: path.into(),
            encode: EncodeOptions::default(),
        }
    }

    /// Whether the sink can take what `target` makes: the file's type and
    /// its directory, checked before any work.
    pub fn check(&self, target: &Target) -> Result<(), Error> {
        let frames_only = || {
            Err(Error::InvalidOption(
                "frames go to a directory (`Sink::Frames`), and a directory holds frames only"
                    .into(),
            ))
        };
        match (self, target) {
            (Sink::Frames { dir, .. }, Target::Frames(_)) => check_frame_dir(dir),
            (Sink::Frames { .. }, _) | (_, Target::Frames(_)) => frames_only(),
            (Sink::Memory(_), _) | (Sink::Stdout(_), Target::Image | Target::Crop(_)) => Ok(()),
            (Sink::Stdout(_), Target::Part(_)) => Err(Error::InvalidOption(
                "--part writes a part file beside OUT for `glint stitch`; name OUT, not `-`".into(),
            )),
            (Sink::File { path, .. }, Target::Image) => check_output(path),
            (Sink::File { path, .. }, Target::Crop(_)) => {
                crate::parts::crop::check_part_format(path)?;
                check_output(path)
            }
            (Sink::File { path, .. }, Target::Part(p)) => {
                ImageFile::of(path)?;
                check_output(&crate::parts::part_path(path, p.index, p.count))
            }
        }
    }

    /// Writes `image`, adding `encode` and `write` to `timings`; returns
    /// the path written.
    pub(super) fn write(
        &self,
        image: &Image,
        target: &Target,
        stamp: Option<&Stamp>,
        timings: &mut Timings,
    ) -> Result<Option<PathBuf>, Error> {
        let (path, encode) = match self {
            Sink::Memory(_) | Sink::Frames { .. } => return Ok(None),
            Sink::File { path, encode } => (Some(path.as_path()), encode),
            Sink::Stdout(encode) => (None, encode),
        };
        let shown = || path.unwrap_or(Path::new("standard output")).to_path_buf();
        match (target, path) {
            (Target::Crop(c), Some(p)) => {
                let fb = image.to_float();
                timings.time("write", || crate::parts::crop::write_part(&fb, c, p))?;
            }
            (Target::Crop(c), None) => {
                let fb = image.to_float();
                timings.time("write", || crate::parts::crop::write_part_to_stdout(&fb, c))?;
            }
            (Target::Part(p), Some(out)) => {
                let stamp = stamp.ok_or_else(|| {
                    Error::InvalidOption("a part is written with its stamp".into())
                })?;
                let file = crate::parts::part_path(out, p.index, p.count);
                let fb = image.to_float();
                timings.time("write", || {
                    crate::parts::stamp::write_part(&fb, stamp, &file)
                })?;
                return Ok(Some(file));
            }
            // Pairs `check` refuses (a part to standard output; frames go
            // through `Renderer::run_frames`): nothing is written.
            (Target::Part(_), None) | (Target::Frames(_), _) => {
                return self.check(target).map(|()| None)
            }
            (Target::Image, _) => {
                let kind = match path {
                    Some(p) => ImageFile::of(p)?,
                    None => ImageFile::Png,
                };
                let bytes = timings
                    .time("encode", || image.encode(kind, encode))
                    .map_err(|e| Error::WriteImage {
                        path: shown(),
                        error: std::io::Error::other(e),
                    })?;
                timings.time("write", || match path {
                    Some(p) => crate::images::framebuffer::write_bytes(p, &bytes),
                    None => crate::images::framebuffer::write_bytes_to_stdout(&bytes),
                })?;
            }
        }
        Ok(Some(shown()))
    }
}

/// A frame directory: not an image's name, and not a file.
fn check_frame_dir(dir: &Path) -> Result<(), Error> {
    let bad = |reason: &str| {
        Err(Error::BadOutput {
            path: dir.to_path_buf(),
            reason: format!(
                "with --frames, the output is a directory for 000.jpg, 001.jpg, ...; {reason}"
            ),
        })
    };
    if ImageFile::of(dir).is_ok() {
        return bad("this is an image name");
    }
    if dir.exists() && !dir.is_dir() {
        return bad("this is a file");
    }
    Ok(())
}

impl Sink {
    /// What the render should hand back for this sink: the file's own
    /// pixels, or floats where a part file keeps them.
    pub(super) fn pixels(&self, target: &Target) -> PixelFormat {
        match (self, target) {
            (Sink::Memory(p), _) => *p,
            (Sink::Frames { format, .. }, _) => PixelFormat::for_file(*format),
            (_, Target::Crop(_) | Target::Part(_)) => PixelFormat::Float,
            (Sink::Stdout(_), Target::Image | Target::Frames(_)) => PixelFormat::Rgb8,
            (Sink::File { path, .. }, Target::Image | Target::Frames(_)) => {
                crate::images::framebuffer::ImageFile::of(path)
                    .map_or(PixelFormat::Float, PixelFormat::for_file)
            }
        }
    }
}
