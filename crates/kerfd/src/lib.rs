//! The interpolator daemon's threads, for `kerfd` and `kerf run --embedded`.
//!
//! ```text
//!  kerf/<m>/moves ──► planning thread ──ring──► real-time thread ──ring──► publishing
//!                     (checks, kerf-plan)        (Cycle: kerf-pipeline's      helper ──►
//!                                                 Interpolator, one period)   kerf/<m>/setpoints
//!  kerf/<m>/control ◄─► control thread ──ring──►  commands
//!                          ▲  └───────────◄ring◄── status snapshots
//! ```
//!
//! - The real-time thread builds everything before its first cycle (rings, the motion
//!   core, the tracker, the estimate ring), locks memory and asks for SCHED_FIFO; then
//!   every period it takes commands and planned items without blocking, steps, and hands
//!   one setpoint to the publishing helper (`publish`: iceoryx2 allocates on every
//!   publish, so the cycle never calls it). It never allocates, locks or logs.
//! - The planning thread converts and checks every message (`kerf_proto`), checks the
//!   travel, plans with the same code as `kerf sim` (`kerf_pipeline::plan_input`) and
//!   fills the ring; it waits when the ring is full, so backpressure reaches the planner
//!   process through the flow-control window.
//! - The control thread answers requests with the latest snapshot and turns commands into
//!   items of the command ring.

#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod cli;
mod control;
mod cycle_thread;
mod dump_writer;
pub mod fates;
pub mod fault_text;
pub mod ipc;
pub mod machine;
mod planning;
pub mod publish;
mod status;
pub mod timing;
pub mod worker;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use kerf_proto::{
    ControlCommand, MachineState, MoveMsg, REASON_NOT_ALLOWED, REASON_OK, Resolved, Response,
    SetpointMsg, StatusMsg, StreamCheck, StreamError,
};

use kerf_config::Config;

use control::control_thread;
pub use control::{dump_patience, reset_patience};
use cycle_thread::cycle_thread;
pub use planning::planning_thread;
use worker::{
    Cycle, CycleCommand, Incoming, Planning, PlanningCounters, Refusal, RtItem, Snapshot,
};

/// Planned items the ring from the planning thread to the cycle holds: a few seconds of
/// dense code ahead of the motion queue.
pub const PLANNED_RING: usize = 8192;

/// Commands the ring to the cycle holds.
pub(crate) const COMMAND_RING: usize = 64;

/// Snapshots the ring from the cycle holds (the control thread drains it every poll).
pub(crate) const STATUS_RING: usize = 256;

/// How often the planning and control threads poll when there is nothing to do.
pub(crate) const POLL: Duration = Duration::from_micros(200);

/// How long a program may go without a message before the planning thread checks that
/// its sender is still alive.
pub(crate) const SENDER_CHECK_AFTER: Duration = Duration::from_millis(50);

/// Stack bytes the cycle thread touches before its first cycle.
pub(crate) const PREFAULT_STACK_BYTES: usize = 256 * 1024;

/// What went wrong starting the daemon.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// Another daemon serves this machine.
    #[error(
        "a kerfd is already running for machine `{0}` (its control service exists); stop it first, or give this machine another `machine` name"
    )]
    AlreadyRunning(String),
    /// The configuration cannot be run by the daemon.
    #[error("{0}")]
    Config(String),
    /// Shared memory or threads could not be set up.
    #[error("{0}")]
    Setup(String),
    /// A node, service or port of the machine's iceoryx2 services could not be made.
    #[error("{0}")]
    Ipc(#[from] ipc::IpcError),
}

/// What the real-time setup achieved.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RtStatus {
    /// SCHED_FIFO and mlockall both took effect.
    pub rt: bool,
    /// The CPU wake-up latency request in force while the daemon runs, µs
    /// (`daemon.cpu_latency_us`); `None` when not requested or refused.
    pub cpu_latency_us: Option<u32>,
    /// What was refused, for the log.
    pub messages: Vec<String>,
}

/// What the daemon's threads and its owner share: the flags that stop them, the cycle's
/// counters and timing, and the planning counters. Cloning shares them.
#[derive(Clone, Default)]
pub(crate) struct Shared {
    /// Every thread ends (after the cycle has stopped, or when joining).
    pub(crate) stop: Arc<AtomicBool>,
    /// A jerk-limited stop on the path is asked for, after which the daemon ends.
    pub(crate) shutdown: Arc<AtomicBool>,
    /// Cycles run so far.
    pub(crate) cycles: Arc<AtomicU64>,
    /// Periods the cycle missed.
    pub(crate) overruns: Arc<AtomicU64>,
    /// The daemon has stopped.
    pub(crate) done: Arc<AtomicBool>,
    /// The cycle runs with real-time scheduling and locked memory.
    pub(crate) rt_ok: Arc<AtomicBool>,
    /// The cycle's timing, once it has ended.
    pub(crate) timing: Arc<Mutex<Option<timing::TimingSummary>>>,
    /// The planning thread's counters and the programs' fates.
    pub(crate) counters: PlanningCounters,
}

/// A running daemon.
pub struct Daemon {
    machine: String,
    shared: Shared,
    threads: Vec<JoinHandle<Result<(), String>>>,
    rt: RtStatus,
    /// Held while the daemon runs; dropping it withdraws the request.
    _cpu_latency: Option<kerf_rt::CpuLatencyRequest>,
}

impl Daemon {
    /// The machine served.
    pub fn machine(&self) -> &str {
        &self.machine
    }

    /// Cycles run so far (the watchdog feeds systemd only while this advances).
    pub fn cycles(&self) -> u64 {
        self.shared.cycles.load(Ordering::Acquire)
    }

    /// What the real-time setup achieved.
    pub fn rt(&self) -> &RtStatus {
        &self.rt
    }

    /// The cycle's wake-up latency and compute time, once the cycle has ended.
    pub fn timing(&self) -> Option<timing::TimingSummary> {
        self.shared.timing.lock().ok().and_then(|t| *t)
    }

    /// Asks for a jerk-limited stop on the path, after which the daemon ends.
    pub fn shutdown(&self) {
        self.shared.shutdown.store(true, Ordering::Release);
    }

    /// `true` once the daemon has stopped (after [`shutdown`](Self::shutdown), or a
    /// thread failed).
    pub fn finished(&self) -> bool {
        self.shared.done.load(Ordering::Acquire) || self.threads.iter().any(|t| t.is_finished())
    }

    /// Waits for every thread; the first error of any.
    pub fn join(mut self) -> Result<(), String> {
        self.stop_all()
    }

    fn stop_all(&mut self) -> Result<(), String> {
        self.shared.shutdown.store(true, Ordering::Release);
        let mut result = Ok(());
        // The cycle ends on its own after the stop; the other threads follow it.
        for t in self.threads.drain(..) {
            let r = t
                .join()
                .unwrap_or_else(|_| Err("a daemon thread panicked".to_string()));
            if result.is_ok() {
                result = r;
            }
            self.shared.stop.store(true, Ordering::Release);
        }
        result
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        if !self.threads.is_empty() {
            let _ = self.stop_all();
        }
    }
}

/// The period range the daemon runs, checked before anything starts.
pub(crate) fn check_period(config: &Config) -> Result<(), StartError> {
    let range = kerf_config::DAEMON_PERIOD_RANGE_US;
    if range.contains(&config.period_us) {
        Ok(())
    } else {
        Err(StartError::Config(format!(
            "`period_us` = {} is outside the daemon's range ({} to {} µs); `kerf sim` accepts it, the real-time cycle does not",
            config.period_us,
            range.start(),
            range.end()
        )))
    }
}

/// The drives the daemon can run: simulated ones, EtherCAT drives in cyclic synchronous
/// position for the axes, with or without distributed clocks, and the spindle's EtherCAT
/// drive in cyclic synchronous velocity (`axis = "s"`). A position axis's drive
/// configured for velocity (`mode = "csv"`) is refused before anything starts (the
/// configuration refuses it too): running it as a position axis would not be what the
/// file says.
pub(crate) fn check_drives(config: &Config) -> Result<(), StartError> {
    let Some(bus) = config.ethercat() else {
        return Ok(());
    };
    // Cyclic synchronous velocity is the spindle's drive's mode (its velocity setpoints
    // come from the machine's spindle); an axis's drive runs in position.
    match bus.drives.iter().find(|d| {
        d.mode != kerf_config::ethercat::DriveMode::Csp
            && d.axis_index != kerf_config::ethercat::SPINDLE_AXIS_INDEX
    }) {
        None => Ok(()),
        Some(d) => Err(StartError::Config(format!(
            "the EtherCAT drive at position {} (axis {}) is configured for cyclic synchronous velocity (`mode = \"csv\"`), which kerfd runs only for the spindle's drive (`axis = \"s\"`): an axis's drive runs in \"csp\"",
            d.position,
            kerf_geom::AXIS_NAMES
                .get(d.axis_index)
                .copied()
                .unwrap_or('?')
        ))),
    }
}

/// Starts the daemon for the machine of `config`: creates the services (after cleaning
/// the resources of dead processes), then the three threads. Returns once the cycle runs
/// and every port is up.
pub fn start(config: &Config, real_time: bool) -> Result<Daemon, StartError> {
    start_with(config, real_time, false)
}

/// [`start`], with `test_faults`: the control service accepts `REQUEST_INJECT`, the
/// faults injected below the motion core for the tests of the safety layer (`kerfd
/// --test-faults`; never on a machine).
pub fn start_with(
    config: &Config,
    real_time: bool,
    test_faults: bool,
) -> Result<Daemon, StartError> {
    check_period(config)?;
    check_drives(config)?;
    let cleaned = ipc::clean_dead_nodes();
    if cleaned > 0 {
        tracing::info!("removed the shared-memory resources of {cleaned} dead process(es)");
    }
    let unfinished = ipc::remove_unfinished_services();
    if unfinished > 0 {
        tracing::info!("removed {unfinished} service file(s) a killed process left unfinished");
    }
    let machine = config.machine.clone();
    let window = config.daemon.move_window as usize;

    let shared = Shared::default();
    // The switches start as the configuration says.
    shared
        .counters
        .single_block
        .store(config.operator.single_block, Ordering::Release);

    let (items_tx, items_rx) = rtrb::RingBuffer::<RtItem>::new(PLANNED_RING);
    let (commands_tx, commands_rx) = rtrb::RingBuffer::<CycleCommand>::new(COMMAND_RING);
    let (status_tx, status_rx) = rtrb::RingBuffer::<Snapshot>::new(STATUS_RING);
    let (dump_rings, dump_writer) = worker::dump_rings();
    let cycle_parts = (items_rx, commands_rx, status_tx, dump_rings);
    let control_ports = control::ControlPorts {
        commands: commands_tx,
        status: status_rx,
        dumps: dump_writer,
    };

    // Each thread reports once its ports are up (or why they are not).
    let (ready_tx, ready_rx) = std::sync::mpsc::channel::<Result<Option<RtStatus>, StartError>>();

    let mut threads = Vec::new();
    // The cycle's CPU (`daemon.cpu`, with real-time scheduling) is the cycle's: the
    // control and planning threads keep off it, where the cycle would preempt them (a
    // request's answer then waits for the cycle's compute and publishing).
    let cycle_cpu = config.daemon.cpu.filter(|_| real_time).map(|c| c as usize);
    let off_cycle_cpu = move || {
        if let Some(cpu) = cycle_cpu
            && let Err(e) = kerf_rt::avoid_cpu(cpu)
        {
            tracing::warn!("cannot keep this thread off the cycle's CPU {cpu}: {e}");
        }
    };

    // The control thread first: its service tells whether another daemon runs.
    {
        let (config, shared, ready) = (config.clone(), shared.clone(), ready_tx.clone());
        threads.push(spawn("kerfd-control", move || {
            off_cycle_cpu();
            control_thread(&config, shared, test_faults, ready, control_ports)
        })?);
    }
    wait_ready(&ready_rx)?;

    {
        let (config, machine, ready) = (config.clone(), machine.clone(), ready_tx.clone());
        let (stop, counters) = (shared.stop.clone(), shared.counters.clone());
        threads.push(spawn("kerfd-planning", move || {
            off_cycle_cpu();
            planning_thread(&config, &machine, window, ready, stop, counters, items_tx)
        })?);
    }
    wait_ready(&ready_rx)?;

    let mut rt_status: RtStatus;
    {
        let (config, shared, ready) = (config.clone(), shared.clone(), ready_tx.clone());
        threads.push(spawn("kerfd-cycle", move || {
            cycle_thread(&config, real_time, shared, ready, cycle_parts)
        })?);
        rt_status = wait_ready(&ready_rx)?.unwrap_or_default();
    }
    // With real-time scheduling, idle CPUs kept quick to wake (see kerf_rt's latency
    // module): the cycle wakes on its own timer, the threads around it do not.
    let cpu_latency = if real_time {
        let latency_us = config.daemon.cpu_latency_us;
        match kerf_rt::CpuLatencyRequest::new(latency_us) {
            Ok(request) => {
                rt_status.cpu_latency_us = Some(latency_us);
                Some(request)
            }
            Err(e) => {
                rt_status.messages.push(format!(
                    "CPU wake-up latency of {latency_us} µs refused ({}: {e}): threads \
                     outside the cycle may wake late from idle CPUs",
                    kerf_rt::CPU_LATENCY_FILE
                ));
                None
            }
        }
    } else {
        None
    };

    Ok(Daemon {
        machine,
        shared,
        threads,
        rt: rt_status,
        _cpu_latency: cpu_latency,
    })
}

fn spawn(
    name: &str,
    f: impl FnOnce() -> Result<(), String> + Send + 'static,
) -> Result<JoinHandle<Result<(), String>>, StartError> {
    std::thread::Builder::new()
        .name(name.to_string())
        .spawn(f)
        .map_err(|e| StartError::Setup(format!("cannot start the {name} thread: {e}")))
}

fn wait_ready(
    rx: &std::sync::mpsc::Receiver<Result<Option<RtStatus>, StartError>>,
) -> Result<Option<RtStatus>, StartError> {
    match rx.recv_timeout(Duration::from_secs(10)) {
        Ok(r) => r,
        Err(_) => Err(StartError::Setup(
            "a daemon thread did not start within 10 s".to_string(),
        )),
    }
}

/// Where a daemon thread reports that its ports are up.
pub type Ready = std::sync::mpsc::Sender<Result<Option<RtStatus>, StartError>>;
