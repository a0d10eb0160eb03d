//! The converged reference of the error readout: computed on its own thread
//! (cancelable, with progress) or read from a PNG/EXR, plus the side
//! panel's "Reference" section.
//!
//! A computed reference belongs to the image it was made for: it stays
//! valid while only the estimator changes (shadow-ray count, pattern,
//! adaptive, seed, `sampled` ↔ `analytic` ↔ `exact`, which share one limit), and is
//! shown as "settings differ" otherwise. A loaded one can only be checked
//! for its size.

use std::panic::AssertUnwindSafe;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

use egui::{RichText, Ui};

use super::render_job::render_pool;
use crate::render::output::read_film;
use crate::render::progressive::{CancelToken, RenderOptions};
use crate::render::scene_file::RenderDesc;
use crate::render::{AreaLightModel, Film, REFERENCE_RAYS, Sampling, SceneDesc};

/// The converged version of `desc` (the image as displayed): the core's
/// reference of it under its own area-light model.
pub fn converged(desc: &SceneDesc) -> SceneDesc {
    crate::render::reference_desc(desc, desc.render.area_light_model, REFERENCE_RAYS)
}

/// Whether two descriptions converge to the same image: they may differ
/// only in how the light is sampled.
pub fn same_limit(a: &SceneDesc, b: &SceneDesc) -> bool {
    fn key(r: &RenderDesc) -> RenderDesc {
        let mut k = r.clone();
        k.shadow_rays = 0;
        k.sampling = Sampling::default();
        k.adaptive = false;
        // The seed places the camera samples too, with several a pixel:
        // the reference takes the image's places (see `ReferenceTask`).
        if k.samples_per_pixel == 1 {
            k.seed = 0;
        }
        // `analytic` and `exact` converge to `sampled`'s image; only the
        // report's nearest-point heuristic converges elsewhere.
        if matches!(
            k.area_light_model,
            AreaLightModel::Analytic | AreaLightModel::Exact
        ) {
            k.area_light_model = AreaLightModel::Sampled;
        }
        k
    }
    a.format == b.format
        && a.camera == b.camera
        && a.light == b.light
        && a.materials == b.materials
        && a.objects == b.objects
        && key(&a.render) == key(&b.render)
}

#[derive(Debug, Clone)]
pub enum Origin {
    Computed {
        desc: Box<SceneDesc>,
        elapsed: Duration,
    },
    Loaded(PathBuf),
}

/// A reference image and where it came from.
#[derive(Debug, Clone)]
pub struct Reference {
    pub film: Arc<Film>,
    pub origin: Origin,
    /// Tells apart readouts of an earlier reference.
    pub id: u64,
}

/// How the reference relates to the image displayed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Match {
    Same,
    SizeDiffers,
    /// Computed for another scene, camera or toggles.
    SettingsDiffer,
}

impl Reference {
    /// Can the image of `desc` (as rendered) be compared with it?
    pub fn check(&self, desc: &SceneDesc) -> Match {
        if (self.film.width, self.film.height) != (desc.camera.width, desc.camera.height) {
            return Match::SizeDiffers;
        }
        match &self.origin {
            Origin::Computed { desc: made, .. } if !same_limit(made, desc) => Match::SettingsDiffer,
            _ => Match::Same,
        }
    }

    pub fn describe(&self) -> String {
        let size = format!("{}×{}", self.film.width, self.film.height);
        match &self.origin {
            Origin::Computed { desc, elapsed } => {
                let made = converged(desc);
                format!(
                    "computed {size}: {} {} rays, {} model, {:.1} s",
                    made.render.shadow_rays,
                    made.render.sampling.name(),
                    made.render.area_light_model.name(),
                    elapsed.as_secs_f64()
                )
            }
            Origin::Loaded(path) => format!(
                "loaded {} ({size})",
                path.file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_else(|| path.display().to_string())
            ),
        }
    }
}

/// What a reference task ended with.
pub enum TaskOutcome {
    Done(Film, Duration),
    Cancelled,
    Failed(String),
}

pub enum TaskKind {
    /// Rendering the converged version of this image's description.
    Compute(Box<SceneDesc>),
    Load(PathBuf),
}

/// A reference being computed or read on its own thread. Dropping it
/// cancels the render.
pub struct ReferenceTask {
    pub kind: TaskKind,
    cancel: CancelToken,
    /// Tiles finished and in all (a one-pass render).
    tiles: Arc<[AtomicUsize; 2]>,
    started: Instant,
    rx: Receiver<TaskOutcome>,
    /// The outcome, once received (by `wait`) and not yet taken.
    outcome: Option<TaskOutcome>,
}

impl ReferenceTask {
    /// Renders the converged version of the image of `desc` (see
    /// [`converged`]) on a thread of its own, in a low-priority pool like
    /// the viewer's renders. With several camera samples a pixel they lie
    /// where the image's do (scrambled by its seed, not the reference's),
    /// so that the error shown is the light's, not the anti-aliasing's.
    pub fn compute(ctx: &egui::Context, desc: SceneDesc) -> ReferenceTask {
        let cancel = CancelToken::new();
        let tiles: Arc<[AtomicUsize; 2]> = Arc::default();
        let (c, t) = (cancel.clone(), tiles.clone());
        let image = desc.clone();
        let rx = spawn(ctx, move |ctx| {
            let start = Instant::now();
            let loaded = crate::render::reference_scene(&converged(&image), &image)
                .map_err(|e| e.to_string())?;
            let options = RenderOptions {
                threads: None,
                progressive: false,
                tile_size: 32,
            };
            let run = || {
                loaded.render(&options, &c, &|u| {
                    t[0].fetch_max(u.tiles_done, Ordering::Relaxed);
                    t[1].store(u.tiles_total, Ordering::Relaxed);
                    ctx.request_repaint();
                })
            };
            let result = match render_pool(true) {
                Some(pool) => pool.install(run),
                None => run(),
            };
            Ok(match result {
                Ok(report) => TaskOutcome::Done(report.film, start.elapsed()),
                Err(_) => TaskOutcome::Cancelled,
            })
        });
        ReferenceTask {
            kind: TaskKind::Compute(Box::new(desc)),
            cancel,
            tiles,
            started: Instant::now(),
            rx,
            outcome: None,
        }
    }

    /// Reads a PNG (sRGB, decoded to linear) or a linear EXR.
    pub fn load(ctx: &egui::Context, path: PathBuf) -> ReferenceTask {
        let p = path.clone();
        let rx = spawn(ctx, move |_| {
            let film = read_film(&p).map_err(|e| e.to_string())?;
            if film.has_non_finite() {
                return Err(format!(
                    "{}: the reference has NaN or infinite pixels",
                    p.display()
                ));
            }
            Ok(TaskOutcome::Done(film, Duration::ZERO))
        });
        ReferenceTask {
            kind: TaskKind::Load(path),
            cancel: CancelToken::new(),
            tiles: Arc::default(),
            started: Instant::now(),
            rx,
            outcome: None,
        }
    }

    /// Fraction of the tiles rendered (0 while loading).
    pub fn fraction(&self) -> f32 {
        let done = self.tiles[0].load(Ordering::Relaxed);
        let total = self.tiles[1].load(Ordering::Relaxed);
        if total == 0 {
            0.0
        } else {
            done as f32 / total as f32
        }
    }

    pub fn elapsed(&self) -> Duration {
        self.started.elapsed()
    }

    pub fn cancel(&self) {
        self.cancel.cancel();
    }

    /// The outcome, once the thread ended.
    pub fn poll(&mut self) -> Option<TaskOutcome> {
        self.outcome.take().or_else(|| self.rx.try_recv().ok())
    }

    /// Blocks until the thread ended (tests only); false on timeout.
    pub fn wait(&mut self, timeout: Duration) -> bool {
        if self.outcome.is_none() {
            self.outcome = self.rx.recv_timeout(timeout).ok();
        }
        self.outcome.is_some()
    }
}

impl Drop for ReferenceTask {
    fn drop(&mut self) {
        self.cancel.cancel();
    }
}

/// Runs `work` on a new thread; a panic or an error ends it as `Failed`.
fn spawn(
    ctx: &egui::Context,
    work: impl FnOnce(&egui::Context) -> Result<TaskOutcome, String> + Send + 'static,
) -> Receiver<TaskOutcome> {
    let (tx, rx) = channel();
    let ctx = ctx.clone();
    std::thread::Builder::new()
        .name("penumbra-reference".into())
        .spawn(move || {
            let outcome = match std::panic::catch_unwind(AssertUnwindSafe(|| work(&ctx))) {
                Ok(Ok(outcome)) => outcome,
                Ok(Err(msg)) => TaskOutcome::Failed(msg),
                Err(_) => TaskOutcome::Failed("the reference worker panicked".into()),
            };
            let _ = tx.send(outcome);
            ctx.request_repaint();
        })
        .expect("spawn the reference thread");
    rx
}

/// What the central panel shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ViewMode {
    #[default]
    Image,
    /// The false-colour difference from the reference.
    Error,
}

/// Buttons of the Reference section that the viewer acts on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RefAction {
    Compute,
    Load,
    Cancel,
    Clear,
}

/// What the Reference section shows.
pub struct RefPanel<'a> {
    pub task: Option<&'a ReferenceTask>,
    pub reference: Option<&'a Reference>,
    pub matched: Option<Match>,
    /// Size of the image displayed.
    pub image_size: [usize; 2],
}

#[derive(Default)]
pub struct RefPanelOutput {
    pub action: Option<RefAction>,
    /// The error exposure changed (the error image must be remade).
    pub exposure_changed: bool,
}

pub fn reference_ui(
    ui: &mut Ui,
    panel: RefPanel,
    mode: &mut ViewMode,
    exposure: &mut f32,
) -> RefPanelOutput {
    let mut out = RefPanelOutput::default();
    egui::CollapsingHeader::new("Reference")
        .default_open(true)
        .show(ui, |ui| {
            ui.horizontal_wrapped(|ui| {
                let computing = matches!(
                    panel.task,
                    Some(ReferenceTask {
                        kind: TaskKind::Compute(_),
                        ..
                    })
                );
                if ui
                    .add_enabled(!computing, egui::Button::new("Compute reference"))
                    .on_hover_text(format!(
                        "Render this image converged in the background: {REFERENCE_RAYS} {} shadow rays, same area-light model, adaptive off",
                        crate::render::REFERENCE_SAMPLING.name()
                    ))
                    .clicked()
                {
                    out.action = Some(RefAction::Compute);
                }
                if ui
                    .button("Load reference…")
                    .on_hover_text("A PNG (sRGB, 8-bit) or EXR (linear, exact) of the same size; or drop one on the window")
                    .clicked()
                {
                    out.action = Some(RefAction::Load);
                }
                if ui
                    .add_enabled(panel.reference.is_some(), egui::Button::new("Clear"))
                    .clicked()
                {
                    out.action = Some(RefAction::Clear);
                }
            });
            if let Some(task) = panel.task {
                ui.horizontal(|ui| {
                    match &task.kind {
                        TaskKind::Compute(_) => {
                            ui.add(
                                egui::ProgressBar::new(task.fraction())
                                    .desired_width(160.0)
                                    .show_percentage(),
                            );
                            ui.label(format!("{:.1} s", task.elapsed().as_secs_f64()));
                        }
                        TaskKind::Load(path) => {
                            ui.spinner();
                            ui.label(format!("reading {}", path.display()));
                        }
                    }
                    if ui.button("Cancel").clicked() {
                        out.action = Some(RefAction::Cancel);
                    }
                });
            }
            match panel.reference {
                Some(r) => {
                    ui.label(RichText::new(r.describe()).small());
                    let warn = ui.visuals().warn_fg_color;
                    match panel.matched {
                        Some(Match::SizeDiffers) => {
                            ui.colored_label(
                                warn,
                                format!(
                                    "size differs from the image ({}×{}): not compared",
                                    panel.image_size[0], panel.image_size[1]
                                ),
                            );
                        }
                        Some(Match::SettingsDiffer) => {
                            ui.colored_label(
                                warn,
                                "made for other scene settings: not compared",
                            );
                        }
                        _ => {}
                    }
                }
                None if panel.task.is_none() => {
                    ui.label(RichText::new("no reference").small().weak());
                }
                None => {}
            }
            ui.horizontal(|ui| {
                ui.label("View");
                ui.selectable_value(mode, ViewMode::Image, "Image");
                ui.selectable_value(mode, ViewMode::Error, "Error")
                    .on_hover_text("False-colour difference from the reference");
            });
            out.exposure_changed = ui
                .add(
                    egui::Slider::new(exposure, 0.0..=10.0)
                        .step_by(0.5)
                        .text("Error exposure")
                        .suffix(" stops"),
                )
                .on_hover_text(
                    "0: white is the largest difference; each stop halves the difference shown as white",
                )
                .changed();
        });
    out
}
