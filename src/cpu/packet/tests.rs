//! Packets against single rays: the same hits, shadow verdicts and
//! colours, where and as far as the module docs allow.

#[cfg(target_arch = "x86_64")]
use super::avx2::*;
#[cfg(target_arch = "x86_64")]
use super::avx512::*;
use super::lanes::*;
use super::sse::*;
use super::walk::*;
use crate::bvh::wide;
use crate::bvh::Bvh;
use crate::cpu::trace::{hit_triangle, CpuScene, Hit, Ray, Sphere, NO_HIT};
use crate::cpu::trace::{make_ray, traverse as single, CpuGeometry};
use crate::cpu::CpuOptions;
use crate::cpu::Real;
use crate::scene::Scene;
use glam::{Vec3, Vec4};

/// `n` random triangles in front of the camera, their tree, and their
/// f32 geometry.
fn fixture(n: usize) -> (Scene, Bvh, CpuGeometry<f32>) {
    let scene = wide::tests::scene(n);
    let bvh = Bvh::build(&scene);
    let geometry = CpuGeometry::new(&scene, &bvh, &Default::default());
    (scene, bvh, geometry)
}

/// Uniform numbers in [-1, 1), replayable from `seed`.
fn uniform(seed: u32) -> impl FnMut() -> f32 {
    let mut state = seed;
    move || {
        state = crate::hash::hash_u32(state);
        f32::from_bits(state >> 9 | 0x3f80_0000) * 2.0 - 3.0
    }
}

/// Every ray of a packet gets the single ray's closest hit (the same
/// t to the bit; a different primitive only at that same t) and the
/// single ray's shadow verdict, packets coherent or not, some lanes off.
#[test]
fn packets_find_what_single_rays_find() {
    let (scene, bvh, geometry) = fixture(3000);
    let camera = crate::camera::Camera::new(64, 48);
    let cpu = CpuScene::new(&scene, &bvh, &geometry, &camera, &CpuOptions::default());
    let mut next = uniform(17);
    let (mut hits, mut blocked, mut ties) = (0, 0, 0);
    for p in 0..600 {
        // Coherent packets (one origin, close directions), scattered
        // ones, and ones whose rays share a direction from many origins
        // (shadow rays towards one light).
        let origin = Vec3::new(next(), next(), next()) * 2.0;
        let dir = Vec3::new(next(), next(), next() - 1.0);
        let spread = [0.01, 1.0, 0.0][p % 3];
        let rays: [Ray<f32>; WIDTH] = std::array::from_fn(|_| {
            let o = if p % 3 == 2 {
                origin + Vec3::new(next(), next(), next())
            } else {
                origin
            };
            let d = dir + Vec3::new(next(), next(), next()) * spread;
            make_ray::<f32>(o, d.normalize(), 0.0)
        });
        let all = u32::MAX >> (32 - WIDTH);
        let active = if p % 5 == 0 { 0xb6b6_b6b6 & all } else { all };
        let got = traverse(&cpu, &rays, active, f32::MAX, false);
        for (r, ray) in rays.iter().enumerate() {
            if active & (1 << r) == 0 {
                assert_eq!(got[r].prim, NO_HIT);
                continue;
            }
            let want = single(&cpu, ray, f32::MAX, false, &[], 0.0);
            assert_eq!(got[r].t.to_bits(), want.t.to_bits(), "packet {p} ray {r}");
            if got[r].prim != want.prim {
                ties += 1;
            } else {
                assert_eq!(
                    (got[r].b1.to_bits(), got[r].b2.to_bits()),
                    (want.b1.to_bits(), want.b2.to_bits())
                );
            }
            hits += usize::from(want.prim != NO_HIT);
        }
        // Shadow rays of random lengths.
        let shadows: [Ray<f32>; WIDTH] = std::array::from_fn(|r| {
            let end = (next() + 1.0) * 20.0;
            make_ray::<f32>(rays[r].origin, rays[r].dir * end, 0.0)
        });
        let got = traverse(&cpu, &shadows, active, 1.0, true);
        for (r, ray) in shadows.iter().enumerate() {
            if active & (1 << r) == 0 {
                continue;
            }
            let want = single(&cpu, ray, 1.0, true, &[], 0.0);
            assert_eq!(got[r].prim != NO_HIT, want.prim != NO_HIT, "packet {p}");
            blocked += usize::from(want.prim != NO_HIT);
        }
    }
    assert!(
        hits > 1000 && blocked > 300,
        "{hits} hits, {blocked} blocked"
    );
    assert!(ties < hits / 100, "{ties} ties");
}

/// The AVX2 and AVX-512 box tests give every ray what the SSE one gives
/// it, to the bit: which children it passes and its entry t, including
/// rays along an axis plane (either sign of zero) and rays with a NaN
/// direction. Each is checked where the CPU has it, and says so where
/// it has not.
#[test]
fn avx_boxes_match_sse() {
    #[cfg(target_arch = "x86_64")]
    {
        if !crate::cpu::simd::has_avx2() {
            skipped("avx_boxes_match_sse: this CPU has no AVX2");
            return;
        }
        let avx512 = crate::cpu::simd::has_avx512();
        if !avx512 {
            skipped("avx_boxes_match_sse's AVX-512 half: this CPU has no AVX-512F");
        }
        let (scene, bvh, geometry) = fixture(500);
        let camera = crate::camera::Camera::new(64, 48);
        let cpu = CpuScene::new(&scene, &bvh, &geometry, &camera, &CpuOptions::default());
        let mut next = uniform(23);
        let (mut passed, mut origin_passed) = (0, 0);
        for p in 0..300 {
            let nodes = &cpu.wide.nodes;
            // Every fifth packet from the origin, as primary rays are,
            // for the tests that skip subtracting it.
            let from_origin = p % 5 == 2;
            let rays: [Ray<f32>; WIDTH] = std::array::from_fn(|r| {
                let mut o = Vec3::new(next(), next(), next()) * 4.0;
                if from_origin {
                    o = Vec3::ZERO;
                }
                let mut d = Vec3::new(next(), next(), next() - 1.0);
                match (p + r) % 8 {
                    1 => d.x = 0.0,
                    2 => d.y = -0.0,
                    3 if p % 16 == 3 => d = Vec3::NAN,
                    _ => {}
                }
                if p % 4 == 1 && !from_origin {
                    // On a box's faces: a ray leaving through a face
                    // meets its box at t_near = t_far = 0, which only
                    // `<=` passes.
                    let node = &nodes[(next().abs() * 1e4) as usize % nodes.len()];
                    let lane = r % 4;
                    for axis in 0..3 {
                        if (p / 4 + r + axis) % 3 != 0 {
                            o[axis] = [node.lo, node.hi][(r + axis) % 2][axis][lane];
                            d[axis] = [0.0, 1.0, -1.0][(p / 4 + axis) % 3];
                        }
                    }
                }
                let d = if d.is_nan() { d } else { d.normalize() };
                make_ray::<f32>(o, d, 0.0)
            });
            let soa = Soa::new(&rays);
            let best_t = Lanes(std::array::from_fn(|_| {
                if next() > 0.0 {
                    f32::MAX
                } else {
                    next() + 20.0
                }
            }));
            let all = u32::MAX >> (32 - WIDTH);
            let mask = if p % 3 == 0 { 0x6d6d_6d6d & all } else { all };
            // Reused from node to node, as a traversal does.
            let [mut a, mut b, mut c, mut d, mut e, mut f] = [0; 6].map(|_| Children::NONE);
            let mut g = Children::NONE;
            for node in &cpu.wide.nodes {
                children_sse::<false, false>(node, &soa, mask, &best_t, &mut a);
                // SAFETY: `has_avx2` holds, checked above.
                unsafe { children_avx2::<false, false>(node, &soa, mask, &best_t, &mut b) };
                assert_eq!(a.hits, b.hits);
                // The any-hit tests find the same rays in each box.
                children_sse::<true, false>(node, &soa, mask, &best_t, &mut d);
                assert_eq!(d.hits, a.hits);
                // SAFETY: as above.
                unsafe { children_avx2::<true, false>(node, &soa, mask, &best_t, &mut c) };
                assert_eq!(c.hits, a.hits);
                // The closest-hit tests' entries, where a ray passed.
                let same_entries = |x: &Children| {
                    for lane in 0..4 {
                        for r in 0..WIDTH {
                            if a.hits[lane] & (1 << r) != 0 {
                                let near = a.near[lane].0[r].to_bits();
                                assert_eq!(near, x.near[lane].0[r].to_bits());
                            }
                        }
                        if a.hits[lane] != 0 {
                            let nearest = a.nearest[lane].to_bits();
                            assert_eq!(nearest, x.nearest[lane].to_bits());
                        }
                    }
                };
                same_entries(&b);
                if from_origin {
                    // Without the origin's subtraction: the same bits.
                    children_sse::<false, true>(node, &soa, mask, &best_t, &mut g);
                    assert_eq!(g.hits, a.hits);
                    same_entries(&g);
                    // SAFETY: `has_avx2` holds, checked above.
                    unsafe { children_avx2::<false, true>(node, &soa, mask, &best_t, &mut g) };
                    assert_eq!(g.hits, a.hits);
                    same_entries(&g);
                    origin_passed += a.hits.iter().map(|h| h.count_ones()).sum::<u32>();
                }
                if avx512 {
                    // SAFETY: `has_avx512` holds, checked above.
                    unsafe {
                        children_avx512::<false, false>(node, &soa, mask, &best_t, &mut e);
                        children_avx512::<true, false>(node, &soa, mask, &best_t, &mut f);
                    }
                    assert_eq!(e.hits, a.hits);
                    assert_eq!(f.hits, a.hits);
                    same_entries(&e);
                    if from_origin {
                        // SAFETY: as above.
                        unsafe {
                            children_avx512::<false, true>(node, &soa, mask, &best_t, &mut g);
                        }
                        assert_eq!(g.hits, a.hits);
                        same_entries(&g);
                    }
                }
                passed += a.hits.iter().map(|h| h.count_ones()).sum::<u32>();
            }
        }
        assert!(passed > 1000, "{passed} box hits");
        assert!(
            origin_passed > 200,
            "{origin_passed} box hits from the origin"
        );
    }
}

/// The packet's sphere test gives each ray the scalar test's t to the
/// bit: hits from outside and inside, misses, grazing rays, rays from
/// the centre, and rays with a NaN direction.
#[test]
fn sphere_rays_match_the_scalar_test() {
    use crate::cpu::trace::hit_sphere;
    let mut next = uniform(29);
    let (mut hits, mut misses) = (0, 0);
    for p in 0..2000 {
        let s = Sphere {
            center: Vec3::new(next(), next(), next() - 4.0),
            radius: next().abs() + 0.01,
            kd: Vec3::ONE,
            ks: Vec3::ZERO,
            shininess: 1.0,
            velocity: Vec3::ZERO,
        };
        let rays: [Ray<f32>; WIDTH] = std::array::from_fn(|r| {
            let o = match (p + r) % 5 {
                0 => s.center,
                1 => s.center + Vec3::new(next(), next(), next()) * s.radius * 0.5,
                _ => Vec3::new(next(), next(), next()),
            };
            let target = s.center + Vec3::new(next(), next(), next()) * s.radius;
            let d = if (p + r) % 97 == 3 {
                Vec3::NAN
            } else {
                (target - o).normalize()
            };
            make_ray::<f32>(o, d, 0.0)
        });
        let best_t = Lanes(std::array::from_fn(|_| {
            if next() > 0.0 {
                f32::MAX
            } else {
                next() + 4.0
            }
        }));
        let got = hit_sphere_rays(&Soa::new(&rays), &s, &best_t);
        for (r, ray) in rays.iter().enumerate() {
            let want = hit_sphere(ray, &s, best_t.0[r], 0.0);
            assert_eq!(got.0[r].to_bits(), want.to_bits(), "sphere {p} ray {r}");
            if want < best_t.0[r] {
                hits += 1;
            } else {
                misses += 1;
            }
        }
    }
    assert!(hits > 3000 && misses > 1000, "{hits} hits, {misses} misses");
}

/// The octet triangle test (and the sixteen-ray one, where the CPU has
/// AVX-512F) gives each ray `wide::hit_block_f32`'s answer to the bit
/// (which triangle, t, barycentrics), over blocks with empty lanes, degenerate and edge-sharing triangles, rays on
/// every axis order and limits that cut hits off; and each of the
/// block's triangles alone (`hit_triangle_octet`) gives each ray
/// `hit_triangle`'s.
#[cfg(target_arch = "x86_64")]
#[test]
fn octet_triangle_test_matches_the_block_test() {
    const ORIGIN_MIN: u32 = 5_000;
    if !crate::cpu::simd::has_avx2() {
        skipped("octet_triangle_test_matches_the_block_test: this CPU has no AVX2, so the octet test never runs");
        return;
    }
    let mut next = uniform(41);
    let (mut hits, mut misses, mut octets, mut sixteens, mut origin_hits) = (0, 0, 0, 0, 0);
    for b in 0..3000 {
        let mut corners = [[Vec3::ZERO; 3]; 4];
        for j in 0..4 {
            let mut tri = [0; 3].map(|_| Vec3::new(next(), next(), next() - 3.0));
            match (b + j) % 7 {
                // Degenerate: two corners the same, or all in a line.
                0 => tri[1] = tri[0],
                1 => tri[2] = tri[0] + (tri[1] - tri[0]) * 0.5,
                // An edge shared with the triangle before.
                2 if j > 0 => [tri[0], tri[1]] = [corners[j - 1][1], corners[j - 1][2]],
                _ => {}
            }
            corners[j] = tri;
        }
        let used = 1 + b % 4;
        let block = wide::LeafBlock {
            p: std::array::from_fn(|axis| {
                std::array::from_fn(|corner| {
                    Vec4::from_array(std::array::from_fn(|j| corners[j][corner][axis]))
                })
            }),
            prims: std::array::from_fn(|j| if j < used { 10 + j as u32 } else { wide::NONE }),
        };
        // Rays aimed at the triangles, mostly along one axis so that
        // octets share an axis order; every few packets a mixed one.
        let axis = b % 3;
        // Every fourth block's rays from the origin, as primary rays are,
        // for the tests that skip subtracting it.
        let from_origin = b % 4 == 3;
        let rays: [Ray<f32>; WIDTH] = std::array::from_fn(|r| {
            let tri = corners[r % used];
            let (u, v) = (next().abs(), next().abs());
            let target = tri[0] + (tri[1] - tri[0]) * u * 0.7 + (tri[2] - tri[0]) * v * 0.7;
            let mut d = Vec3::new(next(), next(), next()) * 0.3;
            d[axis] = if b % 2 == 0 { 1.0 } else { -1.0 };
            if b % 11 == 5 {
                d = Vec3::new(next(), next(), next());
            }
            let o = target - d * (2.0 + next().abs());
            if from_origin {
                return make_ray::<f32>(Vec3::ZERO, target.normalize(), 0.0);
            }
            make_ray::<f32>(o, d.normalize(), 0.0)
        });
        let soa = Soa::new(&rays);
        let limit: [f32; WIDTH] = std::array::from_fn(|_| {
            if next() > -0.3 {
                f32::MAX
            } else {
                next().abs() * 3.0
            }
        });
        sixteens += sixteens_match_the_block_test(b, &block, &soa, &rays, &limit, &mut next);
        for (g, k) in soa.k.iter().enumerate() {
            let Some(k) = *k else { continue };
            octets += 1;
            let m8 = (next().to_bits() >> 3 | 0x11) & 255;
            let (mut best, mut best_t) = no_hits(&limit);
            // SAFETY: `has_avx2` holds, checked above.
            let found = unsafe {
                if from_origin {
                    hit_block_octet::<true>(&block, &soa, k, g, m8, &mut best, &mut best_t)
                } else {
                    hit_block_octet::<false>(&block, &soa, k, g, m8, &mut best, &mut best_t)
                }
            };
            for i in 0..8 {
                let r = 8 * g + i;
                let want = if m8 & 1 << i == 0 {
                    None
                } else {
                    crate::cpu::simd::hit_block_f32(
                        rays[r].origin,
                        rays[r].k,
                        rays[r].shear,
                        &block,
                        limit[r],
                    )
                };
                assert_eq!(found >> r & 1 == 1, want.is_some(), "block {b} ray {r}");
                match want {
                    Some((j, t, b1, b2)) => {
                        hits += 1;
                        origin_hits += u32::from(from_origin);
                        let h = best[r];
                        assert_eq!(h.prim, block.prims[j], "block {b} ray {r}");
                        let got = [h.t, h.b1, h.b2, best_t.0[r]].map(f32::to_bits);
                        assert_eq!(got, [t, b1, b2, t].map(f32::to_bits), "block {b} ray {r}");
                    }
                    None => {
                        misses += 1;
                        assert_eq!(best[r].prim, NO_HIT, "block {b} ray {r}");
                        assert_eq!(best_t.0[r].to_bits(), limit[r].to_bits());
                    }
                }
            }
            // Each triangle alone (a leaf that is no block): each ray
            // `hit_triangle`'s answer, kept where nearer than its limit.
            for (j, tri) in corners.iter().enumerate().take(used) {
                let (mut best, mut best_t) = no_hits(&limit);
                let prim = 10 + j as u32;
                let test = if from_origin {
                    hit_triangle_octet::<true>
                } else {
                    hit_triangle_octet::<false>
                };
                // SAFETY: `has_avx2` holds, checked above.
                let found = unsafe { test(tri, prim, &soa, (k, g, m8), &mut best, &mut best_t) };
                for i in 0..8 {
                    let r = 8 * g + i;
                    let (t, b1, b2) = hit_triangle(&rays[r], tri, limit[r]);
                    let want = m8 & 1 << i != 0 && t < limit[r];
                    assert_eq!(found >> r & 1 == 1, want, "triangle {b}.{j} ray {r}");
                    let expect = if want {
                        (prim, [t, b1, b2])
                    } else {
                        (NO_HIT, [limit[r], 0.0, 0.0])
                    };
                    let h = best[r];
                    let bits = |(p, v): (u32, [f32; 3])| (p, v.map(f32::to_bits));
                    let got = (h.prim, [h.t, h.b1, h.b2]);
                    assert_eq!(bits(got), bits(expect), "triangle {b}.{j} ray {r}");
                    assert_eq!(best_t.0[r].to_bits(), expect.1[0].to_bits());
                }
            }
        }
    }
    assert!(
        hits > 20_000 && misses > 20_000 && octets > 8_000 && origin_hits > ORIGIN_MIN,
        "{hits} hits ({origin_hits} from the origin), {misses} misses, {octets} octets"
    );
    if crate::cpu::simd::has_avx512() {
        assert!(sixteens > 2_000, "{sixteens} sixteens");
    } else {
        skipped("octet_triangle_test_matches_the_block_test: this CPU has no AVX-512F, so the sixteen-ray test did not run");
    }
}

/// `octet_triangle_test_matches_the_block_test`'s check of the
/// sixteen-ray test where the CPU has AVX-512F: for each sixteen whose
/// octets share an axis order, each ray in a random mask gets
/// `hit_block_f32`'s answer to the bit. Returns how many it checked.
#[cfg(target_arch = "x86_64")]
fn sixteens_match_the_block_test(
    b: usize,
    block: &wide::LeafBlock,
    soa: &Soa,
    rays: &[Ray<f32>; WIDTH],
    limit: &[f32; WIDTH],
    next: &mut impl FnMut() -> f32,
) -> u32 {
    if !crate::cpu::simd::has_avx512() {
        return 0;
    }
    let mut sixteens = 0;
    for h in 0..WIDTH / 16 {
        let (Some(k), Some(k2)) = (soa.k[2 * h], soa.k[2 * h + 1]) else {
            continue;
        };
        if k != k2 {
            continue;
        }
        sixteens += 1;
        let m16 = (next().to_bits() >> 3 | 0x1001) & 0xffff;
        let (mut best, mut best_t) = no_hits(limit);
        // SAFETY: `has_avx512` holds, checked above.
        // Rays from the origin (as `octet_triangle_test_matches_the_block_test`
        // makes every fourth block's) also through the test that skips
        // subtracting it.
        let from_origin = rays
            .iter()
            .all(|r| r.origin.to_array().map(f32::to_bits) == [0; 3]);
        let found = unsafe {
            if from_origin {
                hit_block_sixteen::<true>(block, soa, k, h, m16, &mut best, &mut best_t)
            } else {
                hit_block_sixteen::<false>(block, soa, k, h, m16, &mut best, &mut best_t)
            }
        };
        for i in 0..16 {
            let r = 16 * h + i;
            let ray = &rays[r];
            let want = (m16 & 1 << i != 0)
                .then(|| {
                    crate::cpu::simd::hit_block_f32(ray.origin, ray.k, ray.shear, block, limit[r])
                })
                .flatten();
            assert_eq!(
                found >> r & 1 == 1,
                want.is_some(),
                "block {b} ray {r} (16)"
            );
            let (prim, t, b1, b2) = match want {
                Some((j, t, b1, b2)) => (block.prims[j], t, b1, b2),
                None => (NO_HIT, limit[r], 0.0, 0.0),
            };
            let hit = best[r];
            let got = (
                hit.prim,
                [hit.t, hit.b1, hit.b2, best_t.0[r]].map(f32::to_bits),
            );
            let expect = (prim, [t, b1, b2, t].map(f32::to_bits));
            assert_eq!(got, expect, "block {b} ray {r} (16)");
        }
    }
    sixteens
}

/// Rays that have found nothing before their limits `limit`.
fn no_hits(limit: &[f32; WIDTH]) -> ([Hit<f32>; WIDTH], Lanes) {
    let best = std::array::from_fn(|r| Hit {
        t: limit[r],
        prim: NO_HIT,
        b1: 0.0,
        b2: 0.0,
    });
    (best, Lanes(*limit))
}

/// Every field of a ray, as bits.
fn bits(r: &Ray<f32>) -> ([u32; 12], [usize; 3]) {
    let v = |v: Vec3| v.to_array().map(f32::to_bits);
    let [o, d, i, s] = [v(r.origin), v(r.dir), v(r.inv_dir), v(r.shear)];
    let mut out = [0; 12];
    for (k, x) in [o, d, i, s].iter().flatten().enumerate() {
        out[k] = *x;
    }
    assert_eq!(r.time, 0.0);
    (out, r.k)
}

/// The packet's rays are `make_ray`'s to the bit, for directions of
/// every kind: components zero of either sign, below, at and above
/// `MIN_DIR`, all three tiny, infinite, NaN.
#[test]
fn packet_rays_match_make_ray() {
    let mut next = uniform(31);
    let specials = [
        0.0,
        -0.0,
        1e-31,
        -1e-31,
        f32::MIN_DIR,
        -f32::MIN_DIR,
        2e-30,
        f32::INFINITY,
        f32::NAN,
        1.0,
    ];
    let mut special = 0;
    let mut got = Soa::EMPTY;
    for p in 0..500 {
        let origins: [Vec3; WIDTH] =
            std::array::from_fn(|_| Vec3::new(next(), next(), next()) * 8.0);
        let dirs: [Vec3; WIDTH] = std::array::from_fn(|r| {
            let mut d = Vec3::new(next(), next(), next());
            if (p + r) % 3 == 0 {
                special += 1;
                d[special % 3] = specials[special % specials.len()];
                if p % 7 == 0 {
                    d[(special + 1) % 3] = specials[(special / 3) % specials.len()];
                }
            }
            if p % 50 == 0 && r == 3 {
                d = Vec3::splat(1e-31);
            }
            d
        });
        // Into lanes still holding the packet before's rays.
        for r in 0..WIDTH {
            set_lane(&mut got.o, r, origins[r]);
            set_lane(&mut got.dir, r, dirs[r]);
        }
        make_rays(&mut got);
        let want: [Ray<f32>; WIDTH] = std::array::from_fn(|r| make_ray(origins[r], dirs[r], 0.0));
        for r in 0..WIDTH {
            assert_eq!(bits(&got.ray(r)), bits(&want[r]), "{:?}", dirs[r]);
        }
        // An octet's shared axis order where its eight rays have one.
        for (g, k) in got.k.iter().enumerate() {
            let octet = &want[8 * g..8 * g + 8];
            let shared = octet.iter().all(|r| r.k == octet[0].k);
            assert_eq!(*k, shared.then_some(octet[0].k), "packet {p} octet {g}");
        }
    }
}

/// The packet's primary rays are `pixel_ray`'s to the bit, on images of
/// odd and even sizes.
#[test]
fn packet_pixel_rays_match_pixel_ray() {
    let (scene, bvh, geometry) = fixture(10);
    for [w, h] in [[640, 480], [641, 241], [1, 1], [3, 7]] {
        let camera = crate::camera::Camera::new(w, h);
        let cpu = CpuScene::new(&scene, &bvh, &geometry, &camera, &CpuOptions::default());
        let pixels: Vec<[u32; 2]> = (0..h)
            .flat_map(|y| (0..w).map(move |x| [x, y]))
            .filter(|&[x, y]| w < 100 || (x * 7 + y * 3) % 5 == 0)
            .collect();
        for chunk in pixels.chunks(WIDTH) {
            let tile = std::array::from_fn(|i| chunk[i.min(chunk.len() - 1)]);
            let mut soa = Soa::EMPTY;
            pixel_rays(&cpu, &tile, &mut soa);
            for (r, &[x, y]) in tile.iter().enumerate() {
                let want = crate::cpu::trace::pixel_ray(&cpu, x, y);
                assert_eq!(bits(&soa.ray(r)), bits(&want), "{w}x{h} pixel {x},{y}");
            }
        }
    }
}

/// Says past libtest's capture (it intercepts the print macros only) that
/// a test could not run here, and why.
#[allow(dead_code)]
pub(super) fn skipped(why: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "SKIPPED: {why}");
}

/// The walk's order of a node's children is a stable sort of the hit
/// lanes by their nearest entries: ties (any-hit's +inf among them) in
/// lane order, missed lanes left out.
#[test]
fn hit_lanes_sort_nearest_first_and_stably() {
    let values = [0.0, 0.5, 0.5, 2.0, f32::INFINITY];
    let mut s = 0x1234_5678_9ABC_DEF1u64;
    for _ in 0..20_000 {
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let hits: [u32; 4] = std::array::from_fn(|_| (next() % 3 != 0) as u32 * 7);
        let nearest: [f32; 4] = std::array::from_fn(|_| values[(next() % 5) as usize]);
        let mut want: Vec<usize> = (0..4).filter(|&l| hits[l] != 0).collect();
        want.sort_by(|&a, &b| nearest[a].total_cmp(&nearest[b]));
        let (order, n) = hit_lanes_nearest_first(hits, nearest);
        assert_eq!(&order[..n], &want[..], "hits {hits:?}, nearest {nearest:?}");
    }
}

/// The any-hit walk's table orders a node's children as the sorting
/// network does when every entry is +inf: hit lanes in lane order.
#[test]
fn any_hit_order_is_the_networks_for_every_mask() {
    for mask in 0..16u32 {
        let hits: [u32; 4] = std::array::from_fn(|l| (mask >> l & 1) * (l as u32 + 3));
        let (order, n) = hit_lanes_in_order(hits);
        let (want, want_n) = hit_lanes_nearest_first(hits, [f32::INFINITY; 4]);
        assert_eq!(n, want_n, "mask {mask:#06b}");
        assert_eq!(&order[..n], &want[..n], "mask {mask:#06b}");
        let want: Vec<usize> = (0..4).filter(|&l| mask >> l & 1 == 1).collect();
        assert_eq!(&order[..n], &want[..], "mask {mask:#06b}");
    }
}
