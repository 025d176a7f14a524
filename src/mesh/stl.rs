//! STL, ASCII and binary (told apart by content in `source`: binary files
//! often begin with `solid` too). Triangles only, no materials; vertices
//! at the same position are joined, and normals come from the vertices
//! (`smooth_normals`), never from the facet normals, which writers often
//! get wrong. An ASCII file may hold several solids, and a facet with more
//! than three vertices is read as a polygon.

use std::collections::HashMap;
use std::path::Path;

use glam::DVec3;

use super::build::{Builder, Loc};
use super::text::Text;
use super::{Mesh, MeshError};

/// Joins vertices at the same position (bit for bit), so faces share
/// corners and smooth normals span them.
/// Hashed with foldhash, not SipHash: the keys are a file's own
/// coordinates (ASCII files; binary ones are welded by `weld_binary`).
struct Weld {
    index: HashMap<[u64; 3], u32, foldhash::fast::RandomState>,
}

impl Weld {
    /// Room for `vertices` (a guess: a closed mesh has about half as
    /// many vertices as triangles), so the table is not grown and rehashed
    /// as it fills.
    fn new(vertices: usize) -> Weld {
        let mut index = HashMap::with_hasher(foldhash::fast::RandomState::default());
        index.reserve(vertices);
        Weld { index }
    }

    fn vertex(&mut self, b: &mut Builder, p: DVec3) -> u32 {
        let next = b.mesh.positions.len() as u32;
        *self
            .index
            .entry(p.to_array().map(f64::to_bits))
            .or_insert_with(|| {
                b.mesh.positions.push(p);
                next
            })
    }
}

/// Binary STL: an 80-byte header, a little-endian triangle count, then per
/// triangle a normal, three vertices (f32 each) and a 2-byte attribute.
pub fn parse_binary(src: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    let error = |at: usize, message: String| MeshError {
        path: path.to_path_buf(),
        at: Some(format!("byte {at}")),
        message,
    };
    let Some(count) = src.get(80..84) else {
        return Err(error(src.len(), "too short for a binary STL header".into()));
    };
    let count = u32::from_le_bytes([count[0], count[1], count[2], count[3]]) as usize;
    let whole = (src.len() - 84) / 50;
    if whole < count {
        return Err(error(
            src.len(),
            format!("the file ends inside triangle {} of {count}", whole + 1),
        ));
    }
    if count.saturating_mul(3) >= u32::MAX as usize {
        return Err(error(
            84,
            format!("{count} triangles: more than 4 billion corners"),
        ));
    }
    let (positions, ids) = weld_binary(&src[84..84 + 50 * count]);
    let mut b = Builder::new(path);
    b.mesh.positions = positions;
    for (i, t) in ids.chunks_exact(3).enumerate() {
        b.polygon(
            t.iter().map(|&c| (c, None)),
            None,
            Loc::Byte((84 + 50 * i) as u64),
        );
    }
    b.finish()
}

/// A corner's position in binary STL's triangles (`records`, 50 bytes
/// each): corner `c` is vertex `c % 3` of triangle `c / 3`.
fn corner_at(records: &[u8], c: usize) -> DVec3 {
    let o = 50 * (c / 3) + 12 + 12 * (c % 3);
    let f = |k: usize| {
        let b = &records[o + 4 * k..o + 4 * k + 4];
        f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    DVec3::new(f(0), f(1), f(2))
}

/// Every corner of binary STL's triangles welded as `Weld` does (a
/// position's vertex is made at its first corner, in file order), on every
/// thread: the positions are dealt to shards by a fixed hash, each shard
/// finds the first corner of each of its positions, and one pass in file
/// order numbers the vertices. Returns the vertices and each corner's.
/// The whole weld took 1.0 s of a 2M-triangle file's 1.3 s load through
/// one SipHash table.
fn weld_binary(records: &[u8]) -> (Vec<DVec3>, Vec<u32>) {
    use rayon::prelude::*;
    use std::hash::BuildHasher;
    use std::sync::atomic::{AtomicU32, Ordering};
    let corners = records.len() / 50 * 3;
    let key = |c: usize| corner_at(records, c).to_array().map(f64::to_bits);
    // A shard a thread: every shard decodes and hashes every corner to
    // find its own, so more shards cost more than their smaller tables
    // save (8 shards on 2 threads: parse 555-630 ms for 2M triangles; 2:
    // 490-530).
    let shards = rayon::current_num_threads().max(1) as u64;
    let deal = foldhash::fast::FixedState::with_seed(0x5eed);
    let first: Vec<AtomicU32> = (0..corners).map(|_| AtomicU32::new(0)).collect();
    (0..shards).into_par_iter().for_each(|shard| {
        let mut table: HashMap<[u64; 3], u32, foldhash::fast::RandomState> =
            HashMap::with_capacity_and_hasher(
                corners / 6 / shards as usize + 16,
                foldhash::fast::RandomState::default(),
            );
        for (c, slot) in first.iter().enumerate() {
            let k = key(c);
            if deal.hash_one(k) % shards != shard {
                continue;
            }
            slot.store(*table.entry(k).or_insert(c as u32), Ordering::Relaxed);
        }
    });
    let mut positions = Vec::with_capacity(corners / 6 + 3);
    let mut ids = vec![0u32; corners];
    for (c, slot) in first.iter().enumerate() {
        let f = slot.load(Ordering::Relaxed) as usize;
        ids[c] = if f == c {
            positions.push(corner_at(records, c));
            (positions.len() - 1) as u32
        } else {
            ids[f]
        };
    }
    (positions, ids)
}

/// ASCII STL: `solid`, then `facet normal ...`, `outer loop`, `vertex x y
/// z` three times, `endloop`, `endfacet`, ..., `endsolid`; repeated for
/// each solid.
pub fn parse_ascii(src: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    let mut t = Text::new(src, path);
    let mut b = Builder::new(path);
    let mut weld = Weld::new(0);
    let mut corners: Vec<(u32, Option<u32>)> = Vec::new();
    let mut facet_line = 0u64;
    while let Some(key) = t.token() {
        let key = key.to_ascii_lowercase();
        match key.as_slice() {
            b"solid" | b"endsolid" => {
                t.rest_of_line();
            }
            b"facet" => {
                facet_line = t.line() as u64;
                corners.clear();
                // The facet normal is not used.
                t.rest_of_line();
            }
            b"vertex" => {
                let mut v = [0.0; 3];
                for (k, c) in v.iter_mut().enumerate() {
                    let tok = t.token_on_line();
                    *c = t.number(tok, ["x", "y", "z"][k])?;
                }
                if corners.len() >= 1 << 20 {
                    return Err(t.error("a facet of over a million vertices"));
                }
                corners.push((weld.vertex(&mut b, DVec3::from(v)), None));
            }
            b"endfacet" => {
                if b.corner_count() + corners.len() >= u32::MAX as usize {
                    return Err(t.error("more than 4 billion corners"));
                }
                b.polygon(corners.drain(..), None, Loc::Line(facet_line));
            }
            _ => {}
        }
    }
    b.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The weld one corner at a time, as the ASCII reader does.
    fn sequential(records: &[u8]) -> (Vec<DVec3>, Vec<u32>) {
        let mut b = Builder::new(Path::new("t"));
        let mut weld = Weld::new(0);
        let ids = (0..records.len() / 50 * 3)
            .map(|c| weld.vertex(&mut b, corner_at(records, c)))
            .collect();
        (b.mesh.positions, ids)
    }

    #[test]
    fn the_binary_weld_numbers_vertices_as_one_table_would() {
        // Corners drawn from a small set of positions (so most repeat),
        // with 0 and -0 (different vertices) and NaNs among them.
        let values = [0.0f32, -0.0, 1.0, 2.5, f32::NAN, -3.0, 1e-30];
        let mut records = Vec::new();
        let mut x = 12345u32;
        for _ in 0..20_000 {
            records.extend([0u8; 12]);
            for _ in 0..9 {
                x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                records.extend(values[(x >> 24) as usize % values.len()].to_le_bytes());
            }
            records.extend([0u8; 2]);
        }
        let (want_positions, want_ids) = sequential(&records);
        for threads in [1, 2, 5] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let (positions, ids) = pool.install(|| weld_binary(&records));
            assert_eq!(ids, want_ids, "{threads} threads");
            let bits = |p: &[DVec3]| -> Vec<[u64; 3]> {
                p.iter().map(|v| v.to_array().map(f64::to_bits)).collect()
            };
            assert_eq!(bits(&positions), bits(&want_positions), "{threads} threads");
        }
    }
}
