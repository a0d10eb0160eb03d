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
/// [THRESHOLDS[k-1], THRESHOLDS[k]), so a value's code is the number of
/// thresholds at or below it: the correctly rounded code without `powf`.
struct Encoder {
    thresholds: [f32; 255],
    /// Top 16 bits (exponent and 8 mantissa bits) of the first bucket.
    first: u32,
    /// Per bucket of values sharing those bits, from the first threshold up
    /// to 1: the code of its lowest value, at most one short of any value's
    /// in the bucket (a bucket is 1/256 of an octave wide, narrower than the
    /// gap between two thresholds; the table's build checks it).
    start: Vec<u8>,
    /// The largest value below the last threshold.
    below_top: f32,
}

fn encoder() -> &'static Encoder {
    static E: OnceLock<Encoder> = OnceLock::new();
    E.get_or_init(|| {
        let mut thresholds = [0.0f32; 255];
        for (k, v) in thresholds.iter_mut().enumerate() {
            *v = srgb_to_linear((k as f32 + 0.5) / 255.0);
        }
        let first = thresholds[0].to_bits() >> 15;
        let last = 1.0f32.to_bits() >> 15;
        let count = |x: f32| thresholds.partition_point(|&v| v <= x);
        let start = (first..=last)
            .map(|bucket| {
                let lowest = count(f32::from_bits(bucket << 15));
                let highest = count(f32::from_bits(((bucket + 1) << 15) - 1));
                assert!(highest - lowest <= 1, "two thresholds in one bucket");
                lowest as u8
            })
            .collect();
        Encoder {
            below_top: thresholds[254].next_down(),
            thresholds,
            first,
            start,
        }
    })
}

/// One linear value to its 8-bit sRGB code (clamped; NaN gives 0): the
/// number of thresholds at or below it, counted from its bucket's start
/// (a table look-up and one comparison instead of a binary search over
/// 255 values: the viewer encodes every pixel of every edit).
#[inline]
pub fn encode_channel(x: f32) -> u8 {
    encode_with(encoder(), x)
}

/// [`encode_channel`] with the tables at hand, without branches: the
/// value is clamped into the tables' range for the look-up, and the two
/// ends are chosen after it (a branch per end was mispredicted wherever
/// dark or clipped pixels mix with others).
#[inline(always)]
fn encode_with(e: &Encoder, x: f32) -> u8 {
    let t = &e.thresholds;
    // t[0] <= c < t[254] < 1 (NaN: t[0]); for such an x, c = x.
    let c = x.max(t[0]).min(e.below_top);
    // Below 255: no more thresholds than c's are below the bucket's start.
    let start = e.start[((c.to_bits() >> 15) - e.first) as usize];
    let code = start + (t[start as usize] <= c) as u8;
    if x >= t[254] {
        255
    } else if x >= t[0] {
        code
    } else {
        // Below the first threshold, or NaN.
        0
    }
}

/// Every pixel of `pixels` to 8-bit sRGB, handed to `out` in order (the
/// tables fetched once).
#[inline]
pub fn encode_srgb8_each(pixels: &[Vec3], mut out: impl FnMut([u8; 3])) {
    let e = encoder();
    for p in pixels {
        out([
            encode_with(e, p.x),
            encode_with(e, p.y),
            encode_with(e, p.z),
        ]);
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The code by a binary search over the thresholds (the definition).
    fn by_search(x: f32) -> u8 {
        encoder().thresholds.partition_point(|&v| v <= x) as u8
    }

    #[test]
    fn the_bucketed_encoding_counts_the_thresholds_exactly() {
        let t = encoder().thresholds;
        // Every threshold and the 64 values on each side of it.
        for &v in &t {
            let mut x = v;
            for _ in 0..64 {
                x = x.next_down();
            }
            for _ in 0..129 {
                assert_eq!(encode_channel(x), by_search(x), "{x:e}");
                x = x.next_up();
            }
        }
        // A sweep over every bit pattern step from −1 to 2, and the edges.
        for bits in (0u32..=2.0f32.to_bits()).step_by(997) {
            let x = f32::from_bits(bits);
            assert_eq!(encode_channel(x), by_search(x), "{x:e}");
            assert_eq!(encode_channel(-x), 0, "{:e}", -x);
        }
        for x in [0.0, -0.0, 1.0, f32::INFINITY, f32::MIN_POSITIVE, 1e-30] {
            assert_eq!(encode_channel(x), by_search(x), "{x:e}");
        }
        assert_eq!(encode_channel(f32::NAN), 0);
        assert_eq!(encode_channel(f32::NEG_INFINITY), 0);
        assert_eq!((encode_channel(0.0), encode_channel(1.0)), (0, 255));
    }
}
