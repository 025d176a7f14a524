//! The entropy-coded scan of a run of MCU rows: each MCU through a
//! kernel to three quantised blocks, each block Huffman-coded in zigzag
//! order into a bit stream with JPEG's byte stuffing, and a restart
//! marker before every MCU row but the image's first when the file has
//! restart intervals.

use std::ops::Range;

use super::block::{Mcu, Rows};
use super::header::{Huff, Tables};
use super::{Kernel, MARKER, RST0, ZIGZAG};

/// Tightly packed RGB8 rows.
pub(super) struct Image<'a> {
    pub rgb: &'a [u8],
    pub width: usize,
    pub height: usize,
}

/// The scan bytes of MCU rows `rows`, ending on a byte boundary.
pub(super) fn mcu_rows(
    img: &Image,
    rows: Range<usize>,
    tables: &Tables,
    kernel: Kernel,
    restart: bool,
) -> Vec<u8> {
    let cols = img.width.div_ceil(8);
    let mut bits = Stream::with_capacity(rows.len() * cols * 24);
    let mut edge = [[0u8; 24]; 8];
    let mut mcu: Mcu = [[0; 64]; 3];
    let mut prev_dc = [0i16; 3];
    for r in rows {
        if restart && r > 0 {
            bits.align();
            bits.out
                .extend_from_slice(&[MARKER, RST0 + ((r - 1) % 8) as u8]);
            prev_dc = [0; 3];
        }
        // Rows past the image repeat its last, as columns past it repeat
        // each row's last pixel.
        let line = |i: usize| (r * 8 + i).min(img.height - 1) * img.width * 3;
        for x0 in (0..img.width).step_by(8) {
            let pixels: Rows = if x0 + 8 <= img.width {
                std::array::from_fn(|i| {
                    let at = line(i) + x0 * 3;
                    <&[u8; 24]>::try_from(&img.rgb[at..at + 24]).expect("24 bytes")
                })
            } else {
                for (i, row) in edge.iter_mut().enumerate() {
                    for (x, px) in row.chunks_exact_mut(3).enumerate() {
                        let at = line(i) + (x0 + x).min(img.width - 1) * 3;
                        px.copy_from_slice(&img.rgb[at..at + 3]);
                    }
                }
                std::array::from_fn(|i| &edge[i])
            };
            kernel.run(&pixels, &tables.quant, &mut mcu);
            for ((block, dc), t) in mcu.iter().zip(&mut prev_dc).zip([0, 1, 1]) {
                bits.code(|w| code_block(w, block, dc, &tables.dc[t], &tables.ac[t]));
            }
        }
    }
    bits.align();
    bits.out
}

/// One block as `jpeg-encoder` codes it: the DC difference, then runs of
/// zeros and the non-zero coefficients in zigzag order, ZRL for each 16
/// zeros before a coefficient, EOB unless the last coefficient is
/// non-zero.
#[inline]
fn code_block(bits: &mut Writer, block: &[i16; 64], prev_dc: &mut i16, dc: &Huff, ac: &Huff) {
    let nonzero = zigzag_bits(block);
    let (size, extra) = magnitude(block[0].wrapping_sub(*prev_dc));
    *prev_dc = block[0];
    bits.put_coded(dc, size as u8, size, extra);
    let mut rest = nonzero & !1;
    let mut last = 0;
    while rest != 0 {
        let k = rest.trailing_zeros();
        let mut run = k - last - 1;
        while run > 15 {
            bits.put_coded(ac, 0xF0, 0, 0);
            run -= 16;
        }
        let (size, extra) = magnitude(block[usize::from(ZIGZAG[k as usize])]);
        bits.put_coded(ac, ((run << 4) | size) as u8, size, extra);
        last = k;
        rest &= rest - 1;
    }
    if last != 63 {
        bits.put_coded(ac, 0x00, 0, 0);
    }
}

/// Bit k set where zigzag coefficient k is non-zero.
#[inline]
fn zigzag_bits(block: &[i16; 64]) -> u64 {
    // By bytes of the natural-order mask, each byte's bits moved to
    // their zigzag places at once: eight lookups, not 64 tests.
    static TO_ZIGZAG: [[u64; 256]; 8] = {
        let mut place = [0u8; 64];
        let mut k = 0;
        while k < 64 {
            place[ZIGZAG[k] as usize] = k as u8;
            k += 1;
        }
        let mut t = [[0u64; 256]; 8];
        let mut byte = 0;
        while byte < 8 {
            let mut v = 0;
            while v < 256 {
                let mut bit = 0;
                while bit < 8 {
                    if v & (1 << bit) != 0 {
                        t[byte][v] |= 1 << place[byte * 8 + bit];
                    }
                    bit += 1;
                }
                v += 1;
            }
            byte += 1;
        }
        t
    };
    let natural = natural_bits(block);
    TO_ZIGZAG.iter().enumerate().fold(0, |z, (b, t)| {
        z | t[usize::from((natural >> (8 * b)) as u8)]
    })
}

/// Bit i set where coefficient i (natural order) is non-zero.
#[cfg(target_arch = "x86_64")]
#[inline]
pub(super) fn natural_bits(block: &[i16; 64]) -> u64 {
    use std::arch::x86_64::*;
    let p = block.as_ptr().cast::<__m128i>();
    let mut zeros = 0u64;
    for i in 0..4 {
        // SAFETY: SSE2 is part of x86_64; the loads are the block's 16
        // bytes at 32i and 32i + 16.
        let bits = unsafe {
            let a = _mm_cmpeq_epi16(_mm_loadu_si128(p.add(2 * i)), _mm_setzero_si128());
            let b = _mm_cmpeq_epi16(_mm_loadu_si128(p.add(2 * i + 1)), _mm_setzero_si128());
            _mm_movemask_epi8(_mm_packs_epi16(a, b))
        };
        zeros |= u64::from(bits as u16) << (16 * i);
    }
    !zeros
}

#[cfg(not(target_arch = "x86_64"))]
pub(super) use natural_bits_portable as natural_bits;

#[cfg_attr(all(target_arch = "x86_64", not(test)), allow(dead_code))]
pub(super) fn natural_bits_portable(block: &[i16; 64]) -> u64 {
    block
        .iter()
        .enumerate()
        .fold(0, |m, (i, &v)| m | (u64::from(v != 0) << i))
}

/// A coefficient's size category and its `size` low bits (one's
/// complement for negatives), as T.81 F.1.2 codes them.
#[inline]
fn magnitude(v: i16) -> (u32, u32) {
    let v = i32::from(v);
    let size = 32 - v.unsigned_abs().leading_zeros();
    let extra = (v - i32::from(v < 0)) as u32 & ((1u32 << size) - 1);
    (size, extra)
}

/// The scan so far: whole bytes in `out`, the pending bits in `acc`, and
/// room for one block's bytes.
struct Stream {
    out: Vec<u8>,
    acc: u64,
    n: u32,
    block: Box<[u8; BLOCK_BYTES]>,
}

/// More than one block's bytes can be: 64 codes of at most 32 bits, each
/// byte of them perhaps stuffed, and the pending bits before them.
const BLOCK_BYTES: usize = 1024;

impl Stream {
    fn with_capacity(bytes: usize) -> Self {
        Stream {
            out: Vec::with_capacity(bytes),
            acc: 0,
            n: 0,
            block: Box::new([0; BLOCK_BYTES]),
        }
    }

    /// Runs `f` on a writer that holds the pending bits in registers (a
    /// `Vec` it could grow would keep them in memory), then keeps what it
    /// wrote.
    #[inline(always)]
    fn code(&mut self, f: impl FnOnce(&mut Writer)) {
        let mut w = Writer {
            buf: &mut self.block,
            len: 0,
            acc: self.acc,
            n: self.n,
        };
        f(&mut w);
        let Writer { len, acc, n, .. } = w;
        self.out.extend_from_slice(&self.block[..len]);
        self.acc = acc;
        self.n = n;
    }

    /// Pads with one bits to a byte boundary and writes out what is left.
    fn align(&mut self) {
        self.code(|w| {
            let pad = (8 - w.n % 8) % 8;
            if pad > 0 {
                w.put((1 << pad) - 1, pad);
            }
            while w.n >= 8 {
                w.n -= 8;
                w.byte((w.acc >> w.n) as u8);
            }
        });
    }
}

/// Bits, most significant first, into bytes with an 0x00 after every 0xFF.
struct Writer<'a> {
    buf: &'a mut [u8; BLOCK_BYTES],
    len: usize,
    /// The pending bits are the low `n` (under 32 between calls).
    acc: u64,
    n: u32,
}

impl Writer<'_> {
    /// `symbol`'s code from `table`, then `size` bits of `extra`.
    #[inline(always)]
    fn put_coded(&mut self, table: &Huff, symbol: u8, size: u32, extra: u32) {
        let s = usize::from(symbol);
        let code = (u32::from(table.code[s]) << size) | extra;
        self.put(code, u32::from(table.len[s]) + size);
    }

    /// The low `len` (at most 32) bits of `v`.
    #[inline(always)]
    fn put(&mut self, v: u32, len: u32) {
        self.acc = (self.acc << len) | u64::from(v);
        self.n += len;
        if self.n >= 32 {
            self.n -= 32;
            let word = (self.acc >> self.n) as u32;
            // A byte of 0xFF is the only one that sets its top bit and
            // carries out of itself when one is added.
            if word & 0x8080_8080 & !word.wrapping_add(0x0101_0101) == 0 {
                self.buf[self.len..self.len + 4].copy_from_slice(&word.to_be_bytes());
                self.len += 4;
            } else {
                for b in word.to_be_bytes() {
                    self.byte(b);
                }
            }
        }
    }

    #[inline(always)]
    fn byte(&mut self, b: u8) {
        self.buf[self.len] = b;
        self.len += 1;
        if b == MARKER {
            self.buf[self.len] = 0;
            self.len += 1;
        }
    }
}
