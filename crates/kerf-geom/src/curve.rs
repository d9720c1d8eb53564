//! Evaluable curves: a [`Path`] with its derived data precomputed, so that the real-time
//! loop evaluates a point at arc length `s` with a handful of flops and no allocation.
//!
//! Every curve is parameterised by arc length `s` in `[0, length]`. Evaluation at
//! `s >= length` returns the stored end point exactly (not a recomputed approximation), so
//! a motion that stops at the end of a curve stops exactly at the programmed end.

pub use crate::transition::Transition;
use crate::{Path, Vec3};

/// A point on a curve with its first two derivatives with respect to arc length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurvePoint {
    /// Position, mm.
    pub point: Vec3,
    /// Unit tangent `dp/ds`.
    pub tangent: Vec3,
    /// Curvature vector `d²p/ds²`, 1/mm (points to the centre; zero on lines).
    pub curvature: Vec3,
}

/// A circular arc or helix with its frame precomputed.
///
/// `p(s) = center + r (cos θ e1 + sin θ e2) + axis · rise · s / length` with
/// `θ = sweep · s / length`, so `|dp/ds| = 1` when `length = sqrt((r·sweep)² + rise²)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Helix {
    /// Start point, mm.
    pub start: Vec3,
    /// End point, mm (returned exactly at `s >= length`).
    pub end: Vec3,
    /// Centre of the circle in the plane of `start`, mm.
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
    /// Arc length, mm.
    pub length_mm: f64,
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
                let length_mm = ((radius_mm * a.sweep_rad).powi(2) + rise_mm * rise_mm).sqrt();
                Curve::Helix(Helix {
                    start: a.start,
                    end: a.end,
                    center: a.start - radial,
                    e1,
                    e2,
                    axis,
                    radius_mm,
                    sweep_rad: a.sweep_rad,
                    rise_mm,
                    length_mm,
                })
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
                    h.point_at_angle(h.sweep_rad * s / h.length_mm)
                }
            }
            Curve::Transition(t) => t.point_at(s),
        }
    }

    /// Point, unit tangent and curvature vector at arc length `s` (clamped).
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
                let tangent = (h.e2 * cos - h.e1 * sin) * (h.radius_mm * per_mm)
                    + h.axis * (h.rise_mm / h.length_mm);
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
                let th0 = h.sweep_rad * s0 / h.length_mm;
                let frac = (s1 - s0) / h.length_mm;
                let (sin, cos) = th0.sin_cos();
                let e1 = h.e1 * cos + h.e2 * sin;
                Curve::Helix(Helix {
                    start: a,
                    end: b,
                    center: h.center + h.axis * (h.rise_mm * s0 / h.length_mm),
                    e1,
                    e2: h.axis.cross(&e1),
                    axis: h.axis,
                    radius_mm: h.radius_mm,
                    sweep_rad: h.sweep_rad * frac,
                    rise_mm: h.rise_mm * frac,
                    length_mm: s1 - s0,
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
    /// Point at swept angle `theta` from the start (signed like `sweep_rad`).
    #[inline]
    pub fn point_at_angle(&self, theta: f64) -> Vec3 {
        let (sin, cos) = theta.sin_cos();
        self.center
            + (self.e1 * cos + self.e2 * sin) * self.radius_mm
            + self.axis * (self.rise_mm * theta / self.sweep_rad)
    }

    /// Curvature magnitude, 1/mm.
    pub fn curvature(&self) -> f64 {
        let per_mm = self.sweep_rad / self.length_mm;
        self.radius_mm * per_mm * per_mm
    }

    /// Shortest distance from `p` to the helix. A planar arc is solved exactly: the nearest
    /// point is at the angle of `p` projected on the plane if the arc covers it, else an end
    /// point. On a helix the candidates are that angle on the turns near `p`'s height,
    /// refined by Newton steps on the squared distance, and the end points.
    pub fn distance_to(&self, p: &Vec3) -> f64 {
        let mut best = (p - self.start).norm().min((p - self.end).norm());
        let rel = p - self.center;
        let x = rel.dot(&self.e1);
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
                let radial = (x * x + y * y).sqrt() - self.radius_mm;
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
                theta = self.newton(p, theta).clamp(lo, hi);
            }
            best = best.min((p - self.point_at_angle(theta)).norm());
            k += 1.0;
        }
        best
    }

    /// One Newton step on `f(θ) = |p - c(θ)|²` about `theta`.
    fn newton(&self, p: &Vec3, theta: f64) -> f64 {
        let (sin, cos) = theta.sin_cos();
        let pitch = self.rise_mm / self.sweep_rad;
        let c = self.point_at_angle(theta);
        let d1 = (self.e2 * cos - self.e1 * sin) * self.radius_mm + self.axis * pitch;
        let d2 = -(self.e1 * cos + self.e2 * sin) * self.radius_mm;
        let diff = c - p;
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
}
