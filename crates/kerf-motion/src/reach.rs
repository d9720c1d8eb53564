//! Closed-form jerk-limited reachability along the path (`a = 0` at both ends unless
//! said otherwise): the distance to change speed, the highest speed reachable within a
//! distance (these two from `kerf_geom::ramp`, which the planner's estimate of the
//! sections shares), and the quickest rise and fall to a given end acceleration.

pub(crate) use kerf_geom::ramp::bisect;
pub use kerf_geom::ramp::{change_distance, reach, reach_back};

/// Bisection steps on the peak acceleration in `rise_reach`: to 1/65,536 of its range
/// (from the least peak to a bound from the distance); the speed found is at most that
/// low, and lower is always reachable.
pub(crate) const RISE_STEPS: usize = 16;

/// Speed and distance once acceleration `a0` at speed `v0` has been brought to zero at
/// jerk `jerk`.
pub(crate) fn settle(v0_mm_s: f64, a0_mm_s2: f64, jerk_mm_s3: f64) -> (f64, f64) {
    let tau = a0_mm_s2.abs() / jerk_mm_s3;
    let v_at_mm_s = v0_mm_s + a0_mm_s2 * a0_mm_s2.abs() / (2.0 * jerk_mm_s3);
    let d0_mm = v0_mm_s * tau + 0.5 * a0_mm_s2 * tau * tau
        - a0_mm_s2.signum() * jerk_mm_s3 * tau * tau * tau / 6.0;
    (v_at_mm_s, d0_mm)
}

/// Distance and end speed of a rise from `(v0, a0)` at jerk `jerk`: the acceleration up
/// to `peak` and down to `a1` (`peak ≥ a0, a1 ≥ 0`).
pub(crate) fn rise_with_peak(
    v0_mm_s: f64,
    a0_mm_s2: f64,
    a1_mm_s2: f64,
    peak: f64,
    jerk_mm_s3: f64,
) -> (f64, f64) {
    let (t1, t3) = (
        (peak - a0_mm_s2) / jerk_mm_s3,
        (peak - a1_mm_s2) / jerk_mm_s3,
    );
    let d1 = t1 * (v0_mm_s + t1 * (a0_mm_s2 / 2.0 + t1 * jerk_mm_s3 / 6.0));
    let v_up = v0_mm_s + (peak * peak - a0_mm_s2 * a0_mm_s2) / (2.0 * jerk_mm_s3);
    let d3 = t3 * (v_up + t3 * (peak / 2.0 - t3 * jerk_mm_s3 / 6.0));
    (
        d1 + d3,
        v_up + (peak * peak - a1_mm_s2 * a1_mm_s2) / (2.0 * jerk_mm_s3),
    )
}

/// The highest speed the quickest rise from `(v0, a0)` reaches in distance `d`, ending
/// with acceleration `a1` (accelerations in `[0, accel]`): the acceleration up at the jerk
/// limit, held at `accel` if need be, and down to `a1`. `None` when even the rise of the
/// acceleration (to the larger of `a0` and `a1`, and down to `a1`) does not fit, or an
/// input is out of range. Closed form where the acceleration is held, else a bisection on
/// the peak acceleration (the distance grows with it): cheap enough for the cycle.
pub(crate) fn rise_reach(
    v0_mm_s: f64,
    a0_mm_s2: f64,
    a1_mm_s2: f64,
    d_mm: f64,
    accel_mm_s2: f64,
    jerk_mm_s3: f64,
) -> Option<f64> {
    let in_range = |a: f64| (0.0..=accel_mm_s2).contains(&a);
    if !(in_range(a0_mm_s2)
        && in_range(a1_mm_s2)
        && jerk_mm_s3 > 0.0
        && v0_mm_s >= 0.0
        && d_mm > 0.0)
    {
        return None;
    }
    let low = a0_mm_s2.max(a1_mm_s2);
    if rise_with_peak(v0_mm_s, a0_mm_s2, a1_mm_s2, low, jerk_mm_s3).0 > d_mm {
        return None;
    }
    let (d_top, v_top) = rise_with_peak(v0_mm_s, a0_mm_s2, a1_mm_s2, accel_mm_s2, jerk_mm_s3);
    if d_top <= d_mm {
        // Held at `accel` for `h`: the distance grows by `(v_up + accel·t3)·h + accel·h²/2`.
        let t3 = (accel_mm_s2 - a1_mm_s2) / jerk_mm_s3;
        let v_up = v0_mm_s + (accel_mm_s2 * accel_mm_s2 - a0_mm_s2 * a0_mm_s2) / (2.0 * jerk_mm_s3);
        let b = v_up + accel_mm_s2 * t3;
        let h = 2.0 * (d_mm - d_top) / (b + (b * b + 2.0 * accel_mm_s2 * (d_mm - d_top)).sqrt());
        return Some(v_top + accel_mm_s2 * h);
    }
    // The peak is bounded by the distance too: the rise up to it alone takes at least
    // `J t³/6` (from `a0 ≥ 0`), and both ramps at least `v0` times their time.
    let mut top = accel_mm_s2.min(a0_mm_s2 + jerk_mm_s3 * (6.0 * d_mm / jerk_mm_s3).cbrt());
    if v0_mm_s > 0.0 {
        top = top.min(0.5 * (jerk_mm_s3 * d_mm / v0_mm_s + a0_mm_s2 + a1_mm_s2));
    }
    let peak = bisect(low, top.max(low), RISE_STEPS, |p| {
        rise_with_peak(v0_mm_s, a0_mm_s2, a1_mm_s2, p, jerk_mm_s3).0 <= d_mm
    });
    Some(rise_with_peak(v0_mm_s, a0_mm_s2, a1_mm_s2, peak, jerk_mm_s3).1)
}

/// Distance of the quickest fall from `(v0, a0)` to speed `v1` with acceleration `a1`
/// (`a0, a1 ≤ 0`; accelerations in `[-accel, 0]`) at jerk `jerk`: the acceleration down
/// at the jerk limit to a peak deceleration, held at `accel` if need be, and back up to
/// `a1`. The quickest fall covers the least distance. `None` when no such fall ends at
/// `v1` (the drop `v0 - v1` is less than bringing the acceleration from `a0` to `a1`
/// takes), `v1` is below rest, or an input is out of range.
pub(crate) fn fall_distance(
    v0_mm_s: f64,
    a0_mm_s2: f64,
    v1_mm_s: f64,
    a1_mm_s2: f64,
    accel_mm_s2: f64,
    jerk_mm_s3: f64,
) -> Option<f64> {
    let in_range = |a: f64| (-accel_mm_s2..=0.0).contains(&a);
    if !(in_range(a0_mm_s2) && in_range(a1_mm_s2) && jerk_mm_s3 > 0.0 && v1_mm_s >= 0.0) {
        return None;
    }
    let drop_mm_s = v0_mm_s - v1_mm_s;
    let (b0, b1) = (-a0_mm_s2, -a1_mm_s2);
    // With no hold, the drop fixes the peak: `(2 peak² - b0² - b1²) / 2j`.
    let peak_sq = 0.5 * (2.0 * jerk_mm_s3 * drop_mm_s + b0 * b0 + b1 * b1);
    if peak_sq.is_nan() || peak_sq < b0.max(b1).powi(2) {
        return None;
    }
    let peak = peak_sq.sqrt().min(accel_mm_s2);
    // The drop the ramps make at that peak; the rest at `accel`, held for `h`.
    let ramps_mm_s = (2.0 * peak * peak - b0 * b0 - b1 * b1) / (2.0 * jerk_mm_s3);
    let h_s = ((drop_mm_s - ramps_mm_s) / peak).max(0.0);
    let t1 = (peak - b0) / jerk_mm_s3;
    let d1 = t1 * (v0_mm_s - t1 * (b0 / 2.0 + t1 * jerk_mm_s3 / 6.0));
    let v_down = v0_mm_s - (peak * peak - b0 * b0) / (2.0 * jerk_mm_s3);
    let d_hold = h_s * (v_down - peak * h_s / 2.0);
    let v_held = v_down - peak * h_s;
    let t3 = (peak - b1) / jerk_mm_s3;
    let d3 = t3 * (v_held - t3 * (peak / 2.0 - t3 * jerk_mm_s3 / 6.0));
    Some(d1 + d_hold + d3)
}

/// Whether the speed can be brought from `(v0, a0)`, `a0 ≤ 0`, to at most `v_end` with
/// `a = 0` within `d`: by bringing the acceleration to zero (where the speed that leaves
/// is within `v_end`), else by the quickest fall on to `v_end`.
pub(crate) fn falls_within(
    v0_mm_s: f64,
    a0_mm_s2: f64,
    v_end_mm_s: f64,
    d_mm: f64,
    accel_mm_s2: f64,
    jerk_mm_s3: f64,
) -> bool {
    let (v_at_mm_s, d0_mm) = settle(v0_mm_s, a0_mm_s2, jerk_mm_s3);
    if v_at_mm_s <= v_end_mm_s {
        return d0_mm <= d_mm;
    }
    fall_distance(v0_mm_s, a0_mm_s2, v_end_mm_s, 0.0, accel_mm_s2, jerk_mm_s3)
        .is_some_and(|fall_mm| fall_mm <= d_mm)
}

#[cfg(test)]
mod tests {
    use super::{fall_distance, rise_reach};
    use kerf_geom::ramp::bisect;

    /// Distance and end speed of a motion from speed `v0` and acceleration `a0` through
    /// `phases` of (duration, jerk), stepped through numerically in 400 midpoint steps per
    /// phase (exact for the cubic up to rounding): the reference the closed forms are
    /// checked against.
    fn integrate(v0: f64, a0: f64, phases: [(f64, f64); 3]) -> (f64, f64) {
        let (mut p, mut v, mut a) = (0.0, v0, a0);
        for (t, j) in phases {
            let n = 400;
            let dt = t / n as f64;
            for _ in 0..n {
                let a_mid = a + j * dt / 2.0;
                let v_mid = v + a * dt / 2.0 + j * dt * dt / 8.0;
                p += v_mid * dt + j * dt * dt * dt / 24.0;
                v += a_mid * dt;
                a += j * dt;
            }
        }
        (p, v)
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
                integrate(
                    v0,
                    a0,
                    [
                        ((peak - a0) / jerk, jerk),
                        (hold_s, 0.0),
                        ((peak - a1) / jerk, -jerk),
                    ],
                )
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

    /// `fall_distance` against numerical integration: a fall with a random peak
    /// deceleration (held at the acceleration limit for a random time where it reaches
    /// it) is stepped through in small time steps; the closed form, asked for the end
    /// speed the steps reach, must give the distance they covered.
    #[test]
    fn the_quickest_fall_matches_numerical_integration() {
        let mut log_uniform = crate::profile::tests::log_uniform_source(0x5eed_fa11);
        let mut compared = 0;
        for _ in 0..200 {
            let accel = log_uniform(100.0, 1e4);
            let jerk = log_uniform(1e3, 1e6);
            let v0 = log_uniform(1.0, 300.0);
            let b0 = accel * log_uniform(1e-3, 1.0);
            let b1 = accel * log_uniform(1e-3, 1.0);
            let low = b0.max(b1);
            let held = log_uniform(1.0, 4.0) < 2.0;
            let peak = if held {
                accel
            } else {
                low + (accel - low) * log_uniform(1e-3, 1.0)
            };
            let hold_s = if held { log_uniform(1e-4, 0.1) } else { 0.0 };
            let (p, v) = integrate(
                v0,
                -b0,
                [
                    ((peak - b0) / jerk, -jerk),
                    (hold_s, 0.0),
                    ((peak - b1) / jerk, jerk),
                ],
            );
            if v < 0.0 {
                // Passed through rest: out of range for the closed form.
                assert_eq!(fall_distance(v0, -b0, v, -b1, accel, jerk), None);
                continue;
            }
            let d = fall_distance(v0, -b0, v, -b1, accel, jerk).unwrap_or_else(|| {
                panic!("no fall found (v0 {v0} b0 {b0} b1 {b1} peak {peak} hold {hold_s})")
            });
            assert!(
                (d - p).abs() <= 1e-6 * p.max(1e-6),
                "closed form {d} mm, steps {p} mm (v0 {v0} b0 {b0} b1 {b1} peak {peak} hold {hold_s} accel {accel} jerk {jerk})"
            );
            compared += 1;
        }
        assert!(compared > 50, "{compared}");
        // A drop smaller than the change of acceleration allows has no such fall.
        assert_eq!(fall_distance(10.0, -500.0, 9.99, 0.0, 1000.0, 5000.0), None);
    }
}
