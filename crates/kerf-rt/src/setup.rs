//! Real-time set-up of the calling thread: memory lock, stack pre-fault, SCHED_FIFO, affinity.

use std::io;

use crate::RtError;

/// What [`rt_setup`] should do for the calling thread.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RtConfig {
    /// `SCHED_FIFO` priority, 1..=99; `None` keeps the thread's current (normal) policy.
    pub priority: Option<u8>,
    /// The CPU to pin the thread to (0-based); `None` leaves the affinity as it is.
    pub cpu: Option<usize>,
    /// Bytes of stack to touch below the caller's frame, so that the cycle never takes a
    /// page fault on its stack (with memory locked, the touched pages stay resident).
    pub prefault_stack_bytes: usize,
}

impl Default for RtConfig {
    /// Priority 80, no pinning, 256 KiB of stack.
    fn default() -> Self {
        Self {
            priority: Some(80),
            cpu: None,
            prefault_stack_bytes: 256 * 1024,
        }
    }
}

/// What [`rt_setup`] achieved. A `false` field is explained by a line in `messages`, except
/// when the item was not requested (`priority` or `cpu` of `None`).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RtReport {
    /// `mlockall(MCL_CURRENT | MCL_FUTURE)` succeeded.
    pub mlocked: bool,
    /// The thread runs under `SCHED_FIFO` at the requested priority.
    pub fifo: bool,
    /// The thread is pinned to the requested CPU.
    pub affinity: bool,
    /// The thread's timer slack is 1 ns (it defaults to 50 µs for normal threads, which
    /// delays every wake-up of a thread left under the normal scheduler by that much;
    /// `SCHED_FIFO` threads ignore it).
    pub timer_slack: bool,
    /// One line per refused or skipped step, for the daemon to log once.
    pub messages: Vec<String>,
}

impl RtReport {
    /// Memory locked and `SCHED_FIFO` in force: the minimum for real-time guarantees.
    pub fn is_realtime(&self) -> bool {
        self.mlocked && self.fifo
    }
}

/// Stack kept free below the pre-faulted region for the calls that follow.
const STACK_MARGIN_BYTES: usize = 64 * 1024;
const PREFAULT_CHUNK_BYTES: usize = 4096;

/// Prepares the calling thread for the real-time cycle.
///
/// In order: validates the arguments (before changing anything), pins the thread to
/// `cpu` (`sched_setaffinity`), locks all current and future memory (`mlockall`), touches
/// `prefault_stack_bytes` of stack, sets the thread's timer slack to 1 ns
/// (`prctl(PR_SET_TIMERSLACK)`, no privilege needed), and switches the thread to `SCHED_FIFO` at `priority`
/// (`pthread_setschedparam`).
///
/// A system call that fails (typically `EPERM` without `CAP_SYS_NICE`/`CAP_IPC_LOCK` or
/// `RLIMIT_RTPRIO`, `ENOMEM` under a small `RLIMIT_MEMLOCK`, `EINVAL` for a CPU outside the
/// thread's cpuset) is not an error: the step is reported `false` with a message and the
/// others still run. Errors are only for invalid arguments: a priority outside 1..=99, a CPU
/// index the machine does not have, a pre-fault region larger than the thread's stack.
///
/// Note that once `MCL_FUTURE` is in force, every later allocation is locked too; under a
/// finite `RLIMIT_MEMLOCK` an allocation past the limit fails. The systemd unit sets
/// `LimitMEMLOCK=infinity`.
pub fn rt_setup(config: &RtConfig) -> Result<RtReport, RtError> {
    if let Some(priority) = config.priority
        && !(1..=99).contains(&priority)
    {
        return Err(RtError::InvalidPriority { priority });
    }
    if let Some(cpu) = config.cpu {
        let cpu_count = configured_cpu_count()?;
        if cpu >= cpu_count || cpu >= libc::CPU_SETSIZE as usize {
            return Err(RtError::InvalidCpu { cpu, cpu_count });
        }
    }
    let available_bytes = stack_bytes_left()?;
    if config
        .prefault_stack_bytes
        .saturating_add(STACK_MARGIN_BYTES)
        > available_bytes
    {
        return Err(RtError::StackTooSmall {
            requested_bytes: config.prefault_stack_bytes,
            available_bytes,
            margin_bytes: STACK_MARGIN_BYTES,
        });
    }

    let mut report = RtReport::default();

    if let Some(cpu) = config.cpu {
        match pin_to_cpu(cpu) {
            Ok(()) => report.affinity = true,
            Err(e) => report
                .messages
                .push(format!("CPU affinity to CPU {cpu} refused: {e}")),
        }
    }

    // SAFETY: mlockall takes flags only.
    if unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) } == 0 {
        report.mlocked = true;
    } else {
        let e = io::Error::last_os_error();
        report.messages.push(format!(
            "mlockall refused ({e}): memory may be paged out; needs CAP_IPC_LOCK or a large \
             enough RLIMIT_MEMLOCK"
        ));
    }

    prefault_stack(config.prefault_stack_bytes);

    // SAFETY: PR_SET_TIMERSLACK takes an integer argument only.
    if unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong) } == 0 {
        report.timer_slack = true;
    } else {
        let e = io::Error::last_os_error();
        report.messages.push(format!(
            "timer slack unchanged ({e}): normal-scheduler wake-ups stay late"
        ));
    }

    match config.priority {
        Some(priority) => match set_fifo(priority) {
            Ok(()) => report.fifo = true,
            Err(e) => report.messages.push(format!(
                "SCHED_FIFO priority {priority} refused ({e}): running under the normal \
                 scheduler; needs CAP_SYS_NICE or RLIMIT_RTPRIO >= {priority}"
            )),
        },
        None => report
            .messages
            .push("SCHED_FIFO not requested (no priority configured)".to_owned()),
    }

    Ok(report)
}

fn configured_cpu_count() -> Result<usize, RtError> {
    // SAFETY: sysconf takes a constant only.
    let n = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_CONF) };
    if n < 1 {
        return Err(RtError::Os {
            call: "sysconf(_SC_NPROCESSORS_CONF)",
            source: io::Error::last_os_error(),
        });
    }
    Ok(n as usize)
}

/// Bytes between the caller's stack position and the lowest address of the thread's stack.
fn stack_bytes_left() -> Result<usize, RtError> {
    let marker = 0u8;
    let here = std::ptr::from_ref(std::hint::black_box(&marker)) as usize;
    let mut attr = std::mem::MaybeUninit::<libc::pthread_attr_t>::uninit();
    // SAFETY: pthread_getattr_np initialises `attr` on success; it is destroyed below.
    let rc = unsafe { libc::pthread_getattr_np(libc::pthread_self(), attr.as_mut_ptr()) };
    if rc != 0 {
        return Err(RtError::Os {
            call: "pthread_getattr_np",
            source: io::Error::from_raw_os_error(rc),
        });
    }
    let mut addr: *mut libc::c_void = std::ptr::null_mut();
    let mut size: libc::size_t = 0;
    // SAFETY: `attr` was initialised by pthread_getattr_np; `addr` and `size` are writable.
    let rc = unsafe { libc::pthread_attr_getstack(attr.as_ptr(), &mut addr, &mut size) };
    // SAFETY: `attr` was initialised and is not used afterwards.
    unsafe { libc::pthread_attr_destroy(attr.as_mut_ptr()) };
    if rc != 0 {
        return Err(RtError::Os {
            call: "pthread_attr_getstack",
            source: io::Error::from_raw_os_error(rc),
        });
    }
    // The stack grows down from addr + size to addr.
    Ok(here.saturating_sub(addr as usize))
}

/// Touches `bytes` of stack below the caller, one page-sized frame at a time.
fn prefault_stack(bytes: usize) {
    #[inline(never)]
    fn touch(remaining: usize) {
        let mut page = [0u8; PREFAULT_CHUNK_BYTES];
        // black_box keeps the writes (and so the page faults) from being optimised away.
        std::hint::black_box(&mut page);
        if remaining > PREFAULT_CHUNK_BYTES {
            touch(remaining - PREFAULT_CHUNK_BYTES);
        }
        // Using the frame after the call keeps this from becoming a tail call.
        std::hint::black_box(&page);
    }
    if bytes > 0 {
        touch(bytes);
    }
}

fn pin_to_cpu(cpu: usize) -> io::Result<()> {
    // SAFETY: an all-zero cpu_set_t is a valid empty set.
    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    // SAFETY: `cpu` < CPU_SETSIZE was checked by the caller.
    unsafe { libc::CPU_SET(cpu, &mut set) };
    // SAFETY: pid 0 is the calling thread; `set` is a valid cpu_set_t of the given size.
    let rc = unsafe { libc::sched_setaffinity(0, size_of::<libc::cpu_set_t>(), &set) };
    if rc == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

fn set_fifo(priority: u8) -> io::Result<()> {
    let param = libc::sched_param {
        sched_priority: libc::c_int::from(priority),
    };
    // SAFETY: `param` is a valid sched_param; the thread is the calling one.
    let rc = unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) };
    if rc == 0 {
        Ok(())
    } else {
        Err(io::Error::from_raw_os_error(rc))
    }
}

/// Sets the calling thread's timer slack to 1 ns (`prctl(PR_SET_TIMERSLACK)`, no
/// privilege needed), so that its short sleeps and timed waits end when asked instead of
/// up to 50 µs later (the default slack of a normal thread). For threads outside the
/// cycle that wait for it in short steps (the daemon's control thread). `Err` with the
/// system's reason if refused.
pub fn fine_timer_slack() -> io::Result<()> {
    // SAFETY: PR_SET_TIMERSLACK takes an integer argument only.
    if unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong) } == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

/// Keeps the calling thread off `cpu`, the real-time cycle's CPU: its affinity becomes
/// the CPUs it may run on now, without `cpu` (`sched_getaffinity`/`sched_setaffinity`).
/// For the daemon's threads outside the cycle (control, planning), which the cycle would
/// otherwise preempt there, and which would in turn delay nothing of the cycle's but
/// their own answers. `Ok(false)` leaves the affinity as it is: `cpu` is not among the
/// thread's CPUs, or is the only one. Threads the caller starts afterwards inherit it.
pub fn avoid_cpu(cpu: usize) -> io::Result<bool> {
    if cpu >= libc::CPU_SETSIZE as usize {
        return Ok(false);
    }
    // SAFETY: an all-zero cpu_set_t is a valid empty set.
    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    // SAFETY: pid 0 is the calling thread; `set` is a writable cpu_set_t of the given size.
    if unsafe { libc::sched_getaffinity(0, size_of::<libc::cpu_set_t>(), &mut set) } != 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: `set` is a valid cpu_set_t; `cpu` < CPU_SETSIZE.
    if !unsafe { libc::CPU_ISSET(cpu, &set) } || unsafe { libc::CPU_COUNT(&set) } < 2 {
        return Ok(false);
    }
    // SAFETY: as above.
    unsafe { libc::CPU_CLR(cpu, &mut set) };
    // SAFETY: pid 0 is the calling thread; `set` is a valid cpu_set_t of the given size.
    if unsafe { libc::sched_setaffinity(0, size_of::<libc::cpu_set_t>(), &set) } != 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(true)
}
