//! The live error readout: RMSE/PSNR of the image on screen against the
//! reference, and the false-colour error image (tev's "error" view).
//!
//! The work runs on one long-lived thread behind a one-slot mailbox, as the
//! render does: the viewer asks once per finished pass (and when the
//! reference or the exposure changes), a newer request replaces a waiting
//! one, and nothing over the image's pixels runs on the UI thread.

use std::sync::Arc;
use std::time::Duration;

use egui::{Color32, ColorImage, RichText, Ui};

use super::render_job::FilmReader;
use super::worker::{Shared, Stop, Worker};
use crate::render::Film;
use crate::render::compare::{Comparison, compare, diff_image, false_colour};

/// The image to compare.
pub enum ImageSource {
    /// A finished render.
    Film(Arc<Film>),
    /// The render in progress, copied on the worker.
    Snapshot(FilmReader),
}

pub struct ErrorRequest {
    pub generation: u64,
    /// `Some((k, n))`: after pass k (0-based) of n; `None`: finished.
    pub pass: Option<(usize, usize)>,
    pub image: ImageSource,
    pub reference: Arc<Film>,
    pub reference_id: u64,
    /// Stops below the largest difference that show as white.
    pub exposure: f32,
}

/// A readout and its error image.
#[derive(Clone)]
pub struct ErrorShown {
    pub generation: u64,
    pub pass: Option<(usize, usize)>,
    pub reference_id: u64,
    pub comparison: Comparison,
    /// The difference shown as white.
    pub scale: f64,
    /// False colour, black = equal (as uploaded, without a copy).
    pub image: Arc<ColorImage>,
}

#[derive(Default)]
struct State {
    /// Id of the newest request (results of older ones are dropped).
    latest: u64,
    pending: Option<(u64, ErrorRequest)>,
    busy: bool,
    result: Option<(u64, ErrorShown)>,
    shutdown: bool,
}

impl Stop for State {
    fn stop(&mut self) {
        self.shutdown = true;
        self.pending = None;
    }
    fn stopped(&self) -> bool {
        self.shutdown
    }
}

type Inner = Shared<State>;

/// Handle to the comparison thread; dropping it stops the thread.
pub struct ErrorJob {
    worker: Worker<State>,
}

impl ErrorJob {
    pub fn new(repaint: egui::Context) -> ErrorJob {
        ErrorJob {
            worker: Worker::spawn("penumbra-compare", State::default(), repaint, worker_loop),
        }
    }

    fn inner(&self) -> &Inner {
        self.worker.shared()
    }

    /// Asks for a comparison, replacing any request still waiting.
    pub fn request(&self, req: ErrorRequest) {
        let mut s = self.inner().lock();
        s.latest += 1;
        s.pending = Some((s.latest, req));
        s.result = None;
        self.inner().notify();
    }

    /// Forgets waiting requests and results (the reference went away).
    pub fn cancel(&self) {
        let mut s = self.inner().lock();
        s.latest += 1;
        s.pending = None;
        s.result = None;
    }

    /// The newest request's result, once ready.
    pub fn take(&self) -> Option<ErrorShown> {
        let mut s = self.inner().lock();
        match s.result.take() {
            Some((id, shown)) if id == s.latest => Some(shown),
            _ => None,
        }
    }

    /// Blocks until no request waits or runs (tests only); false on
    /// timeout.
    pub fn wait(&self, timeout: Duration) -> bool {
        self.inner()
            .wait_until(timeout, |s| s.pending.is_none() && !s.busy)
    }
}

fn worker_loop(inner: &Inner) {
    loop {
        let Some((id, req)) = inner.next(|s| {
            let p = s.pending.take();
            s.busy = p.is_some();
            p
        }) else {
            return;
        };
        let shown = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| evaluate(req)))
            .ok()
            .flatten();
        {
            let mut s = inner.lock();
            s.busy = false;
            if let Some(shown) = shown
                && id == s.latest
            {
                s.result = Some((id, shown));
            }
        }
        inner.announce();
    }
}

/// `None` if the image is gone (a newer render) or of another size.
fn evaluate(req: ErrorRequest) -> Option<ErrorShown> {
    let film = match req.image {
        ImageSource::Film(f) => f,
        ImageSource::Snapshot(reader) => Arc::new(reader.read(req.generation)?),
    };
    let reference = &req.reference;
    let comparison = compare(&film, reference).ok()?;
    // Finite for finite pixels (taken in f64); else the largest finite one.
    let largest = if comparison.max_diff.is_finite() {
        comparison.max_diff
    } else {
        film.pixels
            .iter()
            .zip(&reference.pixels)
            .map(|(a, b)| (a.as_dvec3() - b.as_dvec3()).abs().max_element())
            .filter(|d| d.is_finite())
            .fold(0.0, f64::max)
    };
    let scale = largest / 2f64.powf(req.exposure as f64);
    let (rgb, scale) = diff_image(&film, reference, Some(scale)).ok()?;
    let image = Arc::new(ColorImage::from_rgb(
        [film.width as usize, film.height as usize],
        &rgb,
    ));
    Some(ErrorShown {
        generation: req.generation,
        pass: req.pass,
        reference_id: req.reference_id,
        comparison,
        scale,
        image,
    })
}

/// "RMSE 1.234e-2 · PSNR 38.17 dB" (linear RGB, peak 1).
pub fn readout_text(c: &Comparison) -> String {
    let rmse = if c.rmse == 0.0 {
        "0".to_string()
    } else {
        format!("{:.3e}", c.rmse)
    };
    format!("RMSE {rmse} · PSNR {:.2} dB", c.psnr)
}

/// The status bar's reference entry.
pub struct Readout {
    pub text: String,
    /// Of an earlier image (the current one is not compared yet).
    pub stale: bool,
    pub hover: String,
}

impl Readout {
    pub fn ui(&self, ui: &mut Ui) {
        let mut text = RichText::new(&self.text);
        if self.stale {
            text = text.weak();
        }
        ui.label(text).on_hover_text(&self.hover);
    }
}

/// The false-colour ramp with its end values.
pub fn legend_ui(ui: &mut Ui, scale: f64) {
    ui.horizontal(|ui| {
        ui.label("0");
        let (rect, _) = ui.allocate_exact_size(egui::vec2(128.0, 12.0), egui::Sense::hover());
        let steps = 32;
        for i in 0..steps {
            let [r, g, b] = false_colour((i as f32 + 0.5) / steps as f32);
            let x0 = rect.left() + rect.width() * i as f32 / steps as f32;
            let x1 = rect.left() + rect.width() * (i + 1) as f32 / steps as f32;
            ui.painter().rect_filled(
                egui::Rect::from_x_y_ranges(x0..=x1, rect.y_range()),
                0.0,
                Color32::from_rgb(r, g, b),
            );
        }
        ui.label(format!("white = {}", scale_text(scale)))
            .on_hover_text("Largest difference of one channel, linear");
    });
}

/// "1.2e-2", or "0" for identical images.
pub fn scale_text(scale: f64) -> String {
    if scale == 0.0 {
        "0".into()
    } else {
        format!("{scale:.1e}")
    }
}
