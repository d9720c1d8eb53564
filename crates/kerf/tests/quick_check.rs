//! `kerf run`'s quick check (issue 31) against the full check `kerf sim` makes: the same
//! programs accepted and refused, over random programs on machines whose travel edges are
//! put at random distances from the path (through it, on it, within the tolerance, far).
//!
//! The full check plans every move and checks every planned segment; the quick check reads
//! the moves without planning ([`QuickCheck`]) and plans only up to where the planned path
//! has passed the last move within twice the tolerance of an edge
//! ([`Prepass::has_passed`]), exactly as `kerf run`'s `check_program` does. Expected values
//! come from the full check, never from the quick one.

use kerf::sim::{Prepass, PrepassError, QuickCheck, SimOptions};
use kerf_config::Config;
use kerf_gcode::{Dialect, Interpreter, Item, Settings};
use kerf_geom::Move;

/// A small fixed pseudo-random generator (SplitMix64): the same cases on every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

/// A random program: a rapid to the start, then pieces of CAM-like dense polylines (small
/// turns, 0.05-0.5 mm steps, waves in Z), long lines with corners of any angle, and arcs,
/// at tolerance `tol_mm`. The path stays near the origin.
fn program(rng: &mut Rng, tol_mm: f64) -> String {
    let mut text = format!(
        "G21 G90 G17 G64 P{tol_mm} F{:.0}\n",
        rng.range(600.0, 6000.0)
    );
    let (mut x, mut y, mut z) = (
        rng.range(-5.0, 5.0),
        rng.range(-5.0, 5.0),
        rng.range(-2.0, 2.0),
    );
    text += &format!("G0 X{x:.4} Y{y:.4} Z{z:.4}\n");
    let mut heading = rng.range(0.0, std::f64::consts::TAU);
    for _ in 0..rng.range(2.0, 7.0) as usize {
        match rng.next() % 3 {
            0 => {
                // A dense polyline.
                let step = rng.range(0.05, 0.5);
                let turn = rng.range(-0.08, 0.08);
                let wave = rng.range(0.0, 0.5);
                for k in 0..rng.range(5.0, 60.0) as usize {
                    heading += turn + rng.range(-0.01, 0.01);
                    x += step * heading.cos();
                    y += step * heading.sin();
                    z = wave * (k as f64 * 0.3).sin();
                    text += &format!("G1 X{x:.4} Y{y:.4} Z{z:.4}\n");
                }
            }
            1 => {
                // Lines with corners.
                for _ in 0..rng.range(1.0, 5.0) as usize {
                    heading += rng.range(-2.5, 2.5);
                    let len = rng.range(0.5, 8.0);
                    x += len * heading.cos();
                    y += len * heading.sin();
                    text += &format!("G1 X{x:.4} Y{y:.4}\n");
                }
            }
            _ => {
                // An arc from here, centre to the side.
                let r = rng.range(1.0, 6.0);
                let side = if rng.next().is_multiple_of(2) {
                    1.0
                } else {
                    -1.0
                };
                let (cx, cy) = (x - side * r * heading.sin(), y + side * r * heading.cos());
                let sweep = rng.range(0.3, 3.0);
                let a0 = (y - cy).atan2(x - cx);
                let a1 = a0 + side * sweep;
                let (ex, ey) = (cx + r * a1.cos(), cy + r * a1.sin());
                let g = if side > 0.0 { "G3" } else { "G2" };
                text += &format!("{g} X{ex:.4} Y{ey:.4} I{:.4} J{:.4}\n", cx - x, cy - y);
                x = ex;
                y = ey;
                heading += side * sweep;
            }
        }
    }
    text += "M2\n";
    text
}

fn axis_mut(config: &mut Config, i: usize) -> &mut kerf_config::LinearAxis {
    match i {
        0 => &mut config.axes.x,
        1 => &mut config.axes.y,
        _ => &mut config.axes.z,
    }
}

fn moves_of(text: &str) -> Vec<Move> {
    Interpreter::new(text.as_bytes(), Dialect::LinuxCnc, Settings::default())
        .filter_map(|item| match item.expect("the generated program is valid") {
            Item::Move(m) => Some(m),
            Item::Event(_) => None,
        })
        .collect()
}

/// The full check: every move planned, every planned segment checked.
fn full(moves: &[Move], config: &Config) -> Result<(), PrepassError> {
    let mut prepass = Prepass::new(config, &SimOptions::default());
    for m in moves {
        prepass.push(m)?;
    }
    prepass.finish().map(|_| ())
}

/// The quick check, as `kerf run` makes it; also whether it planned at all.
fn quick(moves: &[Move], config: &Config) -> (Result<(), PrepassError>, bool) {
    let mut quick = QuickCheck::new(config);
    for m in moves {
        if let Err(e) = quick.push(m) {
            return (Err(e), false);
        }
    }
    let Some((last_near, _)) = quick.last_near() else {
        return (Ok(()), false);
    };
    let mut prepass = Prepass::new(config, &SimOptions::default());
    for m in moves {
        if let Err(e) = prepass.push(m) {
            return (Err(e), true);
        }
        if prepass.has_passed(last_near) {
            return (Ok(()), true);
        }
    }
    (prepass.finish().map(|_| ()), true)
}

#[test]
fn the_quick_check_accepts_and_refuses_what_the_full_check_does() {
    let (base, _) = kerf_config::load_default(None).expect("the embedded configuration");
    let mut rng = Rng(31);
    // (accepted without planning, accepted after planning near an edge, refused for the
    // programmed path, refused for the planned path only)
    let mut seen = [0u32; 4];
    for case in 0..800 {
        let tol_mm = [0.001, 0.01, 0.05, 0.2][rng.next() as usize % 4];
        let text = program(&mut rng, tol_mm);
        let moves = moves_of(&text);
        // The travel: each edge at a random distance from the programmed path's extreme
        // (the path's bounding box from the full check's own points is not needed: the
        // moves' end points and arcs' extremes are in the clearance of a huge box).
        let mut config = base.clone();
        let wide = 10_000.0;
        for axis in [&mut config.axes.x, &mut config.axes.y, &mut config.axes.z] {
            axis.min_mm = -wide;
            axis.max_mm = wide;
        }
        let mut extreme = [[f64::INFINITY, f64::NEG_INFINITY]; 3];
        for (i, reach_of) in extreme.iter_mut().enumerate() {
            for (side, sign) in [(0usize, -1.0f64), (1, 1.0)] {
                // How far the path reaches towards this side: the huge box's clearance
                // with only this side brought in.
                let mut probe = config.clone();
                let axis = axis_mut(&mut probe, i);
                if side == 0 {
                    axis.min_mm = 0.0;
                } else {
                    axis.max_mm = 0.0;
                }
                let reach = moves
                    .iter()
                    .map(|m| kerf_config::travel::clearance_mm(m, &probe.axes))
                    .fold(f64::INFINITY, f64::min);
                // With the edge at 0 the clearance is the path's extreme on this side.
                reach_of[side] = -sign * reach;
            }
        }
        // A third of the machines have every edge clear of the path; on the others each
        // edge is through the programmed path (rarely), within the tolerance of it (most
        // often: where a blend or a smoothed piece may cross it), or clear of it.
        let all_clear = rng.next().is_multiple_of(3);
        for (i, sides) in extreme.iter().enumerate() {
            let mut offset = || match (all_clear, rng.next() % 40) {
                (true, _) | (false, 25..) => rng.range(3.0 * tol_mm, 20.0),
                (false, 0) => rng.range(-0.5, 0.0) * tol_mm,
                (false, 1..=15) => rng.range(0.0, 0.3) * tol_mm,
                (false, _) => rng.range(0.3, 3.0) * tol_mm,
            };
            let (below, above) = (offset(), offset());
            let axis = axis_mut(&mut config, i);
            axis.min_mm = sides[0] - below;
            axis.max_mm = sides[1] + above;
        }
        let expected = full(&moves, &config);
        let (got, planned) = quick(&moves, &config);
        assert_eq!(
            expected.is_ok(),
            got.is_ok(),
            "case {case}: the full check says {expected:?}, the quick one {got:?}\n{text}"
        );
        if let (Err(PrepassError::PlannedTravel(a)), Err(PrepassError::PlannedTravel(b))) =
            (&expected, &got)
        {
            assert_eq!(a, b, "case {case}: another planned segment named\n{text}");
        }
        match (&expected, planned) {
            (Ok(()), false) => seen[0] += 1,
            (Ok(()), true) => seen[1] += 1,
            (Err(PrepassError::PlannedTravel(_)), _) => seen[3] += 1,
            (Err(_), _) => seen[2] += 1,
        }
    }
    // The sweep reaches every outcome, each many times.
    assert!(seen.iter().all(|&n| n >= 10), "outcomes {seen:?}");
}

#[test]
fn a_dense_program_clear_of_the_edges_is_checked_without_planning_and_one_on_an_edge_is_not() {
    let (config, _) = kerf_config::load_default(None).expect("the embedded configuration");
    // A dense zig-zag raster in the middle of the bundled mill's travel (±1000 mm).
    let mut text = String::from("G21 G90 G17 G64 P0.01 F3000\n");
    for k in 0..2000 {
        let x = f64::from(k) * 0.05;
        let z = 0.3 * (x * 0.7).sin();
        text += &format!("G1 X{x:.4} Y{:.4} Z{z:.4}\n", f64::from(k % 2) * 0.01);
    }
    let moves = moves_of(&format!("{text}M2\n"));
    let mut quick = QuickCheck::new(&config);
    for m in &moves {
        quick.push(m).unwrap();
    }
    assert_eq!(quick.last_near(), None);
    assert_eq!(quick.scan().moves, moves.len() as u64);
    // The same program ending with a move to the X edge (1000 mm): its move is near.
    let edge = format!("{text}G0 X1000\nM2\n");
    let moves = moves_of(&edge);
    let mut quick = QuickCheck::new(&config);
    for m in &moves {
        quick.push(m).unwrap();
    }
    let (index, line) = quick.last_near().expect("the move to the edge is near it");
    assert_eq!(index, moves.len() as u64 - 1);
    assert_eq!(line as usize, 2002);
    assert_eq!(quick.near_moves(), 1);
}
