//! Image differences: RMSE and PSNR over linear RGB, the largest per-pixel
//! difference, and a false-colour difference image.

use glam::Vec3;

use super::film::Film;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Comparison {
    /// Root mean square difference over all pixels and channels (linear).
    pub rmse: f64,
    /// 20·log10(1 / rmse), peak 1.0 linear; infinite for equal images.
    pub psnr: f64,
    /// Largest difference of one channel of one pixel, in f64: finite for
    /// any finite pixels (the difference of two f32s near their limit is
    /// past f32's range).
    pub max_diff: f64,
    /// The pixel where it occurs.
    pub max_at: (u32, u32),
}

/// The two images have different sizes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("image sizes differ: {0}×{1} vs {2}×{3}")]
pub struct SizeMismatch(pub u32, pub u32, pub u32, pub u32);

fn check_sizes(a: &Film, b: &Film) -> Result<(), SizeMismatch> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(SizeMismatch(a.width, a.height, b.width, b.height));
    }
    Ok(())
}

/// Per-pixel largest channel difference, in f64: finite for finite pixels.
fn pixel_diff(a: Vec3, b: Vec3) -> f64 {
    (a.as_dvec3() - b.as_dvec3()).abs().max_element()
}

pub fn compare(a: &Film, b: &Film) -> Result<Comparison, SizeMismatch> {
    check_sizes(a, b)?;
    let mut sum = 0.0f64;
    let mut max_diff = 0.0f64;
    let mut max_index = 0usize;
    for (i, (pa, pb)) in a.pixels.iter().zip(&b.pixels).enumerate() {
        let d = pa.as_dvec3() - pb.as_dvec3();
        sum += d.length_squared();
        let m = pixel_diff(*pa, *pb);
        // NaN must count as the largest difference, not be ignored.
        if m > max_diff || (m.is_nan() && !max_diff.is_nan()) {
            max_diff = m;
            max_index = i;
        }
    }
    let n = (a.pixels.len() * 3).max(1) as f64;
    let rmse = (sum / n).sqrt();
    Ok(Comparison {
        rmse,
        psnr: 20.0 * (1.0 / rmse).log10(),
        max_diff,
        max_at: (
            (max_index % a.width as usize) as u32,
            (max_index / a.width as usize) as u32,
        ),
    })
}

/// RMSE of the pixels where `mask` is true (e.g. penumbra regions).
pub fn rmse_masked(a: &Film, b: &Film, mask: &[bool]) -> Result<f64, SizeMismatch> {
    check_sizes(a, b)?;
    let (mut sum, mut n) = (0.0f64, 0usize);
    for ((pa, pb), &m) in a.pixels.iter().zip(&b.pixels).zip(mask) {
        if m {
            sum += (pa.as_dvec3() - pb.as_dvec3()).length_squared();
            n += 3;
        }
    }
    Ok(if n == 0 { 0.0 } else { (sum / n as f64).sqrt() })
}

/// False-colour difference image as 8-bit RGB: black where equal, through
/// blue, magenta and orange to white at `scale` (the largest difference if
/// `None`). Returns the data and the scale used.
/// The differences and the scale are f64, which holds the difference of
/// any two finite pixels.
pub fn diff_image(a: &Film, b: &Film, scale: Option<f64>) -> Result<(Vec<u8>, f64), SizeMismatch> {
    check_sizes(a, b)?;
    let scale = scale.unwrap_or_else(|| {
        a.pixels
            .iter()
            .zip(&b.pixels)
            .map(|(x, y)| pixel_diff(*x, *y))
            .filter(|d| d.is_finite())
            .fold(0.0, f64::max)
    });
    let mut out = Vec::with_capacity(a.pixels.len() * 3);
    for (pa, pb) in a.pixels.iter().zip(&b.pixels) {
        let d = pixel_diff(*pa, *pb);
        let t = if d.is_nan() {
            1.0
        } else if scale > 0.0 {
            (d / scale).clamp(0.0, 1.0) as f32
        } else {
            0.0
        };
        out.extend_from_slice(&false_colour(t));
    }
    Ok((out, scale))
}

/// A perceptually ordered ramp, black → blue → magenta → orange → white.
pub fn false_colour(t: f32) -> [u8; 3] {
    const STOPS: [[f32; 3]; 5] = [
        [0.0, 0.0, 0.0],
        [40.0, 30.0, 160.0],
        [190.0, 40.0, 150.0],
        [250.0, 150.0, 30.0],
        [255.0, 255.0, 255.0],
    ];
    let x = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f32;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - i as f32;
    std::array::from_fn(|c| (STOPS[i][c] + (STOPS[i + 1][c] - STOPS[i][c]) * f).round() as u8)
}
