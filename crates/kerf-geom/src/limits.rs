//! The machine's kinematic limits, shared by the planner, the motion core and the limit
//! monitor.
//!
//! Linear axes (X, Y, Z) are in millimetres, rotary axes (A, B, C) in degrees; a limit
//! field's name says the time part of its unit (`_s`, `_s2`, `_s3`) and its doc the
//! length part.

/// Velocity, acceleration and jerk limits of one axis: mm/s, mm/s², mm/s³ for X, Y, Z;
/// deg/s, deg/s², deg/s³ for the rotary axes A, B, C.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisLimits {
    /// Maximum velocity, mm/s (deg/s for rotary axes).
    pub velocity_units_s: f64,
    /// Maximum acceleration, mm/s² (deg/s² for rotary axes).
    pub acceleration_units_s2: f64,
    /// Maximum jerk, mm/s³ (deg/s³ for rotary axes).
    pub jerk_units_s3: f64,
}

/// The machine as the planner and motion core see it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MachineLimits {
    /// Limits of X, Y, Z, A, B, C (in the order of [`AXIS_NAMES`]); `None` for an axis the
    /// machine does not have.
    pub axes: [Option<AxisLimits>; 6],
    /// Interpolation period, s.
    pub period_s: f64,
    /// Default blend tolerance (G64 without P), mm.
    pub tolerance_mm: f64,
}

/// The highest feed override, as a factor (2.0: 200 %): the motion core clamps to it, the
/// planner designs curved segments for it, the protocol and the commands accept up to it
/// in percent. One number for all of them; raising it changes what `REQUEST_OVERRIDE`
/// accepts, a new protocol version.
pub const MAX_FEED_OVERRIDE: f64 = 2.0;

/// Axis names in the order of [`MachineLimits::axes`].
pub const AXIS_NAMES: [char; 6] = ['X', 'Y', 'Z', 'A', 'B', 'C'];

/// Rounding error of one computed setpoint position, in units of `ε·M` (`ε` =
/// [`f64::EPSILON`], `M` = the magnitude the position is computed at): a point on a helix
/// or quintic, and the path parameter it is taken at, each take a handful of roundings of
/// values of that magnitude. The motion core's output monitor allows it on every setpoint
/// (`kerf_motion::monitor::LimitMonitor`); the planner drops a remnant of a move no longer
/// than it.
pub const POSITION_ROUNDING_ULPS: f64 = 8.0;
