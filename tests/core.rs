//! Headless checks of the rendering core against values computed
//! independently of it.

mod common;

use glam::{DVec3, Vec3};
use penumbra::render::HitTarget;
use penumbra::render::rng::Rng;
use penumbra::render::sampling::Pattern;
use penumbra::render::shading::{Needs, ShadingPoint, light_terms};
use penumbra::render::shadow::{ShadowBuffers, ShadowQuery};
use penumbra::render::{CancelToken, RenderOptions};
use penumbra::render::{Loaded, RayStats, Sampling, SceneDesc};

/// A floor under a 2×2 light at height 8, seen straight from above.
fn lit_floor(extra_objects: &str, render: &str) -> String {
    format!(
        r#"{{
  "format": 1,
  "camera": {{ "position": [0.3, 6, 0.2], "look_at": [0.3, 0, 0.2], "up": [0, 0, 1],
              "fov_y_deg": 10, "width": 9, "height": 9 }},
  "render": {render},
  "light": {{ "corner": [-1, 8, -1], "edge_u": [2, 0, 0], "edge_v": [0, 0, 2],
             "ambient": [0, 0, 0], "diffuse": [1, 1, 1], "specular": [1, 1, 1] }},
  "materials": {{ "matte": {{ "ambient": [0, 0, 0], "diffuse": [1, 1, 1], "specular": [0, 0, 0],
                             "shininess": 10, "reflectivity": 0 }} }},
  "objects": [ {{ "type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "matte" }} {extra_objects} ]
}}"#
    )
}

/// (1/A)∫ max(0, N·L) dA over the light, by a fine midpoint rule in f64,
/// independent of the renderer's code.
fn average_cosine(p: DVec3, n: DVec3, corner: DVec3, eu: DVec3, ev: DVec3, steps: usize) -> f64 {
    let mut sum = 0.0;
    for i in 0..steps {
        for j in 0..steps {
            let y = corner
                + eu * ((i as f64 + 0.5) / steps as f64)
                + ev * ((j as f64 + 0.5) / steps as f64);
            sum += n.dot((y - p).normalize()).max(0.0);
        }
    }
    sum / (steps * steps) as f64
}

#[test]
fn sampled_diffuse_matches_numerical_integral() {
    let loaded = common::scene_json(&lit_floor(
        "",
        r#"{ "shadow_rays": 4096, "sampling": "grid", "max_depth": 1 }"#,
    ));
    let scene = &loaded.scene;
    let film = loaded.render_image();
    for (x, y) in [(4, 4), (0, 0), (8, 3)] {
        let ray = scene.camera.pixel_ray(x, y);
        let (target, t) = scene.closest_hit(&ray).unwrap();
        assert_eq!(target, HitTarget::Object(0));
        let p = ray.at(t);
        let expected = average_cosine(
            p,
            DVec3::Y,
            DVec3::new(-1.0, 8.0, -1.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 2.0),
            1000,
        );
        let got = film.get(x, y);
        for c in got.to_array() {
            let rel = (c as f64 - expected).abs() / expected;
            assert!(
                rel < 2e-4,
                "pixel ({x},{y}): {c} vs {expected} (rel {rel:e})"
            );
        }
    }
}

/// A slab whose edge lies on the plane x = 0 between the floor point at the
/// origin and the light: it hides exactly the light points with x > 0.
const HALF_OCCLUDER: &str =
    r#", { "type": "box", "min": [0, 3, -20], "max": [20, 4, 20], "material": "matte" }"#;

#[test]
fn occluder_hiding_half_the_light_gives_half_visibility() {
    let loaded = common::scene_json(&lit_floor(HALF_OCCLUDER, r#"{ "shadow_rays": 64 }"#));
    let pattern = Pattern::new(Sampling::Grid, 64);
    let mut buf = ShadowBuffers::with_capacity(pattern.count());
    let mut stats = RayStats::default();
    // `shadow::visibility` is crate-private; the light factors run it and
    // leave each light point's visibility in `buf.vis`.
    let point = ShadingPoint {
        point: DVec3::ZERO,
        normal: DVec3::Y,
        view: DVec3::Y,
        shadow: ShadowQuery {
            point: DVec3::ZERO,
            normal: DVec3::Y,
            object: 0,
            inside: false,
        },
        material: &loaded.shading.materials[0],
        material_index: 0,
    };
    light_terms(
        &loaded.scene,
        &loaded.settings,
        &point,
        Needs::ALL,
        &pattern,
        &mut Rng::new(1),
        &mut buf,
        &mut stats,
    );
    let visible: f32 = buf.vis[..64].iter().sum();
    assert_eq!(visible, 32.0);
    // Exactly the points on the x < 0 half arrive.
    for j in 0..64 {
        let x = -1.0 + 2.0 * buf.a[j];
        assert_eq!(buf.vis[j] == 1.0, x < 0.0, "light point {j} at x = {x}");
    }
    assert_eq!(stats.shadow, 64);

    // The same through the renderer: the report's model scales the
    // unshadowed diffuse term by the visible fraction, here 1/2.
    let overhead = |extra: &str| {
        lit_floor(
            extra,
            r#"{ "shadow_rays": 64, "area_light_model": "nearest_point" }"#,
        )
        .replace(
            r#""position": [0.3, 6, 0.2], "look_at": [0.3, 0, 0.2]"#,
            r#""position": [0, 2, 0], "look_at": [0, 0, 0]"#,
        )
    };
    let (lit, half) = (overhead(""), overhead(HALF_OCCLUDER));
    let (a, b) = (
        common::scene_json(&lit).render_image(),
        common::scene_json(&half).render_image(),
    );
    let centre = |f: &penumbra::render::Film| f.get(4, 4).x;
    assert!(centre(&a) > 0.5);
    assert_eq!(centre(&b), centre(&a) * 0.5);
}

#[test]
fn ambient_only_render_is_material_times_light_ambient() {
    let mut desc = common::seed_room(96, 54);
    desc.render.terms.diffuse = 0.0;
    desc.render.terms.specular = 0.0;
    desc.render.max_depth = 1;
    let loaded = common::build(desc);
    let (scene, shading) = (&loaded.scene, &loaded.shading);
    let film = loaded.render_image();
    let mut objects_seen = std::collections::HashSet::new();
    for y in 0..54 {
        for x in 0..96 {
            let expected = match scene.closest_hit(&scene.camera.pixel_ray(x, y)) {
                Some((HitTarget::Object(i), _)) => {
                    objects_seen.insert(i);
                    let m = &shading.materials[scene.objects[i as usize].material as usize];
                    m.ambient * shading.light.ambient
                }
                Some((HitTarget::Light, _)) => shading.light.diffuse,
                None => loaded.settings.background,
            };
            assert_eq!(film.get(x, y), expected, "pixel ({x},{y})");
        }
    }
    assert!(
        objects_seen.len() >= 7,
        "most objects visible: {objects_seen:?}"
    );
}

#[test]
fn reflections_change_only_pixels_that_see_a_mirror() {
    let shallow = {
        let mut d = common::seed_room(96, 54);
        d.render.max_depth = 1;
        common::build(d)
    };
    let deep = common::build(common::seed_room(96, 54));
    let (a, b) = (shallow.render_image(), deep.render_image());
    let mut differing = 0;
    for y in 0..54 {
        for x in 0..96 {
            let reflective = match deep.scene.closest_hit(&deep.scene.camera.pixel_ray(x, y)) {
                Some((HitTarget::Object(i), _)) => {
                    let material = deep.scene.objects[i as usize].material;
                    deep.shading.materials[material as usize].reflectivity > 0.0
                }
                _ => false,
            };
            if a.get(x, y) != b.get(x, y) {
                differing += 1;
                assert!(
                    reflective,
                    "pixel ({x},{y}) changed but sees no reflective surface"
                );
            }
        }
    }
    assert!(differing > 100, "reflections visible on {differing} pixels");
}

/// A 1×1 view of two mirror planes of reflectivity `r` and ambient colour
/// `ambient` (nothing else of their own), under a light of ambient and
/// diffuse `light`. `facing`: the second plane faces the floor (a
/// corridor, the camera between them looking along it), else it is a wall
/// that sends the floor's reflection up to the light.
fn two_mirrors(r: f64, ambient: f64, light: [f64; 2], max_depth: u32, facing: bool) -> Loaded {
    let (eye, target, second) = if facing {
        (
            "[0, 0.5, 0]",
            "[0, 0, 0.5]",
            r#""point": [0, 1, 0], "normal": [0, -1, 0]"#,
        )
    } else {
        (
            "[0, 1, -1]",
            "[0, 0, 0]",
            r#""point": [0, 0, 1.5], "normal": [0, 0, -1]"#,
        )
    };
    let [la, ld] = light;
    common::scene_json(&format!(
        r#"{{
  "format": 1,
  "camera": {{ "position": {eye}, "look_at": {target}, "up": [0, 1, 0],
              "fov_y_deg": 30, "width": 1, "height": 1 }},
  "render": {{ "max_depth": {max_depth}, "shadow_rays": 1 }},
  "light": {{ "corner": [-0.25, 2.5, 0.25], "edge_u": [0.5, 0, 0], "edge_v": [0, 0, 0.5],
             "ambient": [{la}, {la}, {la}], "diffuse": [{ld}, {ld}, {ld}], "specular": [0, 0, 0] }},
  "materials": {{ "m": {{ "ambient": [{ambient}, {ambient}, {ambient}], "diffuse": [0, 0, 0],
                        "specular": [0, 0, 0], "shininess": 1, "reflectivity": {r} }} }},
  "objects": [ {{ "type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "m" }},
               {{ "type": "plane", {second}, "material": "m" }} ]
}}"#
    ))
}

/// The scene format sums every hit up to `max_depth` (colour = local +
/// reflectivity · reflected): a path whose weight is small still reaches
/// what it reaches, however bright, and a corridor of mirrors is followed
/// for as many hits as `max_depth` allows, with skipping on or off.
#[test]
fn reflected_paths_are_followed_to_max_depth_however_faint() {
    for skip in [true, false] {
        // Floor, wall, light: weight 0.03 · 0.03 = 9e-4 on the light's
        // 1000 gives 0.9.
        let mut loaded = two_mirrors(0.03, 0.0, [0.0, 1000.0], 4, false);
        loaded.settings.skip = skip;
        let pixel = loaded.render_image().get(0, 0);
        assert!(
            (pixel - Vec3::splat(0.9)).abs().max_element() < 1e-5,
            "skip {skip}: {pixel} against 0.9"
        );
        // Between mirrors of reflectivity 0.5 and ambient 0.1 each hit
        // adds 0.1 · 0.5^i: the sum tells how many hits were made.
        for depth in [8, 12, 16] {
            let mut loaded = two_mirrors(0.5, 0.1, [1.0, 0.0], depth, true);
            loaded.settings.skip = skip;
            let pixel = loaded.render_image().get(0, 0).x as f64;
            let expected: f64 = (0..depth).map(|i| 0.1 * 0.5f64.powi(i as i32)).sum();
            assert!(
                (pixel - expected).abs() < 2e-7,
                "skip {skip}, max_depth {depth}: {pixel} against {expected}"
            );
        }
    }
}

fn render_with(loaded: &Loaded, options: RenderOptions) -> penumbra::render::RenderReport {
    loaded
        .render(&options, &CancelToken::new(), &|_| {})
        .unwrap()
}

#[test]
fn image_is_identical_for_any_thread_count_and_pass_schedule() {
    let mut desc = common::seed_room(120, 68);
    desc.render.sampling = Sampling::Random;
    desc.render.shadow_rays = 80;
    let scene = common::build(desc);
    let one = render_with(
        &scene,
        RenderOptions {
            threads: Some(1),
            ..Default::default()
        },
    );
    let two = render_with(
        &scene,
        RenderOptions {
            threads: Some(2),
            tile_size: 16,
            ..Default::default()
        },
    );
    let progressive = render_with(
        &scene,
        RenderOptions {
            threads: Some(2),
            progressive: true,
            tile_size: 24,
        },
    );
    assert!(one.film == two.film, "1 vs 2 threads");
    assert!(one.film == progressive.film, "one-shot vs progressive");
    assert_eq!(one.stats, two.stats);
    assert_eq!(one.stats, progressive.final_stats);
    assert!(
        progressive.stats.camera > one.stats.camera,
        "progressive ran more than one pass"
    );
}

#[test]
fn progressive_render_streams_every_tile_of_every_pass() {
    let loaded = common::build(common::seed_room(100, 60));
    let seen = std::sync::Mutex::new(Vec::new());
    let report = loaded
        .render(
            &RenderOptions {
                progressive: true,
                tile_size: 32,
                ..Default::default()
            },
            &CancelToken::new(),
            &|t| {
                seen.lock()
                    .unwrap()
                    .push((t.pass_index, t.rect, t.pixels.len(), t.tiles_total))
            },
        )
        .unwrap();
    let seen = seen.into_inner().unwrap();
    let plan = penumbra::render::pass_plan(64);
    assert_eq!(plan.len(), 2, "{plan:?}");
    let tiles = 4 * 2;
    assert_eq!(seen.len(), plan.len() * tiles);
    for pass in 0..plan.len() {
        let area: usize = seen.iter().filter(|s| s.0 == pass).map(|s| s.2).sum();
        assert_eq!(area, 100 * 60, "pass {pass} covers the image");
    }
    // Tiles are handed over centre first within a pass.
    assert!(
        seen.iter()
            .all(|s| s.3 == tiles && s.2 == (s.1.w * s.1.h) as usize)
    );
    assert!(!report.film.has_non_finite());
}

#[test]
fn cancelling_stops_a_render_early() {
    let loaded = common::build(common::seed_room(640, 360));
    let cancel = CancelToken::new();
    let tiles = std::sync::atomic::AtomicUsize::new(0);
    let result = loaded.render(
        &RenderOptions {
            threads: Some(2),
            ..Default::default()
        },
        &cancel,
        &|_| {
            if tiles.fetch_add(1, std::sync::atomic::Ordering::SeqCst) == 2 {
                cancel.cancel();
            }
        },
    );
    assert!(result.is_err());
    let done = tiles.into_inner();
    // 240 tiles in all; it stops within about a tile per thread.
    assert!(done <= 6, "{done} tiles finished after cancelling");
}

#[test]
fn every_scene_file_loads_and_renders_without_nan() {
    let mut files = Vec::new();
    let mut dirs = vec![std::path::PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes"
    ))];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "json") {
                files.push(path);
            }
        }
    }
    assert!(files.len() >= 5, "scenes found: {files:?}");
    for path in files {
        let mut desc = penumbra::render::SceneDesc::load(&path).unwrap_or_else(|e| panic!("{e}"));
        desc.camera.width = 64;
        desc.camera.height = 36;
        let film = Loaded::new(&desc).unwrap().render_image();
        assert!(
            !film.has_non_finite(),
            "{} has NaN/Inf pixels",
            path.display()
        );
    }
}

#[test]
fn skipping_work_does_not_change_the_image() {
    for model in ["sampled", "nearest_point"] {
        let mut desc = common::seed_room(160, 90);
        desc.render.area_light_model = serde_json::from_str(&format!("\"{model}\"")).unwrap();
        desc.render.sampling = Sampling::Stratified;
        let (a, b) = skip_on_and_off(desc, false, model);
        assert!(
            a.shadow_skipped() > a.shadow,
            "{model}: most shadow rays skipped"
        );
        assert_eq!(b.shadow_skipped(), 0);
    }
}

/// Renders `desc` with skipping on and off, asserts whether shadow packets
/// were used and that the images are identical; returns the two runs' ray
/// counts.
fn skip_on_and_off(desc: SceneDesc, packets: bool, what: &str) -> (RayStats, RayStats) {
    let fast = common::build(desc.clone());
    assert_eq!(
        fast.scene.shadow_bvh.is_some(),
        packets,
        "{what}: packets in use"
    );
    let mut slow = common::build(desc);
    slow.settings.skip = false;
    let a = render_with(&fast, RenderOptions::default());
    let b = render_with(&slow, RenderOptions::default());
    assert!(a.film == b.film, "{what}: images differ");
    (a.stats, b.stats)
}

/// Many objects: shadow rays walk the light-frame BVH as packets, keeping
/// only the rays that can meet each box; the image must be the one tracing
/// every ray against every object gives, for grids, for patterns drawn per
/// hit point, for more rays than one packet holds, and in adaptive mode.
#[test]
fn shadow_packets_give_the_image_of_tracing_everything() {
    use penumbra::render::PACKET_THRESHOLD;
    use penumbra::render::generate::spheres_in_room;
    assert!(
        common::build(spheres_in_room(PACKET_THRESHOLD - 1, 3))
            .scene
            .shadow_bvh
            .is_none()
    );
    let cases = [
        (1000, Sampling::Grid, 64, false),
        (300, Sampling::Random, 100, false),
        (300, Sampling::Sobol, 16, false),
        (300, Sampling::Stratified, 64, true),
    ];
    for (n, sampling, rays, adaptive) in cases {
        let mut desc = spheres_in_room(n, 3);
        desc.camera.width = 96;
        desc.camera.height = 54;
        desc.render.sampling = sampling;
        desc.render.shadow_rays = rays;
        desc.render.adaptive = adaptive;
        let what = format!("{n} spheres, {sampling:?}, {rays} rays");
        let (a, b) = skip_on_and_off(desc, true, &what);
        // The packets leave out most ray-object tests, and some rays
        // entirely: every box they could meet lies elsewhere.
        assert!(a.shadow < b.shadow, "{a:?} vs {b:?}");
    }
}

/// The packets with every kind of bounded object — rotated boxes, rects at
/// all angles (some edge-on to the light), spheres — under a tilted,
/// non-rectangular light, whose frame is not the world's: still the image
/// of tracing everything.
#[test]
fn shadow_packets_handle_every_shape_under_a_tilted_light() {
    use penumbra::render::scene_file::{BoxDesc, ObjectDesc, RectDesc, SphereDesc};
    let mut desc = penumbra::render::generate::spheres_in_room(0, 1);
    desc.light.corner = [-1.5, 7.0, -1.0];
    desc.light.edge_u = [2.5, 0.6, 0.3];
    desc.light.edge_v = [0.8, 0.2, 2.0];
    let mut rng = Rng::new(42);
    let mut u =
        |lo: f64, hi: f64| lo + (hi - lo) * (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    for i in 0..300 {
        let c = [u(-4.0, 4.0), u(0.3, 6.0), u(-4.0, 4.0)];
        let s = u(0.05, 0.4);
        desc.objects.push(match i % 3 {
            0 => ObjectDesc::Box(BoxDesc {
                min: [c[0] - s, c[1] - s, c[2] - s],
                max: [c[0] + s, c[1] + 0.5 * s, c[2] + 2.0 * s],
                rotate_y_deg: u(0.0, 90.0),
                translate: [0.0; 3],
                material: "sand".into(),
            }),
            1 => ObjectDesc::Rect(RectDesc {
                corner: c,
                edge_u: [u(-0.5, 0.5), u(-0.5, 0.5), u(-0.5, 0.5)],
                // Every tenth rect stands edge-on to the world's y axis.
                edge_v: if i % 10 == 1 {
                    [0.0, 0.6, 0.0]
                } else {
                    [u(-0.5, 0.5), u(-0.5, 0.5), u(-0.5, 0.5)]
                },
                material: "green".into(),
            }),
            _ => ObjectDesc::Sphere(SphereDesc {
                center: c,
                radius: s,
                material: "mirror".into(),
            }),
        });
    }
    desc.camera.width = 80;
    desc.camera.height = 45;
    desc.render.shadow_rays = 16;
    let (a, b) = skip_on_and_off(desc, true, "mixed shapes, tilted light");
    assert!(a.shadow < b.shadow, "{a:?} vs {b:?}");
}

/// Hundreds of spheres around one centre land in one leaf of the binary
/// BVH; the packets' 4-wide tree splits it, and the image is still exact.
#[test]
fn concentric_spheres_render_exactly_with_packets() {
    let mut desc = penumbra::render::generate::spheres_in_room(0, 1);
    for i in 0..300 {
        desc.objects
            .push(penumbra::render::scene_file::ObjectDesc::Sphere(
                penumbra::render::scene_file::SphereDesc {
                    center: [0.5, 2.0, 1.0],
                    radius: 0.2 + 0.004 * i as f64,
                    material: "red".into(),
                },
            ));
    }
    desc.camera.width = 64;
    desc.camera.height = 36;
    skip_on_and_off(desc, true, "concentric spheres");
}

#[test]
fn srgb_encoding_rounds_correctly() {
    use penumbra::render::film::{decode_channel, encode_channel};
    for c in 0..=255u8 {
        assert_eq!(encode_channel(decode_channel(c)), c);
    }
    assert_eq!(encode_channel(-1.0), 0);
    assert_eq!(encode_channel(f32::NAN), 0);
    assert_eq!(encode_channel(7.0), 255);
    let mid = penumbra::render::math::linear_to_srgb(0.2);
    assert_eq!(encode_channel(0.2), (mid * 255.0).round() as u8);
    assert_eq!(Vec3::splat(0.5).to_array().map(encode_channel), [188; 3]);
}

#[test]
fn analytic_model_is_exact_and_noise_free_where_the_light_is_unblocked() {
    // Four random shadow rays are enough: with nothing in the way the ratio
    // estimator's ratio is 1 and the closed form is all that remains.
    let loaded = common::scene_json(&lit_floor(
        "",
        r#"{ "shadow_rays": 4, "sampling": "random", "area_light_model": "analytic", "max_depth": 1 }"#,
    ));
    let scene = &loaded.scene;
    let film = loaded.render_image();
    for (x, y) in [(4, 4), (0, 0), (8, 3)] {
        let ray = scene.camera.pixel_ray(x, y);
        let (_, t) = scene.closest_hit(&ray).unwrap();
        let expected = average_cosine(
            ray.at(t),
            DVec3::Y,
            DVec3::new(-1.0, 8.0, -1.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 2.0),
            1000,
        );
        let got = film.get(x, y).x as f64;
        let rel = (got - expected).abs() / expected;
        assert!(
            rel < 1e-5,
            "pixel ({x},{y}): {got} vs {expected} (rel {rel:e})"
        );
    }
}

#[test]
fn sampled_and_analytic_models_converge_to_one_image() {
    let mut desc = common::seed_room(48, 27);
    desc.render.terms.specular = 0.0;
    desc.render.sampling = Sampling::Stratified;
    desc.render.shadow_rays = 1024;
    let sampled = common::build(desc.clone()).render_image();
    desc.render.area_light_model = penumbra::render::AreaLightModel::Analytic;
    let analytic = common::build(desc).render_image();
    let c = penumbra::render::compare::compare(&sampled, &analytic).unwrap();
    assert!(c.rmse < 2e-3, "rmse {:e}", c.rmse);
}

#[test]
fn tile_updates_count_the_rays_of_the_render() {
    let loaded = common::build(common::seed_room(80, 45));
    let rays = std::sync::atomic::AtomicU64::new(0);
    let report = loaded
        .render(
            &RenderOptions {
                progressive: true,
                ..Default::default()
            },
            &CancelToken::new(),
            &|t| {
                rays.fetch_add(t.rays, std::sync::atomic::Ordering::Relaxed);
            },
        )
        .unwrap();
    assert_eq!(rays.into_inner(), report.stats.traced());
}

#[test]
fn pass_plans_leave_out_intermediate_passes_below_16_rays() {
    let counts = |n: u32| -> Vec<(u32, u32)> {
        penumbra::render::pass_plan(n)
            .iter()
            .map(|p| (p.shadow_rays, p.block))
            .collect()
    };
    assert_eq!(counts(1), [(1, 8), (1, 1)]);
    assert_eq!(counts(64), [(4, 8), (64, 1)]);
    assert_eq!(counts(255), [(4, 8), (255, 1)]);
    assert_eq!(counts(256), [(4, 8), (16, 1), (256, 1)]);
    assert_eq!(counts(1024), [(4, 8), (64, 1), (1024, 1)]);
    assert_eq!(counts(4096), [(4, 8), (16, 1), (256, 1), (4096, 1)]);
}
