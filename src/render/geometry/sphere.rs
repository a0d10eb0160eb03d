use glam::DVec3;

use super::{Aabb, Ray, SurfacePoint};

#[derive(Debug, Clone)]
pub struct Sphere {
    pub centre: DVec3,
    pub radius: f64,
}

impl Sphere {
    /// See [`super::Shape::flat`] and [`super::Shape::convex`]: convex.
    pub const FLAT: bool = false;
    pub const CONVEX: bool = true;

    /// Nearest t in (0, t_max). Uses the discriminant form of Haines et al.
    /// ("Precision Improvements for Ray/Sphere Intersection", Ray Tracing
    /// Gems ch. 7), which stays accurate for spheres far from the origin or
    /// small against their distance. `ray.dir` must be unit length.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<f64> {
        let f = ray.origin - self.centre;
        let b = -f.dot(ray.dir);
        let r2 = self.radius * self.radius;
        let l = f + ray.dir * b;
        let disc = r2 - l.length_squared();
        if disc < 0.0 {
            return None;
        }
        let c = f.length_squared() - r2;
        let q = b + b.signum() * disc.sqrt();
        let (t0, t1) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q) };
        let (near, far) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
        super::first_in_range(near, far, t_max)
    }

    #[inline(always)]
    pub fn surface(&self, ray: &Ray, t: f64) -> SurfacePoint {
        let normal = (ray.at(t) - self.centre).normalize();
        SurfacePoint::flat(self.centre + normal * self.radius, normal)
    }

    pub fn bounds(&self) -> Aabb {
        Aabb::new(
            self.centre - DVec3::splat(self.radius),
            self.centre + DVec3::splat(self.radius),
        )
        .padded()
    }
}
