//! Property tests of the geometry, with coordinates spread log-uniformly
//! over 1e-4…1e6 (as pbrt's "reintersect" tests do): reported hits lie on
//! their surface, rays spawned from a hit never meet that surface again at
//! t ≈ 0, boxes are watertight at their edges and corners, and the light's
//! (u, v) coordinates round-trip, also for very thin lights.
//!
//! Error bounds are in units of f64's epsilon times the magnitudes that
//! enter the computation: the primitives work in f64 and re-project their
//! hit points, so errors of a few hundred ulps of the largest magnitude are
//! what they promise, whatever the scale.

use glam::{DVec2, DVec3};
use penumbra::render::geometry::{Cuboid, Parallelogram, Plane, Ray, Shape, Sphere, spawn_origin};
use proptest::prelude::*;

const EPS: f64 = f64::EPSILON;

/// ±10^e, e uniform in [-4, 6].
fn coord() -> impl Strategy<Value = f64> {
    (any::<bool>(), -4.0f64..6.0)
        .prop_map(|(neg, e)| if neg { -(10f64.powf(e)) } else { 10f64.powf(e) })
}

/// 10^e, e uniform in [lo, hi].
fn magnitude(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    (lo..hi).prop_map(|e| 10f64.powf(e))
}

fn point() -> impl Strategy<Value = DVec3> {
    (coord(), coord(), coord()).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

fn unit() -> impl Strategy<Value = DVec3> {
    (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0)
        .prop_filter("not too short", |(x, y, z)| x * x + y * y + z * z > 0.01)
        .prop_map(|(x, y, z)| DVec3::new(x, y, z).normalize())
}

/// A unit direction `w` with `w · n` at least `min` (n a unit vector).
fn leaving(n: DVec3, w: DVec3, min: f64) -> Option<DVec3> {
    let w = if w.dot(n) < 0.0 {
        w - 2.0 * w.dot(n) * n
    } else {
        w
    };
    (w.dot(n) >= min).then_some(w)
}

fn norm_max(v: DVec3) -> f64 {
    v.abs().max_element()
}

/// Two unit vectors perpendicular to `n` and to each other.
fn tangents(n: DVec3) -> (DVec3, DVec3) {
    let a = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let t = n.cross(a).normalize();
    (t, n.cross(t))
}

/// The ray from `origin` towards `target`.
fn aim(origin: DVec3, target: DVec3) -> Ray {
    Ray::new(origin, (target - origin).normalize())
}

/// Checks the spawn property for a hit of `ray` at `t` on `shape`: rays
/// leaving the surface (on the side the ray came from) from the spawned
/// origin, in any direction including grazing ones, never meet the surface
/// again — every primitive is convex or flat, so in exact arithmetic they
/// cannot.
fn assert_spawn_clean(shape: &Shape, ray: &Ray, t: f64, dir: DVec3, grazing: f64, scale: f64) {
    let s = shape.surface(ray, t);
    let n = if s.normal.dot(ray.dir) > 0.0 {
        -s.normal
    } else {
        s.normal
    };
    let Some(d) = leaving(n, dir, 0.0) else {
        return;
    };
    // Tilt towards the tangent plane: grazing = 1e-12 leaves at ~1e-12 rad.
    let (t1, _) = tangents(n);
    let d = (d * grazing + t1 * (1.0 - grazing)).normalize();
    let d = if d.dot(n) <= 0.0 {
        (d + n * 1e-15).normalize()
    } else {
        d
    };
    let o = spawn_origin(s.point, n, scale);
    let again = shape.intersect(&Ray::new(o, d), f64::INFINITY);
    assert!(
        again.is_none(),
        "re-hit at t = {again:?} from {o} (hit {}, normal {n}) along {d}",
        s.point
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn sphere_hits_lie_on_the_sphere(
        centre in point(), radius in magnitude(-4.0, 6.0), u in unit(), w in unit(),
        dist in magnitude(-4.0, 6.0), dir in unit(), grazing in prop_oneof![Just(1.0), Just(1e-3), Just(1e-9)],
    ) {
        let sphere = Sphere { centre, radius };
        let target = centre + u * radius;
        let Some(w) = leaving(u, w, 0.1) else { return Ok(()) };
        let origin = target + w * dist;
        let ray = aim(origin, target);
        let t = sphere.intersect(&ray, f64::INFINITY);
        prop_assert!(t.is_some(), "missed: {origin} → {target}");
        let t = t.unwrap();
        let m = norm_max(centre) + radius;
        let s = sphere.surface(&ray, t);
        let on = ((s.point - centre).length() - radius).abs();
        prop_assert!(on <= 8.0 * EPS * m, "off the surface by {on:e} (m {m:e})");
        // The reported t puts the ray's point on the surface too.
        let err = ((ray.at(t) - centre).length() - radius).abs();
        let bound = 64.0 * EPS * (m + norm_max(origin) + t);
        prop_assert!(err <= bound, "t off: {err:e} > {bound:e}");
        assert_spawn_clean(&Shape::Sphere(sphere), &ray, t, dir, grazing, m);
    }

    #[test]
    fn rays_spawned_inside_a_sphere_cross_it(
        centre in point(), radius in magnitude(-4.0, 6.0), u in unit(), off in unit(),
        k in 0.0f64..0.9, dir in unit(), cos in magnitude(-6.0, 0.0),
    ) {
        // From inside: the spawned ray goes inwards and must reach the far
        // side, a chord of length 2·r·cos away, not stop at t ≈ 0.
        let sphere = Sphere { centre, radius };
        let origin = centre + off * radius * k;
        let ray = aim(origin, centre + u * radius);
        let t = sphere.intersect(&ray, f64::INFINITY);
        prop_assert!(t.is_some());
        let t = t.unwrap();
        let s = sphere.surface(&ray, t);
        let n = -s.normal;
        let (t1, _) = tangents(n);
        let tangent = (dir - n * dir.dot(n)).try_normalize().unwrap_or(t1);
        let d = (n * cos + tangent * (1.0 - cos * cos).sqrt()).normalize();
        let o = spawn_origin(s.point, n, norm_max(centre) + radius);
        let chord = 2.0 * radius * d.dot(n);
        let again = sphere.intersect(&Ray::new(o, d), f64::INFINITY);
        let m = norm_max(centre) + radius;
        // The chord is exact up to the hit point's rounding (a few ulps of
        // m, over the sine of the angle the chord makes with the surface).
        prop_assume!(chord > 1e6 * EPS * m);
        prop_assert!(again.is_some_and(|t| t > 0.5 * chord), "chord {chord:e}, got {again:?}");
    }

    #[test]
    fn plane_hits_lie_on_the_plane(
        p in point(), normal in unit(), a in coord(), b in coord(), w in unit(),
        dist in magnitude(-4.0, 6.0), dir in unit(), grazing in prop_oneof![Just(1.0), Just(1e-3), Just(1e-9)],
    ) {
        let plane = Plane::new(p, normal);
        let (t1, t2) = tangents(plane.normal);
        let target = p + t1 * a + t2 * b;
        // Either side: planes are two-sided.
        let side = if w.dot(plane.normal) >= 0.0 { plane.normal } else { -plane.normal };
        let Some(w) = leaving(side, w, 0.1) else { return Ok(()) };
        let origin = target + w * dist;
        let ray = aim(origin, target);
        let t = plane.intersect(&ray, f64::INFINITY);
        prop_assert!(t.is_some(), "missed: {origin} → {target}");
        let t = t.unwrap();
        let s = plane.surface(&ray, t);
        let m = norm_max(p) + norm_max(s.point);
        let off = plane.signed_distance(s.point).abs();
        prop_assert!(off <= 8.0 * EPS * m, "off the plane by {off:e} (m {m:e})");
        let err = (s.point - target).length();
        let bound = 64.0 * EPS * (m + norm_max(origin) + dist / w.dot(side));
        prop_assert!(err <= bound, "hit {} vs aimed at {target}: {err:e} > {bound:e}", s.point);
        assert_spawn_clean(&Shape::Plane(plane.clone()), &ray, t, dir, grazing, m);
    }

    #[test]
    fn rect_hits_lie_on_the_rect(
        corner in point(), eu in unit(), ev in unit(), lu in magnitude(-4.0, 6.0), lv in magnitude(-4.0, 6.0),
        a in 0.01f64..0.99, b in 0.01f64..0.99, w in unit(), dist in magnitude(-4.0, 6.0),
        dir in unit(), grazing in prop_oneof![Just(1.0), Just(1e-3), Just(1e-9)],
    ) {
        prop_assume!(eu.cross(ev).length() > 0.1);
        let rect = Parallelogram::new(corner, eu * lu, ev * lv);
        let target = rect.point(DVec2::new(a, b));
        let side = if w.dot(rect.normal) >= 0.0 { rect.normal } else { -rect.normal };
        let Some(w) = leaving(side, w, 0.1) else { return Ok(()) };
        let origin = target + w * dist;
        let ray = aim(origin, target);
        let m = norm_max(corner) + lu + lv;
        // Aimed well inside (1% from the edges); the error of the aim is a
        // few ulps of the magnitudes involved.
        prop_assume!(64.0 * EPS * (m + norm_max(origin)) < 0.005 * lu.min(lv));
        let t = rect.intersect(&ray, f64::INFINITY);
        prop_assert!(t.is_some(), "missed: {origin} → {target}");
        let t = t.unwrap();
        let s = rect.surface(&ray, t);
        let off = rect.signed_distance(s.point).abs();
        prop_assert!(off <= 8.0 * EPS * (m + norm_max(s.point)), "off the plane by {off:e}");
        let uv = rect.uv(s.point);
        prop_assert!((uv - DVec2::new(a, b)).abs().max_element() < 0.005, "uv {uv} vs ({a}, {b})");
        assert_spawn_clean(&Shape::Parallelogram(rect.clone()), &ray, t, dir, grazing, m);
    }

    #[test]
    fn box_hits_lie_on_the_box(
        centre in point(), hx in magnitude(-4.0, 6.0), hy in magnitude(-4.0, 6.0), hz in magnitude(-4.0, 6.0),
        rot in -360.0f64..360.0, face in 0usize..6, fa in -0.99f64..0.99, fb in -0.99f64..0.99,
        w in unit(), dist in magnitude(-4.0, 6.0), dir in unit(),
        grazing in prop_oneof![Just(1.0), Just(1e-3), Just(1e-9)],
    ) {
        let half = DVec3::new(hx, hy, hz);
        let cuboid = Cuboid::new(centre - half, centre + half, rot, DVec3::ZERO);
        let (axis, sign) = (face / 2, if face % 2 == 0 { 1.0 } else { -1.0 });
        let mut local = DVec3::ZERO;
        local[axis] = sign * half[axis];
        local[(axis + 1) % 3] = fa * half[(axis + 1) % 3];
        local[(axis + 2) % 3] = fb * half[(axis + 2) % 3];
        let mut n_local = DVec3::ZERO;
        n_local[axis] = sign;
        let n = cuboid.to_world(n_local);
        let target = cuboid.centre + cuboid.to_world(local);
        let Some(w) = leaving(n, w, 0.1) else { return Ok(()) };
        let origin = target + w * dist;
        let ray = aim(origin, target);
        let m = norm_max(cuboid.centre) + norm_max(half);
        let hmin = hx.min(hy).min(hz);
        prop_assume!(64.0 * EPS * (m + norm_max(origin)) < 0.005 * hmin);
        let t = cuboid.intersect(&ray, f64::INFINITY);
        prop_assert!(t.is_some(), "missed: {origin} → {target}");
        let t = t.unwrap();
        let s = cuboid.surface(&ray, t);
        let q = cuboid.to_local(s.point - cuboid.centre);
        let tol = 16.0 * EPS * m;
        let outside = (q.abs() - half).max_element();
        prop_assert!(outside <= tol, "outside the box by {outside:e}");
        let on_face = (q.abs() - half).abs().min_element();
        prop_assert!(on_face <= tol, "inside the box by {on_face:e}");
        assert_spawn_clean(&Shape::Cuboid(cuboid), &ray, t, dir, grazing, m);
    }

    #[test]
    fn rays_aimed_at_box_edges_and_corners_hit(
        centre in point(), hx in magnitude(-4.0, 6.0), hy in magnitude(-4.0, 6.0), hz in magnitude(-4.0, 6.0),
        rot in -360.0f64..360.0, signs in (any::<bool>(), any::<bool>(), any::<bool>()),
        free in 0usize..4, along in -0.9f64..0.9, w in (0.05f64..1.0, 0.05f64..1.0, 0.05f64..1.0),
        dist in magnitude(-4.0, 6.0),
    ) {
        // An edge (one free coordinate) or a vertex (free == 3: none), aimed
        // at from outside through the corner's own octant, pulled inside by
        // a margin just above the rounding of the aim: it must hit — no
        // crack between the faces that meet there.
        let half = DVec3::new(hx, hy, hz);
        let cuboid = Cuboid::new(centre - half, centre + half, rot, DVec3::ZERO);
        let s = DVec3::new(
            if signs.0 { 1.0 } else { -1.0 },
            if signs.1 { 1.0 } else { -1.0 },
            if signs.2 { 1.0 } else { -1.0 },
        );
        let m = norm_max(cuboid.centre) + norm_max(half);
        let margin = 64.0 * EPS * (m + dist);
        prop_assume!(margin < 0.01 * hx.min(hy).min(hz));
        let mut local = s * (half - DVec3::splat(margin));
        let mut out = s * DVec3::new(w.0, w.1, w.2);
        if free < 3 {
            local[free] = along * half[free];
            out[free] *= 0.2;
        }
        let target = cuboid.centre + cuboid.to_world(local);
        let origin = target + cuboid.to_world(out.normalize()) * dist;
        let o = cuboid.to_local(origin - cuboid.centre);
        prop_assume!((o.abs() - half).max_element() > 0.0);
        let ray = aim(origin, target);
        prop_assert!(
            cuboid.intersect(&ray, f64::INFINITY).is_some(),
            "slipped past {} (free axis {free}) from {origin}",
            target
        );
    }

    #[test]
    fn light_uv_round_trips(
        corner in point(), eu in unit(), turn in unit(), lu in magnitude(-4.0, 6.0), lv in magnitude(-4.0, 6.0),
        angle in prop_oneof![magnitude(-8.0, 0.2), Just(std::f64::consts::FRAC_PI_2)],
        a in -0.5f64..1.5, b in -0.5f64..1.5,
    ) {
        // edge_v at `angle` (down to 1e-8 rad: a very thin parallelogram)
        // from edge_u, in a random plane through it.
        let Some(perp) = (turn - eu * turn.dot(eu)).try_normalize() else { return Ok(()) };
        let ev = eu * angle.cos() + perp * angle.sin();
        let light = Parallelogram::new(corner, eu * lu, ev * lv);
        let sin = angle.sin();
        let m = norm_max(corner) + lu + lv;
        let p = light.point(DVec2::new(a, b));
        let uv = light.uv(p);
        let (ta, tb) = (32.0 * EPS * m / (lu * sin), 32.0 * EPS * m / (lv * sin));
        prop_assert!((uv.x - a).abs() <= ta, "a: {} vs {a}, bound {ta:e}", uv.x);
        prop_assert!((uv.y - b).abs() <= tb, "b: {} vs {b}, bound {tb:e}", uv.y);
        // And back: the point of the coordinates is the point.
        let back = light.point(uv);
        let err = (back - p).length();
        prop_assert!(err <= 64.0 * EPS * m / sin, "point: {err:e}");
        // Corners are (0,0), (1,0), (1,1), (0,1).
        for (c, want) in light.corners().iter().zip([DVec2::ZERO, DVec2::X, DVec2::ONE, DVec2::Y]) {
            let got = light.uv(*c);
            let bound = 32.0 * EPS * m / (lu.min(lv) * sin);
            prop_assert!((got - want).abs().max_element() <= bound, "corner {c}: {got} vs {want}, bound {bound:e}");
        }
    }
}
