//! Encoding a finished image into the bytes of a file, apart from writing
//! them (`framebuffer::write_atomically`), so that `render -v` shows the two
//! and animations can encode on worker threads. Each format's encoder is
//! the fastest well-kept one measured (`docs/benchmarks.md`, "Writing the
//! image"), or glint's own where none came near: JPEG in strips on every
//! core (`jpeg`: `jpeg-encoder`'s headers, glint's scan), PNG with `png`'s
//! choice of deflate (fdeflate by default), PPM and float EXR through
//! `image`.

pub mod jpeg;

use image::{ExtendedColorType, ImageEncoder};

use std::path::Path;

use crate::Error;

/// JPEG quality used when the caller does not choose one.
pub const DEFAULT_JPEG_QUALITY: u8 = 95;

/// The image files glint reads and writes, by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFile {
    /// PNG: 8-bit RGB, lossless.
    Png,
    /// JPEG: 8-bit RGB, 4:4:4, at a quality.
    Jpeg,
    /// OpenEXR: linear f32 RGB, no quantization.
    Exr,
    /// Binary PPM (P6), the course starter code's format.
    Ppm,
}

impl ImageFile {
    /// The kind `path`'s extension names (case-insensitive).
    pub fn of(path: &Path) -> Result<ImageFile, Error> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("png") => Ok(ImageFile::Png),
            Some("jpg" | "jpeg") => Ok(ImageFile::Jpeg),
            Some("exr") => Ok(ImageFile::Exr),
            Some("ppm") => Ok(ImageFile::Ppm),
            _ => Err(Error::UnsupportedImageFormat(path.to_path_buf())),
        }
    }

    /// The extension glint writes it with.
    pub fn extension(self) -> &'static str {
        match self {
            ImageFile::Png => "png",
            ImageFile::Jpeg => "jpg",
            ImageFile::Exr => "exr",
            ImageFile::Ppm => "ppm",
        }
    }

    /// Whether it keeps float values (else 8 bits per channel).
    pub fn is_float(self) -> bool {
        self == ImageFile::Exr
    }
}

/// How hard PNG's deflate works; the decoded pixels are the same.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum PngCompression {
    /// fdeflate's fast mode: what glint has always written, a few ms for
    /// 1080p, files about 3x the size of `best`'s on flat renders.
    #[default]
    Fast,
    /// zlib-style deflate at a balanced level: about 8x `fast`'s time.
    Default,
    /// The smallest files: about 2x `default`'s time.
    Best,
}

impl PngCompression {
    fn png(self) -> png::Compression {
        match self {
            PngCompression::Fast => png::Compression::Fast,
            PngCompression::Default => png::Compression::Balanced,
            PngCompression::Best => png::Compression::High,
        }
    }
}

/// What an encoder may choose: JPEG quality, PNG compression.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EncodeOptions {
    /// 1-100.
    pub jpeg_quality: u8,
    /// PNG's deflate effort (the pixels are the same).
    pub png: PngCompression,
}

impl Default for EncodeOptions {
    fn default() -> Self {
        EncodeOptions {
            jpeg_quality: DEFAULT_JPEG_QUALITY,
            png: PngCompression::default(),
        }
    }
}

impl EncodeOptions {
    /// The defaults with JPEG quality `q`.
    pub fn with_quality(q: u8) -> EncodeOptions {
        EncodeOptions {
            jpeg_quality: q,
            ..Default::default()
        }
    }
}

/// Pixels as an encoder reads them: rows top to bottom, channels packed.
#[derive(Clone, Copy)]
pub struct Pixels<'a> {
    /// The pixels' bytes.
    pub bytes: &'a [u8],
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Rgb8, Rgba8, Rgb32F or Rgba32F.
    pub color: ExtendedColorType,
}

/// Encodes `pixels` as a `kind` file. The caller converts to what the
/// format holds: 8-bit for PNG (RGB or RGBA), JPEG and PPM (RGB), float for
/// EXR.
pub fn encode(
    pixels: Pixels<'_>,
    kind: ImageFile,
    options: &EncodeOptions,
) -> Result<Vec<u8>, String> {
    let Pixels {
        bytes,
        width,
        height,
        color,
    } = pixels;
    let mut out = Vec::new();
    match kind {
        ImageFile::Jpeg if color == ExtendedColorType::Rgb8 => {
            return jpeg::encode(bytes, width, height, options.jpeg_quality)
        }
        ImageFile::Png if matches!(color, ExtendedColorType::Rgb8 | ExtendedColorType::Rgba8) => {
            let mut e = png::Encoder::new(&mut out, width, height);
            e.set_color(if color == ExtendedColorType::Rgb8 {
                png::ColorType::Rgb
            } else {
                png::ColorType::Rgba
            });
            e.set_depth(png::BitDepth::Eight);
            e.set_compression(options.png.png());
            let mut w = e.write_header().map_err(|e| e.to_string())?;
            w.write_image_data(bytes).map_err(|e| e.to_string())?;
            w.finish().map_err(|e| e.to_string())?;
        }
        ImageFile::Ppm if color == ExtendedColorType::Rgb8 => {
            use image::codecs::pnm::{PnmEncoder, PnmSubtype, SampleEncoding};
            PnmEncoder::new(&mut out)
                .with_subtype(PnmSubtype::Pixmap(SampleEncoding::Binary))
                .write_image(bytes, width, height, color)
                .map_err(|e| e.to_string())?;
        }
        ImageFile::Exr
            if matches!(
                color,
                ExtendedColorType::Rgb32F | ExtendedColorType::Rgba32F
            ) =>
        {
            // EXR's encoder seeks.
            let mut cursor = std::io::Cursor::new(&mut out);
            image::codecs::openexr::OpenExrEncoder::new(&mut cursor)
                .write_image(bytes, width, height, color)
                .map_err(|e| e.to_string())?;
        }
        _ => return Err(format!("{kind:?} does not hold {color:?} pixels")),
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every compression level decodes to the same pixels.
    #[test]
    fn png_levels_decode_alike() {
        let (w, h) = (37u32, 23u32);
        let rgb: Vec<u8> = (0..w * h * 3).map(|i| (i * 7 % 251) as u8).collect();
        let pixels = Pixels {
            bytes: &rgb,
            width: w,
            height: h,
            color: ExtendedColorType::Rgb8,
        };
        for png in [
            PngCompression::Fast,
            PngCompression::Default,
            PngCompression::Best,
        ] {
            let options = EncodeOptions {
                png,
                ..Default::default()
            };
            let bytes = encode(pixels, ImageFile::Png, &options).expect("encodes");
            let back = image::load_from_memory(&bytes).expect("decodes").to_rgb8();
            assert_eq!(back.as_raw(), &rgb, "{png:?}");
        }
    }

    #[test]
    fn refuses_pixels_the_format_cannot_hold() {
        let pixels = Pixels {
            bytes: &[0; 12],
            width: 1,
            height: 1,
            color: ExtendedColorType::Rgb32F,
        };
        assert!(encode(pixels, ImageFile::Jpeg, &EncodeOptions::default()).is_err());
    }
}
