//! The items of a program as the pipeline takes them ([`Input`]), the planning step that
//! both planning threads run on them ([`plan_input`]), and how long a dwell rests.

use kerf_geom::Move;
use kerf_geom::machine::{Action, Sync};
use kerf_plan::{PlanError, PlannedSegment, Planner};

/// One item of a program as the driver runs it: a move, or a point where the motion must
/// come to an exact stop (a program stop, tool change, spindle or coolant change: the
/// control waits for the motion there), or a dwell (an exact stop, then the machine rests
/// for the time).
// Moves are nearly every item: boxing the large variant would allocate once per move.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Input {
    /// A programmed move.
    Move(Move),
    /// An exact stop at this point of the program (the path is not blended across it).
    Stop,
    /// An exact stop, then rest for this many seconds (rounded up to whole periods).
    Dwell(f64),
    /// Something the machine does at this point (a pause, the spindle, an output): an
    /// action with [`Sync::AtRest`] is also an exact stop.
    Action(Action),
}

impl From<Move> for Input {
    fn from(m: Move) -> Self {
        Input::Move(m)
    }
}

/// Gives one input to the planner: a move is planned; at a stop or a dwell the planner
/// ends the path at rest (it is not blended across) and starts afresh after it.
pub fn plan_input(
    planner: &mut Planner,
    input: &Input,
    out: &mut Vec<PlannedSegment>,
) -> Result<(), PlanError> {
    match input {
        Input::Move(mv) => planner.push(mv, out),
        Input::Action(a) if a.sync() != Sync::AtRest => Ok(()),
        Input::Stop | Input::Dwell(_) | Input::Action(_) => {
            planner.finish(out);
            Ok(())
        }
    }
}

/// Periods a dwell of `seconds` takes: whole periods, rounded up (a dwell is never cut
/// short), ignoring the last bits of rounding in the division.
pub fn dwell_periods(seconds: f64, period_s: f64) -> u64 {
    let positive = |x: f64| x.is_finite() && x > 0.0;
    if !positive(seconds) || !positive(period_s) {
        return 0;
    }
    let n = seconds / period_s;
    (n - n * 1e-12).ceil().max(0.0) as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dwells_take_whole_periods_rounded_up() {
        assert_eq!(dwell_periods(0.5, 0.001), 500);
        assert_eq!(dwell_periods(0.0005, 0.001), 1);
        assert_eq!(dwell_periods(0.001, 62.5e-6), 16);
        assert_eq!(dwell_periods(0.3, 0.1), 3);
        assert_eq!(dwell_periods(0.0, 0.001), 0);
        assert_eq!(dwell_periods(f64::NAN, 0.001), 0);
    }
}
