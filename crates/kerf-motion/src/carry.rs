//! A speed-up carried on into the next section: the end state `(v1, a1 > 0)` a section
//! too short to finish its speed-up hands on (see [`MotionCore::carry_target`]).

use crate::lookahead::{BACKWARD_MARGIN, PLAN_MARGIN};
use crate::motion_core::{Mode, MotionCore};
use crate::reach::{reach, rise_reach, rise_with_peak, settle};

/// Share of the section the quickest rise of a carried speed-up may take (see
/// `MotionCore::carry_target`): the rest is the solver's room.
pub(crate) const CARRY_FILL: f64 = 0.98;
/// Least share of a carried speed-up's rise beyond the least one with its end
/// acceleration (see `MotionCore::carry_target`).
pub(crate) const CARRY_MIN_RISE: f64 = 0.05;
/// End accelerations tried for a carried speed-up, as shares of the acceleration limit:
/// `CARRY_SHARE_RATIO^k` for `k < CARRY_SHARE_STEPS`, highest first (down to a tenth; see
/// `MotionCore::carry_target`).
pub(crate) const CARRY_SHARE_RATIO: f64 = 0.85;
pub(crate) const CARRY_SHARE_STEPS: i32 = 15;

impl MotionCore {
    /// A speed-up that goes on into the next section: the end state `(v1, a1)`, `a1 > 0`,
    /// for the front section entered (or re-planned) at `(v0, a0)` with `rem` left, or
    /// `None` where the speed-up should end at `a = 0` as usual.
    ///
    /// A section whose end speed is bounded by the distance it has to speed up in would
    /// otherwise end its speed-up at `a = 0` and the next section start a new one: a stair
    /// whose every step costs the time the jerk needs to bring the acceleration down and up
    /// again (on the pieces of smoothed CAM code, a ramp from rest crosses two or three
    /// sections). Only at the base level of both sections and while no hold is pending.
    ///
    /// The speed `v1 + a1²/2j` at which the next section can have brought the acceleration
    /// to zero at its conservative jerk (that of its hard lookahead, which segments merged
    /// into it later never go below) must be within:
    /// - its hard and soft start speeds and its conservative feed: the envelope
    ///   `v + a²/2j ≤ v_max` under which the planner's budgets hold is kept (in this
    ///   section too, with its own jerk);
    /// - its hard and soft end speeds: it then reaches its end within its lookahead as from
    ///   an entry at `a = 0` within its hard start speed, once the acceleration is down,
    ///   which must fit in its length. (Without this the speed-up could overshoot what the
    ///   next section has to slow down to, and then lose more than it gained.)
    pub(crate) fn carry_target(
        &self,
        v0_mm_s: f64,
        a0_mm_s2: f64,
        rem_mm: f64,
    ) -> Option<(f64, f64)> {
        if self.mode != Mode::Run || self.sec_count < 2 || a0_mm_s2 < 0.0 {
            return None;
        }
        let ovr = self.override_factor;
        let sec = self.sec(self.sec_head);
        let next = self.sec(self.sec_head + 1);
        if sec.boosted
            || next.wants_boost(ovr)
            || next.hard_start_mm_s < 0.0
            || next.soft_start_mm_s < 0.0
        {
            return None;
        }
        let (v_machine_mm_s, accel_mm_s2, jerk_mm_s3) = sec.limits(false);
        let v_max_mm_s = sec.v_eff(ovr, false).min(v_machine_mm_s);
        let want_mm_s = self.want_end();
        let (v_at_mm_s, d0_mm) = settle(v0_mm_s, a0_mm_s2, jerk_mm_s3);
        let d_mm = rem_mm * PLAN_MARGIN;
        // The end speed with `a = 0`: the carry reaches about as much before its own room.
        let plain_mm_s = reach(v_at_mm_s, d_mm - d0_mm, accel_mm_s2, jerk_mm_s3);
        if d0_mm >= d_mm || v_at_mm_s >= want_mm_s || plain_mm_s >= want_mm_s {
            return None;
        }
        let (c_accel_mm_s2, c_jerk_mm_s3) = next.c_accel_jerk();
        let next_top_mm_s = next
            .hard_start_mm_s
            .min(next.soft_start_mm_s)
            .min(next.v_eff(ovr, false))
            .min(next.c_feed_mm_s * ovr)
            .min(next.hard_end_mm_s)
            .min(next.soft_end_mm_s);
        // The next section brings the acceleration to zero within its length.
        let settles = |v1_mm_s: f64, a1_mm_s2: f64| {
            settle(v1_mm_s, a1_mm_s2, c_jerk_mm_s3).1 <= next.length_mm * BACKWARD_MARGIN
        };
        // The highest end speed reachable with end acceleration `a1`: the quickest rise
        // filling `CARRY_FILL` of the section, so that the solver meets a target inside what
        // is reachable, not on its edge (where it failed in the property tests), and more
        // than the mere rise and fall of the acceleration. None when even that does not fit.
        let top = want_mm_s.min(v_max_mm_s);
        let reach_with = |a1_mm_s2: f64| {
            let v1_mm_s = rise_reach(
                v0_mm_s,
                a0_mm_s2,
                a1_mm_s2,
                CARRY_FILL * d_mm,
                accel_mm_s2,
                jerk_mm_s3,
            )?
            .min(top);
            let least = rise_with_peak(
                v0_mm_s,
                a0_mm_s2,
                a1_mm_s2,
                a0_mm_s2.max(a1_mm_s2),
                jerk_mm_s3,
            )
            .1 - v0_mm_s;
            (v1_mm_s - v0_mm_s - least > CARRY_MIN_RISE * (v1_mm_s - v0_mm_s)).then_some(v1_mm_s)
        };
        // The end speed rises with `a1`, and so does the room `a1²/2j` it needs above it,
        // in this section and the next, and the distance the next one needs to bring it to
        // zero: the highest share of the limit on a geometric grid that keeps within them,
        // by bisection on the grid (each condition fails from some share up), so that the
        // cycle does a handful of closed-form rises at most.
        let a_top_mm_s2 = accel_mm_s2.min(c_accel_mm_s2);
        let room = |v: f64, a1_mm_s2: f64| {
            v + a1_mm_s2 * a1_mm_s2 / (2.0 * jerk_mm_s3) <= v_max_mm_s
                && v + a1_mm_s2 * a1_mm_s2 / (2.0 * c_jerk_mm_s3) <= next_top_mm_s
        };
        let carry_at = |k: i32| {
            let a1_mm_s2 = CARRY_SHARE_RATIO.powi(k) * a_top_mm_s2;
            // A pre-check without the rise: no room even above the plain end speed.
            if !room(plain_mm_s, a1_mm_s2) {
                return None;
            }
            reach_with(a1_mm_s2)
                .filter(|&v1_mm_s| room(v1_mm_s, a1_mm_s2) && settles(v1_mm_s, a1_mm_s2))
                .map(|v1_mm_s| (v1_mm_s, a1_mm_s2))
        };
        let (mut bad, mut good) = (-1, CARRY_SHARE_STEPS - 1);
        let mut found = carry_at(good)?;
        while good - bad > 1 {
            let mid = (bad + good) / 2;
            match carry_at(mid) {
                Some(c) => (good, found) = (mid, c),
                None => bad = mid,
            }
        }
        Some(found)
    }
}
