//! Known answers, on every backend (GPU, CPU f32, CPU f64): pixels worked out
//! by hand, and whole images checked against an independent textbook oracle
//! (quadratic sphere hit, Möller-Trumbore triangle hit, in f64) that shares no
//! code with glint's renderers.

mod common;

use common::*;
use glam::DVec3;
use glint::cpu::Precision;
use glint::images::framebuffer::Framebuffer;
use glint::scene::Scene;

/// Renders on the CPU in f32 and f64, and on the GPU when there is one.
fn all_backends(scene: &Scene, w: u32, h: u32, bg: [f32; 3]) -> Vec<(&'static str, Framebuffer)> {
    let mut out = vec![
        ("cpu-f32", render_cpu(scene, w, h, Precision::F32, bg)),
        ("cpu-f64", render_cpu(scene, w, h, Precision::F64, bg)),
    ];
    if let Some(fb) = render_gpu(scene, w, h, bg) {
        out.push(("gpu", fb));
    }
    out
}

fn pixel(fb: &Framebuffer, x: u32, y: u32) -> [f32; 3] {
    fb.pixels[(y * fb.width + x) as usize]
}

fn assert_close(what: &str, got: [f32; 3], want: [f64; 3], tol: f64) {
    for c in 0..3 {
        assert!(
            (f64::from(got[c]) - want[c]).abs() <= tol,
            "{what}: got {got:?}, want {want:?}"
        );
    }
}

// At an odd image size the centre pixel's ray is exactly (0, 0, -1):
// ndc_x = 2 * (32 + 0.5) / 65 - 1 = 0 with no rounding.
const W: u32 = 65;
const H: u32 = 49;

#[test]
fn centre_of_test1_is_ambient_plus_light_times_kd_plus_ks() {
    let Some(scene) = classic_scene("test1") else {
        return;
    };
    // Sphere (0,0,-3) r=1, light at the eye. The centre ray hits (0,0,-2),
    // N = L = V = R = (0,0,1): 0.3 + 1 * (0.3 * 1 + 0.5 * 1^1) = 1.1 -> clamped to 1.
    for (name, fb) in all_backends(&scene, W, H, WHITE) {
        assert_close(name, pixel(&fb, W / 2, H / 2), [1.0; 3], 0.0);
    }
}

#[test]
fn centre_of_an_unsaturated_sphere_is_exact() {
    // As test1 but 0.1 + 1 * (0.2 * 1 + 0.3 * 1^7) = 0.6, nothing clamps.
    let scene = scene_from(
        "2\namb: 0.1 0.1 0.1\n\
         sphere pos: 0 0 -3 rad: 1 dif: 0.2 0.2 0.2 spe: 0.3 0.3 0.3 shi: 7\n\
         light pos: 0 0 0 col: 1 1 1\n",
    );
    for (name, fb) in all_backends(&scene, W, H, WHITE) {
        assert_close(name, pixel(&fb, W / 2, H / 2), [0.6; 3], 1e-6);
    }
}

#[test]
fn a_point_behind_an_occluder_is_ambient_exactly() {
    // Ground triangle facing the eye at z = -10; light at (4,0,-2); a sphere
    // at (2,0,-6) r=1 sits on the segment light -> (0,0,-10), which is where
    // the centre ray lands (it passes the sphere at distance 2 > r).
    let scene = scene_from(
        "3\namb: 0.2 0.1 0.05\n\
         triangle\n\
         pos: -50 -50 -10 nor: 0 0 1 dif: 1 1 1 spe: 1 1 1 shi: 1\n\
         pos: 50 -50 -10 nor: 0 0 1 dif: 1 1 1 spe: 1 1 1 shi: 1\n\
         pos: 0 50 -10 nor: 0 0 1 dif: 1 1 1 spe: 1 1 1 shi: 1\n\
         sphere pos: 2 0 -6 rad: 1 dif: 1 1 1 spe: 0 0 0 shi: 1\n\
         light pos: 4 0 -2 col: 1 1 1\n",
    );
    for (name, fb) in all_backends(&scene, W, H, WHITE) {
        assert_close(name, pixel(&fb, W / 2, H / 2), [0.2, 0.1, 0.05], 1e-7);
        // And a lit ground pixel is brighter, so the occluder really occludes.
        let lit = pixel(&fb, W - 3, H / 2);
        assert!(lit[0] > 0.5, "{name}: {lit:?}");
    }
}

#[test]
fn specular_is_not_gated_by_n_dot_l_and_zero_shininess_gives_ks() {
    // Light behind a plane facing the eye: L.N = -1 at the centre, so no
    // diffuse; the shadow ray leaves on the light's side and is not blocked.
    // R = 2(L.N)N - L = (0,0,-1), R.V = -1 -> max(.,0) = 0, and 0^0 = 1 (C's
    // pow): the pixel is ambient + ks = 0.1 + 0.25. With shininess 1 it is 0^1 = 0.
    let plane = |shi: &str| {
        scene_from(&format!(
            "2\namb: 0.1 0.1 0.1\n\
             triangle\n\
             pos: -50 -50 -5 nor: 0 0 1 dif: 0.5 0.5 0.5 spe: 0.25 0.25 0.25 shi: {shi}\n\
             pos: 50 -50 -5 nor: 0 0 1 dif: 0.5 0.5 0.5 spe: 0.25 0.25 0.25 shi: {shi}\n\
             pos: 0 50 -5 nor: 0 0 1 dif: 0.5 0.5 0.5 spe: 0.25 0.25 0.25 shi: {shi}\n\
             light pos: 0 0 -10 col: 1 1 1\n"
        ))
    };
    for (name, fb) in all_backends(&plane("0"), W, H, WHITE) {
        assert_close(name, pixel(&fb, W / 2, H / 2), [0.35; 3], 1e-6);
    }
    for (name, fb) in all_backends(&plane("1"), W, H, WHITE) {
        assert_close(name, pixel(&fb, W / 2, H / 2), [0.1; 3], 1e-7);
    }
}

#[test]
fn misses_show_the_background_exactly() {
    let Some(scene) = classic_scene("test1") else {
        return;
    };
    for bg in [WHITE, [0.25, 0.5, 0.75]] {
        for (name, fb) in all_backends(&scene, W, H, bg) {
            assert_eq!(pixel(&fb, 0, 0), bg, "{name}");
        }
    }
}

#[test]
fn scenes_without_spheres_triangles_or_lights_render() {
    // Vulkan forbids zero-sized buffers: every empty list must still work.
    let scenes = [
        "0\namb: 0.5 0.5 0.5\n",
        "1\namb: 0.5 0.5 0.5\nlight pos: 0 0 0 col: 1 1 1\n",
        "1\namb: 0.5 0.5 0.5\nsphere pos: 0 0 -3 rad: 1 dif: 1 1 1 spe: 0 0 0 shi: 1\n",
    ];
    for text in scenes {
        let scene = scene_from(text);
        for (name, fb) in all_backends(&scene, W, H, WHITE) {
            assert_eq!(pixel(&fb, 0, 0), WHITE, "{name}: {text}");
            let centre = pixel(&fb, W / 2, H / 2);
            let want = if scene.spheres.is_empty() {
                [1.0; 3]
            } else {
                [0.5; 3]
            };
            assert_close(name, centre, want.map(f64::from), 0.0);
        }
    }
}

// ---------------------------------------------------------------------------
// The oracle: textbook formulas in f64, written independently of src/.

fn oracle_dir(x: u32, y: u32, w: u32, h: u32) -> DVec3 {
    let t = (30f64).to_radians().tan();
    let a = f64::from(w) / f64::from(h);
    let px = (2.0 * (f64::from(x) + 0.5) / f64::from(w) - 1.0) * t * a;
    let py = (1.0 - 2.0 * (f64::from(y) + 0.5) / f64::from(h)) * t;
    DVec3::new(px, py, -1.0).normalize()
}

struct Lit {
    amb: DVec3,
    light: DVec3,
    light_col: DVec3,
}

/// Material as (kd, ks, shininess).
type Mat = (DVec3, DVec3, f64);

fn phong(l: &Lit, p: DVec3, n: DVec3, v: DVec3, (kd, ks, sh): Mat, shadowed: bool) -> DVec3 {
    let mut c = l.amb;
    if !shadowed {
        let ld = (l.light - p).normalize();
        let ln = ld.dot(n);
        let r = 2.0 * ln * n - ld;
        let rv = r.dot(v).max(0.0);
        let spec = if sh == 0.0 { 1.0 } else { rv.powf(sh) };
        c += l.light_col * (kd * ln.max(0.0) + ks * spec);
    }
    c.clamp(DVec3::ZERO, DVec3::ONE)
}

/// Compares every pixel that is not within `margin` of a decision boundary
/// (silhouette, terminator, triangle edge), where the backends may
/// legitimately flip; returns how many were compared.
fn check_against_oracle(
    name: &str,
    scene: &Scene,
    w: u32,
    h: u32,
    mut oracle: impl FnMut(DVec3) -> Option<DVec3>,
) -> usize {
    let backends = all_backends(scene, w, h, WHITE);
    let mut compared = 0;
    for y in 0..h {
        for x in 0..w {
            let Some(want) = oracle(oracle_dir(x, y, w, h)) else {
                continue;
            };
            compared += 1;
            for (backend, fb) in &backends {
                assert_close(
                    &format!("{name} {backend} pixel ({x}, {y})"),
                    pixel(fb, x, y),
                    want.to_array(),
                    // 0.5 of one 8-bit level: same 8-bit image up to rounding ties.
                    0.5 / 255.0,
                );
            }
        }
    }
    compared
}

#[test]
fn lone_spheres_match_the_oracle() {
    let margin = 1e-3;
    for (light, sh) in [
        (DVec3::new(3.0, 4.0, 0.0), 1.0),
        (DVec3::new(-2.0, 1.0, -1.0), 0.0),
        (DVec3::new(0.0, 5.0, -8.0), 30.0),
        (DVec3::new(1.0, -1.0, 2.0), 1e4),
    ] {
        let (c, r) = (DVec3::new(0.3, -0.2, -4.0), 1.5);
        let (kd, ks) = (DVec3::new(0.6, 0.3, 0.1), DVec3::new(0.3, 0.4, 0.5));
        let lit = Lit {
            amb: DVec3::splat(0.05),
            light,
            light_col: DVec3::new(0.9, 0.8, 1.0),
        };
        let scene = scene_from(&format!(
            "2\namb: 0.05 0.05 0.05\n\
             sphere pos: {} {} {} rad: {r} dif: {} {} {} spe: {} {} {} shi: {sh}\n\
             light pos: {} {} {} col: 0.9 0.8 1.0\n",
            c.x, c.y, c.z, kd.x, kd.y, kd.z, ks.x, ks.y, ks.z, light.x, light.y, light.z
        ));
        let n = check_against_oracle(&format!("sphere sh={sh}"), &scene, 96, 72, |d| {
            // |t d - c|^2 = r^2  ->  t^2 - 2 (d.c) t + |c|^2 - r^2 = 0, |d| = 1.
            let b = d.dot(c);
            let disc = b * b - (c.length_squared() - r * r);
            if disc < margin {
                return if disc < -margin {
                    Some(DVec3::ONE)
                } else {
                    None
                };
            }
            let p = d * (b - disc.sqrt());
            let nrm = (p - c) / r;
            let ln = (light - p).normalize().dot(nrm);
            if ln.abs() < margin {
                return None;
            }
            // On a sphere, a point sees a light outside it iff L.N > 0.
            Some(phong(&lit, p, nrm, -d, (kd, ks, sh), ln < 0.0))
        });
        assert!(n > 96 * 72 / 2, "too few pixels compared: {n}");
    }
}

#[test]
fn a_lone_triangle_matches_the_oracle_with_interpolated_attributes() {
    let v = [
        DVec3::new(-2.0, -1.5, -4.0),
        DVec3::new(2.5, -1.0, -5.0),
        DVec3::new(-0.5, 2.0, -3.0),
    ];
    let nrm = [
        DVec3::new(0.0, 0.0, 1.0),
        DVec3::new(0.3, 0.1, 1.0),
        DVec3::new(-0.2, 0.4, 0.8),
    ];
    let kd = [
        DVec3::new(0.8, 0.1, 0.1),
        DVec3::new(0.1, 0.8, 0.1),
        DVec3::new(0.1, 0.1, 0.8),
    ];
    let ks = [DVec3::splat(0.2), DVec3::splat(0.5), DVec3::splat(0.1)];
    let sh = [1.0, 20.0, 5.0];
    let lit = Lit {
        amb: DVec3::splat(0.1),
        light: DVec3::new(1.0, 2.0, 1.0),
        light_col: DVec3::ONE,
    };
    let mut text = String::from("2\namb: 0.1 0.1 0.1\ntriangle\n");
    for i in 0..3 {
        text += &format!(
            "pos: {} {} {} nor: {} {} {} dif: {} {} {} spe: {} {} {} shi: {}\n",
            v[i].x,
            v[i].y,
            v[i].z,
            nrm[i].x,
            nrm[i].y,
            nrm[i].z,
            kd[i].x,
            kd[i].y,
            kd[i].z,
            ks[i].x,
            ks[i].y,
            ks[i].z,
            sh[i]
        );
    }
    text += "light pos: 1 2 1 col: 1 1 1\n";
    let scene = scene_from(&text);
    assert_eq!(scene.warnings.len(), 2, "two non-unit normals warned");
    let margin = 1e-3;
    let n = check_against_oracle("triangle", &scene, 96, 72, |d| {
        // Möller-Trumbore.
        let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
        let pv = d.cross(e2);
        let det = e1.dot(pv);
        let s = -v[0];
        let u = s.dot(pv) / det;
        let q = s.cross(e1);
        let w = d.dot(q) / det;
        if u < -margin || w < -margin || u + w > 1.0 + margin {
            return Some(DVec3::ONE);
        }
        if u < margin || w < margin || u + w > 1.0 - margin {
            return None;
        }
        let t = e2.dot(q) / det;
        let p = d * t;
        let b = [1.0 - u - w, u, w];
        // The file's normals are not unit; the parser renormalizes each
        // (with a warning) before interpolation.
        let unit = nrm.map(DVec3::normalize);
        let n = (unit[0] * b[0] + unit[1] * b[1] + unit[2] * b[2]).normalize();
        let mix = |a: [DVec3; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let shi = sh[0] * b[0] + sh[1] * b[1] + sh[2] * b[2];
        Some(phong(&lit, p, n, -d, (mix(kd), mix(ks), shi), false))
    });
    assert!(n > 500, "too few pixels compared: {n}");
}

#[test]
fn a_plane_lit_from_behind_shows_ungated_specular() {
    // Light just behind the plane z = -5 (L.N < 0 everywhere, so no diffuse),
    // seen obliquely: R = 2(L.N)N - L points back toward the eye for points on
    // the light's side of the view (R.V > 0 at x > 0), so the literal rule
    // gives a specular highlight there. Nothing blocks the shadow rays: they
    // leave the plane on the light's side.
    let light = DVec3::new(10.0, 0.0, -5.5);
    let lit = Lit {
        amb: DVec3::splat(0.1),
        light,
        light_col: DVec3::ONE,
    };
    let (kd, ks) = (DVec3::splat(0.5), DVec3::splat(0.6));
    let scene = scene_from(
        "2\namb: 0.1 0.1 0.1\n\
         triangle\n\
         pos: -50 -50 -5 nor: 0 0 1 dif: 0.5 0.5 0.5 spe: 0.6 0.6 0.6 shi: 1\n\
         pos: 50 -50 -5 nor: 0 0 1 dif: 0.5 0.5 0.5 spe: 0.6 0.6 0.6 shi: 1\n\
         pos: 0 50 -5 nor: 0 0 1 dif: 0.5 0.5 0.5 spe: 0.6 0.6 0.6 shi: 1\n\
         light pos: 10 0 -5.5 col: 1 1 1\n",
    );
    let mut highlighted = 0;
    check_against_oracle("plane lit from behind", &scene, 96, 72, |d| {
        let p = d * (-5.0 / d.z);
        let c = phong(&lit, p, DVec3::Z, -d, (kd, ks, 1.0), false);
        if c.x > 0.2 {
            highlighted += 1;
        }
        Some(c)
    });
    assert!(
        highlighted > 100,
        "the case must exercise R.V > 0: {highlighted} pixels"
    );
}

#[test]
fn an_axis_aligned_ray_along_a_box_face_still_hits() {
    // The centre ray is exactly (0, 0, -1) from the origin: dir.x = 0 and
    // origin.x = 0 lies on the x = 0 face of the quad's bounding box. A naive
    // slab test forms (0 - 0) * (1 / 0) = NaN there and misses the box; the
    // watertight test counts the shared edge x = 0 as inside, so the centre
    // pixel must be the lit quad (0.1 + 1 * 0.5 * L.N with L = N = +z: 0.6),
    // never the background.
    let scene = scene_from(
        "3\namb: 0.1 0.1 0.1\n\
         triangle\n\
         pos: 0 -1 -5 nor: 0 0 1 dif: 0.5 0.5 0.5 spe: 0 0 0 shi: 1\n\
         pos: 1 -1 -5 nor: 0 0 1 dif: 0.5 0.5 0.5 spe: 0 0 0 shi: 1\n\
         pos: 1 1 -5 nor: 0 0 1 dif: 0.5 0.5 0.5 spe: 0 0 0 shi: 1\n\
         triangle\n\
         pos: 0 -1 -5 nor: 0 0 1 dif: 0.5 0.5 0.5 spe: 0 0 0 shi: 1\n\
         pos: 1 1 -5 nor: 0 0 1 dif: 0.5 0.5 0.5 spe: 0 0 0 shi: 1\n\
         pos: 0 1 -5 nor: 0 0 1 dif: 0.5 0.5 0.5 spe: 0 0 0 shi: 1\n\
         light pos: 0 0 0 col: 1 1 1\n",
    );
    for (name, fb) in all_backends(&scene, W, H, [0.0; 3]) {
        assert_close(name, pixel(&fb, W / 2, H / 2), [0.6; 3], 1e-6);
        assert_finite(name, &fb);
    }
}
