//! The loop of an offline run ([`Runner`]): the [`Interpolator`] in virtual time, fed from
//! a [`Source`], measured, with the commands of [`RunOptions`] applied at their cycles.

use kerf_geom::Move;
use kerf_motion::monitor::LimitMonitor;
use kerf_motion::{MotionCore, Setpoint, StepResult};
use kerf_plan::{MachineLimits, PlanError};

use crate::measure::Measure;
use crate::sink::SinkMachine;
use crate::{
    Interpolator, OperatorEvent, Planned, Poll, RunError, Sink, Summary, Taking, cycle_time_s,
};

/// Options of a run.
#[derive(Clone, Debug, PartialEq)]
pub struct RunOptions {
    /// Queue capacity in segments.
    pub capacity: usize,
    /// Feed override at the start (1.0 = 100 %).
    pub feed_override: f64,
    /// Events, each applied just before the cycle with the given number (1-based, in
    /// order of cycle number).
    pub events: Vec<(u64, OperatorEvent)>,
    /// Stop after this many cycles even if not at rest (a guard for tests).
    pub max_cycles: u64,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            capacity: 4096,
            feed_override: 1.0,
            events: Vec::new(),
            max_cycles: u64::MAX,
        }
    }
}

/// Where an offline run takes its planned items from: planned items in order, and the
/// programmed moves in order (each [`Planned::Segment`] says how many moves the planner
/// had taken when it made it; the deviation check records them before the segment runs).
pub(crate) trait Source {
    /// The next item; never [`Poll::Pending`] or [`Poll::Planning`] (the offline runs wait
    /// for the planner).
    fn poll(&mut self) -> Poll;
    /// The next programmed move.
    fn next_move(&mut self) -> Option<Move>;
    /// The planning error that ended the items early, if any (once).
    fn take_error(&mut self) -> Option<PlanError> {
        None
    }
}

/// An offline run: the [`Interpolator`] in virtual time, measured, with the commands of
/// [`RunOptions::events`] applied at their cycles.
pub(crate) struct Runner<'a, F: Sink> {
    interp: Interpolator,
    measure: Measure<'a>,
    period_s: f64,
    sink: F,
    cycle: u64,
    events: &'a [(u64, OperatorEvent)],
    next_event: usize,
    max_cycles: u64,
    /// Programmed moves recorded so far.
    known: usize,
    /// A segment taken from the source whose moves the tracker could not hold yet.
    held: Option<Poll>,
}

impl<'a, F: Sink> Runner<'a, F> {
    pub(crate) fn new(limits: &MachineLimits, options: &'a RunOptions, sink: F) -> Self {
        let mut core = MotionCore::new(limits.period_s, options.capacity);
        core.set_feed_override(options.feed_override);
        let mut runner = Runner {
            interp: Interpolator::new(core),
            measure: Measure::new(limits.period_s, crate::tracked_moves(options.capacity)),
            held: None,
            period_s: limits.period_s,
            sink,
            cycle: 0,
            events: &options.events,
            next_event: 0,
            max_cycles: options.max_cycles,
            known: 0,
        };
        let mut start = Setpoint::default();
        runner.measure.record(&mut start);
        runner.sink.setpoint(0.0, &start);
        runner
    }

    /// Checks every setpoint from now on with `monitor`, starting with the row at t = 0.
    pub(crate) fn attach(&mut self, monitor: Option<&'a mut LimitMonitor>) -> Result<(), RunError> {
        self.measure.monitor = monitor;
        if let Some(m) = self.measure.monitor.as_mut() {
            m.check(&self.measure.summary.last.position)
                .map_err(RunError::Fault)?;
        }
        Ok(())
    }

    /// Runs the program from `source` to its end: cycles until the motion has come to
    /// rest after the last item with every event applied, or is held with no event left
    /// to resume it, or a setpoint broke a limit, or the cycle guard is reached.
    pub(crate) fn run<S: Source>(mut self, source: &mut S) -> Result<Summary, RunError> {
        loop {
            let events_left = self.next_event < self.events.len();
            if self.measure.fault.is_some() || self.cycle >= self.max_cycles {
                break;
            }
            if self.interp.finished() && !events_left {
                break;
            }
            if self.interp.last_step() == Some(StepResult::Held) && !events_left {
                break;
            }
            self.cycle(source)?;
        }
        self.finish()
    }

    fn cycle<S: Source>(&mut self, source: &mut S) -> Result<StepResult, RunError> {
        let measure = &mut self.measure;
        let known = &mut self.known;
        let held = &mut self.held;
        let aborted = self.interp.aborted();
        // As the daemon's cycle: with nothing queued a full tracker cannot empty.
        let mut queue_empty = self.interp.core().queued() == 0;
        let mut machine = SinkMachine {
            sink: &mut self.sink,
            t_s: cycle_time_s(self.cycle + 1, self.period_s),
        };
        let started = self.interp.feed(
            || {
                let polled = held.take().unwrap_or_else(|| source.poll());
                // The moves the segment's tracking looks at (its own and the next one),
                // of those the planner had taken, as the daemon's planning thread sends
                // them; a full tracker holds the segment back, as the daemon's cycle does.
                if let Poll::Ready(Planned::Segment(seg, moves_known)) = &polled {
                    let needed =
                        (seg.move_index + u64::from(seg.move_count) + 1).min(*moves_known as u64);
                    while (*known as u64) < needed {
                        let taking = measure.taking(queue_empty, aborted);
                        if taking == Taking::Wait {
                            *held = Some(polled);
                            return Poll::Full;
                        }
                        let Some(mv) = source.next_move() else {
                            break;
                        };
                        measure.take_move(&mv, taking);
                        *known += 1;
                    }
                    queue_empty = false;
                }
                polled
            },
            &mut machine,
        )?;
        if let Some(e) = source.take_error() {
            return Err(RunError::Plan(e));
        }
        debug_assert!(started, "an offline source never leaves the motion waiting");
        self.cycle += 1;
        while self.next_event < self.events.len() && self.events[self.next_event].0 <= self.cycle {
            self.interp.apply(self.events[self.next_event].1);
            self.next_event += 1;
        }
        let mut sp = Setpoint::default();
        let r = self.interp.step(&mut sp);
        self.interp.fire_synced(&mut SinkMachine {
            sink: &mut self.sink,
            t_s: cycle_time_s(self.cycle, self.period_s),
        });
        self.measure.record(&mut sp);
        self.sink
            .setpoint(cycle_time_s(self.cycle, self.period_s), &sp);
        self.measure.check(&sp);
        Ok(r)
    }

    /// The summary, or the fault that stopped the run.
    fn finish(self) -> Result<Summary, RunError> {
        if let Some(v) = self.measure.fault {
            return Err(RunError::Fault(v));
        }
        let mut summary = self.measure.summary;
        summary.cycles = self.cycle;
        summary.duration_s = self.cycle as f64 * self.period_s;
        summary.plan_failures = self.interp.core().plan_failures();
        Ok(summary)
    }
}
