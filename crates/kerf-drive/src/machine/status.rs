//! What the machine model shows: its status record, what the program waits for, the
//! result of the last wait on an input, and its latched faults.

use std::fmt;

use kerf_geom::machine::WaitMode;

use super::config::Switches;
use super::io::IoImage;
use super::spindle::SpindleStatus;

/// What the program waits for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PauseReason {
    /// Program stop (M0): cycle start continues.
    ProgramStop,
    /// Optional stop (M1, with the switch on): cycle start continues.
    OptionalStop,
    /// Pallet change pause (M60): cycle start continues.
    PalletChange,
    /// Single block: cycle start continues.
    SingleBlock,
    /// Manual tool change: the operator puts tool `tool` in the spindle and presses cycle
    /// start.
    ToolChange {
        /// The tool to insert (0: empty the spindle).
        tool: u32,
    },
    /// The automatic tool changer is changing to tool `tool`.
    ToolChanging {
        /// The tool.
        tool: u32,
    },
    /// The spindle is coming to rest before the change to tool `tool`.
    SpindleStop {
        /// The tool.
        tool: u32,
    },
    /// A wait on an input (M66).
    WaitInput {
        /// Input number.
        input: u8,
        /// An analog input.
        analog: bool,
        /// What ends the wait.
        mode: WaitMode,
    },
    /// The spindle coming up to speed before a feed move.
    AtSpeed,
    /// The spindle orienting (M19).
    Orient,
}

impl PauseReason {
    /// A short name: `program_stop`, `optional_stop`, `pallet_change`, `single_block`,
    /// `tool_change`, `tool_changing`, `spindle_stop`, `wait_input`, `at_speed`, `orient`.
    pub fn name(self) -> &'static str {
        match self {
            PauseReason::ProgramStop => "program_stop",
            PauseReason::OptionalStop => "optional_stop",
            PauseReason::PalletChange => "pallet_change",
            PauseReason::SingleBlock => "single_block",
            PauseReason::ToolChange { .. } => "tool_change",
            PauseReason::ToolChanging { .. } => "tool_changing",
            PauseReason::SpindleStop { .. } => "spindle_stop",
            PauseReason::WaitInput { .. } => "wait_input",
            PauseReason::AtSpeed => "at_speed",
            PauseReason::Orient => "orient",
        }
    }

    /// `true` if cycle start ([`Machine::resume`](super::Machine::resume)) ends it; the
    /// others end on their own (or time out).
    pub fn needs_cycle_start(self) -> bool {
        matches!(
            self,
            PauseReason::ProgramStop
                | PauseReason::OptionalStop
                | PauseReason::PalletChange
                | PauseReason::SingleBlock
                | PauseReason::ToolChange { .. }
        )
    }
}

/// What the program waits for, and since when.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PauseInfo {
    /// What.
    pub reason: PauseReason,
    /// The program line of the action.
    pub line: u32,
    /// Time since the machine took the action, s.
    pub waited_s: f64,
}

/// The result of the last wait on an input (M66), for `#5399`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InputResult {
    /// The program line of the M66.
    pub line: u32,
    /// A digital input's state (1 or 0), an analog input's value, or -1 on a timeout.
    pub value: f64,
    /// Counts the waits on an input resolved since start (the first is 1): the planner
    /// waits until it has passed the one it sent.
    pub seq: u64,
}

/// The coolant as commanded.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CoolantStatus {
    /// Mist (M7).
    pub mist: bool,
    /// Flood (M8).
    pub flood: bool,
}

/// Why a program was ended other than by its M2/M30.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EndCause {
    /// The operator aborted it.
    Abort,
    /// A fault dropped it.
    Fault,
}

/// A fault of the machine model, latched until [`Machine::reset`](super::Machine::reset).
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum MachineFault {
    /// The spindle did not reach its speed before a feed move within the timeout.
    SpindleNotAtSpeed {
        /// The line of the feed move that waited.
        line: u32,
        /// Commanded speed, rpm.
        commanded_rpm: f64,
        /// Actual speed, signed rpm (`None`: a spindle switched by outputs).
        actual_rpm: Option<f64>,
        /// Time waited, s.
        waited_s: f64,
    },
    /// The spindle left its speed band while the motion was feeding.
    SpindleOutOfBand {
        /// Commanded speed, rpm.
        commanded_rpm: f64,
        /// Actual speed, signed rpm (`None`: the at-speed input went off).
        actual_rpm: Option<f64>,
        /// The band, fraction of the commanded speed.
        tolerance: f64,
    },
    /// The spindle did not come to rest for a tool change within the at-speed timeout.
    SpindleNotStopped {
        /// The line of the tool change.
        line: u32,
        /// Actual speed, signed rpm.
        actual_rpm: Option<f64>,
        /// Time waited, s.
        waited_s: f64,
    },
    /// The spindle orient (M19) did not complete within its timeout.
    OrientTimeout {
        /// The line of the M19.
        line: u32,
        /// The timeout, s.
        timeout_s: f64,
    },
    /// The automatic tool changer did not answer within its timeout.
    ToolChangeTimeout {
        /// The line of the M6.
        line: u32,
        /// The tool.
        tool: u32,
        /// The digital input that did not answer.
        changed_input: u8,
        /// Time waited, s.
        waited_s: f64,
    },
}

impl MachineFault {
    /// A short name: `spindle_not_at_speed`, `spindle_out_of_band`,
    /// `spindle_not_stopped`, `orient_timeout`, `tool_change_timeout`.
    pub fn name(&self) -> &'static str {
        match self {
            MachineFault::SpindleNotAtSpeed { .. } => "spindle_not_at_speed",
            MachineFault::SpindleOutOfBand { .. } => "spindle_out_of_band",
            MachineFault::SpindleNotStopped { .. } => "spindle_not_stopped",
            MachineFault::OrientTimeout { .. } => "orient_timeout",
            MachineFault::ToolChangeTimeout { .. } => "tool_change_timeout",
        }
    }

    /// The program line it happened at (0 for the out-of-band fault, which the cycle
    /// places).
    pub fn line(&self) -> u32 {
        match *self {
            MachineFault::SpindleNotAtSpeed { line, .. }
            | MachineFault::SpindleNotStopped { line, .. }
            | MachineFault::OrientTimeout { line, .. }
            | MachineFault::ToolChangeTimeout { line, .. } => line,
            MachineFault::SpindleOutOfBand { .. } => 0,
        }
    }
}

/// "actual 3400 rpm", or what stands for it without feedback.
struct Actual(Option<f64>);

impl fmt::Display for Actual {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(rpm) => write!(f, "actual {rpm:.0} rpm"),
            None => f.write_str("no at-speed signal"),
        }
    }
}

impl fmt::Display for MachineFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            MachineFault::SpindleNotAtSpeed {
                line,
                commanded_rpm,
                actual_rpm,
                waited_s,
            } => write!(
                f,
                "spindle not at speed after {waited_s:.1} s: commanded {commanded_rpm:.0} rpm, {} (feed move at line {line})",
                Actual(actual_rpm)
            ),
            MachineFault::SpindleOutOfBand {
                commanded_rpm,
                actual_rpm,
                tolerance,
            } => write!(
                f,
                "spindle left its speed band (±{:.1} %) while feeding: commanded {commanded_rpm:.0} rpm, {}",
                tolerance * 100.0,
                Actual(actual_rpm)
            ),
            MachineFault::SpindleNotStopped {
                line,
                actual_rpm,
                waited_s,
            } => write!(
                f,
                "spindle did not stop for the tool change within {waited_s:.1} s: {} (line {line})",
                Actual(actual_rpm)
            ),
            MachineFault::OrientTimeout { line, timeout_s } => write!(
                f,
                "spindle orient (M19) not done within {timeout_s:.1} s (line {line})"
            ),
            MachineFault::ToolChangeTimeout {
                line,
                tool,
                changed_input,
                waited_s,
            } => write!(
                f,
                "tool change to T{tool} not done after {waited_s:.1} s: the tool changer did not answer on digital input {changed_input} (line {line})"
            ),
        }
    }
}

impl std::error::Error for MachineFault {}

/// The machine model's state as the status shows it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MachineStatus {
    /// What the program waits for, if anything (a pause, a tool change, the spindle, an
    /// input).
    pub pause: Option<PauseInfo>,
    /// The runtime switches.
    pub switches: Switches,
    /// The tool in the spindle (0: none).
    pub tool_in_spindle: u32,
    /// The spindle, if the machine has one.
    pub spindle: Option<SpindleStatus>,
    /// The coolant as commanded.
    pub coolant: CoolantStatus,
    /// The feed override applies (M48/M49/M50); the motion core's business, kept here
    /// because the program sets it with the motion.
    pub feed_override_enabled: bool,
    /// The I/O image.
    pub io: IoImage,
    /// The result of the last wait on an input.
    pub last_input: Option<InputResult>,
    /// The latched fault, if any.
    pub fault: Option<MachineFault>,
}
