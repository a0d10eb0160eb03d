use glam::{DVec2, DVec3};

use super::{Aabb, Ray, SurfacePoint};

/// A parallelogram `corner + a·edge_u + b·edge_v`, (a, b) ∈ \[0,1\]²: the
/// `rect` object and the shape of the area light.
#[derive(Debug, Clone)]
pub struct Parallelogram {
    pub corner: DVec3,
    pub edge_u: DVec3,
    pub edge_v: DVec3,
    /// Unit normal along `edge_u × edge_v`.
    pub normal: DVec3,
    /// Rows of the pseudo-inverse of [edge_u edge_v]: `(x - corner) · dual_u`
    /// is the least-squares `a` of x (exact for points in the plane).
    pub dual_u: DVec3,
    pub dual_v: DVec3,
}

impl Parallelogram {
    /// See [`super::Shape::flat`] and [`super::Shape::convex`]: flat and convex.
    pub const FLAT: bool = true;
    pub const CONVEX: bool = true;

    pub fn new(corner: DVec3, edge_u: DVec3, edge_v: DVec3) -> Self {
        // Work with unit-scaled edges so that neither tiny nor huge lights
        // under/overflow in the Gram determinant.
        let (lu, lv) = (edge_u.length(), edge_v.length());
        let (eu, ev) = (edge_u / lu, edge_v / lv);
        // The dual basis from cross products: n = eu × ev has |n|² = sin²
        // of the edges' angle without the cancellation of 1 − (eu·ev)²,
        // which loses all precision for thin parallelograms (sin ≈ 1e-8).
        let n = eu.cross(ev);
        let det = n.length_squared();
        let dual_u = ev.cross(n) / (det * lu);
        let dual_v = n.cross(eu) / (det * lv);
        Parallelogram {
            corner,
            edge_u,
            edge_v,
            normal: n.normalize(),
            dual_u,
            dual_v,
        }
    }

    /// Least-squares (a, b) coordinates of a point (exact in the plane).
    #[inline]
    pub fn uv(&self, p: DVec3) -> DVec2 {
        let d = p - self.corner;
        DVec2::new(d.dot(self.dual_u), d.dot(self.dual_v))
    }

    /// (a, b) of a direction (a point at infinity): the rate at which a
    /// point moving along it changes its coordinates.
    #[inline]
    pub fn uv_of_direction(&self, d: DVec3) -> DVec2 {
        DVec2::new(d.dot(self.dual_u), d.dot(self.dual_v))
    }

    #[inline]
    pub fn point(&self, uv: DVec2) -> DVec3 {
        self.corner + self.edge_u * uv.x + self.edge_v * uv.y
    }

    pub fn corners(&self) -> [DVec3; 4] {
        [
            self.corner,
            self.corner + self.edge_u,
            self.corner + self.edge_u + self.edge_v,
            self.corner + self.edge_v,
        ]
    }

    pub fn centre(&self) -> DVec3 {
        self.corner + (self.edge_u + self.edge_v) * 0.5
    }

    /// Signed distance of a point from the plane, positive on the normal's
    /// side.
    #[inline]
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p - self.corner)
    }

    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<f64> {
        let t = -self.signed_distance(ray.origin) / self.normal.dot(ray.dir);
        if !(t > 0.0 && t < t_max) {
            return None;
        }
        let uv = self.uv(ray.at(t));
        (uv.x >= 0.0 && uv.x <= 1.0 && uv.y >= 0.0 && uv.y <= 1.0).then_some(t)
    }

    #[inline(always)]
    pub fn surface(&self, ray: &Ray, t: f64) -> SurfacePoint {
        let p = ray.at(t);
        SurfacePoint::flat(p - self.normal * self.signed_distance(p), self.normal)
    }

    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(&self.corners()).padded()
    }
}
