//! How a process of this project ends when a signal ends it: never with a temporary file left
//! behind, never with a bare SIGBUS.
//!
//! Every temporary named by `atomic::temporary_path` is noted here, so that SIGINT and SIGTERM
//! can remove this process's own before it ends; a run finds the ones of dead processes by the
//! owner's pid in their names (`atomic::remove_dead_temporaries`). Every mapping made by
//! `mapping::map_range` is noted with a message naming its file, so that a SIGBUS from a mapped
//! file truncated by another process ends the process with [`IO_EXIT_CODE`] and that message,
//! written by an async-signal-safe handler (`write`, then `_exit`).

use std::collections::{HashMap, HashSet};
use std::fs::File;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicPtr, AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard, OnceLock};

/// The exit code of a process whose mapped file changed: sysexits' EX_IOERR, as
/// `reducem::exit_code::IO`.
pub const IO_EXIT_CODE: i32 = 74;

static TEMPORARIES: Mutex<Option<HashSet<PathBuf>>> = Mutex::new(None);

/// Notes `path` as a temporary this process may create.
pub(crate) fn note_temporary(path: &Path) {
    let path = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    temporaries().get_or_insert_with(HashSet::new).insert(path);
}

fn temporaries() -> MutexGuard<'static, Option<HashSet<PathBuf>>> {
    TEMPORARIES
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Removes every temporary this process named, for a process about to end. The list stays
/// locked afterwards, so no thread can name (and then create) another one meanwhile.
pub fn remove_own_temporaries() {
    let guard = temporaries();
    for path in guard.iter().flatten() {
        let _ = std::fs::remove_file(path);
    }
    std::mem::forget(guard);
}

/// For the tools (`reducem`): SIGINT and SIGTERM remove this process's temporaries, then end it
/// as the signal would have; a SIGBUS from a changed mapped file ends it with a message.
pub fn install_for_tool() -> io::Result<()> {
    install_bus_handler()?;
    let mut signals = signal_hook::iterator::Signals::new([
        signal_hook::consts::SIGINT,
        signal_hook::consts::SIGTERM,
    ])?;
    std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            if let Some(signal) = signals.forever().next() {
                remove_own_temporaries();
                let _ = signal_hook::low_level::emulate_default_handler(signal);
            }
        })?;
    Ok(())
}

/// Whether process `pid` exists (on this host): a temporary named with a live owner's pid is
/// being written.
pub fn process_alive(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    if pid <= 0 {
        return false;
    }
    signal_zero(pid) || io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// `kill(pid, 0)`: whether a signal could be sent to `pid` (sends none).
#[allow(unsafe_code)]
fn signal_zero(pid: libc::pid_t) -> bool {
    // SAFETY: signal 0 only checks that the process exists and may be signalled.
    unsafe { libc::kill(pid, 0) == 0 }
}

/// One mapping, as the SIGBUS handler reads it: its address range, when it was made (the
/// latest mapping over an address is the live one) and its message.
struct MappedRange {
    start: AtomicUsize,
    end: AtomicUsize,
    serial: AtomicUsize,
    message: AtomicPtr<u8>,
    message_len: AtomicUsize,
}

impl MappedRange {
    const fn new() -> MappedRange {
        MappedRange {
            start: AtomicUsize::new(0),
            end: AtomicUsize::new(0),
            serial: AtomicUsize::new(0),
            message: AtomicPtr::new(std::ptr::null_mut()),
            message_len: AtomicUsize::new(0),
        }
    }
}

/// The latest mappings, in a ring: a process maps few files at once (a ReduceM file, a ray
/// file, an input window), so the live ones are among the last 64.
const MAPPED_SLOTS: usize = 64;
static MAPPED: [MappedRange; MAPPED_SLOTS] = [const { MappedRange::new() }; MAPPED_SLOTS];
static MAPPINGS_MADE: AtomicUsize = AtomicUsize::new(0);

/// Notes that `length` bytes at `start` map `file`, so that a SIGBUS there names it.
pub(crate) fn note_mapping(start: *const u8, length: usize, file: &File) {
    let message = bus_message(file);
    let serial = MAPPINGS_MADE.fetch_add(1, Ordering::Relaxed) + 1;
    let slot = &MAPPED[serial % MAPPED_SLOTS];
    slot.end.store(0, Ordering::Release);
    slot.start.store(start as usize, Ordering::Release);
    slot.message
        .store(message.as_ptr().cast_mut(), Ordering::Release);
    slot.message_len.store(message.len(), Ordering::Release);
    slot.serial.store(serial, Ordering::Release);
    slot.end
        .store((start as usize).saturating_add(length), Ordering::Release);
}

/// The message for a SIGBUS in a mapping of `file`, made once per path and kept for the life
/// of the process (the handler may read it at any time).
fn bus_message(file: &File) -> &'static [u8] {
    static MESSAGES: OnceLock<Mutex<HashMap<PathBuf, &'static [u8]>>> = OnceLock::new();
    let path = path_of(file);
    let mut messages = MESSAGES
        .get_or_init(Mutex::default)
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    messages.entry(path.clone()).or_insert_with(|| {
        let program = std::env::args_os()
            .next()
            .map(PathBuf::from)
            .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .unwrap_or_default();
        let text = format!(
            "{program}: error: {} changed while it was mapped (truncated or rewritten in place \
             by another process); files are replaced by rename, never modified in place: let \
             the other process finish, then run the command again\n",
            path.display()
        );
        Box::leak(text.into_bytes().into_boxed_slice())
    })
}

/// The path `file` was opened with, as the kernel knows it.
fn path_of(file: &File) -> PathBuf {
    use std::os::fd::AsRawFd;
    std::fs::read_link(format!("/proc/self/fd/{}", file.as_raw_fd()))
        .unwrap_or_else(|_| PathBuf::from("a mapped file"))
}

/// Installs the SIGBUS handler.
#[allow(unsafe_code)]
pub fn install_bus_handler() -> io::Result<()> {
    // SAFETY: a zeroed sigaction is a valid empty one; the handler only reads atomics and
    // calls async-signal-safe functions (write, _exit, signal).
    let installed = unsafe {
        let mut action: libc::sigaction = std::mem::zeroed();
        action.sa_sigaction = on_bus_error as *const () as libc::sighandler_t;
        action.sa_flags = libc::SA_SIGINFO;
        libc::sigemptyset(&mut action.sa_mask);
        libc::sigaction(libc::SIGBUS, &action, std::ptr::null_mut())
    };
    match installed {
        0 => Ok(()),
        _ => Err(io::Error::last_os_error()),
    }
}

/// The SIGBUS handler: the message of the latest mapping holding the faulting address, then
/// `_exit`; a fault outside every noted mapping gets the default action back and faults again.
#[allow(unsafe_code)]
extern "C" fn on_bus_error(_: libc::c_int, info: *mut libc::siginfo_t, _: *mut libc::c_void) {
    // SAFETY: the kernel passes a valid siginfo for a SA_SIGINFO handler of SIGBUS.
    let address = unsafe { (*info).si_addr() } as usize;
    let mapping = MAPPED
        .iter()
        .filter(|slot| {
            let start = slot.start.load(Ordering::Acquire);
            start <= address && address < slot.end.load(Ordering::Acquire)
        })
        .max_by_key(|slot| slot.serial.load(Ordering::Acquire));
    match mapping {
        // SAFETY: the message is leaked, so it lives as long as the process; write and _exit
        // are async-signal-safe.
        Some(slot) => unsafe {
            let message = slot.message.load(Ordering::Acquire);
            let length = slot.message_len.load(Ordering::Acquire);
            libc::write(libc::STDERR_FILENO, message.cast(), length);
            libc::_exit(IO_EXIT_CODE);
        },
        // SAFETY: restoring the default action is async-signal-safe.
        None => unsafe {
            libc::signal(libc::SIGBUS, libc::SIG_DFL);
        },
    }
}
