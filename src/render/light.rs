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
            *corners
                .iter()
                .max_by(|a, b| {
                    let da = (light.point(**a) - q).length_squared();
                    let db = (light.point(**b) - q).length_squared();
                    da.total_cmp(&db)
                })
                .expect("four corners")
        };
        light.point(uv)
    }
}
