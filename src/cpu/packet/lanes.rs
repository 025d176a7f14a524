//! A packet's data: one f32 per ray in aligned lanes, the rays in SoA
//! form, the per-node child results, and the packet's rays themselves.

use crate::cpu::trace::{CpuScene, Ray, Sphere};
use crate::cpu::Real;
use glam::{BVec4A, Vec3, Vec4};

/// A node that at most this many of a packet's rays reach is walked by each
/// of them alone. Low in a big tree most packet visits carry one or two rays
/// (the 2M grid: 111,054 of the primary packets' 319,602 node visits), and
/// each paid the whole packet's pops, sorts and masks. Thread CPU time,
/// alternating, medians of 7, five rounds on a quiet machine: the 2M grid
/// 3-4% faster at 2 (1.5-3% at 3, 1-2.5% at 1), the other scenes within
/// 1%. (In stop 31, on the same machine in a noisy hour, it did not show.)
pub(super) const HAND_OFF: u32 = 2;

/// Rays in a packet.
pub const WIDTH: usize = 32;

/// Fewer of an octet's rays than this meet a leaf block one by one: by
/// operation count the octet test (four triangles of about 45 operations)
/// costs what about three single rays' block tests do; 1 and 5 measured
/// level with 3 within this machine's noise.
pub(super) const OCTET_MIN_RAYS: u32 = 3;

// A packet's rays are bits of a u32 mask, taken eight (AVX2) or sixteen
// (AVX-512) at a time.
const _: () = assert!(WIDTH <= 32 && WIDTH.is_multiple_of(16));

/// SSE vectors (quads of rays) in a packet.
pub(super) const QUADS: usize = WIDTH / 4;

/// One f32 per ray of a packet, aligned for its loads in quads (SSE),
/// octets (AVX2) and sixteens (AVX-512).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(super) struct Lanes(pub(super) [f32; WIDTH]);

impl Lanes {
    pub(super) const ZERO: Lanes = Lanes([0.0; WIDTH]);

    #[inline(always)]
    pub(super) fn quad(&self, h: usize) -> Vec4 {
        Vec4::from_slice(&self.0[4 * h..4 * h + 4])
    }

    #[inline(always)]
    pub(super) fn set_quad(&mut self, h: usize, v: Vec4) {
        v.write_to_slice(&mut self.0[4 * h..4 * h + 4]);
    }
}

/// A packet's rays by component.
pub(super) struct Soa {
    pub(super) o: [Lanes; 3],
    pub(super) dir: [Lanes; 3],
    pub(super) inv: [Lanes; 3],
    /// The rays' `shear`, for the triangle test.
    pub(super) shear: [Lanes; 3],
    /// Per octet of rays, their axis order `k` where all eight share it
    /// (the octet's triangle tests can then run across its rays).
    pub(super) k: [Option<[usize; 3]>; WIDTH / 8],
    /// Per ray its `k`, packed (`pack_k`).
    pub(super) axes: [u32; WIDTH],
}

/// A ray's axis order in a word: kx | ky << 2 | kz << 4.
#[inline(always)]
fn pack_k(k: [usize; 3]) -> u32 {
    (k[0] | k[1] << 2 | k[2] << 4) as u32
}

#[inline(always)]
fn unpack_k(a: u32) -> [usize; 3] {
    [(a & 3) as usize, (a >> 2 & 3) as usize, (a >> 4) as usize]
}

impl Soa {
    /// No rays yet: space for `make_rays`, kept from packet to packet.
    pub(super) const EMPTY: Soa = Soa {
        o: ZEROS,
        dir: ZEROS,
        inv: ZEROS,
        shear: ZEROS,
        k: [None; WIDTH / 8],
        axes: [0; WIDTH],
    };

    #[inline(always)]
    pub(super) fn new(rays: &[Ray<f32>; WIDTH]) -> Self {
        let mut soa = Soa::EMPTY;
        for (r, ray) in rays.iter().enumerate() {
            for axis in 0..3 {
                soa.o[axis].0[r] = ray.origin[axis];
                soa.dir[axis].0[r] = ray.dir[axis];
                soa.inv[axis].0[r] = ray.inv_dir[axis];
                soa.shear[axis].0[r] = ray.shear[axis];
            }
            soa.axes[r] = pack_k(ray.k);
        }
        soa.share_k();
        soa
    }

    /// `k` from `axes`.
    #[inline(always)]
    fn share_k(&mut self) {
        for (g, k) in self.k.iter_mut().enumerate() {
            let octet = &self.axes[8 * g..8 * g + 8];
            *k = octet
                .iter()
                .all(|&a| a == octet[0])
                .then(|| unpack_k(octet[0]));
        }
    }

    /// `f(octet, axis order, its rays)` for each octet of `rays` that
    /// meets a leaf eight rays a register: those whose rays share an axis
    /// order and number `OCTET_MIN_RAYS` or more, taken out of `rays`.
    #[inline(always)]
    pub(super) fn take_octets(&self, rays: &mut u32, mut f: impl FnMut(usize, [usize; 3], u32)) {
        for (g, k) in self.k.iter().enumerate() {
            let m8 = *rays >> (8 * g) & 255;
            let Some(k) = *k else { continue };
            if m8.count_ones() >= OCTET_MIN_RAYS {
                *rays &= !(m8 << (8 * g));
                f(g, k, m8);
            }
        }
    }

    /// `take_octets` sixteen rays at a time: `f(sixteen, axis order, its
    /// rays)` for each pair of octets that share an axis order and would
    /// each be taken as an octet, taken out of `rays`.
    #[inline(always)]
    pub(super) fn take_sixteens(&self, rays: &mut u32, mut f: impl FnMut(usize, [usize; 3], u32)) {
        for h in 0..WIDTH / 16 {
            let (Some(a), Some(b)) = (self.k[2 * h], self.k[2 * h + 1]) else {
                continue;
            };
            let m16 = *rays >> (16 * h) & 0xffff;
            let full = |m: u32| m.count_ones() >= OCTET_MIN_RAYS;
            if a == b && full(m16 & 255) && full(m16 >> 8) {
                *rays &= !(m16 << (16 * h));
                f(h, a, m16);
            }
        }
    }

    /// Ray `r` whole, for the tests a ray takes alone (made only for
    /// those: building all of a packet's rays was 7% of `table`'s
    /// instructions).
    #[inline(always)]
    pub(super) fn ray(&self, r: usize) -> Ray<f32> {
        Ray {
            origin: lane(&self.o, r),
            dir: lane(&self.dir, r),
            inv_dir: lane(&self.inv, r),
            k: unpack_k(self.axes[r]),
            shear: lane(&self.shear, r),
            time: 0.0,
        }
    }
}

/// `trace::hit_sphere` (robust, no grazing band, the sphere where it
/// stands) for every ray of a packet, four at a time: the same operations
/// in the same order per lane, `f32::min` and `max` included (a NaN root
/// gives way to the other), so each ray gets the scalar test's t to the
/// bit. Each ray's limit is its own `best_t`; a miss is `T_INF`.
#[inline(always)]
pub(super) fn hit_sphere_rays(soa: &Soa, s: &Sphere<f32>, best_t: &Lanes) -> Lanes {
    let mut out = Lanes([f32::T_INF; WIDTH]);
    let rr = s.radius * s.radius;
    let dot = |a: [Vec4; 3], b: [Vec4; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let fmin = |a: Vec4, b: Vec4| {
        Vec4::select(
            a.is_nan_mask(),
            b,
            Vec4::select(b.is_nan_mask(), a, a.min(b)),
        )
    };
    let fmax = |a: Vec4, b: Vec4| {
        Vec4::select(
            a.is_nan_mask(),
            b,
            Vec4::select(b.is_nan_mask(), a, a.max(b)),
        )
    };
    for h in 0..QUADS {
        let d = [0, 1, 2].map(|axis| soa.dir[axis].quad(h));
        let f = [0, 1, 2].map(|axis| soa.o[axis].quad(h) - Vec4::splat(s.center[axis]));
        let a = dot(d, d);
        let b = -dot(f, d);
        let c = dot(f, f) - Vec4::splat(rr);
        let ba = b / a;
        let l = [0, 1, 2].map(|axis| f[axis] + d[axis] * ba);
        let disc = Vec4::splat(rr) - dot(l, l);
        let sign = Vec4::select(b.cmpge(Vec4::ZERO), Vec4::ONE, Vec4::NEG_ONE);
        let q = b + sign * (a * disc).sqrt();
        let miss = disc.cmplt(Vec4::ZERO);
        let t0 = Vec4::select(miss, Vec4::splat(f32::T_INF), c / q);
        let t1 = Vec4::select(miss, Vec4::splat(f32::T_INF), q / a);
        let (t_lo, t_hi) = (fmin(t0, t1), fmax(t0, t1));
        let t_max = best_t.quad(h);
        let zero = Vec4::ZERO;
        let lo_ok = t_lo.cmpgt(zero) & t_lo.cmplt(t_max);
        let hi_ok = t_hi.cmpgt(zero) & t_hi.cmplt(t_max);
        let t = Vec4::select(
            lo_ok,
            t_lo,
            Vec4::select(hi_ok, t_hi, Vec4::splat(f32::T_INF)),
        );
        out.set_quad(h, t);
    }
    out
}

/// A node's four children against a packet: per child lane, the rays
/// (of `mask`) whose box test it passes, their entry t, and the nearest of
/// those (the last two left at 0 and +inf in an any-hit traversal, which
/// does not need them). One per traversal, rewritten at each node (`reset`)
/// rather than made and returned per node: its 544 bytes were a `memset`
/// and a `memcpy` at every node visit (7% of the traversal's instructions
/// on the 22k grid, by callgrind).
pub(super) struct Children {
    pub(super) hits: [u32; 4],
    pub(super) near: [Lanes; 4],
    pub(super) nearest: [f32; 4],
}

impl Children {
    /// No ray in any box yet.
    pub(super) const NONE: Children = Children {
        hits: [0; 4],
        near: [Lanes::ZERO; 4],
        nearest: [f32::INFINITY; 4],
    };

    /// No ray in any box, for the next node. `near` keeps what it held:
    /// only the entries of rays in `hits` are read, and a node's test
    /// writes those (a whole octet or quad of them wherever one ray hit).
    #[inline(always)]
    pub(super) fn reset(&mut self) {
        self.hits = [0; 4];
        self.nearest = [f32::INFINITY; 4];
    }
}

/// The lanes of a 4-bit mask, for selects.
pub(super) const LANES: [BVec4A; 16] = {
    let mut out = [BVec4A::FALSE; 16];
    let mut m = 0;
    while m < 16 {
        out[m] = BVec4A::new(m & 1 != 0, m & 2 != 0, m & 4 != 0, m & 8 != 0);
        m += 1;
    }
    out
};

/// A node to open: its index, the rays whose box test reached it, and the
/// nearest of their entry t.
pub(super) type Entry = (u32, u32, f32);

/// What a traversal is asked: the closest hit (or, in an any-hit
/// traversal, a blocker) before `t_max` of each ray whose bit is set in
/// `active`.
#[derive(Clone, Copy)]
pub(super) struct Query<'a> {
    pub(super) soa: &'a Soa,
    pub(super) active: u32,
    pub(super) t_max: f32,
    /// Every ray's origin is (+0, +0, +0).
    pub(super) at_origin: bool,
}

/// Three components of one vector per ray.
pub(super) type V3s = [Lanes; 3];

pub(super) const ZEROS: V3s = [Lanes::ZERO; 3];

/// `v`'s lane `i` as a vector.
#[inline(always)]
pub(super) fn lane(v: &V3s, i: usize) -> Vec3 {
    Vec3::new(v[0].0[i], v[1].0[i], v[2].0[i])
}

/// Sets lane `i` of `v`.
#[inline(always)]
pub(super) fn set_lane(v: &mut V3s, i: usize, x: Vec3) {
    for (c, v) in v.iter_mut().enumerate() {
        v.0[i] = x[c];
    }
}

/// `trace::make_ray` (at time 0) for the rays whose origins and
/// directions `soa` holds (the rest of it is filled in here), in
/// loops over the lanes that fill whole registers: per lane the same
/// operations on the same values (`safe_dir`'s, `ray_with_inverse`'s axis
/// choice and shear), so each ray is `make_ray`'s to the bit. Made one
/// ray at a time, the axis choice's branches mispredicted on shadow rays
/// and each ray paid two divisions alone.
#[inline(always)]
pub(super) fn make_rays(soa: &mut Soa) {
    let Soa {
        dir: dirs,
        inv,
        shear,
        axes,
        ..
    } = soa;
    for (i, axes) in axes.iter_mut().enumerate() {
        let d = [dirs[0].0[i], dirs[1].0[i], dirs[2].0[i]];
        for (axis, &d) in d.iter().enumerate() {
            // `trace::safe_dir`.
            let sign = if d >= 0.0 { 1.0 } else { -1.0 };
            let safe = if d.abs() < f32::MIN_DIR {
                sign * f32::MIN_DIR
            } else {
                d
            };
            inv[axis].0[i] = 1.0 / safe;
        }
        let a = [d[0].abs(), d[1].abs(), d[2].abs()];
        let kz: u32 = if a[0] > a[1] && a[0] > a[2] {
            0
        } else if a[1] > a[2] {
            1
        } else {
            2
        };
        let pick = |k: u32| {
            if k == 0 {
                d[0]
            } else if k == 1 {
                d[1]
            } else {
                d[2]
            }
        };
        let dz = pick(kz);
        let kx = if kz == 2 { 0 } else { kz + 1 };
        let ky = if kx == 2 { 0 } else { kx + 1 };
        let (kx, ky) = if dz < 0.0 { (ky, kx) } else { (kx, ky) };
        let sz = 1.0 / dz;
        shear[0].0[i] = pick(kx) * sz;
        shear[1].0[i] = pick(ky) * sz;
        shear[2].0[i] = sz;
        *axes = pack_k([kx as usize, ky as usize, kz as usize]);
    }
    soa.share_k();
}

/// `trace::pixel_ray` for each of `pixels`, four at a time: the same
/// operations in the same order per lane (`camera_ray`'s, the
/// normalisation's, `make_ray`'s), so each ray is `pixel_ray`'s to the bit.
#[inline(always)]
pub(super) fn pixel_rays(scene: &CpuScene<f32>, pixels: &[[u32; 2]; WIDTH], out: &mut Soa) {
    let (w, h) = (scene.size[0] as f32, scene.size[1] as f32);
    let [hx, hy] = scene.half_extent;
    let dirs = &mut out.dir;
    for q in 0..QUADS {
        let x = Vec4::from_array(std::array::from_fn(|i| pixels[4 * q + i][0] as f32));
        let y = Vec4::from_array(std::array::from_fn(|i| pixels[4 * q + i][1] as f32));
        let two = Vec4::splat(2.0);
        let ndc_x = (two * (x + Vec4::splat(0.5)) / Vec4::splat(w) - Vec4::ONE) * Vec4::splat(hx);
        let ndc_y = (Vec4::ONE - two * (y + Vec4::splat(0.5)) / Vec4::splat(h)) * Vec4::splat(hy);
        // `Real::normalize` of (x, y, -1): its dot product, left to right.
        let len2 = ndc_x * ndc_x + ndc_y * ndc_y + Vec4::ONE;
        let s = Vec4::ONE / len2.sqrt();
        dirs[0].set_quad(q, ndc_x * s);
        dirs[1].set_quad(q, ndc_y * s);
        dirs[2].set_quad(q, Vec4::NEG_ONE * s);
    }
    out.o = ZEROS;
    make_rays(out);
}
