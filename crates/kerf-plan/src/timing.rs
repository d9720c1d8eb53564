//! Rough times of jerk-limited speed changes, used to compare corner treatments and to
//! choose design speeds.

use crate::search::bisect;

/// Halvings when a rough time's speed is found by bisection: `2⁻⁵⁰ ≈ 1e-15` of the
/// bracket, the resolution of an f64.
const SPEED_BISECTION_STEPS: usize = 50;

pub(crate) use kerf_geom::ramp::change_time_s;

/// The highest speed (at most `v_max`) that a jerk-limited ramp from rest with
/// acceleration `a` and jerk `j` reaches within `length`, by bisection.
pub(crate) fn reach_speed(length: f64, v_max: f64, a: f64, j: f64) -> f64 {
    let ramp_mm = |v: f64| 0.5 * v * change_time_s(v, a, j);
    if !(length > 0.0 && v_max > 0.0 && a > 0.0 && j > 0.0) || ramp_mm(v_max) <= length {
        return v_max;
    }
    bisect(0.0, v_max, SPEED_BISECTION_STEPS, |v| ramp_mm(v) <= length)
}

/// Rough time over a segment of `length` entered and left at `v_in`, speeding up on the
/// way to at most `v_top` with acceleration `a` and jerk `j`, s.
pub(crate) fn transit_time_s(length: f64, v_in: f64, v_top: f64, a: f64, j: f64) -> f64 {
    let v_top = v_top.max(v_in);
    // Distance to speed up from `v_in` to `p` and back.
    let there_and_back = |p: f64| (v_in + p) * change_time_s(p - v_in, a, j);
    let peak = if there_and_back(v_top) > length {
        bisect(v_in, v_top, SPEED_BISECTION_STEPS, |p| {
            there_and_back(p) <= length
        })
    } else {
        v_top
    };
    let cruise = (length - there_and_back(peak)).max(0.0);
    let cruise_s = if cruise > 0.0 { cruise / peak } else { 0.0 };
    2.0 * change_time_s(peak - v_in, a, j) + cruise_s
}
