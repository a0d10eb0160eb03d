//! Small numeric helpers shared by the core.

/// Defines `fn $name(args) -> ret` that runs `$body_fn(args)` compiled for
/// 8-wide AVX2 vectors when [`avx2_kernels`] says so, and the baseline
/// (SSE2) build otherwise. The hot loops are plain scalar code written for
/// the vectorizer; only the vector width changes (no FMA contraction), so
/// both give bit-identical results (`tests/simd_paths.rs` renders with
/// each). `$body_fn` must be `#[inline(always)]`. A function may take one
/// type parameter (`fn name<S: Bound>(…)`): each type it is called with
/// gets its own AVX2 copy.
macro_rules! avx2_dispatch {
    ($(#[$meta:meta])* $vis:vis fn $name:ident<$g:ident: $bound:path>($($arg:ident: $ty:ty),* $(,)?) -> $ret:ty => $body_fn:ident) => {
        $(#[$meta])*
        $vis fn $name<$g: $bound>($($arg: $ty),*) -> $ret {
            #[cfg(target_arch = "x86_64")]
            {
                // The kernel's own signature, however long.
                #[allow(clippy::too_many_arguments)]
                #[target_feature(enable = "avx2")]
                fn avx2<$g: $bound>($($arg: $ty),*) -> $ret {
                    $body_fn($($arg),*)
                }
                if $crate::render::math::avx2_kernels() {
                    // SAFETY: the CPU supports AVX2 (`avx2_kernels` checks).
                    return unsafe { avx2($($arg),*) };
                }
            }
            $body_fn($($arg),*)
        }
    };
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) -> $ret:ty => $body_fn:ident) => {
        $(#[$meta])*
        $vis fn $name($($arg: $ty),*) -> $ret {
            #[cfg(target_arch = "x86_64")]
            {
                // The kernel's own signature, however long.
                #[allow(clippy::too_many_arguments)]
                #[target_feature(enable = "avx2")]
                fn avx2($($arg: $ty),*) -> $ret {
                    $body_fn($($arg),*)
                }
                if $crate::render::math::avx2_kernels() {
                    // SAFETY: the CPU supports AVX2 (`avx2_kernels` checks).
                    return unsafe { avx2($($arg),*) };
                }
            }
            $body_fn($($arg),*)
        }
    };
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) => $body_fn:ident) => {
        avx2_dispatch!($(#[$meta])* $vis fn $name($($arg: $ty),*) -> () => $body_fn);
    };
}
pub(crate) use avx2_dispatch;

/// Defines `fn name(args) -> ret` running `body` (an `#[inline(always)]`
/// function of the same arguments) compiled for AVX-512 — sixteen lanes —
/// where the CPU has it ([`avx512_kernels`]) and `cond` (an expression of
/// the arguments, e.g. enough points to fill the lanes) holds, and
/// otherwise `body` on eight lanes (under [`avx2_dispatch!`]), or the
/// `narrow` given after `else` (an [`avx2_dispatch!`] function a test can
/// call by name). The same operations lane by lane, so the same bits.
macro_rules! avx512_dispatch {
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) -> $ret:ty
        => $body_fn:ident if $cond:expr, else $narrow:ident) => {
        $(#[$meta])*
        $vis fn $name($($arg: $ty),*) -> $ret {
            #[cfg(target_arch = "x86_64")]
            {
                // The kernel's own signature, however long.
                #[allow(clippy::too_many_arguments)]
                #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
                fn wide($($arg: $ty),*) -> $ret {
                    $body_fn($($arg),*)
                }
                if $cond && $crate::render::math::avx512_kernels() {
                    // SAFETY: the CPU supports AVX-512 F, VL, DQ and BW
                    // (`avx512_kernels` checks).
                    return unsafe { wide($($arg),*) };
                }
            }
            $narrow($($arg),*)
        }
    };
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?)
        => $body_fn:ident if $cond:expr, else $narrow:ident) => {
        avx512_dispatch!($(#[$meta])* $vis fn $name($($arg: $ty),*) -> () => $body_fn if $cond, else $narrow);
    };
    // Without `else`: the eight-lane path is `body` under [`avx2_dispatch!`]
    // (name it with `else` only where a test calls it directly).
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) -> $ret:ty
        => $body_fn:ident if $cond:expr) => {
        $(#[$meta])*
        $vis fn $name($($arg: $ty),*) -> $ret {
            $crate::render::math::avx2_dispatch!(
                #[allow(clippy::too_many_arguments)]
                fn narrow($($arg: $ty),*) -> $ret => $body_fn
            );
            avx512_dispatch!(
                #[allow(clippy::too_many_arguments)]
                #[inline(always)]
                fn dispatch($($arg: $ty),*) -> $ret => $body_fn if $cond, else narrow
            );
            dispatch($($arg),*)
        }
    };
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?)
        => $body_fn:ident if $cond:expr) => {
        avx512_dispatch!($(#[$meta])* $vis fn $name($($arg: $ty),*) -> () => $body_fn if $cond);
    };
}
pub(crate) use avx512_dispatch;

/// From this many rays (light points) per call on, the shadow and shading
/// kernels take sixteen lanes where they can: below, most of a sixteen-lane
/// loop would be its remainder.
pub(crate) const WIDE_POINTS: usize = 16;

use std::sync::atomic::{AtomicU8, Ordering};

/// Whether the sixteen-lane kernels run with AVX-512 (F, VL, DQ, BW): where
/// the CPU has it, unless `PENUMBRA_KERNELS` is `portable` or `avx2` (to
/// compare the paths); chosen once per process.
#[inline]
pub fn avx512_kernels() -> bool {
    static WIDE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    avx2_kernels()
        && *WIDE.get_or_init(|| {
            let capped = std::env::var("PENUMBRA_KERNELS").is_ok_and(|v| v == "avx2");
            #[cfg(target_arch = "x86_64")]
            let wide = !capped
                && std::arch::is_x86_feature_detected!("avx512f")
                && std::arch::is_x86_feature_detected!("avx512vl")
                && std::arch::is_x86_feature_detected!("avx512dq")
                && std::arch::is_x86_feature_detected!("avx512bw");
            #[cfg(not(target_arch = "x86_64"))]
            let wide = {
                let _ = capped;
                false
            };
            wide
        })
}

/// Which kernels run: 0 not chosen yet, 1 portable, 2 AVX2.
static KERNELS: AtomicU8 = AtomicU8::new(0);

/// Whether the vector kernels run as AVX2: chosen once per process, from
/// the CPU and `PENUMBRA_KERNELS=portable` (which forces the baseline
/// build, to compare the two), then one relaxed load per call, inlined
/// into the caller (the choice itself is out of line).
#[inline(always)]
pub fn avx2_kernels() -> bool {
    match KERNELS.load(Ordering::Relaxed) {
        0 => choose_kernels(),
        k => k == 2,
    }
}

/// The first call of [`avx2_kernels`]: chooses, and returns the choice.
#[cold]
#[inline(never)]
fn choose_kernels() -> bool {
    let forced = std::env::var("PENUMBRA_KERNELS").is_ok_and(|v| v == "portable");
    #[cfg(target_arch = "x86_64")]
    let avx2 = !forced && std::arch::is_x86_feature_detected!("avx2");
    #[cfg(not(target_arch = "x86_64"))]
    let avx2 = {
        let _ = forced;
        false
    };
    KERNELS.store(if avx2 { 2 } else { 1 }, Ordering::Relaxed);
    avx2
}

/// Forces the portable kernels (`true`) or goes back to the CPU's choice,
/// for tests that compare the two in one process; returns whether AVX2
/// kernels run now.
pub fn force_portable_kernels(portable: bool) -> bool {
    KERNELS.store(0, Ordering::Relaxed);
    if portable {
        KERNELS.store(1, Ordering::Relaxed);
        return false;
    }
    avx2_kernels()
}

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

/// x^y for x ≥ 0 and y > 0, as exp2(y · log2 x) with polynomial log and
/// exp: no table and no branch, so loops over it vectorize (`powf` is a
/// libm call per value). Relative error about 1e-7 · max(1, |y·log2 x|);
/// inputs below the smallest normal f32 give 0.
///
/// The two halves are functions of their own so that a re-shade can keep
/// [`pow_log2`] of a cosine (it does not depend on the exponent) and apply
/// only [`pow_from_log2`] for a new exponent, with the same bits.
#[inline(always)]
pub fn pow_approx(x: f32, y: f32) -> f32 {
    pow_from_log2(pow_log2(x), y)
}

/// The first half of [`pow_approx`]: log2 x for x at least the smallest
/// normal f32, −∞ below it (and for NaN), which [`pow_from_log2`] turns into
/// 0 for every y > 0.
#[inline(always)]
pub fn pow_log2(x: f32) -> f32 {
    // x = m · 2^e with m in [√½, √2).
    let bits = x.to_bits() as i32;
    let mut e = ((bits >> 23) & 0xff) - 127;
    let mut m = f32::from_bits(((bits & 0x007f_ffff) | 0x3f80_0000) as u32);
    let big = m > std::f32::consts::SQRT_2;
    m = if big { m * 0.5 } else { m };
    e += big as i32;
    // ln m = 2 atanh(t), t = (m − 1)/(m + 1), |t| ≤ 0.172.
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    let ln_m =
        2.0 * t * (1.0 + t2 * (1.0 / 3.0 + t2 * (1.0 / 5.0 + t2 * (1.0 / 7.0 + t2 * (1.0 / 9.0)))));
    let log2_x = e as f32 + ln_m * std::f32::consts::LOG2_E;
    if x >= f32::MIN_POSITIVE {
        log2_x
    } else {
        f32::NEG_INFINITY
    }
}

/// The second half of [`pow_approx`]: 2^(y · log2_x) for y > 0, 0 where
/// y · log2_x ≤ −126 (so 0 for log2_x = −∞).
#[inline(always)]
pub fn pow_from_log2(log2_x: f32, y: f32) -> f32 {
    // 2^z = 2^k · 2^f with k = round(z), f in [−½, ½].
    let z = (y * log2_x).max(-126.0);
    // Round to nearest by adding and removing 1.5·2²³ (exact for |z| < 2²²);
    // the integer then sits in the sum's low mantissa bits. (`f32::round`
    // is a libm call on baseline x86-64 and `as i32` saturates lane by
    // lane: both block vectorizing.)
    const ROUNDER: f32 = 12_582_912.0;
    let r = z + ROUNDER;
    let k_int = r.to_bits() as i32 - ROUNDER.to_bits() as i32;
    let f = (z - (r - ROUNDER)) * std::f32::consts::LN_2;
    let p = 1.0
        + f * (1.0
            + f * (1.0 / 2.0
                + f * (1.0 / 6.0
                    + f * (1.0 / 24.0
                        + f * (1.0 / 120.0 + f * (1.0 / 720.0 + f * (1.0 / 5040.0)))))));
    let scaled = p * f32::from_bits(((k_int + 127) << 23) as u32);
    if z > -126.0 { scaled } else { 0.0 }
}

/// The n-point Gauss–Legendre rule on [−1, 1], as (node, weight) pairs:
/// the roots of Pₙ by Newton's method from Tricomi's first guesses.
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut t = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, t);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * t * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                dp = n as f64 * (t * p1 - p0) / (t * t - 1.0);
                let dx = p1 / dp;
                t -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            (t, 2.0 / ((1.0 - t * t) * dp * dp))
        })
        .collect()
}

/// Maps in `block` (a fresh allocation, not yet written) in one go, with
/// 2 MiB pages where it spans them. Page by page, each 4 KiB page's first
/// write is a fault, several microseconds in a virtual machine: a film's
/// block is mapped anew for every render (see [`release_free_memory`]),
/// and its faults took 3.9 ms of every 960×540 render, 15 ms at 1920×1080;
/// advised, 0.9 ms and 3.5 ms. Advice only: a kernel without either leaves
/// the pages to be faulted in as before.
pub fn map_in_large_pages<T>(block: &mut [T]) {
    map_in_large_pages_by(block, 1, |populate| populate(0));
}

/// [`map_in_large_pages`] with the mapping-in (the kernel zeroing the
/// pages, 8 ms of one thread for a 1920×1080 film) shared by the threads
/// of rayon's current pool, each a piece of whole large pages. Only where
/// that pool is at work anyway (a render's): it may be the global pool.
pub fn map_in_large_pages_on_pool<T>(block: &mut [T]) {
    map_in_large_pages_by(block, rayon::current_num_threads(), |populate| {
        rayon::broadcast(|ctx| populate(ctx.index()));
    });
}

/// Advises `block` into large pages and has `run` call the mapping-in of
/// piece `i` of `pieces` (its calls may come from several threads).
fn map_in_large_pages_by<T>(
    block: &mut [T],
    pieces: usize,
    run: impl FnOnce(&(dyn Fn(usize) + Sync)),
) {
    #[cfg(not(target_os = "linux"))]
    let _ = (block, pieces, run);
    #[cfg(target_os = "linux")]
    {
        const PAGE: usize = 4096;
        const HUGE_PAGE: usize = 2 << 20;
        let bytes = std::mem::size_of_val(block);
        if bytes < HUGE_PAGE {
            return;
        }
        // madvise takes whole pages: those inside the block.
        let start = (block.as_mut_ptr() as usize).next_multiple_of(PAGE);
        let end = (block.as_mut_ptr() as usize + bytes) / PAGE * PAGE;
        // SAFETY (each call): the range lies inside `block`, which this
        // borrow owns until `run` returns; both advices change how its
        // pages are backed and when they are mapped, never what they hold.
        let advise = |from: usize, to: usize, advice| unsafe {
            libc::madvise(from as *mut libc::c_void, to - from, advice);
        };
        advise(start, end, libc::MADV_HUGEPAGE);
        let piece = ((end - start) / pieces.max(1)).next_multiple_of(HUGE_PAGE);
        run(&|i| {
            let from = start + i * piece;
            if from < end {
                advise(from, (from + piece).min(end), libc::MADV_POPULATE_WRITE);
            }
        });
    }
}

/// Hands memory freed by a large build back to the system. glibc raises
/// its threshold for mapping blocks of their own after each large block is
/// freed, up to 32 MiB, and keeps what is freed below it in its per-thread
/// arenas: a build of millions of triangles then held its scratch space
/// after use, and the next build came on top of it. A fixed threshold
/// (which also stops the raising) and a trim avoid both.
pub fn release_free_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: both calls only change how the allocator obtains and returns
    // pages; they are safe at any time, from any thread.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 1 << 20);
        libc::malloc_trim(0);
    }
}

#[cfg(test)]
mod tests {
    use super::pow_approx;

    #[test]
    fn pow_approx_matches_powf() {
        // The worst error as a share of the bound, and the worst error
        // where |y·log2 x| ≤ 1 (the doc's "about 1e-7").
        let (mut worst_share, mut worst_small) = (0.0f64, 0.0f64);
        for i in 1..=2000 {
            let x = i as f32 / 2000.0;
            for y in [1e-3f32, 0.5, 1.0, 2.0, 7.3, 20.0, 100.0, 500.0, 1e4] {
                let exact = (x as f64).powf(y as f64);
                let got = pow_approx(x, y) as f64;
                if exact < 1e-30 {
                    assert!(got < 1e-30, "{x}^{y}: {got} vs {exact}");
                    continue;
                }
                let rel = (got - exact).abs() / exact;
                let magnitude = (y as f64 * (x as f64).log2()).abs();
                let bound = 3e-7 * (1.0 + magnitude);
                assert!(rel < bound, "{x}^{y}: {got} vs {exact} (rel {rel:e})");
                worst_share = worst_share.max(rel / bound);
                if magnitude <= 1.0 {
                    worst_small = worst_small.max(rel);
                }
            }
        }
        assert_eq!(pow_approx(0.0, 20.0), 0.0);
        assert_eq!(pow_approx(0.0, 1e-3), 0.0);
        assert_eq!(pow_approx(1.0, 1e4), 1.0);
        // The bound is not loose: some input comes within 4× of it
        // (measured: about half of it, at large |y·log2 x|).
        assert!(worst_share > 0.25, "worst error {worst_share} of the bound");
        // Near x^y = 1 the error stays at a couple of f32 ulps (measured:
        // 1.3e-7; one ulp is up to 1.2e-7 relative).
        assert!(
            worst_small < 2e-7,
            "worst error {worst_small:e} at |y·log2 x| ≤ 1"
        );
    }
}
