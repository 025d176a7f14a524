//! The scene cache: what glint makes of a scene before its first pixel,
//! kept on disk and found again by content, in the manner of the pipeline
//! cache (`gpu::cache`).
//!
//! - `bvh`: the tree `Bvh::for_render` builds, keyed by an xxh3-128 of
//!   everything the builder reads (the primitives' positions and
//!   velocities in render space, the lights, the motion-blur span) and of
//!   the builder's own source. A second render of the same geometry (the
//!   same scene, a Slurm part of it, a re-run with other pixels or
//!   effects) reads the tree instead of building it.
//! - `loaded`: a scene file and every model file it names, read, parsed
//!   and given smooth normals, keyed by the content of each file.
//! - `store`: entries on disk, written atomically, checked before use,
//!   least recently used first out past a size cap.
//!
//! An entry is a speed-up, never a source of truth: one that is damaged,
//! truncated, of another version or not a sound tree for the scene at
//! hand is ignored (and counted where `-v` shows it) and made again.

mod bvh;
mod codec;
mod loaded;
mod scene_bytes;
mod store;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_loaded;

use std::path::{Path, PathBuf};

use store::Store;

/// The default cap on the cache's size: a few 2M-triangle scenes.
pub const DEFAULT_CAP: u64 = 4 << 30;

/// Scenes with fewer primitives than this build in a few milliseconds:
/// cheaper than hashing and writing them, so they are not cached.
pub(crate) const MIN_PRIMITIVES: usize = 10_000;

/// A directory of cached scenes and trees, and its size cap.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneCache {
    store: Store,
    /// Keep every loaded scene big enough to cache, however fast it
    /// loaded (`keep_every_scene`).
    keep_every_scene: bool,
}

impl SceneCache {
    /// A cache in `dir` holding at most `cap` bytes.
    pub fn new(dir: PathBuf, cap: u64) -> SceneCache {
        SceneCache {
            store: Store { dir, cap },
            keep_every_scene: false,
        }
    }

    /// This cache, keeping every loaded scene of 10,000 primitives or
    /// more: by default one that loaded faster than it would read back
    /// (a binary PLY) is not kept, its tree is.
    pub fn keep_every_scene(self) -> SceneCache {
        SceneCache {
            keep_every_scene: true,
            ..self
        }
    }

    /// The cache the environment asks for: `GLINT_SCENE_CACHE` (a
    /// directory, or `off`), else `$XDG_CACHE_HOME/glint/scenes`, else
    /// `$HOME/.cache/glint/scenes`; capped by `GLINT_SCENE_CACHE_SIZE`
    /// (e.g. `8G`; default 4 GiB). `Ok(None)` when off or there is no
    /// home; an error for a size that is not one.
    pub fn from_env() -> Result<Option<SceneCache>, String> {
        let fix = "set a size such as 8G, or unset it for the default of 4 GiB";
        let cap = match std::env::var("GLINT_SCENE_CACHE_SIZE") {
            Ok(s) => crate::input::parse_size(&s)
                .map_err(|e| format!("GLINT_SCENE_CACHE_SIZE: {e}; {fix}"))?,
            Err(std::env::VarError::NotPresent) => DEFAULT_CAP,
            Err(e) => return Err(format!("GLINT_SCENE_CACHE_SIZE: {e}; {fix}")),
        };
        let dir = match std::env::var_os("GLINT_SCENE_CACHE") {
            Some(v) if v == "off" || v.is_empty() => return Ok(None),
            Some(v) => Some(PathBuf::from(v)),
            None => crate::gpu::cache::glint_cache_home().map(|g| g.join("scenes")),
        };
        Ok(dir.map(|d| SceneCache::new(d, cap)))
    }

    /// Where its entries live.
    pub fn dir(&self) -> &Path {
        &self.store.dir
    }

    /// Its size cap in bytes.
    pub fn cap(&self) -> u64 {
        self.store.cap
    }
}
