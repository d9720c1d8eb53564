//! A closed-form jerk-limited path profile: the motion core's own fallback when the
//! solver cannot plan a section.
//!
//! [`JerkProfile`] is a sequence of at most eight phases of constant jerk: where it is
//! entered accelerating (`a0 ≠ 0`, a speed-up carried over from the section before), a
//! first phase at the jerk limit brings the acceleration to zero; then a speed change to
//! a cruise speed, a cruise, and a speed change to `v1`. Each speed change is the
//! symmetric jerk-limited S-curve with `a = 0` at both ends (the same curve
//! [`crate::change_distance`] measures), so the profile never exceeds the acceleration
//! and jerk it was built with, and after its first phase its speed stays between the
//! speeds it starts and ends its speed changes at and the cruise speed (the first phase
//! moves the speed by `a0²/2j`, which can take it above the cruise ceiling; it then comes
//! down to it). It is built in closed form (plus a bisection on the cruise speed) without
//! allocation, so it is safe to build inside `step()`.

use crate::change_distance;
use kerf_geom::ramp::bisect;

/// Most phases of a profile: the entry acceleration brought to zero (1), up (3), cruise
/// (1), down (3).
const MAX_PHASES: usize = 8;

/// A piecewise-constant-jerk profile `s(t)` from `s = 0`, with the state at the start
/// of every phase precomputed.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct JerkProfile {
    phases: usize,
    /// Start time of each phase, s (`start_s[phases]` is the duration).
    start_s: [f64; MAX_PHASES + 1],
    jerk: [f64; MAX_PHASES],
    p: [f64; MAX_PHASES + 1],
    v: [f64; MAX_PHASES + 1],
    a: [f64; MAX_PHASES + 1],
}

impl JerkProfile {
    /// The profile over `distance` from speed `v0` to speed `v1` (both with `a = 0`)
    /// through a cruise at the speed closest to `v_max` that fits, with acceleration
    /// `accel` and jerk `jerk`: the highest in `[max(v0, v1), v_max]` when the profile
    /// starts at or below `v_max`, else (entered above it) `v_max` itself or, if the
    /// distance is too short to come down to it and on to `v1`, the lowest speed above it
    /// that fits. `None` when even the direct change from `v0` to `v1` needs more than
    /// `distance` (the end speed is out of reach) or an input is not finite and positive
    /// where it must be.
    pub fn cruise_between(
        v0: f64,
        v1: f64,
        distance: f64,
        v_max: f64,
        accel: f64,
        jerk: f64,
    ) -> Option<Self> {
        Self::cruise_between_from(v0, 0.0, v1, distance, v_max, accel, jerk)
    }

    /// [`JerkProfile::cruise_between`] entered with acceleration `a0` (at most `accel` in
    /// magnitude): a first phase at the jerk limit brings it to zero, then the profile goes
    /// on from the speed that phase ends at (which may be above `v_max`: it then comes down
    /// to it as from any entry above the ceiling). `None` also when that first phase does
    /// not fit in `distance` or would reverse.
    pub fn cruise_between_from(
        v0: f64,
        a0: f64,
        v1: f64,
        distance: f64,
        v_max: f64,
        accel: f64,
        jerk: f64,
    ) -> Option<Self> {
        let finite = [v0, a0, v1, distance, v_max, accel, jerk]
            .iter()
            .all(|x| x.is_finite());
        if !finite
            || v0 < 0.0
            || v1 < 0.0
            || distance <= 0.0
            || accel <= 0.0
            || jerk <= 0.0
            || a0.abs() > accel * (1.0 + 1e-9)
        {
            return None;
        }
        let mut prof = JerkProfile::default();
        prof.v[0] = v0;
        prof.a[0] = a0;
        if a0 != 0.0 {
            prof.push_phase(a0.abs() / jerk, -a0.signum() * jerk);
            prof.a[prof.phases] = 0.0;
        }
        let (d0, v0) = (prof.p[prof.phases], prof.v[prof.phases]);
        if v0 < 0.0 || d0 >= distance {
            return None;
        }
        let distance = distance - d0;
        let need =
            |vc: f64| change_distance(v0, vc, accel, jerk) + change_distance(vc, v1, accel, jerk);
        let lo = v0.max(v1);
        if need(lo) > distance {
            return None;
        }
        let vc = if v0 > v_max && v_max >= v1 {
            // Entered above the ceiling: come down to it if the distance allows, else as
            // close to it as it allows (`need(v0)` fits, checked above).
            if need(v_max) <= distance {
                v_max
            } else {
                bisect(v0, v_max, 60, |vc| need(vc) <= distance)
            }
        } else {
            let hi = v_max.max(lo);
            if need(hi) <= distance {
                hi
            } else {
                // `need` grows with the cruise speed above both end speeds.
                bisect(lo, hi, 60, |vc| need(vc) <= distance)
            }
        };
        if vc <= 0.0 {
            return None;
        }
        prof.push_change(v0, vc, accel, jerk);
        let cruise_s = (distance - need(vc)).max(0.0) / vc;
        prof.push_phase(cruise_s, 0.0);
        prof.push_change(vc, v1, accel, jerk);
        Some(prof)
    }

    /// Appends the S-curve from the current end speed `from` to `to`.
    fn push_change(&mut self, from: f64, to: f64, accel: f64, jerk: f64) {
        let dv = to - from;
        if dv == 0.0 {
            return;
        }
        let sign = dv.signum();
        let dv = dv.abs();
        let (ramp_s, hold_s) = if dv * jerk <= accel * accel {
            ((dv / jerk).sqrt(), 0.0)
        } else {
            (accel / jerk, dv / accel - accel / jerk)
        };
        self.push_phase(ramp_s, sign * jerk);
        self.push_phase(hold_s, 0.0);
        self.push_phase(ramp_s, -sign * jerk);
        // The acceleration is zero at the end of a change by construction; remove the
        // rounding so the next phase starts exactly at rest acceleration.
        self.a[self.phases] = 0.0;
        // Likewise the speed is the target speed.
        self.v[self.phases] = to;
    }

    fn push_phase(&mut self, duration_s: f64, jerk: f64) {
        if duration_s <= 0.0 || self.phases == MAX_PHASES {
            return;
        }
        let i = self.phases;
        let (p, v, a) = Self::integrate(self.p[i], self.v[i], self.a[i], jerk, duration_s);
        self.jerk[i] = jerk;
        self.start_s[i + 1] = self.start_s[i] + duration_s;
        self.p[i + 1] = p;
        self.v[i + 1] = v;
        self.a[i + 1] = a;
        self.phases += 1;
    }

    fn integrate(p: f64, v: f64, a: f64, jerk: f64, t: f64) -> (f64, f64, f64) {
        (
            p + t * (v + t * (a / 2.0 + t * jerk / 6.0)),
            v + t * (a + t * jerk / 2.0),
            a + t * jerk,
        )
    }

    /// Duration, s.
    pub fn duration_s(&self) -> f64 {
        self.start_s[self.phases]
    }

    /// Distance covered at the end.
    pub fn distance(&self) -> f64 {
        self.p[self.phases]
    }

    /// Position, speed and acceleration at time `t` (clamped to the profile).
    pub fn at(&self, t: f64) -> (f64, f64, f64) {
        let t = t.clamp(0.0, self.duration_s());
        let mut i = 0;
        while i + 1 < self.phases && t >= self.start_s[i + 1] {
            i += 1;
        }
        if self.phases == 0 {
            return (0.0, self.v[0], 0.0);
        }
        Self::integrate(
            self.p[i],
            self.v[i],
            self.a[i],
            self.jerk[i],
            t - self.start_s[i],
        )
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A fixed-seed source of log-uniform numbers in `[lo, hi]` (xorshift64) for the
    /// sweeps of the unit tests.
    pub(crate) fn log_uniform_source(seed: u64) -> impl FnMut(f64, f64) -> f64 {
        let mut state = seed;
        move |lo: f64, hi: f64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let unit = (state >> 11) as f64 / (1u64 << 53) as f64;
            (lo.ln() + unit * (hi.ln() - lo.ln())).exp()
        }
    }

    /// Checks a profile by sampling: it reaches the distance and the end speed, never
    /// exceeds the limits, never goes backwards, and its jerk by finite differences of the
    /// sampled positions is within the limit.
    fn check(p: &JerkProfile, v0: f64, v1: f64, d: f64, vmax: f64, accel: f64, jerk: f64) {
        let dur = p.duration_s();
        assert!(dur.is_finite() && dur > 0.0);
        let (pe, ve, ae) = p.at(dur);
        assert!((pe - d).abs() <= 1e-9 * d.max(1.0), "end {pe} vs {d}");
        assert!(
            (ve - v1).abs() <= 1e-9 * v1.max(vmax).max(1.0),
            "end speed {ve} vs {v1}"
        );
        // Times are absolute: a phase of microseconds late in a long profile carries the
        // rounding of its start time (a few ulp of the duration) times the jerk.
        let t_round = 8.0 * f64::EPSILON * dur;
        assert!(
            ae.abs() <= 1e-9 * accel + jerk * t_round,
            "end acceleration {ae} {p:?}"
        );
        let n = 4000;
        let dt = dur / n as f64;
        let mut prev = [p.at(0.0).0; 4];
        for k in 0..=n {
            let (s, v, a) = p.at(k as f64 * dt);
            assert!(v >= -1e-9 * vmax.max(1.0), "backwards: v {v}");
            assert!(
                v <= vmax.max(v0).max(v1) * (1.0 + 1e-9) + 1e-12,
                "v {v} > {vmax}"
            );
            assert!(a.abs() <= accel * (1.0 + 1e-9), "a {a} > {accel}");
            assert!(s >= prev[3] - 1e-12 * d.max(1.0));
            prev = [prev[1], prev[2], prev[3], s];
            if k >= 3 {
                let j = (prev[3] - 3.0 * prev[2] + 3.0 * prev[1] - prev[0]) / (dt * dt * dt);
                let noise = 16.0 * f64::EPSILON * d.max(1.0) / (dt * dt * dt);
                assert!(j.abs() <= jerk * 1.0001 + noise, "jerk {j} > {jerk}");
            }
        }
    }

    #[test]
    fn the_reported_helix_input_plans_at_rest_to_rest() {
        // The inputs the solver failed on for the helix on a fast machine.
        let (d, vmax, a, j) = (
            5.068011275050498,
            50.0,
            19000.295410786068,
            9399969.739963412,
        );
        let p = JerkProfile::cruise_between(0.0, 0.0, d, vmax, a, j).unwrap();
        check(&p, 0.0, 0.0, d, vmax, a, j);
        // It cruises at the feed: the time is the distance at the feed plus one
        // acceleration ramp (a/j + v/a, by symmetry of the two ramps).
        let expect = d / vmax + vmax / a + a / j;
        assert!((p.duration_s() - expect).abs() < 1e-9, "{}", p.duration_s());
    }

    #[test]
    fn short_distances_peak_below_the_feed() {
        let (vmax, a, j) = (100.0, 1000.0, 10000.0);
        // Too short to reach the feed: the peak is where the up and down ramps meet.
        let d = 0.5;
        let p = JerkProfile::cruise_between(0.0, 0.0, d, vmax, a, j).unwrap();
        check(&p, 0.0, 0.0, d, vmax, a, j);
        let peak = (0..=1000)
            .map(|k| p.at(k as f64 * p.duration_s() / 1000.0).1)
            .fold(0.0, f64::max);
        // Rest to rest over d with only jerk phases: d = 2 v t, v = j t² → v = (j d²/4)^(1/3).
        let expect = (j * d * d / 4.0).cbrt();
        assert!(
            peak < vmax && (peak - expect).abs() < 1e-3 * expect,
            "{peak} {expect}"
        );
    }

    #[test]
    fn unreachable_end_speeds_are_refused() {
        // Stopping from 100 mm/s takes a fixed distance; just under it is refused.
        let (a, j) = (1000.0, 10000.0);
        let need = change_distance(100.0, 0.0, a, j);
        assert!(JerkProfile::cruise_between(100.0, 0.0, need * 0.99, 200.0, a, j).is_none());
        let p = JerkProfile::cruise_between(100.0, 0.0, need * 1.01, 200.0, a, j).unwrap();
        check(&p, 100.0, 0.0, need * 1.01, 200.0, a, j);
        assert!(JerkProfile::cruise_between(0.0, 0.0, 1.0, 10.0, f64::NAN, j).is_none());
        assert!(JerkProfile::cruise_between(0.0, 0.0, 0.0, 10.0, a, j).is_none());
    }

    #[test]
    fn entered_above_the_ceiling_comes_down_to_it() {
        // The sweep's escape: entered at 4.75 mm/s with the feed at 1.35 mm/s and 0.0193 mm
        // to go. Coming down takes change_distance(4.75, 1.35) = 0.0185 mm; the rest is a
        // cruise at the feed.
        let (v0, v1, d, a, j) = (
            4.747193270503335,
            1.3466370415100362,
            0.019271730682741104,
            1361.1076378755872,
            370392.22397395375,
        );
        let p = JerkProfile::cruise_between(v0, v1, d, v1, a, j).unwrap();
        check(&p, v0, v1, d, v1, a, j);
        let down = change_distance(v0, v1, a, j);
        let dv = v0 - v1;
        let t_down = 2.0 * (dv / j).sqrt();
        let expect = t_down + (d - down) / v1;
        assert!(
            (p.duration_s() - expect).abs() < 1e-12,
            "{} {expect}",
            p.duration_s()
        );
        // Too short to come all the way down first: the cruise stays as close to the
        // ceiling as the distance allows, and the end speed is still met.
        // Shorter than the direct change: out of reach.
        assert!(JerkProfile::cruise_between(v0, v1, down * 0.9, v1, a, j).is_none());
        // Too short to come down to the ceiling (1.5) before going on down to 1.0: the
        // profile still ends at 1.0 within the distance and never speeds up.
        let direct = change_distance(v0, 1.0, a, j);
        let via = change_distance(v0, 1.5, a, j) + change_distance(1.5, 1.0, a, j);
        assert!(via > direct);
        let d3 = 0.5 * (direct + via);
        let p = JerkProfile::cruise_between(v0, 1.0, d3, 1.5, a, j).unwrap();
        check(&p, v0, 1.0, d3, 1.5, a, j);
    }

    #[test]
    fn random_inputs_hold_their_limits() {
        // A fixed-seed sweep over the range of machines the configuration accepts.
        let mut log_uniform = log_uniform_source(0x2545_F491_4F6C_DD1D);
        let mut built = 0;
        for _ in 0..400 {
            let vmax = log_uniform(1.0, 5000.0);
            let a = log_uniform(100.0, 1e6);
            let j = log_uniform(1e3, 1e9);
            let d = log_uniform(1e-4, 1000.0);
            let v0 = vmax * log_uniform(1e-3, 1.0) * if d > 1.0 { 1.0 } else { 0.0 };
            let v1 = vmax * log_uniform(1e-3, 1.0) * if d < 10.0 { 0.0 } else { 1.0 };
            if let Some(p) = JerkProfile::cruise_between(v0, v1, d, vmax, a, j) {
                check(&p, v0, v1, d, vmax, a, j);
                built += 1;
            } else {
                assert!(change_distance(v0, v1, a, j) > d * (1.0 - 1e-12));
            }
        }
        assert!(built > 200, "{built}");
    }

    #[test]
    fn entered_accelerating_it_starts_from_that_acceleration_and_holds_its_limits() {
        // A section entered with a speed-up (or slow-down) carried over: the profile starts
        // with the entry acceleration (no step in it) and ends at the end speed with
        // `a = 0`, within the limits, the speed ceiling raised only by what bringing the
        // acceleration to zero at the jerk limit adds (`a0²/2j`).
        let mut log_uniform = log_uniform_source(0x9E37_79B9_7F4A_7C15);
        let mut built = 0;
        for k in 0..400 {
            let vmax = log_uniform(1.0, 5000.0);
            let a = log_uniform(100.0, 1e6);
            let j = log_uniform(1e3, 1e9);
            let d = log_uniform(1e-4, 1000.0);
            let v0 = vmax * log_uniform(1e-3, 1.0);
            let v1 = vmax * log_uniform(1e-3, 1.0) * if d < 10.0 { 0.0 } else { 1.0 };
            // Within the envelope of the entry (the speed can neither pass the ceiling nor
            // reverse while the acceleration comes down).
            let a_env = (2.0 * j * if k % 2 == 0 { vmax - v0 } else { v0 }).sqrt();
            let a0 = a.min(a_env) * log_uniform(1e-3, 1.0) * if k % 2 == 0 { 1.0 } else { -1.0 };
            let Some(p) = JerkProfile::cruise_between_from(v0, a0, v1, d, vmax, a, j) else {
                // Refused only where bringing the acceleration to zero and then changing to
                // the end speed does not fit.
                let t = a0.abs() / j;
                let v_at = v0 + a0 * a0.abs() / (2.0 * j);
                let d0 = v0 * t + a0 * t * t / 2.0 - a0.signum() * j * t * t * t / 6.0;
                assert!(d0 + change_distance(v_at, v1, a, j) > d * (1.0 - 1e-12));
                continue;
            };
            let (_, ve, ae) = p.at(0.0);
            assert!((ve - v0).abs() <= 1e-12 * v0 && (ae - a0).abs() <= 1e-12 * a.max(1.0));
            check(&p, v0, v1, d, vmax, a, j);
            built += 1;
        }
        assert!(built > 200, "{built}");
    }
}
