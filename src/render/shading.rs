//! How light is computed at one hit point: the report's Phong model with
//! Blinn's half vector, under the two area-light models.

use glam::{DVec3, Vec3};

use super::math::pow_approx;
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

    pattern.fill(rng, &mut buf.a, &mut buf.b);
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
        AreaLightModel::Sampled => sampled_terms(n, v, m.shininess, need_s, count, buf),
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

/// `sampled` model: the diffuse factor max(0, N·L) and the specular factor
/// max(0, N·H)^shininess averaged over the light points, each weighted by
/// its visibility.
///
/// Written for the vectorizer: eight independent partial sums (one per SIMD
/// lane), no branches, and the buffers padded to a multiple of eight with
/// invisible points. The summation order is fixed, so the result does not
/// depend on which points were found visible by tracing or by skipping.
fn sampled_terms(n: Vec3, v: Vec3, shininess: f32, need_s: bool, count: usize, buf: &ShadowBuffers) -> (f32, f32) {
    const LANES: usize = 8;
    let padded = count.next_multiple_of(LANES);
    let (dx, dy, dz, vis) = (&buf.dx[..padded], &buf.dy[..padded], &buf.dz[..padded], &buf.vis[..padded]);
    let mut diffuse = [0.0f32; LANES];
    let mut specular = [0.0f32; LANES];
    for c in (0..padded).step_by(LANES) {
        for k in 0..LANES {
            let j = c + k;
            let (x, y, z) = (dx[j], dy[j], dz[j]);
            let inv = 1.0 / (x * x + y * y + z * z).sqrt();
            let (lx, ly, lz) = (x * inv, y * inv, z * inv);
            diffuse[k] += vis[j] * (n.x * lx + n.y * ly + n.z * lz).max(0.0);
            if need_s {
                let (hx, hy, hz) = (lx + v.x, ly + v.y, lz + v.z);
                let h2 = hx * hx + hy * hy + hz * hz;
                // N·H / |H|; H = 0 (light exactly behind the viewer) gives 0.
                let c = ((n.x * hx + n.y * hy + n.z * hz) / h2.sqrt()).max(0.0);
                let c = if h2 > 0.0 { c } else { 0.0 };
                specular[k] += vis[j] * pow_approx(c, shininess);
            }
        }
    }
    let sum = |lanes: [f32; LANES]| lanes.iter().fold(0.0, |a, b| a + b);
    let inv = 1.0 / count as f32;
    (sum(diffuse) * inv, sum(specular) * inv)
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
    if c <= 0.0 { 0.0 } else { pow_approx(c, shininess) }
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
