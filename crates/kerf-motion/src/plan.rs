//! Planning the running section's profile: at its start (choosing its level), at a
//! re-plan (more queue, an override change, a move to the boost level), and the
//! closed-form fallbacks and emergency stop when the solver fails.

use crate::motion_core::{Mode, MotionCore};
use crate::profile::JerkProfile;
use crate::reach::{change_distance, settle};
use crate::solver::{PathLimits, PathState, ProfileRequest};

impl MotionCore {
    /// Plans the front section's profile from the current state at its start (or where a
    /// hold left it, at rest).
    pub(crate) fn plan_section_start(&mut self) {
        self.boost_pending = false;
        self.choose_level();
        let sec = *self.sec(self.sec_head);
        // Entered accelerating where the section before carried its speed-up over (see
        // `carry_target`); else `a0 = 0`. Reachability is judged from where the acceleration
        // has come down to zero.
        let (v0, a0) = (self.v, self.a);
        let rem = (sec.length - self.s_local).max(0.0);
        let (v_machine, accel, jerk) = sec.limits(sec.boosted);
        let (v_at, d0) = settle(v0, a0, jerk);
        let (target, _) = self.end_target(v_at.max(0.0), (rem - d0).max(0.0));
        let vmax = sec.v_eff(self.override_factor, sec.boosted).min(v_machine);
        let origin = self.s_local;
        if v0.max(v_at) > vmax * (1.0 + 1e-9) && rem > 0.0 {
            // Entered above the speed limit of this section (its level's feed or override
            // is lower than the one the junction was planned with): come down to it as
            // fast as the limits allow, cruise, and meet the end speed. The solver's own
            // way (brake to the limit, then plan) can overshoot a short section and fail.
            // Where the section is too short to come down to its limit, the end speed is
            // the lowest one reachable (`end_target`'s, above the limit): the machine keeps
            // slowing down into the next section. (Asking the solver for the limit there
            // was a request it could not meet, counted as a solver failure: the soak of
            // `kerf-pipeline`'s properties found it after override cuts.)
            let ends = [target.min(vmax), target];
            for end_v in ends.into_iter().take(if target > vmax { 2 } else { 1 }) {
                if let Some(p) =
                    JerkProfile::cruise_between_from(v0, a0, end_v, rem, vmax, accel, jerk)
                {
                    self.run_own(origin, p, end_v);
                    return;
                }
            }
        }
        let start = PathState::new(v0, a0);
        let limits = PathLimits {
            v_max_mm_s: vmax,
            accel_mm_s2: accel,
            jerk_mm_s3: jerk,
        };
        if self.calc_front(origin, start, rem, target, limits) {
            return;
        }
        // Entered above the feed: let the profile keep the entry speed as its ceiling.
        let peak = v0.max(v_at);
        let vmax2 = vmax.max(peak).min(v_machine.max(peak));
        let request = ProfileRequest {
            origin_mm: origin,
            start,
            distance_mm: rem,
            end: PathState::new(target, 0.0),
            limits: PathLimits {
                v_max_mm_s: vmax2,
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
        let target = target.min(vmax2);
        for end_v in [target, 0.0] {
            if let Some(p) =
                JerkProfile::cruise_between_from(v0, a0, end_v, rem, vmax2, accel, jerk)
            {
                self.run_own(origin, p, end_v);
                return;
            }
        }
        // Cannot happen while the lookahead holds: stop on the path as fast as the limits
        // allow, into the following sections if need be, then go on.
        self.emergency_stop(accel, jerk);
    }

    /// Makes `p` the running profile from section-local position `origin`.
    pub(crate) fn run_own(&mut self, origin: f64, p: JerkProfile, end_v: f64) {
        self.own = p;
        self.own_active = true;
        self.coast_s = 0.0;
        self.traj_scale = 1.0;
        self.traj_time_scale = 1.0;
        self.traj_origin = origin;
        self.traj_t = 0.0;
        self.traj_end_v = end_v;
        self.traj_end_a = 0.0;
    }

    /// A jerk-limited stop on the path from the current state (its acceleration first
    /// brought to zero at the jerk limit) with the given limits, crossing section ends like
    /// a hold's stop; the motion goes on when it ends unless a hold is in force. Only
    /// reached when no plan within the section exists.
    pub(crate) fn emergency_stop(&mut self, accel: f64, jerk: f64) {
        self.emergencies += 1;
        let (v0, a0) = (self.v, self.a);
        let (v_at, d0) = settle(v0, a0, jerk);
        let d = d0 + change_distance(v_at.max(0.0), 0.0, accel, jerk);
        let top = v0.max(v_at);
        match JerkProfile::cruise_between_from(
            v0,
            a0,
            0.0,
            d * (1.0 + 1e-12) + 1e-15,
            top,
            accel.max(a0.abs()),
            jerk,
        ) {
            Some(p) => {
                self.run_own(self.s_local, p, 0.0);
                self.mode = Mode::Braking;
            }
            None => {
                // At rest (or no distance left): nothing to stop, the section ends here.
                self.run_own(self.s_local, JerkProfile::default(), 0.0);
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
        let (v0, a0) = (self.v, self.a);
        let head = self.sec_head;
        let sec = self.sec_mut(head);
        let fits = |v: f64, hard: f64| v0 <= v * (1.0 + 1e-9) && v0 <= hard * (1.0 + 1e-9) + 1e-9;
        let base_ok = fits(sec.v_machine, sec.hard_start);
        // Entered with a speed-up carried over (planned for the base level, see
        // `carry_target`): the boost level only if the acceleration is within its limit and
        // its envelope, as `replan_running` asks before moving a running section there.
        let carry_fits_boost = a0 <= 0.0
            || (a0 <= sec.accel_boost * (1.0 + 1e-9)
                && v0 + a0 * a0 / (2.0 * sec.jerk_boost) <= sec.v_boost * (1.0 + 1e-9));
        let boost_speed_ok = fits(sec.v_boost, sec.hard_start_boost);
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
            let within_envelope =
                self.a >= 0.0 || self.v + self.a * self.a / (2.0 * sec.jerk_boost) <= sec.v_boost;
            if self.a.abs() <= sec.accel_boost && self.v <= sec.v_boost && within_envelope {
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
        let (v0, a0) = (self.v, self.a);
        let (v_machine, accel, j) = sec.limits(sec.boosted);
        // Bring the acceleration to zero first, then check reachability from there.
        let (v_at, d0) = settle(v0, a0, j);
        let rem = sec.length - self.s_local;
        if v_at < 0.0 || d0 >= rem || rem <= 0.0 {
            return false;
        }
        let (target, sure) = self.end_target(v_at, rem - d0);
        if !sure {
            return false;
        }
        // The speed still rises to `v_at` while the acceleration comes down: after an
        // override cut that can be above the new feed, and the ceiling must allow it.
        let peak = v0.max(v_at);
        if peak > v_machine * (1.0 + 1e-9) {
            return false;
        }
        let vmax = sec.v_eff(self.override_factor, sec.boosted).max(peak);
        // On failure the previous profile is untouched and still valid.
        let limits = PathLimits {
            v_max_mm_s: vmax,
            accel_mm_s2: accel,
            jerk_mm_s3: j,
        };
        self.calc_front(self.s_local, PathState::new(v0, a0), rem, target, limits)
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
        if let Some((v1, a1)) = self.carry_target(start.v_mm_s, start.a_mm_s2, rem_mm) {
            if self.calc(&request(PathState::new(v1, a1))) {
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
