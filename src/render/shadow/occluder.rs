//! Objects as seen from one hit point, and the per-ray blocking tests.

use glam::{DVec3, Vec3};

use super::RAY_END;
use crate::render::geometry::{Cuboid, Primitive, Shape, TriangleOccluder};
use crate::render::math::{WIDE_POINTS, avx512_dispatch};

/// An object as seen from one hit point, in f32 relative to it.
#[derive(Debug, Clone, Copy)]
pub(super) enum Occluder {
    /// `oc`: centre − p; `r2`: the radius squared.
    Sphere { oc: Vec3, r2: f32, inside: bool },
    /// `origin`: p in the box's frame; `cos`, `sin`: its rotation about y;
    /// `unsure`: per axis, the rounding bound of its slab distances times
    /// the squared direction component (see `Occluder::new`); `exact`: the
    /// box and `origin` in f64, to decide the rays within that bound.
    Cuboid {
        origin: Vec3,
        half: Vec3,
        cos: f32,
        sin: f32,
        unsure: Vec3,
        exact: (DVec3, Cuboid),
    },
    /// `to_corner`: corner − p; `dual_*`: rows of the pseudo-inverse of the
    /// edges; `dist`: normal · (corner − p).
    Rect {
        to_corner: Vec3,
        normal: Vec3,
        dual_u: Vec3,
        dual_v: Vec3,
        dist: f32,
    },
    /// `dist`: signed distance of p from the plane.
    Plane { normal: Vec3, dist: f32 },
    /// A plane whose normal (in f32) is ± axis `axis` (a room's walls):
    /// its cosine with a direction is ± the direction's component, the
    /// value the full dot product gives (the other products are zeros).
    /// `signed_end`: that sign times [`RAY_END`].
    AxisPlane {
        axis: u8,
        signed_end: f32,
        dist: f32,
    },
    /// See `geometry/triangle.rs`.
    Triangle(TriangleOccluder),
}

impl Occluder {
    /// Object `prim` seen from `p`, for rays no longer than `reach`.
    #[inline(always)]
    pub(super) fn new(prim: Primitive, p: DVec3, inside: bool, reach: f32) -> Occluder {
        let shape = match prim {
            Primitive::Shape(s) => s,
            Primitive::Face { meshes, face } => {
                return Occluder::Triangle(meshes.occluder(face, p, reach));
            }
        };
        match shape {
            Shape::Sphere(s) => Occluder::Sphere {
                oc: (s.centre - p).as_vec3(),
                r2: (s.radius * s.radius) as f32,
                inside,
            },
            Shape::Cuboid(c) => {
                let (origin, unsure) = box_seen_from(c, p, reach);
                Occluder::Cuboid {
                    origin: origin.as_vec3(),
                    half: c.half.as_vec3(),
                    cos: c.cos as f32,
                    sin: c.sin as f32,
                    unsure,
                    exact: (origin, *c),
                }
            }
            Shape::Parallelogram(r) => {
                let to_corner = r.corner - p;
                Occluder::Rect {
                    to_corner: to_corner.as_vec3(),
                    normal: r.normal.as_vec3(),
                    dual_u: r.dual_u.as_vec3(),
                    dual_v: r.dual_v.as_vec3(),
                    dist: r.normal.dot(to_corner) as f32,
                }
            }
            Shape::Plane(pl) => {
                let (normal, dist) = (pl.normal.as_vec3(), pl.signed_distance(p) as f32);
                match pl.axis {
                    Some(axis) => Occluder::AxisPlane {
                        axis,
                        signed_end: normal[axis as usize] * RAY_END,
                        dist,
                    },
                    None => Occluder::Plane { normal, dist },
                }
            }
            Shape::Triangle(t) => Occluder::Triangle(t.occluder(p, reach)),
        }
    }

    /// Clears `vis[j]` for every ray that this occluder blocks.
    pub(super) fn block(&self, d: Dirs, vis: &mut [f32]) {
        block(self, d, vis)
    }

    /// [`block`](Self::block) inlined into the caller, compiled for its CPU
    /// features (the same operations, so the same bits).
    #[inline(always)]
    pub(super) fn block_inline(&self, d: Dirs, vis: &mut [f32]) {
        let n = vis.len();
        let (dx, dy, dz) = (&d.x[..n], &d.y[..n], &d.z[..n]);
        match *self {
            Occluder::Sphere { oc, r2, inside } => {
                for j in 0..n {
                    let blocked = sphere_blocks(oc, r2, inside, dx[j], dy[j], dz[j]);
                    vis[j] *= cleared(blocked);
                }
            }
            Occluder::Cuboid {
                origin,
                half,
                cos,
                sin,
                unsure,
                ref exact,
            } => {
                let (lo, hi) = slab_bounds(half, origin);
                let slabs = BoxSlabs {
                    lo,
                    hi,
                    cos,
                    sin,
                    unsure,
                    exact,
                };
                if slabs.nan_free() {
                    slabs.block::<true>(dx, dy, dz, vis);
                } else {
                    slabs.block::<false>(dx, dy, dz, vis);
                }
            }
            Occluder::Rect {
                to_corner,
                normal,
                dual_u,
                dual_v,
                dist,
            } => {
                for j in 0..n {
                    let d = Vec3::new(dx[j], dy[j], dz[j]);
                    vis[j] *= cleared(rect_blocks(to_corner, normal, (dual_u, dual_v), dist, d));
                }
            }
            Occluder::Plane { normal, dist } => {
                for j in 0..n {
                    vis[j] *= cleared(plane_blocks(normal, dist, dx[j], dy[j], dz[j]));
                }
            }
            Occluder::AxisPlane {
                axis,
                signed_end,
                dist,
            } => {
                let component = match axis {
                    0 => dx,
                    1 => dy,
                    _ => dz,
                };
                for j in 0..n {
                    vis[j] *= cleared(axis_plane_blocks(signed_end, dist, component[j]));
                }
            }
            // Borrowed: a copy would put the vertices the f64 recheck reads
            // on the stack, and the f32 fields read back from that copy.
            Occluder::Triangle(ref t) => {
                // Unsure rays (within rounding of an edge) are left to a
                // second, scalar pass: rare, and kept out of the vector loop.
                let mut unsure = false;
                for j in 0..n {
                    let (blocked, u) = t.blocks_f32(dx[j], dy[j], dz[j], RAY_END);
                    vis[j] = tested(vis[j], blocked, u);
                    unsure |= u;
                }
                if unsure {
                    decide_marked(vis, |j| t.blocks_exact(dx[j], dy[j], dz[j]));
                }
            }
        }
    }

    /// Whether this occluder blocks the single ray `d`.
    pub(super) fn blocks(&self, d: Vec3) -> bool {
        let mut v = [1.0];
        let dirs = Dirs {
            x: &[d.x],
            y: &[d.y],
            z: &[d.z],
        };
        self.block(dirs, &mut v);
        v[0] == 0.0
    }
}

/// A box's slab test from p: its slab bounds `lo`, `hi` in its frame
/// (rotated by `cos`, `sin` about y), the rounding bound `unsure` and the
/// f64 box for the rays within it.
struct BoxSlabs<'a> {
    lo: Vec3,
    hi: Vec3,
    cos: f32,
    sin: f32,
    unsure: Vec3,
    exact: &'a (DVec3, Cuboid),
}

impl BoxSlabs<'_> {
    /// Whether no slab bound is 0. A NaN needs 0·∞: a bound of exactly 0
    /// (p on a face's plane) times the reciprocal of a direction component
    /// of exactly 0. Without one, plain compare-and-select minima and
    /// maxima (one instruction each, where `f32::min` adds two to drop a
    /// NaN) decide as `f32::min` does: they differ from it only in the
    /// sign of a zero, which no decision sees.
    fn nan_free(&self) -> bool {
        self.lo.cmpne(Vec3::ZERO).all() && self.hi.cmpne(Vec3::ZERO).all()
    }

    /// Clears `vis[j]` for every ray the box blocks; `PLAIN`: the minima
    /// and maxima compare and select (only where [`Self::nan_free`]), else
    /// `f32::min`/`max`, which drop the NaN of 0·∞ (a ray in a face's
    /// plane), treating that slab as not limiting.
    #[inline(always)]
    fn block<const PLAIN: bool>(&self, dx: &[f32], dy: &[f32], dz: &[f32], vis: &mut [f32]) {
        let min = |a: f32, b: f32| match PLAIN {
            true if a < b => a,
            true => b,
            false => a.min(b),
        };
        let max = |a: f32, b: f32| match PLAIN {
            true if a > b => a,
            true => b,
            false => a.max(b),
        };
        let BoxSlabs {
            lo,
            hi,
            cos,
            sin,
            unsure,
            exact,
        } = *self;
        let n = vis.len();
        let lane =
            |x: f32, y: f32, z: f32| slab_lane(lo, hi, (cos, sin), unsure, (min, max), (x, y, z));
        // Unsure rays are left to a second, scalar pass: rare, and kept out
        // of the vector loop, which marks them (see `decide_marked`).
        let mut any_unsure = false;
        for j in 0..n {
            let (blocked, unsure) = lane(dx[j], dy[j], dz[j]);
            vis[j] = tested(vis[j], blocked, unsure);
            any_unsure |= unsure;
        }
        if any_unsure {
            let (origin, cuboid) = exact;
            decide_marked(vis, |j| {
                let d = DVec3::new(dx[j] as f64, dy[j] as f64, dz[j] as f64);
                cuboid.segment_meets(*origin, d, RAY_END as f64)
            });
        }
    }
}

/// Box `c` seen from `p`, for rays no longer than `reach`: `p` in the box's
/// frame, and the rounding bound of the f32 slab test per axis (times the
/// squared direction component, see [`slab_lane`]).
#[inline(always)]
pub(super) fn box_seen_from(c: &Cuboid, p: DVec3, reach: f32) -> (DVec3, Vec3) {
    let origin = c.to_local(p - c.centre);
    // A slab distance (±half − origin)/l is off by at most
    // 7·2⁻²⁴·(half + |origin|)·|d|₁/l² (the rounding of the origin, half,
    // rotation, reciprocal and product), and |d|₁ ≤ √3·reach; entry and
    // exit may come from one axis: twice that, and room for the bound's
    // own rounding.
    let unsure = (c.half + origin.abs()).as_vec3() * (reach * SLAB_ROUNDING);
    (origin, unsure)
}

/// A box's slab bounds from `origin` (in its frame, f32): −half − origin
/// and half − origin.
#[inline(always)]
pub(super) fn slab_bounds(half: Vec3, origin: Vec3) -> (Vec3, Vec3) {
    (-half - origin, half - origin)
}

/// Whether the ray (x, y, z) from a point at signed distance `dist` from a
/// plane of unit normal `normal` crosses it before [`RAY_END`]. One lane of
/// the vector loops.
#[inline(always)]
pub(super) fn plane_blocks(normal: Vec3, dist: f32, x: f32, y: f32, z: f32) -> bool {
    let end = dist + (normal.x * x + normal.y * y + normal.z * z) * RAY_END;
    dist * end < 0.0
}

/// [`plane_blocks`] of a plane whose normal is ± an axis, for a direction
/// whose component on that axis is `c`; `signed_end`: the sign times
/// [`RAY_END`]. The same decision: the full dot product is ±c exactly (it
/// adds only zeros, which change the sign of a zero at most, and a zero
/// cosine leaves `end` = `dist`, unblocked either way), and (±c)·RAY_END
/// = c·(±RAY_END), a negation being exact.
#[inline(always)]
pub(super) fn axis_plane_blocks(signed_end: f32, dist: f32, c: f32) -> bool {
    let end = dist + c * signed_end;
    dist * end < 0.0
}

/// Whether the ray `d` from a point meets a rect (corner − point
/// `to_corner`, unit `normal`, `dual` rows of the pseudo-inverse of its
/// edges, `dist` = normal · to_corner) before [`RAY_END`]. One lane of the
/// vector loops.
#[inline(always)]
pub(super) fn rect_blocks(
    to_corner: Vec3,
    normal: Vec3,
    (dual_u, dual_v): (Vec3, Vec3),
    dist: f32,
    d: Vec3,
) -> bool {
    let t = dist / normal.dot(d);
    let q = d * t - to_corner;
    let (a, b) = (q.dot(dual_u), q.dot(dual_v));
    t > 0.0 && t < RAY_END && (0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b)
}

/// One ray (x, y, z) against a box's slabs `lo`, `hi` (in its frame,
/// rotated by `rotation` = (cos, sin) about y), with the rounding bound
/// `unsure`, the minimum and maximum given (see [`BoxSlabs::block`]):
/// (blocked, unsure). An unsure ray enters and leaves within rounding of
/// each other (or of the segment's ends); it is decided in f64, and
/// `blocked` is then false.
#[inline(always)]
pub(super) fn slab_lane(
    lo: Vec3,
    hi: Vec3,
    (cos, sin): (f32, f32),
    unsure: Vec3,
    (min, max): (impl Fn(f32, f32) -> f32, impl Fn(f32, f32) -> f32),
    (x, y, z): (f32, f32, f32),
) -> (bool, bool) {
    let (lx, lz) = (x * cos - z * sin, x * sin + z * cos);
    let (ix, iy, iz) = (1.0 / lx, 1.0 / y, 1.0 / lz);
    let (ax, bx) = (lo.x * ix, hi.x * ix);
    let (ay, by) = (lo.y * iy, hi.y * iy);
    let (az, bz) = (lo.z * iz, hi.z * iz);
    let near = max(max(max(min(ax, bx), min(ay, by)), min(az, bz)), 0.0);
    let far = min(min(min(max(ax, bx), max(ay, by)), max(az, bz)), RAY_END);
    let bound = unsure.x * ix * ix + unsure.y * iy * iy + unsure.z * iz * iz;
    let unsure = (far - near).abs() <= bound;
    // The box is closed, as its triangles are (edges inclusive): a ray that
    // enters and leaves at the same t runs through an edge or corner and is
    // blocked; the segment stays open (t in (0, RAY_END)).
    let blocked = near <= far && far > 0.0 && near < RAY_END;
    (blocked & !unsure, unsure)
}

/// A ray's visibility `v` after a test that found it `blocked` (0), or
/// `unsure` (marked for [`decide_marked`] as 0 − v), or neither (v).
/// (`blocked` excludes `unsure`; `v` is 1 or +0.)
#[inline(always)]
fn tested(v: f32, blocked: bool, unsure: bool) -> f32 {
    (if unsure { 0.0 - v } else { v }) * cleared(blocked)
}

/// The factor of a visibility (1 or +0) after a test: +0 if `blocked`,
/// else 1 (the visibility unchanged). A product, not a select of 0 or the
/// old value: written back in place, such a select becomes a masked store
/// in AVX2 code, microcoded and slow on AMD's CPUs.
#[inline(always)]
pub(super) fn cleared(blocked: bool) -> f32 {
    if blocked { 0.0 } else { 1.0 }
}

/// The second pass of a test that left its unsure rays (those within its
/// rounding bound) undecided and marked them by negating their visibility
/// (as 0 − v, which leaves a 0 a +0): each ray marked visible gets its
/// visibility back, or 0 where `blocks(j)`, the exact test, finds it
/// blocked. A visibility is positive or zero, so a negative one is a mark
/// (a ray already blocked stays so whatever the mark).
#[cold]
#[inline(never)]
fn decide_marked(vis: &mut [f32], blocks: impl Fn(usize) -> bool) {
    for (j, v) in vis.iter_mut().enumerate() {
        if *v < 0.0 {
            *v = if blocks(j) { 0.0 } else { 0.0 - *v };
        }
    }
}

/// The rounding bound of the f32 slab test, relative to the box's half
/// size plus the origin's distance from its centre, and the ray's length
/// (see [`Occluder::new`]).
const SLAB_ROUNDING: f32 = 1.0 / (1 << 18) as f32;

/// Whether the ray (x, y, z) from the hit point meets the sphere (centre
/// `oc` from the hit point, radius² `r2`) before [`RAY_END`]. One lane of
/// the vector loop, and the scalar test of a lone ray: the same operations,
/// so the same answer.
#[inline(always)]
pub(super) fn sphere_blocks(oc: Vec3, r2: f32, inside: bool, x: f32, y: f32, z: f32) -> bool {
    let a = x * x + y * y + z * z;
    let b = oc.x * x + oc.y * y + oc.z * z;
    // disc = b² − a(|oc|² − r²) = a(r² − |e|²), e the centre's offset from
    // the ray's closest point: computed from e (Ray Tracing Gems, ch. 7), it
    // keeps its precision for a small sphere far away, where b² and a|oc|²
    // cancel.
    let t = b / a;
    let (ex, ey, ez) = (oc.x - x * t, oc.y - y * t, oc.z - z * t);
    let disc = a * (r2 - (ex * ex + ey * ey + ez * ez));
    // Roots t = (b ± √disc) / a. Outside: the near root, in (0, 1) iff
    // b > 0 and b − a < √disc. Inside (p is on the sphere, disc = b²): the
    // exit, b + |b| < a.
    if inside {
        b + b.abs() < a * RAY_END
    } else {
        let s = b - a * RAY_END;
        disc >= 0.0 && b > 0.0 && (s < 0.0 || s * s < disc)
    }
}

avx512_dispatch!(
    /// Clears `vis[j]` for every ray that `occ` blocks.
    fn block(occ: &Occluder, d: Dirs, vis: &mut [f32]) => block_generic if vis.len() >= WIDE_POINTS
);

#[inline(always)]
fn block_generic(occ: &Occluder, d: Dirs, vis: &mut [f32]) {
    occ.block_inline(d, vis)
}

/// Directions of shadow rays as parallel slices (unnormalized: from the
/// hit point to the light point).
#[derive(Clone, Copy)]
pub(super) struct Dirs<'a> {
    pub(super) x: &'a [f32],
    pub(super) y: &'a [f32],
    pub(super) z: &'a [f32],
}

impl<'a> Dirs<'a> {
    pub(super) fn range(self, r: std::ops::Range<usize>) -> Dirs<'a> {
        Dirs {
            x: &self.x[r.clone()],
            y: &self.y[r.clone()],
            z: &self.z[r],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::geometry::{Ray, Triangle};
    use crate::render::rng::Rng;

    /// The slab test's plain minima and maxima (taken where no slab bound
    /// is 0) decide every ray as `f32::min`/`max` do: rays along the axes
    /// (a reciprocal of ±∞), through edges and corners, random ones.
    #[test]
    fn plain_slab_minima_decide_as_the_nan_dropping_ones() {
        let mut rng = Rng::new(11);
        let mut u = |lo: f32, hi: f32| lo + (hi - lo) * rng.next_f32();
        let (mut checked, mut blocked) = (0, 0);
        for case in 0..2000 {
            let half = Vec3::new(u(0.1, 2.0), u(0.1, 2.0), u(0.1, 2.0));
            let origin = Vec3::new(u(-6.0, 6.0), u(-6.0, 6.0), u(-6.0, 6.0));
            let (lo, hi) = (-half - origin, half - origin);
            let angle = u(0.0, std::f32::consts::TAU);
            let (sin, cos) = if case % 3 == 0 {
                (0.0, 1.0)
            } else {
                angle.sin_cos()
            };
            let cuboid = Cuboid::new((-half).as_dvec3(), half.as_dvec3(), 0.0, DVec3::ZERO);
            let exact = (origin.as_dvec3(), cuboid);
            let slabs = BoxSlabs {
                lo,
                hi,
                cos,
                sin,
                unsure: (half + origin.abs()) * (20.0 * SLAB_ROUNDING),
                exact: &exact,
            };
            if !slabs.nan_free() {
                continue;
            }
            let mut d: [Vec<f32>; 3] = Default::default();
            for k in 0..64 {
                let mut dir = [u(-8.0, 8.0), u(-8.0, 8.0), u(-8.0, 8.0)];
                // Some along an axis or in a coordinate plane, some at a
                // corner of the box.
                match k % 4 {
                    0 => dir[k % 3] = 0.0,
                    1 => {
                        dir = [0.0; 3];
                        dir[k % 3] = u(-8.0, 8.0);
                    }
                    2 => {
                        let c = Vec3::new(lo.x, hi.y, lo.z) * u(1.0, 3.0);
                        dir = [c.x * cos + c.z * sin, c.y, -c.x * sin + c.z * cos];
                    }
                    _ => {}
                }
                for i in 0..3 {
                    d[i].push(dir[i]);
                }
            }
            let (mut plain, mut dropping) = (vec![1.0f32; 64], vec![1.0f32; 64]);
            slabs.block::<true>(&d[0], &d[1], &d[2], &mut plain);
            slabs.block::<false>(&d[0], &d[1], &d[2], &mut dropping);
            assert_eq!(plain, dropping, "case {case}");
            checked += 1;
            blocked += plain.iter().filter(|&&v| v == 0.0).count();
        }
        assert!(
            checked > 1500 && blocked > 1000,
            "{checked} boxes, {blocked} rays blocked"
        );
    }

    /// A plane whose normal lies on an axis decides every ray as the full
    /// plane test: random points and directions, directions with zero
    /// components, points on the plane, both signs of the normal.
    #[test]
    fn an_axis_plane_decides_as_the_full_plane_test() {
        let mut rng = Rng::new(5);
        let mut u = |lo: f32, hi: f32| lo + (hi - lo) * rng.next_f32();
        let (mut checked, mut blocked) = (0, 0);
        for case in 0..3000 {
            let axis = case % 3;
            let along = if case % 2 == 0 { 1.0 } else { -1.0 };
            let mut normal = Vec3::ZERO;
            normal[axis] = along;
            let dist = match case % 7 {
                0 => 0.0,
                1 => -0.0,
                _ => u(-10.0, 10.0),
            };
            let mut d = [u(-20.0, 20.0), u(-20.0, 20.0), u(-20.0, 20.0)];
            match case % 5 {
                0 => d[axis] = 0.0,
                1 => d[axis] = -0.0,
                2 => d[(axis + 1) % 3] = -0.0,
                _ => {}
            }
            let full = plane_blocks(normal, dist, d[0], d[1], d[2]);
            assert_eq!(
                axis_plane_blocks(along * RAY_END, dist, d[axis]),
                full,
                "normal {normal}, dist {dist}, direction {d:?}"
            );
            checked += 1;
            blocked += full as u32;
        }
        assert!(checked == 3000 && blocked > 300, "{blocked} rays blocked");
    }

    /// The seed room's tall box.
    fn tall_box() -> Cuboid {
        Cuboid::new(
            DVec3::new(-1.0, 0.0, -1.0),
            DVec3::new(1.0, 5.0, 1.0),
            20.0,
            DVec3::new(-2.0, 0.0, 1.0),
        )
    }

    /// A point of the room outside box `c`.
    fn outside(c: &Cuboid, u: &mut impl FnMut(f64, f64) -> f64) -> DVec3 {
        loop {
            let p = DVec3::new(u(-5.0, 5.0), u(0.0, 8.0), u(-5.0, 5.0));
            if !c.to_local(p - c.centre).abs().cmple(c.half).all() {
                return p;
            }
        }
    }

    /// A point of one of box `c`'s edges along axis `along`, nudged off it
    /// by up to 1e-6 (the f32 tests' rounding is ~1e-7 of the distances).
    fn near_an_edge(c: &Cuboid, along: usize, u: &mut impl FnMut(f64, f64) -> f64) -> DVec3 {
        let mut on_edge = DVec3::new(u(-1.0, 1.0), u(-1.0, 1.0), u(-1.0, 1.0)).signum();
        on_edge[along] = u(-1.0, 1.0);
        let jitter = DVec3::new(u(-1.0, 1.0), u(-1.0, 1.0), u(-1.0, 1.0)) * 1e-6;
        c.centre + c.to_world(c.half * on_edge) + jitter
    }

    /// Rays from all over the room to points within 1e-6 of the tall box's
    /// edges (the f32 tests' rounding is ~1e-7 of the distances): the box
    /// and its twelve triangles block exactly the rays the f64 intersection
    /// finds blocked.
    #[test]
    fn a_box_and_its_triangles_decide_grazing_rays_as_the_exact_geometry() {
        let c = tall_box();
        let corner = c.corners();
        let triangles: Vec<Triangle> = Cuboid::FACES
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .map(|t| Triangle::new(corner[t[0]], corner[t[1]], corner[t[2]]).unwrap())
            .collect();
        let shape = Shape::Cuboid(c);
        let mut rng = Rng::new(3);
        let mut u = |lo: f64, hi: f64| lo + (hi - lo) * rng.next_f64();
        let (mut blocked, mut box_wrong, mut triangles_wrong) = (0, 0, 0);
        for _ in 0..100_000 {
            let p = outside(&c, &mut u);
            let along = (u(0.0, 3.0) as usize).min(2);
            let target = near_an_edge(&c, along, &mut u);
            // Past the box (a light beyond it), or short of it.
            let d = ((target - p) * u(0.5, 2.0)).as_vec3();
            let reach = d.length() * 1.001;
            let exact = c
                .intersect(&Ray::new(p, d.as_dvec3()), RAY_END as f64)
                .is_some();
            let by_box = Occluder::new(Primitive::Shape(&shape), p, false, reach).blocks(d);
            let by_triangles = triangles
                .iter()
                .any(|t| Occluder::Triangle(t.occluder(p, reach)).blocks(d));
            blocked += exact as u32;
            box_wrong += (by_box != exact) as u32;
            triangles_wrong += (by_triangles != exact) as u32;
        }
        assert!(blocked > 20_000, "{blocked} rays blocked");
        assert_eq!((box_wrong, triangles_wrong), (0, 0));
    }

    /// Sixty-four rays at once (the sixteen-lane kernels where the CPU has
    /// them), half of them grazing an edge of a box (so within the f32
    /// tests' rounding, left to the exact second pass): each ray's
    /// visibility is what the exact geometry gives it, a ray blocked before
    /// stays blocked, one not blocked keeps its weight, and the marks of
    /// the unsure rays leave no negative value and no −0 behind.
    #[test]
    fn unsure_rays_among_many_get_the_exact_answer_and_no_mark_stays() {
        let c = tall_box();
        let corner = c.corners();
        let face = Triangle::new(corner[0], corner[2], corner[6]).unwrap();
        let shapes = [Shape::Cuboid(c), Shape::Triangle(face)];
        let mut rng = Rng::new(5);
        let mut u = |lo: f64, hi: f64| lo + (hi - lo) * rng.next_f64();
        let (mut cleared, mut kept) = (0, 0);
        for _ in 0..2_000 {
            let p = outside(&c, &mut u);
            let mut d: [Vec<f32>; 3] = Default::default();
            for k in 0..64 {
                let target = if k % 2 == 0 {
                    near_an_edge(&c, k % 3, &mut u)
                } else {
                    DVec3::new(u(-5.0, 5.0), u(0.0, 8.0), u(-5.0, 5.0))
                };
                let dir = ((target - p) * u(0.5, 2.0)).as_vec3();
                for i in 0..3 {
                    d[i].push(dir[i]);
                }
            }
            let dirs = Dirs {
                x: &d[0],
                y: &d[1],
                z: &d[2],
            };
            let reach = (0..64)
                .map(|j| Vec3::new(d[0][j], d[1][j], d[2][j]).length())
                .fold(0.0, f32::max)
                * 1.001;
            for shape in &shapes {
                let occ = Occluder::new(Primitive::Shape(shape), p, false, reach);
                let before: Vec<f32> = (0..64).map(|j| [1.0, 0.0, 0.5][j % 3]).collect();
                let mut vis = before.clone();
                occ.block(dirs, &mut vis);
                for j in 0..64 {
                    let d = Vec3::new(d[0][j], d[1][j], d[2][j]).as_dvec3();
                    let exact = shape.intersect(&Ray::new(p, d), RAY_END as f64).is_some();
                    let expected = if before[j] == 0.0 || exact {
                        0.0
                    } else {
                        before[j]
                    };
                    assert_eq!(vis[j].to_bits(), expected.to_bits(), "ray {j} from {p}");
                    cleared += (before[j] != 0.0 && exact) as u32;
                    kept += (before[j] != 0.0 && !exact) as u32;
                }
            }
        }
        assert!(
            cleared > 10_000 && kept > 10_000,
            "{cleared} cleared, {kept} kept"
        );
    }
}
