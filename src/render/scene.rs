//! The runtime scene: what a validated [`SceneDesc`] fixes for every render
//! of it (camera, light geometry, primitives with their material indices,
//! acceleration structures). Built once per load and shared as an `Arc`;
//! what an edit may change lives beside it, in [`RenderSettings`] and
//! [`ShadingParams`], and a render takes the three as separate arguments.

use std::path::Path;
use std::sync::Arc;

use glam::DVec3;

use super::camera::Camera;
use super::error::SceneError;
use super::film::Film;
use super::geometry::{
    Aabb, Bvh, Cuboid, Parallelogram, Plane, Ray, Shape, Sphere, SurfacePoint, Triangle,
    spawn_origin,
};
use super::light::AreaLight;
use super::mesh;
use super::progressive::{self, CancelToken, Cancelled, RenderOptions, RenderReport, TileUpdate};
use super::scene_file::{ObjectDesc, SceneDesc};
use super::settings::RenderSettings;
use super::shading_params::ShadingParams;
use super::shadow::OccluderBvh;

/// The seed room, built into the binary so the program runs anywhere.
pub const SEED_ROOM_JSON: &str = include_str!("../../scenes/seed-room.json");

#[derive(Debug, Clone)]
pub struct Object {
    pub shape: Shape,
    pub material: u32,
    /// The shape's bounds (`None` for planes), computed once.
    pub bounds: Option<Aabb>,
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
/// light's frame as packets (`shadow/`); below it, testing every
/// object in the shadow pyramid against all rays of a hit point is cheaper
/// (measured on generated rooms: the two meet between 200 and 300).
pub const PACKET_THRESHOLD: usize = 256;

#[derive(Debug, Clone)]
pub struct Scene {
    pub camera: Camera,
    pub light: AreaLight,
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
    /// Union of the bounded objects' bounds.
    pub object_bounds: Option<Aabb>,
    /// Size of the scene's finite part (bounded objects, light, camera):
    /// the floor of ray offsets near the origin.
    pub scale: f64,
    /// Triangles in the scene (`triangle` objects and mesh faces), and the
    /// zero-area ones left out.
    pub triangles: usize,
    pub degenerate_triangles: usize,
}

impl Scene {
    /// Builds the runtime scene of a description that
    /// [`SceneDesc::validate`] accepted (see [`Loaded`] for both steps).
    pub fn build(desc: &SceneDesc) -> Result<Scene, SceneError> {
        let material_names: Vec<String> = desc.materials.keys().cloned().collect();
        let mut objects: Vec<Object> = Vec::with_capacity(desc.objects.len());
        let mut triangles = 0usize;
        let mut degenerate = 0usize;
        for (index, o) in desc.objects.iter().enumerate() {
            let material = material_names
                .binary_search_by(|n| n.as_str().cmp(o.material()))
                .expect("validated material name") as u32;
            let mut push = |shape: Shape| {
                let bounds = shape.bounds();
                objects.push(Object {
                    shape,
                    material,
                    bounds,
                });
            };
            let shape = match o {
                ObjectDesc::Plane(p) => Shape::Plane(Plane::new(p.point.into(), p.normal.into())),
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
                ObjectDesc::Triangle(t) => {
                    let [a, b, c] = t.vertices.map(DVec3::from);
                    match Triangle::new(a, b, c) {
                        Some(t) => {
                            triangles += 1;
                            Shape::Triangle(t)
                        }
                        None => {
                            degenerate += 1;
                            continue;
                        }
                    }
                }
                ObjectDesc::Mesh(m) => {
                    let budget = mesh::limits::MAX_TRIANGLES.saturating_sub(triangles);
                    let loaded = mesh::load(m, desc.base_dir.as_deref(), budget)
                        .map_err(|e| SceneError::new(format!("objects[{index}].file"), e))?;
                    if let Err(e) = check_mesh_range(&loaded.triangles) {
                        return Err(SceneError::new(
                            format!("objects[{index}]"),
                            format!("{}: {e}", m.file),
                        ));
                    }
                    triangles += loaded.triangles.len();
                    degenerate += loaded.degenerate;
                    for t in loaded.triangles {
                        push(Shape::Triangle(t));
                    }
                    continue;
                }
            };
            push(shape);
        }
        if objects.len() > u32::MAX as usize / 2 {
            return Err(SceneError::new("objects", "too many objects"));
        }

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
        let object_bounds = with_bounds.iter().map(|o| o.1).reduce(|a, b| a.union(b));
        let scale = scale_of(object_bounds, &light, &camera);
        // The two trees are independent: built side by side (a mesh's
        // load time is mostly theirs).
        let ((bounded, bvh), shadow_bvh) = rayon::join(
            || {
                if with_bounds.len() > BVH_THRESHOLD {
                    (Vec::new(), Bvh::build(&with_bounds))
                } else {
                    (with_bounds.iter().map(|o| o.0).collect(), Bvh::default())
                }
            },
            || shadow_bvh(&objects, &light),
        );
        Ok(Scene {
            camera,
            light,
            material_names,
            objects,
            unbounded,
            bounded,
            bvh,
            shadow_bvh,
            object_bounds,
            scale,
            triangles,
            degenerate_triangles: degenerate,
        })
    }

    /// The same objects seen by `desc`'s camera under `desc`'s light: the
    /// objects and their BVH are kept, the light-frame BVH is built again
    /// only if the light moved (a camera or light edit is a re-trace, not a
    /// rebuild).
    pub fn with_view(&self, desc: &SceneDesc) -> Scene {
        let light = AreaLight::new(&desc.light);
        let camera = Camera::new(&desc.camera);
        let (a, b) = (&light.shape, &self.light.shape);
        let moved = (a.corner, a.edge_u, a.edge_v) != (b.corner, b.edge_u, b.edge_v);
        Scene {
            scale: scale_of(self.object_bounds, &light, &camera),
            shadow_bvh: if moved {
                shadow_bvh(&self.objects, &light)
            } else {
                self.shadow_bvh.clone()
            },
            camera,
            light,
            material_names: self.material_names.clone(),
            objects: self.objects.clone(),
            unbounded: self.unbounded.clone(),
            bounded: self.bounded.clone(),
            bvh: self.bvh.clone(),
            object_bounds: self.object_bounds,
            triangles: self.triangles,
            degenerate_triangles: self.degenerate_triangles,
        }
    }

    /// Nearest object or light along the ray, with its distance.
    pub fn closest_hit(&self, ray: &Ray) -> Option<(HitTarget, f64)> {
        self.closest_hit_before(ray, f64::INFINITY)
    }

    /// Nearest object or light along the ray with t < `t_max`.
    pub fn closest_hit_before(&self, ray: &Ray, t_max: f64) -> Option<(HitTarget, f64)> {
        let mut best: Option<(HitTarget, f64)> = None;
        let mut t_max = t_max;
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

    /// [`Scene::closest_hit`] for a camera ray: with `cutaway`, planes
    /// seen from behind (the ray runs along their normal) are passed
    /// through, so a camera outside a room sees into it. Only camera rays
    /// ever use this; shadow and reflected rays meet every plane.
    pub fn camera_hit(&self, ray: &Ray, cutaway: bool) -> Option<(HitTarget, f64)> {
        if !cutaway {
            return self.closest_hit(ray);
        }
        let mut best: Option<(HitTarget, f64)> = None;
        let mut t_max = f64::INFINITY;
        if let Some(t) = self.light.shape.intersect(ray, t_max) {
            best = Some((HitTarget::Light, t));
            t_max = t;
        }
        for &i in self.unbounded.iter().chain(self.bounded.iter()) {
            let shape = &self.objects[i as usize].shape;
            if let Shape::Plane(p) = shape
                && p.normal.dot(ray.dir) > 0.0
            {
                continue;
            }
            if let Some(t) = shape.intersect(ray, t_max) {
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

    /// Where the shadow rays of a smooth triangle's hit start: the point
    /// lifted by its shadow offset, unless something (another surface, the
    /// light) lies between the two, in which case the point itself, so
    /// that a ray never starts beyond a surface it should meet. `normal`:
    /// the geometric normal facing the ray.
    pub fn lifted_shadow_point(&self, surface: &SurfacePoint, normal: DVec3) -> DVec3 {
        let lifted = surface.point + surface.shadow_offset;
        let origin = spawn_origin(surface.point, normal, self.scale);
        let d = lifted - origin;
        let len = d.length();
        if len.is_nan() || len <= 0.0 || d.dot(normal) <= 0.0 {
            return surface.point;
        }
        let ray = Ray::new(origin, d / len);
        match self.closest_hit_before(&ray, len) {
            None => lifted,
            Some(_) => surface.point,
        }
    }

    /// Name of an object's material.
    pub fn material_name(&self, object: u32) -> &str {
        &self.material_names[self.objects[object as usize].material as usize]
    }
}

/// Size of the scene's finite part (bounded objects, light, camera).
fn scale_of(object_bounds: Option<Aabb>, light: &AreaLight, camera: &Camera) -> f64 {
    let lit = Aabb::from_points(&light.shape.corners());
    let finite = object_bounds
        .map_or(lit, |b| lit.union(b))
        .grow(camera.origin);
    finite
        .extent()
        .max_element()
        .max(finite.min.abs().max(finite.max.abs()).max_element())
}

/// The light-frame BVH of the bounded objects, from [`PACKET_THRESHOLD`] of
/// them on.
fn shadow_bvh(objects: &[Object], light: &AreaLight) -> Option<OccluderBvh> {
    let ids: Vec<u32> = (0..objects.len() as u32)
        .filter(|&i| objects[i as usize].bounds.is_some())
        .collect();
    (ids.len() >= PACKET_THRESHOLD).then(|| {
        let shapes: Vec<&Shape> = objects.iter().map(|o| &o.shape).collect();
        OccluderBvh::new(light, &shapes, &ids)
    })
}

/// A loaded scene: the immutable part and the two editable parts, as the
/// description sets them. Validation runs here, once per load.
#[derive(Debug, Clone)]
pub struct Loaded {
    pub scene: Arc<Scene>,
    pub settings: RenderSettings,
    pub shading: ShadingParams,
}

impl Loaded {
    /// Validates a description and builds its scene.
    pub fn new(desc: &SceneDesc) -> Result<Loaded, SceneError> {
        desc.validate()?;
        let scene = Scene::build(desc)?;
        Ok(Loaded {
            settings: RenderSettings::from_desc(desc),
            shading: ShadingParams::from_desc(desc),
            scene: Arc::new(scene),
        })
    }

    /// Loads, validates and builds a scene file; errors name the file.
    pub fn load(path: &Path) -> Result<Loaded, SceneError> {
        Loaded::new(&SceneDesc::load(path)?).map_err(|e| e.in_file(path))
    }

    /// Parses and builds a scene from JSON text.
    pub fn from_json(text: &str) -> Result<Loaded, SceneError> {
        Loaded::new(&SceneDesc::from_json(text)?)
    }

    /// The built-in seed room.
    pub fn seed_room() -> Loaded {
        Loaded::from_json(SEED_ROOM_JSON).expect("the built-in seed room is valid")
    }

    /// Renders it with its own settings and shading.
    pub fn render(
        &self,
        options: &RenderOptions,
        cancel: &CancelToken,
        on_tile: &(dyn Fn(&TileUpdate) + Sync),
    ) -> Result<RenderReport, Cancelled> {
        progressive::render(
            &self.scene,
            &self.settings,
            &self.shading,
            options,
            cancel,
            on_tile,
        )
    }

    /// Renders one rectangle of its image (see
    /// [`progressive::render_region`]).
    pub fn render_region(
        &self,
        region: progressive::TileRect,
        options: &RenderOptions,
        cancel: &CancelToken,
        on_tile: &(dyn Fn(&TileUpdate) + Sync),
    ) -> Result<RenderReport, Cancelled> {
        progressive::render_region(
            &self.scene,
            &self.settings,
            &self.shading,
            region,
            options,
            cancel,
            on_tile,
        )
    }

    /// Renders it in one pass on all threads.
    pub fn render_image(&self) -> Film {
        progressive::render_image(&self.scene, &self.settings, &self.shading)
    }
}

/// A mesh's vertices within the coordinates the renderer supports.
fn check_mesh_range(triangles: &[Triangle]) -> Result<(), String> {
    use super::scene_file::limits::MAX_COORD;
    for (i, t) in triangles.iter().enumerate() {
        for v in t.vertices() {
            if v.abs().max_element() > MAX_COORD {
                return Err(format!(
                    "triangle {i} has the vertex {v} after the transform, expected coordinates within ±{MAX_COORD:e}"
                ));
            }
        }
    }
    Ok(())
}
