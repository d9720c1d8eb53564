//! A jerk-limited lower bound of the time to traverse a path: the bound of the CAM
//! benchmark table that carries the same three limits as the machine (docs/PERFORMANCE.md,
//! "CAM code against the feed and the time-optimal bound").
//!
//! [`crate::bound`] ignores jerk: a true lower bound, but a loose one where jerk is what
//! holds the speed (every start and stop, a surface whose Z acceleration swings fast).
//! This module keeps velocity, acceleration *and* jerk per axis.
//!
//! **The path.** A jerk-limited motion cannot pass a point where the path's curvature
//! jumps at any speed above zero (the centripetal acceleration would jump), so a corner
//! cannot take the circular blend of [`crate::bound::blended`]. Every join where the
//! direction or the curvature changes is replaced by a quintic that matches position,
//! direction and curvature vector at both ends ([`g2_blended`]); its middle is at most
//! `tolerance_mm` from the join, and it uses at most half of each neighbour. Reversals
//! stay corners, passed at rest.
//!
//! **The bound.** With the arc length `s`, `b = ṡ²` at every sample and a constant
//! `s̈ = a_k` between samples `k` and `k + 1` (`b_{k+1} = b_k + 2 h_k a_k`), axis `i`
//! accelerates at `acc_ik = t_i a_k + κ_i (b_k + b_{k+1})/2` over interval `k` (unit
//! tangent `t` and curvature vector `κ` at the interval's middle), within its limit, and
//! its speed is within its limit. Each interval has a time `τ_k` of its own, at least
//! `2 h_k / (√b_k + √b_{k+1})` (what the speeds give), and the jerk constraint is
//! `|acc_ik − acc_i,k−1| ≤ J_i (τ_{k−1} + τ_k) / 2`: the change of acceleration between
//! neighbouring intervals over the time between their middles (from and to rest, from
//! and to zero acceleration). Minimising `Σ τ_k` is then a second-order cone program
//! (`c_k ≤ √b_k` and `τ_k (c_k + c_{k+1}) ≥ 2 h_k` are cones, everything else linear),
//! solved with Clarabel. A traversal that keeps the limits, with its true interval times,
//! is one of the program's points, so the optimum is at or below the jerk-limited
//! optimum on that path, up to the discretisation (the times may only be longer than
//! the speeds give, which only loosens the jerk constraint). Near rest the intervals are
//! split finer (`graded`): a motion from rest covers `j t³ / 6` in time `t`.
//!
//! On straight lines it comes within 0.02 % of the S-curve time from rest to rest (the
//! tests work those out by hand), where the acceleration-only bound is 14 % to 21 % under.
// The rows index several per-sample and per-interval arrays at k, k − 1 and k + 1.
#![allow(clippy::many_single_char_names, clippy::needless_range_loop)]

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use kerf_geom::Vec3;

use crate::bound::{self, BoundMachine, Piece, Sample, Shape};

/// The machine of the jerk-limited bound: the acceleration bound's machine and a jerk limit
/// per axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JerkMachine {
    /// Velocity and acceleration limits and the blend tolerance.
    pub base: BoundMachine,
    /// Jerk limit per axis, mm/s³.
    pub jerk_mm_s3: [f64; 3],
}

/// The jerk-limited lower bound along a path.
#[derive(Clone, Debug)]
pub struct JerkBound {
    /// Arc length of each sample, mm.
    pub s_mm: Vec<f64>,
    /// Path speed at each sample of the optimum, mm/s.
    pub speed_mm_s: Vec<f64>,
    /// Time from rest to rest, s: the program's optimum `Σ τ_k`.
    pub time_s: f64,
}

/// Why the bound could not be computed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum JerkError {
    /// The cone program was refused or not solved.
    #[error("the cone solver {0}")]
    Solver(String),
}

/// Turn angles below this (rad), with curvature vectors within [`SAME_CURVATURE`], are
/// smooth joins: no blend.
const TANGENT_RAD: f64 = 1e-9;
/// Curvature vectors closer than this (1/mm) count as equal at a join.
const SAME_CURVATURE: f64 = 1e-9;

/// Direction and curvature vector of a shape at `u`.
fn frame(shape: &Shape, u: f64) -> (Vec3, Vec3, Vec3) {
    let e = shape.eval(u);
    let (t, k, _) = bound::unit_frame(e.d1, e.d2);
    (e.p, t, k)
}

/// The quintic from `p0` (direction `t0`, curvature vector `k0`) to `p1` (`t1`, `k1`),
/// with the parameter's speed at both ends the chord length: position, direction and
/// curvature match at both ends.
fn quintic(p0: Vec3, t0: Vec3, k0: Vec3, p1: Vec3, t1: Vec3, k1: Vec3) -> Shape {
    let l = (p1 - p0).norm();
    let (v0, v1) = (t0 * l, t1 * l);
    let (w0, w1) = (k0 * (l * l), k1 * (l * l));
    Shape::Quintic {
        coeffs: [
            p0,
            v0,
            w0 * 0.5,
            (p1 - p0) * 10.0 - v0 * 6.0 - v1 * 4.0 - w0 * 1.5 + w1 * 0.5,
            (p0 - p1) * 15.0 + v0 * 8.0 + v1 * 7.0 + w0 * 1.5 - w1,
            (p1 - p0) * 6.0 - v0 * 3.0 - v1 * 3.0 - w0 * 0.5 + w1 * 0.5,
        ],
    }
}

/// The path with every join where the direction or the curvature changes replaced by a
/// curvature-continuous quintic (`quintic`) between the points `d` mm before and after
/// it, `d` the largest (by bisection) that keeps the quintic's middle within
/// `tolerance_mm` of the join and uses at most half of either neighbour. Reversals are
/// left as corners.
pub fn g2_blended(pieces: &[Piece], tolerance_mm: f64) -> Vec<Piece> {
    let n = pieces.len();
    let lengths: Vec<f64> = pieces.iter().map(|p| p.shape.length_mm()).collect();
    let mut cut = vec![0.0; n];
    let mut blends: Vec<Option<Piece>> = vec![None; n];
    for k in 0..n.saturating_sub(1) {
        let (vertex, t_in, k_in) = frame(&pieces[k].shape, 1.0);
        let (_, t_out, k_out) = frame(&pieces[k + 1].shape, 0.0);
        let turn = t_in.dot(&t_out).clamp(-1.0, 1.0).acos();
        if turn > std::f64::consts::PI - 1e-6
            || (turn < TANGENT_RAD && (k_in - k_out).norm() < SAME_CURVATURE)
        {
            continue;
        }
        let blend_at = |d: f64| {
            let before = pieces[k].shape.trimmed(0.0, d);
            let after = pieces[k + 1].shape.trimmed(d, 0.0);
            let (p0, t0, k0) = frame(&before, 1.0);
            let (p1, t1, k1) = frame(&after, 0.0);
            quintic(p0, t0, k0, p1, t1, k1)
        };
        let deviation = |d: f64| (blend_at(d).eval(0.5).p - vertex).norm();
        let d_max = (lengths[k] / 2.0).min(lengths[k + 1] / 2.0);
        let d = if deviation(d_max) <= tolerance_mm {
            d_max
        } else {
            let (mut lo, mut hi) = (0.0, d_max);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if deviation(mid) <= tolerance_mm {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            lo
        };
        if d <= 0.0 {
            continue;
        }
        cut[k] = d;
        blends[k] = Some(Piece {
            shape: blend_at(d),
            feed_mm_s: pieces[k].feed_mm_s.min(pieces[k + 1].feed_mm_s),
        });
    }
    bound::spliced(pieces, &lengths, &cut, &blends)
}

/// Levels of the grading at rest points: the first interval is split at 1/2, 1/4, …
const GRADING_LEVELS: usize = 4;

/// `samples` with the interval next to every rest point (the ends and `stops`) split
/// geometrically towards the rest point (at 1/2, 1/4, … of its length): a motion from
/// rest covers `j t³ / 6` in time `t`, so evenly spaced samples would leave its first
/// milliseconds unresolved. The new samples take the geometry of the rest point and the
/// lower speed limit of the two ends. Returns the samples and the new indices of `stops`.
fn graded(samples: &[Sample], stops: &[usize]) -> (Vec<Sample>, Vec<usize>) {
    let n = samples.len();
    let mut rest = vec![false; n];
    rest[0] = true;
    rest[n - 1] = true;
    for &k in stops {
        rest[k] = true;
    }
    let mut out: Vec<Sample> = Vec::with_capacity(n + 4 * GRADING_LEVELS);
    let mut new_stops = Vec::new();
    let split = |from: &Sample, to: &Sample, out: &mut Vec<Sample>, towards_from: bool| {
        let h = to.s_mm - from.s_mm;
        let x_max = from.x_max.min(to.x_max);
        let mut points: Vec<f64> = (1..=GRADING_LEVELS)
            .map(|j| h * 0.5f64.powi(j as i32))
            .collect();
        if towards_from {
            points.reverse();
            for d in points {
                out.push(Sample {
                    s_mm: from.s_mm + d,
                    x_max,
                    ..*from
                });
            }
        } else {
            for d in points {
                out.push(Sample {
                    s_mm: to.s_mm - d,
                    x_max,
                    ..*to
                });
            }
        }
    };
    for k in 0..n {
        if k > 0 && rest[k] && !rest[k - 1] {
            split(&samples[k - 1], &samples[k], &mut out, false);
        }
        if rest[k] && k > 0 {
            new_stops.push(out.len());
        }
        out.push(samples[k]);
        if k + 1 < n && rest[k] {
            split(&samples[k], &samples[k + 1], &mut out, true);
        }
    }
    new_stops.pop(); // the last sample, at rest anyway
    (out, new_stops)
}

/// The jerk-limited lower bound of `pieces` (after [`g2_blended`]) from rest to rest,
/// sampled at most every `ds_mm` (and at least 16 samples per piece; see the module's
/// documentation).
pub fn jerk_lower_bound(
    pieces: &[Piece],
    machine: &JerkMachine,
    ds_mm: f64,
) -> Result<JerkBound, JerkError> {
    let path = g2_blended(pieces, machine.base.tolerance_mm);
    let (samples, stops) = bound::sample(&path, &machine.base, ds_mm);
    let (samples, stops) = graded(&samples, &stops);
    let (x, time_s) = solve(&samples, &stops, machine)?;
    Ok(JerkBound {
        s_mm: samples.iter().map(|s| s.s_mm).collect(),
        speed_mm_s: x.iter().map(|v| v.sqrt()).collect(),
        time_s,
    })
}

/// Builder of a sparse constraint matrix, row by row.
struct Rows {
    i: Vec<usize>,
    j: Vec<usize>,
    v: Vec<f64>,
    b: Vec<f64>,
}

impl Rows {
    /// Adds the row `Σ coeff · x[var] + s = rhs`.
    fn push(&mut self, terms: &[(usize, f64)], rhs: f64) {
        let row = self.b.len();
        for &(var, coeff) in terms {
            if coeff != 0.0 {
                self.i.push(row);
                self.j.push(var);
                self.v.push(coeff);
            }
        }
        self.b.push(rhs);
    }

    /// Adds the inequality `Σ coeff · x[var] ≤ rhs`, divided by `rhs` when positive: the
    /// solver's tolerances are absolute, and the jerk rows' bounds are small in the
    /// scaled units.
    fn push_le(&mut self, terms: &[(usize, f64)], rhs: f64) {
        if rhs > 0.0 {
            let scaled: Vec<(usize, f64)> = terms.iter().map(|&(v, c)| (v, c / rhs)).collect();
            self.push(&scaled, 1.0);
        } else {
            self.push(terms, rhs);
        }
    }
}

/// The cone program of the module's documentation; returns its `ṡ²` per sample, mm²/s²,
/// and its optimum, s.
fn solve(
    samples: &[Sample],
    stops: &[usize],
    machine: &JerkMachine,
) -> Result<(Vec<f64>, f64), JerkError> {
    let n = samples.len();
    let m = n - 1;
    // Scaled units: speed by the largest admissible one, so that b, c are within [0, 1].
    let b_scale = samples
        .iter()
        .map(|s| s.x_max)
        .fold(0.0, f64::max)
        .max(1e-12);
    let v_scale = b_scale.sqrt();
    let h: Vec<f64> = (0..m)
        .map(|k| samples[k + 1].s_mm - samples[k].s_mm)
        .collect();
    let h_unit = h.iter().sum::<f64>() / m as f64;
    // Variables: b (n), c = √b at most (n), a = s̈ / b_scale (m), and τ, the intervals'
    // times in units of h_unit / v_scale (m).
    let (vb, vc, va, vt) = (0, n, 2 * n, 2 * n + m);
    let vars = 2 * n + 2 * m;
    let mid: Vec<(Vec3, Vec3)> = (0..m)
        .map(|k| {
            let t = samples[k].t + samples[k + 1].t;
            let norm = t.norm();
            let t = if norm > 0.0 { t / norm } else { samples[k].t };
            (t, (samples[k].k + samples[k + 1].k) * 0.5)
        })
        .collect();
    let mut at_rest = vec![false; n];
    at_rest[0] = true;
    at_rest[n - 1] = true;
    for &k in stops {
        at_rest[k] = true;
    }
    let mut rows = Rows {
        i: Vec::new(),
        j: Vec::new(),
        v: Vec::new(),
        b: Vec::new(),
    };
    // Equalities: b_{k+1} − b_k − 2 h_k a_k = 0; b = 0 at rest.
    for k in 0..m {
        rows.push(
            &[(vb + k + 1, 1.0), (vb + k, -1.0), (va + k, -2.0 * h[k])],
            0.0,
        );
    }
    for (k, _) in at_rest.iter().enumerate().filter(|(_, r)| **r) {
        rows.push(&[(vb + k, 1.0)], 0.0);
    }
    let zero_rows = rows.b.len();
    // Speed: b_k at most its cap (feed and axis velocities; the acceleration-limited
    // curve too, which every admissible profile is under).
    for (k, s) in samples.iter().enumerate() {
        rows.push_le(&[(vb + k, 1.0)], s.x_max / b_scale);
    }
    // Acceleration of axis i over interval k: t_i a + κ_i (b_k + b_{k+1})/2.
    let acc_terms = |k: usize, i: usize, sign: f64| -> [(usize, f64); 3] {
        let (t, kappa) = mid[k];
        [
            (va + k, sign * t[i]),
            (vb + k, sign * 0.5 * kappa[i]),
            (vb + k + 1, sign * 0.5 * kappa[i]),
        ]
    };
    for k in 0..m {
        for i in 0..3 {
            let limit = machine.base.acceleration_mm_s2[i] / b_scale;
            for sign in [1.0, -1.0] {
                rows.push_le(&acc_terms(k, i, sign), limit);
            }
        }
    }
    // Jerk: |acc_k − acc_{k−1}| ≤ J (τ_{k−1} + τ_k) / 2; in scaled units the times'
    // coefficient is J h_unit / (2 v_scale b_scale). At a rest point the acceleration
    // before its first interval and after its last is zero.
    for k in 0..n {
        for i in 0..3 {
            let per_tau = machine.jerk_mm_s3[i] * h_unit / (2.0 * v_scale * b_scale);
            for sign in [1.0, -1.0] {
                if !at_rest[k] {
                    let mut terms: Vec<(usize, f64)> = acc_terms(k, i, sign).to_vec();
                    terms.extend(acc_terms(k - 1, i, -sign));
                    terms.push((vt + k - 1, -per_tau));
                    terms.push((vt + k, -per_tau));
                    rows.push(&terms, 0.0);
                } else {
                    for interval in [k, k.wrapping_sub(1)] {
                        if interval < m {
                            let mut terms: Vec<(usize, f64)> =
                                acc_terms(interval, i, sign).to_vec();
                            terms.push((vt + interval, -per_tau));
                            rows.push(&terms, 0.0);
                        }
                    }
                }
            }
        }
    }
    let nonneg_rows = rows.b.len() - zero_rows;
    // c_k² ≤ b_k: ‖(2 c, b − 1)‖ ≤ b + 1.
    for k in 0..n {
        rows.push(&[(vb + k, -1.0)], 1.0);
        rows.push(&[(vc + k, -2.0)], 0.0);
        rows.push(&[(vb + k, -1.0)], -1.0);
    }
    // τ_k (c_k + c_{k+1}) ≥ 2 h_k / h_unit: ‖(2 √(2 h_k / h_unit), τ − w)‖ ≤ τ + w with
    // w = c_k + c_{k+1}.
    for k in 0..m {
        rows.push(&[(vt + k, -1.0), (vc + k, -1.0), (vc + k + 1, -1.0)], 0.0);
        rows.push(&[], 2.0 * (2.0 * h[k] / h_unit).sqrt());
        rows.push(&[(vt + k, -1.0), (vc + k, 1.0), (vc + k + 1, 1.0)], 0.0);
    }
    let mut cones: Vec<SupportedConeT<f64>> = vec![
        SupportedConeT::ZeroConeT(zero_rows),
        SupportedConeT::NonnegativeConeT(nonneg_rows),
    ];
    cones.extend((0..n + m).map(|_| SupportedConeT::SecondOrderConeT(3)));
    let row_count = rows.b.len();
    let a_mat = CscMatrix::new_from_triplets(row_count, vars, rows.i, rows.j, rows.v);
    let p_mat = CscMatrix::zeros((vars, vars));
    // Time = Σ τ_k h_unit / v_scale.
    let mut q = vec![0.0; vars];
    for k in 0..m {
        q[vt + k] = h_unit / v_scale;
    }
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .max_iter(400)
        .build()
        .map_err(|e| JerkError::Solver(format!("settings: {e}")))?;
    let mut solver = DefaultSolver::new(&p_mat, &q, &a_mat, &rows.b, &cones, settings)
        .map_err(|e| JerkError::Solver(format!("refused the problem: {e:?}")))?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => {}
        other => {
            return Err(JerkError::Solver(format!(
                "ended with {other:?} ({n} samples, {row_count} rows)"
            )));
        }
    }
    let x = (0..n)
        .map(|k| (solver.solution.x[vb + k] * b_scale).max(0.0))
        .collect();
    Ok((x, solver.solution.obj_val))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(start: Vec3, end: Vec3) -> Piece {
        Piece {
            shape: Shape::Line { start, end },
            feed_mm_s: 50.0,
        }
    }

    /// Largest jump of position, direction and curvature vector between consecutive
    /// pieces.
    fn jumps(path: &[Piece]) -> (f64, f64, f64) {
        let mut worst = (0.0f64, 0.0f64, 0.0f64);
        for w in path.windows(2) {
            let (p0, t0, k0) = frame(&w[0].shape, 1.0);
            let (p1, t1, k1) = frame(&w[1].shape, 0.0);
            worst.0 = worst.0.max((p1 - p0).norm());
            worst.1 = worst.1.max((t1 - t0).norm());
            worst.2 = worst.2.max((k1 - k0).norm());
        }
        worst
    }

    #[test]
    fn corners_become_curvature_continuous_blends_within_the_tolerance() {
        let tol = 0.01;
        let v = Vec3::new(10.0, 0.0, 0.0);
        for end in [
            Vec3::new(10.0, 10.0, 0.0), // a right angle
            Vec3::new(20.0, 1.0, 0.5),  // a small turn in 3D
            Vec3::new(0.5, 3.0, 0.0),   // a sharp turn
        ] {
            let path = g2_blended(&[line(Vec3::zeros(), v), line(v, end)], tol);
            assert_eq!(path.len(), 3, "line, blend, line");
            let (dp, dt, dk) = jumps(&path);
            assert!(dp < 1e-9 && dt < 1e-9 && dk < 1e-9, "{dp} {dt} {dk}");
            // The blend's middle is on the tolerance band (its distance to the vertex),
            // and no point of it is farther than that from the two lines.
            let mid = (path[1].shape.eval(0.5).p - v).norm();
            assert!((mid - tol).abs() < 1e-6 * tol, "middle {mid}");
            let to_segment = |p: Vec3, a: Vec3, b: Vec3| {
                let u = ((p - a).dot(&(b - a)) / (b - a).norm_squared()).clamp(0.0, 1.0);
                (p - (a + (b - a) * u)).norm()
            };
            for k in 0..=100 {
                let p = path[1].shape.eval(k as f64 / 100.0).p;
                let d = to_segment(p, Vec3::zeros(), v).min(to_segment(p, v, end));
                assert!(d <= tol * (1.0 + 1e-6), "{d} at {k}");
            }
            // Ends where the lines go on.
            assert!((path[2].shape.end() - end).norm() < 1e-12);
        }
    }

    #[test]
    fn a_line_into_a_tangent_arc_gets_a_blend_for_the_curvature_jump() {
        // Along X, then a quarter circle of radius 2 about (10, 2) leaving tangentially:
        // tangent at the join, curvature 0 then 1/2.
        let arc = Piece {
            shape: Shape::Arc {
                center: Vec3::new(10.0, 2.0, 0.0),
                e1: Vec3::new(0.0, -1.0, 0.0),
                e2: Vec3::new(1.0, 0.0, 0.0),
                radius_mm: 2.0,
                from_rad: 0.0,
                to_rad: std::f64::consts::FRAC_PI_2,
                axial_per_rad: Vec3::zeros(),
            },
            feed_mm_s: 50.0,
        };
        let path = g2_blended(&[line(Vec3::zeros(), Vec3::new(10.0, 0.0, 0.0)), arc], 0.01);
        assert_eq!(path.len(), 3);
        let (dp, dt, dk) = jumps(&path);
        assert!(dp < 1e-9 && dt < 1e-9 && dk < 1e-9, "{dp} {dt} {dk}");
        // A join already smooth (a line after a line in the same direction) is left.
        let straight = g2_blended(
            &[
                line(Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0)),
                line(Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0)),
            ],
            0.01,
        );
        assert_eq!(straight.len(), 2);
    }
}
