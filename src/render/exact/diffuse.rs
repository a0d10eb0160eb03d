//! The diffuse factor over the visible pieces by the divergence theorem
//! (the edge terms of `analytic.rs`, copied here so that the `analytic`
//! model's images stay the same bits).
//!
//! The pieces tile the visible region, and an edge two pieces share is
//! crossed once each way: its two terms cancel. So the edges are matched
//! (the subtraction makes both sides of a cut from the same numbers, so
//! shared edges have the same endpoints bit for bit) and only the region's
//! outline is summed, about half the edges of the pieces. Where the whole
//! light is small against its distance the per-piece integral of
//! `analytic.rs` is kept (its quadrature branch avoids the edge sum's
//! cancellation there).

use glam::DVec2;

use super::polygon::{Pieces, edges_of};
use crate::render::analytic::diffuse_polygon_integral;
use crate::render::math::avx2_dispatch;

/// Light radius below this fraction of its distance: the per-piece path
/// (as `analytic.rs`'s own switch).
const SMALL_LIGHT: f64 = 0.05;

/// One directed edge, with its endpoints in a canonical order.
#[derive(Debug, Clone, Copy)]
pub struct Edge {
    /// The edge's identity: `key(lo)`, `key(hi)`.
    order: [u64; 4],
    pub lo: DVec2,
    pub hi: DVec2,
    /// +1 if the piece runs lo → hi, −1 if hi → lo (after
    /// [`outline`]: the net count of crossings).
    pub sign: f64,
}

fn key(p: DVec2) -> (u64, u64) {
    // Ordered as the numbers for the finite values the pieces hold.
    let k = |x: f64| {
        let b = x.to_bits();
        if b >> 63 == 1 { !b } else { b | 1 << 63 }
    };
    (k(p.x), k(p.y))
}

/// ∫ (a·x + b)/√(|x|² + h²) dx over the pieces (each counter-clockwise,
/// with a·x + b ≥ 0 on them); `rect`: the light, which holds them.
pub fn diffuse_over_pieces(
    pieces: &Pieces,
    rect: &[DVec2; 4],
    a: DVec2,
    b: f64,
    h: f64,
    outline_scratch: &mut Outline,
) -> f64 {
    if small_light(rect, h) {
        return pieces
            .iter()
            .map(|poly| diffuse_polygon_integral(poly, a, b, h))
            .sum();
    }
    if pieces.len() < 2 {
        return pieces
            .iter()
            .map(|poly| {
                // The whole light (the points it lights wholly): the same
                // test as the light's just above, so it is not small.
                if poly == rect {
                    edge_sum(poly, a, b, h)
                } else {
                    piece_integral(poly, a, b, h)
                }
            })
            .sum();
    }
    outline(pieces, outline_scratch);
    let mut angle = AngleSum::default();
    let mut rest = 0.0;
    let edges = &outline_scratch.edges;
    for_each_segment(
        edges.len(),
        |i| (edges[i].lo, edges[i].hi),
        a,
        b,
        h,
        |i, r, z| {
            let e = &edges[i];
            rest += e.sign * r;
            // The angle of the edge run backwards is the negative one: the
            // conjugate.
            for _ in 0..e.sign.abs() as u32 {
                angle.add(if e.sign > 0.0 {
                    z
                } else {
                    DVec2::new(z.x, -z.y)
                });
            }
        },
    );
    rest + b * h.abs() * angle.total()
}

/// Whether the light `rect` is small against its distance (|h| below the
/// plane): [`diffuse_over_pieces`] then takes `analytic.rs`'s per-piece
/// integral.
pub fn small_light(rect: &[DVec2; 4], h: f64) -> bool {
    let centre = (rect[0] + rect[1] + rect[2] + rect[3]) * 0.25;
    // One square root of the largest square: the same number as the
    // largest root (the root is rounded correctly, so it keeps the order).
    let radius = rect
        .iter()
        .map(|&p| (p - centre).length_squared())
        .fold(0.0, f64::max)
        .sqrt();
    radius < SMALL_LIGHT * (centre.length_squared() + h * h).sqrt()
}

/// The outline of a set of pieces: its edges, and the hash table that
/// finds an edge again (kept warm).
#[derive(Debug, Clone, Default)]
pub struct Outline {
    pub edges: Vec<Edge>,
    /// Index into `edges` + 1 of each slot's edge, 0 for none.
    slots: Vec<u32>,
}

/// The outline of the pieces into `out.edges`: each edge with its net
/// crossings (`sign`, ±1 where the outline runs lo → hi or back), the edges
/// two pieces share left out, in the order they first appear. The same
/// edge is found again by its endpoints' bits in a hash table (linear in
/// the edges, where sorting them was n log n moves of whole edges).
pub fn outline(pieces: &Pieces, out: &mut Outline) {
    let Outline { edges, slots } = out;
    edges.clear();
    // At least twice as many slots as edges: short probe runs.
    let bits = (2 * pieces.verts.len())
        .max(16)
        .next_power_of_two()
        .trailing_zeros();
    slots.clear();
    slots.resize(1 << bits, 0);
    let mask = (1usize << bits) - 1;
    for poly in pieces.iter() {
        let mut kp = key(poly[0]);
        for (p, q) in edges_of(poly) {
            let kq = key(q);
            let (order, lo, hi, sign) = match kp.cmp(&kq) {
                std::cmp::Ordering::Less => ([kp.0, kp.1, kq.0, kq.1], p, q, 1.0),
                std::cmp::Ordering::Greater => ([kq.0, kq.1, kp.0, kp.1], q, p, -1.0),
                std::cmp::Ordering::Equal => {
                    kp = kq;
                    continue;
                }
            };
            kp = kq;
            let hash = (order[0]
                ^ order[1].rotate_left(16)
                ^ order[2].rotate_left(32)
                ^ order[3].rotate_left(48))
            .wrapping_mul(0x9E37_79B9_7F4A_7C15);
            let mut slot = (hash >> (64 - bits)) as usize;
            loop {
                match slots[slot] {
                    0 => {
                        edges.push(Edge {
                            order,
                            lo,
                            hi,
                            sign,
                        });
                        slots[slot] = edges.len() as u32;
                        break;
                    }
                    k if edges[k as usize - 1].order == order => {
                        edges[k as usize - 1].sign += sign;
                        break;
                    }
                    _ => slot = (slot + 1) & mask,
                }
            }
        }
    }
    edges.retain(|e| e.sign != 0.0);
}

/// One counter-clockwise convex piece: `analytic.rs`'s integral where the
/// piece is small against its distance (its quadrature branch), else the
/// edge sum with this file's cheaper inverse hyperbolic sine.
fn piece_integral(poly: &[DVec2], a: DVec2, b: f64, h: f64) -> f64 {
    let k = poly.len();
    if k < 3 {
        return 0.0;
    }
    let centroid = poly.iter().copied().sum::<DVec2>() / k as f64;
    let radius = poly
        .iter()
        .map(|q| (*q - centroid).length_squared())
        .fold(0.0, f64::max)
        .sqrt();
    if radius < SMALL_LIGHT * (centroid.length_squared() + h * h).sqrt() {
        return diffuse_polygon_integral(poly, a, b, h);
    }
    edge_sum(poly, a, b, h)
}

/// The edge sum of one counter-clockwise convex piece.
pub fn edge_sum(poly: &[DVec2], a: DVec2, b: f64, h: f64) -> f64 {
    let mut angle = AngleSum::default();
    let mut rest = 0.0;
    let k = poly.len();
    let edge = |i: usize| (poly[i], poly[if i + 1 == k { 0 } else { i + 1 }]);
    for_each_segment(k, edge, a, b, h, |_, r, z| {
        rest += r;
        angle.add(z);
    });
    rest + b * h.abs() * angle.total()
}

/// The sum of the arguments of complex numbers (x + iy as (x, y)), each
/// in [−π, π] as `atan2` gives it, with one `atan2` at the end: their
/// product's argument plus the whole turns counted on the way (a product
/// of two numbers in the same half-plane whose argument lands in the other
/// one has turned past ±π). The edges' angles φ_q − φ_p all carry the same
/// factor b|h|, so a piece needs one arctangent instead of one per edge.
#[derive(Debug, Clone, Copy)]
struct AngleSum {
    /// The product so far, rescaled to keep it in range.
    product: DVec2,
    turns: f64,
}

impl Default for AngleSum {
    fn default() -> AngleSum {
        AngleSum {
            product: DVec2::X,
            turns: 0.0,
        }
    }
}

impl AngleSum {
    fn add(&mut self, z: DVec2) {
        // atan2(0, 0) = 0: adds nothing (and would zero the product).
        if z == DVec2::ZERO {
            return;
        }
        let w = self.product;
        let p = DVec2::new(w.x * z.x - w.y * z.y, w.x * z.y + w.y * z.x);
        // The sign bits decide the half-planes as `atan2` does (+0 above,
        // −0 below).
        let (lw, lz, lp) = (
            w.y.is_sign_negative(),
            z.y.is_sign_negative(),
            p.y.is_sign_negative(),
        );
        if !lw && !lz && lp {
            self.turns += 1.0;
        } else if lw && lz && !lp {
            self.turns -= 1.0;
        }
        // Rescaled only when far from 1 (each edge's number is about the
        // light's size to the sixth power, far inside the range).
        let size = p.x.abs().max(p.y.abs());
        self.product = if (1e-100..=1e100).contains(&size) {
            p
        } else {
            p / size
        };
    }

    fn total(&self) -> f64 {
        self.product.y.atan2(self.product.x) + std::f64::consts::TAU * self.turns
    }
}

/// The flux of F(x) = a g(x) + b x/(g(x) + |h|) out through the straight
/// boundary segment p → q of a counter-clockwise region: one edge of
/// `analytic.rs`'s edge sum, G(τ_q) − G(τ_p) with
/// G(τ) = a·ν (τ r + c² asinh(τ/c))/2 + b (d asinh(τ/c) + |h| φ(τ)),
/// taken as differences: asinh(τ_q/c) − asinh(τ_p/c) = ln(A_q/A_p) with
/// A = τ + r (as c²/(r − τ) for τ < 0, without cancellation), and
/// φ_q − φ_p as one angle (φ's cosine part d² r + |h| τ² is ≥ 0, so both
/// angles lie in [−π/2, π/2] and their difference in [−π, π]): one
/// logarithm and one arctangent an edge instead of two of each.
pub fn segment_term(p: DVec2, q: DVec2, a: DVec2, b: f64, h: f64) -> f64 {
    let (rest, z) = segment_parts(p, q, a, b, h);
    rest + b * h.abs() * z.y.atan2(z.x)
}

/// [`segment_term`] in two parts: the terms but the angle's, and the
/// complex number (x, y) whose argument is φ_q − φ_p (times b|h| in the
/// term).
fn segment_parts(p: DVec2, q: DVec2, a: DVec2, b: f64, h: f64) -> (f64, DVec2) {
    let (rest, z) = segment_lanes(&[p], &[q], a, b, h);
    (rest[0], z[0])
}

/// Edges taken at once by [`edges_at_once`].
const LANES: usize = 4;

avx2_dispatch!(
    /// [`segment_parts`] of `LANES` edges at once, compiled for AVX2: the
    /// square roots and divisions of four edges in one instruction each
    /// (the same operations lane by lane, so the same bits).
    fn edges_at_once(p: &[DVec2; LANES], q: &[DVec2; LANES], a: DVec2, b: f64, h: f64)
        -> ([f64; LANES], [DVec2; LANES]) => segment_lanes
);

/// [`segment_parts`] of the edges p\[k\] → q\[k\], lane by lane (each
/// coordinate its own array, for the vectorizer); an edge of length 0
/// gives (0, 1).
#[inline(always)]
fn segment_lanes<const N: usize>(
    p: &[DVec2; N],
    q: &[DVec2; N],
    a: DVec2,
    b: f64,
    h: f64,
) -> ([f64; N], [DVec2; N]) {
    segment_lanes_of(p, q, |_| (a, b, h))
}

/// [`segment_lanes`] with each lane's own (a, b, h) from `params`.
#[inline(always)]
fn segment_lanes_of<const N: usize>(
    p: &[DVec2; N],
    q: &[DVec2; N],
    params: impl Fn(usize) -> (DVec2, f64, f64),
) -> ([f64; N], [DVec2; N]) {
    let (mut len, mut c2, mut ratio) = ([0.0; N], [0.0; N], [0.0; N]);
    let (mut part, mut coef) = ([0.0; N], [0.0; N]);
    let (mut zx, mut zy) = ([0.0; N], [0.0; N]);
    for k in 0..N {
        let (a, b, h) = params(k);
        let ah = h.abs();
        let (px, py, qx, qy) = (p[k].x, p[k].y, q[k].x, q[k].y);
        let (ex, ey) = (qx - px, qy - py);
        len[k] = (ex * ex + ey * ey).sqrt();
        let (tx, ty) = (ex / len[k], ey / len[k]);
        let (nx, ny) = (ty, -tx);
        let d = px * nx + py * ny;
        c2[k] = d * d + ah * ah;
        let an = a.x * nx + a.y * ny;
        let (tp, tq) = (px * tx + py * ty, qx * tx + qy * ty);
        let (rp, rq) = ((tp * tp + c2[k]).sqrt(), (tq * tq + c2[k]).sqrt());
        let up = |tau: f64, r: f64| {
            if tau >= 0.0 {
                tau + r
            } else {
                c2[k] / (r - tau)
            }
        };
        ratio[k] = up(tq, rq) / up(tp, rp);
        // φ(τ) = atan2(y, x).
        let angle = |tau: f64, r: f64| {
            (
                -tau * d * (tau * tau + d * d) / (r + ah),
                d * d * r + ah * tau * tau,
            )
        };
        let ((yp, xp), (yq, xq)) = (angle(tp, rp), angle(tq, rq));
        (zx[k], zy[k]) = (xq * xp + yq * yp, yq * xp - xq * yp);
        part[k] = an * 0.5 * (tq * rq - tp * rp);
        coef[k] = an * c2[k] * 0.5 + b * d;
    }
    let mut rest = [0.0; N];
    let mut z = [DVec2::X; N];
    for k in 0..N {
        if len[k] == 0.0 {
            continue;
        }
        // asinh(τ/c) only ever appears multiplied by c² or d, both zero
        // when c is.
        let ash = if c2[k] > 0.0 { ratio[k].ln() } else { 0.0 };
        rest[k] = part[k] + coef[k] * ash;
        z[k] = DVec2::new(zx[k], zy[k]);
    }
    (rest, z)
}

/// Rectangles whose edge sums [`rect_edge_sums`] takes side by side.
pub const RECTS: usize = 8;

avx2_dispatch!(
    /// [`segment_parts`] of the four edges of each rectangle, each with its
    /// own (a, b, h), compiled for AVX2 (the same operations lane by lane,
    /// so the same bits).
    fn rect_edges_at_once(p: &[DVec2; 4 * RECTS], q: &[DVec2; 4 * RECTS], params: &[(DVec2, f64, f64); RECTS])
        -> ([f64; 4 * RECTS], [DVec2; 4 * RECTS]) => rect_edge_lanes
);

#[inline(always)]
fn rect_edge_lanes(
    p: &[DVec2; 4 * RECTS],
    q: &[DVec2; 4 * RECTS],
    params: &[(DVec2, f64, f64); RECTS],
) -> ([f64; 4 * RECTS], [DVec2; 4 * RECTS]) {
    segment_lanes_of(p, q, |k| params[k / 4])
}

/// [`edge_sum`] of `count` ≤ [`RECTS`] counter-clockwise convex
/// quadrilaterals `rect(i)` = (corners, a, b, h) at once: the same bits as
/// [`edge_sum`] of each.
pub fn rect_edge_sums<'a>(
    count: usize,
    rect: impl Fn(usize) -> (&'a [DVec2; 4], DVec2, f64, f64),
    out: &mut [f64; RECTS],
) {
    debug_assert!(count <= RECTS);
    let (mut p, mut q) = ([DVec2::ZERO; 4 * RECTS], [DVec2::X; 4 * RECTS]);
    let mut params = [(DVec2::ZERO, 0.0, 1.0); RECTS];
    for i in 0..count {
        let (corners, a, b, h) = rect(i);
        for e in 0..4 {
            (p[4 * i + e], q[4 * i + e]) = (corners[e], corners[(e + 1) % 4]);
        }
        params[i] = (a, b, h);
    }
    let (rest, z) = rect_edges_at_once(&p, &q, &params);
    for i in 0..count {
        let (_, b, h) = params[i];
        // As `edge_sum` adds them.
        let mut angle = AngleSum::default();
        let mut sum = 0.0;
        for e in 4 * i..4 * i + 4 {
            sum += rest[e];
            angle.add(z[e]);
        }
        out[i] = sum + b * h.abs() * angle.total();
    }
}

/// The terms of the edges `edge(i)` for i < `count`, `LANES` at a time,
/// handed in order to `each` (with the edge's index).
fn for_each_segment(
    count: usize,
    edge: impl Fn(usize) -> (DVec2, DVec2),
    a: DVec2,
    b: f64,
    h: f64,
    mut each: impl FnMut(usize, f64, DVec2),
) {
    for start in (0..count).step_by(LANES) {
        let n = (count - start).min(LANES);
        let (mut p, mut q) = ([DVec2::ZERO; LANES], [DVec2::ZERO; LANES]);
        for k in 0..n {
            (p[k], q[k]) = edge(start + k);
        }
        let (rest, z) = edges_at_once(&p, &q, a, b, h);
        for k in 0..n {
            each(start + k, rest[k], z[k]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{AngleSum, RECTS, edge_sum, rect_edge_sums, segment_term};
    use crate::render::rng::Rng;
    use glam::DVec2;

    /// `analytic.rs`'s form of one edge: G at each end, asinh and atan2 of
    /// each.
    use crate::render::analytic::edge_term as two_ended;

    /// The one-logarithm, one-arctangent edge against the two-ended form
    /// on random edges (either side of the foot of the perpendicular,
    /// lines through the origin, points in the light's plane, short
    /// edges): the same value to rounding of the terms' size.
    #[test]
    fn segment_term_matches_the_two_ended_form() {
        let mut rng = Rng::new(3);
        let mut next = || rng.next_f64() * 2.0 - 1.0;
        for case in 0..4000 {
            let p = DVec2::new(next(), next()) * 3.0;
            let mut q = match case % 4 {
                0 => p * (1.0 + next()),
                1 => p + DVec2::new(next(), next()) * 1e-4,
                _ => DVec2::new(next(), next()) * 3.0,
            };
            if q == p {
                q.x += 1.0;
            }
            let a = DVec2::new(next(), next());
            let b = next() * 2.0;
            let h = if case % 7 == 0 { 0.0 } else { next() * 4.0 };
            let (got, want) = (segment_term(p, q, a, b, h), two_ended(p, q, a, b, h));
            // The size of each end's term: the two-ended form loses its
            // digits to that on short edges.
            let r = p.length().max(q.length()) + h.abs();
            let scale = (a.length() * r * r + b.abs() * r).max(want.abs());
            assert!(
                (got - want).abs() <= 1e-14 * scale,
                "case {case}: {got} vs {want}"
            );
        }
    }

    /// Quadrilaterals side by side, each with its own integrand: the bits
    /// of each one's own edge sum (random convex quadrilaterals, lights
    /// beside and above the point, a degenerate edge, any count).
    #[test]
    fn rect_edge_sums_give_the_bits_of_each_edge_sum() {
        let mut rng = Rng::new(42);
        let mut next = || rng.next_f64() * 2.0 - 1.0;
        for round in 0..3000 {
            let count = 1 + round % RECTS;
            let quads: Vec<([DVec2; 4], DVec2, f64, f64)> = (0..count)
                .map(|k| {
                    let o = DVec2::new(next(), next()) * 4.0;
                    let (u, v) = (
                        DVec2::new(1.0 + next(), 0.3 * next()),
                        DVec2::new(0.3 * next(), 1.0 + next()),
                    );
                    let mut corners = [o, o + u, o + u + v, o + v];
                    if (round + k) % 11 == 0 {
                        corners[2] = corners[1];
                    }
                    let h = if (round + k) % 13 == 0 {
                        0.0
                    } else {
                        -4.0 * next().abs() - 0.01
                    };
                    (corners, DVec2::new(next(), next()), next() * 3.0, h)
                })
                .collect();
            let mut out = [0.0; RECTS];
            rect_edge_sums(
                count,
                |i| (&quads[i].0, quads[i].1, quads[i].2, quads[i].3),
                &mut out,
            );
            for (i, (corners, a, b, h)) in quads.iter().enumerate() {
                let want = edge_sum(corners, *a, *b, *h);
                assert_eq!(out[i].to_bits(), want.to_bits(), "round {round} quad {i}");
            }
        }
    }

    /// One arctangent of the product with the turns counted against the
    /// sum of one arctangent each: random numbers, runs that wind several
    /// times either way, and numbers on the negative real axis (±0 above
    /// and below, where `atan2` gives ±π).
    #[test]
    fn angle_sum_matches_the_sum_of_arctangents() {
        let mut rng = Rng::new(4);
        let mut next = || rng.next_f64() * 2.0 - 1.0;
        for case in 0..4000 {
            let count = 1 + case % 40;
            let (mut sum, mut want) = (AngleSum::default(), 0.0);
            for i in 0..count {
                let z = match (case + i) % 5 {
                    0 => DVec2::new(-1.0 - next().abs(), 0.0),
                    1 => DVec2::new(-1.0 - next().abs(), -0.0),
                    // Winding one way: angles near +3 (or −3).
                    2 => DVec2::from_angle(3.0 * (case % 2) as f64 * 2.0 - 3.0 + 0.1 * next()),
                    _ => DVec2::new(next(), next()) * 10f64.powf(3.0 * next()),
                };
                sum.add(z);
                want += z.y.atan2(z.x);
            }
            let got = sum.total();
            assert!(
                (got - want).abs() <= 1e-12 * count as f64,
                "case {case}: {got} vs {want}"
            );
        }
    }
}
