//! Convex polygons in a plane: clipping by a half-plane, subtraction of one
//! convex polygon from another (as convex pieces), the convex hull, area.
//! All in f64, counter-clockwise, allocation-free once the buffers are warm.

use glam::DVec2;

/// A half-plane `n · x + c ≥ 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfPlane {
    pub n: DVec2,
    pub c: f64,
}

impl HalfPlane {
    #[inline]
    pub fn eval(&self, x: DVec2) -> f64 {
        self.n.dot(x) + self.c
    }

    /// The inner side of the directed edge `p → q` of a counter-clockwise
    /// polygon (its left).
    #[inline]
    pub fn left_of(p: DVec2, q: DVec2) -> HalfPlane {
        let n = (q - p).perp();
        HalfPlane { n, c: -n.dot(p) }
    }

    /// The other side.
    #[inline]
    pub fn flipped(self) -> HalfPlane {
        HalfPlane {
            n: -self.n,
            c: -self.c,
        }
    }
}

/// Appends to `out` the part of the convex polygon `poly` where `h ≥ 0`
/// (Sutherland–Hodgman); returns how many vertices it appended (0 or ≥ 3).
pub fn clip_into(poly: &[DVec2], h: HalfPlane, out: &mut Vec<DVec2>) -> usize {
    let start = out.len();
    let Some(&first) = poly.first() else {
        return 0;
    };
    // Each edge a → b, b the next vertex (the last edge closes on the
    // first): no index modulo per edge.
    let mut a = first;
    let mut da = h.eval(a);
    for &b in poly[1..].iter().chain(std::iter::once(&first)) {
        let db = h.eval(b);
        if da >= 0.0 {
            out.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            // Opposite signs: da − db ≠ 0.
            out.push(a + (b - a) * (da / (da - db)));
        }
        (a, da) = (b, db);
    }
    let n = out.len() - start;
    if n < 3 {
        out.truncate(start);
        return 0;
    }
    n
}

/// The edges of a closed polygon, each (a, b) with b the next vertex (the
/// last edge closes on the first), without an index modulo per edge.
#[inline]
pub fn edges_of(poly: &[DVec2]) -> impl Iterator<Item = (DVec2, DVec2)> + '_ {
    let next = poly.get(1..).unwrap_or_default().iter().chain(poly.first());
    poly.iter().zip(next).map(|(&a, &b)| (a, b))
}

/// Twice the signed area (positive counter-clockwise).
#[inline]
pub fn twice_area(poly: &[DVec2]) -> f64 {
    let k = poly.len();
    let o = poly[0];
    let mut s = 0.0;
    for i in 1..k.saturating_sub(1) {
        s += (poly[i] - o).perp_dot(poly[i + 1] - o);
    }
    s
}

/// Whether every vertex of `poly` satisfies `h ≥ 0` / `h ≤ 0`.
#[inline]
fn sides(poly: &[DVec2], h: HalfPlane) -> (bool, bool) {
    let (mut all_in, mut all_out) = (true, true);
    for &p in poly {
        let d = h.eval(p);
        all_in &= d >= 0.0;
        all_out &= d <= 0.0;
    }
    (all_in, all_out)
}

/// Convex pieces, stored back to back in one buffer.
#[derive(Debug, Default)]
pub struct Pieces {
    pub verts: Vec<DVec2>,
    /// Piece i is `verts[ends[i-1]..ends[i]]`.
    pub ends: Vec<usize>,
}

// By hand: the derived `clone_from` would allocate anew on every hit point
// instead of reusing the warm buffers.
impl Clone for Pieces {
    fn clone(&self) -> Self {
        Pieces {
            verts: self.verts.clone(),
            ends: self.ends.clone(),
        }
    }

    fn clone_from(&mut self, source: &Self) {
        self.verts.clone_from(&source.verts);
        self.ends.clone_from(&source.ends);
    }
}

impl Pieces {
    pub fn clear(&mut self) {
        self.verts.clear();
        self.ends.clear();
    }

    pub fn len(&self) -> usize {
        self.ends.len()
    }

    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }

    pub fn piece(&self, i: usize) -> &[DVec2] {
        let start = if i == 0 { 0 } else { self.ends[i - 1] };
        &self.verts[start..self.ends[i]]
    }

    pub fn iter(&self) -> impl Iterator<Item = &[DVec2]> {
        (0..self.len()).map(|i| self.piece(i))
    }

    /// The pieces' total area.
    pub fn area(&self) -> f64 {
        self.iter().map(twice_area).sum::<f64>() * 0.5
    }

    /// Adds a piece, unless it is too thin to matter (`min_area`: twice
    /// the area below which a sliver of rounding is dropped).
    pub fn push(&mut self, poly: &[DVec2], min_area: f64) {
        if poly.len() >= 3 && twice_area(poly) > min_area {
            self.verts.extend_from_slice(poly);
            self.ends.push(self.verts.len());
        }
    }

    /// Closes the piece just appended to `verts` (after `start`), or drops
    /// it if it is a sliver.
    fn close_from(&mut self, start: usize, min_area: f64) {
        if self.verts.len() - start >= 3 && twice_area(&self.verts[start..]) > min_area {
            self.ends.push(self.verts.len());
        } else {
            self.verts.truncate(start);
        }
    }

    /// Replaces every piece by its part where `h ≥ 0`. Pieces wholly
    /// there are kept as they are (what clipping them would give, and every
    /// piece held passed `min_area` when it was added).
    pub fn clip(&mut self, h: HalfPlane, min_area: f64, work: &mut Work) {
        if self.verts.iter().all(|&p| h.eval(p) >= 0.0) {
            return;
        }
        let tmp = &mut work.tmp;
        tmp.clear();
        for p in self.iter() {
            let start = tmp.verts.len();
            clip_into(p, h, &mut tmp.verts);
            tmp.close_from(start, min_area);
        }
        std::mem::swap(self, tmp);
    }

    /// Replaces every piece by its parts outside the convex
    /// counter-clockwise polygon `s`: for each edge of `s`, the part of
    /// what is left beyond that edge is a convex piece, and what is inside
    /// every edge (the piece ∩ s) is dropped. A piece cut by k edges of `s`
    /// gives at most k pieces.
    pub fn subtract(&mut self, s: &[DVec2], min_area: f64, work: &mut Work) {
        let Work { tmp, rest, next } = work;
        tmp.clear();
        let (lo, hi) = bounds(s);
        'pieces: for p in self.iter() {
            let (plo, phi) = bounds(p);
            if phi.x <= lo.x || phi.y <= lo.y || plo.x >= hi.x || plo.y >= hi.y {
                tmp.push_unchecked(p);
                continue;
            }
            rest.clear();
            rest.extend_from_slice(p);
            for (p0, p1) in edges_of(s) {
                let inner = HalfPlane::left_of(p0, p1);
                let (all_in, all_out) = sides(rest, inner);
                if all_in {
                    continue;
                }
                if all_out {
                    // What is left lies wholly outside s.
                    let start = tmp.verts.len();
                    tmp.verts.extend_from_slice(rest);
                    tmp.close_from(start, min_area);
                    continue 'pieces;
                }
                let start = tmp.verts.len();
                clip_into(rest, inner.flipped(), &mut tmp.verts);
                tmp.close_from(start, min_area);
                next.clear();
                if clip_into(rest, inner, next) == 0 {
                    continue 'pieces;
                }
                std::mem::swap(rest, next);
            }
            // What is left is inside s: in its shadow.
        }
        std::mem::swap(self, tmp);
    }

    fn push_unchecked(&mut self, poly: &[DVec2]) {
        self.verts.extend_from_slice(poly);
        self.ends.push(self.verts.len());
    }
}

/// Scratch buffers of [`Pieces::clip`] and [`Pieces::subtract`].
#[derive(Debug, Clone, Default)]
pub struct Work {
    tmp: Pieces,
    rest: Vec<DVec2>,
    next: Vec<DVec2>,
}

/// Merges vertices closer than `1e-10` of the polygon's size or 16 ulps of
/// its coordinates (the
/// rounding of clipping makes such pairs): the edge between two of them
/// has a direction of rounding alone, and as a half-plane of a subtraction
/// it would cut along that random line. Leaves an empty polygon if fewer
/// than three vertices remain.
pub fn merge_close_vertices(poly: &mut Vec<DVec2>) {
    if poly.len() < 3 {
        poly.clear();
        return;
    }
    let (lo, hi) = bounds(poly);
    // Or 16 ulps of the coordinates, for a polygon small against its
    // distance from the origin (a tiny light far from the point).
    let magnitude = lo.abs().max(hi.abs()).max_element();
    let eps = (1e-10 * (hi - lo).max_element()).max(16.0 * f64::EPSILON * magnitude);
    let mut kept = 0;
    for i in 0..poly.len() {
        if kept == 0 || (poly[i] - poly[kept - 1]).length() > eps {
            poly[kept] = poly[i];
            kept += 1;
        }
    }
    while kept > 1 && (poly[kept - 1] - poly[0]).length() <= eps {
        kept -= 1;
    }
    poly.truncate(kept);
    if poly.len() < 3 {
        poly.clear();
    }
}

/// Axis-aligned bounds of a polygon.
#[inline]
pub fn bounds(poly: &[DVec2]) -> (DVec2, DVec2) {
    poly.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    )
}

/// The convex hull of `points` (Andrew's monotone chain), counter-clockwise
/// into `out`, collinear points dropped. `points` is sorted in place.
pub fn hull_into(points: &mut [DVec2], out: &mut Vec<DVec2>) {
    out.clear();
    if points.len() < 3 {
        return;
    }
    points.sort_unstable_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    for &p in points.iter() {
        while out.len() >= 2 && cross(out[out.len() - 2], out[out.len() - 1], p) <= 0.0 {
            out.pop();
        }
        out.push(p);
    }
    let lower = out.len() + 1;
    for &p in points.iter().rev().skip(1) {
        while out.len() >= lower && cross(out[out.len() - 2], out[out.len() - 1], p) <= 0.0 {
            out.pop();
        }
        out.push(p);
    }
    out.pop();
    if out.len() < 3 {
        out.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(lo: f64, hi: f64) -> Vec<DVec2> {
        vec![
            DVec2::new(lo, lo),
            DVec2::new(hi, lo),
            DVec2::new(hi, hi),
            DVec2::new(lo, hi),
        ]
    }

    fn total_area(p: &Pieces) -> f64 {
        p.iter().map(|q| twice_area(q) * 0.5).sum()
    }

    #[test]
    fn subtracting_a_square_leaves_the_frame() {
        let mut p = Pieces::default();
        p.push(&square(0.0, 4.0), 0.0);
        let mut w = Work::default();
        p.subtract(&square(1.0, 2.0), 0.0, &mut w);
        assert_eq!(p.len(), 4);
        assert!((total_area(&p) - 15.0).abs() < 1e-12);
        for q in p.iter() {
            assert!(twice_area(q) > 0.0);
        }
        // The same square again removes nothing more; a covering one all.
        p.subtract(&square(1.0, 2.0), 0.0, &mut w);
        assert!((total_area(&p) - 15.0).abs() < 1e-12);
        p.subtract(&square(-1.0, 5.0), 0.0, &mut w);
        assert!(p.is_empty());
    }

    #[test]
    fn overlapping_subtractions_remove_the_union() {
        let mut p = Pieces::default();
        p.push(&square(0.0, 4.0), 0.0);
        let mut w = Work::default();
        p.subtract(&square(1.0, 3.0), 0.0, &mut w);
        let tri = [
            DVec2::new(2.0, 2.0),
            DVec2::new(6.0, 2.0),
            DVec2::new(2.0, 6.0),
        ];
        p.subtract(&tri, 0.0, &mut w);
        // The triangle (x, y ≥ 2, x + y ≤ 8) covers [2,4]² of the square
        // (area 4), of which [2,3]² (area 1) was already gone: 16 − 4 − 3.
        assert!((total_area(&p) - 9.0).abs() < 1e-12, "{}", total_area(&p));
        for q in p.iter() {
            assert!(twice_area(q) > 0.0);
        }
    }

    #[test]
    fn vertices_a_rounding_apart_do_not_cut_along_a_random_line() {
        // A triangle whose second vertex is doubled within rounding, in the
        // direction that would cut the square in two (the case of a shadow
        // clipped at the light's edge).
        let mut s = vec![
            DVec2::new(0.0, 4.0),
            DVec2::new(2.0, 1.0),
            DVec2::new(2.0 + 2e-17, 1.0 - 2e-16),
            DVec2::new(2.0, 4.0),
        ];
        merge_close_vertices(&mut s);
        assert_eq!(s.len(), 3);
        let mut p = Pieces::default();
        p.push(&square(-2.0, 4.0), 0.0);
        let mut w = Work::default();
        p.subtract(&s, 1e-12, &mut w);
        assert!(
            (total_area(&p) - (36.0 - 3.0)).abs() < 1e-9,
            "{}",
            total_area(&p)
        );
    }

    #[test]
    fn hull_of_a_box_projection() {
        let mut pts = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(0.0, 1.0),
            DVec2::new(0.5, 0.5),
            DVec2::new(0.5, 0.0),
        ];
        let mut out = Vec::new();
        hull_into(&mut pts, &mut out);
        assert_eq!(out.len(), 4);
        assert!((twice_area(&out) - 2.0).abs() < 1e-15);
    }
}
