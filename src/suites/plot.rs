//! The reports' charts (`glint accuracy`, `glint bench --plot`): log-log
//! lines of named series, drawn by `plotters` as SVG, or as a picture for a
//! PNG, with DejaVu Sans embedded (`dejavu`) so that a PNG's text needs no
//! font on the machine.

use std::sync::Once;

use image::RgbImage;
use plotters::backend::{BitMapBackend, SVGBackend};
use plotters::coord::Shift;
use plotters::prelude::*;

/// The chart's size in SVG pixels; the PNG is drawn at a multiple of it.
const SIZE: (u32, u32) = (760, 480);

/// The series' colours: matplotlib's ten, then two darker ones, so that
/// an accuracy sweep's series (two backends by two samplers by up to three
/// knobs) all differ; the markers cycle through three shapes as well.
const COLOURS: [RGBColor; 12] = [
    RGBColor(0x1f, 0x77, 0xb4),
    RGBColor(0xd6, 0x27, 0x28),
    RGBColor(0x2c, 0xa0, 0x2c),
    RGBColor(0x94, 0x67, 0xbd),
    RGBColor(0xff, 0x7f, 0x0e),
    RGBColor(0x8c, 0x56, 0x4b),
    RGBColor(0xe3, 0x77, 0xc2),
    RGBColor(0x17, 0xbe, 0xcf),
    RGBColor(0xbc, 0xbd, 0x22),
    RGBColor(0x7f, 0x7f, 0x7f),
    RGBColor(0x00, 0x2b, 0x5c),
    RGBColor(0x5c, 0x00, 0x2b),
];

/// A log-log chart: one line through its points per named series (points
/// not positive on both axes are left out), with a legend that shows each
/// series' line and marker.
#[derive(Clone, Debug, PartialEq)]
pub struct LogLog {
    /// Above the chart.
    pub title: String,
    /// Under the x axis.
    pub x_label: String,
    /// Beside the y axis.
    pub y_label: String,
    /// (name, points), drawn in order.
    pub series: Vec<(String, Vec<[f64; 2]>)>,
}

/// A log-log chart of `series`; see `LogLog`.
pub fn log_log(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[(String, Vec<[f64; 2]>)],
) -> LogLog {
    LogLog {
        title: title.to_string(),
        x_label: x_label.to_string(),
        y_label: y_label.to_string(),
        series: series
            .iter()
            .map(|(name, points)| {
                let kept = points
                    .iter()
                    .copied()
                    .filter(|p| p[0] > 0.0 && p[1] > 0.0 && p[0].is_finite() && p[1].is_finite())
                    .collect();
                (name.clone(), kept)
            })
            .filter(|(_, points): &(String, Vec<[f64; 2]>)| !points.is_empty())
            .collect(),
    }
}

impl LogLog {
    /// The chart as an SVG document.
    pub fn to_svg(&self) -> String {
        register_font();
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
            // Drawing into a string cannot fail but for a font that cannot
            // lay out text, and the embedded one can.
            self.draw(&root, 1.0).expect("drawing a chart into memory");
        }
        svg
    }

    /// The chart as a picture, `scale` pixels an SVG pixel.
    pub fn to_image(&self, scale: f64) -> RgbImage {
        register_font();
        let (w, h) = (
            (f64::from(SIZE.0) * scale).round().max(1.0) as u32,
            (f64::from(SIZE.1) * scale).round().max(1.0) as u32,
        );
        let mut pixels = vec![0u8; (w * h * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut pixels, (w, h)).into_drawing_area();
            self.draw(&root, scale)
                .expect("drawing a chart into memory");
        }
        RgbImage::from_raw(w, h, pixels).expect("a buffer of w x h x 3 bytes")
    }

    fn draw<B: DrawingBackend>(
        &self,
        root: &DrawingArea<B, Shift>,
        scale: f64,
    ) -> Result<(), DrawingAreaErrorKind<B::ErrorType>> {
        let px = |v: f64| (v * scale).round() as i32;
        root.fill(&WHITE)?;
        let (x_range, y_range) = (self.range(0), self.range(1));
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, ("sans-serif", px(18.0)))
            .margin(px(12.0))
            .x_label_area_size(px(44.0))
            .y_label_area_size(px(64.0))
            .build_cartesian_2d(x_range.log_scale(), y_range.log_scale())?;
        chart
            .configure_mesh()
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .label_style(("sans-serif", px(13.0)))
            .axis_desc_style(("sans-serif", px(14.0)))
            .x_label_formatter(&|v| number(*v))
            .y_label_formatter(&|v| number(*v))
            .light_line_style(RGBColor(0xee, 0xee, 0xee))
            .draw()?;
        let (marker, width) = (px(4.0).max(1) as u32, px(2.0).max(1) as u32);
        // The legend's glyph: a line with the marker on it, in the space
        // plotters leaves before each label (`legend_area_size`).
        let glyph = px(26.0);
        for (i, (name, points)) in self.series.iter().enumerate() {
            let colour = COLOURS[i % COLOURS.len()];
            let line = colour.stroke_width(width);
            chart
                .draw_series(LineSeries::new(points.iter().map(|p| (p[0], p[1])), line))?
                .label(name.as_str())
                .legend(move |(x, y)| {
                    EmptyElement::at((x, y))
                        + PathElement::new(vec![(0, 0), (glyph, 0)], line)
                        + Shape::new(i, (glyph / 2, 0), marker, colour)
                });
            chart.draw_series(
                points.iter().map(|p| {
                    EmptyElement::at((p[0], p[1])) + Shape::new(i, (0, 0), marker, colour)
                }),
            )?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .legend_area_size(glyph + px(8.0))
            .label_font(("sans-serif", px(13.0)))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(0x99, 0x99, 0x99))
            .draw()?;
        root.present()
    }

    /// The data's extent on `axis`, widened to whole decades so that the
    /// axes show at least one labelled power of ten.
    fn range(&self, axis: usize) -> std::ops::Range<f64> {
        let values = self
            .series
            .iter()
            .flat_map(|(_, p)| p.iter().map(|q| q[axis]));
        let lo = values.clone().fold(f64::INFINITY, f64::min);
        let hi = values.fold(f64::NEG_INFINITY, f64::max);
        if !lo.is_finite() {
            return 1.0..10.0;
        }
        let lo = 10f64.powf(lo.log10().floor());
        let hi = 10f64.powf(hi.log10().ceil()).max(lo * 10.0);
        lo..hi
    }
}

/// An axis label: a power of ten as people write it (0.01, 1, 1000), or
/// in exponent form where that is long (1e-5, 1e6).
fn number(v: f64) -> String {
    let e = v.abs().log10().round();
    if (-3.0..=4.0).contains(&e) {
        let digits = (-e).max(0.0) as usize;
        format!("{v:.digits$}")
    } else {
        format!("{v:.0e}")
    }
}

/// A series' marker, told apart by shape as well as colour: a disc, a
/// square or a triangle, in turn.
struct Shape;

impl Shape {
    #[allow(clippy::new_ret_no_self)]
    fn new<DB: DrawingBackend>(
        series: usize,
        at: (i32, i32),
        size: u32,
        colour: RGBColor,
    ) -> DynElement<'static, DB, (i32, i32)> {
        let s = size as i32;
        let style = colour.filled();
        match series % 3 {
            0 => Circle::new(at, size, style).into_dyn(),
            1 => Rectangle::new([(at.0 - s, at.1 - s), (at.0 + s, at.1 + s)], style).into_dyn(),
            _ => Polygon::new(
                vec![
                    (at.0, at.1 - s - 1),
                    (at.0 - s - 1, at.1 + s),
                    (at.0 + s + 1, at.1 + s),
                ],
                style,
            )
            .into_dyn(),
        }
    }
}

/// DejaVu Sans as plotters' "sans-serif", once per process.
fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The embedded font parses; a failure would leave the charts
        // without text, never without their lines.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chart() -> LogLog {
        log_log(
            "errors",
            "time (ms)",
            "RMSE",
            &[
                ("spp (cpu, sobol)".into(), vec![[1.0, 0.1], [10.0, 0.01]]),
                (
                    "spp (cpu, stratified)".into(),
                    vec![[2.0, 0.2], [20.0, 0.05]],
                ),
                ("nothing".into(), vec![[0.0, 1.0], [1.0, -1.0]]),
            ],
        )
    }

    #[test]
    fn axis_numbers_read_as_written() {
        let shown: Vec<String> = [1e-5, 0.001, 0.01, 1.0, 10.0, 1e4, 1e6]
            .into_iter()
            .map(number)
            .collect();
        assert_eq!(shown, ["1e-5", "0.001", "0.01", "1", "10", "10000", "1e6"]);
    }

    #[test]
    fn points_off_a_log_axis_are_left_out() {
        let c = chart();
        let names: Vec<&str> = c.series.iter().map(|s| s.0.as_str()).collect();
        assert_eq!(names, ["spp (cpu, sobol)", "spp (cpu, stratified)"]);
        assert_eq!(c.range(0), 1.0..100.0);
        assert_eq!(c.range(1), 0.01..1.0);
    }

    /// Both forms carry the title, the axes' names and every series in the
    /// legend; the picture has each series' colour in it.
    #[test]
    fn svg_and_png_show_every_series() {
        let c = chart();
        let svg = c.to_svg();
        for text in [
            "errors",
            "time (ms)",
            "RMSE",
            "spp (cpu, sobol)",
            "spp (cpu, stratified)",
        ] {
            assert!(svg.contains(text), "{text} missing from the SVG");
        }
        let img = c.to_image(2.0);
        assert_eq!((img.width(), img.height()), (2 * SIZE.0, 2 * SIZE.1));
        for colour in &COLOURS[..2] {
            let count = img
                .pixels()
                .filter(|p| p.0 == [colour.0, colour.1, colour.2])
                .count();
            assert!(count > 100, "{colour:?}: {count} pixels");
        }
        let dark = img.pixels().filter(|p| p.0.iter().all(|&c| c < 64)).count();
        assert!(dark > 1000, "text and axes drawn: {dark} dark pixels");
    }
}
