//! The simulated drive's homing mode (CiA 402 mode 6): the drive's own motion to its
//! home position, and its redefinition of its coordinates there.
//!
//! The motion is planned by the drive itself, acceleration-limited: a reference (position
//! `r`, velocity `v`) whose acceleration is at most `acceleration_counts_s2` and whose
//! speed is at most the search speed of the leg it is in. The servo model follows it with
//! full velocity and acceleration feed-forward (a drive's profile generator feeds both),
//! so at the tuned inertia the motor tracks the reference up to rounding.
//!
//! A homing is a sequence of up to three legs, each a run at constant speed in one
//! direction until the home switch changes to a given state, then a stop at the homing
//! acceleration. The leg that ends on the home position latches the motor's position at
//! the switch's edge (as a drive's touch-probe input does: the position where the switch
//! changes state, not the next sample). After the latch the drive stops, returns to the
//! latched point at the zero speed, settles there, and redefines its coordinates so that
//! the home position reads the home offset; then it reports homing attained.
//!
//! Methods (the switch is active at and beyond `home_switch_counts` in the method's
//! search direction, in the motor's own frame):
//!
//! | Method | Switch | Switch inactive at start | Switch active at start |
//! |---|---|---|---|
//! | 19 | positive | + search until active; − zero until inactive, latch | − zero until inactive, latch |
//! | 20 | positive | + search until active; − search until inactive; + zero until active, latch | − search until inactive; + zero until active, latch |
//! | 21 | negative | − search until active; + zero until inactive, latch | + zero until inactive, latch |
//! | 22 | negative | − search until active; + search until inactive; − zero until active, latch | + search until inactive; − zero until active, latch |
//! | 35, 37 | none | no motion: the current position is the home position | the same |
//!
//! A leg that travels `search_limit_counts` without its switch change ends the homing in
//! an error: the drive stops and reports bit 13. An unsupported method reports bit 13 at
//! once, without motion.

use crate::cia402::{HomingStatus, homing_method};

/// The homing methods the simulated drive supports (0x6098).
pub const SUPPORTED_METHODS: [i8; 6] = [
    homing_method::POSITIVE_SWITCH_FALLING,
    homing_method::POSITIVE_SWITCH_RISING,
    homing_method::NEGATIVE_SWITCH_FALLING,
    homing_method::NEGATIVE_SWITCH_RISING,
    homing_method::CURRENT_POSITION_35,
    homing_method::CURRENT_POSITION,
];

/// Whether the simulated drive supports homing method `method`.
pub fn is_supported_method(method: i8) -> bool {
    SUPPORTED_METHODS.contains(&method)
}

/// A settled motor: within this of the home position, counts, and moving less than this
/// per period, for a whole period (the drive's position window and its time).
const SETTLED_COUNTS: f64 = 0.25;

/// The simulated drive's homing parameters: what a master writes by SDO to a real drive
/// (0x6098, 0x6099, 0x609A, 0x607C), and where its simulated home switch is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimHomingConfig {
    /// Homing method (0x6098): see [`SUPPORTED_METHODS`].
    pub method: i8,
    /// Speed during the search for the switch (0x6099:01), counts/s.
    pub search_speed_counts_s: u32,
    /// Speed during the search for zero (0x6099:02): the approach of the latched edge and
    /// the return to it, counts/s.
    pub zero_speed_counts_s: u32,
    /// Homing acceleration (0x609A), counts/s²; also the deceleration of every stop.
    pub acceleration_counts_s2: u32,
    /// Home offset (0x607C), counts: the position actual value of the home position once
    /// homing is attained.
    pub home_offset_counts: i32,
    /// Where the simulated home switch is, counts in the motor's own frame (its position
    /// from power-up, before any homing redefined it); active at and beyond it in the
    /// method's search direction (positive for methods 19 and 20, negative for 21 and
    /// 22). `None`: no switch (a search never ends on one).
    pub home_switch_counts: Option<f64>,
    /// The most one leg of the search travels without the switch change it waits for
    /// before the drive gives up with a homing error, counts.
    pub search_limit_counts: f64,
}

impl Default for SimHomingConfig {
    /// Method 37 (the current position is home), home offset 0, no switch; 10 000
    /// counts/s search, 1 000 counts/s zero speed, 100 000 counts/s², a search limit of
    /// 1 000 000 counts.
    fn default() -> Self {
        SimHomingConfig {
            method: homing_method::CURRENT_POSITION,
            search_speed_counts_s: 10_000,
            zero_speed_counts_s: 1_000,
            acceleration_counts_s2: 100_000,
            home_offset_counts: 0,
            home_switch_counts: None,
            search_limit_counts: 1.0e6,
        }
    }
}

/// One leg: a run in `direction` (±1) at the search or the zero speed until the switch
/// becomes `until_active`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Leg {
    direction: f64,
    zero_speed: bool,
    until_active: bool,
    /// The switch change ending this leg is the home position.
    latch: bool,
}

const fn leg(direction: f64, zero_speed: bool, until_active: bool, latch: bool) -> Leg {
    Leg {
        direction,
        zero_speed,
        until_active,
        latch,
    }
}

/// What follows a stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum After {
    Leg(usize),
    Return,
    Rest,
}

/// Where the homing motion is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Step {
    /// No homing motion: the reference is held.
    Idle,
    /// Running leg `n`.
    Run(usize),
    /// Decelerating to rest, then what follows.
    Stop(After),
    /// Moving back to the latched point at the zero speed.
    Return,
    /// At the latched point, waiting for the motor to settle.
    Settle,
}

/// The outcome of the last homing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Outcome {
    NotStarted,
    InProgress,
    Interrupted,
    Attained,
    Error,
}

/// The homing motion of a simulated drive (see the module documentation).
#[derive(Debug, Clone)]
pub(super) struct HomingMotion {
    config: SimHomingConfig,
    outcome: Outcome,
    step: Step,
    legs: [Option<Leg>; 3],
    /// Motor position where the current leg started, drive counts.
    leg_start: f64,
    /// The latched home position, drive counts.
    latch: f64,
    /// Reference position, drive counts.
    r: f64,
    /// Reference velocity, counts/s.
    v: f64,
    /// The switch's state at the last substep.
    switch_active: bool,
    /// Drive counts minus motor-frame counts: what homing added to the coordinates.
    frame_shift: f64,
    /// How long the motor has been settled at the latched point, s.
    settled_s: f64,
}

impl HomingMotion {
    pub(super) fn new(position_counts: f64) -> HomingMotion {
        HomingMotion {
            config: SimHomingConfig::default(),
            outcome: Outcome::NotStarted,
            step: Step::Idle,
            legs: [None; 3],
            leg_start: position_counts,
            latch: position_counts,
            r: position_counts,
            v: 0.0,
            switch_active: false,
            frame_shift: 0.0,
            settled_s: 0.0,
        }
    }

    pub(super) fn config(&self) -> &SimHomingConfig {
        &self.config
    }

    /// Takes effect at the next start.
    pub(super) fn set_config(&mut self, config: SimHomingConfig) {
        self.config = config;
    }

    /// No homing motion (the reference is held).
    pub(super) fn at_rest(&self) -> bool {
        self.step == Step::Idle
    }

    /// The reference position, drive counts.
    pub(super) fn reference(&self) -> f64 {
        self.r
    }

    /// Holds the reference at `position` (drive counts), at rest; a homing in progress is
    /// interrupted (the drive left Operation enabled or homing mode).
    pub(super) fn hold(&mut self, position_counts: f64) {
        if self.outcome == Outcome::InProgress {
            self.outcome = Outcome::Interrupted;
        }
        self.step = Step::Idle;
        self.r = position_counts;
        self.v = 0.0;
    }

    /// Statusword bits 13, 12 and 10.
    pub(super) fn status(&self) -> HomingStatus {
        let rest = self.at_rest();
        match self.outcome {
            Outcome::InProgress => HomingStatus::InProgress,
            Outcome::NotStarted | Outcome::Interrupted if rest => HomingStatus::Idle,
            Outcome::NotStarted | Outcome::Interrupted => HomingStatus::InProgress,
            Outcome::Attained => HomingStatus::Completed,
            Outcome::Error if rest => HomingStatus::ErrorAtRest,
            Outcome::Error => HomingStatus::ErrorMoving,
        }
    }

    /// Drive counts minus motor-frame counts: what homing added to the coordinates.
    pub(super) fn frame_shift(&self) -> f64 {
        self.frame_shift
    }

    /// Whether the home switch is active with the motor at `motor_counts` (drive counts).
    pub(super) fn switch_is_active(&self, motor_counts: f64) -> bool {
        let Some(s) = self.config.home_switch_counts else {
            return false;
        };
        let x = motor_counts - self.frame_shift;
        match self.config.method {
            homing_method::POSITIVE_SWITCH_FALLING | homing_method::POSITIVE_SWITCH_RISING => {
                x >= s
            }
            homing_method::NEGATIVE_SWITCH_FALLING | homing_method::NEGATIVE_SWITCH_RISING => {
                x <= s
            }
            _ => false,
        }
    }

    /// The rising edge of controlword bit 4 with the motor at `position_counts` (drive
    /// counts) and the reference at `reference_counts`. Returns the shift of the drive's
    /// coordinates when the homing is attained at once (methods 35 and 37).
    pub(super) fn start(&mut self, position_counts: f64, reference_counts: f64) -> Option<f64> {
        if !self.at_rest() {
            return None;
        }
        self.r = reference_counts;
        self.v = 0.0;
        let active = self.switch_is_active(position_counts);
        self.switch_active = active;
        let c = &self.config;
        let speeds_ok = c.search_speed_counts_s > 0
            && c.zero_speed_counts_s > 0
            && c.acceleration_counts_s2 > 0
            && c.search_limit_counts > 0.0;
        use homing_method::*;
        let legs = match (c.method, active) {
            (CURRENT_POSITION | CURRENT_POSITION_35, _) => {
                self.outcome = Outcome::Attained;
                let delta = f64::from(c.home_offset_counts) - position_counts;
                self.redefine(delta);
                return Some(delta);
            }
            _ if !speeds_ok => None,
            (POSITIVE_SWITCH_FALLING, false) => Some([
                Some(leg(1.0, false, true, false)),
                Some(leg(-1.0, true, false, true)),
                None,
            ]),
            (POSITIVE_SWITCH_FALLING, true) => {
                Some([Some(leg(-1.0, true, false, true)), None, None])
            }
            (POSITIVE_SWITCH_RISING, false) => Some([
                Some(leg(1.0, false, true, false)),
                Some(leg(-1.0, false, false, false)),
                Some(leg(1.0, true, true, true)),
            ]),
            (POSITIVE_SWITCH_RISING, true) => Some([
                Some(leg(-1.0, false, false, false)),
                Some(leg(1.0, true, true, true)),
                None,
            ]),
            (NEGATIVE_SWITCH_FALLING, false) => Some([
                Some(leg(-1.0, false, true, false)),
                Some(leg(1.0, true, false, true)),
                None,
            ]),
            (NEGATIVE_SWITCH_FALLING, true) => {
                Some([Some(leg(1.0, true, false, true)), None, None])
            }
            (NEGATIVE_SWITCH_RISING, false) => Some([
                Some(leg(-1.0, false, true, false)),
                Some(leg(1.0, false, false, false)),
                Some(leg(-1.0, true, true, true)),
            ]),
            (NEGATIVE_SWITCH_RISING, true) => Some([
                Some(leg(1.0, false, false, false)),
                Some(leg(-1.0, true, true, true)),
                None,
            ]),
            _ => None,
        };
        match legs {
            Some(legs) => {
                self.legs = legs;
                self.outcome = Outcome::InProgress;
                self.leg_start = position_counts;
                self.step = Step::Run(0);
            }
            // An unsupported method (or parameters of zero): an error at once.
            None => self.outcome = Outcome::Error,
        }
        None
    }

    /// The falling edge of bit 4, or the halt bit: a homing in progress stops at the
    /// homing acceleration and reports itself interrupted.
    pub(super) fn interrupt(&mut self) {
        if self.outcome == Outcome::InProgress {
            self.outcome = Outcome::Interrupted;
            self.step = Step::Stop(After::Rest);
        }
    }

    fn speed(&self, zero: bool) -> f64 {
        f64::from(if zero {
            self.config.zero_speed_counts_s
        } else {
            self.config.search_speed_counts_s
        })
    }

    /// The reference (position, velocity) at the start of a substep of `dt_s` and its
    /// acceleration over it.
    pub(super) fn command(&self, dt_s: f64) -> (f64, f64, f64) {
        let a_max = f64::from(self.config.acceleration_counts_s2);
        let toward = |v_target: f64| ((v_target - self.v) / dt_s).clamp(-a_max, a_max);
        let a = match self.step {
            Step::Idle | Step::Settle => 0.0,
            Step::Run(n) => match self.legs[n] {
                Some(l) => toward(l.direction * self.speed(l.zero_speed)),
                None => toward(0.0),
            },
            Step::Stop(_) => toward(0.0),
            Step::Return => {
                let d = self.latch - self.r;
                // The speed from which the rest of the way can still be braked, with the
                // speed the next substep adds.
                let brake = (2.0 * a_max * d.abs()).sqrt();
                let v_target = d.signum() * self.speed(true).min(brake);
                toward(v_target)
            }
        };
        (self.r, self.v, a)
    }

    /// Integrates the reference over a substep of `dt_s` with acceleration `a`, and ends
    /// the steps whose reference is done: a stop at rest, a return at the latch.
    pub(super) fn advance(&mut self, a: f64, dt_s: f64) {
        if self.step == Step::Idle || self.step == Step::Settle {
            self.v = 0.0;
            return;
        }
        let a_max = f64::from(self.config.acceleration_counts_s2);
        self.v = if matches!(self.step, Step::Stop(_)) && self.v.abs() <= a_max * dt_s {
            // The last substep of a stop: exactly at rest (v + a·dt is only at rest up to
            // rounding).
            0.0
        } else {
            self.v + a * dt_s
        };
        self.r += self.v * dt_s;
        match self.step {
            Step::Stop(after) if self.v == 0.0 => match after {
                After::Leg(n) => {
                    self.step = Step::Run(n);
                }
                After::Return => self.step = Step::Return,
                After::Rest => self.step = Step::Idle,
            },
            Step::Return => {
                // Within what one substep at the acceleration limit covers, at a speed it
                // can drop: at the latch (the remainder is below a count's thousandth at
                // any sensible speed and acceleration).
                let close = (self.latch - self.r).abs() <= a_max * dt_s * dt_s;
                if close && self.v.abs() <= a_max * dt_s {
                    self.r = self.latch;
                    self.v = 0.0;
                    self.settled_s = 0.0;
                    self.step = Step::Settle;
                }
            }
            _ => {}
        }
    }

    /// After a substep of `dt_s`, the motor at `position_counts` moving at
    /// `velocity_counts_s`: the switch and the search limit seen, a motor settled for a
    /// period attained. Returns the shift of the drive's coordinates when the homing is
    /// attained now.
    pub(super) fn observe(
        &mut self,
        position_counts: f64,
        velocity_counts_s: f64,
        dt_s: f64,
        period_s: f64,
    ) -> Option<f64> {
        let active = self.switch_is_active(position_counts);
        let changed = active != self.switch_active;
        self.switch_active = active;
        match self.step {
            Step::Run(n) => {
                let Some(l) = self.legs[n] else {
                    self.step = Step::Stop(After::Rest);
                    return None;
                };
                if changed && active == l.until_active {
                    self.step = if l.latch {
                        // The position of the switch's edge, in drive counts.
                        let s = self.config.home_switch_counts.unwrap_or(position_counts);
                        self.latch = s + self.frame_shift;
                        Step::Stop(After::Return)
                    } else {
                        self.leg_start = position_counts;
                        Step::Stop(After::Leg(n + 1))
                    };
                } else if (position_counts - self.leg_start).abs()
                    >= self.config.search_limit_counts
                {
                    self.outcome = Outcome::Error;
                    self.step = Step::Stop(After::Rest);
                }
                None
            }
            Step::Stop(After::Leg(_)) => {
                // The next leg's travel counts from where it starts.
                self.leg_start = position_counts;
                None
            }
            Step::Settle => {
                let settled = (position_counts - self.latch).abs() <= SETTLED_COUNTS
                    && velocity_counts_s.abs() * period_s <= SETTLED_COUNTS;
                self.settled_s = if settled { self.settled_s + dt_s } else { 0.0 };
                // (Within rounding of the substeps' sum.)
                if self.settled_s >= period_s * (1.0 - 1e-9) {
                    self.step = Step::Idle;
                    self.outcome = Outcome::Attained;
                    let delta = f64::from(self.config.home_offset_counts) - self.latch;
                    self.redefine(delta);
                    return Some(delta);
                }
                None
            }
            _ => None,
        }
    }

    /// The drive's coordinates move by `delta` counts (the home position becomes the home
    /// offset).
    fn redefine(&mut self, delta: f64) {
        self.r += delta;
        self.latch += delta;
        self.leg_start += delta;
        self.frame_shift += delta;
    }
}
