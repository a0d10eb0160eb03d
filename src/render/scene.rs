//! The runtime scene: a validated [`SceneDesc`] turned into what the tracer
//! needs (camera, light, materials as indices, primitives, BVH).

use std::path::Path;

use glam::{DVec3, Vec3};

use super::camera::Camera;
use super::error::SceneError;
use super::geometry::{Aabb, Bvh, Cuboid, Parallelogram, Plane, Ray, Shape, Sphere};
use super::light::AreaLight;
use super::light_frame::OccluderBvh;
use super::scene_file::{AreaLightModel, ObjectDesc, Sampling, SceneDesc};

/// The seed room, built into the binary so the program runs anywhere.
pub const SEED_ROOM_JSON: &str = include_str!("../../scenes/seed-room.json");

/// Phong material with f32 reflectances (the shading runs in f32).
#[derive(Debug, Clone)]
pub struct Material {
    pub ambient: Vec3,
    pub diffuse: Vec3,
    pub specular: Vec3,
    pub shininess: f32,
    pub reflectivity: f32,
}

#[derive(Debug, Clone)]
pub struct Object {
    pub shape: Shape,
    pub material: u32,
    /// The shape's bounds (`None` for planes), computed once.
    pub bounds: Option<Aabb>,
}

/// Settings of one render, from the scene's `render` section.
#[derive(Debug, Clone)]
pub struct RenderSettings {
    pub shadow_rays: u32,
    pub sampling: Sampling,
    pub max_depth: u32,
    pub seed: u64,
    pub model: AreaLightModel,
    /// Multipliers of the ambient, diffuse and specular terms.
    pub terms: Vec3,
    pub background: Vec3,
    /// `false`: every shadow ray arrives.
    pub shadows: bool,
    /// Trace a few shadow rays first and the rest only where they disagree
    /// (faster, biased).
    pub adaptive: bool,
    /// Skip work whose result is known (exact; see `occlusion.rs`). Only
    /// switched off to measure what the skipping saves.
    pub skip: bool,
}

/// What a ray met first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HitTarget {
    Object(u32),
    Light,
}

/// Bounded objects are tested one by one up to this many, through the BVH
/// beyond.
const BVH_THRESHOLD: usize = 8;

/// From this many bounded objects on, shadow rays walk a BVH in the
/// light's frame as packets (`occlusion.rs`); below it, testing every
/// object in the shadow pyramid against all rays of a hit point is cheaper
/// (measured on generated rooms: the two meet between 200 and 300).
pub const PACKET_THRESHOLD: usize = 256;

#[derive(Debug, Clone)]
pub struct Scene {
    /// The description this scene was built from (what "save" writes).
    pub desc: SceneDesc,
    pub settings: RenderSettings,
    pub camera: Camera,
    pub light: AreaLight,
    pub materials: Vec<Material>,
    /// Material names, in the order of `materials`.
    pub material_names: Vec<String>,
    pub objects: Vec<Object>,
    /// Objects without bounds (planes), always tested one by one.
    pub unbounded: Vec<u32>,
    /// Bounded objects when there are few of them.
    pub bounded: Vec<u32>,
    /// BVH over bounded objects when there are many (`bounded` is then
    /// empty).
    pub bvh: Bvh,
    /// The same objects in a BVH built in the light's frame, for shadow-ray
    /// packets (from [`PACKET_THRESHOLD`] objects on).
    pub shadow_bvh: Option<OccluderBvh>,
    /// Size of the scene's finite part (bounded objects, light, camera):
    /// the floor of ray offsets near the origin.
    pub scale: f64,
}

impl Scene {
    /// Validates a description and builds the runtime scene.
    pub fn new(desc: SceneDesc) -> Result<Scene, SceneError> {
        desc.validate()?;
        let material_names: Vec<String> = desc.materials.keys().cloned().collect();
        let override_shininess = desc.render.shininess_override;
        let materials = desc
            .materials
            .values()
            .map(|m| Material {
                ambient: DVec3::from(m.ambient).as_vec3(),
                diffuse: DVec3::from(m.diffuse).as_vec3(),
                specular: DVec3::from(m.specular).as_vec3(),
                shininess: override_shininess.unwrap_or(m.shininess) as f32,
                reflectivity: m.reflectivity as f32,
            })
            .collect();
        let objects: Vec<Object> = desc
            .objects
            .iter()
            .map(|o| {
                let shape = match o {
                    ObjectDesc::Plane(p) => {
                        Shape::Plane(Plane::new(p.point.into(), p.normal.into()))
                    }
                    ObjectDesc::Rect(r) => Shape::Parallelogram(Parallelogram::new(
                        r.corner.into(),
                        r.edge_u.into(),
                        r.edge_v.into(),
                    )),
                    ObjectDesc::Box(b) => Shape::Cuboid(Cuboid::new(
                        b.min.into(),
                        b.max.into(),
                        b.rotate_y_deg,
                        b.translate.into(),
                    )),
                    ObjectDesc::Sphere(s) => Shape::Sphere(Sphere {
                        centre: s.center.into(),
                        radius: s.radius,
                    }),
                };
                let material = material_names
                    .binary_search_by(|n| n.as_str().cmp(o.material()))
                    .expect("validated material name") as u32;
                let bounds = shape.bounds();
                Object {
                    shape,
                    material,
                    bounds,
                }
            })
            .collect();

        let mut unbounded = Vec::new();
        let mut with_bounds = Vec::new();
        for (i, o) in objects.iter().enumerate() {
            match o.bounds {
                Some(b) => with_bounds.push((i as u32, b)),
                None => unbounded.push(i as u32),
            }
        }
        let light = AreaLight::new(&desc.light);
        let camera = Camera::new(&desc.camera);
        let finite = with_bounds
            .iter()
            .fold(Aabb::from_points(&light.shape.corners()), |b, o| {
                b.union(o.1)
            })
            .grow(camera.origin);
        let scale = finite
            .extent()
            .max_element()
            .max(finite.min.abs().max(finite.max.abs()).max_element());
        let (bounded, bvh) = if with_bounds.len() > BVH_THRESHOLD {
            (Vec::new(), Bvh::build(&with_bounds))
        } else {
            (with_bounds.iter().map(|o| o.0).collect(), Bvh::default())
        };
        let shadow_bvh = (with_bounds.len() >= PACKET_THRESHOLD).then(|| {
            let shapes: Vec<&Shape> = objects.iter().map(|o| &o.shape).collect();
            let ids: Vec<u32> = with_bounds.iter().map(|o| o.0).collect();
            OccluderBvh::new(&light, &shapes, &ids)
        });
        let r = &desc.render;
        let settings = RenderSettings {
            shadow_rays: r.shadow_rays,
            sampling: r.sampling,
            max_depth: r.max_depth,
            seed: r.seed,
            model: r.area_light_model,
            terms: Vec3::new(
                r.terms.ambient as f32,
                r.terms.diffuse as f32,
                r.terms.specular as f32,
            ),
            background: DVec3::from(r.background).as_vec3(),
            shadows: r.shadows,
            adaptive: r.adaptive,
            skip: true,
        };
        Ok(Scene {
            desc,
            settings,
            camera,
            light,
            materials,
            material_names,
            objects,
            unbounded,
            bounded,
            bvh,
            shadow_bvh,
            scale,
        })
    }

    /// Loads, validates and builds a scene file; errors name the file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        Scene::new(SceneDesc::load(path)?).map_err(|e| e.in_file(path))
    }

    /// Parses and builds a scene from JSON text.
    pub fn from_json(text: &str) -> Result<Scene, SceneError> {
        Scene::new(SceneDesc::from_json(text)?)
    }

    /// The built-in seed room.
    pub fn seed_room() -> Scene {
        Scene::from_json(SEED_ROOM_JSON).expect("the built-in seed room is valid")
    }

    /// Nearest object or light along the ray, with its distance.
    pub fn closest_hit(&self, ray: &Ray) -> Option<(HitTarget, f64)> {
        let mut best: Option<(HitTarget, f64)> = None;
        let mut t_max = f64::INFINITY;
        if let Some(t) = self.light.shape.intersect(ray, t_max) {
            best = Some((HitTarget::Light, t));
            t_max = t;
        }
        for &i in self.unbounded.iter().chain(self.bounded.iter()) {
            if let Some(t) = self.objects[i as usize].shape.intersect(ray, t_max) {
                best = Some((HitTarget::Object(i), t));
                t_max = t;
            }
        }
        if let Some((i, t)) = self.bvh.closest(ray, t_max, |i, t_max| {
            self.objects[i as usize].shape.intersect(ray, t_max)
        }) {
            best = Some((HitTarget::Object(i), t));
        }
        best
    }

    /// Name of an object's material.
    pub fn material_name(&self, object: u32) -> &str {
        &self.material_names[self.objects[object as usize].material as usize]
    }
}
