//! Mouse camera control on the scene's own camera description: orbit about
//! `look_at` by dragging, pan with the middle button or shift-drag, zoom
//! with the wheel. Editing `CameraDesc` keeps "save scene" exact.

use egui::{PointerButton, Response, Vec2};
use glam::DVec3;

use crate::render::scene_file::CameraDesc;

/// Radians of orbit per point dragged.
const ORBIT_SPEED: f64 = 0.004;
/// Zoom factor per point of wheel scroll.
const ZOOM_SPEED: f64 = 0.002;

/// Applies this frame's drags and scrolls over the image; true if the
/// camera moved. `image_height` is the displayed height in points (pan
/// follows the cursor at the look-at distance).
pub fn camera_input(
    ui: &egui::Ui,
    response: &Response,
    cam: &mut CameraDesc,
    image_height: f32,
) -> bool {
    let mut moved = false;
    let shift = ui.input(|i| i.modifiers.shift);
    let delta = response.drag_delta();
    if delta != Vec2::ZERO {
        if response.dragged_by(PointerButton::Middle)
            || (shift && response.dragged_by(PointerButton::Primary))
        {
            pan(cam, delta, image_height);
            moved = true;
        } else if response.dragged_by(PointerButton::Primary) {
            orbit(cam, delta);
            moved = true;
        }
    }
    if response.hovered() {
        let scroll = ui.input(|i| i.smooth_scroll_delta.y);
        if scroll != 0.0 {
            zoom(cam, (-(scroll as f64) * ZOOM_SPEED).exp());
            moved = true;
        }
    }
    moved
}

fn v(a: [f64; 3]) -> DVec3 {
    DVec3::from(a)
}

/// Turns the camera about `look_at`: horizontal drags about `up`, vertical
/// ones about the image's right axis, stopping short of the poles.
pub fn orbit(cam: &mut CameraDesc, delta: Vec2) {
    let target = v(cam.look_at);
    let up = v(cam.up).normalize();
    let offset = v(cam.position) - target;
    let yaw = glam::DQuat::from_axis_angle(up, -(delta.x as f64) * ORBIT_SPEED);
    let offset = yaw * offset;
    let right = offset.cross(up).normalize_or_zero();
    let mut pitch = -(delta.y as f64) * ORBIT_SPEED;
    // Keep at least ~3° from straight up or down, where `up` would be
    // parallel to the view and the camera undefined.
    let angle = offset.angle_between(up);
    let limit = 0.05;
    pitch = pitch.clamp(limit - angle, std::f64::consts::PI - limit - angle);
    let offset = if right == DVec3::ZERO {
        offset
    } else {
        glam::DQuat::from_axis_angle(right, -pitch) * offset
    };
    cam.position = (target + offset).to_array();
}

/// Moves camera and target together in the image plane.
pub fn pan(cam: &mut CameraDesc, delta: Vec2, image_height: f32) {
    let pos = v(cam.position);
    let target = v(cam.look_at);
    let forward = target - pos;
    let dist = forward.length();
    let right = forward.cross(v(cam.up)).normalize();
    let up = right.cross(forward).normalize();
    // World units per displayed point at the target's distance.
    let per_point =
        2.0 * dist * (cam.fov_y_deg.to_radians() * 0.5).tan() / image_height.max(1.0) as f64;
    let shift = (-right * delta.x as f64 + up * delta.y as f64) * per_point;
    cam.position = (pos + shift).to_array();
    cam.look_at = (target + shift).to_array();
}

/// Scales the distance to `look_at` by `factor`.
pub fn zoom(cam: &mut CameraDesc, factor: f64) {
    let target = v(cam.look_at);
    let offset = v(cam.position) - target;
    let len = offset.length();
    let new_len = (len * factor).clamp(1e-3 * len.max(1e-6), 1e3 * len.max(1e-6));
    cam.position = (target + offset * (new_len / len)).to_array();
}

/// Makes `pivot` the point orbited about, without moving the camera: the
/// camera turns to look at it.
pub fn set_pivot(cam: &mut CameraDesc, pivot: DVec3) {
    if (pivot - v(cam.position)).length() > 1e-9 {
        cam.look_at = pivot.to_array();
    }
}

/// Keeps the view direction and moves the camera so that the box
/// `min`–`max` fills the view: the pivot goes to the box's centre, the
/// camera back until the box's bounding sphere fits the narrower field of
/// view.
pub fn frame_all(cam: &mut CameraDesc, min: DVec3, max: DVec3) {
    let centre = 0.5 * (min + max);
    let radius = (0.5 * (max - min).length()).max(1e-6);
    let dir = (v(cam.position) - v(cam.look_at)).normalize_or(DVec3::Z);
    let half_y = (cam.fov_y_deg.to_radians() * 0.5).clamp(1e-3, 1.55);
    let aspect = cam.width as f64 / cam.height.max(1) as f64;
    let half_x = (half_y.tan() * aspect).atan();
    let dist = radius / half_y.min(half_x).sin();
    cam.look_at = centre.to_array();
    cam.position = (centre + dir * dist * 1.05).to_array();
}

/// Where a world point lands in an image of the camera, in pixels (x right,
/// y down), or `None` behind the camera.
pub fn project(cam: &CameraDesc, point: DVec3) -> Option<(f64, f64)> {
    let pos = v(cam.position);
    let forward = (v(cam.look_at) - pos).normalize();
    let right = forward.cross(v(cam.up)).normalize();
    let up = right.cross(forward);
    let d = point - pos;
    let z = d.dot(forward);
    if z <= 0.0 {
        return None;
    }
    let half = (cam.fov_y_deg.to_radians() * 0.5).tan();
    let (w, h) = (cam.width as f64, cam.height as f64);
    let ndc_x = d.dot(right) / z / (half * w / h);
    let ndc_y = d.dot(up) / z / half;
    Some(((ndc_x + 1.0) * 0.5 * w, (1.0 - ndc_y) * 0.5 * h))
}
