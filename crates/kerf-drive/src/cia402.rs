//! The CiA 402 drive profile (IEC 61800-7-201) as far as a cyclic synchronous position
//! master needs it: the controlword 0x6040 and its commands, the statusword 0x6041 and
//! the decoding of the power state, the [`Drive`] interface of one drive, the [`Scale`]
//! between machine units and drive counts, and the master-side [`Enabler`] that takes a
//! drive to Operation enabled without a jump.
//!
//! Everything here is allocation-free and has no clock: time is a number of cycles.

use thiserror::Error;

/// Object index of the controlword.
pub const CONTROLWORD_INDEX: u16 = 0x6040;
/// Object index of the statusword.
pub const STATUSWORD_INDEX: u16 = 0x6041;
/// Object index of the error code (last fault).
pub const ERROR_CODE_INDEX: u16 = 0x603F;
/// Object index of the modes of operation.
pub const MODES_OF_OPERATION_INDEX: u16 = 0x6060;
/// Object index of the position actual value (counts).
pub const POSITION_ACTUAL_INDEX: u16 = 0x6064;
/// Object index of the velocity actual value (counts per second).
pub const VELOCITY_ACTUAL_INDEX: u16 = 0x606C;
/// Object index of the following error actual value (counts).
pub const FOLLOWING_ERROR_ACTUAL_INDEX: u16 = 0x60F4;
/// Object index of the target position (counts).
pub const TARGET_POSITION_INDEX: u16 = 0x607A;

/// Object index of the homing method (i8; see [`homing_method`]).
pub const HOMING_METHOD_INDEX: u16 = 0x6098;
/// Object index of the homing speeds (u32, counts/s): sub-index
/// [`HOMING_SPEED_SWITCH_SUBINDEX`] the speed during the search for the switch,
/// [`HOMING_SPEED_ZERO_SUBINDEX`] the speed during the search for zero (the slow approach
/// of the edge).
pub const HOMING_SPEEDS_INDEX: u16 = 0x6099;
/// Sub-index 1 of [`HOMING_SPEEDS_INDEX`]: speed during the search for the switch.
pub const HOMING_SPEED_SWITCH_SUBINDEX: u8 = 0x01;
/// Sub-index 2 of [`HOMING_SPEEDS_INDEX`]: speed during the search for zero.
pub const HOMING_SPEED_ZERO_SUBINDEX: u8 = 0x02;
/// Object index of the homing acceleration (u32, counts/s²).
pub const HOMING_ACCELERATION_INDEX: u16 = 0x609A;
/// Object index of the home offset (i32, counts): the position actual value the drive
/// gives the home position once homing is attained.
pub const HOME_OFFSET_INDEX: u16 = 0x607C;

/// Mode of operation 6: homing (the drive moves on its own to find its home position).
pub const MODE_HOMING: i8 = 6;
/// Mode of operation 8: cyclic synchronous position.
pub const MODE_CYCLIC_SYNC_POSITION: i8 = 8;

/// The homing methods (0x6098) Kerf names; CiA 402 defines 1 to 37 (and negative numbers
/// for the manufacturer's own).
pub mod homing_method {
    /// Method 19: positive home switch; the home position is where the switch falls
    /// (becomes inactive) moving in the negative direction.
    pub const POSITIVE_SWITCH_FALLING: i8 = 19;
    /// Method 20: positive home switch; the home position is where the switch rises
    /// (becomes active) moving in the positive direction.
    pub const POSITIVE_SWITCH_RISING: i8 = 20;
    /// Method 21: negative home switch; the home position is where the switch falls
    /// moving in the positive direction.
    pub const NEGATIVE_SWITCH_FALLING: i8 = 21;
    /// Method 22: negative home switch; the home position is where the switch rises
    /// moving in the negative direction.
    pub const NEGATIVE_SWITCH_RISING: i8 = 22;
    /// Method 35: the current position is the home position; no motion (the older number
    /// of method 37, still found on drives).
    pub const CURRENT_POSITION_35: i8 = 35;
    /// Method 37: the current position is the home position; no motion.
    pub const CURRENT_POSITION: i8 = 37;
    /// The lowest method CiA 402 defines.
    pub const FIRST: i8 = 1;
    /// The highest method CiA 402 defines.
    pub const LAST: i8 = 37;
}

/// Controlword bits (0x6040).
pub mod cw {
    /// Bit 0: switch on.
    pub const SWITCH_ON: u16 = 1 << 0;
    /// Bit 1: enable voltage.
    pub const ENABLE_VOLTAGE: u16 = 1 << 1;
    /// Bit 2: quick stop (active low: 0 commands a quick stop).
    pub const QUICK_STOP: u16 = 1 << 2;
    /// Bit 3: enable operation.
    pub const ENABLE_OPERATION: u16 = 1 << 3;
    /// Bit 4 in homing mode: homing operation start (its rising edge starts the homing,
    /// its falling edge interrupts it).
    pub const HOMING_START: u16 = 1 << 4;
    /// Bit 7: fault reset (acts on the rising edge).
    pub const FAULT_RESET: u16 = 1 << 7;
    /// Bit 8: halt.
    pub const HALT: u16 = 1 << 8;

    /// Command Shutdown (transitions 2, 6, 8).
    pub const SHUTDOWN: u16 = 0x0006;
    /// Command Switch on (transition 3).
    pub const SWITCH_ON_CMD: u16 = 0x0007;
    /// Command Disable operation (transition 5); the same bits as Switch on.
    pub const DISABLE_OPERATION: u16 = 0x0007;
    /// Command Enable operation (transitions 4, and 3+4 from Ready to switch on).
    pub const ENABLE_OPERATION_CMD: u16 = 0x000F;
    /// Command Disable voltage (transitions 7, 9, 10, 12).
    pub const DISABLE_VOLTAGE: u16 = 0x0000;
    /// Command Quick stop (transitions 7, 10, 11).
    pub const QUICK_STOP_CMD: u16 = 0x0002;
}

/// Statusword bits (0x6041).
pub mod sw {
    /// Bit 0: ready to switch on.
    pub const READY_TO_SWITCH_ON: u16 = 1 << 0;
    /// Bit 1: switched on.
    pub const SWITCHED_ON: u16 = 1 << 1;
    /// Bit 2: operation enabled.
    pub const OPERATION_ENABLED: u16 = 1 << 2;
    /// Bit 3: fault.
    pub const FAULT: u16 = 1 << 3;
    /// Bit 4: voltage enabled.
    pub const VOLTAGE_ENABLED: u16 = 1 << 4;
    /// Bit 5: quick stop (active low: 0 while a quick stop is active).
    pub const QUICK_STOP: u16 = 1 << 5;
    /// Bit 6: switch on disabled.
    pub const SWITCH_ON_DISABLED: u16 = 1 << 6;
    /// Bit 7: warning.
    pub const WARNING: u16 = 1 << 7;
    /// Bit 9: remote (the controlword is processed).
    pub const REMOTE: u16 = 1 << 9;
    /// Bit 10: target reached.
    pub const TARGET_REACHED: u16 = 1 << 10;
    /// Bit 11: internal limit active.
    pub const INTERNAL_LIMIT_ACTIVE: u16 = 1 << 11;
    /// Bit 12 in cyclic synchronous position: the drive follows the target.
    pub const DRIVE_FOLLOWS_TARGET: u16 = 1 << 12;
    /// Bit 13 in cyclic synchronous position: following error.
    pub const FOLLOWING_ERROR: u16 = 1 << 13;
    /// Bit 12 in homing mode: homing attained (with bit 10: homing completed).
    pub const HOMING_ATTAINED: u16 = 1 << 12;
    /// Bit 13 in homing mode: homing error (with bit 10: the motor is at rest).
    pub const HOMING_ERROR: u16 = 1 << 13;
}

/// What the statusword says of a homing in homing mode (bits 13, 12 and 10, as CiA 402
/// defines them there).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HomingStatus {
    /// 0 0 0: the homing is in progress.
    InProgress,
    /// 0 0 1: the homing was interrupted or not started.
    Idle,
    /// 0 1 0: the home position was found but the target is not reached yet.
    AttainedMoving,
    /// 0 1 1: the homing completed: home found, at rest there.
    Completed,
    /// 1 0 0: a homing error; the motor still moves.
    ErrorMoving,
    /// 1 0 1: a homing error; the motor is at rest.
    ErrorAtRest,
    /// 1 1 x: reserved.
    Reserved,
}

impl HomingStatus {
    /// Decodes bits 13, 12 and 10 of a statusword read in homing mode.
    pub fn from_statusword(statusword: u16) -> HomingStatus {
        let error = statusword & sw::HOMING_ERROR != 0;
        let attained = statusword & sw::HOMING_ATTAINED != 0;
        let reached = statusword & sw::TARGET_REACHED != 0;
        match (error, attained, reached) {
            (false, false, false) => HomingStatus::InProgress,
            (false, false, true) => HomingStatus::Idle,
            (false, true, false) => HomingStatus::AttainedMoving,
            (false, true, true) => HomingStatus::Completed,
            (true, false, false) => HomingStatus::ErrorMoving,
            (true, false, true) => HomingStatus::ErrorAtRest,
            (true, true, _) => HomingStatus::Reserved,
        }
    }

    /// The statusword bits 13, 12 and 10 that show this status (bit 13 and 12 for
    /// [`HomingStatus::Reserved`]).
    pub fn statusword_bits(self) -> u16 {
        match self {
            HomingStatus::InProgress => 0,
            HomingStatus::Idle => sw::TARGET_REACHED,
            HomingStatus::AttainedMoving => sw::HOMING_ATTAINED,
            HomingStatus::Completed => sw::HOMING_ATTAINED | sw::TARGET_REACHED,
            HomingStatus::ErrorMoving => sw::HOMING_ERROR,
            HomingStatus::ErrorAtRest => sw::HOMING_ERROR | sw::TARGET_REACHED,
            HomingStatus::Reserved => sw::HOMING_ERROR | sw::HOMING_ATTAINED,
        }
    }
}

/// A power state of the CiA 402 state machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DriveState {
    /// Not ready to switch on (initialising).
    NotReadyToSwitchOn,
    /// Switch on disabled.
    SwitchOnDisabled,
    /// Ready to switch on.
    ReadyToSwitchOn,
    /// Switched on.
    SwitchedOn,
    /// Operation enabled.
    OperationEnabled,
    /// Quick stop active.
    QuickStopActive,
    /// Fault reaction active.
    FaultReactionActive,
    /// Fault.
    Fault,
}

/// The standard's state decoding table: (mask, value, state). Bits 0-3, 5 and 6 decide.
const STATE_TABLE: [(u16, u16, DriveState); 8] = [
    (0x004F, 0x0000, DriveState::NotReadyToSwitchOn),
    (0x004F, 0x0040, DriveState::SwitchOnDisabled),
    (0x006F, 0x0021, DriveState::ReadyToSwitchOn),
    (0x006F, 0x0023, DriveState::SwitchedOn),
    (0x006F, 0x0027, DriveState::OperationEnabled),
    (0x006F, 0x0007, DriveState::QuickStopActive),
    (0x004F, 0x000F, DriveState::FaultReactionActive),
    (0x004F, 0x0008, DriveState::Fault),
];

impl DriveState {
    /// Decodes a statusword; `None` for a pattern the standard does not define.
    pub fn from_statusword(statusword: u16) -> Option<DriveState> {
        STATE_TABLE
            .iter()
            .find(|(mask, value, _)| statusword & mask == *value)
            .map(|(_, _, state)| *state)
    }

    /// The statusword bits 0-6 that show this state (bit 4 voltage enabled set where
    /// the power stage has voltage; bits 7-15 left to the caller).
    pub fn statusword_bits(self) -> u16 {
        match self {
            DriveState::NotReadyToSwitchOn => 0x0000,
            DriveState::SwitchOnDisabled => 0x0040,
            DriveState::ReadyToSwitchOn => 0x0031,
            DriveState::SwitchedOn => 0x0033,
            DriveState::OperationEnabled => 0x0037,
            DriveState::QuickStopActive => 0x0017,
            DriveState::FaultReactionActive => 0x001F,
            DriveState::Fault => 0x0008,
        }
    }
}

/// A controlword command as the standard's command table decodes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DriveCommand {
    /// Shutdown: 0xxx x110.
    Shutdown,
    /// Switch on, or Disable operation: 0xxx 0111.
    SwitchOn,
    /// Enable operation (or Switch on + Enable operation): 0xxx 1111.
    EnableOperation,
    /// Disable voltage: 0xxx xx0x.
    DisableVoltage,
    /// Quick stop: 0xxx x01x.
    QuickStop,
}

impl DriveCommand {
    /// Decodes a controlword; `None` when bit 7 (fault reset) is set, since every
    /// command of the table has bit 7 clear. The fault reset is the rising edge of bit 7
    /// and is seen by comparing two controlwords (see [`is_fault_reset_edge`]).
    pub fn from_controlword(controlword: u16) -> Option<DriveCommand> {
        if controlword & cw::FAULT_RESET != 0 {
            None
        } else if controlword & cw::ENABLE_VOLTAGE == 0 {
            Some(DriveCommand::DisableVoltage)
        } else if controlword & cw::QUICK_STOP == 0 {
            Some(DriveCommand::QuickStop)
        } else if controlword & cw::SWITCH_ON == 0 {
            Some(DriveCommand::Shutdown)
        } else if controlword & cw::ENABLE_OPERATION == 0 {
            Some(DriveCommand::SwitchOn)
        } else {
            Some(DriveCommand::EnableOperation)
        }
    }
}

/// True when bit 7 (fault reset) rises from `previous` to `current`.
pub fn is_fault_reset_edge(previous: u16, current: u16) -> bool {
    previous & cw::FAULT_RESET == 0 && current & cw::FAULT_RESET != 0
}

/// True when the standard's state machine has a transition `from` → `to` (or `from`
/// equals `to`). Transition numbers as in the standard: 0-16 (16, Quick stop active →
/// Operation enabled, only with quick stop option codes 5-8).
pub fn is_allowed_transition(from: DriveState, to: DriveState) -> bool {
    use DriveState::*;
    if from == to || to == FaultReactionActive {
        return true; // 13: any state on a fault
    }
    matches!(
        (from, to),
        (NotReadyToSwitchOn, SwitchOnDisabled) // 1
            | (SwitchOnDisabled, ReadyToSwitchOn) // 2
            | (ReadyToSwitchOn, SwitchedOn) // 3
            | (SwitchedOn, OperationEnabled) // 4
            | (OperationEnabled, SwitchedOn) // 5
            | (SwitchedOn, ReadyToSwitchOn) // 6
            | (ReadyToSwitchOn, SwitchOnDisabled) // 7
            | (OperationEnabled, ReadyToSwitchOn) // 8
            | (OperationEnabled, SwitchOnDisabled) // 9
            | (SwitchedOn, SwitchOnDisabled) // 10
            | (OperationEnabled, QuickStopActive) // 11
            | (QuickStopActive, SwitchOnDisabled) // 12
            | (FaultReactionActive, Fault) // 14
            | (Fault, SwitchOnDisabled) // 15
            | (QuickStopActive, OperationEnabled) // 16
    )
}

/// One CiA 402 drive in cyclic synchronous position mode, as the master sees it.
///
/// `write` is the cyclic exchange: the master writes the controlword and the target
/// position once per cycle; the reads return the values of the last exchange.
pub trait Drive {
    /// Writes the controlword (0x6040) and the target position (0x607A, counts).
    fn write(&mut self, controlword: u16, target_position_counts: i32);
    /// Writes the modes of operation (0x6060); the master writes
    /// [`MODE_CYCLIC_SYNC_POSITION`].
    fn set_mode_of_operation(&mut self, mode: i8);
    /// Modes of operation display (0x6061).
    fn mode_of_operation_display(&self) -> i8;
    /// Statusword (0x6041).
    fn statusword(&self) -> u16;
    /// Position actual value (0x6064), counts.
    fn position_actual_counts(&self) -> i32;
    /// Velocity actual value (0x606C), counts per second.
    fn velocity_actual_counts_s(&self) -> i32;
    /// Following error actual value (0x60F4): position demand − position actual, counts.
    fn following_error_counts(&self) -> i32;
    /// Error code (0x603F) of the last fault; 0 when none.
    fn error_code(&self) -> u16;
}

/// Errors of the drive profile's configuration and conversions.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum Cia402Error {
    /// Counts per unit must be finite and positive.
    #[error("counts per unit must be finite and > 0, got {0}")]
    BadCountsPerUnit(f64),
    /// Direction must be +1 or −1.
    #[error("direction must be +1 or -1, got {0}")]
    BadDirection(i32),
    /// A position does not fit in the drive's 32-bit counts.
    #[error("position {0} does not fit in 32-bit drive counts")]
    OutOfRange(f64),
}

/// The scale of one axis: drive counts per machine unit (mm or degree) and a direction.
///
/// `counts = round(direction · counts_per_unit · position)`, rounding half away from
/// zero (so the conversion is symmetric about 0); `position = direction · counts /
/// counts_per_unit`. A position converted to counts and back differs from the original
/// by at most half a count (0.5 / counts_per_unit units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scale {
    counts_per_unit: f64,
    direction: i32,
}

impl Scale {
    /// A scale; `direction` is +1 or −1.
    pub fn new(counts_per_unit: f64, direction: i32) -> Result<Scale, Cia402Error> {
        if !(counts_per_unit.is_finite() && counts_per_unit > 0.0) {
            return Err(Cia402Error::BadCountsPerUnit(counts_per_unit));
        }
        if direction != 1 && direction != -1 {
            return Err(Cia402Error::BadDirection(direction));
        }
        Ok(Scale {
            counts_per_unit,
            direction,
        })
    }

    /// Counts per machine unit.
    pub fn counts_per_unit(&self) -> f64 {
        self.counts_per_unit
    }

    /// +1 or −1.
    pub fn direction(&self) -> i32 {
        self.direction
    }

    /// A position in machine units to drive counts (rounded half away from zero).
    pub fn to_counts(&self, position_units: f64) -> Result<i32, Cia402Error> {
        let counts = (f64::from(self.direction) * self.counts_per_unit * position_units).round();
        if counts.is_finite() && counts >= f64::from(i32::MIN) && counts <= f64::from(i32::MAX) {
            // In range and integral: the cast is exact.
            Ok(counts as i32)
        } else {
            Err(Cia402Error::OutOfRange(position_units))
        }
    }

    /// Drive counts to a position in machine units (exact up to f64 rounding).
    pub fn to_units(&self, counts: i32) -> f64 {
        f64::from(self.direction) * f64::from(counts) / self.counts_per_unit
    }

    /// Drive counts per second (or a count difference) to machine units per second.
    pub fn velocity_to_units_s(&self, counts_s: i32) -> f64 {
        self.to_units(counts_s)
    }
}

/// What the master asks of one drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    /// Reach Operation enabled.
    Enable,
    /// Reach Switch on disabled (power off).
    Disable,
    /// Quick stop: the drive ramps to rest with its own quick-stop deceleration and ends
    /// in Switch on disabled.
    QuickStop,
    /// Fault reset: a rising edge of bit 7, then Switch on disabled.
    FaultReset,
}

/// Where the [`Enabler`] stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EnablerStatus {
    /// On the way; the drive is in this state.
    InProgress(DriveState),
    /// The request is done: the drive is in this state (Operation enabled for
    /// [`Request::Enable`], Switch on disabled for the others).
    Done(DriveState),
    /// The drive stayed in `state` for longer than the timeout.
    Timeout {
        /// The state the drive did not leave.
        state: DriveState,
    },
    /// The drive left Operation enabled on its own (not into a fault) after the enable
    /// request was done; the enabler does not enable it again until a new request.
    Dropped {
        /// The state the drive went to.
        state: DriveState,
    },
    /// The drive is in Fault or Fault reaction active (a fault reset is needed).
    Fault {
        /// The drive's error code (0x603F).
        error_code: u16,
    },
    /// The statusword does not decode to a state.
    BadStatusword(u16),
}

/// What the master writes to the drive this cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EnablerOutput {
    /// The controlword to write.
    pub controlword: u16,
    /// `Some(actual)` while the drive is not in Operation enabled, including the cycle
    /// that sends Enable operation: the master writes it as the target, so the drive
    /// enables where it stands. `None` once enabled: the master writes its setpoints.
    pub hold_target_counts: Option<i32>,
    /// Where the sequence stands.
    pub status: EnablerStatus,
}

/// The master-side sequencer of one drive's power state machine.
///
/// Call [`Enabler::cycle`] once per cycle with the statusword, the actual position and
/// the error code read from the drive, then write the returned controlword (and the
/// held target while there is one). A transition that does not happen within the
/// timeout (in cycles) stops the sequence with [`EnablerStatus::Timeout`]; a new
/// [`Enabler::request`] starts it again. A drive that leaves Operation enabled on its
/// own is reported as [`EnablerStatus::Dropped`] and not enabled again until a new
/// request. A fault is never reset on its own.
// A copy would be a second instance of its state, silently diverging from the first.
#[allow(missing_copy_implementations)]
#[derive(Debug, Clone)]
pub struct Enabler {
    timeout_cycles: u32,
    request: Request,
    last_state: Option<DriveState>,
    cycles_in_state: u32,
    timed_out: Option<DriveState>,
    dropped: Option<DriveState>,
    reached: bool,
    fault_reset_low_sent: bool,
    last_controlword: u16,
}

impl Enabler {
    /// A sequencer with a timeout per transition of `timeout_cycles` cycles; it starts
    /// with [`Request::Disable`].
    pub fn new(timeout_cycles: u32) -> Enabler {
        Enabler {
            timeout_cycles,
            request: Request::Disable,
            last_state: None,
            cycles_in_state: 0,
            timed_out: None,
            dropped: None,
            reached: false,
            fault_reset_low_sent: false,
            last_controlword: cw::DISABLE_VOLTAGE,
        }
    }

    /// The timeout in cycles for a timeout in nanoseconds at a cycle period (rounded up,
    /// at least 1).
    pub fn timeout_cycles_for(timeout_ns: u64, period_ns: u64) -> u32 {
        let period_ns = period_ns.max(1);
        let cycles = timeout_ns.div_ceil(period_ns).max(1);
        u32::try_from(cycles).unwrap_or(u32::MAX)
    }

    /// Sets the request; a different request, or any request after a timeout or a
    /// drop-out, starts the sequence again.
    pub fn request(&mut self, request: Request) {
        if request != self.request || self.timed_out.is_some() || self.dropped.is_some() {
            self.request = request;
            self.cycles_in_state = 0;
            self.timed_out = None;
            self.dropped = None;
            self.reached = false;
            self.fault_reset_low_sent = false;
        }
    }

    /// The current request.
    pub fn current_request(&self) -> Request {
        self.request
    }

    /// One cycle: decides the controlword from what the drive reports.
    pub fn cycle(
        &mut self,
        statusword: u16,
        position_actual_counts: i32,
        error_code: u16,
    ) -> EnablerOutput {
        let out = self.decide(statusword, position_actual_counts, error_code);
        self.last_controlword = out.controlword;
        out
    }

    fn decide(
        &mut self,
        statusword: u16,
        position_actual_counts: i32,
        error_code: u16,
    ) -> EnablerOutput {
        let hold = Some(position_actual_counts);
        let Some(state) = DriveState::from_statusword(statusword) else {
            return EnablerOutput {
                controlword: cw::DISABLE_VOLTAGE,
                hold_target_counts: hold,
                status: EnablerStatus::BadStatusword(statusword),
            };
        };
        if self.last_state == Some(state) {
            self.cycles_in_state = self.cycles_in_state.saturating_add(1);
        } else {
            self.last_state = Some(state);
            self.cycles_in_state = 0;
        }
        let hold_target_counts = if state == DriveState::OperationEnabled {
            None
        } else {
            hold
        };
        if self.request == Request::Enable
            && self.reached
            && self.dropped.is_none()
            && !matches!(
                state,
                DriveState::OperationEnabled | DriveState::Fault | DriveState::FaultReactionActive
            )
        {
            self.dropped = Some(state);
        }
        if let Some(left_in) = self.dropped {
            return EnablerOutput {
                controlword: cw::DISABLE_VOLTAGE,
                hold_target_counts,
                status: EnablerStatus::Dropped { state: left_in },
            };
        }
        if let Some(stuck) = self.timed_out {
            return EnablerOutput {
                controlword: self.safe_controlword(),
                hold_target_counts,
                status: EnablerStatus::Timeout { state: stuck },
            };
        }
        let (controlword, done) = self.step_for(state);
        let status = if done {
            if self.request == Request::Enable {
                self.reached = true;
            }
            EnablerStatus::Done(state)
        } else if matches!(state, DriveState::Fault | DriveState::FaultReactionActive)
            && self.request != Request::FaultReset
        {
            EnablerStatus::Fault { error_code }
        } else if self.cycles_in_state >= self.timeout_cycles {
            self.timed_out = Some(state);
            return EnablerOutput {
                controlword: self.safe_controlword(),
                hold_target_counts,
                status: EnablerStatus::Timeout { state },
            };
        } else {
            EnablerStatus::InProgress(state)
        };
        EnablerOutput {
            controlword,
            hold_target_counts,
            status,
        }
    }

    /// After a timeout: Enable falls back to Disable voltage, Quick stop keeps asking.
    fn safe_controlword(&self) -> u16 {
        match self.request {
            Request::QuickStop => cw::QUICK_STOP_CMD,
            _ => cw::DISABLE_VOLTAGE,
        }
    }

    /// The controlword for `state` under the current request, and whether it is done.
    fn step_for(&mut self, state: DriveState) -> (u16, bool) {
        use DriveState::*;
        match self.request {
            Request::Enable => match state {
                NotReadyToSwitchOn => (cw::DISABLE_VOLTAGE, false),
                SwitchOnDisabled => (cw::SHUTDOWN, false),
                ReadyToSwitchOn => (cw::SWITCH_ON_CMD, false),
                SwitchedOn => (cw::ENABLE_OPERATION_CMD, false),
                OperationEnabled => (cw::ENABLE_OPERATION_CMD, true),
                // Option code 2: the quick stop ends in Switch on disabled, from where
                // the sequence starts again.
                QuickStopActive => (cw::QUICK_STOP_CMD, false),
                FaultReactionActive | Fault => (cw::DISABLE_VOLTAGE, false),
            },
            Request::Disable => match state {
                SwitchOnDisabled => (cw::DISABLE_VOLTAGE, true),
                _ => (cw::DISABLE_VOLTAGE, false),
            },
            Request::QuickStop => match state {
                SwitchOnDisabled => (cw::QUICK_STOP_CMD, true),
                _ => (cw::QUICK_STOP_CMD, false),
            },
            Request::FaultReset => match state {
                Fault => {
                    // Bit 7 low for one cycle, then high: a rising edge.
                    if self.fault_reset_low_sent && self.last_controlword & cw::FAULT_RESET == 0 {
                        (cw::DISABLE_VOLTAGE | cw::FAULT_RESET, false)
                    } else if self.last_controlword & cw::FAULT_RESET != 0 {
                        // Already high and still in Fault: the cause persists; keep it
                        // high (no new edge) until the timeout.
                        (cw::DISABLE_VOLTAGE | cw::FAULT_RESET, false)
                    } else {
                        self.fault_reset_low_sent = true;
                        (cw::DISABLE_VOLTAGE, false)
                    }
                }
                FaultReactionActive => (cw::DISABLE_VOLTAGE, false),
                SwitchOnDisabled => (cw::DISABLE_VOLTAGE, true),
                _ => (cw::DISABLE_VOLTAGE, false),
            },
        }
    }
}
