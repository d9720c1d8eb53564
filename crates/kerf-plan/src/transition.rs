//! G2 transitions at joints with programmed arcs: the neighbours are trimmed and a
//! quintic matching position, tangent and curvature at both ends is inserted where that
//! runs the joint faster within the tolerance.

use kerf_geom::{Curve, Transition};

use crate::DESIGN_RUN_MM;
use crate::junction::junction_cap;
use crate::memo::{KEY_ARC_LENGTH, KEY_WORDS};
use crate::planner::Planner;
use crate::{
    DEVIATION_SAMPLES, MIN_REMNANT_MM, MIN_SEGMENT_MM, PlannedSegment, TRANSITION_TOL_SHARE,
};

/// Factor by which the transition length shrinks per try: 15 % steps find a length
/// within 15 % of the largest that fits, in few tries.
const TRANSITION_SHRINK: f64 = 0.85;
/// Tries before a joint is left without a transition: `0.85⁴⁸ ≈ 4e-4`, so the search spans
/// more than three decades below its start.
const TRANSITION_TRIES: usize = 48;
/// Largest share of a neighbouring segment a transition may take: 45 %, so a piece between
/// two transitions keeps a tenth of its length (no slivers between fast transitions).
pub const TRANSITION_SHARE_OF_MOVE: f64 = 0.45;
/// Longest time a transition slower than [`CRAWL_SPEED_RATIO`] of the neighbours' speed
/// may take, s: 20 ms, beyond which crawling round a sharp kink is slower than stopping
/// at it.
const MAX_CRAWL_S: f64 = 0.02;
/// Below this share of the neighbours' speed a transition counts as a crawl (see
/// [`MAX_CRAWL_S`]): 30 %. Somewhat below it crawling round a sharp joint (a 90° joint
/// between a rapid and an arc, say, with a short transition) already loses to a stop.
const CRAWL_SPEED_RATIO: f64 = 0.3;
/// A joint already passable at this share of its neighbours' speed gets no transition:
/// at most 10 % would be gained, not worth trimming two programmed moves.
const FAST_JOINT_RATIO: f64 = 0.9;
/// A transition is kept only if it raises the joint speed by this factor: gains under
/// 5 % do not pay for the extra segment (and section boundary) it adds.
const MIN_TRANSITION_GAIN: f64 = 1.05;
/// First try of the transition reach against a curvature step, × `sqrt(tol/Δκ)`: about
/// five times the estimate `sqrt(6·tol/Δκ)`, so the shrinking tries start above the
/// largest reach that fits.
const CURVATURE_START_FACTOR: f64 = 12.0;
/// First try of the transition reach against a kink, × `tol/Δt`: four times the estimate
/// `4·tol/Δt`, for the same reason.
const KINK_START_FACTOR: f64 = 16.0;
/// Shortest transition reach tried, mm: 1 nm, the motion core's coast-through length
/// (`kerf_motion::COAST_BELOW_MM`), below which a transition could not be profiled.
const MIN_TRANSITION_MM: f64 = 1e-6;

impl Planner {
    /// `tr` with its arc-length table (`Transition::with_arc_length`), from the memo when
    /// a transition with the same coefficients of degree 1 and up (all the table depends
    /// on) had one made.
    fn with_arc_length(&self, tr: Transition) -> Option<Transition> {
        let mut key = [0u64; KEY_WORDS];
        key[0] = KEY_ARC_LENGTH;
        for (k, c) in tr.coef[1..].iter().enumerate() {
            for i in 0..3 {
                key[1 + 3 * k + i] = c[i].to_bits();
            }
        }
        let found = self.arc_memo.borrow().get(&key);
        let arc = found.unwrap_or_else(|| {
            let arc = tr.with_arc_length().map(|t| (t.length_mm, t.table));
            self.arc_memo.borrow_mut().put(key, arc);
            arc
        });
        arc.map(|(length_mm, table)| Transition {
            length_mm,
            table,
            ..tr
        })
    }

    /// A curvature-continuous transition for the joint from `prev` to `seg`, if the joint
    /// involves a programmed arc, has a curvature jump or kink that caps the speed, and a
    /// transition within `tol` of the programmed path runs faster: `(prev trimmed at its
    /// end, transition, seg trimmed at its start)`.
    pub(crate) fn transition(
        &self,
        prev: &PlannedSegment,
        seg: &PlannedSegment,
        tol: f64,
        origin: Option<&Curve>,
    ) -> Option<(PlannedSegment, PlannedSegment, PlannedSegment)> {
        let (Some(o_prev), Some(o_seg)) = (self.last_origin.as_ref(), origin) else {
            return None;
        };
        if !(tol > 0.0 && tol.is_finite()) || prev.blend || seg.blend {
            return None;
        }
        let is_arc = |s: &PlannedSegment| matches!(s.curve, Curve::Helix(_));
        if !(is_arc(prev) || is_arc(seg)) {
            return None;
        }
        let still = |s: &PlannedSegment| s.abc_start_deg == s.abc_end_deg;
        if !still(prev) || !still(seg) || seg.move_index > prev.move_index + 1 {
            return None;
        }
        let (la, lb) = (prev.curve.length(), seg.curve.length());
        if la < MIN_SEGMENT_MM || lb < MIN_SEGMENT_MM {
            return None;
        }
        let v_ref = prev
            .v_max_mm_s
            .min(seg.v_max_mm_s)
            .min(prev.feed_mm_s)
            .min(seg.feed_mm_s);
        let old = junction_cap(prev, seg, &self.limits);
        if old >= FAST_JOINT_RATIO * v_ref {
            return None;
        }
        let ea = prev.curve.eval(la);
        let eb = seg.curve.eval(0.0);
        let dk = (eb.curvature - ea.curvature).norm();
        let dt = (eb.tangent - ea.tangent).norm();
        // Room: at most [`TRANSITION_SHARE_OF_MOVE`] of each neighbour as it came, so that a
        // piece between two transitions keeps a tenth of its length (and at least
        // [`MIN_REMNANT_MM`]): a sliver of a segment between two fast transitions would be a
        // section the profile generator can fail on.
        let room_a = (TRANSITION_SHARE_OF_MOVE * self.last_full_length).min(la - MIN_REMNANT_MM);
        let room_b = (TRANSITION_SHARE_OF_MOVE * lb).min(lb - MIN_REMNANT_MM);
        if room_a <= 0.0 || room_b <= 0.0 {
            return None;
        }
        let mut d = room_a.min(room_b);
        // Start above the estimates (a curvature ramp of Δκ over 2d sits about
        // Δκ(2d)²/24 off the path; a kink of Δt cuts its corner by about dΔt/4) and shrink.
        if dk > 0.0 {
            d = d.min(CURVATURE_START_FACTOR * (tol / dk).sqrt());
        }
        if dt > 0.0 {
            d = d.min(KINK_START_FACTOR * tol / dt);
        }
        for _ in 0..TRANSITION_TRIES {
            if d < MIN_TRANSITION_MM {
                return None;
            }
            let da = d.min(room_a);
            let db = d.min(room_b);
            d *= TRANSITION_SHRINK;
            let ca = prev.curve.trimmed(0.0, la - da);
            let cb = seg.curve.trimmed(db, lb);
            let a = ca.eval(ca.length());
            let b = cb.eval(0.0);
            let lambda = (b.point - a.point).norm();
            let Some(tr) = Transition::hermite(
                a.point,
                a.tangent,
                a.curvature,
                b.point,
                b.tangent,
                b.curvature,
                lambda,
            ) else {
                continue;
            };
            // Every sample within the tolerance of either programmed path: the samples in
            // bit-reversed order (the middle first, where a transition that does not fit
            // leaves the path), the nearer path first; the same answer as checking them
            // all in order, sooner.
            let within = (0..=DEVIATION_SAMPLES).all(|n| {
                let i = deviation_sample(n);
                let p = tr.poly(i as f64 / DEVIATION_SAMPLES as f64);
                let limit = TRANSITION_TOL_SHARE * tol;
                let (near, far) = if 2 * i <= DEVIATION_SAMPLES {
                    (o_prev, o_seg)
                } else {
                    (o_seg, o_prev)
                };
                near.distance_to(&p) <= limit || far.distance_to(&p) <= limit
            });
            if !within {
                continue;
            }
            let Some(tr) = self.with_arc_length(tr) else {
                continue;
            };
            let curve = Curve::Transition(tr);
            let mut t = PlannedSegment {
                blend: true,
                ..PlannedSegment::with_zero_limits(
                    curve,
                    curve.length(),
                    (prev.abc_end_deg, prev.abc_end_deg),
                    seg.line,
                    prev.move_index,
                    prev.feed_mm_s.min(seg.feed_mm_s),
                )
            };
            // Designed like an arc: for the path that runs on without a corner up to the
            // end of `seg` (geometry only), not for its own length from rest.
            self.set_limits_for_run(&mut t, self.chain_mm.min(DESIGN_RUN_MM));
            let mut p = *prev;
            p.curve = ca;
            p.length_mm = ca.length();
            let mut s = *seg;
            s.curve = cb;
            s.length_mm = cb.length();
            let new = junction_cap(&p, &t, &self.limits)
                .min(t.v_max_mm_s)
                .min(junction_cap(&t, &s, &self.limits));
            // The largest transition within the tolerance is the fastest; take it if it
            // beats the plain joint. A crawl through a long transition (a sharp kink with a
            // small tolerance) costs more time than stopping at the kink: both need the
            // same slow-down, so only the time spent on the transition counts.
            let quick = new >= CRAWL_SPEED_RATIO * v_ref || t.length_mm <= MAX_CRAWL_S * new;
            return (new > MIN_TRANSITION_GAIN * old && quick).then_some((p, t, s));
        }
        None
    }
}

/// The `n`-th deviation sample to check (`0..=DEVIATION_SAMPLES`): the index `n` with its
/// bits reversed, so that the checks go from coarse to fine (every sample exactly once,
/// the last one last).
fn deviation_sample(n: usize) -> usize {
    const BITS: u32 = DEVIATION_SAMPLES.trailing_zeros();
    if n >= DEVIATION_SAMPLES {
        return n;
    }
    n.reverse_bits() >> (usize::BITS - BITS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deviation_samples_are_each_checked_once() {
        assert!(DEVIATION_SAMPLES.is_power_of_two());
        let mut seen = [false; DEVIATION_SAMPLES + 1];
        for n in 0..=DEVIATION_SAMPLES {
            let i = deviation_sample(n);
            assert!(!seen[i], "sample {i} twice");
            seen[i] = true;
        }
        assert!(seen.iter().all(|&s| s));
        assert_eq!(deviation_sample(1), DEVIATION_SAMPLES / 2);
    }
}
