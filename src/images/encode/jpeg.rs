//! Baseline JPEG (4:4:4, the IJG tables scaled by quality, as the `image`
//! crate's encoder wrote before) with [`jpeg-encoder`](https://docs.rs/jpeg-encoder)'s
//! AVX2 path, encoded in horizontal strips on several threads.
//!
//! Why strips join: with a restart interval of one MCU row, every row of
//! 8x8 blocks starts its entropy coding afresh (DC predictions reset, the
//! bit buffer padded to a byte before the RSTn marker), so a strip's scan
//! is exactly the bytes one whole-image encode writes for those rows, up to
//! the markers' numbers (RST0..RST7, cycling). The strips are encoded as
//! small JPEGs of their own; the first strip's headers (with the whole
//! image's height) start the file, each later strip's scan follows after
//! the marker that ends the previous row, and its own markers are
//! renumbered to continue the cycle. A decoder sees the same DCT
//! coefficients as from one encode of the whole image.

use rayon::prelude::*;

/// Rows of 8x8 blocks in one strip. A render that encodes strips as it
/// finishes them waits after its last rows for one strip's encode (a
/// 1920-wide strip of 8 takes about 1.5 ms on one core of the 2-core EPYC),
/// so shorter is better until a strip's own start-up shows: test1 at
/// 1920x1080 to .jpg, 21 alternating runs, total 52.4 ms with strips of 16
/// rows of blocks against 48.6 with 8 (4 was within the noise of 8).
const STRIP_MCU_ROWS: usize = 8;

const MARKER: u8 = 0xFF;
const RST0: u8 = 0xD0;
const SOF0: u8 = 0xC0;
const SOS: u8 = 0xDA;
const EOI: u8 = 0xD9;

/// Encodes tightly packed RGB8 rows as a baseline JPEG of `quality` (1-100).
pub fn encode(rgb: &[u8], width: u32, height: u32, quality: u8) -> Result<Vec<u8>, String> {
    let strips = Strips::new(width, height, quality)?;
    let row_bytes = width as usize * 3;
    if rgb.len() != row_bytes * height as usize {
        return Err(format!(
            "{} bytes of pixels for a {width}x{height} RGB image",
            rgb.len()
        ));
    }
    let parts: Vec<Vec<u8>> = rgb
        .par_chunks(row_bytes * strips.rows() as usize)
        .map(|strip| strips.encode(strip))
        .collect::<Result<_, _>>()?;
    strips.join(parts)
}

/// A JPEG cut into strips of `rows()` rows (the last may have fewer), each
/// encoded on its own (`encode`, on any thread, as soon as its rows exist)
/// and joined in order (`join`). The file is the same bytes whichever
/// thread encoded which strip, and whether the strips were made by
/// `encode` above or by a render as it finished their rows.
#[derive(Clone, Copy, Debug)]
pub struct Strips {
    width: u16,
    height: u16,
    quality: u8,
    /// One MCU row's MCUs, where there are several strips (none where one
    /// strip is the whole image and needs no restart markers).
    interval: Option<u16>,
}

impl Strips {
    /// The strips of a `width` x `height` JPEG of `quality` (1-100).
    pub fn new(width: u32, height: u32, quality: u8) -> Result<Strips, String> {
        let (w, h) = (dims(width)?, dims(height)?);
        let interval = if usize::from(h).div_ceil(8) > STRIP_MCU_ROWS {
            let mcus = usize::from(w).div_ceil(8);
            Some(u16::try_from(mcus).map_err(|_| "image too wide for JPEG".to_string())?)
        } else {
            None
        };
        Ok(Strips {
            width: w,
            height: h,
            quality,
            interval,
        })
    }

    /// Rows a strip (a multiple of 8, the height of an MCU).
    pub fn rows(&self) -> u32 {
        STRIP_MCU_ROWS as u32 * 8
    }

    /// The encoded strip of `rgb`: tightly packed RGB8 rows, `rows()` of
    /// them, or what is left of the image for the last strip.
    pub fn encode(&self, rgb: &[u8]) -> Result<Vec<u8>, String> {
        let row_bytes = usize::from(self.width) * 3;
        let rows = u16::try_from(rgb.len() / row_bytes)
            .ok()
            .filter(|&r| {
                r > 0 && u32::from(r) <= self.rows() && rgb.len().is_multiple_of(row_bytes)
            })
            .ok_or_else(|| {
                format!(
                    "{} bytes are not a strip of 1-{} rows of {} pixels",
                    rgb.len(),
                    self.rows(),
                    self.width
                )
            })?;
        encode_one(rgb, self.width, rows, self.quality, self.interval)
    }

    /// The file: the strips' scans, top to bottom, under the first strip's
    /// headers.
    pub fn join(&self, mut parts: Vec<Vec<u8>>) -> Result<Vec<u8>, String> {
        let rows = self.rows() as usize;
        if parts.len() != usize::from(self.height).div_ceil(rows) {
            return Err(format!(
                "{} strips for a JPEG of {} rows",
                parts.len(),
                self.height
            ));
        }
        if parts.len() == 1 {
            return Ok(parts.swap_remove(0));
        }
        join(&parts, self.height, |i| i * STRIP_MCU_ROWS)
            .ok_or_else(|| "the JPEG encoder wrote an unexpected stream".into())
    }
}

fn dims(v: u32) -> Result<u16, String> {
    u16::try_from(v)
        .ok()
        .filter(|&v| v > 0)
        .ok_or_else(|| format!("{v} pixels is outside JPEG's 1-65535"))
}

fn encode_one(
    rgb: &[u8],
    w: u16,
    h: u16,
    quality: u8,
    restart_interval: Option<u16>,
) -> Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(rgb.len() / 8);
    let mut e = jpeg_encoder::Encoder::new(&mut out, quality);
    e.set_sampling_factor(jpeg_encoder::SamplingFactor::F_1_1);
    if let Some(n) = restart_interval {
        e.set_restart_interval(n);
    }
    e.encode(rgb, w, h, jpeg_encoder::ColorType::Rgb)
        .map_err(|e| e.to_string())?;
    Ok(out)
}

/// Where a JPEG's scan data starts (after the SOS segment), and the offset
/// of the SOF0 segment's height field.
fn scan_start(jpeg: &[u8]) -> Option<(usize, usize)> {
    let mut at = 2; // after SOI
    let mut height_field = None;
    loop {
        let &[m, kind, hi, lo] = jpeg.get(at..at + 4)? else {
            return None;
        };
        if m != MARKER {
            return None;
        }
        let len = usize::from(u16::from_be_bytes([hi, lo]));
        if kind == SOF0 {
            height_field = Some(at + 5); // length (2), precision (1)
        }
        at += 2 + len;
        if kind == SOS {
            return Some((at, height_field?));
        }
    }
}

/// The strips' scans joined under the first strip's headers; `first_row(i)`
/// is strip i's first MCU row.
fn join(parts: &[Vec<u8>], height: u16, first_row: impl Fn(usize) -> usize) -> Option<Vec<u8>> {
    let (head, height_field) = scan_start(&parts[0])?;
    let mut out = Vec::with_capacity(parts.iter().map(Vec::len).sum());
    out.extend_from_slice(&parts[0][..head]);
    out[height_field..height_field + 2].copy_from_slice(&height.to_be_bytes());
    for (i, part) in parts.iter().enumerate() {
        let (start, _) = scan_start(part)?;
        let scan = part.get(start..part.len().checked_sub(2)?)?;
        if part[part.len() - 2..] != [MARKER, EOI] {
            return None;
        }
        let row0 = first_row(i);
        if i > 0 {
            // The marker before MCU row r (r >= 1) is RST((r - 1) mod 8).
            out.extend_from_slice(&[MARKER, RST0 + ((row0 - 1) % 8) as u8]);
        }
        // The strip's k-th marker comes before its row k + 1, the image's
        // row row0 + k + 1. Entropy-coded 0xFF bytes are followed by 0x00,
        // so an 0xFF followed by D0-D7 is always a marker.
        let mut k = 0;
        let mut j = 0;
        while j < scan.len() {
            let b = scan[j];
            out.push(b);
            if b == MARKER && j + 1 < scan.len() && (RST0..RST0 + 8).contains(&scan[j + 1]) {
                out.push(RST0 + ((row0 + k) % 8) as u8);
                k += 1;
                j += 1;
            }
            j += 1;
        }
    }
    out.extend_from_slice(&[MARKER, EOI]);
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pattern(w: u32, h: u32) -> Vec<u8> {
        (0..w * h * 3)
            .map(|i| {
                let (p, c) = (i / 3, i % 3);
                let (x, y) = (p % w, p / w);
                ((x * (3 + c) + y * (5 + 2 * c) + (x * y) % 13) % 256) as u8
            })
            .collect()
    }

    fn decode(bytes: &[u8]) -> image::RgbImage {
        image::load_from_memory_with_format(bytes, image::ImageFormat::Jpeg)
            .expect("decodes")
            .to_rgb8()
    }

    /// Joined strips decode to exactly the pixels of one encode of the
    /// whole image, for heights on and off the 8-row grid, widths likewise,
    /// and strip counts past the RST cycle of 8.
    #[test]
    fn strips_decode_as_one_encode() {
        for (w, h) in [
            (640, 480),
            (100, 1037),
            (17, 2000),
            (1920, 1080),
            (8, 8 * 200),
        ] {
            let rgb = pattern(w, h);
            let joined = encode(&rgb, w, h, 95).expect("encodes");
            let one = encode_one(&rgb, w as u16, h as u16, 95, None).expect("encodes");
            assert_eq!(decode(&joined), decode(&one), "{w}x{h}");
        }
    }

    /// Strips encoded alone, in any order (as a render's threads finish
    /// them), join to the bytes of `encode`; a wrong strip or count is an
    /// error, not a broken file.
    #[test]
    fn strips_encoded_in_any_order_join_to_the_same_file() {
        for (w, h) in [(64, 500), (33, 129), (40, 128), (16, 7)] {
            let rgb = pattern(w, h);
            let strips = Strips::new(w, h, 90).expect("strips");
            let chunk = (w * 3 * strips.rows()) as usize;
            let chunks: Vec<&[u8]> = rgb.chunks(chunk).collect();
            let mut parts: Vec<(usize, Vec<u8>)> = chunks
                .iter()
                .enumerate()
                .rev()
                .map(|(i, c)| (i, strips.encode(c).expect("encodes")))
                .collect();
            parts.sort_by_key(|p| p.0);
            let parts: Vec<Vec<u8>> = parts.into_iter().map(|p| p.1).collect();
            let whole = encode(&rgb, w, h, 90).expect("encodes");
            assert_eq!(strips.join(parts.clone()).expect("joins"), whole, "{w}x{h}");
            if parts.len() > 1 {
                assert!(strips.join(parts[1..].to_vec()).is_err(), "{w}x{h}");
            }
            assert!(strips.encode(&rgb[..chunk.min(rgb.len()) - 1]).is_err());
            assert!(strips.encode(&[]).is_err());
        }
    }

    #[test]
    fn refuses_sizes_jpeg_cannot_hold() {
        assert!(encode(&[], 0, 4, 90).is_err());
        assert!(encode(&[0; 9], 70_000, 1, 90).is_err());
        assert!(encode(&[0; 5], 1, 2, 90).is_err());
    }
}
