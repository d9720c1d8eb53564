//! Quintic polynomials in power basis over `u ∈ [0, 1]`: the Hermite coefficients from
//! values and first and second derivatives at both ends, the value, and the first three
//! derivatives. One place for the arithmetic that [`Transition`](crate::Transition) (XYZ,
//! as [`Vec3`](crate::Vec3)), the rotary quintics of a smoothed piece
//! ([`PlannedSegment::abc_poly`](crate::PlannedSegment::abc_poly), as `f64`) and the
//! planner's smoother use.
//!
//! Each function is generic over the coefficient type and does the same floating-point
//! operations in the same order for a scalar as for each component of a vector, so a
//! `Vec3` curve and three scalar ones agree bit for bit.
//!
//! The derivatives come in two spellings that round differently, and each caller keeps
//! its own: [`d1`], [`d2`] and [`d3`] scale the parameter (`c₅·(5u)`), as the XYZ curve
//! of a [`Transition`](crate::Transition) always has; [`d1_d2_scaled_coef`] scales the
//! coefficient (`(5c₅)·u`), as the rotary quintics always have.

use std::ops::{Add, Mul, Neg, Sub};

/// A coefficient of a quintic: `f64` or a vector of them, with the component-wise
/// arithmetic the formulas below need.
pub trait Coef:
    Copy + Add<Output = Self> + Sub<Output = Self> + Neg<Output = Self> + Mul<f64, Output = Self>
{
}

impl<T> Coef for T where
    T: Copy + Add<Output = T> + Sub<Output = T> + Neg<Output = T> + Mul<f64, Output = T>
{
}

/// Quintic Hermite coefficients `[c₀, …, c₅]` (power basis in `u ∈ [0, 1]`) from the value
/// `p0`, first derivative `v0` and second derivative `a0` at `u = 0` and `p1`, `v1`, `a1`
/// at `u = 1` (derivatives with respect to `u`).
#[inline]
pub fn hermite<T: Coef>(p0: T, v0: T, a0: T, p1: T, v1: T, a1: T) -> [T; 6] {
    let d = p1 - p0;
    let c0 = p0;
    let c1 = v0;
    let c2 = a0 * 0.5;
    let c3 = d * 10.0 - v0 * 6.0 - v1 * 4.0 - a0 * 1.5 + a1 * 0.5;
    let c4 = -d * 15.0 + v0 * 8.0 + v1 * 7.0 + a0 * 1.5 - a1;
    let c5 = d * 6.0 - v0 * 3.0 - v1 * 3.0 - a0 * 0.5 + a1 * 0.5;
    [c0, c1, c2, c3, c4, c5]
}

/// `Σ c[k] uᵏ` (Horner).
#[inline]
pub fn value<T: Coef>(c: &[T; 6], u: f64) -> T {
    ((((c[5] * u + c[4]) * u + c[3]) * u + c[2]) * u + c[1]) * u + c[0]
}

/// First derivative, the parameter scaled: `c₅·(5u)`, then Horner.
#[inline]
pub fn d1<T: Coef>(c: &[T; 6], u: f64) -> T {
    (((c[5] * (5.0 * u) + c[4] * 4.0) * u + c[3] * 3.0) * u + c[2] * 2.0) * u + c[1]
}

/// Second derivative, the parameter scaled: `c₅·(20u)`, then Horner.
#[inline]
pub fn d2<T: Coef>(c: &[T; 6], u: f64) -> T {
    ((c[5] * (20.0 * u) + c[4] * 12.0) * u + c[3] * 6.0) * u + c[2] * 2.0
}

/// Third derivative, the parameter scaled: `c₅·(60u)`, then Horner.
#[inline]
pub fn d3<T: Coef>(c: &[T; 6], u: f64) -> T {
    (c[5] * (60.0 * u) + c[4] * 24.0) * u + c[3] * 6.0
}

/// First and second derivatives with the coefficient scaled: `(5c₅)·u` and `(20c₅)·u`,
/// then Horner. Rounds differently from [`d1`] and [`d2`].
#[inline]
pub fn d1_d2_scaled_coef<T: Coef>(c: &[T; 6], u: f64) -> (T, T) {
    let d1 = (((c[5] * 5.0 * u + c[4] * 4.0) * u + c[3] * 3.0) * u + c[2] * 2.0) * u + c[1];
    let d2 = ((c[5] * 20.0 * u + c[4] * 12.0) * u + c[3] * 6.0) * u + c[2] * 2.0;
    (d1, d2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Vec3;

    /// A vector quintic and its three component quintics agree bit for bit.
    #[test]
    fn vector_and_scalar_quintics_agree_bit_for_bit() {
        let p0 = Vec3::new(0.3, -1.7, 2.2);
        let v0 = Vec3::new(1.1, 0.4, -0.9);
        let a0 = Vec3::new(-0.2, 3.3, 0.7);
        let p1 = Vec3::new(1.9, 0.6, -0.4);
        let v1 = Vec3::new(0.8, -1.2, 0.5);
        let a1 = Vec3::new(2.4, -0.6, 1.3);
        let c = hermite(p0, v0, a0, p1, v1, a1);
        for i in 0..3 {
            let s = hermite(p0[i], v0[i], a0[i], p1[i], v1[i], a1[i]);
            for k in 0..6 {
                assert_eq!(c[k][i].to_bits(), s[k].to_bits());
            }
            for u in [0.0, 0.137, 0.5, 0.91, 1.0] {
                assert_eq!(value(&c, u)[i].to_bits(), value(&s, u).to_bits());
                assert_eq!(d1(&c, u)[i].to_bits(), d1(&s, u).to_bits());
                assert_eq!(d2(&c, u)[i].to_bits(), d2(&s, u).to_bits());
                assert_eq!(d3(&c, u)[i].to_bits(), d3(&s, u).to_bits());
            }
        }
        // The ends: value and derivatives as given.
        assert!((value(&c, 1.0) - p1).norm() < 1e-12);
        assert!((d1(&c, 1.0) - v1).norm() < 1e-12);
        assert!((d2(&c, 1.0) - a1).norm() < 1e-12);
        let (e1, e2) = d1_d2_scaled_coef(&c, 1.0);
        assert!((e1 - v1).norm() < 1e-12 && (e2 - a1).norm() < 1e-12);
    }
}
