//! The operating-system side of the `kerfd` real-time daemon, kept out of the motion core.
//!
//! - [`PeriodicClock`]: an absolute-deadline periodic loop on `CLOCK_MONOTONIC`. It sleeps
//!   with `clock_nanosleep(TIMER_ABSTIME)`, reports each cycle's wake-up latency, and after a
//!   missed deadline skips ahead to the next future one (no burst of catch-up cycles).
//! - [`rt_setup`]: locks memory, pre-faults the stack, sets `SCHED_FIFO` and CPU affinity for
//!   the calling thread. A refusal by the system (no privilege) is reported in [`RtReport`],
//!   not raised, so the daemon can warn once and run without real-time guarantees.
//! - [`CpuLatencyRequest`]: holds a CPU wake-up latency request (PM QoS), so that idle
//!   CPUs wake threads outside the cycle without the exit from a deep idle state.
//! - [`Signals`]: SIGTERM / SIGINT handlers that only set an atomic.
//! - [`notify_ready`], [`notify_watchdog`], [`notify_stopping`], [`watchdog_interval`] and
//!   [`Watchdog`]: the systemd notify protocol; no-ops outside systemd.
//!
//! Linux only. Nothing here allocates, locks or logs in [`PeriodicClock::wait_next`], the one
//! call made from the real-time cycle; everything else runs at start-up or on the main thread.

mod clock;
mod error;
mod latency;
mod notify;
mod setup;
mod signals;

pub use clock::{PeriodicClock, Tick, now_ns};
pub use error::RtError;
pub use latency::{CPU_LATENCY_FILE, CpuLatencyRequest};
pub use notify::{Watchdog, notify_ready, notify_stopping, notify_watchdog, watchdog_interval};
pub use setup::{RtConfig, RtReport, avoid_cpu, fine_timer_slack, rt_setup};
pub use signals::{Signals, terminate};
