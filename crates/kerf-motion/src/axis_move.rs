//! A single-axis jerk-limited mover for jogging and homing: [`AxisMove`].
//!
//! The daemon's real-time cycle holds one per axis that jogs or homes, gives it a command
//! when one arrives (or every cycle, the same one again: that changes nothing) and calls
//! [`AxisMove::step`] once per period for the axis's next setpoint. Two kinds of command:
//!
//! - **`move_to(target, speed)`** goes to `target` and stops there, never faster than
//!   `speed`, from whatever state the axis is in. It is one rsruckig position-interface
//!   profile (target velocity and acceleration zero), planned from the state of the last
//!   step, so positions, velocities and accelerations stay continuous through a
//!   re-target. The last sample is `target` itself, bit for bit. A move planned from rest
//!   never passes its target (its samples are kept on this side of it where the plan
//!   never passes it, which only removes rounding).
//! - **`run(velocity)`** runs at a constant signed velocity; `run(0.0)` (and `stop()`)
//!   comes to rest. A velocity change ending at zero acceleration is a closed-form
//!   profile (`VelocityRamp`: the time-optimal three phases of constant jerk, the
//!   acceleration ramped to its peak, held, ramped back to zero), not a solver call: it
//!   cannot fail, and [`AxisMove::stopping_position`] computes the very stop that `stop()`
//!   runs, so a caller that must not pass a bound gets the end of that stop to the bit.
//!
//! A move may begin with one of those closed-form ramps, the move being planned from its
//! end (within the same period, the rest of the period carried over):
//! - **Faster than the move's speed** (the feed override dropping mid-jog): the ramp
//!   down to that speed, then the move from there, if that still stops short of the
//!   target or the axis is heading away from it; else the axis must brake onto the
//!   target anyway, and the move is planned with its current speed as the ceiling.
//! - **A target (all but) where the axis would stop** (within [`TIGHT`] of the move): the
//!   stop, then from rest what is left; a stop that ends on the target but for rounding
//!   rests on the target itself. The solver fails on a braking that must end within a
//!   hair of where it ends anyway.
//! - **An acceleration far above what the move will use** (it would change the speed by
//!   more than the move's peak speed within [`MIN_PHASE`] of its time): one jerk ramp of
//!   it to zero.
//!
//! Design decisions, as in the motion core (see the crate documentation):
//! - **Scaled units.** The solver's tolerances are absolute (1e-8 on position and
//!   velocity, 1e-10 on acceleration), and over the configuration's range (velocities
//!   0.001–1e5, accelerations 0.01–1e8, jerks 1–1e12 per second, distances up to 1e4) the
//!   numbers in mm and s are far from one. Each solver call is made in units in which the
//!   move's peak speed is one and its distance and peak acceleration are balanced about
//!   their product (see `planning_units`).
//! - **Idle limits are lowered.** A limit the move cannot reach is replaced by a lower
//!   one it still cannot reach, and a phase (an acceleration phase, a jerk ramp) shorter
//!   than [`MIN_PHASE`] of the move's time is lengthened to that by lowering its limit, so
//!   the solver never sees limits 1e15 apart. This keeps every limit and changes the time
//!   of a move by a few times that fraction at most.
//! - **Checked results.** A solver result is used only if it ends at rest where it should;
//!   its remaining end error (far below a nanometre) is spread over the profile as a
//!   constant velocity, so the last sample steps onto the target by rounding alone. A
//!   failure is counted ([`AxisMove::plan_failures`]; the tests sweep the whole range and
//!   require zero) and falls back to the closed-form stop, then from rest to the
//!   closed-form [`JerkProfile`]: the axis keeps its limits and never jumps. rsruckig
//!   formats an error message on failure, which allocates: a healthy run has no failures
//!   and so no allocation.
//! - **Idempotent commands.** A command equal to the last one returns at once, so the
//!   caller may repeat it every cycle (a jog renewed by its client) without disturbing the
//!   motion.
//! - **Time** is counted in whole periods since the running profile started, so a long run
//!   accumulates no rounding of the time, and the same calls give bit-identical positions.

use kerf_geom::AxisLimits;
use rsruckig::prelude::*;

use crate::profile::JerkProfile;

/// Shortest phase (a jerk ramp, or a constant-acceleration phase) the mover plans with the
/// solver, as a fraction of the move's time scale: below it the jerk or acceleration limit
/// is lowered (see the module documentation). It changes a move's time by at most a few
/// times this fraction.
pub const MIN_PHASE: f64 = 1e-6;

/// A target closer than this (as a fraction of the larger of the distance to go and the
/// distance to stop) to where the moving axis would stop is reached by that stop and a
/// move from rest over what is left. The solver cannot plan a braking that must end within
/// a hair of where it ends anyway (it fails on such inputs up to a few parts in a million
/// of the distance); the rest is at most this fraction of the move. It is above
/// [`MIN_PHASE`], so the lowered jerk of a plan (which lengthens a stop by less than that
/// fraction) never puts a target beyond the axis's reach.
pub const TIGHT: f64 = 1e-5;

/// Tolerance on the end state of a solver profile in its scaled units (see
/// `planning_units`: the peak speed is one, the distance at most about 1e4): the solver's
/// own precision target. A result further off is a failure. What remains of the position
/// error is spread over the profile as a constant velocity (see `Running::Solver`), so the
/// last sample steps onto the exact target by rounding only.
const END_TOLERANCE: f64 = 1e-8;

/// Why [`AxisMove`] refused an argument. Nothing moves on a refusal.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum AxisMoveError {
    /// The period is not a finite positive number of seconds.
    #[error("period {period_s} s is not a finite positive number")]
    Period {
        /// The period given, s.
        period_s: f64,
    },
    /// An axis limit is not a finite positive number.
    #[error("axis {quantity} limit {value} is not a finite positive number")]
    Limit {
        /// `"velocity"`, `"acceleration"` or `"jerk"`.
        quantity: &'static str,
        /// The limit given, units/sⁿ.
        value: f64,
    },
    /// A position (the start, or a rebase) is not finite.
    #[error("position {position} is not finite")]
    Position {
        /// The position given, mm or deg.
        position: f64,
    },
    /// A move's target (or the distance to it) is not finite.
    #[error("target {target} is not finite or not at a finite distance")]
    Target {
        /// The target given, mm or deg.
        target: f64,
    },
    /// A move's speed is not a finite positive number.
    #[error("speed {speed} is not a finite positive number")]
    Speed {
        /// The speed given, units/s.
        speed: f64,
    },
    /// A run's velocity is not finite.
    #[error("velocity {velocity} is not finite")]
    Velocity {
        /// The velocity given, units/s.
        velocity: f64,
    },
}

/// The last command given, for the idempotence check.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Command {
    /// None since the start or a rebase.
    None,
    /// `move_to(target, speed)` (speed already capped).
    MoveTo { target: f64, speed: f64 },
    /// `run(velocity)` (already capped).
    Run { velocity: f64 },
}

/// What the axis runs.
#[derive(Clone, Copy, Debug)]
enum Running {
    /// At rest at `position`.
    Rest,
    /// A closed-form velocity change, then a constant velocity (or rest at its end if the
    /// velocity is zero). `end_at`: a stop whose end is a target within rounding of it
    /// (its samples are kept on this side of the target, and it rests on it).
    Ramp {
        ramp: VelocityRamp,
        end_at: Option<f64>,
    },
    /// The solver's profile in `traj` to `target`, plus `drift` (scaled length per scaled
    /// time: the profile's end error over its duration, so that it ends on the target
    /// without a step); positions clamped to `[lo, hi]` (the target's side, where the
    /// profile does not pass it).
    Solver {
        target: f64,
        drift: f64,
        lo: f64,
        hi: f64,
    },
    /// The closed-form fallback from rest to `target` (`sign` = direction).
    Own {
        profile: JerkProfile,
        target: f64,
        sign: f64,
    },
}

/// A single-axis jerk-limited mover. See the module documentation.
#[derive(Clone, Debug)]
pub struct AxisMove {
    period_s: f64,
    limits: AxisLimits,
    /// State at the last step.
    position: f64,
    velocity: f64,
    acceleration: f64,
    command: Command,
    running: Running,
    /// A move (target, speed) to plan once the running ramp has ended: after a solver
    /// failure (a stop), or when the acceleration is brought to zero first.
    pending: Option<(f64, f64)>,
    /// Position where the running profile started.
    origin: f64,
    /// Periods since `lead_s` into the running profile.
    cycles: u64,
    /// Time into the running profile at `cycles = 0`, s: the part of a period left over
    /// when the profile before it ended inside the period.
    lead_s: f64,
    otg: Ruckig<1, ThrowErrorHandler>,
    input: InputParameter<1>,
    traj: Trajectory<1>,
    /// Every calculation goes here and is swapped into `traj` on success.
    scratch: Trajectory<1>,
    /// Length unit of `traj`, mm (or deg) per scaled unit.
    unit_length: f64,
    /// Time unit of `traj`, s per scaled unit.
    unit_time_s: f64,
    failures: u64,
}

impl AxisMove {
    /// At rest at `position` (mm or deg), stepping every `period_s` within `limits`
    /// (velocity, acceleration and jerk per second). All memory is allocated here.
    pub fn new(
        period_s: f64,
        limits: AxisLimits,
        position: f64,
    ) -> Result<AxisMove, AxisMoveError> {
        if !(period_s.is_finite() && period_s > 0.0) {
            return Err(AxisMoveError::Period { period_s });
        }
        for (quantity, value) in [
            ("velocity", limits.velocity_units_s),
            ("acceleration", limits.acceleration_units_s2),
            ("jerk", limits.jerk_units_s3),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(AxisMoveError::Limit { quantity, value });
            }
        }
        if !position.is_finite() {
            return Err(AxisMoveError::Position { position });
        }
        let mut traj = Trajectory::new(None);
        traj.reserve_sections(1);
        let mut scratch = Trajectory::new(None);
        scratch.reserve_sections(1);
        Ok(AxisMove {
            period_s,
            limits,
            position,
            velocity: 0.0,
            acceleration: 0.0,
            command: Command::None,
            running: Running::Rest,
            pending: None,
            origin: position,
            cycles: 0,
            lead_s: 0.0,
            otg: Ruckig::new(None, period_s),
            input: InputParameter::new(None),
            traj,
            scratch,
            unit_length: 1.0,
            unit_time_s: 1.0,
            failures: 0,
        })
    }

    /// The period, s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// The limits the axis keeps to.
    pub fn limits(&self) -> AxisLimits {
        self.limits
    }

    /// Position of the last step (the setpoint), mm or deg.
    pub fn position(&self) -> f64 {
        self.position
    }

    /// Velocity of the running profile at the last step, units/s.
    pub fn velocity(&self) -> f64 {
        self.velocity
    }

    /// Acceleration of the running profile at the last step, units/s².
    pub fn acceleration(&self) -> f64 {
        self.acceleration
    }

    /// At rest: no motion left to run, velocity and acceleration zero.
    pub fn at_rest(&self) -> bool {
        matches!(self.running, Running::Rest)
    }

    /// Solver calculations that failed and needed the closed-form fallback so far.
    pub fn plan_failures(&self) -> u64 {
        self.failures
    }

    /// Goes to `target` and stops there exactly, never faster than `speed` (capped at the
    /// velocity limit), from whatever state the axis is in; the same arguments as the last
    /// command change nothing.
    pub fn move_to(&mut self, target: f64, speed: f64) -> Result<(), AxisMoveError> {
        // The distance must be finite too (not from -1e308 to 1e308).
        if !(target - self.position).is_finite() {
            return Err(AxisMoveError::Target { target });
        }
        if !(speed.is_finite() && speed > 0.0) {
            return Err(AxisMoveError::Speed { speed });
        }
        let speed = speed.min(self.limits.velocity_units_s);
        let command = Command::MoveTo { target, speed };
        if command == self.command {
            return Ok(());
        }
        self.command = command;
        self.begin_move(target, speed);
        Ok(())
    }

    /// Runs at the constant signed `velocity` (its magnitude capped at the limit) until
    /// told otherwise; `run(0.0)` stops on a jerk-limited ramp. The same velocity as the
    /// last command changes nothing.
    pub fn run(&mut self, velocity: f64) -> Result<(), AxisMoveError> {
        if !velocity.is_finite() {
            return Err(AxisMoveError::Velocity { velocity });
        }
        let v_max = self.limits.velocity_units_s;
        let velocity = velocity.clamp(-v_max, v_max);
        let command = Command::Run { velocity };
        if command == self.command {
            return Ok(());
        }
        self.command = command;
        // Stopping already (a move's stop onto its target): that stop goes on, so it ends
        // where `stopping_position` said.
        let stopping = matches!(self.running, Running::Ramp { ramp, .. } if ramp.v1 == 0.0);
        if velocity == 0.0 && stopping && self.pending.is_none() {
            return Ok(());
        }
        self.start_ramp(velocity, None);
        Ok(())
    }

    /// A jerk-limited stop as soon as possible (the same as `run(0.0)`).
    pub fn stop(&mut self) {
        // A zero velocity is finite: `run` cannot refuse it.
        let _ = self.run(0.0);
    }

    /// Where a stop started now would come to rest, mm or deg: the end of the running stop,
    /// or of the one [`AxisMove::stop`] would start (the same closed form, to the bit).
    pub fn stopping_position(&self) -> f64 {
        match self.running {
            Running::Rest => self.position,
            Running::Ramp { ramp, end_at } if ramp.v1 == 0.0 && self.pending.is_none() => {
                end_at.unwrap_or(self.origin + ramp.end_distance())
            }
            _ => {
                self.position
                    + VelocityRamp::new(
                        self.velocity,
                        self.acceleration,
                        0.0,
                        self.limits.acceleration_units_s2,
                        self.limits.jerk_units_s3,
                    )
                    .end_distance()
            }
        }
    }

    /// Advances one period and returns the new position. Allocation-free (but for a solver
    /// failure's message), bounded work, never NaN.
    pub fn step(&mut self) -> f64 {
        if matches!(self.running, Running::Rest) {
            return self.position;
        }
        self.cycles += 1;
        // A ramp that ends inside this period with a move waiting behind it (the
        // acceleration brought to zero, a slow-down to the move's speed, a stop) hands the
        // rest of the period to that move, so the motion goes on without a pause. Each
        // hand-over plans the move from the ramp's end, which may start another of those
        // ramps (at most one of each kind in a row); past four the rest of the period is
        // taken up in the next one (a delay of under a period, the motion stays smooth).
        for _ in 0..4 {
            let t_s = self.cycles as f64 * self.period_s + self.lead_s;
            match self.advance(t_s) {
                Some(leftover_s) if !matches!(self.running, Running::Rest) => {
                    self.cycles = 0;
                    self.lead_s = leftover_s;
                }
                _ => break,
            }
        }
        self.position
    }

    /// At rest only: takes `position` as the current position (the machine's coordinates
    /// were shifted by homing) and forgets the last command. `false` (nothing done) while
    /// moving or for a non-finite position.
    pub fn rebase(&mut self, position: f64) -> bool {
        if !self.at_rest() || !position.is_finite() {
            return false;
        }
        self.reset(position);
        true
    }

    /// Drops whatever motion was planned and rests at `position` at once, moving or not:
    /// for an axis that something else brought to rest there (a fault's quick stop). Not
    /// a motion: the caller makes sure the axis really is there. A position that is not
    /// finite is ignored.
    pub fn reset(&mut self, position: f64) {
        if position.is_finite() {
            self.rest_at(position);
            self.command = Command::None;
        }
    }

    /// Samples the running profile `t_s` after its start. `Some(leftover)` when it ended
    /// `leftover` before `t_s` and the move waiting behind it has been planned from its
    /// end (the caller samples that one next).
    fn advance(&mut self, t_s: f64) -> Option<f64> {
        match self.running {
            Running::Rest => {}
            Running::Ramp { ramp: r, end_at } => {
                let end_s = r.duration_s();
                if t_s >= end_s && (r.v1 == 0.0 || self.pending.is_some()) {
                    let x = end_at.unwrap_or(self.origin + r.end_distance());
                    let then = self.pending.take();
                    if r.v1 == 0.0 {
                        self.rest_at(x);
                    } else {
                        self.set_state(x, r.v1, 0.0);
                    }
                    let (target, speed) = then?;
                    self.begin_move(target, speed);
                    return Some(t_s - end_s);
                }
                let (p, v, a) = r.at(t_s);
                let x = match end_at {
                    Some(b) if r.end_distance() > 0.0 => (self.origin + p).min(b),
                    Some(b) => (self.origin + p).max(b),
                    None => self.origin + p,
                };
                self.set_state(x, v, a);
            }
            Running::Solver {
                target,
                drift,
                lo,
                hi,
            } => {
                let tau = self.unit_time_s;
                if t_s >= self.traj.get_duration() * tau {
                    self.rest_at(target);
                } else {
                    let t = t_s / tau;
                    let (p, v, a) = sample(&self.traj, t);
                    let l = self.unit_length;
                    let x = (self.origin + (p + drift * t) * l).clamp(lo, hi);
                    self.set_state(x, (v + drift) * l / tau, a * l / (tau * tau));
                }
            }
            Running::Own {
                profile,
                target,
                sign,
            } => {
                if t_s >= profile.duration_s() {
                    self.rest_at(target);
                } else {
                    let (p, v, a) = profile.at(t_s);
                    let (lo, hi) = if sign > 0.0 {
                        (self.origin, target)
                    } else {
                        (target, self.origin)
                    };
                    self.set_state((self.origin + sign * p).clamp(lo, hi), sign * v, sign * a);
                }
            }
        }
        None
    }

    /// The state after a step; a non-finite sample (which no checked profile gives) keeps
    /// the last state rather than emitting NaN.
    fn set_state(&mut self, x: f64, v: f64, a: f64) {
        if x.is_finite() && v.is_finite() && a.is_finite() {
            self.position = x;
            self.velocity = v;
            self.acceleration = a;
        }
    }

    /// At rest at `x`.
    fn rest_at(&mut self, x: f64) {
        self.position = x;
        self.velocity = 0.0;
        self.acceleration = 0.0;
        self.origin = x;
        self.cycles = 0;
        self.lead_s = 0.0;
        self.pending = None;
        self.running = Running::Rest;
    }

    /// Makes the running profile start at the current state (time zero = the last step).
    fn start_profile(&mut self, running: Running) {
        self.origin = self.position;
        self.cycles = 0;
        self.lead_s = 0.0;
        self.running = running;
    }

    /// Starts the closed-form change to velocity `v1` from the current state, with the
    /// move `then` planned at its end.
    fn start_ramp(&mut self, v1: f64, then: Option<(f64, f64)>) {
        let ramp = VelocityRamp::new(
            self.velocity,
            self.acceleration,
            v1,
            self.limits.acceleration_units_s2,
            self.limits.jerk_units_s3,
        );
        if v1 == 0.0 && ramp.duration_s() == 0.0 {
            self.rest_at(self.position);
            if let Some((target, speed)) = then {
                self.plan_from_rest(target, speed);
            }
        } else {
            self.start_profile(Running::Ramp { ramp, end_at: None });
            self.pending = then;
        }
    }

    /// From rest: the solver's profile to `target`, else the closed-form one.
    fn plan_from_rest(&mut self, target: f64, speed: f64) {
        if !self.plan_move(target, speed) {
            self.own_move(target, speed);
        }
    }

    /// The move to `target` at no more than `speed` from the current state: the solver's
    /// profile; if the solver fails, a stop and then, from rest, the closed-form profile.
    fn begin_move(&mut self, target: f64, speed: f64) {
        self.pending = None;
        if self.plan_move(target, speed) {
            return;
        }
        if self.at_rest() {
            self.own_move(target, speed);
        } else {
            self.start_ramp(0.0, Some((target, speed)));
        }
    }

    /// From rest: the closed-form profile to `target`.
    fn own_move(&mut self, target: f64, speed: f64) {
        let d = target - self.position;
        match JerkProfile::cruise_between(
            0.0,
            0.0,
            d.abs(),
            speed,
            self.limits.acceleration_units_s2,
            self.limits.jerk_units_s3,
        ) {
            Some(profile) => self.start_profile(Running::Own {
                profile,
                target,
                sign: d.signum(),
            }),
            // Only for a distance too small for any profile (a few ulp): reached.
            None => self.rest_at(target),
        }
    }

    /// The solver's position-interface profile from the current state to `target` at no
    /// more than `speed` (or first a ramp of the acceleration to zero, see
    /// [`planning_units`]); `false` (a counted failure, nothing changed) if it failed.
    fn plan_move(&mut self, target: f64, speed: f64) -> bool {
        let AxisLimits {
            acceleration_units_s2: a_max,
            jerk_units_s3: j_max,
            ..
        } = self.limits;
        let (v0, a0) = (self.velocity, self.acceleration.clamp(-a_max, a_max));
        let d = target - self.position;
        let stop = VelocityRamp::new(v0, a0, 0.0, a_max, j_max).end_distance();
        let l = d.abs().max(stop.abs());
        if l == 0.0 {
            // At rest on the target.
            self.rest_at(target);
            return true;
        }
        let moving = v0 != 0.0 || a0 != 0.0;
        if moving && (d - stop).abs() <= TIGHT * l {
            // The target is (all but) where the axis stops: the stop, then what is left
            // from rest. A stop that ends on the target but for rounding (a move re-planned
            // on its own final braking) rests on it, never beyond it, where it goes one
            // way (its velocity keeps its sign).
            let rounding = 16.0 * f64::EPSILON * self.position.abs().max(target.abs()).max(l);
            let w_after = v0 + a0 * a0.abs() / (2.0 * j_max);
            if (d - stop).abs() <= rounding && v0 * w_after >= 0.0 {
                let ramp = VelocityRamp::new(v0, a0, 0.0, a_max, j_max);
                self.start_profile(Running::Ramp {
                    ramp,
                    end_at: Some(target),
                });
            } else {
                self.start_ramp(0.0, Some((target, speed)));
            }
            return true;
        }
        // The velocity once the acceleration is ramped to zero.
        let rise = v0 + a0 * a0.abs() / (2.0 * j_max);
        let mut speed = speed;
        if rise.abs() > speed {
            // Faster than the new speed: come down to it first (a closed-form ramp), then
            // the move from there, if that still stops short of the target or the axis is
            // going away from it. Else the axis must brake onto the target anyway, and the
            // move is planned with its current speed as the ceiling.
            let v1 = speed.copysign(rise);
            let slowed = VelocityRamp::new(v0, a0, v1, a_max, j_max).end_distance()
                + VelocityRamp::new(v1, 0.0, 0.0, a_max, j_max).end_distance();
            if rise * d <= 0.0 || (d - slowed) * d.signum() > TIGHT * l {
                self.start_ramp(v1, Some((target, speed)));
                return true;
            }
            speed = rise.abs();
        }
        let Some(u) = planning_units(v0, a0, l, speed, a_max, j_max) else {
            // The acceleration first: one jerk ramp to zero, then the move from there.
            let v1 = v0 + a0 * a0.abs() / (2.0 * j_max);
            self.start_ramp(v1, Some((target, speed)));
            return true;
        };
        let (tau, unit) = (u.time_s, u.length);
        let (k, kv, ka, kj) = (
            1.0 / unit,
            tau / unit,
            tau * tau / unit,
            tau * tau * tau / unit,
        );
        if !(k.is_finite() && kv.is_finite() && kj.is_finite() && kj > 0.0) {
            self.failures += 1;
            return false;
        }
        let inp = &mut self.input;
        inp.control_interface = ControlInterface::Position;
        inp.current_position[0] = 0.0;
        inp.current_velocity[0] = v0 * kv;
        inp.current_acceleration[0] = a0 * ka;
        inp.target_position[0] = d * k;
        inp.target_velocity[0] = 0.0;
        inp.target_acceleration[0] = 0.0;
        inp.max_velocity[0] = u.speed * kv;
        inp.max_acceleration[0] = u.accel * ka;
        inp.max_jerk[0] = u.jerk * kj;
        let ok = matches!(
            self.otg.calculate(&self.input, &mut self.scratch),
            Ok(RuckigResult::Working)
        );
        let Some(drift) = ok.then(|| end_drift(&self.scratch, d * k)).flatten() else {
            self.failures += 1;
            return false;
        };
        std::mem::swap(&mut self.traj, &mut self.scratch);
        self.unit_length = unit;
        self.unit_time_s = tau;
        // Able to stop before the target at the limits of the plan, the profile never
        // needs to pass it: keep rounding from doing so.
        let stop = VelocityRamp::new(v0, a0, 0.0, u.accel, u.jerk).end_distance();
        let (lo, hi) = match (stop * d.signum() <= d.abs(), d > 0.0) {
            (false, _) => (f64::NEG_INFINITY, f64::INFINITY),
            (true, true) => (f64::NEG_INFINITY, target),
            (true, false) => (target, f64::INFINITY),
        };
        self.start_profile(Running::Solver {
            target,
            drift,
            lo,
            hi,
        });
        true
    }
}

/// The limits a move over `l` from `(v0, a0)` is planned with, and its units of time and
/// length (see the module documentation): `speed`, `a_max`, `j_max` with idle ones
/// lowered, each at most the one given and (but for the phase floor) at least what the
/// move can use of it. `None` when the current acceleration is above the phase floor's
/// acceleration: it would change the speed by more than the move's peak speed within
/// [`MIN_PHASE`] of the move's time, and is brought to zero first.
fn planning_units(v0: f64, a0: f64, l: f64, speed: f64, a_max: f64, j_max: f64) -> Option<Units> {
    // The fastest the axis can be going during the move: where it is (plus the rise while
    // its acceleration ramps to zero), or what it reaches over the way there and back
    // (at most 2 l: the distance to go or to stop is l), from rest to rest at the
    // acceleration (`sqrt(a·2l)`) or the jerk (`(j·(2l)²/4)^(1/3)`) alone.
    let rise = v0.abs() + a0 * a0 / (2.0 * j_max);
    let reach = 3.0 * (a_max * l).sqrt().min((j_max * l * l).cbrt());
    let speed = speed.min(rise + reach);
    let v_peak = rise.max(speed);
    // The move's time scale: the longest time one limit alone needs for l.
    let tau0 = (l / j_max).cbrt().max((l / a_max).sqrt()).max(l / speed);
    // An acceleration above `sqrt(j·dv)` needs a larger velocity change than any of the
    // move's (at most 2 v_peak) to ramp up to and down from: twice that is idle. And a
    // phase shorter than MIN_PHASE of the time scale is lengthened: an acceleration
    // phase by lowering the acceleration, a jerk ramp by lowering the jerk.
    let a_use = (2.0 * j_max * v_peak).sqrt();
    let accel = a_max.min(2.0 * a_use).min(v_peak / (MIN_PHASE * tau0));
    if a0.abs() > accel {
        return None;
    }
    let a_peak = accel.min(a_use).max(a0.abs());
    let jerk = j_max.min(a_peak / (MIN_PHASE * tau0));
    // Units in which the peak speed is one and the distance and the peak acceleration are
    // balanced about their product `R = l·a/v²` (the move's length in acceleration
    // lengths, at most about 1/MIN_PHASE by the floor above): the distance is `10 √R` and
    // the acceleration `√R / 10`, so the solver's absolute tolerances (1e-8 on position,
    // 1e-10 on acceleration) stay far above the rounding of either.
    let r = l * a_peak / (v_peak * v_peak);
    let time_s = 0.1 * r.sqrt() * v_peak / a_peak;
    Some(Units {
        speed,
        accel,
        jerk,
        time_s,
        length: v_peak * time_s,
    })
}

/// See [`planning_units`].
#[derive(Clone, Copy, Debug)]
struct Units {
    speed: f64,
    accel: f64,
    jerk: f64,
    /// Seconds per time unit.
    time_s: f64,
    /// Length (mm or deg) per length unit.
    length: f64,
}

/// A solver result is used only if its duration is finite and positive and it ends at rest
/// at `target` within [`END_TOLERANCE`] (scaled units, so the tolerance is relative to the
/// move): then the drift that makes it end exactly there, else `None`.
fn end_drift(traj: &Trajectory<1>, target: f64) -> Option<f64> {
    let dur = traj.get_duration();
    if !(dur.is_finite() && dur > 0.0) {
        return None;
    }
    let (p, v, a) = sample(traj, dur);
    let ok =
        (p - target).abs() <= END_TOLERANCE && v.abs() <= END_TOLERANCE && a.abs() <= END_TOLERANCE;
    ok.then(|| (target - p) / dur)
}

/// Position, velocity and acceleration of `traj` at (scaled) time `t`.
fn sample(traj: &Trajectory<1>, t: f64) -> (f64, f64, f64) {
    let mut p = DataArrayOrVec::Stack([0.0]);
    let mut v = DataArrayOrVec::Stack([0.0]);
    let mut a = DataArrayOrVec::Stack([0.0]);
    let mut section = None;
    traj.at_time(
        t,
        &mut Some(&mut p),
        &mut Some(&mut v),
        &mut Some(&mut a),
        &mut None,
        &mut section,
    );
    (p[0], v[0], a[0])
}

/// Phases of a [`VelocityRamp`].
const RAMP_PHASES: usize = 3;

/// The time-optimal jerk-limited change from velocity `v0` and acceleration `a0` to
/// velocity `v1` with zero acceleration, then constant velocity `v1`: the acceleration
/// ramped at the jerk limit to its peak (capped at the acceleration limit, then held) and
/// back to zero. The positions are relative to the start.
#[derive(Clone, Copy, Debug, Default)]
struct VelocityRamp {
    /// The end velocity, units/s.
    v1: f64,
    /// Start time of each phase, s (`start_s[3]` is the duration).
    start_s: [f64; RAMP_PHASES + 1],
    jerk: [f64; RAMP_PHASES],
    p: [f64; RAMP_PHASES + 1],
    v: [f64; RAMP_PHASES + 1],
    a: [f64; RAMP_PHASES + 1],
}

impl VelocityRamp {
    fn new(v0: f64, a0: f64, v1: f64, a_max: f64, j_max: f64) -> Self {
        let a0 = a0.clamp(-a_max, a_max);
        // The velocity (relative to v1) once the acceleration is ramped to zero at once
        // decides the direction of the change: `sign` is the direction of the velocity
        // excess, the acceleration goes the other way.
        let w = v0 - v1;
        let w_after = w + a0 * a0.abs() / (2.0 * j_max);
        let sign = if w_after < 0.0 { -1.0 } else { 1.0 };
        let (w, a) = (sign * w, sign * a0);
        // Peak (braking) acceleration of a triangular profile: w + (a² − 2 peak²)/(2j) = 0.
        let mut peak = (j_max * w + 0.5 * a * a).max(0.0).sqrt();
        let mut hold_s = 0.0;
        if peak > a_max {
            peak = a_max;
            hold_s = ((w + 0.5 * a * a / j_max) / a_max - a_max / j_max).max(0.0);
        }
        let durations = [((a + peak) / j_max).max(0.0), hold_s, peak / j_max];
        let jerks = [-sign * j_max, 0.0, sign * j_max];
        let mut r = VelocityRamp {
            v1,
            ..VelocityRamp::default()
        };
        r.v[0] = v0;
        r.a[0] = a0;
        for i in 0..RAMP_PHASES {
            let (p, v, a) = integrate(r.p[i], r.v[i], r.a[i], jerks[i], durations[i]);
            r.jerk[i] = jerks[i];
            r.start_s[i + 1] = r.start_s[i] + durations[i];
            (r.p[i + 1], r.v[i + 1], r.a[i + 1]) = (p, v, a);
        }
        // By construction the change ends at v1 with zero acceleration; remove the rounding
        // so the constant velocity after it is exact.
        r.v[RAMP_PHASES] = v1;
        r.a[RAMP_PHASES] = 0.0;
        r
    }

    /// Duration of the change, s.
    fn duration_s(&self) -> f64 {
        self.start_s[RAMP_PHASES]
    }

    /// Distance covered by the end of the change.
    fn end_distance(&self) -> f64 {
        self.p[RAMP_PHASES]
    }

    /// Position, velocity and acceleration `t_s` after the start (constant velocity `v1`
    /// after the change).
    fn at(&self, t_s: f64) -> (f64, f64, f64) {
        let t_s = t_s.max(0.0);
        if t_s >= self.duration_s() {
            let n = RAMP_PHASES;
            return (self.p[n] + self.v1 * (t_s - self.start_s[n]), self.v1, 0.0);
        }
        let mut i = 0;
        while i + 1 < RAMP_PHASES && t_s >= self.start_s[i + 1] {
            i += 1;
        }
        integrate(
            self.p[i],
            self.v[i],
            self.a[i],
            self.jerk[i],
            t_s - self.start_s[i],
        )
    }
}

/// The state after `t` at constant jerk `j` from `(p, v, a)`.
fn integrate(p: f64, v: f64, a: f64, j: f64, t: f64) -> (f64, f64, f64) {
    (
        p + t * (v + t * (a / 2.0 + t * j / 6.0)),
        v + t * (a + t * j / 2.0),
        a + t * j,
    )
}
