//! How a linear image is shown: exposure in stops, then a tone curve, then
//! the sRGB encoding. Display only: the film (and an EXR) stays linear; a
//! PNG written "as shown" goes through this, so the file and the screen
//! agree byte for byte.

use glam::Vec3;

use super::film::{encode_srgb8, encode_srgb8_each};

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

    /// A whole image, row-major RGB bytes, encoded block by block on the
    /// current rayon pool's threads.
    pub fn encode_all(&self, pixels: &[Vec3]) -> Vec<u8> {
        use rayon::prelude::*;
        const BLOCK: usize = 16384;
        // Zeroed lazily by the system: each block's pages are first touched
        // by the thread that encodes it.
        let mut out = vec![0u8; pixels.len() * 3];
        out.par_chunks_mut(3 * BLOCK)
            .zip(pixels.par_chunks(BLOCK))
            .for_each(|(bytes, block)| {
                let mut next = bytes.chunks_exact_mut(3);
                self.encode_each(block, |rgb| {
                    if let Some(b) = next.next() {
                        b.copy_from_slice(&rgb);
                    }
                });
            });
        out
    }

    /// [`DisplayTransform::encode`] of every pixel, handed to `out` in
    /// order: the identity (the usual case) goes straight to the sRGB
    /// encoding, and the tone curve is chosen once, not per pixel.
    #[inline]
    pub fn encode_each(&self, pixels: &[Vec3], mut out: impl FnMut([u8; 3])) {
        if self.is_identity() {
            return encode_srgb8_each(pixels, out);
        }
        let mut mapped = Vec::with_capacity(pixels.len().min(4096));
        for chunk in pixels.chunks(4096) {
            mapped.clear();
            mapped.extend(chunk.iter().map(|&p| self.map(p)));
            encode_srgb8_each(&mapped, &mut out);
        }
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
    fn encoding_a_whole_image_is_encoding_each_pixel() {
        let values = [
            0.0,
            -0.0,
            -1.0,
            1e-6,
            0.003,
            0.0031308,
            0.18,
            0.5,
            0.999,
            1.0,
            7.5,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ];
        // Several of `encode_all`'s blocks, the last one partial.
        let pixels: Vec<Vec3> = (0..40_000)
            .map(|i| Vec3::new(values[i % 14], values[(i / 3) % 14], values[(i * 7) % 14]))
            .collect();
        for t in [
            DisplayTransform::default(),
            DisplayTransform {
                exposure: 1.5,
                curve: ToneCurve::Srgb,
            },
            DisplayTransform {
                exposure: -2.0,
                curve: ToneCurve::Filmic,
            },
        ] {
            let mut got = Vec::new();
            t.encode_each(&pixels, |rgb| got.push(rgb));
            let want: Vec<[u8; 3]> = pixels.iter().map(|&p| t.encode(p)).collect();
            assert_eq!(got, want, "{}", t.describe());
            assert_eq!(t.encode_all(&pixels), want.concat());
        }
    }

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
