//! The section-merge rule: whether a segment joins the tail section, and how the
//! section's limits change when it does. The planner estimates the same decision with
//! [`kerf_geom::speeds_merge_into`], [`kerf_geom::limits_merge`] and the weaker merge's
//! [`kerf_geom::limits_merge_weaker`] and [`kerf_geom::weaker_merge_keeps_lookahead`] to
//! judge its ramp budgets; the tests `the_planners_merge_estimate_is_the_motion_cores_rule`,
//! `the_planners_merge_estimate_follows_a_section_past_its_first_segment` and
//! `the_planners_estimate_of_the_weaker_merge_is_the_motion_cores_rule` tie the two.

use kerf_geom::{
    Curve, MERGE_RATIO_SLOWER, MERGE_RATIO_SPEED, MergeKind, PlannedSegment, conservative_limits,
    entry_speed, limits_merge_into, limits_merge_weaker, weaker_merge_keeps_lookahead,
};

use crate::MAX_OVERRIDE;
use crate::section::Section;

/// A segment's limits at the boost level (override above 100 %): speed (mm/s),
/// acceleration (mm/s²) and jerk (mm/s³). A segment without one (older producers,
/// straight segments) has the base limits there too.
pub(crate) fn boost_limits(seg: &PlannedSegment) -> (f64, f64, f64) {
    let seg_v_mm_s = seg.v_max_mm_s;
    if seg.v_boost_mm_s > seg_v_mm_s && seg.accel_boost_mm_s2 > 0.0 && seg.jerk_boost_mm_s3 > 0.0 {
        (
            seg.v_boost_mm_s,
            seg.accel_boost_mm_s2.min(seg.accel_mm_s2),
            seg.jerk_boost_mm_s3.min(seg.jerk_mm_s3),
        )
    } else {
        (seg_v_mm_s, seg.accel_mm_s2, seg.jerk_mm_s3)
    }
}

impl Section {
    /// Whether and how `seg` (boost-level limits `boost`, see [`boost_limits`]) joins this
    /// section, the queue's tail, across a junction capped at `prev_cap_mm_s`; `plain_run` is
    /// `true` while the core follows its plan with no hold pending or stopping, and
    /// `weaker_ok` where the weaker merge may also apply (see `MotionCore::push`).
    ///
    /// Its speed must be within [`MERGE_RATIO_SPEED`] of the section's conservative speed
    /// (or within [`MERGE_RATIO_SLOWER`] of the first segment's where nothing was committed
    /// faster), its acceleration and jerk must pass [`limits_merge_into`] (or, where
    /// `weaker_ok`, the weaker merge: [`Section::weaker_joins`]), and the junction
    /// must be passable at the section's conservative speed, at both levels.
    ///
    /// The speed part is not [`kerf_geom::speeds_merge_into`], the planner's estimate of it,
    /// and cannot call it without changing results: its lower bound
    /// `v >= MERGE_RATIO_SLOWER · v_first` is the same expression, but here it applies only
    /// below the conservative speed and with the further conditions above; its upper bound
    /// compares `min(v, feed)·R·R` with the section's `min(c_v_mm_s, c_feed_mm_s)` (`R` =
    /// [`MERGE_RATIO_SPEED`]; `c_v_mm_s` starts at `R·v_first` and falls as slower segments
    /// join), where `speeds_merge_into` compares `v·R·R` with the estimate's conservative
    /// speed: the feed counts here only, and the slower merge's further conditions.
    pub(crate) fn joins(
        &self,
        seg: &PlannedSegment,
        (seg_vb, seg_ab, seg_jb): (f64, f64, f64),
        prev_cap_mm_s: f64,
        (plain_run, weaker_ok): (bool, bool),
    ) -> Option<MergeKind> {
        let t = self;
        let seg_v_mm_s = seg.v_max_mm_s;
        let seg_feed_mm_s = seg.feed_mm_s;
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
        let c_v = t.c_v_mm_s.min(MERGE_RATIO_SPEED * seg_v_mm_s);
        let c_v_boost = t.c_v_boost_mm_s.min(MERGE_RATIO_SPEED * seg_vb);
        let passable = (seg_v_mm_s >= t.c_v_mm_s
            || slower(seg_v_mm_s, t.c_v_mm_s, t.v_first_mm_s, t.hard_start_mm_s))
            && seg_feed_mm_s >= t.c_feed_mm_s
            // Nor much faster: the section runs at its minima, so a fast segment behind
            // a slow one (a slow feed, a tight transition) would crawl through it.
            && seg_v_mm_s.min(seg_feed_mm_s) * MERGE_RATIO_SPEED * MERGE_RATIO_SPEED
                <= t.c_v_mm_s.min(t.c_feed_mm_s)
            && prev_cap_mm_s >= c_v.min(t.c_feed_mm_s * MAX_OVERRIDE)
            && (seg_vb >= t.c_v_boost_mm_s
                || slower(seg_vb, t.c_v_boost_mm_s, t.v_first_boost_mm_s, t.hard_start_boost_mm_s))
            && prev_cap_mm_s >= c_v_boost.min(t.c_feed_mm_s * MAX_OVERRIDE);
        // Not much weaker, nor much stronger (it would ramp at the section's limits): the
        // planner judges ramp budgets by the same function.
        let plain = limits_merge_into(
            seg.accel_mm_s2,
            seg.jerk_mm_s3,
            (matches!(seg.curve, Curve::Line { .. }), seg.length_mm),
            t.accel_jerk_first,
            t.length_first_mm,
        ) && seg_ab >= t.c_accel_boost_mm_s2
            && seg_jb >= t.c_jerk_boost_mm_s3;
        if !passable {
            None
        } else if plain {
            Some(MergeKind::Plain)
        } else if weaker_ok && t.weaker_joins(seg, (seg_vb, seg_ab, seg_jb), prev_cap_mm_s) {
            Some(MergeKind::Weaker)
        } else {
            None
        }
    }

    /// Whether `seg`, weaker than [`limits_merge_into`] allows, joins this section (the
    /// queue's tail) by the weaker merge
    /// ([`MERGE_RATIO_WEAKER`](kerf_geom::MERGE_RATIO_WEAKER)): its limits within
    /// [`limits_merge_weaker`] of the first segment's, and the hard start speeds, at the
    /// base and the boost level, of the section as [`Section::absorb`] leaves it (longer,
    /// at the lower conservative limits) not below the ones the lookahead has already
    /// given the section before ([`weaker_merge_keeps_lookahead`]): what the motion before
    /// has been planned against stays valid.
    fn weaker_joins(
        &self,
        seg: &PlannedSegment,
        boost: (f64, f64, f64),
        prev_cap_mm_s: f64,
    ) -> bool {
        let t = self;
        if !limits_merge_weaker(seg.accel_mm_s2, seg.jerk_mm_s3, t.accel_jerk_first) {
            return false;
        }
        let mut joined = *t;
        joined.absorb(seg, boost, prev_cap_mm_s, MergeKind::Weaker);
        let (cap, _) = t.hard_start_caps();
        let (cap_after, cap_boost_after) = joined.hard_start_caps();
        // At the boost level only the lookahead's promise counts.
        weaker_merge_keeps_lookahead(
            (t.hard_start_mm_s, cap),
            cap_after,
            joined.length_mm,
            joined.c_accel_jerk(),
        ) && entry_speed(
            cap_boost_after,
            0.0,
            joined.length_mm,
            (joined.c_accel_boost_mm_s2, joined.c_jerk_boost_mm_s3),
        ) >= t.hard_start_boost_mm_s
    }

    /// Adds `seg` (boost-level limits `boost`) at the section's end, across a junction
    /// capped at `prev_cap_mm_s`, as [`Section::joins`] found (`kind`): the limits become the
    /// minima, and a segment that joined by the weaker merge founds the reference and the
    /// conservative limits anew. Returns the segment's offset within the section, mm.
    pub(crate) fn absorb(
        &mut self,
        seg: &PlannedSegment,
        (seg_vb, seg_ab, seg_jb): (f64, f64, f64),
        prev_cap_mm_s: f64,
        kind: MergeKind,
    ) -> f64 {
        let t = self;
        let seg_v_mm_s = seg.v_max_mm_s;
        let seg_feed_mm_s = seg.feed_mm_s;
        let offset_mm = t.length_mm;
        t.length_mm += seg.length_mm;
        t.count += 1;
        t.v_machine_mm_s = t.v_machine_mm_s.min(seg_v_mm_s).min(prev_cap_mm_s);
        t.feed_mm_s = t.feed_mm_s.min(seg_feed_mm_s);
        t.accel_mm_s2 = t.accel_mm_s2.min(seg.accel_mm_s2);
        t.jerk_mm_s3 = t.jerk_mm_s3.min(seg.jerk_mm_s3);
        t.v_boost_mm_s = t.v_boost_mm_s.min(seg_vb).min(prev_cap_mm_s);
        t.accel_boost_mm_s2 = t.accel_boost_mm_s2.min(seg_ab);
        t.jerk_boost_mm_s3 = t.jerk_boost_mm_s3.min(seg_jb);
        t.c_v_mm_s = t.c_v_mm_s.min(MERGE_RATIO_SPEED * seg_v_mm_s);
        t.c_v_boost_mm_s = t.c_v_boost_mm_s.min(MERGE_RATIO_SPEED * seg_vb);
        if kind == MergeKind::Weaker {
            let first = t.accel_jerk_first;
            t.accel_jerk_first = (first.0.min(seg.accel_mm_s2), first.1.min(seg.jerk_mm_s3));
            let c_boost = conservative_limits((seg_ab, seg_jb));
            t.c_accel_boost_mm_s2 = t.c_accel_boost_mm_s2.min(c_boost.0);
            t.c_jerk_boost_mm_s3 = t.c_jerk_boost_mm_s3.min(c_boost.1);
        }
        offset_mm
    }
}
