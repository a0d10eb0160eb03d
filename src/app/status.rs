//! The status bar: pass k of n, shadow samples per hit, elapsed time, ray
//! throughput, the error against the reference and the current pass's
//! progress.

use std::time::{Duration, Instant};

use super::error_view::Readout;
use super::render_job::{JobState, TileMsg};
use crate::render::sampling::points_per_hit;
use crate::render::{AreaLightModel, Sampling};

/// Progress of the render on screen, as seen from the tiles shown.
#[derive(Debug, Clone)]
pub struct Progress {
    pub started: Instant,
    pub sampling: Sampling,
    /// The exact model traces no shadow rays (but where a point falls
    /// back): the bar says so instead of a count of samples.
    pub model: AreaLightModel,
    pub pass_index: usize,
    pub pass_count: usize,
    pub shadow_rays: u32,
    pub tiles_done: usize,
    pub tiles_total: usize,
    /// Rays traced by the tiles received so far (all passes).
    pub rays: u64,
    /// Set when the render ended: its time and rays traced (all passes).
    pub finished: Option<(Duration, u64)>,
    /// Camera samples per pixel of the image on screen, and the tiles of a
    /// refinement to more samples received so far (see
    /// `RenderJob::with_refinement`): (samples, tiles done, tiles).
    pub samples: u32,
    pub refining: Option<(u32, usize, usize)>,
}

impl Progress {
    pub fn new(sampling: Sampling, model: AreaLightModel) -> Progress {
        Progress {
            started: Instant::now(),
            sampling,
            model,
            pass_index: 0,
            pass_count: 0,
            shadow_rays: 0,
            tiles_done: 0,
            tiles_total: 0,
            rays: 0,
            finished: None,
            samples: 1,
            refining: None,
        }
    }

    pub fn on_tile(&mut self, t: &TileMsg) {
        if t.refinement {
            if t.samples <= self.samples {
                // A late tile of a level already complete (tiles of one
                // level reach the mailbox in any order).
                return;
            }
            // A refinement of the finished image: its own progress.
            let done = match self.refining {
                Some((to, done, _)) if to == t.samples => done.max(t.tiles_done),
                _ => t.tiles_done,
            };
            self.refining = Some((t.samples, done, t.tiles_total));
            if done == t.tiles_total {
                self.samples = t.samples;
                self.refining = None;
            }
            return;
        }
        if self.pass_count == 0 {
            self.samples = t.samples;
        }
        self.rays += t.rays;
        // Tiles of one pass arrive in any order; keep the furthest.
        if (t.pass_index, t.tiles_done) >= (self.pass_index, self.tiles_done)
            || self.pass_count == 0
        {
            self.pass_index = t.pass_index;
            self.tiles_done = t.tiles_done;
        }
        self.pass_count = t.pass_count;
        self.tiles_total = t.tiles_total;
        if t.pass_index == self.pass_index {
            self.shadow_rays = t.shadow_rays;
        }
    }
}

pub fn status_ui(
    ui: &mut egui::Ui,
    progress: &Progress,
    state: &JobState,
    exporting: Option<&str>,
    reference: Option<&Readout>,
) {
    // Wrapped: at a narrow window the figures go on a second line instead
    // of being cut off.
    ui.horizontal_wrapped(|ui| {
        match state {
            JobState::Failed(_) => {
                ui.colored_label(ui.visuals().error_fg_color, "render failed");
            }
            JobState::Cancelled => {
                ui.label("cancelled");
            }
            _ => {}
        }
        if progress.pass_count > 0 {
            ui.label(format!(
                "pass {} of {}",
                progress.pass_index + 1,
                progress.pass_count
            ));
            ui.separator();
            if progress.model == AreaLightModel::Exact {
                ui.label("exact light").on_hover_text(
                    "The visible part of the light at each hit point, without shadow rays \
                     (a point the exact model does not cover falls back to the analytic \
                     estimate with the shadow rays set)",
                );
            } else {
                ui.label(format!(
                    "{} samples/hit",
                    points_per_hit(progress.sampling, progress.shadow_rays.max(1))
                ));
            }
            ui.separator();
            let spp = match progress.refining {
                Some((to, done, total)) => format!(
                    "{} spp, refining to {to}: {}%",
                    progress.samples,
                    done * 100 / total.max(1)
                ),
                None => format!("{} spp", progress.samples),
            };
            ui.label(spp)
                .on_hover_text("Camera samples per pixel (anti-aliasing)");
            ui.separator();
        }
        let elapsed = match progress.finished {
            Some((d, _)) => d,
            None => progress.started.elapsed(),
        };
        ui.label(format!("{:.2} s", elapsed.as_secs_f64()));
        ui.separator();
        let (time, rays) = progress.finished.unwrap_or((elapsed, progress.rays));
        ui.label(format!(
            "{:.1} Mray/s",
            rays as f64 / time.as_secs_f64().max(1e-9) / 1e6
        ));
        ui.separator();
        if let Some(r) = reference {
            r.ui(ui);
            ui.separator();
        }
        if let Some(what) = exporting {
            ui.spinner();
            ui.label(what);
            ui.separator();
        }
        let fraction = if progress.finished.is_some() {
            1.0
        } else if progress.tiles_total > 0 {
            progress.tiles_done as f32 / progress.tiles_total as f32
        } else {
            0.0
        };
        ui.add(
            egui::ProgressBar::new(fraction)
                .desired_width(ui.available_width().clamp(120.0, 320.0))
                .show_percentage(),
        );
    });
}
