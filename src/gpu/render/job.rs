//! What a GPU render is asked to do: its options, the job (an image, some
//! rectangles of it, or one pixel's path), and the tiles it is cut into.

use std::time::Duration;

use crate::features::Features;
use crate::gpu::pipeline::Kernel;
use crate::layout::WORKGROUP_SIZE;
use crate::methods::Methods;
use crate::scene::Effects;

/// Tiles in flight at once.
pub(super) const SLOTS: usize = 2;

/// Output texels are `vec4<f32>`.
pub(super) const TEXEL_BYTES: u64 = 16;

/// What a colour job's texels become on the device before they cross to
/// the host: what the file needs, no padding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Packing {
    /// R, G, B bytes, tightly packed (`shaders/pack.wgsl`; `pack_rgb8`).
    Rgb8,
    /// f32 R, G, B (`shaders/pack_float.wgsl`).
    RgbF32,
}

impl Packing {
    /// How `job`'s texels cross to the host: colour jobs' packed on the
    /// device, 8-bit pixels where `options` ask, else f32 RGB (unless
    /// `read_texels`); probes' as they are.
    pub(super) fn of(job: Job, options: &GpuRenderOptions) -> Option<Packing> {
        let colour = matches!(job, Job::Image(Kernel::Render) | Job::Rects);
        match (colour, options.pack_rgb8, options.read_texels) {
            (true, true, _) => Some(Packing::Rgb8),
            (true, false, false) => Some(Packing::RgbF32),
            (false, ..) | (true, false, true) => None,
        }
    }

    /// Bytes a texel packed.
    pub(super) fn bytes(self) -> u64 {
        match self {
            Packing::Rgb8 => 3,
            Packing::RgbF32 => 12,
        }
    }

    /// Bytes `texels` packed take on the device: whole words.
    pub(super) fn buffer_bytes(self, texels: u64) -> u64 {
        (texels * self.bytes()).next_multiple_of(4)
    }

    /// Invocations of its shader for `texels`: one a word (8-bit) or a
    /// texel (f32).
    pub(super) fn invocations(self, texels: u64) -> u64 {
        match self {
            Packing::Rgb8 => self.buffer_bytes(texels) / 4,
            Packing::RgbF32 => texels,
        }
    }

    /// Its place in `Resources::pack`.
    pub(super) fn index(self) -> usize {
        self as usize
    }

    /// The shader, its name and entry point.
    pub(super) fn shader(self) -> (&'static str, &'static str, &'static std::ffi::CStr) {
        match self {
            Packing::Rgb8 => ("pack", include_str!("../../../shaders/pack.wgsl"), c"pack"),
            Packing::RgbF32 => (
                "pack_float",
                include_str!("../../../shaders/pack_float.wgsl"),
                c"pack_float",
            ),
        }
    }
}
/// Binding indices (the shader's header lists them).
pub(super) const B_FRAME: usize = 0;
pub(super) const B_TILE: usize = 1;
pub(super) const B_OUTPUT: usize = 8;
pub(super) const B_STATE: usize = 10;
pub(super) const B_STATUS: usize = 11;
pub(super) const B_MATERIALS: usize = 12;
pub(super) const B_SKIPS: usize = 13;
/// `Timings` count: tiles whose one-pass try left pixels unfinished and
/// that were redone with the resumable shader (`TileWork::resumable`).
pub const RESUMABLE_REDOS: &str = "resumable redos";

/// A cut tile is redone with its budget divided by this.
pub(super) const BUDGET_BACKOFF: u32 = 8;

pub use crate::gpu::driver::{DEFAULT_PASS_BUDGET, MAX_CHAIN};

/// How the GPU renderer renders: tiles, pass budget and timeout, methods,
/// effects and the shader's features.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuRenderOptions {
    /// Tile edge in pixels; bounds the pixels in one submit.
    pub tile_size: u32,
    /// Loop iterations one shader invocation may run per pass; bounds the
    /// work per pixel in one submit.
    pub pass_budget: u32,
    /// Longest wait for one pass before giving up with an error.
    pub pass_timeout: Duration,
    /// Intersection and offset methods (robust unless measuring them).
    pub methods: Methods,
    /// Sample counts, reflection depth, shutter and seed.
    pub effects: Effects,
    /// What the shader is specialised for: `Features::of` the scene, or
    /// `Features::ALL` for the generic shader.
    pub features: Features,
    /// A cap on every storage binding below the device's own
    /// `maxStorageBufferRange` (tests use it to reach the limit cheaply).
    pub storage_limit: Option<u64>,
    /// Where the device is a CPU, read the hot lists through their device
    /// addresses (`Lists::Address`, where the driver gathers those loads)
    /// or, where they fit, from uniform copies (`Lists::Uniform`); false:
    /// always the storage lists, as on a GPU.
    pub uniform_lists: bool,
    /// A tile's first pass without pixel state (`DriverProfile::one_pass_first`).
    pub one_pass_first: bool,
    /// Colour renders: pack each tile's texels into 8-bit pixels on the
    /// device (`shaders/pack.wgsl`), so the host reads 3 bytes a pixel,
    /// and hand back `Image::Rgb8`. Otherwise colour renders pack f32 RGB
    /// (12 bytes a pixel, `shaders/pack_float.wgsl`).
    pub pack_rgb8: bool,
    /// Float colour renders read the whole `vec4<f32>` texels (16 bytes a
    /// pixel) instead of packing them: what every float render did before
    /// the pack, kept to check that the pack changes no bit.
    pub read_texels: bool,
    /// Packed colour renders: each tile's last copy lands in its place in
    /// one image-sized, persistently mapped readback buffer, so the host
    /// reads the finished image once instead of placing tile by tile
    /// (images up to `GATHER_MAX` bytes packed). False: tile by tile, as
    /// before, kept to check that gathering changes no byte.
    pub gather: bool,
    /// A tile that needs passes after its first has up to this many queued
    /// at once (2, then 4, ... up to it; at most `MAX_CHAIN`), each its own
    /// submission, and the host waits once for them, not once a pass
    /// (`DriverProfile::chain_passes`). 1: a wait every pass.
    pub chain_passes: u32,
}

impl Default for GpuRenderOptions {
    fn default() -> Self {
        GpuRenderOptions {
            // The driver profile's safe default; renders through `Renderer`
            // take the device's (`DriverProfile::tile_size`).
            tile_size: crate::gpu::driver::SAFE_TILE,
            pass_budget: DEFAULT_PASS_BUDGET,
            // A pass is bounded (pass_budget x tile pixels): on lavapipe,
            // 2 cores, a full-budget 512^2 pass takes about 10 s, so 120 s
            // leaves room for a machine that is busy with other work.
            pass_timeout: Duration::from_secs(120),
            methods: Methods::Robust,
            effects: Effects::default(),
            features: Features::ALL,
            storage_limit: None,
            uniform_lists: true,
            one_pass_first: true,
            pack_rgb8: false,
            read_texels: false,
            gather: true,
            chain_passes: 1,
        }
    }
}

/// Most lights a `--pixel` path record lists (a 1 MiB output buffer).
pub(super) const PATH_MAX_LIGHTS: u32 = 21_000;

/// What one run of the tile loop computes.
#[derive(Clone, Copy, Debug)]
pub(super) enum Job {
    /// `Kernel::Render` or `Kernel::ProbeTile` over the whole image.
    Image(Kernel),
    /// `Kernel::Render` over the rectangles `run` is given (none larger
    /// than a tile).
    Rects,
    /// The path record of one pixel.
    Pixel([u32; 2]),
}

/// Where a run's finished texels go: the rect, its texels, and the texels
/// from one row's start to the next.
pub(super) type TileSink<'a> = dyn FnMut(TileRect, &[u8], usize) + 'a;

#[derive(Clone, Copy, Debug)]
pub(super) struct TileRect {
    pub(super) origin: [u32; 2],
    pub(super) size: [u32; 2],
}

/// A tile's progress through its passes.
#[derive(Clone, Copy, Debug)]
pub(super) struct TileWork {
    pub(super) rect: TileRect,
    /// The number of its (first) pass in flight: 1 for its first.
    pub(super) pass: u32,
    /// Its passes in flight, queued back to back (`chain_passes`).
    pub(super) chain: u32,
    pub(super) budget: u32,
    /// Pixels whose work is not finished, as of the last pass read.
    pub(super) left: u32,
    /// Closest-hit and shadow rays the tile's passes cast so far.
    pub(super) rays: [u64; 2],
    /// Whether its passes keep the pixels' state. A render's tiles start
    /// without (`ONE_PASS`): most finish in one pass, and the state's
    /// loads and stores cost Mesa 22.3 up to an eighth of a render's
    /// instructions (test1) even where no pixel pauses. A tile that has pixels left after that
    /// pass is redone from its start with the resumable shader (same
    /// image: the passes are deterministic), and the render's later tiles
    /// start resumable, as do the next render's
    /// (`GpuRenderer::passes_needed`).
    pub(super) resumable: bool,
}

impl TileWork {
    /// A tile before its first pass, at `budget` (at least 1), with `chain`
    /// passes queued at first (1 unless `resumable`).
    pub(super) fn new(rect: TileRect, budget: u32, resumable: bool, chain: u32) -> TileWork {
        TileWork {
            rect,
            pass: 1,
            budget: budget.max(1),
            left: rect.size[0] * rect.size[1],
            rays: [0; 2],
            chain,
            resumable,
        }
    }
}

/// Copies a tile's texels (row-major, rows `stride` texels apart) into
/// their place in an image `width` pixels wide, converting each with `f`.
pub(super) fn place_tile<S, T>(
    rect: TileRect,
    (texels, stride): (&[S], usize),
    width: usize,
    image: &mut [T],
    f: impl Fn(&S) -> T,
) {
    let [x0, y0] = rect.origin.map(|v| v as usize);
    let w = rect.size[0] as usize;
    for row in 0..rect.size[1] as usize {
        let src = &texels[row * stride..row * stride + w];
        let start = (y0 + row) * width + x0;
        for (dst, t) in image[start..start + w].iter_mut().zip(src) {
            *dst = f(t);
        }
    }
}

/// `place_tile` for texels that are already the image's pixels: each row
/// copied whole, or all at once where they span the image's width.
pub(super) fn place_rows<T: Copy>(
    rect: TileRect,
    (texels, stride): (&[T], usize),
    width: usize,
    image: &mut [T],
) {
    let [x0, y0] = rect.origin.map(|v| v as usize);
    let [w, h] = rect.size.map(|v| v as usize);
    if [x0, w, stride] == [0, width, width] {
        // Whole rows: one copy.
        image[y0 * width..(y0 + h) * width].copy_from_slice(&texels[..w * h]);
        return;
    }
    for row in 0..h {
        let src = &texels[row * stride..row * stride + w];
        let start = (y0 + row) * width + x0;
        image[start..start + w].copy_from_slice(src);
    }
}

/// Most bytes a packed image may take to be gathered on the device
/// (`GpuRenderOptions::gather`): the readback buffer holds a second copy of
/// the image the host builds, so larger images (an f32 one over about 4K x
/// 5K) are read tile by tile, into the host's image alone.
pub(super) const GATHER_MAX: u64 = 256 << 20;

/// Bytes of the image-sized readback buffer a packed render of a `width` x
/// `height` image gathers its tiles into (`GpuRenderOptions::gather`), as
/// 8-bit pixels (`rgb8`) or f32 RGB; 0 where it is over `GATHER_MAX` and
/// read tile by tile instead.
pub fn gathered_image_bytes(width: u32, height: u32, rgb8: bool) -> u64 {
    let pack = if rgb8 { Packing::Rgb8 } else { Packing::RgbF32 };
    let bytes = u64::from(width) * u64::from(height) * pack.bytes();
    if bytes <= GATHER_MAX {
        bytes
    } else {
        0
    }
}

/// The bytes of the image-sized readback buffer a `job` gathers into, or
/// `None` where its tiles are read one by one: unpacked texels, probes,
/// `options.gather` off, or an image over `GATHER_MAX` or the device's
/// largest allocation.
pub(super) fn gather_bytes(
    job: Job,
    pack: Option<Packing>,
    options: &GpuRenderOptions,
    [width, height]: [u32; 2],
    max_allocation: u64,
) -> Option<u64> {
    let bytes = gathered_image_bytes(width, height, pack? == Packing::Rgb8);
    let fits = bytes > 0 && bytes <= max_allocation;
    (options.gather && fits && matches!(job, Job::Image(_) | Job::Rects)).then_some(bytes)
}

/// Texels of the largest tile of a `width` x `height` image rendered with
/// `--tile tile_size`: what each slot's tile buffers hold.
pub fn tile_texels(tile_size: u32, width: u32, height: u32) -> u64 {
    let edge = tile_edge(tile_size);
    u64::from(edge.min(width)) * u64::from(edge.min(height))
}

/// The tile edge a `tile_size` gives: at least one workgroup.
pub(super) fn tile_edge(tile_size: u32) -> u32 {
    tile_size.max(WORKGROUP_SIZE)
}

pub(super) fn tiles(width: u32, height: u32, edge: u32) -> Vec<TileRect> {
    let mut out = Vec::new();
    for y in (0..height).step_by(edge as usize) {
        for x in (0..width).step_by(edge as usize) {
            out.push(TileRect {
                origin: [x, y],
                size: [edge.min(width - x), edge.min(height - y)],
            });
        }
    }
    out
}
