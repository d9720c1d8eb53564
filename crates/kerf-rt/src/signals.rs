//! SIGTERM / SIGINT handling for the daemon's main loop.

use std::io;
use std::sync::atomic::{AtomicI32, Ordering};

use crate::RtError;

/// The one global of the crate, and the only exception to the project's no-globals rule: a
/// signal handler receives nothing but the signal number, so the number it records has to
/// live in a static. 0 means no stop signal has arrived.
static STOP_SIGNAL: AtomicI32 = AtomicI32::new(0);

extern "C" fn record_stop_signal(signal: libc::c_int) {
    // A lock-free atomic store is async-signal-safe. The first signal is kept.
    let _ = STOP_SIGNAL.compare_exchange(0, signal, Ordering::SeqCst, Ordering::SeqCst);
}

const STOP_SIGNALS: [libc::c_int; 2] = [libc::SIGTERM, libc::SIGINT];

/// Asks process `pid` to stop, as `kill PID` does (SIGTERM).
pub fn terminate(pid: u32) -> io::Result<()> {
    let pid =
        libc::pid_t::try_from(pid).map_err(|_| io::Error::from(io::ErrorKind::InvalidInput))?;
    // SAFETY: kill(2) has no memory-safety preconditions.
    if unsafe { libc::kill(pid, libc::SIGTERM) } == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

/// SIGTERM and SIGINT handlers that record the signal instead of ending the process, so the
/// daemon can stop the axes and notify systemd before it exits.
///
/// Dropping the value puts the previous handlers back. The recorded signal is process-wide:
/// two `Signals` values alive at once see the same state.
pub struct Signals {
    previous: [libc::sigaction; 2],
}

impl Signals {
    /// Installs the handlers (with `SA_RESTART`, so other threads' blocking calls are not cut
    /// short) and clears any previously recorded signal.
    pub fn install() -> Result<Self, RtError> {
        STOP_SIGNAL.store(0, Ordering::SeqCst);
        // SAFETY: an all-zero sigaction is a valid value to initialise and to be overwritten.
        let mut previous: [libc::sigaction; 2] = unsafe { std::mem::zeroed() };
        for (i, &signal) in STOP_SIGNALS.iter().enumerate() {
            // SAFETY: as above.
            let mut action: libc::sigaction = unsafe { std::mem::zeroed() };
            let handler: extern "C" fn(libc::c_int) = record_stop_signal;
            action.sa_sigaction = handler as usize;
            action.sa_flags = libc::SA_RESTART;
            // SAFETY: `action.sa_mask` is a valid sigset_t to empty.
            unsafe { libc::sigemptyset(&mut action.sa_mask) };
            // SAFETY: both pointers are valid; the handler only does an atomic store.
            if unsafe { libc::sigaction(signal, &action, &mut previous[i]) } != 0 {
                let source = io::Error::last_os_error();
                for (j, &installed) in STOP_SIGNALS.iter().enumerate().take(i) {
                    // SAFETY: restores a handler obtained from sigaction just above.
                    unsafe { libc::sigaction(installed, &previous[j], std::ptr::null_mut()) };
                }
                return Err(RtError::Os {
                    call: "sigaction",
                    source,
                });
            }
        }
        Ok(Self { previous })
    }

    /// The signal (SIGTERM or SIGINT) that asked the process to stop, if one arrived since
    /// [`Signals::install`].
    pub fn stop_requested(&self) -> Option<i32> {
        match STOP_SIGNAL.load(Ordering::SeqCst) {
            0 => None,
            signal => Some(signal),
        }
    }
}

impl Drop for Signals {
    fn drop(&mut self) {
        for (i, &signal) in STOP_SIGNALS.iter().enumerate() {
            // SAFETY: restores the handler that was in place before `install`.
            unsafe { libc::sigaction(signal, &self.previous[i], std::ptr::null_mut()) };
        }
    }
}

impl std::fmt::Debug for Signals {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Signals")
            .field("stop_requested", &self.stop_requested())
            .finish()
    }
}
