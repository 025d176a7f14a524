//! The lanes' shading (`points`) against the single ray's, to the bit,
//! compiled for SSE (four lanes a register) and, where the CPU has them,
//! for AVX2 (eight) and AVX-512 (sixteen).

use super::lanes::{lane, set_lane, WIDTH, ZEROS};
use super::points::*;
use super::tests::skipped;
use crate::bvh::Bvh;
use crate::cpu::trace::make_ray;
use crate::cpu::trace::{point_shading, shadow_origin, surface_point, CpuGeometry, NO_HIT};
use crate::cpu::trace::{CpuScene, Hit, Ray, SurfacePoint};
use crate::cpu::CpuOptions;
use crate::scene::{Material, Scene, Triangle, Vertex};
use glam::{DVec3, Vec3};

/// Uniform numbers in [-1, 1), replayable from `seed`.
fn uniform(seed: u32) -> impl FnMut() -> f32 {
    let mut state = seed;
    move || {
        state = crate::hash::hash_u32(state);
        f32::from_bits(state >> 9 | 0x3f80_0000) * 2.0 - 3.0
    }
}

/// A check that `all_widths` runs at every width the renderer runs: each
/// impl's `run` is `#[inline(always)]`, so that it is compiled into each
/// width's function (its lanes' loops vectorised there), which a closure
/// called through `Fn` was not.
trait AtEveryWidth {
    fn run(&self);
}

/// `check` once as compiled here (SSE) and once inside an AVX2 and an
/// AVX-512 function where the CPU has them (saying so where it has not).
fn all_widths<C: AtEveryWidth>(check: &C) {
    check.run();
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
        fn avx2<C: AtEveryWidth>(check: &C) {
            check.run()
        }
        #[target_feature(enable = "avx512f,bmi1,bmi2,lzcnt,popcnt")]
        fn avx512<C: AtEveryWidth>(check: &C) {
            check.run()
        }
        if crate::cpu::simd::has_avx2() {
            // SAFETY: `has_avx2` holds, checked just above.
            unsafe { avx2(check) };
        } else {
            skipped("the AVX2 lanes (this CPU has no AVX2)");
        }
        if crate::cpu::simd::has_avx512() {
            // SAFETY: `has_avx512` holds, checked just above.
            unsafe { avx512(check) };
        } else {
            skipped("the AVX-512 lanes (this CPU has no AVX-512F)");
        }
    }
}

fn bits(v: Vec3) -> [u32; 3] {
    v.to_array().map(f32::to_bits)
}

fn fields(s: &SurfacePoint<f32>) -> ([[u32; 3]; 6], u32) {
    (
        [s.p, s.n, s.ng, s.scale, s.kd, s.ks].map(bits),
        s.shininess.to_bits(),
    )
}

/// Triangles of every size (1e-20 to 1e20 across, so that products
/// overflow and underflow), flat ones (whose geometric normal falls
/// back), zero and opposed shading normals (whose sum falls back), and a
/// different material at each corner.
fn triangles() -> Scene {
    let mut next = uniform(5);
    let mut scene = Scene::default();
    let materials: Vec<u32> = (0..8)
        .map(|_| {
            let mut c =
                || DVec3::new(f64::from(next()), f64::from(next()), f64::from(next())).abs();
            scene.add_material(Material {
                kd: c(),
                ks: c(),
                shininess: f64::from(next().abs()) * 100.0,
            })
        })
        .collect();
    for i in 0..4000usize {
        let size = 10f64.powi((i % 41) as i32 - 20);
        let c = DVec3::new(
            f64::from(next()),
            f64::from(next()),
            f64::from(next()) - 2.0,
        ) * size;
        let flat = i % 7 == 0;
        let vertices = [0usize, 1, 2].map(|k| {
            let d = DVec3::new(f64::from(next()), f64::from(next()), f64::from(next()));
            let position = if flat {
                c + DVec3::X * (k as f64 + 0.5) * size
            } else {
                c + d * size
            };
            let normal = match (i + k) % 5 {
                0 => DVec3::ZERO,
                1 if k > 0 => -DVec3::Y,
                1 => DVec3::Y,
                _ => DVec3::new(f64::from(next()), f64::from(next()), f64::from(next())),
            };
            Vertex {
                position,
                normal,
                material: materials[(i + 3 * k) % materials.len()],
            }
        });
        scene.triangles.push(Triangle {
            vertices,
            velocity: DVec3::ZERO,
        });
    }
    scene
}

/// Every lane's surface point is `surface_point`'s, field by field, on
/// `triangles()` with barycentrics inside, on the edges and outside; a
/// packet's lanes hit different triangles, and lanes left out of the mask
/// are overwritten only with what the caller replaces.
#[test]
fn lane_surface_points_are_the_generic_ones_to_the_bit() {
    let scene = triangles();
    let bvh = Bvh::build(&scene);
    let geometry = CpuGeometry::new(&scene, &bvh, &Default::default());
    let camera = crate::camera::Camera::new(64, 48);
    let cpu = CpuScene::new(&scene, &bvh, &geometry, &camera, &CpuOptions::default());
    let ray = make_ray::<f32>(Vec3::ZERO, Vec3::NEG_Z, 0.0);
    let mut next = uniform(7);
    let mut cases = Vec::new();
    for prim in 0..scene.triangles.len() as u32 {
        for k in 0..8 {
            let (b1, b2) = match k {
                0 => (0.0, 0.0),
                1 => (1.0, 0.0),
                2 => (0.5, 0.5),
                3 => (1.5, -0.25),
                _ => ((next() + 1.0) * 0.5, (next() + 1.0) * 0.25),
            };
            cases.push(Hit {
                t: 1.0,
                prim,
                b1,
                b2,
            });
        }
    }
    struct Check<'a> {
        cpu: &'a CpuScene<'a, f32>,
        cases: &'a [Hit<f32>],
        ray: &'a Ray<f32>,
    }
    impl AtEveryWidth for Check<'_> {
        #[inline(always)]
        fn run(&self) {
            let Check { cpu, cases, ray } = *self;
            // Scratch kept from packet to packet, as the renderer keeps it.
            let mut corners = Corners::ZERO;
            let mut points = Points::ZERO;
            for (c, chunk) in cases.chunks(WIDTH).enumerate() {
                let mut hits = [chunk[0]; WIDTH];
                hits[..chunk.len()].copy_from_slice(chunk);
                let mask = u32::MAX >> (32 - chunk.len());
                // Every third packet with a lane left out.
                let mask = if c % 3 == 0 { mask & !2 } else { mask };
                triangle_points(cpu, &hits, mask, &mut corners, &mut points);
                for (i, hit) in hits.iter().enumerate().filter(|(i, _)| mask >> i & 1 != 0) {
                    let want = surface_point(cpu, ray, hit);
                    assert_eq!(
                        fields(&points.get(i)),
                        fields(&want),
                        "triangle {}, b {} {}",
                        hit.prim,
                        hit.b1,
                        hit.b2
                    );
                }
            }
        }
    }
    all_widths(&Check {
        cpu: &cpu,
        cases: &cases,
        ray: &ray,
    });
}

/// Random surface points: normals of both signs, zero and along an axis,
/// points at and far from the origin (the offset's two branches), scales
/// of every size.
fn random_point(next: &mut impl FnMut() -> f32, i: usize) -> SurfacePoint<f32> {
    let mut v = || Vec3::new(next(), next(), next());
    let p = v() * [1e-6, 1.0, 10.0, 1e6][i % 4];
    let n = match i % 9 {
        0 => Vec3::ZERO,
        1 => Vec3::NEG_Y,
        _ => v().normalize_or_zero(),
    };
    SurfacePoint {
        p,
        n,
        ng: if i.is_multiple_of(5) { -n } else { n },
        scale: p.abs() * [1.0, 0.0, 1e3][i % 3],
        kd: v().abs(),
        ks: v().abs(),
        shininess: [0.0, 1.0, 0.5, 100.0][i % 4] * (1.0 + v().x),
    }
}

/// Each lane's shadow ray starts at `shadow_origin`'s point and points at
/// the light, to the bit, lights on the point itself and on either side.
#[test]
fn lane_shadow_rays_are_the_generic_ones_to_the_bit() {
    let (scene, bvh) = (Scene::default(), Bvh::build(&Scene::default()));
    let geometry = CpuGeometry::new(&scene, &bvh, &Default::default());
    let camera = crate::camera::Camera::new(64, 48);
    let cpu = CpuScene::new(&scene, &bvh, &geometry, &camera, &CpuOptions::default());
    struct Check<'a> {
        cpu: &'a CpuScene<'a, f32>,
    }
    impl AtEveryWidth for Check<'_> {
        #[inline(always)]
        fn run(&self) {
            let Check { cpu } = *self;
            let mut next = uniform(11);
            for round in 0..3000 {
                let sps: [SurfacePoint<f32>; WIDTH] =
                    std::array::from_fn(|i| random_point(&mut next, round * WIDTH + i));
                let mut points = Points::ZERO;
                for (i, sp) in sps.iter().enumerate() {
                    points.set(i, sp);
                }
                let target = match round % 3 {
                    0 => sps[round % WIDTH].p,
                    _ => Vec3::new(next(), next(), next()) * 20.0,
                };
                let (mut origin, mut dir) = (ZEROS, ZEROS);
                shadow_rays(&points, target, &mut origin, &mut dir);
                for (i, sp) in sps.iter().enumerate() {
                    let want = shadow_origin(cpu, sp, target);
                    assert_eq!(bits(lane(&origin, i)), bits(want), "round {round} lane {i}");
                    assert_eq!(bits(lane(&dir, i)), bits(target - want), "round {round}");
                }
            }
        }
    }
    all_widths(&Check { cpu: &cpu });
}

/// What each lit lane gains from a point light is `point_shading`'s
/// contribution to the bit (lights at the point itself, behind the
/// surface, shininess 0 (0^0 = 1) and large, views along and against the
/// normal); the lanes not lit keep their colour.
#[test]
fn lane_point_light_is_the_generic_one_to_the_bit() {
    struct Check;
    impl AtEveryWidth for Check {
        #[inline(always)]
        fn run(&self) {
            let mut next = uniform(9);
            for round in 0..6000 {
                let sps: [SurfacePoint<f32>; WIDTH] =
                    std::array::from_fn(|i| random_point(&mut next, round * WIDTH + i));
                let mut points = Points::ZERO;
                let (mut dirs, mut colour) = (ZEROS, ZEROS);
                let mut views = [Vec3::ZERO; WIDTH];
                for (i, sp) in sps.iter().enumerate() {
                    points.set(i, sp);
                    views[i] = match i % 5 {
                        0 => sp.n,
                        1 => -sp.n,
                        _ => Vec3::new(next(), next(), next()).normalize_or_zero(),
                    };
                    set_lane(&mut dirs, i, -views[i]);
                    set_lane(&mut colour, i, Vec3::new(next(), next(), next()).abs());
                }
                let before = colour;
                let target = match round % 7 {
                    0 => sps[round % WIDTH].p,
                    1 => sps[round % WIDTH].p - sps[round % WIDTH].n,
                    _ => Vec3::new(next(), next(), next()) * 20.0,
                };
                let color = Vec3::new(next(), next(), next()).abs();
                let lit = crate::hash::hash_u32(round as u32) | 1;
                let f = facing(&points, &dirs, target);
                let dark = no_highlight(&f, &points, lit);
                let mut terms = ZEROS;
                // In two goes, as the packets fill them: first the points with
                // no highlight, then the others.
                fill_terms(&points, &f, dark, color, &mut terms);
                fill_terms(&points, &f, lit & !dark, color, &mut terms);
                add_terms(&mut colour, &terms, lit);
                let blocker = Hit {
                    t: 0.0,
                    prim: NO_HIT,
                    b1: 0.0,
                    b2: 0.0,
                };
                for (i, sp) in sps.iter().enumerate() {
                    let want = if lit >> i & 1 != 0 {
                        let term = point_shading(sp, views[i], target, color, sp.p, blocker);
                        lane(&before, i) + term.contribution
                    } else {
                        lane(&before, i)
                    };
                    assert_eq!(bits(lane(&colour, i)), bits(want), "round {round} lane {i}");
                }
            }
        }
    }
    all_widths(&Check);
}

/// A lane `changed_by` leaves out is one whose colour comes out the same
/// whether its light is blocked or not (so its shadow ray need not be
/// traced); one it keeps would differ. Terms of 0, -0, far below the
/// colour's ulp, NaN and ordinary ones, on colours of either sign and 0.
#[test]
fn untraced_shadow_rays_could_not_change_a_colour() {
    struct Check;
    impl AtEveryWidth for Check {
        #[inline(always)]
        fn run(&self) {
            let mut next = uniform(21);
            let mut left_out = 0;
            for round in 0..4000 {
                let (mut colour, mut terms) = (ZEROS, ZEROS);
                for i in 0..WIDTH {
                    for a in 0..3 {
                        let c = match (round + i + a) % 5 {
                            0 => 0.0,
                            1 => -0.0,
                            _ => next() * 4.0,
                        };
                        let t = match (round * 3 + i * 7 + a) % 9 {
                            0..=2 => 0.0,
                            3 => -0.0,
                            4 => c * 1e-9,
                            5 => f32::NAN,
                            _ => next().abs(),
                        };
                        colour[a].0[i] = c;
                        terms[a].0[i] = t;
                    }
                }
                let lit = crate::hash::hash_u32(round as u32 ^ 0x5bd1);
                let traced = changed_by(&colour, &terms, lit);
                assert_eq!(traced & !lit, 0, "round {round}: a lane without a surface");
                let (mut blocked, mut clear) = (colour, colour);
                add_terms(&mut clear, &terms, lit);
                add_terms(&mut blocked, &terms, 0);
                for i in 0..WIDTH {
                    let same = bits(lane(&clear, i)) == bits(lane(&blocked, i));
                    if lit >> i & 1 != 0 {
                        assert_eq!(traced >> i & 1 == 0, same, "round {round} lane {i}");
                        left_out += u32::from(same);
                    }
                }
            }
            assert!(left_out > 0, "no lane was left out");
        }
    }
    all_widths(&Check);
}

/// The lanes' clamp is `Real::clamp01`'s to the bit: NaN, both zeros,
/// infinities, subnormals, 1 and its neighbours, and ordinary values.
#[test]
fn lane_clamp_is_the_generic_one_to_the_bit() {
    struct Check;
    impl AtEveryWidth for Check {
        #[inline(always)]
        fn run(&self) {
            use crate::cpu::Real;
            let edges = [
                f32::NAN,
                -f32::NAN,
                0.0,
                -0.0,
                f32::INFINITY,
                f32::NEG_INFINITY,
                f32::MIN_POSITIVE / 2.0,
                -f32::MIN_POSITIVE / 2.0,
                1.0,
                1.0 + f32::EPSILON,
                1.0 - f32::EPSILON / 2.0,
            ];
            let mut next = uniform(33);
            for round in 0..200 {
                let mut colour = ZEROS;
                for i in 0..WIDTH {
                    for a in 0..3 {
                        colour[a].0[i] = match (round + 3 * i + a) % 3 {
                            0 => edges[(round + i + a) % edges.len()],
                            _ => next() * 2.0,
                        };
                    }
                }
                let want: Vec<[u32; 3]> = (0..WIDTH)
                    .map(|i| bits(f32::clamp01(lane(&colour, i))))
                    .collect();
                clamp01(&mut colour);
                for (i, want) in want.iter().enumerate() {
                    assert_eq!(&bits(lane(&colour, i)), want, "round {round} lane {i}");
                }
            }
        }
    }
    all_widths(&Check);
}
