//! Bounding volume hierarchy over the bounded primitives, built with the
//! surface area heuristic over binned centroids. Infinite planes stay
//! outside it (they have no bounds) and are tested on their own.
//!
//! Compact: a node is 32 bytes (an f32 box rounded outwards, so it holds
//! every point its f64 contents hold, and two u32s), and the build works on
//! 16-byte records moved in place. Subtrees of many primitives are built on
//! two threads, the root's records are binned on all, and a node's
//! partition bins its children's records as it moves them (one pass over
//! the records per level, not two); none of this changes the tree (tested
//! against the plain build, node for node). The tree decides only which
//! primitives a ray is tested against; the hit found is the nearest of
//! their own f64 tests whatever its shape.

use glam::{DVec3, UVec4, Vec3, Vec4};
use rayon::prelude::*;

use super::{Aabb, Ray};

#[derive(Debug, Clone, Copy)]
#[repr(C)]
struct Node {
    min: Vec3,
    /// Leaf: first index into `items`; inner: index of the left child (the
    /// right one follows it).
    first: u32,
    max: Vec3,
    /// Number of items in a leaf; 0 for an inner node.
    count: u32,
}

impl Node {
    const EMPTY: Node = Node {
        min: Vec3::splat(f32::INFINITY),
        first: 0,
        max: Vec3::splat(f32::NEG_INFINITY),
        count: 0,
    };

    #[inline]
    fn bounds(&self) -> Aabb {
        Aabb::new(self.min.as_dvec3(), self.max.as_dvec3())
    }
}

/// One primitive as the build sees it: its box snapped outwards to the
/// build's [`Grid`] (16-bit coordinates) and its id, 16 bytes, so that the
/// records of millions of triangles cost little beside the tree.
///
/// The lanes are i16 with a bias: 0–2 the box's lower corner (`lo − 32768`),
/// 4–6 its upper corner negated (`32767 − hi`), 3 and 7 the id's halves.
/// The union of two boxes is then the lane-wise minimum of their lanes (one
/// vector instruction; the id lanes of a union mean nothing), which is what
/// the binning does millions of times.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(16))]
struct BuildRef {
    lanes: [i16; 8],
}

impl BuildRef {
    /// The box holding nothing (its union with a box is that box).
    const EMPTY: BuildRef = BuildRef {
        lanes: [i16::MAX; 8],
    };

    fn new(lo: [u16; 3], hi: [u16; 3], id: u32) -> BuildRef {
        let l = |v: u16| (v as i32 - 32768) as i16;
        let h = |v: u16| (32767 - v as i32) as i16;
        BuildRef {
            lanes: [
                l(lo[0]),
                l(lo[1]),
                l(lo[2]),
                id as u16 as i16,
                h(hi[0]),
                h(hi[1]),
                h(hi[2]),
                (id >> 16) as u16 as i16,
            ],
        }
    }

    #[inline(always)]
    fn id(&self) -> u32 {
        self.lanes[3] as u16 as u32 | (self.lanes[7] as u16 as u32) << 16
    }

    /// The box holding both (the id lanes are left meaningless).
    #[inline(always)]
    fn union(self, o: BuildRef) -> BuildRef {
        let mut lanes = self.lanes;
        for (a, b) in lanes.iter_mut().zip(o.lanes) {
            *a = (*a).min(b);
        }
        BuildRef { lanes }
    }

    /// Twice the centre (the scale does not matter for binning), exact:
    /// `lo + hi` of the grid coordinates (the w lane is some other integer).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn centre2(&self) -> Vec4 {
        use std::arch::x86_64::*;
        // SAFETY: SSE2 is part of x86_64, and the lanes are 16 aligned
        // bytes.
        unsafe {
            let x = _mm_load_si128(self.lanes.as_ptr() as *const __m128i);
            let lo = _mm_srai_epi32(_mm_unpacklo_epi16(x, x), 16);
            let neg_hi = _mm_srai_epi32(_mm_unpackhi_epi16(x, x), 16);
            let c = _mm_add_epi32(_mm_sub_epi32(lo, neg_hi), _mm_set1_epi32(65535));
            Vec4::from(_mm_cvtepi32_ps(c))
        }
    }

    #[cfg(not(target_arch = "x86_64"))]
    #[inline(always)]
    fn centre2(&self) -> Vec4 {
        let c = |a: usize| (self.lanes[a] as i32 - self.lanes[a + 4] as i32 + 65535) as f32;
        Vec4::new(c(0), c(1), c(2), c(3))
    }

    /// [`BuildRef::centre2`] along `axis` minus 65535, in integers.
    #[inline(always)]
    fn centre2_less(&self, axis: usize) -> i32 {
        self.lanes[axis] as i32 - self.lanes[axis + 4] as i32
    }

    /// `hi − lo` per axis (0 for the empty box), exact, in the first three
    /// lanes of a vector (the fourth is some other number).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn extent4(&self) -> Vec4 {
        use std::arch::x86_64::*;
        // SAFETY: SSE2 is part of x86_64, and the lanes are 16 aligned
        // bytes.
        unsafe {
            let x = _mm_load_si128(self.lanes.as_ptr() as *const __m128i);
            let lo = _mm_srai_epi32(_mm_unpacklo_epi16(x, x), 16);
            let neg_hi = _mm_srai_epi32(_mm_unpackhi_epi16(x, x), 16);
            let e = _mm_sub_epi32(_mm_set1_epi32(-1), _mm_add_epi32(lo, neg_hi));
            Vec4::from(_mm_cvtepi32_ps(e)).max(Vec4::ZERO)
        }
    }

    /// `hi − lo` per axis (0 for the empty box), exact.
    #[cfg(not(target_arch = "x86_64"))]
    #[inline(always)]
    fn extent(&self) -> Vec3 {
        let e = |a: usize| ((-1 - self.lanes[a] as i32 - self.lanes[a + 4] as i32) as f32).max(0.0);
        Vec3::new(e(0), e(1), e(2))
    }

    /// The box in grid coordinates as f32 (empty: lower corner 65535,
    /// upper 0).
    #[inline]
    fn decode(&self) -> Box3 {
        let lo = |a: usize| (self.lanes[a] as i32 + 32768) as f32;
        let hi = |a: usize| (32767 - self.lanes[a + 4] as i32) as f32;
        Box3 {
            min: Vec4::new(lo(0), lo(1), lo(2), 0.0),
            max: Vec4::new(hi(0), hi(1), hi(2), 0.0),
        }
    }
}

/// A grid of 65,000 steps along the largest side of every box of a build
/// (the same step on all axes, so that areas keep their proportions), with
/// a margin of 100 steps around it.
#[derive(Debug, Clone, Copy)]
struct Grid {
    origin: DVec3,
    step: f64,
    inv_step: f64,
}

impl Grid {
    fn new(all: &Aabb) -> Grid {
        let ext = all.extent().max_element();
        let step = if ext > 0.0 && ext.is_finite() {
            ext / 65_000.0
        } else {
            1.0
        };
        Grid {
            origin: all.min - step * 100.0,
            step,
            inv_step: 1.0 / step,
        }
    }

    /// The record of primitive `id` with the box `b`: snapped one step
    /// further out than its rounding could need.
    #[inline]
    fn record(&self, id: u32, b: &Aabb) -> BuildRef {
        let lo = ((b.min - self.origin) * self.inv_step).map(floor) - 1.0;
        let hi = ((b.max - self.origin) * self.inv_step).map(ceil) + 1.0;
        let q = |x: f64| x.clamp(0.0, u16::MAX as f64) as u16;
        BuildRef::new([q(lo.x), q(lo.y), q(lo.z)], [q(hi.x), q(hi.y), q(hi.z)], id)
    }

    /// A box of grid coordinates in the world, rounded outwards to f32.
    fn world(&self, b: &BuildRef) -> (Vec3, Vec3) {
        let b = b.decode();
        let lo = self.origin + b.min.truncate().as_dvec3() * self.step;
        let hi = self.origin + b.max.truncate().as_dvec3() * self.step;
        (
            Vec3::new(round_down(lo.x), round_down(lo.y), round_down(lo.z)),
            Vec3::new(round_up(hi.x), round_up(hi.y), round_up(hi.z)),
        )
    }
}

/// `x.floor()` for |x| < 2⁶³ and NaN without the library call (x86_64
/// has no rounding instruction before SSE4.1); beyond that some number
/// that the grid's clamp turns into what it turns `x.floor()` into.
#[inline(always)]
fn floor(x: f64) -> f64 {
    let t = x as i64 as f64;
    let t = if t > x { t - 1.0 } else { t };
    if x.is_nan() { x } else { t }
}

/// `x.ceil()` as [`floor`] is `x.floor()`.
#[inline(always)]
fn ceil(x: f64) -> f64 {
    let t = x as i64 as f64;
    let t = if t < x { t + 1.0 } else { t };
    if x.is_nan() { x } else { t }
}

/// The largest f32 ≤ x (x itself if it is ±∞): `next_down` of the nearest
/// f32 where that lies above x, chosen without branches (which way the
/// rounding went is a coin toss).
#[inline]
pub fn round_down(x: f64) -> f32 {
    let y = x as f32;
    let b = y.to_bits();
    // next_down(y) for y not NaN and not −∞ (never above x).
    let below = if y == 0.0 {
        0x8000_0001
    } else if y > 0.0 {
        b.wrapping_sub(1)
    } else {
        b.wrapping_add(1)
    };
    f32::from_bits(if (y as f64) > x { below } else { b })
}

/// The smallest f32 ≥ x, as [`round_down`].
#[inline]
pub fn round_up(x: f64) -> f32 {
    let y = x as f32;
    let b = y.to_bits();
    // next_up(y) for y not NaN and not +∞ (never below x).
    let above = if y == 0.0 {
        1
    } else if y > 0.0 {
        b.wrapping_add(1)
    } else {
        b.wrapping_sub(1)
    };
    f32::from_bits(if (y as f64) < x { above } else { b })
}

/// An f32 box while building (the w lanes are ignored).
#[derive(Debug, Clone, Copy)]
struct Box3 {
    min: Vec4,
    max: Vec4,
}

impl Box3 {
    #[inline]
    fn extent(&self) -> Vec3 {
        (self.max - self.min).truncate().max(Vec3::ZERO)
    }
}

#[derive(Debug, Clone, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    /// Primitive ids in leaf order.
    items: Vec<u32>,
}

/// What a node holds.
pub enum NodeContent<'a> {
    /// Primitive ids.
    Leaf(&'a [u32]),
    /// The two children.
    Inner([u32; 2]),
}

const BINS: usize = 16;
const MAX_LEAF: usize = 4;
/// Depth beyond which nodes are split in half by count rather than by SAH:
/// with at most 2·10⁷ primitives the tree stays under 40 + 23 levels, within
/// the traversal stacks of 64.
const SAH_DEPTH: usize = 40;
/// Relative cost of visiting a node against testing one primitive.
const TRAVERSAL_COST: f32 = 1.0;
/// Subtrees of at least this many primitives build their two halves on two
/// threads.
const PARALLEL: usize = 16_384;

/// The face weights of the build's area metric, and its grid.
#[derive(Clone, Copy)]
struct Metric {
    weights: Vec3,
    /// The weights of the faces across z, x and y (the products
    /// `e.x·e.y`, `e.y·e.z` and `e.z·e.x` are their areas).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    weights_zxy: Vec4,
    grid: Grid,
}

impl Metric {
    #[inline]
    fn area(&self, b: &Box3) -> f32 {
        self.area_of_extent(b.extent())
    }

    /// [`Metric::area`] of a box in lanes (the same numbers: the same
    /// products in the same order, three lanes at once).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn area_of(&self, b: &BuildRef) -> f32 {
        let e = b.extent4();
        let p = self.weights_zxy * e * glam::Vec4Swizzles::yzxw(e);
        2.0 * (p.x + p.y + p.z)
    }

    #[cfg(not(target_arch = "x86_64"))]
    #[inline]
    fn area_of(&self, b: &BuildRef) -> f32 {
        self.area_of_extent(b.extent())
    }

    #[inline]
    fn area_of_extent(&self, e: Vec3) -> f32 {
        let w = self.weights;
        2.0 * (w.z * e.x * e.y + w.x * e.y * e.z + w.y * e.z * e.x)
    }
}

/// What the build does with one node's primitives.
enum Plan {
    Leaf,
    /// Inner node over `refs[..mid]` and `refs[mid..]` (partitioned).
    Split(usize, [Child; 2]),
}

/// A child of a split: its box, and whether the partition binned its refs
/// on the way (into the slot the caller gave).
#[derive(Clone, Copy)]
struct Child {
    bounds: BuildRef,
    binned: bool,
}

/// How the tree is built; the tree is the same whichever is chosen.
#[derive(Clone, Copy)]
struct Strategy {
    /// The partition of a node bins its children's refs as it moves them
    /// (one pass over the refs per level instead of two).
    fused: bool,
    /// Subtrees of at least this many primitives build their two halves on
    /// two threads, and the root's refs are binned on all.
    parallel: usize,
}

impl Strategy {
    const FAST: Strategy = Strategy {
        fused: true,
        parallel: PARALLEL,
    };
}

/// The box of some refs.
fn bounds_of(refs: &[BuildRef]) -> BuildRef {
    refs.iter().fold(BuildRef::EMPTY, |a, r| a.union(*r))
}

/// The boxes and counts of the refs whose centroids fall into each bin,
/// along each axis.
#[derive(Clone, Copy)]
struct Bins {
    boxes: [[BuildRef; BINS]; 3],
    counts: [[u32; BINS]; 3],
}

impl Bins {
    const EMPTY: Bins = Bins {
        boxes: [[BuildRef::EMPTY; BINS]; 3],
        counts: [[0; BINS]; 3],
    };

    /// Adds `r`, whose bin along axis a is `k[a]` (below `BINS`: the mask
    /// changes no bin and spares the bounds checks in the binning loops).
    #[inline(always)]
    fn add(&mut self, k: UVec4, r: &BuildRef) {
        const _: () = assert!(BINS.is_power_of_two());
        for axis in 0..3 {
            let k = k[axis] as usize & (BINS - 1);
            self.boxes[axis][k] = self.boxes[axis][k].union(*r);
            self.counts[axis][k] += 1;
        }
    }

    /// Unions of boxes and sums of counts are exact and do not depend on
    /// the order: bins merged from parts are the bins of the whole.
    fn merge(mut self, o: Bins) -> Bins {
        for axis in 0..3 {
            for k in 0..BINS {
                self.boxes[axis][k] = self.boxes[axis][k].union(o.boxes[axis][k]);
                self.counts[axis][k] += o.counts[axis][k];
            }
        }
        self
    }

    /// The bins of `refs`. Many refs are binned as two halves side by
    /// side: neighbours in the input often fall into the same bin, and one
    /// set of bins would make each update wait for the one before.
    #[inline(always)]
    fn of(refs: &[BuildRef], binning: &Binning) -> Bins {
        let mut a = Bins::EMPTY;
        if refs.len() < 256 {
            for r in refs {
                a.add(binning.bin(r), r);
            }
            return a;
        }
        let mut b = Bins::EMPTY;
        let (lo, hi) = refs.split_at(refs.len() / 2);
        for (r, s) in lo.iter().zip(hi) {
            a.add(binning.bin(r), r);
            b.add(binning.bin(s), s);
        }
        if let Some(r) = hi.get(lo.len()) {
            a.add(binning.bin(r), r);
        }
        a.merge(b)
    }

    /// [`Bins::of`] on all threads, for the root.
    fn of_parallel(refs: &[BuildRef], binning: &Binning, chunk: usize) -> Bins {
        refs.par_chunks(chunk)
            .map(|c| Bins::of(c, binning))
            .reduce(|| Bins::EMPTY, Bins::merge)
    }
}

/// The integer parts of four numbers in 0..2³¹ (one instruction where
/// `as u32` takes four, each with its checks).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn truncate(v: Vec4) -> UVec4 {
    use std::arch::x86_64::*;
    // SAFETY: SSE2 is part of x86_64; the lanes are non-negative.
    let i: [u32; 4] = unsafe { std::mem::transmute(_mm_cvttps_epi32(v.into())) };
    UVec4::from_array(i)
}

#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn truncate(v: Vec4) -> UVec4 {
    v.as_uvec4()
}

/// A node's box seen by the build: centroids are binned over the box
/// itself, so that the children's boxes come from the bins, without
/// another pass.
#[derive(Clone, Copy)]
struct NodeBox {
    whole: Box3,
    /// Twice the box's extent (`centre2` is twice the centre: it lies in
    /// twice the box).
    ext: Vec3,
    /// The longest axis.
    axis: usize,
    binning: Binning,
}

/// Which bin a centroid falls into along each axis.
#[derive(Clone, Copy)]
struct Binning {
    origin: Vec4,
    scale: Vec4,
}

impl Binning {
    /// The bin along `axis` of a centroid with `centre2` lane `c` (the
    /// same operations as [`Binning::bin`], one lane).
    #[inline]
    fn bin_of(&self, axis: usize, c: f32) -> u32 {
        ((c - self.origin[axis]) * self.scale[axis])
            .max(0.0)
            .min(BINS as f32 - 1.0) as u32
    }

    /// The largest `t` such that every ref whose doubled centre along
    /// `axis` is an integer ≤ t falls into a bin ≤ `bin` (and every one
    /// above t into a later bin): `bin_of` is monotone in the centre, and
    /// doubled centres are integers in 0..=131070, so the partition's test
    /// becomes one integer comparison.
    fn last_centre_in(&self, axis: usize, bin: u32) -> i32 {
        const TOP: i32 = 2 * u16::MAX as i32;
        let inside = |c: i32| self.bin_of(axis, c as f32) <= bin;
        // An estimate from the bin's far edge, then exact steps.
        let (o, s) = (self.origin[axis], self.scale[axis]);
        let guess = if s > 0.0 {
            (o + (bin + 1) as f32 / s).floor()
        } else {
            TOP as f32
        };
        let mut t = (guess as i32).clamp(-1, TOP);
        while t >= 0 && !inside(t) {
            t -= 1;
        }
        while t < TOP && inside(t + 1) {
            t += 1;
        }
        t
    }

    #[inline(always)]
    fn bin(&self, r: &BuildRef) -> UVec4 {
        truncate(
            ((r.centre2() - self.origin) * self.scale)
                .max(Vec4::ZERO)
                .min(Vec4::splat(BINS as f32 - 1.0)),
        )
    }
}

impl NodeBox {
    fn new(bounds: BuildRef) -> NodeBox {
        let whole = bounds.decode();
        let origin = whole.min * 2.0;
        let ext = whole.extent() * 2.0;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let scale = Vec3::select(
            ext.cmpgt(Vec3::ZERO),
            Vec3::splat(BINS as f32 * 0.999_99) / ext,
            Vec3::ZERO,
        )
        .extend(0.0);
        NodeBox {
            whole,
            ext,
            axis,
            binning: Binning { origin, scale },
        }
    }

    /// Whether a node of `count` refs in this box at `depth` is split by
    /// its bins (else it is a leaf or halved by count).
    fn binned(&self, count: usize, depth: usize) -> bool {
        count > MAX_LEAF && self.ext[self.axis] > 0.0 && depth < SAH_DEPTH
    }
}

/// How to split `refs`, whose box is `bounds` (partitioning them in
/// place); `bins`: their bins if the parent's partition made them; `kids`:
/// where the children's bins may be made.
fn plan(
    refs: &mut [BuildRef],
    bounds: BuildRef,
    bins: Option<&Bins>,
    kids: &mut [Bins; 2],
    build: Build,
    depth: usize,
) -> Plan {
    let (metric, strategy) = (build.metric, build.strategy);
    if refs.len() <= MAX_LEAF {
        return Plan::Leaf;
    }
    let node = NodeBox::new(bounds);
    let (whole, ext) = (node.whole, node.ext);
    if ext[node.axis] <= 0.0 {
        return Plan::Leaf;
    }
    if depth >= SAH_DEPTH {
        // Halve by count: the tree stays shallow whatever the layout
        // (SAH alone can peel one object per level off centroids that
        // grow geometrically).
        let (axis, mid) = (node.axis, refs.len() / 2);
        refs.select_nth_unstable_by(mid, |a, b| a.centre2()[axis].total_cmp(&b.centre2()[axis]));
        let (lo, hi) = refs.split_at(mid);
        let child = |r: &[BuildRef]| Child {
            bounds: bounds_of(r),
            binned: false,
        };
        return Plan::Split(mid, [child(lo), child(hi)]);
    }
    // One pass bins the centroids along all three axes.
    let made;
    let Bins {
        boxes: bin_bounds,
        counts: bin_count,
    } = match bins {
        Some(b) => b,
        None => {
            made = if refs.len() >= strategy.parallel {
                Bins::of_parallel(refs, &node.binning, strategy.parallel)
            } else {
                Bins::of(refs, &node.binning)
            };
            &made
        }
    };
    let best = cheapest_plane(bin_bounds, bin_count, ext, node.axis, &metric);
    let area = metric.area(&whole);
    let leaf_cost = area * refs.len() as f32;
    let split_cost = TRAVERSAL_COST * area + best.0;
    if best.0.is_infinite() || (split_cost >= leaf_cost && refs.len() <= 2 * MAX_LEAF) {
        return Plan::Leaf;
    }
    let (_, split_bin, axis) = best;
    let boxes = &bin_bounds[axis];
    let left_box = bounds_of(&boxes[..=split_bin]);
    let right_box = bounds_of(&boxes[split_bin + 1..]);
    let left_count: u32 = bin_count[axis][..=split_bin].iter().sum();
    let (left_node, right_node) = (NodeBox::new(left_box), NodeBox::new(right_box));
    // The children's bins are made on the way only where they will be
    // used (tiny children are leaves).
    let fuse = |n: &NodeBox, count: usize| strategy.fused && n.binned(count, depth + 1);
    let bin_left = fuse(&left_node, left_count as usize);
    let bin_right = fuse(&right_node, refs.len() - left_count as usize);
    let [left_bins, right_bins] = kids;
    if bin_left {
        *left_bins = Bins::EMPTY;
    }
    if bin_right {
        *right_bins = Bins::EMPTY;
    }
    // Hoare partition by the same bin computation; every ref is added to
    // its child's bins once, where it is passed over or swapped.
    let last = node.binning.last_centre_in(axis, split_bin as u32) - 65535;
    let left = |r: &BuildRef| r.centre2_less(axis) <= last;
    let mut to_left = |r: &BuildRef| {
        if bin_left {
            left_bins.add(left_node.binning.bin(r), r);
        }
    };
    let mut to_right = |r: &BuildRef| {
        if bin_right {
            right_bins.add(right_node.binning.bin(r), r);
        }
    };
    let (mut i, mut j) = (0, refs.len());
    loop {
        while i < j && left(&refs[i]) {
            to_left(&refs[i]);
            i += 1;
        }
        while i < j && !left(&refs[j - 1]) {
            to_right(&refs[j - 1]);
            j -= 1;
        }
        if i >= j {
            break;
        }
        // refs[i] goes right and refs[j − 1] left.
        to_right(&refs[i]);
        to_left(&refs[j - 1]);
        refs.swap(i, j - 1);
        i += 1;
        j -= 1;
    }
    debug_assert_eq!(i, left_count as usize);
    Plan::Split(
        i,
        [
            Child {
                bounds: left_box,
                binned: bin_left,
            },
            Child {
                bounds: right_box,
                binned: bin_right,
            },
        ],
    )
}

/// The cheapest split plane over the bins of every axis with an extent:
/// (cost, the last bin on its left, axis), the first of equal costs; an
/// infinite cost if no plane has refs on both sides. Sweeps from both
/// ends; only the planes after non-empty bins are tried: a plane after an
/// empty bin splits as the one before it, which is tried first and kept on
/// a tie.
#[inline]
fn cheapest_plane(
    boxes: &[[BuildRef; BINS]; 3],
    counts: &[[u32; BINS]; 3],
    ext: Vec3,
    first_axis: usize,
    metric: &Metric,
) -> (f32, usize, usize) {
    let mut best = (f32::INFINITY, 0, first_axis);
    for axis in (0..3).filter(|&a| ext[a] > 0.0) {
        let (boxes, counts) = (&boxes[axis], &counts[axis]);
        let mut full = [0usize; BINS];
        let mut m = 0;
        for (k, &c) in counts.iter().enumerate() {
            full[m] = k;
            m += (c > 0) as usize;
        }
        // right_cost[j]: the cost of the bins full[j..m].
        let mut right_cost = [0.0f32; BINS];
        let mut acc = BuildRef::EMPTY;
        let mut count = 0u32;
        for j in (1..m).rev() {
            acc = acc.union(boxes[full[j]]);
            count += counts[full[j]];
            right_cost[j] = metric.area_of(&acc) * count as f32;
        }
        let mut acc = BuildRef::EMPTY;
        let mut count = 0u32;
        for j in 0..m.saturating_sub(1) {
            acc = acc.union(boxes[full[j]]);
            count += counts[full[j]];
            let cost = metric.area_of(&acc) * count as f32 + right_cost[j + 1];
            if cost < best.0 {
                best = (cost, full[j], axis);
            }
        }
    }
    best
}

/// What every node of one build shares.
#[derive(Clone, Copy)]
struct Build {
    metric: Metric,
    strategy: Strategy,
}

/// Builds the subtree over `refs` (with the box `bounds` and the bins
/// `bins` if made) into `nodes[node]` and nodes pushed after it; `first`:
/// where `refs` starts in the item order; `scratch`: bins for the levels
/// below (one pair per level).
#[allow(clippy::too_many_arguments)]
fn split(
    nodes: &mut Vec<Node>,
    node: usize,
    refs: &mut [BuildRef],
    bounds: BuildRef,
    bins: Option<&Bins>,
    first: usize,
    build: Build,
    depth: usize,
    scratch: &mut [[Bins; 2]],
) {
    // (A tree deeper than the scratch, which the count split rules out,
    // would keep those levels' bins on the stack.)
    let mut spare;
    let (kids, below) = match scratch.split_first_mut() {
        Some(k) => k,
        None => {
            spare = [Bins::EMPTY; 2];
            (&mut spare, &mut [][..])
        }
    };
    let plan = plan(refs, bounds, bins, kids, build, depth);
    let n = &mut nodes[node];
    (n.min, n.max) = build.metric.grid.world(&bounds);
    match plan {
        Plan::Leaf => {
            n.first = first as u32;
            n.count = refs.len() as u32;
        }
        Plan::Split(mid, [l, r]) => {
            let left = nodes.len();
            nodes[node].first = left as u32;
            nodes.push(Node::EMPTY);
            nodes.push(Node::EMPTY);
            let (lo, hi) = refs.split_at_mut(mid);
            let [lb, rb] = &*kids;
            let (lb, rb) = (l.binned.then_some(lb), r.binned.then_some(rb));
            split(
                nodes,
                left,
                lo,
                l.bounds,
                lb,
                first,
                build,
                depth + 1,
                below,
            );
            let right_first = first + mid;
            split(
                nodes,
                left + 1,
                hi,
                r.bounds,
                rb,
                right_first,
                build,
                depth + 1,
                below,
            );
        }
    }
}

/// Levels a tree can have (the traversal stacks hold 64 entries).
const MAX_LEVELS: usize = 64;

/// The subtree over `refs` (with the box `bounds` and the bins `bins` if
/// made) as its own node list after `lead` unused slots (root first,
/// children indexed from the root, leaves indexing `refs` from 0); large
/// ones build their halves in parallel. The slots let a parent put itself
/// and its children's roots in front of the left child's list without
/// moving it.
fn subtree(
    refs: &mut [BuildRef],
    bounds: BuildRef,
    bins: Option<&Bins>,
    build: Build,
    depth: usize,
    lead: usize,
) -> Vec<Node> {
    if refs.len() < build.strategy.parallel {
        let mut nodes = Vec::with_capacity(lead + refs.len());
        nodes.resize(lead + 1, Node::EMPTY);
        let mut scratch = vec![[Bins::EMPTY; 2]; MAX_LEVELS.saturating_sub(depth) + 1];
        split(
            &mut nodes,
            lead,
            refs,
            bounds,
            bins,
            0,
            build,
            depth,
            &mut scratch,
        );
        for n in &mut nodes[lead..] {
            if n.count == 0 {
                n.first -= lead as u32;
            }
        }
        return nodes;
    }
    let (min, max) = build.metric.grid.world(&bounds);
    let mut kids = Box::new([Bins::EMPTY; 2]);
    let Plan::Split(mid, [l, r]) = plan(refs, bounds, bins, &mut kids, build, depth) else {
        let mut nodes = vec![Node::EMPTY; lead + 1];
        nodes[lead] = Node {
            min,
            first: 0,
            max,
            count: refs.len() as u32,
        };
        return nodes;
    };
    let (lo, hi) = refs.split_at_mut(mid);
    let [lb, rb] = &*kids;
    let (lb, rb) = (l.binned.then_some(lb), r.binned.then_some(rb));
    let (mut left, right) = rayon::join(
        || subtree(lo, l.bounds, lb, build, depth + 1, lead + 2),
        || subtree(hi, r.bounds, rb, build, depth + 1, 0),
    );
    // [parent, left root, right root, left's others, right's others]: the
    // left list already holds its others there.
    let left_len = (left.len() - (lead + 2)) as u32;
    for n in &mut left[lead + 2..] {
        if n.count == 0 {
            n.first += 2;
        }
    }
    let moved = |mut n: Node| {
        if n.count == 0 {
            n.first += left_len + 1;
        } else {
            n.first += mid as u32;
        }
        n
    };
    left[lead] = Node {
        min,
        first: 1,
        max,
        count: 0,
    };
    left[lead + 1] = left[lead + 2];
    left[lead + 2] = moved(right[0]);
    append_releasing(&mut left, right, moved, 1 << 15);
    left
}

/// Appends `right[1..]`, each node mapped by `moved`, to `left`, copying
/// from the end in pieces and giving each piece's pages of `right` back as
/// it goes: both lists at once would hold the right half's nodes twice at
/// the top merge (about 10 bytes per primitive at the peak of the build).
/// `piece`: nodes per piece (the build's 2¹⁵ are 1 MiB).
fn append_releasing(
    left: &mut Vec<Node>,
    mut right: Vec<Node>,
    moved: impl Fn(Node) -> Node,
    piece: usize,
) {
    let (base, extra) = (left.len(), right.len() - 1);
    left.reserve_exact(extra);
    let spare = &mut left.spare_capacity_mut()[..extra];
    let mut end = right.len();
    while end > 1 {
        let start = end.saturating_sub(piece).max(1);
        for (slot, &n) in spare[start - 1..end - 1].iter_mut().zip(&right[start..end]) {
            slot.write(moved(n));
        }
        end = start;
        right.truncate(end);
        if right.capacity() >= 4 * piece {
            // A large list is mapped pages of its own: shrinking it
            // unmaps the tail.
            right.shrink_to_fit();
        }
    }
    // SAFETY: the loop wrote every one of the `extra` slots after `base`.
    unsafe { left.set_len(base + extra) };
}

impl Bvh {
    /// Builds a BVH over `(object id, bounds)` pairs.
    pub fn build(objects: &[(u32, Aabb)]) -> Bvh {
        Self::build_weighted(objects, DVec3::ONE)
    }

    /// Builds a BVH for rays that mostly run along some axes: `weights`
    /// scales the area of the faces normal to x, y and z in the surface
    /// area heuristic (the chance that a ray along an axis meets a box is
    /// its face area across that axis).
    pub fn build_weighted(objects: &[(u32, Aabb)], weights: DVec3) -> Bvh {
        Self::build_with(objects.len(), |k| objects[k], weights)
    }

    /// Builds a BVH over `count` primitives, `item(k)` giving the id and
    /// bounds of the k-th (called twice for each, from several threads:
    /// nothing per primitive is kept but a 16-byte record).
    pub fn build_with(
        count: usize,
        item: impl Fn(usize) -> (u32, Aabb) + Sync,
        weights: DVec3,
    ) -> Bvh {
        Self::build_by(count, item, weights, Strategy::FAST)
    }

    fn build_by(
        count: usize,
        item: impl Fn(usize) -> (u32, Aabb) + Sync,
        weights: DVec3,
        strategy: Strategy,
    ) -> Bvh {
        if count == 0 {
            return Bvh::default();
        }
        let all = (0..count)
            .into_par_iter()
            .with_min_len(4096)
            .map(|k| item(k).1)
            .reduce(|| Aabb::EMPTY, Aabb::union);
        let grid = Grid::new(&all);
        let mut refs: Vec<BuildRef> = (0..count)
            .into_par_iter()
            .with_min_len(4096)
            .map(|k| {
                let (id, b) = item(k);
                grid.record(id, &b)
            })
            .collect();
        let build = Build {
            metric: Metric {
                weights: weights.as_vec3(),
                weights_zxy: Vec4::new(weights.z as f32, weights.x as f32, weights.y as f32, 0.0),
                grid,
            },
            strategy,
        };
        let bounds = refs
            .par_chunks(PARALLEL)
            .map(bounds_of)
            .reduce(|| BuildRef::EMPTY, BuildRef::union);
        let mut nodes = subtree(&mut refs, bounds, None, build, 0, 0);
        nodes.shrink_to_fit();
        let items = refs.iter().map(|r| r.id()).collect();
        Bvh { nodes, items }
    }

    /// A node's bounds and content (the root is node 0), for trees built
    /// from this one.
    pub fn node(&self, i: u32) -> (Aabb, NodeContent<'_>) {
        let n = &self.nodes[i as usize];
        let content = if n.count > 0 {
            NodeContent::Leaf(&self.items[n.first as usize..(n.first + n.count) as usize])
        } else {
            NodeContent::Inner([n.first, n.first + 1])
        };
        (n.bounds(), content)
    }

    /// Levels below the root (0 for a lone leaf).
    #[cfg(test)]
    pub fn depth(&self, i: u32) -> usize {
        match self.node(i).1 {
            NodeContent::Leaf(_) => 0,
            NodeContent::Inner([l, r]) => 1 + self.depth(l).max(self.depth(r)),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Nodes in the tree.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Nodes and items, for memory figures.
    pub fn size_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node>() + self.items.len() * 4
    }

    /// Bounds of everything inside.
    pub fn bounds(&self) -> Aabb {
        self.nodes.first().map_or(Aabb::EMPTY, |n| n.bounds())
    }

    /// Closest hit: `hit(object, t_max)` returns the object's nearest t below
    /// t_max; nodes are visited near child first and pruned by the best t.
    #[inline(always)]
    pub fn closest(
        &self,
        ray: &Ray,
        mut t_max: f64,
        mut hit: impl FnMut(u32, f64) -> Option<f64>,
    ) -> Option<(u32, f64)> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv = ray.dir.recip();
        let mut best = None;
        let mut stack = [0u32; 64];
        let mut sp = 0;
        let mut node = 0usize;
        let entry = |i: usize, t_max: f64| self.nodes[i].bounds().entry(ray, inv, t_max);
        entry(0, t_max)?;
        loop {
            let n = &self.nodes[node];
            if n.count > 0 {
                for &obj in &self.items[n.first as usize..(n.first + n.count) as usize] {
                    if let Some(t) = hit(obj, t_max) {
                        t_max = t;
                        best = Some((obj, t));
                    }
                }
            } else {
                let (l, r) = (n.first as usize, n.first as usize + 1);
                match (entry(l, t_max), entry(r, t_max)) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if a <= b { (l, r) } else { (r, l) };
                        stack[sp] = far as u32;
                        sp += 1;
                        node = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node = l;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = r;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop the next far child that a closer hit has not pruned since.
            loop {
                if sp == 0 {
                    return best;
                }
                sp -= 1;
                node = stack[sp] as usize;
                if entry(node, t_max).is_some() {
                    break;
                }
            }
        }
    }

    /// Calls `visit` for every object in a leaf whose bounds pass
    /// `overlaps`, pruning subtrees that fail it; visits the child nearer to
    /// `origin` first and stops as soon as `visit` returns false.
    pub fn visit_near_first(
        &self,
        origin: DVec3,
        overlaps: impl Fn(&Aabb) -> bool,
        mut visit: impl FnMut(u32) -> bool,
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = [0u32; 64];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let n = &self.nodes[stack[sp] as usize];
            if !overlaps(&n.bounds()) {
                continue;
            }
            if n.count > 0 {
                for &obj in &self.items[n.first as usize..(n.first + n.count) as usize] {
                    if !visit(obj) {
                        return;
                    }
                }
            } else {
                let (l, r) = (n.first, n.first + 1);
                let dist =
                    |i: u32| (self.nodes[i as usize].bounds().centre() - origin).length_squared();
                let (near, far) = if dist(l) <= dist(r) { (l, r) } else { (r, l) };
                stack[sp] = far;
                stack[sp + 1] = near;
                sp += 2;
            }
        }
    }
}
#[cfg(test)]
mod tests {
    use super::*;

    /// Centroids growing geometrically (×2 per object) would make binned
    /// SAH peel off one object per level; the build's grid snaps the small
    /// ones together and the count split from `SAH_DEPTH` on bounds the
    /// rest: the depth stays within the traversal stacks.
    #[test]
    fn depth_stays_within_the_stacks_for_geometric_layouts() {
        let objects: Vec<(u32, Aabb)> = (0..230)
            .map(|i| {
                let x = 1e-37 * 2f64.powi(i);
                (
                    i as u32,
                    Aabb::new(DVec3::new(x, 0.0, 0.0), DVec3::new(x * 1.001, 1.0, 1.0)),
                )
            })
            .collect();
        let bvh = Bvh::build(&objects);
        let depth = bvh.depth(0);
        assert!(depth < 63, "{depth}");
        // Every object is still found.
        for (i, b) in &objects {
            let ray = Ray::new(DVec3::new(b.centre().x, 0.5, -1.0), DVec3::Z);
            let hit = bvh.closest(&ray, 10.0, |j, _| (j == *i).then_some(1.0));
            assert_eq!(hit.map(|h| h.0), Some(*i));
        }
    }

    /// A tree built on two threads (far more primitives than `PARALLEL`)
    /// finds the nearest box of every ray, as testing all boxes does.
    #[test]
    fn parallel_build_finds_what_brute_force_finds() {
        let mut state = 12345u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let objects: Vec<(u32, Aabb)> = (0..60_000)
            .map(|i| {
                let c = DVec3::new(next(), next(), next()) * 100.0;
                let h = DVec3::new(next(), next(), next()) * 0.4 + 0.01;
                (i as u32, Aabb::new(c - h, c + h))
            })
            .collect();
        let bvh = Bvh::build(&objects);
        assert!(bvh.depth(0) < 63);
        let mut hits = 0;
        for _ in 0..300 {
            let origin = DVec3::new(next(), next(), -0.1) * DVec3::new(100.0, 100.0, 1.0);
            let dir = (DVec3::new(next(), next(), 1.0) - DVec3::new(0.5, 0.5, 0.0)).normalize();
            let ray = Ray::new(origin, dir);
            let inv = dir.recip();
            let t_of = |j: u32, t_max: f64| {
                objects[j as usize]
                    .1
                    .entry(&ray, inv, t_max)
                    .filter(|&t| t < t_max)
            };
            let brute = (0..objects.len() as u32)
                .filter_map(|j| t_of(j, f64::INFINITY).map(|t| (j, t)))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let found = bvh.closest(&ray, f64::INFINITY, t_of);
            assert_eq!(found, brute);
            hits += found.is_some() as u32;
        }
        assert!(hits > 100, "{hits}");
    }

    /// The partition's integer test puts every doubled centre on the side
    /// its bin puts it, for every centre the grid can give.
    #[test]
    fn the_integer_partition_test_agrees_with_the_bins() {
        for (lo, hi) in [
            (0.0, 131_070.0),
            (17.0, 23.0),
            (1000.0, 1001.0),
            (5.0, 98_765.0),
        ] {
            let whole = Box3 {
                min: Vec4::splat(lo / 2.0),
                max: Vec4::splat(hi / 2.0),
            };
            let ext = whole.extent() * 2.0;
            let binning = Binning {
                origin: whole.min * 2.0,
                scale: (Vec3::splat(BINS as f32 * 0.999_99) / ext).extend(0.0),
            };
            for bin in 0..BINS as u32 {
                let last = binning.last_centre_in(0, bin);
                for c in 0..=131_070 {
                    let inside = binning.bin_of(0, c as f32) <= bin;
                    assert_eq!(inside, c <= last, "{lo}..{hi}: centre {c}, bin {bin}");
                }
            }
        }
    }

    /// The branch-free roundings and floor/ceil give the library's answers
    /// (the latter as far as the grid's clamp can tell).
    #[test]
    fn roundings_match_the_library() {
        let mut state = 99u64;
        let mut values = vec![
            0.0,
            -0.0,
            1e-50,
            -1e-50,
            1.0,
            -1.0,
            0.1,
            -0.1,
            1e39,
            -1e39,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f32::MAX as f64,
            65_535.5,
            -0.5,
            1e19,
            -1e19,
        ];
        for _ in 0..100_000 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let x = f64::from_bits(state);
            if x.is_finite() {
                values.push(x);
            }
            values.push((state >> 11) as f64 / (1u64 << 53) as f64 * 140_000.0 - 5_000.0);
        }
        let bits = |y: f32| y.to_bits();
        let q = |x: f64| x.clamp(0.0, u16::MAX as f64) as u16;
        for x in values {
            let y = x as f32;
            let down = if (y as f64) > x { y.next_down() } else { y };
            let up = if (y as f64) < x { y.next_up() } else { y };
            assert_eq!(bits(round_down(x)), bits(down), "{x:e}");
            assert_eq!(bits(round_up(x)), bits(up), "{x:e}");
            assert_eq!(q(floor(x) - 1.0), q(x.floor() - 1.0), "{x:e}");
            assert_eq!(q(ceil(x) + 1.0), q(x.ceil() + 1.0), "{x:e}");
        }
    }

    /// Appending in pieces from the end gives what one `extend` gives.
    #[test]
    fn appending_in_pieces_equals_one_extend() {
        let node = |i: u32| Node {
            min: Vec3::splat(i as f32),
            first: i,
            max: Vec3::splat(i as f32 + 1.0),
            count: i % 3,
        };
        let moved = |mut n: Node| {
            n.first += 1000;
            n
        };
        for (l, r, piece) in [
            (3, 1, 2),
            (5, 2, 1),
            (4, 100, 7),
            (1, 1000, 3),
            (10, 300, 1000),
        ] {
            let left: Vec<Node> = (0..l).map(node).collect();
            let right: Vec<Node> = (0..r).map(|i| node(i + 50)).collect();
            let mut expected = left.clone();
            expected.extend(right[1..].iter().map(|&n| moved(n)));
            let mut got = left.clone();
            append_releasing(&mut got, right, moved, piece);
            let key = |n: &Node| (n.min.x.to_bits(), n.max.x.to_bits(), n.first, n.count);
            let (e, g): (Vec<_>, Vec<_>) = (
                expected.iter().map(key).collect(),
                got.iter().map(key).collect(),
            );
            assert_eq!(g, e, "{l} {r} {piece}");
        }
    }

    /// Node arrays and item orders equal bit for bit.
    fn assert_same_tree(a: &Bvh, b: &Bvh) {
        assert_eq!(a.nodes.len(), b.nodes.len());
        for (i, (m, n)) in a.nodes.iter().zip(&b.nodes).enumerate() {
            let bits = |n: &Node| {
                (
                    n.min.to_array().map(f32::to_bits),
                    n.max.to_array().map(f32::to_bits),
                    n.first,
                    n.count,
                )
            };
            assert_eq!(bits(m), bits(n), "node {i}");
        }
        assert_eq!(a.items, b.items);
    }

    /// The fused, parallel build makes the tree of the plain one (bin,
    /// then partition, one node after the other), node for node: on random
    /// boxes, on a torus's triangles (many equal sizes, a hole), on
    /// clusters of equal centroids, with and without face weights, and
    /// past the depth where nodes are halved by count.
    #[test]
    fn fused_parallel_build_equals_the_plain_sequential_one() {
        let plain = Strategy {
            fused: false,
            parallel: usize::MAX,
        };
        let mut state = 777u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let random: Vec<(u32, Aabb)> = (0..70_000)
            .map(|i| {
                let c = DVec3::new(next(), next() * 0.3, next()) * 100.0;
                let h = DVec3::new(next(), next(), next()) * 0.4 + 0.01;
                (i as u32, Aabb::new(c - h, c + h))
            })
            .collect();
        // A torus of 2·240·160 triangles' boxes.
        let (nu, nv) = (240, 160);
        let at = |i: usize, j: usize| {
            let (u, v) = (
                std::f64::consts::TAU * i as f64 / nu as f64,
                std::f64::consts::TAU * j as f64 / nv as f64,
            );
            let r = 2.0 + 0.6 * v.cos();
            DVec3::new(r * u.cos(), 0.6 * v.sin(), r * u.sin())
        };
        let mut torus = Vec::new();
        for i in 0..nu {
            for j in 0..nv {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                for t in [[a, b, c], [a, c, d]] {
                    let id = torus.len() as u32;
                    torus.push((
                        id,
                        Aabb::new(t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2])),
                    ));
                }
            }
        }
        // Clusters of boxes sharing a centroid (leaves that cannot split).
        let clusters: Vec<(u32, Aabb)> = (0..40_000)
            .map(|i| {
                let c = DVec3::splat((i % 37) as f64);
                let h = DVec3::splat(0.1 + (i % 5) as f64 * 0.01);
                (i as u32, Aabb::new(c - h, c + h))
            })
            .collect();
        let geometric: Vec<(u32, Aabb)> = (0..230)
            .map(|i| {
                let x = 1e-37 * 2f64.powi(i);
                (
                    i as u32,
                    Aabb::new(DVec3::new(x, 0.0, 0.0), DVec3::new(x * 1.001, 1.0, 1.0)),
                )
            })
            .collect();
        for objects in [&random, &torus, &clusters, &geometric] {
            for weights in [DVec3::ONE, DVec3::new(2.0, 2.0, 1.0)] {
                let build = |s: Strategy| Bvh::build_by(objects.len(), |k| objects[k], weights, s);
                let reference = build(plain);
                assert!(reference.node_count() > 1);
                assert_same_tree(&build(Strategy::FAST), &reference);
                // Each change on its own too.
                let fused_only = Strategy {
                    fused: true,
                    parallel: usize::MAX,
                };
                assert_same_tree(&build(fused_only), &reference);
                let parallel_only = Strategy {
                    fused: false,
                    parallel: 1024,
                };
                assert_same_tree(&build(parallel_only), &reference);
            }
        }
    }
}
