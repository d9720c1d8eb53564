//! Halving a piece where its halves follow the curve's third derivative better: the
//! time at constant speed within the axis limits, of the whole piece and of its halves.

use kerf_geom::Transition;

use super::{
    EndFrame, Knot, PieceCurves, RATE_SPLIT_FEED_MARGIN, RATE_SPLIT_GAIN, RATE_SPLIT_MIN_MM,
    RATE_SPLIT_MIN_VERTICES, Run,
};

impl Run {
    /// Where a piece should be halved because its halves follow the curve better: the
    /// vertex between the knots if the two halves, each at the highest speed at which its
    /// geometry can be run at constant speed (see [`Run::constant_speed_time`]), take at
    /// most [`RATE_SPLIT_GAIN`] of the whole piece's time. A quintic over 2 mm of a 3 mm
    /// wave overshoots the wave's third derivative by up to half (at constant speed an
    /// axis's jerk is `p'''·v³`), and a piece runs at the lowest speed its whole length
    /// allows. Pieces that run at the feed either way are never split.
    pub(super) fn rate_split(
        &self,
        ka: &Knot,
        kb: &Knot,
        whole: &Transition,
        finish: bool,
        end_frame: Option<EndFrame>,
    ) -> Option<(Knot, PieceCurves, PieceCurves)> {
        let n = kb.idx - ka.idx;
        // A run's first and last pieces are where it starts from or stops at a corner: a
        // piece there gets a budget for the ramp (`crate::budget::ramp_budget`), which a
        // ramp spread over two halves would run partly without.
        let run_end = ka.idx == 0 || (finish && kb.idx == self.last_idx());
        if run_end || n < 2 * RATE_SPLIT_MIN_VERTICES || whole.length_mm < 2.0 * RATE_SPLIT_MIN_MM {
            return None;
        }
        let (t_whole, feed_bound) = self.constant_speed_time(whole, ka.idx, kb.idx);
        // No finite time (a zero limit, which `kerf` refuses in its configuration but a
        // `Planner` is not kept from): nothing to gain.
        if feed_bound || !t_whole.is_finite() {
            return None;
        }
        let mid = ka.idx + n / 2;
        let km = self.knot_at(mid, finish, end_frame);
        let first = self.piece(ka, &km)?;
        let second = self.piece(&km, kb)?;
        let halves = self.constant_speed_time(&first.0, ka.idx, mid).0
            + self.constant_speed_time(&second.0, mid, kb.idx).0;
        (halves <= RATE_SPLIT_GAIN * t_whole).then_some((km, first, second))
    }

    /// A piece's time at the highest constant speed at which every axis of X, Y, Z stays
    /// within its velocity, acceleration and jerk limits (`|p_s|·v`, `|p_ss|·v²`,
    /// `|p_sss|·v³`, derivatives along the path taken as those in the piece's parameter
    /// over its speed, which is nearly the arc length's), capped by the lowest feed of the
    /// moves between vertices `ia` and `ib` (times [`RATE_SPLIT_FEED_MARGIN`]); samples
    /// every 1/32 of the parameter. Also whether that cap is what bounds it.
    pub(super) fn constant_speed_time(&self, tr: &Transition, ia: u64, ib: u64) -> (f64, bool) {
        let cap = self.min_feed(ia, ib) * RATE_SPLIT_FEED_MARGIN;
        let mut v = cap;
        for i in 0..=32 {
            let u = f64::from(i) / 32.0;
            let d1 = tr.d1(u);
            let sigma = d1.norm();
            let (p1, p2, p3) = (
                d1 / sigma,
                tr.d2(u) / (sigma * sigma),
                tr.d3(u) / (sigma * sigma * sigma),
            );
            for (ax, [vel, acc, jerk]) in self.xyz_limits.iter().enumerate() {
                v = v
                    .min(vel / p1[ax].abs())
                    .min((acc / p2[ax].abs()).sqrt())
                    .min((jerk / p3[ax].abs()).cbrt());
            }
        }
        if v.is_finite() && v > 0.0 {
            (tr.length_mm / v, v >= cap)
        } else {
            (f64::INFINITY, false)
        }
    }
}
