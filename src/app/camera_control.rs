//! Mouse and keyboard camera control on the scene's own camera
//! description: orbit about `look_at` by dragging, pan with the middle
//! button or shift-drag, zoom with the wheel; walk with W/A/S/D (Q/E down
//! and up, Shift faster) and look around with a right-drag, to move inside
//! a room. Editing `CameraDesc` keeps "save scene" exact. Every move
//! stays within the scene's [`Reach`], so no mouse gesture can take the
//! camera where the format refuses it.

use egui::{PointerButton, Response, Vec2};
use glam::DVec3;

use crate::render::Scene;
use crate::render::geometry::Aabb;
use crate::render::scene_file::CameraDesc;
use crate::render::scene_file::limits::{MAX_COORD, MIN_SCENE_SIZE};

/// Radians of orbit per point dragged.
const ORBIT_SPEED: f64 = 0.004;
/// Zoom factor per point of wheel scroll.
const ZOOM_SPEED: f64 = 0.002;
/// Walking speed: the distance to the pivot per second (so it suits any
/// scene's scale); Shift walks [`WALK_FAST`] times as fast.
const WALK_SPEED: f64 = 0.6;
const WALK_FAST: u32 = 4;

/// The walking keys: each key, where it goes, and its step along the view
/// (forward), the image's right and the camera's up.
pub const WALK_KEYS: [(egui::Key, &str, [f64; 3]); 6] = [
    (egui::Key::W, "forward", [1.0, 0.0, 0.0]),
    (egui::Key::A, "left", [0.0, -1.0, 0.0]),
    (egui::Key::S, "back", [-1.0, 0.0, 0.0]),
    (egui::Key::D, "right", [0.0, 1.0, 0.0]),
    (egui::Key::Q, "down", [0.0, 0.0, -1.0]),
    (egui::Key::E, "up", [0.0, 0.0, 1.0]),
];

/// What a drag over the image does to the camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DragMove {
    Orbit,
    Pan,
    Look,
}

impl DragMove {
    fn describe(self) -> &'static str {
        match self {
            DragMove::Orbit => "Orbit about the pivot",
            DragMove::Pan => "Pan",
            DragMove::Look => "Look around (the camera stands, the pivot turns)",
        }
    }
}

/// Which drag does what, first match wins: (button, Shift needed, the
/// move, the gesture's name in the help).
pub const DRAGS: [(PointerButton, bool, DragMove, &str); 4] = [
    (PointerButton::Middle, false, DragMove::Pan, "Middle-drag"),
    (PointerButton::Primary, true, DragMove::Pan, "Shift+drag"),
    (PointerButton::Primary, false, DragMove::Orbit, "Drag"),
    (
        PointerButton::Secondary,
        false,
        DragMove::Look,
        "Right-drag",
    ),
];

/// The camera's gestures for the help, from the tables the input reads:
/// (gesture, what it does).
pub fn help_rows() -> Vec<(String, String)> {
    let mut rows: Vec<(String, String)> = Vec::new();
    for (_, _, m, name) in DRAGS {
        // One row per move: "Middle-drag, Shift+drag: Pan".
        match rows.iter_mut().find(|r| r.1 == m.describe()) {
            Some(r) => r.0 = format!("{}, {name}", r.0),
            None => rows.push((name.to_string(), m.describe().to_string())),
        }
    }
    rows.push(("Wheel".into(), "Zoom towards the pivot".into()));
    let keys: Vec<&str> = WALK_KEYS.iter().map(|(k, _, _)| k.name()).collect();
    let ways: Vec<&str> = WALK_KEYS.iter().map(|(_, w, _)| *w).collect();
    rows.push((
        keys.join("/"),
        format!(
            "Walk {} (over the image; Shift: {WALK_FAST}× faster)",
            ways.join(", ")
        ),
    ));
    rows
}

/// How far the camera may go from the scene's finite part, in scene sizes:
/// far enough to see the scene as a dot, near enough that its features stay
/// above the format's smallest (`MIN_FEATURE` of the scene's size, which
/// grows with the camera's distance): 10⁻⁶ of the scene still renders.
const REACH_IN_SIZES: f64 = 1e3;
/// The nearest the camera may come to its pivot, in scene sizes.
const NEAREST_IN_SIZES: f64 = 1e-6;

/// Where the camera may be: within [`REACH_IN_SIZES`] scene sizes of the
/// centre of the scene's finite part (the bounded objects and the light),
/// and no nearer its pivot than [`NEAREST_IN_SIZES`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reach {
    pub centre: DVec3,
    /// The largest side of the finite part's box.
    pub size: f64,
}

impl Reach {
    /// The reach of a built scene.
    pub fn of_scene(scene: &Scene) -> Reach {
        let mut b = Aabb::from_points(&scene.light.shape.corners());
        if let Some(o) = scene.object_bounds {
            b = b.union(o);
        }
        Reach {
            centre: b.centre(),
            size: b.extent().max_element().max(MIN_SCENE_SIZE),
        }
    }

    /// A stand-in before the scene is built: about what a camera frames.
    pub fn of_camera(cam: &CameraDesc) -> Reach {
        Reach {
            centre: v(cam.look_at),
            size: (v(cam.position) - v(cam.look_at))
                .length()
                .max(MIN_SCENE_SIZE),
        }
    }

    /// The camera's farthest distance from `centre`; the pivot may be twice
    /// as far (the camera within reach, looking outwards).
    fn radius(&self) -> f64 {
        REACH_IN_SIZES * self.size
    }

    /// The nearest the camera may come to a pivot at `target`: the format
    /// refuses a camera on its pivot, and rounding puts it there below
    /// about 10⁻¹² of the coordinates.
    fn min_distance(&self, target: DVec3) -> f64 {
        NEAREST_IN_SIZES * self.size + 1e-9 * target.abs().max_element()
    }

    /// How far out of reach `cam` is: at most 1 within it, infinite
    /// beyond the format's coordinates.
    fn excess(&self, cam: &CameraDesc) -> f64 {
        let (pos, target) = (v(cam.position), v(cam.look_at));
        if !(pos.abs().max_element() <= MAX_COORD && target.abs().max_element() <= MAX_COORD) {
            return f64::INFINITY;
        }
        let r = self.radius();
        ((pos - self.centre).length() / r).max((target - self.centre).length() / (2.0 * r))
    }

    /// Whether a move from `before` to `after` may stand: `after` is within
    /// reach, or no farther out than `before` (a scene's own camera may
    /// stand beyond it, and must be able to come back).
    pub fn allows(&self, before: &CameraDesc, after: &CameraDesc) -> bool {
        let close = |c: &CameraDesc| (v(c.position) - v(c.look_at)).length();
        let too_close = close(after) < self.min_distance(v(after.look_at));
        if too_close && close(after) < close(before) {
            return false;
        }
        self.excess(after) <= self.excess(before).max(1.0)
    }
}

/// Applies this frame's drags and scrolls over the image; true if the
/// camera moved. `image_height` is the displayed height in points (pan
/// follows the cursor at the look-at distance). A move that would leave
/// `reach` is not made.
pub fn camera_input(
    ui: &egui::Ui,
    response: &Response,
    cam: &mut CameraDesc,
    image_height: f32,
    reach: &Reach,
) -> bool {
    let before = cam.clone();
    let mut moved = false;
    let shift = ui.input(|i| i.modifiers.shift);
    let delta = response.drag_delta();
    let drag = DRAGS
        .iter()
        .find(|(button, needs_shift, _, _)| response.dragged_by(*button) && (shift || !needs_shift))
        .map(|d| d.2);
    if delta != Vec2::ZERO
        && let Some(m) = drag
    {
        match m {
            DragMove::Orbit => orbit(cam, delta),
            DragMove::Pan => pan(cam, delta, image_height),
            DragMove::Look => look(cam, delta),
        }
        moved = true;
    }
    if response.hovered() {
        let scroll = ui.input(|i| i.smooth_scroll_delta.y);
        if scroll != 0.0 {
            zoom(cam, (-(scroll as f64) * ZOOM_SPEED).exp(), reach);
            moved = true;
        }
    }
    // Walking: while the image is hovered and no text field takes the keys
    // (Ctrl+S and the like stay shortcuts).
    if response.hovered() && !ui.ctx().egui_wants_keyboard_input() {
        let (keys, dt, command, fast) = ui.input(|i| {
            (
                WALK_KEYS.map(|(k, _, _)| i.key_down(k)),
                i.stable_dt.min(0.1) as f64,
                i.modifiers.command || i.modifiers.alt,
                i.modifiers.shift,
            )
        });
        if !command && keys.contains(&true) {
            let step = WALK_SPEED * dt * if fast { WALK_FAST as f64 } else { 1.0 };
            let mut way = [0.0; 3];
            for ((_, _, dir), down) in WALK_KEYS.iter().zip(keys) {
                if down {
                    (0..3).for_each(|a| way[a] += dir[a]);
                }
            }
            walk(cam, way[0] * step, way[1] * step, way[2] * step);
            // Keep walking while the key is held, without input events.
            ui.ctx().request_repaint();
            moved = true;
        }
    }
    if moved && !reach.allows(&before, cam) {
        *cam = before;
        return false;
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

/// Scales the distance to `look_at` by `factor`, stopping at the edges of
/// `reach` (out, or in to the pivot).
pub fn zoom(cam: &mut CameraDesc, factor: f64, reach: &Reach) {
    let target = v(cam.look_at);
    let offset = v(cam.position) - target;
    let len = offset.length();
    let mut new_len = (len * factor).clamp(1e-3 * len.max(1e-6), 1e3 * len.max(1e-6));
    if factor > 1.0 {
        // Out to the reach's edge, wherever the pivot is within it.
        let room = reach.radius() - (target - reach.centre).length();
        new_len = new_len.min(room.max(len));
    } else {
        new_len = new_len.max(reach.min_distance(target).min(len));
    }
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
