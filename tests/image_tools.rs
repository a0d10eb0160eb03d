//! The image tools of the viewer (exposure and curve, zoom and pan, the
//! pinned image A and its comparison, the inspector), driven headless by
//! egui_kittest. They change what is shown, never the render.

use std::time::Duration;

mod common;

use common::viewer::{WAIT, double_click, finished, settle, settled, small_room};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use penumbra::app::image_view::{MAX_ZOOM, Zoom};
use penumbra::app::pinned::CompareMode;
use penumbra::app::{Viewer, ViewerOptions};
use penumbra::render::compare::{compare, diff_image};
use penumbra::render::output::read_film;
use penumbra::render::{DisplayTransform, Loaded, ToneCurve};

/// The bytes the texture holds, as RGB.
fn shown_rgb(v: &Viewer) -> Vec<u8> {
    v.shown_image()
        .pixels
        .iter()
        .flat_map(|c| [c.r(), c.g(), c.b()])
        .collect()
}

const BRIGHT_FILMIC: DisplayTransform = DisplayTransform {
    exposure: 1.5,
    curve: ToneCurve::Filmic,
};

#[test]
fn exposure_curve_zoom_and_pin_leave_the_linear_film_as_rendered() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let core = Loaded::new(&small_room()).unwrap().render_image();
    assert_eq!(finished(h.state()), core);
    let plain = shown_rgb(h.state());
    assert_eq!(plain, core.to_srgb8());

    h.state_mut().set_display(BRIGHT_FILMIC);
    h.step();
    // What is shown went through the transform ...
    assert_eq!(shown_rgb(h.state()), BRIGHT_FILMIC.encode_all(&core.pixels));
    assert_ne!(shown_rgb(h.state()), plain);
    // ... and so will tiles rendered from now on.
    h.state_mut().edit(|d, _| d.render.terms.ambient *= 0.5);
    settle(&mut h);
    let darker = finished(h.state());
    assert_ne!(darker, core);
    assert_eq!(
        shown_rgb(h.state()),
        BRIGHT_FILMIC.encode_all(&darker.pixels)
    );
    h.state_mut().undo();
    settle(&mut h);

    // Zoom, pan, pin and every comparison mode.
    h.key_press(egui::Key::P);
    h.step();
    for _ in 0..6 {
        h.key_press(egui::Key::Plus);
        h.step();
    }
    assert_eq!(h.state().image_view().zoom, Zoom::Scale(MAX_ZOOM));
    h.key_press(egui::Key::Z);
    h.step();
    for _ in 0..4 {
        h.key_press(egui::Key::X);
        h.step();
    }
    assert!(h.state().compare().pinned.is_some());
    // The render did not restart, its film is the core's to the bit.
    assert_eq!(finished(h.state()), core);
    assert_eq!(h.state().finished_film().unwrap(), core);
    assert_eq!(
        h.state().compare().pinned.as_ref().unwrap().film.as_ref(),
        &core
    );

    // Back to 0 EV and sRGB: the bytes of a plain render again.
    h.state_mut().set_display(DisplayTransform::default());
    h.step();
    assert_eq!(shown_rgb(h.state()), plain);
}

#[test]
fn a_saved_png_is_what_is_shown_and_an_exr_stays_linear() {
    let dir = tempfile::tempdir().unwrap();
    let mut h = settled(ViewerOptions::new(small_room()));
    h.state_mut().set_display(BRIGHT_FILMIC);
    h.step();
    let film = finished(h.state());

    // The dialog says what each file holds.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    h.step();
    h.get_by_label_contains("PNG: the image as shown (exposure +1.5 EV, filmic");
    h.get_by_label_contains("the linear render, without exposure or curve");
    h.key_press(egui::Key::Escape);
    h.step();

    let ctx = h.ctx.clone();
    let png = dir.path().join("shown.png");
    let exr = dir.path().join("linear.exr");
    h.state_mut().save_png(&ctx, png.clone());
    h.state_mut().save_png(&ctx, exr.clone());
    h.state_mut().wait_for_saves(WAIT);
    h.step();
    let bytes = image::open(&png).unwrap().into_rgb8().into_raw();
    assert_eq!(bytes, shown_rgb(h.state()));
    assert_eq!(bytes, BRIGHT_FILMIC.encode_all(&film.pixels));
    assert_eq!(read_film(&exr).unwrap(), film);
    assert!(h.state().banner().is_none(), "{:?}", h.state().banner());
}

#[test]
fn at_32x_the_inspector_picks_the_pixel_under_the_cursor_live_and_pinned() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let a = finished(h.state());
    h.key_press(egui::Key::P);
    h.step();
    h.state_mut().edit(|d, _| d.render.terms.ambient *= 3.0);
    settle(&mut h);
    let live = finished(h.state());
    h.state_mut().set_display(BRIGHT_FILMIC);
    // 32 screen pixels per image pixel, the corner of pixel (20, 10) at
    // the panel's centre.
    *h.state_mut().image_view_mut() = penumbra::app::image_view::ImageView {
        zoom: Zoom::Scale(32.0),
        center: egui::pos2(20.0, 10.0),
        zoom_mode: true,
    };
    h.step();
    let (area, ppp) = h.state().image_area();
    assert_eq!(ppp, 1.0);
    // Two and a half pixels right, a half pixel down of that corner.
    let at = area.center() + egui::vec2(2.5 * 32.0, 0.5 * 32.0);
    double_click(&mut h, at);
    let pick = h.state().pick().expect("a pick").clone();
    assert_eq!(pick.pixel, (22, 10));
    let l = live.get(22, 10);
    assert_eq!(pick.linear_rgb, Some(l.to_array()));
    assert_eq!(pick.shown_srgb, Some(BRIGHT_FILMIC.encode(l)));
    let p = a.get(22, 10);
    assert_eq!(pick.pinned, Some((p.to_array(), BRIGHT_FILMIC.encode(p))));
    assert_ne!(l, p);
    // Next to the cursor: both lines in the popup.
    let [r, g, b] = BRIGHT_FILMIC.encode(l);
    // (A new popup shows from its second frame.)
    h.step();
    h.get_by_label_contains(&format!("sRGB ({r}, {g}, {b})"));
    h.get_by_label_contains(&format!("A     linear RGB ({:.4}", p.x));
}

#[test]
fn ctrl_wheel_zooms_the_image_about_the_cursor_and_the_wheel_still_zooms_the_camera() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let camera = h.state().desc().camera.clone();
    h.step();
    let (area, ppp) = h.state().image_area();
    let at = area.center() + egui::vec2(100.0, -50.0);
    let size = h.state().shown_image().size;
    let under = h
        .state()
        .image_view()
        .pixel_at(area, size, ppp, at)
        .unwrap();
    h.hover_at(at);
    h.step();
    h.event_modifiers(
        egui::Event::MouseWheel {
            unit: egui::MouseWheelUnit::Point,
            delta: egui::vec2(0.0, 200.0),
            phase: egui::TouchPhase::Move,
            source: egui::MouseWheelSource::Wheel,
            modifiers: egui::Modifiers::COMMAND,
        },
        egui::Modifiers::COMMAND,
    );
    for _ in 0..30 {
        h.step();
    }
    let v = *h.state().image_view();
    let Zoom::Scale(s) = v.zoom else {
        panic!("not zoomed: {v:?}")
    };
    let fit = penumbra::app::image_view::fit_scale(area, size, ppp);
    assert!(s > fit * 1.5, "{s} vs fit {fit}");
    // The pixel under the cursor stayed there, the camera did not move.
    assert_eq!(v.pixel_at(area, size, ppp, at), Some(under));
    assert_eq!(h.state().desc().camera, camera);

    // The plain wheel is the camera's, as before.
    h.event(egui::Event::MouseWheel {
        unit: egui::MouseWheelUnit::Point,
        delta: egui::vec2(0.0, 100.0),
        phase: egui::TouchPhase::Move,
        source: egui::MouseWheelSource::Wheel,
        modifiers: egui::Modifiers::NONE,
    });
    for _ in 0..30 {
        h.step();
    }
    assert_ne!(h.state().desc().camera, camera);
    assert_eq!(h.state().image_view().zoom, v.zoom);
    // 0 fits again.
    h.key_press(egui::Key::Num0);
    h.step();
    assert_eq!(h.state().image_view().zoom, Zoom::Fit);
}

/// The frame after the click asks for the difference, the next shows it.
fn settle_difference(h: &mut Harness<'static, Viewer>) {
    h.step();
    h.step();
    assert!(h.state().compare().wait(WAIT));
    h.step();
}

#[test]
fn the_difference_against_the_pinned_image_is_the_cores() {
    let mut h = settled(ViewerOptions::new(small_room()));
    let a = finished(h.state());
    h.get_by_label("Pin A").click();
    h.step();
    assert_eq!(h.state().compare().mode, CompareMode::Split);
    h.state_mut().edit(|d, _| d.render.terms.specular *= 0.25);
    settle(&mut h);
    let live = finished(h.state());
    h.get_by_label("difference").click();
    settle_difference(&mut h);
    let (d, _) = h.state().compare().difference().expect("a difference");
    let expected = compare(&live, &a).unwrap();
    assert!(expected.rmse > 0.0);
    assert_eq!(d.comparison.rmse, expected.rmse);
    assert_eq!(d.comparison.max_at, expected.max_at);
    let (rgb, _) = diff_image(&live, &a, Some(d.scale)).unwrap();
    let got: Vec<u8> = d
        .image
        .pixels
        .iter()
        .flat_map(|c| [c.r(), c.g(), c.b()])
        .collect();
    assert_eq!(got, rgb);
    h.get_by_label_contains("|live − A|: RMSE");
    // Pinning the live image: no difference left.
    h.key_press(egui::Key::P);
    h.step();
    h.get_by_label("difference").click();
    settle_difference(&mut h);
    let (d, _) = h.state().compare().difference().expect("a difference");
    assert_eq!(d.comparison.rmse, 0.0);
}

#[test]
fn a_still_image_with_its_tools_asks_for_no_frames_and_flicker_asks_for_some() {
    let mut h = settled(ViewerOptions::new(small_room()));
    h.key_press(egui::Key::P);
    h.step();
    h.key_press(egui::Key::Num1);
    h.step();
    h.state_mut().set_display(BRIGHT_FILMIC);
    // Split, at 1:1, another exposure: once settled, no frame is asked for.
    h.try_run().expect("the viewer settles");
    assert_eq!(
        h.output()
            .viewport_output
            .values()
            .next()
            .unwrap()
            .repaint_delay,
        Duration::MAX
    );
    // Flicker changes by itself: a frame at the next turn, not sooner.
    h.key_press(egui::Key::X);
    h.step();
    assert_eq!(h.state().compare().mode, CompareMode::Flicker);
    h.try_run().expect("flicker waits between turns");
    let delay = h
        .output()
        .viewport_output
        .values()
        .next()
        .unwrap()
        .repaint_delay;
    assert!(
        delay > Duration::from_millis(5) && delay <= penumbra::app::pinned::FLICKER_PERIOD,
        "{delay:?}"
    );
}
