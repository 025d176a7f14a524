//! The bytes of an entry's body: little-endian numbers and arrays of plain
//! values, each array after its length. Reading checks every length
//! against what is left, so a body that lies about its sizes is an error,
//! never a panic or a huge allocation.

use bytemuck::Pod;
use rayon::prelude::*;
use xxhash_rust::xxh3::{xxh3_128, Xxh3};

/// Writes a body.
#[derive(Default)]
pub(super) struct Writer(pub(super) Vec<u8>);

impl Writer {
    pub(super) fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    pub(super) fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    pub(super) fn f64(&mut self, v: f64) {
        self.u64(v.to_bits());
    }

    /// `values`, after their count.
    pub(super) fn array<T: Pod>(&mut self, values: &[T]) {
        self.u64(values.len() as u64);
        self.0.extend_from_slice(bytemuck::cast_slice(values));
    }

    pub(super) fn text(&mut self, s: &str) {
        self.array(s.as_bytes());
    }
}

/// Reads a body `Writer` wrote.
pub(super) struct Reader<'a> {
    bytes: &'a [u8],
}

pub(super) type Result<T> = std::result::Result<T, String>;

impl<'a> Reader<'a> {
    pub(super) fn new(bytes: &'a [u8]) -> Self {
        Reader { bytes }
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        if n > self.bytes.len() {
            return Err(format!(
                "the body ends {} bytes short",
                n - self.bytes.len()
            ));
        }
        let (head, rest) = self.bytes.split_at(n);
        self.bytes = rest;
        Ok(head)
    }

    pub(super) fn u32(&mut self) -> Result<u32> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    pub(super) fn u64(&mut self) -> Result<u64> {
        let b = self.take(8)?;
        let mut a = [0; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }

    pub(super) fn f64(&mut self) -> Result<f64> {
        self.u64().map(f64::from_bits)
    }

    /// A count no larger than what `size`-byte items could fill of the
    /// rest of the body.
    pub(super) fn count(&mut self, size: usize) -> Result<usize> {
        let n = self.u64()?;
        let most = (self.bytes.len() / size.max(1)) as u64;
        if n > most {
            return Err(format!("a count of {n} where at most {most} fit"));
        }
        Ok(n as usize)
    }

    /// An array `Writer::array` wrote, copied out: one copy where the
    /// bytes happen to be aligned for `T` (as a large read's are), a
    /// zeroing and a copy where not.
    pub(super) fn array<T: Pod + Send + Sync>(&mut self) -> Result<Vec<T>> {
        let size = std::mem::size_of::<T>();
        let n = self.count(size)?;
        let bytes = self.take(n * size)?;
        Ok(match bytemuck::try_cast_slice::<u8, T>(bytes) {
            // On every thread: a large array's copy is mostly page faults.
            Ok(values) => values.par_iter().with_min_len(1 << 16).copied().collect(),
            Err(_) => bytemuck::pod_collect_to_vec(bytes),
        })
    }

    pub(super) fn text(&mut self) -> Result<String> {
        String::from_utf8(self.array::<u8>()?).map_err(|_| "text that is not UTF-8".into())
    }

    /// Whether the whole body was read.
    pub(super) fn end(&self) -> Result<()> {
        if self.bytes.is_empty() {
            Ok(())
        } else {
            Err(format!(
                "{} bytes past the end of the body",
                self.bytes.len()
            ))
        }
    }
}

/// Items hashed per thread at a time: fixed, so the hash is the same on
/// any number of threads.
const CHUNK: usize = 1 << 14;

/// Feeds `items` to `hasher`: each chunk's bytes (as `put` writes them)
/// hashed on some thread, then the chunks' hashes in order.
pub(super) fn hash_items<T: Sync>(
    hasher: &mut Xxh3,
    items: &[T],
    put: impl Fn(&T, &mut Writer) + Sync,
) {
    let chunks: Vec<u128> = items
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut w = Writer::default();
            for item in chunk {
                put(item, &mut w);
            }
            xxh3_128(&w.0)
        })
        .collect();
    hasher.update(&(items.len() as u64).to_le_bytes());
    for c in chunks {
        hasher.update(&c.to_le_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_body_reads_back_and_lies_are_errors() {
        let mut w = Writer::default();
        w.u32(7);
        w.f64(-0.5);
        w.array(&[1u32, 2, 3]);
        w.text("glint");
        let mut r = Reader::new(&w.0);
        assert_eq!(r.u32(), Ok(7));
        assert_eq!(r.f64(), Ok(-0.5));
        assert_eq!(r.array::<u32>(), Ok(vec![1, 2, 3]));
        assert_eq!(r.text().as_deref(), Ok("glint"));
        assert_eq!(r.end(), Ok(()));
        // A count larger than the body: an error, nothing allocated.
        let mut w = Writer::default();
        w.u64(u64::MAX);
        assert!(Reader::new(&w.0).array::<[f32; 8]>().is_err());
        assert!(Reader::new(&[1, 2]).u32().is_err());
    }

    #[test]
    fn the_hash_is_the_same_on_any_number_of_threads() {
        let items: Vec<u32> = (0..100_000).collect();
        let hash = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool");
            pool.install(|| {
                let mut h = Xxh3::new();
                hash_items(&mut h, &items, |i, w| w.u32(*i));
                h.digest128()
            })
        };
        assert_eq!(hash(1), hash(3));
        let mut h = Xxh3::new();
        hash_items(&mut h, &items[1..], |i, w| w.u32(*i));
        assert_ne!(h.digest128(), hash(2));
    }
}
