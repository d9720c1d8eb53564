//! The cost per real-time cycle of moving the machine by hand (issue 29): the movers a
//! jog or a homing runs on (`kerf_motion::AxisMove`, one per axis, on rsruckig), with the
//! bundled machine's X, Y and Z limits at its 1 ms period, the way the daemon's manual
//! cycle drives them:
//!
//! - `jog_3_axes_cycle`: three axes jogging continuously, the request renewed every
//!   cycle (as the dead man's renewals arrive) and reversed every 400 cycles (a new
//!   jerk-limited ramp each time): one cycle of the three movers;
//! - `jog_to_plan_and_step`: an absolute jog's worst cycle, the one that plans it:
//!   `move_to` to a new target (a rsruckig solve) and the first step;
//! - `home_3_axes_cycle`: three axes homing on switches (`kerf_drive::homing::Homing`, the
//!   sequencer, driving the movers; each switch computed from the mover's position),
//!   restarted when done: one cycle of the three sequencers and movers.
//!
//! `cargo bench -p kerf-benches --bench manual`
// criterion_main! writes this bench's `main`, without a doc comment.
#![allow(missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use kerf_config::Config;
use kerf_drive::homing::{HomeCommand, HomeInput, HomeKind, HomePhase, HomeSetup, Homing};
use kerf_motion::axis_move::AxisMove;

const PERIOD_S: f64 = 1e-3;

/// The bundled machine's X, Y and Z movers at `start`, braking at 95 % of the
/// acceleration and jerk limits as the daemon's do.
fn movers(config: &Config, start: [f64; 3]) -> Vec<AxisMove> {
    let m = kerf_config::machine_limits(config);
    (0..3)
        .map(|i| {
            let mut limits = m.axes[i].expect("X, Y and Z");
            limits.acceleration_units_s2 *= 0.95;
            limits.jerk_units_s3 *= 0.95;
            AxisMove::new(PERIOD_S, limits, start[i]).expect("a mover")
        })
        .collect()
}

fn bench_jog(c: &mut Criterion) {
    let config = Config::builtin();
    let mut group = c.benchmark_group("manual");
    let mut axes = movers(&config, [0.0; 3]);
    let mut k = 0u64;
    group.bench_function("jog_3_axes_cycle", |b| {
        b.iter(|| {
            k += 1;
            let sign = if (k / 400).is_multiple_of(2) {
                1.0
            } else {
                -1.0
            };
            let mut sum = 0.0;
            for (i, ax) in axes.iter_mut().enumerate() {
                ax.run(sign * 20.0 * (i + 1) as f64)
                    .expect("a finite velocity");
                sum += ax.step();
            }
            sum
        })
    });
    let mut axis = movers(&config, [0.0; 3]).swap_remove(0);
    let mut n = 0u64;
    group.bench_function("jog_to_plan_and_step", |b| {
        b.iter(|| {
            // Alternating targets 1 to 50 mm away, from wherever the last one left it
            // (mostly moving: each plan starts from a state in motion).
            n += 1;
            let target = if n.is_multiple_of(2) {
                (n % 50) as f64 + 1.0
            } else {
                -((n % 37) as f64)
            };
            axis.move_to(target, 100.0).expect("a reachable target");
            axis.step()
        })
    });
    group.finish();
}

/// Switch homing toward + at 100 mm/s, latching at 2 mm/s where the switch releases,
/// the switch 20 mm from where the axis powers up.
fn home_setup() -> HomeSetup {
    HomeSetup {
        kind: HomeKind::Switch,
        search_velocity: 100.0,
        latch_velocity: -2.0,
        search_distance: 300.0,
        home_offset: 0.0,
        home_position: 10.0,
        final_speed: 100.0,
    }
}

fn bench_homing(c: &mut Criterion) {
    let config = Config::builtin();
    let mut group = c.benchmark_group("manual");
    let mut axes = movers(&config, [0.0; 3]);
    let mut homing: Vec<Homing> = (0..3)
        .map(|_| Homing::new(home_setup()).expect("a valid setup"))
        .collect();
    // Where each switch is in the axis's current coordinates (homing shifts them).
    let mut switch_at = [20.0; 3];
    let mut homed = 0u64;
    group.bench_function("home_3_axes_cycle", |b| {
        b.iter(|| {
            for i in 0..3 {
                let (ax, h) = (&mut axes[i], &mut homing[i]);
                if matches!(h.phase(), HomePhase::Idle | HomePhase::Done) {
                    // Done (or never started): from rest, again.
                    homed += 1;
                    switch_at[i] = ax.position() + 20.0;
                    h.start();
                }
                let input = HomeInput {
                    switch: ax.position() >= switch_at[i],
                    position: ax.position(),
                    at_rest: ax.at_rest(),
                };
                match h.cycle(&input) {
                    HomeCommand::Hold => {}
                    HomeCommand::Run(v) => ax.run(v).expect("a finite velocity"),
                    HomeCommand::Stop => ax.stop(),
                    HomeCommand::MoveTo { position, speed } => {
                        ax.move_to(position, speed).expect("a reachable target")
                    }
                    HomeCommand::Shift(d) => {
                        let here = ax.position();
                        assert!(ax.rebase(here + d), "shifted at rest");
                        switch_at[i] += d;
                    }
                }
                assert!(h.error().is_none(), "{:?}", h.error());
                ax.step();
            }
        })
    });
    group.finish();
    assert!(homed > 3, "the homings never finished");
}

criterion_group!(benches, bench_jog, bench_homing);
criterion_main!(benches);
