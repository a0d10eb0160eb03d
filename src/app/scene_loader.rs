//! Scene and mesh files in, off the UI thread: opening a scene, the hot
//! reload (with its merge of the edits) and reading a mesh to add run on a
//! thread of their own, so that a big scene (10⁶ objects parse for
//! seconds), a big mesh, or a file that is not one (a FIFO, a device:
//! refused by the core's loader before a byte is read) never stops the
//! window.
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
use super::viewer::merge_reload;
use crate::render::SceneDesc;
use crate::render::scene_file::ObjectDesc;

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
    },
    /// A mesh file to add to `scene` (it is placed in that scene's room),
    /// in `material`.
    AddMesh { scene: SceneDesc, material: String },
}

impl LoadKind {
    /// What the progress strip says the thread is doing.
    fn verb(&self) -> &'static str {
        match self {
            LoadKind::Open => "loading",
            LoadKind::Reload { .. } => "reloading",
            LoadKind::AddMesh { .. } => "reading mesh",
        }
    }
}

/// How a load ended.
#[derive(Debug, Clone)]
#[allow(clippy::large_enum_variant)] // one per load, moved once
pub enum LoadResult {
    Opened(SceneDesc),
    Reloaded {
        /// The file as read now.
        theirs: SceneDesc,
        /// With the edits of the fields it left alone.
        merged: SceneDesc,
        /// The edits it was merged with (the UI merges again if the scene
        /// was edited meanwhile).
        mine: SceneDesc,
    },
    /// The mesh read, as the object to add.
    MeshRead(ObjectDesc),
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
    /// Starts reading `path`; a load under way is superseded.
    pub fn start(&mut self, ctx: &egui::Context, path: &Path, kind: LoadKind) {
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
    }

    /// Stops waiting for the load under way; the path it was reading.
    pub fn cancel(&mut self) -> Option<PathBuf> {
        let r = self.running.take()?;
        r.cancelled.store(true, Ordering::Relaxed);
        Some(r.path)
    }

    /// The result of the latest load, once it arrived (older ones are
    /// dropped), with the path it read.
    pub fn poll(&mut self) -> Option<(PathBuf, LoadResult)> {
        let mut out = None;
        for (id, result) in self.rx.try_iter() {
            if self.running.as_ref().is_some_and(|r| r.id == id) {
                let r = self.running.take().expect("checked");
                out = Some((r.path, result));
            }
        }
        out
    }

    /// The load under way: its path, how long it has run, and what it does
    /// ("loading", "reloading", "reading mesh").
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

/// Reads (and for a reload merges) on the load thread; `None` once
/// cancelled.
fn load(path: &Path, kind: LoadKind, cancelled: &AtomicBool) -> Option<LoadResult> {
    if let LoadKind::AddMesh { scene, material } = &kind {
        let read = mesh_object(scene, path, material);
        if cancelled.load(Ordering::Relaxed) {
            return None;
        }
        return Some(read.map_or_else(LoadResult::Failed, LoadResult::MeshRead));
    }
    let theirs = match SceneDesc::load(path) {
        Ok(d) => d,
        Err(e) => return Some(LoadResult::Failed(e.to_string())),
    };
    if cancelled.load(Ordering::Relaxed) {
        return None;
    }
    Some(match kind {
        LoadKind::Open => LoadResult::Opened(theirs),
        LoadKind::AddMesh { .. } => unreachable!("read above"),
        LoadKind::Reload { base, mine } => {
            let merged = match &base {
                Some(base) => merge_reload(base, &mine, &theirs),
                None => theirs.clone(),
            };
            LoadResult::Reloaded {
                theirs,
                merged,
                mine,
            }
        }
    })
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
