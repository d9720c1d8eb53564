//! A section: consecutive segments the core runs as one jerk-limited profile, with the
//! limits (actual and conservative, at the base and the boost level) and the lookahead
//! speeds the core keeps for it.

use kerf_geom::{MERGE_RATIO, MERGE_RATIO_JERK, MERGE_RATIO_SPEED, PlannedSegment};

#[derive(Clone, Copy, Debug)]
pub(crate) struct Section {
    /// Absolute index of the first segment.
    pub(crate) first: u64,
    pub(crate) count: u64,
    pub(crate) length: f64,
    /// Actual limits: minima over segments and interior junction caps.
    pub(crate) v_machine: f64,
    pub(crate) feed: f64,
    pub(crate) accel: f64,
    pub(crate) jerk: f64,
    /// The same for a feed override above 100 % (the segments' `v_boost`,
    /// `accel_boost`, `jerk_boost`; the accelerations are at most the ones above).
    pub(crate) v_boost: f64,
    pub(crate) accel_boost: f64,
    pub(crate) jerk_boost: f64,
    /// Speed limits of the first segment, base and boost level (see
    /// [`MERGE_RATIO_SLOWER`](crate::MERGE_RATIO_SLOWER)).
    pub(crate) v_first: f64,
    pub(crate) v_first_boost: f64,
    /// Acceleration and jerk limits of the first segment: the merge rule's reference
    /// ([`limits_merge`](kerf_geom::limits_merge)); the hard lookahead's are their merge ratios
    /// ([`Section::c_accel_jerk`]).
    pub(crate) accel_jerk_first: (f64, f64),
    /// Conservative limits fixed at creation (hard lookahead); the speeds are lowered when
    /// a slightly slower segment joins (see [`MERGE_RATIO_SLOWER`](crate::MERGE_RATIO_SLOWER)).
    pub(crate) c_v: f64,
    pub(crate) c_feed: f64,
    /// The same for the boost level.
    pub(crate) c_v_boost: f64,
    pub(crate) c_accel_boost: f64,
    pub(crate) c_jerk_boost: f64,
    /// Cap at the junction before the section.
    pub(crate) start_cap: f64,
    /// Hard lookahead at the base level (valid while the section runs with its base limits).
    pub(crate) hard_start: f64,
    pub(crate) hard_end: f64,
    /// Hard lookahead at the boost level (valid with the boost limits, at any override).
    pub(crate) hard_start_boost: f64,
    pub(crate) hard_end_boost: f64,
    pub(crate) soft_start: f64,
    pub(crate) soft_end: f64,
    /// The level the section runs at, fixed when it starts (see `plan_section_start`).
    pub(crate) boosted: bool,
}

impl Section {
    /// A placeholder for the queue's free slots.
    pub(crate) const EMPTY: Section = Section {
        first: 0,
        count: 0,
        length: 0.0,
        v_machine: 0.0,
        feed: 0.0,
        accel: 0.0,
        jerk: 0.0,
        v_boost: 0.0,
        accel_boost: 0.0,
        jerk_boost: 0.0,
        v_first: 0.0,
        v_first_boost: 0.0,
        c_v: 0.0,
        c_feed: 0.0,
        accel_jerk_first: (0.0, 0.0),
        c_v_boost: 0.0,
        c_accel_boost: 0.0,
        c_jerk_boost: 0.0,
        start_cap: 0.0,
        hard_start: 0.0,
        hard_end: 0.0,
        hard_start_boost: 0.0,
        hard_end_boost: 0.0,
        soft_start: 0.0,
        soft_end: 0.0,
        boosted: false,
    };

    /// The section of the one segment `seg` (absolute index `first`, boost-level limits
    /// `boost`) after a junction capped at `start_cap` (mm/s); its lookahead speeds are
    /// not computed yet.
    pub(crate) fn of_segment(
        first: u64,
        seg: &PlannedSegment,
        (seg_vb, seg_ab, seg_jb): (f64, f64, f64),
        start_cap: f64,
    ) -> Section {
        Section {
            first,
            count: 1,
            length: seg.length_mm,
            v_machine: seg.v_max_mm_s,
            feed: seg.feed_mm_s,
            accel: seg.accel_mm_s2,
            jerk: seg.jerk_mm_s3,
            v_first: seg.v_max_mm_s,
            v_first_boost: seg_vb,
            c_v: MERGE_RATIO_SPEED * seg.v_max_mm_s,
            c_feed: MERGE_RATIO_SPEED * seg.feed_mm_s,
            accel_jerk_first: (seg.accel_mm_s2, seg.jerk_mm_s3),
            v_boost: seg_vb,
            accel_boost: seg_ab,
            jerk_boost: seg_jb,
            c_v_boost: MERGE_RATIO_SPEED * seg_vb,
            c_accel_boost: MERGE_RATIO * seg_ab,
            c_jerk_boost: MERGE_RATIO_JERK * seg_jb,
            start_cap,
            hard_start: -1.0,
            hard_end: 0.0,
            hard_start_boost: -1.0,
            hard_end_boost: 0.0,
            soft_start: -1.0,
            soft_end: 0.0,
            boosted: false,
        }
    }
    /// The conservative acceleration and jerk of the hard lookahead: the merge ratios of
    /// the first segment's, which every segment of the section has at least.
    pub(crate) fn c_accel_jerk(&self) -> (f64, f64) {
        let (a, j) = self.accel_jerk_first;
        (MERGE_RATIO * a, MERGE_RATIO_JERK * j)
    }

    /// Speed limit, acceleration and jerk at a level.
    pub(crate) fn limits(&self, boosted: bool) -> (f64, f64, f64) {
        if boosted {
            (self.v_boost, self.accel_boost, self.jerk_boost)
        } else {
            (self.v_machine, self.accel, self.jerk)
        }
    }

    /// The hard end speed at a level.
    pub(crate) fn hard_end_at(&self, boosted: bool) -> f64 {
        if boosted {
            self.hard_end_boost
        } else {
            self.hard_end
        }
    }

    /// Speed at override `ovr` and a level: the machine limit or the scaled feed.
    pub(crate) fn v_eff(&self, ovr: f64, boosted: bool) -> f64 {
        self.limits(boosted).0.min(self.feed * ovr)
    }

    /// The level the section is planned at for override `ovr`: the boost limits only where
    /// the override asks for more speed than the base level allows and the boost level
    /// has it (its accelerations are lower, so it is not used otherwise).
    pub(crate) fn wants_boost(&self, ovr: f64) -> bool {
        self.v_boost > self.v_machine && self.feed * ovr > self.v_machine
    }
}
