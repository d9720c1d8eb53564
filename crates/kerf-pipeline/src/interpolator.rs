//! The per-cycle step shared by `kerf sim` and the daemon ([`Interpolator`]), and the
//! planned items it is fed ([`Planned`], asked for with [`Poll`]).

use kerf_geom::machine::{Action, Gate, MachineIo, Sync};
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
    /// Nothing yet, and the planner is still working through what it has been given (the
    /// daemon's planner behind the moves it has received): unlike [`Poll::Pending`], the
    /// motion may then start before the queue is full, once that changes nothing (see
    /// [`Interpolator::feed`]).
    Planning,
    /// The program has been received to its end.
    End,
    /// More of the program is there but cannot be taken now: the daemon's tracker holds
    /// all the programmed moves it can until the motion passes some (the daemon's source
    /// only). The motion starts as it would with a full queue.
    Full,
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
    /// An action for the machine (see [`Sync`] for when it takes effect).
    Action(Action),
}

/// Actions synchronised with the motion ([`Sync::WithMotion`]) the interpolator holds
/// until the segments before them are done; one more waits in hand.
pub const SYNCED_ACTIONS: usize = 16;

/// Motion at the programmed feed a source whose planner is behind ([`Poll::Planning`])
/// must have handed over before the motion starts without a full queue, s (see
/// [`Interpolator::feed`]): a buffer against the planner's hiccups.
pub const START_LEAD_S: f64 = 1.0;

/// A segment's motion time at its programmed feed (capped by its speed limit), s; 0 for
/// a segment without a speed.
pub fn segment_time_s(seg: &PlannedSegment) -> f64 {
    let v = seg.v_max_mm_s.min(seg.feed_mm_s);
    if v > 0.0 && v.is_finite() {
        seg.length_mm / v
    } else {
        0.0
    }
}

/// The per-cycle step of a program run, shared by `kerf sim` and the daemon's real-time
/// thread (allocation-free): [`feed`](Self::feed) the motion core from a source, apply
/// commands ([`apply`](Self::apply)), then [`step`](Self::step) one period.
///
/// Feeding pushes items while the queue has room. The first item that does not fit stays
/// in hand for the next cycle; a dwell stays in hand until the motion before it has come
/// to rest and the dwell's periods have passed. An action goes to the machine
/// ([`MachineIo`]): at once ([`Sync::Immediate`]), when the motion has finished the
/// segments pushed before it ([`Sync::WithMotion`]: checked at the start of every
/// feeding, so that it takes effect in the cycle of the first setpoint after them), or
/// once the motion has come to rest and everything before it has taken effect
/// ([`Sync::AtRest`]: it stays in hand, asked again every cycle, until the machine says it
/// is done). After an abort every item up to the program's end is dropped, and the
/// synchronised actions not yet due with it (their move never starts).
///
/// The motion of a program starts when the queue is full, or a dwell or the program's
/// end has been received, or the source's planner is behind ([`Poll::Planning`]) once it
/// has handed over [`START_LEAD_S`] of motion at the programmed feed and the core's
/// lookahead has settled ([`MotionCore::lookahead_settled`]): a section ahead has speeds
/// that no later segment can change, so the motion before it is the one a full queue
/// gives. The simulator's source never pends, so it starts with a full queue; the
/// daemon's setpoints equal it as long as its planner keeps a settled section ahead of
/// the motion. While a hold is pending, stopping or held, no segment is pushed (a
/// segment pushed then joins no section, so the sections would depend on when the
/// planner had it). A source that has nothing because its client has not sent more
/// ([`Poll::Pending`]) never starts the motion early: a program that trickles in moves
/// only once its end has come or the queue is full.
pub struct Interpolator {
    core: MotionCore,
    period_s: f64,
    hand: Option<Planned>,
    /// While resting at the dwell in hand: periods left.
    dwell_left: Option<u64>,
    started: bool,
    /// Motion time at the programmed feed of the segments pushed before the start, s.
    lead_s: f64,
    ended: bool,
    aborted: bool,
    last: Option<StepResult>,
    /// Segments pushed into the core since the start.
    pushed: u64,
    /// Synchronised actions waiting for the segments pushed before them (the second
    /// element: `pushed` when the action was taken), oldest first, in a ring.
    synced: [(Action, u64); SYNCED_ACTIONS],
    synced_head: usize,
    synced_len: usize,
    /// The action in hand has been handed to the machine and is not done yet.
    acting: bool,
}

/// A placeholder for the free slots of the synchronised-action ring.
const NO_ACTION: Action = Action {
    line: 0,
    kind: kerf_geom::machine::ActionKind::ProgramEnd,
};

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
            lead_s: 0.0,
            ended: false,
            aborted: false,
            last: None,
            pushed: 0,
            synced: [(NO_ACTION, 0); SYNCED_ACTIONS],
            synced_head: 0,
            synced_len: 0,
            acting: false,
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

    /// The action the machine is carrying out while the program waits for it (a pause,
    /// a tool change, a wait for the spindle or an input), if any.
    pub fn waiting_for(&self) -> Option<&Action> {
        match &self.hand {
            Some(Planned::Action(a)) if self.acting => Some(a),
            _ => None,
        }
    }

    /// `true` when the program is done: received to its end, everything run, and the
    /// last step found the motion at rest.
    pub fn finished(&self) -> bool {
        self.ended
            && self.hand.is_none()
            && self.synced_len == 0
            && self.last == Some(StepResult::Idle)
    }

    /// What the last step returned (`None` before the first).
    pub fn last_step(&self) -> Option<StepResult> {
        self.last
    }

    /// Gets ready for the next program (the core keeps its position and override, and
    /// forgets the last program's line).
    pub fn next_program(&mut self) {
        self.core.forget_line();
        self.hand = None;
        self.dwell_left = None;
        self.started = false;
        self.lead_s = 0.0;
        self.ended = false;
        self.aborted = false;
        self.last = None;
        self.synced_len = 0;
        self.acting = false;
    }

    /// Pushes items from `source` while the queue has room, handing actions to
    /// `machine`; returns whether the motion may step this cycle (the program's motion
    /// has started, or starts now). A segment the core refuses is a bug of the planner,
    /// reported with its line.
    pub fn feed(
        &mut self,
        mut source: impl FnMut() -> Poll,
        machine: &mut (impl MachineIo + ?Sized),
    ) -> Result<bool, RunError> {
        if self.aborted {
            self.synced_len = 0;
        }
        self.fire_synced(machine);
        let mut source_full = false;
        let mut planning = false;
        loop {
            if self.hand.is_none() && !self.ended {
                match source() {
                    Poll::Ready(item) => self.hand = Some(item),
                    Poll::Pending => break,
                    Poll::Planning => {
                        planning = true;
                        break;
                    }
                    Poll::Full => {
                        source_full = true;
                        break;
                    }
                    Poll::End => {
                        self.ended = true;
                        break;
                    }
                }
            }
            match &self.hand {
                None => break,
                Some(h) if self.aborted => {
                    if let (Planned::Action(a), true) = (h, self.acting) {
                        machine.cancel(a);
                    }
                    self.acting = false;
                    self.hand = None;
                }
                // Not while a hold is pending, stopping or held: a segment pushed then
                // joins no section, so the sections would depend on when the source had
                // it (the daemon's planner may still be filling the queue); it waits in
                // hand for the resume, as the segments of a full queue wait for room.
                Some(Planned::Segment(..)) if self.started && !self.core.follows_plan() => break,
                Some(Planned::Segment(seg, _)) => match self.core.push(seg) {
                    Ok(()) => {
                        self.pushed += 1;
                        if !self.started {
                            self.lead_s += segment_time_s(seg);
                        }
                        self.hand = None;
                    }
                    Err(PushError::Full) => break,
                    Err(_) => return Err(RunError::Rejected { line: seg.line }),
                },
                Some(Planned::Action(a)) => {
                    let a = *a;
                    if !self.take_action(a, machine) {
                        break;
                    }
                    self.hand = None;
                }
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
            // The queue is full (or the source cannot hand over more now), or the motion
            // must stop at a dwell or the end anyway, or enough is queued that more
            // cannot change the motion ahead.
            self.started = self.hand.is_some()
                || self.ended
                || source_full
                || (planning && self.lead_s >= START_LEAD_S && self.core.lookahead_settled());
        }
        Ok(self.started)
    }

    /// Hands `action` (in hand) to the machine; `true` once it has been taken (it may be
    /// waiting in the synchronised ring), `false` while it must stay in hand.
    fn take_action(&mut self, action: Action, machine: &mut (impl MachineIo + ?Sized)) -> bool {
        match action.sync() {
            Sync::Immediate => {
                machine.act(&action);
                true
            }
            Sync::WithMotion => {
                if self.synced_len == SYNCED_ACTIONS {
                    return false;
                }
                let tail = (self.synced_head + self.synced_len) % SYNCED_ACTIONS;
                self.synced[tail] = (action, self.pushed);
                self.synced_len += 1;
                true
            }
            Sync::AtRest => {
                self.fire_synced(machine);
                if !self.core.is_idle() || self.synced_len > 0 {
                    return false;
                }
                self.acting = true;
                match machine.act(&action) {
                    Gate::Done => {
                        self.acting = false;
                        true
                    }
                    Gate::Wait => false,
                }
            }
        }
    }

    /// Hands the machine the synchronised actions ([`Sync::WithMotion`]) whose segments
    /// are done. Call it after [`step`](Self::step), so that an output switches in the
    /// cycle of the first setpoint after those segments (feeding calls it too, so an
    /// action is never lost, only a cycle late).
    pub fn fire_synced(&mut self, machine: &mut (impl MachineIo + ?Sized)) {
        let done = self.pushed - self.core.queued() as u64;
        while self.synced_len > 0 {
            let (action, after) = self.synced[self.synced_head];
            if after > done {
                break;
            }
            machine.act(&action);
            self.synced_head = (self.synced_head + 1) % SYNCED_ACTIONS;
            self.synced_len -= 1;
        }
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
