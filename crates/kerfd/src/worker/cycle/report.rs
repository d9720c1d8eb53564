//! What the cycle reports: its state and a snapshot of the machine for the control thread.

use super::*;

impl Cycle {
    pub(super) fn state(&self) -> MachineState {
        if self.stage.fault().is_some() {
            return MachineState::Fault;
        }
        let core = self.interp.core().status();
        match core.state {
            MotionState::Held => MachineState::Holding,
            MotionState::Stopping if self.interp.core().is_held() => MachineState::Holding,
            _ if self.interp.waiting_for().is_some() && self.machine.pause().is_some() => {
                MachineState::Paused
            }
            _ if self.program.is_some() && self.starved => MachineState::Starved,
            _ if self.program.is_some() => MachineState::Running,
            _ if self.manual.active() => MachineState::Manual,
            MotionState::Idle => MachineState::Idle,
            _ => MachineState::Running,
        }
    }

    pub(super) fn report(&mut self, state: MachineState) {
        let core = self.interp.core().status();
        let machine = self.machine.status();
        if let Some(r) = machine.last_input
            && r.seq != self.input_result.0
        {
            // A wait on an input ended in this cycle: it belongs to the running program.
            self.input_result = (r.seq, self.program.map_or(self.last_program.0, |p| p.id));
        }
        let (program_id, refusal, aborted, done) = match self.program {
            Some(p) => (p.id, p.refusal, p.aborted, false),
            None => (
                self.last_program.0,
                self.last_program.1,
                self.last_program.2,
                self.last_program.0 != 0,
            ),
        };
        let snapshot = Snapshot {
            cycles: self.cycles,
            state,
            line: self.setpoint.line,
            position: self.setpoint.position,
            feed_mm_s: self.setpoint.feed_mm_s,
            override_pct: self.override_pct,
            queued_segments: core.queued as u64,
            queued_s: self.queued.sum_s.max(0.0),
            program_id,
            program_done: done,
            aborted,
            refusal,
            program_cycle: self.program.map_or(0, |p| p.cycle),
            shut_down: self.shut_down,
            drives: self.drive_report(),
            bus: self.bus_report(),
            reset: self.last_reset,
            commands_applied: self.commands_applied,
            manual: self.manual.status(self.machine.io()),
            machine,
            input_result_program: self.input_result.1,
        };
        // A full ring means the control thread is behind: it gets the next one.
        let _ = self.status.push(snapshot);
    }
}

impl Cycle {
    pub(super) fn drive_report(&self) -> DriveReport {
        let fault = self.stage.fault().copied();
        let error_code = match fault {
            Some(Fault {
                axis: Some(axis), ..
            }) => self.stage.error_codes()[axis],
            _ => 0,
        };
        DriveReport {
            phase: self.stage.phase(),
            state: self.stage.safety().state(),
            fault,
            error_code,
        }
    }
}
