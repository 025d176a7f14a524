//! Pipelines kept on disk between runs: a real driver's compile of a
//! specialised pipeline costs hundreds of milliseconds (the H200's first
//! builds: 300-500 ms each), lavapipe's tens. Each pipeline's
//! `VkPipelineCache` data is a file under `$XDG_CACHE_HOME/glint/pipelines`
//! (else `~/.cache/glint/pipelines`), keyed by the device (vendor, device,
//! driver version and the driver's own cache UUID) and by a hash of the
//! SPIR-V and entry point. A file that is corrupt, truncated or from
//! another device or driver is ignored (and replaced), never handed to the
//! driver: each carries its keys and a CRC of its data.

use std::io::Write as _;
use std::path::{Path, PathBuf};

/// What identifies a device and driver for cached pipelines.
pub type DeviceKey = [u8; 28];

const MAGIC: &[u8; 8] = b"GLINTPC1";
/// Magic, device key, shader hash, data length, CRC.
const HEADER: usize = 8 + 28 + 8 + 8 + 4;
/// `VkPipelineCacheHeaderVersionOne`: what an empty cache's data holds.
const VK_HEADER: usize = 32;
/// No pipeline cache is larger; a file claiming more is corrupt.
const MAX_DATA: u64 = 256 << 20;

/// Where cached pipelines live: `GLINT_PIPELINE_CACHE` (a directory, or
/// `off`), else `$XDG_CACHE_HOME/glint/pipelines`, else
/// `$HOME/.cache/glint/pipelines`; `None` when off or there is no home.
pub fn default_dir() -> Option<PathBuf> {
    match std::env::var_os("GLINT_PIPELINE_CACHE") {
        Some(v) if v == "off" || v.is_empty() => return None,
        Some(v) => return Some(PathBuf::from(v)),
        None => {}
    }
    Some(glint_cache_home()?.join("pipelines"))
}

/// Where glint keeps what it caches: `$XDG_CACHE_HOME/glint`, else
/// `$HOME/.cache/glint`; `None` without either.
pub(crate) fn glint_cache_home() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CACHE_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(base.join("glint"))
}

/// The device key from the device's properties.
pub fn device_key(
    vendor: u32,
    device: u32,
    driver_version: u32,
    cache_uuid: [u8; 16],
) -> DeviceKey {
    let mut key = [0u8; 28];
    key[..4].copy_from_slice(&vendor.to_le_bytes());
    key[4..8].copy_from_slice(&device.to_le_bytes());
    key[8..12].copy_from_slice(&driver_version.to_le_bytes());
    key[12..].copy_from_slice(&cache_uuid);
    key
}

/// A 64-bit FNV-1a hash of a pipeline's SPIR-V and entry point.
pub fn shader_hash(words: &[u32], entry: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let bytes = words
        .iter()
        .flat_map(|w| w.to_le_bytes())
        .chain(entry.iter().copied());
    for b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// One device's directory of cached pipelines.
#[derive(Clone, Debug)]
pub struct DiskCache {
    dir: PathBuf,
    device: DeviceKey,
}

/// What `DiskCache::load` found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Loaded {
    /// The cached pipeline data.
    Data(Vec<u8>),
    /// No cache file yet.
    Missing,
    /// A file that is not a valid cache for this device and shader.
    Ignored(String),
}

impl DiskCache {
    /// A cache in `dir` for `device`.
    pub fn new(dir: PathBuf, device: DeviceKey) -> DiskCache {
        DiskCache { dir, device }
    }

    fn path(&self, shader: u64) -> PathBuf {
        let id: String = self.device[..12]
            .iter()
            .chain(&self.device[12..20])
            .map(|b| format!("{b:02x}"))
            .collect();
        self.dir.join(format!("{id}-{shader:016x}.bin"))
    }

    /// The cached data for `shader`, checked against its keys and CRC.
    pub fn load(&self, shader: u64) -> Loaded {
        let path = self.path(shader);
        let bytes = match read_bounded(&path) {
            Ok(Some(b)) => b,
            Ok(None) => return Loaded::Missing,
            Err(e) => return Loaded::Ignored(format!("{}: {e}", path.display())),
        };
        match parse(&bytes, &self.device, shader) {
            Ok(data) => Loaded::Data(data.to_vec()),
            Err(why) => Loaded::Ignored(format!("{}: {why}", path.display())),
        }
    }

    /// Writes `data` for `shader`, whole or not at all (a temporary file
    /// renamed into place); a failure to write only costs the next run a
    /// compile, so it is returned for a note, not raised.
    pub fn store(&self, shader: u64, data: &[u8]) -> Result<(), String> {
        // A driver that keeps no pipelines (Mesa 22.3's lavapipe) returns
        // the 32-byte header alone: nothing worth a file.
        if data.len() <= VK_HEADER || data.len() as u64 > MAX_DATA {
            return Ok(());
        }
        let path = self.path(shader);
        let fail = |e: std::io::Error| format!("{}: {e}", path.display());
        std::fs::create_dir_all(&self.dir).map_err(fail)?;
        let mut file = tempfile::NamedTempFile::new_in(&self.dir).map_err(fail)?;
        let mut bytes = Vec::with_capacity(HEADER + data.len());
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&self.device);
        bytes.extend_from_slice(&shader.to_le_bytes());
        bytes.extend_from_slice(&(data.len() as u64).to_le_bytes());
        bytes.extend_from_slice(&crc32fast::hash(data).to_le_bytes());
        bytes.extend_from_slice(data);
        file.write_all(&bytes).map_err(fail)?;
        file.persist(&path).map_err(|e| fail(e.error))?;
        Ok(())
    }
}

fn read_bounded(path: &Path) -> std::io::Result<Option<Vec<u8>>> {
    use std::io::Read;
    let file = match std::fs::File::open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e),
    };
    let mut bytes = Vec::new();
    file.take(HEADER as u64 + MAX_DATA + 1)
        .read_to_end(&mut bytes)?;
    Ok(Some(bytes))
}

fn parse<'a>(bytes: &'a [u8], device: &DeviceKey, shader: u64) -> Result<&'a [u8], String> {
    if bytes.len() < HEADER || &bytes[..8] != MAGIC {
        return Err("not a glint pipeline cache".into());
    }
    if &bytes[8..36] != device {
        return Err("made by another device or driver".into());
    }
    let word = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap_or([0; 8]));
    if word(36) != shader {
        return Err("for another shader".into());
    }
    let len = word(44);
    let crc = u32::from_le_bytes(bytes[52..56].try_into().unwrap_or([0; 4]));
    let data = &bytes[HEADER..];
    if data.len() as u64 != len {
        return Err(format!(
            "{} bytes of data where the header says {len}",
            data.len()
        ));
    }
    if crc32fast::hash(data) != crc {
        return Err("its data does not match its checksum".into());
    }
    Ok(data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stored_data_loads_and_anything_else_is_ignored() {
        let dir = tempfile::tempdir().expect("temp dir");
        let key = device_key(1, 2, 3, [7; 16]);
        let cache = DiskCache::new(dir.path().join("p"), key);
        assert_eq!(cache.load(9), Loaded::Missing);
        let data = [b"a vulkan pipeline cache's data: header and body".as_slice(); 2].concat();
        cache.store(9, &data).expect("stored");
        assert_eq!(cache.load(9), Loaded::Data(data.clone()));
        // A driver's empty cache (its header alone) is not kept.
        cache.store(11, &[0; 32]).expect("nothing to store");
        assert_eq!(cache.load(11), Loaded::Missing);
        // Another shader, another driver version: not this file's.
        assert_eq!(cache.load(10), Loaded::Missing);
        let other = DiskCache::new(dir.path().join("p"), device_key(1, 2, 4, [7; 16]));
        assert_eq!(other.load(9), Loaded::Missing);
        // Corrupt data, a truncated file, garbage: ignored, saying why.
        let path = cache.path(9);
        let mut bytes = std::fs::read(&path).expect("read");
        let last = bytes.len() - 1;
        bytes[last] ^= 1;
        std::fs::write(&path, &bytes).expect("write");
        assert!(matches!(cache.load(9), Loaded::Ignored(w) if w.contains("checksum")));
        std::fs::write(&path, &bytes[..20]).expect("write");
        assert!(matches!(cache.load(9), Loaded::Ignored(_)));
        std::fs::write(&path, b"\0\0\0").expect("write");
        assert!(matches!(cache.load(9), Loaded::Ignored(_)));
        // A copied file under another device's name.
        cache.store(9, &data).expect("stored");
        std::fs::copy(&path, other.path(9)).expect("copy");
        assert!(matches!(other.load(9), Loaded::Ignored(w) if w.contains("another device")));
    }
}
