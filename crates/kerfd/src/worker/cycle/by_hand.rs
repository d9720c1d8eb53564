//! The cycle's side of moving the machine by hand: the hard limit switches checked every
//! cycle, one period of jogging or homing (`Manual`) with what it asks of the drive stage,
//! and the way back to a program paused for the operator.

use super::*;

impl Cycle {
    /// A hard limit switch that becomes active latches a fault (the axes stop on the quick
    /// stop); after a reset the axis may be jogged off it, away from it only.
    pub(super) fn check_hard_limits(&mut self) {
        if self.stage.fault().is_some() || !self.stage.ready() {
            return;
        }
        if let Some((axis, side)) = self.manual.hard_limit(self.machine.io()) {
            let line = self.setpoint.line;
            if let Some(f) = self.stage.trip_axis(
                Check::HardLimit,
                axis,
                f64::from(side),
                f64::from(side),
                line,
            ) {
                self.safety_stop(f);
            }
        }
    }

    /// One period of manual motion (no program runs): the jogs and homing move their
    /// axes; homing's coordinate shifts are applied to the drive side; a homing failure
    /// latches its fault. Returns the shift applied to each axis (0 for none).
    pub(super) fn manual_step(&mut self) -> PerAxis<f64> {
        let factor = self.feed_override_factor();
        let out = self
            .manual
            .cycle(self.machine.io(), &self.actual, factor, self.cycles);
        for i in 0..6 {
            if out.moved & (1 << i) != 0 {
                self.setpoint.position[i] = out.position[i];
            }
        }
        for i in 0..6 {
            if out.drive_start & (1 << i) != 0 && self.stage.start_drive_homing(i).is_err() {
                self.manual.drive_homing_failed(i);
            }
            if self.stage.drive_homing_active(i) {
                // The drive moves the axis itself: the setpoint is where it is.
                self.setpoint.position[i] = self.actual[i];
            }
        }
        let mut shifted = [0.0; 6];
        for (i, shift) in out.shift.iter().enumerate() {
            let Some(d) = *shift else { continue };
            if self.stage.shift_axis(i, d) {
                self.setpoint.position[i] += d;
                self.sent[i] += d;
                self.actual[i] += d;
                self.manual.shifted(i, d);
                shifted[i] = d;
            } else {
                self.manual.shift_refused(i);
            }
        }
        for (i, on) in self.manual.soft_limits().iter().enumerate() {
            if self.stage.safety().soft_limits(i) != *on {
                self.stage.set_soft_limits(i, *on);
            }
        }
        if let Some((check, axis, value, limit)) = out.fault
            && let Some(f) = self.stage.trip_axis(check, axis, value, limit, 0)
        {
            self.safety_stop(f);
        }
        self.setpoint.feed_mm_s = 0.0;
        if self.program.is_none() {
            self.setpoint.line = 0;
            if !self.manual.active() {
                // Manual motion is over: the motion core rests where it left the axes.
                self.interp.core_mut().reset_to(self.setpoint.position);
            }
        }
        shifted
    }

    /// Whether the running program waits at rest for cycle start (a program stop, an
    /// optional stop, a manual tool change, single block): the operator may jog then.
    pub(super) fn paused_for_operator(&self) -> bool {
        self.program.is_some()
            && self.interp.waiting_for().is_some()
            && self
                .machine
                .pause()
                .is_some_and(|p| p.reason.needs_cycle_start())
    }

    /// Cycle start after jogging in a pause: once the way back has brought every axis to
    /// where the program paused, the program resumes.
    pub(super) fn finish_return(&mut self) {
        if !self.resume_after_return || self.manual.active() {
            return;
        }
        if self.paused_at == Some(self.setpoint.position) {
            self.resume_after_return = false;
            self.paused_at = None;
            self.interp.apply(OperatorEvent::Resume);
            self.machine.resume();
        }
    }
}
