//! A section: consecutive segments the core runs as one jerk-limited profile, with the
//! limits (actual and conservative, at the base and the boost level) and the lookahead
//! speeds the core keeps for it.

use kerf_geom::{MERGE_RATIO_SPEED, PlannedSegment, conservative_limits};

use crate::MAX_OVERRIDE;

#[derive(Clone, Copy, Debug)]
pub(crate) struct Section {
    /// Absolute index of the first segment.
    pub(crate) first: u64,
    pub(crate) count: u64,
    pub(crate) length_mm: f64,
    /// Actual limits: minima over segments and interior junction caps.
    pub(crate) v_machine_mm_s: f64,
    pub(crate) feed_mm_s: f64,
    pub(crate) accel_mm_s2: f64,
    pub(crate) jerk_mm_s3: f64,
    /// The same for a feed override above 100 % (the segments' `v_boost`,
    /// `accel_boost`, `jerk_boost`; the accelerations are at most the ones above).
    pub(crate) v_boost_mm_s: f64,
    pub(crate) accel_boost_mm_s2: f64,
    pub(crate) jerk_boost_mm_s3: f64,
    /// Speed limits of the first segment, base and boost level (see
    /// [`MERGE_RATIO_SLOWER`](crate::MERGE_RATIO_SLOWER)).
    pub(crate) v_first_mm_s: f64,
    pub(crate) v_first_boost_mm_s: f64,
    /// Acceleration and jerk limits of the first segment: the merge rule's reference
    /// ([`limits_merge`](kerf_geom::limits_merge)); the hard lookahead's are their merge ratios
    /// ([`Section::c_accel_jerk`]).
    pub(crate) accel_jerk_first: (f64, f64),
    /// Length of the first segment, mm: the measure of a short segment in the merge rule
    /// ([`limits_merge_into`](kerf_geom::limits_merge_into)).
    pub(crate) length_first_mm: f64,
    /// Conservative limits fixed at creation (hard lookahead); the speeds are lowered when
    /// a slightly slower segment joins (see [`MERGE_RATIO_SLOWER`](crate::MERGE_RATIO_SLOWER)).
    pub(crate) c_v_mm_s: f64,
    pub(crate) c_feed_mm_s: f64,
    /// The same for the boost level.
    pub(crate) c_v_boost_mm_s: f64,
    pub(crate) c_accel_boost_mm_s2: f64,
    pub(crate) c_jerk_boost_mm_s3: f64,
    /// Cap at the junction before the section.
    pub(crate) start_cap_mm_s: f64,
    /// Hard lookahead at the base level (valid while the section runs with its base limits).
    pub(crate) hard_start_mm_s: f64,
    pub(crate) hard_end_mm_s: f64,
    /// Hard lookahead at the boost level (valid with the boost limits, at any override).
    pub(crate) hard_start_boost_mm_s: f64,
    pub(crate) hard_end_boost_mm_s: f64,
    pub(crate) soft_start_mm_s: f64,
    pub(crate) soft_end_mm_s: f64,
    /// The level the section runs at, fixed when it starts (see `plan_section_start`).
    pub(crate) boosted: bool,
}

impl Section {
    /// A placeholder for the queue's free slots.
    pub(crate) const EMPTY: Section = Section {
        first: 0,
        count: 0,
        length_mm: 0.0,
        v_machine_mm_s: 0.0,
        feed_mm_s: 0.0,
        accel_mm_s2: 0.0,
        jerk_mm_s3: 0.0,
        v_boost_mm_s: 0.0,
        accel_boost_mm_s2: 0.0,
        jerk_boost_mm_s3: 0.0,
        v_first_mm_s: 0.0,
        v_first_boost_mm_s: 0.0,
        c_v_mm_s: 0.0,
        c_feed_mm_s: 0.0,
        accel_jerk_first: (0.0, 0.0),
        length_first_mm: 0.0,
        c_v_boost_mm_s: 0.0,
        c_accel_boost_mm_s2: 0.0,
        c_jerk_boost_mm_s3: 0.0,
        start_cap_mm_s: 0.0,
        hard_start_mm_s: 0.0,
        hard_end_mm_s: 0.0,
        hard_start_boost_mm_s: 0.0,
        hard_end_boost_mm_s: 0.0,
        soft_start_mm_s: 0.0,
        soft_end_mm_s: 0.0,
        boosted: false,
    };

    /// The section of the one segment `seg` (absolute index `first`, boost-level limits
    /// `boost`) after a junction capped at `start_cap_mm_s`; its lookahead speeds are
    /// not computed yet.
    pub(crate) fn of_segment(
        first: u64,
        seg: &PlannedSegment,
        (seg_vb, seg_ab, seg_jb): (f64, f64, f64),
        start_cap_mm_s: f64,
    ) -> Section {
        let c_boost = conservative_limits((seg_ab, seg_jb));
        Section {
            first,
            count: 1,
            length_mm: seg.length_mm,
            v_machine_mm_s: seg.v_max_mm_s,
            feed_mm_s: seg.feed_mm_s,
            accel_mm_s2: seg.accel_mm_s2,
            jerk_mm_s3: seg.jerk_mm_s3,
            v_first_mm_s: seg.v_max_mm_s,
            v_first_boost_mm_s: seg_vb,
            c_v_mm_s: MERGE_RATIO_SPEED * seg.v_max_mm_s,
            c_feed_mm_s: MERGE_RATIO_SPEED * seg.feed_mm_s,
            accel_jerk_first: (seg.accel_mm_s2, seg.jerk_mm_s3),
            length_first_mm: seg.length_mm,
            v_boost_mm_s: seg_vb,
            accel_boost_mm_s2: seg_ab,
            jerk_boost_mm_s3: seg_jb,
            c_v_boost_mm_s: MERGE_RATIO_SPEED * seg_vb,
            c_accel_boost_mm_s2: c_boost.0,
            c_jerk_boost_mm_s3: c_boost.1,
            start_cap_mm_s,
            hard_start_mm_s: -1.0,
            hard_end_mm_s: 0.0,
            hard_start_boost_mm_s: -1.0,
            hard_end_boost_mm_s: 0.0,
            soft_start_mm_s: -1.0,
            soft_end_mm_s: 0.0,
            boosted: false,
        }
    }
    /// The conservative acceleration and jerk of the hard lookahead: the merge ratios of
    /// the reference (the first segment's, or a weaker one's that joined), which every
    /// segment of the section has at least ([`conservative_limits`]).
    pub(crate) fn c_accel_jerk(&self) -> (f64, f64) {
        conservative_limits(self.accel_jerk_first)
    }

    /// Speed limit, acceleration and jerk at a level.
    pub(crate) fn limits(&self, boosted: bool) -> (f64, f64, f64) {
        if boosted {
            (
                self.v_boost_mm_s,
                self.accel_boost_mm_s2,
                self.jerk_boost_mm_s3,
            )
        } else {
            (self.v_machine_mm_s, self.accel_mm_s2, self.jerk_mm_s3)
        }
    }

    /// The hard end speed at a level.
    pub(crate) fn hard_end_at(&self, boosted: bool) -> f64 {
        if boosted {
            self.hard_end_boost_mm_s
        } else {
            self.hard_end_mm_s
        }
    }

    /// The caps on the hard lookahead's start speeds, at the base and the boost level, from
    /// the section's own conservative limits and its junction cap: the start speeds where
    /// the stop at the queue's end does not reach back to the section.
    pub(crate) fn hard_start_caps(&self) -> (f64, f64) {
        let feed_mm_s = self.c_feed_mm_s * MAX_OVERRIDE;
        (
            self.c_v_mm_s.min(feed_mm_s).min(self.start_cap_mm_s),
            self.c_v_boost_mm_s.min(feed_mm_s).min(self.start_cap_mm_s),
        )
    }

    /// The cap on the soft lookahead's start speed at override `ovr` and `level`, below the
    /// hard start speed of that level `hard_mm_s`.
    pub(crate) fn soft_start_cap(&self, ovr: f64, level: bool, hard_mm_s: f64) -> f64 {
        self.v_eff(ovr, level)
            .min(self.start_cap_mm_s)
            .min(hard_mm_s)
    }

    /// Speed at override `ovr` and a level: the machine limit or the scaled feed.
    pub(crate) fn v_eff(&self, ovr: f64, boosted: bool) -> f64 {
        self.limits(boosted).0.min(self.feed_mm_s * ovr)
    }

    /// The level the section is planned at for override `ovr`: the boost limits only where
    /// the override asks for more speed than the base level allows and the boost level
    /// has it (its accelerations are lower, so it is not used otherwise).
    pub(crate) fn wants_boost(&self, ovr: f64) -> bool {
        self.v_boost_mm_s > self.v_machine_mm_s && self.feed_mm_s * ovr > self.v_machine_mm_s
    }
}
