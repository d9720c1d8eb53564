//! Kerf's real-time motion core: segment queue, lookahead and jerk-limited interpolation.
//!
//! [`MotionCore`] holds a fixed-capacity queue of [`PlannedSegment`]s (from `kerf-plan`,
//! the type lives in `kerf-geom`: this crate depends on `kerf-geom` and `rsruckig` only)
//! and produces one [`Setpoint`] per [`MotionCore::step`]. Everything is allocated in
//! [`MotionCore::new`]; `push` and `step` never allocate, lock or do I/O. Apart from the
//! path, [`AxisMove`] moves one axis on its own (jogging, homing): jerk-limited moves to a
//! target and runs at a velocity, re-planned from any state, stepped the same way.
//!
//! Design decisions:
//! - **Sections.** Consecutive segments are grouped into sections whose limits are the
//!   minima over their segments and interior junction caps. A segment joins the open tail
//!   section while its limits stay within [`MERGE_RATIO`] (jerk: [`MERGE_RATIO_JERK`];
//!   speed and feed: [`MERGE_RATIO_SPEED`]) of the section's first segment and the
//!   junction before it can be passed at that speed. Its speed `min(v_max, feed)` must
//!   not be more than that ratio *above* the first segment's either: the section runs at
//!   its minima, so a long fast segment merged behind a short slow one (a low feed, a
//!   tight G2 transition) would otherwise crawl at the slow one's speed. For the same
//!   reason its acceleration and jerk must not exceed [`MERGE_ABOVE`] times the first
//!   segment's (a line behind a short corner blend would stop with the blend's jerk),
//!   unless it is a line no longer than the first segment ([`MERGE_SHORT_SHARE`]: the short
//!   lines between narrowed corner blends carry the axes' own limits, and a raised axis
//!   limit must not make each of them a section boundary). A
//!   segment up to 3 % slower than the first ([`MERGE_RATIO_SLOWER`]) still joins, the
//!   section then running at its speed, where nothing was committed faster: the tail
//!   section's hard lookahead (it must stop within itself) is below the segment's
//!   conservative speed, so no boundary speed falls. A slow-down across smoothed pieces
//!   whose speeds differ by a per cent or two is then one ramp, not a stair of sections
//!   each ending at `a = 0`. Likewise a segment with down to [`MERGE_RATIO_WEAKER`] of the
//!   first's acceleration (its jerk within the merge rule's bounds) joins a tail
//!   section short enough that the stop at the queue's end reaches back into it, where
//!   the section's hard start speed, recomputed over the longer section at the lower
//!   conservative limits, does not fall (nothing committed against it), and it is not
//!   the section after the running one (a speed-up may be carried into that): the braking
//!   before a stop then runs through pieces whose budgets differ by 10–20 % without a
//!   return to `a = 0` between them; the weaker segment becomes the section's reference
//!   for the merge rule. The running
//!   section is frozen; segments it has passed are released at once, so a program longer
//!   than the queue never stops for room. Dense CAM code thus becomes a few long
//!   sections, and the one-dimensional path profile only has `a = 0` at section
//!   boundaries, not at every tiny segment.
//! - **Profiles.** Each section's path parameter `s(t)` is one jerk-limited profile from
//!   `rsruckig` (position interface, `min_velocity = 0`, target = section end with the
//!   lookahead's end speed and `a = 0`). A section too short to finish its speed-up
//!   hands it on instead: its target is the highest end speed it can reach with some
//!   acceleration `a1 > 0`, the next section starting from that state, where the speed
//!   `v1 + a1²/2j` at which the next section has brought the acceleration to zero (at its
//!   conservative jerk) is within its start and end lookahead speeds and that happens
//!   within its length (see `MotionCore::carry_target`). The next section is then entered
//!   as if at `a = 0` within its hard lookahead, a few jerk-limited milliseconds later, so
//!   every lookahead argument below still holds; a ramp across short sections is one ramp,
//!   not a stair of `a = 0` steps. A slow-down whose next section slows down further goes
//!   on into it the same way, with some deceleration `a1 < 0`, at the highest speed from
//!   which the next section's quickest fall (at its conservative limits) still reaches its
//!   end speed and its hard end speed within its length, within the envelope of both
//!   sections and the junction's cap, and into the queue's tail only within its hard start
//!   speed; the next section counts such an entry as within its hard lookahead by that
//!   fall (see `MotionCore::carry_target`). `calculate()` runs once per section and per event
//!   (override, hold, resume, more queue); `at_time()` samples it every cycle. Time left
//!   over when a profile ends inside a cycle carries into the next section, so a segment
//!   shorter than one period never slows the feed.
//! - **Lookahead.** A backward pass over the sections with the closed-form jerk-limited
//!   reachability of [`reach_back`] (`a = 0` at boundaries) decides the highest speed at
//!   each section boundary from which the queue end can still be reached at rest. (A
//!   jerk-limited partial slow-down can need more distance than a full stop, so "at most
//!   v" at the far end is reachable from the larger of the two start speeds.) It runs in
//!   `push` from the tail and stops at the first section whose value does not change (or
//!   after `MAX_BACKWARD_SECTIONS`: hard speeds only grow with the queue, so a value left
//!   stale is a lower, safe one).
//!   Two values are kept: a *hard* one from conservative limits fixed when the section is
//!   created (so it only ever grows as the queue grows, and is safe at any override) and a
//!   *soft* one with the programmed feed at the current override. Profiles target the
//!   soft speed when it is reachable and never exceed the hard one, so a feed change never
//!   endangers an axis limit.
//! - **Queue end = stop.** The tail section always ends at rest; the motion never commits
//!   to more than it can stop from within the segments it holds.
//! - **Hold / abort** plan a jerk-limited stop (velocity interface) on the path with the
//!   lowest limits of every section it crosses, after checking that it passes every
//!   junction at or below its hard speed and stops before the queue end; otherwise the
//!   running plan goes on and the check is made again as each next section starts (the
//!   plan may still be finishing a speed-up, one carried into that section included:
//!   within the limits, but the stop starts that much later).
//! - **Override** scales the programmed feed (0–200 %); it re-plans the running section
//!   from the current state and recomputes the soft lookahead (one pass over the queue, on
//!   the event). Curved segments have two levels of limits (see `kerf-plan`): the base
//!   one for their design speed and a boost one, with lower accelerations, up to the
//!   speed of the highest override. Each section has a hard lookahead per level; a
//!   section runs at the boost level only while the override asks for more than its base
//!   speed, choosing as it starts (or mid-way, when the override rises, once its state is
//!   within the boost limits and its end is still reachable with them), and keeps that
//!   level to its end. Stops for a hold use limits valid at both levels. Rapids run at
//!   the axis limits whatever the override. Zero override stops like a hold; raising it
//!   resumes unless the operator holds as well.
//! - **Continuity** is checked at `push`: a segment must start where the previous one (or,
//!   on an idle core, the machine) is, within [`CONTINUITY_MM`], or it is refused.
//! - **Bounded cycle**: evaluating a segment is O(1) on every curve kind, G2 transitions
//!   included (table lookup, a cubic interpolation and one Newton step on the arc length,
//!   see `kerf_geom::Transition`). `step` does at most a few `calculate()` calls (the running
//!   section's re-plan, the next section's profile, a carried speed-up's or slow-down's
//!   target and the plain one if that fails, a hold's stop; choosing a carried end
//!   acceleration tries at most five end accelerations for a speed-up, each a rise in
//!   closed form or by a bisection of `RISE_STEPS` closed-form rises, and, where none is
//!   carried, at most five for a slow-down, each a bisection of `CARRY_SPEED_STEPS` steps
//!   of two closed-form falls, see `MotionCore::carry_target`) and crosses at most
//!   `MAX_SECTIONS_PER_STEP` section ends in one cycle; past that the leftover time of the
//!   cycle is dropped (a delay of under one period, the motion stays continuous).
//! - **Slivers**: a section shorter than [`COAST_BELOW_MM`], or taking less than
//!   [`COAST_BELOW_S`] at its entry speed (where neighbouring blends meet
//!   they leave nanometre remnants of the line between them), is coasted through at the
//!   entry speed in the time that takes, without the solver, which cannot plan it.
//! - **Scaled units.** Every solver call is made in units where the numbers are of
//!   order one (the distance as the unit of length, `(d/j)^(1/3)` as the unit of time;
//!   for stops, the stop's own jerk time `sqrt(v/j)`). The solver's tolerances are
//!   absolute (1e-10 on the acceleration): in mm and s, a fast machine's accelerations
//!   (1e4–1e6 mm/s²) carry more rounding than that, and the solver fails on ordinary
//!   feasible inputs over the accepted range of limits, from rest to rest on a plain arc
//!   among them (the unit test `scaled_solver_calls_plan_every_feasible_section` plans
//!   20,000 of them in scaled units, none failing).
//! - **Fallbacks** never jump. A solver result is used only if it ends where it should.
//!   When the solver fails at a section start, [`JerkProfile`] (closed form: S-curve to a
//!   cruise speed, cruise, S-curve to the end speed, all within the section's limits)
//!   runs instead, to the same end speed or else to a stop at the section end (always
//!   reachable: the entry speed is within the hard lookahead); a failed re-plan keeps the
//!   running profile, a failed hold stop waits for the next section. Each solver failure
//!   is counted in [`MotionCore::plan_failures`]; a stop forced because no plan within a
//!   section existed (which the lookahead rules out) in [`MotionCore::emergency_stops`].
//!   Ruckig formats an error message on failure, which allocates: a healthy run has no
//!   failures and so no allocations.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

use kerf_geom::PerAxis;
pub use kerf_geom::{
    AxisLimits, MERGE_ABOVE, MERGE_RATIO, MERGE_RATIO_JERK, MERGE_RATIO_SLOWER, MERGE_RATIO_SPEED,
    MERGE_RATIO_WEAKER, MERGE_SHORT_SHARE, MachineLimits, PlannedSegment,
};
pub mod axis_move;
mod carry;
mod hold;
mod lookahead;
mod merge;
pub mod monitor;
mod motion_core;
mod plan;
mod profile;
mod queue;
mod reach;
mod section;
mod solver;
mod step;
#[cfg(test)]
mod tests;

pub use axis_move::{AxisMove, AxisMoveError};
pub use motion_core::MotionCore;
pub use profile::JerkProfile;
pub use reach::{change_distance, reach, reach_back};

/// Highest feed override ([`kerf_geom::MAX_FEED_OVERRIDE`]).
pub const MAX_OVERRIDE: f64 = kerf_geom::MAX_FEED_OVERRIDE;

/// Sections shorter than this are coasted through at the entry speed (see `calc`), mm.
pub const COAST_BELOW_MM: f64 = 1e-6;

/// Sections that take less than this at the entry speed are coasted through as well, s.
/// (At speed, the solver's scaled-unit profile for a remnant of a few nanometres is
/// wrong: it can hold the position for several cycles while the speed runs on.)
pub const COAST_BELOW_S: f64 = 1e-6;

/// One setpoint: positions of every axis at the end of a cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Setpoint {
    /// X, Y, Z (mm) and A, B, C (degrees).
    pub position: PerAxis<f64>,
    /// Source line of the segment being run.
    pub line: u32,
    /// Index of the source move (program order), for deviation checks.
    pub move_index: u64,
    /// Moves the segment being run stands for, from `move_index` on (more than one on a
    /// smoothed piece of a dense polyline).
    pub move_count: u32,
    /// Path speed, mm/s (deg/s on rotary-only moves).
    pub feed_mm_s: f64,
    /// The segment being run is a rapid (the spindle's at-speed band is watched on feed
    /// moves only).
    pub rapid: bool,
}

/// What a cycle did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepResult {
    /// Moving along the queue.
    Moving,
    /// At rest with an empty queue (program finished or planner starved).
    Idle,
    /// At rest on the path in feed hold.
    Held,
}

/// What the core is doing, for status reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MotionState {
    /// At rest with an empty queue.
    Idle,
    /// Moving along the queue (including a hold waiting for a safe moment to stop).
    Running,
    /// Stopping on the path for a hold or an abort.
    Stopping,
    /// At rest on the path in feed hold (or by zero override).
    Held,
}

/// A snapshot of the core for status messages (all O(1) to read).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Status {
    /// What the core is doing.
    pub state: MotionState,
    /// Source line of the segment being run (or last run).
    pub line: u32,
    /// Segments in the queue.
    pub queued: usize,
    /// Free queue slots.
    pub free: usize,
    /// Path speed, mm/s.
    pub feed_mm_s: f64,
    /// Feed override factor the plan uses.
    pub feed_override: f64,
    /// Profile calculations that needed a fallback so far.
    pub plan_failures: u64,
}

/// Why a segment was not accepted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum PushError {
    /// The queue is full; step and try again.
    Full,
    /// The segment has a non-finite or non-positive length or limit.
    Invalid,
    /// The segment does not start where the previous one ends (or, on an idle core, where
    /// the machine is): running it would make an axis jump.
    Discontinuous,
}

/// Largest gap between consecutive segments that still counts as continuous, mm.
pub const CONTINUITY_MM: f64 = 1e-6;
