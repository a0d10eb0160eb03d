//! Watches the open scene file and tells the UI when it changed on disk.
//!
//! The folder is watched, not the file: editors often save by writing a new
//! file and renaming it over the old one, which a watch on the file itself
//! would lose.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use notify::{RecommendedWatcher, RecursiveMode, Watcher};

/// Quiet time after the last event before reloading, so that a save in
/// several writes is read once, whole.
pub const SETTLE: Duration = Duration::from_millis(150);

pub struct SceneWatcher {
    _watcher: RecommendedWatcher,
    /// Time of the last event on the file, until the UI takes it.
    last_event: Arc<Mutex<Option<Instant>>>,
}

impl SceneWatcher {
    pub fn new(path: &Path, ctx: egui::Context) -> Result<SceneWatcher, String> {
        let file: PathBuf = std::path::absolute(path).map_err(|e| e.to_string())?;
        let dir = file
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        let name = file.file_name().map(|n| n.to_os_string());
        let last_event = Arc::new(Mutex::new(None));
        let seen = last_event.clone();
        let mut watcher = notify::recommended_watcher(move |res: notify::Result<notify::Event>| {
            let Ok(event) = res else { return };
            if event.kind.is_access() {
                return;
            }
            if event.paths.iter().any(|p| p.file_name() == name.as_deref()) {
                *seen.lock().unwrap_or_else(|e| e.into_inner()) = Some(Instant::now());
                ctx.request_repaint_after(SETTLE);
            }
        })
        .map_err(|e| format!("cannot watch {}: {e}", file.display()))?;
        watcher
            .watch(&dir, RecursiveMode::NonRecursive)
            .map_err(|e| format!("cannot watch {}: {e}", dir.display()))?;
        Ok(SceneWatcher {
            _watcher: watcher,
            last_event,
        })
    }

    /// True once the file changed and then stayed quiet for [`SETTLE`]; while
    /// it is settling, `Some(remaining)` says when to look again.
    pub fn poll(&self) -> Result<bool, Duration> {
        let mut last = self.last_event.lock().unwrap_or_else(|e| e.into_inner());
        match *last {
            None => Ok(false),
            Some(t) if t.elapsed() >= SETTLE => {
                *last = None;
                Ok(true)
            }
            Some(t) => Err(SETTLE - t.elapsed()),
        }
    }
}
