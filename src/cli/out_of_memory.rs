//! The binary's allocator: the system's, but an allocation that fails
//! ends the process with one line and exit 2 (the code of every input too
//! large for the memory the process may have), its temporary files
//! removed, where Rust's own handler aborts with a backtrace (exit 134).
//! The memory checks refuse most such inputs before their work; this
//! catches the rest (a mesh whose trees do not fit, say).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::render::memory::{each_work, is_probing};
use crate::render::output::remove_temp_files;

/// Set by the first thread whose allocation fails.
static ENDING: AtomicBool = AtomicBool::new(false);

/// The allocator `main` installs.
pub struct EndWhenExhausted;

// SAFETY: every call goes to `System` with the same arguments; a failure
// the caller does not handle itself ends the process instead of
// returning null.
unsafe impl GlobalAlloc for EndWhenExhausted {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as the caller's contract.
        let block = unsafe { System.alloc(layout) };
        if block.is_null() {
            exhausted(layout.size());
        }
        block
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as the caller's contract.
        let block = unsafe { System.alloc_zeroed(layout) };
        if block.is_null() {
            exhausted(layout.size());
        }
        block
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: as the caller's contract.
        let block = unsafe { System.realloc(ptr, layout, new_size) };
        if block.is_null() {
            exhausted(new_size);
        }
        block
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as the caller's contract.
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// Ends the process for an allocation of `size` bytes that failed, unless
/// the thread is probing (its caller handles the failure). Nothing here
/// allocates: the line is built on the stack.
fn exhausted(size: usize) {
    if is_probing() {
        return;
    }
    // One line, whichever threads fail together: the first ends the
    // process, the others wait for it.
    if ENDING.swap(true, Ordering::SeqCst) {
        loop {
            // SAFETY: pause(2) only waits; the first thread's _exit ends it.
            unsafe { libc::pause() };
        }
    }
    remove_temp_files();
    let mut line = Line::default();
    line.push(b"penumbra: ");
    each_work(|part| {
        line.push_cut(part);
        line.push(b": ");
    });
    line.push(b"out of memory: an allocation of ");
    line.push_number(size);
    line.push(b" bytes failed, more than this process can have\n");
    // SAFETY: write(2) of an initialised buffer, then _exit(2), which runs
    // no handler that could allocate.
    unsafe {
        libc::write(2, line.bytes.as_ptr().cast(), line.len);
        libc::_exit(2);
    }
}

/// A line of at most 512 bytes, longer parts cut.
struct Line {
    bytes: [u8; 512],
    len: usize,
}

impl Default for Line {
    fn default() -> Line {
        Line {
            bytes: [0; 512],
            len: 0,
        }
    }
}

impl Line {
    fn push(&mut self, text: &[u8]) {
        let text = &text[..text.len().min(self.bytes.len() - self.len)];
        self.bytes[self.len..self.len + text.len()].copy_from_slice(text);
        self.len += text.len();
    }

    /// A part of the work, cut to keep room for the rest of the line.
    fn push_cut(&mut self, text: &[u8]) {
        let room = self.bytes.len().saturating_sub(self.len + 160);
        self.push(&text[..text.len().min(room)]);
    }

    fn push_number(&mut self, mut n: usize) {
        let mut digits = [0u8; 20];
        let mut at = digits.len();
        loop {
            at -= 1;
            digits[at] = b'0' + (n % 10) as u8;
            n /= 10;
            if n == 0 {
                break;
            }
        }
        self.push(&digits[at..]);
    }
}
