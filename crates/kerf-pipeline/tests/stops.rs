//! Stops on curved CAM rows. The smoothed piece a row starts or stops in may be designed
//! for a lower speed than the pieces next to it, where the room the axes leave at that
//! speed gives its ramp a much larger budget (`kerf-plan`'s `lowered_ramp_design`).
//! Measured from the setpoints on rows over raster surfaces, on machines from a tenth to
//! four times a mill's limits and at two periods: every axis within its limits, the path
//! within the tolerance, the exact end. The planner's segments show that the lower designs
//! are in use on these rows, so the checks cover them.

mod common;
use common::*;
use kerf_geom::{Curve, Move, PlannedSegment, Vec3};
use kerf_motion::{AxisLimits, MachineLimits};
use kerf_plan::Planner;

/// Height over X, mm.
type Surface = fn(f64) -> f64;

/// Sections along X of the surfaces of `benches/src/cam.rs` (raster B's and raster C's at
/// `y = 0`) and a plain wave, mm.
const SURFACES: [(&str, Surface); 3] = [
    ("raster B", |x| {
        1.5 * (x / 2.5).sin() + 0.3 * (x / 1.2).sin()
    }),
    ("raster C", |x| {
        0.6 * (x / 1.25).sin() + 0.1 * (x / 0.5).sin()
    }),
    ("wave", |x| 0.8 * (x / 2.0).sin()),
];

/// A row of `n` G1 moves of 0.05 mm along X over `surface` from `x0` to `x0 + 0.05 n`
/// (backwards if `reverse`), Z rounded to `decimals`, at F3000, after a move from the
/// origin to its start where that is elsewhere (a stop where the row turns back on it),
/// ending at rest.
fn row(surface: Surface, x0: f64, n: usize, decimals: i32, reverse: bool) -> Vec<Move> {
    let scale = 10f64.powi(decimals);
    let pt = |k: usize| {
        let k = if reverse { n - k } else { k };
        let x = x0 + 0.05 * k as f64;
        Vec3::new(x, 0.0, (surface(x) * scale).round() / scale)
    };
    let mut moves = Vec::new();
    if pt(0) != Vec3::zeros() {
        moves.push(line(1, Vec3::zeros(), pt(0), 3000.0));
    }
    moves.extend((0..n).map(|k| line(k as u32 + 2, pt(k), pt(k + 1), 3000.0)));
    moves
}

/// The mill of `benches/cam-mill.toml` (X, Y 200 mm/s, 2000 mm/s², 50000 mm/s³; Z half
/// the speed and acceleration and 40 % of the jerk), its acceleration and jerk scaled.
fn cam_mill(scale_a: f64, scale_j: f64, period_s: f64) -> MachineLimits {
    let mut m = mill(200.0, 2000.0 * scale_a, 50_000.0 * scale_j, 0.01);
    m.axes[2] = Some(AxisLimits {
        velocity_units_s: 100.0,
        acceleration_units_s2: 1000.0 * scale_a,
        jerk_units_s3: 20_000.0 * scale_j,
    });
    m.period_s = period_s;
    m
}

/// Whether a smoothed piece at a stop (the first or last segment) is designed for a
/// speed at least 5 % under its neighbour's, with more jerk than the neighbour: a
/// design the neighbour's own would not give (a piece's budget falls as its speed rises).
fn lowered_at_a_stop(segs: &[PlannedSegment]) -> bool {
    let piece = |s: &PlannedSegment| matches!(s.curve, Curve::Transition(_)) && s.move_count > 1;
    let n = segs.len();
    n >= 2
        && [(0, 1), (n - 1, n - 2)].iter().any(|&(i, k)| {
            let (s, nb) = (&segs[i], &segs[k]);
            piece(s)
                && piece(nb)
                && s.v_max_mm_s <= 0.95 * nb.v_max_mm_s
                && s.jerk_mm_s3 > nb.jerk_mm_s3
        })
}

#[test]
fn rows_stopping_in_pieces_designed_slower_keep_every_limit() {
    let (mut cases, mut lowered) = (0, 0);
    for (name, surface) in SURFACES {
        for (scale_a, scale_j) in [(1.0, 1.0), (0.5, 0.25), (0.1, 0.1), (4.0, 4.0)] {
            for period_s in [0.001, 0.00025] {
                for (x0, reverse, decimals) in [(0.0, false, 4), (3.7, true, 3), (7.1, false, 6)] {
                    let m = cam_mill(scale_a, scale_j, period_s);
                    let moves = row(surface, x0, 300, decimals, reverse);
                    let case = format!(
                        "{name} from x {x0} (reverse {reverse}, {decimals} decimals), \
                         a × {scale_a}, j × {scale_j}, period {period_s} s"
                    );
                    let mut planner = Planner::new(m);
                    let mut segs = Vec::new();
                    for mv in &moves {
                        planner.push(mv, &mut segs).unwrap();
                    }
                    planner.finish(&mut segs);
                    cases += 1;
                    lowered += usize::from(lowered_at_a_stop(&segs));

                    let s = run_checked(&case, &moves, &m, |_| {});
                    assert_eq!(s.last.feed_mm_s, 0.0, "{case}: at rest");
                    assert_eq!(s.plan_failures, 0, "{case}");
                }
            }
        }
    }
    // The lower designs are exercised: 40 of the 72 rows have such a piece at a stop,
    // against 12 (pieces slower at a stop by their own geometry) before they existed.
    assert!(
        2 * lowered >= cases,
        "lowered at a stop on {lowered} of {cases} rows"
    );
}
