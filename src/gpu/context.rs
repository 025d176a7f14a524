//! Vulkan instance and device: loading the library at run time (no SDK to
//! build), choosing a device, and the memory allocator. Everything else in
//! `gpu` holds an `Arc<Shared>` so destruction happens once, in order, after
//! the device is idle.

use std::ffi::{c_char, CStr};
use std::fmt;
use std::mem::ManuallyDrop;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

use super::debug::DebugMessenger;
use super::driver::DriverProfile;
use super::error::{GpuError, VkResultExt};
pub use super::limits::DeviceLimits;
pub(crate) use super::surface::Surface;
pub use super::surface::WindowTarget;

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// How to pick a device among those `list_devices` reports.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DeviceSelector {
    /// Position in `glint devices`.
    Index(usize),
    /// Case-insensitive substring of the device name.
    Name(String),
}

impl DeviceSelector {
    /// A number selects by index, anything else by name.
    pub fn parse(s: &str) -> DeviceSelector {
        match s.parse() {
            Ok(i) => DeviceSelector::Index(i),
            Err(_) => DeviceSelector::Name(s.to_string()),
        }
    }
}

impl fmt::Display for DeviceSelector {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DeviceSelector::Index(i) => write!(f, "{i}"),
            DeviceSelector::Name(n) => f.write_str(n),
        }
    }
}

/// Which device to open, and with what.
#[derive(Clone, Debug, Default)]
pub struct ContextOptions {
    /// `None` picks the best device: discrete > integrated > virtual > CPU.
    pub device: Option<DeviceSelector>,
    /// Enable VK_LAYER_KHRONOS_validation when it is installed.
    pub validation: bool,
    /// Keep built pipelines on disk here (`cache::default_dir`); `None`:
    /// every run compiles its pipelines.
    pub pipeline_cache: Option<std::path::PathBuf>,
    /// A window to present to (`glint view`): the instance gets the
    /// surface extensions, the queue is one that can present to it and the
    /// device gets `VK_KHR_swapchain` (`gpu::present`).
    pub window: Option<WindowTarget>,
}

/// A Vulkan device as `glint devices` lists it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceInfo {
    /// Its index in the driver's list (`--device N`).
    pub index: usize,
    /// The device's name.
    pub name: String,
    /// Discrete, integrated, virtual or CPU.
    pub device_type: String,
    /// The driver's name and version.
    pub driver: String,
    /// The Vulkan version it supports.
    pub api_version: String,
    /// How glint renders on it (`gpu::driver`).
    pub profile: DriverProfile,
    /// Vendor, device, driver version and the driver's pipeline cache
    /// UUID: what cached pipelines are keyed by (`gpu::cache`).
    pub cache_key: super::cache::DeviceKey,
    has_compute: bool,
    rank: u8,
}

pub(crate) struct Shared {
    _entry: ash::Entry,
    pub instance: ash::Instance,
    pub physical: vk::PhysicalDevice,
    /// The window's surface, with `VK_KHR_swapchain` enabled on `device`.
    pub surface: Option<Surface>,
    debug: Option<DebugMessenger>,
    pub device: ash::Device,
    pub queue: vk::Queue,
    pub queue_family: u32,
    allocator: ManuallyDrop<Mutex<Allocator>>,
    pub info: DeviceInfo,
    pub limits: DeviceLimits,
    /// `VK_KHR_buffer_device_address`, where `DeviceLimits::device_addresses`.
    pub addresses: Option<ash::khr::buffer_device_address::Device>,
    pub validation: bool,
    /// `VK_EXT_pipeline_creation_feedback` is enabled: a pipeline build
    /// says whether the cache it was given held it.
    pub feedback: bool,
    /// Where built pipelines are kept between runs.
    pub pipeline_cache: Option<super::cache::DiskCache>,
    poisoned: AtomicBool,
}

fn limits_of(inst: &ash::Instance, pd: vk::PhysicalDevice, queue_family: u32) -> DeviceLimits {
    // SAFETY: plain queries on a physical device of this instance.
    let props = unsafe { inst.get_physical_device_properties(pd) };
    let mut max_allocation = 1u64 << 30;
    let mut subgroup_size = 0;
    if props.api_version >= vk::API_VERSION_1_1 {
        let mut m3 = vk::PhysicalDeviceMaintenance3Properties::default();
        let mut sg = vk::PhysicalDeviceSubgroupProperties::default();
        let mut props2 = vk::PhysicalDeviceProperties2::default()
            .push_next(&mut m3)
            .push_next(&mut sg);
        // SAFETY: 1.1 device: the maintenance3 and subgroup chain is valid.
        unsafe { inst.get_physical_device_properties2(pd, &mut props2) };
        max_allocation = m3.max_memory_allocation_size;
        subgroup_size = sg.subgroup_size;
    }
    let l = props.limits;
    DeviceLimits {
        max_storage_range: u64::from(l.max_storage_buffer_range),
        max_uniform_range: u64::from(l.max_uniform_buffer_range),
        max_allocation,
        max_group_count: l.max_compute_work_group_count,
        max_storage_buffers: l.max_per_stage_descriptor_storage_buffers,
        max_uniform_buffers: l.max_per_stage_descriptor_uniform_buffers,
        cpu: props.device_type == vk::PhysicalDeviceType::CPU,
        storage_offset_alignment: l.min_storage_buffer_offset_alignment.max(1),
        timestamp_period: l.timestamp_period,
        // SAFETY: a plain query on a physical device of this instance.
        timestamp_bits: unsafe { inst.get_physical_device_queue_family_properties(pd) }
            .get(queue_family as usize)
            .map_or(0, |f| f.timestamp_valid_bits),
        device_addresses: false,
        subgroup_size,
    }
}

impl Shared {
    pub fn allocator(&self) -> MutexGuard<'_, Allocator> {
        // A panic while allocating cannot leave the allocator half-updated in a
        // way that matters to us; keep using it.
        self.allocator.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// After a timeout or lost device the GPU may still be using resources:
    /// from then on, drops leak instead of destroying (and never wait).
    pub fn poison(&self) {
        self.poisoned.store(true, Ordering::SeqCst);
    }

    pub fn is_poisoned(&self) -> bool {
        self.poisoned.load(Ordering::SeqCst)
    }
}

impl Drop for Shared {
    fn drop(&mut self) {
        if self.is_poisoned() {
            return;
        }
        // SAFETY: every other wrapper holds an Arc<Shared> and is gone by now;
        // we wait for the device, then destroy in reverse creation order.
        unsafe {
            let _ = self.device.device_wait_idle();
            ManuallyDrop::drop(&mut self.allocator);
            self.device.destroy_device(None);
            if let Some(surface) = &self.surface {
                surface.loader.destroy_surface(surface.raw, None);
            }
            if let Some(debug) = &self.debug {
                debug.destroy();
            }
            self.instance.destroy_instance(None);
        }
    }
}

/// A Vulkan device ready to run glint's pipelines.
#[derive(Clone)]
pub struct Context {
    pub(crate) shared: Arc<Shared>,
}

fn load_entry() -> Result<ash::Entry, GpuError> {
    // SAFETY: loading the system Vulkan loader; its initialisation has no
    // preconditions beyond being a genuine loader library.
    unsafe { ash::Entry::load() }.map_err(|e| GpuError::Loader(e.to_string()))
}

struct Instance {
    entry: ash::Entry,
    instance: ash::Instance,
    debug: Option<DebugMessenger>,
    version: u32,
    surface: Option<Surface>,
}

impl Instance {
    /// Tears down what was made when no device came of it.
    ///
    /// # Safety
    /// Nothing made from the instance may be in use.
    unsafe fn destroy(&self) {
        if let Some(surface) = &self.surface {
            surface.loader.destroy_surface(surface.raw, None);
        }
        if let Some(d) = &self.debug {
            d.destroy();
        }
        self.instance.destroy_instance(None);
    }

    /// The window's surface (`ContextOptions::window`).
    fn add_surface(&mut self, window: &WindowTarget) -> Result<(), GpuError> {
        self.surface = Some(window.surface(&self.entry, &self.instance)?);
        Ok(())
    }
}

fn create_instance(validation: bool, window: Option<&WindowTarget>) -> Result<Instance, GpuError> {
    let entry = load_entry()?;
    // SAFETY: plain queries on a loaded entry.
    let (exts, layers, loader_version) = unsafe {
        (
            entry
                .enumerate_instance_extension_properties(None)
                .call("vkEnumerateInstanceExtensionProperties")?,
            entry
                .enumerate_instance_layer_properties()
                .call("vkEnumerateInstanceLayerProperties")?,
            entry
                .try_enumerate_instance_version()
                .call("vkEnumerateInstanceVersion")?
                .unwrap_or(vk::API_VERSION_1_0),
        )
    };
    let has_ext = |name: &CStr| exts.iter().any(|e| e.extension_name_as_c_str() == Ok(name));
    let has_layer = layers
        .iter()
        .any(|l| l.layer_name_as_c_str() == Ok(VALIDATION_LAYER));
    if validation && !has_layer {
        return Err(GpuError::NoValidationLayer);
    }
    let mut ext_names: Vec<*const c_char> = Vec::new();
    let mut flags = vk::InstanceCreateFlags::empty();
    // MoltenVK only shows up through portability enumeration.
    if has_ext(ash::khr::portability_enumeration::NAME) {
        ext_names.push(ash::khr::portability_enumeration::NAME.as_ptr());
        flags |= vk::InstanceCreateFlags::ENUMERATE_PORTABILITY_KHR;
    }
    if let Some(w) = window {
        ext_names.extend_from_slice(w.instance_extensions(&has_ext)?);
    }
    let debug_utils = validation && has_ext(ash::ext::debug_utils::NAME);
    if debug_utils {
        ext_names.push(ash::ext::debug_utils::NAME.as_ptr());
    }
    let layer_names: Vec<*const c_char> = if validation {
        vec![VALIDATION_LAYER.as_ptr()]
    } else {
        Vec::new()
    };
    // 1.1 gives vkGetPhysicalDeviceProperties2 (driver names); glint needs
    // nothing newer, and a 1.0 loader still works.
    let version = if loader_version >= vk::API_VERSION_1_1 {
        vk::API_VERSION_1_1
    } else {
        vk::API_VERSION_1_0
    };
    let app = vk::ApplicationInfo::default()
        .application_name(c"glint")
        .engine_name(c"glint")
        .api_version(version);
    let info = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .flags(flags)
        .enabled_extension_names(&ext_names)
        .enabled_layer_names(&layer_names);
    // SAFETY: every pointer in `info` outlives the call.
    let instance = match unsafe { entry.create_instance(&info, None) } {
        Ok(i) => i,
        // The loader's answer when it finds no driver at all.
        Err(vk::Result::ERROR_INCOMPATIBLE_DRIVER) => return Err(GpuError::NoDevice),
        Err(result) => {
            return Err(GpuError::Vk {
                call: "vkCreateInstance",
                result,
            })
        }
    };
    let debug = if debug_utils {
        Some(DebugMessenger::new(&entry, &instance)?)
    } else {
        None
    };
    Ok(Instance {
        entry,
        instance,
        debug,
        version,
        surface: None,
    })
}

fn describe(instance: &Instance, pd: vk::PhysicalDevice, index: usize) -> DeviceInfo {
    let inst = &instance.instance;
    // SAFETY: `pd` comes from this instance.
    let props = unsafe { inst.get_physical_device_properties(pd) };
    // SAFETY: as above.
    let families = unsafe { inst.get_physical_device_queue_family_properties(pd) };
    let mut driver = format!("driver version {:#x}", props.driver_version);
    if instance.version >= vk::API_VERSION_1_1 && props.api_version >= vk::API_VERSION_1_2 {
        let mut driver_props = vk::PhysicalDeviceDriverProperties::default();
        let mut props2 = vk::PhysicalDeviceProperties2::default().push_next(&mut driver_props);
        // SAFETY: 1.1 instance, 1.2 device: the driver-properties chain is valid.
        unsafe { inst.get_physical_device_properties2(pd, &mut props2) };
        let name = driver_props.driver_name_as_c_str().unwrap_or_default();
        let info = driver_props.driver_info_as_c_str().unwrap_or_default();
        driver = format!("{} {}", name.to_string_lossy(), info.to_string_lossy())
            .trim()
            .to_string();
    }
    let (device_type, rank) = match props.device_type {
        vk::PhysicalDeviceType::DISCRETE_GPU => ("discrete GPU", 4),
        vk::PhysicalDeviceType::INTEGRATED_GPU => ("integrated GPU", 3),
        vk::PhysicalDeviceType::VIRTUAL_GPU => ("virtual GPU", 2),
        vk::PhysicalDeviceType::CPU => ("CPU", 1),
        _ => ("other", 0),
    };
    let v = props.api_version;
    let compute = families
        .iter()
        .position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE))
        .unwrap_or(0) as u32;
    let profile = DriverProfile::of(device_type, &driver, &limits_of(inst, pd, compute));
    DeviceInfo {
        index,
        name: props
            .device_name_as_c_str()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|_| "(unnamed)".into()),
        device_type: device_type.to_string(),
        driver,
        profile,
        cache_key: super::cache::device_key(
            props.vendor_id,
            props.device_id,
            props.driver_version,
            props.pipeline_cache_uuid,
        ),
        api_version: format!(
            "{}.{}.{}",
            vk::api_version_major(v),
            vk::api_version_minor(v),
            vk::api_version_patch(v)
        ),
        has_compute: families
            .iter()
            .any(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE)),
        rank,
    }
}

fn physical_devices(instance: &Instance) -> Result<Vec<vk::PhysicalDevice>, GpuError> {
    // SAFETY: plain query on a live instance.
    unsafe { instance.instance.enumerate_physical_devices() }.call("vkEnumeratePhysicalDevices")
}

/// Every Vulkan device the loader reports, in its order (the indices
/// `--device` takes).
pub fn list_devices() -> Result<Vec<DeviceInfo>, GpuError> {
    let instance = create_instance(false, None)?;
    let devices = physical_devices(&instance).map(|pds| {
        pds.iter()
            .enumerate()
            .map(|(i, &pd)| describe(&instance, pd, i))
            .collect()
    });
    // SAFETY: nothing else was created from this instance.
    unsafe { instance.instance.destroy_instance(None) };
    devices
}

fn choose(devices: &[DeviceInfo], selector: Option<&DeviceSelector>) -> Result<usize, GpuError> {
    let usable = || devices.iter().filter(|d| d.has_compute);
    let found = match selector {
        None => usable()
            .max_by_key(|d| (d.rank, std::cmp::Reverse(d.index)))
            .ok_or(GpuError::NoDevice)?,
        Some(sel @ DeviceSelector::Index(i)) => usable()
            .find(|d| d.index == *i)
            .ok_or_else(|| GpuError::DeviceNotFound(sel.to_string()))?,
        Some(sel @ DeviceSelector::Name(name)) => {
            let name = name.to_lowercase();
            usable()
                .find(|d| d.name.to_lowercase().contains(&name))
                .ok_or_else(|| GpuError::DeviceNotFound(sel.to_string()))?
        }
    };
    Ok(found.index)
}

/// A device created on the chosen physical device: its handles, what it
/// is, its queue family, and which of (device addresses, creation
/// feedback) it enabled.
type Chosen = (
    ash::Device,
    vk::PhysicalDevice,
    DeviceInfo,
    u32,
    (bool, bool),
);

impl Context {
    /// Opens the device `options` chooses, with a compute queue.
    pub fn new(options: &ContextOptions) -> Result<Context, GpuError> {
        let mut instance = create_instance(options.validation, options.window.as_ref())?;
        let chosen = match &options.window {
            Some(w) => instance.add_surface(w),
            None => Ok(()),
        }
        .and_then(|()| Self::with_instance(&instance, options));
        match chosen {
            Ok((device, pd, info, queue_family, extensions)) => Self::finish(
                instance,
                device,
                pd,
                info,
                queue_family,
                extensions,
                options.pipeline_cache.clone(),
            ),
            Err(e) => {
                // SAFETY: no device was created; tear down what we made.
                unsafe { instance.destroy() };
                Err(e)
            }
        }
    }

    fn with_instance(instance: &Instance, options: &ContextOptions) -> Result<Chosen, GpuError> {
        let pds = physical_devices(instance)?;
        let infos: Vec<DeviceInfo> = pds
            .iter()
            .enumerate()
            .map(|(i, &pd)| describe(instance, pd, i))
            .collect();
        let index = choose(&infos, options.device.as_ref())?;
        let pd = pds[index];
        let inst = &instance.instance;
        // SAFETY: plain queries on a physical device of this instance.
        let (families, dev_exts) = unsafe {
            (
                inst.get_physical_device_queue_family_properties(pd),
                inst.enumerate_device_extension_properties(pd)
                    .call("vkEnumerateDeviceExtensionProperties")?,
            )
        };
        // With a window, the family must present to it too.
        let presents = |i: usize| match &instance.surface {
            // SAFETY: a plain query on a physical device and surface of
            // this instance.
            Some(s) => unsafe {
                s.loader
                    .get_physical_device_surface_support(pd, i as u32, s.raw)
            }
            .unwrap_or(false),
            None => true,
        };
        // Prefer a compute-only family (async compute on discrete GPUs).
        let family = families
            .iter()
            .enumerate()
            .filter(|(i, f)| f.queue_flags.contains(vk::QueueFlags::COMPUTE) && presents(*i))
            .min_by_key(|(_, f)| f.queue_flags.contains(vk::QueueFlags::GRAPHICS))
            .map(|(i, _)| i as u32);
        let family = match (family, &instance.surface) {
            (Some(f), _) => f,
            (None, None) => return Err(GpuError::NoDevice),
            (None, Some(_)) => {
                return Err(GpuError::NoPresent(format!(
                    "no compute queue of {} can present to the window",
                    infos[index].name
                )))
            }
        };
        let mut ext_names: Vec<*const c_char> = Vec::new();
        if instance.surface.is_some() {
            if !dev_exts
                .iter()
                .any(|e| e.extension_name_as_c_str() == Ok(ash::khr::swapchain::NAME))
            {
                return Err(GpuError::NoPresent(format!(
                    "{} has no VK_KHR_swapchain",
                    infos[index].name
                )));
            }
            ext_names.push(ash::khr::swapchain::NAME.as_ptr());
        }
        // The spec requires enabling portability_subset wherever it is listed.
        if dev_exts
            .iter()
            .any(|e| e.extension_name_as_c_str() == Ok(ash::khr::portability_subset::NAME))
        {
            ext_names.push(ash::khr::portability_subset::NAME.as_ptr());
        }
        // Device addresses, only where they pay (`DriverProfile::address_lists`): the
        // extension, its feature and 64-bit integers (the shader converts a
        // 64-bit address to a pointer).
        let addresses = infos[index].profile.address_lists
            && instance.version >= vk::API_VERSION_1_1
            && dev_exts
                .iter()
                .any(|e| e.extension_name_as_c_str() == Ok(ash::khr::buffer_device_address::NAME))
            && {
                let mut bda = vk::PhysicalDeviceBufferDeviceAddressFeatures::default();
                let mut features = vk::PhysicalDeviceFeatures2::default().push_next(&mut bda);
                // SAFETY: 1.1 instance: the features2 chain is valid.
                unsafe { inst.get_physical_device_features2(pd, &mut features) };
                features.features.shader_int64 == vk::TRUE && bda.buffer_device_address == vk::TRUE
            };
        if addresses {
            ext_names.push(ash::khr::buffer_device_address::NAME.as_ptr());
        }
        let feedback = dev_exts
            .iter()
            .any(|e| e.extension_name_as_c_str() == Ok(ash::ext::pipeline_creation_feedback::NAME));
        if feedback {
            ext_names.push(ash::ext::pipeline_creation_feedback::NAME.as_ptr());
        }
        let priorities = [1.0f32];
        let queues = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(family)
            .queue_priorities(&priorities)];
        let core = vk::PhysicalDeviceFeatures::default().shader_int64(addresses);
        let mut bda =
            vk::PhysicalDeviceBufferDeviceAddressFeatures::default().buffer_device_address(true);
        let mut info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queues)
            .enabled_extension_names(&ext_names)
            .enabled_features(&core);
        if addresses {
            info = info.push_next(&mut bda);
        }
        // SAFETY: every pointer in `info` outlives the call.
        let device = unsafe { inst.create_device(pd, &info, None) }.call("vkCreateDevice")?;
        Ok((
            device,
            pd,
            infos[index].clone(),
            family,
            (addresses, feedback),
        ))
    }

    fn finish(
        instance: Instance,
        device: ash::Device,
        physical: vk::PhysicalDevice,
        info: DeviceInfo,
        queue_family: u32,
        (addresses, feedback): (bool, bool),
        pipeline_cache: Option<std::path::PathBuf>,
    ) -> Result<Context, GpuError> {
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.instance.clone(),
            device: device.clone(),
            physical_device: physical,
            debug_settings: Default::default(),
            buffer_device_address: addresses,
            allocation_sizes: Default::default(),
        });
        let allocator = match allocator {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: nothing was created on the device yet.
                unsafe {
                    device.destroy_device(None);
                    instance.destroy();
                }
                return Err(GpuError::Alloc {
                    what: "the allocator".into(),
                    message: e.to_string(),
                });
            }
        };
        // SAFETY: the family was requested with one queue at device creation.
        let queue = unsafe { device.get_device_queue(queue_family, 0) };
        let validation = instance.debug.is_some();
        let info_key = info.cache_key;
        let mut limits = limits_of(&instance.instance, physical, queue_family);
        limits.device_addresses = addresses;
        let addresses = addresses
            .then(|| ash::khr::buffer_device_address::Device::new(&instance.instance, &device));
        Ok(Context {
            shared: Arc::new(Shared {
                _entry: instance.entry,
                instance: instance.instance,
                physical,
                surface: instance.surface,
                debug: instance.debug,
                device,
                queue,
                queue_family,
                allocator: ManuallyDrop::new(Mutex::new(allocator)),
                info,
                limits,
                addresses,
                validation,
                feedback,
                pipeline_cache: pipeline_cache
                    .map(|dir| super::cache::DiskCache::new(dir, info_key)),
                poisoned: AtomicBool::new(false),
            }),
        })
    }

    /// The device opened.
    pub fn info(&self) -> &DeviceInfo {
        &self.shared.info
    }

    /// The limits glint checks a scene's buffers against.
    pub fn limits(&self) -> &DeviceLimits {
        &self.shared.limits
    }

    /// Whether the validation layer and its messenger are active.
    pub fn validation_active(&self) -> bool {
        self.shared.validation
    }

    /// Validation warnings and errors reported so far (0 when inactive).
    pub fn validation_messages(&self) -> u32 {
        self.shared.debug.as_ref().map_or(0, DebugMessenger::count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dev(index: usize, rank: u8, name: &str) -> DeviceInfo {
        DeviceInfo {
            index,
            name: name.into(),
            device_type: String::new(),
            driver: String::new(),
            api_version: String::new(),
            profile: DriverProfile::unknown(),
            cache_key: [0; 28],
            has_compute: true,
            rank,
        }
    }

    #[test]
    fn prefers_discrete_then_lowest_index_and_honours_selectors() {
        let devices = [
            dev(0, 1, "llvmpipe"),
            dev(1, 3, "Intel"),
            dev(2, 4, "NVIDIA H100"),
        ];
        assert_eq!(choose(&devices, None).unwrap(), 2);
        let sel = DeviceSelector::parse("llvm");
        assert_eq!(choose(&devices, Some(&sel)).unwrap(), 0);
        assert_eq!(
            choose(&devices, Some(&DeviceSelector::parse("1"))).unwrap(),
            1
        );
        assert!(matches!(
            choose(&devices, Some(&DeviceSelector::parse("7"))),
            Err(GpuError::DeviceNotFound(_))
        ));
        assert!(matches!(choose(&[], None), Err(GpuError::NoDevice)));
    }
}
