//! The per-cycle step: advancing the running profile, crossing section ends (carrying the
//! leftover time) and writing the setpoint.

use rsruckig::prelude::*;

use crate::motion_core::{Mode, MotionCore};
use crate::{Setpoint, StepResult};

/// Most section changes handled within one cycle.
pub(crate) const MAX_SECTIONS_PER_STEP: usize = 16;

impl MotionCore {
    /// Advances one period and writes the setpoint. Bounded work, no allocation.
    pub fn step(&mut self, out: &mut Setpoint) -> StepResult {
        if self.mode == Mode::Held {
            *out = self.last;
            if self.abort_requested {
                self.clear();
                return StepResult::Idle;
            }
            return StepResult::Held;
        }
        if self.sec_count == 0 {
            self.v_mm_s = 0.0;
            self.a_mm_s2 = 0.0;
            self.last.feed_mm_s = 0.0;
            *out = self.last;
            return self.at_rest_with_nothing_queued();
        }
        if !self.running {
            self.running = true;
            self.plan_section_start();
        } else if (self.replan || self.boost_pending)
            && matches!(self.mode, Mode::Run | Mode::HoldPending)
        {
            self.replan_running();
        }
        self.replan = false;
        self.traj_t_s += self.period_s;
        let mut changes = 0;
        loop {
            let dur_s = self.running_duration();
            if self.traj_t_s < dur_s {
                break;
            }
            if self.mode == Mode::Braking {
                self.sample(dur_s);
                self.v_mm_s = 0.0;
                self.a_mm_s2 = 0.0;
                self.mode = Mode::Held;
                self.emit(out);
                out.feed_mm_s = 0.0;
                if !self.user_hold && !self.override_hold && !self.abort_requested {
                    // Resumed while stopping: at rest for this cycle, moving from the next.
                    self.resume_inner();
                    return StepResult::Moving;
                }
                return StepResult::Held;
            }
            // The profile ends inside this cycle: carry the leftover time on.
            let leftover_s = self.traj_t_s - dur_s;
            let (end_v_mm_s, end_a) = (self.traj_end_v_mm_s, self.traj_end_a_mm_s2);
            self.pop_section();
            changes += 1;
            if self.sec_count == 0 {
                self.finish_at_end();
                self.emit(out);
                return self.at_rest_with_nothing_queued();
            }
            self.v_mm_s = end_v_mm_s;
            self.a_mm_s2 = end_a;
            self.s_local_mm = 0.0;
            self.plan_section_start();
            if self.mode == Mode::HoldPending {
                self.try_brake();
            }
            // Pathological queues (hundreds of sections inside one period) would make the
            // cycle unbounded: past the limit the leftover time is dropped, which delays
            // the motion by under one period but keeps it continuous.
            self.traj_t_s = if changes >= MAX_SECTIONS_PER_STEP {
                0.0
            } else {
                leftover_s
            };
        }
        let t = self.traj_t_s;
        self.sample(t);
        self.emit(out);
        StepResult::Moving
    }

    /// The step's result at rest with nothing queued: idle, or held where a hold is
    /// pending (one asked for when its stop could no longer start before the queue's end,
    /// in the last deceleration, is in force once at rest there; an abort still clears).
    fn at_rest_with_nothing_queued(&mut self) -> StepResult {
        if self.mode == Mode::HoldPending {
            self.try_brake();
            if self.mode == Mode::Held {
                return StepResult::Held;
            }
        }
        StepResult::Idle
    }

    /// Duration of the running profile (or coast), seconds.
    pub(crate) fn running_duration(&self) -> f64 {
        if self.coast_s > 0.0 {
            self.coast_s
        } else if self.own_active {
            self.own.duration_s()
        } else {
            self.traj.get_duration() * self.traj_time_scale_s
        }
    }

    /// Samples the profile at `t` and updates the section-local state (crossing into later
    /// sections while braking).
    pub(crate) fn sample(&mut self, t: f64) {
        let mut p = [0.0];
        let mut v = [0.0];
        let mut a = [0.0];
        if self.coast_s > 0.0 {
            p[0] = self.traj_end_v_mm_s * t.min(self.coast_s);
            v[0] = self.traj_end_v_mm_s;
        } else if self.own_active {
            (p[0], v[0], a[0]) = self.own.at(t);
        } else {
            let mut pos = DataArrayOrVec::Stack(p);
            let mut vel = DataArrayOrVec::Stack(v);
            let mut acc = DataArrayOrVec::Stack(a);
            let mut section = None;
            self.traj.at_time(
                t / self.traj_time_scale_s,
                &mut Some(&mut pos),
                &mut Some(&mut vel),
                &mut Some(&mut acc),
                &mut None,
                &mut section,
            );
            let (k, tau) = (self.traj_scale, self.traj_time_scale_s);
            p[0] = pos[0] / k;
            v[0] = vel[0] / (k * tau);
            a[0] = acc[0] / (k * tau * tau);
        }
        let mut s = self.traj_origin_mm + p[0];
        // A braking profile may run into following sections.
        while self.mode == Mode::Braking && self.sec_count > 1 {
            let len_mm = self.sec(self.sec_head).length_mm;
            if s <= len_mm {
                break;
            }
            self.pop_section();
            self.traj_origin_mm -= len_mm;
            s -= len_mm;
        }
        let len_mm = self.sec(self.sec_head).length_mm;
        self.s_local_mm = s.clamp(0.0, len_mm);
        self.v_mm_s = v[0].max(0.0);
        self.a_mm_s2 = a[0];
    }

    /// Writes the setpoint for the current section-local position.
    pub(crate) fn emit(&mut self, out: &mut Setpoint) {
        if self.sec_count == 0 {
            *out = self.last;
            return;
        }
        let sec = *self.sec(self.sec_head);
        let last_seg = sec.first + sec.count - 1;
        if self.cursor < sec.first {
            self.cursor = sec.first;
        }
        while self.cursor < last_seg {
            let slot = (self.cursor % self.segs.len() as u64) as usize;
            let end = self.seg_offset_mm[slot] + self.segs[slot].length_mm;
            if self.s_local_mm < end {
                break;
            }
            self.cursor += 1;
        }
        // Segments already passed are released at once, so that a long section frees queue
        // room as it runs (otherwise a queue full of one section would force a stop).
        if self.cursor > sec.first {
            let passed = self.cursor - sec.first;
            self.seg_head += passed;
            self.seg_count -= passed;
            let head = self.sec_head;
            let front = self.sec_mut(head);
            front.first += passed;
            front.count -= passed;
        }
        let slot = (self.cursor % self.segs.len() as u64) as usize;
        let seg = &self.segs[slot];
        let local = self.s_local_mm - self.seg_offset_mm[slot];
        seg.position_at(local, &mut self.last.position);
        self.last.line = seg.line;
        self.last.move_index = seg.move_index;
        self.last.move_count = seg.move_count;
        self.last.rapid = seg.feed_mm_s.is_infinite();
        self.last.feed_mm_s = self.v_mm_s;
        *out = self.last;
    }

    /// Places the state exactly at the end of the section that just ended.
    pub(crate) fn finish_at_end(&mut self) {
        // The popped section's last segment is still in its slot: evaluate its exact end.
        let abs = self.seg_head.wrapping_sub(1);
        let slot = (abs % self.segs.len() as u64) as usize;
        let seg = self.segs[slot];
        seg.position_at(seg.length_mm, &mut self.last.position);
        self.last.line = seg.line;
        self.last.move_index = seg.move_index;
        self.last.move_count = seg.move_count;
        self.v_mm_s = 0.0;
        self.a_mm_s2 = 0.0;
        self.last.feed_mm_s = 0.0;
        self.s_local_mm = 0.0;
        self.running = false;
        self.traj_t_s = 0.0;
    }
}
