//! The `exact` area-light model against symmetry and against an
//! independent integration by ray casting.
//!
//! The reference integrates over the light's (a, b) square: in b by
//! adaptive Simpson, and along each row in a over the visible intervals,
//! whose ends are found by bisecting the f64 ray test of the primitives
//! (`Shape::intersect`, blocked for t in (0, RAY_END)) between 1024 points
//! of the row, each interval by 16-point Gauss–Legendre. It shares no code
//! with the model (no projection, no polygon, no edge sum), and the row
//! integrals are exact to rounding, so it is good to ~1e-10.

use glam::DVec3;
use penumbra::render::exact::{CircleFit, ExactFactors, ExactPoint, ExactScratch, exact_factors};
use penumbra::render::geometry::{Ray, Shape};
use penumbra::render::{AreaLightModel, Loaded, SEED_ROOM_JSON, Sampling, SceneDesc};

/// The sampled model's shadow-ray end (shadow/mod.rs).
const RAY_END: f64 = 1.0 - 1e-4;

/// A scene with the seed room's 2×2 light at height 8 facing down and the
/// given objects (JSON), materials "m".
fn scene(objects: &str) -> Loaded {
    scene_with_light(objects, "[-1, 8, -1]", "[2, 0, 0]", "[0, 0, 2]")
}

fn scene_with_light(objects: &str, corner: &str, u: &str, v: &str) -> Loaded {
    let json = format!(
        r#"{{ "format": 1,
  "camera": {{ "position": [0, 4, -14], "look_at": [0, 3.5, 0], "up": [0, 1, 0], "fov_y_deg": 36, "width": 32, "height": 18 }},
  "render": {{ "max_depth": 1, "area_light_model": "exact" }},
  "light": {{ "corner": {corner}, "edge_u": {u}, "edge_v": {v},
    "ambient": [0, 0, 0], "diffuse": [1, 1, 1], "specular": [1, 1, 1] }},
  "materials": {{ "m": {{ "ambient": [0, 0, 0], "diffuse": [1, 1, 1], "specular": [1, 1, 1], "shininess": 20, "reflectivity": 0 }} }},
  "objects": [ {objects} ] }}"#
    );
    Loaded::from_json(&json).expect("test scene")
}

fn point(p: [f64; 3], n: [f64; 3], v: [f64; 3], shininess: f64) -> ExactPoint {
    let n = DVec3::from(n).normalize();
    ExactPoint {
        shadow_point: p.into(),
        normal: n,
        geometric: n,
        view: DVec3::from(v).normalize(),
        shininess,
        object: u32::MAX,
        inside: false,
        shadows: true,
    }
}

fn exact(l: &Loaded, p: &ExactPoint, fit: CircleFit) -> ExactFactors {
    exact_factors(&l.scene, p, true, fit, &mut ExactScratch::default()).expect("exact, no fallback")
}

/// Whether the shadow ray from p to y arrives (the sampled model's test in
/// f64: in front of the geometric normal, no object at t in (0, RAY_END)).
fn arrives(l: &Loaded, p: &ExactPoint, y: DVec3) -> bool {
    let d = y - p.shadow_point;
    if p.geometric.dot(d) <= 0.0 {
        return false;
    }
    // Unit directions: the sphere's test assumes them.
    let len = d.length();
    let ray = Ray::new(p.shadow_point, d / len);
    !l.scene.objects.iter().any(|o| match &o.shape {
        // Planes: the ray's ends on opposite sides (the sampled test).
        Shape::Plane(pl) => {
            let s = pl.signed_distance(p.shadow_point);
            s * pl.signed_distance(p.shadow_point + d * RAY_END) < 0.0
        }
        s => s.intersect(&ray, RAY_END * len).is_some(),
    })
}

const GL16: [(f64, f64); 8] = [
    (0.095_012_509_837_637_44, 0.189_450_610_455_068_5),
    (0.281_603_550_779_258_9, 0.182_603_415_044_923_6),
    (0.458_016_777_657_227_4, 0.169_156_519_395_002_5),
    (0.617_876_244_402_643_7, 0.149_595_988_816_576_7),
    (0.755_404_408_355_003, 0.124_628_971_255_533_9),
    (0.865_631_202_387_831_7, 0.095_158_511_682_492_8),
    (0.944_575_023_073_232_6, 0.062_253_523_938_647_9),
    (0.989_400_934_991_649_9, 0.027_152_459_411_754_1),
];

/// ∫_lo^hi g by 16-point Gauss–Legendre.
fn gauss(lo: f64, hi: f64, g: &impl Fn(f64) -> f64) -> f64 {
    let (m, r) = ((lo + hi) * 0.5, (hi - lo) * 0.5);
    GL16.iter()
        .map(|&(x, w)| w * (g(m - r * x) + g(m + r * x)))
        .sum::<f64>()
        * r
}

/// The independent reference: (diffuse, specular) averages over the light
/// of visibility × max(0, N·L) and × max(0, N·H)^s.
fn reference(l: &Loaded, p: &ExactPoint) -> (f64, f64) {
    let light = &l.scene.light.shape;
    let at = |a: f64, b: f64| light.corner + light.edge_u * a + light.edge_v * b;
    let terms = |a: f64, b: f64| {
        let d = (at(a, b) - p.shadow_point).normalize();
        let h = (d + p.view).normalize_or_zero();
        let s = p.normal.dot(h).max(0.0).powf(p.shininess);
        (p.normal.dot(d).max(0.0), s)
    };
    let row = |b: f64| -> (f64, f64) {
        const N: usize = 1024;
        let vis = |a: f64| arrives(l, p, at(a, b));
        let mut ends = vec![0.0];
        let mut prev = vis(0.0);
        let mut prev_a = 0.0;
        for i in 1..=N {
            let a = i as f64 / N as f64;
            let now = vis(a);
            if now != prev {
                let (mut lo, mut hi) = (prev_a, a);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if vis(mid) == prev {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                ends.push(0.5 * (lo + hi));
            }
            prev = now;
            prev_a = a;
        }
        ends.push(1.0);
        let (mut d, mut s) = (0.0, 0.0);
        for w in ends.windows(2) {
            if vis(0.5 * (w[0] + w[1])) {
                d += gauss(w[0], w[1], &|a| terms(a, b).0);
                s += gauss(w[0], w[1], &|a| terms(a, b).1);
            }
        }
        (d, s)
    };
    // Adaptive Simpson over b, on both terms at once.
    #[allow(clippy::too_many_arguments)]
    fn simpson(
        row: &impl Fn(f64) -> (f64, f64),
        lo: f64,
        hi: f64,
        fl: (f64, f64),
        fm: (f64, f64),
        fh: (f64, f64),
        whole: (f64, f64),
        depth: u32,
    ) -> (f64, f64) {
        let m = 0.5 * (lo + hi);
        let (lm, hm) = (0.5 * (lo + m), 0.5 * (m + hi));
        let (flm, fhm) = (row(lm), row(hm));
        let w = (hi - lo) / 12.0;
        let left = (
            w * (fl.0 + 4.0 * flm.0 + fm.0),
            w * (fl.1 + 4.0 * flm.1 + fm.1),
        );
        let right = (
            w * (fm.0 + 4.0 * fhm.0 + fh.0),
            w * (fm.1 + 4.0 * fhm.1 + fh.1),
        );
        let err = (left.0 + right.0 - whole.0)
            .abs()
            .max((left.1 + right.1 - whole.1).abs());
        if depth >= 18 || (depth >= 4 && err < 1e-11) {
            return (left.0 + right.0, left.1 + right.1);
        }
        let a = simpson(row, lo, m, fl, flm, fm, left, depth + 1);
        let b = simpson(row, m, hi, fm, fhm, fh, right, depth + 1);
        (a.0 + b.0, a.1 + b.1)
    }
    let (f0, f1, fm) = (row(0.0), row(1.0), row(0.5));
    let whole = (
        (f0.0 + 4.0 * fm.0 + f1.0) / 6.0,
        (f0.1 + 4.0 * fm.1 + f1.1) / 6.0,
    );
    simpson(&row, 0.0, 1.0, f0, fm, f1, whole, 0)
}

/// The model against the reference at `p`: diffuse within `tol_d`,
/// specular within `tol_s` (absolute, the factors lie in [0, 1]).
fn check(l: &Loaded, p: &ExactPoint, what: &str, tol_d: f64, tol_s: f64) -> ExactFactors {
    let got = exact(l, p, CircleFit::SameArea);
    let (d, s) = reference(l, p);
    eprintln!(
        "{what}: diffuse {:.12} vs {d:.12} ({:.1e}), specular {:.10} vs {s:.10} ({:.1e}), {} pieces, {} cells",
        got.diffuse,
        (got.diffuse - d).abs(),
        got.specular,
        (got.specular - s).abs(),
        got.pieces,
        got.cubature.cells
    );
    assert!(
        (got.diffuse - d).abs() <= tol_d,
        "{what}: diffuse {} vs {d}",
        got.diffuse
    );
    assert!(
        (got.specular - s).abs() <= tol_s,
        "{what}: specular {} vs {s}",
        got.specular
    );
    got
}

const BOX: &str = r#"{ "type": "box", "min": [-0.5, 3, -0.6], "max": [0.7, 4, 0.4], "rotate_y_deg": 20, "material": "m" }"#;

#[test]
fn half_occlusion_by_a_box_is_exactly_half() {
    // A slab over x > 0 between the floor point at the origin and the
    // light hides exactly the light's x > 0 half; with the normal and the
    // view straight up both integrands are even in x.
    let open = scene("");
    let half = scene(r#"{ "type": "box", "min": [0, 3, -5], "max": [5, 4, 5], "material": "m" }"#);
    let p = point([0.0; 3], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0], 20.0);
    let whole = exact(&open, &p, CircleFit::SameArea);
    let got = exact(&half, &p, CircleFit::SameArea);
    assert!(whole.diffuse > 0.5);
    assert!(
        (got.diffuse - 0.5 * whole.diffuse).abs() <= 1e-14,
        "{} vs {}",
        got.diffuse,
        whole.diffuse
    );
    assert!(
        (got.specular - 0.5 * whole.specular).abs() <= 1e-6,
        "{} vs {}",
        got.specular,
        whole.specular
    );
    // And the independent integration agrees.
    check(&half, &p, "half box", 1e-9, 1e-6);
}

#[test]
fn box_and_rect_penumbrae_match_an_independent_integration() {
    let l = scene(&format!(
        r#"{BOX}, {{ "type": "rect", "corner": [1.0, 5, -1], "edge_u": [1.2, 0.2, 0], "edge_v": [0, 0.1, 1.5], "material": "m" }}"#
    ));
    // Floor and wall points in the penumbrae of the box and the rect.
    for (i, (p, n)) in [
        ([0.4, 0.0, 0.3], [0.0, 1.0, 0.0]),
        ([-0.9, 0.0, -0.2], [0.0, 1.0, 0.0]),
        ([1.9, 0.0, 0.4], [0.0, 1.0, 0.0]),
        ([2.6, 0.0, -0.5], [0.0, 1.0, 0.0]),
        ([-3.0, 2.0, 0.1], [1.0, 0.0, 0.0]),
    ]
    .into_iter()
    .enumerate()
    {
        let pt = point(p, n, [0.1, 1.0, -0.7], 20.0);
        check(&l, &pt, &format!("penumbra {i}"), 1e-6, 1e-5);
    }
}

#[test]
fn nested_and_overlapping_occluders() {
    let p = point([0.3, 0.0, 0.1], [0.0, 1.0, 0.0], [0.2, 1.0, -0.6], 20.0);
    // A small box inside the shadow of a larger one changes nothing.
    let big =
        r#"{ "type": "box", "min": [-0.4, 5, -0.5], "max": [1.0, 5.5, 0.3], "material": "m" }"#;
    let small =
        r#"{ "type": "box", "min": [0.25, 2.0, 0.05], "max": [0.35, 2.1, 0.15], "material": "m" }"#;
    let one = exact(&scene(big), &p, CircleFit::SameArea);
    let both = exact(&scene(&format!("{big}, {small}")), &p, CircleFit::SameArea);
    assert!(
        (one.diffuse - both.diffuse).abs() < 1e-13,
        "{} {}",
        one.diffuse,
        both.diffuse
    );
    assert!((one.specular - both.specular).abs() < 1e-6);
    // Overlapping shadows: a box, a rect and a triangle sharing parts of
    // the light, against the reference (it sees the union by itself).
    let l = scene(&format!(
        r#"{big}, {{ "type": "rect", "corner": [0.3, 4, -0.9], "edge_u": [1.0, 0, 0], "edge_v": [0, 0, 0.9], "material": "m" }},
           {{ "type": "triangle", "vertices": [[-0.6, 6, 0.1], [0.5, 6, 0.9], [0.4, 6.2, -0.2]], "material": "m" }}"#
    ));
    let got = check(&l, &p, "overlapping", 1e-6, 1e-5);
    assert!(got.pieces >= 3, "a penumbra: {} pieces", got.pieces);
}

#[test]
fn sphere_penumbra_matches_a_dense_integration_and_is_bracketed() {
    let l =
        scene(r#"{ "type": "sphere", "center": [0.4, 4, 0.2], "radius": 0.8, "material": "m" }"#);
    for (i, p) in [[1.4, 0.0, 0.2], [0.9, 0.0, -0.8], [-0.2, 0.0, 0.9]]
        .into_iter()
        .enumerate()
    {
        let pt = point(p, [0.0, 1.0, 0.0], [0.0, 1.0, 0.0], 20.0);
        let got = check(&l, &pt, &format!("sphere {i}"), 2e-6, 1e-5);
        let inner = exact(&l, &pt, CircleFit::Inscribed);
        let outer = exact(&l, &pt, CircleFit::Circumscribed);
        let (d, _) = reference(&l, &pt);
        // The inscribed polygon hides less, the circumscribed more.
        eprintln!(
            "sphere {i}: bracket [{:.10}, {:.10}] width {:.1e}, same-area error {:.1e}",
            outer.diffuse,
            inner.diffuse,
            inner.diffuse - outer.diffuse,
            (got.diffuse - d).abs()
        );
        assert!(outer.diffuse <= d + 1e-12 && d <= inner.diffuse + 1e-12);
        assert!(inner.diffuse - outer.diffuse > 0.0);
        assert!(outer.diffuse <= got.diffuse && got.diffuse <= inner.diffuse);
    }
}

#[test]
fn occluder_crossing_the_lights_plane() {
    // A box through the light's plane (y = 8) over part of the light, and
    // a rect standing through it.
    let l = scene(
        r#"{ "type": "box", "min": [0.2, 6, -2], "max": [3, 9, 0.3], "material": "m" },
           { "type": "rect", "corner": [-0.5, 7, -2], "edge_u": [0, 0, 4], "edge_v": [0, 2, 0], "material": "m" }"#,
    );
    for (i, p) in [[0.5, 0.0, 0.0], [-1.0, 2.0, 0.5], [0.1, 7.5, -0.4]]
        .into_iter()
        .enumerate()
    {
        let pt = point(p, [0.0, 1.0, 0.0], [0.3, 1.0, 0.0], 20.0);
        check(&l, &pt, &format!("crossing {i}"), 1e-6, 1e-5);
    }
}

#[test]
fn open_points_whose_surface_or_horizon_cuts_the_light() {
    // Nothing between the points and the light: the whole light where it
    // lies in front of the surface and above the shading horizon, else the
    // part that does, each against the independent integration.
    let l = scene("");
    let whole = check(
        &l,
        &point([0.3, 0.0, -0.2], [0.0, 1.0, 0.0], [0.2, 1.0, -0.6], 20.0),
        "open, whole light",
        1e-9,
        1e-5,
    );
    assert_eq!(whole.pieces, 1);
    // The surface's plane (x ≤ 0.7 on the light) cuts the light.
    let front = check(
        &l,
        &point([0.5, 7.0, 0.0], [-1.0, 0.2, 0.0], [-1.0, 0.5, 0.0], 20.0),
        "open, surface through the light",
        1e-7,
        1e-5,
    );
    assert!(front.diffuse > 0.0 && front.pieces == 1);
    // The geometric normal sees the whole light; the shading normal's
    // horizon (x ≤ 0.65 on the light) cuts it. The reference's rows do not
    // split at the horizon's kink (2e-5 off), so its diffuse factor is
    // checked against the same point with the surface along the horizon,
    // whose light is the same part (the specular factor, which the horizon
    // does not clip, against the reference).
    let mut p = point([0.5, 7.0, 0.0], [-1.0, 0.15, 0.0], [-1.0, 0.5, 0.0], 20.0);
    let along = check(&l, &p, "open, surface along the horizon", 1e-7, 1e-5);
    p.geometric = DVec3::Y;
    let horizon = check(&l, &p, "open, horizon through the light", 1e-4, 1e-5);
    assert!(
        (horizon.diffuse - along.diffuse).abs() <= 1e-12 && horizon.diffuse > 0.0,
        "{} vs {}",
        horizon.diffuse,
        along.diffuse
    );
    assert!(horizon.specular > along.specular);
    // And the other way round: the shading normal sees the whole light,
    // the surface's plane hides part of it.
    let mut p = point([0.5, 7.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.5, 0.0], 20.0);
    p.geometric = DVec3::new(-1.0, 0.2, 0.0).normalize();
    let behind = check(&l, &p, "open, surface through, horizon clear", 1e-7, 1e-5);
    assert!(behind.diffuse < 0.9 * whole_light_diffuse(&l, &p));
}

/// The diffuse factor of `p` were its surface to face the light squarely
/// (the shading normal's whole-light value).
fn whole_light_diffuse(l: &Loaded, p: &ExactPoint) -> f64 {
    let mut q = *p;
    q.geometric = q.normal;
    exact(l, &q, CircleFit::SameArea).diffuse
}

#[test]
fn light_seen_edge_on() {
    // Points beside the light nearly in its plane, facing it, with a box
    // in the way of part of it.
    let l = scene(
        r#"{ "type": "box", "min": [1.5, 7.9, -0.3], "max": [1.7, 8.5, 0.2], "material": "m" }"#,
    );
    let mut last: Option<f64> = None;
    for h in [1e-2, 1e-4, 1e-7] {
        let pt = point(
            [3.0, 8.0 - h, 0.1],
            [-1.0, 0.0, 0.0],
            [-1.0, -0.2, 0.0],
            20.0,
        );
        let got = check(&l, &pt, &format!("edge-on {h:e}"), 1e-7, 1e-5);
        // The factor has no emitter cosine: it stays finite and continuous
        // as the point comes down to the plane.
        if let Some(prev) = last {
            assert!(
                (got.diffuse - prev).abs() < 1e-2,
                "{} vs {prev}",
                got.diffuse
            );
        }
        last = Some(got.diffuse);
    }
    // In the plane itself: no light, no NaN.
    let pt = point([3.0, 8.0, 0.1], [-1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], 20.0);
    let got = exact(&l, &pt, CircleFit::SameArea);
    assert_eq!((got.diffuse, got.specular), (0.0, 0.0));
}

#[test]
fn sampled_with_many_rays_converges_to_exact() {
    // The seed room, small: the 4096-ray stratified image and the exact one
    // agree to the former's noise, and far better than 64 grid rays do.
    let mut d = SceneDesc::from_json(SEED_ROOM_JSON).unwrap();
    d.camera.width = 96;
    d.camera.height = 54;
    d.render.max_depth = 2;
    let render = |model: AreaLightModel, rays: u32, sampling: Sampling| {
        let mut d = d.clone();
        d.render.area_light_model = model;
        d.render.shadow_rays = rays;
        d.render.sampling = sampling;
        Loaded::new(&d).unwrap().render_image()
    };
    let exact = render(AreaLightModel::Exact, 1, Sampling::Grid);
    let fine = render(AreaLightModel::Sampled, 4096, Sampling::Stratified);
    let grid = render(AreaLightModel::Sampled, 64, Sampling::Grid);
    let rmse = |a: &penumbra::render::Film, b: &penumbra::render::Film| {
        penumbra::render::compare::compare(a, b).unwrap().rmse
    };
    let (e_fine, e_grid) = (rmse(&exact, &fine), rmse(&exact, &grid));
    eprintln!("exact vs 4096 stratified {e_fine:.2e}, vs 64 grid {e_grid:.2e}");
    assert!(e_fine < 3e-4, "{e_fine}");
    assert!(e_fine * 4.0 < e_grid, "{e_fine} vs {e_grid}");
    assert!(exact.pixels.iter().all(|p| p.is_finite()));
}

#[test]
fn a_shadow_clipped_at_the_lights_edge_cuts_nothing_else() {
    // A floor point of the seed room (pixel 415, 510 at 960×540) right
    // beside the sand box: the box's shadow, clipped at the light's edge,
    // got two vertices a rounding apart, and the edge between them once cut
    // the light along a random line (the exact image was 0.05 too bright).
    let l = Loaded::from_json(SEED_ROOM_JSON).unwrap();
    let mut p = point(
        [0.955536019597787, 0.0, -1.8245261112150182],
        [0.0, 1.0, 0.0],
        [-0.0646, 0.2817, 0.9573],
        20.0,
    );
    p.object = 0;
    check(&l, &p, "beside the sand box", 1e-9, 1e-6);
}

#[test]
fn a_light_below_the_exact_size_falls_back() {
    let l = scene_with_light("", "[-5e-5, 8, -5e-5]", "[1e-4, 0, 0]", "[0, 0, 1e-4]");
    let p = point([0.3, 0.0, 0.2], [0.0, 1.0, 0.0], [0.1, 1.0, -0.7], 20.0);
    let r = exact_factors(
        &l.scene,
        &p,
        true,
        CircleFit::SameArea,
        &mut ExactScratch::default(),
    );
    assert_eq!(r.unwrap_err(), penumbra::render::exact::Fallback::TinyLight);
}

/// The diffuse factor of a sphere's penumbra is integrated along its
/// conic shadow: within 1e-6 relative of the dense integration (the
/// 128-gon of the same area alone is off by ~2e-5), for one sphere, a
/// sphere whose shadow the light's edge cuts, a sphere overlapping a box's
/// shadow, and two spheres side by side.
#[test]
fn sphere_diffuse_follows_the_conic_within_1e_6_relative() {
    let one = r#"{ "type": "sphere", "center": [0.4, 4, 0.2], "radius": 0.8, "material": "m" }"#;
    let edge = r#"{ "type": "sphere", "center": [1.1, 5, -0.3], "radius": 0.5, "material": "m" }"#;
    let boxed = format!(
        r#"{one}, {{ "type": "box", "min": [-0.9, 3, -0.5], "max": [0.3, 3.5, 0.4], "material": "m" }}"#
    );
    let pair = r#"{ "type": "sphere", "center": [-0.7, 5, 0.0], "radius": 0.35, "material": "m" },
                  { "type": "sphere", "center": [0.7, 5, 0.1], "radius": 0.35, "material": "m" }"#;
    let cases: [(&str, &str, [[f64; 3]; 3]); 4] = [
        (
            "one",
            one,
            [[1.4, 0.0, 0.2], [0.9, 0.0, -0.8], [-0.2, 0.0, 0.9]],
        ),
        (
            "edge",
            edge,
            [[1.6, 0.0, -0.2], [2.2, 0.5, 0.4], [0.9, 0.0, -1.0]],
        ),
        (
            "boxed",
            &boxed,
            [[0.2, 0.0, 0.3], [-1.6, 0.0, 0.5], [1.0, 0.0, -0.9]],
        ),
        (
            "pair",
            pair,
            [[0.0, 0.0, 0.0], [-1.2, 0.0, 0.3], [1.3, 0.0, -0.2]],
        ),
    ];
    for (name, objects, points) in cases {
        let l = scene(objects);
        for (i, p) in points.into_iter().enumerate() {
            let pt = point(p, [0.0, 1.0, 0.0], [0.0, 1.0, 0.0], 20.0);
            let got = exact(&l, &pt, CircleFit::SameArea);
            let (d, _) = reference(&l, &pt);
            let relative = (got.diffuse - d).abs() / d;
            eprintln!(
                "{name} {i}: diffuse {:.12} vs {d:.12}, relative {relative:.1e}, {} pieces",
                got.diffuse, got.pieces
            );
            assert!(d > 0.01 && got.pieces > 0, "{name} {i}: a penumbra");
            assert!(relative <= 1e-6, "{name} {i}: {} vs {d}", got.diffuse);
        }
    }
}

/// Two spheres whose shadow cones overlap keep the polygons' diffuse value
/// (the conics' parts would be subtracted twice): still within the 128-gon's
/// error of the dense integration.
#[test]
fn overlapping_sphere_shadows_keep_the_polygons_value() {
    let l = scene(
        r#"{ "type": "sphere", "center": [-0.2, 5, 0.0], "radius": 0.45, "material": "m" },
           { "type": "sphere", "center": [0.4, 4.6, 0.1], "radius": 0.4, "material": "m" }"#,
    );
    for (i, p) in [[0.0, 0.0, 0.0], [1.2, 0.0, 0.3]].into_iter().enumerate() {
        let pt = point(p, [0.0, 1.0, 0.0], [0.0, 1.0, 0.0], 20.0);
        let got = check(&l, &pt, &format!("overlapping spheres {i}"), 2e-6, 1e-5);
        assert!(got.pieces > 0);
    }
}
