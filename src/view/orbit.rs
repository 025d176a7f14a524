//! The viewer's camera: orbit, pan and zoom about a pivot, as a scene
//! `camera` block (eye, look, up, fov), so that what the window shows can
//! be pasted into the scene and rendered again bit for bit.

use glam::{DQuat, DVec3};

use crate::scene::{CameraSpec, Scene};

/// Radians of orbit per pixel dragged.
const ORBIT_PER_PIXEL: f64 = 0.006;
/// Zoom factor per wheel line.
const ZOOM_PER_LINE: f64 = 0.9;

/// The view's camera and how the mouse moves it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    /// Where the camera is and looks.
    pub camera: CameraSpec,
    /// Where orbiting turns about: along the view, at the scene's distance.
    pivot_distance: f64,
}

impl Orbit {
    /// The scene's own camera (the classic one without a block); the
    /// pivot along its view at the distance of the scene's centre.
    pub fn of(scene: &Scene) -> Orbit {
        let camera = scene.camera.unwrap_or(CameraSpec::CLASSIC);
        let b = scene.bounds();
        let distance = if b.is_empty() {
            1.0
        } else {
            (b.centroid() - camera.eye).length().max(1e-6)
        };
        Orbit {
            camera,
            pivot_distance: distance,
        }
    }

    fn forward(&self) -> DVec3 {
        (self.camera.look - self.camera.eye)
            .try_normalize()
            .unwrap_or(DVec3::NEG_Z)
    }

    fn pivot(&self) -> DVec3 {
        self.camera.eye + self.forward() * self.pivot_distance
    }

    /// The camera with its look point at the pivot (the same view).
    fn aimed(&self) -> CameraSpec {
        CameraSpec {
            look: self.pivot(),
            ..self.camera
        }
    }

    /// Turns the eye about the pivot: `dx` pixels about the up axis,
    /// `dy` about the camera's right.
    pub fn orbit(&mut self, dx: f64, dy: f64) {
        let cam = self.aimed();
        let pivot = cam.look;
        let up = cam.up.try_normalize().unwrap_or(DVec3::Y);
        let right = self.forward().cross(up).try_normalize().unwrap_or(DVec3::X);
        let yaw = DQuat::from_axis_angle(up, -dx * ORBIT_PER_PIXEL);
        let pitch = DQuat::from_axis_angle(right, -dy * ORBIT_PER_PIXEL);
        let turn = yaw * pitch;
        let offset = turn * (cam.eye - pivot);
        // Keep clear of looking straight along `up`.
        let along = offset.normalize_or_zero().dot(up).abs();
        if along > 0.995 {
            let offset = yaw * (cam.eye - pivot);
            self.camera = CameraSpec {
                eye: pivot + offset,
                ..cam
            };
            return;
        }
        self.camera = CameraSpec {
            eye: pivot + offset,
            ..cam
        };
    }

    /// Moves eye and pivot across the view: `dx`, `dy` pixels of an image
    /// `height` pixels high.
    pub fn pan(&mut self, dx: f64, dy: f64, height: u32) {
        let cam = self.aimed();
        let up = cam.up.try_normalize().unwrap_or(DVec3::Y);
        let forward = self.forward();
        let right = forward.cross(up).try_normalize().unwrap_or(DVec3::X);
        let true_up = right.cross(forward);
        let scale = 2.0 * self.pivot_distance * (cam.fov.to_radians() / 2.0).tan()
            / f64::from(height.max(1));
        let shift = (-dx * right + dy * true_up) * scale;
        self.camera = CameraSpec {
            eye: cam.eye + shift,
            look: cam.look + shift,
            ..cam
        };
    }

    /// Moves the eye towards the pivot (`lines` > 0) or away.
    pub fn zoom(&mut self, lines: f64) {
        let cam = self.aimed();
        let factor = ZOOM_PER_LINE.powf(lines);
        let distance = (self.pivot_distance * factor).max(1e-9);
        let eye = cam.look - self.forward() * distance;
        self.pivot_distance = distance;
        self.camera = CameraSpec { eye, ..cam };
    }

    /// The camera as a scene block, to paste into the scene file.
    pub fn block(&self) -> String {
        let c = self.camera;
        let v = |p: DVec3| format!("{} {} {}", p.x, p.y, p.z);
        format!(
            "camera eye: {} look: {} up: {} fov: {}",
            v(c.eye),
            v(c.look),
            v(c.up),
            c.fov
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene() -> Scene {
        crate::scene::parse_scene(
            b"1\namb: 0 0 0\nsphere pos: 0 0 -5 rad: 1 dif: 1 1 1 spe: 0 0 0 shi: 1\n",
            "t",
        )
        .unwrap()
    }

    #[test]
    fn orbit_keeps_the_distance_to_the_pivot_and_zoom_changes_it() {
        let mut o = Orbit::of(&scene());
        let pivot = o.pivot();
        assert!((pivot - DVec3::new(0.0, 0.0, -5.0)).length() < 1e-9);
        o.orbit(100.0, 40.0);
        assert!(((o.camera.eye - pivot).length() - 5.0).abs() < 1e-9);
        assert!((o.pivot() - pivot).length() < 1e-9);
        o.zoom(2.0);
        assert!(((o.camera.eye - pivot).length() - 5.0 * 0.81).abs() < 1e-9);
        let before = o.camera;
        o.pan(10.0, 0.0, 480);
        assert!(((o.camera.eye - before.eye) - (o.camera.look - before.look)).length() < 1e-9);
    }

    /// The block parses as a camera block and gives the same camera.
    #[test]
    fn the_printed_block_is_a_camera_block_of_the_same_view() {
        let mut o = Orbit::of(&scene());
        o.orbit(33.0, -12.0);
        let text = format!(
            "1\namb: 0 0 0\n{}\nsphere pos: 0 0 -5 rad: 1 dif: 1 1 1 spe: 0 0 0 shi: 1\n",
            o.block()
        );
        let parsed = crate::scene::parse_scene(text.as_bytes(), "t").unwrap();
        assert_eq!(parsed.camera, Some(o.camera));
    }
}
