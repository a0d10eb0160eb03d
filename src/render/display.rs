//! How a linear image is shown: exposure in stops, then a tone curve, then
//! the sRGB encoding. Display only: the film (and an EXR) stays linear; a
//! PNG written "as shown" goes through this, so the file and the screen
//! agree byte for byte.

use glam::Vec3;

use super::film::encode_srgb8;

/// The curve from scaled linear light to display light in [0, 1].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum ToneCurve {
    /// Clip at 1 (the plain sRGB encoding every render has used).
    #[default]
    Srgb,
    /// Narkowicz's fit of the ACES filmic curve: highlights roll off
    /// instead of clipping, shadows get a little contrast.
    Filmic,
}

impl ToneCurve {
    pub const ALL: [ToneCurve; 2] = [ToneCurve::Srgb, ToneCurve::Filmic];

    pub fn label(self) -> &'static str {
        match self {
            ToneCurve::Srgb => "sRGB",
            ToneCurve::Filmic => "filmic (ACES fit)",
        }
    }
}

/// Exposure and tone curve of the image view (and of a PNG saved from it).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct DisplayTransform {
    /// Stops: the linear values are multiplied by 2^exposure.
    pub exposure: f32,
    pub curve: ToneCurve,
}

impl DisplayTransform {
    /// The exposure range the viewer's slider offers.
    pub const EXPOSURE_RANGE: std::ops::RangeInclusive<f32> = -10.0..=10.0;

    /// No exposure and the plain sRGB encoding: what `render -o x.png`
    /// writes.
    pub fn is_identity(&self) -> bool {
        *self == DisplayTransform::default()
    }

    /// Linear light to display light (before the sRGB encoding).
    #[inline]
    pub fn map(&self, p: Vec3) -> Vec3 {
        // 2^0 is exactly 1, so the identity leaves every value as it is;
        // skipping the product spares a libm call per pixel at 0 EV.
        let p = if self.exposure == 0.0 {
            p
        } else {
            p * self.exposure.exp2()
        };
        match self.curve {
            ToneCurve::Srgb => p,
            ToneCurve::Filmic => {
                let x = p.max(Vec3::ZERO);
                let num = x * (x * 2.51 + 0.03);
                let den = x * (x * 2.43 + 0.59) + 0.14;
                (num / den).clamp(Vec3::ZERO, Vec3::ONE)
            }
        }
    }

    /// One pixel as the 8-bit sRGB code shown (NaN shows black).
    #[inline]
    pub fn encode(&self, p: Vec3) -> [u8; 3] {
        encode_srgb8(self.map(p))
    }

    /// A whole image, row-major RGB bytes.
    pub fn encode_all(&self, pixels: &[Vec3]) -> Vec<u8> {
        let mut out = Vec::with_capacity(pixels.len() * 3);
        for p in pixels {
            out.extend_from_slice(&self.encode(*p));
        }
        out
    }

    /// "exposure +1.0 EV, filmic (ACES fit)", for messages and the dialog.
    pub fn describe(&self) -> String {
        format!("exposure {:+.1} EV, {}", self.exposure, self.curve.label())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::film::encode_srgb8;

    #[test]
    fn the_identity_is_the_plain_srgb_encoding() {
        let t = DisplayTransform::default();
        for v in [0.0, 1e-6, 0.003, 0.18, 0.5, 0.999, 1.0, 7.5] {
            let p = Vec3::new(v, v * 0.5, v * 0.25);
            assert_eq!(t.encode(p), encode_srgb8(p));
        }
    }

    #[test]
    fn one_stop_doubles_and_filmic_rolls_off() {
        let up = DisplayTransform {
            exposure: 1.0,
            curve: ToneCurve::Srgb,
        };
        assert_eq!(up.map(Vec3::splat(0.25)), Vec3::splat(0.5));
        let filmic = DisplayTransform {
            exposure: 0.0,
            curve: ToneCurve::Filmic,
        };
        assert_eq!(filmic.map(Vec3::ZERO), Vec3::ZERO);
        // Monotone, below 1 at 4 (no clip yet), 1 far above.
        let a = filmic.map(Vec3::splat(1.0)).x;
        let b = filmic.map(Vec3::splat(4.0)).x;
        assert!(a < b && b < 1.0, "{a} {b}");
        assert_eq!(filmic.map(Vec3::splat(1e6)).x, 1.0);
        assert_eq!(filmic.encode(Vec3::splat(f32::NAN)), [0, 0, 0]);
    }
}
