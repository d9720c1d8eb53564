//! Kerf's planning pipeline: moves → [`Planner`] → [`MotionCore`] → a setpoint sink.
//!
//! `kerf sim` and the daemon `kerfd` run the same code here, so that the daemon's
//! setpoints equal the simulator's cycle for cycle:
//!
//! - [`Interpolator`] is the per-cycle step both run: it takes planned items from a source
//!   ([`Poll`]) while the motion core's queue has room, rests at dwells, drops the rest of
//!   the program after an abort, and steps the core one period. It never allocates, so the
//!   daemon calls it on its real-time thread with a lock-free ring as the source; the
//!   simulator calls it in virtual time with a source that blocks until the planning
//!   thread has the next item (it is never [`Poll::Pending`]).
//! - Motion starts once the queue is full, or the program has been received to its end
//!   (or to a dwell, where the motion must stop anyway): with a planner that keeps up,
//!   the core then sees the same segments at every cycle in both.
//! - [`plan_input`] is the planning step both planning threads run: a move is planned; at
//!   a stop or dwell the path ends at rest.
//! - [`Sink`] consumes setpoints: the CSV writer of `kerf sim`, the daemon's publisher.
//!
//! The offline runs ([`run`], [`run_stream`], [`run_planned`]) also measure what the
//! invariants are about: per-axis peak velocity, acceleration and jerk by finite
//! differences of the setpoints, and the distance of every setpoint from the programmed
//! moves.
#![forbid(unsafe_code)]

use std::collections::VecDeque;

use kerf_geom::{Curve, Helix, Move, Path, Vec3, line_distance};
use kerf_motion::monitor::{LimitMonitor, LimitViolation};
use kerf_motion::{MotionCore, PushError, Setpoint, StepResult};
use kerf_plan::{MachineLimits, PlanError, PlannedSegment, Planner};

/// An input event applied before a given cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event {
    /// Feed hold.
    Hold,
    /// Resume after a hold.
    Resume,
    /// Abort: stop on the path and drop the queue.
    Abort,
    /// Feed override factor (1.0 = 100 %).
    Override(f64),
}

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
        Input::Stop | Input::Dwell(_) => {
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

/// Options of a run.
#[derive(Clone, Debug, PartialEq)]
pub struct RunOptions {
    /// Queue capacity in segments.
    pub capacity: usize,
    /// Feed override at the start (1.0 = 100 %).
    pub feed_override: f64,
    /// Events, each applied just before the cycle with the given number (1-based, in
    /// order of cycle number).
    pub events: Vec<(u64, Event)>,
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

/// Peak per-axis values by finite differences of the setpoints.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxisPeak {
    /// Peak |velocity|, units/s.
    pub velocity: f64,
    /// Peak |acceleration|, units/s².
    pub acceleration: f64,
    /// Peak |jerk|, units/s³.
    pub jerk: f64,
}

/// What a run measured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Summary {
    /// Cycles stepped (rows after the one at t = 0).
    pub cycles: u64,
    /// Duration, s (cycles × period).
    pub duration_s: f64,
    /// Peaks per axis X, Y, Z, A, B, C.
    pub peaks: [AxisPeak; 6],
    /// Largest distance of a setpoint from the programmed moves, mm.
    pub max_deviation_mm: f64,
    /// `true` if any move drove a rotary axis.
    pub rotary_used: bool,
    /// Final setpoint.
    pub last: Setpoint,
    /// Profile calculations that needed a fallback.
    pub plan_failures: u64,
    /// `true` if a non-finite value was ever produced.
    pub saw_nan: bool,
}

impl Summary {
    /// Peak as a fraction of the limit for axis `i` (velocity, acceleration, jerk).
    pub fn fractions(&self, limits: &MachineLimits, i: usize) -> Option<[f64; 3]> {
        let l = limits.axes[i]?;
        let p = self.peaks[i];
        Some([
            p.velocity / l.velocity_units_s,
            p.acceleration / l.acceleration_units_s2,
            p.jerk / l.jerk_units_s3,
        ])
    }
}

/// Why a run stopped early.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum RunError {
    /// A move could not be planned.
    Plan(PlanError),
    /// The planner produced a segment the core rejected (a bug).
    Rejected {
        /// Source line.
        line: u32,
    },
    /// A setpoint broke a limit ([`LimitMonitor`]); the run stopped at it (runs with a
    /// monitor only, see [`run_stream`]).
    Fault(LimitViolation),
}

impl std::fmt::Display for RunError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RunError::Plan(e) => e.fmt(f),
            RunError::Rejected { line } => write!(f, "line {line}: segment rejected"),
            RunError::Fault(v) => v.fmt(f),
        }
    }
}

impl std::error::Error for RunError {}

impl From<PlanError> for RunError {
    fn from(e: PlanError) -> Self {
        RunError::Plan(e)
    }
}

/// Consumes the setpoints of a run, one per cycle: the CSV writer of `kerf sim`, the
/// daemon's publisher, a test's collector. Any `FnMut(f64, &Setpoint)` is one.
pub trait Sink {
    /// The setpoint of the cycle at program time `t_s` (s; 0 for the row before the first
    /// cycle).
    fn setpoint(&mut self, t_s: f64, sp: &Setpoint);
}

impl<F: FnMut(f64, &Setpoint)> Sink for F {
    fn setpoint(&mut self, t_s: f64, sp: &Setpoint) {
        self(t_s, sp)
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
    pub fn apply(&mut self, event: Event) {
        match event {
            Event::Hold => self.core.hold(),
            Event::Resume => self.core.resume(),
            Event::Abort => {
                self.core.abort();
                self.aborted = true;
            }
            Event::Override(f) => self.core.set_feed_override(f),
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

/// What the offline runs measure from the setpoints (the daemon does not).
struct Measure<'a> {
    period_s: f64,
    hist: [[f64; 6]; 4],
    hist_len: usize,
    summary: Summary,
    /// The programmed moves, for the deviation check and the line being passed.
    tracker: Tracker,
    /// Checks every setpoint, when the run has one.
    monitor: Option<&'a mut LimitMonitor>,
    /// The first setpoint that broke a limit: the run stops there.
    fault: Option<LimitViolation>,
}

/// Moves kept before the first move of the segment being run, for the deviation check
/// (it looks one back; the rest is a margin).
const MOVES_KEPT_BEHIND: usize = 16;

impl Measure<'_> {
    fn record(&mut self, sp: &mut Setpoint) {
        if sp.position.iter().any(|v| !v.is_finite()) || !sp.feed_mm_s.is_finite() {
            self.summary.saw_nan = true;
        }
        self.hist.rotate_right(1);
        self.hist[0] = sp.position;
        self.hist_len = (self.hist_len + 1).min(4);
        let t = self.period_s;
        for i in 0..6 {
            let h = |k: usize| self.hist[k][i];
            let p = &mut self.summary.peaks[i];
            if self.hist_len >= 2 {
                p.velocity = p.velocity.max(((h(0) - h(1)) / t).abs());
            }
            if self.hist_len >= 3 {
                p.acceleration = p
                    .acceleration
                    .max(((h(0) - 2.0 * h(1) + h(2)) / (t * t)).abs());
            }
            if self.hist_len >= 4 {
                p.jerk = p
                    .jerk
                    .max(((h(0) - 3.0 * h(1) + 3.0 * h(2) - h(3)) / (t * t * t)).abs());
            }
        }
        if let Some(d) = self.tracker.track(sp) {
            self.summary.max_deviation_mm = self.summary.max_deviation_mm.max(d);
        }
        self.summary.last = *sp;
    }

    /// Records a programmed move for the deviation check.
    fn add_move(&mut self, mv: &Move, aborted: bool) {
        if let Some((s, e)) = mv.abc_deg
            && s != e
        {
            self.summary.rotary_used = true;
        }
        if aborted && !self.tracker.is_empty() {
            // Nothing more is run after an abort: the deviation check needs no more moves.
            return;
        }
        self.tracker.add(mv);
    }

    fn check(&mut self, sp: &Setpoint) {
        if let Some(m) = self.monitor.as_mut()
            && let Err(v) = m.check(&sp.position)
        {
            self.fault.get_or_insert(v);
        }
    }
}

/// The programmed moves around the setpoints, allocation-free once its capacity is
/// reserved: finds the move a setpoint is passing (on a smoothed piece, which stands for
/// many moves, the one of them nearest to the setpoint) and its distance from the
/// programmed path. `kerf sim` and the daemon both run it on every setpoint, so that the
/// `line` of their setpoints agrees on smoothed curves too.
#[derive(Default)]
pub struct Tracker {
    /// The programmed moves not yet passed (compact: no transition variant). Moves before
    /// the segment being run are dropped, so this holds about the moves of the queued
    /// segments, whatever the program's length.
    curves: VecDeque<Programmed>,
    /// Source line of every move in `curves`.
    lines: VecDeque<u32>,
    /// A box around each block of [`BLOCK_MOVES`] moves (program indices
    /// `b·BLOCK_MOVES ..`, from block `block_base` on) that holds all of their points: the
    /// search for the nearest move of a piece skips a block whose box is farther from the
    /// setpoint than the nearest move found so far.
    blocks: VecDeque<Bounds>,
    /// Program index of `curves[0]`.
    base: usize,
    /// Block number of `blocks[0]`.
    block_base: usize,
    /// The move named for the last setpoint on a smoothed piece: where the search starts
    /// (the setpoints advance, so it is usually near), never a limit on it.
    cursor: usize,
}

/// Programmed moves per block of the tracker's search.
const BLOCK_MOVES: usize = 16;

/// An axis-aligned box that holds every point of a few programmed moves.
#[derive(Clone, Copy, Debug)]
struct Bounds {
    lo: Vec3,
    hi: Vec3,
}

impl Bounds {
    /// Grows the box to hold `other`.
    fn merge(&mut self, other: &Bounds) {
        self.lo = self.lo.inf(&other.lo);
        self.hi = self.hi.sup(&other.hi);
    }

    /// The square of the distance from `p` to the nearest point of the box.
    fn gap2(&self, p: &Vec3) -> f64 {
        let mut gap2 = 0.0;
        for i in 0..3 {
            let g = (self.lo[i] - p[i]).max(p[i] - self.hi[i]).max(0.0);
            gap2 += g * g;
        }
        gap2
    }
}

impl Tracker {
    /// A tracker that holds `moves` moves without allocating.
    pub fn with_capacity(moves: usize) -> Tracker {
        Tracker {
            curves: VecDeque::with_capacity(moves),
            lines: VecDeque::with_capacity(moves),
            // The moves `base ..` span at most this many blocks.
            blocks: VecDeque::with_capacity(moves / BLOCK_MOVES + 2),
            base: 0,
            block_base: 0,
            cursor: 0,
        }
    }

    /// `true` while it holds no move.
    pub fn is_empty(&self) -> bool {
        self.curves.is_empty()
    }

    /// `true` when one more move would make it allocate.
    pub fn is_full(&self) -> bool {
        self.curves.len() >= self.curves.capacity()
            || self.lines.len() >= self.lines.capacity()
            || self.blocks.len() >= self.blocks.capacity()
    }

    /// Forgets every move (a new program; the capacity stays).
    pub fn clear(&mut self) {
        self.curves.clear();
        self.lines.clear();
        self.blocks.clear();
        self.base = 0;
        self.block_base = 0;
        self.cursor = 0;
    }

    /// Appends the next programmed move (program order).
    pub fn add(&mut self, mv: &Move) {
        let curve = Programmed::new(&mv.path);
        let bounds = curve.bounds();
        let block = (self.base + self.curves.len()) / BLOCK_MOVES;
        if self.blocks.is_empty() {
            self.block_base = block;
        }
        let open = block < self.block_base + self.blocks.len();
        match self.blocks.back_mut() {
            Some(b) if open => b.merge(&bounds),
            _ => self.blocks.push_back(bounds),
        }
        self.curves.push_back(curve);
        self.lines.push_back(mv.line);
    }

    /// For a setpoint on a smoothed piece, sets its line and move to the programmed move
    /// of the piece nearest to it (the earlier one of equally near moves); returns the
    /// setpoint's distance from the programmed moves (`None` while no move is known).
    /// Drops the moves before the segment being run.
    pub fn track(&mut self, sp: &mut Setpoint) -> Option<f64> {
        if self.curves.is_empty() {
            return None;
        }
        let p = Vec3::new(sp.position[0], sp.position[1], sp.position[2]);
        let first = sp.move_index as usize;
        let (d, k) = self.nearest_move(&p, sp.move_index, sp.move_count);
        if sp.move_count > 1 {
            // A smoothed piece stands for several moves: report the one being passed.
            sp.line = self.lines[k - self.base];
            sp.move_index = k as u64;
            sp.move_count = 1;
        }
        // The segments run in program order: the moves before this one's are never looked
        // at again.
        let keep_from = first.saturating_sub(1 + MOVES_KEPT_BEHIND);
        while self.base < keep_from && self.curves.len() > 1 {
            self.curves.pop_front();
            self.lines.pop_front();
            self.base += 1;
            if (self.block_base + 1) * BLOCK_MOVES <= self.base {
                self.blocks.pop_front();
                self.block_base += 1;
            }
        }
        Some(d)
    }

    /// Distance from `p` to the moves `move_index - 1 ..= move_index + count` (the segment's
    /// own moves and its neighbours, whose corners a blend may cut), and the move the
    /// setpoint is passing: the segment's move, or on a smoothed piece (`count` > 1) the
    /// nearest of its own moves `move_index .. move_index + count`, the earliest of equally
    /// near ones. That search is exact: it starts from the move named last (a close
    /// candidate) and skips only the blocks of moves that lie wholly farther away than the
    /// nearest found, wherever the moves go (a polyline may turn back towards the setpoint:
    /// trochoidal loops, hairpins). The distance is a minimum over moves of the program,
    /// so it is never less than the true distance.
    fn nearest_move(&mut self, p: &Vec3, move_index: u64, count: u32) -> (f64, usize) {
        // Program indices; `curves` holds `base ..= last`.
        let last = self.base + self.curves.len() - 1;
        let i = (move_index as usize).clamp(self.base, last);
        let lo = i.saturating_sub(1).max(self.base);
        let hi = (i + count.max(1) as usize).min(last);
        let curve = |k: usize| &self.curves[k - self.base];
        if count <= 1 {
            let mut best = f64::INFINITY;
            for k in lo..=(i + 1).min(hi) {
                best = best.min(curve(k).distance_to(p));
            }
            return (best, i);
        }
        // A piece: its own moves `i ..= end`, then its neighbours for the distance. The
        // move named last is a close candidate to start from; a block or move whose box
        // lies farther away than the nearest so far is passed over. The slack covers the
        // rounding of the boxes' distances and of the moves' own, far below any distance
        // that matters, so no move as near as the nearest is ever passed over.
        let end = (i + count as usize - 1).min(last);
        let slack = 1e-9 + 1e-14 * (p.x.abs() + p.y.abs() + p.z.abs());
        let beyond = |b: &Bounds, d: f64| b.gap2(p) > (d + slack) * (d + slack);
        let mut best = (f64::INFINITY, i);
        if (i..=end).contains(&self.cursor) {
            best = (curve(self.cursor).distance_to(p), self.cursor);
        }
        // `blocks` starts at or before the block of `base`, and holds that of `last`.
        let blocks = (i / BLOCK_MOVES - self.block_base)..=(end / BLOCK_MOVES - self.block_base);
        for (b, bounds) in self.blocks.range(blocks).enumerate() {
            if beyond(bounds, best.0) {
                continue;
            }
            let block = i / BLOCK_MOVES + b;
            for k in (block * BLOCK_MOVES).max(i)..=((block + 1) * BLOCK_MOVES - 1).min(end) {
                let c = curve(k);
                if beyond(&c.bounds(), best.0) {
                    continue;
                }
                let d = c.distance_to(p);
                if d < best.0 || (d == best.0 && k < best.1) {
                    best = (d, k);
                }
            }
        }
        self.cursor = best.1;
        let mut d = best.0.min(curve(lo).distance_to(p));
        if hi > end {
            d = d.min(curve(hi).distance_to(p));
        }
        (d, best.1)
    }
}

/// Where an offline run takes its planned items from: planned items in order, and the
/// programmed moves in order (each [`Planned::Segment`] says how many moves the planner
/// had taken when it made it; the deviation check records them before the segment runs).
trait Source {
    /// The next item; never [`Poll::Pending`] (the offline runs wait for the planner).
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
struct Runner<'a, F: Sink> {
    interp: Interpolator,
    measure: Measure<'a>,
    period_s: f64,
    sink: F,
    cycle: u64,
    events: &'a [(u64, Event)],
    next_event: usize,
    max_cycles: u64,
    /// Programmed moves recorded so far.
    known: usize,
}

impl<'a, F: Sink> Runner<'a, F> {
    fn new(limits: &MachineLimits, options: &'a RunOptions, sink: F) -> Self {
        let mut core = MotionCore::new(limits.period_s, options.capacity);
        core.set_feed_override(options.feed_override);
        let mut runner = Runner {
            interp: Interpolator::new(core),
            measure: Measure {
                period_s: limits.period_s,
                hist: [[0.0; 6]; 4],
                hist_len: 0,
                summary: Summary::default(),
                tracker: Tracker::default(),
                monitor: None,
                fault: None,
            },
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
    fn attach(&mut self, monitor: Option<&'a mut LimitMonitor>) -> Result<(), RunError> {
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
    fn run<S: Source>(mut self, source: &mut S) -> Result<Summary, RunError> {
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
        let aborted = self.interp.aborted();
        let started = self.interp.feed(|| {
            let polled = source.poll();
            if let Poll::Ready(Planned::Segment(_, moves_known)) = &polled {
                while *known < *moves_known {
                    let Some(mv) = source.next_move() else {
                        break;
                    };
                    measure.add_move(&mv, aborted);
                    *known += 1;
                }
            }
            polled
        })?;
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

/// A programmed move's path as the deviation check needs it (no transition variant, and a
/// line without its derived direction and length). Not boxed: the daemon's tracker must
/// not allocate.
#[allow(clippy::large_enum_variant)]
enum Programmed {
    /// Start and end; the direction and length are derived as in [`Curve::line`].
    Line(Vec3, Vec3),
    Helix(Helix),
}

impl Programmed {
    fn new(path: &Path) -> Programmed {
        match Curve::from_path(path) {
            Curve::Helix(h) => Programmed::Helix(h),
            Curve::Line { start, end, .. } => Programmed::Line(start, end),
            Curve::Transition(_) => unreachable!("a programmed path is a line or an arc"),
        }
    }

    /// A box that holds every point of the move: a line's ends, the points within a
    /// helix's length of its start.
    fn bounds(&self) -> Bounds {
        match self {
            Programmed::Line(start, end) => Bounds {
                lo: start.inf(end),
                hi: start.sup(end),
            },
            Programmed::Helix(h) => {
                let r = Vec3::repeat(h.length_mm);
                Bounds {
                    lo: h.start - r,
                    hi: h.start + r,
                }
            }
        }
    }

    fn distance_to(&self, p: &Vec3) -> f64 {
        match self {
            Programmed::Line(start, end) => {
                // Exactly as `Curve::line` derives them.
                let delta = end - start;
                let length = delta.norm();
                let dir = if length > 0.0 {
                    delta / length
                } else {
                    Vec3::zeros()
                };
                line_distance(start, end, &dir, length, p)
            }
            Programmed::Helix(h) => h.distance_to(p),
        }
    }
}

/// The planning step of the offline runs: each input is planned, and every planned
/// segment carries the number of moves taken so far (the moves the deviation check then
/// knows), a dwell follows the segments before it.
struct PlanStep {
    planner: Planner,
    buf: Vec<PlannedSegment>,
    known: usize,
}

impl PlanStep {
    fn new(limits: &MachineLimits, design_override: f64) -> Self {
        let mut planner = Planner::new(*limits);
        planner.set_design_override(design_override);
        PlanStep {
            planner,
            buf: Vec::new(),
            known: 0,
        }
    }

    /// Plans `input`: a move also goes to `taken`, the planned items to `out`.
    fn input(
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
    fn finish(&mut self, out: &mut impl Extend<Planned>) {
        self.planner.finish(&mut self.buf);
        let known = self.known;
        out.extend(self.buf.drain(..).map(|s| Planned::Segment(s, known)));
    }
}

/// The source of [`run`]: plans each input when the run asks for the next item.
struct Inline<I> {
    inputs: I,
    step: PlanStep,
    ready: VecDeque<Planned>,
    taken: VecDeque<Move>,
    error: Option<PlanError>,
}

impl<I: Iterator<Item = Input>> Source for Inline<I> {
    fn poll(&mut self) -> Poll {
        loop {
            if let Some(p) = self.ready.pop_front() {
                return Poll::Ready(p);
            }
            if self.error.is_some() {
                return Poll::End;
            }
            let Some(input) = self.inputs.next() else {
                self.step.finish(&mut self.ready);
                return match self.ready.pop_front() {
                    Some(p) => Poll::Ready(p),
                    None => Poll::End,
                };
            };
            if let Err(e) = self.step.input(&input, &mut self.taken, &mut self.ready) {
                self.error = Some(e);
                return Poll::End;
            }
        }
    }

    fn next_move(&mut self) -> Option<Move> {
        self.taken.pop_front()
    }

    fn take_error(&mut self) -> Option<PlanError> {
        self.error.take()
    }
}

/// Runs `moves` from rest at the origin; calls `sink(t, setpoint)` for every row, starting
/// with the row at t = 0. Returns what was measured.
pub fn run<I, F>(
    moves: I,
    limits: &MachineLimits,
    options: &RunOptions,
    sink: F,
) -> Result<Summary, RunError>
where
    I: IntoIterator,
    I::Item: Into<Input>,
    F: FnMut(f64, &Setpoint),
{
    let runner = Runner::new(limits, options, sink);
    let mut source = Inline {
        inputs: moves.into_iter().map(Into::into),
        step: PlanStep::new(limits, options.feed_override),
        ready: VecDeque::new(),
        taken: VecDeque::new(),
        error: None,
    };
    runner.run(&mut source)
}

/// Segments per message from the planning thread of [`run_parallel`].
const BATCH: usize = 256;

/// Moves per message at most from the planning thread of [`run_stream`] (a smoothing
/// window may take thousands of moves before it yields a segment).
const MOVES_PER_BATCH: usize = 4096;

/// A batch from the planning thread: the moves it took since the previous batch, in
/// program order, and the planned segments, each with the number of moves the planner had
/// taken when it produced the segment (so that the deviation check sees the same moves as
/// in [`run`]); or the error that stopped planning.
type Batch = Result<(Vec<Move>, Vec<Planned>), PlanError>;

/// What the run is fed after planning: a segment with the number of moves the planner had
/// taken when it produced it (so that the deviation check sees the same moves as in
/// [`run`]), or a dwell (the segments before it end at rest).
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

/// [`run`] with the planner on a second thread: the same setpoints, bit for bit (the
/// feeding policy only depends on the order of the segments), in less wall time when a
/// second core is free. For programs held in memory; see [`run_stream`] for streams.
pub fn run_parallel<F>(
    moves: &[Move],
    limits: &MachineLimits,
    options: &RunOptions,
    sink: F,
) -> Result<Summary, RunError>
where
    F: FnMut(f64, &Setpoint),
{
    run_stream(moves.iter().copied(), limits, options, None, sink)
}

/// The source of [`run_stream`]: batches from the planning thread.
struct Batches {
    rx: std::sync::mpsc::Receiver<Batch>,
    items: std::vec::IntoIter<Planned>,
    pending: VecDeque<Move>,
    error: Option<PlanError>,
}

impl Source for Batches {
    fn poll(&mut self) -> Poll {
        loop {
            if let Some(p) = self.items.next() {
                return Poll::Ready(p);
            }
            match self.rx.recv() {
                Ok(Ok((moves, items))) => {
                    self.pending.extend(moves);
                    self.items = items.into_iter();
                }
                Ok(Err(e)) => {
                    self.error = Some(e);
                    return Poll::End;
                }
                Err(_) => return Poll::End,
            }
        }
    }

    fn next_move(&mut self) -> Option<Move> {
        self.pending.pop_front()
    }

    fn take_error(&mut self) -> Option<PlanError> {
        self.error.take()
    }
}

/// [`run_parallel`] over a stream of moves (`kerf sim` reads them from the program file
/// while the motion runs): memory does not grow with the program, only with the queue
/// capacity. With a `monitor` every setpoint is checked as it is produced, and the run
/// stops at the first one that breaks a limit with [`RunError::Fault`] (the sink has
/// already seen that setpoint). The monitor keeps what it measured (its peaks) for the
/// caller; it is given every setpoint from the row at t = 0 on.
pub fn run_stream<I, F>(
    moves: I,
    limits: &MachineLimits,
    options: &RunOptions,
    monitor: Option<&mut LimitMonitor>,
    sink: F,
) -> Result<Summary, RunError>
where
    I: Iterator + Send,
    I::Item: Into<Input>,
    F: FnMut(f64, &Setpoint),
{
    let (tx, rx) = std::sync::mpsc::sync_channel::<Batch>(4);
    let design_override = options.feed_override;
    std::thread::scope(|scope| {
        scope.spawn(move || {
            let mut step = PlanStep::new(limits, design_override);
            let mut taken = Vec::new();
            let mut batch = Vec::with_capacity(BATCH);
            for input in moves {
                if let Err(e) = step.input(&input.into(), &mut taken, &mut batch) {
                    let _ = tx.send(Err(e));
                    return;
                }
                if batch.len() >= BATCH || taken.len() >= MOVES_PER_BATCH {
                    let full = (
                        std::mem::take(&mut taken),
                        std::mem::replace(&mut batch, Vec::with_capacity(BATCH)),
                    );
                    if tx.send(Ok(full)).is_err() {
                        return;
                    }
                }
            }
            step.finish(&mut batch);
            let _ = tx.send(Ok((taken, batch)));
        });
        let mut runner = Runner::new(limits, options, sink);
        runner.attach(monitor)?;
        let mut source = Batches {
            rx,
            items: Vec::new().into_iter(),
            pending: VecDeque::new(),
            error: None,
        };
        // Dropping the source (and its receiver) when the run returns ends the planning
        // thread's sends (a run stopped early).
        runner.run(&mut source)
    })
}

/// The source of [`run_planned`].
struct Kept<'m, S> {
    segments: S,
    program: std::iter::Copied<std::slice::Iter<'m, Move>>,
}

impl<S: Iterator<Item = Planned>> Source for Kept<'_, S> {
    fn poll(&mut self) -> Poll {
        match self.segments.next() {
            Some(p) => Poll::Ready(p),
            None => Poll::End,
        }
    }

    fn next_move(&mut self) -> Option<Move> {
        self.program.next()
    }
}

/// [`run_stream`] for segments already planned (by the same [`Planner`] with the same
/// limits and design override, which is deterministic): each segment with the number of
/// moves the planner had taken when it produced it, and the dwells in their place. No
/// planning thread; the same setpoints as [`run_stream`] on the same input.
pub fn run_planned<S, F>(
    moves: &[Move],
    segments: S,
    limits: &MachineLimits,
    options: &RunOptions,
    monitor: Option<&mut LimitMonitor>,
    sink: F,
) -> Result<Summary, RunError>
where
    S: IntoIterator<Item = Planned>,
    F: FnMut(f64, &Setpoint),
{
    let mut runner = Runner::new(limits, options, sink);
    runner.attach(monitor)?;
    let mut source = Kept {
        segments: segments.into_iter(),
        program: moves.iter().copied(),
    };
    runner.run(&mut source)
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerf_motion::monitor::*;
    use kerf_plan::AxisLimits;

    #[test]
    fn dwells_take_whole_periods_rounded_up() {
        assert_eq!(dwell_periods(0.5, 0.001), 500);
        assert_eq!(dwell_periods(0.0005, 0.001), 1);
        assert_eq!(dwell_periods(0.001, 62.5e-6), 16);
        assert_eq!(dwell_periods(0.3, 0.1), 3);
        assert_eq!(dwell_periods(0.0, 0.001), 0);
        assert_eq!(dwell_periods(f64::NAN, 0.001), 0);
    }

    #[test]
    fn a_dwell_rests_at_an_exact_stop_the_same_in_every_runner() {
        // Two lines at a shallow angle (blended without the dwell), a 0.1 s dwell between.
        let limits = machine(0.001, 200.0, 2000.0, 50_000.0);
        let mv = |a: Vec3, b: Vec3| Move {
            line: 1,
            rapid: false,
            path: Path::Line(kerf_geom::Line { start: a, end: b }),
            feed_mm_min: Some(1200.0),
            abc_deg: None,
            corner: kerf_geom::CornerMode::Blend {
                tolerance_mm: None,
                naive_cam_mm: None,
            },
        };
        let corner = Vec3::new(10.0, 0.0, 0.0);
        let inputs = [
            Input::Move(mv(Vec3::zeros(), corner)),
            Input::Dwell(0.1),
            Input::Move(mv(corner, Vec3::new(20.0, 2.0, 0.0))),
        ];
        let collect = |streamed: bool| {
            let mut rows: Vec<[f64; 6]> = Vec::new();
            let opts = RunOptions::default();
            let sink = |_: f64, sp: &Setpoint| rows.push(sp.position);
            if streamed {
                run_stream(inputs.iter().copied(), &limits, &opts, None, sink).unwrap();
            } else {
                run(inputs.iter().copied(), &limits, &opts, sink).unwrap();
            }
            rows
        };
        let rows = collect(false);
        assert_eq!(rows, collect(true));
        let at_corner = rows.iter().filter(|p| p[..3] == [10.0, 0.0, 0.0]).count();
        // The arrival row and 100 periods of rest.
        assert!((101..=102).contains(&at_corner), "{at_corner}");
        // Without the dwell the corner is blended: no setpoint is exactly on it.
        let mut blended: Vec<[f64; 6]> = Vec::new();
        run(
            [inputs[0], inputs[2]],
            &limits,
            &RunOptions::default(),
            |_, sp| blended.push(sp.position),
        )
        .unwrap();
        assert!(!blended.iter().any(|p| p[..3] == [10.0, 0.0, 0.0]));
        assert!(blended.len() + 90 < rows.len());
    }

    fn machine(period_s: f64, v: f64, a: f64, j: f64) -> MachineLimits {
        let axis = Some(AxisLimits {
            velocity_units_s: v,
            acceleration_units_s2: a,
            jerk_units_s3: j,
        });
        MachineLimits {
            axes: [axis, axis, axis, None, None, None],
            period_s,
            tolerance_mm: 0.01,
        }
    }

    /// `x(t) = offset + amp · sin(ω t)` on X at the period; Y and Z stay at `offset`.
    fn sine(offset: f64, amp: f64, omega: f64, period_s: f64, n: usize) -> Vec<[f64; 6]> {
        (0..n)
            .map(|k| {
                let t = k as f64 * period_s;
                [
                    offset + amp * (omega * t).sin(),
                    offset,
                    offset,
                    0.0,
                    0.0,
                    0.0,
                ]
            })
            .collect()
    }

    /// The continuous peaks of the sine: `amp ωⁿ`; finite differences at the period
    /// measure slightly less (`amp (2 sin(ωT/2)/T)ⁿ`).
    fn peaks(amp: f64, omega: f64) -> [f64; 3] {
        [amp * omega, amp * omega.powi(2), amp * omega.powi(3)]
    }

    fn first_fault(m: &mut LimitMonitor, stream: &[[f64; 6]]) -> Option<LimitViolation> {
        stream.iter().find_map(|p| m.check(p).err())
    }

    #[test]
    fn a_stream_at_its_limits_passes_wherever_it_runs() {
        // Limits equal to the sine's continuous peaks: the stream is exactly at 100 %.
        for (offset, period_s) in [
            (0.0, 1e-3),
            (-250.0, 2.5e-4),
            (1000.0, 1e-3),
            (9999.0, 6.25e-5),
            (-9999.0, 1e-2),
        ] {
            let (amp, omega) = (5.0, 20.0);
            let [v, a, j] = peaks(amp, omega);
            let limits = machine(period_s, v, a, j);
            let stream = sine(offset, amp, omega, period_s, (1.0 / period_s) as usize);
            // (The sine does not start at rest: nothing is assumed before it.)
            let mut m = LimitMonitor::new(&limits);
            assert_eq!(first_fault(&mut m, &stream), None, "offset {offset}");
            // The peaks read 100 %, within the rounding noise of 9,999 mm at 62.5 µs.
            let r = m.peak_ratios(0).unwrap();
            for q in r {
                assert!((0.97..=1.002).contains(&q), "offset {offset}: {r:?}");
            }
        }
    }

    #[test]
    fn rounding_noise_of_far_positions_at_a_short_period_is_not_a_fault() {
        // 1 µm of motion at 9,999 mm, period 62.5 µs, jerk 1e-3 mm/s³ at the limit: one
        // ulp of 9,999 mm (1.8e-12 mm) over T³ (2.4e-13 s³) is already 7 mm/s³, so the
        // raw third differences are pure rounding noise far above the limit.
        let (amp, omega, period_s) = (1e-3, 1.0, 6.25e-5);
        let [v, a, j] = peaks(amp, omega);
        let limits = machine(period_s, v, a, j);
        let stream = sine(9999.0, amp, omega, period_s, 20_000);
        let raw_jerk = stream
            .windows(4)
            .map(|w| (w[3][0] - 3.0 * w[2][0] + 3.0 * w[1][0] - w[0][0]).abs() / period_s.powi(3))
            .fold(0.0, f64::max);
        assert!(raw_jerk > 100.0 * j, "the noise is real: {raw_jerk}");
        let mut m = LimitMonitor::new(&limits);
        assert_eq!(first_fault(&mut m, &stream), None);
        assert!(m.peak_ratios(0).unwrap()[2] <= LIMIT_MARGIN);
    }

    #[test]
    fn a_two_percent_excess_is_a_fault_naming_the_quantity_and_the_first_setpoint() {
        let (amp, omega, period_s) = (5.0, 20.0, 1e-3);
        let [v, a, j] = peaks(amp, omega);
        let stream = sine(1000.0, amp, omega, period_s, 1000);
        for (q, limits) in [
            (
                Quantity::Velocity,
                machine(period_s, v / 1.02, a * 2.0, j * 2.0),
            ),
            (
                Quantity::Acceleration,
                machine(period_s, v * 2.0, a / 1.02, j * 2.0),
            ),
            (
                Quantity::Jerk,
                machine(period_s, v * 2.0, a * 2.0, j / 1.02),
            ),
        ] {
            let mut m = LimitMonitor::new(&limits);
            let f = first_fault(&mut m, &stream).unwrap_or_else(|| panic!("{q:?} not caught"));
            assert_eq!((f.axis, f.quantity), (0, q));
            assert!((1.01..1.021).contains(&f.ratio()), "{q:?}: {f:?}");
            // It is the first setpoint whose finite difference is beyond 1.01 × limit,
            // computed here independently from the stream.
            let limit = f.limit;
            let n = q as usize + 1;
            let first = (n..stream.len())
                .find(|&k| {
                    let x = |i: usize| stream[k - i][0];
                    let d = match n {
                        1 => x(0) - x(1),
                        2 => x(0) - 2.0 * x(1) + x(2),
                        _ => x(0) - 3.0 * x(1) + 3.0 * x(2) - x(3),
                    };
                    d.abs() / period_s.powi(n as i32) > 1.01 * limit
                })
                .unwrap();
            assert_eq!(f.sample, first as u64, "{q:?}");
        }
    }

    #[test]
    fn a_jump_is_a_velocity_fault_at_the_setpoint_that_jumps() {
        // The teleport: at rest at the origin, then 4.14 mm in one 1 ms period on
        // a 1,000 mm/s machine (414 % of the velocity limit).
        let limits = machine(1e-3, 1000.0, 1e5, 1e7);
        let mut stream = vec![[0.0; 6]; 5];
        stream.extend(vec![[-1.0117, -4.0119, 0.0635, 0.0, 0.0, 0.0]; 5]);
        let mut m = LimitMonitor::at_rest(&limits, &[0.0; 6]);
        let f = first_fault(&mut m, &stream).unwrap();
        assert_eq!((f.sample, f.axis, f.quantity), (5, 1, Quantity::Velocity));
        assert!((f.ratio() - 4.0119).abs() < 1e-9, "{f:?}");
        assert_eq!(
            f.to_string(),
            "setpoint 5: Y velocity 401 % of the limit (1000)"
        );
        // A monitor that knows nothing before its first setpoint sees the same jump.
        let mut m = LimitMonitor::new(&limits);
        assert_eq!(first_fault(&mut m, &stream).map(|f| f.sample), Some(5));
        // A start away from the rest position is a jump too.
        let mut m = LimitMonitor::at_rest(&limits, &[0.0; 6]);
        assert!(m.check(&[1.0, 0.0, 0.0, 0.0, 0.0, 0.0]).is_err());
        // A non-finite position is a fault; an axis the machine lacks is not checked.
        let mut m = LimitMonitor::at_rest(&limits, &[0.0; 6]);
        assert!(m.check(&[0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0]).is_err());
        let mut m = LimitMonitor::at_rest(&limits, &[0.0; 6]);
        assert_eq!(m.check(&[0.0, 0.0, 0.0, 50.0, 0.0, 0.0]), Ok(()));
    }

    #[test]
    fn acceleration_before_jerk_when_both_break() {
        // From rest, a step to a constant speed of 90 % of the velocity limit in one
        // period: velocity holds, acceleration and jerk do not; acceleration is reported.
        let limits = machine(1e-3, 100.0, 1000.0, 1e5);
        let mut m = LimitMonitor::at_rest(&limits, &[0.0; 6]);
        let f = m.check(&[0.09, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap_err();
        assert_eq!(f.quantity, Quantity::Acceleration);
        assert!((f.ratio() - 90.0).abs() < 1e-6, "{f:?}");
    }

    #[test]
    fn a_monitored_run_stops_at_the_first_setpoint_that_breaks_a_limit() {
        // Planned for 100 mm/s, watched by a monitor that allows only 50 mm/s: the run
        // must stop at the first setpoint faster than 50.5 mm/s, found here from the
        // setpoints of an unmonitored run of the same program.
        use kerf_geom::{CornerMode, Line};
        let planned = machine(1e-3, 100.0, 1000.0, 1e5);
        let watched = machine(1e-3, 50.0, 1000.0, 1e5);
        let mv = Move {
            line: 7,
            rapid: false,
            path: Path::Line(Line {
                start: Vec3::zeros(),
                end: Vec3::new(30.0, 0.0, 0.0),
            }),
            feed_mm_min: Some(6000.0),
            abc_deg: None,
            corner: CornerMode::ExactStop,
        };
        let mut free = Vec::new();
        run_stream(
            [mv].into_iter(),
            &planned,
            &RunOptions::default(),
            None,
            |_, sp| free.push(sp.position[0]),
        )
        .unwrap();
        let first = free
            .windows(2)
            .position(|w| (w[1] - w[0]) / 1e-3 > 50.0 * LIMIT_MARGIN)
            .expect("the program runs faster than 50 mm/s")
            + 1;
        let mut monitor = LimitMonitor::at_rest(&watched, &[0.0; 6]);
        let mut seen = Vec::new();
        let result = run_stream(
            [mv].into_iter(),
            &planned,
            &RunOptions::default(),
            Some(&mut monitor),
            |t, sp| seen.push((t, sp.position[0], sp.line)),
        );
        let Err(RunError::Fault(v)) = result else {
            panic!("no fault: {result:?}");
        };
        assert_eq!(
            (v.sample, v.axis, v.quantity),
            (first as u64, 0, Quantity::Velocity)
        );
        // The sink saw every setpoint up to and including the offending one, no more.
        assert_eq!(seen.len(), first + 1);
        assert_eq!(seen.last().unwrap().1, free[first]);
        assert_eq!(seen.last().unwrap().2, 7);
        // The same from planned segments.
        let mut planner = Planner::new(planned);
        let mut segs = Vec::new();
        planner.push(&mv, &mut segs).unwrap();
        planner.finish(&mut segs);
        let mut monitor = LimitMonitor::at_rest(&watched, &[0.0; 6]);
        let mut rows = 0;
        let result = run_planned(
            &[mv],
            segs.into_iter().map(|s| Planned::Segment(s, 1)),
            &planned,
            &RunOptions::default(),
            Some(&mut monitor),
            |_, _| rows += 1,
        );
        assert_eq!(result, Err(RunError::Fault(v)));
        assert_eq!(rows, first + 1);
    }

    /// A tracker holding the lines through `points`, move `k` on source line `k + 1`.
    fn tracker_of(points: &[[f64; 2]]) -> Tracker {
        let mut t = Tracker::with_capacity(64);
        for (k, w) in points.windows(2).enumerate() {
            t.add(&Move {
                line: k as u32 + 1,
                rapid: false,
                path: Path::Line(kerf_geom::Line {
                    start: Vec3::new(w[0][0], w[0][1], 0.0),
                    end: Vec3::new(w[1][0], w[1][1], 0.0),
                }),
                feed_mm_min: Some(600.0),
                abc_deg: None,
                corner: kerf_geom::CornerMode::Blend {
                    tolerance_mm: None,
                    naive_cam_mm: None,
                },
            });
        }
        t
    }

    /// Tracks a setpoint at `(x, y)` on a smoothed piece of `count` moves from `first`:
    /// the line named and the distance.
    fn track_at(t: &mut Tracker, x: f64, y: f64, first: u64, count: u32) -> (u32, f64) {
        let mut sp = Setpoint {
            position: [x, y, 0.0, 0.0, 0.0, 0.0],
            line: first as u32 + 1,
            move_index: first,
            move_count: count,
            feed_mm_s: 1.0,
        };
        let d = t.track(&mut sp).unwrap();
        assert_eq!((sp.move_index, sp.move_count), (u64::from(sp.line) - 1, 1));
        (sp.line, d)
    }

    #[test]
    fn the_tracker_names_the_nearest_move_of_the_piece_the_earlier_of_equal_ones() {
        // A meander, move k on line k + 1: 0 (0,0)→(1,0), 1 →(1,1), 2 →(0,1), 3 →(0,2),
        // 4 →(1,2), 5 →(1,3), 6 →(0,3).
        let pts = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 2.0]];
        let pts = [&pts[..], &[[1.0, 2.0], [1.0, 3.0], [0.0, 3.0]]].concat();
        let mut t = tracker_of(&pts);
        // A piece from move 1 standing for moves 1 to 3. (0.5, 0.5) is 0.5 mm from moves 1
        // and 2, and from move 0 before the piece (never named): the earlier, move 1.
        // (0.5, 1.5) is 0.5 mm from moves 2 and 3, and from move 4 after it: move 2.
        assert_eq!(track_at(&mut t, 0.5, 0.5, 1, 3), (2, 0.5));
        assert_eq!(track_at(&mut t, 0.5, 1.5, 1, 3), (3, 0.5));
        // Nearer to move 4, the next piece's, than to any of its own: its own nearest is
        // named; the distance counts the neighbour.
        assert_eq!(track_at(&mut t, 0.25, 1.875, 1, 3), (4, 0.125));
        // Back towards an earlier move of the piece than the one named last.
        assert_eq!(track_at(&mut t, 0.875, 0.5, 1, 3), (2, 0.125));
        // A piece of six moves from move 1: the nearest of all six, wherever the last one
        // named was.
        assert_eq!(track_at(&mut t, 0.5, 2.875, 1, 6), (7, 0.125));
        assert_eq!(track_at(&mut t, 0.5, 0.875, 1, 6), (3, 0.125));
    }

    #[test]
    fn the_tracker_search_is_exact_over_many_blocks() {
        // A spiral of 400 short moves turning back past itself: every setpoint on a piece
        // of all of them is named after its nearest move, found by brute force.
        let pts: Vec<[f64; 2]> = (0..=400)
            .map(|k| {
                let a = k as f64 * 0.05;
                let r = 1.0 + 0.002 * k as f64;
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        let mut t = tracker_of(&pts);
        let distance = |k: usize, p: Vec3| {
            let (a, b) = (pts[k], pts[k + 1]);
            kerf_geom::Curve::line(Vec3::new(a[0], a[1], 0.0), Vec3::new(b[0], b[1], 0.0))
                .distance_to(&p)
        };
        for n in 0..2000 {
            let a = n as f64 * 0.01;
            let (x, y) = (1.1 * a.cos() + 0.3, 1.1 * a.sin());
            let p = Vec3::new(x, y, 0.0);
            let (line, d) = track_at(&mut t, x, y, 1, 399);
            let (k, dk) = (1..400)
                .map(|k| (k, distance(k, p)))
                .fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
            assert_eq!(line as usize, k + 1, "setpoint {n}");
            assert!(d <= dk, "setpoint {n}");
        }
    }
}
