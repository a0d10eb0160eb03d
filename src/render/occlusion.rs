//! Shadow rays: which of a hit point's light points are visible.
//!
//! All shadow rays of one hit point share their origin, so they are handled
//! together, in f32, in coordinates relative to the hit point: that keeps
//! them precise for a room far from the world origin, and lets the compiler
//! vectorize the per-ray loops (structure of arrays, no branches).
//!
//! A ray from hit point p to light point y is blocked by an object met at
//! t ∈ (0, 1 − 10⁻⁴) on p + t (y − p) (see [`RAY_END`]). A light point
//! behind the surface (N·(y − p) ≤ 0) counts as blocked by the surface
//! itself. The surface's own object is otherwise left out: every primitive
//! is convex or flat, so a ray leaving it on the outer side can never meet
//! it again — exact, with no epsilon. Hit from inside (the normal was
//! flipped), the object is kept and only its exit point counts.
//!
//! Work is skipped where the answer is known (when `settings.skip`):
//! - objects whose bounds miss the pyramid spanned by p and the light
//!   rectangle can block nothing; planes with the whole light on p's side
//!   neither. With no candidate left, every facing point is visible.
//! - if one convex candidate, lying wholly between p and the light's plane,
//!   blocks the rays to all four light corners, it blocks every ray to the
//!   light (the directions that meet a convex body form a convex cone).
//!
//! Both only decide what is also what tracing would find, so the image is
//! the same with skipping on or off.

use glam::{DVec3, Vec3};

use super::geometry::{Aabb, Shape};
use super::math::avx2_dispatch;
use super::scene::Scene;
use super::stats::RayStats;

/// Shadow rays end at this fraction of the way to their light point: a
/// surface the light lies in (a light flush with a ceiling) must not block
/// it, and in f32 the light point's side of such a surface is a coin toss
/// unless the geometry is axis-aligned. Occluders closer to the light than
/// 1e-4 of the ray's length are not seen (a relative margin, so it holds at
/// every scale; pbrt uses the same shadow epsilon).
const RAY_END: f32 = 1.0 - 1e-4;

/// Rays traced first by the adaptive mode.
const ADAPTIVE_PROBES: usize = 8;

/// Per-thread buffers for one hit point's light points, reused from hit to
/// hit so that the hot loop never allocates.
#[derive(Debug, Default)]
pub struct ShadowBuffers {
    /// Light points in the light's (a, b) coordinates.
    pub a: Vec<f32>,
    pub b: Vec<f32>,
    /// Unnormalized directions from the hit point to the light points.
    pub dx: Vec<f32>,
    pub dy: Vec<f32>,
    pub dz: Vec<f32>,
    /// 1 where the light point is visible, 0 where it is blocked.
    pub vis: Vec<f32>,
    /// Per-point diffuse and specular contributions (shading scratch).
    pub term_d: Vec<f32>,
    pub term_s: Vec<f32>,
    /// Per-point unshadowed diffuse factor (the ratio estimator's weights).
    pub term_f: Vec<f32>,
    /// The fixed pattern whose points `a` and `b` already hold, if any.
    pub filled: Option<(super::scene_file::Sampling, u32)>,
    occluders: Vec<Candidate>,
}

/// A possible occluder of one hit point.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    occ: Occluder,
    /// Convex and wholly between the hit point's side and the light's plane:
    /// may decide the umbra test.
    umbra_test: bool,
}

impl ShadowBuffers {
    /// Buffers for up to `points` light points. Lengths are rounded up to a
    /// multiple of 8 and the padding holds invisible points at a finite
    /// direction, so that vector loops may run over whole chunks.
    pub fn with_capacity(points: usize) -> ShadowBuffers {
        let len = points.next_multiple_of(8).max(8);
        let v = |x: f32| vec![x; len];
        ShadowBuffers {
            a: v(0.0),
            b: v(0.0),
            dx: v(0.0),
            dy: v(1.0),
            dz: v(0.0),
            vis: v(0.0),
            term_d: v(0.0),
            term_s: v(0.0),
            term_f: v(0.0),
            filled: None,
            occluders: Vec::with_capacity(16),
        }
    }
}

/// An object as seen from one hit point, in f32 relative to it.
#[derive(Debug, Clone, Copy)]
enum Occluder {
    /// `oc`: centre − p; `c2`: |p − c|² − r² (0 when hit from inside: p is
    /// on the sphere).
    Sphere { oc: Vec3, c2: f32, inside: bool },
    /// `origin`: p in the box's frame; `cos`, `sin`: its rotation about y.
    Cuboid {
        origin: Vec3,
        half: Vec3,
        cos: f32,
        sin: f32,
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
}

impl Occluder {
    fn new(shape: &Shape, p: DVec3, inside: bool) -> Occluder {
        match shape {
            Shape::Sphere(s) => {
                let oc = s.centre - p;
                let c2 = if inside {
                    0.0
                } else {
                    oc.length_squared() - s.radius * s.radius
                };
                Occluder::Sphere {
                    oc: oc.as_vec3(),
                    c2: c2 as f32,
                    inside,
                }
            }
            Shape::Cuboid(c) => Occluder::Cuboid {
                origin: c.to_local(p - c.centre).as_vec3(),
                half: c.half.as_vec3(),
                cos: c.cos as f32,
                sin: c.sin as f32,
            },
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
            Shape::Plane(pl) => Occluder::Plane {
                normal: pl.normal.as_vec3(),
                dist: pl.signed_distance(p) as f32,
            },
        }
    }

    /// Clears `vis[j]` for every ray that this occluder blocks.
    fn block(&self, dx: &[f32], dy: &[f32], dz: &[f32], vis: &mut [f32]) {
        block(self, dx, dy, dz, vis)
    }

    #[inline(always)]
    fn block_generic(&self, dx: &[f32], dy: &[f32], dz: &[f32], vis: &mut [f32]) {
        let n = vis.len();
        let (dx, dy, dz) = (&dx[..n], &dy[..n], &dz[..n]);
        match *self {
            Occluder::Sphere { oc, c2, inside } => {
                for j in 0..n {
                    let (x, y, z) = (dx[j], dy[j], dz[j]);
                    let a = x * x + y * y + z * z;
                    let b = oc.x * x + oc.y * y + oc.z * z;
                    let disc = b * b - a * c2;
                    // Roots t = (b ± √disc) / a. Outside: the near root, in
                    // (0, 1) iff b > 0 and b − a < √disc. Inside: the exit,
                    // b + √disc < a.
                    let blocked = if inside {
                        b + disc.max(0.0).sqrt() < a * RAY_END
                    } else {
                        let s = b - a * RAY_END;
                        disc >= 0.0 && b > 0.0 && (s < 0.0 || s * s < disc)
                    };
                    vis[j] = if blocked { 0.0 } else { vis[j] };
                }
            }
            Occluder::Cuboid {
                origin,
                half,
                cos,
                sin,
            } => {
                let (lo, hi) = (-half - origin, half - origin);
                for j in 0..n {
                    let (x, y, z) = (dx[j], dy[j], dz[j]);
                    let (lx, lz) = (x * cos - z * sin, x * sin + z * cos);
                    let (ix, iy, iz) = (1.0 / lx, 1.0 / y, 1.0 / lz);
                    let (ax, bx) = (lo.x * ix, hi.x * ix);
                    let (ay, by) = (lo.y * iy, hi.y * iy);
                    let (az, bz) = (lo.z * iz, hi.z * iz);
                    // f32::min/max drop the NaN of 0·∞ (a ray in a face's
                    // plane), treating that slab as not limiting.
                    let near = ax.min(bx).max(ay.min(by)).max(az.min(bz)).max(0.0);
                    let far = ax.max(bx).min(ay.max(by)).min(az.max(bz)).min(RAY_END);
                    vis[j] = if near < far { 0.0 } else { vis[j] };
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
                    let t = dist / normal.dot(d);
                    let q = d * t - to_corner;
                    let (a, b) = (q.dot(dual_u), q.dot(dual_v));
                    let blocked = t > 0.0
                        && t < RAY_END
                        && (0.0..=1.0).contains(&a)
                        && (0.0..=1.0).contains(&b);
                    vis[j] = if blocked { 0.0 } else { vis[j] };
                }
            }
            Occluder::Plane { normal, dist } => {
                for j in 0..n {
                    let end =
                        dist + (normal.x * dx[j] + normal.y * dy[j] + normal.z * dz[j]) * RAY_END;
                    vis[j] = if dist * end < 0.0 { 0.0 } else { vis[j] };
                }
            }
        }
    }

    /// Whether this occluder blocks the single ray `d`.
    fn blocks(&self, d: Vec3) -> bool {
        let mut v = [1.0];
        self.block(&[d.x], &[d.y], &[d.z], &mut v);
        v[0] == 0.0
    }
}

/// The pyramid spanned by a hit point and the light rectangle, as five
/// planes `n · x <= d` (four sides and the light's plane), for culling.
struct ShadowPyramid {
    planes: [(DVec3, f64); 5],
    /// Length of each plane's normal (they are not normalized).
    lengths: [f64; 5],
    bounds: Aabb,
}

impl ShadowPyramid {
    fn new(
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
            lengths: planes.map(|(n, _)| n.length()),
            bounds: Aabb::from_points(corners).grow(p),
        }
    }

    /// Conservative: false only if the sphere certainly misses the pyramid.
    fn may_overlap_sphere(&self, centre: DVec3, radius: f64) -> bool {
        self.planes
            .iter()
            .zip(&self.lengths)
            .all(|(&(n, d), &len)| n.dot(centre) - d <= radius * len * (1.0 + 1e-9))
    }

    /// Conservative: false only if the box certainly misses the pyramid.
    fn may_overlap(&self, b: &Aabb) -> bool {
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

/// One hit point whose shadow rays are to be traced.
pub struct ShadowQuery {
    /// The hit point (on the surface).
    pub point: DVec3,
    /// Unit normal facing the incoming ray.
    pub normal: DVec3,
    /// The hit object.
    pub object: u32,
    /// Whether the object was hit from inside.
    pub inside: bool,
}

/// Fills `buf.dx/dy/dz` from `buf.a/b` and `buf.vis` with each point's
/// visibility (1 or 0), for the first `count` points.
pub fn visibility(
    scene: &Scene,
    q: &ShadowQuery,
    count: usize,
    buf: &mut ShadowBuffers,
    stats: &mut RayStats,
) {
    let light = &scene.light.shape;
    let to_corner = (light.corner - q.point).as_vec3();
    let (eu, ev) = (light.edge_u.as_vec3(), light.edge_v.as_vec3());
    let facing = light_directions(to_corner, eu, ev, q.normal.as_vec3(), count, buf);
    stats.shadow_backfacing += count as u64 - facing;
    if facing == 0 {
        return;
    }
    if !scene.settings.shadows {
        stats.shadow_disabled += facing;
        return;
    }

    let skip = scene.settings.skip;
    let corners = light.corners();
    let pyramid = ShadowPyramid::new(q.point, &corners, light.normal, light.centre());
    // An object as a possible occluder of this hit point, unless it can
    // certainly block nothing.
    let candidate = |i: u32| -> Option<Candidate> {
        let inside = i == q.object && q.inside;
        if i == q.object && !inside {
            return None;
        }
        let object = &scene.objects[i as usize];
        if skip {
            match &object.shape {
                // A plane blocks only if some light point lies on its other
                // side from p.
                Shape::Plane(pl) => {
                    let sp = pl.signed_distance(q.point);
                    if corners.iter().all(|c| pl.signed_distance(*c) * sp > 0.0) {
                        return None;
                    }
                }
                // The sphere itself is a tighter test than its box.
                Shape::Sphere(sp) => {
                    if !pyramid.may_overlap_sphere(sp.centre, sp.radius) {
                        return None;
                    }
                }
                _ => {
                    if object.bounds.is_some_and(|b| !pyramid.may_overlap(&b)) {
                        return None;
                    }
                }
            }
        }
        let umbra_test = !inside
            && match object.bounds {
                // Planes block a light point iff it lies on their other side:
                // all four corners there means the whole light.
                None => true,
                Some(b) => {
                    let x = DVec3::select(light.normal.cmpge(DVec3::ZERO), b.min, b.max);
                    light.signed_distance(x) > 0.0
                }
            };
        Some(Candidate {
            occ: Occluder::new(&object.shape, q.point, inside),
            umbra_test,
        })
    };

    // Objects outside the BVH (planes, and all objects of small scenes).
    buf.occluders.clear();
    buf.occluders.extend(
        scene
            .unbounded
            .iter()
            .chain(&scene.bounded)
            .filter_map(|&i| candidate(i)),
    );
    if buf.occluders.is_empty() && scene.bvh.is_empty() {
        stats.shadow_unoccluded += facing;
        return;
    }
    if skip {
        // Umbra: one convex occluder between p and the light's plane that
        // blocks all four corner rays blocks the whole light.
        let corner_dirs = corners.map(|c| (c - q.point).as_vec3());
        let umbra = buf
            .occluders
            .iter()
            .any(|c| c.umbra_test && corner_dirs.iter().all(|d| c.occ.blocks(*d)));
        if umbra {
            buf.vis[..count].fill(0.0);
            stats.shadow_umbra += facing;
            return;
        }
    }
    // Traces rays (directions and visibility as parallel slices) against the
    // candidates; returns whether there was any candidate at all.
    let occluders = &buf.occluders;
    let trace = |dx: &[f32], dy: &[f32], dz: &[f32], vis: &mut [f32]| -> bool {
        let mut traced = !occluders.is_empty();
        for c in occluders {
            c.occ.block(dx, dy, dz, vis);
        }
        // The BVH, nearest nodes first, each leaf's objects blocking rays at
        // once, until no ray is left (an any-hit traversal for the whole
        // packet; the result does not depend on the order).
        if !scene.bvh.is_empty() && (!skip || vis.iter().any(|&v| v != 0.0)) {
            scene.bvh.visit_near_first(
                q.point,
                |b| !skip || pyramid.may_overlap(b),
                |i| {
                    let Some(c) = candidate(i) else {
                        return true;
                    };
                    traced = true;
                    c.occ.block(dx, dy, dz, vis);
                    !skip || vis.iter().any(|&v| v != 0.0)
                },
            );
        }
        traced
    };

    if scene.settings.adaptive && count >= 4 * ADAPTIVE_PROBES {
        // Adaptive (biased): trace a spread subset first; if its facing rays
        // all agree, give every facing ray their answer.
        // The points nearest the light's four corners and four edge
        // midpoints: where a shadow edge would first show.
        const TARGETS: [(f32, f32); ADAPTIVE_PROBES] = [
            (0.0, 0.0),
            (1.0, 0.0),
            (1.0, 1.0),
            (0.0, 1.0),
            (0.5, 0.0),
            (1.0, 0.5),
            (0.5, 1.0),
            (0.0, 0.5),
        ];
        let mut nearest = [(f32::INFINITY, 0usize); ADAPTIVE_PROBES];
        for j in 0..count {
            let (a, b) = (buf.a[j], buf.b[j]);
            for (t, n) in TARGETS.iter().zip(nearest.iter_mut()) {
                let d = (a - t.0) * (a - t.0) + (b - t.1) * (b - t.1);
                if d < n.0 {
                    *n = (d, j);
                }
            }
        }
        let mut probe = [[0.0f32; ADAPTIVE_PROBES]; 4];
        let mut facing_probes = 0.0;
        for (k, &(_, j)) in nearest.iter().enumerate() {
            probe[0][k] = buf.dx[j];
            probe[1][k] = buf.dy[j];
            probe[2][k] = buf.dz[j];
            probe[3][k] = buf.vis[j];
            facing_probes += buf.vis[j];
        }
        let [px, py, pz, pvis] = &mut probe;
        let traced = trace(px, py, pz, pvis);
        let visible: f32 = pvis.iter().sum();
        if !traced {
            stats.shadow_unoccluded += facing;
            return;
        }
        if facing_probes > 0.0 && (visible == 0.0 || visible == facing_probes) {
            if visible == 0.0 {
                buf.vis[..count].fill(0.0);
            }
            stats.shadow += ADAPTIVE_PROBES as u64;
            stats.shadow_adaptive += facing.saturating_sub(ADAPTIVE_PROBES as u64);
            return;
        }
    }

    let (dx, dy, dz) = (&buf.dx[..count], &buf.dy[..count], &buf.dz[..count]);
    let traced = trace(dx, dy, dz, &mut buf.vis[..count]);
    if traced {
        stats.shadow += facing;
    } else {
        stats.shadow_unoccluded += facing;
    }
}

avx2_dispatch!(
    /// Directions from the hit point to the light points, and 1 in `vis` for
    /// those in front of the surface; returns how many are.
    fn light_directions(to_corner: Vec3, eu: Vec3, ev: Vec3, n: Vec3, count: usize, buf: &mut ShadowBuffers) -> u64
        => light_directions_generic
);

#[inline(always)]
fn light_directions_generic(
    to_corner: Vec3,
    eu: Vec3,
    ev: Vec3,
    n: Vec3,
    count: usize,
    buf: &mut ShadowBuffers,
) -> u64 {
    let (a, b) = (&buf.a[..count], &buf.b[..count]);
    let (dx, dy, dz) = (
        &mut buf.dx[..count],
        &mut buf.dy[..count],
        &mut buf.dz[..count],
    );
    let vis = &mut buf.vis[..count];
    for j in 0..count {
        let (x, y, z) = (
            to_corner.x + eu.x * a[j] + ev.x * b[j],
            to_corner.y + eu.y * a[j] + ev.y * b[j],
            to_corner.z + eu.z * a[j] + ev.z * b[j],
        );
        dx[j] = x;
        dy[j] = y;
        dz[j] = z;
        vis[j] = if n.x * x + n.y * y + n.z * z > 0.0 {
            1.0
        } else {
            0.0
        };
    }
    // Exact: a sum of ones and zeros below 2²⁴.
    vis.iter().sum::<f32>() as u64
}

avx2_dispatch!(
    /// Clears `vis[j]` for every ray that `occ` blocks.
    fn block(occ: &Occluder, dx: &[f32], dy: &[f32], dz: &[f32], vis: &mut [f32]) => block_generic
);

#[inline(always)]
fn block_generic(occ: &Occluder, dx: &[f32], dy: &[f32], dz: &[f32], vis: &mut [f32]) {
    occ.block_generic(dx, dy, dz, vis)
}
