//! Whether an image's buffers fit in the memory the process may take. The
//! bytes are asked of the allocator up front and given back at once: an
//! allocation that fails half-way through a render aborts the process,
//! where a refusal before it can say why.

/// Room kept beyond an image's own buffers (the scene, the threads' stacks).
const HEADROOM: usize = 64 << 20;

/// Address space each worker thread takes beyond the image: glibc's
/// malloc maps 128 MiB to carve out a thread's own 64 MiB arena (which
/// `ulimit -v` counts, touched or not), and its stack takes 2 MiB.
const PER_THREAD: usize = 130 << 20;

/// Checks that `width`×`height` pixels of `bytes_per_pixel` each (and some
/// room) can be allocated now; the error says how much it would take.
pub fn check_image_memory(width: u32, height: u32, bytes_per_pixel: usize) -> Result<(), String> {
    check_render_memory(width, height, bytes_per_pixel, 0)
}

/// As [`check_image_memory`], with room for `threads` worker threads that
/// are not running yet.
pub fn check_render_memory(
    width: u32,
    height: u32,
    bytes_per_pixel: usize,
    threads: usize,
) -> Result<(), String> {
    // The threads' arenas are reserved, not used: they count only against
    // a limit on the address space. Without one, a probe of their size
    // could be refused on a many-core machine with little memory (the
    // kernel's overcommit heuristic) where the render itself fits.
    let thread_room = if address_space_limited() {
        threads.saturating_mul(PER_THREAD)
    } else {
        0
    };
    let pixels = width as usize * height as usize;
    let bytes = pixels
        .saturating_mul(bytes_per_pixel)
        .saturating_add(HEADROOM)
        .saturating_add(thread_room);
    fits(bytes).map_err(|()| {
        format!(
            "{width}×{height} needs about {}, more than this process can have",
            amount(bytes)
        )
    })
}

/// Checks, before a `width`×`height` image file is decoded, that the
/// `bytes` its decoder will allocate (beyond the file's bytes, already
/// read) can be allocated now: a decoder's allocation that fails aborts
/// the process.
pub fn check_read_memory(width: u64, height: u64, bytes: u64) -> Result<(), String> {
    let bytes = usize::try_from(bytes).unwrap_or(usize::MAX);
    fits(bytes).map_err(|()| {
        format!(
            "{width}×{height} needs about {} to read, more than this process can have",
            amount(bytes)
        )
    })
}

/// Reserves room in `bytes` for a file of `size` bytes (beyond what it
/// holds), or says why not: where `Vec::with_capacity` would abort, a file
/// larger than the memory the process may have is refused.
pub fn reserve_for_file(bytes: &mut Vec<u8>, size: u64) -> Result<(), String> {
    let size = usize::try_from(size).unwrap_or(usize::MAX);
    bytes
        .try_reserve_exact(size.saturating_sub(bytes.len()))
        .map_err(|_| {
            format!(
                "reading its {size} bytes needs about {}, more than this process can have",
                amount(size)
            )
        })
}

/// Whether `bytes` can be allocated now. Reserved and given back at once,
/// never touched: no page is faulted in.
fn fits(bytes: usize) -> Result<(), ()> {
    let mut probe: Vec<u8> = Vec::new();
    probe.try_reserve_exact(bytes).map_err(drop)
}

/// `bytes` of memory in words: GB to a tenth, or MB below 0.1 GB (where a
/// tenth of a GB would read 0.0).
pub fn amount(bytes: usize) -> String {
    let gb = bytes as f64 / 1e9;
    if gb >= 0.1 {
        format!("{gb:.1} GB of memory")
    } else {
        format!("{:.0} MB of memory", bytes as f64 / 1e6)
    }
}

/// Whether the process's address space is limited (`ulimit -v`).
fn address_space_limited() -> bool {
    let mut limit = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes one rlimit through a valid pointer.
    let read = unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut limit) } == 0;
    read && limit.rlim_cur != libc::RLIM_INFINITY
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_image_fits_and_one_beyond_the_address_space_does_not() {
        assert!(check_image_memory(960, 540, 24).is_ok());
        let err = check_image_memory(u32::MAX, u32::MAX, usize::MAX / 4).unwrap_err();
        assert!(
            err.starts_with("4294967295×4294967295 needs about"),
            "{err}"
        );
    }
}
