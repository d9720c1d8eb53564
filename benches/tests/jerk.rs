//! The jerk-limited lower bound of the CAM table (`kerf_benches::jerk`) against closed
//! forms worked out by hand (S-curve times on straight lines), against the
//! acceleration-limited bound of `kerf_benches::bound` (another method) where jerk is out
//! of the way, and monotonic in every limit.

mod common;
use common::{assert_rel, circle, line};

use kerf_benches::bound::{self, BoundMachine};
use kerf_benches::jerk::{self, JerkMachine};

const MILL: JerkMachine = JerkMachine {
    base: BoundMachine {
        velocity_mm_s: [200.0, 200.0, 100.0],
        acceleration_mm_s2: [2000.0, 2000.0, 1000.0],
        tolerance_mm: 0.01,
    },
    jerk_mm_s3: [50_000.0, 50_000.0, 20_000.0],
};

const DS_MM: f64 = 0.01;

#[test]
fn straight_lines_take_the_s_curve_time() {
    // Rest to rest along one axis, the S-curve by hand:
    // - X, 10 mm at 100 mm/s (2,000 mm/s², 50,000 mm/s³): v ≥ a²/j = 80 mm/s, so the
    //   speed-up reaches the acceleration limit: t = L/v + v/a + a/j = 0.19 s;
    // - X at 50 mm/s (< 80): the acceleration peaks at √(v j) under its limit:
    //   t = L/v + 2 √(v/j);
    // - Z, 20 mm with 200 mm/s asked: Z's own 100 mm/s, 1,000 mm/s², 20,000 mm/s³
    //   (v ≥ a²/j = 50): t = 0.2 + 0.1 + 0.05.
    // The bound is at or a hair under (discretisation), and far above the acceleration
    // bound (L/v + v/a).
    for (end, feed, exact) in [
        ([10.0, 0.0, 0.0], 100.0, 0.1 + 0.05 + 0.04),
        (
            [10.0, 0.0, 0.0],
            50.0,
            0.2 + 2.0 * (50.0f64 / 50_000.0).sqrt(),
        ),
        ([0.0, 0.0, -20.0], 200.0, 0.2 + 0.1 + 0.05),
    ] {
        let b = jerk::jerk_lower_bound(&[line([0.0; 3], end, feed)], &MILL, DS_MM).unwrap();
        assert_rel(b.time_s, exact, 1e-3, &format!("{end:?} at {feed}"));
        assert!(
            b.time_s <= exact * (1.0 + 1e-5),
            "{end:?}: {} above {exact}",
            b.time_s
        );
        let a = bound::lower_bound(&[line([0.0; 3], end, feed)], &MILL.base, DS_MM);
        assert!(
            a.time_s < 0.9 * exact,
            "{end:?}: acceleration bound {}",
            a.time_s
        );
    }
}

#[test]
fn without_jerk_it_is_the_acceleration_bound() {
    // With jerk limits a million times higher the program has the acceleration-limited
    // optimum of `bound` (another method: closed-form phase-plane passes) on the same
    // path, a circle without joins; with the real limits it is above it.
    let turn = [circle(10.0, 1.0, 100.0)];
    let accel = bound::lower_bound(&turn, &MILL.base, 0.005).time_s;
    let loose = JerkMachine {
        jerk_mm_s3: [5e10, 5e10, 2e10],
        ..MILL
    };
    let b = jerk::jerk_lower_bound(&turn, &loose, DS_MM).unwrap();
    assert_rel(b.time_s, accel, 2e-3, "circle without jerk");
    let b = jerk::jerk_lower_bound(&turn, &MILL, DS_MM).unwrap();
    assert!(b.time_s > accel * 1.03, "{} against {accel}", b.time_s);
}

#[test]
fn higher_limits_never_raise_the_bound() {
    // A pocket loop (sharp corners, blended) and a turn: doubling any one limit of any
    // one axis leaves the bound the same or lower (to the solver's accuracy: its scaled
    // units change with the limits, and a solve may end at reduced accuracy, 1e-6 to
    // 1e-5 relative seen).
    let pocket = kerf_benches::cam::pocket(1).pieces;
    let turn = vec![circle(5.0, 1.0, 80.0)];
    for path in [&pocket, &turn] {
        let base = jerk::jerk_lower_bound(path, &MILL, 0.02).unwrap().time_s;
        for axis in 0..3 {
            for which in 0..3 {
                let mut m = MILL;
                match which {
                    0 => m.base.velocity_mm_s[axis] *= 2.0,
                    1 => m.base.acceleration_mm_s2[axis] *= 2.0,
                    _ => m.jerk_mm_s3[axis] *= 2.0,
                }
                let t = jerk::jerk_lower_bound(path, &m, 0.02).unwrap().time_s;
                assert!(
                    t <= base * (1.0 + 1e-4),
                    "axis {axis} limit {which}: {t} > {base}"
                );
            }
        }
    }
}

#[test]
fn bound_speeds_follow_the_s_curve_and_add_up_to_its_time() {
    // What `cam_table --bound-speeds` prints and `benches/speed_bins.py` integrates: the
    // optimum's speed along the path. On 10 mm of X at 100 mm/s (the S-curve of
    // `straight_lines_take_the_s_curve_time`: 0.19 s) it starts and ends at rest, cruises
    // at the feed between the ramps (each 0.05 + 0.04 s, over v·t/2 = 4.5 mm), and
    // ∫ ds / v over its samples is the S-curve's time.
    let b =
        jerk::jerk_lower_bound(&[line([0.0; 3], [10.0, 0.0, 0.0], 100.0)], &MILL, DS_MM).unwrap();
    assert_eq!(b.s_mm.len(), b.speed_mm_s.len());
    assert!(b.speed_mm_s[0] < 1.0 && b.speed_mm_s[b.speed_mm_s.len() - 1] < 1.0);
    let top = b.speed_mm_s.iter().copied().fold(0.0, f64::max);
    assert_rel(top, 100.0, 1e-3, "top speed");
    let mid = b.s_mm.iter().position(|&s| s >= 5.0).unwrap();
    assert_rel(b.speed_mm_s[mid], 100.0, 1e-3, "speed at 5 mm");
    let quarter = b.s_mm.iter().position(|&s| s >= 2.0).unwrap();
    assert!(b.speed_mm_s[quarter] < 95.0, "still ramping at 2 mm");
    let integral: f64 = (1..b.s_mm.len())
        .map(|k| {
            let v = 0.5 * (b.speed_mm_s[k] + b.speed_mm_s[k - 1]);
            (b.s_mm[k] - b.s_mm[k - 1]) / v
        })
        .sum();
    assert_rel(integral, 0.19, 0.02, "integral of ds / v");
}
