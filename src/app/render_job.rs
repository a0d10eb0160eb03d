//! The render worker: one long-lived thread that takes the latest render
//! request, hands it to the core's [`LiveRender`] on rayon's pool (which
//! redoes only what the edit changed: a strength slider recombines, a
//! camera move re-traces progressively), and streams finished tiles
//! (already converted to `Color32`) back to the UI.
//!
//! Requests go through a one-slot mailbox: a new request cancels the
//! running render and overwrites any request still waiting, so rapid slider
//! drags never queue stale renders (at most one running, one pending).
//!
//! While a scene loads or an edit builds, the render of the scene shown is
//! paused (see [`RenderJob::pause`]): its passes and refinement would take
//! the cores the load needs, for an image about to be replaced.

use std::panic::AssertUnwindSafe;
use std::sync::Arc;
use std::time::{Duration, Instant};

use egui::Color32;

use super::settings::numbered_as_edited;
use super::worker::{Shared, Stop, Worker};
use crate::render::progressive::{CancelToken, RenderOptions, TileRect};
use crate::render::{
    DisplayTransform, EditClass, Film, LiveError, LiveRender, LiveReport, Loaded, RenderSettings,
    Scene, SceneDesc, ShadingParams, TileUpdate,
};

/// One finished tile, ready for `TextureHandle::set_partial`.
pub struct TileMsg {
    pub generation: u64,
    pub rect: TileRect,
    /// As shown: through `display`.
    pub pixels: Vec<Color32>,
    /// The linear values (the viewer shows them again when the exposure
    /// or the curve changes).
    pub linear: Vec<glam::Vec3>,
    /// The display transform `pixels` went through.
    pub display: DisplayTransform,
    pub pass_index: usize,
    pub pass_count: usize,
    /// Shadow rays per hit point of the tile's pass.
    pub shadow_rays: u32,
    pub tiles_done: usize,
    pub tiles_total: usize,
    /// Rays traced for the tile.
    pub rays: u64,
    /// Camera samples per pixel of the tile.
    pub samples: u32,
    /// Part of a refinement of a finished image (see
    /// [`RenderJob::with_refinement`]), not of the requested render.
    pub refinement: bool,
}

/// How the render of one generation ended (or that it has not). Cheap to
/// clone: the status bar asks for it every frame.
#[derive(Debug, Clone)]
pub enum JobState {
    /// Waiting in the mailbox or running.
    Running,
    Finished(Arc<FinishedRender>),
    /// The worker panicked or the scene was refused; the message says why.
    Failed(String),
    /// A newer request replaced it.
    Cancelled,
}

/// A completed render: its linear image and what it cost.
#[derive(Debug, Clone)]
pub struct FinishedRender {
    pub desc: SceneDesc,
    /// Shared with a pending export, which writes it without a copy.
    pub film: Arc<Film>,
    pub traced_rays: u64,
    pub elapsed: Duration,
    /// What the edit cost (see [`EditClass`]).
    pub class: EditClass,
    /// From the request to the last tile in the mailbox.
    pub since_request: Duration,
    /// Bytes of the recorded paths the next edit can reuse.
    pub record_bytes: usize,
    /// Camera samples per pixel of `film`: the scene's own, or more once
    /// the worker refined the finished image.
    pub samples: u32,
}

struct Request {
    generation: u64,
    desc: SceneDesc,
    /// The objects of the scene as edited that `desc` leaves out (hidden),
    /// sorted: an error names an object by its place among them.
    hidden: Vec<usize>,
    /// A scene already built (by the loader thread), with the description
    /// it was built for: rendered over instead of building it again.
    built: Option<(SceneDesc, Loaded)>,
    cancel: CancelToken,
    at: Instant,
}

#[derive(Default)]
struct State {
    /// The newest request not yet taken by the worker.
    pending: Option<Request>,
    /// Generation of the newest request.
    latest: u64,
    /// Token of the render running now.
    running: Option<CancelToken>,
    /// The description the worker is rendering (or last rendered).
    running_desc: Option<(u64, SceneDesc)>,
    /// Linear image of the latest generation, written tile by tile (for
    /// picking and for exporting a finished render); a pixel not rendered
    /// yet holds the last image's value.
    film: Option<(u64, Film)>,
    /// The runtime scene being rendered (for picking under the cursor).
    scene: Option<(u64, Arc<Scene>)>,
    tiles: Vec<TileMsg>,
    /// From the request to its first tile in the mailbox.
    first_tile: Option<(u64, Duration)>,
    state: Option<(u64, JobState)>,
    shutdown: bool,
    /// Renders the worker has started (requests it skipped are not counted).
    started: u64,
    /// Test hook: the next render panics inside a tile callback.
    panic_next: bool,
    /// Once a render is finished and nothing else is asked for, add camera
    /// samples up to this many per pixel (1: never).
    refine_to: u32,
    /// How tiles are converted for the screen.
    display: DisplayTransform,
    /// While set, the render of this generation (or an older one) and any
    /// refinement wait at their next tile.
    paused: Option<u64>,
    /// Tiles handed to the UI since the worker started.
    tiles_delivered: u64,
    /// The last finished render a newer request replaced: its image goes
    /// back to the live render to be written over (a fresh one maps and
    /// faults in new pages: milliseconds per edit).
    spent: Option<Arc<FinishedRender>>,
}

impl Stop for State {
    fn stop(&mut self) {
        self.shutdown = true;
        self.pending = None;
        if let Some(c) = &self.running {
            c.cancel();
        }
    }
    fn stopped(&self) -> bool {
        self.shutdown
    }
}

type Inner = Shared<State>;

/// Handle to the worker thread; dropping it cancels and joins the worker.
pub struct RenderJob {
    worker: Worker<State>,
}

impl RenderJob {
    /// A worker that renders what it is asked and stops there.
    pub fn new(repaint: egui::Context) -> RenderJob {
        RenderJob::with_refinement(repaint, 1)
    }

    /// A worker that, once a render is finished and no new request waits,
    /// keeps refining it with more camera samples per pixel (2, 4, 8, …) up
    /// to `refine_to`; each level is the image `penumbra render --spp N`
    /// gives, streamed tile by tile over the last one. The highest level
    /// whose records fit the cap is recorded: a recombine or re-shade edit
    /// is then shown at that many samples at once.
    pub fn with_refinement(repaint: egui::Context, refine_to: u32) -> RenderJob {
        let worker = Worker::spawn(
            "penumbra-render",
            State {
                refine_to,
                ..State::default()
            },
            repaint,
            |inner| match render_pool(false) {
                Some(pool) => pool.install(|| worker_loop(inner)),
                None => worker_loop(inner),
            },
        );
        RenderJob { worker }
    }

    fn inner(&self) -> &Inner {
        self.worker.shared()
    }

    /// Cancels whatever runs or waits and asks for a render of `desc`;
    /// returns its generation.
    pub fn restart(&self, desc: SceneDesc) -> u64 {
        self.restart_built(desc, Vec::new(), None)
    }

    /// As [`restart`](Self::restart), for a scene whose objects `hidden`
    /// (sorted indices) `desc` leaves out, over `built`: a scene built for
    /// the description it comes with (a request that replaces this one
    /// before the worker takes it drops it).
    pub fn restart_built(
        &self,
        desc: SceneDesc,
        hidden: Vec<usize>,
        built: Option<(SceneDesc, Loaded)>,
    ) -> u64 {
        let mut s = self.inner().lock();
        if let Some(c) = &s.running {
            c.cancel();
        }
        let mut built = built;
        if let Some(old) = s.pending.take() {
            s.state = Some((old.generation, JobState::Cancelled));
            // Newer than anything rendered: the worker still starts from it.
            built = built.or(old.built);
        }
        if let Some((_, JobState::Finished(f))) = s.state.take() {
            s.spent = Some(f);
        }
        s.latest += 1;
        let generation = s.latest;
        s.pending = Some(Request {
            generation,
            desc,
            hidden,
            built,
            cancel: CancelToken::new(),
            at: Instant::now(),
        });
        s.state = Some((generation, JobState::Running));
        // Tiles of older generations will never be shown.
        s.tiles.clear();
        self.inner().notify();
        generation
    }

    /// Pauses the render under way and its refinement at their next tile,
    /// keeping what they did (a load needs the cores; the image shown
    /// stays). A newer request is rendered, but not refined, until
    /// [`resume`](Self::resume).
    pub fn pause(&self) {
        let mut s = self.inner().lock();
        s.paused = Some(s.latest);
    }

    /// Goes on with what [`pause`](Self::pause) stopped.
    pub fn resume(&self) {
        self.inner().lock().paused = None;
        self.inner().notify();
    }

    /// Tiles the worker has handed to the UI (renders and refinements).
    pub fn tiles_delivered(&self) -> u64 {
        self.inner().lock().tiles_delivered
    }

    /// Takes the tiles finished since the last call (latest generation only).
    pub fn take_tiles(&self) -> Vec<TileMsg> {
        let mut s = self.inner().lock();
        let latest = s.latest;
        let mut tiles = std::mem::take(&mut s.tiles);
        tiles.retain(|t| t.generation == latest);
        tiles
    }

    /// Converts the tiles from now on through `display` (tiles already
    /// delivered say which they went through).
    pub fn set_display(&self, display: DisplayTransform) {
        self.inner().lock().display = display;
    }

    /// Generation of the newest request.
    pub fn generation(&self) -> u64 {
        self.inner().lock().latest
    }

    /// State of the newest request.
    pub fn state(&self) -> JobState {
        let s = self.inner().lock();
        match &s.state {
            Some((g, st)) if *g == s.latest => st.clone(),
            _ => JobState::Running,
        }
    }

    /// The description the worker took last, with its generation.
    pub fn running_desc(&self) -> Option<(u64, SceneDesc)> {
        self.inner().lock().running_desc.clone()
    }

    /// Linear value of a pixel of the latest generation's image.
    pub fn pixel(&self, x: u32, y: u32) -> Option<glam::Vec3> {
        let s = self.inner().lock();
        match &s.film {
            Some((g, f)) if *g == s.latest && x < f.width && y < f.height => Some(f.get(x, y)),
            _ => None,
        }
    }

    /// The runtime scene of the latest generation, once the worker built it.
    pub fn scene(&self) -> Option<Arc<Scene>> {
        let s = self.inner().lock();
        match &s.scene {
            Some((g, scene)) if *g == s.latest => Some(scene.clone()),
            _ => None,
        }
    }

    /// Blocks until the newest request has ended; false on timeout. For
    /// tests and scripts, never called from the UI.
    pub fn wait(&self, timeout: Duration) -> bool {
        self.inner().wait_until(timeout, |s| {
            matches!(&s.state, Some((g, st)) if *g == s.latest && !matches!(st, JobState::Running))
        })
    }

    /// Time from the newest request to its first tile, once it arrived.
    pub fn first_tile_after(&self) -> Option<Duration> {
        let s = self.inner().lock();
        s.first_tile.filter(|(g, _)| *g == s.latest).map(|(_, d)| d)
    }

    /// How many renders the worker started (stale requests are skipped).
    pub fn renders_started(&self) -> u64 {
        self.inner().lock().started
    }

    /// Test hook: makes the next render panic in a worker thread.
    pub fn inject_panic(&self) {
        self.inner().lock().panic_next = true;
    }

    /// A handle that copies the image being rendered from another thread
    /// (the error readout's worker), so the UI never copies it.
    pub fn film_reader(&self) -> FilmReader {
        FilmReader(self.worker.shared().clone())
    }
}

/// Reads the linear image of a generation as far as it is rendered.
#[derive(Clone)]
pub struct FilmReader(Arc<Inner>);

impl FilmReader {
    /// A copy of `generation`'s image; `None` once a newer request replaced
    /// it.
    pub fn read(&self, generation: u64) -> Option<Film> {
        let s = self.0.lock();
        match &s.film {
            Some((g, f)) if *g == generation && s.latest == generation => Some(f.clone()),
            _ => None,
        }
    }
}

/// The viewer's own rayon pool, one thread per core. The render's threads
/// keep the UI's priority: a lower one let any other process on the machine
/// take their cores (3–4× slower renders under load), while the UI thread,
/// which sleeps between frames, gets a core as soon as it wakes anyway.
/// Background work (the converged reference) asks for `background`: it runs
/// at a lower priority, behind the render.
pub(super) fn render_pool(background: bool) -> Option<rayon::ThreadPool> {
    let mut builder = rayon::ThreadPoolBuilder::new().thread_name(|i| format!("penumbra-tile-{i}"));
    if background {
        builder = builder.start_handler(|_| lower_priority());
    }
    builder.build().ok()
}

#[cfg(target_os = "linux")]
fn lower_priority() {
    // On Linux `setpriority` with a thread id sets that thread's nice value;
    // failing (e.g. under a sandbox) only leaves the default priority.
    // SAFETY: plain system calls on the calling thread, no pointers.
    unsafe {
        let tid = libc::syscall(libc::SYS_gettid) as libc::id_t;
        libc::setpriority(libc::PRIO_PROCESS, tid, 10);
    }
}

#[cfg(not(target_os = "linux"))]
fn lower_priority() {}

/// The records of a refined level (more camera samples than the scene's
/// own), kept so that a recombine or re-shade edit shows that many samples
/// at once instead of starting the refinement again. Only levels whose
/// records fit the live render's cap are recorded.
#[derive(Default)]
struct Kept {
    live: LiveRender,
    /// Samples per pixel of `live`'s records (0: none).
    level: u32,
}

fn worker_loop(inner: &Inner) {
    let mut live = LiveRender::default();
    let mut kept = Kept::default();
    loop {
        let Some((mut req, panic_now, spent, last_film)) = inner.next(|s| {
            let req = s.pending.take()?;
            s.running = Some(req.cancel.clone());
            s.running_desc = Some((req.generation, req.desc.clone()));
            let size = (req.desc.camera.width, req.desc.camera.height);
            // The last image's pages rather than fresh ones, not cleared:
            // a pixel keeps its last value until its first tile arrives, as
            // on the screen (every pass writes every pixel; clearing cost
            // a 6 MB write before each edit's first tile at 960×540).
            let last_film = match s.film.take() {
                Some((_, f)) if (f.width, f.height) == size => Some(f),
                _ => None,
            };
            let panic_now = std::mem::take(&mut s.panic_next);
            s.started += 1;
            Some((req, panic_now, s.spent.take(), last_film))
        }) else {
            return;
        };
        // A new size's image is made outside the lock, which the UI takes
        // every frame (100 MB at the preview's largest).
        let film = last_film.unwrap_or_else(|| {
            let (w, h) = (req.desc.camera.width, req.desc.camera.height);
            Film::new(w, h)
        });
        inner.lock().film = Some((req.generation, film));
        // Unless the UI or an export still holds it.
        if let Some(f) = spent.and_then(|f| Arc::try_unwrap(f).ok())
            && let Ok(film) = Arc::try_unwrap(f.film)
        {
            live.recycle(film);
        }
        if let Some((desc, loaded)) = req.built.take() {
            live.adopt(&desc, loaded);
        }
        let generation = req.generation;
        // A panic anywhere in the render (our callback included) ends this
        // generation with an error message; the thread and the window live on.
        let result = std::panic::catch_unwind(AssertUnwindSafe(|| {
            run_one(inner, &req, panic_now, &mut live, &mut kept)
        }));
        if result.is_err() {
            // Whatever the panic interrupted is not to be reused.
            live = LiveRender::default();
            kept = Kept::default();
        }
        let mut done = None;
        let state = match result {
            Ok(Ok(Some((report, samples, from_kept)))) => {
                done = Some((samples, from_kept));
                JobState::Finished(Arc::new(FinishedRender {
                    samples,
                    desc: req.desc.clone(),
                    traced_rays: report.stats.traced(),
                    elapsed: report.elapsed,
                    class: report.class,
                    since_request: req.at.elapsed(),
                    record_bytes: report.record_bytes,
                    film: Arc::new(report.film),
                }))
            }
            Ok(Ok(None)) => JobState::Cancelled,
            Ok(Err(msg)) => JobState::Failed(msg),
            Err(payload) => JobState::Failed(format!(
                "the render worker panicked: {}",
                panic_message(payload.as_ref())
            )),
        };
        {
            let mut s = inner.lock();
            s.running = None;
            if matches!(&s.state, Some((g, _)) if *g == generation) {
                s.state = Some((generation, state));
            }
        }
        inner.announce();
        if let Some((samples, from_kept)) = done {
            let refined = std::panic::catch_unwind(AssertUnwindSafe(|| {
                refine(inner, &req, &live, &mut kept, samples, from_kept)
            }));
            if refined.is_err() {
                live = LiveRender::default();
                kept = Kept::default();
            }
        }
    }
}

/// `desc` at `spp` camera samples per pixel.
fn at_samples(desc: &SceneDesc, spp: u32) -> SceneDesc {
    let mut d = desc.clone();
    d.render.samples_per_pixel = spp;
    d
}

/// Converts a finished tile for the texture and hands it to the UI, unless
/// a newer request replaced `generation`.
fn deliver(inner: &Inner, req: &Request, t: &TileUpdate, samples: u32, refinement: bool) {
    let generation = req.generation;
    // Paused: this render thread waits here, its work kept, until resumed,
    // replaced by a newer request or stopped.
    inner.wait_while(|s| {
        !s.shutdown
            && s.latest == generation
            && s.paused.is_some_and(|p| refinement || generation <= p)
    });
    let display = inner.lock().display;
    // Convert on the worker: the UI only copies bytes into the texture.
    let mut pixels = Vec::with_capacity(t.pixels.len());
    display.encode_each(t.pixels, |[r, g, b]| {
        pixels.push(Color32::from_rgb(r, g, b))
    });
    {
        let mut s = inner.lock();
        if s.latest != generation {
            return;
        }
        if let Some((g, film)) = &mut s.film
            && *g == generation
        {
            film.write_block(t.rect.x, t.rect.y, t.rect.w, t.pixels);
        }
        s.tiles_delivered += 1;
        if !matches!(s.first_tile, Some((g, _)) if g == generation) {
            s.first_tile = Some((generation, req.at.elapsed()));
        }
        s.tiles.push(TileMsg {
            generation,
            rect: t.rect,
            pixels,
            linear: t.pixels.to_vec(),
            display,
            pass_index: t.pass_index,
            pass_count: t.pass_count,
            shadow_rays: t.pass.shadow_rays,
            tiles_done: t.tiles_done,
            tiles_total: t.tiles_total,
            rays: t.rays,
            samples,
            refinement,
        });
    }
    inner.repaint();
}

/// Refines a finished render with more camera samples per pixel, level by
/// level from above `samples`, while no new request waits. Each level
/// renders every sample again (a pixel is the average of its own samples,
/// so level N equals a fresh render at N samples). A level whose records
/// fit the cap (estimated from the records per sample of the render
/// before) is rendered by the kept live render, which records it; the
/// others by a plain render. `from_kept`: the image was the kept render's.
fn refine(
    inner: &Inner,
    req: &Request,
    live: &LiveRender,
    kept: &mut Kept,
    samples: u32,
    from_kept: bool,
) {
    let refine_to = inner.lock().refine_to;
    let source = if from_kept { &kept.live } else { live };
    let (Some(scene), per_sample) = (
        source.scene().cloned(),
        source.path_record_bytes() / samples.max(1) as usize,
    ) else {
        return;
    };
    let mut settings = RenderSettings::from_desc(&req.desc);
    let shading = ShadingParams::from_desc(&req.desc);
    let options = RenderOptions {
        threads: None,
        progressive: false,
        tile_size: 32,
    };
    let mut level = (samples + 1).next_power_of_two();
    while level <= refine_to {
        let cancel = CancelToken::new();
        {
            let mut s = inner.lock();
            if s.pending.is_some() || s.shutdown || s.latest != req.generation {
                return;
            }
            s.running = Some(cancel.clone());
        }
        let on_tile = |t: &TileUpdate| deliver(inner, req, t, level, true);
        let fits = per_sample > 0 && per_sample.saturating_mul(level as usize) <= kept.live.cap();
        let result = if fits {
            let desc = at_samples(&req.desc, level);
            if !from_kept && kept.live.class_of(&desc) == EditClass::Rebuild {
                // Over the objects and BVH already built.
                kept.live.share_scene(live);
            }
            // Its records are replaced (gone if this level is cancelled).
            kept.level = 0;
            kept.live
                .render(&desc, &options, &cancel, &on_tile)
                .map(|r| {
                    if r.record_bytes > 0 {
                        kept.level = level;
                    }
                    (r.film, r.stats.traced())
                })
                .map_err(|_| ())
        } else {
            settings.samples_per_pixel = level;
            crate::render::render(&scene, &settings, &shading, &options, &cancel, &on_tile)
                .map(|r| (r.film, r.stats.traced()))
                .map_err(|_| ())
        };
        let mut s = inner.lock();
        s.running = None;
        let Ok((film, traced)) = result else { return };
        if s.latest != req.generation {
            return;
        }
        if let Some((g, JobState::Finished(f))) = &s.state
            && *g == req.generation
        {
            let mut refined = (**f).clone();
            refined.film = Arc::new(film);
            refined.samples = level;
            refined.traced_rays = traced;
            s.state = Some((req.generation, JobState::Finished(Arc::new(refined))));
        }
        drop(s);
        inner.announce();
        level *= 2;
    }
}

/// Runs one request: `Ok(None)` if cancelled, `Err` if the scene is
/// refused; else the report, its samples per pixel and whether the kept
/// refined records made it. An edit that only recombines or re-shades the
/// kept records is rendered from them, at their samples per pixel (exactly
/// the image a fresh render at that count gives).
fn run_one(
    inner: &Inner,
    req: &Request,
    panic_now: bool,
    live: &mut LiveRender,
    kept: &mut Kept,
) -> Result<Option<(LiveReport, u32, bool)>, String> {
    let spp = req.desc.render.samples_per_pixel;
    if kept.level > spp && !panic_now {
        let level = kept.level;
        let desc = at_samples(&req.desc, level);
        if kept.live.class_of(&desc) <= EditClass::Reshade {
            let options = RenderOptions {
                threads: None,
                progressive: false,
                tile_size: 32,
            };
            let result = kept.live.render(&desc, &options, &req.cancel, &|t| {
                deliver(inner, req, t, level, false);
            });
            if let Some(scene) = kept.live.scene() {
                inner.lock().scene = Some((req.generation, scene.clone()));
            }
            return match result {
                Ok(report) => Ok(Some((report, level, true))),
                Err(LiveError::Cancelled(_)) => {
                    kept.level = 0;
                    Ok(None)
                }
                Err(LiveError::Scene(e)) => Err(numbered_as_edited(e, &req.hidden).to_string()),
            };
        }
    }
    let options = RenderOptions {
        threads: None,
        progressive: true,
        tile_size: 32,
    };
    let result = live.render(&req.desc, &options, &req.cancel, &|t| {
        if panic_now {
            panic!("injected test panic");
        }
        deliver(inner, req, t, spp, false);
    });
    if let Some(scene) = live.scene() {
        inner.lock().scene = Some((req.generation, scene.clone()));
    }
    match result {
        Ok(report) => Ok(Some((report, spp, false))),
        Err(LiveError::Cancelled(_)) => Ok(None),
        Err(LiveError::Scene(e)) => Err(numbered_as_edited(e, &req.hidden).to_string()),
    }
}

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "unknown panic".into()
    }
}
