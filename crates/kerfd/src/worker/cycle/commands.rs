//! The operator's commands applied in the cycle, and the tests' fault injections.

use super::*;
use crate::worker::fieldbus::MachineDrive;
use kerf_drive::machine::EndCause;

impl Cycle {
    pub(super) fn apply(&mut self, c: CycleCommand) {
        self.commands_applied += 1;
        match c {
            // A hold that arrives after its program ended holds nothing: it must not
            // stop the next program before its first move.
            CycleCommand::Hold if self.program.is_none() => {}
            CycleCommand::Hold if self.resume_after_return => {
                // The way back to a paused program's position stops; cycle start starts
                // it again.
                self.manual.abort();
                self.resume_after_return = false;
            }
            CycleCommand::Hold => self.interp.apply(OperatorEvent::Hold),
            CycleCommand::Resume => {
                if let Some(at) = self.paused_at {
                    // Jogged during the pause: back to where the program paused first.
                    if !self.resume_after_return && self.manual.active() {
                        // Still jogging: the jog stops, then the way back starts.
                        self.manual.abort();
                    }
                    if !self.resume_after_return {
                        self.manual.start_return(at);
                        self.resume_after_return = true;
                    }
                    return;
                }
                // Cycle start: a hold resumes, and a pause that waits for the operator
                // ends (both, when the operator held during a pause).
                self.interp.apply(OperatorEvent::Resume);
                self.machine.resume();
            }
            CycleCommand::Override(pct) => {
                self.override_pct = pct;
                if !self.feed_override_enabled {
                    // Disabled by the program (M49, M50 P0): kept for when it is enabled.
                } else if pct == 0.0 {
                    // A control at 0 % stands still on the path (the core holds).
                    self.interp.apply(OperatorEvent::Override(0.0));
                } else {
                    self.interp.apply(OperatorEvent::Override(pct / 100.0));
                }
            }
            CycleCommand::Abort => {
                self.manual.abort();
                self.forget_pause_position();
                if let Some(p) = self.program.as_mut() {
                    p.aborted = true;
                    self.machine.end_program(EndCause::Abort);
                }
                self.interp.apply(OperatorEvent::Abort)
            }
            CycleCommand::AbortProgram(id) => match self.program.as_mut() {
                Some(p) if p.id == id => {
                    p.aborted = true;
                    self.manual.abort();
                    self.forget_pause_position();
                    self.machine.end_program(EndCause::Abort);
                    self.interp.apply(OperatorEvent::Abort)
                }
                // Already over, or not begun yet: it begins aborted.
                _ if self.last_program.0 != id && !self.pending_abort.contains(&id) => {
                    // The oldest request makes room (programs begin in order).
                    self.pending_abort.rotate_left(1);
                    self.pending_abort[PENDING_ABORTS - 1] = id;
                }
                _ => {}
            },
            CycleCommand::Shutdown => {
                if let Some(p) = self.program.as_mut() {
                    p.aborted = true;
                }
                self.machine.end_program(EndCause::Abort);
                self.shutting_down = true;
                self.interp.apply(OperatorEvent::Abort);
            }
            CycleCommand::Reset(tag) if self.bus_needs_recovery() => {
                // The bus first: back to OP, then the drives' reset (see `drive_cycle`).
                if let Some(bus) = self.bus.as_mut() {
                    bus.start_recovery();
                }
                self.bus_reset_tag = Some(tag);
            }
            CycleCommand::Reset(tag) => {
                self.reset_tag = Some(tag);
                self.stage.request_reset();
            }
            CycleCommand::Dump(tag) => self.stage.request_dump(tag),
            CycleCommand::Inject(i) => self.inject(i),
            CycleCommand::Switch(switch, on) => match switch {
                kerf_proto::Switch::OptionalStop => self.machine.set_optional_stop(on),
                kerf_proto::Switch::BlockDelete => self.machine.set_block_delete(on),
                kerf_proto::Switch::SingleBlock => self.machine.set_single_block(on),
            },
            CycleCommand::SpindleOverride(pct) => self.machine.set_spindle_override_pct(pct),
            CycleCommand::Jog { axis, jog, speed } => {
                // One source of motion at a time: idle, or a program paused for the
                // operator; the control thread said why already.
                let paused = self.paused_for_operator();
                if (self.program.is_some() && !paused)
                    || self.resume_after_return
                    || !self.stage.ready()
                {
                    return;
                }
                if !self.manual.active() {
                    self.manual.rest_at(&self.setpoint.position);
                }
                if paused {
                    self.paused_at.get_or_insert(self.setpoint.position);
                }
                let at = self.setpoint.position.get(axis).copied().unwrap_or(0.0);
                let _ = self.manual.jog(axis, jog, speed, at, self.cycles);
            }
            CycleCommand::JogStop(axis) => self.manual.jog_stop(axis),
            CycleCommand::Home(mask) => {
                if self.program.is_some() || !self.stage.ready() {
                    return;
                }
                if !self.manual.active() {
                    self.manual.rest_at(&self.setpoint.position);
                }
                let _ = self.manual.home(mask);
            }
            CycleCommand::SetInput {
                analog,
                index,
                value,
            } => {
                // The control thread checked that the input exists and is simulated.
                let _ = if analog {
                    self.machine.set_input_analog(index, value)
                } else {
                    self.machine.set_input_digital(index, value != 0.0)
                };
            }
        }
    }

    /// An abort during a pause the operator jogged in: the program ends where the axes
    /// are (its motion core rests there).
    fn forget_pause_position(&mut self) {
        if self.paused_at.take().is_some() {
            self.resume_after_return = false;
            self.interp.core_mut().reset_to(self.setpoint.position);
        }
    }

    pub(super) fn inject(&mut self, injection: Injection) {
        match injection {
            Injection::DriveFault(axis) => {
                // On a fieldbus drive the fault is the drive's (or the emulator's) to raise.
                if let Some(MachineDrive::Sim(d)) = self.stage.drive_mut(axis) {
                    d.set_fault_cause(Some(INJECTED_DRIVE_FAULT));
                }
            }
            Injection::ClearDriveFault(axis) => {
                if let Some(MachineDrive::Sim(d)) = self.stage.drive_mut(axis) {
                    d.set_fault_cause(None);
                }
            }
            Injection::Step(axis, mm) => {
                if axis < 6 {
                    self.step = Some((axis, mm));
                }
            }
            Injection::Stall(n) => self.stall_left = n,
            Injection::SpindleStall(on) => self.machine.inject_spindle_stall(on),
        }
    }
}
