//! Live editing: after any sequence of edits, the image a [`LiveRender`]
//! gives equals a fresh one-shot render of the same description, bit for
//! bit — and each edit costs only what its class says.

use penumbra::render::SEED_ROOM_JSON;
use penumbra::render::generate::{Layout, generate};
use penumbra::render::{
    AreaLightModel, CancelToken, EditClass, Film, LiveError, LiveRender, LiveReport, Loaded,
    RenderOptions, Sampling, SceneDesc, classify,
};
use proptest::prelude::*;

fn room(width: u32, height: u32) -> SceneDesc {
    let mut desc = SceneDesc::from_json(SEED_ROOM_JSON).unwrap();
    desc.camera.width = width;
    desc.camera.height = height;
    desc
}

fn options(progressive: bool) -> RenderOptions {
    RenderOptions {
        threads: Some(2),
        progressive,
        tile_size: 16,
    }
}

fn fresh(desc: &SceneDesc) -> Film {
    Loaded::new(desc).expect("valid scene").render_image()
}

/// Panics unless the two images are equal bit for bit.
fn assert_same_bits(live: &Film, fresh: &Film, what: &str) {
    assert_eq!(
        (live.width, live.height),
        (fresh.width, fresh.height),
        "{what}: size"
    );
    for (i, (a, b)) in live.pixels.iter().zip(&fresh.pixels).enumerate() {
        let bits = |v: glam::Vec3| v.to_array().map(f32::to_bits);
        assert_eq!(
            bits(*a),
            bits(*b),
            "{what}: pixel ({}, {}) is {a} live, {b} fresh",
            i as u32 % live.width,
            i as u32 / live.width
        );
    }
}

/// Renders `desc` live and checks it against a fresh render.
fn step(live: &mut LiveRender, desc: &SceneDesc, what: &str) -> LiveReport {
    let report = live
        .render(desc, &options(true), &CancelToken::new(), &|_| {})
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    assert_same_bits(&report.film, &fresh(desc), what);
    report
}

fn material<'a>(
    desc: &'a mut SceneDesc,
    name: &str,
) -> &'a mut penumbra::render::scene_file::MaterialDesc {
    desc.materials.get_mut(name).expect("material")
}

#[test]
fn a_scripted_session_of_edits_stays_exact_and_costs_what_its_class_says() {
    let mut live = LiveRender::default();
    let mut d = room(96, 54);
    let r = step(&mut live, &d, "first render");
    assert_eq!(r.class, EditClass::Rebuild);
    assert!(r.record_bytes > 0, "the first render records its paths");

    // Each edit with the class it must have and whether it may trace rays.
    type Edit = (&'static str, EditClass, fn(&mut SceneDesc));
    let edits: [Edit; 22] = [
        ("specular strength", EditClass::Recombine, |d| {
            d.render.terms.specular = 0.3
        }),
        ("diffuse term off", EditClass::Recombine, |d| {
            d.render.terms.diffuse = 0.0
        }),
        ("diffuse term back", EditClass::Recombine, |d| {
            d.render.terms.diffuse = 1.7
        }),
        ("light diffuse colour", EditClass::Recombine, |d| {
            d.light.diffuse = [0.9, 0.2, 0.4]
        }),
        ("light ambient colour", EditClass::Recombine, |d| {
            d.light.ambient = [0.3, 0.3, 0.1]
        }),
        ("material colour", EditClass::Recombine, |d| {
            material(d, "red").diffuse = [0.1, 0.8, 0.3]
        }),
        ("specular colour from zero", EditClass::Recombine, |d| {
            material(d, "sand").specular = [0.0, 0.0, 0.0];
        }),
        ("background", EditClass::Recombine, |d| {
            d.render.background = [0.2, 0.1, 0.05]
        }),
        ("shininess override", EditClass::Reshade, |d| {
            d.render.shininess_override = Some(7.0)
        }),
        ("override off", EditClass::Reshade, |d| {
            d.render.shininess_override = None
        }),
        ("one material's shininess", EditClass::Reshade, |d| {
            material(d, "steel").shininess = 3.5
        }),
        ("reflectivity from 0", EditClass::Reshade, |d| {
            material(d, "white").reflectivity = 0.5
        }),
        ("reflectivity down", EditClass::Reshade, |d| {
            material(d, "mirror").reflectivity = 0.01
        }),
        ("reflectivity to 0", EditClass::Reshade, |d| {
            material(d, "steel").reflectivity = 0.0
        }),
        ("shadow rays", EditClass::Retrace, |d| {
            d.render.shadow_rays = 16
        }),
        ("random pattern", EditClass::Retrace, |d| {
            d.render.sampling = Sampling::Random
        }),
        (
            "shininess under a random pattern",
            EditClass::Reshade,
            |d| material(d, "white").shininess = 80.0,
        ),
        ("light moved", EditClass::Relight, |d| {
            d.light.corner[0] += 0.25
        }),
        ("light grown, and a shininess", EditClass::Relight, |d| {
            d.light.edge_u[0] *= 1.5;
            material(d, "steel").shininess = 60.0;
        }),
        ("camera moved", EditClass::Retrace, |d| {
            d.camera.position[1] += 0.3
        }),
        ("nothing", EditClass::Nothing, |_| {}),
        ("an object moved", EditClass::Rebuild, |d| {
            if let penumbra::render::scene_file::ObjectDesc::Sphere(s) = &mut d.objects[7] {
                s.radius *= 0.5;
            }
        }),
    ];
    for (what, class, edit) in edits {
        let before = d.clone();
        edit(&mut d);
        assert_eq!(classify(&before, &d), class, "{what}");
        let r = step(&mut live, &d, what);
        assert_eq!(r.class, class, "{what}");
        if class <= EditClass::Recombine {
            assert_eq!(r.stats.traced(), 0, "{what}: a recombine traces no ray");
        }
        if what == "reflectivity from 0" {
            assert!(
                r.retraced_pixels > 0,
                "the white walls now reflect: their pixels trace"
            );
            assert!(r.retraced_pixels < 96 * 54, "but not every pixel");
        }
        if what == "shininess override" {
            assert_eq!(r.stats.traced(), 0, "a new shininess traces no ray");
        }
    }
}

#[test]
fn every_model_and_pattern_reshades_exactly() {
    for model in AreaLightModel::ALL {
        for sampling in [Sampling::Grid, Sampling::Sobol, Sampling::Mixed] {
            let mut live = LiveRender::default();
            let mut d = room(48, 27);
            d.render.area_light_model = model;
            d.render.sampling = sampling;
            d.render.adaptive = sampling == Sampling::Mixed;
            d.render.shadow_rays = 100;
            let what = format!("{} / {}", model.name(), sampling.name());
            step(&mut live, &d, &what);
            d.render.shininess_override = Some(3.0);
            let r = step(&mut live, &d, &format!("{what}, shininess 3"));
            // The exact model keeps no visibility bits: a new shininess
            // traces again (still equal to a fresh render, which `step`
            // checks).
            let rays = if model == AreaLightModel::Exact {
                r.stats.traced()
            } else {
                0
            };
            assert_eq!(
                (r.class, r.stats.traced()),
                (EditClass::Reshade, rays),
                "{what}"
            );
            assert!(model != AreaLightModel::Exact || rays > 0, "{what}");
            material(&mut d, "mirror").specular = [0.2, 0.9, 0.1];
            d.render.terms.ambient = 0.25;
            step(&mut live, &d, &format!("{what}, colours"));
        }
    }
}

/// Every model's recorded frames (traced side by side, their factors set
/// in the records once the lanes have them) serve a light edit, then
/// colour, strength and shininess edits, each equal to a fresh render; the
/// mirror's reflections and one and several camera samples included.
#[test]
fn every_model_s_records_serve_light_and_colour_edits_exactly() {
    for model in AreaLightModel::ALL {
        for spp in [1, 3] {
            let what = format!("{} × {spp} spp", model.name());
            let mut live = LiveRender::default();
            let mut d = room(48, 27);
            d.render.area_light_model = model;
            d.render.shadow_rays = 16;
            d.render.samples_per_pixel = spp;
            step(&mut live, &d, &what);
            d.light.corner[0] += 0.4;
            let r = step(&mut live, &d, &format!("{what}, light moved"));
            assert!(r.record_bytes > 0, "{what}: the paths are recorded again");
            d.render.terms.diffuse = 0.5;
            material(&mut d, "sand").diffuse = [0.1, 0.7, 0.3];
            let r = step(&mut live, &d, &format!("{what}, colours"));
            assert_eq!(r.stats.traced(), 0, "{what}: colours trace no ray");
            material(&mut d, "steel").shininess = 9.0;
            step(&mut live, &d, &format!("{what}, shininess"));
        }
    }
}

#[test]
fn anti_aliased_frames_recombine_and_reshade_exactly() {
    let mut live = LiveRender::default();
    let mut d = room(48, 27);
    d.render.samples_per_pixel = 5;
    d.render.sampling = Sampling::Stratified;
    step(&mut live, &d, "5 samples per pixel");
    d.render.terms.diffuse = 0.4;
    let r = step(&mut live, &d, "5 spp, strength");
    assert_eq!(r.stats.traced(), 0);
    material(&mut d, "steel").shininess = 4.0;
    let r = step(&mut live, &d, "5 spp, shininess");
    assert_eq!(r.stats.traced(), 0);
    material(&mut d, "white").reflectivity = 0.3;
    let r = step(&mut live, &d, "5 spp, reflectivity from 0");
    assert!(r.retraced_pixels > 0);
    d.render.samples_per_pixel = 2;
    let r = step(&mut live, &d, "2 spp");
    assert_eq!(r.class, EditClass::Retrace);
}

#[test]
fn frames_of_few_shadow_rays_reshade_and_relight_exactly() {
    // Up to four light points a hit, a frame's shadow rays are traced
    // sixteen hits at a time, after the hits are recorded: their
    // visibility reaches the records later, and a new shininess re-shades
    // from it.
    for (sampling, rays, spp) in [
        (Sampling::Grid, 1, 1),
        (Sampling::Random, 3, 1),
        (Sampling::Grid, 4, 1),
        (Sampling::Stratified, 2, 2),
    ] {
        let what = format!("{} × {rays}, {spp} spp", sampling.name());
        let mut live = LiveRender::default();
        let mut d = room(48, 27);
        d.render.sampling = sampling;
        d.render.shadow_rays = rays;
        d.render.samples_per_pixel = spp;
        step(&mut live, &d, &what);
        // A new shininess, re-shaded from the recorded visibility alone.
        let reshade = |d: &mut SceneDesc, shininess: f64, live: &mut LiveRender| {
            d.render.shininess_override = Some(shininess);
            let r = step(live, d, &format!("{what}, shininess {shininess}"));
            assert_eq!(
                (r.class, r.stats.traced()),
                (EditClass::Reshade, 0),
                "{what}"
            );
        };
        reshade(&mut d, 3.0, &mut live);
        d.light.corner[0] += 0.3;
        let r = step(&mut live, &d, &format!("{what}, light moved"));
        assert_eq!(r.class, EditClass::Relight, "{what}");
        reshade(&mut d, 40.0, &mut live);
    }
}

#[test]
fn shadow_packets_of_a_crowded_room_reshade_exactly() {
    // From 256 objects on, shadow rays walk the light-frame BVH as packets.
    let mut d = generate(300, 5, Layout::Volume);
    d.camera.width = 64;
    d.camera.height = 36;
    let mut live = LiveRender::default();
    step(&mut live, &d, "300 spheres");
    for m in d.materials.values_mut() {
        m.shininess = 9.0;
        m.reflectivity = 0.4;
    }
    let r = step(&mut live, &d, "300 spheres, shininess and reflectivity");
    assert_eq!(r.class, EditClass::Reshade);
}

#[test]
fn above_the_memory_cap_edits_fall_back_to_tracing_and_stay_exact() {
    let d0 = room(64, 36);
    for cap in [0, 64 << 10, 200 << 10] {
        let mut live = LiveRender::new(cap);
        let r = step(&mut live, &d0, "first");
        assert!(
            r.record_bytes <= cap,
            "records {} above the cap {cap}",
            r.record_bytes
        );
        let mut d = d0.clone();
        d.render.terms.specular = 0.5;
        let r = step(&mut live, &d, "strength");
        if cap == 0 {
            assert!(r.stats.traced() > 0, "no records: the strength edit traces");
        }
        d.render.shininess_override = Some(2.0);
        step(&mut live, &d, "shininess");
        assert!(live.record_bytes() <= cap);
    }
}

#[test]
fn logarithms_kept_by_a_reshade_give_the_next_ones_exactly_within_the_cap() {
    let d0 = room(80, 45);
    // How much the records take, and how much with every tile's logarithms.
    let mut live = LiveRender::default();
    let bare = step(&mut live, &d0, "first").record_bytes;
    let mut d = d0.clone();
    d.render.shininess_override = Some(12.0);
    let full = step(&mut live, &d, "keeps logarithms").record_bytes;
    assert!(
        full > bare + bare / 4,
        "logarithms kept: {bare} → {full} bytes"
    );
    // All tiles, about half of them, none.
    for cap in [live.cap(), (bare + full) / 2, bare + 1000] {
        let mut live = LiveRender::new(cap);
        let mut d = d0.clone();
        let paths = step(&mut live, &d, "first").record_bytes;
        let check = |live: &mut LiveRender, d: &SceneDesc, what: &str| {
            let r = step(live, d, what);
            assert_eq!(r.class, EditClass::Reshade, "{what}");
            assert_eq!(r.stats.traced(), 0, "{what}: no ray");
            assert!(
                r.record_bytes <= cap,
                "{what}: {} > cap {cap}",
                r.record_bytes
            );
            r.record_bytes
        };
        d.render.shininess_override = Some(12.0);
        let kept = check(&mut live, &d, "override (keeps)");
        // The paths' records alone (what more samples would scale) stay.
        assert_eq!(live.path_record_bytes(), paths);
        if cap == bare + 1000 {
            assert!(kept <= bare + 1000, "no room: no tile keeps");
        } else {
            assert!(kept > bare, "some tiles keep logarithms");
        }
        d.render.shininess_override = Some(300.0);
        check(&mut live, &d, "override from the logarithms");
        d.render.shininess_override = None;
        check(&mut live, &d, "override off");
        material(&mut d, "steel").shininess = 3.5;
        check(&mut live, &d, "one material's shininess");
        material(&mut d, "white").shininess = 0.25;
        check(&mut live, &d, "another material's shininess");
        // Longer paths traced again: those tiles' logarithms go.
        material(&mut d, "white").reflectivity = 0.5;
        step(&mut live, &d, "reflectivity from 0");
        d.render.shininess_override = Some(40.0);
        step(&mut live, &d, "override after the re-traced tiles");
        d.render.shininess_override = Some(41.0);
        step(&mut live, &d, "and again");
    }
}

#[test]
fn a_cancelled_edit_leaves_the_next_one_exact() {
    let mut live = LiveRender::default();
    let mut d = room(64, 36);
    step(&mut live, &d, "first");
    for (what, edit) in [
        (
            "shininess",
            (|d: &mut SceneDesc| material(d, "steel").shininess = 2.0) as fn(&mut SceneDesc),
        ),
        ("reflectivity", |d| material(d, "red").reflectivity = 0.6),
        ("strength", |d| d.render.terms.ambient = 0.1),
        ("shadow rays", |d| d.render.shadow_rays = 9),
    ] {
        edit(&mut d);
        let cancel = CancelToken::new();
        let stop = cancel.clone();
        // Cancel from the first finished tile on.
        let r = live.render(&d, &options(true), &cancel, &move |_| stop.cancel());
        assert!(
            matches!(r, Err(LiveError::Cancelled(_))),
            "{what}: cancelled"
        );
        let r = step(&mut live, &d, &format!("after a cancelled {what} edit"));
        if what == "shininess" || what == "strength" {
            // Each tile knows what its factors hold: the records survive.
            assert_eq!(r.stats.traced(), 0, "{what}: records kept");
        }
    }
}

#[test]
fn a_refused_edit_names_the_field_and_keeps_the_last_scene() {
    let mut live = LiveRender::default();
    let mut d = room(32, 18);
    step(&mut live, &d, "first");
    let good = d.clone();
    d.render.terms.diffuse = -1.0;
    let err = live
        .render(&d, &options(false), &CancelToken::new(), &|_| {})
        .expect_err("a negative strength is refused");
    assert!(err.to_string().contains("render.terms.diffuse"), "{err}");
    let r = step(&mut live, &good, "back to the good scene");
    assert_eq!(r.class, EditClass::Nothing);
}

/// One edit of a random class, drawn by proptest.
#[derive(Debug, Clone)]
enum RandomEdit {
    Strength(usize, f64),
    LightColour(usize, [f64; 3]),
    MaterialColour(usize, usize, [f64; 3]),
    Shininess(usize, f64),
    Override(Option<f64>),
    Reflectivity(usize, f64),
    Background([f64; 3]),
    ShadowRays(u32),
    Sampling(usize),
    Model(usize),
    Depth(u32),
    LightCorner(f64),
    LightSize(f64, f64),
    Camera(f64),
    Samples(u32),
}

fn apply(d: &mut SceneDesc, e: &RandomEdit) {
    let names: Vec<String> = d.materials.keys().cloned().collect();
    let pick = |i: usize| names[i % names.len()].clone();
    match e {
        RandomEdit::Strength(t, v) => match t % 3 {
            0 => d.render.terms.ambient = *v,
            1 => d.render.terms.diffuse = *v,
            _ => d.render.terms.specular = *v,
        },
        RandomEdit::LightColour(t, c) => match t % 3 {
            0 => d.light.ambient = *c,
            1 => d.light.diffuse = *c,
            _ => d.light.specular = *c,
        },
        RandomEdit::MaterialColour(m, t, c) => {
            let m = material(d, &pick(*m));
            match t % 3 {
                0 => m.ambient = *c,
                1 => m.diffuse = *c,
                _ => m.specular = *c,
            }
        }
        RandomEdit::Shininess(m, s) => material(d, &pick(*m)).shininess = *s,
        RandomEdit::Override(s) => d.render.shininess_override = *s,
        RandomEdit::Reflectivity(m, r) => material(d, &pick(*m)).reflectivity = *r,
        RandomEdit::Background(c) => d.render.background = *c,
        RandomEdit::ShadowRays(n) => d.render.shadow_rays = *n,
        RandomEdit::Sampling(i) => d.render.sampling = Sampling::ALL[i % Sampling::ALL.len()],
        RandomEdit::Model(i) => {
            d.render.area_light_model = AreaLightModel::ALL[i % AreaLightModel::ALL.len()]
        }
        RandomEdit::Depth(n) => d.render.max_depth = *n,
        RandomEdit::LightCorner(x) => d.light.corner[2] += x,
        RandomEdit::LightSize(u, v) => {
            d.light.edge_u[0] *= u;
            d.light.edge_v[2] *= v;
        }
        RandomEdit::Camera(x) => d.camera.position[0] += x,
        RandomEdit::Samples(n) => d.render.samples_per_pixel = *n,
    }
}

fn colour() -> impl Strategy<Value = [f64; 3]> {
    prop::array::uniform3(prop_oneof![Just(0.0), 0.0..1.5f64])
}

fn random_edit() -> impl Strategy<Value = RandomEdit> {
    prop_oneof![
        4 => (0..3usize, prop_oneof![Just(0.0), 0.0..3.0f64]).prop_map(|(t, v)| RandomEdit::Strength(t, v)),
        2 => (0..3usize, colour()).prop_map(|(t, c)| RandomEdit::LightColour(t, c)),
        3 => (0..6usize, 0..3usize, colour()).prop_map(|(m, t, c)| RandomEdit::MaterialColour(m, t, c)),
        3 => (0..6usize, 1.0..800.0f64).prop_map(|(m, s)| RandomEdit::Shininess(m, s)),
        1 => prop::option::of(1.0..300.0f64).prop_map(RandomEdit::Override),
        3 => (0..6usize, prop_oneof![Just(0.0), Just(1.0), 0.0..1.0f64]).prop_map(|(m, r)| RandomEdit::Reflectivity(m, r)),
        1 => colour().prop_map(RandomEdit::Background),
        1 => (1..80u32).prop_map(RandomEdit::ShadowRays),
        1 => (0..6usize).prop_map(RandomEdit::Sampling),
        1 => (0..3usize).prop_map(RandomEdit::Model),
        1 => (1..6u32).prop_map(RandomEdit::Depth),
        2 => (-0.5..0.5f64).prop_map(RandomEdit::LightCorner),
        1 => (0.5..2.0f64, 0.5..2.0f64).prop_map(|(u, v)| RandomEdit::LightSize(u, v)),
        1 => (-0.5..0.5f64).prop_map(RandomEdit::Camera),
        1 => (1..6u32).prop_map(RandomEdit::Samples),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn random_edit_sequences_give_the_fresh_render_bit_for_bit(
        edits in prop::collection::vec(random_edit(), 1..8),
    ) {
        let mut live = LiveRender::default();
        let mut d = room(40, 24);
        step(&mut live, &d, "first");
        for (k, e) in edits.iter().enumerate() {
            apply(&mut d, e);
            step(&mut live, &d, &format!("edit {k}: {e:?}"));
        }
    }
}

#[test]
fn a_smooth_mesh_recombines_and_reshades_exactly() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bunny.json");
    let mut d = SceneDesc::load(&path).expect("the bunny scene loads");
    d.camera.width = 64;
    d.camera.height = 36;
    d.render.shadow_rays = 16;
    let mut live = LiveRender::default();
    step(&mut live, &d, "bunny");
    d.render.shininess_override = Some(5.0);
    let r = step(&mut live, &d, "bunny, shininess");
    assert_eq!(r.stats.traced(), 0);
    for m in d.materials.values_mut() {
        m.diffuse = [0.4, 0.5, 0.6];
        m.reflectivity = 0.2;
    }
    step(&mut live, &d, "bunny, colours and reflectivity");
}

/// The light moved and resized over recorded paths: where it now cuts
/// camera or reflected rays, where rays met it before, where it changes
/// which pixels lie in its penumbra, and where it grows past the objects
/// (so reflected rays start elsewhere), together with edits of the other
/// classes — each image equal to a fresh render.
#[test]
fn light_edits_follow_the_recorded_paths_exactly() {
    let mut live = LiveRender::default();
    let mut d = room(80, 45);
    step(&mut live, &d, "first");
    material(&mut d, "steel").shininess = 7.0;
    d.render.terms.specular = 0.6;
    step(&mut live, &d, "re-shade and recombine before");
    type Edit = (&'static str, fn(&mut SceneDesc));
    let edits: [Edit; 9] = [
        ("light along x", |d| d.light.corner[0] += 0.7),
        ("light down into the view", |d| d.light.corner[1] = 4.0),
        ("light back up", |d| d.light.corner[1] = 7.99),
        ("light smaller", |d| {
            d.light.edge_u = [0.5, 0.0, 0.0];
            d.light.edge_v = [0.0, 0.0, 0.25];
        }),
        ("light larger than the room", |d| {
            d.light.corner = [-30.0, 7.99, -30.0];
            d.light.edge_u = [60.0, 0.0, 0.0];
            d.light.edge_v = [0.0, 0.0, 60.0];
        }),
        ("light back, white walls reflect", |d| {
            d.light.corner = [-1.0, 7.99, -1.0];
            d.light.edge_u = [2.0, 0.0, 0.0];
            d.light.edge_v = [0.0, 0.0, 2.0];
            material(d, "white").reflectivity = 0.5;
        }),
        ("light tilted, mirror stops reflecting", |d| {
            d.light.edge_v = [0.0, -0.5, 2.0];
            material(d, "mirror").reflectivity = 0.0;
        }),
        ("light moved, shininess override", |d| {
            d.light.corner[2] -= 0.4;
            d.render.shininess_override = Some(33.0);
        }),
        ("light moved, colours", |d| {
            d.light.corner[0] -= 1.1;
            d.light.diffuse = [0.4, 0.9, 0.2];
            material(d, "red").diffuse = [0.1, 0.2, 0.9];
        }),
    ];
    for (what, edit) in edits {
        edit(&mut d);
        let r = step(&mut live, &d, what);
        assert_eq!(r.class, EditClass::Relight, "{what}");
        assert!(r.record_bytes > 0, "{what}: the paths are recorded again");
    }
    // The records a relight leaves serve the next edits.
    d.render.terms.diffuse = 0.3;
    let r = step(&mut live, &d, "strength after the relights");
    assert_eq!((r.class, r.stats.traced()), (EditClass::Recombine, 0));
    material(&mut d, "green").shininess = 2.0;
    let r = step(&mut live, &d, "shininess after the relights");
    assert_eq!((r.class, r.stats.traced()), (EditClass::Reshade, 0));
}

#[test]
fn light_edits_of_anti_aliased_frames_and_smooth_meshes_stay_exact() {
    let mut live = LiveRender::default();
    let mut d = room(48, 27);
    d.render.samples_per_pixel = 3;
    d.render.sampling = Sampling::Stratified;
    step(&mut live, &d, "3 samples per pixel");
    d.light.corner[0] += 0.5;
    let r = step(&mut live, &d, "3 spp, light moved");
    assert_eq!(r.class, EditClass::Relight);

    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bunny.json");
    let mut d = SceneDesc::load(&path).expect("the bunny scene loads");
    d.camera.width = 64;
    d.camera.height = 36;
    d.render.shadow_rays = 16;
    let mut live = LiveRender::default();
    step(&mut live, &d, "bunny");
    // Smooth triangles' shadow points are lifted unless the light is in
    // the way: they follow the light.
    d.light.corner[1] -= 0.5;
    d.light.edge_u[0] *= 0.5;
    let r = step(&mut live, &d, "bunny, light moved and smaller");
    assert_eq!(r.class, EditClass::Relight);
}

#[test]
fn a_cancelled_relight_leaves_the_next_edit_exact() {
    let mut live = LiveRender::default();
    let mut d = room(64, 36);
    step(&mut live, &d, "first");
    d.light.corner[0] += 0.3;
    let cancel = CancelToken::new();
    let stop = cancel.clone();
    let r = live.render(&d, &options(true), &cancel, &move |_| stop.cancel());
    assert!(matches!(r, Err(LiveError::Cancelled(_))));
    d.light.corner[0] += 0.3;
    let r = step(&mut live, &d, "light moved after a cancelled relight");
    assert_eq!(r.class, EditClass::Retrace, "no records to follow");
    d.light.corner[2] += 0.3;
    let r = step(&mut live, &d, "and again");
    assert_eq!(r.class, EditClass::Relight);
}
