//! The planner's estimate of the motion core's sections: which segments `kerf-motion`
//! will run as one profile, for the ramp budgets to judge a piece where it runs.

use kerf_geom::{
    Curve, MERGE_RATIO_SPEED, PlannedSegment, limits_merge, limits_merge_into, speeds_merge_into,
};

/// The section the planner's last emitted segment is estimated to run in, by the motion
/// core's merge rule as far as the planner can see it: the speeds by
/// [`speeds_merge_into`] (against the first segment and the section's conservative speed),
/// the acceleration and jerk by [`limits_merge_into`] against the first segment's, and the
/// junction passable at the section's speed. The core's further conditions (what it has
/// committed, the boost level, the feed) are run-time state or rare, and are not
/// estimated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SectionEstimate {
    /// Speed limit of its first segment, mm/s.
    first_v_mm_s: f64,
    /// Acceleration and jerk of its first segment: the merge rule's reference.
    first_accel_jerk: (f64, f64),
    /// Length of its first segment, mm (the merge rule's measure of a short line).
    first_mm: f64,
    /// [`MERGE_RATIO_SPEED`] of the least speed limit of its segments, mm/s.
    c_v_mm_s: f64,
    /// The least acceleration and jerk over its segments: the limits it runs at.
    pub(crate) least: (f64, f64),
    /// Cap at the end of its last segment, mm/s.
    end_cap_mm_s: f64,
}

impl SectionEstimate {
    /// The section after `seg` is emitted behind `before` (the section of the segment
    /// emitted before it, if any): `before` with `seg` in it, or a new one that `seg`
    /// starts.
    pub(crate) fn after(before: Option<SectionEstimate>, seg: &PlannedSegment) -> Self {
        match before {
            Some(mut s) if s.takes(seg) => {
                s.least = (
                    s.least.0.min(seg.accel_mm_s2),
                    s.least.1.min(seg.jerk_mm_s3),
                );
                s.c_v_mm_s = s.c_v_mm_s.min(MERGE_RATIO_SPEED * seg.v_max_mm_s);
                s.end_cap_mm_s = seg.end_cap_mm_s;
                s
            }
            _ => SectionEstimate {
                first_v_mm_s: seg.v_max_mm_s,
                first_accel_jerk: (seg.accel_mm_s2, seg.jerk_mm_s3),
                first_mm: seg.length_mm,
                c_v_mm_s: MERGE_RATIO_SPEED * seg.v_max_mm_s,
                least: (seg.accel_mm_s2, seg.jerk_mm_s3),
                end_cap_mm_s: seg.end_cap_mm_s,
            },
        }
    }

    /// Whether a curved piece with speed limit `v_mm_s`, acceleration and jerk `(a, j)`,
    /// entered at speed, would join this section.
    pub(crate) fn takes_curve(&self, v_mm_s: f64, (a, j): (f64, f64)) -> bool {
        speeds_merge_into(v_mm_s, self.first_v_mm_s, self.c_v_mm_s)
            && limits_merge(a, j, self.first_accel_jerk)
    }

    /// Whether `seg`, emitted next, joins this section.
    fn takes(&self, seg: &PlannedSegment) -> bool {
        speeds_merge_into(seg.v_max_mm_s, self.first_v_mm_s, self.c_v_mm_s)
            && limits_merge_into(
                seg.accel_mm_s2,
                seg.jerk_mm_s3,
                (matches!(seg.curve, Curve::Line { .. }), seg.length_mm),
                self.first_accel_jerk,
                self.first_mm,
            )
            && self.end_cap_mm_s >= self.c_v_mm_s.min(MERGE_RATIO_SPEED * seg.v_max_mm_s)
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
}
