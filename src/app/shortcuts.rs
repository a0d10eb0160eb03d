//! The keyboard shortcuts: one table for the keys, the menus, the tooltips
//! and the F1 help overlay.

use egui::{Key, KeyboardShortcut, Modifiers};

/// What a shortcut, a menu entry or a button asks the viewer to do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    Open,
    SavePng,
    SaveScene,
    Quit,
    Undo,
    Redo,
    FrameAll,
    ResetView,
    Cutaway,
    TogglePanel,
    Fullscreen,
    Help,
    About,
    /// The image tools: zoom the image (not the camera), pin it as A and
    /// compare the live render with it.
    ZoomFit,
    ZoomOneToOne,
    ZoomIn,
    ZoomOut,
    ZoomMode,
    PinImage,
    NextCompare,
    /// Close the topmost overlay (help, inspector, dialog).
    Escape,
}

const fn ks(modifiers: Modifiers, key: Key) -> KeyboardShortcut {
    KeyboardShortcut::new(modifiers, key)
}

const CTRL: Modifiers = Modifiers::COMMAND;
const CTRL_SHIFT: Modifiers = Modifiers {
    shift: true,
    ..Modifiers::COMMAND
};
const NONE: Modifiers = Modifiers::NONE;

/// Every binding, in the order the help lists them: (command, keys, what
/// it does). The first key is the one menus show.
pub const BINDINGS: &[(Command, &[KeyboardShortcut], &str)] = &[
    (Command::Open, &[ks(CTRL, Key::O)], "Open a scene"),
    // Ctrl+Shift+S before Ctrl+S (extra Shift is ignored in matching).
    (
        Command::SaveScene,
        &[ks(CTRL_SHIFT, Key::S)],
        "Save the settings as a scene file",
    ),
    (
        Command::SavePng,
        &[ks(CTRL, Key::S)],
        "Save the image as PNG (full resolution)",
    ),
    (Command::Quit, &[ks(CTRL, Key::Q)], "Quit (asks if unsaved)"),
    // Redo before undo: Ctrl+Shift+Z must not be read as Ctrl+Z.
    (
        Command::Redo,
        &[ks(CTRL_SHIFT, Key::Z), ks(CTRL, Key::Y)],
        "Redo",
    ),
    (Command::Undo, &[ks(CTRL, Key::Z)], "Undo the last edit"),
    (
        Command::FrameAll,
        &[ks(NONE, Key::F)],
        "Frame all: the whole scene in view",
    ),
    (
        Command::ResetView,
        &[ks(NONE, Key::Home)],
        "Reset the camera to the scene's own",
    ),
    (
        Command::Cutaway,
        &[ks(NONE, Key::C)],
        "Cut-away: see through walls from behind",
    ),
    (
        Command::TogglePanel,
        &[ks(NONE, Key::Space)],
        "Show or hide the side panel",
    ),
    (Command::Fullscreen, &[ks(NONE, Key::F11)], "Full screen"),
    (
        Command::ZoomFit,
        &[ks(NONE, Key::Num0)],
        "Image: fit the panel",
    ),
    (
        Command::ZoomOneToOne,
        &[ks(NONE, Key::Num1)],
        "Image: 1:1 (one image pixel per screen pixel)",
    ),
    (
        Command::ZoomIn,
        &[ks(NONE, Key::Plus), ks(NONE, Key::Equals)],
        "Image: zoom in 2× (up to 32×, pixel grid from 8×)",
    ),
    (
        Command::ZoomOut,
        &[ks(NONE, Key::Minus)],
        "Image: zoom out 2×",
    ),
    (
        Command::ZoomMode,
        &[ks(NONE, Key::Z)],
        "Image zoom mode: drag pans, wheel zooms the image",
    ),
    (
        Command::PinImage,
        &[ks(NONE, Key::P)],
        "Pin the image as A (to compare after edits)",
    ),
    (
        Command::NextCompare,
        &[ks(NONE, Key::X)],
        "Compare with A: live, split, flicker, difference",
    ),
    (
        Command::Help,
        &[ks(NONE, Key::F1), ks(NONE, Key::Questionmark)],
        "This help",
    ),
    (
        Command::Escape,
        &[ks(NONE, Key::Escape)],
        "Close a menu or colour picker, the help, the inspector or a dialog",
    ),
];

/// The image's mouse bindings and dropped files, for the help (the
/// camera's come from [`super::camera_control::help_rows`]).
pub const MOUSE: &[(&str, &str)] = &[
    (
        "Ctrl+wheel",
        "Zoom the image about the cursor (not the camera)",
    ),
    ("Ctrl+drag", "Pan the zoomed image"),
    ("Double-click", "Set the pivot there and inspect the pixel"),
    (
        "Drop a file",
        "Open a scene (.json), add a mesh (.obj/.ply/.gltf/.glb) or load a reference (.png/.exr)",
    ),
];

/// One key as text: egui's names, except `?` for the question mark.
fn key_text(ctx: &egui::Context, k: &KeyboardShortcut) -> String {
    if k.logical_key == Key::Questionmark {
        "?".into()
    } else {
        ctx.format_shortcut(k)
    }
}

/// The keys of `command` as text ("Ctrl+Shift+Z / Ctrl+Y").
pub fn keys_text(ctx: &egui::Context, command: Command) -> String {
    BINDINGS
        .iter()
        .find(|b| b.0 == command)
        .map(|b| {
            b.1.iter()
                .map(|k| key_text(ctx, k))
                .collect::<Vec<_>>()
                .join(" / ")
        })
        .unwrap_or_default()
}

/// The first key of `command` (for menu entries).
pub fn first_key(ctx: &egui::Context, command: Command) -> String {
    BINDINGS
        .iter()
        .find(|b| b.0 == command)
        .and_then(|b| b.1.first())
        .map(|k| ctx.format_shortcut(k))
        .unwrap_or_default()
}

/// The commands whose keys were pressed this frame (consumed). `typing`:
/// a text field has the keyboard, so only Escape counts.
pub fn read(ctx: &egui::Context, typing: bool) -> Vec<Command> {
    let mut out = Vec::new();
    // An open menu or colour picker is topmost: egui closes it on Escape,
    // if the key is left to it.
    let popup = egui::Popup::is_any_open(ctx);
    ctx.input_mut(|i| {
        for (command, keys, _) in BINDINGS {
            if typing && *command != Command::Escape || popup && *command == Command::Escape {
                continue;
            }
            // `?` is Shift+/ on most layouts: any modifiers.
            let pressed = keys.iter().any(|k| {
                if k.logical_key == Key::Questionmark {
                    i.key_pressed(Key::Questionmark)
                } else {
                    i.consume_shortcut(k)
                }
            });
            if pressed && !out.contains(command) {
                out.push(*command);
            }
        }
    });
    out
}

/// The help overlay's content.
pub fn help_ui(ui: &mut egui::Ui) {
    egui::Grid::new("help-keys")
        .num_columns(2)
        .striped(true)
        .show(ui, |ui| {
            for (command, _, what) in BINDINGS {
                ui.label(egui::RichText::new(keys_text(ui.ctx(), *command)).strong());
                ui.label(*what);
                ui.end_row();
            }
            let camera = super::camera_control::help_rows();
            let mouse = MOUSE.iter().map(|(k, w)| (k.to_string(), w.to_string()));
            for (keys, what) in camera.into_iter().chain(mouse) {
                ui.label(egui::RichText::new(keys).strong());
                ui.label(what);
                ui.end_row();
            }
        });
}
