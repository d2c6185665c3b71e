//! The viewer's camera controls (thesis §4.2.1-4.2.2: "All the camera controls are implemented
//! inside the Camera class through a keyboard and mouse listener ... Every time an update
//! happens, the Film is reset"). They edit the scene's own [`Camera`] (origin, target, field of
//! view, lens), so that the camera the viewer shows is exactly one a scene file can hold.

use glam::{Quat, Vec3};

use crate::arrays::SceneArrays;
use crate::arrays::trace::intersect_closest;
use crate::scene::{Camera, CameraBasis};

/// How far one second of a held key moves the camera, as a fraction of the scene's size.
const MOVE_PER_SECOND: f32 = 0.25;
/// Radians of turn per pixel of mouse drag.
const LOOK_PER_PIXEL: f32 = 0.004;
/// Pitch stays this far (radians) from straight up or down, where the basis degenerates.
const PITCH_MARGIN: f32 = 0.02;

/// One frame's camera input: movement axes in [-1, 1] (right, up, forward), a look drag in
/// pixels, and discrete steps of the lens settings.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CameraInput {
    pub strafe: f32,
    pub lift: f32,
    pub forward: f32,
    pub drag: (f32, f32),
    /// Steps of the field of view (+: wider).
    pub fov_steps: i32,
    /// Steps of the focal distance (+: farther).
    pub focus_steps: i32,
    /// Steps of the lens radius (+: larger aperture).
    pub aperture_steps: i32,
    /// Speed factor (Shift: faster, Ctrl: slower).
    pub speed: f32,
}

/// Applies one frame of `input`, lasting `dt` seconds, to `camera` in a scene of size
/// `scene_size` (the diagonal of its bounds). Returns whether the camera changed.
pub fn apply(camera: &mut Camera, input: &CameraInput, dt: f32, scene_size: f32) -> bool {
    let before = camera.clone();
    let basis = CameraBasis::new(camera);
    let speed = if input.speed > 0.0 { input.speed } else { 1.0 };
    let step = MOVE_PER_SECOND * scene_size.max(1e-3) * dt * speed;
    let offset = (basis.right * input.strafe
        + camera.up.normalize() * input.lift
        + basis.forward * input.forward)
        * step;
    if offset != Vec3::ZERO {
        camera.origin += offset;
        camera.target += offset;
    }
    if input.drag != (0.0, 0.0) {
        look(camera, input.drag, speed);
    }
    if input.fov_steps != 0 {
        let fov = camera.fov_degrees * 1.05f32.powi(input.fov_steps);
        camera.fov_degrees = fov.clamp(5.0, 150.0);
    }
    if input.aperture_steps != 0 {
        // From a pinhole, the first step opens the lens to 0.1 % of the scene size.
        let r = if camera.lens_radius > 0.0 {
            camera.lens_radius * 1.25f32.powi(input.aperture_steps)
        } else if input.aperture_steps > 0 {
            1e-3 * scene_size
        } else {
            0.0
        };
        camera.lens_radius = if r < 2e-4 * scene_size { 0.0 } else { r };
        // A lens needs a focal distance: the target's, until one is chosen.
        if camera.lens_radius > 0.0 && camera.focal_distance.is_none() && !camera.autofocus {
            camera.focal_distance = Some((camera.target - camera.origin).dot(basis.forward));
        }
    }
    if input.focus_steps != 0 {
        let f = camera.focal_distance.unwrap_or(basis.focal_distance);
        camera.focal_distance = Some((f * 1.05f32.powi(input.focus_steps)).max(1e-3));
        camera.autofocus = false;
    }
    *camera != before
}

/// Turns the view by a mouse drag: yaw about the camera's up vector, pitch about its right
/// vector, keeping the distance to the target.
fn look(camera: &mut Camera, (dx, dy): (f32, f32), speed: f32) {
    let up = camera.up.normalize();
    let to_target = camera.target - camera.origin;
    let distance = to_target.length();
    let forward = to_target / distance;
    let right = forward.cross(up).normalize();
    let k = LOOK_PER_PIXEL * speed.sqrt();
    let yawed = Quat::from_axis_angle(up, -dx * k) * forward;
    // The pitch is limited so that the view never turns past straight up or down.
    let pitch_now = forward.dot(up).clamp(-1.0, 1.0).asin();
    let limit = std::f32::consts::FRAC_PI_2 - PITCH_MARGIN;
    let pitch = (pitch_now - dy * k).clamp(-limit, limit) - pitch_now;
    let right = Quat::from_axis_angle(up, -dx * k) * right;
    let turned = (Quat::from_axis_angle(right, pitch) * yawed).normalize();
    camera.target = camera.origin + turned * distance;
}

/// The focal distance (along the view axis, as kernels/render/camera.cl measures it) that
/// puts the surface seen through the centre of pixel (x, y) in focus; None where that ray
/// leaves the scene.
pub fn focus_at(arrays: &SceneArrays, width: u32, height: u32, x: f32, y: f32) -> Option<f32> {
    let c = arrays.camera();
    let (w, h) = (width as f32, height as f32);
    let sx = (2.0 * x / w - 1.0) * c.tan_half_fov * (w / h);
    let sy = (1.0 - 2.0 * y / h) * c.tan_half_fov;
    let dir = (c.forward + sx * c.right + sy * c.up).normalize();
    let hit = intersect_closest(arrays, c.origin, dir, f32::INFINITY)?;
    Some(hit.t * dir.dot(c.forward))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            origin: Vec3::new(0.0, 1.0, 3.0),
            target: Vec3::new(0.0, 1.0, 0.0),
            up: Vec3::Y,
            fov_degrees: 40.0,
            lens_radius: 0.0,
            focal_distance: None,
            autofocus: false,
        }
    }

    #[test]
    fn moving_forward_keeps_the_view_direction_and_no_input_changes_nothing() {
        let mut c = camera();
        assert!(!apply(&mut c, &CameraInput::default(), 0.1, 4.0));
        assert_eq!(c, camera());
        let input = CameraInput {
            forward: 1.0,
            ..Default::default()
        };
        assert!(apply(&mut c, &input, 1.0, 4.0));
        // 0.25 of the scene size per second, along -z.
        assert!(
            (c.origin - Vec3::new(0.0, 1.0, 2.0)).length() < 1e-6,
            "{c:?}"
        );
        assert!((c.target - Vec3::new(0.0, 1.0, -1.0)).length() < 1e-6);
        let fast = CameraInput {
            strafe: 1.0,
            speed: 4.0,
            ..Default::default()
        };
        apply(&mut c, &fast, 1.0, 4.0);
        assert!((c.origin.x - 4.0).abs() < 1e-5, "{c:?}");
    }

    #[test]
    fn looking_turns_about_up_and_stops_short_of_the_pole() {
        let mut c = camera();
        let right = CameraInput {
            drag: (100.0, 0.0),
            ..Default::default()
        };
        apply(&mut c, &right, 0.0, 4.0);
        let f = (c.target - c.origin).normalize();
        assert!(
            f.x > 0.3 && f.y.abs() < 1e-6,
            "a drag to the right turns right: {f}"
        );
        assert!(((c.target - c.origin).length() - 3.0).abs() < 1e-5);
        let up = CameraInput {
            drag: (0.0, -1e5),
            ..Default::default()
        };
        apply(&mut c, &up, 0.0, 4.0);
        let f = (c.target - c.origin).normalize();
        assert!(
            f.y > 0.99 && f.y < 1.0 - 1e-4,
            "pitch is clamped below the pole: {f}"
        );
        assert!(CameraBasis::new(&c).right.is_finite());
    }

    #[test]
    fn lens_steps_open_and_close_the_aperture_and_focus_is_explicit() {
        let mut c = camera();
        let open = CameraInput {
            aperture_steps: 1,
            ..Default::default()
        };
        apply(&mut c, &open, 0.0, 4.0);
        assert!((c.lens_radius - 4e-3).abs() < 1e-9);
        assert_eq!(
            c.focal_distance,
            Some(3.0),
            "a new lens focuses on the target"
        );
        apply(
            &mut c,
            &CameraInput {
                aperture_steps: -10,
                ..open
            },
            0.0,
            4.0,
        );
        assert_eq!(
            c.lens_radius, 0.0,
            "closing far enough gives a pinhole again"
        );
        c.autofocus = true;
        let focus = CameraInput {
            focus_steps: 2,
            ..Default::default()
        };
        apply(&mut c, &focus, 0.0, 4.0);
        assert!(!c.autofocus);
        assert!((c.focal_distance.unwrap() - 3.0 * 1.05f32.powi(2)).abs() < 1e-5);
        let wider = CameraInput {
            fov_steps: 100,
            ..Default::default()
        };
        apply(&mut c, &wider, 0.0, 4.0);
        assert_eq!(c.fov_degrees, 150.0);
    }
}
