//! Where the setpoints of a run go ([`Sink`]), and the program time of each cycle.

use kerf_geom::machine::{Action, Gate, MachineIo};
use kerf_motion::Setpoint;

/// Consumes the setpoints of a run, one per cycle: the CSV writer of `kerf sim`, the
/// daemon's publisher, a test's collector. Any `FnMut(f64, &Setpoint)` is one.
pub trait Sink {
    /// The setpoint of the cycle at program time `t_s` (s; 0 for the row before the first
    /// cycle).
    fn setpoint(&mut self, t_s: f64, sp: &Setpoint);

    /// An action the offline run carried out at once at program time `t_s`, before the
    /// setpoint of that cycle (the offline runs stand for a machine that does everything
    /// at once: an operator who presses cycle start at once at a pause, a spindle always
    /// at speed, inputs that hold their values). Nothing by default.
    fn action(&mut self, _t_s: f64, _action: &Action) {}
}

impl<F: FnMut(f64, &Setpoint)> Sink for F {
    fn setpoint(&mut self, t_s: f64, sp: &Setpoint) {
        self(t_s, sp)
    }
}

/// The machine of the offline runs: every action is done at once and told to the sink.
pub(crate) struct SinkMachine<'s, S: Sink> {
    pub(crate) sink: &'s mut S,
    pub(crate) t_s: f64,
}

impl<S: Sink> MachineIo for SinkMachine<'_, S> {
    fn act(&mut self, action: &Action) -> Gate {
        self.sink.action(self.t_s, action);
        Gate::Done
    }
}

/// Program time of cycle `cycle` (0 is the row before the first cycle). When the period
/// is a whole number of microseconds the product is formed in integers, so that printed
/// times are exact decimals.
pub fn cycle_time_s(cycle: u64, period_s: f64) -> f64 {
    let us = (period_s * 1e6).round();
    if (us * 1e-6 - period_s).abs() <= 1e-15 {
        (cycle as f64 * us) / 1e6
    } else {
        cycle as f64 * period_s
    }
}
