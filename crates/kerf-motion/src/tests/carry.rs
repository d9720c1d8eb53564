//! Carried speed-ups and slow-downs (`carry.rs`), measured from the setpoints.

use super::{x_line, x_positions};
use crate::*;
use kerf_geom::limits_merge;

/// The speeds and accelerations of `xs` (X positions at the period `dt`), after checking
/// from them that the speed stays within `feed`, the acceleration within `accel` and the
/// jerk within the limit of the section each third difference starts in (past a
/// boundary, with the three periods it spans): `jerks` gives each section's start and
/// jerk, in order (the first section's limit holds before every later start).
fn checked_speeds_and_accels(
    xs: &[f64],
    dt: f64,
    feed: f64,
    accel: f64,
    jerks: &[(f64, f64)],
) -> (Vec<f64>, Vec<f64>) {
    let v: Vec<f64> = xs.windows(2).map(|w| (w[1] - w[0]) / dt).collect();
    let a: Vec<f64> = v.windows(2).map(|w| (w[1] - w[0]) / dt).collect();
    let j: Vec<f64> = a.windows(2).map(|w| (w[1] - w[0]) / dt).collect();
    assert!(v.iter().all(|&v| v <= feed * 1.01));
    assert!(a.iter().all(|&a| a.abs() <= accel * 1.01));
    for (k, &j) in j.iter().enumerate() {
        let limit = jerks[1..]
            .iter()
            .rev()
            .find(|&&(from_mm, _)| xs[k] > from_mm)
            .map_or(jerks[0].1, |&(_, jerk)| jerk);
        assert!(j.abs() <= limit * 1.01, "jerk {j} at x = {}", xs[k]);
    }
    (v, a)
}

/// A speed-up from rest over a short section into a longer one it cannot merge with
/// (its jerk is under the merge ratio of the first's; a third section, weaker again,
/// ends the program) goes on across the boundary: measured from the positions, the
/// acceleration does not come down to zero between leaving rest and nearing the feed,
/// and every limit holds (each section's own past its start).
#[test]
fn a_speed_up_goes_on_into_the_next_section_without_a_stair() {
    let feed = 50.0;
    let seg =
        |x0: f64, len: f64, a: f64, j: f64, cap: f64| x_line(x0, len, (feed, feed), (a, j), cap);
    let (accel, j_first, j_second, j_third) = (1200.0, 18_000.0, 13_000.0, 9_000.0);
    assert!(!limits_merge(accel, j_second, (accel, j_first)));
    assert!(!limits_merge(accel, j_third, (accel, j_second)));
    let mut core = MotionCore::new(0.001, 8);
    core.push(&seg(0.0, 1.0, accel, j_first, feed)).unwrap();
    core.push(&seg(1.0, 15.0, accel, j_second, feed)).unwrap();
    core.push(&seg(16.0, 30.0, accel, j_third, 0.0)).unwrap();
    let xs = x_positions(&mut core);
    assert!((xs[xs.len() - 1] - 46.0).abs() < 1e-9);
    assert_eq!(core.plan_failures(), 0);
    let dt = 0.001;
    let (v, a) = checked_speeds_and_accels(
        &xs,
        dt,
        feed,
        accel,
        &[(0.0, j_first), (1.0, j_second), (16.0, j_third)],
    );
    let rising = v.iter().position(|&v| v > 0.1 * feed).unwrap();
    let near = v.iter().position(|&v| v > 0.9 * feed).unwrap();
    let boundary = xs.iter().position(|&x| x > 1.0).unwrap();
    assert!(rising < boundary && boundary < near);
    let low = a[rising..near]
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    assert!(
        low > 0.25 * accel,
        "the acceleration came down to {low} mm/s² on the way up"
    );
}

/// A stop from the feed that begins near the end of a long section and runs through two
/// short ones it cannot merge with (each one's jerk is under the merge ratio of the one
/// before) carries its slow-down across both boundaries. Measured from the positions:
/// - at the last period before each boundary the machine still decelerates at more than
///   a tenth of the acceleration limit (with a stair, as before slow-downs were carried:
///   32 mm/s² before the first, on its way to zero);
/// - every limit holds (each section's own past its start);
/// - it comes to the stop at most 1 % later than the same lines at the weakest one's
///   limits, which merge into one section and stop in one S-curve: measured 0.5 % (797
///   against 793 periods), 3.4 % (820) with the stair;
/// - it ends where it should with no solver failure.
#[test]
fn a_slow_down_goes_on_into_the_next_sections_without_a_stair() {
    let feed = 50.0;
    let (accel, j_first, j_second, j_third) = (1200.0, 18_000.0, 13_000.0, 9_000.0);
    assert!(!limits_merge(accel, j_second, (accel, j_first)));
    assert!(!limits_merge(accel, j_third, (accel, j_second)));
    // The stop at the third section's jerk takes 2 √(v/j) and covers half of that at the
    // feed: more than the two short sections' 2.2 mm.
    let stop_mm = feed * (feed / j_third).sqrt();
    assert!(stop_mm > 2.5, "{stop_mm}");
    let run = |jerks: [f64; 3]| -> Vec<f64> {
        let mut core = MotionCore::new(0.001, 8);
        core.push(&x_line(0.0, 30.0, (feed, feed), (accel, jerks[0]), feed))
            .unwrap();
        core.push(&x_line(30.0, 1.2, (feed, feed), (accel, jerks[1]), feed))
            .unwrap();
        core.push(&x_line(31.2, 1.0, (feed, feed), (accel, jerks[2]), 0.0))
            .unwrap();
        // An exact stop, then a line on: the last short section is not the queue's tail
        // (a segment could still join that one, so nothing is carried into it).
        core.push(&x_line(32.2, 5.0, (feed, feed), (accel, j_third), 0.0))
            .unwrap();
        let xs = x_positions(&mut core);
        assert!((xs[xs.len() - 1] - 37.2).abs() < 1e-9);
        assert_eq!(core.plan_failures(), 0);
        assert_eq!(core.emergency_stops(), 0);
        xs
    };
    let xs = run([j_first, j_second, j_third]);
    let dt = 0.001;
    let (_, a) = checked_speeds_and_accels(
        &xs,
        dt,
        feed,
        accel,
        &[(0.0, j_first), (30.0, j_second), (31.2, j_third)],
    );
    for boundary_mm in [30.0, 31.2] {
        // `a[k]` spans positions k..k+2: the last one whose span ends before the boundary.
        let k = xs.iter().position(|&x| x > boundary_mm).unwrap() - 3;
        assert!(
            a[k] < -0.1 * accel,
            "{} mm/s² before the boundary at {boundary_mm} mm",
            a[k]
        );
    }
    // Periods to the exact stop at 32.2 mm.
    let arrival = |xs: &[f64]| xs.iter().position(|&x| x >= 32.2 - 1e-9).unwrap();
    let weakest = run([j_third; 3]);
    assert!(
        arrival(&xs) as f64 <= 1.01 * arrival(&weakest) as f64,
        "{} periods, {} at the weakest limits",
        arrival(&xs),
        arrival(&weakest)
    );
}

/// A carried speed-up whose next section comes to want its boost level while the
/// carry runs (the feed override raised near the boundary, too late for the running
/// section to re-plan to `a = 0`): the next section starts at a level whose limits the
/// carried acceleration is within (the boost level's acceleration is lower here), and
/// moves to the boost level once it is. While a section runs at its boost level, the
/// acceleration from the positions stays within that level's.
#[test]
fn an_override_raised_during_a_carried_speed_up_keeps_a_level_that_fits_it() {
    let feed = 50.0;
    let (accel, j_first, j_second) = (1200.0, 18_000.0, 13_000.0);
    let (v_boost, accel_boost, jerk_boost) = (80.0, 300.0, 6_000.0);
    let mut second = x_line(1.0, 15.0, (feed, feed), (accel, j_second), feed);
    (
        second.v_boost_mm_s,
        second.accel_boost_mm_s2,
        second.jerk_boost_mm_s3,
    ) = (v_boost, accel_boost, jerk_boost);
    let (mut carried, mut boosted_runs) = (0, 0);
    // Raise the override at every period of the first section's second half in turn.
    for raise_at in 1..200 {
        let mut core = MotionCore::new(0.001, 8);
        core.push(&x_line(0.0, 1.0, (feed, feed), (accel, j_first), feed))
            .unwrap();
        core.push(&second).unwrap();
        core.push(&x_line(16.0, 30.0, (feed, feed), (accel, j_second), 0.0))
            .unwrap();
        let mut sp = Setpoint::default();
        // Position after each step, and whether the section running was boosted.
        let mut xs = vec![(0.0, false)];
        loop {
            let r = core.step(&mut sp);
            let boosted = core.sec_count > 0 && core.sec(core.sec_head).boosted;
            xs.push((sp.position[0], boosted));
            if xs.len() == raise_at {
                if !(0.5..1.0).contains(&sp.position[0]) {
                    break;
                }
                if core.traj_end_a_mm_s2 > 0.0 {
                    carried += 1;
                }
                core.set_feed_override(1.5);
            }
            if r == StepResult::Idle {
                break;
            }
            assert!(xs.len() < 100_000);
        }
        if xs.len() <= raise_at {
            continue;
        }
        assert!((xs[xs.len() - 1].0 - 46.0).abs() < 1e-9);
        assert_eq!(core.plan_failures(), 0, "raised at {raise_at}");
        assert_eq!(core.emergency_stops(), 0, "raised at {raise_at}");
        let dt = 0.001;
        if xs.iter().any(|&(_, b)| b) {
            boosted_runs += 1;
        }
        for (k, w) in xs.windows(3).enumerate() {
            let a = (w[2].0 - 2.0 * w[1].0 + w[0].0) / (dt * dt);
            let limit = if w[1].1 && w[2].1 { accel_boost } else { accel };
            assert!(
                a.abs() <= limit * 1.01,
                "raised at {raise_at}: a {a} mm/s² at step {k}, x = {}",
                w[1].0
            );
        }
    }
    assert!(carried > 5, "{carried}");
    assert!(boosted_runs > 5, "{boosted_runs}");
}

/// Random chains of lines along X whose speed limits, accelerations, jerks and junction
/// caps differ from segment to segment (so they split into sections that slow down into
/// one another): every chain ends exactly at its end with no solver failure and no
/// emergency stop, and the positions keep every limit. A finite difference is an average
/// of its quantity over the periods it spans, so it is held to the highest limit of the
/// segments those periods touch (the segment's own limit inside a segment); a period
/// that spans a junction holds the average speed to the junction's cap plus what the
/// acceleration can change in one period. Many profiles end with a slow-down carried on
/// (counted, so that the sweep is known to exercise it: 6,756 periods); with the carry
/// offered wherever the quickest fall fits, inside the distances the solver refuses (see
/// `MotionCore::carry_target`), case 51 counts plan failures.
#[test]
fn random_chains_with_carried_slow_downs_keep_their_limits() {
    let mut log_uniform = profile::tests::log_uniform_source(0x51_0d0e);
    let dt = 0.001;
    let mut carried = 0;
    for case in 0..300 {
        let n = 3 + (log_uniform(1.0, 10.0) as usize);
        let (mut segs, mut x) = (Vec::new(), 0.0);
        for k in 0..n {
            let len = log_uniform(0.05, 6.0);
            let v = log_uniform(5.0, 150.0);
            let (a, j) = (log_uniform(200.0, 5_000.0), log_uniform(2_000.0, 200_000.0));
            segs.push(x_line(x, len, (v, v), (a, j), 0.0));
            if k > 0 {
                let prev: &mut PlannedSegment = &mut segs[k - 1];
                let cap = prev.v_max_mm_s.min(v) * log_uniform(0.3, 1.0);
                // One junction in about eight is an exact stop.
                prev.end_cap_mm_s = if log_uniform(1.0, 8.0) < 1.3 {
                    0.0
                } else {
                    cap
                };
            }
            x += len;
        }
        let mut core = MotionCore::new(dt, 64);
        for s in &segs {
            core.push(s).unwrap();
        }
        let mut sp = Setpoint::default();
        let mut xs = vec![0.0];
        loop {
            let r = core.step(&mut sp);
            xs.push(sp.position[0]);
            if core.running && core.traj_end_a_mm_s2 < 0.0 {
                carried += 1;
            }
            if r == StepResult::Idle {
                break;
            }
            assert!(xs.len() < 1_000_000, "case {case}: no end");
        }
        assert!((xs[xs.len() - 1] - x).abs() < 1e-9, "case {case}");
        assert_eq!(core.plan_failures(), 0, "case {case}");
        assert_eq!(core.emergency_stops(), 0, "case {case}");
        // The segments a span of positions touches (by their starts).
        let starts: Vec<f64> = segs.iter().map(|s| s.curve.start().x).collect();
        let touched = |lo: f64, hi: f64| {
            let first = starts.partition_point(|&s| s <= lo).saturating_sub(1);
            let last = starts.partition_point(|&s| s < hi).saturating_sub(1);
            &segs[first..=last.max(first)]
        };
        let max_of = |lo: f64, hi: f64, f: &dyn Fn(&PlannedSegment) -> f64| {
            touched(lo, hi).iter().map(f).fold(0.0, f64::max)
        };
        for (k, w) in xs.windows(4).enumerate() {
            let at = format!("case {case}, step {k}, x = {} mm", w[0]);
            let v = (w[1] - w[0]) / dt;
            let span = touched(w[0], w[1]);
            let cap = span[..span.len() - 1]
                .iter()
                .map(|s| s.end_cap_mm_s)
                .fold(f64::INFINITY, f64::min);
            let a_max = max_of(w[0], w[1], &|s| s.accel_mm_s2);
            let v_lim = max_of(w[0], w[1], &|s| s.v_max_mm_s).min(cap + a_max * dt);
            assert!(v <= v_lim * 1.01 + 1e-9, "{at}: v {v} mm/s");
            let a = (w[2] - 2.0 * w[1] + w[0]) / (dt * dt);
            let a_lim = max_of(w[0], w[2], &|s| s.accel_mm_s2);
            assert!(a.abs() <= a_lim * 1.01 + 1e-6, "{at}: a {a} mm/s²");
            let j = (w[3] - 3.0 * w[2] + 3.0 * w[1] - w[0]) / (dt * dt * dt);
            let j_lim = max_of(w[0], w[3], &|s| s.jerk_mm_s3);
            assert!(j.abs() <= j_lim * 1.01 + 1e-3, "{at}: j {j} mm/s³");
        }
    }
    assert!(
        carried > 100,
        "{carried} periods ran a profile ending in a carried slow-down"
    );
}
