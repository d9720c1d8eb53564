//! Arithmetic of jerk-limited speed changes and a bisection, shared by the planner (rough
//! times of corner treatments and design speeds) and the motion core (distances and
//! reachable speeds), so that both use the same formula.

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
