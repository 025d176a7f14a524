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

/// Rows of 8x8 blocks in one strip: below this the threads' start-up costs
/// more than the strip saves (about 1 ms a 1920-wide strip).
const STRIP_MCU_ROWS: usize = 16;

const MARKER: u8 = 0xFF;
const RST0: u8 = 0xD0;
const SOF0: u8 = 0xC0;
const SOS: u8 = 0xDA;
const EOI: u8 = 0xD9;

/// Encodes tightly packed RGB8 rows as a baseline JPEG of `quality` (1-100).
pub fn encode(rgb: &[u8], width: u32, height: u32, quality: u8) -> Result<Vec<u8>, String> {
    let (w, h) = (dims(width)?, dims(height)?);
    if rgb.len() != usize::from(w) * usize::from(h) * 3 {
        return Err(format!(
            "{} bytes of pixels for a {width}x{height} RGB image",
            rgb.len()
        ));
    }
    let mcu_rows = usize::from(h).div_ceil(8);
    let strips = (mcu_rows / STRIP_MCU_ROWS).clamp(1, rayon::current_num_threads() * 4);
    if strips == 1 {
        return encode_one(rgb, w, h, quality, None);
    }
    let mcus_per_row = usize::from(w).div_ceil(8);
    let interval =
        u16::try_from(mcus_per_row).map_err(|_| "image too wide for JPEG".to_string())?;
    let row_bytes = usize::from(w) * 3;
    // Strip i holds MCU rows [start(i), start(i + 1)).
    let start = |i: usize| i * mcu_rows / strips;
    let parts: Vec<Vec<u8>> = (0..strips)
        .into_par_iter()
        .map(|i| {
            let y0 = start(i) * 8;
            let y1 = (start(i + 1) * 8).min(usize::from(h));
            let rows = u16::try_from(y1 - y0).expect("a strip is no taller than the image");
            encode_one(
                &rgb[y0 * row_bytes..y1 * row_bytes],
                w,
                rows,
                quality,
                Some(interval),
            )
        })
        .collect::<Result<_, _>>()?;
    join(&parts, h, start).ok_or_else(|| "the JPEG encoder wrote an unexpected stream".into())
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

    #[test]
    fn refuses_sizes_jpeg_cannot_hold() {
        assert!(encode(&[], 0, 4, 90).is_err());
        assert!(encode(&[0; 9], 70_000, 1, 90).is_err());
        assert!(encode(&[0; 5], 1, 2, 90).is_err());
    }
}
