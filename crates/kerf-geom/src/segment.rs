//! [`PlannedSegment`]: the unit of work the planner hands to the motion core.

use crate::PerAxis;
use crate::{Curve, Transition, quintic};

/// The motion core (`kerf-motion`) merges consecutive segments into one section while
/// their acceleration limits are at least this fraction of the section's first one's (the
/// planner's ramp budgets judge what a piece costs the section it joins by the same rule).
/// A section runs at the least of its segments' limits, and a boundary costs a return to
/// `a = 0`: the ratio trades the one against the other where smoothed pieces' budgets vary
/// along a path (looser runs whole sections at a lower limit, tighter puts boundaries
/// between pieces whose budgets differ slightly; `docs/PERFORMANCE.md` has the
/// measurements).
pub const MERGE_RATIO: f64 = 0.9;
/// The same for the jerk limit (see [`MERGE_RATIO`]).
/// It is looser than [`MERGE_RATIO`]: running a section at a lower jerk only lengthens its
/// ramps by `a/j`, while a boundary in the middle of a ramp is a stall. Much looser lets a
/// piece with far less jerk than its neighbours slow a whole section's ramps; tighter
/// splits sections where a path changes slope.
pub const MERGE_RATIO_JERK: f64 = 0.8;
/// A segment whose acceleration is below [`MERGE_RATIO`] of a section's first one's but
/// not below this fraction of it still joins the section where the section is at the
/// queue's end, short enough that the stop there reaches back into it, and the join
/// lowers no speed the lookahead has given ([`limits_merge_weaker`],
/// [`weaker_merge_keeps_lookahead`]). Near a stop a boundary between such pieces is a
/// return to `a = 0` in the middle of the braking, where running the pieces as one
/// section at the weaker one's limits brakes through.
pub const MERGE_RATIO_WEAKER: f64 = 0.8;
/// Nor does a segment join a section whose first segment has less than `1/MERGE_ABOVE` of
/// its acceleration or jerk: it would run its own ramps at the section's much lower
/// limits (a line behind a short corner blend would stop with the blend's much lower
/// jerk). Below this factor a boundary (a return to `a = 0`) costs more than the lower
/// limits do: the budgets of neighbouring smoothed pieces differ by up to about 3 × along
/// a raster row.
pub const MERGE_ABOVE: f64 = 4.0;
/// Sections merge segments whose speed limit and feed are at least this fraction of the
/// first one's (slower speed limits: [`MERGE_RATIO_SLOWER`]). It is tight because the
/// lookahead's speed at a section boundary uses this conservative value: a boundary
/// inside constant-feed code costs at most 1 % of the feed.
pub const MERGE_RATIO_SPEED: f64 = 0.99;
/// A segment slower than a section's first one by at most this ratio (but by more than
/// [`MERGE_RATIO_SPEED`]) still joins it, the section then running at its speed, where
/// that is safe (`kerf-motion`'s `MotionCore::push`: nothing committed faster): a boundary
/// between pieces whose speeds differ by a few per cent is a return to `a = 0`, and a
/// chain of them lets a slow-down shed only a few mm/s per section. 3 % balances steep
/// rasters, which gain from a looser ratio, against other CAM code, which loses.
pub const MERGE_RATIO_SLOWER: f64 = 0.97;
/// Whether a segment with path acceleration `accel_mm_s2` and jerk `jerk_mm_s3` passes the
/// limit part of the motion core's merge rule for a section whose first segment has
/// `first = (acceleration, jerk)`: within [`MERGE_RATIO`] and [`MERGE_RATIO_JERK`] of it
/// from below, and [`MERGE_ABOVE`] from above. The motion core merges by this function
/// (and also compares speeds and the junction cap); the planner's ramp budgets use it to
/// estimate the section a piece runs in.
pub fn limits_merge(accel_mm_s2: f64, jerk_mm_s3: f64, first: (f64, f64)) -> bool {
    accel_mm_s2 >= MERGE_RATIO * first.0
        && jerk_mm_s3 >= MERGE_RATIO_JERK * first.1
        && accel_mm_s2 <= MERGE_ABOVE * first.0
        && jerk_mm_s3 <= MERGE_ABOVE * first.1
}
/// Whether a segment with path acceleration `accel_mm_s2` and jerk `jerk_mm_s3`, weaker
/// than [`limits_merge`] allows, is within the window of the weaker merge
/// ([`MERGE_RATIO_WEAKER`]) of a section whose first segment has `first = (acceleration,
/// jerk)`: its acceleration at least [`MERGE_RATIO_WEAKER`] of the first's (and not above
/// it), its jerk within the merge rule's bounds ([`MERGE_RATIO_JERK`] below, [`MERGE_ABOVE`]
/// above). The join also needs [`weaker_merge_keeps_lookahead`]. A segment that joins so
/// becomes the section's reference for the merge rule where its limits are lower: `first`
/// becomes the lesser of the two in each.
///
/// (Bounding the jerk from above by `1/MERGE_RATIO_JERK` instead, so that a stop piece with
/// far more jerk keeps its own section, lost the 14 ms this rule gains on the sweep case it
/// was made for and made the sweep's worst losses 3 ms instead of up to 16 ms against the
/// build before it; with the merge rule's bound no sweep case is slower than the build issue
/// 31 started from: `docs/PERFORMANCE.md`.)
pub fn limits_merge_weaker(accel_mm_s2: f64, jerk_mm_s3: f64, first: (f64, f64)) -> bool {
    accel_mm_s2 >= MERGE_RATIO_WEAKER * first.0
        && accel_mm_s2 <= first.0
        && jerk_mm_s3 >= MERGE_RATIO_JERK * first.1
        && jerk_mm_s3 <= MERGE_ABOVE * first.1
}
/// The highest speed a section `length_mm` long can be entered at, mm/s: its cap
/// `cap_mm_s`, or the speed from which it can come down to `end_mm_s` (or to rest) within
/// its length ([`BACKWARD_MARGIN`](crate::ramp::BACKWARD_MARGIN) of it) at acceleration
/// and jerk `limits`, whichever is less. The motion core's backward pass computes every
/// start speed of its lookahead by it; the section at the queue's end has `end_mm_s` 0.
pub fn entry_speed(cap_mm_s: f64, end_mm_s: f64, length_mm: f64, limits: (f64, f64)) -> f64 {
    cap_mm_s.min(crate::ramp::reach_back(
        end_mm_s,
        length_mm * crate::ramp::BACKWARD_MARGIN,
        limits.0,
        limits.1,
    ))
}
/// The conservative acceleration and jerk of a section whose merge reference (its first
/// segment's, see [`limits_merge`]) is `reference`: [`MERGE_RATIO`] and
/// [`MERGE_RATIO_JERK`] of it, which every segment of the section has at least. The motion
/// core's hard lookahead runs at them.
pub fn conservative_limits(reference: (f64, f64)) -> (f64, f64) {
    (MERGE_RATIO * reference.0, MERGE_RATIO_JERK * reference.1)
}
/// How a segment joins a section: by the merge rule ([`limits_merge_into`]), or by the
/// weaker merge ([`MERGE_RATIO_WEAKER`]), which founds the section's reference anew.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MergeKind {
    /// By the merge rule: the section's reference stays.
    Plain,
    /// By the weaker merge: the reference becomes the lesser of the two.
    Weaker,
}
/// The lookahead condition of the weaker merge ([`MERGE_RATIO_WEAKER`]): the tail
/// section's hard start speed `hard_mm_s` is below its cap `cap_mm_s` (the stop at the
/// queue's end reaches back into it: it is short, and the pieces near a stop are what the
/// rule is for), and with the segment in it (`cap_after_mm_s`, `length_after_mm`, the
/// conservative limits after `c_after`, see [`entry_speed`] with an end speed of 0) it is
/// not below
/// `hard_mm_s`: the section before may have been given, and committed to, that speed.
pub fn weaker_merge_keeps_lookahead(
    (hard_mm_s, cap_mm_s): (f64, f64),
    cap_after_mm_s: f64,
    length_after_mm: f64,
    c_after: (f64, f64),
) -> bool {
    hard_mm_s >= 0.0
        && hard_mm_s < cap_mm_s
        && entry_speed(cap_after_mm_s, 0.0, length_after_mm, c_after) >= hard_mm_s
}
/// A straight segment no longer than this share of a section's first segment joins it
/// however much higher its acceleration and jerk are ([`MERGE_ABOVE`] does not bound
/// them; see [`limits_merge_into`]).
///
/// A line carries the axes' own acceleration and jerk, several times what a curve's
/// budget on the same axes leaves, and it scales with them where the curve's does not:
/// raising an axis limit lifted the short lines of a chain of corner blends (the 2 µm
/// remnants between narrowed blends, the short facets between them) above
/// [`MERGE_ABOVE`] times the blends', and every one of them became a section boundary, a
/// return to `a = 0`: the raise slowed the chain by 2–4 %. Run at the section's limits, a
/// line no longer than the curve before it costs little. Curved pieces keep the bound
/// (letting short smoothed pieces join from above slowed raster A by 0.4 %).
pub const MERGE_SHORT_SHARE: f64 = 1.0;
/// [`limits_merge`] for a segment of `length_mm` (`straight`: a line) joining a section
/// whose first segment is `first_mm` long: a line at most [`MERGE_SHORT_SHARE`] of that
/// needs only the lower bounds ([`MERGE_RATIO`], [`MERGE_RATIO_JERK`]). The motion core
/// merges by this function, and so does the planner's estimate of the sections its
/// segments form; its ramp budgets price a piece with [`limits_merge`] (pieces are
/// curves).
pub fn limits_merge_into(
    accel_mm_s2: f64,
    jerk_mm_s3: f64,
    (straight, length_mm): (bool, f64),
    first: (f64, f64),
    first_mm: f64,
) -> bool {
    limits_merge(accel_mm_s2, jerk_mm_s3, first)
        || (straight
            && length_mm <= MERGE_SHORT_SHARE * first_mm
            && accel_mm_s2 >= MERGE_RATIO * first.0
            && jerk_mm_s3 >= MERGE_RATIO_JERK * first.1)
}
/// Whether a segment with speed limit `v_mm_s` passes the speed part of the motion core's
/// merge rule for a section whose first segment has `first_v_mm_s`: the motion core keeps
/// a conservative speed `c_v_mm_s` for the section ([`MERGE_RATIO_SPEED`] of the least
/// speed limit of its segments, `MERGE_RATIO_SPEED · first_v_mm_s` for the first alone),
/// and a segment joins when its speed limit is at least the lesser of that and
/// [`MERGE_RATIO_SLOWER`] of the first's (below the conservative speed the motion core
/// also asks that nothing was committed faster, which at the tail holds almost always),
/// and at most `c_v_mm_s / MERGE_RATIO_SPEED²`: a segment after a slightly slower one is
/// compared with that one. The planner's estimate of the section a piece runs in uses it.
pub fn speeds_merge_into(v_mm_s: f64, first_v_mm_s: f64, c_v_mm_s: f64) -> bool {
    v_mm_s >= (MERGE_RATIO_SLOWER * first_v_mm_s).min(c_v_mm_s)
        && v_mm_s * MERGE_RATIO_SPEED * MERGE_RATIO_SPEED <= c_v_mm_s
}
/// One segment ready for the motion core: geometry plus its limits along the path.
///
/// The path parameter `s` runs over `[0, length_mm]`; it is the XYZ arc length in mm, or,
/// for a move of rotary axes only, the length of the rotary motion in degrees. Every
/// limit below is in path units, so the `mm` in the names of its fields reads `deg` on
/// such a rotary-only segment (`feed_mm_s` is then deg/s, and so on).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlannedSegment {
    /// XYZ geometry.
    pub curve: Curve,
    /// A, B, C at the start, degrees (they move linearly with `s`, unless `abc_poly`).
    pub abc_start_deg: [f64; 3],
    /// A, B, C at the end, degrees.
    pub abc_end_deg: [f64; 3],
    /// On a smoothed piece with rotary motion: A, B, C as quintics in the parameter `u`
    /// of the piece's [`Transition`] curve (power basis, degrees), curvature-continuous
    /// with the neighbouring pieces. `None`: linear in `s`.
    pub abc_poly: Option<[[f64; 6]; 3]>,
    /// Length of the path parameter, mm (deg for rotary-only moves).
    pub length_mm: f64,
    /// Source line.
    pub line: u32,
    /// Index of the source move in program order (0-based), for path-deviation checks.
    pub move_index: u64,
    /// Number of programmed moves the segment stands for, from `move_index` on: 1, or more
    /// for a smoothed piece of a dense polyline.
    pub move_count: u32,
    /// Programmed feed, mm/s (path units/s); infinite for rapids.
    pub feed_mm_s: f64,
    /// Machine speed limit on this segment (axes and curvature; on curved segments also the
    /// programmed feed), mm/s. `accel_mm_s2` and `jerk_mm_s3` are valid for speeds up to
    /// this.
    pub v_max_mm_s: f64,
    /// Path acceleration limit, mm/s².
    pub accel_mm_s2: f64,
    /// Path jerk limit, mm/s³.
    pub jerk_mm_s3: f64,
    /// Speed limit while the feed override is above 100 %, mm/s (at least `v_max_mm_s`):
    /// curved segments are also designed for the highest override where that is faster.
    /// `accel_boost_mm_s2` and `jerk_boost_mm_s3` are valid for every speed up to it.
    pub v_boost_mm_s: f64,
    /// Path acceleration limit valid up to `v_boost_mm_s` (at most `accel_mm_s2`), mm/s².
    pub accel_boost_mm_s2: f64,
    /// Path jerk limit valid up to `v_boost_mm_s` (at most `jerk_mm_s3`), mm/s³.
    pub jerk_boost_mm_s3: f64,
    /// Speed cap at the junction with the next segment, mm/s (0 = stop): the geometric
    /// cap, at most this segment's `v_boost_mm_s` and, as designed, the next one's (their
    /// `v_max_mm_s` bounds it at 100 %). The planner may lower a smoothed piece's design
    /// speed at a stop after the cap before it was sent, so the motion core passes every
    /// junction at most at the lesser of the cap and the speed limits on both sides.
    pub end_cap_mm_s: f64,
    /// `true` if the segment is a corner blend (not a programmed move).
    pub blend: bool,
}

impl PlannedSegment {
    /// A segment of one programmed move (not a blend) on `curve`, its path parameter
    /// running over `[0, length_mm]` (mm, or deg for rotary-only moves), A, B, C moving
    /// linearly from `abc_deg.0` to `abc_deg.1`, at programmed feed `feed_mm_s`; every
    /// limit (`v_max_mm_s` to `end_cap_mm_s`) is 0 until the planner sets it.
    pub fn with_zero_limits(
        curve: Curve,
        length_mm: f64,
        abc_deg: ([f64; 3], [f64; 3]),
        line: u32,
        move_index: u64,
        feed_mm_s: f64,
    ) -> Self {
        PlannedSegment {
            curve,
            abc_start_deg: abc_deg.0,
            abc_end_deg: abc_deg.1,
            abc_poly: None,
            length_mm,
            line,
            move_index,
            move_count: 1,
            feed_mm_s,
            v_max_mm_s: 0.0,
            accel_mm_s2: 0.0,
            jerk_mm_s3: 0.0,
            v_boost_mm_s: 0.0,
            accel_boost_mm_s2: 0.0,
            jerk_boost_mm_s3: 0.0,
            end_cap_mm_s: 0.0,
            blend: false,
        }
    }

    /// Positions of all six axes at path parameter `s`.
    #[inline]
    pub fn position_at(&self, s: f64, out: &mut PerAxis<f64>) {
        if let (Some(c), Curve::Transition(t)) = (&self.abc_poly, &self.curve) {
            if s >= self.length_mm {
                let e = t.end;
                out[..3].copy_from_slice(&[e.x, e.y, e.z]);
                out[3..6].copy_from_slice(&self.abc_end_deg);
            } else if s <= 0.0 {
                let p = t.start;
                out[..3].copy_from_slice(&[p.x, p.y, p.z]);
                out[3..6].copy_from_slice(&self.abc_start_deg);
            } else {
                let u = t.param_at(s);
                let p = t.poly(u);
                out[..3].copy_from_slice(&[p.x, p.y, p.z]);
                for i in 0..3 {
                    out[3 + i] = poly5(&c[i], u);
                }
            }
            return;
        }
        let p = if self.curve.length() > 0.0 {
            self.curve.point_at(s)
        } else {
            self.curve.start()
        };
        out[0] = p.x;
        out[1] = p.y;
        out[2] = p.z;
        if s >= self.length_mm {
            out[3..6].copy_from_slice(&self.abc_end_deg);
        } else {
            let u = if self.length_mm > 0.0 {
                (s / self.length_mm).max(0.0)
            } else {
                1.0
            };
            for i in 0..3 {
                out[3 + i] =
                    self.abc_start_deg[i] + (self.abc_end_deg[i] - self.abc_start_deg[i]) * u;
            }
        }
    }

    /// Derivatives with respect to `s` of all six axes at `s`: (tangent, curvature).
    pub fn derivatives_at(&self, s: f64) -> (PerAxis<f64>, PerAxis<f64>) {
        let mut t = [0.0; 6];
        let mut k = [0.0; 6];
        if self.curve.length() > 0.0 {
            let e = self.curve.eval(s);
            for i in 0..3 {
                t[i] = e.tangent[i];
                k[i] = e.curvature[i];
            }
        }
        if let (Some(c), Curve::Transition(tr)) = (&self.abc_poly, &self.curve) {
            let u = tr.param_at(s);
            let (rt, rk) = rotary_derivatives(tr, c, u);
            t[3..6].copy_from_slice(&rt);
            k[3..6].copy_from_slice(&rk);
        } else if self.length_mm > 0.0 {
            for i in 0..3 {
                t[3 + i] = (self.abc_end_deg[i] - self.abc_start_deg[i]) / self.length_mm;
            }
        }
        (t, k)
    }
}

/// `Σ c[k] uᵏ`: a quintic in power basis, as in [`PlannedSegment::abc_poly`].
#[inline]
pub fn poly5(c: &[f64; 6], u: f64) -> f64 {
    quintic::value(c, u)
}

/// Derivatives of rotary quintics `c` (in the parameter `u` of `tr`) with respect to the
/// XYZ arc length at `u`: `dA/ds = A'/|p'|`, `d²A/ds² = (A'' - A' (p'·p'')/|p'|²)/|p'|²`.
pub fn rotary_derivatives(tr: &Transition, c: &[[f64; 6]; 3], u: f64) -> ([f64; 3], [f64; 3]) {
    let q = tr.d1(u);
    let r = tr.d2(u);
    let sq = q.norm_squared();
    let speed = sq.sqrt();
    let along = q.dot(&r) / sq;
    let mut t = [0.0; 3];
    let mut k = [0.0; 3];
    for i in 0..3 {
        let (d1, d2) = quintic::d1_d2_scaled_coef(&c[i], u);
        t[i] = d1 / speed;
        k[i] = (d2 - d1 * along) / sq;
    }
    (t, k)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Vec3;

    #[test]
    fn zero_limit_segment_moves_rotary_axes_linearly_along_the_line() {
        // A 3-4-5 line in XY with A going from 10° to 40°.
        let curve = Curve::line(Vec3::new(1.0, 1.0, 0.0), Vec3::new(4.0, 5.0, 0.0));
        let seg = PlannedSegment::with_zero_limits(
            curve,
            5.0,
            ([10.0, 0.0, 0.0], [40.0, 0.0, 0.0]),
            7,
            3,
            25.0,
        );
        let limits = [
            seg.v_max_mm_s,
            seg.accel_mm_s2,
            seg.jerk_mm_s3,
            seg.v_boost_mm_s,
            seg.accel_boost_mm_s2,
            seg.jerk_boost_mm_s3,
            seg.end_cap_mm_s,
        ];
        assert_eq!(limits, [0.0; 7]);
        assert!(!seg.blend && seg.move_count == 1 && seg.abc_poly.is_none());
        let mut p = [0.0; 6];
        seg.position_at(2.5, &mut p);
        let expect = [2.5, 3.0, 0.0, 25.0, 0.0, 0.0];
        for i in 0..6 {
            assert!((p[i] - expect[i]).abs() < 1e-12, "axis {i}: {p:?}");
        }
        // dA/ds = 30° over 5 mm.
        let (t, _) = seg.derivatives_at(1.0);
        assert!(
            (t[3] - 6.0).abs() < 1e-12 && (t[0] - 0.6).abs() < 1e-12,
            "{t:?}"
        );
    }
}
