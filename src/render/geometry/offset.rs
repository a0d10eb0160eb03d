use glam::DVec3;

/// Origin for a ray leaving a surface at `point` to the side `normal`
/// points to, far enough off the surface that rounding in the hit point can
/// not make the ray meet the same surface again at t ≈ 0.
///
/// After Wächter & Binder ("A Fast and Robust Method for Avoiding
/// Self-Intersection", Ray Tracing Gems ch. 6): the offset scales with the
/// magnitude of the point's coordinates, since that is what rounding error
/// scales with, instead of a fixed epsilon that fails at other scales. Hit
/// points here are re-projected onto their surface in f64, so their error
/// is a few ulps of the largest coordinate; the offset is 2¹² ulps (about
/// 1e-12 relative). Near the origin the floor `scene_scale · 2⁻⁴⁰` takes
/// over, as W&B's fixed offset does inside their `origin` radius, but
/// relative to the scene so that it also holds for tiny scenes.
#[inline]
pub fn spawn_origin(point: DVec3, normal: DVec3, scene_scale: f64) -> DVec3 {
    const RELATIVE: f64 = 4096.0 * f64::EPSILON;
    let magnitude = point.abs().max_element().max(scene_scale * 2f64.powi(-40));
    point + normal * (magnitude * RELATIVE)
}
