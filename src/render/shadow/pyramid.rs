//! The pyramid from a hit point to the light, for culling occluders.

use glam::DVec3;

use crate::render::geometry::Aabb;

/// The pyramid spanned by a hit point and the light rectangle, as five
/// planes `n · x <= d` (four sides and the light's plane), for culling.
pub(super) struct ShadowPyramid {
    /// Not normalized: a sphere test takes their lengths (most hit points
    /// test no sphere, so they are not computed up front).
    planes: [(DVec3, f64); 5],
    bounds: Aabb,
}

impl ShadowPyramid {
    #[inline(always)]
    pub(super) fn new(
        p: DVec3,
        corners: &[DVec3; 4],
        light_normal: DVec3,
        light_centre: DVec3,
    ) -> ShadowPyramid {
        let mut planes = [(DVec3::ZERO, 0.0); 5];
        for i in 0..4 {
            let mut n = (corners[i] - p).cross(corners[(i + 1) % 4] - p);
            if n.dot(light_centre - p) > 0.0 {
                n = -n;
            }
            planes[i] = (n, n.dot(p));
        }
        planes[4] = (-light_normal, -light_normal.dot(corners[0]));
        ShadowPyramid {
            planes,
            bounds: Aabb::from_points(corners).grow(p),
        }
    }

    /// Conservative: false only if the sphere certainly misses the pyramid.
    #[inline(always)]
    pub(super) fn may_overlap_sphere(&self, centre: DVec3, radius: f64) -> bool {
        // A centre on the inner side passes without the plane's length (the
        // right-hand side is never negative): the same answers.
        self.planes.iter().all(|&(n, d)| {
            let outside = n.dot(centre) - d;
            outside <= 0.0 || outside <= radius * n.length() * (1.0 + 1e-9)
        })
    }

    /// Conservative: false only if the box certainly misses the pyramid.
    #[inline(always)]
    pub(super) fn may_overlap(&self, b: &Aabb) -> bool {
        if b.min.cmpgt(self.bounds.max).any() || b.max.cmplt(self.bounds.min).any() {
            return false;
        }
        self.planes.iter().all(|&(n, d)| {
            // The box corner furthest against the normal.
            let x = DVec3::select(n.cmpge(DVec3::ZERO), b.min, b.max);
            n.dot(x) <= d
        })
    }
}
