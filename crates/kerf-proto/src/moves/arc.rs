//! One arc, in millimetres (docs/PROTOCOL.md): the arc tolerance and the check that an
//! arc's numbers agree about its geometry.

use kerf_geom::{Arc, Vec3};

use crate::Reject;

/// Allowed deviation of `|axis|` from 1 (absolute).
pub const AXIS_UNIT_TOL: f64 = 1e-9;
/// The absolute part of the arc tolerance, mm: how far `end_mm` may lie from the point
/// that `start_mm`, `center_mm`, `axis` and `sweep_rad` lead to (see [`arc_tolerance_mm`]).
/// The interpreter's arcs agree to rounding (about 1e-13 mm at ordinary coordinates); one
/// micrometre leaves room for planners that compute arcs in other ways while refusing
/// data that disagree by a visible amount of path, at any radius.
pub const ARC_END_TOL_MM: f64 = 1e-6;
/// The relative part of the arc tolerance, 2^-46: the rounding of the arc's numbers
/// themselves, 64 units in the last place of the largest one (1.4e-12 mm at 100 mm; it
/// reaches [`ARC_END_TOL_MM`] only beyond 7e7 mm).
pub const ARC_ROUNDING_REL: f64 = 1.0 / 70_368_744_177_664.0;
/// Smallest arc radius accepted, mm (the geometry degenerates below it).
pub const ARC_MIN_RADIUS_MM: f64 = 1e-12;

/// The arc tolerance for an arc of radius `radius_mm` (the start's distance from the
/// centre normal to the axis): `ARC_END_TOL_MM + ARC_ROUNDING_REL × m`, `m` the largest
/// magnitude among the coordinates of start, end and centre and the path length
/// `radius_mm · |sweep_rad|`. NaN when a number is NaN.
fn tolerance_for(a: &Arc, radius_mm: f64) -> f64 {
    let mut largest = radius_mm * a.sweep_rad.abs();
    for p in [&a.start, &a.end, &a.center] {
        for &c in p.iter() {
            // Written so that a NaN anywhere makes the result NaN (`f64::max` drops it).
            if largest.is_nan() || c.is_nan() {
                return f64::NAN;
            }
            largest = largest.max(c.abs());
        }
    }
    ARC_END_TOL_MM + ARC_ROUNDING_REL * largest
}

/// The arc tolerance of `a`, mm (docs/PROTOCOL.md, "One arc, in millimetres"):
/// `ARC_END_TOL_MM + ARC_ROUNDING_REL × m`, where `m` is the largest magnitude among the
/// coordinates of `start`, `end` and `center` and the path length `r · |sweep_rad|`, `r`
/// being the start's distance from the centre normal to the axis. It bounds both the
/// distance of `end` from the point the sweep leads to and the centre's distance from the
/// start's plane. NaN when a number is NaN; infinite when the path length overflows
/// (such an arc is refused).
pub fn arc_tolerance_mm(a: &Arc) -> f64 {
    let axis = a.axis.try_normalize(0.0).unwrap_or_else(Vec3::zeros);
    let u = a.start - a.center;
    let radius_mm = (u - axis * u.dot(&axis)).norm();
    tolerance_for(a, radius_mm)
}

/// Checks the arc's geometry in millimetres of path (docs/PROTOCOL.md, "One arc, in
/// millimetres"); all inputs are finite. Every check is written as "within" (a comparison
/// that is false for NaN, then negated) so that a NaN from overflowing intermediate values
/// (huge coordinates) refuses the arc.
pub(super) fn check_arc(a: &Arc) -> Result<(), Reject> {
    let norm = a.axis.norm();
    let unit = (norm - 1.0).abs() <= AXIS_UNIT_TOL;
    if !unit {
        return Err(Reject::AxisNotUnit);
    }
    let axis = a.axis / norm;
    let u = a.start - a.center;
    let along = u.dot(&axis);
    let u = u - axis * along;
    let radius_mm = u.norm();
    let has_radius = radius_mm >= ARC_MIN_RADIUS_MM;
    if !has_radius {
        return Err(Reject::ZeroRadius);
    }
    let tol_mm = tolerance_for(a, radius_mm);
    let plane_off_mm = along.abs();
    let in_plane = plane_off_mm <= tol_mm;
    if !in_plane {
        return Err(Reject::CenterOffPlane {
            off_mm: plane_off_mm,
            tol_mm,
        });
    }
    if a.sweep_rad == 0.0 {
        return Err(Reject::ZeroSweep);
    }
    // q − start = r (e1 (cos θ − 1) + e2 sin θ) + a h, with cos θ − 1 = −2 sin²(θ/2) so
    // that a small angle on a huge radius keeps its precision; compared with end − start
    // rather than q with end, so that coordinates far from the origin lose nothing either.
    let e1 = u / radius_mm;
    let e2 = axis.cross(&e1);
    let theta = a.sweep_rad;
    let half_sin = (0.5 * theta).sin();
    let cos_minus_1 = -2.0 * half_sin * half_sin;
    let chord = a.end - a.start;
    let lead = (e1 * cos_minus_1 + e2 * theta.sin()) * radius_mm + axis * chord.dot(&axis);
    let off_mm = (lead - chord).norm();
    // An infinite tolerance (a path length beyond f64) accepts nothing.
    let agree = off_mm <= tol_mm && tol_mm < f64::INFINITY;
    if !agree {
        return Err(Reject::EndMismatch { off_mm, tol_mm });
    }
    Ok(())
}
