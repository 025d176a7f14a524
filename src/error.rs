//! The library's error type. Every variant says what failed and where; the
//! CLI maps them to exit codes (`Error::exit_code`).

use std::path::PathBuf;

use crate::gpu::GpuError;
use crate::scene::ParseError;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    // The I/O error is part of the message, not a `source`: a source is
    // printed again by every error reporter that walks the chain.
    #[error("cannot read scene file {path}: {error}")]
    ReadScene {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error(transparent)]
    Parse(#[from] ParseError),
    /// Input refused before it could be parsed: binary data where a scene
    /// was expected, or a stream past `--max-input`.
    #[error("{path}: {error}")]
    Input {
        path: PathBuf,
        error: crate::input::InputError,
    },
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Model(#[from] crate::mesh::MeshError),
    #[error("cannot write image {path}: {error}")]
    WriteImage {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("cannot read image {path}: {message}")]
    ReadImage { path: PathBuf, message: String },
    #[error("{0}: unsupported image type; use a .png, .jpg, .jpeg, .ppm or .exr file name")]
    UnsupportedImageFormat(PathBuf),
    #[error("images differ in size: {0}x{1} vs {2}x{3}")]
    SizeMismatch(u32, u32, u32, u32),
    #[error("cannot write {path}: {error}")]
    WriteFile {
        path: PathBuf,
        error: std::io::Error,
    },
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
    #[error("cannot write {path}: {reason}")]
    BadOutput { path: PathBuf, reason: String },
    /// The renderer's cancel flag was set mid-render
    /// (`Renderer::set_cancel`); nothing of the render is returned.
    #[error("the render was cancelled before it finished")]
    Cancelled,
    /// What failed in frame `index` of an animation.
    #[error("frame {index}: {error}")]
    Frame { index: u32, error: Box<Error> },
    /// A job's image is not written when the validation layer spoke.
    #[error(
        "the Vulkan validation layer reported {0} message(s) (printed above); \
         the result may be wrong, so nothing was written. Please report this with the scene"
    )]
    Validation(u32),
    #[error("the Embree harness {harness} failed on {scene}: {reason}")]
    Harness {
        harness: PathBuf,
        scene: PathBuf,
        reason: String,
    },
    #[error(
        "this render needs about {parts} of memory, but {} is available; nothing was rendered: \
         render a smaller image (--width/--height), or free memory",
        crate::memory::human(*available)
    )]
    OutOfMemory {
        needed: u64,
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
