//! Which intersection and ray-offset methods a render uses.
//!
//! glint renders with the robust methods. The naive ones exist so the cost
//! and the benefit of robustness can be measured side by side (`glint bench
//! hard`); both backends implement both (`ROBUST` override in the shader,
//! `CpuScene::methods` on the CPU).

use std::fmt;

/// How rays meet surfaces and leave them: robust (the default) or naive
/// (to show what robustness fixes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Methods {
    /// Watertight triangles (Woop et al. 2013), the stable sphere test (Ray
    /// Tracing Gems ch. 7), ulp-space origin offsets (Ray Tracing Gems ch. 6).
    #[default]
    Robust,
    /// Möller-Trumbore with a 1e-6 determinant epsilon, the quadratic-formula
    /// sphere test and a fixed 1e-4 offset along the normal: what most ray
    /// tracers of this assignment do.
    Naive,
}

impl Methods {
    /// Both, robust first.
    pub const ALL: [Methods; 2] = [Methods::Robust, Methods::Naive];

    /// What flags and reports call it.
    pub fn name(self) -> &'static str {
        match self {
            Methods::Robust => "robust",
            Methods::Naive => "naive",
        }
    }
}

impl fmt::Display for Methods {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}
