//! How light is computed at one hit point: the report's Phong model with
//! Blinn's half vector, under the area-light models (`exact` in its own
//! folder).

use glam::{DVec3, Vec3};

use super::analytic;
use super::exact::{CircleFit, ExactFactors, ExactPoint, ExactStep, exact_step};
use super::math::{
    WIDE_POINTS, avx2_dispatch, avx512_dispatch, pow_approx, pow_from_log2, pow_log2,
};
use super::rng::Rng;
use super::sampling::Pattern;
use super::scene::Scene;
use super::scene_file::AreaLightModel;
use super::settings::RenderSettings;
use super::shading_params::{LightColours, Material, ShadingParams};
use super::shadow::{self, ShadowBuffers, ShadowQuery};
use super::stats::RayStats;

/// A surface point being shaded.
pub struct ShadingPoint<'a> {
    pub point: DVec3,
    /// Unit shading normal, flipped to face the incoming ray.
    pub normal: DVec3,
    /// Unit direction towards the viewer (against the incoming ray).
    pub view: DVec3,
    /// The point's shadow test, kept whole so that it is handed on without
    /// a copy: where the shadow rays start (`point`, or for smooth
    /// triangles the point lifted off the flat face, see
    /// `geometry/triangle.rs`), the unit geometric normal flipped like
    /// `normal` (what decides which light points lie behind the surface),
    /// the hit object and its side.
    pub shadow: ShadowQuery,
    pub material: &'a Material,
    /// `material`'s index among the shading parameters' materials.
    pub material_index: u32,
}

/// The light-averaged factors of one hit point, before any colour: the
/// diffuse factor max(0, N·L) and the specular factor max(0, N·H)^shininess
/// averaged over the light with their visibility. The local colour is
/// linear in them ([`local_colour`]), which is what lets an edit of a
/// colour or a term recombine cached factors instead of tracing.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LightTerms {
    pub diffuse: f32,
    pub specular: f32,
}

/// Which factors a hit point needs. A render that keeps its factors for
/// later edits needs both; a one-shot render skips a term whose colour
/// product is zero.
#[derive(Debug, Clone, Copy)]
pub struct Needs {
    pub diffuse: bool,
    pub specular: bool,
}

impl Needs {
    pub const ALL: Needs = Needs {
        diffuse: true,
        specular: true,
    };

    /// The factors whose colour products are not zero.
    #[inline]
    pub fn of(m: &Material, light: &LightColours, terms: Vec3) -> Needs {
        Needs {
            diffuse: m.diffuse * light.diffuse * terms.y != Vec3::ZERO,
            specular: m.specular * light.specular * terms.z != Vec3::ZERO,
        }
    }
}

/// The Phong sum of one hit point: ambient plus the diffuse and specular
/// colours times their light factors. The only place the three terms meet,
/// for one-shot renders and cached recombinations alike (the same f32
/// operations in the same order, so the same bits).
#[inline]
pub fn local_colour(m: &Material, light: &LightColours, terms: Vec3, factors: LightTerms) -> Vec3 {
    PhongColours::new(m, light, terms).colour(factors)
}

/// A material's three colours times the light's and the term strengths:
/// what [`local_colour`] multiplies the light factors by. A replay of
/// recorded hits computes them once per material instead of once per hit.
#[derive(Debug, Clone, Copy)]
pub struct PhongColours {
    ambient: Vec3,
    kd: Vec3,
    ks: Vec3,
}

impl PhongColours {
    #[inline]
    pub fn new(m: &Material, light: &LightColours, terms: Vec3) -> PhongColours {
        PhongColours {
            ambient: m.ambient * light.ambient * terms.x,
            kd: m.diffuse * light.diffuse * terms.y,
            ks: m.specular * light.specular * terms.z,
        }
    }

    /// The Phong sum for one hit point's light factors.
    #[inline]
    pub fn colour(&self, factors: LightTerms) -> Vec3 {
        self.ambient + (self.kd * factors.diffuse + self.ks * factors.specular)
    }
}

/// The local colour (without the reflection) of one hit point, computing
/// only the factors its colours need.
#[allow(clippy::too_many_arguments)]
pub fn shade(
    scene: &Scene,
    settings: &RenderSettings,
    shading: &ShadingParams,
    sp: &ShadingPoint,
    pattern: &Pattern,
    rng: &mut Rng,
    buf: &mut ShadowBuffers,
    stats: &mut RayStats,
) -> Vec3 {
    let (m, light) = (sp.material, &shading.light);
    let needs = Needs::of(m, light, settings.terms);
    let factors = light_terms(scene, settings, sp, needs, pattern, rng, buf, stats);
    local_colour(m, light, settings.terms, factors)
}

/// The light factors of one hit point: zero where the point is behind the
/// light; a factor not needed is left at zero.
#[allow(clippy::too_many_arguments)]
pub fn light_terms(
    scene: &Scene,
    s: &RenderSettings,
    sp: &ShadingPoint,
    needs: Needs,
    pattern: &Pattern,
    rng: &mut Rng,
    buf: &mut ShadowBuffers,
    stats: &mut RayStats,
) -> LightTerms {
    match light_points(
        scene,
        s,
        sp,
        needs,
        pattern,
        rng,
        buf,
        stats,
        Shadows::Traced,
    )
    .known(buf)
    {
        Some(factors) => factors,
        None => model_terms(scene, s, sp, needs, pattern.count(), buf),
    }
}

/// The light factors of the `exact` model's factors.
#[inline(always)]
pub(crate) fn exact_terms(f: ExactFactors) -> LightTerms {
    LightTerms {
        diffuse: f.diffuse as f32,
        specular: f.specular as f32,
    }
}

/// What [`light_points`] found.
pub(crate) enum Lit {
    /// The factors, without light points (behind the light, not needed,
    /// or the `exact` model).
    Known(LightTerms),
    /// The `exact` model's point that sees the whole light above its
    /// horizon, left in the buffers' exact scratch: its factors from
    /// [`WholeLight::factors`](super::exact::WholeLight::factors), or side
    /// by side with others' ([`WholeLights`](super::exact::WholeLights)).
    Whole,
    /// The light points are in the buffers, and with [`Shadows::Traced`]
    /// their visibility, for [`model_terms`].
    Points,
}

impl Lit {
    /// The factors, unless they wait for the light points: a whole-light
    /// point's taken now, alone.
    #[inline(always)]
    pub(crate) fn known(self, buf: &mut ShadowBuffers) -> Option<LightTerms> {
        match self {
            Lit::Known(factors) => Some(factors),
            Lit::Whole => Some(exact_terms(buf.exact.whole_point().factors(&mut buf.exact))),
            Lit::Points => None,
        }
    }
}

/// Whether [`light_points`] traces the shadow rays of the points it draws.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Shadows {
    Traced,
    /// Left to the caller (`shadow::HitLanes`: the `sampled` model with
    /// shadows on).
    Later,
}

avx2_dispatch!(
    /// The first part of [`light_terms`]: the light points of one hit point
    /// and their visibility, unless the factors are known without them.
    /// Compiled for AVX2 as a whole where the CPU has it, the shadow culling
    /// inlined: one feature check per hit point, and no separate kernel to
    /// hand the shadow query to.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn light_points(
        scene: &Scene,
        s: &RenderSettings,
        sp: &ShadingPoint,
        needs: Needs,
        pattern: &Pattern,
        rng: &mut Rng,
        buf: &mut ShadowBuffers,
        stats: &mut RayStats,
        shadows: Shadows,
    ) -> Lit => light_points_generic
);

/// [`light_points`] inlined into the caller, compiled for its CPU
/// features (the same operations, so the same bits).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn light_points_generic(
    scene: &Scene,
    s: &RenderSettings,
    sp: &ShadingPoint,
    needs: Needs,
    pattern: &Pattern,
    rng: &mut Rng,
    buf: &mut ShadowBuffers,
    stats: &mut RayStats,
    shadows: Shadows,
) -> Lit {
    let m = sp.material;
    let query = &sp.shadow;
    if !scene.light.illuminates(sp.point) {
        return Lit::Known(LightTerms::default());
    }
    let (need_d, need_s) = (needs.diffuse, needs.specular);
    let count = pattern.count();
    if !(need_d || need_s) && s.skip {
        stats.shadow_unneeded += count as u64;
        return Lit::Known(LightTerms::default());
    }

    if s.model == AreaLightModel::Exact {
        let p = ExactPoint {
            shadow_point: query.point,
            normal: sp.normal,
            geometric: query.normal,
            view: sp.view,
            shininess: m.shininess as f64,
            object: query.object,
            inside: query.inside,
            shadows: s.shadows,
        };
        match exact_step(scene, &p, need_s, CircleFit::SameArea, &mut buf.exact) {
            Ok(ExactStep::Done(f)) => {
                stats.exact_hits += 1;
                return Lit::Known(exact_terms(f));
            }
            Ok(ExactStep::Whole) => {
                stats.exact_hits += 1;
                return Lit::Whole;
            }
            // Outside what the model does exactly: the `analytic` estimate.
            Err(_) => stats.exact_fallbacks += 1,
        }
    }

    fill_light_points(pattern, rng, buf);
    match shadows {
        Shadows::Traced => shadow::visibility_inline(scene, s, query, count, buf, stats),
        Shadows::Later => debug_assert!(s.model == AreaLightModel::Sampled && s.shadows),
    }
    Lit::Points
}

/// The second part of [`light_terms`]: the factors of the model from the
/// `count` light points and their visibility in `buf`.
pub(crate) fn model_terms(
    scene: &Scene,
    s: &RenderSettings,
    sp: &ShadingPoint,
    needs: Needs,
    count: usize,
    buf: &mut ShadowBuffers,
) -> LightTerms {
    let m = sp.material;
    let (need_d, need_s) = (needs.diffuse, needs.specular);
    let n = sp.normal.as_vec3();
    let v = sp.view.as_vec3();
    let (diffuse, specular) = match s.model {
        AreaLightModel::Sampled => {
            let t = sampled_terms(n, v, m.shininess, need_s, count, buf);
            (t.diffuse, t.specular)
        }
        AreaLightModel::Analytic | AreaLightModel::Exact => {
            // Ratio estimator (Heitz, Hill & McGuire 2018): the exact
            // unshadowed diffuse average times the visible share of the
            // sampled integrand. Noise-free wherever the light is wholly
            // visible or wholly hidden. The specular term has no closed form
            // (`analytic::specular_area_average`, a test-only quadrature,
            // shows what it converges to) and stays sampled.
            let t = sampled_terms(n, v, m.shininess, need_s, count, buf);
            let light = &scene.light.shape;
            let exact = if need_d {
                analytic::diffuse_area_average(
                    sp.point,
                    sp.normal,
                    light.corner,
                    light.edge_u,
                    light.edge_v,
                ) as f32
            } else {
                0.0
            };
            // All sampled points below the horizon: no weights, so fall back
            // to the plain visible fraction.
            let ratio = if t.unshadowed_diffuse > 0.0 {
                t.diffuse / t.unshadowed_diffuse
            } else {
                buf.vis[..count].iter().sum::<f32>() / count as f32
            };
            (exact * ratio, t.specular)
        }
        AreaLightModel::NearestPoint => {
            let fraction = visible_fraction(buf, count);
            let (d, sp_) = nearest_point_terms(scene, sp);
            (d * fraction, sp_ * fraction)
        }
    };
    LightTerms { diffuse, specular }
}

/// Draws a hit point's light points into `buf.a`/`buf.b`. A fixed pattern
/// (the grid) is the same at every hit point: it is filled once.
#[inline]
fn fill_light_points(pattern: &Pattern, rng: &mut Rng, buf: &mut ShadowBuffers) {
    let key = (pattern.sampling, pattern.shadow_rays);
    if !(pattern.is_fixed() && buf.filled == Some(key)) {
        pattern.fill(rng, &mut buf.a, &mut buf.b);
        buf.filled = pattern.is_fixed().then_some(key);
    }
}

/// Whether any of the first `count` light points is visible.
#[inline]
pub(crate) fn any_visible(buf: &ShadowBuffers, count: usize) -> bool {
    let vis = &buf.vis[..count];
    if count <= 16 {
        return vis.iter().any(|&v| v != 0.0);
    }
    // Sixteen points at a time, each block without a branch per point: one
    // by one, a hit whose first points are hidden or face away paid a
    // compare and a branch for each (the blocks' set-up costs more than
    // that below sixteen points).
    vis.chunks(16)
        .any(|block| block.iter().fold(false, |any, &v| any | (v != 0.0)))
}

/// Share of the first `count` light points that are visible.
#[inline]
pub fn visible_fraction(buf: &ShadowBuffers, count: usize) -> f32 {
    let visible: f32 = buf.vis[..count].iter().sum();
    visible / count as f32
}

/// `sampled` model: the diffuse factor max(0, N·L) and the specular factor
/// max(0, N·H)^shininess averaged over the light points, each weighted by
/// its visibility.
///
/// Written for the vectorizer: one branch-free loop over the points that
/// writes each one's contributions, then a sum in a fixed order — so the
/// result does not depend on whether visibility came from tracing or
/// skipping. The buffers are padded to a multiple of eight with invisible
/// points. From [`WIDE_POINTS`] points on, sixteen lanes where the CPU has
/// them: the same operations lane by lane, so the same bits, in about half
/// the instructions (the power's polynomials are most of the loop).
pub(crate) fn sampled_terms(
    n: Vec3,
    v: Vec3,
    shininess: f32,
    need_s: bool,
    count: usize,
    buf: &mut ShadowBuffers,
) -> SampledTerms {
    // No point visible (behind the surface or in shadow): every
    // contribution is visibility 0 times a finite factor, so both sums are
    // +0 — the loop's answer, without the loop. (The ratio estimator gets 0
    // from either of its branches.)
    if !any_visible(buf, count) {
        return SampledTerms {
            diffuse: 0.0,
            unshadowed_diffuse: 0.0,
            specular: 0.0,
        };
    }
    sampled_terms_any(n, v, shininess, need_s, count, buf)
}

avx512_dispatch!(
    /// [`sampled_terms`] of a hit point with some light point visible.
    fn sampled_terms_any(
        n: Vec3,
        v: Vec3,
        shininess: f32,
        need_s: bool,
        count: usize,
        buf: &mut ShadowBuffers,
    ) -> SampledTerms => sampled_terms_generic if count >= WIDE_POINTS
);

#[inline(always)]
fn sampled_terms_generic(
    n: Vec3,
    v: Vec3,
    shininess: f32,
    need_s: bool,
    count: usize,
    buf: &mut ShadowBuffers,
) -> SampledTerms {
    let padded = count.next_multiple_of(8);
    let terms = PointTerms {
        f: &mut buf.term_f[..padded],
        d: &mut buf.term_d[..padded],
        s: &mut buf.term_s[..padded],
    };
    point_terms_generic(
        n, v, shininess, need_s, &buf.dx, &buf.dy, &buf.dz, &buf.vis, terms,
    );
    let inv_count = 1.0 / count as f32;
    if !need_s {
        let [d, f] = sequential_sums([&buf.term_d[..count], &buf.term_f[..count]]);
        return SampledTerms {
            diffuse: d * inv_count,
            unshadowed_diffuse: f * inv_count,
            specular: 0.0,
        };
    }
    let [d, f, s] = sequential_sums([
        &buf.term_d[..count],
        &buf.term_f[..count],
        &buf.term_s[..count],
    ]);
    SampledTerms {
        diffuse: d * inv_count,
        unshadowed_diffuse: f * inv_count,
        specular: s * inv_count,
    }
}

/// Where [`point_terms`] writes each light point's contributions (slices
/// of one length, a multiple of eight).
pub(crate) struct PointTerms<'a> {
    /// max(0, N·L) without visibility.
    pub(crate) f: &'a mut [f32],
    /// max(0, N·L) times visibility.
    pub(crate) d: &'a mut [f32],
    /// max(0, N·H)^shininess times visibility (left as it was without
    /// `need_s`).
    pub(crate) s: &'a mut [f32],
}

avx512_dispatch!(
    /// Each light point's contributions of one hit point, from its
    /// directions and visibility (as [`sampled_terms`] computes them, so
    /// the same bits), with the widest vectors the CPU has.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn point_terms(
        n: Vec3,
        v: Vec3,
        shininess: f32,
        need_s: bool,
        dx: &[f32],
        dy: &[f32],
        dz: &[f32],
        vis: &[f32],
        out: PointTerms<'_>,
    ) => point_terms_generic if out.d.len() >= WIDE_POINTS
);

/// Written for the vectorizer: one branch-free loop over the points.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn point_terms_generic(
    n: Vec3,
    v: Vec3,
    shininess: f32,
    need_s: bool,
    dx: &[f32],
    dy: &[f32],
    dz: &[f32],
    vis: &[f32],
    out: PointTerms<'_>,
) {
    let padded = out.d.len();
    let (dx, dy, dz, vis) = (&dx[..padded], &dy[..padded], &dz[..padded], &vis[..padded]);
    let (term_f, term_d) = (&mut out.f[..padded], &mut out.d[..padded]);
    if !need_s {
        for j in 0..padded {
            let (x, y, z) = (dx[j], dy[j], dz[j]);
            let inv = 1.0 / (x * x + y * y + z * z).sqrt();
            let f = ((n.x * x + n.y * y + n.z * z) * inv).max(0.0);
            term_f[j] = f;
            term_d[j] = vis[j] * f;
        }
        return;
    }
    // A point's specular factor is one long chain of dependent operations
    // (two square roots and three divisions, the logarithm's and the
    // exponential's polynomials): about 200 cycles from its direction to
    // its power, against some 50 of work per vector. In one loop the CPU
    // could overlap only two vectors' chains (its window of instructions in
    // flight is full), so the loop waited on latency. Three loops, each a
    // third of the chain, overlap enough vectors to keep the units busy:
    // the same operations lane by lane (the values pass through the
    // specular row exactly), so the same bits.
    let term_s = &mut out.s[..padded];
    // The diffuse terms, and the cosines of the half vectors (sharing each
    // point's 1 / |L|, a square root and a division).
    for j in 0..padded {
        let (x, y, z) = (dx[j], dy[j], dz[j]);
        let inv = 1.0 / (x * x + y * y + z * z).sqrt();
        let f = ((n.x * x + n.y * y + n.z * z) * inv).max(0.0);
        term_f[j] = f;
        term_d[j] = vis[j] * f;
        term_s[j] = blinn_cosine(n, v, x, y, z, inv);
    }
    // Their logarithms, then the powers: `pow_approx` in its two halves.
    for c in term_s.iter_mut() {
        *c = pow_log2(*c);
    }
    for (s, &w) in term_s.iter_mut().zip(vis) {
        *s = w * pow_from_log2(*s, shininess);
    }
}

/// Each slice's sum, left to right from −0 (the order and start of
/// `Iterator::sum`, so the same bits), all slices (of one length) in one
/// loop: each sum is a chain of dependent additions, and interleaving the
/// chains keeps the adder busy where one alone waits on each addition.
#[inline(always)]
pub(crate) fn sequential_sums<const K: usize>(slices: [&[f32]; K]) -> [f32; K] {
    let len = slices[0].len();
    let mut sums = [-0.0f32; K];
    for j in 0..len {
        for (sum, slice) in sums.iter_mut().zip(&slices) {
            *sum += slice[j];
        }
    }
    sums
}

/// max(0, N·H / |H|) for Blinn's half vector H = L / |L| + V, from the
/// direction (x, y, z) to a light point and `inv` = 1 / |L|; H = 0 (the
/// light exactly behind the viewer) gives 0. One definition for the
/// tracer and the re-shade, which must give the same bits.
#[inline(always)]
pub(crate) fn blinn_cosine(n: Vec3, v: Vec3, x: f32, y: f32, z: f32, inv: f32) -> f32 {
    let (hx, hy, hz) = (x * inv + v.x, y * inv + v.y, z * inv + v.z);
    let h2 = hx * hx + hy * hy + hz * hz;
    let c = ((n.x * hx + n.y * hy + n.z * hz) / h2.sqrt()).max(0.0);
    if h2 > 0.0 { c } else { 0.0 }
}

/// Averages over the light points of one hit point.
pub(crate) struct SampledTerms {
    /// max(0, N·L), weighted by visibility.
    pub(crate) diffuse: f32,
    /// max(0, N·L) without visibility (the ratio estimator's denominator).
    pub(crate) unshadowed_diffuse: f32,
    /// max(0, N·H)^shininess, weighted by visibility.
    pub(crate) specular: f32,
}

/// Blinn–Phong specular factor max(0, N·H)^shininess, H = normalize(L + V).
#[inline]
pub fn phong_specular(n: Vec3, l: Vec3, v: Vec3, shininess: f32) -> f32 {
    let h = l + v;
    let len = h.length();
    if len == 0.0 {
        return 0.0;
    }
    let c = n.dot(h) / len;
    if c <= 0.0 {
        0.0
    } else {
        pow_approx(c, shininess)
    }
}

/// `nearest_point` model (the report's): diffuse from the light point met
/// along the normal, specular from the one met along the mirrored view
/// ray, both unshadowed (the caller scales them by the visible fraction).
fn nearest_point_terms(scene: &Scene, sp: &ShadingPoint) -> (f32, f32) {
    let light = &scene.light;
    let n = sp.normal;
    let to_light = |dir: DVec3| (light.nearest_point(sp.point, dir) - sp.point).normalize_or_zero();
    let ld = to_light(n);
    let diffuse = n.dot(ld).max(0.0) as f32;
    let ls = nearest_point_specular_direction(scene, sp);
    let specular =
        nearest_point_specular(n.as_vec3(), ls, sp.view.as_vec3(), sp.material.shininess);
    (diffuse, specular)
}

/// The `nearest_point` model's light direction for the specular term (the
/// light point met along the mirrored view ray), or zero where that point
/// lies below the surface (no specular).
pub fn nearest_point_specular_direction(scene: &Scene, sp: &ShadingPoint) -> Vec3 {
    let n = sp.normal;
    let mirrored = n * (2.0 * n.dot(sp.view)) - sp.view;
    let ls = (scene.light.nearest_point(sp.point, mirrored) - sp.point).normalize_or_zero();
    if n.dot(ls) > 0.0 {
        ls.as_vec3()
    } else {
        Vec3::ZERO
    }
}

/// The `nearest_point` model's unshadowed specular factor for the light
/// direction `ls` of [`nearest_point_specular_direction`].
#[inline]
pub fn nearest_point_specular(n: Vec3, ls: Vec3, v: Vec3, shininess: f32) -> f32 {
    if ls == Vec3::ZERO {
        0.0
    } else {
        phong_specular(n, ls, v, shininess)
    }
}
