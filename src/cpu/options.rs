//! What the CPU reference renders with, besides the scene and camera.

use crate::methods::Methods;
use crate::scene::Effects;

/// Arithmetic precision of the CPU reference.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Precision {
    /// Follows the shader's f32 arithmetic, operation for operation.
    #[default]
    F32,
    /// Ground truth for accuracy measurements and golden images.
    F64,
}

/// What the CPU reference renders with, besides the scene and camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CpuOptions {
    /// The colour of rays that hit nothing.
    pub background: [f32; 3],
    /// f32 (the shader's twin) or f64 (ground truth).
    pub precision: Precision,
    /// Robust or naive ray offsets and intersection.
    pub methods: Methods,
    /// Samples, shadow samples, reflection depth, shutter and seed.
    pub effects: Effects,
    /// Whether f32 renders may trace their pixels' rays in packets
    /// (`packet::applies`); off, every ray goes alone. The image is the
    /// same but where a ray meets two surfaces at (nearly) one t, which
    /// of them is kept (`cpu::packet`).
    pub packets: bool,
}

impl Default for CpuOptions {
    fn default() -> Self {
        CpuOptions {
            background: [1.0; 3],
            precision: Precision::F32,
            methods: Methods::Robust,
            effects: Effects::default(),
            packets: true,
        }
    }
}
