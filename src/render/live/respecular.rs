//! The re-shading kernel: the specular factors of recorded hits for a new
//! shininess, from their recorded light direction, normal, view and
//! visibility bits — the operations of the tracer's sampled specular term
//! (`shading::sampled_terms`) point by point and the same left-to-right
//! sum, so the same bits.
//!
//! [`LANES`] hits run side by side, one per vector lane, walking their
//! light points together: each lane's sum is one hit's, in the points'
//! order, so the sums need no second pass over stored terms, and with a
//! fixed pattern (the grid) the points' offsets along the light's edges
//! are computed once per point for all lanes.

use glam::Vec3;

use super::cosine_logs::{CosineLogs, NO_HIT};
use crate::render::math::{avx2_dispatch, avx512_dispatch, pow_from_log2, pow_log2};
use crate::render::rng::Rng;
use crate::render::sampled_lanes::{LaneInputs, LanePoints, Points};
use crate::render::sampling::Pattern;
use crate::render::shading::blinn_cosine;

/// Hits computed side by side (one AVX-512 vector; 32, two vectors, spilled
/// registers and was slower).
pub const LANES: usize = 16;

/// What a recorded hit's specular factor depends on.
#[derive(Debug, Clone, Copy, Default)]
pub struct RecordedHit {
    /// From the hit point to the light's corner (as the tracer had it).
    pub to_corner: Vec3,
    pub normal: Vec3,
    pub view: Vec3,
    pub shininess: f32,
}

/// Recorded hits waiting for their specular factors (per tile, reused from
/// batch to batch).
#[derive(Default)]
pub struct ReshadeBatch {
    /// Index of each waiting hit in its tile's records.
    index: Vec<usize>,
    hits: LaneInputs,
    /// Visibility, 32 points per entry: bit l of `bits[k][h]` is point
    /// 32·k + l of lane h.
    bits: Vec<[u32; LANES]>,
    points: LanePoints,
    /// Scratch for one hit's points drawn from its generator.
    one_a: Vec<f32>,
    one_b: Vec<f32>,
    /// The batch's logarithms when they are not kept.
    logs: Vec<[f32; LANES]>,
}

impl ReshadeBatch {
    /// Prepares for the hits of a frame traced with `pattern`.
    pub fn start(&mut self, pattern: &Pattern) {
        let count = pattern.count();
        self.index.clear();
        self.bits.clear();
        self.bits.resize(count.div_ceil(32), [0; LANES]);
        self.points.start(pattern);
        if !pattern.is_fixed() {
            let padded = count.next_multiple_of(8);
            self.one_a.resize(padded, 0.0);
            self.one_b.resize(padded, 0.0);
        }
    }

    /// Adds hit `index` (`visible`: its `count.div_ceil(64)` visibility
    /// words; its light points drawn from `rng()` unless the pattern is
    /// fixed); true once the batch is full.
    pub fn push(
        &mut self,
        index: usize,
        hit: RecordedHit,
        visible: &[u64],
        pattern: &Pattern,
        rng: impl FnOnce() -> Rng,
    ) -> bool {
        let h = self.index.len();
        self.index.push(index);
        self.hits
            .set(h, hit.to_corner, hit.normal, hit.view, hit.shininess);
        for (k, bits) in self.bits.iter_mut().enumerate() {
            bits[h] = (visible[k / 2] >> (k % 2 * 32)) as u32;
        }
        if !self.points.is_fixed() {
            pattern.fill(&mut rng(), &mut self.one_a, &mut self.one_b);
            self.points.set_lane(h, &self.one_a, &self.one_b);
        }
        self.index.len() == LANES
    }

    /// Computes the waiting hits' specular factors: `store(index, factor)`
    /// for each.
    pub fn flush(&mut self, edge_u: Vec3, edge_v: Vec3, store: impl FnMut(usize, f32)) {
        self.flush_by(WIDEST, edge_u, edge_v, None, store);
    }

    /// As [`ReshadeBatch::flush`], and appends the batch with its light
    /// points' logarithms to `logs`.
    pub fn flush_keeping(
        &mut self,
        edge_u: Vec3,
        edge_v: Vec3,
        logs: &mut CosineLogs,
        store: impl FnMut(usize, f32),
    ) {
        self.flush_by(WIDEST, edge_u, edge_v, Some(logs), store);
    }

    fn flush_by(
        &mut self,
        (logs_kernel, sums_kernel): Kernels,
        edge_u: Vec3,
        edge_v: Vec3,
        keep: Option<&mut CosineLogs>,
        mut store: impl FnMut(usize, f32),
    ) {
        if self.index.is_empty() {
            return;
        }
        let points = self.points.with_edges(edge_u, edge_v);
        let logs = match keep {
            Some(kept) => {
                let mut lanes = [NO_HIT; LANES];
                for (lane, &i) in lanes.iter_mut().zip(&self.index) {
                    *lane = i as u32;
                }
                kept.batches.push(lanes);
                let from = kept.logs.len();
                kept.logs.resize(from + points.count, [0.0; LANES]);
                &mut kept.logs[from..]
            }
            None => {
                self.logs.resize(points.count, [0.0; LANES]);
                &mut self.logs[..]
            }
        };
        // Lanes past the waiting hits hold finite leftovers of earlier
        // batches (or zeros) and are not read out.
        logs_kernel(&self.hits, &self.bits, &points, logs);
        let sums = sums_kernel(logs, &self.hits.shininess);
        for (&i, s) in self.index.iter().zip(sums) {
            store(i, s);
        }
        self.index.clear();
    }
}

/// The two halves of the computation: the logarithms, then the sums.
type Kernels = (
    fn(&LaneInputs, &[[u32; LANES]], &Points<'_>, &mut [[f32; LANES]]),
    fn(&[[f32; LANES]], &[f32; LANES]) -> [f32; LANES],
);

const WIDEST: Kernels = (cosine_logs_lanes, specular_from_logs);

avx512_dispatch!(
    /// Into `logs[j][h]`, log2 of Blinn's cosine at light point j of lane
    /// h (`math::pow_log2`), or −∞ where the point is hidden, with the
    /// widest vectors the CPU has (the same operations lane by lane
    /// whatever the width, so the same bits).
    fn cosine_logs_lanes(
        hits: &LaneInputs,
        bits: &[[u32; LANES]],
        points: &Points<'_>,
        logs: &mut [[f32; LANES]],
    ) => cosine_logs_generic if true, else cosine_logs_avx2
);

avx2_dispatch!(
    /// [`cosine_logs_lanes`] on eight-lane vectors.
    fn cosine_logs_avx2(
        hits: &LaneInputs,
        bits: &[[u32; LANES]],
        points: &Points<'_>,
        logs: &mut [[f32; LANES]],
    ) => cosine_logs_generic
);

#[inline(always)]
fn cosine_logs_generic(
    hits: &LaneInputs,
    bits: &[[u32; LANES]],
    points: &Points<'_>,
    logs: &mut [[f32; LANES]],
) {
    let count = points.count;
    let logs = &mut logs[..count];
    if points.fixed {
        let (a, b) = (&points.a[..count], &points.b[..count]);
        lane_cosines(hits, points, logs, |j: usize, _: usize| (a[j], b[j]));
    } else {
        let (a, b) = (&points.lane_a[..count], &points.lane_b[..count]);
        lane_cosines(hits, points, logs, |j: usize, h: usize| (a[j][h], b[j][h]));
    }
    // A second pass over the stored cosines: one loop with both halves made
    // each point a chain of some 90 dependent operations (two square
    // roots, three divisions, two polynomials) longer than the CPU can
    // overlap from one point to the next.
    for (k, word) in bits.iter().enumerate() {
        for (l, row) in logs[32 * k..].iter_mut().take(32).enumerate() {
            for h in 0..LANES {
                // A hidden point's term is +0 in the tracer (0 × a finite
                // factor), as `pow_from_log2(−∞)`.
                row[h] = if (word[h] >> l) & 1 != 0 {
                    pow_log2(row[h])
                } else {
                    f32::NEG_INFINITY
                };
            }
        }
    }
}

/// Blinn's cosine max(0, N·H) at every light point of every lane, into
/// `out[j][h]`.
#[inline(always)]
fn lane_cosines(
    hits: &LaneInputs,
    points: &Points<'_>,
    out: &mut [[f32; LANES]],
    point: impl Fn(usize, usize) -> (f32, f32),
) {
    for (j, row) in out.iter_mut().enumerate() {
        for (h, cosine) in row.iter_mut().enumerate() {
            // As `light_directions`, then the specular term.
            let ((x, y, z, inv), n, v) = hits.towards(points, h, point(j, h));
            *cosine = blinn_cosine(n, v, x, y, z, inv);
        }
    }
}

avx512_dispatch!(
    /// The specular factor of every lane from its light points' logarithms
    /// (`logs[j][h]`, one row per point, −∞ for a hidden one) for the
    /// lanes' `shininess`: the tracer's terms (`pow_approx` is
    /// `pow_from_log2 ∘ pow_log2`) and its left-to-right sum from −0 (as
    /// `Iterator::sum`), times 1 / the number of points.
    pub fn specular_from_logs(
        logs: &[[f32; LANES]],
        shininess: &[f32; LANES],
    ) -> [f32; LANES] => specular_from_logs_generic if true, else specular_from_logs_avx2
);

avx2_dispatch!(
    /// [`specular_from_logs`] on eight-lane vectors.
    fn specular_from_logs_avx2(
        logs: &[[f32; LANES]],
        shininess: &[f32; LANES],
    ) -> [f32; LANES] => specular_from_logs_generic
);

#[inline(always)]
fn specular_from_logs_generic(logs: &[[f32; LANES]], shininess: &[f32; LANES]) -> [f32; LANES] {
    let mut sums = [-0.0f32; LANES];
    for row in logs {
        for h in 0..LANES {
            sums[h] += pow_from_log2(row[h], shininess[h]);
        }
    }
    sums.map(|s| s * (1.0 / logs.len() as f32))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::math::pow_approx;
    use crate::render::scene_file::Sampling;

    /// The definition, hit by hit: the tracer's specular term with its
    /// visibility weights and sum.
    pub(super) fn one_hit(
        hit: &RecordedHit,
        visible: &[u64],
        a: &[f32],
        b: &[f32],
        eu: Vec3,
        ev: Vec3,
    ) -> f32 {
        let terms: Vec<f32> = (0..a.len())
            .map(|j| {
                let (x, y, z) = (
                    hit.to_corner.x + eu.x * a[j] + ev.x * b[j],
                    hit.to_corner.y + eu.y * a[j] + ev.y * b[j],
                    hit.to_corner.z + eu.z * a[j] + ev.z * b[j],
                );
                let inv = 1.0 / (x * x + y * y + z * z).sqrt();
                let (n, v) = (hit.normal, hit.view);
                let (hx, hy, hz) = (x * inv + v.x, y * inv + v.y, z * inv + v.z);
                let h2 = hx * hx + hy * hy + hz * hz;
                let c = ((n.x * hx + n.y * hy + n.z * hz) / h2.sqrt()).max(0.0);
                let c = if h2 > 0.0 { c } else { 0.0 };
                let vis = ((visible[j / 64] >> (j % 64)) & 1) as f32;
                vis * pow_approx(c, hit.shininess)
            })
            .collect();
        terms.iter().sum::<f32>() * (1.0 / a.len() as f32)
    }

    /// Every kernel this CPU runs: the baseline build, AVX2 (where the CPU
    /// has it) and the widest (AVX-512 where the CPU has it).
    fn kernels() -> Vec<(&'static str, Kernels)> {
        vec![
            (
                "portable",
                (cosine_logs_generic, specular_from_logs_generic),
            ),
            (
                "avx2 or portable",
                (cosine_logs_avx2, specular_from_logs_avx2),
            ),
            ("widest", WIDEST),
        ]
    }

    #[test]
    fn lanes_give_the_bits_of_one_hit_at_a_time() {
        let (eu, ev) = (Vec3::new(2.0, 0.0, 0.1), Vec3::new(0.0, 0.3, 2.0));
        for (sampling, rays) in [
            (Sampling::Grid, 64),
            (Sampling::Grid, 9),
            (Sampling::Random, 100),
        ] {
            let pattern = Pattern::new(sampling, rays);
            let count = pattern.count();
            let mut rng = Rng::new(7);
            let r = |rng: &mut Rng| rng.next_f32() * 2.0 - 1.0;
            // Two full batches and a partial one.
            let hits: Vec<(RecordedHit, Vec<u64>)> = (0..2 * LANES + 5)
                .map(|i| {
                    let hit = RecordedHit {
                        to_corner: Vec3::new(r(&mut rng), 3.0 + r(&mut rng), r(&mut rng)),
                        normal: Vec3::new(r(&mut rng), 1.0, r(&mut rng)).normalize(),
                        view: Vec3::new(r(&mut rng), r(&mut rng), 1.0).normalize(),
                        shininess: [1.0, 20.0, 100.0, 500.0][i % 4],
                    };
                    let visible = (0..count.div_ceil(64))
                        .map(|k| {
                            let tail = count - 64 * k;
                            let w = rng.next_u64();
                            if tail < 64 { w & ((1 << tail) - 1) } else { w }
                        })
                        .collect();
                    (hit, visible)
                })
                .collect();
            let seed = |i: usize| 100 + i as u64;
            let want: Vec<u32> = hits
                .iter()
                .enumerate()
                .map(|(i, (hit, visible))| {
                    let (mut a, mut b) = (vec![0.0; count + 8], vec![0.0; count + 8]);
                    pattern.fill(&mut Rng::new(seed(i)), &mut a, &mut b);
                    one_hit(hit, visible, &a[..count], &b[..count], eu, ev).to_bits()
                })
                .collect();
            assert!(
                want.iter().any(|&s| f32::from_bits(s) > 0.0),
                "some hits are lit"
            );
            for (name, kernel) in kernels() {
                let mut batch = ReshadeBatch::default();
                batch.start(&pattern);
                let mut got = vec![f32::NAN.to_bits(); hits.len()];
                for (i, (hit, visible)) in hits.iter().enumerate() {
                    if batch.push(i, *hit, visible, &pattern, || Rng::new(seed(i))) {
                        batch.flush_by(kernel, eu, ev, None, |i, s| got[i] = s.to_bits());
                    }
                }
                batch.flush_by(kernel, eu, ev, None, |i, s| got[i] = s.to_bits());
                assert_eq!(got, want, "{name}: {sampling:?} {rays}");
            }
        }
    }
}

#[cfg(test)]
mod kept_logs_tests {
    use super::tests::one_hit;
    use super::*;
    use crate::render::scene_file::Sampling;

    #[test]
    fn kept_logs_give_the_bits_of_the_full_term_for_any_shininess() {
        let (eu, ev) = (Vec3::new(1.0, 0.0, 0.2), Vec3::new(0.1, 0.0, 1.0));
        for (sampling, rays) in [(Sampling::Grid, 64), (Sampling::Random, 20)] {
            let pattern = Pattern::new(sampling, rays);
            let count = pattern.count();
            let all = vec![u64::MAX; count.div_ceil(64)];
            let visible: Vec<u64> = all
                .iter()
                .enumerate()
                .map(|(k, &w)| {
                    let left = count - 64 * k;
                    if left < 64 { (1 << left) - 1 } else { w }
                })
                .collect();
            let mut rng = Rng::new(3);
            let r = |rng: &mut Rng| rng.next_f32() * 2.0 - 1.0;
            // A full batch and a partial one; some facing away from the
            // light (cosine 0, whose log is −∞).
            let hits: Vec<RecordedHit> = (0..LANES + 5)
                .map(|i| RecordedHit {
                    to_corner: Vec3::new(r(&mut rng), 2.0 + r(&mut rng), r(&mut rng)),
                    normal: Vec3::new(
                        r(&mut rng),
                        if i % 5 == 0 { -1.0 } else { 1.0 },
                        r(&mut rng),
                    )
                    .normalize(),
                    view: Vec3::new(r(&mut rng), 0.5, r(&mut rng)).normalize(),
                    shininess: [3.0, 20.0, 150.0][i % 3],
                })
                .collect();
            let points = |i: usize| {
                let (mut a, mut b) = (vec![0.0; count + 8], vec![0.0; count + 8]);
                pattern.fill(&mut Rng::new(50 + i as u64), &mut a, &mut b);
                (a[..count].to_vec(), b[..count].to_vec())
            };
            let mut batch = ReshadeBatch::default();
            batch.start(&pattern);
            let mut logs = CosineLogs::with_room(vec![true], hits.len(), count);
            let mut got = vec![f32::NAN.to_bits(); hits.len()];
            for (i, hit) in hits.iter().enumerate() {
                if batch.push(i, *hit, &visible, &pattern, || Rng::new(50 + i as u64)) {
                    batch.flush_keeping(eu, ev, &mut logs, |i, s| got[i] = s.to_bits());
                }
            }
            batch.flush_keeping(eu, ev, &mut logs, |i, s| got[i] = s.to_bits());
            let want = |shininess: &dyn Fn(usize) -> f32| -> Vec<u32> {
                (0..hits.len())
                    .map(|i| {
                        let (a, b) = points(i);
                        let hit = RecordedHit {
                            shininess: shininess(i),
                            ..hits[i]
                        };
                        one_hit(&hit, &visible, &a, &b, eu, ev).to_bits()
                    })
                    .collect()
            };
            assert_eq!(got, want(&|i| hits[i].shininess), "{sampling:?}: kept");
            assert_eq!(logs.batches.len(), 2);
            assert_eq!(logs.logs.len(), 2 * count);
            assert!(logs.bytes() <= CosineLogs::bytes_for(1, hits.len(), count));
            assert!(logs.logs.iter().flatten().any(|&l| l == f32::NEG_INFINITY));
            // A new shininess from the logs alone.
            for new in [1.0f32, 47.5, 900.0] {
                let mut from_logs = vec![f32::NAN.to_bits(); hits.len()];
                for (b, lanes) in logs.batches.iter().enumerate() {
                    let y = [new; LANES];
                    let sums = specular_from_logs(&logs.logs[b * count..(b + 1) * count], &y);
                    for (&i, s) in lanes.iter().zip(sums) {
                        if i != NO_HIT {
                            from_logs[i as usize] = s.to_bits();
                        }
                    }
                }
                assert_eq!(from_logs, want(&|_| new), "{sampling:?}: shininess {new}");
                assert!(from_logs.iter().any(|&s| f32::from_bits(s) > 0.0));
            }
        }
    }
}
