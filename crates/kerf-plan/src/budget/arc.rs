//! Budgets of lines, arcs and helices: the per-axis weights of the segment's tangent and
//! curvature, and the tangential budget at a design speed (in closed form for arcs in a
//! coordinate plane, by bisection for helices in tilted planes).

use kerf_geom::Curve;
use kerf_geom::PerAxis;

use super::design::design_speed_search;
use super::envelope::envelope_budget;
use super::{CENTRIPETAL_SHARE, boosted};
use crate::memo::Limits;
use crate::search::bisect_max;
use crate::{MachineLimits, PROFILE_SHARE, PlannedSegment};

/// Floor of the in-plane speed factor `q` when dividing by it (a helix that is nearly a
/// straight line along its axis): keeps the quotient finite.
const MIN_IN_PLANE_FACTOR: f64 = 1e-9;

/// Per-axis geometric weights of a segment: the largest |component| over the segment of
/// the unit tangent split into in-plane and axial parts, and the curvature terms.
struct Weights {
    /// Max |tangent_i| over the segment.
    tangent: PerAxis<f64>,
    /// In-plane weight `sqrt(1 - axis_i²)` (0 on lines and rotary axes).
    plane: PerAxis<f64>,
    /// Axial tangent component `|axis_i| · rise/length` on helices.
    axial: PerAxis<f64>,
    /// In-plane speed factor `r |sweep| / length`.
    q: f64,
    /// Curvature, 1/mm.
    kappa: f64,
    /// Sweep per unit length, rad/mm.
    sigma: f64,
}

fn weights(seg: &PlannedSegment) -> Weights {
    let mut w = Weights {
        tangent: [0.0; 6],
        plane: [0.0; 6],
        axial: [0.0; 6],
        q: 0.0,
        kappa: 0.0,
        sigma: 0.0,
    };
    match &seg.curve {
        Curve::Line { dir, .. } => {
            if seg.curve.length() > 0.0 {
                for i in 0..3 {
                    w.tangent[i] = dir[i].abs();
                }
            }
        }
        Curve::Helix(h) => {
            let q = h.radius_mm * h.sweep_rad.abs() / h.length_mm;
            let c = h.rise_mm.abs() / h.length_mm;
            w.q = q;
            w.sigma = h.sweep_rad.abs() / h.length_mm;
            w.kappa = h.curvature();
            for i in 0..3 {
                let ax = h.axis[i].abs().min(1.0);
                w.plane[i] = (1.0 - ax * ax).max(0.0).sqrt();
                w.axial[i] = ax * c;
                // The drift (what the circle misses of the end, within the protocol's arc
                // tolerance; rounding on the interpreter's arcs) moves the axis too.
                let drift = (h.drift_mm_per_rad[i] * h.sweep_rad / h.length_mm).abs();
                w.tangent[i] = w.plane[i] * q + w.axial[i] + drift;
            }
        }
        Curve::Transition(_) => unreachable!("transitions have their own limits"),
    }
    for i in 0..3 {
        w.tangent[3 + i] = (seg.abc_end_deg[i] - seg.abc_start_deg[i]).abs() / seg.length_mm;
    }
    w
}

/// [`super::segment_limits_pair`] of a line, arc or helix: the speed limit from the
/// tangent and the curvature terms, and on curves the design with the least rough time.
pub(super) fn arc_limits(
    seg: &PlannedSegment,
    limits: &MachineLimits,
    feed_scale: f64,
    boost_scale: Option<f64>,
    run_mm: f64,
) -> Limits {
    let w = weights(seg);
    let share = PROFILE_SHARE;
    let mut v = f64::INFINITY;
    let mut a_line = f64::INFINITY;
    let mut j_line = f64::INFINITY;
    let mut v2 = f64::INFINITY;
    let mut v3 = f64::INFINITY;
    for i in 0..6 {
        let Some(l) = limits.axes[i] else { continue };
        if w.tangent[i] > 0.0 {
            v = v.min(share * l.velocity_units_s / w.tangent[i]);
        }
        if w.plane[i] > 0.0 && w.kappa > 0.0 {
            // Bounds on v² and v³; the roots are taken once, after the loop.
            v2 = v2
                .min(CENTRIPETAL_SHARE * share * l.acceleration_units_s2 / (w.plane[i] * w.kappa));
            v3 = v3.min(
                CENTRIPETAL_SHARE * share * l.jerk_units_s3
                    / (w.plane[i] * w.q * w.sigma * w.sigma),
            );
        }
        // Straight components (lines, helix axial parts, rotary axes).
        let straight = if w.plane[i] > 0.0 {
            w.axial[i]
        } else {
            w.tangent[i]
        };
        if straight > 0.0 && w.plane[i] == 0.0 {
            a_line = a_line.min(share * l.acceleration_units_s2 / straight);
            j_line = j_line.min(share * l.jerk_units_s3 / straight);
        }
    }
    if v2.is_finite() {
        v = v.min(v2.sqrt());
    }
    if v3.is_finite() {
        v = v.min(v3.cbrt());
    }
    if w.kappa == 0.0 {
        return (
            (v, a_line, j_line),
            boost_scale.map(|_| (v, a_line, j_line)),
        );
    }
    // Curved: the acceleration and jerk depend on the speed; the design speed (up to the
    // feed) is the one with the least rough time (cruise plus one ramp).
    let search = |v_start: f64| {
        design_speed_search(run_mm.max(seg.length_mm), v_start, |vd| {
            curved_budget(&w, limits, vd, a_line, j_line)
        })
    };
    boosted(v, seg.feed_mm_s, feed_scale, boost_scale, search)
}

/// The best `(a, j)` on a curved segment at design speed `vd`, if there is a useful one.
fn curved_budget(
    w: &Weights,
    limits: &MachineLimits,
    vd: f64,
    a_line: f64,
    j_line: f64,
) -> Option<(f64, f64)> {
    let share = PROFILE_SHARE;
    if (0..6).all(|i| w.plane[i] == 0.0 || w.axial[i] == 0.0) {
        return curved_budget_closed(w, limits, vd, a_line, j_line);
    }
    let fits_acc = |vd: f64, a: f64| -> bool {
        (0..6).all(|i| match limits.axes[i] {
            None => true,
            Some(l) => {
                let inplane = w.plane[i] * ((w.kappa * vd * vd).powi(2) + (w.q * a).powi(2)).sqrt();
                let straight = if w.plane[i] > 0.0 {
                    w.axial[i]
                } else {
                    w.tangent[i]
                };
                inplane + straight * a <= share * l.acceleration_units_s2
            }
        })
    };
    let fits_jerk = |vd: f64, a: f64, j: f64| -> bool {
        (0..6).all(|i| match limits.axes[i] {
            None => true,
            Some(l) => {
                let tang = w.q * (j + w.sigma * w.sigma * vd * vd * vd);
                let norm = 3.0 * w.kappa * vd * a;
                let inplane = w.plane[i] * (tang * tang + norm * norm).sqrt();
                let straight = if w.plane[i] > 0.0 {
                    w.axial[i]
                } else {
                    w.tangent[i]
                };
                inplane + straight * j <= share * l.jerk_units_s3
            }
        })
    };
    // The smallest axis limits bound the searches from above.
    let (mut a_cap, mut j_cap) = (a_line, j_line);
    for l in limits.axes.iter().flatten() {
        a_cap = a_cap.min(l.acceleration_units_s2 / w.q.max(MIN_IN_PLANE_FACTOR));
        j_cap = j_cap.min(l.jerk_units_s3 / w.q.max(MIN_IN_PLANE_FACTOR));
    }
    let accel_at = |v: f64| -> Option<f64> {
        let a = bisect_max(|a| fits_acc(v, a), a_cap);
        (a > 0.0).then_some(a)
    };
    let jerk_at = |v: f64, a: f64| bisect_max(|j| fits_jerk(v, a, j), j_cap);
    envelope_budget(vd, &accel_at, &jerk_at)
}

/// [`curved_budget`] in closed form, for segments where no axis sees both an in-plane and
/// an axial component (every arc in G17/G18/G19 and every blend): per axis the in-plane
/// constraints `w·sqrt((κv²)² + (qa)²) ≤ A` and `w·sqrt((q(j + σ²v³))² + (3κva)²) ≤ J`
/// solve directly for `a` and `j`.
fn curved_budget_closed(
    w: &Weights,
    limits: &MachineLimits,
    vd: f64,
    a_line: f64,
    j_line: f64,
) -> Option<(f64, f64)> {
    let share = PROFILE_SHARE;
    let accel_at = |vd: f64| -> Option<f64> {
        let centripetal = w.kappa * vd * vd;
        let mut a_hi = a_line;
        for i in 0..6 {
            let (Some(l), true) = (limits.axes[i], w.plane[i] > 0.0) else {
                continue;
            };
            let b = share * l.acceleration_units_s2 / w.plane[i];
            let room = b * b - centripetal * centripetal;
            if room <= 0.0 {
                return None;
            }
            a_hi = a_hi.min(room.sqrt() / w.q);
        }
        (a_hi > 0.0 && a_hi.is_finite()).then_some(a_hi)
    };
    let jerk_for = |vd: f64, a: f64| -> f64 {
        let mut j = j_line;
        let normal = 3.0 * w.kappa * vd * a;
        for i in 0..6 {
            let (Some(l), true) = (limits.axes[i], w.plane[i] > 0.0) else {
                continue;
            };
            let c = share * l.jerk_units_s3 / w.plane[i];
            let room = c * c - normal * normal;
            if room <= 0.0 {
                return 0.0;
            }
            j = j.min(room.sqrt() / w.q - w.sigma * w.sigma * vd * vd * vd);
        }
        j
    };
    envelope_budget(vd, &accel_at, &jerk_for)
}
