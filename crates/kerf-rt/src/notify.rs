//! The systemd notify protocol (`Type=notify`, `WatchdogSec=`), through the `sd-notify` crate.
//!
//! Every function is a no-op returning `Ok` when the process was not started by systemd with
//! a notify socket (`NOTIFY_SOCKET` unset). They allocate and make a system call: call them
//! from the main thread, never from the real-time cycle.

use std::io;
use std::time::Duration;

use sd_notify::NotifyState;

/// Tells systemd that start-up is complete (`READY=1`).
pub fn notify_ready() -> io::Result<()> {
    sd_notify::notify(false, &[NotifyState::Ready])
}

/// Tells systemd the service is alive (`WATCHDOG=1`). Prefer [`Watchdog`], which only does so
/// when the real-time cycle has made progress.
pub fn notify_watchdog() -> io::Result<()> {
    sd_notify::notify(false, &[NotifyState::Watchdog])
}

/// Tells systemd the service is shutting down (`STOPPING=1`).
pub fn notify_stopping() -> io::Result<()> {
    sd_notify::notify(false, &[NotifyState::Stopping])
}

/// The watchdog timeout systemd expects keep-alives within (`WATCHDOG_USEC`, for this
/// process according to `WATCHDOG_PID`), or `None` when there is no watchdog. Send
/// keep-alives at least twice per interval.
pub fn watchdog_interval() -> Option<Duration> {
    let mut usec = 0u64;
    if sd_notify::watchdog_enabled(false, &mut usec) && usec > 0 {
        Some(Duration::from_micros(usec))
    } else {
        None
    }
}

/// Keeps the systemd watchdog fed only while the real-time cycle runs.
///
/// The main thread calls [`Watchdog::feed`] periodically (at least twice per
/// [`watchdog_interval`]) with the real-time thread's cycle counter. A keep-alive goes out
/// only if the counter moved since the previous call, so a stalled cycle lets the watchdog
/// expire and systemd restarts the service.
// A copy would be a second instance of its state, silently diverging from the first.
#[allow(missing_copy_implementations)]
#[derive(Debug, Clone, Default)]
pub struct Watchdog {
    last_cycles: Option<u64>,
}

impl Watchdog {
    /// A watchdog that has not seen a counter yet: the first [`Watchdog::feed`] only records
    /// the counter and sends nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records `cycles` and sends `WATCHDOG=1` if it differs from the previous call's value.
    /// Returns whether a keep-alive was due (sent, or a no-op outside systemd).
    pub fn feed(&mut self, cycles: u64) -> io::Result<bool> {
        if self.advanced(cycles) {
            notify_watchdog()?;
            Ok(true)
        } else {
            Ok(false)
        }
    }

    /// The decision part of [`Watchdog::feed`], without sending: whether `cycles` moved since
    /// the previous call (recording it either way).
    pub fn advanced(&mut self, cycles: u64) -> bool {
        let moved = self.last_cycles.is_some_and(|last| last != cycles);
        self.last_cycles = Some(cycles);
        moved
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_moving_counter_is_due() {
        let mut watchdog = Watchdog::new();
        assert!(!watchdog.advanced(5), "first call only records");
        assert!(!watchdog.advanced(5));
        assert!(watchdog.advanced(6));
        assert!(!watchdog.advanced(6));
        assert!(watchdog.advanced(1_000));
        // A counter that wrapped or was reset is still movement.
        assert!(watchdog.advanced(0));
    }
}
