//! The planning step of the offline runs ([`PlanStep`]): inputs in, planned items out, each
//! segment with the number of programmed moves known when it was planned.

use kerf_geom::Move;
use kerf_plan::{MachineLimits, PlanError, PlannedSegment, Planner};

use crate::{Input, Planned, plan_input};

/// The planning step of the offline runs: each input is planned, and every planned
/// segment carries the number of moves taken so far (the moves the deviation check then
/// knows), a dwell follows the segments before it.
pub(crate) struct PlanStep {
    planner: Planner,
    buf: Vec<PlannedSegment>,
    known: usize,
}

impl PlanStep {
    pub(crate) fn new(limits: &MachineLimits, design_override: f64) -> Self {
        let mut planner = Planner::new(*limits);
        planner.set_design_override(design_override);
        PlanStep {
            planner,
            buf: Vec::new(),
            known: 0,
        }
    }

    /// Plans `input`: a move also goes to `taken`, the planned items to `out`.
    pub(crate) fn input(
        &mut self,
        input: &Input,
        taken: &mut impl Extend<Move>,
        out: &mut impl Extend<Planned>,
    ) -> Result<(), PlanError> {
        plan_input(&mut self.planner, input, &mut self.buf)?;
        if let Input::Move(mv) = input {
            taken.extend([*mv]);
            self.known += 1;
        }
        let known = self.known;
        out.extend(self.buf.drain(..).map(|s| Planned::Segment(s, known)));
        if let Input::Dwell(seconds) = input {
            out.extend([Planned::Dwell(*seconds)]);
        }
        Ok(())
    }

    /// The end of the program: the rest of the path, ending at rest.
    pub(crate) fn finish(&mut self, out: &mut impl Extend<Planned>) {
        self.planner.finish(&mut self.buf);
        let known = self.known;
        out.extend(self.buf.drain(..).map(|s| Planned::Segment(s, known)));
    }
}
