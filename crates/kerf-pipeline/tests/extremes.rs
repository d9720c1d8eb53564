//! Extreme machines and the programs that reach their corners.
//!
//! `properties.rs` sweeps machines over a middle band of the accepted range with programs
//! built for a mill. Machines and programs that band never reaches stress the seams
//! between planned pieces hardest, where an axis's jerk or acceleration limit is easiest
//! to break. This file draws from the whole range the configuration accepts and
//! writes every case as G-code text, read back by `kerf_gcode::Interpreter` exactly as
//! `kerf sim` reads it, so that a failure prints a reproducer that runs unchanged.
//!
//! # Machines
//!
//! X, Y and Z, each axis drawn on its own from the validator's ranges (velocity 0.001 to
//! 100,000 mm/s, acceleration 0.01 to 1e8 mm/s², jerk 1 to 1e12 mm/s³, rounded to four
//! significant digits), biased towards the corners: acceleration above jerk × 1 s (a/j up
//! to 100 s), jerk far above acceleration, ordinary axes; the three axes alike (as in the
//! reported case A), independent, or around one axis with each limit up to 1000× apart.
//! The period is a whole number of microseconds (the configuration's `period_us`), 50 to
//! 10,000 µs log-uniform, half of the cases at 50 to 250 µs; the tolerance 1 µm to 1 mm;
//! the feed override 1 to 200 % (100 % in a third of the cases).
//!
//! # Programs
//!
//! Four generators, written in G17, G18 and G19 (LinuxCNC G-code, centre format arcs):
//! - mixed: lines of any length and direction, tangent continuations, arcs and helices
//!   (tangent to the move before or not, several turns), whole circles, rapids, tiny lines,
//!   short zig-zags, `G64`, `G64 P` and `G61` changes;
//! - circles and helices meeting each other: circle into helix, helix into circle, tangent
//!   and not, radii from 0.01 mm against tolerances up to 1 mm (case B);
//! - dense 3D polylines as CAM writes them: short segments with small turns along a curve
//!   with waves and a climb, vertices rounded to 2 to 6 decimals, some with noise;
//! - short zig-zags with tight turns after an approach line, rounded to 3 to 5 decimals
//!   (case A).
//!
//! Every program is scaled to its machine: the feed is 1 % to 2× of the slowest axis's
//! velocity (or of another axis's); the time budget is that of its moves just reaching the
//! feed, times 0.2 to 5, within 1,000 to 30,000 periods; the geometry is drawn for that
//! budget, then shrunk to it by a rough time estimate (a tenth of the slowest axis's
//! acceleration and jerk, corners and curves slowed), down to features of
//! [`MIN_FEATURE_MM`], then moves are cut off its end and at last the feed is raised. So a
//! case runs a few thousand cycles, tens of thousands at most; one that runs out of its
//! [`MAX_CYCLES`] fails.
//!
//! # The check
//!
//! As `check_swept` in `properties.rs`: every axis within 1 % of its velocity, acceleration
//! and jerk measured by finite differences of the setpoint positions at the period (from
//! rest before the first setpoint, plus the same rounding allowance), every setpoint within
//! the tolerance of the path (the largest `G64 P` of the program or the machine's), the
//! exact end point, no solver fallback, and the XYZ speed per period within the feed times
//! the override. A failing case prints its seed and number, the check that failed, and a
//! reproducer (the program as G-code, the machine as a `kerf` TOML, the `kerf sim` command),
//! then a minimised one (moves dropped, limits rounded, while the same check still fails).
//!
//! # Running it
//!
//! Every case's generator is derived from (seed, case) alone, so a case is the same
//! whatever else runs, on any number of threads. Environment:
//! - `KERF_EXTREME_SEED` (default 24) and `KERF_EXTREME_CASES` (default 100);
//! - `KERF_EXTREME_ONLY=N`: run case N of the seed alone;
//! - `KERF_EXTREME_THREADS` (default 1): cases split over that many threads by index;
//! - `KERF_EXTREME_MINIMISE_S` (default 20): seconds the minimiser may spend on one failing
//!   case (0: no minimising).
//!
//! A soak on both cores:
//! `KERF_EXTREME_SEED=1 KERF_EXTREME_CASES=20000 KERF_EXTREME_THREADS=2 cargo test --release
//! -p kerf-pipeline --test extremes extreme_machines -- --nocapture`; a run ends with a
//! summary line (cases, cycles, the worst share of each limit seen, the escapes). Escapes
//! go into [`ESCAPES`] (seed, cases) and their minimised programs into [`FIXED`].

mod common;

use std::f64::consts::{PI, TAU};
use std::fmt::Write as _;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::{Duration, Instant};

use common::{Rng, env_number, unit_vec};
use kerf_gcode::{Dialect, Interpreter, Item, Settings};
use kerf_geom::{CornerMode, Move, Vec3};
use kerf_motion::{AxisLimits, MachineLimits};
use kerf_pipeline::{RunOptions, run};

/// Cycles a case may run. The programs are scaled to at most 30,000 periods by a rough
/// estimate that is slow on purpose; a case that needs 13 times that has stalled or
/// crawls, and fails.
const MAX_CYCLES: u64 = 400_000;

/// The validator's ranges (`config/kerf.toml`).
const V_RANGE: (f64, f64) = (1e-3, 1e5);
const A_RANGE: (f64, f64) = (1e-2, 1e8);
const J_RANGE: (f64, f64) = (1.0, 1e12);
const PERIOD_US: (u32, u32) = (50, 10_000);

/// Minimising a failure stops after this many runs (or its time, whichever comes first).
const MINIMISE_RUNS: usize = 400;

/// The shortest line and the smallest radius a program gets, mm: 0.1 µm, a hundred times
/// the motion core's resolution (`kerf_motion::COAST_BELOW_MM` and `CONTINUITY_MM`, 1 nm:
/// shorter sections are coasted through, smaller gaps are continuous) and far above the
/// front end's (two points within 1 pm are one). A program scaled to a sluggish machine
/// keeps its features at least this long and loses moves at its end instead.
const MIN_FEATURE_MM: f64 = 1e-4;

const AXIS: [&str; 3] = ["X", "Y", "Z"];

// ---------------------------------------------------------------------------------------
// Machines

/// One axis's limits, mm/s, mm/s², mm/s³.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Axis {
    v: f64,
    a: f64,
    j: f64,
}

impl Axis {
    /// Limits clamped to the accepted ranges and rounded to four significant digits.
    fn new(v: f64, a: f64, j: f64) -> Axis {
        let fit = |x: f64, (lo, hi): (f64, f64)| round_sig(x.clamp(lo, hi), 4).clamp(lo, hi);
        Axis {
            v: fit(v, V_RANGE),
            a: fit(a, A_RANGE),
            j: fit(j, J_RANGE),
        }
    }

    fn get(&self, q: usize) -> f64 {
        [self.v, self.a, self.j][q]
    }

    fn set(&mut self, q: usize, x: f64) {
        match q {
            0 => self.v = x,
            1 => self.a = x,
            _ => self.j = x,
        }
    }
}

/// A machine configuration and the feed override of its run.
#[derive(Clone, Debug, PartialEq)]
struct Machine {
    period_us: u32,
    tolerance_mm: f64,
    axes: [Axis; 3],
    /// `kerf sim --override`, percent.
    override_pct: f64,
}

impl Machine {
    fn period_s(&self) -> f64 {
        // As `kerf_config::machine_limits` computes it.
        f64::from(self.period_us) * 1e-6
    }

    fn feed_override(&self) -> f64 {
        // As `kerf sim` computes it from `--override`.
        self.override_pct / 100.0
    }

    fn limits(&self) -> MachineLimits {
        let ax = |a: Axis| {
            Some(AxisLimits {
                velocity_units_s: a.v,
                acceleration_units_s2: a.a,
                jerk_units_s3: a.j,
            })
        };
        MachineLimits {
            axes: [
                ax(self.axes[0]),
                ax(self.axes[1]),
                ax(self.axes[2]),
                None,
                None,
                None,
            ],
            period_s: self.period_s(),
            tolerance_mm: self.tolerance_mm,
        }
    }

    /// The lowest of each limit over the axes.
    fn slowest(&self) -> Axis {
        let low = |q: usize| {
            self.axes
                .iter()
                .map(|a| a.get(q))
                .fold(f64::INFINITY, f64::min)
        };
        Axis {
            v: low(0),
            a: low(1),
            j: low(2),
        }
    }
}

/// One axis from anywhere in the accepted range, biased towards its corners.
fn random_axis(rng: &mut Rng) -> Axis {
    let v = if rng.pick(3) == 0 {
        rng.log(V_RANGE.0, V_RANGE.1)
    } else {
        rng.log(1.0, 1e4)
    };
    let (a, j) = match rng.pick(6) {
        // Anywhere.
        0 => (rng.log(A_RANGE.0, A_RANGE.1), rng.log(J_RANGE.0, J_RANGE.1)),
        // Acceleration above jerk × 1 s: a/j from 1 to 100 s.
        1 | 2 => {
            let j = rng.log(1.0, 1e9);
            (j * rng.log(1.0, 100.0), j)
        }
        // Jerk far above acceleration.
        3 => {
            let a = rng.log(1e-2, 1e6);
            (a, a * rng.log(10.0, 1e5))
        }
        // An ordinary axis.
        _ => (rng.log(100.0, 1e6), rng.log(1e3, 1e9)),
    };
    Axis::new(v, a, j)
}

fn random_machine(rng: &mut Rng) -> Machine {
    let base = random_axis(rng);
    let axes = match rng.pick(4) {
        // Every axis alike (case A).
        0 => [base; 3],
        // Each on its own.
        1 => [base, random_axis(rng), random_axis(rng)],
        // Around one axis, each limit up to 1000× apart.
        _ => {
            let mut axes = [base; 3];
            for ax in axes.iter_mut().skip(1) {
                let mut f = || {
                    if rng.pick(3) == 0 {
                        1.0
                    } else {
                        10f64.powf(rng.range(-3.0, 3.0))
                    }
                };
                *ax = Axis::new(base.v * f(), base.a * f(), base.j * f());
            }
            axes.swap(0, rng.pick(3));
            axes
        }
    };
    let period = if rng.pick(2) == 0 {
        rng.log(50.0, 250.0)
    } else {
        rng.log(50.0, 10_000.0)
    };
    let period_us = (period.round() as u32).clamp(PERIOD_US.0, PERIOD_US.1);
    let tolerance_mm = round_sig(rng.log(1e-3, 1.0), 3);
    let override_pct = if rng.pick(3) == 0 {
        100.0
    } else {
        ((rng.log(1.0, 200.0) * 10.0).round() / 10.0).clamp(1.0, 200.0)
    };
    Machine {
        period_us,
        tolerance_mm,
        axes,
        override_pct,
    }
}

// ---------------------------------------------------------------------------------------
// Programs

/// How a move joins the next: `G64`, `G64 P`, `G61`.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Corner {
    Blend,
    Tol(f64),
    Exact,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Plane {
    Xy,
    Zx,
    Yz,
}

impl Plane {
    /// The axis about which `G3` turns counter-clockwise.
    fn normal(self) -> Vec3 {
        match self {
            Plane::Xy => Vec3::z(),
            Plane::Zx => Vec3::y(),
            Plane::Yz => Vec3::x(),
        }
    }

    fn code(self) -> &'static str {
        match self {
            Plane::Xy => "G17",
            Plane::Zx => "G18",
            Plane::Yz => "G19",
        }
    }

    /// The centre offset words of the plane and the coordinate each takes.
    fn offsets(self) -> [(char, usize); 2] {
        match self {
            Plane::Xy => [('I', 0), ('J', 1)],
            Plane::Zx => [('I', 0), ('K', 2)],
            Plane::Yz => [('J', 1), ('K', 2)],
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Shape {
    Rapid,
    Line,
    /// A centre-format arc or helix (`P` turns); the centre is absolute.
    Arc {
        plane: Plane,
        ccw: bool,
        centre: Vec3,
        turns: u32,
    },
}

/// One block: a move to an absolute end point from the end of the block before (the
/// origin for the first).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Block {
    shape: Shape,
    end: Vec3,
    feed_mm_min: f64,
    corner: Corner,
}

#[derive(Clone, Debug, PartialEq)]
struct Program {
    blocks: Vec<Block>,
    /// The decimals the line vertices are rounded to (CAM-like programs, lines only).
    decimals: Option<i32>,
}

/// Rounds to `digits` significant digits (the result is the double nearest the decimal).
fn round_sig(x: f64, digits: i32) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let e = digits - 1 - x.abs().log10().floor() as i32;
    if e >= 0 {
        let p = 10f64.powi(e);
        (x * p).round() / p
    } else {
        let p = 10f64.powi(-e);
        (x / p).round() * p
    }
}

fn round_dec(x: f64, decimals: i32) -> f64 {
    let p = 10f64.powi(decimals);
    (x * p).round() / p
}

fn in_plane(v: Vec3, n: Vec3) -> Vec3 {
    v - n * n.dot(&v)
}

/// An arc as the interpreter will read it.
struct ArcGeom {
    n: Vec3,
    /// +1 counter-clockwise about `n`, -1 clockwise.
    sense: f64,
    r: f64,
    /// Whole sweep, positive, turns included.
    sweep: f64,
    /// Travel along `n`.
    rise: f64,
    radial0: Vec3,
    radial1: Vec3,
}

impl ArcGeom {
    fn new(start: Vec3, end: Vec3, plane: Plane, ccw: bool, centre: Vec3, turns: u32) -> ArcGeom {
        let n = plane.normal();
        let radial0 = in_plane(start - centre, n);
        let radial1 = in_plane(end - centre, n);
        let sense = if ccw { 1.0 } else { -1.0 };
        let mut phi = (sense * n.dot(&radial0.cross(&radial1))).atan2(radial0.dot(&radial1));
        if phi <= 1e-12 {
            // Negative: the other way round; zero: the end is the start, a whole turn.
            phi += TAU;
        }
        ArcGeom {
            n,
            sense,
            r: radial0.norm(),
            sweep: phi + TAU * f64::from(turns.max(1) - 1),
            rise: n.dot(&(end - start)),
            radial0,
            radial1,
        }
    }

    fn length(&self) -> f64 {
        (self.r * self.sweep).hypot(self.rise)
    }

    /// The unit tangent where the centre-to-point vector is `radial`.
    fn tangent(&self, radial: Vec3) -> Vec3 {
        (self.n.cross(&radial) * (self.sense * self.sweep) + self.n * self.rise).normalize()
    }
}

/// Builds a program move by move, keeping the position and direction.
struct Builder {
    blocks: Vec<Block>,
    p: Vec3,
    dir: Vec3,
    feed: f64,
    corner: Corner,
}

impl Builder {
    fn new(feed: f64, corner: Corner) -> Builder {
        Builder {
            blocks: Vec::new(),
            p: Vec3::zeros(),
            dir: Vec3::x(),
            feed,
            corner,
        }
    }

    fn straight(&mut self, shape: Shape, to: Vec3) {
        let d = to - self.p;
        if d.norm() < 0.1 * MIN_FEATURE_MM {
            return;
        }
        self.blocks.push(Block {
            shape,
            end: to,
            feed_mm_min: self.feed,
            corner: self.corner,
        });
        self.dir = d.normalize();
        self.p = to;
    }

    fn line(&mut self, to: Vec3) {
        self.straight(Shape::Line, to);
    }

    fn rapid(&mut self, to: Vec3) {
        self.straight(Shape::Rapid, to);
    }

    /// An arc from here with centre-to-start vector `radial` (in the plane), turning
    /// `theta` (0 to 2π; 2π is a whole circle) plus `turns - 1` whole turns, rising `rise`
    /// along the plane's normal.
    fn arc(&mut self, plane: Plane, ccw: bool, radial: Vec3, theta: f64, turns: u32, rise: f64) {
        let n = plane.normal();
        let centre = self.p - radial;
        let end = if theta >= TAU {
            // The end is the start exactly: a whole circle for the interpreter.
            self.p + n * rise
        } else {
            let e2 = n.cross(&radial) * if ccw { 1.0 } else { -1.0 };
            centre + radial * theta.cos() + e2 * theta.sin() + n * rise
        };
        if (end - self.p).norm() == 0.0 && theta < TAU {
            return;
        }
        let shape = Shape::Arc {
            plane,
            ccw,
            centre,
            turns,
        };
        self.blocks.push(Block {
            shape,
            end,
            feed_mm_min: self.feed,
            corner: self.corner,
        });
        let g = ArcGeom::new(self.p, end, plane, ccw, centre, turns);
        self.dir = g.tangent(g.radial1);
        self.p = end;
    }

    /// The centre-to-start vector of radius `r` that starts an arc tangent to the
    /// direction so far, if that direction is not along the plane's normal.
    fn tangent_radial(&self, plane: Plane, ccw: bool, r: f64) -> Option<Vec3> {
        let n = plane.normal();
        let t = in_plane(self.dir, n);
        (t.norm() > 1e-3).then(|| {
            let t = t.normalize();
            (if ccw { t.cross(&n) } else { n.cross(&t) }) * r
        })
    }
}

fn random_plane(rng: &mut Rng) -> Plane {
    [Plane::Xy, Plane::Zx, Plane::Yz][rng.pick(3)]
}

fn random_radial(rng: &mut Rng, plane: Plane, r: f64) -> Vec3 {
    loop {
        let v = in_plane(unit_vec(rng), plane.normal());
        if v.norm() > 0.1 {
            return v.normalize() * r;
        }
    }
}

/// A radius for a program of scale `u`: a third of them small, from 0.01 mm (or u/100).
fn random_radius(rng: &mut Rng, u: f64) -> f64 {
    let r = if rng.pick(3) == 0 {
        let small = 0.01f64.min(u * 0.01);
        rng.log(small, small * 10.0)
    } else {
        rng.log(u * 0.01, u)
    };
    r.max(MIN_FEATURE_MM)
}

/// A length from `lo` to `hi`, log-uniform, at least [`MIN_FEATURE_MM`].
fn random_len(rng: &mut Rng, lo: f64, hi: f64) -> f64 {
    rng.log(lo, hi).max(MIN_FEATURE_MM)
}

fn random_corner(rng: &mut Rng, u: f64) -> Corner {
    match rng.pick(8) {
        0 => Corner::Exact,
        1..=3 => Corner::Blend,
        _ => {
            let t = if rng.pick(2) == 0 {
                rng.log(1e-3, 1.0)
            } else {
                u * rng.log(1e-3, 1.0)
            };
            Corner::Tol(round_sig(t.max(1e-6), 3))
        }
    }
}

/// Short lines with tight turns, mostly in XY with a little Z.
fn zig_zag(rng: &mut Rng, b: &mut Builder, u: f64, n: usize) {
    let climb = if rng.pick(2) == 0 {
        0.0
    } else {
        rng.range(0.0, 0.3)
    };
    let mut heading = b.dir.y.atan2(b.dir.x);
    for _ in 0..n {
        let turn = match rng.pick(3) {
            0 => rng.range(2.5, PI),
            1 => rng.range(0.5, 2.5),
            _ => rng.range(0.0, 0.5),
        };
        heading += turn * rng.sign();
        let d = Vec3::new(heading.cos(), heading.sin(), climb * rng.range(-1.0, 1.0)).normalize();
        let len = random_len(rng, u * 1e-3, u * 0.05);
        b.line(b.p + d * len);
    }
}

/// Lines, tangent lines, arcs and helices in the three planes, circles, rapids, tiny
/// lines and zig-zags, with corner mode and feed changes.
fn gen_mixed(rng: &mut Rng, b: &mut Builder, u: f64, n: usize) {
    while b.blocks.len() < n {
        if rng.pick(6) == 0 {
            b.corner = random_corner(rng, u);
        }
        if rng.pick(6) == 0 {
            b.feed = round_sig(b.feed * rng.log(0.3, 3.0), 5);
        }
        match rng.pick(12) {
            0 | 1 => {
                let to = b.p + unit_vec(rng) * random_len(rng, u * 1e-3, u);
                b.line(to);
            }
            2 => {
                let to = b.p + b.dir * random_len(rng, u * 1e-3, u);
                b.line(to);
            }
            k @ (3..=6) => {
                let plane = random_plane(rng);
                let ccw = rng.pick(2) == 0;
                let r = random_radius(rng, u);
                let radial = if rng.pick(2) == 0 {
                    b.tangent_radial(plane, ccw, r)
                } else {
                    None
                }
                .unwrap_or_else(|| random_radial(rng, plane, r));
                let (theta, turns) = if k == 6 {
                    (TAU, 1 + rng.pick(3) as u32)
                } else {
                    (
                        rng.range(0.05, TAU - 0.05),
                        if rng.pick(8) == 0 { 2 } else { 1 },
                    )
                };
                let rise = if k >= 5 { rng.range(-u, u) } else { 0.0 };
                b.arc(plane, ccw, radial, theta, turns, rise);
            }
            7 => {
                let to = b.p + unit_vec(rng) * random_len(rng, u * 1e-2, u);
                b.rapid(to);
            }
            8 | 9 => {
                let n = 3 + rng.pick(6);
                zig_zag(rng, b, u, n);
            }
            _ => {
                let to = b.p + unit_vec(rng) * random_len(rng, u * 1e-5, u * 1e-2);
                b.line(to);
            }
        }
    }
}

/// Whole circles, helices and arcs meeting each other, tangent or not, with short lines.
fn gen_circles(rng: &mut Rng, b: &mut Builder, u: f64, n: usize) {
    let mut plane = random_plane(rng);
    if rng.pick(2) == 0 {
        let to = unit_vec(rng) * random_len(rng, u * 0.01, u);
        b.line(to);
    }
    while b.blocks.len() < n {
        if rng.pick(4) == 0 {
            plane = random_plane(rng);
        }
        if rng.pick(8) == 0 {
            b.corner = random_corner(rng, u);
        }
        let ccw = rng.pick(2) == 0;
        let r = random_radius(rng, u);
        let radial = if rng.pick(2) == 0 {
            b.tangent_radial(plane, ccw, r)
        } else {
            None
        }
        .unwrap_or_else(|| random_radial(rng, plane, r));
        match rng.pick(6) {
            0 | 1 => b.arc(plane, ccw, radial, TAU, 1 + rng.pick(2) as u32, 0.0),
            2 | 3 => {
                let rise = rng.sign() * rng.log(r * 0.01, u.max(r));
                let theta = if rng.pick(2) == 0 {
                    TAU
                } else {
                    rng.range(0.05, TAU - 0.05)
                };
                b.arc(plane, ccw, radial, theta, 1 + rng.pick(3) as u32, rise);
            }
            4 => b.arc(plane, ccw, radial, rng.range(0.05, TAU - 0.05), 1, 0.0),
            _ => {
                let d = if rng.pick(2) == 0 {
                    b.dir
                } else {
                    unit_vec(rng)
                };
                let to = b.p + d * random_len(rng, r * 0.1, u.max(r * 0.2));
                b.line(to);
            }
        }
    }
}

/// A dense 3D polyline along a curve with small turns per segment, a wave and a climb,
/// some with noise on every vertex, starting at the origin.
fn gen_dense(rng: &mut Rng, b: &mut Builder, total: f64, n: usize) {
    let h = (total / n as f64 * rng.log(0.05, 1.0)).max(10.0 * MIN_FEATURE_MM);
    let turn = rng.log(0.002, 0.3);
    let big_r = h / turn;
    let (e1, e2) = if rng.pick(2) == 0 {
        let n = random_plane(rng).normal();
        let e1 = in_plane(unit_vec(rng), n).normalize();
        (e1, n.cross(&e1))
    } else {
        let n = unit_vec(rng);
        let e1 = in_plane(unit_vec(rng), n).normalize();
        (e1, n.cross(&e1))
    };
    let e3 = e1.cross(&e2);
    let dphi = h / big_r;
    let wave_amp = if rng.pick(3) == 0 {
        0.0
    } else {
        big_r * rng.log(1e-3, 0.3)
    };
    let wave_freq = rng.log(1.0, (0.25 / dphi).max(1.0));
    let pitch = if rng.pick(2) == 0 {
        0.0
    } else {
        big_r * rng.range(-0.3, 0.3)
    };
    let noise = if rng.pick(3) == 0 {
        h * rng.log(0.01, 0.5)
    } else {
        0.0
    };
    let curve = |phi: f64| {
        e1 * (big_r * (phi.cos() - 1.0))
            + e2 * (big_r * phi.sin())
            + e3 * (pitch * phi + wave_amp * (wave_freq * phi).sin())
    };
    for i in 1..=n {
        let q = curve(dphi * i as f64) + unit_vec(rng) * (noise * rng.unit());
        b.line(q);
    }
}

/// A long approach, then short lines with tight turns (case A).
fn gen_zig_zag(rng: &mut Rng, b: &mut Builder, u: f64, n: usize) {
    let d = Vec3::new(
        rng.range(-1.0, 1.0),
        rng.range(-1.0, 1.0),
        rng.range(-0.05, 0.05),
    );
    let to = d.normalize() * random_len(rng, u * 0.1, u);
    b.line(to);
    zig_zag(rng, b, u, n);
}

impl Program {
    fn scale(&mut self, k: f64) {
        for b in &mut self.blocks {
            b.end *= k;
            if let Shape::Arc { centre, .. } = &mut b.shape {
                *centre *= k;
            }
        }
    }

    /// Rounds the line vertices to `decimals` and drops the lines that became empty.
    fn round_to(&mut self, decimals: i32) {
        self.decimals = Some(decimals);
        let mut at = Vec3::zeros();
        let mut out = Vec::with_capacity(self.blocks.len());
        for mut b in self.blocks.iter().copied() {
            if !matches!(b.shape, Shape::Arc { .. }) {
                b.end = b.end.map(|x| round_dec(x, decimals));
                if b.end == at {
                    continue;
                }
            }
            at = b.end;
            out.push(b);
        }
        self.blocks = out;
    }

    /// Rounds a CAM-like program's vertices, with more decimals than drawn where its
    /// segments are too short for them.
    fn round_vertices(&mut self) {
        let Some(d) = self.decimals else { return };
        let mut at = Vec3::zeros();
        let mut lens: Vec<f64> = Vec::new();
        for b in &self.blocks {
            lens.push((b.end - at).norm());
            at = b.end;
        }
        lens.sort_by(f64::total_cmp);
        let short = lens[lens.len() / 10].max(1e-300);
        let need = (-(short / 10.0).log10()).ceil() as i32;
        self.round_to(d.max(need).min(15));
    }

    /// Without blocks `i..i + count`. Kept absolute, the move after the gap starts where
    /// the one before it ended (not for an arc: its centre would be off its start);
    /// shifted, everything after the gap moves by the gap's displacement.
    fn without(&self, i: usize, count: usize, shift: bool) -> Option<Program> {
        let n = self.blocks.len();
        if count == 0 || count >= n || i + count > n {
            return None;
        }
        let before = if i == 0 {
            Vec3::zeros()
        } else {
            self.blocks[i - 1].end
        };
        let gone = self.blocks[i + count - 1].end;
        let mut blocks: Vec<Block> = self.blocks[..i].to_vec();
        blocks.extend_from_slice(&self.blocks[i + count..]);
        if shift {
            let delta = before - gone;
            for b in &mut blocks[i..] {
                b.end += delta;
                if let Shape::Arc { centre, .. } = &mut b.shape {
                    *centre += delta;
                }
            }
        } else if let Some(next) = blocks.get(i)
            && (matches!(next.shape, Shape::Arc { .. }) || next.end == before)
        {
            return None;
        }
        let mut p = Program {
            blocks,
            decimals: self.decimals,
        };
        if shift && let Some(d) = self.decimals {
            p.round_to(d);
        }
        (!p.blocks.is_empty()).then_some(p)
    }

    /// The shortest line or smallest radius.
    fn smallest_feature(&self) -> f64 {
        let mut at = Vec3::zeros();
        let mut f = f64::INFINITY;
        for b in &self.blocks {
            f = f.min(match b.shape {
                Shape::Arc { plane, centre, .. } => in_plane(at - centre, plane.normal()).norm(),
                _ => (b.end - at).norm(),
            });
            at = b.end;
        }
        f
    }

    /// The largest coordinate any move reaches (arcs: their centre plus radius).
    fn extent(&self) -> f64 {
        let mut at = Vec3::zeros();
        let mut e: f64 = 0.0;
        for b in &self.blocks {
            e = e.max(b.end.amax());
            if let Shape::Arc { centre, .. } = b.shape {
                e = e.max(centre.amax() + (at - centre).norm() + (b.end - at).norm());
            }
            at = b.end;
        }
        e
    }
}

/// The program as LinuxCNC G-code; numbers in their shortest exact decimal form.
fn gcode(p: &Program) -> String {
    let mut s = String::from("G21 G90 G94 G17 G40 G49 G54\n");
    let mut corner: Option<Corner> = None;
    let mut plane = Plane::Xy;
    let mut feed: Option<f64> = None;
    let mut at = Vec3::zeros();
    for b in &p.blocks {
        if corner != Some(b.corner) {
            match b.corner {
                Corner::Blend => s.push_str("G64\n"),
                Corner::Tol(t) => writeln!(s, "G64 P{t}").unwrap(),
                Corner::Exact => s.push_str("G61\n"),
            }
            corner = Some(b.corner);
        }
        let e = b.end;
        match b.shape {
            Shape::Rapid => {
                writeln!(s, "G0 X{} Y{} Z{}", e.x, e.y, e.z).unwrap();
                at = e;
                continue;
            }
            Shape::Line => write!(s, "G1 X{} Y{} Z{}", e.x, e.y, e.z).unwrap(),
            Shape::Arc {
                plane: pl,
                ccw,
                centre,
                turns,
            } => {
                if pl != plane {
                    writeln!(s, "{}", pl.code()).unwrap();
                    plane = pl;
                }
                let g = if ccw { 3 } else { 2 };
                write!(s, "G{g} X{} Y{} Z{}", e.x, e.y, e.z).unwrap();
                let off = centre - at;
                for (word, i) in pl.offsets() {
                    write!(s, " {word}{}", off[i]).unwrap();
                }
                if turns > 1 {
                    write!(s, " P{turns}").unwrap();
                }
            }
        }
        if feed != Some(b.feed_mm_min) {
            write!(s, " F{}", b.feed_mm_min).unwrap();
            feed = Some(b.feed_mm_min);
        }
        s.push('\n');
        at = e;
    }
    s.push_str("M2\n");
    s
}

/// The moves `kerf sim` runs for the text (LinuxCNC, default settings).
fn parse(text: &str) -> Result<Vec<Move>, String> {
    let mut moves = Vec::new();
    for item in Interpreter::new(text.as_bytes(), Dialect::LinuxCnc, Settings::default()) {
        match item {
            Ok(Item::Move(m)) => moves.push(m),
            Ok(Item::Event(_)) => {}
            Err(d) => return Err(format!("the G-code is refused: {d}")),
        }
    }
    if moves.is_empty() {
        return Err("no moves".into());
    }
    Ok(moves)
}

/// The machine as a `kerf` configuration, travel ±`travel_mm` on every axis.
fn toml(m: &Machine, travel_mm: f64) -> String {
    let mut s = format!(
        "# kerf sim --config m.toml p.ngc --out o.csv --override {}\nmachine = \"extremes\"\nperiod_us = {}\ntolerance_mm = {:?}\n",
        m.override_pct, m.period_us, m.tolerance_mm
    );
    for (name, a) in ["x", "y", "z"].iter().zip(m.axes) {
        write!(
            s,
            "\n[axes.{name}]\nvelocity_mm_s = {:?}\nacceleration_mm_s2 = {:?}\njerk_mm_s3 = {:?}\nmin_mm = {:?}\nmax_mm = {:?}\n",
            a.v, a.a, a.j, -travel_mm, travel_mm
        )
        .unwrap();
    }
    s
}

/// Reads back what [`toml`] writes (and the fixed cases): the period, the tolerance, the
/// axis limits and the override from the command in the first comment.
fn machine_from_toml(text: &str) -> Machine {
    let zero = Axis {
        v: 0.0,
        a: 0.0,
        j: 0.0,
    };
    let mut m = Machine {
        period_us: 1000,
        tolerance_mm: 0.01,
        axes: [zero; 3],
        override_pct: 100.0,
    };
    let mut axis = None;
    for line in text.lines() {
        let line = line.trim();
        if let Some(cmd) = line.strip_prefix('#') {
            if let Some((_, pct)) = cmd.split_once("--override ") {
                m.override_pct = pct.split_whitespace().next().unwrap().parse().unwrap();
            }
            continue;
        }
        if let Some(section) = line.strip_prefix('[') {
            axis = ["axes.x]", "axes.y]", "axes.z]"]
                .iter()
                .position(|&s| s == section);
            continue;
        }
        let Some((key, value)) = line.split_once('=') else {
            continue;
        };
        let value = value.trim();
        let number = || -> f64 { value.parse().unwrap() };
        match (axis, key.trim()) {
            (None, "period_us") => m.period_us = value.parse().unwrap(),
            (None, "tolerance_mm") => m.tolerance_mm = number(),
            (Some(i), "velocity_mm_s") => m.axes[i].v = number(),
            (Some(i), "acceleration_mm_s2") => m.axes[i].a = number(),
            (Some(i), "jerk_mm_s3") => m.axes[i].j = number(),
            _ => {}
        }
    }
    m
}

/// Travel for the reproducer's configuration: a power of ten above twice the extent.
fn travel_mm(p: &Program) -> f64 {
    let e = (2.0 * p.extent()).max(10.0);
    10f64.powi(e.log10().ceil() as i32).min(1e6)
}

// ---------------------------------------------------------------------------------------
// Scaling a program to its machine: a rough, deliberately slow time estimate.

/// Path limits of the estimate.
struct Dyn {
    a: f64,
    j: f64,
}

fn change_s(dv: f64, d: &Dyn) -> f64 {
    let dv = dv.abs();
    if dv * d.j >= d.a * d.a {
        dv / d.a + d.a / d.j
    } else {
        2.0 * (dv / d.j).sqrt()
    }
}

fn change_mm(v0: f64, v1: f64, d: &Dyn) -> f64 {
    0.5 * (v0 + v1) * change_s(v1 - v0, d)
}

/// Time over `len` entered at `v_in`, left at `v_out`, at most `cap`.
fn block_s(len: f64, v_in: f64, v_out: f64, cap: f64, d: &Dyn) -> f64 {
    if len <= 0.0 {
        return 0.0;
    }
    let lo = v_in.max(v_out).min(cap);
    let dist = |vp: f64| change_mm(v_in.min(vp), vp, d) + change_mm(vp, v_out.min(vp), d);
    if dist(lo) >= len {
        let mean = 0.5 * (v_in + v_out);
        let pass = if mean > 0.0 { len / mean } else { 0.0 };
        return change_s(v_in - v_out, d).max(pass);
    }
    let vp = if dist(cap) <= len {
        cap
    } else {
        let (mut a, mut b) = (lo, cap);
        for _ in 0..80 {
            let mid = 0.5 * (a + b);
            if dist(mid) <= len { a = mid } else { b = mid }
        }
        a
    };
    change_s(vp - v_in, d) + change_s(vp - v_out, d) + (len - dist(vp)) / vp
}

/// The highest speed reached from `v0` over `len`, at most `cap`.
fn reach(v0: f64, len: f64, cap: f64, d: &Dyn) -> f64 {
    if cap <= v0 || change_mm(v0, cap, d) <= len {
        return cap;
    }
    let (mut a, mut b) = (v0, cap);
    for _ in 0..80 {
        let mid = 0.5 * (a + b);
        if change_mm(v0, mid, d) <= len {
            a = mid
        } else {
            b = mid
        }
    }
    a
}

/// The length a stop-to-stop move at most `v` covers in `t`.
fn length_for(t: f64, v: f64, d: &Dyn) -> f64 {
    let (mut lo, mut hi) = (1e-12f64.ln(), 1e8f64.ln());
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if block_s(mid.exp(), 0.0, 0.0, v, d) <= t {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo.exp()
}

fn v_curve(r: f64, d: &Dyn) -> f64 {
    if r.is_finite() {
        (d.a * r).sqrt().min((d.j * r * r).cbrt())
    } else {
        f64::INFINITY
    }
}

struct Geo {
    len: f64,
    t0: Vec3,
    t1: Vec3,
    radius: f64,
}

fn geometry(p: &Program) -> Vec<Geo> {
    let mut at = Vec3::zeros();
    let mut out = Vec::with_capacity(p.blocks.len());
    for b in &p.blocks {
        out.push(match b.shape {
            Shape::Arc {
                plane,
                ccw,
                centre,
                turns,
            } => {
                let g = ArcGeom::new(at, b.end, plane, ccw, centre, turns);
                Geo {
                    len: g.length(),
                    t0: g.tangent(g.radial0),
                    t1: g.tangent(g.radial1),
                    radius: g.r,
                }
            }
            _ => {
                let d = b.end - at;
                let len = d.norm();
                let t = if len > 0.0 { d / len } else { Vec3::x() };
                Geo {
                    len,
                    t0: t,
                    t1: t,
                    radius: f64::INFINITY,
                }
            }
        });
        at = b.end;
    }
    out
}

/// A rough upper estimate of the program's time on the machine: a tenth of the slowest
/// axis's acceleration and jerk, the slowest axis's velocity, curves and blended corners
/// slowed to their radius, stops at sharp corners, rapids and exact stops.
fn estimate_s(p: &Program, m: &Machine) -> f64 {
    let geo = geometry(p);
    let slow = m.slowest();
    let d = Dyn {
        a: slow.a / 10.0,
        j: slow.j / 10.0,
    };
    let ovr = m.feed_override();
    let n = p.blocks.len();
    let cap: Vec<f64> = p
        .blocks
        .iter()
        .zip(&geo)
        .map(|(b, g)| {
            let v = match b.shape {
                Shape::Rapid => slow.v,
                _ => (b.feed_mm_min / 60.0 * ovr).min(slow.v),
            };
            v.min(v_curve(g.radius, &d))
        })
        .collect();
    let tol = |b: &Block| match b.corner {
        Corner::Tol(t) => t,
        Corner::Blend => m.tolerance_mm,
        Corner::Exact => 0.0,
    };
    let mut junction = vec![0.0; n + 1];
    for i in 1..n {
        let (a, b) = (&p.blocks[i - 1], &p.blocks[i]);
        let rapid = |b: &Block| matches!(b.shape, Shape::Rapid);
        if rapid(a) || rapid(b) || a.corner == Corner::Exact {
            continue;
        }
        let theta = geo[i - 1].t1.dot(&geo[i].t0).clamp(-1.0, 1.0).acos();
        if theta > 2.0 {
            continue;
        }
        let half = 0.5 * theta;
        let bulge = 1.0 / half.cos() - 1.0;
        let r_tol = if bulge > 0.0 {
            tol(a).min(tol(b)) / bulge
        } else {
            f64::INFINITY
        };
        let r_len = if half > 0.0 {
            0.5 * geo[i - 1].len.min(geo[i].len) / half.tan()
        } else {
            f64::INFINITY
        };
        junction[i] = cap[i - 1].min(cap[i]).min(v_curve(r_tol.min(r_len), &d));
    }
    // What can be reached from the start and what can still stop at the end.
    for i in 0..n {
        junction[i + 1] = junction[i + 1].min(reach(junction[i], geo[i].len, cap[i], &d));
    }
    for i in (0..n).rev() {
        junction[i] = junction[i].min(reach(junction[i + 1], geo[i].len, cap[i], &d));
    }
    (0..n)
        .map(|i| block_s(geo[i].len, junction[i], junction[i + 1], cap[i], &d))
        .sum()
}

/// Shrinks the program until its estimate fits in `t_s` (keeping its features at least
/// [`MIN_FEATURE_MM`], cutting moves off its end, and at last raising its feeds where that
/// is not enough), then rounds its vertices.
fn fit(p: &mut Program, m: &Machine, t_s: f64) {
    for _ in 0..60 {
        let est = estimate_s(p, m);
        let floor = MIN_FEATURE_MM / p.smallest_feature();
        if est <= t_s || floor >= 0.99 {
            break;
        }
        p.scale((t_s / est).powi(2).clamp(1e-3, 0.7).max(floor));
    }
    while p.blocks.len() > 2 && estimate_s(p, m) > t_s {
        p.blocks.truncate(p.blocks.len() * 3 / 4);
    }
    for _ in 0..40 {
        let est = estimate_s(p, m);
        if est <= t_s {
            break;
        }
        for b in &mut p.blocks {
            b.feed_mm_min = round_sig(b.feed_mm_min * (1.5 * est / t_s).min(1e3), 5);
        }
    }
    p.round_vertices();
}

// ---------------------------------------------------------------------------------------
// Cases

struct Case {
    seed: u64,
    case: usize,
    kind: &'static str,
    machine: Machine,
    program: Program,
}

/// The generator of case `case` of `seed`, from those two numbers alone.
fn case_rng(seed: u64, case: usize) -> Rng {
    let mix = |mut z: u64| {
        z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    };
    Rng(mix(mix(seed) ^ mix(case as u64 ^ 0x5eed_0000_0024)) | 1)
}

fn make_case(seed: u64, case: usize) -> Case {
    let mut rng = case_rng(seed, case);
    let machine = random_machine(&mut rng);
    let slow = machine.slowest();
    let d = Dyn {
        a: slow.a / 10.0,
        j: slow.j / 10.0,
    };
    let v_ref = if rng.pick(10) < 7 {
        slow.v
    } else {
        machine.axes[rng.pick(3)].v
    };
    let feed = round_sig(v_ref * rng.log(0.01, 2.0) * 60.0, 5);
    let v_move = (feed / 60.0 * machine.feed_override()).min(slow.v);
    // The time of `moves` moves that just reach the feed, within 1,000 to 30,000 periods.
    let budget = |rng: &mut Rng, moves: f64| {
        let t = moves * 2.0 * change_s(v_move, &d) * rng.log(0.2, 5.0);
        let period = machine.period_s();
        t.clamp(1000.0 * period, 30_000.0 * period)
    };
    let corner = match rng.pick(3) {
        0 => Corner::Blend,
        _ => random_corner(&mut rng, 1.0),
    };
    let corner = if corner == Corner::Exact {
        Corner::Blend
    } else {
        corner
    };
    let mut b = Builder::new(feed, corner);
    let t_target;
    let (kind, decimals) = match rng.pick(4) {
        0 => {
            let n = 3 + rng.pick(30);
            t_target = budget(&mut rng, n as f64);
            let u = length_for(t_target / n as f64, v_move, &d);
            gen_mixed(&mut rng, &mut b, u, n);
            ("mixed", None)
        }
        1 => {
            let n = 2 + rng.pick(8);
            t_target = budget(&mut rng, (3 * n) as f64);
            let u = length_for(t_target / (3 * n) as f64, v_move, &d);
            gen_circles(&mut rng, &mut b, u, n);
            ("circles", None)
        }
        2 => {
            let n = 50 + rng.pick(550);
            t_target = budget(&mut rng, 10.0);
            let total = length_for(t_target, v_move, &d);
            gen_dense(&mut rng, &mut b, total, n);
            ("dense", Some(2 + rng.pick(5) as i32))
        }
        _ => {
            let n = 5 + rng.pick(25);
            t_target = budget(&mut rng, 4.0);
            let u = length_for(t_target / 4.0, v_move, &d);
            gen_zig_zag(&mut rng, &mut b, u, n);
            ("zig-zag", Some(3 + rng.pick(3) as i32))
        }
    };
    let mut program = Program {
        blocks: b.blocks,
        decimals,
    };
    fit(&mut program, &machine, t_target);
    Case {
        seed,
        case,
        kind,
        machine,
        program,
    }
}

// ---------------------------------------------------------------------------------------
// The check

/// What can fail, in the order a failure is named by.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Check {
    /// The interpreter refused the text (a bug of this file's writer).
    Gcode,
    /// The pipeline panicked or returned an error.
    Run,
    NotFinite,
    Velocity,
    Acceleration,
    Jerk,
    PlanFailures,
    Deviation,
    Feed,
    End,
    Cycles,
}

/// What one run measured and what failed.
struct Verdict {
    cycles: u64,
    /// The highest share of each limit (velocity, acceleration, jerk) on any axis.
    worst: [f64; 3],
    /// What failed: the check, how badly (the worst share of what it allows, 1 where
    /// there is no measure), and a description.
    failed: Vec<(Check, f64, String)>,
}

impl Verdict {
    fn failure(check: Check, text: String) -> Verdict {
        Verdict {
            cycles: 0,
            worst: [0.0; 3],
            failed: vec![(check, 1.0, text)],
        }
    }

    fn first(&self) -> Option<Check> {
        self.failed.iter().map(|f| f.0).min()
    }

    /// How badly `check` failed (0 if it passed).
    fn severity(&self, check: Check) -> f64 {
        self.failed
            .iter()
            .filter(|f| f.0 == check)
            .map(|f| f.1)
            .fold(0.0, f64::max)
    }

    fn describe(&self) -> String {
        let mut s = String::new();
        for (_, _, text) in &self.failed {
            writeln!(s, "  {text}").unwrap();
        }
        s
    }
}

/// A setpoint as the checks need it.
#[derive(Clone, Copy)]
struct Row {
    p: [f64; 3],
    move_index: u64,
    line: u32,
}

fn check_text(m: &Machine, text: &str) -> Verdict {
    match parse(text) {
        Ok(moves) => check_moves(m, &moves),
        Err(e) => Verdict::failure(Check::Gcode, e),
    }
}

/// Runs the moves on the machine and checks every invariant.
fn check_moves(m: &Machine, moves: &[Move]) -> Verdict {
    let limits = m.limits();
    let opts = RunOptions {
        feed_override: m.feed_override(),
        max_cycles: MAX_CYCLES,
        ..RunOptions::default()
    };
    let mut rows: Vec<Row> = Vec::new();
    let result = catch_unwind(AssertUnwindSafe(|| {
        run(moves.iter().copied(), &limits, &opts, |_, sp| {
            rows.push(Row {
                p: [sp.position[0], sp.position[1], sp.position[2]],
                move_index: sp.move_index,
                line: sp.line,
            })
        })
    }));
    let s = match result {
        Ok(Ok(s)) => s,
        Ok(Err(e)) => return Verdict::failure(Check::Run, format!("the run failed: {e}")),
        Err(panic) => {
            let text = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            return Verdict::failure(Check::Run, format!("the run panicked: {text}"));
        }
    };
    let mut v = Verdict {
        cycles: s.cycles,
        worst: [0.0; 3],
        failed: Vec::new(),
    };
    if s.saw_nan {
        v.failed
            .push((Check::NotFinite, 1.0, "a non-finite setpoint".into()));
    }
    check_limits(&rows, m, &mut v);
    if s.plan_failures != 0 {
        v.failed.push((
            Check::PlanFailures,
            1.0,
            format!("{} solver fallbacks (plan_failures)", s.plan_failures),
        ));
    }
    let tol = moves
        .iter()
        .filter_map(|mv| match mv.corner {
            CornerMode::Blend {
                tolerance_mm: Some(t),
                ..
            } => Some(t),
            _ => None,
        })
        .fold(m.tolerance_mm, f64::max);
    if s.max_deviation_mm > tol * 1.0001 + 1e-9 {
        v.failed.push((
            Check::Deviation,
            s.max_deviation_mm / tol,
            format!(
                "deviation {} mm from the path, tolerance {tol} mm",
                s.max_deviation_mm
            ),
        ));
    }
    check_feed(&rows, moves, m, &mut v);
    let end = moves.last().unwrap().path.end();
    if s.last.position[..3] != [end.x, end.y, end.z] {
        v.failed.push((
            Check::End,
            1.0,
            format!(
                "ended at {:?}, the program at {:?}",
                &s.last.position[..3],
                [end.x, end.y, end.z]
            ),
        ));
    }
    if s.cycles >= MAX_CYCLES {
        v.failed.push((
            Check::Cycles,
            1.0,
            format!("still running after {MAX_CYCLES} cycles"),
        ));
    }
    v
}

/// Every axis's velocity, acceleration and jerk by finite differences of the positions at
/// the period, from rest before the first setpoint, within 1 % plus the rounding of the
/// positions (as `check_all_axes` in `properties.rs`).
fn check_limits(rows: &[Row], m: &Machine, v: &mut Verdict) {
    let t = m.period_s();
    let big = rows
        .iter()
        .flat_map(|r| r.p)
        .fold(1.0_f64, |m, x| m.max(x.abs()));
    let noise = 8.0 * f64::EPSILON * big;
    let allow = [noise / t, 2.0 * noise / (t * t), 4.0 * noise / (t * t * t)];
    // Per quantity: the first and the worst setpoint beyond the limit (row, axis, value,
    // share of the allowed limit), and how many there were.
    type Hit = (usize, usize, f64, f64);
    let mut first: [Option<Hit>; 3] = [None; 3];
    let mut worst: [Option<Hit>; 3] = [None; 3];
    let mut count = [0usize; 3];
    let rest = [rows[0]; 3];
    let all: Vec<&Row> = rest.iter().chain(rows).collect();
    for (i, axis) in m.axes.iter().enumerate() {
        let lim = [axis.v, axis.a, axis.j];
        for (k, w) in all.windows(4).enumerate() {
            let p = |j: usize| w[j].p[i];
            let val = [
                (p(3) - p(2)).abs() / t,
                (p(3) - 2.0 * p(2) + p(1)).abs() / (t * t),
                (p(3) - 3.0 * p(2) + 3.0 * p(1) - p(0)).abs() / (t * t * t),
            ];
            for q in 0..3 {
                v.worst[q] = v.worst[q].max(val[q] / lim[q]);
                let share = val[q] / (lim[q] * 1.01 + allow[q]);
                if share > 1.0 {
                    count[q] += 1;
                    let hit = Some((k, i, val[q], share));
                    if first[q].is_none_or(|f| k < f.0) {
                        first[q] = hit;
                    }
                    if worst[q].is_none_or(|f| share > f.3) {
                        worst[q] = hit;
                    }
                }
            }
        }
    }
    let names = ["velocity", "acceleration", "jerk"];
    let units = ["mm/s", "mm/s²", "mm/s³"];
    let checks = [Check::Velocity, Check::Acceleration, Check::Jerk];
    let at = |(k, i, val, _): Hit, q: usize| {
        let lim = m.axes[i].get(q);
        let r = rows[k];
        format!(
            "{} {val:.6e} {} = {:.4} of the limit {lim:?} at row {k} (t {} s, line {}, move {})",
            AXIS[i],
            units[q],
            val / lim,
            kerf_pipeline::cycle_time_s(k as u64, t),
            r.line,
            r.move_index
        )
    };
    for q in 0..3 {
        let (Some(f), Some(w)) = (first[q], worst[q]) else {
            continue;
        };
        let mut text = format!(
            "{}: {} setpoints beyond 1.01 x the limit (+ {:.3e} {} for rounding); worst {}",
            names[q],
            count[q],
            allow[q],
            units[q],
            at(w, q)
        );
        if f.0 != w.0 || f.1 != w.1 {
            write!(text, "; first {}", at(f, q)).unwrap();
        }
        v.failed.push((checks[q], w.3, text));
    }
}

/// The XYZ speed per period within the feed of the moves around it times the override,
/// plus 1 % (as `check_feed` in `properties.rs`); rapids are not checked.
fn check_feed(rows: &[Row], moves: &[Move], m: &Machine, v: &mut Verdict) {
    let t = m.period_s();
    let ovr = m.feed_override();
    for (k, w) in rows.windows(2).enumerate() {
        let (a, b) = (&w[0], &w[1]);
        let lo = a.move_index.min(b.move_index).saturating_sub(1) as usize;
        let hi = (a.move_index.max(b.move_index) as usize + 1).min(moves.len() - 1);
        let mut feed: f64 = 0.0;
        let mut rapid = false;
        for mv in &moves[lo.min(hi)..=hi] {
            rapid |= mv.rapid;
            feed = feed.max(mv.feed_mm_min.unwrap_or(f64::INFINITY) / 60.0);
        }
        if rapid {
            continue;
        }
        let d = (0..3)
            .map(|i| (b.p[i] - a.p[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        let speed = d / t;
        if speed > feed * ovr * 1.01 + 1e-9 {
            v.failed.push((
                Check::Feed,
                speed / (feed * ovr * 1.01 + 1e-9),
                format!(
                    "feed: {speed} mm/s at row {} (line {}) above the feed {feed} mm/s x {ovr}",
                    k + 1,
                    b.line
                ),
            ));
            return;
        }
    }
}

// ---------------------------------------------------------------------------------------
// Reports and the minimiser

fn reproducer(m: &Machine, p: &Program) -> String {
    format!(
        "kerf sim --config m.toml p.ngc --out o.csv --override {}\n--- p.ngc ---\n{}--- m.toml ---\n{}",
        m.override_pct,
        gcode(p),
        toml(m, travel_mm(p))
    )
}

/// Greedy shrinking of a failing case while the same check still fails about as badly
/// (at least the square root of the original's share of the limit, so that a gross
/// failure does not shrink into a marginal one of another cause): blocks dropped (halves,
/// quarters, ... down to single blocks, from the front, the middle and the back), the
/// axes made alike, limits, period, tolerance and override rounded, feeds, `G64 P` and
/// vertices rounded. Bounded by [`MINIMISE_RUNS`] runs and `budget`.
struct Minimiser {
    target: Check,
    /// The least severity a variant must keep.
    severity: f64,
    deadline: Instant,
    runs: usize,
    machine: Machine,
    program: Program,
    verdict: Option<Verdict>,
}

impl Minimiser {
    fn spent(&self) -> bool {
        self.runs >= MINIMISE_RUNS || Instant::now() >= self.deadline
    }

    /// Keeps the variant if it still fails the target check.
    fn try_variant(&mut self, m: Machine, p: Program) -> bool {
        if self.spent() || (m == self.machine && p == self.program) {
            return false;
        }
        self.runs += 1;
        let v = check_text(&m, &gcode(&p));
        if v.severity(self.target) >= self.severity {
            self.machine = m;
            self.program = p;
            self.verdict = Some(v);
            true
        } else {
            false
        }
    }

    fn drop_blocks(&mut self) {
        let mut chunk = (self.program.blocks.len() / 2).max(1);
        loop {
            let mut i = 0;
            let mut progress = false;
            while i < self.program.blocks.len() && !self.spent() {
                let mut taken = false;
                for shift in [false, true] {
                    if shift && i + chunk >= self.program.blocks.len() {
                        break;
                    }
                    if let Some(q) = self.program.without(i, chunk, shift)
                        && self.try_variant(self.machine.clone(), q)
                    {
                        taken = true;
                        progress = true;
                        break;
                    }
                }
                if !taken {
                    i += chunk;
                }
            }
            if self.spent() || (chunk == 1 && !progress) {
                return;
            }
            chunk = (chunk / 2).max(1);
        }
    }

    fn round_machine(&mut self) {
        for k in 0..3 {
            let mut m = self.machine.clone();
            m.axes = [m.axes[k]; 3];
            if self.try_variant(m, self.program.clone()) {
                break;
            }
        }
        for i in 0..3 {
            for q in 0..3 {
                for sig in 1..=3 {
                    let mut m = self.machine.clone();
                    let x = round_sig(m.axes[i].get(q), sig);
                    m.axes[i].set(q, x);
                    if self.try_variant(m, self.program.clone()) {
                        break;
                    }
                }
            }
        }
        for sig in 1..=2 {
            let mut m = self.machine.clone();
            m.tolerance_mm = round_sig(m.tolerance_mm, sig);
            if self.try_variant(m, self.program.clone()) {
                break;
            }
        }
        for sig in 1..=2 {
            let mut m = self.machine.clone();
            let p = round_sig(f64::from(m.period_us), sig) as u32;
            m.period_us = p.clamp(PERIOD_US.0, PERIOD_US.1);
            if self.try_variant(m, self.program.clone()) {
                break;
            }
        }
        for pct in [100.0, round_sig(self.machine.override_pct, 1)] {
            let mut m = self.machine.clone();
            m.override_pct = pct.clamp(1.0, 200.0);
            if self.try_variant(m, self.program.clone()) {
                break;
            }
        }
    }

    fn round_program(&mut self) {
        for sig in 1..=3 {
            let mut p = self.program.clone();
            for b in &mut p.blocks {
                b.feed_mm_min = round_sig(b.feed_mm_min, sig);
            }
            if self.try_variant(self.machine.clone(), p) {
                break;
            }
        }
        for sig in 1..=2 {
            let mut p = self.program.clone();
            for b in &mut p.blocks {
                if let Corner::Tol(t) = &mut b.corner {
                    *t = round_sig(*t, sig);
                }
            }
            if self.try_variant(self.machine.clone(), p) {
                break;
            }
        }
        if let Some(d) = self.program.decimals {
            for fewer in (2..d).rev() {
                let mut p = self.program.clone();
                p.round_to(fewer);
                if !self.try_variant(self.machine.clone(), p) {
                    break;
                }
            }
        }
    }
}

fn minimise(m: &Machine, p: &Program, v: &Verdict, budget: Duration) -> Minimiser {
    let target = v.first().unwrap();
    let mut z = Minimiser {
        target,
        severity: v.severity(target).sqrt().max(1e-300),
        deadline: Instant::now() + budget,
        runs: 0,
        machine: m.clone(),
        program: p.clone(),
        verdict: None,
    };
    z.drop_blocks();
    z.round_machine();
    z.round_program();
    z.drop_blocks();
    z
}

fn minimise_budget() -> Duration {
    Duration::from_secs_f64(env_number("KERF_EXTREME_MINIMISE_S").unwrap_or(20.0))
}

/// What a case left for the summary.
struct Outcome {
    cycles: u64,
    worst: [f64; 3],
    /// The report of a failure, with the minimised reproducer.
    failure: Option<String>,
}

/// Runs one generated case; on a failure prints the case's reproducer and returns the
/// one minimised within `budget` (the whole one for a zero budget).
fn run_case(seed: u64, case: usize, budget: Duration) -> Outcome {
    let c = make_case(seed, case);
    let v = check_text(&c.machine, &gcode(&c.program));
    let Some(target) = v.first() else {
        return Outcome {
            cycles: v.cycles,
            worst: v.worst,
            failure: None,
        };
    };
    let title = format!(
        "extremes seed {} case {} ({}, {} blocks, {} cycles): {target:?}",
        c.seed,
        c.case,
        c.kind,
        c.program.blocks.len(),
        v.cycles
    );
    eprintln!(
        "{title}\n{}replay: KERF_EXTREME_SEED={} KERF_EXTREME_ONLY={} cargo test --release -p kerf-pipeline --test extremes extreme_machines -- --nocapture\n{}",
        v.describe(),
        c.seed,
        c.case,
        reproducer(&c.machine, &c.program)
    );
    let mut report = format!("{title}\n{}", v.describe());
    if target != Check::Gcode && !budget.is_zero() {
        let t0 = Instant::now();
        let z = minimise(&c.machine, &c.program, &v, budget);
        if let Some(mv) = &z.verdict {
            write!(
                report,
                "minimised ({} runs, {:.1} s) to {} blocks, {} cycles:\n{}{}",
                z.runs,
                t0.elapsed().as_secs_f64(),
                z.program.blocks.len(),
                mv.cycles,
                mv.describe(),
                reproducer(&z.machine, &z.program)
            )
            .unwrap();
        } else {
            write!(
                report,
                "(no smaller variant fails it)\n{}",
                reproducer(&c.machine, &c.program)
            )
            .unwrap();
        }
    } else {
        report.push_str(&reproducer(&c.machine, &c.program));
    }
    eprintln!("{report}");
    Outcome {
        cycles: v.cycles,
        worst: v.worst,
        failure: Some(report),
    }
}

#[derive(Default)]
struct Tally {
    cases: usize,
    cycles: u64,
    /// The worst share of each limit and the case it was seen in.
    worst: [(f64, usize); 3],
    failures: Vec<(usize, String)>,
}

impl Tally {
    fn add(&mut self, case: usize, o: Outcome) {
        self.cases += 1;
        self.cycles += o.cycles;
        for q in 0..3 {
            if o.worst[q] > self.worst[q].0 {
                self.worst[q] = (o.worst[q], case);
            }
        }
        if let Some(f) = o.failure {
            self.failures.push((case, f));
        }
    }

    fn merge(&mut self, other: Tally) {
        self.cases += other.cases;
        self.cycles += other.cycles;
        for q in 0..3 {
            if other.worst[q].0 > self.worst[q].0 {
                self.worst[q] = other.worst[q];
            }
        }
        self.failures.extend(other.failures);
    }
}

/// Runs the cases of `seed` on `threads` threads (split by index).
fn sweep(seed: u64, cases: &[usize], threads: usize) -> Tally {
    let threads = threads.max(1);
    let t0 = Instant::now();
    let tallies: Vec<Tally> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                s.spawn(move || {
                    let mut tally = Tally::default();
                    for (k, &case) in cases.iter().enumerate() {
                        if k % threads == t {
                            tally.add(case, run_case(seed, case, minimise_budget()));
                            if tally.cases % 500 == 0 {
                                eprintln!(
                                    "extremes: thread {t}: {} cases, {} failed, {:.0} s",
                                    tally.cases,
                                    tally.failures.len(),
                                    t0.elapsed().as_secs_f64()
                                );
                            }
                        }
                    }
                    tally
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let mut tally = Tally::default();
    for t in tallies {
        tally.merge(t);
    }
    tally.failures.sort_by_key(|f| f.0);
    let escapes: Vec<usize> = tally.failures.iter().map(|f| f.0).collect();
    eprintln!(
        "extremes: seed {seed}: {} cases, {} cycles in {:.1} s; worst of the limits: v {:.4} (case {}), a {:.4} (case {}), j {:.4} (case {}); {} escapes {escapes:?}",
        tally.cases,
        tally.cycles,
        t0.elapsed().as_secs_f64(),
        tally.worst[0].0,
        tally.worst[0].1,
        tally.worst[1].0,
        tally.worst[1].1,
        tally.worst[2].0,
        tally.worst[2].1,
        escapes.len()
    );
    tally
}

fn fail_on(tally: &Tally, what: &str) {
    if tally.failures.is_empty() {
        return;
    }
    let mut msg = format!(
        "{} of {} {what} failed:\n",
        tally.failures.len(),
        tally.cases
    );
    for (_, report) in &tally.failures {
        msg.push_str(report);
        msg.push('\n');
    }
    panic!("{msg}");
}

/// 100 random cases in every test run (about 2 s); see the file's documentation for a soak.
#[test]
fn extreme_machines_hold_every_invariant() {
    let seed: u64 = env_number("KERF_EXTREME_SEED").unwrap_or(24);
    let cases: usize = env_number("KERF_EXTREME_CASES").unwrap_or(100);
    let threads: usize = env_number("KERF_EXTREME_THREADS").unwrap_or(1);
    let list: Vec<usize> = match env_number::<usize>("KERF_EXTREME_ONLY") {
        Some(k) => vec![k],
        None => (0..cases).collect(),
    };
    let tally = sweep(seed, &list, threads);
    fail_on(&tally, &format!("extreme cases of seed {seed}"));
}

/// Escapes found by soaks: (seed, cases), replayed in every run. Those of seeds 24 and 1
/// below 1,000 and seed 2's case 124 stress the seams of smoothed dense polylines, zig-zag
/// corners, circles meeting circles (jerk and acceleration at the limits) and the
/// programmed feed on smoothed pieces. Seed 1's case 14517: two arc blends of a zig-zag
/// 0.07 pm apart, the remnant of the line between them kept (dropping it is a jump, seen
/// in X's jerk against its limit of 23.4 mm/s³ at a 142 µs period). Seed 1's case 17536
/// and seed 2's case 19379: smoothed pieces within the tolerance between the samples of
/// their deviation check too. Seed 3's case 15501: a polygon of 3.5 µm corner blends
/// passed two or three to a 4.666 ms period, whose kinks, each within its junction cap
/// alone, must not add up beyond the limit in one finite-difference window. Seed 3's cases
/// 16266 and 16890: a 0.2 µm remnant entered at the 1 nm/s cap of a kink on an axis with
/// 4 mm/s³ must not be coasted through for minutes (the run must end within its cycles).
const ESCAPES: &[(u64, &[usize])] = &[
    (
        24,
        &[12, 17, 32, 48, 104, 106, 121, 125, 129, 198, 223, 252, 281],
    ),
    (
        1,
        &[
            52, 67, 100, 103, 161, 244, 248, 255, 375, 378, 489, 508, 556, 572, 611, 636, 695, 743,
            788, 793, 845, 867, 891, 898, 949, 14517, 17536,
        ],
    ),
    (2, &[124, 19379]),
    (3, &[15501, 16266, 16890]),
];

/// A program and machine that once broke an invariant, as the reproducer printed them
/// (the travel may be left out: a failure prints the configuration with one that fits).
struct Fixed {
    name: &'static str,
    toml: &'static str,
    gcode: &'static str,
}

/// Case A: a zig-zag of short lines with tight turns on a machine whose acceleration is 27
/// times its jerk × 1 s; a jump inside a smoothed piece (`Transition::param_at`) shows
/// here as a jerk far beyond the limit.
const CASE_A: Fixed = Fixed {
    name: "A: zig-zag, a/j 27 s",
    toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 100
period_us = 1000
tolerance_mm = 0.529
[axes.x]
velocity_mm_s = 1568.0
acceleration_mm_s2 = 88710.0
jerk_mm_s3 = 3292.0
min_mm = -100.0
max_mm = 100.0
[axes.y]
velocity_mm_s = 1568.0
acceleration_mm_s2 = 88710.0
jerk_mm_s3 = 3292.0
min_mm = -100.0
max_mm = 100.0
[axes.z]
velocity_mm_s = 1568.0
acceleration_mm_s2 = 88710.0
jerk_mm_s3 = 3292.0
min_mm = -100.0
max_mm = 100.0
",
    gcode: "G21 G90 G17 G94 G40 G49 G54
G1 X-2.913 Y-0.679 Z0.056 F2880.5
G1 X-26.1292 Y32.3022
G1 X-26.3066 Y32.1605
G1 X-26.3087 Y32.1442
X-26.2918 Y32.0653
G1 X-26.2833 Y32.051
G1 X-26.0669 Y31.974
G1 X-26.0513 Y31.9789
X-25.8053 Y32.3222
G1 X-25.8078 Y32.3383
X-25.8115 Y32.3543
G1 X-26.4657 Y32.775
G1 X-26.7427 Y32.9162
M2
",
};

/// Case B: a whole circle into a two-turn helix in G19, at 100 µs; the G2 transition
/// between them must keep the jerk within the limit.
const CASE_B: Fixed = Fixed {
    name: "B: circle into helix, G19",
    toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 100
period_us = 100
tolerance_mm = 0.177
[axes.x]
velocity_mm_s = 2960.0
acceleration_mm_s2 = 12300.0
jerk_mm_s3 = 2198000.0
min_mm = -100.0
max_mm = 100.0
[axes.y]
velocity_mm_s = 3200.0
acceleration_mm_s2 = 841700.0
jerk_mm_s3 = 46070.0
min_mm = -100.0
max_mm = 100.0
[axes.z]
velocity_mm_s = 4303.0
acceleration_mm_s2 = 1239.0
jerk_mm_s3 = 186900.0
min_mm = -100.0
max_mm = 100.0
",
    gcode: "G21 G90
G64 P0.844
G19
G2 X0 Y0 Z0 J-1.492 K0.3629 F650.5
G2 X-2.5525 Y0 Z0 J-1.1761 K-0.3847 P2
M2
",
};

/// Minimised escapes of the random sweep (the reproducers as printed, travel left out),
/// replayed by [`extreme_escapes_stay_fixed`]: the first seven are tight zig-zags on
/// µm-scale lines; the rest dense polylines, circles meeting circles, and feeds on smoothed
/// pieces.
const FIXED: &[Fixed] = &[
    Fixed {
        name: "seed 1 case 14517, zig-zag, 19 moves at 157.4 %: X jerk 1.34x (a dropped remnant)",
        toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 157.4
machine = \"extremes\"
period_us = 142
tolerance_mm = 0.00104

[axes.x]
velocity_mm_s = 247.9
acceleration_mm_s2 = 52.74
jerk_mm_s3 = 23.4
min_mm = -10.0
max_mm = 10.0

[axes.y]
velocity_mm_s = 0.04688
acceleration_mm_s2 = 128.5
jerk_mm_s3 = 43580.0
min_mm = -10.0
max_mm = 10.0

[axes.z]
velocity_mm_s = 0.5545
acceleration_mm_s2 = 42810.0
jerk_mm_s3 = 250700.0
min_mm = -10.0
max_mm = 10.0
",
        gcode: "G21 G90 G94 G17 G40 G49 G54
G64
G1 X-0.001853 Y0.000225 Z-0.000052 F3.3446
G1 X-0.002414 Y-0.000073 Z-0.000218
G1 X-0.002513 Y-0.000073 Z-0.000228
G1 X-0.002523 Y0.000026 Z-0.000222
G1 X-0.00245 Y0.000094 Z-0.000214
G1 X-0.002533 Y0.00004 Z-0.00023
G1 X-0.002518 Y0.000138 Z-0.000215
G1 X-0.002522 Y0.00029 Z-0.000255
G1 X-0.002613 Y0.00025 Z-0.000246
G1 X-0.002514 Y0.000233 Z-0.000244
G1 X-0.002613 Y0.00022 Z-0.000254
G1 X-0.002635 Y0.000329 Z-0.000237
G1 X-0.002693 Y0.000779 Z-0.000143
G1 X-0.002682 Y0.000876 Z-0.000125
G1 X-0.003075 Y0.001284 Z-0.000141
G1 X-0.002427 Y0.001148 Z-0.000157
G1 X-0.001801 Y0.001067 Z-0.000037
G1 X-0.0019 Y0.001051 Z-0.000034
G1 X-0.001997 Y0.001029 Z-0.000028
M2
",
    },
    Fixed {
        name: "seed 24 case 106, zig-zag, 3 moves: Z jerk 2.52x",
        toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 100
period_us = 120
tolerance_mm = 0.002
[axes.x]
velocity_mm_s = 3.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 15.0
[axes.y]
velocity_mm_s = 7.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10.0
[axes.z]
velocity_mm_s = 7.0
acceleration_mm_s2 = 5.0
jerk_mm_s3 = 2.0
",
        gcode: "G21 G90 G94 G17 G40 G49 G54
G64
G1 X0.002837 Y0.000544 Z0.000112 F100
G1 X0.002851 Y0.000643 Z0.000111
G1 X0.00285 Y0.000544 Z0.000121
M2
",
    },
    Fixed {
        name: "seed 24 case 121, zig-zag, 4 moves: Y jerk 1.34x",
        toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 100
period_us = 100
tolerance_mm = 0.03
[axes.x]
velocity_mm_s = 10.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 700000.0
[axes.y]
velocity_mm_s = 3.0
acceleration_mm_s2 = 7000.0
jerk_mm_s3 = 5000.0
[axes.z]
velocity_mm_s = 5000.0
acceleration_mm_s2 = 100.0
jerk_mm_s3 = 300000.0
",
        gcode: "G21 G90 G94 G17 G40 G49 G54
G64
G1 X-0.00263 Y-0.003989 Z0.000733 F20
G1 X-0.002624 Y-0.003889 Z0.000733
G1 X-0.002709 Y-0.003835 Z0.000733
G1 X-0.002622 Y-0.003884 Z0.000729
M2
",
    },
    Fixed {
        name: "seed 1 case 244, zig-zag, 3 moves: Z jerk 3.28x",
        toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 100
period_us = 70
tolerance_mm = 0.5
[axes.x]
velocity_mm_s = 4000.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 2000.0
[axes.y]
velocity_mm_s = 100.0
acceleration_mm_s2 = 20000.0
jerk_mm_s3 = 5.0
[axes.z]
velocity_mm_s = 5.0
acceleration_mm_s2 = 2000000.0
jerk_mm_s3 = 5.0
",
        gcode: "G21 G90 G94 G17 G40 G49 G54
G64
G1 X0.00003 Y-0.0001 Z0.00001 F100000
G1 X0.00001 Y-0.0002 Z0.00001
G1 X0.00002 Y-0.0001 Z0
M2
",
    },
    Fixed {
        name: "seed 1 case 378, zig-zag, 4 moves: X jerk 2.05x",
        toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 100
period_us = 60
tolerance_mm = 0.09
[axes.x]
velocity_mm_s = 7.0
acceleration_mm_s2 = 30.0
jerk_mm_s3 = 300.0
[axes.y]
velocity_mm_s = 7.0
acceleration_mm_s2 = 30.0
jerk_mm_s3 = 20000.0
[axes.z]
velocity_mm_s = 7.0
acceleration_mm_s2 = 1.0
jerk_mm_s3 = 300.0
",
        gcode: "G21 G90 G94 G17 G40 G49 G54
G64 P0.5
G1 X0.00232 Y0.002998 Z-0.000043 F30
G1 X0.002312 Y0.002899 Z-0.000043
G1 X0.002319 Y0.002799 Z-0.000043
G1 X0.00227 Y0.002886 Z-0.000043
M2
",
    },
    Fixed {
        name: "seed 1 case 556, zig-zag, 3 moves: Z jerk 1.12x",
        toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 100
period_us = 80
tolerance_mm = 0.05
[axes.x]
velocity_mm_s = 90.0
acceleration_mm_s2 = 100.0
jerk_mm_s3 = 5000.0
[axes.y]
velocity_mm_s = 9.0
acceleration_mm_s2 = 5000.0
jerk_mm_s3 = 5000.0
[axes.z]
velocity_mm_s = 90.0
acceleration_mm_s2 = 100.0
jerk_mm_s3 = 23.0
",
        gcode: "G21 G90 G94 G17 G40 G49 G54
G64 P0.02
G1 X-0.001432 Y0.002295 Z0.000114 F90
G1 X-0.001509 Y0.002231 Z0.000105
G1 X-0.001445 Y0.002307 Z0.000112
M2
",
    },
    Fixed {
        name: "seed 1 case 898, zig-zag, 3 moves: Y acceleration 1.27x",
        toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 100
period_us = 100
tolerance_mm = 0.009
[axes.x]
velocity_mm_s = 1.0
acceleration_mm_s2 = 4.0
jerk_mm_s3 = 80000.0
[axes.y]
velocity_mm_s = 1.0
acceleration_mm_s2 = 0.4
jerk_mm_s3 = 2000.0
[axes.z]
velocity_mm_s = 6.0
acceleration_mm_s2 = 3.0
jerk_mm_s3 = 900.0
",
        gcode: "G21 G90 G94 G17 G40 G49 G54
G64
G1 X-0.00588 Y0.00068 Z0.0003 F2
G1 X-0.00598 Y0.00066 Z0.0003
G1 X-0.00588 Y0.00066 Z0.0003
M2
",
    },
    Fixed {
        name: "seed 2 case 124, zig-zag, 3 moves: Z jerk 2.92x",
        toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 100
period_us = 200
tolerance_mm = 0.2
[axes.x]
velocity_mm_s = 100.0
acceleration_mm_s2 = 5.0
jerk_mm_s3 = 40.0
[axes.y]
velocity_mm_s = 300.0
acceleration_mm_s2 = 3.0
jerk_mm_s3 = 3000.0
[axes.z]
velocity_mm_s = 300.0
acceleration_mm_s2 = 0.04
jerk_mm_s3 = 20.0
",
        gcode: "G21 G90 G94 G17 G40 G49 G54
G64 P0.1
G1 X-0.00002 Y-0.0001 Z0 F10000
G1 X-0.00002 Y-0.0002 Z0.00002
G1 X-0.00001 Y-0.0001 Z0.00002
M2
",
    },
    Fixed {
        name: "seed 24 case 48, dense, 10 moves: X jerk 815x",
        toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 100
period_us = 60
tolerance_mm = 0.1
[axes.x]
velocity_mm_s = 100000.0
acceleration_mm_s2 = 100000000.0
jerk_mm_s3 = 20000.0
[axes.y]
velocity_mm_s = 100000.0
acceleration_mm_s2 = 100000000.0
jerk_mm_s3 = 20000.0
[axes.z]
velocity_mm_s = 100000.0
acceleration_mm_s2 = 100000000.0
jerk_mm_s3 = 20000.0
",
        gcode: "G21 G90 G94 G17 G40 G49 G54
G64
G1 X-0.0613 Y-0.0046 Z-0.0327 F300000
G1 X-0.0638 Y-0.0023 Z-0.0341
G1 X-0.0676 Y0.0276 Z-0.0367
G1 X-0.0667 Y0.0311 Z-0.0363
G1 X-0.0111 Y0.067 Z-0.0071
G1 X-0.008 Y0.0661 Z-0.0054
G1 X-0.005 Y0.065 Z-0.0038
G1 X0.0256 Y0.005 Z0.0138
G1 X0.025 Y0.0015 Z0.0135
G1 X-0.015 Y-0.0397 Z-0.0072
M2
",
    },
    Fixed {
        name: "seed 1 case 743, dense, 10 moves: X jerk 1.51e+03x",
        toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 100
period_us = 90
tolerance_mm = 0.001
[axes.x]
velocity_mm_s = 3000.0
acceleration_mm_s2 = 2000.0
jerk_mm_s3 = 1000.0
[axes.y]
velocity_mm_s = 3000.0
acceleration_mm_s2 = 2000.0
jerk_mm_s3 = 1000.0
[axes.z]
velocity_mm_s = 3000.0
acceleration_mm_s2 = 2000.0
jerk_mm_s3 = 1000.0
",
        gcode: "G21 G90 G94 G17 G40 G49 G54
G64 P0.004
G1 X-0.00146 Y0.00413 Z-0.0065 F10000
G1 X-0.00297 Y0.00483 Z-0.00768
G1 X-0.0125 Y0.0044 Z-0.00759
G1 X-0.01391 Y0.00356 Z-0.00638
G1 X-0.01385 Y-0.0016 Z0.00164
G1 X-0.01242 Y-0.00235 Z0.00289
G1 X-0.00289 Y-0.00219 Z0.00322
G1 X-0.0014 Y-0.00139 Z0.00208
G1 X-0.00095 Y0.00378 Z-0.00593
G1 X-0.00189 Y0.00589 Z-0.00926
M2
",
    },
    Fixed {
        name: "seed 24 case 104, circles, 2 moves: Z jerk 11.9x",
        toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 100
period_us = 100
tolerance_mm = 0.01
[axes.x]
velocity_mm_s = 70000.0
acceleration_mm_s2 = 60.0
jerk_mm_s3 = 40.0
[axes.y]
velocity_mm_s = 70000.0
acceleration_mm_s2 = 60.0
jerk_mm_s3 = 40.0
[axes.z]
velocity_mm_s = 70000.0
acceleration_mm_s2 = 60.0
jerk_mm_s3 = 40.0
",
        gcode: "G21 G90 G94 G17 G40 G49 G54
G64 P0.003
G19
G3 X-0.0004234819479414501 Y0 Z0 J-0.0013838109872492703 K0.0007319206512907662 F200000
G2 X-0.000433276579744813 Y0.0000013447969065991469 Z-0.00023068836146214624 J0.00021570628321634114 K-0.00011409064153555204 P2
M2
",
    },
    Fixed {
        name: "seed 24 case 129, circles, 2 moves: Y jerk 1.23x",
        toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 100
period_us = 200
tolerance_mm = 0.6
[axes.x]
velocity_mm_s = 50.0
acceleration_mm_s2 = 5000000.0
jerk_mm_s3 = 100.0
[axes.y]
velocity_mm_s = 50.0
acceleration_mm_s2 = 5000000.0
jerk_mm_s3 = 100.0
[axes.z]
velocity_mm_s = 50.0
acceleration_mm_s2 = 5000000.0
jerk_mm_s3 = 100.0
",
        gcode: "G21 G90 G94 G17 G40 G49 G54
G64
G2 X0 Y0 Z-0.0003787746093588399 I0.001153907683954119 J0.001294387706416343 F7
G2 X0 Y0 Z-0.0003787746093588399 I-0.00016372863091809934 J-0.00012586624452701472 P2
M2
",
    },
    Fixed {
        name: "seed 24 case 32, dense, 16 moves: X acceleration 41.7x",
        toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 100
period_us = 1000
tolerance_mm = 0.2
[axes.x]
velocity_mm_s = 5.0
acceleration_mm_s2 = 5.0
jerk_mm_s3 = 40.0
[axes.y]
velocity_mm_s = 5.0
acceleration_mm_s2 = 5.0
jerk_mm_s3 = 40.0
[axes.z]
velocity_mm_s = 5.0
acceleration_mm_s2 = 5.0
jerk_mm_s3 = 40.0
",
        gcode: "G21 G90 G94 G17 G40 G49 G54
G64
G1 X-0.062 Y-0 Z0.225 F30
G1 X-0.058 Y-0 Z0.233
G1 X-0.054 Y0 Z0.241
G1 X-0.049 Y0.001 Z0.249
G1 X-0.043 Y0.001 Z0.255
G1 X0.19 Y0.008 Z0.271
G1 X0.197 Y0.008 Z0.266
G1 X0.204 Y0.008 Z0.26
G1 X0.234 Y0.008 Z0.226
G1 X0.239 Y0.008 Z0.219
G1 X0.208 Y-0 Z-0.013
G1 X0.201 Y-0 Z-0.019
G1 X-0.026 Y-0.002 Z-0.026
G1 X-0.033 Y-0.002 Z-0.021
G1 X-0.04 Y-0.002 Z-0.015
G1 X-0.046 Y-0.002 Z-0.008
M2
",
    },
    Fixed {
        name: "seed 24 case 198, dense, 17 moves: XYZ speed 1.15x the feed at 63 %",
        toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 63
period_us = 1790
tolerance_mm = 0.0079
[axes.x]
velocity_mm_s = 1.104
acceleration_mm_s2 = 203.5
jerk_mm_s3 = 110800000.0
[axes.y]
velocity_mm_s = 273.5
acceleration_mm_s2 = 945.2
jerk_mm_s3 = 37480000.0
[axes.z]
velocity_mm_s = 1436.0
acceleration_mm_s2 = 405000.0
jerk_mm_s3 = 2341000.0
",
        gcode: "G21 G90 G94 G17 G40 G49 G54
G64 P0.0326
G1 X-0.00072 Y0.00005 Z0.00001 F3.7858
G1 X-0.00089 Y0.00004 Z0
G1 X-0.00174 Y-0.00015 Z0.00001
G1 X-0.00196 Y-0.00033 Z0.00002
G1 X-0.00278 Y-0.00461 Z0.00002
G1 X-0.00274 Y-0.00474 Z0
G1 X-0.00217 Y-0.00518 Z0.00002
G1 X-0.00158 Y-0.00513 Z0.00002
G1 X0.00028 Y-0.00432 Z0
G1 X0.00039 Y-0.00422 Z0.00002
G1 X0.00047 Y-0.0041 Z0.00006
G1 X0.0001 Y0.00023 Z0.00006
G1 X0.00003 Y0.00035 Z0.00009
G1 X-0.0002 Y0.00054 Z0.00006
G1 X-0.00122 Y0.00106 Z0.00007
G1 X-0.00136 Y0.00109 Z0.00009
G1 X-0.00252 Y0.001 Z0.00013
M2
",
    },
    Fixed {
        name: "seed 1 case 100, dense, 16 moves: XYZ speed 1.018x the feed",
        toml: "# kerf sim --config m.toml p.ngc --out o.csv --override 100
period_us = 400
tolerance_mm = 0.006
[axes.x]
velocity_mm_s = 100000.0
acceleration_mm_s2 = 100000.0
jerk_mm_s3 = 50000000.0
[axes.y]
velocity_mm_s = 100000.0
acceleration_mm_s2 = 100000.0
jerk_mm_s3 = 50000000.0
[axes.z]
velocity_mm_s = 100000.0
acceleration_mm_s2 = 100000.0
jerk_mm_s3 = 50000000.0
",
        gcode: "G21 G90 G94 G17 G40 G49 G54
G64
G1 X-0.00155 Y-0.00191 Z0.00209 F4
G1 X-0.00163 Y-0.00193 Z0.00215
G1 X-0.00171 Y-0.00194 Z0.00221
G1 X-0.00483 Y0.0003 Z0.00344
G1 X-0.00487 Y0.0004 Z0.00343
G1 X-0.00458 Y0.00303 Z0.00253
G1 X-0.00453 Y0.0031 Z0.00249
G1 X-0.0028 Y0.0041 Z0.00147
G1 X-0.0027 Y0.00411 Z0.00143
G1 X0.00032 Y0.00261 Z0.00101
G1 X0.00037 Y0.00253 Z0.00103
G1 X0.00033 Y-0.00065 Z0.00296
G1 X0.00028 Y-0.00071 Z0.00303
G1 X0.00022 Y-0.00076 Z0.00309
G1 X0.00016 Y-0.0008 Z0.00316
G1 X0.0001 Y-0.00085 Z0.00322
M2
",
    },
];

/// Runs a fixed case; the report of its failure, if it fails.
fn check_fixed(f: &Fixed) -> Option<String> {
    let m = machine_from_toml(f.toml);
    let v = check_text(&m, f.gcode);
    v.first()?;
    // Travel for the configuration: a power of ten above twice what the moves reach.
    let reach = parse(f.gcode)
        .unwrap_or_default()
        .iter()
        .map(|mv| match mv.path {
            kerf_geom::Path::Arc(a) => {
                (a.center.amax() + (a.start - a.center).norm()).max(a.end.amax())
            }
            _ => mv.path.end().amax(),
        })
        .fold(0.0, f64::max);
    let travel = 10f64.powi((2.0 * reach).max(10.0).log10().ceil() as i32);
    Some(format!(
        "fixed case {}: {} cycles\n{}kerf sim --config m.toml p.ngc --out o.csv --override {}\n--- p.ngc ---\n{}--- m.toml ---\n{}",
        f.name,
        v.cycles,
        v.describe(),
        m.override_pct,
        f.gcode,
        toml(&m, travel.min(1e6))
    ))
}

#[test]
fn extreme_escapes_stay_fixed() {
    let mut tally = Tally::default();
    for &(seed, cases) in ESCAPES {
        for &case in cases {
            // Replayed as found (`KERF_EXTREME_ONLY` on the sweep minimises one).
            let o = run_case(seed, case, Duration::ZERO);
            tally.add(case, o);
        }
    }
    for (k, f) in FIXED.iter().enumerate() {
        tally.cases += 1;
        if let Some(report) = check_fixed(f) {
            tally.failures.push((k, report));
        }
    }
    fail_on(&tally, "escapes");
}

#[test]
fn case_a_zig_zag_on_an_axis_whose_acceleration_is_27_times_its_jerk() {
    if let Some(report) = check_fixed(&CASE_A) {
        panic!("{report}");
    }
}

#[test]
fn case_b_circle_into_a_helix_in_g19() {
    if let Some(report) = check_fixed(&CASE_B) {
        panic!("{report}");
    }
}

// ---------------------------------------------------------------------------------------
// The generators themselves

/// The arcs written as G-code are the ones the generator meant: the end point, the sweep
/// with its turns, the tangents at both ends (so that "tangent" arcs are tangent).
#[test]
fn generated_arcs_are_the_arcs_the_interpreter_reads() {
    let mut rng = Rng(0xa2c5_0024);
    for k in 0..300 {
        let mut b = Builder::new(600.0, Corner::Blend);
        b.line(unit_vec(&mut rng) * rng.log(0.1, 10.0));
        let before = b.dir;
        let plane = random_plane(&mut rng);
        let ccw = rng.pick(2) == 0;
        let r = rng.log(0.01, 10.0);
        let tangent = b.tangent_radial(plane, ccw, r);
        let radial = tangent.unwrap_or_else(|| random_radial(&mut rng, plane, r));
        let theta = if rng.pick(3) == 0 {
            TAU
        } else {
            rng.range(0.05, TAU - 0.05)
        };
        let turns = 1 + rng.pick(3) as u32;
        let rise = if rng.pick(2) == 0 {
            0.0
        } else {
            rng.range(-5.0, 5.0)
        };
        let start = b.p;
        b.arc(plane, ccw, radial, theta, turns, rise);
        let p = Program {
            blocks: b.blocks.clone(),
            decimals: None,
        };
        let text = gcode(&p);
        let moves = parse(&text).unwrap();
        assert_eq!(moves.len(), 2, "{k}: {text}");
        let kerf_geom::Path::Arc(arc) = moves[1].path else {
            panic!("{k}: not an arc: {text}");
        };
        assert!((arc.end - b.p).norm() < 1e-9, "{k}: end {text}");
        let Shape::Arc { centre, .. } = b.blocks[1].shape else {
            unreachable!()
        };
        let g = ArcGeom::new(start, b.p, plane, ccw, centre, turns);
        assert!(
            (arc.sweep_rad.abs() - g.sweep).abs() < 1e-6,
            "{k}: sweep {} against {}: {text}",
            arc.sweep_rad,
            g.sweep
        );
        let curve = kerf_geom::Curve::from_path(&moves[1].path);
        let t0 = curve.eval(0.0).tangent;
        let t1 = curve.eval(1e300).tangent;
        assert!(
            (t0 - g.tangent(g.radial0)).norm() < 1e-6,
            "{k}: start tangent"
        );
        assert!(
            (t1 - b.dir).norm() < 1e-6,
            "{k}: end tangent {t1:?} {:?}",
            b.dir
        );
        if tangent.is_some() {
            let n = plane.normal();
            let (a, c) = (in_plane(before, n), in_plane(t0, n));
            assert!(
                a.normalize().dot(&c.normalize()) > 1.0 - 1e-9,
                "{k}: not tangent: {text}"
            );
        }
    }
}

/// A reproducer replays exactly: the configuration text reads back as the same machine,
/// and the G-code is accepted and ends where the program does. (An arc too small for
/// LinuxCNC's whole-turn rule, its end within 0.1 µm beside the start's ray, is read as a
/// whole turn spiralling to its end, so there may be more moves than blocks.)
#[test]
fn reproducers_replay_exactly() {
    for case in 0..60 {
        let c = make_case(11, case);
        let text = toml(&c.machine, travel_mm(&c.program));
        assert_eq!(machine_from_toml(&text), c.machine, "case {case}:\n{text}");
        let moves = parse(&gcode(&c.program)).unwrap_or_else(|e| panic!("case {case}: {e}"));
        assert!(moves.len() >= c.program.blocks.len(), "case {case}");
        let end = c.program.blocks.last().unwrap().end;
        assert_eq!(moves.last().unwrap().path.end(), end, "case {case}");
        // The same case whatever ran before it.
        let again = make_case(11, case);
        assert_eq!(again.program, c.program);
        assert_eq!(again.machine, c.machine);
    }
}
