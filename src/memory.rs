//! What a render will need in host memory, said before it starts (`-v`,
//! `glint info`) and checked against what the machine has, so that a huge
//! image fails at once with the numbers instead of after minutes, or by the
//! kernel's OOM killer.
//!
//! Counted: the f32 image (12 bytes a pixel, tiles are read back into it
//! directly), its 8-bit copy for encoding (3 bytes a pixel; a CPU render to
//! 8-bit pixels makes them band by band and counts them alone), and on the GPU
//! path the packed scene, its staging copy, the tile buffers, the image-sized
//! buffer the tiles are gathered into (host memory on every device) and, on a
//! device without memory of its own (lavapipe and other CPU devices), the
//! device copies too. The parsed scene and its BVH already exist when this is asked
//! and are not counted.

use std::fmt;

use crate::layout::{GpuPixelState, GpuScene};

/// Bytes a render needs beyond what is already allocated, by part.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MemoryNeed {
    /// (what, bytes), in the order they are allocated.
    pub parts: Vec<(&'static str, u64)>,
}

/// Bytes of the f32 image per pixel.
pub const IMAGE_BYTES_PER_PIXEL: u64 = 12;
/// Bytes of the 8-bit copy per pixel.
pub const RGB8_BYTES_PER_PIXEL: u64 = 3;

impl MemoryNeed {
    /// The image alone: what every backend needs.
    pub fn image(width: u32, height: u32) -> MemoryNeed {
        let pixels = u64::from(width) * u64::from(height);
        MemoryNeed {
            parts: vec![
                ("image", pixels * IMAGE_BYTES_PER_PIXEL),
                ("8-bit copy", pixels * RGB8_BYTES_PER_PIXEL),
            ],
        }
    }

    /// The 8-bit image alone: a CPU render made straight into bytes.
    pub fn rgb8(width: u32, height: u32) -> MemoryNeed {
        let pixels = u64::from(width) * u64::from(height);
        MemoryNeed {
            parts: vec![("8-bit image", pixels * RGB8_BYTES_PER_PIXEL)],
        }
    }

    /// The GPU path's share, for `scene` packed, tiles of `tile_texels`
    /// (`gpu::tile_texels`); `host_device` when the device's memory is the
    /// host's (a CPU device such as lavapipe, or an integrated GPU).
    pub fn add_gpu(&mut self, scene: &GpuScene, tile_texels: u64, host_device: bool) {
        let lists = scene.list_bytes();
        let total: u64 = lists.iter().sum();
        let largest = lists.iter().copied().max().unwrap_or(0);
        // The leaf order's ids stay on the host only.
        let ids = 4 * scene.scene_triangles.len() as u64;
        self.parts.push(("packed scene", total + ids));
        self.parts.push(("staging", largest));
        let texels = tile_texels;
        // Two slots, each with output + readback texels and pixel state.
        let per_texel = 16 + 16 + std::mem::size_of::<GpuPixelState>() as u64;
        let slots = 2 * texels * per_texel;
        if host_device {
            self.parts.push(("device copies", total + slots));
        } else {
            self.parts.push(("tile readback", 2 * texels * 16));
        }
    }

    /// The image-sized readback buffer a GPU render gathers its tiles into
    /// (`gpu::gathered_image_bytes`: `bytes`, 0 where there is none).
    pub fn add_gathered(&mut self, bytes: u64) {
        self.parts.push(("image readback", bytes));
    }

    /// All the parts' bytes together.
    pub fn total(&self) -> u64 {
        self.parts.iter().map(|p| p.1).sum()
    }

    /// `Err` with the message when the need exceeds `available` bytes.
    pub fn check(&self, available: Option<u64>) -> Result<(), crate::Error> {
        match available {
            Some(available) if self.total() > available => Err(crate::Error::OutOfMemory {
                needed: self.total(),
                available,
                parts: self.to_string(),
            }),
            _ => Ok(()),
        }
    }
}

impl fmt::Display for MemoryNeed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", human(self.total()))?;
        let parts: Vec<String> = self
            .parts
            .iter()
            .filter(|p| p.1 > 0)
            .map(|(name, bytes)| format!("{name} {}", human(*bytes)))
            .collect();
        if !parts.is_empty() {
            write!(f, " ({})", parts.join(", "))?;
        }
        Ok(())
    }
}

/// What the kernel can give this process without swapping: `MemAvailable`
/// of /proc/meminfo, or less when the process's memory cgroup (v2 or v1, as
/// containers and CI runners set) has a limit closer to its usage; `None`
/// where neither can be read (not Linux).
pub fn available() -> Option<u64> {
    let system = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|info| parse_meminfo(&info));
    match (system, cgroup_headroom()) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// The most resident memory this process has held so far (`VmHWM` of
/// /proc/self/status); `None` where it cannot be read (not Linux).
pub fn peak_resident() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// The memory cgroup's limit minus its usage, when it has a limit.
fn cgroup_headroom() -> Option<u64> {
    let read =
        |path: String| -> Option<u64> { std::fs::read_to_string(path).ok()?.trim().parse().ok() };
    let groups = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    for line in groups.lines() {
        let mut fields = line.splitn(3, ':');
        let (_, controllers, path) = (fields.next()?, fields.next()?, fields.next()?);
        // Inside a cgroup namespace the group is the mount's root.
        let (files, dirs) = if controllers.is_empty() {
            (
                ["memory.max", "memory.current"],
                [format!("/sys/fs/cgroup{path}"), "/sys/fs/cgroup".into()],
            )
        } else if controllers.split(',').any(|c| c == "memory") {
            (
                ["memory.limit_in_bytes", "memory.usage_in_bytes"],
                [
                    format!("/sys/fs/cgroup/memory{path}"),
                    "/sys/fs/cgroup/memory".into(),
                ],
            )
        } else {
            continue;
        };
        for dir in dirs {
            // v2 writes "max" and v1 a huge number for no limit; both fail or
            // exceed any real usage here.
            if let (Some(limit), Some(usage)) = (
                read(format!("{dir}/{}", files[0])),
                read(format!("{dir}/{}", files[1])),
            ) {
                if limit < 1 << 60 {
                    return Some(limit.saturating_sub(usage));
                }
                break;
            }
        }
    }
    None
}

fn parse_meminfo(info: &str) -> Option<u64> {
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

pub use crate::units::human;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_need_counts_both_copies() {
        let need = MemoryNeed::image(1000, 500);
        assert_eq!(need.total(), 500_000 * 15);
        assert_eq!(
            need.to_string(),
            "7.2 MiB (image 5.7 MiB, 8-bit copy 1.4 MiB)"
        );
    }

    #[test]
    fn an_8_bit_cpu_render_counts_its_bytes_alone() {
        let need = MemoryNeed::rgb8(1000, 500);
        assert_eq!(need.total(), 500_000 * 3);
        assert_eq!(need.to_string(), "1.4 MiB (8-bit image 1.4 MiB)");
    }

    /// The gathered image counts as the pixels the file needs, and not at
    /// all where it is too large to gather (read tile by tile).
    #[test]
    fn a_gathered_image_counts_its_packed_pixels() {
        use crate::gpu::gathered_image_bytes;
        assert_eq!(gathered_image_bytes(1920, 1080, true), 1920 * 1080 * 3);
        assert_eq!(gathered_image_bytes(1920, 1080, false), 1920 * 1080 * 12);
        assert_eq!(gathered_image_bytes(16384, 16384, false), 0);
        let mut need = MemoryNeed::image(1000, 500);
        need.add_gathered(gathered_image_bytes(1000, 500, true));
        assert_eq!(need.total(), 500_000 * (15 + 3));
    }

    #[test]
    fn a_need_past_what_is_available_is_refused() {
        let need = MemoryNeed::image(100, 100);
        assert!(need.check(Some(150_000)).is_ok());
        let err = need.check(Some(149_999)).unwrap_err().to_string();
        assert!(err.contains("146.5 KiB"), "{err}");
        assert!(need.check(None).is_ok());
    }

    #[test]
    fn meminfo_is_read_in_kib() {
        let info = "MemTotal:       24000000 kB\nMemFree: 1 kB\nMemAvailable:   2048 kB\n";
        assert_eq!(parse_meminfo(info), Some(2048 * 1024));
        assert_eq!(parse_meminfo("MemTotal: 5 kB\n"), None);
    }

    #[test]
    fn human_sizes() {
        assert_eq!(human(999), "999 bytes");
        assert_eq!(human(1536), "1.5 KiB");
        assert_eq!(human(3 << 30), "3.0 GiB");
    }
}
