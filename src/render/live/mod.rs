//! Live editing: a render that keeps what the next edit does not change.
//!
//! [`LiveRender::render`] takes the whole description each time, asks
//! [`classify`] what the edit invalidates, and redoes only that:
//! - recombine: the recorded light factors of every hit are combined with
//!   the new colours and strengths (no rays);
//! - re-shade: the specular factors of the hits whose shininess changed are
//!   computed again from their recorded visibility, and only the pixels
//!   whose paths a reflectivity edit lengthens are traced;
//! - relight: a progressive render whose final pass follows the recorded
//!   paths under the new light, intersecting only the rays it may cut;
//! - re-trace and rebuild: a progressive render (the scene is built again
//!   only for a rebuild) whose final pass records the paths again.
//!
//! Every path is recombined with the arithmetic of the tracer itself
//! (`tracer::replay`), so the image after any sequence of edits equals a
//! fresh one-shot render of the same description, bit for bit.

pub mod cosine_logs;
pub mod edit;
pub mod record;
pub mod relight;
pub mod respecular;

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use glam::Vec3;

use cosine_logs::{CosineLogs, LogBudget, NO_HIT};
pub use edit::{EditClass, classify};
use record::{Budget, TileRecord, TileRecorder, shininess_of};
use relight::Previous;
use respecular::{RecordedHit, ReshadeBatch, specular_from_logs};

use super::error::SceneError;
use super::film::Film;
use super::progressive::{
    CancelToken, Cancelled, Pass, RenderOptions, TileJob, TileRect, TileUpdate, in_pool, lock,
    pass_plan, render_passes,
};
use super::rng::Rng;
use super::scene::{Loaded, Scene};
use super::scene_file::{AreaLightModel, SceneDesc};
use super::settings::RenderSettings;
use super::shading::nearest_point_specular;
use super::shading_params::ShadingParams;
use super::stats::RayStats;
use super::tracer::{ReplayMaterial, Tracer, replay_materials, replay_pixel};

/// Default memory cap of the records (see `record.rs` for the bytes per
/// hit): the seed room at 960×540, 64 shadow rays, depth 4 needs ~42 MB,
/// and a re-shade keeps logarithms for the next one in the rest
/// (`cosine_logs.rs`). 64 MB in decimal units, as the bench prints them.
pub const DEFAULT_RECORD_CAP: usize = 64_000_000;

/// A light edit goes straight to its final pass, without the preview,
/// when the last frame took at most this long per tile and thread: its
/// first full tile then arrives within a frame, as a preview's would, and
/// the image does not flash to blocks on every step of a drag (the preview
/// also cost about 2 % of the time to full quality, most of it delivering
/// a whole image of blocks).
const PREVIEW_TILE_TIME: Duration = Duration::from_millis(4);

/// What one live render did.
#[derive(Debug, Clone)]
pub struct LiveReport {
    pub class: EditClass,
    pub film: Film,
    /// Rays traced (none for a recombine).
    pub stats: RayStats,
    pub elapsed: Duration,
    /// Pixels traced again by a re-shade (reflectivity edits).
    pub retraced_pixels: usize,
    /// Heap bytes the records hold after this render.
    pub record_bytes: usize,
}

/// Why a live render gave no image.
#[derive(Debug, Clone, thiserror::Error)]
pub enum LiveError {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Cancelled(#[from] Cancelled),
}

/// The state of the last render.
struct Current {
    desc: SceneDesc,
    scene: Arc<Scene>,
    settings: RenderSettings,
    shading: ShadingParams,
    /// The records of its full-quality image (`None` after a cancelled
    /// render, or above the memory cap).
    frame: Option<Frame>,
}

struct Frame {
    tiles: Vec<Mutex<TileRecord>>,
    /// Whether every tile holds its shininess tier.
    shapes: bool,
    /// Side of the tiles the records were cut into.
    tile_size: u32,
    /// The render's time per tile and thread (all its passes).
    tile_time: Duration,
}

/// What a re-trace takes over from the last frame.
#[derive(Default)]
struct Reuse {
    /// Its paths, for a light edit to follow.
    previous: Option<Previous>,
    /// Its records, whose buffers the new ones take over.
    spares: Vec<TileRecord>,
    /// Whether to go straight to the final pass (see [`PREVIEW_TILE_TIME`]).
    skip_preview: bool,
}

impl Frame {
    fn bytes(&self) -> usize {
        self.tiles.iter().map(|t| lock(t).bytes()).sum()
    }

    /// Without the kept logarithms.
    fn path_bytes(&self) -> usize {
        self.tiles.iter().map(|t| lock(t).path_bytes()).sum()
    }
}

/// A render that keeps what the next edit does not change.
pub struct LiveRender {
    cap: usize,
    current: Option<Current>,
    /// An image given back by the caller ([`LiveRender::recycle`]): a
    /// recombine writes every pixel of it instead of mapping fresh pages.
    spare: Option<Film>,
}

impl Default for LiveRender {
    fn default() -> Self {
        LiveRender::new(DEFAULT_RECORD_CAP)
    }
}

impl LiveRender {
    /// A live render whose records hold at most `cap` bytes.
    pub fn new(cap: usize) -> LiveRender {
        LiveRender {
            cap,
            current: None,
            spare: None,
        }
    }

    /// Takes `other`'s scene (no records): the next render re-traces over
    /// its objects and BVH instead of building them again.
    pub fn share_scene(&mut self, other: &LiveRender) {
        self.current = other.current.as_ref().map(|c| Current {
            desc: c.desc.clone(),
            scene: c.scene.clone(),
            settings: c.settings.clone(),
            shading: c.shading.clone(),
            frame: None,
        });
    }

    /// Starts from `loaded`, built elsewhere (a viewer's loader thread)
    /// for `desc`: the next render traces over its objects and BVH instead
    /// of reading the meshes and building them again.
    pub fn adopt(&mut self, desc: &SceneDesc, loaded: Loaded) {
        self.current = Some(Current {
            desc: desc.clone(),
            scene: loaded.scene,
            settings: loaded.settings,
            shading: loaded.shading,
            frame: None,
        });
    }

    /// Takes back an image this render gave, no longer needed: the next
    /// recombine or re-shade of the same size writes into it.
    pub fn recycle(&mut self, film: Film) {
        self.spare = Some(film);
    }

    /// The memory cap of the records.
    pub fn cap(&self) -> usize {
        self.cap
    }

    /// The scene of the last render, if any.
    pub fn scene(&self) -> Option<&Arc<Scene>> {
        self.current.as_ref().map(|c| &c.scene)
    }

    /// Bytes the records hold now.
    pub fn record_bytes(&self) -> usize {
        self.current
            .as_ref()
            .and_then(|c| c.frame.as_ref())
            .map_or(0, Frame::bytes)
    }

    /// Bytes the records of the paths hold now: without the logarithms a
    /// re-shade kept for the next one in the room they left (which a
    /// re-trace's records take back), so what a render with more samples
    /// would need scales from it.
    pub fn path_record_bytes(&self) -> usize {
        self.current
            .as_ref()
            .and_then(|c| c.frame.as_ref())
            .map_or(0, Frame::path_bytes)
    }

    /// What rendering `desc` now would cost.
    pub fn class_of(&self, desc: &SceneDesc) -> EditClass {
        match &self.current {
            None => EditClass::Rebuild,
            Some(c) => {
                let class = classify(&c.desc, desc);
                if c.frame.is_none() {
                    // No records (a cancelled render, or above the cap).
                    class.max(EditClass::Retrace)
                } else {
                    class
                }
            }
        }
    }

    /// Renders `desc`, calling `on_tile` with every finished tile, and
    /// redoing only what changed since the last call. A cancelled render
    /// leaves the state such that the next call is still exact.
    pub fn render(
        &mut self,
        desc: &SceneDesc,
        options: &RenderOptions,
        cancel: &CancelToken,
        on_tile: &(dyn Fn(&TileUpdate) + Sync),
    ) -> Result<LiveReport, LiveError> {
        let start = Instant::now();
        let class = self.class_of(desc);
        let mut report = match class {
            EditClass::Rebuild => {
                let loaded = Loaded::new(desc)?;
                self.retrace(
                    desc,
                    loaded.scene,
                    loaded.settings,
                    loaded.shading,
                    options,
                    cancel,
                    on_tile,
                    Reuse::default(),
                )?
            }
            EditClass::Relight | EditClass::Retrace => {
                desc.validate()?;
                let last = self.current.take().expect("a scene to re-trace");
                let scene = Arc::new(last.scene.with_view(desc));
                let reuse = match last.frame {
                    Some(frame) => {
                        let follow = class == EditClass::Relight
                            && frame.tile_size == super::progressive::tile_side(options);
                        let skip_preview = follow && frame.tile_time <= PREVIEW_TILE_TIME;
                        let tiles = frame
                            .tiles
                            .into_iter()
                            .map(|t| t.into_inner().unwrap_or_else(|e| e.into_inner()));
                        // A light edit follows the last frame's paths; any
                        // other re-trace records into their buffers.
                        if follow {
                            Reuse {
                                previous: Some(Previous {
                                    tiles: tiles.map(|t| Mutex::new(Some(t))).collect(),
                                    reflections: scene.scale == last.scene.scale,
                                }),
                                spares: Vec::new(),
                                skip_preview,
                            }
                        } else {
                            Reuse {
                                spares: tiles.collect(),
                                ..Reuse::default()
                            }
                        }
                    }
                    None => Reuse::default(),
                };
                self.retrace(
                    desc,
                    scene,
                    RenderSettings::from_desc(desc),
                    ShadingParams::from_desc(desc),
                    options,
                    cancel,
                    on_tile,
                    reuse,
                )?
            }
            EditClass::Nothing | EditClass::Recombine | EditClass::Reshade => {
                desc.validate()?;
                self.reshade(desc, class, options, cancel, on_tile)?
            }
        };
        report.class = class;
        report.elapsed = start.elapsed();
        report.record_bytes = self.record_bytes();
        Ok(report)
    }

    #[allow(clippy::too_many_arguments)]
    fn retrace(
        &mut self,
        desc: &SceneDesc,
        scene: Arc<Scene>,
        settings: RenderSettings,
        shading: ShadingParams,
        options: &RenderOptions,
        cancel: &CancelToken,
        on_tile: &(dyn Fn(&TileUpdate) + Sync),
        reuse: Reuse,
    ) -> Result<LiveReport, LiveError> {
        // Until the final pass is done there are no records of this scene.
        self.current = Some(Current {
            desc: desc.clone(),
            scene: scene.clone(),
            settings: settings.clone(),
            shading: shading.clone(),
            frame: None,
        });
        let budget = Budget::new(self.cap, reuse.spares);
        let final_pass = Pass {
            shadow_rays: settings.shadow_rays,
            block: 1,
        };
        let plan = if options.progressive && !reuse.skip_preview {
            pass_plan(settings.shadow_rays)
        } else {
            vec![final_pass]
        };
        let (report, mut tiles) = in_pool(options.threads, || {
            render_passes(
                &scene,
                &settings,
                &shading,
                &plan,
                TileRect::whole(&scene.camera),
                options,
                cancel,
                on_tile,
                Some(&budget),
                reuse.previous.as_ref(),
            )
        })?;
        let threads = options.threads.unwrap_or_else(rayon::current_num_threads);
        let tile_time = report.elapsed * threads as u32 / tiles.len().max(1) as u32;
        // The `exact` model records no visibility bits to recompute its
        // specular factor from: a shininess edit traces again.
        let shapes = budget.shapes_allowed() && settings.model != AreaLightModel::Exact;
        if !shapes {
            tiles.iter_mut().for_each(TileRecord::drop_shapes);
        }
        let bytes: usize = tiles.iter().map(TileRecord::bytes).sum();
        let frame = (bytes <= self.cap).then(|| Frame {
            tiles: tiles.into_iter().map(Mutex::new).collect(),
            shapes,
            tile_size: super::progressive::tile_side(options),
            tile_time,
        });
        if let Some(c) = &mut self.current {
            c.frame = frame;
        }
        Ok(LiveReport {
            class: EditClass::Retrace,
            film: report.film,
            stats: report.final_stats,
            elapsed: report.elapsed,
            retraced_pixels: 0,
            record_bytes: 0,
        })
    }

    /// Recombines or re-shades the recorded frame for `desc`'s shading.
    fn reshade(
        &mut self,
        desc: &SceneDesc,
        class: EditClass,
        options: &RenderOptions,
        cancel: &CancelToken,
        on_tile: &(dyn Fn(&TileUpdate) + Sync),
    ) -> Result<LiveReport, LiveError> {
        let current = self.current.as_mut().expect("a recorded frame");
        let settings = RenderSettings::from_desc(desc);
        let shading = ShadingParams::from_desc(desc);
        let shininess = shininess_of(&shading);
        let frame = current.frame.as_ref().expect("a recorded frame");
        // Above the memory cap the visibility was not kept; records of
        // another tile size cover other rectangles.
        let unusable = (!frame.shapes
            && frame.tiles.iter().any(|t| lock(t).shininess != shininess))
            || frame.tile_size != super::progressive::tile_side(options);
        if unusable {
            let scene = self.current.take().expect("a scene").scene;
            return self.retrace(
                desc,
                scene,
                settings,
                shading,
                options,
                cancel,
                on_tile,
                Reuse::default(),
            );
        }
        let scene = current.scene.clone();
        let (width, height) = (scene.camera.width, scene.camera.height);
        // Every tile is written (a cancelled render's image is dropped).
        let film = match self.spare.take() {
            Some(f) if (f.width, f.height) == (width, height) => f,
            _ => Film::new(width, height),
        };
        let film = Mutex::new(film);
        let retraced = AtomicUsize::new(0);
        let tracer = Tracer::new(&scene, &settings, &shading, settings.shadow_rays);
        let materials = replay_materials(&settings, &shading);
        let records = &frame.tiles;
        let rects: Vec<TileRect> = records.iter().map(|t| lock(t).rect).collect();
        let job = TileJob {
            tiles: &rects,
            film: &film,
            origin: (0, 0),
            cancel,
            on_tile,
            pass: Pass {
                shadow_rays: settings.shadow_rays,
                block: 1,
            },
            pass_index: 0,
            pass_count: 1,
        };
        // What the records leave under the cap may keep logarithms for the
        // next re-shade (a reflectivity edit's longer paths may take some
        // back: see below).
        let log_budget = LogBudget::new(self.cap.saturating_sub(frame.bytes()));
        let result = in_pool(options.threads, || {
            job.run(&tracer, |i, _, scratch, pixels| {
                let mut record = lock(&records[i]);
                if record.shininess != shininess {
                    respecular_tile(&scene, &tracer, &shininess, &mut record, &log_budget);
                }
                let n = replay_tile(&tracer, &materials, &mut record, scratch, pixels);
                retraced.fetch_add(n, Ordering::Relaxed);
                true
            })
        });
        let film = film.into_inner().unwrap_or_else(|e| e.into_inner());
        // Tiles traced again may have grown: the kept logarithms go first.
        let mut over = frame.bytes().saturating_sub(self.cap);
        for tile in records.iter().rev() {
            if over == 0 {
                break;
            }
            if let Some(logs) = lock(tile).logs.take() {
                over = over.saturating_sub(logs.bytes());
            }
        }
        // Cancelled: every tile is consistent on its own (it knows the
        // shininess of its factors), so the records stay.
        let stats = result?;
        current.desc = desc.clone();
        current.settings = settings;
        current.shading = shading;
        Ok(LiveReport {
            class,
            film,
            stats,
            elapsed: Duration::ZERO,
            retraced_pixels: retraced.into_inner(),
            record_bytes: 0,
        })
    }
}

/// Computes the specular factors of a tile's hits whose material's
/// shininess differs from `shininess`, from their recorded visibility, in
/// batches of [`respecular::LANES`] hits — or from the logarithms a
/// previous re-shade kept, which the first re-shade of the tile keeps for
/// its lit hits if `budget` has room.
fn respecular_tile(
    scene: &Scene,
    tracer: &Tracer,
    shininess: &Arc<[f32]>,
    record: &mut TileRecord,
    budget: &LogBudget,
) {
    let respecular: Vec<bool> = shininess
        .iter()
        .zip(record.shininess.iter())
        .map(|(new, old)| new != old)
        .collect();
    record.shininess = shininess.clone();
    let (settings, shading, pattern) = (tracer.settings, tracer.shading, &tracer.pattern);
    let count = pattern.count();
    let TileRecord {
        rect,
        starts,
        hits,
        shapes,
        logs,
        ..
    } = record;
    let shapes = shapes.as_ref().expect("the shininess tier");
    let words = shapes.words;
    let visible_of = |h: usize| &shapes.visible[h * words..(h + 1) * words];
    let spp = tracer.samples() as usize;
    let light = &scene.light.shape;
    let (edge_u, edge_v) = (light.edge_u.as_vec3(), light.edge_v.as_vec3());
    let nearest = settings.model == AreaLightModel::NearestPoint;
    // The kept hits, from their logarithms.
    if let Some(kept) = logs.as_ref() {
        for (b, lanes) in kept.batches.iter().enumerate() {
            let wanted = |&i: &u32| i != NO_HIT && respecular[hits[i as usize].material as usize];
            if !lanes.iter().any(wanted) {
                continue;
            }
            let y = lanes.map(|i| match i {
                NO_HIT => 1.0,
                i => shading.materials[hits[i as usize].material as usize].shininess,
            });
            let sums = specular_from_logs(&kept.logs[b * count..(b + 1) * count], &y);
            for (&i, s) in lanes.iter().zip(sums) {
                if i != NO_HIT {
                    hits[i as usize].factors.specular = s;
                }
            }
        }
    }
    let kept_materials = logs.as_ref().map(|k| k.materials.clone());
    let is_kept = |material: usize| kept_materials.as_ref().is_some_and(|m| m[material]);
    // Or keep them now, if there is room for all of this tile's.
    let mut keeping = None;
    if logs.is_none() && !nearest {
        let lit = (0..hits.len())
            .filter(|&h| {
                respecular[hits[h].material as usize] && visible_of(h).iter().any(|&w| w != 0)
            })
            .count();
        if lit > 0 && budget.take(CosineLogs::bytes_for(respecular.len(), lit, count)) {
            keeping = Some(CosineLogs::with_room(respecular.clone(), lit, count));
        }
    }
    let mut batch = ReshadeBatch::default();
    batch.start(pattern);
    // One path per camera sample, pixel by pixel.
    for (path, w) in starts.windows(2).enumerate() {
        let (i, sample) = (path / spp, (path % spp) as u32);
        let (x, y) = (rect.x + i as u32 % rect.w, rect.y + i as u32 / rect.w);
        for (k, h) in (w[0] as usize..w[1] as usize).enumerate() {
            let material = hits[h].material as usize;
            if !respecular[material] {
                continue;
            }
            let shape = &shapes.hits[h];
            let visible = visible_of(h);
            let shininess = shading.materials[material].shininess;
            if nearest {
                let seen: u32 = visible.iter().map(|w| w.count_ones()).sum();
                hits[h].factors.specular =
                    nearest_point_specular(shape.normal, shape.to_light, shape.view, shininess)
                        * (seen as f32 / count as f32);
                continue;
            }
            // `sampled` and `analytic` (`exact` frames keep no shininess
            // tier, see `retrace`: their factors come from no bits).
            if visible.iter().all(|&w| w == 0) {
                // Every term of the average is 0 × a finite factor.
                hits[h].factors.specular = 0.0;
                continue;
            }
            if is_kept(material) {
                continue;
            }
            let recorded = RecordedHit {
                to_corner: shape.to_light,
                normal: shape.normal,
                view: shape.view,
                shininess,
            };
            let rng = || Rng::for_sample(settings.seed, x, y, sample, k as u32 + 1);
            if batch.push(h, recorded, visible, pattern, rng) {
                let store = |i: usize, s: f32| hits[i].factors.specular = s;
                match &mut keeping {
                    Some(kept) => batch.flush_keeping(edge_u, edge_v, kept, store),
                    None => batch.flush(edge_u, edge_v, store),
                }
            }
        }
    }
    let store = |i: usize, s: f32| hits[i].factors.specular = s;
    match keeping {
        Some(mut kept) => {
            batch.flush_keeping(edge_u, edge_v, &mut kept, store);
            *logs = Some(kept);
        }
        None => batch.flush(edge_u, edge_v, store),
    }
}

/// The pixels of a tile from its records (into `out`), tracing the pixels
/// whose paths an edit lengthened; returns how many were traced.
fn replay_tile(
    tracer: &Tracer,
    materials: &[ReplayMaterial],
    record: &mut TileRecord,
    scratch: &mut super::tracer::TraceScratch,
    out: &mut Vec<Vec3>,
) -> usize {
    out.clear();
    let pixels = (record.rect.w * record.rect.h) as usize;
    let spp = tracer.samples();
    let mut short = Vec::new();
    for i in 0..pixels {
        let paths = (i * spp as usize..(i + 1) * spp as usize)
            .map(|p| (&record.hits[record.path_hits(p)], record.ends[p]));
        match replay_pixel(paths, spp, tracer.settings, tracer.shading, materials) {
            Some(c) => out.push(c),
            None => {
                short.push(i);
                out.push(Vec3::ZERO);
            }
        }
    }
    if short.is_empty() {
        return 0;
    }
    // Record the tile again: the lengthened pixels traced, the others copied.
    let rect = record.rect;
    let mut fresh = TileRecord::new(
        rect,
        tracer.pattern.count(),
        record.shapes.is_some(),
        record.shininess.clone(),
    );
    let mut next_short = short.iter().peekable();
    for (i, pixel) in out.iter_mut().enumerate() {
        if next_short.peek() == Some(&&i) {
            next_short.next();
            let (x, y) = (rect.x + i as u32 % rect.w, rect.y + i as u32 / rect.w);
            *pixel = tracer.trace(x, y, scratch, &mut TileRecorder { record: &mut fresh });
            continue;
        }
        for p in i * spp as usize..(i + 1) * spp as usize {
            let range = record.path_hits(p);
            fresh.hits.extend_from_slice(&record.hits[range.clone()]);
            fresh
                .objects
                .extend_from_slice(&record.objects[range.clone()]);
            fresh
                .distances
                .extend_from_slice(&record.distances[range.clone()]);
            if let (Some(to), Some(from)) = (&mut fresh.shapes, &record.shapes) {
                to.hits.extend_from_slice(&from.hits[range.clone()]);
                to.visible.extend_from_slice(
                    &from.visible[range.start * from.words..range.end * from.words],
                );
            }
            fresh.ends.push(record.ends[p]);
            fresh.starts.push(fresh.hits.len() as u32);
        }
    }
    fresh.shrink();
    *record = fresh;
    short.len()
}
