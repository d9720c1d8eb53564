//! The spindle: the command in force (direction, programmed speed, override, clamping),
//! the velocity ramp and the simulated spindle drive, the outputs of a spindle switched
//! by outputs, and whether it is at speed or at rest.

use kerf_geom::machine::SpindleDir;

use super::Clock;
use super::config::{SpindleConfig, SpindleKind};
use super::io::IoImage;

/// Below this speed a spindle drive counts as at rest, rpm (the simulated drive reaches
/// exactly 0).
pub const REST_RPM: f64 = 1.0;

/// Cycles after a change before a VFD's at-speed input is believed: the fieldbus brings
/// the inputs that answer a cycle's outputs back one cycle later, so the input of the
/// changing cycle and the next still tell of the old speed.
pub const AT_SPEED_INPUT_DELAY_CYCLES: u64 = 2;

/// Highest spindle override, %.
pub const MAX_SPINDLE_OVERRIDE_PCT: f64 = 200.0;

/// What the status shows of the spindle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpindleStatus {
    /// Commanded direction (M3, M4, M5; off after M19 and a tool change).
    pub dir: SpindleDir,
    /// Programmed speed (the S word), rpm.
    pub programmed_rpm: f64,
    /// Commanded speed after the override and the min/max clamping, rpm (0 while off).
    pub commanded_rpm: f64,
    /// Actual speed, rpm, signed (negative counter-clockwise); `None` for a spindle
    /// switched by outputs (no feedback).
    pub actual_rpm: Option<f64>,
    /// At speed: within the band around a commanded speed above 0.
    pub at_speed: bool,
    /// Spindle override, % (0–200).
    pub override_pct: f64,
    /// The override applies (M48/M49/M51).
    pub override_enabled: bool,
    /// Oriented by M19 (and standing) since; cleared by the next spindle command.
    pub oriented: bool,
}

/// The spindle's state.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Spindle {
    config: SpindleConfig,
    dir: SpindleDir,
    programmed_rpm: f64,
    override_pct: f64,
    override_enabled: bool,
    /// Speed after override and clamping, rpm, >= 0 (0 while off).
    commanded_rpm: f64,
    /// The velocity ramp (drive kind), signed rpm.
    setpoint_rpm: f64,
    /// The drive's actual speed (drive kind), signed rpm.
    actual_rpm: f64,
    stalled: bool,
    /// Cycle of the last change of direction or commanded speed.
    changed_cycle: u64,
    /// At speed at least once since the last change.
    at_speed_once: bool,
    oriented: bool,
}

impl Spindle {
    /// A stopped spindle, 0 rpm programmed, override 100 % and enabled.
    pub(crate) fn new(config: SpindleConfig) -> Self {
        Spindle {
            config,
            dir: SpindleDir::Off,
            programmed_rpm: 0.0,
            override_pct: 100.0,
            override_enabled: true,
            commanded_rpm: 0.0,
            setpoint_rpm: 0.0,
            actual_rpm: 0.0,
            stalled: false,
            changed_cycle: 0,
            at_speed_once: false,
            oriented: false,
        }
    }

    pub(crate) fn config(&self) -> &SpindleConfig {
        &self.config
    }

    /// The speed the command comes to after the override and the clamping.
    fn target_magnitude_rpm(&self) -> f64 {
        if self.dir == SpindleDir::Off {
            return 0.0;
        }
        let factor = if self.override_enabled {
            self.override_pct / 100.0
        } else {
            1.0
        };
        let rpm = self.programmed_rpm * factor;
        if rpm > 0.0 {
            rpm.clamp(self.config.min_rpm, self.config.max_rpm)
        } else {
            0.0
        }
    }

    /// Recomputes the commanded speed; a change restarts the at-speed supervision.
    fn update(&mut self, now: Clock, io: &mut IoImage) {
        let rpm = self.target_magnitude_rpm();
        if rpm != self.commanded_rpm {
            self.commanded_rpm = rpm;
            self.changed(now);
        }
        self.write_outputs(io);
    }

    fn changed(&mut self, now: Clock) {
        self.changed_cycle = now.cycles;
        self.at_speed_once = false;
    }

    /// The program's spindle command (M3/M4/M5 with S).
    pub(crate) fn command(&mut self, dir: SpindleDir, rpm: f64, now: Clock, io: &mut IoImage) {
        self.programmed_rpm = if rpm.is_nan() { 0.0 } else { rpm.max(0.0) };
        if dir != self.dir {
            self.dir = dir;
            self.changed(now);
        }
        self.oriented = false;
        self.update(now, io);
    }

    /// Stops the spindle (the programmed speed stays for the next start).
    pub(crate) fn stop(&mut self, now: Clock, io: &mut IoImage) {
        if self.dir != SpindleDir::Off {
            self.dir = SpindleDir::Off;
            self.changed(now);
        }
        self.update(now, io);
    }

    pub(crate) fn set_override_pct(&mut self, pct: f64, now: Clock, io: &mut IoImage) {
        if !pct.is_nan() {
            self.override_pct = pct.clamp(0.0, MAX_SPINDLE_OVERRIDE_PCT);
            self.update(now, io);
        }
    }

    pub(crate) fn set_override_enabled(&mut self, on: bool, now: Clock, io: &mut IoImage) {
        self.override_enabled = on;
        self.update(now, io);
    }

    pub(crate) fn set_oriented(&mut self) {
        self.oriented = true;
    }

    pub(crate) fn set_stalled(&mut self, stalled: bool) {
        self.stalled = stalled;
    }

    /// The fieldbus drive's actual speed, signed rpm.
    pub(crate) fn set_actual_rpm(&mut self, rpm: f64) {
        if rpm.is_finite() {
            self.actual_rpm = rpm;
        }
    }

    /// The velocity setpoint for a spindle drive this cycle, signed rpm.
    pub(crate) fn setpoint_rpm(&self) -> f64 {
        self.setpoint_rpm
    }

    /// Commanded speed after override and clamping, rpm (0 while off).
    pub(crate) fn commanded_rpm(&self) -> f64 {
        self.commanded_rpm
    }

    /// The actual speed, signed rpm, where the spindle reports one.
    pub(crate) fn actual_rpm(&self) -> Option<f64> {
        match self.config.kind {
            SpindleKind::Drive { .. } => Some(self.actual_rpm),
            SpindleKind::Outputs(_) => None,
        }
    }

    pub(crate) fn at_speed_once(&self) -> bool {
        self.at_speed_once
    }

    /// One period: the ramp, the simulated drive or the outputs, and the at-speed
    /// latch.
    pub(crate) fn step(&mut self, now: Clock, io: &mut IoImage, simulated_inputs: bool) {
        let step_rpm = self.config.acceleration_rpm_s * now.period_s;
        match self.config.kind {
            SpindleKind::Drive { simulated } => {
                let target = self.dir.sign() * self.commanded_rpm;
                self.setpoint_rpm = approach(self.setpoint_rpm, target, step_rpm);
                if simulated {
                    let goal = if self.stalled { 0.0 } else { self.setpoint_rpm };
                    self.actual_rpm = approach(self.actual_rpm, goal, step_rpm);
                }
            }
            SpindleKind::Outputs(o) => {
                if let (true, Some(n)) = (simulated_inputs, o.at_speed_input) {
                    let up = !self.stalled
                        && self.commanded_rpm > 0.0
                        && now.reached(self.changed_cycle, o.spin_up_s);
                    io.set_digital_input(n, up);
                }
            }
        }
        self.write_outputs(io);
        if self.at_speed(now, io) {
            self.at_speed_once = true;
        }
    }

    fn write_outputs(&self, io: &mut IoImage) {
        if let SpindleKind::Outputs(o) = self.config.kind {
            io.set_digital_output(o.enable_output, self.dir != SpindleDir::Off);
            if let Some(n) = o.reverse_output {
                io.set_digital_output(n, self.dir == SpindleDir::Ccw);
            }
            if let Some(n) = o.speed_output {
                io.analog_outputs[usize::from(n)] = self.commanded_rpm * o.speed_units_per_rpm;
            }
        }
    }

    /// At speed: a commanded speed above 0, and the actual speed within the band around
    /// it (drive kind), or the at-speed input on (from the second cycle after the change),
    /// or `spin_up_s` passed since the change (outputs kind).
    pub(crate) fn at_speed(&self, now: Clock, io: &IoImage) -> bool {
        if self.commanded_rpm <= 0.0 {
            return false;
        }
        match self.config.kind {
            SpindleKind::Drive { .. } => {
                let target = self.dir.sign() * self.commanded_rpm;
                (self.actual_rpm - target).abs()
                    <= self.config.at_speed_tolerance * self.commanded_rpm
            }
            SpindleKind::Outputs(o) => match o.at_speed_input {
                Some(n) => {
                    now.cycles.saturating_sub(self.changed_cycle) >= AT_SPEED_INPUT_DELAY_CYCLES
                        && io.digital_input(n)
                }
                None => now.reached(self.changed_cycle, o.spin_up_s),
            },
        }
    }

    /// At rest: the drive's actual speed within [`REST_RPM`] of 0, or (outputs kind) off
    /// for `spin_up_s` (the spin-down taken as long as the spin-up).
    pub(crate) fn at_rest(&self, now: Clock) -> bool {
        match self.config.kind {
            SpindleKind::Drive { .. } => self.actual_rpm.abs() <= REST_RPM,
            SpindleKind::Outputs(o) => {
                self.commanded_rpm <= 0.0 && now.reached(self.changed_cycle, o.spin_up_s)
            }
        }
    }

    pub(crate) fn status(&self, now: Clock, io: &IoImage) -> SpindleStatus {
        SpindleStatus {
            dir: self.dir,
            programmed_rpm: self.programmed_rpm,
            commanded_rpm: self.commanded_rpm,
            actual_rpm: self.actual_rpm(),
            at_speed: self.at_speed(now, io),
            override_pct: self.override_pct,
            override_enabled: self.override_enabled,
            oriented: self.oriented,
        }
    }
}

/// `x` moved toward `target` by at most `step`.
fn approach(x: f64, target: f64, step: f64) -> f64 {
    if (target - x).abs() <= step {
        target
    } else if target > x {
        x + step
    } else {
        x - step
    }
}
