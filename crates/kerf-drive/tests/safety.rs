//! The safety layer measured from its outputs: each check trips exactly at its limit
//! with the right axis and value, faults latch until a reset that is refused while the
//! cause persists, and the quick stop stays within the axis limits and stops in the
//! analytic jerk-limited time. Expected values are derived by hand in the comments.

use kerf_drive::MAX_AXES;
use kerf_drive::safety::{
    AxisSafety, Check, CycleInput, ResetRefused, Safety, SafetyConfig, SafetyConfigError,
    SafetyState, StopProfile,
};
use kerf_geom::AxisLimits;
use proptest::prelude::*;

const T: f64 = 0.001;

fn axis(v: f64, a: f64, j: f64) -> AxisSafety {
    AxisSafety {
        limits: AxisLimits {
            velocity_units_s: v,
            acceleration_units_s2: a,
            jerk_units_s3: j,
        },
        min_limit_units: -500.0,
        max_limit_units: 500.0,
        ferror_units: 1.0,
        min_ferror_units: 0.1,
    }
}

/// X, Y, Z with the same limits; margin 5 %, stall after 3 missed cycles.
fn config(ax: AxisSafety) -> SafetyConfig {
    SafetyConfig::new([Some(ax), Some(ax), Some(ax), None, None, None], T)
}

/// A realistic mill axis: 100 mm/s, 1000 mm/s², 50000 mm/s³.
fn mill_axis() -> AxisSafety {
    axis(100.0, 1000.0, 50_000.0)
}

/// The safety layer with a perfect drive that reaches each command one cycle later.
struct Rig {
    s: Safety,
    fault: [bool; MAX_AXES],
    line: u32,
}

impl Rig {
    fn new(cfg: SafetyConfig) -> Self {
        Self {
            s: Safety::new(cfg, [0.0; MAX_AXES]).expect("valid config"),
            fault: [false; MAX_AXES],
            line: 7,
        }
    }
    fn step(&mut self, sp: Option<[f64; MAX_AXES]>) -> kerf_drive::safety::Verdict {
        self.step_actual(sp, self.s.command())
    }
    fn step_actual(
        &mut self,
        sp: Option<[f64; MAX_AXES]>,
        actual: [f64; MAX_AXES],
    ) -> kerf_drive::safety::Verdict {
        self.line += 1;
        self.s.check(&CycleInput {
            setpoint: sp,
            actual,
            drive_fault: self.fault,
            line: self.line,
        })
    }
}

fn on(axis: usize, x: f64) -> [f64; MAX_AXES] {
    let mut p = [0.0; MAX_AXES];
    p[axis] = x;
    p
}

#[test]
fn velocity_trips_exactly_at_its_limit() {
    // Acceleration out of the way; limit 100 mm/s × 1.05 = 105 mm/s, a step of
    // 0.105 mm per 1 ms period.
    let cfg = config(axis(100.0, 1e12, 1e15));
    let step = 105.0 * T;
    let mut r = Rig::new(cfg);
    let v = r.step(Some(on(1, step * (1.0 - 1e-9))));
    assert_eq!(v.state, SafetyState::Running);
    assert!(v.tripped.is_none());
    assert_eq!(v.command[1], step * (1.0 - 1e-9));

    let mut r = Rig::new(cfg);
    let v = r.step(Some(on(1, step * (1.0 + 1e-9))));
    let f = v.tripped.expect("trips");
    assert_eq!(f.check, Check::Velocity);
    assert_eq!(f.axis, Some(1));
    assert!((f.value - 105.0).abs() < 1e-6, "{f:?}");
    assert!((f.limit - 105.0).abs() < 1e-9);
    assert_eq!(f.line, 8);
    // The setpoint never reaches the drive: the axis stops from rest, where it was.
    assert_eq!(v.command[1], 0.0);
    assert_eq!(r.s.fault(), Some(&f));
}

#[test]
fn acceleration_trips_exactly_at_its_limit() {
    // From rest the second difference is the first step: 1000 × 1.05 = 1050 mm/s²
    // is a step of 1050 × 1e-6 = 1.05e-3 mm.
    let cfg = config(axis(1e9, 1000.0, 1e12));
    let step = 1050.0 * T * T;
    let mut r = Rig::new(cfg);
    assert!(r.step(Some(on(2, step * (1.0 - 1e-9)))).tripped.is_none());
    // In motion: x = 0, s, 3s is a second difference of s as well (1 mm/s per cycle more).
    let mut r = Rig::new(cfg);
    let s = 1000.0 * T * T;
    assert!(r.step(Some(on(2, s))).tripped.is_none());
    assert!(r.step(Some(on(2, 3.0 * s))).tripped.is_none());
    let v = r.step(Some(on(2, 3.0 * s + 2.0 * s + step * (1.0 + 1e-9))));
    let f = v.tripped.expect("trips");
    assert_eq!((f.check, f.axis), (Check::Acceleration, Some(2)));
    assert!((f.value - 1050.0).abs() < 1e-3, "{f:?}");
    assert!((f.limit - 1050.0).abs() < 1e-9);
}

#[test]
fn a_stop_that_would_end_beyond_the_travel_trips_before_the_setpoint_crosses() {
    // X at 50 mm/s towards the limit at 500 (and, mirrored, towards -500), steady (a = 0).
    // Its jerk-limited stop (a_max 1000, j_max 50000): v ≥ a²/j = 20, so
    // t = v/a + a/j = 0.07 s and the distance is v·t/2 = 1.75 mm. Setpoints stepping
    // 0.05 mm per period trip once the next one is within 1.75 mm of the limit, while the
    // setpoint itself is still inside. (The axis gets there from rest at ±480 at
    // 500 mm/s², in 2.5 mm.) Both sides: the check on the minimum side is its own code.
    for dir in [1.0, -1.0] {
        let limit = 500.0 * dir;
        let mut s = Safety::new(config(mill_axis()), on(0, 480.0 * dir)).expect("config");
        let (mut x, mut v) = (480.0 * dir, 0.0);
        let mut tripped = None;
        let mut sent = vec![x];
        for k in 0..600 {
            v = f64::min(v + 0.5, 50.0);
            x += dir * v * T;
            let v = s.check(&CycleInput {
                setpoint: Some(on(0, x)),
                actual: on(0, s.command()[0]),
                drive_fault: [false; MAX_AXES],
                line: k,
            });
            sent.push(v.command[0]);
            if v.tripped.is_some() && tripped.is_none() {
                tripped = v.tripped.map(|f| (f, x));
            }
        }
        let (f, x_trip) = tripped.expect("trips");
        assert_eq!(
            (f.check, f.axis, f.limit),
            (Check::SoftLimit, Some(0), limit)
        );
        // Distances measured towards the limit.
        let inside = (limit - x_trip) * dir;
        assert!(inside > 0.0 && inside < 1.75 + 0.1, "{x_trip}");
        let beyond = (f.value - limit) * dir;
        assert!(
            beyond > 0.0 && ((f.value - x_trip) * dir - 1.75).abs() < 0.01,
            "{f:?}"
        );
        // The quick stop from the last setpoint sent ends within the travel.
        assert!(
            sent.iter().all(|&p| p * dir <= 500.0),
            "{:?}",
            &sent[sent.len() - 5..]
        );
        assert_eq!(s.state(), SafetyState::Stopped);
    }
}

#[test]
fn soft_limits_trip_just_beyond_the_travel() {
    // At rest on the limit; a step of 1e-6 mm is 1e-3 mm/s and 1 mm/s², far within the
    // mill's limits, so only the travel trips.
    for (axis, end) in [(0, 500.0), (1, -500.0)] {
        let mut s = Safety::new(config(mill_axis()), on(axis, end)).expect("config");
        let input = |x: f64| CycleInput {
            setpoint: Some(on(axis, x)),
            actual: on(axis, end),
            drive_fault: [false; MAX_AXES],
            line: 3,
        };
        assert!(s.check(&input(end)).tripped.is_none());
        let beyond = end + end.signum() * 1e-6;
        let v = s.check(&input(beyond));
        let f = v.tripped.expect("trips");
        assert_eq!((f.check, f.axis), (Check::SoftLimit, Some(axis)));
        // The value is where the axis would come to rest from the setpoint: beyond it by
        // the stopping distance of 1.5e-3 mm/s and 1 mm/s², well under 1e-6 mm.
        assert_eq!((f.limit, f.line), (end, 3));
        assert!(
            (f.value - beyond).abs() < 1e-6 && (f.value - end).abs() >= 1e-6,
            "{f:?}"
        );
        // Never sent: the axis stays where it is, at rest.
        assert_eq!(v.command[axis], end);
        assert_eq!(v.state, SafetyState::Stopped);
    }
}

#[test]
fn following_error_limit_follows_the_linuxcnc_formula() {
    // limit = max(MIN_FERROR 0.1, FERROR 1.0 · |v| / 100): 0.1 at 0 and 5 mm/s,
    // 0.5 at 50 mm/s, 1.0 at 100 mm/s, also moving backwards.
    let cfg = config(axis(100.0, 1e12, 1e15));
    for (v_mm_s, limit) in [
        (0.0, 0.1),
        (5.0, 0.1),
        (50.0, 0.5),
        (100.0, 1.0),
        (-50.0, 0.5),
    ] {
        for (scale, trips) in [(1.0 - 1e-6, false), (1.0 + 1e-6, true)] {
            let mut r = Rig::new(cfg);
            for k in 1..=20 {
                r.step(Some(on(1, f64::from(k) * v_mm_s * T)));
            }
            let err = limit * scale;
            let mut actual = r.s.command();
            actual[1] -= err;
            let v = r.step_actual(Some(on(1, 21.0 * v_mm_s * T)), actual);
            assert_eq!(v.tripped.is_some(), trips, "v {v_mm_s} err {err}");
            if let Some(f) = v.tripped {
                assert_eq!((f.check, f.axis), (Check::FollowingError, Some(1)));
                assert!((f.value - err).abs() < 1e-9, "{f:?}");
                assert!((f.limit - limit).abs() < 1e-9, "{f:?}");
                assert_eq!(f.line, 28);
            }
        }
    }
}

#[test]
fn on_a_fieldbus_the_following_error_is_taken_against_the_command_one_cycle_older() {
    // A drive at 50 mm/s (0.05 mm per 1 ms period) whose actual position answers the
    // command of two cycles back, as over a fieldbus, with a servo lag on top. The limit
    // at 50 mm/s is 0.5 mm. With the one-cycle feedback delay the error is the lag itself;
    // without it the error is the lag plus one period's travel, 0.05 mm more, so it
    // trips at a lag of 0.45 mm.
    let v_mm_s = 50.0;
    let step = v_mm_s * T;
    for (delay, lag, trips) in [
        (1, 0.3, false),
        (1, 0.5 + 1e-6, true),
        (0, 0.3, false),
        (0, 0.45 + 1e-6, true),
    ] {
        let mut cfg = config(axis(100.0, 1e12, 1e15));
        cfg.feedback_delay_cycles = delay;
        let mut r = Rig::new(cfg);
        for k in 1..=20 {
            r.step(Some(on(1, f64::from(k) * step)));
        }
        // The command two cycles back is k = 19.
        let actual = on(1, 19.0 * step - lag);
        let v = r.step_actual(Some(on(1, 21.0 * step)), actual);
        assert_eq!(
            v.tripped.is_some(),
            trips,
            "delay {delay} lag {lag}: {:?}",
            v.tripped
        );
        if let Some(f) = v.tripped {
            // Against the tracked command: k = 19 with the delay, k = 20 without.
            let tracked = if delay == 1 { 19.0 } else { 20.0 };
            assert!(
                (f.value - (tracked * step - (19.0 * step - lag))).abs() < 1e-9,
                "{f:?}"
            );
            assert!((f.limit - 0.5).abs() < 1e-9, "{f:?}");
        }
    }
    let mut cfg = config(axis(100.0, 1e12, 1e15));
    cfg.feedback_delay_cycles = 2;
    assert_eq!(
        Safety::new(cfg, [0.0; MAX_AXES]).err(),
        Some(SafetyConfigError::FeedbackDelay(2))
    );
}

#[test]
fn a_lost_exchange_leaves_the_feedback_stale_for_two_cycles_and_does_not_read_as_a_following_error()
{
    // At 50 mm/s (0.05 mm a period) on a fieldbus (feedback one cycle late) with a tight
    // following error: 0.03 mm at this speed. The exchange after cycle 20 is lost: cycle
    // 21 reads the actual position of cycle 20 again, and in cycle 22 the drive, which
    // missed a command, is still a period behind: 0.05 mm against the tracked command.
    let step = 50.0 * T;
    let run = |stale: bool| {
        let mut ax = axis(100.0, 1e12, 1e15);
        ax.ferror_units = 0.06;
        ax.min_ferror_units = 0.01;
        let mut cfg = config(ax);
        cfg.feedback_delay_cycles = 1;
        let mut r = Rig::new(cfg);
        let mut trips = Vec::new();
        for k in 1..=30u32 {
            let k_f = f64::from(k);
            let behind = if k == 21 || k == 22 { 3.0 } else { 2.0 };
            if stale && k == 21 {
                r.s.feedback_stale();
            }
            let actual = on(1, (k_f - behind).max(0.0) * step);
            let v = r.step_actual(Some(on(1, k_f * step)), actual);
            if v.tripped.is_some() {
                trips.push(k);
                break;
            }
        }
        trips
    };
    assert_eq!(
        run(false),
        vec![21],
        "without the mark the lost exchange trips"
    );
    assert_eq!(run(true), Vec::<u32>::new(), "marked stale: no trip");
}

#[test]
fn a_stall_holds_for_n_minus_one_cycles_then_stops() {
    let cfg = config(axis(100.0, 1e12, 1e15));
    assert_eq!(cfg.stall_cycles, 3);
    let mut r = Rig::new(cfg);
    for k in 1..=10 {
        r.step(Some(on(0, f64::from(k) * 0.01)));
    }
    // Two missed cycles, then the stream comes back: no trip.
    for _ in 0..2 {
        let v = r.step(None);
        assert_eq!(v.state, SafetyState::Holding);
        assert_eq!(v.command[0], 0.1);
    }
    assert_eq!(r.step(Some(on(0, 0.11))).state, SafetyState::Running);
    for _ in 0..2 {
        let v = r.step(None);
        assert_eq!((v.state, v.command[0]), (SafetyState::Holding, 0.11));
        assert!(v.tripped.is_none());
    }
    let v = r.step(None);
    let f = v.tripped.expect("third missed cycle trips");
    assert_eq!(
        (f.check, f.axis, f.value, f.limit),
        (Check::StreamStall, None, 3.0, 3.0)
    );
    // Held at rest, so the quick stop is already at rest there.
    assert_eq!(v.command[0], 0.11);
    assert_eq!(v.state, SafetyState::Stopped);
}

#[test]
fn a_stall_in_motion_stops_where_the_position_is_held() {
    // 50 mm/s on the mill, then the stream stops: the command is held at the last
    // setpoint, and the quick stop after the second missed cycle (stall_cycles 2)
    // starts from that rest (it does not move on, nor back up).
    let mut cfg = config(mill_axis());
    cfg.stall_cycles = 2;
    let mut r = Rig::new(cfg);
    let stream = ramp_stream(500.0, 50.0, 20, [1.0, -1.0, 0.0, 0.0, 0.0, 0.0]);
    for sp in &stream {
        r.step(Some(*sp));
    }
    let last = stream[stream.len() - 1];
    for _ in 0..50 {
        let v = r.step(None);
        assert_eq!(v.command, last);
    }
    assert_eq!(r.s.fault().map(|f| f.check), Some(Check::StreamStall));
    assert_eq!(r.s.state(), SafetyState::Stopped);
}

/// A stream from rest at constant acceleration `a` up to `v`, then `cruise` cycles at
/// `v`, per axis with a factor; returns the setpoints.
fn ramp_stream(a: f64, v: f64, cruise: usize, factors: [f64; MAX_AXES]) -> Vec<[f64; MAX_AXES]> {
    let mut out = Vec::new();
    let ramp_cycles = (v / a / T).round() as usize;
    let mut x = 0.0;
    for k in 1..=ramp_cycles + cruise {
        x = if k <= ramp_cycles {
            0.5 * a * (k as f64 * T).powi(2)
        } else {
            x + v * T
        };
        out.push(factors.map(|f| f * x));
    }
    out
}

#[test]
fn a_drive_fault_on_one_axis_stops_all() {
    let mut r = Rig::new(config(mill_axis()));
    let stream = ramp_stream(500.0, 50.0, 50, [1.0, 0.5, -1.0, 0.0, 0.0, 0.0]);
    for sp in &stream {
        assert!(r.step(Some(*sp)).tripped.is_none());
    }
    let before = r.s.command();
    r.fault[2] = true;
    let last = stream[stream.len() - 1];
    let mut sp = last;
    let v = r.step(Some(sp));
    let f = v.tripped.expect("drive fault trips");
    assert_eq!((f.check, f.axis), (Check::DriveFault, Some(2)));
    // Cycles count from 0 at construction: the stream's cycles, then this one.
    assert_eq!(f.cycle, stream.len() as u64);
    let mut cmds = vec![before, v.command];
    for _ in 0..400 {
        sp = sp.map(|x| x + 0.05);
        let v = r.step(Some(sp));
        assert!(v.tripped.is_none());
        cmds.push(v.command);
    }
    assert_eq!(r.s.state(), SafetyState::Stopped);
    assert_eq!(r.s.fault(), Some(&f), "latched");
    for ax in 0..3 {
        let n = cmds.len();
        // Each moving axis came to rest, ahead of where it was, in its direction.
        assert_eq!(cmds[n - 1][ax], cmds[n - 2][ax], "axis {ax} at rest");
        let travelled = cmds[n - 1][ax] - before[ax];
        let dir = [1.0, 0.5, -1.0][ax];
        assert!(travelled * dir > 0.0, "axis {ax} travelled {travelled}");
        // v = 50·|f| mm/s ≥ a²/j = 20 mm/s: trapezoidal, t = v/a + a/j, and the
        // distance is v·t/2 (the velocity falls point-symmetrically): X and Z 50 mm/s,
        // 0.07 s, 1.75 mm; Y 25 mm/s, 0.045 s, 0.5625 mm.
        let v = 50.0 * dir;
        let t = v.abs() / 1000.0 + 1000.0 / 50_000.0;
        assert!(
            (travelled - v * t / 2.0).abs() < 1e-9,
            "axis {ax} travelled {travelled}"
        );
    }
}

/// Finite differences of `xs` at the period: the largest |v|, |a|, |j|.
fn max_diffs(xs: &[f64]) -> (f64, f64, f64) {
    let d: Vec<f64> = xs.windows(2).map(|w| (w[1] - w[0]) / T).collect();
    let dd: Vec<f64> = d.windows(2).map(|w| (w[1] - w[0]) / T).collect();
    let ddd: Vec<f64> = dd.windows(2).map(|w| (w[1] - w[0]) / T).collect();
    let m = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    (m(&d), m(&dd), m(&ddd))
}

#[test]
fn quick_stop_from_full_speed_is_within_limits_and_takes_the_analytic_time() {
    // (v, a, j, stopping time, stopping distance), by hand:
    // - 100 mm/s, 1000 mm/s², 50000 mm/s³: a²/j = 20 ≤ v, trapezoidal acceleration,
    //   t = v/a + a/j = 0.1 + 0.02 = 0.12 s; the velocity falls point-symmetrically, so
    //   the distance is v·t/2 = 6 mm.
    // - 10 mm/s, same a and j: a²/j = 20 > v, triangular, t = 2·√(v/j) = 0.028284 s,
    //   distance v·t/2 = 0.141421 mm.
    let tri_s = 2.0 * (10.0f64 / 50_000.0).sqrt();
    for (vmax, t_stop, dist) in [(100.0, 0.12, 6.0), (10.0, tri_s, 10.0 * tri_s / 2.0)] {
        let (a, j) = (1000.0, 50_000.0);
        let mut r = Rig::new(config(axis(vmax, a, j)));
        // Up to full speed at 500 mm/s², then cruise.
        for sp in ramp_stream(500.0, vmax, 20, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]) {
            assert!(r.step(Some(sp)).tripped.is_none());
        }
        let x0 = r.s.command()[0];
        // The last three cruise commands, then the stop (a drive fault on Y trips it).
        let mut xs = vec![x0 - 2.0 * vmax * T, x0 - vmax * T, x0];
        r.fault[1] = true;
        let mut sp = r.s.command();
        let mut rest_at = None;
        let mut stopped_at = None;
        for k in 1..=400 {
            sp[0] += vmax * T;
            let v = r.step(Some(sp));
            assert_eq!(v.tripped.is_some(), k == 1);
            if rest_at.is_none() && v.command[0] == xs[xs.len() - 1] {
                rest_at = Some(k - 1);
            }
            // QuickStop while the axis ramps down, Stopped from when it is at rest.
            match (stopped_at, v.state) {
                (None, SafetyState::QuickStop) => {}
                (None, SafetyState::Stopped) => stopped_at = Some(k),
                (Some(_), SafetyState::Stopped) => {}
                (_, state) => panic!("cycle {k} of the stop: {state:?}"),
            }
            xs.push(v.command[0]);
        }
        let stopped_s = stopped_at.expect("stops") as f64 * T;
        assert!(
            (stopped_s - t_stop).abs() <= 2.0 * T,
            "Stopped after {stopped_s} s of a {t_stop} s stop"
        );
        let (vm, am, jm) = max_diffs(&xs);
        assert!(vm <= vmax * 1.01, "v {vm}");
        assert!(am <= a * 1.01, "a {am}");
        assert!(jm <= j * 1.01, "j {jm}");
        let rest_s = rest_at.expect("comes to rest") as f64 * T;
        assert!((rest_s - t_stop).abs() <= 1.0 * T, "{rest_s} vs {t_stop}");
        let travelled = xs[xs.len() - 1] - x0;
        assert!((travelled - dist).abs() < 1e-9, "{travelled} vs {dist}");
        assert_eq!(r.s.state(), SafetyState::Stopped);
    }
}

#[test]
fn stop_profiles_from_any_state_respect_the_limits() {
    let l = AxisLimits {
        velocity_units_s: 100.0,
        acceleration_units_s2: 1000.0,
        jerk_units_s3: 50_000.0,
    };
    for (v0, a0) in [
        (80.0, 800.0),
        (80.0, -800.0),
        (-30.0, 1000.0),
        (0.0, 500.0),
        (1.0, -1000.0),
        (0.0, 0.0),
    ] {
        let p = StopProfile::new(3.0, v0, a0, &l);
        let xs: Vec<f64> = (0..=400).map(|k| p.position(f64::from(k) * T)).collect();
        let (_, am, jm) = max_diffs(&xs);
        assert!(am <= 1000.0 * 1.01, "({v0}, {a0}): a {am}");
        assert!(jm <= 50_000.0 * 1.01, "({v0}, {a0}): j {jm}");
        // At rest at the end: velocity and acceleration by differences are 0.
        let n = xs.len();
        assert_eq!(xs[n - 1], xs[n - 2], "({v0}, {a0})");
        let (x, v, a) = p.state(p.duration_s());
        assert!(
            v.abs() < 1e-9 && a.abs() < 1e-9,
            "({v0}, {a0}): {x} {v} {a}"
        );
    }
}

#[test]
fn reset_is_refused_while_the_cause_persists() {
    // Drive fault: refused while stopping, then while the drive is in fault.
    let mut r = Rig::new(config(mill_axis()));
    for sp in ramp_stream(500.0, 50.0, 10, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]) {
        r.step(Some(sp));
    }
    r.fault[0] = true;
    let sp = r.s.command();
    assert!(r.step(Some(sp)).tripped.is_some());
    assert_eq!(r.s.reset(), Err(ResetRefused::Moving(0)));
    for _ in 0..200 {
        r.step(Some(sp));
    }
    assert_eq!(r.s.state(), SafetyState::Stopped);
    assert_eq!(r.s.reset(), Err(ResetRefused::DriveFault(0)));
    assert!(r.s.fault().is_some(), "still latched");
    r.fault[0] = false;
    let held = r.s.command();
    r.step(Some(sp));
    assert!(r.s.fault().is_some(), "never resets on its own");
    assert_eq!(r.s.reset(), Ok(()));
    assert_eq!(r.s.fault(), None);
    // The stream continues from the held position.
    let v = r.step(Some(held));
    assert_eq!(
        (v.state, v.command, v.tripped),
        (SafetyState::Running, held, None)
    );

    // Following error: refused while the axis still lags by more than MIN_FERROR.
    let mut r = Rig::new(config(mill_axis()));
    let lag = on(2, -0.2);
    let f = r
        .step_actual(Some([0.0; MAX_AXES]), lag)
        .tripped
        .expect("trips");
    assert_eq!((f.check, f.axis), (Check::FollowingError, Some(2)));
    r.step_actual(Some([0.0; MAX_AXES]), lag);
    match r.s.reset() {
        Err(ResetRefused::FollowingError {
            axis: 2,
            value,
            limit,
        }) => {
            assert!((value - 0.2).abs() < 1e-12 && limit == 0.1);
        }
        other => panic!("{other:?}"),
    }
    r.step(Some([0.0; MAX_AXES]));
    assert_eq!(r.s.reset(), Ok(()));

    // Stall: refused while the stream is still missing.
    let mut r = Rig::new(config(mill_axis()));
    for _ in 0..4 {
        r.step(None);
    }
    assert_eq!(r.s.fault().map(|f| f.check), Some(Check::StreamStall));
    assert_eq!(r.s.reset(), Err(ResetRefused::StreamMissing));
    r.step(Some([0.0; MAX_AXES]));
    assert_eq!(r.s.reset(), Ok(()));

    // Soft limit: refused while an actual position is beyond the travel.
    let mut r = Rig::new(config(mill_axis()));
    let out = on(0, 600.0);
    r.step_actual(Some([0.0; MAX_AXES]), [0.0; MAX_AXES]);
    r.s.check(&CycleInput {
        setpoint: Some(on(0, 700.0)),
        actual: [0.0; MAX_AXES],
        drive_fault: [false; MAX_AXES],
        line: 1,
    });
    assert!(r.s.fault().is_some());
    r.step_actual(Some([0.0; MAX_AXES]), out);
    assert!(matches!(
        r.s.reset(),
        Err(ResetRefused::SoftLimit {
            axis: 0,
            value: 600.0
        })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn random_streams_never_panic_and_faults_stay_latched(
        steps in proptest::collection::vec(
            (prop_oneof![
                6 => (-0.2f64..0.2).prop_map(Some),
                1 => Just(None),
                1 => Just(Some(f64::NAN)),
                1 => (-1e3f64..1e3).prop_map(Some),
            ], -0.3f64..0.3, proptest::bool::weighted(0.02), proptest::bool::weighted(0.05)),
            1..300),
    ) {
        let mut r = Rig::new(config(mill_axis()));
        let mut x = 0.0;
        let mut latched = None;
        for (step, lag, drive_fault, reset) in steps {
            r.fault[0] = drive_fault;
            let sp = step.map(|d| { x += d; [x, -x, 0.5 * x, 0.0, 0.0, 0.0] });
            let mut actual = r.s.command();
            actual[1] += lag;
            let v = r.step_actual(sp, actual);
            prop_assert!(v.command.iter().all(|c| c.is_finite()));
            if let Some(f) = latched {
                prop_assert_eq!(r.s.fault(), Some(&f), "latched until reset");
                prop_assert!(v.tripped.is_none());
            } else {
                latched = v.tripped;
            }
            if reset && r.s.reset().is_ok() {
                latched = None;
            }
            if x.is_nan() { x = 0.0; }
        }
    }
}

#[test]
fn bad_configurations_are_refused() {
    use kerf_drive::safety::SafetyConfigError;
    let ok = config(mill_axis());
    assert!(Safety::new(ok, [0.0; MAX_AXES]).is_ok());
    let mut c = ok;
    c.period_s = 0.0;
    assert_eq!(
        Safety::new(c, [0.0; MAX_AXES]).err(),
        Some(SafetyConfigError::Period(0.0))
    );
    let mut c = ok;
    c.stall_cycles = 0;
    assert_eq!(
        Safety::new(c, [0.0; MAX_AXES]).err(),
        Some(SafetyConfigError::StallCycles)
    );
    let mut c = ok;
    c.margin = -0.01;
    assert!(matches!(
        Safety::new(c, [0.0; MAX_AXES]),
        Err(SafetyConfigError::Margin(_))
    ));
    let mut ax = mill_axis();
    ax.min_limit_units = 600.0;
    let mut c = ok;
    c.axes[1] = Some(ax);
    assert!(matches!(
        Safety::new(c, [0.0; MAX_AXES]),
        Err(SafetyConfigError::Axis { axis: 'Y', .. })
    ));
    let mut ax = mill_axis();
    ax.limits.jerk_units_s3 = 0.0;
    let mut c = ok;
    c.axes[2] = Some(ax);
    assert!(matches!(
        Safety::new(c, [0.0; MAX_AXES]),
        Err(SafetyConfigError::Axis { axis: 'Z', .. })
    ));
    assert_eq!(
        Safety::new(ok, on(0, f64::NAN)).err(),
        Some(SafetyConfigError::StartPosition('X'))
    );
}

#[test]
fn a_fault_names_check_axis_value_limit_and_line() {
    let mut s = Safety::new(config(mill_axis()), on(0, 500.0)).expect("config");
    let f = s
        .check(&CycleInput {
            setpoint: Some(on(0, 500.0005)),
            actual: on(0, 500.0),
            drive_fault: [false; MAX_AXES],
            line: 42,
        })
        .tripped
        .expect("trips");
    // 500.0005 is 0.0005 mm in 1 ms: 0.5 mm/s, 500 mm/s², within limits; beyond travel.
    assert_eq!(f.check, Check::SoftLimit);
    let text = f.to_string();
    // The value is where a stop from 0.5 mm/s and 500 mm/s² comes to rest.
    assert!(text.starts_with("soft_limit on axis X: 500.0"), "{text}");
    assert!(text.contains("against limit 500 (line 42"), "{text}");
}

/// The checks' numbers on the wire are PROTOCOL.md's `SAFETY_*` (1 velocity … 10
/// subdevice state, 0 none), in the order of `Check::ALL`, each with its own name.
#[test]
fn check_codes_are_the_protocols_numbers() {
    let expected = [
        (Check::Velocity, 1, "velocity"),
        (Check::Acceleration, 2, "acceleration"),
        (Check::SoftLimit, 3, "soft_limit"),
        (Check::FollowingError, 4, "following_error"),
        (Check::StreamStall, 5, "stream_stall"),
        (Check::DriveFault, 6, "drive_fault"),
        (Check::EnableTimeout, 7, "enable_timeout"),
        (Check::DriveDisabled, 8, "drive_disabled"),
        (Check::Fieldbus, 9, "fieldbus"),
        (Check::SubdeviceState, 10, "subdevice_state"),
        (Check::SpindleAtSpeed, 11, "spindle_at_speed"),
        (Check::SpindleBand, 12, "spindle_band"),
        (Check::SpindleOrient, 13, "spindle_orient"),
        (Check::ToolChange, 14, "tool_change"),
        (Check::SpindleDrive, 15, "spindle_drive"),
        (Check::HomeSearch, 16, "home_search"),
        (Check::HomeRelease, 17, "home_release"),
        (Check::HomeLatch, 18, "home_latch"),
        (Check::HardLimit, 19, "hard_limit"),
        (Check::DriveHoming, 20, "drive_homing"),
    ];
    assert_eq!(Check::ALL.len(), expected.len());
    for (check, (want, code, name)) in Check::ALL.iter().zip(expected) {
        assert_eq!(*check, want);
        assert_eq!(check.code(), code, "{check:?}");
        assert_eq!(check.name(), name, "{check:?}");
    }
}

/// The safety layer's states by the names the black box's `state` column and DRIVES.md
/// use.
#[test]
fn safety_states_have_the_documented_names() {
    let names = [
        (SafetyState::Running, "running"),
        (SafetyState::Holding, "holding"),
        (SafetyState::QuickStop, "quick_stop"),
        (SafetyState::Stopped, "stopped"),
    ];
    for (state, name) in names {
        assert_eq!(state.name(), name, "{state:?}");
    }
}

/// `rebase` (a drive enabled again away from its last command) is taken only while a
/// fault is latched and the quick stop is over: never while running, never during the
/// quick stop, never for an axis beyond the sixth or a non-finite position.
#[test]
fn rebase_is_taken_only_in_a_stopped_fault() {
    let mut r = Rig::new(config(mill_axis()));
    let stream = ramp_stream(500.0, 50.0, 5, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    for sp in &stream {
        assert!(r.step(Some(*sp)).tripped.is_none());
    }
    assert!(!r.s.rebase(0, 1.0), "rebased while running");
    r.fault[1] = true;
    let last = stream[stream.len() - 1];
    assert!(r.step(Some(last)).tripped.is_some());
    assert_eq!(r.s.state(), SafetyState::QuickStop);
    assert!(!r.s.rebase(0, 1.0), "rebased during the quick stop");
    for _ in 0..400 {
        r.step(Some(last));
    }
    assert_eq!(r.s.state(), SafetyState::Stopped);
    assert!(!r.s.rebase(MAX_AXES, 1.0));
    assert!(!r.s.rebase(0, f64::NAN));
    assert!(r.s.rebase(0, 12.5));
    assert_eq!(r.s.command()[0], 12.5);
}

/// A stop profile's state: during the stop the velocity is between the start's and 0,
/// from its end on the axis is at rest, velocity and acceleration exactly 0.
#[test]
fn a_stop_profile_moves_until_its_end_then_rests() {
    let l = AxisLimits {
        velocity_units_s: 100.0,
        acceleration_units_s2: 1000.0,
        jerk_units_s3: 50_000.0,
    };
    // 50 mm/s at constant speed: trapezoidal, 0.05 + 0.02 = 0.07 s.
    let p = StopProfile::new(0.0, 50.0, 0.0, &l);
    let d = p.duration_s();
    assert!((d - 0.07).abs() < 1e-9, "{d}");
    let (_, v_mid, a_mid) = p.state(d / 2.0);
    assert!(v_mid > 0.0 && v_mid < 50.0, "{v_mid}");
    assert!(a_mid < 0.0, "{a_mid}");
    let (x_end, v_end, a_end) = p.state(d + 0.01);
    assert_eq!((v_end, a_end), (0.0, 0.0));
    // v·t/2: the velocity falls point-symmetrically.
    assert!((x_end - 50.0 * 0.07 / 2.0).abs() < 1e-9, "{x_end}");
}

/// An unhomed axis has no soft limits: a setpoint beyond them passes; once they are on
/// again, the same setpoint trips `soft_limit`.
#[test]
fn soft_limits_apply_only_while_on() {
    let mut r = Rig::new(config(mill_axis()));
    r.s.set_soft_limits(0, false);
    // Creep past the upper limit (500) at 50 mm/s.
    let mut x: f64 = 0.0;
    let mut path = Vec::new();
    // A jump is refused by the velocity check whatever the limits: move within the
    // velocity limit (50 mm/s) and the acceleration limit (from rest at 50 µm per cycle
    // is a step of 50 m/s² in the first cycle: within 1000).
    // 500 mm/s² up to 50 mm/s, then on at that speed.
    let mut v: f64 = 0.0;
    while x < 510.0 {
        v = (v + 500.0 * T).min(50.0);
        x += v * T;
        path.push(x);
    }
    for &p in &path {
        let v = r.step(Some(on(0, p)));
        assert_eq!(v.tripped, None, "at {p} with the soft limits off");
    }
    // On again beyond 510: the next setpoint (on at the same speed) trips.
    r.s.set_soft_limits(0, true);
    let v = r.step(Some(on(0, x + 50.0 * T)));
    assert_eq!(v.tripped.map(|f| f.check), Some(Check::SoftLimit));
}

/// Homing's shift moves every held position: the stream continues from the shifted
/// position without a velocity or following-error trip; with a fault latched it is
/// refused.
#[test]
fn a_shift_at_rest_moves_the_held_positions_with_the_coordinates() {
    let mut r = Rig::new(config(mill_axis()));
    for _ in 0..5 {
        r.step(Some(on(1, 0.0)));
    }
    assert!(r.s.shift(1, 123.25), "at rest");
    assert_eq!(r.s.command()[1], 123.25);
    // The drive reads the shifted coordinate at once (its offset moved with it); the
    // stream goes on from there at 500 mm/s².
    for k in 0..5 {
        let sp = on(1, 123.25 + 0.5 * 500.0 * (T * f64::from(k)).powi(2));
        let v = r.step_actual(Some(sp), r.s.command());
        assert_eq!(v.tripped, None, "cycle {k} after the shift");
    }
    // Moving: the differences are kept, the stream goes on from the shifted positions.
    assert!(r.s.shift(1, -100.0));
    let x = r.s.command()[1];
    let v = r.step(Some(on(
        1,
        x + 0.5 * 500.0 * (T * 5.0).powi(2) - 0.5 * 500.0 * (T * 4.0).powi(2),
    )));
    assert_eq!(v.tripped, None, "on after a shift while moving");
    // A latched fault: refused.
    r.s.trip(Check::DriveFault, Some(0), 1.0, 0.0, 1);
    assert!(!r.s.shift(1, 1.0));
}
