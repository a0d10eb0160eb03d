//! Zoom and pan of the image on screen, independent of the camera: fit to
//! the panel, 1:1 (one image pixel on one screen pixel), up to 32× with a
//! pixel grid, panned while zoomed in. Pure mapping maths between screen
//! points and image pixels, so the inspector picks the pixel under the
//! cursor at any zoom.

use egui::{Color32, Pos2, Rect, Stroke, Vec2, pos2, vec2};

/// The largest zoom: screen pixels per image pixel.
pub const MAX_ZOOM: f32 = 32.0;
/// The smallest zoom (a large image seen whole on a small panel).
pub const MIN_ZOOM: f32 = 1.0 / 32.0;
/// From this zoom on, image pixels are drawn as blocks (no smoothing) with
/// a grid between them.
pub const GRID_ZOOM: f32 = 8.0;

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Zoom {
    /// The whole image, as large as the panel allows.
    Fit,
    /// Screen pixels (not points) per image pixel.
    Scale(f32),
}

/// Where the image sits in the panel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageView {
    pub zoom: Zoom,
    /// The image point (in pixels from the top-left corner) at the centre
    /// of the panel, while zoomed; the image's centre when fitted.
    pub center: Pos2,
    /// Drag pans and the wheel zooms the image (the camera stands still).
    pub zoom_mode: bool,
}

impl Default for ImageView {
    fn default() -> Self {
        ImageView {
            zoom: Zoom::Fit,
            center: Pos2::ZERO,
            zoom_mode: false,
        }
    }
}

impl ImageView {
    /// Screen pixels per image pixel in `area` for an image of `size`.
    /// `ppp` is egui's pixels per point.
    pub fn scale(&self, area: Rect, size: [usize; 2], ppp: f32) -> f32 {
        match self.zoom {
            Zoom::Fit => fit_scale(area, size, ppp),
            Zoom::Scale(s) => s,
        }
    }

    /// The image's rectangle on screen (points), possibly larger than the
    /// panel.
    pub fn image_rect(&self, area: Rect, size: [usize; 2], ppp: f32) -> Rect {
        let points_per_pixel = self.scale(area, size, ppp) / ppp;
        let (w, h) = (size[0] as f32, size[1] as f32);
        let center = match self.zoom {
            Zoom::Fit => pos2(w / 2.0, h / 2.0),
            Zoom::Scale(_) => self.center,
        };
        let min = area.center() - center.to_vec2() * points_per_pixel;
        Rect::from_min_size(min, vec2(w, h) * points_per_pixel)
    }

    /// The image pixel under screen point `pos`, if the image is there.
    pub fn pixel_at(&self, area: Rect, size: [usize; 2], ppp: f32, pos: Pos2) -> Option<[u32; 2]> {
        let rect = self.image_rect(area, size, ppp);
        if !rect.contains(pos) || size[0] == 0 || size[1] == 0 {
            return None;
        }
        let points_per_pixel = rect.width() / size[0] as f32;
        let x = ((pos.x - rect.min.x) / points_per_pixel) as u32;
        let y = ((pos.y - rect.min.y) / points_per_pixel) as u32;
        Some([x.min(size[0] as u32 - 1), y.min(size[1] as u32 - 1)])
    }

    /// Zooms by `factor` keeping the image point under `anchor` in place.
    pub fn zoom_about(
        &mut self,
        area: Rect,
        size: [usize; 2],
        ppp: f32,
        anchor: Pos2,
        factor: f32,
    ) {
        let old = self.scale(area, size, ppp);
        let new = (old * factor).clamp(MIN_ZOOM, MAX_ZOOM);
        self.set_scale_about(area, size, ppp, anchor, new);
    }

    /// Sets the zoom to `scale`, keeping the image point under `anchor` in
    /// place.
    pub fn set_scale_about(
        &mut self,
        area: Rect,
        size: [usize; 2],
        ppp: f32,
        anchor: Pos2,
        scale: f32,
    ) {
        let rect = self.image_rect(area, size, ppp);
        let old_points = rect.width() / size[0].max(1) as f32;
        // The image point under the anchor stays under it.
        let under = (anchor - rect.min) / old_points;
        let new_points = scale.clamp(MIN_ZOOM, MAX_ZOOM) / ppp;
        self.center = pos2(under.x, under.y) - (anchor - area.center()) / new_points;
        self.zoom = Zoom::Scale(scale.clamp(MIN_ZOOM, MAX_ZOOM));
        self.clamp_center(size);
    }

    /// Back to the whole image.
    pub fn fit(&mut self) {
        self.zoom = Zoom::Fit;
    }

    /// Moves the image by `delta` points on screen.
    pub fn pan(&mut self, area: Rect, size: [usize; 2], ppp: f32, delta: Vec2) {
        if let Zoom::Fit = self.zoom {
            // Panning a fitted image zooms it in place first.
            let s = fit_scale(area, size, ppp);
            self.center = pos2(size[0] as f32 / 2.0, size[1] as f32 / 2.0);
            self.zoom = Zoom::Scale(s);
        }
        let points_per_pixel = self.scale(area, size, ppp) / ppp;
        self.center -= delta / points_per_pixel;
        self.clamp_center(size);
    }

    /// Keeps some of the image on screen: the centre stays on it.
    fn clamp_center(&mut self, size: [usize; 2]) {
        self.center.x = self.center.x.clamp(0.0, size[0] as f32);
        self.center.y = self.center.y.clamp(0.0, size[1] as f32);
    }

    /// Image pixels are blocks at this zoom (nearest-pixel magnification).
    pub fn shows_blocks(&self, area: Rect, size: [usize; 2], ppp: f32) -> bool {
        matches!(self.zoom, Zoom::Scale(_)) && self.scale(area, size, ppp) >= 2.0
    }

    /// "fit (1.6×)", "1:1", "8×".
    pub fn label(&self, area: Rect, size: [usize; 2], ppp: f32) -> String {
        let s = self.scale(area, size, ppp);
        let value = if s >= 1.0 {
            format!("{s:.3}")
                .trim_end_matches('0')
                .trim_end_matches('.')
                .to_string()
        } else {
            format!("1/{:.3}", 1.0 / s)
                .trim_end_matches('0')
                .trim_end_matches('.')
                .to_string()
        };
        match self.zoom {
            Zoom::Fit => format!("fit ({value}×)"),
            Zoom::Scale(1.0) => "1:1".into(),
            Zoom::Scale(_) => format!("{value}×"),
        }
    }
}

/// The fit's screen pixels per image pixel.
pub fn fit_scale(area: Rect, size: [usize; 2], ppp: f32) -> f32 {
    let (w, h) = (size[0].max(1) as f32, size[1].max(1) as f32);
    (area.width() / w).min(area.height() / h) * ppp
}

/// The next power-of-two zoom step above (`up`) or below the current one.
pub fn zoom_step(scale: f32, up: bool) -> f32 {
    let k = scale.log2();
    // Snap to the powers of two: 1.6× goes to 2× and 1×.
    let next = if up {
        (k + 1e-3).floor() + 1.0
    } else {
        (k - 1e-3).ceil() - 1.0
    };
    next.exp2().clamp(MIN_ZOOM, MAX_ZOOM)
}

/// Thin lines between image pixels, over the visible part (`clip`).
pub fn paint_grid(painter: &egui::Painter, rect: Rect, size: [usize; 2], clip: Rect) {
    let step = rect.width() / size[0].max(1) as f32;
    let visible = rect.intersect(clip);
    if !visible.is_positive() || step <= 0.0 {
        return;
    }
    let stroke = Stroke::new(1.0, Color32::from_black_alpha(110));
    let first_x = ((visible.min.x - rect.min.x) / step).ceil() as i64;
    let last_x = ((visible.max.x - rect.min.x) / step).floor() as i64;
    for i in first_x..=last_x {
        let x = rect.min.x + i as f32 * step;
        painter.vline(x, visible.y_range(), stroke);
    }
    let first_y = ((visible.min.y - rect.min.y) / step).ceil() as i64;
    let last_y = ((visible.max.y - rect.min.y) / step).floor() as i64;
    for j in first_y..=last_y {
        let y = rect.min.y + j as f32 * step;
        painter.hline(visible.x_range(), y, stroke);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area() -> Rect {
        Rect::from_min_size(pos2(100.0, 50.0), vec2(800.0, 600.0))
    }

    #[test]
    fn one_to_one_maps_one_image_pixel_to_one_screen_pixel() {
        let size = [64, 36];
        let mut v = ImageView::default();
        v.set_scale_about(area(), size, 1.0, area().center(), 1.0);
        let r = v.image_rect(area(), size, 1.0);
        assert_eq!(r.size(), vec2(64.0, 36.0));
        assert_eq!(r.center(), area().center());
        // At 2 pixels per point a pixel is half a point.
        let r2 = v.image_rect(area(), size, 2.0);
        assert_eq!(r2.size(), vec2(32.0, 18.0));
        // Pixel (10, 5) starts 10 and 5 points right of and below the corner.
        let p = r.min + vec2(10.5, 5.5);
        assert_eq!(v.pixel_at(area(), size, 1.0, p), Some([10, 5]));
        assert_eq!(v.pixel_at(area(), size, 1.0, r.min - vec2(1.0, 1.0)), None);
    }

    #[test]
    fn zooming_keeps_the_point_under_the_cursor() {
        let size = [960, 540];
        let mut v = ImageView::default();
        let anchor = pos2(300.3, 200.3);
        let before = v.pixel_at(area(), size, 1.0, anchor).unwrap();
        v.zoom_about(area(), size, 1.0, anchor, 20.0);
        let after = v.pixel_at(area(), size, 1.0, anchor).unwrap();
        assert_eq!(before, after);
        assert!(
            matches!(v.zoom, Zoom::Scale(s) if (s - 20.0 * fit_scale(area(), size, 1.0)).abs() < 1e-3)
        );
        v.zoom_about(area(), size, 1.0, anchor, 1000.0);
        assert_eq!(v.zoom, Zoom::Scale(MAX_ZOOM));
    }

    #[test]
    fn at_32x_each_pixel_is_32_screen_pixels_and_panning_moves_by_pixels() {
        let size = [64, 36];
        let mut v = ImageView {
            zoom: Zoom::Scale(32.0),
            center: pos2(20.0, 10.0),
            zoom_mode: false,
        };
        let c = area().center();
        // The panel's centre is the corner between pixels (19, 9) and (20, 10).
        assert_eq!(
            v.pixel_at(area(), size, 1.0, c + vec2(1.0, 1.0)),
            Some([20, 10])
        );
        assert_eq!(
            v.pixel_at(area(), size, 1.0, c - vec2(1.0, 1.0)),
            Some([19, 9])
        );
        assert_eq!(
            v.pixel_at(area(), size, 1.0, c + vec2(33.0, 1.0)),
            Some([21, 10])
        );
        // Dragging 64 points left shows two pixels further right.
        v.pan(area(), size, 1.0, vec2(-64.0, 0.0));
        assert_eq!(v.center, pos2(22.0, 10.0));
        // The centre stays on the image.
        v.pan(area(), size, 1.0, vec2(-1e6, 1e6));
        assert_eq!(v.center, pos2(64.0, 0.0));
    }

    #[test]
    fn zoom_steps_are_powers_of_two() {
        assert_eq!(zoom_step(1.6, true), 2.0);
        assert_eq!(zoom_step(1.6, false), 1.0);
        assert_eq!(zoom_step(2.0, true), 4.0);
        assert_eq!(zoom_step(2.0, false), 1.0);
        assert_eq!(zoom_step(32.0, true), 32.0);
    }
}
