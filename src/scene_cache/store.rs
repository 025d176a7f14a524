//! The cache's entries on disk: one file each, named by its kind and key,
//! written whole or not at all, and never trusted without its checks.
//!
//! A file is a 48-byte header (magic, kind, key, body length, xxh3-64 of
//! the body) and the body. It is written to a temporary file in the same
//! directory and renamed into place, so a reader (another Slurm task on a
//! shared disk) sees the old entry, the new one or none, never part of
//! one; two writers of one entry each rename a whole file, and the last
//! wins. A file whose header or checksum does not match is ignored, said,
//! and replaced by the next store.
//!
//! Least recently used first out: a hit sets the file's modification
//! time, and a store that takes the directory past its cap removes the
//! oldest entries until it is back under.

use std::io::{Read as _, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use xxhash_rust::xxh3::Xxh3;

const MAGIC: &[u8; 8] = b"GLINTSC1";
/// Magic, kind, key, body length, checksum.
const HEADER: usize = 8 + 4 + 16 + 8 + 8;
/// Temporary files older than this are a crashed writer's: removed.
const STALE_TEMP: Duration = Duration::from_secs(3600);

/// What an entry holds; part of its file name and header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    /// A BVH (`super::bvh`).
    Bvh = 1,
    /// A loaded scene (`super::loaded`).
    Scene = 2,
}

impl Kind {
    fn prefix(self) -> &'static str {
        match self {
            Kind::Bvh => "bvh",
            Kind::Scene => "scene",
        }
    }
}

/// An entry's body as read whole (`Store::load`).
#[derive(Debug, PartialEq, Eq)]
pub(crate) struct Body(Vec<u8>);

impl Body {
    pub(crate) fn bytes(&self) -> &[u8] {
        &self.0
    }
}

/// What `Store::load` found.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum Found {
    /// The entry's body, its checksum verified.
    Body(Body),
    /// No entry.
    Missing,
    /// A file that is not a whole entry for this key, and why.
    Ignored(String),
}

/// What `Store::open` found.
pub(crate) enum Opened {
    /// An entry whose header is this key's and whose length is whole.
    Entry(Box<Entry>),
    /// No entry.
    Missing,
    /// A file that is not an entry for this key, and why.
    Ignored(String),
}

/// An entry's body as a stream, hashed as it passes: what is read of it
/// is only known to be the body that was written once `finish` says so.
pub(crate) struct Entry {
    file: std::io::BufReader<std::fs::File>,
    left: u64,
    hasher: Xxh3,
    checksum: u64,
    path: PathBuf,
}

impl std::io::Read for Entry {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let most = buf
            .len()
            .min(usize::try_from(self.left).unwrap_or(usize::MAX));
        let n = self.file.read(&mut buf[..most])?;
        if n == 0 && most > 0 {
            return Err(std::io::ErrorKind::UnexpectedEof.into());
        }
        self.hasher.update(&buf[..n]);
        self.left -= n as u64;
        Ok(n)
    }
}

impl Entry {
    /// The body's length in bytes.
    pub(crate) fn left(&self) -> u64 {
        self.left
    }

    /// Whether the whole body was read and is what was written.
    pub(crate) fn finish(self) -> Result<(), String> {
        if self.left != 0 {
            return Err(format!(
                "{}: {} bytes of its body unread",
                self.path.display(),
                self.left
            ));
        }
        if self.hasher.digest() != self.checksum {
            return Err(format!(
                "{}: its body does not match its checksum",
                self.path.display()
            ));
        }
        Ok(())
    }
}

/// A directory of entries with a size cap.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Store {
    pub(crate) dir: PathBuf,
    pub(crate) cap: u64,
}

impl Store {
    fn path(&self, kind: Kind, key: u128) -> PathBuf {
        self.dir.join(format!("{}-{key:032x}.bin", kind.prefix()))
    }

    /// The entry stored under `kind` and `key`, its body no longer than
    /// `max` bytes, to be read as a stream.
    pub(crate) fn open(&self, kind: Kind, key: u128, max: u64) -> Opened {
        let path = self.path(kind, key);
        let file = match std::fs::File::open(&path) {
            Ok(f) => f,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Opened::Missing,
            Err(e) => return Opened::Ignored(format!("{}: {e}", path.display())),
        };
        let ignored = |why: String| Opened::Ignored(format!("{}: {why}", path.display()));
        let len = match file.metadata() {
            Ok(m) => m.len(),
            Err(e) => return ignored(e.to_string()),
        };
        let mut header = [0u8; HEADER];
        if (&file).read_exact(&mut header).is_err() {
            return ignored("shorter than an entry's header".into());
        }
        let (body, checksum) = match check(&header, kind, key) {
            Ok(h) => h,
            Err(why) => return ignored(why),
        };
        if len != HEADER as u64 + body {
            return ignored(format!(
                "{} bytes of body where the header says {body}: truncated or grown",
                len.saturating_sub(HEADER as u64)
            ));
        }
        if body > max {
            return ignored(format!("a body of {body} bytes, more than {max} could be"));
        }
        // Recently used: the last to be evicted. A read-only cache still
        // serves.
        let _ = file.set_modified(SystemTime::now());
        Opened::Entry(Box::new(Entry {
            file: std::io::BufReader::with_capacity(1 << 16, file),
            left: body,
            hasher: Xxh3::new(),
            checksum,
            path,
        }))
    }

    /// The body stored under `kind` and `key`, read whole and checked.
    pub(crate) fn load(&self, kind: Kind, key: u128, max: u64) -> Found {
        let mut entry = match self.open(kind, key, max) {
            Opened::Entry(e) => e,
            Opened::Missing => return Found::Missing,
            Opened::Ignored(why) => return Found::Ignored(why),
        };
        let mut bytes = Vec::with_capacity(usize::try_from(entry.left()).unwrap_or(0));
        if let Err(e) = entry.read_to_end(&mut bytes) {
            return Found::Ignored(format!("{}: {e}", entry.path.display()));
        }
        match entry.finish() {
            Ok(()) => Found::Body(Body(bytes)),
            Err(why) => Found::Ignored(why),
        }
    }

    /// Stores `body` under `kind` and `key` (`store_with`).
    pub(crate) fn store(&self, kind: Kind, key: u128, body: &[u8]) -> Result<(), String> {
        self.store_with(kind, key, |w| w.write_all(body))
    }

    /// Stores what `write` writes under `kind` and `key`, then evicts past
    /// the cap. A failure only costs the next run the work again, so it
    /// is returned for a note, not raised; an entry larger than the cap
    /// is not kept.
    pub(crate) fn store_with(
        &self,
        kind: Kind,
        key: u128,
        write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
    ) -> Result<(), String> {
        let path = self.path(kind, key);
        let fail = |e: std::io::Error| format!("{}: {e}", path.display());
        std::fs::create_dir_all(&self.dir).map_err(fail)?;
        let mut file = tempfile::Builder::new()
            .prefix(".tmp-")
            .tempfile_in(&self.dir)
            .map_err(fail)?;
        file.write_all(&[0; HEADER]).map_err(fail)?;
        let mut body = Hashing {
            out: std::io::BufWriter::with_capacity(1 << 20, file.as_file_mut()),
            hasher: Xxh3::new(),
            len: 0,
            cap: self.cap.saturating_sub(HEADER as u64),
        };
        write(&mut body).map_err(fail)?;
        body.out.flush().map_err(fail)?;
        let (len, checksum) = (body.len, body.hasher.digest());
        drop(body);
        let mut header = Vec::with_capacity(HEADER);
        header.extend_from_slice(MAGIC);
        header.extend_from_slice(&(kind as u32).to_le_bytes());
        header.extend_from_slice(&key.to_le_bytes());
        header.extend_from_slice(&len.to_le_bytes());
        header.extend_from_slice(&checksum.to_le_bytes());
        use std::io::Seek as _;
        file.rewind().map_err(fail)?;
        file.write_all(&header).map_err(fail)?;
        file.persist(&path).map_err(|e| fail(e.error))?;
        self.evict(&path);
        Ok(())
    }

    /// Removes the least recently used entries until the directory is
    /// within its cap, keeping `keep` (the entry just stored); and any
    /// temporary file a crashed writer left.
    fn evict(&self, keep: &Path) {
        let Ok(dir) = std::fs::read_dir(&self.dir) else {
            return;
        };
        let now = SystemTime::now();
        let mut entries = Vec::new();
        for e in dir.flatten() {
            let name = e.file_name();
            let name = name.to_string_lossy();
            let Ok(meta) = e.metadata() else { continue };
            let modified = meta.modified().unwrap_or(SystemTime::UNIX_EPOCH);
            if name.starts_with(".tmp-") {
                if now.duration_since(modified).unwrap_or_default() > STALE_TEMP {
                    let _ = std::fs::remove_file(e.path());
                }
            } else if meta.is_file() && is_entry_name(&name) {
                entries.push((modified, meta.len(), e.path()));
            }
        }
        let mut total: u64 = entries.iter().map(|e| e.1).sum();
        entries.sort();
        for (_, len, path) in entries {
            if total <= self.cap {
                break;
            }
            if path != keep && std::fs::remove_file(&path).is_ok() {
                total -= len;
            }
        }
    }
}

/// Whether `name` is an entry's file name (nothing else in the directory
/// is ever removed).
fn is_entry_name(name: &str) -> bool {
    let Some(rest) = name.strip_suffix(".bin") else {
        return false;
    };
    let hex = rest
        .strip_prefix("bvh-")
        .or_else(|| rest.strip_prefix("scene-"));
    hex.is_some_and(|h| h.len() == 32 && h.bytes().all(|b| b.is_ascii_hexdigit()))
}

/// A header's body length and checksum, if it is an entry's header for
/// `kind` and `key`.
fn check(header: &[u8; HEADER], kind: Kind, key: u128) -> Result<(u64, u64), String> {
    if &header[..8] != MAGIC {
        return Err("not a glint scene cache entry".into());
    }
    let u64_at = |at: usize| {
        let mut b = [0; 8];
        b.copy_from_slice(&header[at..at + 8]);
        u64::from_le_bytes(b)
    };
    if header[8..12] != (kind as u32).to_le_bytes() || header[12..28] != key.to_le_bytes() {
        return Err("an entry of another kind or key under this name".into());
    }
    Ok((u64_at(28), u64_at(36)))
}

/// The body's writer: counts and hashes what passes, and stops at the
/// cap (an entry larger than the cache is never written whole).
struct Hashing<'f> {
    out: std::io::BufWriter<&'f mut std::fs::File>,
    hasher: Xxh3,
    len: u64,
    cap: u64,
}

impl Write for Hashing<'_> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if self.len + buf.len() as u64 > self.cap {
            return Err(std::io::Error::other(format!(
                "an entry larger than the cache's cap of {} (GLINT_SCENE_CACHE_SIZE)",
                crate::units::human(self.cap + HEADER as u64)
            )));
        }
        let n = self.out.write(buf)?;
        self.hasher.update(&buf[..n]);
        self.len += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn store(dir: &Path, cap: u64) -> Store {
        Store {
            dir: dir.join("scenes"),
            cap,
        }
    }

    #[test]
    fn a_stored_body_loads_and_a_damaged_one_is_ignored() {
        let dir = tempfile::tempdir().expect("temp dir");
        let s = store(dir.path(), 1 << 20);
        assert_eq!(s.load(Kind::Bvh, 7, 1000), Found::Missing);
        let body = b"the body of a cache entry".repeat(3);
        s.store(Kind::Bvh, 7, &body).expect("stored");
        assert!(matches!(s.load(Kind::Bvh, 7, 1000), Found::Body(b) if b.bytes() == body));
        // Another key, another kind: not this entry.
        assert_eq!(s.load(Kind::Bvh, 8, 1000), Found::Missing);
        assert_eq!(s.load(Kind::Scene, 7, 1000), Found::Missing);
        // Longer than the caller allows: ignored, not read whole.
        assert!(matches!(s.load(Kind::Bvh, 7, 10), Found::Ignored(w) if w.contains("more than")));
        let path = s.path(Kind::Bvh, 7);
        let good = std::fs::read(&path).expect("read");
        let mut flipped = good.clone();
        *flipped.last_mut().expect("a body") ^= 4;
        std::fs::write(&path, &flipped).expect("write");
        assert!(matches!(s.load(Kind::Bvh, 7, 1000), Found::Ignored(w) if w.contains("checksum")));
        std::fs::write(&path, &good[..good.len() - 1]).expect("write");
        assert!(matches!(s.load(Kind::Bvh, 7, 1000), Found::Ignored(w) if w.contains("truncated")));
        std::fs::write(&path, &good[..20]).expect("write");
        assert!(matches!(s.load(Kind::Bvh, 7, 1000), Found::Ignored(_)));
        // Another entry's file under this one's name.
        s.store(Kind::Bvh, 9, &body).expect("stored");
        std::fs::copy(s.path(Kind::Bvh, 9), &path).expect("copy");
        assert!(matches!(s.load(Kind::Bvh, 7, 1000), Found::Ignored(w) if w.contains("key")));
        // The next store replaces a damaged entry.
        s.store(Kind::Bvh, 7, &body).expect("stored");
        assert!(matches!(s.load(Kind::Bvh, 7, 1000), Found::Body(b) if b.bytes() == body));
    }

    #[test]
    fn the_cap_evicts_the_least_recently_used() {
        let dir = tempfile::tempdir().expect("temp dir");
        let body = vec![1u8; 1000];
        let entry = (HEADER + body.len()) as u64;
        let s = store(dir.path(), 3 * entry);
        let old = SystemTime::now() - Duration::from_secs(100);
        for key in 1..=3u128 {
            s.store(Kind::Bvh, key, &body).expect("stored");
            let f = std::fs::File::options()
                .write(true)
                .open(s.path(Kind::Bvh, key))
                .expect("open");
            f.set_modified(old + Duration::from_secs(key as u64))
                .expect("touch");
        }
        // Entry 1, the oldest, is used: entry 2 is now the least recent.
        assert!(matches!(s.load(Kind::Bvh, 1, 2000), Found::Body(_)));
        // A file that is not an entry stays whatever its age.
        std::fs::write(s.dir.join("notes.txt"), "mine").expect("write");
        s.store(Kind::Bvh, 4, &body).expect("stored");
        let kept = |k| s.path(Kind::Bvh, k).exists();
        assert!(kept(1) && !kept(2) && kept(3) && kept(4));
        assert!(s.dir.join("notes.txt").exists());
        // An entry past the cap is refused, and nothing is evicted for it.
        let huge = vec![0u8; 4 * entry as usize];
        assert!(s.store(Kind::Bvh, 5, &huge).is_err());
        assert!(kept(1) && kept(3) && kept(4) && !kept(5));
    }

    #[test]
    fn writers_of_one_entry_at_once_leave_a_whole_one() {
        let dir = tempfile::tempdir().expect("temp dir");
        let s = store(dir.path(), 1 << 30);
        let bodies: Vec<Vec<u8>> = (0..8u8)
            .map(|i| vec![i; 200_000 + usize::from(i)])
            .collect();
        std::thread::scope(|scope| {
            let all = &bodies;
            for b in all {
                let s = &s;
                scope.spawn(move || {
                    for _ in 0..5 {
                        s.store(Kind::Scene, 3, b).expect("stored");
                        match s.load(Kind::Scene, 3, 1 << 20) {
                            Found::Body(got) => assert!(all.iter().any(|b| b == got.bytes())),
                            other => panic!("a reader saw {other:?}"),
                        }
                    }
                });
            }
        });
        assert!(
            matches!(s.load(Kind::Scene, 3, 1 << 20), Found::Body(got) if bodies.iter().any(|b| b == got.bytes()))
        );
        let names: Vec<_> = std::fs::read_dir(&s.dir)
            .expect("dir")
            .map(|e| e.expect("entry").file_name())
            .collect();
        assert_eq!(names.len(), 1, "{names:?}");
    }
}
