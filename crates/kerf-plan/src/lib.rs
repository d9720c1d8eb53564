//! Segment and junction limits and corner blending for Kerf.
//!
//! [`Planner`] turns the front end's [`Move`](kerf_geom::Move)s, in program order, into
//! [`PlannedSegment`]s for the motion core. It runs off the real-time path and may
//! allocate (per transition, its sampled bounds), within bounded memory: the smoother
//! holds a window of the run, the memos a fixed number of slots. Its job is everything
//! about a segment that does not depend on time: geometry, corner blends, and the
//! kinematic limits along and between segments. The code is split by concern: `planner`
//! (streaming), `run` and `smooth` (dense polylines), `blend` (corners), `transition`
//! (joints with arcs), `budget` (limits along a segment), `junction` (caps between
//! segments).
//!
//! Design decisions:
//! - **Corner blends between two lines are circular arcs** (G2 blends or a stop where
//!   quicker, and G2 blends narrowed to their room on faceted code, below), tangent to
//!   both, as large as the tolerance allows and taking at most half of the outgoing move
//!   (and at most what the previous blend left of the incoming move). Dense polylines are smoothed instead (below). Joints touching an
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
//!   (the smoother emits nothing of a run before that much of it is known); for a G2
//!   transition at a joint with an arc, like an arc, the path that runs on without a
//!   corner up to the end of the move after it, at most `DESIGN_RUN_MM` (designed for
//!   their own short length from rest, transitions would hold the arcs and lines beside
//!   them below the speed that fits);
//!   for a circular corner blend its own length; for a G2 corner blend `DESIGN_RUN_MM`
//!   (it is entered and left at speed, the lines do the slowing), and for one narrowed to
//!   its room (below) the corner-free path behind it and its own length, at most
//!   `DESIGN_RUN_MM` (on a chain of them along a short polygon, designed for 30 mm, a
//!   raised limit chose a higher design speed with less tangential budget, and the chain
//!   of a few tenths of a millimetre ran slower). These distances are
//!   geometry only, never the limits. At each design speed the tangential acceleration
//!   is the one that makes that ramp quickest given the jerk the axes leave at it (the
//!   normal jerk `3κva` grows with it), never a share of the axis limit and never more than
//!   the ramp can use, `sqrt(v·j)`. Both choices are minima over sets that only grow when
//!   an axis limit is raised, so raising one never lowers the design by that measure.
//!   (Fractions of the axis limit would not do: with a large acceleration and a small
//!   jerk every fraction can leave no jerk, and a circle then crawls.)
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
//! - **Ramp budgets at stops**: a smoothed piece that starts or ends at a
//!   junction capped below half its design speed gets the tangential budget of
//!   `budget::ramp_budget` where that stops quicker: there the speed obeys
//!   `v² ≤ cap² + 2a·distance` (the motion core keeps the path acceleration within `a` and
//!   the junctions within their caps), so the curvature terms are checked at that lower
//!   speed, sample by sample, instead of at the design speed. Where only the start is
//!   slow, the raised budget splits a motion-core section mid-ramp, so it is used only
//!   where a rough estimate says that pays. Budgets are compared by the stop they give
//!   where they run: a piece entered at speed joins the motion-core section the segment
//!   before it runs in when its limits and speed are like that section's first segment's
//!   and its conservative speed (`kerf_geom::limits_merge`, `kerf_geom::speeds_merge_into`;
//!   the planner follows the sections as the core will group them, `section`), and then
//!   runs at the least limits of the section and itself. The curvature
//!   terms are checked under the jerk-limited envelope: at speed `u` a ramp whose top
//!   speed is `v_max` has at most `sqrt(2j(v_max − u))` of acceleration left.
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
//!   transition is kept only if it makes the joint faster and, if it runs below 30 %
//!   of the neighbours' speed, takes at most 20 ms (crawling round a sharp kink at a tiny
//!   tolerance is slower than stopping at it); otherwise the joint is taken at its cap as
//!   before. Rotary motion on either side, exact stops and joints between two lines are
//!   left alone. A transition makes [`PlannedSegment`] a few hundred bytes larger (the
//!   curve carries its arc-length table inline).
//!   Its limits come from sampled per-axis bounds of `|t_i|`, `|K_i|` and `|K'_i|`
//!   (curvature vector and its arc-length derivative; for X, Y, Z the derivative in closed
//!   form at each sample, with a bound on the rise between samples and [`RATE_SAFETY`];
//!   for the rotary axes A, B, C (`K_i = d²A/ds²`) by central differences on the
//!   samples, with [`LIMIT_SAFETY`] on both their bounds): with arc-length parametrisation
//!   `x_i'' = t_i a + K_i v²` and `x_i''' = t_i j + 3K_i v a + K'_i v³`. The bounds are
//!   taken on each of eight equal stretches of the parameter and the budget is the least
//!   of the stretches' (`budget::bounds`): one set of maxima over the whole curve counts
//!   the steepest tangent, the largest curvature and its fastest change as if they came
//!   together, where on a 2 mm piece of a wavy surface they lie a millimetre apart.
//!   Example: r = 5 mm, 0.01 mm tolerance, F3000 on a 2,000 mm/s², 50,000 mm/s³ mill: the
//!   joints run at the full 50 mm/s instead of 3.5 mm/s.
//! - **Dense polylines are smoothed** (module `smooth`): runs of short feed lines with small
//!   turns (CAM output approximating a curve) become curvature-continuous quintic pieces
//!   with knots at vertices of the polyline (moved within their rounding), with positions,
//!   tangents and curvatures fitted over windows of vertices, each piece checked to stay within the tolerance of the lines it replaces.
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
//!   Where the widest G2 blend would not fit (its reach beyond the room the neighbouring
//!   corners leave: facets of a millimetre meeting at a few degrees, as mesh-based CAM
//!   writes, at a tolerance too small to smooth them) the largest one that fits is taken,
//!   over the arc whatever the estimate says when it reaches at least half the arc's
//!   distance: there the arc takes its whole room too and meets the neighbouring blends
//!   through curvature steps that the estimate (which judges chained arcs as entered from
//!   arcs like themselves) does not charge, and the speed fell to rest at most facet
//!   edges; the narrowed G2 blends meet at zero curvature. The CAM table's faceted raster:
//!   9.05 s → 5.34 s (1.36× the jerk-limited bound). A narrowed blend is tried at the
//!   first parameter scale that reaches its room only (planning cost). Circular arcs stay
//!   where the lines leave no room, and where the narrowed blend would reach under half
//!   the arc's distance and the estimate prefers the arc. Rotary motion and exact stops are left alone as for arcs.
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
//!   [`JUNCTION_SHARE`] of the jerk limit (and the velocity step within that share of the
//!   acceleration limit over a period). Kinks closer together than a period's travel fall
//!   several into one finite-difference window, where they add up like a curvature
//!   `Δt/L` (`L` the shorter of the two segments): the cap also keeps `v²Δt/L` within the
//!   same share, which binds only where `L < vT`. An exact-stop corner has cap 0.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

// The planner's input and output types live in kerf-geom (the motion core reads them
// too); re-exported here because they are this crate's API.
pub use kerf_geom::{AXIS_NAMES, AxisLimits, MachineLimits, PlannedSegment};

mod blend;
mod budget;
mod grid_search;
mod junction;
mod memo;
mod planner;
mod run;
mod search;
mod section;
mod smooth;
mod timing;
mod transition;

pub use blend::G2_LAMBDA_RATIOS;
pub use budget::{CURVATURE_SAFETY, DESIGN_RUN_MM, LIMIT_SAFETY, RATE_SAFETY, segment_limits};
pub use junction::junction_cap;
pub use planner::Planner;
pub use smooth::MAX_PIECE_MOVES;
pub use transition::TRANSITION_SHARE_OF_MOVE;

/// Highest feed override curved segments are designed for: the machine's highest override
/// ([`kerf_geom::MAX_FEED_OVERRIDE`], which the motion core clamps to), so no override
/// asks for more than a boost design covers.
pub const MAX_DESIGN_OVERRIDE: f64 = kerf_geom::MAX_FEED_OVERRIDE;
/// Share of every axis limit that the path profile may use: 95 %, so that with the 5 %
/// of [`JUNCTION_SHARE`] the profile and the junction steps together stay within 100 %.
pub const PROFILE_SHARE: f64 = 0.95;
/// Share of every axis jerk limit left for the steps at junctions: what the profile
/// leaves (`1 - PROFILE_SHARE`).
pub const JUNCTION_SHARE: f64 = 0.05;
/// Segments shorter than this are dropped, mm: 1 pm, far below any machine's resolution,
/// so nothing that could be seen is lost.
pub const MIN_SEGMENT_MM: f64 = 1e-9;
/// Share of the tolerance a G2 transition may deviate from the programmed path at the
/// sampled points: the other 10 % covers the path between the [`DEVIATION_SAMPLES`].
pub const TRANSITION_TOL_SHARE: f64 = 0.9;
/// Samples of a transition checked against the tolerance: 128, dense enough on a smooth
/// quintic for the 10 % that [`TRANSITION_TOL_SHARE`] leaves to cover the path between.
pub const DEVIATION_SAMPLES: usize = 128;
/// Shortest piece of a segment a transition or blend may leave, mm: 1 µm, a thousand
/// times the motion core's coast-through length (`kerf_motion::COAST_BELOW_MM`), so a
/// remnant is still a section the profile generator plans.
pub const MIN_REMNANT_MM: f64 = 1e-3;

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

#[cfg(test)]
mod tests;
