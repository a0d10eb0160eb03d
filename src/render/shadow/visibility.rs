//! Which of a hit point's light points are visible: culling, the umbra
//! test, adaptive probes, and the tracing itself.

use std::cell::OnceCell;

use glam::{DVec3, Vec3};

use super::buffers::ShadowBuffers;
use super::cells::{ObjectBits, OccluderCells};
use super::light_frame::Eye;
use super::occluder::{Dirs, Occluder};
use super::packet::{PacketScratch, Packets, packet};
use super::pyramid::ShadowPyramid;
use super::ray_packet::{PACKET, RayBins};
use crate::render::geometry::{Aabb, Bvh, Primitive, Shape};
use crate::render::math::{WIDE_POINTS, avx2_dispatch, avx512_dispatch};
use crate::render::scene::Scene;
use crate::render::settings::RenderSettings;
use crate::render::stats::RayStats;

/// Rays traced first by the adaptive mode.
const ADAPTIVE_PROBES: usize = 8;

/// From this many light points per hit point on, the umbra test (four
/// corner rays per convex candidate) is tried before tracing: with fewer,
/// tracing the rays themselves costs less and finds the same.
const UMBRA_TEST_RAYS: usize = 4;

/// A possible occluder of one hit point.
#[derive(Debug, Clone, Copy)]
pub(super) struct Candidate {
    occ: Occluder,
    /// Convex and wholly between the hit point's side and the light's plane:
    /// may decide the umbra test.
    umbra_test: bool,
}

avx512_dispatch!(
    /// Clears `vis[j]` for every ray some candidate blocks (one call, and
    /// one dispatch, for all of a hit point's candidates).
    fn block_all(occs: &[Candidate], d: Dirs, vis: &mut [f32]) => block_all_generic if vis.len() >= WIDE_POINTS
);

avx512_dispatch!(
    /// [`block_all`] of the candidates among `listed` (all objects where
    /// it is `ObjectBits::MAX`), each made and tested in turn; whether
    /// there was one.
    fn block_candidates(
        culling: &Culling<'_>,
        listed: ObjectBits,
        objects: &[u32],
        d: Dirs,
        vis: &mut [f32],
    ) -> bool => block_candidates_generic if vis.len() >= WIDE_POINTS
);

#[inline(always)]
fn block_candidates_generic(
    culling: &Culling<'_>,
    listed: ObjectBits,
    objects: &[u32],
    d: Dirs,
    vis: &mut [f32],
) -> bool {
    let mut any = false;
    let mut block = |i: u32| {
        if let Some(c) = culling.candidate(i) {
            any = true;
            c.occ.block_inline(d, vis);
        }
    };
    if listed == ObjectBits::MAX {
        let scene = culling.scene;
        for &i in scene.unbounded.iter().chain(scene.bounded.iter()) {
            block(i);
        }
    } else {
        for i in each_bit(listed, objects) {
            block(i);
        }
    }
    any
}

#[inline(always)]
fn block_all_generic(occs: &[Candidate], d: Dirs, vis: &mut [f32]) {
    for c in occs {
        c.occ.block_inline(d, vis);
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

avx2_dispatch!(
    /// Fills `buf.dx/dy/dz` from `buf.a/b` and `buf.vis` with each point's
    /// visibility (1 or 0), for the first `count` points. Compiled for AVX2
    /// as a whole where the CPU has it: the culling's scalar f64 arithmetic
    /// then takes fewer instructions (the same operations, so the same
    /// decisions).
    pub fn visibility(
        scene: &Scene,
        settings: &RenderSettings,
        q: &ShadowQuery,
        count: usize,
        buf: &mut ShadowBuffers,
        stats: &mut RayStats,
    ) => visibility_inline
);

/// [`visibility`] inlined into the caller, compiled for its CPU features
/// (the same operations, so the same bits).
#[inline(always)]
pub(crate) fn visibility_inline(
    scene: &Scene,
    settings: &RenderSettings,
    q: &ShadowQuery,
    count: usize,
    buf: &mut ShadowBuffers,
    stats: &mut RayStats,
) {
    let light = &scene.light.shape;
    let to_corner = (light.corner - q.point).as_vec3();
    let (eu, ev) = (light.edge_u.as_vec3(), light.edge_v.as_vec3());
    let n = q.normal.as_vec3();
    // Below sixteen points, inlined: this kernel is compiled for the same
    // CPU features as the eight-lane one it would call (the same bits,
    // without two calls and a dispatch per hit point).
    let facing = if count < WIDE_POINTS {
        light_directions_generic(to_corner, eu, ev, n, count, buf)
    } else {
        light_directions(to_corner, eu, ev, n, count, buf)
    };
    stats.shadow_backfacing += count as u64 - facing;
    if facing == 0 {
        return;
    }
    if !settings.shadows {
        stats.shadow_disabled += facing;
        return;
    }

    let skip = settings.skip;
    // The objects that may block a ray from p's cube of space (all of
    // them when not skipping).
    // (An `if`, not `bool::then` with a closure: a closure may stay a call of
    // baseline code, outside the kernel's CPU features.)
    let list = if skip {
        buf.cells.list_at(scene, q.point)
    } else {
        None
    };
    let (listed, bvh_may_block) = match list {
        Some(list) => {
            let own = |i: u32| i == q.object && scene.primitive(i).skips_itself(q.inside);
            if !list.bvh && each_bit(list.objects, buf.cells.objects()).all(own) {
                stats.shadow_unoccluded += facing;
                return;
            }
            (list.objects, list.bvh)
        }
        None => (ObjectBits::MAX, true),
    };
    // The BVH's objects, unless the cube's list leaves them all out.
    let bvh = (bvh_may_block && !scene.bvh.is_empty()).then_some(&*scene.bvh);
    let umbra_tested = skip && count >= UMBRA_TEST_RAYS;
    let corners = light.corners();
    let pyramid = LazyPyramid::new(q.point, corners, scene);
    let culling = Culling {
        scene,
        q,
        skip,
        umbra_tested,
        pyramid: &pyramid,
        reach: longest_ray(q.point, &corners),
    };

    let adaptive = settings.adaptive && count >= 4 * ADAPTIVE_PROBES;
    let walks_packets = skip && bvh.is_some() && scene.shadow_bvh.is_some();
    if !umbra_tested && !adaptive && !walks_packets {
        // Nothing reads the candidates twice: each one blocks the rays as
        // it is made, in the same order, instead of being stored and read
        // back (the same tests, so the same bits and counts).
        let (d, vis) = (
            Dirs {
                x: &buf.dx,
                y: &buf.dy,
                z: &buf.dz,
            }
            .range(0..count),
            &mut buf.vis[..count],
        );
        let listed_traced = block_candidates(&culling, listed, buf.cells.objects(), d, vis);
        if !listed_traced && bvh.is_none() {
            stats.shadow_unoccluded += facing;
            return;
        }
        let tree_traced = culling.block_by_tree(bvh, d, vis);
        let tested = if listed_traced || tree_traced {
            facing
        } else {
            0
        };
        stats.shadow += tested;
        stats.shadow_unoccluded += facing - tested;
        return;
    }

    // Objects outside the BVH (planes, and all objects of small scenes).
    buf.occluders.clear();
    if listed == ObjectBits::MAX {
        for &i in scene.unbounded.iter().chain(scene.bounded.iter()) {
            if let Some(c) = culling.candidate(i) {
                buf.occluders.push(c);
            }
        }
    } else {
        for i in each_bit(listed, buf.cells.objects()) {
            if let Some(c) = culling.candidate(i) {
                buf.occluders.push(c);
            }
        }
    }
    if buf.occluders.is_empty() && bvh.is_none() {
        stats.shadow_unoccluded += facing;
        return;
    }
    if umbra_tested {
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
    let packets = scene
        .shadow_bvh
        .as_ref()
        .filter(|_| skip && bvh.is_some())
        .map(|sb| {
            let p = sb.frame.local(q.point);
            // Wider than the rounding of the f32 ray tests by orders of
            // magnitude (their decisions move by ~1e-6 of the distances), so
            // no ray the full test would find blocked is left out.
            let margin =
                1e-4 * (p.abs().max_element() + light.edge_u.length() + light.edge_v.length());
            Packets {
                sb,
                eye: Eye::new(p, margin),
                q,
                reach: culling.reach,
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
        let mut tested = 0;
        if !occluders.is_empty() {
            tested = facing;
            block_all(occluders, d.range(0..count), &mut vis[..count]);
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
        let tree_traced = culling.block_by_tree(bvh, d.range(0..count), &mut vis[..count]);
        if tree_traced || !occluders.is_empty() {
            facing
        } else {
            0
        }
    };

    if adaptive {
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

/// The pyramid from a hit point to the light, built when first asked for:
/// planes are culled without it, and most hit points test nothing else.
struct LazyPyramid {
    p: DVec3,
    corners: [DVec3; 4],
    light_normal: DVec3,
    light_centre: DVec3,
    built: OnceCell<ShadowPyramid>,
}

impl LazyPyramid {
    #[inline(always)]
    fn new(p: DVec3, corners: [DVec3; 4], scene: &Scene) -> LazyPyramid {
        let light = &scene.light.shape;
        LazyPyramid {
            p,
            corners,
            light_normal: light.normal,
            light_centre: light.centre(),
            built: OnceCell::new(),
        }
    }

    #[inline(always)]
    fn get(&self) -> &ShadowPyramid {
        if let Some(pyramid) = self.built.get() {
            return pyramid;
        }
        // Built here, not in `get_or_init`'s closure: that would be a call
        // of code compiled without the kernel's CPU features.
        let pyramid =
            ShadowPyramid::new(self.p, &self.corners, self.light_normal, self.light_centre);
        self.built.get_or_init(|| pyramid)
    }
}

/// What decides whether an object is a possible occluder of one hit point.
struct Culling<'a> {
    scene: &'a Scene,
    q: &'a ShadowQuery,
    skip: bool,
    umbra_tested: bool,
    pyramid: &'a LazyPyramid,
    /// See [`longest_ray`].
    reach: f32,
}

/// A bound on the length of every shadow ray from `p` (the light is convex:
/// its farthest point is a corner), with room for the rays' rounding.
#[inline(always)]
pub(super) fn longest_ray(p: DVec3, corners: &[DVec3; 4]) -> f32 {
    let longest2 = corners
        .iter()
        .map(|c| c.distance_squared(p))
        .fold(0.0, f64::max);
    (longest2.sqrt() * (1.0 + 1e-3)) as f32
}

impl Culling<'_> {
    /// Clears `vis[j]` for every ray an object of `bvh` blocks: the tree,
    /// nearest nodes first, each leaf's objects blocking rays at once, until
    /// no ray is left (an any-hit traversal for the whole packet; the
    /// result does not depend on the order). Whether some object of the
    /// tree was a candidate.
    #[inline(always)]
    fn block_by_tree(&self, bvh: Option<&Bvh>, d: Dirs, vis: &mut [f32]) -> bool {
        let mut traced = false;
        let skip = self.skip;
        if let Some(bvh) = bvh
            && (!skip || vis.iter().any(|&v| v != 0.0))
        {
            bvh.visit_near_first(
                self.q.point,
                |b| !skip || self.pyramid.get().may_overlap(b),
                |i| {
                    let Some(c) = self.candidate(i) else {
                        return true;
                    };
                    traced = true;
                    c.occ.block(d, vis);
                    !skip || vis.iter().any(|&v| v != 0.0)
                },
            );
        }
        traced
    }

    /// Object `i` as a possible occluder of the hit point, unless it can
    /// certainly block nothing. A function, not a closure, so that it is
    /// inlined into (and compiled for the same CPU features as) the
    /// kernel that calls it: a closure stays a call of baseline code.
    #[inline(always)]
    fn candidate(&self, i: u32) -> Option<Candidate> {
        let (scene, q) = (self.scene, self.q);
        let light = &scene.light.shape;
        let prim = scene.primitive(i);
        let inside = i == q.object && q.inside;
        if i == q.object && prim.skips_itself(q.inside) {
            return None;
        }
        let bounds = scene.bounds_of(i);
        if self.skip
            && cannot_block(
                prim,
                bounds,
                q.point,
                &scene.light_sides_of(i),
                self.pyramid,
            )
        {
            return None;
        }
        let umbra_test = self.umbra_tested
            && !inside
            && prim.convex()
            && match bounds {
                // Planes block a light point iff it lies on their other side:
                // all four corners there means the whole light.
                None => true,
                Some(b) => {
                    let x = DVec3::select(light.normal.cmpge(DVec3::ZERO), b.min, b.max);
                    light.signed_distance(x) > 0.0
                }
            };
        Some(Candidate {
            occ: Occluder::new(prim, q.point, inside, self.reach),
            umbra_test,
        })
    }
}

/// Whether primitive `prim` (of bounds `bounds`) certainly blocks no
/// shadow ray from `p` to the light (of pyramid `pyramid` from p; a
/// plane's `sides`: its signed distances of the light's corners, from
/// [`Scene::light_sides_of`]).
#[inline(always)]
fn cannot_block(
    prim: Primitive,
    bounds: Option<Aabb>,
    p: DVec3,
    sides: &[f64; 4],
    pyramid: &LazyPyramid,
) -> bool {
    match prim {
        // A plane blocks only if some light point lies on its other side
        // from p.
        Primitive::Shape(Shape::Plane(pl)) => {
            let sp = pl.signed_distance(p);
            sides.iter().all(|&c| c * sp > 0.0)
        }
        // The sphere itself is a tighter test than its box.
        Primitive::Shape(Shape::Sphere(sp)) => {
            !pyramid.get().may_overlap_sphere(sp.centre, sp.radius)
        }
        _ => bounds.is_some_and(|b| !pyramid.get().may_overlap(&b)),
    }
}

/// The objects that may block a shadow ray of `q` (the culling of
/// [`visibility`], without its rays), each with whether q lies inside it
/// (hit from inside: the object is kept, and only its exit counts). Only
/// the objects of q's cube of space are tested where `cells` list them.
pub(crate) fn possible_occluders(
    scene: &Scene,
    q: &ShadowQuery,
    cells: &mut OccluderCells,
    out: &mut Vec<(u32, bool)>,
) {
    out.clear();
    // The cube's list of the objects tested one by one; the BVH is walked
    // as before (its pyramid test keeps the same occluders).
    let listed = cells.list_at(scene, q.point).map(|list| list.objects);
    let own = |i: u32| i == q.object && scene.primitive(i).skips_itself(q.inside);
    if scene.bvh.is_empty() && listed.is_some_and(|bits| each_bit(bits, cells.objects()).all(own)) {
        return;
    }
    let light = &scene.light.shape;
    let pyramid = LazyPyramid::new(q.point, light.corners(), scene);
    let mut consider = |i: u32| {
        let prim = scene.primitive(i);
        if i == q.object && prim.skips_itself(q.inside) {
            return;
        }
        if !cannot_block(
            prim,
            scene.bounds_of(i),
            q.point,
            &scene.light_sides_of(i),
            &pyramid,
        ) {
            out.push((i, i == q.object && q.inside));
        }
    };
    match listed {
        Some(bits) => each_bit(bits, cells.objects()).for_each(&mut consider),
        None => scene
            .unbounded
            .iter()
            .chain(scene.bounded.iter())
            .for_each(|&i| consider(i)),
    }
    scene.bvh.visit_near_first(
        q.point,
        |b| pyramid.get().may_overlap(b),
        |i| {
            consider(i);
            true
        },
    );
}

/// The objects of `objects` whose bits are set in `bits`, in order.
#[inline(always)]
fn each_bit(mut bits: ObjectBits, objects: &[u32]) -> impl Iterator<Item = u32> + '_ {
    std::iter::from_fn(move || {
        if bits == 0 {
            return None;
        }
        let k = bits.trailing_zeros();
        bits &= bits - 1;
        Some(objects[k as usize])
    })
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

avx512_dispatch!(
    /// Directions from the hit point to the light points, and 1 in `vis` for
    /// those in front of the surface; returns how many are.
    pub(crate) fn light_directions(to_corner: Vec3, eu: Vec3, ev: Vec3, n: Vec3, count: usize, buf: &mut ShadowBuffers) -> u64
        => light_directions_generic if count >= WIDE_POINTS
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
    // Counted as integers: a float sum of the ones would be one chain of
    // dependent additions (the same value, exact below 2²⁴, far slower).
    // As u32 (a hit has at most 4096 rays), lane for lane with the f32s: u64
    // counts halve the vectorized loop's width.
    let mut facing = 0u32;
    for j in 0..count {
        let ((x, y, z), front) = light_direction(to_corner, (eu, ev), n, (a[j], b[j]));
        dx[j] = x;
        dy[j] = y;
        dz[j] = z;
        vis[j] = if front { 1.0 } else { 0.0 };
        facing += front as u32;
    }
    u64::from(facing)
}

/// The direction from a hit point (light corner − point `to_corner`) to
/// the light point at offsets (a, b) along the light's edges `eu`, `ev`,
/// and whether it lies in front of the surface of normal `n`. One lane of
/// the vector loops.
#[inline(always)]
pub(super) fn light_direction(
    to_corner: Vec3,
    (eu, ev): (Vec3, Vec3),
    n: Vec3,
    (a, b): (f32, f32),
) -> ((f32, f32, f32), bool) {
    let (x, y, z) = (
        to_corner.x + eu.x * a + ev.x * b,
        to_corner.y + eu.y * a + ev.y * b,
        to_corner.z + eu.z * a + ev.z * b,
    );
    ((x, y, z), n.x * x + n.y * y + n.z * z > 0.0)
}
