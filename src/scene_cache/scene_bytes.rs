//! A loaded `Scene` as an entry's body, every field of it, and back. The
//! triangles, nearly all of a big scene, go as one array of plain records
//! converted on every thread; the rest field by field. Decoding checks
//! what the renderer would index with (a corner's material), so an entry
//! that decodes is a scene glint can render.

use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use rayon::prelude::*;

use super::codec::{Reader, Result, Writer};
use crate::mesh::report::{Report, Tolerance, Warning};
use crate::scene::{
    Bounds, CameraSpec, Diagnostic, Light, LightShape, Material, MeshInfo, Sampler, Scene,
    Settings, Sphere, Triangle, Vertex,
};

/// A triangle as stored: corners' positions and normals, their
/// materials, the velocity.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct StoredTriangle {
    corners: [[f64; 6]; 3],
    materials: [u32; 3],
    pad: u32,
    velocity: [f64; 3],
}

fn v3(v: DVec3) -> [f64; 3] {
    v.to_array()
}

fn d3(a: &[f64]) -> DVec3 {
    DVec3::new(a[0], a[1], a[2])
}

fn material_values(m: &Material) -> [f64; 7] {
    let (d, s) = (m.kd, m.ks);
    [d.x, d.y, d.z, s.x, s.y, s.z, m.shininess]
}

fn material_from(a: &[f64]) -> Material {
    Material {
        kd: d3(&a[0..3]),
        ks: d3(&a[3..6]),
        shininess: a[6],
    }
}

/// `scene` as a body, or `None` where a path in it is not UTF-8 (such a
/// scene is loaded every time, not cached).
pub(super) fn encode(scene: &Scene, w: &mut Writer) -> Option<()> {
    w.array(&[v3(scene.ambient)]);
    let spheres: Vec<[f64; 14]> = scene
        .spheres
        .iter()
        .map(|s| {
            let mut a = [0.0; 14];
            a[0..3].copy_from_slice(&v3(s.center));
            a[3] = s.radius;
            a[4..11].copy_from_slice(&material_values(&s.material));
            a[11..14].copy_from_slice(&v3(s.velocity));
            a
        })
        .collect();
    w.array(&spheres);
    // The triangles follow the rest (`write_triangles`).
    w.u64(scene.triangles.len() as u64);
    w.array(
        &scene
            .materials
            .iter()
            .map(material_values)
            .collect::<Vec<_>>(),
    );
    let lights: Vec<[f64; 16]> = scene.lights.iter().map(light_values).collect();
    w.array(&lights);
    settings(&scene.settings, w);
    w.u64(scene.warnings.len() as u64);
    for d in &scene.warnings {
        w.text(&d.path);
        w.u64(d.line as u64);
        w.u64(d.col as u64);
        w.text(&d.message);
        opt_text(w, d.hint.as_deref());
        w.text(&d.source_line);
        w.u64(d.caret_col as u64);
        w.u64(d.width as u64);
    }
    w.u64(scene.more_warnings as u64);
    match &scene.camera {
        Some(c) => {
            w.u32(1);
            let (e, l, u) = (v3(c.eye), v3(c.look), v3(c.up));
            w.array(&[e, l, u]);
            w.f64(c.fov);
        }
        None => w.u32(0),
    }
    w.u64(scene.meshes.len() as u64);
    for m in &scene.meshes {
        w.text(&m.file);
        w.u64(m.triangles as u64);
        w.array(&[v3(m.bounds.min), v3(m.bounds.max)]);
        report(&m.report, w)?;
        w.u64(m.files.len() as u64);
        for f in &m.files {
            w.text(f.to_str()?);
        }
    }
    Some(())
}

fn light_values(l: &Light) -> [f64; 16] {
    let mut a = [0.0; 16];
    a[0..3].copy_from_slice(&v3(l.position));
    a[3..6].copy_from_slice(&v3(l.color));
    a[6..9].copy_from_slice(&v3(l.velocity));
    match l.shape {
        LightShape::Point => a[9] = 0.0,
        LightShape::Sphere { radius } => {
            a[9] = 1.0;
            a[10] = radius;
        }
        LightShape::Rect { edge_u, edge_v } => {
            a[9] = 2.0;
            a[10..13].copy_from_slice(&v3(edge_u));
            a[13..16].copy_from_slice(&v3(edge_v));
        }
    }
    a
}

fn light_from(a: &[f64; 16]) -> Result<Light> {
    let shape = match a[9] {
        0.0 => LightShape::Point,
        1.0 => LightShape::Sphere { radius: a[10] },
        2.0 => LightShape::Rect {
            edge_u: d3(&a[10..13]),
            edge_v: d3(&a[13..16]),
        },
        _ => return Err("a light of no shape".into()),
    };
    Ok(Light {
        position: d3(&a[0..3]),
        color: d3(&a[3..6]),
        velocity: d3(&a[6..9]),
        shape,
    })
}

fn opt_text(w: &mut Writer, s: Option<&str>) {
    match s {
        Some(s) => {
            w.u32(1);
            w.text(s);
        }
        None => w.u32(0),
    }
}

fn read_opt_text(r: &mut Reader) -> Result<Option<String>> {
    Ok(match r.u32()? {
        0 => None,
        _ => Some(r.text()?),
    })
}

fn settings(s: &Settings, w: &mut Writer) {
    let u = |w: &mut Writer, v: Option<u32>| {
        w.u32(u32::from(v.is_some()));
        w.u32(v.unwrap_or(0));
    };
    let f = |w: &mut Writer, v: Option<f64>| {
        w.u32(u32::from(v.is_some()));
        w.f64(v.unwrap_or(0.0));
    };
    u(w, s.reflect);
    u(w, s.spp);
    u(w, s.shadow_samples);
    f(w, s.shutter);
    u(w, s.seed);
    f(w, s.fps);
    let sampler = s
        .sampler
        .and_then(|x| Sampler::ALL.iter().position(|&y| y == x));
    u(w, sampler.map(|i| i as u32));
}

fn read_settings(r: &mut Reader) -> Result<Settings> {
    let u = |r: &mut Reader| -> Result<Option<u32>> {
        let (some, v) = (r.u32()?, r.u32()?);
        Ok((some != 0).then_some(v))
    };
    let f = |r: &mut Reader| -> Result<Option<f64>> {
        let (some, v) = (r.u32()?, r.f64()?);
        Ok((some != 0).then_some(v))
    };
    Ok(Settings {
        reflect: u(r)?,
        spp: u(r)?,
        shadow_samples: u(r)?,
        shutter: f(r)?,
        seed: u(r)?,
        fps: f(r)?,
        sampler: match u(r)? {
            None => None,
            Some(i) => Some(
                *Sampler::ALL
                    .get(i as usize)
                    .ok_or("a sampler glint does not have")?,
            ),
        },
    })
}

fn report(report: &Report, w: &mut Writer) -> Option<()> {
    let kind = |k: Tolerance| {
        Tolerance::ALL
            .iter()
            .position(|&t| t == k)
            .map(|i| i as u32)
    };
    w.u64(report.kept.len() as u64);
    for k in &report.kept {
        w.u32(kind(k.kind)?);
        w.text(k.path.to_str()?);
        opt_text(w, k.at.as_deref());
        w.text(&k.message);
    }
    w.u64(report.counts.len() as u64);
    for (&k, &n) in &report.counts {
        w.u32(kind(k)?);
        w.u64(n as u64);
    }
    Some(())
}

fn read_report(r: &mut Reader) -> Result<Report> {
    let kind = |r: &mut Reader| -> Result<Tolerance> {
        Tolerance::ALL
            .get(r.u32()? as usize)
            .copied()
            .ok_or_else(|| "a warning of no kind".to_string())
    };
    let mut out = Report::default();
    for _ in 0..r.count(8)? {
        out.kept.push(Warning {
            kind: kind(r)?,
            path: r.text()?.into(),
            at: read_opt_text(r)?,
            message: r.text()?,
        });
    }
    for _ in 0..r.count(12)? {
        let k = kind(r)?;
        out.counts.insert(k, r.u64()? as usize);
    }
    Ok(out)
}

/// The scene `encode` wrote, its triangles still to be read (how many
/// there are: the second value).
pub(super) fn decode(r: &mut Reader) -> Result<(Scene, u64)> {
    let ambient: Vec<[f64; 3]> = r.array()?;
    let ambient = match ambient.as_slice() {
        [a] => d3(a),
        _ => return Err("no ambient colour".into()),
    };
    let spheres = r
        .array::<[f64; 14]>()?
        .iter()
        .map(|a| Sphere {
            center: d3(&a[0..3]),
            radius: a[3],
            material: material_from(&a[4..11]),
            velocity: d3(&a[11..14]),
        })
        .collect();
    // The triangles follow the rest (`read_triangles`).
    let count = r.u64()?;
    let materials: Vec<Material> = r
        .array::<[f64; 7]>()?
        .iter()
        .map(|a| material_from(a))
        .collect();
    let lights = r
        .array::<[f64; 16]>()?
        .iter()
        .map(light_from)
        .collect::<Result<Vec<_>>>()?;
    let settings = read_settings(r)?;
    let mut warnings = Vec::new();
    for _ in 0..r.count(8)? {
        warnings.push(Diagnostic {
            path: r.text()?,
            line: r.u64()? as usize,
            col: r.u64()? as usize,
            message: r.text()?,
            hint: read_opt_text(r)?,
            source_line: r.text()?,
            caret_col: r.u64()? as usize,
            width: r.u64()? as usize,
        });
    }
    let more_warnings = r.u64()? as usize;
    let camera = match r.u32()? {
        0 => None,
        _ => {
            let axes: Vec<[f64; 3]> = r.array()?;
            let [e, l, u] = axes.as_slice() else {
                return Err("a camera without its three points".into());
            };
            Some(CameraSpec {
                eye: d3(e),
                look: d3(l),
                up: d3(u),
                fov: r.f64()?,
            })
        }
    };
    let mut meshes = Vec::new();
    for _ in 0..r.count(8)? {
        let file = r.text()?;
        let triangles = r.u64()? as usize;
        let bounds: Vec<[f64; 3]> = r.array()?;
        let [min, max] = bounds.as_slice() else {
            return Err("a mesh without its bounds".into());
        };
        let report = read_report(r)?;
        let files = (0..r.count(8)?)
            .map(|_| r.text().map(Into::into))
            .collect::<Result<Vec<_>>>()?;
        meshes.push(MeshInfo {
            file,
            triangles,
            bounds: Bounds {
                min: d3(min),
                max: d3(max),
            },
            // Nothing was read or parsed: the cache's phase is the time.
            load_time: Default::default(),
            read_time: Default::default(),
            normals_time: Default::default(),
            report,
            files,
        });
    }
    let scene = Scene {
        ambient,
        spheres,
        triangles: Vec::new(),
        materials,
        lights,
        settings,
        warnings,
        more_warnings,
        camera,
        meshes,
    };
    Ok((scene, count))
}

/// Triangles a chunk of the stream holds: a few megabytes, converted on
/// every thread while the next is read.
const CHUNK: usize = 1 << 15;
const SIZE: usize = std::mem::size_of::<StoredTriangle>();
/// See `SIZE`.
pub(super) const STORED_SIZE: usize = SIZE;

/// Writes `triangles` as records, a chunk at a time.
pub(super) fn write_triangles(
    triangles: &[Triangle],
    out: &mut dyn std::io::Write,
) -> std::io::Result<()> {
    let mut buf = Vec::new();
    for chunk in triangles.chunks(CHUNK) {
        buf.resize(chunk.len() * SIZE, 0);
        buf.par_chunks_mut(SIZE).zip(chunk).for_each(|(b, t)| {
            let stored = StoredTriangle {
                corners: t.vertices.map(|v| {
                    let (p, n) = (v.position, v.normal);
                    [p.x, p.y, p.z, n.x, n.y, n.z]
                }),
                materials: t.vertices.map(|v| v.material),
                pad: 0,
                velocity: v3(t.velocity),
            };
            b.copy_from_slice(bytemuck::bytes_of(&stored));
        });
        out.write_all(&buf)?;
    }
    Ok(())
}

/// Reads the `count` triangles `write_triangles` wrote, each corner's
/// material below `materials`; a chunk is converted while the next is
/// read.
pub(super) fn read_triangles(
    input: &mut (dyn std::io::Read + Send),
    count: u64,
    materials: usize,
) -> Result<Vec<Triangle>> {
    let table = u32::try_from(materials).unwrap_or(u32::MAX);
    let count = usize::try_from(count).map_err(|_| "more triangles than memory")?;
    let mut out: Vec<Triangle> = Vec::with_capacity(count);
    let mut read = |buf: &mut Vec<u8>, left: usize| -> Result<()> {
        buf.resize(left.min(CHUNK) * SIZE, 0);
        input
            .read_exact(buf)
            .map_err(|e| format!("its triangles: {e}"))
    };
    let (mut this, mut next) = (Vec::new(), Vec::new());
    read(&mut this, count)?;
    while !this.is_empty() {
        let left = count - out.len() - this.len() / SIZE;
        let (got, converted) = rayon::join(
            || {
                if left > 0 {
                    read(&mut next, left)
                } else {
                    next.clear();
                    Ok(())
                }
            },
            || convert(&this, table),
        );
        got?;
        out.par_extend(converted?);
        std::mem::swap(&mut this, &mut next);
    }
    Ok(out)
}

/// A chunk's records as triangles, if every material is in the table.
fn convert(bytes: &[u8], table: u32) -> Result<Vec<Triangle>> {
    bytes
        .par_chunks_exact(SIZE)
        .map(|b| {
            let t: StoredTriangle = bytemuck::pod_read_unaligned(b);
            if t.materials.iter().any(|&m| m >= table) {
                return Err("a corner whose material is not in the table".to_string());
            }
            Ok(Triangle {
                vertices: [0, 1, 2].map(|i| Vertex {
                    position: d3(&t.corners[i][0..3]),
                    normal: d3(&t.corners[i][3..6]),
                    material: t.materials[i],
                }),
                velocity: d3(&t.velocity),
            })
        })
        .collect()
}
