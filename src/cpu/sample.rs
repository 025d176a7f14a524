//! The shader's random numbers and sample patterns (`rng`, `stratified_2d`,
//! ...), bit for bit: integer hashing is exact on every device, and the
//! floats are built from 24-bit integers, exact in f32 and f64.

use super::real::Real;
use crate::scene::Sampler;

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

/// The index that draws a Sobol dimension's key (`sobol_key`).
pub const SOBOL_KEY: u32 = 0xffff_fffe;
/// What tells a Sobol point's coordinates' seeds apart.
pub const SOBOL_X: u32 = 0x68bc_21eb;
/// See `SOBOL_X`.
pub const SOBOL_Y: u32 = 0x02e5_be93;

/// Laine and Karras's hash with Burley's constants: each output bit depends
/// only on the input bits at and below it (the shader's `laine_karras`).
pub fn laine_karras(x: u32, seed: u32) -> u32 {
    let mut v = x.wrapping_add(seed);
    v ^= v.wrapping_mul(0x6c50_b47c);
    v ^= v.wrapping_mul(0xb82f_1e52);
    v ^= v.wrapping_mul(0xc7af_e638);
    v ^= v.wrapping_mul(0x8d22_f6e6);
    v
}

/// A nested uniform (Owen) scramble of `x`'s bits, keyed by `seed`.
pub fn owen_scramble(x: u32, seed: u32) -> u32 {
    laine_karras(x.reverse_bits(), seed).reverse_bits()
}

/// Sobol's second coordinate of index `i`, bit-reversed: a sum over
/// supersets of bit positions (the shader's `sobol_second_reversed`).
pub fn sobol_second_reversed(i: u32) -> u32 {
    let mut x = i;
    x ^= (x >> 1) & 0x5555_5555;
    x ^= (x >> 2) & 0x3333_3333;
    x ^= (x >> 4) & 0x0f0f_0f0f;
    x ^= (x >> 8) & 0x00ff_00ff;
    x ^= (x >> 16) & 0x0000_ffff;
    x
}

/// The randomisation of dimension `stream` of `pixel`.
pub fn sobol_key(seed: u32, pixel: u32, stream: u32) -> u32 {
    rng(seed, pixel, ROTATION, stream, SOBOL_KEY)
}

/// Point `i` of a pixel's 2D dimension `key`, in [0, 1)²: Owen-scrambled
/// Sobol with a scrambled index (the shader's `sobol_2d`).
pub fn sobol_2d<R: Real>(key: u32, i: u32) -> [R; 2] {
    sobol_2d_seeded(key, sobol_seeds(key), i)
}

/// The seeds of a 2D dimension's two coordinates, from its key (the
/// shader's `sobol_seeds`).
pub fn sobol_seeds(key: u32) -> [u32; 2] {
    [hash_u32(key ^ SOBOL_X), hash_u32(key ^ SOBOL_Y)]
}

/// `sobol_2d` with its coordinates' seeds drawn already (an area light's
/// samples share them; the shader's `sobol_2d_seeded`).
pub fn sobol_2d_seeded<R: Real>(key: u32, seeds: [u32; 2], i: u32) -> [R; 2] {
    let j = owen_scramble(i, key);
    let x = laine_karras(j, seeds[0]).reverse_bits();
    let y = laine_karras(sobol_second_reversed(j), seeds[1]).reverse_bits();
    [unit_float(x), unit_float(y)]
}

/// Point `i` of a pixel's 1D dimension `key`, in [0, 1).
pub fn sobol_1d<R: Real>(key: u32, i: u32) -> R {
    let j = owen_scramble(i, key);
    unit_float(laine_karras(j, hash_u32(key ^ SOBOL_X)).reverse_bits())
}

/// What an area light's samples at one sample of a pixel share, drawn once
/// for all of them: the Sobol dimension's key and seeds, or the stratified
/// grid's rotation (the shader's `AreaPattern`, `area_pattern`).
#[derive(Clone, Copy, Debug)]
pub struct AreaPattern {
    sampler: Sampler,
    seed: u32,
    pixel: u32,
    sample: u32,
    stream: u32,
    /// Sobol: the dimension's key; stratified: the rotation.
    base: u32,
    /// Sobol: the coordinates' seeds.
    seeds: [u32; 2],
}

impl AreaPattern {
    /// The pattern of stream `stream` at sample `sample` of `pixel`.
    pub fn new(sampler: Sampler, seed: u32, pixel: u32, sample: u32, stream: u32) -> AreaPattern {
        let (base, seeds) = match sampler {
            Sampler::Sobol => {
                let key = sobol_key(seed, pixel, stream);
                (key, sobol_seeds(key))
            }
            Sampler::Stratified => (rng(seed, pixel, sample, stream, ROTATION), [0; 2]),
        };
        AreaPattern {
            sampler,
            seed,
            pixel,
            sample,
            stream,
            base,
            seeds,
        }
    }

    /// Sample `m` of `n`, in [0, 1)²: Sobol points `sample * n + m` of the
    /// light's dimension, so that a pixel's samples together cover the
    /// light; or cell `m` of the stratified grid (the shader's `area_uv`).
    pub fn uv<R: Real>(&self, m: u32, n: u32) -> [R; 2] {
        match self.sampler {
            Sampler::Sobol => {
                let i = self.sample.wrapping_mul(n).wrapping_add(m);
                sobol_2d_seeded(self.base, self.seeds, i)
            }
            Sampler::Stratified => {
                let draw = |index| rng(self.seed, self.pixel, self.sample, self.stream, index);
                let jitter = [unit_float(draw(2 * m)), unit_float(draw(2 * m + 1))];
                stratified_2d(m, n, self.base, jitter)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Effects;

    /// Sobol's second coordinate by its definition: the xor of the
    /// direction numbers v_k (v_0 = 1/2, v_{k+1} = v_k ^ (v_k >> 1)) of the
    /// bits k set in the index.
    fn sobol_second_by_definition(i: u32) -> u32 {
        let (mut r, mut v) = (0u32, 0x8000_0000u32);
        for k in 0..32 {
            if i >> k & 1 != 0 {
                r ^= v;
            }
            v ^= v >> 1;
        }
        r
    }

    #[test]
    fn sobol_second_matches_its_direction_numbers() {
        let mut x = 0x1234_5678u32;
        for i in (0..4096u32).chain((0..4096).map(|_| {
            x = hash_u32(x);
            x
        })) {
            assert_eq!(
                sobol_second_reversed(i).reverse_bits(),
                sobol_second_by_definition(i),
                "index {i}"
            );
        }
    }

    /// Every power-of-two run of a pixel's points, from its start, is a
    /// (0, m, 2)-net: each of the 2^m elementary boxes of every shape
    /// (2^a x 2^(m-a)) holds exactly one point. That is what makes the
    /// sampler progressive and stratified in both coordinates at once.
    #[test]
    fn sobol_prefixes_are_nets_at_every_shape() {
        for key in [0u32, 1, 0xdead_beef, hash_u32(7)] {
            for m in 0..=8u32 {
                let n = 1u32 << m;
                let points: Vec<[f64; 2]> = (0..n).map(|i| sobol_2d::<f64>(key, i)).collect();
                for a in 0..=m {
                    let (cols, rows) = (1u32 << a, 1u32 << (m - a));
                    let mut seen = vec![false; n as usize];
                    for p in &points {
                        let c = (p[0] * f64::from(cols)) as u32;
                        let r = (p[1] * f64::from(rows)) as u32;
                        let cell = (r * cols + c) as usize;
                        assert!(
                            !seen[cell],
                            "key {key:#x}, {n} points, {cols}x{rows}: two in one box"
                        );
                        seen[cell] = true;
                    }
                }
            }
        }
    }

    #[test]
    fn an_area_pattern_draws_its_dimensions_points() {
        let pattern = AreaPattern::new(Sampler::Sobol, 3, 41, 5, STREAM_LIGHT + 1);
        let key = sobol_key(3, 41, STREAM_LIGHT + 1);
        for m in 0..16 {
            assert_eq!(pattern.uv::<f64>(m, 16), sobol_2d::<f64>(key, 5 * 16 + m));
        }
    }

    #[test]
    fn sobol_dimensions_of_one_pixel_differ() {
        // The index shuffle differs per key: the same sample index lands in
        // unrelated places of two dimensions (the position and the time).
        let (a, b) = (sobol_key(0, 5, STREAM_PIXEL), sobol_key(0, 5, STREAM_TIME));
        let same = (0..64)
            .filter(|&i| {
                let p = sobol_2d::<f64>(a, i)[0];
                let t = sobol_1d::<f64>(b, i);
                (p * 8.0) as u32 == (t * 8.0) as u32
            })
            .count();
        // Independent: about 1 in 8 agree on their eighth; tied: all 64.
        assert!(same < 24, "{same} of 64 samples share their eighth");
    }

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
