//! A window to present to (`glint view`): its raw handles, the instance
//! extensions its display needs, and its Vulkan surface.

use std::ffi::{c_char, CStr};
use std::fmt;

use ash::vk;

use super::error::GpuError;

/// A window's raw handles, for a Vulkan surface.
#[derive(Clone, Copy)]
pub struct WindowTarget {
    /// The display connection.
    pub display: raw_window_handle::RawDisplayHandle,
    /// The window.
    pub window: raw_window_handle::RawWindowHandle,
}

// SAFETY: the handles are plain identifiers of a window and its display
// connection; whoever makes a `WindowTarget` keeps the window open for as
// long as any context made with it lives (`glint view` joins its render
// thread before the window closes), and Vulkan's surface calls take them
// from any thread.
unsafe impl Send for WindowTarget {}
// SAFETY: as above; nothing reads through the handles but Vulkan.
unsafe impl Sync for WindowTarget {}

impl fmt::Debug for WindowTarget {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("WindowTarget")
    }
}

/// A context's window surface (`ContextOptions::window`).
pub(crate) struct Surface {
    pub loader: ash::khr::surface::Instance,
    pub raw: vk::SurfaceKHR,
}

impl WindowTarget {
    /// The instance extensions a surface on this display needs, each
    /// checked against what the loader has (`has`).
    pub(crate) fn instance_extensions(
        &self,
        has: &dyn Fn(&CStr) -> bool,
    ) -> Result<&'static [*const c_char], GpuError> {
        let needed = ash_window::enumerate_required_extensions(self.display).map_err(|r| {
            GpuError::NoPresent(format!("this display has no Vulkan surface ({r})"))
        })?;
        for &name in needed {
            // SAFETY: ash_window's names are NUL-terminated statics.
            let name = unsafe { CStr::from_ptr(name) };
            if !has(name) {
                return Err(GpuError::NoPresent(format!(
                    "the Vulkan loader lacks {}",
                    name.to_string_lossy()
                )));
            }
        }
        Ok(needed)
    }

    /// The window's surface, on an instance made with
    /// `instance_extensions`.
    pub(crate) fn surface(
        &self,
        entry: &ash::Entry,
        instance: &ash::Instance,
    ) -> Result<Surface, GpuError> {
        // SAFETY: the handles are a live window's (see the Send impl), and
        // the instance was made with the extensions they need.
        let raw =
            unsafe { ash_window::create_surface(entry, instance, self.display, self.window, None) }
                .map_err(|r| GpuError::NoPresent(format!("vkCreate*SurfaceKHR failed: {r}")))?;
        Ok(Surface {
            loader: ash::khr::surface::Instance::new(entry, instance),
            raw,
        })
    }
}
