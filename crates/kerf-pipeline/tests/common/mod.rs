//! Helpers shared by the motion tests: machines and programs built by hand.
#![allow(dead_code)]

use kerf_geom::{Arc, CornerMode, Line, Move, Path, Vec3};
use kerf_motion::{MachineLimits, Setpoint};
use kerf_pipeline::{RunOptions, Summary, run};

/// A mill with the same limits on X, Y, Z.
#[allow(unused_imports)]
pub use kerf_testkit::machines::mill_with as mill;

pub fn blend() -> CornerMode {
    CornerMode::Blend {
        tolerance_mm: None,
        naive_cam_mm: None,
    }
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
        if k.is_multiple_of(n) {
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

/// xorshift64*: a tiny deterministic generator, so the tests need no extra dependency.
pub struct Rng(pub u64);

impl Rng {
    /// The generator for a soak's seed number (`KERF_SEED=3` and the like): spread over
    /// the state space, never zero.
    pub fn seeded(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1)
    }
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    pub fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    /// Log-uniform in [lo, hi].
    pub fn log(&mut self, lo: f64, hi: f64) -> f64 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.unit()).exp()
    }
    pub fn pick(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    pub fn sign(&mut self) -> f64 {
        if self.pick(2) == 0 { 1.0 } else { -1.0 }
    }
}

/// A random unit vector (rejection sampling in the unit ball).
pub fn unit_vec(rng: &mut Rng) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        );
        if v.norm() > 0.2 && v.norm() < 1.0 {
            return v.normalize();
        }
    }
}

/// A random plane for a circle: its axis (Z half the time, else Y or any direction) and
/// two unit vectors `u`, `v` spanning it.
pub fn plane_basis(rng: &mut Rng) -> (Vec3, Vec3, Vec3) {
    let axis = match rng.pick(4) {
        0 | 1 => Vec3::z(),
        2 => Vec3::y(),
        _ => unit_vec(rng),
    };
    let w = unit_vec(rng);
    let w = w - axis * w.dot(&axis);
    let u = if w.norm() < 1e-3 {
        axis.cross(&Vec3::x()).normalize()
    } else {
        w.normalize()
    };
    (axis, u, axis.cross(&u))
}

/// A number from the environment (the soak knobs of the property tests), if set.
pub fn env_number<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|s| s.parse().ok())
}

/// Every limit of every configured axis (A, B, C included), by finite differences of the
/// setpoint positions at the period, within 1 % plus the rounding of the positions
/// themselves (8 ulp of the largest coordinate, divided by the period's power). Panics
/// naming `name`, the axis and the row of the window's last position.
pub fn check_axis_limits(name: &str, positions: &[[f64; 6]], limits: &MachineLimits) {
    let t = limits.period_s;
    let big = positions
        .iter()
        .flatten()
        .fold(1.0_f64, |m, x| m.max(x.abs()));
    let noise = 8.0 * f64::EPSILON * big;
    for i in 0..6 {
        let Some(l) = limits.axes[i] else { continue };
        for (k, w) in positions.windows(4).enumerate() {
            let p = |j: usize| w[j][i];
            let v = (p(3) - p(2)).abs() / t;
            let a = (p(3) - 2.0 * p(2) + p(1)).abs() / (t * t);
            let j = (p(3) - 3.0 * p(2) + 3.0 * p(1) - p(0)).abs() / (t * t * t);
            let ratios = [
                v / (l.velocity_units_s * 1.01 + noise / t),
                a / (l.acceleration_units_s2 * 1.01 + 2.0 * noise / (t * t)),
                j / (l.jerk_units_s3 * 1.01 + 4.0 * noise / (t * t * t)),
            ];
            assert!(
                ratios.iter().all(|&r| r <= 1.0),
                "{name}: axis {i} at row {}: v/a/j {ratios:?} of the limits (+1 %)",
                k + 3
            );
        }
    }
}

/// Runs `moves` on `limits` with the default options, handing each setpoint to `sink`,
/// and checks what a program must always give, naming `name`: every axis limit from the
/// positions ([`check_axis_limits`]), the path within the tolerance, and the end exactly
/// on the program's end. Returns the run's summary.
pub fn run_checked(
    name: &str,
    moves: &[Move],
    limits: &MachineLimits,
    mut sink: impl FnMut(&Setpoint),
) -> Summary {
    let mut positions = Vec::new();
    let s = run(
        moves.iter().copied(),
        limits,
        &RunOptions::default(),
        |_, sp| {
            positions.push(sp.position);
            sink(sp);
        },
    )
    .unwrap_or_else(|e| panic!("{name}: {e}"));
    check_axis_limits(name, &positions, limits);
    assert!(
        s.max_deviation_mm <= limits.tolerance_mm * 1.0001,
        "{name}: deviation {} mm",
        s.max_deviation_mm
    );
    let end = moves.last().unwrap().path.end();
    assert_eq!(s.last.position[..3], [end.x, end.y, end.z], "{name}: end");
    s
}

/// Asserts that the first `axes` axes stayed within 1 % of their limits, by the run's
/// summary ([`Summary::fractions`]).
pub fn assert_within_limits(s: &Summary, limits: &MachineLimits, axes: usize) {
    for i in 0..axes {
        for f in s.fractions(limits, i).unwrap() {
            assert!(f <= 1.01, "axis {i}: {f}");
        }
    }
}
