//! A prototype of a motion core that checks every point of the path at its own speed and
//! acceleration (docs/PERFORMANCE.md, "What it would take"): benchmark-only, to measure
//! what such a core would reach on the CAM corpus and what one cycle of it costs, before
//! anything of it goes into the real-time core.
//!
//! **The path** is tabulated every `ds` mm of arc length with the tangent `t = p'`, the
//! curvature vector `κ = p''` and its derivative `κ' = p'''` (differences of `κ` within
//! each curve), over the six axes X Y Z A B C; between grid points they are interpolated
//! linearly, and positions are cubic Hermite interpolations of the points and their
//! tangents. Two paths: [`Grid::from_pieces`] takes the exact geometry (XYZ) with the
//! jerk-limited bound's curvature-continuous corner blends ([`crate::jerk::g2_blended`]),
//! and [`Grid::from_segments`] takes the planner's segments, the path Kerf's motion core
//! runs, rotary axes included (`PlannedSegment::derivatives_at`: the path parameter is the
//! XYZ arc length, degrees on a move of the rotary axes alone). Axes that do not move in
//! a section are left out of its checks.
//!
//! **The limits at a point.** With path speed `v`, acceleration `a` and jerk `j`, axis `i`
//! moves with velocity `tᵢ v`, acceleration `tᵢ a + κᵢ v²` and jerk
//! `tᵢ j + 3 κᵢ v a + κ'ᵢ v³`. At a given `v` (and `a`), each axis's limit is an interval
//! of `a` (of `j`), not a symmetric budget: the intersection over the axes is what the
//! point allows (`Section::ranges`). The speed limit of a point
//! (`v_max`) is the largest speed that leaves a non-empty interval of `a` at `a = 0`, with
//! [`CENTRIPETAL_SHARE`] of the acceleration, and of `j` at `a = 0`, with [`JERK_SHARE`]
//! of the jerk, within the feed and the axis velocities, and within the speed from which
//! [`BACKWARD_SHARE`] of the tangential deceleration reaches every later point's limit.
//!
//! **The cycle.** The state is `(s, v, a)`; the controller chooses one constant path
//! jerk for a piece of [`BRAKE_PIECE_S`] (the brakings' pieces: one period at 1 ms, four
//! at 250 µs, a single period where no piece is admissible, as in the last creep to a
//! stop), checks the piece's periods as a braking's (the intervals at its middle and its
//! end, the differences at every period) and certifies the state it ends in and, once
//! that holds, the states within it (not a condition of the piece), so that a hold
//! brakes at once where it comes on one; within the piece it plays those periods. At
//! 250 µs that is a third of the work of choosing every period, for times 0.2 to 0.7 %
//! longer. A period is admissible if the speed never falls below zero and stays within
//! `v_max` over the stretch it passes, the acceleration and the jerk stay within the intervals
//! at the middle and the end of the period, and the finite differences of the new
//! position at the period, as the output monitor takes them, stay within the whole
//! limits. A jerk is admissible if its period is and it ends in a state from which a
//! braking comes to rest before the next stop (a reversal, a stop the planner set, or
//! the end of the path) with every period admissible (`Section::can_stop`). A braking
//! heads for one of a fixed ladder of decelerations ([`BRAKE_DECELS_MM_S2`]) at a jerk
//! fixed by that deceleration ([`BRAKE_JERK_PER_S`]), fitted into each point's jerk
//! interval where it falls outside, and turns back to zero acceleration as the speed runs
//! out, landing on rest within a period (the jerk `a²/2v` brings speed and acceleration
//! to zero together; where braking harder would leave no landing, the most negative jerk
//! that still does). The brakings do not move with the limits, so that what certifies a
//! state on one machine certifies it on a machine with higher limits. Braking is itself a
//! continuation the controller may take, so a state it accepts has one: the motion can
//! stop within the known path, as today's core can.
//!
//! **Stops exactly.** A braking lands where its period ends, a little short of the stop
//! (10⁻⁷ to 10⁻⁶ mm). The last periods onto a stop are an exact approach: three periods
//! whose jerks solve the end's acceleration, speed and position (from the landing, or
//! from rest short of the stop), else, from rest, four phases `+j, −j, −j, +j` of as many
//! periods as their jerk needs; every period checked as any other. The motion comes to
//! rest on the stop within 10⁻⁹ mm, the end of the program included, and the next section
//! starts where it is (a step of 10⁻⁶ mm is 64,000 mm/s³ in the differences at 250 µs).
//!
//! **The search** for each period's jerk ([`Search`]) is where the work is, since every
//! candidate simulates brakings to rest. [`Search::Largest`] takes the largest admissible
//! jerk (a scan down the point's interval, then bisection: about 18 candidates).
//! [`Search::Candidates`], the default, tries a few jerks (around the period before's,
//! the top of the interval, the jerks that level the acceleration off and that arrive
//! at the speed limit), from the largest, and takes the first admissible; where none
//! is, it continues the braking that certified the state before, whose tail is already
//! checked to rest, so that continuation costs one period's check. It does a tenth of
//! the work or less, for times within 1.5 % (docs/PERFORMANCE.md).
//!
//! It is not quite monotonic in the limits: a raised limit slowed 5 of 1,440 runs of the
//! sweep (`cam_table --pointwise-raise`, seeds 1 to 8) by more than 1 % and a period,
//! by 2.8 % at worst; the greedy choice of each period's jerk can run a quicker machine
//! faster into a tight corner, where it then has to slow further (docs/PERFORMANCE.md).
//! With brakings that were shares of each point's deceleration, 28 runs were, by up to
//! 49 %.
//!
//! What it does not do yet: bound its cost per cycle (one braking simulated to rest is
//! still the least a moving period costs), or take the allocation-free, fixed-window
//! form of the real-time core. Its output is measured as Kerf's is: positions at the
//! period through `kerf_motion::monitor::LimitMonitor`.
#![allow(clippy::many_single_char_names)]

use std::cell::Cell;
use std::time::Instant;

use kerf_geom::ramp::bisect;
use kerf_geom::{MachineLimits, PlannedSegment, Vec3};
use kerf_motion::monitor::LimitMonitor;
use nalgebra::Vector6;

use crate::bound::{Piece, max_speed_squared_axes, unit_frame};
use crate::jerk::{JerkMachine, g2_blended};

/// Share of each axis's acceleration the speed limit of a point leaves to the centripetal
/// term at `a = 0`. The speed limit is only a cap (every period is checked against the
/// intervals themselves): 1.0 makes it the point's own limit; 0.85 and 0.95 measured
/// slower on raster C and the obround (docs/PERFORMANCE.md).
pub const CENTRIPETAL_SHARE: f64 = 1.0;
/// Share of the tangential deceleration the axes allow (each axis's acceleration over its
/// tangent component, centripetal part left out) with which the speed limit of a point
/// is carried backwards along the path: the limit is also the speed from which that
/// deceleration comes down to every later point's limit in time. Only ever a lower cap,
/// so it cannot admit what the checks refuse; it makes the controller, greedy for the
/// largest jerk, slow down before a curve at a moderate deceleration rather than brake
/// hard into it, where the `3 κ v a` term of the jerk then forced it far below the
/// curve's limit (the obround on the planner's segments: 2.424 s without it, 2.149 s
/// with 0.5; 2.155 s with 0.4, 2.167 s with 0.6; the rest within 0.1 % on the planner's
/// segments; docs/PERFORMANCE.md).
pub const BACKWARD_SHARE: f64 = 0.5;
/// Share of each axis's jerk the speed limit of a point leaves to the `κ' v³` term (a cap
/// as [`CENTRIPETAL_SHARE`]).
pub const JERK_SHARE: f64 = 1.0;
/// Share of the acceleration and jerk limits the controller plans with (the intervals):
/// the rest is the room the finite differences at the period, checked against the whole
/// limits, need (at 1.0 the two collide and the rasters crawl; docs/PERFORMANCE.md).
pub const PLAN_SHARE: f64 = 0.97;
/// Bisection steps on the jerk of a period ([`Search::Largest`]).
pub const BISECTION_STEPS: usize = 10;
/// Steps of the scan down the jerk interval for a first admissible jerk
/// ([`Search::Largest`]).
pub const SCAN_STEPS: usize = 8;
/// [`Search::Candidates`] tries the previous period's jerk and that jerk moved by 1 and 4
/// of this many parts of the point's jerk interval, either way.
const CANDIDATE_STEPS: f64 = 64.0;
/// The decelerations the brakings that certify a state head for, hardest first, mm/s².
/// First the hardest each point allows (`∞`: its most negative acceleration, at the
/// largest jerk its interval allows), which stops a line in the S-curve's time; then
/// halves from 64 m/s² down to 8 mm/s², a ladder that does not move with the machine's
/// limits, so that a braking of it that lands on a machine also lands, the same motion,
/// on any machine with higher limits (as far as its jerk is not fitted into a point's
/// interval, see `Section::brake_jerk`).
///
/// The former family, shares (1 to 1/16) of each point's most negative acceleration,
/// made every braking harder as an acceleration limit rose; at speed on a curve the
/// harder braking then failed the `3 κ v a` jerk term, and a raised limit slowed 28 of
/// the 1,440 runs of the monotonic sweep, by up to 49 % (4 now, by up to 5.6 %;
/// docs/PERFORMANCE.md, "Monotonic in the limits"). Halves rather than steps of 1/√2:
/// half the brakings, and that sweep no worse.
pub const BRAKE_DECELS_MM_S2: [f64; 15] = [
    f64::INFINITY,
    65536.0,
    32768.0,
    16384.0,
    8192.0,
    4096.0,
    2048.0,
    1024.0,
    512.0,
    256.0,
    128.0,
    64.0,
    32.0,
    16.0,
    8.0,
];
/// The jerk of a braking, per mm/s² of its deceleration, 1/s: the most it turns its
/// acceleration down to its deceleration with, and back to zero with as it lands (40 ms
/// each way), unless a point's jerk interval asks for more. Fixed, like the
/// decelerations, and near the ratio of the axes' limits on the CAM mill (25 and 20 /s).
/// Brakings at 40 and 10 /s as well (twice the brakings) made one run of the monotonic
/// sweep 40 % slower (docs/PERFORMANCE.md).
pub const BRAKE_JERK_PER_S: f64 = 25.0;
/// A period whose lowest speed, where its acceleration turns from negative to positive,
/// is below this lands on rest there, mm/s.
const LANDED_MM_S: f64 = 1e-6;
/// A braking whose hard jerk would leave no landing lands at once (the jerk `a²/2v`)
/// only if that jerk is at least this share of the braking's largest: at an acceleration
/// near zero it is near zero, and the speed would never run out (a braking from
/// 0.024 mm/s ran 100,000 periods); below it the braking takes the most negative jerk
/// that still lands.
const LAND_FLOOR: f64 = 0.25;
/// A motion at rest this close short of its stop has reached it, mm: within rounding.
const STOP_GAP_MM: f64 = 1e-9;
/// At rest at most this far short of a stop, the motion goes there by an exact approach
/// (`Section::final_approach`), mm.
const FINAL_APPROACH_MM: f64 = 0.01;
/// Most periods of each of the four phases of a final approach.
const FINAL_APPROACH_PERIODS: usize = 256;
/// Slack of the intervals checked within a period, as a share of their width: a
/// braking's jerk is fitted to the end point's interval once, at a state a little
/// different from the one it ends in.
const END_SLACK: f64 = 1e-3;
/// A braking holds each jerk this long (whole periods, at least one), with the intervals
/// checked about its middle and end and the finite differences every period: at periods
/// shorter than this, a braking's simulation to rest checks no more points per second
/// of motion than at this period.
pub const BRAKE_PIECE_S: f64 = 0.001;
/// Below this |tangent component| an axis takes no part in the tangential terms.
const TINY: f64 = 1e-12;
/// Most fits of a braking's jerk into the intervals at its piece's middle and end
/// (`Section::brake_jerk`).
const FIT_ROUNDS: usize = 3;
/// Step of the curve parameter (of [0, 1]) for the derivative of the curvature vector.
const KP_DU: f64 = 1e-5;
/// Junctions of planned segments whose tangents turn by more than this (rad) are passed
/// at rest: a kink has no finite jerk at any other speed.
const KINK_RAD: f64 = 1e-6;

/// The path between two stops, tabulated along its arc length with each point's speed
/// limit.
struct Section {
    /// Length, mm: the section ends at rest.
    length_mm: f64,
    /// Spacing of the points, mm.
    ds_mm: f64,
    /// Position of each point, X Y Z mm and A B C degrees.
    p: Vec<Vec6>,
    /// Tangent: the axes' derivatives by the path parameter (a unit vector in XYZ).
    t: Vec<Vec6>,
    /// Curvature vector: the second derivatives, 1/mm.
    k: Vec<Vec6>,
    /// Its derivative by the path parameter, 1/mm².
    kp: Vec<Vec6>,
    /// Speed limit, mm/s.
    v_max: Vec<f64>,
    /// Axis acceleration and jerk limits at [`PLAN_SHARE`] (the velocities are in `v_max`).
    acc: [f64; 6],
    jerk: [f64; 6],
    /// Axis velocity, acceleration and jerk limits, whole: what the finite differences of
    /// the positions at the period are checked against.
    whole: [[f64; 6]; 3],
    /// The axes that move in the section (a tangent, curvature or position that is not
    /// the same at every point), ascending: the others are left out of the intervals,
    /// where they ask nothing (a machine of three axes costs about what it did before).
    moving: [usize; 6],
    n_moving: usize,
    /// Periods checked in the current run (the measure of the controller's work).
    checked: Cell<u64>,
}

/// A path from rest to rest, in sections between the stops on it (reversals, kinks, the
/// stops the planner set).
pub struct Grid {
    sections: Vec<Section>,
}

/// What the controller did on one program.
#[derive(Clone, Copy, Debug)]
pub struct Run {
    /// Periods from the start to rest times the period, s.
    pub time_s: f64,
    /// Periods stepped.
    pub cycles: u64,
    /// Periods where no jerk of the point's interval was admissible (the controller then
    /// braked as hard as the point allows): each is a defect of the prototype.
    pub fallbacks: u64,
    /// The largest velocity, acceleration and jerk over the axes as fractions of their
    /// limits, from the positions at the period.
    pub peaks: [f64; 3],
    /// Mean wall time of the controller per period, µs (the positions and their check
    /// not included).
    pub us_per_cycle: f64,
    /// Mean number of periods checked per period run (the candidates' and the brakings'
    /// simulated to rest).
    pub checks_per_cycle: f64,
    /// The most periods checked in one period run: the work of the worst cycle, counted,
    /// not timed.
    pub most_checks: u64,
    /// Points of the grid.
    pub points: usize,
    /// Stops along the path, the end included.
    pub stops: usize,
    /// The largest distance short of a stop where the motion came to rest, mm: rounding
    /// (a braking lands where its period ends, and the last periods onto the stop are
    /// an exact approach: 10⁻⁹ mm at most).
    pub gap_mm: f64,
    /// The run stood still short of a stop for a second of periods (or ran an hour), and
    /// was ended there: the controller found no admissible way on.
    pub stuck: bool,
    /// Periods from a hold ([`Grid::run_held`]) to rest; 0 without a hold or where it
    /// came at rest.
    pub hold_periods: u64,
    /// Periods checked over those: one each, the braking's own period.
    pub hold_checks: u64,
}

/// A curve of the path by a parameter in [0, 1]: point and first two derivatives.
struct Parametric {
    /// `(p, dp/du, d²p/du²)` at `u`.
    eval: Box<dyn Fn(f64) -> (Vec3, Vec3, Vec3)>,
    /// Programmed feed, mm/s.
    feed_mm_s: f64,
    /// The motion comes to rest where this curve starts.
    stop_before: bool,
}

/// The state of the motion: arc length, mm; speed, mm/s; acceleration, mm/s².
type State = (f64, f64, f64);

/// How the controller chooses each piece's jerk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Search {
    /// The largest admissible jerk of the point's interval: a scan down it in
    /// [`SCAN_STEPS`] steps, then [`BISECTION_STEPS`] bisections, every candidate's
    /// brakings simulated to rest (about 18 candidates a piece).
    Largest,
    /// A few candidates (around the piece before's jerk, the top of the interval, the
    /// jerks that level the acceleration off and that arrive at the speed limit), tried
    /// from the largest, the first admissible taken; where none is, the braking that
    /// certified the state before, continued (its tail is already checked, so it costs
    /// no simulation). The full search only at rest.
    Candidates,
}

/// Why a period is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Refusal {
    /// It ends past the stop, or over a point's speed limit.
    TooFast,
    /// Any other check.
    Other,
}

/// A period the controller took: its jerk, the state and positions it ends in, and the
/// braking that stops that state within the section.
#[derive(Clone, Copy, Debug)]
struct Next {
    j: f64,
    x: State,
    h: Hist,
    braking: Braking,
    /// Periods of the piece the jerk was chosen for, this one included: the jerk holds
    /// for all of them (see [`Search`]); `braking` certifies the state `x` after this
    /// one. 1 for a braking's period.
    periods: usize,
    /// The period continues the certified braking (the controller's fallback).
    follows: bool,
    /// The rung of the braking that certifies the state after each period of the piece
    /// (the last one's is `braking`'s), [`NO_CERT`] where none lands: a hold within the
    /// piece brakes from the state it is in, at once, where that state has one.
    certs: [u8; MAX_PIECE_PERIODS],
    /// `braking` certifies `x` (false within a piece at a state none certifies: a hold
    /// there plays the piece on to a state that has one, at the latest its end).
    certified: bool,
}

/// In [`Next::certs`]: no braking from that state lands.
const NO_CERT: u8 = u8::MAX;

/// The last periods onto a stop, exactly ([`Section::finish`], [`Section::final_approach`]).
#[derive(Clone, Copy, Debug)]
enum Approach {
    /// Three periods at these jerks, from a motion still landing.
    Finish([f64; 3]),
    /// From rest: four phases of `n` periods at the jerks `+j, −j, −j, +j`.
    FromRest(f64, usize),
}

impl Approach {
    /// Its periods.
    fn periods(self) -> usize {
        match self {
            Approach::Finish(_) => 3,
            Approach::FromRest(_, n) => 4 * n,
        }
    }

    /// The jerk of period `k`.
    fn jerk(self, k: usize) -> f64 {
        match self {
            Approach::Finish(j) => j[k],
            Approach::FromRest(j, n) => {
                if k < n || k >= 3 * n {
                    j
                } else {
                    -j
                }
            }
        }
    }
}

/// A braking under way: its rung of [`BRAKE_DECELS_MM_S2`], the
/// periods of its current piece done (0: a new piece starts) and that piece's jerk. A
/// braking holds each jerk for a piece of [`BRAKE_PIECE_S`]; its state a period on is
/// what its simulation to rest met there, so continuing it repeats that simulation
/// period by period.
#[derive(Clone, Copy, Debug)]
struct Braking {
    rung: usize,
    phase: usize,
    j: f64,
}

/// Where a period's acceleration and jerk are checked against the point's intervals
/// (its finite differences always are).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Intervals {
    /// At its middle and its end: every period the controller chooses, and a braking's
    /// at a period of [`BRAKE_PIECE_S`] or more.
    MidAndEnd,
    /// At its end only.
    End,
    /// Not at all.
    Neither,
}

impl Intervals {
    /// The checks of period `phase` (from 0) of a braking piece of `m` periods: with one
    /// period a piece, at its middle and end; else at the end of every `m / 2`-th period
    /// and of the last, about the middle and the end of the piece.
    fn of_piece(phase: usize, m: usize) -> Intervals {
        let stride = (m / 2).max(1);
        if m == 1 {
            Intervals::MidAndEnd
        } else if (phase + 1).is_multiple_of(stride) || phase + 1 == m {
            Intervals::End
        } else {
            Intervals::Neither
        }
    }
}

/// Periods of a braking's piece at the period `dt`: [`BRAKE_PIECE_S`] in whole periods,
/// at least one and at most [`MAX_PIECE_PERIODS`].
fn piece_periods(dt: f64) -> usize {
    ((BRAKE_PIECE_S / dt).round() as usize).clamp(1, MAX_PIECE_PERIODS)
}

/// Most periods of a piece: [`BRAKE_PIECE_S`] at the shortest period the configuration
/// accepts (50 µs).
const MAX_PIECE_PERIODS: usize = 20;

/// The positions of the last three periods, oldest first, mm: what the next position's
/// finite differences are taken with.
type Hist = [Vec6; 3];

/// A vector over the six axes, X Y Z A B C.
type Vec6 = Vector6<f64>;

/// XYZ `v` with A, B and C at zero.
fn lift(v: Vec3) -> Vec6 {
    Vec6::new(v.x, v.y, v.z, 0.0, 0.0, 0.0)
}

/// Velocity, acceleration and jerk limits of the six axes (infinite for an axis the
/// machine does not have).
#[derive(Clone, Copy, Debug)]
struct Axes {
    velocity: [f64; 6],
    acceleration: [f64; 6],
    jerk: [f64; 6],
}

impl Axes {
    /// X, Y and Z of the bound's `machine`.
    fn of_machine(machine: &JerkMachine) -> Axes {
        let six = |xyz: [f64; 3]| {
            [
                xyz[0],
                xyz[1],
                xyz[2],
                f64::INFINITY,
                f64::INFINITY,
                f64::INFINITY,
            ]
        };
        Axes {
            velocity: six(machine.base.velocity_mm_s),
            acceleration: six(machine.base.acceleration_mm_s2),
            jerk: six(machine.jerk_mm_s3),
        }
    }

    /// Every axis of `limits`.
    fn of_limits(limits: &MachineLimits) -> Axes {
        let each = |f: fn(&kerf_geom::AxisLimits) -> f64| {
            limits.axes.map(|a| a.as_ref().map_or(f64::INFINITY, f))
        };
        Axes {
            velocity: each(|a| a.velocity_units_s),
            acceleration: each(|a| a.acceleration_units_s2),
            jerk: each(|a| a.jerk_units_s3),
        }
    }
}

/// A point's intervals of the path acceleration and of the path jerk
/// ([`Section::ranges`]).
type Ranges = ((f64, f64), (f64, f64));

/// The interval of `x` with `|c x + m| ≤ w` for every `(c, m, w)` of `term` over `axes`,
/// intersected; an axis with `c = 0` needs `|m| ≤ w` (else the interval is empty).
fn interval(axes: &[usize], term: impl Fn(usize) -> (f64, f64, f64)) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for &axis in axes {
        let (c, m, w) = term(axis);
        if c.abs() > TINY {
            let a = (-w - m) / c;
            let b = (w - m) / c;
            lo = lo.max(a.min(b));
            hi = hi.min(a.max(b));
        } else if m.abs() > w {
            return (1.0, -1.0);
        }
    }
    (lo, hi)
}

/// A floor of the distance a braking towards the deceleration `decel` with the descent
/// jerk `j_d` takes from speed `v` and acceleration `a`, where its jerk is not fitted
/// into a point's interval: its acceleration then never falls faster than `j_d` nor
/// below `-decel` (or `a`, where that is lower), so the ramp at `j_d` down to `-decel`
/// and then `-decel` to rest stop no later.
fn braking_distance_floor(v: f64, a: f64, decel: f64, j_d: f64) -> f64 {
    if a <= -decel {
        return v * v / (-2.0 * a);
    }
    let t1 = (a + decel) / j_d;
    let v1 = v + a * t1 - j_d * t1 * t1 / 2.0;
    if v1 <= 0.0 {
        return v * v / (2.0 * decel.max(-a));
    }
    let s1 = v * t1 + a * t1 * t1 / 2.0 - j_d * t1 * t1 * t1 / 6.0;
    s1 + v1 * v1 / (2.0 * decel)
}

/// The state after `dt` of jerk `j` from `(s, v, a)`.
fn step((s, v, a): State, j: f64, dt: f64) -> State {
    (
        s + v * dt + a * dt * dt / 2.0 + j * dt * dt * dt / 6.0,
        v + a * dt + j * dt * dt / 2.0,
        a + j * dt,
    )
}

impl Grid {
    /// The exact path of `pieces` after [`g2_blended`], tabulated every `ds_mm` at most
    /// for `machine`; reversals are stops.
    pub fn from_pieces(pieces: &[Piece], machine: &JerkMachine, ds_mm: f64) -> Grid {
        let path = g2_blended(pieces, machine.base.tolerance_mm);
        let curves: Vec<Parametric> = path
            .iter()
            .map(|piece| {
                let shape = piece.shape;
                Parametric {
                    eval: Box::new(move |u| {
                        let e = shape.eval(u);
                        (e.p, e.d1, e.d2)
                    }),
                    feed_mm_s: piece.feed_mm_s,
                    stop_before: false,
                }
            })
            .collect();
        Grid::from_curves(curves, machine, ds_mm)
    }

    /// The planner's path, `segments` (all six axes, by the segments' own path parameter:
    /// the XYZ arc length, degrees on a move of the rotary axes alone), tabulated every
    /// `ds_mm` at most for the axes of `limits`. A junction where the planner set a stop
    /// (`end_cap_mm_s` 0) is a stop, and so is one where the direction (of all six axes)
    /// reverses or turns by more than a micro-radian.
    pub fn from_segments(segments: &[PlannedSegment], limits: &MachineLimits, ds_mm: f64) -> Grid {
        let axes = Axes::of_limits(limits);
        let six = |v: [f64; 6]| Vec6::from_column_slice(&v);
        // The segments of non-zero length, and the stops between them.
        let mut live: Vec<&PlannedSegment> = Vec::with_capacity(segments.len());
        let mut stops = Vec::new();
        let mut total = 0.0;
        let mut stop_pending = false;
        for (n, seg) in segments.iter().enumerate() {
            stop_pending |= n > 0 && segments[n - 1].end_cap_mm_s <= 0.0;
            if seg.length_mm <= 0.0 {
                continue;
            }
            if let Some(before) = live.last() {
                let t_end = six(before.derivatives_at(before.length_mm).0);
                let t_start = six(seg.derivatives_at(0.0).0);
                let turn = t_end
                    .normalize()
                    .dot(&t_start.normalize())
                    .clamp(-1.0, 1.0)
                    .acos();
                if stop_pending || turn > KINK_RAD {
                    stops.push(total);
                }
            }
            stop_pending = false;
            total += seg.length_mm;
            live.push(seg);
        }
        stops.push(total);
        let (mut piece, mut start) = (0usize, 0.0);
        // The geometry at `s` from the path's start; at a junction, of the segment before
        // it unless `after`.
        let sample = |s: f64, after: bool| {
            while piece + 1 < live.len()
                && (s > start + live[piece].length_mm
                    || (after && s >= start + live[piece].length_mm))
            {
                start += live[piece].length_mm;
                piece += 1;
            }
            let seg = live[piece];
            let len = seg.length_mm;
            let local = (s - start).clamp(0.0, len);
            let (t, k) = seg.derivatives_at(local);
            let mut p = [0.0; 6];
            seg.position_at(local, &mut p);
            // κ' by differences within the segment (one-sided at its ends): a junction
            // is continuous in κ, not in κ'.
            let (s0, s1) = (
                (local - KP_DU * len).max(0.0),
                (local + KP_DU * len).min(len),
            );
            let kp = (six(seg.derivatives_at(s1).1) - six(seg.derivatives_at(s0).1)) / (s1 - s0);
            (six(p), six(t), six(k), kp, seg.feed_mm_s)
        };
        Grid::of_stops(&stops, ds_mm, &axes, sample)
    }

    /// Tabulates a chain of curves by arc length (each finely in its parameter, with the
    /// chord lengths from its start, the points between by the parameter interpolated in
    /// them). A junction is a stop where the curve asks for one, where the direction
    /// reverses, or where the tangent turns by more than [`KINK_RAD`].
    fn from_curves(curves: Vec<Parametric>, machine: &JerkMachine, ds_mm: f64) -> Grid {
        let axes = Axes::of_machine(machine);
        // The curves of non-zero length, each with its chord lengths and length.
        let mut live: Vec<(&Parametric, Vec<f64>, f64)> = Vec::with_capacity(curves.len());
        let mut total = 0.0;
        let mut stops = Vec::new();
        let mut stop_pending = false;
        for c in &curves {
            let (p0, d0, _) = (c.eval)(0.0);
            let (p1, _, _) = (c.eval)(1.0);
            // Sized by the chord and the tangent's length, whichever is longer.
            let rough = (p1 - p0).norm().max(d0.norm());
            let m = (((rough / ds_mm).ceil() as usize) * 8).max(64);
            let mut cum = Vec::with_capacity(m + 1);
            let mut prev = p0;
            let mut acc = 0.0;
            for j in 0..=m {
                let q = (c.eval)(j as f64 / m as f64).0;
                acc += (q - prev).norm();
                prev = q;
                cum.push(acc);
            }
            stop_pending |= c.stop_before;
            if acc <= 0.0 {
                continue;
            }
            if let Some((before, _, _)) = live.last() {
                let t_end = (before.eval)(1.0).1;
                let turn = t_end
                    .normalize()
                    .dot(&d0.normalize())
                    .clamp(-1.0, 1.0)
                    .acos();
                if stop_pending || turn > KINK_RAD {
                    stops.push(total);
                }
            }
            stop_pending = false;
            total += acc;
            live.push((c, cum, acc));
        }
        let (mut piece, mut start, mut j) = (0usize, 0.0, 0usize);
        // The geometry at arc length `s`; at a junction, of the curve before it unless
        // `after`.
        let sample = |s: f64, after: bool| {
            while piece + 1 < live.len()
                && (s > start + live[piece].2 || (after && s >= start + live[piece].2))
            {
                start += live[piece].2;
                piece += 1;
                j = 0;
            }
            let (curve, cum, len) = &live[piece];
            let local = (s - start).clamp(0.0, *len);
            while j + 1 < cum.len() - 1 && cum[j + 1] < local {
                j += 1;
            }
            let span = cum[j + 1] - cum[j];
            let frac = if span > 0.0 {
                ((local - cum[j]) / span).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let u = (j as f64 + frac) / (cum.len() - 1) as f64;
            let frame = |u: f64| {
                let (p, d1, d2) = (curve.eval)(u);
                (p, unit_frame(d1, d2))
            };
            let (p, (t, k, speed)) = frame(u);
            // κ' by differences within the curve (one-sided at its ends): a junction
            // of two curves is continuous in κ, not in κ'.
            let (u0, u1) = ((u - KP_DU).max(0.0), (u + KP_DU).min(1.0));
            let kp = (frame(u1).1.1 - frame(u0).1.1) / ((u1 - u0) * speed);
            (lift(p), lift(t), lift(k), lift(kp), curve.feed_mm_s)
        };
        stops.push(total);
        Grid::of_stops(&stops, ds_mm, &axes, sample)
    }

    /// The sections between `stops` (arc lengths from the path's start, the end the
    /// last), each tabulated every `ds_mm` at most for `axes` from `sample(s, first)`:
    /// the point at `s` from the path's start, of the curve after it where `first`.
    fn of_stops(
        stops: &[f64],
        ds_mm: f64,
        axes: &Axes,
        mut sample: impl FnMut(f64, bool) -> (Vec6, Vec6, Vec6, Vec6, f64),
    ) -> Grid {
        let mut sections = Vec::with_capacity(stops.len());
        let mut from = 0.0;
        for &to in stops {
            if to > from {
                sections.push(Section::tabulate(to - from, ds_mm, axes, |s, first| {
                    sample(from + s, first)
                }));
            }
            from = to;
        }
        Grid { sections }
    }

    /// Stops on the path, the end included.
    pub fn stops(&self) -> usize {
        self.sections.len()
    }

    /// Points of the tabulation.
    pub fn points(&self) -> usize {
        self.sections.iter().map(|s| s.p.len()).sum()
    }
}

impl Section {
    /// Tabulates a section of length `total` mm every `ds_mm` at most: `sample(s, first)`
    /// gives the point, unit tangent, curvature vector, its derivative and the feed at
    /// arc length `s` from the section's start (called in ascending order; `first` at
    /// the start).
    fn tabulate(
        total: f64,
        ds_mm: f64,
        axes: &Axes,
        mut sample: impl FnMut(f64, bool) -> (Vec6, Vec6, Vec6, Vec6, f64),
    ) -> Section {
        let n = ((total / ds_mm).ceil() as usize).max(2);
        let ds = total / n as f64;
        let mut grid = Section {
            length_mm: total,
            ds_mm: ds,
            p: Vec::with_capacity(n + 1),
            t: Vec::with_capacity(n + 1),
            k: Vec::with_capacity(n + 1),
            kp: Vec::with_capacity(n + 1),
            v_max: Vec::with_capacity(n + 1),
            acc: axes.acceleration.map(|a| a * PLAN_SHARE),
            jerk: axes.jerk.map(|j| j * PLAN_SHARE),
            whole: [axes.velocity, axes.acceleration, axes.jerk],
            moving: [0; 6],
            n_moving: 0,
            checked: Cell::new(0),
        };
        let mut feed = Vec::with_capacity(n + 1);
        for i in 0..=n {
            let (p, t, k, kp, f) = sample((i as f64 * ds).min(total), i == 0);
            grid.p.push(p);
            grid.t.push(t);
            grid.k.push(k);
            grid.kp.push(kp);
            feed.push(f);
        }
        for axis in 0..6 {
            let p0 = grid.p[0][axis];
            let moves = (0..grid.p.len()).any(|i| {
                grid.p[i][axis] != p0
                    || grid.t[i][axis] != 0.0
                    || grid.k[i][axis] != 0.0
                    || grid.kp[i][axis] != 0.0
            });
            if moves {
                grid.moving[grid.n_moving] = axis;
                grid.n_moving += 1;
            }
        }
        let centripetal = axes
            .acceleration
            .map(|a| a * CENTRIPETAL_SHARE * PLAN_SHARE);
        let jerk = axes.jerk.map(|j| j * JERK_SHARE * PLAN_SHARE);
        for (i, &feed_mm_s) in feed.iter().enumerate() {
            // The same pairwise condition as the centripetal one, on `κ' v³` and the jerk
            // (the jerk interval at a = 0 not empty: the path jerk may make up for the
            // tangential part of `κ' v³`).
            let (t, k, kp) = (&grid.t[i], &grid.k[i], &grid.kp[i]);
            let (t, k, kp) = (t.as_slice(), k.as_slice(), kp.as_slice());
            let x = max_speed_squared_axes(t, k, feed_mm_s, &axes.velocity, &centripetal);
            let v3 = max_speed_squared_axes(t, kp, f64::INFINITY, &[f64::INFINITY; 6], &jerk);
            grid.v_max.push(x.sqrt().min(v3.cbrt()));
        }
        // The approach cap: backwards from each point, the speed from which
        // BACKWARD_SHARE of the tangential deceleration the axes allow brings the motion
        // down to that point's limit.
        for i in (0..grid.v_max.len() - 1).rev() {
            let t = grid.t[i];
            let mut decel = f64::INFINITY;
            for x in 0..6 {
                if t[x].abs() > TINY {
                    decel = decel.min(grid.acc[x] / t[x].abs());
                }
            }
            let next = grid.v_max[i + 1];
            let reach = (next * next + 2.0 * BACKWARD_SHARE * decel * grid.ds_mm).sqrt();
            if reach < grid.v_max[i] {
                grid.v_max[i] = reach;
            }
        }
        grid
    }

    /// The grid interval holding `s` and the fraction of it.
    fn locate(&self, s: f64) -> (usize, f64) {
        let n = self.p.len() - 1;
        let x = (s / self.ds_mm).clamp(0.0, n as f64);
        // `x` is not negative: the conversion truncates as `floor` would.
        let i = (x as usize).min(n - 1);
        (i, x - i as f64)
    }

    /// Tangent, curvature vector and its derivative at `s`, interpolated linearly.
    fn geometry(&self, s: f64) -> (Vec6, Vec6, Vec6) {
        let (i, u) = self.locate(s);
        let mix = |v: &[Vec6]| v[i] * (1.0 - u) + v[i + 1] * u;
        (mix(&self.t), mix(&self.k), mix(&self.kp))
    }

    /// The lowest speed limit of the grid points around the stretch from `s0` to `s1`.
    fn v_max_over(&self, s0: f64, s1: f64) -> f64 {
        let (i0, _) = self.locate(s0);
        let (i1, _) = self.locate(s1);
        // (Not `f64::min`: the limits are never NaN, and its NaN handling costs a tenth
        // of a braking's simulation.)
        let mut low = f64::INFINITY;
        for &v in &self.v_max[i0..=i1 + 1] {
            if v < low {
                low = v;
            }
        }
        low
    }

    /// The path accelerations the point at `s` allows at speed `v`, mm/s², and the path
    /// jerks it allows at speed `v` and acceleration `a`, mm/s³ (empty: `lo > hi`).
    fn ranges(&self, s: f64, v: f64, a: f64) -> ((f64, f64), (f64, f64)) {
        let (t, k, kp) = self.geometry(s);
        let (v2, va, v3) = (v * v, 3.0 * v * a, v * v * v);
        let axes = &self.moving[..self.n_moving];
        (
            interval(axes, |x| (t[x], k[x] * v2, self.acc[x])),
            interval(axes, |x| (t[x], k[x] * va + kp[x] * v3, self.jerk[x])),
        )
    }

    /// The path jerks the point at `s` allows at speed `v` and acceleration `a`, mm/s³.
    fn jerk_range(&self, s: f64, v: f64, a: f64) -> (f64, f64) {
        self.ranges(s, v, a).1
    }

    /// Position at arc length `s`: the cubic Hermite interpolation of the neighbouring
    /// points and their tangents.
    fn position(&self, s: f64) -> Vec6 {
        let (i, u) = self.locate(s);
        let (h00, h10) = (
            (1.0 + 2.0 * u) * (1.0 - u) * (1.0 - u),
            u * (1.0 - u) * (1.0 - u),
        );
        let (h01, h11) = (u * u * (3.0 - 2.0 * u), u * u * (u - 1.0));
        self.p[i] * h00
            + self.t[i] * (h10 * self.ds_mm)
            + self.p[i + 1] * h01
            + self.t[i + 1] * (h11 * self.ds_mm)
    }

    /// The state after a period `dt` of jerk `j` from `x`, and the positions with the new
    /// one, if the period is admissible (see the module's documentation) and ends by
    /// `stop`, with the intervals checked where `intervals` says; else why it is refused.
    /// A period that lands on rest ends there, at rest. `known`: the intervals at the
    /// period's middle and end where the caller has them already (a braking's fit); used
    /// where the period runs whole.
    #[allow(clippy::too_many_arguments)]
    fn period_or_why(
        &self,
        x: State,
        h: &Hist,
        j: f64,
        dt: f64,
        stop: f64,
        intervals: Intervals,
        known: Option<[Ranges; 2]>,
    ) -> Result<(State, Hist), Refusal> {
        self.checked.set(self.checked.get() + 1);
        let (_, v, a) = x;
        let mut span = dt;
        let mut landed = false;
        if a < 0.0 && a + j * dt > 0.0 {
            // The lowest speed of the period, where the acceleration turns positive.
            let v_min = v - a * a / (2.0 * j);
            if v_min < -1e-9 {
                return Err(Refusal::Other);
            }
            if v_min <= LANDED_MM_S {
                span = -a / j;
                landed = true;
            }
        }
        let (s1, v1, a1) = step(x, j, span);
        if s1 > stop + 1e-9 || v1 > self.v_max_over(x.0, s1) {
            return Err(Refusal::TooFast);
        }
        if v1 < -1e-9 {
            return Err(Refusal::Other);
        }
        let points = match intervals {
            Intervals::MidAndEnd => &[step(x, j, span / 2.0), (s1, v1, a1)][..],
            Intervals::End => &[(s1, v1, a1)][..],
            Intervals::Neither => &[][..],
        };
        let known = known.filter(|_| !landed && intervals == Intervals::MidAndEnd);
        for (n, &(s_x, v_x, a_x)) in points.iter().enumerate() {
            let v_x = v_x.max(0.0);
            let ((lo, hi), (j_lo, j_hi)) = match known {
                Some(known) => known[n],
                None => self.ranges(s_x, v_x, a_x),
            };
            let (da, dj) = (END_SLACK * (hi - lo).abs(), END_SLACK * (j_hi - j_lo).abs());
            if !(lo - da <= a_x && a_x <= hi + da && j_lo - dj <= j && j <= j_hi + dj) {
                return Err(Refusal::Other);
            }
        }
        // The position the drive gets, and its finite differences at the period as the
        // output monitor takes them, within the whole limits.
        let p = self.position(s1);
        if !self.differences_within(h, p, dt) {
            return Err(Refusal::Other);
        }
        let state = if landed {
            (s1, 0.0, 0.0)
        } else {
            (s1, v1.max(0.0), a1)
        };
        Ok((state, [h[1], h[2], p]))
    }

    /// Whether the position `p` after the positions `h` keeps the finite differences at
    /// the period `dt` (as the output monitor takes them) within the whole limits, on
    /// every axis: one that stands still in the section may still be coming to rest from
    /// the section before in the positions `h`.
    fn differences_within(&self, h: &Hist, p: Vec6, dt: f64) -> bool {
        let (inv, inv2, inv3) = (1.0 / dt, 1.0 / (dt * dt), 1.0 / (dt * dt * dt));
        let vel = (p - h[2]) * inv;
        let acc = (p - h[2] * 2.0 + h[1]) * inv2;
        let jerk = (p - h[2] * 3.0 + h[1] * 3.0 - h[0]) * inv3;
        (0..6).all(|i| {
            vel[i].abs() <= self.whole[0][i]
                && acc[i].abs() <= self.whole[1][i]
                && jerk[i].abs() <= self.whole[2][i]
        })
    }

    /// Whether standing still after the positions `h` keeps the finite differences within
    /// the whole limits (the three periods until they all see rest).
    fn rest_within(&self, h: &Hist, dt: f64) -> bool {
        let mut h = *h;
        for _ in 0..3 {
            if !self.differences_within(&h, h[2], dt) {
                return false;
            }
            h = [h[1], h[2], h[2]];
        }
        true
    }

    /// The jerk of a braking at `x` over a period `dt`: towards the acceleration
    /// `-decel_mm_s2` at a jerk of at most [`BRAKE_JERK_PER_S`] times `decel_mm_s2`, and
    /// back to zero acceleration as the speed runs out (the jerk `a²/2v` brings both to
    /// zero together) once braking on for another period would leave that return above
    /// that jerk; fitted into the jerk intervals of the start point and (re-evaluated
    /// up to [`FIT_ROUNDS`] times) of the middle and the end of `dt` where it falls
    /// outside them. Only that fitting depends on the machine's limits: a braking that
    /// needs none is the same motion on every machine. `decel_mm_s2` = `∞` is the hardest braking instead: towards the point's
    /// most negative acceleration, at any jerk its interval allows (limits and all).
    /// `None` where the point allows no jerk.
    fn brake_jerk(&self, x: State, dt: f64, decel_mm_s2: f64) -> Option<f64> {
        self.brake_jerk_ranges(x, dt, decel_mm_s2).map(|(j, _)| j)
    }

    /// [`Section::brake_jerk`], with the intervals at the middle and the end of `dt` at
    /// that jerk where the fit has them.
    fn brake_jerk_ranges(
        &self,
        x: State,
        dt: f64,
        decel_mm_s2: f64,
    ) -> Option<(f64, Option<[Ranges; 2]>)> {
        let (s, v, a) = x;
        let ((a_lo, _), (j_lo, j_hi)) = self.ranges(s, v, a);
        if j_lo > j_hi {
            return None;
        }
        // The hardest: the point's most negative acceleration, at any jerk it allows.
        let (decel_mm_s2, j_d) = if decel_mm_s2.is_infinite() {
            (-a_lo.min(0.0), f64::INFINITY)
        } else {
            (decel_mm_s2, decel_mm_s2 * BRAKE_JERK_PER_S)
        };
        let choose = |lo: f64, hi: f64| {
            let top = j_d.min(hi).max(lo);
            let hard = ((-decel_mm_s2 - a) / dt).clamp(-j_d, j_d).clamp(lo, hi);
            let mut j = hard;
            if a < 0.0 && v > 0.0 {
                let (_, v1, a1) = step(x, hard, dt);
                let land_now = a * a / (2.0 * v);
                let must = v1 <= 0.0 || (a1 < 0.0 && a1 * a1 / (2.0 * v1) > top);
                if (must && land_now >= LAND_FLOOR * top) || land_now >= top {
                    j = land_now.clamp(lo, hi);
                }
            }
            // A jerk after which the braking can still land (the speed left at least
            // what the return of the acceleration to zero takes); else the most negative
            // one that can, by bisection.
            let landable = |j: f64| {
                if a < 0.0 && a + j * dt >= 0.0 {
                    return v - a * a / (2.0 * j) >= -1e-9;
                }
                let (_, v1, a1) = step(x, j, dt);
                v1 >= -1e-9 && (a1 >= 0.0 || v1 >= a1 * a1 / (2.0 * top))
            };
            if landable(j) || !landable(top) {
                return j;
            }
            bisect(top, j, BISECTION_STEPS, landable)
        };
        // Fitted into the intervals at the piece's middle and end too, where the period
        // checks them. Those move with the jerk (the state they are taken at does), so
        // the fit is repeated from the jerk it gave, up to FIT_ROUNDS times: fitted once,
        // a braking turning down hard on a curve whose interval closes in (raster C's
        // rows, 2,400 mm/s³ a period) missed the end's bound by a few mm/s³ and was
        // refused, with every gentler rung, which were on the same bound.
        let mut j = choose(j_lo, j_hi);
        for _ in 0..FIT_ROUNDS {
            let (s_m, v_m, a_m) = step(x, j, dt / 2.0);
            let mid = self.ranges(s_m, v_m.max(0.0), a_m);
            let (s1, v1, a1) = step(x, j, dt);
            let end = self.ranges(s1, v1.max(0.0), a1);
            let (lo, hi) = (
                j_lo.max(mid.1.0).max(end.1.0),
                j_hi.min(mid.1.1).min(end.1.1),
            );
            if lo > hi || (lo <= j && j <= hi) {
                return Some((j, Some([mid, end])));
            }
            j = choose(lo, hi);
        }
        Some((j, None))
    }

    /// The periods that take the motion from rest at `x` to rest on `stop` exactly (the
    /// braking lands where the period ends, a little short of the stop): four phases of
    /// `n` periods at the path jerks `+j, −j, −j, +j` with `j = gap / 2 (n dt)³`, which
    /// come to rest after `2 j (n dt)³`, for the fewest `n` whose every period is
    /// admissible (the jerk within the intervals, the finite differences within the
    /// limits) and after which standing still is too: `(j, n)`, for `n` of 1, 2, 4, …
    /// up to [`FINAL_APPROACH_PERIODS`] (`None` where none is). Playing it
    /// ([`Section::approach_period`]) repeats these periods exactly.
    fn final_approach(&self, x: State, h: &Hist, dt: f64, stop: f64) -> Option<Approach> {
        let gap = stop - x.0;
        let (j_lo, j_hi) = self.jerk_range(x.0, 0.0, 0.0);
        let mut n = 1;
        while n <= FINAL_APPROACH_PERIODS {
            let t = n as f64 * dt;
            let j = gap / (2.0 * t * t * t);
            if j > j_hi || -j < j_lo {
                n *= 2;
                continue;
            }
            let approach = Approach::FromRest(j, n);
            if self.approach_holds(x, h, dt, stop, approach) {
                return Some(approach);
            }
            n *= 2;
        }
        None
    }

    /// Whether every period of `approach` from `x` is admissible, it ends at rest on
    /// `stop`, and standing still after it is admissible too.
    fn approach_holds(&self, x: State, h: &Hist, dt: f64, stop: f64, approach: Approach) -> bool {
        let (mut y, mut hy) = (x, *h);
        for k in 0..approach.periods() {
            match self.approach_period(y, &hy, dt, stop, approach, k) {
                Some((y1, h1)) => (y, hy) = (y1, h1),
                None => return false,
            }
        }
        self.rest_within(&hy, dt)
    }

    /// The three periods that bring the motion at `x` (landing, or at rest short of the
    /// stop) to rest on `stop` exactly: the jerks of the linear system of the end's
    /// acceleration, speed and position (from rest `g/dt³ · (1, −2, 1)`), where every
    /// period, and standing still after them, is admissible. Tried where the motion is
    /// slow enough for three periods of the point's jerk to stop it (the speed at most
    /// twice that jerk times the period squared) and within [`FINAL_APPROACH_MM`] of the
    /// stop.
    fn finish(&self, x: State, h: &Hist, dt: f64, stop: f64) -> Option<Approach> {
        let (s0, v0, a0) = x;
        let (j_lo, j_hi) = self.jerk_range(s0, v0, a0);
        if v0 < 0.0 || stop - s0 > FINAL_APPROACH_MM || v0 > 2.0 * j_hi.max(-j_lo) * dt * dt {
            return None;
        }
        // a₃ = a₀ + dt Σ jᵢ = 0; v₃ = v₀ + 3 a₀ dt + dt² (5/2 j₁ + 3/2 j₂ + 1/2 j₃) = 0;
        // s₃ = s₀ + 3 v₀ dt + 9/2 a₀ dt² + dt³ (19/6 j₁ + 7/6 j₂ + 1/6 j₃) = stop.
        let r1 = -a0 / dt;
        let r2 = -(v0 + 3.0 * a0 * dt) / (dt * dt);
        let r3 = (stop - s0 - 3.0 * v0 * dt - 4.5 * a0 * dt * dt) / (dt * dt * dt);
        let approach = Approach::Finish([
            r1 / 3.0 - r2 + r3,
            -7.0 / 6.0 * r1 + 3.0 * r2 - 2.0 * r3,
            11.0 / 6.0 * r1 - 2.0 * r2 + r3,
        ]);
        self.approach_holds(x, h, dt, stop, approach)
            .then_some(approach)
    }

    /// Period `k` of `approach` from `x`: the state and positions after it, if
    /// admissible; the last one ends at rest on `stop` (within [`STOP_GAP_MM`], and the
    /// rounding of its speed and acceleration, some 1e-15, set to rest).
    fn approach_period(
        &self,
        x: State,
        h: &Hist,
        dt: f64,
        stop: f64,
        approach: Approach,
        k: usize,
    ) -> Option<(State, Hist)> {
        let (y, hy) = self
            .period_or_why(x, h, approach.jerk(k), dt, stop, Intervals::MidAndEnd, None)
            .ok()?;
        if k + 1 < approach.periods() {
            return Some((y, hy));
        }
        let at_rest = y.1.abs() <= 1e-9 && y.2.abs() <= 1e-6;
        ((stop - y.0).abs() <= STOP_GAP_MM && at_rest).then_some(((stop, 0.0, 0.0), hy))
    }

    /// The first of the brakings of [`BRAKE_DECELS_MM_S2`] from `x` that comes to rest by
    /// `stop` (its rung), tried from the hardest. The rungs of the ladder harder than the
    /// point allows at `x` are left out: half the work, the times within 0.4 %, and the
    /// monotonic sweep about the same (4 of 1,440 runs slower, by up to 5.6 %, against 3,
    /// by up to 6.0 %). Every other rung is tried: starting three rungs harder than the
    /// one that certified the state before did a fifth less work, but left the motion on
    /// a gentle braking that certified none of its candidates (a run 5 % slower with a
    /// raised jerk). With `quick`, a braking refused for being too fast (past `stop`, or
    /// over a point's speed limit) ends the search, as a gentler one is mostly faster
    /// still. That is a guess, not a rule (the search for the largest jerk, without a
    /// continuation of its own to fall back on, met states that only a gentler braking
    /// certified), and it only ever refuses: it cannot let a state through that has no
    /// braking. It spares the gentler brakings' simulations where the stop or a slow
    /// stretch is near.
    fn can_stop(&self, x: State, h: &Hist, dt: f64, stop: f64, quick: bool) -> Option<usize> {
        // Rungs harder than the point allows at `x` are left out (the hardest braking
        // stands for them): a raised limit only adds rungs.
        let hardest = -self.ranges(x.0, x.1, x.2).0.0;
        for (rung, &decel) in BRAKE_DECELS_MM_S2.iter().enumerate() {
            if rung > 0 && decel > hardest {
                continue;
            }
            match self.brakes(x, h, dt, stop, rung) {
                Ok(()) => return Some(rung),
                Err(Refusal::TooFast) if quick => return None,
                Err(_) => {}
            }
        }
        None
    }

    /// Whether the braking of `rung` from `x` comes to rest by `stop`, every period on the
    /// way admissible; if not, why its first refused period was.
    fn brakes(
        &self,
        mut x: State,
        h: &Hist,
        dt: f64,
        stop: f64,
        rung: usize,
    ) -> Result<(), Refusal> {
        // Unfitted, it would stop no shorter than the floor: too fast for `stop` without
        // a simulation. (A jerk fitted into an interval can brake harder, so this may
        // refuse a braking that lands; it only ever refuses.)
        let decel = BRAKE_DECELS_MM_S2[rung];
        if decel.is_finite()
            && braking_distance_floor(x.1, x.2, decel, decel * BRAKE_JERK_PER_S) > stop - x.0 + 1e-9
        {
            return Err(Refusal::TooFast);
        }
        let mut h = *h;
        let mut braking = Braking {
            rung,
            phase: 0,
            j: 0.0,
        };
        for _ in 0..100_000 {
            if x.1 <= 1e-9 && x.2.abs() <= 1e-9 {
                return if x.0 <= stop + 1e-9 && self.rest_within(&h, dt) {
                    Ok(())
                } else {
                    Err(Refusal::Other)
                };
            }
            (x, h, braking) = self.brake_period(x, &h, dt, stop, braking)?;
        }
        Err(Refusal::Other)
    }

    /// One period of `braking` from `x`: a new piece's jerk at its first period, the
    /// intervals checked as [`Intervals::of_piece`] says; the state, the positions and
    /// the braking a period on.
    fn brake_period(
        &self,
        x: State,
        h: &Hist,
        dt: f64,
        stop: f64,
        braking: Braking,
    ) -> Result<(State, Hist, Braking), Refusal> {
        let m = piece_periods(dt);
        let (j, known) = if braking.phase == 0 {
            self.brake_jerk_ranges(x, m as f64 * dt, BRAKE_DECELS_MM_S2[braking.rung])
                .ok_or(Refusal::Other)?
        } else {
            (braking.j, None)
        };
        // The fit's intervals are the period's own where the piece is one period.
        let known = known.filter(|_| m == 1);
        let (x, h) = self.period_or_why(
            x,
            h,
            j,
            dt,
            stop,
            Intervals::of_piece(braking.phase, m),
            known,
        )?;
        Ok((
            x,
            h,
            Braking {
                rung: braking.rung,
                phase: (braking.phase + 1) % m,
                j,
            },
        ))
    }

    /// `braking`, certified from the state before, continued a period from `x`: the
    /// controller's fallback and a hold's every period ([`Section::brake_period`] as a
    /// [`Next`]).
    fn continued(&self, x: State, h: &Hist, dt: f64, stop: f64, braking: Braking) -> Option<Next> {
        let (next, h1, braking) = self.brake_period(x, h, dt, stop, braking).ok()?;
        Some(Next {
            j: braking.j,
            x: next,
            h: h1,
            braking,
            periods: 1,
            follows: true,
            certs: [NO_CERT; MAX_PIECE_PERIODS],
            certified: true,
        })
    }

    /// The piece of `m` periods of jerk `j` from `x`, if each period is admissible (the
    /// intervals checked as a braking's piece's are, [`Intervals::of_piece`]) and it ends,
    /// early where it lands on rest, in a state that can stop by `stop`
    /// ([`Section::can_stop`], `quick` or not): its first period's state and positions,
    /// and the braking that stops the state it ends in.
    #[allow(clippy::too_many_arguments)]
    fn admissible(
        &self,
        x: State,
        h: &Hist,
        j: f64,
        dt: f64,
        stop: f64,
        quick: bool,
        m: usize,
    ) -> Option<Next> {
        let mut states = [(x, *h); MAX_PIECE_PERIODS];
        let (mut end, mut end_h) = (x, *h);
        let mut periods = 0;
        for phase in 0..m {
            (end, end_h) = self
                .period_or_why(
                    end,
                    &end_h,
                    j,
                    dt,
                    stop,
                    Intervals::of_piece(phase, m),
                    None,
                )
                .ok()?;
            states[periods] = (end, end_h);
            periods += 1;
            if end.1 == 0.0 && end.2 == 0.0 {
                break;
            }
        }
        let rung = self.can_stop(end, &end_h, dt, stop, quick)?;
        // The states within the piece certified too (only for a piece whose end is, and
        // not a condition of it: requiring them made a raised limit slow 14 runs of the
        // sweep, by up to 6 %), so that a hold brakes where it comes.
        let mut certs = [NO_CERT; MAX_PIECE_PERIODS];
        certs[periods - 1] = rung as u8;
        for k in 0..periods - 1 {
            let (y, hy) = states[k];
            // The end's braking first: from a state a period or two before, it mostly
            // lands too, and any landing braking will do for a hold.
            let cert = if self.brakes(y, &hy, dt, stop, rung).is_ok() {
                Some(rung)
            } else {
                self.can_stop(y, &hy, dt, stop, quick)
            };
            certs[k] = cert.map_or(NO_CERT, |r| r as u8);
        }
        let (next, h1) = states[0];
        Some(Next {
            j,
            x: next,
            h: h1,
            braking: Braking {
                rung: if certs[0] == NO_CERT {
                    rung
                } else {
                    usize::from(certs[0])
                },
                phase: 0,
                j: 0.0,
            },
            periods,
            follows: false,
            certs,
            certified: certs[0] != NO_CERT,
        })
    }

    /// The next piece of `m` periods under `search` (its jerk, its first period), from `x`
    /// with the positions `h`, where `memo` is what was chosen before (none at rest).
    /// `None` where no jerk of the point's interval is admissible.
    #[allow(clippy::too_many_arguments)]
    fn next(
        &self,
        x: State,
        h: &Hist,
        dt: f64,
        stop: f64,
        search: Search,
        memo: Option<Next>,
        m: usize,
    ) -> Option<Next> {
        let (j_lo, j_hi) = self.jerk_range(x.0, x.1, x.2);
        let at_rest = x.1 == 0.0 && x.2 == 0.0;
        // The previous state's braking, a period on: its tail is the braking already
        // checked to rest, so the state it reaches needs no new simulation.
        let backup = memo
            .filter(|_| !at_rest)
            .and_then(|memo| self.continued(x, h, dt, stop, memo.braking));
        if j_lo > j_hi {
            // A state within a braking's piece, where the intervals are not checked, may
            // lie outside them: only the braking goes on from it.
            return backup;
        }
        let memo = match (search, memo) {
            // At rest (a start, or short of a stop) the full search: its bisection finds
            // the small jerks that creep the last distance.
            (Search::Candidates, Some(memo)) if !at_rest => memo,
            _ => {
                return self
                    .largest_admissible(x, h, dt, stop, j_lo, j_hi, m)
                    .or(backup);
            }
        };
        let step = (j_hi - j_lo) / CANDIDATE_STEPS;
        let previous = memo.j.clamp(j_lo, j_hi);
        let toward_backup = backup.map_or(j_lo, |b| 0.5 * (previous + b.j));
        let (_, v, a) = x;
        // The jerk that levels the acceleration off within the period, and the one that
        // brings it to zero as the speed reaches the point's limit (the landing's jerk
        // `a²/2Δv`, upwards): at a speed limit the search would otherwise dither below
        // it.
        let v_cap = self.v_max_over(x.0, x.0);
        let level = -a / dt;
        let arrive = if a > 0.0 && v < v_cap {
            -a * a / (2.0 * (v_cap - v))
        } else {
            level
        };
        let mut candidates = [
            j_hi,
            previous + 4.0 * step,
            previous + step,
            previous,
            previous - step,
            previous - 4.0 * step,
            toward_backup,
            level,
            arrive,
        ];
        candidates.sort_by(|p, q| q.total_cmp(p));
        let mut tried = f64::INFINITY;
        for j in candidates {
            let j = j.clamp(j_lo, j_hi);
            // Descending: a jerk at or above one refused already is not tried again.
            if j >= tried {
                continue;
            }
            tried = j;
            if backup.is_some_and(|b| j <= b.j) {
                break;
            }
            if let Some(next) = self.admissible(x, h, j, dt, stop, true, m) {
                return Some(next);
            }
        }
        backup.or_else(|| self.largest_admissible(x, h, dt, stop, j_lo, j_hi, m))
    }

    /// The largest jerk of `[j_lo, j_hi]` whose period is [`Section::admissible`], with
    /// the state it ends in: the interval scanned from the top in [`SCAN_STEPS`] steps for
    /// a first admissible jerk (else a braking's), then bisection between it and the step
    /// above.
    #[allow(clippy::too_many_arguments)]
    fn largest_admissible(
        &self,
        x: State,
        h: &Hist,
        dt: f64,
        stop: f64,
        j_lo: f64,
        j_hi: f64,
        m: usize,
    ) -> Option<Next> {
        if let Some(next) = self.admissible(x, h, j_hi, dt, stop, false, m) {
            return Some(next);
        }
        let width = j_hi - j_lo;
        let mut hi = j_hi;
        let mut found = None;
        for k in 1..=SCAN_STEPS {
            let j = j_hi - width * k as f64 / SCAN_STEPS as f64;
            if let Some(next) = self.admissible(x, h, j, dt, stop, false, m) {
                found = Some(next);
                break;
            }
            hi = j;
        }
        let mut best = match found {
            Some(b) => b,
            None => {
                // A braking continuation: admissible whenever the state before was.
                let b = BRAKE_DECELS_MM_S2.iter().find_map(|&decel| {
                    let j = self.brake_jerk(x, dt, decel)?;
                    self.admissible(x, h, j, dt, stop, false, m)
                })?;
                hi = j_hi.min(b.j + width / SCAN_STEPS as f64);
                b
            }
        };
        for _ in 0..BISECTION_STEPS {
            let mid = 0.5 * (best.j + hi);
            match self.admissible(x, h, mid, dt, stop, false, m) {
                Some(next) => best = next,
                None => hi = mid,
            }
        }
        Some(best)
    }
}

impl Grid {
    /// Runs the path from rest to rest at the period of `limits` with the candidates'
    /// search ([`Search::Candidates`]), checking the positions against `limits`.
    pub fn run(&self, limits: &MachineLimits) -> Run {
        self.run_with(limits, Search::Candidates)
    }

    /// Runs the path from rest to rest at the period of `limits` with `search`, section
    /// by section, checking the positions against `limits`.
    pub fn run_with(&self, limits: &MachineLimits, search: Search) -> Run {
        self.run_inner(limits, search, None)
    }

    /// Runs the path as [`Grid::run`] until the period `hold_at` (counted from 0), then
    /// holds: from there every period continues the braking that certified the state
    /// the motion is in, as a real-time cycle would on a feed hold, until rest, where the
    /// run ends ([`Run::hold_periods`], [`Run::hold_checks`]).
    pub fn run_held(&self, limits: &MachineLimits, hold_at: u64) -> Run {
        self.run_inner(limits, Search::Candidates, Some(hold_at))
    }

    fn run_inner(&self, limits: &MachineLimits, search: Search, hold_at: Option<u64>) -> Run {
        let dt = limits.period_s;
        let p0 = self.sections[0].position(0.0);
        let mut h: Hist = [p0; 3];
        let mut monitor = LimitMonitor::at_rest(limits, &p0.into());
        let (mut cycles, mut fallbacks) = (0u64, 0u64);
        let mut planning_s = 0.0;
        let mut most_checks = 0u64;
        let mut gap_mm = 0.0f64;
        // A run that takes more than an hour of periods, or stands still for a second
        // short of its stop, is stuck.
        let max_cycles = (3600.0 / dt) as u64;
        let max_still = (1.0 / dt) as u64;
        let mut stuck = false;
        let (mut hold_periods, mut hold_checks) = (0u64, 0u64);
        for section in &self.sections {
            section.checked.set(0);
        }
        'sections: for section in &self.sections {
            let stop = section.length_mm;
            let mut x: State = (0.0, 0.0, 0.0);
            let mut memo: Option<Next> = None;
            let mut still = 0u64;
            // The approach onto the stop under way, and its periods done.
            let mut approach: Option<(Approach, usize)> = None;
            // Periods left of the piece chosen last (its jerk, or the certified braking).
            let mut left = 0usize;
            loop {
                if cycles >= max_cycles || still >= max_still {
                    stuck = true;
                    break;
                }
                let at_rest = x.1 < 1e-6 && x.2.abs() < 1e-3;
                if stop - x.0 < 1e-9 || (at_rest && stop - x.0 < STOP_GAP_MM) {
                    gap_mm = gap_mm.max(stop - x.0);
                    break;
                }
                let clock = Instant::now();
                let checked_before = section.checked.get();
                let held = hold_at.is_some_and(|at| cycles >= at);
                if approach.is_none() && !held && left == 0 {
                    let gap = stop - x.0;
                    if x.1 == 0.0 && x.2 == 0.0 {
                        // At rest a little short of the stop (a braking lands where its
                        // period ends): the exact approach onto it.
                        if gap > STOP_GAP_MM && gap <= FINAL_APPROACH_MM {
                            approach = section
                                .finish(x, &h, dt, stop)
                                .or_else(|| section.final_approach(x, &h, dt, stop))
                                .map(|a| (a, 0));
                        }
                    } else {
                        // Landing near the stop: three periods onto it, where they hold.
                        approach = section.finish(x, &h, dt, stop).map(|a| (a, 0));
                    }
                }
                let chosen = if let Some((a, k)) = approach {
                    // The approach goes on to its end, held or not (a few periods, to
                    // rest; each checked again as it is played).
                    approach = (k + 1 < a.periods()).then_some((a, k + 1));
                    let period = section.approach_period(x, &h, dt, stop, a, k);
                    let j = a.jerk(k);
                    if held {
                        hold_periods += 1;
                        hold_checks += section.checked.get() - checked_before;
                    }
                    period.map(|(x1, h1)| Next {
                        j,
                        x: x1,
                        h: h1,
                        braking: Braking {
                            rung: 0,
                            phase: 0,
                            j: 0.0,
                        },
                        periods: 1,
                        follows: false,
                        certs: [NO_CERT; MAX_PIECE_PERIODS],
                        certified: true,
                    })
                } else if left > 0 && !(held && memo.is_some_and(|m| m.certified)) {
                    // Within a piece: its jerk (checked when it was chosen, with the
                    // braking from its states where one lands), or the braking it
                    // follows; held, on to a state a braking certifies.
                    left -= 1;
                    let piece = memo.and_then(|m| {
                        if m.follows {
                            section.continued(x, &h, dt, stop, m.braking)
                        } else {
                            let (x1, h1) = section
                                .period_or_why(x, &h, m.j, dt, stop, Intervals::Neither, None)
                                .ok()?;
                            let done = m.periods - 1 - left;
                            let cert = m.certs[done];
                            let braking = Braking {
                                rung: if cert == NO_CERT {
                                    m.braking.rung
                                } else {
                                    usize::from(cert)
                                },
                                ..m.braking
                            };
                            Some(Next {
                                x: x1,
                                h: h1,
                                braking,
                                certified: cert != NO_CERT,
                                ..m
                            })
                        }
                    });
                    if held {
                        hold_periods += 1;
                        hold_checks += section.checked.get() - checked_before;
                    }
                    piece
                } else if held {
                    // Held: only the certified braking goes on, to rest.
                    if x.1 == 0.0 && x.2 == 0.0 {
                        break 'sections;
                    }
                    let braking = memo.and_then(|m| section.continued(x, &h, dt, stop, m.braking));
                    hold_periods += 1;
                    hold_checks += section.checked.get() - checked_before;
                    braking
                } else {
                    // A piece of BRAKE_PIECE_S at periods under it (the brakings' own
                    // pieces): a quarter of the decisions at 250 µs. Where no piece is
                    // admissible (the last creep to a stop), a single period.
                    let m = piece_periods(dt);
                    let next = section.next(x, &h, dt, stop, search, memo, m).or_else(|| {
                        (m > 1)
                            .then(|| section.next(x, &h, dt, stop, search, memo, 1))
                            .flatten()
                    });
                    left = match next {
                        Some(n) if n.follows => piece_periods(dt) - 1,
                        Some(n) => n.periods - 1,
                        None => 0,
                    };
                    next
                };
                memo = chosen;
                (x, h) = match chosen {
                    Some(next) => (next.x, next.h),
                    None => {
                        fallbacks += 1;
                        let (j_lo, j_hi) = section.jerk_range(x.0, x.1, x.2);
                        let j = section
                            .brake_jerk(x, dt, f64::INFINITY)
                            .unwrap_or(j_lo.min(j_hi));
                        let (s1, v1, a1) = step(x, j, dt);
                        let s1 = s1.min(stop);
                        let next = (s1, v1.max(0.0), if v1 <= 0.0 { 0.0 } else { a1 });
                        (next, [h[1], h[2], section.position(s1)])
                    }
                };
                planning_s += clock.elapsed().as_secs_f64();
                most_checks = most_checks.max(section.checked.get() - checked_before);
                cycles += 1;
                still = if x.1 == 0.0 { still + 1 } else { 0 };
                if x.1 == 0.0 && x.2 == 0.0 {
                    // At rest the piece is over (a braking, or a creep, landed in it).
                    left = 0;
                }
                let p = h[2];
                let _ = monitor.check(&p.into());
            }
            if stuck {
                break;
            }
        }
        let mut peaks = [0.0f64; 3];
        for axis in 0..6 {
            if let Some(r) = monitor.peak_ratios(axis) {
                for (peak, ratio) in peaks.iter_mut().zip(r) {
                    *peak = peak.max(ratio);
                }
            }
        }
        Run {
            time_s: cycles as f64 * dt,
            cycles,
            fallbacks,
            peaks,
            us_per_cycle: planning_s * 1e6 / cycles.max(1) as f64,
            checks_per_cycle: self.sections.iter().map(|s| s.checked.get()).sum::<u64>() as f64
                / cycles.max(1) as f64,
            most_checks,
            points: self.points(),
            stops: self.stops(),
            gap_mm,
            stuck,
            hold_periods,
            hold_checks,
        }
    }
}
