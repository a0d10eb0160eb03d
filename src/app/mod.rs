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
pub mod history;
pub mod reference;
pub mod render_job;
pub mod settings;
pub mod shortcuts;
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
    /// A file that is missing or broken is no reason to give up: the
    /// viewer starts on the seed room with the error in its banner and
    /// loads the file once it is valid.
    pub fn from_args(args: &ViewArgs) -> Result<ViewerOptions, String> {
        let seed = || SceneDesc::from_json(SEED_ROOM_JSON).map_err(|e| e.to_string());
        let (desc, startup_error) = match &args.scene {
            Some(p) => match SceneDesc::load(p) {
                Ok(d) => (d, None),
                Err(e) => (seed()?, Some(e.to_string())),
            },
            None => (seed()?, None),
        };
        Ok(ViewerOptions {
            desc,
            scene_path: args.scene.clone(),
            log_timings: args.log_timings,
            wiggle: args.wiggle.map(Duration::from_secs_f64),
            startup_error,
        })
    }
}

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
