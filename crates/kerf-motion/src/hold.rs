//! Feed hold, resume, abort and feed override, and the check that starts a hold's stop
//! only when it is safe.

use crate::MAX_OVERRIDE;
use crate::motion_core::{Mode, MotionCore};
use crate::solver::PathState;

/// Most sections scanned when checking a hold.
pub(crate) const MAX_HOLD_SCAN: usize = 64;

impl MotionCore {
    /// Sets the feed override (clamped to 0–200 %). Takes effect at once, jerk-limited.
    pub fn set_feed_override(&mut self, factor: f64) {
        let f = if factor.is_finite() {
            factor.clamp(0.0, MAX_OVERRIDE)
        } else {
            1.0
        };
        // Zero override stops the motion like a hold (on the path, jerk-limited) and raising
        // it again resumes, unless the operator also asked for a hold. Planning keeps a
        // small positive factor so that no limit is ever zero.
        if f == 0.0 {
            if !self.override_hold {
                self.override_hold = true;
                if self.mode == Mode::Run {
                    self.mode = Mode::HoldPending;
                    self.try_brake();
                }
            }
            return;
        }
        if self.override_hold {
            self.override_hold = false;
            if !self.user_hold {
                self.resume_inner();
            }
        }
        if f == self.override_factor {
            return;
        }
        self.override_factor = f;
        self.full_soft_pass();
        self.replan = true;
    }

    /// Requests a feed hold: stop on the path as fast as the limits allow.
    pub fn hold(&mut self) {
        self.user_hold = true;
        if self.mode == Mode::Run {
            self.mode = Mode::HoldPending;
            self.try_brake();
        }
    }

    /// Resumes after a hold (or cancels a pending one).
    pub fn resume(&mut self) {
        self.user_hold = false;
        if !self.override_hold {
            self.resume_inner();
        }
    }

    pub(crate) fn resume_inner(&mut self) {
        match self.mode {
            Mode::HoldPending => self.mode = Mode::Run,
            Mode::Held => {
                self.mode = Mode::Run;
                if self.sec_count > 0 {
                    self.plan_section_start();
                }
            }
            Mode::Braking => {
                // The stop finishes first; `step` resumes when it ends if no hold is left.
            }
            Mode::Run => {}
        }
    }

    /// Aborts: stops on the path as fast as the limits allow, then drops the queue.
    pub fn abort(&mut self) {
        self.abort_requested = true;
        if self.mode == Mode::Held || self.v_mm_s == 0.0 && self.a_mm_s2 == 0.0 {
            self.clear();
            return;
        }
        if self.mode == Mode::Run {
            self.hold();
        }
    }

    /// Starts the hold stop if it is safe now: the stop must pass every junction within
    /// its distance at or below the hard lookahead speed and stop before the queue end.
    pub(crate) fn try_brake(&mut self) {
        if self.sec_count == 0 || !self.running {
            if self.v_mm_s == 0.0 {
                self.mode = if self.abort_requested {
                    Mode::Run
                } else {
                    Mode::Held
                };
                if self.abort_requested {
                    self.clear();
                }
            }
            return;
        }
        let (v0_mm_s, a0_mm_s2) = (self.v_mm_s, self.a_mm_s2);
        let front = *self.sec(self.sec_head);
        // The front section runs at its level; the later ones may start at either, so the
        // stop uses the limits valid at both (the boost ones are at most the base ones).
        let (_, mut accel_mm_s2, mut jerk_mm_s3) = front.limits(front.boosted);
        let (front_accel_mm_s2, front_jerk_mm_s3) = (accel_mm_s2, jerk_mm_s3);

        for _ in 0..3 {
            if !self.calc_brake(PathState::new(v0_mm_s, a0_mm_s2), accel_mm_s2, jerk_mm_s3) {
                self.failures += 1;
                return;
            }
            let dist_mm = self.brake_distance();
            // Lowest limits over the sections the stop crosses.
            let (mut a_min_mm_s2, mut j_min_mm_s3) = (front_accel_mm_s2, front_jerk_mm_s3);
            let mut covered_mm = front.length_mm - self.s_local_mm;
            let mut k = self.sec_head + 1;
            let mut n = 0;
            while covered_mm < dist_mm && k < self.sec_head + self.sec_count && n < MAX_HOLD_SCAN {
                let s = self.sec(k);
                a_min_mm_s2 = a_min_mm_s2.min(s.accel_mm_s2).min(s.accel_boost_mm_s2);
                j_min_mm_s3 = j_min_mm_s3.min(s.jerk_mm_s3).min(s.jerk_boost_mm_s3);
                covered_mm += s.length_mm;
                k += 1;
                n += 1;
            }
            if a_min_mm_s2 >= accel_mm_s2 && j_min_mm_s3 >= jerk_mm_s3 {
                break;
            }
            accel_mm_s2 = a_min_mm_s2;
            jerk_mm_s3 = j_min_mm_s3;
        }
        // Already decelerating so hard that a stop with these limits would undershoot into
        // reverse: the running plan stops sooner anyway, so wait for the next section.
        if a0_mm_s2 < 0.0 && v0_mm_s + a0_mm_s2 * a0_mm_s2.abs() / (2.0 * jerk_mm_s3) <= 1e-9 {
            return;
        }
        let dist_mm = self.brake_distance();
        let v_peak_mm_s = v0_mm_s
            + if a0_mm_s2 > 0.0 {
                a0_mm_s2 * a0_mm_s2 / (2.0 * jerk_mm_s3)
            } else {
                0.0
            };
        // The segments' budgets hold where `v + a²/2j ≤ v_max` (the jerk-limited envelope,
        // see `kerf-plan`'s budgets); a stop with a lower jerk than the front section's
        // (a later section's) rises to `v_peak` first, which must stay within the limit.
        let mut ok = v_peak_mm_s <= front.limits(front.boosted).0 * (1.0 + 1e-9);
        let mut boundary_mm = front.length_mm - self.s_local_mm;
        let mut k = self.sec_head;
        let end = self.sec_head + self.sec_count;
        let mut n = 0;
        while ok && boundary_mm < dist_mm {
            let s = self.sec(k);
            // Past the front section the stop runs on limits valid at the boost level.
            let hard = if k == self.sec_head {
                s.hard_end_at(s.boosted)
            } else {
                s.hard_end_boost_mm_s
            };
            if k + 1 >= end || n >= MAX_HOLD_SCAN || hard < v_peak_mm_s {
                ok = false;
                break;
            }
            let next = self.sec(k + 1);
            if next.v_boost_mm_s < v_peak_mm_s
                || next.accel_mm_s2.min(next.accel_boost_mm_s2) < accel_mm_s2
                || next.jerk_mm_s3.min(next.jerk_boost_mm_s3) < jerk_mm_s3
            {
                ok = false;
                break;
            }
            boundary_mm += next.length_mm;
            k += 1;
            n += 1;
        }
        if ok {
            std::mem::swap(&mut self.traj, &mut self.scratch);
            self.own_active = false;
            self.coast_s = 0.0;
            self.traj_scale = self.brake_scale;
            self.traj_time_scale_s = self.brake_time_scale_s;
            self.traj_origin_mm = self.s_local_mm;
            self.traj_t_s = 0.0;
            self.traj_end_v_mm_s = 0.0;
            self.traj_end_a_mm_s2 = 0.0;
            self.mode = Mode::Braking;
        }
    }
}
