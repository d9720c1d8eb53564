//! Kerf's real-time motion core: segment queue, lookahead and jerk-limited interpolation.
//!
//! [`MotionCore`] holds a fixed-capacity queue of [`PlannedSegment`]s (from `kerf-plan`,
//! the type lives in `kerf-geom`: this crate depends on `kerf-geom` and `rsruckig` only)
//! and produces one [`Setpoint`] per [`MotionCore::step`]. Everything is allocated in
//! [`MotionCore::new`]; `push` and `step` never allocate, lock or do I/O.
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
//!   segment's (a line behind a short corner blend would stop with the blend's jerk). A
//!   segment up to 3 % slower than the first ([`MERGE_RATIO_SLOWER`]) still joins, the
//!   section then running at its speed, where nothing was committed faster: the tail
//!   section's hard lookahead (it must stop within itself) is below the segment's
//!   conservative speed, so no boundary speed falls. A slow-down across smoothed pieces
//!   whose speeds differ by a per cent or two is then one ramp, not a stair of sections
//!   each ending at `a = 0`. The running
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
//!   not a stair of `a = 0` steps. `calculate()` runs once per section and per event
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
//!   section's re-plan, the next section's profile, a carried speed-up's target and the
//!   plain one if that fails, a hold's stop; choosing a carried end acceleration tries at
//!   most five end accelerations, each a rise in closed form or by a bisection of
//!   `RISE_STEPS` closed-form rises, see `MotionCore::carry_target`) and crosses at most
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
//!   (1e4–1e6 mm/s²) carry more rounding than that, and it failed on 0.3 % of ordinary
//!   feasible inputs over the accepted range of limits (58 of the 20,000 of the unit test
//!   `scaled_solver_calls_plan_every_feasible_section`; none in scaled units), from rest
//!   to rest on a plain arc among them.
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

use kerf_geom::Vec3;
use kerf_geom::limits_merge;
use kerf_geom::ramp::{bisect, change_time_s};
pub use kerf_geom::{
    AxisLimits, MERGE_ABOVE, MERGE_RATIO, MERGE_RATIO_JERK, MERGE_RATIO_SLOWER, MERGE_RATIO_SPEED,
    MachineLimits, PlannedSegment,
};
use rsruckig::prelude::*;

pub mod monitor;
mod profile;

pub use profile::JerkProfile;

/// Highest feed override ([`kerf_geom::MAX_FEED_OVERRIDE`]).
pub const MAX_OVERRIDE: f64 = kerf_geom::MAX_FEED_OVERRIDE;
/// Fraction of the remaining distance the lookahead assumes available (numerical margin).
const BACKWARD_MARGIN: f64 = 0.998;
/// Fraction of the remaining distance a profile plan may use in its own checks.
const PLAN_MARGIN: f64 = 0.999;
/// Sections shorter than this are coasted through at the entry speed (see `calc`), mm.
pub const COAST_BELOW_MM: f64 = 1e-6;
/// Sections that take less than this at the entry speed are coasted through as well, s.
/// (At speed, the solver's scaled-unit profile for a remnant of a few nanometres is
/// wrong: it froze the position for several cycles while the speed ran on.)
pub const COAST_BELOW_S: f64 = 1e-6;
/// Most sections one `push` revisits in the backward pass (bounds its work).
const MAX_BACKWARD_SECTIONS: usize = 256;
/// Most section changes handled within one cycle.
const MAX_SECTIONS_PER_STEP: usize = 16;
/// Most sections scanned when checking a hold.
const MAX_HOLD_SCAN: usize = 64;

/// One setpoint: positions of every axis at the end of a cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Setpoint {
    /// X, Y, Z (mm) and A, B, C (degrees).
    pub position: [f64; 6],
    /// Source line of the segment being run.
    pub line: u32,
    /// Index of the source move (program order), for deviation checks.
    pub move_index: u64,
    /// Moves the segment being run stands for, from `move_index` on (more than one on a
    /// smoothed piece of a dense polyline).
    pub move_count: u32,
    /// Path speed, mm/s (deg/s on rotary-only moves).
    pub feed_mm_s: f64,
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

/// The core's motion mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    /// Following the lookahead plan.
    Run,
    /// Running the plan while a hold waits for a safe moment.
    HoldPending,
    /// Stopping on the path.
    Braking,
    /// Stopped on the path.
    Held,
}

#[derive(Clone, Copy, Debug)]
struct Section {
    /// Absolute index of the first segment.
    first: u64,
    count: u64,
    length: f64,
    /// Actual limits: minima over segments and interior junction caps.
    v_machine: f64,
    feed: f64,
    accel: f64,
    jerk: f64,
    /// The same for a feed override above 100 % (the segments' `v_boost`,
    /// `accel_boost`, `jerk_boost`; the accelerations are at most the ones above).
    v_boost: f64,
    accel_boost: f64,
    jerk_boost: f64,
    /// Speed limits of the first segment, base and boost level (see
    /// [`MERGE_RATIO_SLOWER`]).
    v_first: f64,
    v_first_boost: f64,
    /// Acceleration and jerk limits of the first segment: the merge rule's reference
    /// ([`limits_merge`]); the hard lookahead's are their merge ratios
    /// ([`Section::c_accel_jerk`]).
    accel_jerk_first: (f64, f64),
    /// Conservative limits fixed at creation (hard lookahead); the speeds are lowered when
    /// a slightly slower segment joins (see [`MERGE_RATIO_SLOWER`]).
    c_v: f64,
    c_feed: f64,
    /// The same for the boost level.
    c_v_boost: f64,
    c_accel_boost: f64,
    c_jerk_boost: f64,
    /// Cap at the junction before the section.
    start_cap: f64,
    /// Hard lookahead at the base level (valid while the section runs with its base limits).
    hard_start: f64,
    hard_end: f64,
    /// Hard lookahead at the boost level (valid with the boost limits, at any override).
    hard_start_boost: f64,
    hard_end_boost: f64,
    soft_start: f64,
    soft_end: f64,
    /// The level the section runs at, fixed when it starts (see `plan_section_start`).
    boosted: bool,
}

impl Section {
    /// The conservative acceleration and jerk of the hard lookahead: the merge ratios of
    /// the first segment's, which every segment of the section has at least.
    fn c_accel_jerk(&self) -> (f64, f64) {
        let (a, j) = self.accel_jerk_first;
        (MERGE_RATIO * a, MERGE_RATIO_JERK * j)
    }

    /// Speed limit, acceleration and jerk at a level.
    fn limits(&self, boosted: bool) -> (f64, f64, f64) {
        if boosted {
            (self.v_boost, self.accel_boost, self.jerk_boost)
        } else {
            (self.v_machine, self.accel, self.jerk)
        }
    }

    /// The hard end speed at a level.
    fn hard_end_at(&self, boosted: bool) -> f64 {
        if boosted {
            self.hard_end_boost
        } else {
            self.hard_end
        }
    }

    /// Speed at override `ovr` and a level: the machine limit or the scaled feed.
    fn v_eff(&self, ovr: f64, boosted: bool) -> f64 {
        self.limits(boosted).0.min(self.feed * ovr)
    }

    /// The level the section is planned at for override `ovr`: the boost limits only where
    /// the override asks for more speed than the base level allows and the boost level
    /// has it (its accelerations are lower, so it is not used otherwise).
    fn wants_boost(&self, ovr: f64) -> bool {
        self.v_boost > self.v_machine && self.feed * ovr > self.v_machine
    }
}

/// The real-time motion core. See the crate documentation.
pub struct MotionCore {
    period_s: f64,
    segs: Vec<PlannedSegment>,
    /// Offset of each segment's start within its section (parallel to `segs`).
    seg_offset: Vec<f64>,
    seg_head: u64,
    seg_count: u64,
    secs: Vec<Section>,
    sec_head: u64,
    sec_count: u64,
    /// The front section is running (its limits are frozen).
    running: bool,
    otg: Ruckig<1, IgnoreErrorHandler>,
    input: InputParameter<1>,
    traj: Trajectory<1>,
    /// Scratch trajectory: every calculation goes here and is swapped in on success.
    scratch: Trajectory<1>,
    /// Factor the running profile's positions are scaled by (see `calc`).
    traj_scale: f64,
    /// Seconds per time unit of the running profile (see `calc`).
    traj_time_scale: f64,
    /// Section-local position where the profile starts.
    traj_origin: f64,
    /// Time since the profile start, s.
    traj_t: f64,
    /// End speed the running profile targets.
    traj_end_v: f64,
    /// End acceleration the running profile targets: zero except where a speed-up goes on
    /// into the next section (see `carry_target`).
    traj_end_a: f64,
    /// The running profile is `own` (the closed-form fallback) instead of `traj`.
    own_active: bool,
    own: JerkProfile,
    /// When positive, the running "profile" is a coast at `traj_end_v` through a sliver
    /// section this many seconds long instead of `traj` (see `calc`).
    coast_s: f64,
    /// Set when the lookahead raised the running section's end speed.
    replan: bool,
    /// The running section waits for its acceleration to come down to move to its boost
    /// level (see `replan_running`).
    boost_pending: bool,
    mode: Mode,
    abort_requested: bool,
    override_factor: f64,
    /// A hold requested by the operator is in force.
    user_hold: bool,
    /// A hold caused by a zero feed override is in force.
    override_hold: bool,
    /// Current segment (absolute index) and section-local state.
    cursor: u64,
    s_local: f64,
    v: f64,
    a: f64,
    last: Setpoint,
    failures: u64,
    /// Stops forced because no plan within a section existed (see `emergency_stop`).
    emergencies: u64,
    /// Units of the profile in `scratch` after `calc_brake` (see there).
    brake_scale: f64,
    brake_time_scale: f64,
    /// Tests: make every solver call fail, to exercise the fallbacks.
    #[cfg(test)]
    fail_solver: bool,
}

impl std::fmt::Debug for MotionCore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MotionCore")
            .field("queued", &self.seg_count)
            .field("sections", &self.sec_count)
            .field("mode", &self.mode)
            .finish_non_exhaustive()
    }
}

/// Distance to change speed from `v0` to `v1` with `a = 0` at both ends along the
/// symmetric jerk-limited profile (exact: the speed curve is point-symmetric).
pub fn change_distance(v0: f64, v1: f64, accel: f64, jerk: f64) -> f64 {
    0.5 * (v0 + v1) * change_time_s((v1 - v0).abs(), accel, jerk)
}

/// Highest speed reachable from `v0` (or from which `v0` is reachable) within distance
/// `d` with `a = 0` at both ends: the inverse of [`change_distance`] in its second
/// argument, in closed form (a bounded Newton solve of a cubic, then a quadratic).
pub fn reach(v0: f64, d: f64, accel: f64, jerk: f64) -> f64 {
    if d <= 0.0 || accel <= 0.0 || jerk <= 0.0 {
        return v0;
    }
    let v0 = v0.max(0.0);
    // Short change: d = (2 v0 + j x²) x with x = sqrt(dv / j). Newton from an upper
    // bound converges monotonically because the cubic is convex for x > 0.
    let mut x = (d / jerk).cbrt();
    if v0 > 0.0 {
        x = x.min(d / (2.0 * v0));
    }
    for _ in 0..12 {
        let f = jerk * x * x * x + 2.0 * v0 * x - d;
        let df = 3.0 * jerk * x * x + 2.0 * v0;
        if df <= 0.0 {
            break;
        }
        let nx = x - f / df;
        // Stop when Newton no longer decreases (converged, or NaN from bad input).
        if nx.partial_cmp(&x) != Some(std::cmp::Ordering::Less) {
            break;
        }
        x = nx.max(0.0);
    }
    let dv = jerk * x * x;
    if dv * jerk <= accel * accel {
        return v0 + dv;
    }
    // Long change with a constant-acceleration phase: dv² + B dv + C = 0.
    let b = 2.0 * v0 + accel * accel / jerk;
    let c = 2.0 * v0 * accel * accel / jerk - 2.0 * d * accel;
    let disc = (b * b - 4.0 * c).max(0.0);
    let dv = -2.0 * c / (b + disc.sqrt());
    v0 + dv.max(0.0)
}

/// Highest speed at the start of a distance `d` from which the speed at its end can be
/// brought to at most `v_end` (`a = 0` at both ends). Slowing down only partially can need
/// more distance than stopping (the jerk-limited profile's time grows with the speed
/// change), so both ending at `v_end` and ending at rest are candidates.
pub fn reach_back(v_end: f64, d: f64, accel: f64, jerk: f64) -> f64 {
    reach(v_end, d, accel, jerk).max(reach(0.0, d, accel, jerk))
}

/// Share of the section the quickest rise of a carried speed-up may take (see
/// `MotionCore::carry_target`): the rest is the solver's room.
const CARRY_FILL: f64 = 0.98;
/// Least share of a carried speed-up's rise beyond the least one with its end
/// acceleration (see `MotionCore::carry_target`).
const CARRY_MIN_RISE: f64 = 0.05;
/// End accelerations tried for a carried speed-up, as shares of the acceleration limit:
/// `CARRY_SHARE_RATIO^k` for `k < CARRY_SHARE_STEPS`, highest first (down to a tenth; see
/// `MotionCore::carry_target`).
const CARRY_SHARE_RATIO: f64 = 0.85;
const CARRY_SHARE_STEPS: i32 = 15;
/// Bisection steps on the peak acceleration in `rise_reach`: to 1/65,536 of its range
/// (from the least peak to a bound from the distance); the speed found is at most that
/// low, and lower is always reachable.
const RISE_STEPS: usize = 16;

/// Speed and distance once acceleration `a0` at speed `v0` has been brought to zero at
/// jerk `jerk`.
fn settle(v0: f64, a0: f64, jerk: f64) -> (f64, f64) {
    let tau = a0.abs() / jerk;
    let v_at = v0 + a0 * a0.abs() / (2.0 * jerk);
    let d0 = v0 * tau + 0.5 * a0 * tau * tau - a0.signum() * jerk * tau * tau * tau / 6.0;
    (v_at, d0)
}

/// Distance and end speed of a rise from `(v0, a0)` at jerk `jerk`: the acceleration up
/// to `peak` and down to `a1` (`peak ≥ a0, a1 ≥ 0`).
fn rise_with_peak(v0: f64, a0: f64, a1: f64, peak: f64, jerk: f64) -> (f64, f64) {
    let (t1, t3) = ((peak - a0) / jerk, (peak - a1) / jerk);
    let d1 = t1 * (v0 + t1 * (a0 / 2.0 + t1 * jerk / 6.0));
    let v_up = v0 + (peak * peak - a0 * a0) / (2.0 * jerk);
    let d3 = t3 * (v_up + t3 * (peak / 2.0 - t3 * jerk / 6.0));
    (d1 + d3, v_up + (peak * peak - a1 * a1) / (2.0 * jerk))
}

/// The highest speed the quickest rise from `(v0, a0)` reaches in distance `d`, ending
/// with acceleration `a1` (accelerations in `[0, accel]`): the acceleration up at the jerk
/// limit, held at `accel` if need be, and down to `a1`. `None` when even the rise of the
/// acceleration (to the larger of `a0` and `a1`, and down to `a1`) does not fit, or an
/// input is out of range. Closed form where the acceleration is held, else a bisection on
/// the peak acceleration (the distance grows with it): cheap enough for the cycle.
fn rise_reach(v0: f64, a0: f64, a1: f64, d: f64, accel: f64, jerk: f64) -> Option<f64> {
    let in_range = |a: f64| (0.0..=accel).contains(&a);
    if !(in_range(a0) && in_range(a1) && jerk > 0.0 && v0 >= 0.0 && d > 0.0) {
        return None;
    }
    let low = a0.max(a1);
    if rise_with_peak(v0, a0, a1, low, jerk).0 > d {
        return None;
    }
    let (d_top, v_top) = rise_with_peak(v0, a0, a1, accel, jerk);
    if d_top <= d {
        // Held at `accel` for `h`: the distance grows by `(v_up + accel·t3)·h + accel·h²/2`.
        let t3 = (accel - a1) / jerk;
        let v_up = v0 + (accel * accel - a0 * a0) / (2.0 * jerk);
        let b = v_up + accel * t3;
        let h = 2.0 * (d - d_top) / (b + (b * b + 2.0 * accel * (d - d_top)).sqrt());
        return Some(v_top + accel * h);
    }
    // The peak is bounded by the distance too: the rise up to it alone takes at least
    // `J t³/6` (from `a0 ≥ 0`), and both ramps at least `v0` times their time.
    let mut top = accel.min(a0 + jerk * (6.0 * d / jerk).cbrt());
    if v0 > 0.0 {
        top = top.min(0.5 * (jerk * d / v0 + a0 + a1));
    }
    let peak = bisect(low, top.max(low), RISE_STEPS, |p| {
        rise_with_peak(v0, a0, a1, p, jerk).0 <= d
    });
    Some(rise_with_peak(v0, a0, a1, peak, jerk).1)
}

impl MotionCore {
    /// A core interpolating at `period_s` (seconds per [`MotionCore::step`]) holding up to
    /// `capacity` segments. All memory is allocated here. The core needs no machine limits:
    /// every limit it keeps to is carried by the segments ([`PlannedSegment`]).
    pub fn new(period_s: f64, capacity: usize) -> Self {
        let capacity = capacity.max(2);
        let dummy = PlannedSegment::with_zero_limits(
            kerf_geom::Curve::line(Vec3::zeros(), Vec3::zeros()),
            0.0,
            ([0.0; 3], [0.0; 3]),
            0,
            0,
            0.0,
        );
        let dummy_sec = Section {
            first: 0,
            count: 0,
            length: 0.0,
            v_machine: 0.0,
            feed: 0.0,
            accel: 0.0,
            jerk: 0.0,
            v_boost: 0.0,
            accel_boost: 0.0,
            jerk_boost: 0.0,
            v_first: 0.0,
            v_first_boost: 0.0,
            c_v: 0.0,
            c_feed: 0.0,
            accel_jerk_first: (0.0, 0.0),
            c_v_boost: 0.0,
            c_accel_boost: 0.0,
            c_jerk_boost: 0.0,
            start_cap: 0.0,
            hard_start: 0.0,
            hard_end: 0.0,
            hard_start_boost: 0.0,
            hard_end_boost: 0.0,
            soft_start: 0.0,
            soft_end: 0.0,
            boosted: false,
        };
        let mut input = InputParameter::new(None);
        input.min_velocity = Some(DataArrayOrVec::new(None, 0.0));
        let mut traj = Trajectory::new(None);
        traj.reserve_sections(1);
        let mut scratch = Trajectory::new(None);
        scratch.reserve_sections(1);
        MotionCore {
            period_s,
            segs: vec![dummy; capacity],
            seg_offset: vec![0.0; capacity],
            seg_head: 0,
            seg_count: 0,
            secs: vec![dummy_sec; capacity],
            sec_head: 0,
            sec_count: 0,
            running: false,
            otg: Ruckig::new(None, period_s),
            input,
            traj,
            scratch,
            traj_scale: 1.0,
            traj_time_scale: 1.0,
            traj_origin: 0.0,
            traj_t: 0.0,
            traj_end_v: 0.0,
            traj_end_a: 0.0,
            own_active: false,
            own: JerkProfile::default(),
            coast_s: 0.0,
            replan: false,
            boost_pending: false,
            mode: Mode::Run,
            abort_requested: false,
            override_factor: 1.0,
            user_hold: false,
            override_hold: false,
            cursor: 0,
            s_local: 0.0,
            v: 0.0,
            a: 0.0,
            last: Setpoint::default(),
            failures: 0,
            emergencies: 0,
            brake_scale: 1.0,
            brake_time_scale: 1.0,
            #[cfg(test)]
            fail_solver: false,
        }
    }

    /// The interpolation period, s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// Capacity of the segment queue.
    pub fn capacity(&self) -> usize {
        self.segs.len()
    }

    /// Segments in the queue (including the one running).
    pub fn queued(&self) -> usize {
        self.seg_count as usize
    }

    /// Free queue slots.
    pub fn free(&self) -> usize {
        self.segs.len() - self.seg_count as usize
    }

    /// `true` when at rest with nothing queued.
    pub fn is_idle(&self) -> bool {
        self.seg_count == 0 && self.v == 0.0
    }

    /// `true` while stopped on the path in feed hold (or by zero override).
    pub fn is_held(&self) -> bool {
        self.mode == Mode::Held
    }

    /// A status snapshot.
    pub fn status(&self) -> Status {
        let state = match self.mode {
            Mode::Held => MotionState::Held,
            Mode::Braking => MotionState::Stopping,
            Mode::Run | Mode::HoldPending if self.is_idle() => MotionState::Idle,
            Mode::Run | Mode::HoldPending => MotionState::Running,
        };
        Status {
            state,
            line: self.last.line,
            queued: self.queued(),
            free: self.free(),
            feed_mm_s: self.v,
            feed_override: self.override_factor,
            plan_failures: self.failures,
        }
    }

    /// Number of profile calculations that failed (each fell back to a safer plan).
    pub fn plan_failures(&self) -> u64 {
        self.failures
    }

    /// Number of jerk-limited stops forced because no plan within a section existed
    /// (zero while the lookahead holds; each is also a limit-respecting stop).
    pub fn emergency_stops(&self) -> u64 {
        self.emergencies
    }

    /// The feed override factor the plan uses (a zero override holds instead and leaves
    /// this at its previous value).
    pub fn feed_override(&self) -> f64 {
        self.override_factor
    }

    /// Sets the position the core rests at (only while idle); the first segment pushed
    /// should start there.
    pub fn set_position(&mut self, position: [f64; 6]) {
        if self.is_idle() {
            self.last.position = position;
        }
    }

    /// Drops the queue and every motion state at once and rests at `position`: for the
    /// drive side's quick stop, after which the drives stand where its jerk-limited ramp
    /// brought them, not where this core's path stop would have. Never allocates.
    pub fn reset_to(&mut self, position: [f64; 6]) {
        self.clear();
        self.last = Setpoint {
            position,
            ..Setpoint::default()
        };
    }

    fn seg(&self, abs: u64) -> &PlannedSegment {
        &self.segs[(abs % self.segs.len() as u64) as usize]
    }

    fn sec_slot(&self, abs: u64) -> usize {
        (abs % self.secs.len() as u64) as usize
    }

    fn sec(&self, abs: u64) -> &Section {
        &self.secs[self.sec_slot(abs)]
    }

    fn sec_mut(&mut self, abs: u64) -> &mut Section {
        let i = self.sec_slot(abs);
        &mut self.secs[i]
    }

    /// Appends a segment. Never allocates; the lookahead work is a backward pass from the
    /// tail that stops at the first section whose speeds do not change.
    pub fn push(&mut self, seg: &PlannedSegment) -> Result<(), PushError> {
        if self.seg_count as usize >= self.segs.len() {
            return Err(PushError::Full);
        }
        let valid = seg.length_mm.is_finite()
            && seg.length_mm > 0.0
            && seg.v_max_mm_s > 0.0
            && seg.accel_mm_s2 > 0.0
            && seg.jerk_mm_s3 > 0.0
            && seg.feed_mm_s > 0.0
            && seg.end_cap_mm_s >= 0.0;
        if !valid {
            return Err(PushError::Invalid);
        }
        let mut start = [0.0; 6];
        seg.position_at(0.0, &mut start);
        let mut before = self.last.position;
        if self.seg_count > 0 {
            let prev = *self.seg(self.seg_head + self.seg_count - 1);
            prev.position_at(prev.length_mm, &mut before);
        }
        if (0..6).any(|i| (start[i] - before[i]).abs() > CONTINUITY_MM) {
            return Err(PushError::Discontinuous);
        }
        let abs = self.seg_head + self.seg_count;
        let slot = (abs % self.segs.len() as u64) as usize;
        self.segs[slot] = *seg;
        self.seg_count += 1;

        let seg_v = seg.v_max_mm_s;
        let seg_feed = seg.feed_mm_s;
        // The boost level (override above 100 %); a segment without one (older producers,
        // straight segments) has the base limits there too.
        let (seg_vb, seg_ab, seg_jb) = if seg.v_boost_mm_s > seg_v
            && seg.accel_boost_mm_s2 > 0.0
            && seg.jerk_boost_mm_s3 > 0.0
        {
            (
                seg.v_boost_mm_s,
                seg.accel_boost_mm_s2.min(seg.accel_mm_s2),
                seg.jerk_boost_mm_s3.min(seg.jerk_mm_s3),
            )
        } else {
            (seg_v, seg.accel_mm_s2, seg.jerk_mm_s3)
        };
        // The cap at the junction before this segment is the previous segment's end cap.
        let prev_cap = if abs > self.seg_head {
            self.seg(abs - 1).end_cap_mm_s
        } else {
            0.0
        };
        let tail = self.sec_head + self.sec_count;
        let mode = self.mode;
        let can_merge = self.sec_count > 0 && !(self.sec_count == 1 && self.running) && {
            let t = self.sec(tail - 1);
            // A segment slower than the section's conservative speed by a little joins it
            // when nothing has been committed above its speed: the tail section's hard
            // lookahead (it must stop within itself) is already below it, so lowering the
            // conservative speed lowers no boundary speed, and no profile or stop was
            // planned into the section faster (see [`MERGE_RATIO_SLOWER`]).
            let slower = |v: f64, c_v: f64, first: f64, hard: f64| {
                v < c_v
                    && mode == Mode::Run
                    && v >= MERGE_RATIO_SLOWER * first
                    && hard >= 0.0
                    && hard <= MERGE_RATIO_SPEED * v
            };
            // The conservative speeds after the merge.
            let c_v = t.c_v.min(MERGE_RATIO_SPEED * seg_v);
            let c_v_boost = t.c_v_boost.min(MERGE_RATIO_SPEED * seg_vb);
            (seg_v >= t.c_v || slower(seg_v, t.c_v, t.v_first, t.hard_start))
                && seg_feed >= t.c_feed
                // Nor much faster: the section runs at its minima, so a fast segment behind
                // a slow one (a slow feed, a tight transition) would crawl through it.
                && seg_v.min(seg_feed) * MERGE_RATIO_SPEED * MERGE_RATIO_SPEED
                    <= t.c_v.min(t.c_feed)
                // Not much weaker, nor much stronger (it would ramp at the section's
                // limits): the planner judges ramp budgets by the same function.
                && limits_merge(seg.accel_mm_s2, seg.jerk_mm_s3, t.accel_jerk_first)
                && prev_cap >= c_v.min(t.c_feed * MAX_OVERRIDE)
                && (seg_vb >= t.c_v_boost
                    || slower(seg_vb, t.c_v_boost, t.v_first_boost, t.hard_start_boost))
                && seg_ab >= t.c_accel_boost
                && seg_jb >= t.c_jerk_boost
                && prev_cap >= c_v_boost.min(t.c_feed * MAX_OVERRIDE)
        };
        if can_merge {
            let t = self.sec_mut(tail - 1);
            let offset = t.length;
            t.length += seg.length_mm;
            t.count += 1;
            t.v_machine = t.v_machine.min(seg_v).min(prev_cap);
            t.feed = t.feed.min(seg_feed);
            t.accel = t.accel.min(seg.accel_mm_s2);
            t.jerk = t.jerk.min(seg.jerk_mm_s3);
            t.v_boost = t.v_boost.min(seg_vb).min(prev_cap);
            t.accel_boost = t.accel_boost.min(seg_ab);
            t.jerk_boost = t.jerk_boost.min(seg_jb);
            t.c_v = t.c_v.min(MERGE_RATIO_SPEED * seg_v);
            t.c_v_boost = t.c_v_boost.min(MERGE_RATIO_SPEED * seg_vb);
            self.seg_offset[slot] = offset;
        } else {
            if self.sec_count as usize >= self.secs.len() {
                // Cannot happen: there are never more sections than segments.
                self.seg_count -= 1;
                return Err(PushError::Full);
            }
            let start_cap = if self.sec_count > 0 { prev_cap } else { 0.0 };
            let sec = Section {
                first: abs,
                count: 1,
                length: seg.length_mm,
                v_machine: seg_v,
                feed: seg_feed,
                accel: seg.accel_mm_s2,
                jerk: seg.jerk_mm_s3,
                v_first: seg_v,
                v_first_boost: seg_vb,
                c_v: MERGE_RATIO_SPEED * seg_v,
                c_feed: MERGE_RATIO_SPEED * seg_feed,
                accel_jerk_first: (seg.accel_mm_s2, seg.jerk_mm_s3),
                v_boost: seg_vb,
                accel_boost: seg_ab,
                jerk_boost: seg_jb,
                c_v_boost: MERGE_RATIO_SPEED * seg_vb,
                c_accel_boost: MERGE_RATIO * seg_ab,
                c_jerk_boost: MERGE_RATIO_JERK * seg_jb,
                start_cap,
                hard_start: -1.0,
                hard_end: 0.0,
                hard_start_boost: -1.0,
                hard_end_boost: 0.0,
                soft_start: -1.0,
                soft_end: 0.0,
                boosted: false,
            };
            let i = self.sec_slot(tail);
            self.secs[i] = sec;
            self.sec_count += 1;
            self.seg_offset[slot] = 0.0;
            if self.sec_count == 1 {
                // The new section is the front one: the core was idle.
                self.cursor = abs;
                self.s_local = 0.0;
            }
        }
        self.backward_pass(MAX_BACKWARD_SECTIONS);
        Ok(())
    }

    /// Recomputes the lookahead speeds from the tail until they stop changing.
    ///
    /// `max_sections` bounds the work: values left stale beyond it are lower than they
    /// could be (hard speeds only grow as the queue grows), so stopping early is safe.
    fn backward_pass(&mut self, max_sections: usize) {
        if self.sec_count == 0 {
            return;
        }
        let mut visited = 0;
        let ovr = self.override_factor;
        let first = self.sec_head;
        let mut k = self.sec_head + self.sec_count - 1;
        let mut hard_end = 0.0;
        let mut hard_end_boost = 0.0;
        let mut soft_end = 0.0;
        loop {
            let is_running = k == first && self.running;
            let s = self.sec_mut(k);
            s.hard_end = hard_end;
            s.hard_end_boost = hard_end_boost;
            s.soft_end = soft_end;
            if is_running {
                // The running section's limits are frozen; a higher end speed is taken by
                // re-planning its profile.
                let hard = s.hard_end_at(s.boosted);
                if hard.min(soft_end) > self.traj_end_v * 1.001 + 1e-9 {
                    self.replan = true;
                }
                break;
            }
            let d = s.length * BACKWARD_MARGIN;
            let hard = s.c_v.min(s.c_feed * MAX_OVERRIDE).min(s.start_cap).min({
                let (c_accel, c_jerk) = s.c_accel_jerk();
                reach_back(hard_end, d, c_accel, c_jerk)
            });
            let hard_boost = s
                .c_v_boost
                .min(s.c_feed * MAX_OVERRIDE)
                .min(s.start_cap)
                .min(reach_back(
                    hard_end_boost,
                    d,
                    s.c_accel_boost,
                    s.c_jerk_boost,
                ));
            let level = s.wants_boost(ovr);
            let (_, a, j) = s.limits(level);
            let soft = s
                .v_eff(ovr, level)
                .min(s.start_cap)
                .min(if level { hard_boost } else { hard })
                .min(reach_back(soft_end, d, a, j));
            let changed =
                hard != s.hard_start || hard_boost != s.hard_start_boost || soft != s.soft_start;
            s.hard_start = hard;
            s.hard_start_boost = hard_boost;
            s.soft_start = soft;
            visited += 1;
            if !changed || k == first || visited >= max_sections {
                break;
            }
            hard_end = hard;
            hard_end_boost = hard_boost;
            soft_end = soft;
            k -= 1;
        }
    }

    /// Recomputes the whole soft lookahead (after an override change).
    fn full_soft_pass(&mut self) {
        // Forcing a change in every section makes the pass run to the front.
        for k in self.sec_head..self.sec_head + self.sec_count {
            self.sec_mut(k).soft_start = -1.0;
        }
        self.backward_pass(usize::MAX);
    }

    /// Sets the feed override (clamped to 0–200 %). Takes effect at once, jerk-limited.
    pub fn set_feed_override(&mut self, factor: f64) {
        let f = if factor.is_finite() {
            factor.clamp(0.0, MAX_OVERRIDE)
        } else {
            1.0
        };
        // Zero override stops the motion like a hold (on the path, jerk-limited) and raising
        // it again resumes, unless the operator also asked for a hold. Planning keeps a
        // small positive factor so that no limit is ever zero.
        if f == 0.0 {
            if !self.override_hold {
                self.override_hold = true;
                if self.mode == Mode::Run {
                    self.mode = Mode::HoldPending;
                    self.try_brake();
                }
            }
            return;
        }
        if self.override_hold {
            self.override_hold = false;
            if !self.user_hold {
                self.resume_inner();
            }
        }
        if f == self.override_factor {
            return;
        }
        self.override_factor = f;
        self.full_soft_pass();
        self.replan = true;
    }

    /// Requests a feed hold: stop on the path as fast as the limits allow.
    pub fn hold(&mut self) {
        self.user_hold = true;
        if self.mode == Mode::Run {
            self.mode = Mode::HoldPending;
            self.try_brake();
        }
    }

    /// Resumes after a hold (or cancels a pending one).
    pub fn resume(&mut self) {
        self.user_hold = false;
        if !self.override_hold {
            self.resume_inner();
        }
    }

    fn resume_inner(&mut self) {
        match self.mode {
            Mode::HoldPending => self.mode = Mode::Run,
            Mode::Held => {
                self.mode = Mode::Run;
                if self.sec_count > 0 {
                    self.plan_section_start();
                }
            }
            Mode::Braking => {
                // The stop finishes first; `step` resumes when it ends if no hold is left.
            }
            Mode::Run => {}
        }
    }

    /// Aborts: stops on the path as fast as the limits allow, then drops the queue.
    pub fn abort(&mut self) {
        self.abort_requested = true;
        if self.mode == Mode::Held || self.v == 0.0 && self.a == 0.0 {
            self.clear();
            return;
        }
        if self.mode == Mode::Run {
            self.hold();
        }
    }

    fn clear(&mut self) {
        self.seg_head += self.seg_count;
        self.seg_count = 0;
        self.sec_head += self.sec_count;
        self.sec_count = 0;
        self.running = false;
        self.mode = Mode::Run;
        self.abort_requested = false;
        self.user_hold = false;
        self.override_hold = false;
        self.v = 0.0;
        self.a = 0.0;
        self.s_local = 0.0;
        self.last.feed_mm_s = 0.0;
    }

    /// Advances one period and writes the setpoint. Bounded work, no allocation.
    pub fn step(&mut self, out: &mut Setpoint) -> StepResult {
        if self.mode == Mode::Held {
            *out = self.last;
            if self.abort_requested {
                self.clear();
                return StepResult::Idle;
            }
            return StepResult::Held;
        }
        if self.sec_count == 0 {
            self.v = 0.0;
            self.a = 0.0;
            self.last.feed_mm_s = 0.0;
            *out = self.last;
            return StepResult::Idle;
        }
        if !self.running {
            self.running = true;
            self.plan_section_start();
        } else if (self.replan || self.boost_pending)
            && matches!(self.mode, Mode::Run | Mode::HoldPending)
        {
            self.replan_running();
        }
        self.replan = false;
        self.traj_t += self.period_s;
        let mut changes = 0;
        loop {
            let dur = self.running_duration();
            if self.traj_t < dur {
                break;
            }
            if self.mode == Mode::Braking {
                self.sample(dur);
                self.v = 0.0;
                self.a = 0.0;
                self.mode = Mode::Held;
                self.emit(out);
                out.feed_mm_s = 0.0;
                if !self.user_hold && !self.override_hold && !self.abort_requested {
                    // Resumed while stopping: at rest for this cycle, moving from the next.
                    self.resume_inner();
                    return StepResult::Moving;
                }
                return StepResult::Held;
            }
            // The profile ends inside this cycle: carry the leftover time on.
            let leftover = self.traj_t - dur;
            let (end_v, end_a) = (self.traj_end_v, self.traj_end_a);
            self.pop_section();
            changes += 1;
            if self.sec_count == 0 {
                self.finish_at_end();
                self.emit(out);
                return StepResult::Idle;
            }
            self.v = end_v;
            self.a = end_a;
            self.s_local = 0.0;
            self.plan_section_start();
            if self.mode == Mode::HoldPending {
                self.try_brake();
            }
            // Pathological queues (hundreds of sections inside one period) would make the
            // cycle unbounded: past the limit the leftover time is dropped, which delays
            // the motion by under one period but keeps it continuous.
            self.traj_t = if changes >= MAX_SECTIONS_PER_STEP {
                0.0
            } else {
                leftover
            };
        }
        let t = self.traj_t;
        self.sample(t);
        self.emit(out);
        StepResult::Moving
    }

    /// Duration of the running profile (or coast), seconds.
    fn running_duration(&self) -> f64 {
        if self.coast_s > 0.0 {
            self.coast_s
        } else if self.own_active {
            self.own.duration_s()
        } else {
            self.traj.get_duration() * self.traj_time_scale
        }
    }

    /// Samples the profile at `t` and updates the section-local state (crossing into later
    /// sections while braking).
    fn sample(&mut self, t: f64) {
        let mut p = [0.0];
        let mut v = [0.0];
        let mut a = [0.0];
        if self.coast_s > 0.0 {
            p[0] = self.traj_end_v * t.min(self.coast_s);
            v[0] = self.traj_end_v;
        } else if self.own_active {
            (p[0], v[0], a[0]) = self.own.at(t);
        } else {
            let mut pos = DataArrayOrVec::Stack(p);
            let mut vel = DataArrayOrVec::Stack(v);
            let mut acc = DataArrayOrVec::Stack(a);
            let mut section = None;
            self.traj.at_time(
                t / self.traj_time_scale,
                &mut Some(&mut pos),
                &mut Some(&mut vel),
                &mut Some(&mut acc),
                &mut None,
                &mut section,
            );
            let (k, tau) = (self.traj_scale, self.traj_time_scale);
            p[0] = pos[0] / k;
            v[0] = vel[0] / (k * tau);
            a[0] = acc[0] / (k * tau * tau);
        }
        let mut s = self.traj_origin + p[0];
        // A braking profile may run into following sections.
        while self.mode == Mode::Braking && self.sec_count > 1 {
            let len = self.sec(self.sec_head).length;
            if s <= len {
                break;
            }
            self.pop_section();
            self.traj_origin -= len;
            s -= len;
        }
        let len = self.sec(self.sec_head).length;
        self.s_local = s.clamp(0.0, len);
        self.v = v[0].max(0.0);
        self.a = a[0];
    }

    /// Writes the setpoint for the current section-local position.
    fn emit(&mut self, out: &mut Setpoint) {
        if self.sec_count == 0 {
            *out = self.last;
            return;
        }
        let sec = *self.sec(self.sec_head);
        let last_seg = sec.first + sec.count - 1;
        if self.cursor < sec.first {
            self.cursor = sec.first;
        }
        while self.cursor < last_seg {
            let slot = (self.cursor % self.segs.len() as u64) as usize;
            let end = self.seg_offset[slot] + self.segs[slot].length_mm;
            if self.s_local < end {
                break;
            }
            self.cursor += 1;
        }
        // Segments already passed are released at once, so that a long section frees queue
        // room as it runs (otherwise a queue full of one section would force a stop).
        if self.cursor > sec.first {
            let passed = self.cursor - sec.first;
            self.seg_head += passed;
            self.seg_count -= passed;
            let head = self.sec_head;
            let front = self.sec_mut(head);
            front.first += passed;
            front.count -= passed;
        }
        let slot = (self.cursor % self.segs.len() as u64) as usize;
        let seg = &self.segs[slot];
        let local = self.s_local - self.seg_offset[slot];
        seg.position_at(local, &mut self.last.position);
        self.last.line = seg.line;
        self.last.move_index = seg.move_index;
        self.last.move_count = seg.move_count;
        self.last.feed_mm_s = self.v;
        *out = self.last;
    }

    /// Places the state exactly at the end of the section that just ended.
    fn finish_at_end(&mut self) {
        // The popped section's last segment is still in its slot: evaluate its exact end.
        let abs = self.seg_head.wrapping_sub(1);
        let slot = (abs % self.segs.len() as u64) as usize;
        let seg = self.segs[slot];
        seg.position_at(seg.length_mm, &mut self.last.position);
        self.last.line = seg.line;
        self.last.move_index = seg.move_index;
        self.last.move_count = seg.move_count;
        self.v = 0.0;
        self.a = 0.0;
        self.last.feed_mm_s = 0.0;
        self.s_local = 0.0;
        self.running = false;
        self.traj_t = 0.0;
    }

    fn pop_section(&mut self) {
        let sec = *self.sec(self.sec_head);
        self.seg_head += sec.count;
        self.seg_count -= sec.count;
        self.sec_head += 1;
        self.sec_count -= 1;
        self.cursor = self.seg_head;
        if self.sec_count == 0 {
            self.running = false;
        }
    }

    /// Target end speed of the front section from state `(v0, a = 0)` with `rem` left,
    /// and whether it is certainly reachable.
    fn end_target(&self, v0: f64, rem: f64) -> (f64, bool) {
        let sec = self.sec(self.sec_head);
        let hard = sec.hard_end_at(sec.boosted);
        let want = self.want_end();
        let d = rem * PLAN_MARGIN;
        let (_, a, j) = sec.limits(sec.boosted);
        let fits = |v1: f64| change_distance(v0, v1, a, j) <= d;
        if v0 < want {
            return (want.min(reach(v0, d, a, j)), true);
        }
        if fits(want) {
            return (want, true);
        }
        // The soft target is out of reach; slowing down partially can be out of reach too
        // while a full stop is not (see [`reach_back`]). Take the lowest reachable speed at
        // or above the soft target, else the hard end speed, else a stop.
        let top = v0.min(hard);
        if v0 <= hard {
            return (bisect(top, want, 30, fits), false);
        }
        if fits(hard) {
            (hard, false)
        } else {
            (0.0, false)
        }
    }

    /// The end speed the front section aims at: its soft lookahead within its own and the
    /// next section's speed limits and its hard lookahead (zero at the queue end).
    fn want_end(&self) -> f64 {
        if self.sec_count < 2 {
            return 0.0;
        }
        let sec = self.sec(self.sec_head);
        let next = self.sec(self.sec_head + 1);
        let ovr = self.override_factor;
        sec.soft_end
            .min(sec.v_eff(ovr, sec.boosted))
            .min(sec.hard_end_at(sec.boosted))
            .min(next.v_eff(ovr, next.wants_boost(ovr)))
    }

    /// A speed-up that goes on into the next section: the end state `(v1, a1)`, `a1 > 0`,
    /// for the front section entered (or re-planned) at `(v0, a0)` with `rem` left, or
    /// `None` where the speed-up should end at `a = 0` as usual.
    ///
    /// A section whose end speed is bounded by the distance it has to speed up in would
    /// otherwise end its speed-up at `a = 0` and the next section start a new one: a stair
    /// whose every step costs the time the jerk needs to bring the acceleration down and up
    /// again (on the pieces of smoothed CAM code, a ramp from rest crosses two or three
    /// sections). Only at the base level of both sections and while no hold is pending.
    ///
    /// The speed `v1 + a1²/2j` at which the next section can have brought the acceleration
    /// to zero at its conservative jerk (that of its hard lookahead, which segments merged
    /// into it later never go below) must be within:
    /// - its hard and soft start speeds and its conservative feed: the envelope
    ///   `v + a²/2j ≤ v_max` under which the planner's budgets hold is kept (in this
    ///   section too, with its own jerk);
    /// - its hard and soft end speeds: it then reaches its end within its lookahead as from
    ///   an entry at `a = 0` within its hard start speed, once the acceleration is down,
    ///   which must fit in its length. (Without this the speed-up could overshoot what the
    ///   next section has to slow down to, and then lose more than it gained: raising an
    ///   acceleration limit slowed a program of `monotonic.rs` by 2 %.)
    fn carry_target(&self, v0: f64, a0: f64, rem: f64) -> Option<(f64, f64)> {
        if self.mode != Mode::Run || self.sec_count < 2 || a0 < 0.0 {
            return None;
        }
        let ovr = self.override_factor;
        let sec = self.sec(self.sec_head);
        let next = self.sec(self.sec_head + 1);
        if sec.boosted || next.wants_boost(ovr) || next.hard_start < 0.0 || next.soft_start < 0.0 {
            return None;
        }
        let (v_machine, accel, jerk) = sec.limits(false);
        let vmax = sec.v_eff(ovr, false).min(v_machine);
        let want = self.want_end();
        let (v_at, d0) = settle(v0, a0, jerk);
        let d = rem * PLAN_MARGIN;
        // The end speed with `a = 0`: the carry reaches about as much before its own room.
        let plain = reach(v_at, d - d0, accel, jerk);
        if d0 >= d || v_at >= want || plain >= want {
            return None;
        }
        let (c_accel, c_jerk) = next.c_accel_jerk();
        let next_top = next
            .hard_start
            .min(next.soft_start)
            .min(next.v_eff(ovr, false))
            .min(next.c_feed * ovr)
            .min(next.hard_end)
            .min(next.soft_end);
        // The next section brings the acceleration to zero within its length.
        let settles = |v1: f64, a1: f64| settle(v1, a1, c_jerk).1 <= next.length * BACKWARD_MARGIN;
        // The highest end speed reachable with end acceleration `a1`: the quickest rise
        // filling `CARRY_FILL` of the section, so that the solver meets a target inside what
        // is reachable, not on its edge (where it failed in the property tests), and more
        // than the mere rise and fall of the acceleration. None when even that does not fit.
        let top = want.min(vmax);
        let reach_with = |a1: f64| {
            let v1 = rise_reach(v0, a0, a1, CARRY_FILL * d, accel, jerk)?.min(top);
            let least = rise_with_peak(v0, a0, a1, a0.max(a1), jerk).1 - v0;
            (v1 - v0 - least > CARRY_MIN_RISE * (v1 - v0)).then_some(v1)
        };
        // The end speed rises with `a1`, and so does the room `a1²/2j` it needs above it,
        // in this section and the next, and the distance the next one needs to bring it to
        // zero: the highest share of the limit on a geometric grid that keeps within them,
        // by bisection on the grid (each condition fails from some share up), so that the
        // cycle does a handful of closed-form rises at most.
        let a_top = accel.min(c_accel);
        let room = |v: f64, a1: f64| {
            v + a1 * a1 / (2.0 * jerk) <= vmax && v + a1 * a1 / (2.0 * c_jerk) <= next_top
        };
        let carry_at = |k: i32| {
            let a1 = CARRY_SHARE_RATIO.powi(k) * a_top;
            // A pre-check without the rise: no room even above the plain end speed.
            if !room(plain, a1) {
                return None;
            }
            reach_with(a1)
                .filter(|&v1| room(v1, a1) && settles(v1, a1))
                .map(|v1| (v1, a1))
        };
        let (mut bad, mut good) = (-1, CARRY_SHARE_STEPS - 1);
        let mut found = carry_at(good)?;
        while good - bad > 1 {
            let mid = (bad + good) / 2;
            match carry_at(mid) {
                Some(c) => (good, found) = (mid, c),
                None => bad = mid,
            }
        }
        Some(found)
    }

    /// Plans the front section's profile from the current state at its start (or where a
    /// hold left it, at rest).
    fn plan_section_start(&mut self) {
        self.boost_pending = false;
        self.choose_level();
        let sec = *self.sec(self.sec_head);
        // Entered accelerating where the section before carried its speed-up over (see
        // `carry_target`); else `a0 = 0`. Reachability is judged from where the acceleration
        // has come down to zero.
        let (v0, a0) = (self.v, self.a);
        let rem = (sec.length - self.s_local).max(0.0);
        let (v_machine, accel, jerk) = sec.limits(sec.boosted);
        let (v_at, d0) = settle(v0, a0, jerk);
        let (target, _) = self.end_target(v_at.max(0.0), (rem - d0).max(0.0));
        let vmax = sec.v_eff(self.override_factor, sec.boosted).min(v_machine);
        let origin = self.s_local;
        if v0.max(v_at) > vmax * (1.0 + 1e-9) && rem > 0.0 {
            // Entered above the speed limit of this section (its level's feed or override
            // is lower than the one the junction was planned with): come down to it as
            // fast as the limits allow, cruise, and meet the end speed. The solver's own
            // way (brake to the limit, then plan) can overshoot a short section and fail.
            // Where the section is too short to come down to its limit, the end speed is
            // the lowest one reachable (`end_target`'s, above the limit): the machine keeps
            // slowing down into the next section. (Asking the solver for the limit there
            // was a request it could not meet, counted as a solver failure: the soak of
            // `kerf-pipeline`'s properties found it after override cuts.)
            let ends = [target.min(vmax), target];
            for end_v in ends.into_iter().take(if target > vmax { 2 } else { 1 }) {
                if let Some(p) =
                    JerkProfile::cruise_between_from(v0, a0, end_v, rem, vmax, accel, jerk)
                {
                    self.run_own(origin, p, end_v);
                    return;
                }
            }
        }
        if self.calc_front(origin, v0, a0, rem, target, vmax, accel, jerk) {
            return;
        }
        // Entered above the feed: let the profile keep the entry speed as its ceiling.
        let peak = v0.max(v_at);
        let vmax2 = vmax.max(peak).min(v_machine.max(peak));
        if self.calc(origin, v0, a0, rem, (target, 0.0), vmax2, accel, jerk) {
            return;
        }
        self.failures += 1;
        // The solver failed twice: the closed-form profile to the same target, else to a
        // stop at the section end (reachable: the entry speed is within the hard lookahead,
        // which the section's limits can stop from within its length).
        let target = target.min(vmax2);
        for end_v in [target, 0.0] {
            if let Some(p) =
                JerkProfile::cruise_between_from(v0, a0, end_v, rem, vmax2, accel, jerk)
            {
                self.run_own(origin, p, end_v);
                return;
            }
        }
        // Cannot happen while the lookahead holds: stop on the path as fast as the limits
        // allow, into the following sections if need be, then go on.
        self.emergency_stop(accel, jerk);
    }

    /// Makes `p` the running profile from section-local position `origin`.
    fn run_own(&mut self, origin: f64, p: JerkProfile, end_v: f64) {
        self.own = p;
        self.own_active = true;
        self.coast_s = 0.0;
        self.traj_scale = 1.0;
        self.traj_time_scale = 1.0;
        self.traj_origin = origin;
        self.traj_t = 0.0;
        self.traj_end_v = end_v;
        self.traj_end_a = 0.0;
    }

    /// A jerk-limited stop on the path from the current state (its acceleration first
    /// brought to zero at the jerk limit) with the given limits, crossing section ends like
    /// a hold's stop; the motion goes on when it ends unless a hold is in force. Only
    /// reached when no plan within the section exists.
    fn emergency_stop(&mut self, accel: f64, jerk: f64) {
        self.emergencies += 1;
        let (v0, a0) = (self.v, self.a);
        let (v_at, d0) = settle(v0, a0, jerk);
        let d = d0 + change_distance(v_at.max(0.0), 0.0, accel, jerk);
        let top = v0.max(v_at);
        match JerkProfile::cruise_between_from(
            v0,
            a0,
            0.0,
            d * (1.0 + 1e-12) + 1e-15,
            top,
            accel.max(a0.abs()),
            jerk,
        ) {
            Some(p) => {
                self.run_own(self.s_local, p, 0.0);
                self.mode = Mode::Braking;
            }
            None => {
                // At rest (or no distance left): nothing to stop, the section ends here.
                self.run_own(self.s_local, JerkProfile::default(), 0.0);
            }
        }
    }

    /// Fixes the level the front section runs at as it starts: the one the override wants
    /// (see `Section::wants_boost`), if the entry speed is within that level's speed limit
    /// and hard lookahead, else the other (the previous section ended within the hard
    /// speed of the level it planned for, so one of them always fits). An entry with a
    /// carried speed-up, which is planned for the base level, takes the boost level only
    /// within its acceleration and envelope; else the section starts at the base level
    /// and moves up as [`MotionCore::replan_running`] does, once the acceleration allows.
    fn choose_level(&mut self) {
        let ovr = self.override_factor;
        let (v0, a0) = (self.v, self.a);
        let head = self.sec_head;
        let sec = self.sec_mut(head);
        let fits = |v: f64, hard: f64| v0 <= v * (1.0 + 1e-9) && v0 <= hard * (1.0 + 1e-9) + 1e-9;
        let base_ok = fits(sec.v_machine, sec.hard_start);
        // Entered with a speed-up carried over (planned for the base level, see
        // `carry_target`): the boost level only if the acceleration is within its limit and
        // its envelope, as `replan_running` asks before moving a running section there.
        let carry_fits_boost = a0 <= 0.0
            || (a0 <= sec.accel_boost * (1.0 + 1e-9)
                && v0 + a0 * a0 / (2.0 * sec.jerk_boost) <= sec.v_boost * (1.0 + 1e-9));
        let boost_speed_ok = fits(sec.v_boost, sec.hard_start_boost);
        let boost_ok = boost_speed_ok && carry_fits_boost;
        let wants = sec.wants_boost(ovr);
        sec.boosted = if wants {
            boost_ok || !base_ok
        } else {
            !base_ok && boost_ok
        };
        // Refused for the carried acceleration alone: move up once it has come down.
        self.boost_pending = wants && !sec.boosted && boost_speed_ok;
    }

    /// Re-plans the running section from the current state (more queue, override).
    fn replan_running(&mut self) {
        // The override asks for more than the running section's base level allows: move
        // it to its boost level if the state is within that level's limits (speed and
        // acceleration) and the end of the section is still reachable with them; else
        // keep the base level and try again next cycle while the acceleration is too high.
        self.boost_pending = false;
        let head = self.sec_head;
        let sec = *self.sec(head);
        if !sec.boosted && sec.wants_boost(self.override_factor) {
            // The boost budgets hold under the envelope `v + a²/2j ≤ v_boost` (see
            // `kerf-plan`'s budgets): a deceleration begun at the base level must be
            // within it at the boost jerk too.
            let within_envelope =
                self.a >= 0.0 || self.v + self.a * self.a / (2.0 * sec.jerk_boost) <= sec.v_boost;
            if self.a.abs() <= sec.accel_boost && self.v <= sec.v_boost && within_envelope {
                self.sec_mut(head).boosted = true;
                if self.replan_at_level() {
                    return;
                }
                self.sec_mut(head).boosted = false;
            } else {
                self.boost_pending = true;
            }
        }
        self.replan_at_level();
    }

    /// [`MotionCore::replan_running`] at the running section's level; `true` if a new
    /// profile is running.
    fn replan_at_level(&mut self) -> bool {
        let sec = *self.sec(self.sec_head);
        let (v0, a0) = (self.v, self.a);
        let (v_machine, accel, j) = sec.limits(sec.boosted);
        // Bring the acceleration to zero first, then check reachability from there.
        let (v_at, d0) = settle(v0, a0, j);
        let rem = sec.length - self.s_local;
        if v_at < 0.0 || d0 >= rem || rem <= 0.0 {
            return false;
        }
        let (target, sure) = self.end_target(v_at, rem - d0);
        if !sure {
            return false;
        }
        // The speed still rises to `v_at` while the acceleration comes down: after an
        // override cut that can be above the new feed, and the ceiling must allow it.
        let peak = v0.max(v_at);
        if peak > v_machine * (1.0 + 1e-9) {
            return false;
        }
        let vmax = sec.v_eff(self.override_factor, sec.boosted).max(peak);
        // On failure the previous profile is untouched and still valid.
        self.calc_front(self.s_local, v0, a0, rem, target, vmax, accel, j)
    }

    /// The front section's profile from `(v0, a0)` at `origin` with `rem` left: to the
    /// carried speed-up's end state where [`MotionCore::carry_target`] offers one and the
    /// solver takes it, else to `target` with `a = 0`. Each calculation refused counts as
    /// a solver failure; on `false` the running profile is untouched.
    #[allow(clippy::too_many_arguments)]
    fn calc_front(
        &mut self,
        origin: f64,
        v0: f64,
        a0: f64,
        rem: f64,
        target: f64,
        vmax: f64,
        accel: f64,
        jerk: f64,
    ) -> bool {
        if let Some(carry) = self.carry_target(v0, a0, rem) {
            if self.calc(origin, v0, a0, rem, carry, vmax, accel, jerk) {
                return true;
            }
            self.failures += 1;
        }
        let ok = self.calc(origin, v0, a0, rem, (target, 0.0), vmax, accel, jerk);
        if !ok {
            self.failures += 1;
        }
        ok
    }

    /// One position-interface profile calculation from `(v0, a0)` to `(v1, a1)` at
    /// `distance`; on success it becomes the running profile, on failure the running
    /// profile is left untouched.
    ///
    /// Very short moves are planned in scaled units: the solver's numerics fail on
    /// remainders of nanometres (left by a stop or a hold right at a section end). With the
    /// distance as the unit of length and `(d/j)^(1/3)` as the unit of time every input is
    /// of order one; the profile is the same motion, sampled and scaled back.
    #[allow(clippy::too_many_arguments)]
    fn calc(
        &mut self,
        origin: f64,
        v0: f64,
        a0: f64,
        distance: f64,
        (v1, a1): (f64, f64),
        vmax: f64,
        accel: f64,
        jerk: f64,
    ) -> bool {
        // A remainder below a picometre is taken as reached at the current speed: the step
        // it leaves in the position is invisible even in the jerk at the period.
        let (a0, distance, v1, a1, vmax) = if distance < 1e-12 {
            (0.0, 0.0, v0, 0.0, vmax.max(v0))
        } else {
            (a0, distance, v1, a1, vmax)
        };
        // A sliver section (blends that meet leave nanometre remnants of a line) is passed at
        // the entry speed in the time it takes, where the solver fails on such inputs: when
        // it takes less than `COAST_BELOW_S` (no speed can change over it), or when it is
        // shorter than `COAST_BELOW_MM` and no slower end is asked for. At a few µm/s a
        // nanometre takes milliseconds, and the lookahead may have planned a slow-down
        // over it: coasted at the entry speed, it entered the next junction at 8 times its
        // cap (a 1e-6 mm remnant between two near-reversing arc blends, 1.8 µm/s against
        // 0.22 µm/s, a Y jerk of 127 % of 2,000 mm/s³ at 100 µs, issue 24). Nor where the
        // coast would take longer than a jerk-limited move across it from rest to rest
        // (`(32 d / j)^(1/3)`): a 0.2 µm remnant entered at 1 nm/s, the cap of a kink on an
        // axis with 4 mm/s³, was coasted for 175 s instead of planned in 7 ms. Its time is
        // kept, so the positions stay smooth.
        if a0 == 0.0
            && a1 == 0.0
            && v0 > 0.0
            && distance > 0.0
            && (distance < v0 * COAST_BELOW_S
                || (distance < COAST_BELOW_MM
                    && v1.min(vmax) >= v0 * (1.0 - 1e-9)
                    && distance / v0 <= (32.0 * distance / jerk).cbrt()))
        {
            self.coast_s = distance / v0;
            self.own_active = false;
            self.traj_origin = origin;
            self.traj_t = 0.0;
            self.traj_end_v = v0;
            self.traj_end_a = 0.0;
            return true;
        }
        // Scaled units: the distance is the unit of length and the time to cover it at the
        // jerk limit alone, `(d/j)^(1/3)`, the unit of time, so every input is of order
        // one. The solver's tolerances are absolute (1e-10 on the acceleration, 1e-8 on
        // speed and position); in millimetres and seconds a fast machine (acceleration
        // 1e4..1e6 mm/s²) is rounded past them and the solver fails on ordinary
        // rest-to-rest moves (0.3 % of feasible inputs over the accepted limits).
        #[cfg(test)]
        if self.fail_solver {
            return false;
        }
        let (k, tau) = if distance > 0.0 {
            (1.0 / distance, (distance / jerk).cbrt())
        } else {
            (1.0, 1.0)
        };
        // Velocity, acceleration and jerk in the scaled units.
        let (kv, ka, kj) = (k * tau, k * tau * tau, k * tau * tau * tau);
        let inp = &mut self.input;
        inp.control_interface = ControlInterface::Position;
        inp.current_position[0] = 0.0;
        inp.current_velocity[0] = v0 * kv;
        inp.current_acceleration[0] = a0 * ka;
        inp.target_position[0] = distance * k;
        inp.target_velocity[0] = v1.min(vmax) * kv;
        inp.target_acceleration[0] = a1 * ka;
        inp.max_velocity[0] = vmax.max(1e-9) * kv;
        inp.max_acceleration[0] = accel * ka;
        inp.max_jerk[0] = jerk * kj;
        let ok = matches!(
            self.otg.calculate(&self.input, &mut self.scratch),
            Ok(RuckigResult::Working)
        ) && self.scratch_reaches(distance * k);
        if ok {
            std::mem::swap(&mut self.traj, &mut self.scratch);
            self.own_active = false;
            self.coast_s = 0.0;
            self.traj_scale = k;
            self.traj_time_scale = tau;
            self.traj_origin = origin;
            self.traj_t = 0.0;
            self.traj_end_v = v1.min(vmax);
            self.traj_end_a = a1;
        }
        ok
    }

    /// A solver result is used only if its duration is finite and it ends at `target`
    /// (scaled units, so the tolerance is relative).
    fn scratch_reaches(&self, target: f64) -> bool {
        let dur = self.scratch.get_duration();
        if !dur.is_finite() || dur < 0.0 {
            return false;
        }
        let mut p = DataArrayOrVec::Stack([0.0]);
        let mut section = None;
        self.scratch.at_time(
            dur,
            &mut Some(&mut p),
            &mut None,
            &mut None,
            &mut None,
            &mut section,
        );
        (p[0] - target).abs() <= 1e-6 * target.abs().max(1.0)
    }

    /// Starts the hold stop if it is safe now: the stop must pass every junction within
    /// its distance at or below the hard lookahead speed and stop before the queue end.
    fn try_brake(&mut self) {
        if self.sec_count == 0 || !self.running {
            if self.v == 0.0 {
                self.mode = if self.abort_requested {
                    Mode::Run
                } else {
                    Mode::Held
                };
                if self.abort_requested {
                    self.clear();
                }
            }
            return;
        }
        let (v0, a0) = (self.v, self.a);
        let front = *self.sec(self.sec_head);
        // The front section runs at its level; the later ones may start at either, so the
        // stop uses the limits valid at both (the boost ones are at most the base ones).
        let (_, mut accel, mut jerk) = front.limits(front.boosted);
        let (front_accel, front_jerk) = (accel, jerk);

        for _ in 0..3 {
            if !self.calc_brake(v0, a0, accel, jerk) {
                self.failures += 1;
                return;
            }
            let dist = self.brake_distance();
            // Lowest limits over the sections the stop crosses.
            let (mut a_min, mut j_min) = (front_accel, front_jerk);
            let mut covered = front.length - self.s_local;
            let mut k = self.sec_head + 1;
            let mut n = 0;
            while covered < dist && k < self.sec_head + self.sec_count && n < MAX_HOLD_SCAN {
                let s = self.sec(k);
                a_min = a_min.min(s.accel).min(s.accel_boost);
                j_min = j_min.min(s.jerk).min(s.jerk_boost);
                covered += s.length;
                k += 1;
                n += 1;
            }
            if a_min >= accel && j_min >= jerk {
                break;
            }
            accel = a_min;
            jerk = j_min;
        }
        // Already decelerating so hard that a stop with these limits would undershoot into
        // reverse: the running plan stops sooner anyway, so wait for the next section.
        if a0 < 0.0 && v0 + a0 * a0.abs() / (2.0 * jerk) <= 1e-9 {
            return;
        }
        let dist = self.brake_distance();
        let v_peak = v0
            + if a0 > 0.0 {
                a0 * a0 / (2.0 * jerk)
            } else {
                0.0
            };
        // The segments' budgets hold where `v + a²/2j ≤ v_max` (the jerk-limited envelope,
        // see `kerf-plan`'s budgets); a stop with a lower jerk than the front section's
        // (a later section's) rises to `v_peak` first, which must stay within the limit.
        let mut ok = v_peak <= front.limits(front.boosted).0 * (1.0 + 1e-9);
        let mut boundary = front.length - self.s_local;
        let mut k = self.sec_head;
        let end = self.sec_head + self.sec_count;
        let mut n = 0;
        while ok && boundary < dist {
            let s = self.sec(k);
            // Past the front section the stop runs on limits valid at the boost level.
            let hard = if k == self.sec_head {
                s.hard_end_at(s.boosted)
            } else {
                s.hard_end_boost
            };
            if k + 1 >= end || n >= MAX_HOLD_SCAN || hard < v_peak {
                ok = false;
                break;
            }
            let next = self.sec(k + 1);
            if next.v_boost < v_peak
                || next.accel.min(next.accel_boost) < accel
                || next.jerk.min(next.jerk_boost) < jerk
            {
                ok = false;
                break;
            }
            boundary += next.length;
            k += 1;
            n += 1;
        }
        if ok {
            std::mem::swap(&mut self.traj, &mut self.scratch);
            self.own_active = false;
            self.coast_s = 0.0;
            self.traj_scale = self.brake_scale;
            self.traj_time_scale = self.brake_time_scale;
            self.traj_origin = self.s_local;
            self.traj_t = 0.0;
            self.traj_end_v = 0.0;
            self.traj_end_a = 0.0;
            self.mode = Mode::Braking;
        }
    }

    /// A velocity-interface stop from `(v0, a0)` into `scratch`, in scaled units for the
    /// same reason as in `calc`: the unit of time is the stop's own jerk time scale
    /// (`sqrt(v/j)` or `|a|/j`, whichever is longer) and the unit of length what the jerk
    /// covers in it, so that the state is of order one whatever limit is idle (a huge
    /// acceleration limit must not make the speed vanish in the solver's units).
    /// `brake_scale`/`brake_time_scale` hold the units.
    fn calc_brake(&mut self, v0: f64, a0: f64, accel: f64, jerk: f64) -> bool {
        let a_lim = accel.max(a0.abs());
        let tau = (v0.abs() / jerk).sqrt().max(a0.abs() / jerk);
        // At rest there is nothing to scale: the stop is empty in any units.
        let (k, tau) = if tau > 0.0 {
            (1.0 / (jerk * tau * tau * tau), tau)
        } else {
            (1.0, 1.0)
        };
        if !(k.is_finite() && tau.is_finite() && k > 0.0) {
            return false;
        }
        let (kv, ka) = (k * tau, k * tau * tau);
        let inp = &mut self.input;
        inp.control_interface = ControlInterface::Velocity;
        inp.current_position[0] = 0.0;
        inp.current_velocity[0] = v0 * kv;
        inp.current_acceleration[0] = a0 * ka;
        inp.target_velocity[0] = 0.0;
        inp.target_acceleration[0] = 0.0;
        inp.max_acceleration[0] = a_lim * ka;
        inp.max_jerk[0] = jerk * ka * tau;
        let ok = matches!(
            self.otg.calculate(&self.input, &mut self.scratch),
            Ok(RuckigResult::Working)
        ) && self.scratch.get_duration().is_finite();
        self.input.control_interface = ControlInterface::Position;
        self.brake_scale = k;
        self.brake_time_scale = tau;
        ok
    }

    /// Distance of the stop in `scratch` (after `calc_brake`), mm.
    fn brake_distance(&self) -> f64 {
        let mut p = DataArrayOrVec::Stack([0.0]);
        let mut section = None;
        self.scratch.at_time(
            self.scratch.get_duration(),
            &mut Some(&mut p),
            &mut None,
            &mut None,
            &mut None,
            &mut section,
        );
        p[0] / self.brake_scale
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerf_geom::{Arc, CornerMode, Curve, Line, Move, Path};

    /// A planned line along X from `x0`, `len` mm long, with speed limit `v_max` and feed
    /// `feed` (mm/s), acceleration `a` and jerk `j` at both levels, and end cap `cap`.
    fn x_line(
        x0: f64,
        len: f64,
        (v_max, feed): (f64, f64),
        (a, j): (f64, f64),
        cap: f64,
    ) -> PlannedSegment {
        let curve = Curve::line(Vec3::new(x0, 0.0, 0.0), Vec3::new(x0 + len, 0.0, 0.0));
        let mut s = PlannedSegment::with_zero_limits(curve, len, ([0.0; 3], [0.0; 3]), 1, 0, feed);
        s.v_max_mm_s = v_max;
        (s.accel_mm_s2, s.jerk_mm_s3) = (a, j);
        (s.v_boost_mm_s, s.accel_boost_mm_s2, s.jerk_boost_mm_s3) = (v_max, a, j);
        s.end_cap_mm_s = cap;
        s
    }

    /// Steps `core` until it is idle: the X position before the first step and after
    /// every step, the idle one included.
    fn x_positions(core: &mut MotionCore) -> Vec<f64> {
        let mut sp = Setpoint::default();
        let mut xs = vec![0.0];
        loop {
            let r = core.step(&mut sp);
            xs.push(sp.position[0]);
            if r == StepResult::Idle {
                return xs;
            }
            assert!(xs.len() < 100_000);
        }
    }

    fn mv(path: Path, feed_mm_min: f64) -> Move {
        Move {
            line: 1,
            rapid: false,
            path,
            feed_mm_min: Some(feed_mm_min),
            abc_deg: None,
            corner: CornerMode::Blend {
                tolerance_mm: None,
                naive_cam_mm: None,
            },
        }
    }

    /// The solver, called as `calc` calls it (scaled units), plans every feasible profile
    /// from a section start (`a = 0`, any entry speed, any end speed the distance allows)
    /// over the whole accepted range of limits. In mm and s, 58 of these 20,000 failed.
    #[test]
    fn scaled_solver_calls_plan_every_feasible_section() {
        let axis = AxisLimits {
            velocity_units_s: 100.0,
            acceleration_units_s2: 1000.0,
            jerk_units_s3: 1e4,
        };
        let limits = MachineLimits {
            axes: [Some(axis), Some(axis), Some(axis), None, None, None],
            period_s: 0.001,
            tolerance_mm: 0.01,
        };
        let mut core = MotionCore::new(limits.period_s, 4);
        let mut log_uniform = crate::profile::tests::log_uniform_source(0x9e37_79b9_7f4a_7c15);
        let (mut tried, mut failed) = (0, 0);
        while tried < 20_000 {
            let vmax = log_uniform(1.0, 5000.0);
            let a = log_uniform(100.0, 1e6);
            let j = log_uniform(1e3, 1e9);
            let d = log_uniform(1e-4, 1000.0);
            let v0 = if log_uniform(1.0, 4.0) < 2.0 {
                0.0
            } else {
                log_uniform(1e-3, 1.0) * vmax
            };
            let v1 = if log_uniform(1.0, 4.0) < 2.0 {
                0.0
            } else {
                log_uniform(1e-3, 1.0) * vmax
            };
            if change_distance(v0, v1, a, j) > d * PLAN_MARGIN {
                continue;
            }
            tried += 1;
            if !core.calc(0.0, v0, 0.0, d, (v1, 0.0), vmax, a, j) {
                failed += 1;
            }
        }
        assert_eq!(failed, 0, "of {tried}");
    }

    /// A feed override cut just before a chain of short sections: the machine enters each
    /// of them above its new feed and cannot come down to it within one, so it keeps
    /// slowing down from section to section, as fast as each section's limits allow, and no
    /// solver call fails (the soak of `kerf-pipeline`'s properties found the motion core
    /// asking the solver for the new feed at the end of such a section, which it could not
    /// meet, and counting a failure for each; the motion itself was then planned again).
    /// The limits of the short sections are those of that soak case.
    #[test]
    fn entered_above_the_overridden_feed_it_slows_on_without_solver_failures() {
        let seg = |x0: f64, len: f64, feed: f64, a: f64, j: f64, cap: f64| {
            x_line(x0, len, (200.0, feed), (a, j), cap)
        };
        // Feeds differ by more than the merge ratio, so every short move is a section.
        let short = [
            (0.816, 1929.0, 67_278.0),
            (0.368, 4324.0, 126_136.0),
            (0.526, 1390.0, 53_290.0),
            (0.7, 2000.0, 50_000.0),
            (0.5, 3000.0, 90_000.0),
            (4.0, 2000.0, 50_000.0),
        ];
        for cut_at_mm in [
            19.0, 19.3, 19.5, 19.6, 19.7, 19.8, 19.85, 19.9, 19.95, 19.98,
        ] {
            let mut segs = vec![seg(0.0, 20.0, 40.0, 2000.0, 50_000.0, 40.0)];
            let mut x = 20.0;
            for (k, &(len, a, j)) in short.iter().enumerate() {
                let feed = if k % 2 == 0 { 40.0 } else { 36.0 };
                let last = k + 1 == short.len();
                segs.push(seg(x, len, feed, a, j, if last { 0.0 } else { 36.0 }));
                x += len;
            }
            let mut core = MotionCore::new(0.001, 64);
            for s in &segs {
                core.push(s).unwrap();
            }
            let mut sp = Setpoint::default();
            let mut feeds = Vec::new();
            let mut cut = None;
            for cycle in 0..100_000 {
                let r = core.step(&mut sp);
                feeds.push(sp.feed_mm_s);
                if cut.is_none() && sp.position[0] >= cut_at_mm {
                    core.set_feed_override(0.23);
                    cut = Some(cycle);
                }
                if r == StepResult::Idle {
                    break;
                }
            }
            let cut = cut.expect("the cut happened");
            assert_eq!(core.plan_failures(), 0, "cut at {cut_at_mm} mm");
            assert_eq!(core.emergency_stops(), 0, "cut at {cut_at_mm} mm");
            assert!(
                (sp.position[0] - x).abs() < 1e-9,
                "ends at {}",
                sp.position[0]
            );
            // From the cut on, the speed only falls until it is at the new feed (36 · 0.23
            // = 8.28 mm/s on the slower moves), and then stays at or under 40 · 0.23.
            let new_feed = 40.0 * 0.23;
            let under = cut
                + feeds[cut..]
                    .iter()
                    .position(|&f| f <= new_feed + 1e-9)
                    .unwrap();
            for w in feeds[cut + 1..under].windows(2) {
                assert!(
                    w[1] <= w[0] + 1e-9,
                    "cut at {cut_at_mm} mm: speeds up to {}",
                    w[1]
                );
            }
            assert!(feeds[under..].iter().all(|&f| f <= new_feed + 1e-9));
        }
    }

    /// A long line behind a short segment with about a nineteenth of its acceleration and a
    /// fifteenth of its jerk (a corner blend) stops with its own limits, not the short
    /// one's: it is a section of its own ([`MERGE_ABOVE`]). Measured from the positions:
    /// the stop at the end takes about `2·sqrt(v/j)` with the line's jerk (15 ms), where
    /// the blend's limits need `v/a + a/j` (62 ms; 59 ms measured without the rule). The
    /// junction between them is passable at any speed, so only the limits decide.
    #[test]
    fn a_line_behind_a_much_weaker_segment_stops_with_its_own_limits() {
        let v = 4.17;
        let seg =
            |x0: f64, len: f64, a: f64, j: f64, cap: f64| x_line(x0, len, (200.0, v), (a, j), cap);
        let (a_weak, j_weak, a_line, j_line) = (100.0, 5000.0, 1900.0, 75_000.0);
        // By the lower merge ratios alone the line would join the weak segment's section
        // (its limits are above them); more than `MERGE_ABOVE` times above, it may not.
        assert!(a_line > MERGE_ABOVE * a_weak && j_line > MERGE_ABOVE * j_weak);
        let mut core = MotionCore::new(0.001, 8);
        core.push(&seg(0.0, 0.05, a_weak, j_weak, 200.0)).unwrap();
        core.push(&seg(0.05, 5.0, a_line, j_line, 0.0)).unwrap();
        let xs = x_positions(&mut core);
        assert!(
            (xs[xs.len() - 1] - 5.05).abs() < 1e-9,
            "{}",
            xs[xs.len() - 1]
        );
        let speeds: Vec<f64> = xs.windows(2).map(|w| (w[1] - w[0]) / 0.001).collect();
        // From the last period at (nearly) the feed to rest.
        let last_fast = speeds.iter().rposition(|&s| s > 0.99 * v).unwrap();
        let stop_s = (speeds.len() - last_fast) as f64 * 0.001;
        let with_line = 2.0 * (v / j_line).sqrt();
        let with_weak = v / a_weak + a_weak / j_weak;
        assert!(
            stop_s < 0.5 * (with_line + with_weak),
            "stop took {stop_s} s: {with_line} s with the line's limits, {with_weak} s with the weak one's"
        );
    }

    /// A speed-up from rest over a short section into a longer one it cannot merge with
    /// (its jerk is under the merge ratio of the first's; a third section, weaker again,
    /// ends the program) goes on across the boundary: measured from the positions, the
    /// acceleration does not come down to zero between leaving rest and nearing the feed,
    /// and every limit holds (each section's own past its start).
    #[test]
    fn a_speed_up_goes_on_into_the_next_section_without_a_stair() {
        let feed = 50.0;
        let seg = |x0: f64, len: f64, a: f64, j: f64, cap: f64| {
            x_line(x0, len, (feed, feed), (a, j), cap)
        };
        let (accel, j_first, j_second, j_third) = (1200.0, 18_000.0, 13_000.0, 9_000.0);
        assert!(!limits_merge(accel, j_second, (accel, j_first)));
        assert!(!limits_merge(accel, j_third, (accel, j_second)));
        let mut core = MotionCore::new(0.001, 8);
        core.push(&seg(0.0, 1.0, accel, j_first, feed)).unwrap();
        core.push(&seg(1.0, 15.0, accel, j_second, feed)).unwrap();
        core.push(&seg(16.0, 30.0, accel, j_third, 0.0)).unwrap();
        let xs = x_positions(&mut core);
        assert!((xs[xs.len() - 1] - 46.0).abs() < 1e-9);
        assert_eq!(core.plan_failures(), 0);
        let dt = 0.001;
        let v: Vec<f64> = xs.windows(2).map(|w| (w[1] - w[0]) / dt).collect();
        let a: Vec<f64> = v.windows(2).map(|w| (w[1] - w[0]) / dt).collect();
        let j: Vec<f64> = a.windows(2).map(|w| (w[1] - w[0]) / dt).collect();
        assert!(v.iter().all(|&v| v <= feed * 1.01));
        assert!(a.iter().all(|&a| a.abs() <= accel * 1.01));
        for (k, &j) in j.iter().enumerate() {
            // Past the boundary (with the three periods a third difference spans).
            let limit = match xs[k] {
                x if x > 16.0 => j_third,
                x if x > 1.0 => j_second,
                _ => j_first,
            };
            assert!(j.abs() <= limit * 1.01, "jerk {j} at x = {}", xs[k]);
        }
        let rising = v.iter().position(|&v| v > 0.1 * feed).unwrap();
        let near = v.iter().position(|&v| v > 0.9 * feed).unwrap();
        let boundary = xs.iter().position(|&x| x > 1.0).unwrap();
        assert!(rising < boundary && boundary < near);
        let low = a[rising..near]
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        assert!(
            low > 0.25 * accel,
            "the acceleration came down to {low} mm/s² on the way up"
        );
    }

    /// A carried speed-up whose next section comes to want its boost level while the
    /// carry runs (the feed override raised near the boundary, too late for the running
    /// section to re-plan to `a = 0`): the next section starts at a level whose limits the
    /// carried acceleration is within (the boost level's acceleration is lower here), and
    /// moves to the boost level once it is. While a section runs at its boost level, the
    /// acceleration from the positions stays within that level's.
    #[test]
    fn an_override_raised_during_a_carried_speed_up_keeps_a_level_that_fits_it() {
        let feed = 50.0;
        let (accel, j_first, j_second) = (1200.0, 18_000.0, 13_000.0);
        let (v_boost, accel_boost, jerk_boost) = (80.0, 300.0, 6_000.0);
        let mut second = x_line(1.0, 15.0, (feed, feed), (accel, j_second), feed);
        (
            second.v_boost_mm_s,
            second.accel_boost_mm_s2,
            second.jerk_boost_mm_s3,
        ) = (v_boost, accel_boost, jerk_boost);
        let (mut carried, mut boosted_runs) = (0, 0);
        // Raise the override at every period of the first section's second half in turn.
        for raise_at in 1..200 {
            let mut core = MotionCore::new(0.001, 8);
            core.push(&x_line(0.0, 1.0, (feed, feed), (accel, j_first), feed))
                .unwrap();
            core.push(&second).unwrap();
            core.push(&x_line(16.0, 30.0, (feed, feed), (accel, j_second), 0.0))
                .unwrap();
            let mut sp = Setpoint::default();
            // Position after each step, and whether the section running was boosted.
            let mut xs = vec![(0.0, false)];
            loop {
                let r = core.step(&mut sp);
                let boosted = core.sec_count > 0 && core.sec(core.sec_head).boosted;
                xs.push((sp.position[0], boosted));
                if xs.len() == raise_at {
                    if !(0.5..1.0).contains(&sp.position[0]) {
                        break;
                    }
                    if core.traj_end_a > 0.0 {
                        carried += 1;
                    }
                    core.set_feed_override(1.5);
                }
                if r == StepResult::Idle {
                    break;
                }
                assert!(xs.len() < 100_000);
            }
            if xs.len() <= raise_at {
                continue;
            }
            assert!((xs[xs.len() - 1].0 - 46.0).abs() < 1e-9);
            assert_eq!(core.plan_failures(), 0, "raised at {raise_at}");
            assert_eq!(core.emergency_stops(), 0, "raised at {raise_at}");
            let dt = 0.001;
            if xs.iter().any(|&(_, b)| b) {
                boosted_runs += 1;
            }
            for (k, w) in xs.windows(3).enumerate() {
                let a = (w[2].0 - 2.0 * w[1].0 + w[0].0) / (dt * dt);
                let limit = if w[1].1 && w[2].1 { accel_boost } else { accel };
                assert!(
                    a.abs() <= limit * 1.01,
                    "raised at {raise_at}: a {a} mm/s² at step {k}, x = {}",
                    w[1].0
                );
            }
        }
        assert!(carried > 5, "{carried}");
        assert!(boosted_runs > 5, "{boosted_runs}");
    }

    /// A chain of 2 mm segments whose speeds differ by 1–2 % (smoothed pieces on a slope)
    /// ending at a stop: a slower segment joins the section before it, so speeds stepping
    /// down make no stair of sections each ending at `a = 0` (a step up still starts a
    /// section). Measured from the positions against the same chain with every segment
    /// at the slowest one's speed (one section by any rule), which is nowhere faster: the
    /// chain takes at most 5 % longer (3.0 % measured; 16.8 % without
    /// [`MERGE_RATIO_SLOWER`]).
    #[test]
    fn a_slow_down_across_pieces_of_nearly_equal_speed_makes_no_stair() {
        let run = |speeds: &[f64]| -> f64 {
            let mut core = MotionCore::new(0.001, 64);
            let mut x = 0.0;
            for (k, &v) in speeds.iter().enumerate() {
                let len = 2.0;
                let next = speeds.get(k + 1).copied().unwrap_or(0.0);
                let s = x_line(x, len, (v, 100.0), (1400.0, 10_000.0), v.min(next));
                core.push(&s).unwrap();
                x += len;
            }
            let mut sp = Setpoint::default();
            let mut cycles = 0;
            while core.step(&mut sp) != StepResult::Idle {
                cycles += 1;
                assert!(cycles < 100_000);
            }
            assert!((sp.position[0] - x).abs() < 1e-9);
            assert_eq!(core.plan_failures(), 0);
            cycles as f64 * 0.001
        };
        let speeds = [
            76.73, 76.73, 75.82, 77.11, 76.28, 75.56, 76.73, 75.82, 77.11, 76.28, 75.56,
        ];
        let slowest = speeds.iter().copied().fold(f64::INFINITY, f64::min);
        let varied = run(&speeds);
        let equal = run(&[slowest; 11]);
        assert!(
            varied <= 1.05 * equal,
            "{varied} s with the speeds as they are, {equal} s all at {slowest} mm/s"
        );
    }

    /// `rise_reach` against a search by numerical integration: each candidate rise (jerk up
    /// to a peak, a hold there, jerk down to `a1`) is stepped through in small time steps,
    /// and the highest peak, then the longest hold at the acceleration limit, that fits in
    /// the distance is found by bisection; its end speed must be the closed form's (which
    /// bisects its peak only 16 times, so to within 1e-3).
    #[test]
    fn the_quickest_rise_matches_a_brute_force_search() {
        let mut log_uniform = crate::profile::tests::log_uniform_source(0x0bad_5eed);
        let mut compared = 0;
        for _ in 0..60 {
            let accel = log_uniform(100.0, 1e4);
            let jerk = log_uniform(1e3, 1e6);
            let v0 = log_uniform(0.1, 100.0);
            let a0 = accel * log_uniform(1e-3, 1.0);
            let a1 = accel * log_uniform(1e-3, 1.0);
            let d = log_uniform(0.01, 20.0);
            let Some(v_closed) = rise_reach(v0, a0, a1, d, accel, jerk) else {
                continue;
            };
            // Numerical integration of one rise: distance and end speed.
            let simulate = |peak: f64, hold_s: f64| {
                let phases = [
                    ((peak - a0) / jerk, jerk),
                    (hold_s, 0.0),
                    ((peak - a1) / jerk, -jerk),
                ];
                let (mut p, mut v, mut a) = (0.0, v0, a0);
                for (t, j) in phases {
                    let n = 400;
                    let dt = t / n as f64;
                    for _ in 0..n {
                        // Midpoint steps: exact for the cubic up to rounding.
                        let a_mid = a + j * dt / 2.0;
                        let v_mid = v + a * dt / 2.0 + j * dt * dt / 8.0;
                        p += v_mid * dt + j * dt * dt * dt / 24.0;
                        v += a_mid * dt;
                        a += j * dt;
                    }
                }
                (p, v)
            };
            // The distance grows with the peak and the hold: the highest peak that fits,
            // by bisection on the simulated distance, and at the acceleration limit the
            // longest hold that fits.
            let low = a0.max(a1);
            let best = if simulate(accel, 0.0).0 <= d {
                let hold = bisect(0.0, 2.0 * d / v0, 60, |h| simulate(accel, h).0 <= d);
                simulate(accel, hold).1
            } else {
                let peak = bisect(low, accel, 60, |p| simulate(p, 0.0).0 <= d);
                simulate(peak, 0.0).1
            };
            assert!(
                (best - v_closed).abs() <= 1e-3 * v_closed,
                "closed form {v_closed}, brute force {best} (v0 {v0} a0 {a0} a1 {a1} d {d} accel {accel} jerk {jerk})"
            );
            compared += 1;
        }
        assert!(compared > 20, "{compared}");
    }

    /// The planner judges ramp budgets by whether a piece joins the section before it
    /// (`kerf_geom::speeds_merge`, `kerf_geom::limits_merge`); the motion core decides the
    /// same: for two segments with the given speed limits and limits ratios, at the tail
    /// of a queue (where the slower-merge condition holds), it makes one section exactly
    /// when both functions say so.
    #[test]
    fn the_planners_merge_estimate_is_the_motion_cores_rule() {
        let mut log_uniform = crate::profile::tests::log_uniform_source(0x5eed_cafe);
        let seg = |x0: f64, v: f64, a: f64, j: f64| x_line(x0, 2.0, (v, 1000.0), (a, j), 1e6);
        let (mut merged, mut split, mut slower) = (0, 0, 0);
        for _ in 0..2000 {
            let v1 = log_uniform(20.0, 200.0);
            let (a1, j1) = (log_uniform(500.0, 5000.0), log_uniform(5e3, 1e5));
            let v2 = v1 * log_uniform(0.9, 1.1);
            let a2 = a1 * log_uniform(0.8, 5.0);
            let j2 = j1 * log_uniform(0.7, 5.0);
            let mut core = MotionCore::new(0.001, 8);
            core.push(&seg(0.0, v1, a1, j1)).unwrap();
            core.push(&seg(2.0, v2, a2, j2)).unwrap();
            let expected =
                kerf_geom::speeds_merge(v2, v1) && kerf_geom::limits_merge(a2, j2, (a1, j1));
            let one_section = core.sec_count == 1;
            assert_eq!(
                one_section, expected,
                "v {v1} -> {v2}, a {a1} -> {a2}, j {j1} -> {j2}"
            );
            if one_section {
                merged += 1;
                if v2 < MERGE_RATIO_SPEED * v1 {
                    slower += 1;
                }
            } else {
                split += 1;
            }
        }
        // Both outcomes are exercised, the slower merge among them.
        assert!(
            merged > 100 && split > 100 && slower > 20,
            "{merged} merged ({slower} slower), {split} split"
        );
    }

    /// With every solver call failing, the closed-form fallback runs the whole program:
    /// no jump, every limit holds by finite differences of the positions, and the run
    /// ends at rest exactly at the program's end.
    #[test]
    fn the_fallback_runs_a_program_within_the_limits() {
        for (v, a, j, period_s) in [
            (200.0, 2000.0, 50_000.0, 0.001),
            (1000.0, 100_000.0, 1e7, 0.001),
            (30.0, 300.0, 3000.0, 0.00025),
            (5000.0, 1e6, 1e9, 0.0000625),
        ] {
            let axis = AxisLimits {
                velocity_units_s: v,
                acceleration_units_s2: a,
                jerk_units_s3: j,
            };
            let limits = MachineLimits {
                axes: [Some(axis), Some(axis), Some(axis), None, None, None],
                period_s,
                tolerance_mm: 0.01,
            };
            let p = |x: f64, y: f64, z: f64| Vec3::new(x, y, z);
            let line = |a: Vec3, b: Vec3, f: f64| mv(Path::Line(Line { start: a, end: b }), f);
            let moves = [
                line(p(0.0, 0.0, 0.0), p(10.0, 0.0, 0.0), 3000.0),
                line(p(10.0, 0.0, 0.0), p(10.0, 0.003, 0.0), 3000.0),
                line(p(10.0, 0.003, 0.0), p(12.0, 5.0, 1.0), 600.0),
                mv(
                    Path::Arc(Arc {
                        start: p(12.0, 5.0, 1.0),
                        end: p(8.0, 5.0, 1.5),
                        center: p(10.0, 5.0, 1.0),
                        axis: Vec3::z(),
                        sweep_rad: std::f64::consts::PI,
                    }),
                    6000.0,
                ),
                line(p(8.0, 5.0, 1.5), p(0.0, 0.0, 0.0), 12000.0),
            ];
            let mut planner = kerf_plan::Planner::new(limits);
            let mut segs = Vec::new();
            for m in &moves {
                planner.push(m, &mut segs).unwrap();
            }
            planner.finish(&mut segs);
            let mut core = MotionCore::new(limits.period_s, 64);
            core.fail_solver = true;
            // At rest at the origin before the first cycle.
            let mut rows: Vec<[f64; 6]> = vec![[0.0; 6]; 3];
            let mut sp = Setpoint::default();
            let mut next = 0;
            for _ in 0..10_000_000 {
                while next < segs.len() && core.push(&segs[next]).is_ok() {
                    next += 1;
                }
                let r = core.step(&mut sp);
                rows.push(sp.position);
                if r == StepResult::Idle && next == segs.len() {
                    break;
                }
            }
            assert!(core.plan_failures() > 0, "the fallback was not exercised");
            assert_eq!(rows.last().unwrap()[..3], [0.0, 0.0, 0.0]);
            // The path is about 31 mm long and no axis may exceed v.
            let t = period_s;
            let duration_s = (rows.len() - 3) as f64 * t;
            assert!(duration_s > 31.0 / (v * 3f64.sqrt()), "{duration_s} s");
            for w in rows.windows(4) {
                let axes = w[0].iter().zip(&w[1]).zip(&w[2]).zip(&w[3]).take(3);
                for (((q0, q1), q2), q3) in axes {
                    let vel = (q3 - q2).abs() / t;
                    let acc = (q3 - 2.0 * q2 + q1).abs() / (t * t);
                    let jerk = (q3 - 3.0 * q2 + 3.0 * q1 - q0).abs() / (t * t * t);
                    let noise = 8.0 * f64::EPSILON * 20.0;
                    assert!(vel <= v * 1.01, "v {vel} > {v}");
                    assert!(acc <= a * 1.01 + 2.0 * noise / (t * t), "a {acc} > {a}");
                    assert!(
                        jerk <= j * 1.01 + 4.0 * noise / (t * t * t),
                        "j {jerk} > {j}"
                    );
                }
            }
        }
    }
}
