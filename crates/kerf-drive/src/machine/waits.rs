//! The actions the program's motion waits on: pauses, tool changes, the spindle's speed
//! and orientation, and waits on an input; each one's progress is a [`Pending`].

use kerf_geom::machine::{Action, ActionKind, Gate, PauseCode, WaitMode};

use super::status::{InputResult, MachineFault, PauseInfo, PauseReason};
use super::{Clock, Machine, ToolChanger};

/// The simulated orient takes this long once the spindle is at rest, s.
pub const ORIENT_SETTLE_S: f64 = 0.2;

/// Where a waiting action stands.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Phase {
    /// Waiting for cycle start (`released`: it came).
    Paused { released: bool },
    /// A tool change waits for the spindle to come to rest.
    SpindleStop,
    /// The automatic changer's handshake (`requested`: the request is on).
    Changing { requested: bool },
    /// Waiting for the spindle's speed.
    AtSpeed,
    /// Orienting; since when the spindle is at rest.
    Orient { rest_since: Option<u64> },
    /// Waiting on an input (`armed`: an edge's first state was seen).
    Input { armed: bool },
}

/// The action the program waits on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Pending {
    pub(crate) action: Action,
    /// The cycle the machine took it.
    started: u64,
    /// The cycle its phase began.
    since: u64,
    phase: Phase,
}

impl Pending {
    /// Cycle start: `true` if it waited for one.
    pub(crate) fn release(&mut self) -> bool {
        match &mut self.phase {
            Phase::Paused { released } if !*released => {
                *released = true;
                true
            }
            _ => false,
        }
    }

    /// What the status shows of it (nothing once released).
    pub(crate) fn info(&self, now: Clock) -> Option<PauseInfo> {
        let reason = match (self.action.kind, self.phase) {
            (_, Phase::Paused { released: true }) => return None,
            (ActionKind::Pause(code), _) => match code {
                PauseCode::ProgramStop => PauseReason::ProgramStop,
                PauseCode::OptionalStop => PauseReason::OptionalStop,
                PauseCode::PalletChange => PauseReason::PalletChange,
                PauseCode::SingleBlock => PauseReason::SingleBlock,
            },
            (ActionKind::ToolChange { tool }, Phase::SpindleStop) => {
                PauseReason::SpindleStop { tool }
            }
            (ActionKind::ToolChange { tool }, Phase::Changing { .. }) => {
                PauseReason::ToolChanging { tool }
            }
            (ActionKind::ToolChange { tool }, _) => PauseReason::ToolChange { tool },
            (ActionKind::WaitAtSpeed, _) => PauseReason::AtSpeed,
            (ActionKind::Orient { .. }, _) => PauseReason::Orient,
            (
                ActionKind::WaitInput {
                    input,
                    analog,
                    mode,
                    ..
                },
                _,
            ) => PauseReason::WaitInput {
                input,
                analog,
                mode,
            },
            _ => return None,
        };
        Some(PauseInfo {
            reason,
            line: self.action.line,
            waited_s: now.elapsed_s(self.started),
        })
    }
}

impl Machine {
    fn is_pending(&self, action: &Action) -> bool {
        self.pending.is_some_and(|p| p.action == *action)
    }

    /// The pending state of `action`: the one in progress, or a new one in `phase`.
    fn begin(&mut self, action: &Action, phase: Phase) -> Pending {
        if let Some(p) = self.pending
            && p.action == *action
        {
            return p;
        }
        // Another action's wait (dropped without a cancel) is forgotten.
        self.forget();
        let p = Pending {
            action: *action,
            started: self.clock.cycles,
            since: self.clock.cycles,
            phase,
        };
        self.pending = Some(p);
        p
    }

    /// The action is done: its wait ends.
    fn done(&mut self) -> Gate {
        self.forget();
        Gate::Done
    }

    fn spindle_at_rest(&self) -> bool {
        self.spindle.as_ref().is_none_or(|s| s.at_rest(self.clock))
    }

    pub(super) fn pause_for(&mut self, action: &Action, code: PauseCode) -> Gate {
        if code == PauseCode::OptionalStop
            && !self.switches.optional_stop
            && !self.is_pending(action)
        {
            return Gate::Done;
        }
        match self.begin(action, Phase::Paused { released: false }).phase {
            Phase::Paused { released: true } => self.done(),
            _ => Gate::Wait,
        }
    }

    pub(super) fn tool_change(&mut self, action: &Action, tool: u32) -> Gate {
        let changer = self.config.tool_changer;
        if !self.is_pending(action) {
            if tool == self.tool_in_spindle || changer == ToolChanger::None {
                return Gate::Done;
            }
            if let Some(s) = &mut self.spindle {
                s.stop(self.clock, &mut self.io);
            }
        }
        let mut p = self.begin(action, Phase::SpindleStop);
        let now = self.clock;
        if p.phase == Phase::SpindleStop {
            if !self.spindle_at_rest() {
                if let Some(s) = &self.spindle
                    && now.reached(p.since, s.config().at_speed_timeout_s)
                {
                    let fault = MachineFault::SpindleNotStopped {
                        line: action.line,
                        actual_rpm: s.actual_rpm(),
                        waited_s: now.elapsed_s(p.since),
                    };
                    self.trip(fault);
                }
                return Gate::Wait;
            }
            p.since = now.cycles;
            p.phase = match changer {
                ToolChanger::Automatic(a) => {
                    self.io.analog_outputs[usize::from(a.number_output)] = f64::from(tool);
                    Phase::Changing { requested: false }
                }
                _ => Phase::Paused { released: false },
            };
            self.pending = Some(p);
        }
        match (p.phase, changer) {
            (Phase::Paused { released: true }, _) => {
                self.tool_in_spindle = tool;
                self.done()
            }
            (Phase::Changing { requested }, ToolChanger::Automatic(a)) => {
                let answered = self.io.digital_input(a.changed_input);
                if requested && answered {
                    self.io.set_digital_output(a.change_output, false);
                    self.tool_in_spindle = tool;
                    return self.done();
                }
                if !requested && !answered {
                    // The answer of the change before has gone: request this one.
                    self.io.set_digital_output(a.change_output, true);
                    p.phase = Phase::Changing { requested: true };
                    self.pending = Some(p);
                } else if now.reached(p.since, a.timeout_s) {
                    self.trip(MachineFault::ToolChangeTimeout {
                        line: action.line,
                        tool,
                        changed_input: a.changed_input,
                        waited_s: now.elapsed_s(p.since),
                    });
                }
                Gate::Wait
            }
            _ => Gate::Wait,
        }
    }

    pub(super) fn wait_at_speed(&mut self, action: &Action) -> Gate {
        let now = self.clock;
        let Some(s) = &self.spindle else {
            return Gate::Done;
        };
        if s.commanded_rpm() <= 0.0 || s.at_speed(now, &self.io) {
            return self.done();
        }
        let (commanded_rpm, actual_rpm) = (s.commanded_rpm(), s.actual_rpm());
        let timeout_s = s.config().at_speed_timeout_s;
        let p = self.begin(action, Phase::AtSpeed);
        if now.reached(p.since, timeout_s) {
            self.trip(MachineFault::SpindleNotAtSpeed {
                line: action.line,
                commanded_rpm,
                actual_rpm,
                waited_s: now.elapsed_s(p.since),
            });
        }
        Gate::Wait
    }

    pub(super) fn orient(&mut self, action: &Action, timeout_s: f64) -> Gate {
        let now = self.clock;
        let Some(config) = self.config.spindle else {
            return Gate::Done;
        };
        let timeout_s = if timeout_s.is_finite() && timeout_s > 0.0 {
            timeout_s
        } else {
            config.orient_timeout_s
        };
        if !self.is_pending(action)
            && let Some(s) = &mut self.spindle
        {
            s.stop(now, &mut self.io);
        }
        let mut p = self.begin(action, Phase::Orient { rest_since: None });
        let Phase::Orient { mut rest_since } = p.phase else {
            return Gate::Wait;
        };
        if rest_since.is_none() && self.spindle_at_rest() {
            rest_since = Some(now.cycles);
        }
        if let Some(t) = rest_since
            && now.reached(t, ORIENT_SETTLE_S)
        {
            if let Some(s) = &mut self.spindle {
                s.set_oriented();
            }
            return self.done();
        }
        if now.reached(p.since, timeout_s) {
            self.trip(MachineFault::OrientTimeout {
                line: action.line,
                timeout_s,
            });
        } else {
            p.phase = Phase::Orient { rest_since };
            self.pending = Some(p);
        }
        Gate::Wait
    }

    pub(super) fn wait_input(
        &mut self,
        action: &Action,
        input: u8,
        analog: bool,
        mode: WaitMode,
        timeout_s: f64,
    ) -> Gate {
        if analog {
            let value = self.io.analog_input(input);
            return self.input_result(action.line, value);
        }
        let on = self.io.digital_input(input);
        let value = if on { 1.0 } else { 0.0 };
        if mode == WaitMode::Immediate {
            return self.input_result(action.line, value);
        }
        let mut p = self.begin(action, Phase::Input { armed: false });
        let Phase::Input { mut armed } = p.phase else {
            return Gate::Wait;
        };
        let met = match mode {
            WaitMode::Rise | WaitMode::Fall => {
                // LinuxCNC: a rise waits for the input off, then on.
                let first = on != (mode == WaitMode::Rise);
                let met = armed && !first;
                armed |= first;
                met
            }
            WaitMode::High => on,
            WaitMode::Low | WaitMode::Immediate => !on,
        };
        if met {
            return self.input_result(action.line, value);
        }
        if self.clock.reached(p.since, timeout_s) {
            return self.input_result(action.line, -1.0);
        }
        p.phase = Phase::Input { armed };
        self.pending = Some(p);
        Gate::Wait
    }

    /// Keeps the result of a wait on an input; the wait is done.
    fn input_result(&mut self, line: u32, value: f64) -> Gate {
        self.input_seq += 1;
        self.last_input = Some(InputResult {
            line,
            value,
            seq: self.input_seq,
        });
        self.done()
    }
}
