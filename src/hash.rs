//! The integer hash every random number of glint's comes from, the
//! shader's and the CPU reference's alike (`cpu::sample`), and the tests'
//! reproducible pseudo-random scenes: exact on every device.

/// A 32-bit integer hash (lowbias32: two multiply-xorshift rounds).
/// Inlined: every sample's random numbers come from it, and it lives in a
/// module (and codegen unit) of its own.
#[inline]
pub fn hash_u32(x: u32) -> u32 {
    let mut h = x;
    h ^= h >> 16;
    h = h.wrapping_mul(0x7feb_352d);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846c_a68b);
    h ^= h >> 16;
    h
}
