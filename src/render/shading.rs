//! How light is computed at one hit point: the report's Phong model with
//! Blinn's half vector, under the two area-light models.

use glam::{DVec3, Vec3};

use super::analytic;
use super::math::{avx2_dispatch, pow_approx};
use super::occlusion::{self, ShadowBuffers, ShadowQuery};
use super::rng::Rng;
use super::sampling::Pattern;
use super::scene::{Material, Scene};
use super::scene_file::AreaLightModel;
use super::stats::RayStats;

/// A surface point being shaded.
pub struct ShadingPoint<'a> {
    pub point: DVec3,
    /// Unit normal, flipped to face the incoming ray.
    pub normal: DVec3,
    /// Unit direction towards the viewer (against the incoming ray).
    pub view: DVec3,
    pub object: u32,
    pub inside: bool,
    pub material: &'a Material,
}

/// The local colour (without the reflection) of one hit point.
pub fn shade(
    scene: &Scene,
    sp: &ShadingPoint,
    pattern: &Pattern,
    rng: &mut Rng,
    buf: &mut ShadowBuffers,
    stats: &mut RayStats,
) -> Vec3 {
    let s = &scene.settings;
    let light = &scene.light;
    let m = sp.material;
    let mut colour = m.ambient * light.ambient * s.terms.x;
    if !light.illuminates(sp.point) {
        return colour;
    }
    // Skip a term whose product of multiplier and reflectances is zero.
    let kd = m.diffuse * light.diffuse * s.terms.y;
    let ks = m.specular * light.specular * s.terms.z;
    let need_d = kd != Vec3::ZERO;
    let need_s = ks != Vec3::ZERO;
    let count = pattern.count();
    if !(need_d || need_s) && s.skip {
        stats.shadow_unneeded += count as u64;
        return colour;
    }

    // A fixed pattern (the grid) is the same at every hit point: fill once.
    let key = (pattern.sampling, pattern.shadow_rays);
    if !(pattern.is_fixed() && buf.filled == Some(key)) {
        pattern.fill(rng, &mut buf.a, &mut buf.b);
        buf.filled = pattern.is_fixed().then_some(key);
    }
    let query = ShadowQuery {
        point: sp.point,
        normal: sp.normal,
        object: sp.object,
        inside: sp.inside,
    };
    occlusion::visibility(scene, &query, count, buf, stats);

    let n = sp.normal.as_vec3();
    let v = sp.view.as_vec3();
    let (diffuse, specular) = match s.model {
        AreaLightModel::Sampled => {
            let t = sampled_terms(n, v, m.shininess, need_s, count, buf);
            (t.diffuse, t.specular)
        }
        AreaLightModel::Analytic => {
            // Ratio estimator (Heitz, Hill & McGuire 2018): the exact
            // unshadowed diffuse average times the visible share of the
            // sampled integrand. Noise-free wherever the light is wholly
            // visible or wholly hidden. The specular term has no closed form
            // (see `analytic::specular_area_average`) and stays sampled.
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
            let visible: f32 = buf.vis[..count].iter().sum();
            let fraction = visible / count as f32;
            let (d, sp_) = nearest_point_terms(scene, sp);
            (d * fraction, sp_ * fraction)
        }
    };
    colour += kd * diffuse + ks * specular;
    colour
}

avx2_dispatch!(
    /// `sampled` model: the diffuse factor max(0, N·L) and the specular factor
    /// max(0, N·H)^shininess averaged over the light points, each weighted by
    /// its visibility.
    ///
    /// Written for the vectorizer: one branch-free loop per term that writes
    /// each point's contribution, then a sum in a fixed order — so the result
    /// does not depend on whether visibility came from tracing or skipping.
    /// The buffers are padded to a multiple of eight with invisible points.
    fn sampled_terms(
    n: Vec3,
    v: Vec3,
    shininess: f32,
    need_s: bool,
    count: usize,
    buf: &mut ShadowBuffers,
) -> SampledTerms => sampled_terms_generic);

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
    let (dx, dy, dz, vis) = (
        &buf.dx[..padded],
        &buf.dy[..padded],
        &buf.dz[..padded],
        &buf.vis[..padded],
    );
    let (term_d, term_f, term_s) = (
        &mut buf.term_d[..padded],
        &mut buf.term_f[..padded],
        &mut buf.term_s[..padded],
    );
    for j in 0..padded {
        let (x, y, z) = (dx[j], dy[j], dz[j]);
        let inv = 1.0 / (x * x + y * y + z * z).sqrt();
        let f = ((n.x * x + n.y * y + n.z * z) * inv).max(0.0);
        term_f[j] = f;
        term_d[j] = vis[j] * f;
    }
    let inv_count = 1.0 / count as f32;
    let mut terms = SampledTerms {
        diffuse: term_d[..count].iter().sum::<f32>() * inv_count,
        unshadowed_diffuse: term_f[..count].iter().sum::<f32>() * inv_count,
        specular: 0.0,
    };
    if need_s {
        for j in 0..padded {
            let (x, y, z) = (dx[j], dy[j], dz[j]);
            let inv = 1.0 / (x * x + y * y + z * z).sqrt();
            let (hx, hy, hz) = (x * inv + v.x, y * inv + v.y, z * inv + v.z);
            let h2 = hx * hx + hy * hy + hz * hz;
            // N·H / |H|; H = 0 (light exactly behind the viewer) gives 0.
            let c = ((n.x * hx + n.y * hy + n.z * hz) / h2.sqrt()).max(0.0);
            let c = if h2 > 0.0 { c } else { 0.0 };
            term_s[j] = vis[j] * pow_approx(c, shininess);
        }
        terms.specular = term_s[..count].iter().sum::<f32>() * inv_count;
    }
    terms
}

/// Averages over the light points of one hit point.
struct SampledTerms {
    /// max(0, N·L), weighted by visibility.
    diffuse: f32,
    /// max(0, N·L) without visibility (the ratio estimator's denominator).
    unshadowed_diffuse: f32,
    /// max(0, N·H)^shininess, weighted by visibility.
    specular: f32,
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
    let mirrored = n * (2.0 * n.dot(sp.view)) - sp.view;
    let ls = to_light(mirrored);
    let specular = if n.dot(ls) > 0.0 {
        phong_specular(
            n.as_vec3(),
            ls.as_vec3(),
            sp.view.as_vec3(),
            sp.material.shininess,
        )
    } else {
        0.0
    };
    (diffuse, specular)
}
