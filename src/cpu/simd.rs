//! The CPU reference's SIMD kernels on the 4-wide tree (`bvh::wide`):
//! four boxes in one test (`Vec4` lanes in f32, `DVec4` in f64, each lane
//! `trace::hit_aabb`'s arithmetic) and a leaf block's up to four triangles
//! in one watertight test in f32, each lane operation for operation the
//! scalar test.

use glam::{Vec3, Vec4};

use crate::bvh::wide::{LeafBlock, Node4, WideBvh};

/// Whether the CPU runs the packets' AVX2 kernels: AVX2 and the bit
/// instructions every AVX2 CPU has (POPCNT, BMI1, BMI2, LZCNT), which the
/// kernels are compiled with (`#[target_feature(enable = "avx2,bmi1,bmi2,
/// lzcnt,popcnt")]`): without POPCNT a lane count (`count_ones`, asked at
/// every node visit and leaf) is a dozen shifts and masks (with it, one
/// thread, minimums of 61 renders on the AVX-512 machine: `table` 22.0 ->
/// 21.3 ms, the 240k grid 92.6 -> 90.5).
#[cfg(target_arch = "x86_64")]
#[inline]
pub fn has_avx2() -> bool {
    use std::arch::is_x86_feature_detected as has;
    has!("avx2") && has!("popcnt") && has!("bmi1") && has!("bmi2") && has!("lzcnt")
}

/// Whether the CPU runs the packets' AVX-512 kernels: AVX-512F and
/// `has_avx2`'s instructions (`#[target_feature(enable = "avx512f,bmi1,
/// bmi2,lzcnt,popcnt")]`).
#[cfg(target_arch = "x86_64")]
#[inline]
pub fn has_avx512() -> bool {
    std::arch::is_x86_feature_detected!("avx512f") && has_avx2()
}

/// Starts loading what will be read soon: every cache line `items` (side
/// by side in memory) touch, with a counted loop over the lines (a
/// `step_by` per item took a twentieth of the traversal's instructions on
/// the 240k grid, by cachegrind).
#[inline(always)]
pub fn prefetch<T>(items: &[T]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let range = items.as_ptr_range();
        // From the line holding the first byte to the one holding the
        // last: an item need not start on a line.
        let mut line = range.start as usize & !63;
        while line < range.end as usize {
            // SAFETY: prefetching has no effect on memory, and never faults.
            unsafe { _mm_prefetch(line as *const i8, _MM_HINT_T0) };
            line += 64;
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = items;
}

/// Starts loading the node in `node`'s lane `lane` (a node child) and its
/// leaf blocks, for a walk that will open it soon: the next node then
/// arrives while this one's leaves are tested, and its leaves with it.
#[inline(always)]
pub fn prefetch_child(tree: &WideBvh, node: &Node4, lane: usize) {
    prefetch(std::slice::from_ref(&tree.nodes[node.child[lane] as usize]));
    prefetch(&tree.leaves[node.leaf_run(lane)]);
}

/// The watertight test (`trace::hit_triangle`) on a block's triangles, one
/// per SIMD lane, operation for operation as the scalar one, so each lane
/// gives the scalar test's t and barycentrics to the bit. Returns the lane
/// of the nearest hit before `t_max` (the first of equal ones, as a scalar
/// loop keeping strictly nearer hits would) with its t, b1, b2.
#[inline(always)]
pub fn hit_block_f32(
    origin: Vec3,
    k: [usize; 3],
    shear: Vec3,
    block: &LeafBlock,
    t_max: f32,
) -> Option<(usize, f32, f32, f32)> {
    let [kx, ky, kz] = k;
    let o = origin.to_array();
    let rel = |axis: usize, corner: usize| block.p[axis][corner] - Vec4::splat(o[axis]);
    let (s0, s1, s2) = (
        Vec4::splat(shear.x),
        Vec4::splat(shear.y),
        Vec4::splat(shear.z),
    );
    let (a_z, b_z, c_z) = (rel(kz, 0), rel(kz, 1), rel(kz, 2));
    let ax = rel(kx, 0) - s0 * a_z;
    let ay = rel(ky, 0) - s1 * a_z;
    let bx = rel(kx, 1) - s0 * b_z;
    let by = rel(ky, 1) - s1 * b_z;
    let cx = rel(kx, 2) - s0 * c_z;
    let cy = rel(ky, 2) - s1 * c_z;
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    let zero = Vec4::ZERO;
    let some_negative = u.cmplt(zero) | v.cmplt(zero) | w.cmplt(zero);
    let some_positive = u.cmpgt(zero) | v.cmpgt(zero) | w.cmpgt(zero);
    let det = u + v + w;
    let t_scaled = u * (s2 * a_z) + v * (s2 * b_z) + w * (s2 * c_z);
    let end = Vec4::splat(t_max) * det;
    let positive = t_scaled.cmpgt(zero) & t_scaled.cmplt(end);
    let negative = t_scaled.cmplt(zero) & t_scaled.cmpgt(end);
    let det_positive = det.cmpgt(zero);
    let inside = (det_positive & positive) | (!det_positive & negative);
    let hit = !(some_negative & some_positive) & det.cmpne(zero) & inside;
    let mut mask = hit.bitmask() & block.lanes();
    if mask == 0 {
        return None;
    }
    let inv_det = Vec4::ONE / det;
    let (t, b1, b2) = (t_scaled * inv_det, v * inv_det, w * inv_det);
    let mut best: Option<(usize, f32, f32, f32)> = None;
    while mask != 0 {
        let lane = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        let limit = best.map_or(t_max, |b| b.1);
        if t[lane] < limit {
            best = Some((lane, t[lane], b1[lane], b2[lane]));
        }
    }
    best
}

/// The four boxes of `node` against a ray from `origin` with `inv_dir`,
/// in f32 SIMD lanes: a bit per lane hit before `t_max`, and the entry t
/// per lane. Operation for operation `trace::hit_aabb`.
#[inline(always)]
pub fn hit_boxes_f32(
    origin: glam::Vec3,
    inv_dir: glam::Vec3,
    node: &Node4,
    t_max: f32,
    box_t_scale: f32,
) -> (u32, [f32; 4]) {
    let slab = |axis: usize, o: f32, inv: f32| {
        let t0 = (node.lo[axis] - Vec4::splat(o)) * Vec4::splat(inv);
        let t1 = (node.hi[axis] - Vec4::splat(o)) * Vec4::splat(inv);
        (t0.min(t1), t0.max(t1))
    };
    let (nx, fx) = slab(0, origin.x, inv_dir.x);
    let (ny, fy) = slab(1, origin.y, inv_dir.y);
    let (nz, fz) = slab(2, origin.z, inv_dir.z);
    let t_near = nx.max(ny).max(nz.max(Vec4::ZERO));
    let t_far = fx.min(fy).min(fz.min(Vec4::splat(t_max))) * Vec4::splat(box_t_scale);
    (t_near.cmple(t_far).bitmask(), t_near.to_array())
}

/// `hit_boxes_f32` in f64 (the ground-truth reference): the f32 boxes
/// widened exactly, each lane `trace::hit_aabb`'s arithmetic in f64.
#[inline(always)]
pub fn hit_boxes_f64(
    origin: glam::DVec3,
    inv_dir: glam::DVec3,
    node: &Node4,
    t_max: f64,
    box_t_scale: f64,
) -> (u32, [f64; 4]) {
    use glam::DVec4;
    let slab = |axis: usize, o: f64, inv: f64| {
        let t0 = (node.lo[axis].as_dvec4() - DVec4::splat(o)) * DVec4::splat(inv);
        let t1 = (node.hi[axis].as_dvec4() - DVec4::splat(o)) * DVec4::splat(inv);
        (t0.min(t1), t0.max(t1))
    };
    let (nx, fx) = slab(0, origin.x, inv_dir.x);
    let (ny, fy) = slab(1, origin.y, inv_dir.y);
    let (nz, fz) = slab(2, origin.z, inv_dir.z);
    let t_near = nx.max(ny).max(nz.max(DVec4::ZERO));
    let t_far = fx.min(fy).min(fz.min(DVec4::splat(t_max))) * DVec4::splat(box_t_scale);
    (t_near.cmple(t_far).bitmask(), t_near.to_array())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::wide::collapse;
    use crate::bvh::wide::tests::{corners, scene};
    use crate::bvh::Bvh;
    use crate::scene::Scene;

    /// Closest and any hits through the collapsed tree are those of testing
    /// every primitive, in both precisions.
    #[test]
    fn traversal_finds_what_testing_everything_finds() {
        use crate::cpu::trace::{hit_triangle, make_ray, traverse, CpuGeometry, CpuScene};
        use crate::cpu::{CpuOptions, Real};
        fn check<R: Real>(scene: &Scene, bvh: &Bvh) {
            let camera = crate::camera::Camera::new(64, 48);
            let geometry = CpuGeometry::<R>::new(scene, bvh, &Default::default());
            let cpu = CpuScene::new(scene, bvh, &geometry, &camera, &CpuOptions::default());
            let mut state = 11u32;
            let mut next = || {
                state = crate::hash::hash_u32(state);
                R::from_f64(f64::from(state) / f64::from(u32::MAX) * 2.0 - 1.0)
            };
            let (mut hits, mut blocked) = (0, 0);
            for _ in 0..3000 {
                let origin = R::v3(next(), next(), next() * R::from_f64(4.0));
                let dir = R::normalize(R::v3(next(), next(), next() - R::ONE));
                let ray = make_ray(origin, dir, R::ZERO);
                let brute = cpu
                    .triangles
                    .iter()
                    .map(|t| hit_triangle(&ray, t, R::T_INF).0)
                    .fold(R::T_INF, |a, b| if b < a { b } else { a });
                let hit = traverse(&cpu, &ray, R::T_INF, false, &[], R::ZERO);
                assert_eq!(hit.t.to_f64(), brute.to_f64());
                hits += usize::from(hit.prim != u32::MAX);
                // A shadow ray of a random length up to 40.
                let end = (next() + R::ONE) * R::from_f64(20.0);
                let shadow = make_ray(origin, dir * end, R::ZERO);
                let any = traverse(&cpu, &shadow, R::ONE, true, &[], R::ZERO);
                let brute_any = cpu
                    .triangles
                    .iter()
                    .any(|t| hit_triangle(&shadow, t, R::ONE).0 < R::ONE);
                assert_eq!(any.prim != u32::MAX, brute_any);
                blocked += usize::from(brute_any);
            }
            assert!(hits > 300 && blocked > 30, "{hits} hits, {blocked} blocked");
            // NaN directions pass every box test, unused lanes included.
            let nan = R::from_f64(f64::NAN);
            let ray = make_ray(
                R::v3(R::ZERO, R::ZERO, R::ZERO),
                R::v3(nan, nan, nan),
                R::ZERO,
            );
            assert_eq!(
                traverse(&cpu, &ray, R::T_INF, false, &[], R::ZERO).prim,
                u32::MAX
            );
        }
        let scene = scene(2000);
        let bvh = Bvh::build(&scene);
        check::<f32>(&scene, &bvh);
        check::<f64>(&scene, &bvh);
    }

    /// Each lane of the SIMD triangle test gives the scalar test's t and
    /// barycentrics to the bit, and the block's answer is the nearest hit
    /// (the first of equal ones), as testing the leaf's triangles in order.
    #[test]
    fn simd_triangles_match_the_scalar_test() {
        use crate::cpu::trace::{hit_triangle, make_ray};
        use glam::Vec3;
        let scene = scene(3000);
        let bvh = Bvh::build(&scene);
        let wide = collapse(&bvh, corners(&scene));
        let tri = |r: u32| corners(&scene)(r).expect("triangle").map(Vec3::from);
        let mut state = 5u32;
        let mut next = || {
            state = crate::hash::hash_u32(state);
            f32::from_bits(state >> 9 | 0x3f80_0000) * 2.0 - 3.0
        };
        let mut hits = 0;
        for (leaf, span) in wide.leaves.iter().zip(&wide.spans) {
            let refs = &bvh.prim_refs[span.range()];
            for _ in 0..20 {
                // Rays from near the camera towards a point of the leaf's
                // first triangle, so many hit, some on edges and corners.
                let target = tri(refs[0])[0] * (1.0 + next().abs() * 1e-3);
                let origin = Vec3::new(next(), next(), next()) * 3.0;
                let ray = make_ray::<f32>(origin, (target - origin).normalize(), 0.0);
                let t_max = if next() > 0.0 { f32::MAX } else { 18.0 };
                let mut want = None;
                let mut limit = t_max;
                for (lane, &r) in refs.iter().enumerate() {
                    let (t, b1, b2) = hit_triangle(&ray, &tri(r), limit);
                    if t < limit {
                        limit = t;
                        want = Some((lane, t, b1, b2));
                    }
                }
                let got = hit_block_f32(ray.origin, ray.k, ray.shear, leaf, t_max);
                assert_eq!(
                    got.map(|g| (g.0, g.1.to_bits(), g.2.to_bits(), g.3.to_bits())),
                    want.map(|g| (g.0, g.1.to_bits(), g.2.to_bits(), g.3.to_bits()))
                );
                hits += usize::from(want.is_some());
            }
        }
        assert!(hits > wide.leaves.len() * 3, "{hits} hits");
    }

    /// The SIMD test gives each lane what the scalar test gives its box, in
    /// both precisions.
    #[test]
    fn simd_boxes_match_the_scalar_test() {
        use crate::cpu::trace::{hit_aabb, make_ray};
        use crate::cpu::Real;
        let scene = scene(500);
        let wide = collapse(&Bvh::build(&scene), corners(&scene));
        let mut state = 3u32;
        let mut next = || {
            state = crate::hash::hash_u32(state);
            f32::from_bits(state >> 9 | 0x3f80_0000) * 2.0 - 3.0
        };
        for i in 0..2000 {
            let origin = glam::Vec3::new(next(), next(), next()) * 4.0;
            let mut dir = glam::Vec3::new(next(), next(), next() - 1.0);
            // Some rays along an axis plane, of either sign of zero, and
            // some with a NaN direction.
            match i % 8 {
                1 => dir.x = 0.0,
                2 => dir.y = -0.0,
                3 => dir = glam::Vec3::new(0.0, -0.0, dir.z),
                4 if i % 64 == 4 => dir = glam::Vec3::NAN,
                _ => {}
            }
            let dir = if dir.is_nan() { dir } else { dir.normalize() };
            let ray = make_ray::<f32>(origin, dir, 0.0);
            let t_max = if next() > 0.0 {
                f32::MAX
            } else {
                next() + 20.0
            };
            for node in &wide.nodes {
                let (mask, t) =
                    hit_boxes_f32(ray.origin, ray.inv_dir, node, t_max, f32::BOX_T_SCALE);
                for (lane, t) in t.iter().enumerate() {
                    let (lo, hi) = node.lane_box(lane);
                    let scalar = hit_aabb(&ray, lo, hi, t_max);
                    let hit = scalar != f32::T_INF;
                    assert_eq!(mask & (1 << lane) != 0, hit, "lane {lane}");
                    if hit {
                        assert_eq!(t.to_bits(), scalar.to_bits());
                    }
                }
                let ray64 = make_ray::<f64>(origin.as_dvec3(), dir.as_dvec3(), 0.0);
                let t_max64 = f64::from(t_max);
                let (mask, t) =
                    hit_boxes_f64(ray64.origin, ray64.inv_dir, node, t_max64, f64::BOX_T_SCALE);
                for (lane, t) in t.iter().enumerate() {
                    let (lo, hi) = node.lane_box(lane);
                    let scalar = hit_aabb(&ray64, lo, hi, t_max64);
                    let hit = scalar != f64::T_INF;
                    assert_eq!(mask & (1 << lane) != 0, hit, "f64 lane {lane}");
                    if hit {
                        assert_eq!(t.to_bits(), scalar.to_bits());
                    }
                }
            }
        }
    }
}
