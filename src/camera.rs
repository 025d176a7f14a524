//! The camera the renderers trace from: the classic assignment's, at the
//! origin, looking down -z, +y up, image plane at z = -1, one ray through
//! each pixel centre, row 0 at the top; 60 degrees of vertical field of view
//! unless a scene's `camera` block says otherwise (which also moves the
//! scene into this camera's view, `Scene::in_view_space`).

/// Vertical field of view, in degrees.
pub const FOV_Y_DEGREES: f64 = 60.0;
/// Image width unless told otherwise.
pub const DEFAULT_WIDTH: u32 = 640;
/// Image height unless told otherwise.
pub const DEFAULT_HEIGHT: u32 = 480;

/// The classic camera for one image size: at the origin, looking down -z,
/// +y up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Half-extent of the image plane at z = -1: (tan(fov/2) * aspect, tan(fov/2)).
    /// Computed in f64; the shader and the CPU f32 path both use its f32 rounding.
    pub half_extent: [f64; 2],
}

impl Camera {
    /// The classic camera for a `width` x `height` image (60° vertical field).
    pub fn new(width: u32, height: u32) -> Camera {
        Camera::with_fov(width, height, FOV_Y_DEGREES)
    }

    /// As `new`, with a vertical field of view of `fov_y` degrees (a scene's
    /// `camera` block; the view itself is moved into place on the scene,
    /// `Scene::in_view_space`).
    pub fn with_fov(width: u32, height: u32, fov_y: f64) -> Camera {
        let half_y = (fov_y.to_radians() * 0.5).tan();
        let aspect = f64::from(width) / f64::from(height);
        Camera {
            width,
            height,
            half_extent: [half_y * aspect, half_y],
        }
    }

    /// `half_extent` rounded to f32, as the shader reads it.
    pub fn half_extent_f32(&self) -> [f32; 2] {
        [self.half_extent[0] as f32, self.half_extent[1] as f32]
    }
}
