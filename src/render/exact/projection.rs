//! Shadows on the light's plane: each occluder projected from the hit point.
//!
//! The light's frame seen from the shadow point q: q at the origin, x and y
//! in the light's plane (x along `edge_u`), z along the light's normal, so
//! the light's plane is z = −h. A shadow ray to the light point y meets an
//! occluder point x at t = −x.z / h; the sampled model counts it blocked for
//! t in (0, `RAY_END`), i.e. for −`RAY_END`·h < x.z < 0. So the shadow of an
//! occluder is the central projection from q, x ↦ (x.x, x.y)·h/(−x.z), of
//! its part inside the frustum K: that slab, cut by the four planes through
//! q and the light's edges. K keeps every projection inside the light (no
//! point at infinity), and the projection of a convex body is convex:
//! - a box, rect or triangle: each face clipped to K (Sutherland–Hodgman),
//!   projected, and the convex hull of all (plus the light's corners whose
//!   rays run inside a box, the vertices of K inside it);
//! - a sphere: its silhouette circle (the tangent points from q) as a
//!   regular N-gon, clipped and projected likewise. The inscribed and the
//!   circumscribed N-gons bracket the true shadow; the polygon of the same
//!   area as the circle lies between them and is what shading uses (its
//!   error falls as N⁻⁴, see `tests/exact_shadows.rs`);
//! - an infinite plane: a half-plane of the light's plane.
//!
//! The slab's side near q stops at z = −`NEAR`·h rather than 0: the part
//! of an occluder within 10⁻⁶·h of q's plane only blocks rays that graze it
//! and would project arbitrarily far.

use glam::{DVec2, DVec3};

use super::polygon::{HalfPlane, hull_into};
use crate::render::geometry::{Cuboid, Parallelogram, Plane, Sphere};
use crate::render::shadow::RAY_END;

/// Relative height below q's plane where the frustum starts.
const NEAR: f64 = 1e-6;

/// The light's frame seen from one shadow point.
#[derive(Debug, Clone)]
pub struct LightView {
    pub q: DVec3,
    pub e1: DVec3,
    pub e2: DVec3,
    /// Unit normal of the light towards its lit side.
    pub m: DVec3,
    /// Height of q above the light's plane (> 0).
    pub h: f64,
    /// The light's corners in the plane, counter-clockwise.
    pub rect: [DVec2; 4],
    /// Area of the light, and its root.
    pub area: f64,
    pub side: f64,
    /// The light's corner and edges in the frame (3-D).
    pub corner: DVec3,
    pub edge_u: DVec3,
    pub edge_v: DVec3,
    /// The light's corners in the frame (3-D), in the order of `rect`.
    corners: [DVec3; 4],
    /// The frustum's planes `n · x + c ≥ 0`.
    planes: [(DVec3, f64); 6],
    /// Cut-off of `RAY_END` (f32) as f64.
    ray_end: f64,
}

/// What of [`LightView`] depends on the light alone: the same from every
/// point, so a thread keeps it (its square roots and division are a
/// chain of latencies each point would wait for again).
#[derive(Debug, Clone)]
pub struct LightFrame {
    /// The light's edges and normal (world) it was made from.
    of: [DVec3; 3],
    e1: DVec3,
    e2: DVec3,
    m: DVec3,
    /// The light's edges in the frame.
    edge_u: DVec3,
    edge_v: DVec3,
    area: f64,
    /// √area.
    side: f64,
}

impl LightFrame {
    pub fn new(light: &Parallelogram) -> LightFrame {
        let m = light.normal;
        let e1 = light.edge_u.normalize();
        let e2 = m.cross(e1);
        let local = |d: DVec3| DVec3::new(d.dot(e1), d.dot(e2), d.dot(m));
        let area = light.edge_u.cross(light.edge_v).length();
        LightFrame {
            of: [light.edge_u, light.edge_v, light.normal],
            e1,
            e2,
            m,
            edge_u: local(light.edge_u),
            edge_v: local(light.edge_v),
            area,
            side: area.sqrt(),
        }
    }

    /// The light's edges in the frame (a [`LightView`]'s `edge_u`, `edge_v`).
    pub fn edges(&self) -> (DVec3, DVec3) {
        (self.edge_u, self.edge_v)
    }

    /// Whether this is the frame of `light` (its corner does not enter).
    pub fn is_of(&self, light: &Parallelogram) -> bool {
        self.of == [light.edge_u, light.edge_v, light.normal]
    }
}

impl LightView {
    /// The frame of `light` (`frame`: [`LightFrame::new`] of it) seen from
    /// `q`, or `None` if q is not strictly on the lit side.
    pub fn new(light: &Parallelogram, frame: &LightFrame, q: DVec3) -> Option<LightView> {
        let LightFrame {
            e1,
            e2,
            m,
            edge_u,
            edge_v,
            area,
            side,
            ..
        } = *frame;
        let h = m.dot(q - light.corner);
        // Also refuses a NaN height.
        if h.is_nan() || h <= 0.0 {
            return None;
        }
        let local = |d: DVec3| DVec3::new(d.dot(e1), d.dot(e2), d.dot(m));
        let corner = local(light.corner - q);
        let c3 = [
            corner,
            corner + edge_u,
            corner + edge_u + edge_v,
            corner + edge_v,
        ];
        let rect = c3.map(|c| DVec2::new(c.x, c.y));
        let centre = corner + (edge_u + edge_v) * 0.5;
        let ray_end = RAY_END as f64;
        let mut planes = [(DVec3::ZERO, 0.0); 6];
        for i in 0..4 {
            let mut n = c3[i].cross(c3[(i + 1) % 4]);
            if n.dot(centre) < 0.0 {
                n = -n;
            }
            planes[i] = (n, 0.0);
        }
        planes[4] = (DVec3::Z, ray_end * h);
        planes[5] = (-DVec3::Z, -NEAR * h);
        Some(LightView {
            q,
            e1,
            e2,
            m,
            h,
            rect,
            area,
            side,
            corner,
            edge_u,
            edge_v,
            corners: c3,
            planes,
            ray_end,
        })
    }

    /// Whether the box hides the whole light: its shadow (convex, as the
    /// projection of a convex solid) holds the four corners. A corner is
    /// hidden where its ray from q meets the box between the frustum's
    /// ends (t in [`NEAR`], `RAY_END` of the way). `false` where q is
    /// inside the box (its shadow is not computed).
    pub fn box_hides_light(&self, c: &Cuboid) -> bool {
        let o = c.to_local(self.q - c.centre);
        if o.abs().cmplt(c.half).all() {
            return false;
        }
        self.corners.iter().all(|&ray| {
            let d = c.to_local(self.e1 * ray.x + self.e2 * ray.y + self.m * ray.z);
            let (mut lo, mut hi) = (NEAR, self.ray_end);
            for k in 0..3 {
                if d[k] == 0.0 {
                    if o[k].abs() > c.half[k] {
                        return false;
                    }
                    continue;
                }
                let (t1, t2) = ((-c.half[k] - o[k]) / d[k], (c.half[k] - o[k]) / d[k]);
                lo = lo.max(t1.min(t2));
                hi = hi.min(t1.max(t2));
            }
            lo <= hi
        })
    }

    /// [`LightView::box_hides_light`] for a sphere; `false` where q is
    /// inside it or it reaches below the rays' end (its shadow is not
    /// computed there either).
    pub fn sphere_hides_light(&self, sphere: &Sphere) -> bool {
        let oc = self.local(sphere.centre);
        let r2 = sphere.radius * sphere.radius;
        let k = oc.length_squared() - r2;
        if k <= 0.0 || oc.z - sphere.radius < -self.ray_end * self.h {
            return false;
        }
        self.corners.iter().all(|&ray| {
            // |t ray − oc|² ≤ r²: a t² − 2 b t + k ≤ 0.
            let (a, b) = (ray.length_squared(), ray.dot(oc));
            let disc = b * b - a * k;
            if disc < 0.0 {
                return false;
            }
            let root = disc.sqrt();
            (b - root) / a <= self.ray_end && (b + root) / a >= NEAR
        })
    }

    /// A world point in the frame.
    #[inline]
    pub fn local(&self, x: DVec3) -> DVec3 {
        let d = x - self.q;
        DVec3::new(d.dot(self.e1), d.dot(self.e2), d.dot(self.m))
    }

    /// A world direction in the frame.
    #[inline]
    pub fn local_dir(&self, d: DVec3) -> DVec3 {
        DVec3::new(d.dot(self.e1), d.dot(self.e2), d.dot(self.m))
    }

    /// A frame point back in the world.
    #[inline]
    fn world(&self, x: DVec3) -> DVec3 {
        self.q + self.e1 * x.x + self.e2 * x.y + self.m * x.z
    }

    /// Where the ray from q through a frame point (z < 0) meets the plane.
    #[inline]
    fn project(&self, x: DVec3) -> DVec2 {
        DVec2::new(x.x, x.y) * (self.h / -x.z)
    }

    /// The half-plane of light points in front of a surface of unit normal
    /// `n` (world) through q: n · (y − q) > 0.
    pub fn front_of(&self, n: DVec3) -> HalfPlane {
        let l = self.local_dir(n);
        HalfPlane {
            n: DVec2::new(l.x, l.y),
            c: -self.h * l.z,
        }
    }

    /// Light points whose shadow rays an infinite plane does not cut (the
    /// sampled test: q and the ray's end `RAY_END` of the way to y on the
    /// same side), or `None` if q lies in the plane (it blocks nothing).
    pub fn plane_clear(&self, plane: &Plane) -> Option<HalfPlane> {
        let s = plane.signed_distance(self.q);
        if s == 0.0 {
            return None;
        }
        let l = self.local_dir(plane.normal);
        let sign = s.signum();
        let re = self.ray_end;
        Some(HalfPlane {
            n: DVec2::new(l.x, l.y) * (sign * re),
            c: sign * (s - re * self.h * l.z),
        })
    }
}

/// How a sphere's silhouette circle is turned into a polygon.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CircleFit {
    /// Vertices on the circle: a shadow inside the true one.
    Inscribed,
    /// Edges tangent to it: a shadow containing the true one.
    Circumscribed,
    /// The N-gon of the circle's area, between the two (what shading uses:
    /// for the pieces and the specular factor; the diffuse factor then
    /// follows the conic itself where it can, see `conic.rs`).
    SameArea,
}

/// Why a shadow cannot be computed exactly.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unsupported {
    /// q lies inside the occluder.
    Inside,
    /// A sphere reaching below the rays' end near the light's plane (its
    /// silhouette no longer bounds its shadow there).
    SphereAtLight,
}

/// Scratch of the projections.
#[derive(Debug, Clone, Default)]
pub struct ProjectScratch {
    face: Vec<DVec3>,
    clipped: Vec<DVec3>,
    points: Vec<DVec2>,
}

/// Bit i set: some of `points` (frame coordinates) lie outside the
/// frustum's plane i. The polygons of those points need clipping by those
/// planes only. And whether all of them lie outside one plane (the polygon
/// clips to nothing).
fn planes_crossed(view: &LightView, points: &[DVec3]) -> (u8, bool) {
    crossed_by_sides(points.len(), |i, j| {
        let (n, c) = view.planes[i];
        n.dot(points[j]) + c
    })
}

/// [`planes_crossed`] from `side(i, j)`: frustum plane i's value at point
/// j of `count` (a box's faces read them from the values at its corners,
/// each corner taken once instead of once per face).
#[inline]
fn crossed_by_sides(count: usize, side: impl Fn(usize, usize) -> f64) -> (u8, bool) {
    let mut mask = 0;
    for i in 0..6 {
        let out = (0..count).filter(|&j| side(i, j) < 0.0).count();
        if out == count {
            return (mask, true);
        }
        if out > 0 {
            mask |= 1 << i;
        }
    }
    (mask, false)
}

/// Clips a planar polygon (frame coordinates) to the frustum's planes of
/// `mask` (the others hold all of it), appending its projection to
/// `points`.
fn clip_and_project(
    view: &LightView,
    mask: u8,
    face: &mut Vec<DVec3>,
    tmp: &mut Vec<DVec3>,
    points: &mut Vec<DVec2>,
) {
    for (_, &(n, c)) in view
        .planes
        .iter()
        .enumerate()
        .filter(|&(i, _)| mask & (1 << i) != 0)
    {
        tmp.clear();
        // Each edge a → b, b the next vertex (the last edge closes on the
        // first): no index modulo per edge.
        let Some(&first) = face.first() else {
            return;
        };
        let mut a = first;
        let mut da = n.dot(a) + c;
        for &b in face[1..].iter().chain(std::iter::once(&first)) {
            let db = n.dot(b) + c;
            if da >= 0.0 {
                tmp.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                tmp.push(a + (b - a) * (da / (da - db)));
            }
            (a, da) = (b, db);
        }
        std::mem::swap(face, tmp);
        if face.len() < 3 {
            return;
        }
    }
    points.extend(face.iter().map(|&x| view.project(x)));
}

/// The shadow of the convex polygons `faces` (frame coordinates), into `out`
/// (counter-clockwise; empty if none). `extra` are points of the plane
/// known to be in the shadow (the light's corners inside a solid).
fn faces_shadow(
    view: &LightView,
    faces: &[&[DVec3]],
    crossed: impl Fn(usize) -> (u8, bool),
    extra: &[DVec2],
    s: &mut ProjectScratch,
    out: &mut Vec<DVec2>,
) {
    s.points.clear();
    s.points.extend_from_slice(extra);
    for (k, f) in faces.iter().enumerate() {
        // Only the planes that cut this face (`crossed`, as
        // [`planes_crossed`]): a face wholly inside a plane comes out of
        // its clip as it went in, and one wholly outside any plane adds
        // nothing.
        let (crossed, outside) = crossed(k);
        if outside {
            continue;
        }
        s.face.clear();
        s.face.extend_from_slice(f);
        clip_and_project(view, crossed, &mut s.face, &mut s.clipped, &mut s.points);
    }
    hull_into(&mut s.points, out);
}

pub fn box_shadow(
    view: &LightView,
    c: &Cuboid,
    s: &mut ProjectScratch,
    out: &mut Vec<DVec2>,
) -> Result<(), Unsupported> {
    let h = c.half;
    let corners = c.corners();
    let inside = |world: DVec3| {
        let l = c.to_local(world - c.centre).abs();
        l.cmple(h).all()
    };
    if c.to_local(view.q - c.centre).abs().cmplt(h).all() {
        return Err(Unsupported::Inside);
    }
    let local = corners.map(|x| view.local(x));
    // Each frustum plane's value at each corner, for every test below.
    let sides: [[f64; 8]; 6] = view.planes.map(|(n, k)| local.map(|x| n.dot(x) + k));
    out.clear();
    // Wholly beyond one plane of the frustum: no shadow.
    if sides.iter().any(|row| row.iter().all(|&v| v < 0.0)) {
        return Ok(());
    }
    if sides.iter().all(|row| row.iter().all(|&v| v >= 0.0)) {
        s.points.clear();
        s.points.extend(local.iter().map(|&x| view.project(x)));
        hull_into(&mut s.points, out);
        return Ok(());
    }
    // The frustum's vertices inside the box: its corner rays at both ends.
    let mut extra = [DVec2::ZERO; 4];
    let mut n_extra = 0;
    for (r, &ray) in view.rect.iter().zip(&view.corners) {
        if inside(view.world(ray * view.ray_end)) || inside(view.world(ray * NEAR)) {
            extra[n_extra] = *r;
            n_extra += 1;
        }
    }
    let faces: [[DVec3; 4]; 6] = Cuboid::FACES.map(|f| f.map(|i| local[i]));
    let refs: [&[DVec3]; 6] = std::array::from_fn(|i| &faces[i][..]);
    let crossed = |k: usize| crossed_by_sides(4, |i, j| sides[i][Cuboid::FACES[k][j]]);
    faces_shadow(view, &refs, crossed, &extra[..n_extra], s, out);
    Ok(())
}

pub fn rect_shadow(
    view: &LightView,
    r: &Parallelogram,
    s: &mut ProjectScratch,
    out: &mut Vec<DVec2>,
) {
    let face = r.corners().map(|x| view.local(x));
    faces_shadow(view, &[&face], |_| planes_crossed(view, &face), &[], s, out);
}

pub fn triangle_shadow(
    view: &LightView,
    vertices: [DVec3; 3],
    s: &mut ProjectScratch,
    out: &mut Vec<DVec2>,
) {
    let face = vertices.map(|x| view.local(x));
    faces_shadow(view, &[&face], |_| planes_crossed(view, &face), &[], s, out);
}

/// The circle where the tangent cone from q (at the origin) touches a
/// sphere of centre `oc` and radius `r` (`d2` = |oc|², above r²): its
/// centre, radius, the cone's unit axis and two unit vectors spanning the
/// circle's plane. One computation for the polygon and the conic, so both
/// start from the same bits.
pub(super) struct Silhouette {
    pub centre: DVec3,
    pub rho: f64,
    pub axis: DVec3,
    pub u: DVec3,
    pub w: DVec3,
}

impl Silhouette {
    pub(super) fn new(oc: DVec3, r: f64, d2: f64) -> Silhouette {
        let k = r * r / d2;
        let axis = oc / d2.sqrt();
        let u = axis.any_orthonormal_vector();
        Silhouette {
            centre: oc * (1.0 - k),
            rho: r * (1.0 - k).sqrt(),
            axis,
            u,
            w: axis.cross(u),
        }
    }
}

/// The shadow of a sphere from its silhouette as an `n`-gon.
pub fn sphere_shadow(
    view: &LightView,
    sphere: &Sphere,
    n: usize,
    fit: CircleFit,
    s: &mut ProjectScratch,
    out: &mut Vec<DVec2>,
) -> Result<(), Unsupported> {
    out.clear();
    let oc = view.local(sphere.centre);
    let r = sphere.radius;
    let d2 = oc.length_squared();
    if d2 <= r * r {
        return Err(Unsupported::Inside);
    }
    if oc.z - r < -view.ray_end * view.h {
        return Err(Unsupported::SphereAtLight);
    }
    // Wholly behind q's plane or outside a side of the pyramid.
    if view.planes.iter().any(|&(pn, c)| {
        let len = pn.length();
        pn.dot(oc) + c < -r * len
    }) {
        return Ok(());
    }
    let Silhouette {
        centre, rho, u, w, ..
    } = Silhouette::new(oc, r, d2);
    let step = std::f64::consts::TAU / n as f64;
    let scale = match fit {
        CircleFit::Inscribed => 1.0,
        CircleFit::Circumscribed => 1.0 / (step * 0.5).cos(),
        CircleFit::SameArea => (step / step.sin()).sqrt(),
    };
    s.face.clear();
    let ring = unit_ring(n);
    s.face.extend(
        ring.iter()
            .map(|&(sn, cs)| centre + (u * cs + w * sn) * (rho * scale)),
    );
    // Only the planes the polygon may cross: its vertices lie within
    // r · scale of the centre (the circle lies on the sphere).
    let mut mask = 0;
    for (i, &(pn, c)) in view.planes.iter().enumerate() {
        if pn.dot(oc) + c < r * scale * pn.length() * (1.0 + 1e-9) {
            mask |= 1 << i;
        }
    }
    s.points.clear();
    let ProjectScratch {
        face,
        clipped,
        points,
    } = s;
    clip_and_project(view, mask, face, clipped, points);
    // The projection of a convex polygon is convex and keeps its order;
    // only the winding may turn.
    out.extend_from_slice(points);
    if out.len() >= 3 && super::polygon::twice_area(out) < 0.0 {
        out.reverse();
    }
    if out.len() < 3 {
        out.clear();
    }
    Ok(())
}

/// (sin, cos) of i · 2π/n for i < n: the same values as computing them,
/// kept for the two usual n (every sphere of every hit point needs them).
fn unit_ring(n: usize) -> std::borrow::Cow<'static, [(f64, f64)]> {
    use std::sync::OnceLock;
    let make = |n: usize| -> Vec<(f64, f64)> {
        let step = std::f64::consts::TAU / n as f64;
        (0..n).map(|i| (i as f64 * step).sin_cos()).collect()
    };
    static POLYGON: OnceLock<Vec<(f64, f64)>> = OnceLock::new();
    static CONIC: OnceLock<Vec<(f64, f64)>> = OnceLock::new();
    match n {
        super::SPHERE_EDGES => std::borrow::Cow::Borrowed(POLYGON.get_or_init(|| make(n))),
        super::CONIC_SPHERE_EDGES => std::borrow::Cow::Borrowed(CONIC.get_or_init(|| make(n))),
        _ => std::borrow::Cow::Owned(make(n)),
    }
}

#[cfg(test)]
mod tests {
    use super::{CircleFit, LightFrame, LightView, ProjectScratch, box_shadow, sphere_shadow};
    use crate::render::exact::polygon::{Pieces, Work};
    use crate::render::geometry::{Cuboid, Parallelogram, Sphere};
    use crate::render::rng::Rng;
    use glam::{DVec2, DVec3};

    /// The light's area left outside a shadow polygon.
    fn left_visible(view: &LightView, shadow: &[DVec2]) -> f64 {
        let mut p = Pieces::default();
        p.push(&view.rect, 0.0);
        if shadow.len() >= 3 {
            p.subtract(shadow, 0.0, &mut Work::default());
        }
        p.area()
    }

    /// The umbra shortcut agrees with the projected shadows: from points
    /// under a box or sphere (in umbra, penumbra and full light), a box
    /// that hides the light leaves nothing of it outside its shadow and
    /// one that does not leaves some; a sphere that hides it leaves
    /// nothing outside its circumscribed polygon, and one whose inscribed
    /// polygon covers the light hides it.
    #[test]
    fn hiding_the_whole_light_agrees_with_the_shadows() {
        let light = Parallelogram::new(
            DVec3::new(-1.0, 7.99, -1.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 2.0),
        );
        let frame = LightFrame::new(&light);
        let mut rng = Rng::new(21);
        let mut next = || rng.next_f64();
        let mut s = ProjectScratch::default();
        let mut shadow = Vec::new();
        let (mut hidden, mut seen) = (0, 0);
        for case in 0..4000 {
            let q = DVec3::new(6.0 * next() - 3.0, 2.0 * next(), 6.0 * next() - 3.0);
            let view = LightView::new(&light, &frame, q).expect("below the light");
            let area = view.area;
            let size = DVec3::new(0.5 + next(), 0.2 + next(), 0.5 + next());
            let centre = DVec3::new(next() - 0.5, 4.0 + next(), next() - 0.5);
            if case % 2 == 0 {
                let c = Cuboid::new(centre - size, centre + size, 90.0 * next(), DVec3::ZERO);
                let hides = view.box_hides_light(&c);
                box_shadow(&view, &c, &mut s, &mut shadow).expect("q outside the box");
                let left = left_visible(&view, &shadow);
                if hides {
                    assert!(left <= 1e-9 * area, "case {case}: {left} of {area} left");
                } else {
                    assert!(left > 0.0, "case {case}: nothing left, yet not hidden");
                }
                (hidden, seen) = (hidden + hides as u32, seen + !hides as u32);
            } else {
                let sphere = Sphere {
                    centre,
                    radius: 0.5 + next(),
                };
                let hides = view.sphere_hides_light(&sphere);
                let mut left = |fit| {
                    sphere_shadow(&view, &sphere, 128, fit, &mut s, &mut shadow).expect("outside");
                    left_visible(&view, &shadow)
                };
                if hides {
                    let outer = left(CircleFit::Circumscribed);
                    assert!(outer <= 1e-9 * area, "case {case}: {outer} of {area} left");
                }
                if left(CircleFit::Inscribed) == 0.0 {
                    assert!(hides, "case {case}: covered, yet not hidden");
                }
                (hidden, seen) = (hidden + hides as u32, seen + !hides as u32);
            }
        }
        assert!(hidden > 150 && seen > 150, "{hidden} hidden, {seen} seen");
    }
}
