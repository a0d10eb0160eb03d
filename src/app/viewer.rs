//! The viewer's state and frame: the edited scene, the texture the tiles
//! stream into, and the panels around it.
//!
//! One road for every parameter: a control edits `desc` (or `view`), then
//! [`Viewer::restart`] renders `view.apply(&desc)` on the worker. Nothing
//! renders on the UI thread, and nothing here waits for the worker.
//!
//! The error readout follows the same road: the reference is made or read
//! on its own thread, and each finished pass is compared with it on the
//! compare thread; the UI only shows the figures and uploads the image.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use egui::{Color32, ColorImage, ImageData, Sense, TextureHandle, TextureOptions, Ui};

use super::camera_control::{Reach, camera_input, frame_all, set_pivot};
use super::controls::{Action, ControlsState, controls_ui};
use super::error_view::{
    ErrorJob, ErrorRequest, ErrorShown, ImageSource, Readout, legend_ui, readout_text,
};
use super::export::IoTasks;
use super::file_dialog::{DialogResult, PathDialog, Purpose};
use super::history::{History, Snapshot};
use super::image_toolbar::toolbar_ui;
use super::image_view::{GRID_ZOOM, ImageView, paint_grid, zoom_step};
use super::pinned::{Compare, CompareMode};
use super::reference::{
    Match, Origin, RefAction, RefPanel, Reference, ReferenceTask, TaskKind, TaskOutcome, ViewMode,
    reference_ui, same_limit,
};
use super::render_job::{JobState, RenderJob};
use super::scene_loader::{Built, LoadKind, LoadResult, SceneLoads, progress_ui};
use super::settings::{ViewSettings, numbered_as_edited, preview_size};
use super::shortcuts::{self, Command, help_ui};
use super::status::{Progress, status_ui};
use super::timings::Timings;
use super::watch::SceneWatcher;
use crate::render::scene::HitTarget;
use crate::render::scene_file::{CameraDesc, ObjectDesc};
use crate::render::{DisplayTransform, EditClass, Film, SceneDesc, classify};

/// Background of the image area and of an image not yet rendered.
const EMPTY: Color32 = Color32::from_rgb(24, 24, 24);

/// The status line's hint while the camera stands behind a plane with the
/// cut-away off.
const BEHIND_A_WALL: &str = "the camera is behind a wall: C (cut-away) sees through it";

/// What names the built-in scene where a file's path would (the loading
/// strip's "building the seed room…").
const SEED_ROOM: &str = "the seed room";

/// A whole texture.
const FULL_UV: egui::Rect = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));

/// How the viewer starts.
#[derive(Debug, Clone)]
pub struct ViewerOptions {
    pub desc: SceneDesc,
    /// The scene file, watched for changes; `None` for the built-in room.
    pub scene_path: Option<PathBuf>,
    pub log_timings: bool,
    /// Change a slider by itself at this interval (for measuring
    /// `--log-timings` without a person at the mouse).
    pub wiggle: Option<Duration>,
    /// Refine a finished image with camera samples up to this many per
    /// pixel while nothing changes (1: never, as for `new`).
    pub refine_spp: u32,
    /// A scene file to open once the window is up (in place of `desc`).
    pub open_at_launch: Option<LaunchScene>,
}

/// The scene file a launch opens: read and built on the load thread as
/// *File → Open* does, under the loading strip with its timer and Cancel,
/// while the window draws. Nothing renders until it arrives; if it does
/// not open (or is cancelled) the viewer shows the seed room.
#[derive(Debug, Clone)]
pub struct LaunchScene {
    pub path: PathBuf,
    /// Named on the command line: a file that does not open is named in
    /// the banner, and watched and opened once it is valid. Otherwise (the
    /// last session's scene) the seed room is shown without a word.
    pub named: bool,
}

impl ViewerOptions {
    /// Options for a scene description, nothing else switched on.
    pub fn new(desc: SceneDesc) -> ViewerOptions {
        ViewerOptions {
            desc,
            scene_path: None,
            log_timings: false,
            wiggle: None,
            refine_spp: 1,
            open_at_launch: None,
        }
    }
}

/// What a double-click on the image found.
#[derive(Debug, Clone)]
pub struct PickInfo {
    pub pixel: (u32, u32),
    /// "objects\[3\] (box)", "the light" or "background".
    pub what: String,
    pub material: Option<String>,
    pub linear_rgb: Option<[f32; 3]>,
    /// The 8-bit sRGB code shown there (through the exposure and curve).
    pub shown_srgb: Option<[u8; 3]>,
    /// The pinned image A there: linear RGB and the sRGB code shown.
    pub pinned: Option<([f32; 3], [u8; 3])>,
}

/// The inspector's text: what is there, its linear RGB and the sRGB code
/// shown, for the live image and A.
pub fn inspector_text(p: &PickInfo) -> String {
    let values = |linear: [f32; 3], srgb: [u8; 3]| {
        format!(
            "linear RGB ({:.4}, {:.4}, {:.4})  sRGB ({}, {}, {})",
            linear[0], linear[1], linear[2], srgb[0], srgb[1], srgb[2]
        )
    };
    let mut text = format!(
        "pixel ({}, {}): {}{}\nlive  {}",
        p.pixel.0,
        p.pixel.1,
        p.what,
        p.material
            .as_ref()
            .map(|m| format!(", material \"{m}\""))
            .unwrap_or_default(),
        match (p.linear_rgb, p.shown_srgb) {
            (Some(l), Some(s)) => values(l, s),
            _ => "not rendered yet".into(),
        }
    );
    if let Some((l, s)) = p.pinned {
        text.push_str(&format!("\nA     {}", values(l, s)));
    }
    text
}

pub struct Viewer {
    /// The scene as edited, at its own resolution.
    desc: SceneDesc,
    /// The scene as last read from its file (to tell what a reload changed).
    file_desc: Option<SceneDesc>,
    home_camera: CameraDesc,
    /// Where the camera may go: from the latest scene built (`None`
    /// before one is).
    reach: Option<Reach>,
    /// What the latest open replaced, until the opened scene's first
    /// render ends.
    replaced: Option<Box<Replaced>>,
    view: ViewSettings,
    controls: ControlsState,
    objects: super::object_list::ObjectListState,
    scene_path: Option<PathBuf>,
    watcher: Option<SceneWatcher>,
    job: Option<RenderJob>,
    texture: Option<TextureHandle>,
    /// What the texture holds, kept on the CPU (for tests and resizes).
    shown: ColorImage,
    /// The linear values of `shown` (to show them again through another
    /// exposure or curve; the render's own film is never touched).
    linear: Film,
    /// Exposure and tone curve of the image view (and of a saved PNG).
    display: DisplayTransform,
    /// Zoom and pan of the image, independent of the camera.
    image_view: ImageView,
    /// The image area and pixels per point of the last frame (for the
    /// zoom keys).
    image_area: (egui::Rect, f32),
    /// The textures draw image pixels as blocks (zoomed in).
    blocks: bool,
    /// The pinned image A and the comparison with it.
    compare: Compare,
    progress: Progress,
    /// Generation whose end (finished or failed) was already handled.
    handled: u64,
    banner: Option<String>,
    /// The banner shows a failed render (cleared by the next good one).
    banner_from_render: bool,
    notice: Option<String>,
    dialog: Option<PathDialog>,
    io: IoTasks,
    /// Scene files being read (open, hot reload) on their own thread.
    loads: SceneLoads,
    /// The scene a load built, for the next render to start from.
    built: Option<Built>,
    /// The render is paused for a load (see [`RenderJob::pause`]).
    render_paused: bool,
    /// The scene file the launch is opening, until it arrives.
    launch: Option<Launching>,
    /// The build of an edit that needs the scene built again, under way.
    rebuild: Option<Rebuild>,
    /// What the render was last asked for: an edit is compared with it to
    /// tell whether it needs the scene built again, and it comes back if
    /// that build fails or is cancelled.
    render_base: Option<RenderBase>,
    /// The scene's fields and the view as last accepted: an edit the
    /// loader would refuse goes back to them.
    accepted: Option<Accepted>,
    /// The banner shows a refused edit (cleared by the next good one).
    banner_from_edit: bool,
    /// egui's context, once the first frame has run (loads repaint it).
    ctx: Option<egui::Context>,
    pick: Option<PickInfo>,
    timings: Timings,
    wiggle: Option<(Duration, Instant, u32)>,
    /// The reference of the error readout.
    reference: Option<Reference>,
    /// A reference being computed or read.
    ref_task: Option<ReferenceTask>,
    /// How the reference relates to the image on screen (set on restart).
    ref_match: Option<Match>,
    /// Id of the latest reference.
    ref_ids: u64,
    view_mode: ViewMode,
    /// Stops below the largest difference shown as white.
    error_exposure: f32,
    errors: Option<ErrorJob>,
    /// The latest readout and its error image.
    error: Option<ErrorShown>,
    error_texture: Option<TextureHandle>,
    /// Camera samples per pixel to refine a finished image to.
    refine_spp: u32,
    /// Tiles received of the pass being streamed: (generation, pass, count).
    pass_tiles: (u64, usize, usize),
    /// The latest pass complete on screen: (generation, pass, pass count).
    last_pass: Option<(u64, usize, usize)>,
    history: History,
    /// The scene as last opened, reloaded or saved (toggles applied): the
    /// edits are unsaved while the scene differs from it.
    saved: SceneDesc,
    /// A question waiting for an answer (unsaved edits).
    confirm: Option<Confirm>,
    help_open: bool,
    about_open: bool,
    panel_visible: bool,
    fullscreen: bool,
    /// The window title last sent.
    title: String,
    /// Quitting with unsaved edits was confirmed.
    quit_confirmed: bool,
    /// Remember settings between runs (off: `--no-persist`, and in tests).
    pub persist: bool,
    /// Where the inspector popup opens (the double-click's position).
    pick_pos: Option<egui::Pos2>,
    /// Scene files opened lately, newest first.
    recent: Vec<PathBuf>,
    /// The folder the file dialog was last in.
    last_dir: Option<PathBuf>,
}

/// What the viewer remembers between runs (eframe's storage; the window's
/// geometry and the side panel's sections open or closed are eframe's and
/// egui's own).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Persisted {
    /// The scene shown at exit (opened again by a bare `penumbra`).
    pub last_scene: Option<PathBuf>,
    pub recent: Vec<PathBuf>,
    /// The folder the file dialog was last in.
    pub last_dir: Option<PathBuf>,
    pub panel_hidden: bool,
    pub resolution_scale: Option<f64>,
    pub error_view: bool,
    pub error_exposure: f32,
}

impl Persisted {
    /// The key in eframe's storage.
    pub const KEY: &'static str = "penumbra-viewer";
}

/// What an open replaced, kept until the opened scene's first render ends:
/// if that fails (the JSON was fine, but a mesh file is missing or broken
/// and the scene does not build), it comes back, as it stays when a file
/// does not parse.
struct Replaced {
    desc: SceneDesc,
    file_desc: Option<SceneDesc>,
    saved: SceneDesc,
    home_camera: CameraDesc,
    view: ViewSettings,
    history: History,
    scene_path: Option<PathBuf>,
    recent: Vec<PathBuf>,
}

/// The launch's scene file being read and built (see [`LaunchScene`]).
struct Launching {
    scene: LaunchScene,
    /// Its load's id, once the first frame started it.
    load: Option<u64>,
}

/// An edited scene being built on the load thread.
struct Rebuild {
    load: u64,
    /// The scene to render being built (toggles applied).
    target: SceneDesc,
}

/// The state the render was last asked to show, kept with one copy of
/// the objects (a scene may hold 10⁶).
struct RenderBase {
    /// The scene with the toggles applied: what the render got.
    shown: SceneDesc,
    /// The scene as edited, without its objects, and the view.
    head: SceneDesc,
    view: ViewSettings,
    /// The objects the view hides (left out of `shown`), in order.
    hidden_objects: Vec<ObjectDesc>,
}

impl RenderBase {
    /// The scene as edited and the view that gave `shown`.
    fn state(&self) -> (SceneDesc, ViewSettings) {
        let total = self.shown.objects.len() + self.hidden_objects.len();
        let (mut shown, mut hidden) = (self.shown.objects.iter(), self.hidden_objects.iter());
        let objects = (0..total)
            .filter_map(|i| match self.view.hidden.binary_search(&i) {
                Ok(_) => hidden.next(),
                Err(_) => shown.next(),
            })
            .cloned()
            .collect();
        let desc = SceneDesc {
            objects,
            ..head_of(&self.head)
        };
        (desc, self.view.clone())
    }
}

/// Everything an edit in the panel or on the image may change but the
/// objects: those take only another material (always a valid one) or a
/// visibility toggle (a view setting), and copying 10⁶ of them on every
/// edit would stall the window.
struct Accepted {
    /// The scene without its objects.
    head: SceneDesc,
    view: ViewSettings,
}

impl Accepted {
    fn of(desc: &SceneDesc, view: &ViewSettings) -> Accepted {
        Accepted {
            head: head_of(desc),
            view: view.clone(),
        }
    }
}

/// `desc` without its objects.
fn head_of(desc: &SceneDesc) -> SceneDesc {
    SceneDesc {
        format: desc.format,
        camera: desc.camera.clone(),
        render: desc.render.clone(),
        light: desc.light.clone(),
        materials: desc.materials.clone(),
        objects: Vec::new(),
        base_dir: desc.base_dir.clone(),
    }
}

/// Makes `target` equal to `source`, copying the objects only if they
/// differ (comparing them allocates nothing; a copy of 10⁶ takes longer
/// than a frame).
fn copy_scene(target: &mut SceneDesc, source: &SceneDesc) {
    if target.objects != source.objects {
        target.objects = source.objects.clone();
    }
    let objects = std::mem::take(&mut target.objects);
    *target = SceneDesc {
        objects,
        ..head_of(source)
    };
}

/// The JSON paths of the fields (leaves, a vector counting as one) whose
/// values differ between two scenes without objects: what an edit changed.
fn changed_fields(before: &SceneDesc, after: &SceneDesc) -> Vec<String> {
    use serde_json::Value;
    fn walk(path: &str, a: Option<&Value>, b: Option<&Value>, out: &mut Vec<String>) {
        if let (Some(Value::Object(a)), Some(Value::Object(b))) = (a, b) {
            let mut keys: Vec<&String> = a.keys().chain(b.keys()).collect();
            keys.sort();
            keys.dedup();
            for k in keys {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                walk(&p, a.get(k), b.get(k), out);
            }
        } else if a != b {
            out.push(path.to_string());
        }
    }
    let value = |d: &SceneDesc| serde_json::to_value(d).ok();
    let mut out = Vec::new();
    walk("", value(before).as_ref(), value(after).as_ref(), &mut out);
    out
}

/// What waits for "discard unsaved edits?".
#[derive(Debug, Clone, PartialEq)]
pub enum Confirm {
    Quit,
    Open(PathBuf),
}

impl Viewer {
    pub fn new(options: ViewerOptions) -> Viewer {
        let desc = options.desc;
        let history = History::new(Snapshot {
            desc: desc.clone(),
            view: ViewSettings::for_scene(&desc),
        });
        // The size the first render will have (the preview's).
        let (width, height) = preview_size(desc.camera.width, desc.camera.height);
        let shown = ColorImage::filled([width as usize, height as usize], EMPTY);
        let linear = blank_film(width, height);
        Viewer {
            home_camera: desc.camera.clone(),
            reach: None,
            render_paused: false,
            replaced: None,
            view: ViewSettings::for_scene(&desc),
            progress: Progress::new(desc.render.sampling, desc.render.area_light_model),
            file_desc: options.scene_path.as_ref().map(|_| desc.clone()),
            saved: desc.clone(),
            history,
            confirm: None,
            help_open: false,
            about_open: false,
            panel_visible: true,
            fullscreen: false,
            title: String::new(),
            quit_confirmed: false,
            pick_pos: None,
            persist: false,
            recent: Vec::new(),
            last_dir: None,
            desc,
            controls: ControlsState::default(),
            objects: Default::default(),
            scene_path: options.scene_path,
            watcher: None,
            job: None,
            texture: None,
            shown,
            linear,
            display: DisplayTransform::default(),
            image_view: ImageView::default(),
            image_area: (egui::Rect::ZERO, 1.0),
            blocks: false,
            compare: Compare::default(),
            handled: 0,
            banner: None,
            banner_from_render: false,
            banner_from_edit: false,
            notice: None,
            dialog: None,
            io: IoTasks::default(),
            loads: SceneLoads::default(),
            built: None,
            launch: options
                .open_at_launch
                .map(|scene| Launching { scene, load: None }),
            rebuild: None,
            render_base: None,
            accepted: None,
            ctx: None,
            pick: None,
            timings: Timings::new(options.log_timings),
            wiggle: options.wiggle.map(|d| (d, Instant::now(), 0)),
            refine_spp: options.refine_spp,
            reference: None,
            ref_task: None,
            ref_match: None,
            ref_ids: 0,
            view_mode: ViewMode::Image,
            error_exposure: 0.0,
            errors: None,
            error: None,
            error_texture: None,
            pass_tiles: (0, 0, 0),
            last_pass: None,
        }
    }

    /// Takes what the last run remembered (not the scene: the caller
    /// chose which to open).
    pub fn restore_persisted(&mut self, p: Persisted) {
        self.recent = p.recent;
        self.last_dir = p.last_dir;
        self.panel_visible = !p.panel_hidden;
        if let Some(s) = p.resolution_scale
            && ViewSettings::SCALE_RANGE.contains(&s)
        {
            self.view.resolution_scale = s;
            self.history.reset(self.snapshot());
        }
        self.view_mode = if p.error_view {
            ViewMode::Error
        } else {
            ViewMode::Image
        };
        self.error_exposure = p.error_exposure;
    }

    /// What to remember for the next run.
    pub fn persisted(&self) -> Persisted {
        Persisted {
            last_scene: self
                .scene_path
                .as_ref()
                .map(|p| std::path::absolute(p).unwrap_or_else(|_| p.clone())),
            recent: self.recent.clone(),
            last_dir: self.last_dir.clone(),
            panel_hidden: !self.panel_visible,
            resolution_scale: Some(self.view.resolution_scale),
            error_view: self.view_mode == ViewMode::Error,
            error_exposure: self.error_exposure,
        }
    }

    // ----- API for tests and scripts -------------------------------------

    /// The scene as edited (full resolution, toggles not applied).
    pub fn desc(&self) -> &SceneDesc {
        &self.desc
    }

    /// Edits the scene and restarts the render, as a control would but
    /// unchecked: tests reach states the controls refuse with it.
    pub fn edit(&mut self, f: impl FnOnce(&mut SceneDesc, &mut ViewSettings)) {
        f(&mut self.desc, &mut self.view);
        self.restart();
    }

    pub fn view_settings(&self) -> &ViewSettings {
        &self.view
    }

    /// The scene the renderer would get now (toggles and scale applied).
    pub fn render_desc(&self) -> SceneDesc {
        self.view.apply(&self.desc, false)
    }

    /// Generation of the latest render request (0 before the first frame).
    pub fn render_generation(&self) -> u64 {
        self.job.as_ref().map_or(0, RenderJob::generation)
    }

    /// The description the worker took last, with its generation.
    pub fn worker_desc(&self) -> Option<(u64, SceneDesc)> {
        self.job.as_ref().and_then(RenderJob::running_desc)
    }

    /// Tiles the render worker has delivered (renders and refinements).
    pub fn render_tiles_delivered(&self) -> u64 {
        self.job.as_ref().map_or(0, RenderJob::tiles_delivered)
    }

    /// How many renders the worker actually started.
    pub fn renders_started(&self) -> u64 {
        self.job.as_ref().map_or(0, RenderJob::renders_started)
    }

    /// Blocks until the latest render ended (tests only; the UI never
    /// waits). False on timeout.
    pub fn wait_for_render(&self, timeout: Duration) -> bool {
        self.job.as_ref().is_some_and(|j| j.wait(timeout))
    }

    /// The latest render's linear image, once it finished.
    pub fn finished_film(&self) -> Option<Film> {
        match self.job.as_ref()?.state() {
            JobState::Finished(f) => Some((*f.film).clone()),
            _ => None,
        }
    }

    pub fn render_state(&self) -> Option<JobState> {
        self.job.as_ref().map(RenderJob::state)
    }

    /// What the texture shows (sRGB bytes as uploaded).
    pub fn shown_image(&self) -> &ColorImage {
        &self.shown
    }

    pub fn banner(&self) -> Option<&str> {
        self.banner.as_deref()
    }

    pub fn notice(&self) -> Option<&str> {
        self.notice.as_deref()
    }

    pub fn pick(&self) -> Option<&PickInfo> {
        self.pick.as_ref()
    }

    /// Waits for running saves (tests only) and shows their results.
    pub fn wait_for_saves(&mut self, timeout: Duration) {
        let results = self.io.wait_all(timeout);
        self.show_results(results);
    }

    /// Test hook: the next render panics in a worker thread.
    pub fn inject_worker_panic(&self) {
        if let Some(j) = &self.job {
            j.inject_panic();
        }
    }

    pub fn reference(&self) -> Option<&Reference> {
        self.reference.as_ref()
    }

    /// How the reference relates to the image on screen.
    pub fn reference_match(&self) -> Option<Match> {
        self.ref_match
    }

    /// A reference is being computed or read.
    pub fn reference_busy(&self) -> bool {
        self.ref_task.is_some()
    }

    /// Blocks until the reference task ended (tests only); the next frame
    /// takes its result. False on timeout.
    pub fn wait_for_reference(&mut self, timeout: Duration) -> bool {
        self.ref_task.as_mut().is_none_or(|t| t.wait(timeout))
    }

    /// Blocks until the requested comparison is done (tests only); the
    /// next frame shows it. False on timeout.
    pub fn wait_for_error(&self, timeout: Duration) -> bool {
        self.errors.as_ref().is_none_or(|e| e.wait(timeout))
    }

    /// The latest readout and error image (possibly of an earlier image or
    /// reference: see its `generation` and `reference_id`).
    pub fn error_shown(&self) -> Option<&ErrorShown> {
        self.error.as_ref()
    }

    pub fn view_mode(&self) -> ViewMode {
        self.view_mode
    }

    pub fn set_view_mode(&mut self, mode: ViewMode) {
        self.view_mode = mode;
    }

    /// The current state as an undo step sees it.
    fn snapshot(&self) -> Snapshot {
        Snapshot {
            desc: self.desc.clone(),
            view: self.view.clone(),
        }
    }

    /// Whether the scene as edited waits for its build: an edit that has
    /// not taken effect yet, and may not (the build fails or is cancelled),
    /// so it is no undo step until it does.
    fn edit_pending(&self) -> bool {
        self.rebuild.is_some() && !self.history.is_baseline(&self.desc, &self.view)
    }

    /// Goes back one step; false if there is none. An edit still being
    /// built is dropped instead (it never took effect).
    pub fn undo(&mut self) -> bool {
        if self.edit_pending() {
            let before = self.history.baseline().clone();
            return self.restore(before, "undo");
        }
        let current = self.snapshot();
        match self.history.undo(&current) {
            Some(s) => self.restore(s, "undo"),
            None => false,
        }
    }

    /// Goes forward one undone step; false if there is none. An edit still
    /// being built is dropped first (it never took effect).
    pub fn redo(&mut self) -> bool {
        let current = if self.edit_pending() {
            self.history.baseline().clone()
        } else {
            self.snapshot()
        };
        match self.history.redo(&current) {
            Some(s) => self.restore(s, "redo"),
            None => false,
        }
    }

    fn restore(&mut self, s: Snapshot, what: &str) -> bool {
        self.desc = s.desc;
        self.view = s.view;
        self.pick = None;
        self.notice = Some(what.into());
        self.restart();
        true
    }

    pub fn can_undo(&self) -> bool {
        self.history.can_undo() || !self.history.is_baseline(&self.desc, &self.view)
    }

    /// The scene differs from the file (or the built-in room) as last
    /// opened, reloaded or saved.
    pub fn is_dirty(&self) -> bool {
        !self.view.applied_equals(&self.desc, true, &self.saved)
    }

    /// The window title: the scene's name, with " •" while unsaved.
    pub fn title(&self) -> String {
        let name = self
            .launch
            .as_ref()
            .map(|l| &l.scene.path)
            .or(self.scene_path.as_ref())
            .and_then(|p| p.file_name())
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "seed room".into());
        let mark = if self.is_dirty() { " •" } else { "" };
        format!("{name}{mark} — penumbra")
    }

    /// The question waiting for an answer, if any.
    pub fn confirm(&self) -> Option<&Confirm> {
        self.confirm.as_ref()
    }

    pub fn help_open(&self) -> bool {
        self.help_open
    }

    pub fn about_open(&self) -> bool {
        self.about_open
    }

    pub fn panel_visible(&self) -> bool {
        self.panel_visible
    }

    /// The scene file shown (and watched).
    pub fn scene_path(&self) -> Option<&Path> {
        self.scene_path.as_deref()
    }

    /// Runs a command as its key or menu entry would.
    pub fn execute(&mut self, ctx: &egui::Context, command: Command) {
        match command {
            Command::Open => self.open_dialog(Purpose::OpenScene),
            Command::SavePng => {
                if !self.refuse_png() {
                    self.open_dialog(Purpose::SavePng);
                }
            }
            Command::SaveScene => self.open_dialog(Purpose::SaveScene),
            Command::Quit => ctx.send_viewport_cmd(egui::ViewportCommand::Close),
            Command::Undo => {
                if !self.undo() {
                    self.notice = Some("nothing to undo".into());
                }
            }
            Command::Redo => {
                if !self.redo() {
                    self.notice = Some("nothing to redo".into());
                }
            }
            Command::FrameAll => self.frame_all(),
            Command::ResetView => self.reset_view(),
            Command::Cutaway => {
                self.desc.render.cutaway = !self.desc.render.cutaway;
                self.restart();
            }
            Command::TogglePanel => self.panel_visible = !self.panel_visible,
            Command::Fullscreen => {
                self.fullscreen = !self.fullscreen;
                ctx.send_viewport_cmd(egui::ViewportCommand::Fullscreen(self.fullscreen));
            }
            Command::Help => self.help_open = !self.help_open,
            Command::About => self.about_open = true,
            Command::ZoomFit | Command::ZoomOneToOne | Command::ZoomIn | Command::ZoomOut => {
                self.zoom_command(command)
            }
            Command::ZoomMode => self.image_view.zoom_mode = !self.image_view.zoom_mode,
            Command::PinImage => self.pin_image(ctx),
            Command::NextCompare => {
                if self.compare.pinned.is_none() {
                    self.notice = Some("nothing pinned: P pins the image as A".into());
                } else {
                    self.compare.mode = self.compare.mode.next();
                    self.compare.restart_flicker();
                }
            }
            Command::Escape => {
                // The topmost overlay only.
                if self.confirm.take().is_some() {
                    return;
                }
                if let Some(d) = self.dialog.take() {
                    self.last_dir = Some(d.dir().to_path_buf());
                    return;
                }
                if self.help_open || self.about_open {
                    self.help_open = false;
                    self.about_open = false;
                } else {
                    self.pick = None;
                }
            }
        }
    }

    /// Moves the camera back along its view direction until the scene's
    /// finite part (bounded objects and the light) fills the view.
    pub fn frame_all(&mut self) {
        // The worker's scene, or (while it builds one) a scene of our own.
        let scene = match self.job.as_ref().and_then(RenderJob::scene) {
            Some(s) => s,
            None => match crate::render::Loaded::new(&self.render_desc()) {
                Ok(l) => l.scene,
                Err(_) => return,
            },
        };
        let mut b = crate::render::geometry::Aabb::from_points(&scene.light.shape.corners());
        if let Some(o) = scene.object_bounds {
            b = b.union(o);
        }
        frame_all(&mut self.desc.camera, b.min, b.max);
        self.commit_edit();
    }

    /// Sets the orbit pivot to the surface under image pixel (px, py) of
    /// the image on screen; false if the background is there.
    pub fn set_pivot_at(&mut self, px: u32, py: u32) -> bool {
        let Some(scene) = self.job.as_ref().and_then(RenderJob::scene) else {
            return false;
        };
        let ray = scene.camera.pixel_ray(px, py);
        let Some((_, t)) = scene.camera_hit(&ray, self.desc.render.cutaway) else {
            return false;
        };
        set_pivot(&mut self.desc.camera, ray.at(t));
        self.restart();
        true
    }

    /// Asks for a quit as the window's close button does.
    pub fn request_quit(&mut self, ctx: &egui::Context) {
        if self.is_dirty() && !self.quit_confirmed {
            self.confirm = Some(Confirm::Quit);
        } else {
            self.quit_confirmed = true;
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
    }

    /// Opens a scene, asking first if the edits are unsaved.
    pub fn request_open(&mut self, ctx: &egui::Context, path: &Path) {
        if self.is_dirty() {
            self.confirm = Some(Confirm::Open(path.to_path_buf()));
        } else {
            self.open_scene(ctx, path);
        }
    }

    /// Answers the waiting question: `discard` the edits and go on, or
    /// keep them and stay.
    pub fn answer_confirm(&mut self, ctx: &egui::Context, discard: bool) {
        let Some(c) = self.confirm.take() else { return };
        if !discard {
            return;
        }
        match c {
            Confirm::Quit => {
                self.quit_confirmed = true;
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            }
            Confirm::Open(p) => self.open_scene(ctx, &p),
        }
    }

    // ----- actions -------------------------------------------------------

    /// Cancels the running render and starts one of the current settings.
    /// An edit that needs the scene built again (its objects or the set of
    /// materials changed) is built on the load thread first, under the
    /// loading strip; the render stays on the scene before until it
    /// arrives. Nothing renders while the launch's scene loads.
    pub fn restart(&mut self) {
        if self.job.is_none() || self.launch.is_some() {
            return;
        }
        let desc = self.view.apply(&self.desc, false);
        self.accepted = Some(Accepted::of(&self.desc, &self.view));
        let rebuilds = |from: &SceneDesc| classify(from, &desc) == EditClass::Rebuild;
        // A scene built for another set of objects is of no use.
        let built = self.built.take().filter(|(d, _)| !rebuilds(d));
        if built.is_none()
            && let Some(base) = &self.render_base
            && rebuilds(&base.shown)
        {
            // The build under way serves unless the objects changed again.
            if self.rebuild.as_ref().is_none_or(|r| rebuilds(&r.target)) {
                self.start_rebuild(desc);
            }
            return;
        }
        if self.rebuild.take().is_some() {
            // The edit that needed it was undone.
            self.loads.cancel();
        }
        let Some(job) = &self.job else { return };
        let size = (desc.camera.width, desc.camera.height);
        // A reference computed for another image is of no use: stop it.
        if let Some(ReferenceTask {
            kind: TaskKind::Compute(made),
            ..
        }) = &self.ref_task
            && !same_limit(made, &desc)
        {
            self.ref_task = None;
            self.notice = Some("reference cancelled: the image changed".into());
        }
        self.ref_match = self.reference.as_ref().map(|r| r.check(&desc));
        if !desc.render.cutaway && behind_a_plane(&desc) {
            self.notice = Some(BEHIND_A_WALL.into());
        } else if self.notice.as_deref() == Some(BEHIND_A_WALL) {
            // Cut-away on, or back in front: the hint no longer holds.
            self.notice = None;
        }
        self.last_pass = None;
        self.progress = Progress::new(desc.render.sampling, desc.render.area_light_model);
        let hidden_objects = (self.view.hidden.iter())
            .filter_map(|&i| self.desc.objects.get(i).cloned())
            .collect();
        let (head, view) = (head_of(&self.desc), self.view.clone());
        match &mut self.render_base {
            Some(base) => {
                copy_scene(&mut base.shown, &desc);
                (base.head, base.view, base.hidden_objects) = (head, view, hidden_objects);
            }
            None => {
                self.render_base = Some(RenderBase {
                    shown: desc.clone(),
                    head,
                    view,
                    hidden_objects,
                })
            }
        }
        let generation = job.restart_built(desc, self.view.hidden.clone(), built);
        self.timings.on_change(generation, size);
        let shown_size = [size.0 as usize, size.1 as usize];
        if self.shown.size != shown_size {
            // A new size: start from an empty picture of it.
            self.shown = ColorImage::filled(shown_size, EMPTY);
            self.linear = blank_film(size.0, size.1);
            let options = self.texture_options();
            if let Some(t) = &mut self.texture {
                t.set(self.shown.clone(), options);
            }
        }
    }

    /// Builds `shown`, the edited scene to render, on the load thread.
    fn start_rebuild(&mut self, shown: SceneDesc) {
        let Some(ctx) = self.ctx.clone() else { return };
        let name = self
            .scene_path
            .clone()
            .unwrap_or_else(|| PathBuf::from(SEED_ROOM));
        let kind = LoadKind::Rebuild {
            scene: self.desc.clone(),
            view: self.view.clone(),
        };
        let load = self.start_load(&ctx, &name, kind);
        self.rebuild = Some(Rebuild {
            load,
            target: shown,
        });
    }

    /// Starts a load, which supersedes the one under way: a launch's gives
    /// way to the seed room meanwhile, and an edit whose build it was is
    /// built again by the next render if the new load does not take it in.
    fn start_load(&mut self, ctx: &egui::Context, path: &Path, kind: LoadKind) -> u64 {
        self.rebuild = None;
        let launch = self.launch.take();
        let id = self.loads.start(ctx, path, kind);
        if launch.is_some() {
            self.restart();
        }
        id
    }

    /// Opens a scene file: read on the load thread (a newer open or reload
    /// supersedes it); on failure the banner shows why and the current
    /// scene stays.
    pub fn open_scene(&mut self, ctx: &egui::Context, path: &Path) {
        self.start_load(ctx, path, LoadKind::Open);
    }

    /// Reads the watched file again, on the load thread. The rule for
    /// unsaved edits: the file wins on every field it changed, and each
    /// edit of a field it left alone (the camera included) stays; the
    /// viewer's own toggles are not in the file and stay. The state before
    /// the reload is one undo step away. A bad file only shows the banner.
    fn reload(&mut self, ctx: &egui::Context) {
        let Some(path) = self.scene_path.clone() else {
            return;
        };
        let kind = LoadKind::Reload {
            base: self.file_desc.clone(),
            mine: self.desc.clone(),
            view: self.view.clone(),
        };
        self.start_load(ctx, &path, kind);
    }

    /// A load under way: its path, how long it has run, what it does
    /// ("loading", "reloading", "reading mesh", "building").
    pub fn loading(&self) -> Option<(&Path, Duration, &'static str)> {
        self.loads.busy()
    }

    /// Stops waiting for the load under way (the scene shown stays: for
    /// the launch's, the seed room; for an edit's build, the scene before
    /// the edit).
    pub fn cancel_load(&mut self) {
        let Some(p) = self.loads.cancel() else { return };
        self.notice = Some(format!("cancelled loading {}", p.display()));
        if self.launch.take().is_some() {
            self.restart();
        } else if self.rebuild.take().is_some() {
            self.notice = Some(format!(
                "cancelled building {}: the scene before the edit stays",
                p.display()
            ));
            self.back_to_render_base();
        } else {
            self.build_if_unbuilt();
        }
    }

    /// Back to the state the render shows (an edit whose build failed or
    /// was cancelled is dropped).
    fn back_to_render_base(&mut self) {
        if let Some(base) = &self.render_base {
            (self.desc, self.view) = base.state();
        }
        self.pick = None;
        self.restart();
    }

    /// Builds the edited scene if the render is not on it: a load that
    /// superseded its build failed or was cancelled.
    fn build_if_unbuilt(&mut self) {
        let unbuilt = self.render_base.as_ref().is_some_and(|base| {
            classify(&base.shown, &self.view.apply(&self.desc, false)) == EditClass::Rebuild
        });
        if unbuilt {
            self.restart();
        }
    }

    /// Pauses the render while a load runs, so that the load has the cores
    /// (the image shown stays), and lets it go on once the load ended: a
    /// load that failed or was cancelled leaves the scene shown, whose
    /// render and refinement go on where they stopped.
    fn pause_render_while_loading(&mut self) {
        let loading = self.loads.busy().is_some();
        if loading == self.render_paused {
            return;
        }
        let Some(job) = &self.job else { return };
        if loading {
            job.pause();
        } else {
            job.resume();
        }
        self.render_paused = loading;
    }

    /// Blocks until every load thread ended (tests only); the next frame
    /// takes the result.
    pub fn wait_for_loads(&self, timeout: Duration) -> bool {
        self.loads.wait_idle(timeout)
    }

    /// Test hook: load threads wait before reading while `on`.
    pub fn hold_loads_for_tests(&self, on: bool) {
        self.loads.hold_for_tests(on);
    }

    /// Where the camera may go, from the scene rendered (before the first
    /// scene is built: about the scene's own view).
    fn reach(&self) -> Reach {
        self.reach
            .unwrap_or_else(|| Reach::of_camera(&self.home_camera))
    }

    /// Takes the rendered scene's size, for the camera's reach and the
    /// light size sliders, before the frame draws them.
    fn update_scene_size(&mut self) {
        if let Some(scene) = self.job.as_ref().and_then(RenderJob::scene) {
            self.reach = Some(Reach::of_scene(&scene));
        }
        self.controls.scene_size = self.reach().size;
    }

    /// Takes a finished load.
    fn poll_loads(&mut self, ctx: &egui::Context) {
        let Some((id, path, result)) = self.loads.poll() else {
            return;
        };
        let launch = self.launch.take_if(|l| l.load == Some(id));
        let rebuild = self.rebuild.take_if(|r| r.load == id);
        match result {
            LoadResult::Opened(desc, built) => {
                self.built = Some(built);
                self.opened(ctx, &path, desc, launch.is_some())
            }
            LoadResult::Reloaded {
                theirs,
                merged,
                mine,
                built,
            } => {
                self.built = Some(built);
                // Edited while the file was read: merge those edits instead.
                let merged = match &self.file_desc {
                    Some(base) if self.desc != mine => merge_reload(base, &self.desc, &theirs),
                    _ => merged,
                };
                self.reloaded(&path, theirs, merged)
            }
            LoadResult::MeshRead(object, built) => {
                self.built = Some(built);
                self.desc.objects.push(object);
                self.notice = Some(format!("added {}", path.display()));
                self.restart();
            }
            LoadResult::Rebuilt(built) => {
                self.built = Some(built);
                self.restart();
            }
            LoadResult::Failed(e) => {
                if let Some(l) = launch {
                    self.launch_failed(ctx, l.scene, e);
                } else if rebuild.is_some() {
                    self.show_error(format!(
                        "the edited scene does not build, the scene before the edit stays: {e}"
                    ));
                    self.back_to_render_base();
                } else {
                    self.show_error(e);
                    self.build_if_unbuilt();
                }
            }
        }
    }

    /// The launch's scene did not open: the seed room, and for a file
    /// named on the command line the reason in the banner and the file
    /// watched, opened once it is valid (as a reload of a file never read).
    fn launch_failed(&mut self, ctx: &egui::Context, scene: LaunchScene, why: String) {
        if scene.named {
            self.scene_path = Some(scene.path);
            self.file_desc = None;
            self.watch(ctx);
            self.show_error(why);
        }
        self.restart();
    }

    /// Takes an opened scene (`at_launch`: the launch's, which keeps the
    /// resolution scale the last session left).
    fn opened(&mut self, ctx: &egui::Context, path: &Path, desc: SceneDesc, at_launch: bool) {
        let mut view = ViewSettings::for_scene(&desc);
        if at_launch {
            view.resolution_scale = self.view.resolution_scale;
        }
        let history = History::new(Snapshot {
            desc: desc.clone(),
            view: view.clone(),
        });
        let replaced = Replaced {
            view: std::mem::replace(&mut self.view, view),
            home_camera: std::mem::replace(&mut self.home_camera, desc.camera.clone()),
            file_desc: self.file_desc.replace(desc.clone()),
            saved: std::mem::replace(&mut self.saved, desc.clone()),
            history: std::mem::replace(&mut self.history, history),
            desc: std::mem::replace(&mut self.desc, desc),
            scene_path: self.scene_path.replace(path.to_path_buf()),
            recent: self.recent.clone(),
        };
        // An open that replaced a scene which never rendered keeps the
        // scene shown before both.
        if self.replaced.is_none() {
            self.replaced = Some(Box::new(replaced));
        }
        self.reach = None;
        self.remember_dir(path);
        self.add_recent(path);
        self.watch(ctx);
        self.banner = None;
        self.pick = None;
        self.notice = Some(format!("opened {}", path.display()));
        self.restart();
    }

    /// An opened scene that does not render gives way to the scene it
    /// replaced, with the reason in the banner (it stays, as for a file
    /// that does not parse).
    fn back_from_open(&mut self, ctx: &egui::Context, r: Replaced, why: &str) {
        let opened = self.scene_path.take();
        self.desc = r.desc;
        self.file_desc = r.file_desc;
        self.saved = r.saved;
        self.home_camera = r.home_camera;
        self.view = r.view;
        self.history = r.history;
        self.scene_path = r.scene_path;
        self.recent = r.recent;
        self.reach = None;
        self.pick = None;
        self.watch(ctx);
        let name = opened.map_or_else(String::new, |p| format!("{}: ", p.display()));
        self.show_error(format!(
            "{name}cannot be shown, the scene before it stays: {why}"
        ));
        self.notice = None;
        self.restart();
    }

    fn reloaded(&mut self, path: &Path, theirs: SceneDesc, merged: SceneDesc) {
        if self.scene_path.as_deref() != Some(path) {
            self.built = None;
            return;
        }
        if self.file_desc.is_none() {
            // Not read before (broken at launch): all of it.
            self.view = ViewSettings::for_scene(&theirs);
        }
        if self
            .file_desc
            .as_ref()
            .is_none_or(|b| b.camera != theirs.camera)
        {
            self.home_camera = theirs.camera.clone();
        }
        self.file_desc = Some(theirs.clone());
        self.saved = theirs;
        self.desc = merged;
        self.banner = None;
        self.notice = Some(format!(
            "reloaded {}{}",
            path.display(),
            if self.is_dirty() {
                " (your edits of other fields kept; Ctrl+Z goes back)"
            } else {
                ""
            }
        ));
        self.restart();
    }

    fn add_recent(&mut self, path: &Path) {
        let p = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
        self.recent.retain(|r| *r != p);
        self.recent.insert(0, p);
        self.recent.truncate(10);
    }

    /// Scene files opened lately, newest first.
    pub fn recent(&self) -> &[PathBuf] {
        &self.recent
    }

    fn remember_dir(&mut self, path: &Path) {
        if let Some(d) = std::path::absolute(path)
            .ok()
            .and_then(|p| p.parent().map(Path::to_path_buf))
        {
            self.last_dir = Some(d);
        }
    }

    fn watch(&mut self, ctx: &egui::Context) {
        self.watcher = None;
        if let Some(path) = &self.scene_path {
            match SceneWatcher::new(path, ctx.clone()) {
                Ok(w) => self.watcher = Some(w),
                Err(e) => self.notice = Some(e),
            }
        }
    }

    /// Writes the image at the scene's full resolution: the finished image
    /// on screen if it is that, else a fresh render on a background thread.
    pub fn save_png(&mut self, ctx: &egui::Context, mut path: PathBuf) {
        if self.refuse_png() {
            return;
        }
        if path.extension().is_none() {
            path.set_extension("png");
        }
        let full = self.view.apply(&self.desc, true);
        let film = match self.job.as_ref().map(RenderJob::state) {
            Some(JobState::Finished(f)) if f.desc == full => Some(f.film.clone()),
            _ => None,
        };
        if film.is_none()
            && let Err(why) = full_size_memory(&full, &path)
        {
            let scene = self
                .scene_path
                .as_ref()
                .map_or_else(|| "the seed room".into(), |p| p.display().to_string());
            self.show_error(format!(
                "{} not saved: {scene}: camera.width × camera.height: {why}",
                path.display()
            ));
            return;
        }
        self.io.save_png(ctx, full, film, path, self.display);
    }

    /// Refuses to save an image while the render has failed (the scene
    /// cannot be rendered, at full size either), saying so in the banner;
    /// true if refused. The message goes with the next good render.
    fn refuse_png(&mut self) -> bool {
        if self.refuse_while_launching() {
            return true;
        }
        let Some(JobState::Failed(why)) = self.job.as_ref().map(RenderJob::state) else {
            return false;
        };
        self.banner = Some(format!("nothing to save: the render failed ({why})"));
        self.banner_from_render = true;
        self.banner_from_edit = false;
        true
    }

    /// While the launch's scene loads there is nothing of it to save (the
    /// seed room behind it is not what was asked for): true if so.
    fn refuse_while_launching(&mut self) -> bool {
        let Some(l) = &self.launch else { return false };
        self.notice = Some(format!(
            "nothing to save yet: {} is loading",
            l.scene.path.display()
        ));
        true
    }

    /// Writes the settings as a scene file that renders to the same image.
    /// A scene the format refuses is not written (it would not load
    /// again): the banner says why.
    pub fn save_scene(&mut self, ctx: &egui::Context, mut path: PathBuf) {
        if self.refuse_while_launching() {
            return;
        }
        if path.extension().is_none() {
            path.set_extension("json");
        }
        let full = self.view.apply(&self.desc, true);
        if let Err(e) = full.validate() {
            self.show_error(format!(
                "{} not saved: the scene would not load again: {e}",
                path.display()
            ));
            return;
        }
        self.io.save_scene(ctx, full.clone(), path.clone());
        // Saved as: this is now the scene's file (watched; its contents
        // are these settings, so the reload it causes changes nothing).
        self.saved = full.clone();
        self.file_desc = Some(full);
        self.remember_dir(&path);
        if self.scene_path.as_deref() != Some(path.as_path()) {
            self.scene_path = Some(path);
            self.watch(ctx);
        }
    }

    // ----- image tools (display only) ------------------------------------

    pub fn display(&self) -> DisplayTransform {
        self.display
    }

    /// Shows the image through another exposure or curve: the texture is
    /// converted again from the linear values on screen, the worker's
    /// tiles go through it from now on. The render is not touched.
    pub fn set_display(&mut self, display: DisplayTransform) {
        self.display = display;
        if let Some(job) = &self.job {
            job.set_display(display);
        }
        self.shown.pixels = pixels_shown(&self.linear.pixels, &display);
        let options = self.texture_options();
        if let Some(t) = &mut self.texture {
            t.set(self.shown.clone(), options);
        }
        self.compare.redisplay(&display, options);
    }

    pub fn image_view(&self) -> &ImageView {
        &self.image_view
    }

    /// The image panel of the last frame and egui's pixels per point.
    pub fn image_area(&self) -> (egui::Rect, f32) {
        self.image_area
    }

    pub fn image_view_mut(&mut self) -> &mut ImageView {
        &mut self.image_view
    }

    pub fn compare(&self) -> &Compare {
        &self.compare
    }

    pub fn compare_mut(&mut self) -> &mut Compare {
        &mut self.compare
    }

    /// Pins the image on screen as A.
    pub fn pin_image(&mut self, ctx: &egui::Context) {
        let samples = match self.job.as_ref().map(RenderJob::state) {
            Some(JobState::Finished(f)) => f.samples,
            _ => self.desc.render.samples_per_pixel,
        };
        let options = self.texture_options();
        self.compare
            .pin(ctx, self.linear.clone(), samples, &self.display, options);
        self.notice = Some("pinned the image as A: edit, then compare (X)".into());
    }

    /// Zoom keys and buttons act about the panel's centre.
    fn zoom_command(&mut self, command: Command) {
        let (area, ppp) = self.image_area;
        let size = self.shown.size;
        let v = &mut self.image_view;
        match command {
            Command::ZoomFit => v.fit(),
            Command::ZoomOneToOne => v.set_scale_about(area, size, ppp, area.center(), 1.0),
            Command::ZoomIn | Command::ZoomOut => {
                let s = zoom_step(v.scale(area, size, ppp), command == Command::ZoomIn);
                v.set_scale_about(area, size, ppp, area.center(), s);
            }
            _ => {}
        }
    }

    /// Nearest-pixel magnification once zoomed in (pixels as blocks), else
    /// smooth.
    fn texture_options(&self) -> TextureOptions {
        if self.blocks {
            TextureOptions {
                magnification: egui::TextureFilter::Nearest,
                ..TextureOptions::LINEAR
            }
        } else {
            TextureOptions::LINEAR
        }
    }

    /// Uploads the textures again when the zoom crosses into blocks or out.
    fn update_texture_filter(&mut self, area: egui::Rect, ppp: f32) {
        let blocks = self.image_view.shows_blocks(area, self.shown.size, ppp);
        if blocks == self.blocks {
            return;
        }
        self.blocks = blocks;
        let options = self.texture_options();
        if let Some(t) = &mut self.texture {
            t.set(self.shown.clone(), options);
        }
        if let (Some(t), Some(e)) = (&mut self.error_texture, &self.error) {
            t.set(ImageData::Color(e.image.clone()), options);
        }
        self.compare.set_texture_options(options);
    }

    /// Asks for the difference against A of the finished image, and takes
    /// a finished one.
    fn poll_compare(&mut self, ctx: &egui::Context) {
        let options = self.texture_options();
        self.compare.poll(ctx, options);
        if self.compare.mode != CompareMode::Difference {
            return;
        }
        let Some(job) = &self.job else { return };
        if let JobState::Finished(f) = job.state() {
            let generation = job.generation();
            self.compare.request_difference(
                ctx,
                &f.film,
                generation,
                f.samples,
                self.error_exposure,
            );
        }
    }

    // ----- reference and error readout ----------------------------------

    /// Starts computing the converged reference of the image on screen
    /// (replacing a task under way).
    pub fn compute_reference(&mut self, ctx: &egui::Context) {
        self.ref_task = Some(ReferenceTask::compute(ctx, self.render_desc()));
    }

    /// Reads a reference from a PNG or EXR file in the background.
    pub fn load_reference(&mut self, ctx: &egui::Context, path: PathBuf) {
        self.ref_task = Some(ReferenceTask::load(ctx, path));
    }

    pub fn cancel_reference(&mut self) {
        if self.ref_task.take().is_some() {
            self.notice = Some("reference cancelled".into());
        }
    }

    pub fn clear_reference(&mut self) {
        self.reference = None;
        self.ref_match = None;
        self.error = None;
        if let Some(e) = &self.errors {
            e.cancel();
        }
    }

    /// Takes the reference task's outcome, if it ended.
    fn poll_reference(&mut self) {
        let Some(outcome) = self.ref_task.as_mut().and_then(ReferenceTask::poll) else {
            return;
        };
        let Some(task) = self.ref_task.take() else {
            return;
        };
        match outcome {
            TaskOutcome::Done(film, elapsed) => {
                let origin = match &task.kind {
                    TaskKind::Compute(desc) => Origin::Computed {
                        desc: desc.clone(),
                        elapsed,
                    },
                    TaskKind::Load(path) => Origin::Loaded(path.clone()),
                };
                self.ref_ids += 1;
                let r = Reference {
                    film: Arc::new(film),
                    origin,
                    id: self.ref_ids,
                };
                self.notice = Some(format!("reference {}", r.describe()));
                self.ref_match = Some(r.check(&self.render_desc()));
                self.reference = Some(r);
                self.refresh_error();
            }
            TaskOutcome::Cancelled => self.notice = Some("reference cancelled".into()),
            TaskOutcome::Failed(msg) => self.show_error(msg),
        }
    }

    /// Asks the compare thread for the readout of the newest image: the
    /// finished render, else the render as far as its last complete pass.
    fn refresh_error(&mut self) {
        let (Some(job), Some(errors)) = (&self.job, &self.errors) else {
            return;
        };
        let Some(r) = self
            .reference
            .as_ref()
            .filter(|_| self.ref_match == Some(Match::Same))
        else {
            errors.cancel();
            return;
        };
        let generation = job.generation();
        let (image, pass) = match job.state() {
            JobState::Finished(f) => (ImageSource::Film(f.film.clone()), None),
            _ => match self.last_pass {
                Some((g, k, n)) if g == generation => {
                    (ImageSource::Snapshot(job.film_reader()), Some((k, n)))
                }
                _ => return,
            },
        };
        errors.request(ErrorRequest {
            generation,
            pass,
            image,
            reference: r.film.clone(),
            reference_id: r.id,
            exposure: self.error_exposure,
        });
    }

    /// Shows a comparison the compare thread finished.
    fn poll_error(&mut self, ctx: &egui::Context) {
        let Some(shown) = self.errors.as_ref().and_then(ErrorJob::take) else {
            return;
        };
        let image = ImageData::Color(shown.image.clone());
        let options = self.texture_options();
        match &mut self.error_texture {
            Some(t) => t.set(image, options),
            None => self.error_texture = Some(ctx.load_texture("error", image, options)),
        }
        self.error = Some(shown);
    }

    /// The readout of a reference that matches the image on screen.
    fn current_error(&self) -> Option<&ErrorShown> {
        let r = self.reference.as_ref()?;
        self.error
            .as_ref()
            .filter(|e| e.reference_id == r.id && self.ref_match == Some(Match::Same))
    }

    /// The status bar's entry for the reference.
    fn readout(&self) -> Option<Readout> {
        let Some(r) = &self.reference else {
            let task = self.ref_task.as_ref()?;
            return Some(Readout {
                text: format!("reference {:.0}%", task.fraction() * 100.0),
                stale: true,
                hover: "computing the reference".into(),
            });
        };
        let (w, h) = (r.film.width, r.film.height);
        Some(match self.ref_match? {
            Match::SizeDiffers => Readout {
                text: "reference: size differs".into(),
                stale: false,
                hover: format!(
                    "The reference is {w}×{h}, the image {}×{}: not compared",
                    self.shown.size[0], self.shown.size[1]
                ),
            },
            Match::SettingsDiffer => Readout {
                text: "reference: settings differ".into(),
                stale: false,
                hover: "The reference was computed for another scene, camera or toggles: \
                        not compared (compute it again)"
                    .into(),
            },
            Match::Same => match self.current_error() {
                Some(e) => {
                    let mut text = readout_text(&e.comparison);
                    if let Some((k, n)) = e.pass {
                        text.push_str(&format!(" (pass {} of {n})", k + 1));
                    }
                    let c = &e.comparison;
                    Readout {
                        text,
                        stale: e.generation != self.render_generation(),
                        hover: format!(
                            "Against the reference ({}), linear RGB, peak 1.\n\
                             Largest difference {:.3e} at pixel ({}, {}).",
                            r.describe(),
                            c.max_diff,
                            c.max_at.0,
                            c.max_at.1
                        ),
                    }
                }
                None => Readout {
                    text: "RMSE …".into(),
                    stale: true,
                    hover: "Compared once a pass of the render is complete".into(),
                },
            },
        })
    }

    fn reset_view(&mut self) {
        self.desc.camera = self.home_camera.clone();
        self.restart();
    }

    /// Shows an error that stays until dismissed or fixed.
    fn show_error(&mut self, message: String) {
        self.banner = Some(message);
        self.banner_from_render = false;
        self.banner_from_edit = false;
    }

    /// Renders an edit made in the panel or on the image if the loader
    /// would take the scene (`SceneDesc::validate`: every field's range,
    /// and the limits across fields, such as a light moved so far that the
    /// room's features fall below the floor the scene's size sets). An
    /// edit it refuses is undone, back to the last state accepted, and
    /// the banner names the field edited, the field refused and the limit:
    /// never a failed render.
    fn commit_edit(&mut self) {
        // The toggles only lower values to 0 or 1, which every scene
        // takes; hidden objects change the scene's size.
        let checked = if self.view.hidden.is_empty() {
            self.desc.validate()
        } else {
            self.view
                .apply(&self.desc, true)
                .validate()
                .map_err(|e| numbered_as_edited(e, &self.view.hidden))
        };
        let (Err(e), Some(accepted)) = (checked, self.accepted.take()) else {
            if std::mem::take(&mut self.banner_from_edit) {
                self.banner = None;
            }
            self.restart();
            return;
        };
        let mut edited = changed_fields(&accepted.head, &head_of(&self.desc));
        if accepted.view.hidden != self.view.hidden {
            edited.push("the objects shown".into());
        }
        let Accepted { head, view } = accepted;
        let d = &mut self.desc;
        (d.camera, d.render, d.light, d.materials) =
            (head.camera, head.render, head.light, head.materials);
        self.view = view;
        self.accepted = Some(Accepted::of(&self.desc, &self.view));
        let what = match edited.as_slice() {
            [] => "the edit".to_string(),
            fields => fields.join(", "),
        };
        self.banner = Some(format!(
            "{what}: edit refused, the value before it stays: {e}"
        ));
        self.banner_from_render = false;
        self.banner_from_edit = true;
    }

    fn show_results(&mut self, results: Vec<Result<String, String>>) {
        for r in results {
            match r {
                Ok(msg) => self.notice = Some(msg),
                Err(e) => self.show_error(e),
            }
        }
    }

    /// Adds a mesh file to the scene, on the floor and scaled to the room,
    /// in the object list's material. The file is read on the load thread
    /// (as a scene is, with the progress strip and Cancel); one that cannot
    /// be read is a banner.
    pub fn add_mesh(&mut self, ctx: &egui::Context, path: &Path) {
        let kind = LoadKind::AddMesh {
            scene: self.desc.clone(),
            material: super::object_list::mesh_material(&self.objects, &self.desc),
            view: self.view.clone(),
        };
        self.start_load(ctx, path, kind);
    }

    /// Opens the path dialog. It starts in the folder last used in it;
    /// before that, in the scene's folder (the current one for the seed
    /// room).
    fn open_dialog(&mut self, purpose: Purpose) {
        let scene_dir = self
            .scene_path
            .as_ref()
            .and_then(|p| std::path::absolute(p).ok())
            .and_then(|p| p.parent().map(Path::to_path_buf));
        let dir = self
            .last_dir
            .clone()
            .filter(|d| d.is_dir())
            .or(scene_dir)
            .unwrap_or_else(|| std::env::current_dir().unwrap_or_else(|_| PathBuf::from(".")));
        let stem = self
            .scene_path
            .as_ref()
            .and_then(|p| p.file_stem())
            .map(|s| s.to_string_lossy().into_owned());
        let name = match purpose {
            Purpose::SavePng => format!("{}.png", stem.as_deref().unwrap_or("penumbra")),
            Purpose::SaveScene => format!("{}.json", stem.as_deref().unwrap_or("scene")),
            Purpose::OpenScene => self
                .scene_path
                .as_ref()
                .and_then(|p| p.file_name())
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            Purpose::AddMesh => String::new(),
            Purpose::OpenReference => match self.reference.as_ref().map(|r| &r.origin) {
                Some(Origin::Loaded(p)) => p
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                _ => "reference.exr".into(),
            },
        };
        let mut dialog = PathDialog::new(purpose, &dir.join(name));
        if purpose == Purpose::SavePng {
            dialog.note = Some(format!(
                "PNG: the image as shown ({}). EXR (name it .exr): the linear render, \
                 without exposure or curve.",
                self.display.describe()
            ));
        }
        if purpose == Purpose::SaveScene {
            dialog.note = self.view.save_note();
        }
        self.dialog = Some(dialog);
    }

    /// The open path dialog, if any (tests fill in its path).
    pub fn dialog_mut(&mut self) -> Option<&mut PathDialog> {
        self.dialog.as_mut()
    }

    // ----- the frame -----------------------------------------------------

    /// Draws one frame. `cpu_usage` is eframe's CPU time of the previous
    /// frame, when known (for `--log-timings`).
    pub fn show(&mut self, ui: &mut Ui, cpu_usage: Option<f32>) {
        let frame_start = Instant::now();
        self.timings.begin_frame();
        let ctx = ui.ctx().clone();
        self.start(&ctx);
        self.poll_inputs(&ctx);
        self.stream_tiles();
        self.check_render_end(&ctx);
        self.poll_reference();
        self.poll_error(&ctx);
        self.poll_compare(&ctx);
        self.poll_loads(&ctx);
        self.update_scene_size();

        let mut changed = false;
        let mut action = None;
        let mut ref_action = None;
        let mut add_mesh = false;
        let mut exposure_changed = false;
        // A modal question or a dialog has the keyboard: only Escape.
        let typing =
            ctx.egui_wants_keyboard_input() || self.confirm.is_some() || self.dialog.is_some();
        let mut commands = shortcuts::read(&ctx, typing);

        egui::Panel::top("menu").show(ui, |ui| self.menu_bar(ui, &mut commands));
        if let Some(msg) = self.banner.clone() {
            egui::Panel::top("banner")
                .frame(
                    egui::Frame::new()
                        .fill(Color32::from_rgb(120, 24, 24))
                        .inner_margin(6.0),
                )
                .show(ui, |ui| {
                    ui.horizontal_wrapped(|ui| {
                        ui.colored_label(Color32::WHITE, format!("Error: {msg}"));
                        if ui.small_button("Dismiss").clicked() {
                            self.banner = None;
                        }
                    });
                });
        }
        if self.loads.busy().is_some() {
            let mut cancel = false;
            egui::Panel::top("loading").show(ui, |ui| cancel = progress_ui(ui, &self.loads));
            if cancel {
                self.cancel_load();
            }
        }
        egui::Panel::bottom("status").show(ui, |ui| {
            let state = self
                .job
                .as_ref()
                .map_or(JobState::Running, RenderJob::state);
            let readout = self.readout();
            // Nothing renders while the launch's scene loads.
            if self.launch.is_none() {
                status_ui(ui, &self.progress, &state, self.io.busy(), readout.as_ref());
            }
            if let Some(n) = &self.notice {
                ui.add(egui::Label::new(n.as_str()).wrap());
            }
        });
        if self.panel_visible {
            egui::Panel::left("controls")
                .default_size(360.0)
                .show(ui, |ui| {
                    egui::ScrollArea::vertical().show(ui, |ui| {
                        if let Some(l) = &self.launch {
                            // Not the seed room's settings: it is not shown.
                            // (The panel keeps the width the controls take.)
                            ui.set_min_width(ui.available_width());
                            ui.label(
                                egui::RichText::new(l.scene.path.display().to_string()).strong(),
                            );
                            ui.weak("Its settings show here once it is read.");
                            return;
                        }
                        if let Some(p) = &self.scene_path {
                            ui.label(egui::RichText::new(p.display().to_string()).strong());
                        } else {
                            ui.label(egui::RichText::new("built-in seed room").strong());
                        }
                        let out =
                            controls_ui(ui, &mut self.controls, &mut self.desc, &mut self.view);
                        changed |= out.changed;
                        action = out.action;
                        let (edited, add) = super::object_list::object_list_ui(
                            ui,
                            &mut self.objects,
                            &mut self.desc,
                            &mut self.view,
                        );
                        changed |= edited;
                        add_mesh |= add.is_some();
                        let panel = RefPanel {
                            task: self.ref_task.as_ref(),
                            reference: self.reference.as_ref(),
                            matched: self.ref_match,
                            image_size: self.shown.size,
                        };
                        let out =
                            reference_ui(ui, panel, &mut self.view_mode, &mut self.error_exposure);
                        ref_action = out.action;
                        exposure_changed = out.exposure_changed;
                    });
                });
        }
        egui::Panel::top("image-tools").show(ui, |ui| {
            let (area, ppp) = self.image_area;
            let zoom = self.image_view.label(area, self.shown.size, ppp);
            let mut display = self.display;
            let zoom_mode = self.image_view.zoom_mode;
            let out = toolbar_ui(ui, &mut display, &mut self.compare, &zoom, zoom_mode);
            if out.display_changed {
                self.set_display(display);
            }
            commands.extend(out.commands);
        });
        egui::CentralPanel::no_frame()
            .frame(egui::Frame::new().fill(EMPTY))
            .show(ui, |ui| changed |= self.image_ui(ui));

        match action {
            Some(Action::OpenScene) => commands.push(Command::Open),
            Some(Action::SavePng) => commands.push(Command::SavePng),
            Some(Action::SaveScene) => commands.push(Command::SaveScene),
            Some(Action::ResetView) => commands.push(Command::ResetView),
            Some(Action::FrameAll) => commands.push(Command::FrameAll),
            None => {}
        }
        // The render restarts before a command acts on the new state.
        if changed {
            self.pick = None;
            self.commit_edit();
            changed = false;
        }
        for c in commands {
            self.execute(&ctx, c);
        }
        if add_mesh {
            self.open_dialog(Purpose::AddMesh);
        }
        match ref_action {
            Some(RefAction::Compute) => self.compute_reference(&ctx),
            Some(RefAction::Load) => self.open_dialog(Purpose::OpenReference),
            Some(RefAction::Cancel) => self.cancel_reference(),
            Some(RefAction::Clear) => self.clear_reference(),
            None => {}
        }
        if exposure_changed {
            self.refresh_error();
        }
        if let Some(d) = &mut self.dialog {
            match d.show(&ctx) {
                DialogResult::Open => {}
                DialogResult::Cancelled => {
                    // The folder browsed to is where the next dialog starts.
                    self.last_dir = Some(d.dir().to_path_buf());
                    self.dialog = None;
                }
                DialogResult::Chosen(purpose, path) => {
                    self.dialog = None;
                    self.remember_dir(&path);
                    match purpose {
                        Purpose::OpenScene => self.request_open(&ctx, &path),
                        Purpose::SavePng => self.save_png(&ctx, path),
                        Purpose::SaveScene => self.save_scene(&ctx, path),
                        Purpose::OpenReference => self.load_reference(&ctx, path),
                        Purpose::AddMesh => self.add_mesh(&ctx, &path),
                    }
                }
            }
        }
        self.overlays(&ctx);
        if changed {
            self.commit_edit();
        }
        self.pause_render_while_loading();

        // A drag, a wheel scroll or a walk (W/A/S/D held) is one undo step,
        // closed when it ends.
        let gesture = ctx.input(|i| {
            i.pointer.any_down()
                || i.smooth_scroll_delta != egui::Vec2::ZERO
                || super::camera_control::WALK_KEYS
                    .iter()
                    .any(|&(k, _, _)| i.key_down(k))
        });
        // (A copy of the scene only when it changed: it may be 10⁶ objects.)
        // An edit being built is a step once built: one that fails or is
        // cancelled goes back to the last step and leaves none.
        if !gesture && !self.edit_pending() && !self.history.is_baseline(&self.desc, &self.view) {
            let snapshot = self.snapshot();
            self.history.observe(&snapshot, false);
        }

        let title = self.title();
        if title != self.title {
            ctx.send_viewport_cmd(egui::ViewportCommand::Title(title.clone()));
            self.title = title;
        }
        if ctx.input(|i| i.viewport().close_requested()) && !self.quit_confirmed {
            if self.is_dirty() {
                ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
                self.confirm = Some(Confirm::Quit);
            } else {
                self.quit_confirmed = true;
            }
        }

        if self.timings.wants_frame() {
            ctx.request_repaint();
        }
        let rendering = self.progress.finished.is_none() && self.job.is_some();
        self.timings
            .end_frame(frame_start.elapsed(), cpu_usage, rendering);
    }

    /// The menu bar: File, Edit, View, Render, Help, each entry with its key.
    fn menu_bar(&mut self, ui: &mut Ui, commands: &mut Vec<Command>) {
        let ctx = ui.ctx().clone();
        let item = |ui: &mut Ui, text: &str, c: Command, enabled: bool, out: &mut Vec<Command>| {
            let b = egui::Button::new(text).shortcut_text(shortcuts::first_key(&ctx, c));
            if ui.add_enabled(enabled, b).clicked() {
                out.push(c);
            }
        };
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                item(ui, "Open scene…", Command::Open, true, commands);
                ui.menu_button("Open recent", |ui| {
                    if self.recent.is_empty() {
                        ui.label("(none yet)");
                    }
                    for p in self.recent.clone() {
                        if ui.button(p.display().to_string()).clicked() {
                            self.request_open(&ctx, &p);
                        }
                    }
                });
                ui.separator();
                item(ui, "Save PNG…", Command::SavePng, true, commands);
                item(ui, "Save scene…", Command::SaveScene, true, commands);
                ui.separator();
                item(ui, "Quit", Command::Quit, true, commands);
            });
            ui.menu_button("Edit", |ui| {
                let undo = self.can_undo();
                item(ui, "Undo", Command::Undo, undo, commands);
                item(ui, "Redo", Command::Redo, self.history.can_redo(), commands);
            });
            ui.menu_button("View", |ui| {
                item(ui, "Frame all", Command::FrameAll, true, commands);
                item(ui, "Reset camera", Command::ResetView, true, commands);
                ui.separator();
                item(ui, "Side panel", Command::TogglePanel, true, commands);
                item(ui, "Full screen", Command::Fullscreen, true, commands);
                ui.separator();
                ui.radio_value(&mut self.view_mode, ViewMode::Image, "Image");
                ui.radio_value(&mut self.view_mode, ViewMode::Error, "Error");
                ui.separator();
                item(ui, "Zoom image to fit", Command::ZoomFit, true, commands);
                item(ui, "Image 1:1", Command::ZoomOneToOne, true, commands);
                item(ui, "Zoom image in", Command::ZoomIn, true, commands);
                item(ui, "Zoom image out", Command::ZoomOut, true, commands);
                let mark = if self.image_view.zoom_mode {
                    "✔ "
                } else {
                    ""
                };
                let text = format!("{mark}Image zoom mode");
                item(ui, &text, Command::ZoomMode, true, commands);
                ui.separator();
                item(ui, "Pin image as A", Command::PinImage, true, commands);
                let pinned = self.compare.pinned.is_some();
                item(
                    ui,
                    "Compare with A: next",
                    Command::NextCompare,
                    pinned,
                    commands,
                );
            });
            ui.menu_button("Render", |ui| {
                let mark = if self.desc.render.cutaway { "✔ " } else { "" };
                item(
                    ui,
                    &format!("{mark}Cut-away"),
                    Command::Cutaway,
                    true,
                    commands,
                );
            });
            ui.menu_button("Help", |ui| {
                item(ui, "Keyboard and mouse", Command::Help, true, commands);
                item(ui, "About penumbra", Command::About, true, commands);
            });
        });
    }

    /// The help, the About box and the unsaved-edits question.
    fn overlays(&mut self, ctx: &egui::Context) {
        if self.help_open {
            let mut open = true;
            egui::Window::new("Keyboard and mouse")
                .open(&mut open)
                .collapsible(false)
                .resizable(false)
                .anchor(egui::Align2::CENTER_CENTER, egui::Vec2::ZERO)
                .show(ctx, help_ui);
            self.help_open &= open;
        }
        if self.about_open {
            let mut open = true;
            egui::Window::new("About penumbra")
                .open(&mut open)
                .collapsible(false)
                .resizable(false)
                .anchor(egui::Align2::CENTER_CENTER, egui::Vec2::ZERO)
                .show(ctx, |ui| {
                    for line in about_lines() {
                        ui.label(line);
                    }
                });
            self.about_open &= open;
        }
        let Some(c) = self.confirm.clone() else {
            return;
        };
        let (question, go) = match &c {
            Confirm::Quit => ("Quit and lose the unsaved edits?".to_string(), "Quit"),
            Confirm::Open(p) => (
                format!("Open {} and lose the unsaved edits?", p.display()),
                "Open",
            ),
        };
        let mut answer = None;
        egui::Modal::new(egui::Id::unique("penumbra-confirm")).show(ctx, |ui| {
            ui.heading("Unsaved changes");
            ui.label(question);
            ui.label("(Save scene… keeps them in a file.)");
            ui.horizontal(|ui| {
                if ui.button(go).clicked() {
                    answer = Some(true);
                }
                if ui.button("Cancel").clicked() {
                    answer = Some(false);
                }
            });
        });
        if let Some(discard) = answer {
            self.answer_confirm(ctx, discard);
        }
    }

    /// First frame: the worker, the texture, the watcher, the first render
    /// (or the launch's load).
    fn start(&mut self, ctx: &egui::Context) {
        if self.job.is_some() {
            return;
        }
        self.ctx = Some(ctx.clone());
        self.job = Some(RenderJob::with_refinement(ctx.clone(), self.refine_spp));
        self.errors = Some(ErrorJob::new(ctx.clone()));
        self.texture = Some(ctx.load_texture("render", self.shown.clone(), self.texture_options()));
        self.watch(ctx);
        if let Some(l) = &mut self.launch {
            l.load = Some(self.loads.start(ctx, &l.scene.path, LoadKind::Open));
        }
        self.restart();
    }

    /// Dropped files, the watched file, finished saves, the wiggle.
    fn poll_inputs(&mut self, ctx: &egui::Context) {
        let dropped: Vec<PathBuf> = ctx.input(|i| {
            i.raw
                .dropped_files
                .iter()
                .map(|f| f.path().to_path_buf())
                .collect()
        });
        if let Some(path) = dropped.first() {
            let ext = path.extension().map(|e| e.to_ascii_lowercase());
            if ext.as_ref().is_some_and(|e| e == "png" || e == "exr") {
                // An image dropped on the window is a reference.
                self.load_reference(ctx, path.clone());
            } else if super::object_list::is_mesh_file(path) {
                self.add_mesh(ctx, path);
            } else {
                self.request_open(ctx, path);
            }
        }
        if let Some(w) = &self.watcher {
            match w.poll() {
                Ok(true) => self.reload(ctx),
                Ok(false) => {}
                Err(wait) => ctx.request_repaint_after(wait),
            }
        }
        let results = self.io.poll();
        self.show_results(results);
        if let Some((every, last, count)) = &mut self.wiggle {
            if last.elapsed() >= *every && *count < 6 {
                *last = Instant::now();
                *count += 1;
                // Alternate the ambient strength: a real slider change.
                let t = &mut self.desc.render.terms.ambient;
                *t = if *count % 2 == 1 { *t * 0.9 } else { *t / 0.9 };
                self.restart();
            }
            if let Some((every, last, count)) = self.wiggle
                && count < 6
            {
                ctx.request_repaint_after(every.saturating_sub(last.elapsed()));
            }
        }
    }

    /// Copies the finished tiles into the texture, rectangle by rectangle.
    fn stream_tiles(&mut self) {
        let Some(job) = &self.job else { return };
        let tiles = job.take_tiles();
        let options = self.texture_options();
        let Some(texture) = &mut self.texture else {
            return;
        };
        let mut pass_done = false;
        // Many tiles at once (a recombined image arrives whole within a
        // frame): one upload of the whole picture instead of one per tile.
        let area: usize = tiles.iter().map(|t| t.pixels.len()).sum();
        let whole = area * 4 > self.shown.pixels.len();
        for t in tiles {
            // Passes run one after the other: the last tile of one is on
            // screen when as many tiles as it has arrived. (The final pass
            // is compared when the render is reported finished.)
            let key = (t.generation, t.pass_index);
            if (self.pass_tiles.0, self.pass_tiles.1) != key {
                self.pass_tiles = (key.0, key.1, 0);
            }
            self.pass_tiles.2 += 1;
            if self.pass_tiles.2 == t.tiles_total && t.pass_index + 1 < t.pass_count {
                self.last_pass = Some((t.generation, t.pass_index, t.pass_count));
                pass_done = true;
            }
            let (x, y, w, h) = (
                t.rect.x as usize,
                t.rect.y as usize,
                t.rect.w as usize,
                t.rect.h as usize,
            );
            if x + w > self.shown.size[0] || y + h > self.shown.size[1] {
                continue;
            }
            self.linear
                .write_block(t.rect.x, t.rect.y, t.rect.w, &t.linear);
            let mut t = t;
            if t.display != self.display {
                // Converted before the exposure or curve changed.
                t.pixels = pixels_shown(&t.linear, &self.display);
            }
            for row in 0..h {
                let dst = (y + row) * self.shown.size[0] + x;
                self.shown.pixels[dst..dst + w].copy_from_slice(&t.pixels[row * w..(row + 1) * w]);
            }
            self.progress.on_tile(&t);
            self.timings.on_upload(t.generation);
            if !whole {
                let image = ColorImage::new([w, h], t.pixels);
                texture.set_partial([x, y], image, options);
            }
        }
        if whole {
            texture.set(self.shown.clone(), options);
        }
        if pass_done {
            self.refresh_error();
        }
    }

    /// The latest render's end: its figures, or its error in the banner
    /// (or, for the first render of a scene just opened, the scene before).
    fn check_render_end(&mut self, ctx: &egui::Context) {
        let Some(job) = &self.job else { return };
        let generation = job.generation();
        if self.handled == generation {
            return;
        }
        match job.state() {
            JobState::Finished(f) => {
                // The opened scene renders: it stays.
                self.replaced = None;
                self.progress.finished = Some((f.elapsed, f.traced_rays));
                self.progress.tiles_done = self.progress.tiles_total;
                self.handled = generation;
                if std::mem::take(&mut self.banner_from_render) {
                    self.banner = None;
                }
                self.refresh_error();
            }
            JobState::Failed(msg) => {
                self.progress.finished = Some((self.progress.started.elapsed(), 0));
                self.handled = generation;
                if let Some(r) = self.replaced.take() {
                    self.back_from_open(ctx, *r, &msg);
                    return;
                }
                self.banner = Some(msg);
                self.banner_from_render = true;
                self.banner_from_edit = false;
            }
            JobState::Running | JobState::Cancelled => {}
        }
    }

    /// The image (fitted, or zoomed and panned: see [`ImageView`]), with
    /// mouse camera control, the comparison with A and the inspector; true
    /// if the camera moved.
    fn image_ui(&mut self, ui: &mut Ui) -> bool {
        let area = ui.available_rect_before_wrap();
        let response = ui.allocate_rect(area, Sense::click_and_drag());
        let ppp = ui.ctx().pixels_per_point();
        let size = self.shown.size;
        self.image_area = (area, ppp);
        // Ctrl+wheel (egui's zoom gesture), or the wheel in zoom mode, zooms
        // the image about the cursor; Ctrl+drag, or a drag in zoom mode,
        // pans it. Everything else is the camera's, as before.
        let (zoom_delta, scroll, ctrl) =
            ui.input(|i| (i.zoom_delta(), i.smooth_scroll_delta.y, i.modifiers.command));
        if let Some(pos) = response.hover_pos() {
            let mut factor = zoom_delta;
            if self.image_view.zoom_mode && scroll != 0.0 {
                factor *= (scroll * 0.005).exp();
            }
            if factor != 1.0 {
                self.image_view.zoom_about(area, size, ppp, pos, factor);
            }
        }
        let image_drag = self.image_view.zoom_mode || ctrl;
        if image_drag && response.drag_delta() != egui::Vec2::ZERO {
            self.image_view.pan(area, size, ppp, response.drag_delta());
        }
        self.update_texture_filter(area, ppp);
        let rect = self.image_view.image_rect(area, size, ppp);
        let painter = ui.painter_at(area);
        let error = self
            .current_error()
            .filter(|e| self.view_mode == ViewMode::Error && e.image.size == self.shown.size);
        let texture = match error {
            Some(_) => self.error_texture.as_ref(),
            None => self.texture.as_ref(),
        };
        if let Some(t) = texture {
            painter.image(t.id(), rect, FULL_UV, Color32::WHITE);
        }
        let shown_rect = rect.intersect(area);
        if let Some(wait) = self.compare.paint(ui, &painter, rect, shown_rect, size) {
            ui.ctx().request_repaint_after(wait);
        }
        if self.image_view.scale(area, size, ppp) >= GRID_ZOOM {
            paint_grid(&painter, rect, [size[0], size[1]], area);
        }
        if self.view_mode == ViewMode::Error {
            let scale = error.map(|e| e.scale);
            let why = match (&self.reference, self.ref_match) {
                _ if scale.is_some() => "",
                (None, _) => "Error view: no reference (compute or load one)",
                (_, Some(Match::SizeDiffers)) => "Error view: the reference's size differs",
                (_, Some(Match::SettingsDiffer)) => {
                    "Error view: the reference was made for other settings"
                }
                _ => "Error view: comparing…",
            };
            egui::Area::new(egui::Id::unique("penumbra-error-legend"))
                .pivot(egui::Align2::LEFT_BOTTOM)
                .fixed_pos(shown_rect.left_bottom() + egui::vec2(8.0, -8.0))
                .show(ui.ctx(), |ui| {
                    egui::Frame::popup(ui.style()).show(ui, |ui| match scale {
                        Some(s) => legend_ui(ui, s),
                        None => {
                            ui.label(why);
                        }
                    });
                });
        }
        let reach = self.reach();
        let moved = !image_drag
            && camera_input(ui, &response, &mut self.desc.camera, rect.height(), &reach);
        if response.double_clicked()
            && let Some(pos) = response.interact_pointer_pos().or(response.hover_pos())
            && let Some([px, py]) = self.image_view.pixel_at(area, size, ppp, pos)
        {
            self.pick = self.pick_at(px, py);
            self.pick_pos = Some(pos);
            // The surface there becomes the pivot the camera orbits about.
            self.set_pivot_at(px, py);
        }
        if let Some(p) = &self.pick {
            let text = inspector_text(p);
            // At the cursor, kept inside the image area.
            let at = self.pick_pos.unwrap_or(rect.left_top()) + egui::vec2(12.0, 12.0);
            let at = egui::pos2(
                at.x.min(area.right() - 300.0).max(area.left()),
                at.y.min(area.bottom() - 130.0).max(area.top()),
            );
            egui::Area::new(egui::Id::unique("penumbra-pick"))
                .fixed_pos(at)
                .show(ui.ctx(), |ui| {
                    egui::Frame::popup(ui.style()).show(ui, |ui| {
                        ui.label(text);
                        if ui.small_button("close").clicked() {
                            self.pick = None;
                        }
                    });
                });
        }
        moved
    }

    /// What the rendered scene shows at a pixel of the image.
    fn pick_at(&self, px: u32, py: u32) -> Option<PickInfo> {
        let job = self.job.as_ref()?;
        let scene = job.scene()?;
        let hit = scene.camera_hit(&scene.camera.pixel_ray(px, py), self.desc.render.cutaway);
        let (what, material) = match hit {
            Some((HitTarget::Object(i), _)) => (
                format!(
                    "objects[{i}] ({})",
                    self.desc.objects.get(i as usize).map_or("?", |o| o.kind())
                ),
                Some(scene.material_name(i).to_string()),
            ),
            Some((HitTarget::Light, _)) => ("the light".to_string(), None),
            None => ("background".to_string(), None),
        };
        let linear = job.pixel(px, py);
        let pinned = self
            .compare
            .pinned
            .as_ref()
            .filter(|a| a.film.width > px && a.film.height > py)
            .map(|a| {
                let c = a.film.get(px, py);
                (c.to_array(), self.display.encode(c))
            });
        Some(PickInfo {
            pixel: (px, py),
            what,
            material,
            linear_rgb: linear.map(|c| c.to_array()),
            shown_srgb: linear.map(|c| self.display.encode(c)),
            pinned,
        })
    }
}

impl eframe::App for Viewer {
    fn ui(&mut self, ui: &mut Ui, frame: &mut eframe::Frame) {
        self.show(ui, frame.info().cpu_usage);
    }

    fn save(&mut self, storage: &mut dyn eframe::Storage) {
        if self.persist {
            eframe::set_value(storage, Persisted::KEY, &self.persisted());
        }
    }

    fn persist_egui_memory(&self) -> bool {
        self.persist
    }
}

/// Whether a fresh render of `full` and its encoding for `path` fit in
/// memory (the export renders at the scene's own size, which the preview
/// may not be).
fn full_size_memory(full: &SceneDesc, path: &Path) -> Result<(), String> {
    use crate::render::output::FileKind;
    // The film's 12 bytes a pixel and the encoder's (a PNG's 3, an EXR's 12).
    let per_pixel = if FileKind::of(path).ok() == Some(FileKind::Exr) {
        24
    } else {
        15
    };
    crate::render::memory::check_image_memory(full.camera.width, full.camera.height, per_pixel)
}

/// A black image for the viewer's copy of the linear values. Plain pages:
/// `Film::new` asks for large ones, whose first touch can wait for the
/// kernel to compact memory (0.1–0.25 s for 2880² on a loaded machine),
/// which the UI thread must not.
fn blank_film(width: u32, height: u32) -> Film {
    Film {
        width,
        height,
        pixels: vec![glam::Vec3::ZERO; width as usize * height as usize],
    }
}

/// Linear pixels as the texture shows them.
fn pixels_shown(linear: &[glam::Vec3], display: &DisplayTransform) -> Vec<Color32> {
    let mut pixels = Vec::with_capacity(linear.len());
    display.encode_each(linear, |[r, g, b]| pixels.push(Color32::from_rgb(r, g, b)));
    pixels
}

/// A hot reload's three-way merge, field by field of the JSON tree: where
/// the file changed a value (`theirs` differs from `base`, the file as read
/// before) the file's value is taken, else the edited one (`mine`). Lists
/// (the objects) count as one value. If the merged scene is invalid, the
/// file's is taken whole.
pub fn merge_reload(base: &SceneDesc, mine: &SceneDesc, theirs: &SceneDesc) -> SceneDesc {
    use serde_json::Value;
    fn merge(base: Option<&Value>, mine: Option<&Value>, theirs: Option<&Value>) -> Option<Value> {
        if let (Some(Value::Object(b)), Some(Value::Object(m)), Some(Value::Object(t))) =
            (base, mine, theirs)
        {
            let mut keys: Vec<&String> = b.keys().chain(m.keys()).chain(t.keys()).collect();
            keys.sort();
            keys.dedup();
            let out = keys
                .into_iter()
                .filter_map(|k| Some((k.clone(), merge(b.get(k), m.get(k), t.get(k))?)))
                .collect();
            return Some(Value::Object(out));
        }
        if theirs != base {
            theirs.cloned()
        } else {
            mine.cloned()
        }
    }
    let value = |d: &SceneDesc| serde_json::to_value(d).expect("scene descriptions serialize");
    let merged = merge(Some(&value(base)), Some(&value(mine)), Some(&value(theirs)));
    merged
        .and_then(|m| SceneDesc::from_json(&m.to_string()).ok())
        .unwrap_or_else(|| theirs.clone())
}

/// The About box: version, build and the CPU features in use.
pub fn about_lines() -> Vec<String> {
    let mut features = Vec::new();
    #[cfg(target_arch = "x86_64")]
    for (name, on) in [
        ("sse2", cfg!(target_feature = "sse2")),
        ("sse4.1", cfg!(target_feature = "sse4.1")),
        ("avx", cfg!(target_feature = "avx")),
        ("avx2", cfg!(target_feature = "avx2")),
        ("fma", cfg!(target_feature = "fma")),
    ] {
        if on {
            features.push(name);
        }
    }
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    vec![
        format!("penumbra {}", env!("CARGO_PKG_VERSION")),
        env!("CARGO_PKG_DESCRIPTION").to_string(),
        format!(
            "build: {} ({}, {})",
            if cfg!(debug_assertions) {
                "debug"
            } else {
                "release"
            },
            std::env::consts::ARCH,
            std::env::consts::OS
        ),
        format!(
            "CPU features compiled in: {}",
            if features.is_empty() {
                "baseline".to_string()
            } else {
                features.join(", ")
            }
        ),
        format!("render threads: {threads}"),
        format!("license: {}", env!("CARGO_PKG_LICENSE")),
    ]
}

/// Whether the camera stands behind one of the scene's planes (on the side
/// its normal points away from), where the plane hides everything else.
pub fn behind_a_plane(desc: &SceneDesc) -> bool {
    use crate::render::scene_file::ObjectDesc;
    let cam = glam::DVec3::from(desc.camera.position);
    desc.objects.iter().any(|o| match o {
        ObjectDesc::Plane(p) => {
            let n = glam::DVec3::from(p.normal);
            n.dot(cam - glam::DVec3::from(p.point)) < 0.0
        }
        _ => false,
    })
}
