//! An acceleration-limited time-optimal traversal of a path: the lower bound of the CAM
//! benchmark table (docs/PERFORMANCE.md, "CAM code against the feed and the time-optimal
//! bound").
//!
//! The path is a chain of [`Piece`]s (lines, circular arcs and helices, and rows over a
//! smooth surface), each with its programmed feed. Where two pieces meet at an angle, the
//! corner is replaced by the largest circular arc tangent to both that stays inside the
//! tolerance band (the arc's middle is `tolerance_mm` from the vertex) and uses at most
//! half of each neighbour ([`blended`]). The speed along that geometry is then the largest
//! one that keeps, at every point, the path speed at most the feed, every axis's speed at
//! most its limit and every axis's acceleration (tangential and centripetal parts
//! together) at most its limit. It starts and ends at rest. Jerk is ignored.
//!
//! Method: the classic phase-plane formulation (time-optimal path parametrisation). With
//! `s` the arc length, `x = ṡ²`, the unit tangent `q'(s)` and the curvature vector `q''(s)`,
//! axis `i` moves with velocity `q'_i ṡ` and acceleration `q'_i s̈ + q''_i x`, and
//! `dx/ds = 2 s̈`. At each sample (every `ds` mm at most) the largest admissible `x` (the
//! maximum velocity curve) follows in closed form; a forward pass from rest with the
//! largest admissible `s̈` and a backward pass from rest with the smallest give the
//! profile, and the time is `Σ 2 Δs / (√x_k + √x_{k+1})` (exact where `s̈` is constant).
//! The discretisation error shrinks with `ds`; the tests compare it with closed forms.
#![allow(clippy::many_single_char_names)]

use kerf_geom::Vec3;

/// The machine the bound is computed for: linear axes X, Y, Z.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundMachine {
    /// Velocity limit per axis, mm/s.
    pub velocity_mm_s: [f64; 3],
    /// Acceleration limit per axis, mm/s².
    pub acceleration_mm_s2: [f64; 3],
    /// Corner blend tolerance: the largest distance from a corner's vertex, mm.
    pub tolerance_mm: f64,
}

/// Geometry of one piece of path.
#[derive(Clone, Copy, Debug)]
pub enum Shape {
    /// A straight line from `start` to `end`.
    Line {
        /// Start point, mm.
        start: Vec3,
        /// End point, mm.
        end: Vec3,
    },
    /// `center + r (cos φ e1 + sin φ e2) + φ axial_per_rad` for φ from `from_rad` to
    /// `to_rad` (increasing): a circular arc, or a helix when `axial_per_rad` is not zero.
    Arc {
        /// Centre of the circle at φ = 0, mm.
        center: Vec3,
        /// Unit vector from the centre towards φ = 0.
        e1: Vec3,
        /// Unit vector of the direction of travel at φ = 0, perpendicular to `e1`.
        e2: Vec3,
        /// Radius, mm.
        radius_mm: f64,
        /// Start angle, rad.
        from_rad: f64,
        /// End angle, rad, above `from_rad`.
        to_rad: f64,
        /// Displacement along the helix axis per radian, mm (perpendicular to e1 and e2).
        axial_per_rad: Vec3,
    },
    /// `(x, y, z(x, y))` over a smooth surface `z`, at a fixed `y`, from `x_from` to `x_to`
    /// (either direction).
    Row {
        /// The surface: `(z, ∂z/∂x, ∂²z/∂x²)` at `(x, y)`, mm.
        surface: fn(f64, f64) -> (f64, f64, f64),
        /// The row's y, mm.
        y: f64,
        /// First x, mm.
        x_from: f64,
        /// Last x, mm.
        x_to: f64,
    },
    /// `Σ coeffs[j] u^j` for u in [0, 1]: a quintic, the curvature-continuous corner
    /// blends of the jerk-limited bound ([`crate::jerk::g2_blended`]).
    Quintic {
        /// Coefficients of u⁰ to u⁵, mm.
        coeffs: [Vec3; 6],
    },
}

/// A piece of path with its feed.
#[derive(Clone, Copy, Debug)]
pub struct Piece {
    /// The geometry.
    pub shape: Shape,
    /// Programmed feed along the piece, mm/s.
    pub feed_mm_s: f64,
}

/// A point of a piece: position, first and second derivative by the parameter.
pub(crate) struct Eval {
    pub(crate) p: Vec3,
    pub(crate) d1: Vec3,
    pub(crate) d2: Vec3,
}

/// The unit tangent and the curvature vector (the second derivative by arc length) of a
/// curve whose first and second derivatives by its parameter are `d1` and `d2`, and the
/// parameter's speed `|d1|`.
pub(crate) fn unit_frame(d1: Vec3, d2: Vec3) -> (Vec3, Vec3, f64) {
    let speed = d1.norm();
    let t = d1 / speed;
    (t, (d2 - t * d2.dot(&t)) / (speed * speed), speed)
}

impl Shape {
    /// Position and derivatives at `u` in [0, 1].
    pub(crate) fn eval(&self, u: f64) -> Eval {
        match *self {
            Shape::Line { start, end } => Eval {
                p: start + (end - start) * u,
                d1: end - start,
                d2: Vec3::zeros(),
            },
            Shape::Arc {
                center,
                e1,
                e2,
                radius_mm: r,
                from_rad,
                to_rad,
                axial_per_rad,
            } => {
                let w = to_rad - from_rad;
                let phi = from_rad + w * u;
                let (s, c) = phi.sin_cos();
                Eval {
                    p: center + (e1 * c + e2 * s) * r + axial_per_rad * phi,
                    d1: ((e2 * c - e1 * s) * r + axial_per_rad) * w,
                    d2: (e1 * c + e2 * s) * (-r * w * w),
                }
            }
            Shape::Row {
                surface,
                y,
                x_from,
                x_to,
            } => {
                let w = x_to - x_from;
                let x = x_from + w * u;
                let (z, zx, zxx) = surface(x, y);
                Eval {
                    p: Vec3::new(x, y, z),
                    d1: Vec3::new(w, 0.0, zx * w),
                    d2: Vec3::new(0.0, 0.0, zxx * w * w),
                }
            }
            Shape::Quintic { coeffs: c } => {
                let mut e = Eval {
                    p: Vec3::zeros(),
                    d1: Vec3::zeros(),
                    d2: Vec3::zeros(),
                };
                // Horner's rule on the polynomial and its two derivatives.
                for j in (0..6).rev() {
                    e.d2 = e.d2 * u + e.d1 * 2.0;
                    e.d1 = e.d1 * u + e.p;
                    e.p = e.p * u + c[j];
                }
                e
            }
        }
    }

    /// Start point, mm.
    pub fn start(&self) -> Vec3 {
        self.eval(0.0).p
    }

    /// End point, mm.
    pub fn end(&self) -> Vec3 {
        self.eval(1.0).p
    }

    /// Unit tangent at `u`.
    fn tangent(&self, u: f64) -> Vec3 {
        self.eval(u).d1.normalize()
    }

    /// Length, mm (exact for lines and arcs, Simpson's rule over 256 intervals for rows
    /// and quintics).
    pub fn length_mm(&self) -> f64 {
        match self {
            Shape::Line { .. } | Shape::Arc { .. } => self.eval(0.0).d1.norm(),
            Shape::Row { .. } | Shape::Quintic { .. } => {
                let n = 256;
                let f = |k: usize| self.eval(k as f64 / n as f64).d1.norm();
                let sum: f64 = (0..=n)
                    .map(|k| {
                        let w = if k == 0 || k == n {
                            1.0
                        } else if k % 2 == 1 {
                            4.0
                        } else {
                            2.0
                        };
                        w * f(k)
                    })
                    .sum();
                sum / (3.0 * n as f64)
            }
        }
    }

    /// The piece without `from_start_mm` at its start and `from_end_mm` at its end
    /// (exact for lines and arcs; rows use the speed of the parameter at each end, which
    /// is exact to second order over the short lengths a corner blend removes).
    pub(crate) fn trimmed(&self, from_start_mm: f64, from_end_mm: f64) -> Shape {
        let du0 = from_start_mm / self.eval(0.0).d1.norm();
        let du1 = from_end_mm / self.eval(1.0).d1.norm();
        match *self {
            Shape::Line { start, end } => Shape::Line {
                start: start + (end - start) * du0,
                end: start + (end - start) * (1.0 - du1),
            },
            Shape::Arc {
                center,
                e1,
                e2,
                radius_mm,
                from_rad,
                to_rad,
                axial_per_rad,
            } => {
                let w = to_rad - from_rad;
                Shape::Arc {
                    center,
                    e1,
                    e2,
                    radius_mm,
                    from_rad: from_rad + w * du0,
                    to_rad: to_rad - w * du1,
                    axial_per_rad,
                }
            }
            Shape::Row {
                surface,
                y,
                x_from,
                x_to,
            } => {
                let w = x_to - x_from;
                Shape::Row {
                    surface,
                    y,
                    x_from: x_from + w * du0,
                    x_to: x_to - w * du1,
                }
            }
            Shape::Quintic { coeffs } => {
                // p(u0 + w v) expanded in v: coefficient j is Σ_{m≥j} C(m, j) c_m u0^(m-j) w^j.
                let (u0, w) = (du0, 1.0 - du0 - du1);
                let mut out = [Vec3::zeros(); 6];
                for (m, c) in coeffs.iter().enumerate() {
                    let mut binom = 1.0;
                    for (j, o) in out.iter_mut().enumerate().take(m + 1) {
                        *o += c * (binom * u0.powi((m - j) as i32) * w.powi(j as i32));
                        binom = binom * (m - j) as f64 / (j + 1) as f64;
                    }
                }
                Shape::Quintic { coeffs: out }
            }
        }
    }
}

/// Turn angles below this (rad) are tangent joins: no blend.
const TANGENT_RAD: f64 = 1e-9;

/// The path with every corner replaced by its largest circular blend inside the
/// tolerance band: for a turn of angle θ the blend radius is
/// `R = tolerance · cos(θ/2) / (1 − cos(θ/2))` (the arc's middle is `tolerance_mm` from
/// the vertex), reduced when its tangent length `R tan(θ/2)` would exceed half of either
/// neighbour. A reversal (θ = π) cannot be blended; it is left as a corner, which the
/// bound passes at rest.
pub fn blended(pieces: &[Piece], tolerance_mm: f64) -> Vec<Piece> {
    let n = pieces.len();
    // Tangent length taken from the end of piece k (and the start of piece k + 1).
    let mut cut = vec![0.0; n];
    let mut arcs: Vec<Option<Piece>> = vec![None; n];
    let lengths: Vec<f64> = pieces.iter().map(|p| p.shape.length_mm()).collect();
    for k in 0..n.saturating_sub(1) {
        let t1 = pieces[k].shape.tangent(1.0);
        let t2 = pieces[k + 1].shape.tangent(0.0);
        let theta = t1.dot(&t2).clamp(-1.0, 1.0).acos();
        if !(TANGENT_RAD..=std::f64::consts::PI - 1e-6).contains(&theta) {
            continue;
        }
        let half = theta / 2.0;
        let r_band = tolerance_mm * half.cos() / (1.0 - half.cos());
        let len = (r_band * half.tan())
            .min(lengths[k] / 2.0)
            .min(lengths[k + 1] / 2.0);
        let radius_mm = len / half.tan();
        let vertex = pieces[k].shape.end();
        let bisector = (t2 - t1).normalize();
        let center = vertex + bisector * (radius_mm / half.cos());
        let start = vertex - t1 * len;
        cut[k] = len;
        arcs[k] = Some(Piece {
            shape: Shape::Arc {
                center,
                e1: (start - center) / radius_mm,
                e2: t1,
                radius_mm,
                from_rad: 0.0,
                to_rad: theta,
                axial_per_rad: Vec3::zeros(),
            },
            feed_mm_s: pieces[k].feed_mm_s.min(pieces[k + 1].feed_mm_s),
        });
    }
    spliced(pieces, &lengths, &cut, &arcs)
}

/// `pieces` (of `lengths`) with `cut[k]` taken from the end of piece `k` and the start of
/// piece `k + 1`, and `blends[k]` put in between: the path of [`blended`] and of
/// [`crate::jerk::g2_blended`]. A piece both its blends take whole is left out.
pub(crate) fn spliced(
    pieces: &[Piece],
    lengths: &[f64],
    cut: &[f64],
    blends: &[Option<Piece>],
) -> Vec<Piece> {
    let mut out = Vec::with_capacity(2 * pieces.len());
    for (k, piece) in pieces.iter().enumerate() {
        let before = if k > 0 { cut[k - 1] } else { 0.0 };
        if lengths[k] - before - cut[k] > 1e-9 {
            out.push(Piece {
                shape: piece.shape.trimmed(before, cut[k]),
                feed_mm_s: piece.feed_mm_s,
            });
        }
        if let Some(b) = blends[k] {
            out.push(b);
        }
    }
    out
}

/// One sample of the path for the phase-plane passes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sample {
    /// Arc length from the start, mm.
    pub(crate) s_mm: f64,
    /// Unit tangent.
    pub(crate) t: Vec3,
    /// Curvature vector (second derivative by arc length), 1/mm.
    pub(crate) k: Vec3,
    /// Largest admissible ṡ², mm²/s².
    pub(crate) x_max: f64,
}

/// Below this |tangent component| an axis takes no part in the tangential acceleration.
const TINY: f64 = 1e-12;

impl Sample {
    /// The admissible range of s̈ at ṡ² = x, mm/s² (empty when lo > hi).
    fn accel_range(&self, x: f64, a: &[f64; 3]) -> (f64, f64) {
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for (i, a_i) in a.iter().enumerate() {
            if self.t[i].abs() > TINY {
                let c = -self.k[i] * x / self.t[i];
                let w = a_i / self.t[i].abs();
                lo = lo.max(c - w);
                hi = hi.min(c + w);
            }
        }
        (lo, hi)
    }
}

/// The largest ṡ² at a point with unit tangent `t` and curvature vector `k` that keeps
/// the speed within `feed_mm_s` and the axis velocities, and leaves some admissible
/// tangential acceleration: axis i needs s̈ in `[-(k_i x + a_i)/t_i, (a_i - k_i x)/t_i]`
/// (sorted), an interval of centre `-k_i x / t_i` and half-width `a_i / |t_i|`; two axes'
/// intervals meet while `x |k_i/t_i - k_j/t_j| ≤ a_i/|t_i| + a_j/|t_j|`, and an axis with
/// no tangent component needs `|k_i| x ≤ a_i`.
pub fn max_speed_squared(t: &Vec3, k: &Vec3, feed_mm_s: f64, machine: &BoundMachine) -> f64 {
    max_speed_squared_axes(
        t.as_slice(),
        k.as_slice(),
        feed_mm_s,
        &machine.velocity_mm_s,
        &machine.acceleration_mm_s2,
    )
}

/// [`max_speed_squared`] over any number of axes, their velocity and acceleration limits
/// by axis (the point-wise prototype's six).
pub(crate) fn max_speed_squared_axes(
    t: &[f64],
    k: &[f64],
    feed_mm_s: f64,
    velocity: &[f64],
    acceleration: &[f64],
) -> f64 {
    let a = acceleration;
    let mut x = feed_mm_s * feed_mm_s;
    for i in 0..t.len() {
        if t[i].abs() > TINY {
            x = x.min((velocity[i] / t[i].abs()).powi(2));
            for j in i + 1..t.len() {
                if t[j].abs() > TINY {
                    let d = (k[i] / t[i] - k[j] / t[j]).abs();
                    if d > 0.0 {
                        x = x.min((a[i] / t[i].abs() + a[j] / t[j].abs()) / d);
                    }
                }
            }
        } else if k[i].abs() > 0.0 {
            x = x.min(a[i] / k[i].abs());
        }
    }
    x
}

/// The time-optimal speed profile along a path.
#[derive(Clone, Debug)]
pub struct Bound {
    /// Arc length of each sample, mm.
    pub s_mm: Vec<f64>,
    /// Path speed at each sample, mm/s.
    pub speed_mm_s: Vec<f64>,
    /// Time from rest to rest, s.
    pub time_s: f64,
}

/// The path sampled at most every `ds_mm` (and at least 16 samples per piece), with the
/// indices of samples at unblended corners (reversals, the only joins [`blended`] leaves
/// turning by more than a right angle), where a traversal passes at rest.
pub(crate) fn sample(
    path: &[Piece],
    machine: &BoundMachine,
    ds_mm: f64,
) -> (Vec<Sample>, Vec<usize>) {
    let mut samples: Vec<Sample> = Vec::new();
    let mut stops: Vec<usize> = Vec::new();
    let mut s_mm = 0.0;
    for piece in path {
        let len = piece.shape.length_mm();
        let n = ((len / ds_mm).ceil() as usize).max(16);
        let mut prev = piece.shape.eval(0.0).p;
        for j in 0..=n {
            let e = piece.shape.eval(j as f64 / n as f64);
            s_mm += (e.p - prev).norm();
            prev = e.p;
            let (t, k, _) = unit_frame(e.d1, e.d2);
            let x_max = max_speed_squared(&t, &k, piece.feed_mm_s, machine);
            let count = samples.len();
            match samples.last_mut() {
                // A junction: one sample, with the stricter limit and the geometry of the
                // piece that starts there.
                Some(last) if j == 0 => {
                    if last.t.dot(&t) < 0.0 {
                        stops.push(count - 1);
                    }
                    last.x_max = last.x_max.min(x_max);
                    last.t = t;
                    last.k = k;
                }
                _ => samples.push(Sample { s_mm, t, k, x_max }),
            }
        }
    }
    (samples, stops)
}

/// The acceleration-limited time-optimal `ṡ²` at each sample, from rest to rest and at
/// rest at `stops`: the largest admissible profile, so every traversal within the
/// acceleration limits (jerk-limited ones included) is at or below it everywhere.
fn accel_profile(samples: &[Sample], stops: &[usize], machine: &BoundMachine) -> Vec<f64> {
    let n = samples.len();
    let mut x: Vec<f64> = samples.iter().map(|s| s.x_max).collect();
    x[0] = 0.0;
    x[n - 1] = 0.0;
    for &i in stops {
        x[i] = 0.0;
    }
    let a = &machine.acceleration_mm_s2;
    // Forward: from each sample, the largest admissible s̈ over the step.
    for i in 0..n - 1 {
        let h = samples[i + 1].s_mm - samples[i].s_mm;
        let (_, hi) = samples[i].accel_range(x[i], a);
        let reach = (x[i] + 2.0 * h * hi.max(0.0)).max(0.0);
        x[i + 1] = x[i + 1].min(reach);
    }
    // Backward: into each sample, the largest admissible deceleration over the step.
    for i in (0..n - 1).rev() {
        let h = samples[i + 1].s_mm - samples[i].s_mm;
        let (lo, _) = samples[i + 1].accel_range(x[i + 1], a);
        let reach = (x[i + 1] - 2.0 * h * lo.min(0.0)).max(0.0);
        x[i] = x[i].min(reach);
    }
    x
}

/// Time of a traversal with speed `speed_mm_s[i]` at arc length `s_mm[i]` and a constant
/// s̈ between samples, s: `Σ 2 Δs / (v_k + v_{k+1})`.
fn traversal_time_s(s_mm: &[f64], speed_mm_s: &[f64]) -> f64 {
    let mut time_s = 0.0;
    for i in 0..s_mm.len() - 1 {
        let h = s_mm[i + 1] - s_mm[i];
        if h > 0.0 {
            time_s += 2.0 * h / (speed_mm_s[i] + speed_mm_s[i + 1]);
        }
    }
    time_s
}

/// The acceleration-limited time-optimal traversal of `pieces` (after [`blended`]) from
/// rest to rest, sampled at most every `ds_mm` (and at least 16 samples per piece).
pub fn lower_bound(pieces: &[Piece], machine: &BoundMachine, ds_mm: f64) -> Bound {
    let path = blended(pieces, machine.tolerance_mm);
    let (samples, stops) = sample(&path, machine, ds_mm);
    let x = accel_profile(&samples, &stops, machine);
    let speed_mm_s: Vec<f64> = x.iter().map(|v| v.sqrt()).collect();
    let s_mm: Vec<f64> = samples.iter().map(|s| s.s_mm).collect();
    let time_s = traversal_time_s(&s_mm, &speed_mm_s);
    Bound {
        s_mm,
        speed_mm_s,
        time_s,
    }
}
