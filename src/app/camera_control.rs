//! Mouse and keyboard camera control on the scene's own camera
//! description: orbit about `look_at` by dragging, pan with the middle
//! button or shift-drag, zoom with the wheel; walk with W/A/S/D (Q/E down
//! and up, Shift faster) and look around with a right-drag, to move inside
//! a room. Editing `CameraDesc` keeps "save scene" exact.

use egui::{PointerButton, Response, Vec2};
use glam::DVec3;

use crate::render::scene_file::CameraDesc;

/// Radians of orbit per point dragged.
const ORBIT_SPEED: f64 = 0.004;
/// Zoom factor per point of wheel scroll.
const ZOOM_SPEED: f64 = 0.002;
/// Walking speed: the distance to the pivot per second (so it suits any
/// scene's scale); Shift walks four times as fast.
const WALK_SPEED: f64 = 0.6;

/// The walking keys: forward, back, left, right, down, up.
pub const WALK_KEYS: [egui::Key; 6] = [
    egui::Key::W,
    egui::Key::S,
    egui::Key::A,
    egui::Key::D,
    egui::Key::Q,
    egui::Key::E,
];

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
    if delta != Vec2::ZERO && response.dragged_by(PointerButton::Secondary) {
        look(cam, delta);
        moved = true;
    }
    if response.hovered() {
        let scroll = ui.input(|i| i.smooth_scroll_delta.y);
        if scroll != 0.0 {
            zoom(cam, (-(scroll as f64) * ZOOM_SPEED).exp());
            moved = true;
        }
    }
    // Walking: while the image is hovered and no text field takes the keys
    // (Ctrl+S and the like stay shortcuts).
    if response.hovered() && !ui.ctx().egui_wants_keyboard_input() {
        let (keys, dt, command, fast) = ui.input(|i| {
            (
                WALK_KEYS.map(|k| i.key_down(k)),
                i.stable_dt.min(0.1) as f64,
                i.modifiers.command || i.modifiers.alt,
                i.modifiers.shift,
            )
        });
        if !command && keys.contains(&true) {
            let axis = |plus: bool, minus: bool| plus as i32 as f64 - minus as i32 as f64;
            let step = WALK_SPEED * dt * if fast { 4.0 } else { 1.0 };
            walk(
                cam,
                axis(keys[0], keys[1]) * step,
                axis(keys[3], keys[2]) * step,
                axis(keys[5], keys[4]) * step,
            );
            // Keep walking while the key is held, without input events.
            ui.ctx().request_repaint();
            moved = true;
        }
    }
    moved
}

/// Moves camera and pivot together: `forward` along the view, `right` along
/// the image's right axis, `up` along the camera's up, each in units of the
/// distance to the pivot.
pub fn walk(cam: &mut CameraDesc, forward: f64, right: f64, up: f64) {
    let pos = v(cam.position);
    let target = v(cam.look_at);
    let view = target - pos;
    let dist = view.length();
    let f = view / dist;
    let r = f.cross(v(cam.up)).normalize_or_zero();
    let u = v(cam.up).normalize();
    let shift = (f * forward + r * right + u * up) * dist;
    cam.position = (pos + shift).to_array();
    cam.look_at = (target + shift).to_array();
}

/// Turns the view about the camera's own position (first-person look):
/// the pivot moves, the camera stands.
pub fn look(cam: &mut CameraDesc, delta: Vec2) {
    let pos = v(cam.position);
    let up = v(cam.up).normalize();
    let offset = v(cam.look_at) - pos;
    let yaw = glam::DQuat::from_axis_angle(up, -(delta.x as f64) * ORBIT_SPEED);
    let offset = yaw * offset;
    let right = offset.cross(up).normalize_or_zero();
    let angle = offset.angle_between(up);
    let limit = 0.05;
    let pitch = (-(delta.y as f64) * ORBIT_SPEED)
        .clamp(limit - (std::f64::consts::PI - angle), angle - limit);
    let offset = if right == DVec3::ZERO {
        offset
    } else {
        glam::DQuat::from_axis_angle(right, pitch) * offset
    };
    cam.look_at = (pos + offset).to_array();
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
