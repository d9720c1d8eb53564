//! `AxisMove`, the single-axis mover for jogging and homing, measured from the positions
//! its `step()` returns: velocity, acceleration and jerk by finite differences at the
//! period (`LimitMonitor`, 1 % plus the rounding allowance), ends, speed caps and stopping
//! distances against closed forms written here. The mover's own getters are used only to
//! decide when to stop stepping and to issue commands; every verdict is taken on the
//! samples. Limits, periods and distances sweep the configuration's whole range.

use kerf_motion::axis_move::{AxisMove, AxisMoveError};
use kerf_motion::monitor::{LimitMonitor, Quantity};
use kerf_motion::{AxisLimits, MachineLimits};
use kerf_testkit::alloc::{Count, CountingAllocator};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// Most steps a property case may take (the distances are chosen to fit).
const MAX_STEPS: f64 = 100_000.0;

fn config(cases: u32, seed: u64) -> ProptestConfig {
    ProptestConfig {
        cases,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// Log-uniform in `[lo, hi]`.
fn log_uniform(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    (lo.ln()..=hi.ln()).prop_map(f64::exp)
}

/// Axis limits over the configuration's whole range.
fn any_limits() -> impl Strategy<Value = AxisLimits> {
    (
        log_uniform(0.001, 1e5),
        log_uniform(0.01, 1e8),
        log_uniform(1.0, 1e12),
    )
        .prop_map(|(v, a, j)| AxisLimits {
            velocity_units_s: v,
            acceleration_units_s2: a,
            jerk_units_s3: j,
        })
}

/// Periods from 50 µs to 10 ms.
fn any_period() -> impl Strategy<Value = f64> {
    log_uniform(50e-6, 10e-3)
}

/// Time of a jerk-limited change of velocity by `dv` starting and ending at zero
/// acceleration (two jerk ramps, with a constant-acceleration phase between them when
/// `dv > a²/j`).
fn change_time(dv: f64, a: f64, j: f64) -> f64 {
    if dv * j <= a * a {
        2.0 * (dv / j).sqrt()
    } else {
        dv / a + a / j
    }
}

/// Distance of a stop from velocity `v` at zero acceleration: the velocity falls
/// symmetrically about its half-way point, so the distance is `v/2` times the time.
fn stop_distance(v: f64, a: f64, j: f64) -> f64 {
    0.5 * v * change_time(v, a, j)
}

/// The time-optimal rest-to-rest time over `d` with limits `(v, a, j)`: up to a peak
/// speed along the symmetric S-curve, cruise, and down again; the peak is the speed limit
/// if the distance allows it, else the speed whose up and down fill the distance exactly
/// (by bisection: the distance grows with it).
fn rest_to_rest_time(d: f64, limits: &AxisLimits) -> f64 {
    let (v, a, j) = (
        limits.velocity_units_s,
        limits.acceleration_units_s2,
        limits.jerk_units_s3,
    );
    let up_and_down = |vp: f64| vp * change_time(vp, a, j);
    if up_and_down(v) <= d {
        return 2.0 * change_time(v, a, j) + (d - up_and_down(v)) / v;
    }
    let (mut lo, mut hi) = (0.0, v);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if up_and_down(mid) <= d {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    2.0 * change_time(lo, a, j)
}

/// The largest distance up to `d` whose rest-to-rest time at `limits` fits in `steps`
/// periods.
fn fit_distance(d: f64, limits: &AxisLimits, period_s: f64, steps: f64) -> f64 {
    let budget = steps * period_s;
    if rest_to_rest_time(d, limits) <= budget {
        return d;
    }
    let (mut lo, mut hi) = (0.0, d);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if rest_to_rest_time(mid, limits) <= budget {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The highest speed up to `v` that a velocity change from rest (or a stop) reaches in
/// `steps` periods.
fn fit_speed(v: f64, limits: &AxisLimits, period_s: f64, steps: f64) -> f64 {
    let (a, j) = (limits.acceleration_units_s2, limits.jerk_units_s3);
    let budget = steps * period_s;
    if change_time(v, a, j) <= budget {
        return v;
    }
    let (mut lo, mut hi) = (0.0, v);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if change_time(mid, a, j) <= budget {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// A mover with its samples: the start position, then every step's.
struct Trace {
    mover: AxisMove,
    x: Vec<f64>,
    period_s: f64,
    limits: AxisLimits,
}

impl Trace {
    fn new(period_s: f64, limits: AxisLimits, start: f64) -> Trace {
        Trace {
            mover: AxisMove::new(period_s, limits, start).unwrap(),
            x: vec![start],
            period_s,
            limits,
        }
    }

    fn step(&mut self) -> f64 {
        let x = self.mover.step();
        assert!(x.is_finite(), "step {} gave {x}", self.x.len());
        self.x.push(x);
        x
    }

    fn steps(&mut self, n: usize) {
        for _ in 0..n {
            self.step();
        }
    }

    /// The largest |position| of the trace.
    fn magnitude(&self) -> f64 {
        self.x.iter().fold(0.0f64, |m, x| m.max(x.abs()))
    }

    /// A limit monitor for the trace, from rest at its start. Positions are computed as a
    /// start plus a distance, each at most the trace's largest |position| (twice that
    /// between them): that is the magnitude of their rounding.
    fn monitor(&self) -> LimitMonitor {
        let machine = MachineLimits {
            axes: [Some(self.limits), None, None, None, None, None],
            period_s: self.period_s,
            tolerance_mm: 0.01,
        };
        let start = [self.x[0], 0.0, 0.0, 0.0, 0.0, 0.0];
        let m = 2.0 * self.magnitude();
        LimitMonitor::at_rest(&machine, &start).with_position_scale([m; 6])
    }

    /// Every sample within the velocity, acceleration and jerk limits by finite
    /// differences (1 % and the rounding allowance, as the daemon's monitor).
    fn check_limits(&self) {
        let mut monitor = self.monitor();
        for &x in &self.x[1..] {
            if let Err(v) = monitor.check(&[x, 0.0, 0.0, 0.0, 0.0, 0.0]) {
                panic!("{v} (limits {:?}, period {} s)", self.limits, self.period_s);
            }
        }
    }

    /// Steps until the mover says it is at rest (at most `max` steps), then a few more,
    /// and checks on the samples that it really stays put and that every limit held; the
    /// rest position.
    fn run_to_rest(&mut self, max: f64) -> f64 {
        let mut n = 0.0;
        while !self.mover.at_rest() {
            assert!(n <= max, "not at rest after {max} steps");
            self.step();
            n += 1.0;
        }
        let rest = *self.x.last().unwrap();
        for _ in 0..3 {
            assert_eq!(self.step().to_bits(), rest.to_bits(), "moved after rest");
        }
        assert_eq!(self.mover.plan_failures(), 0, "solver failures");
        self.check_limits();
        rest
    }

    /// |Δx/T| of sample `i` (from sample `i − 1`).
    fn speed(&self, i: usize) -> f64 {
        (self.x[i] - self.x[i - 1]).abs() / self.period_s
    }

    /// The rounding allowance of a measured speed at the trace's magnitude.
    fn speed_allowance(&self) -> f64 {
        self.monitor()
            .allowance(Quantity::Velocity, 2.0 * self.magnitude())
    }

    /// Steps the rest-to-rest time of a move (with room for rounding) at most.
    fn budget(&self, d: f64) -> f64 {
        rest_to_rest_time(d.abs(), &self.limits) * (1.0 + 1e-4) / self.period_s + 10.0
    }
}

/// A move planned from rest ends bit-exactly on its target, never passes it (the samples
/// go one way, from start to target), never exceeds the speed asked for, keeps every limit
/// and takes no longer than the time-optimal rest-to-rest time (within the planner's phase
/// floor and two periods).
#[test]
fn move_from_rest_ends_exactly_on_target_within_limits() {
    proptest!(config(400, 0x29a1), |(
        limits in any_limits(),
        period_s in any_period(),
        d in log_uniform(1e-6, 1e4),
        backwards in any::<bool>(),
        start in -1000.0f64..1000.0,
        speed_frac in log_uniform(1e-3, 2.0),
    )| {
        let speed = limits.velocity_units_s * speed_frac;
        let capped = AxisLimits { velocity_units_s: speed.min(limits.velocity_units_s), ..limits };
        let d = fit_distance(d, &capped, period_s, MAX_STEPS);
        prop_assume!(d > 1e-9);
        let d = if backwards { -d } else { d };
        let target = start + d;
        let mut t = Trace::new(period_s, limits, start);
        t.mover.move_to(target, speed).unwrap();
        let budget = rest_to_rest_time(d.abs(), &capped) * (1.0 + 1e-4) / period_s + 10.0;
        let end = t.run_to_rest(budget);
        prop_assert_eq!(end.to_bits(), target.to_bits());
        // One way, never past the target (rounding may repeat a sample, never reverse it).
        let (lo, hi) = (start.min(target), start.max(target));
        let allow = t.speed_allowance();
        for i in 1..t.x.len() {
            let x = t.x[i];
            prop_assert!(lo <= x && x <= hi, "sample {i} at {x} outside [{lo}, {hi}]");
            let step = (x - t.x[i - 1]) * d.signum();
            prop_assert!(step >= -allow * period_s, "sample {i} goes back by {step}");
            prop_assert!(t.speed(i) <= capped.velocity_units_s * (1.0 + 1e-9) + allow,
                "sample {i}: speed {} over {}", t.speed(i), capped.velocity_units_s);
        }
        // Time-optimal: on the target within the optimal time (and the planner's phase
        // floor). Not faster than it either, but that is the limits' business: near the end
        // a sample may round onto the target early.
        let moving = t.x.iter().position(|&x| x.to_bits() == target.to_bits()).unwrap();
        let optimal = rest_to_rest_time(d.abs(), &capped) / period_s;
        prop_assert!((moving as f64) <= optimal * (1.0 + 1e-5) + 2.0,
            "{moving} steps, optimal {optimal}");
    });
}

/// Re-targeting mid-motion: a new target behind the axis while it moves fast, at the same
/// or another speed. The motion stays within the limits through the re-plan (no jump in
/// position, velocity or acceleration) and ends exactly on the new target.
#[test]
fn retarget_mid_motion_behind_the_axis() {
    proptest!(config(300, 0x29a2), |(
        limits in any_limits(),
        period_s in any_period(),
        d in log_uniform(1e-6, 1e4),
        when in 0.0f64..1.0,
        back in 0.0f64..2.0,
        speed2_frac in log_uniform(0.01, 2.0),
    )| {
        let d = fit_distance(d, &limits, period_s, MAX_STEPS / 4.0);
        prop_assume!(d > 1e-9);
        let mut t = Trace::new(period_s, limits, 0.0);
        t.mover.move_to(d, limits.velocity_units_s).unwrap();
        let n = (rest_to_rest_time(d, &limits) / period_s * when) as usize;
        t.steps(n);
        let here = *t.x.last().unwrap();
        let target2 = here - back * d;
        let speed2 = limits.velocity_units_s * speed2_frac;
        t.mover.move_to(target2, speed2).unwrap();
        // Stopping (at most a move over d), and the way back (at most from d to target2,
        // at the new speed).
        let slow = AxisLimits { velocity_units_s: speed2.min(limits.velocity_units_s), ..limits };
        let back_steps = rest_to_rest_time(d - target2, &slow) / period_s;
        let budget = t.budget(d) + back_steps * (1.0 + 1e-4) + 10.0;
        let end = t.run_to_rest(budget);
        prop_assert_eq!(end.to_bits(), target2.to_bits());
    });
}

/// The speed asked for changes while the axis moves (the feed override dropping or
/// rising during a jog): the limits hold through the change, the new speed holds from the
/// first sample at or below it on (at a lower speed the axis brakes down to it first; an
/// axis still speeding up first brings its acceleration down), and the move ends exactly
/// on the target without passing it.
#[test]
fn speed_change_mid_motion() {
    proptest!(config(300, 0x29a3), |(
        limits in any_limits(),
        period_s in any_period(),
        d in log_uniform(1e-6, 1e4),
        when in 0.0f64..1.0,
        speed1_frac in log_uniform(0.05, 1.0),
        factor in log_uniform(0.01, 4.0),
        backwards in any::<bool>(),
    )| {
        let speed1 = limits.velocity_units_s * speed1_frac;
        let slow = AxisLimits {
            velocity_units_s: (speed1 * factor.min(1.0)).min(limits.velocity_units_s),
            ..limits
        };
        let d = fit_distance(d, &slow, period_s, MAX_STEPS / 2.0);
        prop_assume!(d > 1e-9);
        let target = if backwards { -d } else { d };
        let mut t = Trace::new(period_s, limits, 0.0);
        t.mover.move_to(target, speed1).unwrap();
        let fast = AxisLimits { velocity_units_s: speed1, ..limits };
        let n = (rest_to_rest_time(d, &fast) / period_s * when) as usize;
        t.steps(n);
        let speed2 = speed1 * factor;
        t.mover.move_to(target, speed2).unwrap();
        let k = t.x.len();
        let end = t.run_to_rest(t.budget(d) * 2.0 + rest_to_rest_time(d, &slow) / period_s);
        prop_assert_eq!(end.to_bits(), target.to_bits());
        let cap = speed2.min(limits.velocity_units_s) * (1.0 + 1e-9) + t.speed_allowance();
        // An axis accelerating at a (measured from the samples before the change) goes on
        // speeding up while its acceleration comes down at the jerk limit, |a|/j: past
        // that (and a period of rounding in the measure), the cap holds from the first
        // sample at or below it.
        // The n-th last sample before the change (the start, at rest, before the first).
        let back = |n: usize| t.x[k.saturating_sub(n)];
        let a = (back(1) - 2.0 * back(2) + back(3)) / (period_s * period_s);
        let settle = k + ((a.abs() / limits.jerk_units_s3) / period_s).ceil() as usize + 2;
        let first = (settle.min(t.x.len() - 1)..t.x.len()).find(|&i| t.speed(i) <= cap).unwrap();
        for i in first..t.x.len() {
            prop_assert!(t.speed(i) <= cap, "sample {i}: speed {} over {cap}", t.speed(i));
        }
        // From rest on the new target's side, nothing passes it (it was not passed before).
        for &x in &t.x {
            prop_assert!(x * target.signum() <= target.abs(), "{x} past {target}");
        }
    });
}

/// Run → stop at random instants (accelerating or at speed, either direction): the
/// limits hold, the axis comes to rest where `stopping_position()` said it would (to the
/// bit), and from a cruise the stop takes the jerk-limited stopping distance of its speed.
#[test]
fn run_then_stop_at_random_instants() {
    proptest!(config(400, 0x29a4), |(
        limits in any_limits(),
        period_s in any_period(),
        v_frac in log_uniform(1e-3, 1.5),
        negative in any::<bool>(),
        when in 0.0f64..2.0,
    )| {
        let v = fit_speed(limits.velocity_units_s * v_frac.min(1.0), &limits, period_s, MAX_STEPS / 4.0);
        prop_assume!(v > 0.0);
        let v = if negative { -v } else { v };
        let mut t = Trace::new(period_s, limits, 0.0);
        t.mover.run(v).unwrap();
        let up = change_time(v.abs(), limits.acceleration_units_s2, limits.jerk_units_s3);
        let n = (up / period_s * when) as usize;
        t.steps(n);
        let from = *t.x.last().unwrap();
        let said = t.mover.stopping_position();
        t.mover.stop();
        let end = t.run_to_rest(2.0 * up / period_s + 10.0);
        prop_assert_eq!(end.to_bits(), said.to_bits());
        if when > 1.0 && (n as f64) * period_s > up + 2.0 * period_s {
            // At speed v (a = 0): the stop's distance is the closed form's, and the
            // cruise itself is at v.
            let m = t.magnitude();
            let measured = t.speed(n);
            prop_assert!((measured - v.abs()).abs() <= 1e-9 * v.abs() + t.speed_allowance(),
                "cruise at {measured} for {v}");
            let bound = stop_distance(v.abs(), limits.acceleration_units_s2, limits.jerk_units_s3);
            let went = (end - from) * v.signum();
            prop_assert!(went <= bound * (1.0 + 1e-9) + 64.0 * f64::EPSILON * m,
                "stopped after {went}, bound {bound}");
            prop_assert!(went >= bound * (1.0 - 1e-9) - 64.0 * f64::EPSILON * m,
                "stopped after {went}, less than the time-optimal {bound}");
        }
    });
}

/// `stopping_position()` during a move (the solver's profile, at random instants,
/// possibly while braking to a lower speed) names the rest position of the stop that
/// follows, bit for bit, and the stop keeps the limits.
#[test]
fn stop_during_a_move_ends_where_announced() {
    proptest!(config(300, 0x29a5), |(
        limits in any_limits(),
        period_s in any_period(),
        d in log_uniform(1e-6, 1e4),
        when in 0.0f64..1.0,
    )| {
        let d = fit_distance(d, &limits, period_s, MAX_STEPS / 4.0);
        prop_assume!(d > 1e-9);
        let mut t = Trace::new(period_s, limits, 5.0);
        t.mover.move_to(5.0 + d, limits.velocity_units_s).unwrap();
        t.steps((rest_to_rest_time(d, &limits) / period_s * when) as usize);
        let said = t.mover.stopping_position();
        t.mover.stop();
        let end = t.run_to_rest(t.budget(d));
        prop_assert_eq!(end.to_bits(), said.to_bits());
        let rounding = 4.0 * f64::EPSILON * (5.0 + d);
        prop_assert!(end <= 5.0 + d + rounding, "stopped at {end}, past the move's target");
    });
}

/// A command repeated every cycle changes nothing: a script of random commands, each held
/// for a random number of cycles, gives bit-identical positions whether each command is
/// given once or again every cycle, and the same script run twice gives the same positions
/// (determinism).
#[test]
fn repeated_commands_change_nothing_and_runs_are_deterministic() {
    #[derive(Clone, Copy, Debug)]
    enum Cmd {
        MoveTo(f64, f64),
        Run(f64),
        Stop,
    }
    let cmd = prop_oneof![
        (-1.0f64..1.0, 0.05f64..1.5).prop_map(|(x, s)| Cmd::MoveTo(x, s)),
        (-1.5f64..1.5).prop_map(Cmd::Run),
        Just(Cmd::Stop),
    ];
    proptest!(config(200, 0x29a6), |(
        limits in any_limits(),
        period_s in any_period(),
        script in proptest::collection::vec((cmd, 1usize..400), 1..8),
    )| {
        // Commands in units of what the axis can do in a few hundred periods.
        let reach = limits.velocity_units_s * 300.0 * period_s;
        let v = limits.velocity_units_s;
        let play = |every_cycle: bool| {
            let mut t = Trace::new(period_s, limits, 0.0);
            for &(c, cycles) in &script {
                for k in 0..cycles {
                    if k == 0 || every_cycle {
                        match c {
                            Cmd::MoveTo(x, s) => t.mover.move_to(x * reach, s * v).unwrap(),
                            Cmd::Run(r) => t.mover.run(r * v).unwrap(),
                            Cmd::Stop => t.mover.stop(),
                        }
                    }
                    t.step();
                }
            }
            t.mover.stop();
            t.steps(50);
            assert_eq!(t.mover.plan_failures(), 0);
            t.check_limits();
            t.x
        };
        let once = play(false);
        let again = play(false);
        let every = play(true);
        let bits = |x: &Vec<f64>| x.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        prop_assert_eq!(bits(&once), bits(&again));
        prop_assert_eq!(bits(&once), bits(&every));
    });
}

/// `rebase` takes a new position only at rest: refused while moving; at rest, the next
/// samples read the new position and moves go from there.
#[test]
fn rebase_only_at_rest() {
    let limits = AxisLimits {
        velocity_units_s: 50.0,
        acceleration_units_s2: 500.0,
        jerk_units_s3: 5000.0,
    };
    let mut m = AxisMove::new(0.001, limits, 3.0).unwrap();
    m.move_to(10.0, 20.0).unwrap();
    m.step();
    m.step();
    assert!(!m.rebase(100.0));
    let mut x = m.step();
    while !m.at_rest() {
        x = m.step();
    }
    assert_eq!(x, 10.0);
    assert!(m.rebase(-2.5));
    assert_eq!(m.step(), -2.5);
    // The same move as before is a new one in the new frame.
    m.move_to(10.0, 20.0).unwrap();
    assert!(m.step() > -2.5);
    while !m.at_rest() {
        x = m.step();
    }
    assert_eq!(x, 10.0);
    assert!(!m.rebase(f64::NAN));
}

/// Bad arguments are refused with the value named, and nothing moves.
#[test]
fn bad_arguments_are_refused() {
    let ok = AxisLimits {
        velocity_units_s: 10.0,
        acceleration_units_s2: 100.0,
        jerk_units_s3: 1000.0,
    };
    assert_eq!(
        AxisMove::new(0.0, ok, 0.0).unwrap_err(),
        AxisMoveError::Period { period_s: 0.0 }
    );
    assert!(AxisMove::new(f64::NAN, ok, 0.0).is_err());
    for bad in [0.0, -1.0, f64::INFINITY, f64::NAN] {
        for which in 0..3 {
            let mut l = ok;
            match which {
                0 => l.velocity_units_s = bad,
                1 => l.acceleration_units_s2 = bad,
                _ => l.jerk_units_s3 = bad,
            }
            let e = AxisMove::new(0.001, l, 0.0).unwrap_err();
            assert!(matches!(e, AxisMoveError::Limit { .. }), "{e}");
        }
    }
    assert!(AxisMove::new(0.001, ok, f64::INFINITY).is_err());
    let mut m = AxisMove::new(0.001, ok, 1.0).unwrap();
    assert!(m.move_to(f64::NAN, 1.0).is_err());
    assert!(m.move_to(2.0, 0.0).is_err());
    assert!(m.move_to(2.0, -1.0).is_err());
    assert!(m.move_to(2.0, f64::NAN).is_err());
    assert!(m.run(f64::INFINITY).is_err());
    let e = m.run(f64::NAN).unwrap_err().to_string();
    assert!(e.contains("velocity"), "{e}");
    for _ in 0..10 {
        assert_eq!(m.step(), 1.0);
    }
    assert!(m.at_rest());
}

/// `step`, `move_to`, `run` and `stop` never allocate: a counting allocator armed around
/// many cycles of moves, re-targets, speed changes, runs and stops on several machines.
#[test]
fn the_cycle_never_allocates() {
    let machines = [
        (50.0, 500.0, 5000.0, 0.001),
        (1e5, 1e8, 1e12, 50e-6),
        (0.01, 0.05, 2.0, 0.01),
        (200.0, 1e4, 1e9, 250e-6),
    ];
    for (v, a, j, period_s) in machines {
        let limits = AxisLimits {
            velocity_units_s: v,
            acceleration_units_s2: a,
            jerk_units_s3: j,
        };
        let mut m = AxisMove::new(period_s, limits, 0.0).unwrap();
        let reach = v * 500.0 * period_s;
        let count = Count::start();
        let mut sum = 0.0;
        for round in 0..20 {
            let f = f64::from(round);
            m.move_to(reach * (1.0 + f * 0.1), v).unwrap();
            for k in 0..300 {
                if k == 100 {
                    m.move_to(-reach * 0.5, v * 0.3).unwrap();
                }
                if k == 150 {
                    m.move_to(-reach * 0.5, v).unwrap();
                }
                sum += m.step();
            }
            m.run(if round % 2 == 0 { v } else { -v * 0.5 }).unwrap();
            for _ in 0..200 {
                sum += m.step();
            }
            sum += m.stopping_position();
            m.stop();
            for _ in 0..200 {
                sum += m.step();
            }
        }
        let allocations = count.stop();
        assert!(sum.is_finite());
        assert_eq!(m.plan_failures(), 0);
        assert_eq!(allocations, 0, "{limits:?}");
    }
}
