//! `block::mcu` in AVX2 registers: a row of eight pixels a register, the
//! same integers lane for lane.

use std::arch::x86_64::*;

use super::block::{dct_pass, Mcu, Rows};
use super::header::Quant;

/// Two `i16` factors in one lane, as `_mm256_madd_epi16` pairs them: `lo`
/// multiplies a pair's first element.
const fn pair(lo: i16, hi: i16) -> i32 {
    (((hi as u16 as u32) << 16) | lo as u16 as u32) as i32
}

#[target_feature(enable = "avx2")]
pub(super) fn mcu(rows: &Rows, quant: &[Quant; 2], out: &mut Mcu) {
    // Bytes 0..16 of a row in the low half, 8..24 in the high, so that
    // pixels 0-3 and 4-7 each lie in one half: per pixel, the lane pairs
    // (R, G) and (G, B) as `i16`.
    #[rustfmt::skip]
    let rg_at = _mm256_setr_epi8(
        0, -1, 1, -1, 3, -1, 4, -1, 6, -1, 7, -1, 9, -1, 10, -1,
        4, -1, 5, -1, 7, -1, 8, -1, 10, -1, 11, -1, 13, -1, 14, -1,
    );
    #[rustfmt::skip]
    let gb_at = _mm256_setr_epi8(
        1, -1, 2, -1, 4, -1, 5, -1, 7, -1, 8, -1, 10, -1, 11, -1,
        5, -1, 6, -1, 8, -1, 9, -1, 11, -1, 12, -1, 14, -1, 15, -1,
    );
    let k = _mm256_set1_epi32;
    let mut planes = [[_mm256_setzero_si256(); 8]; 3];
    for (y, row) in rows.iter().enumerate() {
        // SAFETY: two 16-byte loads at bytes 0 and 8 of the row's 24.
        let (lo, hi) = unsafe {
            (
                _mm_loadu_si128(row.as_ptr().cast()),
                _mm_loadu_si128(row.as_ptr().add(8).cast()),
            )
        };
        let px = _mm256_set_m128i(hi, lo);
        let rg = _mm256_shuffle_epi8(px, rg_at);
        let gb = _mm256_shuffle_epi8(px, gb_at);
        // 38470 G, past i16, as 19235 G twice; 32768 B and R as shifts.
        // The luma's -128 folds into its rounding constant; the chroma's
        // +128 and -128 cancel.
        let luma = _mm256_add_epi32(
            _mm256_madd_epi16(rg, k(pair(19595, 19235))),
            _mm256_madd_epi16(gb, k(pair(19235, 7471))),
        );
        let r = _mm256_and_si256(rg, k(0xFFFF));
        let b = _mm256_srli_epi32::<16>(gb);
        let cb = _mm256_add_epi32(
            _mm256_madd_epi16(rg, k(pair(-11059, -21709))),
            _mm256_slli_epi32::<15>(b),
        );
        let cr = _mm256_add_epi32(
            _mm256_madd_epi16(gb, k(pair(-27439, -5329))),
            _mm256_slli_epi32::<15>(r),
        );
        let round = |v, c| _mm256_srai_epi32::<16>(_mm256_add_epi32(v, k(c)));
        planes[0][y] = round(luma, 0x7FFF - (128 << 16));
        planes[1][y] = round(cb, 0x7FFF);
        planes[2][y] = round(cr, 0x7FFF);
    }
    for ((plane, out), q) in planes.iter().zip(out).zip([0, 1, 1]) {
        let columns = transpose(*plane);
        let pass1 = dct_pass!(columns, true; _mm256_add_epi32, _mm256_sub_epi32,
            _mm256_mullo_epi32, _mm256_set1_epi32, _mm256_srai_epi32, _mm256_slli_epi32);
        let rows = transpose(pass1);
        let dct = dct_pass!(rows, false; _mm256_add_epi32, _mm256_sub_epi32,
            _mm256_mullo_epi32, _mm256_set1_epi32, _mm256_srai_epi32, _mm256_slli_epi32);
        let quant = &quant[q];
        let q: [__m256i; 8] = std::array::from_fn(|y| {
            // SAFETY: row y's eight `i32` of 64.
            let (recip, corr) = unsafe {
                (
                    _mm256_loadu_si256(quant.recip.as_ptr().add(8 * y).cast()),
                    _mm256_loadu_si256(quant.corr.as_ptr().add(8 * y).cast()),
                )
            };
            let v = dct[y];
            let scaled = _mm256_mullo_epi32(_mm256_add_epi32(_mm256_abs_epi32(v), corr), recip);
            _mm256_sign_epi32(_mm256_srli_epi32::<15>(scaled), v)
        });
        for (pair, dst) in q.chunks_exact(2).zip(out.chunks_exact_mut(16)) {
            // packs interleaves the halves; the permute puts the rows back.
            let packed = _mm256_permute4x64_epi64::<0xD8>(_mm256_packs_epi32(pair[0], pair[1]));
            // SAFETY: 16 `i16` of the block's 64.
            unsafe { _mm256_storeu_si256(dst.as_mut_ptr().cast(), packed) };
        }
    }
}

/// Rows of eight `i32` to columns.
#[target_feature(enable = "avx2")]
fn transpose(r: [__m256i; 8]) -> [__m256i; 8] {
    let t: [__m256i; 8] = std::array::from_fn(|i| {
        let (a, b) = (r[i & !1], r[i | 1]);
        if i & 1 == 0 {
            _mm256_unpacklo_epi32(a, b)
        } else {
            _mm256_unpackhi_epi32(a, b)
        }
    });
    // u[4h + j]: rows 4h..4h+4 of columns j (low half) and j + 4 (high).
    let u = [
        _mm256_unpacklo_epi64(t[0], t[2]),
        _mm256_unpackhi_epi64(t[0], t[2]),
        _mm256_unpacklo_epi64(t[1], t[3]),
        _mm256_unpackhi_epi64(t[1], t[3]),
        _mm256_unpacklo_epi64(t[4], t[6]),
        _mm256_unpackhi_epi64(t[4], t[6]),
        _mm256_unpacklo_epi64(t[5], t[7]),
        _mm256_unpackhi_epi64(t[5], t[7]),
    ];
    std::array::from_fn(|c| {
        let (a, b) = (u[c % 4], u[4 + c % 4]);
        if c < 4 {
            _mm256_permute2x128_si256::<0x20>(a, b)
        } else {
            _mm256_permute2x128_si256::<0x31>(a, b)
        }
    })
}
