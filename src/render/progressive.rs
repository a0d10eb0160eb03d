//! Who does the work: the image is cut into tiles that rayon's worker
//! threads take from a shared counter (centre first, so a viewer sees the
//! middle of the picture first), in passes of growing quality.
//!
//! Each pass renders every pixel from scratch at its own shadow-ray count,
//! and a pixel's value depends only on the scene, the pixel and that count
//! (its random numbers are keyed by seed, pixel and depth). So the last
//! pass equals a one-shot render bit for bit, whatever the thread count,
//! tile order or cancelled passes before it — and the scheme works for any
//! estimator, including ones that are not sums of independent batches.
//! The cost is the earlier passes: counts grow 16× per pass, and none has
//! fewer than 16 rays (`MIN_INTERMEDIATE_RAYS`), since a frame's base cost
//! does not shrink with its rays.

use std::sync::Arc;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use glam::Vec3;

use super::camera::Camera;
use super::film::Film;
use super::live::record::{Budget, TileRecord, TileRecorder, shininess_of};
use super::live::relight::{Previous, Relighter};
use super::scene::Scene;
use super::settings::RenderSettings;
use super::shading_params::ShadingParams;
use super::stats::RayStats;
use super::tracer::{TraceScratch, Tracer};

/// Shared flag to stop a render; checked before every tile and every row.
#[derive(Debug, Clone, Default)]
pub struct CancelToken(Arc<AtomicBool>);

impl CancelToken {
    pub fn new() -> CancelToken {
        CancelToken::default()
    }
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Relaxed);
    }
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// The render was cancelled before it finished.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("render cancelled")]
pub struct Cancelled;

/// One pass over the image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pass {
    /// Shadow rays per hit point in this pass.
    pub shadow_rays: u32,
    /// 1 for full resolution; b > 1 renders one pixel per b×b block and
    /// fills the block with it (a quick preview).
    pub block: u32,
}

/// Side of the preview pass's blocks.
pub const PREVIEW_BLOCK: u32 = 8;

/// Fewest shadow rays of an intermediate full-resolution pass: below it a
/// pass costs about a frame's base cost (camera paths and shading), a large
/// share of the final pass for little to see (on the seed room at 64 rays a
/// 4-ray pass added 40–80 % to the time to full quality).
const MIN_INTERMEDIATE_RAYS: u32 = 16;

/// The passes of a progressive render ending at `shadow_rays`: a preview at
/// 1/8 resolution, then full-resolution passes whose counts grow 16× up to
/// the requested one, from [`MIN_INTERMEDIATE_RAYS`] on.
pub fn pass_plan(shadow_rays: u32) -> Vec<Pass> {
    let mut counts = vec![shadow_rays];
    while let Some(&s) = counts.last() {
        if s / 16 < MIN_INTERMEDIATE_RAYS {
            break;
        }
        counts.push(s / 16);
    }
    counts.reverse();
    let mut plan = vec![Pass {
        shadow_rays: shadow_rays.min(4),
        block: PREVIEW_BLOCK,
    }];
    plan.extend(counts.into_iter().map(|shadow_rays| Pass {
        shadow_rays,
        block: 1,
    }));
    plan
}

/// A rectangle of the image, in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TileRect {
    pub x: u32,
    pub y: u32,
    pub w: u32,
    pub h: u32,
}

impl TileRect {
    /// The whole image of `camera`.
    pub fn whole(camera: &Camera) -> TileRect {
        TileRect {
            x: 0,
            y: 0,
            w: camera.width,
            h: camera.height,
        }
    }
}

/// A finished tile, handed to the caller from the worker thread.
pub struct TileUpdate<'a> {
    /// Index of the pass in the plan and the number of passes.
    pub pass_index: usize,
    pub pass_count: usize,
    pub pass: Pass,
    pub rect: TileRect,
    /// Linear RGB, `rect.w × rect.h`, rows packed.
    pub pixels: &'a [Vec3],
    /// Tiles of this pass finished so far (this one included), and in all.
    pub tiles_done: usize,
    pub tiles_total: usize,
    /// Rays traced for this tile (for a live rays-per-second readout).
    pub rays: u64,
}

/// How to run a render.
#[derive(Debug, Clone)]
pub struct RenderOptions {
    /// Worker threads; `None` uses rayon's current pool.
    pub threads: Option<usize>,
    /// Run the preview and intermediate passes, or only the final one.
    pub progressive: bool,
    /// Side of a tile in pixels (a multiple of the preview block).
    pub tile_size: u32,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            threads: None,
            progressive: false,
            tile_size: 32,
        }
    }
}

/// What a finished render returns.
#[derive(Debug, Clone)]
pub struct RenderReport {
    pub film: Film,
    /// Rays of all passes.
    pub stats: RayStats,
    /// Rays of the final pass alone (equal to a one-shot render's).
    pub final_stats: RayStats,
    pub elapsed: Duration,
}

/// Tiles of a rectangle of the image, nearest its centre first.
pub fn tiles_of(area: TileRect, size: u32) -> Vec<TileRect> {
    let mut tiles = Vec::new();
    let (x_end, y_end) = (area.x + area.w, area.y + area.h);
    for y in (area.y..y_end).step_by(size as usize) {
        for x in (area.x..x_end).step_by(size as usize) {
            tiles.push(TileRect {
                x,
                y,
                w: size.min(x_end - x),
                h: size.min(y_end - y),
            });
        }
    }
    let cx = area.x as f64 + area.w as f64 / 2.0;
    let cy = area.y as f64 + area.h as f64 / 2.0;
    tiles.sort_by(|a, b| {
        let d = |t: &TileRect| {
            let dx = t.x as f64 + t.w as f64 / 2.0 - cx;
            let dy = t.y as f64 + t.h as f64 / 2.0 - cy;
            dx * dx + dy * dy
        };
        d(a).total_cmp(&d(b))
    });
    tiles
}

/// Renders the scene without progress reports (one pass, all threads).
pub fn render_image(scene: &Scene, settings: &RenderSettings, shading: &ShadingParams) -> Film {
    render(
        scene,
        settings,
        shading,
        &RenderOptions::default(),
        &CancelToken::new(),
        &|_| {},
    )
    .expect("an uncancellable render finishes")
    .film
}

/// Renders the scene, calling `on_tile` from the worker threads with every
/// finished tile of every pass.
pub fn render(
    scene: &Scene,
    settings: &RenderSettings,
    shading: &ShadingParams,
    options: &RenderOptions,
    cancel: &CancelToken,
    on_tile: &(dyn Fn(&TileUpdate) + Sync),
) -> Result<RenderReport, Cancelled> {
    let plan = if options.progressive {
        pass_plan(settings.shadow_rays)
    } else {
        vec![Pass {
            shadow_rays: settings.shadow_rays,
            block: 1,
        }]
    };
    let whole = TileRect::whole(&scene.camera);
    in_pool(options.threads, || {
        render_passes(
            scene, settings, shading, &plan, whole, options, cancel, on_tile, None, None,
        )
        .map(|(report, _)| report)
    })
}

/// Renders one rectangle of the image (a crop window; one pass): the film
/// is `region`'s size and each of its pixels is the one a render of the
/// whole image has there, bit for bit, since a pixel's random numbers are
/// keyed by its position in the whole image.
pub fn render_region(
    scene: &Scene,
    settings: &RenderSettings,
    shading: &ShadingParams,
    region: TileRect,
    options: &RenderOptions,
    cancel: &CancelToken,
    on_tile: &(dyn Fn(&TileUpdate) + Sync),
) -> Result<RenderReport, Cancelled> {
    let plan = [Pass {
        shadow_rays: settings.shadow_rays,
        block: 1,
    }];
    in_pool(options.threads, || {
        render_passes(
            scene, settings, shading, &plan, region, options, cancel, on_tile, None, None,
        )
        .map(|(report, _)| report)
    })
}

/// Runs `f` on a pool of `threads` workers, or on rayon's current pool.
pub(crate) fn in_pool<T: Send>(
    threads: Option<usize>,
    f: impl FnOnce() -> Result<T, Cancelled> + Send,
) -> Result<T, Cancelled> {
    on_threads(threads, f).unwrap_or(Err(Cancelled))
}

/// Runs `f` on a pool of `threads` workers, or on rayon's current pool
/// (`None`: the pool could not be started).
pub fn on_threads<T: Send>(threads: Option<usize>, f: impl FnOnce() -> T + Send) -> Option<T> {
    match threads {
        Some(n) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n.max(1))
                .thread_name(|i| format!("penumbra-render-{i}"))
                .build()
                .ok()?;
            Some(pool.install(f))
        }
        None => Some(f()),
    }
}

/// The passes of `plan` over `area` of the image (the film is `area`'s
/// size); with `budget`, the final pass also records every pixel's path
/// (one record per tile, in the order of [`tiles_of`]), following the
/// `previous` frame's paths where it has the tile (a light edit).
#[allow(clippy::too_many_arguments)]
pub(crate) fn render_passes(
    scene: &Scene,
    settings: &RenderSettings,
    shading: &ShadingParams,
    plan: &[Pass],
    area: TileRect,
    options: &RenderOptions,
    cancel: &CancelToken,
    on_tile: &(dyn Fn(&TileUpdate) + Sync),
    budget: Option<&Budget>,
    previous: Option<&Previous>,
) -> Result<(RenderReport, Vec<TileRecord>), Cancelled> {
    let start = Instant::now();
    let tiles = tiles_of(area, tile_side(options));
    let film = Mutex::new(Film::new_on_pool(area.w, area.h));
    let records: Mutex<Vec<Option<TileRecord>>> = Mutex::new(vec![None; tiles.len()]);
    let mut total = RayStats::default();
    let mut last = RayStats::default();
    for (pass_index, &pass) in plan.iter().enumerate() {
        let tracer = Tracer::new(scene, settings, shading, pass.shadow_rays);
        let record = budget.filter(|_| pass_index + 1 == plan.len());
        let shininess = shininess_of(shading);
        let job = TileJob {
            tiles: &tiles,
            film: &film,
            origin: (area.x, area.y),
            cancel,
            on_tile,
            pass,
            pass_index,
            pass_count: plan.len(),
        };
        let stats = job.run(&tracer, |i, rect, scratch, pixels| {
            let Some(budget) = record else {
                return render_tile(&tracer, rect, pass.block, cancel, scratch, pixels);
            };
            let mut rec = budget.record(rect, tracer.pattern.count(), shininess.clone());
            let old = previous
                .and_then(|p| Some((lock(p.tiles.get(i)?).take()?, p.reflections)))
                .filter(|(old, _)| old.rect == rect);
            // Every path is recorded; under a light edit it follows the
            // tile's old records as far as they hold.
            let mut recorder = TileRecorder { record: &mut rec };
            let finished = match &old {
                Some((old, reflections)) => {
                    let light = &tracer.scene.light.shape;
                    let mut relighter = Relighter::new(recorder, old, light, *reflections);
                    tracer.trace_rect(rect, cancel, scratch, &mut relighter, pixels)
                }
                None => tracer.trace_rect(rect, cancel, scratch, &mut recorder, pixels),
            };
            if !finished {
                return false;
            }
            if let Some((old, _)) = old {
                budget.recycle(old);
            }
            rec.shrink();
            budget.add(&rec);
            lock(&records)[i] = Some(rec);
            true
        })?;
        last = stats;
        total += last;
    }
    let records = records
        .into_inner()
        .unwrap_or_else(|e| e.into_inner())
        .into_iter()
        .flatten()
        .collect();
    Ok((
        RenderReport {
            film: film.into_inner().unwrap_or_else(|e| e.into_inner()),
            stats: total,
            final_stats: last,
            elapsed: start.elapsed(),
        },
        records,
    ))
}

/// One pass of tiles over the image: rayon's threads take tiles from a
/// shared counter (in the order of `tiles`), each tile's pixels go into the
/// film and to `on_tile`. The loop of every pass, and of the live re-shade.
pub(crate) struct TileJob<'a> {
    pub tiles: &'a [TileRect],
    pub film: &'a Mutex<Film>,
    /// Where the film's top-left pixel is in the image.
    pub origin: (u32, u32),
    pub cancel: &'a CancelToken,
    pub on_tile: &'a (dyn Fn(&TileUpdate) + Sync),
    pub pass: Pass,
    pub pass_index: usize,
    pub pass_count: usize,
}

impl TileJob<'_> {
    /// Runs `work(index, rect, scratch, pixels)` for every tile on every
    /// thread of the current pool; `work` fills `pixels` (the tile's rows)
    /// and returns false if cancelled part-way. Returns the rays traced.
    pub(crate) fn run(
        &self,
        tracer: &Tracer,
        work: impl Fn(usize, TileRect, &mut TraceScratch, &mut Vec<Vec3>) -> bool + Sync,
    ) -> Result<RayStats, Cancelled> {
        let next = AtomicUsize::new(0);
        let done = AtomicUsize::new(0);
        let stats = Mutex::new(RayStats::default());
        rayon::broadcast(|_| {
            let mut scratch = tracer.scratch();
            let mut pixels = Vec::new();
            loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                if i >= self.tiles.len() || self.cancel.is_cancelled() {
                    break;
                }
                let rect = self.tiles[i];
                let traced_before = scratch.stats.traced();
                if !work(i, rect, &mut scratch, &mut pixels) {
                    break;
                }
                let (x, y) = (rect.x - self.origin.0, rect.y - self.origin.1);
                lock(self.film).write_block(x, y, rect.w, &pixels);
                let tiles_done = done.fetch_add(1, Ordering::Relaxed) + 1;
                (self.on_tile)(&TileUpdate {
                    pass_index: self.pass_index,
                    pass_count: self.pass_count,
                    pass: self.pass,
                    rect,
                    pixels: &pixels,
                    tiles_done,
                    tiles_total: self.tiles.len(),
                    rays: scratch.stats.traced() - traced_before,
                });
            }
            *lock(&stats) += scratch.stats;
        });
        if self.cancel.is_cancelled() {
            return Err(Cancelled);
        }
        Ok(stats.into_inner().unwrap_or_else(|e| e.into_inner()))
    }
}

/// Locks a mutex, through a panic of another holder (the data is pixels).
pub(crate) fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Side of a tile: a multiple of the preview block.
pub(crate) fn tile_side(options: &RenderOptions) -> u32 {
    options
        .tile_size
        .max(PREVIEW_BLOCK)
        .next_multiple_of(PREVIEW_BLOCK)
}

/// Renders one tile into `out`; false if cancelled part-way.
fn render_tile(
    tracer: &Tracer,
    rect: TileRect,
    block: u32,
    cancel: &CancelToken,
    scratch: &mut TraceScratch,
    out: &mut Vec<Vec3>,
) -> bool {
    if block == 1 {
        return tracer.tile(rect, cancel, scratch, out);
    }
    out.clear();
    out.resize((rect.w * rect.h) as usize, Vec3::ZERO);
    let (width, height) = (tracer.scene.camera.width, tracer.scene.camera.height);
    for by in (0..rect.h).step_by(block as usize) {
        if cancel.is_cancelled() {
            return false;
        }
        for bx in (0..rect.w).step_by(block as usize) {
            if block == 1 {
                out[(by * rect.w + bx) as usize] = tracer.pixel(rect.x + bx, rect.y + by, scratch);
                continue;
            }
            // Preview: the block's centre pixel fills the block.
            let px = (rect.x + bx + block / 2).min(width - 1);
            let py = (rect.y + by + block / 2).min(height - 1);
            let c = tracer.pixel(px, py, scratch);
            for y in by..(by + block).min(rect.h) {
                for x in bx..(bx + block).min(rect.w) {
                    out[(y * rect.w + x) as usize] = c;
                }
            }
        }
    }
    true
}
