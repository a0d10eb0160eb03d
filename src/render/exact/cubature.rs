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
//! integrates exactly. So the work follows the integrand's shape, not the
//! number of shadow pieces: a cell wholly visible is just its node sum.
//!
//! Error: each accepted cell's fit error is ≤ [`TOLERANCE`] by the
//! estimate, and the cells cover the light once, so the factor's error is
//! estimated ≤ [`TOLERANCE`] (absolute; the factor lies in [0, 1]).

use std::sync::OnceLock;

use glam::{DVec2, DVec3};

use super::polygon::{HalfPlane, Pieces, clip_into, twice_area};
use crate::render::math::avx2_dispatch;

/// Nodes per axis of a cell (the fit has degree `ORDER − 1`).
const ORDER: usize = 8;
/// Deepest split of the light's square (cells of 1/256 of its side).
const MAX_DEPTH: u32 = 8;
/// Estimated error of the specular factor above which a cell is split.
pub const TOLERANCE: f64 = 1e-5;

/// The integrand: max(0, n·H)^s at light point (a, b), in the light's frame
/// seen from the shadow point.
#[derive(Debug, Clone, Copy)]
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

avx2_dispatch!(
    /// The integrand at the light points (a\[j\], b\[j\]), in f64 (the
    /// rounding of f32, ~1e-7 per value, would put a floor under the
    /// coefficients' estimate), written for the vectorizer like the
    /// `sampled` model's loops.
    fn lobe_at_nodes(l: &Lobe, a: &[f64; NODES], b: &[f64; NODES], out: &mut [f64; NODES])
        => lobe_at_nodes_generic
);

#[inline(always)]
fn lobe_at_nodes_generic(l: &Lobe, a: &[f64; NODES], b: &[f64; NODES], out: &mut [f64; NODES]) {
    let (c, u, w, n, v, s) = (l.corner, l.edge_u, l.edge_v, l.n, l.v, l.shininess);
    for j in 0..NODES {
        let x = c.x + u.x * a[j] + w.x * b[j];
        let y = c.y + u.y * a[j] + w.y * b[j];
        let z = c.z + u.z * a[j] + w.z * b[j];
        let inv = 1.0 / (x * x + y * y + z * z).sqrt();
        let (hx, hy, hz) = (x * inv + v.x, y * inv + v.y, z * inv + v.z);
        let h2 = hx * hx + hy * hy + hz * hz;
        // N·H / |H|; H = 0 (light exactly behind the viewer) gives 0.
        let cs = ((n.x * hx + n.y * hy + n.z * hz) / h2.sqrt()).max(0.0);
        let cs = if h2 > 0.0 { cs } else { 0.0 };
        out[j] = pow64(cs, s);
    }
}

/// x^y for x in [0, 1] and y > 0 in f64 without a libm call (so that the
/// node loop vectorizes): exp2(y · log2 x) with series for both, relative
/// error ~1e-14 · max(1, |y · log2 x|); inputs below the smallest normal
/// give 0.
#[inline(always)]
fn pow64(x: f64, y: f64) -> f64 {
    let bits = x.to_bits() as i64;
    let mut e = ((bits >> 52) & 0x7ff) - 1023;
    let mut m = f64::from_bits(((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000) as u64);
    let big = m > std::f64::consts::SQRT_2;
    m = if big { m * 0.5 } else { m };
    e += big as i64;
    // ln m = 2 atanh(t), t = (m − 1)/(m + 1), |t| ≤ 0.172.
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    let mut series = 1.0 / 17.0;
    for k in [15.0, 13.0, 11.0, 9.0, 7.0, 5.0, 3.0, 1.0] {
        series = series * t2 + 1.0 / k;
    }
    let log2_x = e as f64 + 2.0 * t * series * std::f64::consts::LOG2_E;
    let z = (y * log2_x).max(-1022.0);
    // 2^z = 2^k · e^(f·ln 2), k = round(z) by adding and removing 1.5·2⁵².
    const ROUNDER: f64 = 6_755_399_441_055_744.0;
    let r = z + ROUNDER;
    let k = r.to_bits() as i64 - ROUNDER.to_bits() as i64;
    let f = (z - (r - ROUNDER)) * std::f64::consts::LN_2;
    let mut p = 1.0 / 479_001_600.0;
    for d in [
        39_916_800.0,
        3_628_800.0,
        362_880.0,
        40_320.0,
        5_040.0,
        720.0,
        120.0,
        24.0,
        6.0,
        2.0,
        1.0,
        1.0,
    ] {
        p = p * f + 1.0 / d;
    }
    let scaled = p * f64::from_bits(((k + 1023) << 52) as u64);
    if x >= f64::MIN_POSITIVE && z > -1022.0 {
        scaled
    } else {
        0.0
    }
}

/// Gauss–Legendre nodes and weights on [−1, 1], and the Legendre values
/// times weights at them: `pw[k][i] = P_k(x_i) w_i`.
struct Rule {
    x: [f64; ORDER],
    w: [f64; ORDER],
    pw: [[f64; ORDER]; ORDER],
}

fn rule() -> &'static Rule {
    static RULE: OnceLock<Rule> = OnceLock::new();
    RULE.get_or_init(|| {
        let n = ORDER;
        let mut x = [0.0; ORDER];
        let mut w = [0.0; ORDER];
        for i in 0..n {
            let mut t = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, t);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * t * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                dp = n as f64 * (t * p1 - p0) / (t * t - 1.0);
                let dx = p1 / dp;
                t -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            x[i] = t;
            w[i] = 2.0 / ((1.0 - t * t) * dp * dp);
        }
        let mut pw = [[0.0; ORDER]; ORDER];
        for i in 0..n {
            let p = legendre(x[i]);
            for k in 0..n {
                pw[k][i] = p[k] * w[i];
            }
        }
        Rule { x, w, pw }
    })
}

/// P_0 … P_ORDER at x.
#[inline]
fn legendre_plus(x: f64) -> [f64; ORDER + 1] {
    let mut p = [0.0; ORDER + 1];
    p[0] = 1.0;
    p[1] = x;
    for k in 1..ORDER {
        p[k + 1] = ((2 * k + 1) as f64 * x * p[k] - k as f64 * p[k - 1]) / (k + 1) as f64;
    }
    p
}

#[inline]
fn legendre(x: f64) -> [f64; ORDER] {
    let p = legendre_plus(x);
    std::array::from_fn(|k| p[k])
}

/// R_k(x) = ∫_{−1}^x P_k for k < ORDER.
#[inline]
fn legendre_integrals(x: f64) -> [f64; ORDER] {
    let p = legendre_plus(x);
    std::array::from_fn(|k| {
        if k == 0 {
            x + 1.0
        } else {
            (p[k + 1] - p[k - 1]) / (2 * k + 1) as f64
        }
    })
}

/// Scratch of the cubature: the visible pieces clipped to each level's cell.
#[derive(Debug, Clone, Default)]
pub struct CubatureScratch {
    levels: Vec<Pieces>,
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

/// ∫ f da db over the pieces (in the light's (a, b) coordinates, inside
/// the unit square): the specular factor of the visible region.
pub fn specular_factor(
    lobe: &Lobe,
    pieces: &Pieces,
    s: &mut CubatureScratch,
) -> (f64, CubatureReport) {
    let mut report = CubatureReport::default();
    if pieces.is_empty() {
        return (0.0, report);
    }
    if s.levels.len() < MAX_DEPTH as usize + 1 {
        s.levels
            .resize_with(MAX_DEPTH as usize + 1, Pieces::default);
    }
    s.levels[0].clone_from(pieces);
    // The lobe's width in L (cos^s θ_H ≈ exp(−s θ_H²/2), θ_L ≈ 2 θ_H) and
    // the mirror direction, where it peaks.
    let width = 2.0 / lobe.shininess.max(1.0).sqrt();
    let mirror = lobe.n * (2.0 * lobe.n.dot(lobe.v)) - lobe.v;
    let ctx = Ctx {
        lobe,
        width,
        mirror: mirror.normalize_or_zero(),
        side: lobe.edge_u.length().max(lobe.edge_v.length()),
    };
    let total = cell(&ctx, s, 0, DVec2::ZERO, 1.0, &mut report);
    (total, report)
}

struct Ctx<'a> {
    lobe: &'a Lobe,
    width: f64,
    mirror: DVec3,
    /// The light's longer edge.
    side: f64,
}

/// ∫ over the visible part of the cell [lo, lo + size]² (its pieces in
/// `s.levels[depth]`).
// Tensor nodes and coefficients: index loops read best.
#[allow(clippy::needless_range_loop)]
fn cell(
    ctx: &Ctx,
    s: &mut CubatureScratch,
    depth: u32,
    lo: DVec2,
    size: f64,
    report: &mut CubatureReport,
) -> f64 {
    let d = depth as usize;
    let covered: f64 = s.levels[d].iter().map(twice_area).sum::<f64>() * 0.5;
    if covered <= 0.0 {
        return 0.0;
    }
    let full = covered >= size * size * (1.0 - 1e-12);
    let r = rule();
    let half = 0.5 * size;
    let lobe = ctx.lobe;

    // The fit's coefficients c[k][l] (x along a, y along b).
    let (mut na, mut nb, mut nf) = ([0.0; NODES], [0.0; NODES], [0.0; NODES]);
    for i in 0..ORDER {
        for j in 0..ORDER {
            na[i * ORDER + j] = lo.x + (r.x[i] + 1.0) * half;
            nb[i * ORDER + j] = lo.y + (r.x[j] + 1.0) * half;
        }
    }
    lobe_at_nodes(lobe, &na, &nb, &mut nf);
    let f: [[f64; ORDER]; ORDER] =
        std::array::from_fn(|i| std::array::from_fn(|j| nf[i * ORDER + j]));
    report.cells += 1;
    let mut t = [[0.0; ORDER]; ORDER];
    for i in 0..ORDER {
        for l in 0..ORDER {
            t[i][l] = (0..ORDER).map(|j| f[i][j] * r.pw[l][j]).sum();
        }
    }
    let mut c = [[0.0; ORDER]; ORDER];
    let mut tail = 0.0;
    for k in 0..ORDER {
        for l in 0..ORDER {
            let norm = (2 * k + 1) as f64 * (2 * l + 1) as f64 * 0.25;
            c[k][l] = norm * (0..ORDER).map(|i| r.pw[k][i] * t[i][l]).sum::<f64>();
            if k.max(l) + 1 == ORDER {
                tail += c[k][l].abs();
            }
        }
    }

    let split = depth < MAX_DEPTH && (tail > TOLERANCE || lobe_unresolved(ctx, lo, size));
    if split {
        let mut total = 0.0;
        for (dx, dy) in [(0.0, 0.0), (half, 0.0), (0.0, half), (half, half)] {
            let child = lo + DVec2::new(dx, dy);
            clip_level(s, d, child, half);
            total += cell(ctx, s, depth + 1, child, half, report);
        }
        return total;
    }
    // The accepted cell's share of the estimated error.
    report.error += tail * covered;
    let jac = half * half;
    if full {
        // ∫ over the whole cell of the fit: the node sum.
        return 4.0 * c[0][0] * jac;
    }
    // Green's theorem over each piece, in the cell's [−1, 1]² coordinates.
    let mut total = 0.0;
    let to_cell = |p: DVec2| (p - lo) / half - DVec2::ONE;
    for piece in s.levels[d].iter() {
        let k = piece.len();
        for e in 0..k {
            let (p0, p1) = (to_cell(piece[e]), to_cell(piece[(e + 1) % k]));
            let dy = p1.y - p0.y;
            if dy == 0.0 {
                continue;
            }
            let mut edge = 0.0;
            for g in 0..ORDER {
                // The rule on [0, 1].
                let (tg, wg) = ((r.x[g] + 1.0) * 0.5, r.w[g] * 0.5);
                let p = p0 + (p1 - p0) * tg;
                let rk = legendre_integrals(p.x);
                let pl = legendre(p.y);
                let mut m = 0.0;
                for kk in 0..ORDER {
                    let row: f64 = (0..ORDER).map(|l| c[kk][l] * pl[l]).sum();
                    m += rk[kk] * row;
                }
                edge += wg * m;
            }
            total += edge * dy;
        }
    }
    total * jac
}

/// A cell too coarse for a narrow lobe that may lie on it: its nodes are
/// farther apart than half the lobe's width, and the mirror direction
/// passes within its angular size plus six widths (beyond which the lobe
/// is below e⁻¹⁸ of its peak).
fn lobe_unresolved(ctx: &Ctx, lo: DVec2, size: f64) -> bool {
    let centre = ctx.lobe.direction(lo.x + 0.5 * size, lo.y + 0.5 * size);
    let dist = centre.length();
    let angular = size * ctx.side * std::f64::consts::SQRT_2 / dist;
    if angular / ORDER as f64 <= 0.5 * ctx.width {
        return false;
    }
    let cos = (centre / dist).dot(ctx.mirror).clamp(-1.0, 1.0);
    cos.acos() < angular + 6.0 * ctx.width
}

/// The pieces of level `d` clipped to the cell [lo, lo + size]², into
/// level d + 1.
fn clip_level(s: &mut CubatureScratch, d: usize, lo: DVec2, size: f64) {
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
    let (parent, out) = (&head[d], &mut tail[0]);
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
    use super::pow64;

    #[test]
    fn pow64_matches_powf() {
        let mut worst: f64 = 0.0;
        for i in 1..=4000 {
            let x = i as f64 / 4000.0;
            for y in [0.5, 1.0, 3.0, 20.0, 100.0, 500.0, 1e4] {
                let want = x.powf(y);
                let got = pow64(x, y);
                if want < 1e-300 {
                    assert!(got < 1e-290, "{x}^{y}: {got}");
                    continue;
                }
                let rel = (got - want).abs() / want;
                let bound = 1e-13 * (1.0 + (y * x.log2()).abs());
                assert!(rel < bound, "{x}^{y}: {got} vs {want} ({rel:e})");
                worst = worst.max(rel);
            }
        }
        assert_eq!(pow64(0.0, 20.0), 0.0);
        assert_eq!(pow64(1.0, 500.0), 1.0);
        eprintln!("pow64 worst relative error {worst:e}");
    }
}
