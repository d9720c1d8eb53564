//! The daemon's two workers, free of any transport: the planning worker (received items →
//! validated moves → [`Planner`] → a ring of planned items) and the real-time cycle
//! ([`Cycle`]: commands and planned items in, one setpoint out per period).
//!
//! The iceoryx2 edges (`super::ipc`) only convert messages into [`Incoming`] items and
//! setpoints into messages, so that everything here is tested without shared memory and
//! the cycle is the same code whatever carries its input.

use kerf_geom::PerAxis;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use kerf_drive::machine::{Machine, MachineStatus};
use kerf_drive::recorder::Recorder;
use kerf_drive::safety::{Fault, ResetRefused, SafetyState};
use kerf_drive::sim::SimDrive;
use kerf_drive::stage::{AxisDrive, DriveStage, Dump, Phase, StageInput};
use kerf_geom::Move;
use kerf_motion::{MotionCore, MotionState, Setpoint};
use kerf_pipeline::{
    ActionOrder, Input, Interpolator, OperatorEvent, Planned, Poll, ProgramActions, RunError,
    Taking, Tracker, plan_input,
};
use kerf_plan::{MachineLimits, PlanError, PlannedSegment, Planner};
use kerf_proto::{MachineState, SetpointMsg, StreamError};

use kerf_config::travel::{PlannedTravelError, TravelError, check_move, check_segment};
use kerf_config::{Axes, Config};

mod cycle;
mod events;
pub mod fieldbus;
mod planning;

pub use cycle::*;
pub(crate) use cycle::{Manual, simulated_switches};
pub use events::input_of_event;
pub use planning::*;

/// One item from a planner process, after the message was converted and checked against
/// the stream rules.
#[derive(Clone, Debug, PartialEq)]
pub enum Incoming {
    /// A program starts at `start` (X, Y, Z mm, A, B, C deg).
    Begin {
        /// The program's id, chosen by the sender.
        program_id: u64,
        /// Where the program starts.
        start: PerAxis<f64>,
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
    /// The program asks for something this machine does not have (a spindle, coolant,
    /// an input or output, a tool changer, a speed above the spindle's top speed).
    #[error(
        "line {line}: this machine cannot carry out {} ({value}): the configuration's [spindle], [coolant], [io] or [tool_changer] has nothing for it",
        code.as_str()
    )]
    Machine {
        /// Source line.
        line: u32,
        /// The code.
        code: kerf_geom::EventCode,
        /// Its value (the speed, or the input or output's number).
        value: f64,
    },
    /// The program began while an axis was not homed and the machine requires homing.
    #[error("not started: axis {0} is not homed; home the machine first (`kerf home --all`)")]
    NotHomed(char),
    /// The program began while an axis stood on a hard limit switch.
    #[error("not started: axis {0} stands on a hard limit switch; jog it off first")]
    OnLimitSwitch(char),
    /// The program began while an axis moved by hand (a jog, homing).
    #[error("not started: an axis is moving by hand (a jog or homing); wait until it is at rest")]
    ManualMotion,
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
        start: PerAxis<f64>,
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
pub enum CycleCommand {
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
    /// An operator's switch on or off.
    Switch(kerf_proto::Switch, bool),
    /// The spindle override, percent (0 to 200).
    SpindleOverride(f64),
    /// Jog an axis (the control thread checked the request; the cycle checks it again
    /// against the machine as it is now and ignores it when refused).
    Jog {
        /// The axis, 0–5.
        axis: usize,
        /// How.
        jog: kerf_proto::Jog,
        /// mm/s or deg/s; 0: the configured default.
        speed: f64,
    },
    /// Stop the jog of an axis.
    JogStop(usize),
    /// Home the axes of the bit mask.
    Home(u32),
    /// A simulated input's new value (digital: 1 or 0).
    SetInput {
        /// An analog input (else digital).
        analog: bool,
        /// Its number.
        index: u8,
        /// Its value.
        value: f64,
    },
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
    /// The simulated spindle drive loses its load (`true`: a broken belt, its speed
    /// decays to rest) or gets it back.
    SpindleStall(bool),
}

/// The error code a lasting injected drive fault reports: 0x4310, excess temperature of
/// the drive.
pub(crate) const INJECTED_DRIVE_FAULT: u16 = 0x4310;

impl Injection {
    /// The size of the step `Injection::from_code` makes, mm (deg).
    pub const STEP_MM: f64 = 1.0;

    /// Decodes a `REQUEST_INJECT` value, `kind · 16 + n`: kind 1 a lasting drive fault on
    /// axis n (0–5 = X–C), 2 its cause removed, 3 a step of [`Injection::STEP_MM`] on axis
    /// n, 4 a stall of n × 10 cycles (n 0–15), 5 the simulated spindle stalled (n 1) or
    /// freed (n 0).
    pub(crate) fn from_code(code: u32) -> Option<Injection> {
        let (kind, arg) = (code / 16, (code % 16) as usize);
        match kind {
            1 if arg < 6 => Some(Injection::DriveFault(arg)),
            2 if arg < 6 => Some(Injection::ClearDriveFault(arg)),
            3 if arg < 6 => Some(Injection::Step(arg, Injection::STEP_MM)),
            4 => Some(Injection::Stall(arg as u32 * 10)),
            5 if arg < 2 => Some(Injection::SpindleStall(arg == 1)),
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
            Injection::SpindleStall(on) => Some(80 + u32::from(on)),
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
    pub state: MachineState,
    /// Source line of the motion.
    pub line: u32,
    /// Setpoint position, X Y Z mm, A B C deg.
    pub position: PerAxis<f64>,
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
    /// The EtherCAT bus, when the drives are on one.
    pub bus: Option<fieldbus::BusReport>,
    /// The last reset's tag and outcome.
    pub reset: Option<(u64, Result<(), ResetRefused>)>,
    /// Commands the cycle has taken and applied since the start (a request's answer
    /// waits until its command is among them).
    pub commands_applied: u64,
    /// The machine around the axes: pause, switches, tool, spindle, coolant, I/O.
    pub machine: MachineStatus,
    /// Homing, jogging and the axes' switches.
    pub manual: ManualStatus,
    /// The program during which the last wait on an input (its result in
    /// `machine.last_input`) ended; 0 when none.
    pub input_result_program: u64,
}

impl Snapshot {
    /// `true` when the program waits at a pause that cycle start ends (a program stop, a
    /// manual tool change, single block).
    pub fn waits_for_operator(&self) -> bool {
        self.machine
            .pause
            .is_some_and(|p| p.reason.needs_cycle_start())
    }
}
