//! Eight rays through the wide tree together: the CPU reference's fast
//! path for a row's primary rays and for their shadow rays towards each
//! point light. Neighbouring pixels' rays open mostly the same nodes, so
//! one pop, one child sort and one push serve all eight, where a single ray
//! pays them alone; that bookkeeping, not the box arithmetic, was most of a
//! single ray's cost.
//!
//! Each ray's box tests are `wide::hit_boxes_f32`'s arithmetic lane for
//! lane (the rays, not the boxes, fill the SIMD lanes here), with the ray's
//! own nearest hit so far as its limit, and a leaf meets only the rays whose
//! own test reached it, tested exactly as a single ray's (`hit_leaf`). So
//! each ray gets a single ray's shadow verdict, and its closest hit but
//! where two surfaces meet it at the same t or within an ulp or two (as at
//! a mesh's vertices): the triangle test checks a candidate against the hit
//! found so far, so which of such near-equals is kept follows the order
//! leaves are opened in, here the packet's nearest ray's. That order is as
//! deterministic as the single ray's (tests/packets.rs bounds where and how
//! far the images differ).

use glam::{BVec4A, Vec3, Vec4};

use super::trace::{
    centre_key, count_ray, hit_leaf, light_at, light_term, pixel_ray, point_shading,
    point_shadow_ray, reflect_path, surface_point, CpuScene, Hit, Ray, SurfacePoint, NO_HIT,
};
use super::wide;
use super::Real;
use crate::layout::LIGHT_POINT;

/// Rays in a packet.
pub const WIDTH: usize = 8;

const HALVES: usize = WIDTH / 4;

/// A packet's rays, by component and half (`o[axis][half]` holds rays
/// `4 * half..4 * half + 4`).
struct Soa {
    o: [[Vec4; HALVES]; 3],
    inv: [[Vec4; HALVES]; 3],
}

impl Soa {
    #[inline(always)]
    fn new(rays: &[Ray<f32>; WIDTH]) -> Self {
        let mut o = [[[0.0f32; 4]; HALVES]; 3];
        let mut inv = [[[0.0f32; 4]; HALVES]; 3];
        for (r, ray) in rays.iter().enumerate() {
            for axis in 0..3 {
                o[axis][r / 4][r % 4] = ray.origin[axis];
                inv[axis][r / 4][r % 4] = ray.inv_dir[axis];
            }
        }
        let v = |a: [[[f32; 4]; HALVES]; 3]| a.map(|h| h.map(Vec4::from_array));
        Soa {
            o: v(o),
            inv: v(inv),
        }
    }
}

/// The lanes of a 4-bit mask, for selects.
const LANES: [BVec4A; 16] = {
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
type Entry = (u32, u32, f32);

/// The closest hit (`any_hit`: a blocker) before `t_max` of each ray whose
/// bit is set in `active`; the other rays' hits say `NO_HIT`. As
/// `trace::traverse` with no surfaces to skip and no grazing band.
pub fn traverse(
    scene: &CpuScene<f32>,
    rays: &[Ray<f32>; WIDTH],
    active: u32,
    t_max: f32,
    any_hit: bool,
) -> [Hit<f32>; WIDTH] {
    let mut best = [Hit {
        t: t_max,
        prim: NO_HIT,
        b1: 0.0,
        b2: 0.0,
    }; WIDTH];
    if scene.wide.nodes.is_empty() || active == 0 {
        return best;
    }
    let soa = Soa::new(rays);
    let mut best_t = [Vec4::splat(t_max); HALVES];
    let scale = Vec4::splat(f32::BOX_T_SCALE);
    // Rays still looking: an any-hit ray leaves once blocked.
    let mut live = active;
    // Uninitialised, as `trace::traverse`'s: clearing it per packet showed
    // in profiles.
    let mut stack = [std::mem::MaybeUninit::<Entry>::uninit(); wide::STACK];
    stack[0] = std::mem::MaybeUninit::new((0, active, 0.0));
    let mut len = 1;
    while len > 0 {
        len -= 1;
        // SAFETY: stack[..len + 1] were all written before `len` grew past them.
        let (index, entered, t_entry) = unsafe { stack[len].assume_init() };
        let mask = entered & live;
        if mask == 0 {
            continue;
        }
        // Dropped unopened when no ray that entered it could find a hit
        // nearer than its entry any more (the box test they would fail).
        let farthest = (0..HALVES)
            .map(|h| {
                Vec4::select(
                    LANES[(mask >> (4 * h) & 15) as usize],
                    best_t[h],
                    Vec4::NEG_INFINITY,
                )
                .max_element()
            })
            .fold(f32::NEG_INFINITY, f32::max);
        if t_entry > farthest * f32::BOX_T_SCALE {
            continue;
        }
        let node = &scene.wide.nodes[index as usize];
        // Per child lane: the rays that hit its box, their entry t, and the
        // nearest of those.
        let mut hits = [0u32; 4];
        let mut near = [[Vec4::ZERO; HALVES]; 4];
        let mut nearest = [f32::INFINITY; 4];
        for lane in 0..4 {
            if node.child[lane] == wide::EMPTY {
                continue;
            }
            for h in 0..HALVES {
                let m = mask >> (4 * h) & 15;
                if m == 0 {
                    continue;
                }
                let slab = |axis: usize| {
                    let t0 = (Vec4::splat(node.lo[axis][lane]) - soa.o[axis][h]) * soa.inv[axis][h];
                    let t1 = (Vec4::splat(node.hi[axis][lane]) - soa.o[axis][h]) * soa.inv[axis][h];
                    (t0.min(t1), t0.max(t1))
                };
                let (nx, fx) = slab(0);
                let (ny, fy) = slab(1);
                let (nz, fz) = slab(2);
                let t_near = nx.max(ny).max(nz.max(Vec4::ZERO));
                let t_far = fx.min(fy).min(fz.min(best_t[h])) * scale;
                let hit = t_near.cmple(t_far).bitmask() & m;
                if hit != 0 {
                    hits[lane] |= hit << (4 * h);
                    near[lane][h] = t_near;
                    nearest[lane] = nearest[lane].min(
                        Vec4::select(LANES[hit as usize], t_near, Vec4::INFINITY).min_element(),
                    );
                }
            }
        }
        // Hit lanes nearest first (by their nearest ray, then lane).
        let mut order = [0usize; 4];
        let mut n = 0;
        for lane in 0..4 {
            if hits[lane] == 0 {
                continue;
            }
            let mut i = n;
            while i > 0 && nearest[order[i - 1]] > nearest[lane] {
                order[i] = order[i - 1];
                i -= 1;
            }
            order[i] = lane;
            n += 1;
        }
        // Leaves are tested as they come, each by the rays that reached it
        // and have not found a hit nearer than their entry since.
        for &lane in &order[..n] {
            let child = node.child[lane];
            if child & wide::LEAF == 0 {
                continue;
            }
            let leaf = &scene.wide.leaves[(child & !wide::LEAF) as usize];
            // The rays that reached it and have not found a hit nearer than
            // their entry since.
            let mut rays_in = hits[lane] & live;
            for h in 0..HALVES {
                let late = near[lane][h].cmpgt(best_t[h] * scale).bitmask();
                rays_in &= !(late << (4 * h));
            }
            if rays_in == 0 {
                continue;
            }
            while rays_in != 0 {
                let r = rays_in.trailing_zeros() as usize;
                rays_in &= rays_in - 1;
                let done = hit_leaf(scene, &rays[r], leaf, &mut best[r], any_hit, &[], 0.0);
                best_t[r / 4][r % 4] = best[r].t;
                if done {
                    live &= !(1 << r);
                }
            }
            if live == 0 {
                return best;
            }
        }
        // Nodes onto the stack, farthest first, so the nearest is next.
        for &lane in order[..n].iter().rev() {
            let child = node.child[lane];
            if child & wide::LEAF == 0 {
                // Indexed with a bounds check: `wide::STACK` bounds the depth.
                stack[len] = std::mem::MaybeUninit::new((child, hits[lane], nearest[lane]));
                len += 1;
                prefetch(&scene.wide.nodes[child as usize]);
            }
        }
    }
    best
}

/// Starts loading a node (its two cache lines) that will be opened soon.
#[inline(always)]
fn prefetch(node: &wide::Node4) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = (node as *const wide::Node4).cast::<i8>();
        // SAFETY: prefetching has no effect on memory; both addresses lie
        // within the node.
        unsafe {
            _mm_prefetch(p, _MM_HINT_T0);
            _mm_prefetch(p.add(64), _MM_HINT_T0);
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = node;
}

/// Whether a render of `scene` may take its rows in packets: one sample a
/// pixel, at its centre, with nothing moving, so every ray of a row starts
/// at the same time from the camera.
pub fn applies(scene: &CpuScene<f32>) -> bool {
    scene.spp <= 1 && !scene.motion_blur
}

/// A packet's pixels: a block `TILE[0]` wide and `TILE[1]` high, whose
/// rays stay closer together than a row's eight.
pub const TILE: [u32; 2] = [4, 2];

/// The colours `pixel_color` gives `pixels` (up to `WIDTH`), clamped: the
/// primary rays as a packet, then per point light the shadow rays of the
/// pixels that hit something; area lights, lights on surfaces and
/// reflections one pixel at a time, as `shade_phong` and `radiance` take
/// them.
pub fn colours(scene: &CpuScene<f32>, pixels: &[[u32; 2]]) -> [[f32; 3]; WIDTH] {
    let mut out = [[0.0; 3]; WIDTH];
    let n = pixels.len().min(WIDTH);
    if n == 0 {
        return out;
    }
    let active = (1u32 << n) - 1;
    // Lanes past the last pixel repeat it, unused.
    let rays: [Ray<f32>; WIDTH] = std::array::from_fn(|i| {
        let [x, y] = pixels[i.min(n - 1)];
        pixel_ray(scene, x, y)
    });
    for _ in 0..n {
        count_ray(0);
    }
    let hits = traverse(scene, &rays, active, f32::T_INF, false);
    let mut lit = 0u32;
    let mut points: [Option<SurfacePoint<f32>>; WIDTH] = [None; WIDTH];
    let mut colour = [scene.background; WIDTH];
    for (i, hit) in hits.iter().enumerate() {
        if active & (1 << i) != 0 && hit.prim != NO_HIT {
            points[i] = Some(surface_point(scene, &rays[i], hit));
            colour[i] = scene.ambient;
            lit |= 1 << i;
        }
    }
    let key = |i: usize| centre_key(scene, pixels[i][0], pixels[i][1]);
    for l in 0..scene.lights.len() {
        let light = light_at(scene, l, 0.0);
        let on_surface = scene
            .surfaces_at_lights
            .get(l)
            .is_some_and(|s| !s.is_empty());
        if light.kind != LIGHT_POINT || on_surface {
            for (i, sp) in points.iter().enumerate() {
                if let Some(sp) = sp {
                    let term = light_term(scene, sp, -rays[i].dir, l, 0, &key(i));
                    colour[i] += term.contribution;
                }
            }
            continue;
        }
        let mut origins = [Vec3::ZERO; WIDTH];
        let shadows: [Ray<f32>; WIDTH] = std::array::from_fn(|i| {
            // Lanes without a surface carry a copy of the primary ray, unused.
            let Some(sp) = &points[i] else {
                return rays[i];
            };
            let (origin, ray, _) = point_shadow_ray(scene, sp, light.position, 0.0, &[]);
            origins[i] = origin;
            ray
        });
        for _ in 0..lit.count_ones() {
            count_ray(1);
        }
        let blockers = traverse(scene, &shadows, lit, 1.0, true);
        for (i, sp) in points.iter().enumerate() {
            if let Some(sp) = sp {
                let term = point_shading(
                    sp,
                    -rays[i].dir,
                    light.position,
                    light.color,
                    origins[i],
                    blockers[i],
                );
                colour[i] += term.contribution;
            }
        }
    }
    for (i, px) in out.iter_mut().enumerate().take(n) {
        let local = f32::clamp01(colour[i]);
        let c = if lit & (1 << i) != 0 && scene.reflect_depth > 0 {
            reflect_path(scene, &rays[i], hits[i], local, &key(i))
        } else {
            local
        };
        *px = f32::v3_to_f32(f32::clamp01(c));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::Bvh;
    use crate::cpu::trace::{make_ray, traverse as single, CpuGeometry};
    use crate::cpu::CpuOptions;
    use glam::Vec3;

    /// Every ray of a packet gets the single ray's closest hit (the same
    /// t to the bit; a different primitive only at that same t) and the
    /// single ray's shadow verdict, packets coherent or not, some lanes off.
    #[test]
    fn packets_find_what_single_rays_find() {
        let scene = wide::tests::scene(3000);
        let bvh = Bvh::build(&scene);
        let camera = crate::camera::Camera::new(64, 48);
        let geometry = CpuGeometry::<f32>::new(&scene, &bvh, &Default::default());
        let cpu = CpuScene::new(&scene, &bvh, &geometry, &camera, &CpuOptions::default());
        let mut state = 17u32;
        let mut next = || {
            state = crate::cpu::sample::hash_u32(state);
            f32::from_bits(state >> 9 | 0x3f80_0000) * 2.0 - 3.0
        };
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
            let active = if p % 5 == 0 { 0b1011_0110 } else { 0xff };
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
}
