//! The shader's algorithm on the CPU, function for function and name for name
//! (`shaders/trace/`), generic over f32 (the shader's twin) and f64.
//! Comments on the why live in the shader; this file stays a mirror of it.

mod hit;
mod scene;
mod shade;
mod traverse;

pub use crate::cpu::real::Ray;
pub use hit::*;
pub use scene::*;
pub use shade::*;
pub use traverse::*;
