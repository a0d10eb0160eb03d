//! Where the shadow rays of a batch of hit points can go: every ray runs
//! from a ball around the hit points to a ball around their light points,
//! so it stays within the larger radius of the segment between the two
//! centres. An object clear of that capsule by a margin far beyond the f32
//! tests' rounding blocks none of the batch's rays, and [`HitLanes`]
//! leaves it out for the whole batch: the same bits, without its tests.
//!
//! [`HitLanes`]: super::HitLanes

use glam::{DVec2, DVec3};

use crate::render::geometry::{Cuboid, Parallelogram};

/// The margin of a ball, relative to the distances involved (ray lengths
/// and the object's distance from the hits): the f32 tests err by a few
/// 2⁻²⁴ of those, and a sphere missed by a distance m leaves at least m²
/// between the squares its test compares (so m = 4·10⁻³ leaves 1.6·10⁻⁵
/// relative, some 60 times that rounding).
const MARGIN: f64 = 4e-3;

/// The margin of a plane, relative to the same distances: its test's
/// signed distances err by a few 2⁻²⁴ of them (50 times less than this),
/// and a light 10⁻² below a ceiling 8 above the floor is clear of it.
const PLANE_MARGIN: f64 = 1e-5;

/// A ball around a batch's hit points and one around its light points.
#[derive(Debug, Clone, Copy)]
pub(super) struct BatchReach {
    hits: DVec3,
    hits_radius: f64,
    light: DVec3,
    light_radius: f64,
    /// The capsule: the larger radius, the segment from `hits` to
    /// `light`, its squared length, and the longest ray's length bound.
    radius: f64,
    along: DVec3,
    along2: f64,
    length: f64,
}

impl BatchReach {
    /// The balls of hit points within the box `points` (its lowest and
    /// highest corners) and of light points whose offsets along `light`'s
    /// edges lie within the box `offsets`.
    pub(super) fn new(
        points: (DVec3, DVec3),
        offsets: (DVec2, DVec2),
        light: &Parallelogram,
    ) -> BatchReach {
        let (lo, hi) = points;
        let (a, b) = offsets;
        let mid = (a + b) * 0.5;
        let hits = (lo + hi) * 0.5;
        let hits_radius = (hi - lo).length() * 0.5;
        let light_centre = light.corner + light.edge_u * mid.x + light.edge_v * mid.y;
        let light_radius =
            0.5 * ((b.x - a.x) * light.edge_u.length() + (b.y - a.y) * light.edge_v.length());
        let along = light_centre - hits;
        BatchReach {
            hits,
            hits_radius,
            light: light_centre,
            light_radius,
            radius: hits_radius.max(light_radius),
            along,
            along2: along.length_squared(),
            length: along.length() + hits_radius + light_radius,
        }
    }

    /// True if the ball of `centre` and `radius` is clear of every ray of
    /// the batch, by the margin; false whenever unsure (NaN included).
    pub(super) fn misses_ball(&self, centre: DVec3, radius: f64) -> bool {
        let to_centre = centre - self.hits;
        let s = if self.along2 > 0.0 {
            (to_centre.dot(self.along) / self.along2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let distance = (to_centre - self.along * s).length();
        let margin = MARGIN * (self.length + to_centre.length() + radius);
        distance > radius + self.radius + margin
    }

    /// True if box `c` is clear of every ray of the batch, by the margin:
    /// some axis separates it from the capsule (the box's three axes and
    /// those at right angles to both the capsule's segment and one of
    /// them, the axes that separate a segment from a box). False whenever
    /// unsure.
    pub(super) fn misses_box(&self, c: &Cuboid) -> bool {
        let (start, end) = (
            c.to_local(self.hits - c.centre),
            c.to_local(self.light - c.centre),
        );
        let half = c.half;
        let mut gap = f64::NEG_INFINITY;
        for i in 0..3 {
            let (lo, hi) = (start[i].min(end[i]), start[i].max(end[i]));
            gap = gap.max(lo - half[i]).max(-half[i] - hi);
        }
        let along = end - start;
        for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
            // The segment projects to one value on an axis at right angles
            // to it; the box to [−r, r].
            let normal = along.cross(axis);
            let length = normal.length();
            if length > 0.0 {
                let r = half.dot(normal.abs());
                gap = gap.max((start.dot(normal).abs() - r) / length);
            }
        }
        let margin = MARGIN * (self.length + start.length() + half.length());
        gap > self.radius + margin
    }

    /// For the plane of unit `normal` through the points x with `normal ·
    /// x = offset`: the side (±1) where the whole ball of light points lies
    /// clear of the plane, beyond the margin; None if it does not. A ray
    /// from a hit point on that side (or in the plane) then does not cross
    /// the plane: its test's end point lies on that side by at least the
    /// margin, less its rounding.
    pub(super) fn plane_side(&self, normal: DVec3, offset: f64) -> Option<f64> {
        let light = normal.dot(self.light) - offset;
        let margin = PLANE_MARGIN * (self.length + light.abs());
        (light.abs() > self.light_radius + margin).then(|| light.signum())
    }

    /// Whether the whole ball of hit points lies on `side` of the plane
    /// (as [`Self::plane_side`] takes it), clear of its rounding.
    pub(super) fn hits_on_side(&self, normal: DVec3, offset: f64, side: f64) -> bool {
        let hits = side * (normal.dot(self.hits) - offset);
        hits > self.hits_radius + PLANE_MARGIN * (self.length + hits.abs())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::rng::Rng;

    fn light() -> Parallelogram {
        Parallelogram::new(
            DVec3::new(-1.0, 7.99, -1.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 2.0),
        )
    }

    /// Whether the segment from p to q comes within `radius` of `centre`.
    fn segment_meets_ball(p: DVec3, q: DVec3, centre: DVec3, radius: f64) -> bool {
        let d = q - p;
        let s = ((centre - p).dot(d) / d.length_squared()).clamp(0.0, 1.0);
        (p + d * s - centre).length() <= radius
    }

    /// Random batches of hit points and light points, random balls and
    /// planes: wherever the reach says an object is missed, no ray of the
    /// batch comes near it (each ray checked); and it does say so often.
    #[test]
    fn what_a_batch_misses_no_ray_of_it_meets() {
        let light = light();
        let mut rng = Rng::new(3);
        let mut r = |lo: f64, hi: f64| lo + (hi - lo) * rng.next_f64();
        let (mut balls_missed, mut planes_missed) = (0, 0);
        let (mut boxes_missed, mut boxes_kept) = (0, 0);
        for _ in 0..2000 {
            let spread = r(0.0, 2.0);
            let base = DVec3::new(r(-5.0, 5.0), r(0.0, 7.0), r(-5.0, 5.0));
            let points: Vec<DVec3> = (0..16)
                .map(|_| base + DVec3::new(r(0.0, spread), r(0.0, spread), r(0.0, spread)))
                .collect();
            let width = r(0.0, 1.0);
            let (a0, b0) = (r(0.0, 1.0 - width), r(0.0, 1.0 - width));
            let offsets: Vec<DVec2> = (0..16)
                .map(|_| DVec2::new(a0 + r(0.0, width), b0 + r(0.0, width)))
                .collect();
            let lo = points.iter().fold(DVec3::INFINITY, |m, &p| m.min(p));
            let hi = points.iter().fold(DVec3::NEG_INFINITY, |m, &p| m.max(p));
            let alo = offsets.iter().fold(DVec2::INFINITY, |m, &p| m.min(p));
            let ahi = offsets.iter().fold(DVec2::NEG_INFINITY, |m, &p| m.max(p));
            let reach = BatchReach::new((lo, hi), (alo, ahi), &light);
            let rays: Vec<(DVec3, DVec3)> = points
                .iter()
                .zip(&offsets)
                .map(|(&p, o)| (p, light.corner + light.edge_u * o.x + light.edge_v * o.y))
                .collect();

            let centre = DVec3::new(r(-5.0, 5.0), r(0.0, 8.0), r(-5.0, 5.0));
            let radius = r(0.01, 1.5);
            if reach.misses_ball(centre, radius) {
                balls_missed += 1;
                for &(p, q) in &rays {
                    assert!(!segment_meets_ball(p, q, centre, radius * 1.001));
                }
            }

            let min = DVec3::new(r(-5.0, 4.0), r(0.0, 7.0), r(-5.0, 4.0));
            let size = DVec3::new(r(0.01, 1.0), r(0.01, 4.0), r(0.01, 1.0));
            let angle = r(0.0, 360.0);
            let translate = DVec3::new(r(-0.5, 0.5), 0.0, r(-0.5, 0.5));
            let cuboid = Cuboid::new(min, min + size, angle, translate);
            if reach.misses_box(&cuboid) {
                boxes_missed += 1;
                // Every ray, and each grown sideways by the margin's worth.
                for &(p, q) in &rays {
                    let origin = cuboid.to_local(p - cuboid.centre);
                    assert!(!cuboid.segment_meets(origin, q - p, 1.0));
                    for shift in [
                        DVec3::X,
                        DVec3::Y,
                        DVec3::Z,
                        -DVec3::X,
                        -DVec3::Y,
                        -DVec3::Z,
                    ] {
                        let o = cuboid.to_local(p + shift * 1e-3 - cuboid.centre);
                        assert!(!cuboid.segment_meets(o, q - p, 1.0));
                    }
                }
            } else {
                boxes_kept += 1;
            }

            let normal = DVec3::new(r(-1.0, 1.0), r(-1.0, 1.0), r(-1.0, 1.0)).normalize();
            let offset = normal.dot(DVec3::new(r(-5.0, 5.0), r(0.0, 8.0), r(-5.0, 5.0)));
            if let Some(side) = reach.plane_side(normal, offset) {
                let all_on_side = reach.hits_on_side(normal, offset, side);
                for &(p, q) in &rays {
                    assert!(side * (normal.dot(q) - offset) > 0.0);
                    assert!(!all_on_side || side * (normal.dot(p) - offset) > 0.0);
                    if side * (normal.dot(p) - offset) > 0.0 {
                        planes_missed += 1;
                    }
                }
            }
        }
        assert!(balls_missed > 200, "{balls_missed} balls missed");
        assert!(
            boxes_missed > 200 && boxes_kept > 200,
            "{boxes_missed} boxes missed, {boxes_kept} kept"
        );
        assert!(planes_missed > 2000, "{planes_missed} rays clear of planes");
    }

    /// A batch of one hit point and one light point reaches along its one
    /// ray: a ball just beside it is not missed, one well clear of it is.
    #[test]
    fn a_lone_ray_s_reach_is_the_ray_and_its_margin() {
        let light = light();
        let p = DVec3::new(0.0, 0.0, 0.0);
        let reach = BatchReach::new((p, p), (DVec2::splat(0.5), DVec2::splat(0.5)), &light);
        // The ray runs up the y axis to (0, 7.99, 0).
        assert!(!reach.misses_ball(DVec3::new(1.0, 4.0, 0.0), 0.99));
        assert!(!reach.misses_ball(DVec3::new(1.0, 4.0, 0.0), 0.95));
        assert!(reach.misses_ball(DVec3::new(1.0, 4.0, 0.0), 0.9));
        // Behind the hit point, beyond the light: clear, as far as the margin.
        assert!(reach.misses_ball(DVec3::new(0.0, -1.0, 0.0), 0.9));
        assert!(!reach.misses_ball(DVec3::new(0.0, -1.0, 0.0), 0.99));
        assert!(!reach.misses_ball(DVec3::new(0.0, f64::NAN, 0.0), 0.1));
        // The ceiling just above the light, the floor the point lies on.
        assert_eq!(reach.plane_side(DVec3::NEG_Y, -8.0), Some(1.0));
        assert_eq!(reach.plane_side(DVec3::Y, 0.0), Some(1.0));
        assert_eq!(reach.plane_side(DVec3::NEG_Y, -7.99001), None);
    }
}
