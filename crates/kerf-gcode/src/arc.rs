//! Exact arc construction in the selected plane.
//!
//! Every function works on plane coordinates (u, v) with u × v = the plane normal, so one
//! code path serves G17, G18 and G19 and the sweep sign is always "positive = counter-
//! clockwise seen from the positive end of the normal".

use std::f64::consts::{PI, TAU};

use kerf_geom::{Arc, Vec3};

/// The working plane.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Plane {
    /// G17: X/Y, normal +Z.
    Xy,
    /// G18: Z/X, normal +Y.
    Zx,
    /// G19: Y/Z, normal +X.
    Yz,
}

impl Plane {
    /// Indices of the abscissa, ordinate and normal axes (0 = X, 1 = Y, 2 = Z).
    pub(crate) fn axes(self) -> (usize, usize, usize) {
        match self {
            Plane::Xy => (0, 1, 2),
            Plane::Zx => (2, 0, 1),
            Plane::Yz => (1, 2, 0),
        }
    }

    /// The unit normal of the plane.
    pub(crate) fn normal(self) -> Vec3 {
        match self {
            Plane::Xy => Vec3::new(0.0, 0.0, 1.0),
            Plane::Zx => Vec3::new(0.0, 1.0, 0.0),
            Plane::Yz => Vec3::new(1.0, 0.0, 0.0),
        }
    }

    /// The G code that selects the plane, for messages.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Plane::Xy => "XY",
            Plane::Zx => "XZ",
            Plane::Yz => "YZ",
        }
    }
}

/// Why an arc could not be built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum ArcError {
    /// The start or end point coincides with the centre.
    ZeroRadius,
    /// Centre format: the end point is not on the circle through the start point.
    EndRadiusDiffers { r_start: f64, r_end: f64 },
    /// Radius format: |R| is shorter than half the chord beyond the allowed slack.
    RadiusTooSmall,
    /// Radius format: the end point equals the start point.
    SamePoint,
}

/// How a centre-format end point is checked.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Tolerance {
    /// LinuxCNC: rejected when |r1 − r2| > 100·t, or when it exceeds t and the relative
    /// error exceeds 0.1 %; `t_mm` is 0.02828 mm in G21 and 0.002828 in in G20.
    LinuxCnc { t_mm: f64 },
    /// Sinumerik-style: rejected when |r1 − r2| > max(abs, r1 × rel).
    AbsRel { abs_mm: f64, rel: f64 },
}

/// Chords shorter than this (mm) make the end point equal to the start point.
pub(crate) const SAME_POINT_MM: f64 = 1e-9;

/// The length of (a, b). Plain `sqrt` instead of `hypot`: machine coordinates can neither
/// overflow nor underflow when squared, and `hypot` costs several times as much.
#[inline]
pub(crate) fn len2(a: f64, b: f64) -> f64 {
    (a * a + b * b).sqrt()
}

fn uv(p: &Vec3, plane: Plane) -> (f64, f64) {
    let (u, v, _) = plane.axes();
    (p[u], p[v])
}

/// Builds the arc from its exact data; `center_uv` is the centre in plane coordinates.
pub(crate) fn make_arc(
    start: Vec3,
    end: Vec3,
    center_uv: (f64, f64),
    plane: Plane,
    sweep_rad: f64,
) -> Arc {
    let (u, v, w) = plane.axes();
    let mut center = Vec3::zeros();
    center[u] = center_uv.0;
    center[v] = center_uv.1;
    center[w] = start[w];
    Arc {
        start,
        end,
        center,
        axis: plane.normal(),
        sweep_rad,
    }
}

/// True when start and end coincide in the plane.
pub(crate) fn same_in_plane(start: &Vec3, end: &Vec3, plane: Plane) -> bool {
    let (su, sv) = uv(start, plane);
    let (eu, ev) = uv(end, plane);
    len2(eu - su, ev - sv) < SAME_POINT_MM
}

/// How far the end of a LinuxCNC arc may lie beside the ray from the centre through the
/// start, mm, for its end angle to count as the start angle: the 0.0001 of the 4 decimals
/// rs274 prints (within it, which side the end falls on is a rounding of the program's
/// numbers, not an intent to turn a hair's breadth instead of a whole circle).
pub(crate) const SAME_ANGLE_LATERAL_MM: f64 = 1e-4;

/// LinuxCNC's whole-turn rule: the end of a centre-format arc whose radius differs from
/// the start's lies on the ray from the programmed centre through the start (its angle
/// about the centre is the start's, within [`SAME_ANGLE_LATERAL_MM`]). LinuxCNC then turns
/// a whole circle, spiralling from the start radius to the end radius.
pub(crate) fn end_on_start_ray(
    start: &Vec3,
    end: &Vec3,
    center_uv: (f64, f64),
    plane: Plane,
) -> bool {
    let (su, sv) = uv(start, plane);
    let (eu, ev) = uv(end, plane);
    let (cu, cv) = center_uv;
    let (ru, rv) = (su - cu, sv - cv);
    let (du, dv) = (eu - cu, ev - cv);
    let (r1, r2) = (len2(ru, rv), len2(du, dv));
    if r1 <= SAME_POINT_MM || r1 == r2 || same_in_plane(start, end, plane) {
        return false;
    }
    // The end's distance from the ray's line, and that it lies on the start's side.
    let lateral = (ru * dv - rv * du).abs() / r1;
    lateral <= SAME_ANGLE_LATERAL_MM && ru * du + rv * dv > 0.0
}

/// The sweep from angle `a1` to angle `a2` in the given direction, in (0, 2π] or
/// [−2π, 0); equal angles (`full`) give a whole circle.
fn base_sweep(a1: f64, a2: f64, ccw: bool, full: bool) -> f64 {
    if full {
        return if ccw { TAU } else { -TAU };
    }
    let mut d = a2 - a1;
    if ccw {
        if d <= 0.0 {
            d += TAU;
        }
    } else if d >= 0.0 {
        d -= TAU;
    }
    d
}

fn turns(extra_turns: u32, ccw: bool) -> f64 {
    let t = f64::from(extra_turns) * TAU;
    if ccw { t } else { -t }
}

/// A centre-format arc. The end radius is checked against `tol`; when it is accepted but
/// differs from the start radius, the centre is moved onto the perpendicular bisector of
/// the chord, to the point closest to the programmed centre, so that the result is an
/// exact circle through both end points.
pub(crate) fn arc_from_center(
    start: Vec3,
    end: Vec3,
    center_uv: (f64, f64),
    plane: Plane,
    ccw: bool,
    extra_turns: u32,
    tol: Tolerance,
) -> Result<Arc, ArcError> {
    let (su, sv) = uv(&start, plane);
    let (eu, ev) = uv(&end, plane);
    let (mut cu, mut cv) = center_uv;
    let r1 = len2(su - cu, sv - cv);
    let r2 = len2(eu - cu, ev - cv);
    if !(r1 > SAME_POINT_MM && r2 > SAME_POINT_MM) {
        return Err(ArcError::ZeroRadius);
    }
    let abs_err = (r1 - r2).abs();
    let reject = match tol {
        Tolerance::LinuxCnc { t_mm } => {
            let rel_err = abs_err / r1.max(r2);
            abs_err > 100.0 * t_mm || (rel_err > 0.001 && abs_err > t_mm)
        }
        Tolerance::AbsRel { abs_mm, rel } => abs_err > abs_mm.max(r1 * rel),
    };
    if reject || !abs_err.is_finite() {
        return Err(ArcError::EndRadiusDiffers {
            r_start: r1,
            r_end: r2,
        });
    }
    let full = len2(eu - su, ev - sv) < SAME_POINT_MM;
    let mut end = end;
    if full {
        let (u, v, _) = plane.axes();
        end[u] = start[u];
        end[v] = start[v];
    } else if abs_err > 0.0 {
        let (mu, mv) = ((su + eu) * 0.5, (sv + ev) * 0.5);
        let chord = len2(eu - su, ev - sv);
        let (nu, nv) = (-(ev - sv) / chord, (eu - su) / chord);
        let along = (cu - mu) * nu + (cv - mv) * nv;
        cu = mu + along * nu;
        cv = mv + along * nv;
    }
    let a1 = (sv - cv).atan2(su - cu);
    let a2 = (ev - cv).atan2(eu - cu);
    let sweep = base_sweep(a1, a2, ccw, full) + turns(extra_turns, ccw);
    Ok(make_arc(start, end, (cu, cv), plane, sweep))
}

/// A radius-format arc: positive `radius` for at most 180°, negative for more. |R| short
/// of half the chord by at most `slack_mm` is taken as half the chord (a semicircle).
pub(crate) fn arc_from_radius(
    start: Vec3,
    end: Vec3,
    radius: f64,
    plane: Plane,
    ccw: bool,
    extra_turns: u32,
    slack_mm: f64,
) -> Result<Arc, ArcError> {
    let (su, sv) = uv(&start, plane);
    let (eu, ev) = uv(&end, plane);
    let chord = len2(eu - su, ev - sv);
    if chord < SAME_POINT_MM {
        return Err(ArcError::SamePoint);
    }
    let half = chord * 0.5;
    let r = radius.abs();
    if half - r > slack_mm || !r.is_finite() {
        return Err(ArcError::RadiusTooSmall);
    }
    let h = if half >= r {
        0.0
    } else {
        (r * r - half * half).sqrt()
    };
    let (mu, mv) = ((su + eu) * 0.5, (sv + ev) * 0.5);
    // Left normal of the chord direction: travelling counter-clockwise on an arc of at most
    // 180°, the centre lies to the left of the chord.
    let (nu, nv) = (-(ev - sv) / chord, (eu - su) / chord);
    let left = ccw != (radius < 0.0);
    let (cu, cv) = if left {
        (mu + h * nu, mv + h * nv)
    } else {
        (mu - h * nu, mv - h * nv)
    };
    let a1 = (sv - cv).atan2(su - cu);
    let a2 = (ev - cv).atan2(eu - cu);
    let mut sweep = base_sweep(a1, a2, ccw, false);
    if h == 0.0 {
        // A semicircle: rounding in atan2 must not turn it into a full circle minus π.
        sweep = if ccw { PI } else { -PI };
    }
    Ok(make_arc(
        start,
        end,
        (cu, cv),
        plane,
        sweep + turns(extra_turns, ccw),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    const TOL: Tolerance = Tolerance::LinuxCnc { t_mm: 0.02828 };

    #[test]
    fn quarter_circles_in_each_plane() {
        // G17 G3 from (10,0) to (0,10) about the origin: +90° about +Z.
        let a = arc_from_center(
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(0.0, 10.0, 0.0),
            (0.0, 0.0),
            Plane::Xy,
            true,
            0,
            TOL,
        )
        .unwrap();
        assert!((a.sweep_rad - PI / 2.0).abs() < 1e-12);
        // G18 G2 from X10 to Z10 about the origin. Seen from +Y, Z is the abscissa and X the
        // ordinate, so going from +X to +Z is clockwise: -90°.
        let a = arc_from_center(
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 10.0),
            (0.0, 0.0),
            Plane::Zx,
            false,
            0,
            TOL,
        )
        .unwrap();
        assert!((a.sweep_rad + PI / 2.0).abs() < 1e-12);
        assert_eq!(a.axis, Vec3::new(0.0, 1.0, 0.0));
    }

    #[test]
    fn radius_format_picks_the_side() {
        // From (0,0) to (10,0) with R5: a semicircle whichever sign.
        let s = Vec3::zeros();
        let e = Vec3::new(10.0, 0.0, 0.0);
        let a = arc_from_radius(s, e, 5.0, Plane::Xy, false, 0, 0.00127).unwrap();
        assert!((a.sweep_rad + PI).abs() < 1e-12);
        // R = 10/sqrt(2) gives 90° (positive R) or 270° (negative R); counter-clockwise,
        // the short arc has its centre on the left of the chord.
        let r = 10.0 / 2f64.sqrt();
        let a = arc_from_radius(s, e, r, Plane::Xy, true, 0, 0.00127).unwrap();
        assert!((a.sweep_rad - PI / 2.0).abs() < 1e-9);
        assert!((a.center - Vec3::new(5.0, 5.0, 0.0)).norm() < 1e-9);
        let a = arc_from_radius(s, e, -r, Plane::Xy, true, 0, 0.00127).unwrap();
        assert!((a.sweep_rad - 1.5 * PI).abs() < 1e-9);
        assert!((a.center - Vec3::new(5.0, -5.0, 0.0)).norm() < 1e-9);
        assert_eq!(
            arc_from_radius(s, e, 4.99, Plane::Xy, true, 0, 0.00127),
            Err(ArcError::RadiusTooSmall)
        );
    }

    #[test]
    fn centre_is_corrected_onto_the_bisector() {
        // Start radius 10, end radius 10.01: accepted (0.01 < t), centre moved so that
        // both ends are equidistant.
        let a = arc_from_center(
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(0.0, 10.01, 0.0),
            (0.0, 0.0),
            Plane::Xy,
            true,
            0,
            TOL,
        )
        .unwrap();
        let r1 = (a.start - a.center).norm();
        let r2 = (a.end - a.center).norm();
        assert!((r1 - r2).abs() < 1e-12);
    }
}
