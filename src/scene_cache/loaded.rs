//! A scene file and the model files it names, read, parsed and given
//! smooth normals once, then kept: keyed by the scene file's path and
//! content and by glint's loaders, checked against every model file's
//! content before it is used.

use std::io::Read as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use xxhash_rust::xxh3::Xxh3;

use super::codec::{self, Reader, Writer};
use super::store::{Kind, Opened};
use super::{scene_bytes, SceneCache, MIN_PRIMITIVES};
use crate::scene::Scene;
use crate::timing::Timings;
use crate::Error;

/// The body's layout; a new one is a new key.
const FORMAT: u32 = 1;

/// The source of everything that turns files into a `Scene`, with its
/// path (`tests.rs` holds the list to the directories): a change to any
/// loader is a new key, so a cache never hands back a scene the running
/// glint would not make.
macro_rules! sources {
    ($($p:literal),* $(,)?) => { [$(($p, include_bytes!($p).as_slice())),*] };
}
pub(super) const LOADERS: [(&str, &[u8]); 32] = sources!(
    "../scene/diagnostic.rs",
    "../scene/framed.rs",
    "../scene/mesh.rs",
    "../scene/mod.rs",
    "../scene/model.rs",
    "../scene/obj.rs",
    "../scene/objects.rs",
    "../scene/parse.rs",
    "../scene/settings.rs",
    "../scene/space.rs",
    "../scene/windows.rs",
    "../scene/write.rs",
    "../mesh/build.rs",
    "../mesh/gltf.rs",
    "../mesh/mod.rs",
    "../mesh/mtl.rs",
    "../mesh/obj.rs",
    "../mesh/obj_fast.rs",
    "../mesh/off.rs",
    "../mesh/ply.rs",
    "../mesh/ply_fast.rs",
    "../mesh/ply_layout.rs",
    "../mesh/polygon.rs",
    "../mesh/report.rs",
    "../mesh/source.rs",
    "../mesh/stl.rs",
    "../mesh/text.rs",
    "../input.rs",
    "../material.rs",
    "../number.rs",
    "scene_bytes.rs",
    "loaded.rs",
);

/// Reading an entry back runs at about 1.4 GB/s on the 2-core machine of
/// `docs/benchmarks.md` (a 2M-triangle scene's 368 MB in 258 ms), writing
/// it at about the same (225 ms for the bytes alone): a scene that loaded
/// faster than half that rate (the binary PLY of those triangles, 350 ms)
/// gains less from a hit than its write costs, and is not kept.
const KEEP_BELOW_BYTES_PER_SECOND: f64 = 700e6;

/// Whether a scene that took `load` to load is worth an entry: slow
/// enough to load that reading it back is the faster way.
fn worth_keeping(scene: &Scene, load: Duration) -> bool {
    let bytes =
        scene.triangles.len() as f64 * STORED_TRIANGLE as f64 + scene.spheres.len() as f64 * 112.0;
    load.as_secs_f64() * KEEP_BELOW_BYTES_PER_SECOND > bytes
}

/// A scene not kept: it loads faster than it would read back.
pub(crate) const SKIPPED: &str = "scene cache not kept (loads faster than it reads back)";

/// What `-v` counts: a scene read from the cache, or loaded (and stored).
pub(crate) const HIT: &str = "scene cache hit";
/// See `HIT`.
pub(crate) const MISS: &str = "scene cache miss";
/// An entry found but not used (damaged, or a model file changed).
pub(crate) const IGNORED: &str = "scene cache entries ignored";

/// A file's length and xxh3-128, or `None` where it is not there.
type Content = Option<(u64, u128)>;

impl SceneCache {
    /// `scene::read_scene(path)`, from the cache where an entry for this
    /// file is there, sound, and every model file it names unchanged;
    /// else loaded and stored. Also what `-v` shows of it: `scene key`
    /// and `scene from cache`, or the load's own phases and `scene cache
    /// write`; a hit or a miss. A scene that is not a regular file (a
    /// pipe, a device) is loaded every time.
    pub fn read_scene(&self, path: &Path) -> Result<(Scene, Timings), Error> {
        self.read_scene_with(path, crate::scene::read_scene)
    }

    /// `read_scene`, loading with `load` on a miss (the command line's
    /// shows a progress bar over a big file). A scene is kept where it
    /// has 10,000 primitives or more and loaded slower than it would read
    /// back (`keep_every_scene`: however fast it loaded).
    pub fn read_scene_with(
        &self,
        path: &Path,
        load: impl FnOnce(&Path) -> Result<Scene, Error>,
    ) -> Result<(Scene, Timings), Error> {
        let mut timings = Timings::default();
        let started = SystemTime::now();
        let key = timings.time("scene key", || key(path));
        let Some(key) = key else {
            let scene = timed_load(path, load, &mut timings)?;
            return Ok((scene, timings));
        };
        let found = timings.time("scene from cache", || self.find(key));
        match found {
            Ok(Some(scene)) => {
                timings.count(HIT, 1);
                return Ok((scene, timings));
            }
            Ok(None) => {}
            Err(_) => timings.count(IGNORED, 1),
        }
        timings.count(MISS, 1);
        let start = std::time::Instant::now();
        let scene = timed_load(path, load, &mut timings)?;
        if scene.primitive_count() < MIN_PRIMITIVES {
            // Cheaper to load than to key, write and read back.
        } else if !self.keep_every_scene && !worth_keeping(&scene, start.elapsed()) {
            timings.count(SKIPPED, 1);
        } else {
            timings.time("scene cache write", || {
                if let Some(head) = head(&scene, path, started) {
                    // Not written, the next run loads again: nothing more.
                    let _ = self.store.store_with(Kind::Scene, key, |w| {
                        w.write_all(&(head.len() as u64).to_le_bytes())?;
                        w.write_all(&head)?;
                        scene_bytes::write_triangles(&scene.triangles, w)
                    });
                }
            });
        }
        Ok((scene, timings))
    }

    /// The scene stored under `key`: `Ok(None)` where there is none or a
    /// file its models came from has changed, an error where the entry
    /// is not whole and sound.
    fn find(&self, key: u128) -> codec::Result<Option<Scene>> {
        let mut entry = match self.store.open(Kind::Scene, key, self.store.cap) {
            Opened::Entry(e) => e,
            Opened::Missing => return Ok(None),
            Opened::Ignored(why) => return Err(why),
        };
        let mut len = [0u8; 8];
        entry.read_exact(&mut len).map_err(|e| e.to_string())?;
        let len = u64::from_le_bytes(len);
        if len > entry.left() {
            return Err(format!(
                "a head of {len} bytes in a body of {}",
                entry.left()
            ));
        }
        let mut head = vec![0u8; len as usize];
        entry.read_exact(&mut head).map_err(|e| e.to_string())?;
        let mut r = Reader::new(&head);
        if !unchanged(&mut r)? {
            return Ok(None);
        }
        let (mut scene, count) = scene_bytes::decode(&mut r)?;
        r.end()?;
        if count.checked_mul(STORED_TRIANGLE) != Some(entry.left()) {
            return Err("a triangle count that does not match the body".into());
        }
        scene.triangles = scene_bytes::read_triangles(&mut entry, count, scene.materials.len())?;
        entry.finish()?;
        Ok(Some(scene))
    }
}

/// The size of a triangle as stored.
const STORED_TRIANGLE: u64 = scene_bytes::STORED_SIZE as u64;

/// `load(path)`, its time split into `-v`'s phases.
fn timed_load(
    path: &Path,
    load: impl FnOnce(&Path) -> Result<Scene, Error>,
    timings: &mut Timings,
) -> Result<Scene, Error> {
    let start = std::time::Instant::now();
    let scene = load(path)?;
    for (name, d) in scene.shown_load_phases(start.elapsed()) {
        timings.add(name, d);
    }
    Ok(scene)
}

/// The entry's key: glint's loaders, the path as given and as the disk
/// resolves it (model files are named relative to it), and the file's
/// content. `None` for anything but a regular file.
fn key(path: &Path) -> Option<u128> {
    let meta = std::fs::metadata(path).ok()?;
    if !meta.is_file() {
        return None;
    }
    let (_, content) = content(path).ok()??;
    let mut h = Xxh3::new();
    h.update(b"glint scene");
    h.update(env!("CARGO_PKG_VERSION").as_bytes());
    h.update(&FORMAT.to_le_bytes());
    for (_, source) in LOADERS {
        h.update(&xxhash_rust::xxh3::xxh3_64(source).to_le_bytes());
    }
    let canonical = std::fs::canonicalize(path).ok()?;
    for p in [path, &canonical] {
        let text = p.to_string_lossy();
        h.update(&(text.len() as u64).to_le_bytes());
        h.update(text.as_bytes());
    }
    h.update(&content.to_le_bytes());
    Some(h.digest128())
}

/// A regular file's length and xxh3-128, read a megabyte at a time;
/// `None` where there is no such file.
fn content(path: &Path) -> std::io::Result<Content> {
    let mut file = match std::fs::File::open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e),
    };
    if !file.metadata()?.is_file() {
        return Err(std::io::Error::other("not a regular file"));
    }
    let mut h = Xxh3::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut len = 0u64;
    loop {
        match file.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => {
                h.update(&buf[..n]);
                len += n as u64;
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(Some((len, h.digest128())))
}

/// File systems stamp modifications from a coarse clock (Linux: a
/// scheduler tick, up to 10 ms behind the precise time); a stamp this
/// close before the load began may be a change made during it.
const STAMP_SLACK: Duration = Duration::from_millis(20);

/// Whether `path` may have changed at or after `since` (its content may
/// not be what the load read).
fn changed_since(path: &Path, since: SystemTime) -> bool {
    std::fs::metadata(path)
        .and_then(|m| m.modified())
        .map_or(true, |t| t + STAMP_SLACK >= since)
}

/// The entry's head: every file the scene's models came from with its
/// content, then the scene but its triangles. `None` where it must not be
/// stored: a file changed while it loaded, one that is not a regular
/// file, a path not UTF-8.
fn head(scene: &Scene, path: &Path, started: SystemTime) -> Option<Vec<u8>> {
    let files: Vec<&PathBuf> = scene.meshes.iter().flat_map(|m| &m.files).collect();
    if changed_since(path, started) {
        return None;
    }
    let mut w = Writer::default();
    w.u64(files.len() as u64);
    for f in files {
        let found = content(f).ok()?;
        if found.is_some() && changed_since(f, started) {
            return None;
        }
        w.text(f.to_str()?);
        let (len, hash) = found.map_or((u64::MAX, 0), |c| c);
        w.u64(len);
        w.array(&[hash]);
    }
    scene_bytes::encode(scene, &mut w)?;
    Some(w.0)
}

/// Whether every file the head lists has the content it had.
fn unchanged(r: &mut Reader) -> codec::Result<bool> {
    for _ in 0..r.count(8)? {
        let path = PathBuf::from(r.text()?);
        let len = r.u64()?;
        let hash: Vec<u128> = r.array()?;
        let stored: Content = match hash.as_slice() {
            [_] if len == u64::MAX => None,
            [h] => Some((len, *h)),
            _ => return Err("a file without its hash".into()),
        };
        if content(&path).ok() != Some(stored) {
            return Ok(false);
        }
    }
    Ok(true)
}
