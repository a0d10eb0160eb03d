//! `--log-timings`: latency from a change to its first pixels on screen, and
//! UI frame times, printed to stderr.

use std::time::{Duration, Instant};

#[derive(Default)]
pub struct Timings {
    pub enabled: bool,
    /// The last change: its generation and when it was made.
    change: Option<(u64, Instant)>,
    /// Set in the frame that uploaded the change's first tile; logged when
    /// the next frame starts, i.e. after that frame was painted.
    uploaded: Option<(u64, Instant, Duration)>,
    frame_start: Option<Instant>,
    last_frame_start: Option<Instant>,
    /// The previous frame was drawn while a render ran.
    last_rendering: bool,
    window: FrameWindow,
}

#[derive(Default)]
struct FrameWindow {
    start: Option<Instant>,
    frames: u32,
    rendering_frames: u32,
    ui_sum: f64,
    ui_max: f64,
    cpu_sum: f64,
    cpu_max: f64,
    interval_max: f64,
}

impl Timings {
    pub fn new(enabled: bool) -> Timings {
        Timings {
            enabled,
            ..Timings::default()
        }
    }

    pub fn on_change(&mut self, generation: u64, size: (u32, u32)) {
        if self.enabled {
            self.change = Some((generation, Instant::now()));
            eprintln!(
                "[timings] change: render {generation} restarted at {}×{}",
                size.0, size.1
            );
        }
    }

    /// A tile of `generation` went into the texture in this frame.
    pub fn on_upload(&mut self, generation: u64) {
        if let Some((g, t)) = self.change
            && g == generation
        {
            self.uploaded = Some((g, Instant::now(), t.elapsed()));
            self.change = None;
        }
    }

    /// Whether a log line waits for the next frame (which must then come).
    pub fn wants_frame(&self) -> bool {
        self.uploaded.is_some()
    }

    pub fn begin_frame(&mut self) {
        if !self.enabled {
            return;
        }
        let now = Instant::now();
        if let Some((g, at, upload)) = self.uploaded.take() {
            let shown = upload + now.duration_since(at);
            eprintln!(
                "[timings] change -> first pixels: render {g}: tile uploaded after {:.1} ms, on screen by {:.1} ms",
                ms(upload),
                ms(shown)
            );
        }
        self.last_frame_start = self.frame_start.replace(now);
    }

    /// `ui_time`: our UI code this frame; `cpu`: eframe's CPU time of the
    /// previous frame (layout, tessellation, painting calls).
    pub fn end_frame(&mut self, ui_time: Duration, cpu: Option<f32>, rendering: bool) {
        if !self.enabled {
            return;
        }
        let w = &mut self.window;
        let now = Instant::now();
        let start = *w.start.get_or_insert(now);
        w.frames += 1;
        w.rendering_frames += rendering as u32;
        let ui = ms(ui_time);
        w.ui_sum += ui;
        w.ui_max = w.ui_max.max(ui);
        if let Some(c) = cpu {
            let c = c as f64 * 1e3;
            w.cpu_sum += c;
            w.cpu_max = w.cpu_max.max(c);
        }
        // Idle gaps (nothing to repaint) are not frame times: an interval
        // counts only if the frames at both of its ends were rendering.
        if rendering
            && self.last_rendering
            && let (Some(a), Some(b)) = (self.last_frame_start, self.frame_start)
        {
            w.interval_max = w.interval_max.max(ms(b - a));
        }
        self.last_rendering = rendering;
        let span = now.duration_since(start);
        if span >= Duration::from_secs(1) {
            let n = w.frames as f64;
            eprintln!(
                "[timings] frames: {} in {:.2} s ({} while rendering): ui mean {:.2} ms max {:.2} ms; egui cpu mean {:.2} ms max {:.2} ms; longest frame interval while rendering {:.1} ms",
                w.frames,
                span.as_secs_f64(),
                w.rendering_frames,
                w.ui_sum / n,
                w.ui_max,
                w.cpu_sum / n,
                w.cpu_max,
                w.interval_max
            );
            *w = FrameWindow::default();
        }
    }
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}
