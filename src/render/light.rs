use glam::{DVec2, DVec3};

use super::geometry::Parallelogram;
use super::scene_file::LightDesc;

/// The rectangular area light's geometry. It emits from the side `edge_u ×
/// edge_v` points to and is seen by camera and reflected rays as a
/// rectangle of its diffuse colour (its colours are shading parameters:
/// [`LightColours`](super::shading_params::LightColours)).
#[derive(Debug, Clone)]
pub struct AreaLight {
    pub shape: Parallelogram,
}

impl AreaLight {
    pub fn new(desc: &LightDesc) -> AreaLight {
        AreaLight {
            shape: Parallelogram::new(desc.corner.into(), desc.edge_u.into(), desc.edge_v.into()),
        }
    }

    /// Whether a point is on the emitting side (strictly in front of the
    /// light's plane); points behind or in the plane get no direct light.
    /// "In the plane" includes the rounding of the distance (a few ulps of
    /// the coordinates): otherwise a surface flush with a light that is not
    /// axis-aligned would be lit at random points.
    #[inline]
    pub fn illuminates(&self, p: DVec3) -> bool {
        let c = self.shape.corner;
        let magnitude = p.abs().max_element() + c.abs().max_element() + (p - c).abs().max_element();
        self.shape.signed_distance(p) > 64.0 * f64::EPSILON * magnitude
    }

    /// The report's "optimal" light point for a point `p` looking along
    /// `dir`: follow the ray to the light's plane, take the intersection's
    /// (a, b) coordinates by least squares and clamp them into \[0,1\]². If
    /// the intersection lies behind `p`, take the light's corner farthest
    /// from it, as the report does. A ray parallel to the plane meets it at
    /// infinity in its own direction: each coordinate whose direction
    /// component is positive clamps to 1, negative to 0, and zero keeps
    /// `p`'s own (clamped) coordinate — the exact limit of the finite case,
    /// with no offset and no NaN.
    ///
    /// Two corners equally far from the intersection behind `p` (within its
    /// rounding) are a tie the report leaves open. It is not rare: with the
    /// camera in the light's plane, every point of a face at right angles to
    /// that plane has the same intersection (the camera's mirror image), so
    /// a camera on a plane of symmetry of the light ties a whole region.
    /// The tie goes to the corner farther from `p`: the limit as the
    /// intersection moves towards `p`, which is where it goes when the
    /// camera leaves the plane on the light's dark side (the side that
    /// points in the plane count as, see [`AreaLight::illuminates`]). So
    /// the image is continuous as the camera comes down to the plane.
    pub fn nearest_point(&self, p: DVec3, dir: DVec3) -> DVec3 {
        let light = &self.shape;
        let denom = light.normal.dot(dir);
        let t = -light.signed_distance(p) / denom;
        let uv = if denom == 0.0 || !t.is_finite() {
            let along = light.uv_of_direction(dir);
            let own = light.uv(p).clamp(DVec2::ZERO, DVec2::ONE);
            let limit = |d: f64, own: f64| {
                if d > 0.0 {
                    1.0
                } else if d < 0.0 {
                    0.0
                } else {
                    own
                }
            };
            DVec2::new(limit(along.x, own.x), limit(along.y, own.y))
        } else if t >= 0.0 {
            light.uv(p + dir * t).clamp(DVec2::ZERO, DVec2::ONE)
        } else {
            let q = p + dir * t;
            let corners = [DVec2::ZERO, DVec2::X, DVec2::ONE, DVec2::Y];
            let d2 = corners.map(|c| (light.point(c) - q).length_squared());
            let far = d2.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            // The rounding of q (and of the corners): a few ulps of the
            // largest magnitude involved, times the distance.
            let reach = p.abs().max_element()
                + (dir * t).abs().max_element()
                + light.corner.abs().max_element()
                + light.edge_u.abs().max_element()
                + light.edge_v.abs().max_element();
            let tol = 256.0 * f64::EPSILON * reach * far.sqrt();
            let mut best = (0, f64::NEG_INFINITY);
            for (i, c) in corners.iter().enumerate() {
                if d2[i] >= far - tol {
                    let from_p = (light.point(*c) - p).length_squared();
                    if from_p >= best.1 {
                        best = (i, from_p);
                    }
                }
            }
            corners[best.0]
        };
        light.point(uv)
    }
}
