//! The Phong material, below both the scene parser and the model-file
//! readers that make one.

use glam::DVec3;

/// Diffuse and specular reflectance with a Phong exponent, per channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Diffuse reflectance, per channel.
    pub kd: DVec3,
    /// Specular reflectance, per channel (also the reflection weight).
    pub ks: DVec3,
    /// The Phong exponent.
    pub shininess: f64,
}

impl Material {
    /// Its exact bits, for finding equal materials (`-0.0` and `0.0` apart).
    pub fn key(&self) -> [u64; 7] {
        let (d, s) = (self.kd, self.ks);
        [d.x, d.y, d.z, s.x, s.y, s.z, self.shininess].map(f64::to_bits)
    }
}
