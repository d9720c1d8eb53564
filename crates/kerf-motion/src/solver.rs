//! The calls into the rsruckig solver, in scaled units: a position-interface profile to a
//! section's end state and a velocity-interface stop, each checked before it is used.

use rsruckig::prelude::*;

use crate::motion_core::MotionCore;
use crate::{COAST_BELOW_MM, COAST_BELOW_S};

/// A state along the path: speed and acceleration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PathState {
    /// Path speed, mm/s.
    pub(crate) v_mm_s: f64,
    /// Path acceleration, mm/s².
    pub(crate) a_mm_s2: f64,
}

impl PathState {
    /// The state at speed `v_mm_s` and acceleration `a_mm_s2`.
    pub(crate) const fn new(v_mm_s: f64, a_mm_s2: f64) -> Self {
        PathState { v_mm_s, a_mm_s2 }
    }
}

/// The limits a profile keeps to along the path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PathLimits {
    /// Speed ceiling, mm/s.
    pub(crate) v_max_mm_s: f64,
    /// Acceleration limit, mm/s².
    pub(crate) accel_mm_s2: f64,
    /// Jerk limit, mm/s³.
    pub(crate) jerk_mm_s3: f64,
}

/// One position-interface profile for [`MotionCore::calc`]: from `start` at the
/// section-local position `origin_mm`, over `distance_mm`, to `end`, within `limits`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ProfileRequest {
    /// Section-local position where the profile starts, mm.
    pub(crate) origin_mm: f64,
    /// Speed and acceleration at the start.
    pub(crate) start: PathState,
    /// Distance to the end, mm.
    pub(crate) distance_mm: f64,
    /// Speed (capped at `limits.v_max_mm_s`) and acceleration at the end.
    pub(crate) end: PathState,
    /// Limits along the way.
    pub(crate) limits: PathLimits,
}

impl MotionCore {
    /// One position-interface profile calculation: `request.start` to `request.end` over
    /// `request.distance_mm`; on success it becomes the running profile, on failure the
    /// running profile is left untouched.
    ///
    /// Very short moves are planned in scaled units: the solver's numerics fail on
    /// remainders of nanometres (left by a stop or a hold right at a section end). With the
    /// distance as the unit of length and `(d/j)^(1/3)` as the unit of time every input is
    /// of order one; the profile is the same motion, sampled and scaled back.
    pub(crate) fn calc(&mut self, request: &ProfileRequest) -> bool {
        let ProfileRequest {
            origin_mm,
            start:
                PathState {
                    v_mm_s: v0_mm_s,
                    a_mm_s2: a0_mm_s2,
                },
            distance_mm,
            end:
                PathState {
                    v_mm_s: v1_mm_s,
                    a_mm_s2: a1_mm_s2,
                },
            limits:
                PathLimits {
                    v_max_mm_s,
                    accel_mm_s2,
                    jerk_mm_s3,
                },
        } = *request;
        // A remainder below a picometre is taken as reached at the current speed: the step
        // it leaves in the position is invisible even in the jerk at the period.
        let (a0_mm_s2, distance_mm, v1_mm_s, a1_mm_s2, v_max_mm_s) = if distance_mm < 1e-12 {
            (0.0, 0.0, v0_mm_s, 0.0, v_max_mm_s.max(v0_mm_s))
        } else {
            (a0_mm_s2, distance_mm, v1_mm_s, a1_mm_s2, v_max_mm_s)
        };
        // A sliver section (blends that meet leave nanometre remnants of a line) is passed at
        // the entry speed in the time it takes, where the solver fails on such inputs: when
        // it takes less than `COAST_BELOW_S` (no speed can change over it), or when it is
        // shorter than `COAST_BELOW_MM` and no slower end is asked for: at a few µm/s a
        // nanometre takes milliseconds, and the lookahead may have planned a slow-down
        // over it, which a coast at the entry speed would skip, entering the next junction
        // far above its cap. Nor where the coast would take longer than a jerk-limited
        // move across it from rest to rest (`(32 d / j)^(1/3)`): at the tiny cap of a kink
        // on an axis with a low jerk, a coast takes seconds where the move takes
        // milliseconds. Its time is kept, so the positions stay smooth.
        if a0_mm_s2 == 0.0
            && a1_mm_s2 == 0.0
            && v0_mm_s > 0.0
            && distance_mm > 0.0
            && (distance_mm < v0_mm_s * COAST_BELOW_S
                || (distance_mm < COAST_BELOW_MM
                    && v1_mm_s.min(v_max_mm_s) >= v0_mm_s * (1.0 - 1e-9)
                    && distance_mm / v0_mm_s <= (32.0 * distance_mm / jerk_mm_s3).cbrt()))
        {
            self.coast_s = distance_mm / v0_mm_s;
            self.own_active = false;
            self.traj_origin_mm = origin_mm;
            self.traj_t_s = 0.0;
            self.traj_end_v_mm_s = v0_mm_s;
            self.traj_end_a_mm_s2 = 0.0;
            return true;
        }
        // Scaled units: the distance is the unit of length and the time to cover it at the
        // jerk limit alone, `(d/j)^(1/3)`, the unit of time, so every input is of order
        // one. The solver's tolerances are absolute (1e-10 on the acceleration, 1e-8 on
        // speed and position); in millimetres and seconds a fast machine (acceleration
        // 1e4..1e6 mm/s²) is rounded past them and the solver fails on ordinary
        // rest-to-rest moves.
        #[cfg(test)]
        if self.fail_solver {
            return false;
        }
        let (k, tau) = if distance_mm > 0.0 {
            (1.0 / distance_mm, (distance_mm / jerk_mm_s3).cbrt())
        } else {
            (1.0, 1.0)
        };
        // Velocity, acceleration and jerk in the scaled units.
        let (kv, ka, kj) = (k * tau, k * tau * tau, k * tau * tau * tau);
        let inp = &mut self.input;
        inp.control_interface = ControlInterface::Position;
        inp.current_position[0] = 0.0;
        inp.current_velocity[0] = v0_mm_s * kv;
        inp.current_acceleration[0] = a0_mm_s2 * ka;
        inp.target_position[0] = distance_mm * k;
        inp.target_velocity[0] = v1_mm_s.min(v_max_mm_s) * kv;
        inp.target_acceleration[0] = a1_mm_s2 * ka;
        inp.max_velocity[0] = v_max_mm_s.max(1e-9) * kv;
        inp.max_acceleration[0] = accel_mm_s2 * ka;
        inp.max_jerk[0] = jerk_mm_s3 * kj;
        let ok = matches!(
            self.otg.calculate(&self.input, &mut self.scratch),
            Ok(RuckigResult::Working)
        ) && self.scratch_reaches(distance_mm * k);
        if ok {
            std::mem::swap(&mut self.traj, &mut self.scratch);
            self.own_active = false;
            self.coast_s = 0.0;
            self.traj_scale = k;
            self.traj_time_scale_s = tau;
            self.traj_origin_mm = origin_mm;
            self.traj_t_s = 0.0;
            self.traj_end_v_mm_s = v1_mm_s.min(v_max_mm_s);
            self.traj_end_a_mm_s2 = a1_mm_s2;
        }
        ok
    }

    /// A solver result is used only if its duration is finite and it ends at `target`
    /// (scaled units, so the tolerance is relative).
    pub(crate) fn scratch_reaches(&self, target: f64) -> bool {
        let dur_s = self.scratch.get_duration();
        if !dur_s.is_finite() || dur_s < 0.0 {
            return false;
        }
        let mut p = DataArrayOrVec::Stack([0.0]);
        let mut section = None;
        self.scratch.at_time(
            dur_s,
            &mut Some(&mut p),
            &mut None,
            &mut None,
            &mut None,
            &mut section,
        );
        (p[0] - target).abs() <= 1e-6 * target.abs().max(1.0)
    }

    /// A velocity-interface stop from `(v0, a0)` into `scratch`, in scaled units for the
    /// same reason as in `calc`: the unit of time is the stop's own jerk time scale
    /// (`sqrt(v/j)` or `|a|/j`, whichever is longer) and the unit of length what the jerk
    /// covers in it, so that the state is of order one whatever limit is idle (a huge
    /// acceleration limit must not make the speed vanish in the solver's units).
    /// `brake_scale`/`brake_time_scale_s` hold the units.
    pub(crate) fn calc_brake(
        &mut self,
        start: PathState,
        accel_mm_s2: f64,
        jerk_mm_s3: f64,
    ) -> bool {
        let (v0_mm_s, a0_mm_s2) = (start.v_mm_s, start.a_mm_s2);
        let a_lim_mm_s2 = accel_mm_s2.max(a0_mm_s2.abs());
        let tau = (v0_mm_s.abs() / jerk_mm_s3)
            .sqrt()
            .max(a0_mm_s2.abs() / jerk_mm_s3);
        // At rest there is nothing to scale: the stop is empty in any units.
        let (k, tau) = if tau > 0.0 {
            (1.0 / (jerk_mm_s3 * tau * tau * tau), tau)
        } else {
            (1.0, 1.0)
        };
        if !(k.is_finite() && tau.is_finite() && k > 0.0) {
            return false;
        }
        let (kv, ka) = (k * tau, k * tau * tau);
        let inp = &mut self.input;
        inp.control_interface = ControlInterface::Velocity;
        inp.current_position[0] = 0.0;
        inp.current_velocity[0] = v0_mm_s * kv;
        inp.current_acceleration[0] = a0_mm_s2 * ka;
        inp.target_velocity[0] = 0.0;
        inp.target_acceleration[0] = 0.0;
        inp.max_acceleration[0] = a_lim_mm_s2 * ka;
        inp.max_jerk[0] = jerk_mm_s3 * ka * tau;
        let ok = matches!(
            self.otg.calculate(&self.input, &mut self.scratch),
            Ok(RuckigResult::Working)
        ) && self.scratch.get_duration().is_finite();
        self.input.control_interface = ControlInterface::Position;
        self.brake_scale = k;
        self.brake_time_scale_s = tau;
        ok
    }

    /// Distance of the stop in `scratch` (after `calc_brake`), mm.
    pub(crate) fn brake_distance(&self) -> f64 {
        let mut p = DataArrayOrVec::Stack([0.0]);
        let mut section = None;
        self.scratch.at_time(
            self.scratch.get_duration(),
            &mut Some(&mut p),
            &mut None,
            &mut None,
            &mut None,
            &mut section,
        );
        p[0] / self.brake_scale
    }
}

#[cfg(test)]
mod tests {
    use super::{PathLimits, PathState, ProfileRequest};
    use crate::lookahead::PLAN_MARGIN;
    use crate::{AxisLimits, MachineLimits, MotionCore, change_distance};

    /// The solver, called as `calc` calls it (scaled units), plans every feasible profile
    /// from a section start (`a = 0`, any entry speed, any end speed the distance allows)
    /// over the whole accepted range of limits. In mm and s, 58 of these 20,000 failed.
    #[test]
    fn scaled_solver_calls_plan_every_feasible_section() {
        let axis = AxisLimits {
            velocity_units_s: 100.0,
            acceleration_units_s2: 1000.0,
            jerk_units_s3: 1e4,
        };
        let limits = MachineLimits {
            axes: [Some(axis), Some(axis), Some(axis), None, None, None],
            period_s: 0.001,
            tolerance_mm: 0.01,
        };
        let mut core = MotionCore::new(limits.period_s, 4);
        let mut log_uniform = crate::profile::tests::log_uniform_source(0x9e37_79b9_7f4a_7c15);
        let (mut tried, mut failed) = (0, 0);
        while tried < 20_000 {
            let vmax = log_uniform(1.0, 5000.0);
            let a = log_uniform(100.0, 1e6);
            let j = log_uniform(1e3, 1e9);
            let d = log_uniform(1e-4, 1000.0);
            let v0 = if log_uniform(1.0, 4.0) < 2.0 {
                0.0
            } else {
                log_uniform(1e-3, 1.0) * vmax
            };
            let v1 = if log_uniform(1.0, 4.0) < 2.0 {
                0.0
            } else {
                log_uniform(1e-3, 1.0) * vmax
            };
            if change_distance(v0, v1, a, j) > d * PLAN_MARGIN {
                continue;
            }
            tried += 1;
            let request = ProfileRequest {
                origin_mm: 0.0,
                start: PathState::new(v0, 0.0),
                distance_mm: d,
                end: PathState::new(v1, 0.0),
                limits: PathLimits {
                    v_max_mm_s: vmax,
                    accel_mm_s2: a,
                    jerk_mm_s3: j,
                },
            };
            if !core.calc(&request) {
                failed += 1;
            }
        }
        assert_eq!(failed, 0, "of {tried}");
    }
}
