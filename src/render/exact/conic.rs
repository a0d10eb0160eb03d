//! A sphere's shadow as the conic it is, for the diffuse factor.
//!
//! The shadow of a sphere on the light's plane is the central projection
//! from q of its silhouette circle (the tangent points from q): an ellipse
//! when the circle lies wholly below q's plane. The diffuse integrand
//! f(x) = (a·x + b)/g(x), g = √(|x|² + h²), is the divergence of
//! F(x) = a g(x) + b x/(g(x) + |h|) (see `analytic.rs`), so its integral
//! over a convex piece P's part inside the ellipse, P ∩ S, is the flux of F
//! out through the boundary of P ∩ S:
//! - along P's edges inside S (an interval of each, a quadratic's roots):
//!   the closed-form edge terms (`diffuse.rs`);
//! - along the arcs of S inside P (the circle's angles between its
//!   crossings of P's edge lines, each a cos/sin equation): adaptive
//!   16-point Gauss–Legendre in the circle's angle, an interval split in
//!   two until the two highest Legendre coefficients of the flux's
//!   interpolant at the nodes (degrees 14 and 15) fall within
//!   [`ARC_TOLERANCE`] of the light's area. F along the arc is analytic
//!   (the projection has no pole while the circle stays below q's plane),
//!   so its coefficients fall geometrically, and the rule's error (of the
//!   degrees from 32 on) is far below theirs. One rule an arc where the
//!   flux is smooth on it, where comparing the whole with its halves took
//!   three.

use std::sync::OnceLock;

use glam::{DVec2, DVec3};

use super::diffuse::segment_term;
use super::polygon::edges_of;
use super::projection::{LightView, Silhouette};
use crate::render::geometry::Sphere;

/// Size of an arc's two highest Legendre coefficients (relative to the
/// light's area) below which its rule is taken.
pub const ARC_TOLERANCE: f64 = 1e-13;

/// The silhouette circle's highest point must lie below q's plane by this
/// fraction of the light's height (else the projection stretches without
/// bound, and the polygon is used).
const BELOW: f64 = 1e-3;

/// Halvings of an arc at most.
const MAX_SPLITS: u32 = 16;

/// A sphere's shadow seen from q (the light's frame of `LightView`).
#[derive(Debug, Clone, Copy)]
pub struct ConicShadow {
    /// The silhouette circle: centre, radius and two unit axes of its plane.
    centre: DVec3,
    rho: f64,
    u: DVec3,
    w: DVec3,
    /// The sphere's centre from q, and |oc|² − r² (the cone's test).
    oc: DVec3,
    k: f64,
    /// Unit axis of the tangent cone and its half-angle.
    axis: DVec3,
    half_angle: f64,
    /// Height of q above the plane.
    h: f64,
    /// +1 if the circle's angle runs counter-clockwise in the plane.
    orient: f64,
}

impl ConicShadow {
    /// The shadow of `sphere`, or `None` if its silhouette circle reaches
    /// near q's plane (or q is inside it).
    pub fn new(view: &LightView, sphere: &Sphere) -> Option<ConicShadow> {
        let oc = view.local(sphere.centre);
        let r = sphere.radius;
        let d2 = oc.length_squared();
        // (NaN fails too.)
        if d2.partial_cmp(&(r * r)) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let Silhouette {
            centre,
            rho,
            axis,
            u,
            w,
        } = Silhouette::new(oc, r, d2);
        let top = centre.z + rho * (u.z * u.z + w.z * w.z).sqrt();
        if top.partial_cmp(&(-BELOW * view.h)) != Some(std::cmp::Ordering::Less) {
            return None;
        }
        let mut c = ConicShadow {
            centre,
            rho,
            u,
            w,
            oc,
            k: d2 - r * r,
            axis,
            half_angle: (r / d2.sqrt()).asin(),
            h: view.h,
            orient: 1.0,
        };
        let yc = c.project(centre);
        let (y0, t0) = c.point_and_tangent(0.0);
        c.orient = (y0 - yc).perp_dot(t0).signum();
        Some(c)
    }

    /// Whether the two shadows cannot overlap: their cones from q are
    /// apart by more than the sum of their half-angles.
    pub fn disjoint(&self, o: &ConicShadow) -> bool {
        let apart = self.axis.dot(o.axis).clamp(-1.0, 1.0).acos();
        apart > self.half_angle + o.half_angle + 1e-9
    }

    #[inline]
    fn project(&self, x: DVec3) -> DVec2 {
        DVec2::new(x.x, x.y) * (self.h / -x.z)
    }

    /// The shadow's boundary point at the circle's angle t, and its
    /// derivative in t.
    #[inline]
    fn point_and_tangent(&self, t: f64) -> (DVec2, DVec2) {
        let (s, c) = t.sin_cos();
        let x = self.centre + (self.u * c + self.w * s) * self.rho;
        let dx = (self.w * c - self.u * s) * self.rho;
        let z = -x.z;
        let tangent =
            (DVec2::new(dx.x, dx.y) * z + DVec2::new(x.x, x.y) * dx.z) * (self.h / (z * z));
        (self.project(x), tangent)
    }

    /// ∫ (a·x + b)/√(|x|² + h²) dx over the part of the counter-clockwise
    /// convex polygon `poly` inside the shadow (a·x + b ≥ 0 on `poly`);
    /// `light_area` scales the arcs' tolerance.
    pub fn diffuse_inside(
        &self,
        poly: &[DVec2],
        a: DVec2,
        b: f64,
        light_area: f64,
        s: &mut ArcScratch,
    ) -> f64 {
        let n = poly.len();
        if n < 3 {
            return 0.0;
        }
        let h = self.h;
        let mut total = 0.0;
        // P's edges inside S: the cone's test (d·oc)² ≥ k|d|² along
        // d(t) = (p + t e, −h), a quadratic A t² + B t + C ≥ 0 with A < 0.
        let (angles, lines) = (&mut s.angles, &mut s.lines);
        angles.clear();
        lines.clear();
        for (p, q) in edges_of(poly) {
            let e = q - p;
            let d0 = DVec3::new(p.x, p.y, -h);
            let de = DVec3::new(e.x, e.y, 0.0);
            let (al, be) = (d0.dot(self.oc), de.dot(self.oc));
            let qa = be * be - self.k * de.length_squared();
            let qb = 2.0 * (al * be - self.k * d0.dot(de));
            let qc = al * al - self.k * d0.length_squared();
            let disc = qb * qb - 4.0 * qa * qc;
            if qa < 0.0 && disc > 0.0 {
                let s = disc.sqrt();
                let r = -0.5 * (qb + s.copysign(qb));
                let (t1, t2) = (r / qa, if r != 0.0 { qc / r } else { 0.0 });
                let (lo, hi) = (t1.min(t2).max(0.0), t1.max(t2).min(1.0));
                if lo < hi {
                    total += segment_term(p + e * lo, p + e * hi, a, b, h);
                }
            }
            // The edge line n·y + c ≥ 0 inside, times −X.z > 0 on the
            // circle: g(t) = h n·X.xy − c X.z = g0 + g1 cos t + g2 sin t.
            let nn = DVec2::new(-e.y, e.x);
            let c = e.y * p.x - e.x * p.y;
            let lin = |x: DVec3| h * (nn.x * x.x + nn.y * x.y) - c * x.z;
            let (g0, g1, g2) = (
                lin(self.centre),
                self.rho * lin(self.u),
                self.rho * lin(self.w),
            );
            lines.push((g0, g1, g2));
            let amp = g1.hypot(g2);
            if amp > g0.abs() {
                let phi = g2.atan2(g1);
                let delta = (-g0 / amp).acos();
                for t in [phi - delta, phi + delta] {
                    angles.push(t.rem_euclid(std::f64::consts::TAU));
                }
            }
        }
        angles.push(0.0);
        angles.push(std::f64::consts::TAU);
        angles.sort_unstable_by(f64::total_cmp);
        let inside = |t: f64| {
            let (s, c) = t.sin_cos();
            lines
                .iter()
                .all(|&(g0, g1, g2)| g0 + g1 * c + g2 * s >= 0.0)
        };
        let tol = ARC_TOLERANCE * light_area;
        for pair in angles.windows(2) {
            let (t0, t1) = (pair[0], pair[1]);
            if t1 > t0 && inside(0.5 * (t0 + t1)) {
                total += self.arc(t0, t1, a, b, tol, MAX_SPLITS);
            }
        }
        total
    }

    /// The flux of F out through the arc t0 → t1 (adaptive).
    fn arc(&self, t0: f64, t1: f64, a: DVec2, b: f64, tol: f64, splits: u32) -> f64 {
        let (whole, tail) = self.arc_rule(t0, t1, a, b);
        if splits == 0 || tail <= tol {
            return whole;
        }
        let mid = 0.5 * (t0 + t1);
        self.arc(t0, mid, a, b, 0.5 * tol, splits - 1)
            + self.arc(mid, t1, a, b, 0.5 * tol, splits - 1)
    }

    /// 16-point Gauss–Legendre of the flux through the arc t0 → t1, and
    /// the size of its interpolant's two highest coefficients over the arc
    /// (the estimate).
    fn arc_rule(&self, t0: f64, t1: f64, a: DVec2, b: f64) -> (f64, f64) {
        let ah = self.h.abs();
        let (mid, half) = (0.5 * (t0 + t1), 0.5 * (t1 - t0));
        let (mut sum, mut c14, mut c15) = (0.0, 0.0, 0.0);
        for n in gl16() {
            let t = mid + half * n.x;
            let (y, tangent) = self.point_and_tangent(t);
            let dy = tangent * self.orient;
            let g = (y.length_squared() + ah * ah).sqrt();
            let f = a * g + y * (b / (g + ah));
            // F · ν ds with ν ds = (dy.y, −dy.x) dt for a counter-clockwise
            // boundary.
            let flux = f.x * dy.y - f.y * dy.x;
            sum += n.w * flux;
            c14 += n.c14 * flux;
            c15 += n.c15 * flux;
        }
        (sum * half, 2.0 * half.abs() * (c14.abs() + c15.abs()))
    }
}

/// Scratch of [`ConicShadow::diffuse_inside`]: the circle's angles where
/// it crosses a piece's edge lines, and those lines (kept warm: a piece
/// may have dozens of edges, too many to zero on the stack per call).
#[derive(Debug, Clone, Default)]
pub struct ArcScratch {
    angles: Vec<f64>,
    lines: Vec<(f64, f64, f64)>,
}

/// A node of the 16-point rule on [−1, 1]: x, its weight, and the
/// weights of the interpolant's coefficients of degrees 14 and 15,
/// (2k + 1)/2 · w · P_k(x).
struct Node {
    x: f64,
    w: f64,
    c14: f64,
    c15: f64,
}

fn gl16() -> &'static [Node] {
    static RULE: OnceLock<Vec<Node>> = OnceLock::new();
    RULE.get_or_init(|| {
        crate::render::math::gauss_legendre(16)
            .into_iter()
            .map(|(x, w)| {
                // Bonnet's recurrence up to P_15.
                let (mut p0, mut p1) = (1.0, x);
                let mut p14 = 0.0;
                for k in 1..15 {
                    let p2 = ((2 * k + 1) as f64 * x * p1 - k as f64 * p0) / (k + 1) as f64;
                    (p0, p1) = (p1, p2);
                    if k == 13 {
                        p14 = p1;
                    }
                }
                Node {
                    x,
                    w,
                    c14: 14.5 * w * p14,
                    c15: 15.5 * w * p1,
                }
            })
            .collect()
    })
}
