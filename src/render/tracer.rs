//! Whitted-style tracing of one camera path: local Phong shading at each
//! hit plus the mirrored ray, weighted by reflectivity, up to `max_depth`
//! hits.
//!
//! A path can be traced for its colour alone (a one-shot render) or also
//! recorded hit by hit ([`PathSink`]) so that an edit of a shading
//! parameter can recompute the colour without tracing (`live/`). Both run
//! the same code, and [`replay`] repeats the colour arithmetic of
//! [`Tracer::pixel`] operation for operation, so the two give the same bits.

use glam::{DVec3, Vec3};

use super::exact::WholeLights;
use super::geometry::{Ray, spawn_origin};
use super::live::record::ColourHit;
use super::math::avx2_dispatch;
use super::pixel_filter::PixelFilter;
use super::progressive::{CancelToken, TileRect};
use super::rng::Rng;
use super::sampled_lanes::{LaneHit, LaneInputs, SampledLanes};
use super::sampling::Pattern;
use super::scene::{HitTarget, Scene};
use super::scene_file::AreaLightModel;
use super::settings::RenderSettings;
use super::shading::{
    LightTerms, Lit, Needs, PhongColours, ShadingPoint, Shadows, any_visible, exact_terms,
    light_points_generic, light_terms, model_terms, nearest_point_specular_direction,
};
use super::shading_params::ShadingParams;
use super::shadow::{HitLanes, LANE_RAYS, ShadowBuffers, ShadowQuery, lanes_fit};
use super::stats::RayStats;
use super::tile_frustum::{TileTargets, camera_objects};

/// Why a path ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PathEnd {
    /// Nothing was hit: the background.
    Background,
    /// The light was hit (seen as its diffuse colour).
    Light,
    /// The last hit reached `max_depth`.
    MaxDepth,
    /// The last hit's material does not reflect.
    Absorbed,
}

/// One recorded hit: what the colour needs besides the shading parameters,
/// and what a new shininess needs to recompute the specular factor.
#[derive(Debug, Clone, Copy)]
pub struct HitRecord {
    pub material: u32,
    /// The object the path's ray met, and at what distance along it.
    pub object: u32,
    pub t: f64,
    pub factors: LightTerms,
    /// `sampled`/`analytic`: light corner − hit point; `nearest_point`: the
    /// specular light direction (zero: no specular).
    pub to_light: Vec3,
    pub normal: Vec3,
    pub view: Vec3,
}

/// Receives a path's hits as they are traced.
pub trait PathSink {
    /// Whether to compute every light factor (a recorded path must serve
    /// any later colour) instead of only those the colours need.
    const RECORD: bool;
    /// Whether [`PathSink::nearest`] finds a path's camera hit with `find`
    /// (false: the sink knows most of them, and a tile does not search
    /// its rows' camera rays ahead).
    const FINDS_CAMERA_HITS: bool = true;
    /// The nearest hit of the path's ray at `depth` (1: the camera ray):
    /// what `find` finds, unless the sink knows it without intersecting
    /// (`live/relight.rs`).
    #[inline(always)]
    fn nearest(
        &mut self,
        _depth: u32,
        _ray: &Ray,
        find: impl FnOnce() -> Option<(HitTarget, f64)>,
    ) -> Option<(HitTarget, f64)> {
        find()
    }
    /// A hit with its factors; `buf` holds its light points' visibility
    /// as it was traced. Returns the hit's index among the sink's hits.
    fn hit(&mut self, hit: HitRecord, buf: &ShadowBuffers, count: usize) -> usize;
    /// The factors of hit `index`, recorded before they were known (the
    /// hits a tile shades side by side, see [`Tracer::trace_rect`]).
    fn set_factors(&mut self, index: usize, factors: LightTerms);
    /// The visibility of hit `index`'s light points (bit j: point j; at
    /// most 64), recorded before its shadow rays were traced (the hits
    /// whose rays a tile traces side by side, [`HitLanes`]), as 0.
    fn set_visible(&mut self, index: usize, bits: u64);
    fn end(&mut self, end: PathEnd);
}

/// A one-shot render records nothing.
impl PathSink for () {
    const RECORD: bool = false;
    #[inline(always)]
    fn hit(&mut self, _: HitRecord, _: &ShadowBuffers, _: usize) -> usize {
        0
    }
    #[inline(always)]
    fn set_factors(&mut self, _: usize, _: LightTerms) {}
    #[inline(always)]
    fn set_visible(&mut self, _: usize, _: u64) {}
    #[inline(always)]
    fn end(&mut self, _: PathEnd) {}
}

/// Where a path's camera ray finds its nearest hit.
#[derive(Debug, Clone, Copy)]
enum CameraHit<'t> {
    /// Among the tile's objects, if known, else the scene's.
    Search(Option<&'t TileTargets>),
    /// Already found: a row's camera rays searched side by side
    /// ([`TileTargets::nearest_of_rays`]).
    Found(Option<(HitTarget, f64)>),
}

/// Traces pixels of one scene at one shadow-ray count.
pub struct Tracer<'a> {
    pub scene: &'a Scene,
    pub settings: &'a RenderSettings,
    pub shading: &'a ShadingParams,
    pub pattern: Pattern,
    /// Where a pixel's camera samples go, with more than one per pixel.
    filter: Option<PixelFilter>,
    /// Each material's needs and colours, computed once instead of per hit.
    material_terms: Vec<MaterialTerms>,
    /// Whether [`Tracer::tile`] traces the shadow rays of its hits side by
    /// side ([`HitLanes`]): few light points per hit, few objects.
    shadows_in_lanes: bool,
}

/// What [`Tracer::tile`] multiplies a material's light factors by, and
/// which factors it needs ([`Needs::of`], [`PhongColours::new`]: the same
/// values).
#[derive(Debug, Clone, Copy)]
struct MaterialTerms {
    needs: Needs,
    colours: PhongColours,
}

/// Per-thread scratch space of a tracer.
pub struct TraceScratch {
    pub shadow: ShadowBuffers,
    pub stats: RayStats,
    /// [`Tracer::tile`]'s hits waiting for their factors, its terms and
    /// their factors.
    lanes: SampledLanes,
    terms: Vec<Term>,
    factors: Vec<LightTerms>,
    /// A recording sink's index of each waiting hit.
    factor_hits: Vec<u32>,
    /// A recording sink's hits traced in [`HitLanes`], with their
    /// visibility bits.
    hit_visibility: Vec<(u32, u64)>,
    /// [`Tracer::tile`]'s hits waiting for their shadow rays, and their
    /// index in `factors` and lane data.
    shadow_lanes: HitLanes,
    shadow_index: Vec<(usize, bool)>,
    shadow_inputs: LaneInputs,
    /// What [`Tracer::tile`]'s camera rays test.
    camera_objects: TileTargets,
    /// One row of a tile's camera rays (or one depth's reflected rays),
    /// and their nearest hits.
    camera_rays: Vec<Ray>,
    camera_hits: Vec<Option<(HitTarget, f64)>>,
    /// [`Tracer::tile`]'s paths waiting for their reflected rays' hits at
    /// one depth, and at the next; each path's colour.
    reflections: Vec<Reflection>,
    next_reflections: Vec<Reflection>,
    path_sums: Vec<Vec3>,
    /// [`Tracer::tile`]'s `exact` points that see the whole light, waiting
    /// to be taken side by side.
    whole_lights: WholeLights,
}

impl<'a> Tracer<'a> {
    /// A tracer using `shadow_rays` (instead of the settings') per hit
    /// point.
    pub fn new(
        scene: &'a Scene,
        settings: &'a RenderSettings,
        shading: &'a ShadingParams,
        shadow_rays: u32,
    ) -> Tracer<'a> {
        let pattern = Pattern::new(settings.sampling, shadow_rays);
        let shadows_in_lanes = settings.model == AreaLightModel::Sampled
            && settings.skip
            && settings.shadows
            && !settings.adaptive
            && pattern.count() <= LANE_RAYS
            && lanes_fit(scene);
        Tracer {
            scene,
            settings,
            shading,
            pattern,
            shadows_in_lanes,
            filter: (settings.samples_per_pixel > 1).then(|| PixelFilter::new(settings.filter)),
            material_terms: shading
                .materials
                .iter()
                .map(|m| MaterialTerms {
                    needs: Needs::of(m, &shading.light, settings.terms),
                    colours: PhongColours::new(m, &shading.light, settings.terms),
                })
                .collect(),
        }
    }

    /// Camera samples per pixel.
    pub fn samples(&self) -> u32 {
        self.settings.samples_per_pixel
    }

    pub fn scratch(&self) -> TraceScratch {
        TraceScratch {
            shadow: ShadowBuffers::with_capacity(self.pattern.count()),
            stats: RayStats::default(),
            lanes: SampledLanes::default(),
            terms: Vec::new(),
            factors: Vec::new(),
            factor_hits: Vec::new(),
            shadow_lanes: HitLanes::default(),
            shadow_index: Vec::new(),
            shadow_inputs: LaneInputs::default(),
            hit_visibility: Vec::new(),
            camera_objects: TileTargets::default(),
            camera_rays: Vec::new(),
            camera_hits: Vec::new(),
            reflections: Vec::new(),
            next_reflections: Vec::new(),
            path_sums: Vec::new(),
            whole_lights: WholeLights::default(),
        }
    }

    /// Linear RGB of pixel (x, y).
    #[inline]
    pub fn pixel(&self, x: u32, y: u32, scratch: &mut TraceScratch) -> Vec3 {
        self.trace(x, y, scratch, &mut ())
    }

    /// Linear RGB of pixel (x, y), handing every hit of every camera
    /// sample's path to `sink`, sample by sample. One sample is the ray
    /// through the pixel centre; several are placed by the filter and
    /// averaged.
    pub fn trace<S: PathSink>(
        &self,
        x: u32,
        y: u32,
        scratch: &mut TraceScratch,
        sink: &mut S,
    ) -> Vec3 {
        let camera = &self.scene.camera;
        let Some(filter) = &self.filter else {
            let mut colour = Sum(Vec3::ZERO);
            let ray = camera.pixel_ray(x, y);
            let camera_hit = CameraHit::Search(None);
            self.trace_path(x, y, 0, &ray, camera_hit, scratch, sink, &mut colour);
            return colour.0;
        };
        let mut sum = Vec3::ZERO;
        for (sample, ray) in (0..).zip(self.sample_rays(filter, x, y)) {
            let mut colour = Sum(Vec3::ZERO);
            let camera_hit = CameraHit::Search(None);
            self.trace_path(x, y, sample, &ray, camera_hit, scratch, sink, &mut colour);
            sum += colour.0;
        }
        sum * (1.0 / self.settings.samples_per_pixel as f32)
    }

    /// The camera rays of pixel (x, y)'s samples, in order, placed by the
    /// filter.
    fn sample_rays<'s>(
        &'s self,
        filter: &'s PixelFilter,
        x: u32,
        y: u32,
    ) -> impl Iterator<Item = Ray> + 's {
        let pixel_seed = Rng::for_sample(self.settings.camera_seed, x, y, 0, 0).next_u64() as u32;
        (0..self.settings.samples_per_pixel).map(move |sample| {
            let (px, py) = filter.position(x, y, sample, pixel_seed);
            self.scene.camera.ray(px, py)
        })
    }

    /// Camera paths per pixel: the samples placed by the filter, or one
    /// through the pixel's centre.
    fn paths_per_pixel(&self) -> u32 {
        match self.filter {
            Some(_) => self.settings.samples_per_pixel,
            None => 1,
        }
    }

    /// Linear RGB of the pixels of `rect` (rows packed) into `out`, as
    /// [`Tracer::pixel`] gives each (the same bits): the camera rays test
    /// only the objects the tile's rays may meet ([`camera_objects`]), the
    /// reflected rays (under every model) wait for the tile's camera rays
    /// and are searched side by side, depth by depth
    /// ([`Scene::closest_hits`]), and the colours are summed path by path
    /// in their order. Under the `sampled` model the paths' hits
    /// also wait for their light factors in [`SampledLanes`] and are shaded
    /// [`LANES`](super::sampled_lanes::LANES) at a time. With several camera samples per
    /// pixel the tile's objects are those the filter's reach around its
    /// pixels may meet, and each pixel's paths are summed and averaged as
    /// [`Tracer::trace`] sums them. False if cancelled part-way.
    pub fn tile(
        &self,
        rect: TileRect,
        cancel: &CancelToken,
        scratch: &mut TraceScratch,
        out: &mut Vec<Vec3>,
    ) -> bool {
        self.per_tile(rect, scratch, |objects, scratch| {
            tile_in_lanes(self, rect, objects, cancel, scratch, &mut (), out)
        })
    }

    /// `work` for tile `rect` with the objects its camera rays may meet
    /// ([`camera_objects`]), the thread's occluder lists checked against
    /// the scene once for all its hit points.
    #[inline(always)]
    fn per_tile<R>(
        &self,
        rect: TileRect,
        scratch: &mut TraceScratch,
        work: impl FnOnce(&TileTargets, &mut TraceScratch) -> R,
    ) -> R {
        let mut objects = std::mem::take(&mut scratch.camera_objects);
        let reach = self.filter.as_ref().map_or(0.0, PixelFilter::reach);
        camera_objects(self.scene, rect, reach, &mut objects);
        scratch.shadow.start_tile(self.scene);
        let result = work(&objects, scratch);
        scratch.shadow.end_tile();
        scratch.camera_objects = objects;
        result
    }

    /// The pixels of `rect` (rows packed) into `out`, each path given to
    /// `sink`, as [`Tracer::trace`] gives them (the same bits), traced as
    /// [`Tracer::tile`] traces them ([`tile_in_lanes`]): a recording
    /// sink's hits are recorded as they are met, their factors (and under
    /// the `sampled` model their visibility) set once the lanes have them.
    /// The camera rays test only the tile's [`camera_objects`], and every
    /// tile's hit points check the thread's occluder lists once
    /// ([`Tracer::per_tile`]). False if cancelled part-way.
    pub fn trace_rect<S: PathSink>(
        &self,
        rect: TileRect,
        cancel: &CancelToken,
        scratch: &mut TraceScratch,
        sink: &mut S,
        out: &mut Vec<Vec3>,
    ) -> bool {
        out.clear();
        self.per_tile(rect, scratch, |objects, scratch| {
            tile_in_lanes(self, rect, objects, cancel, scratch, sink, out)
        })
    }

    /// What a recording sink keeps of hit `sp` (object `object` at
    /// distance `t` along its ray) with light factors `factors`.
    #[inline(always)]
    fn hit_record(&self, sp: &ShadingPoint, t: f64, factors: LightTerms) -> HitRecord {
        let to_light = match self.settings.model {
            AreaLightModel::NearestPoint => nearest_point_specular_direction(self.scene, sp),
            // The directions the shadow rays took: from the shadow point
            // (lifted on smooth triangles).
            _ => (self.scene.light.shape.corner - sp.shadow.point).as_vec3(),
        };
        HitRecord {
            material: sp.material_index,
            object: sp.shadow.object,
            t,
            factors,
            to_light,
            normal: sp.normal.as_vec3(),
            view: sp.view.as_vec3(),
        }
    }

    /// One camera sample's path, its linear RGB added to `colour`;
    /// `camera_hit`: where its camera ray finds its nearest hit.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn trace_path<S: PathSink, C: PathColour>(
        &self,
        x: u32,
        y: u32,
        sample: u32,
        camera_ray: &Ray,
        camera_hit: CameraHit,
        scratch: &mut TraceScratch,
        sink: &mut S,
        colour: &mut C,
    ) {
        let (scene, s) = (self.scene, self.settings);
        scratch.stats.camera += 1;
        let mut weight = 1.0f32;
        // The camera ray read where the row's rays are, not copied: a copy
        // to the stack was two overlapping 32-byte stores, and reading its
        // direction back across them stalled every path (the load waits
        // for both stores to reach the cache).
        let mut ray = camera_ray;
        let mut reflected: Ray;
        for depth in 1..=s.max_depth {
            // Only the camera ray (depth 1) may cut away planes.
            // Inlined, so that it is compiled for the caller's CPU features.
            let hit = sink.nearest(
                depth,
                ray,
                #[inline(always)]
                || {
                    if depth == 1 {
                        match camera_hit {
                            CameraHit::Search(Some(tile)) => tile.nearest(scene, ray, s.cutaway),
                            CameraHit::Search(None) => scene.camera_hit(ray, s.cutaway),
                            CameraHit::Found(hit) => hit,
                        }
                    } else {
                        scene.closest_hit(ray)
                    }
                },
            );
            let at = PathStep {
                x,
                y,
                sample,
                depth,
                weight,
            };
            let Some(next) = self.path_hit(at, ray, hit, scratch, sink, colour) else {
                break;
            };
            (reflected, weight) = next;
            ray = &reflected;
        }
    }

    /// The hit `hit` of a path's ray `ray` at step `at`: its colour (or
    /// the background's, or the light's) added to `colour` times the path
    /// weight; the reflected ray and its weight if the path goes on.
    #[inline(always)]
    fn path_hit<S: PathSink, C: PathColour>(
        &self,
        at: PathStep,
        ray: &Ray,
        hit: Option<(HitTarget, f64)>,
        scratch: &mut TraceScratch,
        sink: &mut S,
        colour: &mut C,
    ) -> Option<(Ray, f32)> {
        let (scene, s, shading) = (self.scene, self.settings, self.shading);
        let PathStep {
            x,
            y,
            sample,
            depth,
            weight,
        } = at;
        let Some((target, t)) = hit else {
            colour.add(s.background, weight);
            sink.end(PathEnd::Background);
            return None;
        };
        let object = match target {
            HitTarget::Light => {
                colour.add(shading.light.diffuse, weight);
                sink.end(PathEnd::Light);
                return None;
            }
            HitTarget::Object(i) => i,
        };
        let surface = scene.surface(object, ray, t);
        let material_index = scene.material_of(object);
        let inside = surface.normal.dot(ray.dir) > 0.0;
        let (normal, shading_normal) = if inside {
            (-surface.normal, -surface.shading)
        } else {
            (surface.normal, surface.shading)
        };
        let shadow_point = if surface.shadow_offset == DVec3::ZERO {
            surface.point
        } else {
            scene.lifted_shadow_point(&surface, normal)
        };
        let material = &shading.materials[material_index as usize];
        let sp = ShadingPoint {
            point: surface.point,
            normal: shading_normal,
            view: -ray.dir,
            shadow: ShadowQuery {
                point: shadow_point,
                normal,
                object,
                inside,
            },
            material,
            material_index,
        };
        // A fixed pattern draws no random numbers: its hits need no
        // stream of their own.
        let mut rng = if self.pattern.is_fixed() {
            Rng::new(0)
        } else {
            Rng::for_sample(s.seed, x, y, sample, depth)
        };
        colour.hit(self, &sp, &mut rng, scratch, weight, sink, t);

        if material.reflectivity == 0.0 || depth == s.max_depth {
            sink.end(if material.reflectivity == 0.0 {
                PathEnd::Absorbed
            } else {
                PathEnd::MaxDepth
            });
            return None;
        }
        // About the shading normal, unless that would send the ray
        // into the surface.
        let mut mirrored = reflect(ray.dir, shading_normal);
        if mirrored.dot(normal) <= 0.0 {
            mirrored = reflect(ray.dir, normal);
        }
        // Traced whatever the path weight: however faint, the rest of
        // the path may meet a light or surface bright enough to matter
        // (colours reach 10⁶), and the scene format sums every hit up
        // to `max_depth`.
        scratch.stats.reflected += 1;
        let reflected = Ray::new(spawn_origin(surface.point, normal, scene.scale), mirrored);
        Some((reflected, weight * material.reflectivity))
    }
}

/// Where a path is: its pixel, camera sample and hit (1: the camera
/// ray's), and its weight there.
#[derive(Debug, Clone, Copy)]
struct PathStep {
    x: u32,
    y: u32,
    sample: u32,
    depth: u32,
    weight: f32,
}

impl PathStep {
    /// The camera ray's hit of sample `sample` of pixel (x, y).
    fn camera(x: u32, y: u32, sample: u32) -> PathStep {
        PathStep {
            x,
            y,
            sample,
            depth: 1,
            weight: 1.0,
        }
    }
}

/// A tile's path waiting for its reflected ray's hit: the step it is at,
/// the ray, and the path's index in the tile (see [`Deferred::path`]).
#[derive(Debug, Clone, Copy)]
struct Reflection {
    at: PathStep,
    ray: Ray,
    path: u32,
}

avx2_dispatch!(
    /// The pixels of `rect` with their hits shaded side by side, each
    /// path given to `sink` ([`Tracer::tile`] with `()`, and
    /// [`Tracer::trace_rect`] of a recording sink, whose hits are recorded
    /// as they are traced and their factors set once the lanes have
    /// them), under every model. Compiled for AVX2 as a whole where
    /// the CPU has it: one feature check per tile, and the shading kernels
    /// and the sink inlined into the path loop instead of a dispatched call
    /// per hit point (the same operations, so the same bits).
    fn tile_in_lanes<S: PathSink>(
        tracer: &Tracer<'_>,
        rect: TileRect,
        objects: &TileTargets,
        cancel: &CancelToken,
        scratch: &mut TraceScratch,
        sink: &mut S,
        out: &mut Vec<Vec3>,
    ) -> bool => tile_in_lanes_generic
);

/// [`tile_in_lanes`], the hits' `sampled` sums side by side in
/// [`Deferred`] (other models' factors computed hit by hit).
#[inline(always)]
fn tile_in_lanes_generic<S: PathSink>(
    tracer: &Tracer<'_>,
    rect: TileRect,
    objects: &TileTargets,
    cancel: &CancelToken,
    scratch: &mut TraceScratch,
    sink: &mut S,
    out: &mut Vec<Vec3>,
) -> bool {
    let mut lanes = std::mem::take(&mut scratch.lanes);
    lanes.start(&tracer.pattern);
    let mut colour = Deferred {
        lanes,
        path: 0,
        terms: std::mem::take(&mut scratch.terms),
        factors: std::mem::take(&mut scratch.factors),
        hits: std::mem::take(&mut scratch.factor_hits),
        visible: std::mem::take(&mut scratch.hit_visibility),
        edges: (
            tracer.scene.light.shape.edge_u.as_vec3(),
            tracer.scene.light.shape.edge_v.as_vec3(),
        ),
    };
    colour.terms.clear();
    colour.factors.clear();
    colour.hits.clear();
    colour.visible.clear();
    // The rows written out, not through a closure: it would be compiled
    // without this function's CPU features.
    let camera = &tracer.scene.camera;
    let mut rays = std::mem::take(&mut scratch.camera_rays);
    let mut hits = std::mem::take(&mut scratch.camera_hits);
    let spp = tracer.paths_per_pixel();
    // A one-shot render's reflected rays wait until the tile's camera rays
    // are traced, and are then searched side by side, depth by depth
    // (each path's terms still summed in its order). A recording sink
    // takes each path's hits in its order: its paths are traced whole.
    let defer = !S::RECORD && S::FINDS_CAMERA_HITS;
    let mut reflections = std::mem::take(&mut scratch.reflections);
    reflections.clear();
    let mut finished = true;
    for y in rect.y..rect.y + rect.h {
        if cancel.is_cancelled() {
            finished = false;
            break;
        }
        // The index of the row's first path in the tile.
        let row_path = (y - rect.y) * rect.w * spp;
        // One sample a pixel: its ray through the pixel's centre. Several:
        // placed by the filter, as `Tracer::trace` places them, pixel by
        // pixel (`spp` rays to a pixel).
        match &tracer.filter {
            None => camera.row_rays(rect.x, y, rect.w, &mut rays),
            Some(filter) => {
                rays.clear();
                for x in rect.x..rect.x + rect.w {
                    rays.extend(tracer.sample_rays(filter, x, y));
                }
            }
        }
        // The row's camera rays searched side by side, unless the sink
        // knows their hits. The tile's objects are those of the filter's
        // reach around its pixels.
        let ahead = S::FINDS_CAMERA_HITS;
        if ahead {
            objects.nearest_of_rays(tracer.scene, &rays, tracer.settings.cutaway, &mut hits);
        }
        // Two loops, so that a one-sample path's camera search is known
        // where it is inlined (a choice per path cost 2 % of a frame's
        // instructions), with no division to find its pixel.
        if spp == 1 {
            for (k, (x, ray)) in (rect.x..).zip(&rays).enumerate() {
                colour.path = row_path + k as u32;
                if defer {
                    scratch.stats.camera += 1;
                    let at = PathStep::camera(x, y, 0);
                    let step = (at, ray, hits[k]);
                    colour.step(tracer, step, scratch, sink, &mut reflections);
                    continue;
                }
                let hit = if ahead {
                    CameraHit::Found(hits[k])
                } else {
                    CameraHit::Search(Some(objects))
                };
                tracer.trace_path(x, y, 0, ray, hit, scratch, sink, &mut colour);
            }
            continue;
        }
        for (k, ray) in (0..).zip(&rays) {
            let (x, sample) = (rect.x + k / spp, k % spp);
            colour.path = row_path + k;
            if defer {
                scratch.stats.camera += 1;
                let step = (PathStep::camera(x, y, sample), ray, hits[k as usize]);
                colour.step(tracer, step, scratch, sink, &mut reflections);
                continue;
            }
            let hit = if ahead {
                CameraHit::Found(hits[k as usize])
            } else {
                CameraHit::Search(Some(objects))
            };
            tracer.trace_path(x, y, sample, ray, hit, scratch, sink, &mut colour);
        }
    }
    // The reflected rays, depth by depth: each depth's rays searched side
    // by side, then each hit shaded, the rays it reflects waiting for the
    // next depth.
    let mut next = std::mem::take(&mut scratch.next_reflections);
    while finished && !reflections.is_empty() {
        rays.clear();
        rays.extend(reflections.iter().map(|r| r.ray));
        tracer.scene.closest_hits(&rays, &mut hits);
        next.clear();
        for (r, &hit) in reflections.iter().zip(&hits) {
            colour.path = r.path;
            colour.step(tracer, (r.at, &r.ray, hit), scratch, sink, &mut next);
        }
        std::mem::swap(&mut reflections, &mut next);
    }
    scratch.reflections = reflections;
    scratch.next_reflections = next;
    scratch.camera_rays = rays;
    scratch.camera_hits = hits;
    if finished {
        colour.trace_waiting_shadows::<S>(tracer, scratch);
        colour.flush();
        colour.take_whole_lights(scratch);
        // Only a recording sink's waiting hits have entries in `hits` and
        // `visible`.
        for (&hit, &factors) in colour.hits.iter().zip(&colour.factors) {
            sink.set_factors(hit as usize, factors);
        }
        for &(hit, bits) in &colour.visible {
            sink.set_visible(hit as usize, bits);
        }
        // Each path's terms summed from zero in its order (a path's terms
        // are in its order among the tile's, if not together); with
        // several samples a pixel, the pixel's paths summed from zero and
        // averaged (the sums of `Tracer::trace`).
        let paths = (rect.w * rect.h * spp) as usize;
        let sums = &mut scratch.path_sums;
        sums.clear();
        sums.resize(paths, Vec3::ZERO);
        for term in &colour.terms {
            let local = match term.colour {
                TermColour::Known(c) => c,
                TermColour::Waiting { material, factors } => {
                    let f = colour.factors[factors as usize];
                    tracer.material_terms[material as usize].colours.colour(f)
                }
            };
            sums[term.path as usize] += local * term.weight;
        }
        out.clear();
        if spp == 1 {
            out.extend_from_slice(sums);
        } else {
            out.extend(sums.chunks(spp as usize).map(|pixel| {
                let sum = pixel.iter().fold(Vec3::ZERO, |sum, &path| sum + path);
                sum * (1.0 / spp as f32)
            }));
        }
    } else {
        colour.lanes.discard();
        scratch.shadow_lanes.clear();
        scratch.shadow_index.clear();
        scratch.whole_lights.clear();
    }
    scratch.lanes = colour.lanes;
    scratch.terms = colour.terms;
    scratch.factors = colour.factors;
    scratch.factor_hits = colour.hits;
    scratch.hit_visibility = colour.visible;
    finished
}

/// Where a path's colour goes: each hit's local colour and the path's end,
/// times the path weight there, added in the path's order.
trait PathColour {
    /// Adds `c * weight`.
    fn add(&mut self, c: Vec3, weight: f32);
    /// Adds the local colour of hit `sp` times `weight`; a recording sink
    /// (`S::RECORD`) also gets the hit, `t` along its ray, with every light
    /// factor computed (a later edit of any colour finds it).
    #[allow(clippy::too_many_arguments)]
    fn hit<S: PathSink>(
        &mut self,
        tracer: &Tracer,
        sp: &ShadingPoint,
        rng: &mut Rng,
        scratch: &mut TraceScratch,
        weight: f32,
        sink: &mut S,
        t: f64,
    );
}

/// A path's colour summed as it is traced.
struct Sum(Vec3);

impl PathColour for Sum {
    #[inline(always)]
    fn add(&mut self, c: Vec3, weight: f32) {
        self.0 += c * weight;
    }

    #[inline(always)]
    fn hit<S: PathSink>(
        &mut self,
        tracer: &Tracer,
        sp: &ShadingPoint,
        rng: &mut Rng,
        scratch: &mut TraceScratch,
        weight: f32,
        sink: &mut S,
        t: f64,
    ) {
        // As `shading::shade`, with the material's needs and colours
        // worked out once per tracer.
        let (s, count) = (tracer.settings, tracer.pattern.count());
        let terms = &tracer.material_terms[sp.material_index as usize];
        // A record serves any later colour: every factor.
        let needs = if S::RECORD { Needs::ALL } else { terms.needs };
        let buf = &mut scratch.shadow;
        if S::RECORD {
            // So that a point behind the light records as invisible.
            buf.vis[..count].fill(0.0);
        }
        let factors = light_terms(
            tracer.scene,
            s,
            sp,
            needs,
            &tracer.pattern,
            rng,
            buf,
            &mut scratch.stats,
        );
        if S::RECORD {
            sink.hit(tracer.hit_record(sp, t, factors), buf, count);
        }
        self.0 += terms.colours.colour(factors) * weight;
    }
}

/// What the light-factor lanes need of hit `sp`.
#[inline(always)]
fn lane_hit(scene: &Scene, sp: &ShadingPoint, needs: Needs) -> LaneHit {
    LaneHit {
        to_corner: (scene.light.shape.corner - sp.shadow.point).as_vec3(),
        normal: sp.normal.as_vec3(),
        view: sp.view.as_vec3(),
        shininess: sp.material.shininess,
        specular: needs.specular,
    }
}

/// One term of a tile's path colours, in the order of [`Tracer::trace`]'s
/// sum.
#[derive(Debug, Clone, Copy)]
struct Term {
    colour: TermColour,
    weight: f32,
    /// The index of the term's path in the tile: its pixel's, row by row,
    /// times the samples per pixel, plus its sample's.
    path: u32,
}

/// The colour a [`Term`]'s weight multiplies.
#[derive(Debug, Clone, Copy)]
enum TermColour {
    Known(Vec3),
    /// A hit's local colour, whose light factors wait in the lanes (their
    /// index in `factors`).
    Waiting {
        material: u32,
        factors: u32,
    },
}

impl Term {
    #[inline(always)]
    fn new(colour: TermColour, weight: f32, path: u32) -> Term {
        Term {
            colour,
            weight,
            path,
        }
    }
}

/// A tile's path colours as terms, the light factors of lit hits computed
/// side by side ([`Tracer::tile`]).
struct Deferred {
    lanes: SampledLanes,
    /// The index in the tile of the path whose terms are being added.
    path: u32,
    terms: Vec<Term>,
    factors: Vec<LightTerms>,
    /// A recording sink's index of the hit each of `factors` belongs to.
    hits: Vec<u32>,
    /// A recording sink's hits whose shadow rays [`HitLanes`] traced, and
    /// the visibility bits it found.
    visible: Vec<(u32, u64)>,
    /// The light's edges, as the light points' directions take them.
    edges: (Vec3, Vec3),
}

impl Deferred {
    /// Shades step `at` of the current path, whose ray `ray` has hit
    /// `hit`; the ray it reflects waits in `reflections` for the next
    /// depth's search.
    #[inline(always)]
    fn step<S: PathSink>(
        &mut self,
        tracer: &Tracer,
        (at, ray, hit): (PathStep, &Ray, Option<(HitTarget, f64)>),
        scratch: &mut TraceScratch,
        sink: &mut S,
        reflections: &mut Vec<Reflection>,
    ) {
        if let Some((ray, weight)) = tracer.path_hit(at, ray, hit, scratch, sink, self) {
            let at = PathStep {
                depth: at.depth + 1,
                weight,
                ..at
            };
            let path = self.path;
            reflections.push(Reflection { at, ray, path });
        }
    }

    /// Computes the waiting hits' factors.
    #[inline(always)]
    fn flush(&mut self) {
        let factors = &mut self.factors;
        self.lanes
            .flush(self.edges.0, self.edges.1, |i, f| factors[i] = f);
    }

    /// Computes the factors of the `exact` model's points waiting in
    /// [`WholeLights`]. Not inlined: its kernels stay out of the hit loop
    /// the other models share.
    #[inline(never)]
    fn take_whole_lights(&mut self, scratch: &mut TraceScratch) {
        let factors = &mut self.factors;
        scratch
            .whole_lights
            .flush(&mut scratch.shadow.exact, |i, f| {
                factors[i as usize] = exact_terms(f)
            });
    }

    /// Adds hit `sp`'s term, its colour waiting for its light factors:
    /// their index in `factors`, returned.
    #[inline(always)]
    fn wait_for_factors(&mut self, sp: &ShadingPoint, weight: f32) -> usize {
        let index = self.factors.len();
        self.factors.push(LightTerms::default());
        self.terms.push(Term::new(
            TermColour::Waiting {
                material: sp.material_index,
                factors: index as u32,
            },
            weight,
            self.path,
        ));
        index
    }

    /// A hit whose light points are drawn, their directions, facing and
    /// shadow rays left to [`HitLanes`] ([`Tracer::shadows_in_lanes`]): its
    /// colour waits for its factors, which wait for its rays.
    #[inline(always)]
    fn wait_for_shadows<S: PathSink>(
        &mut self,
        tracer: &Tracer,
        sp: &ShadingPoint,
        needs: Needs,
        scratch: &mut TraceScratch,
        weight: f32,
    ) {
        let index = self.wait_for_factors(sp, weight);
        let hit = lane_hit(tracer.scene, sp, needs);
        let h = scratch.shadow_index.len();
        scratch
            .shadow_inputs
            .set(h, hit.to_corner, hit.normal, hit.view, hit.shininess);
        scratch.shadow_index.push((index, hit.specular));
        let count = tracer.pattern.count();
        let buf = &scratch.shadow;
        if scratch
            .shadow_lanes
            .push(&sp.shadow, &buf.a[..count], &buf.b[..count])
        {
            self.trace_waiting_shadows::<S>(tracer, scratch);
        }
    }

    /// Traces the shadow rays of the hits waiting in [`HitLanes`], then
    /// computes their light factors lane for lane, as the lanes compute
    /// those of hits traced one by one (a hit with no point in view gets
    /// the +0 factors of the `sampled` sums of no visible point).
    #[inline(always)]
    fn trace_waiting_shadows<S: PathSink>(&mut self, tracer: &Tracer, scratch: &mut TraceScratch) {
        if scratch.shadow_lanes.len() == 0 {
            return;
        }
        let lanes = &mut scratch.shadow_lanes;
        lanes.trace(tracer.scene, &mut scratch.stats);
        let (visible, a, b) = lanes.visible();
        // A recording sink's hits (each waiting hit has its index in
        // `hits`) learn their visibility.
        if S::RECORD {
            for (&(factors, _), &bits) in scratch.shadow_index.iter().zip(&visible) {
                self.visible.push((self.hits[factors], bits));
            }
        }
        self.lanes.push_lanes(
            &scratch.shadow_index,
            &scratch.shadow_inputs,
            &visible,
            a,
            b,
        );
        self.flush();
        lanes.clear();
        scratch.shadow_index.clear();
    }
}

impl PathColour for Deferred {
    #[inline(always)]
    fn add(&mut self, colour: Vec3, weight: f32) {
        self.terms
            .push(Term::new(TermColour::Known(colour), weight, self.path));
    }

    // Its factors now, or left to the lanes (the `sampled` sums of a hit
    // with a light point in view; a recording sink's at the flush); `()`
    // gets only the needed factors.
    #[inline(always)]
    fn hit<S: PathSink>(
        &mut self,
        tracer: &Tracer,
        sp: &ShadingPoint,
        rng: &mut Rng,
        scratch: &mut TraceScratch,
        weight: f32,
        sink: &mut S,
        t: f64,
    ) {
        let (scene, s) = (tracer.scene, tracer.settings);
        let terms = &tracer.material_terms[sp.material_index as usize];
        // A record serves any later colour: every factor.
        let needs = if S::RECORD { Needs::ALL } else { terms.needs };
        let count = tracer.pattern.count();
        let (pattern, buf, stats) = (&tracer.pattern, &mut scratch.shadow, &mut scratch.stats);
        // A call of its own, its `Shadows` known where it is inlined: one
        // chosen at run time cost the hit-by-hit path 3.6 % more
        // instructions with skipping off (its candidates copied through
        // memory).
        // A recording sink's hit is recorded at once, its visibility (0
        // until then) and factors once its rays are traced.
        if tracer.shadows_in_lanes {
            if S::RECORD {
                // So that a point behind the light records as invisible.
                buf.vis[..count].fill(0.0);
            }
            let later = Shadows::Later;
            let lit = light_points_generic(scene, s, sp, needs, pattern, rng, buf, stats, later);
            match lit.known(buf) {
                Some(f) => {
                    if S::RECORD {
                        sink.hit(tracer.hit_record(sp, t, f), buf, count);
                    }
                    self.add(terms.colours.colour(f), weight)
                }
                None => {
                    if S::RECORD {
                        let open = tracer.hit_record(sp, t, LightTerms::default());
                        self.hits.push(sink.hit(open, buf, count) as u32);
                    }
                    self.wait_for_shadows::<S>(tracer, sp, needs, scratch, weight)
                }
            }
            return;
        }
        let buf = &mut scratch.shadow;
        if S::RECORD {
            // So that a point behind the light records as invisible.
            buf.vis[..count].fill(0.0);
        }
        let lit = light_points_generic(
            scene,
            s,
            sp,
            needs,
            &tracer.pattern,
            rng,
            buf,
            &mut scratch.stats,
            Shadows::Traced,
        );
        let factors = match lit {
            Lit::Known(f) => f,
            // Taken side by side with the tile's next such points.
            Lit::Whole => {
                let index = self.wait_for_factors(sp, weight);
                if S::RECORD {
                    let open = tracer.hit_record(sp, t, LightTerms::default());
                    self.hits.push(sink.hit(open, buf, count) as u32);
                }
                if scratch
                    .whole_lights
                    .push(index as u32, &scratch.shadow.exact)
                {
                    self.take_whole_lights(scratch);
                }
                return;
            }
            // The lanes hold the `sampled` sums: other models' terms now.
            Lit::Points if !any_visible(buf, count) || s.model != AreaLightModel::Sampled => {
                model_terms(scene, s, sp, needs, count, buf)
            }
            Lit::Points => {
                let index = self.wait_for_factors(sp, weight);
                if S::RECORD {
                    let open = tracer.hit_record(sp, t, LightTerms::default());
                    self.hits.push(sink.hit(open, buf, count) as u32);
                }
                let hit = lane_hit(scene, sp, needs);
                if self.lanes.push(index, hit, buf) {
                    self.flush();
                }
                return;
            }
        };
        if S::RECORD {
            sink.hit(tracer.hit_record(sp, t, factors), buf, count);
        }
        self.terms.push(Term::new(
            TermColour::Known(terms.colours.colour(factors)),
            weight,
            self.path,
        ));
    }
}

/// What [`replay`] needs of each material, computed once per replay.
#[derive(Debug, Clone, Copy)]
pub struct ReplayMaterial {
    colours: PhongColours,
    reflectivity: f32,
}

/// The materials of `shading` as [`replay`] uses them.
pub fn replay_materials(settings: &RenderSettings, shading: &ShadingParams) -> Vec<ReplayMaterial> {
    shading
        .materials
        .iter()
        .map(|m| ReplayMaterial {
            colours: PhongColours::new(m, &shading.light, settings.terms),
            reflectivity: m.reflectivity,
        })
        .collect()
}

/// The colour of a pixel from its recorded paths (`paths` yields each
/// sample's hits and end), with the arithmetic of [`Tracer::trace`];
/// `None` if an edit made a path longer than what was recorded.
#[inline]
pub fn replay_pixel<'r>(
    mut paths: impl Iterator<Item = (&'r [ColourHit], PathEnd)>,
    spp: u32,
    settings: &RenderSettings,
    shading: &ShadingParams,
    materials: &[ReplayMaterial],
) -> Option<Vec3> {
    if spp == 1 {
        let (hits, end) = paths.next()?;
        return replay(hits, end, settings, shading, materials);
    }
    let mut sum = Vec3::ZERO;
    for (hits, end) in paths {
        sum += replay(hits, end, settings, shading, materials)?;
    }
    Some(sum * (1.0 / spp as f32))
}

/// The colour of a recorded path under (possibly edited) shading
/// parameters (`materials` from [`replay_materials`]), with the arithmetic
/// of [`Tracer::trace_path`]; `None` if the edit makes the path longer than
/// what was recorded (a reflectivity that was 0, or a weight that was below
/// the cut-off), so it must be traced.
#[inline]
pub fn replay(
    hits: &[ColourHit],
    end: PathEnd,
    settings: &RenderSettings,
    shading: &ShadingParams,
    materials: &[ReplayMaterial],
) -> Option<Vec3> {
    let mut colour = Vec3::ZERO;
    let mut weight = 1.0f32;
    for (k, hit) in hits.iter().enumerate() {
        let m = &materials[hit.material as usize];
        colour += m.colours.colour(hit.factors) * weight;
        if m.reflectivity == 0.0 || k as u32 + 1 == settings.max_depth {
            return Some(colour);
        }
        weight *= m.reflectivity;
    }
    match end {
        PathEnd::Background => colour += settings.background * weight,
        PathEnd::Light => colour += shading.light.diffuse * weight,
        PathEnd::MaxDepth | PathEnd::Absorbed => return None,
    }
    Some(colour)
}

/// Mirror direction of `d` about the normal `n`.
#[inline]
pub fn reflect(d: DVec3, n: DVec3) -> DVec3 {
    (d - n * (2.0 * d.dot(n))).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::scene::Loaded;
    use crate::render::scene_file::Sampling;

    /// A tile (its camera rays testing the tile's objects, its hits shaded
    /// side by side, with few light points their shadow rays too) has,
    /// pixel for pixel, the bits of the
    /// pixels traced one at a time: floor, walls, both boxes and the mirror
    /// sphere (reflected paths), the image's corners, several patterns and
    /// counts, with and without cut-away, with one camera sample a pixel
    /// and several.
    /// Every pixel of `tile` (rectangle `r`, rows packed) has the bits of
    /// the pixel traced alone.
    fn assert_tile_is_its_pixels(
        tracer: &Tracer,
        r: TileRect,
        tile: &[Vec3],
        scratch: &mut TraceScratch,
        what: &str,
    ) {
        assert_eq!(tile.len(), (r.w * r.h) as usize, "{what}");
        for (k, c) in tile.iter().enumerate() {
            let (x, y) = (r.x + k as u32 % r.w, r.y + k as u32 / r.w);
            let want = tracer.pixel(x, y, scratch);
            assert_eq!(
                c.to_array().map(f32::to_bits),
                want.to_array().map(f32::to_bits),
                "{what}: pixel ({x}, {y})"
            );
        }
    }

    #[test]
    fn a_tile_in_lanes_gives_the_bits_of_each_pixel() {
        let loaded = Loaded::seed_room();
        let rect = TileRect {
            x: 280,
            y: 150,
            w: 400,
            h: 300,
        };
        for (sampling, rays, skip, cutaway, spp) in [
            (Sampling::Grid, 1, true, false, 1),
            (Sampling::Grid, 1, false, false, 1),
            (Sampling::Grid, 1, true, true, 1),
            (Sampling::Grid, 4, true, false, 1),
            (Sampling::Random, 3, true, false, 1),
            (Sampling::Stratified, 9, true, false, 1),
            (Sampling::Grid, 64, true, true, 1),
            // Several camera samples a pixel, placed by the filter.
            (Sampling::Grid, 1, true, false, 4),
            (Sampling::Random, 2, true, true, 3),
            (Sampling::Grid, 16, true, false, 2),
        ] {
            let mut settings = loaded.settings.clone();
            settings.sampling = sampling;
            settings.shadow_rays = rays;
            settings.skip = skip;
            settings.cutaway = cutaway;
            settings.samples_per_pixel = spp;
            let tracer = Tracer::new(&loaded.scene, &settings, &loaded.shading, rays);
            // One camera ray a pixel through its centre, or the filter's.
            assert_eq!(tracer.filter.is_none(), spp == 1);
            assert_eq!(tracer.settings.model, AreaLightModel::Sampled);
            // Up to four light points with skipping on, the hits' shadow
            // rays are traced side by side too.
            assert_eq!(tracer.shadows_in_lanes, skip && rays <= 4);
            let mut scratch = tracer.scratch();
            let mut tile = Vec::new();
            // Every fourth pixel, so that the test stays quick.
            let small = |i: u32| match i {
                100 => TileRect {
                    x: 0,
                    y: 0,
                    w: 32,
                    h: 32,
                },
                101 => TileRect {
                    x: 928,
                    y: 0,
                    w: 32,
                    h: 32,
                },
                102 => TileRect {
                    x: 0,
                    y: 508,
                    w: 32,
                    h: 32,
                },
                103 => TileRect {
                    x: 929,
                    y: 509,
                    w: 31,
                    h: 31,
                },
                104 => TileRect {
                    x: 500,
                    y: 20,
                    w: 1,
                    h: 30,
                },
                _ => TileRect {
                    x: rect.x + 4 * (i % 25),
                    y: rect.y + 4 * (i / 25) * 3,
                    w: 13,
                    h: 7,
                },
            };
            for i in 0..105 {
                let r = small(i);
                assert!(tracer.tile(r, &CancelToken::new(), &mut scratch, &mut tile));
                let what = format!("{sampling:?} {rays} skip {skip} spp {spp}");
                assert_tile_is_its_pixels(&tracer, r, &tile, &mut scratch, &what);
            }
        }
        // Cancelled: no pixels, and the next tile is still right.
        let tracer = Tracer::new(&loaded.scene, &loaded.settings, &loaded.shading, 1);
        let mut scratch = tracer.scratch();
        let cancel = CancelToken::new();
        cancel.cancel();
        let mut tile = Vec::new();
        assert!(!tracer.tile(rect, &cancel, &mut scratch, &mut tile));
        let r = TileRect {
            x: 500,
            y: 300,
            w: 4,
            h: 2,
        };
        assert!(tracer.tile(r, &CancelToken::new(), &mut scratch, &mut tile));
        assert_eq!(tile[5], tracer.pixel(501, 301, &mut scratch));
    }

    /// Under the other models a tile's paths are traced side by side too
    /// (reflected rays searched depth by depth, terms summed path by path),
    /// their factors computed hit by hit: the same bits as each pixel
    /// traced alone. The mirror sphere and boxes reflect (depth 4); the
    /// `exact` model's hits are exact in the seed room and all fall back
    /// to the `analytic` estimate under a light too small for it.
    #[test]
    fn a_tile_gives_the_bits_of_each_pixel_under_every_model() {
        use crate::render::scene::SEED_ROOM_JSON;
        // The seed room's 2 × 2 light made 2 × 10⁻⁶ (below the exact
        // model's smallest light from 0.02 below it).
        let tiny = SEED_ROOM_JSON
            .replace("[-1, 7.99, -1]", "[-1e-6, 7.99, -1e-6]")
            .replace("\"edge_u\": [2, 0, 0]", "\"edge_u\": [2e-6, 0, 0]")
            .replace("\"edge_v\": [0, 0, 2]", "\"edge_v\": [0, 0, 2e-6]");
        assert_ne!(tiny, SEED_ROOM_JSON);
        let rooms = [
            (Loaded::seed_room(), false),
            (Loaded::from_json(&tiny).expect("a valid room"), true),
        ];
        for (loaded, small_light) in &rooms {
            for (model, rays, skip) in [
                (AreaLightModel::Exact, 4, true),
                (AreaLightModel::Analytic, 4, true),
                (AreaLightModel::Analytic, 9, false),
                (AreaLightModel::NearestPoint, 4, true),
            ] {
                if *small_light && model != AreaLightModel::Exact {
                    continue;
                }
                let mut settings = loaded.settings.clone();
                (settings.model, settings.shadow_rays, settings.skip) = (model, rays, skip);
                let tracer = Tracer::new(&loaded.scene, &settings, &loaded.shading, rays);
                assert_ne!(tracer.settings.model, AreaLightModel::Sampled);
                let mut scratch = tracer.scratch();
                let mut tile = Vec::new();
                // Tiles over the floor, the boxes, the mirror sphere and
                // the back wall.
                for i in 0..24 {
                    let r = TileRect {
                        x: 300 + 16 * (i % 6),
                        y: 120 + 60 * (i / 6),
                        w: 11,
                        h: 9,
                    };
                    let before = scratch.stats;
                    assert!(tracer.tile(r, &CancelToken::new(), &mut scratch, &mut tile));
                    let (exact, fallbacks) = (
                        scratch.stats.exact_hits - before.exact_hits,
                        scratch.stats.exact_fallbacks - before.exact_fallbacks,
                    );
                    if model == AreaLightModel::Exact {
                        // Every hit takes the branch the room sets.
                        let (want, other) = if *small_light {
                            (fallbacks, exact)
                        } else {
                            (exact, fallbacks)
                        };
                        assert!(
                            want >= u64::from(r.w * r.h),
                            "{model:?} small light {small_light} tile {i}: {want} {other}"
                        );
                        assert_eq!(other, 0, "{model:?} tile {i}");
                    }
                    let what = format!("{model:?} {rays} skip {skip} small light {small_light}");
                    assert_tile_is_its_pixels(&tracer, r, &tile, &mut scratch, &what);
                }
            }
        }
    }
}
