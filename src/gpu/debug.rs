//! VK_EXT_debug_utils messenger that prints validation messages and counts
//! the warnings and errors, so tests can fail on any.

use std::ffi::{c_void, CStr};
use std::sync::atomic::{AtomicU32, Ordering};

use ash::vk;

use super::error::{GpuError, VkResultExt};

pub(crate) struct DebugMessenger {
    loader: ash::ext::debug_utils::Instance,
    messenger: vk::DebugUtilsMessengerEXT,
    // Boxed so the address handed to Vulkan as user data stays put.
    count: Box<AtomicU32>,
}

impl DebugMessenger {
    pub fn new(entry: &ash::Entry, instance: &ash::Instance) -> Result<Self, GpuError> {
        let loader = ash::ext::debug_utils::Instance::new(entry, instance);
        let count = Box::new(AtomicU32::new(0));
        let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(
                vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                    | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
            )
            .message_type(
                vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                    | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                    | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
            )
            .pfn_user_callback(Some(on_message))
            .user_data(&*count as *const AtomicU32 as *mut c_void);
        // SAFETY: `info` is valid; `count` outlives the messenger (destroyed in `destroy`).
        let messenger = unsafe { loader.create_debug_utils_messenger(&info, None) }
            .call("vkCreateDebugUtilsMessengerEXT")?;
        Ok(DebugMessenger {
            loader,
            messenger,
            count,
        })
    }

    pub fn count(&self) -> u32 {
        self.count.load(Ordering::SeqCst)
    }

    /// # Safety
    /// Call once, before the instance is destroyed.
    pub unsafe fn destroy(&self) {
        // SAFETY: the caller guarantees the instance is alive and this runs once.
        unsafe {
            self.loader
                .destroy_debug_utils_messenger(self.messenger, None)
        };
    }
}

unsafe extern "system" fn on_message(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: Vulkan passes a valid callback-data pointer (or null), and
    // `user` is the AtomicU32 registered in `DebugMessenger::new`.
    unsafe {
        let message = data
            .as_ref()
            .filter(|d| !d.p_message.is_null())
            .map(|d| CStr::from_ptr(d.p_message).to_string_lossy())
            .unwrap_or_default();
        eprintln!("vulkan {severity:?}: {message}");
        if let Some(count) = (user as *const AtomicU32).as_ref() {
            count.fetch_add(1, Ordering::SeqCst);
        }
    }
    vk::FALSE
}
