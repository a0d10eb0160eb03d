//! Helpers of the viewer's tests (egui_kittest, headless).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use egui_kittest::Harness;
use penumbra::app::render_job::JobState;
use penumbra::app::{Viewer, ViewerOptions};
use penumbra::render::{Film, SEED_ROOM_JSON, SceneDesc};

/// How long a test waits for a render or a load.
pub const WAIT: Duration = Duration::from_secs(60);

/// The seed room at 64×36 with few shadow rays.
pub fn small_room() -> SceneDesc {
    let mut d = SceneDesc::from_json(SEED_ROOM_JSON).unwrap();
    d.camera.width = 64;
    d.camera.height = 36;
    d.render.shadow_rays = 16;
    d
}

pub fn harness(options: ViewerOptions) -> Harness<'static, Viewer> {
    harness_of(Viewer::new(options))
}

/// A harness around a viewer of `options` whose first render has ended
/// ([`settle`]).
pub fn settled(options: ViewerOptions) -> Harness<'static, Viewer> {
    let mut h = harness(options);
    settle(&mut h);
    h
}

/// A harness around a viewer made by the test (to set its test hooks
/// before the first frame).
pub fn harness_of(viewer: Viewer) -> Harness<'static, Viewer> {
    Harness::builder()
        .with_size([1280.0, 960.0])
        // Real frame times, so that two clicks make a double-click.
        .with_step_dt(1.0 / 60.0)
        .build_ui_state(|ui, v: &mut Viewer| v.show(ui, None), viewer)
}

/// Waits for the load under way (a scene or an edit being built), a frame
/// to take it, then the latest render to end, and a frame so its last
/// tiles reach the texture.
pub fn settle(h: &mut Harness<'static, Viewer>) {
    if h.state().loading().is_some() {
        assert!(h.state().wait_for_loads(WAIT), "a load did not end");
        h.step();
    }
    assert!(h.state().wait_for_render(WAIT), "render did not finish");
    h.step();
}

/// The film of the finished render.
pub fn finished(v: &Viewer) -> Film {
    match v.render_state() {
        Some(JobState::Finished(f)) => (*f.film).clone(),
        other => panic!("render did not finish: {other:?}"),
    }
}

/// Steps frames until `done` or a timeout.
pub fn step_until(h: &mut Harness<'static, Viewer>, done: impl Fn(&Viewer) -> bool) {
    let start = Instant::now();
    while !done(h.state()) {
        assert!(start.elapsed() < WAIT, "timed out");
        h.step();
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// A file dropped on the window, as eframe hands it to egui.
#[derive(Debug)]
struct Dropped(PathBuf);

impl egui::DroppedFile for Dropped {
    fn path(&self) -> &Path {
        &self.0
    }
    fn bytes(&self) -> Result<Vec<u8>, String> {
        std::fs::read(&self.0).map_err(|e| e.to_string())
    }
}

/// Drops `path` on the window; the next frame takes it.
pub fn drop_file(h: &mut Harness<'static, Viewer>, path: &Path) {
    h.input_mut()
        .dropped_files
        .push(Arc::new(Dropped(path.to_path_buf())));
}

/// Double-clicks at `pos` (two clicks 50 ms apart, frame times set
/// explicitly).
pub fn double_click(h: &mut Harness<'static, Viewer>, pos: egui::Pos2) {
    h.event(egui::Event::PointerMoved(pos));
    h.step();
    let t0 = h.ctx.input(|i| i.time) + 1.0;
    for (k, pressed) in [true, false, true, false].into_iter().enumerate() {
        h.input_mut().time = Some(t0 + 0.05 * k as f64);
        h.input_mut().events.push(egui::Event::PointerButton {
            pos,
            button: egui::PointerButton::Primary,
            pressed,
            modifiers: egui::Modifiers::NONE,
        });
        if k < 3 {
            h.step();
        }
    }
    h.step();
}
