//! Travel limits: reject a program whose path leaves an axis's `min`/`max` anywhere.
//!
//! Issue 3 asks that positions outside the configured travel anywhere on the path reject
//! the program before any motion, naming the line. The check is exact for the geometry the
//! front end produces: a line's extremes are its end points, and an arc's are its end
//! points plus the points where the circle is tangent to a coordinate direction, when they
//! fall inside the swept angle (multi-turn helices included). Rotary axes move linearly
//! with the path, so their end values are their extremes.

use std::f64::consts::TAU;

use kerf_geom::{Arc, Move, Path, Vec3};

use crate::config::Axes;

/// Slack for rounding in computed arc points, mm: a path that touches a limit exactly must
/// not be rejected because `cos` came out one ulp high.
const SLACK_MM: f64 = 1e-9;

/// A move that leaves an axis's travel.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error(
    "{axis} {position}{unit} is outside the travel of the {axis} axis ({min}{unit} to {max}{unit})"
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
            for p in arc_extremes(a).into_iter().flatten() {
                check_point(&p)?;
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

/// Checks every move in order and reports the first one that leaves the travel.
pub fn check_moves<'a, I>(moves: I, axes: &Axes) -> Result<(), TravelError>
where
    I: IntoIterator<Item = &'a Move>,
{
    moves.into_iter().try_for_each(|m| check_move(m, axes))
}

/// The points of an arc where a coordinate is at a maximum or minimum of the circle and
/// which lie inside the swept angle: up to two per coordinate.
fn arc_extremes(a: &Arc) -> [Option<Vec3>; 6] {
    let radial = a.start - a.center;
    let binormal = a.axis.cross(&radial);
    let axial = (a.end - a.start).dot(&a.axis);
    let (lo, hi) = if a.sweep_rad < 0.0 {
        (a.sweep_rad, 0.0)
    } else {
        (0.0, a.sweep_rad)
    };
    // Along the path the point is
    //   center + cos θ · radial + sin θ · binormal + axis · axial · θ / sweep,
    // so coordinate k of the circle part is extreme where tan θ = binormal_k / radial_k.
    let mut out = [None; 6];
    for k in 0..3 {
        if radial[k] == 0.0 && binormal[k] == 0.0 {
            // The circle does not move this coordinate (it is the arc's axis).
            continue;
        }
        let base = binormal[k].atan2(radial[k]);
        for (j, theta0) in [base, base + std::f64::consts::PI].into_iter().enumerate() {
            // The first angle at or after `lo` that is congruent to `theta0`.
            let theta = theta0 + ((lo - theta0) / TAU).ceil() * TAU;
            if theta <= hi && a.sweep_rad != 0.0 {
                let p = a.center
                    + radial * theta.cos()
                    + binormal * theta.sin()
                    + a.axis * (axial * theta / a.sweep_rad);
                out[2 * k + j] = Some(p);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{Config, LinearAxis, RotaryAxis};
    use kerf_geom::{CornerMode, Line};
    use std::f64::consts::PI;

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

    #[test]
    fn bundled_config_accepts_the_bundled_part_extent() {
        // The example part stays inside X -8..108, Y 0..60, Z -6..25; the bundled mill's
        // travel is ±1000 mm in X and Y and ±500 mm in Z.
        let c = Config::builtin();
        let m = line(Vec3::new(-8.0, 0.0, 25.0), Vec3::new(108.0, 60.0, -6.0));
        assert_eq!(check_move(&m, &c.axes), Ok(()));
    }
}
