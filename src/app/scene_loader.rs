//! Scene and mesh files in, off the UI thread: opening a scene, the hot
//! reload (with its merge of the edits) and reading a mesh to add run on a
//! thread of their own, so that a big scene (10⁶ objects parse for
//! seconds), a big mesh, or a file that is not one (a FIFO, a device:
//! refused by the core's loader before a byte is read) never stops the
//! window. The thread also builds the scene to be shown (reading its mesh
//! files: seconds for 10⁶ triangles) and hands it to the render: a scene
//! that does not build is refused like one that does not parse, before it
//! replaces anything, and the loading strip stays up while it builds.
//! An edit that needs the scene built again (its objects or the set of
//! materials changed) is built here too, so the render never reads meshes
//! itself, with the strip and Cancel as for an open.
//!
//! One load counts: a newer request supersedes the one under way (its
//! result is dropped when it arrives), and a load can be cancelled. A
//! parse cannot be stopped half-way; a superseded or cancelled thread runs
//! to its end and its result goes nowhere.

use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use super::object_list::mesh_object;
use super::settings::{ViewSettings, numbered_as_edited};
use super::viewer::merge_reload;
use crate::render::scene_file::ObjectDesc;
use crate::render::{Loaded, SceneDesc};

/// A scene built for the description it comes with (the one the viewer
/// renders: toggles applied, at the preview's size).
pub type Built = (SceneDesc, Loaded);

/// Bytes a pixel of the preview takes in the viewer: the render's film and
/// the viewer's linear copy (12 each), the texture's bytes and their copy
/// on the CPU (4 each), and as much again for tiles and refinement.
const VIEWER_BYTES_PER_PIXEL: usize = 64;

/// What the file is read for.
#[derive(Debug, Clone)]
#[allow(clippy::large_enum_variant)] // one per load, moved once
pub enum LoadKind {
    /// Opened: it replaces the scene shown.
    Open,
    /// The watched file changed: merged with the edits (see
    /// [`merge_reload`]); `base` is the file as read before, `None` if it
    /// never was (broken at launch).
    Reload {
        base: Option<SceneDesc>,
        mine: SceneDesc,
        /// The viewer's toggles the merged scene will be shown with.
        view: ViewSettings,
    },
    /// A mesh file to add to `scene` (it is placed in that scene's room),
    /// in `material`, shown with `view`.
    AddMesh {
        scene: SceneDesc,
        material: String,
        view: ViewSettings,
    },
    /// An edit of `scene` that needs it built again, shown with `view`;
    /// the path only names the scene (nothing is read from it).
    Rebuild {
        scene: SceneDesc,
        view: ViewSettings,
    },
}

impl LoadKind {
    /// What the progress strip says the thread is doing.
    fn verb(&self) -> &'static str {
        match self {
            LoadKind::Open => "loading",
            LoadKind::Reload { .. } => "reloading",
            LoadKind::AddMesh { .. } => "reading mesh",
            LoadKind::Rebuild { .. } => "building",
        }
    }
}

/// How a load ended.
#[derive(Debug, Clone)]
#[allow(clippy::large_enum_variant)] // one per load, moved once
pub enum LoadResult {
    Opened(SceneDesc, Built),
    Reloaded {
        /// The file as read now.
        theirs: SceneDesc,
        /// With the edits of the fields it left alone.
        merged: SceneDesc,
        /// The edits it was merged with (the UI merges again if the scene
        /// was edited meanwhile).
        mine: SceneDesc,
        built: Built,
    },
    /// The mesh read, as the object to add.
    MeshRead(ObjectDesc, Built),
    /// The edited scene, built.
    Rebuilt(Built),
    /// The message for the banner (names the file).
    Failed(String),
}

/// A load under way.
struct Running {
    id: u64,
    path: PathBuf,
    verb: &'static str,
    started: Instant,
    cancelled: Arc<AtomicBool>,
}

pub struct SceneLoads {
    tx: Sender<(u64, LoadResult)>,
    rx: Receiver<(u64, LoadResult)>,
    ids: u64,
    running: Option<Running>,
    /// Load threads not yet ended (superseded ones included).
    threads: Arc<AtomicUsize>,
    /// Test hook: while set, load threads wait before reading.
    hold: Arc<(Mutex<bool>, Condvar)>,
}

impl Default for SceneLoads {
    fn default() -> Self {
        let (tx, rx) = channel();
        SceneLoads {
            tx,
            rx,
            ids: 0,
            running: None,
            threads: Arc::new(AtomicUsize::new(0)),
            hold: Arc::new((Mutex::new(false), Condvar::new())),
        }
    }
}

impl SceneLoads {
    /// Starts reading `path`; a load under way is superseded. Returns the
    /// load's id (see [`poll`](Self::poll)).
    pub fn start(&mut self, ctx: &egui::Context, path: &Path, kind: LoadKind) -> u64 {
        if let Some(old) = self.running.take() {
            old.cancelled.store(true, Ordering::Relaxed);
        }
        self.ids += 1;
        let id = self.ids;
        let cancelled = Arc::new(AtomicBool::new(false));
        self.running = Some(Running {
            id,
            path: path.to_path_buf(),
            verb: kind.verb(),
            started: Instant::now(),
            cancelled: cancelled.clone(),
        });
        let (tx, ctx, file) = (self.tx.clone(), ctx.clone(), path.to_path_buf());
        let (threads, hold) = (self.threads.clone(), self.hold.clone());
        threads.fetch_add(1, Ordering::SeqCst);
        let spawned = std::thread::Builder::new()
            .name("penumbra-load".into())
            .spawn(move || {
                {
                    let (held, wake) = &*hold;
                    let mut h = held.lock().unwrap_or_else(|e| e.into_inner());
                    while *h {
                        h = wake.wait(h).unwrap_or_else(|e| e.into_inner());
                    }
                }
                let result =
                    std::panic::catch_unwind(AssertUnwindSafe(|| load(&file, kind, &cancelled)))
                        .unwrap_or_else(|_| {
                            Some(LoadResult::Failed(format!(
                                "{}: the loader panicked",
                                file.display()
                            )))
                        });
                if let Some(r) = result {
                    let _ = tx.send((id, r));
                }
                threads.fetch_sub(1, Ordering::SeqCst);
                ctx.request_repaint();
            });
        if spawned.is_err() {
            self.threads.fetch_sub(1, Ordering::SeqCst);
            self.running = None;
            let _ = self.tx.send((
                id,
                LoadResult::Failed(format!("{}: cannot start a loader thread", path.display())),
            ));
        }
        id
    }

    /// Stops waiting for the load under way; the path it was reading.
    pub fn cancel(&mut self) -> Option<PathBuf> {
        let r = self.running.take()?;
        r.cancelled.store(true, Ordering::Relaxed);
        Some(r.path)
    }

    /// The result of the latest load, once it arrived (older ones are
    /// dropped), with its id and the path it read.
    pub fn poll(&mut self) -> Option<(u64, PathBuf, LoadResult)> {
        let mut out = None;
        for (id, result) in self.rx.try_iter() {
            if self.running.as_ref().is_some_and(|r| r.id == id) {
                let r = self.running.take().expect("checked");
                out = Some((id, r.path, result));
            }
        }
        out
    }

    /// The load under way: its path, how long it has run, and what it does
    /// ("loading", "reloading", "reading mesh", "building").
    pub fn busy(&self) -> Option<(&Path, Duration, &'static str)> {
        self.running
            .as_ref()
            .map(|r| (r.path.as_path(), r.started.elapsed(), r.verb))
    }

    /// Blocks until every load thread ended (tests only); false on timeout.
    pub fn wait_idle(&self, timeout: Duration) -> bool {
        let deadline = Instant::now() + timeout;
        while self.threads.load(Ordering::SeqCst) > 0 {
            if Instant::now() >= deadline {
                return false;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        true
    }

    /// Test hook: while `on`, load threads wait before reading (to see the
    /// viewer with a load under way, whatever the machine's speed).
    pub fn hold_for_tests(&self, on: bool) {
        let (held, wake) = &*self.hold;
        *held.lock().unwrap_or_else(|e| e.into_inner()) = on;
        wake.notify_all();
    }
}

/// Reads (and for a reload merges) on the load thread, and builds the
/// scene to show; `None` once cancelled.
fn load(path: &Path, kind: LoadKind, cancelled: &AtomicBool) -> Option<LoadResult> {
    let is_cancelled = || cancelled.load(Ordering::Relaxed);
    let result = match kind {
        LoadKind::AddMesh {
            scene,
            material,
            view,
        } => {
            let object = match mesh_object(&scene, path, &material) {
                Ok(o) => o,
                Err(e) => return (!is_cancelled()).then_some(LoadResult::Failed(e)),
            };
            let mut with = scene;
            with.objects.push(object.clone());
            build(path, &with, &view, &is_cancelled).map(|b| LoadResult::MeshRead(object, b))
        }
        LoadKind::Open => {
            let theirs = match SceneDesc::load(path) {
                Ok(d) => d,
                Err(e) => return Some(LoadResult::Failed(e.to_string())),
            };
            let view = ViewSettings::for_scene(&theirs);
            build(path, &theirs, &view, &is_cancelled).map(|b| LoadResult::Opened(theirs, b))
        }
        LoadKind::Rebuild { scene, view } => {
            build(path, &scene, &view, &is_cancelled).map(LoadResult::Rebuilt)
        }
        LoadKind::Reload { base, mine, view } => {
            let theirs = match SceneDesc::load(path) {
                Ok(d) => d,
                Err(e) => return Some(LoadResult::Failed(e.to_string())),
            };
            let (merged, view) = match &base {
                Some(base) => (merge_reload(base, &mine, &theirs), view),
                // Not read before (broken at launch): all of it.
                None => (theirs.clone(), ViewSettings::for_scene(&theirs)),
            };
            build(path, &merged, &view, &is_cancelled).map(|built| LoadResult::Reloaded {
                theirs,
                merged,
                mine,
                built,
            })
        }
    };
    if is_cancelled() {
        return None;
    }
    Some(result.unwrap_or_else(LoadResult::Failed))
}

/// Builds `desc` as the viewer will show it (through `view`), once its
/// preview's buffers are known to fit in memory; errors name the file.
fn build(
    path: &Path,
    desc: &SceneDesc,
    view: &ViewSettings,
    is_cancelled: &dyn Fn() -> bool,
) -> Result<Built, String> {
    let shown = view.apply(desc, false);
    let (w, h) = (shown.camera.width, shown.camera.height);
    crate::render::memory::check_image_memory(w, h, VIEWER_BYTES_PER_PIXEL).map_err(|why| {
        format!(
            "{}: camera.width × camera.height ({}×{}, previewed at {w}×{h}): {why}",
            path.display(),
            desc.camera.width,
            desc.camera.height
        )
    })?;
    if is_cancelled() {
        return Err(String::new());
    }
    let loaded = Loaded::new(&shown).map_err(|e| {
        // A mesh's error names its own file; say which scene it is in.
        let e = numbered_as_edited(e, &view.hidden).to_string();
        match path.to_str() {
            Some(p) if e.contains(p) => e,
            _ => format!("{}: {e}", path.display()),
        }
    })?;
    Ok((shown, loaded))
}

/// The strip shown while a load runs: what, how long, and Cancel; true if
/// Cancel was clicked.
pub fn progress_ui(ui: &mut egui::Ui, loads: &SceneLoads) -> bool {
    let Some((path, elapsed, verb)) = loads.busy() else {
        return false;
    };
    let mut cancel = false;
    ui.horizontal(|ui| {
        ui.spinner();
        ui.label(format!(
            "{verb} {}… {:.1} s",
            path.display(),
            elapsed.as_secs_f64()
        ));
        cancel = ui.button("Cancel").clicked();
    });
    cancel
}
