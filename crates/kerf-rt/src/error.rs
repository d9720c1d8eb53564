use std::io;

/// Errors of this crate: invalid arguments, and the few system calls whose failure leaves
/// nothing sensible to fall back to. A system that merely refuses real-time privileges is not
/// an error (see [`crate::RtReport`]).
#[derive(Debug, thiserror::Error)]
pub enum RtError {
    /// A periodic clock needs a period of at least one nanosecond.
    #[error("the cycle period must be at least 1 ns, got {period_ns} ns")]
    InvalidPeriod {
        /// The rejected period.
        period_ns: u64,
    },
    /// `SCHED_FIFO` priorities run from 1 to 99 on Linux.
    #[error("SCHED_FIFO priority {priority} is outside 1..=99")]
    InvalidPriority {
        /// The rejected priority.
        priority: u8,
    },
    /// The CPU index does not name a CPU of this machine.
    #[error("CPU {cpu} does not exist: this machine has {cpu_count} CPUs, numbered from 0")]
    InvalidCpu {
        /// The rejected CPU index.
        cpu: usize,
        /// The number of CPUs the machine is configured with.
        cpu_count: usize,
    },
    /// The calling thread's stack cannot hold the requested pre-fault region.
    #[error(
        "cannot pre-fault {requested_bytes} bytes of stack: the thread has {available_bytes} bytes \
         left (keeping a {margin_bytes}-byte margin)"
    )]
    StackTooSmall {
        /// The requested pre-fault size.
        requested_bytes: usize,
        /// What remains below the current stack position.
        available_bytes: usize,
        /// The part of the remainder kept free for the calls that follow.
        margin_bytes: usize,
    },
    /// A system call failed for a reason other than missing privilege.
    #[error("{call} failed: {source}")]
    Os {
        /// The system call.
        call: &'static str,
        /// The error it returned.
        #[source]
        source: io::Error,
    },
}
