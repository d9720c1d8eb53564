//! Limits of a quintic segment (a G2 transition, a G2 corner blend or a smoothed piece)
//! from its sampled bounds, by the per-axis and the Frenet bound, whichever is larger.

use kerf_geom::Transition;

use super::bounds::{TransitionBounds, transition_bounds, without_covered};
use super::design::design_speed_search;
use super::envelope::envelope_budget;
use super::{CENTRIPETAL_SHARE, boosted};
use crate::memo::Limits;
use crate::{MachineLimits, PROFILE_SHARE, PlannedSegment};

/// Stretches a quintic's bounds are taken on ([`transition_bounds`]): its budget is the
/// least of theirs. With one, the maxima over the whole curve meet where they do not
/// (steepest tangent, largest curvature, fastest change of it); eight took raster B from
/// 3.755 s to 3.670 s and raster C from 5.223 s to 5.138 s (`cam_table`) for 2.5× the
/// planning cost on raster B (`plan_rate`: 9.7 → 24 µs per move; 0.70× that again in
/// instructions since each stretch is joined with the limits once, [`StretchTerms`]);
/// sixteen, 8 ms more for 1.7× that cost again.
pub(super) const BOUND_WINDOWS: usize = 8;

/// Path limits of a G2 transition. With arc-length parametrisation each axis sees
/// `x_i'' = t_i a + K_i v²` and `x_i''' = t_i j + 3 K_i v a + K'_i v³`. Two bounds hold for
/// every axis and either may be used: the per-axis one, `|t_i| a + |K_i| v²` and
/// `|t_i| j + 3 |K_i| v a + |K'_i| v³` with the sampled maxima; and the Frenet one,
/// `w_i sqrt(a² + (κv²)²)` and `w_i sqrt((j + κ²v³)² + (3κva + |K' + κ²t| v³)²)` (the
/// tangent and normal parts of the vectors are orthogonal; `w_i` is the axis' share of the
/// curve's plane), which is much tighter where the curve turns. They are kept within
/// [`PROFILE_SHARE`] of the limits at every speed `v` up to the design speed `vd` with
/// tangential accelerations `|a| ≤ sqrt(2j(vd − v))`, the jerk-limited envelope of
/// [`envelope_budget`] (not the full `a` at `vd`); the design speed is chosen like on
/// arcs. Both are taken on each stretch of the curve with its own maxima
/// ([`BOUND_WINDOWS`]), and the budget at each speed is the least over the stretches.
pub(super) fn transition_limits(
    seg: &PlannedSegment,
    t: &Transition,
    limits: &MachineLimits,
    samples: usize,
    feed_scale: f64,
    boost_scale: Option<f64>,
    run_mm: f64,
) -> Limits {
    let windows = without_covered(transition_bounds(
        t,
        seg.abc_poly.as_ref(),
        samples,
        BOUND_WINDOWS,
    ));
    let share = PROFILE_SHARE;
    let mut v = f64::INFINITY;
    for b in &windows {
        let (tm, km, kp) = (b.tangent, b.curvature, b.curvature_rate);
        for i in 0..6 {
            let Some(l) = limits.axes[i] else { continue };
            if tm[i] > 0.0 {
                v = v.min(share * l.velocity_units_s / tm[i]);
            }
            if km[i] > 0.0 {
                v = v.min((CENTRIPETAL_SHARE * share * l.acceleration_units_s2 / km[i]).sqrt());
            }
            if kp[i] > 0.0 {
                v = v.min((CENTRIPETAL_SHARE * share * l.jerk_units_s3 / kp[i]).cbrt());
            }
        }
    }
    let stretches: Vec<StretchTerms> = windows
        .iter()
        .map(|b| StretchTerms::new(b, limits))
        .collect();
    // The budget on the whole transition: the least over its stretches.
    let accel_at = |vd: f64| -> Option<f64> {
        let a = stretches
            .iter()
            .map(|s| s.accel(vd))
            .fold(f64::INFINITY, f64::min);
        (a > 0.0 && a.is_finite()).then_some(a)
    };
    let jerk_at = |vd: f64, a: f64| -> f64 {
        stretches
            .iter()
            .map(|s| s.jerk(vd, a))
            .fold(f64::INFINITY, f64::min)
    };
    let budget = |vd: f64| envelope_budget(vd, &accel_at, &jerk_at);
    let run_mm = seg.length_mm.max(run_mm);
    let search = |v_start: f64| design_speed_search(run_mm, v_start, budget);
    boosted(v, seg.feed_mm_s, feed_scale, boost_scale, search)
}

/// One axis of a stretch: its limits within [`PROFILE_SHARE`] and the stretch's bounds.
#[derive(Clone, Copy, Default)]
struct AxisTerms {
    accel: f64,
    jerk: f64,
    tangent: f64,
    curvature: f64,
    curvature_rate: f64,
    rotary: bool,
}

/// A stretch's bounds joined with the axis limits once, for the design search's many
/// evaluations of the budget at a speed: the axes that have limits, and the Frenet
/// bound's least limit over X, Y and Z scaled by the axis' share of the curve's plane
/// (its bound is the same increasing function of that limit on every axis, so the least
/// limit gives the least bound, to the bit).
struct StretchTerms {
    axes: [AxisTerms; 6],
    count: usize,
    frenet_accel: f64,
    frenet_jerk: f64,
    kappa: f64,
    kappa_rate: f64,
}

impl StretchTerms {
    fn new(b: &TransitionBounds, limits: &MachineLimits) -> Self {
        let share = PROFILE_SHARE;
        let mut s = StretchTerms {
            axes: [AxisTerms::default(); 6],
            count: 0,
            frenet_accel: f64::INFINITY,
            frenet_jerk: f64::INFINITY,
            kappa: b.kappa,
            kappa_rate: b.kappa_rate,
        };
        for i in 0..6 {
            let Some(l) = limits.axes[i] else { continue };
            let (accel, jerk) = (share * l.acceleration_units_s2, share * l.jerk_units_s3);
            s.axes[s.count] = AxisTerms {
                accel,
                jerk,
                tangent: b.tangent[i],
                curvature: b.curvature[i],
                curvature_rate: b.curvature_rate[i],
                rotary: i >= 3,
            };
            s.count += 1;
            if i < 3 && b.plane[i] > 0.0 {
                s.frenet_accel = s.frenet_accel.min(accel / b.plane[i]);
                s.frenet_jerk = s.frenet_jerk.min(jerk / b.plane[i]);
            }
        }
        s
    }

    /// Largest tangential acceleration at speed `vd` on the stretch, by either bound.
    fn accel(&self, vd: f64) -> f64 {
        let mut per_axis = f64::INFINITY;
        // Rotary axes have only the per-axis bound, under either choice.
        let mut frenet = f64::INFINITY;
        for ax in &self.axes[..self.count] {
            let own = axis_rate(ax.accel - ax.curvature * vd * vd, ax.tangent);
            per_axis = per_axis.min(own);
            if ax.rotary {
                frenet = frenet.min(own);
            }
        }
        let c = self.frenet_accel;
        if c.is_finite() {
            let n = self.kappa * vd * vd;
            frenet = frenet.min((c * c - n * n).max(0.0).sqrt());
        }
        per_axis.max(frenet)
    }

    /// Largest tangential jerk at speed `vd` and tangential acceleration `a` on the
    /// stretch, by either bound.
    fn jerk(&self, vd: f64, a: f64) -> f64 {
        let mut per_axis = f64::INFINITY;
        let mut frenet = f64::INFINITY;
        for ax in &self.axes[..self.count] {
            let room = ax.jerk - 3.0 * ax.curvature * vd * a - ax.curvature_rate * vd * vd * vd;
            let own = axis_rate(room, ax.tangent);
            per_axis = per_axis.min(own);
            if ax.rotary {
                frenet = frenet.min(own);
            }
        }
        let c = self.frenet_jerk;
        if c.is_finite() {
            let n = 3.0 * self.kappa * vd * a + self.kappa_rate * vd * vd * vd;
            let tangential = (c * c - n * n).max(0.0).sqrt() - self.kappa * self.kappa * vd.powi(3);
            frenet = frenet.min(tangential.max(0.0));
        }
        per_axis.max(frenet)
    }
}

/// The largest tangential rate (acceleration or jerk) an axis allows when `room` of its
/// limit is left after the curvature terms and it sees `weight` of the tangential rate:
/// none if nothing is left, any if it does not see it.
pub(super) fn axis_rate(room: f64, weight: f64) -> f64 {
    if room <= 0.0 {
        0.0
    } else if weight > 0.0 {
        room / weight
    } else {
        f64::INFINITY
    }
}
