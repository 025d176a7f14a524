//! A rendered image in linear [0, 1] RGB (f32), its 8-bit conversion, and
//! reading and writing it (PNG, JPEG, PPM, float EXR) without ever leaving a
//! half-written file.

use std::io::Write;
use std::path::Path;

use image::{DynamicImage, RgbImage};

use crate::Error;

/// A float image: linear RGB per pixel, unclamped as rendered.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Framebuffer {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major, row 0 at the top.
    pub pixels: Vec<[f32; 3]>,
}

/// The image convention's 8-bit value: `v * 255` rounded (half away from
/// zero, as C's `round`), after clamping to [0, 1]; no gamma.
#[inline]
// `clamp` keeps NaN, which the unchecked conversion below must never see.
#[allow(clippy::manual_clamp)]
pub fn to_u8(v: f32) -> u8 {
    // The whole part plus one where the fraction is at least a half: C's
    // round of a non-negative y, with `y - t` exact (checked against
    // `f32::round` for every f32 in [0, 1]). Written so that it
    // vectorises: with `round` and saturating casts, 1080p's conversion
    // took 9.4 ms on 2 cores. `max` then `min` map NaN to 0.
    let y = v.max(0.0).min(1.0) * 255.0;
    // SAFETY: y is finite and in [0, 255], which i32 holds.
    let t: i32 = unsafe { y.to_int_unchecked() };
    (t + i32::from(y - t as f32 >= 0.5)) as u8
}

impl Framebuffer {
    /// The 8-bit image (`to_u8` of every channel), converted on every
    /// core: at 1080p a serial pass took 17 ms, longer than PNG's encode.
    pub fn to_rgb8(&self) -> RgbImage {
        use rayon::prelude::*;
        // Channel by channel over flat slices: a one-to-one map that
        // vectorises, where a loop over [f32; 3] pixels did not.
        let values: &[f32] = bytemuck::cast_slice(&self.pixels);
        let mut bytes = vec![0u8; values.len()];
        bytes
            .par_chunks_mut(3 * 4096)
            .zip(values.par_chunks(3 * 4096))
            .for_each(|(out, values)| {
                for (o, &v) in out.iter_mut().zip(values) {
                    *o = to_u8(v);
                }
            });
        RgbImage::from_raw(self.width, self.height, bytes)
            .expect("pixel count matches width * height")
    }

    /// How many pixels hold NaN or infinity in any channel.
    pub fn non_finite_count(&self) -> usize {
        self.pixels
            .iter()
            .filter(|p| p.iter().any(|c| !c.is_finite()))
            .count()
    }
}

pub use crate::images::encode::DEFAULT_JPEG_QUALITY;
use crate::images::encode::{EncodeOptions, Pixels};

pub use crate::images::encode::ImageFile;

/// A finished image as a sink takes it: float values, or the 8-bit
/// pixels a device (or the CPU reference's threads) already converted
/// (`Framebuffer::to_rgb8`'s values) for an 8-bit file.
#[derive(Clone, Debug, PartialEq)]
pub enum Image {
    /// Linear f32 RGB, as rendered.
    Float(Framebuffer),
    /// 8-bit RGB, `to_u8` of each channel.
    Rgb8(RgbImage),
}

impl Image {
    /// Width in pixels.
    pub fn width(&self) -> u32 {
        match self {
            Image::Float(fb) => fb.width,
            Image::Rgb8(img) => img.width(),
        }
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        match self {
            Image::Float(fb) => fb.height,
            Image::Rgb8(img) => img.height(),
        }
    }

    /// The float image: itself, or 8-bit values v / 255 (what reading the
    /// 8-bit file back gives).
    pub fn to_float(&self) -> std::borrow::Cow<'_, Framebuffer> {
        match self {
            Image::Float(fb) => std::borrow::Cow::Borrowed(fb),
            Image::Rgb8(img) => std::borrow::Cow::Owned(Framebuffer {
                width: img.width(),
                height: img.height(),
                pixels: img
                    .pixels()
                    .map(|p| p.0.map(|c| f32::from(c) / 255.0))
                    .collect(),
            }),
        }
    }

    /// The float image, without a copy where it is one.
    pub fn into_float(self) -> Framebuffer {
        match self {
            Image::Float(fb) => fb,
            image => image.to_float().into_owned(),
        }
    }

    /// The 8-bit image (`Framebuffer::to_rgb8` of a float one).
    pub fn to_rgb8(&self) -> std::borrow::Cow<'_, RgbImage> {
        match self {
            Image::Float(fb) => std::borrow::Cow::Owned(fb.to_rgb8()),
            Image::Rgb8(img) => std::borrow::Cow::Borrowed(img),
        }
    }

    /// The bytes of a `kind` file: float values for EXR (8-bit ones as
    /// v / 255), else the 8-bit conversion.
    pub fn encode(&self, kind: ImageFile, options: &EncodeOptions) -> Result<Vec<u8>, String> {
        match self {
            Image::Float(fb) => encode_framebuffer(fb, kind, options),
            Image::Rgb8(img) => encode_rgb8(img, kind, options),
        }
    }
}

/// Writes a render: as float values for .exr, else its 8-bit conversion as
/// PNG, JPEG or PPM.
pub fn write_framebuffer(fb: &Framebuffer, path: &Path, jpeg_quality: u8) -> Result<(), Error> {
    let kind = ImageFile::of(path)?;
    let bytes = encode_framebuffer(fb, kind, &EncodeOptions::with_quality(jpeg_quality))
        .map_err(|e| encode_error(path, e))?;
    write_bytes(path, &bytes)
}

/// `Image::encode` of a borrowed float image.
pub fn encode_framebuffer(
    fb: &Framebuffer,
    kind: ImageFile,
    options: &EncodeOptions,
) -> Result<Vec<u8>, String> {
    if kind.is_float() {
        let pixels = Pixels {
            bytes: bytemuck::cast_slice(&fb.pixels),
            width: fb.width,
            height: fb.height,
            color: image::ExtendedColorType::Rgb32F,
        };
        return crate::images::encode::encode(pixels, kind, options);
    }
    encode_rgb8(&fb.to_rgb8(), kind, options)
}

/// `Image::encode` of a borrowed 8-bit image (as floats v / 255 for EXR).
pub fn encode_rgb8(
    img: &RgbImage,
    kind: ImageFile,
    options: &EncodeOptions,
) -> Result<Vec<u8>, String> {
    if kind.is_float() {
        return encode_framebuffer(&Image::Rgb8(img.clone()).to_float(), kind, options);
    }
    crate::images::encode::encode(
        Pixels {
            bytes: img.as_raw(),
            width: img.width(),
            height: img.height(),
            color: image::ExtendedColorType::Rgb8,
        },
        kind,
        options,
    )
}

fn encode_error(path: &Path, message: String) -> Error {
    Error::WriteImage {
        path: path.to_path_buf(),
        error: std::io::Error::other(message),
    }
}

/// Writes a render to standard output as `kind` (`glint render S -`).
pub fn write_framebuffer_to_stdout(
    fb: &Framebuffer,
    kind: ImageFile,
    jpeg_quality: u8,
) -> Result<(), Error> {
    let bytes = encode_framebuffer(fb, kind, &EncodeOptions::with_quality(jpeg_quality))
        .map_err(|e| encode_error(Path::new("<standard output>"), e))?;
    write_bytes_to_stdout(&bytes)
}

/// Writes encoded bytes to standard output.
pub fn write_bytes_to_stdout(bytes: &[u8]) -> Result<(), Error> {
    let wrap = |error: std::io::Error| Error::WriteImage {
        path: "<standard output>".into(),
        error,
    };
    let mut out = std::io::stdout().lock();
    out.write_all(bytes).map_err(wrap)?;
    out.flush().map_err(wrap)
}

/// Writes encoded bytes to `path` atomically (`write_atomically`).
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    write_atomically(path, |w| w.write_all(bytes))
}

/// Writes `img` as PNG, JPEG, PPM or EXR, chosen by the extension (.exr
/// stores 8-bit values v / 255 as floats).
pub fn write_image(img: &RgbImage, path: &Path, jpeg_quality: u8) -> Result<(), Error> {
    let kind = ImageFile::of(path)?;
    let bytes = encode_rgb8(img, kind, &EncodeOptions::with_quality(jpeg_quality))
        .map_err(|e| encode_error(path, e))?;
    write_bytes(path, &bytes)
}

/// Writes any image (RGB or RGBA, 8-bit or float) in the format `path`'s
/// extension names, converting where the format needs it.
pub(crate) fn write_dynamic(
    img: &DynamicImage,
    path: &Path,
    jpeg_quality: u8,
) -> Result<(), Error> {
    let kind = ImageFile::of(path)?;
    let bytes = encode_dynamic(img, kind, jpeg_quality).map_err(|e| encode_error(path, e))?;
    write_bytes(path, &bytes)
}

/// As `write_dynamic`, to standard output.
pub(crate) fn write_dynamic_to_stdout(
    img: &DynamicImage,
    kind: ImageFile,
    jpeg_quality: u8,
) -> Result<(), Error> {
    let bytes = encode_dynamic(img, kind, jpeg_quality)
        .map_err(|e| encode_error(Path::new("<standard output>"), e))?;
    write_bytes_to_stdout(&bytes)
}

fn encode_dynamic(
    img: &DynamicImage,
    kind: ImageFile,
    jpeg_quality: u8,
) -> Result<Vec<u8>, String> {
    use std::borrow::Cow;
    // Converted only when the format needs another pixel type.
    let converted: Cow<'_, DynamicImage> = match (kind, img) {
        (ImageFile::Exr, DynamicImage::ImageRgb32F(_) | DynamicImage::ImageRgba32F(_)) => {
            Cow::Borrowed(img)
        }
        (ImageFile::Exr, _) if img.color().has_alpha() => Cow::Owned(img.to_rgba32f().into()),
        (ImageFile::Exr, _) => Cow::Owned(img.to_rgb32f().into()),
        (ImageFile::Png, DynamicImage::ImageRgb8(_) | DynamicImage::ImageRgba8(_)) => {
            Cow::Borrowed(img)
        }
        (ImageFile::Png, _) if img.color().has_alpha() => Cow::Owned(img.to_rgba8().into()),
        (_, DynamicImage::ImageRgb8(_)) => Cow::Borrowed(img),
        _ => Cow::Owned(img.to_rgb8().into()),
    };
    let pixels = Pixels {
        bytes: converted.as_bytes(),
        width: converted.width(),
        height: converted.height(),
        color: converted.color().into(),
    };
    crate::images::encode::encode(pixels, kind, &EncodeOptions::with_quality(jpeg_quality))
}

/// Checks, before any work, that an image can be written at `path`: a
/// known extension, not a directory, in a directory that exists and takes
/// new files (a probe file is created and removed).
pub fn check_output(path: &Path) -> Result<(), Error> {
    if !path.is_dir() {
        ImageFile::of(path)?;
    }
    check_writable(path)
}

/// Checks, before any work, that a file can be written at `path`: not a
/// directory, in a directory that exists and takes new files (a probe file
/// is created and removed).
pub fn check_writable(path: &Path) -> Result<(), Error> {
    let bad = |reason: String| Error::BadOutput {
        path: path.to_path_buf(),
        reason,
    };
    if path.is_dir() {
        return Err(bad(format!(
            "it is a directory; name an image file, e.g. {}",
            path.join("out.png").display()
        )));
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(bad(format!(
            "the directory {} does not exist; create it first",
            dir.display()
        )));
    }
    tempfile::Builder::new()
        .prefix(".glint-probe-")
        .tempfile_in(dir)
        .map(drop)
        .map_err(|e| {
            bad(format!(
                "the directory {} does not take new files ({e})",
                dir.display()
            ))
        })
}

pub(crate) type FileSink<'a> = std::io::BufWriter<&'a mut std::fs::File>;

/// Runs `encode` into a temporary file in `path`'s directory, which is then
/// renamed over `path`: an interrupted or failed write never leaves a
/// half-written image or clobbers a good one.
pub(crate) fn write_atomically(
    path: &Path,
    encode: impl FnOnce(&mut FileSink<'_>) -> std::io::Result<()>,
) -> Result<(), Error> {
    let wrap = |error: std::io::Error| Error::WriteImage {
        path: path.to_path_buf(),
        error,
    };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let (mut tmp, _registered) = PartialFile::create_in(dir).map_err(wrap)?;
    {
        let mut w = std::io::BufWriter::new(tmp.as_file_mut());
        encode(&mut w).map_err(wrap)?;
        w.flush().map_err(wrap)?;
    }
    tmp.as_file().sync_all().map_err(wrap)?;
    // Temporary files are created owner-only; give the image the mode the
    // file it replaces had, or the usual 0644 for a new one.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(path).map_or(0o644, |m| m.permissions().mode() & 0o7777);
        tmp.as_file()
            .set_permissions(std::fs::Permissions::from_mode(mode))
            .map_err(wrap)?;
    }
    tmp.persist(path).map_err(|e| wrap(e.error))?;
    Ok(())
}

/// Temporary files being written right now, so that a signal handler can
/// remove them (`remove_partial_files`): a drop never runs when a signal
/// ends the process.
static PARTIAL_FILES: std::sync::Mutex<Vec<std::path::PathBuf>> = std::sync::Mutex::new(Vec::new());

struct PartialFile(std::path::PathBuf);

impl PartialFile {
    /// A new temporary file in `dir`, listed. It is created with the list
    /// locked: a signal's handler (on its own thread) that comes while the
    /// file exists but is not yet listed waits for the lock and then finds
    /// it, where it used to miss it and leave it behind.
    fn create_in(dir: &Path) -> std::io::Result<(tempfile::NamedTempFile, PartialFile)> {
        let mut files = PARTIAL_FILES.lock().unwrap_or_else(|e| e.into_inner());
        let tmp = tempfile::Builder::new()
            .prefix(".glint-")
            .suffix(".part")
            .tempfile_in(dir)?;
        files.push(tmp.path().to_path_buf());
        let listed = PartialFile(tmp.path().to_path_buf());
        Ok((tmp, listed))
    }
}

impl Drop for PartialFile {
    fn drop(&mut self) {
        let mut files = PARTIAL_FILES.lock().unwrap_or_else(|e| e.into_inner());
        files.retain(|p| p != &self.0);
    }
}

/// Removes every image file still being written; for a SIGINT/SIGTERM
/// handler, which then exits.
pub fn remove_partial_files() {
    let files = PARTIAL_FILES.lock().unwrap_or_else(|e| e.into_inner());
    for p in files.iter() {
        let _ = std::fs::remove_file(p);
    }
}

/// Reads a PNG, JPEG, PPM or EXR as 8-bit RGB (EXR values clamped and rounded
/// as the image convention says).
pub fn read_image(path: &Path) -> Result<RgbImage, Error> {
    if ImageFile::of(path)?.is_float() {
        return Ok(read_framebuffer(path)?.to_rgb8());
    }
    Ok(open(path)?.to_rgb8())
}

/// Reads a PNG, JPEG, PPM or EXR as linear float RGB (8-bit values v / 255).
pub fn read_framebuffer(path: &Path) -> Result<Framebuffer, Error> {
    ImageFile::of(path)?;
    let img = open(path)?.to_rgb32f();
    Ok(Framebuffer {
        width: img.width(),
        height: img.height(),
        pixels: img.pixels().map(|p| p.0).collect(),
    })
}

/// Reads and decodes an image file with bounded memory: its bytes under
/// `--max-input` (a FIFO or device never reads forever), its decoded size
/// under what the largest render (16384 x 16384 RGBA f32) needs.
pub fn open(path: &Path) -> Result<image::DynamicImage, Error> {
    let bytes = crate::input::read_path(path, crate::input::Kind::Binary).map_err(|e| {
        Error::ReadImage {
            path: path.to_path_buf(),
            message: e.to_string(),
        }
    })?;
    decode_image(&bytes, path)
}

/// Decodes an image held in memory; the format is the one `path`'s
/// extension names, else the one its bytes start with.
pub fn decode_image(bytes: &[u8], path: &Path) -> Result<image::DynamicImage, Error> {
    const MAX_EDGE: u32 = 16384;
    let error = |e: image::ImageError| Error::ReadImage {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes));
    match image::ImageFormat::from_path(path) {
        Ok(format) => reader.set_format(format),
        Err(_) => reader = reader.with_guessed_format().map_err(|e| error(e.into()))?,
    }
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_EDGE);
    limits.max_image_height = Some(MAX_EDGE);
    limits.max_alloc = Some(u64::from(MAX_EDGE) * u64::from(MAX_EDGE) * 16 + (64 << 20));
    reader.limits(limits);
    reader.decode().map_err(error)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_is_half_away_from_zero() {
        // 0.5/255 scales to exactly 0.5 in f32 arithmetic here.
        assert_eq!(to_u8(0.5 / 255.0), 1);
        assert_eq!(to_u8(-1.0), 0);
        assert_eq!(to_u8(2.0), 255);
        assert_eq!(to_u8(0.3), 77); // 76.5 -> 77
        assert_eq!(to_u8(f32::NAN), 0);
    }

    /// Equal to C's round of `v * 255` (clamped) at and around every
    /// rounding edge: the f32s within 64 ulps of (n + 0.5) / 255, and of
    /// n + 0.5 after the scaling, for every level n.
    #[test]
    fn to_u8_is_c_round_at_every_edge() {
        let c_round = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
        for n in 0..255u32 {
            for centre in [(n as f32 + 0.5) / 255.0, n as f32 + 0.5] {
                let bits = centre.to_bits();
                for b in bits - 64..=bits + 64 {
                    let v = f32::from_bits(b);
                    assert_eq!(to_u8(v), c_round(v), "{v:e}");
                    assert_eq!(to_u8(v / 255.0), c_round(v / 255.0), "{v:e} / 255");
                }
            }
        }
    }

    /// EXR keeps every float bit, values beyond [0, 1] included; PNG keeps
    /// the 8-bit conversion.
    #[test]
    fn exr_round_trips_floats_and_png_rounds() {
        let dir = tempfile::tempdir().expect("temp dir");
        let fb = Framebuffer {
            width: 3,
            height: 2,
            pixels: vec![
                [0.0, 1.0, 0.5],
                [0.123_456_79, 1e-7, 0.999_999],
                [2.5, -0.25, 0.3],
                [1.0 / 3.0, 0.7, 0.1],
                [0.0; 3],
                [1.0; 3],
            ],
        };
        let exr = dir.path().join("a.EXR");
        write_framebuffer(&fb, &exr, 95).expect("write exr");
        assert_eq!(read_framebuffer(&exr).expect("read exr"), fb);
        assert_eq!(read_image(&exr).expect("read exr as 8 bits"), fb.to_rgb8());
        let png = dir.path().join("a.png");
        write_framebuffer(&fb, &png, 95).expect("write png");
        let back = read_framebuffer(&png).expect("read png");
        for (a, b) in fb.pixels.iter().zip(&back.pixels) {
            for c in 0..3 {
                assert_eq!(to_u8(a[c]), to_u8(b[c]), "{a:?} {b:?}");
            }
        }
        let bad = dir.path().join("a.bmp");
        assert!(matches!(
            write_framebuffer(&fb, &bad, 95),
            Err(Error::UnsupportedImageFormat(_))
        ));
        assert!(!bad.exists());
    }
}
