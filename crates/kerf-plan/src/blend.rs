//! Corner blends between two lines: a circular arc, a symmetric G2 (quintic) blend at an
//! isolated corner, or a stop, whichever costs the least rough time.

use kerf_geom::{Curve, Path, Transition, Vec3};

use crate::junction::junction_cap;
use crate::planner::{Pending, Planner, corner_tolerance, feed_of};
use crate::timing::{change_time_s, reach_speed, transit_time_s};
use crate::{
    DESIGN_RUN_MM, DEVIATION_SAMPLES, MIN_REMNANT_MM, MIN_SEGMENT_MM, MachineLimits,
    PlannedSegment, TRANSITION_TOL_SHARE,
};

/// Turn angles below this are treated as collinear (no blend needed), radians: 0.1 µrad
/// bends the path by 0.1 nm per mm, far below any tolerance.
const COLLINEAR_RAD: f64 = 1e-7;
/// Turns within this of a full reversal are not blended, radians: `tan(θ/2)` (the blend's
/// reach per radius) grows without bound at π.
const REVERSAL_MARGIN_RAD: f64 = 1e-6;
/// A circular blend is sized for this share of the tolerance at its midpoint: the 2 %
/// margin keeps the evaluated arc inside the tolerance despite rounding.
const BLEND_TOL_MARGIN: f64 = 0.98;
/// Largest share of the outgoing line a blend may take: half, so the next corner's blend
/// has the other half and neighbouring blends never overlap.
const BLEND_SHARE_OF_OUTGOING: f64 = 0.5;
/// A G2 blend narrowed to its room is taken over the arc unconditionally only where it
/// reaches at least this share of the arc's distance (see [`Planner::blend`]): on facets of
/// a few micrometres the remnants it must leave ([`MIN_REMNANT_MM`]) would make it much
/// tighter than the arc, and the time estimate decides there.
const G2_NARROWED_MIN_OF_ARC: f64 = 0.5;
/// Tries confirming a G2 blend on the programmed lines after scaling it from 1 mm.
const G2_CONFIRM_TRIES: usize = 8;
/// Shrink per confirming try: 0.1 %, so the eight tries cover the rounding of the scaled
/// deviation without giving up noticeable blend size.
const G2_CONFIRM_SHRINK: f64 = 0.999;

/// Parameter scales tried for a G2 corner blend, as multiples of its chord (measured: 1.2
/// is quickest for 90°, 1.0 for shallow turns, the larger ones for reversals; three keep
/// the per-corner cost at three candidates).
pub const G2_LAMBDA_RATIOS: [f64; 3] = [1.0, 1.2, 1.5];

impl Planner {
    /// The blend for the corner between `prev` and `next` and the distance it takes from
    /// each, if the corner is blended: a circular arc, or a G2 blend
    /// ([`Planner::g2_blend`]) where that costs less time ([`corner_time_s`]) or where the
    /// widest G2 blend within the tolerance does not fit between the neighbouring corners
    /// (see below).
    pub(crate) fn blend(&self, prev: &Pending, next: &Pending) -> Option<(PlannedSegment, f64)> {
        let tol = corner_tolerance(prev.mv.corner, next.mv.corner, self.limits.tolerance_mm)?;
        if tol <= 0.0 || !tol.is_finite() {
            return None;
        }
        let (Path::Line(l1), Path::Line(l2)) = (prev.mv.path, next.mv.path) else {
            return None;
        };
        // Rotary motion on either side would need a blend in six dimensions; take those
        // corners at the junction speed instead.
        if prev.abc_start != prev.abc_end || next.abc_start != next.abc_end {
            return None;
        }
        let len1 = (l1.end - l1.start).norm();
        let len2 = (l2.end - l2.start).norm();
        if len1 < MIN_SEGMENT_MM || len2 < MIN_SEGMENT_MM {
            return None;
        }
        let u1 = (l1.end - l1.start) / len1;
        let u2 = (l2.end - l2.start) / len2;
        let cos = u1.dot(&u2).clamp(-1.0, 1.0);
        let normal = u1.cross(&u2);
        let sin = normal.norm();
        let theta = sin.atan2(cos);
        if !(COLLINEAR_RAD..=std::f64::consts::PI - REVERSAL_MARGIN_RAD).contains(&theta) {
            return None;
        }
        // Deviation at the blend midpoint is r (1 - cos(θ/2)) = 2 r sin²(θ/4).
        let s4 = (theta / 4.0).sin();
        let r_tol = BLEND_TOL_MARGIN * tol / (2.0 * s4 * s4);
        let tan_half = (theta / 2.0).tan();
        let d_tol = r_tol * tan_half;
        let d = d_tol
            .min(len1 - prev.start_trim)
            .min(len2 * BLEND_SHARE_OF_OUTGOING);
        if d < MIN_SEGMENT_MM {
            return None;
        }
        let radius = d / tan_half;
        let axis = normal / sin;
        let corner = l1.end;
        let b1 = corner - u1 * d;
        let b2 = corner + u2 * d;
        let center = b1 + axis.cross(&u1) * radius;
        let path = Path::Arc(kerf_geom::Arc {
            start: b1,
            end: b2,
            center,
            axis,
            sweep_rad: theta,
        });
        let curve = Curve::from_path(&path);
        let feed = feed_of(&prev.mv).min(feed_of(&next.mv));
        let mut seg = PlannedSegment {
            blend: true,
            ..PlannedSegment::with_zero_limits(
                curve,
                curve.length(),
                (prev.abc_end, prev.abc_end),
                next.mv.line,
                prev.move_index,
                feed,
            )
        };
        self.set_limits(&mut seg);
        // The G2 blend's room: both lines keep a remnant of at least [`MIN_REMNANT_MM`], so
        // the neighbouring blends do not meet.
        let room_mm = (len1 - prev.start_trim - MIN_REMNANT_MM)
            .min(BLEND_SHARE_OF_OUTGOING * len2 - MIN_REMNANT_MM);
        if room_mm <= 0.0 {
            return Some((seg, d));
        }
        let mut lines = self.corner_lines(&seg, u1, u2, (len1 - prev.start_trim).min(len2));
        let corner_g2 = G2Corner {
            corner,
            u1,
            u2,
            line1: Curve::line(l1.start, l1.end),
            line2: Curve::line(l2.start, l2.end),
            tol_mm: tol,
            room_mm,
            // The stand-in line in runs along `u1`: the chain before it is the one the
            // incoming line continues.
            run_in_mm: self.chain_before(&lines.0) + len1 - prev.start_trim,
        };
        // Each side at its own move's feed (the blend runs at the lesser).
        lines.0.feed_mm_s = feed_of(&prev.mv);
        lines.1.feed_mm_s = feed_of(&next.mv);
        // The blend begins where the previous corner's blend ended (they meet, as on a
        // polygon approximating an arc at a wide tolerance): it is entered from that arc,
        // not from a line through a curvature step.
        let chained_in = prev.start_trim > 0.0 && d >= len1 - prev.start_trim - MIN_REMNANT_MM;
        // The blend takes all of the outgoing line it may: the next corner's blend, if
        // any, begins where it ends, so it is left into that blend, not into a line.
        let chained_out = d >= BLEND_SHARE_OF_OUTGOING * len2 - MIN_REMNANT_MM;
        let arc_time_s = corner_time_s(&seg, d, &lines, (chained_in, chained_out), &self.limits);
        // A G2 blend narrowed to its room (on a polygon of short facets turning by a few
        // degrees, as mesh-based CAM writes) is taken over the arc whatever the estimate
        // says: there the arc takes its whole room too and meets the neighbouring corners'
        // blends through curvature steps, whose caps the estimate does not charge (chained,
        // it is judged as entered from and left into arcs like itself); the G2 blend meets
        // them at zero curvature (unless the remnants it leaves make it much tighter than
        // the arc, on facets of a few micrometres). The faceted raster of the CAM table ran
        // at 3.57 times its feed time with arcs there (to rest at most facet edges), 2.11
        // times with these.
        let (best, best_time_s) = match self.g2_blend(&corner_g2, &seg, &lines) {
            Some(g2)
                if (g2.narrowed && g2.d_mm >= G2_NARROWED_MIN_OF_ARC * d)
                    || g2.time_s < arc_time_s =>
            {
                ((g2.seg, g2.d_mm), g2.time_s)
            }
            _ => ((seg, d), arc_time_s),
        };
        // A sharp corner at a small tolerance must slow down nearly to a stop for any
        // blend, and then crawls through it: stopping at the corner is quicker there (and
        // trivially within the tolerance).
        if stop_time_s(&lines) < best_time_s {
            return None;
        }
        Some(best)
    }

    /// Stand-ins for the two lines of a corner whose blend is `blend` (in along `u1`, out
    /// along `u2`), with their limits: for the junction caps with the blend and the speed
    /// the corner is approached at.
    ///
    /// Their speed is at most what a ramp from rest reaches over `reach_mm` (the shorter
    /// of the two programmed lines): a corner between short lines is not approached at
    /// the machine's speed, and judging a stop or a blend against that speed (which a
    /// raised velocity limit raises) made short zig-zags stop where a blend is quicker.
    fn corner_lines(
        &self,
        blend: &PlannedSegment,
        u1: Vec3,
        u2: Vec3,
        reach_mm: f64,
    ) -> (PlannedSegment, PlannedSegment) {
        let mut line_in = *blend;
        line_in.blend = false;
        line_in.curve = Curve::line(blend.curve.start() - u1, blend.curve.start());
        line_in.length_mm = 1.0;
        let mut line_out = line_in;
        line_out.curve = Curve::line(blend.curve.end(), blend.curve.end() + u2);
        self.set_limits(&mut line_in);
        self.set_limits(&mut line_out);
        for l in [&mut line_in, &mut line_out] {
            let v = reach_speed(reach_mm, l.v_max_mm_s, l.accel_mm_s2, l.jerk_mm_s3);
            l.v_max_mm_s = v;
            l.v_boost_mm_s = l.v_boost_mm_s.min(v);
        }
        (line_in, line_out)
    }

    /// The symmetric G2 corner blend for `c` (zero curvature at both ends, so the joints
    /// with the lines are continuous in tangent and curvature), the distance it takes from
    /// each line and its [`corner_time_s`]: for each parameter scale of
    /// [`G2_LAMBDA_RATIOS`] the largest blend within the tolerance, and of those the
    /// quickest. `None` if none fits in `c.room_mm`. `template` gives the segment fields.
    ///
    /// Narrowed to the room, the first scale that reaches it ends the search (1.0 first:
    /// the quickest on shallow turns, where blends are narrowed): each candidate's design
    /// by search is most of a corner's planning cost, and trying all three there raised
    /// the planning of the rough surface of `plan_rate` by half again, for 0.4 % of its
    /// motion time (faceted A was 0.4 % slower with all three).
    fn g2_blend(
        &self,
        c: &G2Corner,
        template: &PlannedSegment,
        lines: &(PlannedSegment, PlannedSegment),
    ) -> Option<G2Blend> {
        if c.room_mm.is_nan() || c.room_mm <= 0.0 {
            return None;
        }
        let limit_mm = TRANSITION_TOL_SHARE * c.tol_mm;
        // The shape scales with d: its deviation at d = 1 mm gives the largest d.
        let unit = G2Corner {
            corner: Vec3::zeros(),
            line1: Curve::line(-c.u1 * 2.0, Vec3::zeros()),
            line2: Curve::line(Vec3::zeros(), c.u2 * 2.0),
            ..*c
        };
        let mut best: Option<G2Blend> = None;
        for rho in G2_LAMBDA_RATIOS {
            let Some(dev_1mm) = unit.curve(1.0, rho).map(|t| unit.deviation(&t)) else {
                continue;
            };
            if !(dev_1mm > 0.0 && dev_1mm.is_finite()) {
                continue;
            }
            let widest_mm = limit_mm / dev_1mm;
            let narrowed = widest_mm >= c.room_mm;
            let mut d = widest_mm.min(c.room_mm);
            // Rounding: confirm against the programmed lines, shrinking slightly if needed.
            let mut found = None;
            for _ in 0..G2_CONFIRM_TRIES {
                if let Some(t) = c.curve(d, rho)
                    && c.deviation(&t) <= limit_mm
                {
                    found = Some(t);
                    break;
                }
                d *= G2_CONFIRM_SHRINK;
            }
            let Some(tr) = found.and_then(|t| t.with_arc_length()) else {
                continue;
            };
            let curve = Curve::Transition(tr);
            let mut seg = PlannedSegment {
                curve,
                length_mm: curve.length(),
                ..*template
            };
            // Designed for a run through it at speed, not for its own length from rest:
            // the lines on either side slow down to it and speed up after it, so what it
            // costs is its length at its speed. Designed for its own length from rest,
            // the 90° blend at 0.01 mm chose 1.91 mm/s, 72 % of what its shape allows at
            // constant speed, for tangential budget it never uses; now 2.31 mm/s (87 %:
            // the profile's share, the sampling margin and the centripetal share).
            let run_mm = if narrowed {
                (c.run_in_mm - d + seg.length_mm).min(DESIGN_RUN_MM)
            } else {
                DESIGN_RUN_MM
            };
            self.set_limits_for_run(&mut seg, run_mm);
            let time_s = corner_time_s(&seg, d, lines, (false, false), &self.limits);
            if best.as_ref().is_none_or(|b| time_s < b.time_s) {
                best = Some(G2Blend {
                    seg,
                    d_mm: d,
                    time_s,
                    narrowed,
                });
            }
            if narrowed {
                // See above: the other scales would only be designed to be compared.
                break;
            }
        }
        best
    }
}

/// A G2 corner blend ([`Planner::g2_blend`]).
struct G2Blend {
    seg: PlannedSegment,
    /// The distance it takes from each line, mm.
    d_mm: f64,
    /// Its [`corner_time_s`].
    time_s: f64,
    /// Narrowed to the room: the widest blend within the tolerance would not fit.
    narrowed: bool,
}

/// A line-line corner for a G2 blend.
#[derive(Clone, Copy, Debug)]
struct G2Corner {
    /// The corner point, mm.
    corner: Vec3,
    /// Unit direction of the incoming line.
    u1: Vec3,
    /// Unit direction of the outgoing line.
    u2: Vec3,
    /// The programmed incoming line.
    line1: Curve,
    /// The programmed outgoing line.
    line2: Curve,
    /// Path tolerance, mm.
    tol_mm: f64,
    /// Largest distance the blend may take from the corner along each line, mm.
    room_mm: f64,
    /// The path without a corner that ends at the corner: the incoming line's untrimmed
    /// part and the chain of segments tangent to it before, mm.
    run_in_mm: f64,
}

impl G2Corner {
    /// The blend from `corner - u1·d` to `corner + u2·d` with parameter scale
    /// `rho` × chord (polynomial only).
    fn curve(&self, d: f64, rho: f64) -> Option<Transition> {
        let b1 = self.corner - self.u1 * d;
        let b2 = self.corner + self.u2 * d;
        let lambda = rho * (b2 - b1).norm();
        Transition::hermite(
            b1,
            self.u1,
            Vec3::zeros(),
            b2,
            self.u2,
            Vec3::zeros(),
            lambda,
        )
    }

    /// Largest distance of [`DEVIATION_SAMPLES`] points of `t` from the two lines, mm.
    fn deviation(&self, t: &Transition) -> f64 {
        (0..=DEVIATION_SAMPLES)
            .map(|i| {
                let p = t.poly(i as f64 / DEVIATION_SAMPLES as f64);
                self.line1.distance_to(&p).min(self.line2.distance_to(&p))
            })
            .fold(0.0, f64::max)
    }
}

/// The speed a corner's stand-in line runs at: its limit, at most its own move's feed.
fn side_speed(line: &PlannedSegment) -> f64 {
    line.v_max_mm_s.min(line.feed_mm_s)
}

/// Rough time a stop at a corner costs over running straight through at the lines' speed:
/// on each side, half the slow-down to rest (and back), from that line's own speed (a rapid
/// into a plunge at the feed slows down from the rapid's).
fn stop_time_s(lines: &(PlannedSegment, PlannedSegment)) -> f64 {
    let (a, j) = corner_ramp_limits(lines);
    let side = |l: &PlannedSegment| 0.5 * change_time_s(side_speed(l), a, j);
    side(&lines.0) + side(&lines.1)
}

/// The acceleration and jerk both sides of a corner are judged with: the lesser of the
/// two lines' (the estimate compares a stop with blends, not the lines with each other).
fn corner_ramp_limits(lines: &(PlannedSegment, PlannedSegment)) -> (f64, f64) {
    let (line_in, line_out) = lines;
    (
        line_in.accel_mm_s2.min(line_out.accel_mm_s2),
        line_in.jerk_mm_s3.min(line_out.jerk_mm_s3),
    )
}

/// Rough time a corner blend costs over running straight through at the lines' speed: the
/// transit of the blend, and on each side the slow-down from that line's own speed to the
/// speed the blend and its joints allow, less the `d` of line the blend replaces there at
/// that line's speed. (With one speed for both sides, the lesser, a rapid into a slow
/// plunge would be credited the time of the rapid a blend replaces at the plunge's speed,
/// though the rapid runs it in its last milliseconds before it stops, and a blend that
/// costs more than the stop would win.) Used to choose between a circular and a G2 blend (the circular one is
/// entered at its curvature-step cap but may speed up inside; the G2 one has no such step)
/// and a stop. `chained_in`: the blend begins where the previous corner's ended, so it is
/// entered from that arc, with no junction cap and no slow-down on the way in (judged as
/// from a line, the blends of a polygon along an arc would look dearer at every corner
/// until a stop won, and every later corner would stop).
/// `chained_out`: the blend ends where the next corner's blend may begin (it takes all
/// the outgoing line it may), so it is left into that blend, with no junction cap and no
/// slow-down on the way out; a stop at the next corner is charged by that corner's
/// estimate, over the short rest of the line. Judged as leaving into a line, the first
/// corner of such a chain would pay a slow-down to the curvature-step cap and back that
/// the chain never makes, and could lose to a stop; then no later corner could be entered
/// from a blend and every one of them would stop.
fn corner_time_s(
    blend: &PlannedSegment,
    d: f64,
    lines: &(PlannedSegment, PlannedSegment),
    (chained_in, chained_out): (bool, bool),
    limits: &MachineLimits,
) -> f64 {
    let (line_in, line_out) = lines;
    let v_top = blend.v_max_mm_s.min(blend.feed_mm_s);
    let cap_in = if chained_in {
        f64::INFINITY
    } else {
        junction_cap(line_in, blend, limits)
    };
    let cap_out = if chained_out {
        f64::INFINITY
    } else {
        junction_cap(blend, line_out, limits)
    };
    let v_in = cap_in.min(cap_out).min(v_top);
    let transit = transit_time_s(
        blend.length_mm,
        v_in,
        v_top,
        blend.accel_mm_s2,
        blend.jerk_mm_s3,
    );
    // On each side, slowing from v to v_in (or speeding back up): t over a distance
    // (v + v_in)·t/2, which at v would take (v + v_in)·t/(2v); the loss is the rest.
    let (a, j) = corner_ramp_limits(lines);
    // Chained in or out: no slow-down on that side (between two chained blends there is
    // none), only the line the blend replaces there.
    let side = |l: &PlannedSegment, slows: bool| {
        let v = side_speed(l);
        if !(v > 0.0 && v.is_finite()) {
            return 0.0;
        }
        let dv = if slows { (v - v_in).max(0.0) } else { 0.0 };
        0.5 * change_time_s(dv, a, j) * dv / v - d / v
    };
    transit + side(line_in, !chained_in) + side(line_out, !chained_out)
}
