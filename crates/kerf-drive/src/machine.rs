//! The machine model of the real-time cycle: what a program asks of the machine besides
//! motion ([`Action`]s, through [`MachineIo`]), carried out on the spindle, the coolant,
//! the tool changer and the I/O image, with pauses and waits the program's motion waits
//! for, and the machine's faults.
//!
//! A [`Machine`] is built once from a [`MachineConfig`]; nothing allocates after that.
//! Time is counted in cycles of the configured period (no clock): a run is deterministic.
//! The daemon's cycle, per period:
//!
//! 1. the fieldbus writes the inputs it read ([`Machine::set_bus_inputs`], and a spindle
//!    drive's speed, [`Machine::set_spindle_actual_rpm`]);
//! 2. [`Machine::cycle`] advances the models one period (the spindle's ramp and the
//!    simulated spindle drive, the simulated tool changer and at-speed signal) and
//!    supervises the spindle while the motion feeds;
//! 3. the interpolator's feed hands actions to [`MachineIo::act`]: the outputs they set
//!    are in the image at once;
//! 4. the fieldbus sends the outputs ([`Machine::io`]) and the spindle's velocity
//!    setpoint ([`Machine::spindle_velocity_setpoint_rpm`]).
//!
//! What each action does (an action the machine waits on returns [`Gate::Wait`] and is
//! shown in the status, [`MachineStatus::pause`], until it is done):
//!
//! - `Pause`: program stop, pallet change and single block pause until cycle start
//!   ([`Machine::resume`]); an optional stop only while the optional-stop switch is on
//!   when the machine gets to it (else it is done at once).
//! - `ToolChange`: a change to the tool already in the spindle is done at once, and so is
//!   any change without a tool changer (the planner refuses M6 then). Otherwise the
//!   spindle is stopped (as LinuxCNC's M6 leaves it) and the change waits until it is at
//!   rest (bounded by the spindle's at-speed timeout); then a manual change pauses until
//!   cycle start, and an automatic one runs the handshake: the tool number on its analog
//!   output, the change request on (once the change-done input is off), done when the
//!   change-done input is on, then the request off. The changer's timeout counts from
//!   the request and faults. The tool in the spindle changes when the change is done.
//!   With simulated inputs a simulated changer answers `sim_change_s` after the request
//!   and drops its answer when the request goes off.
//! - `Spindle`: the command in force; the override (0–200 %) applies while enabled; a
//!   commanded speed above 0 is clamped to `min_rpm`–`max_rpm`.
//! - `WaitAtSpeed`: waits until the spindle is at speed; done at once if the commanded
//!   speed is 0 (nothing to wait for) or the machine has no spindle. Not at speed within
//!   `at_speed_timeout_s`: the [`MachineFault::SpindleNotAtSpeed`] fault.
//! - `Orient` (M19): stops the spindle; the simulated orient is done
//!   [`ORIENT_SETTLE_S`] after the spindle is at rest. Its timeout is the Q word, or the
//!   configured `orient_timeout_s` without one; past it, [`MachineFault::OrientTimeout`].
//! - `Coolant`, `Digital`, `Analog`: set the outputs. An output the I/O does not have is
//!   ignored here: the planner side refuses such programs before motion. A program may
//!   switch an output that the spindle, coolant or changer uses; the next change of
//!   those writes it again.
//! - `WaitInput` (M66, LinuxCNC's semantics): L0 reads the input at once (the only mode
//!   for an analog input: an analog wait in another mode reads at once too); L1 waits
//!   for a rising edge (the input seen off, then on, from the first cycle of the wait on),
//!   L2 a falling edge, L3 until on, L4 until off. The result, kept in
//!   [`MachineStatus::last_input`] for `#5399`, is the input's value when the wait ends,
//!   or -1 when the Q timeout passes first (not a fault; Q 0 checks once). An input that
//!   does not exist reads as off (the planner refuses it before motion).
//! - `Overrides`: the spindle override's enable; the feed override's is kept for the
//!   cycle to apply to the motion core ([`MachineStatus::feed_override_enabled`]).
//! - `ProgramEnd`: the spindle and each coolant output off as their `off.at_end` says;
//!   both overrides enabled again (LinuxCNC's M2/M30 do M48).
//!
//! [`Machine::end_program`] does the same for an abort or a fault (per `off.at_abort`,
//! `off.at_fault`) and forgets any wait; [`MachineIo::cancel`] forgets the wait of one
//! action (an automatic change's request goes off; the tool in the spindle stays the one
//! before). A fault latches ([`Machine::fault`]) until [`Machine::reset`]: the spindle
//! and coolant go off as `off.at_fault` says, the wait is forgotten, and every action
//! waits (the cycle drops the program).
//!
//! The spindle ([`SpindleKind`]): a drive in velocity mode gets a setpoint that ramps at
//! `acceleration_rpm_s` toward the signed commanded speed (a reversal passes through 0);
//! the simulated drive's speed follows it, never faster than that acceleration, and
//! decays to 0 at that rate while stalled ([`Machine::inject_spindle_stall`], a broken
//! belt). At speed: `|actual − commanded| ≤ tolerance · commanded`, with the commanded
//! speed above 0. A spindle switched by outputs is at speed while its at-speed input is
//! on (believed from the [`AT_SPEED_INPUT_DELAY_CYCLES`]th cycle after a change), or
//! without one `spin_up_s` after the change. With `fault_out_of_band`, a spindle that
//! was at speed since the last change (of direction, speed or override) and is not,
//! in a cycle where the motion feeds, is the [`MachineFault::SpindleOutOfBand`] fault.

mod config;
mod io;
mod spindle;
mod status;
mod waits;

#[cfg(test)]
mod tests;

pub use config::{
    AutomaticChanger, CoolantConfig, CoolantOutput, DEFAULT_SIM_CHANGE_S, IoConfig, MachineConfig,
    MachineConfigError, OffPolicy, SpindleConfig, SpindleKind, SpindleOutputs, Switches,
    ToolChanger,
};
pub use io::{ANALOG_IO, DIGITAL_IO, InputError, IoImage};
pub use spindle::{AT_SPEED_INPUT_DELAY_CYCLES, MAX_SPINDLE_OVERRIDE_PCT, REST_RPM, SpindleStatus};
pub use status::{
    CoolantStatus, EndCause, InputResult, MachineFault, MachineStatus, PauseInfo, PauseReason,
};
pub use waits::ORIENT_SETTLE_S;

use kerf_geom::machine::{Action, ActionKind, Gate, MachineIo};

use spindle::Spindle;
use waits::Pending;

/// The machine's time: cycles since construction and the period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Clock {
    pub(crate) cycles: u64,
    pub(crate) period_s: f64,
}

impl Clock {
    /// Whole periods in `seconds`, rounded up (0 for none, `u64::MAX` for infinity).
    pub(crate) fn periods(self, seconds: f64) -> u64 {
        if seconds.is_nan() || seconds <= 0.0 {
            return 0;
        }
        // The slack keeps 10 s at 1 ms at 10000 periods despite the rounding of the
        // quotient.
        let n = (seconds / self.period_s - 1e-9).ceil();
        if n >= u64::MAX as f64 {
            u64::MAX
        } else {
            n as u64
        }
    }

    /// Cycles since `since`.
    pub(crate) fn elapsed(self, since: u64) -> u64 {
        self.cycles.saturating_sub(since)
    }

    /// Seconds since `since`.
    pub(crate) fn elapsed_s(self, since: u64) -> f64 {
        self.elapsed(since) as f64 * self.period_s
    }

    /// `true` once `seconds` have passed since `since`.
    pub(crate) fn reached(self, since: u64, seconds: f64) -> bool {
        self.elapsed(since) >= self.periods(seconds)
    }
}

/// The machine model (see the module documentation).
// A copy would be a second machine, silently diverging from the first.
#[allow(missing_copy_implementations)]
#[derive(Clone, Debug)]
pub struct Machine {
    config: MachineConfig,
    clock: Clock,
    io: IoImage,
    spindle: Option<Spindle>,
    coolant: CoolantStatus,
    switches: Switches,
    tool_in_spindle: u32,
    feed_override_enabled: bool,
    /// The action the program waits on.
    pending: Option<Pending>,
    last_input: Option<InputResult>,
    input_seq: u64,
    fault: Option<MachineFault>,
    /// The simulated changer: the cycle its request went out.
    changer_request_cycle: Option<u64>,
}

impl Machine {
    /// A machine at rest: spindle stopped, coolant and outputs off, the simulated inputs
    /// at their initial values, the switches and the tool as configured.
    pub fn new(config: MachineConfig) -> Result<Machine, MachineConfigError> {
        config.check()?;
        let mut io = IoImage::default();
        if config.io.simulated_inputs {
            io.digital_inputs = config.io.initial_digital_inputs & config.io.digital_inputs;
            for (n, v) in io.analog_inputs.iter_mut().enumerate() {
                if config.io.has_analog_input(n as u8) {
                    *v = config.io.initial_analog_inputs[n];
                }
            }
        }
        Ok(Machine {
            config,
            clock: Clock {
                cycles: 0,
                period_s: config.period_s,
            },
            io,
            spindle: config.spindle.map(Spindle::new),
            coolant: CoolantStatus::default(),
            switches: config.switches,
            tool_in_spindle: config.tool_in_spindle,
            feed_override_enabled: true,
            pending: None,
            last_input: None,
            input_seq: 0,
            fault: None,
            changer_request_cycle: None,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &MachineConfig {
        &self.config
    }

    /// Cycles run since construction.
    pub fn cycles(&self) -> u64 {
        self.clock.cycles
    }

    /// One period (see the module documentation for where in the cycle): the spindle's
    /// ramp and simulated drive, the simulations of the inputs, and the spindle's
    /// supervision; `feeding`: the motion is running a feed move (not a rapid, not at
    /// rest) this cycle.
    pub fn cycle(&mut self, feeding: bool) {
        self.clock.cycles += 1;
        let now = self.clock;
        let simulated = self.config.io.simulated_inputs;
        if let Some(s) = &mut self.spindle {
            s.step(now, &mut self.io, simulated);
        }
        self.simulate_changer();
        if let (true, None, Some(s)) = (feeding, self.fault, &self.spindle)
            && s.config().fault_out_of_band
            && s.at_speed_once()
            && !s.at_speed(now, &self.io)
        {
            let fault = MachineFault::SpindleOutOfBand {
                commanded_rpm: s.commanded_rpm(),
                actual_rpm: s.actual_rpm(),
                tolerance: s.config().at_speed_tolerance,
            };
            self.trip(fault);
        }
    }

    /// The simulated tool changer answers `sim_change_s` after the request went out, and
    /// drops its answer when the request goes off.
    fn simulate_changer(&mut self) {
        let ToolChanger::Automatic(a) = self.config.tool_changer else {
            return;
        };
        if !self.config.io.simulated_inputs {
            return;
        }
        if self.io.digital_output(a.change_output) {
            // The request was set by an action of the cycle before.
            let since = *self
                .changer_request_cycle
                .get_or_insert(self.clock.cycles.saturating_sub(1));
            if self.clock.reached(since, a.sim_change_s) {
                self.io.set_digital_input(a.changed_input, true);
            }
        } else {
            self.changer_request_cycle = None;
            self.io.set_digital_input(a.changed_input, false);
        }
    }

    /// The I/O image: the fieldbus sends its outputs.
    pub fn io(&self) -> &IoImage {
        &self.io
    }

    /// The fieldbus's inputs of this cycle (bits and values of inputs that do not exist
    /// are ignored, and so is a value that is not finite: the input keeps its last).
    pub fn set_bus_inputs(&mut self, digital: u64, analog: &[f64; ANALOG_IO]) {
        self.io.digital_inputs = digital & self.config.io.digital_inputs;
        for (n, &v) in analog.iter().enumerate() {
            if self.config.io.has_analog_input(n as u8) && v.is_finite() {
                self.io.analog_inputs[n] = v;
            }
        }
    }

    /// Sets digital input `n` from a simulation of the machine itself (a simulated home or
    /// limit switch that follows its axis's motor); ignored for an input that does not
    /// exist or comes from the fieldbus.
    pub fn drive_input(&mut self, n: u8, on: bool) {
        if self.config.io.has_digital_input(n) && self.config.io.simulated_inputs {
            self.io.set_digital_input(n, on);
        }
    }

    /// Sets simulated digital input `n` (an operator's or a test's command). Refused for
    /// an input that does not exist, with inputs from the fieldbus, and for an input the
    /// machine's own simulations drive (the changer's answer, a VFD's at-speed signal).
    pub fn set_input_digital(&mut self, n: u8, on: bool) -> Result<(), InputError> {
        if !self.config.io.has_digital_input(n) {
            return Err(InputError::NoDigitalInput(n));
        }
        if !self.config.io.simulated_inputs {
            return Err(InputError::NotSimulated);
        }
        if let ToolChanger::Automatic(a) = self.config.tool_changer
            && a.changed_input == n
        {
            return Err(InputError::Simulated {
                input: n,
                what: "tool changer's change-done answer",
            });
        }
        if let Some(SpindleKind::Outputs(o)) = self.config.spindle.map(|s| s.kind)
            && o.at_speed_input == Some(n)
        {
            return Err(InputError::Simulated {
                input: n,
                what: "spindle's at-speed signal",
            });
        }
        self.io.set_digital_input(n, on);
        Ok(())
    }

    /// Sets simulated analog input `n`. Refused for an input that does not exist, a value
    /// that is not finite, and with inputs from the fieldbus.
    pub fn set_input_analog(&mut self, n: u8, value: f64) -> Result<(), InputError> {
        if !self.config.io.has_analog_input(n) {
            return Err(InputError::NoAnalogInput(n));
        }
        if !value.is_finite() {
            return Err(InputError::NotFinite { input: n, value });
        }
        if !self.config.io.simulated_inputs {
            return Err(InputError::NotSimulated);
        }
        self.io.analog_inputs[usize::from(n)] = value;
        Ok(())
    }

    /// The spindle override, % (clamped to 0–200; ignored if not a number or without a
    /// spindle). It applies while the program has it enabled (M48, M51).
    pub fn set_spindle_override_pct(&mut self, pct: f64) {
        if let Some(s) = &mut self.spindle {
            s.set_override_pct(pct, self.clock, &mut self.io);
        }
    }

    /// The velocity setpoint of a spindle drive this cycle, signed rpm (0 without one).
    pub fn spindle_velocity_setpoint_rpm(&self) -> f64 {
        self.spindle.as_ref().map_or(0.0, Spindle::setpoint_rpm)
    }

    /// A fieldbus spindle drive's actual speed, signed rpm (ignored if not finite, and
    /// for the simulated drive, which has its own).
    pub fn set_spindle_actual_rpm(&mut self, rpm: f64) {
        if let Some(s) = &mut self.spindle
            && s.config().kind == (SpindleKind::Drive { simulated: false })
        {
            s.set_actual_rpm(rpm);
        }
    }

    /// Test hook, a broken belt: while `true` the simulated spindle drive's speed decays
    /// to 0 at its acceleration (and a simulated at-speed signal goes off).
    pub fn inject_spindle_stall(&mut self, stalled: bool) {
        if let Some(s) = &mut self.spindle {
            s.set_stalled(stalled);
        }
    }

    /// Cycle start: ends a pause that waits for it (a program stop, optional stop, pallet
    /// change, single block, manual tool change); `true` if there was one.
    pub fn resume(&mut self) -> bool {
        self.pending.as_mut().is_some_and(Pending::release)
    }

    /// The program ended without its M2/M30 (aborted, or dropped by a fault): the
    /// spindle and coolant go off per their policy, any wait is forgotten, and both
    /// overrides are enabled again.
    pub fn end_program(&mut self, cause: EndCause) {
        match cause {
            EndCause::Abort => self.switch_off(|p| p.at_abort),
            EndCause::Fault => self.switch_off(|p| p.at_fault),
        }
        self.forget();
        self.enable_overrides();
    }

    /// The latched fault, if any.
    pub fn fault(&self) -> Option<MachineFault> {
        self.fault
    }

    /// Clears the latched fault.
    pub fn reset(&mut self) {
        self.fault = None;
    }

    /// The optional-stop switch (M1 pauses while on).
    pub fn set_optional_stop(&mut self, on: bool) {
        self.switches.optional_stop = on;
    }

    /// The single-block switch (stored and shown; the planner side acts on it).
    pub fn set_single_block(&mut self, on: bool) {
        self.switches.single_block = on;
    }

    /// The block-delete switch (stored and shown; the interpreter acts on it).
    pub fn set_block_delete(&mut self, on: bool) {
        self.switches.block_delete = on;
    }

    /// The switches.
    pub fn switches(&self) -> Switches {
        self.switches
    }

    /// The tool in the spindle (0: none).
    pub fn tool_in_spindle(&self) -> u32 {
        self.tool_in_spindle
    }

    /// Sets the tool in the spindle without a change (the daemon's saved state at start,
    /// LinuxCNC's M61).
    pub fn set_tool_in_spindle(&mut self, tool: u32) {
        self.tool_in_spindle = tool;
    }

    /// The feed override applies (M48, M49, M50).
    pub fn feed_override_enabled(&self) -> bool {
        self.feed_override_enabled
    }

    /// What the program waits for, if anything.
    pub fn pause(&self) -> Option<PauseInfo> {
        self.pending.and_then(|p| p.info(self.clock))
    }

    /// The status.
    pub fn status(&self) -> MachineStatus {
        MachineStatus {
            pause: self.pause(),
            switches: self.switches,
            tool_in_spindle: self.tool_in_spindle,
            spindle: self.spindle.map(|s| s.status(self.clock, &self.io)),
            coolant: self.coolant,
            feed_override_enabled: self.feed_override_enabled,
            io: self.io,
            last_input: self.last_input,
            fault: self.fault,
        }
    }

    /// Latches `fault` (the first one stays): the spindle and coolant go off per their
    /// fault policy and the wait is forgotten.
    fn trip(&mut self, fault: MachineFault) {
        if self.fault.is_none() {
            self.fault = Some(fault);
            self.switch_off(|p| p.at_fault);
            self.forget();
        }
    }

    /// Switches the spindle and each coolant output off where `policy` says so.
    fn switch_off(&mut self, policy: impl Fn(&OffPolicy) -> bool) {
        if let Some(s) = &mut self.spindle
            && policy(&s.config().off)
        {
            s.stop(self.clock, &mut self.io);
        }
        let coolant = self.config.coolant;
        let mist = self.coolant.mist && !coolant.mist.is_none_or(|c| policy(&c.off));
        let flood = self.coolant.flood && !coolant.flood.is_none_or(|c| policy(&c.off));
        self.set_coolant(mist, flood);
    }

    fn set_coolant(&mut self, mist: bool, flood: bool) {
        self.coolant = CoolantStatus { mist, flood };
        if let Some(c) = self.config.coolant.mist {
            self.io.set_digital_output(c.output, mist);
        }
        if let Some(c) = self.config.coolant.flood {
            self.io.set_digital_output(c.output, flood);
        }
    }

    fn enable_overrides(&mut self) {
        self.feed_override_enabled = true;
        if let Some(s) = &mut self.spindle {
            s.set_override_enabled(true, self.clock, &mut self.io);
        }
    }

    /// Forgets the wait in progress (an automatic change's request goes off).
    fn forget(&mut self) {
        if let Some(p) = self.pending.take()
            && let (ActionKind::ToolChange { .. }, ToolChanger::Automatic(a)) =
                (p.action.kind, self.config.tool_changer)
        {
            self.io.set_digital_output(a.change_output, false);
        }
    }
}

impl MachineIo for Machine {
    fn act(&mut self, action: &Action) -> Gate {
        if self.fault.is_some() {
            return Gate::Wait;
        }
        let now = self.clock;
        match action.kind {
            ActionKind::Pause(code) => self.pause_for(action, code),
            ActionKind::ToolChange { tool } => self.tool_change(action, tool),
            ActionKind::Spindle { dir, rpm } => {
                if let Some(s) = &mut self.spindle {
                    s.command(dir, rpm, now, &mut self.io);
                }
                Gate::Done
            }
            ActionKind::WaitAtSpeed => self.wait_at_speed(action),
            ActionKind::Orient { timeout_s, .. } => self.orient(action, timeout_s),
            ActionKind::Coolant { mist, flood } => {
                self.set_coolant(mist, flood);
                Gate::Done
            }
            ActionKind::Digital { output, on, .. } => {
                if self.config.io.has_digital_output(output) {
                    self.io.set_digital_output(output, on);
                }
                Gate::Done
            }
            ActionKind::Analog { output, value, .. } => {
                if self.config.io.has_analog_output(output) && value.is_finite() {
                    self.io.analog_outputs[usize::from(output)] = value;
                }
                Gate::Done
            }
            ActionKind::WaitInput {
                input,
                analog,
                mode,
                timeout_s,
            } => self.wait_input(action, input, analog, mode, timeout_s),
            ActionKind::Overrides { feed, spindle } => {
                if let Some(on) = feed {
                    self.feed_override_enabled = on;
                }
                if let (Some(on), Some(s)) = (spindle, &mut self.spindle) {
                    s.set_override_enabled(on, now, &mut self.io);
                }
                Gate::Done
            }
            ActionKind::ProgramEnd => {
                self.switch_off(|p| p.at_end);
                self.forget();
                self.enable_overrides();
                Gate::Done
            }
        }
    }

    fn cancel(&mut self, action: &Action) {
        if self.pending.is_some_and(|p| p.action == *action) {
            self.forget();
        }
    }
}
