//! Packets of pixels shaded: a tile's primary rays traced together, their
//! surface points, and the shadow rays towards each point light traced
//! together too; the shading in lanes too (`points`), each value the
//! single ray's to the bit.

use super::lanes::*;
use super::points::{
    add_terms, changed_by, clamp01, facing, fill_terms, no_highlight, shadow_rays, triangle_points,
    Corners, Points,
};
use super::walk::traverse_packet;
use crate::cpu::trace::{
    centre_key, count_rays, light_at, light_term, reflect_path, surface_point, CpuScene, NO_HIT,
    UNTRACED,
};
use crate::cpu::{Keep, Real};
use crate::layout::{LIGHT_POINT, SPHERE_BIT};
use crate::methods::Methods;

/// A packet's pixels: a block `TILE[0]` wide and `TILE[1]` high, whose
/// rays stay closer together than a row's. Measured against 4 x 4 tiles of
/// sixteen rays and 8 x 4 ones: taller tiles were faster, most on the big
/// grids.
pub const TILE: [u32; 2] = [4, 8];

// A tile's pixels fit one packet (`fill_band` gathers them into one).
const _: () = assert!(TILE[0] * TILE[1] <= WIDTH as u32);

/// Fills a band of `TILE[1]` rows (fewer for the last) from row `y0`, each
/// `TILE`-sized tile's pixels that `keep` says as one packet (`colours`),
/// the others left as they are.
pub fn fill_band(scene: &CpuScene<f32>, y0: u32, band: &mut [[f32; 3]], keep: Keep) {
    let [tw, _] = TILE;
    let w = scene.size[0];
    let rows = band.len() as u32 / w.max(1);
    let mut scratch = Scratch {
        corners: Corners::ZERO,
        points: Points::ZERO,
        primary: Soa::EMPTY,
        shadows: Soa::EMPTY,
    };
    for x0 in (0..w).step_by(tw as usize) {
        let mut pixels = [[0u32; 2]; WIDTH];
        let mut n = 0;
        for y in y0..y0 + rows {
            for x in x0..(x0 + tw).min(w) {
                if keep.pixel(x, y) {
                    pixels[n] = [x, y];
                    n += 1;
                }
            }
        }
        for (&[x, y], c) in pixels[..n]
            .iter()
            .zip(colours(scene, &pixels[..n], &mut scratch))
        {
            band[((y - y0) * w + x) as usize] = c;
        }
    }
}

/// A packet's working space, kept from packet to packet so that no
/// packet pays for clearing its 12 KB (`Corners`, `Soa`).
struct Scratch {
    corners: Corners,
    points: Points,
    primary: Soa,
    shadows: Soa,
}

/// The colours `pixel_color` gives `pixels` (up to `WIDTH`), clamped: the
/// primary rays as a packet, then per point light the shadow rays of the
/// pixels that hit something; area lights, lights on surfaces and
/// reflections one pixel at a time, as `shade_phong` and `radiance` take
/// them.
fn colours(scene: &CpuScene<f32>, pixels: &[[u32; 2]], scratch: &mut Scratch) -> [[f32; 3]; WIDTH] {
    #[cfg(target_arch = "x86_64")]
    if crate::cpu::simd::has_avx512() {
        // SAFETY: `has_avx512` holds, checked just above.
        return unsafe { colours_avx512(scene, pixels, scratch) };
    }
    #[cfg(target_arch = "x86_64")]
    if crate::cpu::simd::has_avx2() {
        // SAFETY: `has_avx2` holds, checked just above.
        return unsafe { colours_avx2(scene, pixels, scratch) };
    }
    colours_with(scene, pixels, scratch)
}

/// `colours_with` compiled for AVX-512, so that its lanes' loops take
/// sixteen rays a register (`table` 22.0 -> 19.8 ms against AVX2's eight,
/// one thread, minimums of 61 renders).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,bmi1,bmi2,lzcnt,popcnt")]
fn colours_avx512(
    scene: &CpuScene<f32>,
    pixels: &[[u32; 2]],
    scratch: &mut Scratch,
) -> [[f32; 3]; WIDTH] {
    colours_with(scene, pixels, scratch)
}

/// `colours_with` compiled for AVX2, so that its lanes' loops
/// (`points`) take eight rays a register.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
fn colours_avx2(
    scene: &CpuScene<f32>,
    pixels: &[[u32; 2]],
    scratch: &mut Scratch,
) -> [[f32; 3]; WIDTH] {
    colours_with(scene, pixels, scratch)
}

/// `colours`, for the instruction sets its caller was compiled for.
#[inline(always)]
fn colours_with(
    scene: &CpuScene<f32>,
    pixels: &[[u32; 2]],
    scratch: &mut Scratch,
) -> [[f32; 3]; WIDTH] {
    let Scratch {
        corners,
        points,
        primary,
        shadows,
    } = scratch;
    let mut out = [[0.0; 3]; WIDTH];
    let n = pixels.len().min(WIDTH);
    if n == 0 {
        return out;
    }
    let active = u32::MAX >> (32 - n);
    // Lanes past the last pixel repeat it, unused.
    let mut tile = [[0u32; 2]; WIDTH];
    for (i, t) in tile.iter_mut().enumerate() {
        *t = pixels[i.min(n - 1)];
    }
    pixel_rays(scene, &tile, primary);
    count_rays(0, n as u64);
    let hits = traverse_packet(scene, primary, active, f32::T_INF, false, true);
    let mut lit = 0u32;
    for (i, hit) in hits.iter().enumerate() {
        if active & (1 << i) != 0 && hit.prim != NO_HIT {
            lit |= 1 << i;
        }
    }
    // Surface points: triangles in lanes (the robust method, nothing
    // moving: always, where packets apply), spheres one by one.
    let lanes_ok = !scene.motion_blur && scene.methods == Methods::Robust;
    let mut triangles = 0u32;
    let mut each = lit;
    while each != 0 {
        let i = each.trailing_zeros() as usize;
        each &= each - 1;
        if lanes_ok && hits[i].prim & SPHERE_BIT == 0 {
            triangles |= 1 << i;
        }
    }
    if triangles != 0 {
        triangle_points(scene, &hits, triangles, corners, points);
    }
    let mut each = lit & !triangles;
    while each != 0 {
        let i = each.trailing_zeros() as usize;
        each &= each - 1;
        points.set(i, &surface_point(scene, &primary.ray(i), &hits[i]));
    }
    let mut colour = ZEROS;
    for (a, colour) in colour.iter_mut().enumerate() {
        let (on, off) = (scene.ambient[a], scene.background[a]);
        for i in 0..WIDTH {
            colour.0[i] = if lit & (1 << i) != 0 { on } else { off };
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
            let mut each = lit;
            while each != 0 {
                let i = each.trailing_zeros() as usize;
                each &= each - 1;
                let view = -lane(&primary.dir, i);
                let term = light_term(scene, &points.get(i), view, l, 0, &key(i));
                let sum = lane(&colour, i) + term.contribution;
                set_lane(&mut colour, i, sum);
            }
            continue;
        }
        // Only the shadow rays whose answer can change a colour are traced:
        // where the light's term leaves the sum's bits as they are (a 0
        // term, as at most points facing away from it), blocked or not
        // gives the same pixel. Asked only where the term is known without
        // `powf` (no highlight), so that `powf` runs for unblocked points
        // alone, as before.
        if lit == 0 {
            continue;
        }
        let f = facing(points, &primary.dir, light.position);
        let dark = no_highlight(&f, points, lit);
        let mut terms = ZEROS;
        fill_terms(points, &f, dark, light.color, &mut terms);
        let needed = (lit & !dark) | changed_by(&colour, &terms, dark);
        count_rays(UNTRACED, u64::from((lit & !needed).count_ones()));
        if needed == 0 {
            continue;
        }
        // `point_shadow_ray`'s rays (no surfaces at this light, so no
        // grazing band). Lanes not traced copy a traced one's ray, so that
        // an octet's rays share an axis order (`Soa::k`) wherever its
        // traced ones do.
        shadow_rays(points, light.position, &mut shadows.o, &mut shadows.dir);
        let first = needed.trailing_zeros() as usize;
        let (o, d) = (lane(&shadows.o, first), lane(&shadows.dir, first));
        let mut each = !needed;
        while each != 0 {
            let i = each.trailing_zeros() as usize;
            each &= each - 1;
            set_lane(&mut shadows.o, i, o);
            set_lane(&mut shadows.dir, i, d);
        }
        make_rays(shadows);
        count_rays(1, u64::from(needed.count_ones()));
        let blockers = traverse_packet(scene, shadows, needed, 1.0, true, false);
        let mut clear = 0u32;
        for (i, b) in blockers.iter().enumerate() {
            if b.prim == NO_HIT {
                clear |= 1 << i;
            }
        }
        fill_terms(points, &f, needed & clear & !dark, light.color, &mut terms);
        add_terms(&mut colour, &terms, needed & clear);
    }
    // Clamping twice is clamping once: a pixel without a reflection is
    // its lane.
    clamp01(&mut colour);
    for (i, px) in out.iter_mut().enumerate().take(n) {
        *px = [colour[0].0[i], colour[1].0[i], colour[2].0[i]];
    }
    if scene.reflect_depth > 0 {
        let mut each = lit;
        while each != 0 {
            let i = each.trailing_zeros() as usize;
            each &= each - 1;
            let local = lane(&colour, i);
            let c = reflect_path(scene, &primary.ray(i), hits[i], local, &key(i));
            out[i] = f32::v3_to_f32(f32::clamp01(c));
        }
    }
    out
}
