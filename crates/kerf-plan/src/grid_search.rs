//! Grid-then-golden search for the least value of a measure over `(0, top]`: a geometric
//! grid down from `top`, stopped once the measure has risen past its best point, then
//! golden-section search in the logarithm between that point's neighbours. The design
//! speed of a curved segment and the tangential acceleration of its budget are both chosen
//! so; [`GridGolden`] holds what differs between the two.

use crate::search::golden_min;

/// When the grid stops going down once it has a best point.
#[derive(Clone, Copy, Debug)]
pub(crate) enum GridStop {
    /// At the first point at least `after` points past the best that is not better than
    /// it; a point without a value counts as not better.
    NotBetter {
        /// Points past the best before the grid may stop.
        after: usize,
    },
    /// At the first point at least `after` points past the best whose value is above
    /// `ratio` times the best; points without a value are passed over.
    Above {
        /// Points past the best before the grid may stop.
        after: usize,
        /// How much above the best a value must be.
        ratio: f64,
    },
}

/// When the measure is probed just below the top, to see whether the top is best.
#[derive(Clone, Copy, Debug)]
pub(crate) enum TopProbe {
    /// Before the grid: if the top has a value and the probe is not better (or has none),
    /// the top wins and no other point is evaluated.
    First,
    /// After the grid, only where its best point is the top: if the probe is not better
    /// (or has none), the top wins and there is no golden-section refinement.
    AfterGrid,
}

/// The parameters of a grid-then-golden search.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GridGolden {
    /// Ratio between neighbouring grid points (below 1): point `k` is `top·ratioᵏ`.
    pub ratio: f64,
    /// Points of the grid, the top included.
    pub points: usize,
    /// When the grid stops early.
    pub stop: GridStop,
    /// When the top is probed.
    pub probe: TopProbe,
    /// Where the probe is, × the top.
    pub probe_ratio: f64,
    /// Where no grid point has a value: go on down the grid while a point is above this
    /// × the top, until one has (`None`: give up). With a floor the golden bracket of the
    /// lowest point reaches the next point below it; without, it ends at that point.
    pub floor: Option<f64>,
    /// Golden-section narrowings between the best grid point's neighbours.
    pub golden_steps: usize,
}

/// What [`grid_golden_min`] found.
#[derive(Clone, Copy, Debug)]
pub(crate) enum GridMin<T> {
    /// The top: the probe just below it is not better. Its value and payload.
    Top((f64, T)),
    /// A minimum away from the top (or the top where the probe did not decide).
    Min {
        /// The value and payload at the top, if it has one.
        at_top: Option<(f64, T)>,
        /// The best grid point: where, its value and its payload.
        grid: (f64, f64, T),
        /// The golden-section point and its value, where it is strictly better than the
        /// best grid point.
        refined: Option<(f64, f64)>,
    },
    /// No point tried had a value; the lowest point tried.
    Nothing {
        /// The lowest point tried.
        lowest: f64,
    },
}

/// The least value of `measure` over `(0, top]` by the search `p` describes. `measure(x)`
/// is the value at `x` with a payload, or `None` where `x` has none; the golden-section
/// search sees no value as `+∞`. The points are evaluated in a fixed order (the probe
/// where [`TopProbe::First`], the grid down from the top, the points below it, the probe
/// where [`TopProbe::AfterGrid`], the golden section), which matters to a measure that
/// keeps state between calls.
pub(crate) fn grid_golden_min<T: Copy>(
    top: f64,
    p: &GridGolden,
    measure: impl Fn(f64) -> Option<(f64, T)>,
) -> GridMin<T> {
    let grid = |k: usize| top * p.ratio.powi(k as i32);
    // The value at the top, when the probe came first (the grid's point 0 reuses it).
    let mut first = None;
    if let TopProbe::First = p.probe {
        let at_top = measure(top);
        if let Some(t) = at_top
            && measure(p.probe_ratio * top).is_none_or(|e| e.0 >= t.0)
        {
            return GridMin::Top(t);
        }
        first = Some(at_top);
    }
    let mut at_top = None;
    let mut best: Option<(usize, (f64, T))> = None;
    for k in 0..p.points {
        let e = match (k, first) {
            (0, Some(v)) => v,
            _ => measure(grid(k)),
        };
        if k == 0 {
            at_top = e;
        }
        let Some(e) = e else {
            if let GridStop::NotBetter { after } = p.stop
                && best.is_some_and(|b| k >= b.0 + after)
            {
                break;
            }
            continue;
        };
        if best.is_none_or(|b| e.0 < b.1.0) {
            best = Some((k, e));
        } else if let Some(b) = best {
            let stop = match p.stop {
                GridStop::NotBetter { after } => k >= b.0 + after,
                GridStop::Above { after, ratio } => k >= b.0 + after && e.0 > ratio * b.1.0,
            };
            if stop {
                break;
            }
        }
    }
    // Below the grid, while nothing has a value.
    let mut k_low = p.points;
    if let Some(floor) = p.floor {
        while best.is_none() && grid(k_low) > top * floor {
            if let Some(e) = measure(grid(k_low)) {
                best = Some((k_low, e));
            }
            k_low += 1;
        }
    }
    let Some((k, found)) = best else {
        return GridMin::Nothing {
            lowest: grid(k_low),
        };
    };
    if let TopProbe::AfterGrid = p.probe
        && k == 0
        && measure(p.probe_ratio * top).is_none_or(|e| e.0 >= found.0)
    {
        return GridMin::Top(found);
    }
    let below = if p.floor.is_some() {
        k + 1
    } else {
        (k + 1).min(p.points - 1)
    };
    let (lo, hi) = (grid(below).ln(), grid(k.saturating_sub(1)).min(top).ln());
    let (x, c) = golden_min(lo, hi, p.golden_steps, |x| {
        measure(x.exp()).map_or(f64::INFINITY, |e| e.0)
    });
    GridMin::Min {
        at_top,
        grid: (grid(k), found.0, found.1),
        refined: (c < found.0).then(|| (x.exp(), c)),
    }
}
