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
    Aabb, Bvh, Cuboid, Meshes, Parallelogram, Plane, Primitive, Ray, Shape, Sphere, SurfacePoint,
    Triangle, spawn_origin,
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
///
/// Primitive ids: `0..objects.len()` are the objects, in the order of the
/// description without its meshes; from `objects.len()` on, the faces of
/// every mesh, in order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HitTarget {
    Object(u32),
    Light,
}

/// Bounded objects are tested one by one up to this many, through the BVH
/// beyond.
const BVH_THRESHOLD: usize = 8;

/// Rays whose nearest hits [`Scene::closest_hits`] finds side by side.
const RAY_LANES: usize = 8;

/// Makes object `id` the nearest hit of each ray of `chunk` that `test`
/// finds it nearer than the ray's `t_max` (`best`: the rays' nearest).
#[inline(always)]
fn nearer(
    id: u32,
    chunk: &[Ray],
    t_max: &mut [f64; RAY_LANES],
    best: &mut [Option<HitTarget>; RAY_LANES],
    test: impl Fn(&Ray, f64) -> Option<f64>,
) {
    for (j, ray) in chunk.iter().enumerate() {
        if let Some(t) = test(ray, t_max[j]) {
            (best[j], t_max[j]) = (Some(HitTarget::Object(id)), t);
        }
    }
}

/// From this many bounded objects on, shadow rays walk a BVH in the
/// light's frame as packets (`shadow/`); below it, testing every
/// object in the shadow pyramid against all rays of a hit point is cheaper
/// (measured on generated rooms: the two meet between 200 and 300).
pub const PACKET_THRESHOLD: usize = 256;

/// What a camera or light edit leaves as it is: objects, meshes and their
/// trees, shared between the scenes of one description's views.
#[derive(Debug, Clone)]
pub struct Scene {
    pub camera: Camera,
    pub light: AreaLight,
    /// Material names, in the order of `materials`.
    pub material_names: Arc<[String]>,
    /// The objects that are not meshes.
    pub objects: Arc<[Object]>,
    /// Every mesh face, after the objects in the id space.
    pub meshes: Arc<Meshes>,
    /// Primitives without bounds (planes), always tested one by one.
    pub unbounded: Arc<[u32]>,
    /// Bounded primitives when there are few of them.
    pub bounded: Arc<[u32]>,
    /// BVH over bounded primitives when there are many (`bounded` is then
    /// empty).
    pub bvh: Arc<Bvh>,
    /// The same primitives in a BVH built in the light's frame, for
    /// shadow-ray packets (from [`PACKET_THRESHOLD`] of them on).
    pub shadow_bvh: Option<Arc<OccluderBvh>>,
    /// Union of the bounded primitives' bounds.
    pub object_bounds: Option<Aabb>,
    /// Per object (by id), a plane's signed distances of the light's four
    /// corners (0 for other objects): the shadow culling compares them
    /// with each hit point's, so they are computed once per light.
    pub light_sides: Arc<[[f64; 4]]>,
    /// Size of the scene's finite part (bounded objects, light, camera):
    /// the floor of ray offsets near the origin.
    pub scale: f64,
    /// Triangles in the scene (`triangle` objects and mesh faces), and the
    /// zero-area ones left out.
    pub triangles: usize,
    pub degenerate_triangles: usize,
}

/// Each plane object's signed distances of the light's corners (see
/// [`Scene::light_sides`]).
fn light_sides(objects: &[Object], light: &AreaLight) -> Arc<[[f64; 4]]> {
    let corners = light.shape.corners();
    objects
        .iter()
        .map(|o| match &o.shape {
            Shape::Plane(pl) => corners.map(|c| pl.signed_distance(c)),
            _ => [0.0; 4],
        })
        .collect()
}

/// Address space the scene's trees take at most while they are built, per
/// bounded object or triangle (131 and 141 bytes measured with 4 M and
/// 0.5 M triangles): checked first, so that a scene whose trees do not fit
/// is refused naming its objects rather than ended by the allocator.
const TREE_BYTES: usize = 160;

impl Scene {
    /// Builds the runtime scene of a description that
    /// [`SceneDesc::validate`] accepted (see [`Loaded`] for both steps).
    pub fn build(desc: &SceneDesc) -> Result<Scene, SceneError> {
        use rayon::prelude::*;
        super::math::release_free_memory();
        let material_names: Vec<String> = desc.materials.keys().cloned().collect();
        let mut objects: Vec<Object> = Vec::with_capacity(desc.objects.len());
        let mut meshes = Meshes::default();
        let mut triangles = 0usize;
        let mut degenerate = 0usize;
        for (index, o) in desc.objects.iter().enumerate() {
            let material = material_names
                .binary_search_by(|n| n.as_str().cmp(o.material()))
                .expect("validated material name") as u32;
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
                    let _working = super::memory::working(
                        super::memory::Work::Part,
                        format!("objects[{index}].file {}", mesh::quoted_file(&m.file)),
                    );
                    let part = mesh::load(m, desc.base_dir.as_deref(), budget)
                        .map_err(|e| SceneError::new(format!("objects[{index}].file"), e))?;
                    let first = meshes.len();
                    let skipped = part
                        .check_range(super::scene_file::limits::MAX_COORD)
                        .and_then(|()| meshes.add(part, material))
                        .map_err(|e| {
                            SceneError::new(
                                format!("objects[{index}]"),
                                format!("{}: {e}", mesh::quoted_file(&m.file)),
                            )
                        })?;
                    triangles += meshes.len() - first;
                    degenerate += skipped;
                    continue;
                }
            };
            let bounds = shape.bounds();
            objects.push(Object {
                shape,
                material,
                bounds,
            });
        }
        if objects.len() + meshes.len() > u32::MAX as usize / 4 {
            return Err(SceneError::new("objects", "too many objects"));
        }
        let objects: Arc<[Object]> = objects.into();
        let meshes = Arc::new(meshes);
        let _working = super::memory::working(
            super::memory::Work::Part,
            format!(
                "the trees of {} objects and {} triangles",
                objects.len(),
                meshes.len()
            ),
        );

        let n = objects.len() as u32;
        let mut unbounded = Vec::new();
        let mut bounded_objects = Vec::new();
        let mut object_bounds: Option<Aabb> = None;
        for (i, o) in objects.iter().enumerate() {
            match o.bounds {
                Some(b) => {
                    bounded_objects.push(i as u32);
                    object_bounds = Some(object_bounds.map_or(b, |a| a.union(b)));
                }
                None => unbounded.push(i as u32),
            }
        }
        let face_bounds = (0..meshes.len() as u32)
            .into_par_iter()
            .map(|f| meshes.bounds(f))
            .reduce(|| Aabb::EMPTY, Aabb::union);
        if !meshes.is_empty() {
            object_bounds = Some(object_bounds.map_or(face_bounds, |a| a.union(face_bounds)));
        }
        let light = AreaLight::new(&desc.light);
        let camera = Camera::new(&desc.camera);
        let scale = scale_of(object_bounds, &light, &camera);
        let with_bounds = bounded_objects.len() + meshes.len();
        let faces = n..n + meshes.len() as u32;
        // One tree after the other: the records of one build, the tree
        // being built and the finished one are what is held at most.
        super::memory::check_build_memory(with_bounds.saturating_mul(TREE_BYTES)).map_err(|e| {
            SceneError::new(
                "objects",
                format!("the trees of {with_bounds} objects and triangles need {e}"),
            )
        })?;
        let shadow_bvh = (with_bounds >= PACKET_THRESHOLD).then(|| {
            Arc::new(OccluderBvh::new(
                &light,
                &bounded_objects,
                faces.clone(),
                |i| primitive(&objects, &meshes, i),
            ))
        });
        let (bounded, bvh): (Vec<u32>, Bvh) = if with_bounds > BVH_THRESHOLD {
            let item = |k: usize| match bounded_objects.get(k) {
                Some(&i) => (i, objects[i as usize].bounds.expect("bounded")),
                None => {
                    let f = (k - bounded_objects.len()) as u32;
                    (n + f, meshes.bounds(f))
                }
            };
            let b = Bvh::build_with(with_bounds, item, DVec3::ONE);
            (Vec::new(), b)
        } else {
            let mut ids = bounded_objects.clone();
            ids.extend(faces.clone());
            (ids, Bvh::default())
        };
        super::math::release_free_memory();
        Ok(Scene {
            light_sides: light_sides(&objects, &light),
            camera,
            light,
            material_names: material_names.into(),
            objects,
            meshes,
            unbounded: unbounded.into(),
            bounded: bounded.into(),
            bvh: Arc::new(bvh),
            shadow_bvh,
            object_bounds,
            scale,
            triangles,
            degenerate_triangles: degenerate,
        })
    }

    /// The same objects seen by `desc`'s camera under `desc`'s light: the
    /// objects, meshes and their BVH are shared, the light-frame BVH is
    /// built again only if the light moved (a camera or light edit is a
    /// re-trace, not a rebuild).
    pub fn with_view(&self, desc: &SceneDesc) -> Scene {
        let light = AreaLight::new(&desc.light);
        let camera = Camera::new(&desc.camera);
        let (a, b) = (&light.shape, &self.light.shape);
        let moved = (a.corner, a.edge_u, a.edge_v) != (b.corner, b.edge_u, b.edge_v);
        Scene {
            light_sides: light_sides(&self.objects, &light),
            scale: scale_of(self.object_bounds, &light, &camera),
            shadow_bvh: if moved {
                self.build_shadow_bvh(&light)
            } else {
                self.shadow_bvh.clone()
            },
            camera,
            light,
            ..self.clone()
        }
    }

    /// Primitive `id` (an object's shape or a mesh face).
    #[inline]
    pub fn primitive(&self, id: u32) -> Primitive<'_> {
        primitive(&self.objects, &self.meshes, id)
    }

    /// Nearest intersection of primitive `id` with `t` in (0, t_max).
    /// Inlined: the BVH walks call it per object from the tile kernel.
    #[inline(always)]
    pub fn intersect(&self, id: u32, ray: &Ray, t_max: f64) -> Option<f64> {
        match self.objects.get(id as usize) {
            Some(o) => o.shape.intersect(ray, t_max),
            None => self
                .meshes
                .intersect(id - self.objects.len() as u32, ray, t_max),
        }
    }

    /// The surface point of a hit on primitive `id` found by
    /// [`Scene::intersect`]. Inlined, so that the tile kernel's hit points
    /// are computed with its CPU features (the same operations, so the same
    /// bits).
    #[inline(always)]
    pub fn surface(&self, id: u32, ray: &Ray, t: f64) -> SurfacePoint {
        match self.objects.get(id as usize) {
            Some(o) => o.shape.surface(ray, t),
            None => self.meshes.surface(id - self.objects.len() as u32, ray, t),
        }
    }

    /// A plane object's signed distances of the light's four corners (0
    /// for other primitives).
    #[inline]
    pub fn light_sides_of(&self, id: u32) -> [f64; 4] {
        self.light_sides
            .get(id as usize)
            .copied()
            .unwrap_or([0.0; 4])
    }

    /// Bounds of primitive `id` (`None` for planes).
    #[inline]
    pub fn bounds_of(&self, id: u32) -> Option<Aabb> {
        match self.objects.get(id as usize) {
            Some(o) => o.bounds,
            None => Some(self.meshes.bounds(id - self.objects.len() as u32)),
        }
    }

    /// Material index of primitive `id`.
    pub fn material_of(&self, id: u32) -> u32 {
        match self.objects.get(id as usize) {
            Some(o) => o.material,
            None => self.meshes.material(id - self.objects.len() as u32),
        }
    }

    /// Primitives in the scene (objects and mesh faces).
    pub fn primitive_count(&self) -> usize {
        self.objects.len() + self.meshes.len()
    }

    /// The light-frame BVH of the bounded primitives under `light`, from
    /// [`PACKET_THRESHOLD`] of them on.
    fn build_shadow_bvh(&self, light: &AreaLight) -> Option<Arc<OccluderBvh>> {
        let n = self.objects.len() as u32;
        let bounded: Vec<u32> = (0..n)
            .filter(|&i| self.objects[i as usize].bounds.is_some())
            .collect();
        (bounded.len() + self.meshes.len() >= PACKET_THRESHOLD).then(|| {
            let faces = n..n + self.meshes.len() as u32;
            let prim = |i| self.primitive(i);
            Arc::new(OccluderBvh::new(light, &bounded, faces, prim))
        })
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
            if let Some(t) = self.intersect(i, ray, t_max) {
                best = Some((HitTarget::Object(i), t));
                t_max = t;
            }
        }
        if let Some((i, t)) = self
            .bvh
            .closest(ray, t_max, |i, t_max| self.intersect(i, ray, t_max))
        {
            best = Some((HitTarget::Object(i), t));
        }
        best
    }

    /// [`Scene::closest_hit`] of each of `rays` into `out`, [`RAY_LANES`]
    /// rays at a time: each object tested against all of them in turn
    /// (the tests of different rays overlap instead of each waiting for
    /// the one before), each shape's test written out for it. Every ray
    /// meets the tests in the same order with the same operations, so
    /// each finds the same hit and distance.
    #[inline(always)]
    pub(crate) fn closest_hits(&self, rays: &[Ray], out: &mut Vec<Option<(HitTarget, f64)>>) {
        out.clear();
        for chunk in rays.chunks(RAY_LANES) {
            let mut t_max = [f64::INFINITY; RAY_LANES];
            let mut best = [None; RAY_LANES];
            for (j, ray) in chunk.iter().enumerate() {
                if let Some(t) = self.light.shape.intersect(ray, t_max[j]) {
                    (best[j], t_max[j]) = (Some(HitTarget::Light), t);
                }
            }
            for &i in self.unbounded.iter().chain(self.bounded.iter()) {
                let (t_max, best) = (&mut t_max, &mut best);
                match self.primitive(i) {
                    Primitive::Shape(Shape::Plane(s)) => {
                        nearer(i, chunk, t_max, best, |r, t| s.intersect(r, t))
                    }
                    Primitive::Shape(Shape::Sphere(s)) => {
                        nearer(i, chunk, t_max, best, |r, t| s.intersect(r, t))
                    }
                    Primitive::Shape(Shape::Cuboid(s)) => {
                        nearer(i, chunk, t_max, best, |r, t| s.intersect(r, t))
                    }
                    _ => nearer(i, chunk, t_max, best, |r, t| self.intersect(i, r, t)),
                }
            }
            for (j, ray) in chunk.iter().enumerate() {
                if let Some((i, t)) = self
                    .bvh
                    .closest(ray, t_max[j], |i, t_max| self.intersect(i, ray, t_max))
                {
                    (best[j], t_max[j]) = (Some(HitTarget::Object(i)), t);
                }
                out.push(best[j].map(|target| (target, t_max[j])));
            }
        }
    }

    /// [`Scene::closest_hit`] for a camera ray: with `cutaway`, planes
    /// seen from behind (the ray runs along their normal) are passed
    /// through, so a camera outside a room sees into it. Only camera rays
    /// ever use this; shadow and reflected rays meet every plane.
    pub fn camera_hit(&self, ray: &Ray, cutaway: bool) -> Option<(HitTarget, f64)> {
        if !cutaway {
            return self.closest_hit(ray);
        }
        let all = self.unbounded.iter().chain(self.bounded.iter());
        self.camera_hit_among(ray, true, true, all.copied())
    }

    /// [`Scene::camera_hit`] testing, of the unbounded and bounded
    /// objects, only `objects` (a subsequence of them that leaves out only
    /// objects the ray misses: the same hit), the light only if `light`
    /// (false only if the ray misses it), the BVH as ever.
    pub fn camera_hit_among(
        &self,
        ray: &Ray,
        cutaway: bool,
        light: bool,
        objects: impl IntoIterator<Item = u32>,
    ) -> Option<(HitTarget, f64)> {
        let mut best: Option<(HitTarget, f64)> = None;
        let mut t_max = f64::INFINITY;
        if light && let Some(t) = self.light.shape.intersect(ray, t_max) {
            best = Some((HitTarget::Light, t));
            t_max = t;
        }
        for i in objects {
            if cutaway
                && let Primitive::Shape(Shape::Plane(p)) = self.primitive(i)
                && p.normal.dot(ray.dir) > 0.0
            {
                continue;
            }
            if let Some(t) = self.intersect(i, ray, t_max) {
                best = Some((HitTarget::Object(i), t));
                t_max = t;
            }
        }
        if let Some((i, t)) = self
            .bvh
            .closest(ray, t_max, |i, t_max| self.intersect(i, ray, t_max))
        {
            best = Some((HitTarget::Object(i), t));
        }
        best
    }

    /// Where the shadow rays of a smooth triangle's hit start: the point
    /// lifted by its shadow offset, unless something (another surface, the
    /// light) lies between the two, in which case the point itself, so
    /// that a ray never starts beyond a surface it should meet. `normal`:
    /// the geometric normal facing the ray.
    #[inline(always)]
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
        &self.material_names[self.material_of(object) as usize]
    }
}

/// Primitive `id` of a scene with these objects and meshes.
#[inline]
fn primitive<'a>(objects: &'a [Object], meshes: &'a Meshes, id: u32) -> Primitive<'a> {
    match objects.get(id as usize) {
        Some(o) => Primitive::Shape(&o.shape),
        None => Primitive::Face {
            meshes,
            face: id - objects.len() as u32,
        },
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

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::render::rng::Rng;
    use crate::render::scene_file::{ObjectDesc, TriangleDesc};

    /// Planes, a turned box, a sphere and a tilted rect under a light (as
    /// the shadow rays in lanes take them: no triangle).
    pub(crate) const SHAPES_ROOM: &str = r#"{
      "format": 1,
      "camera": { "position": [0, 4, -14], "look_at": [0, 3.5, 0], "up": [0, 1, 0],
                  "fov_y_deg": 36, "width": 64, "height": 36 },
      "render": { "shadow_rays": 4, "sampling": "random", "max_depth": 2, "seed": 1,
                  "area_light_model": "sampled",
                  "terms": { "ambient": 1.0, "diffuse": 1.0, "specular": 1.0 },
                  "background": [0, 0, 0] },
      "light": { "corner": [-1, 7.99, -1], "edge_u": [2, 0, 0], "edge_v": [0, 0, 2],
                 "ambient": [0.1, 0.1, 0.1], "diffuse": [0.9, 0.9, 0.9], "specular": [1, 1, 1] },
      "materials": { "m": { "ambient": [0.5, 0.5, 0.5], "diffuse": [0.5, 0.5, 0.5],
                            "specular": [0.3, 0.3, 0.3], "shininess": 20, "reflectivity": 0.0 } },
      "objects": [
        { "type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "m" },
        { "type": "plane", "point": [0, 8, 0], "normal": [0, -1, 0], "material": "m" },
        { "type": "plane", "point": [5, 0, 0], "normal": [-1, 0, 0], "material": "m" },
        { "type": "box", "min": [-1, 0, -1], "max": [1, 3, 1], "rotate_y_deg": 30,
          "translate": [1, 0, 1], "material": "m" },
        { "type": "sphere", "center": [-2, 2.5, 0], "radius": 1, "material": "m" },
        { "type": "rect", "corner": [-1, 5, -2], "edge_u": [2, 0, 0.5], "edge_v": [0, 0.4, 2],
          "material": "m" }
      ]
    }"#;

    /// Rays from anywhere in a room of every kind of shape, in chunks of
    /// every length: each finds, side by side, what it finds alone (the
    /// same object or the light, the same distance), and the rays meet
    /// every object and the light.
    #[test]
    fn rays_side_by_side_find_what_each_finds_alone() {
        // The lanes' room and a triangle.
        let mut desc = SceneDesc::from_json(SHAPES_ROOM).expect("the test room");
        desc.objects.push(ObjectDesc::Triangle(TriangleDesc {
            vertices: [[-4.0, 1.0, 3.0], [-2.0, 4.0, 3.0], [-3.0, 1.0, 1.0]],
            material: "m".into(),
        }));
        let loaded = Loaded::new(&desc).expect("the test room");
        let scene = &loaded.scene;
        let mut rng = Rng::new(11);
        let mut r = |lo: f64, hi: f64| lo + (hi - lo) * rng.next_f64();
        let mut met = Vec::new();
        let mut hits = Vec::new();
        for length in 1..=40 {
            let rays: Vec<Ray> = (0..length)
                .map(|_| {
                    let origin = DVec3::new(r(-4.9, 4.9), r(0.1, 7.9), r(-4.9, 4.9));
                    let dir = DVec3::new(r(-1.0, 1.0), r(-1.0, 1.0), r(-1.0, 1.0));
                    Ray::new(origin, dir.normalize())
                })
                .collect();
            scene.closest_hits(&rays, &mut hits);
            assert_eq!(hits.len(), rays.len());
            for (ray, &hit) in rays.iter().zip(&hits) {
                assert_eq!(hit, scene.closest_hit(ray), "{ray:?}");
                met.push(hit.map(|(target, _)| target));
            }
        }
        let objects = (0..7).map(|i| Some(HitTarget::Object(i)));
        for target in objects.chain([Some(HitTarget::Light)]) {
            assert!(met.contains(&target), "no ray met {target:?}");
        }
    }
}
