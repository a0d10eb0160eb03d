//! Anti-aliasing: where a pixel's camera samples go, and the
//! reconstruction filter that weighs them.
//!
//! The filter is applied by importance (filter sampling, as in pbrt-v4):
//! each sample's offset from the pixel centre is drawn with the filter's
//! density, and a pixel is the plain average of its own samples. A pixel
//! therefore depends on nothing outside it — tiles, threads and passes stay
//! independent — while the result is the filtered image. Sub-pixel
//! positions come from an Owen-scrambled Sobol' sequence per pixel, so any
//! prefix of the samples (the viewer's progressive refinement) is well
//! stratified.

use super::sobol::sobol_2d;

/// Side of the inverse-CDF table of a tabulated filter.
const TABLE: usize = 256;

/// The reconstruction filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FilterKind {
    /// Uniform over the pixel's own square.
    Box,
    /// Blackman–Harris of the given width in pixels: smooth, little
    /// ringing, sharper than a Gaussian of the same width.
    BlackmanHarris { width: f32 },
}

impl FilterKind {
    /// The default: Blackman–Harris, 1.5 pixels wide (Cycles' default).
    /// A box filter aliases what it does not cover and shows each pixel's
    /// square; a smooth filter slightly wider than a pixel removes the
    /// staircase without the blur of a wide Gaussian.
    pub const DEFAULT: FilterKind = FilterKind::BlackmanHarris { width: 1.5 };

    pub fn name(self) -> &'static str {
        match self {
            FilterKind::Box => "box",
            FilterKind::BlackmanHarris { .. } => "blackman-harris",
        }
    }

    /// Width of the filter's support, in pixels.
    pub fn width(self) -> f32 {
        match self {
            FilterKind::Box => 1.0,
            FilterKind::BlackmanHarris { width } => width,
        }
    }
}

/// A filter ready to place samples: its inverse CDF, tabulated.
#[derive(Debug, Clone)]
pub struct PixelFilter {
    /// Offsets (in pixels, from the centre) at cumulative probability
    /// k / TABLE, k = 0..=TABLE.
    inverse_cdf: Vec<f32>,
    /// Half the filter's width: no sample lies further from its pixel's
    /// centre along either axis.
    half: f32,
}

impl PixelFilter {
    pub fn new(kind: FilterKind) -> PixelFilter {
        let half = kind.width() as f64 / 2.0;
        let density = |x: f64| -> f64 {
            match kind {
                FilterKind::Box => 1.0,
                FilterKind::BlackmanHarris { .. } => {
                    // The 4-term Blackman–Harris window over [−half, half].
                    let t = std::f64::consts::TAU * (x / (2.0 * half) + 0.5);
                    0.35875 - 0.48829 * t.cos() + 0.14128 * (2.0 * t).cos()
                        - 0.01168 * (3.0 * t).cos()
                }
            }
        };
        // Integrate on a fine grid, then invert at TABLE + 1 levels.
        const FINE: usize = 4096;
        let xs: Vec<f64> = (0..=FINE)
            .map(|i| -half + 2.0 * half * i as f64 / FINE as f64)
            .collect();
        let mut cdf = vec![0.0f64; FINE + 1];
        for i in 1..=FINE {
            let w = (density(xs[i - 1]).max(0.0) + density(xs[i]).max(0.0)) / 2.0;
            cdf[i] = cdf[i - 1] + w * (xs[i] - xs[i - 1]);
        }
        let total = cdf[FINE];
        let mut inverse_cdf = Vec::with_capacity(TABLE + 1);
        let mut j = 0;
        for k in 0..=TABLE {
            let p = total * k as f64 / TABLE as f64;
            while j + 1 < FINE && cdf[j + 1] < p {
                j += 1;
            }
            let (c0, c1) = (cdf[j], cdf[j + 1]);
            let f = if c1 > c0 {
                ((p - c0) / (c1 - c0)).clamp(0.0, 1.0)
            } else {
                0.0
            };
            inverse_cdf.push((xs[j] + f * (xs[j + 1] - xs[j])) as f32);
        }
        PixelFilter {
            inverse_cdf,
            half: half as f32,
        }
    }

    /// A bound, in pixels, on how far a sample lies from its pixel's centre
    /// along either axis: half the width, and room for the table's f32
    /// rounding.
    pub fn reach(&self) -> f64 {
        self.half as f64 + 1e-3
    }

    /// Offset from the pixel centre, in pixels, of a uniform `u` ∈ [0, 1).
    #[inline]
    fn offset(&self, u: f32) -> f32 {
        let x = u * TABLE as f32;
        let k = (x as usize).min(TABLE - 1);
        let f = x - k as f32;
        self.inverse_cdf[k] + f * (self.inverse_cdf[k + 1] - self.inverse_cdf[k])
    }

    /// Image position of sample `sample` of pixel (x, y): (0, 0) is the
    /// image's top-left corner, pixel (i, j)'s centre (i + ½, j + ½).
    /// `pixel_seed` scrambles the pixel's Sobol' points.
    #[inline]
    pub fn position(&self, x: u32, y: u32, sample: u32, pixel_seed: u32) -> (f64, f64) {
        let (u, v) = sobol_2d(sample, pixel_seed);
        (
            x as f64 + 0.5 + self.offset(u) as f64,
            y as f64 + 0.5 + self.offset(v) as f64,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_box_filter_spreads_samples_uniformly_over_the_pixel() {
        let f = PixelFilter::new(FilterKind::Box);
        for k in 0..=16 {
            let u = k as f32 / 16.0 * 0.999_999;
            assert!(
                (f.offset(u) - (u - 0.5)).abs() < 1e-4,
                "u {u}: {}",
                f.offset(u)
            );
        }
    }

    #[test]
    fn blackman_harris_offsets_stay_in_its_support_and_are_symmetric() {
        let f = PixelFilter::new(FilterKind::DEFAULT);
        let half = FilterKind::DEFAULT.width() / 2.0;
        for k in 0..1000 {
            let u = k as f32 / 1000.0;
            let o = f.offset(u);
            assert!(o.abs() <= half + 1e-6, "{o}");
            // Away from the thin tails, where the inverse CDF is steep.
            if (20..=980).contains(&k) {
                let mirrored = f.offset(1.0 - u);
                assert!((o + mirrored).abs() < 1e-2, "u {u}: {o} vs {mirrored}");
            }
        }
        assert!(f.offset(0.0) < -0.5 && f.offset(0.999_9) > 0.5);
        // Most of its weight is near the centre: the median of |offset| is
        // well inside half a pixel.
        assert!(f.offset(0.75).abs() < 0.25, "{}", f.offset(0.75));
    }
}
