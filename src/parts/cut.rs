//! Where an image is cut into parts: contiguous runs of pixels in row-major
//! order, one per part, with about equal estimated cost each.
//!
//! Every task of an array computes the cut on its own, so it is integer
//! arithmetic over a deterministic estimate (`Costs`): the same scene and
//! settings give the same cut on every node, and `stitch` still checks that
//! the parts it gets cover each pixel exactly once.

use std::fmt;

/// The pixels `start..end` of an image, counted row-major from the top left
/// (pixel `y * width + x`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Span {
    /// The first pixel.
    pub start: u64,
    /// The first pixel past it.
    pub end: u64,
    /// The image's width, to place the pixels in rows.
    pub width: u32,
}

impl Span {
    /// How many pixels it holds.
    pub fn pixels(&self) -> u64 {
        self.end - self.start
    }

    /// Whether pixel (x, y) is in the span.
    pub fn contains(&self, x: u32, y: u32) -> bool {
        let i = u64::from(y) * u64::from(self.width) + u64::from(x);
        x < self.width && (self.start..self.end).contains(&i)
    }

    /// The span as at most three rectangles (x, y, width, height): the rest
    /// of its first row, its whole rows, the start of its last row.
    pub fn rects(&self) -> Vec<[u32; 4]> {
        let w = u64::from(self.width);
        let mut out = Vec::with_capacity(3);
        let (mut i, end) = (self.start, self.end);
        if i % w != 0 {
            let row_end = (i / w + 1) * w;
            let stop = row_end.min(end);
            out.push([(i % w) as u32, (i / w) as u32, (stop - i) as u32, 1]);
            i = stop;
        }
        if end - i >= w {
            let rows = (end - i) / w;
            out.push([0, (i / w) as u32, self.width, rows as u32]);
            i += rows * w;
        }
        if i < end {
            out.push([0, (i / w) as u32, (end - i) as u32, 1]);
        }
        out
    }
}

impl fmt::Display for Span {
    /// As `x,y` of the first pixel to `x,y` of the last.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let w = u64::from(self.width);
        let last = self.end.saturating_sub(1);
        write!(
            f,
            "pixels {},{} to {},{}",
            self.start % w,
            self.start / w,
            last % w,
            last / w
        )
    }
}

/// Parts start and end on a multiple of this many rows where the image has
/// rows enough (else on whole rows, else anywhere). A part that starts
/// inside a band of the CPU's packet tiles (`cpu::packet::TILE`, 8 rows
/// tall) would trace that band's tiles as packets of a few lanes, at nearly
/// a full packet's cost each; the GPU's workgroups are 8 x 8 pixels, and a
/// part cut inside one leaves its other invocations idle. The grain is a
/// constant, not a device's, because every node of a mixed cluster must cut
/// alike.
pub const GRAIN_ROWS: u32 = 8;

/// The estimated cost of each row's pixels: `per_pixel[y]` for every pixel
/// of row `y` (at least 1, so that no pixel is free and every part holds
/// pixels).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Costs {
    /// The image's width.
    pub width: u32,
    /// Per row, the cost of each of its pixels.
    pub per_pixel: Vec<u64>,
}

impl Costs {
    /// Every pixel alike: equal strips.
    pub fn uniform(width: u32, height: u32) -> Costs {
        Costs {
            width,
            per_pixel: vec![1; height as usize],
        }
    }

    /// Costs of a `width` x `height` image from a coarser estimate: `probe`
    /// holds `probe_width` costs a row, and full row `y` takes the summed
    /// cost of probe row `y * probe_rows / height`.
    pub fn from_probe(width: u32, height: u32, probe: &[u64], probe_width: u32) -> Costs {
        let probe_width = probe_width.max(1) as usize;
        let rows: Vec<u64> = probe
            .chunks(probe_width)
            .map(|r| r.iter().sum::<u64>().max(1))
            .collect();
        let per_pixel = (0..u64::from(height))
            .map(|y| match rows.len() as u64 {
                0 => 1,
                n => rows[(y * n / u64::from(height)) as usize],
            })
            .collect();
        Costs { width, per_pixel }
    }

    fn pixels(&self) -> u64 {
        u64::from(self.width) * self.per_pixel.len() as u64
    }
}

/// Cuts the image into `count` spans of about equal cost, in order, each
/// holding at least one pixel, their ends on `GRAIN_ROWS` rows where the
/// image allows (each part's cost then within a band's of the ideal, finer
/// than the probe behind `costs` resolves);
/// `count` must be 1 to the pixel count.
pub fn cut(costs: &Costs, count: u32) -> Vec<Span> {
    let width = u64::from(costs.width);
    let pixels = costs.pixels();
    let n = u64::from(count);
    assert!(
        (1..=pixels.max(1)).contains(&n),
        "{count} parts of {pixels} pixels"
    );
    let total: u128 = costs
        .per_pixel
        .iter()
        .map(|&c| u128::from(c.max(1)) * u128::from(width))
        .sum();
    // Boundary k is the first pixel whose cost before it reaches k/n of the
    // total: walk the rows once, placing boundaries as their targets pass.
    let mut bounds = Vec::with_capacity(count as usize + 1);
    bounds.push(0u64);
    let mut before: u128 = 0;
    let mut k = 1u64;
    for (y, &c) in costs.per_pixel.iter().enumerate() {
        let c = u128::from(c.max(1));
        let row_start = y as u64 * width;
        let row_total = c * u128::from(width);
        while k < n {
            let target = (total * u128::from(k)).div_ceil(u128::from(n));
            if target > before + row_total {
                break;
            }
            // The first x with before + c * x >= target.
            let x = (target.saturating_sub(before)).div_ceil(c) as u64;
            bounds.push(row_start + x.min(width));
            k += 1;
        }
        before += row_total;
    }
    while bounds.len() < count as usize {
        bounds.push(pixels);
    }
    bounds.push(pixels);
    // Equal boundaries (a part too cheap to hold a pixel) are spread so that
    // each part holds at least one: part k starts at k at the earliest and
    // leaves one pixel for each part after it.
    for k in 1..count as usize {
        let lowest = bounds[k - 1] + 1;
        let highest = pixels - (n - k as u64);
        bounds[k] = bounds[k].clamp(lowest, highest);
    }
    let bounds = snapped(&bounds, width);
    bounds
        .windows(2)
        .map(|b| Span {
            start: b[0],
            end: b[1],
            width: costs.width,
        })
        .collect()
}

/// The boundaries each rounded to the nearest band of `GRAIN_ROWS` rows,
/// else to the nearest row, else left, whichever comes first that keeps
/// it past the boundary before (so every part holds a pixel) and before
/// the next one's unrounded place (so that one still has a choice).
fn snapped(bounds: &[u64], width: u64) -> Vec<u64> {
    let near = |b: u64, grain: u64| (b + grain / 2) / grain * grain;
    let mut out = bounds.to_vec();
    for k in 1..bounds.len().saturating_sub(1) {
        let (before, next) = (out[k - 1], bounds[k + 1]);
        out[k] = [
            near(bounds[k], width * u64::from(GRAIN_ROWS)),
            near(bounds[k], width),
        ]
        .into_iter()
        .find(|&c| before < c && c < next)
        .unwrap_or(bounds[k]);
    }
    out
}

/// The frames `first..last + 1` of `frames` that part `index` of `count`
/// renders: contiguous shares whose sizes differ by one at most; None for a
/// part with no frame (more parts than frames).
pub fn frame_share(frames: u32, index: u32, count: u32) -> Option<[u32; 2]> {
    let (f, n, i) = (u64::from(frames), u64::from(count), u64::from(index));
    let first = i * f / n;
    let end = (i + 1) * f / n;
    (end > first).then(|| [first as u32, end as u32 - 1])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn covers_once(spans: &[Span], width: u32, height: u32) {
        let mut held = vec![0u8; (width * height) as usize];
        for s in spans {
            assert!(s.pixels() > 0, "{s:?}");
            let mut from_rects = 0u64;
            for [x, y, w, h] in s.rects() {
                for yy in y..y + h {
                    for xx in x..x + w {
                        assert!(s.contains(xx, yy), "{s:?} rect pixel {xx},{yy}");
                        held[(yy * width + xx) as usize] += 1;
                    }
                }
                from_rects += u64::from(w) * u64::from(h);
            }
            assert_eq!(from_rects, s.pixels(), "{s:?}");
        }
        assert!(held.iter().all(|&h| h == 1), "{width}x{height}: {spans:?}");
    }

    /// Every N from 1 to the pixel count, uniform and skewed costs: each
    /// pixel lies in exactly one part, through `contains` and `rects` alike.
    #[test]
    fn every_pixel_is_in_exactly_one_part_for_any_count() {
        for (w, h) in [(1, 1), (7, 5), (13, 1), (1, 11), (16, 9)] {
            let skewed = Costs {
                width: w,
                per_pixel: (0..h).map(|y| if y % 3 == 0 { 1 } else { 40 }).collect(),
            };
            for costs in [Costs::uniform(w, h), skewed] {
                for n in 1..=w * h {
                    let spans = cut(&costs, n);
                    assert_eq!(spans.len(), n as usize);
                    assert!(spans.windows(2).all(|p| p[0].end == p[1].start));
                    covers_once(&spans, w, h);
                }
            }
        }
        // A large image, a count past its rows.
        let spans = cut(&Costs::uniform(640, 480), 1000);
        covers_once(&spans, 640, 480);
    }

    /// A cheap sky over a costly floor: parts over the sky are taller, and
    /// every part's estimated cost is within a band of the costly rows of
    /// the ideal (each end snapped to a band moves by half a band at most).
    #[test]
    fn parts_balance_the_estimated_cost() {
        let (w, h) = (64u32, 100u32);
        let costs = Costs {
            width: w,
            per_pixel: (0..h).map(|y| if y < 50 { 1 } else { 9 }).collect(),
        };
        let spans = cut(&costs, 5);
        let cost = |s: &Span| -> u64 {
            (s.start..s.end)
                .map(|i| costs.per_pixel[(i / u64::from(w)) as usize])
                .sum()
        };
        let total: u64 = spans.iter().map(cost).sum();
        for s in &spans {
            let off = cost(s).abs_diff(total / 5);
            let band = u64::from(GRAIN_ROWS * w * 9);
            assert!(off <= band, "{s:?}: {} against {}", cost(s), total / 5);
        }
        assert!(spans[0].pixels() > 4 * spans[4].pixels(), "{spans:?}");
    }

    /// Where the image has bands enough, every boundary lies on one; where
    /// it has rows enough, on a row; the cover stays exact either way.
    #[test]
    fn boundaries_snap_to_bands_then_rows() {
        let costs = Costs {
            width: 1920,
            per_pixel: (0..1080).map(|y| 1 + y / 10).collect(),
        };
        let band = 1920 * u64::from(GRAIN_ROWS);
        let spans = cut(&costs, 16);
        assert!(spans.iter().all(|s| s.start % band == 0), "{spans:?}");
        // 135 bands hold 100 even parts but not 200; 1080 rows hold 200.
        let even = Costs::uniform(1920, 1080);
        assert!(cut(&even, 100).iter().all(|s| s.start % band == 0));
        let rows = cut(&even, 200);
        assert!(rows.iter().all(|s| s.start % 1920 == 0), "{rows:?}");
        assert!(rows.iter().any(|s| s.start % band != 0));
        // Where the costly rows crowd parts into one band, those fall back.
        for n in [100, 500, 3000] {
            let spans = cut(&costs, n);
            assert_eq!(spans.len(), n as usize);
            assert!(spans.windows(2).all(|p| p[0].end == p[1].start));
            assert!(spans.iter().all(|s| s.pixels() > 0));
        }
        covers_once(&cut(&Costs::uniform(64, 9), 20), 64, 9);
    }

    #[test]
    fn probe_rows_map_onto_full_rows() {
        let c = Costs::from_probe(8, 4, &[1, 1, 5, 5], 2);
        assert_eq!(c.per_pixel, vec![2, 2, 10, 10]);
        assert_eq!(Costs::from_probe(8, 3, &[], 2).per_pixel, vec![1, 1, 1]);
    }

    #[test]
    fn frame_shares_cover_every_frame_once() {
        for frames in [1, 2, 7, 100] {
            for count in [1, 3, 7, 16] {
                let mut seen = vec![0; frames as usize];
                for i in 0..count {
                    if let Some([a, b]) = frame_share(frames, i, count) {
                        (a..=b).for_each(|f| seen[f as usize] += 1);
                    }
                }
                assert!(seen.iter().all(|&s| s == 1), "{frames} / {count}");
            }
        }
        assert_eq!(frame_share(2, 0, 3), None);
        assert_eq!(frame_share(2, 1, 3), Some([0, 0]));
    }

    #[test]
    fn spans_name_their_pixels() {
        let s = Span {
            start: 5,
            end: 23,
            width: 8,
        };
        assert_eq!(s.rects(), vec![[5, 0, 3, 1], [0, 1, 8, 1], [0, 2, 7, 1]]);
        assert_eq!(s.to_string(), "pixels 5,0 to 6,2");
    }
}
