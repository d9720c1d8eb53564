//! Curvature-continuous (G2) transition curves: quintic Hermite polynomials that match
//! position, unit tangent and curvature vector at both ends, evaluated at arc length.
//!
//! The polynomial `p(u)`, `u ∈ [0, 1]`, has `p(0) = P0`, `p'(0) = λT0`, `p''(0) = λ²K0`,
//! `p(1) = P1`, `p'(1) = λT1`, `p''(1) = λ²K1`, where `K` is the curvature vector (normal to
//! `T`): with no tangential component in `p''` the curvature at the ends is exactly `K`.
//!
//! Arc length is not polynomial, so [`Transition::new`] precomputes a fixed table of the
//! parameter `u` at [`TABLE_POINTS`] equally spaced arc lengths (by 5-point Gauss-Legendre
//! quadrature). At run time `s → u` is a cubic Hermite interpolation in the table (slopes
//! `du/ds = 1/|p'(u)|`) and one Newton step on the arc length (5-point quadrature from the
//! table node to the estimate): bounded work, no allocation. The end points are returned
//! exactly.
//!
//! That evaluation is only as good as the quadrature over a table interval, and a curve
//! whose parametric speed changes sharply (a quintic close to a cusp: over a 1.6 mm
//! smoothed piece of a zig-zag, from 0.12 to 2.1 mm per unit of `u`) defeats it: the
//! position can jump at a table node by a fraction of a micrometre, many times an axis'
//! jerk limit at a 1 ms period. [`Transition::with_arc_length`] therefore checks
//! the run-time evaluation against the table on every interval, at its end (where a
//! mismatch is a jump: [`ARC_TABLE_RELATIVE`]) and in its middle ([`ARC_MID_RELATIVE`]),
//! and refuses a curve it cannot serve; the planner then builds another (a shorter transition, other
//! smoothed pieces) or none.

use crate::{Vec3, quintic};

/// Nodes of the arc-length table (equal steps in `s`).
pub const TABLE_POINTS: usize = 33;

/// Largest error of the run-time arc-length evaluation ([`Transition::param_at`]) that
/// [`Transition::with_arc_length`] accepts, relative to a table interval's length: at a
/// table node it is a jump of the position, seen at the period `T` as a jerk of about
/// `2·δ/T³`. 1e-12 of an interval (a 20 mm curve: 6e-13 mm) stays below the rounding of
/// the positions themselves; the planner's curves are evaluated to about 1e-14 (every
/// transition of the CAM corpus), a near-cusp quintic to 1e-4.
pub const ARC_TABLE_RELATIVE: f64 = 1e-12;

/// Largest error of [`Transition::param_at`] in the middle of a table interval that
/// [`Transition::with_arc_length`] accepts, relative to the interval's length: there the
/// error of the one Newton step is smooth and zero at both nodes, so it is no jump; the
/// planner's curves leave up to about 1e-11 (a near-cusp quintic 1e-4).
pub const ARC_MID_RELATIVE: f64 = 1e-9;

/// 5-point Gauss-Legendre nodes and weights on [-1, 1].
const GL_X: [f64; 5] = [
    -0.906_179_845_938_664,
    -0.538_469_310_105_683,
    0.0,
    0.538_469_310_105_683,
    0.906_179_845_938_664,
];
const GL_W: [f64; 5] = [
    0.236_926_885_056_189,
    0.478_628_670_499_366,
    0.568_888_888_888_889,
    0.478_628_670_499_366,
    0.236_926_885_056_189,
];

/// A quintic G2 transition with its arc-length table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transition {
    /// Power-basis coefficients: `p(u) = Σ c[i] uⁱ`.
    pub coef: [Vec3; 6],
    /// Start point (returned exactly at `s <= 0`).
    pub start: Vec3,
    /// End point (returned exactly at `s >= length`).
    pub end: Vec3,
    /// Unit tangent at the start.
    pub t0: Vec3,
    /// Curvature vector at the start, 1/mm.
    pub k0: Vec3,
    /// Unit tangent at the end.
    pub t1: Vec3,
    /// Curvature vector at the end, 1/mm.
    pub k1: Vec3,
    /// Arc length, mm.
    pub length_mm: f64,
    /// `u` at `s = k · length / (TABLE_POINTS - 1)`.
    pub table: [f64; TABLE_POINTS],
}

impl Transition {
    /// The quintic from `(p0, t0, k0)` to `(p1, t1, k1)` with parameter scale `lambda`
    /// (mm; the chord is a good choice), with its arc-length table. `t0`, `t1` must be unit
    /// vectors and `k0 ⟂ t0`, `k1 ⟂ t1`. Returns `None` if the curve has a cusp or is
    /// degenerate.
    pub fn new(
        p0: Vec3,
        t0: Vec3,
        k0: Vec3,
        p1: Vec3,
        t1: Vec3,
        k1: Vec3,
        lambda: f64,
    ) -> Option<Transition> {
        Transition::hermite(p0, t0, k0, p1, t1, k1, lambda)?.with_arc_length()
    }

    /// The polynomial only ([`Transition::poly`] and its derivatives work; arc-length
    /// evaluation needs [`Transition::with_arc_length`]): cheap, for trying shapes.
    pub fn hermite(
        p0: Vec3,
        t0: Vec3,
        k0: Vec3,
        p1: Vec3,
        t1: Vec3,
        k1: Vec3,
        lambda: f64,
    ) -> Option<Transition> {
        if !(lambda > 0.0 && lambda.is_finite()) {
            return None;
        }
        let v0 = t0 * lambda;
        let v1 = t1 * lambda;
        let a0 = k0 * (lambda * lambda);
        let a1 = k1 * (lambda * lambda);
        let coef = quintic::hermite(p0, v0, a0, p1, v1, a1);
        let tr = Transition {
            coef,
            start: p0,
            end: p1,
            t0,
            k0,
            t1,
            k1,
            length_mm: 0.0,
            table: [0.0; TABLE_POINTS],
        };
        Some(tr)
    }

    /// Adds the arc-length table to a [`Transition::hermite`] curve; `None` if the curve
    /// has a cusp (parametric speed below 5 % of the chord scale) or is degenerate.
    pub fn with_arc_length(mut self) -> Option<Transition> {
        let tr = &mut self;
        let lambda = tr.coef[1].norm().max(tr.d1(1.0).norm());
        // No cusp: the parametric speed stays well away from zero.
        let mut min_speed = f64::INFINITY;
        for i in 0..=256 {
            min_speed = min_speed.min(tr.speed(i as f64 / 256.0));
        }
        if min_speed.is_nan() || min_speed <= 0.05 * lambda {
            return None;
        }
        // Cumulative arc length over fine intervals, then invert at equal steps.
        const FINE: usize = 64;
        let mut cum = [0.0; FINE + 1];
        for i in 0..FINE {
            let (a, b) = (i as f64 / FINE as f64, (i + 1) as f64 / FINE as f64);
            cum[i + 1] = cum[i] + tr.arc(a, b);
        }
        let length = cum[FINE];
        if !(length > 0.0 && length.is_finite()) {
            return None;
        }
        tr.length_mm = length;
        tr.table[0] = 0.0;
        tr.table[TABLE_POINTS - 1] = 1.0;
        let mut j = 0;
        for k in 1..TABLE_POINTS - 1 {
            let s = length * k as f64 / (TABLE_POINTS - 1) as f64;
            while j + 1 < FINE && cum[j + 1] < s {
                j += 1;
            }
            let ua = j as f64 / FINE as f64;
            // Newton from the linear estimate within the fine interval.
            let mut u = ua + (s - cum[j]) / (cum[j + 1] - cum[j]) / FINE as f64;
            for _ in 0..8 {
                let err = cum[j] + tr.arc(ua, u) - s;
                let step = err / tr.speed(u);
                u -= step;
                if step.abs() < 1e-15 {
                    break;
                }
            }
            tr.table[k] = u.clamp(0.0, 1.0);
        }
        // The run-time evaluation must reproduce the table: over each interval (its end is
        // where the next interval's evaluation starts afresh, so a mismatch is a jump) and
        // in its middle (one Newton step from the cubic estimate).
        let h = length / (TABLE_POINTS - 1) as f64;
        let allowed = ARC_TABLE_RELATIVE * h;
        for k in 0..TABLE_POINTS - 1 {
            let (u0, u1) = (tr.table[k], tr.table[k + 1]);
            let node_error = (tr.arc(u0, u1) - h).abs();
            if node_error.is_nan() || node_error > allowed {
                return None;
            }
            let s = h * (k as f64 + 0.5);
            let u = tr.param_at(s);
            let mid_error = (tr.arc(u0, u) - 0.5 * h).abs();
            if mid_error.is_nan() || mid_error > ARC_MID_RELATIVE * h {
                return None;
            }
        }
        Some(self)
    }

    /// `p(u)`.
    #[inline]
    pub fn poly(&self, u: f64) -> Vec3 {
        quintic::value(&self.coef, u)
    }

    /// `p'(u)`.
    #[inline]
    pub fn d1(&self, u: f64) -> Vec3 {
        quintic::d1(&self.coef, u)
    }

    /// `p''(u)`.
    #[inline]
    pub fn d2(&self, u: f64) -> Vec3 {
        quintic::d2(&self.coef, u)
    }

    /// `p'''(u)`.
    #[inline]
    pub fn d3(&self, u: f64) -> Vec3 {
        quintic::d3(&self.coef, u)
    }

    /// `|p'(u)|`, mm per unit of `u`.
    #[inline]
    pub fn speed(&self, u: f64) -> f64 {
        self.d1(u).norm()
    }

    /// Arc length from `a` to `b` (5-point Gauss-Legendre).
    #[inline]
    fn arc(&self, a: f64, b: f64) -> f64 {
        let h = 0.5 * (b - a);
        let m = 0.5 * (a + b);
        let mut sum = 0.0;
        for i in 0..5 {
            sum += GL_W[i] * self.speed(m + h * GL_X[i]);
        }
        sum * h
    }

    /// The parameter `u` at arc length `s` (clamped to `[0, 1]`).
    #[inline]
    pub fn param_at(&self, s: f64) -> f64 {
        if s <= 0.0 {
            return 0.0;
        }
        if s >= self.length_mm {
            return 1.0;
        }
        let n = (TABLE_POINTS - 1) as f64;
        let h = self.length_mm / n;
        let x = s / h;
        let k = (x.floor() as usize).min(TABLE_POINTS - 2);
        let t = x - k as f64;
        let (u0, u1) = (self.table[k], self.table[k + 1]);
        let (m0, m1) = (h / self.speed(u0), h / self.speed(u1));
        // Cubic Hermite in the interval.
        let t2 = t * t;
        let t3 = t2 * t;
        let u = (2.0 * t3 - 3.0 * t2 + 1.0) * u0
            + (t3 - 2.0 * t2 + t) * m0
            + (-2.0 * t3 + 3.0 * t2) * u1
            + (t3 - t2) * m1;
        // One Newton step on the arc length from the node, with the quadrature that
        // `with_arc_length` checked over every interval (the 3-point rule left 6e-13 of an
        // interval at the nodes of ordinary curves: a jump of the position).
        let sk = h * k as f64;
        let err = sk + self.arc(u0, u) - s;
        (u - err / self.speed(u)).clamp(0.0, 1.0)
    }

    /// Point at arc length `s` (exact end points outside the curve).
    #[inline]
    pub fn point_at(&self, s: f64) -> Vec3 {
        if s <= 0.0 {
            self.start
        } else if s >= self.length_mm {
            self.end
        } else {
            self.poly(self.param_at(s))
        }
    }

    /// Unit tangent and curvature vector at parameter `u`.
    pub fn frame_at_param(&self, u: f64) -> (Vec3, Vec3) {
        let q = self.d1(u);
        let r = self.d2(u);
        let sq = q.norm_squared();
        let t = q / sq.sqrt();
        let k = (r - t * r.dot(&t)) / sq;
        (t, k)
    }

    /// Unit tangent, curvature vector `K = dT/ds` and its arc-length derivative `dK/ds`
    /// at parameter `u`, in closed form from the polynomial's first three derivatives
    /// (the axes' third derivatives along the path: at constant speed `v` each axis's
    /// jerk is `K'_i v³`).
    ///
    /// With `q = p'`, `r = p''`, `w = p'''`, `g = q·q` and `m = q·r`:
    /// `K = N/g` with `N = r − q m/g`, so `dK/du = N'/g − N g'/g²` with `g' = 2m`,
    /// `N' = w − r m/g − q (m'/g − m g'/g²)`, `m' = r·r + q·w`; and `dK/ds = (dK/du)/√g`.
    pub fn frame_rate_at_param(&self, u: f64) -> (Vec3, Vec3, Vec3) {
        let q = self.d1(u);
        let r = self.d2(u);
        let w = self.d3(u);
        let g = q.norm_squared();
        let sigma = g.sqrt();
        let m = q.dot(&r);
        let dg = 2.0 * m;
        let dm = r.norm_squared() + q.dot(&w);
        let n = r - q * (m / g);
        let dn = w - r * (m / g) - q * (dm / g - m * dg / (g * g));
        let k = n / g;
        let dk_du = dn / g - n * (dg / (g * g));
        (q / sigma, k, dk_du / sigma)
    }

    /// Unit tangent and curvature vector at arc length `s` (exact at the ends).
    pub fn frame_at(&self, s: f64) -> (Vec3, Vec3) {
        if s <= 0.0 {
            (self.t0, self.k0)
        } else if s >= self.length_mm {
            (self.t1, self.k1)
        } else {
            self.frame_at_param(self.param_at(s))
        }
    }

    /// Shortest distance from `p` (dense sampling refined by golden-section search; for
    /// checks, not for the real-time path).
    pub fn distance_to(&self, p: &Vec3) -> f64 {
        const N: usize = 128;
        let f = |u: f64| (self.poly(u) - p).norm();
        let mut best = (f64::INFINITY, 0usize);
        for i in 0..=N {
            let d = f(i as f64 / N as f64);
            if d < best.0 {
                best = (d, i);
            }
        }
        let mut lo = (best.1.saturating_sub(1)) as f64 / N as f64;
        let mut hi = ((best.1 + 1).min(N)) as f64 / N as f64;
        let g = 0.618_033_988_749_895;
        for _ in 0..40 {
            let a = hi - g * (hi - lo);
            let b = lo + g * (hi - lo);
            if f(a) < f(b) {
                hi = b;
            } else {
                lo = a;
            }
        }
        best.0
            .min(f(0.5 * (lo + hi)))
            .min((self.start - p).norm())
            .min((self.end - p).norm())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_match_and_arc_length_is_consistent() {
        // Line along +X into a CCW circle of radius 5 tangent at the origin.
        let p0 = Vec3::new(-0.5, 0.0, 0.0);
        let t0 = Vec3::x();
        let k0 = Vec3::zeros();
        let th: f64 = 0.1;
        let c = Vec3::new(0.0, 5.0, 0.0);
        let p1 = c + Vec3::new(5.0 * th.sin(), -5.0 * th.cos(), 0.0);
        let t1 = Vec3::new(th.cos(), th.sin(), 0.0);
        let k1 = (c - p1) / 25.0;
        let tr = Transition::new(p0, t0, k0, p1, t1, k1, (p1 - p0).norm()).unwrap();
        let (t, k) = tr.frame_at_param(0.0);
        assert!((t - t0).norm() < 1e-12 && (k - k0).norm() < 1e-9);
        let (t, k) = tr.frame_at_param(1.0);
        assert!((t - t1).norm() < 1e-12 && (k - k1).norm() < 1e-9);
        // Arc length: finite differences of point_at have unit speed.
        let l = tr.length_mm;
        let h = 1e-6;
        for i in 1..50 {
            let s = l * i as f64 / 50.0;
            let v = (tr.point_at(s + h) - tr.point_at(s - h)).norm() / (2.0 * h);
            assert!((v - 1.0).abs() < 1e-7, "{v}");
        }
        assert_eq!(tr.point_at(l), p1);
        assert_eq!(tr.point_at(0.0), p0);
        assert!((tr.point_at(l * (1.0 - 1e-12)) - p1).norm() < 1e-9);
        assert!(tr.distance_to(&p0) < 1e-12);
    }

    /// The closed-form `dK/ds` is the third derivative of the point along the arc length,
    /// measured here by differences of `point_at` (the arc-length table, not the formula).
    #[test]
    fn curvature_rate_is_the_third_derivative_along_the_path() {
        // A twisted piece: tangents and curvatures out of one plane.
        let p0 = Vec3::new(0.0, 0.0, 0.0);
        let t0 = Vec3::new(1.0, 0.2, -0.3).normalize();
        let k0 = {
            let k = Vec3::new(0.0, 0.4, 0.3);
            k - t0 * k.dot(&t0)
        };
        let p1 = Vec3::new(1.8, 0.5, 0.2);
        let t1 = Vec3::new(0.8, 0.1, 0.6).normalize();
        let k1 = {
            let k = Vec3::new(-0.2, -0.5, 0.4);
            k - t1 * k.dot(&t1)
        };
        let tr = Transition::new(p0, t0, k0, p1, t1, k1, (p1 - p0).norm()).unwrap();
        let l = tr.length_mm;
        let h = 0.01;
        let mut largest: f64 = 0.0;
        let mut worst: f64 = 0.0;
        for i in 1..40 {
            let s = 2.0 * h + (l - 4.0 * h) * i as f64 / 40.0;
            let x = |k: f64| tr.point_at(s + k * h);
            let third = (x(2.0) - x(1.0) * 2.0 + x(-1.0) * 2.0 - x(-2.0)) / (2.0 * h * h * h);
            let second = (x(1.0) - x(0.0) * 2.0 + x(-1.0)) / (h * h);
            let (t, k, dk) = tr.frame_rate_at_param(tr.param_at(s));
            assert!((t - (x(1.0) - x(-1.0)) / (2.0 * h)).norm() < 1e-4);
            assert!(
                (k - second).norm() < 1e-3 * k.norm().max(1.0),
                "{k} {second}"
            );
            largest = largest.max(dk.norm());
            worst = worst.max((dk - third).norm());
        }
        assert!(
            largest > 0.5,
            "the test piece is not curved enough: {largest}"
        );
        assert!(worst < 2e-3 * largest, "{worst} of {largest}");
    }

    /// splitmix64 in [0, 1): a fixed-seed stream of draws.
    fn draws(mut state: u64) -> impl FnMut() -> f64 {
        move || {
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// Every curve `with_arc_length` accepts is evaluated at arc length without a
    /// jump at the table's nodes and where a brute-force inversion of the arc length puts
    /// it; curves it cannot serve so (near-cusp quintics, hairpins) are refused. Random
    /// quintics from gentle to near a cusp: most with tangents near the chord and a
    /// parameter scale of 0.9 to 2.9 times it (the planner's curves), a quarter turning
    /// anywhere with curvatures up to 20 / chord and scales of 0.15 to 4 chords); the reference
    /// integrates `|p'(u)|` with 20,000 Simpson steps and inverts by interpolation,
    /// independent of the table. Before the fix, 0.14 µm jumps at nodes (a jerk of 43
    /// times a 3,292 mm/s³ limit at 1 ms) passed.
    #[test]
    fn accepted_curves_are_evaluated_without_jumps() {
        let mut next = draws(0x24_24_24);
        let unit = |next: &mut dyn FnMut() -> f64| {
            let z: f64 = 2.0 * next() - 1.0;
            let phi = std::f64::consts::TAU * next();
            let r = (1.0 - z * z).sqrt();
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        };
        let (mut accepted, mut refused) = (0, 0);
        for case in 0..400 {
            let chord = 10f64.powf(-2.0 + 3.0 * next());
            let p0 = Vec3::new(100.0 * next(), -50.0 * next(), 3.0 * next());
            let d = unit(&mut next);
            let p1 = p0 + d * chord;
            // Mostly along the chord (as the planner's curves are), a quarter of them
            // turning anywhere (hairpins, near-cusps).
            let wild = next() < 0.25;
            let spread = if wild { 3.0 } else { 0.8 * next() };
            let t0 = (d + unit(&mut next) * spread).normalize();
            let t1 = (d + unit(&mut next) * spread).normalize();
            let bend = |t: Vec3, next: &mut dyn FnMut() -> f64| {
                let n = Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5);
                let n = n - t * n.dot(&t);
                n * (if wild { 20.0 } else { 2.0 } * next() * next() / chord / n.norm().max(1e-12))
            };
            let k0 = bend(t0, &mut next);
            let k1 = bend(t1, &mut next);
            let lambda = if wild {
                chord * 10f64.powf(-0.82 + 1.42 * next())
            } else {
                chord * (0.9 + 2.0 * next())
            };
            let Some(tr) = Transition::new(p0, t0, k0, p1, t1, k1, lambda) else {
                refused += 1;
                continue;
            };
            accepted += 1;
            // The reference: cumulative arc length by Simpson's rule on a fine grid.
            const N: usize = 20_000;
            let mut cum = vec![0.0; N + 1];
            for i in 0..N {
                let (a, b) = (i as f64 / N as f64, (i + 1) as f64 / N as f64);
                cum[i + 1] = cum[i]
                    + (b - a) / 6.0 * (tr.speed(a) + 4.0 * tr.speed(0.5 * (a + b)) + tr.speed(b));
            }
            let length = cum[N];
            assert!(
                (length - tr.length_mm).abs() <= 1e-10 * length,
                "case {case}: length {} against {length}",
                tr.length_mm
            );
            let reference = |s: f64| {
                let i = cum.partition_point(|&c| c < s).clamp(1, N);
                let (c0, c1) = (cum[i - 1], cum[i]);
                let mut u = (i - 1) as f64 / N as f64 + (s - c0) / (c1 - c0) / N as f64;
                // Two Newton steps on the Simpson integral from the grid point.
                for _ in 0..2 {
                    let a = (i - 1) as f64 / N as f64;
                    let arc =
                        (u - a) / 6.0 * (tr.speed(a) + 4.0 * tr.speed(0.5 * (a + u)) + tr.speed(u));
                    u -= (c0 + arc - s) / tr.speed(u);
                }
                tr.poly(u)
            };
            let n = TABLE_POINTS - 1;
            let h = tr.length_mm / n as f64;
            for k in 1..n {
                // Across each node: the two sides are as far apart as the arc between them.
                let (eps, s) = (1e-7 * h, h * k as f64);
                let gap = (tr.point_at(s + eps) - tr.point_at(s - eps)).norm();
                assert!(
                    (gap - 2.0 * eps).abs() <= 1e-11 * h + 1e-13,
                    "case {case}: a jump of {:e} mm at node {k}",
                    gap - 2.0 * eps
                );
            }
            for i in 0..=97 {
                let s = tr.length_mm * i as f64 / 97.0;
                let off = (tr.point_at(s) - reference(s)).norm();
                assert!(
                    off <= 1e-9 * tr.length_mm + 1e-12,
                    "case {case}: at s = {s} the point is {off:e} mm off the arc length"
                );
            }
        }
        assert!(
            accepted >= 100 && refused >= 10,
            "{accepted} accepted, {refused} refused"
        );
    }
}
