//! Baseline JPEG (4:4:4, the IJG tables scaled by quality, as the `image`
//! crate's encoder wrote before), with the arithmetic of
//! [`jpeg-encoder`](https://docs.rs/jpeg-encoder)'s portable path, in
//! horizontal strips on several threads.
//!
//! `jpeg-encoder` writes the headers and so chooses the tables (`header`);
//! glint writes the scan (`scan`), with its own kernel for colour
//! conversion, DCT and quantisation (`block`, in AVX2 where the CPU has
//! it: `avx2`). Why: at 1920x1080, on one core of this project's machines,
//! `jpeg-encoder` took 24-29 ms a frame (its quantisation, zigzag and
//! block copies one sample at a time) and glint takes 5-7 ms, in the same
//! run (`benches/history.md`). A second reason: `jpeg-encoder`'s AVX2 DCT
//! leaves out the rounding of the first and fifth outputs of odd columns
//! in its second pass (its rounding constant is set as 32-bit lanes and
//! added as 16-bit ones), so its files depend on the CPU; glint's follow
//! the IJG integer DCT, its portable path, on every CPU.
//!
//! Why strips join: with a restart interval of one MCU row, every row of
//! 8x8 blocks starts its entropy coding afresh (DC predictions reset, the
//! bit buffer padded to a byte before the RSTn marker), so each strip's
//! scan is coded on its own and the strips are concatenated.

#[cfg(target_arch = "x86_64")]
mod avx2;
mod block;
mod header;
mod scan;
#[cfg(test)]
mod tests;

use rayon::prelude::*;

/// Rows of 8x8 blocks in one strip, at least: a 1920-wide strip of 16 is
/// about 0.6 ms of one core's coding (5 ms for 135 such rows), well above
/// what handing it to a thread costs.
const STRIP_MCU_ROWS: usize = 16;

const MARKER: u8 = 0xFF;
const RST0: u8 = 0xD0;
const EOI: u8 = 0xD9;

/// Natural index (row * 8 + column) of each zigzag position: the
/// anti-diagonals in turn, up and right on even ones, down and left on odd.
const ZIGZAG: [u8; 64] = {
    let mut order = [0u8; 64];
    let (mut k, mut s) = (0, 0);
    while s < 15 {
        let lo = if s > 7 { s - 7 } else { 0 };
        let hi = if s < 7 { s } else { 7 };
        let mut i = 0;
        while i <= hi - lo {
            let row = if s % 2 == 0 { hi - i } else { lo + i };
            order[k] = (row * 8 + (s - row)) as u8;
            k += 1;
            i += 1;
        }
        s += 1;
    }
    order
};

/// The MCU kernel: the portable one, or AVX2's where the CPU has it. Only
/// `best` and `portable` make one, so the AVX2 kernel runs only where it
/// was found.
#[derive(Clone, Copy)]
struct Kernel(fn(&block::Rows, &[header::Quant; 2], &mut block::Mcu));

impl Kernel {
    fn best() -> Self {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            return Kernel(mcu_avx2);
        }
        Self::portable()
    }

    fn portable() -> Self {
        Kernel(block::mcu)
    }

    fn run(self, rows: &block::Rows, quant: &[header::Quant; 2], out: &mut block::Mcu) {
        (self.0)(rows, quant, out)
    }
}

#[cfg(target_arch = "x86_64")]
fn mcu_avx2(rows: &block::Rows, quant: &[header::Quant; 2], out: &mut block::Mcu) {
    // SAFETY: only `Kernel::best` names this function, after finding AVX2.
    unsafe { avx2::mcu(rows, quant, out) }
}

/// Encodes tightly packed RGB8 rows as a baseline JPEG of `quality` (1-100).
pub fn encode(rgb: &[u8], width: u32, height: u32, quality: u8) -> Result<Vec<u8>, String> {
    encode_with(rgb, width, height, quality, Kernel::best())
}

fn encode_with(
    rgb: &[u8],
    width: u32,
    height: u32,
    quality: u8,
    kernel: Kernel,
) -> Result<Vec<u8>, String> {
    let (w, h) = (dims(width)?, dims(height)?);
    if rgb.len() != usize::from(w) * usize::from(h) * 3 {
        return Err(format!(
            "{} bytes of pixels for a {width}x{height} RGB image",
            rgb.len()
        ));
    }
    let mcu_rows = usize::from(h).div_ceil(8);
    // Restart markers only where there are strips to join, so that a small
    // image's file is what one plain encode writes. Whether there are
    // follows from the height alone (the thread count only splits the
    // strips finer), so the file is the same on any machine.
    let strips = (mcu_rows / STRIP_MCU_ROWS).clamp(1, rayon::current_num_threads() * 4);
    let restart = mcu_rows >= 2 * STRIP_MCU_ROWS;
    let interval = u16::try_from(usize::from(w).div_ceil(8)).expect("at most 8192 MCUs a row");
    let (head, tables) = header::header(w, h, quality, restart.then_some(interval))?;
    let img = scan::Image {
        rgb,
        width: usize::from(w),
        height: usize::from(h),
    };
    // Strip i holds MCU rows [start(i), start(i + 1)).
    let start = |i: usize| i * mcu_rows / strips;
    let parts: Vec<Vec<u8>> = (0..strips)
        .into_par_iter()
        .map(|i| scan::mcu_rows(&img, start(i)..start(i + 1), &tables, kernel, restart))
        .collect();
    let mut out = Vec::with_capacity(head.len() + parts.iter().map(Vec::len).sum::<usize>() + 2);
    out.extend_from_slice(&head);
    for part in &parts {
        out.extend_from_slice(part);
    }
    out.extend_from_slice(&[MARKER, EOI]);
    Ok(out)
}

fn dims(v: u32) -> Result<u16, String> {
    u16::try_from(v)
        .ok()
        .filter(|&v| v > 0)
        .ok_or_else(|| format!("{v} pixels is outside JPEG's 1-65535"))
}
