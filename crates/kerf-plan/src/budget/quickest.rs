//! The tangential budget at one design speed that makes the quickest jerk-limited change
//! of speed by it: the acceleration chosen for the time it gives, with the jerk the axes
//! leave at that acceleration.

use super::TOP_PROBE_RATIO;
use crate::grid_search::{GridGolden, GridMin, GridStop, TopProbe, grid_golden_min};
use crate::search::falsi_max;
use crate::timing::change_time_s;

/// Grid ratio of [`quickest_budget`]'s coarse search over the acceleration: halving
/// spans many decades in few points; golden-section search refines between them.
const BUDGET_GRID_RATIO: f64 = 0.5;
/// Points of that grid: it spans `a_hi` down to `a_hi·0.5²⁰ ≈ 1e-6·a_hi`, below which an
/// acceleration gives no usable ramp.
const BUDGET_GRID_POINTS: usize = 21;
/// The acceleration grid stops this many points past the best (the time falls and then
/// rises with the acceleration, so two rising points end the search).
const BUDGET_STOP_AFTER: usize = 2;
/// Golden-section narrowings of the acceleration between grid neighbours:
/// `0.618¹⁴ ≈ 0.1 %` of a bracket twice as wide (in log) as the design speed's.
const BUDGET_GOLDEN_STEPS: usize = 14;
/// Relative width at which the search for the acceleration a ramp by `vd` peaks at stops
/// (regula falsi, [`falsi_max`]): far below what the ramp time can tell.
const PEAK_REL: f64 = 1e-9;
/// Steps at most of that search (regula falsi converges in about ten).
const PEAK_STEPS: usize = 60;

/// The grid-then-golden search over the acceleration (see the constants above).
const BUDGET_SEARCH: GridGolden = GridGolden {
    ratio: BUDGET_GRID_RATIO,
    points: BUDGET_GRID_POINTS,
    stop: GridStop::NotBetter {
        after: BUDGET_STOP_AFTER,
    },
    probe: TopProbe::AfterGrid,
    probe_ratio: TOP_PROBE_RATIO,
    floor: None,
    golden_steps: BUDGET_GOLDEN_STEPS,
};

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
pub(super) fn quickest_budget(
    vd: f64,
    a_hi: f64,
    jerk_for: impl Fn(f64) -> f64,
) -> Option<(f64, f64)> {
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
    // log a) around the best grid point. A cost that is not finite is no value: the grid
    // counts it as not better, the golden-section search sees it as it is.
    let found = grid_golden_min(a_hi, &BUDGET_SEARCH, |a| {
        let c = cost(a);
        (c != f64::INFINITY).then_some((c, ()))
    });
    let a = match found {
        GridMin::Nothing { .. } => return None,
        GridMin::Top(_) => {
            let j = jerk_for(a_hi);
            return Some((a_hi, j));
        }
        GridMin::Min {
            grid: (a, ..),
            refined,
            ..
        } => refined.map_or(a, |(x, _)| x),
    };
    let j = jerk_for(a);
    // Never more acceleration than a ramp by `vd` reaches (`a = sqrt(vd·j(a))`, found by
    // regula falsi, [`falsi_max`]): less leaves the same ramp time and more jerk room.
    if a * a > vd * j {
        let lo = falsi_max(0.0, a, PEAK_REL, PEAK_STEPS, |x| x * x - vd * jerk_for(x));
        let j_lo = jerk_for(lo);
        if lo > 0.0 && j_lo >= j {
            return Some((lo, j_lo));
        }
    }
    Some((a, j))
}
