//! What a part file says of itself: which render it belongs to (a digest of
//! the scene, the settings and glint's version), which part of how many,
//! its pixels and its renderer. Kept in the file's own metadata (a PNG
//! `tEXt` chunk, an EXR header attribute, both named `glint-part`), so a
//! part needs no side file and survives being copied around a cluster.

use std::io::Write;
use std::path::Path;

use xxhash_rust::xxh3::Xxh3;

use super::cut::Span;
use crate::images::framebuffer::{Framebuffer, ImageFile};
use crate::scene::Scene;
use crate::Error;

/// The metadata key (PNG keyword, EXR attribute name).
pub const KEY: &str = "glint-part";

/// A part's record of itself.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Stamp {
    /// `render_digest` of the render the part belongs to.
    pub render: String,
    /// This part, counted from 0.
    pub index: u32,
    /// How many parts the render is split into.
    pub count: u32,
    /// The pixels it holds.
    pub span: Span,
    /// The image's height.
    pub height: u32,
    /// What rendered it (`Renderer::name`).
    pub renderer: String,
}

impl Stamp {
    /// The stamp as the text a part file carries.
    pub fn to_text(&self) -> String {
        format!(
            "render {}\npart {} of {}\npixels {}-{} of {}x{}\nrenderer {}\n",
            self.render,
            self.index,
            self.count,
            self.span.start,
            self.span.end,
            self.span.width,
            self.height,
            // One line: the renderer's name never holds a newline, but a
            // stamp must parse whatever it holds.
            self.renderer.replace(['\n', '\r'], " ")
        )
    }

    /// A stamp read back from `to_text`'s text; `None` where it is not one.
    pub fn parse(text: &str) -> Option<Stamp> {
        let mut render = None;
        let (mut part, mut pixels, mut renderer) = (None, None, None);
        for line in text.lines() {
            let (key, value) = line.split_once(' ')?;
            match key {
                "render" => render = Some(value.to_string()),
                "part" => {
                    let (i, n) = value.split_once(" of ")?;
                    part = Some((i.parse().ok()?, n.parse().ok()?));
                }
                "pixels" => {
                    let (range, size) = value.split_once(" of ")?;
                    let (a, b) = range.split_once('-')?;
                    let (w, h) = size.split_once('x')?;
                    pixels = Some((
                        a.parse().ok()?,
                        b.parse().ok()?,
                        w.parse().ok()?,
                        h.parse().ok()?,
                    ));
                }
                "renderer" => renderer = Some(value.to_string()),
                _ => {}
            }
        }
        let (index, count): (u32, u32) = part?;
        let (start, end, width, height): (u64, u64, u32, u32) = pixels?;
        let valid = index < count && start < end && end <= u64::from(width) * u64::from(height);
        valid.then_some(Stamp {
            render: render?,
            index,
            count,
            span: Span { start, end, width },
            height,
            renderer: renderer.unwrap_or_default(),
        })
    }
}

/// A digest of everything that decides a render's pixels: glint's version,
/// `settings` (the caller's account of size, background, methods, effects
/// and precision) and the parsed scene (so models it loads count too).
/// xxh3-128 over exact bit patterns: equal renders agree on every node.
pub fn render_digest(scene: &Scene, settings: &str) -> String {
    let mut h = Xxh3::new();
    let mut text = |s: &str| {
        h.update(&(s.len() as u64).to_le_bytes());
        h.update(s.as_bytes());
    };
    text(concat!("glint ", env!("CARGO_PKG_VERSION")));
    text(settings);
    text(&format!(
        "{:?} {:?} {:?} {:?}",
        scene.settings, scene.camera, scene.lights, scene.ambient
    ));
    let mut bits = |v: &[f64]| {
        for x in v {
            h.update(&x.to_bits().to_le_bytes());
        }
    };
    for s in &scene.spheres {
        let m = s.material.key().map(f64::from_bits);
        bits(&[s.center.x, s.center.y, s.center.z, s.radius]);
        bits(&m);
        bits(&s.velocity.to_array());
    }
    for m in &scene.materials {
        bits(&m.key().map(f64::from_bits));
    }
    for t in &scene.triangles {
        for v in &t.vertices {
            bits(&v.position.to_array());
            bits(&v.normal.to_array());
            bits(&[f64::from(v.material)]);
        }
        bits(&t.velocity.to_array());
    }
    format!("{:032x}", h.digest128())
}

/// Writes the pixels of `fb` inside `span` as a full-size part (alpha
/// opaque inside, 0 outside: what `region::stitch` reads) carrying `stamp`;
/// PNG (8-bit) or EXR (f32) by `path`'s extension; atomically.
pub fn write_part(fb: &Framebuffer, stamp: &Stamp, path: &Path) -> Result<(), Error> {
    let (w, h) = (fb.width, fb.height);
    let span = stamp.span;
    let inside = |i: usize| (span.start..span.end).contains(&(i as u64));
    let io = |e: &dyn std::fmt::Display| std::io::Error::other(e.to_string());
    match ImageFile::of(path)? {
        ImageFile::Png => {
            let bytes: Vec<u8> = fb
                .pixels
                .iter()
                .enumerate()
                .flat_map(|(i, p)| match inside(i) {
                    true => {
                        let [r, g, b] = p.map(crate::images::framebuffer::to_u8);
                        [r, g, b, 255]
                    }
                    false => [0; 4],
                })
                .collect();
            crate::images::framebuffer::write_atomically(path, |sink| {
                let mut e = png::Encoder::new(sink, w, h);
                e.set_color(png::ColorType::Rgba);
                e.set_depth(png::BitDepth::Eight);
                e.add_text_chunk(KEY.into(), stamp.to_text())
                    .map_err(|e| io(&e))?;
                let mut writer = e.write_header().map_err(|e| io(&e))?;
                writer.write_image_data(&bytes).map_err(|e| io(&e))?;
                writer.finish().map_err(|e| io(&e))
            })
        }
        ImageFile::Exr => {
            use exr::prelude::*;
            let pixel = |p: Vec2<usize>| {
                let i = p.y() * w as usize + p.x();
                match inside(i) {
                    true => {
                        let [r, g, b] = fb.pixels[i];
                        (r, g, b, 1.0f32)
                    }
                    false => (0.0, 0.0, 0.0, 0.0),
                }
            };
            let mut attributes = LayerAttributes::default();
            attributes.other.insert(
                Text::from(KEY),
                exr::meta::attribute::AttributeValue::Text(Text::from(stamp.to_text().as_str())),
            );
            let layer = Layer::new(
                (w as usize, h as usize),
                attributes,
                Encoding::FAST_LOSSLESS,
                SpecificChannels::rgba(pixel),
            );
            // exr seeks as it writes: encode in memory, then write the file.
            let mut buf = std::io::Cursor::new(Vec::new());
            Image::from_layer(layer)
                .write()
                .to_buffered(&mut buf)
                .map_err(|e| crate::Error::WriteImage {
                    path: path.to_path_buf(),
                    error: io(&e),
                })?;
            crate::images::framebuffer::write_atomically(path, |sink| sink.write_all(buf.get_ref()))
        }
        _ => Err(Error::BadOutput {
            path: path.to_path_buf(),
            reason: "a part is a .png or .exr, whose alpha marks the pixels it holds".into(),
        }),
    }
}

/// The stamp a part file carries; None for a file without one (a part made
/// by `--crop`, or any other image). Reads the header only.
pub fn read_stamp(path: &Path) -> Result<Option<Stamp>, Error> {
    let bytes = crate::input::read_path(path, crate::input::Kind::Binary).map_err(|e| {
        Error::ReadImage {
            path: path.to_path_buf(),
            message: e.to_string(),
        }
    })?;
    stamp_of(&bytes, path)
}

/// `read_stamp` of bytes already read.
pub fn stamp_of(bytes: &[u8], path: &Path) -> Result<Option<Stamp>, Error> {
    let bad = |message: String| Error::ReadImage {
        path: path.to_path_buf(),
        message,
    };
    let text = match ImageFile::of(path)? {
        ImageFile::Png => {
            let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
            let reader = decoder.read_info().map_err(|e| bad(e.to_string()))?;
            reader
                .info()
                .uncompressed_latin1_text
                .iter()
                .find(|t| t.keyword == KEY)
                .map(|t| t.text.clone())
        }
        ImageFile::Exr => {
            let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
                .map_err(|e| bad(e.to_string()))?;
            meta.headers.first().and_then(|h| {
                match h
                    .own_attributes
                    .other
                    .get(&exr::meta::attribute::Text::from(KEY))
                {
                    Some(exr::meta::attribute::AttributeValue::Text(t)) => Some(t.to_string()),
                    _ => None,
                }
            })
        }
        _ => None,
    };
    match text {
        None => Ok(None),
        Some(t) => Stamp::parse(&t)
            .map(Some)
            .ok_or_else(|| bad(format!("its `{KEY}` record is not one glint writes: {t:?}"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stamp(render: &str, index: u32) -> Stamp {
        Stamp {
            render: render.into(),
            index,
            count: 2,
            span: Span {
                start: 20 * index as u64,
                end: 20 * (index as u64 + 1),
                width: 8,
            },
            height: 5,
            renderer: "CPU reference (f32, 2 threads)".into(),
        }
    }

    /// The stamp survives PNG and EXR, a file without one reads as None,
    /// and parts of two renders are refused by index.
    #[test]
    fn stamps_round_trip_and_other_renders_are_refused() {
        let dir = tempfile::tempdir().expect("temp dir");
        let fb = Framebuffer {
            width: 8,
            height: 5,
            pixels: (0..40).map(|i| [i as f32 / 40.0, 0.5, 1.0]).collect(),
        };
        for ext in ["png", "exr"] {
            let paths: Vec<_> = (0..2)
                .map(|i| dir.path().join(format!("p{i}.{ext}")))
                .collect();
            for (i, p) in paths.iter().enumerate() {
                write_part(&fb, &stamp("aa", i as u32), p).expect("write");
                assert_eq!(read_stamp(p).expect("read"), Some(stamp("aa", i as u32)));
            }
            let refs: Vec<&Path> = paths.iter().map(|p| p.as_path()).collect();
            let joined = crate::parts::crop::stitch(&refs).expect("stitch");
            assert_eq!(joined.image.to_rgb8(), fb.to_rgb8());
            assert!(crate::parts::vet(&paths, Some(2)).is_ok());
            write_part(&fb, &stamp("bb", 1), &paths[1]).expect("write");
            let e = crate::parts::vet(&paths, Some(2))
                .expect_err("mixed")
                .to_string();
            assert!(e.contains("part 1 of render bb"), "{e}");
            assert!(crate::parts::vet(&paths[..1], Some(2)).is_ok());
            let swapped = [paths[1].clone(), paths[0].clone()];
            assert!(crate::parts::vet(&swapped, Some(2)).is_err());
        }
        let plain = dir.path().join("plain.png");
        crate::images::framebuffer::write_framebuffer(&fb, &plain, 90).expect("write");
        assert_eq!(read_stamp(&plain).expect("read"), None);
        assert_eq!(
            Stamp::parse("render x\npart 3 of 2\npixels 0-1 of 1x1\n"),
            None
        );
    }

    /// The digest follows the scene's numbers and the settings, not where
    /// the file came from.
    #[test]
    fn digests_follow_scene_and_settings() {
        let a = crate::scene::parse_scene(
            b"1\namb: 0 0 0\nsphere\npos: 0 0 -2 rad: 1\ndif: 1 0 0 spe: 0 0 0 shi: 1\n",
            "a",
        )
        .expect("scene");
        let mut b = a.clone();
        b.spheres[0].radius = 1.0 + 1e-12;
        let d = render_digest(&a, "640x480");
        assert_eq!(d, render_digest(&a.clone(), "640x480"));
        assert_ne!(d, render_digest(&b, "640x480"));
        assert_ne!(d, render_digest(&a, "640x481"));
        assert_eq!(d.len(), 32);
    }
}
