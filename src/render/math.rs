//! Small numeric helpers shared by the core.

use glam::DVec3;

/// Normalizes any finite non-zero vector without overflow or underflow
/// (user input may hold 1e-300 or 1e300 components).
pub fn normalize_robust(v: DVec3) -> DVec3 {
    let m = v.abs().max_element();
    (v / m).normalize()
}

/// sRGB transfer function, linear → encoded, for values in [0, 1].
pub fn linear_to_srgb(x: f32) -> f32 {
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// sRGB transfer function, encoded → linear.
pub fn srgb_to_linear(x: f32) -> f32 {
    if x <= 0.040_45 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}
