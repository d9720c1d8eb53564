//! The daemon's other messages: [`SetpointMsg`] every cycle, and [`Request`] /
//! [`Response`] (with its [`StatusMsg`]) on the control service.

use iceoryx2::prelude::ZeroCopySend;

use crate::{AXES, BUS_MAX_SUBDEVICES, PROTOCOL_VERSION, read_text, write_text};

/// Daemon state: no program running, at rest.
pub const STATE_IDLE: u32 = 0;
/// Daemon state: executing a program.
pub const STATE_RUNNING: u32 = 1;
/// Daemon state: feed hold (decelerating or stopped on the path; RESUME continues).
pub const STATE_HOLDING: u32 = 2;
/// Daemon state: stopped or stopping at the end of the queued geometry because the planner
/// did not deliver in time; continues when moves arrive.
pub const STATE_STARVED: u32 = 3;
/// Daemon state: a fault stopped the motion; see the status' `fault` and `fault_text`.
pub const STATE_FAULT: u32 = 4;
/// Daemon state: aborting (decelerating to rest, then the queue is dropped).
pub const STATE_STOPPING: u32 = 5;
/// Daemon state: the program waits at rest for something (`pause_reason`): a program
/// stop, a manual tool change or single block (cycle start, [`REQUEST_RESUME`], goes on),
/// the spindle, an input or the tool changer (it goes on by itself).
pub const STATE_PAUSED: u32 = 6;
/// Daemon state: no program runs and an axis moves by hand: a jog, or homing (the status's
/// `jogging` and `homing` say which).
pub const STATE_MANUAL: u32 = 7;

/// The daemon's state, decoded from a `state` field with [`TryFrom<u32>`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MachineState {
    /// [`STATE_IDLE`].
    Idle,
    /// [`STATE_RUNNING`].
    Running,
    /// [`STATE_HOLDING`].
    Holding,
    /// [`STATE_STARVED`].
    Starved,
    /// [`STATE_FAULT`].
    Fault,
    /// [`STATE_STOPPING`].
    Stopping,
    /// [`STATE_PAUSED`].
    Paused,
    /// [`STATE_MANUAL`].
    Manual,
}

/// A `state` value that is none of the `STATE_*` constants.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown daemon state {0}")]
pub struct UnknownState(pub u32);

impl MachineState {
    /// The `STATE_*` value.
    pub fn as_u32(self) -> u32 {
        match self {
            MachineState::Idle => STATE_IDLE,
            MachineState::Running => STATE_RUNNING,
            MachineState::Holding => STATE_HOLDING,
            MachineState::Starved => STATE_STARVED,
            MachineState::Fault => STATE_FAULT,
            MachineState::Stopping => STATE_STOPPING,
            MachineState::Paused => STATE_PAUSED,
            MachineState::Manual => STATE_MANUAL,
        }
    }

    /// Lowercase name: "idle", "running", ...
    pub fn as_str(self) -> &'static str {
        match self {
            MachineState::Idle => "idle",
            MachineState::Running => "running",
            MachineState::Holding => "holding",
            MachineState::Starved => "starved",
            MachineState::Fault => "fault",
            MachineState::Stopping => "stopping",
            MachineState::Paused => "paused",
            MachineState::Manual => "manual",
        }
    }
}

impl TryFrom<u32> for MachineState {
    type Error = UnknownState;

    fn try_from(v: u32) -> Result<MachineState, UnknownState> {
        Ok(match v {
            STATE_IDLE => MachineState::Idle,
            STATE_RUNNING => MachineState::Running,
            STATE_HOLDING => MachineState::Holding,
            STATE_STARVED => MachineState::Starved,
            STATE_FAULT => MachineState::Fault,
            STATE_STOPPING => MachineState::Stopping,
            STATE_PAUSED => MachineState::Paused,
            STATE_MANUAL => MachineState::Manual,
            other => return Err(UnknownState(other)),
        })
    }
}

/// One real-time cycle's output, published on the setpoints service every cycle.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[type_name("kerf.SetpointMsg.v6")]
pub struct SetpointMsg {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// `STATE_*` at the end of the cycle.
    pub state: u32,
    /// Cycle number since the daemon started (0 = first cycle); consecutive unless
    /// messages were lost.
    pub seq: u64,
    /// CLOCK_MONOTONIC time of the cycle's deadline, ns.
    pub time_ns: u64,
    /// The program started last (0 = none since the daemon started).
    pub program_id: u64,
    /// Cycles since that program's first cycle (0 on the cycle that starts it). It keeps
    /// counting while idle after the program, so `(program_id, program_cycle)` is a time
    /// base for recordings; 0 while `program_id` is 0.
    pub program_cycle: u64,
    /// Commanded position X, Y, Z mm, A, B, C degrees.
    pub position_mm_deg: [f64; AXES],
    /// Commanded velocity X, Y, Z mm/s, A, B, C deg/s.
    pub velocity_mm_deg_s: [f64; AXES],
    /// Feed along the path, mm/s (after override).
    pub feed_mm_s: f64,
    /// Source line of the move being executed (0 = none).
    pub line: u32,
    /// Bit i set: axis i (X, Y, Z, A, B, C) is configured; other entries are 0.
    pub axes_mask: u32,
    /// Periods since the daemon started in which no cycle ran (missed deadlines): between
    /// two samples its increase is the number of periods skipped between them, and
    /// `time_ns` advances by `(1 + increase) × period`. (A gap in `seq` is samples lost
    /// on the way, not periods missed.)
    pub missed_periods: u64,
}

impl SetpointMsg {
    /// All fields zero except `version`.
    pub fn new() -> SetpointMsg {
        SetpointMsg {
            version: PROTOCOL_VERSION,
            state: STATE_IDLE,
            seq: 0,
            time_ns: 0,
            program_id: 0,
            program_cycle: 0,
            position_mm_deg: [0.0; AXES],
            velocity_mm_deg_s: [0.0; AXES],
            feed_mm_s: 0.0,
            line: 0,
            axes_mask: 0,
            missed_periods: 0,
        }
    }

    /// The decoded state.
    pub fn state(&self) -> Result<MachineState, UnknownState> {
        MachineState::try_from(self.state)
    }
}

impl Default for SetpointMsg {
    fn default() -> Self {
        SetpointMsg::new()
    }
}

/// Request kind: reply with the status only.
pub const REQUEST_STATUS: u32 = 1;
/// Request kind: feed hold.
pub const REQUEST_HOLD: u32 = 2;
/// Request kind: cycle start: resume after a feed hold, and go on after a pause that
/// waits for the operator (a program stop, a manual tool change, single block).
pub const REQUEST_RESUME: u32 = 3;
/// Request kind: abort the program (stop smoothly, drop the queue).
pub const REQUEST_ABORT: u32 = 4;
/// Request kind: set the feed override to `value` percent (0..=200).
pub const REQUEST_OVERRIDE: u32 = 5;
/// Request kind: clear the latched fault of the drive side once its cause is gone; the
/// response comes once the reset has ended (refused with the reason while the cause
/// persists).
pub const REQUEST_RESET: u32 = 6;
/// Request kind: write the black-box recorder to a file; the response's message is the
/// file's absolute path.
pub const REQUEST_DUMP: u32 = 7;
/// Request kind, for tests only: inject a fault below the motion core (`value`: the
/// injection code, a whole number; see `docs/DRIVES.md`). A daemon started without
/// `--test-faults` refuses it with [`REASON_NOT_ALLOWED`].
pub const REQUEST_INJECT: u32 = 8;
/// The highest feed override [`REQUEST_OVERRIDE`] accepts, percent (200: the machine's
/// highest override, [`kerf_geom::MAX_FEED_OVERRIDE`]).
pub const MAX_OVERRIDE_PCT: f64 = kerf_geom::MAX_FEED_OVERRIDE * 100.0;
/// Request kind: the fate of program `program_id` (the response's `program_fate`, and for
/// a refused or aborted program the reason in its message). The daemon remembers the last
/// [`PROGRAMS_REMEMBERED`] programs.
pub const REQUEST_PROGRAM: u32 = 9;

/// Request kind: the optional-stop switch (M1 pauses while on): `value` 1 on, 0 off.
pub const REQUEST_OPTIONAL_STOP: u32 = 10;
/// Request kind: the block-delete switch (lines starting with `/` are skipped by programs
/// sent from now on): `value` 1 on, 0 off.
pub const REQUEST_BLOCK_DELETE: u32 = 11;
/// Request kind: the single-block switch (a pause after every block planned from now on):
/// `value` 1 on, 0 off.
pub const REQUEST_SINGLE_BLOCK: u32 = 12;
/// Request kind: the spindle override, `value` percent (0..=200).
pub const REQUEST_SPINDLE_OVERRIDE: u32 = 13;
/// Request kind: set simulated digital input `index` (0..=63) to `value` (1 on, 0 off);
/// refused with [`REASON_NOT_ALLOWED`] for an input that is not simulated.
pub const REQUEST_SET_INPUT: u32 = 14;
/// Request kind: set simulated analog input `index` (0..=15) to `value`; refused with
/// [`REASON_NOT_ALLOWED`] for an input that is not simulated.
pub const REQUEST_SET_ANALOG_INPUT: u32 = 15;
/// Request kind: jog axis `index` (0–5 = X–C): `mode` is `JOG_*`, `value` its direction,
/// step or target, `speed` the speed in mm/s or deg/s (0: the configured default). A
/// continuous jog moves while the same request is renewed within the configured dead-man
/// time and stops on a jerk-limited ramp when the renewals stop.
pub const REQUEST_JOG: u32 = 16;
/// Request kind: stop the jog of axis `index` on a jerk-limited ramp.
pub const REQUEST_JOG_STOP: u32 = 17;
/// Request kind: home the axes of bit mask `index` (bit i: axis i), in the configured
/// sequence; the status tells the progress (`homing`, `home_phase`) and the end (`homed`,
/// or a fault).
pub const REQUEST_HOME: u32 = 18;
/// [`REQUEST_JOG`] mode: move while renewed; `value` +1 or -1 is the direction.
pub const JOG_CONTINUOUS: u32 = 1;
/// [`REQUEST_JOG`] mode: move by `value` (signed, not 0) and stop there exactly.
pub const JOG_STEP: u32 = 2;
/// [`REQUEST_JOG`] mode: move to machine coordinate `value` and stop there exactly.
pub const JOG_TO: u32 = 3;
/// `StatusMsg::home_phase`: not homing.
pub const HOME_PHASE_IDLE: u8 = 0;
/// `StatusMsg::home_phase`: waiting for the axes of an earlier home sequence number.
pub const HOME_PHASE_WAITING: u8 = 1;
/// `StatusMsg::home_phase`: moving off a home switch that was already active.
pub const HOME_PHASE_MOVE_OFF: u8 = 2;
/// `StatusMsg::home_phase`: searching for the home switch at the search velocity.
pub const HOME_PHASE_SEARCH: u8 = 3;
/// `StatusMsg::home_phase`: backing off the switch before the latch.
pub const HOME_PHASE_BACK_OFF: u8 = 4;
/// `StatusMsg::home_phase`: latching the switch's edge at the latch velocity.
pub const HOME_PHASE_LATCH: u8 = 5;
/// `StatusMsg::home_phase`: moving to the home position.
pub const HOME_PHASE_FINAL: u8 = 6;
/// The highest spindle override [`REQUEST_SPINDLE_OVERRIDE`] accepts, percent.
pub const MAX_SPINDLE_OVERRIDE_PCT: f64 = 200.0;
/// Digital inputs and outputs a machine has at most (numbers 0 to 63).
pub const DIGITAL_IO: usize = 64;
/// Analog inputs and outputs a machine has at most (numbers 0 to 15).
pub const ANALOG_IO: usize = 16;

/// How many programs (the last ones whose BEGIN arrived, accepted or refused) the daemon
/// remembers for [`REQUEST_PROGRAM`].
pub const PROGRAMS_REMEMBERED: usize = 256;

/// `Response.program_fate`: the daemon knows no program of this id (never seen, or more
/// than [`PROGRAMS_REMEMBERED`] programs ago); also the value for every other request.
pub const PROGRAM_FATE_UNKNOWN: u32 = 0;
/// `Response.program_fate`: its BEGIN was accepted and its items are being received (its
/// motion may have started).
pub const PROGRAM_FATE_RECEIVING: u32 = 1;
/// `Response.program_fate`: received to its END; running or about to run.
pub const PROGRAM_FATE_RUNNING: u32 = 2;
/// `Response.program_fate`: ran to its end; the machine is at rest.
pub const PROGRAM_FATE_FINISHED: u32 = 3;
/// `Response.program_fate`: aborted (`kerf abort`, a shutdown); the message says so.
pub const PROGRAM_FATE_ABORTED: u32 = 4;
/// `Response.program_fate`: refused (its BEGIN, a message or a move), or stopped by the
/// safety layer; the message says why.
pub const PROGRAM_FATE_REFUSED: u32 = 5;

/// A request from a client to the daemon on the control service.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[type_name("kerf.Request.v6")]
pub struct Request {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// `REQUEST_*`.
    pub kind: u32,
    /// Chosen by the client, echoed in the response.
    pub id: u64,
    /// [`REQUEST_OVERRIDE`]: percent, 0..=200; 0 for every other kind.
    pub value: f64,
    /// [`REQUEST_PROGRAM`]: the program asked about (not 0); 0 for every other kind.
    pub program_id: u64,
    /// [`REQUEST_SET_INPUT`], [`REQUEST_SET_ANALOG_INPUT`]: the input's number;
    /// [`REQUEST_JOG`], [`REQUEST_JOG_STOP`]: the axis (0–5 = X–C); [`REQUEST_HOME`]: the
    /// axes' bit mask; 0 for every other kind.
    pub index: u32,
    /// [`REQUEST_JOG`]: `JOG_*`; 0 for every other kind.
    pub mode: u32,
    /// [`REQUEST_JOG`]: the speed, mm/s or deg/s (0: the configured default); 0 for every
    /// other kind.
    pub speed: f64,
}

/// A validated request.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ControlCommand {
    /// [`REQUEST_STATUS`].
    Status,
    /// [`REQUEST_HOLD`].
    Hold,
    /// [`REQUEST_RESUME`].
    Resume,
    /// [`REQUEST_ABORT`].
    Abort,
    /// [`REQUEST_OVERRIDE`].
    Override {
        /// Feed override, percent (0..=200).
        percent: f64,
    },
    /// [`REQUEST_RESET`].
    Reset,
    /// [`REQUEST_DUMP`].
    Dump,
    /// [`REQUEST_INJECT`] (tests only).
    Inject {
        /// The injection code.
        code: u32,
    },
    /// [`REQUEST_PROGRAM`].
    Program {
        /// The program asked about.
        program_id: u64,
    },
    /// [`REQUEST_OPTIONAL_STOP`], [`REQUEST_BLOCK_DELETE`], [`REQUEST_SINGLE_BLOCK`].
    Switch {
        /// Which.
        switch: Switch,
        /// On or off.
        on: bool,
    },
    /// [`REQUEST_SPINDLE_OVERRIDE`].
    SpindleOverride {
        /// Percent, 0..=200.
        percent: f64,
    },
    /// [`REQUEST_SET_INPUT`], [`REQUEST_SET_ANALOG_INPUT`].
    SetInput {
        /// An analog input (else digital).
        analog: bool,
        /// Its number.
        index: u32,
        /// The value (digital: 1 or 0).
        value: f64,
    },
    /// [`REQUEST_JOG`].
    Jog {
        /// The axis, 0–5 = X–C.
        axis: u8,
        /// How it moves.
        jog: Jog,
        /// mm/s or deg/s; 0: the configured default.
        speed: f64,
    },
    /// [`REQUEST_JOG_STOP`].
    JogStop {
        /// The axis, 0–5 = X–C.
        axis: u8,
    },
    /// [`REQUEST_HOME`].
    Home {
        /// Bit i: home axis i.
        axes: u32,
    },
}

/// How a [`ControlCommand::Jog`] moves its axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Jog {
    /// While renewed, in the positive (`true`) or negative direction ([`JOG_CONTINUOUS`]).
    Continuous(bool),
    /// By this distance, signed, mm or deg ([`JOG_STEP`]).
    Step(f64),
    /// To this machine coordinate, mm or deg ([`JOG_TO`]).
    To(f64),
}

impl Jog {
    /// The `JOG_*` mode and the request's `value`.
    pub fn mode_value(self) -> (u32, f64) {
        match self {
            Jog::Continuous(positive) => (JOG_CONTINUOUS, if positive { 1.0 } else { -1.0 }),
            Jog::Step(d) => (JOG_STEP, d),
            Jog::To(x) => (JOG_TO, x),
        }
    }
}

/// The operator's switches ([`ControlCommand::Switch`]; `StatusMsg::switches` bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Switch {
    /// M1 pauses while on ([`SWITCH_OPTIONAL_STOP`]).
    OptionalStop,
    /// `/` lines are skipped while on ([`SWITCH_BLOCK_DELETE`]).
    BlockDelete,
    /// A pause after every block while on ([`SWITCH_SINGLE_BLOCK`]).
    SingleBlock,
}

impl Switch {
    /// Its bit in `StatusMsg::switches`.
    pub fn bit(self) -> u32 {
        match self {
            Switch::OptionalStop => SWITCH_OPTIONAL_STOP,
            Switch::BlockDelete => SWITCH_BLOCK_DELETE,
            Switch::SingleBlock => SWITCH_SINGLE_BLOCK,
        }
    }

    /// Its name as `kerf` spells it: "optional-stop", "block-delete", "single-block".
    pub fn as_str(self) -> &'static str {
        match self {
            Switch::OptionalStop => "optional-stop",
            Switch::BlockDelete => "block-delete",
            Switch::SingleBlock => "single-block",
        }
    }
}

/// Why a [`Request`] was refused; [`RequestReject::reason`] is the response's code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RequestReject {
    /// Another protocol version.
    #[error("protocol version {0}, expected {PROTOCOL_VERSION}")]
    WrongVersion(u32),
    /// Unknown request kind.
    #[error("unknown request kind {0}")]
    UnknownKind(u32),
    /// The value is out of range, not finite, or not zero for a kind without one.
    #[error("request value or program id out of range")]
    BadValue,
}

impl RequestReject {
    /// The `REASON_*` code for a response.
    pub fn reason(self) -> u32 {
        match self {
            RequestReject::WrongVersion(_) => REASON_WRONG_VERSION,
            RequestReject::UnknownKind(_) => REASON_UNKNOWN_KIND,
            RequestReject::BadValue => REASON_BAD_VALUE,
        }
    }
}

impl Request {
    /// A request of this protocol version.
    pub fn new(kind: u32, id: u64, value: f64) -> Request {
        Request {
            version: PROTOCOL_VERSION,
            kind,
            id,
            value,
            program_id: 0,
            index: 0,
            mode: 0,
            speed: 0.0,
        }
    }

    /// The request for `command`.
    pub fn from_command(command: ControlCommand, id: u64) -> Request {
        let (kind, value) = match command {
            ControlCommand::Status => (REQUEST_STATUS, 0.0),
            ControlCommand::Hold => (REQUEST_HOLD, 0.0),
            ControlCommand::Resume => (REQUEST_RESUME, 0.0),
            ControlCommand::Abort => (REQUEST_ABORT, 0.0),
            ControlCommand::Override { percent } => (REQUEST_OVERRIDE, percent),
            ControlCommand::Reset => (REQUEST_RESET, 0.0),
            ControlCommand::Dump => (REQUEST_DUMP, 0.0),
            ControlCommand::Inject { code } => (REQUEST_INJECT, f64::from(code)),
            ControlCommand::Program { program_id } => {
                let mut r = Request::new(REQUEST_PROGRAM, id, 0.0);
                r.program_id = program_id;
                return r;
            }
            ControlCommand::Switch { switch, on } => {
                let kind = match switch {
                    Switch::OptionalStop => REQUEST_OPTIONAL_STOP,
                    Switch::BlockDelete => REQUEST_BLOCK_DELETE,
                    Switch::SingleBlock => REQUEST_SINGLE_BLOCK,
                };
                (kind, if on { 1.0 } else { 0.0 })
            }
            ControlCommand::SpindleOverride { percent } => (REQUEST_SPINDLE_OVERRIDE, percent),
            ControlCommand::SetInput {
                analog,
                index,
                value,
            } => {
                let kind = if analog {
                    REQUEST_SET_ANALOG_INPUT
                } else {
                    REQUEST_SET_INPUT
                };
                let mut r = Request::new(kind, id, value);
                r.index = index;
                return r;
            }
            ControlCommand::Jog { axis, jog, speed } => {
                let (mode, value) = jog.mode_value();
                let mut r = Request::new(REQUEST_JOG, id, value);
                r.index = u32::from(axis);
                r.mode = mode;
                r.speed = speed;
                return r;
            }
            ControlCommand::JogStop { axis } => {
                let mut r = Request::new(REQUEST_JOG_STOP, id, 0.0);
                r.index = u32::from(axis);
                return r;
            }
            ControlCommand::Home { axes } => {
                let mut r = Request::new(REQUEST_HOME, id, 0.0);
                r.index = axes;
                return r;
            }
        };
        Request::new(kind, id, value)
    }

    /// Validates the request.
    pub fn command(&self) -> Result<ControlCommand, RequestReject> {
        if self.version != PROTOCOL_VERSION {
            return Err(RequestReject::WrongVersion(self.version));
        }
        if let REQUEST_JOG..=REQUEST_HOME = self.kind {
            return self.manual_command();
        }
        if self.mode != 0 || self.speed.to_bits() != 0 {
            return Err(RequestReject::BadValue);
        }
        if let REQUEST_SET_INPUT | REQUEST_SET_ANALOG_INPUT = self.kind {
            let analog = self.kind == REQUEST_SET_ANALOG_INPUT;
            let (count, value_ok) = if analog {
                (ANALOG_IO, self.value.is_finite())
            } else {
                (DIGITAL_IO, self.value == 0.0 || self.value == 1.0)
            };
            if self.program_id != 0 || self.index as usize >= count || !value_ok {
                return Err(RequestReject::BadValue);
            }
            return Ok(ControlCommand::SetInput {
                analog,
                index: self.index,
                value: self.value,
            });
        }
        if self.index != 0 && self.kind <= REQUEST_SPINDLE_OVERRIDE {
            return Err(RequestReject::BadValue);
        }
        if self.kind == REQUEST_PROGRAM {
            if self.program_id == 0 || self.value.to_bits() != 0 {
                return Err(RequestReject::BadValue);
            }
            return Ok(ControlCommand::Program {
                program_id: self.program_id,
            });
        }
        let known = matches!(
            self.kind,
            REQUEST_STATUS..=REQUEST_INJECT | REQUEST_OPTIONAL_STOP..=REQUEST_SPINDLE_OVERRIDE
        );
        if self.program_id != 0 && known {
            return Err(RequestReject::BadValue);
        }
        let command = match self.kind {
            REQUEST_STATUS => ControlCommand::Status,
            REQUEST_HOLD => ControlCommand::Hold,
            REQUEST_RESUME => ControlCommand::Resume,
            REQUEST_ABORT => ControlCommand::Abort,
            REQUEST_RESET => ControlCommand::Reset,
            REQUEST_DUMP => ControlCommand::Dump,
            REQUEST_INJECT => {
                let v = self.value;
                if !(v >= 0.0 && v <= f64::from(u32::MAX) && v.fract() == 0.0) {
                    return Err(RequestReject::BadValue);
                }
                // A whole number within the range: the cast is exact.
                return Ok(ControlCommand::Inject { code: v as u32 });
            }
            REQUEST_OVERRIDE => {
                if !(0.0..=MAX_OVERRIDE_PCT).contains(&self.value) {
                    return Err(RequestReject::BadValue);
                }
                return Ok(ControlCommand::Override {
                    percent: self.value,
                });
            }
            REQUEST_SPINDLE_OVERRIDE => {
                if !(0.0..=MAX_SPINDLE_OVERRIDE_PCT).contains(&self.value) {
                    return Err(RequestReject::BadValue);
                }
                return Ok(ControlCommand::SpindleOverride {
                    percent: self.value,
                });
            }
            REQUEST_OPTIONAL_STOP | REQUEST_BLOCK_DELETE | REQUEST_SINGLE_BLOCK => {
                if self.value != 0.0 && self.value != 1.0 {
                    return Err(RequestReject::BadValue);
                }
                let switch = match self.kind {
                    REQUEST_OPTIONAL_STOP => Switch::OptionalStop,
                    REQUEST_BLOCK_DELETE => Switch::BlockDelete,
                    _ => Switch::SingleBlock,
                };
                return Ok(ControlCommand::Switch {
                    switch,
                    on: self.value == 1.0,
                });
            }
            other => return Err(RequestReject::UnknownKind(other)),
        };
        if self.value.to_bits() != 0 {
            return Err(RequestReject::BadValue);
        }
        Ok(command)
    }
}

impl Request {
    /// Validates a [`REQUEST_JOG`], [`REQUEST_JOG_STOP`] or [`REQUEST_HOME`].
    fn manual_command(&self) -> Result<ControlCommand, RequestReject> {
        let axis_ok = (self.index as usize) < AXES;
        if self.program_id != 0 {
            return Err(RequestReject::BadValue);
        }
        let still = self.value.to_bits() == 0 && self.mode == 0 && self.speed.to_bits() == 0;
        match self.kind {
            REQUEST_JOG => {
                if !(axis_ok && self.speed.is_finite() && self.speed >= 0.0) {
                    return Err(RequestReject::BadValue);
                }
                let v = self.value;
                let jog = match self.mode {
                    JOG_CONTINUOUS if v == 1.0 || v == -1.0 => Jog::Continuous(v > 0.0),
                    JOG_STEP if v.is_finite() && v != 0.0 => Jog::Step(v),
                    JOG_TO if v.is_finite() => Jog::To(v),
                    _ => return Err(RequestReject::BadValue),
                };
                Ok(ControlCommand::Jog {
                    // Below 6: the cast is exact.
                    axis: self.index as u8,
                    jog,
                    speed: self.speed,
                })
            }
            REQUEST_JOG_STOP if axis_ok && still => Ok(ControlCommand::JogStop {
                axis: self.index as u8,
            }),
            REQUEST_HOME if still && self.index != 0 && self.index < 1 << AXES => {
                Ok(ControlCommand::Home { axes: self.index })
            }
            _ => Err(RequestReject::BadValue),
        }
    }
}

/// Response reason: accepted.
pub const REASON_OK: u32 = 0;
/// Response reason: the request has another protocol version.
pub const REASON_WRONG_VERSION: u32 = 1;
/// Response reason: unknown request kind.
pub const REASON_UNKNOWN_KIND: u32 = 2;
/// Response reason: value out of range.
pub const REASON_BAD_VALUE: u32 = 3;
/// Response reason: not possible in the current state (e.g. RESUME while not holding).
pub const REASON_NOT_ALLOWED: u32 = 4;
/// Response reason: the request kind is reserved and not implemented yet.
pub const REASON_NOT_IMPLEMENTED: u32 = 5;

/// The daemon's status, embedded in every [`Response`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[type_name("kerf.StatusMsg.v6")]
pub struct StatusMsg {
    /// `STATE_*`.
    pub state: u32,
    /// Source line of the move being executed (0 = none).
    pub line: u32,
    /// Commanded position X, Y, Z mm, A, B, C degrees.
    pub position_mm_deg: [f64; AXES],
    /// Feed override, percent.
    pub override_pct: f64,
    /// Moves queued in the daemon (received, not yet finished).
    pub queued_moves: u64,
    /// Motion time of the queued moves at the current feed, s (an estimate).
    pub queued_s: f64,
    /// Real-time cycles run since the daemon started.
    pub cycles: u64,
    /// Cycles that missed their deadline since the daemon started.
    pub overruns: u64,
    /// 1 when the real-time thread runs with real-time scheduling, else 0.
    pub rt: u32,
    /// 1 when the current program was received to its END, fully executed and the machine
    /// is at rest, else 0.
    pub program_done: u32,
    /// The current (last started) program, 0 = none.
    pub program_id: u64,
    /// Items (moves and events) of the current program accepted by the daemon; the
    /// client's flow-control acknowledgement.
    pub moves_received: u64,
    /// Items the client may have sent but not yet acknowledged (`moves_received`): the
    /// flow-control window, items.
    pub window_items: u64,
    /// Move messages rejected since the daemon started.
    pub rejected: u64,
    /// Fault code, 0 = none.
    pub fault: u32,
    /// Bit i set: axis i (X, Y, Z, A, B, C) is configured.
    pub axes_mask: u32,
    /// Fault description, UTF-8, NUL-padded (see [`StatusMsg::fault_text`]).
    pub fault_text: [u8; 128],
    /// Real-time cycle period, ns.
    pub period_ns: u64,
    /// How program `program_id` ended: `PROGRAM_END_*` (`PROGRAM_END_NONE` while it runs).
    pub program_end: u32,
    /// What the drive side does: `DRIVES_*`.
    pub drives: u32,
    /// The safety check that tripped the latched fault: `SAFETY_*` (`SAFETY_NONE` when no
    /// fault is latched).
    pub safety_check: u32,
    /// The axis of the latched fault, 0–5 = X–C, or [`SAFETY_AXIS_NONE`].
    pub safety_axis: u32,
    /// The value that tripped (its unit is the check's: see `docs/DRIVES.md`).
    pub safety_value: f64,
    /// The limit it was checked against, same unit.
    pub safety_limit: f64,
    /// The program line of the cycle that tripped (0 = none).
    pub safety_line: u32,
    /// The error code (0x603F) the faulted drive reports, 0 = none.
    pub drive_error_code: u32,
    /// The cycle of the trip, counted from the drives' enabling.
    pub safety_cycle: u64,
    /// The black-box file written at the latched fault, UTF-8, NUL-padded (empty until
    /// written; see [`StatusMsg::fault_dump`]).
    pub fault_dump: [u8; 160],
    /// EtherCAT subdevices on the bus (ring positions 0 to `bus_subdevices - 1`); 0 when
    /// the drives are not on an EtherCAT bus, and then every `bus_*` and `dc_*` field is
    /// 0. Readers take at most [`BUS_MAX_SUBDEVICES`] ([`StatusMsg::bus_positions`]).
    pub bus_subdevices: u32,
    /// 1 while a reset brings the bus back to OP, else 0.
    pub bus_recovering: u32,
    /// Each subdevice's AL state by ring position (`BUS_STATE_*`; 0 = unknown), as the
    /// last exchange that came back saw it; 0 beyond `bus_subdevices`.
    pub bus_states: [u8; BUS_MAX_SUBDEVICES],
    /// Each subdevice's AL status code (ETG.1000.6) by ring position, as last read (when
    /// it left OP, or during a reset's recovery); 0 = none.
    pub bus_al_codes: [u16; BUS_MAX_SUBDEVICES],
    /// Cycles whose process data was exchanged completely, since the bus came up.
    pub bus_cycles_complete: u64,
    /// Cycles whose frame did not come back in time.
    pub bus_cycles_lost: u64,
    /// Cycles whose working counter was short (a subdevice did not take part).
    pub bus_cycles_short: u64,
    /// Cycles in which a subdevice was not in OP.
    pub bus_cycles_not_op: u64,
    /// The most consecutive incomplete cycles seen, cycles.
    pub bus_longest_gap_cycles: u32,
    /// 1 when the bus runs with distributed clocks (the `dc_*` fields below), else 0.
    pub dc_used: u32,
    /// The last cycle's offset of its start from its place before SYNC0, ns (positive =
    /// late).
    pub dc_offset_ns: i64,
    /// Median of |offset| over the cycles measured, ns.
    pub dc_offset_abs_p50_ns: u64,
    /// 99th percentile of |offset|, ns.
    pub dc_offset_abs_p99_ns: u64,
    /// 99.9th percentile of |offset|, ns.
    pub dc_offset_abs_p999_ns: u64,
    /// Largest |offset|, ns.
    pub dc_offset_abs_max_ns: u64,
    /// Cycles whose offset was measured (the distribution's sample count).
    pub dc_samples: u64,
    /// What the program waits for at rest (`PAUSE_*`; the state is [`STATE_PAUSED`]
    /// unless a hold or fault says more); [`PAUSE_NONE`] when nothing.
    pub pause_reason: u32,
    /// The source line of the pause; 0 when none.
    pub pause_line: u32,
    /// [`PAUSE_TOOL_CHANGE`], [`PAUSE_TOOL_CHANGING`]: the tool; [`PAUSE_WAIT_INPUT`]:
    /// the input's number; otherwise 0.
    pub pause_value: u32,
    /// The operator's switches: `SWITCH_*` bits.
    pub switches: u32,
    /// The tool in the spindle (0: none).
    pub tool_in_spindle: u32,
    /// The tool changer: `TOOL_CHANGER_*`.
    pub tool_changer: u32,
    /// The length of the tool in the spindle in the tool table, mm (0 without a tool or
    /// entry).
    pub tool_length_mm: f64,
    /// The spindle: `SPINDLE_*` (its kind); [`SPINDLE_NONE`] makes every `spindle_*`
    /// field 0.
    pub spindle_kind: u32,
    /// The commanded direction: 1 clockwise (M3), -1 counter-clockwise (M4), 0 stopped.
    pub spindle_dir: i32,
    /// The programmed speed (S), rpm.
    pub spindle_programmed_rpm: f64,
    /// The commanded speed after the override and the speed range, rpm, signed by the
    /// direction (0 when stopped).
    pub spindle_commanded_rpm: f64,
    /// The spindle's actual speed, rpm, signed (the drive's feedback, or for a spindle on
    /// outputs the commanded speed once at speed).
    pub spindle_actual_rpm: f64,
    /// The spindle override, percent (0 to 200).
    pub spindle_override_pct: f64,
    /// Flag: 1 when the spindle turns at its commanded speed (within the at-speed band).
    pub spindle_at_speed: u32,
    /// Bits: [`OVERRIDES_FEED`], [`OVERRIDES_SPINDLE`] when that override is enabled (M48
    /// to M51).
    pub overrides_enabled: u32,
    /// Bits: [`COOLANT_MIST`], [`COOLANT_FLOOD`] when that coolant output is on.
    pub coolant: u32,
    /// The line of the last wait on an input (M66) that ended; 0 when none.
    pub input_result_line: u32,
    /// The digital outputs: bit n = output n on.
    pub digital_outputs: u64,
    /// The digital inputs: bit n = input n on.
    pub digital_inputs: u64,
    /// The analog outputs 0 to 15.
    pub analog_outputs: [f64; ANALOG_IO],
    /// The analog inputs 0 to 15.
    pub analog_inputs: [f64; ANALOG_IO],
    /// Waits on an input (M66) ended since the daemon started: a planner process waiting
    /// for one to resolve `#5399` waits for this to pass the count it knew.
    pub input_result_seq: u64,
    /// The program of the last wait on an input that ended.
    pub input_result_program: u64,
    /// Its result, as `#5399`: the input's value, or -1 when the wait timed out.
    pub input_result_value: f64,
    /// What the pause waits for in words ("insert tool T3 (length 45.200 mm)"), UTF-8,
    /// NUL-padded; empty when nothing.
    pub pause_text: [u8; 96],
    /// Bit i: axis i is homed (its machine coordinates are known).
    pub homed: u32,
    /// 1 when programs and MDI are refused until every axis is homed
    /// (`[homing] required`), else 0.
    pub homing_required: u32,
    /// Bit i: axis i is homing (a `REQUEST_HOME` is carrying it out or waits to).
    pub homing: u32,
    /// Bit i: axis i is jogging (moving under a jog request, or ramping to rest after one).
    pub jogging: u32,
    /// Bit i: axis i's home switch is active.
    pub home_switches: u32,
    /// Bit i: axis i's lower hard limit switch is active.
    pub min_limit_switches: u32,
    /// Bit i: axis i's upper hard limit switch is active.
    pub max_limit_switches: u32,
    /// Bit i: axis i stands on a hard limit switch after a reset and may be jogged away
    /// from it only.
    pub limit_released: u32,
    /// Each axis's homing phase, X to C (`HOME_PHASE_*`); the last two bytes are 0.
    pub home_phase: [u8; 8],
}

/// `StatusMsg::pause_reason`: nothing.
pub const PAUSE_NONE: u32 = 0;
/// A program stop (M0): cycle start goes on.
pub const PAUSE_PROGRAM_STOP: u32 = 1;
/// An optional stop (M1, the switch on): cycle start goes on.
pub const PAUSE_OPTIONAL_STOP: u32 = 2;
/// A pallet change (M60): cycle start goes on.
pub const PAUSE_PALLET_CHANGE: u32 = 3;
/// Single block: the block before ended; cycle start runs the next.
pub const PAUSE_SINGLE_BLOCK: u32 = 4;
/// A manual tool change: insert tool `pause_value`, then cycle start.
pub const PAUSE_TOOL_CHANGE: u32 = 5;
/// The automatic tool changer is changing to tool `pause_value`.
pub const PAUSE_TOOL_CHANGING: u32 = 6;
/// A wait on input `pause_value` (M66).
pub const PAUSE_WAIT_INPUT: u32 = 7;
/// A wait for the spindle to reach its speed before a feed move.
pub const PAUSE_AT_SPEED: u32 = 8;
/// A wait for the spindle's orientation (M19).
pub const PAUSE_ORIENT: u32 = 9;
/// `StatusMsg::switches`: optional stop on.
pub const SWITCH_OPTIONAL_STOP: u32 = 1;
/// `StatusMsg::switches`: block delete on.
pub const SWITCH_BLOCK_DELETE: u32 = 2;
/// `StatusMsg::switches`: single block on.
pub const SWITCH_SINGLE_BLOCK: u32 = 4;
/// `StatusMsg::tool_changer`: M6 is refused.
pub const TOOL_CHANGER_NONE: u32 = 0;
/// `StatusMsg::tool_changer`: the operator changes tools at a pause.
pub const TOOL_CHANGER_MANUAL: u32 = 1;
/// `StatusMsg::tool_changer`: an automatic changer (output/input handshake).
pub const TOOL_CHANGER_AUTOMATIC: u32 = 2;
/// `StatusMsg::spindle_kind`: no spindle.
pub const SPINDLE_NONE: u32 = 0;
/// `StatusMsg::spindle_kind`: a drive in velocity mode (simulated, or CiA 402 CSV).
pub const SPINDLE_DRIVE: u32 = 1;
/// `StatusMsg::spindle_kind`: enable/direction outputs and an analog speed output.
pub const SPINDLE_OUTPUTS: u32 = 2;
/// `StatusMsg::overrides_enabled`: the feed override is enabled.
pub const OVERRIDES_FEED: u32 = 1;
/// `StatusMsg::overrides_enabled`: the spindle override is enabled.
pub const OVERRIDES_SPINDLE: u32 = 2;
/// `StatusMsg::coolant`: mist (M7) on.
pub const COOLANT_MIST: u32 = 1;
/// `StatusMsg::coolant`: flood (M8) on.
pub const COOLANT_FLOOD: u32 = 2;

/// `StatusMsg::bus_states`: the AL state INIT.
pub const BUS_STATE_INIT: u8 = 1;
/// `StatusMsg::bus_states`: the AL state PRE-OP (mailbox, no process data).
pub const BUS_STATE_PRE_OP: u8 = 2;
/// `StatusMsg::bus_states`: the AL state BOOT (firmware update).
pub const BUS_STATE_BOOT: u8 = 3;
/// `StatusMsg::bus_states`: the AL state SAFE-OP (inputs exchanged, outputs ignored).
pub const BUS_STATE_SAFE_OP: u8 = 4;
/// `StatusMsg::bus_states`: the AL state OP (process data exchanged both ways).
pub const BUS_STATE_OP: u8 = 8;

/// `StatusMsg::drives`: the drives are being enabled; no motion yet.
pub const DRIVES_ENABLING: u32 = 1;
/// `StatusMsg::drives`: every drive enabled, setpoints pass the safety checks.
pub const DRIVES_RUNNING: u32 = 2;
/// `StatusMsg::drives`: a missed cycle; the last position is held.
pub const DRIVES_HOLDING: u32 = 3;
/// `StatusMsg::drives`: a fault is latched and the quick stop ramps every axis to rest.
pub const DRIVES_QUICK_STOP: u32 = 4;
/// `StatusMsg::drives`: a fault is latched and every axis is at rest; `kerf reset`.
pub const DRIVES_STOPPED: u32 = 5;
/// `StatusMsg::drives`: a reset is in progress.
pub const DRIVES_RESETTING: u32 = 6;

/// `StatusMsg::safety_check`: no fault latched.
pub const SAFETY_NONE: u32 = 0;
/// `StatusMsg::safety_check`: a setpoint's step over the period above the velocity limit.
pub const SAFETY_VELOCITY: u32 = 1;
/// `StatusMsg::safety_check`: the setpoints' second difference above the acceleration
/// limit.
pub const SAFETY_ACCELERATION: u32 = 2;
/// `StatusMsg::safety_check`: a setpoint outside the soft limits.
pub const SAFETY_SOFT_LIMIT: u32 = 3;
/// `StatusMsg::safety_check`: following error above its limit.
pub const SAFETY_FOLLOWING_ERROR: u32 = 4;
/// `StatusMsg::safety_check`: too many consecutive missed cycles.
pub const SAFETY_STREAM_STALL: u32 = 5;
/// `StatusMsg::safety_check`: a drive reported a fault.
pub const SAFETY_DRIVE_FAULT: u32 = 6;
/// `StatusMsg::safety_check`: a drive did not enable within its timeout.
pub const SAFETY_ENABLE_TIMEOUT: u32 = 7;
/// `StatusMsg::safety_check`: a drive left Operation enabled on its own.
pub const SAFETY_DRIVE_DISABLED: u32 = 8;
/// `StatusMsg::safety_check`: the fieldbus stopped carrying the cyclic data (lost frames
/// or a short working counter, more cycles in a row than allowed).
pub const SAFETY_FIELDBUS: u32 = 9;
/// `StatusMsg::safety_check`: an EtherCAT subdevice left OP on its own; `safety_value` is
/// its ring position, `safety_limit` its AL status code.
pub const SAFETY_SUBDEVICE_STATE: u32 = 10;
/// Safety check: the spindle did not reach its speed within the at-speed timeout before a
/// feed move (`safety_value` its actual, `safety_limit` its commanded speed, rpm).
pub const SAFETY_SPINDLE_AT_SPEED: u32 = 11;
/// Safety check: the spindle left its at-speed band while the axes fed (value actual,
/// limit commanded, rpm).
pub const SAFETY_SPINDLE_BAND: u32 = 12;
/// Safety check: the spindle's orientation (M19) did not end in time (value the time
/// waited, limit the timeout, s).
pub const SAFETY_SPINDLE_ORIENT: u32 = 13;
/// Safety check: the automatic tool changer did not report the change done in time
/// (value the tool, limit the timeout, s).
pub const SAFETY_TOOL_CHANGE: u32 = 14;
/// Safety check: the spindle's drive on the fieldbus failed; `safety_limit` says how (0:
/// a fault, `safety_value` its error code; 1: it did not enable, the value the timeout in
/// cycles; 2: it left Operation enabled on its own).
pub const SAFETY_SPINDLE_DRIVE: u32 = 15;
/// Safety check: homing found no home switch within the search distance (`safety_value`
/// the distance travelled, `safety_limit` the configured search distance, mm or deg).
pub const SAFETY_HOME_SEARCH: u32 = 16;
/// Safety check: homing moved off (or backed off) the home switch for the search distance
/// and it did not release (value, limit as [`SAFETY_HOME_SEARCH`]).
pub const SAFETY_HOME_RELEASE: u32 = 17;
/// Safety check: homing found no latch edge of the home switch within the search distance
/// (value, limit as [`SAFETY_HOME_SEARCH`]).
pub const SAFETY_HOME_LATCH: u32 = 18;
/// Safety check: a hard limit switch is active (`safety_value` -1 the lower, +1 the upper
/// one).
pub const SAFETY_HARD_LIMIT: u32 = 19;
/// Safety check: the axis's drive ended its own homing (CiA 402 homing mode) in an error,
/// or did not take the homing mode (`safety_value` the drive's error code, 0 when it
/// gives none).
pub const SAFETY_DRIVE_HOMING: u32 = 20;
/// `StatusMsg::safety_axis` of a fault that is not an axis's (a stream stall).
pub const SAFETY_AXIS_NONE: u32 = 255;

/// `StatusMsg::program_end`: the program still runs, or there is none.
pub const PROGRAM_END_NONE: u32 = 0;
/// `StatusMsg::program_end`: the program ran to its end and the machine is at rest.
pub const PROGRAM_END_FINISHED: u32 = 1;
/// `StatusMsg::program_end`: the program was aborted (`kerf abort`, a shutdown); the
/// machine stopped on the path.
pub const PROGRAM_END_ABORTED: u32 = 2;
/// `StatusMsg::program_end`: the daemon refused a message or move of the program and
/// stopped it at the end of its last valid move; `fault_text` says why.
pub const PROGRAM_END_REFUSED: u32 = 3;

impl StatusMsg {
    /// All fields zero.
    pub fn zeroed() -> StatusMsg {
        StatusMsg {
            state: STATE_IDLE,
            line: 0,
            position_mm_deg: [0.0; AXES],
            override_pct: 0.0,
            queued_moves: 0,
            queued_s: 0.0,
            cycles: 0,
            overruns: 0,
            rt: 0,
            program_done: 0,
            program_id: 0,
            moves_received: 0,
            window_items: 0,
            rejected: 0,
            fault: 0,
            axes_mask: 0,
            fault_text: [0; 128],
            period_ns: 0,
            program_end: PROGRAM_END_NONE,
            drives: 0,
            safety_check: SAFETY_NONE,
            safety_axis: SAFETY_AXIS_NONE,
            safety_value: 0.0,
            safety_limit: 0.0,
            safety_line: 0,
            drive_error_code: 0,
            safety_cycle: 0,
            fault_dump: [0; 160],
            bus_subdevices: 0,
            bus_recovering: 0,
            bus_states: [0; BUS_MAX_SUBDEVICES],
            bus_al_codes: [0; BUS_MAX_SUBDEVICES],
            bus_cycles_complete: 0,
            bus_cycles_lost: 0,
            bus_cycles_short: 0,
            bus_cycles_not_op: 0,
            bus_longest_gap_cycles: 0,
            dc_used: 0,
            dc_offset_ns: 0,
            dc_offset_abs_p50_ns: 0,
            dc_offset_abs_p99_ns: 0,
            dc_offset_abs_p999_ns: 0,
            dc_offset_abs_max_ns: 0,
            dc_samples: 0,
            pause_reason: PAUSE_NONE,
            pause_line: 0,
            pause_value: 0,
            switches: 0,
            tool_in_spindle: 0,
            tool_changer: TOOL_CHANGER_NONE,
            tool_length_mm: 0.0,
            spindle_kind: SPINDLE_NONE,
            spindle_dir: 0,
            spindle_programmed_rpm: 0.0,
            spindle_commanded_rpm: 0.0,
            spindle_actual_rpm: 0.0,
            spindle_override_pct: 0.0,
            spindle_at_speed: 0,
            overrides_enabled: 0,
            coolant: 0,
            input_result_line: 0,
            digital_outputs: 0,
            digital_inputs: 0,
            analog_outputs: [0.0; ANALOG_IO],
            analog_inputs: [0.0; ANALOG_IO],
            input_result_seq: 0,
            input_result_program: 0,
            input_result_value: 0.0,
            pause_text: [0; 96],
            homed: 0,
            homing_required: 0,
            homing: 0,
            jogging: 0,
            home_switches: 0,
            min_limit_switches: 0,
            max_limit_switches: 0,
            limit_released: 0,
            home_phase: [HOME_PHASE_IDLE; 8],
        }
    }

    /// The decoded state.
    pub fn state(&self) -> Result<MachineState, UnknownState> {
        MachineState::try_from(self.state)
    }

    /// Sets `fault_text`, truncated at a character boundary to 128 bytes.
    pub fn set_fault_text(&mut self, text: &str) {
        write_text(&mut self.fault_text, text);
    }

    /// `fault_text` up to its first NUL (its valid UTF-8 prefix).
    pub fn fault_text(&self) -> &str {
        read_text(&self.fault_text)
    }

    /// Sets `fault_dump`, truncated at a character boundary to 160 bytes.
    pub fn set_fault_dump(&mut self, path: &str) {
        write_text(&mut self.fault_dump, path);
    }

    /// `fault_dump` up to its first NUL (its valid UTF-8 prefix).
    pub fn fault_dump(&self) -> &str {
        read_text(&self.fault_dump)
    }

    /// Sets `pause_text`, truncated at a character boundary to 96 bytes.
    pub fn set_pause_text(&mut self, text: &str) {
        write_text(&mut self.pause_text, text);
    }

    /// `pause_text` up to its first NUL (its valid UTF-8 prefix).
    pub fn pause_text(&self) -> &str {
        read_text(&self.pause_text)
    }

    /// The ring positions the bus section describes: `bus_subdevices`, at most
    /// [`BUS_MAX_SUBDEVICES`] whatever a writer left there; 0 without an EtherCAT bus.
    pub fn bus_positions(&self) -> usize {
        usize::try_from(self.bus_subdevices)
            .map_or(BUS_MAX_SUBDEVICES, |n| n.min(BUS_MAX_SUBDEVICES))
    }
}

impl Default for StatusMsg {
    fn default() -> Self {
        StatusMsg::zeroed()
    }
}

/// The daemon's answer to a [`Request`]: whether it was accepted, why not, and the status
/// after handling it.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[type_name("kerf.Response.v6")]
pub struct Response {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// 1 accepted, 0 refused.
    pub accepted: u32,
    /// The request's `id`.
    pub request_id: u64,
    /// `REASON_*`.
    pub reason: u32,
    /// [`REQUEST_PROGRAM`]: the program's `PROGRAM_FATE_*`; 0 for every other request.
    pub program_fate: u32,
    /// Human-readable message, UTF-8, NUL-padded (see [`Response::message`]).
    pub message: [u8; 224],
    /// The status after the request was handled.
    pub status: StatusMsg,
}

impl Response {
    /// An accepted (`reason` [`REASON_OK`]) or refused response to request `request_id`,
    /// with `message` truncated at a character boundary to 224 bytes.
    pub fn new(request_id: u64, reason: u32, message: &str, status: StatusMsg) -> Response {
        let mut r = Response {
            version: PROTOCOL_VERSION,
            accepted: u32::from(reason == REASON_OK),
            request_id,
            reason,
            program_fate: PROGRAM_FATE_UNKNOWN,
            message: [0; 224],
            status,
        };
        r.set_message(message);
        r
    }

    /// Sets `message`, truncated at a character boundary to 224 bytes.
    pub fn set_message(&mut self, text: &str) {
        write_text(&mut self.message, text);
    }

    /// `message` up to its first NUL (its valid UTF-8 prefix).
    pub fn message(&self) -> &str {
        read_text(&self.message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn states_round_trip_and_unknown_is_refused() {
        let all = [
            MachineState::Idle,
            MachineState::Running,
            MachineState::Holding,
            MachineState::Starved,
            MachineState::Fault,
            MachineState::Stopping,
            MachineState::Paused,
            MachineState::Manual,
        ];
        for s in all {
            assert_eq!(MachineState::try_from(s.as_u32()), Ok(s));
        }
        assert_eq!(MachineState::Paused.as_u32(), 6);
        assert_eq!(MachineState::Manual.as_u32(), 7);
        assert_eq!(MachineState::try_from(8), Err(UnknownState(8)));
        assert_eq!(
            MachineState::try_from(u32::MAX),
            Err(UnknownState(u32::MAX))
        );
    }

    #[test]
    fn requests_validate() {
        for (c, kind) in [
            (ControlCommand::Status, REQUEST_STATUS),
            (ControlCommand::Hold, REQUEST_HOLD),
            (ControlCommand::Resume, REQUEST_RESUME),
            (ControlCommand::Abort, REQUEST_ABORT),
            (
                ControlCommand::Override { percent: 150.0 },
                REQUEST_OVERRIDE,
            ),
            (ControlCommand::Reset, REQUEST_RESET),
            (ControlCommand::Dump, REQUEST_DUMP),
            (ControlCommand::Inject { code: 17 }, REQUEST_INJECT),
        ] {
            let r = Request::from_command(c, 7);
            assert_eq!(r.kind, kind);
            assert_eq!(r.command(), Ok(c));
        }
        let ovr = |v| Request::new(REQUEST_OVERRIDE, 1, v).command();
        assert_eq!(ovr(0.0), Ok(ControlCommand::Override { percent: 0.0 }));
        assert_eq!(ovr(200.0), Ok(ControlCommand::Override { percent: 200.0 }));
        assert_eq!(ovr(200.5), Err(RequestReject::BadValue));
        assert_eq!(ovr(-1.0), Err(RequestReject::BadValue));
        assert_eq!(ovr(f64::NAN), Err(RequestReject::BadValue));
        assert_eq!(
            Request::new(REQUEST_HOLD, 1, 3.0).command(),
            Err(RequestReject::BadValue)
        );
        assert_eq!(
            Request::new(0, 1, 0.0).command(),
            Err(RequestReject::UnknownKind(0))
        );
        let inject = |v| Request::new(REQUEST_INJECT, 1, v).command();
        assert_eq!(inject(0.0), Ok(ControlCommand::Inject { code: 0 }));
        assert_eq!(inject(1.5), Err(RequestReject::BadValue));
        assert_eq!(inject(-1.0), Err(RequestReject::BadValue));
        assert_eq!(inject(f64::NAN), Err(RequestReject::BadValue));
        assert_eq!(inject(4294967296.0), Err(RequestReject::BadValue));
        assert_eq!(
            Request::new(REQUEST_DUMP, 1, 1.0).command(),
            Err(RequestReject::BadValue)
        );
        let mut old = Request::new(REQUEST_STATUS, 1, 0.0);
        old.version = 1;
        assert_eq!(old.command(), Err(RequestReject::WrongVersion(1)));
        assert_eq!(RequestReject::BadValue.reason(), REASON_BAD_VALUE);
    }

    #[test]
    fn machine_requests_validate() {
        let switch = |switch, on| ControlCommand::Switch { switch, on };
        for (c, kind, value, index) in [
            (
                switch(Switch::OptionalStop, true),
                REQUEST_OPTIONAL_STOP,
                1.0,
                0,
            ),
            (
                switch(Switch::BlockDelete, false),
                REQUEST_BLOCK_DELETE,
                0.0,
                0,
            ),
            (
                switch(Switch::SingleBlock, true),
                REQUEST_SINGLE_BLOCK,
                1.0,
                0,
            ),
            (
                ControlCommand::SpindleOverride { percent: 80.0 },
                REQUEST_SPINDLE_OVERRIDE,
                80.0,
                0,
            ),
            (
                ControlCommand::SetInput {
                    analog: false,
                    index: 63,
                    value: 1.0,
                },
                REQUEST_SET_INPUT,
                1.0,
                63,
            ),
            (
                ControlCommand::SetInput {
                    analog: true,
                    index: 15,
                    value: -2.5,
                },
                REQUEST_SET_ANALOG_INPUT,
                -2.5,
                15,
            ),
        ] {
            let r = Request::from_command(c, 3);
            assert_eq!((r.kind, r.value, r.index), (kind, value, index));
            assert_eq!(r.command(), Ok(c));
        }
        let req = |kind, value, index| {
            let mut r = Request::new(kind, 1, value);
            r.index = index;
            r.command()
        };
        // A switch is 0 or 1; a digital input 0 or 1 and 0 to 63; an analog one any finite
        // value, 0 to 15; the override 0 to 200 %.
        assert_eq!(
            req(REQUEST_OPTIONAL_STOP, 0.5, 0),
            Err(RequestReject::BadValue)
        );
        assert_eq!(req(REQUEST_SET_INPUT, 2.0, 0), Err(RequestReject::BadValue));
        assert_eq!(
            req(REQUEST_SET_INPUT, 1.0, 64),
            Err(RequestReject::BadValue)
        );
        assert_eq!(
            req(REQUEST_SET_ANALOG_INPUT, 1.0, 16),
            Err(RequestReject::BadValue)
        );
        assert_eq!(
            req(REQUEST_SET_ANALOG_INPUT, f64::INFINITY, 0),
            Err(RequestReject::BadValue)
        );
        assert_eq!(
            req(REQUEST_SPINDLE_OVERRIDE, 200.1, 0),
            Err(RequestReject::BadValue)
        );
        // The index belongs to the input and manual requests only, mode and speed to the
        // jog.
        assert_eq!(req(REQUEST_HOLD, 0.0, 1), Err(RequestReject::BadValue));
        let mut r = Request::new(REQUEST_STATUS, 1, 0.0);
        r.mode = 1;
        assert_eq!(r.command(), Err(RequestReject::BadValue));
        let mut r = Request::new(REQUEST_STATUS, 1, 0.0);
        r.speed = 1.0;
        assert_eq!(r.command(), Err(RequestReject::BadValue));
    }

    #[test]
    fn manual_requests_validate() {
        for c in [
            ControlCommand::Jog {
                axis: 0,
                jog: Jog::Continuous(true),
                speed: 0.0,
            },
            ControlCommand::Jog {
                axis: 5,
                jog: Jog::Continuous(false),
                speed: 12.5,
            },
            ControlCommand::Jog {
                axis: 2,
                jog: Jog::Step(-0.1),
                speed: 1.0,
            },
            ControlCommand::Jog {
                axis: 1,
                jog: Jog::To(-250.0),
                speed: 0.0,
            },
            ControlCommand::JogStop { axis: 3 },
            ControlCommand::Home { axes: 0b111 },
            ControlCommand::Home { axes: 0b10_0000 },
        ] {
            assert_eq!(Request::from_command(c, 4).command(), Ok(c));
        }
        let jog = |index: u32, mode: u32, value: f64, speed: f64| {
            let mut r = Request::new(REQUEST_JOG, 1, value);
            r.index = index;
            r.mode = mode;
            r.speed = speed;
            r.command()
        };
        let bad = Err(RequestReject::BadValue);
        assert_eq!(jog(6, JOG_STEP, 1.0, 0.0), bad, "axis 6 does not exist");
        assert_eq!(jog(0, 0, 1.0, 0.0), bad, "no mode");
        assert_eq!(jog(0, 4, 1.0, 0.0), bad, "unknown mode");
        assert_eq!(jog(0, JOG_CONTINUOUS, 0.5, 0.0), bad, "a direction is +-1");
        assert_eq!(jog(0, JOG_STEP, 0.0, 0.0), bad, "a step of nothing");
        assert_eq!(jog(0, JOG_STEP, f64::NAN, 0.0), bad);
        assert_eq!(jog(0, JOG_TO, f64::INFINITY, 0.0), bad);
        assert_eq!(jog(0, JOG_TO, 1.0, -1.0), bad, "a negative speed");
        assert_eq!(jog(0, JOG_TO, 1.0, f64::NAN), bad);
        let mut r = Request::new(REQUEST_HOME, 1, 0.0);
        assert_eq!(r.command(), bad, "no axis to home");
        r.index = 64;
        assert_eq!(r.command(), bad, "bit 6 is no axis");
        r.index = 1;
        r.speed = 1.0;
        assert_eq!(r.command(), bad, "homing takes no speed");
        let mut r = Request::new(REQUEST_JOG_STOP, 1, 1.0);
        assert_eq!(r.command(), bad, "a stop takes no value");
        r.value = 0.0;
        r.program_id = 3;
        assert_eq!(r.command(), bad);
    }

    #[test]
    fn response_text_fields() {
        let mut st = StatusMsg::zeroed();
        let long = "é".repeat(100); // 200 bytes
        st.set_fault_text(&long);
        assert_eq!(st.fault_text(), "é".repeat(64));
        let r = Response::new(9, REASON_NOT_ALLOWED, "not holding", st);
        assert_eq!(r.accepted, 0);
        assert_eq!(r.message(), "not holding");
        assert_eq!(r.status.fault_text().len(), 128);
        let ok = Response::new(9, REASON_OK, "", st);
        assert_eq!(ok.accepted, 1);
        assert_eq!(ok.message(), "");
    }
}
