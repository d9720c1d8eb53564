//! A speed-up or slow-down carried on into the next section: the end state `(v1, a1)`,
//! `a1 ≠ 0`, a section hands on where ending at `a = 0` would make a stair (see
//! [`MotionCore::carry_target`]).

use crate::lookahead::{BACKWARD_MARGIN, PLAN_MARGIN};
use crate::motion_core::{Mode, MotionCore};
use crate::reach::{
    bisect, change_distance, fall_distance, falls_within, reach, rise_reach, rise_with_peak, settle,
};

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
/// Share of the envelope `v + a²/2j ≤ v_max` a carried slow-down's end state keeps within
/// (see `MotionCore::carry_target`).
const ENVELOPE_INSIDE: f64 = 1.0 - 1e-6;
/// Bisection steps on a carried slow-down's end speed (see `MotionCore::carry_target`):
/// to 1/65,536 of its range, as `RISE_STEPS`.
const CARRY_SPEED_STEPS: usize = 16;

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
    ///
    /// Where no speed-up is carried and the next section slows down further, a slow-down
    /// may be carried instead: `(v1, a1)` with `a1 < 0` (see `carry_down`).
    pub(crate) fn carry_target(
        &self,
        v0_mm_s: f64,
        a0_mm_s2: f64,
        rem_mm: f64,
    ) -> Option<(f64, f64)> {
        if self.mode != Mode::Run || self.sec_count < 2 {
            return None;
        }
        // Both kinds only at the base level of both sections, and only once the next
        // section's lookahead has been computed.
        let ovr = self.override_factor;
        let next = self.sec(self.sec_head + 1);
        if self.sec(self.sec_head).boosted
            || next.wants_boost(ovr)
            || next.hard_start_mm_s < 0.0
            || next.soft_start_mm_s < 0.0
        {
            return None;
        }
        if a0_mm_s2 >= 0.0
            && let Some(up) = self.carry_up(v0_mm_s, a0_mm_s2, rem_mm)
        {
            return Some(up);
        }
        self.carry_down(v0_mm_s, a0_mm_s2, rem_mm)
    }

    /// The speed-up half of [`MotionCore::carry_target`] (`a0 ≥ 0`).
    fn carry_up(&self, v0_mm_s: f64, a0_mm_s2: f64, rem_mm: f64) -> Option<(f64, f64)> {
        let ovr = self.override_factor;
        let sec = self.sec(self.sec_head);
        let next = self.sec(self.sec_head + 1);
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
        highest_share(carry_at)
    }

    /// A slow-down that goes on into the next section: the end state `(v1, a1)`, `a1 < 0`,
    /// for the front section entered (or re-planned) at `(v0, a0)`, `a0 ≤ 0`, with `rem`
    /// left, or `None`.
    ///
    /// Where the next section slows down further (its end speed below its start speed),
    /// ending this one at `a = 0` makes a stair: the deceleration comes down to zero at the
    /// boundary and builds up again after it. Carried on, the boundary is crossed faster,
    /// at the highest `v1` from which the quickest fall on to the next section's end
    /// speed, at its conservative limits, fits in its length: the lookahead's guarantee
    /// (every section ends within its hard end speed, so the queue can stop within itself)
    /// holds as for an entry at `a = 0` within its hard start speed, which `v1` may exceed.
    /// Within:
    /// - the envelope `v + a²/2j ≤ v_max` under which the planner's budgets hold, in this
    ///   section (its jerk) and the next (its conservative jerk and speeds), and under the
    ///   junction's cap as well (as a carried speed-up keeps under the next section's hard
    ///   start speed, which is within that cap): a corner whose cap is low is crossed
    ///   with little acceleration, whose step in direction there is a step in the axes'
    ///   acceleration;
    /// - where the next section is the queue's tail, its hard start speed too: a segment
    ///   slightly slower than its conservative speed may still join it, down to that speed
    ///   ([`MERGE_RATIO_SLOWER`](crate::MERGE_RATIO_SLOWER));
    /// - this section: the quickest way to `(v1, a1)` (a fall, or a settle, a rise and a
    ///   fall) fits in `CARRY_FILL` of what is left.
    ///
    /// Only at the base level of both sections, and only where the next section, once it
    /// has brought the acceleration to zero (at its conservative jerk), is not below the
    /// end speed this section would aim at with `a = 0`.
    fn carry_down(&self, v0_mm_s: f64, a0_mm_s2: f64, rem_mm: f64) -> Option<(f64, f64)> {
        if a0_mm_s2 > 0.0 {
            return None;
        }
        let ovr = self.override_factor;
        let sec = self.sec(self.sec_head);
        let next = self.sec(self.sec_head + 1);
        let want_mm_s = self.want_end();
        let next_end_mm_s = next.hard_end_mm_s.min(next.soft_end_mm_s);
        if next_end_mm_s >= want_mm_s {
            return None;
        }
        let (v_machine_mm_s, accel_mm_s2, jerk_mm_s3) = sec.limits(false);
        let v_max_mm_s = sec.v_eff(ovr, false).min(v_machine_mm_s);
        let (c_accel_mm_s2, c_jerk_mm_s3) = next.c_accel_jerk();
        let tail = self.sec_count == 2;
        let next_env_mm_s = next
            .v_eff(ovr, false)
            .min(next.c_v_mm_s)
            .min(next.c_feed_mm_s * ovr)
            .min(next.start_cap_mm_s)
            .min(if tail {
                next.hard_start_mm_s
            } else {
                f64::INFINITY
            });
        let d_mm = rem_mm * PLAN_MARGIN * CARRY_FILL;
        let (v_at_mm_s, d0_mm) = settle(v0_mm_s, a0_mm_s2, jerk_mm_s3);
        if d0_mm >= d_mm || v_at_mm_s > v_max_mm_s {
            return None;
        }
        let room_mm = next.length_mm * BACKWARD_MARGIN.min(PLAN_MARGIN) * CARRY_FILL;
        let a_top_mm_s2 = accel_mm_s2.min(c_accel_mm_s2);
        let carry_at = |k: i32| {
            let b_mm_s2 = CARRY_SHARE_RATIO.powi(k) * a_top_mm_s2;
            let a1_mm_s2 = -b_mm_s2;
            let (lift_mm_s, c_lift_mm_s) = (
                b_mm_s2 * b_mm_s2 / (2.0 * jerk_mm_s3),
                b_mm_s2 * b_mm_s2 / (2.0 * c_jerk_mm_s3),
            );
            // Inside the envelopes by a hair: the solver refuses an end state right on its
            // speed limit's envelope (found by the extreme machines' sweep).
            let cap_mm_s = (v_max_mm_s * ENVELOPE_INSIDE - lift_mm_s)
                .min(next_env_mm_s * ENVELOPE_INSIDE - c_lift_mm_s);
            // Not below the wanted end speed once the next section has brought the
            // acceleration to zero: where it would rather not slow down at once (it is
            // long), the carry must not leave it slower than an entry at `a = 0` would.
            let least_mm_s = want_mm_s + c_lift_mm_s;
            if cap_mm_s < least_mm_s {
                return None;
            }
            // The next section falls on to its end speed within its length (at its
            // conservative limits, which every segment in it has at least), and to its
            // hard end speed, which its start checks (`choose_level`); the fall grows
            // with the speed it starts from.
            let next_fits = |v1_mm_s: f64| {
                [next_end_mm_s, next.hard_end_mm_s]
                    .into_iter()
                    .all(|v_end_mm_s| {
                        falls_within(
                            v1_mm_s,
                            a1_mm_s2,
                            v_end_mm_s,
                            room_mm,
                            c_accel_mm_s2,
                            c_jerk_mm_s3,
                        )
                    })
            };
            let v1_mm_s = if next_fits(cap_mm_s) {
                cap_mm_s
            } else if next_fits(least_mm_s) {
                bisect(least_mm_s, cap_mm_s, CARRY_SPEED_STEPS, next_fits)
            } else {
                return None;
            };
            // This section. Where the speed it settles to from the entry state is at least
            // `v1 + a1²/2j` (the least speed a fall to `(v1, a1)` starts from at `a = 0`),
            // every distance from the quickest fall on is a profile (the fall, held back
            // by less, by a cruise, by a rise); else the distances that are split in two:
            // falls that never bring the acceleration up to zero, and, from a settle, a rise
            // to that least speed and the fall on, profiles that rise first. Only the
            // second kind is used, whose least distance is known in closed form (the
            // solver refuses the gap between them).
            let need_mm_s = v1_mm_s + lift_mm_s;
            let least_mm = if v_at_mm_s >= need_mm_s {
                fall_distance(
                    v0_mm_s,
                    a0_mm_s2,
                    v1_mm_s,
                    a1_mm_s2,
                    accel_mm_s2,
                    jerk_mm_s3,
                )?
            } else {
                d0_mm
                    + change_distance(v_at_mm_s, need_mm_s, accel_mm_s2, jerk_mm_s3)
                    + fall_distance(need_mm_s, 0.0, v1_mm_s, a1_mm_s2, accel_mm_s2, jerk_mm_s3)?
            };
            (least_mm <= d_mm).then_some((v1_mm_s, a1_mm_s2))
        };
        highest_share(carry_at)
    }
}

/// The carry at the highest share of the acceleration limit on the grid
/// `CARRY_SHARE_RATIO^k`, `k < CARRY_SHARE_STEPS`, that `carry_at(k)` finds, by bisection
/// on the grid (each condition of a carry fails from some share up): a handful of
/// evaluations at most. `None` when even the lowest share has none.
fn highest_share(carry_at: impl Fn(i32) -> Option<(f64, f64)>) -> Option<(f64, f64)> {
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
