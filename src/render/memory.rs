//! Whether an image's buffers fit in the memory the process may take. The
//! bytes are asked of the allocator up front and given back at once: an
//! allocation that fails half-way through a render aborts the process,
//! where a refusal before it can say why. Also what the binary's
//! allocator needs to end the process in one line when one fails anyway
//! ([`probing`], [`working`]).

use std::cell::Cell;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

/// Room kept beyond an image's own buffers (the scene, the threads' stacks).
const HEADROOM: usize = 64 << 20;

/// Address space a thread takes: its stack (2 MiB and a guard page) and
/// its thread-locals.
const PER_THREAD: usize = 4 << 20;

/// Address space a thread's own malloc arena takes where the threads do
/// not share one (see [`share_one_arena_under_address_limit`]): glibc maps
/// 128 MiB to carve out a 64 MiB arena, which `ulimit -v` counts, touched
/// or not.
const PER_ARENA: usize = 128 << 20;

/// Whether [`share_one_arena_under_address_limit`] took effect.
static ONE_ARENA: AtomicBool = AtomicBool::new(false);

/// Under a limit on the address space (`ulimit -v`), makes every thread
/// allocate from the process's one main arena. Each thread's own arena
/// would take 64–128 MiB of the limit, and how many threads have made one
/// by the time a large buffer is allocated depends on timing: a render
/// that passed the check could then abort when its film's allocation
/// failed. Call it first thing in `main`, before any thread starts.
pub fn share_one_arena_under_address_limit() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    if address_space_limited() {
        // SAFETY: mallopt only sets a malloc parameter; no thread allocates yet.
        let set = unsafe { libc::mallopt(libc::M_ARENA_MAX, 1) } == 1;
        ONE_ARENA.store(set, Ordering::Relaxed);
    }
}

/// Checks that `width`×`height` pixels of `bytes_per_pixel` each (and some
/// room) can be allocated now; the error says how much it would take.
pub fn check_image_memory(width: u32, height: u32, bytes_per_pixel: usize) -> Result<(), String> {
    check_render_memory(width, height, bytes_per_pixel, 0)
}

/// As [`check_image_memory`], with room for `threads` worker threads that
/// are not running yet, and for the threads beside them (rayon's global
/// pool, which builds the scene's trees, and the signal watcher).
pub fn check_render_memory(
    width: u32,
    height: u32,
    bytes_per_pixel: usize,
    threads: usize,
) -> Result<(), String> {
    // The threads' stacks and arenas are reserved, not used: they count
    // only against a limit on the address space. Without one, a probe of
    // their size could be refused on a many-core machine with little
    // memory (the kernel's overcommit heuristic) where the render fits.
    let thread_room = if address_space_limited() {
        let beside = std::thread::available_parallelism().map_or(1, |n| n.get()) + 1;
        let per_thread = if ONE_ARENA.load(Ordering::Relaxed) {
            PER_THREAD
        } else {
            PER_THREAD + PER_ARENA
        };
        threads.saturating_add(beside).saturating_mul(per_thread)
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

/// Checks that `bytes` more can be allocated now: "about X of memory,
/// more than this process can have" if not (the caller says for what).
pub fn check_build_memory(bytes: usize) -> Result<(), String> {
    fits(bytes).map_err(|()| format!("about {}, more than this process can have", amount(bytes)))
}

/// Reserves room in `bytes` for a file of `size` bytes (beyond what it
/// holds), or says why not: where `Vec::with_capacity` would abort, a file
/// larger than the memory the process may have is refused.
pub fn reserve_for_file(bytes: &mut Vec<u8>, size: u64) -> Result<(), String> {
    let size = usize::try_from(size).unwrap_or(usize::MAX);
    probing(|| bytes.try_reserve_exact(size.saturating_sub(bytes.len()))).map_err(|_| {
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
    probing(|| probe.try_reserve_exact(bytes)).map_err(drop)
}

thread_local! {
    static PROBING: Cell<bool> = const { Cell::new(false) };
}

/// Runs `f`, whose failed allocations are its own to handle (a probe, a
/// `try_reserve`): the binary's allocator ends the process on any other
/// (see `cli::out_of_memory`).
pub fn probing<T>(f: impl FnOnce() -> T) -> T {
    let before = PROBING.replace(true);
    let result = f();
    PROBING.set(before);
    result
}

/// Whether this thread is inside [`probing`].
pub fn is_probing() -> bool {
    PROBING.get()
}

/// What the process is reading or building, for the line that says it ran
/// out of memory: the file, then the part of it. Replaced under the lock
/// and freed after it, so that no allocation happens while it is held.
static WORK: [Mutex<Option<Box<str>>>; 2] = [const { Mutex::new(None) }; 2];

/// Which of the two parts of the work [`working`] names.
#[derive(Debug, Clone, Copy)]
pub enum Work {
    /// The file being read (a scene).
    File = 0,
    /// The part of it (a mesh, the scene's trees).
    Part = 1,
}

/// Names `what` as the process's work at `level` until the guard drops.
pub fn working(level: Work, what: String) -> Working {
    replace_work(level, Some(what.into_boxed_str()));
    Working(level)
}

/// Clears the work [`working`] named when dropped.
pub struct Working(Work);

impl Drop for Working {
    fn drop(&mut self) {
        replace_work(self.0, None);
    }
}

fn replace_work(level: Work, text: Option<Box<str>>) {
    let before = {
        let mut slot = WORK[level as usize]
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        std::mem::replace(&mut *slot, text)
    };
    drop(before);
}

/// Hands each part of the work [`working`] named to `push`, the file
/// first; a part being replaced right now is left out (never waited for).
pub fn each_work(mut push: impl FnMut(&[u8])) {
    for slot in &WORK {
        if let Ok(text) = slot.try_lock()
            && let Some(text) = text.as_deref()
        {
            push(text.as_bytes());
        }
    }
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
