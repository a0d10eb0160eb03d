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

use super::polygon::Pieces;
use crate::render::analytic::diffuse_polygon_integral;

/// Light radius below this fraction of its distance: the per-piece path
/// (as `analytic.rs`'s own switch).
const SMALL_LIGHT: f64 = 0.05;

/// One directed edge, with its endpoints in a canonical order.
#[derive(Debug, Clone, Copy)]
pub struct Edge {
    lo: DVec2,
    hi: DVec2,
    /// +1 if the piece runs lo → hi, −1 if hi → lo.
    sign: f64,
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
    edges: &mut Vec<Edge>,
) -> f64 {
    let centre = (rect[0] + rect[1] + rect[2] + rect[3]) * 0.25;
    let radius = rect
        .iter()
        .map(|&p| (p - centre).length())
        .fold(0.0, f64::max);
    if pieces.len() < 2 || radius < SMALL_LIGHT * (centre.length_squared() + h * h).sqrt() {
        return pieces
            .iter()
            .map(|poly| diffuse_polygon_integral(poly, a, b, h))
            .sum();
    }
    edges.clear();
    for poly in pieces.iter() {
        let n = poly.len();
        for i in 0..n {
            let (p, q) = (poly[i], poly[(i + 1) % n]);
            match key(p).cmp(&key(q)) {
                std::cmp::Ordering::Less => edges.push(Edge {
                    lo: p,
                    hi: q,
                    sign: 1.0,
                }),
                std::cmp::Ordering::Greater => edges.push(Edge {
                    lo: q,
                    hi: p,
                    sign: -1.0,
                }),
                std::cmp::Ordering::Equal => {}
            }
        }
    }
    edges.sort_unstable_by_key(|e| (key(e.lo), key(e.hi)));
    let mut total = 0.0;
    let mut i = 0;
    while i < edges.len() {
        let e = edges[i];
        let mut net = e.sign;
        let mut j = i + 1;
        while j < edges.len() && key(edges[j].lo) == key(e.lo) && key(edges[j].hi) == key(e.hi) {
            net += edges[j].sign;
            j += 1;
        }
        if net != 0.0 {
            total += net * segment_term(e.lo, e.hi, a, b, h);
        }
        i = j;
    }
    total
}

/// The flux of F(x) = a g(x) + b x/(g(x) + |h|) out through the straight
/// boundary segment p → q of a counter-clockwise region: one edge of
/// `analytic.rs`'s edge sum.
pub fn segment_term(p: DVec2, q: DVec2, a: DVec2, b: f64, h: f64) -> f64 {
    let ah = h.abs();
    let e = q - p;
    let len = e.length();
    if len == 0.0 {
        return 0.0;
    }
    let t = e / len;
    let nu = DVec2::new(t.y, -t.x);
    let d = p.dot(nu);
    let c2 = d * d + ah * ah;
    let c = c2.sqrt();
    let an = a.dot(nu);
    let g = |tau: f64| {
        let r = (tau * tau + c2).sqrt();
        // asinh(τ/c) only ever appears multiplied by c² or d, both zero
        // when c is.
        let ash = if c > 0.0 { (tau / c).asinh() } else { 0.0 };
        let phi = (-tau * d * (tau * tau + d * d) / (r + ah)).atan2(d * d * r + ah * tau * tau);
        an * (tau * r + c2 * ash) * 0.5 + b * (d * ash + ah * phi)
    };
    g(q.dot(t)) - g(p.dot(t))
}
