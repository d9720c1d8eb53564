//! `kerf sim`: the whole pipeline in virtual time.
//!
//! The resolved moves go through the same [`kerf_plan::Planner`] and
//! [`kerf_motion::MotionCore`] the daemon runs, fed by the deterministic policy of
//! [`kerf_pipeline`] (push while the queue has room, step one period when it is full,
//! then step until rest), so a simulation reproduces the daemon's setpoints bit for bit.
//!
//! Output: one CSV row per period, `t,x,y,z` (then `a,b,c` when the program drives a rotary
//! axis), then `line,feed_mm_s`; t in s, positions in mm (degrees for rotary axes), from
//! t = 0 at the origin until the last move has come to rest. Floats are printed with
//! Rust's shortest round-trip formatting, so equal runs give equal bytes.
//!
//! Memory does not grow with the program. The first pass ([`Prepass`]) streams the moves
//! through the travel check and the same planner the run uses, and checks every planned
//! segment against the travel (blends and smoothed curves included); it also learns what
//! the CSV header needs (whether a rotary axis moves) and a row estimate for the progress
//! bar. A program whose moves and segments fit in 16 MiB is kept and run from memory
//! ([`simulate_kept`]); a longer one is read again and streamed into the run
//! ([`simulate_stream`]). Then three threads share the work: the planner
//! ([`kerf_pipeline::run_stream`]), the motion core with the measurements, and the
//! CSV formatting (a kept program needs no planner thread). The output is the same, byte
//! for byte, as with everything on one thread (the feeding policy depends only on the
//! order of the segments; tests compare the kept, the streamed and the one-thread runs).
//!
//! Every setpoint is checked against the limits it was planned for by a
//! [`LimitMonitor`] (finite differences at the period, 1 % margin plus a derived rounding
//! allowance): the first setpoint that breaks one stops the run with
//! [`SimError::Fault`]; the CSV then ends with that setpoint.

use kerf_geom::PerAxis;
use std::collections::VecDeque;
use std::fmt;
use std::io::{self, BufWriter, Write};

use kerf_config::machine_limits;
use kerf_geom::machine::Action;
use kerf_geom::{CornerMode, Move, Path, Vec3, line_distance};
use kerf_motion::monitor::{LimitMonitor, LimitViolation};
use kerf_motion::{MachineLimits, PlannedSegment, Setpoint};
use kerf_pipeline::{
    self as driver, ActionOrder, Input, OperatorEvent, Planned, RunError, RunOptions, Summary,
};
use kerf_plan::{PlanError, Planner};

use crate::sim_plot::{PlotOutput, PlotRecorder, RapidIndex};
use kerf_config::Config;
use kerf_config::travel::{self, PlannedTravelError, TravelError};

/// Options of a simulation.
#[derive(Clone, Debug, PartialEq)]
pub struct SimOptions {
    /// Feed override, 1.0 = 100 % (0–2).
    pub feed_override: f64,
    /// Motion queue capacity in segments (the daemon's default is 4,096).
    pub queue_capacity: usize,
    /// Events applied before the given cycle number (hold, resume, abort, override).
    pub events: Vec<(u64, OperatorEvent)>,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            feed_override: 1.0,
            queue_capacity: 4096,
            events: Vec::new(),
        }
    }
}

/// Peak velocity, acceleration and jerk of one axis as fractions of its limits, by finite
/// differences of the setpoints at the period, as [`LimitMonitor::peak_ratios`] measures
/// them (a run that succeeded never shows more than 1.01).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisReport {
    /// Axis name (`X` … `C`).
    pub axis: char,
    /// Peak |v| / velocity limit.
    pub velocity: f64,
    /// Peak |a| / acceleration limit.
    pub acceleration: f64,
    /// Peak |j| / jerk limit.
    pub jerk: f64,
}

/// What a simulation measured.
#[derive(Clone, Debug, PartialEq)]
pub struct SimSummary {
    /// Time from the start until rest, s.
    pub duration_s: f64,
    /// Rows written (including the one at t = 0).
    pub rows: u64,
    /// One entry per axis in the output (X, Y, Z, then used rotary axes).
    pub axes: Vec<AxisReport>,
    /// Largest distance of a setpoint from the programmed path, mm.
    pub max_deviation_mm: f64,
    /// `true` if the program drove a rotary axis (the CSV has `a,b,c`).
    pub rotary_used: bool,
    /// Motion-core profile calculations that needed a fallback (0 on a healthy run; the
    /// setpoints were checked against the limits all the same).
    pub plan_failures: u64,
    /// The actions a machine waits at (pauses, tool changes, the spindle, inputs) with
    /// their program times: the simulation stands for an operator who presses cycle
    /// start at once and a machine that is always ready, and does not wait.
    pub waits: Vec<(f64, Action)>,
    /// The raw measurements.
    pub raw: Summary,
}

impl fmt::Display for SimSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "duration {:.3} s", self.duration_s)?;
        for a in &self.axes {
            write!(
                f,
                "; {} v {:.0}% a {:.0}% j {:.0}%",
                a.axis,
                a.velocity * 100.0,
                a.acceleration * 100.0,
                a.jerk * 100.0
            )?;
        }
        write!(f, "; max deviation {:.4} mm", self.max_deviation_mm)?;
        if self.plan_failures > 0 {
            write!(f, "; {} profile fallbacks", self.plan_failures)?;
        }
        for (t_s, action) in &self.waits {
            write!(
                f,
                "; line {} at t = {t_s:.3} s: {}",
                action.line,
                assumed(action)
            )?;
        }
        Ok(())
    }
}

/// Why a simulation failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// A move could not be planned (unconfigured axis, non-finite value, zero feed).
    #[error("{0}")]
    Plan(#[from] RunError),
    /// Writing the CSV failed.
    #[error("writing the simulation output: {0}")]
    Io(#[from] io::Error),
    /// A setpoint broke a limit: the run stopped there (the CSV ends with it).
    #[error(
        "setpoint at t = {t_s} s (line {line}): {axis} {quantity} {percent:.0} % of the limit ({key} = {limit})",
        axis = kerf_geom::AXIS_NAMES[violation.axis],
        quantity = violation.quantity.name(),
        percent = violation.ratio() * 100.0,
        key = limit_key(violation),
        limit = violation.limit
    )]
    Fault {
        /// What broke.
        violation: LimitViolation,
        /// Time of the setpoint, s (as in the CSV).
        t_s: f64,
        /// Source line of the move being run.
        line: u32,
    },
    /// The program read in the second pass was not the one checked in the first (the file
    /// changed while it was simulated).
    #[error("the program changed while it was simulated")]
    Changed,
}

/// The configuration key of the limit a violation broke.
fn limit_key(v: &LimitViolation) -> &'static str {
    use kerf_motion::monitor::Quantity::*;
    match (v.axis < 3, v.quantity) {
        (true, Velocity) => "velocity_mm_s",
        (true, Acceleration) => "acceleration_mm_s2",
        (true, Jerk) => "jerk_mm_s3",
        (false, Velocity) => "velocity_deg_s",
        (false, Acceleration) => "acceleration_deg_s2",
        (false, Jerk) => "jerk_deg_s3",
    }
}

/// Why the first pass refused a program.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PrepassError {
    /// A programmed move leaves the travel.
    #[error("{0}")]
    Travel(#[from] TravelError),
    /// The planned path (a blend or a smoothed curve) leaves the travel.
    #[error("{0}")]
    PlannedTravel(#[from] PlannedTravelError),
    /// A move cannot be planned (unconfigured axis, non-finite value, zero feed).
    #[error("{0}")]
    Plan(#[from] PlanError),
}

impl PrepassError {
    /// The source line the error names, if any.
    pub fn line(&self) -> Option<u32> {
        match self {
            PrepassError::Travel(e) => Some(e.line),
            PrepassError::PlannedTravel(e) => Some(e.line),
            PrepassError::Plan(_) => None,
        }
    }
}

/// What the first pass learned about a program.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Scan {
    /// Moves in the program.
    pub moves: u64,
    /// `true` if a move drives a rotary axis (the CSV has `a,b,c`).
    pub rotary_used: bool,
    /// A rough motion time, s, for the progress bar only: every move at its programmed
    /// feed (rapids at the slowest linear axis's limit), without acceleration.
    pub estimated_s: f64,
    /// Where the program ends: X, Y, Z (mm) and A, B, C (degrees) of the last move's end
    /// (the origin for a program without motion). The run must end exactly there.
    pub end: PerAxis<f64>,
    /// `kerf run`: the check ended at this line, the first that reads `#5399` after an
    /// `M66` (what follows depends on the machine's input); `None`: the whole program.
    pub checked_to_line: Option<u32>,
}

impl Scan {
    /// `Err` with a message when a run that ended at rest at `position` did not reach the
    /// program's end (the motion stopped short: exit 0 must mean the program ran).
    pub fn check_end(&self, position: &PerAxis<f64>) -> Result<(), String> {
        let off = (0..6).any(|i| (position[i] - self.end[i]).abs() > 1e-9);
        if !off {
            return Ok(());
        }
        Err(format!(
            "the motion came to rest at X{} Y{} Z{}, not at the end of the program X{} Y{} Z{}",
            position[0], position[1], position[2], self.end[0], self.end[1], self.end[2]
        ))
    }
}

impl Scan {
    /// Counts the next move `m` (rapids at `rapid_mm_s` in the estimate).
    fn add_move(&mut self, m: &Move, rapid_mm_s: f64) {
        if let Some((s, e)) = m.abc_deg
            && s != e
        {
            self.rotary_used = true;
        }
        self.estimated_s += estimated_seconds(m, rapid_mm_s);
        self.moves += 1;
        let e = m.path.end();
        let end = &self.end;
        let abc = m.abc_deg.map_or([end[3], end[4], end[5]], |(_, b)| b);
        self.end = [e.x, e.y, e.z, abc[0], abc[1], abc[2]];
    }

    /// The rough number of CSV rows of [`Scan::estimated_s`].
    pub fn estimated_rows(&self, config: &Config) -> u64 {
        let rows = self.estimated_s / (f64::from(config.period_us) * 1e-6);
        if rows.is_finite() { rows as u64 } else { 0 }
    }
}

/// The moves and planned segments of a program small enough to keep between the passes.
#[derive(Debug)]
pub struct Kept {
    moves: Vec<Move>,
    segments: Vec<Planned>,
}

/// Bytes of moves and planned segments the first pass keeps at most for the run, so
/// that an ordinary program is read and planned only once (larger ones are streamed
/// again, so memory stays bounded).
const KEEP_BYTES: usize = 16 << 20;

/// What the first pass left: what it learned, and for a program whose moves and planned
/// segments fit in 16 MiB, those, so that the run ([`simulate_kept`]) need not read and
/// plan it again (the planner is deterministic: the segments are the ones the run would
/// plan). Larger programs are read again ([`simulate_stream`]).
#[derive(Debug)]
pub struct Checked {
    /// What the pass learned.
    pub scan: Scan,
    /// The program's moves and segments, when small enough.
    pub kept: Option<Kept>,
}

/// Moves remembered by the first pass for naming the line of a smoothed piece that leaves
/// the travel (a piece stands for at most a few thousand moves).
const RECENT_MOVES: usize = 1 << 16;

/// The first pass of `kerf sim`, fed one move at a time in program order: the travel of
/// every programmed move (exact), then of every segment the planner makes of them
/// ([`travel::check_segment`]; the planner is the one the run uses, with the same
/// limits and design override, and it is deterministic, so the run plans the same
/// segments). Memory is bounded: the planner holds back only what a blend or smoothing
/// window may still change, and the last 65,536 moves are kept to name lines.
pub struct Prepass {
    planner: Planner,
    axes: kerf_config::Axes,
    buf: Vec<PlannedSegment>,
    /// Line, start and end of the last moves, by program index.
    recent: VecDeque<(u32, Vec3, Vec3)>,
    /// Program index of `recent[0]`.
    recent_base: u64,
    rapid_mm_s: f64,
    scan: Scan,
    kept: Option<Kept>,
    /// Where the actions synchronised with the motion go among the kept segments.
    order: ActionOrder,
    /// The highest `move_index` of the planned segments checked so far (see
    /// [`Prepass::has_passed`]).
    checked_past: Option<u64>,
}

impl Prepass {
    /// A first pass for the machine of `config` with the run's `options`.
    pub fn new(config: &Config, options: &SimOptions) -> Self {
        let mut planner = Planner::new(machine_limits(config));
        planner.set_design_override(options.feed_override);
        let rapid_mm_s = slowest_linear_mm_s(config);
        Prepass {
            planner,
            axes: config.axes,
            buf: Vec::new(),
            recent: VecDeque::new(),
            recent_base: 0,
            rapid_mm_s,
            scan: Scan::default(),
            order: ActionOrder::new(),
            checked_past: None,
            kept: Some(Kept {
                moves: Vec::new(),
                segments: Vec::new(),
            }),
        }
    }

    /// Checks the next move and the segments planned so far.
    pub fn push(&mut self, m: &Move) -> Result<(), PrepassError> {
        travel::check_move(m, &self.axes)?;
        self.scan.add_move(m, self.rapid_mm_s);
        if self.recent.len() == RECENT_MOVES {
            self.recent.pop_front();
            self.recent_base += 1;
        }
        self.recent
            .push_back((m.line, m.path.start(), m.path.end()));
        self.planner.push(m, &mut self.buf)?;
        self.order.moved();
        if let Some(k) = self.kept.as_mut() {
            k.moves.push(*m);
        }
        self.check_planned()
    }

    /// One input of the program (see [`kerf_pipeline::ProgramActions`]): a move is
    /// checked; at an exact stop, a dwell or an action the machine waits for, the planner
    /// ends the path at rest here, as the run's will.
    pub fn input(&mut self, input: &Input) -> Result<(), PrepassError> {
        if let Input::Move(m) = input {
            return self.push(m);
        }
        if self.order.take_held(input) {
            return Ok(());
        }
        // The path ends at rest at a stop, a dwell or an action at rest.
        driver::plan_input(&mut self.planner, input, &mut self.buf)?;
        self.check_planned()?;
        if let Input::Dwell(seconds) = input {
            self.scan.estimated_s += seconds;
        }
        let mut after = Vec::new();
        self.order.after(input, &mut after);
        if let Some(k) = self.kept.as_mut() {
            k.segments.extend(after);
        }
        Ok(())
    }

    /// Checks the segments the planner still held, and returns what the pass learned.
    pub fn finish(mut self) -> Result<Checked, PrepassError> {
        self.planner.finish(&mut self.buf);
        self.check_planned()?;
        if let Some(k) = self.kept.as_mut() {
            k.segments.extend(self.order.release());
        }
        Ok(Checked {
            scan: self.scan,
            kept: self.kept,
        })
    }

    /// `true` once every planned segment that involves move `index` (0-based, in program
    /// order) has been checked: the planner emits segments in path order, and a segment
    /// involves its own `move_index` and later moves only (a corner blend carries the
    /// index of the move before the corner), so once a segment of move `index + 2` or
    /// later has been checked, so has every segment of move `index` and of the corner
    /// after it. [`QuickCheck`]'s caller plans up to here.
    pub fn has_passed(&self, index: u64) -> bool {
        self.checked_past.is_some_and(|i| i > index + 1)
    }

    fn check_planned(&mut self) -> Result<(), PrepassError> {
        if let Some(k) = self.kept.as_mut() {
            let known = self.scan.moves as usize;
            for s in &self.buf {
                k.segments.extend(self.order.before(s));
                k.segments.push(Planned::Segment(*s, known));
            }
            let bytes = k.moves.len() * size_of::<Move>() + k.segments.len() * size_of::<Planned>();
            if bytes > KEEP_BYTES {
                self.kept = None;
            }
        }
        for seg in self.buf.drain(..) {
            self.checked_past = Some(
                self.checked_past
                    .map_or(seg.move_index, |i| i.max(seg.move_index)),
            );
            if let Err(mut e) = travel::check_segment(&seg, &self.axes) {
                if seg.move_count > 1 {
                    // Name the move of the piece nearest to where it leaves the travel.
                    let from = seg.move_index.max(self.recent_base);
                    let to = (seg.move_index + u64::from(seg.move_count))
                        .min(self.recent_base + self.recent.len() as u64);
                    let nearest = (from..to)
                        .map(|k| {
                            let (line, a, b) = self.recent[(k - self.recent_base) as usize];
                            let d = b - a;
                            let len = d.norm();
                            let dir = if len > 0.0 { d / len } else { d };
                            (line_distance(&a, &b, &dir, len, &e.point), line)
                        })
                        .fold(
                            (f64::INFINITY, e.line),
                            |x, y| if y.0 < x.0 { y } else { x },
                        );
                    e.line = nearest.1;
                }
                return Err(e.into());
            }
        }
        Ok(())
    }
}

/// The velocity limit of the slowest linear axis, mm/s: the rapids' speed in the rough
/// estimate of [`Scan::estimated_s`].
fn slowest_linear_mm_s(config: &Config) -> f64 {
    config
        .axes
        .linear()
        .iter()
        .map(|a| a.velocity_mm_s)
        .fold(f64::INFINITY, f64::min)
}

/// The first half of `kerf run`'s check, at the speed of reading the program (no
/// planning): every move's exact path against the travel ([`travel::check_move`]), what
/// the planner would refuse ([`Planner::check`]), and how close the move comes to an
/// edge of the travel ([`travel::clearance_mm`]).
///
/// The planned path stays within the path tolerance of the moves it is made of (corner
/// blends and transitions within the tolerance of the corner, smoothed pieces within the
/// tolerance of the lines they replace), so the planned path of a move whose clearance
/// exceeds twice the tolerance that applies to it cannot leave the travel: it needs no
/// planning to be checked. The twice is a safety factor over the planner's sampled
/// deviation checks. The moves closer to an edge than that are the ones whose planned
/// path must be checked exactly: [`QuickCheck::last_near`] is the index of the last of
/// them, and the caller plans and checks the program ([`Prepass`]) up to where the
/// planned path has passed it ([`Prepass::has_passed`]); for the rest, this pass is
/// the check.
pub struct QuickCheck {
    axes: kerf_config::Axes,
    /// For [`Planner::check`] only (nothing is planned).
    planner: Planner,
    default_tolerance_mm: f64,
    /// The blending tolerance of the previous move (0 after an exact stop): a corner takes
    /// the smaller of its two moves' tolerances, but the arriving move's governs when
    /// the leaving move is in exact-stop mode, so the corner at a move's start may take
    /// the previous move's.
    previous_tolerance_mm: f64,
    rapid_mm_s: f64,
    scan: Scan,
    last_near: Option<(u64, u32)>,
    near_moves: u64,
}

impl QuickCheck {
    /// The quick check for the machine of `config`.
    pub fn new(config: &Config) -> Self {
        let limits = machine_limits(config);
        QuickCheck {
            axes: config.axes,
            default_tolerance_mm: limits.tolerance_mm,
            planner: Planner::new(limits),
            previous_tolerance_mm: 0.0,
            rapid_mm_s: slowest_linear_mm_s(config),
            scan: Scan::default(),
            last_near: None,
            near_moves: 0,
        }
    }

    /// Checks the next move of the program.
    pub fn push(&mut self, m: &Move) -> Result<(), PrepassError> {
        travel::check_move(m, &self.axes)?;
        self.planner.check(m)?;
        self.scan.add_move(m, self.rapid_mm_s);
        let own_mm = match m.corner {
            CornerMode::Blend { tolerance_mm, .. } => {
                tolerance_mm.unwrap_or(self.default_tolerance_mm)
            }
            CornerMode::ExactStop => 0.0,
        };
        let margin_mm = 2.0 * own_mm.max(self.previous_tolerance_mm);
        // A NaN tolerance or clearance counts as near.
        let clear = travel::clearance_mm(m, &self.axes)
            .partial_cmp(&margin_mm)
            .is_some_and(|o| o == std::cmp::Ordering::Greater);
        if !clear {
            // Its index in program order: the moves counted before it.
            self.last_near = Some((self.scan.moves - 1, m.line));
            self.near_moves += 1;
        }
        self.previous_tolerance_mm = own_mm;
        Ok(())
    }

    /// The index (0-based, in program order, as the planner counts moves) and line of the
    /// last move whose planned path must be checked exactly; `None` if there is none.
    pub fn last_near(&self) -> Option<(u64, u32)> {
        self.last_near
    }

    /// How many moves come near an edge of the travel.
    pub fn near_moves(&self) -> u64 {
        self.near_moves
    }

    /// What the pass learned.
    pub fn scan(&self) -> Scan {
        self.scan
    }
}

/// A move's length over its programmed feed (rapids: `rapid_mm_s`), s.
fn estimated_seconds(m: &Move, rapid_mm_s: f64) -> f64 {
    let length_mm = match &m.path {
        Path::Line(l) => (l.end - l.start).norm(),
        Path::Arc(a) => {
            let radius = (a.start - a.center).norm();
            let axial = (a.end - a.start).dot(&a.axis);
            (radius * a.sweep_rad).hypot(axial)
        }
    };
    let speed_mm_s = match m.feed_mm_min {
        Some(f) if !m.rapid && f > 0.0 => f / 60.0,
        _ => rapid_mm_s,
    };
    length_mm / speed_mm_s
}

/// Runs `moves` on the machine `limits`, calling `row(t, setpoint)` for every period from
/// t = 0. Use this to plot or check the motion without a CSV. Every setpoint is checked
/// against the limits (see [`LimitMonitor`]); the first that breaks one ends the run with
/// [`SimError::Fault`] after `row` has seen it.
pub fn simulate_with<F: FnMut(f64, &Setpoint)>(
    moves: &[Move],
    limits: &MachineLimits,
    options: &SimOptions,
    row: F,
) -> Result<SimSummary, SimError> {
    run_checked(
        Feed::Stream(moves.iter().copied().map(Input::Move)),
        limits,
        [0.0; 6],
        options,
        row,
    )
}

/// Where the run's segments come from.
enum Feed<I> {
    /// Moves, planned on a second thread.
    Stream(I),
    /// Moves and segments the first pass kept.
    Kept(Kept),
}

/// The run with its limit monitor; `scale` is the rounding scale of the positions per
/// axis (see [`LimitMonitor::with_position_scale`]).
fn run_checked<I, F>(
    feed: Feed<I>,
    limits: &MachineLimits,
    scale: PerAxis<f64>,
    options: &SimOptions,
    mut row: F,
) -> Result<SimSummary, SimError>
where
    I: Iterator<Item = Input> + Send,
    F: FnMut(f64, &Setpoint),
{
    let run_options = RunOptions {
        capacity: options.queue_capacity,
        feed_override: options.feed_override,
        events: options.events.clone(),
        max_cycles: u64::MAX,
    };
    // The machine is at rest at the origin before the first setpoint.
    let mut monitor = LimitMonitor::at_rest(limits, &[0.0; 6]).with_position_scale(scale);
    let mut sink = RowSink {
        row: &mut row,
        last: (0.0, 0),
        waits: Vec::new(),
    };
    let raw = match feed {
        Feed::Stream(moves) => {
            driver::run_stream(moves, limits, &run_options, Some(&mut monitor), &mut sink)
        }
        Feed::Kept(k) => driver::run_planned(
            &k.moves,
            k.segments,
            limits,
            &run_options,
            Some(&mut monitor),
            &mut sink,
        ),
    };
    let RowSink { last, waits, .. } = sink;
    let raw = match raw {
        Ok(raw) => raw,
        Err(RunError::Fault(violation)) => {
            return Err(SimError::Fault {
                violation,
                t_s: last.0,
                line: last.1,
            });
        }
        Err(e) => return Err(e.into()),
    };
    let mut axes = Vec::new();
    for i in 0..6 {
        if i >= 3 && !raw.rotary_used {
            break;
        }
        // The monitor's peaks: a run that passed never shows more than 101 %.
        if let Some(f) = monitor.peak_ratios(i) {
            axes.push(AxisReport {
                axis: kerf_geom::AXIS_NAMES[i],
                velocity: f[0],
                acceleration: f[1],
                jerk: f[2],
            });
        }
    }
    Ok(SimSummary {
        duration_s: raw.duration_s,
        rows: raw.cycles + 1,
        axes,
        max_deviation_mm: raw.max_deviation_mm,
        rotary_used: raw.rotary_used,
        plan_failures: raw.plan_failures,
        waits,
        raw,
    })
}

/// The sink of a simulation: the rows, the last row's time and line (to name a fault),
/// and the actions a machine would have waited at.
struct RowSink<'r, F> {
    row: &'r mut F,
    last: (f64, u32),
    waits: Vec<(f64, Action)>,
}

impl<F: FnMut(f64, &Setpoint)> driver::Sink for &mut RowSink<'_, F> {
    fn setpoint(&mut self, t_s: f64, sp: &Setpoint) {
        self.last = (t_s, sp.line);
        (self.row)(t_s, sp)
    }

    fn action(&mut self, t_s: f64, action: &Action) {
        if waits_on_the_machine(action) {
            self.waits.push((t_s, *action));
        }
    }
}

/// `true` for an action a machine waits at (a pause, a tool change, the spindle, an
/// input): the simulation does not wait, and says so.
fn waits_on_the_machine(action: &Action) -> bool {
    use kerf_geom::machine::ActionKind as K;
    matches!(
        action.kind,
        K::Pause(_)
            | K::ToolChange { .. }
            | K::WaitAtSpeed
            | K::Orient { .. }
            | K::WaitInput { .. }
    )
}

/// What the simulation assumed at an action a machine waits at.
fn assumed(action: &Action) -> String {
    use kerf_geom::machine::{ActionKind as K, PauseCode};
    match action.kind {
        K::Pause(PauseCode::ProgramStop) => "M0 pause, cycle start at once".to_string(),
        K::Pause(PauseCode::OptionalStop) => "M1 optional stop, cycle start at once".to_string(),
        K::Pause(PauseCode::PalletChange) => "M60 pause, cycle start at once".to_string(),
        K::Pause(PauseCode::SingleBlock) => "single block, cycle start at once".to_string(),
        K::ToolChange { tool } => format!("M6 T{tool}, changed at once"),
        K::WaitAtSpeed => "spindle at speed at once".to_string(),
        K::Orient { .. } => "M19 oriented at once".to_string(),
        K::WaitInput { input, .. } => format!("M66 input {input}, no wait"),
        _ => String::new(),
    }
}

/// Runs `moves` with the machine of `config` and writes the CSV to `out`.
pub fn simulate<W: Write + Send>(
    moves: &[Move],
    config: &Config,
    options: &SimOptions,
    out: W,
) -> Result<SimSummary, SimError> {
    simulate_and_plot(moves, config, options, out, None)
}

/// [`simulate`], and with `plot` also draws the toolpath, the feed, and each axis's
/// velocity, acceleration and jerk against its limits over time, as an SVG or PNG image
/// (for `kerf sim --plot FILE.svg|FILE.png`; see [`crate::sim_plot`]). The CSV is the same
/// with or without a plot.
pub(crate) fn simulate_and_plot<W: Write + Send>(
    moves: &[Move],
    config: &Config,
    options: &SimOptions,
    out: W,
    plot: Option<PlotOutput<'_>>,
) -> Result<SimSummary, SimError> {
    let rotary = moves.iter().any(|m| m.abc_deg.is_some_and(|(s, e)| s != e));
    simulate_stream(
        moves.iter().copied().map(Input::Move),
        rotary,
        config,
        options,
        out,
        plot,
    )
}

/// `simulate_and_plot` over a stream of moves (the second pass of `kerf sim`):
/// `rotary_used` (from the first pass, [`Scan::rotary_used`]) decides the CSV header.
/// Memory does not grow with the program, nor with the plot (it keeps at most 2,048
/// columns of time and a thinned toolpath, see [`crate::sim_plot`]).
pub fn simulate_stream<I, W>(
    moves: I,
    rotary_used: bool,
    config: &Config,
    options: &SimOptions,
    out: W,
    plot: Option<PlotOutput<'_>>,
) -> Result<SimSummary, SimError>
where
    I: Iterator<Item = Input> + Send,
    W: Write + Send,
{
    simulate_feed(Feed::Stream(moves), rotary_used, config, options, out, plot)
}

/// [`simulate_stream`] from what the first pass kept (the same setpoints, without reading
/// and planning the program again). `options` must be those the [`Prepass`] had.
pub fn simulate_kept<W: Write + Send>(
    kept: Kept,
    scan: &Scan,
    config: &Config,
    options: &SimOptions,
    out: W,
    plot: Option<PlotOutput<'_>>,
) -> Result<SimSummary, SimError> {
    let feed: Feed<std::iter::Empty<Input>> = Feed::Kept(kept);
    simulate_feed(feed, scan.rotary_used, config, options, out, plot)
}

fn simulate_feed<I, W>(
    feed: Feed<I>,
    rotary_used: bool,
    config: &Config,
    options: &SimOptions,
    out: W,
    plot: Option<PlotOutput<'_>>,
) -> Result<SimSummary, SimError>
where
    I: Iterator<Item = Input> + Send,
    W: Write + Send,
{
    let limits = machine_limits(config);
    let rotary = rotary_used;
    let mut scale = [0.0; 6];
    for (i, l) in config.axes.linear().iter().enumerate() {
        scale[i] = l.min_mm.abs().max(l.max_mm.abs());
    }
    for (i, r) in config.axes.rotary().iter().enumerate() {
        if let Some(r) = r {
            scale[3 + i] = r.min_deg.abs().max(r.max_deg.abs());
        }
    }
    // The plot learns which moves are rapids: from the kept moves, or from the stream as
    // the planner thread reads it (always before the moves' setpoints).
    let mut recorder = None;
    let feed = match feed {
        Feed::Kept(k) if plot.is_some() => {
            let mut rapids = RapidIndex::default();
            for m in &k.moves {
                rapids.push(m.rapid);
            }
            recorder = Some(PlotRecorder::new(&limits, rapids));
            Feed::Kept(k)
        }
        Feed::Stream(moves) if plot.is_some() => {
            let (flips, rx) = std::sync::mpsc::channel();
            let mut r = PlotRecorder::new(&limits, RapidIndex::default());
            r.flips_from(rx);
            recorder = Some(r);
            let mut rapids = RapidIndex::default();
            let watched: Box<dyn Iterator<Item = Input> + Send + '_> =
                Box::new(moves.inspect(move |i| {
                    if let Input::Move(m) = i
                        && let Some(at) = rapids.next_flip(m.rapid)
                    {
                        // The recorder outlives the run: a send cannot fail before it ends.
                        let _ = flips.send(at);
                    }
                }));
            Feed::Stream(watched)
        }
        Feed::Stream(moves) => {
            let moves: Box<dyn Iterator<Item = Input> + Send + '_> = Box::new(moves);
            Feed::Stream(moves)
        }
        Feed::Kept(k) => Feed::Kept(k),
    };
    // The rows are formatted and written on a second thread, in chunks: at a 1 ms period
    // the text is a large share of a simulation's work.
    let (tx, rx) = std::sync::mpsc::sync_channel::<Vec<(f64, Setpoint)>>(4);
    let (summary, written) = std::thread::scope(|scope| {
        let writer = scope.spawn(move || -> io::Result<()> {
            let mut w = BufWriter::new(out);
            writeln!(w, "{}", csv_header(rotary))?;
            for chunk in rx {
                for (t, sp) in &chunk {
                    write_row(&mut w, *t, sp, rotary)?;
                }
            }
            w.flush()
        });
        let mut chunk = Vec::with_capacity(ROWS_PER_CHUNK);
        let mut writer_gone = false;
        let summary = run_checked(feed, &limits, scale, options, |t, sp| {
            chunk.push((t, *sp));
            if chunk.len() == ROWS_PER_CHUNK && !writer_gone {
                let full = std::mem::replace(&mut chunk, Vec::with_capacity(ROWS_PER_CHUNK));
                // A send fails only when the writer stopped on an I/O error (reported below).
                writer_gone = tx.send(full).is_err();
            } else if chunk.len() == ROWS_PER_CHUNK {
                chunk.clear();
            }
            if let Some(r) = recorder.as_mut() {
                r.push(sp);
            }
        });
        // The rows up to a fault are written too: the CSV ends with the offending setpoint.
        if !writer_gone && !chunk.is_empty() {
            let _ = tx.send(chunk);
        }
        drop(tx);
        let written = writer
            .join()
            .unwrap_or_else(|_| Err(io::Error::other("the CSV writer panicked")));
        (summary, written)
    });
    written?;
    let summary = summary?;
    if let (Some(plot), Some(r)) = (plot, recorder) {
        r.write(plot.format, &plot.title, plot.out)?;
    }
    Ok(summary)
}

/// Rows per chunk handed to the CSV writer thread.
const ROWS_PER_CHUNK: usize = 4096;

/// Writes one CSV row. Floats use the shortest round-trip form of the `zmij` crate (as
/// `kerf plan` does), which is several times faster than `Display` and matters here: at a
/// 1 ms period the rows are most of a simulation's work.
/// The header line of the setpoint CSV (`kerf sim`, `kerf run --record`, `kerf record`).
pub fn csv_header(rotary: bool) -> &'static str {
    if rotary {
        "t,x,y,z,a,b,c,line,feed_mm_s"
    } else {
        "t,x,y,z,line,feed_mm_s"
    }
}

/// One row of the setpoint CSV: `t`, the positions (A, B, C with `rotary`), the line and
/// the path feed, each number in its shortest exact form.
pub fn write_row<W: Write>(w: &mut W, t: f64, sp: &Setpoint, rotary: bool) -> io::Result<()> {
    let mut floats = zmij::Buffer::new();
    let mut ints = itoa::Buffer::new();
    let p = &sp.position;
    let used = if rotary { 6 } else { 3 };
    w.write_all(floats.format(t).as_bytes())?;
    for v in &p[..used] {
        w.write_all(b",")?;
        w.write_all(floats.format(*v).as_bytes())?;
    }
    w.write_all(b",")?;
    w.write_all(ints.format(sp.line).as_bytes())?;
    w.write_all(b",")?;
    w.write_all(floats.format(sp.feed_mm_s).as_bytes())?;
    w.write_all(b"\n")
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerf_geom::machine::Sync;
    use kerf_geom::{Arc, CornerMode, Line, Path, Vec3};

    #[test]
    fn messages_and_log_calls_do_not_stop_the_motion() {
        for code in [
            kerf_gcode::EventCode::Msg,
            kerf_gcode::EventCode::Debug,
            kerf_gcode::EventCode::Print,
            kerf_gcode::EventCode::Log,
        ] {
            let mut e = kerf_gcode::Event::new(3, code, None);
            e.text = Some("LOGOPEN,results.txt".into());
            assert_eq!(kerfd::worker::input_of_event(&e), None, "{code:?}");
        }
        // A program stop is an action at rest: the path ends there.
        let m0 = kerf_gcode::Event::new(4, kerf_gcode::EventCode::M0, None);
        match kerfd::worker::input_of_event(&m0) {
            Some(Input::Action(a)) => assert_eq!(a.sync(), Sync::AtRest),
            other => panic!("M0 became {other:?}"),
        }
    }

    fn program() -> Vec<Move> {
        let a = Vec3::zeros();
        let b = Vec3::new(10.0, 0.0, 0.0);
        let line = Move {
            line: 1,
            rapid: false,
            path: Path::Line(Line { start: a, end: b }),
            feed_mm_min: Some(3000.0),
            abc_deg: None,
            corner: CornerMode::Blend {
                tolerance_mm: None,
                naive_cam_mm: None,
            },
        };
        // A half circle back towards the start, tangent to the line.
        let arc = Move {
            line: 2,
            rapid: false,
            path: Path::Arc(Arc {
                start: b,
                end: Vec3::new(10.0, 10.0, 0.0),
                center: Vec3::new(10.0, 5.0, 0.0),
                axis: Vec3::z(),
                sweep_rad: std::f64::consts::PI,
            }),
            feed_mm_min: Some(3000.0),
            abc_deg: None,
            corner: CornerMode::Blend {
                tolerance_mm: None,
                naive_cam_mm: None,
            },
        };
        vec![line, arc]
    }

    #[test]
    fn csv_starts_at_the_origin_and_is_deterministic() {
        let config = Config::builtin();
        let mut first = Vec::new();
        let mut svg = Vec::new();
        let summary = simulate_and_plot(
            &program(),
            &config,
            &SimOptions::default(),
            &mut first,
            Some(PlotOutput {
                format: crate::sim_plot::PlotFormat::Svg,
                out: &mut svg,
                title: "program".to_string(),
            }),
        )
        .unwrap();
        let mut second = Vec::new();
        simulate(&program(), &config, &SimOptions::default(), &mut second).unwrap();
        let svg = String::from_utf8(svg).unwrap();
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        assert_eq!(first, second);
        let text = String::from_utf8(first).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("t,x,y,z,line,feed_mm_s"));
        assert_eq!(lines.next(), Some("0.0,0.0,0.0,0.0,0,0.0"));
        let last = text.lines().last().unwrap();
        assert!(last.ends_with(",10.0,10.0,0.0,2,0.0"), "{last}");
        assert_eq!(summary.rows as usize, text.lines().count() - 1);
        assert_eq!(summary.axes.len(), 3);
        for a in &summary.axes {
            assert!(a.velocity <= 1.01 && a.acceleration <= 1.01 && a.jerk <= 1.01);
        }
        assert!(summary.max_deviation_mm <= config.tolerance_mm);
    }

    /// A dense rounded polyline (smoothed), a few corners and an arc, as G-code moves.
    fn mixed_program() -> Vec<Input> {
        let mut text = String::from("G21 G90 G17 G64 F3000\n");
        for k in 1..=400 {
            let a = k as f64 * 0.01;
            text += &format!("G1 X{:.3} Y{:.3}\n", 20.0 * a.sin(), 20.0 * (1.0 - a.cos()));
        }
        text += "G1 X0 Y30\nG4 P0.25\nG3 X-10 Y20 I0 J-10\nM5\nG1 X-10 Y0 Z-2\nG0 X0 Y0 Z0\nM2\n";
        kerf_gcode::Interpreter::new(
            text.as_bytes(),
            kerf_gcode::Dialect::LinuxCnc,
            Config::builtin().settings(),
        )
        .filter_map(|item| match item.unwrap() {
            kerf_gcode::Item::Move(m) => Some(Input::Move(m)),
            kerf_gcode::Item::Event(e) => kerfd::worker::input_of_event(&e),
        })
        .collect()
    }

    fn mixed_moves() -> Vec<Move> {
        mixed_program()
            .into_iter()
            .filter_map(|i| match i {
                Input::Move(m) => Some(m),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn a_run_that_stops_short_of_the_program_end_is_not_a_success() {
        let config = Config::builtin();
        let mut pre = Prepass::new(&config, &SimOptions::default());
        for m in mixed_moves() {
            pre.push(&m).unwrap();
        }
        let scan = pre.finish().unwrap().scan;
        // The mixed program returns to the origin with a rapid.
        assert_eq!(scan.end, [0.0; 6]);
        assert!(scan.check_end(&[0.0; 6]).is_ok());
        let e = scan
            .check_end(&[0.0, 30.0, 0.0, 0.0, 0.0, 0.0])
            .unwrap_err();
        assert!(
            e.contains("X0 Y30 Z0") && e.contains("end of the program X0 Y0 Z0"),
            "{e}"
        );
        assert!(scan.check_end(&[0.0, 0.0, 0.0, 1e-6, 0.0, 0.0]).is_err());
        // A program without motion ends where it starts.
        assert!(Scan::default().check_end(&[0.0; 6]).is_ok());
    }

    #[test]
    fn the_kept_first_pass_and_the_streamed_second_pass_write_the_same_csv() {
        let config = Config::builtin();
        let options = SimOptions::default();
        let inputs = mixed_program();
        let mut pre = Prepass::new(&config, &options);
        for i in &inputs {
            pre.input(i).unwrap();
        }
        let checked = pre.finish().unwrap();
        assert_eq!(checked.scan.moves, mixed_moves().len() as u64);
        assert!(!checked.scan.rotary_used);
        let kept = checked.kept.expect("a small program is kept");
        let mut a = Vec::new();
        let sa = simulate_kept(kept, &checked.scan, &config, &options, &mut a, None).unwrap();
        let mut b = Vec::new();
        let sb = simulate_stream(
            inputs.iter().copied(),
            false,
            &config,
            &options,
            &mut b,
            None,
        )
        .unwrap();
        assert_eq!(a, b);
        assert_eq!(sa, sb);
        assert!(sa.rows > 1000);
        // The dwell is in both: 250 rows at rest at (0, 30).
        let text = String::from_utf8(a).unwrap();
        let at_rest = text
            .lines()
            .filter(|l| l.split(',').skip(1).take(2).eq(["0.0", "30.0"]))
            .count();
        assert!((250..=252).contains(&at_rest), "{at_rest}");
    }

    #[test]
    fn a_program_beyond_the_keep_budget_is_not_kept() {
        // Long lines with stops in between: one segment per move.
        let config = Config::builtin();
        let per_move = size_of::<Move>() + size_of::<Planned>();
        let n = KEEP_BYTES / per_move + 10;
        let mut pre = Prepass::new(&config, &SimOptions::default());
        let mut m = mixed_moves()[0];
        m.corner = CornerMode::ExactStop;
        for k in 0..n {
            let (x0, x1) = if k % 2 == 0 { (0.0, 5.0) } else { (5.0, 0.0) };
            m.path = Path::Line(Line {
                start: Vec3::new(x0, 0.0, 0.0),
                end: Vec3::new(x1, 0.0, 0.0),
            });
            m.line = k as u32 + 1;
            pre.push(&m).unwrap();
        }
        let checked = pre.finish().unwrap();
        assert_eq!(checked.scan.moves, n as u64);
        assert!(checked.kept.is_none());
        // Every move is 5 mm at F3000 (0.1 s): the estimate counts them all.
        let expected_s = n as f64 * 5.0 / 50.0;
        assert!((checked.scan.estimated_s - expected_s).abs() < 1e-6 * expected_s);
    }
}
