//! The side panel: every control edits a field of the scene description
//! (or of [`ViewSettings`]) in place and reports whether anything changed;
//! the viewer then restarts the render from the edited description.

use std::ops::RangeInclusive;

use egui::{Slider, SliderClamping, Ui};

use super::settings::ViewSettings;
use crate::render::sampling::{grid_side, points_per_hit};
use crate::render::scene_file::limits::{
    MAX_COLOUR, MAX_COORD, MAX_DEPTH, MAX_SHADOW_RAYS, MAX_SHININESS, MIN_FEATURE, MIN_SCENE_SIZE,
};
use crate::render::{AreaLightModel, Sampling, SceneDesc};

/// The shortest light width or depth any scene takes: the loader's floor
/// is [`MIN_FEATURE`] of the scene's size, which is at least
/// [`MIN_SCENE_SIZE`]. Whether this scene takes a length (its own floor)
/// is checked with the whole edit, by the viewer.
const LIGHT_SIZE_MIN: f64 = MIN_FEATURE * MIN_SCENE_SIZE;

/// A slider that never changes a value it only shows: a scene's 4096
/// shadow rays or strength 20 load, show and save unchanged (egui's default
/// clamping would rewrite them). Ranges are the format's limits; a value
/// dragged or typed is clamped to them (see [`slider_within`]).
fn slider<'a, N: egui::emath::Numeric>(value: &'a mut N, range: RangeInclusive<N>) -> Slider<'a> {
    slider_within(value, range.clone(), range)
}

/// A shininess slider (the override's or a material's): logarithmic over
/// 1–10⁶, any positive value typed.
fn shininess_slider<'a>(value: &'a mut f64, text: &str) -> Slider<'a> {
    slider_within(value, 1.0..=MAX_SHININESS, ABOVE_ZERO..=MAX_SHININESS)
        .logarithmic(true)
        .text(text)
}

/// A slider over `rail` whose dragged or typed values are clamped to
/// `limits` and whose number field refuses NaN and infinities, so no edit
/// can leave the format's range (a scene saved with one would not load).
/// The term strengths' rail is 0–10 of the format's 0–10⁶, so that a drag
/// stays fine while the number field takes any value the format does.
/// A typed value is taken on Enter or on leaving the field (see
/// [`typed_on_enter`]); a drag applies as it goes.
fn slider_within<'a, N: egui::emath::Numeric>(
    value: &'a mut N,
    rail: RangeInclusive<N>,
    limits: RangeInclusive<N>,
) -> Slider<'a> {
    let (lo, hi) = (limits.start().to_f64(), limits.end().to_f64());
    let rail = rail.start().to_f64()..=rail.end().to_f64();
    let slider = Slider::from_get_set(rail, move |new| {
        if let Some(x) = new.filter(|x| x.is_finite()) {
            *value = N::from_f64(x.clamp(lo, hi));
        }
        value.to_f64()
    })
    .clamping(SliderClamping::Never)
    .custom_parser(parse_finite);
    let slider = typed_on_enter(slider);
    if N::INTEGRAL {
        slider.integer()
    } else {
        slider
    }
}

/// The light's width or depth rail spans these fractions of the scene's
/// size: two decades and a bit, where lights are (a room 10 across: 0.1
/// to 20), so that a drag of ten points changes a size by about half
/// (over the loader's 24 decades, by hundreds of times).
const LIGHT_RAIL_BELOW: f64 = 1e-2;
const LIGHT_RAIL_ABOVE: f64 = 2.0;

/// The light's width or depth, `len`, the length of `edge`: a logarithmic
/// slider over `rail` (see [`light_rail`]) whose number field takes every
/// length the loader takes for it, from [`LIGHT_SIZE_MIN`] to the one that
/// puts the edge's largest component at [`MAX_COORD`]; its drag is fine:
/// half a percent of the size per point. A value it only shows is never
/// changed: the field shows six digits, and entering them again keeps the
/// value.
fn light_size_slider<'a>(
    len: &'a mut f64,
    edge: [f64; 3],
    rail: (f64, f64),
    text: &str,
) -> Slider<'a> {
    let max = light_size_max(*len, edge);
    let fine_step = *len * 0.005;
    let slider = Slider::from_get_set(rail.0..=rail.1, move |new| {
        if let Some(x) = new.filter(|x| x.is_finite())
            && six_digits(x) != six_digits(*len)
        {
            *len = x.clamp(LIGHT_SIZE_MIN, max);
        }
        *len
    })
    .logarithmic(true)
    .clamping(SliderClamping::Never)
    .drag_value_speed(fine_step)
    .custom_parser(parse_finite)
    .custom_formatter(|x, _| six_digits(x))
    .text(text);
    typed_on_enter(slider)
}

/// The longest width or depth the loader takes for a light edge `edge` of
/// length `len`: the one that puts its largest component at [`MAX_COORD`].
fn light_size_max(len: f64, edge: [f64; 3]) -> f64 {
    let largest = edge.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    // A hair below, so that rounding cannot lift a component past it.
    let max = if largest > 0.0 && len.is_finite() {
        MAX_COORD * (len / largest) * (1.0 - 1e-12)
    } else {
        MAX_COORD
    };
    max.max(LIGHT_SIZE_MIN)
}

/// The rail of a light size slider: around `scene_size` (see
/// [`LIGHT_RAIL_BELOW`]), reaching out to `len` if it lies beyond, so
/// that the handle shows where a loaded or typed size is; within what the
/// loader takes.
fn light_rail(scene_size: f64, len: f64, edge: [f64; 3]) -> (f64, f64) {
    let max = light_size_max(len, edge);
    let len = len.clamp(LIGHT_SIZE_MIN, max);
    let lo = (scene_size * LIGHT_RAIL_BELOW).min(len).max(LIGHT_SIZE_MIN);
    let hi = (scene_size * LIGHT_RAIL_ABOVE).max(len).min(max);
    (lo, hi.max(lo))
}

/// `slider` with its number field taking a typed value on Enter or on
/// leaving the field, not at each key: typing 4096 shadow rays rendered 4,
/// 40 and 409 first (each a full re-render), typing 0.25 as the resolution
/// scale rendered at 0.1 on the way, and a light size typed key by key
/// could be refused half-way (the value before the typing then lost).
fn typed_on_enter(slider: Slider<'_>) -> Slider<'_> {
    slider.update_while_editing(false)
}

/// A number to six significant digits, in plain notation from 10⁻³ to
/// 10⁶ and in scientific notation beyond (`2`, `0.005`, `1e-8`, `2.5e9`).
fn six_digits(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let rounded: f64 = format!("{x:.5e}").parse().unwrap_or(x);
    if (1e-3..1e6).contains(&rounded.abs()) {
        format!("{rounded}")
    } else {
        format!("{rounded:e}")
    }
}

/// Reads a typed number as egui does (spaces ignored, "−" as "-"), but
/// refuses NaN and infinities: egui would clamp NaN to the top of the
/// range and take "inf" or 1e999 as a number.
pub fn parse_finite(text: &str) -> Option<f64> {
    let text: String = text
        .chars()
        .filter(|c| !c.is_whitespace())
        .map(|c| if c == '\u{2212}' { '-' } else { c })
        .collect();
    text.parse::<f64>().ok().filter(|x| x.is_finite())
}

/// The smallest value a field the format wants above zero (shininess)
/// takes when typed; the format itself has no smaller bound.
const ABOVE_ZERO: f64 = f64::MIN_POSITIVE;

/// Buttons of the panel that the viewer acts on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    OpenScene,
    SavePng,
    SaveScene,
    ResetView,
    FrameAll,
}

/// What the panel did this frame.
#[derive(Default)]
pub struct ControlsOutput {
    /// The scene to render changed.
    pub changed: bool,
    pub action: Option<Action>,
}

/// State of the panel itself (not part of the scene).
#[derive(Default)]
pub struct ControlsState {
    /// Material selected in the editor.
    pub material: String,
    /// The scene's size (the largest side of the box around the light and
    /// the bounded objects; set by the viewer each frame): the light size
    /// sliders span around it.
    pub scene_size: f64,
    /// The light width's and depth's rails as last drawn: kept while the
    /// pointer is down and as it is released, since a rail that follows
    /// the size dragged (the scene's size grows with the light) would move
    /// under the pointer.
    light_rails: [Option<(f64, f64)>; 2],
}

pub fn controls_ui(
    ui: &mut Ui,
    state: &mut ControlsState,
    desc: &mut SceneDesc,
    view: &mut ViewSettings,
) -> ControlsOutput {
    let mut out = ControlsOutput::default();
    let mut changed = false;

    ui.horizontal_wrapped(|ui| {
        if ui
            .button("Open…")
            .on_hover_text("Ctrl+O: open a scene file (or drop one on the window)")
            .clicked()
        {
            out.action = Some(Action::OpenScene);
        }
        if ui
            .button("Save PNG…")
            .on_hover_text("Ctrl+S: the image at the scene's full resolution")
            .clicked()
        {
            out.action = Some(Action::SavePng);
        }
        if ui
            .button("Save scene…")
            .on_hover_text("Ctrl+Shift+S: write these settings as a scene file")
            .clicked()
        {
            out.action = Some(Action::SaveScene);
        }
        if ui
            .button("Frame all")
            .on_hover_text("F: the whole scene in view, same direction")
            .clicked()
        {
            out.action = Some(Action::FrameAll);
        }
        if ui
            .button("Reset view")
            .on_hover_text("Home: the scene's own camera")
            .clicked()
        {
            out.action = Some(Action::ResetView);
        }
    });
    ui.separator();

    egui::CollapsingHeader::new("Phong terms")
        .default_open(true)
        .show(ui, |ui| {
            let terms = &mut desc.render.terms;
            for (label, on, strength) in [
                ("Ambient", &mut view.ambient, &mut terms.ambient),
                ("Diffuse", &mut view.diffuse, &mut terms.diffuse),
                ("Specular", &mut view.specular, &mut terms.specular),
            ] {
                ui.horizontal(|ui| {
                    changed |= ui.checkbox(on, label).changed();
                    ui.add_enabled_ui(*on, |ui| {
                        changed |= ui
                            .add(
                                slider_within(strength, 0.0..=10.0, 0.0..=MAX_COLOUR)
                                    .text(format!("{label} strength"))
                                    // A recombine of the recorded paths:
                                    // cheap enough to follow the typing.
                                    .update_while_editing(true),
                            )
                            .changed();
                    });
                });
            }
            ui.horizontal(|ui| {
                let mut on = desc.render.shininess_override.is_some();
                if ui
                    .checkbox(&mut on, "Override shininess")
                    .on_hover_text("One Blinn–Phong exponent for every material")
                    .changed()
                {
                    desc.render.shininess_override = on.then_some(view.shininess);
                    changed = true;
                }
                ui.add_enabled_ui(on, |ui| {
                    if ui
                        .add(shininess_slider(&mut view.shininess, "Shininess"))
                        .changed()
                    {
                        desc.render.shininess_override = Some(view.shininess);
                        changed = true;
                    }
                });
            });
        });

    egui::CollapsingHeader::new("Shadows and reflections")
        .default_open(true)
        .show(ui, |ui| {
            let r = &mut desc.render;
            changed |= ui.checkbox(&mut r.shadows, "Shadows").changed();
            let (label, hover) = if r.area_light_model == AreaLightModel::Exact {
                (
                    "Fallback shadow rays",
                    "The exact model traces no shadow rays: these serve only the points \
                     it leaves to the analytic estimate (too many shadow pieces or mesh \
                     triangles in view, a light seen as a point)",
                )
            } else {
                ("Shadow rays", "Shadow rays per hit point (the final pass)")
            };
            changed |= ui
                .add(
                    slider(&mut r.shadow_rays, 1..=MAX_SHADOW_RAYS)
                        .logarithmic(true)
                        .text(label),
                )
                .on_hover_text(hover)
                .changed();
            if let Some(note) = points_note(r.sampling, r.shadow_rays) {
                ui.weak(note);
            }
            egui::ComboBox::from_label("Sampling")
                .selected_text(r.sampling.name())
                .show_ui(ui, |ui| {
                    for s in Sampling::ALL {
                        changed |= ui.selectable_value(&mut r.sampling, s, s.name()).changed();
                    }
                });
            changed |= ui
                .checkbox(&mut r.adaptive, "Adaptive shadow rays")
                .on_hover_text(
                    "A few probe rays first, the rest only where they disagree (faster, biased)",
                )
                .changed();
            egui::ComboBox::from_label("Area-light model")
                .selected_text(r.area_light_model.name())
                .show_ui(ui, |ui| {
                    for m in AreaLightModel::ALL {
                        changed |= ui
                            .selectable_value(&mut r.area_light_model, m, m.name())
                            .changed();
                    }
                });
            changed |= ui.checkbox(&mut view.reflections, "Reflections").changed();
            changed |= ui
                .checkbox(&mut r.cutaway, "Cut-away")
                .on_hover_text(
                    "C: camera rays pass through walls seen from behind \
                     (shadows and reflections unchanged)",
                )
                .changed();
            ui.add_enabled_ui(view.reflections, |ui| {
                changed |= ui
                    .add(slider(&mut r.max_depth, 1..=MAX_DEPTH).text("Max depth"))
                    .changed();
            });
            changed |= ui
                .add(typed_on_enter(
                    Slider::new(&mut view.resolution_scale, ViewSettings::SCALE_RANGE)
                        .custom_parser(parse_finite)
                        .text("Resolution scale"),
                ))
                .on_hover_text(
                    "Preview size relative to the scene's camera; export is always full size",
                )
                .changed();
            let (w, h) = (desc.camera.width, desc.camera.height);
            let shown = view.apply_size(w, h);
            if shown != (w, h) {
                ui.label(format!(
                    "Previewed at {}×{}; Save PNG writes {w}×{h}",
                    shown.0, shown.1
                ));
            }
        });

    egui::CollapsingHeader::new("Light")
        .default_open(true)
        .show(ui, |ui| changed |= light_ui(ui, state, desc));

    egui::CollapsingHeader::new("Materials")
        .default_open(true)
        .show(ui, |ui| changed |= material_ui(ui, state, desc));

    out.changed = changed;
    out
}

/// Position (centre) and size of the light rectangle.
fn light_ui(ui: &mut Ui, state: &mut ControlsState, desc: &mut SceneDesc) -> bool {
    let l = &mut desc.light;
    let len = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let mut centre: [f64; 3] =
        std::array::from_fn(|i| l.corner[i] + 0.5 * (l.edge_u[i] + l.edge_v[i]));
    let (mut w, mut d) = (len(l.edge_u), len(l.edge_v));
    let mut changed = false;
    ui.horizontal(|ui| {
        ui.label("Centre");
        for (c, name) in centre.iter_mut().zip(["x", "y", "z"]) {
            changed |= ui
                .add(
                    egui::DragValue::new(c)
                        .speed(0.02)
                        .range(-MAX_COORD..=MAX_COORD)
                        .clamp_existing_to_range(false)
                        .custom_parser(parse_finite)
                        .prefix(format!("{name} "))
                        .max_decimals(3)
                        // Taken on Enter or leaving the field, not at each
                        // key: typing 1e9 would apply 1 first, and a
                        // refused 1e9 would then fall back to 1, not to
                        // the value before the typing.
                        .update_while_editing(false),
                )
                .changed();
        }
    });
    // Sizes are relative to the light's own edges, so any light works.
    let (edge_u, edge_v) = (l.edge_u, l.edge_v);
    let scene_size = state.scene_size.max(MIN_SCENE_SIZE);
    let dragging = ui.input(|i| i.pointer.any_down() || i.pointer.any_released());
    let mut rail = |k: usize, len: f64, edge: [f64; 3]| match state.light_rails[k] {
        Some(r) if dragging => r,
        _ => *state.light_rails[k].insert(light_rail(scene_size, len, edge)),
    };
    let (rail_u, rail_v) = (rail(0, w, edge_u), rail(1, d, edge_v));
    changed |= ui
        .add(light_size_slider(&mut w, edge_u, rail_u, "Light width"))
        .changed();
    changed |= ui
        .add(light_size_slider(&mut d, edge_v, rail_v, "Light depth"))
        .changed();
    if ui.button("Square").on_hover_text("Depth = width").clicked() {
        d = w;
        changed = true;
    }
    if changed {
        let (lu, lv) = (len(l.edge_u), len(l.edge_v));
        l.edge_u = l.edge_u.map(|x| x * w / lu);
        l.edge_v = l.edge_v.map(|x| x * d / lv);
        // A centre at the format's edge must not push the corner past it.
        l.corner = std::array::from_fn(|i| {
            (centre[i] - 0.5 * (l.edge_u[i] + l.edge_v[i])).clamp(-MAX_COORD, MAX_COORD)
        });
    }
    ui.horizontal(|ui| {
        ui.label("Diffuse intensity");
        changed |= colour_edit(ui, &mut l.diffuse);
    });
    changed
}

/// Pick a material by name and edit its colours, shininess and
/// reflectivity.
fn material_ui(ui: &mut Ui, state: &mut ControlsState, desc: &mut SceneDesc) -> bool {
    if !desc.materials.contains_key(&state.material) {
        state.material = desc.materials.keys().next().cloned().unwrap_or_default();
    }
    egui::ComboBox::from_label("Material")
        .selected_text(state.material.as_str())
        .show_ui(ui, |ui| {
            for name in desc.materials.keys() {
                ui.selectable_value(&mut state.material, name.clone(), name);
            }
        });
    let Some(m) = desc.materials.get_mut(&state.material) else {
        return false;
    };
    let mut changed = false;
    egui::Grid::new("material").num_columns(2).show(ui, |ui| {
        for (label, colour) in [
            ("Ambient", &mut m.ambient),
            ("Diffuse", &mut m.diffuse),
            ("Specular", &mut m.specular),
        ] {
            ui.label(label);
            changed |= colour_edit(ui, colour);
            ui.end_row();
        }
    });
    changed |= ui
        .add(shininess_slider(&mut m.shininess, "Material shininess"))
        .changed();
    changed |= ui
        .add(slider(&mut m.reflectivity, 0.0..=1.0).text("Reflectivity"))
        .changed();
    changed
}

/// An egui colour picker on a linear f64 colour. Only a component the
/// picker really moved is written back: opening it, or moving another
/// component, leaves 0.3 as 0.3 (not its f32 rounding, 0.30000001).
fn colour_edit(ui: &mut Ui, c: &mut [f64; 3]) -> bool {
    let shown = c.map(|x| x as f32);
    let mut rgb = shown;
    if !ui.color_edit_button_rgb(&mut rgb).changed() {
        return false;
    }
    let mut changed = false;
    for i in 0..3 {
        if rgb[i] != shown[i] {
            c[i] = rgb[i] as f64;
            changed = true;
        }
    }
    changed
}

/// What a pattern makes of a shadow-ray count it does not take as it is
/// (the grids use the largest square at or below it; `mixed` adds as many
/// random points), so that the slider's number and the status bar's
/// samples per hit do not seem to disagree; `None` where it takes it.
pub(crate) fn points_note(sampling: Sampling, shadow_rays: u32) -> Option<String> {
    let points = points_per_hit(sampling, shadow_rays);
    if points == shadow_rays as usize {
        return None;
    }
    let side = grid_side(shadow_rays);
    let name = sampling.name();
    let noun = if points == 1 { "point" } else { "points" };
    let grid = format!("{name}: {points} {noun} per hit (a {side}×{side} grid");
    Some(match sampling {
        Sampling::Mixed => format!("{grid} and as many random)"),
        _ => format!("{grid})"),
    })
}
