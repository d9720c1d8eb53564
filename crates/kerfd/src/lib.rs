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
pub mod fates;
pub mod fault_text;
pub mod ipc;
pub mod publish;
pub mod timing;
pub mod worker;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use kerf_proto::{
    Command as Request, MoveMsg, REASON_NOT_ALLOWED, REASON_OK, Resolved, Response, SetpointMsg,
    State, StatusMsg, StreamCheck, StreamError,
};

use kerf_config::Config;
use worker::{Command, Cycle, Incoming, Planning, PlanningCounters, Refusal, RtItem, Snapshot};

/// Planned items the ring from the planning thread to the cycle holds: a few seconds of
/// dense code ahead of the motion queue.
pub const PLANNED_RING: usize = 8192;

/// Commands the ring to the cycle holds.
const COMMAND_RING: usize = 64;

/// Snapshots the ring from the cycle holds (the control thread drains it every poll).
const STATUS_RING: usize = 256;

/// How often the planning and control threads poll when there is nothing to do.
const POLL: Duration = Duration::from_micros(200);

/// How long a program may go without a message before the planning thread checks that
/// its sender is still alive.
const SENDER_CHECK_AFTER: Duration = Duration::from_millis(50);

/// Stack bytes the cycle thread touches before its first cycle.
const PREFAULT_STACK_BYTES: usize = 256 * 1024;

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
}

/// What the real-time setup achieved.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RtStatus {
    /// SCHED_FIFO and mlockall both took effect.
    pub rt: bool,
    /// What was refused, for the log.
    pub messages: Vec<String>,
}

/// A running daemon.
pub struct Daemon {
    machine: String,
    stop: Arc<AtomicBool>,
    shutdown: Arc<AtomicBool>,
    cycles: Arc<AtomicU64>,
    done: Arc<AtomicBool>,
    threads: Vec<JoinHandle<Result<(), String>>>,
    rt: RtStatus,
    timing: Arc<Mutex<Option<timing::TimingSummary>>>,
}

impl Daemon {
    /// The machine served.
    pub fn machine(&self) -> &str {
        &self.machine
    }

    /// Cycles run so far (the watchdog feeds systemd only while this advances).
    pub fn cycles(&self) -> u64 {
        self.cycles.load(Ordering::Acquire)
    }

    /// What the real-time setup achieved.
    pub fn rt(&self) -> &RtStatus {
        &self.rt
    }

    /// The cycle's wake-up latency and compute time, once the cycle has ended.
    pub fn timing(&self) -> Option<timing::TimingSummary> {
        self.timing.lock().ok().and_then(|t| *t)
    }

    /// Asks for a jerk-limited stop on the path, after which the daemon ends.
    pub fn shutdown(&self) {
        self.shutdown.store(true, Ordering::Release);
    }

    /// `true` once the daemon has stopped (after [`shutdown`](Self::shutdown), or a
    /// thread failed).
    pub fn finished(&self) -> bool {
        self.done.load(Ordering::Acquire) || self.threads.iter().any(|t| t.is_finished())
    }

    /// Waits for every thread; the first error of any.
    pub fn join(mut self) -> Result<(), String> {
        self.stop_all()
    }

    fn stop_all(&mut self) -> Result<(), String> {
        self.shutdown.store(true, Ordering::Release);
        let mut result = Ok(());
        // The cycle ends on its own after the stop; the other threads follow it.
        for t in self.threads.drain(..) {
            let r = t
                .join()
                .unwrap_or_else(|_| Err("a daemon thread panicked".to_string()));
            if result.is_ok() {
                result = r;
            }
            self.stop.store(true, Ordering::Release);
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
pub fn check_period(config: &Config) -> Result<(), StartError> {
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

    let stop = Arc::new(AtomicBool::new(false));
    let shutdown = Arc::new(AtomicBool::new(false));
    let cycles = Arc::new(AtomicU64::new(0));
    let overruns = Arc::new(AtomicU64::new(0));
    let done = Arc::new(AtomicBool::new(false));
    let rt_ok = Arc::new(AtomicBool::new(false));
    let timing = Arc::new(Mutex::new(None));
    let counters = PlanningCounters::default();

    let (items_tx, items_rx) = rtrb::RingBuffer::<RtItem>::new(PLANNED_RING);
    let (commands_tx, commands_rx) = rtrb::RingBuffer::<Command>::new(COMMAND_RING);
    let (status_tx, status_rx) = rtrb::RingBuffer::<Snapshot>::new(STATUS_RING);
    let (dump_rings, dump_writer) = worker::dump_rings();
    let cycle_parts = (items_rx, commands_rx, status_tx, dump_rings);

    // Each thread reports once its ports are up (or why they are not).
    let (ready_tx, ready_rx) = std::sync::mpsc::channel::<Result<Option<RtStatus>, StartError>>();

    let mut threads = Vec::new();

    // The control thread first: its service tells whether another daemon runs.
    {
        let machine = machine.clone();
        let ready = ready_tx.clone();
        let stop = stop.clone();
        let shutdown = shutdown.clone();
        let done = done.clone();
        let counters = counters.clone();
        let overruns = overruns.clone();
        let rt_ok = rt_ok.clone();
        let config = config.clone();
        threads.push(spawn("kerfd-control", move || {
            control_thread(
                &config,
                &machine,
                ready,
                stop,
                shutdown,
                done,
                counters,
                overruns,
                rt_ok,
                test_faults,
                commands_tx,
                status_rx,
                dump_writer,
            )
        })?);
    }
    wait_ready(&ready_rx)?;

    {
        let machine = machine.clone();
        let ready = ready_tx.clone();
        let stop = stop.clone();
        let config = config.clone();
        let counters = counters.clone();
        threads.push(spawn("kerfd-planning", move || {
            planning_thread(&config, &machine, window, ready, stop, counters, items_tx)
        })?);
    }
    wait_ready(&ready_rx)?;

    let rt_status;
    {
        let ready = ready_tx.clone();
        let stop = stop.clone();
        let cycles = cycles.clone();
        let config = config.clone();
        let timing = timing.clone();
        threads.push(spawn("kerfd-cycle", move || {
            cycle_thread(
                &config,
                real_time,
                timing,
                ready,
                stop,
                cycles,
                overruns,
                rt_ok,
                cycle_parts,
            )
        })?);
        rt_status = wait_ready(&ready_rx)?.unwrap_or_default();
    }

    Ok(Daemon {
        machine,
        stop,
        shutdown,
        cycles,
        done,
        threads,
        rt: rt_status,
        timing,
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

/// What the cycle thread is built from: the ring of planned items, the commands, the
/// status snapshots and the dump rings.
type CycleParts = (
    rtrb::Consumer<RtItem>,
    rtrb::Consumer<Command>,
    rtrb::Producer<Snapshot>,
    worker::DumpRings,
);

/// Where a daemon thread reports that its ports are up.
pub type Ready = std::sync::mpsc::Sender<Result<Option<RtStatus>, StartError>>;

#[allow(clippy::too_many_arguments)]
fn control_thread(
    config: &Config,
    machine: &str,
    ready: Ready,
    stop: Arc<AtomicBool>,
    shutdown: Arc<AtomicBool>,
    done: Arc<AtomicBool>,
    counters: PlanningCounters,
    overruns: Arc<AtomicU64>,
    rt_ok: Arc<AtomicBool>,
    test_faults: bool,
    mut commands: rtrb::Producer<Command>,
    status: rtrb::Consumer<Snapshot>,
    mut dumps: worker::DumpWriterRings,
) -> Result<(), String> {
    let setup = || -> Result<_, StartError> {
        let node = ipc::node("kerfd-control").map_err(StartError::Setup)?;
        let service = ipc::create_control(&node, machine).map_err(StartError::Setup)?;
        // The control service has one server slot: taken means a live daemon serves the
        // machine (a dead one's was removed with its node).
        let server = service
            .server_builder()
            .create()
            .map_err(|_| StartError::AlreadyRunning(machine.to_string()))?;
        Ok((node, service, server))
    };
    let (_node, _service, server) = match setup() {
        Ok(ports) => {
            let _ = ready.send(Ok(None));
            ports
        }
        Err(e) => {
            let message = e.to_string();
            let _ = ready.send(Err(e));
            return Err(message);
        }
    };

    let period_ns = config.period_us as u64 * 1000;
    let axes_mask = axes_mask(config);
    let window = config.daemon.move_window as u64;
    let mut writer = DumpWriter::new(config);
    let reset_patience = reset_patience(config);
    let dump_patience = dump_patience(config);
    let apply_patience = apply_patience(config);
    let mut view = CycleView {
        ring: status,
        latest: idle_snapshot(),
        counters: counters.clone(),
    };
    let mut rt_flag = 0u32;
    let mut hold_requested = false;
    let mut shutdown_sent = false;
    let mut next_tag = 1u64;
    // Commands pushed to the cycle so far: an answer waits until the cycle has applied
    // its command, so that its status is the status after the request.
    let mut pushed = 0u64;
    // Requests wait until the cycle has run once: by then every port (moves, setpoints)
    // is up, so a client that got an answer can open them all (`kerfd` is ready when
    // `kerf status` answers).
    let mut cycle_runs = false;
    loop {
        cycle_runs |= view.pull();
        writer.take(&mut dumps, None);
        if view.latest.state != State::Holding && view.latest.program_done {
            // The program is over: a hold asked for during it is void.
            hold_requested = false;
        }
        while cycle_runs && let Ok(Some(active)) = server.receive() {
            let request = *active.payload();
            let mut fate = kerf_proto::PROGRAM_FATE_UNKNOWN;
            let mut push = |commands: &mut rtrb::Producer<Command>, c: Command| {
                let answer = push_command(commands, c);
                if answer.0 == REASON_OK {
                    pushed += 1;
                }
                answer
            };
            let (reason, message) = match request.command() {
                Err(e) => (e.reason(), e.to_string()),
                Ok(Request::Status) => (REASON_OK, String::new()),
                Ok(Request::Program { program_id }) => {
                    let f = lock_fates(&counters).get(program_id);
                    fate = f.code;
                    (REASON_OK, f.reason)
                }
                Ok(Request::Hold) => {
                    let latest = &view.latest;
                    // No program yet (id 0) or the last one is over: nothing to hold.
                    if latest.state == State::Idle
                        && (latest.program_done || latest.program_id == 0)
                    {
                        (
                            REASON_NOT_ALLOWED,
                            "nothing to hold: no program is running".to_string(),
                        )
                    } else {
                        hold_requested = true;
                        push(&mut commands, Command::Hold)
                    }
                }
                Ok(Request::Resume) => {
                    if hold_requested || view.latest.state == State::Holding {
                        hold_requested = false;
                        push(&mut commands, Command::Resume)
                    } else {
                        (
                            REASON_NOT_ALLOWED,
                            "not holding: nothing to resume".to_string(),
                        )
                    }
                }
                Ok(Request::Abort) => {
                    hold_requested = false;
                    // Every program not yet over ends: the one moving, and the one being
                    // received (which the planning thread stops taking at once). The plain
                    // abort is for the moving one even when the fates have forgotten it
                    // (256 BEGINs since, refused ones included); aborting it twice is
                    // harmless.
                    let open = counters.open.load(Ordering::Acquire);
                    let unfinished = lock_fates(&counters).unfinished();
                    counters.abort.store(open, Ordering::Release);
                    let mut answer = push(&mut commands, Command::Abort);
                    for id in unfinished {
                        if answer.0 == REASON_OK {
                            answer = push(&mut commands, Command::AbortProgram(id));
                        }
                    }
                    answer
                }
                Ok(Request::Override { percent }) => {
                    push(&mut commands, Command::Override(percent))
                }
                Ok(Request::Reset) => {
                    let tag = next_tag;
                    next_tag += 1;
                    match push(&mut commands, Command::Reset(tag)) {
                        (REASON_OK, _) => {
                            wait_reset(&mut view, &mut writer, &mut dumps, tag, reset_patience)
                        }
                        refused => refused,
                    }
                }
                Ok(Request::Dump) => {
                    let tag = next_tag;
                    next_tag += 1;
                    match push(&mut commands, Command::Dump(tag)) {
                        (REASON_OK, _) => {
                            let waited = wait_dump(&mut view, &mut writer, &mut dumps, tag, dump_patience);
                            match waited {
                                Ok(path) => (REASON_OK, path.display().to_string()),
                                Err(e) => (REASON_NOT_ALLOWED, e),
                            }
                        }
                        refused => refused,
                    }
                }
                Ok(Request::Inject { code }) => match worker::Injection::from_code(code) {
                    _ if !test_faults => (
                        REASON_NOT_ALLOWED,
                        "fault injection is for tests only: this kerfd was not started with --test-faults".to_string(),
                    ),
                    Some(i) => push(&mut commands, Command::Inject(i)),
                    None => (
                        kerf_proto::REASON_BAD_VALUE,
                        format!("unknown injection code {code}"),
                    ),
                },
            };
            // The answer carries the status after the request: wait until the cycle has
            // applied every command pushed so far.
            let applied = poll_cycle(&mut view, apply_patience, |s| {
                (s.commands_applied >= pushed).then_some(())
            });
            if applied.is_none() {
                tracing::warn!(
                    "the real-time cycle did not apply a command within {apply_patience:?}"
                );
            }
            let mut msg = status_msg(
                &view.latest,
                &counters,
                rt_flag,
                overruns.load(Ordering::Acquire),
                window,
                axes_mask,
                period_ns,
            );
            if view.latest.drives.fault.is_some()
                && let Some(path) = writer.fault_path()
            {
                msg.set_fault_dump(&path.display().to_string());
            }
            let mut response = Response::new(request.id, reason, &message, msg);
            response.program_fate = fate;
            let _ = active.send_copy(response);
        }
        if rt_flag == 0 && rt_ok.load(Ordering::Acquire) {
            rt_flag = 1;
        }
        if shutdown.load(Ordering::Acquire) && !shutdown_sent {
            shutdown_sent = commands.push(Command::Shutdown).is_ok();
            // The program being received ends too: the planning thread drops its rest and
            // ends it, so that the cycle can come to rest and stop.
            counters
                .abort
                .store(counters.open.load(Ordering::Acquire), Ordering::Release);
        }
        if view.latest.shut_down || stop.load(Ordering::Acquire) {
            done.store(true, Ordering::Release);
            stop.store(true, Ordering::Release);
            return Ok(());
        }
        std::thread::sleep(POLL);
    }
}

/// The snapshot before the cycle's first report.
fn idle_snapshot() -> Snapshot {
    Snapshot {
        cycles: 0,
        state: State::Idle,
        line: 0,
        position: [0.0; 6],
        feed_mm_s: 0.0,
        override_pct: 100.0,
        queued_segments: 0,
        queued_s: 0.0,
        program_id: 0,
        program_done: false,
        aborted: false,
        refusal: None,
        program_cycle: 0,
        shut_down: false,
        drives: worker::DriveReport {
            phase: kerf_drive::stage::Phase::Enabling,
            state: kerf_drive::safety::State::Running,
            fault: None,
            error_code: 0,
        },
        reset: None,
        commands_applied: 0,
    }
}

fn lock_fates(counters: &PlanningCounters) -> std::sync::MutexGuard<'_, fates::Fates> {
    // A panic while holding the lock leaves a consistent table: take it anyway.
    counters
        .fates
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The control thread's view of the cycle: the snapshots it reports, the latest one, and
/// what they tell of each program's end (recorded in the fates; a program refused when
/// it would start is counted as refused).
struct CycleView {
    ring: rtrb::Consumer<Snapshot>,
    latest: Snapshot,
    counters: PlanningCounters,
}

impl CycleView {
    /// Takes every snapshot the cycle reported; `true` if there was one.
    fn pull(&mut self) -> bool {
        let mut got = false;
        while let Ok(s) = self.ring.pop() {
            self.observe(&s);
            self.latest = s;
            got = true;
        }
        got
    }

    fn observe(&self, s: &Snapshot) {
        if s.program_id == 0 || !s.program_done {
            return;
        }
        let (code, reason) = match (s.aborted, s.refusal) {
            (true, _) => (
                kerf_proto::PROGRAM_FATE_ABORTED,
                "aborted: the motion stopped on the path and the rest of the program was dropped"
                    .to_string(),
            ),
            (false, Some(r)) => (kerf_proto::PROGRAM_FATE_REFUSED, r.to_string()),
            (false, None) => (kerf_proto::PROGRAM_FATE_FINISHED, String::new()),
        };
        let changed = lock_fates(&self.counters).end(s.program_id, code, reason);
        if changed
            && !s.aborted
            && matches!(
                s.refusal,
                Some(Refusal::WrongStart { .. } | Refusal::Faulted(_))
            )
        {
            // Its BEGIN was refused when the program would have started.
            self.counters.refused.fetch_add(1, Ordering::AcqRel);
        }
    }
}

/// How long an answer waits for the cycle to apply its command: 100 periods, at least
/// 100 ms.
fn apply_patience(config: &Config) -> Duration {
    Duration::from_micros(u64::from(config.period_us) * 100).max(Duration::from_millis(100))
}

/// How long a reset may take: a fault reset and then the enable sequence (four
/// transitions), each within the drives' enable timeout, and a second more.
pub fn reset_patience(config: &Config) -> Duration {
    let period = Duration::from_micros(u64::from(config.period_us));
    let max_enable_cycles = config
        .drive_configs()
        .iter()
        .flatten()
        .map(|d| d.enable_timeout_cycles)
        .max()
        .unwrap_or(1);
    period.saturating_mul(max_enable_cycles.saturating_mul(5).saturating_add(16))
        + Duration::from_secs(1)
}

/// How long a black-box dump may take: the copy, a chunk per cycle, the writing, and a
/// second more.
pub fn dump_patience(config: &Config) -> Duration {
    let period = Duration::from_micros(u64::from(config.period_us));
    let cycles = config.recorder_capacity() / kerf_drive::stage::DUMP_CHUNK + 16;
    period.saturating_mul(u32::try_from(cycles).unwrap_or(u32::MAX)) + Duration::from_secs(2)
}

/// Polls the cycle every [`POLL`] (the latest status snapshot into `latest`) until
/// `outcome` has an answer, at most `patience`; `None` if it ran out.
fn poll_cycle<T>(
    view: &mut CycleView,
    patience: Duration,
    mut outcome: impl FnMut(&Snapshot) -> Option<T>,
) -> Option<T> {
    let deadline = Instant::now() + patience;
    loop {
        view.pull();
        if let Some(answer) = outcome(&view.latest) {
            return Some(answer);
        }
        if Instant::now() > deadline {
            return None;
        }
        std::thread::sleep(POLL);
    }
}

/// Waits for the outcome of reset `tag` (the status snapshots carry it), writing the
/// dumps that come out meanwhile.
fn wait_reset(
    view: &mut CycleView,
    writer: &mut DumpWriter,
    dumps: &mut worker::DumpWriterRings,
    tag: u64,
    patience: Duration,
) -> (u32, String) {
    let outcome = poll_cycle(view, patience, |s| {
        writer.take(dumps, None);
        match s.reset {
            Some((t, Ok(()))) if t == tag => Some((REASON_OK, String::new())),
            Some((t, Err(e))) if t == tag => Some((REASON_NOT_ALLOWED, e.to_string())),
            _ => None,
        }
    });
    outcome.unwrap_or_else(|| {
        (
            REASON_NOT_ALLOWED,
            "reset: no outcome from the real-time cycle in time".to_string(),
        )
    })
}

/// Waits for dump `tag` and writes it; its file.
fn wait_dump(
    view: &mut CycleView,
    writer: &mut DumpWriter,
    dumps: &mut worker::DumpWriterRings,
    tag: u64,
    patience: Duration,
) -> Result<std::path::PathBuf, String> {
    poll_cycle(view, patience, |_| writer.take(dumps, Some(tag))).unwrap_or_else(|| {
        Err("dump: the black box did not come out of the real-time cycle in time".to_string())
    })
}

/// Writes the black-box dumps that come out of the cycle into the dump directory.
struct DumpWriter {
    machine: String,
    dir: std::path::PathBuf,
    /// The file written for the last fault.
    fault: Option<std::path::PathBuf>,
    written: u64,
}

impl DumpWriter {
    fn new(config: &Config) -> Self {
        DumpWriter {
            machine: config.machine.clone(),
            dir: config.dump_dir(),
            fault: None,
            written: 0,
        }
    }

    fn fault_path(&self) -> Option<&std::path::Path> {
        self.fault.as_deref()
    }

    /// Writes every dump waiting in the ring, gives the rings back; the outcome of dump
    /// `tag` if it was among them.
    fn take(
        &mut self,
        rings: &mut worker::DumpWriterRings,
        tag: Option<u64>,
    ) -> Option<Result<std::path::PathBuf, String>> {
        let mut outcome = None;
        while let Ok(dump) = rings.dumps.pop() {
            let kind = match dump.reason {
                kerf_drive::stage::DumpReason::Fault(_) => "fault",
                kerf_drive::stage::DumpReason::Request(_) => "dump",
            };
            let written = self.write(kind, &dump.recorder);
            match (&written, dump.reason) {
                (Ok(path), kerf_drive::stage::DumpReason::Fault(f)) => {
                    tracing::error!("safety fault: {f}; black box written to {}", path.display());
                    self.fault = Some(path.clone());
                }
                (Err(e), kerf_drive::stage::DumpReason::Fault(f)) => {
                    tracing::error!("safety fault: {f}; the black box could not be written: {e}");
                }
                (Ok(path), _) => tracing::info!("black box written to {}", path.display()),
                (Err(e), _) => tracing::warn!("{e}"),
            }
            if let kerf_drive::stage::DumpReason::Request(t) = dump.reason
                && Some(t) == tag
            {
                outcome = Some(written);
            }
            // The ring goes back to the cycle (the ring to it has room for both).
            let _ = rings.spares.push(dump.recorder);
        }
        outcome
    }

    /// Writes `recorder` as CSV to a new file, through a temporary file renamed at the end.
    fn write(
        &mut self,
        kind: &str,
        recorder: &kerf_drive::recorder::Recorder,
    ) -> Result<std::path::PathBuf, String> {
        self.written += 1;
        let stamp = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        let name = format!(
            "kerf-{}-{kind}-{stamp}-{}-{}.csv",
            self.machine,
            std::process::id(),
            self.written
        );
        let path = self.dir.join(&name);
        let tmp = self.dir.join(format!(".{name}.tmp"));
        let fail =
            |e: std::io::Error| format!("cannot write the black box to {}: {e}", path.display());
        std::fs::create_dir_all(&self.dir).map_err(fail)?;
        let file = std::fs::File::create(&tmp).map_err(fail)?;
        let result = recorder
            .dump(std::io::BufWriter::new(file))
            .and_then(|()| std::fs::rename(&tmp, &path));
        if let Err(e) = result {
            let _ = std::fs::remove_file(&tmp);
            return Err(fail(e));
        }
        Ok(std::fs::canonicalize(&path).unwrap_or(path))
    }
}

fn push_command(commands: &mut rtrb::Producer<Command>, c: Command) -> (u32, String) {
    match commands.push(c) {
        Ok(()) => (REASON_OK, String::new()),
        Err(_) => (
            REASON_NOT_ALLOWED,
            "the command queue is full; try again".to_string(),
        ),
    }
}

fn axes_mask(config: &Config) -> u32 {
    let mut mask = 0b111;
    for (i, r) in config.axes.rotary().iter().enumerate() {
        if r.is_some() {
            mask |= 1 << (3 + i);
        }
    }
    mask
}

fn status_msg(
    s: &Snapshot,
    counters: &PlanningCounters,
    rt: u32,
    overruns: u64,
    window: u64,
    axes_mask: u32,
    period_ns: u64,
) -> StatusMsg {
    let mut msg = StatusMsg::zeroed();
    msg.state = match (s.state, s.refusal) {
        // A planner process that went away is no fault of the machine: it comes to rest
        // and reports idle (the reason stays in `fault` and `program_end`).
        (State::Idle, Some(Refusal::SenderGone)) => State::Idle,
        // A program the safety layer stopped (or refused while a fault was latched):
        // the fault is the drive side's, shown while it is latched (below); once reset,
        // the machine is idle.
        (State::Idle, Some(Refusal::Safety(_) | Refusal::Faulted(_))) => State::Idle,
        // The refused program's fault is shown until the next program begins.
        (State::Idle, Some(_)) => State::Fault,
        (state, _) => state,
    }
    .as_u32();
    msg.line = s.line;
    msg.position_mm_deg = s.position;
    msg.override_pct = s.override_pct;
    msg.queued_moves = s.queued_segments;
    msg.queued_s = s.queued_s;
    msg.cycles = s.cycles;
    msg.overruns = overruns;
    msg.rt = rt;
    msg.program_done = u32::from(s.program_done && !s.aborted && s.refusal.is_none());
    msg.program_end = match (s.program_done, s.aborted, s.refusal) {
        (false, ..) => kerf_proto::PROGRAM_END_NONE,
        (true, true, _) => kerf_proto::PROGRAM_END_ABORTED,
        (true, false, Some(_)) => kerf_proto::PROGRAM_END_REFUSED,
        (true, false, None) => kerf_proto::PROGRAM_END_FINISHED,
    };
    msg.program_id = s.program_id;
    msg.moves_received = counters.received.load(Ordering::Acquire);
    msg.window_items = window;
    msg.rejected = counters.refused.load(Ordering::Acquire);
    match s.refusal {
        Some(Refusal::Safety(_) | Refusal::Faulted(_)) if s.drives.fault.is_none() => {}
        Some(r) => {
            msg.fault = 1;
            msg.set_fault_text(&r.to_string());
        }
        None => {}
    }
    msg.axes_mask = axes_mask;
    msg.period_ns = period_ns;
    let d = &s.drives;
    msg.drives = match (d.phase, d.state) {
        (kerf_drive::stage::Phase::Enabling, _) => kerf_proto::DRIVES_ENABLING,
        (kerf_drive::stage::Phase::Resetting, _) => kerf_proto::DRIVES_RESETTING,
        (_, kerf_drive::safety::State::Running) => kerf_proto::DRIVES_RUNNING,
        (_, kerf_drive::safety::State::Holding) => kerf_proto::DRIVES_HOLDING,
        (_, kerf_drive::safety::State::QuickStop) => kerf_proto::DRIVES_QUICK_STOP,
        (_, kerf_drive::safety::State::Stopped) => kerf_proto::DRIVES_STOPPED,
    };
    if let Some(f) = d.fault {
        msg.state = State::Fault.as_u32();
        msg.safety_check = f.check.code();
        msg.safety_axis = f.axis.map_or(kerf_proto::SAFETY_AXIS_NONE, |a| a as u32);
        msg.safety_value = f.value;
        msg.safety_limit = f.limit;
        msg.safety_line = f.line;
        msg.safety_cycle = f.cycle;
        msg.drive_error_code = u32::from(d.error_code);
        msg.fault = 2;
        msg.set_fault_text(&fault_text::safety_text(&msg).unwrap_or_default());
    }
    msg
}

/// The planning thread's loop (public for the throughput bench in `benches/`).
pub fn planning_thread(
    config: &Config,
    machine: &str,
    window: usize,
    ready: Ready,
    stop: Arc<AtomicBool>,
    counters: PlanningCounters,
    items: rtrb::Producer<RtItem>,
) -> Result<(), String> {
    let setup = || -> Result<_, String> {
        let node = ipc::node("kerfd-planning")?;
        let service = ipc::create_moves(&node, machine, window)?;
        let subscriber = ipc::move_subscriber(&service, window)?;
        Ok((node, service, subscriber))
    };
    let (_node, service, subscriber) = match setup() {
        Ok(ports) => {
            let _ = ready.send(Ok(None));
            ports
        }
        Err(e) => {
            let _ = ready.send(Err(StartError::Setup(e.clone())));
            return Err(e);
        }
    };
    let mut planning = Planning::new(config, items, stop.clone(), &counters);
    let mut intake = Intake {
        check: StreamCheck::new(),
        current: 0,
        dropping: false,
    };
    let mut last_message = Instant::now();
    let mut last_sender_check = Instant::now();
    loop {
        if stop.load(Ordering::Acquire) {
            return Ok(());
        }
        let mut got = false;
        loop {
            let msg: MoveMsg = match subscriber.receive() {
                Ok(Some(sample)) => *sample,
                Ok(None) => break,
                Err(e) => return Err(format!("receiving moves: {e:?}")),
            };
            got = true;
            if let Some(incoming) = take_message(&msg, &mut intake, &counters)
                && !planning.handle(incoming)
            {
                return Ok(());
            }
            if planning.dropping() && intake.check.program_id().is_some() {
                // The program was refused: it is over, its rest is dropped.
                intake.check.reset();
                intake.dropping = true;
            }
            if intake.check.program_id().is_none() {
                counters.open.store(0, Ordering::Release);
            }
            // An abort of the open program drops the rest of it at once.
            if !abort_open(&mut planning, &mut intake, &counters) {
                return Ok(());
            }
        }
        if !abort_open(&mut planning, &mut intake, &counters) {
            return Ok(());
        }
        let now = Instant::now();
        if got {
            last_message = now;
            continue;
        }
        if planning.in_program()
            && now.duration_since(last_message) > SENDER_CHECK_AFTER
            && now.duration_since(last_sender_check) > SENDER_CHECK_AFTER
        {
            last_sender_check = now;
            ipc::clean_dead_nodes();
            if service.dynamic_config().number_of_publishers() == 0 {
                intake.check.reset();
                counters.open.store(0, Ordering::Release);
                if !planning.handle(Incoming::SenderGone) {
                    return Ok(());
                }
            }
        }
        std::thread::sleep(POLL);
    }
}

/// The planning thread's side of the stream rules that span programs: the stream check
/// of the open program and the program whose items count in `moves_received`.
struct Intake {
    check: StreamCheck,
    /// The open program, or the one stopped early whose rest is being dropped; 0 none.
    current: u64,
    /// The current program stopped early: its further items and END are dropped.
    dropping: bool,
}

/// A message refused without touching the open program: counted, logged, dropped.
fn refuse_alone(counters: &PlanningCounters, why: &StreamError) {
    counters.refused.fetch_add(1, Ordering::AcqRel);
    tracing::warn!("message refused: {why}");
}

/// Applies the stream rules that span programs to one message and returns what the
/// planning worker gets of it (`None`: refused or dropped here, see PROTOCOL.md's stream
/// rules 1, 2 and 6).
fn take_message(
    msg: &MoveMsg,
    intake: &mut Intake,
    counters: &PlanningCounters,
) -> Option<Incoming> {
    let id = msg.program_id;
    let open = intake.check.program_id();
    if msg.kind == kerf_proto::KIND_BEGIN {
        if let Some(open) = open {
            let why = StreamError::UnexpectedBegin { open, found: id };
            refuse_alone(counters, &why);
            lock_fates(counters).begin(id, Some(why.to_string()));
            return None;
        }
        if id != 0 && lock_fates(counters).knows(id) {
            refuse_alone(counters, &StreamError::RepeatedId { program_id: id });
            return None;
        }
        return match intake.check.check(msg) {
            Ok(Resolved::Begin {
                program_id,
                start_mm_deg,
                ..
            }) => {
                counters.received.store(0, Ordering::Release);
                counters.open.store(program_id, Ordering::Release);
                intake.current = program_id;
                intake.dropping = false;
                lock_fates(counters).begin(program_id, None);
                Some(Incoming::Begin {
                    program_id,
                    start: start_mm_deg,
                })
            }
            Ok(_) => None,
            Err(why) => {
                refuse_alone(counters, &why);
                lock_fates(counters).begin(id, Some(format!("message refused: {why}")));
                None
            }
        };
    }
    let item = msg.kind != kerf_proto::KIND_END;
    if intake.dropping && open.is_none() && id == intake.current {
        // The rest of a program stopped early: taken (for its client's flow control) and
        // dropped, up to its END.
        if item {
            counters.received.fetch_add(1, Ordering::AcqRel);
        } else {
            intake.dropping = false;
        }
        return None;
    }
    match open {
        Some(open) if open == id => {}
        Some(open) => {
            refuse_alone(
                counters,
                &StreamError::WrongProgram {
                    expected: open,
                    found: id,
                },
            );
            return None;
        }
        None => {
            refuse_alone(counters, &StreamError::NoBegin { program_id: id });
            return None;
        }
    }
    if item {
        counters.received.fetch_add(1, Ordering::AcqRel);
    }
    Some(match intake.check.check(msg) {
        Ok(Resolved::Move(m)) => Incoming::Move(m),
        Ok(Resolved::Event(e)) => Incoming::Event(e),
        Ok(Resolved::End { .. }) => {
            lock_fates(counters).received(id);
            Incoming::End
        }
        Ok(Resolved::Begin { .. }) => return None,
        Err(e) => {
            intake.check.reset();
            intake.dropping = true;
            Incoming::Rejected(e)
        }
    })
}

/// Ends the open program if the control thread asked for its abort. Returns `false` if
/// the worker must stop.
fn abort_open(planning: &mut Planning, intake: &mut Intake, counters: &PlanningCounters) -> bool {
    let id = counters.abort.swap(0, Ordering::AcqRel);
    if id == 0 || id != intake.current || intake.check.program_id() != Some(id) {
        return true;
    }
    intake.check.reset();
    intake.dropping = true;
    counters.open.store(0, Ordering::Release);
    planning.abort()
}

#[allow(clippy::too_many_arguments)]
fn cycle_thread(
    config: &Config,
    real_time: bool,
    timing_out: Arc<Mutex<Option<timing::TimingSummary>>>,
    ready: Ready,
    stop: Arc<AtomicBool>,
    cycles: Arc<AtomicU64>,
    overruns: Arc<AtomicU64>,
    rt_ok: Arc<AtomicBool>,
    parts: CycleParts,
) -> Result<(), String> {
    let (items, commands, status, dump_rings) = parts;
    // iceoryx2 allocates on publish: a helper thread publishes (see `publish`).
    let helper_rt = real_time.then(|| kerf_rt::RtConfig {
        priority: Some(config.daemon.priority.saturating_sub(1).max(1)),
        cpu: config.daemon.cpu.map(|c| c as usize),
        prefault_stack_bytes: PREFAULT_STACK_BYTES,
    });
    let (mut publisher, helper) = match publish::spawn(&config.machine, helper_rt) {
        Ok(p) => p,
        Err(e) => {
            let _ = ready.send(Err(StartError::Setup(e.clone())));
            return Err(e);
        }
    };
    let mut cycle = match Cycle::new(config, [0.0; 6], items, commands, status, dump_rings) {
        Ok(c) => c,
        Err(e) => {
            let _ = ready.send(Err(StartError::Config(e.clone())));
            return Err(e);
        }
    };
    let rt = if real_time {
        let report = kerf_rt::rt_setup(&kerf_rt::RtConfig {
            priority: Some(config.daemon.priority),
            cpu: config.daemon.cpu.map(|c| c as usize),
            prefault_stack_bytes: PREFAULT_STACK_BYTES,
        });
        match report {
            Ok(r) => {
                let ok = r.mlocked && r.fifo;
                rt_ok.store(ok, Ordering::Release);
                RtStatus {
                    rt: ok,
                    messages: r.messages,
                }
            }
            Err(e) => {
                let _ = ready.send(Err(StartError::Config(e.to_string())));
                return Err(e.to_string());
            }
        }
    } else {
        RtStatus {
            rt: false,
            messages: vec!["real-time scheduling not requested".to_string()],
        }
    };
    let axes_mask = axes_mask(config);
    let mut clock = match kerf_rt::PeriodicClock::new(config.period_us as u64 * 1000) {
        Ok(c) => c,
        Err(e) => {
            let _ = ready.send(Err(StartError::Config(e.to_string())));
            return Err(e.to_string());
        }
    };
    let _ = ready.send(Ok(Some(rt)));
    let mut msg = SetpointMsg::new();
    msg.axes_mask = axes_mask;
    let mut timing = timing::CycleTiming::new();
    loop {
        let tick = clock.wait_next();
        if tick.missed > 0 {
            overruns.fetch_add(tick.missed, Ordering::AcqRel);
            // The drives got no setpoint in the periods missed: they held.
            cycle.missed(tick.missed);
        }
        let out = cycle.run();
        out.fill(&mut msg, tick.deadline_ns);
        publisher.push(msg);
        let woke_ns = tick.deadline_ns + tick.latency_ns;
        timing.record(tick.latency_ns, kerf_rt::now_ns().saturating_sub(woke_ns));
        cycles.store(out.seq, Ordering::Release);
        if cycle.shut_down() || stop.load(Ordering::Acquire) {
            let mut summary = timing.summary();
            if let Some(h) = helper.finish() {
                summary.publish = h.percentiles();
            }
            tracing::info!(
                "cycle timing: {summary}; {} setpoints dropped",
                publisher.dropped()
            );
            if let Ok(mut t) = timing_out.lock() {
                *t = Some(summary);
            }
            stop.store(true, Ordering::Release);
            return Ok(());
        }
    }
}
