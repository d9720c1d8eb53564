//! Machines and paths drawn at random for the point-wise prototype ([`crate::pointwise`]):
//! what its swept tests and `cam_table --pointwise-raise` share, so that both draw the
//! same machines from the same seed.

use kerf_geom::{AxisLimits, MachineLimits, Vec3};

use crate::bound::{BoundMachine, Piece, Shape};
use crate::jerk::JerkMachine;

/// Draws from [0, 1) (a 64-bit linear congruential generator, the high bits).
#[derive(Clone, Copy, Debug)]
pub struct Draw(pub u64);

impl Draw {
    /// The next draw from [0, 1).
    pub fn unit(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    /// The next draw from [`lo`, `hi`).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

/// A machine and a feed drawn from slow and soft to fast and stiff, axis by axis.
#[derive(Clone, Copy, Debug)]
pub struct Drawn {
    /// Axis velocities, mm/s (50 to 300).
    pub velocity_mm_s: [f64; 3],
    /// Axis accelerations, mm/s² (300 to 3,000).
    pub acceleration_mm_s2: [f64; 3],
    /// Axis jerks, mm/s³ (5,000 to 80,000).
    pub jerk_mm_s3: [f64; 3],
    /// Path tolerance, mm (0.005 to 0.05).
    pub tolerance_mm: f64,
    /// Programmed feed, mm/s (20 to 150).
    pub feed_mm_s: f64,
}

impl Drawn {
    /// The next machine and feed of `draw`.
    pub fn draw(draw: &mut Draw) -> Drawn {
        Drawn {
            velocity_mm_s: [0, 1, 2].map(|_| draw.range(50.0, 300.0)),
            acceleration_mm_s2: [0, 1, 2].map(|_| draw.range(300.0, 3000.0)),
            jerk_mm_s3: [0, 1, 2].map(|_| draw.range(5_000.0, 80_000.0)),
            tolerance_mm: draw.range(0.005, 0.05),
            feed_mm_s: draw.range(20.0, 150.0),
        }
    }
}

/// The machine of the bounds and the output monitor's limits with the same numbers, at
/// the period `period_s`.
pub fn machine(
    velocity_mm_s: [f64; 3],
    acceleration_mm_s2: [f64; 3],
    jerk_mm_s3: [f64; 3],
    tolerance_mm: f64,
    period_s: f64,
) -> (JerkMachine, MachineLimits) {
    let mut axes = [None; 6];
    for (i, axis) in axes.iter_mut().take(3).enumerate() {
        *axis = Some(AxisLimits {
            velocity_units_s: velocity_mm_s[i],
            acceleration_units_s2: acceleration_mm_s2[i],
            jerk_units_s3: jerk_mm_s3[i],
        });
    }
    (
        JerkMachine {
            base: BoundMachine {
                velocity_mm_s,
                acceleration_mm_s2,
                tolerance_mm,
            },
            jerk_mm_s3,
        },
        MachineLimits {
            axes,
            period_s,
            tolerance_mm,
        },
    )
}

/// A line from `start` to `end` at `feed_mm_s`.
pub fn line(start: [f64; 3], end: [f64; 3], feed_mm_s: f64) -> Piece {
    Piece {
        shape: Shape::Line {
            start: Vec3::from(start),
            end: Vec3::from(end),
        },
        feed_mm_s,
    }
}

/// A helix about Z from the origin: radius `r`, `turns`, rising `rise_mm` a turn.
pub fn helix(r: f64, turns: f64, rise_mm: f64, feed_mm_s: f64) -> Piece {
    Piece {
        shape: Shape::Arc {
            center: Vec3::new(-r, 0.0, 0.0),
            e1: Vec3::x(),
            e2: Vec3::y(),
            radius_mm: r,
            from_rad: 0.0,
            to_rad: turns * std::f64::consts::TAU,
            axial_per_rad: Vec3::new(0.0, 0.0, rise_mm / std::f64::consts::TAU),
        },
        feed_mm_s,
    }
}

/// The three swept paths at `feed_mm_s`: corners (blended within the tolerance), a
/// reversal, and a helix of radius 1.5 mm, 1.25 turns, 1 mm a turn.
pub fn paths(feed_mm_s: f64) -> [(&'static str, Vec<Piece>); 3] {
    [
        (
            "corners",
            vec![
                line([0.0; 3], [3.0, 0.0, 0.0], feed_mm_s),
                line([3.0, 0.0, 0.0], [3.0, 2.0, 0.5], feed_mm_s),
                line([3.0, 2.0, 0.5], [1.0, 3.0, 0.5], feed_mm_s),
            ],
        ),
        (
            "reversal",
            vec![
                line([0.0; 3], [2.0, 1.0, 0.0], feed_mm_s),
                line([2.0, 1.0, 0.0], [0.0, 0.0, 0.0], feed_mm_s),
            ],
        ),
        ("helix", vec![helix(1.5, 1.25, 1.0, feed_mm_s)]),
    ]
}

/// One pair of runs of [`raise_sweep`]: a path on a drawn machine, and again with one
/// axis's limit raised.
#[derive(Clone, Copy, Debug)]
pub struct Raised {
    /// The case (machine) drawn, from 0.
    pub case: u64,
    /// The path's name ([`paths`]).
    pub path: &'static str,
    /// The period of both runs, s.
    pub period_s: f64,
    /// The programmed feed, mm/s.
    pub feed_mm_s: f64,
    /// The limit raised: 0 velocity, 1 acceleration, 2 jerk.
    pub which: usize,
    /// The axis whose limit was raised.
    pub axis: usize,
    /// The factor it was raised by (1.1 to 3).
    pub factor: f64,
    /// The time of the drawn machine's run and of the raised one's, s.
    pub times_s: [f64; 2],
}

impl Raised {
    /// Whether the raised machine took more than 1 % and a period longer: what
    /// kerf-pipeline's `monotonic` property calls slower.
    pub fn slower(&self) -> bool {
        self.times_s[1] > 1.01 * self.times_s[0] + self.period_s
    }
}

/// Whether the point-wise prototype is monotonic in the limits, as Kerf's core is:
/// `cases` machines drawn from `seed` as the swept tests draw them (every other one at
/// 250 µs), the three [`paths`] on each, run again with one axis's velocity,
/// acceleration or jerk raised 1.1 to 3-fold, on a grid of `ds_mm`. Every pair of runs,
/// or why a run failed (stuck, or a fallback).
pub fn raise_sweep(
    seed: u64,
    cases: u64,
    search: crate::pointwise::Search,
    ds_mm: f64,
) -> Result<Vec<Raised>, String> {
    let mut draw = Draw(seed);
    let mut out = Vec::new();
    for case in 0..cases {
        let Drawn {
            velocity_mm_s: v,
            acceleration_mm_s2: a,
            jerk_mm_s3: j,
            tolerance_mm,
            feed_mm_s,
        } = Drawn::draw(&mut draw);
        let axis = ((draw.unit() * 3.0) as usize).min(2);
        let which = ((draw.unit() * 3.0) as usize).min(2);
        let factor = draw.range(1.1, 3.0);
        let period_s = if case % 2 == 1 { 0.00025 } else { 0.001 };
        let mut raised = [v, a, j];
        raised[which][axis] *= factor;
        for (path, pieces) in paths(feed_mm_s) {
            let mut times_s = [0.0; 2];
            for (k, [vv, aa, jj]) in [[v, a, j], raised].into_iter().enumerate() {
                let (m, limits) = machine(vv, aa, jj, tolerance_mm, period_s);
                let run = crate::pointwise::Grid::from_pieces(&pieces, &m, ds_mm)
                    .run_with(&limits, search);
                if run.stuck || run.fallbacks > 0 {
                    return Err(format!("case {case} {path}: stuck or fell back"));
                }
                times_s[k] = run.time_s;
            }
            out.push(Raised {
                case,
                path,
                period_s,
                feed_mm_s,
                which,
                axis,
                factor,
                times_s,
            });
        }
    }
    Ok(out)
}
