//! "Save PNG" and "Save scene": file writes (and a full-resolution render
//! when the image on screen is not one) run on their own threads, so the UI
//! never waits; each ends in a message for the status line or the banner.

use std::io::Write;
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::{Duration, Instant};

use crate::render::output::{write_atomic, write_film_shown};
use crate::render::progressive::{CancelToken, RenderOptions};
use crate::render::{DisplayTransform, Film, Loaded, SceneDesc};

/// What a finished task reports: a message to show, or an error.
pub type TaskResult = Result<String, String>;

pub struct IoTasks {
    tx: Sender<TaskResult>,
    rx: Receiver<TaskResult>,
    /// Labels of the tasks still running.
    running: Vec<String>,
    /// Stops export renders when the viewer closes.
    cancel: CancelToken,
}

impl Default for IoTasks {
    fn default() -> Self {
        let (tx, rx) = channel();
        IoTasks {
            tx,
            rx,
            running: Vec::new(),
            cancel: CancelToken::new(),
        }
    }
}

impl Drop for IoTasks {
    fn drop(&mut self) {
        self.cancel.cancel();
    }
}

impl IoTasks {
    fn spawn(
        &mut self,
        ctx: &egui::Context,
        label: String,
        task: impl FnOnce(&CancelToken) -> TaskResult + Send + 'static,
    ) {
        let tx = self.tx.clone();
        let ctx = ctx.clone();
        let cancel = self.cancel.clone();
        self.running.push(label);
        std::thread::spawn(move || {
            let result = std::panic::catch_unwind(AssertUnwindSafe(|| task(&cancel)))
                .unwrap_or_else(|_| Err("the export worker panicked".into()));
            let _ = tx.send(result);
            ctx.request_repaint();
        });
    }

    /// Results of the tasks that ended since the last call.
    pub fn poll(&mut self) -> Vec<TaskResult> {
        let done: Vec<TaskResult> = self.rx.try_iter().collect();
        self.running.drain(..done.len().min(self.running.len()));
        done
    }

    /// Waits for every running task (tests only); their results.
    pub fn wait_all(&mut self, timeout: Duration) -> Vec<TaskResult> {
        let deadline = Instant::now() + timeout;
        let mut done = Vec::new();
        while done.len() < self.running.len() {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.rx.recv_timeout(left) {
                Ok(r) => done.push(r),
                Err(_) => break,
            }
        }
        self.running.drain(..done.len());
        done
    }

    /// What is running, for the status bar.
    pub fn busy(&self) -> Option<&str> {
        self.running.first().map(String::as_str)
    }

    /// Writes `film` if given (the finished image on screen, already at
    /// full size), else renders `desc` first. A PNG goes through `display`
    /// (what the viewer shows); an EXR is the linear image.
    pub fn save_png(
        &mut self,
        ctx: &egui::Context,
        desc: SceneDesc,
        film: Option<Arc<Film>>,
        path: PathBuf,
        display: DisplayTransform,
    ) {
        let label = format!("saving {}", file_name(&path));
        self.spawn(ctx, label, move |cancel| {
            let film = match film {
                Some(f) => f,
                None => {
                    let loaded = Loaded::new(&desc).map_err(|e| e.to_string())?;
                    let options = RenderOptions::default();
                    loaded
                        .render(&options, cancel, &|_| {})
                        .map_err(|e| format!("{}: {e}", path.display()))?
                        .film
                        .into()
                }
            };
            write_film_shown(&film, &path, &display).map_err(|e| e.to_string())?;
            let how = match crate::render::output::FileKind::of(&path) {
                Ok(crate::render::output::FileKind::Exr) => "linear".to_string(),
                _ => display.describe(),
            };
            Ok(format!(
                "saved {} ({}×{}, {how})",
                path.display(),
                film.width,
                film.height
            ))
        });
    }

    /// Writes the scene as JSON (atomically); the JSON is made on the
    /// task's thread too (seconds for 10⁶ objects).
    pub fn save_scene(&mut self, ctx: &egui::Context, desc: SceneDesc, path: PathBuf) {
        let label = format!("saving {}", file_name(&path));
        self.spawn(ctx, label, move |_| {
            let json = desc.to_json();
            write_atomic(&path, |w| {
                w.write_all(json.as_bytes()).map_err(|e| e.to_string())
            })
            .map_err(|e| e.to_string())?;
            Ok(format!("saved {}", path.display()))
        });
    }
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| p.display().to_string())
}
