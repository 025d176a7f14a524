//! The shader's algorithm on the CPU, function for function and name for name
//! (`shaders/trace.wgsl`), generic over f32 (the shader's twin) and f64.
//! Comments on the why live in the shader; this file stays a mirror of it.

use crate::bvh::Bvh;
use crate::camera::Camera;
use crate::info::Features;
use crate::layout::{
    FLAG_NONFINITE_COLOR, FLAG_NONFINITE_SURFACE, LIGHT_POINT, LIGHT_RECT, LIGHT_SPHERE, SPHERE_BIT,
};
use crate::methods::Methods;
use crate::scene::{Effects, LightShape, Scene};

use super::real::Real;
use super::sample::{
    rng, stratified_2d, unit_float, ROTATION, STREAM_LIGHT, STREAM_PIXEL, STREAM_TIME,
};
use super::wide::{self, WideBvh};
use super::CpuOptions;

pub const NO_HIT: u32 = u32::MAX;

#[derive(Clone, Copy, Debug)]
pub struct Sphere<R: Real> {
    pub center: R::V3,
    pub radius: R,
    pub kd: R::V3,
    pub ks: R::V3,
    pub shininess: R,
    pub velocity: R::V3,
}

/// A triangle corner's shading normal and material (an index into
/// `CpuScene::materials`, as the scene keeps them: a material per corner
/// would be most of a big scene's memory here too).
#[derive(Clone, Copy, Debug)]
pub struct VertexShading<R: Real> {
    pub normal: R::V3,
    pub material: u32,
}

#[derive(Clone, Copy, Debug)]
pub struct SurfaceMaterial<R: Real> {
    pub kd: R::V3,
    pub ks: R::V3,
    pub shininess: R,
}

#[derive(Clone, Copy, Debug)]
pub struct Light<R: Real> {
    pub position: R::V3,
    pub color: R::V3,
    pub kind: u32,
    pub radius: R,
    pub edge_u: R::V3,
    pub edge_v: R::V3,
    pub velocity: R::V3,
}

/// The scene as the CPU reference reads it: the shader's buffers, in `R`.
/// The BVH is shared with the GPU (f32 boxes, rounded outward). The
/// per-primitive arrays and the wide tree are a `CpuGeometry`'s, built
/// once per prepared scene (`render::Renderer`), as the GPU packs its
/// buffers once.
pub struct CpuScene<'a, R: Real> {
    pub spheres: &'a [Sphere<R>],
    pub triangles: &'a [[R::V3; 3]],
    pub triangle_velocity: &'a [R::V3],
    pub shading: &'a [[VertexShading<R>; 3]],
    pub materials: &'a [SurfaceMaterial<R>],
    pub lights: Vec<Light<R>>,
    /// The BVH collapsed to four children a node, with its leaves'
    /// triangles in blocks for the SIMD test (`wide`).
    pub wide: &'a WideBvh,
    pub prim_refs: &'a [u32],
    /// Per light, the surfaces through it (`lights_on_surfaces`).
    pub surfaces_at_lights: &'a [Vec<u32>],
    pub ambient: R::V3,
    pub background: R::V3,
    pub half_extent: [R; 2],
    pub size: [u32; 2],
    /// The shader's `ROBUST` override.
    pub methods: Methods,
    /// The shader's `MOTION_BLUR` override.
    pub motion_blur: bool,
    pub seed: u32,
    pub spp: u32,
    pub shadow_samples: u32,
    pub reflect_depth: u32,
    /// Seconds the shutter is open (0 without motion blur).
    pub shutter: R,
}

/// What of a `CpuScene` grows with the scene: its primitives in `R` and the
/// wide tree. It depends on the scene, its BVH and whether the scene moves,
/// not on the camera, seed or samples, so one serves every render of a
/// prepared scene (and every pass of a progressive one).
#[derive(Clone)]
pub struct CpuGeometry<R: Real> {
    spheres: Vec<Sphere<R>>,
    triangles: Vec<[R::V3; 3]>,
    triangle_velocity: Vec<R::V3>,
    shading: Vec<[VertexShading<R>; 3]>,
    materials: Vec<SurfaceMaterial<R>>,
    wide: WideBvh,
    motion_blur: bool,
}

impl<R: Real> CpuGeometry<R> {
    /// `scene` in view space and the BVH built for it with `effects`.
    pub fn new(scene: &Scene, bvh: &Bvh, effects: &Effects) -> Self {
        // f64 -> R once, as the GPU packing does for f32, in the BVH's
        // render space.
        let scene = &*scene.in_render_space(bvh.scale);
        let v = R::v3_from_f64;
        let features = Features::of(scene, effects);
        // The f32 corners are the f32 path's own (`v` rounds the same way);
        // none where `R` tests leaves one triangle at a time.
        let corners = |r: u32| {
            let t = scene
                .triangles
                .get(r as usize)
                .filter(|_| R::SIMD_LEAVES && r & SPHERE_BIT == 0)?;
            Some(t.vertices.map(|x| x.position.as_vec3().to_array()))
        };
        // The tree on one thread, the primitives on the others: at 8M
        // triangles each is seconds, and a render waits for both.
        use rayon::prelude::*;
        let (wide, (triangles, shading)) = rayon::join(
            || super::wide::collapse(bvh, corners),
            || {
                rayon::join(
                    || {
                        scene
                            .triangles
                            .par_iter()
                            .map(|t| t.vertices.map(|x| v(x.position)))
                            .collect()
                    },
                    || {
                        scene
                            .triangles
                            .par_iter()
                            .map(|t| {
                                t.vertices.map(|x| VertexShading {
                                    normal: v(x.normal),
                                    material: x.material,
                                })
                            })
                            .collect()
                    },
                )
            },
        );
        CpuGeometry {
            spheres: scene
                .spheres
                .iter()
                .map(|s| Sphere {
                    center: v(s.center),
                    radius: R::from_f64(s.radius),
                    kd: v(s.material.kd),
                    ks: v(s.material.ks),
                    shininess: R::from_f64(s.material.shininess),
                    velocity: v(s.velocity),
                })
                .collect(),
            triangles,
            // Read only with motion blur (`triangle_at`).
            triangle_velocity: if features.motion_blur {
                scene.triangles.iter().map(|t| v(t.velocity)).collect()
            } else {
                Vec::new()
            },
            shading,
            materials: scene
                .materials
                .iter()
                .map(|m| SurfaceMaterial {
                    kd: v(m.kd),
                    ks: v(m.ks),
                    shininess: R::from_f64(m.shininess),
                })
                .collect(),
            wide,
            motion_blur: features.motion_blur,
        }
    }
}

impl<'a, R: Real> CpuScene<'a, R> {
    /// Over `geometry`, which `CpuGeometry::new` built for this scene and BVH.
    pub fn new(
        scene: &Scene,
        bvh: &'a Bvh,
        geometry: &'a CpuGeometry<R>,
        camera: &Camera,
        options: &CpuOptions,
    ) -> Self {
        let v = R::v3_from_f64;
        let effects = &options.effects;
        let g = geometry;
        let motion_blur = g.motion_blur;
        CpuScene {
            spheres: &g.spheres,
            triangles: &g.triangles,
            triangle_velocity: &g.triangle_velocity,
            shading: &g.shading,
            materials: &g.materials,
            wide: &g.wide,
            // Lights and ambient only: the rest of the scene is in
            // `geometry`, already in render space.
            lights: scene
                .lights
                .iter()
                .map(|l| l.scaled(bvh.scale))
                .map(|l| {
                    let zero = R::v3(R::ZERO, R::ZERO, R::ZERO);
                    let (kind, radius, edge_u, edge_v) = match l.shape {
                        LightShape::Point => (LIGHT_POINT, R::ZERO, zero, zero),
                        LightShape::Sphere { radius } => {
                            (LIGHT_SPHERE, R::from_f64(radius), zero, zero)
                        }
                        LightShape::Rect { edge_u, edge_v } => {
                            (LIGHT_RECT, R::ZERO, v(edge_u), v(edge_v))
                        }
                    };
                    Light {
                        position: v(l.position),
                        color: v(l.color),
                        kind,
                        radius,
                        edge_u,
                        edge_v,
                        velocity: v(l.velocity),
                    }
                })
                .collect(),
            surfaces_at_lights: &bvh.surfaces_at_lights,
            prim_refs: &bvh.prim_refs,
            ambient: v(scene.ambient),
            background: R::v3_from_f32(options.background),
            half_extent: camera.half_extent.map(R::from_f64),
            size: [camera.width, camera.height],
            methods: options.methods,
            motion_blur,
            seed: effects.seed,
            spp: effects.spp,
            shadow_samples: effects.shadow_samples,
            reflect_depth: effects.reflect_depth,
            // Rounded to f32 first, as the GPU's uniform holds it.
            shutter: if motion_blur {
                R::from_f64(f64::from(effects.shutter_seconds() as f32))
            } else {
                R::ZERO
            },
        }
    }
}

#[derive(Clone, Copy, Debug)]
pub struct Ray<R: Real> {
    pub origin: R::V3,
    pub dir: R::V3,
    pub inv_dir: R::V3,
    pub k: [usize; 3],
    pub shear: R::V3,
    pub time: R,
}

#[derive(Clone, Copy, Debug)]
pub struct Hit<R: Real> {
    pub t: R,
    pub prim: u32,
    pub b1: R,
    pub b2: R,
}

thread_local! {
    /// Closest-hit and shadow rays this thread has cast (`rays_cast`), as
    /// the shader's status counts them; a thread-local, so counting costs
    /// no shared cache line.
    static RAYS: std::cell::Cell<[u64; 2]> = const { std::cell::Cell::new([0; 2]) };
}

pub(super) fn count_ray(kind: usize) {
    RAYS.with(|r| {
        let mut v = r.get();
        v[kind] += 1;
        r.set(v);
    });
}

/// Closest-hit and shadow rays cast on this thread so far; the difference
/// of two readings around some work is what that work cast.
pub fn rays_cast() -> [u64; 2] {
    RAYS.with(std::cell::Cell::get)
}

#[inline(always)]
pub fn make_ray<R: Real>(origin: R::V3, dir: R::V3, time: R) -> Ray<R> {
    let inv_dir = R::v3(
        R::ONE / safe_dir(dir[0]),
        R::ONE / safe_dir(dir[1]),
        R::ONE / safe_dir(dir[2]),
    );
    ray_with_inverse(origin, dir, inv_dir, time)
}

/// A direction component as `make_ray` divides by it: one too near zero
/// for its inverse to stay finite moved off to `MIN_DIR`, with its sign.
#[inline(always)]
pub fn safe_dir<R: Real>(d: R) -> R {
    if d.abs() < R::MIN_DIR {
        d.sign_nonzero() * R::MIN_DIR
    } else {
        d
    }
}

/// `make_ray` once its inverse direction is known (`packet::make_rays`
/// takes the divisions for many rays at once).
#[inline(always)]
pub fn ray_with_inverse<R: Real>(origin: R::V3, dir: R::V3, inv_dir: R::V3, time: R) -> Ray<R> {
    let a = R::vabs(dir);
    let kz = if a[0] > a[1] && a[0] > a[2] {
        0
    } else if a[1] > a[2] {
        1
    } else {
        2
    };
    let mut kx = (kz + 1) % 3;
    let mut ky = (kx + 1) % 3;
    if dir[kz] < R::ZERO {
        std::mem::swap(&mut kx, &mut ky);
    }
    let sz = R::ONE / dir[kz];
    Ray {
        origin,
        dir,
        inv_dir,
        k: [kx, ky, kz],
        shear: R::v3(dir[kx] * sz, dir[ky] * sz, sz),
        time,
    }
}

pub fn camera_ray<R: Real>(scene: &CpuScene<R>, x: u32, y: u32, offset: [R; 2], time: R) -> Ray<R> {
    let (w, h) = (R::from_u32(scene.size[0]), R::from_u32(scene.size[1]));
    let ndc_x = (R::TWO * (R::from_u32(x) + offset[0]) / w - R::ONE) * scene.half_extent[0];
    let ndc_y = (R::ONE - R::TWO * (R::from_u32(y) + offset[1]) / h) * scene.half_extent[1];
    let zero = R::v3(R::ZERO, R::ZERO, R::ZERO);
    make_ray(zero, R::normalize(R::v3(ndc_x, ndc_y, -R::ONE)), time)
}

pub fn pixel_ray<R: Real>(scene: &CpuScene<R>, x: u32, y: u32) -> Ray<R> {
    camera_ray(scene, x, y, [R::HALF, R::HALF], R::ZERO)
}

pub fn sphere_at<R: Real>(scene: &CpuScene<R>, index: usize, time: R) -> Sphere<R> {
    let mut s = scene.spheres[index];
    if scene.motion_blur {
        s.center = s.center + s.velocity * time;
    }
    s
}

pub fn triangle_at<R: Real>(scene: &CpuScene<R>, index: usize, time: R) -> [R::V3; 3] {
    let mut tri = scene.triangles[index];
    if scene.motion_blur {
        let shift = scene.triangle_velocity[index] * time;
        tri = tri.map(|v| v + shift);
    }
    tri
}

pub fn light_at<R: Real>(scene: &CpuScene<R>, index: usize, time: R) -> Light<R> {
    let mut light = scene.lights[index];
    if scene.motion_blur {
        light.position = light.position + light.velocity * time;
    }
    light
}

pub fn hit_aabb<R: Real>(ray: &Ray<R>, bmin: [f32; 3], bmax: [f32; 3], t_max: R) -> R {
    let t0 = (R::v3_from_f32(bmin) - ray.origin) * ray.inv_dir;
    let t1 = (R::v3_from_f32(bmax) - ray.origin) * ray.inv_dir;
    let tn = R::vmin(t0, t1);
    let tf = R::vmax(t0, t1);
    let t_near = tn[0].max(tn[1]).max(tn[2].max(R::ZERO));
    let t_far = tf[0].min(tf[1]).min(tf[2].min(t_max)) * R::BOX_T_SCALE;
    if t_near <= t_far {
        t_near
    } else {
        R::T_INF
    }
}

/// Both t where the ray's line meets the sphere (unordered), or T_INF twice
/// when it misses, or only grazes it: its discriminant r^2 - |l|^2 is below
/// `band` (0 but for shadow rays inside a plane through the light; see
/// `graze_band`). The shader's `sphere_roots`.
pub fn sphere_roots<R: Real>(ray: &Ray<R>, s: &Sphere<R>, band: R) -> [R; 2] {
    let f = ray.origin - s.center;
    let a = R::dot(ray.dir, ray.dir);
    let b = -R::dot(f, ray.dir);
    let c = R::dot(f, f) - s.radius * s.radius;
    let l = f + ray.dir * (b / a);
    let disc = s.radius * s.radius - R::dot(l, l);
    if disc < band {
        return [R::T_INF; 2];
    }
    let q = b + b.sign_nonzero() * (a * disc).sqrt();
    [c / q, q / a]
}

pub fn hit_sphere<R: Real>(ray: &Ray<R>, s: &Sphere<R>, t_max: R, band: R) -> R {
    let [t0, t1] = sphere_roots(ray, s, band);
    let t_lo = t0.min(t1);
    let t_hi = t0.max(t1);
    if t_lo > R::ZERO && t_lo < t_max {
        return t_lo;
    }
    if t_hi > R::ZERO && t_hi < t_max {
        return t_hi;
    }
    R::T_INF
}

/// For a sphere through the light a shadow ray ends at (`skip`): the crossing
/// that is not the light's own, when it lies in (0, 1 - TANGENT_BAND), else
/// T_INF (the shader's `hit_sphere_through_end`).
pub fn hit_sphere_through_end<R: Real>(ray: &Ray<R>, s: &Sphere<R>, band: R) -> R {
    let [t0, t1] = sphere_roots(ray, s, band);
    // The root nearer 1 is the light's own (a miss gives T_INF either way).
    let other = if (t0 - R::ONE).abs() > (t1 - R::ONE).abs() {
        t0
    } else {
        t1
    };
    if other > R::ZERO && other < R::ONE - R::from_f64(crate::lights_on_surfaces::TANGENT_BAND) {
        other
    } else {
        R::T_INF
    }
}

pub fn hit_sphere_naive<R: Real>(ray: &Ray<R>, s: &Sphere<R>, t_max: R) -> R {
    let oc = ray.origin - s.center;
    let a = R::dot(ray.dir, ray.dir);
    let b = R::TWO * R::dot(oc, ray.dir);
    let c = R::dot(oc, oc) - s.radius * s.radius;
    let disc = b * b - R::from_f64(4.0) * a * c;
    if disc < R::ZERO {
        return R::T_INF;
    }
    let root = disc.sqrt();
    let t0 = (-b - root) / (R::TWO * a);
    let t1 = (-b + root) / (R::TWO * a);
    if t0 > R::ZERO && t0 < t_max {
        return t0;
    }
    if t1 > R::ZERO && t1 < t_max {
        return t1;
    }
    R::T_INF
}

pub fn hit_triangle_naive<R: Real>(ray: &Ray<R>, tri: &[R::V3; 3], t_max: R) -> (R, R, R) {
    let miss = (R::T_INF, R::ZERO, R::ZERO);
    let e1 = tri[1] - tri[0];
    let e2 = tri[2] - tri[0];
    let pv = R::cross(ray.dir, e2);
    let det = R::dot(e1, pv);
    if det.abs() < R::NAIVE_DET_EPSILON {
        return miss;
    }
    let inv_det = R::ONE / det;
    let tv = ray.origin - tri[0];
    let u = R::dot(tv, pv) * inv_det;
    if u < R::ZERO || u > R::ONE {
        return miss;
    }
    let qv = R::cross(tv, e1);
    let v = R::dot(ray.dir, qv) * inv_det;
    if v < R::ZERO || u + v > R::ONE {
        return miss;
    }
    let t = R::dot(e2, qv) * inv_det;
    if t <= R::ZERO || t >= t_max {
        return miss;
    }
    (t, u, v)
}

/// Returns (t, b1, b2), t = `T_INF` for a miss.
pub fn hit_triangle<R: Real>(ray: &Ray<R>, tri: &[R::V3; 3], t_max: R) -> (R, R, R) {
    let miss = (R::T_INF, R::ZERO, R::ZERO);
    let a = tri[0] - ray.origin;
    let b = tri[1] - ray.origin;
    let c = tri[2] - ray.origin;
    let [kx, ky, kz] = ray.k;
    let s = ray.shear;
    let ax = a[kx] - s[0] * a[kz];
    let ay = a[ky] - s[1] * a[kz];
    let bx = b[kx] - s[0] * b[kz];
    let by = b[ky] - s[1] * b[kz];
    let cx = c[kx] - s[0] * c[kz];
    let cy = c[ky] - s[1] * c[kz];
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    let zero = R::ZERO;
    if (u < zero || v < zero || w < zero) && (u > zero || v > zero || w > zero) {
        return miss;
    }
    let det = u + v + w;
    if det == zero {
        return miss;
    }
    let az = s[2] * a[kz];
    let bz = s[2] * b[kz];
    let cz = s[2] * c[kz];
    let t_scaled = u * az + v * bz + w * cz;
    let positive = t_scaled > zero && t_scaled < t_max * det;
    let negative = t_scaled < zero && t_scaled > t_max * det;
    let inside = if det > zero { positive } else { negative };
    if !inside {
        return miss;
    }
    let inv_det = R::ONE / det;
    (t_scaled * inv_det, v * inv_det, w * inv_det)
}

/// A leaf's primitives: true when an any-hit query found its hit. Up to
/// four static triangles meet the robust test in SIMD lanes where `R` has
/// them; the rest one by one.
pub(super) fn hit_leaf<R: Real>(
    scene: &CpuScene<R>,
    ray: &Ray<R>,
    leaf: usize,
    best: &mut Hit<R>,
    any_hit: bool,
    skip: &[u32],
    graze: R,
) -> bool {
    let robust = scene.methods == Methods::Robust;
    let block = &scene.wide.leaves[leaf];
    if block.simd() && robust && !scene.motion_blur && skip.is_empty() {
        if let Some((lane, t, b1, b2)) = R::hit_block(ray, block, best.t) {
            let prim = block.prims[lane];
            *best = Hit { t, prim, b1, b2 };
            return any_hit;
        }
        return false;
    }
    for &prim in &scene.prim_refs[scene.wide.spans[leaf].range()] {
        if hit_prim(scene, ray, prim, best, any_hit, skip, graze) {
            return true;
        }
    }
    false
}

/// The primitive `prim` (a reference): true when `any_hit` and it blocks,
/// so the traversal can stop. The shader's `hit_prim`, which its traversal
/// calls for every reference of a node's hit leaves in one loop.
fn hit_prim<R: Real>(
    scene: &CpuScene<R>,
    ray: &Ray<R>,
    prim: u32,
    best: &mut Hit<R>,
    any_hit: bool,
    skip: &[u32],
    graze: R,
) -> bool {
    // The shader branches on ROBUST inside hit_sphere and hit_triangle.
    let robust = scene.methods == Methods::Robust;
    let index = (prim & !SPHERE_BIT) as usize;
    if any_hit && skip.contains(&prim) {
        // A surface through the light: triangles never block it, a
        // sphere only with its other crossing.
        if prim & SPHERE_BIT != 0 {
            let sphere = &sphere_at(scene, index, ray.time);
            let t = hit_sphere_through_end(ray, sphere, graze_band(graze, sphere.radius));
            if t < best.t {
                *best = Hit {
                    t,
                    prim,
                    b1: R::ZERO,
                    b2: R::ZERO,
                };
                return true;
            }
        }
        return false;
    }
    if prim & SPHERE_BIT != 0 {
        let sphere = &sphere_at(scene, index, ray.time);
        let t = if robust {
            let band = if any_hit {
                graze_band(graze, sphere.radius)
            } else {
                R::ZERO
            };
            hit_sphere(ray, sphere, best.t, band)
        } else {
            hit_sphere_naive(ray, sphere, best.t)
        };
        if t < best.t {
            *best = Hit {
                t,
                prim,
                b1: R::ZERO,
                b2: R::ZERO,
            };
            return any_hit;
        }
    } else {
        let tri = &triangle_at(scene, index, ray.time);
        let (t, b1, b2) = if robust {
            hit_triangle(ray, tri, best.t)
        } else {
            hit_triangle_naive(ray, tri, best.t)
        };
        if t < best.t {
            *best = Hit { t, prim, b1, b2 };
            return any_hit;
        }
    }
    false
}

/// With `any_hit`, `skip` names the surfaces through the light the ray ends
/// at and `graze` is the height of the ray's grazing band (`graze_band`).
///
/// Nearest child first: of the lanes a node's test hits, the nearest is
/// entered next and the others wait on the stack with their entry t, to be
/// dropped unopened if a hit closer than that has been found meanwhile
/// (the box test they would fail).
pub fn traverse<R: Real>(
    scene: &CpuScene<R>,
    ray: &Ray<R>,
    t_max: R,
    any_hit: bool,
    skip: &[u32],
    graze: R,
) -> Hit<R> {
    let mut best = Hit {
        t: t_max,
        prim: NO_HIT,
        b1: R::ZERO,
        b2: R::ZERO,
    };
    if scene.wide.nodes.is_empty() {
        return best;
    }
    let mut stack = Stack::new();
    stack.push(0, R::ZERO);
    traverse_from(scene, ray, &mut best, any_hit, skip, graze, &mut stack);
    best
}

/// `traverse`'s stack: nodes to visit with their entry t. Left
/// uninitialised, because clearing a fresh array per ray cost a tenth of
/// the render, and a stack kept per thread cost its lookups.
struct Stack<R: Real> {
    items: [std::mem::MaybeUninit<(u32, R)>; wide::STACK],
    len: usize,
}

impl<R: Real> Stack<R> {
    fn new() -> Self {
        Stack {
            items: [std::mem::MaybeUninit::uninit(); wide::STACK],
            len: 0,
        }
    }

    #[inline(always)]
    fn push(&mut self, node: u32, t: R) {
        // Indexed with a bounds check: `wide::STACK` bounds the depth.
        self.items[self.len] = std::mem::MaybeUninit::new((node, t));
        self.len += 1;
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, R)> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: items[..len] were all written by `push`.
        Some(unsafe { self.items[self.len].assume_init() })
    }
}

/// `traverse` from `node` down, keeping `best` unless it finds nearer.
pub(crate) fn traverse_below<R: Real>(
    scene: &CpuScene<R>,
    ray: &Ray<R>,
    node: u32,
    best: &mut Hit<R>,
    any_hit: bool,
) {
    let mut stack = Stack::new();
    stack.push(node, R::ZERO);
    traverse_from(scene, ray, best, any_hit, &[], R::ZERO, &mut stack);
}

#[allow(clippy::too_many_arguments)]
fn traverse_from<R: Real>(
    scene: &CpuScene<R>,
    ray: &Ray<R>,
    best: &mut Hit<R>,
    any_hit: bool,
    skip: &[u32],
    graze: R,
    stack: &mut Stack<R>,
) {
    while let Some((entry, t_entry)) = stack.pop() {
        if t_entry > best.t * R::BOX_T_SCALE {
            continue;
        }
        let node = &scene.wide.nodes[entry as usize];
        let (mut mask, t) = R::hit_boxes(ray, node, best.t);
        // Hit lanes onto the stack, farthest first, so the nearest is
        // popped next; the order is fixed by t, then lane. The shader's
        // `traverse` keeps the same order (its `order`, `append_hit`).
        let mut lanes = [0usize; 4];
        let mut n = 0;
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            // A ray with a NaN direction passes every box test, even an
            // unused lane's (and then hits no primitive).
            if node.child[lane] == wide::EMPTY {
                continue;
            }
            let mut i = n;
            while i > 0 && t[lanes[i - 1]] < t[lane] {
                lanes[i] = lanes[i - 1];
                i -= 1;
            }
            lanes[i] = lane;
            n += 1;
        }
        // Leaves are tested as they come, nearest first; nodes are stacked.
        for &lane in lanes[..n].iter().rev() {
            let child = node.child[lane];
            if child & wide::LEAF == 0 {
                continue;
            }
            if t[lane] > best.t * R::BOX_T_SCALE {
                continue;
            }
            let leaf = (child & !wide::LEAF) as usize;
            if hit_leaf(scene, ray, leaf, best, any_hit, skip, graze) {
                return;
            }
        }
        for &lane in &lanes[..n] {
            let child = node.child[lane];
            if child & wide::LEAF == 0 {
                stack.push(child, t[lane]);
            }
        }
    }
}

pub fn trace_closest<R: Real>(scene: &CpuScene<R>, ray: &Ray<R>) -> Hit<R> {
    count_ray(0);
    traverse(scene, ray, R::T_INF, false, &[], R::ZERO)
}

/// `skip`, `graze`: the surfaces through the light and the grazing band's
/// height (`lights_on_surfaces`; empty and 0 for other lights).
pub fn occluder<R: Real>(scene: &CpuScene<R>, ray: &Ray<R>, skip: &[u32], graze: R) -> Hit<R> {
    count_ray(1);
    traverse(scene, ray, R::ONE, true, skip, graze)
}

/// The least discriminant r^2 - |l|^2 at which a shadow ray whose line may
/// lie up to `h` off its true one still meets a sphere of radius `r`
/// (`h` = 0: any). Moving a line by h changes |l|^2 by at most
/// 2 r h + h^2, so within the band it may only graze the sphere; the
/// sphere's own rounding adds ON_SURFACE r to h. The shader's `graze_band`.
pub fn graze_band<R: Real>(h: R, r: R) -> R {
    if h <= R::ZERO {
        return R::ZERO;
    }
    let h = h + R::from_f64(crate::lights_on_surfaces::ON_SURFACE) * r;
    h * (R::TWO * r + h)
}

/// For a shadow ray towards a point light on a surface: when the light lies
/// in the plane of the surface the ray leaves (within the ray's own lift off
/// it and the light's rounding), the height of the band within which the
/// ray's true line runs inside that plane, else 0. Such a line can only
/// touch a sphere resting on the plane, so lifted by the origin offset it
/// must not be blocked by clipping one (`lights_on_surfaces`).
pub fn in_plane_graze<R: Real>(sp: &SurfacePoint<R>, origin: R::V3, target: R::V3) -> R {
    let length = |v: R::V3| R::dot(v, v).sqrt();
    let to_light = target - sp.p;
    let t = R::vabs(target);
    let h = R::TWO * length(origin - sp.p)
        + R::from_f64(crate::lights_on_surfaces::ON_SURFACE)
            * (t[0].max(t[1]).max(t[2]) + length(to_light));
    if R::dot(sp.ng, to_light).abs() <= h {
        R::TWO * h
    } else {
        R::ZERO
    }
}

pub fn offset_ray<R: Real>(scene: &CpuScene<R>, p: R::V3, n: R::V3, scale: R::V3) -> R::V3 {
    match scene.methods {
        Methods::Robust => R::offset_ray(p, n, scale),
        Methods::Naive => p + n * R::NAIVE_OFFSET,
    }
}

pub fn safe_normalize<R: Real>(v: R::V3, fallback: R::V3) -> R::V3 {
    let len2 = R::dot(v, v);
    if len2 > R::ZERO {
        v * len2.inverse_sqrt()
    } else {
        fallback
    }
}

pub fn pow_c<R: Real>(x: R, y: R) -> R {
    if y == R::ZERO {
        return R::ONE;
    }
    if x <= R::ZERO {
        return R::ZERO;
    }
    x.powf(y)
}

#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint<R: Real> {
    pub p: R::V3,
    pub n: R::V3,
    pub ng: R::V3,
    pub scale: R::V3,
    pub kd: R::V3,
    pub ks: R::V3,
    pub shininess: R,
}

pub fn surface_point<R: Real>(scene: &CpuScene<R>, ray: &Ray<R>, hit: &Hit<R>) -> SurfacePoint<R> {
    let index = (hit.prim & !SPHERE_BIT) as usize;
    if hit.prim & SPHERE_BIT != 0 {
        let s = &sphere_at(scene, index, ray.time);
        let p = ray.origin + ray.dir * hit.t;
        let n = (p - s.center) * (R::ONE / s.radius);
        return SurfacePoint {
            p,
            n,
            ng: n,
            scale: R::vabs(s.center) + R::v3(s.radius, s.radius, s.radius),
            kd: s.kd,
            ks: s.ks,
            shininess: s.shininess,
        };
    }
    let tri = &triangle_at(scene, index, ray.time);
    let b0 = R::ONE - hit.b1 - hit.b2;
    let w = [b0, hit.b1, hit.b2];
    let p = match scene.methods {
        Methods::Robust => tri[0] * w[0] + tri[1] * w[1] + tri[2] * w[2],
        Methods::Naive => ray.origin + ray.dir * hit.t,
    };
    let up = R::v3(R::ZERO, R::ZERO, R::ONE);
    let ng = safe_normalize::<R>(R::cross(tri[1] - tri[0], tri[2] - tri[0]), up);
    let s = &scene.shading[index];
    let n = safe_normalize::<R>(
        s[0].normal * w[0] + s[1].normal * w[1] + s[2].normal * w[2],
        ng,
    );
    let m = s.map(|c| &scene.materials[c.material as usize]);
    SurfacePoint {
        p,
        n,
        ng,
        scale: R::vabs(tri[0] * w[0]) + R::vabs(tri[1] * w[1]) + R::vabs(tri[2] * w[2]),
        kd: m[0].kd * w[0] + m[1].kd * w[1] + m[2].kd * w[2],
        ks: m[0].ks * w[0] + m[1].ks * w[1] + m[2].ks * w[2],
        shininess: w[0] * m[0].shininess + w[1] * m[1].shininess + w[2] * m[2].shininess,
    }
}

#[derive(Clone, Copy, Debug)]
pub struct LightTerm<R: Real> {
    pub origin: R::V3,
    pub blocker: Hit<R>,
    pub ln: R,
    pub rv: R,
    pub spec: R,
    pub contribution: R::V3,
}

/// `skip`: the surfaces through `target` when it is a point light's
/// position (`lights_on_surfaces`), else empty.
#[allow(clippy::too_many_arguments)]
pub fn point_term<R: Real>(
    scene: &CpuScene<R>,
    sp: &SurfacePoint<R>,
    view: R::V3,
    target: R::V3,
    color: R::V3,
    time: R,
    skip: &[u32],
) -> LightTerm<R> {
    let (origin, ray, graze) = point_shadow_ray(scene, sp, target, time, skip);
    let blocker = occluder(scene, &ray, skip, graze);
    point_shading(sp, view, target, color, origin, blocker)
}

/// The shadow ray `point_term` casts from `sp` towards `target`: its
/// origin, the ray (t = 1 at the target) and its grazing band.
#[inline(always)]
pub fn point_shadow_ray<R: Real>(
    scene: &CpuScene<R>,
    sp: &SurfacePoint<R>,
    target: R::V3,
    time: R,
    skip: &[u32],
) -> (R::V3, Ray<R>, R) {
    let origin = shadow_origin(scene, sp, target);
    let graze = if skip.is_empty() {
        R::ZERO
    } else {
        in_plane_graze(sp, origin, target)
    };
    (origin, make_ray(origin, target - origin, time), graze)
}

/// Where the shadow ray from `sp` towards `target` starts: `sp` moved off
/// its surface to the side `target` is on.
#[inline(always)]
pub fn shadow_origin<R: Real>(scene: &CpuScene<R>, sp: &SurfacePoint<R>, target: R::V3) -> R::V3 {
    let to_light = target - sp.p;
    let side = if R::dot(sp.ng, to_light) >= R::ZERO {
        sp.ng
    } else {
        -sp.ng
    };
    offset_ray(scene, sp.p, side, sp.scale)
}

/// `point_term` once its shadow ray from `origin` found `blocker`.
#[inline(always)]
pub fn point_shading<R: Real>(
    sp: &SurfacePoint<R>,
    view: R::V3,
    target: R::V3,
    color: R::V3,
    origin: R::V3,
    blocker: Hit<R>,
) -> LightTerm<R> {
    let zero = R::v3(R::ZERO, R::ZERO, R::ZERO);
    let mut term = LightTerm {
        origin,
        blocker,
        ln: R::ZERO,
        rv: R::ZERO,
        spec: R::ZERO,
        contribution: zero,
    };
    if term.blocker.prim != NO_HIT {
        return term;
    }
    let to_light = target - sp.p;
    let l = safe_normalize::<R>(to_light, sp.n);
    term.ln = R::dot(l, sp.n);
    let r = sp.n * (R::TWO * term.ln) - l;
    term.rv = R::dot(r, view).max(R::ZERO);
    term.spec = pow_c(term.rv, sp.shininess);
    term.contribution = color * (sp.kd * term.ln.max(R::ZERO) + sp.ks * term.spec);
    term
}

#[derive(Clone, Copy, Debug)]
pub struct SampleKey<R: Real> {
    pub pixel: u32,
    pub sample: u32,
    pub time: R,
}

fn basis_u<R: Real>(w: R::V3) -> R::V3 {
    let s = w[2].sign_nonzero();
    let a = -R::ONE / (s + w[2]);
    R::v3(R::ONE + s * w[0] * w[0] * a, s * w[0] * w[1] * a, -s * w[0])
}

fn basis_v<R: Real>(w: R::V3) -> R::V3 {
    let s = w[2].sign_nonzero();
    let a = -R::ONE / (s + w[2]);
    R::v3(w[0] * w[1] * a, s + w[1] * w[1] * a, -w[1])
}

pub fn light_sample_point<R: Real>(light: &Light<R>, p: R::V3, uv: [R; 2]) -> R::V3 {
    if light.kind == LIGHT_RECT {
        return light.position
            + light.edge_u * (uv[0] - R::HALF)
            + light.edge_v * (uv[1] - R::HALF);
    }
    let up = R::v3(R::ZERO, R::ZERO, R::ONE);
    let w = safe_normalize::<R>(light.position - p, up);
    let r = light.radius * uv[0].sqrt();
    let phi = R::TWO * R::PI * uv[1];
    light.position + basis_u::<R>(w) * (r * phi.cos()) + basis_v::<R>(w) * (r * phi.sin())
}

pub fn area_term<R: Real>(
    scene: &CpuScene<R>,
    sp: &SurfacePoint<R>,
    view: R::V3,
    light: &Light<R>,
    stream: u32,
    key: &SampleKey<R>,
) -> LightTerm<R> {
    let n = scene.shadow_samples.max(1);
    let draw = |index| rng(scene.seed, key.pixel, key.sample, stream, index);
    let rotation = draw(ROTATION);
    let color = light.color * (R::ONE / R::from_u32(n));
    let zero = R::v3(R::ZERO, R::ZERO, R::ZERO);
    let no_hit = Hit {
        t: R::ZERO,
        prim: NO_HIT,
        b1: R::ZERO,
        b2: R::ZERO,
    };
    let mut total = LightTerm {
        origin: zero,
        blocker: no_hit,
        ln: R::ZERO,
        rv: R::ZERO,
        spec: R::ZERO,
        contribution: zero,
    };
    let mut blocked = 0;
    for m in 0..n {
        let jitter = [unit_float(draw(2 * m)), unit_float(draw(2 * m + 1))];
        let uv = stratified_2d(m, n, rotation, jitter);
        let target = light_sample_point(light, sp.p, uv);
        let term = point_term(scene, sp, view, target, color, key.time, &[]);
        total.contribution = total.contribution + term.contribution;
        total.origin = term.origin;
        if term.blocker.prim != NO_HIT {
            if blocked == 0 {
                total.blocker = term.blocker;
            }
            blocked += 1;
        } else {
            total.ln = term.ln;
            total.rv = term.rv;
            total.spec = term.spec;
        }
    }
    if blocked < n {
        total.blocker = no_hit;
    }
    total
}

pub fn light_term<R: Real>(
    scene: &CpuScene<R>,
    sp: &SurfacePoint<R>,
    view: R::V3,
    i: usize,
    bounce: u32,
    key: &SampleKey<R>,
) -> LightTerm<R> {
    let light = light_at(scene, i, key.time);
    if light.kind != LIGHT_POINT {
        let stream = STREAM_LIGHT
            .wrapping_add(bounce << 24)
            .wrapping_add(i as u32);
        return area_term(scene, sp, view, &light, stream, key);
    }
    let skip = scene
        .surfaces_at_lights
        .get(i)
        .map_or(&[][..], Vec::as_slice);
    point_term(scene, sp, view, light.position, light.color, key.time, skip)
}

#[derive(Clone, Copy, Debug)]
pub struct Shading<R: Real> {
    pub color: R::V3,
    pub shadow_mask: u32,
}

pub fn shade_phong<R: Real>(
    scene: &CpuScene<R>,
    sp: &SurfacePoint<R>,
    view: R::V3,
    bounce: u32,
    key: &SampleKey<R>,
) -> Shading<R> {
    let mut out = Shading {
        color: scene.ambient,
        shadow_mask: 0,
    };
    for i in 0..scene.lights.len() {
        let term = light_term(scene, sp, view, i, bounce, key);
        out.color = out.color + term.contribution;
        if term.blocker.prim != NO_HIT {
            out.shadow_mask |= 1 << i.min(31);
        }
    }
    out
}

#[derive(Clone, Copy, Debug)]
pub struct PixelResult<R: Real> {
    pub hit: Hit<R>,
    /// Not yet clamped.
    pub color: R::V3,
    pub shadow_mask: u32,
    pub flags: u32,
}

pub fn trace_primary<R: Real>(
    scene: &CpuScene<R>,
    ray: &Ray<R>,
    key: &SampleKey<R>,
) -> PixelResult<R> {
    let hit = trace_closest(scene, ray);
    if hit.prim == NO_HIT {
        return PixelResult {
            hit,
            color: scene.background,
            shadow_mask: 0,
            flags: 0,
        };
    }
    let sp = surface_point(scene, ray, &hit);
    let shading = shade_phong(scene, &sp, -ray.dir, 0, key);
    let mut flags = 0;
    if R::nonfinite(shading.color) {
        flags |= FLAG_NONFINITE_COLOR;
    }
    if R::nonfinite(sp.p) || R::nonfinite(sp.n) {
        flags |= FLAG_NONFINITE_SURFACE;
    }
    PixelResult {
        hit,
        color: shading.color,
        shadow_mask: shading.shadow_mask,
        flags,
    }
}

pub fn radiance<R: Real>(scene: &CpuScene<R>, primary: &Ray<R>, key: &SampleKey<R>) -> R::V3 {
    let first = trace_primary(scene, primary, key);
    let local = R::clamp01(first.color);
    if first.hit.prim != NO_HIT && scene.reflect_depth > 0 {
        return reflect_path(scene, primary, first.hit, local, key);
    }
    local
}

pub(super) fn reflect_path<R: Real>(
    scene: &CpuScene<R>,
    primary: &Ray<R>,
    first_hit: Hit<R>,
    first_local: R::V3,
    key: &SampleKey<R>,
) -> R::V3 {
    let mut ray = *primary;
    let mut sp = surface_point(scene, primary, &first_hit);
    let mut local = first_local;
    let mut color = R::v3(R::ZERO, R::ZERO, R::ZERO);
    let one = R::v3(R::ONE, R::ONE, R::ONE);
    let mut weight = one;
    for bounce in 0..scene.reflect_depth {
        if (0..3).all(|i| sp.ks[i] == R::ZERO) {
            break;
        }
        color = color + weight * (one - sp.ks) * local;
        weight = weight * sp.ks;
        let dir = safe_normalize::<R>(ray.dir - sp.n * (R::TWO * R::dot(ray.dir, sp.n)), sp.n);
        let side = if R::dot(sp.ng, dir) >= R::ZERO {
            sp.ng
        } else {
            -sp.ng
        };
        ray = make_ray(offset_ray(scene, sp.p, side, sp.scale), dir, ray.time);
        let hit = trace_closest(scene, &ray);
        if hit.prim == NO_HIT {
            local = scene.background;
            break;
        }
        sp = surface_point(scene, &ray, &hit);
        local = R::clamp01(shade_phong(scene, &sp, -ray.dir, bounce + 1, key).color);
    }
    color + weight * local
}

pub fn sample_color<R: Real>(scene: &CpuScene<R>, x: u32, y: u32, s: u32, n: u32) -> R::V3 {
    let pixel = y.wrapping_mul(scene.size[0]).wrapping_add(x);
    let draw = |sample, stream, index| rng(scene.seed, pixel, sample, stream, index);
    let mut offset = [R::HALF, R::HALF];
    let mut time = R::ZERO;
    if n > 1 {
        let rotation = draw(ROTATION, STREAM_PIXEL, ROTATION);
        let jitter = [
            unit_float(draw(s, STREAM_PIXEL, 0)),
            unit_float(draw(s, STREAM_PIXEL, 1)),
        ];
        offset = stratified_2d(s, n, rotation, jitter);
    }
    if scene.motion_blur {
        time = scene.shutter * unit_float(draw(s, STREAM_TIME, 0));
    }
    let key = SampleKey {
        pixel,
        sample: s,
        time,
    };
    radiance(scene, &camera_ray(scene, x, y, offset, time), &key)
}

pub fn pixel_color<R: Real>(scene: &CpuScene<R>, x: u32, y: u32) -> R::V3 {
    let n = scene.spp.max(1);
    if n == 1 {
        return sample_color(scene, x, y, 0, 1);
    }
    let mut sum = R::v3(R::ZERO, R::ZERO, R::ZERO);
    for s in 0..n {
        sum = sum + sample_color(scene, x, y, s, n);
    }
    sum * (R::ONE / R::from_u32(n))
}

pub fn centre_key<R: Real>(scene: &CpuScene<R>, x: u32, y: u32) -> SampleKey<R> {
    SampleKey {
        pixel: y.wrapping_mul(scene.size[0]).wrapping_add(x),
        sample: 0,
        time: R::ZERO,
    }
}
