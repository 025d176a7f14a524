//! The scene as the CPU reference traces it: f32 or f64 geometry built once
//! from the scene and its tree, lights, materials, and what a hit records.

use crate::bvh::wide::WideBvh;
use crate::bvh::Bvh;
use crate::camera::Camera;
use crate::cpu::options::CpuOptions;
use crate::cpu::real::Real;
use crate::features::Features;
use crate::layout::{LIGHT_POINT, LIGHT_RECT, LIGHT_SPHERE, SPHERE_BIT};
use crate::methods::Methods;
use crate::scene::{Effects, LightShape, Sampler, Scene};

/// `Hit::prim` of a ray that hit nothing.
pub const NO_HIT: u32 = u32::MAX;

/// A sphere as the CPU reference reads it.
#[derive(Clone, Copy, Debug)]
pub struct Sphere<R: Real> {
    /// The centre (at time 0 when it moves).
    pub center: R::V3,
    /// The radius.
    pub radius: R,
    /// Diffuse colour.
    pub kd: R::V3,
    /// Specular colour.
    pub ks: R::V3,
    /// Phong exponent.
    pub shininess: R,
    /// Scene units a second it moves (zero when still).
    pub velocity: R::V3,
}

/// A triangle corner's shading normal and material (an index into
/// `CpuScene::materials`, as the scene keeps them: a material per corner
/// would be most of a big scene's memory here too).
#[derive(Clone, Copy, Debug)]
pub struct VertexShading<R: Real> {
    /// The corner's shading normal (not normalised).
    pub normal: R::V3,
    /// Index into `CpuScene::materials`.
    pub material: u32,
}

/// One distinct (kd, ks, shininess) of the triangle corners.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceMaterial<R: Real> {
    /// Diffuse colour.
    pub kd: R::V3,
    /// Specular colour.
    pub ks: R::V3,
    /// Phong exponent.
    pub shininess: R,
}

/// A light as the CPU reference reads it (the shader's `GpuLight`).
#[derive(Clone, Copy, Debug)]
pub struct Light<R: Real> {
    /// Point lights: the light; area lights: the centre.
    pub position: R::V3,
    /// The light's colour.
    pub color: R::V3,
    /// `LIGHT_POINT`, `LIGHT_SPHERE` or `LIGHT_RECT`.
    pub kind: u32,
    /// Sphere lights only.
    pub radius: R,
    /// Rectangle lights only: the first edge, centred on `position`.
    pub edge_u: R::V3,
    /// Rectangle lights only: the second edge.
    pub edge_v: R::V3,
    /// Scene units a second the light moves (motion blur).
    pub velocity: R::V3,
}

/// The scene as the CPU reference reads it: the shader's buffers, in `R`.
/// The BVH is shared with the GPU (f32 boxes, rounded outward). The
/// per-primitive arrays and the wide tree are a `CpuGeometry`'s, built
/// once per prepared scene (`render::Renderer`), as the GPU packs its
/// buffers once.
pub struct CpuScene<'a, R: Real> {
    /// The spheres.
    pub spheres: &'a [Sphere<R>],
    /// The triangles' corner positions.
    pub triangles: &'a [[R::V3; 3]],
    /// Per triangle, scene units a second it moves (read with motion blur only).
    pub triangle_velocity: &'a [R::V3],
    /// Per triangle, its corners' normals and materials.
    pub shading: &'a [[VertexShading<R>; 3]],
    /// The distinct materials of the triangle corners.
    pub materials: &'a [SurfaceMaterial<R>],
    /// The lights, in render space.
    pub lights: Vec<Light<R>>,
    /// The BVH collapsed to four children a node, with its leaves'
    /// triangles in blocks for the SIMD test (`wide`).
    pub wide: &'a WideBvh,
    /// Leaf references into the spheres (`SPHERE_BIT`) and triangles.
    pub prim_refs: &'a [u32],
    /// Per light, the surfaces through it (`lights_on_surfaces`).
    pub surfaces_at_lights: &'a [Vec<u32>],
    /// The ambient colour, added once.
    pub ambient: R::V3,
    /// The colour of rays that hit nothing.
    pub background: R::V3,
    /// The camera's half extent of the image plane at distance 1 (x, y).
    pub half_extent: [R; 2],
    /// Image width and height in pixels.
    pub size: [u32; 2],
    /// The shader's `ROBUST` override.
    pub methods: Methods,
    /// The shader's `MOTION_BLUR` override.
    pub motion_blur: bool,
    /// Seed of the per-pixel sample hash.
    pub seed: u32,
    /// How the random dimensions are drawn (the shader's `frame.sampling`).
    pub sampler: Sampler,
    /// Samples per pixel.
    pub spp: u32,
    /// Shadow samples per area light.
    pub shadow_samples: u32,
    /// Reflection bounces after the primary hit.
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
        // The tree's shape on one thread, the primitives on the others: at
        // 8M triangles each is seconds, and a render waits for both.
        use rayon::prelude::*;
        let (mut wide, (triangles, shading)) = rayon::join(
            || WideBvh::shape(bvh),
            || {
                rayon::join(
                    || {
                        scene
                            .triangles
                            .par_iter()
                            .map(|t| t.vertices.map(|x| v(x.position)))
                            .collect::<Vec<_>>()
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
        wide.fill_leaves(bvh, leaf_corners::<R>(&triangles));
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

/// A triangle reference's corners in f32 for the leaf blocks, read from
/// the converted triangles (36 or 72 bytes, not the scene's 192): in f32
/// they are those corners, in f64 their nearest f32, as the f32 path
/// rounds the scene's values. None for a sphere, and always where `R`
/// tests leaves one triangle at a time.
fn leaf_corners<R: Real>(
    triangles: &[[R::V3; 3]],
) -> impl Fn(u32) -> Option<[[f32; 3]; 3]> + Sync + '_ {
    move |r: u32| {
        let t = triangles
            .get(r as usize)
            .filter(|_| R::SIMD_LEAVES && r & SPHERE_BIT == 0)?;
        Some(t.map(R::v3_to_f32))
    }
}

impl<R: Real> CpuGeometry<R> {
    /// Moves this geometry to `scene`, the primitives it was made from
    /// moved along their velocities (`Scene::at_time`, in view space), with
    /// `bvh` refitted to them: new corners, sphere centres and boxes, in
    /// the wide tree's shape. Normals, materials, radii and velocities are
    /// what moving leaves them, so they are kept.
    pub(crate) fn refit(&mut self, scene: &Scene, bvh: &Bvh) {
        use rayon::prelude::*;
        let scene = &*scene.in_render_space(bvh.scale);
        let v = R::v3_from_f64;
        for (s, moved) in self.spheres.iter_mut().zip(&scene.spheres) {
            s.center = v(moved.center);
        }
        self.triangles
            .par_iter_mut()
            .zip(scene.triangles.par_iter())
            .with_min_len(1 << 12)
            .for_each(|(t, moved)| *t = moved.vertices.map(|x| v(x.position)));
        self.wide.refit(bvh, leaf_corners::<R>(&self.triangles));
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
            sampler: effects.sampler,
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

/// The closest hit of a ray.
#[derive(Clone, Copy, Debug)]
pub struct Hit<R: Real> {
    /// Distance along the ray.
    pub t: R,
    /// The primitive hit (`SPHERE_BIT` marks a sphere), or `NO_HIT`.
    pub prim: u32,
    /// First barycentric coordinate (triangles).
    pub b1: R,
    /// Second barycentric coordinate (triangles).
    pub b2: R,
}

/// What shading needs of a hit point.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint<R: Real> {
    /// The point.
    pub p: R::V3,
    /// The shading normal, unit length.
    pub n: R::V3,
    /// The geometric normal: the triangle's plane, unit length (spheres: `n`).
    pub ng: R::V3,
    /// Per axis, the size the offset of a ray leaving `p` scales with.
    pub scale: R::V3,
    /// Diffuse colour.
    pub kd: R::V3,
    /// Specular colour.
    pub ks: R::V3,
    /// Phong exponent.
    pub shininess: R,
}
