use glam::DVec3;

use super::{Aabb, Ray, SurfacePoint};

/// The `box` object: an axis-aligned box rotated about the y axis through
/// its centre, then translated. Intersections run in the box's own frame.
#[derive(Debug, Clone, Copy)]
pub struct Cuboid {
    /// World position of the box's centre.
    pub centre: DVec3,
    /// Half the box's size along its own axes.
    pub half: DVec3,
    /// cos and sin of the rotation about y.
    pub cos: f64,
    pub sin: f64,
}

impl Cuboid {
    /// See [`super::Shape::flat`] and [`super::Shape::convex`]: convex.
    pub const FLAT: bool = false;
    pub const CONVEX: bool = true;

    /// The faces as indices of [`Self::corners`], each counter-clockwise
    /// seen from outside.
    pub const FACES: [[usize; 4]; 6] = [
        [0, 2, 6, 4],
        [1, 5, 7, 3],
        [0, 4, 5, 1],
        [2, 3, 7, 6],
        [0, 1, 3, 2],
        [4, 6, 7, 5],
    ];

    /// The corners in world space; bits 0, 1, 2 of the index pick the high
    /// side along the box's x, y, z.
    pub fn corners(&self) -> [DVec3; 8] {
        std::array::from_fn(|i| {
            let side = |bit: usize| if i & bit == 0 { -1.0 } else { 1.0 };
            self.centre + self.to_world(self.half * DVec3::new(side(1), side(2), side(4)))
        })
    }

    pub fn new(min: DVec3, max: DVec3, rotate_y_deg: f64, translate: DVec3) -> Self {
        let (sin, cos) = rotate_y_deg.to_radians().sin_cos();
        Cuboid {
            centre: (min + max) * 0.5 + translate,
            half: (max - min) * 0.5,
            cos,
            sin,
        }
    }

    /// World → box frame, for directions.
    #[inline]
    pub fn to_local(&self, v: DVec3) -> DVec3 {
        DVec3::new(
            v.x * self.cos - v.z * self.sin,
            v.y,
            v.x * self.sin + v.z * self.cos,
        )
    }

    /// Box frame → world, for directions.
    #[inline]
    pub fn to_world(&self, v: DVec3) -> DVec3 {
        DVec3::new(
            v.x * self.cos + v.z * self.sin,
            v.y,
            -v.x * self.sin + v.z * self.cos,
        )
    }

    /// Entry and exit distances of the ray's line through the slabs.
    #[inline]
    fn slabs(&self, ray: &Ray) -> (f64, f64) {
        self.local_slabs(self.to_local(ray.origin - self.centre), ray.dir)
    }

    /// [`Self::slabs`] of the line `origin + t·dir`, `origin` in the box's
    /// frame relative to its centre, `dir` in world space.
    #[inline]
    fn local_slabs(&self, origin: DVec3, dir: DVec3) -> (f64, f64) {
        let inv = self.to_local(dir).recip();
        let t0 = (-self.half - origin) * inv;
        let t1 = (self.half - origin) * inv;
        // f64::min/max drop a NaN (0·∞ for a ray in a face's plane).
        (t0.min(t1).max_element(), t0.max(t1).min_element())
    }

    /// Whether the segment `t·d`, t in (0, end), from `origin` (in the
    /// box's frame, relative to its centre) meets the closed box: the f64
    /// decision of the shadow test for a ray its f32 form is unsure of.
    #[cold]
    #[inline(never)]
    pub fn segment_meets(&self, origin: DVec3, d: DVec3, end: f64) -> bool {
        let (near, far) = self.local_slabs(origin, d);
        let (near, far) = (near.max(0.0), far.min(end));
        near <= far && far > 0.0 && near < end
    }

    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<f64> {
        let (near, far) = self.slabs(ray);
        if near > far {
            return None;
        }
        super::first_in_range(near, far, t_max)
    }

    #[inline(always)]
    pub fn surface(&self, ray: &Ray, t: f64) -> SurfacePoint {
        let mut local = self.to_local(ray.at(t) - self.centre);
        // The face is the axis where the point is relatively closest to the
        // slab; snap it onto the face exactly.
        let rel = local.abs() / self.half.max(DVec3::splat(f64::MIN_POSITIVE));
        let axis = if rel.x >= rel.y && rel.x >= rel.z {
            0
        } else if rel.y >= rel.z {
            1
        } else {
            2
        };
        let sign = if local[axis] >= 0.0 { 1.0 } else { -1.0 };
        local[axis] = sign * self.half[axis];
        let mut n = DVec3::ZERO;
        n[axis] = sign;
        SurfacePoint::flat(self.centre + self.to_world(local), self.to_world(n))
    }

    pub fn bounds(&self) -> Aabb {
        let h = self.half;
        let ext = DVec3::new(
            (h.x * self.cos).abs() + (h.z * self.sin).abs(),
            h.y,
            (h.x * self.sin).abs() + (h.z * self.cos).abs(),
        );
        Aabb::new(self.centre - ext, self.centre + ext).padded()
    }
}
