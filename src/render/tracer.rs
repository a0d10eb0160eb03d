//! Whitted-style tracing of one camera path: local Phong shading at each
//! hit plus the mirrored ray, weighted by reflectivity, up to `max_depth`
//! hits.

use glam::{DVec3, Vec3};

use super::geometry::{Ray, spawn_origin};
use super::occlusion::ShadowBuffers;
use super::rng::Rng;
use super::sampling::Pattern;
use super::scene::{HitTarget, Scene};
use super::shading::{ShadingPoint, shade};
use super::stats::RayStats;

/// Reflected rays whose path weight falls below this are not traced (when
/// skipping is on): they could change the pixel by at most this fraction of
/// the brightest surface.
pub const MIN_PATH_WEIGHT: f32 = 1.0 / 1024.0;

/// Traces pixels of one scene at one shadow-ray count.
pub struct Tracer<'a> {
    pub scene: &'a Scene,
    pub pattern: Pattern,
}

/// Per-thread scratch space of a tracer.
pub struct TraceScratch {
    pub shadow: ShadowBuffers,
    pub stats: RayStats,
}

impl<'a> Tracer<'a> {
    /// A tracer using `shadow_rays` (instead of the scene's) per hit point.
    pub fn new(scene: &'a Scene, shadow_rays: u32) -> Tracer<'a> {
        Tracer {
            scene,
            pattern: Pattern::new(scene.settings.sampling, shadow_rays),
        }
    }

    pub fn scratch(&self) -> TraceScratch {
        TraceScratch {
            shadow: ShadowBuffers::with_capacity(self.pattern.count()),
            stats: RayStats::default(),
        }
    }

    /// Linear RGB of pixel (x, y).
    pub fn pixel(&self, x: u32, y: u32, scratch: &mut TraceScratch) -> Vec3 {
        let scene = self.scene;
        let s = &scene.settings;
        let mut ray = scene.camera.pixel_ray(x, y);
        scratch.stats.camera += 1;
        let mut colour = Vec3::ZERO;
        let mut weight = 1.0f32;
        for depth in 1..=s.max_depth {
            let Some((target, t)) = scene.closest_hit(&ray) else {
                colour += s.background * weight;
                break;
            };
            let object = match target {
                HitTarget::Light => {
                    colour += scene.light.diffuse * weight;
                    break;
                }
                HitTarget::Object(i) => i,
            };
            let obj = &scene.objects[object as usize];
            let surface = obj.shape.surface(&ray, t);
            let inside = surface.normal.dot(ray.dir) > 0.0;
            let normal = if inside {
                -surface.normal
            } else {
                surface.normal
            };
            let material = &scene.materials[obj.material as usize];
            let sp = ShadingPoint {
                point: surface.point,
                normal,
                view: -ray.dir,
                object,
                inside,
                material,
            };
            let mut rng = Rng::for_vertex(s.seed, x, y, depth);
            colour += shade(
                scene,
                &sp,
                &self.pattern,
                &mut rng,
                &mut scratch.shadow,
                &mut scratch.stats,
            ) * weight;

            if material.reflectivity == 0.0 || depth == s.max_depth {
                break;
            }
            weight *= material.reflectivity;
            if s.skip && weight < MIN_PATH_WEIGHT {
                scratch.stats.reflected_culled += 1;
                break;
            }
            ray = Ray::new(
                spawn_origin(surface.point, normal, scene.scale),
                reflect(ray.dir, normal),
            );
            scratch.stats.reflected += 1;
        }
        colour
    }
}

/// Mirror direction of `d` about the normal `n`.
#[inline]
pub fn reflect(d: DVec3, n: DVec3) -> DVec3 {
    (d - n * (2.0 * d.dot(n))).normalize()
}
