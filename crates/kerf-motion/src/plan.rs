//! Planning the running section's profile: at its start (choosing its level), at a
//! re-plan (more queue, an override change, a move to the boost level), and the
//! closed-form fallbacks and emergency stop when the solver fails.

use crate::lookahead::BACKWARD_MARGIN;
use crate::motion_core::{Mode, MotionCore};
use crate::profile::JerkProfile;
use crate::reach::{change_distance, falls_within, settle};
use crate::solver::{PathLimits, PathState, ProfileRequest};

impl MotionCore {
    /// Plans the front section's profile from the current state at its start (or where a
    /// hold left it, at rest).
    pub(crate) fn plan_section_start(&mut self) {
        self.boost_pending = false;
        self.choose_level();
        let sec = *self.sec(self.sec_head);
        // Entered accelerating or decelerating where the section before carried its
        // speed-up or slow-down over (see `carry_target`); else `a0 = 0`. Reachability is
        // judged from where the acceleration has come down to zero, or for a carried
        // slow-down by the fall it continues (`end_target_from`).
        let (v0_mm_s, a0_mm_s2) = (self.v_mm_s, self.a_mm_s2);
        let rem_mm = (sec.length_mm - self.s_local_mm).max(0.0);
        let (v_machine_mm_s, accel_mm_s2, jerk_mm_s3) = sec.limits(sec.boosted);
        let (v_at_mm_s, _) = settle(v0_mm_s, a0_mm_s2, jerk_mm_s3);
        let (target_mm_s, _) = self.end_target_from(v0_mm_s, a0_mm_s2, rem_mm);
        let v_max_mm_s = sec
            .v_eff(self.override_factor, sec.boosted)
            .min(v_machine_mm_s);
        let origin_mm = self.s_local_mm;
        if v0_mm_s.max(v_at_mm_s) > v_max_mm_s * (1.0 + 1e-9) && rem_mm > 0.0 {
            // Entered above the speed limit of this section (its level's feed or override
            // is lower than the one the junction was planned with): come down to it as
            // fast as the limits allow, cruise, and meet the end speed. The solver's own
            // way (brake to the limit, then plan) can overshoot a short section and fail.
            // Where the section is too short to come down to its limit, the end speed is
            // the lowest one reachable (`end_target`'s, above the limit): the machine keeps
            // slowing down into the next section. (The solver cannot meet a request for
            // the limit there, and each refusal would count as a solver failure.)
            let ends = [target_mm_s.min(v_max_mm_s), target_mm_s];
            for end_v_mm_s in ends
                .into_iter()
                .take(if target_mm_s > v_max_mm_s { 2 } else { 1 })
            {
                if let Some(p) = JerkProfile::cruise_between_from(
                    v0_mm_s,
                    a0_mm_s2,
                    end_v_mm_s,
                    rem_mm,
                    v_max_mm_s,
                    accel_mm_s2,
                    jerk_mm_s3,
                ) {
                    self.run_own(origin_mm, p, end_v_mm_s);
                    return;
                }
            }
        }
        let start = PathState::new(v0_mm_s, a0_mm_s2);
        let limits = PathLimits {
            v_max_mm_s,
            accel_mm_s2,
            jerk_mm_s3,
        };
        if self.calc_front(origin_mm, start, rem_mm, target_mm_s, limits) {
            return;
        }
        // Entered above the feed: let the profile keep the entry speed as its ceiling.
        let peak = v0_mm_s.max(v_at_mm_s);
        let v_max2_mm_s = v_max_mm_s.max(peak).min(v_machine_mm_s.max(peak));
        let request = ProfileRequest {
            origin_mm,
            start,
            distance_mm: rem_mm,
            end: PathState::new(target_mm_s, 0.0),
            limits: PathLimits {
                v_max_mm_s: v_max2_mm_s,
                ..limits
            },
        };
        if self.calc(&request) {
            return;
        }
        self.failures += 1;
        // The solver failed twice: the closed-form profile to the same target, else to a
        // stop at the section end (reachable: the entry speed is within the hard lookahead,
        // which the section's limits can stop from within its length).
        let target_mm_s = target_mm_s.min(v_max2_mm_s);
        for end_v_mm_s in [target_mm_s, 0.0] {
            if let Some(p) = JerkProfile::cruise_between_from(
                v0_mm_s,
                a0_mm_s2,
                end_v_mm_s,
                rem_mm,
                v_max2_mm_s,
                accel_mm_s2,
                jerk_mm_s3,
            ) {
                self.run_own(origin_mm, p, end_v_mm_s);
                return;
            }
        }
        // Cannot happen while the lookahead holds: stop on the path as fast as the limits
        // allow, into the following sections if need be, then go on.
        self.emergency_stop(accel_mm_s2, jerk_mm_s3);
    }

    /// Makes `p` the running profile from section-local position `origin`.
    pub(crate) fn run_own(&mut self, origin_mm: f64, p: JerkProfile, end_v_mm_s: f64) {
        self.own = p;
        self.own_active = true;
        self.coast_s = 0.0;
        self.traj_scale = 1.0;
        self.traj_time_scale_s = 1.0;
        self.traj_origin_mm = origin_mm;
        self.traj_t_s = 0.0;
        self.traj_end_v_mm_s = end_v_mm_s;
        self.traj_end_a_mm_s2 = 0.0;
    }

    /// A jerk-limited stop on the path from the current state (its acceleration first
    /// brought to zero at the jerk limit) with the given limits, crossing section ends like
    /// a hold's stop; the motion goes on when it ends unless a hold is in force. Only
    /// reached when no plan within the section exists.
    pub(crate) fn emergency_stop(&mut self, accel_mm_s2: f64, jerk_mm_s3: f64) {
        self.emergencies += 1;
        let (v0_mm_s, a0_mm_s2) = (self.v_mm_s, self.a_mm_s2);
        let (v_at_mm_s, d0_mm) = settle(v0_mm_s, a0_mm_s2, jerk_mm_s3);
        let d_mm = d0_mm + change_distance(v_at_mm_s.max(0.0), 0.0, accel_mm_s2, jerk_mm_s3);
        let top = v0_mm_s.max(v_at_mm_s);
        match JerkProfile::cruise_between_from(
            v0_mm_s,
            a0_mm_s2,
            0.0,
            d_mm * (1.0 + 1e-12) + 1e-15,
            top,
            accel_mm_s2.max(a0_mm_s2.abs()),
            jerk_mm_s3,
        ) {
            Some(p) => {
                self.run_own(self.s_local_mm, p, 0.0);
                self.mode = Mode::Braking;
            }
            None => {
                // At rest (or no distance left): nothing to stop, the section ends here.
                self.run_own(self.s_local_mm, JerkProfile::default(), 0.0);
            }
        }
    }

    /// Fixes the level the front section runs at as it starts: the one the override wants
    /// (see `Section::wants_boost`), if the entry speed is within that level's speed limit
    /// and hard lookahead, else the other (the previous section ended within the hard
    /// speed of the level it planned for, so one of them always fits). An entry with a
    /// carried speed-up, which is planned for the base level, takes the boost level only
    /// within its acceleration and envelope; else the section starts at the base level
    /// and moves up as [`MotionCore::replan_running`] does, once the acceleration allows.
    pub(crate) fn choose_level(&mut self) {
        let ovr = self.override_factor;
        let (v0_mm_s, a0_mm_s2) = (self.v_mm_s, self.a_mm_s2);
        let head = self.sec_head;
        let sec = self.sec_mut(head);
        // Entered with a slow-down carried over (see `carry_target`): within a level's
        // hard lookahead where the speed can come down to its hard end speed within the
        // section at its conservative limits, as the carry was checked for (or where the
        // speed the section settles to is within its hard start speed).
        let length_mm = sec.length_mm;
        let fits = |v: f64, (hard_start, hard_end): (f64, f64), (c_a, c_j): (f64, f64)| {
            let within = if a0_mm_s2 < 0.0 {
                settle(v0_mm_s, a0_mm_s2, c_j).0 <= hard_start
                    || falls_within(
                        v0_mm_s,
                        a0_mm_s2,
                        hard_end,
                        length_mm * BACKWARD_MARGIN,
                        c_a,
                        c_j,
                    )
            } else {
                v0_mm_s <= hard_start * (1.0 + 1e-9) + 1e-9
            };
            v0_mm_s <= v * (1.0 + 1e-9) && within
        };
        let base_ok = fits(
            sec.v_machine_mm_s,
            (sec.hard_start_mm_s, sec.hard_end_mm_s),
            sec.c_accel_jerk(),
        );
        // Entered with a speed-up carried over (planned for the base level, see
        // `carry_target`): the boost level only if the acceleration is within its limit and
        // its envelope, as `replan_running` asks before moving a running section there.
        let carry_fits_boost = a0_mm_s2 == 0.0
            || (a0_mm_s2.abs() <= sec.accel_boost_mm_s2 * (1.0 + 1e-9)
                && v0_mm_s + a0_mm_s2 * a0_mm_s2 / (2.0 * sec.jerk_boost_mm_s3)
                    <= sec.v_boost_mm_s * (1.0 + 1e-9));
        let boost_speed_ok = fits(
            sec.v_boost_mm_s,
            (sec.hard_start_boost_mm_s, sec.hard_end_boost_mm_s),
            (sec.c_accel_boost_mm_s2, sec.c_jerk_boost_mm_s3),
        );
        let boost_ok = boost_speed_ok && carry_fits_boost;
        let wants = sec.wants_boost(ovr);
        sec.boosted = if wants {
            boost_ok || !base_ok
        } else {
            !base_ok && boost_ok
        };
        // Refused for the carried acceleration alone: move up once it has come down.
        self.boost_pending = wants && !sec.boosted && boost_speed_ok;
    }

    /// Re-plans the running section from the current state (more queue, override).
    pub(crate) fn replan_running(&mut self) {
        // The override asks for more than the running section's base level allows: move
        // it to its boost level if the state is within that level's limits (speed and
        // acceleration) and the end of the section is still reachable with them; else
        // keep the base level and try again next cycle while the acceleration is too high.
        self.boost_pending = false;
        let head = self.sec_head;
        let sec = *self.sec(head);
        if !sec.boosted && sec.wants_boost(self.override_factor) {
            // The boost budgets hold under the envelope `v + a²/2j ≤ v_boost` (see
            // `kerf-plan`'s budgets): a deceleration begun at the base level must be
            // within it at the boost jerk too.
            let within_envelope = self.a_mm_s2 >= 0.0
                || self.v_mm_s + self.a_mm_s2 * self.a_mm_s2 / (2.0 * sec.jerk_boost_mm_s3)
                    <= sec.v_boost_mm_s;
            if self.a_mm_s2.abs() <= sec.accel_boost_mm_s2
                && self.v_mm_s <= sec.v_boost_mm_s
                && within_envelope
            {
                self.sec_mut(head).boosted = true;
                if self.replan_at_level() {
                    return;
                }
                self.sec_mut(head).boosted = false;
            } else {
                self.boost_pending = true;
            }
        }
        self.replan_at_level();
    }

    /// [`MotionCore::replan_running`] at the running section's level; `true` if a new
    /// profile is running.
    pub(crate) fn replan_at_level(&mut self) -> bool {
        let sec = *self.sec(self.sec_head);
        let (v0_mm_s, a0_mm_s2) = (self.v_mm_s, self.a_mm_s2);
        let (v_machine_mm_s, accel_mm_s2, j) = sec.limits(sec.boosted);
        // Bring the acceleration to zero first, then check reachability from there.
        let (v_at_mm_s, d0_mm) = settle(v0_mm_s, a0_mm_s2, j);
        let rem_mm = sec.length_mm - self.s_local_mm;
        if v_at_mm_s < 0.0 || d0_mm >= rem_mm || rem_mm <= 0.0 {
            return false;
        }
        let (target_mm_s, sure) = self.end_target_from(v0_mm_s, a0_mm_s2, rem_mm);
        if !sure {
            return false;
        }
        // The speed still rises to `v_at` while the acceleration comes down: after an
        // override cut that can be above the new feed, and the ceiling must allow it.
        let peak = v0_mm_s.max(v_at_mm_s);
        if peak > v_machine_mm_s * (1.0 + 1e-9) {
            return false;
        }
        let v_max_mm_s = sec.v_eff(self.override_factor, sec.boosted).max(peak);
        // On failure the previous profile is untouched and still valid.
        let limits = PathLimits {
            v_max_mm_s,
            accel_mm_s2,
            jerk_mm_s3: j,
        };
        self.calc_front(
            self.s_local_mm,
            PathState::new(v0_mm_s, a0_mm_s2),
            rem_mm,
            target_mm_s,
            limits,
        )
    }

    /// The front section's profile from `start` at `origin_mm` with `rem_mm` left: to the
    /// carried speed-up's end state where [`MotionCore::carry_target`] offers one and the
    /// solver takes it, else to `target_mm_s` with `a = 0`. Each calculation refused counts
    /// as a solver failure; on `false` the running profile is untouched.
    pub(crate) fn calc_front(
        &mut self,
        origin_mm: f64,
        start: PathState,
        rem_mm: f64,
        target_mm_s: f64,
        limits: PathLimits,
    ) -> bool {
        let request = |end: PathState| ProfileRequest {
            origin_mm,
            start,
            distance_mm: rem_mm,
            end,
            limits,
        };
        if let Some((v1_mm_s, a1_mm_s2)) = self.carry_target(start.v_mm_s, start.a_mm_s2, rem_mm) {
            if self.calc(&request(PathState::new(v1_mm_s, a1_mm_s2))) {
                return true;
            }
            self.failures += 1;
        }
        let ok = self.calc(&request(PathState::new(target_mm_s, 0.0)));
        if !ok {
            self.failures += 1;
        }
        ok
    }
}
