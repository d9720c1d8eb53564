//! The design speed of a curved segment: among all speeds up to the top one, the one
//! whose tangential budget gives the least rough time over the distance the speed is held.

use super::TOP_PROBE_RATIO;
use crate::grid_search::{GridGolden, GridMin, GridStop, TopProbe, grid_golden_min};
use crate::timing::change_time_s;

/// Distance a curved segment's design speed is chosen for at the least, mm: the segment
/// may be one of a long chain (a dense circle, a helix in turns), so its own length says
/// little about how long the speed is held.
pub const DESIGN_RUN_MM: f64 = 30.0;
/// Ratio of the design-speed candidates below the top speed: 20 % steps are fine enough
/// for the golden-section refinement between neighbours to find the minimum.
const DESIGN_GRID_RATIO: f64 = 0.8;
/// Candidates of that grid: down to `0.8²⁴ ≈ 0.5 %` of the top speed, below which a
/// design speed is a crawl.
const DESIGN_GRID_POINTS: usize = 25;
/// The design grid stops once this many points past the best one...
const DESIGN_STOP_AFTER: usize = 3;
/// ...are this much slower than it: 50 % past the best, the unimodal measure will not
/// come back.
const DESIGN_STOP_RATIO: f64 = 1.5;
/// Lowest design speed tried when no grid point has a budget, × the top speed: 1e-12 is
/// where the curvature terms (`v²`, `v³`) have vanished for any finite limits.
const DESIGN_FLOOR_RATIO: f64 = 1e-12;
/// Golden-section narrowings of the design speed between grid neighbours: `0.618¹⁰ ≈ 1 %`
/// of the bracket, finer than the rough time it minimises.
const DESIGN_GOLDEN_STEPS: usize = 10;
/// Acceleration and jerk of a segment whose top speed is 0 or not finite (no speed to
/// design for), path units/s² and /s³: tiny and positive, never 0 or infinite.
const DEGENERATE_BUDGET: f64 = 1e-3;

/// The grid-then-golden search over the design speed (see the constants above).
const DESIGN_SEARCH: GridGolden = GridGolden {
    ratio: DESIGN_GRID_RATIO,
    points: DESIGN_GRID_POINTS,
    stop: GridStop::Above {
        after: DESIGN_STOP_AFTER,
        ratio: DESIGN_STOP_RATIO,
    },
    probe: TopProbe::First,
    probe_ratio: TOP_PROBE_RATIO,
    floor: Some(DESIGN_FLOOR_RATIO),
    golden_steps: DESIGN_GOLDEN_STEPS,
};

/// The design speed `vd` (at most `v_top`) and its tangential budget `budget(vd)` that
/// give the least rough time over `length` from rest to rest: the cruise at `vd` plus one
/// jerk-limited ramp to it ([`change_time_s`]). The callers pass the segment's design run
/// (`run_mm` of [`crate::segment_limits`]) or its own length if longer: for arcs, smoothed
/// pieces and G2 transitions the path that runs on without a corner, at most
/// [`DESIGN_RUN_MM`] (G2 corner blends: `DESIGN_RUN_MM`); for circular corner blends 0,
/// so just their own length. On a curve a higher design speed leaves less of the axis
/// limits to the tangential motion (the centripetal terms take them), so the fastest
/// cruise is not the quickest segment.
///
/// The choice is a minimum of one measure over every speed up to `v_top`, and a larger
/// limit on any axis only raises `v_top` and every speed's budget: the measure it finds
/// never grows with a limit. (A rule such as "the highest speed whose budget is a fifth
/// of the axis limits" is not: a larger limit moves the threshold and can push the
/// design speed up into a poorer budget or down to a crawl.)
pub(super) fn design_speed_search(
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
        return (v_top.max(0.0), DEGENERATE_BUDGET, DEGENERATE_BUDGET);
    }
    // Coarse grid down from the top, stopping once the measure has risen well past its
    // best (it is unimodal in practice: the cruise term falls with vd, the ramp grows);
    // then golden-section search in log vd between the best point's neighbours. The usual
    // case is tried first: the top speed is best and the measure rises just below it (the
    // measure being unimodal, the grid would find nothing better). Where no grid speed has
    // a budget (the curvature terms used all of it) the search goes on lowering, as they
    // vanish with the speed (v² and v³) and leave the whole tangential budget at a low
    // enough one: a floor of made-up limits would crawl (a short G2 blend for seconds).
    let found = grid_golden_min(v_top, &DESIGN_SEARCH, |vd| {
        eval(vd).map(|(t, a, j)| (t, (a, j)))
    });
    let (at_top, mut vd, mut found, refined) = match found {
        GridMin::Top((_, (a, j))) => return (v_top, a, j),
        GridMin::Nothing { lowest } => {
            // Unreachable for finite limits (see above): the lowest speed tried, and a
            // budget as small, keep the segment slow but finite.
            return (lowest, lowest, lowest);
        }
        GridMin::Min {
            at_top,
            grid: (vd, t, (a, j)),
            refined,
        } => (at_top, vd, (t, a, j), refined),
    };
    if let Some((x, _)) = refined
        && let Some(e) = eval(x).filter(|e| e.0 < found.0)
    {
        vd = x;
        found = e;
    }
    // A minimum within 1 % below the top is the top: the measure differs there by less
    // than its own accuracy, while a smoothed piece 1 % under the feed makes the motion
    // core run its whole section 1 % slower.
    if vd >= TOP_PROBE_RATIO * v_top
        && let Some((_, (a, j))) = at_top
    {
        return (v_top, a, j);
    }
    (vd, found.1, found.2)
}
