//! Travel limits: reject a program whose path leaves an axis's `min`/`max` anywhere.
//!
//! A position outside the configured travel anywhere on the path rejects the program
//! before any motion, naming the line. The check is exact for the geometry the
//! front end produces: a line's extremes are its end points, and an arc's are its end
//! points plus the points where a coordinate is stationary along the curve, when they
//! fall inside the swept angle (multi-turn helices included). The arc's points are those
//! of the curve the motion follows ([`Curve::from_path`]'s helix, evaluated with its own
//! `point_at_angle`: relative to the start, with the drift that ends it exactly at its end
//! point), so what is checked is what is executed, at any radius. Rotary axes move
//! linearly with the path, so their end values are their extremes.
//!
//! The planned path is checked too: corner blends, transitions and smoothed pieces leave
//! the programmed lines within the tolerance, and near a limit that can be outside the
//! travel. [`check_segment`] checks every planned segment: lines and arcs exactly as
//! above; quintic curves (and rotary quintics) by sampling with a certified bound (see
//! [`quintic_beyond`]).

use std::f64::consts::{PI, TAU};

use kerf_geom::PlannedSegment;
use kerf_geom::{Curve, Helix, Move, Path, Vec3};

use crate::Axes;

/// Slack for rounding in computed arc points, mm: a path that touches a limit exactly must
/// not be rejected because `cos` came out one ulp high.
const SLACK_MM: f64 = 1e-9;

/// `v` rounded to 1e-9 (a nanometre, or a nano-degree) for messages: a point computed on
/// a curve carries rounding in its last digits (-1004.9999999999999 for -1005), which
/// would only hide the number a person wants to read.
fn to_nanometre(v: &f64) -> f64 {
    let r = (v * 1e9).round() / 1e9;
    if r.is_finite() { r } else { *v }
}

/// A move that leaves an axis's travel.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error(
    "{axis} {}{unit} is outside the travel of the {axis} axis ({min}{unit} to {max}{unit})",
    to_nanometre(.position)
)]
pub struct TravelError {
    /// 1-based source line of the move.
    pub line: u32,
    /// The axis: `X`, `Y`, `Z`, `A`, `B` or `C`.
    pub axis: char,
    /// The farthest position reached beyond the limit (mm, or degrees for rotary axes).
    pub position: f64,
    /// Lower travel limit.
    pub min: f64,
    /// Upper travel limit.
    pub max: f64,
    /// `" mm"` or `" deg"`.
    pub unit: &'static str,
}

/// Checks one move against the travel limits of `axes`.
///
/// Rotary positions are only checked on the rotary axes the machine has; a program that
/// drives a missing axis is the motion planner's error to report.
pub fn check_move(m: &Move, axes: &Axes) -> Result<(), TravelError> {
    let linear = axes.linear();
    let check_point = |p: &Vec3| -> Result<(), TravelError> {
        for (i, limits) in linear.iter().enumerate() {
            let v = p[i];
            if !(v >= limits.min_mm - SLACK_MM && v <= limits.max_mm + SLACK_MM) {
                return Err(TravelError {
                    line: m.line,
                    axis: ['X', 'Y', 'Z'][i],
                    position: v,
                    min: limits.min_mm,
                    max: limits.max_mm,
                    unit: " mm",
                });
            }
        }
        Ok(())
    };
    match &m.path {
        Path::Line(l) => {
            check_point(&l.start)?;
            check_point(&l.end)?;
        }
        Path::Arc(a) => {
            check_point(&a.start)?;
            check_point(&a.end)?;
            // The curve the motion follows (drift included), not a recomputed circle.
            if let Curve::Helix(h) = Curve::from_path(&m.path) {
                for p in helix_extremes(&h).into_iter().flatten() {
                    check_point(&p)?;
                }
            }
        }
    }
    if let Some((start, end)) = m.abc_deg {
        for (i, limits) in axes.rotary().iter().enumerate() {
            let Some(limits) = limits else { continue };
            for v in [start[i], end[i]] {
                if !(v >= limits.min_deg && v <= limits.max_deg) {
                    return Err(TravelError {
                        line: m.line,
                        axis: ['A', 'B', 'C'][i],
                        position: v,
                        min: limits.min_deg,
                        max: limits.max_deg,
                        unit: " deg",
                    });
                }
            }
        }
    }
    Ok(())
}

/// How far `m`'s exact path stays inside the linear travel of `axes`, mm: the least
/// distance from any point of it (a line's end points; an arc's end points and the
/// points where a coordinate is stationary, as [`check_move`] finds them) to any
/// `min_mm`/`max_mm` plane. Negative if the move leaves the travel. Zero if the move
/// drives a rotary axis the machine limits (the planner's rotary curves at corners have
/// no distance bound to measure against), so such a move always counts as at the edge.
///
/// A planned path stays within the tolerance of the moves it is made of, so the planned
/// path of moves whose clearance exceeds that tolerance cannot leave the travel: this is
/// what lets `kerf run` check those moves without planning them (it asks for twice the
/// tolerance; `kerf::sim::QuickCheck`).
pub fn clearance_mm(m: &Move, axes: &Axes) -> f64 {
    let linear = axes.linear();
    let mut clearance = f64::INFINITY;
    let mut point = |p: &Vec3| {
        for (i, limits) in linear.iter().enumerate() {
            clearance = clearance
                .min(p[i] - limits.min_mm)
                .min(limits.max_mm - p[i]);
        }
    };
    match &m.path {
        Path::Line(l) => {
            point(&l.start);
            point(&l.end);
        }
        Path::Arc(a) => {
            point(&a.start);
            point(&a.end);
            if let Curve::Helix(h) = Curve::from_path(&m.path) {
                for p in helix_extremes(&h).into_iter().flatten() {
                    point(&p);
                }
            }
        }
    }
    if let Some((start, end)) = m.abc_deg {
        let rotary_moves = axes
            .rotary()
            .iter()
            .enumerate()
            .any(|(i, l)| l.is_some() && start[i] != end[i]);
        if rotary_moves {
            clearance = clearance.min(0.0);
        }
    }
    // NaN (a non-finite coordinate) counts as no clearance at all.
    if clearance.is_nan() { 0.0 } else { clearance }
}

/// Checks every move in order and reports the first one that leaves the travel.
pub fn check_moves<'a, I>(moves: I, axes: &Axes) -> Result<(), TravelError>
where
    I: IntoIterator<Item = &'a Move>,
{
    moves.into_iter().try_for_each(|m| check_move(m, axes))
}

/// What kind of planned path left the travel, for the message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlannedKind {
    /// A corner blend or a transition the planner inserted between two moves.
    Blend,
    /// A smoothed piece standing for several short moves.
    Smoothed,
    /// The planned geometry of a programmed move.
    Move,
}

/// A planned segment that leaves an axis's travel although the programmed moves stay in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlannedTravelError {
    /// 1-based source line of the move the segment belongs to (for a smoothed piece, the
    /// move nearest to where it leaves the travel, when the caller knows it).
    pub line: u32,
    /// The axis: `X`, `Y`, `Z`, `A`, `B` or `C`.
    pub axis: char,
    /// What kind of path.
    pub kind: PlannedKind,
    /// The farthest position found beyond the limit.
    pub position: f64,
    /// The limit it is beyond.
    pub limit: f64,
    /// `true` if `limit` is the upper limit (`max_mm`/`max_deg`).
    pub upper: bool,
    /// The XYZ point where it leaves (for naming the nearest move).
    pub point: Vec3,
}

impl std::fmt::Display for PlannedTravelError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let rotary = matches!(self.axis, 'A' | 'B' | 'C');
        let (unit, key) = match (rotary, self.upper) {
            (false, true) => ("mm", "max_mm"),
            (false, false) => ("mm", "min_mm"),
            (true, true) => ("deg", "max_deg"),
            (true, false) => ("deg", "min_deg"),
        };
        let by = (self.position - self.limit).abs();
        let by = if by >= 0.001 {
            format!("{by:.3}")
        } else {
            format!("{by:.1e}")
        };
        let (what, inside) = match self.kind {
            PlannedKind::Blend => ("the blended path at this corner", "move the corner inside"),
            PlannedKind::Smoothed => (
                "the smoothed path through these moves",
                "move the path inside",
            ),
            PlannedKind::Move => ("the planned path of this move", "move it inside"),
        };
        write!(
            f,
            "{what} leaves the {axis} travel ({key} = {limit}) by {by} {unit}; lower the \
             tolerance (G64 P) or {inside}",
            axis = self.axis,
            limit = self.limit,
        )
    }
}

impl std::error::Error for PlannedTravelError {}

/// Checks one planned segment against the travel limits of `axes`: the whole curve, not
/// only its end points. Rotary axes are checked on the axes the machine has.
pub fn check_segment(seg: &PlannedSegment, axes: &Axes) -> Result<(), PlannedTravelError> {
    let kind = if seg.move_count > 1 {
        PlannedKind::Smoothed
    } else if seg.blend {
        PlannedKind::Blend
    } else {
        PlannedKind::Move
    };
    let error =
        |axis: usize, position: f64, limit: f64, upper: bool, point: Vec3| PlannedTravelError {
            line: seg.line,
            axis: ['X', 'Y', 'Z', 'A', 'B', 'C'][axis],
            kind,
            position,
            limit,
            upper,
            point,
        };
    let linear = axes.linear();
    let point_inside = |p: &Vec3| -> Result<(), PlannedTravelError> {
        for (i, l) in linear.iter().enumerate() {
            if p[i] > l.max_mm + SLACK_MM {
                return Err(error(i, p[i], l.max_mm, true, *p));
            }
            if p[i] < l.min_mm - SLACK_MM {
                return Err(error(i, p[i], l.min_mm, false, *p));
            }
        }
        Ok(())
    };
    match &seg.curve {
        Curve::Line { start, end, .. } => {
            point_inside(start)?;
            point_inside(end)?;
        }
        Curve::Helix(h) => {
            point_inside(&h.start)?;
            point_inside(&h.end)?;
            for p in helix_extremes(h).into_iter().flatten() {
                point_inside(&p)?;
            }
        }
        Curve::Transition(t) => {
            point_inside(&t.start)?;
            point_inside(&t.end)?;
            for (i, l) in linear.iter().enumerate() {
                let c = t.coef.map(|v| v[i]);
                let at = |u: f64| t.poly(u);
                if let Some((u, x)) = quintic_beyond(&c, l.max_mm + SLACK_MM, true) {
                    return Err(error(i, x, l.max_mm, true, at(u)));
                }
                if let Some((u, x)) = quintic_beyond(&c, l.min_mm - SLACK_MM, false) {
                    return Err(error(i, x, l.min_mm, false, at(u)));
                }
            }
        }
    }
    for (i, limits) in axes.rotary().iter().enumerate() {
        let Some(l) = limits else { continue };
        let ends = [seg.abc_start_deg[i], seg.abc_end_deg[i]];
        let start_point = seg.curve.start();
        for v in ends {
            if v > l.max_deg + SLACK_MM {
                return Err(error(3 + i, v, l.max_deg, true, start_point));
            }
            if v < l.min_deg - SLACK_MM {
                return Err(error(3 + i, v, l.min_deg, false, start_point));
            }
        }
        if let (Some(poly), Curve::Transition(t)) = (&seg.abc_poly, &seg.curve) {
            if let Some((u, v)) = quintic_beyond(&poly[i], l.max_deg + SLACK_MM, true) {
                return Err(error(3 + i, v, l.max_deg, true, t.poly(u)));
            }
            if let Some((u, v)) = quintic_beyond(&poly[i], l.min_deg - SLACK_MM, false) {
                return Err(error(3 + i, v, l.min_deg, false, t.poly(u)));
            }
        }
    }
    Ok(())
}

/// Samples of a quintic before refinement.
const QUINTIC_SAMPLES: usize = 64;
/// Function evaluations per quintic at most while refining near a limit.
const QUINTIC_MAX_EVALS: usize = 20_000;

/// Where the quintic `f(u) = Σ c[k] uᵏ`, `u ∈ [0, 1]`, is beyond `limit` (above it if
/// `upper`, else below): the parameter and value of a point found beyond, or `None`.
///
/// The bound: on an interval of width `h` the quintic deviates from the chord through its
/// end values by at most `M₂ h² / 8`, where `M₂ ≥ max |f''|` on `[0, 1]` is
/// `2|c₂| + 6|c₃| + 12|c₄| + 20|c₅|`. So `max(f(a), f(b)) + M₂ h²/8` bounds `f` on
/// `[a, b]` from above. The curve is sampled at 64 equal steps; every interval whose bound
/// reaches the limit is halved (sampling its middle) until the bound clears the limit or a
/// sample lies beyond it. A point is reported only when a sample is beyond the limit (the
/// limit passed in already includes the rounding slack), so a curve that touches the limit
/// exactly is never refused; refinement stops after 20,000 evaluations per curve, and
/// what it may then miss is below `M₂ h²/8` of the narrowest interval reached (a few
/// nanometres at most for the curves the planner builds).
pub fn quintic_beyond(c: &[f64; 6], limit: f64, upper: bool) -> Option<(f64, f64)> {
    let sign = if upper { 1.0 } else { -1.0 };
    // Work on g = sign · f, looking for g > sign · limit.
    let g = |u: f64| sign * (((((c[5] * u + c[4]) * u + c[3]) * u + c[2]) * u + c[1]) * u + c[0]);
    let lim = sign * limit;
    let m2 = 2.0 * c[2].abs() + 6.0 * c[3].abs() + 12.0 * c[4].abs() + 20.0 * c[5].abs();
    let beyond = |v: f64| v > lim;
    // Once a point is beyond, the farthest one (for the message): 1,024 samples.
    let farthest = || {
        let (mut best_u, mut best) = (0.0, f64::NEG_INFINITY);
        for k in 0..=1024 {
            let u = k as f64 / 1024.0;
            let v = g(u);
            if v > best {
                (best_u, best) = (u, v);
            }
        }
        Some((best_u, sign * best))
    };
    let mut stack: Vec<(f64, f64, f64, f64)> = Vec::new();
    let h = 1.0 / QUINTIC_SAMPLES as f64;
    let mut prev = (0.0, g(0.0));
    if beyond(prev.1) {
        return farthest();
    }
    for k in 1..=QUINTIC_SAMPLES {
        let u = k as f64 * h;
        let v = g(u);
        if beyond(v) {
            return farthest();
        }
        stack.push((prev.0, prev.1, u, v));
        prev = (u, v);
    }
    let mut evals = QUINTIC_SAMPLES + 1;
    while let Some((a, ga, b, gb)) = stack.pop() {
        let w = b - a;
        if ga.max(gb) + m2 * w * w / 8.0 <= lim {
            continue;
        }
        if evals >= QUINTIC_MAX_EVALS {
            break;
        }
        let m = 0.5 * (a + b);
        if m <= a || m >= b {
            continue;
        }
        let gm = g(m);
        evals += 1;
        if beyond(gm) {
            return farthest()
                .filter(|f| sign * f.1 > gm)
                .or(Some((m, sign * gm)));
        }
        stack.push((a, ga, m, gm));
        stack.push((m, gm, b, gb));
    }
    None
}

/// The points of a helix (the curve the motion follows, see [`kerf_geom::Helix`]) where a
/// coordinate has a maximum or minimum inside the swept angle, evaluated with the helix's
/// own [`Helix::point_at_angle`]: up to four per coordinate.
///
/// Coordinate `k` along the curve is
///   `x(θ) = start_k + r (e1_k (cos θ − 1) + e2_k sin θ) + c_k θ`,
/// with `c_k = axis_k · rise / sweep + drift_k` the part linear in the angle. With
/// `A = r · sqrt(e1_k² + e2_k²)` and `φ = atan2(e2_k, e1_k)`, `x'(θ) = −A sin(θ − φ) + c_k`
/// vanishes where `sin(θ − φ) = c_k / A`: at `φ + asin(c_k/A)` and `φ + π − asin(c_k/A)`,
/// modulo whole turns (for a plain arc about Z, `c_k = 0` in X and Y: where the circle is
/// tangent to the coordinate direction). When `|c_k| ≥ A` the coordinate is monotonic and
/// its extremes are the end points. With `c_k ≠ 0` the maxima of successive turns differ
/// by `2π c_k`, so the first and the last turn's are the candidates.
fn helix_extremes(h: &Helix) -> [Option<Vec3>; 12] {
    let (lo, hi) = if h.sweep_rad < 0.0 {
        (h.sweep_rad, 0.0)
    } else {
        (0.0, h.sweep_rad)
    };
    let mut out = [None; 12];
    if h.sweep_rad == 0.0 || !h.sweep_rad.is_finite() {
        return out;
    }
    let pitch = h.rise_mm / h.sweep_rad;
    for k in 0..3 {
        let amp = h.radius_mm * h.e1[k].hypot(h.e2[k]);
        let c = h.axis[k] * pitch + h.drift_mm_per_rad[k];
        let turns_back = amp > c.abs();
        if !turns_back {
            // The circle does not move this coordinate (it is the arc's axis), or the
            // linear part outruns it: monotonic, extreme at the end points.
            continue;
        }
        let phi = h.e2[k].atan2(h.e1[k]);
        let shift = (c / amp).asin();
        for (j, theta0) in [phi + shift, phi + PI - shift].into_iter().enumerate() {
            // The first and the last angle in [lo, hi] congruent to `theta0`.
            let first = theta0 + ((lo - theta0) / TAU).ceil() * TAU;
            let last = theta0 + ((hi - theta0) / TAU).floor() * TAU;
            if first <= hi {
                out[4 * k + 2 * j] = Some(h.point_at_angle(first));
            }
            if last >= lo && last > first {
                out[4 * k + 2 * j + 1] = Some(h.point_at_angle(last));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Config, LinearAxis, RotaryAxis};
    use kerf_geom::{Arc, CornerMode, Line};

    fn axes(min_mm: f64, max_mm: f64) -> Axes {
        let axis = LinearAxis {
            velocity_mm_s: 100.0,
            acceleration_mm_s2: 1000.0,
            jerk_mm_s3: 10000.0,
            min_mm,
            max_mm,
        };
        Axes {
            x: axis,
            y: axis,
            z: axis,
            a: None,
            b: None,
            c: None,
        }
    }

    fn arc(start: Vec3, end: Vec3, center: Vec3, sweep_rad: f64) -> Move {
        Move {
            line: 4,
            rapid: false,
            path: Path::Arc(Arc {
                start,
                end,
                center,
                axis: Vec3::new(0.0, 0.0, 1.0),
                sweep_rad,
            }),
            feed_mm_min: Some(100.0),
            abc_deg: None,
            corner: CornerMode::ExactStop,
        }
    }

    fn line(start: Vec3, end: Vec3) -> Move {
        Move {
            line: 2,
            rapid: true,
            path: Path::Line(Line { start, end }),
            feed_mm_min: None,
            abc_deg: None,
            corner: CornerMode::ExactStop,
        }
    }

    #[test]
    fn line_inside_and_touching_the_limits_passes() {
        let m = line(Vec3::new(-5.0, 0.0, 0.0), Vec3::new(5.0, 5.0, -5.0));
        assert_eq!(check_move(&m, &axes(-5.0, 5.0)), Ok(()));
    }

    #[test]
    fn line_end_outside_names_axis_line_and_limits() {
        let m = line(Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 6.5, 0.0));
        let e = check_move(&m, &axes(-5.0, 5.0)).unwrap_err();
        assert_eq!((e.line, e.axis, e.position), (2, 'Y', 6.5));
        assert_eq!(
            e.to_string(),
            "Y 6.5 mm is outside the travel of the Y axis (-5 mm to 5 mm)"
        );
    }

    #[test]
    fn semicircle_bulging_past_the_limit_between_its_end_points_is_rejected() {
        // CCW from (0,0) to (8,0) about (4,0): the arc passes through (4,-4) at its lowest.
        let m = arc(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(8.0, 0.0, 0.0),
            Vec3::new(4.0, 0.0, 0.0),
            PI,
        );
        let e = check_move(&m, &axes(-3.0, 10.0)).unwrap_err();
        assert_eq!((e.line, e.axis), (4, 'Y'));
        assert!((e.position + 4.0).abs() < 1e-12, "{e}");
        // The same end points the other way round (CW) bulge upwards to (4,4) instead.
        let cw = arc(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(8.0, 0.0, 0.0),
            Vec3::new(4.0, 0.0, 0.0),
            -PI,
        );
        assert_eq!(check_move(&cw, &axes(-3.0, 10.0)), Ok(()));
        let mut low_ceiling = axes(-10.0, 10.0);
        low_ceiling.y.max_mm = 3.0;
        let e = check_move(&cw, &low_ceiling).unwrap_err();
        assert_eq!(e.axis, 'Y');
        assert!((e.position - 4.0).abs() < 1e-12, "{e}");
    }

    #[test]
    fn quarter_arc_only_checks_the_extremes_it_sweeps() {
        // CCW quarter from (10,0) to (0,10) about the origin: X and Y stay within [0, 10],
        // although the full circle would reach -10 on both.
        let m = arc(
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(0.0, 10.0, 0.0),
            Vec3::new(0.0, 0.0, 0.0),
            PI / 2.0,
        );
        assert_eq!(check_move(&m, &axes(0.0, 10.0)), Ok(()));
    }

    #[test]
    fn helix_of_several_turns_reaches_every_side_and_its_depth() {
        // Two turns of radius 3 about (50, 30) from Z0 down to Z-3.
        let mut m = arc(
            Vec3::new(53.0, 30.0, 0.0),
            Vec3::new(53.0, 30.0, -3.0),
            Vec3::new(50.0, 30.0, 0.0),
            4.0 * PI,
        );
        let mut a = axes(0.0, 100.0);
        a.z.min_mm = -3.0;
        assert_eq!(check_move(&m, &a), Ok(()));
        // X reaches 47 on the far side of the circle.
        let mut narrow = a;
        narrow.x.min_mm = 48.0;
        assert_eq!(check_move(&m, &narrow).unwrap_err().axis, 'X');
        // And Z reaches -3 at the end.
        a.z.min_mm = -2.5;
        assert_eq!(check_move(&m, &a).unwrap_err().axis, 'Z');
        m.line = 9;
        assert_eq!(check_moves([&m], &a).unwrap_err().line, 9);
    }

    #[test]
    fn rotary_axes_are_checked_when_configured() {
        let mut m = line(Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0));
        m.abc_deg = Some(([0.0, 0.0, 0.0], [0.0, 0.0, 400.0]));
        let mut a = axes(-10.0, 10.0);
        assert_eq!(check_move(&m, &a), Ok(()), "no C axis configured");
        a.c = Some(RotaryAxis {
            velocity_deg_s: 360.0,
            acceleration_deg_s2: 3600.0,
            jerk_deg_s3: 36000.0,
            min_deg: -360.0,
            max_deg: 360.0,
        });
        let e = check_move(&m, &a).unwrap_err();
        assert_eq!((e.axis, e.position, e.unit), ('C', 400.0, " deg"));
    }

    /// A fixed-seed source of numbers in `[0, 1)` (a 64-bit LCG).
    fn unit_source(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// The largest value of a quintic on `[0, 1]` by brute force: a million samples.
    fn brute_max(c: &[f64; 6]) -> f64 {
        (0..=1_000_000)
            .map(|k| {
                let u = k as f64 / 1e6;
                c.iter().rev().fold(0.0, |acc, ck| acc * u + ck)
            })
            .fold(f64::NEG_INFINITY, f64::max)
    }

    #[test]
    fn quintic_beyond_agrees_with_brute_force_sampling() {
        // Fixed-seed random quintics of the planner's scale (positions around ±1000 mm,
        // shapes of up to a few mm), each tested against limits just above and just
        // below its true maximum.
        let mut unit = unit_source(0x5eed_7a4e);
        let mut next = || unit() * 2.0 - 1.0;
        for case in 0..40 {
            let mut c = [0.0; 6];
            c[0] = 1000.0 * next();
            for ck in c.iter_mut().skip(1) {
                *ck = 5.0 * next();
            }
            let max = brute_max(&c);
            // A limit 1 µm below the maximum: found, with the maximum reported.
            let (u, v) = quintic_beyond(&c, max - 1e-6, true)
                .unwrap_or_else(|| panic!("case {case}: a 1 µm excess was missed"));
            assert!((v - max).abs() < 1e-5, "case {case}: {v} vs {max}");
            assert!((0.0..=1.0).contains(&u));
            // A limit at the maximum (plus the rounding slack): nothing beyond.
            assert_eq!(
                quintic_beyond(&c, max + SLACK_MM, true),
                None,
                "case {case}"
            );
            // The same below, on the mirrored quintic.
            let neg = c.map(|x| -x);
            let (_, v) = quintic_beyond(&neg, -(max - 1e-6), false).unwrap();
            assert!((v + max).abs() < 1e-5, "case {case}");
            assert_eq!(quintic_beyond(&neg, -(max + SLACK_MM), false), None);
        }
    }

    #[test]
    fn a_quintic_that_touches_the_limit_tangentially_is_not_beyond_it() {
        // f(u) = 1000 - 3 (1 - u)³ ... reaches 1000 at u = 1 with zero slope and
        // curvature, the way a G2 blend ends on a line along the limit.
        let c = [997.0, 9.0, -9.0, 3.0, 0.0, 0.0];
        assert_eq!(quintic_beyond(&c, 1000.0 + SLACK_MM, true), None);
        // Raised by 10 nm, it is beyond.
        let mut up = c;
        up[0] += 1e-8;
        assert!(quintic_beyond(&up, 1000.0 + SLACK_MM, true).is_some());
    }

    /// A planned segment on `curve` with rotary values `abc` at both ends.
    fn planned(curve: Curve, abc: ([f64; 3], [f64; 3])) -> PlannedSegment {
        PlannedSegment {
            curve,
            abc_start_deg: abc.0,
            abc_end_deg: abc.1,
            abc_poly: None,
            length_mm: curve.length(),
            line: 12,
            move_index: 0,
            move_count: 1,
            feed_mm_s: 50.0,
            v_max_mm_s: 50.0,
            accel_mm_s2: 1000.0,
            jerk_mm_s3: 10000.0,
            v_boost_mm_s: 50.0,
            accel_boost_mm_s2: 1000.0,
            jerk_boost_mm_s3: 10000.0,
            end_cap_mm_s: 0.0,
            blend: true,
        }
    }

    #[test]
    fn planned_transitions_are_checked_where_the_setpoints_go() {
        // Fixed-seed random G2 transitions near X = 1000 (like corner blends at the
        // limit): the farthest X is measured by evaluating the segment where the motion
        // core does (`position_at`, 20,000 arc-length samples). A limit 0.1 µm inside it is
        // reported, with that farthest X; a limit 1 nm outside it is not.
        // The ends' tangents turn up to 0.8 rad either side of the chord, as a corner
        // blend's do (tangents across the chord make quintics whose arc length the
        // run-time evaluation cannot serve, which `Transition::new` refuses).
        let mut next = unit_source(0x7ae5_17e5);
        let mut checked = 0;
        for case in 0..60 {
            let a0 = (next() - 0.5) * 1.6;
            let a1 = (next() - 0.5) * 1.6;
            let p0 = Vec3::new(1000.0 - 2.0 * next(), -1.0, 0.0);
            let p1 = Vec3::new(1000.0 - 2.0 * next(), 1.0, 0.0);
            let chord = (p1 - p0).y.atan2((p1 - p0).x);
            let t0 = Vec3::new((chord + a0).cos(), (chord + a0).sin(), 0.0);
            let t1 = Vec3::new((chord + a1).cos(), (chord + a1).sin(), 0.0);
            let Some(tr) = kerf_geom::Transition::new(
                p0,
                t0,
                Vec3::zeros(),
                p1,
                t1,
                Vec3::zeros(),
                (p1 - p0).norm(),
            ) else {
                continue;
            };
            let seg = planned(Curve::Transition(tr), ([0.0; 3], [0.0; 3]));
            let mut out = [0.0; 6];
            let mut max_x = f64::NEG_INFINITY;
            for k in 0..=20_000 {
                seg.position_at(seg.length_mm * k as f64 / 20_000.0, &mut out);
                max_x = max_x.max(out[0]);
            }
            let mut a = axes(-2000.0, 2000.0);
            a.x.max_mm = max_x - 1e-7;
            let e = check_segment(&seg, &a).unwrap_err();
            assert_eq!(
                (e.axis, e.line, e.upper, e.kind),
                ('X', 12, true, PlannedKind::Blend)
            );
            assert!(
                (e.position - max_x).abs() < 1e-6,
                "case {case}: {e:?} vs {max_x}"
            );
            assert!(
                e.to_string()
                    .starts_with("the blended path at this corner leaves the X travel (max_mm = ")
            );
            a.x.max_mm = max_x + 1e-6;
            assert_eq!(check_segment(&seg, &a), Ok(()), "case {case}");
            checked += 1;
        }
        assert!(checked > 40, "{checked} of 60");
    }

    #[test]
    fn planned_rotary_ends_are_checked_on_configured_axes() {
        let line = Curve::line(Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0));
        let seg = planned(line, ([0.0, 0.0, 0.0], [0.0, 0.0, 370.0]));
        let mut a = axes(-10.0, 10.0);
        assert_eq!(check_segment(&seg, &a), Ok(()), "no C axis configured");
        a.c = Some(RotaryAxis {
            velocity_deg_s: 360.0,
            acceleration_deg_s2: 3600.0,
            jerk_deg_s3: 36000.0,
            min_deg: -360.0,
            max_deg: 360.0,
        });
        let e = check_segment(&seg, &a).unwrap_err();
        assert_eq!((e.axis, e.position, e.upper), ('C', 370.0, true));
        assert_eq!(
            e.to_string(),
            "the blended path at this corner leaves the C travel (max_deg = 360) by 10.000 deg; \
             lower the tolerance (G64 P) or move the corner inside"
        );
    }

    #[test]
    fn huge_radius_arc_bulging_past_a_limit_is_checked_on_the_executed_curve() {
        // A clockwise arc of radius 1e12 mm from (-1000, y0) to (1000, y0) about a centre
        // 1e12 mm below: its top, at X 0, is dx² / (r + dy) = 5e-7 mm above the end
        // points (written without the cancellation of r − dy, so the expected height is
        // exact to rounding). A circle evaluated about the centre would lose it: a unit in
        // the last place of 1e12 is 1.2e-4 mm.
        let radius = 1e12;
        let y0 = -5e-7;
        let center = Vec3::new(0.0, y0 - radius, 0.0);
        let start = Vec3::new(-1000.0, y0, 0.0);
        let end = Vec3::new(1000.0, y0, 0.0);
        let (dx, dy) = (start.x - center.x, start.y - center.y);
        let r = dx.hypot(dy);
        let top = y0 + dx * dx / (r + dy);
        assert!((top - 0.0).abs() < 1e-9, "{top}");
        let sweep = -2.0 * (1000.0 / r).asin();
        let m = arc(start, end, center, sweep);
        let mut a = axes(-2000.0, 2000.0);
        // A ceiling 10 nm above the top passes, one 0.1 µm below it is refused, naming
        // the top (within the 1 nm rounding slack).
        a.y.max_mm = top + 1e-8;
        assert_eq!(check_move(&m, &a), Ok(()));
        a.y.max_mm = top - 1e-7;
        let e = check_move(&m, &a).unwrap_err();
        assert_eq!((e.axis, e.line), ('Y', 4));
        assert!((e.position - top).abs() < 1e-9, "{e:?} vs {top}");
        // The same on the planned segment of that arc.
        let seg = planned(Curve::from_path(&m.path), ([0.0; 3], [0.0; 3]));
        a.y.max_mm = top + 1e-8;
        assert_eq!(check_segment(&seg, &a), Ok(()));
        a.y.max_mm = top - 1e-7;
        let e = check_segment(&seg, &a).unwrap_err();
        assert_eq!((e.axis, e.upper), ('Y', true));
        assert!((e.position - top).abs() < 1e-9, "{e:?} vs {top}");
    }

    #[test]
    fn tilted_helix_extremes_follow_the_linear_part() {
        // A helix of three turns about an axis tilted 45° in XZ: X moves with the circle
        // and with the rise (axis_x · rise / sweep per radian), so its largest value is
        // on the last turn, where sin(θ − φ) = c / A (the circle's tangent point shifted
        // by the rise). Expected maximum by brute force on 2 million points of the same
        // parametrisation, written out here.
        let s2 = std::f64::consts::FRAC_1_SQRT_2;
        let axis = Vec3::new(s2, 0.0, s2);
        let e1 = Vec3::new(0.0, 1.0, 0.0);
        let e2 = axis.cross(&e1);
        let (r, sweep, rise) = (5.0, 3.0 * TAU, 30.0);
        let start = Vec3::new(10.0, 20.0, 30.0);
        let at = |th: f64| {
            start + (e1 * (th.cos() - 1.0) + e2 * th.sin()) * r + axis * (rise * th / sweep)
        };
        let end = at(sweep);
        let mv = Move {
            line: 7,
            rapid: false,
            path: Path::Arc(Arc {
                start,
                end,
                center: start - e1 * r,
                axis,
                sweep_rad: sweep,
            }),
            feed_mm_min: Some(100.0),
            abc_deg: None,
            corner: CornerMode::ExactStop,
        };
        let max_x = (0..=2_000_000)
            .map(|k| at(sweep * k as f64 / 2e6).x)
            .fold(f64::NEG_INFINITY, f64::max);
        let mut a = axes(-1000.0, 1000.0);
        a.x.max_mm = max_x + 1e-8;
        assert_eq!(check_move(&mv, &a), Ok(()));
        a.x.max_mm = max_x - 1e-7;
        let e = check_move(&mv, &a).unwrap_err();
        assert_eq!(e.axis, 'X');
        assert!((e.position - max_x).abs() < 1e-8, "{e:?} vs {max_x}");
    }

    #[test]
    fn bundled_config_accepts_the_bundled_part_extent() {
        // The example part stays inside X -8..108, Y 0..60, Z -6..25; the bundled mill's
        // travel is ±1000 mm in X and Y and ±500 mm in Z.
        let c = Config::builtin();
        let m = line(Vec3::new(-8.0, 0.0, 25.0), Vec3::new(108.0, 60.0, -6.0));
        assert_eq!(check_move(&m, &c.axes), Ok(()));
    }
}
