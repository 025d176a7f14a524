//! Every driver- and device-specific decision glint makes, in one place: a
//! `DriverProfile` made from the device's type, driver and limits, each
//! choice with the measurement behind it and a safe default for drivers
//! never measured. No other file looks at a driver's name; `glint devices`
//! and `glint check` print the profile each device gets.
//!
//! Measured drivers: Mesa's lavapipe (llvmpipe) 22.3 and 25.0 on 2-core
//! x86-64 CI machines, and NVIDIA's 580 driver on an H200 (no display, so
//! no watchdog). Everything else takes the safe defaults: 512-pixel tiles,
//! 2048 loop iterations a pass, the storage lists.

use std::fmt;

use super::limits::DeviceLimits;

/// The default loop iterations per invocation per pass. llvmpipe ends every
/// loop of an invocation once it has run 65535 iterations of all its loops
/// together (counted per 8-lane vector, so divergent lanes can add up to 8
/// times one lane's count); 2048 per lane plus one traversal stays below that
/// in the worst case. Measured on lavapipe: SIGGRAPH needs one pass at
/// 640x480, and passes add under 3% where one would do. On the H200 every
/// classic scene and the 2M grid finish in one pass at 1920x1080 with
/// 2048-pixel tiles, and a larger budget (16384) changed no GPU time, so
/// every device keeps it: it bounds each submission, which a desktop GPU's
/// watchdog (about 2 s on Windows) needs.
pub const DEFAULT_PASS_BUDGET: u32 = 2048;

/// Tile edge for devices never measured, and for CPU devices. On lavapipe
/// (2 cores), 640x480, median of 5 dispatch times: SIGGRAPH 548/511/413/359
/// ms at tiles of 128/256/512/1024, `table` flat (~330-350 ms): each tile
/// ends with one core idle, and 512 keeps each submit short.
pub const SAFE_TILE: u32 = 512;

/// Most passes of a tile queued before the host waits
/// (`GpuRenderOptions::chain_passes`): each of the renderer's tile slots
/// holds this many command buffers, fences and status copies.
pub const MAX_CHAIN: u32 = 8;

/// Tile edge for hardware GPUs whose limits hold a whole tile's state. On
/// the H200 at 1920x1080 (GPU time by timestamps, two runs each): the 2M
/// triangle grid 11.2 / 5.5 / 3.6 / 2.9 ms at tiles of 256 / 512 / 1024 /
/// 2048, `table` 1.25 / 0.67 / 0.49 / 0.43 ms: a 512 tile leaves most of
/// the GPU idle while each of its 12 passes drains.
pub const GPU_TILE: u32 = 2048;

/// Bytes of pixel state a resumable pass keeps per pixel
/// (`layout::GpuPixelState`), for sizing tiles against the limits.
const STATE_BYTES: u64 = 128;

/// What kind of device and driver glint recognised.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriverKind {
    /// Mesa's llvmpipe (lavapipe), with its major version.
    Llvmpipe {
        /// Mesa's major version.
        mesa: u32,
    },
    /// Another device of `VK_PHYSICAL_DEVICE_TYPE_CPU` (SwiftShader, ...).
    OtherCpu,
    /// A discrete or integrated GPU.
    Gpu,
    /// Virtual or other: never measured.
    Unknown,
}

/// How glint renders on one device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DriverProfile {
    /// Which device and driver it is.
    pub kind: DriverKind,
    /// Default tile edge (`--tile`): pixels per pass.
    pub tile_size: u32,
    /// Default loop iterations per invocation per pass (`--pass-budget`).
    pub pass_budget: u32,
    /// Read the hot lists through device addresses (`Lists::Address`).
    pub address_lists: bool,
    /// Read the hot lists from uniform copies where they fit
    /// (`Lists::Uniform`).
    pub uniform_copies: bool,
    /// A tile's first pass runs the shader without pixel state
    /// (`ONE_PASS`), redone resumable only where pixels are left.
    pub one_pass_first: bool,
    /// Most passes of a tile queued before one host wait
    /// (`GpuRenderOptions::chain_passes`); 1: a wait every pass.
    pub chain_passes: u32,
    /// `--backend auto` renders on the CPU reference instead: the device
    /// renders the same image slower on the same cores.
    pub prefer_cpu_reference: bool,
    /// The device's buffers are host memory (a CPU device, an integrated
    /// GPU): a render's device copies count against the host's free memory
    /// before it starts (`memory::MemoryNeed`).
    pub host_memory: bool,
}

impl DriverProfile {
    /// The profile for a device of `device_type` (as `DeviceInfo` names it)
    /// whose driver reports itself as `driver`, with `limits`.
    pub fn of(device_type: &str, driver: &str, limits: &DeviceLimits) -> DriverProfile {
        let kind = match (device_type, mesa_llvmpipe(driver)) {
            ("CPU", Some(mesa)) => DriverKind::Llvmpipe { mesa },
            ("CPU", None) => DriverKind::OtherCpu,
            ("discrete GPU" | "integrated GPU", _) => DriverKind::Gpu,
            _ => DriverKind::Unknown,
        };
        let cpu = matches!(kind, DriverKind::Llvmpipe { .. } | DriverKind::OtherCpu);
        DriverProfile {
            kind,
            tile_size: match kind {
                DriverKind::Gpu => gpu_tile(limits),
                _ => SAFE_TILE,
            },
            pass_budget: DEFAULT_PASS_BUDGET,
            // llvmpipe from Mesa 25 loads the eight lanes of a
            // device-address read with one gather instruction. Measured
            // with a chain of dependent 14-word loads (the shape of a node
            // visit): Mesa 25.0 took 41-55 ms through device addresses
            // against 70-99 ms from a uniform buffer and 160-190 ms from a
            // storage buffer; Mesa 22.3 took 570 ms through device
            // addresses (a call per lane) against 74-84 and 190-250. GPUs
            // keep their storage lists (their caches serve them; unmeasured
            // against addresses).
            address_lists: matches!(kind, DriverKind::Llvmpipe { mesa } if mesa >= 25),
            // A CPU device reads uniform buffers faster than storage ones:
            // SIGGRAPH 1,712 -> 1,208 M instructions on Mesa 25. A GPU's
            // uniform path is for uniform (same for every lane) reads,
            // which a traversal's are not.
            uniform_copies: cpu,
            // Mesa 22.3 loads and stores the pixel state lane by lane even
            // where no pixel pauses (test1 -12.6% instructions without
            // it, `table` -3.8%); on the H200 every tile finishes in its
            // first pass at the profile's tile and budget, so the try never
            // costs a redo there. Kept everywhere: it only removes work.
            one_pass_first: true,
            // Each chained pass is still its own submission, bounded as
            // before, so a watchdog sees nothing longer; what goes is the
            // host's round trip between passes, while the device idles.
            // Unmeasured on a GPU (on the H200 every tile finished in one
            // pass); on lavapipe the device is the host's cores and the
            // queued passes run when they would have anyway.
            chain_passes: match kind {
                DriverKind::Unknown => 1,
                _ => MAX_CHAIN,
            },
            // The image is the same (the CPU f32 twin follows the shader),
            // and lavapipe is slower than the CPU reference on the same
            // cores (docs/cli.md, "Choosing a device").
            prefer_cpu_reference: cpu,
            host_memory: cpu || device_type == "integrated GPU",
        }
    }

    /// The safe defaults, for a device glint knows nothing of.
    pub fn unknown() -> DriverProfile {
        DriverProfile {
            kind: DriverKind::Unknown,
            tile_size: SAFE_TILE,
            pass_budget: DEFAULT_PASS_BUDGET,
            address_lists: false,
            uniform_copies: false,
            one_pass_first: true,
            chain_passes: 1,
            prefer_cpu_reference: false,
            host_memory: true,
        }
    }

    /// Each decision, its value and why, for `glint devices` and `glint
    /// check`'s reports.
    pub fn decisions(&self) -> Vec<(&'static str, String)> {
        let on = |b: bool| if b { "yes" } else { "no" }.to_string();
        vec![
            ("tile", format!("{} px", self.tile_size)),
            ("pass budget", self.pass_budget.to_string()),
            ("address lists", on(self.address_lists)),
            ("uniform copies", on(self.uniform_copies)),
            ("one-pass first try", on(self.one_pass_first)),
            ("passes per wait", self.chain_passes.to_string()),
            (
                "auto prefers the CPU reference",
                on(self.prefer_cpu_reference),
            ),
            ("buffers in host memory", on(self.host_memory)),
        ]
    }
}

impl fmt::Display for DriverKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DriverKind::Llvmpipe { mesa } => write!(f, "llvmpipe (Mesa {mesa})"),
            DriverKind::OtherCpu => write!(f, "software device"),
            DriverKind::Gpu => write!(f, "hardware GPU"),
            DriverKind::Unknown => write!(f, "unknown device (safe defaults)"),
        }
    }
}

/// The largest tile up to `GPU_TILE` whose output and pixel state fit the
/// device's storage bindings.
fn gpu_tile(limits: &DeviceLimits) -> u32 {
    let mut tile = GPU_TILE;
    while tile > SAFE_TILE {
        let pixels = u64::from(tile) * u64::from(tile);
        if pixels * STATE_BYTES <= limits.max_storage_range
            && pixels * STATE_BYTES <= limits.max_allocation
        {
            break;
        }
        tile /= 2;
    }
    tile
}

/// Mesa's major version, where `driver` is llvmpipe's
/// ("llvmpipe Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)").
fn mesa_llvmpipe(driver: &str) -> Option<u32> {
    driver
        .strip_prefix("llvmpipe Mesa ")?
        .split('.')
        .next()?
        .parse()
        .ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits(storage: u64) -> DeviceLimits {
        DeviceLimits {
            max_storage_range: storage,
            max_uniform_range: 65536,
            max_allocation: 1 << 40,
            max_group_count: [65535; 3],
            max_storage_buffers: 32,
            max_uniform_buffers: 16,
            cpu: false,
            storage_offset_alignment: 16,
            timestamp_period: 1.0,
            timestamp_bits: 64,
            device_addresses: false,
            subgroup_size: 8,
        }
    }

    #[test]
    fn device_addresses_only_on_llvmpipe_from_mesa_25() {
        let of = |driver: &str| DriverProfile::of("CPU", driver, &limits(1 << 27));
        assert!(of("llvmpipe Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)").address_lists);
        assert!(of("llvmpipe Mesa 26.1.0 (LLVM 19.1.7)").address_lists);
        assert!(!of("llvmpipe Mesa 22.3.6 (LLVM 15.0.6)").address_lists);
        assert!(!of("llvmpipe Mesa 24.2.8-1 (LLVM 19.1.4)").address_lists);
        assert!(!of("driver version 0x1").address_lists);
        let gpu = DriverProfile::of("discrete GPU", "NVIDIA 580.159.04", &limits(u64::MAX));
        assert!(!gpu.address_lists && !gpu.uniform_copies && !gpu.prefer_cpu_reference);
    }

    #[test]
    fn tiles_grow_on_gpus_as_far_as_their_limits_hold_the_state() {
        let gpu = |storage| DriverProfile::of("discrete GPU", "x", &limits(storage)).tile_size;
        assert_eq!(gpu(u64::from(u32::MAX)), 2048);
        assert_eq!(gpu(1 << 28), 1024);
        assert_eq!(gpu(1 << 20), SAFE_TILE);
        let lavapipe = DriverProfile::of("CPU", "llvmpipe Mesa 22.3.6", &limits(1 << 27));
        assert_eq!(
            (lavapipe.tile_size, lavapipe.pass_budget),
            (SAFE_TILE, DEFAULT_PASS_BUDGET)
        );
        let unknown = DriverProfile::of("virtual GPU", "x", &limits(u64::MAX));
        assert_eq!(unknown.kind, DriverKind::Unknown);
        assert_eq!(unknown.tile_size, SAFE_TILE);
    }
}
