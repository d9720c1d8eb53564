//! The planner's estimate of the motion core's sections: which segments `kerf-motion`
//! will run as one profile, for the ramp budgets to judge a piece where it runs.

use kerf_geom::{
    Curve, MERGE_RATIO_SPEED, MergeKind, PlannedSegment, conservative_limits, entry_speed,
    limits_merge, limits_merge_into, limits_merge_weaker, speeds_merge_into,
    weaker_merge_keeps_lookahead,
};

/// The section the planner's last emitted segment is estimated to run in, by the motion
/// core's merge rule as far as the planner can see it: the speeds by
/// [`speeds_merge_into`] (against the first segment and the section's conservative speed),
/// the acceleration and jerk by [`limits_merge_into`] against the first segment's (or by
/// the weaker merge, [`limits_merge_weaker`] and [`weaker_merge_keeps_lookahead`], with
/// the section at the queue's end as the core sees it when the segment arrives), and the
/// junction passable at the section's speed. The core's further conditions (what it has
/// committed, whether a hold is pending, the boost level, the feed) are run-time state or
/// rare, and are not estimated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SectionEstimate {
    /// Speed limit of its first segment, mm/s.
    first_v_mm_s: f64,
    /// Acceleration and jerk of its first segment: the merge rule's reference (the lesser
    /// of it and a segment's that joined by the weaker merge).
    first_accel_jerk: (f64, f64),
    /// Length of its first segment, mm (the merge rule's measure of a short line).
    first_mm: f64,
    /// [`MERGE_RATIO_SPEED`] of the least speed limit of its segments, mm/s.
    c_v_mm_s: f64,
    /// The least acceleration and jerk over its segments: the limits it runs at.
    pub(crate) least: (f64, f64),
    /// Cap at the end of its last segment, mm/s.
    end_cap_mm_s: f64,
    /// Cap at the junction before it, mm/s (0 for the program's first section).
    start_cap_mm_s: f64,
    /// Its length, mm.
    length_mm: f64,
}

impl SectionEstimate {
    /// The section after `seg` is emitted behind `before` (the section of the segment
    /// emitted before it, if any): `before` with `seg` in it, or a new one that `seg`
    /// starts.
    pub(crate) fn after(before: Option<SectionEstimate>, seg: &PlannedSegment) -> Self {
        match before.map(|s| (s, s.joins(seg))) {
            Some((mut s, Some(kind))) => {
                if kind == MergeKind::Weaker {
                    // The reference is founded anew.
                    s.first_accel_jerk = (
                        s.first_accel_jerk.0.min(seg.accel_mm_s2),
                        s.first_accel_jerk.1.min(seg.jerk_mm_s3),
                    );
                }
                s.least = (
                    s.least.0.min(seg.accel_mm_s2),
                    s.least.1.min(seg.jerk_mm_s3),
                );
                s.c_v_mm_s = s.c_v_mm_s.min(MERGE_RATIO_SPEED * seg.v_max_mm_s);
                s.end_cap_mm_s = seg.end_cap_mm_s;
                s.length_mm += seg.length_mm;
                s
            }
            _ => SectionEstimate {
                first_v_mm_s: seg.v_max_mm_s,
                first_accel_jerk: (seg.accel_mm_s2, seg.jerk_mm_s3),
                first_mm: seg.length_mm,
                c_v_mm_s: MERGE_RATIO_SPEED * seg.v_max_mm_s,
                least: (seg.accel_mm_s2, seg.jerk_mm_s3),
                end_cap_mm_s: seg.end_cap_mm_s,
                start_cap_mm_s: before.map_or(0.0, |s| s.end_cap_mm_s),
                length_mm: seg.length_mm,
            },
        }
    }

    /// Whether a curved piece with speed limit `v_mm_s`, acceleration and jerk `(a, j)`,
    /// entered at speed, would join this section.
    pub(crate) fn takes_curve(&self, v_mm_s: f64, (a, j): (f64, f64)) -> bool {
        speeds_merge_into(v_mm_s, self.first_v_mm_s, self.c_v_mm_s)
            && limits_merge(a, j, self.first_accel_jerk)
    }

    /// Whether and how `seg`, emitted next, joins this section.
    fn joins(&self, seg: &PlannedSegment) -> Option<MergeKind> {
        let c_v_after = self.c_v_mm_s.min(MERGE_RATIO_SPEED * seg.v_max_mm_s);
        if !speeds_merge_into(seg.v_max_mm_s, self.first_v_mm_s, self.c_v_mm_s)
            || self.end_cap_mm_s < c_v_after
        {
            None
        } else if limits_merge_into(
            seg.accel_mm_s2,
            seg.jerk_mm_s3,
            (matches!(seg.curve, Curve::Line { .. }), seg.length_mm),
            self.first_accel_jerk,
            self.first_mm,
        ) {
            Some(MergeKind::Plain)
        } else if self.takes_weaker(seg, c_v_after) {
            Some(MergeKind::Weaker)
        } else {
            None
        }
    }

    /// Whether `seg` joins by the weaker merge, the section being the queue's end with the
    /// conservative speed `c_v_after_mm_s` after the join (the motion core's
    /// `Section::weaker_joins` at the base level).
    fn takes_weaker(&self, seg: &PlannedSegment, c_v_after_mm_s: f64) -> bool {
        let first = self.first_accel_jerk;
        let (a, j) = (seg.accel_mm_s2, seg.jerk_mm_s3);
        let cap = self.c_v_mm_s.min(self.start_cap_mm_s);
        limits_merge_weaker(a, j, first)
            && weaker_merge_keeps_lookahead(
                (
                    entry_speed(cap, 0.0, self.length_mm, conservative_limits(first)),
                    cap,
                ),
                c_v_after_mm_s.min(self.start_cap_mm_s),
                self.length_mm + seg.length_mm,
                conservative_limits((first.0.min(a), first.1.min(j))),
            )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerf_geom::Vec3;

    /// A line along X from `x0`, `len` long, with the given speed limit, acceleration,
    /// jerk and end cap.
    fn line(x0: f64, len: f64, v: f64, (a, j): (f64, f64), cap: f64) -> PlannedSegment {
        let curve = Curve::line(Vec3::new(x0, 0.0, 0.0), Vec3::new(x0 + len, 0.0, 0.0));
        let mut s = PlannedSegment::with_zero_limits(curve, len, ([0.0; 3], [0.0; 3]), 1, 0, 1e3);
        s.v_max_mm_s = v;
        (s.accel_mm_s2, s.jerk_mm_s3) = (a, j);
        s.end_cap_mm_s = cap;
        s
    }

    fn sections(segs: &[PlannedSegment]) -> Vec<SectionEstimate> {
        let mut out: Vec<SectionEstimate> = Vec::new();
        for s in segs {
            out.push(SectionEstimate::after(out.last().copied(), s));
        }
        out
    }

    /// The estimate follows the motion core's rule (the numbers worked out from the merge
    /// ratios by hand): a segment joins while its speed, limits and the junction allow,
    /// runs at the least limits, and a segment behind a slightly slower one is compared
    /// with that one's speed.
    #[test]
    fn the_estimate_groups_segments_as_the_merge_rule_does() {
        let lim = (1000.0, 20_000.0);
        let s = sections(&[
            line(0.0, 2.0, 50.0, lim, 50.0),
            // 2 % slower: joins (at least 97 % of the first).
            line(2.0, 2.0, 49.0, (950.0, 17_000.0), 50.0),
            // As fast as the first, but more than 1/0.99² above the section's 0.99 × 49.
            line(4.0, 2.0, 50.0, lim, 50.0),
            // Joins that one; then a junction below its speed ends the section.
            line(6.0, 2.0, 50.0, lim, 10.0),
            line(8.0, 2.0, 50.0, (1100.0, 20_000.0), 50.0),
            // Acceleration more than four times the first's, and longer than it: a
            // section of its own.
            line(10.0, 3.0, 50.0, (4500.0, 20_000.0), 50.0),
        ]);
        assert_eq!(s[1].first_v_mm_s, 50.0);
        assert_eq!(s[1].least, (950.0, 17_000.0));
        assert_eq!(s[2].first_v_mm_s, 50.0);
        assert_eq!(s[2].first_mm, 2.0);
        assert_ne!(
            s[2],
            SectionEstimate::after(Some(s[1]), &line(4.0, 2.0, 49.0, lim, 50.0))
        );
        // A new section starts at the third segment (its least limits are its own).
        assert_eq!(s[2].least, lim);
        assert_eq!(s[3].least, lim);
        assert_eq!((s[3].first_v_mm_s, s[3].first_mm), (50.0, 2.0));
        // After the slow junction a new section, with the fifth segment's limits only.
        assert_eq!(s[4].least, (1100.0, 20_000.0));
        assert_eq!(s[4].first_accel_jerk, (1100.0, 20_000.0));
        assert_eq!(s[5].first_accel_jerk, (4500.0, 20_000.0));
        assert_eq!(s[5].least, (4500.0, 20_000.0));
        // A curved piece with the first segment's limits would join the section of s[1]
        // at 49 mm/s but not at 50.
        assert!(s[1].takes_curve(49.0, lim));
        assert!(!s[1].takes_curve(50.0, lim));
        assert!(!s[1].takes_curve(49.0, (3.0 * 1000.0, 90_000.0)));
    }

    /// The weaker merge (numbers worked out by hand from the jerk-limited stop): a piece
    /// with 85 % of the acceleration of the 2 mm piece before it joins that piece's
    /// section where the piece is entered at speed (its hard start, stopping within
    /// 2 mm at 900 mm/s² and 16,000 mm/s³, about 40 mm/s, is below its cap of 49.5 mm/s;
    /// over 5 mm at 765 mm/s² it is at the cap again), and becomes the reference; not where
    /// the piece starts from rest (a junction capped at 0: its hard start is its cap),
    /// nor behind a 200 mm piece (the stop does not reach back into it), nor with 75 %.
    #[test]
    fn a_slightly_weaker_piece_joins_a_short_section_near_a_stop() {
        let lim = (1000.0, 20_000.0);
        let weak = (850.0, 20_000.0);
        let lead = |cap: f64| line(-5.0, 5.0, 50.0, (1e5, 1e7), cap);
        let s = sections(&[
            lead(50.0),
            line(0.0, 2.0, 50.0, lim, 50.0),
            line(2.0, 3.0, 50.0, weak, 0.0),
        ]);
        assert_eq!((s[2].first_mm, s[2].length_mm), (2.0, 5.0));
        assert_eq!((s[2].first_accel_jerk, s[2].least), (weak, weak));
        // From rest.
        let s = sections(&[
            lead(0.0),
            line(0.0, 2.0, 50.0, lim, 50.0),
            line(2.0, 3.0, 50.0, weak, 0.0),
        ]);
        assert_eq!((s[2].first_mm, s[2].first_accel_jerk), (3.0, weak));
        assert_eq!(s[1].least, lim);
        // Behind a long piece.
        let s = sections(&[
            lead(50.0),
            line(0.0, 200.0, 50.0, lim, 50.0),
            line(200.0, 3.0, 50.0, weak, 0.0),
        ]);
        assert_eq!(s[2].first_mm, 3.0);
        // Too weak.
        let s = sections(&[
            lead(50.0),
            line(0.0, 2.0, 50.0, lim, 50.0),
            line(2.0, 3.0, 50.0, (750.0, 20_000.0), 0.0),
        ]);
        assert_eq!(s[2].first_mm, 3.0);
    }
}
