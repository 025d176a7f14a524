//! What a pixel's primary ray found, beyond its colour: the data behind the
//! robustness suite (`ProbeImage`, one record per pixel) and behind
//! `glint render --pixel` (`PathRecord`, one pixel in full). Both backends
//! produce the same types: the GPU through the shader's `probe_tile` and
//! `probe_pixel` entry points, the CPU reference through `cpu::probe` and
//! `cpu::pixel_path`.

use std::fmt;

use crate::layout::{
    FLAG_NONFINITE_COLOR, FLAG_NONFINITE_SURFACE, PATH_HEADER, PATH_PER_LIGHT, SPHERE_BIT,
};

/// No primitive: the ray missed, or (for a shadow ray) nothing blocks it.
pub const NO_HIT: u32 = u32::MAX;

/// What a primary ray found at one pixel (`probe_tile`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProbePixel {
    /// Primitive reference (bit 31: sphere), or `NO_HIT`.
    pub prim: u32,
    /// Bit i: light i is blocked (lights 31 and up share bit 31).
    pub shadow_mask: u32,
    /// `FLAG_NONFINITE_*` bits.
    pub flags: u32,
    /// Distance along the primary ray (meaningless on a miss).
    pub t: f32,
}

impl ProbePixel {
    /// Whether the primary ray hit something.
    pub fn hit(&self) -> bool {
        self.prim != NO_HIT
    }
    /// Whether the shader flagged an infinite or NaN colour or surface.
    pub fn nonfinite(&self) -> bool {
        self.flags & (FLAG_NONFINITE_COLOR | FLAG_NONFINITE_SURFACE) != 0
    }
}

/// One `ProbePixel` per pixel, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeImage {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Row-major, row 0 at the top.
    pub pixels: Vec<ProbePixel>,
}

impl ProbeImage {
    /// Decodes the shader's `probe_tile` texels (integers bit-cast to f32).
    pub fn from_texels(width: u32, height: u32, texels: &[[f32; 4]]) -> ProbeImage {
        let pixels = texels
            .iter()
            .map(|t| ProbePixel {
                prim: t[0].to_bits(),
                shadow_mask: t[1].to_bits(),
                flags: t[2].to_bits(),
                t: t[3],
            })
            .collect();
        ProbeImage {
            width,
            height,
            pixels,
        }
    }

    /// Pixel (x, y); panics outside the image.
    pub fn get(&self, x: u32, y: u32) -> &ProbePixel {
        &self.pixels[(y * self.width + x) as usize]
    }
}

/// The surface a primary ray hit, as the shader computed it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathSurface {
    /// The hit point.
    pub point: [f64; 3],
    /// Shading normal (interpolated for triangles).
    pub normal: [f64; 3],
    /// Geometric normal: the side shadow rays leave from.
    pub geometric_normal: [f64; 3],
    /// Diffuse colour.
    pub kd: [f64; 3],
    /// Specular colour.
    pub ks: [f64; 3],
    /// Phong exponent.
    pub shininess: f64,
}

/// One light's shadow ray and Phong terms at the hit point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathLight {
    /// The offset origin of the shadow ray.
    pub origin: [f64; 3],
    /// The first blocker found, or `NO_HIT`.
    pub blocker: u32,
    /// Where along the shadow ray (0 = origin, 1 = light) the blocker lies.
    pub blocker_t: f64,
    /// L·N, max(R·V, 0) and its power; zero when blocked (not computed).
    pub ln: f64,
    /// See `ln`.
    pub rv: f64,
    /// See `ln`.
    pub spec: f64,
    /// The light's colour times the Phong terms.
    pub contribution: [f64; 3],
}

/// A pixel's whole path: primary hit, surface, and every light's verdict.
#[derive(Clone, Debug, PartialEq)]
pub struct PathRecord {
    /// The primary ray's direction.
    pub dir: [f64; 3],
    /// What it hit (bit 31: sphere), or `NO_HIT`.
    pub prim: u32,
    /// Distance along the primary ray.
    pub t: f64,
    /// Barycentric weights of vertices 1 and 2 (triangles).
    pub b1: f64,
    /// See `b1`.
    pub b2: f64,
    /// Before clamping.
    pub color: [f64; 3],
    /// Bit i: light i is blocked (lights 31 and up share bit 31).
    pub shadow_mask: u32,
    /// `FLAG_NONFINITE_*` bits.
    pub flags: u32,
    /// What it hit; None on a miss.
    pub surface: Option<PathSurface>,
    /// The first lights (all unless the GPU record ran out of room).
    pub lights: Vec<PathLight>,
}

fn xyz(t: [f32; 4]) -> [f64; 3] {
    [f64::from(t[0]), f64::from(t[1]), f64::from(t[2])]
}

impl PathRecord {
    /// The record of a scene rendered scaled by `scale` (`Bvh::scale`), in
    /// the scene's own units: distances and points divided by it (exact,
    /// `scale` is a power of two); directions, normals and fractions stay.
    pub fn in_scene_units(mut self, scale: f64) -> PathRecord {
        let unscale = |p: [f64; 3]| p.map(|v| v / scale);
        self.t /= scale;
        if let Some(surface) = &mut self.surface {
            surface.point = unscale(surface.point);
        }
        for light in &mut self.lights {
            light.origin = unscale(light.origin);
        }
        self
    }

    /// The record (in view space) back in the world of a scene whose
    /// `camera` moved it: points, normals and directions.
    pub fn in_world(mut self, cam: &crate::scene::CameraSpec) -> PathRecord {
        use crate::scene::CameraSpec;
        use glam::DVec3;
        let Some(basis) = cam.basis() else {
            return self;
        };
        let point = |p: [f64; 3]| cam.to_world(&basis, DVec3::from(p)).to_array();
        let dir = |v: [f64; 3]| CameraSpec::dir_to_world(&basis, DVec3::from(v)).to_array();
        self.dir = dir(self.dir);
        if let Some(surface) = &mut self.surface {
            surface.point = point(surface.point);
            surface.normal = dir(surface.normal);
            surface.geometric_normal = dir(surface.geometric_normal);
        }
        for light in &mut self.lights {
            light.origin = point(light.origin);
        }
        self
    }

    /// Decodes the shader's `probe_pixel` record. Texels: 0 (prim, t, b1,
    /// b2), 1 (ray direction, flags), 2 (colour, shadow mask); for a hit
    /// also 3 (point, shininess), 4 (normal, lights listed), 5 geometric
    /// normal, 6 kd, 7 ks, then per light (origin, blocker), (L·N, R·V,
    /// power, blocker t), (contribution).
    pub fn from_texels(texels: &[[f32; 4]]) -> PathRecord {
        let h = |i: u32| texels[i as usize];
        let prim = h(0)[0].to_bits();
        // Texels 3.. are written only for a hit.
        let shown = if prim == NO_HIT { 0 } else { h(4)[3].to_bits() };
        let surface = (prim != NO_HIT).then(|| PathSurface {
            point: xyz(h(3)),
            normal: xyz(h(4)),
            geometric_normal: xyz(h(5)),
            kd: xyz(h(6)),
            ks: xyz(h(7)),
            shininess: f64::from(h(3)[3]),
        });
        let lights = (0..shown)
            .map(|i| {
                let base = PATH_HEADER + PATH_PER_LIGHT * i;
                let (a, b, c) = (h(base), h(base + 1), h(base + 2));
                PathLight {
                    origin: xyz(a),
                    blocker: a[3].to_bits(),
                    ln: f64::from(b[0]),
                    rv: f64::from(b[1]),
                    spec: f64::from(b[2]),
                    blocker_t: f64::from(b[3]),
                    contribution: xyz(c),
                }
            })
            .collect();
        PathRecord {
            dir: xyz(h(1)),
            prim,
            t: f64::from(h(0)[1]),
            b1: f64::from(h(0)[2]),
            b2: f64::from(h(0)[3]),
            color: xyz(h(2)),
            shadow_mask: h(2)[3].to_bits(),
            flags: h(1)[3].to_bits(),
            surface,
            lights,
        }
    }
}

/// "sphere 3", "triangle 12" or "nothing".
pub fn prim_name(prim: u32) -> String {
    if prim == NO_HIT {
        "nothing".into()
    } else if prim & SPHERE_BIT != 0 {
        format!("sphere {}", prim & !SPHERE_BIT)
    } else {
        format!("triangle {prim}")
    }
}

struct V([f64; 3]);

impl fmt::Display for V {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [x, y, z] = self.0;
        write!(f, "({x:.9e}, {y:.9e}, {z:.9e})")
    }
}

impl fmt::Display for PathRecord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "primary ray direction {}", V(self.dir))?;
        let Some(s) = &self.surface else {
            writeln!(f, "miss: background {}", V(self.color))?;
            return Ok(());
        };
        write!(f, "hit {} at t = {:.9e}", prim_name(self.prim), self.t)?;
        if self.prim & SPHERE_BIT == 0 {
            let b0 = 1.0 - self.b1 - self.b2;
            write!(
                f,
                ", barycentrics ({b0:.9e}, {:.9e}, {:.9e})",
                self.b1, self.b2
            )?;
        }
        writeln!(f)?;
        writeln!(f, "  point            {}", V(s.point))?;
        writeln!(f, "  normal           {}", V(s.normal))?;
        writeln!(f, "  geometric normal {}", V(s.geometric_normal))?;
        writeln!(
            f,
            "  kd {}  ks {}  shininess {:.9e}",
            V(s.kd),
            V(s.ks),
            s.shininess
        )?;
        for (i, l) in self.lights.iter().enumerate() {
            write!(f, "light {i}: shadow ray from {}: ", V(l.origin))?;
            if l.blocker != NO_HIT {
                writeln!(
                    f,
                    "blocked by {} at {:.9e} of the way to the light",
                    prim_name(l.blocker),
                    l.blocker_t
                )?;
            } else {
                writeln!(
                    f,
                    "lit; L.N = {:.9e}, max(R.V, 0) = {:.9e}, (R.V)^shininess = {:.9e}, adds {}",
                    l.ln,
                    l.rv,
                    l.spec,
                    V(l.contribution)
                )?;
            }
        }
        writeln!(f, "colour before clamping {}", V(self.color))?;
        if self.flags & FLAG_NONFINITE_COLOR != 0 {
            writeln!(f, "warning: the colour has an infinite or NaN component")?;
        }
        if self.flags & FLAG_NONFINITE_SURFACE != 0 {
            writeln!(
                f,
                "warning: the point or normal has an infinite or NaN component"
            )?;
        }
        Ok(())
    }
}
