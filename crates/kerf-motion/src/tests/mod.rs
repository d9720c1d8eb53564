//! Tests of the motion core as a whole: merging, overrides and the fallbacks, measured
//! from the setpoints; carried speed-ups and slow-downs in `carry.rs`.

use super::*;
use kerf_geom::{Arc, CornerMode, Curve, Line, Move, Path};
use kerf_geom::{Vec3, limits_merge};

mod carry;

/// A planned line along X from `x0`, `len` mm long, with speed limit `v_max` and feed
/// `feed` (mm/s), acceleration `a` and jerk `j` at both levels, and end cap `cap`.
fn x_line(
    x0: f64,
    len: f64,
    (v_max, feed): (f64, f64),
    (a, j): (f64, f64),
    cap: f64,
) -> PlannedSegment {
    let curve = Curve::line(Vec3::new(x0, 0.0, 0.0), Vec3::new(x0 + len, 0.0, 0.0));
    let mut s = PlannedSegment::with_zero_limits(curve, len, ([0.0; 3], [0.0; 3]), 1, 0, feed);
    s.v_max_mm_s = v_max;
    (s.accel_mm_s2, s.jerk_mm_s3) = (a, j);
    (s.v_boost_mm_s, s.accel_boost_mm_s2, s.jerk_boost_mm_s3) = (v_max, a, j);
    s.end_cap_mm_s = cap;
    s
}

/// Steps `core` until it is idle: the X position before the first step and after
/// every step, the idle one included.
fn x_positions(core: &mut MotionCore) -> Vec<f64> {
    let mut sp = Setpoint::default();
    let mut xs = vec![0.0];
    loop {
        let r = core.step(&mut sp);
        xs.push(sp.position[0]);
        if r == StepResult::Idle {
            return xs;
        }
        assert!(xs.len() < 100_000);
    }
}

fn mv(path: Path, feed_mm_min: f64) -> Move {
    Move {
        line: 1,
        rapid: false,
        path,
        feed_mm_min: Some(feed_mm_min),
        abc_deg: None,
        corner: CornerMode::Blend {
            tolerance_mm: None,
            naive_cam_mm: None,
        },
    }
}

/// A feed override cut just before a chain of short sections: the machine enters each
/// of them above its new feed and cannot come down to it within one, so it keeps
/// slowing down from section to section, as fast as each section's limits allow, and no
/// solver call fails (the soak of `kerf-pipeline`'s properties found the motion core
/// asking the solver for the new feed at the end of such a section, which it could not
/// meet, and counting a failure for each; the motion itself was then planned again).
/// The limits of the short sections are those of that soak case.
#[test]
fn entered_above_the_overridden_feed_it_slows_on_without_solver_failures() {
    let seg = |x0: f64, len: f64, feed: f64, a: f64, j: f64, cap: f64| {
        x_line(x0, len, (200.0, feed), (a, j), cap)
    };
    // Feeds differ by more than the merge ratio, so every short move is a section.
    let short = [
        (0.816, 1929.0, 67_278.0),
        (0.368, 4324.0, 126_136.0),
        (0.526, 1390.0, 53_290.0),
        (0.7, 2000.0, 50_000.0),
        (0.5, 3000.0, 90_000.0),
        (4.0, 2000.0, 50_000.0),
    ];
    for cut_at_mm in [
        19.0, 19.3, 19.5, 19.6, 19.7, 19.8, 19.85, 19.9, 19.95, 19.98,
    ] {
        let mut segs = vec![seg(0.0, 20.0, 40.0, 2000.0, 50_000.0, 40.0)];
        let mut x = 20.0;
        for (k, &(len, a, j)) in short.iter().enumerate() {
            let feed = if k % 2 == 0 { 40.0 } else { 36.0 };
            let last = k + 1 == short.len();
            segs.push(seg(x, len, feed, a, j, if last { 0.0 } else { 36.0 }));
            x += len;
        }
        let mut core = MotionCore::new(0.001, 64);
        for s in &segs {
            core.push(s).unwrap();
        }
        let mut sp = Setpoint::default();
        let mut feeds = Vec::new();
        let mut cut = None;
        for cycle in 0..100_000 {
            let r = core.step(&mut sp);
            feeds.push(sp.feed_mm_s);
            if cut.is_none() && sp.position[0] >= cut_at_mm {
                core.set_feed_override(0.23);
                cut = Some(cycle);
            }
            if r == StepResult::Idle {
                break;
            }
        }
        let cut = cut.expect("the cut happened");
        assert_eq!(core.plan_failures(), 0, "cut at {cut_at_mm} mm");
        assert_eq!(core.emergency_stops(), 0, "cut at {cut_at_mm} mm");
        assert!(
            (sp.position[0] - x).abs() < 1e-9,
            "ends at {}",
            sp.position[0]
        );
        // From the cut on, the speed only falls until it is at the new feed (36 · 0.23
        // = 8.28 mm/s on the slower moves), and then stays at or under 40 · 0.23.
        let new_feed = 40.0 * 0.23;
        let under = cut
            + feeds[cut..]
                .iter()
                .position(|&f| f <= new_feed + 1e-9)
                .unwrap();
        for w in feeds[cut + 1..under].windows(2) {
            assert!(
                w[1] <= w[0] + 1e-9,
                "cut at {cut_at_mm} mm: speeds up to {}",
                w[1]
            );
        }
        assert!(feeds[under..].iter().all(|&f| f <= new_feed + 1e-9));
    }
}

/// A long line behind a short segment with about a nineteenth of its acceleration and a
/// fifteenth of its jerk (a corner blend) stops with its own limits, not the short
/// one's: it is a section of its own ([`MERGE_ABOVE`]). Measured from the positions:
/// the stop at the end takes about `2·sqrt(v/j)` with the line's jerk (15 ms), where
/// the blend's limits need `v/a + a/j` (62 ms; 59 ms measured without the rule). The
/// junction between them is passable at any speed, so only the limits decide.
#[test]
fn a_line_behind_a_much_weaker_segment_stops_with_its_own_limits() {
    let v = 4.17;
    let seg =
        |x0: f64, len: f64, a: f64, j: f64, cap: f64| x_line(x0, len, (200.0, v), (a, j), cap);
    let (a_weak, j_weak, a_line, j_line) = (100.0, 5000.0, 1900.0, 75_000.0);
    // By the lower merge ratios alone the line would join the weak segment's section
    // (its limits are above them); more than `MERGE_ABOVE` times above, it may not.
    assert!(a_line > MERGE_ABOVE * a_weak && j_line > MERGE_ABOVE * j_weak);
    let mut core = MotionCore::new(0.001, 8);
    core.push(&seg(0.0, 0.05, a_weak, j_weak, 200.0)).unwrap();
    core.push(&seg(0.05, 5.0, a_line, j_line, 0.0)).unwrap();
    let xs = x_positions(&mut core);
    assert!(
        (xs[xs.len() - 1] - 5.05).abs() < 1e-9,
        "{}",
        xs[xs.len() - 1]
    );
    let speeds: Vec<f64> = xs.windows(2).map(|w| (w[1] - w[0]) / 0.001).collect();
    // From the last period at (nearly) the feed to rest.
    let last_fast = speeds.iter().rposition(|&s| s > 0.99 * v).unwrap();
    let stop_s = (speeds.len() - last_fast) as f64 * 0.001;
    let with_line = 2.0 * (v / j_line).sqrt();
    let with_weak = v / a_weak + a_weak / j_weak;
    assert!(
        stop_s < 0.5 * (with_line + with_weak),
        "stop took {stop_s} s: {with_line} s with the line's limits, {with_weak} s with the weak one's"
    );
}

/// A chain of 2 mm segments whose speeds differ by 1–2 % (smoothed pieces on a slope)
/// ending at a stop: a slower segment joins the section before it, so speeds stepping
/// down make no stair of sections each ending at `a = 0` (a step up still starts a
/// section). Measured from the positions against the same chain with every segment
/// at the slowest one's speed (one section by any rule), which is nowhere faster: the
/// chain takes at most 5 % longer (3.0 % measured; 16.8 % without
/// [`MERGE_RATIO_SLOWER`]).
#[test]
fn a_slow_down_across_pieces_of_nearly_equal_speed_makes_no_stair() {
    let run = |speeds: &[f64]| -> f64 {
        let mut core = MotionCore::new(0.001, 64);
        let mut x = 0.0;
        for (k, &v) in speeds.iter().enumerate() {
            let len = 2.0;
            let next = speeds.get(k + 1).copied().unwrap_or(0.0);
            let s = x_line(x, len, (v, 100.0), (1400.0, 10_000.0), v.min(next));
            core.push(&s).unwrap();
            x += len;
        }
        let mut sp = Setpoint::default();
        let mut cycles = 0;
        while core.step(&mut sp) != StepResult::Idle {
            cycles += 1;
            assert!(cycles < 100_000);
        }
        assert!((sp.position[0] - x).abs() < 1e-9);
        assert_eq!(core.plan_failures(), 0);
        cycles as f64 * 0.001
    };
    let speeds = [
        76.73, 76.73, 75.82, 77.11, 76.28, 75.56, 76.73, 75.82, 77.11, 76.28, 75.56,
    ];
    let slowest = speeds.iter().copied().fold(f64::INFINITY, f64::min);
    let varied = run(&speeds);
    let equal = run(&[slowest; 11]);
    assert!(
        varied <= 1.05 * equal,
        "{varied} s with the speeds as they are, {equal} s all at {slowest} mm/s"
    );
}

/// The planner judges ramp budgets by whether a piece joins the section before it
/// (`kerf_geom::speeds_merge_into` with the conservative speed of a section of one
/// segment, `kerf_geom::limits_merge`); the motion core decides the same: for two
/// segments with the given speed limits and limits ratios, at the tail of a queue (where
/// the slower-merge condition holds), it makes one section exactly when both functions
/// say so.
/// (The second segment is longer than the first: a line no longer than the first joins
/// by the wider rule of `kerf_geom::limits_merge_into`, tested below.)
#[test]
fn the_planners_merge_estimate_is_the_motion_cores_rule() {
    let mut log_uniform = profile::tests::log_uniform_source(0x5eed_cafe);
    let seg = |x0: f64, len: f64, v: f64, a: f64, j: f64| x_line(x0, len, (v, 1000.0), (a, j), 1e6);
    let (mut merged, mut split, mut slower) = (0, 0, 0);
    for _ in 0..2000 {
        let v1 = log_uniform(20.0, 200.0);
        let (a1, j1) = (log_uniform(500.0, 5000.0), log_uniform(5e3, 1e5));
        let v2 = v1 * log_uniform(0.9, 1.1);
        let a2 = a1 * log_uniform(0.8, 5.0);
        let j2 = j1 * log_uniform(0.7, 5.0);
        let mut core = MotionCore::new(0.001, 8);
        core.push(&seg(0.0, 2.0, v1, a1, j1)).unwrap();
        core.push(&seg(2.0, 3.0, v2, a2, j2)).unwrap();
        let expected = kerf_geom::speeds_merge_into(v2, v1, MERGE_RATIO_SPEED * v1)
            && limits_merge(a2, j2, (a1, j1));
        let one_section = core.sec_count == 1;
        assert_eq!(
            one_section, expected,
            "v {v1} -> {v2}, a {a1} -> {a2}, j {j1} -> {j2}"
        );
        if one_section {
            merged += 1;
            if v2 < MERGE_RATIO_SPEED * v1 {
                slower += 1;
            }
        } else {
            split += 1;
        }
    }
    // Both outcomes are exercised, the slower merge among them.
    assert!(
        merged > 100 && split > 100 && slower > 20,
        "{merged} merged ({slower} slower), {split} split"
    );
}

/// Past its first segment a section compares a newcomer's speed with its conservative
/// speed, which a slightly slower segment lowers: the planner's estimate of the section a
/// piece runs in (`kerf_geom::speeds_merge_into`, with `MERGE_RATIO_SPEED` of the least
/// speed limit so far) decides as the motion core does for a third segment behind two
/// that merged, where the first segment alone (its conservative speed,
/// `MERGE_RATIO_SPEED · v1`) would say otherwise in some of the cases.
#[test]
fn the_planners_merge_estimate_follows_a_section_past_its_first_segment() {
    let mut log_uniform = profile::tests::log_uniform_source(0x5ec7_1013);
    let seg = |x0: f64, len: f64, v: f64| x_line(x0, len, (v, 1000.0), (2000.0, 40_000.0), 1e6);
    let (mut merged, mut split, mut differs) = (0, 0, 0);
    for _ in 0..2000 {
        let v1 = log_uniform(20.0, 200.0);
        let v2 = v1 * log_uniform(0.96, 1.0);
        let v3 = v1 * log_uniform(0.94, 1.04);
        let mut core = MotionCore::new(0.001, 8);
        core.push(&seg(0.0, 2.0, v1)).unwrap();
        core.push(&seg(2.0, 3.0, v2)).unwrap();
        if core.sec_count != 1 {
            continue;
        }
        core.push(&seg(5.0, 3.0, v3)).unwrap();
        let c_v = (MERGE_RATIO_SPEED * v1).min(MERGE_RATIO_SPEED * v2);
        let expected = kerf_geom::speeds_merge_into(v3, v1, c_v);
        let one_section = core.sec_count == 1;
        assert_eq!(one_section, expected, "v {v1} -> {v2} -> {v3}");
        if one_section {
            merged += 1;
        } else {
            split += 1;
        }
        if expected != kerf_geom::speeds_merge_into(v3, v1, MERGE_RATIO_SPEED * v1) {
            differs += 1;
        }
    }
    assert!(
        merged > 100 && split > 100 && differs > 50,
        "{merged} merged, {split} split, {differs} where the first segment alone differs"
    );
}

/// A stop that brakes across two pieces whose accelerations differ by 15 % (smoothed
/// pieces before a row end) brakes through their junction: the weaker piece joins the
/// section of the one before ([`MERGE_RATIO_WEAKER`]), and the two run as one at its
/// limits. Measured from the positions against the same chain with both pieces at the
/// weaker one's limits (one section by any rule): no slower (without the rule 5.5 ms
/// slower, the braking coming back to `a = 0` at about 52 mm/s at the junction), and the
/// acceleration within the weaker piece's limit through both.
#[test]
fn a_stop_braking_across_a_slightly_weaker_piece_brakes_through_the_junction() {
    let period_s = 0.0005;
    let (v, j) = (60.0, 20_000.0);
    let run = |a_before: f64, a_weak: f64| -> (f64, Vec<f64>) {
        let mut core = MotionCore::new(period_s, 8);
        // A fast line of its own (far stronger), then the two pieces and the stop.
        core.push(&x_line(0.0, 20.0, (v, v), (3000.0, 60_000.0), v))
            .unwrap();
        core.push(&x_line(20.0, 3.0, (v, v), (a_before, j), v))
            .unwrap();
        core.push(&x_line(23.0, 3.0, (v, v), (a_weak, j), 0.0))
            .unwrap();
        let mut sp = Setpoint::default();
        let mut xs = vec![0.0];
        while core.step(&mut sp) != StepResult::Idle {
            xs.push(sp.position[0]);
            assert!(xs.len() < 100_000);
        }
        assert!((sp.position[0] - 26.0).abs() < 1e-9, "{}", sp.position[0]);
        assert_eq!(core.plan_failures(), 0);
        ((xs.len() - 1) as f64 * period_s, xs)
    };
    let a_weak = 850.0;
    // Not by the merge ratio: by the weaker merge only.
    assert!(!limits_merge(a_weak, j, (1000.0, j)));
    let (varied_s, xs) = run(1000.0, a_weak);
    let (equal_s, _) = run(a_weak, a_weak);
    assert!(
        varied_s <= equal_s + 1e-9,
        "{varied_s} s with the pieces as they are, {equal_s} s both at {a_weak} mm/s²"
    );
    // From the first piece's start on, the acceleration from the positions.
    let start = xs.iter().position(|&x| x >= 20.0).unwrap();
    let worst = xs[start - 1..]
        .windows(3)
        .map(|w| ((w[2] - 2.0 * w[1] + w[0]) / (period_s * period_s)).abs())
        .fold(0.0, f64::max);
    assert!(worst <= a_weak * 1.001, "{worst} mm/s²");
}

/// A weaker piece (85 % of the acceleration) pushed while the first of two short
/// sections runs a speed-up from rest (a short queue: the daemon's planner a little ahead
/// of the motion) does not join the second, the section a speed-up may be carried into:
/// a carried acceleration is chosen within that section's conservative limits and end
/// speed, which the weaker merge would change under it. Measured from the positions: the
/// speed-up goes on across the first boundary in every case (the acceleration there at
/// least 250 mm/s²; where the piece joined, the second section ended at the program's
/// stop, into which no speed-up is carried: 5–12 mm/s² at the boundary, the cases from 2 ms
/// quicker to 21 ms slower), every acceleration within the limit of the segment it is in,
/// no solver failure, the program's end reached.
#[test]
fn a_weaker_piece_does_not_join_a_section_a_speed_up_is_carried_into() {
    let feed = 50.0;
    let seg =
        |x0: f64, len: f64, a: f64, j: f64, cap: f64| x_line(x0, len, (feed, feed), (a, j), cap);
    let (accel, weak, jerk) = (1200.0, 1020.0, 13_000.0);
    assert!(!limits_merge(weak, jerk, (accel, jerk)));
    assert!(kerf_geom::limits_merge_weaker(weak, jerk, (accel, jerk)));
    for first_mm in [0.3, 0.5, 0.8, 1.2] {
        for second_mm in [1.0, 1.5, 2.0, 2.5] {
            let case = format!("{first_mm} + {second_mm} mm");
            let mut core = MotionCore::new(0.001, 8);
            core.push(&seg(0.0, first_mm, accel, 18_000.0, feed))
                .unwrap();
            core.push(&seg(first_mm, second_mm, accel, jerk, feed))
                .unwrap();
            let mut sp = Setpoint::default();
            let mut xs = vec![0.0];
            core.step(&mut sp);
            xs.push(sp.position[0]);
            let end_mm = first_mm + second_mm;
            core.push(&seg(end_mm, 10.0, weak, jerk, 0.0)).unwrap();
            while core.step(&mut sp) != StepResult::Idle {
                xs.push(sp.position[0]);
                assert!(xs.len() < 100_000);
            }
            assert!((sp.position[0] - end_mm - 10.0).abs() < 1e-9, "{case}");
            assert_eq!(core.plan_failures(), 0, "{case}");
            let dt = 0.001;
            for k in 1..xs.len() - 1 {
                let a = accel_at(&xs, k, dt);
                let limit = if xs[k] > end_mm { weak } else { accel };
                assert!(
                    a.abs() <= limit * 1.01,
                    "{a} mm/s² at x = {} ({case})",
                    xs[k]
                );
            }
            let boundary = xs.iter().position(|&x| x > first_mm).unwrap();
            let carried = accel_at(&xs, boundary, dt);
            assert!(carried >= 250.0, "{carried} mm/s² at the boundary ({case})");
        }
    }
}

/// The acceleration from the positions `xs` (period `dt`) at sample `k`.
fn accel_at(xs: &[f64], k: usize, dt: f64) -> f64 {
    (xs[k + 1] - 2.0 * xs[k] + xs[k - 1]) / (dt * dt)
}

/// The planner's estimate of the section a segment runs in (`kerf-plan`'s
/// `SectionEstimate`, built from `kerf_geom`'s functions) decides the weaker merge as the
/// motion core does: behind a section of its own (a much stronger line, passed at speed),
/// a short piece and a weaker one after it make one section exactly when
/// [`kerf_geom::limits_merge`] or [`kerf_geom::limits_merge_weaker`] with
/// [`kerf_geom::weaker_merge_keeps_lookahead`] (the piece's hard start from
/// [`kerf_geom::entry_speed`] with an end speed of 0, below its cap and not lowered by the join) say so.
#[test]
fn the_planners_estimate_of_the_weaker_merge_is_the_motion_cores_rule() {
    use kerf_geom::{
        conservative_limits, entry_speed, limits_merge_weaker, weaker_merge_keeps_lookahead,
    };
    let mut log_uniform = profile::tests::log_uniform_source(0x3ea6_e12d);
    let (mut weaker, mut merged, mut split) = (0, 0, 0);
    for _ in 0..3000 {
        let v1 = log_uniform(20.0, 200.0);
        let len1 = log_uniform(0.2, 20.0);
        let len2 = len1 * log_uniform(1.01, 3.0);
        let cap0 = v1 * log_uniform(0.5, 2.0);
        let (a1, j1) = (log_uniform(300.0, 3000.0), log_uniform(5e3, 1e5));
        let a2 = a1 * log_uniform(0.7, 1.2);
        let j2 = j1 * log_uniform(0.7, 5.0);
        let mut core = MotionCore::new(0.001, 8);
        let lead = x_line(0.0, 5.0, (v1, 1000.0), (1e5, 1e7), cap0);
        core.push(&lead).unwrap();
        core.push(&x_line(5.0, len1, (v1, 1000.0), (a1, j1), 1e6))
            .unwrap();
        assert_eq!(core.sec_count, 2);
        core.push(&x_line(5.0 + len1, len2, (v1, 1000.0), (a2, j2), 1e6))
            .unwrap();
        let cap = (MERGE_RATIO_SPEED * v1).min(cap0);
        let by_weaker = limits_merge_weaker(a2, j2, (a1, j1))
            && weaker_merge_keeps_lookahead(
                (
                    entry_speed(cap, 0.0, len1, conservative_limits((a1, j1))),
                    cap,
                ),
                cap,
                len1 + len2,
                conservative_limits((a1.min(a2), j1.min(j2))),
            );
        let expected = limits_merge(a2, j2, (a1, j1)) || by_weaker;
        let one_section = core.sec_count == 2;
        assert_eq!(
            one_section, expected,
            "len {len1} + {len2}, cap {cap0}, a {a1} -> {a2}, j {j1} -> {j2}"
        );
        match (one_section, by_weaker && !limits_merge(a2, j2, (a1, j1))) {
            (true, true) => weaker += 1,
            (true, false) => merged += 1,
            _ => split += 1,
        }
    }
    assert!(
        weaker > 100 && merged > 100 && split > 100,
        "{weaker} by the weaker merge, {merged} by the ratios, {split} split"
    );
}

/// A line no longer than a section's first segment joins it however much higher its
/// acceleration and jerk (`kerf_geom::MERGE_SHORT_SHARE`), not when it is longer, nor
/// when its limits are lower than the merge ratios allow, nor when it is a curve; and the
/// section runs at the lesser limits: its acceleration and jerk from the positions stay
/// within the first segment's.
#[test]
fn a_short_line_joins_the_section_before_it() {
    let (a1, j1) = (500.0, 10_000.0);
    let first = x_line(0.0, 1.0, (50.0, 3000.0), (a1, j1), 50.0);
    let sections = |len: f64, a: f64, j: f64, curved: bool| {
        let mut second = x_line(1.0, len, (50.0, 3000.0), (a, j), 0.0);
        if curved {
            // The same straight path as a transition: a curve to the merge rule.
            second.curve = Curve::Transition(
                kerf_geom::Transition::hermite(
                    Vec3::new(1.0, 0.0, 0.0),
                    Vec3::x(),
                    Vec3::zeros(),
                    Vec3::new(1.0 + len, 0.0, 0.0),
                    Vec3::x(),
                    Vec3::zeros(),
                    len,
                )
                .and_then(|t| t.with_arc_length())
                .unwrap(),
            );
        }
        let mut core = MotionCore::new(0.001, 8);
        core.push(&first).unwrap();
        core.push(&second).unwrap();
        let count = core.sec_count;
        let xs = x_positions(&mut core);
        assert!((xs.last().unwrap() - (1.0 + len)).abs() < 1e-9);
        if count == 1 {
            for w in xs.windows(4) {
                let acc = (w[3] - 2.0 * w[2] + w[1]).abs() / 1e-6;
                let jerk = (w[3] - 3.0 * w[2] + 3.0 * w[1] - w[0]).abs() / 1e-9;
                assert!(acc <= a1 * 1.01 && jerk <= j1 * 1.01, "{acc} {jerk}");
            }
        }
        count
    };
    assert_eq!(sections(0.002, 10.0 * a1, 10.0 * j1, false), 1);
    assert_eq!(sections(1.0, 10.0 * a1, 10.0 * j1, false), 1);
    assert_eq!(sections(1.5, 10.0 * a1, 10.0 * j1, false), 2);
    assert_eq!(sections(0.002, 0.5 * a1, j1, false), 2);
    assert_eq!(sections(0.002, 10.0 * a1, 10.0 * j1, true), 2);
    // Within MERGE_ABOVE any length joins, as before.
    assert_eq!(sections(1.5, 2.0 * a1, 2.0 * j1, false), 1);
}

/// With every solver call failing, the closed-form fallback runs the whole program:
/// no jump, every limit holds by finite differences of the positions, and the run
/// ends at rest exactly at the program's end.
#[test]
fn the_fallback_runs_a_program_within_the_limits() {
    for (v, a, j, period_s) in [
        (200.0, 2000.0, 50_000.0, 0.001),
        (1000.0, 100_000.0, 1e7, 0.001),
        (30.0, 300.0, 3000.0, 0.00025),
        (5000.0, 1e6, 1e9, 0.0000625),
    ] {
        let axis = AxisLimits {
            velocity_units_s: v,
            acceleration_units_s2: a,
            jerk_units_s3: j,
        };
        let limits = MachineLimits {
            axes: [Some(axis), Some(axis), Some(axis), None, None, None],
            period_s,
            tolerance_mm: 0.01,
        };
        let p = |x: f64, y: f64, z: f64| Vec3::new(x, y, z);
        let line = |a: Vec3, b: Vec3, f: f64| mv(Path::Line(Line { start: a, end: b }), f);
        let moves = [
            line(p(0.0, 0.0, 0.0), p(10.0, 0.0, 0.0), 3000.0),
            line(p(10.0, 0.0, 0.0), p(10.0, 0.003, 0.0), 3000.0),
            line(p(10.0, 0.003, 0.0), p(12.0, 5.0, 1.0), 600.0),
            mv(
                Path::Arc(Arc {
                    start: p(12.0, 5.0, 1.0),
                    end: p(8.0, 5.0, 1.5),
                    center: p(10.0, 5.0, 1.0),
                    axis: Vec3::z(),
                    sweep_rad: std::f64::consts::PI,
                }),
                6000.0,
            ),
            line(p(8.0, 5.0, 1.5), p(0.0, 0.0, 0.0), 12000.0),
        ];
        let mut planner = kerf_plan::Planner::new(limits);
        let mut segs = Vec::new();
        for m in &moves {
            planner.push(m, &mut segs).unwrap();
        }
        planner.finish(&mut segs);
        let mut core = MotionCore::new(limits.period_s, 64);
        core.fail_solver = true;
        // At rest at the origin before the first cycle.
        let mut rows: Vec<[f64; 6]> = vec![[0.0; 6]; 3];
        let mut sp = Setpoint::default();
        let mut next = 0;
        for _ in 0..10_000_000 {
            while next < segs.len() && core.push(&segs[next]).is_ok() {
                next += 1;
            }
            let r = core.step(&mut sp);
            rows.push(sp.position);
            if r == StepResult::Idle && next == segs.len() {
                break;
            }
        }
        assert!(core.plan_failures() > 0, "the fallback was not exercised");
        assert_eq!(rows.last().unwrap()[..3], [0.0, 0.0, 0.0]);
        // The path is about 31 mm long and no axis may exceed v.
        let t = period_s;
        let duration_s = (rows.len() - 3) as f64 * t;
        assert!(duration_s > 31.0 / (v * 3f64.sqrt()), "{duration_s} s");
        for w in rows.windows(4) {
            let axes = w[0].iter().zip(&w[1]).zip(&w[2]).zip(&w[3]).take(3);
            for (((q0, q1), q2), q3) in axes {
                let vel = (q3 - q2).abs() / t;
                let acc = (q3 - 2.0 * q2 + q1).abs() / (t * t);
                let jerk = (q3 - 3.0 * q2 + 3.0 * q1 - q0).abs() / (t * t * t);
                let noise = 8.0 * f64::EPSILON * 20.0;
                assert!(vel <= v * 1.01, "v {vel} > {v}");
                assert!(acc <= a * 1.01 + 2.0 * noise / (t * t), "a {acc} > {a}");
                assert!(
                    jerk <= j * 1.01 + 4.0 * noise / (t * t * t),
                    "j {jerk} > {j}"
                );
            }
        }
    }
}

/// A hold asked for at any moment of a move, its final deceleration included (where the
/// stop cannot start before the queue's end and the core waits for the next section),
/// ends held: the status says so once the machine is at rest, a move queued afterwards
/// does not start, and cycle start runs it. (The web page's test found a hold asked for
/// in a rapid's last milliseconds, with nothing queued behind it, that the status showed
/// as running.)
#[test]
fn a_hold_in_the_last_deceleration_ends_held_and_keeps_the_next_move_waiting() {
    let run = |core: &mut MotionCore, sp: &mut Setpoint| {
        let mut xs = Vec::new();
        for _ in 0..100_000 {
            core.step(sp);
            xs.push(sp.position[0]);
            let n = xs.len();
            if n > 3 && xs[n - 1] == xs[n - 2] && xs[n - 2] == xs[n - 3] {
                return xs;
            }
        }
        panic!("never at rest");
    };
    // How many cycles the move takes without a hold.
    let mut core = MotionCore::new(0.001, 64);
    core.push(&x_line(0.0, 10.0, (40.0, 40.0), (2000.0, 50_000.0), 0.0))
        .unwrap();
    let cycles = x_positions(&mut core).len();
    for hold_at in 1..cycles {
        let mut core = MotionCore::new(0.001, 64);
        core.push(&x_line(0.0, 10.0, (40.0, 40.0), (2000.0, 50_000.0), 0.0))
            .unwrap();
        let mut sp = Setpoint::default();
        for _ in 0..hold_at {
            core.step(&mut sp);
        }
        core.hold();
        let xs = run(&mut core, &mut sp);
        let at_rest = *xs.last().unwrap();
        assert_eq!(
            core.status().state,
            MotionState::Held,
            "hold at cycle {hold_at} of {cycles}: at rest at X{at_rest} but not held"
        );
        // The next move waits for cycle start.
        core.push(&x_line(10.0, 5.0, (40.0, 40.0), (2000.0, 50_000.0), 0.0))
            .unwrap();
        for _ in 0..200 {
            core.step(&mut sp);
            assert_eq!(
                sp.position[0], at_rest,
                "hold at cycle {hold_at}: moved while held"
            );
        }
        assert_eq!(core.status().state, MotionState::Held);
        core.resume();
        let xs = x_positions(&mut core);
        assert!(
            (xs.last().unwrap() - 15.0).abs() < 1e-9,
            "hold at cycle {hold_at}: ends at X{}",
            xs.last().unwrap()
        );
    }
}
