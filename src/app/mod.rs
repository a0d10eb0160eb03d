//! The egui viewer (only UI; rendering lives in `crate::render`).
//!
//! - [`viewer`]: the app state and its frame.
//! - [`render_job`]: the render's worker thread, cancellation and tile
//!   streaming; [`worker`]: the thread-and-mailbox pattern it shares with
//!   the error readout.
//! - [`controls`], [`camera_control`], [`status`]: the panels and the mouse.
//! - [`object_list`]: the objects' visibility and materials, adding meshes.
//! - [`settings`]: viewer toggles that map onto the scene description.
//! - [`file_dialog`], [`export`], [`scene_loader`], [`watch`]: files in and
//!   out, off the UI thread.
//! - [`timings`]: the `--log-timings` figures.
//! - [`mod@reference`], [`error_view`]: the converged reference and the live
//!   error readout against it.
//! - [`image_view`], [`image_toolbar`], [`pinned`]: the image tools (zoom
//!   and pan, exposure and curve, the pinned image A); display only.

pub mod camera_control;
pub mod controls;
pub mod error_view;
pub mod export;
pub mod file_dialog;
pub mod history;
pub mod image_toolbar;
pub mod image_view;
pub mod object_list;
pub mod pinned;
pub mod reference;
pub mod render_job;
pub mod scene_loader;
pub mod settings;
pub mod shortcuts;
pub mod status;
pub mod timings;
pub mod viewer;
pub mod watch;
pub mod worker;

use std::time::Duration;

pub use viewer::{LaunchScene, Persisted, PickInfo, Viewer, ViewerOptions};

use crate::cli::ViewArgs;
use crate::render::SceneDesc;
use crate::render::scene::SEED_ROOM_JSON;

impl ViewerOptions {
    /// The viewer the command line asks for: the scene it names is opened
    /// once the window is up, read and built on the load thread under the
    /// loading strip (see [`LaunchScene`]); the seed room if none. A file
    /// that is missing or broken is no reason to give up: the viewer shows
    /// the seed room with the error in its banner and loads the file once
    /// it is valid.
    pub fn from_args(args: &ViewArgs) -> Result<ViewerOptions, String> {
        let seed = SceneDesc::from_json(SEED_ROOM_JSON).map_err(|e| e.to_string())?;
        Ok(ViewerOptions {
            log_timings: args.log_timings,
            wiggle: args.wiggle.map(Duration::from_secs_f64),
            refine_spp: args.refine_spp.unwrap_or(DEFAULT_REFINE_SPP),
            open_at_launch: args
                .scene
                .clone()
                .map(|path| LaunchScene { path, named: true }),
            ..ViewerOptions::new(seed)
        })
    }
}

/// Camera samples per pixel the viewer refines a finished image to: enough
/// for smooth edges (see the README's anti-aliasing table), and reached in
/// a few seconds on the seed room.
pub const DEFAULT_REFINE_SPP: u32 = 16;

/// Opens the viewer window and runs it until it is closed. Unless
/// `--no-persist`, the window's geometry, the side panel's sections, the
/// last scene (opened again when none is named), the recent files and the
/// view settings are remembered in eframe's storage.
pub fn run(args: &ViewArgs) -> Result<(), String> {
    let options = ViewerOptions::from_args(args)?;
    let persist = !args.no_persist;
    let named = args.scene.is_some();
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("penumbra")
            .with_inner_size([1500.0, 860.0])
            .with_min_inner_size([480.0, 320.0])
            .with_drag_and_drop(true),
        persist_window: persist,
        ..Default::default()
    };
    eframe::run_native(
        "penumbra",
        native,
        Box::new(move |cc| {
            let stored: Option<Persisted> = cc
                .storage
                .filter(|_| persist)
                .and_then(|s| eframe::get_value(s, Persisted::KEY));
            let mut options = options;
            // A bare `penumbra` goes on with the last scene, if it still
            // opens (else the seed room, quietly).
            if !named && let Some(p) = stored.as_ref().and_then(|s| s.last_scene.clone()) {
                options.open_at_launch = Some(LaunchScene {
                    path: p,
                    named: false,
                });
            }
            let mut viewer = Viewer::new(options);
            viewer.persist = persist;
            if let Some(s) = stored {
                viewer.restore_persisted(s);
            }
            Ok(Box::new(viewer))
        }),
    )
    .map_err(|e| format!("cannot open the viewer window: {e}"))
}
