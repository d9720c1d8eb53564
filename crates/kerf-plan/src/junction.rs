//! Junction caps: the speed at which one segment may pass into the next.

use crate::{JUNCTION_SHARE, MachineLimits, PlannedSegment};

/// Tangent or curvature steps at or below this (per axis, 1 and 1/mm) are rounding noise
/// of the unit tangents and curvature vectors, not a kink: they set no cap.
const NEGLIGIBLE_STEP: f64 = 1e-12;

/// Speed cap at the junction from `a` to `b`, from the tangent and curvature steps seen by
/// finite differences at the period.
pub fn junction_cap(a: &PlannedSegment, b: &PlannedSegment, limits: &MachineLimits) -> f64 {
    let (ta, ka) = a.derivatives_at(a.length_mm);
    let (tb, kb) = b.derivatives_at(0.0);
    let t = limits.period_s;
    let mut cap = a
        .v_boost_mm_s
        .max(a.v_max_mm_s)
        .min(b.v_boost_mm_s.max(b.v_max_mm_s));
    for i in 0..6 {
        let dt = (tb[i] - ta[i]).abs();
        let dk = (kb[i] - ka[i]).abs();
        let Some(l) = limits.axes[i] else {
            if dt > 0.0 || dk > 0.0 {
                return 0.0;
            }
            continue;
        };
        if dt > NEGLIGIBLE_STEP {
            let room = JUNCTION_SHARE * l.acceleration_units_s2.min(l.jerk_units_s3 * t);
            cap = cap.min(room * t / dt);
            // Kinks closer than a period's travel fall several into one finite-difference
            // window, where they add up like a curvature `Δt / L`: `v²·Δt/L` within the same
            // share. It binds only where `L < v·T` (then `sqrt(room·L/Δt) < room·T/Δt`).
            // Counted per kink alone, a polygon of tiny corner blends passed two or three
            // to a period would take an axis beyond its acceleration.
            let near = a.length_mm.min(b.length_mm);
            if near > 0.0 {
                cap = cap.min((room * near / dt).sqrt());
            }
        }
        if dk > NEGLIGIBLE_STEP {
            cap = cap.min((JUNCTION_SHARE * l.jerk_units_s3 * t / dk).sqrt());
        }
    }
    cap.max(0.0)
}
