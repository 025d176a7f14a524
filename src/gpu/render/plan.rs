//! Where a render's data goes: each list's binding, big lists split over
//! several bindings where one cannot hold them, the lists' binding form
//! (plain, split, uniform copies or device addresses) and the pipeline that
//! reads it, all checked against the device's limits before anything is
//! allocated.

use ash::vk;

use super::job::{GpuRenderOptions, B_MATERIALS, B_OUTPUT, B_SKIPS, B_STATE};
use crate::gpu::bindings::{Lists, BINDINGS};
use crate::gpu::context::DeviceLimits;
use crate::gpu::error::GpuError;
use crate::gpu::pipeline::{Kernel, PipelineKey};
use crate::layout::{
    padded, uniform_copy_bytes, uniform_copy_form, CopyForm, GpuMaterial, GpuScene, GpuTriangle,
    GpuTriangleNormals, GpuWideNode, ADDRESS_LISTS, SPLIT_CHUNKS, SPLIT_FIRST, SPLIT_LISTS,
    UNIFORM_LISTS, UNIFORM_LIST_BYTES,
};

/// The device's limits, storage bindings capped at `storage_limit`.
pub(super) fn capped(mut limits: DeviceLimits, storage_limit: Option<u64>) -> DeviceLimits {
    if let Some(cap) = storage_limit {
        limits.max_storage_range = limits.max_storage_range.min(cap);
    }
    limits
}

/// The pipeline for `kernel` over `scene`; a render's is its tiles' first
/// pass without pixel state unless `resumable` (`TileWork::resumable`).
pub(super) fn key(
    options: &GpuRenderOptions,
    kernel: Kernel,
    lists: Lists,
    scene: &GpuScene,
    uploads: &[Upload],
    resumable: bool,
) -> PipelineKey {
    let triangles = uploads
        .iter()
        .find(|u| u.binding == UNIFORM_LISTS[1].0)
        .map_or(0, |u| u.bytes.len() as u64);
    PipelineKey {
        methods: options.methods,
        features: options.features,
        lists,
        light_skips: !scene.skips.is_empty(),
        corners: lists == Lists::Uniform && uniform_copy_form(1, triangles) == CopyForm::Corners,
        leaf_order: scene.leaf_order(),
        one_pass: kernel == Kernel::Render && !resumable,
        kernel,
    }
}

/// Element sizes of the `SPLIT_LISTS`, in their order.
pub(super) const SPLIT_STRIDES: [u64; 4] = [
    std::mem::size_of::<GpuTriangle>() as u64,
    std::mem::size_of::<GpuTriangleNormals>() as u64,
    std::mem::size_of::<GpuMaterial>() as u64,
    std::mem::size_of::<GpuWideNode>() as u64,
];

/// How one render lays the `SPLIT_LISTS` over bindings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Split {
    /// Some list exceeds one binding: the split layout and shader.
    pub(super) split: bool,
    /// Per list: log2 of the elements per chunk (0 when not split).
    pub(super) shifts: [u32; 4],
    /// Per list: bytes per chunk (the whole list when not split).
    pub(super) chunk_bytes: [u64; 4],
}

impl Split {
    /// The chunking of lists of `lens` bytes under `limits`; an error when a
    /// list needs more than `SPLIT_CHUNKS` bindings.
    pub(super) fn plan(lens: [u64; 4], limits: &DeviceLimits) -> Result<Split, GpuError> {
        let range = limits.max_storage_range;
        if lens.iter().all(|&len| len <= range) {
            return Ok(Split {
                split: false,
                shifts: [0; 4],
                chunk_bytes: lens,
            });
        }
        let mut plan = Split {
            split: true,
            shifts: [0; 4],
            chunk_bytes: [0; 4],
        };
        for (j, (&len, &stride)) in lens.iter().zip(&SPLIT_STRIDES).enumerate() {
            let (binding, name) = SPLIT_LISTS[j];
            // A power of two of elements, so the shader finds the chunk with a
            // shift; at least one element, at most 2^31.
            let elems = (range / stride).max(1);
            let shift = elems.ilog2().min(31);
            let chunk = stride << shift;
            let alignment = limits.storage_offset_alignment;
            if !chunk.is_multiple_of(alignment) {
                return Err(GpuError::Limit {
                    what: format!("a chunk of the {name} buffer (binding {binding})"),
                    needed: chunk,
                    limit_name: "minStorageBufferOffsetAlignment, a multiple of",
                    limit: alignment,
                    unit: " bytes",
                    hint: "render fewer primitives on this device, or use --backend cpu".into(),
                });
            }
            let capacity = chunk * SPLIT_CHUNKS as u64;
            if len > capacity {
                return Err(GpuError::Limit {
                    what: format!(
                        "the {name} buffer (binding {binding}, split over {SPLIT_CHUNKS} bindings)"
                    ),
                    needed: len,
                    limit_name: "maxStorageBufferRange per binding",
                    limit: capacity,
                    unit: " bytes",
                    hint: "render fewer primitives on this device, or use --backend cpu".into(),
                });
            }
            plan.shifts[j] = shift;
            plan.chunk_bytes[j] = chunk;
        }
        Ok(plan)
    }

    /// (list, chunk) when `binding` shows a chunk of a split list.
    pub(super) fn chunk_of(binding: usize) -> Option<(usize, usize)> {
        if let Some(j) = SPLIT_LISTS.iter().position(|&(b, _)| b == binding) {
            return Some((j, 0));
        }
        let extra = binding.checked_sub(SPLIT_FIRST)?;
        let per = SPLIT_CHUNKS - 1;
        (extra < per * SPLIT_LISTS.len()).then(|| (extra / per, extra % per + 1))
    }

    /// The (offset, range) chunk `k` of list `j` of `len` bytes is bound to.
    /// A chunk past the list's end repeats chunk 0: the shader never reads it,
    /// but Vulkan wants every binding of the layout written.
    pub(super) fn range(&self, j: usize, k: usize, len: u64) -> (u64, u64) {
        let chunk = self.chunk_bytes[j];
        let offset = chunk * k as u64;
        if offset < len {
            (offset, chunk.min(len - offset))
        } else {
            (0, chunk.min(len))
        }
    }
}

/// One binding's contents for a render.
pub(super) struct Upload<'a> {
    pub(super) binding: usize,
    pub(super) name: &'static str,
    pub(super) bytes: std::borrow::Cow<'a, [u8]>,
}

pub(super) fn upload<'a>(
    binding: usize,
    name: &'static str,
    bytes: std::borrow::Cow<'a, [u8]>,
) -> Upload<'a> {
    Upload {
        binding,
        name,
        bytes,
    }
}

/// The scene's lists as uploaded, one per binding (the frame and the
/// uniform copies are added by the render).
pub(super) fn scene_uploads(scene: &GpuScene) -> Vec<Upload<'_>> {
    vec![
        upload(2, "spheres", padded(&scene.spheres)),
        upload(3, "triangles", padded(&scene.triangles)),
        upload(4, "normals", padded(&scene.normals)),
        upload(5, "lights", padded(&scene.lights)),
        upload(6, "bvh nodes", padded(&scene.nodes)),
        upload(7, "primitive refs", padded(&scene.prim_refs)),
        upload(9, "velocities", padded(&scene.velocities)),
        upload(B_MATERIALS, "materials", padded(&scene.materials)),
        upload(B_SKIPS, "light skips", padded(&scene.skips)),
    ]
}

/// How a render with `uploads` binds its lists: split over bindings where
/// one cannot hold them, else as `choose_lists` says.
pub(super) fn plan_lists(
    uploads: &[Upload],
    limits: &DeviceLimits,
    forms: ListForms,
) -> Result<(Split, Lists), GpuError> {
    let len_of = |binding: usize| {
        uploads
            .iter()
            .find(|u| u.binding == binding)
            .map_or(0, |u| u.bytes.len() as u64)
    };
    let split = Split::plan(SPLIT_LISTS.map(|(b, _)| len_of(b)), limits)?;
    let lists = choose_lists(
        split.split,
        UNIFORM_LISTS.map(|(b, _)| len_of(b)),
        ADDRESS_LISTS.map(|(b, _)| len_of(b)),
        limits,
        forms,
    );
    Ok((split, lists))
}

/// The largest list the shader reads through its device address: it
/// indexes a list by 4-byte words with a 32-bit index, which SPIR-V's
/// access chains take as signed.
pub(super) const ADDRESS_LIST_MAX_BYTES: u64 = 1 << 33;

/// Which of the faster list forms a render may use: the device's driver
/// profile (`gpu::driver`) and the user (`--storage-lists` allows neither).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct ListForms {
    /// Device addresses (`DriverProfile::address_lists`).
    pub(crate) address: bool,
    /// Uniform copies (`DriverProfile::uniform_copies`).
    pub(crate) uniform: bool,
}

/// Address lists (see "Address lists" in shaders/trace/layout.wgsl) where `forms`
/// allows them, no list is split, the device enabled device addresses and
/// each of `layout::ADDRESS_LISTS` (`address_lens` bytes) is at most
/// `ADDRESS_LIST_MAX_BYTES`. Otherwise uniform lists (see "Uniform lists"
/// in shaders/trace/layout.wgsl) where `forms` allows them, no list is split,
/// each of `layout::UNIFORM_LISTS` (`lens` bytes) fits its copy, and the
/// device binds copies that large and that many uniform buffers; else the
/// plain or split layout.
pub(super) fn choose_lists(
    split: bool,
    lens: [u64; 4],
    address_lens: [u64; 6],
    limits: &DeviceLimits,
    forms: ListForms,
) -> Lists {
    if split {
        return Lists::Split;
    }
    if forms.address
        && limits.device_addresses
        && address_lens.iter().all(|&n| n <= ADDRESS_LIST_MAX_BYTES)
    {
        return Lists::Address;
    }
    // frame, tile and the copies.
    let uniform_buffers = 2 + UNIFORM_LISTS.len() as u32;
    let fits = (0..lens.len()).all(|j| uniform_copy_bytes(j, lens[j]) <= UNIFORM_LIST_BYTES);
    if forms.uniform
        && fits
        && limits.max_uniform_range >= UNIFORM_LIST_BYTES
        && limits.max_uniform_buffers >= uniform_buffers
    {
        Lists::Uniform
    } else {
        Lists::Plain
    }
}

pub(super) fn binding_name(binding: usize) -> &'static str {
    match binding {
        B_OUTPUT => "tile output",
        B_STATE => "pixel state",
        _ => "buffer",
    }
}

/// The bytes each binding of a render would hold, checked against the
/// device's limits before anything is allocated; how the big lists are
/// split over bindings to fit, and how the lists are bound.
pub(super) fn check_limits(
    limits: &DeviceLimits,
    uploads: &[Upload],
    slot_bytes: &[(usize, u64)],
    forms: ListForms,
) -> Result<(Split, Lists), GpuError> {
    let (split, lists) = plan_lists(uploads, limits, forms)?;
    let storage = lists
        .bindings()
        .filter(|&b| BINDINGS[b] == vk::DescriptorType::STORAGE_BUFFER)
        .count() as u32;
    if storage > limits.max_storage_buffers {
        return Err(GpuError::Limit {
            what: if split.split {
                "storage buffers per shader stage (with the big lists split)".into()
            } else {
                "storage buffers per shader stage".into()
            },
            needed: u64::from(storage),
            limit_name: "maxPerStageDescriptorStorageBuffers",
            limit: u64::from(limits.max_storage_buffers),
            unit: "",
            hint: "use another device or --backend cpu".into(),
        });
    }
    let sizes = uploads
        .iter()
        .map(|u| (u.binding, u.name, u.bytes.len() as u64))
        .chain(slot_bytes.iter().map(|&(b, n)| (b, binding_name(b), n)));
    for (binding, name, bytes) in sizes {
        let uniform = BINDINGS[binding] == vk::DescriptorType::UNIFORM_BUFFER;
        let (limit_name, limit) = if uniform {
            ("maxUniformBufferRange", limits.max_uniform_range)
        } else {
            ("maxStorageBufferRange", limits.max_storage_range)
        };
        let hint = match binding {
            B_OUTPUT | B_STATE => "use a smaller --tile".to_string(),
            _ => {
                "render fewer primitives or lights on this device, or use --backend cpu".to_string()
            }
        };
        // A split list's chunks fit by construction (Split::plan).
        let bound = match Split::chunk_of(binding) {
            Some((j, _)) => split.chunk_bytes[j].min(bytes),
            None => bytes,
        };
        if bound > limit {
            return Err(GpuError::Limit {
                what: format!("the {name} buffer (binding {binding})"),
                needed: bytes,
                limit_name,
                limit,
                unit: " bytes",
                hint,
            });
        }
        if bytes > limits.max_allocation {
            return Err(GpuError::Limit {
                what: format!("the {name} buffer (binding {binding})"),
                needed: bytes,
                limit_name: "maxMemoryAllocationSize",
                limit: limits.max_allocation,
                unit: " bytes",
                hint,
            });
        }
    }
    Ok((split, lists))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::uniform_copy;

    fn lavapipe() -> DeviceLimits {
        DeviceLimits {
            max_storage_range: 1 << 27,
            max_uniform_range: 65536,
            max_allocation: 1 << 30,
            max_group_count: [65535; 3],
            max_storage_buffers: 1_000_000,
            max_uniform_buffers: 15,
            cpu: true,
            storage_offset_alignment: 16,
            timestamp_period: 1.0,
            timestamp_bits: 64,
            device_addresses: false,
            subgroup_size: 8,
        }
    }

    const SMALL: [u64; 6] = [48, 48, 64, 16, 36, 32];

    /// `choose_lists` with the forms a device's profile allows: both on a
    /// CPU device (lavapipe's profile: addresses where the device enabled
    /// them), neither on a GPU; `allowed` false as `--storage-lists`.
    fn choose(
        split: bool,
        lens: [u64; 4],
        address: [u64; 6],
        l: &DeviceLimits,
        allowed: bool,
    ) -> Lists {
        let forms = ListForms {
            address: allowed && l.cpu,
            uniform: allowed && l.cpu,
        };
        choose_lists(split, lens, address, l, forms)
    }

    #[test]
    fn uniform_lists_only_on_a_cpu_device_where_every_copy_fits() {
        let fits = [48, UNIFORM_LIST_BYTES, 64, 16];
        let cpu = lavapipe();
        assert_eq!(choose(false, fits, SMALL, &cpu, true), Lists::Uniform);
        assert_eq!(choose(false, fits, SMALL, &cpu, false), Lists::Plain);
        assert_eq!(choose(true, fits, SMALL, &cpu, true), Lists::Split);
        for j in 0..fits.len() {
            let mut lens = fits;
            // Too big in any form (triangles fit past 64 KiB as corners).
            lens[j] = 2 * UNIFORM_LIST_BYTES;
            assert_eq!(
                choose(false, lens, SMALL, &cpu, true),
                Lists::Plain,
                "list {j}"
            );
        }
        let gpu = DeviceLimits { cpu: false, ..cpu };
        assert_eq!(choose(false, fits, SMALL, &gpu, true), Lists::Plain);
        let small = DeviceLimits {
            max_uniform_range: 16384,
            ..cpu
        };
        assert_eq!(choose(false, fits, SMALL, &small, true), Lists::Plain);
        let few = DeviceLimits {
            // frame, tile and four copies: one short.
            max_uniform_buffers: 5,
            ..cpu
        };
        assert_eq!(choose(false, fits, SMALL, &few, true), Lists::Plain);
    }

    #[test]
    fn address_lists_only_where_a_cpu_device_gathers_them_and_indices_reach() {
        let fits = [48, UNIFORM_LIST_BYTES, 64, 16];
        let mesa25 = DeviceLimits {
            device_addresses: true,
            ..lavapipe()
        };
        assert_eq!(choose(false, fits, SMALL, &mesa25, true), Lists::Address);
        // Even where the uniform copies would not fit.
        let big = [1 << 30; 4];
        assert_eq!(choose(false, big, SMALL, &mesa25, true), Lists::Address);
        assert_eq!(choose(false, fits, SMALL, &mesa25, false), Lists::Plain);
        assert_eq!(choose(true, fits, SMALL, &mesa25, true), Lists::Split);
        for j in 0..SMALL.len() {
            let mut lens = SMALL;
            lens[j] = ADDRESS_LIST_MAX_BYTES + 4;
            assert_eq!(
                choose(false, fits, lens, &mesa25, true),
                Lists::Uniform,
                "list {j}"
            );
        }
        let disabled = DeviceLimits {
            device_addresses: false,
            ..mesa25
        };
        assert_eq!(choose(false, fits, SMALL, &disabled, true), Lists::Uniform);
        let gpu = DeviceLimits {
            cpu: false,
            ..mesa25
        };
        assert_eq!(choose(false, fits, SMALL, &gpu, true), Lists::Plain);
    }

    #[test]
    fn a_uniform_copy_is_its_list_zero_padded_to_the_fixed_length() {
        let copy = uniform_copy(0, &[1, 2, 3]).expect("fits");
        assert_eq!(copy.len() as u64, UNIFORM_LIST_BYTES);
        assert_eq!(&copy[..3], &[1, 2, 3]);
        assert!(copy[3..].iter().all(|&b| b == 0));
    }

    /// Triangles past 1,365 go as their corners' nine words back to back,
    /// up to 1,820; more have no copy.
    #[test]
    fn triangles_past_a_whole_copy_go_as_corners() {
        let triangles = |n: usize| -> Vec<GpuTriangle> {
            (0..n)
                .map(|i| GpuTriangle {
                    v: [0, 1, 2].map(|c| [0, 1, 2, 3].map(|k| (100 * i + 10 * c + k) as f32)),
                })
                .collect()
        };
        let whole = triangles(1365);
        let bytes: &[u8] = bytemuck::cast_slice(&whole);
        assert_eq!(uniform_copy_form(1, bytes.len() as u64), CopyForm::Whole);
        assert_eq!(&uniform_copy(1, bytes).expect("fits")[..bytes.len()], bytes);
        let many = triangles(1820);
        let bytes: &[u8] = bytemuck::cast_slice(&many);
        assert_eq!(uniform_copy_form(1, bytes.len() as u64), CopyForm::Corners);
        let copy = uniform_copy(1, bytes).expect("fits as corners");
        let words: &[f32] = bytemuck::cast_slice(&copy);
        for (i, t) in many.iter().enumerate() {
            for c in 0..3 {
                assert_eq!(&words[9 * i + 3 * c..9 * i + 3 * c + 3], &t.v[c][..3]);
            }
        }
        let lens = |triangles: usize| [0, 48 * triangles as u64, 64, 16];
        let cpu = lavapipe();
        assert_eq!(choose(false, lens(1820), SMALL, &cpu, true), Lists::Uniform);
        assert_eq!(choose(false, lens(1821), SMALL, &cpu, true), Lists::Plain);
        let too_many = triangles(1821);
        assert!(uniform_copy(1, bytemuck::cast_slice(&too_many)).is_none());
    }
}
