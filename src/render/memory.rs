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
    let mut probe: Vec<u8> = Vec::new();
    // Reserved, never touched: no page is faulted in.
    probe.try_reserve_exact(bytes).map_err(|_| {
        format!(
            "{width}×{height} needs about {:.1} GB of memory, more than this process can have",
            bytes as f64 / 1e9
        )
    })
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
