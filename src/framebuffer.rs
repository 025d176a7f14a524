//! A rendered image in linear [0, 1] RGB (f32), its 8-bit conversion, and
//! writing it to disk without ever leaving a half-written file.

use std::io::Write;
use std::path::Path;

use image::{ImageFormat, RgbImage};

use crate::Error;

#[derive(Clone, Debug, PartialEq)]
pub struct Framebuffer {
    pub width: u32,
    pub height: u32,
    /// Row-major, row 0 at the top.
    pub pixels: Vec<[f32; 3]>,
}

/// The image convention's 8-bit value: `v * 255` rounded (half away from
/// zero, as C's `round`), after clamping to [0, 1]; no gamma.
pub fn to_u8(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

impl Framebuffer {
    pub fn to_rgb8(&self) -> RgbImage {
        let bytes = self.pixels.iter().flat_map(|p| p.map(to_u8)).collect();
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

/// JPEG quality used when the caller does not choose one.
pub const DEFAULT_JPEG_QUALITY: u8 = 95;

/// Writes `img` as PNG or JPEG (chosen by the extension: .png, .jpg, .jpeg).
///
/// The image goes to a temporary file in the same directory, which is then
/// renamed over `path`: an interrupted or failed write never leaves a
/// half-written image or clobbers a good one.
pub fn write_image(img: &RgbImage, path: &Path, jpeg_quality: u8) -> Result<(), Error> {
    let format = image_format(path)?;
    let wrap = |source: std::io::Error| Error::WriteImage {
        path: path.to_path_buf(),
        source,
    };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut tmp = tempfile::Builder::new()
        .prefix(".glint-")
        .suffix(".part")
        .tempfile_in(dir)
        .map_err(wrap)?;
    let _registered = PartialFile::register(tmp.path());
    {
        let mut w = std::io::BufWriter::new(tmp.as_file_mut());
        let encoded = match format {
            ImageFormat::Jpeg => img.write_with_encoder(
                image::codecs::jpeg::JpegEncoder::new_with_quality(&mut w, jpeg_quality),
            ),
            _ => img.write_with_encoder(image::codecs::png::PngEncoder::new(&mut w)),
        };
        encoded.map_err(|e| wrap(std::io::Error::other(e)))?;
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
    fn register(path: &Path) -> PartialFile {
        let mut files = PARTIAL_FILES.lock().unwrap_or_else(|e| e.into_inner());
        files.push(path.to_path_buf());
        PartialFile(path.to_path_buf())
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

fn image_format(path: &Path) -> Result<ImageFormat, Error> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("png") => Ok(ImageFormat::Png),
        Some("jpg" | "jpeg") => Ok(ImageFormat::Jpeg),
        _ => Err(Error::UnsupportedImageFormat(path.to_path_buf())),
    }
}

/// Reads a PNG or JPEG as 8-bit RGB.
pub fn read_image(path: &Path) -> Result<RgbImage, Error> {
    let img = image::open(path).map_err(|e| Error::ReadImage {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    Ok(img.to_rgb8())
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
    }
}
