//! The light's own frame, and a BVH of the occluders built in it.
//!
//! Seen from a hit point p, a shadow ray is fixed by where it ends on the
//! light. In a frame whose z axis is the light's normal, the rays through
//! an axis-aligned box end inside a rectangle of the light's plane that is
//! cheap to bound (see [`LightFrame::footprint`]). Testing that rectangle
//! against the light points of a packet tells which rays can meet the box:
//! the packet traversal in `packet.rs` descends a node only with those
//! rays, and stops following a ray once it is blocked. The work per hit
//! point then follows the rays still in flight rather than every object
//! inside the shadow pyramid.

use glam::DVec3;

use crate::render::geometry::{Aabb, Bvh, Bvh4, Node4, Primitive, Shape};
use crate::render::light::AreaLight;

/// An orthonormal frame with its origin at the light's corner, x along
/// `edge_u`, z along the light's normal (towards the lit side).
#[derive(Debug, Clone)]
pub struct LightFrame {
    origin: DVec3,
    axes: [DVec3; 3],
    /// The light's edges in this frame: `edge_u = (u_x, 0, 0)`,
    /// `edge_v = (v_x, v_y, 0)`.
    u_x: f64,
    v_x: f64,
    v_y: f64,
}

impl LightFrame {
    pub fn new(light: &AreaLight) -> LightFrame {
        let shape = &light.shape;
        let z = shape.normal;
        let x = shape.edge_u.normalize();
        let y = z.cross(x);
        LightFrame {
            origin: shape.corner,
            axes: [x, y, z],
            u_x: shape.edge_u.length(),
            v_x: shape.edge_v.dot(x),
            v_y: shape.edge_v.dot(y),
        }
    }

    /// A point in this frame.
    #[inline]
    pub fn local(&self, p: DVec3) -> DVec3 {
        let d = p - self.origin;
        DVec3::new(
            d.dot(self.axes[0]),
            d.dot(self.axes[1]),
            d.dot(self.axes[2]),
        )
    }

    /// The light point with coordinates (a, b), as (x, y) in the light's
    /// plane of this frame.
    #[inline]
    pub fn light_point(&self, a: f64, b: f64) -> [f64; 2] {
        [a * self.u_x + b * self.v_x, b * self.v_y]
    }

    /// Bounds of a primitive in this frame (conservative: padded for
    /// rounding). Inlined: the tree builds call it for every face, from
    /// their own code units.
    #[inline]
    pub fn bounds(&self, prim: Primitive) -> Option<Aabb> {
        let shape = match prim {
            Primitive::Shape(s) => s,
            Primitive::Face { meshes, face } => {
                let b = Aabb::from_points(&meshes.vertices(face).map(|v| self.local(v)));
                return Some(Self::pad(b));
            }
        };
        let b = match shape {
            Shape::Plane(_) => return None,
            Shape::Sphere(s) => {
                let c = self.local(s.centre);
                Aabb::new(c - s.radius, c + s.radius)
            }
            Shape::Parallelogram(r) => Aabb::from_points(&r.corners().map(|c| self.local(c))),
            Shape::Cuboid(c) => {
                let h = c.half;
                let corners: [DVec3; 8] = std::array::from_fn(|i| {
                    let s = DVec3::new(
                        if i & 1 == 0 { -1.0 } else { 1.0 },
                        if i & 2 == 0 { -1.0 } else { 1.0 },
                        if i & 4 == 0 { -1.0 } else { 1.0 },
                    );
                    self.local(c.centre + c.to_world(h * s))
                });
                Aabb::from_points(&corners)
            }
            Shape::Triangle(t) => t.bounds_in(|v| self.local(v)),
        };
        Some(Self::pad(b))
    }

    /// Rounding of the frame change is ~1e-16 relative; pad by far more.
    #[inline]
    fn pad(b: Aabb) -> Aabb {
        let pad = (b.max.abs().max(b.min.abs()).max_element() + b.extent().max_element()) * 1e-9;
        Aabb::new(b.min - pad, b.max + pad)
    }

    /// The rectangle `[x0, x1, y0, y1]` of the light's plane that the
    /// segments from the eye through the triangle `v` (world space) can
    /// end in, grown by the eye's margin; `None` unless every vertex lies
    /// nearer to the light's plane than the eye (the rays through it then
    /// spread without bound). A triangle's rays end inside its own shadow
    /// on the light, far smaller than its leaf's footprint.
    ///
    /// Seen from the eye, a point at height z projects to
    /// x_L = p.x + (x − p.x)·p.z / (p.z − z); the projection keeps straight
    /// lines (every point in front of the eye), so the triangle's shadow is
    /// the triangle of its vertices' shadows. The vertices are lanes (the
    /// fourth repeats the first), which vectorizes.
    // Lanes of parallel arrays: index loops are what vectorizes.
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    pub fn triangle_footprint(&self, eye: &Eye, v: [DVec3; 3]) -> Option<[f64; 4]> {
        let p = eye.p;
        let max = |a: f64, b: f64| if a > b { a } else { b };
        let min = |a: f64, b: f64| if a < b { a } else { b };
        let mut w = [[0.0; 4]; 3];
        for lane in 0..4 {
            let d = v[lane % 3] - self.origin;
            for axis in 0..3 {
                w[axis][lane] = d.dot(self.axes[axis]);
            }
        }
        let (mut x, mut y, mut near) = ([0.0; 4], [0.0; 4], [false; 4]);
        for lane in 0..4 {
            let depth = p.z - w[2][lane];
            near[lane] = depth > eye.guard;
            let s = p.z / depth;
            x[lane] = p.x + (w[0][lane] - p.x) * s;
            y[lane] = p.y + (w[1][lane] - p.y) * s;
        }
        if near != [true; 4] {
            return None;
        }
        Some([
            min(min(x[0], x[1]), x[2]) - eye.margin,
            max(max(x[0], x[1]), x[2]) + eye.margin,
            min(min(y[0], y[1]), y[2]) - eye.margin,
            max(max(y[0], y[1]), y[2]) + eye.margin,
        ])
    }

    /// For each of a node's four boxes, the rectangle of the light's plane
    /// (z = 0) that the segments from the eye (`p.z > 0`) through the box
    /// can end in, grown by the eye's margin; the empty rectangle (+∞ … −∞)
    /// if no such segment meets the box.
    ///
    /// Only the part of the box with z in [0, p.z] matters. A point at
    /// height z projects to x_L = p.x + (x − p.x)·s with s = p.z / (p.z − z):
    /// bilinear in (x − p.x, s) over a rectangle, so its extremes lie at the
    /// rectangle's corners. A box reaching p's height projects to infinity.
    /// Straight-line code over the four lanes, which vectorizes.
    // Lanes of parallel arrays: index loops are what vectorizes.
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    pub fn footprints(eye: &Eye, node: &Node4) -> Footprints {
        let p = eye.p;
        // Plain comparisons (no NaN handling: none occurs) map to vector
        // min/max.
        let max = |a: f64, b: f64| if a > b { a } else { b };
        let min = |a: f64, b: f64| if a < b { a } else { b };
        let mut f = Footprints::default();
        let mut s_lo = [0.0; 4];
        let mut s_hi = [0.0; 4];
        let mut seen = [false; 4];
        for s in 0..4 {
            let z_lo = max(node.min[2][s] as f64, 0.0);
            let z_hi = min(node.max[2][s] as f64, p.z);
            seen[s] = z_lo <= z_hi;
            f.near[s] = p.z - z_hi - eye.guard;
            s_lo[s] = min(p.z / (p.z - z_lo + eye.guard), f64::MAX);
            // d_near ≤ 0 gives a negative or infinite quotient: f64::MAX.
            let q = p.z / f.near[s];
            s_hi[s] = if q > 0.0 && q < f64::MAX { q } else { f64::MAX };
        }
        for s in 0..4 {
            let ends = |lo: f64, hi: f64, pc: f64| {
                let (u0, u1) = (lo - pc, hi - pc);
                let lo = u0 * if u0 >= 0.0 { s_lo[s] } else { s_hi[s] };
                let hi = u1 * if u1 >= 0.0 { s_hi[s] } else { s_lo[s] };
                (pc + lo - eye.margin, pc + hi + eye.margin)
            };
            let (x0, x1) = ends(node.min[0][s] as f64, node.max[0][s] as f64, p.x);
            let (y0, y1) = ends(node.min[1][s] as f64, node.max[1][s] as f64, p.y);
            let inf = f64::INFINITY;
            f.x0[s] = if seen[s] { x0 } else { inf };
            f.x1[s] = if seen[s] { x1 } else { -inf };
            f.y0[s] = if seen[s] { y0 } else { inf };
            f.y1[s] = if seen[s] { y1 } else { -inf };
        }
        f
    }
}

/// The segment from a hit point to one light point, for slab tests of the
/// tree's f32 boxes (widened by the eye's margin).
#[derive(Debug, Clone, Copy)]
pub struct Segment {
    /// The origin moved by +margin and −margin: the offsets of a box's low
    /// and high faces, so the box is tested grown by the margin (which
    /// dwarfs the f32 rounding of these values and of the test).
    lo: [f32; 3],
    hi: [f32; 3],
    /// 1 / direction, clamped to ±1e30 so that 0·∞ never occurs.
    inv: [f32; 3],
}

impl Segment {
    /// Which of a node's four boxes the segment meets (for t in [0, 1]),
    /// and where it enters each.
    // Lanes of parallel arrays: index loops are what vectorizes.
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    pub fn hits(&self, node: &Node4) -> ([bool; 4], [f32; 4]) {
        let max = |a: f32, b: f32| if a > b { a } else { b };
        let min = |a: f32, b: f32| if a < b { a } else { b };
        let mut near = [0.0f32; 4];
        let mut far = [1.0f32; 4];
        for axis in 0..3 {
            for s in 0..4 {
                let t0 = (node.min[axis][s] - self.lo[axis]) * self.inv[axis];
                let t1 = (node.max[axis][s] - self.hi[axis]) * self.inv[axis];
                near[s] = max(near[s], min(t0, t1));
                far[s] = min(far[s], max(t0, t1));
            }
        }
        // Widened against the rounding above (Ize 2013).
        let mut hit = [false; 4];
        for s in 0..4 {
            hit[s] = near[s] <= far[s] * (1.0 + 1e-6);
        }
        (hit, near)
    }
}

/// A hit point as the footprints see it: in the light's frame, with the
/// margins that keep them conservative.
#[derive(Debug, Clone, Copy)]
pub struct Eye {
    pub p: DVec3,
    /// Growth of every footprint.
    margin: f64,
    /// Widening of every box's z range, beyond the rounding of `p.z`.
    guard: f64,
}

impl Eye {
    /// `p` in the light's frame (`p.z > 0`); `margin` in the light plane's
    /// units.
    pub fn new(p: DVec3, margin: f64) -> Eye {
        Eye {
            p,
            margin,
            guard: 1e-12 * p.abs().max_element(),
        }
    }

    /// The segment to the light point `(x, y)` of the light's plane.
    pub fn segment(&self, [x, y]: [f64; 2]) -> Segment {
        let d = [x - self.p.x, y - self.p.y, -self.p.z];
        let p = self.p.to_array();
        Segment {
            lo: p.map(|c| (c + self.margin) as f32),
            hi: p.map(|c| (c - self.margin) as f32),
            inv: d.map(|c| (1.0 / c).clamp(-1e30, 1e30) as f32),
        }
    }
}

/// Where the rays from a point through four boxes can end on the light's
/// plane (see [`LightFrame::footprints`]): rectangles in the frame's (x, y),
/// one lane each.
#[derive(Debug, Clone, Copy, Default)]
pub struct Footprints {
    pub x0: [f64; 4],
    pub x1: [f64; 4],
    pub y0: [f64; 4],
    pub y1: [f64; 4],
    /// Distance along z from the point to the nearest part of the box that
    /// lies between the point and the light's plane (for near-first order).
    pub near: [f64; 4],
}

/// The bounded objects in a BVH built in the light's frame, for shadow-ray
/// packets.
#[derive(Debug, Clone)]
pub struct OccluderBvh {
    pub frame: LightFrame,
    pub tree: Bvh4,
}

impl OccluderBvh {
    /// The tree over the bounded objects `objects` and the faces with
    /// primitive ids `faces`, where `prim(id)` is primitive `id`.
    pub fn new<'a>(
        light: &AreaLight,
        objects: &[u32],
        faces: std::ops::Range<u32>,
        prim: impl Fn(u32) -> Primitive<'a> + Sync,
    ) -> OccluderBvh {
        let frame = LightFrame::new(light);
        let bounds = |i: u32| {
            frame
                .bounds(prim(i))
                .expect("only bounded primitives are in the tree")
        };
        let id = |k: usize| match objects.get(k) {
            Some(&i) => i,
            None => faces.start + (k - objects.len()) as u32,
        };
        let count = objects.len() + faces.len();
        // Faces across x and y count double in the area heuristic: the tree
        // prefers slabs across z. Shadow rays run from the hit point
        // along −z and most stop at their first blocker, so slabs near
        // the point answer them before farther ones are opened
        // (measured: 6 % faster than plain SAH on 10,000 spheres).
        let binary = Bvh::build_with(count, |k| (id(k), bounds(id(k))), DVec3::new(2.0, 2.0, 1.0));
        crate::render::math::release_free_memory();
        let tree = Bvh4::from_binary(&binary, bounds);
        drop(binary);
        crate::render::math::release_free_memory();
        OccluderBvh { frame, tree }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::geometry::Slot;

    /// The seed room's light moved to `corner` with edges `edge_u`, `edge_v`.
    fn seed_light_at(corner: [f64; 3], edge_u: [f64; 3], edge_v: [f64; 3]) -> AreaLight {
        AreaLight::new(&crate::render::scene_file::LightDesc {
            corner,
            edge_u,
            edge_v,
            ..crate::render::SceneDesc::from_json(crate::render::scene::SEED_ROOM_JSON)
                .unwrap()
                .light
        })
    }

    /// One box's footprint.
    #[derive(Debug, Clone, Copy, PartialEq)]
    struct Footprint {
        x: [f64; 2],
        y: [f64; 2],
        near: f64,
    }

    /// The footprint of a box (the first lane of a node), `None` when empty.
    fn fp(p: DVec3, b: &Aabb) -> Option<Footprint> {
        let mut node = Node4::empty();
        node.set(0, Slot::Object(0), b);
        let f = LightFrame::footprints(&Eye::new(p, 0.0), &node);
        (f.x0[0] <= f.x1[0]).then_some(Footprint {
            x: [f.x0[0], f.x1[0]],
            y: [f.y0[0], f.y1[0]],
            near: f.near[0],
        })
    }

    /// Brute force: the segments from p to light-plane points on a fine
    /// grid that pass through the box all end inside the footprint.
    #[test]
    fn footprint_holds_every_segment_through_the_box() {
        let boxes = [
            Aabb::new(DVec3::new(-1.0, 0.5, 1.0), DVec3::new(0.5, 2.0, 3.0)),
            Aabb::new(DVec3::new(0.2, -3.0, -1.0), DVec3::new(0.4, -2.5, 4.5)),
            Aabb::new(DVec3::new(1.5, 1.5, 0.0), DVec3::new(2.5, 2.5, 5.0)),
        ];
        let points = [DVec3::new(0.0, 0.0, 5.0), DVec3::new(1.0, -2.0, 4.0)];
        let mut inside = 0;
        for p in points {
            for b in &boxes {
                let f = fp(p, b);
                for i in -200..=200 {
                    for j in -200..=200 {
                        let end = DVec3::new(i as f64 * 0.05, j as f64 * 0.05, 0.0);
                        let ray = crate::render::geometry::Ray::new(p, end - p);
                        if b.entry(&ray, ray.dir.recip(), 1.0).is_some() {
                            let f = f.expect("a segment meets the box");
                            assert!(f.x[0] <= end.x && end.x <= f.x[1], "{p} {b:?} {end}");
                            assert!(f.y[0] <= end.y && end.y <= f.y[1], "{p} {b:?} {end}");
                            inside += 1;
                        }
                    }
                }
            }
        }
        assert!(inside > 1000, "the boxes are seen at all: {inside}");
    }

    /// Brute force under a tilted light: the segments from p to light
    /// points on a fine grid that meet the triangle all end inside its
    /// footprint (a small one's a fifth of the light at most); a triangle with a
    /// vertex level with p or behind it has none.
    #[test]
    fn triangle_footprint_holds_every_segment_through_the_triangle() {
        let light = seed_light_at([-1.5, 7.0, -1.0], [2.5, 0.6, 0.3], [0.8, 0.2, 2.0]);
        let frame = LightFrame::new(&light);
        let p = DVec3::new(0.5, 0.2, -0.3);
        let eye = Eye::new(frame.local(p), 0.0);
        let triangles = [
            [[0.0, 3.0, 0.0], [0.3, 3.2, 0.1], [0.1, 3.4, -0.2]],
            [[-1.0, 1.0, -1.0], [0.2, 6.5, 0.1], [0.9, 2.0, 0.4]],
            [[0.4, 0.6, -0.2], [0.6, 0.8, -0.4], [0.5, 0.5, -0.1]],
        ]
        .map(|t| t.map(DVec3::from_array));
        let mut inside = 0;
        let mut areas = Vec::new();
        for v in triangles {
            let [x0, x1, y0, y1] = frame.triangle_footprint(&eye, v).expect("in front of p");
            let tri = crate::render::geometry::Triangle::new(v[0], v[1], v[2]).unwrap();
            for i in 0..=200 {
                for j in 0..=200 {
                    let end = light
                        .shape
                        .point(glam::DVec2::new(i as f64, j as f64) / 200.0);
                    let ray = crate::render::geometry::Ray::new(p, end - p);
                    if tri.intersect(&ray, 1.0).is_some() {
                        let [x, y] = frame.light_point(i as f64 / 200.0, j as f64 / 200.0);
                        assert!(x0 <= x && x <= x1 && y0 <= y && y <= y1, "{v:?} {end}");
                        inside += 1;
                    }
                }
            }
            areas.push((x1 - x0) * (y1 - y0));
        }
        assert!(areas[0] < 0.2 * light.shape.edge_u.cross(light.shape.edge_v).length());
        assert!(inside > 1000, "the triangles are seen at all: {inside}");
        let level = [p + DVec3::X, p + DVec3::new(0.0, 2.0, 0.0), p - DVec3::Y];
        let level = level.map(|v| v + light.shape.normal * light.shape.normal.dot(p - v));
        assert_eq!(frame.triangle_footprint(&eye, level), None);
    }

    #[test]
    fn footprint_is_tight_for_a_box_level_with_the_light() {
        // A thin box lying on the light's plane projects onto itself.
        let b = Aabb::new(DVec3::new(1.0, 2.0, 0.0), DVec3::new(3.0, 4.0, 0.0));
        let close = |f: Footprint, x: [f64; 2], y: [f64; 2], near: f64| {
            let d = [
                f.x[0] - x[0],
                f.x[1] - x[1],
                f.y[0] - y[0],
                f.y[1] - y[1],
                f.near - near,
            ];
            assert!(d.iter().all(|d| d.abs() < 1e-9), "{f:?}");
            // Grown, never shrunk, by the guard against rounding.
            assert!(f.x[0] <= x[0] && f.x[1] >= x[1] && f.y[0] <= y[0] && f.y[1] >= y[1]);
        };
        let f = fp(DVec3::new(0.0, 0.0, 2.0), &b).unwrap();
        close(f, [1.0, 3.0], [2.0, 4.0], 2.0);
        // Halfway up, its shadow on the plane doubles around p's foot.
        let b = Aabb::new(DVec3::new(1.0, 2.0, 1.0), DVec3::new(3.0, 4.0, 1.0));
        let f = fp(DVec3::new(0.0, 0.0, 2.0), &b).unwrap();
        close(f, [2.0, 6.0], [4.0, 8.0], 1.0);
        // Behind the point or beyond the light: nothing.
        let b = Aabb::new(DVec3::new(-1.0, -1.0, 2.5), DVec3::new(1.0, 1.0, 3.0));
        assert_eq!(fp(DVec3::new(0.0, 0.0, 2.0), &b), None);
        let b = Aabb::new(DVec3::new(-1.0, -1.0, -3.0), DVec3::new(1.0, 1.0, -0.5));
        assert_eq!(fp(DVec3::new(0.0, 0.0, 2.0), &b), None);
    }

    #[test]
    fn frame_maps_the_light_onto_its_plane() {
        let light = seed_light_at([1.0, 7.0, -2.0], [0.0, 0.0, 3.0], [2.0, 0.0, 1.0]);
        let frame = LightFrame::new(&light);
        for (a, b) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (0.3, 0.8)] {
            let world = light.shape.point(glam::DVec2::new(a, b));
            let l = frame.local(world);
            let [x, y] = frame.light_point(a, b);
            assert!((l.x - x).abs() < 1e-12 && (l.y - y).abs() < 1e-12 && l.z.abs() < 1e-12);
        }
        // The lit side is +z.
        let above = light.shape.centre() + light.shape.normal;
        assert!((frame.local(above).z - 1.0).abs() < 1e-12);
    }
}
