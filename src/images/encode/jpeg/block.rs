//! One MCU (8x8 pixels, 4:4:4) from RGB to three quantised blocks: the
//! colour conversion, forward DCT and quantisation of `jpeg-encoder`,
//! integer for integer, so that its files and glint's are the same bytes.
//! The portable kernel is here; `avx2` has the same arithmetic in
//! registers of eight lanes.

use super::header::Quant;

/// Eight rows of eight RGB pixels.
pub(super) type Rows<'a> = [&'a [u8; 24]; 8];

/// The Y, Cb and Cr blocks of an MCU, quantised, in natural order.
pub(super) type Mcu = [[i16; 64]; 3];

pub(super) const CONST_BITS: i32 = 13;
pub(super) const PASS1_BITS: i32 = 2;

/// One 1-D pass of the slow-but-accurate integer DCT (IJG's `islow`: the
/// Loeffler-Ligtenberg-Moschytz factorisation with 12 multiplies, 13-bit
/// constants) over eight values, each an `i32` or a register of eight:
/// `$set1` broadcasts a constant, `$srai::<N>` and `$slli::<N>` shift.
/// The first pass (`$first`) keeps `PASS1_BITS` more bits than the
/// second, which removes them. A macro so that the AVX2 kernel's copy
/// expands inside its `target_feature` function.
macro_rules! dct_pass {
    ($v:expr, $first:literal; $add:ident, $sub:ident, $mul:ident, $set1:ident, $srai:ident, $slli:ident) => {{
        use $crate::images::encode::jpeg::block::{CONST_BITS, PASS1_BITS};
        const SHIFT: i32 = if $first {
            CONST_BITS - PASS1_BITS
        } else {
            CONST_BITS + PASS1_BITS
        };
        let v = $v;
        let k = |c: i32| $set1(c);
        let descale = |x| $srai::<SHIFT>($add(x, k(1 << (SHIFT - 1))));
        let (tmp0, tmp7) = ($add(v[0], v[7]), $sub(v[0], v[7]));
        let (tmp1, tmp6) = ($add(v[1], v[6]), $sub(v[1], v[6]));
        let (tmp2, tmp5) = ($add(v[2], v[5]), $sub(v[2], v[5]));
        let (tmp3, tmp4) = ($add(v[3], v[4]), $sub(v[3], v[4]));
        let (tmp10, tmp13) = ($add(tmp0, tmp3), $sub(tmp0, tmp3));
        let (tmp11, tmp12) = ($add(tmp1, tmp2), $sub(tmp1, tmp2));
        let (o0, o4) = if $first {
            (
                $slli::<PASS1_BITS>($add(tmp10, tmp11)),
                $slli::<PASS1_BITS>($sub(tmp10, tmp11)),
            )
        } else {
            let half = k(1 << (PASS1_BITS - 1));
            (
                $srai::<PASS1_BITS>($add($add(tmp10, tmp11), half)),
                $srai::<PASS1_BITS>($add($sub(tmp10, tmp11), half)),
            )
        };
        let z1 = $mul($add(tmp12, tmp13), k(4433));
        let o2 = descale($add(z1, $mul(tmp13, k(6270))));
        let o6 = descale($add(z1, $mul(tmp12, k(-15137))));
        let z5 = $mul($add($add(tmp4, tmp6), $add(tmp5, tmp7)), k(9633));
        let z1 = $mul($add(tmp4, tmp7), k(-7373));
        let z2 = $mul($add(tmp5, tmp6), k(-20995));
        let z3 = $add($mul($add(tmp4, tmp6), k(-16069)), z5);
        let z4 = $add($mul($add(tmp5, tmp7), k(-3196)), z5);
        let o7 = descale($add($add($mul(tmp4, k(2446)), z1), z3));
        let o5 = descale($add($add($mul(tmp5, k(16819)), z2), z4));
        let o3 = descale($add($add($mul(tmp6, k(25172)), z2), z3));
        let o1 = descale($add($add($mul(tmp7, k(12299)), z1), z4));
        [o0, o1, o2, o3, o4, o5, o6, o7]
    }};
}
// Only the AVX2 kernel expands it outside this file.
#[cfg_attr(not(target_arch = "x86_64"), allow(unused_imports))]
pub(super) use dct_pass;

/// The portable kernel: `jpeg-encoder`'s scalar arithmetic.
pub(super) fn mcu(rows: &Rows, quant: &[Quant; 2], out: &mut Mcu) {
    let mut planes = [[0i32; 64]; 3];
    for (y, row) in rows.iter().enumerate() {
        for (x, px) in row.chunks_exact(3).enumerate() {
            let [yy, cb, cr] = ycbcr(px[0], px[1], px[2]);
            planes[0][y * 8 + x] = yy - 128;
            planes[1][y * 8 + x] = cb - 128;
            planes[2][y * 8 + x] = cr - 128;
        }
    }
    for ((plane, out), q) in planes.iter_mut().zip(out).zip([0, 1, 1]) {
        fdct(plane);
        for ((o, &v), (&recip, &corr)) in out
            .iter_mut()
            .zip(plane.iter())
            .zip(quant[q].recip.iter().zip(&quant[q].corr))
        {
            let q = ((v.abs() + corr) * recip) >> 15;
            // In range: the DCT's outputs are under 2^14 in magnitude.
            *o = (if v < 0 { -q } else { q }) as i16;
        }
    }
}

/// `jpeg-encoder`'s RGB to YCbCr: 16-bit fixed point, rounded.
fn ycbcr(r: u8, g: u8, b: u8) -> [i32; 3] {
    let (r, g, b) = (i32::from(r), i32::from(g), i32::from(b));
    let y = 19595 * r + 38470 * g + 7471 * b;
    let cb = -11059 * r - 21709 * g + 32768 * b + (128 << 16);
    let cr = 32768 * r - 27439 * g - 5329 * b + (128 << 16);
    [y, cb, cr].map(|v| (v + 0x7FFF) >> 16)
}

fn add(a: i32, b: i32) -> i32 {
    a + b
}
fn sub(a: i32, b: i32) -> i32 {
    a - b
}
fn mul(a: i32, b: i32) -> i32 {
    a * b
}
fn set1(c: i32) -> i32 {
    c
}
fn srai<const N: i32>(a: i32) -> i32 {
    a >> N
}
fn slli<const N: i32>(a: i32) -> i32 {
    a << N
}

/// Rows first, then columns, as `jpeg-encoder` does; the result is the
/// true DCT scaled by eight.
pub(super) fn fdct(block: &mut [i32; 64]) {
    for row in block.chunks_exact_mut(8) {
        let v: [i32; 8] = std::array::from_fn(|i| row[i]);
        row.copy_from_slice(&dct_pass!(v, true; add, sub, mul, set1, srai, slli));
    }
    for x in 0..8 {
        let v: [i32; 8] = std::array::from_fn(|y| block[y * 8 + x]);
        let out = dct_pass!(v, false; add, sub, mul, set1, srai, slli);
        for (y, o) in out.into_iter().enumerate() {
            block[y * 8 + x] = o;
        }
    }
}
