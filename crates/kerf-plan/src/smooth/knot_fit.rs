//! The frame at a knot: tangent and curvature (and the rotary axes' derivatives) from a
//! weighted least-squares polynomial over a window of vertices around it, and the knot's
//! position where the vertices are coarsely rounded.

use kerf_geom::Vec3;

use super::{
    Knot, POSITION_MAX_TURN_RAD, POSITION_NOISE_SHARE, POSITION_TOL_SHARE, POSITION_WINDOW_MM,
    QUARTIC_MIN_VERTICES, RESIDUAL_TOL_SHARE, Run, WINDOW_MM,
};

impl Run {
    /// from the widest window whose fit explains its vertices, and its position, the
    /// vertex moved by [`Run::position_offset`] where the curve turns by at most
    /// [`POSITION_MAX_TURN_RAD`] over [`POSITION_WINDOW_MM`] (else, and where no fit
    /// succeeds, the vertex itself).
    pub(super) fn fit_knot(&self, idx: u64) -> Knot {
        let first = self.base;
        let last = self.last_idx();
        let s0 = self.v(idx).sigma;
        // The window must reach at least two vertices on each side that has them.
        let lo2 = idx.saturating_sub(2).max(first);
        let hi2 = (idx + 2).min(last);
        let w_min = (s0 - self.v(lo2).sigma).max(self.v(hi2).sigma - s0);
        let mut w = WINDOW_MM.max(w_min);
        let mut fit = None;
        loop {
            let f = self.local_fit(idx, w);
            let good = f.map(|f| f.residual <= RESIDUAL_TOL_SHARE * self.tol);
            if f.is_some() {
                fit = f;
            }
            if good == Some(true) || w <= w_min {
                break;
            }
            w = (0.5 * w).max(w_min);
        }
        let p = self.v(idx).p;
        let a = self.v(idx).abc;
        match fit {
            Some(f) => {
                let sq = f.d1.norm_squared();
                let speed = sq.sqrt();
                let t = f.d1 / speed;
                let k = (f.d2 - t * f.d2.dot(&t)) / sq;
                // The rotary axes against the XYZ arc length s, from their fit against the
                // chord parameter x: dA/ds = A'/|p'|, d²A/ds² = (A'' - A' (p'·p'')/|p'|²)/|p'|².
                let along = f.d1.dot(&f.d2) / sq;
                let da = std::array::from_fn(|i| f.a1[i] / speed);
                let dda = std::array::from_fn(|i| (f.a2[i] - f.a1[i] * along) / sq);
                // Where the curve turns by more than POSITION_MAX_TURN_RAD over
                // POSITION_WINDOW_MM, half the window (the start of a spiral), no low-order
                // fit follows it: the knot stays on its vertex.
                let p = if k.norm() * POSITION_WINDOW_MM <= POSITION_MAX_TURN_RAD {
                    p + self.position_offset(idx)
                } else {
                    p
                };
                Knot {
                    idx,
                    p,
                    t,
                    k,
                    a,
                    da,
                    dda,
                }
            }
            None => {
                // Degenerate data: the direction of an adjacent segment, no curvature.
                let (va, vb) = if idx < last {
                    (self.v(idx), self.v(idx + 1))
                } else {
                    (self.v(idx - 1), self.v(idx))
                };
                let len = (vb.p - va.p).norm();
                Knot {
                    idx,
                    p,
                    t: (vb.p - va.p) / len,
                    k: Vec3::zeros(),
                    a,
                    da: std::array::from_fn(|i| (vb.abc[i] - va.abc[i]) / len),
                    dda: [0.0; 3],
                }
            }
        }
    }

    /// Where a knot inside the run lies relative to its vertex: the value at the vertex
    /// of a weighted least-squares quadratic over the vertices within
    /// [`POSITION_WINDOW_MM`] (its free constant), so that a coarsely rounded vertex does
    /// not pull the curve by its rounding. Zero (the knot on its vertex) where a quartic
    /// over the same vertices leaves every one within [`POSITION_NOISE_SHARE`] of the
    /// tolerance (the vertices are precise, and the quadratic's own bias would only move
    /// the knot off the curve), where a fit fails, and at a run end (a one-sided window
    /// holds the fit through the vertex). At most [`POSITION_TOL_SHARE`] of the tolerance.
    fn position_offset(&self, idx: u64) -> Vec3 {
        let (w, lo, hi) = self.window(idx, POSITION_WINDOW_MM);
        // Rounding shows as the residual of a quartic over the same vertices, which
        // follows a curve's fourth derivative where a quadratic would leave it.
        let noisy = self
            .local_fit_n::<5>(idx, w, lo, hi)
            .is_some_and(|f| f.residual >= POSITION_NOISE_SHARE * self.tol);
        if !noisy {
            return Vec3::zeros();
        }
        let Some(d0) = self.local_fit_n::<3>(idx, w, lo, hi).map(|f| f.d0) else {
            return Vec3::zeros();
        };
        // At most half the band (rounding to half the band is the most a fit should take
        // out), so that a line kept from this knot stays within the band too.
        let limit = POSITION_TOL_SHARE * self.tol;
        let off = d0.norm();
        if off.is_finite() && off <= limit {
            d0
        } else if off.is_finite() {
            d0 * (limit / off)
        } else {
            Vec3::zeros()
        }
    }

    /// Weighted least-squares `p(x) = p_idx + d0 + d1 x + d2 x²/2 + d3 x³/6 + d4 x⁴/24`
    /// (x = chord length from the vertex) over the vertices within `w` (biweight); a cubic
    /// where the window has fewer than [`QUARTIC_MIN_VERTICES`] vertices besides the
    /// knot's own. Except at a run end, the fit is not held through the vertex (`d0` is
    /// free): a rounded vertex would tilt the tangent and bend the curvature by its own
    /// rounding. The knot stays on its vertex, or where the vertices are coarsely
    /// rounded takes its position from a narrower fit ([`Run::position_offset`]) whose
    /// fourth-derivative bias is smaller; a piece's check against the polyline keeps it in
    /// the band. The cubic term keeps the curvature of a circle from leaking into the
    /// residual, so windows stay wide on arcs; the quartic term keeps a curve's fourth
    /// derivative out of the curvature (in a symmetric window a cubic's x² coefficient
    /// absorbs the x⁴ term), so a small circle's pieces follow it several times more
    /// closely than with a cubic.
    fn local_fit(&self, idx: u64, w: f64) -> Option<LocalFit> {
        let (w, lo, hi) = self.window(idx, w);
        if (hi - lo) as usize >= QUARTIC_MIN_VERTICES {
            self.local_fit_n::<5>(idx, w, lo, hi)
        } else {
            self.local_fit_n::<4>(idx, w, lo, hi)
        }
    }

    /// [`Run::local_fit`] with `N` polynomial terms (the constant included) over the
    /// vertices `lo..=hi`, `w` their half-width.
    fn local_fit_n<const N: usize>(&self, idx: u64, w: f64, lo: u64, hi: u64) -> Option<LocalFit> {
        let s0 = self.v(idx).sigma;
        let p0 = self.v(idx).p;
        let a0 = Vec3::from(self.v(idx).abc);
        // Normal equations in scaled x (x/w) for conditioning; XYZ and A, B, C share them.
        let mut m = [[0.0f64; N]; N];
        let mut r = [Vec3::zeros(); N];
        let mut ra = [Vec3::zeros(); N];
        let mut count = 0;
        // A one-sided window (a run end) weighs its vertices equally: tapering it would
        // leave the curvature to the few vertices next to the end.
        let one_sided = lo == idx || hi == idx;
        for k in lo..=hi {
            let v = self.v(k);
            let x = (v.sigma - s0) / w;
            let om = if one_sided {
                1.0
            } else {
                (1.0 - x * x).powi(2)
            };
            let y = v.p - p0;
            let ya = Vec3::from(v.abc) - a0;
            let basis = taylor_basis::<N>(x);
            for i in 0..N {
                for j in 0..N {
                    m[i][j] += om * basis[i] * basis[j];
                }
                r[i] += y * (om * basis[i]);
                if self.rotary {
                    ra[i] += ya * (om * basis[i]);
                }
            }
            count += 1;
        }
        if count < N {
            return None;
        }
        if one_sided {
            // At a run end the fit is held through the vertex (the constant is zero): the
            // end is exact anyway, and a free constant extrapolated to the window's end
            // cost a tenth of the curvature there.
            m[0] = [0.0; N];
            for row in m.iter_mut() {
                row[0] = 0.0;
            }
            m[0][0] = 1.0;
            r[0] = Vec3::zeros();
            ra[0] = Vec3::zeros();
        }
        // Back to mm: the k-th coefficient is the k-th derivative times w^k.
        let unscale = |c: [Vec3; N]| -> [Vec3; N] {
            let mut f = 1.0;
            std::array::from_fn(|k| {
                let out = c[k] / f;
                f *= w;
                out
            })
        };
        let d = unscale(solve_normal(&m, &r)?);
        let (d1, d2) = (d[1], d[2]);
        if !d1.iter().chain(d2.iter()).all(|c| c.is_finite()) || d1.norm() <= 1e-9 {
            return None;
        }
        let da = if self.rotary {
            unscale(solve_normal(&m, &ra)?)
        } else {
            [Vec3::zeros(); N]
        };
        if !da[1].iter().chain(da[2].iter()).all(|c| c.is_finite()) || !d[0].norm().is_finite() {
            return None;
        }
        // The largest residual, in mm for XYZ and in degrees for the rotary axes (both
        // against the same tolerance number).
        let mut residual: f64 = 0.0;
        let poly = |c: &[Vec3; N], x: f64| -> Vec3 {
            let b = taylor_basis::<N>(x);
            (0..N).fold(Vec3::zeros(), |acc, k| acc + c[k] * b[k])
        };
        for k in lo..=hi {
            let v = self.v(k);
            let x = v.sigma - s0;
            residual = residual.max((p0 + poly(&d, x) - v.p).norm());
            if self.rotary {
                let fit = a0 + poly(&da, x);
                for i in 0..3 {
                    residual = residual.max((fit[i] - v.abc[i]).abs());
                }
            }
        }
        Some(LocalFit {
            d0: d[0],
            d1,
            d2,
            a1: da[1].into(),
            a2: da[2].into(),
            residual,
        })
    }

    /// The window of half-width `w` around vertex `idx`, widened by a rounding margin so
    /// that a vertex exactly `w` away is inside: that half-width and its first and last
    /// vertices.
    fn window(&self, idx: u64, w: f64) -> (f64, u64, u64) {
        let w = w * 1.000_001;
        (
            w,
            self.window_end(idx, w, false),
            self.window_end(idx, w, true),
        )
    }

    /// The last vertex within chord distance `w` of `idx` on one side.
    fn window_end(&self, idx: u64, w: f64, forward: bool) -> u64 {
        let s0 = self.v(idx).sigma;
        let mut k = idx;
        if forward {
            while k < self.last_idx() && self.v(k + 1).sigma - s0 < w {
                k += 1;
            }
        } else {
            while k > self.base && s0 - self.v(k - 1).sigma < w {
                k -= 1;
            }
        }
        k
    }
}

/// The first two derivatives of a local fit at its vertex, and its largest residual.
#[derive(Clone, Copy, Debug)]
struct LocalFit {
    /// The fit's offset from the vertex at the vertex (zero at a run end).
    d0: Vec3,
    d1: Vec3,
    d2: Vec3,
    /// First and second derivatives of A, B, C against the chord parameter.
    a1: [f64; 3],
    a2: [f64; 3],
    residual: f64,
}

/// `[1, x, x²/2, x³/6, …]`: the Taylor basis with `N` terms.
fn taylor_basis<const N: usize>(x: f64) -> [f64; N] {
    let mut term = 1.0;
    std::array::from_fn(|k| {
        if k > 0 {
            term *= x / k as f64;
        }
        term
    })
}

/// Solves the symmetric positive semi-definite system `m c = r` (one right-hand side per
/// coordinate) by Gaussian elimination with partial pivoting; `None` if it is singular
/// (a pivot under 1e-12 of the diagonal's scale).
fn solve_normal<const N: usize>(m: &[[f64; N]; N], r: &[Vec3; N]) -> Option<[Vec3; N]> {
    let mut a = *m;
    let mut b = *r;
    let scale = (0..N).map(|i| m[i][i].abs()).fold(0.0, f64::max);
    if !scale.is_finite() || scale <= 0.0 {
        return None;
    }
    for col in 0..N {
        let pivot = (col..N).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() <= 1e-12 * scale {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        let (pivot_row, pivot_b) = (a[col], b[col]);
        for row in col + 1..N {
            let f = a[row][col] / pivot_row[col];
            for (x, p) in a[row].iter_mut().zip(&pivot_row).skip(col) {
                *x -= f * p;
            }
            b[row] -= pivot_b * f;
        }
    }
    let mut out = [Vec3::zeros(); N];
    for col in (0..N).rev() {
        let mut acc = b[col];
        for k in col + 1..N {
            acc -= out[k] * a[col][k];
        }
        out[col] = acc / a[col][col];
    }
    Some(out)
}
