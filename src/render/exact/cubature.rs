//! The specular factor over the visible part of the light: Blinn's
//! max(0, N·H)^s has no closed form over a polygon, so it is integrated by
//! a deterministic adaptive cubature.
//!
//! The light is the unit square of its (a, b) coordinates. A cell of a
//! quadtree over it is fitted by the tensor Legendre polynomial of degree
//! `ORDER − 1` that interpolates the integrand at `ORDER`² Gauss–Legendre
//! nodes; the size of its highest order of coefficients estimates the
//! fit's error. A cell whose estimate is above [`TOLERANCE`] is split in
//! four (down to `MAX_DEPTH` levels), and so is one too coarse for a narrow
//! lobe that lies on it. The polynomial of an accepted cell is integrated
//! exactly over the visible pieces inside the cell by Green's theorem:
//! ∫∫ P_k(x) P_l(y) = ∮ R_k(x) P_l(y) dy with R_k the antiderivative, a
//! polynomial along each straight edge that an `ORDER`-point rule
//! integrates exactly. Over a part of a cell the fit is first cut to the
//! lowest degree D whose dropped coefficients, with the tail, stay within
//! [`TOLERANCE`] (|P_k P_l| ≤ 1 bounds what each dropped one moves), so a
//! (D + 1)-point edge rule is exact. So the work follows the integrand's
//! shape, not the number of shadow pieces. A part of a cell where the
//! nested rules below would be trusted (not near the point, the lobe
//! resolved) first tries the degree-3 fit at 4² nodes, its top
//! coefficients times 4 its estimate (its test finds its errors, above
//! the f32 lobe's rounding, at most 7.4 % of that): most such cells need
//! no more. A cell wholly visible needs no fit at all, only its integral:
//! unless it is near the point against its size, it first tries the
//! nested 2², 3², 4² and 5² Gauss–Legendre product rules (16 lobe
//! values, then 16 and 32 more), whose differences (the first one times
//! 4) are its estimate, and takes the first value within the tolerance;
//! else it is fitted as above. A lobe whose upper
//! bound over the whole light, times the visible share of the light, is
//! below `SKIP` is taken as 0 without a cell.
//!
//! Error: each accepted cell's estimate (the tail, plus the dropped
//! coefficients, or the nested rules' difference) is ≤ [`TOLERANCE`] of
//! its area, and the cells cover the light once,
//! so the factor's error is estimated ≤ [`TOLERANCE`] (absolute; the
//! factor lies in [0, 1]).

use std::sync::OnceLock;

use glam::{DVec2, DVec3, Vec3};

use super::diffuse::{Outline, outline};
use super::polygon::{HalfPlane, Pieces, clip_into, edges_of};
use crate::render::math::avx512_dispatch;

/// Nodes per axis of a cell (the fit has degree `ORDER − 1`).
const ORDER: usize = 8;
/// Deepest split of the light's square (cells of 1/256 of its side).
const MAX_DEPTH: u32 = 8;
/// Estimated error of the specular factor above which a cell is split.
pub const TOLERANCE: f64 = 1e-4;

/// The integrand: max(0, n·H)^s at light point (a, b), in the light's frame
/// seen from the shadow point.
#[derive(Debug, Clone, Copy, Default)]
pub struct Lobe {
    /// Unit shading normal and view direction.
    pub n: DVec3,
    pub v: DVec3,
    pub shininess: f64,
    /// The light's corner (from the shadow point) and edges.
    pub corner: DVec3,
    pub edge_u: DVec3,
    pub edge_v: DVec3,
}

impl Lobe {
    #[inline]
    fn direction(&self, a: f64, b: f64) -> DVec3 {
        self.corner + self.edge_u * a + self.edge_v * b
    }
}

/// Nodes of a cell.
const NODES: usize = ORDER * ORDER;

avx512_dispatch!(
    /// The integrand at a fitted cell's tensor nodes (xs\[i\], ys\[j\])
    /// into `out[i * ORDER + j]`, the nodes spread inside the kernel (no
    /// 64-node coordinate arrays built and zeroed outside it). Sixteen
    /// lanes where the CPU has them (the same operations lane by lane, so
    /// the same bits).
    fn lobe_at_tensor_nodes(l: &Lobe, xs: &[f64; ORDER], ys: &[f64; ORDER], out: &mut [f64; NODES])
        => lobe_at_tensor_nodes_generic if true
);

#[inline(always)]
fn lobe_at_tensor_nodes_generic(
    l: &Lobe,
    xs: &[f64; ORDER],
    ys: &[f64; ORDER],
    out: &mut [f64; NODES],
) {
    let a: [f32; NODES] = std::array::from_fn(|k| xs[k / ORDER] as f32);
    let b: [f32; NODES] = std::array::from_fn(|k| ys[k % ORDER] as f32);
    lobe_f32(l, &a, &b, out);
}

avx512_dispatch!(
    /// The integrand at `CHUNK` nodes of the nested rules of the cell
    /// [lo, lo + size]², at (lo.x + x\[j\] size, lo.y + y\[j\] size): the
    /// coordinates in the kernel's lanes too. Sixteen lanes where the CPU
    /// has them, as [`lobe_at_tensor_nodes`].
    fn lobe_at_nested_nodes(l: &Lobe, lo: DVec2, size: f64, x: &[f64; CHUNK], y: &[f64; CHUNK], out: &mut [f64; CHUNK])
        => lobe_at_nested_nodes_generic if true
);

#[inline(always)]
fn lobe_at_nested_nodes_generic(
    l: &Lobe,
    lo: DVec2,
    size: f64,
    x: &[f64; CHUNK],
    y: &[f64; CHUNK],
    out: &mut [f64; CHUNK],
) {
    let a: [f32; CHUNK] = std::array::from_fn(|j| (lo.x + x[j] * size) as f32);
    let b: [f32; CHUNK] = std::array::from_fn(|j| (lo.y + y[j] * size) as f32);
    lobe_f32(l, &a, &b, out);
}

/// The integrand at the light points (a\[j\], b\[j\]), in f32 lanes
/// (twice as many per instruction as f64), written for the vectorizer
/// like the `sampled` model's loops. The rounding that matters is kept
/// small: cos²θ_H is taken as 1 − sin²θ_H with sin²θ_H = |N × H|²/|H|²,
/// accurate relative to itself where the lobe peaks (1 − cos² in f32
/// would lose its digits there), and raised to s/2 by
/// [`log2_one_minus_times`] and [`exp2_unless_zero`]. What remains is
/// the f32 direction's rounding, amplified by the shininess: values within
/// 5e-6 of the f64 lobe up to shininess 2000 (tested), below the
/// cubature's tolerance.
#[inline(always)]
fn lobe_f32<const M: usize>(l: &Lobe, af: &[f32; M], bf: &[f32; M], out: &mut [f64; M]) {
    let l = LobeF32::new(l);
    // Three loops, each a third of a node's chain of dependent operations
    // (as `shading::point_terms`): in one loop the CPU overlapped too few
    // vectors to hide the chain's latency. The same operations lane by
    // lane, so the same values.
    let mut sin2 = [0f32; M];
    let mut lit = [false; M];
    for j in 0..M {
        (sin2[j], lit[j]) = l.sin2_at(af[j], bf[j]);
    }
    let mut exponent = [0f32; M];
    for j in 0..M {
        exponent[j] = log2_one_minus_times(sin2[j], l.half_s);
    }
    for j in 0..M {
        out[j] = lobe_value(exponent[j], sin2[j], lit[j]);
    }
}

/// A [`Lobe`] in f32, as [`lobe_f32`] takes it.
#[derive(Debug, Clone, Copy, Default)]
struct LobeF32 {
    c: Vec3,
    u: Vec3,
    w: Vec3,
    n: Vec3,
    v: Vec3,
    half_s: f32,
}

impl LobeF32 {
    #[inline(always)]
    fn new(l: &Lobe) -> LobeF32 {
        LobeF32 {
            c: l.corner.as_vec3(),
            u: l.edge_u.as_vec3(),
            w: l.edge_v.as_vec3(),
            n: l.n.as_vec3(),
            v: l.v.as_vec3(),
            half_s: (0.5 * l.shininess) as f32,
        }
    }

    /// sin²θ_H at light point (a, b), and whether the lobe is lit there.
    #[inline(always)]
    fn sin2_at(&self, a: f32, b: f32) -> (f32, bool) {
        let LobeF32 { c, u, w, n, v, .. } = *self;
        let x = c.x + u.x * a + w.x * b;
        let y = c.y + u.y * a + w.y * b;
        let z = c.z + u.z * a + w.z * b;
        let inv = 1.0 / (x * x + y * y + z * z).sqrt();
        let (hx, hy, hz) = (x * inv + v.x, y * inv + v.y, z * inv + v.z);
        let h2 = hx * hx + hy * hy + hz * hz;
        let nh = n.x * hx + n.y * hy + n.z * hz;
        let (cx, cy, cz) = (
            n.y * hz - n.z * hy,
            n.z * hx - n.x * hz,
            n.x * hy - n.y * hx,
        );
        // N·H ≤ 0 and H = 0 (light exactly behind the viewer) give 0.
        (
            ((cx * cx + cy * cy + cz * cz) / h2).min(1.0),
            nh > 0.0 && h2 > 0.0,
        )
    }
}

/// The lobe's value from [`log2_one_minus_times`]'s exponent.
#[inline(always)]
fn lobe_value(exponent: f32, sin2: f32, lit: bool) -> f64 {
    let value = exp2_unless_zero(exponent, sin2);
    (if lit { value } else { 0.0 }) as f64
}

/// (1 − e)^y for e in [0, 1] and y > 0 in f32 without a libm call:
/// exp2(y · log2(1 − e)), the logarithm from e itself where e is small
/// (ln(1 − e) = −2 atanh(e/(2 − e))) and from the mantissa of 1 − e
/// elsewhere; relative error ~1e-7 · max(1, |y · log2(1 − e)|); results
/// below 2⁻¹²⁶ give 0. In two halves, [`log2_one_minus_times`] and
/// [`exp2_unless_zero`], so that a loop can run each over many nodes.
#[cfg(test)]
fn pow_one_minus(e: f32, y: f32) -> f32 {
    exp2_unless_zero(log2_one_minus_times(e, y), e)
}

/// The first half of [`pow_one_minus`]: y · log2(1 − e), at least −126.
#[inline(always)]
fn log2_one_minus_times(e: f32, y: f32) -> f32 {
    // Small e: t = e/(2 − e) ≤ 1/7.
    // Elsewhere: 1 − e = m 2^k with m in [√½, √2), t = (m − 1)/(m + 1).
    let x = 1.0 - e;
    let bits = x.to_bits() as i32;
    let mut k = ((bits >> 23) & 0xff) - 127;
    let mut m = f32::from_bits(((bits & 0x007f_ffff) | 0x3f80_0000) as u32);
    let big = m > std::f32::consts::SQRT_2;
    m = if big { m * 0.5 } else { m };
    k += big as i32;
    let small = e < 0.25;
    // One division of the chosen numerator and denominator (the same
    // quotient as choosing between the two quotients).
    let t = if small { e } else { m - 1.0 } / if small { 2.0 - e } else { m + 1.0 };
    let t2 = t * t;
    let mut series = 1.0 / 11.0;
    for d in [9.0, 7.0, 5.0, 3.0, 1.0] {
        series = series * t2 + 1.0 / d;
    }
    let ln_small = -2.0 * t * series;
    let ln_big = k as f32 * std::f32::consts::LN_2 + 2.0 * t * series;
    let ln = if small { ln_small } else { ln_big };
    (y * ln * std::f32::consts::LOG2_E).max(-126.0)
}

/// The second half of [`pow_one_minus`]: 2^z, or 0 where z is at its floor
/// or 1 − e is not positive.
#[inline(always)]
fn exp2_unless_zero(z: f32, e: f32) -> f32 {
    let x = 1.0 - e;
    // 2^z = 2^r · e^(f·ln 2), r = round(z) by adding and removing 1.5·2²³.
    const ROUNDER: f32 = 12_582_912.0;
    let r = z + ROUNDER;
    let ki = r.to_bits() as i32 - ROUNDER.to_bits() as i32;
    let f = (z - (r - ROUNDER)) * std::f32::consts::LN_2;
    let mut p = 1.0 / 40_320.0;
    for d in [5_040.0, 720.0, 120.0, 24.0, 6.0, 2.0, 1.0, 1.0] {
        p = p * f + 1.0 / d;
    }
    let scaled = p * f32::from_bits(((ki + 127) << 23) as u32);
    if x > 0.0 && z > -126.0 { scaled } else { 0.0 }
}

/// The nested rules of a whole cell: the 2², 3², 4² and 5² Gauss–Legendre
/// product rules. Over a cell wholly visible only the integral is wanted,
/// not the fit, and a Gauss rule integrates far better than its fit
/// interpolates: the fit's top coefficients (the partial cells' estimate)
/// overstate a whole cell's error by orders of magnitude. So a whole cell
/// takes the first rule that agrees with the one before within the
/// tolerance (the difference is the estimate: it bounds the larger rule's
/// error wherever the smaller one's error is the larger, as for every
/// smooth lobe): 16 lobe values where the lobe is wide against the cell,
/// 32 or 64 where it is narrower, and no fit.
const NESTED_ORDERS: [usize; 4] = [2, 3, 4, 5];
/// The 2²/3² difference times this is the 3² rule's estimate: two and
/// three nodes a side are too few for the difference to track the error
/// alone (an x and a y error of opposite signs can cancel in the 2² rule),
/// and over 10⁴ random lobes and cells the error reached 9× the bare
/// difference; times 4, no error exceeded the estimate by more than the f32
/// lobe's rounding.
const START_SAFETY: f64 = 4.0;
/// The rules' nodes back to back (4 + 9 + 16 + 25), padded to whole chunks.
const NESTED_NODES: usize = 64;
/// Nodes evaluated at once (whole f32 lanes).
const CHUNK: usize = 16;

/// The nested rules' nodes, at (x\[i\], y\[i\]) in [0, 1]² of the cell,
/// each with its weight in its own rule (the weights of a rule sum to 1);
/// rule k's nodes end at `ends[k]`.
struct NestedRule {
    x: [f64; NESTED_NODES],
    y: [f64; NESTED_NODES],
    w: [f64; NESTED_NODES],
    ends: [usize; NESTED_ORDERS.len()],
}

fn nested_rule() -> &'static NestedRule {
    static RULE: OnceLock<NestedRule> = OnceLock::new();
    RULE.get_or_init(|| {
        let mut r = NestedRule {
            x: [0.5; NESTED_NODES],
            y: [0.5; NESTED_NODES],
            w: [0.0; NESTED_NODES],
            ends: [0; NESTED_ORDERS.len()],
        };
        let mut at = 0;
        for (k, &n) in NESTED_ORDERS.iter().enumerate() {
            let g = crate::render::math::gauss_legendre(n);
            for &(ti, wi) in &g {
                for &(tj, wj) in &g {
                    r.x[at] = (ti + 1.0) * 0.5;
                    r.y[at] = (tj + 1.0) * 0.5;
                    r.w[at] = wi * wj * 0.25;
                    at += 1;
                }
            }
            r.ends[k] = at;
        }
        r
    })
}

/// The integral over the whole cell [lo, lo + size]² by the nested rules,
/// and its estimated error (both in the light's (a, b) area), or `None`
/// where no pair of rules agrees within the cell's share of the
/// tolerance. `coarse`: whether the 3² rule resolves the lobe on the cell
/// (else the first value taken is the 4² one).
fn nested_cell(lobe: &Lobe, lo: DVec2, size: f64, coarse: bool) -> Option<(f64, f64)> {
    let r = nested_rule();
    let area = size * size;
    let mut f = [0.0; NESTED_NODES];
    let mut evaluated = 0;
    let mut previous = 0.0;
    let mut start = 0;
    for (k, &end) in r.ends.iter().enumerate() {
        while evaluated < end {
            let chunk = evaluated..evaluated + CHUNK;
            let x = r.x[chunk.clone()].try_into().expect("a chunk");
            let y = r.y[chunk.clone()].try_into().expect("a chunk");
            let out = (&mut f[chunk]).try_into().expect("a chunk");
            lobe_at_nested_nodes(lobe, lo, size, x, y, out);
            evaluated += CHUNK;
        }
        let q = rule_value(r, &f, start, end);
        start = end;
        if let Some(taken) = rule_taken(k, q, previous, area, coarse) {
            return Some(taken);
        }
        previous = q;
    }
    None
}

/// The value of the nested rule whose nodes are `start..end` of `r`, from
/// the integrand `f` at the nodes.
#[inline]
fn rule_value(r: &NestedRule, f: &[f64; NESTED_NODES], start: usize, end: usize) -> f64 {
    (start..end).map(|i| r.w[i] * f[i]).sum()
}

/// Whether [`nested_cell`] takes rule `k`'s value `q` (on a cell of area
/// `area`, the rule before's value `previous`): its integral and estimated
/// error if so.
#[inline]
fn rule_taken(k: usize, q: f64, previous: f64, area: f64, coarse: bool) -> Option<(f64, f64)> {
    let safety = if k == 1 { START_SAFETY } else { 1.0 };
    let estimate = safety * (q - previous).abs() * area;
    (k > 0 && (coarse || k > 1) && estimate <= TOLERANCE * area).then_some((q * area, estimate))
}

/// Lobes whose whole-light cells [`whole_light_specular`] takes side by
/// side.
pub const WHOLE_LANES: usize = 8;

avx512_dispatch!(
    /// The integrand of each lobe at nodes `chunk · CHUNK ..` of the nested
    /// rules over the whole light (the cell [0, 1]²) into `out[k]`: the
    /// lobes' chains of dependent operations side by side, each lane's
    /// operations those of [`lobe_at_nested_nodes`] (so the same bits).
    fn lobes_at_whole_nodes(ls: &[LobeF32; WHOLE_LANES], chunk: usize, out: &mut [[f64; CHUNK]; WHOLE_LANES])
        => lobes_at_whole_nodes_generic if true
);

#[inline(always)]
fn lobes_at_whole_nodes_generic(
    ls: &[LobeF32; WHOLE_LANES],
    chunk: usize,
    out: &mut [[f64; CHUNK]; WHOLE_LANES],
) {
    let r = nested_rule();
    let nodes = chunk * CHUNK..(chunk + 1) * CHUNK;
    // As `lobe_at_nested_nodes` places them on the cell at 0 of side 1.
    let a: [f32; CHUNK] = std::array::from_fn(|j| (0.0 + r.x[nodes.start + j] * 1.0) as f32);
    let b: [f32; CHUNK] = std::array::from_fn(|j| (0.0 + r.y[nodes.start + j] * 1.0) as f32);
    lobes_f32(ls, WHOLE_LANES, &a, &b, out);
}

/// The first `count` lobes at the light points (a\[j\], b\[j\]), each lane
/// as [`lobe_f32`] does it for one lobe (the same three loops, so the
/// same bits), the lobes' chains side by side.
#[inline(always)]
fn lobes_f32<const M: usize>(
    ls: &[LobeF32; WHOLE_LANES],
    count: usize,
    a: &[f32; M],
    b: &[f32; M],
    out: &mut [[f64; M]; WHOLE_LANES],
) {
    let count = count.min(WHOLE_LANES);
    let mut sin2 = [[0f32; M]; WHOLE_LANES];
    let mut lit = [[false; M]; WHOLE_LANES];
    for k in 0..count {
        for j in 0..M {
            (sin2[k][j], lit[k][j]) = ls[k].sin2_at(a[j], b[j]);
        }
    }
    let mut exponent = [[0f32; M]; WHOLE_LANES];
    for k in 0..count {
        for j in 0..M {
            exponent[k][j] = log2_one_minus_times(sin2[k][j], ls[k].half_s);
        }
    }
    for k in 0..count {
        for j in 0..M {
            out[k][j] = lobe_value(exponent[k][j], sin2[k][j], lit[k][j]);
        }
    }
}

avx512_dispatch!(
    /// The integrand of the first `count` lobes at the tensor nodes of the
    /// whole light's fit (as `cell` places them on the cell at 0 of side
    /// 1) into `out[k]`: the lobes side by side, each lane's operations
    /// those of [`lobe_at_tensor_nodes`] (so the same bits). One lobe's 64
    /// nodes are too few vectors to hide the chain's latency; several
    /// lobes' are not.
    fn lobes_at_whole_tensor_nodes(ls: &[LobeF32; WHOLE_LANES], count: usize, out: &mut [[f64; NODES]; WHOLE_LANES])
        => lobes_at_whole_tensor_nodes_generic if true
);

#[inline(always)]
fn lobes_at_whole_tensor_nodes_generic(
    ls: &[LobeF32; WHOLE_LANES],
    count: usize,
    out: &mut [[f64; NODES]; WHOLE_LANES],
) {
    let fit = rule();
    let half = 0.5 * 1.0;
    // As `cell` spreads the nodes on the cell at 0 of side 1, and
    // `lobe_at_tensor_nodes` takes them.
    let xs: [f64; ORDER] = std::array::from_fn(|i| 0.0 + (fit.x[i] + 1.0) * half);
    let a: [f32; NODES] = std::array::from_fn(|k| xs[k / ORDER] as f32);
    let b: [f32; NODES] = std::array::from_fn(|k| xs[k % ORDER] as f32);
    lobes_f32(ls, count, &a, &b, out);
}

/// How [`whole_light_specular`] takes a lobe's root cell: as
/// [`specular_factor`] would, or not at all.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Root {
    /// Left to [`specular_factor`].
    Alone,
    /// The nested rules (`coarse`: as [`whole_cell`] takes it).
    Nested { coarse: bool },
    /// The fit at the tensor nodes (a cell in the near field).
    Fit,
}

/// [`specular_factor`] of up to [`WHOLE_LANES`] lobes of light `span`
/// over the whole light (`visible`: its area as [`Pieces::area`] gives it
/// for the light's square) side by side, where the root cell takes the
/// nested rules' 3² or 4² value or its fit is accepted: the same value
/// and report as [`specular_factor`] gives (the same gates and
/// operations), or where it skips the lobe; `None` where it would do
/// anything else (split the cell, or take the 5² rule), left to
/// [`specular_factor`].
pub fn whole_light_specular(
    span: &LightSpan,
    lobes: &[(&Lobe, f64)],
    out: &mut [Option<(f64, CubatureReport)>; WHOLE_LANES],
) {
    debug_assert!(lobes.len() <= WHOLE_LANES);
    let r = nested_rule();
    let empty = Pieces::default();
    let mut root = [Root::Alone; WHOLE_LANES];
    // `specular_factor`'s, `cell`'s and `whole_cell`'s gates of the root
    // cell.
    for (k, &(lobe, visible)) in lobes.iter().enumerate() {
        out[k] = None;
        if let Some(report) = skipped(lobe, visible.min(1.0)) {
            out[k] = Some((0.0, report));
            continue;
        }
        // `cell`'s tests of a cell of side 1 (covered, then full).
        let full = visible >= 1.0 * 1.0 * (1.0 - 1e-12);
        if !full {
            continue;
        }
        let ctx = Ctx::new(lobe, span, &empty);
        let view = CellView::new(&ctx, DVec2::ZERO, 1.0);
        root[k] = match view.nested_rules(&ctx, DVec2::ZERO, 1.0) {
            Some(coarse) => Root::Nested { coarse },
            None if view.lobe_unresolved(ORDER) => Root::Alone,
            None => Root::Fit,
        };
    }
    // The fitted cells, their nodes side by side, each fit as `cell` fits
    // a whole cell of side 1.
    let mut fitted = [0; WHOLE_LANES];
    let mut ls = [LobeF32::default(); WHOLE_LANES];
    let mut count = 0;
    for (k, &(lobe, _)) in lobes.iter().enumerate() {
        if root[k] == Root::Fit {
            (fitted[count], ls[count]) = (k, LobeF32::new(lobe));
            count += 1;
        }
    }
    if count > 0 {
        let half = 0.5 * 1.0;
        let fit = rule();
        let mut nf = [[0.0; NODES]; WHOLE_LANES];
        lobes_at_whole_tensor_nodes(&ls, count, &mut nf);
        for (&k, nf) in fitted[..count].iter().zip(&nf) {
            let (tail, sum) = whole_cell_fit(fit, nf);
            if tail <= TOLERANCE {
                let visible = lobes[k].1;
                out[k] = Some((4.0 * sum * (half * half), whole_report(tail * visible)));
            }
        }
    }
    let mut ls = [LobeF32::default(); WHOLE_LANES];
    let mut nested = false;
    for (k, &(lobe, _)) in lobes.iter().enumerate() {
        if let Root::Nested { .. } = root[k] {
            ls[k] = LobeF32::new(lobe);
            nested = true;
        }
    }
    if !nested {
        return;
    }
    // The 2², 3² and 4² rules (nodes 0..29: two chunks), as `nested_cell`
    // sums and compares them on a cell of area 1.
    let mut f = [[0.0; NESTED_NODES]; WHOLE_LANES];
    let mut chunk = [[0.0; CHUNK]; WHOLE_LANES];
    lobes_at_whole_nodes(&ls, 0, &mut chunk);
    for k in 0..WHOLE_LANES {
        f[k][..CHUNK].copy_from_slice(&chunk[k]);
    }
    let area = 1.0 * 1.0;
    let [end_2, end_3, end_4, _] = r.ends;
    let taken = |(value, estimate)| (value, whole_report(estimate));
    let mut previous = [0.0; WHOLE_LANES];
    let mut more = false;
    for k in 0..lobes.len() {
        let Root::Nested { coarse } = root[k] else {
            continue;
        };
        let (q0, q1) = (
            rule_value(r, &f[k], 0, end_2),
            rule_value(r, &f[k], end_2, end_3),
        );
        out[k] = rule_taken(1, q1, q0, area, coarse).map(taken);
        if out[k].is_none() {
            previous[k] = q1;
            more = true;
        }
    }
    if !more {
        return;
    }
    debug_assert!(end_4 <= 2 * CHUNK);
    lobes_at_whole_nodes(&ls, 1, &mut chunk);
    for k in 0..lobes.len() {
        let Root::Nested { coarse } = root[k] else {
            continue;
        };
        if out[k].is_some() {
            continue;
        }
        f[k][CHUNK..2 * CHUNK].copy_from_slice(&chunk[k]);
        let q2 = rule_value(r, &f[k], end_3, end_4);
        out[k] = rule_taken(2, q2, previous[k], area, coarse).map(taken);
    }
}

/// [`specular_factor`]'s report of a root cell taken whole, with error
/// estimate `estimate`.
fn whole_report(estimate: f64) -> CubatureReport {
    let mut report = CubatureReport::default();
    report.cells += 1;
    report.error += estimate;
    report
}

/// Gauss–Legendre nodes and weights on [−1, 1], and the Legendre values
/// times weights at them: `pw[k][i] = P_k(x_i) w_i`, with its transpose
/// and the normalisations of the fit's coefficients.
struct Rule {
    x: [f64; ORDER],
    pw: [[f64; ORDER]; ORDER],
    /// `pwt[i][k] = pw[k][i]`.
    pwt: [[f64; ORDER]; ORDER],
    /// (2k + 1)(2l + 1)/4.
    norm: [[f64; ORDER]; ORDER],
    /// The n-point rules on [0, 1] for n = 1 … ORDER (row n − 1): the edge
    /// rules of a fit truncated to degree n − 1.
    edge_t: [[f64; ORDER]; ORDER],
    edge_w: [[f64; ORDER]; ORDER],
}

/// The n-point Gauss–Legendre nodes and weights on [−1, 1] (n ≤ ORDER).
fn gauss_legendre(n: usize) -> ([f64; ORDER], [f64; ORDER]) {
    let (mut x, mut w) = ([0.0; ORDER], [0.0; ORDER]);
    for (i, (t, wt)) in crate::render::math::gauss_legendre(n)
        .into_iter()
        .enumerate()
    {
        x[i] = t;
        w[i] = wt;
    }
    (x, w)
}

fn rule() -> &'static Rule {
    static RULE: OnceLock<Rule> = OnceLock::new();
    RULE.get_or_init(|| {
        let n = ORDER;
        let (x, w) = gauss_legendre(n);
        let (mut edge_t, mut edge_w) = ([[0.0; ORDER]; ORDER], [[0.0; ORDER]; ORDER]);
        for m in 1..=ORDER {
            let (xm, wm) = gauss_legendre(m);
            for i in 0..m {
                edge_t[m - 1][i] = (xm[i] + 1.0) * 0.5;
                edge_w[m - 1][i] = wm[i] * 0.5;
            }
        }
        let mut pw = [[0.0; ORDER]; ORDER];
        let mut pwt = [[0.0; ORDER]; ORDER];
        for i in 0..n {
            let p = legendre(x[i], ORDER - 1);
            for k in 0..n {
                pw[k][i] = p[k] * w[i];
                pwt[i][k] = p[k] * w[i];
            }
        }
        let norm = std::array::from_fn(|k| {
            std::array::from_fn(|l| (2 * k + 1) as f64 * (2 * l + 1) as f64 * 0.25)
        });
        Rule {
            x,
            pw,
            pwt,
            norm,
            edge_t,
            edge_w,
        }
    })
}

avx512_dispatch!(
    /// The first half of the fit: `t[i][l] = Σ_j f[i][j] P_l(x_j) w_j`
    /// (x along a, y along b), an 8×8 matrix product written row by row so
    /// that it vectorizes. [`coefficients`], [`tail_estimate`] and
    /// [`whole_cell_fit`] finish what each cell needs of it.
    fn fit_rows(r: &Rule, f: &[f64; NODES], t: &mut [[f64; ORDER]; ORDER]) => fit_rows_generic if true
);

// Tensor nodes and coefficients: index loops read best.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn fit_rows_generic(r: &Rule, f: &[f64; NODES], t: &mut [[f64; ORDER]; ORDER]) {
    *t = [[0.0; ORDER]; ORDER];
    for i in 0..ORDER {
        for j in 0..ORDER {
            let fij = f[i * ORDER + j];
            for l in 0..ORDER {
                t[i][l] += fij * r.pwt[j][l];
            }
        }
    }
}

avx512_dispatch!(
    /// The fit's coefficients `c[k][l] = norm Σ_i P_k(x_i) w_i t[i][l]`.
    fn coefficients(r: &Rule, t: &[[f64; ORDER]; ORDER], c: &mut [[f64; ORDER]; ORDER]) => coefficients_generic if true
);

#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn coefficients_generic(r: &Rule, t: &[[f64; ORDER]; ORDER], c: &mut [[f64; ORDER]; ORDER]) {
    for k in 0..ORDER {
        let mut row = [0.0; ORDER];
        for i in 0..ORDER {
            let p = r.pw[k][i];
            for l in 0..ORDER {
                row[l] += p * t[i][l];
            }
        }
        for l in 0..ORDER {
            c[k][l] = row[l] * r.norm[k][l];
        }
    }
}

avx512_dispatch!(
    /// The fit's error estimate, Σ |c_kl| over its highest degree (k or l =
    /// ORDER − 1), from the row and column of coefficients alone (the same
    /// sums, so the same bits, as from all of them); the row and column
    /// summed in vector lanes as [`coefficients`] does.
    fn tail_estimate(r: &Rule, t: &[[f64; ORDER]; ORDER]) -> f64
        => tail_estimate_generic if true
);

#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn tail_estimate_generic(r: &Rule, t: &[[f64; ORDER]; ORDER]) -> f64 {
    let last = ORDER - 1;
    let (mut row, mut col) = ([0.0; ORDER], [0.0; ORDER]);
    for i in 0..ORDER {
        let p = r.pw[last][i];
        for l in 0..ORDER {
            row[l] += p * t[i][l];
        }
        for k in 0..ORDER {
            col[k] += r.pwt[i][k] * t[i][last];
        }
    }
    tail_of(r, &row, &col)
}

/// Σ |c_kl| over the fit's highest degree, from its highest row (`row`)
/// and column (`col`) before their normalisation.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn tail_of(r: &Rule, row: &[f64; ORDER], col: &[f64; ORDER]) -> f64 {
    let last = ORDER - 1;
    let mut tail = 0.0;
    for l in 0..ORDER {
        tail += (row[l] * r.norm[last][l]).abs();
    }
    for k in 0..last {
        tail += (col[k] * r.norm[k][last]).abs();
    }
    tail
}

avx512_dispatch!(
    /// A whole cell's fit reduced to what a whole cell needs of it: the
    /// error estimate of [`tail_estimate`] and the node sum (c\[0\]\[0\],
    /// whose multiple is the integral), straight from the node values. The
    /// highest row of coefficients is
    /// Σ_j (Σ_i P_last(x_i) w_i f_ij) P_l(x_j) w_j; the highest column and
    /// the node sum contract one index first likewise:
    /// five 8×8 products of vectors instead of the 8×8×8 of [`fit_rows`]
    /// (which a part of a cell needs for all its coefficients).
    fn whole_cell_fit(r: &Rule, f: &[f64; NODES]) -> (f64, f64) => whole_cell_fit_generic if true
);

#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn whole_cell_fit_generic(r: &Rule, f: &[f64; NODES]) -> (f64, f64) {
    let last = ORDER - 1;
    // u[j] = Σ_i P_last(x_i) w_i f_ij; the column t[i][last] and t[i][0]
    // of `fit_rows`.
    let mut u = [0.0; ORDER];
    let (mut t_last, mut t_first) = ([0.0; ORDER], [0.0; ORDER]);
    for i in 0..ORDER {
        let p = r.pw[last][i];
        let fi = &f[i * ORDER..(i + 1) * ORDER];
        for j in 0..ORDER {
            u[j] += p * fi[j];
        }
        let (mut a, mut b) = (0.0, 0.0);
        for j in 0..ORDER {
            a += fi[j] * r.pwt[j][last];
            b += fi[j] * r.pwt[j][0];
        }
        t_last[i] = a;
        t_first[i] = b;
    }
    let (mut row, mut col) = ([0.0; ORDER], [0.0; ORDER]);
    for j in 0..ORDER {
        for l in 0..ORDER {
            row[l] += u[j] * r.pwt[j][l];
        }
    }
    for i in 0..ORDER {
        for k in 0..ORDER {
            col[k] += r.pwt[i][k] * t_last[i];
        }
    }
    let tail = tail_of(r, &row, &col);
    let mut sum = 0.0;
    for i in 0..ORDER {
        sum += r.pw[0][i] * t_first[i];
    }
    (tail, sum * r.norm[0][0])
}

avx512_dispatch!(
    /// m\[k\]\[l\] += ∮ R_k(x) P_l(y) dy along the edge p0 → p1 (cell
    /// coordinates) for k, l ≤ `degree`: Green's theorem's moments of one
    /// straight edge, by the (degree + 1)-point rule (exact: the integrand
    /// is a polynomial of degree 2·degree + 1 along the edge). Entries with
    /// k > degree are left alone, those with l > degree are not taken (the
    /// fit is zero there, and they are not read).
    fn edge_moments(r: &Rule, degree: usize, p0: DVec2, p1: DVec2, m: &mut [[f64; ORDER]; ORDER]) => edge_moments_generic if true
);

#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn edge_moments_generic(
    r: &Rule,
    degree: usize,
    p0: DVec2,
    p1: DVec2,
    m: &mut [[f64; ORDER]; ORDER],
) {
    let dy = p1.y - p0.y;
    // R_k(−1) = 0: an edge along the cell's left side adds nothing.
    if dy == 0.0 || (p0.x == -1.0 && p1.x == -1.0) {
        return;
    }
    let (ts, ws) = (&r.edge_t[degree], &r.edge_w[degree]);
    for g in 0..=degree {
        let wg = ws[g] * dy;
        let p = p0 + (p1 - p0) * ts[g];
        let rk = legendre_integrals(p.x, degree);
        let pl = legendre(p.y, degree);
        for k in 0..=degree {
            let s = wg * rk[k];
            // The whole row, a fixed length that vectorizes without a
            // loop: the entries past `degree` are never read.
            for l in 0..ORDER {
                m[k][l] += s * pl[l];
            }
        }
    }
}

/// Bonnet's recurrence without divisions: P_{k+1} = A_k x P_k − B_k P_{k−1}
/// with A_k = (2k + 1)/(k + 1), B_k = k/(k + 1); and 1/(2k + 1) for R_k.
const fn recurrence() -> ([f64; ORDER], [f64; ORDER], [f64; ORDER]) {
    let (mut a, mut b, mut inv) = ([0.0; ORDER], [0.0; ORDER], [0.0; ORDER]);
    let mut k = 0;
    while k < ORDER {
        a[k] = (2 * k + 1) as f64 / (k + 1) as f64;
        b[k] = k as f64 / (k + 1) as f64;
        inv[k] = 1.0 / (2 * k + 1) as f64;
        k += 1;
    }
    (a, b, inv)
}
const RECURRENCE: ([f64; ORDER], [f64; ORDER], [f64; ORDER]) = recurrence();

/// P_0 … P_top at x (1 ≤ top ≤ ORDER), zeros after: a fit cut to a low
/// degree needs only the first few of the recurrence's chain.
#[inline]
fn legendre_plus(x: f64, top: usize) -> [f64; ORDER + 1] {
    let (a, b, _) = &RECURRENCE;
    let mut p = [0.0; ORDER + 1];
    p[0] = 1.0;
    p[1] = x;
    for k in 1..top {
        p[k + 1] = a[k] * x * p[k] - b[k] * p[k - 1];
    }
    p
}

/// P_0 … P_top at x (top < ORDER), zeros after.
#[inline]
fn legendre(x: f64, top: usize) -> [f64; ORDER] {
    let p = legendre_plus(x, top.max(1));
    std::array::from_fn(|k| p[k])
}

/// R_k(x) = ∫_{−1}^x P_k for k ≤ top (top < ORDER); the entries after
/// are not.
#[inline]
fn legendre_integrals(x: f64, top: usize) -> [f64; ORDER] {
    let p = legendre_plus(x, top + 1);
    std::array::from_fn(|k| {
        if k == 0 {
            x + 1.0
        } else {
            (p[k + 1] - p[k - 1]) * RECURRENCE.2[k]
        }
    })
}

/// Scratch of the cubature: the visible pieces clipped to each level's cell.
#[derive(Debug, Clone, Default)]
pub struct CubatureScratch {
    /// Level d ≥ 1 (the root's pieces are the caller's, not copied: see
    /// [`Ctx::pieces`]).
    levels: Vec<Pieces>,
    outline: Outline,
    tmp: Vec<DVec2>,
    tmp2: Vec<DVec2>,
}

/// What the cubature did (for the tests and the bench).
#[derive(Debug, Clone, Copy, Default)]
pub struct CubatureReport {
    /// Cells fitted.
    pub cells: u32,
    /// Sum of the accepted cells' error estimates (relative to the light's
    /// area): the factor's estimated error.
    pub error: f64,
}

/// What the cubature's gates take of the light's shape alone: the same
/// from every point, so kept with the light's frame.
#[derive(Debug, Clone, Copy, Default)]
pub struct LightSpan {
    /// The longer edge.
    side: f64,
    /// The half-sum of the edges (see [`Ctx`]).
    reach: f64,
    /// The unit normal of the light's plane (the point's height along it).
    normal: DVec3,
}

impl LightSpan {
    /// The span of the light with edges `edge_u`, `edge_v` (those of the
    /// [`Lobe`]s it is used with).
    pub fn new(edge_u: DVec3, edge_v: DVec3) -> LightSpan {
        LightSpan {
            side: edge_u.length().max(edge_v.length()),
            reach: 0.5 * (edge_u.length() + edge_v.length()),
            normal: edge_u.cross(edge_v).normalize_or_zero(),
        }
    }
}

/// ∫ f da db over the pieces (in the light's (a, b) coordinates, inside
/// the unit square): the specular factor of the visible region. `span`:
/// [`LightSpan::new`] of the lobe's light.
pub fn specular_factor(
    lobe: &Lobe,
    span: &LightSpan,
    pieces: &Pieces,
    s: &mut CubatureScratch,
) -> (f64, CubatureReport) {
    let mut report = CubatureReport::default();
    if pieces.is_empty() {
        return (0.0, report);
    }
    let visible = pieces.area();
    if let Some(skipped) = skipped(lobe, visible.min(1.0)) {
        return (0.0, skipped);
    }
    if s.levels.len() < MAX_DEPTH as usize + 1 {
        s.levels
            .resize_with(MAX_DEPTH as usize + 1, Pieces::default);
    }
    let ctx = Ctx::new(lobe, span, pieces);
    let total = cell(&ctx, s, 0, DVec2::ZERO, 1.0, visible, &mut report);
    (total, report)
}

/// The report of a lobe taken as 0: its bound over the light, times the
/// visible share of the light `share`, is below the skip level (the factor
/// is 0 within that bound); `None` for a lobe to integrate.
#[inline]
fn skipped(lobe: &Lobe, share: f64) -> Option<CubatureReport> {
    // Most lobes are settled (well above the skip) by their value in the
    // light centre's direction, a lower bound of the bound: without the
    // bound's square roots.
    if settled_by_centre(lobe, share) {
        return None;
    }
    let cos_h = lobe_bound_cos(lobe);
    // ln x ≥ 1 − 1/x: a lower bound of the logarithms that settles most
    // points (a lobe well above the skip) without taking them.
    let lower = lobe.shininess * (1.0 - 1.0 / cos_h) + (1.0 - 1.0 / share);
    if lower > SKIP.ln() + SKIP_MARGIN {
        return None;
    }
    let bound_ln = bound_ln(cos_h, lobe.shininess) + share.ln();
    (bound_ln <= SKIP.ln()).then(|| CubatureReport {
        error: bound_ln.exp(),
        ..CubatureReport::default()
    })
}

/// A lobe whose bound over the light is below this is taken as 0 (far
/// below [`TOLERANCE`], so that the skip adds no visible bias).
const SKIP: f64 = 1e-2 * TOLERANCE;

/// Far above the rounding of the lower bound and of the logarithms (both
/// of terms within ln [`SKIP`] of 0 where it decides): a lower bound this
/// far above the skip level leaves the logarithms above it too.
const SKIP_MARGIN: f64 = 1e-9;

/// Whether the lobe's value in the direction of the light's centre, N·H
/// there (a light point, so at most the bound of [`lobe_bound_cos`]),
/// already settles the skip test of [`specular_factor`] (visible share
/// `share`): its lower bound of the logarithms, taken with N·H for the
/// bound, clears the skip level by more than the roundings. N·H is off
/// by ~1e-15 relative at most, which moves s (1 − 1/N·H) by at most
/// s/N·H times that, and s/N·H < s + 14 wherever the test passes: the
/// margin, 10⁻¹² (1 + s) beyond the skip test's own, covers it 1000-fold.
/// The bound then settles it too: the same decision, from two square
/// roots instead of nine.
#[inline]
fn settled_by_centre(l: &Lobe, share: f64) -> bool {
    let centre = l.direction(0.5, 0.5);
    let h = centre / centre.length() + l.v;
    let cos = l.n.dot(h) / h.length();
    // A NaN (a zero direction) or N·H ≤ 0 compares false: the full test.
    cos > 0.0
        && l.shininess * (1.0 - 1.0 / cos) + (1.0 - 1.0 / share)
            > SKIP.ln() + SKIP_MARGIN + CENTRE_MARGIN * (1.0 + l.shininess)
}

/// See [`settled_by_centre`].
const CENTRE_MARGIN: f64 = 1e-12;

/// The logarithm of the lobe's bound `cos_h`^s (a logarithm is cheaper
/// than the power, and the skip only compares it).
fn bound_ln(cos_h: f64, shininess: f64) -> f64 {
    if cos_h == 0.0 {
        f64::NEG_INFINITY
    } else {
        cos_h.ln() * shininess
    }
}

/// An upper bound of max(0, N·H) over the light: 1 where there is none,
/// 0 where N·H ≤ 0 over all of it. The light's directions
/// lie in the cone about its centre's direction through its farthest
/// corner (half-angle α: a convex polygon's farthest point from an axis is
/// a vertex); over that cone N·L ≤ cos(max(0, θ_N − α)) and
/// L·V ≥ cos(min(π, θ_V + α)), so N·H = (N·L + N·V)/|L + V| is at most the
/// largest numerator over the smallest denominator.
fn lobe_bound_cos(l: &Lobe) -> f64 {
    let centre = (l.corner + 0.5 * (l.edge_u + l.edge_v)).normalize();
    let mut cos_a: f64 = 1.0;
    for c in [
        l.corner,
        l.corner + l.edge_u,
        l.corner + l.edge_v,
        l.corner + l.edge_u + l.edge_v,
    ] {
        cos_a = cos_a.min(centre.dot(c) / c.length());
    }
    // A light 90° or more wide (or a NaN): no bound.
    if cos_a.is_nan() || cos_a <= 0.0 {
        return 1.0;
    }
    let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
    let (cn, cv) = (l.n.dot(centre), l.v.dot(centre));
    let max_nl = if cn >= cos_a {
        1.0
    } else {
        cn * cos_a + (1.0 - cn * cn).max(0.0).sqrt() * sin_a
    };
    let min_lv = if cv >= -cos_a {
        cv * cos_a - (1.0 - cv * cv).max(0.0).sqrt() * sin_a
    } else {
        -1.0
    };
    let num = max_nl + l.n.dot(l.v);
    if num <= 0.0 {
        return 0.0;
    }
    let den2 = 2.0 + 2.0 * min_lv;
    // Rounding margin: the bound only decides a skip far below the peak.
    if den2 > 1e-12 {
        (num / den2.sqrt() * (1.0 + 1e-9)).min(1.0)
    } else {
        1.0
    }
}

struct Ctx<'a> {
    lobe: &'a Lobe,
    /// The visible pieces (the root cell's).
    root: &'a Pieces,
    /// The lobe's width in L along the plane of incidence (how far it
    /// reaches) and across it (the finest detail to resolve).
    width: f64,
    narrow: f64,
    mirror: DVec3,
    /// The light's longer edge.
    side: f64,
    /// The half-sum of the light's edges (a cell's centre lies within
    /// `size` times that of each of its points) and the point's height
    /// above the light's plane: the cell's distance is at least the larger
    /// of the height and the centre's distance less `size` × `reach`.
    reach: f64,
    height: f64,
}

impl Ctx<'_> {
    fn new<'a>(lobe: &'a Lobe, span: &LightSpan, root: &'a Pieces) -> Ctx<'a> {
        // The lobe's width in L (cos^s θ_H ≈ exp(−s θ_H²/2), θ_L ≈ 2 θ_H)
        // and the mirror direction, where it peaks.
        let mirror = lobe.n * (2.0 * lobe.n.dot(lobe.v)) - lobe.v;
        // Across the plane of incidence H turns by the turn of L over
        // |L + V| = 2 N·V at the peak, not by half of it: at grazing views
        // the lobe is N·V times as narrow there (a lobe 0.007 rad across
        // at N·V = 0.035, shininess 100, fell between the nested rules'
        // nodes, tested below).
        let width = 2.0 / lobe.shininess.max(1.0).sqrt();
        Ctx {
            lobe,
            root,
            width,
            narrow: width * lobe.n.dot(lobe.v).clamp(NARROWEST, 1.0),
            mirror: mirror.normalize_or_zero(),
            side: span.side,
            reach: span.reach,
            height: lobe.corner.dot(span.normal).abs(),
        }
    }
}

/// The lobe's narrowing across the plane of incidence is taken at most
/// this (views more grazing still resolve to the deepest cells).
const NARROWEST: f64 = 1e-3;

/// Nested rules only on a cell whose side is at most this fraction of its
/// distance from the point. Nearer, the directions bend across the cell
/// (1/|d| is singular at the point's height off the plane, in complex
/// light coordinates) faster than 5 nodes a side follow, and the rules'
/// differences were seen to understate their error 60-fold, by up to
/// 2.6e-4 of the cell.
const NEAR_FIELD: f64 = 0.5;

/// A cell as its gates see it: its centre's distance from the point, its
/// angular size, whether the mirror direction passes within that plus
/// six lobe widths (beyond which the lobe is below e⁻¹⁸ of its peak), and
/// the lobe's narrowest width across the plane of incidence on the cell,
/// taken once for all of a cell's gates.
struct CellView {
    distance: f64,
    angular: f64,
    near_mirror: bool,
    narrow: f64,
}

/// acos(`cos`) < `limit`, mostly without the arccosine: the chord
/// r = √(2 − 2 cos) brackets the angle θ as r ≤ θ ≤ π r/2 (2 sin(θ/2) ≥
/// 2θ/π on [0, π]); only where `limit` falls within the bracket (widened
/// far beyond the roundings) is the arccosine taken.
fn angle_below(cos: f64, limit: f64) -> bool {
    const MARGIN: f64 = 1e-9;
    let r = (2.0 - 2.0 * cos).sqrt();
    if std::f64::consts::FRAC_PI_2 * r < limit * (1.0 - MARGIN) {
        true
    } else if r > limit * (1.0 + MARGIN) {
        false
    } else {
        cos.acos() < limit
    }
}

impl CellView {
    fn new(ctx: &Ctx, lo: DVec2, size: f64) -> CellView {
        let centre = ctx.lobe.direction(lo.x + 0.5 * size, lo.y + 0.5 * size);
        let distance = centre.length();
        let angular = size * ctx.side * std::f64::consts::SQRT_2 / distance;
        // Only asked with 3 nodes a side or more (and the cell's narrow
        // width is never below the peak's).
        let near_mirror = angular / NESTED_ORDERS[1] as f64 > 0.5 * ctx.narrow && {
            let cos = (centre / distance).dot(ctx.mirror).clamp(-1.0, 1.0);
            angle_below(cos, angular + 6.0 * ctx.width)
        };
        // Across the plane of incidence H turns by the turn of L over
        // |L + V| (2 N·V at the peak, where `Ctx::narrow` takes it). A cell
        // whose directions all lie nearer V than that (the light above a
        // point seen at a grazing angle, the peak beside it) sees the lobe
        // that much wider: |L + V|/2 = cos(∠(L, V)/2), and ∠(L, V) is at
        // most the centre's angle plus the cell's angular size.
        let narrow = if near_mirror {
            let cos_v = (centre / distance).dot(ctx.lobe.v).clamp(-1.0, 1.0);
            let widest = (cos_v.acos() + angular).min(std::f64::consts::PI);
            ctx.narrow.max(ctx.width * (0.5 * widest).cos())
        } else {
            ctx.narrow
        };
        CellView {
            distance,
            angular,
            near_mirror,
            narrow,
        }
    }

    /// Too coarse for a narrow lobe that may lie on it: `nodes` (≥ 3) per
    /// side farther apart than half the lobe's width, and the mirror
    /// direction near.
    fn lobe_unresolved(&self, nodes: usize) -> bool {
        self.angular / nodes as f64 > 0.5 * self.narrow && self.near_mirror
    }

    /// Whether the nested rules may take the cell (of side `size`) whole:
    /// `None` where it is in the near field or too coarse for them, else
    /// whether the 3² rule resolves the lobe (`coarse` of
    /// [`nested_cell`]).
    fn nested_rules(&self, ctx: &Ctx, lo: DVec2, size: f64) -> Option<bool> {
        if self.near_field(ctx, lo, size) || self.lobe_unresolved(NESTED_ORDERS[2]) {
            return None;
        }
        Some(!self.lobe_unresolved(NESTED_ORDERS[1]))
    }

    /// Too near the point for the nested rules: the side above
    /// [`NEAR_FIELD`] of the cell's distance (its nearest point's). A
    /// lower bound from the centre's distance settles most cells; the
    /// nearest point is found only where the bound says near (it
    /// understates the distance of a cell beside the point by up to half
    /// the cell's diagonal, and the light's cells seen from the walls
    /// below it all looked near).
    fn near_field(&self, ctx: &Ctx, lo: DVec2, size: f64) -> bool {
        let bound = (self.distance - size * ctx.reach).max(ctx.height);
        size * ctx.side > NEAR_FIELD * bound && size * ctx.side > NEAR_FIELD * ctx.nearest(lo, size)
    }
}

impl Ctx<'_> {
    /// The distance from the point to the nearest point of the cell
    /// [lo, lo + size]² of the light (a parallelogram): its height where
    /// its foot on the light's plane lies in the cell, else the nearest of
    /// the cell's four edges.
    fn nearest(&self, lo: DVec2, size: f64) -> f64 {
        let (c, u, v) = (self.lobe.corner, self.lobe.edge_u, self.lobe.edge_v);
        let (uu, uv, vv) = (u.dot(u), u.dot(v), v.dot(v));
        let det = uu * vv - uv * uv;
        if det > 0.0 {
            // The foot's (a, b): its offset from the corner, −c, against
            // the edges.
            let (cu, cv) = (-c.dot(u), -c.dot(v));
            let foot = DVec2::new(cu * vv - cv * uv, cv * uu - cu * uv) / det;
            let hi = lo + DVec2::splat(size);
            if foot.cmpge(lo).all() && foot.cmple(hi).all() {
                return self.height;
            }
        }
        let corners = [
            lo,
            DVec2::new(lo.x + size, lo.y),
            lo + DVec2::splat(size),
            DVec2::new(lo.x, lo.y + size),
        ]
        .map(|p| self.lobe.direction(p.x, p.y));
        (0..4)
            .map(|i| {
                let (p, q) = (corners[i], corners[(i + 1) % 4]);
                let e = q - p;
                let t = (-p.dot(e) / e.length_squared()).clamp(0.0, 1.0);
                (p + e * t).length()
            })
            .fold(f64::INFINITY, f64::min)
            .max(self.height)
    }
}

/// The nested rules over a wholly visible cell where they resolve the
/// lobe and the cell is not in the near field (`view`: `None` at the
/// deepest level, where they are always tried), as [`nested_cell`].
fn whole_cell(ctx: &Ctx, lo: DVec2, size: f64, view: Option<&CellView>) -> Option<(f64, f64)> {
    let coarse = match view {
        Some(v) => v.nested_rules(ctx, lo, size)?,
        None => true,
    };
    nested_cell(ctx.lobe, lo, size, coarse)
}

/// ∫ over the visible part of the cell [lo, lo + size]² (its pieces in
/// `s.levels[depth]`, of area `covered`: the caller has it).
fn cell(
    ctx: &Ctx,
    s: &mut CubatureScratch,
    depth: u32,
    lo: DVec2,
    size: f64,
    covered: f64,
    report: &mut CubatureReport,
) -> f64 {
    let d = depth as usize;
    if covered <= 0.0 {
        return 0.0;
    }
    let full = covered >= size * size * (1.0 - 1e-12);
    let deepest = depth == MAX_DEPTH;
    let view = (!deepest).then(|| CellView::new(ctx, lo, size));
    if full && let Some((value, estimate)) = whole_cell(ctx, lo, size, view.as_ref()) {
        report.cells += 1;
        report.error += estimate;
        return value;
    }
    let half = 0.5 * size;
    // A cell too coarse for the lobe splits whatever its fit's estimate:
    // no fit to take.
    if view.as_ref().is_some_and(|v| v.lobe_unresolved(ORDER)) {
        return split_cell(ctx, s, depth, lo, half, report);
    }
    let r = rule();
    let lobe = ctx.lobe;
    let jac = half * half;
    // A part of a cell where the nested rules would take it whole (not in
    // the near field, the lobe resolved by four nodes a side) first tries
    // the low fit: most such cells need no more than degree 3.
    let low = match &view {
        Some(v) if !full && v.nested_rules(ctx, lo, size).is_some() => low_fit(lobe, lo, size),
        _ => None,
    };
    let (c, tail) = match low {
        Some(fit) => {
            report.cells += 1;
            fit
        }
        None => {
            // The tensor nodes from the ORDER coordinates of each axis.
            let xs: [f64; ORDER] = std::array::from_fn(|i| lo.x + (r.x[i] + 1.0) * half);
            let ys: [f64; ORDER] = std::array::from_fn(|j| lo.y + (r.x[j] + 1.0) * half);
            let mut nf = [0.0; NODES];
            lobe_at_tensor_nodes(lobe, &xs, &ys, &mut nf);
            report.cells += 1;
            if full {
                // A whole cell needs only the estimate and the node sum.
                let (tail, sum) = whole_cell_fit(r, &nf);
                if view.is_some() && tail > TOLERANCE {
                    return split_cell(ctx, s, depth, lo, half, report);
                }
                // The accepted cell's share of the estimated error.
                report.error += tail * covered;
                // ∫ over the whole cell of the fit: the node sum.
                return 4.0 * sum * jac;
            }
            let mut t = [[0.0; ORDER]; ORDER];
            fit_rows(r, &nf, &mut t);
            let tail = tail_estimate(r, &t);
            if view.is_some() && tail > TOLERANCE {
                return split_cell(ctx, s, depth, lo, half, report);
            }
            let mut c = [[0.0; ORDER]; ORDER];
            coefficients(r, &t, &mut c);
            (c, tail)
        }
    };
    // Over a part of the cell, the fit truncated to the lowest degree
    // whose dropped coefficients, with the tail, stay within the
    // tolerance (|P_k P_l| ≤ 1, so dropping c_kl moves the cell's
    // integral by at most |c_kl| × its visible share): the edge rule
    // shrinks with the degree.
    let mut ring = [0.0; ORDER];
    for (k, row) in c.iter().enumerate() {
        for (l, x) in row.iter().enumerate() {
            ring[k.max(l)] += x.abs();
        }
    }
    let (mut degree, mut dropped) = (ORDER - 1, 0.0);
    while degree > 0 && dropped + ring[degree] + tail <= TOLERANCE {
        dropped += ring[degree];
        degree -= 1;
    }
    report.error += (tail + dropped) * covered;
    // Green's theorem over each piece, in the cell's [−1, 1]² coordinates:
    // the moments ∫∫ P_k(x) P_l(y) of the visible part, then their sum
    // against the coefficients.
    let mut m = [[0.0; ORDER]; ORDER];
    // Along the pieces' outline only: an edge two pieces share is crossed
    // once each way, and its moments would cancel. One piece is its own
    // outline (no sort to find it).
    let to_cell = |p: DVec2| (p - lo) / half - DVec2::ONE;
    let pieces = level(ctx.root, &s.levels, d);
    if pieces.len() == 1 {
        let poly = pieces.piece(0);
        for (p, q) in edges_of(poly) {
            edge_moments(r, degree, to_cell(p), to_cell(q), &mut m);
        }
    } else {
        outline(pieces, &mut s.outline);
        for e in &s.outline.edges {
            let (p0, p1) = (to_cell(e.lo), to_cell(e.hi));
            for _ in 0..e.sign.abs() as u32 {
                if e.sign > 0.0 {
                    edge_moments(r, degree, p0, p1, &mut m);
                } else {
                    edge_moments(r, degree, p1, p0, &mut m);
                }
            }
        }
    }
    let mut total = 0.0;
    for (ck, mk) in c.iter().zip(&m).take(degree + 1) {
        total += ck[..=degree]
            .iter()
            .zip(&mk[..=degree])
            .map(|(a, b)| a * b)
            .sum::<f64>();
    }
    total * jac
}

/// Nodes a side of the low fit: degree 3 from sixteen lobe values (one
/// chunk of the nested rules' kernel) instead of the full fit's 64.
const LOW: usize = 4;

/// The low fit's degree-3 coefficients times this are its estimate: four
/// nodes a side are as few as the 3² rule's for the top degree to track
/// the error alone, so the margin is the one that rule needs.
const LOW_SAFETY: f64 = START_SAFETY;

/// The low fit's tensor nodes in [0, 1]² (node i·LOW + j at (x\[i\],
/// y\[j\]), as the full fit orders them), with `pw[k][i] = P_k(x_i) w_i`
/// on [−1, 1].
struct LowRule {
    x: [f64; CHUNK],
    y: [f64; CHUNK],
    pw: [[f64; LOW]; LOW],
}

fn low_rule() -> &'static LowRule {
    static RULE: OnceLock<LowRule> = OnceLock::new();
    RULE.get_or_init(|| {
        let g = crate::render::math::gauss_legendre(LOW);
        let mut r = LowRule {
            x: [0.0; CHUNK],
            y: [0.0; CHUNK],
            pw: [[0.0; LOW]; LOW],
        };
        for (i, &(ti, wi)) in g.iter().enumerate() {
            let p = legendre(ti, LOW - 1);
            for (k, pw) in r.pw.iter_mut().enumerate() {
                pw[i] = p[k] * wi;
            }
            for (j, &(tj, _)) in g.iter().enumerate() {
                r.x[i * LOW + j] = (ti + 1.0) * 0.5;
                r.y[i * LOW + j] = (tj + 1.0) * 0.5;
            }
        }
        r
    })
}

/// The degree-3 fit of the lobe on the cell [lo, lo + size]² (its
/// coefficients, zero above degree 3) and its estimate, [`LOW_SAFETY`]
/// times the sum of its degree-3 coefficients; `None` where that is above
/// [`TOLERANCE`] (the full fit is taken instead).
#[allow(clippy::needless_range_loop)]
fn low_fit(lobe: &Lobe, lo: DVec2, size: f64) -> Option<([[f64; ORDER]; ORDER], f64)> {
    let r = low_rule();
    let mut f = [0.0; CHUNK];
    lobe_at_nested_nodes(lobe, lo, size, &r.x, &r.y, &mut f);
    // t[i][l] = Σ_j f_ij P_l(y_j) w_j; c_kl = norm Σ_i P_k(x_i) w_i t[i][l].
    let mut t = [[0.0; LOW]; LOW];
    for i in 0..LOW {
        for j in 0..LOW {
            for l in 0..LOW {
                t[i][l] += f[i * LOW + j] * r.pw[l][j];
            }
        }
    }
    let norm = &rule().norm;
    let mut c = [[0.0; ORDER]; ORDER];
    let mut tail = 0.0;
    for k in 0..LOW {
        for l in 0..LOW {
            let mut sum = 0.0;
            for i in 0..LOW {
                sum += r.pw[k][i] * t[i][l];
            }
            c[k][l] = sum * norm[k][l];
            if k.max(l) == LOW - 1 {
                tail += c[k][l].abs();
            }
        }
    }
    let estimate = LOW_SAFETY * tail;
    (estimate <= TOLERANCE).then_some((c, estimate))
}

/// ∫ over the visible part of the cell at `lo` as the sum of its four
/// quarters (side `half`).
fn split_cell(
    ctx: &Ctx,
    s: &mut CubatureScratch,
    depth: u32,
    lo: DVec2,
    half: f64,
    report: &mut CubatureReport,
) -> f64 {
    let mut total = 0.0;
    for (dx, dy) in [(0.0, 0.0), (half, 0.0), (0.0, half), (half, half)] {
        let child = lo + DVec2::new(dx, dy);
        clip_level(ctx.root, s, depth as usize, child, half);
        let covered = s.levels[depth as usize + 1].area();
        total += cell(ctx, s, depth + 1, child, half, covered, report);
    }
    total
}

/// The pieces of level `d`: `root` at level 0, else those of a cell.
fn level<'a>(root: &'a Pieces, levels: &'a [Pieces], d: usize) -> &'a Pieces {
    if d == 0 { root } else { &levels[d] }
}

/// The pieces of level `d` (`root` at level 0) clipped to the cell
/// [lo, lo + size]², into level d + 1.
fn clip_level(root: &Pieces, s: &mut CubatureScratch, d: usize, lo: DVec2, size: f64) {
    let hi = lo + DVec2::splat(size);
    let planes = [
        HalfPlane {
            n: DVec2::X,
            c: -lo.x,
        },
        HalfPlane {
            n: -DVec2::X,
            c: hi.x,
        },
        HalfPlane {
            n: DVec2::Y,
            c: -lo.y,
        },
        HalfPlane {
            n: -DVec2::Y,
            c: hi.y,
        },
    ];
    let (head, tail) = s.levels.split_at_mut(d + 1);
    let (parent, out) = (level(root, head, d), &mut tail[0]);
    out.clear();
    for p in parent.iter() {
        let (plo, phi) = super::polygon::bounds(p);
        if phi.x <= lo.x || phi.y <= lo.y || plo.x >= hi.x || plo.y >= hi.y {
            continue;
        }
        s.tmp.clear();
        s.tmp.extend_from_slice(p);
        let mut alive = true;
        for h in planes {
            s.tmp2.clear();
            if clip_into(&s.tmp, h, &mut s.tmp2) == 0 {
                alive = false;
                break;
            }
            std::mem::swap(&mut s.tmp, &mut s.tmp2);
        }
        if alive {
            out.push(&s.tmp, 0.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{
        CHUNK, CellView, Ctx, CubatureScratch, LightSpan, Lobe, MAX_DEPTH, Pieces, SKIP,
        SKIP_MARGIN, TOLERANCE, WHOLE_LANES, bound_ln, lobe_at_nested_nodes, lobe_bound_cos,
        pow_one_minus, settled_by_centre, specular_factor, whole_cell, whole_light_specular,
    };
    use crate::render::rng::Rng;
    use glam::{DVec2, DVec3};

    /// A whole cell's reduced fit gives the estimate and node sum of the
    /// full fit (other sums of the same products: equal to rounding).
    #[test]
    fn whole_cell_fit_matches_the_full_fit() {
        use super::{NODES, ORDER, fit_rows, rule, tail_estimate, whole_cell_fit};
        let r = rule();
        let mut rng = Rng::new(21);
        for case in 0..500 {
            // Smooth and rough node values, of every scale.
            let scale = 10f64.powi(case % 7 - 3);
            let f: [f64; NODES] = std::array::from_fn(|k| {
                let (i, j) = ((k / ORDER) as f64, (k % ORDER) as f64);
                scale
                    * if case % 2 == 0 {
                        (0.3 * i + 0.2 * j).exp()
                    } else {
                        rng.next_f64()
                    }
            });
            let mut t = [[0.0; ORDER]; ORDER];
            fit_rows(r, &f, &mut t);
            let (tail, sum) = whole_cell_fit(r, &f);
            let want_tail = tail_estimate(r, &t);
            let want_sum: f64 =
                (0..ORDER).map(|i| r.pw[0][i] * t[i][0]).sum::<f64>() * r.norm[0][0];
            assert!(
                (sum - want_sum).abs() <= 1e-14 * scale,
                "case {case}: {sum} vs {want_sum}"
            );
            assert!(
                (tail - want_tail).abs() <= 1e-13 * scale,
                "case {case}: {tail} vs {want_tail}"
            );
        }
    }

    /// The skip's bound is never below the lobe anywhere on the light
    /// (dense points, lights seen from many points, normals and views).
    #[test]
    fn lobe_bound_is_above_the_lobe() {
        let mut rng = Rng::new(1);
        let mut next = || rng.next_f64();
        let mut unit = || {
            let v = DVec3::new(next() * 2.0 - 1.0, next() * 2.0 - 1.0, next() * 2.0 - 1.0);
            v.normalize()
        };
        let mut skipped = 0;
        for case in 0..400 {
            let (n, v) = (unit(), unit());
            let corner = DVec3::new(-1.0, 2.0 + (case % 7) as f64, -1.0) + unit() * 0.5;
            let shininess = [5.0, 20.0, 100.0, 500.0][case % 4];
            let lobe = Lobe {
                n,
                v,
                shininess,
                corner,
                edge_u: DVec3::new(2.0, 0.0, 0.0),
                edge_v: DVec3::new(0.0, 0.3, 2.0),
            };
            let bound = bound_ln(lobe_bound_cos(&lobe), lobe.shininess).exp();
            let mut peak: f64 = 0.0;
            for i in 0..=64 {
                for j in 0..=64 {
                    let l = lobe.direction(i as f64 / 64.0, j as f64 / 64.0).normalize();
                    let h = (l + v).normalize_or_zero();
                    peak = peak.max(n.dot(h).max(0.0).powf(shininess));
                }
            }
            assert!(
                peak <= bound * (1.0 + 1e-12),
                "case {case}: {peak} > {bound}"
            );
            skipped += (bound <= super::SKIP) as u32;
        }
        // The bound is tight enough to skip some lobes.
        assert!(skipped > 20, "{skipped}");
    }

    /// The light centre's lobe settles the skip test only where the
    /// bound settles it too (so the two decide alike): random lobes and
    /// lights, shininess up to the format's 10⁶, many of them set to put
    /// the centre's test within a hair of the skip level.
    #[test]
    fn the_centre_settles_only_lobes_the_bound_settles() {
        let mut rng = Rng::new(9);
        let unit = |rng: &mut Rng| {
            let mut c = || rng.next_f64() * 2.0 - 1.0;
            DVec3::new(c(), c(), c()).normalize()
        };
        let (mut by_centre, mut near, mut near_settled) = (0, 0, 0);
        for case in 0..200_000 {
            let (n, v) = (unit(&mut rng), unit(&mut rng));
            let corner = unit(&mut rng) * (0.2 + 6.0 * rng.next_f64());
            // Some lights tiny: the bound then comes within its own
            // margin of the centre's value.
            let size = if case % 5 == 0 { 1e-13 } else { 1.0 };
            let edge_u = unit(&mut rng) * (0.05 + 3.0 * rng.next_f64()) * size;
            let edge_v = unit(&mut rng) * (0.05 + 3.0 * rng.next_f64()) * size;
            let share = if case % 3 == 0 {
                1.0
            } else {
                (0.01 + rng.next_f64()).min(1.0)
            };
            let mut lobe = Lobe {
                n,
                v,
                shininess: 10f64.powf(6.0 * rng.next_f64()),
                corner,
                edge_u,
                edge_v,
            };
            if case % 2 == 0 {
                // The shininess that puts the centre's test at the skip
                // level, give or take 10⁻⁶ to 10⁻¹⁰ of it.
                let h = lobe.direction(0.5, 0.5).normalize() + v;
                let cos = n.dot(h) / h.length();
                let level = SKIP.ln() + SKIP_MARGIN - (1.0 - 1.0 / share);
                let spread = 10f64.powi(-6 - case / 2 % 5);
                let s = level / (1.0 - 1.0 / cos) * (1.0 + spread * (rng.next_f64() - 0.5));
                if !(s > 0.0 && s <= 1e6) {
                    continue;
                }
                lobe.shininess = s;
                near += 1;
            }
            if settled_by_centre(&lobe, share) {
                by_centre += 1;
                near_settled += (case % 2 == 0) as u32;
                let cos_h = lobe_bound_cos(&lobe);
                let lower = lobe.shininess * (1.0 - 1.0 / cos_h) + (1.0 - 1.0 / share);
                assert!(lower > SKIP.ln() + SKIP_MARGIN, "case {case}: {lobe:?}");
            }
        }
        // Many lobes settle by the centre, and many of them within a hair
        // of the skip level.
        assert!(
            by_centre > 30_000 && near > 40_000 && near_settled > 5_000,
            "{by_centre} {near} {near_settled}"
        );
    }

    /// The bracketed angle test decides as the arccosine does: random
    /// angles and limits, and limits a rounding away from the angle.
    #[test]
    fn angle_below_matches_the_arccosine() {
        let mut rng = Rng::new(5);
        let mut next = || rng.next_f64();
        for case in 0..200_000 {
            let cos = (2.0 * next() - 1.0).powi(1 + 2 * (case % 3));
            let theta = cos.acos();
            let limit = match case % 4 {
                0 => 4.0 * next(),
                1 => theta * (1.0 + 1e-12 * (next() - 0.5)),
                2 => f64::from_bits(theta.to_bits() + (case % 3) as u64),
                _ => theta * (0.5 + next()),
            };
            if limit > 0.0 {
                assert_eq!(
                    super::angle_below(cos, limit),
                    theta < limit,
                    "{cos}, {limit}"
                );
            }
        }
    }

    #[test]
    fn pow_one_minus_matches_powf() {
        let mut worst: f64 = 0.0;
        for i in 0..=4000 {
            // e from 0 through tiny values to 1.
            let e = if i < 2000 {
                1e-9 * 1.01f64.powi(i)
            } else {
                (i - 2000) as f64 / 2000.0
            }
            .min(1.0);
            let e32 = e as f32;
            for y in [0.5f32, 1.0, 3.0, 20.0, 100.0, 500.0, 1e4] {
                let want = (1.0 - e32 as f64).powf(y as f64);
                let got = pow_one_minus(e32, y) as f64;
                if want < 1e-36 {
                    assert!(got < 1e-35, "(1 − {e})^{y}: {got}");
                    continue;
                }
                let rel = (got - want).abs() / want;
                let bound = 1e-6 * (1.0 + (y as f64 * (1.0 - e32 as f64).log2()).abs());
                assert!(rel < bound, "(1 − {e})^{y}: {got} vs {want} ({rel:e})");
                worst = worst.max(rel);
            }
        }
        assert_eq!(pow_one_minus(1.0, 20.0), 0.0);
        assert_eq!(pow_one_minus(0.0, 500.0), 1.0);
        eprintln!("pow_one_minus worst relative error {worst:e}");
    }

    /// The f32 lobe against max(0, N·H)^s in f64 at random nodes, normals,
    /// views and shininesses up to 2000: within 5e-6 (absolute, the
    /// factor's scale; a twentieth of the cubature's tolerance) and 2e-5 relative.
    #[test]
    fn f32_lobe_matches_the_f64_formula() {
        let mut rng = Rng::new(2);
        let mut next = || rng.next_f64();
        let mut worst: f64 = 0.0;
        for case in 0..1200 {
            let n = DVec3::new(next() - 0.5, 1.0, next() - 0.5).normalize();
            // Views near the mirror direction of the light's centre too, so
            // that narrow lobes peak on it.
            let corner = DVec3::new(-1.0 + next(), 2.0 + 6.0 * next(), -1.0 + next());
            let centre = (corner + DVec3::new(1.0, 0.0, 1.0)).normalize();
            let mirror = n * (2.0 * n.dot(centre)) - centre;
            let jitter = DVec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * 0.2;
            let v = (mirror + jitter * (case % 3) as f64).normalize();
            let shininess = [1.0, 20.0, 100.0, 500.0, 2000.0][case % 5];
            let lobe = Lobe {
                n,
                v,
                shininess,
                corner,
                edge_u: DVec3::new(2.0, 0.0, 0.0),
                edge_v: DVec3::new(0.0, 0.0, 2.0),
            };
            let a: [f64; CHUNK] = std::array::from_fn(|_| next());
            let b: [f64; CHUNK] = std::array::from_fn(|_| next());
            let mut got = [0.0; CHUNK];
            // The unit cell: the nodes are (a, b) themselves.
            lobe_at_nested_nodes(&lobe, DVec2::ZERO, 1.0, &a, &b, &mut got);
            for j in 0..CHUNK {
                let l = lobe.direction(a[j], b[j]).normalize();
                let h = (l + v).normalize_or_zero();
                let want = n.dot(h).max(0.0).powf(shininess);
                let err = (got[j] - want).abs();
                assert!(
                    err <= 5e-6 && err <= 2e-5 * want + 1e-9,
                    "case {case} node {j}: {} vs {want}",
                    got[j]
                );
                worst = worst.max(err);
            }
        }
        eprintln!("f32 lobe worst absolute error {worst:e}");
    }

    /// A whole cell's nested rules against a dense product rule (the f64
    /// lobe, 64² Gauss points per quarter of the cell), through the
    /// renderer's gate (`whole_cell`): where they accept, the value is
    /// within the tolerance of the cell's area and within their estimate
    /// plus the f32 lobe's rounding. Random lobes from wide to narrow
    /// (views near the mirror direction, so that narrow lobes peak on the
    /// light, anywhere in front, and grazing), points from a tenth of the light's
    /// side off its plane to four sides, cells from the whole light to the
    /// deepest level, each in front of the surface as the visible pieces
    /// are.
    #[test]
    fn whole_lights_side_by_side_give_the_bits_of_each_alone() {
        let mut rng = Rng::new(41);
        let mut next = || rng.next_f64();
        let mut scratch = CubatureScratch::default();
        let (mut nested, mut fitted, mut alone) = (0, 0, 0);
        for round in 0..1500 {
            let span_edges = (DVec3::new(2.0, 0.0, 0.0), DVec3::new(0.0, 0.0, 2.0));
            let span = LightSpan::new(span_edges.0, span_edges.1);
            let count = 1 + round % WHOLE_LANES;
            let lobes: Vec<Lobe> = (0..count)
                .map(|k| {
                    let n = DVec3::new(next() - 0.5, 1.0, next() - 0.5).normalize();
                    // From far (nested rules) to near the light (fits,
                    // splits) above the point.
                    let height = match (round + k) % 3 {
                        0 => 0.05 + next(),
                        1 => 1.0 + 3.0 * next(),
                        _ => 6.0 + 6.0 * next(),
                    };
                    let corner = DVec3::new(-1.8 * next(), height, -1.8 * next());
                    let v = match k % 3 {
                        0 => {
                            let c = (corner + DVec3::new(1.0, 0.0, 1.0)).normalize();
                            n * (2.0 * n.dot(c)) - c
                        }
                        _ => DVec3::new(next() - 0.5, 0.2 + next(), next() - 0.5),
                    }
                    .normalize();
                    Lobe {
                        n,
                        v,
                        shininess: [1.0, 5.0, 20.0, 100.0, 500.0][(round + k) % 5],
                        corner,
                        edge_u: span_edges.0,
                        edge_v: span_edges.1,
                    }
                })
                .collect();
            // The light's square, to rounding, as the points see it.
            let eps = [0.0, 1e-17, -2e-16][round % 3];
            let square = [
                DVec2::new(0.0, eps),
                DVec2::new(1.0, 0.0),
                DVec2::new(1.0 + eps, 1.0),
                DVec2::new(0.0, 1.0),
            ];
            let mut pieces = Pieces::default();
            pieces.push(&square, 0.0);
            let visible = pieces.area();
            let asked: Vec<(&Lobe, f64)> = lobes.iter().map(|l| (l, visible)).collect();
            let mut out = [None; WHOLE_LANES];
            whole_light_specular(&span, &asked, &mut out);
            for (k, lobe) in lobes.iter().enumerate() {
                let (want, report) = specular_factor(lobe, &span, &pieces, &mut scratch);
                let Some((got, got_report)) = out[k] else {
                    alone += 1;
                    continue;
                };
                assert_eq!(got.to_bits(), want.to_bits(), "round {round} lobe {k}");
                assert_eq!(got_report.cells, report.cells);
                assert_eq!(got_report.error.to_bits(), report.error.to_bits());
                // The near field (the light's side above half the
                // distance less its reach) takes the fit; far, the nested
                // rules.
                let distance = (lobe.corner + DVec3::new(1.0, 0.0, 1.0)).length();
                if distance < 5.5 {
                    fitted += 1;
                } else if distance > 6.5 {
                    nested += 1;
                }
            }
        }
        // Every way: the nested rules, the near field's fit, and points
        // left to the one-point path.
        assert!(
            nested > 500 && fitted > 500 && alone > 500,
            "{nested} {fitted} {alone}"
        );
    }

    /// ∫ f over the convex polygon `poly` by a dense rule: its fan
    /// triangles each split `splits` times in four by their midpoints, and
    /// the collapsed-square product of the Gauss–Legendre rule `g` on each.
    fn dense_over(poly: &[DVec2], splits: u32, g: &[(f64, f64)], f: impl Fn(DVec2) -> f64) -> f64 {
        let mut triangles: Vec<[DVec2; 3]> = (1..poly.len() - 1)
            .map(|i| [poly[0], poly[i], poly[i + 1]])
            .collect();
        for _ in 0..splits {
            triangles = triangles
                .iter()
                .flat_map(|&[a, b, c]| {
                    let (ab, bc, ca) = ((a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5);
                    [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
                })
                .collect();
        }
        let mut sum = 0.0;
        for [a, b, c] in &triangles {
            let area = 0.5 * (*b - *a).perp_dot(*c - *a).abs();
            for &(ti, wi) in g {
                let u = (ti + 1.0) * 0.5;
                for &(tj, wj) in g {
                    let w = (tj + 1.0) * 0.5;
                    let p = *a + (*b - *a) * u + (*c - *b) * (u * w);
                    sum += f(p) * wi * wj * 0.25 * u * 2.0 * area;
                }
            }
        }
        sum
    }

    /// A random lobe of the 2 × 2 light seen from 0.2 to 8.2 below it
    /// (views near the mirror direction, anywhere, and grazing; shininess
    /// 1 to 2000) and a random cell of it down to the deepest level, or
    /// `None` where a corner of the cell is behind the surface or the view
    /// is (case `tried` picks the view and the shininess).
    fn random_cell(
        tried: usize,
        next: &mut impl FnMut() -> f64,
    ) -> Option<(Lobe, u32, DVec2, f64)> {
        let n = DVec3::new(next() - 0.5, 1.0, next() - 0.5).normalize();
        let height = 0.2 + 8.0 * next() * next();
        let corner = DVec3::new(-1.0 + next(), height, -1.0 + next());
        let centre = (corner + DVec3::new(1.0, 0.0, 1.0)).normalize();
        let mirror = n * (2.0 * n.dot(centre)) - centre;
        let jitter = DVec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * 0.6;
        let v = match tried % 5 {
            3 => DVec3::new(next() - 0.5, 0.3 + next(), next() - 0.5),
            // Grazing views (N·V from 0.02 to 0.3) in any direction:
            // the peak mostly beside the light, which is then seen
            // where the lobe is wider than at its peak (the cell's
            // narrow width of `CellView`).
            4 => {
                let t = DVec3::new(next() - 0.5, 0.0, next() - 0.5) + DVec3::X * 1e-3;
                t.reject_from(n).normalize() + n * (0.02 + 0.3 * next())
            }
            k => mirror + jitter * k as f64,
        }
        .normalize();
        let shininess = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 500.0, 2000.0][tried % 9];
        let lobe = Lobe {
            n,
            v,
            shininess,
            corner,
            edge_u: DVec3::new(2.0, 0.0, 0.0),
            edge_v: DVec3::new(0.0, 0.0, 2.0),
        };
        let depth = (next() * next() * (MAX_DEPTH + 1) as f64) as u32;
        let size = 0.5f64.powi(depth as i32);
        let cells = (1u32 << depth) as f64;
        let lo = DVec2::new(
            (next() * cells).floor() * size,
            (next() * cells).floor() * size,
        );
        let in_front = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
            .iter()
            .all(|&(x, y)| lobe.direction(lo.x + x * size, lo.y + y * size).dot(n) > 0.0);
        (in_front && n.dot(v) > 0.0).then_some((lobe, depth, lo, size))
    }

    /// `Ctx::nearest` against the nearest of a 65² grid of the cell's
    /// points (and no farther than the grid's spacing from it), on the
    /// square light and on a sheared one (a parallelogram, whose nearest
    /// point is not the foot clamped to the cell).
    #[test]
    fn a_cell_s_nearest_point_is_its_nearest() {
        let mut rng = Rng::new(18);
        let mut next = || rng.next_f64();
        let (mut tried, mut inside) = (0, 0);
        while tried < 2_000 {
            let Some((mut lobe, _, lo, size)) = random_cell(tried, &mut next) else {
                continue;
            };
            tried += 1;
            if tried % 2 == 0 {
                lobe.edge_v = DVec3::new(1.4 * (next() - 0.5), 0.0, 2.0);
            }
            let none = Pieces::default();
            let ctx = Ctx::new(&lobe, &LightSpan::new(lobe.edge_u, lobe.edge_v), &none);
            let got = ctx.nearest(lo, size);
            const STEPS: usize = 64;
            let mut grid = f64::INFINITY;
            for i in 0..=STEPS {
                for j in 0..=STEPS {
                    let (a, b) = (i as f64 / STEPS as f64, j as f64 / STEPS as f64);
                    grid = grid.min(lobe.direction(lo.x + a * size, lo.y + b * size).length());
                }
            }
            let spacing = size / STEPS as f64 * (lobe.edge_u.length() + lobe.edge_v.length());
            assert!(
                got <= grid * (1.0 + 1e-12),
                "case {tried}: {got} beyond the grid's {grid}"
            );
            assert!(
                got >= grid - spacing,
                "case {tried}: {got} below the grid's {grid} by more than {spacing}"
            );
            if (got - ctx.height).abs() <= 1e-12 * got {
                inside += 1;
            }
        }
        // Some cells hold the point's foot, most do not.
        assert!(inside > 20 && inside < tried / 2, "{inside} of {tried}");
    }

    #[test]
    fn nested_rules_of_a_whole_cell_keep_their_estimate() {
        let mut rng = Rng::new(15);
        let mut next = || rng.next_f64();
        let g = crate::render::math::gauss_legendre(64);
        let (mut tried, mut accepted, mut worst) = (0, 0, 0.0f64);
        while tried < 12_500 {
            let Some((lobe, depth, lo, size)) = random_cell(tried, &mut next) else {
                continue;
            };
            let (n, v, shininess) = (lobe.n, lobe.v, lobe.shininess);
            tried += 1;
            let none = Pieces::default();
            let ctx = Ctx::new(&lobe, &LightSpan::new(lobe.edge_u, lobe.edge_v), &none);
            let view = (depth < MAX_DEPTH).then(|| CellView::new(&ctx, lo, size));
            let Some((value, estimate)) = whole_cell(&ctx, lo, size, view.as_ref()) else {
                continue;
            };
            accepted += 1;
            let mut dense = 0.0;
            for qx in 0..2 {
                for qy in 0..2 {
                    for &(ti, wi) in &g {
                        for &(tj, wj) in &g {
                            let a = lo.x + size * (qx as f64 + (ti + 1.0) * 0.5) * 0.5;
                            let b = lo.y + size * (qy as f64 + (tj + 1.0) * 0.5) * 0.5;
                            let l = lobe.direction(a, b).normalize();
                            let h = (l + v).normalize_or_zero();
                            let f = n.dot(h).max(0.0).powf(shininess);
                            dense += f * wi * wj * 0.0625 * size * size;
                        }
                    }
                }
            }
            let err = (value - dense).abs();
            let area = size * size;
            assert!(err <= TOLERANCE * area, "{value} vs {dense}");
            assert!(
                err <= estimate + 5e-6 * area,
                "shininess {shininess}, depth {depth}: error {err:e} above the estimate {estimate:e}"
            );
            worst = worst.max(err / area);
        }
        assert!(accepted > 4000, "{accepted}");
        eprintln!(
            "nested rules: {accepted} of {tried} accepted, worst error {worst:e} of the cell's area"
        );
    }
    /// The low fit over part of a cell (the cell cut by a random line),
    /// wherever the cell passes the gates `cell` takes it behind and the
    /// fit its own estimate: the fit's integral over the part against the
    /// lobe's, both by the same dense rule (a fan of the part's triangles
    /// split 4³ times, 8² collapsed-square Gauss points on each), is within
    /// the estimate times the part's area (plus the f32 lobe's rounding).
    #[test]
    fn low_fits_of_partial_cells_keep_their_estimate() {
        use super::super::polygon::{HalfPlane, clip_into, twice_area};
        use super::{LOW, legendre, low_fit};
        let mut rng = Rng::new(17);
        let mut next = || rng.next_f64();
        let g = crate::render::math::gauss_legendre(8);
        let (mut tried, mut accepted, mut worst, mut worst_share) = (0, 0, 0.0f64, 0.0f64);
        while tried < 6_000 {
            let Some((lobe, depth, lo, size)) = random_cell(tried, &mut next) else {
                continue;
            };
            tried += 1;
            let none = Pieces::default();
            let ctx = Ctx::new(&lobe, &LightSpan::new(lobe.edge_u, lobe.edge_v), &none);
            if depth == MAX_DEPTH
                || CellView::new(&ctx, lo, size)
                    .nested_rules(&ctx, lo, size)
                    .is_none()
            {
                continue;
            }
            let Some((c, estimate)) = low_fit(&lobe, lo, size) else {
                continue;
            };
            let dir = DVec2::from_angle(std::f64::consts::TAU * next());
            let through = lo + DVec2::new(next(), next()) * size;
            let cell = [
                lo,
                lo + DVec2::new(size, 0.0),
                lo + DVec2::splat(size),
                lo + DVec2::new(0.0, size),
            ];
            let mut part = Vec::new();
            let cut = HalfPlane {
                n: dir,
                c: -dir.dot(through),
            };
            clip_into(&cell, cut, &mut part);
            let covered = 0.5 * twice_area(&part).abs();
            if part.len() < 3 || covered < 1e-3 * size * size {
                continue;
            }
            accepted += 1;
            let lobe_at = |p: DVec2| {
                let l = lobe.direction(p.x, p.y).normalize();
                let h = (l + lobe.v).normalize_or_zero();
                lobe.n.dot(h).max(0.0).powf(lobe.shininess)
            };
            let fit_at = |p: DVec2| {
                let x = (p - lo) / (0.5 * size) - DVec2::ONE;
                let (px, py) = (legendre(x.x, LOW - 1), legendre(x.y, LOW - 1));
                let mut sum = 0.0;
                for k in 0..LOW {
                    for l in 0..LOW {
                        sum += c[k][l] * px[k] * py[l];
                    }
                }
                sum
            };
            // Both by the same dense rule: the fit's error over the part.
            let difference = dense_over(&part, 3, &g, |p| fit_at(p) - lobe_at(p));
            let err = difference.abs();
            assert!(
                err <= (estimate + 5e-6) * covered,
                "shininess {}, depth {depth}: error {:e} of the part above the estimate {estimate:e}",
                lobe.shininess,
                err / covered
            );
            worst = worst.max(err / covered);
            // Above the f32 lobe's rounding, the share of the estimate.
            if err > 1e-7 * covered {
                worst_share = worst_share.max(err / (estimate * covered));
            }
        }
        assert!(accepted > 1000, "{accepted}");
        eprintln!(
            "low fits: {accepted} of {tried} cut cells, worst error {worst:e} of the part's area; \
             errors above 1e-7 of it at most {:.1} % of the estimate",
            100.0 * worst_share
        );
    }

    /// The whole cubature over part of the light, from points near it (a
    /// hundredth to a quarter of the light's side above it, so that the
    /// light is also seen at grazing angles), against a dense integration:
    /// the error stays within the estimate the report gives (plus the f32
    /// lobe's rounding). Written to check the partial cells' fit, whose
    /// estimate has no near-field gate; what it found instead was a lobe
    /// narrowed at a grazing view (N·V = 0.035) that fell between the
    /// nested rules' nodes of whole cells: an error 2 500 times their
    /// estimate, 4e-5 of the factor, before `Ctx::narrow`.
    #[test]
    fn partial_cells_keep_their_estimate_near_the_point() {
        use super::super::polygon::{HalfPlane, Pieces, clip_into, twice_area};
        use super::{CubatureScratch, specular_factor};
        let mut rng = Rng::new(16);
        let mut next = || rng.next_f64();
        let g = crate::render::math::gauss_legendre(12);
        let mut scratch = CubatureScratch::default();
        let (mut worst, mut checked) = (0.0f64, 0);
        for case in 0..240 {
            let n = DVec3::new(0.3 * (next() - 0.5), 1.0, 0.3 * (next() - 0.5)).normalize();
            let height = 0.02 * 25f64.powf(next());
            let corner = DVec3::new(-2.0 * next(), height, -2.0 * next());
            let centre = (corner + DVec3::new(1.0, 0.0, 1.0)).normalize();
            let mirror = n * (2.0 * n.dot(centre)) - centre;
            let jitter = DVec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * 0.5;
            let v = (mirror + jitter * (case % 3) as f64).normalize();
            if n.dot(v) <= 0.0 {
                continue;
            }
            let shininess = [1.0, 5.0, 20.0, 100.0, 500.0, 2000.0][case % 6];
            let lobe = Lobe {
                n,
                v,
                shininess,
                corner,
                edge_u: DVec3::new(2.0, 0.0, 0.0),
                edge_v: DVec3::new(0.0, 0.0, 2.0),
            };
            // The light's square in front of the surface, cut by one or
            // two random lines (partial cells along them).
            let mut poly = vec![DVec2::ZERO, DVec2::X, DVec2::ONE, DVec2::Y];
            let mut cuts = vec![HalfPlane {
                n: DVec2::new(lobe.edge_u.dot(n), lobe.edge_v.dot(n)),
                c: corner.dot(n),
            }];
            for _ in 0..1 + case % 2 {
                let dir = DVec2::from_angle(std::f64::consts::TAU * next());
                let through = DVec2::new(next(), next());
                cuts.push(HalfPlane {
                    n: dir,
                    c: -dir.dot(through),
                });
            }
            for h in cuts {
                let mut out = Vec::new();
                clip_into(&poly, h, &mut out);
                poly = out;
            }
            if poly.len() < 3 || twice_area(&poly) < 1e-3 {
                continue;
            }
            let mut pieces = Pieces::default();
            pieces.push(&poly, 0.0);
            let (value, report) = specular_factor(
                &lobe,
                &LightSpan::new(lobe.edge_u, lobe.edge_v),
                &pieces,
                &mut scratch,
            );
            // Dense: each fan triangle split in 4⁵ by its midpoints, 12²
            // collapsed-square Gauss points on each.
            let f = |p: DVec2| {
                let l = lobe.direction(p.x, p.y).normalize();
                let h = (l + v).normalize_or_zero();
                n.dot(h).max(0.0).powf(shininess)
            };
            let dense = dense_over(&poly, 5, &g, f);
            let err = (value - dense).abs();
            checked += 1;
            assert!(
                err <= report.error + 5e-6,
                "case {case}: height {height:.3}, shininess {shininess}: {value} vs {dense}, \
                 error {err:e} above the estimate {:e}",
                report.error
            );
            assert!(err <= TOLERANCE, "case {case}: error {err:e}");
            worst = worst.max(err);
        }
        assert!(checked > 100, "{checked}");
        eprintln!("partial cells near the point: {checked} checked, worst error {worst:e}");
    }
}
