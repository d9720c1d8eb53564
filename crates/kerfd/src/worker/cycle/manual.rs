//! Manual motion in the cycle: jogging and homing, one jerk-limited mover per axis
//! (`kerf_motion::axis_move::AxisMove`), the homing sequencers (`kerf_drive::homing`), the
//! simulated home and limit switches, and the hard limit switches.
//!
//! Manual motion runs only while no program does (a program is refused while an axis
//! moves by hand, and a jog or homing is refused while a program runs): one source of
//! motion at a time. Everything here is built once and allocation-free per cycle.

use kerf_config::{AxisSetup, HomingKind};
use kerf_drive::homing::{
    HomeCommand, HomeError, HomeInput, HomeKind, HomePhase, HomeSetup, Homing,
};
use kerf_drive::safety::Check;
use kerf_geom::PerAxis;
use kerf_motion::axis_move::AxisMove;
use kerf_proto::Jog;

/// How an axis jogs.
#[derive(Clone, Copy, Debug, PartialEq)]
enum JogMode {
    /// Not jogging (the mover may still ramp to rest).
    Idle,
    /// While renewed: in a direction at a speed, until cycle `until` (the dead man's
    /// switch).
    Continuous {
        positive: bool,
        speed: f64,
        until: u64,
    },
    /// To a target, stopping there exactly.
    Target { target: f64, speed: f64 },
}

/// Where an axis homed by its drive (CiA 402 homing mode) stands.
#[derive(Clone, Copy, Debug, PartialEq)]
enum DriveStep {
    /// Not homing by the drive.
    Off,
    /// The drive stage is to start the drive's homing this cycle.
    Start,
    /// The drive homes; the axis follows its actual position.
    Running,
    /// The drive has homed: the axis moves to its home position.
    Final,
}

/// One axis's manual side.
struct ManualAxis {
    /// Homing by the drive: its step.
    drive: DriveStep,
    mover: AxisMove,
    setup: AxisSetup,
    velocity_limit: f64,
    min: f64,
    max: f64,
    homing: Homing,
    homed: bool,
    jog: JogMode,
    /// The side (-1 lower, +1 upper) of a hard limit switch the axis stands on after a
    /// reset: it may be jogged away from it only.
    released: i8,
    /// The homing phase as last reported (a sequencer that ended reports `Idle` here).
    phase: u8,
}

/// What one manual cycle asks of the cycle around it.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct ManualOut {
    /// Axes the manual motion moved this cycle (their positions are in `position`).
    pub(crate) moved: u32,
    /// Axes whose drive is to start homing (CiA 402 homing mode) this cycle.
    pub(crate) drive_start: u32,
    /// The new positions of the moved axes.
    pub(crate) position: PerAxis<f64>,
    /// Coordinate shifts homing asks for (at rest), per axis.
    pub(crate) shift: PerAxis<Option<f64>>,
    /// A fault to latch: (check, axis, value, limit).
    pub(crate) fault: Option<(Check, usize, f64, f64)>,
}

/// Where the way back to a paused program's position stands: Z up (never down) first,
/// then the other axes, then Z down to where the program paused.
#[derive(Clone, Copy, Debug, PartialEq)]
enum ReturnStage {
    Up,
    Across,
    Down,
}

/// The manual side of the machine: jogs, homing, switches.
pub(crate) struct Manual {
    /// The way back to a paused program's position, while it runs.
    back: Option<(PerAxis<f64>, ReturnStage)>,
    axes: [Option<ManualAxis>; 6],
    deadman_cycles: u64,
    required: bool,
    unhomed_jog_pct: f64,
    default_speed_pct: f64,
    /// Axes asked to home and not done yet.
    pending: u32,
}

/// The sequencer's configuration of an axis.
fn home_setup(setup: &AxisSetup) -> HomeSetup {
    let h = &setup.homing;
    HomeSetup {
        kind: match h.kind {
            // The drive homes itself: Kerf's sequencer is not used (see `DriveStep`).
            HomingKind::None | HomingKind::Drive => HomeKind::None,
            HomingKind::Switch => HomeKind::Switch,
            HomingKind::Absolute => HomeKind::Absolute,
        },
        search_velocity: h.search_velocity_units_s,
        latch_velocity: h.latch_velocity_units_s,
        search_distance: h.search_distance_units,
        home_offset: h.home_offset_units,
        home_position: h.home_units,
        final_speed: h.final_speed_units_s,
    }
}

/// The `HOME_PHASE_*` of a sequencer's phase.
fn phase_code(phase: HomePhase) -> u8 {
    match phase {
        HomePhase::InitialBackOff => kerf_proto::HOME_PHASE_MOVE_OFF,
        HomePhase::Search => kerf_proto::HOME_PHASE_SEARCH,
        HomePhase::BackOff => kerf_proto::HOME_PHASE_BACK_OFF,
        HomePhase::Latch => kerf_proto::HOME_PHASE_LATCH,
        HomePhase::Final => kerf_proto::HOME_PHASE_FINAL,
        _ => kerf_proto::HOME_PHASE_IDLE,
    }
}

/// The safety check of a homing error that is a fault: (check, distance travelled,
/// limit); `None` for an abort (the operator's, not a fault).
fn home_fault(e: HomeError) -> Option<(Check, f64, f64)> {
    match e {
        // The sequencer stops looking once the phase's window is travelled.
        HomeError::SwitchNotFound { phase, distance } => Some(match phase {
            HomePhase::InitialBackOff | HomePhase::BackOff => {
                (Check::HomeRelease, distance, distance)
            }
            HomePhase::Latch => (Check::HomeLatch, distance, distance),
            _ => (Check::HomeSearch, distance, distance),
        }),
        _ => None,
    }
}

/// The status of the manual side.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ManualStatus {
    /// Bit i: axis i homed.
    pub homed: u32,
    /// Programs need every axis homed.
    pub required: bool,
    /// Bit i: axis i homing (or waiting to).
    pub homing: u32,
    /// Bit i: axis i jogging or ramping to rest after a jog.
    pub jogging: u32,
    /// Bit i: axis i's home switch active.
    pub home_switches: u32,
    /// Bit i: axis i's lower hard limit switch active.
    pub min_limit_switches: u32,
    /// Bit i: axis i's upper hard limit switch active.
    pub max_limit_switches: u32,
    /// Bit i: axis i stands on a hard limit switch after a reset.
    pub limit_released: u32,
    /// Per axis, `HOME_PHASE_*`.
    pub home_phase: [u8; 6],
}

impl Manual {
    /// The manual side of `config`'s machine, at rest at `position`. Jogs keep to the soft
    /// limits the safety layer checks (`Config::safety_config`).
    pub(crate) fn new(
        config: &kerf_config::Config,
        limits: &kerf_geom::MachineLimits,
        position: PerAxis<f64>,
    ) -> Result<Manual, String> {
        let setups = config.axis_setups();
        let safety = config.safety_config();
        let mut axes: [Option<ManualAxis>; 6] = [None, None, None, None, None, None];
        for (i, slot) in axes.iter_mut().enumerate() {
            let (Some(setup), Some(l)) = (setups[i], limits.axes[i]) else {
                continue;
            };
            let name = kerf_geom::AXIS_NAMES[i];
            // Moves by hand brake with the share of the limits the path profile uses: the
            // safety layer refuses a setpoint once a quick stop at the full limits could
            // not end within the soft limits, so a jog that stops at a soft limit must
            // brake no harder than that stop.
            let share = kerf_plan::PROFILE_SHARE;
            let mover_limits = kerf_geom::AxisLimits {
                velocity_units_s: l.velocity_units_s,
                acceleration_units_s2: l.acceleration_units_s2 * share,
                jerk_units_s3: l.jerk_units_s3 * share,
            };
            let mover = AxisMove::new(limits.period_s, mover_limits, position[i])
                .map_err(|e| format!("axis {name}: {e}"))?;
            let homing =
                Homing::new(home_setup(&setup)).map_err(|e| format!("axis {name}: homing: {e}"))?;
            let (min, max) = safety.axes[i].map_or((f64::NEG_INFINITY, f64::INFINITY), |a| {
                (a.min_limit_units, a.max_limit_units)
            });
            *slot = Some(ManualAxis {
                drive: DriveStep::Off,
                mover,
                setup,
                velocity_limit: l.velocity_units_s,
                min,
                max,
                homing,
                homed: setup.homing.kind.homed_at_start(),
                jog: JogMode::Idle,
                released: 0,
                phase: kerf_proto::HOME_PHASE_IDLE,
            });
        }
        let period_s = limits.period_s;
        Ok(Manual {
            axes,
            // Whole periods (a period that does not divide it rounds to the nearest).
            deadman_cycles: ((f64::from(config.jog.deadman_ms) * 1e-3) / period_s).round() as u64,
            required: config.homing.required,
            unhomed_jog_pct: config.homing.unhomed_jog_pct,
            default_speed_pct: config.jog.default_speed_pct,
            pending: 0,
            back: None,
        })
    }

    /// The drive offset an absolute encoder's axis starts with (machine = drive +
    /// offset), per axis.
    pub(crate) fn absolute_offsets(&self) -> PerAxis<Option<f64>> {
        let mut out = [None; 6];
        for (o, ax) in out.iter_mut().zip(self.axes.iter()) {
            if let Some(ax) = ax
                && ax.setup.homing.kind == HomingKind::Absolute
            {
                *o = Some(ax.setup.homing.home_offset_units);
            }
        }
        out
    }

    /// Whether the machine has axis `i`.
    pub(crate) fn has_axis(&self, i: usize) -> bool {
        self.axes.get(i).is_some_and(Option::is_some)
    }

    /// The first axis that keeps programs from starting: not homed (when homing is
    /// required), or standing on a hard limit switch.
    pub(crate) fn blocks_programs(&self) -> Option<(usize, bool)> {
        for (i, ax) in self.axes.iter().enumerate() {
            let Some(ax) = ax else { continue };
            if self.required && !ax.homed {
                return Some((i, false));
            }
            if ax.released != 0 {
                return Some((i, true));
            }
        }
        None
    }

    /// Whether any axis moves by hand, homes or waits to home.
    pub(crate) fn active(&self) -> bool {
        self.back.is_some()
            || self.pending != 0
            || self
                .axes
                .iter()
                .flatten()
                .any(|a| a.jog != JogMode::Idle || !a.mover.at_rest() || a.phase != 0)
    }

    /// Every mover rests at `position` (the machine's position while nothing moves by
    /// hand, or where a fault's quick stop holds the axes).
    pub(crate) fn rest_at(&mut self, position: &PerAxis<f64>) {
        for (i, ax) in self.axes.iter_mut().enumerate() {
            if let Some(ax) = ax
                && (ax.mover.position() != position[i] || !ax.mover.at_rest())
            {
                ax.mover.reset(position[i]);
            }
        }
    }

    /// Stops every jog and homing at once (an abort, a fault): the movers ramp to rest,
    /// axes that were homing stay unhomed.
    pub(crate) fn abort(&mut self) {
        self.pending = 0;
        self.back = None;
        for ax in self.axes.iter_mut().flatten() {
            ax.jog = JogMode::Idle;
            ax.drive = DriveStep::Off;
            if ax.phase != 0 {
                ax.homing.abort();
                ax.phase = 0;
            }
            ax.mover.stop();
        }
    }

    /// The speed a jog of `axis` runs at: `speed` (0: the configured default), capped
    /// while the axis is not homed (`homed`). Err with the reason when above the limit.
    fn jog_speed(&self, axis: usize, speed: f64, homed: bool) -> Result<f64, String> {
        let name = kerf_geom::AXIS_NAMES.get(axis).copied().unwrap_or('?');
        let Some(ax) = self.axes.get(axis).and_then(Option::as_ref) else {
            return Err(format!("this machine has no axis {name}"));
        };
        let v = ax.velocity_limit;
        let cap = if homed {
            v
        } else {
            v * self.unhomed_jog_pct / 100.0
        };
        if speed == 0.0 {
            return Ok((v * self.default_speed_pct / 100.0).min(cap));
        }
        if speed > cap {
            return Err(if homed {
                format!("jog speed {speed} is above axis {name}'s velocity limit {v}")
            } else {
                format!(
                    "jog speed {speed} is above {cap} ({} % of axis {name}'s velocity, the limit while it is not homed)",
                    self.unhomed_jog_pct
                )
            });
        }
        Ok(speed)
    }

    /// Checks a jog of `axis` from `position` on the machine as it is: `homed` (the axis),
    /// `released` (the side of the hard limit switch it stands on after a reset: -1 the
    /// lower, +1 the upper, 0 none): the speed (returned, the default filled in), the soft
    /// limits of a homed axis, the direction off a hard limit switch. Returns the speed,
    /// the target (none for a continuous jog) and the direction; Err with the reason.
    pub(crate) fn check_jog(
        &self,
        axis: usize,
        jog: Jog,
        speed: f64,
        position: f64,
        homed: bool,
        released: i8,
    ) -> Result<(f64, Option<f64>, i8), String> {
        let speed = self.jog_speed(axis, speed, homed)?;
        let name = kerf_geom::AXIS_NAMES[axis];
        let Some(ax) = self.axes[axis].as_ref() else {
            return Err(format!("this machine has no axis {name}"));
        };
        let (direction, target) = match jog {
            Jog::Continuous(positive) => (if positive { 1 } else { -1 }, None),
            Jog::Step(d) => (if d > 0.0 { 1 } else { -1 }, Some(position + d)),
            Jog::To(x) => (if x >= position { 1 } else { -1 }, Some(x)),
        };
        if released != 0 && direction == released {
            return Err(format!(
                "axis {name} stands on its {} hard limit switch: jog it the other way",
                if released < 0 { "lower" } else { "upper" }
            ));
        }
        if let Some(t) = target
            && homed
            && !(t >= ax.min && t <= ax.max)
        {
            return Err(format!(
                "axis {name}: {t:.4} is beyond the soft limits {:.4} to {:.4}",
                ax.min, ax.max
            ));
        }
        Ok((speed, target, direction))
    }

    /// Starts (or renews) a jog of `axis` from `position` at cycle `now`. Err with the
    /// reason when refused (nothing moves then).
    pub(crate) fn jog(
        &mut self,
        axis: usize,
        jog: Jog,
        speed: f64,
        position: f64,
        now: u64,
    ) -> Result<(), String> {
        if self.pending != 0 || self.axes.iter().flatten().any(|a| a.phase != 0) {
            return Err("the machine is homing".to_string());
        }
        // A step adds to the target of a step still running.
        let from = match self.axes.get(axis).and_then(Option::as_ref).map(|a| a.jog) {
            Some(JogMode::Target { target, .. }) if matches!(jog, Jog::Step(_)) => target,
            _ => position,
        };
        let (homed, released) = self.axes[axis]
            .as_ref()
            .map_or((true, 0), |a| (a.homed, a.released));
        let (speed, target, direction) = self.check_jog(axis, jog, speed, from, homed, released)?;
        let deadman = self.deadman_cycles;
        let Some(ax) = self.axes[axis].as_mut() else {
            return Err("no such axis".to_string());
        };
        ax.jog = match target {
            None => JogMode::Continuous {
                positive: direction > 0,
                speed,
                until: now + deadman,
            },
            Some(target) => JogMode::Target { target, speed },
        };
        Ok(())
    }

    /// Stops the jog of `axis` on a jerk-limited ramp (not homing, nor the way back to a
    /// paused program: those stop with an abort).
    pub(crate) fn jog_stop(&mut self, axis: usize) {
        if self.back.is_some() {
            return;
        }
        if let Some(Some(ax)) = self.axes.get_mut(axis)
            && ax.phase == 0
        {
            ax.jog = JogMode::Idle;
            ax.mover.stop();
        }
    }

    /// Asks to home the axes of `mask` (bit i: axis i); the ones without homing motion
    /// are homed at once. Err with the reason when refused.
    pub(crate) fn home(&mut self, mask: u32) -> Result<(), String> {
        for (i, ax) in self.axes.iter().enumerate() {
            if mask & (1 << i) != 0 && ax.is_none() {
                return Err(format!(
                    "this machine has no axis {}",
                    kerf_geom::AXIS_NAMES[i]
                ));
            }
        }
        if self
            .axes
            .iter()
            .flatten()
            .any(|a| a.jog != JogMode::Idle || !a.mover.at_rest())
        {
            return Err("an axis is jogging".to_string());
        }
        for (i, ax) in self.axes.iter_mut().enumerate() {
            let Some(ax) = ax else { continue };
            if mask & (1 << i) == 0 {
                continue;
            }
            if matches!(ax.setup.homing.kind, HomingKind::Switch | HomingKind::Drive) {
                self.pending |= 1 << i;
                ax.homed = false;
                ax.phase = kerf_proto::HOME_PHASE_WAITING;
            } else {
                ax.homed = true;
            }
        }
        Ok(())
    }

    /// After a reset: axes standing on a hard limit switch may be jogged off it (away from
    /// it only).
    pub(crate) fn after_reset(&mut self, io: &kerf_drive::machine::IoImage) {
        for ax in self.axes.iter_mut().flatten() {
            let (min, max) = limit_switches(ax, io);
            ax.released = if min {
                -1
            } else if max {
                1
            } else {
                0
            };
        }
    }

    /// The first hard limit switch that trips: (axis, side -1 lower / +1 upper). An axis
    /// released after a reset trips again only on the other switch; its release ends when
    /// its switch lets go.
    pub(crate) fn hard_limit(&mut self, io: &kerf_drive::machine::IoImage) -> Option<(usize, i8)> {
        for (i, ax) in self.axes.iter_mut().enumerate() {
            let Some(ax) = ax else { continue };
            let (min, max) = limit_switches(ax, io);
            if ax.released != 0 && !min && !max {
                ax.released = 0;
            }
            if min && ax.released != -1 {
                return Some((i, -1));
            }
            if max && ax.released != 1 {
                return Some((i, 1));
            }
        }
        None
    }

    /// Drives the simulated switches of every axis from the drives' positions `drive`
    /// (in the drives' own frame, without the homing offset).
    pub(crate) fn simulate_switches(
        &self,
        drive: &PerAxis<f64>,
        machine: &mut kerf_drive::machine::Machine,
    ) {
        for (i, ax) in self.axes.iter().enumerate() {
            let Some(ax) = ax else { continue };
            for s in simulated_switches(&ax.setup).into_iter().flatten() {
                machine.drive_input(s.input, s.active_at(drive[i]));
            }
        }
    }

    /// The soft limits each axis needs checked now: on once homed.
    pub(crate) fn soft_limits(&self) -> PerAxis<bool> {
        let mut on = [true; 6];
        for (o, ax) in on.iter_mut().zip(self.axes.iter()) {
            if let Some(ax) = ax {
                *o = ax.homed;
            }
        }
        on
    }

    /// One period of manual motion. `actual`: the drives' actual positions (machine
    /// frame), `override_factor` the feed override in force (jogs follow it, homing does
    /// not), `now` the cycle number.
    pub(crate) fn cycle(
        &mut self,
        io: &kerf_drive::machine::IoImage,
        actual: &PerAxis<f64>,
        override_factor: f64,
        now: u64,
    ) -> ManualOut {
        let mut out = ManualOut::default();
        self.advance_sequence();
        self.advance_return();
        for (i, slot) in self.axes.iter_mut().enumerate() {
            let Some(ax) = slot else { continue };
            if ax.drive != DriveStep::Off {
                match ax.drive {
                    DriveStep::Start => {
                        out.drive_start |= 1 << i;
                        ax.drive = DriveStep::Running;
                    }
                    // The drive moves the axis; the cycle follows its actual position.
                    DriveStep::Running | DriveStep::Off => {}
                    DriveStep::Final => {
                        let home = ax.setup.homing.home_units;
                        if ax.mover.at_rest() && ax.mover.position() == home {
                            ax.drive = DriveStep::Off;
                            ax.homed = true;
                            ax.phase = 0;
                            self.pending &= !(1 << i);
                        } else {
                            // Above 0 for every kind that homes (the configuration fills
                            // in its default).
                            let _ = ax.mover.move_to(home, ax.setup.homing.final_speed_units_s);
                        }
                    }
                }
            } else if ax.phase > kerf_proto::HOME_PHASE_WAITING || ax.homing_started() {
                let input = HomeInput {
                    switch: ax
                        .setup
                        .homing
                        .switch_input
                        .is_some_and(|n| io.digital_input(n as u8)),
                    position: actual[i],
                    at_rest: ax.mover.at_rest(),
                };
                match ax.homing.cycle(&input) {
                    HomeCommand::Hold => {}
                    HomeCommand::Run(v) => {
                        let _ = ax.mover.run(v);
                    }
                    HomeCommand::Stop => ax.mover.stop(),
                    HomeCommand::MoveTo { position, speed } => {
                        let _ = ax.mover.move_to(position, speed);
                    }
                    HomeCommand::Shift(d) => out.shift[i] = Some(d),
                }
                if let Some(e) = ax.homing.error() {
                    if let Some((check, value, limit)) = home_fault(e) {
                        out.fault.get_or_insert((check, i, value, limit));
                    }
                    ax.phase = 0;
                    self.pending &= !(1 << i);
                    ax.mover.stop();
                } else if ax.homing.phase() == HomePhase::Done {
                    ax.homed = true;
                    ax.phase = 0;
                    self.pending &= !(1 << i);
                } else {
                    ax.phase = phase_code(ax.homing.phase());
                }
            } else {
                match ax.jog {
                    JogMode::Idle => {}
                    JogMode::Continuous { until, .. } if now > until => {
                        // The dead man's switch: no renewal in time.
                        ax.jog = JogMode::Idle;
                        ax.mover.stop();
                    }
                    JogMode::Continuous {
                        positive, speed, ..
                    } => {
                        let v = speed * override_factor;
                        if v <= 0.0 {
                            ax.mover.stop();
                        } else if ax.homed {
                            let bound = if positive { ax.max } else { ax.min };
                            let _ = ax.mover.move_to(bound, v);
                        } else {
                            let _ = ax.mover.run(if positive { v } else { -v });
                        }
                    }
                    JogMode::Target { target, speed } => {
                        let v = speed * override_factor;
                        if v <= 0.0 {
                            ax.mover.stop();
                        } else {
                            let _ = ax.mover.move_to(target, v);
                        }
                        if ax.mover.at_rest() && ax.mover.position() == target {
                            ax.jog = JogMode::Idle;
                        }
                    }
                }
            }
            if ax.drive == DriveStep::Running {
                // Not the mover's: the cycle takes the drive's actual position.
                continue;
            }
            if !ax.mover.at_rest() || ax.jog != JogMode::Idle || ax.phase != 0 {
                out.position[i] = ax.mover.step();
                out.moved |= 1 << i;
            }
        }
        out
    }

    /// Axis `i`'s coordinates were shifted by `delta` (homing's latch): its mover follows.
    pub(crate) fn shifted(&mut self, i: usize, delta: f64) {
        if let Some(Some(ax)) = self.axes.get_mut(i) {
            let p = ax.mover.position() + delta;
            ax.mover.reset(p);
        }
    }

    /// Axis `i`'s drive has homed and stands at `position` (the drive's new coordinates):
    /// its mover rests there, and the axis moves on to its home position.
    pub(crate) fn drive_homed(&mut self, i: usize, position: f64) {
        if let Some(Some(ax)) = self.axes.get_mut(i)
            && ax.drive == DriveStep::Running
        {
            ax.mover.reset(position);
            ax.drive = DriveStep::Final;
            ax.phase = kerf_proto::HOME_PHASE_FINAL;
        }
    }

    /// The drive stage could not start axis `i`'s homing by its drive, or the drive's
    /// homing ended without a position: its homing ends unhomed.
    pub(crate) fn drive_homing_failed(&mut self, i: usize) {
        if let Some(Some(ax)) = self.axes.get_mut(i) {
            ax.drive = DriveStep::Off;
            ax.phase = 0;
            self.pending &= !(1 << i);
        }
    }

    /// Homing could not shift axis `i`'s coordinates: its homing ends unhomed.
    pub(crate) fn shift_refused(&mut self, i: usize) {
        if let Some(Some(ax)) = self.axes.get_mut(i) {
            ax.homing.abort();
            ax.phase = 0;
            self.pending &= !(1 << i);
        }
    }

    /// Starts the way back to `target` (where a paused program stopped, before the
    /// operator jogged): Z up to the higher of where it is and its target first, then
    /// every other axis, then Z down to its target; each at its default jog speed. The
    /// program resumes once it is done ([`Manual::active`] false again).
    pub(crate) fn start_return(&mut self, target: PerAxis<f64>) {
        for ax in self.axes.iter_mut().flatten() {
            ax.jog = JogMode::Idle;
        }
        self.back = Some((target, ReturnStage::Up));
    }

    /// One cycle of the way back: gives each axis of the current stage its target, and
    /// moves to the next stage once they are all at rest there.
    fn advance_return(&mut self) {
        let Some((target, stage)) = self.back else {
            return;
        };
        let pct = self.default_speed_pct;
        const Z: usize = 2;
        let mut all_there = true;
        for (i, ax) in self.axes.iter_mut().enumerate() {
            let Some(ax) = ax else { continue };
            let goal = match (stage, i) {
                (ReturnStage::Up, Z) => Some(ax.mover.position().max(target[Z])),
                (ReturnStage::Across, i) if i != Z => Some(target[i]),
                (ReturnStage::Down, Z) => Some(target[Z]),
                _ => None,
            };
            let Some(goal) = goal else { continue };
            let there = ax.mover.at_rest() && ax.mover.position() == goal;
            if !there {
                all_there = false;
                if ax.jog == JogMode::Idle {
                    ax.jog = JogMode::Target {
                        target: goal,
                        speed: ax.velocity_limit * pct / 100.0,
                    };
                }
            }
        }
        if all_there {
            self.back = match stage {
                ReturnStage::Up => Some((target, ReturnStage::Across)),
                ReturnStage::Across => Some((target, ReturnStage::Down)),
                ReturnStage::Down => None,
            };
        }
    }

    /// Starts the axes of the lowest pending home sequence once the one before is done.
    fn advance_sequence(&mut self) {
        let busy = self
            .axes
            .iter()
            .flatten()
            .any(|a| a.phase > kerf_proto::HOME_PHASE_WAITING);
        if busy || self.pending == 0 {
            return;
        }
        let next = self
            .axes
            .iter()
            .enumerate()
            .filter(|(i, a)| a.is_some() && self.pending & (1 << i) != 0)
            .filter_map(|(_, a)| a.as_ref().map(|a| a.setup.homing.sequence))
            .min();
        for (i, ax) in self.axes.iter_mut().enumerate() {
            let Some(ax) = ax else { continue };
            if self.pending & (1 << i) != 0 && Some(ax.setup.homing.sequence) == next {
                if ax.setup.homing.kind == HomingKind::Drive {
                    ax.drive = DriveStep::Start;
                    ax.phase = kerf_proto::HOME_PHASE_SEARCH;
                } else {
                    ax.homing.start();
                    ax.phase = phase_code(ax.homing.phase()).max(kerf_proto::HOME_PHASE_MOVE_OFF);
                }
            }
        }
    }

    /// The status of the manual side, with the switches as `io` has them.
    pub(crate) fn status(&self, io: &kerf_drive::machine::IoImage) -> ManualStatus {
        let mut s = ManualStatus {
            required: self.required,
            ..ManualStatus::default()
        };
        for (i, ax) in self.axes.iter().enumerate() {
            let Some(ax) = ax else { continue };
            let bit = 1u32 << i;
            if ax.homed {
                s.homed |= bit;
            }
            if ax.phase != 0 || self.pending & bit != 0 {
                s.homing |= bit;
            }
            if ax.jog != JogMode::Idle || (!ax.mover.at_rest() && ax.phase == 0) {
                s.jogging |= bit;
            }
            if ax
                .setup
                .homing
                .switch_input
                .is_some_and(|n| io.digital_input(n as u8))
            {
                s.home_switches |= bit;
            }
            let (min, max) = limit_switches(ax, io);
            if min {
                s.min_limit_switches |= bit;
            }
            if max {
                s.max_limit_switches |= bit;
            }
            if ax.released != 0 {
                s.limit_released |= bit;
            }
            s.home_phase[i] = ax.phase;
        }
        s
    }
}

impl ManualAxis {
    /// The sequencer runs (it was started and has not ended).
    fn homing_started(&self) -> bool {
        !matches!(
            self.homing.phase(),
            HomePhase::Idle | HomePhase::Done | HomePhase::Failed
        )
    }
}

/// A switch that the simulated machine places on an axis (`[axes.*.sim]`) and whose input
/// it sets from the axis's position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SimSwitch {
    /// The digital input.
    pub(crate) input: u8,
    /// Where it is, in the drive's own frame.
    pub(crate) at: f64,
    /// Active at and above `at` (else at and below).
    pub(crate) above: bool,
}

impl SimSwitch {
    /// Whether the switch is active with the axis's drive at `x`.
    fn active_at(self, x: f64) -> bool {
        if self.above {
            x >= self.at
        } else {
            x <= self.at
        }
    }
}

/// The switches the simulated machine places on the axis of `setup`: the home switch
/// (active beyond its place in the search direction), the lower and the upper limit
/// switch. The one list the simulation drives and `kerf input` refuses to set.
pub(crate) fn simulated_switches(setup: &AxisSetup) -> [Option<SimSwitch>; 3] {
    let switch = |at: Option<f64>, input: Option<u32>, above: bool| {
        Some(SimSwitch {
            input: u8::try_from(input?).ok()?,
            at: at?,
            above,
        })
    };
    let sim = &setup.sim;
    [
        switch(
            sim.home_switch_units,
            setup.homing.switch_input,
            setup.homing.search_velocity_units_s >= 0.0,
        ),
        switch(sim.min_limit_units, setup.limit_switches.min_input, false),
        switch(sim.max_limit_units, setup.limit_switches.max_input, true),
    ]
}

/// Axis `ax`'s hard limit switches (lower, upper) as `io` has them.
fn limit_switches(ax: &ManualAxis, io: &kerf_drive::machine::IoImage) -> (bool, bool) {
    let on = |n: Option<u32>| n.is_some_and(|n| io.digital_input(n as u8));
    (
        on(ax.setup.limit_switches.min_input),
        on(ax.setup.limit_switches.max_input),
    )
}
