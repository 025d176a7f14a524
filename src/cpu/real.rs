//! The scalar/vector types the CPU reference is generic over: f32 with glam's
//! `Vec3` (the shader's twin) and f64 with `DVec3` (ground truth).

use std::fmt::Debug;
use std::ops::{Add, Div, Index, Mul, Neg, Sub};

use glam::{DVec3, Vec3};

use crate::bvh::wide::{LeafBlock, Node4};

/// A ray as both backends trace it: origin, direction and its inverse,
/// the watertight test's axis permutation `k` and shear, and its time.
#[derive(Clone, Copy, Debug)]
pub struct Ray<R: Real> {
    /// Where the ray starts.
    pub origin: R::V3,
    /// Its direction (not necessarily unit length).
    pub dir: R::V3,
    /// Per axis, one over `dir`.
    pub inv_dir: R::V3,
    /// The watertight test's axes: `k[2]` the largest of `dir`, then the other two.
    pub k: [usize; 3],
    /// The watertight test's shear of the triangle's corners.
    pub shear: R::V3,
    /// Seconds into the shutter (motion blur; 0 otherwise).
    pub time: R,
}

/// The precision the CPU reference computes in: `f32` (the shader's twin) or
/// `f64` (ground truth), each with its 3-vector.
pub trait Real:
    Copy
    + Send
    + Sync
    + Debug
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + 'static
{
    /// The 3-vector of this precision (`Vec3`, `DVec3`).
    type V3: Copy
        + Send
        + Sync
        + Debug
        + Add<Output = Self::V3>
        + Sub<Output = Self::V3>
        + Mul<Self, Output = Self::V3>
        + Mul<Self::V3, Output = Self::V3>
        + Neg<Output = Self::V3>
        + Index<usize, Output = Self>;

    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// 2.
    const TWO: Self;
    /// 0.5.
    const HALF: Self;
    /// Largest finite value: "no limit" for t, as `T_INF` in the shader.
    const T_INF: Self;
    /// 1 + 2 * gamma(3) for this precision (Ize 2013); see `BOX_T_SCALE` in the shader.
    const BOX_T_SCALE: Self;
    /// See `MIN_DIR` in the shader.
    const MIN_DIR: Self;
    /// Wächter-Binder offset constants; the f64 ones scale the f32 ones by
    /// the ratio of the two machine epsilons.
    const OFFSET_ORIGIN: Self;
    /// See `OFFSET_ORIGIN`.
    const OFFSET_FLOAT_SCALE: Self;
    /// See `OFFSET_ORIGIN`.
    const OFFSET_INT_SCALE: Self;
    /// The naive methods' magic numbers; see `NAIVE_OFFSET` in the shader.
    const NAIVE_OFFSET: Self;
    /// See `NAIVE_OFFSET`.
    const NAIVE_DET_EPSILON: Self;

    /// The nearest value of this precision.
    fn from_f64(x: f64) -> Self;
    /// The nearest value of this precision.
    fn from_u32(x: u32) -> Self;
    /// The value as an `f64` (exact).
    fn to_f64(self) -> f64;
    /// Square root.
    fn sqrt(self) -> Self;
    /// One over the square root.
    fn inverse_sqrt(self) -> Self;
    /// `self` to the power `y`, as C's `pow` (0^0 = 1).
    fn powf(self, y: Self) -> Self;
    /// The smaller of the two.
    fn min(self, o: Self) -> Self;
    /// The larger of the two.
    fn max(self, o: Self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// Sine (radians).
    fn sin(self) -> Self;
    /// Cosine (radians).
    fn cos(self) -> Self;
    /// π.
    const PI: Self;
    /// 1 for zero and above, -1 below.
    fn sign_nonzero(self) -> Self {
        if self >= Self::ZERO {
            Self::ONE
        } else {
            -Self::ONE
        }
    }

    /// A vector of three components.
    fn v3(x: Self, y: Self, z: Self) -> Self::V3;
    /// The vector rounded to this precision.
    fn v3_from_f64(v: DVec3) -> Self::V3;
    /// The vector in this precision (exact).
    fn v3_from_f32(v: [f32; 3]) -> Self::V3;
    /// The vector rounded to f32.
    fn v3_to_f32(v: Self::V3) -> [f32; 3];
    /// The vector as f64 (exact).
    fn v3_to_f64(v: Self::V3) -> [f64; 3];
    /// Whether any component is infinite or NaN.
    fn nonfinite(v: Self::V3) -> bool;
    /// Dot product.
    fn dot(a: Self::V3, b: Self::V3) -> Self;
    /// Cross product.
    fn cross(a: Self::V3, b: Self::V3) -> Self::V3;
    /// The vector divided by its length.
    fn normalize(v: Self::V3) -> Self::V3;
    /// Per component, the smaller.
    fn vmin(a: Self::V3, b: Self::V3) -> Self::V3;
    /// Per component, the larger.
    fn vmax(a: Self::V3, b: Self::V3) -> Self::V3;
    /// Each component clamped to [0, 1].
    fn clamp01(v: Self::V3) -> Self::V3;
    /// Per component, the absolute value.
    fn vabs(v: Self::V3) -> Self::V3;

    /// Moves `p` off its surface along `n` by whole ulps (Ray Tracing Gems ch. 6).
    /// `scale`: per-axis magnitude of the coordinates `p` came from.
    fn offset_ray(p: Self::V3, n: Self::V3, scale: Self::V3) -> Self::V3;

    /// `hit_aabb` on the four boxes of a collapsed node: a bit per lane
    /// hit, and each lane's entry t (`wide::hit_boxes_f32`, `_f64`).
    fn hit_boxes(ray: &Ray<Self>, node: &Node4, t_max: Self) -> (u32, [Self; 4]);

    /// Whether `hit_block` tests a leaf's triangles together; only then
    /// does a collapsed tree get leaves it may be called on (`LeafBlock::simd`).
    const SIMD_LEAVES: bool = false;

    /// For a box's entry t (+0 or more, never NaN): bits that order as the
    /// value does, in 32 bits, where the precision has them, so that a
    /// node's hit lanes sort without branches (`trace::traverse`'s
    /// `nearest_last`). None for f64, whose 63 leave no room for a lane.
    #[inline(always)]
    fn entry_key(self) -> Option<u64> {
        None
    }

    /// `wide::hit_block_f32` where `SIMD_LEAVES`; never called otherwise.
    fn hit_block(
        _ray: &Ray<Self>,
        _block: &LeafBlock,
        _t_max: Self,
    ) -> Option<(usize, Self, Self, Self)> {
        None
    }
}

/// `Real::offset_ray` one coordinate at a time, as the free functions
/// `$name` (a vector) and `$coord` (one coordinate): f64's, and f32's off
/// x86-64 (and there the definition that `offset_sse2` must match).
macro_rules! scalar_offset_ray {
    ($name:ident, $coord:ident, $t:ty, $v:ty, $i:ty) => {
        pub(crate) fn $coord(p: $t, n: $t, scale: $t) -> $t {
            // Truncation toward zero, as the shader's vec3<i32>(f32).
            let of_i = (<$t>::OFFSET_INT_SCALE * n) as $i;
            let bits = p.to_bits() as $i;
            let moved = if p < 0.0 {
                bits.wrapping_sub(of_i)
            } else {
                bits.wrapping_add(of_i)
            };
            if p.abs() < <$t>::OFFSET_ORIGIN * scale {
                p + <$t>::OFFSET_FLOAT_SCALE * scale * n
            } else {
                <$t>::from_bits(moved as _)
            }
        }

        fn $name(p: $v, n: $v, scale: $v) -> $v {
            <$v>::new(
                $coord(p.x, n.x, scale.x),
                $coord(p.y, n.y, scale.y),
                $coord(p.z, n.z, scale.z),
            )
        }
    };
}

scalar_offset_ray!(offset_ray_f64, offset_f64, f64, DVec3, i64);
#[cfg(any(test, not(target_arch = "x86_64")))]
scalar_offset_ray!(offset_ray_f32_scalar, offset_f32_scalar, f32, Vec3, i32);

macro_rules! impl_real {
    ($t:ty, $v:ty, $eps_ratio:expr $(, $extra:item)*) => {
        impl Real for $t {
            $($extra)*
            type V3 = $v;
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            const TWO: Self = 2.0;
            const HALF: Self = 0.5;
            const T_INF: Self = <$t>::MAX;
            const BOX_T_SCALE: Self = {
                // gamma(3) = 3u / (1 - 3u), u = unit roundoff = EPSILON / 2.
                let u = <$t>::EPSILON * 0.5;
                1.0 + 2.0 * (3.0 * u / (1.0 - 3.0 * u))
            };
            const MIN_DIR: Self = 1e-30;
            const OFFSET_ORIGIN: Self = 1.0 / 32.0;
            const OFFSET_FLOAT_SCALE: Self = 1.0 / 65536.0 * $eps_ratio;
            const OFFSET_INT_SCALE: Self = 256.0;
            const NAIVE_OFFSET: Self = 1e-4;
            const NAIVE_DET_EPSILON: Self = 1e-6;

            fn from_f64(x: f64) -> Self {
                x as $t
            }
            fn from_u32(x: u32) -> Self {
                x as $t
            }
            fn to_f64(self) -> f64 {
                self as f64
            }
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            fn inverse_sqrt(self) -> Self {
                1.0 / <$t>::sqrt(self)
            }
            fn powf(self, y: Self) -> Self {
                <$t>::powf(self, y)
            }
            fn min(self, o: Self) -> Self {
                <$t>::min(self, o)
            }
            fn max(self, o: Self) -> Self {
                <$t>::max(self, o)
            }
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            fn sin(self) -> Self {
                <$t>::sin(self)
            }
            fn cos(self) -> Self {
                <$t>::cos(self)
            }
            // The shader's literal, rounded to this precision.
            const PI: Self = std::f64::consts::PI as $t;
            fn v3(x: Self, y: Self, z: Self) -> $v {
                <$v>::new(x, y, z)
            }
            fn v3_from_f64(v: DVec3) -> $v {
                <$v>::new(v.x as $t, v.y as $t, v.z as $t)
            }
            fn v3_from_f32(v: [f32; 3]) -> $v {
                <$v>::new(v[0] as $t, v[1] as $t, v[2] as $t)
            }
            fn v3_to_f32(v: $v) -> [f32; 3] {
                [v.x as f32, v.y as f32, v.z as f32]
            }
            fn v3_to_f64(v: $v) -> [f64; 3] {
                [v.x as f64, v.y as f64, v.z as f64]
            }
            fn nonfinite(v: $v) -> bool {
                !v.is_finite()
            }
            fn dot(a: $v, b: $v) -> Self {
                a.dot(b)
            }
            fn cross(a: $v, b: $v) -> $v {
                a.cross(b)
            }
            fn normalize(v: $v) -> $v {
                v * (1.0 / v.dot(v).sqrt())
            }
            fn vmin(a: $v, b: $v) -> $v {
                a.min(b)
            }
            fn vmax(a: $v, b: $v) -> $v {
                a.max(b)
            }
            fn clamp01(v: $v) -> $v {
                v.clamp(<$v>::ZERO, <$v>::ONE)
            }
            fn vabs(v: $v) -> $v {
                v.abs()
            }
        }
    };
}

impl_real!(
    f32,
    Vec3,
    1.0,
    #[inline(always)]
    fn offset_ray(p: Vec3, n: Vec3, scale: Vec3) -> Vec3 {
        #[cfg(target_arch = "x86_64")]
        return offset_ray_sse2(p, n, scale);
        #[cfg(not(target_arch = "x86_64"))]
        return offset_ray_f32_scalar(p, n, scale);
    },
    #[inline(always)]
    fn hit_boxes(ray: &Ray<f32>, node: &Node4, t_max: f32) -> (u32, [f32; 4]) {
        super::simd::hit_boxes_f32(ray.origin, ray.inv_dir, node, t_max, Self::BOX_T_SCALE)
    },
    const SIMD_LEAVES: bool = true;,
    #[inline(always)]
    fn entry_key(self) -> Option<u64> {
        Some(u64::from(self.to_bits()))
    },
    #[inline(always)]
    fn hit_block(ray: &Ray<f32>, block: &LeafBlock, t_max: f32) -> Option<(usize, f32, f32, f32)> {
        super::simd::hit_block_f32(ray.origin, ray.k, ray.shear, block, t_max)
    }
);
impl_real!(
    f64,
    DVec3,
    (f64::EPSILON / f32::EPSILON as f64),
    #[inline(always)]
    fn offset_ray(p: DVec3, n: DVec3, scale: DVec3) -> DVec3 {
        offset_ray_f64(p, n, scale)
    },
    #[inline(always)]
    fn hit_boxes(ray: &Ray<f64>, node: &Node4, t_max: f64) -> (u32, [f64; 4]) {
        super::simd::hit_boxes_f64(ray.origin, ray.inv_dir, node, t_max, Self::BOX_T_SCALE)
    }
);

/// f32's `offset_ray`, the three coordinates in one SSE2 register: per
/// coordinate the scalar version's operations on the same values (its
/// saturating `as i32` included), so the same bits, in a third of the
/// instructions (it ran once a shadow ray, 86 instructions a call by
/// cachegrind, a twentieth of a 240k-grid render's).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn offset_ray_sse2(p: Vec3, n: Vec3, scale: Vec3) -> Vec3 {
    use std::arch::x86_64::*;
    // SAFETY: SSE2 is part of x86-64; the rest is arithmetic on registers.
    unsafe {
        let [p, n, s] = [p, n, scale].map(|v| _mm_setr_ps(v.x, v.y, v.z, 0.0));
        let out = offset_sse2(p, n, s);
        let mut lanes = [0.0f32; 4];
        _mm_storeu_ps(lanes.as_mut_ptr(), out);
        Vec3::new(lanes[0], lanes[1], lanes[2])
    }
}

/// f32's `offset_ray` of one coordinate in each of four lanes (`p` moved
/// along `n`, `scale` its size): the scalar version's operations, its
/// saturating `as i32` included, so the same bits. The packets' shadow
/// rays take it four rays at a time, where the compiler's own `as i32`
/// ran a lane at a time (5% of `table`'s instructions).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn offset_sse2(
    p: std::arch::x86_64::__m128,
    n: std::arch::x86_64::__m128,
    s: std::arch::x86_64::__m128,
) -> std::arch::x86_64::__m128 {
    use std::arch::x86_64::*;
    // SAFETY: SSE2 is part of x86-64; the rest is arithmetic on registers.
    unsafe {
        let of = _mm_mul_ps(_mm_set1_ps(f32::OFFSET_INT_SCALE), n);
        // `as i32`: NaN to 0 and 2^31 or more to i32::MAX, where the
        // conversion gives i32::MIN (as `as` does below -2^31).
        let of_i = _mm_cvttps_epi32(of);
        let big = _mm_castps_si128(_mm_cmpge_ps(of, _mm_set1_ps(2_147_483_648.0)));
        let of_i = _mm_or_si128(
            _mm_andnot_si128(big, of_i),
            _mm_and_si128(big, _mm_set1_epi32(i32::MAX)),
        );
        let of_i = _mm_andnot_si128(_mm_castps_si128(_mm_cmpunord_ps(of, of)), of_i);
        // Wrapping add, or subtract where p < 0 (not for -0.0): the
        // negation of x is (x ^ -1) + 1.
        let neg = _mm_castps_si128(_mm_cmplt_ps(p, _mm_setzero_ps()));
        let step = _mm_sub_epi32(_mm_xor_si128(of_i, neg), neg);
        let moved = _mm_castsi128_ps(_mm_add_epi32(_mm_castps_si128(p), step));
        let abs = _mm_andnot_ps(_mm_set1_ps(-0.0), p);
        let near_origin = _mm_cmplt_ps(abs, _mm_mul_ps(_mm_set1_ps(f32::OFFSET_ORIGIN), s));
        let float = _mm_add_ps(
            p,
            _mm_mul_ps(_mm_mul_ps(_mm_set1_ps(f32::OFFSET_FLOAT_SCALE), s), n),
        );
        _mm_or_ps(
            _mm_and_ps(near_origin, float),
            _mm_andnot_ps(near_origin, moved),
        )
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use glam::Vec3;

    /// The SSE2 offset gives the scalar one's bits on ordinary points and
    /// normals and on every special value a coordinate can hold: zeros of
    /// both signs, subnormals, the largest floats, infinities, NaN, and
    /// normals whose offset overflows an i32 either way.
    #[test]
    fn sse2_offset_is_the_scalar_offset_to_the_bit() {
        let specials = [
            0.0,
            -0.0,
            1e-40,
            -1e-40,
            f32::MIN_POSITIVE,
            0.03,
            -0.03,
            1.0,
            -1.0,
            0.5,
            3.0e7,
            -3.0e7,
            1e10,
            -1e10,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        let mut state = 0x1234_5678u32;
        let mut next = move || {
            state = crate::hash::hash_u32(state);
            state
        };
        let mut cases = Vec::new();
        for &a in &specials {
            for &b in &specials {
                cases.push((
                    Vec3::new(a, b, -a),
                    Vec3::new(b, a, 0.7),
                    Vec3::new(a.abs(), 1.0, b.abs()),
                ));
            }
        }
        for _ in 0..100_000 {
            // Any bit pattern, then values of ordinary size.
            let mut v = || {
                Vec3::new(
                    f32::from_bits(next()),
                    f32::from_bits(next()),
                    f32::from_bits(next()),
                )
            };
            cases.push((v(), v(), v()));
            let mut w = || (next() as f32 / u32::MAX as f32 - 0.5) * 200.0;
            let n = Vec3::new(w(), w(), w()).normalize_or_zero();
            let p = Vec3::new(w(), w(), w()) * 0.01;
            cases.push((p, n, p.abs() + Vec3::splat(w().abs())));
        }
        for (p, n, s) in cases {
            let want = super::offset_ray_f32_scalar(p, n, s)
                .to_array()
                .map(f32::to_bits);
            let got = super::offset_ray_sse2(p, n, s).to_array().map(f32::to_bits);
            assert_eq!(got, want, "p {p:?} n {n:?} scale {s:?}");
        }
    }
}
