//! OBJ files of positions, normals and faces alone (what scanners and most
//! exporters write, texture coordinates, groups and comments read past)
//! parsed on every thread: the file is cut at line ends into pieces, each
//! piece parsed alone, and face indices resolved once the pieces before
//! each say how many vertices and normals they define.
//!
//! It gives exactly the polygons the general reader (`obj::parse`) would
//! hand to `build`, or nothing: a material (`mtllib`, `usemtl`), vertex
//! colours, points or lines, a malformed or non-finite number, an index
//! out of range, anything that reader would warn of or refuse sends the
//! whole file to it, so every error and warning keeps its line.

use glam::DVec3;
use rayon::prelude::*;

/// Below this, one thread parses as fast as the pieces would.
const PIECE: usize = 1 << 20;

/// What the pieces give `build`: positions, normals, and polygons as corner
/// lists with their lines.
pub(super) struct Polygons {
    pub positions: Vec<DVec3>,
    pub normals: Vec<DVec3>,
    /// (position, normal) indices, resolved and in range.
    pub corners: Vec<(u32, Option<u32>)>,
    /// (first corner, corner count, line) of each polygon.
    pub polygons: Vec<(u32, u32, u64)>,
}

/// One piece's findings, its indices as written.
#[derive(Default)]
struct Piece {
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    /// (position index, normal index) as written: 1-based, or negative.
    corners: Vec<(i64, Option<i64>)>,
    /// (first corner, count, line in the piece from 0, positions and
    /// normals the piece had defined before it).
    polygons: Vec<(u32, u32, u32, u32, u32)>,
    lines: usize,
}

pub(super) fn read(src: &[u8]) -> Option<Polygons> {
    if memchr::memchr(0x0b, src).is_some() {
        // A vertical tab is a blank between tokens but part of a word
        // inside one: the general reader's business.
        return None;
    }
    let pieces: Vec<&[u8]> = cut(src);
    let parsed: Vec<Piece> = pieces.par_iter().map(|p| piece(p)).collect::<Option<_>>()?;
    // What the pieces before each define.
    let mut before = Vec::with_capacity(parsed.len());
    let (mut positions, mut normals, mut lines, mut corners) = (0usize, 0usize, 0usize, 0usize);
    for p in &parsed {
        before.push((positions, normals, lines, corners));
        positions += p.positions.len();
        normals += p.normals.len();
        lines += p.lines;
        corners += p.corners.len();
    }
    if positions >= u32::MAX as usize
        || normals >= u32::MAX as usize
        || corners >= u32::MAX as usize
    {
        return None;
    }
    // Each piece resolves its corners straight into its stretch of the
    // whole list; its polygons, positions and normals are copied to theirs.
    let mut all = Vec::with_capacity(corners);
    let mut rest = &mut all.spare_capacity_mut()[..corners];
    let mut stretches = Vec::with_capacity(parsed.len());
    for p in &parsed {
        let (mine, more) = rest.split_at_mut(p.corners.len());
        stretches.push(mine);
        rest = more;
    }
    let polygons: Vec<Vec<(u32, u32, u64)>> = parsed
        .par_iter()
        .zip(&before)
        .zip(stretches)
        .map(|((p, &(vp, np, lp, cp)), out)| resolve(p, vp, np, lp, cp, out))
        .collect::<Option<_>>()?;
    // SAFETY: the stretches cover the first `corners` slots exactly (their
    // lengths sum to it), and every piece's `resolve` succeeded, writing
    // each slot of its stretch.
    unsafe { all.set_len(corners) };
    Some(Polygons {
        positions: gather(parsed.iter().map(|p| p.positions.as_slice()), positions),
        normals: gather(parsed.iter().map(|p| p.normals.as_slice()), normals),
        corners: all,
        polygons: gather(
            polygons.iter().map(Vec::as_slice),
            polygons.iter().map(Vec::len).sum(),
        ),
    })
}

/// The parts one after another in one vector of `total` items, copied on
/// every thread.
fn gather<'a, T: Copy + Send + Sync + 'a>(
    parts: impl Iterator<Item = &'a [T]>,
    total: usize,
) -> Vec<T> {
    let parts: Vec<&[T]> = parts.collect();
    assert_eq!(parts.iter().map(|p| p.len()).sum::<usize>(), total);
    let mut out = Vec::with_capacity(total);
    let mut rest = &mut out.spare_capacity_mut()[..total];
    let mut stretches = Vec::with_capacity(parts.len());
    for p in &parts {
        let (mine, more) = rest.split_at_mut(p.len());
        stretches.push(mine);
        rest = more;
    }
    stretches
        .into_par_iter()
        .zip(parts)
        .for_each(|(out, part)| {
            for (o, &v) in out.iter_mut().zip(part) {
                o.write(v);
            }
        });
    // SAFETY: the stretches cover the first `total` slots exactly (the
    // parts' lengths sum to it, asserted), and each was written in full.
    unsafe { out.set_len(total) };
    out
}

/// The file in pieces of about `PIECE` bytes, each ending after a line end
/// (the last at the end of the file).
fn cut(src: &[u8]) -> Vec<&[u8]> {
    let mut pieces = Vec::new();
    let mut rest = src;
    while rest.len() > PIECE {
        let end = match memchr::memchr(b'\n', &rest[PIECE..]) {
            Some(i) => PIECE + i + 1,
            None => rest.len(),
        };
        pieces.push(&rest[..end]);
        rest = &rest[end..];
    }
    if !rest.is_empty() {
        pieces.push(rest);
    }
    pieces
}

/// A piece's indices made global and checked as the general reader checks
/// them: each refers to one defined so far.
fn resolve(
    p: &Piece,
    positions_before: usize,
    normals_before: usize,
    lines_before: usize,
    corners_before: usize,
    out: &mut [std::mem::MaybeUninit<(u32, Option<u32>)>],
) -> Option<Vec<(u32, u32, u64)>> {
    let index = |i: i64, count: usize| -> Option<u32> {
        let index = if i < 0 {
            (count as i64).saturating_add(i)
        } else {
            i - 1
        };
        (i != 0 && index >= 0 && index < count as i64).then_some(index as u32)
    };
    let mut polygons = Vec::with_capacity(p.polygons.len());
    for &(start, len, line, vp, np) in &p.polygons {
        let (vcount, ncount) = (positions_before + vp as usize, normals_before + np as usize);
        let range = start as usize..(start + len) as usize;
        for (&(v, n), o) in p.corners[range.clone()].iter().zip(&mut out[range]) {
            let n = match n {
                Some(n) => Some(index(n, ncount)?),
                None => None,
            };
            o.write((index(v, vcount)?, n));
        }
        polygons.push((
            (corners_before + start as usize) as u32,
            len,
            (lines_before + line as usize + 1) as u64,
        ));
    }
    Some(polygons)
}

/// A cursor over a piece: tokens on the current line, as `Text` cuts
/// them (blanks between, `#` to the line's end a comment).
struct Cursor<'a> {
    src: &'a [u8],
    pos: usize,
    /// Line ends passed: the current line's index in the piece.
    ends: usize,
}

impl<'a> Cursor<'a> {
    /// The next token on this line; None at its end or a comment.
    #[inline]
    fn token(&mut self) -> Option<&'a [u8]> {
        self.skip_blanks();
        match self.src.get(self.pos) {
            None | Some(b'\n' | b'#') => None,
            Some(_) => {
                let start = self.pos;
                self.pos = super::text::word_end(self.src, start);
                Some(&self.src[start..self.pos])
            }
        }
    }

    /// The next token on this line as a number the general reader takes
    /// without a word (finite, within f32), read where it stands when it
    /// is a plain decimal; None for anything else.
    #[inline]
    fn number(&mut self) -> Option<f64> {
        self.skip_blanks();
        let rest = &self.src[self.pos..];
        if let Some((v, len)) = crate::number::parse_prefix(rest) {
            let ends = rest
                .get(len)
                .is_none_or(|&c| c.is_ascii_whitespace() || c == b'#');
            if ends {
                self.pos += len;
                return finite(v);
            }
        }
        finite(crate::number::parse_f64(self.token()?)?)
    }

    #[inline]
    fn skip_blanks(&mut self) {
        while let Some(&c) = self.src.get(self.pos) {
            if matches!(c, b' ' | b'\t' | b'\r' | b'\x0c') {
                self.pos += 1;
            } else {
                break;
            }
        }
    }

    /// Past the end of this line (counted in `ends`); false at the end of
    /// the piece.
    fn next_line(&mut self) -> bool {
        match memchr::memchr(b'\n', &self.src[self.pos..]) {
            Some(i) => {
                self.pos += i + 1;
                self.ends += 1;
                self.pos < self.src.len()
            }
            None => {
                self.pos = self.src.len();
                false
            }
        }
    }
}

/// A number the general reader takes without a word: finite, within f32.
#[inline]
fn finite(v: f64) -> Option<f64> {
    (v.is_finite() && v.abs() <= f64::from(f32::MAX)).then_some(v)
}

fn piece(src: &[u8]) -> Option<Piece> {
    let mut p = Piece::default();
    let mut c = Cursor {
        src,
        pos: 0,
        ends: 0,
    };
    loop {
        if let Some(key) = c.token() {
            match key {
                b"v" => {
                    let v = [c.number()?, c.number()?, c.number()?];
                    // `v x y z r g b` is a colour: the general reader's.
                    if c.token().is_some() && c.token().is_some() && c.token().is_some() {
                        return None;
                    }
                    p.positions.push(DVec3::from(v));
                }
                b"vn" => {
                    let n = DVec3::new(c.number()?, c.number()?, c.number()?);
                    if n.length_squared() == 0.0 || !n.length_squared().is_finite() {
                        return None;
                    }
                    p.normals.push(n);
                }
                b"f" | b"fo" => {
                    let start = p.corners.len();
                    while let Some(tok) = c.token() {
                        p.corners.push(corner(tok)?);
                    }
                    let len = p.corners.len() - start;
                    p.polygons.push((
                        u32::try_from(start).ok()?,
                        u32::try_from(len).ok()?,
                        u32::try_from(c.ends).ok()?,
                        u32::try_from(p.positions.len()).ok()?,
                        u32::try_from(p.normals.len()).ok()?,
                    ));
                }
                b"p" | b"l" | b"mtllib" | b"usemtl" => return None,
                _ => {}
            }
        }
        if !c.next_line() {
            break;
        }
    }
    p.lines = c.ends;
    Some(p)
}

/// One `f` corner, `v`, `v/vt`, `v//vn` or `v/vt/vn`, its indices as written.
#[inline]
fn corner(tok: &[u8]) -> Option<(i64, Option<i64>)> {
    let int = |s: &[u8]| -> Option<i64> {
        // Plain digits (with a minus) here; anything else as the general
        // reader parses it.
        let (negative, digits) = match s.split_first() {
            Some((b'-', rest)) => (true, rest),
            _ => (false, s),
        };
        if !digits.is_empty() && digits.len() <= 18 && digits.iter().all(u8::is_ascii_digit) {
            let v = digits
                .iter()
                .fold(0i64, |v, &d| v * 10 + i64::from(d - b'0'));
            return Some(if negative { -v } else { v });
        }
        std::str::from_utf8(s).ok()?.parse::<i64>().ok()
    };
    let mut parts = tok.split(|&c| c == b'/');
    let v = int(parts.next()?)?;
    let _texture = parts.next();
    let n = match parts.next() {
        Some(s) if !s.is_empty() => Some(int(s)?),
        _ => None,
    };
    Some((v, n))
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::super::{obj, Refs};

    /// Whether the fast reader took `src`; both readers' meshes (with
    /// their warnings and errors) must be equal either way.
    fn both(src: &str) -> bool {
        let path = Path::new("t.obj");
        let general = obj::parse_general(src.as_bytes(), path, Refs::None);
        let chosen = obj::parse(src.as_bytes(), path, Refs::None);
        // Compared as printed: a NaN equals itself there.
        assert_eq!(format!("{chosen:?}"), format!("{general:?}"), "{src:.200}");
        super::read(src.as_bytes()).is_some()
    }

    const QUAD: &str = "# a quad\r\nv 0 0 0\r\nv 1 0 0\r\nv 1 1 0.5\r\nv 0 1 0.25\r\n\
                        vt 0 0\nvn 0 0 1\nvn 0 0.6 0.8\n\ng one\ns 1\no it\n\
                        f 1/1/1 2/1/1 3//2 # comment\n  f\t-4//1 -2//2 -1//2\nf 1 2 3 4\n";

    #[test]
    fn plain_files_read_fast_and_as_the_general_reader_does() {
        assert!(both(QUAD));
        assert!(
            both("v 1 2 3 1\nv 2 3 4\nv 1 1 1\nf 1 2 3\n"),
            "a w is not a colour"
        );
        assert!(both(""), "nothing at all");
        // Polygons the builder warns of keep their lines.
        assert!(both(
            "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\nf 1 1 2\n"
        ));
    }

    #[test]
    fn big_files_in_pieces_keep_indices_and_lines() {
        // Over a few pieces: faces with negative indices across piece
        // ends, and a face without area near the end whose warning must
        // name its line.
        let mut s = String::from("vn 0 0 1\n");
        let rows = 100_000;
        for i in 0..rows {
            s += &format!("v {i} 0 {}\nv {i} 1 0.5\n", i % 7);
            if i > 0 {
                s += "f -4 -3 -1\nf -4//1 -1//1 -2//1\n";
            }
        }
        s += "v 0 0 0\nv 1 0 0\nv 2 0 0\nf -3 -2 -1\n";
        assert!(s.len() > 3 * super::PIECE);
        assert!(both(&s));
        let mesh = obj::parse(s.as_bytes(), Path::new("t.obj"), Refs::None).unwrap();
        assert_eq!(mesh.faces.len(), 2 * (rows - 1));
        assert!(
            format!("{:?}", mesh.report).contains("line"),
            "{:?}",
            mesh.report
        );
    }

    #[test]
    fn what_needs_care_goes_to_the_general_reader() {
        let face = "v 0 0 0\nv 1 0 0\nv 1 1 0\n";
        for tail in [
            "mtllib a.mtl\nf 1 2 3\n",
            "usemtl red\nf 1 2 3\n",
            "v 1 1 1 0.5 0.5 0.5\nf 1 2 3\n",
            "v nan 0 0\nf 1 2 4\n",
            "v 1.0.0 0 0\nf 1 2 4\n",
            "v 1e39 0 0\n",
            "f 1 2 4\n",
            "f 0 1 2\n",
            "f 1//1 2//1 3//1\n",
            "vn 0 0 0\nf 1//1 2//1 3//1\n",
            "p 1\nf 1 2 3\n",
            "l 1 2\nf 1 2 3\n",
            "f 1 2 x\n",
            "v 1 2\n",
            "v 1\x0b2 3\n",
        ] {
            assert!(
                !both(&format!("{face}{tail}")),
                "{tail}: the fast reader should decline"
            );
        }
    }
}
