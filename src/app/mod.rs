//! The egui viewer (only UI; rendering lives in `crate::render`).
//!
//! - [`viewer`]: the app state and its frame.
//! - [`render_job`]: the render's worker thread, cancellation and tile
//!   streaming; [`worker`]: the thread-and-mailbox pattern it shares with
//!   the error readout.
//! - [`controls`], [`camera_control`], [`status`]: the panels and the mouse.
//! - [`settings`]: viewer toggles that map onto the scene description.
//! - [`file_dialog`], [`export`], [`watch`]: files in and out.
//! - [`timings`]: the `--log-timings` figures.
//! - [`mod@reference`], [`error_view`]: the converged reference and the live
//!   error readout against it.

pub mod camera_control;
pub mod controls;
pub mod error_view;
pub mod export;
pub mod file_dialog;
pub mod reference;
pub mod render_job;
pub mod settings;
pub mod status;
pub mod timings;
pub mod viewer;
pub mod watch;
pub mod worker;

use std::time::Duration;

pub use viewer::{PickInfo, Viewer, ViewerOptions};

use crate::cli::ViewArgs;
use crate::render::SceneDesc;
use crate::render::scene::SEED_ROOM_JSON;

impl ViewerOptions {
    /// Reads the scene named on the command line (the seed room if none).
    pub fn from_args(args: &ViewArgs) -> Result<ViewerOptions, String> {
        let desc = match &args.scene {
            Some(p) => SceneDesc::load(p).map_err(|e| e.to_string())?,
            None => SceneDesc::from_json(SEED_ROOM_JSON).map_err(|e| e.to_string())?,
        };
        Ok(ViewerOptions {
            desc,
            scene_path: args.scene.clone(),
            log_timings: args.log_timings,
            wiggle: args.wiggle.map(Duration::from_secs_f64),
            refine_spp: args.refine_spp.unwrap_or(DEFAULT_REFINE_SPP),
        })
    }
}

/// Camera samples per pixel the viewer refines a finished image to: enough
/// for smooth edges (see the README's anti-aliasing table), and reached in
/// a few seconds on the seed room.
pub const DEFAULT_REFINE_SPP: u32 = 16;

/// Opens the viewer window and runs it until it is closed.
pub fn run(args: &ViewArgs) -> Result<(), String> {
    let options = ViewerOptions::from_args(args)?;
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("penumbra")
            .with_inner_size([1500.0, 860.0])
            .with_min_inner_size([640.0, 400.0])
            .with_drag_and_drop(true),
        ..Default::default()
    };
    eframe::run_native(
        "penumbra",
        native,
        Box::new(move |_cc| Ok(Box::new(Viewer::new(options)))),
    )
    .map_err(|e| format!("cannot open the viewer window: {e}"))
}
