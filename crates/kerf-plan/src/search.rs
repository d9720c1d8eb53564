//! One-dimensional numeric searches: golden section for a minimum ([`golden_min`]),
//! bisection for the largest `x` that passes a monotone test ([`bisect_max`]) and regula
//! falsi for the largest `x` below a sign change ([`falsi_max`]). The plain bisection is
//! `kerf_geom::ramp::bisect`, shared with the motion core and re-exported here.

pub(crate) use kerf_geom::ramp::bisect;

/// Golden-section search for the minimum of `cost` on `[lo, hi]` (`steps` narrowings):
/// the better of the last two points, and its cost.
pub(crate) fn golden_min(
    mut lo: f64,
    mut hi: f64,
    steps: usize,
    cost: impl Fn(f64) -> f64,
) -> (f64, f64) {
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

/// Halvings at most in [`bisect_max`]: `2⁻⁶⁰` of even a huge bracket (it starts from `hi`,
/// possibly near `f64::MAX`) is below the relative resolution asked for.
const BISECT_MAX_STEPS: usize = 60;
/// Relative resolution of [`bisect_max`]: 1e-6, far finer than any limit it computes needs.
const BISECT_MAX_REL: f64 = 1e-6;

/// Largest `x` in `[0, hi]` with `ok(x)` (assumes `ok` is monotone), to [`BISECT_MAX_REL`]
/// relative.
pub(crate) fn bisect_max(ok: impl Fn(f64) -> bool, hi: f64) -> f64 {
    if ok(hi) {
        return hi;
    }
    // Find a finite bracket first when `hi` is huge.
    let mut lo = 0.0;
    let mut up = hi;
    for _ in 0..BISECT_MAX_STEPS {
        let mid = 0.5 * (lo + up);
        if ok(mid) {
            lo = mid;
        } else {
            up = mid;
        }
        if up - lo <= BISECT_MAX_REL * up {
            break;
        }
    }
    lo
}

/// The largest `x` known with `gap(x) ≤ 0` between `good` (`gap(good) ≤ 0`) and `bad`
/// (`gap(bad) > 0`), for a `gap` that changes sign once there (it grows with `x` where it
/// matters): regula falsi, Illinois variant (the end kept twice in a row has its value
/// halved), which converges in about ten steps where a bisection takes 24 to 60 and never
/// leaves the bracket. Stops once the bracket is within `rel` of `bad`, or after `steps`;
/// a NaN `gap` counts as past the root (the bracket halves there).
pub(crate) fn falsi_max(
    mut good: f64,
    mut bad: f64,
    rel: f64,
    steps: usize,
    gap: impl Fn(f64) -> f64,
) -> f64 {
    let (mut g_good, mut g_bad) = (gap(good), gap(bad));
    if !(g_good <= 0.0 && g_bad > 0.0 && bad > good) {
        return good;
    }
    // Which end moved last: -1 the good one, 1 the bad one.
    let mut side = 0i8;
    for _ in 0..steps {
        if bad - good <= rel * bad.abs() {
            break;
        }
        let mut mid = (good * g_bad - bad * g_good) / (g_bad - g_good);
        if !(mid > good && mid < bad) {
            mid = 0.5 * (good + bad);
        }
        let g = gap(mid);
        if g <= 0.0 {
            good = mid;
            g_good = g;
            if side == -1 {
                g_bad *= 0.5;
            }
            side = -1;
        } else {
            bad = mid;
            g_bad = if g.is_nan() { f64::MAX } else { g };
            if side == 1 {
                g_good *= 0.5;
            }
            side = 1;
        }
    }
    good
}
