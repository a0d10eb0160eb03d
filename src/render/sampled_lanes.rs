//! The `sampled` model's light factors of many hit points at once, one hit
//! per vector lane: the operations of `shading::sampled_terms` point by
//! point and the same left-to-right sums, so the same bits.
//!
//! One hit at a time, a hit with few light points fills a vector with
//! padding (at 1 shadow ray, one lane in eight does work), and every hit's
//! sums are chains of dependent additions. Side by side, [`LANES`] hits walk
//! their light points together: each lane's sum is one hit's, in the
//! points' order, and the chains of the lanes run in one vector. The
//! directions are recomputed from the light points as `light_directions`
//! computes them (the same expression, so the same values), so a waiting
//! hit keeps only its visibility bits.
//!
//! From [`LANE_POINTS`] points on, one hit's points fill the vectors: each
//! hit's contributions are computed point by point as it arrives (by
//! `shading::point_terms`, as the tracer does), and only the sums wait, to
//! run [`LANES`] hits' chains of additions side by side instead of one
//! hit's alone (each still in its points' order).

use glam::Vec3;

use super::math::{avx2_dispatch, avx512_dispatch, pow_from_log2, pow_log2};
use super::rng::Rng;
use super::sampling::Pattern;
use super::scene_file::Sampling;
use super::shading::{LightTerms, PointTerms, blinn_cosine, point_terms};
use super::shadow::{ShadowBuffers, live_rays};

/// Hits computed side by side.
pub const LANES: usize = 16;

/// Hits with fewer light points than this are worth shading side by side.
/// From sixteen on, one hit's own points fill the vectors (the per-hit
/// kernels' sixteen lanes), and packing the visibility into bits cost more
/// than the lanes saved (8 % slower at 64 grid rays per hit, 1920×1080):
/// such hits wait with their contributions computed ([`HitRows`]).
pub const LANE_POINTS: usize = 16;

/// What a hit's sampled factors depend on besides its visibility.
#[derive(Debug, Clone, Copy)]
pub struct LaneHit {
    /// From the shadow point to the light's corner.
    pub to_corner: Vec3,
    pub normal: Vec3,
    pub view: Vec3,
    pub shininess: f32,
    /// Whether the specular factor is wanted (0 otherwise, as the tracer
    /// leaves it).
    pub specular: bool,
}

/// The lanes' inputs, one array entry per lane (shared with the live
/// re-shade's kernels, which must give the same bits).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct LaneInputs {
    /// From the hit point to the light's corner.
    pub(crate) c: [[f32; LANES]; 3],
    pub(crate) n: [[f32; LANES]; 3],
    pub(crate) v: [[f32; LANES]; 3],
    pub(crate) shininess: [f32; LANES],
}

impl LaneInputs {
    /// Puts a hit into lane h.
    #[inline]
    pub(crate) fn set(
        &mut self,
        h: usize,
        to_corner: Vec3,
        normal: Vec3,
        view: Vec3,
        shininess: f32,
    ) {
        for k in 0..3 {
            self.c[k][h] = to_corner[k];
            self.n[k][h] = normal[k];
            self.v[k][h] = view[k];
        }
        self.shininess[h] = shininess;
    }

    /// Lane h's vector to the light point at offsets (a, b) along the
    /// light's edges and its reciprocal length, as `light_directions` has
    /// them, and the lane's normal and view direction.
    #[inline(always)]
    pub(crate) fn towards(
        &self,
        points: &Points<'_>,
        h: usize,
        (a, b): (f32, f32),
    ) -> ((f32, f32, f32, f32), Vec3, Vec3) {
        let (eu, ev) = (points.edge_u, points.edge_v);
        let [cx, cy, cz] = &self.c;
        let (x, y, z) = (
            cx[h] + eu.x * a + ev.x * b,
            cy[h] + eu.y * a + ev.y * b,
            cz[h] + eu.z * a + ev.z * b,
        );
        let inv = 1.0 / (x * x + y * y + z * z).sqrt();
        let [nx, ny, nz] = &self.n;
        let [vx, vy, vz] = &self.v;
        (
            (x, y, z, inv),
            Vec3::new(nx[h], ny[h], nz[h]),
            Vec3::new(vx[h], vy[h], vz[h]),
        )
    }
}

/// Hits waiting for their factors (per thread, reused from batch to batch).
#[derive(Debug, Default)]
pub struct SampledLanes {
    /// The caller's index of each waiting hit, and whether it wants the
    /// specular factor.
    index: Vec<(usize, bool)>,
    hits: LaneInputs,
    /// Visibility, 64 points per entry: bit l of `bits[k][h]` is point
    /// 64·k + l of lane h.
    bits: Vec<[u64; LANES]>,
    points: LanePoints,
    /// From [`LANE_POINTS`] points on, instead of `hits` and `bits`.
    rows: HitRows,
    /// The pattern the batch is set up for.
    pattern: Option<(Sampling, u32)>,
}

impl SampledLanes {
    /// Prepares for hits traced with `pattern` (a no-op if it already is;
    /// no hit may be waiting).
    pub fn start(&mut self, pattern: &Pattern) {
        debug_assert!(self.index.is_empty());
        let key = (pattern.sampling, pattern.shadow_rays);
        if self.pattern == Some(key) {
            return;
        }
        self.pattern = Some(key);
        let count = pattern.count();
        self.rows
            .start(if count >= LANE_POINTS { count } else { 0 });
        self.bits.clear();
        if self.rows.is_used() {
            return;
        }
        self.bits.resize(count.div_ceil(64), [0; LANES]);
        self.points.start(pattern);
    }

    /// Adds hit `index`, whose light points and their visibility `buf`
    /// holds (some point visible); true once the batch is full. Inlined
    /// into the path loop (a call per hit saved and restored most
    /// registers).
    #[inline(always)]
    pub fn push(&mut self, index: usize, hit: LaneHit, buf: &ShadowBuffers) -> bool {
        let h = self.index.len();
        self.index.push((index, hit.specular));
        if self.rows.is_used() {
            self.rows.set(h, &hit, buf);
            return self.index.len() == LANES;
        }
        self.hits
            .set(h, hit.to_corner, hit.normal, hit.view, hit.shininess);
        let padded = self.points.count().next_multiple_of(8);
        // Bits past the last point may hold anything: the kernel reads
        // only the first `count`.
        for (bits, points) in self.bits.iter_mut().zip(buf.vis[..padded].chunks(64)) {
            bits[h] = live_rays(points);
        }
        if !self.points.is_fixed() {
            self.points.set_lane(h, &buf.a, &buf.b);
        }
        self.index.len() == LANES
    }

    /// Takes [`LANES`] hits at once (none may be waiting; fewer than
    /// [`LANE_POINTS`] points): lane h is the caller's hit `index[h].0`
    /// (wanting the specular factor if `index[h].1`) with lane h of
    /// `inputs`, visibility `visible[h]` (bit j: point j) and, for a pattern
    /// drawn per hit, points `a[j][h]`, `b[j][h]`. A hit with no point
    /// visible gets +0 sums, as its own hit-by-hit factors are. Lanes past
    /// `index` are computed but not read out.
    #[inline(always)]
    pub(crate) fn push_lanes(
        &mut self,
        index: &[(usize, bool)],
        inputs: &LaneInputs,
        visible: &[u64; LANES],
        a: &[[f32; LANES]],
        b: &[[f32; LANES]],
    ) {
        debug_assert!(self.index.is_empty() && !self.rows.is_used() && self.bits.len() == 1);
        self.index.extend_from_slice(index);
        self.hits = *inputs;
        self.bits[0] = *visible;
        if !self.points.is_fixed() {
            let count = self.points.count();
            self.points.lane_a[..count].copy_from_slice(&a[..count]);
            self.points.lane_b[..count].copy_from_slice(&b[..count]);
        }
    }

    /// Drops the waiting hits (a cancelled tile).
    pub fn discard(&mut self) {
        self.index.clear();
    }

    /// Computes the waiting hits' factors: `store(index, factors)` for each.
    /// Inlined, so that it is compiled for the caller's CPU features.
    #[inline(always)]
    pub fn flush(&mut self, edge_u: Vec3, edge_v: Vec3, store: impl FnMut(usize, LightTerms)) {
        self.flush_by(sampled_lanes, edge_u, edge_v, store);
    }

    #[inline(always)]
    fn flush_by(
        &mut self,
        kernel: Kernel,
        edge_u: Vec3,
        edge_v: Vec3,
        mut store: impl FnMut(usize, LightTerms),
    ) {
        if self.index.is_empty() {
            return;
        }
        // Lanes past the waiting hits hold finite leftovers of earlier
        // batches (or zeros) and are not read out.
        let (diffuse, specular) = if self.rows.is_used() {
            self.rows.sums()
        } else {
            kernel(
                &self.hits,
                &self.bits,
                &self.points.with_edges(edge_u, edge_v),
            )
        };
        for (h, &(i, wants_specular)) in self.index.iter().enumerate() {
            store(
                i,
                LightTerms {
                    diffuse: diffuse[h],
                    specular: if wants_specular { specular[h] } else { 0.0 },
                },
            );
        }
        self.index.clear();
    }
}

/// The contributions of hits with many light points, point by point: row
/// h of `d` (diffuse) and of `s` (specular) is lane h's.
#[derive(Debug, Default)]
struct HitRows {
    count: usize,
    /// Row length: `count` padded to a multiple of eight.
    padded: usize,
    d: Vec<f32>,
    s: Vec<f32>,
    /// The unshadowed diffuse contributions (the `sampled` model does not
    /// use them).
    unshadowed: Vec<f32>,
}

/// Lanes whose sums [`HitRows::sums_by_rows`] runs at once: two chains each, enough
/// to keep the adders busy without running out of registers.
const SUMMED_TOGETHER: usize = 4;

impl HitRows {
    /// Rows of `count` points (0: not used).
    fn start(&mut self, count: usize) {
        self.count = count;
        self.padded = count.next_multiple_of(8);
        for v in [&mut self.d, &mut self.s] {
            v.clear();
            v.resize(LANES * self.padded, 0.0);
        }
        self.unshadowed.clear();
        self.unshadowed.resize(self.padded, 0.0);
    }

    fn is_used(&self) -> bool {
        self.count > 0
    }

    /// Lane h's contributions, from its directions and visibility in `buf`
    /// (without the specular factor, its specular row keeps finite
    /// leftovers, not read out).
    #[inline(always)]
    fn set(&mut self, h: usize, hit: &LaneHit, buf: &ShadowBuffers) {
        let row = h * self.padded..(h + 1) * self.padded;
        let out = PointTerms {
            f: &mut self.unshadowed,
            d: &mut self.d[row.clone()],
            s: &mut self.s[row],
        };
        point_terms(
            hit.normal,
            hit.view,
            hit.shininess,
            hit.specular,
            &buf.dx,
            &buf.dy,
            &buf.dz,
            &buf.vis,
            out,
        );
    }

    /// Each lane's averages: its row's sums left to right from −0 (as
    /// `Iterator::sum`).
    #[inline(always)]
    fn sums(&self) -> ([f32; LANES], [f32; LANES]) {
        let (diffuse, specular) = self.row_sums();
        let inv_count = 1.0 / self.count as f32;
        (
            diffuse.map(|s| s * inv_count),
            specular.map(|s| s * inv_count),
        )
    }

    /// Each lane's row summed left to right from −0, the widest way the
    /// CPU has.
    #[inline(always)]
    fn row_sums(&self) -> ([f32; LANES], [f32; LANES]) {
        #[cfg(target_arch = "x86_64")]
        if crate::render::math::avx2_kernels() {
            // SAFETY: the CPU supports AVX2 (`avx2_kernels` checks).
            return unsafe { self.sums_transposed() };
        }
        self.sums_by_rows()
    }

    /// [`row_sums`](Self::row_sums) on eight-lane vectors, one lane per
    /// row: each block of eight points of eight rows is transposed in
    /// registers, so that a row's next point is the same lane of the next
    /// vector. Each lane adds its row's points in order, as
    /// [`sums_by_rows`](Self::sums_by_rows) does, so the same bits, with a
    /// third of the shuffles of gathering the lanes' points one by one.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn sums_transposed(&self) -> ([f32; LANES], [f32; LANES]) {
        use std::arch::x86_64::*;
        const { assert!(LANES == 16, "two octets of lanes") };
        let (count, padded) = (self.count, self.padded);
        // Every read below is of the first LANES · padded values.
        assert!(self.d.len() >= LANES * padded && self.s.len() >= LANES * padded);
        let (d, s) = (self.d.as_ptr(), self.s.as_ptr());
        let octet = 8 * padded;
        // Diffuse and specular sums of lanes 0..8 and 8..16.
        let zero = _mm256_set1_ps(-0.0);
        let (mut d0, mut d1, mut s0, mut s1) = (zero, zero, zero, zero);
        for j in (0..count).step_by(8) {
            // Points past `count` (a row's padding) are transposed but not
            // added: they may hold anything. One octet of one row set at a
            // time: the four at once would not fit in the registers.
            let len = (count - j).min(8);
            // SAFETY: j + 8 ≤ padded, so rows 0..16 of the block are within
            // the first LANES · padded values (asserted above).
            unsafe {
                d0 = add_columns(d0, d.add(j), padded, len);
                d1 = add_columns(d1, d.add(octet + j), padded, len);
                s0 = add_columns(s0, s.add(j), padded, len);
                s1 = add_columns(s1, s.add(octet + j), padded, len);
            }
        }
        let mut diffuse = [0.0f32; LANES];
        let mut specular = [0.0f32; LANES];
        // SAFETY: each destination holds eight f32s.
        unsafe {
            _mm256_storeu_ps(diffuse.as_mut_ptr(), d0);
            _mm256_storeu_ps(diffuse.as_mut_ptr().add(8), d1);
            _mm256_storeu_ps(specular.as_mut_ptr(), s0);
            _mm256_storeu_ps(specular.as_mut_ptr().add(8), s1);
        }
        (diffuse, specular)
    }

    /// The chains of [`SUMMED_TOGETHER`] lanes side by side, each lane's
    /// points gathered one by one (the portable build's). Not inlined: the
    /// AVX2 tile kernel, which never calls it, stays as small as before.
    #[inline(never)]
    fn sums_by_rows(&self) -> ([f32; LANES], [f32; LANES]) {
        let (count, padded) = (self.count, self.padded);
        let mut diffuse = [-0.0f32; LANES];
        let mut specular = [-0.0f32; LANES];
        for first in (0..LANES).step_by(SUMMED_TOGETHER) {
            let lanes = first..first + SUMMED_TOGETHER;
            fn rows(
                v: &[f32],
                first: usize,
                padded: usize,
                count: usize,
            ) -> [&[f32]; SUMMED_TOGETHER] {
                std::array::from_fn(|k| &v[(first + k) * padded..][..count])
            }
            let (d, s) = (
                rows(&self.d, first, padded, count),
                rows(&self.s, first, padded, count),
            );
            let mut sum_d = [-0.0f32; SUMMED_TOGETHER];
            let mut sum_s = [-0.0f32; SUMMED_TOGETHER];
            // Eight points at a time, as arrays: no bounds check inside.
            let whole = count - count % 8;
            for j in (0..whole).step_by(8) {
                let d: [&[f32; 8]; SUMMED_TOGETHER] =
                    std::array::from_fn(|k| d[k][j..j + 8].try_into().unwrap());
                let s: [&[f32; 8]; SUMMED_TOGETHER] =
                    std::array::from_fn(|k| s[k][j..j + 8].try_into().unwrap());
                for l in 0..8 {
                    for k in 0..SUMMED_TOGETHER {
                        sum_d[k] += d[k][l];
                        sum_s[k] += s[k][l];
                    }
                }
            }
            for j in whole..count {
                for k in 0..SUMMED_TOGETHER {
                    sum_d[k] += d[k][j];
                    sum_s[k] += s[k][j];
                }
            }
            diffuse[lanes.clone()].copy_from_slice(&sum_d);
            specular[lanes].copy_from_slice(&sum_s);
        }
        (diffuse, specular)
    }
}

/// `sum` plus, lane by lane in order, the first `len` of the eight points
/// from `p` of eight rows `stride` apart (lane k: row k).
///
/// # Safety
/// As [`transpose8`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn add_columns(
    mut sum: std::arch::x86_64::__m256,
    p: *const f32,
    stride: usize,
    len: usize,
) -> std::arch::x86_64::__m256 {
    use std::arch::x86_64::_mm256_add_ps;
    // SAFETY: as the caller vouches.
    let columns = unsafe { transpose8(p, stride) };
    for column in &columns[..len] {
        sum = _mm256_add_ps(sum, *column);
    }
    sum
}

/// The eight points from `p` of eight rows `stride` apart, as eight
/// vectors of one point each: lane k of vector l is `p[k·stride + l]`.
/// Rows k and k + 4 load as the two halves of one vector, so only the
/// in-half 4×4 transposes are shuffles (16 of them).
///
/// # Safety
/// The CPU has AVX2, and `p[k·stride + l]` is readable for k, l < 8.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn transpose8(p: *const f32, stride: usize) -> [std::arch::x86_64::__m256; 8] {
    use std::arch::x86_64::*;
    let mut out = [_mm256_setzero_ps(); 8];
    for h in 0..2 {
        // Points 4·h..4·h + 4 of rows k (low half) and k + 4 (high half).
        // SAFETY: within the rows the caller vouches for.
        let [r0, r1, r2, r3]: [__m256; 4] = std::array::from_fn(|k| unsafe {
            _mm256_loadu2_m128(p.add((k + 4) * stride + 4 * h), p.add(k * stride + 4 * h))
        });
        let (t0, t1) = (_mm256_unpacklo_ps(r0, r1), _mm256_unpackhi_ps(r0, r1));
        let (t2, t3) = (_mm256_unpacklo_ps(r2, r3), _mm256_unpackhi_ps(r2, r3));
        out[4 * h] = _mm256_shuffle_ps::<0x44>(t0, t2);
        out[4 * h + 1] = _mm256_shuffle_ps::<0xEE>(t0, t2);
        out[4 * h + 2] = _mm256_shuffle_ps::<0x44>(t1, t3);
        out[4 * h + 3] = _mm256_shuffle_ps::<0xEE>(t1, t3);
    }
    out
}

/// Points a pass of [`lane_sums`] takes at once.
const BLOCK: usize = 16;

type Kernel = fn(&LaneInputs, &[[u64; LANES]], &Points<'_>) -> ([f32; LANES], [f32; LANES]);

/// The light points of a batch: a fixed pattern's offsets along the
/// light's edges (`a`, `b`), or each point's lane by lane (`lane_a[j][h]`).
pub(crate) struct Points<'a> {
    pub(crate) a: &'a [f32],
    pub(crate) b: &'a [f32],
    pub(crate) lane_a: &'a [[f32; LANES]],
    pub(crate) lane_b: &'a [[f32; LANES]],
    pub(crate) fixed: bool,
    pub(crate) count: usize,
    pub(crate) edge_u: Vec3,
    pub(crate) edge_v: Vec3,
}

/// The light points of a batch of lanes, kept from batch to batch: a fixed
/// pattern's (the same at every hit), or each lane's own.
#[derive(Debug, Default)]
pub(crate) struct LanePoints {
    a: Vec<f32>,
    b: Vec<f32>,
    lane_a: Vec<[f32; LANES]>,
    lane_b: Vec<[f32; LANES]>,
    fixed: bool,
    count: usize,
}

impl LanePoints {
    /// Prepares for hits traced with `pattern`.
    pub(crate) fn start(&mut self, pattern: &Pattern) {
        let count = pattern.count();
        self.count = count;
        self.fixed = pattern.is_fixed();
        if self.fixed {
            // The same points at every hit (the generator is not used).
            let padded = count.next_multiple_of(8);
            self.a.resize(padded, 0.0);
            self.b.resize(padded, 0.0);
            pattern.fill(&mut Rng::new(0), &mut self.a, &mut self.b);
            self.a.truncate(count);
            self.b.truncate(count);
        } else {
            self.lane_a.clear();
            self.lane_b.clear();
            self.lane_a.resize(count, [0.0; LANES]);
            self.lane_b.resize(count, [0.0; LANES]);
        }
    }

    pub(crate) fn count(&self) -> usize {
        self.count
    }

    pub(crate) fn is_fixed(&self) -> bool {
        self.fixed
    }

    /// Lane h's points, offsets along the light's edges (a pattern drawn
    /// per hit only).
    #[inline]
    pub(crate) fn set_lane(&mut self, h: usize, a: &[f32], b: &[f32]) {
        for j in 0..self.count {
            self.lane_a[j][h] = a[j];
            self.lane_b[j][h] = b[j];
        }
    }

    /// The points as the kernels read them, for a light of these edges.
    pub(crate) fn with_edges(&self, edge_u: Vec3, edge_v: Vec3) -> Points<'_> {
        Points {
            a: &self.a,
            b: &self.b,
            lane_a: &self.lane_a,
            lane_b: &self.lane_b,
            fixed: self.fixed,
            count: self.count,
            edge_u,
            edge_v,
        }
    }
}

avx512_dispatch!(
    /// Every lane's factors, with the widest vectors the CPU has (the same
    /// operations lane by lane whatever the width, so the same bits).
    fn sampled_lanes(
        hits: &LaneInputs,
        bits: &[[u64; LANES]],
        points: &Points<'_>,
    ) -> ([f32; LANES], [f32; LANES]) => sampled_lanes_generic if true, else sampled_lanes_avx2
);

avx2_dispatch!(
    /// [`sampled_lanes`] on eight-lane vectors.
    fn sampled_lanes_avx2(
        hits: &LaneInputs,
        bits: &[[u64; LANES]],
        points: &Points<'_>,
    ) -> ([f32; LANES], [f32; LANES]) => sampled_lanes_generic
);

#[inline(always)]
fn sampled_lanes_generic(
    hits: &LaneInputs,
    bits: &[[u64; LANES]],
    points: &Points<'_>,
) -> ([f32; LANES], [f32; LANES]) {
    if points.fixed {
        let (a, b) = (&points.a[..points.count], &points.b[..points.count]);
        lane_sums(hits, bits, points, |j, _| (a[j], b[j]))
    } else {
        let (a, b) = (
            &points.lane_a[..points.count],
            &points.lane_b[..points.count],
        );
        lane_sums(hits, bits, points, |j, h| (a[j][h], b[j][h]))
    }
}

/// Each lane's averages of max(0, N·L) and max(0, N·H)^shininess over its
/// visible points.
#[inline(always)]
fn lane_sums(
    hits: &LaneInputs,
    bits: &[[u64; LANES]],
    points: &Points<'_>,
    point: impl Fn(usize, usize) -> (f32, f32),
) -> ([f32; LANES], [f32; LANES]) {
    let count = points.count;
    // Each sum left to right from −0 (as `Iterator::sum`).
    let mut diffuse = [-0.0f32; LANES];
    let mut specular = [-0.0f32; LANES];
    // A block of points at a time in passes (cosines, logarithms, powers,
    // sums): one loop made each point one chain of dependent operations
    // longer than the CPU overlaps from point to point (as
    // `shading::point_terms`). The same operations lane by lane and the
    // same order of the sums, so the same bits.
    let mut start = 0;
    while start < count {
        let len = (count - start).min(BLOCK);
        let mut f = [[0f32; LANES]; BLOCK];
        let mut s = [[0f32; LANES]; BLOCK];
        for i in 0..len {
            for h in 0..LANES {
                // As `light_directions`, then the terms of `sampled_terms`.
                let ((x, y, z, inv), n, v) = hits.towards(points, h, point(start + i, h));
                f[i][h] = ((n.x * x + n.y * y + n.z * z) * inv).max(0.0);
                s[i][h] = blinn_cosine(n, v, x, y, z, inv);
            }
        }
        // `pow_approx` in its two halves.
        for row in &mut s[..len] {
            for c in row.iter_mut() {
                *c = pow_log2(*c);
            }
        }
        for row in &mut s[..len] {
            for (c, &shininess) in row.iter_mut().zip(&hits.shininess) {
                *c = pow_from_log2(*c, shininess);
            }
        }
        for i in 0..len {
            let j = start + i;
            let (word, l) = (&bits[j / 64], j % 64);
            for h in 0..LANES {
                // The tracer multiplies by the visibility (1 or 0): the
                // term, or +0 (both are finite and not negative), here by
                // a mask of the term's bits (a select became a masked
                // store, slow on AMD's CPUs).
                let keep = 0u32.wrapping_sub(((word[h] >> l) & 1) as u32);
                diffuse[h] += f32::from_bits(f[i][h].to_bits() & keep);
                specular[h] += f32::from_bits(s[i][h].to_bits() & keep);
            }
        }
        start += len;
    }
    let inv_count = 1.0 / count as f32;
    (
        diffuse.map(|s| s * inv_count),
        specular.map(|s| s * inv_count),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::shading::sampled_terms;

    /// Every kernel this CPU runs: the baseline build, AVX2 (where the CPU
    /// has it) and the widest (AVX-512 where the CPU has it).
    fn kernels() -> Vec<(&'static str, Kernel)> {
        vec![
            ("portable", sampled_lanes_generic),
            ("avx2 or portable", sampled_lanes_avx2),
            ("widest", sampled_lanes),
        ]
    }

    /// The transposed sums add each row's points in the same order as the
    /// row by row ones, so the same bits, whatever the count (whole blocks
    /// of eight or not) and whatever the rows' padding holds.
    #[test]
    fn transposed_sums_give_the_bits_of_the_row_sums() {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            let mut rng = Rng::new(11);
            for count in [16, 17, 23, 24, 64, 100] {
                let mut rows = HitRows::default();
                rows.start(count);
                for (i, (d, s)) in rows.d.iter_mut().zip(rows.s.iter_mut()).enumerate() {
                    if i % rows.padded >= count {
                        // Padding: never added.
                        (*d, *s) = (f32::NAN, f32::INFINITY);
                    } else {
                        // Magnitudes far apart, so that the order of the
                        // additions shows in the bits.
                        *d = rng.next_f32() * [1.0, 1e-4, 1e4][i % 3];
                        *s = rng.next_f32() * [1e-7, 1.0, 3e3][i % 3];
                    }
                }
                let bits = |(d, s): ([f32; LANES], [f32; LANES])| {
                    (d.map(f32::to_bits), s.map(f32::to_bits))
                };
                let by_rows = bits(rows.sums_by_rows());
                // SAFETY: the CPU has AVX2 (checked above).
                let transposed = bits(unsafe { rows.sums_transposed() });
                assert_eq!(transposed, by_rows, "{count} points");
                assert!(by_rows.0.iter().all(|&b| f32::from_bits(b) > 0.0));
            }
        }
    }

    /// Hits pushed in batches give, bit for bit, the tracer's factors of
    /// each hit alone (`sampled_terms` on its directions and visibility).
    #[test]
    fn lanes_give_the_bits_of_one_hit_at_a_time() {
        let (eu, ev) = (Vec3::new(2.0, 0.0, 0.1), Vec3::new(0.0, 0.3, 2.0));
        for (sampling, rays) in [
            (Sampling::Grid, 1),
            (Sampling::Grid, 4),
            (Sampling::Grid, 9),
            (Sampling::Random, 1),
            (Sampling::Random, 13),
            (Sampling::Stratified, 9),
            (Sampling::Grid, 64),
            (Sampling::Random, 100),
        ] {
            let pattern = Pattern::new(sampling, rays);
            let count = pattern.count();
            let mut rng = Rng::new(7);
            let r = |rng: &mut Rng| rng.next_f32() * 2.0 - 1.0;
            // 37 hits: two full batches and a partial one; each with its
            // own light points (for patterns drawn per hit) and visibility.
            let mut bufs = Vec::new();
            let mut hits = Vec::new();
            for i in 0..37 {
                let mut buf = ShadowBuffers::with_capacity(count);
                pattern.fill(&mut Rng::new(100 + i as u64), &mut buf.a, &mut buf.b);
                let hit = LaneHit {
                    to_corner: Vec3::new(r(&mut rng), 3.0 + r(&mut rng), r(&mut rng)),
                    normal: Vec3::new(r(&mut rng), 1.0, r(&mut rng)).normalize(),
                    view: Vec3::new(r(&mut rng), r(&mut rng), 1.0).normalize(),
                    shininess: [1.0, 20.0, 100.0, 500.0][i % 4],
                    specular: i % 5 != 0,
                };
                for j in 0..count {
                    let c = hit.to_corner;
                    // As `light_directions`.
                    buf.dx[j] = c.x + eu.x * buf.a[j] + ev.x * buf.b[j];
                    buf.dy[j] = c.y + eu.y * buf.a[j] + ev.y * buf.b[j];
                    buf.dz[j] = c.z + eu.z * buf.a[j] + ev.z * buf.b[j];
                    // Some hits with one point visible, most with about half.
                    let lit = if i % 7 == 3 {
                        j == count / 2
                    } else {
                        rng.next_f32() < 0.5
                    };
                    buf.vis[j] = if lit || j == 0 { 1.0 } else { 0.0 };
                }
                hits.push(hit);
                bufs.push(buf);
            }
            let want: Vec<(u32, u32)> = hits
                .iter()
                .zip(&mut bufs)
                .map(|(hit, buf)| {
                    let t = sampled_terms(
                        hit.normal,
                        hit.view,
                        hit.shininess,
                        hit.specular,
                        count,
                        buf,
                    );
                    (t.diffuse.to_bits(), t.specular.to_bits())
                })
                .collect();
            assert!(
                want.iter()
                    .any(|&(d, s)| f32::from_bits(d) > 0.0 && f32::from_bits(s) > 0.0),
                "some hits are lit"
            );
            for (name, kernel) in kernels() {
                let mut lanes = SampledLanes::default();
                lanes.start(&pattern);
                let mut got = vec![(f32::NAN.to_bits(), f32::NAN.to_bits()); hits.len()];
                let mut store =
                    |i: usize, f: LightTerms| got[i] = (f.diffuse.to_bits(), f.specular.to_bits());
                for (i, (hit, buf)) in hits.iter().zip(&bufs).enumerate() {
                    if lanes.push(i, *hit, buf) {
                        lanes.flush_by(kernel, eu, ev, &mut store);
                    }
                }
                lanes.flush_by(kernel, eu, ev, &mut store);
                assert_eq!(got, want, "{name}: {sampling:?} {rays}");
            }
        }
    }
}
