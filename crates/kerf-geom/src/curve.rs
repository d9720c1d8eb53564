//! Evaluable curves: a [`Path`] with its derived data precomputed, so that the real-time
//! loop evaluates a point at arc length `s` with a handful of flops and no allocation.
//!
//! Every curve is parameterised by arc length `s` in `[0, length]` (a helix whose end the
//! circle misses by its drift, within rounding or the protocol's arc tolerance, by a
//! length that bounds its speed: `|dp/ds| ≤ 1`, see [`Helix`]). Evaluation at
//! `s >= length` returns the stored end point exactly (not a recomputed approximation), so
//! a motion that stops at the end of a curve stops exactly at the programmed end.

pub use crate::transition::Transition;
use crate::{Path, Vec3};

/// A point on a curve with its first two derivatives with respect to arc length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurvePoint {
    /// Position, mm.
    pub point: Vec3,
    /// Tangent `dp/ds`: of unit length, except on a helix with a drift, where it is
    /// shorter by at most `|drift · sweep| / length` (see [`Helix`]).
    pub tangent: Vec3,
    /// Curvature vector `d²p/ds²`, 1/mm (points to the centre; zero on lines).
    pub curvature: Vec3,
}

/// What a helix may miss of its end point without a drift, mm: rounding (the
/// interpreter's arcs at ordinary coordinates miss by about 1e-13 mm).
const NEGLIGIBLE_MISS_MM: f64 = 1e-12;

/// A circular arc or helix with its frame precomputed.
///
/// At swept angle `θ = sweep · s / length` the point is
///
/// `p(θ) = start + r (e1 (cos θ − 1) + e2 sin θ) + axis · rise · θ / sweep + drift · θ`,
///
/// written relative to the start (with `cos θ − 1 = −2 sin²(θ/2)`) so that a huge radius
/// (1e12 mm) loses nothing of the start point or of a small angle to cancellation.
///
/// `drift` spreads what the circle misses of the stored end linearly over the angle:
/// [`Curve::from_path`] sets it to `(end − p₀(sweep)) / sweep`, `p₀` being the curve
/// without it, so that `p(sweep)` is `end` to rounding and the curve never jumps to its
/// end (a miss of at most 1e-12 mm, rounding, is left as it was: no drift, and the exact
/// end at `s >= length`). For the interpreter's arcs it is rounding; for an arc the daemon accepted it is
/// at most the protocol's arc tolerance (docs/PROTOCOL.md, "One arc, in millimetres")
/// over the sweep. It is part of the tangent `dp/ds`, not of the curvature.
///
/// `length = sqrt((r·sweep)² + rise²) + |drift|·|sweep|`: the helix's arc length plus the
/// whole drift, so that `|dp/ds| ≤ 1` everywhere (the speed along the curve never exceeds
/// the planned speed, however large the drift is against a tiny arc); for an arc without
/// drift it is the exact arc length and `|dp/ds| = 1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Helix {
    /// Start point, mm.
    pub start: Vec3,
    /// End point, mm (returned exactly at `s >= length`).
    pub end: Vec3,
    /// Centre of the circle in the plane of `start`, mm (`start − r · e1`).
    pub center: Vec3,
    /// Unit vector from the centre to the start.
    pub e1: Vec3,
    /// `axis × e1`.
    pub e2: Vec3,
    /// Unit normal of the plane.
    pub axis: Vec3,
    /// Radius, mm.
    pub radius_mm: f64,
    /// Signed sweep about `axis`, radians.
    pub sweep_rad: f64,
    /// Displacement along `axis` from start to end, mm.
    pub rise_mm: f64,
    /// Arc length, mm (see the type's documentation).
    pub length_mm: f64,
    /// What the circle misses of `end`, spread over the swept angle: mm per radian of
    /// `θ` (signed like `sweep_rad`, so `drift · sweep` is the whole difference).
    pub drift_mm_per_rad: Vec3,
}

/// A path ready for evaluation at arc length.
///
/// The transition variant is a few hundred bytes (its arc-length table is inline): curves
/// live by value in the motion core's fixed-capacity queue, so boxing it would allocate.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Curve {
    /// A straight line.
    Line {
        /// Start point, mm.
        start: Vec3,
        /// End point, mm.
        end: Vec3,
        /// Unit direction (zero for a zero-length line).
        dir: Vec3,
        /// Length, mm.
        length_mm: f64,
    },
    /// A circular arc or helix.
    Helix(Helix),
    /// A curvature-continuous transition inserted by the planner (see [`Transition`]).
    Transition(Transition),
}

impl Curve {
    /// Precomputes the evaluable form of `path`. An arc whose radius is zero degenerates to
    /// the straight line between its end points, which is the only curve it can describe.
    pub fn from_path(path: &Path) -> Curve {
        match path {
            Path::Line(l) => Curve::line(l.start, l.end),
            Path::Arc(a) => {
                let axis = a.axis.try_normalize(1e-300).unwrap_or(Vec3::z());
                let radial = a.start - a.center;
                // The centre lies in the plane of the start by contract; remove any rounding
                // component along the axis so that the frame is exactly orthonormal.
                let radial = radial - axis * radial.dot(&axis);
                let radius_mm = radial.norm();
                if radius_mm < 1e-12 || !a.sweep_rad.is_finite() || a.sweep_rad == 0.0 {
                    return Curve::line(a.start, a.end);
                }
                let e1 = radial / radius_mm;
                let e2 = axis.cross(&e1);
                let rise_mm = (a.end - a.start).dot(&axis);
                let mut h = Helix {
                    start: a.start,
                    end: a.end,
                    center: a.start - radial,
                    e1,
                    e2,
                    axis,
                    radius_mm,
                    sweep_rad: a.sweep_rad,
                    rise_mm,
                    length_mm: 0.0,
                    drift_mm_per_rad: Vec3::zeros(),
                };
                // What the helix misses of the end, relative to the start (no rounding at
                // the coordinates' magnitude), spread over the sweep.
                let missed = (a.end - a.start) - h.offset_at_angle(a.sweep_rad);
                // A rounding-level miss (the interpreter's arcs) is left to the exact end
                // point at `s >= length`, with no drift: the step is far
                // below anything a limit can see, and the curve's data stay the same for
                // the same shape anywhere on the machine (the planner's memos key on them).
                if missed.norm() > NEGLIGIBLE_MISS_MM {
                    h.drift_mm_per_rad = missed / a.sweep_rad;
                }
                let helix_mm = ((radius_mm * a.sweep_rad).powi(2) + rise_mm * rise_mm).sqrt();
                h.length_mm = helix_mm + h.drift_mm_per_rad.norm() * a.sweep_rad.abs();
                let usable = h.length_mm > 0.0
                    && h.length_mm < f64::INFINITY
                    && h.drift_mm_per_rad.iter().all(|d| d.is_finite());
                if !usable {
                    // A sweep so small that the circle vanishes in rounding (the drift per
                    // radian overflows, or nothing is left of the length): what is left is
                    // the straight way from start to end.
                    return Curve::line(a.start, a.end);
                }
                Curve::Helix(h)
            }
        }
    }

    /// A straight line from `start` to `end`.
    pub fn line(start: Vec3, end: Vec3) -> Curve {
        let delta = end - start;
        let length_mm = delta.norm();
        let dir = if length_mm > 0.0 {
            delta / length_mm
        } else {
            Vec3::zeros()
        };
        Curve::Line {
            start,
            end,
            dir,
            length_mm,
        }
    }

    /// Arc length, mm.
    pub fn length(&self) -> f64 {
        match self {
            Curve::Line { length_mm, .. } => *length_mm,
            Curve::Helix(h) => h.length_mm,
            Curve::Transition(t) => t.length_mm,
        }
    }

    /// Start point.
    pub fn start(&self) -> Vec3 {
        match self {
            Curve::Line { start, .. } => *start,
            Curve::Helix(h) => h.start,
            Curve::Transition(t) => t.start,
        }
    }

    /// End point.
    pub fn end(&self) -> Vec3 {
        match self {
            Curve::Line { end, .. } => *end,
            Curve::Helix(h) => h.end,
            Curve::Transition(t) => t.end,
        }
    }

    /// Point at arc length `s` (clamped to the curve; exact end point at `s >= length`).
    #[inline]
    pub fn point_at(&self, s: f64) -> Vec3 {
        match self {
            Curve::Line {
                start,
                end,
                dir,
                length_mm,
            } => {
                if s >= *length_mm {
                    *end
                } else if s <= 0.0 {
                    *start
                } else {
                    start + dir * s
                }
            }
            Curve::Helix(h) => {
                if s >= h.length_mm {
                    h.end
                } else if s <= 0.0 {
                    h.start
                } else {
                    h.point_at_angle(h.angle_at(s))
                }
            }
            Curve::Transition(t) => t.point_at(s),
        }
    }

    /// Point, tangent `dp/ds` and curvature vector at arc length `s` (clamped).
    pub fn eval(&self, s: f64) -> CurvePoint {
        match self {
            Curve::Line { dir, .. } => CurvePoint {
                point: self.point_at(s),
                tangent: *dir,
                curvature: Vec3::zeros(),
            },
            Curve::Helix(h) => {
                let u = (s / h.length_mm).clamp(0.0, 1.0);
                let theta = h.sweep_rad * u;
                let (sin, cos) = theta.sin_cos();
                let per_mm = h.sweep_rad / h.length_mm;
                // dp/ds: the circle's and the rise's parts, and the drift's.
                let tangent = (h.e2 * cos - h.e1 * sin) * (h.radius_mm * per_mm)
                    + h.axis * (h.rise_mm / h.length_mm)
                    + h.drift_mm_per_rad * per_mm;
                let curvature = -(h.e1 * cos + h.e2 * sin) * (h.radius_mm * per_mm * per_mm);
                CurvePoint {
                    point: self.point_at(s),
                    tangent,
                    curvature,
                }
            }
            Curve::Transition(t) => {
                let (tangent, curvature) = t.frame_at(s);
                CurvePoint {
                    point: t.point_at(s),
                    tangent,
                    curvature,
                }
            }
        }
    }

    /// Shortest distance from `p` to the curve, mm.
    pub fn distance_to(&self, p: &Vec3) -> f64 {
        match self {
            Curve::Line {
                start,
                end,
                dir,
                length_mm,
            } => line_distance(start, end, dir, *length_mm, p),
            Curve::Helix(h) => h.distance_to(p),
            Curve::Transition(t) => t.distance_to(p),
        }
    }

    /// The part of a line or arc/helix between arc lengths `s0 < s1` (clamped), as a curve
    /// of the same kind whose end points are exactly `point_at(s0)` and `point_at(s1)` of
    /// this one. Transitions are returned unchanged (the planner never trims them).
    pub fn trimmed(&self, s0: f64, s1: f64) -> Curve {
        let len = self.length();
        let s0 = s0.clamp(0.0, len);
        let s1 = s1.clamp(s0, len);
        let (a, b) = (self.point_at(s0), self.point_at(s1));
        match self {
            Curve::Line { dir, .. } => Curve::Line {
                start: a,
                end: b,
                dir: *dir,
                length_mm: s1 - s0,
            },
            Curve::Helix(h) => {
                // The piece from θ0 on is the same curve: with e1' = e1 cos θ0 + e2 sin θ0
                // and e2' = axis × e1', r (e1' (cos φ − 1) + e2' sin φ) is
                // r (e1 cos(θ0 + φ) + e2 sin(θ0 + φ)) − r (e1 cos θ0 + e2 sin θ0), the rise
                // per radian is unchanged and so is the drift per radian; so
                // p'(φ) = p(θ0) + [p(θ0 + φ) − p(θ0)] = p(θ0 + φ).
                let th0 = h.angle_at(s0);
                let frac = (s1 - s0) / h.length_mm;
                let (sin, cos) = th0.sin_cos();
                let e1 = h.e1 * cos + h.e2 * sin;
                Curve::Helix(Helix {
                    start: a,
                    end: b,
                    center: a - e1 * h.radius_mm,
                    e1,
                    e2: h.axis.cross(&e1),
                    axis: h.axis,
                    radius_mm: h.radius_mm,
                    sweep_rad: h.sweep_rad * frac,
                    rise_mm: h.rise_mm * frac,
                    length_mm: s1 - s0,
                    drift_mm_per_rad: h.drift_mm_per_rad,
                })
            }
            Curve::Transition(_) => *self,
        }
    }
}

/// Shortest distance from `p` to the line from `start` to `end` with unit direction `dir`
/// and length `length_mm` (the data of [`Curve::Line`]), mm.
pub fn line_distance(start: &Vec3, end: &Vec3, dir: &Vec3, length_mm: f64, p: &Vec3) -> f64 {
    if length_mm == 0.0 {
        return (p - start).norm();
    }
    let along = (p - start).dot(dir);
    if along <= 0.0 {
        (p - start).norm()
    } else if along >= length_mm {
        (p - end).norm()
    } else {
        (p - (start + dir * along)).norm()
    }
}

impl Helix {
    /// The angle at arc length `s`: `sweep · s / length`, or `sweep · (s / length)` where
    /// the product overflows (an arc of so many turns that its sweep times its length is
    /// beyond f64, which would make the angle infinite and the point NaN). Every other arc
    /// gets the first, bit for bit.
    #[inline]
    pub fn angle_at(&self, s: f64) -> f64 {
        let theta = self.sweep_rad * s / self.length_mm;
        if theta.is_finite() {
            theta
        } else {
            self.sweep_rad * (s / self.length_mm)
        }
    }

    /// Point at swept angle `theta` from the start (signed like `sweep_rad`): the point the
    /// motion follows, drift included (see [`Helix`]).
    #[inline]
    pub fn point_at_angle(&self, theta: f64) -> Vec3 {
        self.start + (self.offset_at_angle(theta) + self.drift_mm_per_rad * theta)
    }

    /// `p₀(θ) − start` of the helix without its drift: `r (e1 (cos θ − 1) + e2 sin θ) +
    /// axis · rise · θ / sweep`, with `cos θ − 1 = −2 sin²(θ/2)` and
    /// `sin θ = 2 sin(θ/2) cos(θ/2)` (one `sin_cos`, no cancellation at small angles).
    #[inline]
    fn offset_at_angle(&self, theta: f64) -> Vec3 {
        let (sin_half, cos_half) = (0.5 * theta).sin_cos();
        let sin = 2.0 * sin_half * cos_half;
        let cos_minus_1 = -2.0 * sin_half * sin_half;
        (self.e1 * cos_minus_1 + self.e2 * sin) * self.radius_mm
            + self.axis * (self.rise_mm * theta / self.sweep_rad)
    }

    /// Curvature magnitude, 1/mm.
    pub fn curvature(&self) -> f64 {
        let per_mm = self.sweep_rad / self.length_mm;
        self.radius_mm * per_mm * per_mm
    }

    /// Shortest distance from `p` to the helix without its drift (the programmed circle or
    /// helix; the curve the motion follows is at most `|drift · sweep|` from it, which
    /// for an accepted arc is within the protocol's arc tolerance). A planar arc is solved
    /// exactly: the nearest point is at the angle of `p` projected on the plane if the arc
    /// covers it, else an end point. On a helix the candidates are that angle on the turns
    /// near `p`'s height, refined by Newton steps on the squared distance, and the end
    /// points. Everything is measured from the start, so a huge radius loses nothing.
    pub fn distance_to(&self, p: &Vec3) -> f64 {
        let mut best = (p - self.start).norm().min((p - self.end).norm());
        // Coordinates about the centre: x = r + dx, y, h (the centre is in the start's
        // plane).
        let rel = p - self.start;
        let dx = rel.dot(&self.e1);
        let x = self.radius_mm + dx;
        let y = rel.dot(&self.e2);
        let h = rel.dot(&self.axis);
        let base = y.atan2(x);
        let (lo, hi) = if self.sweep_rad >= 0.0 {
            (0.0, self.sweep_rad)
        } else {
            (self.sweep_rad, 0.0)
        };
        let tau = std::f64::consts::TAU;
        if self.rise_mm == 0.0 {
            // Some turn of the arc passes the angle of `p` iff `base + 2πk` is in range.
            let k = ((lo - base) / tau).ceil();
            if base + k * tau <= hi {
                // sqrt(x² + y²) − r without the cancellation of two huge numbers.
                let rho = (x * x + y * y).sqrt();
                let radial = (dx * (2.0 * self.radius_mm + dx) + y * y) / (rho + self.radius_mm);
                best = best.min((radial * radial + h * h).sqrt());
            }
            return best;
        }
        // Turns within one revolution of the angle at which the helix has `p`'s height.
        let pitch = self.rise_mm / self.sweep_rad;
        let theta_h = (h / pitch).clamp(lo, hi);
        let mut k = ((theta_h - tau - base) / tau).ceil();
        while base + k * tau <= theta_h + tau {
            let mut theta = (base + k * tau).clamp(lo, hi);
            for _ in 0..3 {
                theta = self.newton(&rel, theta).clamp(lo, hi);
            }
            best = best.min((rel - self.offset_at_angle(theta)).norm());
            k += 1.0;
        }
        best
    }

    /// One Newton step on `f(θ) = |rel − c(θ)|²` about `theta`, `c` the offset of the
    /// helix without drift from the start and `rel` the point's.
    fn newton(&self, rel: &Vec3, theta: f64) -> f64 {
        let (sin, cos) = theta.sin_cos();
        let pitch = self.rise_mm / self.sweep_rad;
        let c = self.offset_at_angle(theta);
        let d1 = (self.e2 * cos - self.e1 * sin) * self.radius_mm + self.axis * pitch;
        let d2 = -(self.e1 * cos + self.e2 * sin) * self.radius_mm;
        let diff = c - rel;
        let g = diff.dot(&d1);
        let h = d1.dot(&d1) + diff.dot(&d2);
        if h > 1e-300 { theta - g / h } else { theta }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Arc;
    use std::f64::consts::{FRAC_PI_2, PI, TAU};

    fn helix() -> Curve {
        // Two full turns of radius 3 about +Z rising 4 mm: length sqrt((3·4π)² + 4²).
        Curve::from_path(&Path::Arc(Arc {
            start: Vec3::new(3.0, 0.0, 0.0),
            end: Vec3::new(3.0, 0.0, 4.0),
            center: Vec3::zeros(),
            axis: Vec3::z(),
            sweep_rad: 2.0 * TAU,
        }))
    }

    #[test]
    fn helix_length_points_and_derivatives() {
        let c = helix();
        let len = ((3.0 * 2.0 * TAU).powi(2) + 16.0f64).sqrt();
        assert!((c.length() - len).abs() < 1e-12);
        // A quarter turn is an eighth of the length: (0, 3, 0.5).
        let p = c.point_at(len / 8.0);
        assert!((p - Vec3::new(0.0, 3.0, 0.5)).norm() < 1e-12);
        let e = c.eval(len / 8.0);
        assert!((e.tangent.norm() - 1.0).abs() < 1e-12);
        // Curvature of a helix: r / (r² + pitch²), pitch = rise per radian.
        let pitch = 4.0 / (2.0 * TAU);
        let k = 3.0 / (9.0 + pitch * pitch);
        assert!((e.curvature - Vec3::new(0.0, -k, 0.0)).norm() < 1e-12);
        // The exact end point, not a recomputed one.
        assert_eq!(c.point_at(len), Vec3::new(3.0, 0.0, 4.0));
    }

    #[test]
    fn distances() {
        let c = helix();
        // On the axis at height 1: distance is the radius.
        assert!((c.distance_to(&Vec3::new(0.0, 0.0, 1.0)) - 3.0).abs() < 1e-9);
        // Outside at (5, 0, 2): the helix passes (3, 0, 2) after one turn.
        assert!((c.distance_to(&Vec3::new(5.0, 0.0, 2.0)) - 2.0).abs() < 1e-9);
        // Clockwise quarter arc from (1, 0) to (0, -1); (0, 1) is nearest to the start.
        let a = Curve::from_path(&Path::Arc(Arc {
            start: Vec3::new(1.0, 0.0, 0.0),
            end: Vec3::new(0.0, -1.0, 0.0),
            center: Vec3::zeros(),
            axis: Vec3::z(),
            sweep_rad: -FRAC_PI_2,
        }));
        assert!((a.distance_to(&Vec3::new(0.0, 1.0, 0.0)) - 2f64.sqrt()).abs() < 1e-12);
        assert!((a.distance_to(&Vec3::new(2.0, -2.0, 0.0)) - (8f64.sqrt() - 1.0)).abs() < 1e-12);
        let l = Curve::line(Vec3::zeros(), Vec3::new(2.0, 0.0, 0.0));
        assert_eq!(l.distance_to(&Vec3::new(1.0, 1.0, 0.0)), 1.0);
        assert_eq!(l.distance_to(&Vec3::new(3.0, 0.0, 0.0)), 1.0);
        assert!((Curve::line(Vec3::zeros(), Vec3::zeros()).length()).abs() < 1e-300);
        let _ = PI;
    }

    fn helix_of(c: &Curve) -> Helix {
        match c {
            Curve::Helix(h) => *h,
            other => panic!("not a helix: {other:?}"),
        }
    }

    #[test]
    fn huge_radius_keeps_the_start_and_the_circle() {
        // 10 mm of a circle of radius r about (0, r, 0), counter-clockwise from the origin
        // (towards +X). A point (x, y) is on it iff x² + y² − 2ry = 0, and near the origin
        // its distance from it is |x² + y² − 2ry| / 2r: computed from the small
        // coordinates, with no cancellation of numbers of the radius's size. A circle
        // evaluated about its centre would be off by a unit in the last place of r
        // (1.2e-4 mm at 1e12).
        for r in [1e4f64, 1e8, 1e10, 1e12] {
            let theta = 10.0 / r;
            let half = (0.5 * theta).sin();
            let end = Vec3::new(r * theta.sin(), 2.0 * r * half * half, 0.0);
            let c = Curve::from_path(&Path::Arc(Arc {
                start: Vec3::zeros(),
                end,
                center: Vec3::new(0.0, r, 0.0),
                axis: Vec3::z(),
                sweep_rad: theta,
            }));
            let len = c.length();
            assert!((len - 10.0).abs() < 1e-9, "r {r}: length {len}");
            assert_eq!(c.point_at(0.0), Vec3::zeros());
            assert_eq!(c.point_at(len), end);
            let mut prev = Vec3::zeros();
            for k in 1..=1000 {
                let s = len * k as f64 / 1000.0;
                let p = c.point_at(s);
                let off = (p.x * p.x + p.y * p.y - 2.0 * r * p.y) / (2.0 * r);
                assert!(off.abs() < 1e-12, "r {r}, s {s}: {off:e} mm off the circle");
                let x = r * (theta * s / len).sin();
                assert!((p.x - x).abs() < 1e-12, "r {r}, s {s}: x {} vs {x}", p.x);
                assert!(
                    (p - prev).norm() <= len / 1000.0 + 1e-12,
                    "r {r}, s {s}: a jump"
                );
                prev = p;
            }
            // 1 µm inside the circle at its middle (towards the centre): 1 µm from it.
            let mid = c.point_at(5.0);
            let inward = (Vec3::new(0.0, r, 0.0) - mid).normalize();
            let d = c.distance_to(&(mid + inward * 1e-6));
            assert!((d - 1e-6).abs() < 1e-12, "r {r}: distance {d:e}");
            // Continuous with both ends.
            assert!(c.point_at(1e-9).norm() < 1.1e-9);
            assert!((c.point_at(len - 1e-9) - end).norm() < 1.1e-9);
        }
    }

    #[test]
    fn drift_ends_the_curve_at_its_end_without_a_jump() {
        // A quarter circle of radius 10 about the origin rising 2 mm, whose end is moved
        // by delta (in the plane): the curve is the helix plus delta · θ / sweep.
        let delta = Vec3::new(3e-7, -4e-7, 0.0);
        let sweep = FRAC_PI_2;
        let end = Vec3::new(0.0, 10.0, 2.0) + delta;
        let c = Curve::from_path(&Path::Arc(Arc {
            start: Vec3::new(10.0, 0.0, 0.0),
            end,
            center: Vec3::zeros(),
            axis: Vec3::z(),
            sweep_rad: sweep,
        }));
        let h = helix_of(&c);
        // (cos(π/2) of the circle is 6e-17, not 0: rounding on top of delta.)
        assert!((h.drift_mm_per_rad - delta / sweep).norm() < 1e-14);
        let helix_len = ((10.0 * sweep).powi(2) + 4.0f64).sqrt();
        assert!((c.length() - (helix_len + 5e-7)).abs() < 1e-12);
        let len = c.length();
        let n = 10_000;
        let mut prev = c.point_at(0.0);
        for k in 1..=n {
            let s = len * k as f64 / n as f64;
            let th = sweep * s / len;
            let exact = Vec3::new(10.0 * th.cos(), 10.0 * th.sin(), 2.0 * th / sweep);
            let p = c.point_at(s);
            if k < n {
                assert!((p - (exact + delta * (th / sweep))).norm() < 1e-12, "s {s}");
            } else {
                assert_eq!(p, end);
            }
            // |dp/ds| <= 1: no step longer than its arc length, the last one included.
            assert!((p - prev).norm() <= len / n as f64 * (1.0 + 1e-9), "s {s}");
            prev = p;
        }
        // The tangent is dp/ds, drift included, and never longer than 1.
        for k in 1..100 {
            let s = len * k as f64 / 100.0;
            let e = c.eval(s);
            let eps = 1e-5;
            let fd = (c.point_at(s + eps) - c.point_at(s - eps)) / (2.0 * eps);
            assert!((e.tangent - fd).norm() < 1e-8, "s {s}");
            assert!(e.tangent.norm() <= 1.0 + 1e-15);
        }
    }

    #[test]
    fn trimmed_pieces_evaluate_the_same_points() {
        // Two and a half turns with rise and a drift, cut in three pieces.
        let whole = Curve::from_path(&Path::Arc(Arc {
            start: Vec3::new(3.0, 0.0, 0.0),
            end: Vec3::new(-3.0, 2e-7, 5.0),
            center: Vec3::zeros(),
            axis: Vec3::z(),
            sweep_rad: 5.0 * PI,
        }));
        assert!(helix_of(&whole).drift_mm_per_rad.norm() > 1e-8);
        let len = whole.length();
        let cuts = [0.0, 0.3 * len, 0.71 * len, len];
        for w in cuts.windows(2) {
            let piece = whole.trimmed(w[0], w[1]);
            assert_eq!(piece.start(), whole.point_at(w[0]));
            assert_eq!(piece.end(), whole.point_at(w[1]));
            assert!((piece.length() - (w[1] - w[0])).abs() < 1e-12);
            let ph = helix_of(&piece);
            assert_eq!(ph.drift_mm_per_rad, helix_of(&whole).drift_mm_per_rad);
            for k in 0..=500 {
                let t = piece.length() * k as f64 / 500.0;
                let d = (piece.point_at(t) - whole.point_at(w[0] + t)).norm();
                assert!(d < 1e-12, "piece at {}, t {t}: {d:e}", w[0]);
                let (a, b) = (piece.eval(t), whole.eval(w[0] + t));
                assert!((a.tangent - b.tangent).norm() < 1e-12);
                assert!((a.curvature - b.curvature).norm() < 1e-12);
            }
        }
    }

    #[test]
    fn full_circles_close_exactly() {
        for turns in [1.0, 2.0, 50.0] {
            for dir in [1.0, -1.0] {
                let start = Vec3::new(3.0, 0.0, 1.0);
                let c = Curve::from_path(&Path::Arc(Arc {
                    start,
                    end: start,
                    center: Vec3::new(0.0, 0.0, 1.0),
                    axis: Vec3::z(),
                    sweep_rad: dir * TAU * turns,
                }));
                let len = c.length();
                assert!((len - 3.0 * TAU * turns).abs() < 1e-9 * turns);
                assert!(helix_of(&c).drift_mm_per_rad.norm() < 1e-14);
                assert_eq!(c.point_at(len), start);
                assert!((c.point_at(len - 1e-9) - start).norm() < 1.1e-9);
                for k in 0..=1000 {
                    let p = c.point_at(len * k as f64 / 1000.0);
                    let r = (p - Vec3::new(0.0, 0.0, 1.0)).norm();
                    assert!((r - 3.0).abs() < 1e-12, "turns {turns}: radius {r}");
                }
            }
        }
    }

    #[test]
    fn a_sweep_lost_in_rounding_is_the_straight_way() {
        // 1e-320 rad of a unit circle ends 1e-320 mm from the start; whatever is left to
        // the end cannot be spread over that angle (it would overflow): a line.
        let c = Curve::from_path(&Path::Arc(Arc {
            start: Vec3::new(1.0, 0.0, 0.0),
            end: Vec3::new(1.0, 1e-7, 0.0),
            center: Vec3::zeros(),
            axis: Vec3::z(),
            sweep_rad: 1e-320,
        }));
        assert!(matches!(c, Curve::Line { .. }), "{c:?}");
        assert_eq!(c.length(), 1e-7);
    }
}
