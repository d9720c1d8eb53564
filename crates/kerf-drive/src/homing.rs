//! Homing of one axis as a pure state machine: [`Homing`] says each cycle what the axis's
//! mover should do ([`HomeCommand`]) from the home switch, the actual position and whether
//! the mover is at rest ([`HomeInput`]). It holds no mover and does no I/O: the daemon's
//! cycle owns the axis's jerk-limited mover and the machine coordinates, so the motion of
//! homing keeps the same limits and goes through the same safety layer as any other.
//! Everything is `Copy` and allocation-free; the cycle holds one [`Homing`] per axis.
//!
//! Three kinds ([`HomeKind`]):
//! - **`None`**: no switch and no motion; the axis is homed where it stands, its machine
//!   coordinates unchanged.
//! - **`Absolute`**: an absolute encoder; no motion, the machine position is the encoder's
//!   plus `home_offset` ([`Homing::absolute_shift`]).
//! - **`Switch`**: Kerf homes the axis on a home switch in position mode, in LinuxCNC's
//!   sequence (the names in brackets are LinuxCNC's `[JOINT_n]` keys and homing states):
//!
//! 1. **Initial back-off** ([`HomePhase::InitialBackOff`]): if the switch is already
//!    active at the start, move off it, against the search direction at
//!    |`search_velocity`|, until it releases; stop.
//! 2. **Search** ([`HomePhase::Search`], `HOME_SEARCH_VEL`): move in the direction of
//!    `search_velocity`'s sign at its speed until the switch becomes active; stop.
//! 3. **Back-off** ([`HomePhase::BackOff`], LinuxCNC's final back-off): only when
//!    `latch_velocity` (`HOME_LATCH_VEL`) has the search's sign. Move against the search
//!    direction at |`search_velocity`| (as LinuxCNC backs off at the search speed) until
//!    the switch has been active and then releases (a narrow switch overrun by the
//!    search's stop is crossed back); stop.
//! 4. **Latch** ([`HomePhase::Latch`]): with the search's sign, approach again at
//!    `latch_velocity` and latch where the switch becomes active; with the opposite sign,
//!    move off the switch at `latch_velocity` and latch where it releases. Either way the
//!    latch is the switch edge the search meets first, found at the slow speed. Stop;
//!    at rest, [`HomeCommand::Shift`] by `home_offset − latch` (`HOME_OFFSET`: the machine
//!    coordinate of the latch point).
//! 5. **Final move** ([`HomePhase::Final`]): to `home_position` (`HOME`) at `final_speed`
//!    (`HOME_FINAL_VEL`); at rest there, [`HomePhase::Done`].
//!
//! **Bounded travel.** Every phase that looks for a switch edge (1–4) moves to the end of
//! a window of `search_distance` from where it starts ([`HomeCommand::MoveTo`], not a
//! run at a velocity), so the axis never travels further than that looking for an edge,
//! stopping included; at rest at the window's end without the edge, the sequence fails
//! with [`HomeError::SwitchNotFound`] naming the phase and the distance, and commands a
//! stop. An edge found stops the axis at once ([`HomeCommand::Stop`]).
//!
//! **The latch point.** The switch is sampled once per cycle together with the actual
//! position. The edge lies between the last position with the old switch state and the
//! first with the new one; the latch is their midpoint, off by at most half the latch
//! travel of one period (`|latch_velocity|·T/2`: at 1 mm/s and 1 ms, 0.5 µm).
//!
//! **The caller's cycle**, per period: build the [`HomeInput`] from the switch, the actual
//! position and the mover's rest after the last step; call [`Homing::cycle`]; apply the
//! command to the mover (on [`HomeCommand::Shift`], add the shift to every position held
//! for the axis, the mover's included: it is only emitted at rest); step the mover.

use thiserror::Error;

/// How an axis is homed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HomeKind {
    /// No switch, no motion: homed where it stands.
    None,
    /// On a home switch, by Kerf in position mode (see the module documentation).
    Switch,
    /// An absolute encoder: no motion, machine position = encoder + `home_offset`.
    Absolute,
}

/// The homing configuration of one axis. Lengths are mm (deg for a rotary axis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomeSetup {
    /// How the axis is homed.
    pub kind: HomeKind,
    /// Signed: the sign is the search direction (LinuxCNC `HOME_SEARCH_VEL`). Units/s.
    pub search_velocity: f64,
    /// Signed: the search's sign = back off the switch, then approach again slowly and
    /// latch where it trips; the opposite sign = move off the switch slowly and latch
    /// where it releases (LinuxCNC `HOME_LATCH_VEL`). Units/s.
    pub latch_velocity: f64,
    /// The most the axis may travel in any one phase looking for a switch edge, units
    /// (> 0).
    pub search_distance: f64,
    /// The machine coordinate of the latch point (LinuxCNC `HOME_OFFSET`); for an absolute
    /// encoder, machine = encoder + this.
    pub home_offset: f64,
    /// Where the axis goes after latching, machine coordinates (LinuxCNC `HOME`).
    pub home_position: f64,
    /// Speed of that final move, units/s (> 0; LinuxCNC `HOME_FINAL_VEL`).
    pub final_speed: f64,
}

impl HomeSetup {
    /// The setup's error, if any: every value finite; for switch homing the velocities
    /// non-zero and the search distance and final speed positive.
    pub fn check(&self) -> Result<(), HomeError> {
        let setup = |field, value, reason| {
            Err(HomeError::Setup {
                field,
                value,
                reason,
            })
        };
        for (field, value) in [
            ("search_velocity", self.search_velocity),
            ("latch_velocity", self.latch_velocity),
            ("search_distance", self.search_distance),
            ("home_offset", self.home_offset),
            ("home_position", self.home_position),
            ("final_speed", self.final_speed),
        ] {
            if !value.is_finite() {
                return setup(field, value, "not a finite number");
            }
        }
        if self.kind != HomeKind::Switch {
            return Ok(());
        }
        if self.search_velocity == 0.0 {
            return setup("search_velocity", 0.0, "switch homing needs a search speed");
        }
        if self.latch_velocity == 0.0 {
            return setup("latch_velocity", 0.0, "switch homing needs a latch speed");
        }
        if self.search_distance <= 0.0 {
            return setup(
                "search_distance",
                self.search_distance,
                "must be above zero",
            );
        }
        if self.final_speed <= 0.0 {
            return setup("final_speed", self.final_speed, "must be above zero");
        }
        Ok(())
    }
}

/// Where a homing sequence is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HomePhase {
    /// Not started (or reset).
    Idle,
    /// Moving off a switch that was active at the start.
    InitialBackOff,
    /// Looking for the switch at the search speed.
    Search,
    /// Moving off the switch before the slow approach.
    BackOff,
    /// Finding the switch edge at the latch speed.
    Latch,
    /// Moving to the home position.
    Final,
    /// Homed.
    Done,
    /// Stopped by an error or an abort ([`Homing::error`]).
    Failed,
}

impl HomePhase {
    /// The phase in words, for progress and errors: `"idle"`, `"initial back-off"`,
    /// `"search"`, `"back-off"`, `"latch"`, `"final move"`, `"done"`, `"failed"`.
    pub fn name(self) -> &'static str {
        match self {
            HomePhase::Idle => "idle",
            HomePhase::InitialBackOff => "initial back-off",
            HomePhase::Search => "search",
            HomePhase::BackOff => "back-off",
            HomePhase::Latch => "latch",
            HomePhase::Final => "final move",
            HomePhase::Done => "done",
            HomePhase::Failed => "failed",
        }
    }
}

/// What the axis's mover should do this cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HomeCommand {
    /// Nothing new this cycle: keep whatever the mover does.
    Hold,
    /// Run at this signed velocity, units/s. (The switch sequence moves to the end of its
    /// search window instead, which bounds its travel exactly.)
    Run(f64),
    /// A jerk-limited stop.
    Stop,
    /// Move to `position` (machine coordinates) at no more than `speed` (units/s) and stop
    /// there.
    MoveTo {
        /// Machine coordinate, units.
        position: f64,
        /// Units/s (> 0).
        speed: f64,
    },
    /// Shift the axis's machine coordinates by this (units): add it to every position held
    /// for the axis. Emitted only while the input says the axis is at rest.
    Shift(f64),
}

/// What the sequence sees of the axis each cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomeInput {
    /// The home switch is active.
    pub switch: bool,
    /// The actual position, in the current machine frame, units, sampled with the switch.
    pub position: f64,
    /// The mover is at rest (after the last cycle's command and step).
    pub at_rest: bool,
}

/// Why homing stopped, or why a setup was refused.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
#[non_exhaustive]
pub enum HomeError {
    /// No switch edge within the phase's window; the axis was stopped.
    #[error("home switch not found within {distance} mm in the {} phase", phase.name())]
    SwitchNotFound {
        /// The phase that looked for it.
        phase: HomePhase,
        /// The window it looked in (`search_distance`), units.
        distance: f64,
    },
    /// The operator aborted homing.
    #[error("homing aborted in the {} phase", phase.name())]
    Aborted {
        /// The phase it was in.
        phase: HomePhase,
    },
    /// A setup value that cannot be homed with.
    #[error("homing setup: {field} = {value}: {reason}")]
    Setup {
        /// The field of [`HomeSetup`].
        field: &'static str,
        /// Its value.
        value: f64,
        /// What is wrong with it.
        reason: &'static str,
    },
}

/// Where a phase is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    /// Waiting for the axis to be at rest before the phase's motion starts.
    Start,
    /// Moving through the window, watching for the edge.
    Seek,
    /// The edge was found; stopping.
    Stopping,
}

/// A homing sequence for one axis. See the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Homing {
    setup: HomeSetup,
    phase: HomePhase,
    step: Step,
    /// The switch and position of the previous cycle of the running phase.
    previous: (bool, f64),
    /// The switch has been seen active in the running phase.
    seen_active: bool,
    /// The latch point, in the machine frame before the shift.
    latch: Option<f64>,
    error: Option<HomeError>,
    /// A stop the next cycle commands (after an abort).
    stop_due: bool,
}

impl Homing {
    /// A sequence for `setup`, idle; refused if the setup is not usable
    /// ([`HomeSetup::check`]).
    pub fn new(setup: HomeSetup) -> Result<Homing, HomeError> {
        setup.check()?;
        Ok(Homing {
            setup,
            phase: HomePhase::Idle,
            step: Step::Start,
            previous: (false, 0.0),
            seen_active: false,
            latch: None,
            error: None,
            stop_due: false,
        })
    }

    /// The setup.
    pub fn setup(&self) -> &HomeSetup {
        &self.setup
    }

    /// Begins the sequence (switch homing: its first phase starts at the next cycle, once
    /// the axis is at rest), or completes it at once (no switch, absolute encoder).
    pub fn start(&mut self) {
        self.error = None;
        self.stop_due = false;
        self.latch = None;
        self.step = Step::Start;
        self.phase = match self.setup.kind {
            HomeKind::Switch => HomePhase::Search,
            HomeKind::None | HomeKind::Absolute => HomePhase::Done,
        };
    }

    /// The phase.
    pub fn phase(&self) -> HomePhase {
        self.phase
    }

    /// Why the sequence failed, if it did.
    pub fn error(&self) -> Option<HomeError> {
        self.error
    }

    /// The latch point found, in the machine frame before the shift (switch homing, from
    /// the latch on).
    pub fn latch_position(&self) -> Option<f64> {
        self.latch
    }

    /// For an absolute encoder, the shift to apply at start: `home_offset` (machine =
    /// encoder + it); `None` for the other kinds.
    pub fn absolute_shift(&self) -> Option<f64> {
        (self.setup.kind == HomeKind::Absolute).then_some(self.setup.home_offset)
    }

    /// Operator abort: the sequence fails ([`HomeError::Aborted`]) and the next cycle
    /// commands a stop (the caller should stop the mover at once as well). Nothing
    /// happens when it is not running.
    pub fn abort(&mut self) {
        if matches!(
            self.phase,
            HomePhase::Idle | HomePhase::Done | HomePhase::Failed
        ) {
            return;
        }
        self.error = Some(HomeError::Aborted { phase: self.phase });
        self.phase = HomePhase::Failed;
        self.stop_due = true;
    }

    /// One cycle of the sequence: what the mover should do. Allocation-free.
    pub fn cycle(&mut self, input: &HomeInput) -> HomeCommand {
        if self.stop_due {
            self.stop_due = false;
            return HomeCommand::Stop;
        }
        match self.phase {
            HomePhase::Idle | HomePhase::Done | HomePhase::Failed => HomeCommand::Hold,
            HomePhase::Final => {
                if self.step == Step::Start {
                    self.step = Step::Seek;
                    HomeCommand::MoveTo {
                        position: self.setup.home_position,
                        speed: self.setup.final_speed,
                    }
                } else if input.at_rest {
                    self.phase = HomePhase::Done;
                    HomeCommand::Hold
                } else {
                    HomeCommand::Hold
                }
            }
            HomePhase::InitialBackOff
            | HomePhase::Search
            | HomePhase::BackOff
            | HomePhase::Latch => self.seek(input),
        }
    }

    /// A phase that looks for a switch edge (see the module documentation).
    fn seek(&mut self, input: &HomeInput) -> HomeCommand {
        match self.step {
            Step::Start => {
                if !input.at_rest {
                    // Homing started on a moving axis: stop it first.
                    return HomeCommand::Stop;
                }
                if self.phase == HomePhase::Search && input.switch {
                    self.phase = HomePhase::InitialBackOff;
                }
                self.begin(input)
            }
            Step::Seek => {
                let switch = input.switch;
                let (was, last) = self.previous;
                self.previous = (switch, input.position);
                let toward_search = self.setup.latch_velocity * self.setup.search_velocity > 0.0;
                let edge = match self.phase {
                    HomePhase::Search => switch,
                    HomePhase::Latch if toward_search => switch && !was,
                    // Off the switch: released after having been active.
                    _ => {
                        let released = self.seen_active && !switch;
                        self.seen_active |= switch;
                        released
                    }
                };
                if edge {
                    if self.phase == HomePhase::Latch {
                        self.latch = Some(0.5 * (last + input.position));
                    }
                    self.step = Step::Stopping;
                    HomeCommand::Stop
                } else if input.at_rest {
                    // At the end of the window without the edge.
                    self.error = Some(HomeError::SwitchNotFound {
                        phase: self.phase,
                        distance: self.setup.search_distance,
                    });
                    self.phase = HomePhase::Failed;
                    HomeCommand::Stop
                } else {
                    HomeCommand::Hold
                }
            }
            Step::Stopping => {
                if !input.at_rest {
                    return HomeCommand::Hold;
                }
                let toward_search = self.setup.latch_velocity * self.setup.search_velocity > 0.0;
                match self.phase {
                    HomePhase::InitialBackOff => {
                        self.phase = HomePhase::Search;
                        self.begin(input)
                    }
                    HomePhase::Search => {
                        self.phase = if toward_search {
                            HomePhase::BackOff
                        } else {
                            HomePhase::Latch
                        };
                        self.begin(input)
                    }
                    HomePhase::BackOff => {
                        self.phase = HomePhase::Latch;
                        self.begin(input)
                    }
                    _ => {
                        // Latched and at rest: the latch point becomes `home_offset`.
                        self.phase = HomePhase::Final;
                        self.step = Step::Start;
                        let latch = self.latch.unwrap_or(input.position);
                        HomeCommand::Shift(self.setup.home_offset - latch)
                    }
                }
            }
        }
    }

    /// Starts the running phase's motion from rest: to the end of its window, at its
    /// speed.
    fn begin(&mut self, input: &HomeInput) -> HomeCommand {
        let s = &self.setup;
        let search = s.search_velocity.signum();
        let (direction, speed) = match self.phase {
            HomePhase::Search => (search, s.search_velocity.abs()),
            HomePhase::Latch => (s.latch_velocity.signum(), s.latch_velocity.abs()),
            // Both back-offs: against the search, at the search speed.
            _ => (-search, s.search_velocity.abs()),
        };
        self.step = Step::Seek;
        self.previous = (input.switch, input.position);
        self.seen_active = input.switch;
        HomeCommand::MoveTo {
            position: input.position + direction * s.search_distance,
            speed,
        }
    }
}
