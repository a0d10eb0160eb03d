//! The viewer, driven headless by egui_kittest: no display, no GPU. Each
//! test uses a tiny image so that renders take milliseconds.

use std::path::Path;
use std::time::{Duration, Instant};

mod common;

use common::viewer::{
    WAIT, double_click, drop_file, finished, harness, settle, settled, small_room, step_until,
};
use egui::accesskit::Role;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use penumbra::app::render_job::JobState;
use penumbra::app::{Viewer, ViewerOptions};
use penumbra::render::SEED_ROOM_JSON;
use penumbra::render::film::encode_srgb8;
use penumbra::render::{Film, Loaded, SceneDesc};

fn core_render(desc: &SceneDesc) -> Film {
    Loaded::new(desc).unwrap().render_image()
}

/// The sRGB bytes the texture should hold for a film.
fn assert_shows(v: &Viewer, film: &Film) {
    let shown = v.shown_image();
    assert_eq!(shown.size, [film.width as usize, film.height as usize]);
    for (i, (s, p)) in shown.pixels.iter().zip(&film.pixels).enumerate() {
        let [r, g, b] = encode_srgb8(*p);
        assert_eq!([s.r(), s.g(), s.b()], [r, g, b], "pixel {i}");
    }
}

/// The core's render of the small room changed by `edit`.
fn room_render(edit: impl FnOnce(&mut SceneDesc)) -> Film {
    let mut desc = small_room();
    edit(&mut desc);
    core_render(&desc)
}

#[test]
fn first_frame_renders_the_scene_into_the_texture() {
    let h = settled(ViewerOptions::new(small_room()));
    let film = finished(h.state());
    assert_eq!(film, core_render(&small_room()));
    assert_shows(h.state(), &film);
    // The status bar: 16 shadow rays = a preview pass and one full pass.
    h.get_by_label("pass 2 of 2");
    h.get_by_label("16 samples/hit");
    h.get_by_label_contains("Mray/s");
}

/// The exact model traces no shadow rays: the bar names it instead of a
/// count of samples per hit that nothing uses.
#[test]
fn with_the_exact_model_the_status_bar_names_it_instead_of_samples() {
    let mut desc = small_room();
    desc.render.area_light_model = penumbra::render::AreaLightModel::Exact;
    let h = settled(ViewerOptions::new(desc.clone()));
    assert_eq!(finished(h.state()), core_render(&desc));
    h.get_by_label("exact light");
    assert!(h.query_by_label_contains("samples/hit").is_none());
    // Its shadow-ray count serves only the points it falls back on, and
    // the slider says so.
    h.get_by_role_and_label(Role::Slider, "Fallback shadow rays");
    assert!(h.query_by_label("Shadow rays").is_none());
}

/// A grid takes the largest square at or below the slider's count: the
/// panel says what it uses, so that the slider and the status bar's
/// samples per hit do not seem to disagree; a square count needs no note.
#[test]
fn the_panel_says_how_many_points_a_grid_makes_of_the_shadow_rays() {
    let mut desc = small_room();
    desc.render.shadow_rays = 2;
    let h = settled(ViewerOptions::new(desc.clone()));
    h.get_by_label("grid: 1 point per hit (a 1×1 grid)");
    h.get_by_label("1 samples/hit");
    desc.render.shadow_rays = 20;
    desc.render.sampling = penumbra::render::Sampling::Mixed;
    let h = settled(ViewerOptions::new(desc.clone()));
    h.get_by_label("mixed: 32 points per hit (a 4×4 grid and as many random)");
    h.get_by_label("32 samples/hit");
    desc.render.shadow_rays = 16;
    desc.render.sampling = penumbra::render::Sampling::Grid;
    let h = settled(ViewerOptions::new(desc));
    assert!(h.query_by_label_contains("per hit (a").is_none());
}

#[test]
fn slider_move_restarts_the_render_with_the_new_value() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let before = h.state().render_generation();

    h.get_by_role_and_label(Role::Slider, "Shadow rays")
        .set_value_accesskit(4.0);
    h.step();

    let v = h.state();
    assert_eq!(v.desc().render.shadow_rays, 4);
    assert!(v.render_generation() > before, "no restart");
    settle(&mut h);
    let (generation, desc) = h.state().worker_desc().unwrap();
    assert_eq!(generation, h.state().render_generation());
    assert_eq!(desc.render.shadow_rays, 4);
    let film = finished(h.state());
    assert_eq!(film, room_render(|d| d.render.shadow_rays = 4));
    assert_shows(h.state(), &film);
}

#[test]
fn rapid_changes_leave_only_the_last_render() {
    let mut h = harness(ViewerOptions::new(small_room()));
    for k in 1..=20 {
        h.state_mut()
            .edit(|d, _| d.render.terms.ambient = k as f64 / 10.0);
    }
    settle(&mut h);
    let (_, desc) = h.state().worker_desc().unwrap();
    assert_eq!(desc.render.terms.ambient, 2.0);
    // Stale requests were dropped, not queued: 21 requests, few renders.
    let started = h.state().renders_started();
    assert!(started <= 10, "{started} renders started for 21 requests");
    let expected = room_render(|d| d.render.terms.ambient = 2.0);
    assert_eq!(finished(h.state()), expected);
}

#[test]
fn ambient_only_equals_the_cores_ambient_only_render() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let full = finished(h.state());

    h.get_by_role_and_label(Role::CheckBox, "Diffuse").click();
    h.step();
    h.get_by_role_and_label(Role::CheckBox, "Specular").click();
    h.step();
    assert!(!h.state().view_settings().diffuse && !h.state().view_settings().specular);
    settle(&mut h);

    let mut ambient_only = small_room();
    ambient_only.render.terms.diffuse = 0.0;
    ambient_only.render.terms.specular = 0.0;
    let expected = core_render(&ambient_only);
    let film = finished(h.state());
    assert_eq!(film, expected);
    assert_ne!(film, full);
    assert_shows(h.state(), &film);
    // The strengths are kept for when the terms come back on.
    assert_eq!(h.state().desc().render.terms.diffuse, 1.0);
}

#[test]
fn shadows_toggle_and_reflections_toggle_reach_the_renderer() {
    let mut h = settled(ViewerOptions::new(small_room()));
    h.get_by_role_and_label(Role::CheckBox, "Shadows").click();
    h.step();
    h.get_by_role_and_label(Role::CheckBox, "Reflections")
        .click();
    h.step();
    settle(&mut h);
    let expected = room_render(|d| {
        d.render.shadows = false;
        d.render.max_depth = 1;
    });
    assert_eq!(finished(h.state()), expected);
}

#[test]
fn sampling_model_and_adaptive_controls_reach_the_renderer() {
    let mut h = settled(ViewerOptions::new(small_room()));
    h.get_by_role_and_label(Role::CheckBox, "Adaptive shadow rays")
        .click();
    h.step();
    h.state_mut().edit(|d, _| {
        d.render.sampling = penumbra::render::Sampling::Stratified;
        d.render.area_light_model = penumbra::render::AreaLightModel::NearestPoint;
    });
    settle(&mut h);
    let expected = room_render(|d| {
        d.render.adaptive = true;
        d.render.sampling = penumbra::render::Sampling::Stratified;
        d.render.area_light_model = penumbra::render::AreaLightModel::NearestPoint;
    });
    assert_eq!(finished(h.state()), expected);
}

#[test]
fn ctrl_s_exports_a_full_size_png_that_decodes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("shot.png");
    let mut h = harness(ViewerOptions::new(small_room()));
    // Preview at half size: the export must still be the scene's size.
    h.get_by_role_and_label(Role::Slider, "Resolution scale")
        .set_value_accesskit(0.5);
    h.step();
    settle(&mut h);
    assert_eq!(h.state().shown_image().size, [32, 18]);

    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    h.step();
    h.state_mut()
        .dialog_mut()
        .expect("the save dialog opens")
        .path = out.display().to_string();
    h.step();
    h.get_by_role_and_label(Role::Button, "Save").click();
    h.step();
    h.state_mut().wait_for_saves(WAIT);

    let img = image::open(&out).expect("the PNG decodes").into_rgb8();
    assert_eq!(img.dimensions(), (64, 36));
    let expected = core_render(&small_room());
    assert_eq!(img.into_raw(), expected.to_srgb8());
    assert!(h.state().notice().unwrap().contains("shot.png"));
    assert!(h.state().banner().is_none());
}

#[test]
fn a_failed_export_is_shown_not_panicked() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let ctx = h.ctx.clone();
    h.state_mut()
        .save_png(&ctx, "/nonexistent-dir/x/out.png".into());
    h.state_mut().wait_for_saves(WAIT);
    h.step();
    let banner = h.state().banner().expect("an error banner").to_string();
    assert!(banner.contains("out.png"), "{banner}");
    h.get_by_label_contains("nonexistent-dir");
}

#[test]
fn saved_scene_loads_again_to_the_same_image() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("saved.json");
    let mut h = harness(ViewerOptions::new(small_room()));
    h.state_mut().edit(|d, view| {
        view.specular = false;
        view.reflections = false;
        d.render.shininess_override = Some(7.0);
        d.light.corner[0] = -1.5;
    });
    settle(&mut h);
    let shown = finished(h.state());
    let ctx = h.ctx.clone();
    h.state_mut().save_scene(&ctx, path.clone());
    h.state_mut().wait_for_saves(WAIT);
    let loaded = SceneDesc::load(&path).unwrap();
    assert_eq!(core_render(&loaded), shown);
}

fn write(path: &Path, text: &str) {
    // Write and rename, as editors do (the watcher must see this too).
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, text).unwrap();
    std::fs::rename(&tmp, path).unwrap();
}

#[test]
fn a_broken_scene_file_shows_a_banner_and_keeps_the_old_image() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("room.json");
    let good = small_room().to_json();
    write(&path, &good);
    let mut options = ViewerOptions::new(SceneDesc::load(&path).unwrap());
    options.scene_path = Some(path.clone());
    let mut h = settled(options);
    let image = h.state().shown_image().clone();
    let generation = h.state().render_generation();

    // The sphere's radius made negative: the loader names the field.
    let broken = good.replacen("\"radius\": 1.0", "\"radius\": -1.0", 1);
    assert_ne!(broken, good);
    write(&path, &broken);
    step_until(&mut h, |v| v.banner().is_some());
    let banner = h.state().banner().unwrap().to_string();
    assert!(
        banner.contains("room.json") && banner.contains("radius"),
        "{banner}"
    );
    h.get_by_label_contains("radius");
    assert_eq!(h.state().render_generation(), generation, "no new render");
    assert_eq!(h.state().shown_image(), &image);
    assert_eq!(h.state().desc(), &small_room());

    // Fixed on disk: reloaded, banner gone, the new scene rendered.
    let mut fixed = small_room();
    fixed.materials.get_mut("red").unwrap().diffuse = [0.2, 0.2, 0.8];
    write(&path, &fixed.to_json());
    step_until(&mut h, |v| v.banner().is_none());
    settle(&mut h);
    assert_eq!(finished(h.state()), core_render(&fixed));
}

#[test]
fn reload_keeps_the_camera_when_the_file_did_not_change_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("room.json");
    write(&path, &small_room().to_json());
    let mut options = ViewerOptions::new(SceneDesc::load(&path).unwrap());
    options.scene_path = Some(path.clone());
    let mut h = settled(options);
    h.state_mut().edit(|d, _| d.camera.position[0] = 1.0);
    let mut changed = small_room();
    changed.render.shadow_rays = 4;
    write(&path, &changed.to_json());
    step_until(&mut h, |v| v.desc().render.shadow_rays == 4);
    assert_eq!(h.state().desc().camera.position[0], 1.0);
}

#[test]
fn a_panicking_worker_shows_the_error_and_the_viewer_goes_on() {
    let mut h = settled(ViewerOptions::new(small_room()));
    h.state().inject_worker_panic();
    h.state_mut().edit(|d, _| d.render.terms.ambient = 0.5);
    settle(&mut h);
    let banner = h.state().banner().expect("an error banner").to_string();
    assert!(banner.contains("panicked"), "{banner}");

    h.state_mut().edit(|d, _| d.render.terms.ambient = 0.7);
    settle(&mut h);
    let expected = room_render(|d| d.render.terms.ambient = 0.7);
    assert_eq!(finished(h.state()), expected);
}

#[test]
fn dragging_the_image_orbits_the_camera_and_double_click_picks() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let before = h.state().desc().camera.clone();
    let generation = h.state().render_generation();
    // The image area: right of the side panel, above the status bar.
    let centre = egui::pos2(800.0, 450.0);
    h.drag_at(centre);
    h.step();
    h.hover_at(centre + egui::vec2(40.0, 0.0));
    h.step();
    h.drop_at(centre + egui::vec2(40.0, 0.0));
    h.step();
    let after = h.state().desc().camera.clone();
    assert_ne!(after.position, before.position, "orbit");
    assert_eq!(after.look_at, before.look_at);
    assert!(h.state().render_generation() > generation);

    h.get_by_role_and_label(Role::Button, "Reset view").click();
    h.step();
    assert_eq!(h.state().desc().camera, before);
    settle(&mut h);

    let film = finished(h.state());
    // Double-click the middle of the image: the back wall is there.
    double_click(&mut h, centre);
    let pick = h.state().pick().expect("double-click shows a pick").clone();
    assert!(pick.what.contains("objects["), "{pick:?}");
    assert!(pick.material.is_some());
    let (x, y) = pick.pixel;
    assert_eq!(pick.linear_rgb, Some(film.get(x, y).to_array()));
    // The double-click also made that point the pivot: the camera stayed
    // and turned to it, so it is now at the image's centre.
    let cam = h.state().desc().camera.clone();
    assert_eq!(cam.position, before.position);
    assert_ne!(cam.look_at, before.look_at);
    let (sx, sy) = penumbra::app::camera_control::project(&cam, cam.look_at.into()).unwrap();
    assert!((sx - 32.0).abs() < 1e-6 && (sy - 18.0).abs() < 1e-6);
}

// ----- reference and error readout ---------------------------------------

use penumbra::app::reference::{Match, ViewMode, converged};
use penumbra::render::compare::{compare, diff_image};
use penumbra::render::output::write_film;

/// Writes a linear EXR (exact values, unlike an 8-bit PNG).
fn write_exr(dir: &Path, name: &str, film: &Film) -> std::path::PathBuf {
    let path = dir.join(name);
    write_film(film, &path).unwrap();
    path
}

/// Waits for the reference task and then for the comparison, with a frame
/// after each so that the viewer takes and shows the results.
/// The small room at 32×18: its 4096-ray reference takes moments.
fn reference_room() -> SceneDesc {
    let mut room = small_room();
    room.camera.width = 32;
    room.camera.height = 18;
    room
}

/// Clicks *Compute reference* and takes the frame that starts it.
fn compute_reference(h: &mut Harness<'static, Viewer>) {
    h.get_by_role_and_label(Role::Button, "Compute reference")
        .click();
    h.step();
}

fn settle_reference(h: &mut Harness<'static, Viewer>) {
    assert!(h.state_mut().wait_for_reference(WAIT), "no reference");
    h.step();
    assert!(h.state().wait_for_error(WAIT), "no comparison");
    h.step();
}

/// Moves a slider, then waits for the render it starts (if `render`) and
/// for the comparison that follows, with a frame after each.
fn slide_and_compare(h: &mut Harness<'static, Viewer>, slider: &str, value: f64, render: bool) {
    h.get_by_role_and_label(Role::Slider, slider)
        .set_value_accesskit(value);
    h.step();
    if render {
        settle(h);
    }
    assert!(h.state().wait_for_error(WAIT), "no comparison");
    h.step();
}

/// The status bar's text for a comparison.
fn readout_label(film: &Film, reference: &Film) -> String {
    let c = compare(film, reference).unwrap();
    format!("RMSE {:.3e} · PSNR {:.2} dB", c.rmse, c.psnr)
}

#[test]
fn loading_the_cores_own_render_as_reference_reads_rmse_zero() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_exr(dir.path(), "same.exr", &core_render(&small_room()));
    let mut h = settled(ViewerOptions::new(small_room()));

    h.get_by_role_and_label(Role::Button, "Load reference…")
        .click();
    h.step();
    h.state_mut()
        .dialog_mut()
        .expect("the load dialog opens")
        .path = path.display().to_string();
    h.step();
    h.get_by_role_and_label(Role::Button, "Load").click();
    h.step();
    settle_reference(&mut h);

    assert_eq!(h.state().reference_match(), Some(Match::Same));
    let shown = h.state().error_shown().expect("a readout");
    assert_eq!(shown.comparison.rmse, 0.0);
    assert_eq!(shown.pass, None, "the finished image was compared");
    h.get_by_label("RMSE 0 · PSNR inf dB");
    assert!(h.state().banner().is_none());
}

#[test]
fn a_reference_of_more_shadow_rays_reads_the_cores_rmse_and_error_image() {
    let dir = tempfile::tempdir().unwrap();
    let mut converged = small_room();
    converged.render.shadow_rays = 256;
    converged.render.sampling = penumbra::render::Sampling::Stratified;
    let reference = core_render(&converged);
    let path = write_exr(dir.path(), "ref.exr", &reference);
    let mut h = settled(ViewerOptions::new(small_room()));
    let ctx = h.ctx.clone();
    h.state_mut().load_reference(&ctx, path);
    h.step();
    settle_reference(&mut h);

    let film = finished(h.state());
    let expected = compare(&film, &reference).unwrap();
    assert!(expected.rmse > 0.0);
    let shown = h.state().error_shown().expect("a readout").clone();
    assert_eq!(shown.comparison, expected);
    h.get_by_label(&readout_label(&film, &reference));

    // The error view: the core's false-colour image, black where equal.
    assert!(h.query_by_label_contains("white = ").is_none());
    h.get_by_label("Error").click();
    // New overlays are measured in an invisible first frame.
    h.step();
    h.step();
    assert_eq!(h.state().view_mode(), ViewMode::Error);
    let (rgb, scale) = diff_image(&film, &reference, None).unwrap();
    assert_eq!(shown.scale, scale);
    let img = &shown.image;
    assert_eq!(img.size, [64, 36]);
    let mut coloured = 0;
    for (i, p) in img.pixels.iter().enumerate() {
        assert_eq!([p.r(), p.g(), p.b()], rgb[3 * i..3 * i + 3], "pixel {i}");
        if film.pixels[i] == reference.pixels[i] {
            assert_eq!(*p, egui::Color32::BLACK, "pixel {i}");
        } else if (film.pixels[i].as_dvec3() - reference.pixels[i].as_dvec3())
            .abs()
            .max_element()
            > 0.1 * scale
        {
            assert_ne!(*p, egui::Color32::BLACK, "pixel {i}");
            coloured += 1;
        }
    }
    assert!(coloured > 0, "no visible difference");
    h.get_by_label(&format!("white = {scale:.1e}"));

    // Two stops of exposure: white at a quarter of the largest difference.
    slide_and_compare(&mut h, "Error exposure", 2.0, false);
    let brighter = h.state().error_shown().unwrap();
    assert_eq!(brighter.scale, scale / 4.0);
    assert_eq!(brighter.comparison, expected);
    h.get_by_label(&format!("white = {:.1e}", scale / 4.0));
}

#[test]
fn a_reference_of_another_size_is_not_compared() {
    let dir = tempfile::tempdir().unwrap();
    let mut half = small_room();
    half.camera.width = 32;
    half.camera.height = 18;
    let path = write_exr(dir.path(), "half.exr", &core_render(&half));
    let mut h = settled(ViewerOptions::new(small_room()));
    let ctx = h.ctx.clone();
    h.state_mut().load_reference(&ctx, path);
    h.step();
    settle_reference(&mut h);
    assert_eq!(h.state().reference_match(), Some(Match::SizeDiffers));
    h.get_by_label("reference: size differs");
    assert!(h.query_by_label_contains("RMSE").is_none());
    assert!(h.state().error_shown().is_none());

    // At half the resolution the sizes agree: compared, and equal.
    slide_and_compare(&mut h, "Resolution scale", 0.5, true);
    assert_eq!(h.state().reference_match(), Some(Match::Same));
    h.get_by_label("RMSE 0 · PSNR inf dB");
}

/// With several camera samples a pixel, the computed reference puts them
/// where the image does (scrambled by the image's seed): its error is the
/// light's, not the anti-aliasing's, far below the error against the same
/// reference with its own places; a new seed moves the image's samples,
/// so the reference no longer applies.
#[test]
fn an_anti_aliased_image_s_reference_samples_the_image_s_places() {
    let mut room = reference_room();
    room.render.samples_per_pixel = 4;
    let mut h = settled(ViewerOptions::new(room.clone()));
    compute_reference(&mut h);
    settle_reference(&mut h);
    let reference = h.state().reference().expect("a reference").film.clone();
    let mut same_places = Loaded::new(&converged(&room)).unwrap();
    same_places.settings.camera_seed = room.render.seed;
    assert_eq!(*reference, same_places.render_image());
    let film = finished(h.state());
    let light_only = compare(&film, &reference).unwrap().rmse;
    let own_places = core_render(&converged(&room));
    assert!(
        light_only * 4.0 < compare(&film, &own_places).unwrap().rmse,
        "{light_only}"
    );

    h.state_mut().edit(|d, _| d.render.seed += 1);
    settle(&mut h);
    assert_eq!(h.state().reference_match(), Some(Match::SettingsDiffer));
}

#[test]
fn computing_a_reference_in_the_background_then_reads_the_error() {
    let room = reference_room();
    let mut h = settled(ViewerOptions::new(room.clone()));
    compute_reference(&mut h);
    assert!(h.state().reference_busy());
    settle_reference(&mut h);
    assert!(!h.state().reference_busy());

    // The converged render of the image on screen.
    let converged = converged(&room);
    assert_eq!(converged.render.shadow_rays, 4096);
    assert_eq!(
        converged.render.sampling,
        penumbra::render::Sampling::Stratified
    );
    let reference = h.state().reference().expect("a reference").film.clone();
    assert_eq!(*reference, core_render(&converged));
    let film = finished(h.state());
    assert_eq!(
        h.state().error_shown().unwrap().comparison,
        compare(&film, &reference).unwrap()
    );
    h.get_by_label(&readout_label(&film, &reference));

    // Fewer shadow rays: the same reference, a larger error.
    slide_and_compare(&mut h, "Shadow rays", 4.0, true);
    assert_eq!(h.state().reference_match(), Some(Match::Same));
    let fewer = finished(h.state());
    assert!(compare(&fewer, &reference).unwrap().rmse > compare(&film, &reference).unwrap().rmse);
    h.get_by_label(&readout_label(&fewer, &reference));

    // Another scene: the reference no longer applies.
    h.state_mut().edit(|d, _| d.light.corner[0] += 0.5);
    h.step();
    assert_eq!(h.state().reference_match(), Some(Match::SettingsDiffer));
    h.get_by_label("reference: settings differ");
}

#[test]
fn a_reference_computation_is_cancelled_by_the_button_or_a_scene_change() {
    let mut room = small_room();
    // Large enough to take seconds at 4096 shadow rays.
    room.camera.width = 320;
    room.camera.height = 180;
    room.render.shadow_rays = 1;
    let mut h = settled(ViewerOptions::new(room));

    compute_reference(&mut h);
    assert!(h.state().reference_busy());
    // Only the estimator changes: the reference still applies.
    h.state_mut().edit(|d, _| d.render.shadow_rays = 2);
    h.step();
    assert!(h.state().reference_busy());
    h.get_by_role_and_label(Role::Button, "Cancel").click();
    h.step();
    assert!(!h.state().reference_busy());
    assert_eq!(h.state().notice(), Some("reference cancelled"));

    compute_reference(&mut h);
    assert!(h.state().reference_busy());
    h.state_mut().edit(|d, _| d.camera.position[0] += 0.1);
    h.step();
    assert!(!h.state().reference_busy());
    assert!(h.state().notice().unwrap().contains("cancelled"));
    assert!(h.state().reference().is_none());
}

#[test]
fn values_outside_the_sliders_ranges_load_show_and_stay_unchanged() {
    let mut d = small_room();
    d.render.shadow_rays = 4096;
    d.render.terms.diffuse = 10.0;
    d.render.max_depth = 16;
    let m = d.materials.get_mut("steel").unwrap();
    m.shininess = 0.5;
    m.diffuse = [0.3, 0.7, 0.1];
    d.light.diffuse = [0.3, 3.0, 0.3];
    let mut h = harness(ViewerOptions::new(d.clone()));
    for _ in 0..4 {
        h.step();
    }
    assert_eq!(
        h.state().desc(),
        &d,
        "showing the controls changed the scene"
    );
    // The worker takes the request in its own time (later under load).
    step_until(&mut h, |v| v.worker_desc().is_some());
    assert_eq!(h.state().desc(), &d);
    let worker = h.state().worker_desc().expect("a render started").1;
    assert_eq!(worker.render.shadow_rays, 4096);
    assert_eq!(worker.render.terms.diffuse, 10.0);
}

// ----- camera, undo, unsaved edits, launch, keys ----------------------------

use penumbra::app::camera_control::project;
use penumbra::app::viewer::Confirm;

/// Waits for the scene loads under way, then a frame takes the result.
fn loaded(h: &mut Harness<'static, Viewer>) {
    assert!(h.state().wait_for_loads(WAIT), "a load did not end");
    h.step();
}

/// Drags on the image from `from` by `by` in a few steps (one gesture).
fn drag_image(h: &mut Harness<'static, Viewer>, from: egui::Pos2, by: egui::Vec2) {
    h.drag_at(from);
    h.step();
    for k in 1..=4 {
        h.hover_at(from + by * (k as f32 / 4.0));
        h.step();
    }
    h.drop_at(from + by);
    h.step();
}

/// The nearest surface the camera ray through image point (x, y) meets:
/// its distance, for the scene as the viewer renders it.
fn camera_distance(v: &Viewer, x: f64, y: f64, cutaway: bool) -> Option<f64> {
    let loaded = Loaded::new(&v.render_desc()).unwrap();
    let ray = loaded.scene.camera.ray(x, y);
    loaded.scene.camera_hit(&ray, cutaway).map(|(_, t)| t)
}

#[test]
fn an_orbit_about_the_pivot_keeps_it_in_view_with_the_cutaway() {
    let mut h = settled(ViewerOptions::new(small_room()));
    // The pivot on the first bounded object found left of the centre row
    // (a sphere or box, not a wall): double-click there.
    let loaded = Loaded::new(&h.state().render_desc()).unwrap();
    let px = (0..64)
        .find(|&x| {
            let ray = loaded.scene.camera.pixel_ray(x, 24);
            matches!(loaded.scene.closest_hit(&ray),
                Some((penumbra::render::HitTarget::Object(i), _))
                    if loaded.scene.objects[i as usize].bounds.is_some())
        })
        .expect("an object in the row");
    assert!(h.state_mut().set_pivot_at(px, 24));
    let pivot = glam::DVec3::from(h.state().desc().camera.look_at);
    h.get_by_role_and_label(Role::CheckBox, "Cut-away").click();
    h.step();
    assert!(h.state().desc().render.cutaway);

    // Orbit far round (well past the ~100 px that put the camera behind a
    // wall): the pivot stays at the image's centre and, with the cut-away,
    // nothing hides it.
    let centre = egui::pos2(800.0, 450.0);
    for _ in 0..3 {
        drag_image(&mut h, centre, egui::vec2(160.0, 0.0));
        let cam = h.state().desc().camera.clone();
        assert_eq!(glam::DVec3::from(cam.look_at), pivot);
        let (x, y) = project(&cam, pivot).expect("the pivot is in front");
        assert!((x - 32.0).abs() < 1e-6 && (y - 18.0).abs() < 1e-6);
        let dist = (pivot - glam::DVec3::from(cam.position)).length();
        let seen = camera_distance(h.state(), x, y, true).expect("a surface");
        assert!((seen - dist).abs() < 1e-6 * dist, "hidden: {seen} < {dist}");
    }
    // Without the cut-away a wall stands between (the bug this fixes), and
    // the viewer says so.
    h.key_press(egui::Key::C);
    h.step();
    assert!(!h.state().desc().render.cutaway);
    assert!(h.state().notice().unwrap().contains("behind a wall"));
    let cam = h.state().desc().camera.clone();
    let dist = (pivot - glam::DVec3::from(cam.position)).length();
    let blocked = camera_distance(h.state(), 32.0, 18.0, false).unwrap();
    assert!(
        blocked < dist * 0.999,
        "no wall in the way: test orbit too short"
    );
    settle(&mut h);
    // The viewer's image is the core's render of the cut-away scene.
    assert_eq!(finished(h.state()), core_render(&h.state().render_desc()));
}

#[test]
fn frame_all_shows_the_whole_scene_and_home_resets_the_camera() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let home = h.state().desc().camera.clone();
    // Far off, zoomed in on a corner.
    h.state_mut().edit(|d, _| {
        d.camera.position = [9.0, 1.0, 30.0];
        d.camera.look_at = [3.0, 0.5, 2.0];
    });
    h.key_press(egui::Key::F);
    h.step();
    let cam = h.state().desc().camera.clone();
    assert_ne!(cam.position, [9.0, 1.0, 30.0]);
    let loaded = Loaded::new(&h.state().render_desc()).unwrap();
    let b = loaded.scene.object_bounds.unwrap();
    let mut points: Vec<glam::DVec3> = loaded.scene.light.shape.corners().to_vec();
    for i in 0..8 {
        points.push(glam::DVec3::new(
            if i & 1 == 0 { b.min.x } else { b.max.x },
            if i & 2 == 0 { b.min.y } else { b.max.y },
            if i & 4 == 0 { b.min.z } else { b.max.z },
        ));
    }
    for p in points {
        let (x, y) = project(&cam, p).expect("in front");
        assert!(
            (0.0..=64.0).contains(&x) && (0.0..=36.0).contains(&y),
            "{p} at ({x}, {y})"
        );
    }
    h.key_press(egui::Key::Home);
    h.step();
    assert_eq!(h.state().desc().camera, home);
}

#[test]
fn undo_restores_the_image_bit_for_bit_and_a_drag_is_one_step() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let original = finished(h.state());
    let camera = h.state().desc().camera.clone();
    assert!(!h.state().can_undo());

    // A real mouse drag along the "Shadow rays" slider: many values, one step.
    let rect = h.get_by_role_and_label(Role::Slider, "Shadow rays").rect();
    let start = rect.center();
    h.drag_at(start);
    h.step();
    for dx in [-20.0, -40.0, -60.0, -80.0] {
        h.hover_at(start + egui::vec2(dx, 0.0));
        h.step();
    }
    h.drop_at(start + egui::vec2(-80.0, 0.0));
    h.step();
    let rays = h.state().desc().render.shadow_rays;
    assert!(rays < 16, "the drag moved the slider: {rays}");
    // Then an orbit (another drag) and a toggle.
    drag_image(&mut h, egui::pos2(800.0, 450.0), egui::vec2(60.0, 20.0));
    assert_ne!(h.state().desc().camera, camera);
    h.get_by_role_and_label(Role::CheckBox, "Shadows").click();
    h.step();
    settle(&mut h);
    let edited = finished(h.state());
    assert_ne!(edited, original);

    // Three steps back (Ctrl+Z): the original image, bit for bit.
    for _ in 0..3 {
        h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
        h.step();
    }
    assert_eq!(h.state().desc(), &small_room());
    settle(&mut h);
    assert_eq!(finished(h.state()), original);
    assert_shows(h.state(), &original);
    assert!(!h.state().can_undo());
    assert!(!h.state_mut().undo(), "nothing more to undo");

    // Redo all three (Ctrl+Shift+Z twice, Ctrl+Y once): the edited image.
    h.key_press_modifiers(
        egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
        egui::Key::Z,
    );
    h.step();
    assert_eq!(h.state().desc().render.shadow_rays, rays);
    assert_eq!(h.state().desc().camera, camera);
    h.key_press_modifiers(
        egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
        egui::Key::Z,
    );
    h.step();
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Y);
    h.step();
    assert!(!h.state().desc().render.shadows);
    settle(&mut h);
    assert_eq!(finished(h.state()), edited);
}

#[test]
fn unsaved_edits_mark_the_title_and_quit_or_open_asks_first() {
    let dir = tempfile::tempdir().unwrap();
    let other = dir.path().join("other.json");
    let mut o = small_room();
    o.render.shadow_rays = 4;
    write(&other, &o.to_json());
    let mut h = settled(ViewerOptions::new(small_room()));
    assert_eq!(h.state().title(), "seed room — penumbra");
    assert!(!h.state().is_dirty());
    h.get_by_role_and_label(Role::CheckBox, "Specular").click();
    h.step();
    assert!(h.state().is_dirty());
    assert_eq!(h.state().title(), "seed room • — penumbra");

    // Quit with unsaved edits: a question, and Cancel keeps everything.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Q);
    h.step();
    let ctx = h.ctx.clone();
    h.state_mut().request_quit(&ctx);
    h.step();
    h.step();
    assert_eq!(h.state().confirm(), Some(&Confirm::Quit));
    h.get_by_label("Unsaved changes");
    h.get_by_role_and_label(Role::Button, "Cancel").click();
    h.step();
    assert!(h.state().confirm().is_none());
    assert!(!h.state().view_settings().specular);

    // Opening (here by dropping a file) asks too; "Open" goes on.
    drop_file(&mut h, &other);
    h.step();
    assert_eq!(h.state().confirm(), Some(&Confirm::Open(other.clone())));
    h.step();
    h.get_by_role_and_label(Role::Button, "Open").click();
    h.step();
    loaded(&mut h);
    assert_eq!(h.state().scene_path(), Some(other.as_path()));
    assert_eq!(h.state().desc(), &o);
    assert!(!h.state().is_dirty());
    assert_eq!(h.state().title(), "other.json — penumbra");
    // Undo does not cross into another file.
    assert!(!h.state().can_undo());
}

#[test]
fn dropping_a_scene_file_opens_it_and_a_png_loads_a_reference() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("dropped.json");
    let mut d = small_room();
    d.render.terms.ambient = 0.5;
    write(&scene, &d.to_json());
    let mut h = settled(ViewerOptions::new(small_room()));
    drop_file(&mut h, &scene);
    h.step();
    loaded(&mut h);
    assert_eq!(h.state().scene_path(), Some(scene.as_path()));
    assert_eq!(h.state().recent()[0], std::path::absolute(&scene).unwrap());
    settle(&mut h);
    assert_eq!(finished(h.state()), core_render(&d));

    let png = dir.path().join("ref.exr");
    write_film(&core_render(&d), &png).unwrap();
    drop_file(&mut h, &png);
    h.step();
    settle_reference(&mut h);
    assert_eq!(h.state().reference_match(), Some(Match::Same));
    h.get_by_label("RMSE 0 · PSNR inf dB");
}

#[test]
fn a_hot_reload_takes_the_files_changes_keeps_other_edits_and_is_undoable() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("room.json");
    write(&path, &small_room().to_json());
    let mut options = ViewerOptions::new(SceneDesc::load(&path).unwrap());
    options.scene_path = Some(path.clone());
    let mut h = settled(options);
    // Edits in the viewer: shadow rays, a material's shininess, the camera,
    // a toggle.
    h.state_mut().edit(|d, v| {
        d.render.shadow_rays = 8;
        d.materials.get_mut("steel").unwrap().shininess = 3.0;
        d.camera.position[0] = 1.0;
        v.specular = false;
    });
    h.step();
    let edited = h.state().desc().clone();
    // The file changes other fields, and one of the edited ones.
    let mut file = small_room();
    file.materials.get_mut("red").unwrap().diffuse = [0.1, 0.2, 0.9];
    file.render.max_depth = 2;
    file.materials.get_mut("steel").unwrap().shininess = 9.0;
    write(&path, &file.to_json());
    step_until(&mut h, |v| v.desc().render.max_depth == 2);
    let d = h.state().desc().clone();
    // The file's changes, field by field...
    assert_eq!(d.materials["red"].diffuse, [0.1, 0.2, 0.9]);
    assert_eq!(d.materials["steel"].shininess, 9.0);
    // ...and every edit of a field the file left alone.
    assert_eq!(d.render.shadow_rays, 8);
    assert_eq!(d.camera.position[0], 1.0);
    assert!(!h.state().view_settings().specular);
    assert!(h.state().is_dirty());
    let mut expected = file.clone();
    expected.render.shadow_rays = 8;
    expected.camera.position[0] = 1.0;
    assert_eq!(d, expected);
    // One Ctrl+Z: the state just before the reload.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.step();
    assert_eq!(h.state().desc(), &edited);
}

#[test]
fn launch_with_a_broken_file_shows_the_seed_room_and_loads_it_once_fixed() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.json");
    std::fs::write(&path, "{ \"format\": 1, ").unwrap();
    let args = penumbra::cli::ViewArgs {
        scene: Some(path.clone()),
        refine_spp: Some(1),
        ..Default::default()
    };
    let options = ViewerOptions::from_args(&args).expect("the viewer starts");
    let mut h = settled(options);
    let banner = h
        .state()
        .banner()
        .expect("the error in the banner")
        .to_string();
    assert!(banner.contains("broken.json"), "{banner}");
    h.get_by_label_contains("Error: ");
    // The seed room on screen meanwhile.
    let seed = SceneDesc::from_json(SEED_ROOM_JSON).unwrap();
    assert_eq!(h.state().desc(), &seed);

    let fixed = small_room();
    write(&path, &fixed.to_json());
    step_until(&mut h, |v| v.banner().is_none());
    assert_eq!(h.state().desc(), &fixed);
    settle(&mut h);
    assert_eq!(finished(h.state()), core_render(&fixed));

    // A missing file is the same: banner, seed room, loaded once written.
    let missing = dir.path().join("later.json");
    let args = penumbra::cli::ViewArgs {
        scene: Some(missing.clone()),
        refine_spp: Some(1),
        ..Default::default()
    };
    let mut h = settled(ViewerOptions::from_args(&args).unwrap());
    assert!(h.state().banner().unwrap().contains("later.json"));
    write(&missing, &fixed.to_json());
    step_until(&mut h, |v| v.banner().is_none());
    assert_eq!(h.state().desc(), &fixed);
}

#[test]
fn f1_shows_the_help_and_the_menus_reach_every_command() {
    let mut h = settled(ViewerOptions::new(small_room()));
    h.key_press(egui::Key::F1);
    h.step();
    h.step();
    assert!(h.state().help_open());
    h.get_by_label("Frame all: the whole scene in view");
    h.get_by_label("Undo the last edit");
    h.get_by_label("F1 / ?");
    h.get_by_label("Ctrl+Shift+Z / Ctrl+Y");
    h.key_press(egui::Key::Escape);
    h.step();
    assert!(!h.state().help_open());
    h.key_press(egui::Key::Questionmark);
    h.step();
    assert!(h.state().help_open(), "? opens the help too");
    h.key_press(egui::Key::Escape);
    h.step();

    h.get_by_label("Help").click();
    h.step();
    h.step();
    h.get_by_label_contains("About penumbra").click();
    h.step();
    h.step();
    assert!(h.state().about_open());
    h.get_by_label_contains("CPU features");
    h.get_by_label(&format!("penumbra {}", env!("CARGO_PKG_VERSION")));

    // Space hides the side panel; C toggles the cut-away.
    h.key_press(egui::Key::Space);
    h.step();
    assert!(!h.state().panel_visible());
    h.key_press(egui::Key::C);
    h.step();
    assert!(h.state().desc().render.cutaway);
}

/// eframe's storage in memory.
#[derive(Default)]
struct MemStorage(std::collections::HashMap<String, String>);

impl eframe::Storage for MemStorage {
    fn get_string(&self, key: &str) -> Option<String> {
        self.0.get(key).cloned()
    }
    fn set_string(&mut self, key: &str, value: String) {
        self.0.insert(key.to_string(), value);
    }
    fn remove_string(&mut self, key: &str) {
        self.0.remove(key);
    }
    fn flush(&mut self) {}
}

#[test]
fn the_last_scene_recent_files_and_view_settings_are_remembered() {
    use eframe::App;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("kept.json");
    write(&path, &small_room().to_json());
    let mut h = settled(ViewerOptions::new(small_room()));
    drop_file(&mut h, &path);
    h.step();
    loaded(&mut h);
    h.get_by_role_and_label(Role::Slider, "Resolution scale")
        .set_value_accesskit(0.5);
    h.step();
    h.key_press(egui::Key::Space);
    h.step();

    // Saved through eframe's storage (off unless asked: `--no-persist`
    // and tests leave nothing behind).
    let mut storage = MemStorage::default();
    h.state_mut().save(&mut storage);
    assert!(storage.0.is_empty(), "persist is off by default");
    h.state_mut().persist = true;
    h.state_mut().save(&mut storage);
    let stored: penumbra::app::Persisted =
        eframe::get_value(&storage, penumbra::app::Persisted::KEY).expect("stored");
    let abs = std::path::absolute(&path).unwrap();
    assert_eq!(stored.last_scene.as_ref(), Some(&abs));
    assert_eq!(stored.recent, vec![abs.clone()]);
    assert_eq!(stored.last_dir.as_deref(), abs.parent());

    // The next run takes it back.
    let mut next = Viewer::new(ViewerOptions::new(small_room()));
    next.restore_persisted(stored);
    assert_eq!(next.view_settings().resolution_scale, 0.5);
    assert!(!next.panel_visible());
    assert_eq!(next.recent(), &[abs]);
    assert!(!next.can_undo(), "restoring is not an edit");
}

#[test]
fn the_file_dialog_starts_in_the_scenes_folder_keeps_its_size_and_asks_before_replacing() {
    let dir = tempfile::tempdir().unwrap();
    let sub = dir.path().join("sub");
    std::fs::create_dir(&sub).unwrap();
    for k in 0..30 {
        std::fs::write(sub.join(format!("s{k:02}.json")), "{}").unwrap();
    }
    let path = dir.path().join("room.json");
    write(&path, &small_room().to_json());
    let mut options = ViewerOptions::new(small_room());
    options.scene_path = Some(path.clone());
    let mut h = settled(options);

    // Save scene… starts in the scene's folder with its name: the file
    // exists, so Save asks first and "Keep it" writes nothing.
    h.key_press_modifiers(
        egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
        egui::Key::S,
    );
    h.step();
    h.step();
    let d = h.state_mut().dialog_mut().expect("the save dialog");
    assert_eq!(d.dir(), std::path::absolute(dir.path()).unwrap());
    assert_eq!(d.path, "room.json");
    let window = h.get_by_label("Save scene").rect();
    h.state_mut().edit(|d, _| d.render.terms.ambient = 0.25);
    h.get_by_role_and_label(Role::Button, "Save").click();
    h.step();
    assert!(
        h.state_mut()
            .dialog_mut()
            .unwrap()
            .overwrite_pending()
            .is_some()
    );
    h.step();
    h.get_by_label_contains("exists.");
    assert_eq!(
        h.get_by_label("Save scene").rect(),
        window,
        "the question moved it"
    );
    h.get_by_role_and_label(Role::Button, "Keep it").click();
    h.step();
    assert!(h.state_mut().dialog_mut().is_some());
    assert_eq!(SceneDesc::load(&path).unwrap(), small_room());

    // Into a folder with many files: the dialog neither grows nor moves.
    h.get_by_label("sub/").click();
    h.step();
    h.step();
    assert_eq!(h.get_by_label("Save scene").rect(), window);

    // Back up, Save, Replace: written.
    h.get_by_label("../").click();
    h.step();
    h.state_mut().dialog_mut().unwrap().path = "room.json".into();
    h.step();
    h.get_by_role_and_label(Role::Button, "Save").click();
    h.step();
    h.step();
    h.get_by_role_and_label(Role::Button, "Replace").click();
    h.step();
    h.state_mut().wait_for_saves(WAIT);
    assert!(h.state_mut().dialog_mut().is_none());
    assert_eq!(SceneDesc::load(&path).unwrap().render.terms.ambient, 0.25);

    // The next dialog starts where the last one was.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::O);
    h.step();
    let d = h.state_mut().dialog_mut().expect("the open dialog");
    assert_eq!(d.dir(), std::path::absolute(dir.path()).unwrap());
}

#[test]
fn at_500_points_wide_the_status_bar_wraps_instead_of_being_cut_off() {
    let mut h = Harness::builder()
        .with_size([500.0, 700.0])
        .with_step_dt(1.0 / 60.0)
        .build_ui_state(
            |ui, v: &mut Viewer| v.show(ui, None),
            Viewer::new(ViewerOptions::new(small_room())),
        );
    h.step();
    settle(&mut h);
    h.step();
    for label in ["pass 2 of 2", "16 samples/hit"] {
        let r = h.get_by_label(label).rect();
        assert!(r.right() <= 500.0 && r.left() >= 0.0, "{label} at {r:?}");
    }
    let r = h.get_by_label_contains("Mray/s").rect();
    assert!(r.right() <= 500.0, "Mray/s at {r:?}");
}

#[test]
fn a_finished_image_is_refined_to_more_samples_exactly() {
    let mut options = ViewerOptions::new(small_room());
    options.refine_spp = 4;
    let mut h = settled(options);
    // Refinement runs on by itself: 2, then 4 samples per pixel.
    let start = std::time::Instant::now();
    let film = loop {
        h.step();
        if let Some(JobState::Finished(f)) = h.state().render_state()
            && f.samples == 4
        {
            break (*f.film).clone();
        }
        assert!(start.elapsed() < WAIT, "no refinement to 4 samples");
        std::thread::sleep(Duration::from_millis(5));
    };
    let mut four = small_room();
    four.render.samples_per_pixel = 4;
    assert_eq!(film, core_render(&four), "level 4 is the 4-spp render");
    // Its last tiles reach the texture, and the status bar says so.
    for _ in 0..3 {
        h.step();
    }
    assert_shows(h.state(), &film);
    h.get_by_label("4 spp");
    // An edit shows the scene's own samples again, then refines anew.
    h.state_mut().edit(|d, _| d.render.terms.specular = 0.5);
    settle(&mut h);
    match h.state().render_state() {
        Some(JobState::Finished(f)) => assert!(f.samples <= 4),
        other => panic!("{other:?}"),
    }
}

#[test]
fn w_a_s_d_walk_the_camera_and_its_pivot_and_a_walk_is_one_undo_step() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let before = h.state().desc().camera.clone();
    let centre = egui::pos2(800.0, 450.0);
    h.hover_at(centre);
    h.step();
    // Hold W for a few frames: forward, along the view.
    h.event(egui::Event::Key {
        key: egui::Key::W,
        physical_key: None,
        pressed: true,
        repeat: false,
        modifiers: egui::Modifiers::NONE,
    });
    for _ in 0..5 {
        h.step();
    }
    h.event(egui::Event::Key {
        key: egui::Key::W,
        physical_key: None,
        pressed: false,
        repeat: false,
        modifiers: egui::Modifiers::NONE,
    });
    h.step();
    let after = h.state().desc().camera.clone();
    let d = |a: [f64; 3], b: [f64; 3]| glam::DVec3::from(a) - glam::DVec3::from(b);
    let moved = d(after.position, before.position);
    let view = d(before.look_at, before.position).normalize();
    assert!(moved.length() > 1e-3, "W moved the camera: {moved}");
    assert!(
        moved.normalize().dot(view) > 0.999,
        "along the view: {moved}"
    );
    assert!(
        (d(after.look_at, before.look_at) - moved).length() < 1e-9,
        "the pivot moves with the camera"
    );
    // The whole walk is one step.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.step();
    assert_eq!(h.state().desc().camera, before);
}

/// Steps until the finished image has `spp` samples per pixel; its film.
fn refined_to(h: &mut Harness<'static, Viewer>, spp: u32) -> Film {
    let start = Instant::now();
    loop {
        h.step();
        if let Some(JobState::Finished(f)) = h.state().render_state()
            && f.samples == spp
        {
            return (*f.film).clone();
        }
        assert!(start.elapsed() < WAIT, "no refinement to {spp} samples");
        std::thread::sleep(Duration::from_millis(5));
    }
}

#[test]
fn a_recombine_or_reshade_edit_keeps_the_refined_samples() {
    let mut options = ViewerOptions::new(small_room());
    options.refine_spp = 8;
    let mut h = settled(options);
    refined_to(&mut h, 8);
    let at = |edit: &dyn Fn(&mut SceneDesc), spp: u32| {
        let mut d = small_room();
        edit(&mut d);
        d.render.samples_per_pixel = spp;
        core_render(&d)
    };
    // A strength (recombine), then a shininess (re-shade): 8 samples at
    // once, no camera rays, the image of a fresh 8-spp render.
    let ambient = |d: &mut SceneDesc| d.render.terms.ambient = 0.5;
    h.state_mut().edit(|d, _| ambient(d));
    settle(&mut h);
    match h.state().render_state() {
        Some(JobState::Finished(f)) => {
            assert_eq!(f.samples, 8);
            assert_eq!(f.traced_rays, 0, "a recombine traces nothing");
            assert_eq!(*f.film, at(&ambient, 8));
        }
        other => panic!("{other:?}"),
    }
    let shiny = |d: &mut SceneDesc| {
        d.render.terms.ambient = 0.5;
        d.materials.get_mut("white").unwrap().shininess = 80.0;
    };
    h.state_mut()
        .edit(|d, _| d.materials.get_mut("white").unwrap().shininess = 80.0);
    settle(&mut h);
    match h.state().render_state() {
        Some(JobState::Finished(f)) => {
            assert_eq!(f.samples, 8);
            assert_eq!(*f.film, at(&shiny, 8));
        }
        other => panic!("{other:?}"),
    }
    for _ in 0..3 {
        h.step();
    }
    h.get_by_label("8 spp");
    // A camera move starts from the scene's own sample again.
    h.state_mut().edit(|d, _| d.camera.position[0] += 0.5);
    settle(&mut h);
    match h.state().render_state() {
        Some(JobState::Finished(f)) => {
            let moved = |d: &mut SceneDesc| {
                shiny(d);
                d.camera.position[0] += 0.5;
            };
            assert_eq!(*f.film, at(&moved, f.samples));
        }
        other => panic!("{other:?}"),
    }
}

/// A dropped mesh file joins the scene standing on the floor, in the
/// object list's material; its toggle in the list hides it again (the
/// image is the room's once more), and undo brings it back.
#[test]
fn a_dropped_mesh_joins_the_scene_and_its_toggle_hides_it() {
    let dir = common::Scratch::new("viewer-mesh");
    let file = dir.join("box.obj");
    std::fs::write(&file, common::box_obj([1.0; 3])).unwrap();

    let mut h = settled(ViewerOptions::new(small_room()));
    let room = finished(h.state());
    let before = h.state().desc().objects.len();
    drop_file(&mut h, &file);
    h.step();
    loaded(&mut h);
    let desc = h.state().desc().clone();
    assert_eq!(desc.objects.len(), before + 1);
    let penumbra::render::scene_file::ObjectDesc::Mesh(m) = desc.objects.last().unwrap() else {
        panic!("a mesh")
    };
    assert_eq!(m.material, "white");
    // On the floor (y = 0): its lowest corner a hair above it; 40 % of the
    // room's smallest side (8, floor to ceiling) wide.
    let penumbra::render::scene_file::MeshScale::Uniform(s) = m.scale else {
        panic!("uniform")
    };
    assert!((s * 2.0 - 0.4 * 8.0).abs() < 1e-9, "{s}");
    assert!(
        m.translate[1] - s > 0.0 && m.translate[1] - s < 0.01,
        "{:?}",
        m.translate
    );
    settle(&mut h);
    let with_mesh = finished(h.state());
    assert_ne!(with_mesh, room, "the mesh shows");

    // Its toggle in the object list: the room's image again, bit for bit.
    h.get_by_label("Objects").click();
    h.step();
    let label = format!("{before}: mesh box.obj");
    h.get_by_role_and_label(Role::CheckBox, &label)
        .click_accesskit();
    h.step();
    assert_eq!(h.state().view_settings().hidden, vec![before]);
    settle(&mut h);
    assert_eq!(finished(h.state()), room);

    // Undo: shown again.
    assert!(h.state_mut().undo());
    h.step();
    assert!(h.state().view_settings().hidden.is_empty());
    settle(&mut h);
    assert_eq!(finished(h.state()), with_mesh);

    // A file that is not a mesh is a banner, and the scene stays.
    let bad = dir.join("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nf 1 2 3\n").unwrap();
    drop_file(&mut h, &bad);
    h.step();
    loaded(&mut h);
    assert!(
        h.state().banner().is_some_and(|b| b.contains("bad.obj")),
        "{:?}",
        h.state().banner()
    );
    assert_eq!(h.state().desc().objects.len(), before + 1);
}

// ----- limits of typed values and camera moves, failed states --------------

use penumbra::render::scene_file::limits::{MAX_COLOUR, MAX_COORD};

/// Types `text` into a number field as a person does: focus (which
/// selects its text), type, Enter.
fn type_into(
    h: &mut Harness<'static, Viewer>,
    find: impl Fn(&Harness<'static, Viewer>) -> egui::Rect,
    text: &str,
) {
    // A render ending (its banner coming or going) moves the panel.
    settle(h);
    let field = find(h);
    let node = h
        .get_all_by_role(Role::SpinButton)
        .find(|n| n.rect() == field)
        .expect("the number field");
    node.focus();
    h.step();
    h.step();
    // Focused, the field edits its text (all of it selected).
    assert!(
        h.get_all_by_role(Role::SpinButton).any(|n| n.is_focused()),
        "the field took no focus"
    );
    h.event(egui::Event::Text(text.into()));
    h.step();
    h.key_press(egui::Key::Enter);
    h.step();
    h.step();
}

/// [`type_into`], one key at a time with a frame after each, as a person
/// types.
fn type_keys_into(
    h: &mut Harness<'static, Viewer>,
    find: impl Fn(&Harness<'static, Viewer>) -> egui::Rect,
    text: &str,
) {
    settle(h);
    let field = find(h);
    h.get_all_by_role(Role::SpinButton)
        .find(|n| n.rect() == field)
        .expect("the number field")
        .focus();
    h.step();
    h.step();
    for key in text.chars() {
        h.event(egui::Event::Text(key.into()));
        h.step();
    }
    h.key_press(egui::Key::Enter);
    h.step();
    h.step();
}

/// The number field of a slider: the one on the slider's row, right of it.
fn slider_field(h: &Harness<'static, Viewer>, slider: &str) -> egui::Rect {
    let rail = h.get_by_role_and_label(Role::Slider, slider).rect();
    h.get_all_by_role(Role::SpinButton)
        .map(|n| n.rect())
        .filter(|r| r.left() >= rail.right() && (r.center().y - rail.center().y).abs() < 4.0)
        .min_by(|a, b| a.left().total_cmp(&b.left()))
        .expect("the slider's number field")
}

/// Sets a slider as a screen reader does, once the render has ended.
fn set_slider(h: &mut Harness<'static, Viewer>, label: &str, value: f64) {
    settle(h);
    h.get_by_role_and_label(Role::Slider, label)
        .set_value_accesskit(value);
    h.step();
}

fn light_centre(d: &SceneDesc) -> [f64; 3] {
    let l = &d.light;
    std::array::from_fn(|i| l.corner[i] + 0.5 * (l.edge_u[i] + l.edge_v[i]))
}

#[test]
fn typed_numbers_are_clamped_to_the_formats_limits_and_nan_is_refused() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let x = |h: &Harness<'static, Viewer>| h.get_by_role_and_label(Role::SpinButton, "x").rect();

    // A slider's number field: the light depth stops at the longest edge
    // the format takes.
    let depth = |h: &Harness<'static, Viewer>| slider_field(h, "Light depth");
    type_into(&mut h, depth, "1e300");
    let edge = h.state().desc().light.edge_v;
    let len = edge.iter().map(|c| c * c).sum::<f64>().sqrt();
    assert!(len <= MAX_COORD && len > 0.999 * MAX_COORD, "{len}");
    type_into(&mut h, depth, "NaN");
    assert_eq!(h.state().desc().light.edge_v, edge);
    type_into(&mut h, depth, "2");

    // NaN (egui made it inf) and "inf" are refused: the light stays.
    let light = h.state().desc().light.clone();
    type_into(&mut h, x, "NaN");
    assert_eq!(h.state().desc().light, light);
    type_into(&mut h, x, "inf");
    assert_eq!(h.state().desc().light, light);

    // 1e300 stops at the format's largest coordinate, which makes the
    // scene too large for its features: refused, the light stays.
    type_into(&mut h, x, "1e300");
    assert_eq!(h.state().desc().light, light);
    type_into(&mut h, x, "0");
    assert!(light_centre(h.state().desc())[0].abs() < 1e-9);

    // A strength's field goes past its rail (0–10) to the format's limit,
    // no further; shadow rays stay at least 1.
    set_slider(&mut h, "Ambient strength", 1e300);
    assert_eq!(h.state().desc().render.terms.ambient, MAX_COLOUR);
    set_slider(&mut h, "Ambient strength", f64::NAN);
    assert_eq!(h.state().desc().render.terms.ambient, MAX_COLOUR);
    set_slider(&mut h, "Shadow rays", -5.0);
    assert_eq!(h.state().desc().render.shadow_rays, 1);

    // What is left renders, and saves to a file that loads again.
    h.state().desc().validate().expect("a valid scene");
    settle(&mut h);
    finished(h.state());
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("typed.json");
    let ctx = h.ctx.clone();
    h.state_mut().save_scene(&ctx, path.clone());
    h.state_mut().wait_for_saves(WAIT);
    SceneDesc::load(&path).expect("the saved scene loads");
}

/// The length of a light edge.
fn length(v: [f64; 3]) -> f64 {
    v.iter().map(|c| c * c).sum::<f64>().sqrt()
}

/// The light's width and depth cover every size the loader takes (they
/// were 0.01–20): a light 50 wide loads and shows 50, and a drag or a
/// typed value reaches any size the scene takes; one it does not take is
/// refused, never clamped into the slider's range.
#[test]
fn the_light_size_controls_cover_every_size_the_loader_takes() {
    let mut d = small_room();
    d.light.corner = [-25.0, 7.99, -1.0];
    d.light.edge_u = [50.0, 0.0, 0.0];
    d.light.edge_v = [0.0, 0.0, 0.004];
    let mut h = settled(ViewerOptions::new(d.clone()));
    assert_eq!(
        h.state().desc(),
        &d,
        "showing the controls changed the light"
    );
    let value = |h: &Harness<'static, Viewer>, slider: &str| {
        let field = slider_field(h, slider);
        h.get_all_by_role(Role::SpinButton)
            .find(|n| n.rect() == field)
            .and_then(|n| n.value())
            .expect("the slider's value")
    };
    assert_eq!(value(&h, "Light width"), "50");
    assert_eq!(value(&h, "Light depth"), "0.004");
    // The handles show the values, inside rails around the room's size
    // (a few decades: a drag moves the size finely where lights are),
    // which reach out to a size beyond them.
    use egui_kittest::kittest::NodeT;
    let rail = |h: &Harness<'static, Viewer>, slider: &str| {
        let node = h.get_by_role_and_label(Role::Slider, slider);
        let node = node.accesskit_node();
        let (lo, hi) = (
            node.min_numeric_value().unwrap(),
            node.max_numeric_value().unwrap(),
        );
        (lo, node.numeric_value().unwrap(), hi)
    };
    let (lo, at, hi) = rail(&h, "Light width");
    assert_eq!(at, 50.0);
    assert!(lo <= 1.0 && hi >= 50.0 && hi / lo <= 1e3, "{lo}..{hi}");
    let (lo, at, hi) = rail(&h, "Light depth");
    assert_eq!(at, 0.004);
    assert!(lo == 0.004 && (50.0..=1e3).contains(&hi), "{lo}..{hi}");

    set_slider(&mut h, "Light width", 60.0);
    assert!((length(h.state().desc().light.edge_u) - 60.0).abs() < 1e-9);
    set_slider(&mut h, "Light width", 1e4);
    assert!((length(h.state().desc().light.edge_u) - 1e4).abs() < 1e-6);
    set_slider(&mut h, "Light depth", 1e-3);
    assert!((length(h.state().desc().light.edge_v) - 1e-3).abs() < 1e-15);
    settle(&mut h);
    finished(h.state());

    // Typed: 1e300 stops at the longest edge the format takes (1e9), which
    // makes the scene so large that the light's 0.001 depth falls below
    // its size floor: refused, named.
    let light = h.state().desc().light.clone();
    type_into(&mut h, |h| slider_field(h, "Light width"), "1e300");
    assert_eq!(h.state().desc().light, light);
    let banner = h.state().banner().expect("a banner").to_string();
    assert!(
        banner.contains("light.edge_u: edit refused")
            && banner
                .contains("light.edge_v: length 1.000e-3 is below the smallest supported size"),
        "{banner}"
    );
    // Typed: the shortest length any scene takes, 1e-15, below this
    // one's floor: refused, named (the field takes it).
    type_into(&mut h, |h| slider_field(h, "Light depth"), "1e-20");
    assert_eq!(h.state().desc().light, light);
    let banner = h.state().banner().expect("a banner").to_string();
    assert!(
        banner.contains("light.edge_v: length 1.000e-15 is below the smallest supported size"),
        "{banner}"
    );
    // Its number field shows six digits; entering them again changes
    // nothing.
    set_slider(&mut h, "Light width", 1234.56789);
    let light = h.state().desc().light.clone();
    assert_eq!(value(&h, "Light width"), "1234.57");
    type_into(&mut h, |h| slider_field(h, "Light width"), "1234.57");
    assert_eq!(h.state().desc().light, light);
}

/// The light width's slider spans a few decades around the room's size,
/// so that a drag of a few points changes a light of a usual size by a
/// little (over the 24 decades the loader takes, 10 points multiplied it
/// by hundreds), and the rail holds still under the drag.
#[test]
fn dragging_the_light_width_changes_it_finely() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let width = |h: &Harness<'static, Viewer>| length(h.state().desc().light.edge_u);
    let rail = h.get_by_role_and_label(Role::Slider, "Light width").rect();
    let from = rail.center();
    h.drag_at(from);
    h.step();
    let at = width(&h);
    for k in 1..=5 {
        h.hover_at(from + egui::vec2(2.0 * k as f32, 0.0));
        h.step();
    }
    let moved = width(&h);
    h.drop_at(from + egui::vec2(10.0, 0.0));
    h.step();
    assert!(
        (0.05..5.0).contains(&at) && moved > at && moved / at < 2.0,
        "{at} -> {moved}"
    );
    assert_eq!(
        width(&h),
        moved,
        "the rail moved under the drag {at} {moved}"
    );
}

/// A number field whose value costs a re-render (or may be refused) takes
/// a typed value on Enter, not at each key: typing 64 shadow rays rendered
/// 6 rays first, and 0.25 as the resolution scale rendered at 0.1 on the
/// way.
#[test]
fn a_typed_number_applies_on_enter_not_at_each_key() {
    let mut h = settled(ViewerOptions::new(small_room()));
    for (slider, typed) in [
        ("Shadow rays", "64"),
        ("Resolution scale", "0.25"),
        ("Max depth", "12"),
        ("Light width", "2.5"),
        ("Material shininess", "250"),
        ("Reflectivity", "0.25"),
    ] {
        let requests = h.state().render_generation();
        type_keys_into(&mut h, |h| slider_field(h, slider), typed);
        assert_eq!(
            h.state().render_generation(),
            requests + 1,
            "{slider}: {typed} rendered on the way"
        );
    }
    let d = h.state().desc();
    assert_eq!((d.render.shadow_rays, d.render.max_depth), (64, 12));
    assert_eq!(h.state().view_settings().resolution_scale, 0.25);
    assert!((length(d.light.edge_u) - 2.5).abs() < 1e-12);
    let material = d.materials.values().find(|m| m.shininess == 250.0);
    assert_eq!(material.map(|m| m.reflectivity), Some(0.25));
}

/// An edit the loader would refuse for a limit across fields (a light
/// centre of 1e9 makes the scene so large that the room's sphere falls
/// below its size floor) is refused with a banner naming the field and
/// the limit, the last valid value kept: no failed render, no NaN.
#[test]
fn an_edit_the_loader_would_refuse_is_undone_and_named_in_the_banner() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let light = h.state().desc().light.clone();
    let image = h.state().shown_image().clone();
    let x = |h: &Harness<'static, Viewer>| h.get_by_role_and_label(Role::SpinButton, "x").rect();

    // Typed key by key: the value before the typing stays, not the "1"
    // on the way to "1e9".
    type_keys_into(&mut h, x, "1e9");
    assert_eq!(h.state().desc().light, light);
    let banner = h.state().banner().expect("a banner").to_string();
    assert!(
        banner.contains("light.corner")
            && banner.contains("smallest supported size")
            && banner.contains("because of the light"),
        "{banner}"
    );
    h.get_by_label_contains("edit refused");
    settle(&mut h);
    assert!(matches!(
        h.state().render_state(),
        Some(JobState::Finished(_))
    ));
    assert_eq!(h.state().shown_image(), &image);
    assert!(light_centre(h.state().desc()).iter().all(|c| c.is_finite()));

    // A valid value is taken, and the banner goes with it.
    type_into(&mut h, x, "0.5");
    assert!((light_centre(h.state().desc())[0] - 0.5).abs() < 1e-12);
    assert_eq!(h.state().banner(), None);
    settle(&mut h);
    let moved = h.state().desc().clone();
    assert_eq!(finished(h.state()), core_render(&moved));
}

#[test]
fn save_scene_refuses_a_scene_that_would_not_load() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.json");
    let mut h = settled(ViewerOptions::new(small_room()));
    h.state_mut().edit(|d, _| d.light.corner[0] = f64::INFINITY);
    settle(&mut h);
    assert!(matches!(
        h.state().render_state(),
        Some(JobState::Failed(_))
    ));
    let ctx = h.ctx.clone();
    h.state_mut().save_scene(&ctx, path.clone());
    h.state_mut().wait_for_saves(WAIT);
    h.step();
    assert!(!path.exists(), "an unloadable scene was written");
    let banner = h.state().banner().expect("a banner").to_string();
    assert!(
        banner.contains("not saved") && banner.contains("light.corner[0]"),
        "{banner}"
    );
    // Still the seed room, not a scene named after the refused file.
    assert_eq!(h.state().scene_path(), None);
    assert!(h.state().is_dirty());
}

/// Wheel scrolls over the image (negative: out), each given a few frames.
fn wheel(h: &mut Harness<'static, Viewer>, delta: f32, times: usize) {
    h.hover_at(egui::pos2(800.0, 450.0));
    h.step();
    for _ in 0..times {
        h.event(egui::Event::MouseWheel {
            unit: egui::MouseWheelUnit::Point,
            delta: egui::vec2(0.0, delta),
            phase: egui::TouchPhase::Move,
            source: egui::MouseWheelSource::Wheel,
            modifiers: egui::Modifiers::NONE,
        });
        for _ in 0..5 {
            h.step();
        }
    }
    // egui spreads a scroll over frames: let it end.
    for _ in 0..600 {
        if h.ctx.input(|i| i.smooth_scroll_delta == egui::Vec2::ZERO) {
            break;
        }
        h.step();
    }
}

#[test]
fn wheel_zoom_and_pan_keep_the_camera_within_the_formats_range() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let pivot = glam::DVec3::from(h.state().desc().camera.look_at);
    let distance = |v: &Viewer| {
        (glam::DVec3::from(v.desc().camera.position) - glam::DVec3::from(v.desc().camera.look_at))
            .length()
    };

    // Far out (unbounded, this went past 1e9 and the render failed for
    // good): the camera stops well inside the format's range.
    wheel(&mut h, -3000.0, 40);
    let far = distance(h.state());
    assert!(far > 1e3, "the wheel did not zoom out: {far}");
    assert!(far < 1e5, "no limit: {far}");
    assert_eq!(glam::DVec3::from(h.state().desc().camera.look_at), pivot);
    h.state().desc().validate().expect("a valid camera");
    settle(&mut h);
    finished(h.state());

    // Panning (from a few hundred metres, where a point is a metre) stops
    // too: twice the distance allowed, unbounded.
    h.key_press(egui::Key::Home);
    h.step();
    wheel(&mut h, -1000.0, 2);
    for _ in 0..40 {
        pan_image(&mut h, egui::pos2(600.0, 450.0), egui::vec2(400.0, 0.0));
    }
    let cam = h.state().desc().camera.clone();
    let off = glam::DVec3::from(cam.position).length();
    assert!(off > 2e3, "the pan did not go far: {off}");
    assert!(off < 1e4, "no limit: {cam:?}");
    h.state().desc().validate().expect("a valid camera");

    // Back in, all the way: the camera never reaches its pivot.
    h.key_press(egui::Key::Home);
    h.step();
    wheel(&mut h, 3000.0, 40);
    let near = distance(h.state());
    assert!(near > 0.0 && near < 1e-2, "{near}");
    h.state().desc().validate().expect("a valid camera");
    settle(&mut h);
    finished(h.state());
    // And out again: the wheel still works.
    wheel(&mut h, -600.0, 2);
    assert!(distance(h.state()) > near);
}

/// Middle-drags on the image (a pan) from `from` by `by`.
fn pan_image(h: &mut Harness<'static, Viewer>, from: egui::Pos2, by: egui::Vec2) {
    let button = |pos, pressed| egui::Event::PointerButton {
        pos,
        button: egui::PointerButton::Middle,
        pressed,
        modifiers: egui::Modifiers::NONE,
    };
    h.event(egui::Event::PointerMoved(from));
    h.event(button(from, true));
    h.step();
    for k in 1..=4 {
        h.event(egui::Event::PointerMoved(from + by * (k as f32 / 4.0)));
        h.step();
    }
    h.event(button(from + by, false));
    h.step();
}

#[test]
fn save_png_after_a_failed_render_says_so_and_the_banner_goes_with_the_fix() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("failed.png");
    let mut h = settled(ViewerOptions::new(small_room()));
    h.state_mut().edit(|d, _| d.light.corner[2] = -5e299);
    settle(&mut h);
    assert!(matches!(
        h.state().render_state(),
        Some(JobState::Failed(_))
    ));

    // Ctrl+S: no dialog, but the reason.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    h.step();
    assert!(h.state_mut().dialog_mut().is_none(), "a save dialog opened");
    let banner = h.state().banner().expect("a banner").to_string();
    assert!(banner.contains("nothing to save"), "{banner}");
    // The same from a path chosen before the render failed.
    let ctx = h.ctx.clone();
    h.state_mut().save_png(&ctx, out.clone());
    h.state_mut().wait_for_saves(WAIT);
    h.step();
    assert!(!out.exists());
    assert!(h.state().banner().unwrap().contains("nothing to save"));

    // Ctrl+Z brings the light back: the render succeeds and the banner,
    // no longer true, goes by itself.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.step();
    settle(&mut h);
    finished(h.state());
    assert_eq!(h.state().banner(), None);
}

/// `missingmesh.json` in `dir`: the small room with a mesh whose file is
/// not there (it parses, but does not build).
fn room_with_a_missing_mesh(dir: &Path) -> std::path::PathBuf {
    let path = dir.join("missingmesh.json");
    let mut json: serde_json::Value = serde_json::from_str(&small_room().to_json()).unwrap();
    json["objects"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!(
            {"type": "mesh", "file": "/nonexistent/nope.obj", "material": "white"}
        ));
    std::fs::write(&path, json.to_string()).unwrap();
    path
}

#[test]
fn a_scene_whose_mesh_is_missing_keeps_the_scene_before_and_its_name() {
    let dir = tempfile::tempdir().unwrap();
    let path = room_with_a_missing_mesh(dir.path());
    let mut h = settled(ViewerOptions::new(small_room()));
    let title = h.state().title();
    let image = h.state().shown_image().clone();

    let ctx = h.ctx.clone();
    h.state_mut().open_scene(&ctx, &path);
    loaded(&mut h);
    step_until(&mut h, |v| v.banner().is_some());
    let banner = h.state().banner().unwrap().to_string();
    assert!(
        banner.contains("missingmesh.json") && banner.contains("nope.obj"),
        "{banner}"
    );
    // The seed room, its name and its image stay, as for invalid JSON.
    assert_eq!(h.state().scene_path(), None);
    assert_eq!(h.state().title(), title);
    assert_eq!(h.state().desc(), &small_room());
    assert!(h.state().recent().is_empty(), "{:?}", h.state().recent());
    settle(&mut h);
    assert_eq!(h.state().shown_image(), &image);
    // Edits act on the scene shown.
    h.state_mut().edit(|d, _| d.render.terms.ambient = 0.7);
    settle(&mut h);
    assert_eq!(
        finished(h.state()),
        room_render(|d| d.render.terms.ambient = 0.7)
    );
    // The banner stays until dismissed, as for invalid JSON.
    assert!(h.state().banner().is_some());
}

#[test]
fn the_behind_a_wall_hint_shows_only_while_the_cutaway_is_off() {
    let mut h = settled(ViewerOptions::new(small_room()));
    const HINT: &str = "behind a wall";
    // Behind the back wall (z = 5, facing -z).
    h.state_mut()
        .edit(|d, _| d.camera.position = [0.0, 4.0, 10.0]);
    h.step();
    assert!(h.state().notice().is_some_and(|n| n.contains(HINT)));

    h.key_press(egui::Key::C);
    h.step();
    assert!(h.state().desc().render.cutaway);
    assert!(
        !h.state().notice().is_some_and(|n| n.contains(HINT)),
        "{:?}",
        h.state().notice()
    );
    // Off again: true again.
    h.key_press(egui::Key::C);
    h.step();
    assert!(h.state().notice().is_some_and(|n| n.contains(HINT)));
    // Home puts the camera in front: gone.
    h.key_press(egui::Key::Home);
    h.step();
    assert!(!h.state().notice().is_some_and(|n| n.contains(HINT)));
}

// ----- big scenes, loads that build, keys and small UI ----------------------

use penumbra::app::settings::{PREVIEW_MAX_PIXELS, preview_size};
use penumbra::render::EditClass;

/// A 16384² scene took the UI thread 39 s and 13 GB (its film, its copy
/// and the texture, at full size): it is previewed at a display's pixels,
/// its proportions kept, and its own size stays the scene's (and export's).
#[test]
fn a_scene_larger_than_a_display_is_previewed_at_a_displays_size() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.json");
    let mut huge = small_room();
    huge.camera.width = 16384;
    huge.camera.height = 16384;
    huge.render.shadow_rays = 1;
    std::fs::write(&path, huge.to_json()).unwrap();
    let mut options = ViewerOptions::new(small_room());
    options.refine_spp = 1;
    let mut h = settled(options);

    let ctx = h.ctx.clone();
    h.state_mut().open_scene(&ctx, &path);
    loaded(&mut h);
    let (w, h_px) = preview_size(16384, 16384);
    assert!(w as u64 * h_px as u64 <= PREVIEW_MAX_PIXELS && w == h_px);
    assert_eq!(h.state().scene_path(), Some(path.as_path()));
    assert_eq!(h.state().shown_image().size, [w as usize, h_px as usize]);
    let shown = h.state().render_desc().camera;
    assert_eq!((shown.width, shown.height), (w, h_px));
    assert_eq!(h.state().desc().camera.width, 16384);
    h.get_by_label(&format!(
        "Previewed at {w}×{h_px}; Save PNG writes 16384×16384"
    ));

    // Launched with it: the same.
    let h2 = harness(ViewerOptions::new(huge));
    assert_eq!(h2.state().shown_image().size, [w as usize, h_px as usize]);
}

/// An opened scene is built (its meshes read) on the load thread, under
/// the loading strip: one that does not build is refused before it
/// replaces anything (the title never names it), and one that does is
/// rendered over the objects and BVH built there, not built again.
#[test]
fn an_opened_scene_is_built_under_the_loading_strip_before_it_replaces_the_shown_one() {
    let dir = tempfile::tempdir().unwrap();
    let missing = room_with_a_missing_mesh(dir.path());
    let mut h = settled(ViewerOptions::new(small_room()));
    let title = h.state().title();

    h.state().hold_loads_for_tests(true);
    let ctx = h.ctx.clone();
    h.state_mut().open_scene(&ctx, &missing);
    h.step();
    h.get_by_label_contains(&format!("loading {}…", missing.display()));
    h.state().hold_loads_for_tests(false);
    loaded(&mut h);
    // In the very frame the load ended: refused, nothing replaced.
    let banner = h.state().banner().expect("a banner").to_string();
    assert!(
        banner.contains("missingmesh.json") && banner.contains("nope.obj"),
        "{banner}"
    );
    assert_eq!(h.state().scene_path(), None);
    assert_eq!(h.state().title(), title);
    assert_eq!(h.state().desc(), &small_room());
    // An edit now is on the scene shown, and stays.
    h.state_mut().edit(|d, _| d.render.terms.ambient = 0.7);
    settle(&mut h);
    assert_eq!(h.state().desc().render.terms.ambient, 0.7);

    // A scene with a mesh: built by the loader, so its first render only
    // traces over it.
    let obj = dir.path().join("box.obj");
    std::fs::write(&obj, common::box_obj([1.0; 3])).unwrap();
    let with_mesh = dir.path().join("withmesh.json");
    let mut json: serde_json::Value = serde_json::from_str(&small_room().to_json()).unwrap();
    json["objects"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"type": "mesh", "file": "box.obj", "material": "white"}));
    std::fs::write(&with_mesh, json.to_string()).unwrap();
    h.state_mut().open_scene(&ctx, &with_mesh);
    loaded(&mut h);
    assert_eq!(h.state().scene_path(), Some(with_mesh.as_path()));
    assert!(h.state().title().starts_with("withmesh.json"));
    settle(&mut h);
    match h.state().render_state() {
        Some(JobState::Finished(f)) => assert_eq!(f.class, EditClass::Retrace),
        other => panic!("not finished: {other:?}"),
    }
    let desc = SceneDesc::load(&with_mesh).unwrap();
    assert_eq!(finished(h.state()), core_render(&desc));
}

/// The help lists the camera's gestures from the tables the input reads:
/// the walking keys and the right-drag look were missing.
#[test]
fn the_help_lists_the_walking_keys_and_every_drag() {
    let mut h = settled(ViewerOptions::new(small_room()));
    h.key_press(egui::Key::F1);
    h.step();
    h.step();
    h.get_by_label("W/A/S/D/Q/E");
    h.get_by_label_contains("Walk forward, left, back, right, down, up");
    h.get_by_label("Right-drag");
    h.get_by_label_contains("Look around");
    h.get_by_label("Middle-drag, Shift+drag");
    h.get_by_label("Drag");
    h.get_by_label("Wheel");
}

/// Escape closes an open menu or colour picker (the viewer's shortcut
/// reader took the key before egui's popups saw it).
#[test]
fn escape_closes_a_menu_and_the_colour_picker() {
    let mut h = settled(ViewerOptions::new(small_room()));
    type Opener = fn(&Harness<'static, Viewer>);
    let openers: [(&str, Opener); 2] = [
        ("menu", |h| h.get_by_label("File").click()),
        ("picker", |h| {
            h.get_all_by_role(Role::ColorWell).next().unwrap().click()
        }),
    ];
    for (what, open) in openers {
        open(&h);
        h.step();
        h.step();
        assert!(egui::Popup::is_any_open(&h.ctx), "the {what} opened");
        h.key_press(egui::Key::Escape);
        h.step();
        h.step();
        assert!(
            !egui::Popup::is_any_open(&h.ctx),
            "Escape left the {what} open"
        );
    }
}

/// Every text on screen with the colour picker open has its glyphs in the
/// fonts (its copy button's 📋 drew as a box).
#[test]
fn the_colour_picker_draws_no_missing_glyph() {
    let mut h = settled(ViewerOptions::new(small_room()));
    h.get_all_by_role(Role::ColorWell).next().unwrap().click();
    h.step();
    h.step();
    let texts = std::cell::RefCell::new(Vec::new());
    let _ = h
        .query_all_by(|n| {
            texts
                .borrow_mut()
                .extend([n.label(), n.value()].into_iter().flatten());
            false
        })
        .count();
    let texts = texts.into_inner();
    assert!(
        texts.iter().any(|t| t.starts_with("R ")),
        "the picker opened"
    );
    let font = egui::FontId::proportional(14.0);
    for t in texts {
        assert!(
            h.ctx.fonts_mut(|f| f.has_glyphs(&font, &t)),
            "a glyph of {t:?} is missing"
        );
    }
}

/// The exposure's value box keeps its width from "+0.0 EV" to "+10.0 EV",
/// so the strip after it (and the slider's handle under the cursor)
/// does not move.
#[test]
fn the_image_strip_does_not_shift_when_the_exposure_label_widens() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let reset = |h: &Harness<'static, Viewer>| h.get_by_role_and_label(Role::Button, "0").rect();
    let before = reset(&h);
    for exposure in [10.0, -10.0] {
        let mut display = h.state().display();
        display.exposure = exposure;
        h.state_mut().set_display(display);
        h.step();
        h.step();
        assert_eq!(reset(&h), before, "at {exposure} EV");
    }
}

/// Save scene… says, before the file is written, what the file holds
/// other than the scene as edited: it renders the image shown, so hidden
/// objects are left out and switched-off terms and reflections are
/// written as zero strengths and depth 1. With nothing switched off it
/// says nothing.
#[test]
fn the_save_scene_dialog_says_what_the_file_leaves_out() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let open_save = |h: &mut Harness<'_, Viewer>| {
        h.key_press_modifiers(
            egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
            egui::Key::S,
        );
        h.step();
        h.step();
        h.state_mut()
            .dialog_mut()
            .expect("the save dialog")
            .note
            .clone()
    };
    assert_eq!(open_save(&mut h), None);
    h.key_press(egui::Key::Escape);
    h.step();
    h.state_mut().edit(|_, view| {
        view.hidden = vec![0];
        view.specular = false;
        view.reflections = false;
    });
    settle(&mut h);
    let note = "The file renders the image shown: the hidden object left out; \
                specular strength written as 0; max depth written as 1 (reflections off).";
    assert_eq!(open_save(&mut h).as_deref(), Some(note));
    h.get_by_label(note);
}
