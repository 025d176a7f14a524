//! Which pixels a render computes: all, the active blocks of a progressive
//! pass, a `--crop` rectangle or a `--part` span.

use super::passes::Blocks;
use crate::parts::crop::Crop;
use crate::parts::cut::Span;

/// Which pixels a render computes; the others are left 0.
#[derive(Clone, Copy)]
pub(crate) enum Region<'a> {
    All,
    /// The active blocks of a progressive render.
    Blocks(&'a Blocks),
    Crop(Crop),
    /// A part of `--part` (`parts::cut`).
    Span(Span),
}

impl Region<'_> {
    pub(crate) fn pixels(&self, width: u32, height: u32) -> u64 {
        match self {
            Region::All => u64::from(width) * u64::from(height),
            Region::Blocks(b) => b
                .rects()
                .iter()
                .map(|r| u64::from(r[2]) * u64::from(r[3]))
                .sum(),
            Region::Crop(c) => c.pixels(),
            Region::Span(s) => s.pixels(),
        }
    }

    /// Rows holding every pixel the region keeps.
    pub(crate) fn rows(&self, height: u32) -> std::ops::Range<u32> {
        match self {
            Region::All | Region::Blocks(_) => 0..height,
            Region::Crop(c) => c.y0..c.y1,
            Region::Span(s) => {
                let w = u64::from(s.width);
                (s.start / w) as u32..(s.end.div_ceil(w)) as u32
            }
        }
    }

    pub(crate) fn keeps(&self, x: u32, y: u32) -> bool {
        match self {
            Region::All => true,
            Region::Blocks(b) => b.is_active(x, y),
            Region::Crop(c) => c.contains(x, y),
            Region::Span(s) => s.contains(x, y),
        }
    }
}
