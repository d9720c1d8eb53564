//! The section-merge rule: whether a segment joins the tail section, and how the
//! section's limits change when it does. The planner estimates the same decision with
//! [`kerf_geom::speeds_merge`] and [`kerf_geom::limits_merge`] to judge its ramp budgets;
//! the test `the_planners_merge_estimate_is_the_motion_cores_rule` ties the two.

use kerf_geom::{MERGE_RATIO_SLOWER, MERGE_RATIO_SPEED, PlannedSegment, limits_merge};

use crate::MAX_OVERRIDE;
use crate::section::Section;

/// A segment's limits at the boost level (override above 100 %): speed (mm/s),
/// acceleration (mm/s²) and jerk (mm/s³). A segment without one (older producers,
/// straight segments) has the base limits there too.
pub(crate) fn boost_limits(seg: &PlannedSegment) -> (f64, f64, f64) {
    let seg_v = seg.v_max_mm_s;
    if seg.v_boost_mm_s > seg_v && seg.accel_boost_mm_s2 > 0.0 && seg.jerk_boost_mm_s3 > 0.0 {
        (
            seg.v_boost_mm_s,
            seg.accel_boost_mm_s2.min(seg.accel_mm_s2),
            seg.jerk_boost_mm_s3.min(seg.jerk_mm_s3),
        )
    } else {
        (seg_v, seg.accel_mm_s2, seg.jerk_mm_s3)
    }
}

impl Section {
    /// Whether `seg` (boost-level limits `boost`, see [`boost_limits`]) joins this section,
    /// the queue's tail, across a junction capped at `prev_cap_mm_s`; `plain_run` is
    /// `true` while the core follows its plan with no hold pending or stopping.
    ///
    /// Its speed must be within [`MERGE_RATIO_SPEED`] of the section's conservative speed
    /// (or within [`MERGE_RATIO_SLOWER`] of the first segment's where nothing was committed
    /// faster), its acceleration and jerk must pass [`limits_merge`], and the junction must
    /// be passable at the section's conservative speed, at both levels.
    ///
    /// The speed part is not [`kerf_geom::speeds_merge`] computed on the segments' speed
    /// limits, though the planner uses that as its estimate: the upper bound here compares
    /// `min(v, feed)·R·R` with the section's conservative `min(c_v, c_feed)` (`c_v` starts
    /// at `R·v_first`, `R` = [`MERGE_RATIO_SPEED`], and falls as slower segments join),
    /// where `speeds_merge` compares `v·R` with `v_first`; the two roundings can differ by
    /// an ulp, and the feed and the later segments count here only.
    pub(crate) fn takes(
        &self,
        seg: &PlannedSegment,
        (seg_vb, seg_ab, seg_jb): (f64, f64, f64),
        prev_cap_mm_s: f64,
        plain_run: bool,
    ) -> bool {
        let t = self;
        let prev_cap = prev_cap_mm_s;
        let seg_v = seg.v_max_mm_s;
        let seg_feed = seg.feed_mm_s;
        // A segment slower than the section's conservative speed by a little joins it
        // when nothing has been committed above its speed: the tail section's hard
        // lookahead (it must stop within itself) is already below it, so lowering the
        // conservative speed lowers no boundary speed, and no profile or stop was
        // planned into the section faster (see [`MERGE_RATIO_SLOWER`]).
        let slower = |v: f64, c_v: f64, first: f64, hard: f64| {
            v < c_v
                && plain_run
                && v >= MERGE_RATIO_SLOWER * first
                && hard >= 0.0
                && hard <= MERGE_RATIO_SPEED * v
        };
        // The conservative speeds after the merge.
        let c_v = t.c_v.min(MERGE_RATIO_SPEED * seg_v);
        let c_v_boost = t.c_v_boost.min(MERGE_RATIO_SPEED * seg_vb);
        (seg_v >= t.c_v || slower(seg_v, t.c_v, t.v_first, t.hard_start))
            && seg_feed >= t.c_feed
            // Nor much faster: the section runs at its minima, so a fast segment behind
            // a slow one (a slow feed, a tight transition) would crawl through it.
            && seg_v.min(seg_feed) * MERGE_RATIO_SPEED * MERGE_RATIO_SPEED
                <= t.c_v.min(t.c_feed)
            // Not much weaker, nor much stronger (it would ramp at the section's
            // limits): the planner judges ramp budgets by the same function.
            && limits_merge(seg.accel_mm_s2, seg.jerk_mm_s3, t.accel_jerk_first)
            && prev_cap >= c_v.min(t.c_feed * MAX_OVERRIDE)
            && (seg_vb >= t.c_v_boost
                || slower(seg_vb, t.c_v_boost, t.v_first_boost, t.hard_start_boost))
            && seg_ab >= t.c_accel_boost
            && seg_jb >= t.c_jerk_boost
            && prev_cap >= c_v_boost.min(t.c_feed * MAX_OVERRIDE)
    }

    /// Adds `seg` (boost-level limits `boost`) at the section's end, across a junction
    /// capped at `prev_cap_mm_s`: the limits become the minima. Returns the segment's
    /// offset within the section, mm.
    pub(crate) fn absorb(
        &mut self,
        seg: &PlannedSegment,
        (seg_vb, seg_ab, seg_jb): (f64, f64, f64),
        prev_cap_mm_s: f64,
    ) -> f64 {
        let t = self;
        let prev_cap = prev_cap_mm_s;
        let seg_v = seg.v_max_mm_s;
        let seg_feed = seg.feed_mm_s;
        let offset = t.length;
        t.length += seg.length_mm;
        t.count += 1;
        t.v_machine = t.v_machine.min(seg_v).min(prev_cap);
        t.feed = t.feed.min(seg_feed);
        t.accel = t.accel.min(seg.accel_mm_s2);
        t.jerk = t.jerk.min(seg.jerk_mm_s3);
        t.v_boost = t.v_boost.min(seg_vb).min(prev_cap);
        t.accel_boost = t.accel_boost.min(seg_ab);
        t.jerk_boost = t.jerk_boost.min(seg_jb);
        t.c_v = t.c_v.min(MERGE_RATIO_SPEED * seg_v);
        t.c_v_boost = t.c_v_boost.min(MERGE_RATIO_SPEED * seg_vb);
        offset
    }
}
