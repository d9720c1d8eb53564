//! The offline driver: moves → [`Planner`] → [`MotionCore`] in virtual time.
//!
//! This is the loop `kerf sim` and the tests run, with the same deterministic feeding
//! policy the daemon uses: push segments while the queue has room, step one period when
//! it is full, and after the last move step until the motion is at rest. It also measures
//! what the invariants are about: per-axis peak velocity, acceleration and jerk by finite
//! differences of the setpoints, and the distance of every setpoint from the programmed
//! moves.

use crate::{MotionCore, PushError, Setpoint, StepResult};
use kerf_geom::{Curve, Helix, Move, Path, Vec3, line_distance};
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
            p.velocity / l.velocity,
            p.acceleration / l.acceleration,
            p.jerk / l.jerk,
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
}

impl std::fmt::Display for RunError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RunError::Plan(e) => e.fmt(f),
            RunError::Rejected { line } => write!(f, "line {line}: segment rejected"),
        }
    }
}

impl std::error::Error for RunError {}

impl From<PlanError> for RunError {
    fn from(e: PlanError) -> Self {
        RunError::Plan(e)
    }
}

struct Runner<'a, F: FnMut(f64, &Setpoint)> {
    core: MotionCore,
    period_s: f64,
    sink: F,
    cycle: u64,
    events: &'a [(u64, Event)],
    next_event: usize,
    hist: [[f64; 6]; 4],
    hist_len: usize,
    summary: Summary,
    /// The programmed moves, for the deviation check (compact: no transition variant).
    curves: Vec<Programmed>,
    /// Source line of every move.
    lines: Vec<u32>,
    /// The move nearest to the last setpoint.
    cursor: usize,
    last_result: StepResult,
    max_cycles: u64,
    /// After an abort nothing more is fed (the rest of the program is dropped).
    aborted: bool,
}

impl<F: FnMut(f64, &Setpoint)> Runner<'_, F> {
    fn step(&mut self) -> StepResult {
        self.cycle += 1;
        while self.next_event < self.events.len() && self.events[self.next_event].0 <= self.cycle {
            match self.events[self.next_event].1 {
                Event::Hold => self.core.hold(),
                Event::Resume => self.core.resume(),
                Event::Abort => {
                    self.core.abort();
                    self.aborted = true;
                }
                Event::Override(f) => self.core.set_feed_override(f),
            }
            self.next_event += 1;
        }
        let mut sp = Setpoint::default();
        let r = self.core.step(&mut sp);
        self.record(&mut sp);
        let t = self.time();
        (self.sink)(t, &sp);
        self.last_result = r;
        r
    }

    /// Time of the current cycle; a whole number of microseconds per period is multiplied
    /// in integers so that printed times are exact decimals.
    fn time(&self) -> f64 {
        let us = (self.period_s * 1e6).round();
        if (us * 1e-6 - self.period_s).abs() <= 1e-15 {
            (self.cycle as f64 * us) / 1e6
        } else {
            self.cycle as f64 * self.period_s
        }
    }

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
        if !self.curves.is_empty() {
            let p = Vec3::new(sp.position[0], sp.position[1], sp.position[2]);
            let (d, k) = self.nearest_move(&p, sp.move_index, sp.move_count);
            self.summary.max_deviation_mm = self.summary.max_deviation_mm.max(d);
            if sp.move_count > 1 {
                // A smoothed piece stands for several moves: report the one being passed.
                sp.line = self.lines[k];
                sp.move_index = k as u64;
                sp.move_count = 1;
            }
        }
        self.summary.last = *sp;
    }

    /// Distance from `p` to the moves `move_index - 1 ..= move_index + count` (the segment's
    /// own moves and its neighbours, whose corners a blend may cut), and the move the
    /// setpoint is passing. A smoothed piece stands for many moves: they are scanned from
    /// the one passed last, on until they lie farther away than the nearest so far by more
    /// than their length (the setpoints advance along them). The result is a minimum over
    /// moves of the program, so it is never less than the true distance.
    fn nearest_move(&mut self, p: &Vec3, move_index: u64, count: u32) -> (f64, usize) {
        let last = self.curves.len() - 1;
        let i = (move_index as usize).min(last);
        let lo = i.saturating_sub(1);
        let hi = (i + count.max(1) as usize).min(last);
        let mut best = f64::INFINITY;
        if count <= 1 {
            for k in lo..=(i + 1).min(hi) {
                best = best.min(self.curves[k].distance_to(p));
            }
            return (best, i);
        }
        // A piece: its predecessor, then its own moves from the one passed last.
        best = self.curves[lo].distance_to(p);
        let from = if (i..=hi).contains(&self.cursor) {
            self.cursor
        } else {
            i
        };
        let mut local = (f64::INFINITY, from);
        for k in from..=hi {
            let c = &self.curves[k];
            let d = c.distance_to(p);
            if d < local.0 {
                local = (d, k);
            } else if k > local.1 + 1 && (c.start() - p).norm() > local.0 + c.length() {
                break;
            }
        }
        self.cursor = local.1;
        (best.min(local.0), local.1)
    }

    fn push(&mut self, seg: &PlannedSegment) -> Result<(), RunError> {
        loop {
            if self.aborted {
                return Ok(());
            }
            match self.core.push(seg) {
                Ok(()) => return Ok(()),
                Err(PushError::Full) => {
                    if self.cycle >= self.max_cycles {
                        return Ok(());
                    }
                    self.step();
                }
                Err(_) => return Err(RunError::Rejected { line: seg.line }),
            }
        }
    }
}

/// A programmed move's path as the deviation check needs it.
enum Programmed {
    /// Start, end, unit direction, length (as in [`Curve::Line`]).
    Line(Vec3, Vec3, Vec3, f64),
    Helix(Helix),
}

impl Programmed {
    fn new(path: &Path) -> Programmed {
        match Curve::from_path(path) {
            Curve::Helix(h) => Programmed::Helix(h),
            Curve::Line {
                start,
                end,
                dir,
                length_mm,
            } => Programmed::Line(start, end, dir, length_mm),
            Curve::Transition(_) => unreachable!("a programmed path is a line or an arc"),
        }
    }

    fn start(&self) -> Vec3 {
        match self {
            Programmed::Line(start, ..) => *start,
            Programmed::Helix(h) => h.start,
        }
    }

    fn length(&self) -> f64 {
        match self {
            Programmed::Line(.., length) => *length,
            Programmed::Helix(h) => h.length_mm,
        }
    }

    fn distance_to(&self, p: &Vec3) -> f64 {
        match self {
            Programmed::Line(start, end, dir, length) => line_distance(start, end, dir, *length, p),
            Programmed::Helix(h) => h.distance_to(p),
        }
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
    I: IntoIterator<Item = Move>,
    F: FnMut(f64, &Setpoint),
{
    let mut runner = Runner::new(limits, options, sink);
    let mut planner = Planner::new(*limits);
    planner.set_design_override(options.feed_override);
    let mut buf = Vec::new();
    for mv in moves {
        runner.add_move(&mv);
        planner.push(&mv, &mut buf)?;
        for seg in buf.drain(..) {
            runner.push(&seg)?;
        }
    }
    planner.finish(&mut buf);
    for seg in buf.drain(..) {
        runner.push(&seg)?;
    }
    Ok(runner.finish())
}

/// Segments per message from the planning thread of [`run_parallel`].
const BATCH: usize = 256;

/// A batch of planned segments, each with the number of moves the planner had taken when
/// it produced the segment (so that the deviation check sees the same moves as in
/// [`run`]), or the error that stopped planning.
type Batch = Result<Vec<(PlannedSegment, usize)>, PlanError>;

/// [`run`] with the planner on a second thread: the same setpoints, bit for bit (the
/// feeding policy only depends on the order of the segments), in less wall time when a
/// second core is free. For programs held in memory (`kerf sim`).
pub fn run_parallel<F>(
    moves: &[Move],
    limits: &MachineLimits,
    options: &RunOptions,
    sink: F,
) -> Result<Summary, RunError>
where
    F: FnMut(f64, &Setpoint),
{
    let (tx, rx) = std::sync::mpsc::sync_channel::<Batch>(4);
    let design_override = options.feed_override;
    std::thread::scope(|scope| {
        scope.spawn(move || {
            let mut planner = Planner::new(*limits);
            planner.set_design_override(design_override);
            let mut buf = Vec::new();
            let mut batch = Vec::with_capacity(BATCH);
            for (k, mv) in moves.iter().enumerate() {
                if let Err(e) = planner.push(mv, &mut buf) {
                    let _ = tx.send(Err(e));
                    return;
                }
                batch.extend(buf.drain(..).map(|s| (s, k + 1)));
                if batch.len() >= BATCH {
                    let full = std::mem::replace(&mut batch, Vec::with_capacity(BATCH));
                    if tx.send(Ok(full)).is_err() {
                        return;
                    }
                }
            }
            planner.finish(&mut buf);
            batch.extend(buf.drain(..).map(|s| (s, moves.len())));
            let _ = tx.send(Ok(batch));
        });
        let mut runner = Runner::new(limits, options, sink);
        let mut known = 0;
        for batch in rx {
            for (seg, moves_known) in batch? {
                while known < moves_known {
                    runner.add_move(&moves[known]);
                    known += 1;
                }
                runner.push(&seg)?;
            }
        }
        // Dropping the receiver (on an error above) ends the planning thread's sends.
        Ok(runner.finish())
    })
}

impl<'a, F: FnMut(f64, &Setpoint)> Runner<'a, F> {
    fn new(limits: &MachineLimits, options: &'a RunOptions, sink: F) -> Self {
        let mut core = MotionCore::new(*limits, options.capacity);
        core.set_feed_override(options.feed_override);
        let mut runner = Runner {
            core,
            period_s: limits.period_s,
            sink,
            cycle: 0,
            events: &options.events,
            next_event: 0,
            hist: [[0.0; 6]; 4],
            hist_len: 0,
            summary: Summary::default(),
            curves: Vec::new(),
            lines: Vec::new(),
            cursor: 0,
            last_result: StepResult::Idle,
            max_cycles: options.max_cycles,
            aborted: false,
        };
        let mut start = Setpoint::default();
        runner.record(&mut start);
        (runner.sink)(0.0, &start);
        runner
    }

    /// Records a programmed move for the deviation check.
    fn add_move(&mut self, mv: &Move) {
        if let Some((s, e)) = mv.abc_deg {
            if s != e {
                self.summary.rotary_used = true;
            }
        }
        self.curves.push(Programmed::new(&mv.path));
        self.lines.push(mv.line);
    }

    /// Steps until the motion is at rest after the last segment (and every event is
    /// applied), and returns the summary.
    fn finish(mut self) -> Summary {
        loop {
            if self.cycle >= self.max_cycles {
                break;
            }
            let r = self.step();
            let events_left = self.next_event < self.events.len();
            match r {
                StepResult::Moving => {}
                StepResult::Idle if !events_left => break,
                StepResult::Held if !events_left => break,
                _ => {}
            }
        }
        self.summary.cycles = self.cycle;
        self.summary.duration_s = self.cycle as f64 * self.period_s;
        self.summary.plan_failures = self.core.plan_failures();
        self.summary
    }
}
