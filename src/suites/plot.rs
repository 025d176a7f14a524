//! A small vector drawing (lines, dots, text) written as SVG, whose text
//! the viewer's fonts draw, and rasterised here to a PNG-ready image, whose
//! text comes from a built-in 8x8 bitmap font: one description, so the two
//! files always show the same plot, and no system font or plotting program
//! is needed.

use std::fmt::Write as _;

use image::{Rgb, RgbImage};

/// Where text sits on its anchor point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Anchor {
    /// The text starts there.
    Start,
    /// The text is centred there.
    Middle,
    /// The text ends there.
    End,
}

#[derive(Clone, Debug)]
enum Item {
    Line {
        points: Vec<[f64; 2]>,
        colour: [u8; 3],
        width: f64,
    },
    Dot {
        at: [f64; 2],
        radius: f64,
        colour: [u8; 3],
    },
    Text {
        at: [f64; 2],
        text: String,
        size: f64,
        anchor: Anchor,
        /// Read bottom to top (rotated -90 degrees about `at`).
        vertical: bool,
    },
}

/// A drawing in user units (SVG pixels), on white.
#[derive(Clone, Debug)]
pub struct Plot {
    /// Width in user units.
    pub width: f64,
    /// Height in user units.
    pub height: f64,
    items: Vec<Item>,
}

/// `#rrggbb` as bytes; black for anything else.
pub fn hex(colour: &str) -> [u8; 3] {
    let v = u32::from_str_radix(colour.trim_start_matches('#'), 16).unwrap_or(0);
    [(v >> 16) as u8, (v >> 8) as u8, v as u8]
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Rows of a glyph in the bitmap font (bit 0 is the leftmost pixel); `?`
/// for characters outside Basic Latin.
fn glyph(c: char) -> [u8; 8] {
    use font8x8::UnicodeFonts;
    font8x8::BASIC_FONTS
        .get(c)
        .or_else(|| font8x8::BASIC_FONTS.get('?'))
        .unwrap_or([0; 8])
}

impl Plot {
    /// An empty drawing of this size.
    pub fn new(width: f64, height: f64) -> Plot {
        Plot {
            width,
            height,
            items: Vec::new(),
        }
    }

    /// A polyline (two points: a segment).
    pub fn line(&mut self, points: &[[f64; 2]], colour: [u8; 3], width: f64) {
        self.items.push(Item::Line {
            points: points.to_vec(),
            colour,
            width,
        });
    }

    /// A filled circle.
    pub fn dot(&mut self, at: [f64; 2], radius: f64, colour: [u8; 3]) {
        self.items.push(Item::Dot { at, radius, colour });
    }

    /// Black text whose baseline passes through `at`.
    pub fn text(&mut self, at: [f64; 2], text: &str, size: f64, anchor: Anchor, vertical: bool) {
        self.items.push(Item::Text {
            at,
            text: text.to_string(),
            size,
            anchor,
            vertical,
        });
    }

    /// The drawing as an SVG document.
    pub fn to_svg(&self) -> String {
        let (w, h) = (self.width, self.height);
        let mut s = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\">\n<rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n"
        );
        let rgb = |c: [u8; 3]| format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2]);
        for item in &self.items {
            let _ = match item {
                Item::Line {
                    points,
                    colour,
                    width,
                } => {
                    let pts: Vec<String> = points
                        .iter()
                        .map(|p| format!("{:.1},{:.1}", p[0], p[1]))
                        .collect();
                    writeln!(
                        s,
                        "<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"{width}\"/>",
                        pts.join(" "),
                        rgb(*colour)
                    )
                }
                Item::Dot { at, radius, colour } => writeln!(
                    s,
                    "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"{radius}\" fill=\"{}\"/>",
                    at[0],
                    at[1],
                    rgb(*colour)
                ),
                Item::Text {
                    at,
                    text,
                    size,
                    anchor,
                    vertical,
                } => {
                    let anchor = match anchor {
                        Anchor::Start => "start",
                        Anchor::Middle => "middle",
                        Anchor::End => "end",
                    };
                    let rotate = if *vertical {
                        format!(" transform=\"rotate(-90 {:.1} {:.1})\"", at[0], at[1])
                    } else {
                        String::new()
                    };
                    writeln!(
                        s,
                        "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"{size}\" text-anchor=\"{anchor}\"{rotate}>{}</text>",
                        at[0],
                        at[1],
                        escape(text)
                    )
                }
            };
        }
        s.push_str("</svg>\n");
        s
    }

    /// The drawing rasterised at `scale` pixels per user unit, lines and
    /// dots antialiased by their coverage of each pixel.
    pub fn to_image(&self, scale: f64) -> RgbImage {
        let (w, h) = (
            (self.width * scale).round().max(1.0) as u32,
            (self.height * scale).round().max(1.0) as u32,
        );
        let mut img = RgbImage::from_pixel(w, h, Rgb([255; 3]));
        for item in &self.items {
            match item {
                Item::Line {
                    points,
                    colour,
                    width,
                } => {
                    for pair in points.windows(2) {
                        let a = pair[0].map(|v| v * scale);
                        let b = pair[1].map(|v| v * scale);
                        let half = (width * scale / 2.0).max(0.5);
                        cover(&mut img, *colour, [a, b], half + 1.0, |p| {
                            half + 0.5 - segment_distance(p, a, b)
                        });
                    }
                }
                Item::Dot { at, radius, colour } => {
                    let c = at.map(|v| v * scale);
                    let r = radius * scale;
                    cover(&mut img, *colour, [c, c], r + 1.0, |p| {
                        r + 0.5 - ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2)).sqrt()
                    });
                }
                Item::Text {
                    at,
                    text,
                    size,
                    anchor,
                    vertical,
                } => draw_text(
                    &mut img,
                    at.map(|v| v * scale),
                    text,
                    size * scale,
                    *anchor,
                    *vertical,
                ),
            }
        }
        img
    }
}

fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (qx, qy) = (a[0] + t * dx, a[1] + t * dy);
    ((p[0] - qx).powi(2) + (p[1] - qy).powi(2)).sqrt()
}

/// Blends `colour` into every pixel near the segment `ends` (within
/// `reach`) by `coverage(pixel centre)`, clamped to [0, 1].
fn cover(
    img: &mut RgbImage,
    colour: [u8; 3],
    ends: [[f64; 2]; 2],
    reach: f64,
    coverage: impl Fn([f64; 2]) -> f64,
) {
    let (w, h) = (f64::from(img.width()), f64::from(img.height()));
    let x0 = (ends[0][0].min(ends[1][0]) - reach).floor().clamp(0.0, w) as u32;
    let x1 = (ends[0][0].max(ends[1][0]) + reach).ceil().clamp(0.0, w) as u32;
    let y0 = (ends[0][1].min(ends[1][1]) - reach).floor().clamp(0.0, h) as u32;
    let y1 = (ends[0][1].max(ends[1][1]) + reach).ceil().clamp(0.0, h) as u32;
    for y in y0..y1 {
        for x in x0..x1 {
            let a = coverage([f64::from(x) + 0.5, f64::from(y) + 0.5]).clamp(0.0, 1.0);
            if a > 0.0 {
                let px = img.get_pixel_mut(x, y);
                for (v, &c) in px.0.iter_mut().zip(&colour) {
                    *v = (f64::from(*v) * (1.0 - a) + f64::from(c) * a).round() as u8;
                }
            }
        }
    }
}

/// Text in the 8x8 font, each font pixel a square of about a tenth of
/// `size` (so a capital is about 0.7 `size` tall, as in common fonts); the
/// baseline is the glyph's seventh row.
fn draw_text(
    img: &mut RgbImage,
    at: [f64; 2],
    text: &str,
    size: f64,
    anchor: Anchor,
    vertical: bool,
) {
    let p = (size / 10.0).round().max(1.0) as i64;
    let n = text.chars().count() as i64;
    let width = 8 * p * n;
    let start = match anchor {
        Anchor::Start => 0,
        Anchor::Middle => -width / 2,
        Anchor::End => -width,
    };
    let (ax, ay) = (at[0].round() as i64, at[1].round() as i64);
    for (i, c) in text.chars().enumerate() {
        for (row, bits) in glyph(c).iter().enumerate() {
            for col in 0..8 {
                if bits & (1 << col) == 0 {
                    continue;
                }
                // Along the text (u) and down from the baseline (v).
                let u = start + (i as i64 * 8 + col) * p;
                let v = (row as i64 - 7) * p;
                let (x, y) = if vertical {
                    (ax + v, ay - u - p)
                } else {
                    (ax + u, ay + v)
                };
                for dy in 0..p {
                    for dx in 0..p {
                        let (px, py) = (x + dx, y + dy);
                        if px >= 0
                            && py >= 0
                            && px < i64::from(img.width())
                            && py < i64::from(img.height())
                        {
                            img.put_pixel(px as u32, py as u32, Rgb([0; 3]));
                        }
                    }
                }
            }
        }
    }
}

/// A log-log chart: one line with dots per named series of (x, y) points
/// (positive; others are left out), decades on both axes, and a legend.
pub fn log_log(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[(String, Vec<[f64; 2]>)],
) -> Plot {
    let (w, h) = (720.0, 480.0);
    let (left, right, top, bottom) = (70.0, 230.0, 40.0, 50.0);
    let logs: Vec<(&str, Vec<[f64; 2]>)> = series
        .iter()
        .map(|(name, points)| {
            let pts = points
                .iter()
                .filter(|p| p[0] > 0.0 && p[1] > 0.0)
                .map(|p| [p[0].log10(), p[1].log10()])
                .collect();
            (name.as_str(), pts)
        })
        .filter(|(_, pts): &(&str, Vec<[f64; 2]>)| !pts.is_empty())
        .collect();
    let span = |axis: usize| {
        let all = logs
            .iter()
            .flat_map(|(_, p)| p.iter().map(move |q| q[axis]));
        let lo = all.clone().fold(f64::INFINITY, f64::min);
        let hi = all.fold(f64::NEG_INFINITY, f64::max);
        if lo.is_finite() {
            (lo.floor(), hi.ceil().max(lo.floor() + 1.0))
        } else {
            (0.0, 1.0)
        }
    };
    let (x0, x1) = span(0);
    let (y0, y1) = span(1);
    let px = |x: f64| left + (x - x0) / (x1 - x0) * (w - left - right);
    let py = |y: f64| h - bottom - (y - y0) / (y1 - y0) * (h - top - bottom);
    let mut p = Plot::new(w, h);
    p.text([left, 22.0], title, 14.0, Anchor::Start, false);
    let grid = [0xdd; 3];
    for d in (x0 as i32)..=(x1 as i32) {
        let x = px(f64::from(d));
        p.line(&[[x, top], [x, h - bottom]], grid, 1.0);
        p.text(
            [x, h - bottom + 16.0],
            &format!("1e{d}"),
            12.0,
            Anchor::Middle,
            false,
        );
    }
    for d in (y0 as i32)..=(y1 as i32) {
        let y = py(f64::from(d));
        p.line(&[[left, y], [w - right, y]], grid, 1.0);
        p.text(
            [left - 6.0, y + 4.0],
            &format!("1e{d}"),
            12.0,
            Anchor::End,
            false,
        );
    }
    p.text(
        [(left + w - right) / 2.0, h - 12.0],
        x_label,
        12.0,
        Anchor::Middle,
        false,
    );
    p.text(
        [16.0, (top + h - bottom) / 2.0],
        y_label,
        12.0,
        Anchor::Middle,
        true,
    );
    let colours = [
        "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf",
    ];
    for (i, (name, pts)) in logs.iter().enumerate() {
        let colour = hex(colours[i % colours.len()]);
        let coords: Vec<[f64; 2]> = pts.iter().map(|q| [px(q[0]), py(q[1])]).collect();
        p.line(&coords, colour, 2.0);
        for &c in &coords {
            p.dot(c, 3.0, colour);
        }
        let ly = top + 10.0 + 18.0 * i as f64;
        p.line(
            &[[w - right + 10.0, ly], [w - right + 30.0, ly]],
            colour,
            2.0,
        );
        p.text(
            [w - right + 36.0, ly + 4.0],
            name,
            12.0,
            Anchor::Start,
            false,
        );
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The PNG shows what the SVG says: lines where they are, text in the
    /// bitmap font where its anchor puts it, white elsewhere.
    #[test]
    fn raster_matches_the_description() {
        let mut p = Plot::new(100.0, 50.0);
        p.line(&[[10.0, 10.0], [90.0, 10.0]], [255, 0, 0], 2.0);
        p.dot([50.0, 40.0], 3.0, [0, 0, 255]);
        p.text([50.0, 30.0], "Hi", 10.0, Anchor::Middle, false);
        let svg = p.to_svg();
        assert!(
            svg.contains("<polyline points=\"10.0,10.0 90.0,10.0\""),
            "{svg}"
        );
        assert!(svg.contains("text-anchor=\"middle\">Hi</text>"), "{svg}");
        let img = p.to_image(2.0);
        assert_eq!((img.width(), img.height()), (200, 100));
        assert_eq!(img.get_pixel(100, 20).0, [255, 0, 0], "on the line");
        assert_eq!(img.get_pixel(100, 30).0, [255; 3], "off it");
        assert_eq!(img.get_pixel(100, 80).0, [0, 0, 255], "the dot");
        // "Hi" at 2 px a font pixel: 32 px wide, centred on x = 100, rows
        // 46-59 (the baseline at y = 60 is the glyphs' seventh row).
        let ink = |x0: u32, x1: u32| {
            (x0..x1)
                .flat_map(|x| (40..62).map(move |y| (x, y)))
                .filter(|&(x, y)| img.get_pixel(x, y).0 == [0; 3])
                .count()
        };
        assert!(
            ink(84, 100) > 20 && ink(100, 116) > 10,
            "both letters drawn"
        );
        assert_eq!(ink(0, 83) + ink(117, 200), 0, "nothing outside the text");
        let mut v = Plot::new(40.0, 40.0);
        v.text([20.0, 20.0], "ab", 10.0, Anchor::Middle, true);
        let img = v.to_image(1.0);
        let rows: Vec<u32> = (0..40)
            .filter(|&y| (0..40).any(|x| img.get_pixel(x, y).0 == [0; 3]))
            .collect();
        assert!(rows.len() > 10, "vertical text spans rows: {rows:?}");
    }
}
