//! Where pixels go: the linear f32 RGB image of a render, and its sRGB
//! 8-bit encoding.

use std::sync::{Mutex, OnceLock};

use glam::Vec3;

use super::math::{map_in_large_pages, map_in_large_pages_on_pool, srgb_to_linear};

/// A linear RGB image, row-major from the top-left pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

/// The pixels of the last film dropped (of at most [`SPARE_MAX_PIXELS`]),
/// for the next render's film of the same size ([`Film::new_on_pool`]).
static SPARE_PIXELS: Mutex<Vec<Vec3>> = Mutex::new(Vec::new());

/// The largest film whose memory is kept for the next (48 MiB; a
/// 1920×1080 film is 25 MB): larger ones are rare, and their memory goes
/// back to the system.
const SPARE_MAX_PIXELS: usize = 1 << 22;

impl Drop for Film {
    fn drop(&mut self) {
        let n = self.pixels.len();
        if n == 0 || n > SPARE_MAX_PIXELS {
            return;
        }
        // Never waits: another thread's film may take or leave the spare.
        if let Ok(mut spare) = SPARE_PIXELS.try_lock() {
            *spare = std::mem::take(&mut self.pixels);
        }
    }
}

/// The spare pixels if there are `n` of them. Spare pixels of another
/// size are freed first: the memory a render checks it may take (`ulimit
/// -v`) counts one film, not a spare beside it.
fn take_spare(n: usize) -> Option<Vec<Vec3>> {
    let spare = std::mem::take(&mut *SPARE_PIXELS.lock().unwrap_or_else(|e| e.into_inner()));
    (n > 0 && spare.len() == n).then_some(spare)
}

/// Sets every pixel to black, the threads of rayon's current pool a
/// piece each.
fn clear_on_pool(pixels: &mut [Vec3]) {
    use rayon::prelude::*;
    // Never empty: a spare has pixels.
    let piece = pixels.len().div_ceil(rayon::current_num_threads());
    pixels
        .par_chunks_mut(piece)
        .for_each(|chunk| chunk.fill(Vec3::ZERO));
}

impl Film {
    pub fn new(width: u32, height: u32) -> Film {
        let mut film = Film::zeroed(width, height);
        map_in_large_pages(&mut film.pixels);
        film
    }

    /// [`Film::new`] mapped in by the threads of rayon's current pool (a
    /// render's film, made where that pool is about to render it). The
    /// memory of the last film dropped, if it was of this size, is cleared
    /// and taken instead: the viewer renders frame after frame at one size,
    /// and a fresh film's pages cost the kernel 0.5–1 ms to map in and
    /// zero at 960×540 (5 % of a one-ray frame), clearing them 0.2–0.5 ms.
    pub fn new_on_pool(width: u32, height: u32) -> Film {
        let n = width as usize * height as usize;
        if let Some(mut pixels) = take_spare(n) {
            clear_on_pool(&mut pixels);
            return Film {
                width,
                height,
                pixels,
            };
        }
        let mut film = Film::zeroed(width, height);
        map_in_large_pages_on_pool(&mut film.pixels);
        film
    }

    /// A black film from zeroed memory: a fresh block of the system's is
    /// zero already (its pages are mapped in zeroed), so no pass writes
    /// the zeros (25 MB at 1920×1080).
    fn zeroed(width: u32, height: u32) -> Film {
        let n = width as usize * height as usize;
        let pixels = if n == 0 {
            Vec::new()
        } else {
            let layout = std::alloc::Layout::array::<Vec3>(n).expect("a film's size fits");
            // SAFETY: the layout is of n > 0 `Vec3`s; the block is checked
            // for null, and all-zero bytes are the `Vec3` 0.0, 0.0, 0.0.
            // The `Vec` frees it with the same global allocator and layout.
            unsafe {
                let block = std::alloc::alloc_zeroed(layout) as *mut Vec3;
                if block.is_null() {
                    std::alloc::handle_alloc_error(layout);
                }
                Vec::from_raw_parts(block, n, n)
            }
        };
        Film {
            width,
            height,
            pixels,
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
    /// `start` in 32 bits (what a gather loads).
    start_wide: Vec<u32>,
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
        let start: Vec<u8> = (first..=last)
            .map(|bucket| {
                let lowest = count(f32::from_bits(bucket << 15));
                let highest = count(f32::from_bits(((bucket + 1) << 15) - 1));
                assert!(highest - lowest <= 1, "two thresholds in one bucket");
                lowest as u8
            })
            .collect();
        Encoder {
            below_top: thresholds[254].next_down(),
            start_wide: start.iter().map(|&s: &u8| s as u32).collect(),
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

/// Every pixel of `pixels` to 8-bit sRGB, handed to `out` in order: the
/// channels of 256 pixels at a time go through [`encode_values`].
#[inline]
pub fn encode_srgb8_each(pixels: &[Vec3], mut out: impl FnMut([u8; 3])) {
    let mut values = [0.0f32; 3 * 256];
    let mut codes = [0u8; 3 * 256];
    for chunk in pixels.chunks(256) {
        let n = 3 * chunk.len();
        for (k, p) in chunk.iter().enumerate() {
            (values[3 * k], values[3 * k + 1], values[3 * k + 2]) = (p.x, p.y, p.z);
        }
        encode_values(&values[..n], &mut codes[..n]);
        for c in codes[..n].chunks_exact(3) {
            out([c[0], c[1], c[2]]);
        }
    }
}

/// [`encode_channel`] of every value, `codes[i]` for `values[i]`: eight at
/// a time with AVX2 gathers from the tables where the CPU has them (the
/// same comparisons, so the same codes), else one at a time.
fn encode_values(values: &[f32], codes: &mut [u8]) {
    let e = encoder();
    #[cfg(target_arch = "x86_64")]
    if super::math::avx2_kernels() {
        // SAFETY: the CPU supports AVX2 (`avx2_kernels` checks).
        return unsafe { encode_values_avx2(e, values, codes) };
    }
    for (code, &x) in codes.iter_mut().zip(values) {
        *code = encode_with(e, x);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn encode_values_avx2(e: &Encoder, values: &[f32], codes: &mut [u8]) {
    use std::arch::x86_64::*;
    let t = &e.thresholds;
    let n = values.len().min(codes.len());
    let whole = n / 8 * 8;
    let low = _mm256_set1_ps(t[0]);
    let high = _mm256_set1_ps(t[254]);
    let below_top = _mm256_set1_ps(e.below_top);
    let first = _mm256_set1_epi32(e.first as i32);
    let all = _mm256_set1_epi32(255);
    for i in (0..whole).step_by(8) {
        // SAFETY: i + 8 <= n, within both slices; the gathers' indices stay
        // in the tables: as in `encode_with`, the clamped value lies in
        // [t[0], t[254]) (NaN: t[0]), whose buckets `start` covers, and a
        // bucket's start is at most 254.
        unsafe {
            let x = _mm256_loadu_ps(values.as_ptr().add(i));
            let at_least_low = _mm256_cmp_ps::<_CMP_GE_OQ>(x, low);
            let c = _mm256_blendv_ps(low, x, at_least_low);
            let c = _mm256_blendv_ps(below_top, c, _mm256_cmp_ps::<_CMP_LE_OQ>(c, below_top));
            let bucket = _mm256_sub_epi32(_mm256_srli_epi32::<15>(_mm256_castps_si256(c)), first);
            let start = _mm256_i32gather_epi32::<4>(e.start_wide.as_ptr().cast(), bucket);
            let threshold = _mm256_i32gather_ps::<4>(t.as_ptr(), start);
            // The comparison's mask is −1 where the threshold is at or
            // below the value: subtracting it adds 1.
            let passed = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LE_OQ>(threshold, c));
            let code = _mm256_sub_epi32(start, passed);
            let top = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GE_OQ>(x, high));
            let code = _mm256_blendv_epi8(code, all, top);
            let code = _mm256_and_si256(code, _mm256_castps_si256(at_least_low));
            let mut lanes = [0u32; 8];
            _mm256_storeu_si256(lanes.as_mut_ptr().cast(), code);
            for (k, &c) in lanes.iter().enumerate() {
                codes[i + k] = c as u8;
            }
        }
    }
    for k in whole..n {
        codes[k] = encode_with(e, values[k]);
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

    /// A film of `size`, every pixel black.
    fn black(film: &Film, size: (u32, u32)) {
        assert_eq!((film.width, film.height), size);
        assert_eq!(film.pixels.len(), (size.0 * size.1) as usize);
        assert!(film.pixels.iter().all(|&p| p == Vec3::ZERO));
    }

    /// A film large enough to be mapped in large pages starts black, every
    /// pixel of it, and keeps what a block writes: the advice changes how
    /// its memory is mapped, not what it holds. So does one mapped in by a
    /// pool's threads (1 to 3 of them), one made where a freed film of
    /// colour was (memory the allocator hands out again, not fresh), and
    /// the small and empty ones.
    #[test]
    fn a_full_hd_film_starts_black_and_keeps_its_blocks() {
        let mut film = Film::new(1920, 1080);
        black(&film, (1920, 1080));
        let block = vec![Vec3::new(0.25, 0.5, 1.0); 32 * 32];
        film.write_block(1888, 1048, 32, &block);
        assert_eq!(film.get(1919, 1079), Vec3::new(0.25, 0.5, 1.0));
        assert_eq!(film.get(1887, 1079), Vec3::ZERO);
        for threads in 1..=3 {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            for size in [(1920, 1080), (1000, 700), (31, 7), (0, 5)] {
                // A film of colour freed first, whose memory may come back.
                let mut lit = Film::new(size.0, size.1);
                lit.pixels.fill(Vec3::ONE);
                drop(lit);
                black(&pool.install(|| Film::new_on_pool(size.0, size.1)), size);
                black(&Film::new(size.0, size.1), size);
            }
        }
    }

    #[test]
    fn a_render_film_reuses_the_last_film_s_memory_cleared() {
        // A size no other test uses; another test's film dropped in between
        // may take the spare's place, so a few tries.
        let size = (613, 29);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let mut reused = 0;
        for _ in 0..50 {
            let mut lit = pool.install(|| Film::new_on_pool(size.0, size.1));
            lit.pixels.fill(Vec3::new(1.0, f32::MAX, 0.5));
            let memory = lit.pixels.as_ptr();
            drop(lit);
            let film = pool.install(|| Film::new_on_pool(size.0, size.1));
            black(&film, size);
            reused += usize::from(film.pixels.as_ptr() == memory);
        }
        assert!(reused > 0, "no film took the memory of the one before");
        // One too large to keep is not kept.
        let big = Film::new(2048, 2049);
        let memory = big.pixels.as_ptr();
        drop(big);
        assert!(take_spare(2048 * 2049).is_none_or(|p| p.as_ptr() != memory));
        // A film of another size frees the spare before it is made.
        drop(Film::new(size.0, size.1));
        let other = pool.install(|| Film::new_on_pool(size.0 + 1, size.1));
        assert!(take_spare(size.0 as usize * size.1 as usize).is_none());
        drop(other);
    }

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

    #[test]
    fn eight_values_at_a_time_give_the_codes_of_one_at_a_time() {
        let mut values: Vec<f32> = (0u32..=2.0f32.to_bits())
            .step_by(991)
            .map(f32::from_bits)
            .flat_map(|x| [x, -x])
            .collect();
        for &v in &encoder().thresholds {
            values.extend([v.next_down(), v, v.next_up()]);
        }
        values.extend([f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -0.0, 1.0, 0.5]);
        let want: Vec<u8> = values.iter().map(|&x| encode_channel(x)).collect();
        assert!(want.iter().filter(|&&c| c == 255).count() > 10);
        // Every start, so that the tail of each length is one at a time.
        for skip in 0..9 {
            let mut got = vec![7u8; values.len() - skip];
            encode_values(&values[skip..], &mut got);
            assert_eq!(got, want[skip..], "from {skip}");
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            let mut got = vec![7u8; values.len()];
            // SAFETY: the CPU supports AVX2.
            unsafe { encode_values_avx2(encoder(), &values, &mut got) };
            assert_eq!(got, want, "AVX2");
        }
    }
}
