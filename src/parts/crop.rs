//! Part of an image: `--crop` renders a rectangle of the full image, and
//! `stitch` joins such parts (rendered anywhere, in any order) into the
//! image one render would have made, bit for bit.
//!
//! A part is a full-size PNG or EXR whose alpha says which pixels it holds
//! (255 or 1.0 inside the rectangle, 0 outside), so it describes itself: no
//! side file, no naming scheme, and any viewer shows it in place.

use std::fmt;
use std::path::Path;

use crate::images::framebuffer::{Framebuffer, ImageFile};
use crate::Error;

/// A rectangle of pixels, `x0 <= x < x1`, `y0 <= y < y1` (pbrt's
/// `--pixelbounds`), row 0 at the top.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crop {
    /// The first column inside.
    pub x0: u32,
    /// The first row inside.
    pub y0: u32,
    /// The first column past it.
    pub x1: u32,
    /// The first row past it.
    pub y1: u32,
}

impl Crop {
    /// Parses `X0,Y0,X1,Y1`.
    pub fn parse(s: &str) -> Result<Crop, String> {
        let v: Vec<Option<u32>> = s.split(',').map(|p| p.trim().parse().ok()).collect();
        match v.as_slice() {
            [Some(x0), Some(y0), Some(x1), Some(y1)] if x0 < x1 && y0 < y1 => Ok(Crop {
                x0: *x0,
                y0: *y0,
                x1: *x1,
                y1: *y1,
            }),
            _ => Err(format!(
                "expected X0,Y0,X1,Y1 as whole numbers with X0 < X1 and Y0 < Y1 (the pixels \
                 X0..X1-1 by Y0..Y1-1, e.g. 0,0,640,240 for the top half), found `{s}`"
            )),
        }
    }

    /// Checks that the rectangle lies inside a `width` x `height` image.
    pub fn check(&self, width: u32, height: u32) -> Result<(), Error> {
        if self.x1 > width || self.y1 > height {
            return Err(Error::InvalidOption(format!(
                "--crop {self} reaches outside the {width}x{height} image (X1 and Y1 are \
                 exclusive: at most {width} and {height})"
            )));
        }
        Ok(())
    }

    /// Whether pixel (x, y) is inside.
    pub fn contains(&self, x: u32, y: u32) -> bool {
        (self.x0..self.x1).contains(&x) && (self.y0..self.y1).contains(&y)
    }

    /// As (x, y, width, height).
    pub fn rect(&self) -> [u32; 4] {
        [self.x0, self.y0, self.x1 - self.x0, self.y1 - self.y0]
    }

    /// How many pixels it holds.
    pub fn pixels(&self) -> u64 {
        u64::from(self.x1 - self.x0) * u64::from(self.y1 - self.y0)
    }
}

impl fmt::Display for Crop {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{},{},{},{}", self.x0, self.y0, self.x1, self.y1)
    }
}

/// Whether `path` can hold a part (its alpha marks the pixels it holds).
pub fn check_part_format(path: &Path) -> Result<(), Error> {
    match ImageFile::of(path)? {
        ImageFile::Png | ImageFile::Exr => Ok(()),
        _ => Err(Error::BadOutput {
            path: path.to_path_buf(),
            reason: "with --crop, the output is a part for `glint stitch`: write .png or .exr, \
                     whose alpha marks the pixels the part holds"
                .into(),
        }),
    }
}

/// Writes the pixels of `fb` inside `crop` as a full-size part: PNG RGBA8
/// or EXR RGBA f32, alpha opaque inside the rectangle and 0 outside.
pub fn write_part(fb: &Framebuffer, crop: &Crop, path: &Path) -> Result<(), Error> {
    check_part_format(path)?;
    let img = part_image(fb, crop, ImageFile::of(path)?.is_float());
    crate::images::framebuffer::write_dynamic(&img, path, 95)
}

/// As `write_part`, a PNG on standard output.
pub fn write_part_to_stdout(fb: &Framebuffer, crop: &Crop) -> Result<(), Error> {
    crate::images::framebuffer::write_dynamic_to_stdout(
        &part_image(fb, crop, false),
        ImageFile::Png,
        95,
    )
}

fn part_image(fb: &Framebuffer, crop: &Crop, float: bool) -> image::DynamicImage {
    let inside = |i: usize| crop.contains(i as u32 % fb.width, i as u32 / fb.width);
    if float {
        let flat: Vec<f32> = fb
            .pixels
            .iter()
            .enumerate()
            .flat_map(|(i, p)| {
                let a = if inside(i) { 1.0 } else { 0.0 };
                [p[0] * a, p[1] * a, p[2] * a, a]
            })
            .collect();
        return image::Rgba32FImage::from_raw(fb.width, fb.height, flat)
            .expect("pixel count matches width * height")
            .into();
    }
    let bytes: Vec<u8> = fb
        .pixels
        .iter()
        .enumerate()
        .flat_map(|(i, p)| {
            if inside(i) {
                let [r, g, b] = p.map(crate::images::framebuffer::to_u8);
                [r, g, b, 255]
            } else {
                [0; 4]
            }
        })
        .collect();
    image::RgbaImage::from_raw(fb.width, fb.height, bytes)
        .expect("pixel count matches width * height")
        .into()
}

/// What `stitch` made of its parts.
#[derive(Debug)]
pub struct Stitched {
    /// The joined image.
    pub image: Framebuffer,
    /// Whether every part was float (EXR): then `image` holds their float
    /// values, else 8-bit values v / 255.
    pub float: bool,
    /// Pixels held by more than one part, and how many of those disagree
    /// (the later part wins).
    pub overlapping: u64,
    /// Of the overlapping pixels, how many the parts disagree on.
    pub disagreeing: u64,
}

/// Joins parts written by `--crop` (`write_part`), in order; a pixel held
/// by several takes the last one's value. Every pixel must be held by some
/// part, else the error names how many are missing and where.
pub fn stitch(parts: &[&Path]) -> Result<Stitched, Error> {
    let mut size: Option<(u32, u32, &Path)> = None;
    let mut image: Vec<[f32; 3]> = Vec::new();
    let mut held: Vec<bool> = Vec::new();
    let mut float = true;
    let (mut overlapping, mut disagreeing) = (0u64, 0u64);
    for &path in parts {
        let kind = ImageFile::of(path)?;
        let img = crate::images::framebuffer::open(path)?;
        if !img.color().has_alpha() {
            return Err(Error::ReadImage {
                path: path.to_path_buf(),
                message: "it has no alpha channel, so it does not say which pixels it holds; \
                          parts are written by `glint render --crop X0,Y0,X1,Y1` as .png or .exr"
                    .into(),
            });
        }
        float &= kind.is_float();
        let (w, h) = (img.width(), img.height());
        match size {
            None => {
                size = Some((w, h, path));
                image = vec![[0.0; 3]; w as usize * h as usize];
                held = vec![false; image.len()];
            }
            Some((w0, h0, first)) if (w0, h0) != (w, h) => {
                return Err(Error::ReadImage {
                    path: path.to_path_buf(),
                    message: format!(
                        "it is {w}x{h}, but {} is {w0}x{h0}; parts of one image have its full size",
                        first.display()
                    ),
                });
            }
            Some(_) => {}
        }
        // 8-bit parts keep their levels exactly: v / 255 in f32 converts
        // back to the same level (`to_u8`).
        let rgba = img.to_rgba32f();
        for (i, p) in rgba.pixels().enumerate() {
            let [r, g, b, a] = p.0;
            if a <= 0.0 {
                continue;
            }
            if a < 1.0 {
                return Err(Error::ReadImage {
                    path: path.to_path_buf(),
                    message: format!(
                        "pixel {},{} is partly transparent (alpha {a}); a part's pixels are \
                         either held (opaque) or not (transparent)",
                        i as u32 % w,
                        i as u32 / w
                    ),
                });
            }
            if held[i] {
                overlapping += 1;
                if image[i] != [r, g, b] {
                    disagreeing += 1;
                }
            }
            image[i] = [r, g, b];
            held[i] = true;
        }
    }
    let Some((width, height, _)) = size else {
        return Err(Error::InvalidOption(
            "stitch needs at least one part".into(),
        ));
    };
    let missing: Vec<usize> = (0..held.len()).filter(|&i| !held[i]).collect();
    if let (Some(&first), Some(&last)) = (missing.first(), missing.last()) {
        let (mut x0, mut x1) = (u32::MAX, 0);
        for &i in &missing {
            x0 = x0.min(i as u32 % width);
            x1 = x1.max(i as u32 % width);
        }
        return Err(Error::InvalidOption(format!(
            "the parts leave {} of the {width}x{height} pixels uncovered, within {},{},{},{} \
             (as --crop would say it); render that region with --crop and stitch again",
            missing.len(),
            x0,
            first as u32 / width,
            x1 + 1,
            last as u32 / width + 1
        )));
    }
    Ok(Stitched {
        image: Framebuffer {
            width,
            height,
            pixels: image,
        },
        float,
        overlapping,
        disagreeing,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_and_check() {
        let c = Crop::parse("1, 2,30,40").expect("valid");
        assert_eq!(c.rect(), [1, 2, 29, 38]);
        assert!(c.contains(1, 2) && c.contains(29, 39) && !c.contains(30, 2));
        for bad in ["1,2,3", "5,0,5,4", "0,4,4,4", "a,b,c,d", "-1,0,4,4"] {
            assert!(Crop::parse(bad).is_err(), "{bad}");
        }
        assert!(c.check(30, 40).is_ok());
        assert!(c.check(29, 40).is_err());
    }

    fn image(width: u32, height: u32) -> Framebuffer {
        Framebuffer {
            width,
            height,
            pixels: (0..width * height)
                .map(|i| {
                    let v = i as f32 / (width * height) as f32;
                    [v, 1.0 - v, (v * 7.3).fract()]
                })
                .collect(),
        }
    }

    /// Parts in either format join to exactly the full image: floats bit
    /// for bit from EXR, 8-bit levels from PNG; a gap is an error that
    /// names the missing rectangle.
    #[test]
    fn parts_join_bit_exactly_and_gaps_are_named() {
        let dir = tempfile::tempdir().expect("temp dir");
        let fb = image(13, 9);
        let crops = [
            Crop::parse("0,0,13,4").expect("valid"),
            Crop::parse("0,4,6,9").expect("valid"),
            Crop::parse("6,4,13,9").expect("valid"),
        ];
        for ext in ["exr", "png"] {
            let paths: Vec<std::path::PathBuf> = (0..3)
                .map(|i| dir.path().join(format!("part{i}.{ext}")))
                .collect();
            for (c, p) in crops.iter().zip(&paths) {
                write_part(&fb, c, p).expect("write part");
            }
            let refs: Vec<&Path> = paths.iter().map(|p| p.as_path()).collect();
            let s = stitch(&refs).expect("stitch");
            assert_eq!(s.overlapping, 0);
            if ext == "exr" {
                assert!(s.float);
                assert_eq!(s.image, fb);
            } else {
                assert!(!s.float);
                assert_eq!(s.image.to_rgb8(), fb.to_rgb8());
            }
            let err = stitch(&refs[..2]).expect_err("a gap").to_string();
            assert!(err.contains("35 of the 13x9 pixels"), "{err}");
            assert!(err.contains("6,4,13,9"), "{err}");
        }
        let bad = dir.path().join("p.jpg");
        assert!(write_part(&fb, &crops[0], &bad).is_err());
    }
}
