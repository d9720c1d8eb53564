//! The lookahead: the backward pass over the sections that fixes their hard and soft
//! boundary speeds, and the end speed the front section aims at.

use kerf_geom::entry_speed;
use kerf_geom::ramp::bisect;

use crate::motion_core::MotionCore;
use crate::reach::{change_distance, fall_distance, reach, settle};

pub(crate) use kerf_geom::ramp::BACKWARD_MARGIN;
/// Fraction of the remaining distance a profile plan may use in its own checks.
pub(crate) const PLAN_MARGIN: f64 = 0.999;
/// Most sections one `push` revisits in the backward pass (bounds its work).
pub(crate) const MAX_BACKWARD_SECTIONS: usize = 256;
/// Most sections after the front one [`MotionCore::lookahead_settled`] looks at (bounds
/// its work in the cycle).
const SETTLED_SCAN_SECTIONS: u64 = 64;

impl MotionCore {
    /// Recomputes the lookahead speeds from the tail until they stop changing.
    ///
    /// `max_sections` bounds the work: values left stale beyond it are lower than they
    /// could be (hard speeds only grow as the queue grows), so stopping early is safe.
    pub(crate) fn backward_pass(&mut self, max_sections: usize) {
        if self.sec_count == 0 {
            return;
        }
        let mut visited = 0;
        let ovr = self.override_factor;
        let first = self.sec_head;
        let mut k = self.sec_head + self.sec_count - 1;
        let mut hard_end = 0.0;
        let mut hard_end_boost = 0.0;
        let mut soft_end = 0.0;
        loop {
            let is_running = k == first && self.running;
            let s = self.sec_mut(k);
            s.hard_end_mm_s = hard_end;
            s.hard_end_boost_mm_s = hard_end_boost;
            s.soft_end_mm_s = soft_end;
            if is_running {
                // The running section's limits are frozen; a higher end speed is taken by
                // re-planning its profile.
                let hard = s.hard_end_at(s.boosted);
                if hard.min(soft_end) > self.traj_end_v_mm_s * 1.001 + 1e-9 {
                    self.replan = true;
                }
                break;
            }
            let length_mm = s.length_mm;
            let (hard_cap, hard_boost_cap) = s.hard_start_caps();
            let hard = entry_speed(hard_cap, hard_end, length_mm, s.c_accel_jerk());
            let hard_boost = entry_speed(
                hard_boost_cap,
                hard_end_boost,
                length_mm,
                (s.c_accel_boost_mm_s2, s.c_jerk_boost_mm_s3),
            );
            let level = s.wants_boost(ovr);
            let (_, a, j) = s.limits(level);
            let soft = entry_speed(
                s.soft_start_cap(ovr, level, if level { hard_boost } else { hard }),
                soft_end,
                length_mm,
                (a, j),
            );
            let changed = hard != s.hard_start_mm_s
                || hard_boost != s.hard_start_boost_mm_s
                || soft != s.soft_start_mm_s;
            s.hard_start_mm_s = hard;
            s.hard_start_boost_mm_s = hard_boost;
            s.soft_start_mm_s = soft;
            visited += 1;
            if !changed || k == first || visited >= max_sections {
                break;
            }
            hard_end = hard;
            hard_end_boost = hard_boost;
            soft_end = soft;
            k -= 1;
        }
    }

    /// `true` when a section after the front one and before the tail has start speeds
    /// bound by its own limits and its junction cap alone (hard, hard at the boost level,
    /// and soft at the present override), not by the stop at the queue's end.
    ///
    /// No segment pushed later can then change the lookahead of the sections before it:
    /// the backward pass of every later push stops at that section (its speeds are at
    /// their caps: hard speeds only grow as the queue grows, and soft ones at a given
    /// override too), and later segments join the tail section, never the front one. So
    /// the motion through the sections before it is the same whether the rest of the
    /// program is queued now or later, as long as such a section stays ahead of the
    /// motion; a source that cannot hand over the whole lookahead at once (the daemon's
    /// planner) may start the motion then. Looks at most 64 sections after the front
    /// one, a few comparisons each, and allocates nothing.
    pub fn lookahead_settled(&self) -> bool {
        if self.sec_count < 3 {
            return false;
        }
        let ovr = self.override_factor;
        let tail = self.sec_head + self.sec_count - 1;
        let last = tail.min(self.sec_head + 1 + SETTLED_SCAN_SECTIONS);
        // The caps are the backward pass's own terms (`Section::hard_start_caps`,
        // `soft_start_cap`): a start speed equal to its cap is final.
        (self.sec_head + 1..last).any(|k| {
            let s = self.sec(k);
            let (hard, hard_boost) = s.hard_start_caps();
            let level = s.wants_boost(ovr);
            let soft = s.soft_start_cap(ovr, level, if level { hard_boost } else { hard });
            s.hard_start_mm_s == hard
                && s.hard_start_boost_mm_s == hard_boost
                && s.soft_start_mm_s == soft
        })
    }

    /// Recomputes the whole soft lookahead (after an override change).
    pub(crate) fn full_soft_pass(&mut self) {
        // Forcing a change in every section makes the pass run to the front.
        for k in self.sec_head..self.sec_head + self.sec_count {
            self.sec_mut(k).soft_start_mm_s = -1.0;
        }
        self.backward_pass(usize::MAX);
    }

    /// Target end speed of the front section from state `(v0, a = 0)` with `rem` left,
    /// and whether it is certainly reachable.
    pub(crate) fn end_target(&self, v0_mm_s: f64, rem_mm: f64) -> (f64, bool) {
        let sec = self.sec(self.sec_head);
        let hard = sec.hard_end_at(sec.boosted);
        let want_mm_s = self.want_end();
        let d_mm = rem_mm * PLAN_MARGIN;
        let (_, a, j) = sec.limits(sec.boosted);
        let fits = |v1_mm_s: f64| change_distance(v0_mm_s, v1_mm_s, a, j) <= d_mm;
        if v0_mm_s < want_mm_s {
            return (want_mm_s.min(reach(v0_mm_s, d_mm, a, j)), true);
        }
        if fits(want_mm_s) {
            return (want_mm_s, true);
        }
        // The soft target is out of reach; slowing down partially can be out of reach too
        // while a full stop is not (see [`reach_back`](crate::reach::reach_back)). Take the lowest reachable speed at
        // or above the soft target, else the hard end speed, else a stop.
        let top = v0_mm_s.min(hard);
        if v0_mm_s <= hard {
            return (bisect(top, want_mm_s, 30, fits), false);
        }
        if fits(hard) {
            (hard, false)
        } else {
            (0.0, false)
        }
    }

    /// [`MotionCore::end_target`] from state `(v0, a0)` with `rem` left: with a slow-down
    /// carried in (`a0 < 0`, see `MotionCore::carry_target`), the wanted end speed where
    /// the quickest fall on to it fits (the continued slow-down the carry was checked
    /// for); else the target from where the acceleration has come to zero at the running
    /// level's jerk, as for any entry.
    pub(crate) fn end_target_from(&self, v0_mm_s: f64, a0_mm_s2: f64, rem_mm: f64) -> (f64, bool) {
        let sec = self.sec(self.sec_head);
        let (_, a, j) = sec.limits(sec.boosted);
        let (v_at_mm_s, d0_mm) = settle(v0_mm_s, a0_mm_s2, j);
        if a0_mm_s2 < 0.0 {
            let want_mm_s = self.want_end();
            if want_mm_s <= v_at_mm_s
                && fall_distance(v0_mm_s, a0_mm_s2, want_mm_s, 0.0, a, j)
                    .is_some_and(|d_mm| d_mm <= rem_mm * PLAN_MARGIN)
            {
                return (want_mm_s, true);
            }
        }
        self.end_target(v_at_mm_s.max(0.0), (rem_mm - d0_mm).max(0.0))
    }

    /// The end speed the front section aims at: its soft lookahead within its own and the
    /// next section's speed limits and its hard lookahead (zero at the queue end).
    pub(crate) fn want_end(&self) -> f64 {
        if self.sec_count < 2 {
            return 0.0;
        }
        let sec = self.sec(self.sec_head);
        let next = self.sec(self.sec_head + 1);
        let ovr = self.override_factor;
        sec.soft_end_mm_s
            .min(sec.v_eff(ovr, sec.boosted))
            .min(sec.hard_end_at(sec.boosted))
            .min(next.v_eff(ovr, next.wants_boost(ovr)))
    }
}
