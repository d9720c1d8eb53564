//! Sampled bounds of a quintic segment's tangent, curvature vector and the curvature's
//! derivative per axis, with what they may rise between samples, and the plane of a
//! planar curve.

use kerf_geom::PerAxis;
use kerf_geom::{Transition, Vec3, rotary_derivatives};

use super::{CURVATURE_SAFETY, LIMIT_SAFETY, RATE_SAFETY, TANGENT_SAFETY};

/// Sampled bounds of a transition (with the safety factors above on the curvature terms).
#[derive(Clone, Copy)]
pub(super) struct TransitionBounds {
    /// Per axis X..C: largest `|t_i|` (unit tangent; for rotary axes `dA/ds`).
    pub(super) tangent: PerAxis<f64>,
    /// Per axis: largest `|K_i|` (curvature vector; for rotary axes `d²A/ds²`).
    pub(super) curvature: PerAxis<f64>,
    /// Per axis: largest `|K'_i|` (derivative of the curvature vector along the path).
    pub(super) curvature_rate: PerAxis<f64>,
    /// Largest curvature `κ`, 1/mm.
    pub(super) kappa: f64,
    /// Largest `|K' + κ² t| = sqrt(κ'² + (κτ)²)` (the part of `K'` off the tangent), 1/mm².
    pub(super) kappa_rate: f64,
    /// Per axis: the largest share of a vector in the curve's plane that the axis sees,
    /// `sqrt(1 - N_i²)` for a planar curve with normal `N`, 1 otherwise.
    pub(super) plane: [f64; 3],
}

/// Bounds of a transition, sampled densely along it: one [`TransitionBounds`] for each of
/// `windows` equal stretches of its parameter (each covering its own samples and what
/// may rise between them, so each holds on its stretch alone). The budget of the whole
/// transition is the least of the stretches' budgets: tighter than one set of maxima over
/// the whole curve, where the steepest tangent, the largest curvature and its fastest
/// change count as if they came together even where they are a millimetre apart.
pub(super) fn transition_bounds(
    t: &Transition,
    abc: Option<&[[f64; 6]; 3]>,
    samples: usize,
    windows: usize,
) -> Vec<TransitionBounds> {
    let n = samples;
    let windows = windows.clamp(1, n);
    // Frames on a grid in u. X, Y, Z: the curvature's derivative in closed form
    // ([`Transition::frame_rate_at_param`]), its rise between samples bounded by
    // [`rate_rise`]. Rotary axes: their derivatives with respect to the XYZ arc length,
    // the second one's rate by central differences on the grid (one-sided at the ends).
    let mut rate: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; n + 1]);
    let mut tangent: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; n + 1]);
    let mut curvature: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; n + 1]);
    let mut kappa = vec![0.0; n + 1];
    let mut kappa_rate = vec![0.0; n + 1];
    // Rotary axes per sample: |dA/ds|, |d²A/ds²| and the rate of the latter (none
    // without rotary motion: their bounds stay 0).
    let rot_len = if abc.is_some() { n + 1 } else { 0 };
    let mut rot: [[Vec<f64>; 3]; 3] =
        std::array::from_fn(|_| std::array::from_fn(|_| vec![0.0; rot_len]));
    let rotary = |i: usize| {
        let u = i as f64 / n as f64;
        abc.map_or(([0.0; 3], [0.0; 3]), |c| rotary_derivatives(t, c, u))
    };
    let (mut prev, mut cur) = (rotary(0), rotary(0));
    for i in 0..=n {
        let u = i as f64 / n as f64;
        let (tan, k, dk) = t.frame_rate_at_param(u);
        let next = if i < n { rotary(i + 1) } else { cur };
        for ax in 0..3 {
            tangent[ax][i] = tan[ax];
            curvature[ax][i] = k[ax].abs();
            rate[ax][i] = dk[ax];
        }
        let kap = k.norm();
        kappa[i] = kap;
        kappa_rate[i] = (dk + tan * (kap * kap)).norm();
        if abc.is_some() {
            let (ia, ib) = (i.saturating_sub(1), (i + 1).min(n));
            let ka = if i == 0 { cur.1 } else { prev.1 };
            let kb = if i == n { cur.1 } else { next.1 };
            let ds = (ib - ia) as f64 / n as f64 * t.speed(u);
            for r in 0..3 {
                rot[0][r][i] = cur.0[r].abs();
                rot[1][r][i] = cur.1[r].abs();
                rot[2][r][i] = ((kb[r] - ka[r]) / ds).abs();
            }
        }
        prev = cur;
        cur = next;
    }
    let plane = plane_normal(&t.coef).map_or([1.0; 3], |normal| {
        std::array::from_fn(|ax| (1.0 - normal[ax] * normal[ax]).max(0.0).sqrt())
    });
    let max_of = |f: &[f64]| f.iter().fold(0.0, |m: f64, x| m.max(*x));
    (0..windows)
        .map(|w| {
            // Samples lo..=hi are the stretch's (its end sample is the next one's start).
            let (lo, hi) = (w * n / windows, (w + 1) * n / windows);
            let within = |f: &[f64]| rate_rise(f, lo, hi);
            let mut b = TransitionBounds {
                tangent: [0.0; 6],
                curvature: [0.0; 6],
                curvature_rate: [0.0; 6],
                kappa: max_of(&kappa[lo..=hi]) * CURVATURE_SAFETY,
                kappa_rate: within(&kappa_rate) * RATE_SAFETY,
                plane,
            };
            for ax in 0..3 {
                // The tangent's components too can rise between samples, where the
                // curvature bends them over (by up to 0.08 % at 64 samples, more than
                // `TANGENT_SAFETY` alone covers).
                b.tangent[ax] = (within(&tangent[ax]) * TANGENT_SAFETY).min(1.0);
                b.curvature[ax] = max_of(&curvature[ax][lo..=hi]) * CURVATURE_SAFETY;
                b.curvature_rate[ax] = within(&rate[ax]) * RATE_SAFETY;
                // Rotary derivatives come from central differences, which smooth the
                // peaks: the larger factor.
                if abc.is_some() {
                    b.tangent[3 + ax] = max_of(&rot[0][ax][lo..=hi]) * TANGENT_SAFETY;
                    b.curvature[3 + ax] = max_of(&rot[1][ax][lo..=hi]) * LIMIT_SAFETY;
                    b.curvature_rate[3 + ax] = max_of(&rot[2][ax][lo..=hi]) * LIMIT_SAFETY;
                }
            }
            b
        })
        .collect()
}

/// The stretches of `all` whose budget may be the least: a stretch whose every bound is
/// at most another's has at least that one's budget at every speed and acceleration, so
/// dropping it changes no result and saves the budget searches its evaluations.
pub(super) fn without_covered(all: Vec<TransitionBounds>) -> Vec<TransitionBounds> {
    let mut kept: Vec<TransitionBounds> = Vec::with_capacity(all.len());
    for (i, b) in all.iter().enumerate() {
        // Of two equal stretches the first is kept.
        let covered = all
            .iter()
            .enumerate()
            .any(|(k, c)| k != i && c.covers(b) && (k < i || !b.covers(c)));
        if !covered {
            kept.push(*b);
        }
    }
    kept
}

impl TransitionBounds {
    /// Every bound of `self` at least `other`'s (same plane): `self`'s budget is then at
    /// most `other`'s at every speed and acceleration.
    fn covers(&self, other: &TransitionBounds) -> bool {
        let ge = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| x >= y);
        ge(&self.tangent, &other.tangent)
            && ge(&self.curvature, &other.curvature)
            && ge(&self.curvature_rate, &other.curvature_rate)
            && self.kappa >= other.kappa
            && self.kappa_rate >= other.kappa_rate
            && ge(&self.plane, &other.plane)
    }
}

/// A bound on `|f|` between the equally spaced samples `f_lo ..= f_hi` of a smooth
/// function: the largest of their `|f_k|` plus [`rise_between_samples`] over the second
/// differences around them (one sample either side more, where there is one).
pub(super) fn rate_rise(f: &[f64], lo: usize, hi: usize) -> f64 {
    let max = f[lo..=hi].iter().fold(0.0, |m: f64, x| m.max(x.abs()));
    let around = &f[lo.saturating_sub(1)..=(hi + 1).min(f.len() - 1)];
    max + rise_between_samples(around)
}

/// How far a smooth function may rise between equally spaced samples `f_k` above the
/// larger of the two: a quarter of the largest second difference `|f_k+1 − 2f_k + f_k−1|`.
/// A parabola through three samples rises above them by at most an eighth of its second
/// difference; twice that covers the change of the second derivative between samples.
pub(super) fn rise_between_samples(f: &[f64]) -> f64 {
    let bend = f
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
        .fold(0.0, f64::max);
    0.25 * bend
}

/// A curve counts as straight when its coefficients' largest cross product is below this,
/// relative to their squared size: rounding noise, no plane to speak of.
const STRAIGHT_REL: f64 = 1e-9;
/// A curve counts as planar when every coefficient leaves the plane by at most this,
/// relative to their size: a few ulps of rounding.
const PLANAR_REL: f64 = 1e-12;

/// The unit normal of the plane a polynomial curve lies in, if it is planar (and not
/// straight).
pub(super) fn plane_normal(coef: &[Vec3; 6]) -> Option<Vec3> {
    let scale = coef[1..].iter().map(|c| c.norm()).fold(0.0, f64::max);
    if scale.is_nan() || scale <= 0.0 {
        return None;
    }
    let mut best = Vec3::zeros();
    for i in 1..6 {
        for j in i + 1..6 {
            let c = coef[i].cross(&coef[j]);
            if c.norm() > best.norm() {
                best = c;
            }
        }
    }
    if best.norm() <= STRAIGHT_REL * scale * scale {
        return None;
    }
    let normal = best.normalize();
    coef[1..]
        .iter()
        .all(|c| c.dot(&normal).abs() <= PLANAR_REL * scale)
        .then_some(normal)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::budget::transition_limits::BOUND_WINDOWS;
    use crate::budget::{LIMIT_SAMPLES, PIECE_LIMIT_SAMPLES};

    /// splitmix64: a fixed-seed stream of draws, no dependency.
    struct Draws(u64);

    impl Draws {
        fn unit_interval(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            (z ^ (z >> 31)) as f64 / u64::MAX as f64
        }

        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.unit_interval()
        }

        /// A direction drawn uniformly on the sphere.
        fn direction(&mut self) -> Vec3 {
            let z = self.range(-1.0, 1.0);
            let phi = self.range(0.0, std::f64::consts::TAU);
            let r = (1.0 - z * z).sqrt();
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        }
    }

    /// Stretches whose every bound is at most another's are dropped (their budget is at
    /// least that one's), of two equal ones the first is kept, and a stretch that is
    /// larger in one bound and smaller in another stays.
    #[test]
    fn only_stretches_that_may_hold_the_least_budget_are_kept() {
        let stretch = |tangent: f64, rate: f64, kappa: f64| TransitionBounds {
            tangent: [tangent, 0.1, 0.0, 0.0, 0.0, 0.0],
            curvature: [0.2; 6],
            curvature_rate: [rate, 0.0, 0.0, 0.0, 0.0, 0.0],
            kappa,
            kappa_rate: rate,
            plane: [1.0; 3],
        };
        let steep = stretch(0.9, 0.1, 0.2);
        let bent = stretch(0.5, 0.8, 0.2);
        let under_both = stretch(0.5, 0.1, 0.2);
        let kept = without_covered(vec![under_both, steep, bent, steep]);
        let tangents: Vec<f64> = kept.iter().map(|b| b.tangent[0]).collect();
        let rates: Vec<f64> = kept.iter().map(|b| b.curvature_rate[0]).collect();
        assert_eq!(tangents, [0.9, 0.5]);
        assert_eq!(rates, [0.1, 0.8]);
        // A stretch larger in the curvature alone covers the other.
        let kept = without_covered(vec![steep, stretch(0.9, 0.1, 0.3)]);
        assert_eq!(kept.len(), 1);
        assert_eq!(kept[0].kappa, 0.3);
    }

    /// The sampled bounds of a quintic, on which the budgets of every smoothed piece and G2
    /// transition rest (the curvature's derivative in closed form at 64 or 128 samples, plus
    /// a bound on its rise between them), against the same quantities at 20,000 points of
    /// random quintics in space: chords of 0.2 to 3 mm, end tangents up to about 50° off the
    /// chord, end curvatures up to 2/mm, parameter scales from 0.8 to 1.6 × the chord
    /// (smoothed pieces use about the arc length, G2 blends 1 to 1.5 × the chord). Each bound
    /// must hold at every dense point, of the whole curve and of each of the stretches the
    /// budgets take separately (`BOUND_WINDOWS`): a miss between samples, or near a
    /// stretch's end, would be a budget above what the axis limits allow. The dense values
    /// come from the closed forms of `kerf-geom`, which its own test checks against
    /// differences of the curve's points.
    #[test]
    fn sampled_bounds_of_a_quintic_hold_between_the_samples() {
        let mut draws = Draws(0x6b65_7266);
        let (mut cases, mut closest) = (0, 0.0f64);
        while cases < 300 {
            let chord = draws.range(0.2, 3.0);
            let d = draws.direction();
            let bend =
                |draws: &mut Draws| (d + draws.direction() * draws.range(0.0, 0.8)).normalize();
            let (t0, t1) = (bend(&mut draws), bend(&mut draws));
            let normal = |draws: &mut Draws, t: Vec3| {
                let v = draws.direction();
                (v - t * v.dot(&t)).normalize() * draws.range(0.0, 2.0)
            };
            let (k0, k1) = (normal(&mut draws, t0), normal(&mut draws, t1));
            let lambda = chord * draws.range(0.8, 1.6);
            let Some(tr) = Transition::new(Vec3::zeros(), t0, k0, d * chord, t1, k1, lambda) else {
                continue;
            };
            cases += 1;
            for (samples, windows) in [
                (PIECE_LIMIT_SAMPLES, 1),
                (LIMIT_SAMPLES, 1),
                (PIECE_LIMIT_SAMPLES, BOUND_WINDOWS),
                (LIMIT_SAMPLES, BOUND_WINDOWS),
            ] {
                let stretches = transition_bounds(&tr, None, samples, windows);
                assert_eq!(stretches.len(), windows);
                for (w, b) in stretches.iter().enumerate() {
                    // Dense points of this stretch of the parameter, its ends included.
                    let n = 20_000 / windows;
                    let (u0, du) = (w as f64 / windows as f64, 1.0 / windows as f64);
                    let mut dense = [[0.0f64; 3]; 3];
                    let (mut kappa, mut kappa_rate) = (0.0f64, 0.0f64);
                    for i in 0..=n {
                        let u = u0 + du * i as f64 / n as f64;
                        let (tan, k, dk) = tr.frame_rate_at_param(u);
                        for ax in 0..3 {
                            dense[0][ax] = dense[0][ax].max(tan[ax].abs());
                            dense[1][ax] = dense[1][ax].max(k[ax].abs());
                            dense[2][ax] = dense[2][ax].max(dk[ax].abs());
                        }
                        kappa = kappa.max(k.norm());
                        kappa_rate = kappa_rate.max((dk + tan * k.norm_squared()).norm());
                    }
                    let bounds = [b.tangent, b.curvature, b.curvature_rate];
                    for (what, (dense, bound)) in ["tangent", "curvature", "curvature rate"]
                        .iter()
                        .zip(dense.iter().zip(bounds))
                    {
                        for ax in 0..3 {
                            assert!(
                                dense[ax] <= bound[ax] + 1e-9,
                                "case {cases}, {samples} samples, stretch {w} of {windows}, \
                                 axis {ax}: {what} {} above its bound {}",
                                dense[ax],
                                bound[ax]
                            );
                            if dense[ax] > 1e-6 {
                                closest = closest.max(dense[ax] / bound[ax]);
                            }
                        }
                    }
                    assert!(
                        kappa <= b.kappa + 1e-9,
                        "case {cases}, stretch {w} of {windows}: κ {kappa} > {}",
                        b.kappa
                    );
                    assert!(
                        kappa_rate <= b.kappa_rate + 1e-9,
                        "case {cases}, stretch {w} of {windows}: κ' {kappa_rate} > {}",
                        b.kappa_rate
                    );
                }
            }
        }
        // The bounds are tight somewhere (not merely huge).
        assert!(closest > 0.97, "{closest}");
    }
}
