//! The `line` of the setpoints on smoothed curves, measured from the output.
//!
//! The contract (README, `kerf sim`): the `line` column is the source line of the move
//! being run; on a smoothed curve, which stands for several programmed moves, it is the
//! line of the one of them nearest to the setpoint (the earlier of equally near ones).
//!
//! Each run goes through [`kerf_pipeline::run`], the loop `kerf sim` runs (the daemon runs
//! the same tracker). Which smoothed piece each setpoint lies on (its first move and how
//! many it stands for) is taken from a second, bare loop of the planner and the motion
//! core over the same program, whose positions must equal the run's bit for bit; the
//! nearest move is then found by brute force over the piece's moves with a distance of the
//! test's own, independent of the tracker's code. The programs are dense polylines as CAM
//! writes them and harder ones that turn back towards themselves (trochoidal loops,
//! hairpins, zig-zags, noise), where the moves near a setpoint are not in path order: a
//! tracker that scanned only forward from the move it named last, and stopped at the first
//! move that lay farther away, named moves up to 90 moves and 0.33 mm away from the
//! nearest of the piece (and moves of the next piece).
//!
//! `KERF_SEED=N KERF_CASES=M` runs another seed with more cases.

mod common;
use common::*;
use kerf_geom::{CornerMode, Move, Path, Vec3};
use kerf_motion::{MachineLimits, MotionCore, Setpoint};
use kerf_pipeline::{Interpolator, Planned, Poll, RunOptions, run};
use kerf_plan::Planner;

/// How much farther the named move may lie than the nearest move of the piece: the
/// rounding of two ways of computing a distance.
const DISTANCE_ROUNDING_MM: f64 = 1e-9;

/// A machine with random limits, tolerance and period (the property tests' range).
fn random_limits(rng: &mut Rng) -> MachineLimits {
    let mut m = mill(100.0, 1000.0, 10000.0, rng.log(0.002, 0.1));
    m.period_s = [0.000125, 0.00025, 0.0005, 0.001, 0.002, 0.004][rng.pick(6)];
    for ax in m.axes.iter_mut().take(3) {
        *ax = Some(kerf_motion::AxisLimits {
            velocity_units_s: rng.log(30.0, 500.0),
            acceleration_units_s2: rng.log(300.0, 5000.0),
            jerk_units_s3: rng.log(3000.0, 200_000.0),
        });
    }
    m
}

/// Builds a polyline of feed lines; every move's line is its index + 1, so that a line
/// names one move.
struct Polyline {
    moves: Vec<Move>,
    at: Vec3,
    feed: f64,
    corner: CornerMode,
    scale: f64,
}

impl Polyline {
    fn new() -> Polyline {
        Polyline {
            moves: Vec::new(),
            at: Vec3::zeros(),
            feed: 3000.0,
            corner: blend(),
            scale: 1e4,
        }
    }

    /// The feed, the path tolerance (`None`: the machine's) and the decimals of what
    /// follows.
    fn style(&mut self, feed: f64, tolerance_mm: Option<f64>, decimals: i32) {
        self.feed = feed;
        self.corner = CornerMode::Blend {
            tolerance_mm,
            naive_cam_mm: None,
        };
        self.scale = 10f64.powi(decimals);
    }

    /// A line to `to` rounded to the decimals (none if that is where it is).
    fn to(&mut self, to: Vec3) {
        let r = |v: f64| (v * self.scale).round() / self.scale;
        let q = Vec3::new(r(to.x), r(to.y), r(to.z));
        if q != self.at {
            let mut m = line(self.moves.len() as u32 + 1, self.at, q, self.feed);
            m.corner = self.corner;
            self.moves.push(m);
            self.at = q;
        }
    }
}

/// A random tolerance: the machine's, or a G64 P from 1 µm to 1 mm.
fn tolerance(rng: &mut Rng) -> Option<f64> {
    (rng.pick(3) != 0).then(|| rng.log(0.001, 1.0))
}

/// Arcs and circles of random radius and plane sampled at random spacing, rounded to 3–6
/// decimals (the property tests' rounded polylines).
fn rounded_arcs(rng: &mut Rng, b: &mut Polyline) {
    b.style(
        rng.log(300.0, 12000.0),
        tolerance(rng),
        3 + rng.pick(4) as i32,
    );
    let (_, u, v) = plane_basis(rng);
    let r = rng.log(0.5, 50.0);
    let spacing = rng.log(0.002, 0.5).min(r);
    let step = spacing / r * rng.sign();
    let sweep = rng.range(0.3, std::f64::consts::TAU);
    let k = ((sweep / step.abs()) as usize).clamp(5, 400);
    let center = b.at + Vec3::new(rng.range(-5.0, 5.0), rng.range(-5.0, 5.0), 0.0);
    let ang0 = rng.range(0.0, std::f64::consts::TAU);
    for i in 0..=k {
        let a = ang0 + step * i as f64;
        b.to(center + (u * a.cos() + v * a.sin()) * r);
    }
}

/// Raster passes over a smooth surface (the CAM corpus' rasters): a point every
/// 0.01–0.2 mm along X, 3–5 decimals, rows joined by a step-over.
fn raster(rng: &mut Rng, b: &mut Polyline) {
    b.style(
        rng.log(600.0, 9000.0),
        tolerance(rng),
        3 + rng.pick(3) as i32,
    );
    let amp = rng.range(0.2, 2.0);
    let (l1, l2) = (rng.log(1.0, 10.0), rng.log(2.0, 10.0));
    let spacing = rng.log(0.01, 0.2);
    let width = rng.range(1.0, 6.0);
    let rows = 1 + rng.pick(3);
    let o = b.at;
    let z = |x: f64, y: f64| amp * (x / l1).sin() * (y / l2).cos();
    let per_row = ((width / spacing) as usize).max(2);
    for row in 0..rows {
        let y = 0.5 * row as f64;
        for i in 0..=per_row {
            let i = if row % 2 == 1 { per_row - i } else { i };
            let x = width * i as f64 / per_row as f64;
            b.to(o + Vec3::new(x, y, z(x, y)));
        }
    }
}

/// A wave, or a zig-zag, along a random direction with many short moves and noise.
fn wiggle(rng: &mut Rng, b: &mut Polyline) {
    b.style(
        rng.log(300.0, 12000.0),
        tolerance(rng),
        3 + rng.pick(3) as i32,
    );
    let dir = unit_vec(rng);
    let side = {
        let w = unit_vec(rng);
        (w - dir * w.dot(&dir)).normalize()
    };
    let spacing = rng.log(0.001, 0.1);
    let amp = rng.log(0.0005, 0.5);
    let wavelength = rng.log(0.005, 5.0);
    let noise = rng.log(1e-5, 0.01);
    let zig = rng.pick(3) == 0;
    let o = b.at;
    for i in 1..=20 + rng.pick(300) {
        let s = i as f64 * spacing;
        let off = if zig {
            0.1 * amp * if i % 2 == 0 { 1.0 } else { -1.0 }
        } else {
            amp * (std::f64::consts::TAU * s / wavelength).sin()
        };
        let n = Vec3::new(
            rng.range(-noise, noise),
            rng.range(-noise, noise),
            rng.range(-noise, noise),
        );
        b.to(o + dir * s + side * off + n);
    }
}

/// Turns in the XY plane through up to 1.5 turns (a hairpin, a trochoidal loop) in steps
/// of 3° to 40°, after a straight stretch, with short moves of uneven length.
fn loops(rng: &mut Rng, b: &mut Polyline) {
    b.style(
        rng.log(300.0, 30000.0),
        tolerance(rng),
        3 + rng.pick(3) as i32,
    );
    let h = rng.log(0.001, 0.2);
    let mut heading = rng.range(0.0, std::f64::consts::TAU);
    let mut exact = b.at;
    for _ in 0..1 + rng.pick(4) {
        let straight = rng.pick(30);
        let turn = rng.range(-3.0, 3.0) * std::f64::consts::PI;
        let step = rng.range(0.05, 0.7).copysign(turn);
        let turns = (turn / step).abs() as usize;
        for k in 0..straight + turns {
            if k >= straight {
                heading += step;
            }
            exact += Vec3::new(heading.cos(), heading.sin(), 0.0) * h * rng.range(0.5, 1.5);
            b.to(exact);
        }
    }
}

/// A random walk of small turns with moves whose lengths span up to three decades.
fn walk(rng: &mut Rng, b: &mut Polyline) {
    b.style(
        rng.log(300.0, 60000.0),
        tolerance(rng),
        3 + rng.pick(3) as i32,
    );
    let lo = rng.log(0.001, 1.0);
    let hi = lo * rng.log(1.0, 1000.0);
    let turn = rng.log(0.001, 0.8);
    let mut dir = unit_vec(rng);
    let mut exact = b.at;
    for _ in 0..10 + rng.pick(100) {
        let w = unit_vec(rng);
        dir = (dir + (w - dir * w.dot(&dir)) * turn.tan()).normalize();
        exact += dir * rng.log(lo, hi);
        b.to(exact);
    }
}

/// A program of `n` moves or more, of the kinds above in random order.
fn program(rng: &mut Rng, n: usize) -> Vec<Move> {
    let mut b = Polyline::new();
    while b.moves.len() < n {
        match rng.pick(5) {
            0 => rounded_arcs(rng, &mut b),
            1 => raster(rng, &mut b),
            2 => wiggle(rng, &mut b),
            3 => loops(rng, &mut b),
            _ => walk(rng, &mut b),
        }
    }
    b.moves
}

/// The setpoints of the planner and the motion core alone, without the tracker: each
/// names the segment being run (on a smoothed piece, its first move and its move count).
fn bare_setpoints(moves: &[Move], limits: &MachineLimits, capacity: usize) -> Vec<Setpoint> {
    let mut planner = Planner::new(*limits);
    let mut segments = Vec::new();
    for m in moves {
        planner.push(m, &mut segments).unwrap();
    }
    planner.finish(&mut segments);
    let mut segments = segments.into_iter();
    let mut interp = Interpolator::new(MotionCore::new(limits.period_s, capacity));
    let mut out = vec![Setpoint::default()];
    while !interp.finished() {
        interp
            .feed(
                || match segments.next() {
                    Some(s) => Poll::Ready(Planned::Segment(s, 0)),
                    None => Poll::End,
                },
                &mut kerf_geom::machine::InstantMachine,
            )
            .unwrap();
        let mut sp = Setpoint::default();
        interp.step(&mut sp);
        out.push(sp);
    }
    out
}

/// Distance from `p` to the segment `a`–`b` (the test's own formula).
fn segment_distance(a: Vec3, b: Vec3, p: Vec3) -> f64 {
    let d = b - a;
    let l2 = d.dot(&d);
    let t = if l2 > 0.0 {
        ((p - a).dot(&d) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + d * t - p).norm()
}

/// What one run showed.
#[derive(Default)]
struct Seen {
    /// Setpoints on smoothed pieces.
    on_pieces: usize,
    /// Of them, where the nearest move of the piece is not the one named for the setpoint
    /// before on the same piece, nor a later one (the search had to look back).
    backwards: usize,
}

/// Checks the `line` of every setpoint of `moves` on a smoothed piece.
fn check(name: &str, moves: &[Move], limits: &MachineLimits) -> Seen {
    let options = RunOptions::default();
    let mut rows: Vec<Setpoint> = Vec::new();
    let summary = run(
        moves.iter().copied(),
        limits,
        &options,
        |_, sp: &Setpoint| rows.push(*sp),
    )
    .unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!(summary.plan_failures, 0, "{name}");
    let bare = bare_setpoints(moves, limits, options.capacity);
    assert_eq!(rows.len(), bare.len(), "{name}: the bare loop's setpoints");
    let ends: Vec<(Vec3, Vec3)> = moves
        .iter()
        .map(|m| match &m.path {
            Path::Line(l) => (l.start, l.end),
            _ => unreachable!("only lines"),
        })
        .collect();
    let mut seen = Seen::default();
    let mut last: Option<(u64, usize)> = None;
    for (n, (row, sp)) in rows.iter().zip(&bare).enumerate() {
        assert_eq!(row.position, sp.position, "{name}: setpoint {n}");
        if sp.move_count <= 1 {
            continue;
        }
        seen.on_pieces += 1;
        let at = format!("{name}: setpoint {n} {:?}", &row.position[..3]);
        let p = Vec3::new(row.position[0], row.position[1], row.position[2]);
        let first = sp.move_index as usize;
        let piece = first..first + sp.move_count as usize;
        let named = row.line as usize - 1;
        assert!(
            piece.contains(&named),
            "{at}: line {} names move {named}, not one of the piece's moves {piece:?}",
            row.line
        );
        let d = |k: usize| segment_distance(ends[k].0, ends[k].1, p);
        let (nearest, dn) = piece
            .clone()
            .map(|k| (k, d(k)))
            .fold((first, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
        assert!(
            d(named) <= dn + DISTANCE_ROUNDING_MM,
            "{at}: line {} names move {named} at {} mm; move {nearest} of the piece {piece:?} is at {dn} mm",
            row.line,
            d(named)
        );
        if let Some((piece_first, before)) = last
            && piece_first == sp.move_index
            && nearest < before
            && d(before) > dn + DISTANCE_ROUNDING_MM
        {
            seen.backwards += 1;
        }
        last = Some((sp.move_index, named));
    }
    seen
}

#[test]
fn the_line_on_a_smoothed_curve_names_the_nearest_of_its_moves() {
    let seed: u64 = env_number("KERF_SEED").unwrap_or(0x11e5_5eed);
    let cases: usize = env_number("KERF_CASES").unwrap_or(24);
    let mut rng = Rng::seeded(seed);
    let mut total = Seen::default();
    for case in 0..cases {
        let limits = random_limits(&mut rng);
        let n = 150 + rng.pick(450);
        let moves = program(&mut rng, n);
        let seen = check(&format!("seed {seed} case {case}"), &moves, &limits);
        total.on_pieces += seen.on_pieces;
        total.backwards += seen.backwards;
    }
    eprintln!(
        "{} setpoints on smoothed pieces, {} of them nearest to a move before the one named for the setpoint before",
        total.on_pieces, total.backwards
    );
    // The programs reach what the contract is about: many setpoints on smoothed pieces,
    // some where the nearest move lies behind the one named last.
    assert!(total.on_pieces > 5_000, "{}", total.on_pieces);
    if cases >= 24 {
        assert!(total.backwards > 0);
    }
}
