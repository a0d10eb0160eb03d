//! What keeps the CLI's files safe: signals that stop a render or a write
//! without leaving a temporary file, and outputs that would overwrite an
//! input.

use std::path::Path;
use std::sync::atomic::{AtomicPtr, AtomicUsize, Ordering};

use super::CliError;
use crate::render::CancelToken;
use crate::render::output::{interrupt_writes, remove_temp_files, writes_interrupted};

/// Signals whose default action ends the process and that a handler can
/// catch, other than the three that stop a render gracefully (SIGINT,
/// SIGTERM, SIGHUP): on any of them the temporary file being written is
/// removed and the signal then ends the process as it would have.
const FATAL: [libc::c_int; 12] = [
    libc::SIGQUIT,
    libc::SIGUSR1,
    libc::SIGUSR2,
    libc::SIGALRM,
    libc::SIGVTALRM,
    libc::SIGPROF,
    libc::SIGXCPU,
    libc::SIGIO,
    libc::SIGPWR,
    libc::SIGSYS,
    libc::SIGTRAP,
    libc::SIGABRT,
];

extern "C" fn remove_and_die(signal: libc::c_int) {
    remove_temp_files();
    // SA_RESETHAND restored the default action: raise it again.
    // SAFETY: raise(3) is async-signal-safe.
    unsafe {
        libc::raise(signal);
    }
}

/// SIGINT, SIGTERM and SIGHUP cancel `cancel` and every atomic write (the
/// render stops, no file is written, the target is untouched); the other
/// catchable fatal signals remove the temporary file and end the process;
/// SIGXFSZ is ignored so that a file-size limit fails the write with an
/// error instead of killing the process with the file half written.
pub fn handle_signals(cancel: &CancelToken) {
    let cancel = cancel.clone();
    // Fails only if a handler is already set (a second command in one
    // process): the first one stays.
    let _ = ctrlc::set_handler(move || {
        cancel.cancel();
        interrupt_writes();
    });
    // SAFETY: sigaction with a handler that only calls async-signal-safe
    // functions; SIG_IGN for SIGXFSZ.
    unsafe {
        for signal in FATAL {
            install_remove_and_die(signal);
        }
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
}

/// A failed atomic write as the command reports it (exit 1, as other I/O
/// failures): `interrupted` when a signal stopped it ([`handle_signals`]),
/// else the write's own error, which names the file.
pub fn write_failure(error: impl std::fmt::Display, interrupted: &str) -> CliError {
    if writes_interrupted() {
        CliError::other(interrupted)
    } else {
        CliError::other(error)
    }
}

/// The line [`report_and_exit`] writes: set once by [`end_on_signals`],
/// read by the handler (a pointer and a length: atomics, which a handler
/// may read).
static INTERRUPTED_LINE: AtomicPtr<u8> = AtomicPtr::new(std::ptr::null_mut());
static INTERRUPTED_LINE_LEN: AtomicUsize = AtomicUsize::new(0);

extern "C" fn report_and_exit(_signal: libc::c_int) {
    remove_temp_files();
    let line = INTERRUPTED_LINE.load(Ordering::SeqCst);
    // SAFETY: write(2) and _exit(2) are async-signal-safe; the line is a
    // leaked string that is never freed.
    unsafe {
        if !line.is_null() {
            libc::write(
                libc::STDERR_FILENO,
                line as *const libc::c_void,
                INTERRUPTED_LINE_LEN.load(Ordering::SeqCst),
            );
        }
        libc::_exit(1);
    }
}

/// For the work of commands that has no render to stop (reading and
/// merging parts, comparing, the bench): SIGINT, SIGTERM and SIGHUP remove
/// the temporary file being written, print `penumbra: {message}` and end
/// the process with exit code 1, as an interrupted `render` does (before,
/// the signal ended it silently with 130 or 143). They end it at once,
/// even in a blocking read of a FIFO. The other fatal signals are handled
/// as in [`handle_signals`]; a later [`handle_signals`] takes SIGINT,
/// SIGTERM and SIGHUP over for a write that can be stopped cleanly.
pub fn end_on_signals(message: &str) {
    let line: &'static mut str = format!("penumbra: {message}\n").leak();
    INTERRUPTED_LINE_LEN.store(line.len(), Ordering::SeqCst);
    INTERRUPTED_LINE.store(line.as_mut_ptr(), Ordering::SeqCst);
    let stopping = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];
    // SAFETY: as in handle_signals; report_and_exit only calls
    // async-signal-safe functions, and the three signals are blocked
    // while it runs, so that a second one prints no second line.
    unsafe {
        for signal in FATAL {
            install_remove_and_die(signal);
        }
        let mut action: libc::sigaction = std::mem::zeroed();
        action.sa_sigaction = report_and_exit as extern "C" fn(libc::c_int) as usize;
        libc::sigemptyset(&mut action.sa_mask);
        for signal in stopping {
            libc::sigaddset(&mut action.sa_mask, signal);
        }
        for signal in stopping {
            libc::sigaction(signal, &action, std::ptr::null_mut());
        }
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
}

/// # Safety
/// Replaces the disposition of `signal` for the whole process.
unsafe fn install_remove_and_die(signal: libc::c_int) {
    // SAFETY: a zeroed sigaction is valid; the handler only calls
    // async-signal-safe functions.
    unsafe {
        let mut action: libc::sigaction = std::mem::zeroed();
        action.sa_sigaction = remove_and_die as extern "C" fn(libc::c_int) as usize;
        action.sa_flags = libc::SA_RESETHAND;
        libc::sigemptyset(&mut action.sa_mask);
        libc::sigaction(signal, &action, std::ptr::null_mut());
    }
}

/// Whether two paths name the same file (the same device and inode,
/// through symbolic and hard links). A path that does not exist is no
/// file.
pub fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

/// Refuses (exit 2), before any work, an output that is an existing
/// read-only file: the write at the end would replace it (a rename takes
/// no heed of the file's permissions), or fail after the work.
pub fn refuse_read_only(output: &Path, what: &str) -> Result<(), CliError> {
    if crate::render::output::is_read_only(output) {
        return Err(CliError::input(format!(
            "{}: the {what} is {}",
            output.display(),
            crate::render::output::READ_ONLY
        )));
    }
    Ok(())
}

/// Refuses (exit 2), before any work, an output that is a folder or whose
/// folder is not there: the write at the end would fail after the render.
/// A folder that is there but cannot be written stays a write error
/// (exit 1), reported in the system's words when it happens.
pub fn refuse_missing_folder(output: &Path, what: &str) -> Result<(), CliError> {
    if output.as_os_str() == "-" {
        return Ok(());
    }
    // A link is written through: the folder that counts is its target's.
    let Some(target) = crate::render::output::through_links(output) else {
        return Err(CliError::input(format!(
            "{}: the {what} is {}",
            output.display(),
            crate::render::output::LINK_LOOPS
        )));
    };
    if output.is_dir() {
        return Err(CliError::input(format!(
            "{}: the {what} is a folder, not a file",
            output.display()
        )));
    }
    let dir = match target.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if dir.is_dir() {
        return Ok(());
    }
    Err(CliError::input(format!(
        "{}: the {what} cannot be written: there is no folder {}",
        output.display(),
        dir.display()
    )))
}

/// Refuses (exit 2) an output that is the same file as one of the inputs:
/// writing it would destroy the input.
pub fn refuse_overwriting_inputs(
    output: &Path,
    what: &str,
    inputs: &[(&str, &Path)],
) -> Result<(), CliError> {
    for (name, input) in inputs {
        let (same, shown) = if input.as_os_str() == "-" {
            (is_standard_input(output), "read from standard input".into())
        } else {
            (same_file(output, input), input.display().to_string())
        };
        if same {
            return Err(CliError::input(format!(
                "{}: the {what} is the same file as the {name} {shown}: refusing to overwrite it",
                output.display(),
            )));
        }
    }
    Ok(())
}

/// Whether `path` is the file standard input reads (an input named `-`):
/// the same device and inode as descriptor 0.
fn is_standard_input(path: &Path) -> bool {
    use std::os::fd::AsFd;
    use std::os::unix::fs::MetadataExt;
    let stdin = std::io::stdin()
        .as_fd()
        .try_clone_to_owned()
        .map(std::fs::File::from)
        .and_then(|f| f.metadata());
    match (stdin, std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}
