//! Numerical stress scenes (`scenes/stress/`): every render is checked for
//! NaN/Inf pixels, and each scene has its own check of what must hold —
//! scale and translation invariance, no rays slipping through surfaces at
//! grazing angles, no speckle along contact lines, exact sums for extreme
//! materials, convergence for extreme sampling.
//!
//! Images are small (at most 161×91) and shadow-ray counts low so that the
//! whole file runs in seconds in a release build.

use std::path::Path;

use glam::Vec3;
use penumbra::render::compare::compare;
use penumbra::render::film::encode_srgb8;
use penumbra::render::{Film, Loaded, SceneDesc};

fn load(name: &str) -> SceneDesc {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes/stress")
        .join(name);
    SceneDesc::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// Renders and asserts that every pixel is finite.
fn render(desc: &SceneDesc, what: &str) -> Film {
    let loaded = Loaded::new(desc).unwrap_or_else(|e| panic!("{what}: {e}"));
    let film = loaded.render_image();
    let bad: Vec<(usize, Vec3)> = film
        .pixels
        .iter()
        .copied()
        .enumerate()
        .filter(|(_, p)| !p.is_finite())
        .take(5)
        .collect();
    assert!(bad.is_empty(), "{what}: non-finite pixels {bad:?}");
    dump(&film, what);
    film
}

/// With `PENUMBRA_STRESS_DUMP=dir` set, writes every render there as a PNG,
/// 4× enlarged, for a look at what a failing check saw.
fn dump(film: &Film, what: &str) {
    let Some(dir) = std::env::var_os("PENUMBRA_STRESS_DUMP") else {
        return;
    };
    let k = 4;
    let mut big = Film::new(film.width * k, film.height * k);
    for y in 0..big.height {
        for x in 0..big.width {
            big.pixels[(y * big.width + x) as usize] = film.get(x / k, y / k);
        }
    }
    let name: String = what
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect();
    penumbra::render::output::write_film(&big, &Path::new(&dir).join(format!("{name}.png")))
        .unwrap();
}

fn with_terms(desc: &SceneDesc, a: f64, d: f64, s: f64) -> SceneDesc {
    let mut desc = desc.clone();
    desc.render.terms.ambient = a;
    desc.render.terms.diffuse = d;
    desc.render.terms.specular = s;
    desc
}

/// Largest difference of one 8-bit sRGB channel between two pixels.
fn levels(a: Vec3, b: Vec3) -> u8 {
    let (a, b) = (encode_srgb8(a), encode_srgb8(b));
    (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap()
}

fn luma8(p: Vec3) -> i32 {
    let c = encode_srgb8(p);
    (c[0] as i32 * 2126 + c[1] as i32 * 7152 + c[2] as i32 * 722) / 10000
}

/// Pixels (inside `region`: x0, y0, x1, y1, exclusive) whose 8-bit luma
/// differs from the median of their 3×3 neighbourhood by more than
/// `threshold` levels: isolated dots such as shadow acne. Pixels on straight
/// or gently curved edges agree with the majority of their neighbourhood
/// and are not counted.
fn speckles(film: &Film, region: (u32, u32, u32, u32), threshold: i32) -> Vec<(u32, u32)> {
    let (x0, y0, x1, y1) = region;
    let mut out = Vec::new();
    for y in y0.max(1)..y1.min(film.height - 1) {
        for x in x0.max(1)..x1.min(film.width - 1) {
            let mut n: Vec<i32> = (0..9)
                .map(|k| luma8(film.get(x + k % 3 - 1, y + k / 3 - 1)))
                .collect();
            let own = luma8(film.get(x, y));
            n.sort_unstable();
            if (own - n[4]).abs() > threshold {
                out.push((x, y));
            }
        }
    }
    out
}

const WHOLE: (u32, u32, u32, u32) = (0, 0, u32::MAX, u32::MAX);

/// Pixels in a penumbra (some but not all shadow rays blocked somewhere
/// along the path), grown by one pixel: the image with shadows differs both
/// from the unshadowed one and from the ambient-only one.
fn penumbra_mask(desc: &SceneDesc, shadowed: &Film) -> Vec<bool> {
    let mut open = desc.clone();
    open.render.shadows = false;
    let open = render(&open, "unshadowed");
    let dark = render(&with_terms(desc, 1.0, 0.0, 0.0), "ambient only");
    let (w, h) = (shadowed.width as i64, shadowed.height as i64);
    let core: Vec<bool> = (0..shadowed.pixels.len())
        .map(|i| {
            let s = shadowed.pixels[i];
            (s - open.pixels[i]).abs().max_element() > 1e-6
                && (s - dark.pixels[i]).abs().max_element() > 1e-6
        })
        .collect();
    (0..core.len() as i64)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            (-1..=1).any(|dy| {
                (-1..=1).any(|dx| {
                    let (nx, ny) = (x + dx, y + dy);
                    nx >= 0 && ny >= 0 && nx < w && ny < h && core[(ny * w + nx) as usize]
                })
            })
        })
        .collect()
}

#[test]
fn the_room_matches_at_every_scale_and_far_from_the_origin() {
    let base = load("room.json");
    let reference = render(&base, "unit scale");
    let mask = penumbra_mask(&base, &reference);
    let masked = mask.iter().filter(|m| **m).count();
    assert!(
        masked < reference.pixels.len() / 3,
        "penumbra mask too large to be meaningful: {masked}"
    );
    let cases = [
        ("scale 1e-3", base.clone().scaled(1e-3)),
        ("scale 1e-1", base.clone().scaled(1e-1)),
        ("scale 10", base.clone().scaled(10.0)),
        ("scale 1e3", base.clone().scaled(1e3)),
        ("scale 1e5", base.clone().scaled(1e5)),
        ("translated 1e4", base.clone().translated([1e4, 1e4, 1e4])),
        (
            "scale 1e3, translated 1e6",
            base.clone().scaled(1e3).translated([1e6, -1e6, 1e6]),
        ),
    ];
    for (what, desc) in cases {
        let film = render(&desc, what);
        let c = compare(&reference, &film).unwrap();
        let mut worst_outside = 0u8;
        let mut off_inside = 0usize;
        for (i, (a, b)) in reference.pixels.iter().zip(&film.pixels).enumerate() {
            let d = levels(*a, *b);
            if mask[i] {
                off_inside += (d > 3) as usize;
            } else {
                worst_outside = worst_outside.max(d);
            }
        }
        eprintln!(
            "{what}: rmse {:.2e}, worst outside penumbrae {worst_outside} levels, \
             {off_inside} of {masked} penumbra pixels off by > 3 levels",
            c.rmse
        );
        assert!(
            c.rmse < 1.0 / 255.0,
            "{what}: rmse {:e} (max diff {} at {:?})",
            c.rmse,
            c.max_diff,
            c.max_at
        );
        assert!(
            worst_outside <= 3,
            "{what}: a pixel outside penumbrae is off by {worst_outside} levels"
        );
        // Inside penumbrae a shadow ray passing within f32 rounding of a
        // silhouette may flip; that must stay rare.
        assert!(
            off_inside <= masked / 100 + 2,
            "{what}: {off_inside} of {masked} penumbra pixels off by more than 3 levels"
        );
    }
}

/// The shadow packets (used from 256 objects on) keep their margins
/// relative to the scene: at any scale and far from the origin they give
/// the image that testing every ray against every object gives.
#[test]
fn shadow_packets_are_exact_at_every_scale() {
    let mut base = penumbra::render::generate::spheres_in_room(400, 11);
    base.camera.width = 80;
    base.camera.height = 45;
    base.render.shadow_rays = 16;
    let cases = [
        ("scale 1e-3", base.clone().scaled(1e-3)),
        ("scale 1e5", base.clone().scaled(1e5)),
        (
            "scale 1e3, translated 1e6",
            base.clone().scaled(1e3).translated([1e6, -1e6, 1e6]),
        ),
    ];
    for (what, desc) in cases {
        let fast = Loaded::new(&desc).unwrap();
        assert!(fast.scene.shadow_bvh.is_some(), "{what}: packets in use");
        let mut slow = Loaded::new(&desc).unwrap();
        slow.settings.skip = false;
        let a = fast.render_image();
        let b = slow.render_image();
        assert!(
            a.pixels.iter().all(|p| p.is_finite()),
            "{what}: non-finite pixels"
        );
        assert!(a == b, "{what}: packets change the image");
    }
}

/// Renders a scene and the same scene with the light moved by `delta` and
/// by `-delta` (relative to its size), for each delta: the configuration
/// with points exactly in the light's plane or on its edge must be the limit
/// of one side or the other, pixel by pixel, with no jump of its own and no
/// NaN. (The Phong light has no cosine of its own: it lights every point in
/// front of its plane, however grazing, and none in it, so a pixel exactly
/// in the plane takes the dark side's value.) `skip` lists pixels left out.
fn assert_limit(
    name: &str,
    deltas: &[f64],
    skip: &[(u32, u32)],
    perturb: impl Fn(&mut SceneDesc, f64),
) {
    let base = load(name);
    let exact = render(&base, name);
    let w = exact.width as usize;
    for &delta in deltas {
        let side = |d: f64| {
            let mut moved = base.clone();
            perturb(&mut moved, d);
            render(&moved, &format!("{name} moved by {d}"))
        };
        let (plus, minus) = (side(delta), side(-delta));
        let off: Vec<(usize, usize)> = (0..exact.pixels.len())
            .filter(|&i| !skip.contains(&((i % w) as u32, (i / w) as u32)))
            .filter(|&i| {
                levels(exact.pixels[i], plus.pixels[i])
                    .min(levels(exact.pixels[i], minus.pixels[i]))
                    > 3
            })
            .map(|i| (i % w, i / w))
            .collect();
        assert!(
            off.len() <= exact.pixels.len() / 1000,
            "{name} ± {delta}: {} pixels off both limits by more than 3 levels, e.g. {:?}",
            off.len(),
            &off[..off.len().min(8)]
        );
    }
}

fn light_size(desc: &SceneDesc) -> f64 {
    let l = &desc.light;
    l.edge_u
        .iter()
        .chain(&l.edge_v)
        .fold(0.0, |m, x| m.max(x.abs()))
}

#[test]
fn surfaces_in_the_lights_plane_are_continuous_under_both_models() {
    for model in penumbra::render::AreaLightModel::ALL {
        for name in ["light-in-ceiling.json", "camera-in-light-plane.json"] {
            let mut desc = load(name);
            desc.render.area_light_model = model;
            let film = render(&desc, name);
            // Not black: the room is lit.
            assert!(film.pixels.iter().any(|p| p.max_element() > 0.2), "{name}");
        }
    }
    // The light moved off the plane that hit points or the camera share
    // with it, by ±1e-9 and ±1e-6 of its size. (Above the ceiling, the
    // ceiling hides the light: that side is dark.)
    let lift = |d: &mut SceneDesc, delta: f64| d.light.corner[1] += delta * light_size(d);
    assert_limit("light-in-ceiling.json", &[1e-9, 1e-6], &[], lift);
    assert_limit("camera-in-light-plane.json", &[1e-9, 1e-6], &[], lift);
}

#[test]
fn a_light_flush_with_a_tilted_ceiling_is_not_speckled() {
    // The light lies in the ceiling's plane, both tilted by 30° about z. In
    // f32 a light point's side of the ceiling is then decided by rounding;
    // the ceiling must not block it (as it does not when axis-aligned).
    let flush = load("tilted-light-in-ceiling.json");
    let film = render(&flush, "tilted flush light");
    // The light lowered off the ceiling by 2e-3 (1e-3 of its size): the
    // same room, without the coincidence.
    let mut lowered = flush.clone();
    let l = &mut lowered.light;
    let n = glam::DVec3::from(l.edge_u)
        .cross(glam::DVec3::from(l.edge_v))
        .normalize();
    l.corner = (glam::DVec3::from(l.corner) + n * 2e-3).to_array();
    let other = render(&lowered, "tilted light lowered");
    // Corners of silhouettes are in both; dots on the walls or on the
    // ceiling around the light would be in the flush one only.
    let near = speckles(&other, WHOLE, 24);
    let added: Vec<(u32, u32)> = speckles(&film, WHOLE, 24)
        .into_iter()
        .filter(|p| !near.contains(p))
        .collect();
    let off: Vec<(usize, usize)> = (0..film.pixels.len())
        .filter(|&i| levels(film.pixels[i], other.pixels[i]) > 2)
        .map(|i| (i % film.width as usize, i / film.width as usize))
        .collect();
    // Moving the light by 2e-3 moves its reflection in the sphere by about
    // a pixel: a few pixels there differ. Dots around the light on the
    // ceiling (lit at random when the light's side is left to rounding)
    // would add more.
    eprintln!(
        "tilted flush light: {} speckles added, {} pixels off by > 2 levels: {off:?}",
        added.len(),
        off.len()
    );
    assert!(
        added.len() <= 2 && off.len() <= 6,
        "{} speckles added, e.g. {:?}; {} pixels off by > 2 levels: {off:?}",
        added.len(),
        &added[..added.len().min(8)],
        off.len()
    );
}

#[test]
fn the_nearest_point_model_is_finite_for_directions_parallel_to_the_light() {
    let loaded = Loaded::new(&load("camera-in-light-plane.json")).unwrap();
    let light = &loaded.scene.light;
    let n = light.shape.normal;
    // Points below, in and above the light's plane, looking in directions
    // parallel to it and tilted off it by tiny angles.
    for p in [
        glam::DVec3::new(4.0, 2.0, 0.5),
        glam::DVec3::new(-4.0, 6.0, 3.0),
        glam::DVec3::new(0.3, 6.0, -0.2),
        glam::DVec3::new(0.0, 9.0, 0.0),
    ] {
        for dir in [
            glam::DVec3::X,
            glam::DVec3::NEG_Z,
            glam::DVec3::new(1.0, 0.0, 1.0),
        ] {
            let parallel = light.nearest_point(p, dir);
            assert!(parallel.is_finite(), "{p} {dir}");
            let uv = light.shape.uv(parallel);
            assert!(uv.min_element() >= -1e-12 && uv.max_element() <= 1.0 + 1e-12);
            for tilt in [1e-300, 1e-12, 1e-6] {
                // Tilted towards the light's plane from the lit side, the
                // intersection runs off to infinity along `dir`: the limit
                // is the parallel answer.
                let towards = dir - n * tilt;
                let q = light.nearest_point(p, towards);
                assert!(q.is_finite(), "{p} {towards}");
                if light.illuminates(p) {
                    assert!(
                        (q - parallel).length() < 1e-9,
                        "{p} {dir} tilt {tilt}: {q} vs the parallel limit {parallel}"
                    );
                }
                assert!(light.nearest_point(p, dir + n * tilt).is_finite());
            }
        }
    }
}

/// Elevation (radians) of the centre ray of row `y` of a camera looking
/// `pitch` radians below the horizontal with vertical field `fov`.
fn row_elevation(pitch: f64, fov: f64, y: u32, height: u32) -> f64 {
    let sy = 1.0 - 2.0 * (y as f64 + 0.5) / height as f64;
    -pitch + (sy * (fov / 2.0).tan()).atan()
}

#[test]
fn a_grazing_camera_never_sees_through_the_floor() {
    let desc = load("grazing-camera.json");
    let film = render(&desc, "grazing");
    let c = &desc.camera;
    let fwd = [c.look_at[1] - c.position[1], c.look_at[2] - c.position[2]];
    let pitch = (-fwd[0] / fwd[1]).atan();
    assert!((pitch.to_degrees() - 0.001).abs() < 1e-9);
    let fov = c.fov_y_deg.to_radians();
    let (mut sky, mut floor) = (0, 0);
    for y in 0..film.height {
        let e = row_elevation(pitch, fov, y, film.height);
        for x in 0..film.width {
            let p = film.get(x, y);
            if e > 1e-9 {
                assert_eq!(
                    p,
                    Vec3::new(0.0, 0.0, 1.0),
                    "pixel ({x}, {y}) above the horizon"
                );
                sky += 1;
            } else if e < -1e-9 {
                // Nothing in the scene is blue except the background.
                assert_eq!(
                    p.z, 0.0,
                    "pixel ({x}, {y}) below the horizon sees the sky: {p}"
                );
                assert!(p.x > 0.0, "pixel ({x}, {y}) is black");
                floor += 1;
            }
        }
    }
    assert!(sky > 1000 && floor > 5000, "sky {sky}, floor {floor}");
    let s = speckles(&film, WHOLE, 8);
    assert!(s.is_empty(), "speckles on the floor: {s:?}");
}

#[test]
fn a_long_corridor_has_no_leaks_and_no_speckle() {
    let desc = load("corridor.json");
    let film = render(&desc, "corridor");
    // The corridor is closed and nothing in it is blue: a blue pixel is a
    // ray that left through a wall.
    let leaks: Vec<usize> = (0..film.pixels.len())
        .filter(|&i| film.pixels[i].z != 0.0)
        .collect();
    assert!(leaks.is_empty(), "{} leaking pixels", leaks.len());
    let s = speckles(&film, WHOLE, 24);
    assert!(s.len() <= 2, "speckles: {s:?}");
}

#[test]
fn points_on_the_lights_edge_and_corner_are_finite_and_continuous() {
    let desc = load("light-edge.json");
    let film = render(&desc, "light edge");
    // The centre pixel's ray meets the room's corner, which is the light's
    // corner; its colour is finite (checked) and the wall next to it lit.
    let (cx, cy) = (film.width / 2, film.height / 2);
    assert!(film.get(cx - 3, cy + 3).max_element() > 0.05);
    // Shrinking the light by 1e-9 (so that no wall point lies on its edge)
    // or growing it changes the image by rounding only. Left out: the centre
    // pixel, whose ray meets three walls and the light at one point — when
    // the light is shrunk it hits the mirror wall there, and its reflected
    // ray, starting outside a neighbouring wall by rounding, escapes (a
    // known limit: see the report).
    assert_limit("light-edge.json", &[1e-9, 1e-6], &[(cx, cy)], |d, delta| {
        let s = d.light.edge_u[0].abs() * delta;
        d.light.corner[0] += s;
        d.light.corner[2] += s;
        d.light.edge_u[0] -= 2.0 * s;
        d.light.edge_v[2] -= 2.0 * s;
    });
}

/// Contact scenes: no isolated dots along the contact lines, and the same
/// image when the touching object is sunk a hair into what it touches.
/// Corners of silhouettes and staircase edges also differ from their
/// neighbourhood's median; they appear in both renders, so only the dots
/// that the exact contact adds count.
fn assert_clean_contact(name: &str, sink: impl Fn(&mut SceneDesc)) {
    let desc = load(name);
    let film = render(&desc, name);
    let mut sunk = desc.clone();
    sink(&mut sunk);
    let other = render(&sunk, &format!("{name} sunk"));
    let near = speckles(&other, WHOLE, 24);
    let added: Vec<(u32, u32)> = speckles(&film, WHOLE, 24)
        .into_iter()
        .filter(|p| !near.contains(p))
        .collect();
    assert!(added.len() <= 1, "{name}: speckles at {added:?}");
    let c = compare(&film, &other).unwrap();
    assert!(
        c.rmse < 1.0 / 255.0,
        "{name}: rmse {:e} against sunk",
        c.rmse
    );
}

#[test]
fn the_speckle_counter_finds_acne() {
    let mut film = render(&load("box-on-floor.json"), "box on floor");
    let before = speckles(&film, WHOLE, 24);
    for (x, y) in [(40, 70), (90, 60), (120, 80)] {
        film.pixels[(y * film.width + x) as usize] = Vec3::ZERO;
    }
    let after = speckles(&film, WHOLE, 24);
    for p in [(40, 70), (90, 60), (120, 80)] {
        assert!(after.contains(&p) && !before.contains(&p), "{p:?}");
    }
}

#[test]
fn a_box_standing_on_the_floor_has_no_speckle() {
    use penumbra::render::scene_file::ObjectDesc;
    assert_clean_contact("box-on-floor.json", |d| {
        if let ObjectDesc::Box(b) = &mut d.objects[1] {
            b.min[1] = -1e-6;
        }
    });
}

#[test]
fn two_boxes_sharing_a_face_have_no_speckle() {
    use penumbra::render::scene_file::ObjectDesc;
    assert_clean_contact("shared-face.json", |d| {
        if let ObjectDesc::Box(b) = &mut d.objects[2] {
            b.min[0] = -1e-6;
        }
    });
}

#[test]
fn a_sphere_touching_a_wall_has_no_speckle() {
    use penumbra::render::scene_file::ObjectDesc;
    assert_clean_contact("sphere-touching-wall.json", |d| {
        if let ObjectDesc::Sphere(s) = &mut d.objects[2] {
            s.radius += 1e-6;
        }
    });
}

#[test]
fn extreme_shininess_orders_the_highlights() {
    // With no reflections, each pixel's specular factor is an average of
    // c^shininess over its light points with c = N·H in [0, 1]: it falls as
    // the shininess grows, and the other terms do not depend on it.
    let low = load("shininess-low.json");
    let high = load("shininess-high.json");
    let mut mid = low.clone();
    for m in mid.materials.values_mut() {
        m.shininess = 20.0;
    }
    let lo = render(&low, "shininess 1e-3");
    let md = render(&mid, "shininess 20");
    let hi = render(&high, "shininess 1e4");
    let no_spec = render(&with_terms(&low, 1.0, 1.0, 0.0), "no specular");
    let tol = 1e-5;
    for i in 0..lo.pixels.len() {
        let (a, b, c, d) = (lo.pixels[i], md.pixels[i], hi.pixels[i], no_spec.pixels[i]);
        assert!(
            a.cmpge(b - tol).all() && b.cmpge(c - tol).all() && c.cmpge(d - tol).all(),
            "pixel {i}: 1e-3 {a}, 20 {b}, 1e4 {c}, none {d}"
        );
    }
    // At shininess 1e-3, c^s is within 1% of 1 for any c > 1e-4: where a
    // surface sees the whole light the specular term is its ks times the
    // light's specular (1). The largest ks is the mirror sphere's 0.9.
    let spec = |f: &Film, i: usize| (f.pixels[i] - no_spec.pixels[i]).max_element();
    let max_low = (0..lo.pixels.len())
        .map(|i| spec(&lo, i))
        .fold(0.0, f32::max);
    assert!(
        (max_low - 0.9).abs() < 0.01,
        "largest specular at shininess 1e-3: {max_low}"
    );
    // At shininess 1e4 a highlight needs N·H within about 1.5° of 1: few
    // pixels have any.
    let lit = (0..hi.pixels.len())
        .filter(|&i| spec(&hi, i) > 1e-3)
        .count();
    assert!(
        lit < hi.pixels.len() / 50,
        "{lit} pixels with a 1e4 highlight"
    );
}

#[test]
fn two_parallel_mirrors_alternate_for_sixteen_bounces() {
    // Ambient-only materials, reflectivity 1, no light reaching the gap:
    // every camera ray meets mirror A, then B, then A ... and the pixel is
    // the sum of the ambient colours of the surfaces met. A ray that
    // re-hit its own mirror or escaped would break the count.
    let desc = load("parallel-mirrors.json");
    let a = desc.materials["a"].ambient[0] as f32;
    let b = desc.materials["b"].ambient[1] as f32;
    for depth in [1u32, 2, 5, 15, 16] {
        let mut d = desc.clone();
        d.render.max_depth = depth;
        let film = render(&d, &format!("mirrors, depth {depth}"));
        let want = Vec3::new(a * depth.div_ceil(2) as f32, b * (depth / 2) as f32, 0.0);
        for (i, p) in film.pixels.iter().enumerate() {
            assert!(
                (*p - want).abs().max_element() < 1e-5,
                "depth {depth}, pixel {i}: {p}, expected {want}"
            );
        }
    }
}

#[test]
fn term_multipliers_zero_and_ten_are_exact() {
    // The pixel is L + t·X for terms (t, t, t): L what the light contributes
    // when seen (directly or in a mirror), X the Phong terms.
    let zero = load("terms-zero.json");
    let ten = load("terms-ten.json");
    let one = with_terms(&zero, 1.0, 1.0, 1.0);
    let l = render(&zero, "terms 0");
    let x1 = render(&one, "terms 1");
    let x10 = render(&ten, "terms 10");
    let light = Vec3::from_array(zero.light.diffuse.map(|v| v as f32));
    let mut seen = 0;
    for i in 0..l.pixels.len() {
        let (l, x1, x10) = (l.pixels[i], x1.pixels[i], x10.pixels[i]);
        // Terms 0: only the light itself remains, never brighter than it.
        assert!(l.cmple(light + 1e-6).all(), "pixel {i}: {l}");
        seen += (l != Vec3::ZERO) as usize;
        let want = l + (x1 - l) * 10.0;
        assert!(
            (x10 - want).abs().max_element() <= 1e-5 * (1.0 + want.max_element()),
            "pixel {i}: terms 10 {x10}, expected {want}"
        );
    }
    assert!(seen > 0, "the light is in view");
    // Superposition: each term alone adds up to all three.
    let parts = [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
        .map(|(a, d, s)| render(&with_terms(&zero, a, d, s), "one term"));
    for i in 0..l.pixels.len() {
        let sum = parts[0].pixels[i] + parts[1].pixels[i] + parts[2].pixels[i] - l.pixels[i] * 2.0;
        assert!(
            (sum - x1.pixels[i]).abs().max_element() < 1e-5,
            "pixel {i}: sum of terms {sum} vs {}",
            x1.pixels[i]
        );
    }
}

/// The image seen through a light-only mask: pixels where the light is
/// seen (directly or in a mirror) in either render are left out.
fn light_free(a: &SceneDesc, b: &SceneDesc) -> Vec<bool> {
    let la = render(&with_terms(a, 0.0, 0.0, 0.0), "light only");
    let lb = render(&with_terms(b, 0.0, 0.0, 0.0), "light only");
    (0..la.pixels.len())
        .map(|i| la.pixels[i] == Vec3::ZERO && lb.pixels[i] == Vec3::ZERO)
        .collect()
}

fn point_light(desc: &SceneDesc) -> SceneDesc {
    // One grid ray goes to the light's centre: a point light there.
    let mut d = desc.clone();
    d.render.shadow_rays = 1;
    d.render.sampling = penumbra::render::Sampling::Grid;
    d
}

#[test]
fn one_shadow_ray_is_a_point_light_at_the_centre() {
    let one = load("shadow-rays-1.json");
    let mut tiny = load("tiny-light.json");
    tiny.render = one.render.clone();
    tiny.camera = one.camera.clone();
    let a = render(&one, "1 shadow ray");
    let b = render(&tiny, "tiny light, 1 shadow ray");
    let mask = light_free(&one, &tiny);
    let off: Vec<usize> = (0..a.pixels.len())
        .filter(|&i| mask[i] && levels(a.pixels[i], b.pixels[i]) > 1)
        .collect();
    assert!(
        off.len() <= 3,
        "{} pixels differ between one ray to a 2×2 light and to a 1e-6 light: {:?}",
        off.len(),
        &off[..off.len().min(8)]
    );
}

#[test]
fn a_tiny_light_converges_to_a_hard_shadow() {
    let tiny = load("tiny-light.json");
    let soft = render(&tiny, "tiny light");
    let hard = render(&point_light(&tiny), "tiny light, one ray");
    let c = compare(&soft, &hard).unwrap();
    let off = (0..soft.pixels.len())
        .filter(|&i| levels(soft.pixels[i], hard.pixels[i]) > 2)
        .count();
    assert!(c.rmse < 0.25 / 255.0, "rmse {:e}", c.rmse);
    assert!(off <= 3, "{off} pixels differ by more than 2 levels");
    // And it is hard: the big light's soft shadow differs from it.
    let mut big = tiny.clone();
    big.light = load("room.json").light;
    let big = render(&big, "2×2 light");
    let off_big = (0..soft.pixels.len())
        .filter(|&i| levels(big.pixels[i], hard.pixels[i]) > 2)
        .count();
    assert!(off_big > 100, "the 2×2 light's penumbrae: {off_big} pixels");
}

#[test]
fn shadow_rays_4096_converge() {
    let full = load("shadow-rays-4096.json");
    let reference = render(&full, "4096 shadow rays");
    let rmse_at = |n: u32| {
        let mut d = full.clone();
        d.render.shadow_rays = n;
        compare(&reference, &render(&d, &format!("{n} shadow rays")))
            .unwrap()
            .rmse
    };
    let errors = [4, 16, 256, 1024].map(rmse_at);
    assert!(errors[3] < 0.5 / 255.0, "rmse at 1024 vs 4096: {errors:?}");
    assert!(
        errors[0] > errors[1] && errors[1] > errors[2] && errors[2] > errors[3],
        "errors do not fall with more rays: {errors:?}"
    );
}

#[test]
fn a_light_larger_than_the_room_is_cut_by_the_walls() {
    // A 20×20 light over a closed 10×10 room, with an 8×8 grid: exactly the
    // 4×4 points inside the room are the grid of a 10×10 light of 16 rays,
    // the others are behind the walls. The Phong terms are averages over
    // all points, so they are a quarter of the room-sized light's.
    let huge = load("huge-light.json");
    let mut room = huge.clone();
    room.light.corner = [-5.0, 7.99, -5.0];
    room.light.edge_u = [10.0, 0.0, 0.0];
    room.light.edge_v = [0.0, 0.0, 10.0];
    room.render.shadow_rays = 16;
    let h = render(&huge, "huge light");
    let r = render(&room, "room-sized light");
    let h0 = render(&with_terms(&huge, 1.0, 0.0, 0.0), "huge light, ambient");
    let r0 = render(&with_terms(&room, 1.0, 0.0, 0.0), "room light, ambient");
    let mut lit = 0;
    for i in 0..h.pixels.len() {
        let xh = h.pixels[i] - h0.pixels[i];
        let xr = r.pixels[i] - r0.pixels[i];
        assert!(
            (xh - xr * 0.25).abs().max_element() < 1e-4,
            "pixel {i}: huge light adds {xh}, room-sized light {xr}"
        );
        lit += (xr.max_element() > 0.05) as usize;
    }
    assert!(lit > h.pixels.len() / 2, "{lit} lit pixels");
}
