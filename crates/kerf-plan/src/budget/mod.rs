//! Limit budgets: the path limits `(v, a, j)` of a segment such that every axis stays
//! within [`crate::PROFILE_SHARE`] of its limits, and the design speed of curved segments.
//!
//! One file per step: [`arc`] (lines, arcs and helices: weights and budgets in closed form
//! or by bisection), [`bounds`] (sampled bounds of a quintic), [`transition_limits`]
//! (quintic segments), [`design`] (the design speed), [`envelope`] (the tangential budget
//! at one design speed under the jerk-limited envelope), [`quickest`] (the acceleration
//! of the quickest ramp), [`ramp`] (ramp budgets of smoothed pieces at stops) and [`key`]
//! (the memo key).

mod arc;
mod bounds;
mod design;
mod envelope;
mod key;
mod quickest;
mod ramp;
mod transition_limits;

pub use design::DESIGN_RUN_MM;
pub(crate) use key::limits_key;
pub(crate) use ramp::{PieceSamples, lowered_ramp_design, ramp_budget};

use crate::memo::Limits;
use crate::{MachineLimits, PlannedSegment};
use kerf_geom::Curve;

/// Share of the acceleration (and jerk) budget that centripetal terms may take on curves:
/// 85 % bounds the speed limit from curvature, leaving at least 15 % for the tangential
/// ramps at that speed. A larger share leaves so little at the top speed that a machine
/// can fail to plan and a short arc crawls; a smaller one slows jerk-bound curves
/// (`docs/PERFORMANCE.md` has the measurements).
const CENTRIPETAL_SHARE: f64 = 0.85;

/// Samples of a transition for its curvature bounds: 128 like [`crate::DEVIATION_SAMPLES`];
/// what rises between samples is covered by [`bounds::rate_rise`] with [`RATE_SAFETY`],
/// [`CURVATURE_SAFETY`] and, on rotary axes, [`LIMIT_SAFETY`].
const LIMIT_SAMPLES: usize = 128;
/// Samples for the curvature bounds of a smoothed piece that covers several moves: such
/// pieces are gentle (their curvature follows a fitted window, not a corner), so half of
/// [`LIMIT_SAMPLES`] suffices and halves the cost on dense CAM code.
const PIECE_LIMIT_SAMPLES: usize = 64;
/// Safety factor on the sampled bounds of the rotary axes' second derivatives along a
/// transition and of their rate (by central differences): 10 % covers the
/// finite-difference error and the rise between samples. (X, Y, Z take the curvature's
/// derivative in closed form, with [`RATE_SAFETY`].)
pub const LIMIT_SAFETY: f64 = 1.1;
/// Safety factor on the sampled unit-tangent components of a transition (X, Y, Z: with
/// their rise between samples bounded by [`bounds::rate_rise`]): 0.1 % for what that bound misses.
const TANGENT_SAFETY: f64 = 1.001;
/// Safety factor on the sampled curvature of a transition. The curvature itself is
/// sampled directly; between samples of a smooth quintic it cannot rise by more than a
/// fraction of a per cent.
pub const CURVATURE_SAFETY: f64 = 1.02;
/// Safety factor on the curvature's derivative of a transition (XYZ), evaluated in closed
/// form at each sample with its rise between samples bounded by `rate_rise`: 2 % for
/// what that bound misses. Closed form rather than central differences, which smooth the
/// peaks and would need the larger [`LIMIT_SAFETY`] (costing jerk-bound curves speed).
pub const RATE_SAFETY: f64 = 1.02;
/// Probe just below the top of a grid (design speed or acceleration): 1 % below, to see
/// whether the measure rises there (then the top is best and no refinement is needed).
const TOP_PROBE_RATIO: f64 = 0.99;

/// Path limits `(v_max, a_max, j_max)` of a segment such that every axis stays within
/// [`crate::PROFILE_SHARE`] of its limits at any speed `v` up to `v_max` (curved segments: up to
/// the programmed feed) with jerk up to `j_max` and tangential acceleration within the
/// jerk-limited envelope `|a| ≤ min(a_max, sqrt(2 j_max (v_max − v)))`: the full `a_max`
/// only where `v` is far enough below `v_max`. That is how the motion core runs: a
/// speed-up, one carried across a section boundary included, keeps `v + a²/2j` within
/// the speed limits (see `envelope_budget`). On lines, where no term grows with the
/// speed, the limits hold for any `|a| ≤ a_max` at any speed up to `v_max`.
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
    segment_limits_pair(seg, limits, feed_scale, None, run_mm).0
}

/// [`segment_limits`] at `feed_scale` and, if given, at `boost_scale` too: the same as two
/// calls, sharing the work both need (a transition's bounds, the design for the feed).
pub(crate) fn segment_limits_pair(
    seg: &PlannedSegment,
    limits: &MachineLimits,
    feed_scale: f64,
    boost_scale: Option<f64>,
    run_mm: f64,
) -> Limits {
    if let Curve::Transition(t) = &seg.curve {
        // Smoothed pieces keep the programmed feed as their design speed: boosted, their
        // limits vary with the direction from piece to piece, and differences beyond the
        // merge ratios split the motion core's sections (a return to a = 0 at each
        // boundary a speed-up is not carried over), which costs more than it gains.
        let (samples, feed_scale, boost_scale) = if seg.move_count > 1 {
            (PIECE_LIMIT_SAMPLES, 1.0, boost_scale.map(|_| 1.0))
        } else {
            (LIMIT_SAMPLES, feed_scale, boost_scale)
        };
        return transition_limits::transition_limits(
            seg,
            t,
            limits,
            samples,
            feed_scale,
            boost_scale,
            run_mm,
        );
    }
    arc::arc_limits(seg, limits, feed_scale, boost_scale, run_mm)
}

/// The design for the programmed feed (at most the machine speed `v`), or for the feed
/// times `feed_scale` if that allows a speed at least 10 % higher: a design speed above
/// the feed leaves less tangential budget (slower ramps), which a few per cent more speed
/// does not pay for (the dense circle at 150 %: 102 mm/s instead of 100, but 0.96 s
/// instead of 0.78 s). The same for `boost_scale` if given (the design for the feed is
/// searched once for both).
fn boosted(
    v: f64,
    feed: f64,
    feed_scale: f64,
    boost_scale: Option<f64>,
    search: impl Fn(f64) -> (f64, f64, f64),
) -> Limits {
    let base = search(v.min(feed));
    let pick = |scale: f64| {
        if scale > 1.0 && v > feed {
            let boost = search(v.min(feed * scale));
            if boost.0 >= 1.1 * base.0 {
                return boost;
            }
        }
        base
    };
    (pick(feed_scale), boost_scale.map(pick))
}
