//! Counting what goes wrong in a probe image, against the CPU f64 reference
//! of the same scene.
//!
//! A pixel's *verdict* is (hit or miss, shadow mask). The reference is never
//! exact either, so counts that concern shading only look at pixels whose
//! reference primitive and verdict agree with all 8 neighbours (*interior*
//! pixels): a pixel that straddles a shadow edge, a silhouette, or the seam
//! between two primitives may legitimately go either way under f32 rounding;
//! one that does not may not. Disagreements on seams are counted apart
//! (`Seam`) and not asserted: where two separate surfaces meet at a crease
//! (a box standing on the ground), a point on the crease lies on both, and a
//! shadow ray leaving one surface can graze the other within rounding, in
//! f64 as in f32.

use std::fmt;

use crate::probe::{ProbeImage, ProbePixel};

/// The failure kinds the hard-case suite counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Metric {
    /// Pixels whose colour, point or normal is infinite or NaN.
    Nan,
    /// Background where the reference and its 8 neighbours hit (cracks,
    /// missed shared edges and vertices; not silhouettes).
    Crack,
    /// Interior pixels shadowed by a light the reference says is visible.
    Acne,
    /// Interior pixels lit by a light the reference says is blocked.
    Leak,
    /// Lone pixels whose verdict on the reference's primitive differs from
    /// the reference while all four neighbours agree with it (acne dots,
    /// speckle on grazing planes).
    Speckle,
    /// Hit/miss disagreements more than one pixel from the reference's
    /// silhouette.
    Silhouette,
    /// Shading disagreements on the reference's primitive next to another
    /// primitive (creases, mesh edges); reported, never asserted.
    Seam,
}

impl Metric {
    /// Every metric, in report order.
    pub const ALL: [Metric; 7] = [
        Metric::Nan,
        Metric::Crack,
        Metric::Acne,
        Metric::Leak,
        Metric::Speckle,
        Metric::Silhouette,
        Metric::Seam,
    ];

    /// What reports call it.
    pub fn name(self) -> &'static str {
        match self {
            Metric::Nan => "NaN",
            Metric::Crack => "crack",
            Metric::Acne => "acne",
            Metric::Leak => "leak",
            Metric::Speckle => "speckle",
            Metric::Silhouette => "silhouette",
            Metric::Seam => "seam",
        }
    }
}

impl fmt::Display for Metric {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Pixel counts per `Metric`, in `Metric::ALL` order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts(pub [usize; 7]);

impl Counts {
    /// The count of `m`.
    pub fn get(&self, m: Metric) -> usize {
        self.0[Metric::ALL.iter().position(|&x| x == m).expect("in ALL")]
    }
}

fn verdict(p: &ProbePixel) -> (bool, u32) {
    (p.hit(), if p.hit() { p.shadow_mask } else { 0 })
}

/// Counts every metric of `image` against `reference` (same size).
pub fn count(image: &ProbeImage, reference: &ProbeImage) -> Counts {
    let mut c = [0usize; 7];
    for_each_failure(image, reference, |_, _, flags| {
        for (n, f) in c.iter_mut().zip(flags) {
            *n += usize::from(f);
        }
    });
    Counts(c)
}

/// The pixels that count towards `metric`, in row order.
pub fn failing_pixels(image: &ProbeImage, reference: &ProbeImage, metric: Metric) -> Vec<[u32; 2]> {
    let k = Metric::ALL
        .iter()
        .position(|&m| m == metric)
        .expect("in ALL");
    let mut out = Vec::new();
    for_each_failure(image, reference, |x, y, flags| {
        if flags[k] {
            out.push([x, y]);
        }
    });
    out
}

/// Calls `f(x, y, flags)` for every pixel, flags in `Metric::ALL` order.
fn for_each_failure(
    image: &ProbeImage,
    reference: &ProbeImage,
    mut f: impl FnMut(u32, u32, [bool; 7]),
) {
    assert_eq!(
        (image.width, image.height),
        (reference.width, reference.height),
        "probe images of different sizes"
    );
    let (w, h) = (i64::from(image.width), i64::from(image.height));
    let at = |img: &ProbeImage, x: i64, y: i64| -> Option<(bool, u32)> {
        (x >= 0 && y >= 0 && x < w && y < h).then(|| verdict(img.get(x as u32, y as u32)))
    };
    let prim_at = |x: i64, y: i64| -> Option<u32> {
        (x >= 0 && y >= 0 && x < w && y < h).then(|| reference.get(x as u32, y as u32).prim)
    };
    let neighbours8 = [
        (-1, -1),
        (0, -1),
        (1, -1),
        (-1, 0),
        (1, 0),
        (-1, 1),
        (0, 1),
        (1, 1),
    ];
    let neighbours4 = [(0, -1), (-1, 0), (1, 0), (0, 1)];
    for y in 0..h {
        for x in 0..w {
            let b = image.get(x as u32, y as u32);
            let r = reference.get(x as u32, y as u32);
            let (vb, vr) = (verdict(b), verdict(r));
            let mut flags = [false; 7];
            flags[0] = b.nonfinite();
            if vb != vr {
                let uniform = |keep: fn((bool, u32), (bool, u32)) -> bool| {
                    neighbours8
                        .iter()
                        .all(|&(dx, dy)| at(reference, x + dx, y + dy).is_none_or(|n| keep(n, vr)))
                };
                let hit_interior = uniform(|n, v| n.0 == v.0);
                flags[1] = r.hit() && !b.hit() && hit_interior;
                // Shading verdicts compare only on the same primitive: a ray
                // through a seam within rounding may meet the neighbour.
                let same = b.hit() && b.prim == r.prim;
                let one_prim = neighbours8
                    .iter()
                    .all(|&(dx, dy)| prim_at(x + dx, y + dy).is_none_or(|p| p == r.prim));
                if same && one_prim && uniform(|n, v| n == v) {
                    flags[2] = b.shadow_mask & !r.shadow_mask != 0;
                    flags[3] = r.shadow_mask & !b.shadow_mask != 0;
                }
                flags[4] = same
                    && one_prim
                    && neighbours4.iter().all(|&(dx, dy)| {
                        match (at(image, x + dx, y + dy), at(reference, x + dx, y + dy)) {
                            (Some(nb), Some(nr)) => nb == nr && nr == vr,
                            _ => true,
                        }
                    });
                flags[6] = same && !one_prim;
                flags[5] = b.hit() != r.hit() && hit_interior;
            }
            f(x as u32, y as u32, flags);
        }
    }
}

/// Pixels of `image` alone against their own 4 neighbours: those hit the
/// same primitive and share one verdict, and the pixel's differs. Salt and
/// pepper by its shape; needs no reference, so it can judge the reference.
pub fn lone_pixels(image: &ProbeImage) -> usize {
    let mut n = 0;
    for y in 1..image.height.saturating_sub(1) {
        for x in 1..image.width.saturating_sub(1) {
            let p = image.get(x, y);
            let around =
                [(x, y - 1), (x - 1, y), (x + 1, y), (x, y + 1)].map(|(a, b)| image.get(a, b));
            let first = around[0];
            if p.hit()
                && around
                    .iter()
                    .all(|q| q.prim == p.prim && verdict(q) == verdict(first))
                && verdict(p) != verdict(first)
            {
                n += 1;
            }
        }
    }
    n
}
