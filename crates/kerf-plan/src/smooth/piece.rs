//! A piece between two knots: the quintic (and the rotary quintics), checked against the
//! polyline it replaces within the tolerance.

use kerf_geom::{Transition, Vec3, poly5, quintic};

use super::{Knot, PieceCurves, Run};
use crate::TRANSITION_TOL_SHARE;

impl Run {
    /// The quintic between two knots, with the rotary quintics if the run moves a rotary
    /// axis, if they stay within the tolerance of the polyline (rotary axes: the same
    /// number in degrees, against the programmed linear interpolation).
    pub(super) fn piece(&self, ka: &Knot, kb: &Knot) -> Option<PieceCurves> {
        let chord = (kb.p - ka.p).norm();
        if chord.is_nan() || chord <= 0.0 {
            return None;
        }
        // The parameter scale is the arc length of the polyline between the knots (the
        // vertices are dense, so it is the curve's arc length to within the rounding):
        // `p'(u) = λt`, `p''(u) = λ²K` at both ends are then exactly the derivatives of
        // the curve parametrised by `u = s/λ`, and the quintic reproduces a smooth curve to
        // sixth order. With the chord (shorter by `θ²/24` of the length for a turn of θ)
        // the ends would be parametrised too slowly for the middle: the pieces would sag
        // between knots and their third derivative, which the axes' jerk must follow,
        // would exceed the surface's.
        let poly_len = self.v(kb.idx).sigma - self.v(ka.idx).sigma;
        let lambda = if poly_len.is_finite() && poly_len >= chord {
            poly_len
        } else {
            chord
        };
        let tr = Transition::hermite(ka.p, ka.t, ka.k, kb.p, kb.t, kb.k, lambda)?;
        // With p'(0) = λt and p''(0) = λ²K (K ⟂ t), ds/du = λ and d²s/du² = 0 at the ends,
        // so dA/du = λ dA/ds and d²A/du² = λ² d²A/ds² there.
        let poly = self.rotary.then(|| {
            let l = lambda;
            std::array::from_fn(|i| {
                quintic::hermite(
                    ka.a[i],
                    l * ka.da[i],
                    l * l * ka.dda[i],
                    kb.a[i],
                    l * kb.da[i],
                    l * l * kb.dda[i],
                )
            })
        });
        // Twelve samples per line it replaces, and at least one per 0.0125 mm (between
        // samples the distance to a line changes by spacing² · κ / 8 at most, which the
        // tenth of the tolerance that `TRANSITION_TOL_SHARE` leaves must cover); fewer
        // let a piece leave the tolerance between samples on random dense polylines.
        // Without rotary axes, never more than the samples that leave at most a tenth of
        // the tolerance of the quintic's length between two of them: the distance to the
        // polyline grows no faster than the point moves, so between them it rises by a
        // twentieth of the tolerance at most, within the tenth left. (The quintic's speed
        // `|p'(u)|` is at most `Σ i·|cᵢ|` on [0, 1].) This bounds the cost of code whose
        // steps are far under the tolerance.
        let segments = (kb.idx - ka.idx) as usize;
        let per_line = if self.rotary {
            12 * segments
        } else {
            let speed_bound: f64 = (1..6).map(|i| i as f64 * tr.coef[i].norm()).sum();
            (12 * segments).min((speed_bound / (0.1 * self.tol)).ceil() as usize)
        };
        let n = per_line.max((chord / 0.0125) as usize).clamp(128, 4096);
        let limit = TRANSITION_TOL_SHARE * self.tol;
        let mut cursor = ka.idx;
        for i in 1..n {
            let u = i as f64 / n as f64;
            let q = tr.poly(u);
            let (d, c, along) = self.nearest(&q, cursor, ka.idx, kb.idx, limit);
            if d.is_nan() || d > limit {
                return None;
            }
            if let Some(poly) = &poly {
                let (a, b) = (self.v(c).abc, self.v(c + 1).abc);
                for ax in 0..3 {
                    let programmed = a[ax] + (b[ax] - a[ax]) * along;
                    let off = (poly5(&poly[ax], u) - programmed).abs();
                    if off.is_nan() || off > limit {
                        return None;
                    }
                }
            }
            cursor = c;
        }
        let tr = tr.with_arc_length()?;
        // The arc-length table must not be much longer than the polyline (a loop).
        (tr.length_mm <= 1.5 * poly_len + self.tol).then_some((tr, poly))
    }

    /// Distance from `q` to the polyline segments `[lo, hi)`, searched from `cursor`
    /// (the samples advance along the polyline): the minimum over the segments visited, so
    /// never less than the true distance.
    /// Also returns the segment and the position along it (0 to 1) of the nearest point.
    fn nearest(&self, q: &Vec3, cursor: u64, lo: u64, hi: u64, slack: f64) -> (f64, u64, f64) {
        let mut k = cursor.saturating_sub(1).max(lo);
        let mut best = (f64::INFINITY, cursor.min(hi.saturating_sub(1)).max(lo), 0.0);
        while k < hi {
            let a = self.v(k).p;
            let b = self.v(k + 1).p;
            let (d, along) = segment_distance_along(q, &a, &b);
            if d < best.0 {
                best = (d, k, along);
            } else if k > cursor && (q - a).norm() > best.0 + slack {
                break;
            }
            k += 1;
        }
        best
    }
}

/// Distance from `q` to the segment `a`–`b`.
#[cfg(test)]
pub(super) fn segment_distance(q: &Vec3, a: &Vec3, b: &Vec3) -> f64 {
    segment_distance_along(q, a, b).0
}

/// Distance from `q` to the segment `a`–`b`, and where along it (0 to 1) the nearest point is.
pub(super) fn segment_distance_along(q: &Vec3, a: &Vec3, b: &Vec3) -> (f64, f64) {
    let ab = b - a;
    let l2 = ab.norm_squared();
    if l2 == 0.0 {
        return ((q - a).norm(), 0.0);
    }
    let t = ((q - a).dot(&ab) / l2).clamp(0.0, 1.0);
    ((q - (a + ab * t)).norm(), t)
}
