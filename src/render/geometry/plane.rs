use glam::DVec3;

use super::{Ray, SurfacePoint};

/// Infinite plane `normal · x = offset`.
#[derive(Debug, Clone)]
pub struct Plane {
    /// Unit normal.
    pub normal: DVec3,
    pub offset: f64,
    /// The axis of the normal where, in f32, it is ± that axis: shadow
    /// rays then test it in one multiplication.
    pub(crate) axis: Option<u8>,
}

impl Plane {
    /// See [`super::Shape::flat`] and [`super::Shape::convex`]: a half-space boundary: flat, and the light points it hides (those on its far side) are a convex set.
    pub const FLAT: bool = true;
    pub const CONVEX: bool = true;

    pub fn new(point: DVec3, normal: DVec3) -> Self {
        let normal = super::super::math::normalize_robust(normal);
        Plane {
            normal,
            offset: normal.dot(point),
            axis: [glam::Vec3::X, glam::Vec3::Y, glam::Vec3::Z]
                .iter()
                .position(|&axis| normal.as_vec3().abs() == axis)
                .map(|k| k as u8),
        }
    }

    /// Signed distance of a point from the plane.
    #[inline]
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p) - self.offset
    }

    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<f64> {
        let denom = self.normal.dot(ray.dir);
        // A ray parallel to the plane never meets it (0/0 or x/0 below).
        let t = -self.signed_distance(ray.origin) / denom;
        (t > 0.0 && t < t_max).then_some(t)
    }

    #[inline(always)]
    pub fn surface(&self, ray: &Ray, t: f64) -> SurfacePoint {
        let p = ray.at(t);
        SurfacePoint::flat(p - self.normal * self.signed_distance(p), self.normal)
    }
}
