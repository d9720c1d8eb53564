//! Arithmetic of jerk-limited speed changes and a bisection, shared by the planner (rough
//! times of corner treatments and design speeds, its estimate of the motion core's
//! sections) and the motion core (distances and reachable speeds), so that both use the
//! same formula.

/// Fraction of a section's length the motion core's lookahead assumes available when it
/// works out the speeds a section can be entered at (a numerical margin).
pub const BACKWARD_MARGIN: f64 = 0.998;

/// Time of a jerk-limited change of speed by `dv` (≥ 0) with acceleration limit `a` and
/// jerk `j`, starting and ending at zero acceleration, s: a pure jerk ramp while
/// `dv ≤ a²/j`, else one with a constant-acceleration phase.
pub fn change_time_s(dv: f64, a: f64, j: f64) -> f64 {
    if dv * j <= a * a {
        2.0 * (dv / j).sqrt()
    } else {
        dv / a + a / j
    }
}

/// Distance to change speed from `v0` to `v1` with `a = 0` at both ends along the
/// symmetric jerk-limited profile (exact: the speed curve is point-symmetric).
pub fn change_distance(v0_mm_s: f64, v1_mm_s: f64, accel_mm_s2: f64, jerk_mm_s3: f64) -> f64 {
    0.5 * (v0_mm_s + v1_mm_s) * change_time_s((v1_mm_s - v0_mm_s).abs(), accel_mm_s2, jerk_mm_s3)
}

/// Highest speed reachable from `v0` (or from which `v0` is reachable) within distance
/// `d` with `a = 0` at both ends: the inverse of [`change_distance`] in its second
/// argument, in closed form (a bounded Newton solve of a cubic, then a quadratic).
pub fn reach(v0_mm_s: f64, d_mm: f64, accel_mm_s2: f64, jerk_mm_s3: f64) -> f64 {
    if d_mm <= 0.0 || accel_mm_s2 <= 0.0 || jerk_mm_s3 <= 0.0 {
        return v0_mm_s;
    }
    let v0_mm_s = v0_mm_s.max(0.0);
    // Short change: d = (2 v0 + j x²) x with x = sqrt(dv / j). Newton from an upper
    // bound converges monotonically because the cubic is convex for x > 0.
    let mut x = (d_mm / jerk_mm_s3).cbrt();
    if v0_mm_s > 0.0 {
        x = x.min(d_mm / (2.0 * v0_mm_s));
    }
    for _ in 0..12 {
        let f = jerk_mm_s3 * x * x * x + 2.0 * v0_mm_s * x - d_mm;
        let df = 3.0 * jerk_mm_s3 * x * x + 2.0 * v0_mm_s;
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
    let dv = jerk_mm_s3 * x * x;
    if dv * jerk_mm_s3 <= accel_mm_s2 * accel_mm_s2 {
        return v0_mm_s + dv;
    }
    // Long change with a constant-acceleration phase: dv² + B dv + C = 0.
    let b = 2.0 * v0_mm_s + accel_mm_s2 * accel_mm_s2 / jerk_mm_s3;
    let c = 2.0 * v0_mm_s * accel_mm_s2 * accel_mm_s2 / jerk_mm_s3 - 2.0 * d_mm * accel_mm_s2;
    let disc = (b * b - 4.0 * c).max(0.0);
    let dv = -2.0 * c / (b + disc.sqrt());
    v0_mm_s + dv.max(0.0)
}

/// Highest speed at the start of a distance `d` from which the speed at its end can be
/// brought to at most `v_end` (`a = 0` at both ends). Slowing down only partially can need
/// more distance than stopping (the jerk-limited profile's time grows with the speed
/// change), so both ending at `v_end` and ending at rest are candidates.
pub fn reach_back(v_end_mm_s: f64, d_mm: f64, accel_mm_s2: f64, jerk_mm_s3: f64) -> f64 {
    reach(v_end_mm_s, d_mm, accel_mm_s2, jerk_mm_s3).max(reach(0.0, d_mm, accel_mm_s2, jerk_mm_s3))
}

/// Bisection between a value `good`, where `ok` holds, and one, `bad`, where it does not
/// (`ok` changes only once between them): after `steps` halvings, the value nearest `bad`
/// known to satisfy `ok` (`good` itself if no midpoint does).
pub fn bisect(mut good: f64, mut bad: f64, steps: usize, ok: impl Fn(f64) -> bool) -> f64 {
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
