//! Appending segments to the queue (the continuity check and the section-merge rule) and
//! dropping finished sections.

use kerf_geom::PlannedSegment;

use crate::lookahead::MAX_BACKWARD_SECTIONS;
use crate::merge::boost_limits;
use crate::motion_core::{Mode, MotionCore};
use crate::section::Section;
use crate::{CONTINUITY_MM, PushError};

impl MotionCore {
    /// Appends a segment. Never allocates; the lookahead work is a backward pass from the
    /// tail that stops at the first section whose speeds do not change.
    pub fn push(&mut self, seg: &PlannedSegment) -> Result<(), PushError> {
        if self.seg_count as usize >= self.segs.len() {
            return Err(PushError::Full);
        }
        let valid = seg.length_mm.is_finite()
            && seg.length_mm > 0.0
            && seg.v_max_mm_s > 0.0
            && seg.accel_mm_s2 > 0.0
            && seg.jerk_mm_s3 > 0.0
            && seg.feed_mm_s > 0.0
            && seg.end_cap_mm_s >= 0.0;
        if !valid {
            return Err(PushError::Invalid);
        }
        let mut start = [0.0; 6];
        seg.position_at(0.0, &mut start);
        let mut before = self.last.position;
        if self.seg_count > 0 {
            let prev = *self.seg(self.seg_head + self.seg_count - 1);
            prev.position_at(prev.length_mm, &mut before);
        }
        if (0..6).any(|i| (start[i] - before[i]).abs() > CONTINUITY_MM) {
            return Err(PushError::Discontinuous);
        }
        let abs = self.seg_head + self.seg_count;
        let slot = (abs % self.segs.len() as u64) as usize;
        self.segs[slot] = *seg;
        self.seg_count += 1;

        let boost = boost_limits(seg);
        // The cap at the junction before this segment is the previous segment's end cap.
        let prev_cap_mm_s = if abs > self.seg_head {
            self.seg(abs - 1).end_cap_mm_s
        } else {
            0.0
        };
        let tail = self.sec_head + self.sec_count;
        let plain_run = self.mode == Mode::Run;
        // The weaker merge lowers a section's conservative acceleration: not in the section
        // after the running one, which a speed-up may already be carried into at the
        // acceleration its old conservative limits allow (see `carry_target`).
        let weaker_ok = plain_run && !(self.sec_count == 2 && self.running);
        let join = if self.sec_count > 0 && !(self.sec_count == 1 && self.running) {
            self.sec(tail - 1)
                .joins(seg, boost, prev_cap_mm_s, (plain_run, weaker_ok))
        } else {
            None
        };
        if let Some(kind) = join {
            let offset_mm = self
                .sec_mut(tail - 1)
                .absorb(seg, boost, prev_cap_mm_s, kind);
            self.seg_offset_mm[slot] = offset_mm;
        } else {
            if self.sec_count as usize >= self.secs.len() {
                // Cannot happen: there are never more sections than segments.
                self.seg_count -= 1;
                return Err(PushError::Full);
            }
            let start_cap = if self.sec_count > 0 {
                prev_cap_mm_s
            } else {
                0.0
            };
            let sec = Section::of_segment(abs, seg, boost, start_cap);
            let i = self.sec_slot(tail);
            self.secs[i] = sec;
            self.sec_count += 1;
            self.seg_offset_mm[slot] = 0.0;
            if self.sec_count == 1 {
                // The new section is the front one: the core was idle.
                self.cursor = abs;
                self.s_local_mm = 0.0;
            }
        }
        self.backward_pass(MAX_BACKWARD_SECTIONS);
        Ok(())
    }

    pub(crate) fn pop_section(&mut self) {
        let sec = *self.sec(self.sec_head);
        self.seg_head += sec.count;
        self.seg_count -= sec.count;
        self.sec_head += 1;
        self.sec_count -= 1;
        self.cursor = self.seg_head;
        if self.sec_count == 0 {
            self.running = false;
        }
    }
}
