//! A corner takes the smaller tolerance of its two moves, measured from the
//! setpoints: the distance of every setpoint from the programmed path is computed here,
//! independently of the driver's own measure.

mod common;
use common::*;
use kerf_geom::{CornerMode, Curve, Move, Path, Vec3};
use kerf_motion::MachineLimits;
use kerf_pipeline::{RunOptions, run};

fn with_tol(mut m: Move, tol_mm: f64) -> Move {
    m.corner = CornerMode::Blend {
        tolerance_mm: Some(tol_mm),
        naive_cam_mm: None,
    };
    m
}

/// Distance from `p` to a programmed move: exact for lines, densely sampled for arcs.
fn distance(m: &Move, p: Vec3) -> f64 {
    match m.path {
        Path::Line(l) => {
            let d = l.end - l.start;
            let u = ((p - l.start).dot(&d) / d.norm_squared()).clamp(0.0, 1.0);
            (l.start + d * u - p).norm()
        }
        Path::Arc(a) => {
            let r = (a.start - a.center).norm();
            let radial = p - a.center - a.axis * (p - a.center).dot(&a.axis);
            let to_circle = (radial.norm() - r).abs();
            let c = Curve::from_path(&m.path);
            // Off the circle by `to_circle`, and along it no nearer than the samples say.
            let n = 20_000;
            let sampled = (0..=n)
                .map(|i| (c.point_at(c.length() * i as f64 / n as f64) - p).norm())
                .fold(f64::INFINITY, f64::min);
            sampled.max(to_circle)
        }
    }
}

/// Runs `moves` and returns every setpoint's XYZ and the largest distance of a setpoint
/// from the programmed moves.
fn run_and_measure(moves: &[Move], limits: &MachineLimits) -> (Vec<Vec3>, f64) {
    let mut pts = Vec::new();
    let s = run(
        moves.iter().copied(),
        limits,
        &RunOptions::default(),
        |_, sp| pts.push(Vec3::new(sp.position[0], sp.position[1], sp.position[2])),
    )
    .unwrap();
    let end = moves.last().unwrap().path.end();
    assert_eq!(
        s.last.position[..3],
        [end.x, end.y, end.z],
        "the run ends at the end"
    );
    for i in 0..3 {
        let f = s.fractions(limits, i).unwrap();
        assert!(f.iter().all(|&x| x <= 1.01), "axis {i}: {f:?}");
    }
    let worst = pts
        .iter()
        .map(|&p| {
            moves
                .iter()
                .map(|m| distance(m, p))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max);
    (pts, worst)
}

/// The machine's default tolerance is deliberately large, so that only the programmed
/// tolerances can bound the corner.
fn machine() -> MachineLimits {
    mill(200.0, 2000.0, 50_000.0, 0.5)
}

/// Two-move programs with a corner at (20, 0, 0): line-line at several turn angles,
/// line-arc and arc-line.
fn corners() -> Vec<(String, Move, Move)> {
    let o = Vec3::zeros();
    let c = Vec3::new(20.0, 0.0, 0.0);
    let mut v = Vec::new();
    for deg in [20.0_f64, 60.0, 90.0, 135.0] {
        let t = deg.to_radians();
        let out = c + Vec3::new(t.cos(), t.sin(), 0.0) * 20.0;
        v.push((
            format!("line-line {deg}°"),
            line(1, o, c, 3000.0),
            line(2, c, out, 3000.0),
        ));
    }
    // Line into an arc whose start tangent turns 90° (+Y), and an arc out of the corner.
    v.push((
        "line-arc".into(),
        line(1, o, c, 3000.0),
        arc(2, c, c - Vec3::new(10.0, 0.0, 0.0), 1.5, 0.0, 3000.0),
    ));
    // An arc ending at the corner heading +Y, then a line back to the left.
    let arc_in = arc_about(
        1,
        Vec3::new(30.0, -10.0, 0.0),
        Vec3::new(0.0, -10.0, 0.0),
        Vec3::z(),
        std::f64::consts::FRAC_PI_2,
        0.0,
        3000.0,
    );
    // It starts at (30, -10) about the centre (30, 0) and ends at (40, 0): move it so that
    // it ends at the corner.
    let shift = c - arc_in.path.end();
    let arc_in = shift_move(arc_in, shift);
    v.push((
        "arc-line".into(),
        arc_in,
        line(2, c, c + Vec3::new(-20.0, 5.0, 0.0), 3000.0),
    ));
    // Every program starts at the origin, where the machine is.
    v.into_iter()
        .map(|(name, a, b)| {
            let d = -a.path.start();
            (name, shift_move(a, d), shift_move(b, d))
        })
        .collect()
}

fn shift_move(mut m: Move, d: Vec3) -> Move {
    match &mut m.path {
        Path::Line(l) => {
            l.start += d;
            l.end += d;
        }
        Path::Arc(a) => {
            a.start += d;
            a.end += d;
            a.center += d;
        }
    }
    m
}

#[test]
fn a_coarse_move_then_a_fine_one_takes_the_fine_tolerance() {
    let limits = machine();
    for (name, a, b) in corners() {
        let moves = [with_tol(a, 1.0), with_tol(b, 0.01)];
        let (_, worst) = run_and_measure(&moves, &limits);
        assert!(worst <= 0.01 + 1e-6, "{name}: {worst} mm from the path");
    }
}

#[test]
fn a_fine_move_then_a_coarse_one_takes_the_fine_tolerance() {
    let limits = machine();
    for (name, a, b) in corners() {
        let moves = [with_tol(a, 0.01), with_tol(b, 1.0)];
        let (_, worst) = run_and_measure(&moves, &limits);
        assert!(worst <= 0.01 + 1e-6, "{name}: {worst} mm from the path");
    }
}

/// The coarse tolerance still applies where both moves have it: the corner is cut by
/// more than the fine tolerance would allow (so the tests above are not passing because
/// nothing is ever blended).
#[test]
fn two_coarse_moves_keep_the_coarse_tolerance() {
    let limits = machine();
    let c = Vec3::new(20.0, 0.0, 0.0);
    let moves = [
        with_tol(line(1, Vec3::zeros(), c, 3000.0), 1.0),
        with_tol(line(2, c, c + Vec3::new(0.0, 20.0, 0.0), 3000.0), 1.0),
    ];
    let (pts, worst) = run_and_measure(&moves, &limits);
    assert!(worst <= 1.0 + 1e-6, "{worst}");
    let nearest = pts
        .iter()
        .map(|p| (p - c).norm())
        .fold(f64::INFINITY, f64::min);
    assert!(nearest > 0.1, "the corner was not blended: {nearest} mm");
}

/// Exact stop belongs to the move that ends at the corner, as in LinuxCNC's `tp` and as
/// G9 (exact stop at the end of one block) needs: an arriving exact-stop move stops on
/// the corner; a blending move arriving at a move in exact-stop mode blends within its
/// own tolerance.
#[test]
fn exact_stop_is_the_arriving_moves() {
    let limits = machine();
    let c = Vec3::new(20.0, 0.0, 0.0);
    let a = line(1, Vec3::zeros(), c, 3000.0);
    let b = line(2, c, c + Vec3::new(0.0, 20.0, 0.0), 3000.0);
    let mut stop_first = [a, with_tol(b, 1.0)];
    stop_first[0].corner = CornerMode::ExactStop;
    let (pts, worst) = run_and_measure(&stop_first, &limits);
    assert!(worst <= 1e-9, "{worst}");
    // On the lines themselves, through the corner point.
    let nearest = pts
        .iter()
        .map(|p| (p - c).norm())
        .fold(f64::INFINITY, f64::min);
    assert!(nearest < 1e-3, "the corner was cut: {nearest} mm");

    // A shallow corner, which a blend passes quicker than a stop.
    let t = 20.0_f64.to_radians();
    let shallow = line(2, c, c + Vec3::new(t.cos(), t.sin(), 0.0) * 20.0, 3000.0);
    let mut stop_second = [with_tol(a, 0.05), shallow];
    stop_second[1].corner = CornerMode::ExactStop;
    let (pts, worst) = run_and_measure(&stop_second, &limits);
    assert!(worst <= 0.05 + 1e-6, "{worst}");
    let nearest = pts
        .iter()
        .map(|p| (p - c).norm())
        .fold(f64::INFINITY, f64::min);
    assert!(nearest > 0.01, "the corner was not blended: {nearest} mm");
}

/// A dense polyline (smoothed into curves) along a circle of radius 50 mm, `n` segments
/// of 0.5 mm from `start` heading +X, turning left.
fn dense_arc(start: Vec3, n: usize, tol_mm: f64) -> Vec<Move> {
    let r = 50.0;
    let c = start + Vec3::new(0.0, r, 0.0);
    let step = 0.5 / r;
    let pt = |k: usize| {
        let a = -std::f64::consts::FRAC_PI_2 + step * k as f64;
        c + Vec3::new(r * a.cos(), r * a.sin(), 0.0)
    };
    (0..n)
        .map(|k| with_tol(line(k as u32 + 1, pt(k), pt(k + 1), 3000.0), tol_mm))
        .collect()
}

/// Smoothing must not bend a coarse run into a fine move: a run under `G64 P1` ending
/// where a `G64 P0.01` line turns off by 20° (a turn a run at 1 mm would round over the
/// last 0.5 mm segment, 0.02 mm off it), and the same the other way round.
#[test]
fn a_smoothed_run_takes_the_fine_tolerance_where_it_meets_a_fine_move() {
    let limits = machine();
    let turn = 20.0_f64.to_radians();
    // Coarse run, then the fine line.
    let mut moves = dense_arc(Vec3::zeros(), 40, 1.0);
    let (p, d) = {
        let Path::Line(l) = moves.last().unwrap().path else {
            unreachable!()
        };
        (l.end, (l.end - l.start).normalize())
    };
    let (s, c) = turn.sin_cos();
    let out = Vec3::new(d.x * c + d.y * s, -d.x * s + d.y * c, 0.0);
    moves.push(with_tol(line(41, p, p + out * 10.0, 3000.0), 0.01));
    let (_, worst) = run_and_measure(&moves, &limits);
    assert!(worst <= 0.01 + 1e-6, "coarse run, fine line: {worst} mm");

    // The fine line, then the coarse run starting 20° off its direction.
    let dir = Vec3::new(turn.cos(), -turn.sin(), 0.0);
    let first = with_tol(line(1, Vec3::zeros(), dir * 10.0, 3000.0), 0.01);
    let mut moves = vec![first];
    moves.extend(dense_arc(dir * 10.0, 40, 1.0));
    let (_, worst) = run_and_measure(&moves, &limits);
    assert!(worst <= 0.01 + 1e-6, "fine line, coarse run: {worst} mm");
}
