//! Segment and junction limits and corner blending for Kerf.
//!
//! [`Planner`] turns the front end's [`Move`]s, in program order, into [`PlannedSegment`]s
//! for the motion core. It runs off the real-time path and may allocate (it does not, per
//! move, beyond its output). Its job is everything about a segment that does not depend on
//! time: geometry, corner blends, and the kinematic limits along and between segments.
//!
//! Design decisions:
//! - **Corner blends between two lines are circular arcs** (isolated corners: G2 blends
//!   or a stop where quicker, below), tangent to both, as large as the tolerance allows and
//!   taking at most half of the outgoing move (and at most what the previous blend left of
//!   the incoming move). Dense polylines are smoothed instead (below). Joints touching an
//!   arc get G2 transitions (below).
//!   The deviation of a circular blend from the two lines is `r (1 - cos(θ/2))` at its
//!   midpoint (θ = turn angle), which is what the tolerance bounds.
//! - **Per-segment limits** `(v, a, j)` along the path are chosen so that the worst case
//!   over the segment stays within every axis limit: the tangent projection on lines, and on
//!   arcs/helices the centripetal acceleration `κv²` and the jerk terms `σ²v³` and `3κva`
//!   (σ = swept angle per mm), each taken at its worst sign and phase. They are constant
//!   per segment, which is conservative but cheap and makes the lookahead closed-form.
//!   On curved segments the budget depends on the speed: `(a, j)` are worked out (in closed
//!   form for arcs in any plane, by bisection for helices in tilted planes) at a design
//!   speed, chosen among all speeds up to the programmed feed (or the curvature limit if
//!   lower) for the least rough time from rest to rest (cruise plus one jerk-limited ramp)
//!   over the distance the speed is held: for a programmed arc the path that runs on
//!   without a corner (tangent-continuous, no exact stop) up to its end, at most
//!   [`DESIGN_RUN_MM`]; for a smoothed piece the path that runs on without a corner
//!   through it to the end of its run, at least the whole run, at most `DESIGN_RUN_MM`
//!   (the smoother emits nothing of a run before that much of it is known); for a blend
//!   or transition its own length. These distances are geometry only, never the limits. At each design speed the tangential acceleration
//!   is the one that makes that ramp quickest given the jerk the axes leave at it (the
//!   normal jerk `3κva` grows with it), never a share of the axis limit and never more than
//!   the ramp can use, `sqrt(v·j)`. Both choices are minima over sets that only grow when
//!   an axis limit is raised, so raising one never lowers the design by that measure.
//!   (Issue 7: the tangential acceleration used to be tried as fractions of the axis
//!   limit; with a large acceleration and a small jerk every fraction left no jerk, and a
//!   circle at F600 with jerk 1,000 mm/s³ took 503 s at 200,000 mm/s² instead of 7.2 s.)
//!   `v_max_mm_s` is that design speed. For a feed
//!   override above 100 %, arcs and transitions carry a second design for the highest
//!   override (`v_boost_mm_s`, `accel_boost_mm_s2`, `jerk_boost_mm_s3`, where that gains at least 10 %
//!   speed), which the motion core switches to while the override asks for more than
//!   `v_max_mm_s`; [`Planner::set_design_override`] moves the first design to the override in
//!   force when the segments are planned (`kerf sim --override` passes its factor).
//!   Smoothed pieces keep the programmed feed: boosted, their limits vary with the
//!   direction and split the motion core's sections.
//!   Only [`PROFILE_SHARE`] of each axis limit is used by the path profile; the rest is left
//!   for the junctions.
//! - **G2 transitions at joints with arcs.** A tangent line→arc, arc→line or arc→arc joint
//!   is a curvature step, which at speed v is an acceleration step `v²Δκ`; left alone its
//!   cap `sqrt(JUNCTION_SHARE·J·T/Δκ)` is low (≈3.5 mm/s for r = 5 mm, J = 50,000 mm/s³,
//!   T = 1 ms). Where a programmed arc meets another move in blend mode and the joint caps
//!   the speed (curvature step or kink), the incoming segment is trimmed by `d_a` and the
//!   outgoing by `d_b` (at most [`TRANSITION_SHARE_OF_MOVE`] of each, leaving at least
//!   [`MIN_REMNANT_MM`]) and a quintic
//!   [`kerf_geom::Transition`] is inserted that matches position, unit tangent and
//!   curvature vector at both ends. Its distance from the two programmed moves is sampled
//!   ([`DEVIATION_SAMPLES`] points, at most [`TRANSITION_TOL_SHARE`] of the tolerance);
//!   `d` starts above the estimate `Δκ(2d)²/24 ≈ tol` and shrinks until it holds. The
//!   transition is kept only if it makes the joint faster and, if it runs below a quarter
//!   of the neighbours' speed, takes at most 20 ms (crawling round a sharp kink at a tiny
//!   tolerance is slower than stopping at it); otherwise the joint is taken at its cap as
//!   before. Rotary motion on either side, exact stops and joints between two lines are
//!   left alone. A transition makes [`PlannedSegment`] a few hundred bytes larger (the
//!   curve carries its arc-length table inline).
//!   Its limits come from sampled per-axis bounds of `|t_i|`, `|K_i|` and `|K'_i|`
//!   (curvature vector and its arc-length derivative, ×[`LIMIT_SAFETY`]): with arc-length
//!   parametrisation `x_i'' = t_i a + K_i v²` and `x_i''' = t_i j + 3K_i v a + K'_i v³`.
//!   Example: r = 5 mm, 0.01 mm tolerance, F3000 on a 2,000 mm/s², 50,000 mm/s³ mill: the
//!   joints run at the full 50 mm/s instead of 3.5 mm/s.
//! - **Dense polylines are smoothed** (module `smooth`): runs of short feed lines with small
//!   turns (CAM output approximating a curve) become curvature-continuous quintic pieces
//!   through vertices of the polyline, with tangents and curvatures fitted over a window of
//!   vertices, each piece checked to stay within the tolerance of the lines it replaces.
//!   Rounded vertices then no longer turn into curvature noise: the 3,600-line circle of
//!   radius 10 mm runs in the same time with 3, 4 or 12 decimals. A piece stands for
//!   several moves (`move_count`).
//! - **G2 blends at isolated line-line corners.** A circular corner blend makes its two
//!   joints curvature steps, capped at `sqrt(JUNCTION_SHARE·J·T·r)` (≈0.29 mm/s for a 90°
//!   corner at 0.01 mm on the mill above). Where the corner is *isolated* (the blend
//!   leaves at least [`MIN_REMNANT_MM`] of the incoming line after the previous blend and
//!   takes less than half of the outgoing one, so the neighbouring blends cannot meet) a
//!   symmetric quintic [`kerf_geom::Transition`] from `corner - u1·d` to `corner + u2·d`
//!   with zero curvature at both ends is tried instead: its joints with the lines are
//!   continuous in tangent and curvature, so only its own limits (from
//!   [`segment_limits`], as for transitions) bound the speed. The shape scales with `d`,
//!   so for each parameter scale of [`G2_LAMBDA_RATIOS`] × chord the deviation at
//!   `d` = 1 mm ([`DEVIATION_SAMPLES`] points, distance to the two lines) gives the largest
//!   `d` within [`TRANSITION_TOL_SHARE`] of the tolerance, confirmed on the real lines.
//!   The candidate (or the arc) with the smallest rough corner time wins (the lines'
//!   speed in it is at most what a ramp from rest reaches over the shorter line, so that a
//!   raised velocity limit does not make a corner between short lines look like one
//!   approached at full speed): slow-down to the
//!   corner speed and back with the lines' limits, plus the transit of the blend (the arc
//!   entered at its step cap and speeding up inside). The time, not the blend's `v_max`,
//!   decides because a longer blend with a higher `v_max` can take longer to cross: at
//!   0.05 mm the fastest G2 candidate (5.3 mm/s over 0.54 mm) lost to the arc. Measured on
//!   a 20 mm square at F3000: 90° corners at 0.01 mm are passed at 1.8 instead of
//!   0.29 mm/s; single corners at 0.01 mm: 20° at 9.8 instead of 1.3 mm/s, 10° at 19.5
//!   instead of 3.2 mm/s (0.05 mm: 10° at the full 50 mm/s). A 90° corner at 0.01 mm stays
//!   dominated by the slow-down it needs at any blend (the jerk-limited ceiling is about
//!   5 mm/s), so an exact stop there is still a little quicker than either blend.
//!   Corners whose blends use up the lines (coarse polygons that are not smoothed) keep
//!   circular arcs. Rotary motion and exact stops are left alone as for arcs.
//! - **A corner takes the smaller tolerance of its two moves**, as in LinuxCNC's `tp`:
//!   every decision at the junction of two moves (circular or G2 blend, G2 transition,
//!   whether a smoothed run ends on the next move's tangent or a run continues the frame
//!   of the move before it) uses `min(tol_i, tol_{i+1})`, so `G64 P1` before a
//!   `G64 P0.01` move does not cut that move's start by more than 0.01 mm. Smoothed runs
//!   never span a change of tolerance (their moves share one). An **exact stop belongs to
//!   the move that ends at the corner**: G61 (or G9) on the arriving move stops there; a
//!   move in exact-stop mode leaving a blended corner adds no tolerance of its own, so the
//!   arriving move's governs. This is what LinuxCNC's `tp` does (the arriving segment's
//!   terminal condition) and what the non-modal G9/G09 of the other controls needs (an
//!   exact stop at the end of that one block, not also at its start).
//! - **Junction caps**: a tangent kink of Δt at speed v is a velocity step `vΔt`; a curvature
//!   jump Δκ is an acceleration step `v²Δκ`. Sampled at the period T, these look like a jerk
//!   of `vΔt/T²` and `v²Δκ/T`, so the speed at the junction is capped to keep them within
//!   [`JUNCTION_SHARE`] of the jerk limit. An exact-stop corner has cap 0.
#![deny(missing_docs)]

use kerf_geom::{CornerMode, Curve, Move, Path, Transition, Vec3, rotary_derivatives};

// The planner's input and output types live in kerf-geom (the motion core reads them
// too); re-exported here because they are this crate's API.
pub use kerf_geom::{AXIS_NAMES, AxisLimits, MachineLimits, PlannedSegment};

mod smooth;

/// Highest feed override curved segments are designed for (the motion core's highest).
pub const MAX_DESIGN_OVERRIDE: f64 = 2.0;
/// Share of every axis limit that the path profile may use.
pub const PROFILE_SHARE: f64 = 0.95;
/// Share of every axis jerk limit left for the steps at junctions.
pub const JUNCTION_SHARE: f64 = 0.05;
/// Share of the acceleration (and jerk) budget that centripetal terms may take on curves.
const CENTRIPETAL_SHARE: f64 = 0.75;
/// Segments shorter than this are dropped (they cannot be seen in the output), mm.
pub const MIN_SEGMENT_MM: f64 = 1e-9;
/// Turn angles below this are treated as collinear (no blend needed), radians.
const COLLINEAR_RAD: f64 = 1e-7;
/// Share of the tolerance a G2 transition may deviate from the programmed path at the
/// sampled points (the rest covers the path between samples).
pub const TRANSITION_TOL_SHARE: f64 = 0.9;
/// Samples of a transition checked against the tolerance.
pub const DEVIATION_SAMPLES: usize = 128;
/// Factor by which the transition length shrinks per try.
const TRANSITION_SHRINK: f64 = 0.85;
/// Tries before a joint is left without a transition.
const TRANSITION_TRIES: usize = 48;
/// Largest share of a neighbouring segment a transition may take.
pub const TRANSITION_SHARE_OF_MOVE: f64 = 0.45;
/// Shortest piece of a segment a transition may leave, mm.
pub const MIN_REMNANT_MM: f64 = 1e-3;
/// Longest time a transition slower than a quarter of the neighbours' speed may take, s.
const MAX_CRAWL_S: f64 = 0.02;
/// Samples of a transition for its curvature bounds.
const LIMIT_SAMPLES: usize = 128;
/// Samples for the curvature bounds of a smoothed piece that covers several moves: such
/// pieces are gentle (their curvature follows a fitted window, not a corner).
const PIECE_LIMIT_SAMPLES: usize = 64;
/// Safety factor on the sampled curvature bounds of a transition.
pub const LIMIT_SAFETY: f64 = 1.1;
/// Safety factor on the sampled curvature of a transition. The curvature itself is
/// sampled directly (its derivative by finite differences, hence the larger
/// [`LIMIT_SAFETY`]); between samples of a smooth quintic it cannot rise by more than a
/// fraction of a per cent.
pub const CURVATURE_SAFETY: f64 = 1.02;
/// Parameter scales tried for a G2 corner blend, as multiples of its chord (measured: 1.2
/// is quickest for 90°, 1.0 for shallow turns, the larger ones for reversals).
pub const G2_LAMBDA_RATIOS: [f64; 3] = [1.0, 1.2, 1.5];

/// Why a move cannot be planned.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum PlanError {
    /// The move drives an axis the machine does not have.
    AxisNotConfigured {
        /// Source line.
        line: u32,
        /// Axis name.
        axis: char,
    },
    /// The move contains a non-finite coordinate or feed.
    NotFinite {
        /// Source line.
        line: u32,
    },
    /// A feed move with zero or negative feed.
    ZeroFeed {
        /// Source line.
        line: u32,
    },
}

impl std::fmt::Display for PlanError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PlanError::AxisNotConfigured { line, axis } => {
                write!(f, "line {line}: axis {axis} is not configured")
            }
            PlanError::NotFinite { line } => write!(f, "line {line}: non-finite coordinate"),
            PlanError::ZeroFeed { line } => write!(f, "line {line}: feed move with zero feed"),
        }
    }
}

impl std::error::Error for PlanError {}

/// The move currently waiting for its successor (its end may still be blended).
#[derive(Clone, Copy, Debug)]
struct Pending {
    mv: Move,
    move_index: u64,
    /// Start point after the previous blend trimmed it.
    start: Vec3,
    /// How much the previous blend trimmed from the start, mm.
    start_trim: f64,
    abc_start: [f64; 3],
    abc_end: [f64; 3],
}

/// Streaming path preparation: moves in, planned segments out (one move of delay, since a
/// corner can only be blended once both sides are known).
#[derive(Debug)]
pub struct Planner {
    limits: MachineLimits,
    pending: Option<Pending>,
    /// The last produced segment, held back until its end junction cap is known.
    last: Option<PlannedSegment>,
    /// Corner mode at the end of `last`.
    last_corner: CornerMode,
    /// The programmed path `last` was cut from (`None` for corner blends).
    last_origin: Option<Curve>,
    /// Length of `last` before a transition trimmed its start, path units.
    last_full_length: f64,
    next_index: u64,
    abc_current: [f64; 3],
    /// The dense-polyline run being collected, if any.
    run: Option<RunState>,
    /// Scratch for smoothed pieces (kept to reuse its allocation).
    pieces: Vec<smooth::Emitted>,
    /// Feed override the curved segments are designed for (see
    /// [`Planner::set_design_override`]).
    design_override: f64,
    /// Length of the path that runs on without a corner (tangent-continuous, no exact
    /// stop) up to the end of `last`, mm.
    chain_mm: f64,
    /// The run the next programmed arc or smoothed piece is designed for (see
    /// [`segment_limits`]), mm; 0 for every other segment.
    run_mm: f64,
}

/// A run of lines that may be smoothed (see [`smooth`]).
#[derive(Debug)]
struct RunState {
    run: smooth::Run,
    /// The moves, kept until the run is long enough to be smoothed (then it commits and
    /// they are dropped); a shorter run goes through corner blending after all.
    buffered: Vec<Pending>,
    committed: bool,
    /// The last move of the run.
    last: Pending,
    /// Tolerance, mm.
    tol: f64,
    /// The programmed tolerance (`None`: the configured one), which members must share.
    tol_mm: Option<f64>,
}

impl RunState {
    /// The tolerance of the run `p` would start, if it may start one.
    fn starts(p: &Pending, limits: &MachineLimits) -> Option<f64> {
        let CornerMode::Blend { tolerance_mm } = p.mv.corner else {
            return None;
        };
        let tol = tolerance_mm.unwrap_or(limits.tolerance_mm);
        (tol > 0.0 && tol.is_finite() && smoothable(p)).then_some(tol)
    }

    fn new(p: Pending, tol: f64, start_frame: Option<smooth::EndFrame>) -> RunState {
        let CornerMode::Blend { tolerance_mm } = p.mv.corner else {
            unreachable!("checked by RunState::starts")
        };
        let mut run = smooth::Run::new(p.mv.path.start(), p.abc_start, start_frame, tol);
        run.push(
            p.mv.path.end(),
            p.abc_end,
            p.mv.line,
            p.move_index,
            feed_of(&p.mv),
        );
        RunState {
            run,
            buffered: vec![p],
            committed: false,
            last: p,
            tol,
            tol_mm: tolerance_mm,
        }
    }

    /// Whether `p` continues the run: every member has the run's tolerance, at both of its
    /// ends (a move under another tolerance starts a run of its own, so a coarse run
    /// never smooths a fine move).
    fn joins(&self, p: &Pending) -> bool {
        let mode = CornerMode::Blend {
            tolerance_mm: self.tol_mm,
        };
        if self.last.mv.corner != mode
            || p.mv.corner != mode
            || !smoothable(p)
            || p.abc_start != self.run.end_abc()
            || (p.mv.path.start() - self.run.end()).norm() > MIN_SEGMENT_MM
        {
            return false;
        }
        let Some(d) = self.run.last_dir() else {
            return false;
        };
        let len = self.run.last_len().max(line_len(p));
        turn_fits(d, line_dir(p), len, self.tol)
            && rotary_turn_fits(self.run.last_abc_rate(), abc_rate(p), len, self.tol)
    }

    fn add(&mut self, p: Pending) {
        self.run.push(
            p.mv.path.end(),
            p.abc_end,
            p.mv.line,
            p.move_index,
            feed_of(&p.mv),
        );
        if !self.committed {
            self.buffered.push(p);
        }
        self.last = p;
    }
}

/// A feed line short enough for a run (it may move rotary axes along, but not only them).
fn smoothable(p: &Pending) -> bool {
    !p.mv.rapid
        && matches!(p.mv.path, Path::Line(_))
        && (1e-6..=smooth::MAX_SEGMENT_MM).contains(&line_len(p))
}

/// Rate of A, B, C along the XYZ length of a line, degrees per mm.
fn abc_rate(p: &Pending) -> [f64; 3] {
    let len = line_len(p);
    std::array::from_fn(|i| (p.abc_end[i] - p.abc_start[i]) / len)
}

/// Whether a change of rotary rate from `a` to `b` (degrees per mm) at a vertex next to a
/// segment of length `len` may lie inside a smoothed run: a smooth A(s) through the
/// vertices sags `len·Δ(dA/ds)/8` from the programmed linear interpolation, which must be
/// within [`smooth::SAG_TOL_SHARE`] of the tolerance (the same number, in degrees).
fn rotary_turn_fits(a: [f64; 3], b: [f64; 3], len: f64, tol: f64) -> bool {
    (0..3).all(|i| len * (b[i] - a[i]).abs() / 8.0 <= smooth::SAG_TOL_SHARE * tol)
}

fn line_len(p: &Pending) -> f64 {
    (p.mv.path.end() - p.mv.path.start()).norm()
}

fn line_dir(p: &Pending) -> Vec3 {
    (p.mv.path.end() - p.mv.path.start()).normalize()
}

/// Whether a turn from direction `a` to `b` at a vertex next to a segment of length `len`
/// may lie inside a smoothed run: at most [`smooth::MAX_TURN_RAD`], with a sag `len·θ/8`
/// within [`smooth::SAG_TOL_SHARE`] of the tolerance.
fn turn_fits(a: Vec3, b: Vec3, len: f64, tol: f64) -> bool {
    let theta = a.dot(&b).clamp(-1.0, 1.0).acos();
    theta <= smooth::MAX_TURN_RAD && len * theta / 8.0 <= smooth::SAG_TOL_SHARE * tol
}

/// The tolerance of the corner where a move in mode `arriving` meets one in mode
/// `leaving`, mm: the smaller of the two moves' tolerances (LinuxCNC's `tp` takes the
/// minimum too), `None` for an exact stop. An exact stop belongs to the move that ends
/// at the corner (the arriving one), as in LinuxCNC's `tp` and as G9/G09 (exact stop for
/// one block, at its end) needs; a leaving move in exact-stop mode adds no tolerance of
/// its own, so the arriving move's governs.
fn corner_tolerance(arriving: CornerMode, leaving: CornerMode, default_mm: f64) -> Option<f64> {
    let CornerMode::Blend { tolerance_mm } = arriving else {
        return None;
    };
    let tol = tolerance_mm.unwrap_or(default_mm);
    Some(match leaving {
        CornerMode::Blend { tolerance_mm } => tol.min(tolerance_mm.unwrap_or(default_mm)),
        CornerMode::ExactStop => tol,
    })
}

/// The tangent and curvature at the start of a feed move (A, B, C move linearly along it).
fn next_start_frame(p: &Pending) -> Option<smooth::EndFrame> {
    let c = Curve::from_path(&p.mv.path);
    if p.mv.rapid || c.length() < MIN_SEGMENT_MM {
        return None;
    }
    let e = c.eval(0.0);
    Some(smooth::EndFrame {
        tangent: e.tangent,
        curvature: e.curvature,
        abc_d: std::array::from_fn(|i| (p.abc_end[i] - p.abc_start[i]) / c.length()),
        abc_dd: [0.0; 3],
    })
}

/// The frame at the end of `prev` if a run starting with the line `next` may continue it
/// smoothly.
fn joining_frame(prev: &Pending, next: &Pending, tol: f64) -> Option<smooth::EndFrame> {
    let CornerMode::Blend { tolerance_mm } = prev.mv.corner else {
        return None;
    };
    // The corner takes the smaller tolerance of its two moves.
    let tol = tolerance_mm.map_or(tol, |t| t.min(tol));
    if prev.mv.rapid
        || prev.abc_end != next.abc_start
        || (prev.mv.path.end() - next.mv.path.start()).norm() > MIN_SEGMENT_MM
    {
        return None;
    }
    let c = Curve::from_path(&prev.mv.path);
    if c.length() < MIN_SEGMENT_MM {
        return None;
    }
    let e = c.eval(c.length());
    let abc_d: [f64; 3] =
        std::array::from_fn(|i| (prev.abc_end[i] - prev.abc_start[i]) / c.length());
    // The sag is judged over the first run segment only.
    (turn_fits(e.tangent, line_dir(next), line_len(next), tol)
        && rotary_turn_fits(abc_d, abc_rate(next), line_len(next), tol))
    .then_some(smooth::EndFrame {
        tangent: e.tangent,
        curvature: e.curvature,
        abc_d,
        abc_dd: [0.0; 3],
    })
}

impl Planner {
    /// A planner for a machine; the path starts at the origin with rotary axes at 0.
    pub fn new(limits: MachineLimits) -> Self {
        Planner {
            limits,
            pending: None,
            last: None,
            last_corner: CornerMode::ExactStop,
            last_origin: None,
            last_full_length: 0.0,
            next_index: 0,
            abc_current: [0.0; 3],
            run: None,
            pieces: Vec::new(),
            design_override: 1.0,
            chain_mm: 0.0,
            run_mm: 0.0,
        }
    }

    /// Designs curved segments for a feed override of `factor` (clamped to 1–2): their
    /// speed limit is the programmed feed times it, where the machine allows. Straight
    /// segments are limited by the axes alone and follow any override anyway. Planning
    /// for more than 100 % costs a little tangential acceleration on curves, so a control
    /// passes the override in force when the segments are planned; segments already
    /// planned keep their limit (the motion core never exceeds it).
    pub fn set_design_override(&mut self, factor: f64) {
        self.design_override = if factor.is_finite() {
            factor.clamp(1.0, MAX_DESIGN_OVERRIDE)
        } else {
            1.0
        };
    }

    /// Adds the next move; finished segments are appended to `out`.
    pub fn push(&mut self, mv: &Move, out: &mut Vec<PlannedSegment>) -> Result<(), PlanError> {
        self.check(mv)?;
        let (abc_start, abc_end) = match mv.abc_deg {
            Some((s, e)) => (s, e),
            None => (self.abc_current, self.abc_current),
        };
        self.abc_current = abc_end;
        let index = self.next_index;
        self.next_index += 1;
        let next = Pending {
            mv: *mv,
            move_index: index,
            start: mv.path.start(),
            start_trim: 0.0,
            abc_start,
            abc_end,
        };
        let mut carried = None;
        if let Some(mut run) = self.run.take() {
            if run.joins(&next) {
                run.add(next);
                self.run = Some(run);
                self.advance_run(out);
                return Ok(());
            }
            carried = self.end_run(run, Some(&next), out);
        }
        if let Some(tol) = RunState::starts(&next, &self.limits) {
            let frame = carried.or_else(|| {
                self.pending
                    .as_ref()
                    .and_then(|p| joining_frame(p, &next, tol))
            });
            self.run = Some(RunState::new(next, tol, frame));
            return Ok(());
        }
        self.push_plain(next, out);
        Ok(())
    }

    /// A move through the corner-blending path (not part of a smoothed run).
    fn push_plain(&mut self, mut next: Pending, out: &mut Vec<PlannedSegment>) {
        if let Some(prev) = self.pending.take() {
            if let Some((blend, d)) = self.blend(&prev, &next) {
                let (p_start, u1) = match prev.mv.path {
                    Path::Line(l) => (l.end, (l.end - l.start).normalize()),
                    Path::Arc(_) => unreachable!("only lines are blended"),
                };
                let cut = p_start - u1 * d;
                self.emit_line(
                    &prev,
                    prev.start,
                    cut,
                    CornerMode::Blend { tolerance_mm: None },
                    out,
                );
                let mode = CornerMode::Blend { tolerance_mm: None };
                self.emit(blend, mode, mode, None, out);
                let u2 = (next.mv.path.end() - next.start).normalize();
                next.start += u2 * d;
                next.start_trim = d;
            } else {
                self.emit_move(&prev, out);
            }
        }
        self.pending = Some(next);
    }

    /// Emits the pieces of the current run that are ready; commits the run (flushing the
    /// move before it, unblended) once it is long enough to be smoothed.
    fn advance_run(&mut self, out: &mut Vec<PlannedSegment>) {
        let Some(run) = self.run.as_mut() else { return };
        if !run.committed {
            if run.buffered.len() < smooth::MIN_RUN_MOVES {
                return;
            }
            run.committed = true;
            run.buffered.clear();
            if let Some(prev) = self.pending.take() {
                self.emit_move(&prev, out);
            }
        }
        let Some(run) = self.run.as_mut() else { return };
        let mut pieces = std::mem::take(&mut self.pieces);
        run.run.emit(false, None, &mut pieces);
        self.emit_pieces(&mut pieces, None, out);
        self.pieces = pieces;
    }

    /// Ends `run` before `next` (or at the program end); returns the frame the run ended
    /// with when `next` starts a run that must continue it.
    fn end_run(
        &mut self,
        mut run: RunState,
        next: Option<&Pending>,
        out: &mut Vec<PlannedSegment>,
    ) -> Option<smooth::EndFrame> {
        if !run.committed && run.buffered.len() < smooth::MIN_RUN_MOVES {
            for p in std::mem::take(&mut run.buffered) {
                self.push_plain(p, out);
            }
            return None;
        }
        if !run.committed {
            run.committed = true;
            if let Some(prev) = self.pending.take() {
                self.emit_move(&prev, out);
            }
        }
        let blended = matches!(run.last.mv.corner, CornerMode::Blend { .. });
        // A line that starts another run (the tolerance changed, or the turn or sag at
        // the joint is too much for this run) is not matched: the run ends on its fitted
        // frame, and the next run starts on that frame where the turn fits, so a curve
        // split into two runs stays curvature-continuous.
        let next_run = next.filter(|n| blended && RunState::starts(n, &self.limits).is_some());
        // Decisions at the joint with `next` take the smaller tolerance of the two moves.
        let corner_tol = next.map_or(run.tol, |n| {
            corner_tolerance(run.last.mv.corner, n.mv.corner, self.limits.tolerance_mm)
                .map_or(run.tol, |t| t.min(run.tol))
        });
        let end_frame = match (run.last.mv.corner, next) {
            _ if next_run.is_some() => None,
            (CornerMode::Blend { .. }, Some(n)) => {
                let first = next_start_frame(n);
                first.filter(|f| {
                    run.run
                        .last_dir()
                        .is_some_and(|d| turn_fits(d, f.tangent, run.run.last_len(), corner_tol))
                })
            }
            _ => None,
        };
        let mut pieces = std::mem::take(&mut self.pieces);
        run.run.emit(true, end_frame, &mut pieces);
        let corner = run.last.mv.corner;
        self.emit_pieces(&mut pieces, Some(corner), out);
        self.pieces = pieces;
        if let Some(n) = next_run {
            return run
                .run
                .end_frame()
                .filter(|f| turn_fits(f.tangent, line_dir(n), line_len(n), corner_tol));
        }
        end_frame
    }

    /// Turns smoothed pieces into segments; the last one takes `last_corner` when the run
    /// ends with it.
    fn emit_pieces(
        &mut self,
        pieces: &mut Vec<smooth::Emitted>,
        last_corner: Option<CornerMode>,
        out: &mut Vec<PlannedSegment>,
    ) {
        let n = pieces.len();
        for (i, e) in pieces.drain(..).enumerate() {
            let curve = match e.piece {
                smooth::Piece::Curve(tr) => Curve::Transition(tr),
                smooth::Piece::Line(p, q) => Curve::line(p, q),
            };
            let mut seg = PlannedSegment {
                curve,
                abc_start_deg: e.abc_start,
                abc_end_deg: e.abc_end,
                abc_poly: e.abc_poly,
                length_mm: curve.length(),
                line: e.line,
                move_index: e.move_index,
                move_count: e.move_count,
                feed_mm_s: e.feed,
                v_max_mm_s: 0.0,
                accel_mm_s2: 0.0,
                jerk_mm_s3: 0.0,
                v_boost_mm_s: 0.0,
                accel_boost_mm_s2: 0.0,
                jerk_boost_mm_s3: 0.0,
                end_cap_mm_s: 0.0,
                blend: true,
            };
            if seg.length_mm < MIN_SEGMENT_MM {
                continue;
            }
            // Designed for the path that runs on without a corner through the piece to the
            // end of its run (at least the whole run), at most [`DESIGN_RUN_MM`]: known
            // geometry only, as for programmed arcs.
            self.run_mm = (self.chain_before(&seg) + e.rest_mm)
                .max(e.design_run_mm)
                .min(DESIGN_RUN_MM);
            self.set_limits(&mut seg, false);
            self.run_mm = 0.0;
            let corner = match last_corner {
                Some(c) if i + 1 == n => c,
                _ => CornerMode::Blend { tolerance_mm: None },
            };
            self.emit(
                seg,
                CornerMode::Blend { tolerance_mm: None },
                corner,
                None,
                out,
            );
        }
    }

    /// Ends the program: flushes every remaining segment (the last one ends at rest).
    pub fn finish(&mut self, out: &mut Vec<PlannedSegment>) {
        if let Some(run) = self.run.take() {
            self.end_run(run, None, out);
        }
        if let Some(prev) = self.pending.take() {
            self.emit_move(&prev, out);
        }
        if let Some(mut last) = self.last.take() {
            last.end_cap_mm_s = 0.0;
            out.push(last);
        }
    }

    fn check(&self, mv: &Move) -> Result<(), PlanError> {
        let line = mv.line;
        let finite = |v: &Vec3| v.iter().all(|c| c.is_finite());
        let ok = match &mv.path {
            Path::Line(l) => finite(&l.start) && finite(&l.end),
            Path::Arc(a) => {
                finite(&a.start)
                    && finite(&a.end)
                    && finite(&a.center)
                    && finite(&a.axis)
                    && a.sweep_rad.is_finite()
            }
        };
        if !ok {
            return Err(PlanError::NotFinite { line });
        }
        if !mv.rapid {
            match mv.feed_mm_min {
                Some(f) if f.is_finite() && f > 0.0 => {}
                Some(f) if !f.is_finite() => return Err(PlanError::NotFinite { line }),
                _ => return Err(PlanError::ZeroFeed { line }),
            }
        }
        if let Some((s, e)) = mv.abc_deg {
            for i in 0..3 {
                if !s[i].is_finite() || !e[i].is_finite() {
                    return Err(PlanError::NotFinite { line });
                }
                if s[i] != e[i] && self.limits.axes[3 + i].is_none() {
                    return Err(PlanError::AxisNotConfigured {
                        line,
                        axis: AXIS_NAMES[3 + i],
                    });
                }
            }
        }
        Ok(())
    }

    /// The blend for the corner between `prev` and `next` and the distance it takes from
    /// each, if the corner is blended: a circular arc, or at an isolated corner a G2 blend
    /// ([`Planner::g2_blend`]) where that costs less time ([`corner_time_s`]).
    fn blend(&self, prev: &Pending, next: &Pending) -> Option<(PlannedSegment, f64)> {
        let tol = corner_tolerance(prev.mv.corner, next.mv.corner, self.limits.tolerance_mm)?;
        if tol <= 0.0 || !tol.is_finite() {
            return None;
        }
        let (Path::Line(l1), Path::Line(l2)) = (prev.mv.path, next.mv.path) else {
            return None;
        };
        // Rotary motion on either side would need a blend in six dimensions; take those
        // corners at the junction speed instead.
        if prev.abc_start != prev.abc_end || next.abc_start != next.abc_end {
            return None;
        }
        let len1 = (l1.end - l1.start).norm();
        let len2 = (l2.end - l2.start).norm();
        if len1 < MIN_SEGMENT_MM || len2 < MIN_SEGMENT_MM {
            return None;
        }
        let u1 = (l1.end - l1.start) / len1;
        let u2 = (l2.end - l2.start) / len2;
        let cos = u1.dot(&u2).clamp(-1.0, 1.0);
        let normal = u1.cross(&u2);
        let sin = normal.norm();
        let theta = sin.atan2(cos);
        if !(COLLINEAR_RAD..=std::f64::consts::PI - 1e-6).contains(&theta) {
            return None;
        }
        // Deviation at the blend midpoint is r (1 - cos(θ/2)) = 2 r sin²(θ/4).
        let s4 = (theta / 4.0).sin();
        let r_tol = 0.98 * tol / (2.0 * s4 * s4);
        let tan_half = (theta / 2.0).tan();
        let d_tol = r_tol * tan_half;
        let d = d_tol.min(len1 - prev.start_trim).min(len2 * 0.5);
        if d < MIN_SEGMENT_MM {
            return None;
        }
        let radius = d / tan_half;
        let axis = normal / sin;
        let corner = l1.end;
        let b1 = corner - u1 * d;
        let b2 = corner + u2 * d;
        let center = b1 + axis.cross(&u1) * radius;
        let path = Path::Arc(kerf_geom::Arc {
            start: b1,
            end: b2,
            center,
            axis,
            sweep_rad: theta,
        });
        let curve = Curve::from_path(&path);
        let feed = feed_of(&prev.mv).min(feed_of(&next.mv));
        let rapid = prev.mv.rapid && next.mv.rapid;
        let mut seg = PlannedSegment {
            curve,
            abc_start_deg: prev.abc_end,
            abc_end_deg: prev.abc_end,
            abc_poly: None,
            length_mm: curve.length(),
            line: next.mv.line,
            move_index: prev.move_index,
            move_count: 1,
            feed_mm_s: feed,
            v_max_mm_s: 0.0,
            accel_mm_s2: 0.0,
            jerk_mm_s3: 0.0,
            v_boost_mm_s: 0.0,
            accel_boost_mm_s2: 0.0,
            jerk_boost_mm_s3: 0.0,
            end_cap_mm_s: 0.0,
            blend: true,
        };
        self.set_limits(&mut seg, rapid);
        // Isolated: both lines keep a remnant of at least [`MIN_REMNANT_MM`], so the
        // neighbouring blends do not meet. A G2 blend within the tolerance takes more than
        // half of what the arc would (about as much, except near reversals); where that
        // does not fit (dense polylines) the arc is kept without trying.
        let room_mm = (len1 - prev.start_trim - MIN_REMNANT_MM).min(0.5 * len2 - MIN_REMNANT_MM);
        if room_mm <= 0.5 * d_tol {
            return Some((seg, d));
        }
        let corner_g2 = G2Corner {
            corner,
            u1,
            u2,
            line1: Curve::line(l1.start, l1.end),
            line2: Curve::line(l2.start, l2.end),
            tol_mm: tol,
            room_mm,
        };
        let lines = self.corner_lines(&seg, u1, u2, (len1 - prev.start_trim).min(len2));
        let arc_time_s = corner_time_s(&seg, d, &lines, &self.limits);
        let (best, best_time_s) = match self.g2_blend(&corner_g2, &seg, &lines, rapid) {
            Some((g2, d_g2, time_s)) if time_s < arc_time_s => ((g2, d_g2), time_s),
            _ => ((seg, d), arc_time_s),
        };
        // A sharp corner at a small tolerance must slow down nearly to a stop for any
        // blend, and then crawls through it: stopping at the corner is quicker there (and
        // trivially within the tolerance).
        if stop_time_s(&lines) < best_time_s {
            return None;
        }
        Some(best)
    }

    /// Stand-ins for the two lines of a corner whose blend is `blend` (in along `u1`, out
    /// along `u2`), with their limits: for the junction caps with the blend and the speed
    /// the corner is approached at.
    ///
    /// Their speed is at most what a ramp from rest reaches over `reach_mm` (the shorter
    /// of the two programmed lines): a corner between short lines is not approached at
    /// the machine's speed, and judging a stop or a blend against that speed (which a
    /// raised velocity limit raises) made short zig-zags stop where a blend is quicker.
    fn corner_lines(
        &self,
        blend: &PlannedSegment,
        u1: Vec3,
        u2: Vec3,
        reach_mm: f64,
    ) -> (PlannedSegment, PlannedSegment) {
        let mut line_in = *blend;
        line_in.blend = false;
        line_in.curve = Curve::line(blend.curve.start() - u1, blend.curve.start());
        line_in.length_mm = 1.0;
        let mut line_out = line_in;
        line_out.curve = Curve::line(blend.curve.end(), blend.curve.end() + u2);
        self.set_limits(&mut line_in, false);
        self.set_limits(&mut line_out, false);
        for l in [&mut line_in, &mut line_out] {
            let v = reach_speed(reach_mm, l.v_max_mm_s, l.accel_mm_s2, l.jerk_mm_s3);
            l.v_max_mm_s = v;
            l.v_boost_mm_s = l.v_boost_mm_s.min(v);
        }
        (line_in, line_out)
    }

    /// The symmetric G2 corner blend for `c` (zero curvature at both ends, so the joints
    /// with the lines are continuous in tangent and curvature), the distance it takes from
    /// each line and its [`corner_time_s`]: for each parameter scale of
    /// [`G2_LAMBDA_RATIOS`] the largest blend within the tolerance, and of those the
    /// quickest. `None` if none fits in `c.room_mm`. `template` gives the segment fields.
    fn g2_blend(
        &self,
        c: &G2Corner,
        template: &PlannedSegment,
        lines: &(PlannedSegment, PlannedSegment),
        rapid: bool,
    ) -> Option<(PlannedSegment, f64, f64)> {
        if c.room_mm.is_nan() || c.room_mm <= 0.0 {
            return None;
        }
        let limit_mm = TRANSITION_TOL_SHARE * c.tol_mm;
        // The shape scales with d: its deviation at d = 1 mm gives the largest d.
        let unit = G2Corner {
            corner: Vec3::zeros(),
            line1: Curve::line(-c.u1 * 2.0, Vec3::zeros()),
            line2: Curve::line(Vec3::zeros(), c.u2 * 2.0),
            ..*c
        };
        let mut best: Option<(PlannedSegment, f64, f64)> = None;
        for rho in G2_LAMBDA_RATIOS {
            let Some(dev_1mm) = unit.curve(1.0, rho).map(|t| unit.deviation(&t)) else {
                continue;
            };
            if !(dev_1mm > 0.0 && dev_1mm.is_finite()) {
                continue;
            }
            let mut d = limit_mm / dev_1mm;
            if d >= c.room_mm {
                continue;
            }
            // Rounding: confirm against the programmed lines, shrinking slightly if needed.
            let mut found = None;
            for _ in 0..8 {
                if let Some(t) = c.curve(d, rho) {
                    if c.deviation(&t) <= limit_mm {
                        found = Some(t);
                        break;
                    }
                }
                d *= 0.999;
            }
            let Some(tr) = found.and_then(|t| t.with_arc_length()) else {
                continue;
            };
            let curve = Curve::Transition(tr);
            let mut seg = PlannedSegment {
                curve,
                length_mm: curve.length(),
                ..*template
            };
            self.set_limits(&mut seg, rapid);
            let time_s = corner_time_s(&seg, d, lines, &self.limits);
            if best.as_ref().is_none_or(|b| time_s < b.2) {
                best = Some((seg, d, time_s));
            }
        }
        best
    }

    fn emit_move(&mut self, p: &Pending, out: &mut Vec<PlannedSegment>) {
        match p.mv.path {
            Path::Line(l) => self.emit_line(p, p.start, l.end, p.mv.corner, out),
            Path::Arc(_) => {
                let curve = Curve::from_path(&p.mv.path);
                self.emit_curve(p, curve, p.mv.corner, out);
            }
        }
    }

    fn emit_line(
        &mut self,
        p: &Pending,
        start: Vec3,
        end: Vec3,
        corner: CornerMode,
        out: &mut Vec<PlannedSegment>,
    ) {
        self.emit_curve(p, Curve::line(start, end), corner, out);
    }

    fn emit_curve(
        &mut self,
        p: &Pending,
        curve: Curve,
        corner: CornerMode,
        out: &mut Vec<PlannedSegment>,
    ) {
        let xyz = curve.length();
        let rot = (0..3)
            .map(|i| (p.abc_end[i] - p.abc_start[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        let length = if xyz >= MIN_SEGMENT_MM { xyz } else { rot };
        if length < MIN_SEGMENT_MM {
            return;
        }
        let curve = if xyz >= MIN_SEGMENT_MM {
            curve
        } else {
            Curve::line(curve.start(), curve.start())
        };
        let mut seg = PlannedSegment {
            curve,
            abc_start_deg: p.abc_start,
            abc_end_deg: p.abc_end,
            abc_poly: None,
            length_mm: length,
            line: p.mv.line,
            move_index: p.move_index,
            move_count: 1,
            feed_mm_s: feed_of(&p.mv),
            v_max_mm_s: 0.0,
            accel_mm_s2: 0.0,
            jerk_mm_s3: 0.0,
            v_boost_mm_s: 0.0,
            accel_boost_mm_s2: 0.0,
            jerk_boost_mm_s3: 0.0,
            end_cap_mm_s: 0.0,
            blend: false,
        };
        // A programmed arc is designed for the path that runs on without a corner up to
        // its end, at most [`DESIGN_RUN_MM`]: known geometry only, so that the choice
        // does not depend on the limits.
        self.run_mm = (self.chain_before(&seg) + seg.length_mm).min(DESIGN_RUN_MM);
        self.set_limits(&mut seg, p.mv.rapid);
        self.run_mm = 0.0;
        self.emit(
            seg,
            p.mv.corner,
            corner,
            Some(Curve::from_path(&p.mv.path)),
            out,
        );
    }

    /// Appends `seg` (in mode `own`, the mode of the move it comes from, and ending in
    /// mode `corner`) after the held-back segment, deciding the junction between them.
    fn emit(
        &mut self,
        mut seg: PlannedSegment,
        own: CornerMode,
        corner: CornerMode,
        origin: Option<Curve>,
        out: &mut Vec<PlannedSegment>,
    ) {
        let full_length = seg.length_mm;
        self.chain_mm = self.chain_before(&seg) + seg.length_mm;
        if let Some(mut prev) = self.last.take() {
            match corner_tolerance(self.last_corner, own, self.limits.tolerance_mm) {
                None => {
                    prev.end_cap_mm_s = 0.0;
                    out.push(prev);
                }
                Some(tol) => match self.transition(&prev, &seg, tol, origin.as_ref()) {
                    Some((p, mut t, s)) => {
                        prev = p;
                        seg = s;
                        prev.end_cap_mm_s = junction_cap(&prev, &t, &self.limits);
                        t.end_cap_mm_s = junction_cap(&t, &seg, &self.limits);
                        out.push(prev);
                        out.push(t);
                    }
                    None => {
                        prev.end_cap_mm_s = junction_cap(&prev, &seg, &self.limits);
                        out.push(prev);
                    }
                },
            }
        }
        self.last = Some(seg);
        self.last_corner = corner;
        self.last_origin = origin;
        self.last_full_length = full_length;
    }

    /// The length of the path that runs on without a corner into `seg`: the chain ending
    /// at the held-back segment if `seg` continues it in tangent (all six axes) and the
    /// junction is not an exact stop, else 0.
    fn chain_before(&self, seg: &PlannedSegment) -> f64 {
        let Some(last) = &self.last else { return 0.0 };
        if matches!(self.last_corner, CornerMode::ExactStop) || seg.length_mm <= 0.0 {
            return 0.0;
        }
        let (ta, _) = last.derivatives_at(last.length_mm);
        let (tb, _) = seg.derivatives_at(0.0);
        let tangent = (0..6).all(|i| (ta[i] - tb[i]).abs() <= 1e-6);
        if tangent { self.chain_mm } else { 0.0 }
    }

    /// A curvature-continuous transition for the joint from `prev` to `seg`, if the joint
    /// involves a programmed arc, has a curvature jump or kink that caps the speed, and a
    /// transition within `tol` of the programmed path runs faster: `(prev trimmed at its
    /// end, transition, seg trimmed at its start)`.
    fn transition(
        &self,
        prev: &PlannedSegment,
        seg: &PlannedSegment,
        tol: f64,
        origin: Option<&Curve>,
    ) -> Option<(PlannedSegment, PlannedSegment, PlannedSegment)> {
        let (Some(o_prev), Some(o_seg)) = (self.last_origin.as_ref(), origin) else {
            return None;
        };
        if !(tol > 0.0 && tol.is_finite()) || prev.blend || seg.blend {
            return None;
        }
        let is_arc = |s: &PlannedSegment| matches!(s.curve, Curve::Helix(_));
        if !(is_arc(prev) || is_arc(seg)) {
            return None;
        }
        let still = |s: &PlannedSegment| s.abc_start_deg == s.abc_end_deg;
        if !still(prev) || !still(seg) || seg.move_index > prev.move_index + 1 {
            return None;
        }
        let (la, lb) = (prev.curve.length(), seg.curve.length());
        if la < MIN_SEGMENT_MM || lb < MIN_SEGMENT_MM {
            return None;
        }
        let v_ref = prev
            .v_max_mm_s
            .min(seg.v_max_mm_s)
            .min(prev.feed_mm_s)
            .min(seg.feed_mm_s);
        let old = junction_cap(prev, seg, &self.limits);
        if old >= 0.9 * v_ref {
            return None;
        }
        let ea = prev.curve.eval(la);
        let eb = seg.curve.eval(0.0);
        let dk = (eb.curvature - ea.curvature).norm();
        let dt = (eb.tangent - ea.tangent).norm();
        // Room: at most [`TRANSITION_SHARE_OF_MOVE`] of each neighbour as it came, so that a
        // piece between two transitions keeps a tenth of its length (and at least
        // [`MIN_REMNANT_MM`]): a sliver of a segment between two fast transitions would be a
        // section the profile generator can fail on.
        let room_a = (TRANSITION_SHARE_OF_MOVE * self.last_full_length).min(la - MIN_REMNANT_MM);
        let room_b = (TRANSITION_SHARE_OF_MOVE * lb).min(lb - MIN_REMNANT_MM);
        if room_a <= 0.0 || room_b <= 0.0 {
            return None;
        }
        let mut d = room_a.min(room_b);
        // Start above the estimates (a curvature ramp of Δκ over 2d sits about
        // Δκ(2d)²/24 off the path; a kink of Δt cuts its corner by about dΔt/4) and shrink.
        if dk > 0.0 {
            d = d.min(12.0 * (tol / dk).sqrt());
        }
        if dt > 0.0 {
            d = d.min(16.0 * tol / dt);
        }
        for _ in 0..TRANSITION_TRIES {
            if d < 1e-6 {
                return None;
            }
            let da = d.min(room_a);
            let db = d.min(room_b);
            d *= TRANSITION_SHRINK;
            let ca = prev.curve.trimmed(0.0, la - da);
            let cb = seg.curve.trimmed(db, lb);
            let a = ca.eval(ca.length());
            let b = cb.eval(0.0);
            let lambda = (b.point - a.point).norm();
            let Some(tr) = Transition::hermite(
                a.point,
                a.tangent,
                a.curvature,
                b.point,
                b.tangent,
                b.curvature,
                lambda,
            ) else {
                continue;
            };
            let within = (0..=DEVIATION_SAMPLES).all(|i| {
                let p = tr.poly(i as f64 / DEVIATION_SAMPLES as f64);
                o_prev.distance_to(&p).min(o_seg.distance_to(&p)) <= TRANSITION_TOL_SHARE * tol
            });
            if !within {
                continue;
            }
            let Some(tr) = tr.with_arc_length() else {
                continue;
            };
            let curve = Curve::Transition(tr);
            let mut t = PlannedSegment {
                curve,
                abc_start_deg: prev.abc_end_deg,
                abc_end_deg: prev.abc_end_deg,
                abc_poly: None,
                length_mm: curve.length(),
                line: seg.line,
                move_index: prev.move_index,
                move_count: 1,
                feed_mm_s: prev.feed_mm_s.min(seg.feed_mm_s),
                v_max_mm_s: 0.0,
                accel_mm_s2: 0.0,
                jerk_mm_s3: 0.0,
                v_boost_mm_s: 0.0,
                accel_boost_mm_s2: 0.0,
                jerk_boost_mm_s3: 0.0,
                end_cap_mm_s: 0.0,
                blend: true,
            };
            self.set_limits(&mut t, false);
            let mut p = *prev;
            p.curve = ca;
            p.length_mm = ca.length();
            let mut s = *seg;
            s.curve = cb;
            s.length_mm = cb.length();
            let new = junction_cap(&p, &t, &self.limits)
                .min(t.v_max_mm_s)
                .min(junction_cap(&t, &s, &self.limits));
            // The largest transition within the tolerance is the fastest; take it if it
            // beats the plain joint. A crawl through a long transition (a sharp kink with a
            // small tolerance) costs more time than stopping at the kink: both need the
            // same slow-down, so only the time spent on the transition counts.
            let quick = new >= 0.25 * v_ref || t.length_mm <= MAX_CRAWL_S * new;
            return (new > 1.05 * old && quick).then_some((p, t, s));
        }
        None
    }

    /// Sets `v_max_mm_s`, `accel_mm_s2` and `jerk_mm_s3` of `seg` from the axis limits.
    fn set_limits(&self, seg: &mut PlannedSegment, _rapid: bool) {
        let (v, a, j) = segment_limits(seg, &self.limits, self.design_override, self.run_mm);
        seg.v_max_mm_s = v;
        seg.accel_mm_s2 = a;
        seg.jerk_mm_s3 = j;
        (
            seg.v_boost_mm_s,
            seg.accel_boost_mm_s2,
            seg.jerk_boost_mm_s3,
        ) = (v, a, j);
        // Curved segments (not smoothed pieces, which keep the programmed feed) also get a
        // design for the highest override, which the motion core uses while the override
        // is above 100 %. Straight segments are limited by the axes alone.
        let curved = match seg.curve {
            Curve::Line { .. } => false,
            Curve::Helix(_) => true,
            Curve::Transition(_) => seg.move_count <= 1,
        };
        if curved && seg.feed_mm_s.is_finite() && self.design_override < MAX_DESIGN_OVERRIDE {
            let (vb, ab, jb) = segment_limits(seg, &self.limits, MAX_DESIGN_OVERRIDE, self.run_mm);
            if vb > v {
                seg.v_boost_mm_s = vb;
                seg.accel_boost_mm_s2 = ab.min(a);
                seg.jerk_boost_mm_s3 = jb.min(j);
            }
        }
    }
}

/// A line-line corner for a G2 blend.
#[derive(Clone, Copy, Debug)]
struct G2Corner {
    /// The corner point, mm.
    corner: Vec3,
    /// Unit direction of the incoming line.
    u1: Vec3,
    /// Unit direction of the outgoing line.
    u2: Vec3,
    /// The programmed incoming line.
    line1: Curve,
    /// The programmed outgoing line.
    line2: Curve,
    /// Path tolerance, mm.
    tol_mm: f64,
    /// Largest distance the blend may take from the corner along each line, mm.
    room_mm: f64,
}

impl G2Corner {
    /// The blend from `corner - u1·d` to `corner + u2·d` with parameter scale
    /// `rho` × chord (polynomial only).
    fn curve(&self, d: f64, rho: f64) -> Option<Transition> {
        let b1 = self.corner - self.u1 * d;
        let b2 = self.corner + self.u2 * d;
        let lambda = rho * (b2 - b1).norm();
        Transition::hermite(
            b1,
            self.u1,
            Vec3::zeros(),
            b2,
            self.u2,
            Vec3::zeros(),
            lambda,
        )
    }

    /// Largest distance of [`DEVIATION_SAMPLES`] points of `t` from the two lines, mm.
    fn deviation(&self, t: &Transition) -> f64 {
        (0..=DEVIATION_SAMPLES)
            .map(|i| {
                let p = t.poly(i as f64 / DEVIATION_SAMPLES as f64);
                self.line1.distance_to(&p).min(self.line2.distance_to(&p))
            })
            .fold(0.0, f64::max)
    }
}

/// Time of a jerk-limited change of speed by `dv` with acceleration `a` and jerk `j`, s.
fn change_time_s(dv: f64, a: f64, j: f64) -> f64 {
    if dv <= a * a / j {
        2.0 * (dv / j).sqrt()
    } else {
        dv / a + a / j
    }
}

/// The highest speed (at most `v_max`) that a jerk-limited ramp from rest with
/// acceleration `a` and jerk `j` reaches within `length`, by bisection.
fn reach_speed(length: f64, v_max: f64, a: f64, j: f64) -> f64 {
    let ramp_mm = |v: f64| 0.5 * v * change_time_s(v, a, j);
    if !(length > 0.0 && v_max > 0.0 && a > 0.0 && j > 0.0) || ramp_mm(v_max) <= length {
        return v_max;
    }
    bisect(0.0, v_max, 50, |v| ramp_mm(v) <= length)
}

/// Bisection between `good`, where `ok` holds, and `bad`, where it does not (`ok` changes
/// once between them): the value nearest `bad` known to satisfy `ok`, after `steps`
/// halvings.
fn bisect(mut good: f64, mut bad: f64, steps: usize, ok: impl Fn(f64) -> bool) -> f64 {
    for _ in 0..steps {
        let mid = 0.5 * (good + bad);
        if ok(mid) {
            good = mid;
        } else {
            bad = mid;
        }
    }
    good
}

/// Rough time over a segment of `length` entered and left at `v_in`, speeding up on the
/// way to at most `v_top` with acceleration `a` and jerk `j`, s.
fn transit_time_s(length: f64, v_in: f64, v_top: f64, a: f64, j: f64) -> f64 {
    let v_top = v_top.max(v_in);
    // Distance to speed up from `v_in` to `p` and back.
    let there_and_back = |p: f64| (v_in + p) * change_time_s(p - v_in, a, j);
    let peak = if there_and_back(v_top) > length {
        bisect(v_in, v_top, 50, |p| there_and_back(p) <= length)
    } else {
        v_top
    };
    let cruise = (length - there_and_back(peak)).max(0.0);
    let cruise_s = if cruise > 0.0 { cruise / peak } else { 0.0 };
    2.0 * change_time_s(peak - v_in, a, j) + cruise_s
}

/// Rough time a stop at a corner costs over running straight through at the lines' speed:
/// the slow-down to rest and back with the lines' limits.
fn stop_time_s(lines: &(PlannedSegment, PlannedSegment)) -> f64 {
    let (line_in, line_out) = lines;
    let v_line = line_in
        .v_max_mm_s
        .min(line_out.v_max_mm_s)
        .min(line_in.feed_mm_s);
    change_time_s(
        v_line,
        line_in.accel_mm_s2.min(line_out.accel_mm_s2),
        line_in.jerk_mm_s3.min(line_out.jerk_mm_s3),
    )
}

/// Rough time a corner blend costs over running straight through at the lines' speed:
/// the slow-down to the speed the blend and its joints allow and back (with the lines'
/// limits), the transit of the blend, less the `2·d` of line it replaces. Used to choose
/// between a circular and a G2 blend (the circular one is entered at its curvature-step
/// cap but may speed up inside; the G2 one has no such step).
fn corner_time_s(
    blend: &PlannedSegment,
    d: f64,
    lines: &(PlannedSegment, PlannedSegment),
    limits: &MachineLimits,
) -> f64 {
    let (line_in, line_out) = lines;
    let v_line = line_in
        .v_max_mm_s
        .min(line_out.v_max_mm_s)
        .min(blend.feed_mm_s);
    let a_line = line_in.accel_mm_s2.min(line_out.accel_mm_s2);
    let j_line = line_in.jerk_mm_s3.min(line_out.jerk_mm_s3);
    let v_top = blend.v_max_mm_s.min(blend.feed_mm_s);
    let v_in = junction_cap(line_in, blend, limits)
        .min(junction_cap(blend, line_out, limits))
        .min(v_top);
    let transit = transit_time_s(
        blend.length_mm,
        v_in,
        v_top,
        blend.accel_mm_s2,
        blend.jerk_mm_s3,
    );
    let dv = (v_line - v_in).max(0.0);
    // Slowing from v_line to v_in and back: 2·t over a distance (v_line + v_in)·t.
    let dip = change_time_s(dv, a_line, j_line) * dv / v_line;
    transit + dip - 2.0 * d / v_line
}

fn feed_of(mv: &Move) -> f64 {
    if mv.rapid {
        f64::INFINITY
    } else {
        mv.feed_mm_min.unwrap_or(0.0) / 60.0
    }
}

/// Per-axis geometric weights of a segment: the largest |component| over the segment of
/// the unit tangent split into in-plane and axial parts, and the curvature terms.
struct Weights {
    /// Max |tangent_i| over the segment.
    tangent: [f64; 6],
    /// In-plane weight `sqrt(1 - axis_i²)` (0 on lines and rotary axes).
    plane: [f64; 6],
    /// Axial tangent component `|axis_i| · rise/length` on helices.
    axial: [f64; 6],
    /// In-plane speed factor `r |sweep| / length`.
    q: f64,
    /// Curvature, 1/mm.
    kappa: f64,
    /// Sweep per unit length, rad/mm.
    sigma: f64,
}

fn weights(seg: &PlannedSegment) -> Weights {
    let mut w = Weights {
        tangent: [0.0; 6],
        plane: [0.0; 6],
        axial: [0.0; 6],
        q: 0.0,
        kappa: 0.0,
        sigma: 0.0,
    };
    match &seg.curve {
        Curve::Line { dir, .. } => {
            if seg.curve.length() > 0.0 {
                for i in 0..3 {
                    w.tangent[i] = dir[i].abs();
                }
            }
        }
        Curve::Helix(h) => {
            let q = h.radius_mm * h.sweep_rad.abs() / h.length_mm;
            let c = h.rise_mm.abs() / h.length_mm;
            w.q = q;
            w.sigma = h.sweep_rad.abs() / h.length_mm;
            w.kappa = h.curvature();
            for i in 0..3 {
                let ax = h.axis[i].abs().min(1.0);
                w.plane[i] = (1.0 - ax * ax).max(0.0).sqrt();
                w.axial[i] = ax * c;
                w.tangent[i] = w.plane[i] * q + w.axial[i];
            }
        }
        Curve::Transition(_) => unreachable!("transitions have their own limits"),
    }
    for i in 0..3 {
        w.tangent[3 + i] = (seg.abc_end_deg[i] - seg.abc_start_deg[i]).abs() / seg.length_mm;
    }
    w
}

/// Path limits `(v_max, a_max, j_max)` of a segment such that every axis stays within
/// [`PROFILE_SHARE`] of its limits for any speed up to `v_max` (curved segments: up to the
/// programmed feed), any tangential acceleration up to `a_max` and jerk up to `j_max`.
///
/// `feed_scale` (at least 1) is the feed override the curved segments are designed for:
/// their `v_max` is at most the programmed feed times it.
///
/// `run_mm` is the distance a curved segment's design speed is chosen for (at least its
/// length is used): how far the path runs on without a corner, see [`DESIGN_RUN_MM`].
pub fn segment_limits(
    seg: &PlannedSegment,
    limits: &MachineLimits,
    feed_scale: f64,
    run_mm: f64,
) -> (f64, f64, f64) {
    if let Curve::Transition(t) = &seg.curve {
        // Smoothed pieces keep the programmed feed as their design speed: boosted, their
        // limits vary with the direction from piece to piece, and every difference splits
        // the motion core's sections (a return to a = 0), which costs more than it gains.
        let (samples, feed_scale) = if seg.move_count > 1 {
            (PIECE_LIMIT_SAMPLES, 1.0)
        } else {
            (LIMIT_SAMPLES, feed_scale)
        };
        return transition_limits(seg, t, limits, samples, feed_scale, run_mm);
    }
    let w = weights(seg);
    let share = PROFILE_SHARE;
    let mut v = f64::INFINITY;
    let mut a_line = f64::INFINITY;
    let mut j_line = f64::INFINITY;
    let mut v2 = f64::INFINITY;
    let mut v3 = f64::INFINITY;
    for i in 0..6 {
        let Some(l) = limits.axes[i] else { continue };
        if w.tangent[i] > 0.0 {
            v = v.min(share * l.velocity_units_s / w.tangent[i]);
        }
        if w.plane[i] > 0.0 && w.kappa > 0.0 {
            // Bounds on v² and v³; the roots are taken once, after the loop.
            v2 = v2
                .min(CENTRIPETAL_SHARE * share * l.acceleration_units_s2 / (w.plane[i] * w.kappa));
            v3 = v3.min(
                CENTRIPETAL_SHARE * share * l.jerk_units_s3
                    / (w.plane[i] * w.q * w.sigma * w.sigma),
            );
        }
        // Straight components (lines, helix axial parts, rotary axes).
        let straight = if w.plane[i] > 0.0 {
            w.axial[i]
        } else {
            w.tangent[i]
        };
        if straight > 0.0 && w.plane[i] == 0.0 {
            a_line = a_line.min(share * l.acceleration_units_s2 / straight);
            j_line = j_line.min(share * l.jerk_units_s3 / straight);
        }
    }
    if v2.is_finite() {
        v = v.min(v2.sqrt());
    }
    if v3.is_finite() {
        v = v.min(v3.cbrt());
    }
    if w.kappa == 0.0 {
        return (v, a_line, j_line);
    }
    // Curved: the acceleration and jerk depend on the speed; the design speed (up to the
    // feed) is the one with the least rough time (cruise plus one ramp).
    let search = |v_start: f64| {
        design_speed_search(run_mm.max(seg.length_mm), v_start, |vd| {
            curved_budget(&w, limits, vd, a_line, j_line)
        })
    };
    boosted(v, seg.feed_mm_s, feed_scale, search)
}

/// The design for the programmed feed (at most the machine speed `v`), or for the feed
/// times `feed_scale` if that allows a speed at least 10 % higher: a design speed above
/// the feed leaves less tangential budget (slower ramps), which a few per cent more speed
/// does not pay for (the dense circle at 150 %: 102 mm/s instead of 100, but 0.96 s
/// instead of 0.78 s).
fn boosted(
    v: f64,
    feed: f64,
    feed_scale: f64,
    search: impl Fn(f64) -> (f64, f64, f64),
) -> (f64, f64, f64) {
    let base = search(v.min(feed));
    if feed_scale > 1.0 && v > feed {
        let boost = search(v.min(feed * feed_scale));
        if boost.0 >= 1.1 * base.0 {
            return boost;
        }
    }
    base
}

/// Distance a curved segment's design speed is chosen for at the least, mm: the segment
/// may be one of a long chain (a dense circle, a helix in turns), so its own length says
/// little about how long the speed is held.
pub const DESIGN_RUN_MM: f64 = 30.0;
/// Ratio of the design-speed candidates below the top speed.
const DESIGN_GRID_RATIO: f64 = 0.8;
/// Candidates of that grid: down to `0.8²⁴ ≈ 0.5 %` of the top speed.
const DESIGN_GRID_POINTS: usize = 25;

/// The design speed `vd` (at most `v_top`) and its tangential budget `budget(vd)` that
/// give the least rough time over `max(length, DESIGN_RUN_MM)` from rest to rest: the
/// cruise at `vd` plus one jerk-limited ramp to it ([`change_time_s`]). On a curve a
/// higher design speed leaves less of the axis limits to the tangential motion (the
/// centripetal terms take them), so the fastest cruise is not the quickest segment.
///
/// The choice is a minimum of one measure over every speed up to `v_top`, and a larger
/// limit on any axis only raises `v_top` and every speed's budget: the measure it finds
/// never grows with a limit. (A rule such as "the highest speed whose budget is a fifth
/// of the axis limits" is not: a larger limit moves the threshold and can push the
/// design speed up into a poorer budget or down to a crawl.)
fn design_speed_search(
    length: f64,
    v_top: f64,
    budget: impl Fn(f64) -> Option<(f64, f64)>,
) -> (f64, f64, f64) {
    let run_mm = length;
    let eval = |vd: f64| -> Option<(f64, f64, f64)> {
        let (a, j) = budget(vd)?;
        Some((run_mm / vd + change_time_s(vd, a, j), a, j))
    };
    if !(v_top > 0.0 && v_top.is_finite()) {
        return (v_top.max(0.0), 1e-3, 1e-3);
    }
    // Coarse grid down from the top, stopping once the measure has risen well past its
    // best (it is unimodal in practice: the cruise term falls with vd, the ramp grows);
    // then golden-section search in log vd between the best point's neighbours.
    let grid = |k: usize| v_top * DESIGN_GRID_RATIO.powi(k as i32);
    let mut best: Option<(usize, (f64, f64, f64))> = None;
    for k in 0..DESIGN_GRID_POINTS {
        let e = eval(grid(k));
        if let Some(e) = e {
            if best.is_none_or(|b| e.0 < b.1.0) {
                best = Some((k, e));
            } else if best.is_some_and(|b| k >= b.0 + 3 && e.0 > 1.5 * b.1.0) {
                break;
            }
        }
    }
    // No budget at any of those speeds (the curvature terms used all of it): go on
    // lowering, as they vanish with the speed (v² and v³) and leave the whole tangential
    // budget at a low enough one. A floor of made-up limits would crawl: a 0.07 mm G2
    // blend took 18 s, and a hold on it 6.5 s.
    let mut k_low = DESIGN_GRID_POINTS;
    while best.is_none() && grid(k_low) > v_top * 1e-12 {
        if let Some(e) = eval(grid(k_low)) {
            best = Some((k_low, e));
        }
        k_low += 1;
    }
    let Some((k, mut found)) = best else {
        // Unreachable for finite limits (see above): the lowest speed tried, and a budget
        // as small, keep the segment slow but finite.
        let v = grid(k_low);
        return (v, v, v);
    };
    // The usual case: the top speed is best and the measure rises just below it.
    if k == 0 && eval(0.99 * v_top).is_none_or(|e| e.0 >= found.0) {
        return (v_top, found.1, found.2);
    }
    let mut vd = grid(k);
    let (lo, hi) = (grid(k + 1).ln(), grid(k.saturating_sub(1)).min(v_top).ln());
    let measure = |x: f64| eval(x.exp()).map_or(f64::INFINITY, |e| e.0);
    let (x, _) = golden_min(lo, hi, 10, measure);
    if let Some(e) = eval(x.exp()).filter(|e| e.0 < found.0) {
        vd = x.exp();
        found = e;
    }
    (vd, found.1, found.2)
}

/// Sampled bounds of a transition (with [`LIMIT_SAFETY`] on the curvature terms).
struct TransitionBounds {
    /// Per axis X..C: largest `|t_i|` (unit tangent; for rotary axes `dA/ds`).
    tangent: [f64; 6],
    /// Per axis: largest `|K_i|` (curvature vector; for rotary axes `d²A/ds²`).
    curvature: [f64; 6],
    /// Per axis: largest `|K'_i|` (derivative of the curvature vector along the path).
    curvature_rate: [f64; 6],
    /// Largest curvature `κ`, 1/mm.
    kappa: f64,
    /// Largest `|K' + κ² t| = sqrt(κ'² + (κτ)²)` (the part of `K'` off the tangent), 1/mm².
    kappa_rate: f64,
    /// Per axis: the largest share of a vector in the curve's plane that the axis sees,
    /// `sqrt(1 - N_i²)` for a planar curve with normal `N`, 1 otherwise.
    plane: [f64; 3],
}

/// Bounds of a transition, sampled densely along it.
fn transition_bounds(
    t: &Transition,
    abc: Option<&[[f64; 6]; 3]>,
    samples: usize,
) -> TransitionBounds {
    let mut b = TransitionBounds {
        tangent: [0.0; 6],
        curvature: [0.0; 6],
        curvature_rate: [0.0; 6],
        kappa: 0.0,
        kappa_rate: 0.0,
        plane: [1.0; 3],
    };
    let n = samples;
    // Frames on a grid in u; dK/ds by central differences on the grid (one-sided at the
    // ends), so each sample costs one evaluation.
    // Six-axis frames: XYZ unit tangent and curvature vector, and the rotary axes'
    // derivatives with respect to the XYZ arc length.
    let frame = |i: usize| {
        let u = i as f64 / n as f64;
        let (tan, k) = t.frame_at_param(u);
        let mut t6 = [tan[0], tan[1], tan[2], 0.0, 0.0, 0.0];
        let mut k6 = [k[0], k[1], k[2], 0.0, 0.0, 0.0];
        if let Some(c) = abc {
            let (rt, rk) = rotary_derivatives(t, c, u);
            t6[3..6].copy_from_slice(&rt);
            k6[3..6].copy_from_slice(&rk);
        }
        (tan, k, t6, k6)
    };
    let (mut prev, mut cur) = (frame(0), frame(0));
    for i in 0..=n {
        let next = if i < n { frame(i + 1) } else { cur };
        let (tan, k, t6, k6) = cur;
        let (ia, ib) = (i.saturating_sub(1), (i + 1).min(n));
        let du = (ib - ia) as f64 / n as f64;
        let ka = if i == 0 { cur.3 } else { prev.3 };
        let kb = if i == n { cur.3 } else { next.3 };
        let ds = du * t.speed(i as f64 / n as f64);
        let dk6: [f64; 6] = std::array::from_fn(|ax| (kb[ax] - ka[ax]) / ds);
        let dk = Vec3::new(dk6[0], dk6[1], dk6[2]);
        for ax in 0..6 {
            b.tangent[ax] = b.tangent[ax].max(t6[ax].abs());
            b.curvature[ax] = b.curvature[ax].max(k6[ax].abs());
            b.curvature_rate[ax] = b.curvature_rate[ax].max(dk6[ax].abs());
        }
        let kappa = k.norm();
        b.kappa = b.kappa.max(kappa);
        b.kappa_rate = b.kappa_rate.max((dk + tan * (kappa * kappa)).norm());
        prev = cur;
        cur = next;
    }
    for ax in 0..6 {
        b.tangent[ax] *= 1.001;
        if ax < 3 {
            b.tangent[ax] = b.tangent[ax].min(1.0);
        }
        // Rotary derivatives are sampled like the curvature's derivative: the larger
        // factor.
        b.curvature[ax] *= if ax < 3 {
            CURVATURE_SAFETY
        } else {
            LIMIT_SAFETY
        };
        b.curvature_rate[ax] *= LIMIT_SAFETY;
    }
    b.kappa *= CURVATURE_SAFETY;
    b.kappa_rate *= LIMIT_SAFETY;
    if let Some(normal) = plane_normal(&t.coef) {
        for ax in 0..3 {
            b.plane[ax] = (1.0 - normal[ax] * normal[ax]).max(0.0).sqrt();
        }
    }
    b
}

/// The unit normal of the plane a polynomial curve lies in, if it is planar (and not
/// straight).
fn plane_normal(coef: &[Vec3; 6]) -> Option<Vec3> {
    let scale = coef[1..].iter().map(|c| c.norm()).fold(0.0, f64::max);
    if scale.is_nan() || scale <= 0.0 {
        return None;
    }
    let mut best = Vec3::zeros();
    for i in 1..6 {
        for j in i + 1..6 {
            let c = coef[i].cross(&coef[j]);
            if c.norm() > best.norm() {
                best = c;
            }
        }
    }
    if best.norm() <= 1e-9 * scale * scale {
        return None;
    }
    let normal = best.normalize();
    coef[1..]
        .iter()
        .all(|c| c.dot(&normal).abs() <= 1e-12 * scale)
        .then_some(normal)
}

/// Path limits of a G2 transition. With arc-length parametrisation each axis sees
/// `x_i'' = t_i a + K_i v²` and `x_i''' = t_i j + 3 K_i v a + K'_i v³`. Two bounds hold for
/// every axis and either may be used: the per-axis one, `|t_i| a + |K_i| v²` and
/// `|t_i| j + 3 |K_i| v a + |K'_i| v³` with the sampled maxima; and the Frenet one,
/// `w_i sqrt(a² + (κv²)²)` and `w_i sqrt((j + κ²v³)² + (3κva + |K' + κ²t| v³)²)` (the
/// tangent and normal parts of the vectors are orthogonal; `w_i` is the axis' share of the
/// curve's plane), which is much tighter where the curve turns. They are kept within
/// [`PROFILE_SHARE`] of the limits for every speed up to the design speed, which is chosen
/// like on arcs.
fn transition_limits(
    seg: &PlannedSegment,
    t: &Transition,
    limits: &MachineLimits,
    samples: usize,
    feed_scale: f64,
    run_mm: f64,
) -> (f64, f64, f64) {
    let b = transition_bounds(t, seg.abc_poly.as_ref(), samples);
    let (tm, km, kp) = (b.tangent, b.curvature, b.curvature_rate);
    let share = PROFILE_SHARE;
    let mut v = f64::INFINITY;
    for i in 0..6 {
        let Some(l) = limits.axes[i] else { continue };
        if tm[i] > 0.0 {
            v = v.min(share * l.velocity_units_s / tm[i]);
        }
        if km[i] > 0.0 {
            v = v.min((CENTRIPETAL_SHARE * share * l.acceleration_units_s2 / km[i]).sqrt());
        }
        if kp[i] > 0.0 {
            v = v.min((CENTRIPETAL_SHARE * share * l.jerk_units_s3 / kp[i]).cbrt());
        }
    }
    // Largest tangential acceleration at speed vd, by either bound.
    let accel_at = |vd: f64| -> Option<f64> {
        let mut per_axis = f64::INFINITY;
        let mut frenet = f64::INFINITY;
        for i in 0..6 {
            let Some(l) = limits.axes[i] else { continue };
            let own = axis_rate(share * l.acceleration_units_s2 - km[i] * vd * vd, tm[i]);
            per_axis = per_axis.min(own);
            if i >= 3 {
                // Rotary axes have only the per-axis bound, under either choice.
                frenet = frenet.min(own);
            } else if b.plane[i] > 0.0 {
                let c = share * l.acceleration_units_s2 / b.plane[i];
                let n = b.kappa * vd * vd;
                frenet = frenet.min((c * c - n * n).max(0.0).sqrt());
            }
        }
        let a = per_axis.max(frenet);
        (a > 0.0 && a.is_finite()).then_some(a)
    };
    let jerk_at = |vd: f64, a: f64| -> f64 {
        let mut per_axis = f64::INFINITY;
        let mut frenet = f64::INFINITY;
        for i in 0..6 {
            let Some(l) = limits.axes[i] else { continue };
            let room = share * l.jerk_units_s3 - 3.0 * km[i] * vd * a - kp[i] * vd * vd * vd;
            let own = axis_rate(room, tm[i]);
            per_axis = per_axis.min(own);
            if i >= 3 {
                frenet = frenet.min(own);
            } else if b.plane[i] > 0.0 {
                let c = share * l.jerk_units_s3 / b.plane[i];
                let n = 3.0 * b.kappa * vd * a + b.kappa_rate * vd * vd * vd;
                let tangential = (c * c - n * n).max(0.0).sqrt() - b.kappa * b.kappa * vd.powi(3);
                frenet = frenet.min(tangential.max(0.0));
            }
        }
        per_axis.max(frenet)
    };
    let budget = |vd: f64| -> Option<(f64, f64)> {
        let a_hi = accel_at(vd)?;
        quickest_budget(vd, a_hi, |a| jerk_at(vd, a))
    };
    let run_mm = if seg.move_count > 1 {
        seg.length_mm.max(run_mm)
    } else {
        seg.length_mm
    };
    let search = |v_start: f64| design_speed_search(run_mm, v_start, budget);
    boosted(v, seg.feed_mm_s, feed_scale, search)
}

/// The largest tangential rate (acceleration or jerk) an axis allows when `room` of its
/// limit is left after the curvature terms and it sees `weight` of the tangential rate:
/// none if nothing is left, any if it does not see it.
fn axis_rate(room: f64, weight: f64) -> f64 {
    if room <= 0.0 {
        0.0
    } else if weight > 0.0 {
        room / weight
    } else {
        f64::INFINITY
    }
}

/// The best `(a, j)` on a curved segment at design speed `vd`, if there is a useful one.
fn curved_budget(
    w: &Weights,
    limits: &MachineLimits,
    vd: f64,
    a_line: f64,
    j_line: f64,
) -> Option<(f64, f64)> {
    let share = PROFILE_SHARE;
    if (0..6).all(|i| w.plane[i] == 0.0 || w.axial[i] == 0.0) {
        return curved_budget_closed(w, limits, vd, a_line, j_line);
    }
    let fits_acc = |a: f64| -> bool {
        (0..6).all(|i| match limits.axes[i] {
            None => true,
            Some(l) => {
                let inplane = w.plane[i] * ((w.kappa * vd * vd).powi(2) + (w.q * a).powi(2)).sqrt();
                let straight = if w.plane[i] > 0.0 {
                    w.axial[i]
                } else {
                    w.tangent[i]
                };
                inplane + straight * a <= share * l.acceleration_units_s2
            }
        })
    };
    let fits_jerk = |a: f64, j: f64| -> bool {
        (0..6).all(|i| match limits.axes[i] {
            None => true,
            Some(l) => {
                let tang = w.q * (j + w.sigma * w.sigma * vd * vd * vd);
                let norm = 3.0 * w.kappa * vd * a;
                let inplane = w.plane[i] * (tang * tang + norm * norm).sqrt();
                let straight = if w.plane[i] > 0.0 {
                    w.axial[i]
                } else {
                    w.tangent[i]
                };
                inplane + straight * j <= share * l.jerk_units_s3
            }
        })
    };
    // The smallest axis limits bound the searches from above.
    let (mut a_cap, mut j_cap) = (a_line, j_line);
    for l in limits.axes.iter().flatten() {
        a_cap = a_cap.min(l.acceleration_units_s2 / w.q.max(1e-9));
        j_cap = j_cap.min(l.jerk_units_s3 / w.q.max(1e-9));
    }
    let a_hi = bisect_max(fits_acc, a_cap);
    if a_hi <= 0.0 {
        return None;
    }
    quickest_budget(vd, a_hi, |a| bisect_max(|j| fits_jerk(a, j), j_cap))
}

/// [`curved_budget`] in closed form, for segments where no axis sees both an in-plane and
/// an axial component (every arc in G17/G18/G19 and every blend): per axis the in-plane
/// constraints `w·sqrt((κv²)² + (qa)²) ≤ A` and `w·sqrt((q(j + σ²v³))² + (3κva)²) ≤ J`
/// solve directly for `a` and `j`.
fn curved_budget_closed(
    w: &Weights,
    limits: &MachineLimits,
    vd: f64,
    a_line: f64,
    j_line: f64,
) -> Option<(f64, f64)> {
    let share = PROFILE_SHARE;
    let centripetal = w.kappa * vd * vd;
    let mut a_hi = a_line;
    for i in 0..6 {
        let (Some(l), true) = (limits.axes[i], w.plane[i] > 0.0) else {
            continue;
        };
        let b = share * l.acceleration_units_s2 / w.plane[i];
        let room = b * b - centripetal * centripetal;
        if room <= 0.0 {
            return None;
        }
        a_hi = a_hi.min(room.sqrt() / w.q);
    }
    if !(a_hi > 0.0 && a_hi.is_finite()) {
        return None;
    }
    let jerk_for = |a: f64| -> f64 {
        let mut j = j_line;
        let normal = 3.0 * w.kappa * vd * a;
        for i in 0..6 {
            let (Some(l), true) = (limits.axes[i], w.plane[i] > 0.0) else {
                continue;
            };
            let c = share * l.jerk_units_s3 / w.plane[i];
            let room = c * c - normal * normal;
            if room <= 0.0 {
                return 0.0;
            }
            j = j.min(room.sqrt() / w.q - w.sigma * w.sigma * vd * vd * vd);
        }
        j
    };
    quickest_budget(vd, a_hi, jerk_for)
}

/// Grid ratio of [`quickest_budget`]'s coarse search over the acceleration.
const BUDGET_GRID_RATIO: f64 = 0.5;
/// Points of that grid: it spans `a_hi` down to `a_hi·0.5²⁰ ≈ 1e-6·a_hi`.
const BUDGET_GRID_POINTS: usize = 21;

/// The tangential budget `(a, j)` on a curve at design speed `vd` that makes the
/// quickest jerk-limited change of speed by `vd` ([`change_time_s`]), for accelerations
/// up to `a_hi` and the jerk `jerk_for(a)` the axes leave at each (it falls as `a` grows:
/// the normal jerk `3κva` takes its share). `None` if no acceleration leaves any jerk.
///
/// The acceleration is chosen for the time it gives, never as a share of `a_hi`: on a
/// machine with a large acceleration and a small jerk any fixed share of `a_hi` can leave
/// no jerk at all (a circle of 10 mm at 10 mm/s with jerk 1,000 mm/s³ and 200,000 mm/s²:
/// 5 % of the acceleration makes `3κva` alone 30 times the jerk), and the design speed
/// then fell to a crawl. And it is never more than a change of speed by `vd` can use:
/// such a ramp peaks at `sqrt(vd·j)`. A larger limit on any axis only widens the choice
/// (more `a_hi`, more jerk at every `a`), so the time this budget gives never grows.
fn quickest_budget(vd: f64, a_hi: f64, jerk_for: impl Fn(f64) -> f64) -> Option<(f64, f64)> {
    if !(vd > 0.0 && a_hi > 0.0) || vd.is_infinite() {
        return None;
    }
    // The jerk left is largest at a = 0, and a ramp by `vd` never reaches more than
    // `sqrt(vd·j)`: nothing above `sqrt(vd·j(0))` is worth trying.
    let j0 = jerk_for(0.0);
    if j0.is_nan() || j0 <= 0.0 {
        return None;
    }
    let a_hi = a_hi.min((vd * j0).sqrt()).min(f64::MAX.sqrt());
    let cost = |a: f64| -> f64 {
        let j = jerk_for(a);
        if j > 0.0 && j.is_finite() {
            change_time_s(vd, a, j)
        } else {
            f64::INFINITY
        }
    };
    // Coarse: a geometric grid down from `a_hi`, until the time has risen for two points
    // past the best (it falls and then rises with a); then golden-section search (in
    // log a) around the best grid point.
    let mut best = (f64::INFINITY, 0usize);
    let grid = |k: usize| a_hi * BUDGET_GRID_RATIO.powi(k as i32);
    for k in 0..BUDGET_GRID_POINTS {
        let c = cost(grid(k));
        if c < best.0 {
            best = (c, k);
        } else if best.0.is_finite() && k >= best.1 + 2 {
            break;
        }
    }
    if !best.0.is_finite() {
        return None;
    }
    let k = best.1;
    if k == 0 && cost(0.99 * a_hi) >= best.0 {
        let j = jerk_for(a_hi);
        return Some((a_hi, j));
    }
    let (lo, hi) = (
        grid((k + 1).min(BUDGET_GRID_POINTS - 1)).ln(),
        grid(k.saturating_sub(1)).ln(),
    );
    let (x, c) = golden_min(lo, hi, 14, |x| cost(x.exp()));
    let mut a = grid(k);
    if c < best.0 {
        a = x.exp();
    }
    let j = jerk_for(a);
    // Never more acceleration than a ramp by `vd` reaches (`a = sqrt(vd·j(a))`, found by
    // bisection): less leaves the same ramp time and more jerk room.
    if a * a > vd * j {
        let lo = bisect(0.0, a, 60, |x| x * x <= vd * jerk_for(x));
        let j_lo = jerk_for(lo);
        if lo > 0.0 && j_lo >= j {
            return Some((lo, j_lo));
        }
    }
    Some((a, j))
}

/// Golden-section search for the minimum of `cost` on `[lo, hi]` (`steps` narrowings):
/// the better of the last two points, and its cost.
fn golden_min(mut lo: f64, mut hi: f64, steps: usize, cost: impl Fn(f64) -> f64) -> (f64, f64) {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut x1, mut x2) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut c1, mut c2) = (cost(x1), cost(x2));
    for _ in 0..steps {
        if c1 <= c2 {
            hi = x2;
            x2 = x1;
            c2 = c1;
            x1 = hi - g * (hi - lo);
            c1 = cost(x1);
        } else {
            lo = x1;
            x1 = x2;
            c1 = c2;
            x2 = lo + g * (hi - lo);
            c2 = cost(x2);
        }
    }
    if c1 <= c2 { (x1, c1) } else { (x2, c2) }
}

/// Largest `x` in `[0, hi]` with `ok(x)` (assumes `ok` is monotone), to 1e-6 relative.
fn bisect_max(ok: impl Fn(f64) -> bool, hi: f64) -> f64 {
    if ok(hi) {
        return hi;
    }
    // Find a finite bracket first when `hi` is huge.
    let mut lo = 0.0;
    let mut up = hi;
    for _ in 0..60 {
        let mid = 0.5 * (lo + up);
        if ok(mid) {
            lo = mid;
        } else {
            up = mid;
        }
        if up - lo <= 1e-6 * up {
            break;
        }
    }
    lo
}

/// Speed cap at the junction from `a` to `b`, from the tangent and curvature steps seen by
/// finite differences at the period.
pub fn junction_cap(a: &PlannedSegment, b: &PlannedSegment, limits: &MachineLimits) -> f64 {
    let (ta, ka) = a.derivatives_at(a.length_mm);
    let (tb, kb) = b.derivatives_at(0.0);
    let t = limits.period_s;
    let mut cap = a
        .v_boost_mm_s
        .max(a.v_max_mm_s)
        .min(b.v_boost_mm_s.max(b.v_max_mm_s));
    for i in 0..6 {
        let dt = (tb[i] - ta[i]).abs();
        let dk = (kb[i] - ka[i]).abs();
        let Some(l) = limits.axes[i] else {
            if dt > 0.0 || dk > 0.0 {
                return 0.0;
            }
            continue;
        };
        if dt > 1e-12 {
            cap = cap.min(
                JUNCTION_SHARE * (l.jerk_units_s3 * t * t).min(l.acceleration_units_s2 * t) / dt,
            );
        }
        if dk > 1e-12 {
            cap = cap.min((JUNCTION_SHARE * l.jerk_units_s3 * t / dk).sqrt());
        }
    }
    cap.max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerf_geom::{Arc, Line};

    fn mill() -> MachineLimits {
        let l = AxisLimits {
            velocity_units_s: 200.0,
            acceleration_units_s2: 2000.0,
            jerk_units_s3: 50000.0,
        };
        MachineLimits {
            axes: [Some(l), Some(l), Some(l), None, None, None],
            period_s: 0.001,
            tolerance_mm: 0.01,
        }
    }

    fn mv(path: Path, feed: f64) -> Move {
        Move {
            line: 1,
            rapid: false,
            path,
            feed_mm_min: Some(feed),
            abc_deg: None,
            corner: CornerMode::Blend { tolerance_mm: None },
        }
    }

    fn plan(moves: &[Move]) -> Vec<PlannedSegment> {
        let mut p = Planner::new(mill());
        let mut out = Vec::new();
        for m in moves {
            p.push(m, &mut out).unwrap();
        }
        p.finish(&mut out);
        out
    }

    #[test]
    fn diagonal_line_uses_both_axes() {
        // Along (1, 1, 0)/√2 each axis sees 1/√2 of the path: share · limit · √2.
        let line = Line {
            start: Vec3::zeros(),
            end: Vec3::new(10.0, 10.0, 0.0),
        };
        let segs = plan(&[mv(Path::Line(line), 60000.0)]);
        let s2 = std::f64::consts::SQRT_2;
        let share = PROFILE_SHARE;
        assert!((segs[0].v_max_mm_s - share * 200.0 * s2).abs() < 1e-9);
        assert!((segs[0].accel_mm_s2 - share * 2000.0 * s2).abs() < 1e-9);
        assert!((segs[0].jerk_mm_s3 - share * 50000.0 * s2).abs() < 1e-9);
        assert_eq!(segs[0].end_cap_mm_s, 0.0);
    }

    #[test]
    fn arc_budget_respects_every_axis_at_the_feed() {
        // r = 10 at 100 mm/s: centripetal 1000 mm/s², jerk v³/r² = 10,000 mm/s³.
        let arc = Arc {
            start: Vec3::new(10.0, 0.0, 0.0),
            end: Vec3::new(-10.0, 0.0, 0.0),
            center: Vec3::zeros(),
            axis: Vec3::z(),
            sweep_rad: std::f64::consts::PI,
        };
        let segs = plan(&[mv(Path::Arc(arc), 6000.0)]);
        let s = &segs[0];
        assert!((s.v_max_mm_s - 100.0).abs() < 1e-9);
        let (k, v) = (0.1, s.v_max_mm_s);
        let share = PROFILE_SHARE;
        assert!(((k * v * v).powi(2) + s.accel_mm_s2.powi(2)).sqrt() <= share * 2000.0 + 1e-6);
        let tang = s.jerk_mm_s3 + k * k * v * v * v;
        let norm = 3.0 * k * v * s.accel_mm_s2;
        assert!((tang * tang + norm * norm).sqrt() <= share * 50000.0 + 1e-6);
        // The budget is worth having: more than a third of the limits.
        assert!(s.accel_mm_s2 > 2000.0 / 3.0 && s.jerk_mm_s3 > 50000.0 / 3.0);
    }

    /// Line along +X, tangent quarter arc of radius 5 (CCW), tangent line along +Y.
    fn line_arc_line() -> Vec<Move> {
        let b = Vec3::new(20.0, 0.0, 0.0);
        let c = Vec3::new(25.0, 5.0, 0.0);
        vec![
            mv(
                Path::Line(Line {
                    start: Vec3::zeros(),
                    end: b,
                }),
                3000.0,
            ),
            mv(
                Path::Arc(Arc {
                    start: b,
                    end: c,
                    center: Vec3::new(20.0, 5.0, 0.0),
                    axis: Vec3::z(),
                    sweep_rad: std::f64::consts::FRAC_PI_2,
                }),
                3000.0,
            ),
            mv(
                Path::Line(Line {
                    start: c,
                    end: Vec3::new(25.0, 25.0, 0.0),
                }),
                3000.0,
            ),
        ]
    }

    #[test]
    fn g2_transitions_match_position_tangent_and_curvature() {
        let moves = line_arc_line();
        let segs = plan(&moves);
        let kinds: Vec<_> = segs
            .iter()
            .map(|s| matches!(s.curve, Curve::Transition(_)))
            .collect();
        assert_eq!(kinds, [false, true, false, true, false]);
        let origins: Vec<Curve> = moves.iter().map(|m| Curve::from_path(&m.path)).collect();
        for w in segs.windows(2) {
            // Continuous position at every joint, exactly.
            assert_eq!(w[0].curve.end(), w[1].curve.start());
        }
        let h = 1e-4;
        for k in [1, 3] {
            let (a, t, b) = (&segs[k - 1], &segs[k], &segs[k + 1]);
            // Finite differences of the transition at its ends (arc length h inside) against
            // the neighbours' exact tangent and curvature.
            let fd = |c: &Curve, s: f64| {
                let p = |x: f64| c.point_at(x);
                let d1 = (p(s + h) - p(s - h)) / (2.0 * h);
                let d2 = (p(s + h) - p(s) * 2.0 + p(s - h)) / (h * h);
                (d1, d2)
            };
            let ea = a.curve.eval(a.length_mm);
            let eb = b.curve.eval(0.0);
            let (t0, k0) = fd(&t.curve, 2.0 * h);
            let (t1, k1) = fd(&t.curve, t.length_mm - 2.0 * h);
            // Tangent: O(h·κ) from the offset; curvature: O(h·κ') and rounding.
            assert!((t0 - ea.tangent).norm() < 1e-3, "{t0} {}", ea.tangent);
            assert!((t1 - eb.tangent).norm() < 1e-3, "{t1} {}", eb.tangent);
            assert!((k0 - ea.curvature).norm() < 5e-3, "{k0} {}", ea.curvature);
            assert!((k1 - eb.curvature).norm() < 5e-3, "{k1} {}", eb.curvature);
            // Unit speed: the arc-length table is right.
            for i in 1..100 {
                let s = t.length_mm * i as f64 / 100.0;
                let (d1, _) = fd(&t.curve, s);
                assert!((d1.norm() - 1.0).abs() < 1e-6, "{}", d1.norm());
            }
            // Within the tolerance of the programmed path, measured densely.
            let dev = (0..=2000)
                .map(|i| {
                    let p = t.curve.point_at(t.length_mm * i as f64 / 2000.0);
                    origins
                        .iter()
                        .map(|o| o.distance_to(&p))
                        .fold(f64::INFINITY, f64::min)
                })
                .fold(0.0, f64::max);
            assert!(dev <= 0.01 && dev > 0.001, "{dev}");
            // The joint runs far faster than the curvature-step cap sqrt(0.05·J·T·r).
            let step_cap = (JUNCTION_SHARE * 50000.0 * 0.001 * 5.0).sqrt();
            assert!(a.end_cap_mm_s > 5.0 * step_cap && t.end_cap_mm_s > 5.0 * step_cap);
            assert!(t.v_max_mm_s > 5.0 * step_cap);
        }
    }

    #[test]
    fn collinear_joint_runs_through_and_exact_stop_stops() {
        let a = Vec3::zeros();
        let b = Vec3::new(5.0, 0.0, 0.0);
        let c = Vec3::new(9.0, 0.0, 0.0);
        let d = Vec3::new(9.0, 4.0, 0.0);
        let first = mv(Path::Line(Line { start: a, end: b }), 3000.0);
        let mut second = mv(Path::Line(Line { start: b, end: c }), 3000.0);
        second.corner = CornerMode::ExactStop;
        let third = mv(Path::Line(Line { start: c, end: d }), 3000.0);
        let segs = plan(&[first, second, third]);
        assert_eq!(
            segs.len(),
            3,
            "no blend at a collinear joint or an exact stop"
        );
        assert_eq!(
            segs[0].end_cap_mm_s,
            segs[0].v_max_mm_s.min(segs[1].v_max_mm_s)
        );
        assert_eq!(segs[1].end_cap_mm_s, 0.0);
    }

    /// Finite differences of a curve at `s` with step `h`: (first, second derivative).
    fn fd(c: &Curve, s: f64, h: f64) -> (Vec3, Vec3) {
        let p = |x: f64| c.point_at(x);
        let d1 = (p(s + h) - p(s - h)) / (2.0 * h);
        let d2 = (p(s + h) - p(s) * 2.0 + p(s - h)) / (h * h);
        (d1, d2)
    }

    #[test]
    fn sharp_isolated_corner_stops_where_that_is_quicker() {
        // 90° between two 10 mm lines at 0.01 mm: any blend must slow nearly to a stop and
        // then crawl through it, so the corner is taken as a stop (no blend segment, a
        // near-zero cap from the kink).
        let (a, b, c) = (
            Vec3::zeros(),
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(10.0, 10.0, 0.0),
        );
        let moves = [
            mv(Path::Line(Line { start: a, end: b }), 3000.0),
            mv(Path::Line(Line { start: b, end: c }), 3000.0),
        ];
        let segs = plan(&moves);
        assert_eq!(segs.len(), 2);
        assert_eq!(segs[0].curve.end(), b);
        assert!(segs[0].end_cap_mm_s < 0.01, "{}", segs[0].end_cap_mm_s);
    }

    #[test]
    fn isolated_corner_gets_a_g2_blend() {
        // A 10° corner between two 10 mm lines at 0.01 mm: the blend takes a few
        // millimetres at most, so the corner is isolated, and a G2 blend is quicker than
        // an arc (whose joints are curvature steps) or a stop.
        let th = 10f64.to_radians();
        let (a, b) = (Vec3::zeros(), Vec3::new(10.0, 0.0, 0.0));
        let u2 = Vec3::new(th.cos(), th.sin(), 0.0);
        let c = b + u2 * 10.0;
        let moves = [
            mv(Path::Line(Line { start: a, end: b }), 3000.0),
            mv(Path::Line(Line { start: b, end: c }), 3000.0),
        ];
        let segs = plan(&moves);
        assert_eq!(segs.len(), 3);
        let Curve::Transition(_) = segs[1].curve else {
            panic!("expected a G2 blend, got {:?}", segs[1].curve)
        };
        assert!(segs[1].blend && !segs[0].blend && !segs[2].blend);
        for w in segs.windows(2) {
            assert_eq!(w[0].curve.end(), w[1].curve.start());
        }
        let t = &segs[1];
        let len = t.length_mm;
        // Symmetric: it takes the same distance d from both lines.
        let d = (b - t.curve.start()).norm();
        assert!((d - (t.curve.end() - b).norm()).abs() < 1e-12);
        // Tangent of the lines and zero curvature at both ends, by finite differences
        // (the curvature extrapolated to the end from 2h and 4h inside: it grows
        // linearly from zero there).
        let h = 1e-4;
        for (s, sign, u) in [(0.0, 1.0, Vec3::x()), (len, -1.0, u2)] {
            let (t1, k1) = fd(&t.curve, s + sign * 2.0 * h, h);
            let (_, k2) = fd(&t.curve, s + sign * 4.0 * h, h);
            let k_end = k1 * 2.0 - k2;
            assert!((t1 - u).norm() < 1e-3, "tangent {t1} at {s}");
            // The circular blend's curvature is 1/r ≈ 0.4 /mm, all of it a step.
            assert!(k_end.norm() < 0.01, "curvature {k_end} at {s}");
        }
        // Unit speed inside (the arc-length table is right).
        for i in 1..100 {
            let (d1, _) = fd(&t.curve, len * i as f64 / 100.0, 1e-5);
            assert!((d1.norm() - 1.0).abs() < 1e-6, "{}", d1.norm());
        }
        // Within the tolerance of the two lines, densely, and using most of it.
        let lines: Vec<Curve> = moves.iter().map(|m| Curve::from_path(&m.path)).collect();
        let dev = (0..=5000)
            .map(|i| {
                let p = t.curve.point_at(len * i as f64 / 5000.0);
                lines
                    .iter()
                    .map(|l| l.distance_to(&p))
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max);
        assert!(dev <= 0.01 && dev > 0.008, "{dev}");
        // The joints have no curvature step, so only the blend itself limits the speed, and
        // that is far above the circular blend's curvature-step cap sqrt(0.05·J·T·r) with
        // r (1 - cos 5°) = 0.98 · tolerance.
        let r = 0.98 * 0.01 / (1.0 - (th / 2.0).cos());
        let step_cap = (JUNCTION_SHARE * 50000.0 * 0.001 * r).sqrt();
        assert!(
            t.v_max_mm_s > 5.0 * step_cap,
            "{} vs {step_cap}",
            t.v_max_mm_s
        );
        assert_eq!(segs[0].end_cap_mm_s, t.v_max_mm_s);
        assert_eq!(t.end_cap_mm_s, t.v_max_mm_s);
        // Its limits hold at v_max: centripetal |K|v² within the axis acceleration.
        let k_peak = (0..=1000)
            .map(|i| t.curve.eval(len * i as f64 / 1000.0).curvature.norm())
            .fold(0.0, f64::max);
        assert!(k_peak * t.v_max_mm_s * t.v_max_mm_s <= 2000.0, "{k_peak}");
    }
}
