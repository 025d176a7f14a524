//! The shader's random numbers and sample patterns (`rng`, `stratified_2d`,
//! ...), bit for bit: integer hashing is exact on every device, and the
//! floats are built from 24-bit integers, exact in f32 and f64.

use super::real::Real;

/// The stream of the pixel position (streams and the rotation index are
/// the shader's).
pub const STREAM_PIXEL: u32 = 0;
/// The stream of the motion-blur time.
pub const STREAM_TIME: u32 = 1;
/// The stream of area lights' points (plus the light and bounce).
pub const STREAM_LIGHT: u32 = 2;
/// The index that draws a pixel's or light's rotation of its grid.
pub const ROTATION: u32 = u32::MAX;

pub use crate::hash::hash_u32;

/// The random word of (seed, pixel, sample, stream, index): a hash chain,
/// the shader's `rng`.
pub fn rng(seed: u32, pixel: u32, sample: u32, stream: u32, index: u32) -> u32 {
    let mut h = hash_u32(seed ^ 0x9e37_79b9);
    h = hash_u32(h ^ pixel);
    h = hash_u32(h ^ sample);
    h = hash_u32(h ^ stream);
    hash_u32(h ^ index)
}

/// The top 24 bits of `x` as a number in [0, 1).
pub fn unit_float<R: Real>(x: u32) -> R {
    R::from_u32(x >> 8) * R::from_f64(1.0 / 16_777_216.0)
}

/// Columns of the near-square grid `stratified_2d` lays over `n` samples:
/// ceil(sqrt(n)), at least 1, the float root corrected by one either way.
pub fn grid_columns(n: u32) -> u32 {
    let mut c = (n as f32).sqrt() as u32;
    if c * c < n {
        c += 1;
    }
    if c > 1 && (c - 1) * (c - 1) >= n {
        c -= 1;
    }
    c.max(1)
}

/// Sample `k` of `n` in the unit square: a cell of a `grid_columns(n)` grid,
/// visited from `rotation`, with `jitter` ([0,1)²) within the cell.
pub fn stratified_2d<R: Real>(k: u32, n: u32, rotation: u32, jitter: [R; 2]) -> [R; 2] {
    let cols = grid_columns(n);
    let rows = n.div_ceil(cols);
    let cells = cols * rows;
    let cell = (k + rotation % cells) % cells;
    [
        (R::from_u32(cell % cols) + jitter[0]) / R::from_u32(cols),
        (R::from_u32(cell / cols) + jitter[1]) / R::from_u32(rows),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Effects;

    #[test]
    fn grid_columns_is_ceil_sqrt() {
        for n in 1..=Effects::MAX_SPP {
            let c = grid_columns(n);
            assert!(c * c >= n && (c - 1) * (c - 1) < n, "{n} -> {c}");
        }
    }

    #[test]
    fn stratified_samples_take_distinct_cells_and_cover_a_square_grid() {
        for n in [1u32, 2, 3, 4, 5, 9, 16, 17] {
            let cols = grid_columns(n);
            let rows = n.div_ceil(cols);
            for rotation in [0u32, 1, 7, 123_456] {
                let mut cells: Vec<(u32, u32)> = (0..n)
                    .map(|k| {
                        let [x, y] = stratified_2d::<f64>(k, n, rotation, [0.5, 0.5]);
                        assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
                        ((x * f64::from(cols)) as u32, (y * f64::from(rows)) as u32)
                    })
                    .collect();
                cells.sort();
                cells.dedup();
                assert_eq!(cells.len(), n as usize, "n = {n}");
            }
        }
    }

    #[test]
    fn unit_floats_are_in_range_and_exact() {
        assert_eq!(unit_float::<f32>(0), 0.0);
        assert!(unit_float::<f32>(u32::MAX) < 1.0);
        for x in [1u32 << 8, 12_345_678, u32::MAX] {
            assert_eq!(f64::from(unit_float::<f32>(x)), unit_float::<f64>(x), "{x}");
        }
    }
}
