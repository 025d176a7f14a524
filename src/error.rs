//! The library's error type. Every variant says what failed and where; the
//! CLI maps them to exit codes (`Error::exit_code`).

use std::path::PathBuf;

use crate::gpu::GpuError;
use crate::scene::ParseError;

/// What went wrong, and where; `exit_code` is the command line's code for it.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    // The I/O error is part of the message, not a `source`: a source is
    // printed again by every error reporter that walks the chain.
    /// A scene file could not be read.
    #[error("cannot read scene file {path}: {error}")]
    ReadScene {
        /// The file.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// A scene file is malformed: its `file:line:col` and what to do.
    #[error(transparent)]
    Parse(#[from] ParseError),
    /// Input refused before it could be parsed: binary data where a scene
    /// was expected, or a stream past `--max-input`.
    #[error("{path}: {error}")]
    Input {
        /// The input (a file, `<stdin>`).
        path: PathBuf,
        /// Why it was refused.
        error: crate::input::InputError,
    },
    /// The Vulkan device failed, or none is usable.
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// A model file (OBJ, PLY, OFF, STL, glTF) is malformed: its line, byte
    /// or JSON path.
    #[error(transparent)]
    Model(#[from] crate::mesh::MeshError),
    /// An image could not be encoded or written.
    #[error("cannot write image {path}: {error}")]
    WriteImage {
        /// The image file.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// An image could not be read or decoded.
    #[error("cannot read image {path}: {message}")]
    ReadImage {
        /// The image file.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// A file name whose extension names no image type glint writes.
    #[error("{0}: unsupported image type; use a .png, .jpg, .jpeg, .ppm or .exr file name")]
    UnsupportedImageFormat(PathBuf),
    /// Two images to compare differ in size: the first's width and height,
    /// then the second's.
    #[error("images differ in size: {0}x{1} vs {2}x{3}")]
    SizeMismatch(u32, u32, u32, u32),
    /// A file other than an image could not be written.
    #[error("cannot write {path}: {error}")]
    WriteFile {
        /// The file.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// Settings that cannot go together, or a value out of range, found
    /// before any work.
    #[error("invalid option: {0}")]
    InvalidOption(String),
    /// No window could open: no display, or the display refused.
    #[error(
        "cannot open a window: {0}; set DISPLAY (X11) or WAYLAND_DISPLAY, or render to a file \
         with `glint render SCENE OUT`"
    )]
    NoWindow(String),
    /// Parts that cannot be stitched into one image: missing or of
    /// different renders.
    #[error("cannot stitch: {0}")]
    Parts(String),
    /// An output that cannot be written as asked, found before any work.
    #[error("cannot write {path}: {reason}")]
    BadOutput {
        /// The output.
        path: PathBuf,
        /// Why, and what to do.
        reason: String,
    },
    /// The renderer's cancel flag was set mid-render
    /// (`Renderer::set_cancel`); nothing of the render is returned.
    #[error("the render was cancelled before it finished")]
    Cancelled,
    /// What failed in frame `index` of an animation.
    #[error("frame {index}: {error}")]
    Frame {
        /// The frame, counted from 0.
        index: u32,
        /// What failed.
        error: Box<Error>,
    },
    /// A job's image is not written when the validation layer spoke.
    #[error(
        "the Vulkan validation layer reported {0} message(s) (printed above); \
         the result may be wrong, so nothing was written. Please report this with the scene"
    )]
    Validation(u32),
    /// A program a benchmark runs failed: `glint bench embree`'s Embree
    /// harness, or glint itself for `glint bench`'s end-to-end times.
    #[error("{harness} failed on {scene}: {reason}")]
    Harness {
        /// The harness program.
        harness: PathBuf,
        /// The scene it was given.
        scene: PathBuf,
        /// What it said, or why nothing came.
        reason: String,
    },
    /// A render would need more host memory than there is; nothing was
    /// rendered.
    #[error(
        "this render needs about {parts} of memory, but {} is available; nothing was rendered: \
         render a smaller image (--width/--height), or free memory",
        crate::memory::human(*available)
    )]
    OutOfMemory {
        /// Bytes it needs.
        needed: u64,
        /// Bytes available (memory and the cgroup's limit).
        available: u64,
        /// The need, part by part (`MemoryNeed`'s display).
        parts: String,
    },
}

impl Error {
    /// 2: bad input (a scene file or image missing or malformed, an invalid
    /// option, an output that cannot be written, found before any work);
    /// 3: no usable Vulkan device; 1: anything else.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::ReadScene { .. }
            | Error::Parse(_)
            | Error::Input { .. }
            | Error::Model(_)
            | Error::ReadImage { .. }
            | Error::UnsupportedImageFormat(_)
            | Error::SizeMismatch(..)
            | Error::InvalidOption(_)
            | Error::NoWindow(_)
            | Error::Parts(_)
            | Error::BadOutput { .. } => 2,
            Error::Gpu(GpuError::Loader(_) | GpuError::NoDevice | GpuError::DeviceNotFound(_)) => 3,
            Error::Frame { error, .. } => error.exit_code(),
            _ => 1,
        }
    }

    /// This error, as frame `index`'s.
    pub fn in_frame(self, index: u32) -> Error {
        Error::Frame {
            index,
            error: Box::new(self),
        }
    }
}
