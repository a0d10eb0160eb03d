//! The triangle: the `triangle` object and every face of a `mesh`.
//!
//! Everything a primitive needs lives here: the f64 intersection of camera
//! and reflected rays (Möller–Trumbore, edges inclusive), the surface point
//! with its flat or smooth shading normal and the shadow-ray origin that
//! hides the shadow terminator, bounds, the f32 shadow-ray form relative to
//! a hit point (watertight) and the bounds in any other frame.

use glam::{DVec3, Vec3};

use super::{Aabb, Ray, SurfacePoint};

/// Unit vertex normals of a smooth triangle, oriented to the side of the
/// geometric normal.
#[derive(Debug, Clone)]
pub struct VertexNormals(pub [DVec3; 3]);

/// A flat, two-sided triangle `v0 + u·e1 + v·e2`, u, v ≥ 0, u + v ≤ 1,
/// optionally with vertex normals for smooth shading.
#[derive(Debug, Clone)]
pub struct Triangle {
    pub v0: DVec3,
    pub v1: DVec3,
    pub v2: DVec3,
    /// Unit geometric normal along `(v1 − v0) × (v2 − v0)`.
    pub normal: DVec3,
    /// Vertex normals (smooth shading), boxed so that flat triangles stay
    /// small.
    pub smooth: Option<Box<VertexNormals>>,
}

impl Triangle {
    /// A triangle is flat (it never meets a ray leaving its own surface) and
    /// convex (the directions from a point that meet it form a convex cone).
    pub const FLAT: bool = true;
    pub const CONVEX: bool = true;

    /// The triangle, or `None` if it is degenerate (zero area, or so thin
    /// that its normal is undefined in f64).
    pub fn new(v0: DVec3, v1: DVec3, v2: DVec3) -> Option<Triangle> {
        Triangle::face_normal(&[v0, v1, v2]).map(|normal| Triangle {
            v0,
            v1,
            v2,
            normal,
            smooth: None,
        })
    }

    /// Unit normal along `(v1 − v0) × (v2 − v0)`, or `None` for a
    /// degenerate triangle.
    #[inline]
    pub fn face_normal([v0, v1, v2]: &[DVec3; 3]) -> Option<DVec3> {
        let n = (*v1 - *v0).cross(*v2 - *v0);
        let len = n.length();
        if !(len > 0.0 && len.is_finite()) {
            return None;
        }
        let normal = n / len;
        normal.is_finite().then_some(normal)
    }

    /// With vertex normals (any length, not zero); normals that point
    /// against the geometric normal on average are flipped, so that the
    /// shading normal and the geometric one agree on the front side.
    pub fn with_normals(mut self, normals: [DVec3; 3]) -> Triangle {
        let mut n = normals.map(|n| n.normalize_or_zero());
        if n.iter().any(|n| *n == DVec3::ZERO || !n.is_finite()) {
            return self;
        }
        if n.iter().map(|n| n.dot(self.normal)).sum::<f64>() < 0.0 {
            n = n.map(|n| -n);
        }
        self.smooth = Some(Box::new(VertexNormals(n)));
        self
    }

    pub fn vertices(&self) -> [DVec3; 3] {
        [self.v0, self.v1, self.v2]
    }

    /// Möller–Trumbore in f64, edges inclusive, both sides.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<f64> {
        intersect(&self.vertices(), ray, t_max)
    }

    #[inline(always)]
    pub fn surface(&self, ray: &Ray, t: f64) -> SurfacePoint {
        surface(
            &self.vertices(),
            self.normal,
            self.smooth.as_ref().map(|n| &n.0),
            ray,
            t,
        )
    }

    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(&self.vertices()).padded()
    }

    /// Bounds of the vertices mapped by `f` (another frame).
    pub fn bounds_in(&self, f: impl Fn(DVec3) -> DVec3) -> Aabb {
        Aabb::from_points(&self.vertices().map(f))
    }

    /// The shadow-ray form seen from `p`, for rays no longer than `reach`.
    pub fn occluder(&self, p: DVec3, reach: f32) -> TriangleOccluder {
        TriangleOccluder::new(&self.vertices(), p, reach)
    }
}

/// Möller–Trumbore in f64 on the vertices `v`, edges inclusive, both sides
/// (for `triangle` objects and mesh faces alike).
#[inline(always)]
pub fn intersect(v: &[DVec3; 3], ray: &Ray, t_max: f64) -> Option<f64> {
    let e1 = v[1] - v[0];
    let e2 = v[2] - v[0];
    let p = ray.dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let s = ray.origin - v[0];
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = ray.dir.dot(q) * inv;
    if !(v >= 0.0 && u + v <= 1.0) {
        return None;
    }
    let t = e2.dot(q) * inv;
    (t > 0.0 && t < t_max).then_some(t)
}

/// Barycentric weights (w0, w1, w2) of a point in the plane of `v`.
#[inline]
fn barycentric(v: &[DVec3; 3], p: DVec3) -> [f64; 3] {
    let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
    let n = e1.cross(e2);
    let inv = 1.0 / n.length_squared();
    let d = p - v[0];
    let w1 = d.cross(e2).dot(n) * inv;
    let w2 = e1.cross(d).dot(n) * inv;
    [1.0 - w1 - w2, w1, w2]
}

/// The surface point of a hit at `t` on the triangle `v` with unit normal
/// `normal` and, when smooth, unit vertex normals on the normal's side.
#[inline(always)]
pub fn surface(
    v: &[DVec3; 3],
    normal: DVec3,
    smooth: Option<&[DVec3; 3]>,
    ray: &Ray,
    t: f64,
) -> SurfacePoint {
    let hit = ray.at(t);
    let point = hit - normal * normal.dot(hit - v[0]);
    let Some(vn) = smooth else {
        return SurfacePoint {
            point,
            normal,
            shading: normal,
            shadow_offset: DVec3::ZERO,
        };
    };
    let w = barycentric(v, point).map(|w| w.clamp(0.0, 1.0));
    let shading = (vn[0] * w[0] + vn[1] * w[1] + vn[2] * w[2]).normalize_or(normal);
    // Hanika, "Hacking the shadow terminator" (Ray Tracing Gems II,
    // ch. 4): the point lifted onto the curved surface the vertex
    // normals describe (the barycentric blend of its projections onto
    // the three tangent planes, each only lifted, never lowered), on the
    // side the ray came from. Shadow rays start there.
    let side = if normal.dot(ray.dir) > 0.0 { -1.0 } else { 1.0 };
    let mut offset = DVec3::ZERO;
    for k in 0..3 {
        let n = vn[k] * side;
        let d = (point - v[k]).dot(n).min(0.0);
        offset -= n * (d * w[k]);
    }
    // Never below the flat surface.
    if !offset.is_finite() || offset.dot(normal * side) <= 0.0 {
        offset = DVec3::ZERO;
    }
    SurfacePoint {
        point,
        normal,
        shading,
        shadow_offset: offset,
    }
}

/// The rounding bound of an f32 edge test, relative to the squared
/// distance of the farthest vertex and the ray's length (see
/// [`TriangleOccluder::new`]).
const EDGE_ROUNDING: f32 = 1.0 / (1 << 19) as f32;

/// A triangle seen from a hit point (the origin), in f32: the normals of
/// the three planes through the origin and an edge, and the triangle's own
/// plane.
///
/// Watertight: a ray meets the triangle's cone iff `d` lies on the same
/// side of all three edge planes (zero counts as either side). Two
/// triangles that share an edge share its vertices, so the edge plane's
/// normal of one is exactly the negation of the other's (`b × a` is `−(a ×
/// b)` in floating point too): no ray slips between them.
///
/// Exact at the edges: where an f32 edge test lies within its rounding
/// bound of zero, its sign may not be the true one, and the edges are
/// decided again in f64 from the unrounded vertices (the f32 direction is
/// the ray): a mesh blocks grazing rays as its exact surface does. The
/// shared-edge argument holds in f64 as well.
#[derive(Debug, Clone, Copy)]
pub struct TriangleOccluder {
    ab: Vec3,
    bc: Vec3,
    ca: Vec3,
    n: Vec3,
    /// `n · a`: the plane is met at t = dist / (n · d).
    dist: f32,
    /// The rounding bound of the edge tests.
    unsure: f32,
    /// The vertices relative to the hit point, unrounded.
    exact: [DVec3; 3],
}

impl TriangleOccluder {
    /// The shadow-ray form of the triangle `v` seen from `p`, for rays no
    /// longer than `reach`.
    #[inline(always)]
    pub fn new(v: &[DVec3; 3], p: DVec3, reach: f32) -> TriangleOccluder {
        let exact = v.map(|v| v - p);
        let [a, b, c] = exact.map(|v| v.as_vec3());
        let n = (b - a).cross(c - a);
        // |ab · d| is off by at most 7.2·2⁻²⁴·|a|₁|b|₁|d|₁ from the exact value
        // of the unrounded vertices (their rounding, the cross product's and
        // the dot product's), and |d|₁ ≤ √3·reach: 2⁻¹⁹ leaves room for the
        // rounding of the bound itself. One bound for the three edges, from
        // the farthest vertex: a lane then compares the nearest edge only.
        let far = a
            .abs()
            .element_sum()
            .max(b.abs().element_sum())
            .max(c.abs().element_sum());
        TriangleOccluder {
            ab: a.cross(b),
            bc: b.cross(c),
            ca: c.cross(a),
            n,
            dist: n.dot(a),
            unsure: far * far * (reach * EDGE_ROUNDING),
            exact,
        }
    }

    /// Whether the ray `t·(x, y, z)` meets the triangle for t in (0, end).
    #[inline(always)]
    pub fn blocks(&self, x: f32, y: f32, z: f32, end: f32) -> bool {
        match self.blocks_f32(x, y, z, end) {
            (_, true) => self.blocks_exact(x, y, z),
            (blocked, false) => blocked,
        }
    }

    /// The f32 test: (blocked, unsure). An unsure ray meets the plane within
    /// (0, end) and lies within rounding of an edge plane: it is blocked iff
    /// [`blocks_exact`](Self::blocks_exact) says so; `blocked` is then false.
    /// Lane arithmetic without branches, for the vector loops.
    #[inline(always)]
    pub fn blocks_f32(&self, x: f32, y: f32, z: f32, end: f32) -> (bool, bool) {
        let e = |n: Vec3| n.x * x + n.y * y + n.z * z;
        let (e0, e1, e2) = (e(self.ab), e(self.bc), e(self.ca));
        let inside = (e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0) || (e0 <= 0.0 && e1 <= 0.0 && e2 <= 0.0);
        let t = self.dist / e(self.n);
        let on_plane = t > 0.0 && t < end;
        let unsure = on_plane & (e0.abs().min(e1.abs()).min(e2.abs()) <= self.unsure);
        (inside & on_plane & !unsure, unsure)
    }

    /// The edges decided in f64, for a ray that [`blocks_f32`]
    /// (Self::blocks_f32) found unsure.
    #[inline(always)]
    pub fn blocks_exact(&self, x: f32, y: f32, z: f32) -> bool {
        exact_edges(&self.exact, x, y, z)
    }
}

/// [`TriangleOccluder::blocks_exact`] out of line, given the vertices
/// alone: only they are then kept in memory for the call, and the f32
/// fields of the caller's occluder stay in registers.
#[cold]
#[inline(never)]
fn exact_edges(&[a, b, c]: &[DVec3; 3], x: f32, y: f32, z: f32) -> bool {
    let d = DVec3::new(x as f64, y as f64, z as f64);
    let (e0, e1, e2) = (a.cross(b).dot(d), b.cross(c).dot(d), c.cross(a).dot(d));
    (e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0) || (e0 <= 0.0 && e1 <= 0.0 && e2 <= 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> Triangle {
        Triangle::new(
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
        )
        .unwrap()
    }

    #[test]
    fn hits_inside_misses_outside_from_both_sides() {
        let t = tri();
        for dz in [1.0, -1.0] {
            let r = Ray::new(DVec3::new(0.5, 0.5, -3.0 * dz), DVec3::new(0.0, 0.0, dz));
            assert_eq!(t.intersect(&r, f64::INFINITY), Some(3.0));
            let r = Ray::new(DVec3::new(1.5, 1.5, -3.0 * dz), DVec3::new(0.0, 0.0, dz));
            assert_eq!(t.intersect(&r, f64::INFINITY), None);
        }
        assert_eq!(t.normal, DVec3::Z);
    }

    #[test]
    fn degenerate_triangles_are_refused() {
        let p = DVec3::new(1.0, 2.0, 3.0);
        assert!(Triangle::new(p, p, DVec3::ZERO).is_none());
        assert!(Triangle::new(DVec3::ZERO, p, p * 2.0).is_none());
        assert!(Triangle::new(DVec3::ZERO, p, DVec3::splat(f64::NAN)).is_none());
    }

    #[test]
    fn occluder_agrees_with_the_f64_test() {
        let t = tri();
        let p = DVec3::new(0.3, 0.7, -2.0);
        let occ = t.occluder(p, 6.0);
        for i in -30..30 {
            for j in -30..30 {
                let target = DVec3::new(i as f64 * 0.1, j as f64 * 0.1 + 0.013, 1.0);
                let d = target - p;
                let f64_hit = t.intersect(&Ray::new(p, d), 1.0).is_some();
                let d = d.as_vec3();
                assert_eq!(occ.blocks(d.x, d.y, d.z, 1.0), f64_hit, "{target}");
            }
        }
    }

    /// Rays through a shared edge are blocked by one of the two triangles.
    #[test]
    fn shared_edges_are_watertight() {
        let a = DVec3::new(-1.0, -1.0, 0.3);
        let b = DVec3::new(1.3, 0.9, -0.2);
        let t1 = Triangle::new(a, b, DVec3::new(-1.0, 1.0, 0.1)).unwrap();
        let t2 = Triangle::new(b, a, DVec3::new(1.0, -1.0, 0.0)).unwrap();
        let p = DVec3::new(0.1, 0.2, -3.0);
        let (o1, o2) = (t1.occluder(p, 6.0), t2.occluder(p, 6.0));
        // Away from the ends: around a vertex the two triangles cover only
        // a wedge, which a ray rounded off the edge may miss.
        for k in 10..=9_990 {
            let s = k as f64 / 10_000.0;
            let on_edge = a + (b - a) * s;
            let d = ((on_edge - p) * 1.5).as_vec3();
            assert!(
                o1.blocks(d.x, d.y, d.z, 1.0) || o2.blocks(d.x, d.y, d.z, 1.0),
                "{s}"
            );
        }
    }

    #[test]
    fn smooth_normals_lift_the_shadow_origin_only_upwards() {
        // Normals splayed outwards, as on a coarse sphere.
        let t = tri().with_normals([
            DVec3::new(-1.0, -1.0, 1.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(0.0, 1.0, 1.0),
        ]);
        let r = Ray::new(DVec3::new(0.5, 0.5, 3.0), DVec3::new(0.0, 0.0, -1.0));
        let s = t.surface(&r, 3.0);
        assert!(s.shadow_offset.z > 0.0, "{:?}", s.shadow_offset);
        assert!(s.shading.z > 0.0 && (s.shading.length() - 1.0).abs() < 1e-12);
        // From below the surface is concave: nothing is lifted.
        let r = Ray::new(DVec3::new(0.5, 0.5, -3.0), DVec3::new(0.0, 0.0, 1.0));
        assert_eq!(t.surface(&r, 3.0).shadow_offset, DVec3::ZERO);
        // Normals pulled inwards: lifted on the lower side.
        let inward = tri().with_normals([
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(-1.0, 0.0, 1.0),
            DVec3::new(0.0, -1.0, 1.0),
        ]);
        assert!(inward.surface(&r, 3.0).shadow_offset.z < 0.0);
        // Normals equal to the face normal: no offset.
        let flat = tri().with_normals([DVec3::Z; 3]);
        assert_eq!(flat.surface(&r, 3.0).shadow_offset, DVec3::ZERO);
    }
}
