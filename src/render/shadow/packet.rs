//! Shadow rays as packets through the BVH built in the light's frame.

use super::RAY_END;
use super::light_frame::{Eye, LightFrame, OccluderBvh};
use super::occluder::{Dirs, Occluder, sphere_blocks};
use super::ray_packet::RayBins;
use super::visibility::ShadowQuery;
use glam::Vec3;

use crate::render::geometry::{Primitive, Shape, Slot, TriangleOccluder};
use crate::render::math::avx2_dispatch;
use crate::render::scene::Scene;

/// One hit point's shadow rays against the light-frame BVH.
pub(super) struct Packets<'a> {
    pub(super) sb: &'a OccluderBvh,
    /// The hit point in the light's frame.
    pub(super) eye: Eye,
    pub(super) q: &'a ShadowQuery,
    /// A bound on the length of every shadow ray (see `Occluder::new`).
    pub(super) reach: f32,
}

avx2_dispatch!(
    /// Traces up to 64 rays (light points `ab`, directions and visibility
    /// as slices of whole chunks of 8) through the light-frame BVH; returns
    /// the rays tested against at least one object.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn packet(pk: &Packets, scene: &Scene, bins: &RayBins, ab: [&[f32]; 2], d: Dirs, vis: &mut [f32], scratch: &mut PacketScratch) -> u64
        => packet_generic
);

/// Rays left in a packet up to which they walk the tree one by one: a
/// slab test per ray and box is then cheaper than the footprints.
const SOLO: u32 = 2;

/// Whether `m` has at most `n` bits set: `n` times the lowest cleared. Bit
/// arithmetic, as the kernels' CPU features leave out the popcount.
#[inline(always)]
fn at_most(m: u64, n: u32) -> bool {
    let mut rest = m;
    for _ in 0..n {
        rest &= rest.wrapping_sub(1);
    }
    rest == 0
}

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
    let mut tests = Tests {
        pk,
        scene,
        bins,
        d,
        vis,
        tested: 0,
    };
    let mut lone = [0];
    // Depth-first; each entry holds the rays that may meet the node.
    stack.clear();
    stack.push((0, live));
    while let Some((index, rays)) = stack.pop() {
        let rays = rays & live;
        if rays == 0 {
            continue;
        }
        if at_most(rays, SOLO) {
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
                            objects => {
                                for &i in slot_objects(objects, &tree.items, &mut lone) {
                                    live = tests.test(i, 1 << j, live);
                                    if live == 0 {
                                        return tests.tested;
                                    }
                                    if live & (1 << j) == 0 {
                                        break 'walk;
                                    }
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
                objects => {
                    for &i in slot_objects(objects, &tree.items, &mut lone) {
                        live = tests.test(i, m & live, live);
                        if live == 0 {
                            return tests.tested;
                        }
                        if m & live == 0 {
                            break;
                        }
                    }
                }
            }
        }
        // Push the farthest first so that the nearest is visited next.
        let next = &mut next[..n_next];
        sort_far_first(next);
        stack.extend(next.iter().map(|&(_, c)| c));
    }
    tests.tested
}

/// The objects of an object or leaf slot (a lone object is put in `lone`):
/// one loop, so one inlined copy of the object test per walk.
#[inline(always)]
fn slot_objects<'s>(slot: Slot, items: &'s [u32], lone: &'s mut [u32; 1]) -> &'s [u32] {
    match slot {
        Slot::Leaf { first, count } => &items[first as usize..(first + count) as usize],
        Slot::Object(i) => {
            lone[0] = i;
            lone
        }
        Slot::Empty | Slot::Node(_) => &[],
    }
}

/// Rays of one packet tested against single objects. A struct with an
/// inlined method, not a closure: a closure would stay a call of baseline
/// code, outside the kernel's CPU features.
struct Tests<'p, 'a> {
    pk: &'p Packets<'a>,
    scene: &'p Scene,
    bins: &'p RayBins,
    d: Dirs<'p>,
    vis: &'p mut [f32],
    /// The rays tested against at least one object.
    tested: u64,
}

impl Tests<'_, '_> {
    /// Tests object i against the rays `m` (and possibly others of their
    /// chunks of 8); returns the rays still live. Every answer is the
    /// exact f32 test, so which rays are tested together changes nothing
    /// but the time.
    // Lanes of parallel arrays: index loops are what vectorizes.
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    fn test(&mut self, i: u32, m: u64, live: u64) -> u64 {
        let pk = self.pk;
        let prim = self.scene.primitive(i);
        let inside = i == pk.q.object && pk.q.inside;
        if i == pk.q.object && prim.skips_itself(pk.q.inside) {
            return live;
        }
        match prim {
            Primitive::Face { meshes, face } => {
                // Its vertices read once, for the cull and the occluder.
                let v = meshes.vertices(face);
                // A face meets only the rays ending inside its own shadow on
                // the light: most rays of its leaf's footprint miss it.
                let m = match pk.sb.frame.triangle_footprint(&pk.eye, v) {
                    Some(rect) => m & self.bins.rays_in_rect(rect),
                    None => m,
                };
                if m & live == 0 {
                    return live;
                }
                let occ = TriangleOccluder::new(&v, pk.q.point, pk.reach);
                self.block(&Occluder::Triangle(occ), m, live)
            }
            // Spheres fill the generated rooms: inlined as well.
            Primitive::Shape(Shape::Sphere(_)) => {
                self.block(&Occluder::new(prim, pk.q.point, inside, pk.reach), m, live)
            }
            _ => shape_test(self, prim, inside, m, live),
        }
    }

    /// Clears the rays `m` (and possibly others of their chunks of 8) that
    /// `occ` blocks; returns the rays still live. Inlined into each kind
    /// of object's test, so that a face's knows its occluder's kind.
    // Lanes of parallel arrays: index loops are what vectorizes.
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    fn block(&mut self, occ: &Occluder, m: u64, live: u64) -> u64 {
        let d = self.d;
        self.tested |= m;
        let few = at_most(m, FEW);
        let vis = &mut *self.vis;
        let mut live = live;
        if few && let Some(blocks) = LoneRayTest::of(occ) {
            // A few rays: the lane test alone, without a vector call.
            let mut rays = m;
            while rays != 0 {
                let j = rays.trailing_zeros() as usize;
                rays &= rays - 1;
                if blocks.blocks(d.x[j], d.y[j], d.z[j]) {
                    vis[j] = 0.0;
                    live &= !(1 << j);
                }
            }
            return live;
        }
        // Bit 8c set where chunk c holds a ray of `m`.
        let mut chunks = m;
        for shift in [1, 2, 4] {
            chunks |= chunks >> shift;
        }
        chunks &= 0x0101_0101_0101_0101;
        if at_most(chunks, SPARSE_CHUNKS) {
            // The chunks holding rays of `m`, each inlined (eight lanes of
            // this kernel's vectors).
            while chunks != 0 {
                let c = chunks.trailing_zeros() as usize / 8;
                chunks &= chunks - 1;
                let r = 8 * c..8 * c + 8;
                let v = &mut vis[r.clone()];
                occ.block_inline(d.range(r), v);
                live &= !(0xff << (8 * c)) | (live_rays(v) << (8 * c));
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
    }
}

avx2_dispatch!(
    /// [`Tests::test`] of an object other than a face or sphere, out of
    /// line: the scenes that walk packets hold mostly those, and the
    /// kernel stays small.
    #[inline(never)]
    fn shape_test(tests: &mut Tests, prim: Primitive, inside: bool, m: u64, live: u64) -> u64
        => shape_test_generic
);

#[inline(always)]
fn shape_test_generic(tests: &mut Tests, prim: Primitive, inside: bool, m: u64, live: u64) -> u64 {
    let pk = tests.pk;
    tests.block(&Occluder::new(prim, pk.q.point, inside, pk.reach), m, live)
}

/// Chunks of 8 rays up to which a test covers only the chunks holding its
/// rays, inlined; beyond, the span from the first to the last in one
/// (wider) vector call.
const SPARSE_CHUNKS: u32 = 3;

/// Rays of a test up to which each is tested alone (the lane test without
/// a vector call).
const FEW: u32 = 4;

/// An occluder whose lane test, run on one ray, is cheap enough to beat
/// a vector call for a few rays.
/// (Borrowing the triangle: a copy of its f64 vertices per test costs.)
#[derive(Clone, Copy)]
enum LoneRayTest<'o> {
    Sphere { oc: Vec3, r2: f32, inside: bool },
    Triangle(&'o TriangleOccluder),
}

impl<'o> LoneRayTest<'o> {
    #[inline(always)]
    fn of(occ: &'o Occluder) -> Option<LoneRayTest<'o>> {
        match occ {
            &Occluder::Sphere { oc, r2, inside } => Some(LoneRayTest::Sphere { oc, r2, inside }),
            Occluder::Triangle(t) => Some(LoneRayTest::Triangle(t)),
            _ => None,
        }
    }

    /// The lane test of [`Occluder::block`] (the same operations, so the
    /// same answer).
    #[inline(always)]
    fn blocks(self, x: f32, y: f32, z: f32) -> bool {
        match self {
            LoneRayTest::Sphere { oc, r2, inside } => sphere_blocks(oc, r2, inside, x, y, z),
            LoneRayTest::Triangle(t) => t.blocks(x, y, z, RAY_END),
        }
    }
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
/// each chunk becomes two compares and two move-masks).
#[inline(always)]
pub(crate) fn live_rays(vis: &[f32]) -> u64 {
    let mut m = 0;
    for (c, chunk) in vis.chunks_exact(8).enumerate() {
        m |= (chunk_bits(chunk.try_into().expect("chunks of 8")) as u64) << (8 * c);
    }
    m
}

/// Bit i set where `chunk[i]` is not 0. On x86-64 with the move-mask of
/// its baseline SSE2 (the compiler packs the bits of a plain loop one
/// shift at a time).
#[inline(always)]
fn chunk_bits(chunk: &[f32; 8]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_cmpneq_ps, _mm_loadu_ps, _mm_movemask_ps, _mm_setzero_ps};
        // SAFETY: the chunk holds eight f32, read as two unaligned groups of
        // four; SSE2 is part of x86-64.
        unsafe {
            let zero = _mm_setzero_ps();
            let lo = _mm_loadu_ps(chunk.as_ptr());
            let hi = _mm_loadu_ps(chunk.as_ptr().add(4));
            let lo = _mm_movemask_ps(_mm_cmpneq_ps(lo, zero)) as u32;
            let hi = _mm_movemask_ps(_mm_cmpneq_ps(hi, zero)) as u32;
            lo | (hi << 4)
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let mut byte = 0;
        for (i, &v) in chunk.iter().enumerate() {
            byte |= ((v != 0.0) as u32) << i;
        }
        byte
    }
}
