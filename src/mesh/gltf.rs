//! glTF 2.0, `.gltf` (JSON, buffers external or in data URIs) and `.glb`
//! (binary container), through the `gltf` crate's JSON model and
//! validation. Triangle primitives (lists, strips and fans, indexed or
//! not) of the default scene's nodes, placed by the node hierarchy's
//! transforms; without a scene, every mesh as it is.
//!
//! Materials map from metallic-roughness to the classic model:
//! kd = base × (1 − metallic), ks = 0.04 + (base − 0.04) × metallic (the
//! reflectance at normal incidence), shininess = (2/α² − 2)/4 with
//! α = roughness² (the Blinn-Phong exponent of that roughness, over four
//! for Phong's R·V), from 1 to 10,000. `baseColorFactor` times `COLOR_0`
//! is the diffuse colour where a primitive has vertex colours. Without
//! normals a primitive gets flat normals, as the specification asks.
//!
//! Accessors are read here, not by the crate's reader: its reader panics
//! on component types and ranges that validation lets through, and every
//! range is checked against its buffer first, naming the JSON path.

use std::path::Path;

use glam::{DMat3, DMat4, DVec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;
use gltf::Semantic;

use super::build::{Builder, Loc};
use super::report::Tolerance;
use super::{Mesh, MeshError, Refs};
use crate::material::Material;

fn error(path: &Path, at: impl Into<String>, message: impl Into<String>) -> MeshError {
    MeshError {
        path: path.to_path_buf(),
        at: Some(at.into()),
        message: message.into(),
    }
}

pub fn parse(src: &[u8], path: &Path, refs: Refs) -> Result<Mesh, MeshError> {
    let (json, bin) = if src.starts_with(b"glTF") {
        split_glb(src, path)?
    } else {
        (src, None)
    };
    let json = json.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(json);
    let mut b = Builder::new(path);
    let root = root(json, &mut b)?;
    let textured = root
        .materials
        .iter()
        .any(|m| m.pbr_metallic_roughness.base_color_texture.is_some());
    let doc = gltf::Document::from_json_without_validation(root);
    let buffers = load_buffers(&doc, bin, path, refs)?;
    for m in doc.materials() {
        b.mesh.materials.push(material(&m));
    }
    if textured {
        b.warn(
            Tolerance::TextureIgnored,
            Some("materials".into()),
            "base colour textures are not rendered: glint shades with baseColorFactor",
        );
    }
    let scene = doc.default_scene().or_else(|| doc.scenes().next());
    let mut r = Reader {
        b,
        buffers: &buffers,
        visited: vec![false; doc.nodes().count()],
    };
    match scene {
        Some(scene) => {
            for node in scene.nodes() {
                r.node(&node, DMat4::IDENTITY)?;
            }
        }
        None => {
            for mesh in doc.meshes() {
                r.mesh(&mesh, DMat4::IDENTITY)?;
            }
        }
    }
    r.b.finish()
}

/// The glTF JSON as the crate's model, validated. What mainstream
/// importers tolerate is repaired first, with a warning: a scene without
/// `nodes`, a default `scene` that does not exist, required extensions
/// that only change materials. Validation errors in what glint does not
/// read (accessor bounds, textures, images, samplers) are let through;
/// every other is refused with its JSON path, since the crate's accessors
/// panic on what validation would have caught.
fn root(json: &[u8], b: &mut Builder) -> Result<gltf::json::Root, MeshError> {
    use gltf::json::validation::Validate as _;
    let path = b.path;
    let syntax = |e: serde_json::Error| MeshError {
        path: path.to_path_buf(),
        at: Some(format!("JSON line {} column {}", e.line(), e.column())),
        message: format!("not valid glTF JSON: {e}"),
    };
    let mut value: serde_json::Value = serde_json::from_slice(json).map_err(syntax)?;
    let Some(obj) = value.as_object_mut() else {
        return Err(error(path, "JSON line 1", "a glTF file is a JSON object"));
    };
    let scene_count = obj
        .get("scenes")
        .and_then(|s| s.as_array())
        .map_or(0, Vec::len);
    if let Some(scenes) = obj.get_mut("scenes").and_then(|s| s.as_array_mut()) {
        for (i, scene) in scenes.iter_mut().enumerate() {
            if let Some(scene) = scene.as_object_mut() {
                if !scene.contains_key("nodes") {
                    scene.insert("nodes".into(), serde_json::Value::Array(Vec::new()));
                    b.warn(
                        Tolerance::Structure,
                        Some(format!("scenes[{i}]")),
                        "a scene without `nodes` is read as empty",
                    );
                }
            }
        }
    }
    if let Some(index) = obj.get("scene").and_then(serde_json::Value::as_u64) {
        if index as usize >= scene_count {
            obj.remove("scene");
            b.warn(
                Tolerance::Structure,
                Some("scene".into()),
                format!("the default scene {index} does not exist; the first scene is read"),
            );
        }
    }
    let mut root: gltf::json::Root =
        serde_path_to_error::deserialize(value).map_err(|e| MeshError {
            path: path.to_path_buf(),
            at: Some(e.path().to_string()),
            message: format!("not valid glTF: {}", e.inner()),
        })?;
    for (i, ext) in root.extensions_required.iter().enumerate() {
        let at = format!("extensionsRequired[{i}]");
        match ext.as_str() {
            "KHR_draco_mesh_compression" | "EXT_meshopt_compression" => {
                return Err(error(
                    path,
                    at,
                    format!(
                        "the file's meshes are compressed ({ext}), which glint does not \
                         decode; export without mesh compression (or decompress it with \
                         gltf-transform)"
                    ),
                ))
            }
            "KHR_mesh_quantization" => {
                return Err(error(
                    path,
                    at,
                    "quantized vertex data (KHR_mesh_quantization) is not read; export with \
                     float positions",
                ))
            }
            _ => b.warn(
                Tolerance::Extension,
                Some(at),
                format!("the required extension {ext} is not implemented; the geometry is read without it"),
            ),
        }
    }
    root.extensions_required.clear();
    // The crate's validation indexes the accessor a POSITION names before
    // checking that it exists (gltf-json 1.4: a panic, found by fuzzing).
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let position =
                gltf::json::validation::Checked::Valid(gltf::json::mesh::Semantic::Positions);
            if let Some(i) = prim.attributes.get(&position) {
                if i.value() >= root.accessors.len() {
                    return Err(error(
                        path,
                        format!("meshes[{m}].primitives[{p}].attributes.POSITION"),
                        format!(
                            "refers to accessor {}, but there are {}",
                            i.value(),
                            root.accessors.len()
                        ),
                    ));
                }
            }
        }
    }
    let mut errors = Vec::new();
    root.validate(&root, gltf::json::Path::new, &mut |at, e| {
        let at = at().to_string();
        let unread = at.starts_with("textures")
            || at.starts_with("images")
            || at.starts_with("samplers")
            || at.contains("Texture")
            || ((at.ends_with(".min") || at.ends_with(".max"))
                && e == gltf::json::validation::Error::Missing);
        if !unread {
            errors.push((at, e));
        }
    });
    if let Some((at, e)) = errors.first() {
        let more = match errors.len() {
            1 => String::new(),
            n => format!(" (and {} more problems)", n - 1),
        };
        return Err(error(path, at.clone(), format!("invalid glTF: {e}{more}")));
    }
    Ok(root)
}

/// GLB: the 12-byte header, a JSON chunk, an optional BIN chunk. Checked
/// here, before the crate sees it: its own reader underflows on a short
/// length.
fn split_glb<'a>(src: &'a [u8], path: &Path) -> Result<(&'a [u8], Option<&'a [u8]>), MeshError> {
    let word = |i: usize| -> Option<u32> {
        src.get(i..i + 4)
            .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
    };
    let length = word(8).ok_or_else(|| error(path, "byte 0", "too short for a GLB header"))?;
    let end = (length as usize).min(src.len());
    let mut chunks = Vec::new();
    let mut at = 12usize;
    while at + 8 <= end && chunks.len() < 2 {
        let (len, ty) = (word(at).unwrap_or(0) as usize, word(at + 4).unwrap_or(0));
        let data = src
            .get(at + 8..at + 8 + len)
            .filter(|_| at + 8 + len <= end);
        let Some(data) = data else {
            return Err(error(
                path,
                format!("byte {at}"),
                format!("a GLB chunk of {len} bytes runs past the file's end"),
            ));
        };
        chunks.push((ty, data));
        at += 8 + len.next_multiple_of(4);
    }
    const JSON: u32 = 0x4E4F_534A;
    const BIN: u32 = 0x004E_4942;
    match chunks.as_slice() {
        [(JSON, json)] => Ok((json, None)),
        [(JSON, json), (BIN, bin)] => Ok((json, Some(bin))),
        [(JSON, json), _] => Ok((json, None)),
        _ => Err(error(
            path,
            "byte 12",
            "a GLB file must begin with a JSON chunk",
        )),
    }
}

fn load_buffers(
    doc: &gltf::Document,
    bin: Option<&[u8]>,
    path: &Path,
    refs: Refs,
) -> Result<Vec<Vec<u8>>, MeshError> {
    let mut out = Vec::new();
    for buffer in doc.buffers() {
        let at = format!("buffers[{}]", buffer.index());
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => bin
                .ok_or_else(|| {
                    error(
                        path,
                        &at,
                        "refers to the GLB's binary chunk, which it has not",
                    )
                })?
                .to_vec(),
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                let Some((head, data)) = uri.split_once(',') else {
                    return Err(error(path, &at, "a data URI without a comma"));
                };
                if !head.ends_with(";base64") {
                    return Err(error(path, &at, "a data URI that is not base64"));
                }
                use base64::Engine as _;
                base64::engine::general_purpose::STANDARD
                    .decode(data.trim())
                    .map_err(|e| error(path, &at, format!("its base64 data URI: {e}")))?
            }
            gltf::buffer::Source::Uri(uri) => {
                if refs == Refs::None {
                    return Err(error(
                        path,
                        &at,
                        format!("refers to the file `{uri}`, which is not read here"),
                    ));
                }
                let name = urlencoding::decode(uri).unwrap_or_else(|_| uri.into());
                let file = path.parent().unwrap_or(Path::new(".")).join(&*name);
                super::source::read_referenced(&file, crate::input::Kind::Binary)
                    .map_err(|e| error(path, &at, format!("cannot read {}: {e}", file.display())))?
            }
        };
        if data.len() < buffer.length() {
            return Err(error(
                path,
                &at,
                format!(
                    "byteLength is {} but the data has {} bytes",
                    buffer.length(),
                    data.len()
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// The classic material for a glTF metallic-roughness one (module docs).
fn material(m: &gltf::Material) -> Material {
    let pbr = m.pbr_metallic_roughness();
    let [r, g, b, _] = pbr
        .base_color_factor()
        .map(|c| f64::from(c).clamp(0.0, 1.0));
    let base = DVec3::new(r, g, b);
    let metallic = f64::from(pbr.metallic_factor()).clamp(0.0, 1.0);
    let roughness = f64::from(pbr.roughness_factor()).clamp(0.0, 1.0);
    let alpha = roughness * roughness;
    let shininess = if alpha > 0.0 {
        ((2.0 / (alpha * alpha) - 2.0) / 4.0).clamp(1.0, 10_000.0)
    } else {
        10_000.0
    };
    Material {
        kd: base * (1.0 - metallic),
        ks: DVec3::splat(0.04) + (base - DVec3::splat(0.04)) * metallic,
        shininess,
    }
}

/// A perspective camera placed by its node's transform (glTF cameras
/// look down their local -z with +y up); None for an orthographic one.
/// Whether it can see is the scene's to judge (`CameraSpec::basis`).
fn file_camera(camera: &gltf::Camera, world: DMat4) -> Option<super::FileCamera> {
    let gltf::camera::Projection::Perspective(p) = camera.projection() else {
        return None;
    };
    let eye = world.transform_point3(DVec3::ZERO);
    Some(super::FileCamera {
        eye,
        look: eye + world.transform_vector3(DVec3::NEG_Z),
        up: world.transform_vector3(DVec3::Y),
        fov: f64::from(p.yfov()).to_degrees(),
    })
}

struct Reader<'a, 'p> {
    b: Builder<'p>,
    buffers: &'a [Vec<u8>],
    visited: Vec<bool>,
}

impl Reader<'_, '_> {
    fn node(&mut self, node: &gltf::Node, parent: DMat4) -> Result<(), MeshError> {
        let i = node.index();
        if std::mem::replace(&mut self.visited[i], true) {
            return Err(error(
                self.b.path,
                format!("nodes[{i}]"),
                "this node is reached twice from the scene: the node hierarchy has a cycle, \
                 or a node with two parents",
            ));
        }
        let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
        if !local.is_finite() {
            return Err(error(
                self.b.path,
                format!("nodes[{i}]"),
                "its transform is not finite",
            ));
        }
        let world = parent * local;
        if let (None, Some(camera)) = (self.b.mesh.camera, node.camera()) {
            self.b.mesh.camera = file_camera(&camera, world);
        }
        if let Some(mesh) = node.mesh() {
            self.mesh(&mesh, world)?;
        }
        for child in node.children() {
            self.node(&child, world)?;
        }
        Ok(())
    }

    fn mesh(&mut self, mesh: &gltf::Mesh, world: DMat4) -> Result<(), MeshError> {
        for prim in mesh.primitives() {
            let at = format!("meshes[{}].primitives[{}]", mesh.index(), prim.index());
            self.primitive(&prim, world, at)?;
        }
        Ok(())
    }

    fn primitive(
        &mut self,
        prim: &gltf::Primitive,
        world: DMat4,
        at: String,
    ) -> Result<(), MeshError> {
        if !matches!(
            prim.mode(),
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            self.b.warn(
                Tolerance::NotSurface,
                Some(at),
                format!("a primitive of {:?}, not a surface, skipped", prim.mode()),
            );
            return Ok(());
        }
        let Some(pos) = prim.get(&Semantic::Positions) else {
            self.b.warn(
                Tolerance::NotSurface,
                Some(at),
                "a primitive without POSITION skipped",
            );
            return Ok(());
        };
        let path = self.b.path;
        let positions = floats(
            &pos,
            self.buffers,
            path,
            &format!("{at}.attributes.POSITION"),
            &[3],
        )?;
        let normals = match prim.get(&Semantic::Normals) {
            Some(a) => Some(floats(
                &a,
                self.buffers,
                path,
                &format!("{at}.attributes.NORMAL"),
                &[3],
            )?),
            None => None,
        };
        let colors = match prim.get(&Semantic::Colors(0)) {
            Some(a) => Some(floats(
                &a,
                self.buffers,
                path,
                &format!("{at}.attributes.COLOR_0"),
                &[3, 4],
            )?),
            None => None,
        };
        let n = positions.len() / 3;
        let corners: Vec<u32> = match prim.indices() {
            Some(a) => indices(&a, self.buffers, path, &format!("{at}.indices"))?,
            None => (0..n as u32).collect(),
        };
        if let Some(&bad) = corners.iter().find(|&&c| c as usize >= n) {
            return Err(error(
                path,
                format!("{at}.indices"),
                format!("index {bad} refers past the {n} vertices of POSITION"),
            ));
        }
        if normals.as_ref().is_some_and(|v| v.len() / 3 != n)
            || colors
                .as_ref()
                .is_some_and(|c| c.len() / c_width(c, n) != n)
        {
            return Err(error(
                path,
                format!("{at}.attributes"),
                "its attributes have different counts",
            ));
        }
        let material = prim.material().index().map(|m| m as u32);
        let base = self.b.mesh.positions.len();
        if base + n >= u32::MAX as usize {
            return Err(error(path, at, "more than 4 billion vertices"));
        }
        let identity = world == DMat4::IDENTITY;
        let turn = DMat3::from_mat4(world).inverse().transpose();
        for v in positions.chunks_exact(3) {
            let p = DVec3::new(v[0], v[1], v[2]);
            self.b.mesh.positions.push(if identity {
                p
            } else {
                world.transform_point3(p)
            });
        }
        let normal_base = self.b.mesh.normals.len() as u32;
        if let Some(normals) = &normals {
            for v in normals.chunks_exact(3) {
                let nrm = DVec3::new(v[0], v[1], v[2]);
                self.b
                    .mesh
                    .normals
                    .push(if identity { nrm } else { turn * nrm });
            }
        }
        self.add_colors(colors.as_deref(), n, material);
        let label = self.b.labels.len() as u32;
        self.b.labels.push(at);
        let tris = triangles(prim.mode(), &corners);
        for t in tris {
            let positions = t.map(|c| base as u32 + c);
            let ns = match &normals {
                Some(_) => t.map(|c| Some(normal_base + c)),
                None => {
                    // Flat, as the specification asks of a primitive without normals.
                    let [a, b, c] = positions.map(|p| self.b.mesh.positions[p as usize]);
                    let flat = (b - a).cross(c - a).normalize_or_zero();
                    let k = self.b.mesh.normals.len() as u32;
                    self.b.mesh.normals.push(flat);
                    [Some(k); 3]
                }
            };
            self.b.polygon(
                (0..3).map(|k| (positions[k], ns[k])),
                material,
                Loc::Label(label),
            );
        }
        Ok(())
    }

    /// Vertex colours are per position for the whole mesh: once one
    /// primitive has them, every vertex gets one (its material's diffuse
    /// colour where the primitive has none).
    fn add_colors(&mut self, colors: Option<&[f64]>, n: usize, material: Option<u32>) {
        let mesh = &mut self.b.mesh;
        let before = mesh.positions.len() - n;
        if colors.is_none() && mesh.colors.is_empty() {
            return;
        }
        let kd_of = |mesh: &Mesh, m: Option<u32>| {
            m.and_then(|m| mesh.materials.get(m as usize))
                .map_or(super::DEFAULT_MATERIAL.kd, |m| m.kd)
        };
        if mesh.colors.len() < before {
            // Earlier primitives had none: their materials' colours. Their
            // materials are not known per vertex here, so the default's.
            let kd = super::DEFAULT_MATERIAL.kd;
            mesh.colors.resize(before, kd);
        }
        let kd = kd_of(mesh, material);
        match colors {
            Some(c) => {
                let w = c_width(c, n);
                for v in c.chunks_exact(w) {
                    mesh.colors.push(kd * DVec3::new(v[0], v[1], v[2]));
                }
            }
            None => mesh.colors.resize(before + n, kd),
        }
    }
}

fn c_width(c: &[f64], n: usize) -> usize {
    if n > 0 && c.len() == 4 * n {
        4
    } else {
        3
    }
}

/// A primitive's triangles, as corner numbers into its vertex list.
fn triangles(mode: Mode, c: &[u32]) -> Vec<[u32; 3]> {
    match mode {
        Mode::TriangleStrip => (0..c.len().saturating_sub(2))
            .map(|k| {
                if k % 2 == 0 {
                    [c[k], c[k + 1], c[k + 2]]
                } else {
                    [c[k + 1], c[k], c[k + 2]]
                }
            })
            .collect(),
        Mode::TriangleFan => (1..c.len().saturating_sub(1))
            .map(|k| [c[0], c[k], c[k + 1]])
            .collect(),
        _ => c.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
    }
}

/// The bytes of an accessor's elements, checked against its view and
/// buffer: (data, stride, count).
fn elements<'a>(
    a: &gltf::Accessor,
    buffers: &'a [Vec<u8>],
    path: &Path,
    at: &str,
) -> Result<(&'a [u8], usize, usize), MeshError> {
    let here = format!("{at} (accessors[{}])", a.index());
    if a.sparse().is_some() {
        return Err(error(path, here, "sparse accessors are not read"));
    }
    let Some(view) = a.view() else {
        return Err(error(
            path,
            here,
            "an accessor without a bufferView is not read",
        ));
    };
    let buffer = &buffers[view.buffer().index()];
    let size = a.size();
    let stride = view.stride().unwrap_or(size);
    let count = a.count();
    let range = (|| {
        let view_end = view.offset().checked_add(view.length())?;
        let start = view.offset().checked_add(a.offset())?;
        if count == 0 {
            // Nothing to read, wherever it claims to start (found by
            // fuzzing: an offset past the buffer with no elements).
            return Some(0..0);
        }
        let end = stride
            .checked_mul(count - 1)?
            .checked_add(size)?
            .checked_add(start)?;
        (stride >= size && end <= view_end && view_end <= buffer.len()).then_some(start..end)
    })();
    let Some(range) = range else {
        return Err(error(
            path,
            here,
            format!(
                "{count} elements of {size} bytes every {stride} from byte {} of bufferViews[{}] \
                 run past it or its buffer",
                a.offset(),
                view.index()
            ),
        ));
    };
    Ok((&buffer[range], stride, count))
}

/// Float (or normalized integer) vectors of one of the `widths`, flattened.
fn floats(
    a: &gltf::Accessor,
    buffers: &[Vec<u8>],
    path: &Path,
    at: &str,
    widths: &[usize],
) -> Result<Vec<f64>, MeshError> {
    let width = match a.dimensions() {
        Dimensions::Vec3 => 3,
        Dimensions::Vec4 => 4,
        _ => 0,
    };
    let ty = a.data_type();
    let ok_type =
        ty == DataType::F32 || (a.normalized() && matches!(ty, DataType::U8 | DataType::U16));
    if !widths.contains(&width) || !ok_type {
        return Err(error(
            path,
            format!("{at} (accessors[{}])", a.index()),
            format!(
                "{:?} of {:?}{}: glint reads float vectors of {widths:?} components here",
                a.dimensions(),
                ty,
                if a.normalized() { ", normalized" } else { "" }
            ),
        ));
    }
    let (data, stride, count) = elements(a, buffers, path, at)?;
    let mut out = Vec::with_capacity(count * width);
    for e in 0..count {
        let el = &data[e * stride..];
        for k in 0..width {
            let v = match ty {
                DataType::U8 => f64::from(el[k]) / 255.0,
                DataType::U16 => {
                    f64::from(u16::from_le_bytes([el[2 * k], el[2 * k + 1]])) / 65535.0
                }
                _ => f64::from(f32::from_le_bytes([
                    el[4 * k],
                    el[4 * k + 1],
                    el[4 * k + 2],
                    el[4 * k + 3],
                ])),
            };
            out.push(v);
        }
    }
    Ok(out)
}

fn indices(
    a: &gltf::Accessor,
    buffers: &[Vec<u8>],
    path: &Path,
    at: &str,
) -> Result<Vec<u32>, MeshError> {
    let ty = a.data_type();
    if a.dimensions() != Dimensions::Scalar
        || !matches!(ty, DataType::U8 | DataType::U16 | DataType::U32)
    {
        return Err(error(
            path,
            format!("{at} (accessors[{}])", a.index()),
            format!(
                "indices of {:?} {:?}: expected unsigned integer scalars",
                a.dimensions(),
                ty
            ),
        ));
    }
    let (data, stride, count) = elements(a, buffers, path, at)?;
    Ok((0..count)
        .map(|e| {
            let el = &data[e * stride..];
            match ty {
                DataType::U8 => u32::from(el[0]),
                DataType::U16 => u32::from(u16::from_le_bytes([el[0], el[1]])),
                _ => u32::from_le_bytes([el[0], el[1], el[2], el[3]]),
            }
        })
        .collect())
}
