//! A small, fast, seedable generator. Every hit point gets its own stream,
//! keyed by (scene seed, pixel, camera sample, depth), so an image does not depend on the
//! number of threads or the order in which tiles are rendered.

/// SplitMix64 (Steele, Lea & Flood 2014): one add and a few multiplies
/// and xor-shifts per number, and it passes BigCrush.
#[derive(Debug, Clone)]
pub struct Rng {
    state: u64,
}

const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

#[inline]
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng { state: mix(seed) }
    }

    /// The stream of vertex `depth` of camera sample `sample` of pixel
    /// (x, y). Sample 0 is the stream of a render with one sample per pixel
    /// ([`Rng::for_vertex`]); depth 0 is the camera sample itself.
    #[inline]
    pub fn for_sample(seed: u64, x: u32, y: u32, sample: u32, depth: u32) -> Rng {
        let base = Rng::for_vertex(seed, x, y, depth);
        if sample == 0 {
            return base;
        }
        Rng::new(
            base.state
                ^ mix((sample as u64)
                    .wrapping_mul(0xD1B5_4A32_D192_ED03)
                    .wrapping_add(GOLDEN)),
        )
    }

    /// The stream of one path vertex of a pixel's first camera sample.
    #[inline]
    pub fn for_vertex(seed: u64, x: u32, y: u32, depth: u32) -> Rng {
        let key = mix(seed ^ GOLDEN)
            ^ mix(((x as u64) << 32 | y as u64).wrapping_add(GOLDEN))
            ^ mix((depth as u64)
                .wrapping_mul(GOLDEN)
                .wrapping_add(0x632B_E59B_D9B4_E019));
        Rng::new(key)
    }

    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GOLDEN);
        mix(self.state)
    }

    /// Uniform in [0, 1), 24 random bits.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    /// Uniform in [0, 1), 53 random bits (the tests' random inputs).
    #[cfg(test)]
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}
