//! The planning step of the offline runs ([`PlanStep`]): inputs in, planned items out, each
//! segment with the number of programmed moves known when it was planned.

use kerf_geom::Move;
use kerf_plan::{MachineLimits, PlanError, PlannedSegment, Planner};

use crate::{ActionOrder, Input, Planned, plan_input};

/// The planning step of the offline runs: each input is planned, and every planned
/// segment carries the number of moves taken so far (the moves the deviation check then
/// knows), a dwell follows the segments before it.
pub(crate) struct PlanStep {
    planner: Planner,
    buf: Vec<PlannedSegment>,
    known: usize,
    order: ActionOrder,
}

impl PlanStep {
    pub(crate) fn new(limits: &MachineLimits, design_override: f64) -> Self {
        let mut planner = Planner::new(*limits);
        planner.set_design_override(design_override);
        PlanStep {
            planner,
            buf: Vec::new(),
            known: 0,
            order: ActionOrder::new(),
        }
    }

    /// Plans `input`: a move also goes to `taken`, the planned items to `out`.
    pub(crate) fn input(
        &mut self,
        input: &Input,
        taken: &mut impl Extend<Move>,
        out: &mut impl Extend<Planned>,
    ) -> Result<(), PlanError> {
        if self.order.take_held(input) {
            return Ok(());
        }
        plan_input(&mut self.planner, input, &mut self.buf)?;
        if let Input::Move(mv) = input {
            taken.extend([*mv]);
            self.known += 1;
            self.order.moved();
        }
        self.drain(out);
        self.order.after(input, out);
        Ok(())
    }

    /// The end of the program: the rest of the path, ending at rest.
    pub(crate) fn finish(&mut self, out: &mut impl Extend<Planned>) {
        self.planner.finish(&mut self.buf);
        self.drain(out);
        out.extend(self.order.release());
    }

    /// The planned segments, each after the held actions due before it.
    fn drain(&mut self, out: &mut impl Extend<Planned>) {
        let known = self.known;
        for s in self.buf.drain(..) {
            out.extend(self.order.before(&s));
            out.extend([Planned::Segment(s, known)]);
        }
    }
}
