//! The scalar/vector types the CPU reference is generic over: f32 with glam's
//! `Vec3` (the shader's twin) and f64 with `DVec3` (ground truth).

use std::fmt::Debug;
use std::ops::{Add, Div, Index, Mul, Neg, Sub};

use glam::{DVec3, Vec3};

use super::trace::Ray;
use super::wide::{LeafBlock, Node4};

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

    const ZERO: Self;
    const ONE: Self;
    const TWO: Self;
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
    const OFFSET_FLOAT_SCALE: Self;
    const OFFSET_INT_SCALE: Self;
    /// The naive methods' magic numbers; see `NAIVE_OFFSET` in the shader.
    const NAIVE_OFFSET: Self;
    const NAIVE_DET_EPSILON: Self;

    fn from_f64(x: f64) -> Self;
    fn from_u32(x: u32) -> Self;
    fn to_f64(self) -> f64;
    fn sqrt(self) -> Self;
    fn inverse_sqrt(self) -> Self;
    fn powf(self, y: Self) -> Self;
    fn min(self, o: Self) -> Self;
    fn max(self, o: Self) -> Self;
    fn abs(self) -> Self;
    fn sin(self) -> Self;
    fn cos(self) -> Self;
    const PI: Self;
    fn sign_nonzero(self) -> Self {
        if self >= Self::ZERO {
            Self::ONE
        } else {
            -Self::ONE
        }
    }

    fn v3(x: Self, y: Self, z: Self) -> Self::V3;
    fn v3_from_f64(v: DVec3) -> Self::V3;
    fn v3_from_f32(v: [f32; 3]) -> Self::V3;
    fn v3_to_f32(v: Self::V3) -> [f32; 3];
    fn v3_to_f64(v: Self::V3) -> [f64; 3];
    /// Whether any component is infinite or NaN.
    fn nonfinite(v: Self::V3) -> bool;
    fn dot(a: Self::V3, b: Self::V3) -> Self;
    fn cross(a: Self::V3, b: Self::V3) -> Self::V3;
    fn normalize(v: Self::V3) -> Self::V3;
    fn vmin(a: Self::V3, b: Self::V3) -> Self::V3;
    fn vmax(a: Self::V3, b: Self::V3) -> Self::V3;
    fn clamp01(v: Self::V3) -> Self::V3;
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

    /// `wide::hit_block_f32` where `SIMD_LEAVES`; never called otherwise.
    fn hit_block(
        _ray: &Ray<Self>,
        _block: &LeafBlock,
        _t_max: Self,
    ) -> Option<(usize, Self, Self, Self)> {
        None
    }
}

macro_rules! impl_real {
    ($t:ty, $v:ty, $i:ty, $eps_ratio:expr $(, $extra:item)*) => {
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
            fn offset_ray(p: $v, n: $v, scale: $v) -> $v {
                let off = |p: $t, n: $t, scale: $t| -> $t {
                    // Truncation toward zero, as the shader's vec3<i32>(f32).
                    let of_i = (Self::OFFSET_INT_SCALE * n) as $i;
                    let bits = p.to_bits() as $i;
                    let moved = if p < 0.0 {
                        bits.wrapping_sub(of_i)
                    } else {
                        bits.wrapping_add(of_i)
                    };
                    if p.abs() < Self::OFFSET_ORIGIN * scale {
                        p + Self::OFFSET_FLOAT_SCALE * scale * n
                    } else {
                        <$t>::from_bits(moved as _)
                    }
                };
                <$v>::new(
                    off(p.x, n.x, scale.x),
                    off(p.y, n.y, scale.y),
                    off(p.z, n.z, scale.z),
                )
            }
        }
    };
}

impl_real!(
    f32,
    Vec3,
    i32,
    1.0,
    #[inline(always)]
    fn hit_boxes(ray: &Ray<f32>, node: &Node4, t_max: f32) -> (u32, [f32; 4]) {
        super::wide::hit_boxes_f32(ray.origin, ray.inv_dir, node, t_max, Self::BOX_T_SCALE)
    },
    const SIMD_LEAVES: bool = true;,
    #[inline(always)]
    fn hit_block(ray: &Ray<f32>, block: &LeafBlock, t_max: f32) -> Option<(usize, f32, f32, f32)> {
        super::wide::hit_block_f32(ray, block, t_max)
    }
);
impl_real!(
    f64,
    DVec3,
    i64,
    (f64::EPSILON / f32::EPSILON as f64),
    #[inline(always)]
    fn hit_boxes(ray: &Ray<f64>, node: &Node4, t_max: f64) -> (u32, [f64; 4]) {
        super::wide::hit_boxes_f64(ray.origin, ray.inv_dir, node, t_max, Self::BOX_T_SCALE)
    }
);
