//! The safety checks of the real-time cycle, above every drive.
//!
//! A [`Safety`] is built once from a [`SafetyConfig`] (per-axis limits, soft limits and
//! following-error limits); the cycle then calls [`Safety::check`] with the new setpoint,
//! the drives' actual positions and fault bits, and the program line, and sends the
//! [`Verdict`]'s command to the drives. Nothing here allocates after construction.
//!
//! The checks (formulas and defaults in `docs/DRIVES.md`, "Safety checks"):
//! - plausibility of each new setpoint against the previous one of the stream:
//!   |Δx|/T ≤ v_max·(1 + margin) and |Δ²x|/T² ≤ a_max·(1 + margin);
//! - soft limits: `min_limit_units` ≤ x ≤ `max_limit_units`;
//! - following error as LinuxCNC defines it: |commanded − actual| ≤
//!   max(`min_ferror_units`, `ferror_units`·|v|/v_max);
//! - stream supervision: a missed cycle holds the last position, `stall_cycles`
//!   consecutive missed cycles trip; a drive reporting a fault trips.
//!
//! Any trip latches a [`Fault`] and starts a jerk-limited quick stop of every axis from
//! its current commanded position, velocity and acceleration ([`StopProfile`]); the
//! offending setpoint never reaches a drive. Only [`Safety::reset`] clears the fault, and
//! only once its cause is gone.

use crate::{MAX_AXES, PerAxis};
use kerf_geom::{AXIS_NAMES, AxisLimits};

/// Default allowed excess of a setpoint's velocity or acceleration over the axis limit:
/// 5 % (the motion core keeps its own stream within 1 %).
pub const DEFAULT_MARGIN: f64 = 0.05;

/// Room for rounding in the soft-limit check of the stopping point, mm or deg: a motion
/// that decelerates to rest exactly at a soft limit is not refused for the last bits of
/// its floating-point stop.
pub const SOFT_LIMIT_ROUNDING: f64 = 1e-6;

/// Default number of consecutive missed cycles that trips the stream supervision.
pub const DEFAULT_STALL_CYCLES: u32 = 3;

/// Safety configuration of one axis. Lengths are mm for X, Y, Z and degrees for A, B, C.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisSafety {
    /// Velocity, acceleration and jerk limits; the quick stop stays within them.
    pub limits: AxisLimits,
    /// Soft limit, lower end of travel, mm or deg (LinuxCNC's `MIN_LIMIT`).
    pub min_limit_units: f64,
    /// Soft limit, upper end of travel, mm or deg (LinuxCNC's `MAX_LIMIT`).
    pub max_limit_units: f64,
    /// Following-error limit at the axis's maximum velocity, mm or deg (LinuxCNC's
    /// `FERROR`); scaled by |v|/v_max.
    pub ferror_units: f64,
    /// Following-error limit at rest and at low speed, mm or deg (LinuxCNC's
    /// `MIN_FERROR`).
    pub min_ferror_units: f64,
}

impl AxisSafety {
    /// The following-error limit at commanded velocity `velocity_units_s`:
    /// max(`min_ferror_units`, `ferror_units`·|v|/v_max).
    pub fn ferror_limit_units(&self, velocity_units_s: f64) -> f64 {
        self.min_ferror_units
            .max(self.ferror_units * velocity_units_s.abs() / self.limits.velocity_units_s)
    }
}

/// Configuration of a [`Safety`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SafetyConfig {
    /// Per-axis configuration in the order X, Y, Z, A, B, C; `None` for an axis the
    /// machine does not have (its command is passed through unchecked).
    pub axes: PerAxis<Option<AxisSafety>>,
    /// Cycle period, s.
    pub period_s: f64,
    /// Allowed relative excess of velocity and acceleration over the axis limits
    /// (default [`DEFAULT_MARGIN`]).
    pub margin: f64,
    /// Consecutive missed cycles that trip (default [`DEFAULT_STALL_CYCLES`]); fewer are
    /// held.
    pub stall_cycles: u32,
    /// Cycles between a command leaving the stage and the actual position that answers
    /// it coming back, beyond the one every drive has: 0 for the simulated drives (the
    /// drive steps when written), 1 on a fieldbus (the frame that carries a command
    /// brings back the inputs of the cycle before). The following error is taken against
    /// the command that many cycles older. At most 1.
    pub feedback_delay_cycles: usize,
}

impl SafetyConfig {
    /// A configuration with the default margin and stall count.
    pub fn new(axes: PerAxis<Option<AxisSafety>>, period_s: f64) -> Self {
        Self {
            axes,
            period_s,
            margin: DEFAULT_MARGIN,
            stall_cycles: DEFAULT_STALL_CYCLES,
            feedback_delay_cycles: 0,
        }
    }
}

/// A configuration [`Safety::new`] refuses.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum SafetyConfigError {
    /// The period is not a positive finite number.
    #[error("safety: the cycle period must be positive, got {0} s")]
    Period(f64),
    /// The margin is negative or not finite.
    #[error("safety: the margin must be zero or positive, got {0}")]
    Margin(f64),
    /// `stall_cycles` is zero.
    #[error("safety: stall_cycles must be at least 1")]
    StallCycles,
    /// `feedback_delay_cycles` is above 1.
    #[error("safety: the feedback delay must be 0 or 1 cycles, got {0}")]
    FeedbackDelay(usize),
    /// A limit of an axis is not positive and finite, or the soft limits are reversed.
    #[error("safety: axis {axis}: {what}")]
    Axis {
        /// Axis name.
        axis: char,
        /// What is wrong.
        what: &'static str,
    },
    /// A start position is not finite.
    #[error("safety: axis {0}: the start position is not finite")]
    StartPosition(char),
}

/// Which check tripped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Check {
    /// Setpoint step over the period above the velocity limit (or a non-finite setpoint).
    Velocity,
    /// Second difference of the setpoints over T² above the acceleration limit.
    Acceleration,
    /// Setpoint outside the soft limits.
    SoftLimit,
    /// Following error above its limit.
    FollowingError,
    /// Too many consecutive missed cycles.
    StreamStall,
    /// A drive reported a fault.
    DriveFault,
    /// A drive did not reach Operation enabled within its enable timeout (at start or at
    /// a reset); reported by the drive stage ([`crate::stage`]).
    EnableTimeout,
    /// A drive left Operation enabled on its own (not into a fault); reported by the
    /// drive stage.
    DriveDisabled,
    /// The fieldbus stopped carrying the cyclic data: more consecutive cycles without a
    /// complete exchange (a lost frame, a working counter short) than allowed; reported
    /// by the daemon's bus ([`crate::stage::DriveStage::trip_fieldbus`]). The drives stop
    /// by their own process-data watchdog, as the master can no longer command them.
    Fieldbus,
    /// A subdevice on the fieldbus left OP on its own (its process-data watchdog, an error
    /// of its own); the value is its ring position, the limit its AL status code.
    SubdeviceState,
    /// The spindle did not reach its commanded speed within the at-speed timeout before
    /// a feed move; the value is its actual speed, the limit the commanded one, rpm.
    SpindleAtSpeed,
    /// The spindle left its at-speed band while the axes fed (a broken belt, a stalled
    /// spindle); the value is its actual speed, the limit the commanded one, rpm.
    SpindleBand,
    /// The spindle's orientation (M19) did not end within its timeout; the value is the
    /// time waited, the limit the timeout, s.
    SpindleOrient,
    /// The automatic tool changer did not report the change done within its timeout; the
    /// value is the tool, the limit the timeout, s.
    ToolChange,
    /// The spindle's drive on the fieldbus failed: the limit says how (0: it reports a
    /// fault, the value its error code 0x603F; 1: it did not enable, the value the timeout
    /// in cycles; 2: it left Operation enabled on its own).
    SpindleDrive,
    /// Homing found no home switch within the search distance; the value is the distance
    /// travelled, the limit the search distance, mm or deg.
    HomeSearch,
    /// Homing moved off (or backed off) the home switch for the search distance and it
    /// did not release; value and limit as [`Check::HomeSearch`].
    HomeRelease,
    /// Homing found no latch edge of the home switch within the search distance; value and
    /// limit as [`Check::HomeSearch`].
    HomeLatch,
    /// A hard limit switch is active; the value is -1 for the lower, +1 for the upper one.
    HardLimit,
    /// A drive homing itself (CiA 402 homing mode) reported a homing error (statusword
    /// bit 13: e.g. its home switch not found); the value is the drive's error code
    /// (0x603F, 0 when it gives none), the limit 0. Reported by the drive stage
    /// ([`crate::stage::DriveStage::start_drive_homing`]).
    DriveHoming,
}

impl Check {
    /// A short name: `velocity`, `acceleration`, `soft_limit`, `following_error`,
    /// `stream_stall`, `drive_fault`.
    pub fn name(self) -> &'static str {
        match self {
            Check::Velocity => "velocity",
            Check::Acceleration => "acceleration",
            Check::SoftLimit => "soft_limit",
            Check::FollowingError => "following_error",
            Check::StreamStall => "stream_stall",
            Check::DriveFault => "drive_fault",
            Check::EnableTimeout => "enable_timeout",
            Check::DriveDisabled => "drive_disabled",
            Check::Fieldbus => "fieldbus",
            Check::SubdeviceState => "subdevice_state",
            Check::SpindleAtSpeed => "spindle_at_speed",
            Check::SpindleBand => "spindle_band",
            Check::SpindleOrient => "spindle_orient",
            Check::ToolChange => "tool_change",
            Check::SpindleDrive => "spindle_drive",
            Check::HomeSearch => "home_search",
            Check::HomeRelease => "home_release",
            Check::HomeLatch => "home_latch",
            Check::HardLimit => "hard_limit",
            Check::DriveHoming => "drive_homing",
        }
    }

    /// Every check, in the order of their codes.
    pub const ALL: [Check; 20] = [
        Check::Velocity,
        Check::Acceleration,
        Check::SoftLimit,
        Check::FollowingError,
        Check::StreamStall,
        Check::DriveFault,
        Check::EnableTimeout,
        Check::DriveDisabled,
        Check::Fieldbus,
        Check::SubdeviceState,
        Check::SpindleAtSpeed,
        Check::SpindleBand,
        Check::SpindleOrient,
        Check::ToolChange,
        Check::SpindleDrive,
        Check::HomeSearch,
        Check::HomeRelease,
        Check::HomeLatch,
        Check::HardLimit,
        Check::DriveHoming,
    ];

    /// The check's number on the wire (1 to 20, in the order of [`Check::ALL`]; 0 means
    /// none).
    pub fn code(self) -> u32 {
        match self {
            Check::Velocity => 1,
            Check::Acceleration => 2,
            Check::SoftLimit => 3,
            Check::FollowingError => 4,
            Check::StreamStall => 5,
            Check::DriveFault => 6,
            Check::EnableTimeout => 7,
            Check::DriveDisabled => 8,
            Check::Fieldbus => 9,
            Check::SubdeviceState => 10,
            Check::SpindleAtSpeed => 11,
            Check::SpindleBand => 12,
            Check::SpindleOrient => 13,
            Check::ToolChange => 14,
            Check::SpindleDrive => 15,
            Check::HomeSearch => 16,
            Check::HomeRelease => 17,
            Check::HomeLatch => 18,
            Check::HardLimit => 19,
            Check::DriveHoming => 20,
        }
    }
}

/// A latched fault: what tripped, where, by how much, and at which program line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fault {
    /// The check that tripped.
    pub check: Check,
    /// Axis index (0–5 = X–C); `None` for the stream stall.
    pub axis: Option<usize>,
    /// The measured value: |velocity| units/s, |acceleration| units/s², the position
    /// (soft limit), |following error| units, consecutive missed cycles, or 1 for a
    /// drive fault. Infinite for a non-finite setpoint or actual position.
    pub value: f64,
    /// The limit it was checked against, same unit (with the margin included); the
    /// soft limit crossed; `stall_cycles`; 0 for a drive fault.
    pub limit: f64,
    /// Program line given with the cycle that tripped.
    pub line: u32,
    /// Cycle count (from 0 at construction) of the cycle that tripped.
    pub cycle: u64,
}

impl std::fmt::Display for Fault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let axis = self.axis.map_or('-', |a| AXIS_NAMES[a]);
        write!(
            f,
            "{} on axis {}: {} against limit {} (line {}, cycle {})",
            self.check.name(),
            axis,
            self.value,
            self.limit,
            self.line,
            self.cycle
        )
    }
}

/// Why [`Safety::reset`] refused: the cause of a fault persists.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum ResetRefused {
    /// The quick stop has not come to rest yet.
    #[error("reset refused: axis {} is still stopping", AXIS_NAMES[*.0])]
    Moving(usize),
    /// A drive still reports a fault.
    #[error("reset refused: the drive of axis {} still reports a fault", AXIS_NAMES[*.0])]
    DriveFault(usize),
    /// An axis's actual position is outside its soft limits.
    #[error("reset refused: axis {} is at {value}, outside its soft limits", AXIS_NAMES[*axis])]
    SoftLimit {
        /// Axis index.
        axis: usize,
        /// Actual position.
        value: f64,
    },
    /// An axis's following error at rest is above `min_ferror`.
    #[error("reset refused: axis {} following error {value} above {limit}", AXIS_NAMES[*axis])]
    FollowingError {
        /// Axis index.
        axis: usize,
        /// |commanded − actual|.
        value: f64,
        /// `min_ferror`.
        limit: f64,
    },
    /// The last cycle had no new setpoint: the stream is still missing.
    #[error("reset refused: the setpoint stream is still missing")]
    StreamMissing,
    /// A drive did not reach Operation enabled again within its enable timeout.
    #[error("reset refused: the drive of axis {} did not enable", AXIS_NAMES[*.0])]
    NotEnabled(usize),
    /// The fieldbus does not answer: its frames do not come back.
    #[error(
        "reset refused: the EtherCAT bus does not exchange its cyclic data (no frame came back within {0} ms): check the cable and the subdevices' power"
    )]
    Fieldbus(u32),
    /// A subdevice on the fieldbus did not return to OP.
    #[error(
        "reset refused: the EtherCAT subdevice at position {position} did not return to OP within {timeout_ms} ms: it is in {state}, AL status code {code:#06x} (one that fell to INIT or PRE-OP, e.g. power-cycled, has lost its configuration: restart kerfd)"
    )]
    SubdeviceState {
        /// Its ring position.
        position: u16,
        /// The state it is in, in words.
        state: &'static str,
        /// Its AL status code.
        code: u16,
        /// The time it had.
        timeout_ms: u32,
    },
}

/// What the cycle gives [`Safety::check`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CycleInput {
    /// The motion core's new setpoint per axis, or `None` for a missed cycle.
    pub setpoint: Option<PerAxis<f64>>,
    /// The drives' actual positions, read this cycle (units as the axis).
    pub actual: PerAxis<f64>,
    /// Whether each drive reports a fault.
    pub drive_fault: PerAxis<bool>,
    /// Program line of the setpoint (for the fault report).
    pub line: u32,
}

/// What the safety layer is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SafetyState {
    /// Setpoints pass through to the drives.
    Running,
    /// A missed cycle: the last position is held.
    Holding,
    /// A fault is latched and the quick stop is ramping.
    QuickStop,
    /// A fault is latched and every axis is at rest.
    Stopped,
}

impl SafetyState {
    /// `running`, `holding`, `quick_stop` or `stopped`.
    pub fn name(self) -> &'static str {
        match self {
            SafetyState::Running => "running",
            SafetyState::Holding => "holding",
            SafetyState::QuickStop => "quick_stop",
            SafetyState::Stopped => "stopped",
        }
    }
}

/// The answer of one [`Safety::check`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Verdict {
    /// State after this cycle.
    pub state: SafetyState,
    /// Position to send to each drive this cycle.
    pub command: PerAxis<f64>,
    /// The fault that tripped in this very cycle, if any (it is also latched).
    pub tripped: Option<Fault>,
}

/// A jerk-limited stop of one axis: from position `x0`, velocity `v0` and acceleration
/// `a0` to rest with |a| ≤ a_max and |j| ≤ j_max, in at most three phases of constant
/// jerk (ramp the acceleration to the braking peak, hold it, ramp it back to 0).
///
/// The profile is continuous in time; [`StopProfile::position`] samples it. The
/// velocity overshoots |v0| only when `a0` accelerates (by a0²/(2 j_max)), which no
/// jerk-limited stop can avoid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StopProfile {
    x0: f64,
    v0: f64,
    a0: f64,
    /// Phase durations, s.
    durations_s: [f64; 3],
    /// Phase jerks, units/s³.
    jerks: [f64; 3],
}

impl StopProfile {
    /// The stop from (`x0`, `v0`, `a0`) within `limits`; `a0` is clamped to ±a_max.
    pub fn new(x0: f64, v0: f64, a0: f64, limits: &AxisLimits) -> Self {
        let j = limits.jerk_units_s3;
        let a_max = limits.acceleration_units_s2;
        let a0 = a0.clamp(-a_max, a_max);
        // Velocity reached if the acceleration is ramped to 0 at once.
        let v_after = v0 + a0 * a0.abs() / (2.0 * j);
        // Work in the direction where v_after ≥ 0, braking with a negative acceleration.
        let s = if v_after < 0.0 { -1.0 } else { 1.0 };
        let (v, a) = (s * v0, s * a0);
        // Peak braking acceleration without a constant phase: v + (a² − 2 ap²)/(2j) = 0.
        let mut peak = (j * v + 0.5 * a * a).max(0.0).sqrt();
        let mut hold_s = 0.0;
        if peak > a_max {
            peak = a_max;
            hold_s = ((v + (a * a - 2.0 * a_max * a_max) / (2.0 * j)) / a_max).max(0.0);
        }
        let ramp_down_s = ((a + peak) / j).max(0.0);
        let ramp_up_s = peak / j;
        Self {
            x0,
            v0,
            a0,
            durations_s: [ramp_down_s, hold_s, ramp_up_s],
            jerks: [-s * j, 0.0, s * j],
        }
    }

    /// The stop from the newest of three positions sampled at period `t_s` (`x0`, then
    /// `x1` one period before and `x2` two before), continuing them smoothly: the
    /// acceleration is their second difference, and the velocity at `x0` their last step
    /// over the period plus half a period of that acceleration (the step's velocity is
    /// that of the middle of the period). The samples of the stop then continue the
    /// samples before with a third difference of at most the jerk limit.
    pub fn from_samples(x0: f64, x1: f64, x2: f64, t_s: f64, limits: &AxisLimits) -> Self {
        let a0 = (x0 - 2.0 * x1 + x2) / (t_s * t_s);
        let v0 = (x0 - x1) / t_s + 0.5 * a0 * t_s;
        Self::new(x0, v0, a0, limits)
    }

    /// Where the stop comes to rest.
    pub fn end_position(&self) -> f64 {
        self.position(self.duration_s())
    }

    /// At rest from the start: holds `x0`.
    pub fn at_rest(x0: f64) -> Self {
        Self {
            x0,
            v0: 0.0,
            a0: 0.0,
            durations_s: [0.0; 3],
            jerks: [0.0; 3],
        }
    }

    /// Time to rest, s.
    pub fn duration_s(&self) -> f64 {
        self.durations_s.iter().sum()
    }

    /// Position, velocity and acceleration `t_s` seconds after the start (held at rest
    /// after [`StopProfile::duration_s`]).
    pub fn state(&self, t_s: f64) -> (f64, f64, f64) {
        let (mut x, mut v, mut a) = (self.x0, self.v0, self.a0);
        let mut left = t_s.max(0.0);
        for (d, j) in self.durations_s.iter().zip(self.jerks.iter()) {
            let dt = left.min(*d);
            x += v * dt + a * dt * dt / 2.0 + j * dt * dt * dt / 6.0;
            v += a * dt + j * dt * dt / 2.0;
            a += j * dt;
            left -= dt;
        }
        if left > 0.0 {
            // At rest: v and a are 0 up to rounding.
            return (x, 0.0, 0.0);
        }
        (x, v, a)
    }

    /// Position `t_s` seconds after the start.
    pub fn position(&self, t_s: f64) -> f64 {
        self.state(t_s).0
    }
}

/// The safety layer of the real-time cycle. See the module documentation.
#[derive(Clone, Debug)]
pub struct Safety {
    config: SafetyConfig,
    /// Commands sent in the last three cycles (newest first).
    out: [PerAxis<f64>; 3],
    /// Last two setpoints received from the stream (newest first).
    stream: [PerAxis<f64>; 2],
    missed: u32,
    /// Cycles whose following error is not checked: the drives' feedback is stale (a
    /// fieldbus exchange missed; see [`Safety::feedback_stale`]).
    ferror_skip: usize,
    fault: Option<Fault>,
    stops: [StopProfile; MAX_AXES],
    stop_elapsed_s: f64,
    cycle: u64,
    last: Option<CycleInput>,
    state: SafetyState,
    /// Per axis, whether the soft limits are checked (off on an axis not homed yet).
    soft_limits: PerAxis<bool>,
}

impl Safety {
    /// A safety layer at rest at `position` (the drives' actual positions when enabled).
    pub fn new(config: SafetyConfig, position: PerAxis<f64>) -> Result<Self, SafetyConfigError> {
        let pos_finite = |v: f64| v.is_finite() && v > 0.0;
        if !pos_finite(config.period_s) {
            return Err(SafetyConfigError::Period(config.period_s));
        }
        if !(config.margin.is_finite() && config.margin >= 0.0) {
            return Err(SafetyConfigError::Margin(config.margin));
        }
        if config.stall_cycles == 0 {
            return Err(SafetyConfigError::StallCycles);
        }
        if config.feedback_delay_cycles > 1 {
            return Err(SafetyConfigError::FeedbackDelay(
                config.feedback_delay_cycles,
            ));
        }
        for (i, ax) in config.axes.iter().enumerate() {
            let axis = AXIS_NAMES[i];
            if !position[i].is_finite() {
                return Err(SafetyConfigError::StartPosition(axis));
            }
            let Some(ax) = ax else { continue };
            let l = &ax.limits;
            if !(pos_finite(l.velocity_units_s)
                && pos_finite(l.acceleration_units_s2)
                && pos_finite(l.jerk_units_s3))
            {
                return Err(SafetyConfigError::Axis {
                    axis,
                    what: "velocity, acceleration and jerk limits must be positive",
                });
            }
            if !(ax.min_limit_units.is_finite() && ax.max_limit_units.is_finite())
                || ax.min_limit_units > ax.max_limit_units
            {
                return Err(SafetyConfigError::Axis {
                    axis,
                    what: "min_limit must be at most max_limit",
                });
            }
            let non_negative = |v: f64| v.is_finite() && v >= 0.0;
            if !(non_negative(ax.ferror_units) && non_negative(ax.min_ferror_units)) {
                return Err(SafetyConfigError::Axis {
                    axis,
                    what: "ferror and min_ferror must be zero or positive",
                });
            }
        }
        Ok(Self {
            config,
            out: [position; 3],
            stream: [position; 2],
            missed: 0,
            ferror_skip: 0,
            fault: None,
            stops: position.map(StopProfile::at_rest),
            stop_elapsed_s: 0.0,
            cycle: 0,
            last: None,
            state: SafetyState::Running,
            soft_limits: [true; MAX_AXES],
        })
    }

    /// Checks axis `axis`'s soft limits (`on`, the default) or not: an axis that is not
    /// homed has machine coordinates that mean nothing yet (LinuxCNC applies no soft
    /// limits to an unhomed joint either).
    pub fn set_soft_limits(&mut self, axis: usize, on: bool) {
        if axis < MAX_AXES {
            self.soft_limits[axis] = on;
        }
    }

    /// Whether axis `axis`'s soft limits are checked.
    pub fn soft_limits(&self, axis: usize) -> bool {
        self.soft_limits.get(axis).copied().unwrap_or(true)
    }

    /// Shifts axis `axis`'s coordinates by `delta`: every command, setpoint and actual
    /// position held moves with them (the machine's zero was found by homing; nothing
    /// moves physically), so the differences the checks take are unchanged. Refused
    /// (`false`) while a fault is latched (the quick stop runs in the old coordinates).
    pub fn shift(&mut self, axis: usize, delta: f64) -> bool {
        if self.fault.is_some() || axis >= MAX_AXES || !delta.is_finite() {
            return false;
        }
        for out in self.out.iter_mut() {
            out[axis] += delta;
        }
        for s in self.stream.iter_mut() {
            s[axis] += delta;
        }
        if let Some(last) = self.last.as_mut() {
            last.actual[axis] += delta;
            if let Some(sp) = last.setpoint.as_mut() {
                sp[axis] += delta;
            }
        }
        self.stops[axis] = StopProfile::at_rest(self.out[0][axis]);
        true
    }

    /// The configuration.
    pub fn config(&self) -> &SafetyConfig {
        &self.config
    }

    /// The latched fault, if any.
    pub fn fault(&self) -> Option<&Fault> {
        self.fault.as_ref()
    }

    /// The current state.
    pub fn state(&self) -> SafetyState {
        self.state
    }

    /// The command sent in the last cycle.
    pub fn command(&self) -> PerAxis<f64> {
        self.out[0]
    }

    /// The actual positions of the coming cycle are stale: the fieldbus exchange that
    /// should have brought them did not happen or did not come back, so the drives also
    /// missed a command. The following error is not checked in that cycle and in the
    /// `feedback_delay_cycles` after it, until the feedback again matches the command it
    /// is compared with; the fieldbus's own supervision (missed cycles in a row) and every
    /// other check stay. Without this a single lost frame at speed would read as a
    /// following error of one period's travel.
    pub fn feedback_stale(&mut self) {
        self.ferror_skip = self.config.feedback_delay_cycles + 1;
    }

    /// One cycle: check `input`, and say what to send to the drives. Allocation-free.
    ///
    /// The following error is the actual position against the command of the previous
    /// cycle (the one the drive has been tracking; on a fieldbus the one before,
    /// [`SafetyConfig::feedback_delay_cycles`]), with v that command's velocity.
    pub fn check(&mut self, input: &CycleInput) -> Verdict {
        let mut tripped = None;
        if self.fault.is_none() {
            tripped = self.supervise(input);
            if let Some(f) = tripped {
                self.latch(f);
            }
        }
        let command = if self.fault.is_some() {
            self.stop_elapsed_s += self.config.period_s;
            let mut cmd = self.out[0];
            let mut moving = false;
            for (i, c) in cmd.iter_mut().enumerate() {
                if self.config.axes[i].is_some() {
                    *c = self.stops[i].position(self.stop_elapsed_s);
                    moving |= self.stop_elapsed_s < self.stops[i].duration_s();
                }
            }
            self.state = if moving {
                SafetyState::QuickStop
            } else {
                SafetyState::Stopped
            };
            cmd
        } else if let Some(sp) = input.setpoint {
            self.state = SafetyState::Running;
            sp
        } else {
            self.state = SafetyState::Holding;
            self.out[0]
        };
        self.out = [command, self.out[0], self.out[1]];
        self.last = Some(*input);
        self.cycle += 1;
        Verdict {
            state: self.state,
            command,
            tripped,
        }
    }

    /// Runs every check on `input`; the first violation found (lowest axis first).
    fn supervise(&mut self, input: &CycleInput) -> Option<Fault> {
        let t = self.config.period_s;
        let m = 1.0 + self.config.margin;
        let cycle = self.cycle;
        let fault = |check, axis, value, limit| Fault {
            check,
            axis,
            value,
            limit,
            line: input.line,
            cycle,
        };
        let check_ferror = self.ferror_skip == 0;
        self.ferror_skip = self.ferror_skip.saturating_sub(1);
        for (i, ax) in self.config.axes.iter().enumerate() {
            let Some(ax) = ax else { continue };
            if input.drive_fault[i] {
                return Some(fault(Check::DriveFault, Some(i), 1.0, 0.0));
            }
            if !check_ferror {
                continue;
            }
            // Following error against the command the drive has been tracking: the
            // previous one, or the one before on a fieldbus.
            let d = self.config.feedback_delay_cycles.min(1);
            let v_cmd = (self.out[d][i] - self.out[d + 1][i]) / t;
            let limit = ax.ferror_limit_units(v_cmd);
            let err = (self.out[d][i] - input.actual[i]).abs();
            let err = if err.is_finite() { err } else { f64::INFINITY };
            if err > limit {
                return Some(fault(Check::FollowingError, Some(i), err, limit));
            }
        }
        let Some(sp) = input.setpoint else {
            self.missed += 1;
            if self.missed >= self.config.stall_cycles {
                let n = f64::from(self.config.stall_cycles);
                return Some(fault(Check::StreamStall, None, f64::from(self.missed), n));
            }
            return None;
        };
        for (i, ax) in self.config.axes.iter().enumerate() {
            let Some(ax) = ax else { continue };
            let x = sp[i];
            let v_limit = ax.limits.velocity_units_s * m;
            if !x.is_finite() {
                return Some(fault(Check::Velocity, Some(i), f64::INFINITY, v_limit));
            }
            let v = ((x - self.stream[0][i]) / t).abs();
            if v > v_limit {
                return Some(fault(Check::Velocity, Some(i), v, v_limit));
            }
            let a = ((x - 2.0 * self.stream[0][i] + self.stream[1][i]) / (t * t)).abs();
            let a_limit = ax.limits.acceleration_units_s2 * m;
            if a > a_limit {
                return Some(fault(Check::Acceleration, Some(i), a, a_limit));
            }
            // Where a quick stop from this setpoint would bring the axis to rest: a
            // setpoint is refused once that is beyond a soft limit, so that the quick stop
            // from the last accepted one (the same stop) always ends within the limits.
            if !self.soft_limits[i] {
                continue;
            }
            let rest =
                StopProfile::from_samples(x, self.stream[0][i], self.stream[1][i], t, &ax.limits)
                    .end_position();
            if x < ax.min_limit_units || rest < ax.min_limit_units - SOFT_LIMIT_ROUNDING {
                return Some(fault(
                    Check::SoftLimit,
                    Some(i),
                    rest.min(x),
                    ax.min_limit_units,
                ));
            }
            if x > ax.max_limit_units || rest > ax.max_limit_units + SOFT_LIMIT_ROUNDING {
                return Some(fault(
                    Check::SoftLimit,
                    Some(i),
                    rest.max(x),
                    ax.max_limit_units,
                ));
            }
        }
        self.missed = 0;
        self.stream = [sp, self.stream[0]];
        None
    }

    /// Latches `f` and plans the quick stop of every axis from the commanded state.
    fn latch(&mut self, f: Fault) {
        let t = self.config.period_s;
        // A held command is at rest: the velocity step of the hold is not carried into
        // the stop as an acceleration (the stop would back up).
        let held = self.state == SafetyState::Holding;
        self.fault = Some(f);
        self.stop_elapsed_s = 0.0;
        for (i, ax) in self.config.axes.iter().enumerate() {
            let x0 = self.out[0][i];
            self.stops[i] = match ax {
                Some(ax) if !held => {
                    StopProfile::from_samples(x0, self.out[1][i], self.out[2][i], t, &ax.limits)
                }
                _ => StopProfile::at_rest(x0),
            };
        }
    }

    /// Latches a fault found outside the checks of [`Safety::check`] (by the drive stage:
    /// an enable timeout, a drive that disabled itself) and starts the quick stop, as a
    /// trip of a check would. Does nothing while a fault is latched (the first stays).
    /// Returns the fault latched now, if any.
    pub fn trip(
        &mut self,
        check: Check,
        axis: Option<usize>,
        value: f64,
        limit: f64,
        line: u32,
    ) -> Option<Fault> {
        if self.fault.is_some() {
            return None;
        }
        let f = Fault {
            check,
            axis,
            value,
            limit,
            line,
            cycle: self.cycle,
        };
        self.latch(f);
        self.state = SafetyState::QuickStop;
        Some(f)
    }

    /// Takes `position` as everything held for axis `axis` (the commands, the setpoint
    /// stream, the last actual position) and its quick stop, at rest there: for an axis
    /// whose drive moves on its own (CiA 402 homing mode), called each cycle before
    /// [`Safety::check`] with its actual position, which the cycle also gives as its
    /// setpoint. Its following error, velocity and acceleration then read zero, so the
    /// drive's own motion (and its coordinates redefined at the home position) trips
    /// nothing; a quick stop holds it where it stands. The other axes are untouched.
    /// Returns whether it was done (an axis of the machine, a finite position).
    pub fn follow(&mut self, axis: usize, position: f64) -> bool {
        if axis >= MAX_AXES || !position.is_finite() {
            return false;
        }
        for out in self.out.iter_mut() {
            out[axis] = position;
        }
        for s in self.stream.iter_mut() {
            s[axis] = position;
        }
        if let Some(last) = self.last.as_mut() {
            last.actual[axis] = position;
            if let Some(sp) = last.setpoint.as_mut() {
                sp[axis] = position;
            }
        }
        self.stops[axis] = StopProfile::at_rest(position);
        true
    }

    /// Takes `position` as the commanded position of `axis`, at rest: for a drive enabled
    /// again at a reset, whose motor stopped on its own (brake or its own quick stop)
    /// away from the last command. Only while a fault is latched and every axis is at
    /// rest; returns whether it was done.
    pub fn rebase(&mut self, axis: usize, position: f64) -> bool {
        if self.fault.is_none() || self.state != SafetyState::Stopped || axis >= MAX_AXES {
            return false;
        }
        if !position.is_finite() {
            return false;
        }
        for out in self.out.iter_mut() {
            out[axis] = position;
        }
        for s in self.stream.iter_mut() {
            s[axis] = position;
        }
        self.stops[axis] = StopProfile::at_rest(position);
        true
    }

    /// Clears the latched fault if its cause is gone: every axis at rest, no drive
    /// fault, every actual position within the soft limits, every following error at
    /// rest within `min_ferror`, and a setpoint in the last cycle. Refused with the
    /// reason otherwise. The stream then continues from the held position at rest.
    pub fn reset(&mut self) -> Result<(), ResetRefused> {
        if self.fault.is_none() {
            return Ok(());
        }
        for (i, ax) in self.config.axes.iter().enumerate() {
            if ax.is_some() && self.stop_elapsed_s < self.stops[i].duration_s() {
                return Err(ResetRefused::Moving(i));
            }
        }
        let Some(last) = self.last else {
            return Err(ResetRefused::StreamMissing);
        };
        for (i, ax) in self.config.axes.iter().enumerate() {
            let Some(ax) = ax else { continue };
            if last.drive_fault[i] {
                return Err(ResetRefused::DriveFault(i));
            }
            let x = last.actual[i];
            if self.soft_limits[i] && !(x >= ax.min_limit_units && x <= ax.max_limit_units) {
                return Err(ResetRefused::SoftLimit { axis: i, value: x });
            }
            // The actual position was read against the command of the cycle before.
            let err = (self.out[1][i] - x).abs();
            if err.is_nan() || err > ax.min_ferror_units {
                return Err(ResetRefused::FollowingError {
                    axis: i,
                    value: err,
                    limit: ax.min_ferror_units,
                });
            }
        }
        if last.setpoint.is_none() {
            return Err(ResetRefused::StreamMissing);
        }
        let held = self.out[0];
        self.out = [held; 3];
        self.stream = [held; 2];
        self.missed = 0;
        self.fault = None;
        self.state = SafetyState::Running;
        Ok(())
    }
}
