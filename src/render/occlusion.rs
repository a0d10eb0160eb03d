//! Shadow rays: which of a hit point's light points are visible.
//!
//! All shadow rays of one hit point share their origin, so they are handled
//! together, in f32, in coordinates relative to the hit point: that keeps
//! them precise for a room far from the world origin, and lets the compiler
//! vectorize the per-ray loops (structure of arrays, no branches).
//!
//! A ray from hit point p to light point y is blocked by an object met at
//! t ∈ (0, 1 − 10⁻⁴) on p + t (y − p) (see `RAY_END`). A light point
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
//! - from [`PACKET_THRESHOLD`](super::scene::PACKET_THRESHOLD) objects on,
//!   the rays walk a BVH built in the light's frame as packets of 64
//!   (`light_frame.rs`, `ray_packet.rs`): a box is opened only with the
//!   rays whose light points lie in its footprint, grown by a margin far
//!   beyond the f32 tests' rounding, and a ray stops at its first blocker.
//!
//! All only decide what is also what tracing would find, so the image is
//! the same with skipping on or off.

use glam::{DVec3, Vec3};

use super::geometry::{Aabb, Shape, Slot};
use super::light_frame::{Eye, LightFrame, OccluderBvh};
use super::math::avx2_dispatch;
use super::ray_packet::{PACKET, RayBins};
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
    /// The light points binned per packet of 64 rays, and the fixed pattern
    /// they were binned for (a pattern drawn per hit point is binned anew).
    bins: Vec<RayBins>,
    bins_for: Option<(super::scene_file::Sampling, u32)>,
    scratch: PacketScratch,
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
            bins: Vec::with_capacity(points.div_ceil(PACKET)),
            bins_for: None,
            scratch: PacketScratch::default(),
        }
    }
}

/// An object as seen from one hit point, in f32 relative to it.
#[derive(Debug, Clone, Copy)]
enum Occluder {
    /// `oc`: centre − p; `r2`: the radius squared.
    Sphere { oc: Vec3, r2: f32, inside: bool },
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
            Shape::Sphere(s) => Occluder::Sphere {
                oc: (s.centre - p).as_vec3(),
                r2: (s.radius * s.radius) as f32,
                inside,
            },
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
    fn block(&self, d: Dirs, vis: &mut [f32]) {
        block(self, d, vis)
    }

    #[inline(always)]
    fn block_generic(&self, d: Dirs, vis: &mut [f32]) {
        let n = vis.len();
        let (dx, dy, dz) = (&d.x[..n], &d.y[..n], &d.z[..n]);
        match *self {
            Occluder::Sphere { oc, r2, inside } => {
                for j in 0..n {
                    let blocked = sphere_blocks(oc, r2, inside, dx[j], dy[j], dz[j]);
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
        let dirs = Dirs {
            x: &[d.x],
            y: &[d.y],
            z: &[d.z],
        };
        self.block(dirs, &mut v);
        v[0] == 0.0
    }
}

/// Whether the ray (x, y, z) from the hit point meets the sphere (centre
/// `oc` from the hit point, radius² `r2`) before [`RAY_END`]. One lane of
/// the vector loop, and the scalar test of a lone ray: the same operations,
/// so the same answer.
#[inline(always)]
fn sphere_blocks(oc: Vec3, r2: f32, inside: bool, x: f32, y: f32, z: f32) -> bool {
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
    // With many objects, shadow rays walk the light-frame BVH as packets
    // whose nodes keep only the rays that can meet them.
    let packets = scene.shadow_bvh.as_ref().filter(|_| skip).map(|sb| {
        let p = sb.frame.local(q.point);
        // Wider than the rounding of the f32 ray tests by orders of
        // magnitude (their decisions move by ~1e-6 of the distances), so
        // no ray the full test would find blocked is left out.
        let margin = 1e-4 * (p.abs().max_element() + light.edge_u.length() + light.edge_v.length());
        Packets {
            sb,
            eye: Eye::new(p, margin),
            q,
        }
    });

    // Traces rays (directions and visibility as parallel slices) against the
    // candidates; returns how many facing rays met a candidate test.
    let occluders = &buf.occluders;
    let trace = |rays: Rays, facing: u64, bins: Option<&[RayBins]>| -> u64 {
        let Rays {
            a,
            b,
            d,
            vis,
            scratch,
            count,
        } = rays;
        let mut tested = if occluders.is_empty() { 0 } else { facing };
        for c in occluders {
            c.occ.block(d.range(0..count), &mut vis[..count]);
        }
        if let Some(pk) = &packets {
            let mut own_bins;
            for (k, start) in (0..count).step_by(PACKET).enumerate() {
                let n = PACKET.min(count - start);
                let bins = match bins {
                    Some(bins) => &bins[k],
                    None => {
                        own_bins =
                            RayBins::new(&pk.sb.frame, &a[start..start + n], &b[start..start + n]);
                        &own_bins
                    }
                };
                let end = (start + n).next_multiple_of(8);
                let r = packet(
                    pk,
                    scene,
                    bins,
                    [&a[start..start + n], &b[start..start + n]],
                    d.range(start..end),
                    &mut vis[start..end],
                    scratch,
                );
                if occluders.is_empty() {
                    tested += r.count_ones() as u64;
                }
            }
            return tested;
        }
        let mut traced = !occluders.is_empty();
        // The BVH, nearest nodes first, each leaf's objects blocking rays at
        // once, until no ray is left (an any-hit traversal for the whole
        // packet; the result does not depend on the order).
        let (d, vis) = (d.range(0..count), &mut vis[..count]);
        if !scene.bvh.is_empty() && (!skip || vis.iter().any(|&v| v != 0.0)) {
            scene.bvh.visit_near_first(
                q.point,
                |b| !skip || pyramid.may_overlap(b),
                |i| {
                    let Some(c) = candidate(i) else {
                        return true;
                    };
                    traced = true;
                    c.occ.block(d, vis);
                    !skip || vis.iter().any(|&v| v != 0.0)
                },
            );
        }
        if traced { facing } else { 0 }
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
        let mut probe = [[0.0f32; ADAPTIVE_PROBES]; 6];
        let mut facing_probes = 0.0;
        for (k, &(_, j)) in nearest.iter().enumerate() {
            probe[0][k] = buf.a[j];
            probe[1][k] = buf.b[j];
            probe[2][k] = buf.dx[j];
            probe[3][k] = buf.dy[j];
            probe[4][k] = buf.dz[j];
            probe[5][k] = buf.vis[j];
            facing_probes += buf.vis[j];
        }
        let [pa, pb, px, py, pz, pvis] = &mut probe;
        let rays = Rays {
            a: pa,
            b: pb,
            d: Dirs {
                x: px,
                y: py,
                z: pz,
            },
            vis: pvis,
            scratch: &mut PacketScratch::default(),
            count: ADAPTIVE_PROBES,
        };
        let traced = trace(rays, facing_probes as u64, None) > 0;
        let visible: f32 = pvis.iter().sum();
        if !traced && packets.is_none() {
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

    // The packets' bins depend only on the light points: a fixed pattern's
    // serve every hit point of the tile.
    let bins = match &packets {
        Some(pk) => {
            if buf.filled.is_none() || buf.bins_for != buf.filled {
                buf.bins.clear();
                for start in (0..count).step_by(PACKET) {
                    let end = (start + PACKET).min(count);
                    buf.bins.push(RayBins::new(
                        &pk.sb.frame,
                        &buf.a[start..end],
                        &buf.b[start..end],
                    ));
                }
                buf.bins_for = buf.filled;
            }
            Some(&buf.bins[..])
        }
        None => None,
    };
    let rays = Rays {
        a: &buf.a,
        b: &buf.b,
        d: Dirs {
            x: &buf.dx,
            y: &buf.dy,
            z: &buf.dz,
        },
        vis: &mut buf.vis,
        scratch: &mut buf.scratch,
        count,
    };
    let tested = trace(rays, facing, bins);
    stats.shadow += tested;
    stats.shadow_unoccluded += facing - tested;
}

/// Shadow rays as parallel slices: light points, directions, visibility.
/// The slices reach past `count` to a multiple of 8 (padding rays are
/// invisible).
struct Rays<'a> {
    a: &'a [f32],
    b: &'a [f32],
    d: Dirs<'a>,
    vis: &'a mut [f32],
    scratch: &'a mut PacketScratch,
    count: usize,
}

/// One hit point's shadow rays against the light-frame BVH.
struct Packets<'a> {
    sb: &'a OccluderBvh,
    /// The hit point in the light's frame.
    eye: Eye,
    q: &'a ShadowQuery,
}

avx2_dispatch!(
    /// Traces up to 64 rays (light points `ab`, directions and visibility
    /// as slices of whole chunks of 8) through the light-frame BVH; returns
    /// the rays tested against at least one object.
    #[allow(clippy::too_many_arguments)]
    fn packet(pk: &Packets, scene: &Scene, bins: &RayBins, ab: [&[f32]; 2], d: Dirs, vis: &mut [f32], scratch: &mut PacketScratch) -> u64
        => packet_generic
);

/// Rays left in a packet below which they walk the tree one by one: a
/// slab test per ray and box is then cheaper than the footprints.
const SOLO: u32 = 2;

/// Scratch space of the packet traversal.
#[derive(Debug, Default)]
pub struct PacketScratch {
    /// Nodes to visit, with the rays that may meet each.
    stack: Vec<(u32, u64)>,
    /// Nodes to visit by one ray.
    solo: Vec<u32>,
}

// Lanes of parallel arrays: index loops are what vectorizes.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn packet_generic(
    pk: &Packets,
    scene: &Scene,
    bins: &RayBins,
    ab: [&[f32]; 2],
    d: Dirs,
    vis: &mut [f32],
    scratch: &mut PacketScratch,
) -> u64 {
    let PacketScratch { stack, solo } = scratch;
    let mut live = live_rays(vis) & bins.all;
    let tree = &pk.sb.tree;
    if live == 0 || tree.nodes.is_empty() {
        return 0;
    }
    let mut tested = 0;
    // Tests object i against the rays `m` (and whichever share their chunks
    // of 8); returns the rays still live. Every answer is the exact f32
    // test, so the order of the tests changes nothing but the time.
    let mut test = |i: u32, m: u64, live: u64| -> u64 {
        let inside = i == pk.q.object && pk.q.inside;
        if i == pk.q.object && !inside {
            return live;
        }
        tested |= m;
        let occ = Occluder::new(&scene.objects[i as usize].shape, pk.q.point, inside);
        if let Occluder::Sphere { oc, r2, inside } = occ
            && m.count_ones() <= 4
        {
            // A few rays: the lane test alone, without a vector call.
            let mut live = live;
            let mut rays = m;
            while rays != 0 {
                let j = rays.trailing_zeros() as usize;
                rays &= rays - 1;
                if sphere_blocks(oc, r2, inside, d.x[j], d.y[j], d.z[j]) {
                    vis[j] = 0.0;
                    live &= !(1 << j);
                }
            }
            return live;
        }
        // The chunks from the first to the last ray to test, in one call.
        let first = m.trailing_zeros() as usize / 8 * 8;
        let past = (64 - m.leading_zeros() as usize).div_ceil(8) * 8;
        let r = first..past;
        let v = &mut vis[r.clone()];
        occ.block(d.range(r), v);
        let span = (u64::MAX >> (64 - (past - first))) << first;
        live & (!span | (live_rays(v) << first))
    };

    // Depth-first; each entry holds the rays that may meet the node.
    stack.clear();
    stack.push((0, live));
    while let Some((index, rays)) = stack.pop() {
        let rays = rays & live;
        if rays == 0 {
            continue;
        }
        if rays.count_ones() <= SOLO {
            // Each ray alone through this subtree, nearest boxes first.
            let mut each = rays;
            while each != 0 {
                let j = each.trailing_zeros() as usize;
                each &= each - 1;
                if live & (1 << j) == 0 {
                    // Blocked meanwhile, by a test of its chunk.
                    continue;
                }
                let ray = pk
                    .eye
                    .segment(pk.sb.frame.light_point(ab[0][j] as f64, ab[1][j] as f64));
                solo.clear();
                solo.push(index);
                'walk: while let Some(n) = solo.pop() {
                    let node = &tree.nodes[n as usize];
                    let (hit, near) = ray.hits(node);
                    let mut next = [(0.0f32, 0u32); 4];
                    let mut n_next = 0;
                    for s in 0..4 {
                        if !hit[s] {
                            continue;
                        }
                        match node.slot(s) {
                            Slot::Empty => {}
                            Slot::Node(c) => {
                                next[n_next] = (near[s], c);
                                n_next += 1;
                            }
                            Slot::Object(i) => {
                                live = test(i, 1 << j, live);
                                if live == 0 {
                                    return tested;
                                }
                                if live & (1 << j) == 0 {
                                    break 'walk;
                                }
                            }
                        }
                    }
                    let next = &mut next[..n_next];
                    sort_far_first(next);
                    solo.extend(next.iter().map(|&(_, c)| c));
                }
            }
            continue;
        }
        let node = &tree.nodes[index as usize];
        let feet = LightFrame::footprints(&pk.eye, node);
        let masks = bins.rays_in4(&feet);
        let mut next = [(0.0f64, (0u32, 0u64)); 4];
        let mut n_next = 0;
        for s in 0..4 {
            let m = masks[s] & rays & live;
            if m == 0 {
                continue;
            }
            match node.slot(s) {
                Slot::Empty => {}
                Slot::Node(c) => {
                    next[n_next] = (feet.near[s], (c, m));
                    n_next += 1;
                }
                Slot::Object(i) => {
                    live = test(i, m, live);
                    if live == 0 {
                        return tested;
                    }
                }
            }
        }
        // Push the farthest first so that the nearest is visited next.
        let next = &mut next[..n_next];
        sort_far_first(next);
        stack.extend(next.iter().map(|&(_, c)| c));
    }
    tested
}

/// Sorts up to four children by distance, farthest first (so that the
/// nearest is popped next): an insertion sort the compiler unrolls.
#[inline(always)]
fn sort_far_first<K: PartialOrd + Copy, T: Copy>(v: &mut [(K, T)]) {
    for i in 1..v.len() {
        let x = v[i];
        let mut k = i;
        while k > 0 && v[k - 1].0 < x.0 {
            v[k] = v[k - 1];
            k -= 1;
        }
        v[k] = x;
    }
}

/// Bit j set where `vis[j]` is not 0 (at most 64 rays, whole chunks of 8:
/// each chunk becomes one compare and one move-mask).
#[inline(always)]
fn live_rays(vis: &[f32]) -> u64 {
    let mut m = 0;
    for (c, chunk) in vis.chunks_exact(8).enumerate() {
        let mut byte = 0u64;
        for (i, &v) in chunk.iter().enumerate() {
            byte |= ((v != 0.0) as u64) << i;
        }
        m |= byte << (8 * c);
    }
    m
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
    fn block(occ: &Occluder, d: Dirs, vis: &mut [f32]) => block_generic
);

#[inline(always)]
fn block_generic(occ: &Occluder, d: Dirs, vis: &mut [f32]) {
    occ.block_generic(d, vis)
}

/// Directions of shadow rays as parallel slices (unnormalized: from the
/// hit point to the light point).
#[derive(Clone, Copy)]
struct Dirs<'a> {
    x: &'a [f32],
    y: &'a [f32],
    z: &'a [f32],
}

impl<'a> Dirs<'a> {
    fn range(self, r: std::ops::Range<usize>) -> Dirs<'a> {
        Dirs {
            x: &self.x[r.clone()],
            y: &self.y[r.clone()],
            z: &self.z[r],
        }
    }
}
