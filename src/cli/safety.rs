//! What keeps the CLI's files safe: signals that stop a render or a write
//! without leaving a temporary file, and outputs that would overwrite an
//! input.

use std::path::Path;

use super::CliError;
use crate::render::CancelToken;
use crate::render::output::{interrupt_writes, remove_temp_files};

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

/// For commands without a render to stop (`compare`, `bench`): SIGINT,
/// SIGTERM and SIGHUP too remove the temporary file being written and end
/// the process at once, as the other fatal signals do (see
/// [`handle_signals`]).
pub fn remove_temp_files_on_signals() {
    // SAFETY: as in handle_signals.
    unsafe {
        for signal in FATAL
            .into_iter()
            .chain([libc::SIGINT, libc::SIGTERM, libc::SIGHUP])
        {
            install_remove_and_die(signal);
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

/// Refuses (exit 2), before any work, an output that is a folder or whose
/// folder is not there: the write at the end would fail after the render.
/// A folder that is there but cannot be written stays a write error
/// (exit 1), reported in the system's words when it happens.
pub fn refuse_missing_folder(output: &Path, what: &str) -> Result<(), CliError> {
    if output.as_os_str() == "-" {
        return Ok(());
    }
    if output.is_dir() {
        return Err(CliError::input(format!(
            "{}: the {what} is a folder, not a file",
            output.display()
        )));
    }
    let dir = match output.parent() {
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
        if same_file(output, input) {
            return Err(CliError::input(format!(
                "{}: the {what} is the same file as the {name} {}: refusing to overwrite it",
                output.display(),
                input.display()
            )));
        }
    }
    Ok(())
}
