//! The per-cycle step shared by `kerf sim` and the daemon ([`Interpolator`]), and the
//! planned items it is fed ([`Planned`], asked for with [`Poll`]).

use kerf_motion::{MotionCore, PushError, Setpoint, StepResult};
use kerf_plan::PlannedSegment;

use crate::{OperatorEvent, RunError, dwell_periods};

/// What a source of planned items has for the [`Interpolator`] when asked.
// Nearly every item is a segment (see [`Planned`]).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Poll {
    /// The next item of the program.
    Ready(Planned),
    /// Nothing yet: the planner has not produced the next item (the daemon's source only;
    /// the simulator's source waits for it).
    Pending,
    /// The program has been received to its end.
    End,
}

/// What the run is fed after planning: a segment with the number of moves the planner had
/// taken when it produced it (so that the deviation check sees the same moves as in
/// [`run`](crate::run)), or a dwell (the segments before it end at rest).
// Nearly every item is a segment: boxing them to shrink the rare dwell would cost an
// allocation per segment.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Planned {
    /// A planned segment and the moves known when it was planned.
    Segment(PlannedSegment, usize),
    /// Rest for this many seconds once the motion before has stopped.
    Dwell(f64),
}

/// The per-cycle step of a program run, shared by `kerf sim` and the daemon's real-time
/// thread (allocation-free): [`feed`](Self::feed) the motion core from a source, apply
/// commands ([`apply`](Self::apply)), then [`step`](Self::step) one period.
///
/// Feeding pushes items while the queue has room. The first item that does not fit stays
/// in hand for the next cycle; a dwell stays in hand until the motion before it has come
/// to rest and the dwell's periods have passed. After an abort every item up to the
/// program's end is dropped. The motion of a program starts only when the queue is full,
/// or a dwell or the program's end has been received: the core then has the same
/// lookahead in the simulator and in the daemon.
pub struct Interpolator {
    core: MotionCore,
    period_s: f64,
    hand: Option<Planned>,
    /// While resting at the dwell in hand: periods left.
    dwell_left: Option<u64>,
    started: bool,
    ended: bool,
    aborted: bool,
    last: Option<StepResult>,
}

impl Interpolator {
    /// An interpolator around `core` (its queue capacity is the lookahead window).
    pub fn new(core: MotionCore) -> Self {
        let period_s = core.period_s();
        Interpolator {
            core,
            period_s,
            hand: None,
            dwell_left: None,
            started: false,
            ended: false,
            aborted: false,
            last: None,
        }
    }

    /// The motion core.
    pub fn core(&self) -> &MotionCore {
        &self.core
    }

    /// The motion core, for commands the interpolator does not track (positions).
    pub fn core_mut(&mut self) -> &mut MotionCore {
        &mut self.core
    }

    /// Applies a command before the next [`step`](Self::step).
    pub fn apply(&mut self, event: OperatorEvent) {
        match event {
            OperatorEvent::Hold => self.core.hold(),
            OperatorEvent::Resume => self.core.resume(),
            OperatorEvent::Abort => {
                self.core.abort();
                self.aborted = true;
            }
            OperatorEvent::Override(f) => self.core.set_feed_override(f),
        }
    }

    /// `true` once the program was aborted (the rest of it is dropped).
    pub fn aborted(&self) -> bool {
        self.aborted
    }

    /// `true` once the motion of the program has started.
    pub fn started(&self) -> bool {
        self.started
    }

    /// `true` once the source reported the program's end.
    pub fn source_ended(&self) -> bool {
        self.ended
    }

    /// `true` while resting at a dwell.
    pub fn dwelling(&self) -> bool {
        self.dwell_left.is_some()
    }

    /// `true` when the program is done: received to its end, everything run, and the
    /// last step found the motion at rest.
    pub fn finished(&self) -> bool {
        self.ended && self.hand.is_none() && self.last == Some(StepResult::Idle)
    }

    /// What the last step returned (`None` before the first).
    pub fn last_step(&self) -> Option<StepResult> {
        self.last
    }

    /// Gets ready for the next program (the core keeps its position and override).
    pub fn next_program(&mut self) {
        self.hand = None;
        self.dwell_left = None;
        self.started = false;
        self.ended = false;
        self.aborted = false;
        self.last = None;
    }

    /// Pushes items from `source` while the queue has room; returns whether the motion
    /// may step this cycle (the program's motion has started, or starts now). A segment
    /// the core refuses is a bug of the planner, reported with its line.
    pub fn feed(&mut self, mut source: impl FnMut() -> Poll) -> Result<bool, RunError> {
        loop {
            if self.hand.is_none() && !self.ended {
                match source() {
                    Poll::Ready(item) => self.hand = Some(item),
                    Poll::Pending => break,
                    Poll::End => {
                        self.ended = true;
                        break;
                    }
                }
            }
            match &self.hand {
                None => break,
                Some(_) if self.aborted => self.hand = None,
                Some(Planned::Segment(seg, _)) => match self.core.push(seg) {
                    Ok(()) => self.hand = None,
                    Err(PushError::Full) => break,
                    Err(_) => return Err(RunError::Rejected { line: seg.line }),
                },
                Some(Planned::Dwell(_)) => match self.dwell_left {
                    Some(0) => {
                        self.dwell_left = None;
                        self.hand = None;
                    }
                    _ => break,
                },
            }
        }
        if !self.started {
            // The queue is full, or the motion must stop at a dwell or the end anyway.
            self.started = self.hand.is_some() || self.ended;
        }
        Ok(self.started)
    }

    /// Steps the motion one period and writes the setpoint to `out`.
    pub fn step(&mut self, out: &mut Setpoint) -> StepResult {
        let r = self.core.step(out);
        if let Some(Planned::Dwell(seconds)) = self.hand {
            match &mut self.dwell_left {
                Some(n) => *n = n.saturating_sub(1),
                None if r == StepResult::Idle => {
                    self.dwell_left = Some(dwell_periods(seconds, self.period_s));
                }
                None => {}
            }
        }
        self.last = Some(r);
        r
    }
}
