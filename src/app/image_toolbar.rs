//! The strip above the image: exposure and tone curve, zoom, and the pin
//! with its comparison. Everything here changes how the image is shown,
//! never the render.

use egui::Ui;

use super::pinned::{Compare, CompareMode};
use super::shortcuts::{Command, first_key};
use crate::render::{DisplayTransform, ToneCurve};

/// What the strip changed this frame.
#[derive(Default)]
pub struct ToolbarOut {
    /// The exposure or the curve changed (the image is shown again).
    pub display_changed: bool,
    /// Buttons pressed, run as their keys would.
    pub commands: Vec<Command>,
}

/// Draws the strip. `zoom_label` says the zoom now ("fit (1.4×)").
pub fn toolbar_ui(
    ui: &mut Ui,
    display: &mut DisplayTransform,
    compare: &mut Compare,
    zoom_label: &str,
    zoom_mode: bool,
) -> ToolbarOut {
    let mut out = ToolbarOut::default();
    let ctx = ui.ctx().clone();
    let tip = |c: Command, what: &str| format!("{what} ({})", first_key(&ctx, c));
    ui.horizontal_wrapped(|ui| {
        ui.spacing_mut().slider_width = 90.0;
        ui.label("Exposure");
        // The value's box as wide as its widest text, so that the strip
        // does not shift (under the cursor) as "+0.0 EV" becomes "+10.0 EV".
        let font = egui::TextStyle::Button.resolve(ui.style());
        let widest = ["+10.0 EV", "-10.0 EV"]
            .map(|t| {
                ui.painter()
                    .layout_no_wrap(t.into(), font.clone(), egui::Color32::WHITE)
                    .size()
                    .x
            })
            .into_iter()
            .fold(0.0, f32::max);
        let r = ui
            .scope(|ui| {
                ui.spacing_mut().interact_size.x = widest + 2.0 * ui.spacing().button_padding.x;
                ui.add(
                    egui::Slider::new(&mut display.exposure, DisplayTransform::EXPOSURE_RANGE)
                        .step_by(0.1)
                        .custom_formatter(|v, _| format!("{v:+.1}"))
                        .suffix(" EV"),
                )
            })
            .inner
            .on_hover_text("Stops: the image is shown ×2^EV (display only; the render and an EXR stay linear)");
        out.display_changed |= r.changed();
        if ui
            .small_button("0")
            .on_hover_text("Exposure back to 0 EV")
            .clicked()
            && display.exposure != 0.0
        {
            display.exposure = 0.0;
            out.display_changed = true;
        }
        let before = display.curve;
        egui::ComboBox::from_id_salt("penumbra-tone-curve")
            .selected_text(display.curve.label())
            .show_ui(ui, |ui| {
                for c in ToneCurve::ALL {
                    ui.selectable_value(&mut display.curve, c, c.label());
                }
            })
            .response
            .on_hover_text("Display transform: sRGB clips at 1, filmic rolls highlights off");
        out.display_changed |= display.curve != before;
        ui.separator();

        ui.label(format!("Zoom {zoom_label}"));
        for (c, text, what) in [
            (Command::ZoomFit, "Fit", "Fit the image to the panel"),
            (Command::ZoomOneToOne, "1:1", "One image pixel per screen pixel"),
            (Command::ZoomOut, "−", "Zoom out"),
            (Command::ZoomIn, "+", "Zoom in (pixel grid from 8×)"),
        ] {
            if ui.small_button(text).on_hover_text(tip(c, what)).clicked() {
                out.commands.push(c);
            }
        }
        if ui
            .selectable_label(zoom_mode, "pan mode")
            .on_hover_text(tip(
                Command::ZoomMode,
                "Zoom mode: drag pans, wheel zooms the image; Ctrl+wheel and Ctrl+drag do so anyway",
            ))
            .clicked()
        {
            out.commands.push(Command::ZoomMode);
        }
        ui.separator();

        if ui
            .button("Pin A")
            .on_hover_text(tip(
                Command::PinImage,
                "Keep the image on screen as A, to compare the live render with it after edits",
            ))
            .clicked()
        {
            out.commands.push(Command::PinImage);
        }
    });
    // The comparison on a row of its own: the strip never runs off the
    // panel's edge.
    if compare.pinned.is_none() {
        return out;
    }
    ui.horizontal_wrapped(|ui| {
        ui.spacing_mut().slider_width = 120.0;
        if let Some(p) = &compare.pinned {
            ui.label("A vs live:").on_hover_text(format!(
                "A: {}×{}, {} camera samples per pixel",
                p.film.width, p.film.height, p.samples
            ));
            for m in CompareMode::ALL {
                if ui
                    .selectable_label(compare.mode == m, m.label())
                    .on_hover_text(tip(
                        Command::NextCompare,
                        "How the live image is set against A",
                    ))
                    .clicked()
                {
                    compare.mode = m;
                    if m == CompareMode::Flicker {
                        compare.restart_flicker();
                    }
                }
            }
            if compare.mode == CompareMode::Split {
                ui.add(
                    egui::Slider::new(&mut compare.split, 0.0..=1.0)
                        .show_value(false)
                        .text("split"),
                )
                .on_hover_text("A left of the line, the live render right of it");
            }
            if ui.small_button("Unpin").clicked() {
                compare.clear();
            }
        }
    });
    out
}
