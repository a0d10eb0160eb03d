//! "Snapshot A": the image on screen pinned, to compare the live render
//! with it after edits (the before/after view of a person tweaking a
//! material). Split (A left of a slider, the live image right), flicker
//! (A and the live image by turns) and the false-colour difference, made
//! on the error readout's thread as against a reference.
//!
//! Display only: A is a copy of the linear image, shown through the same
//! exposure and tone curve as the live one.

use std::sync::Arc;
use std::time::{Duration, Instant};

use egui::{
    Align2, Color32, ColorImage, ImageData, Pos2, Rect, Stroke, TextureHandle, TextureOptions,
    pos2, vec2,
};

use super::error_view::{
    ErrorJob, ErrorRequest, ErrorShown, ImageSource, readout_text, scale_text,
};
use crate::render::{DisplayTransform, Film};

/// How the live image is set against A.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CompareMode {
    /// The live image only.
    #[default]
    Off,
    /// A left of the split line, the live image right of it.
    Split,
    /// A and the live image by turns.
    Flicker,
    /// The false-colour difference |live − A|.
    Difference,
}

impl CompareMode {
    pub const ALL: [CompareMode; 4] = [
        CompareMode::Off,
        CompareMode::Split,
        CompareMode::Flicker,
        CompareMode::Difference,
    ];

    pub fn label(self) -> &'static str {
        match self {
            CompareMode::Off => "live",
            CompareMode::Split => "split",
            CompareMode::Flicker => "flicker",
            CompareMode::Difference => "difference",
        }
    }

    /// The next mode (the X key).
    pub fn next(self) -> CompareMode {
        let i = CompareMode::ALL
            .iter()
            .position(|m| *m == self)
            .unwrap_or(0);
        CompareMode::ALL[(i + 1) % CompareMode::ALL.len()]
    }
}

/// How long each image shows while flickering.
pub const FLICKER_PERIOD: Duration = Duration::from_millis(600);

/// The pinned image.
pub struct PinnedImage {
    /// Linear, as rendered.
    pub film: Arc<Film>,
    /// Camera samples per pixel it had.
    pub samples: u32,
    /// Tells one pin from the next (the difference is of one pin).
    pub id: u64,
    /// As shown (through the display transform).
    pub image: ColorImage,
    texture: TextureHandle,
}

impl PinnedImage {
    pub fn size(&self) -> [usize; 2] {
        [self.film.width as usize, self.film.height as usize]
    }

    pub fn texture(&self) -> &TextureHandle {
        &self.texture
    }
}

/// The pin and the comparison's settings.
pub struct Compare {
    pub pinned: Option<PinnedImage>,
    pub mode: CompareMode,
    /// Where the split line is, 0 (left edge) to 1.
    pub split: f32,
    flicker_since: Instant,
    /// Made on the first difference asked for.
    diff_job: Option<ErrorJob>,
    diff: Option<ErrorShown>,
    diff_texture: Option<TextureHandle>,
    /// What the last difference asked for: (generation, samples, pin id,
    /// exposure bits).
    requested: Option<(u64, u32, u64, u32)>,
    ids: u64,
}

impl Default for Compare {
    fn default() -> Self {
        Compare {
            pinned: None,
            mode: CompareMode::Off,
            split: 0.5,
            flicker_since: Instant::now(),
            diff_job: None,
            diff: None,
            diff_texture: None,
            requested: None,
            ids: 0,
        }
    }
}

impl Compare {
    /// Pins `film` (the linear image on screen) as A.
    pub fn pin(
        &mut self,
        ctx: &egui::Context,
        film: Film,
        samples: u32,
        display: &DisplayTransform,
        options: TextureOptions,
    ) {
        self.ids += 1;
        let image = shown(&film, display);
        let texture = ctx.load_texture("pinned", image.clone(), options);
        self.pinned = Some(PinnedImage {
            film: Arc::new(film),
            samples,
            id: self.ids,
            image,
            texture,
        });
        self.diff = None;
        self.requested = None;
        if self.mode == CompareMode::Off {
            self.mode = CompareMode::Split;
        }
        self.flicker_since = Instant::now();
    }

    pub fn clear(&mut self) {
        self.pinned = None;
        self.diff = None;
        self.requested = None;
        self.mode = CompareMode::Off;
        if let Some(j) = &self.diff_job {
            j.cancel();
        }
    }

    /// Shows A through a new exposure or curve.
    pub fn redisplay(&mut self, display: &DisplayTransform, options: TextureOptions) {
        if let Some(p) = &mut self.pinned {
            p.image = shown(&p.film, display);
            p.texture.set(p.image.clone(), options);
        }
    }

    /// Uploads A and the difference again with other texture options.
    pub fn set_texture_options(&mut self, options: TextureOptions) {
        if let Some(p) = &mut self.pinned {
            p.texture.set(p.image.clone(), options);
        }
        if let (Some(t), Some(d)) = (&mut self.diff_texture, &self.diff) {
            t.set(ImageData::Color(d.image.clone()), options);
        }
    }

    /// A and the live image can be compared (same size).
    pub fn comparable(&self, size: [usize; 2]) -> bool {
        self.pinned.as_ref().is_some_and(|p| p.size() == size)
    }

    /// Asks for the difference of the finished live image against A, once
    /// per image (a newer one replaces a waiting request).
    pub fn request_difference(
        &mut self,
        ctx: &egui::Context,
        live: &Arc<Film>,
        generation: u64,
        samples: u32,
        exposure: f32,
    ) {
        let Some(p) = &self.pinned else { return };
        if self.mode != CompareMode::Difference
            || p.film.width != live.width
            || p.film.height != live.height
        {
            return;
        }
        let key = (generation, samples, p.id, exposure.to_bits());
        if self.requested == Some(key) {
            return;
        }
        self.requested = Some(key);
        let job = self
            .diff_job
            .get_or_insert_with(|| ErrorJob::new(ctx.clone()));
        job.request(ErrorRequest {
            generation,
            pass: None,
            image: ImageSource::Film(live.clone()),
            reference: p.film.clone(),
            reference_id: p.id,
            exposure,
        });
    }

    /// Takes a finished difference into its texture.
    pub fn poll(&mut self, ctx: &egui::Context, options: TextureOptions) {
        let Some(d) = self.diff_job.as_ref().and_then(ErrorJob::take) else {
            return;
        };
        let image = ImageData::Color(d.image.clone());
        match &mut self.diff_texture {
            Some(t) => t.set(image, options),
            None => self.diff_texture = Some(ctx.load_texture("pin-difference", image, options)),
        }
        self.diff = Some(d);
    }

    /// The difference against the current pin, if made.
    pub fn difference(&self) -> Option<(&ErrorShown, &TextureHandle)> {
        let p = self.pinned.as_ref()?;
        let d = self.diff.as_ref().filter(|d| d.reference_id == p.id)?;
        Some((d, self.diff_texture.as_ref()?))
    }

    /// Blocks until the difference asked for is made (tests only).
    pub fn wait(&self, timeout: Duration) -> bool {
        self.diff_job.as_ref().is_none_or(|j| j.wait(timeout))
    }

    /// While flickering: whether A shows now, and when that changes.
    pub fn flicker_shows_pinned(&self) -> (bool, Duration) {
        let t = self.flicker_since.elapsed().as_secs_f64() / FLICKER_PERIOD.as_secs_f64();
        let left = (1.0 - t.fract()) * FLICKER_PERIOD.as_secs_f64();
        (
            (t as u64).is_multiple_of(2),
            Duration::from_secs_f64(left.max(0.01)),
        )
    }

    /// Starts flickering with A.
    pub fn restart_flicker(&mut self) {
        self.flicker_since = Instant::now();
    }
}

impl Compare {
    /// Paints the comparison over the live image at `rect` (of which
    /// `shown` is on screen); the time after which it changes by itself
    /// (flicker), if it does.
    pub fn paint(
        &self,
        ui: &egui::Ui,
        painter: &egui::Painter,
        rect: Rect,
        shown: Rect,
        size: [usize; 2],
    ) -> Option<Duration> {
        let a = self.pinned.as_ref()?;
        if self.mode == CompareMode::Off {
            return None;
        }
        if !self.comparable(size) {
            tag(
                ui,
                "pin-size",
                shown.left_top(),
                Align2::LEFT_TOP,
                &format!(
                    "A is {}×{}, the image {}×{}: not compared",
                    a.film.width, a.film.height, size[0], size[1]
                ),
            );
            return None;
        }
        let full = Rect::from_min_max(pos2(0.0, 0.0), pos2(1.0, 1.0));
        match self.mode {
            CompareMode::Off => None,
            CompareMode::Split => {
                let x = rect.min.x + self.split * rect.width();
                let left = Rect::from_min_max(rect.min, pos2(x, rect.max.y));
                let uv = Rect::from_min_max(pos2(0.0, 0.0), pos2(self.split, 1.0));
                painter.image(a.texture.id(), left, uv, Color32::WHITE);
                painter.vline(x, shown.y_range(), Stroke::new(1.5, Color32::WHITE));
                let top = shown.top() + 6.0;
                tag(ui, "pin-a", pos2(x - 6.0, top), Align2::RIGHT_TOP, "A");
                tag(ui, "pin-live", pos2(x + 6.0, top), Align2::LEFT_TOP, "live");
                None
            }
            CompareMode::Flicker => {
                let (pinned, wait) = self.flicker_shows_pinned();
                if pinned {
                    painter.image(a.texture.id(), rect, full, Color32::WHITE);
                }
                let text = if pinned { "A" } else { "live" };
                tag(
                    ui,
                    "pin-flicker",
                    shown.left_top() + vec2(6.0, 6.0),
                    Align2::LEFT_TOP,
                    text,
                );
                Some(wait)
            }
            CompareMode::Difference => {
                let text = match self.difference() {
                    Some((d, texture)) => {
                        painter.image(texture.id(), rect, full, Color32::WHITE);
                        format!(
                            "|live − A|: {}, white = {}",
                            readout_text(&d.comparison),
                            scale_text(d.scale)
                        )
                    }
                    None => "|live − A|: comparing once the render is finished…".into(),
                };
                tag(
                    ui,
                    "pin-difference",
                    shown.right_bottom() - vec2(8.0, 8.0),
                    Align2::RIGHT_BOTTOM,
                    &text,
                );
                None
            }
        }
    }
}

/// A small label over the image.
fn tag(ui: &egui::Ui, id: &str, at: Pos2, pivot: Align2, text: &str) {
    egui::Area::new(egui::Id::unique(("penumbra-tag", id)))
        .pivot(pivot)
        .fixed_pos(at)
        .interactable(false)
        .show(ui.ctx(), |ui| {
            egui::Frame::popup(ui.style()).show(ui, |ui| {
                ui.add(egui::Label::new(text).extend());
            });
        });
}

/// A linear image as shown, for a texture.
pub fn shown(film: &Film, display: &DisplayTransform) -> ColorImage {
    ColorImage::from_rgb(
        [film.width as usize, film.height as usize],
        &display.encode_all(&film.pixels),
    )
}
