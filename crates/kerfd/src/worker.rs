//! The daemon's two workers, free of any transport: the planning worker (received items →
//! validated moves → [`Planner`] → a ring of planned items) and the real-time cycle
//! ([`Cycle`]: commands and planned items in, one setpoint out per period).
//!
//! The iceoryx2 edges (`super::ipc`) only convert messages into [`Incoming`] items and
//! setpoints into messages, so that everything here is tested without shared memory and
//! the cycle is the same code whatever carries its input.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use kerf_drive::recorder::Recorder;
use kerf_drive::safety::{Fault, ResetRefused, State as SafetyState};
use kerf_drive::sim::SimDrive;
use kerf_drive::stage::{AxisDrive, DriveStage, Dump, Phase, StageInput};
use kerf_geom::Move;
use kerf_motion::{MotionCore, MotionState, Setpoint};
use kerf_pipeline::{Event, Input, Interpolator, Planned, Poll, RunError, Tracker, plan_input};
use kerf_plan::{MachineLimits, PlanError, PlannedSegment, Planner};
use kerf_proto::{SetpointMsg, State, StreamError};

use kerf_config::travel::{PlannedTravelError, TravelError, check_move, check_segment};
use kerf_config::{Axes, Config};

/// One item from a planner process, after the message was converted and checked against
/// the stream rules.
#[derive(Clone, Debug, PartialEq)]
pub enum Incoming {
    /// A program starts at `start` (X, Y, Z mm, A, B, C deg).
    Begin {
        /// The program's id, chosen by the sender.
        program_id: u64,
        /// Where the program starts.
        start: [f64; 6],
    },
    /// A resolved move.
    Move(Move),
    /// A non-motion event.
    Event(kerf_geom::Event),
    /// The program was received to its end.
    End,
    /// A message was refused: it is never executed, and the running program stops at the
    /// end of its last valid move.
    Rejected(StreamError),
    /// The sending process went away in the middle of a program.
    SenderGone,
}

/// Why a program stopped before its end (all `Copy`: the reason crosses the real-time
/// thread, which never formats text).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum Refusal {
    /// A message broke the protocol or the stream rules.
    #[error("message refused: {0}")]
    Message(StreamError),
    /// A move leaves the configured travel.
    #[error("line {}: {}", .0.line, .0)]
    Travel(TravelError),
    /// The planned path leaves the configured travel.
    #[error("line {}: {}", .0.line, .0)]
    PlannedTravel(PlannedTravelError),
    /// A move cannot be planned on this machine.
    #[error("{0}")]
    Plan(PlanError),
    /// The motion core refused a planned segment (a defect of the planner).
    #[error("line {line}: the motion core refused the planned segment")]
    Core {
        /// Source line.
        line: u32,
    },
    /// The planner process went away in the middle of the program.
    #[error("the planner process went away in the middle of the program")]
    SenderGone,
    /// A new program began before the previous one was received to its end.
    #[error("a new program began before this one was received to its end")]
    Interrupted,
    /// The drive side's safety layer tripped during the program: the axes were brought
    /// to rest by the quick stop and the rest of the program was dropped.
    #[error("stopped by the safety layer: {0}")]
    Safety(Fault),
    /// The program began while a fault was latched: nothing of it moved.
    #[error("not started: a fault is latched ({0}); clear it with `kerf reset`")]
    Faulted(Fault),
    /// The program does not start where the machine is.
    #[error("the program starts at {axis} {start}, but the machine is at {axis} {actual}")]
    WrongStart {
        /// The axis that differs.
        axis: char,
        /// Where the program starts on it.
        start: f64,
        /// Where the machine is.
        actual: f64,
    },
}

/// An item from the planning worker to the real-time cycle.
// Nearly every item is a segment (as in `Planned`).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug)]
pub enum RtItem {
    /// A program starts.
    Begin {
        /// Its id.
        program_id: u64,
        /// Where it starts.
        start: [f64; 6],
    },
    /// A programmed move, sent just before the first segment planned after it was taken
    /// (as `kerf sim` records it), for the line being passed on smoothed curves.
    Move(Move),
    /// A planned segment or dwell.
    Planned(Planned),
    /// The program ends here: received to its end (`None`), or stopped early.
    End(Option<Refusal>),
}

/// A command for the real-time cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    /// Feed hold: a jerk-limited stop on the path.
    Hold,
    /// Resume after a hold.
    Resume,
    /// Stop on the path and drop the rest of the program.
    Abort,
    /// Abort program `id`: the running one if it is that one, else the program of that id
    /// when it begins (it then begins aborted and never moves).
    AbortProgram(u64),
    /// Feed override, percent (0 to 200).
    Override(f64),
    /// Stop on the path, drop the program, then end the cycle (SIGTERM, SIGINT).
    Shutdown,
    /// Clear the drive side's latched fault once its cause is gone; the outcome comes in
    /// [`Snapshot::reset`] with this tag.
    Reset(u64),
    /// Dump the black box; the dump comes out of the dump ring with this tag.
    Dump(u64),
    /// Tests only: a fault injected below the motion core.
    Inject(Injection),
}

/// A fault injected below the motion core, for tests of the safety layer (`kerfd
/// --test-faults`; refused otherwise).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Injection {
    /// The simulated drive of the axis gets a lasting fault cause (error code 0x4310,
    /// drive over temperature) until [`Injection::ClearDriveFault`].
    DriveFault(usize),
    /// The fault cause of the axis's simulated drive goes away.
    ClearDriveFault(usize),
    /// The next setpoint of the axis is moved by this many mm (deg) on its way to the
    /// drive.
    Step(usize, f64),
    /// The next this many cycles give the drive side no setpoint.
    Stall(u32),
}

/// The error code a lasting injected drive fault reports: 0x4310, excess temperature of
/// the drive.
pub const INJECTED_DRIVE_FAULT: u16 = 0x4310;

impl Injection {
    /// The size of the step [`Injection::from_code`] makes, mm (deg).
    pub const STEP_MM: f64 = 1.0;

    /// Decodes a `REQUEST_INJECT` value, `kind · 16 + n`: kind 1 a lasting drive fault on
    /// axis n (0–5 = X–C), 2 its cause removed, 3 a step of [`Injection::STEP_MM`] on axis
    /// n, 4 a stall of n × 10 cycles (n 0–15).
    pub fn from_code(code: u32) -> Option<Injection> {
        let (kind, arg) = (code / 16, (code % 16) as usize);
        match kind {
            1 if arg < 6 => Some(Injection::DriveFault(arg)),
            2 if arg < 6 => Some(Injection::ClearDriveFault(arg)),
            3 if arg < 6 => Some(Injection::Step(arg, Injection::STEP_MM)),
            4 => Some(Injection::Stall(arg as u32 * 10)),
            _ => None,
        }
    }

    /// The code of this injection for `REQUEST_INJECT` (`None` for what no code makes).
    pub fn code(self) -> Option<u32> {
        match self {
            Injection::DriveFault(a) if a < 6 => Some(16 + a as u32),
            Injection::ClearDriveFault(a) if a < 6 => Some(32 + a as u32),
            Injection::Step(a, mm) if a < 6 && mm == Injection::STEP_MM => Some(48 + a as u32),
            Injection::Stall(n) if n % 10 == 0 && n / 10 < 16 => Some(64 + n / 10),
            _ => None,
        }
    }
}

/// What the drive side reports after each cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveReport {
    /// The drive stage's phase.
    pub phase: Phase,
    /// The safety layer's state.
    pub state: SafetyState,
    /// The latched fault, if any.
    pub fault: Option<Fault>,
    /// The error code (0x603F) of the faulted drive, 0 when none.
    pub error_code: u16,
}

/// What the cycle reports to the control thread after every period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Snapshot {
    /// Cycles run since the daemon started.
    pub cycles: u64,
    /// What the machine is doing.
    pub state: State,
    /// Source line of the motion.
    pub line: u32,
    /// Setpoint position, X Y Z mm, A B C deg.
    pub position: [f64; 6],
    /// Path speed, mm/s.
    pub feed_mm_s: f64,
    /// Feed override, percent.
    pub override_pct: f64,
    /// Segments in the motion queue.
    pub queued_segments: u64,
    /// Motion time of the queued segments at their planned speed limits, s.
    pub queued_s: f64,
    /// The current (or last) program's id; 0 before the first.
    pub program_id: u64,
    /// `true` once the current program has finished moving and the machine is at rest.
    pub program_done: bool,
    /// `true` if the current program was aborted.
    pub aborted: bool,
    /// Why the current program stopped early, if it did.
    pub refusal: Option<Refusal>,
    /// Cycles of the current program (its setpoints' program time is this × period).
    pub program_cycle: u64,
    /// `true` once the cycle has stopped for a shutdown.
    pub shut_down: bool,
    /// The drive side.
    pub drives: DriveReport,
    /// The last reset's tag and outcome.
    pub reset: Option<(u64, Result<(), ResetRefused>)>,
    /// Commands the cycle has taken and applied since the start (a request's answer
    /// waits until its command is among them).
    pub commands_applied: u64,
}

/// Periods to wait between polls while the ring to the cycle is full.
const RING_FULL_WAIT: Duration = Duration::from_micros(200);

/// The planning worker's side of the ring to the cycle; the worker stops when `stop` is
/// set.
pub struct Planning {
    limits: MachineLimits,
    axes: Axes,
    out: rtrb::Producer<RtItem>,
    stop: Arc<AtomicBool>,
    /// Messages refused since the daemon started.
    refused: Arc<AtomicU64>,
    planner: Option<Planner>,
    /// The current program was stopped early: its remaining items are dropped until the
    /// next one begins.
    failed: bool,
    buf: Vec<PlannedSegment>,
    /// Moves taken by the planner and not yet sent to the cycle.
    taken: std::collections::VecDeque<Move>,
}

/// Counters the planning worker shares with the control thread.
#[derive(Clone, Debug, Default)]
pub struct PlanningCounters {
    /// Items (not BEGIN or END) of the current program taken off the moves service.
    pub received: Arc<AtomicU64>,
    /// Messages refused since start.
    pub refused: Arc<AtomicU64>,
    /// The program being received (its BEGIN accepted, neither its END received nor
    /// stopped early); 0 when none.
    pub open: Arc<AtomicU64>,
    /// A program to abort, set by the control thread; the planning thread drops the rest
    /// of it (when it is the open one) and clears this.
    pub abort: Arc<AtomicU64>,
    /// What became of the last programs.
    pub fates: Arc<std::sync::Mutex<super::fates::Fates>>,
}

impl Planning {
    /// A worker for the machine of `config`, feeding `out`.
    pub fn new(
        config: &Config,
        out: rtrb::Producer<RtItem>,
        stop: Arc<AtomicBool>,
        counters: &PlanningCounters,
    ) -> Self {
        Planning {
            limits: kerf_config::machine_limits(config),
            axes: config.axes,
            out,
            stop,
            refused: counters.refused.clone(),
            planner: None,
            failed: false,
            buf: Vec::new(),
            taken: std::collections::VecDeque::new(),
        }
    }

    /// `true` while a program is being received.
    pub fn in_program(&self) -> bool {
        self.planner.is_some()
    }

    /// `true` after the current program was stopped early: its remaining messages are
    /// dropped until the next program begins.
    pub fn dropping(&self) -> bool {
        self.failed
    }

    /// Drops the rest of the open program after an abort: nothing more of it is planned,
    /// and the cycle (which aborted the motion) gets its end. Returns `false` if told to
    /// stop.
    pub fn abort(&mut self) -> bool {
        if self.planner.is_none() || self.failed {
            return true;
        }
        tracing::info!("program aborted: the rest of it is dropped");
        self.buf.clear();
        self.taken.clear();
        self.failed = true;
        self.send(RtItem::End(None))
    }

    /// Handles one incoming item. Returns `false` once the worker must stop.
    pub fn handle(&mut self, item: Incoming) -> bool {
        match item {
            Incoming::Begin { program_id, start } => {
                if self.planner.is_some() && !self.failed {
                    self.fail(Refusal::Interrupted);
                }
                self.failed = false;
                self.taken.clear();
                self.planner = Some(Planner::new(self.limits));
                self.send(RtItem::Begin { program_id, start })
            }
            Incoming::Move(m) => {
                if self.failed || self.planner.is_none() {
                    return true;
                }
                match self.plan(&Input::Move(m), Some(&m)) {
                    Ok(()) => self.flush(),
                    Err(r) => self.refuse(r),
                }
            }
            Incoming::Event(e) => {
                if self.failed || self.planner.is_none() {
                    return true;
                }
                let Some(input) = input_of_event(&e) else {
                    return true;
                };
                match self.plan(&input, None) {
                    Ok(()) => {
                        if !self.flush() {
                            return false;
                        }
                        match input {
                            Input::Dwell(s) => self.send(RtItem::Planned(Planned::Dwell(s))),
                            _ => true,
                        }
                    }
                    Err(r) => self.refuse(r),
                }
            }
            Incoming::End => match self.planner.take() {
                Some(mut planner) if !self.failed => {
                    planner.finish(&mut self.buf);
                    self.planner = Some(planner);
                    let ok = self.flush();
                    self.planner = None;
                    ok && self.send(RtItem::End(None))
                }
                _ => {
                    self.planner = None;
                    true
                }
            },
            Incoming::Rejected(reject) => {
                self.refused.fetch_add(1, Ordering::AcqRel);
                tracing::warn!("message refused: {reject}");
                if self.planner.is_some() && !self.failed {
                    self.fail(Refusal::Message(reject))
                } else {
                    true
                }
            }
            Incoming::SenderGone => {
                if self.planner.is_some() && !self.failed {
                    tracing::warn!("the planner process went away in the middle of a program");
                    let ok = self.fail(Refusal::SenderGone);
                    self.planner = None;
                    ok
                } else {
                    self.planner = None;
                    true
                }
            }
        }
    }

    /// A received move or event failed the daemon's own checks (travel, planning): the
    /// message is refused and counted like one the stream check refused, and the program
    /// stops at the end of its last valid move.
    fn refuse(&mut self, reason: Refusal) -> bool {
        self.refused.fetch_add(1, Ordering::AcqRel);
        self.fail(reason)
    }

    /// Validates and plans one input into `buf`.
    fn plan(&mut self, input: &Input, m: Option<&Move>) -> Result<(), Refusal> {
        if let Some(m) = m {
            check_move(m, &self.axes).map_err(Refusal::Travel)?;
        }
        let Some(planner) = self.planner.as_mut() else {
            return Ok(());
        };
        plan_input(planner, input, &mut self.buf).map_err(Refusal::Plan)?;
        if let Some(m) = m {
            self.taken.push_back(*m);
        }
        for seg in &self.buf {
            check_segment(seg, &self.axes).map_err(Refusal::PlannedTravel)?;
        }
        Ok(())
    }

    /// Sends the planned segments in `buf`, each after the moves taken before it was
    /// planned.
    fn flush(&mut self) -> bool {
        let mut buf = std::mem::take(&mut self.buf);
        let mut ok = true;
        if !buf.is_empty() {
            while let Some(m) = self.taken.pop_front() {
                if !self.send(RtItem::Move(m)) {
                    self.buf = buf;
                    return false;
                }
            }
        }
        for seg in buf.drain(..) {
            // The count of moves known is only used by the offline deviation check.
            if !self.send(RtItem::Planned(Planned::Segment(seg, 0))) {
                ok = false;
                break;
            }
        }
        self.buf = buf;
        ok
    }

    /// Stops the current program at the end of its last valid move: the segments planned
    /// from the valid moves are sent (the planner holds back the end of the path for
    /// blending), then the end with the reason.
    fn fail(&mut self, reason: Refusal) -> bool {
        tracing::warn!("program stopped: {reason}");
        self.buf.clear();
        if let Some(planner) = self.planner.as_mut() {
            planner.finish(&mut self.buf);
        }
        // A segment planned from the valid moves that leaves the travel is dropped with
        // everything after it.
        if let Some(bad) = self
            .buf
            .iter()
            .position(|seg| check_segment(seg, &self.axes).is_err())
        {
            self.buf.truncate(bad);
        }
        self.failed = true;
        self.flush() && self.send(RtItem::End(Some(reason)))
    }

    /// Sends one item, waiting while the ring is full. Returns `false` if told to stop.
    fn send(&mut self, mut item: RtItem) -> bool {
        loop {
            match self.out.push(item) {
                Ok(()) => return true,
                Err(rtrb::PushError::Full(back)) => {
                    if self.stop.load(Ordering::Acquire) {
                        return false;
                    }
                    item = back;
                    std::thread::sleep(RING_FULL_WAIT);
                }
            }
        }
    }
}

/// A program the cycle is running.
#[derive(Clone, Copy, Debug)]
struct ProgramRun {
    id: u64,
    aborted: bool,
    cycle: u64,
    refusal: Option<Refusal>,
    /// Set when the program must not move at all (it starts elsewhere).
    dropped: bool,
    /// Planned items (segments, dwells) taken for the motion so far.
    planned: u64,
}

/// The setpoint of one cycle as the daemon publishes it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CycleOutput {
    /// Cycle number since the daemon started (1 for the first).
    pub seq: u64,
    /// The setpoint.
    pub setpoint: Setpoint,
    /// Per-axis velocity, by the backward difference of the positions, per s.
    pub velocity: [f64; 6],
    /// The program this setpoint belongs to (0: none).
    pub program_id: u64,
    /// Cycles of that program so far (its program time is this × period); 0 while the
    /// program waits for its lookahead window.
    pub program_cycle: u64,
    /// What the machine is doing.
    pub state: u32,
    /// Periods since the start in which no cycle ran (see [`Cycle::missed`]).
    pub missed_periods: u64,
}

impl CycleOutput {
    /// Writes this cycle into the published message (`time_ns`: the cycle's deadline on
    /// CLOCK_MONOTONIC); the message's other fields (version, axes) stay.
    pub fn fill(&self, msg: &mut SetpointMsg, time_ns: u64) {
        msg.state = self.state;
        msg.seq = self.seq;
        msg.time_ns = time_ns;
        msg.program_id = self.program_id;
        msg.program_cycle = self.program_cycle;
        msg.position_mm_deg = self.setpoint.position;
        msg.velocity_mm_deg_s = self.velocity;
        msg.feed_mm_s = self.setpoint.feed_mm_s;
        msg.line = self.setpoint.line;
        msg.missed_periods = self.missed_periods;
    }
}

/// Commands taken per cycle at most (the rest wait for the next cycle).
const COMMANDS_PER_CYCLE: usize = 8;

/// Programmed moves the cycle's tracker holds without allocating: far more than the
/// moves of a full queue of smoothed pieces (a smoothing window drops its oldest moves
/// beyond 4,096).
pub const TRACKED_MOVES: usize = 65_536;

/// The ends of the rings that carry black-box dumps out of the cycle and their rings back.
pub struct DumpRings {
    /// Finished dumps, to the thread that writes them.
    pub dumps: rtrb::Producer<Dump>,
    /// Rings written and given back.
    pub spares: rtrb::Consumer<Box<Recorder>>,
}

/// The other ends of [`DumpRings`], for the thread that writes the dumps.
pub struct DumpWriterRings {
    /// Finished dumps.
    pub dumps: rtrb::Consumer<Dump>,
    /// Where written rings go back.
    pub spares: rtrb::Producer<Box<Recorder>>,
}

/// The two rings between the cycle and the dump writer (a dump is two boxes at most:
/// one being written, one waiting).
pub fn dump_rings() -> (DumpRings, DumpWriterRings) {
    let (dumps_tx, dumps_rx) = rtrb::RingBuffer::new(2);
    let (spares_tx, spares_rx) = rtrb::RingBuffer::new(2);
    (
        DumpRings {
            dumps: dumps_tx,
            spares: spares_rx,
        },
        DumpWriterRings {
            dumps: dumps_rx,
            spares: spares_tx,
        },
    )
}

/// The drive stage of `config`'s machine: a simulated drive per axis whose motor stands
/// at `position` at power-up, the safety layer and the black box.
pub fn drive_stage(config: &Config, position: [f64; 6]) -> Result<DriveStage<SimDrive>, String> {
    let setups = config.drive_configs();
    let mut axes: [Option<AxisDrive<SimDrive>>; 6] = [None, None, None, None, None, None];
    for (i, (slot, setup)) in axes.iter_mut().zip(setups.iter()).enumerate() {
        let Some(setup) = setup else { continue };
        let name = kerf_plan::AXIS_NAMES[i];
        let counts = setup
            .scale
            .to_counts(position[i])
            .map_err(|e| format!("axis {name}: the start position: {e}"))?;
        let sim = kerf_drive::sim::SimConfig {
            initial_position_counts: f64::from(counts),
            ..setup.sim
        };
        *slot = Some(AxisDrive {
            drive: SimDrive::new(sim),
            scale: setup.scale,
            enable_timeout_cycles: setup.enable_timeout_cycles,
        });
    }
    DriveStage::new(axes, config.safety_config(), config.recorder_capacity())
        .map_err(|e| e.to_string())
}

/// The real-time cycle: commands and planned items in, one setpoint out per period;
/// allocation-free once built.
///
/// After the motion core's step, the drive stage (`kerf_drive::stage`) checks the setpoint
/// and sends it to the drives; what the cycle publishes is what the drives were sent.
/// Programs wait until every drive is enabled, and start from the drives' actual
/// positions; a trip of the safety layer drops the running program, the drives ramp to
/// rest on the quick stop and the motion core rests where they stopped; programs are
/// refused until `kerf reset` clears the fault.
pub struct Cycle {
    interp: Interpolator,
    tracker: Tracker,
    period_s: f64,
    items: rtrb::Consumer<RtItem>,
    commands: rtrb::Consumer<Command>,
    status: rtrb::Producer<Snapshot>,
    program: Option<ProgramRun>,
    /// The last program's id, why it stopped early, and whether it was aborted.
    last_program: (u64, Option<Refusal>, bool),
    /// The last program ended in this cycle (a safety trip in the same cycle is its).
    ended_this_cycle: bool,
    /// Programs to abort when they begin (their abort came before their beginning); 0 =
    /// free slot.
    pending_abort: [u64; PENDING_ABORTS],
    /// The feed override in force, percent.
    override_pct: f64,
    /// Commands taken from the command ring and applied since the start.
    commands_applied: u64,
    /// Periods in which no cycle ran, since the start.
    missed_periods: u64,
    cycles: u64,
    /// The last setpoint of the motion core (the machine's position between programs).
    setpoint: Setpoint,
    /// The position sent to the drives in the last cycle.
    sent: [f64; 6],
    starved: bool,
    shutting_down: bool,
    shut_down: bool,
    /// Estimated motion time of the queued segments.
    queued: QueuedTime,
    stage: DriveStage<SimDrive>,
    dump_rings: DumpRings,
    /// A finished dump the dump ring had no room for.
    dump_waiting: Option<Dump>,
    /// The reset asked for (its tag) and the last reset's outcome.
    reset_tag: Option<u64>,
    last_reset: Option<(u64, Result<(), ResetRefused>)>,
    /// Injected faults still to apply.
    stall_left: u32,
    step: Option<(usize, f64)>,
    /// Cycles since a shutdown asked the drives to power off.
    disable_wait: u32,
    /// Whether any drive keeps its own time (see [`Cycle::missed`]).
    drives_keep_time: bool,
}

impl Cycle {
    /// A cycle for the machine of `config`; the simulated drives' motors stand at
    /// `position` at power-up, and the motion core starts where the drives report once
    /// they are enabled.
    pub fn new(
        config: &Config,
        position: [f64; 6],
        items: rtrb::Consumer<RtItem>,
        commands: rtrb::Consumer<Command>,
        status: rtrb::Producer<Snapshot>,
        dump_rings: DumpRings,
    ) -> Result<Self, String> {
        let limits = kerf_config::machine_limits(config);
        let capacity = config.daemon.queue_segments as usize;
        let stage = drive_stage(config, position)?;
        let start = stage.command();
        let mut core = MotionCore::new(limits.period_s, capacity);
        core.set_position(start);
        Ok(Cycle {
            interp: Interpolator::new(core),
            tracker: Tracker::with_capacity(TRACKED_MOVES),
            period_s: limits.period_s,
            items,
            commands,
            status,
            program: None,
            last_program: (0, None, false),
            ended_this_cycle: false,
            pending_abort: [0; PENDING_ABORTS],
            override_pct: 100.0,
            commands_applied: 0,
            missed_periods: 0,
            cycles: 0,
            setpoint: Setpoint {
                position: start,
                ..Setpoint::default()
            },
            sent: start,
            starved: false,
            shutting_down: false,
            shut_down: false,
            queued: QueuedTime::with_capacity(capacity),
            stage,
            dump_rings,
            dump_waiting: None,
            reset_tag: None,
            last_reset: None,
            stall_left: 0,
            step: None,
            disable_wait: 0,
            drives_keep_time: config
                .drive_configs()
                .iter()
                .flatten()
                .any(|d| d.kind.keeps_time()),
        })
    }

    /// The drive stage (for tests: its black box and drives).
    pub fn stage(&self) -> &DriveStage<SimDrive> {
        &self.stage
    }

    /// Periods the cycle did not run (its deadline was missed). A drive that keeps its own
    /// time (a fieldbus drive) got no setpoint in each: the drive side runs a cycle
    /// without one (the drives hold; the safety layer counts them, at most
    /// `stall_cycles + 1`, enough to trip). The simulated drives have no clock of their
    /// own: their time is the cycle's, and a late cycle delays them with it, so nothing
    /// was missed. Every missed period is counted in the setpoints (`missed_periods`).
    /// Allocation-free.
    pub fn missed(&mut self, periods: u64) {
        self.missed_periods += periods;
        if !self.drives_keep_time {
            return;
        }
        let n = periods.min(u64::from(self.stage.safety().config().stall_cycles) + 1);
        for _ in 0..n {
            self.drive_cycle(None);
        }
    }

    /// `true` once a shutdown has brought the machine to rest.
    pub fn shut_down(&self) -> bool {
        self.shut_down
    }

    /// Runs one period: takes commands and planned items without blocking, steps the
    /// motion, and returns the setpoint. Never allocates, locks or blocks.
    pub fn run(&mut self) -> CycleOutput {
        self.cycles += 1;
        self.ended_this_cycle = false;
        let mut commands = [None; COMMANDS_PER_CYCLE];
        for slot in commands.iter_mut() {
            match self.commands.pop() {
                Ok(c) => *slot = Some(c),
                Err(_) => break,
            }
        }
        if self.program.is_none() {
            self.begin_next();
        }
        let previous = self.sent;
        // Feeding comes before the commands, as in `kerf sim`, where an event applies
        // after the cycle's feeding and before its step.
        let mut started = match self.program {
            Some(p) if !p.dropped => self.feed(),
            _ => false,
        };
        if started && self.program.is_some_and(|p| p.planned == 0) && self.interp.source_ended() {
            // Nothing of the program was planned (refused at its first move, or empty):
            // it ends without a moving cycle.
            started = false;
            self.end_program();
        }
        for c in commands.iter().flatten() {
            self.apply(*c);
        }
        let mut program_id = self.last_program.0;
        let mut program_cycle = 0;
        if started {
            let mut sp = Setpoint::default();
            self.interp.step(&mut sp);
            self.tracker.track(&mut sp);
            self.setpoint = sp;
            // Forget the estimated times of the segments the core has finished.
            self.queued.keep_last(self.interp.core().queued());
            if let Some(p) = self.program.as_mut() {
                p.cycle += 1;
                program_id = p.id;
                program_cycle = p.cycle;
            }
            if self.interp.finished() {
                self.end_program();
            }
        } else {
            // At rest (idle, or a program waiting for its lookahead window).
            self.setpoint.feed_mm_s = 0.0;
            if let Some(p) = self.program {
                program_id = p.id;
                if p.dropped && self.drain_dropped() {
                    self.end_program();
                }
            }
        }
        // The drive side: the setpoint (unless an injected stall withholds it, or an
        // injected step moves it) goes through the safety layer to the drives.
        let setpoint = if self.stall_left > 0 {
            self.stall_left -= 1;
            None
        } else {
            let mut p = self.setpoint.position;
            if let Some((axis, mm)) = self.step.take() {
                p[axis] += mm;
            }
            Some(p)
        };
        self.drive_cycle(setpoint);
        let position = self.sent;
        let mut velocity = [0.0; 6];
        for (v, (p, q)) in velocity
            .iter_mut()
            .zip(position.iter().zip(previous.iter()))
        {
            *v = (p - q) / self.period_s;
        }
        if self.shutting_down && self.program.is_none() && self.interp.core().is_idle() {
            // At rest: the drives are powered off (the brakes hold), then the cycle ends.
            if self.disable_wait == 0 {
                self.stage.request_disable();
            }
            self.disable_wait += 1;
            self.shut_down = self.stage.disabled() || self.disable_wait > DISABLE_WAIT_CYCLES;
        }
        let state = self.state();
        self.report(state);
        let mut sp = self.setpoint;
        sp.position = position;
        CycleOutput {
            seq: self.cycles,
            setpoint: sp,
            velocity,
            program_id,
            program_cycle,
            state: state.as_u32(),
            missed_periods: self.missed_periods,
        }
    }

    /// One cycle of the drive side with `setpoint` (`None`: a missed cycle).
    fn drive_cycle(&mut self, setpoint: Option<[f64; 6]>) {
        let out = self.stage.cycle(&StageInput {
            setpoint,
            line: self.setpoint.line,
            time_s: self.cycles as f64 * self.period_s,
        });
        if let Some(p) = out.enabled_at {
            self.rest_at(p);
        }
        if let Some(f) = out.tripped {
            self.safety_stop(f);
        }
        if self.stage.fault().is_some() {
            // The drives follow the quick stop; the motion core rests where they are.
            self.rest_at(out.command);
        }
        if let Some(r) = out.reset
            && let Some(tag) = self.reset_tag.take()
        {
            self.last_reset = Some((tag, r));
        }
        self.sent = out.command;
        while let Ok(ring) = self.dump_rings.spares.pop() {
            self.stage.return_spare(ring);
        }
        if self.dump_waiting.is_none() {
            self.dump_waiting = self.stage.take_dump();
        }
        if let Some(d) = self.dump_waiting.take()
            && let Err(rtrb::PushError::Full(d)) = self.dump_rings.dumps.push(d)
        {
            self.dump_waiting = Some(d);
        }
    }

    /// The motion core drops everything and rests at `position`.
    fn rest_at(&mut self, position: [f64; 6]) {
        self.interp.core_mut().reset_to(position);
        self.setpoint.position = position;
        self.setpoint.feed_mm_s = 0.0;
    }

    /// The safety layer tripped: the program is dropped (its rest is refused), the
    /// motion core forgets its queue.
    fn safety_stop(&mut self, fault: Fault) {
        if let Some(p) = self.program.as_mut() {
            p.refusal = Some(Refusal::Safety(fault));
            self.interp.apply(Event::Abort);
            self.interp.next_program();
            self.tracker.clear();
            self.end_program();
        } else if self.ended_this_cycle && self.last_program.1.is_none() {
            // The setpoint of the program's last cycle tripped: the program did not
            // finish, whatever its motion reported.
            self.last_program.1 = Some(Refusal::Safety(fault));
        }
    }

    fn apply(&mut self, c: Command) {
        self.commands_applied += 1;
        match c {
            // A hold that arrives after its program ended holds nothing: it must not
            // stop the next program before its first move.
            Command::Hold if self.program.is_none() => {}
            Command::Hold => self.interp.apply(Event::Hold),
            Command::Resume => self.interp.apply(Event::Resume),
            Command::Override(pct) => {
                self.override_pct = pct;
                if pct == 0.0 {
                    // A control at 0 % stands still on the path (the core holds).
                    self.interp.apply(Event::Override(0.0));
                } else {
                    self.interp.apply(Event::Override(pct / 100.0));
                }
            }
            Command::Abort => {
                if let Some(p) = self.program.as_mut() {
                    p.aborted = true;
                }
                self.interp.apply(Event::Abort)
            }
            Command::AbortProgram(id) => match self.program.as_mut() {
                Some(p) if p.id == id => {
                    p.aborted = true;
                    self.interp.apply(Event::Abort)
                }
                // Already over, or not begun yet: it begins aborted.
                _ if self.last_program.0 != id && !self.pending_abort.contains(&id) => {
                    // The oldest request makes room (programs begin in order).
                    self.pending_abort.rotate_left(1);
                    self.pending_abort[PENDING_ABORTS - 1] = id;
                }
                _ => {}
            },
            Command::Shutdown => {
                if let Some(p) = self.program.as_mut() {
                    p.aborted = true;
                }
                self.shutting_down = true;
                self.interp.apply(Event::Abort);
            }
            Command::Reset(tag) => {
                self.reset_tag = Some(tag);
                self.stage.request_reset();
            }
            Command::Dump(tag) => self.stage.request_dump(tag),
            Command::Inject(i) => self.inject(i),
        }
    }

    fn inject(&mut self, injection: Injection) {
        match injection {
            Injection::DriveFault(axis) => {
                if let Some(d) = self.stage.drive_mut(axis) {
                    d.set_fault_cause(Some(INJECTED_DRIVE_FAULT));
                }
            }
            Injection::ClearDriveFault(axis) => {
                if let Some(d) = self.stage.drive_mut(axis) {
                    d.set_fault_cause(None);
                }
            }
            Injection::Step(axis, mm) => {
                if axis < 6 {
                    self.step = Some((axis, mm));
                }
            }
            Injection::Stall(n) => self.stall_left = n,
        }
    }

    /// Starts the next program if its beginning is in the ring (it waits while the
    /// drives are being enabled, and is refused while a fault is latched).
    fn begin_next(&mut self) {
        let Ok(RtItem::Begin { program_id, start }) = self.items.peek().copied() else {
            // Anything but a beginning while no program runs is the rest of an aborted
            // or refused program: dropped.
            while let Ok(item) = self.items.peek() {
                if matches!(item, RtItem::Begin { .. }) {
                    break;
                }
                let _ = self.items.pop();
            }
            return;
        };
        let fault = self.stage.fault().copied();
        if fault.is_none() && !self.stage.ready() {
            return;
        }
        let _ = self.items.pop();
        if let Some(f) = fault {
            self.program = Some(ProgramRun {
                id: program_id,
                aborted: false,
                cycle: 0,
                refusal: Some(Refusal::Faulted(f)),
                dropped: true,
                planned: 0,
            });
            return;
        }
        self.interp.next_program();
        self.tracker.clear();
        let aborted = self.pending_abort.contains(&program_id);
        if aborted {
            for slot in self.pending_abort.iter_mut().filter(|s| **s == program_id) {
                *slot = 0;
            }
        }
        let mut run = ProgramRun {
            id: program_id,
            aborted,
            cycle: 0,
            refusal: None,
            dropped: self.shutting_down || aborted,
            planned: 0,
        };
        for (i, (&s, &p)) in start.iter().zip(self.setpoint.position.iter()).enumerate() {
            // A start that is not a number is refused too.
            let at_machine = (s - p).abs() <= START_TOL;
            if !at_machine && !aborted {
                run.refusal = Some(Refusal::WrongStart {
                    axis: kerf_plan::AXIS_NAMES[i],
                    start: s,
                    actual: p,
                });
                run.dropped = true;
                break;
            }
        }
        self.setpoint.line = 0;
        self.program = Some(run);
    }

    /// Drops the items of a program that must not move; `true` once its end was taken.
    fn drain_dropped(&mut self) -> bool {
        loop {
            match self.items.peek() {
                Ok(RtItem::Begin { .. }) => return true,
                Ok(RtItem::End(_)) => {
                    let _ = self.items.pop();
                    return true;
                }
                Ok(RtItem::Planned(_) | RtItem::Move(_)) => {
                    let _ = self.items.pop();
                }
                Err(_) => return false,
            }
        }
    }

    /// Feeds the interpolator from the ring; returns whether the motion may step.
    fn feed(&mut self) -> bool {
        let items = &mut self.items;
        let tracker = &mut self.tracker;
        let queued = &mut self.queued;
        let aborted = self.interp.aborted();
        let mut refusal = None;
        let mut pending = false;
        let mut planned = 0u64;
        let result = self.interp.feed(|| {
            loop {
                let Ok(item) = items.peek() else {
                    pending = true;
                    return Poll::Pending;
                };
                match *item {
                    // The next program's beginning: this one ended without its end (cannot
                    // happen: the planning worker always ends a program before the next).
                    RtItem::Begin { .. } => return Poll::End,
                    RtItem::Move(_) if tracker.is_full() => return Poll::Pending,
                    // Programmed moves go to the tracker until the next planned item;
                    // after an abort they are not needed (as in `kerf sim`).
                    RtItem::Move(m) => {
                        if !aborted || tracker.is_empty() {
                            tracker.add(&m);
                        }
                    }
                    RtItem::Planned(p) => {
                        if let Planned::Segment(seg, _) = &p {
                            queued.push(segment_time_s(seg));
                        }
                        planned += 1;
                        let _ = items.pop();
                        return Poll::Ready(p);
                    }
                    RtItem::End(r) => {
                        refusal = r;
                        let _ = items.pop();
                        return Poll::End;
                    }
                }
                let _ = items.pop();
            }
        });
        if let Some(p) = self.program.as_mut() {
            p.planned += planned;
            if let Some(r) = refusal {
                p.refusal = Some(r);
            }
        }
        match result {
            Ok(started) => {
                self.starved = pending && started && !self.interp.source_ended();
                started
            }
            Err(RunError::Rejected { line }) => {
                if let Some(p) = self.program.as_mut() {
                    p.refusal.get_or_insert(Refusal::Core { line });
                }
                self.interp.apply(Event::Abort);
                true
            }
            Err(_) => true,
        }
    }

    fn end_program(&mut self) {
        if let Some(p) = self.program.take() {
            self.last_program = (p.id, p.refusal, p.aborted);
            self.ended_this_cycle = true;
        }
        self.starved = false;
        self.queued.keep_last(0);
    }

    fn state(&self) -> State {
        if self.stage.fault().is_some() {
            return State::Fault;
        }
        let core = self.interp.core().status();
        match core.state {
            MotionState::Held => State::Holding,
            MotionState::Stopping if self.interp.core().is_held() => State::Holding,
            _ if self.program.is_some() && self.starved => State::Starved,
            _ if self.program.is_some() => State::Running,
            MotionState::Idle => State::Idle,
            _ => State::Running,
        }
    }

    fn report(&mut self, state: State) {
        let core = self.interp.core().status();
        let (program_id, refusal, aborted, done) = match self.program {
            Some(p) => (p.id, p.refusal, p.aborted, false),
            None => (
                self.last_program.0,
                self.last_program.1,
                self.last_program.2,
                self.last_program.0 != 0,
            ),
        };
        let snapshot = Snapshot {
            cycles: self.cycles,
            state,
            line: self.setpoint.line,
            position: self.setpoint.position,
            feed_mm_s: self.setpoint.feed_mm_s,
            override_pct: self.override_pct,
            queued_segments: core.queued as u64,
            queued_s: self.queued.sum_s.max(0.0),
            program_id,
            program_done: done,
            aborted,
            refusal,
            program_cycle: self.program.map_or(0, |p| p.cycle),
            shut_down: self.shut_down,
            drives: self.drive_report(),
            reset: self.last_reset,
            commands_applied: self.commands_applied,
        };
        // A full ring means the control thread is behind: it gets the next one.
        let _ = self.status.push(snapshot);
    }
}

impl Cycle {
    fn drive_report(&self) -> DriveReport {
        let fault = self.stage.fault().copied();
        let error_code = match fault {
            Some(Fault {
                axis: Some(axis), ..
            }) => self.stage.error_codes()[axis],
            _ => 0,
        };
        DriveReport {
            phase: self.stage.phase(),
            state: self.stage.safety().state(),
            fault,
            error_code,
        }
    }
}

/// Programs the cycle remembers to abort when they begin (one moving, one received and
/// waiting, one being received, and a spare).
const PENDING_ABORTS: usize = 4;

/// How far (mm or degrees, any axis) a program may start from the machine's position.
pub const START_TOL: f64 = 1e-6;

/// Cycles a shutdown waits for the drives to power off before the cycle ends anyway.
const DISABLE_WAIT_CYCLES: u32 = 1000;

/// The estimated motion time of a segment at its planned speed limit, s.
fn segment_time_s(seg: &PlannedSegment) -> f64 {
    let v = seg.v_max_mm_s.min(seg.feed_mm_s);
    if v > 0.0 && v.is_finite() {
        seg.length_mm / v
    } else {
        0.0
    }
}

/// The estimated motion times of the segments in the motion queue, in push order, and
/// their sum: preallocated for the whole queue, so that it never allocates.
struct QueuedTime {
    times_s: std::collections::VecDeque<f64>,
    sum_s: f64,
}

impl QueuedTime {
    fn with_capacity(segments: usize) -> Self {
        QueuedTime {
            times_s: std::collections::VecDeque::with_capacity(segments),
            sum_s: 0.0,
        }
    }

    /// Adds a pushed segment's time (never beyond the reserved capacity).
    fn push(&mut self, t_s: f64) {
        if self.times_s.len() < self.times_s.capacity() {
            self.times_s.push_back(t_s);
            self.sum_s += t_s;
        }
    }

    /// Forgets all but the `n` segments pushed last (the core has finished the others).
    fn keep_last(&mut self, n: usize) {
        while self.times_s.len() > n {
            if let Some(t) = self.times_s.pop_front() {
                self.sum_s -= t;
            }
        }
        if self.times_s.is_empty() {
            self.sum_s = 0.0;
        }
    }
}

/// What a non-motion event of the program means to the motion: a dwell (`G4`) is an exact
/// stop and a rest; a program stop (M0, M1), an end (M2, M30), a tool change (M6), a
/// spindle (M3, M4, M5, S) or coolant (M7, M8, M9) change is an exact stop, because the
/// control waits for the motion to finish before it acts on it (as LinuxCNC does); a tool
/// selection (T) does not stop the motion. A pallet-change pause (M60) is a program stop,
/// and a user M code (M100–M199) runs its program after the motion before it, as LinuxCNC
/// does; messages (MSG, DEBUG, PRINT), LinuxCNC's log calls (LOG, passed on) and the
/// override controls (M48–M53) do not stop the motion. The
/// simulation does not wait at a program stop (it stands for an operator who presses
/// cycle start at once) and runs M1 like M0.
pub fn input_of_event(e: &kerf_geom::Event) -> Option<Input> {
    use kerf_geom::EventCode as C;
    match e.code {
        C::G4 => Some(Input::Dwell(e.value.unwrap_or(0.0))),
        // The override controls (M48–M53) change what the operator's overrides do from
        // this point of the path on: LinuxCNC queues them with the motion, no stop.
        C::T | C::Msg | C::Debug | C::Print | C::Log => None,
        C::M48 | C::M49 | C::M50 | C::M51 | C::M52 | C::M53 => None,
        C::M60 | C::User(_) => Some(Input::Stop),
        C::M0
        | C::M1
        | C::M2
        | C::M30
        | C::M3
        | C::M4
        | C::M5
        | C::M6
        | C::M7
        | C::M8
        | C::M9
        | C::M19
        | C::S => Some(Input::Stop),
    }
}
