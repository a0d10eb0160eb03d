//! Where pixels go: the linear f32 RGB image of a render, and its sRGB
//! 8-bit encoding.

use std::sync::OnceLock;

use glam::Vec3;

use super::math::srgb_to_linear;

/// A linear RGB image, row-major from the top-left pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

impl Film {
    pub fn new(width: u32, height: u32) -> Film {
        Film {
            width,
            height,
            pixels: vec![Vec3::ZERO; width as usize * height as usize],
        }
    }

    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// Copies a `w`-wide block of pixels (rows packed) into the image at
    /// (x, y).
    ///
    /// Every pixel must be finite: debug builds report the offenders (how
    /// many, and the first) and panic; release builds refuse to write such
    /// an image (see [`super::output::write_film`]).
    pub fn write_block(&mut self, x: u32, y: u32, w: u32, block: &[Vec3]) {
        #[cfg(debug_assertions)]
        {
            let bad = block.iter().filter(|p| !p.is_finite()).count();
            if bad > 0 {
                let i = block.iter().position(|p| !p.is_finite()).unwrap_or(0);
                let (bx, by) = (x + i as u32 % w, y + i as u32 / w);
                panic!(
                    "{bad} non-finite pixels in the block at ({x}, {y}), the first at ({bx}, {by}): {}",
                    block[i]
                );
            }
        }
        let stride = self.width as usize;
        for (row, src) in block.chunks_exact(w as usize).enumerate() {
            let start = (y as usize + row) * stride + x as usize;
            self.pixels[start..start + w as usize].copy_from_slice(src);
        }
    }

    /// sRGB-encoded 8-bit RGB, clamped, row-major.
    pub fn to_srgb8(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.pixels.len() * 3);
        for p in &self.pixels {
            out.extend_from_slice(&encode_srgb8(*p));
        }
        out
    }

    /// Whether any pixel is NaN or infinite.
    pub fn has_non_finite(&self) -> bool {
        self.pixels.iter().any(|p| !p.is_finite())
    }

    /// How many pixels are NaN or infinite, and where the first one (in
    /// row-major order) is; `None` if every pixel is finite.
    pub fn non_finite(&self) -> Option<(usize, (u32, u32))> {
        let first = self.pixels.iter().position(|p| !p.is_finite())?;
        let count = self.pixels[first..]
            .iter()
            .filter(|p| !p.is_finite())
            .count();
        let w = self.width.max(1) as usize;
        Some((count, ((first % w) as u32, (first / w) as u32)))
    }
}

/// Linear values where each 8-bit sRGB code begins: code k covers
/// [THRESHOLDS[k-1], THRESHOLDS[k]). A binary search over them gives the
/// correctly rounded code without evaluating `powf` per pixel.
fn thresholds() -> &'static [f32; 255] {
    static T: OnceLock<[f32; 255]> = OnceLock::new();
    T.get_or_init(|| {
        let mut t = [0.0f32; 255];
        for (k, v) in t.iter_mut().enumerate() {
            *v = srgb_to_linear((k as f32 + 0.5) / 255.0);
        }
        t
    })
}

/// One linear value to its 8-bit sRGB code (clamped; NaN gives 0).
#[inline]
pub fn encode_channel(x: f32) -> u8 {
    let t = thresholds();
    // partition_point: number of thresholds <= x (NaN compares false).
    t.partition_point(|&v| v <= x) as u8
}

/// A linear RGB pixel to 8-bit sRGB.
#[inline]
pub fn encode_srgb8(p: Vec3) -> [u8; 3] {
    [
        encode_channel(p.x),
        encode_channel(p.y),
        encode_channel(p.z),
    ]
}

/// An 8-bit sRGB code to its linear value.
pub fn decode_channel(c: u8) -> f32 {
    static T: OnceLock<[f32; 256]> = OnceLock::new();
    T.get_or_init(|| std::array::from_fn(|k| srgb_to_linear(k as f32 / 255.0)))[c as usize]
}
