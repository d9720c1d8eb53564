//! Helpers shared by the motion tests: machines and programs built by hand.
#![allow(dead_code)]

use kerf_geom::{Arc, CornerMode, Line, Move, Path, Vec3};
use kerf_motion::{AxisLimits, MachineLimits};

/// A mill with the same limits on X, Y, Z.
pub fn mill(v: f64, a: f64, j: f64, tol: f64) -> MachineLimits {
    let l = AxisLimits {
        velocity: v,
        acceleration: a,
        jerk: j,
    };
    MachineLimits {
        axes: [Some(l), Some(l), Some(l), None, None, None],
        period_s: 0.001,
        tolerance_mm: tol,
    }
}

pub fn blend() -> CornerMode {
    CornerMode::Blend { tolerance_mm: None }
}

pub fn line(line_no: u32, a: Vec3, b: Vec3, feed_mm_min: f64) -> Move {
    Move {
        line: line_no,
        rapid: false,
        path: Path::Line(Line { start: a, end: b }),
        feed_mm_min: Some(feed_mm_min),
        abc_deg: None,
        corner: blend(),
    }
}

pub fn arc(line_no: u32, start: Vec3, center: Vec3, sweep: f64, rise: f64, feed: f64) -> Move {
    let r = start - center;
    let (s, c) = sweep.sin_cos();
    let end = center + Vec3::new(r.x * c - r.y * s, r.x * s + r.y * c, 0.0) + Vec3::z() * rise;
    Move {
        line: line_no,
        rapid: false,
        path: Path::Arc(Arc {
            start,
            end,
            center,
            axis: Vec3::z(),
            sweep_rad: sweep,
        }),
        feed_mm_min: Some(feed),
        abc_deg: None,
        corner: blend(),
    }
}

/// The circle of radius `r` made of `n` lines, starting and ending at the origin (centre
/// at (r, 0)), counter-clockwise.
pub fn polygon_circle(r: f64, n: usize, feed: f64) -> Vec<Move> {
    let center = Vec3::new(r, 0.0, 0.0);
    let pt = |k: usize| {
        let th = std::f64::consts::PI + std::f64::consts::TAU * (k % n) as f64 / n as f64;
        if k % n == 0 {
            Vec3::zeros()
        } else {
            center + Vec3::new(r * th.cos(), r * th.sin(), 0.0)
        }
    };
    (0..n)
        .map(|k| line(k as u32 + 1, pt(k), pt(k + 1), feed))
        .collect()
}

/// An arc or helix about any unit `axis`; `radial` is the centre-to-start vector (must be
/// perpendicular to `axis`).
pub fn arc_about(
    line_no: u32,
    start: Vec3,
    radial: Vec3,
    axis: Vec3,
    sweep: f64,
    rise: f64,
    feed: f64,
) -> Move {
    let center = start - radial;
    let e2 = axis.cross(&radial);
    let (s, c) = sweep.sin_cos();
    let end = center + radial * c + e2 * s + axis * rise;
    Move {
        line: line_no,
        rapid: false,
        path: Path::Arc(Arc {
            start,
            end,
            center,
            axis,
            sweep_rad: sweep,
        }),
        feed_mm_min: Some(feed),
        abc_deg: None,
        corner: blend(),
    }
}
