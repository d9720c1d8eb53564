//! The drive side's cost per real-time cycle: `DriveStage::cycle` with the daemon's
//! configuration (three simulated drives, 20 integration substeps each at 1 ms, the
//! safety checks, the 10 s black box), following a motion; and the same with a dump being
//! copied out (256 records per cycle). And the machine around the axes
//! (`kerf_drive::machine::Machine`, the bundled machine's simulated spindle, coolant and
//! I/O) per cycle: its step while the spindle ramps and is watched while feeding, and a
//! cycle that also hands it an action.
//!
//! `cargo bench -p kerf-benches --bench drive`
// criterion_main! writes this bench's `main`, without a doc comment.
#![allow(missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use kerf_config::Config;
use kerf_drive::stage::StageInput;
use kerfd::worker::drive_stage;

fn bench_drive(c: &mut Criterion) {
    let config = Config::builtin();
    let mut stage = drive_stage(&config, [0.0; 6]).expect("the built-in machine's drives");
    let mut k = 0u64;
    // Enable, then a back-and-forth motion along a diagonal, once per second (from rest:
    // 5·(1 − cos ωt), at most 197 mm/s² and 31 mm/s).
    let mut step = |stage: &mut kerf_drive::stage::DriveStage<_>| {
        k += 1;
        let t = k as f64 * 1e-3;
        let w = 2.0 * std::f64::consts::PI;
        let s = 1.0 - (w * t).cos();
        let p = [5.0 * s, 3.0 * s, -s, 0.0, 0.0, 0.0];
        stage.cycle(&StageInput {
            setpoint: Some(p),
            line: 1,
            time_s: t,
        })
    };
    for _ in 0..10 {
        stage.cycle(&StageInput {
            setpoint: Some([0.0; 6]),
            line: 0,
            time_s: 0.0,
        });
    }
    assert!(stage.ready());
    let mut group = c.benchmark_group("drive_stage");
    group.bench_function("cycle_3_sim_drives", |b| {
        b.iter(|| {
            let out = step(&mut stage);
            assert!(out.tripped.is_none());
            out
        })
    });
    group.bench_function("cycle_3_sim_drives_while_dumping", |b| {
        b.iter(|| {
            if let Some(d) = stage.take_dump() {
                stage.return_spare(d.recorder);
            }
            stage.request_dump(1);
            step(&mut stage)
        })
    });
    group.finish();
}

fn bench_machine(c: &mut Criterion) {
    use kerf_geom::machine::{Action, ActionKind, MachineIo, SpindleDir};
    let config = Config::builtin();
    let mut machine = kerf_drive::machine::Machine::new(
        kerfd::machine::machine_config(&config).expect("the built-in machine"),
    )
    .expect("a valid machine");
    let spindle = |dir, rpm| Action {
        line: 1,
        kind: ActionKind::Spindle { dir, rpm },
    };
    let mut group = c.benchmark_group("machine");
    // The spindle reverses between ±12000 rpm every 4000 cycles: it ramps most of the time.
    let mut k = 0u64;
    group.bench_function("cycle_spindle_ramping_while_feeding", |b| {
        b.iter(|| {
            k += 1;
            if k.is_multiple_of(4000) {
                let dir = if (k / 4000).is_multiple_of(2) {
                    SpindleDir::Cw
                } else {
                    SpindleDir::Ccw
                };
                machine.act(&spindle(dir, 12000.0));
            }
            machine.cycle(true);
            machine.status()
        })
    });
    let coolant = |flood| Action {
        line: 2,
        kind: ActionKind::Coolant { mist: false, flood },
    };
    let mut on = false;
    group.bench_function("cycle_with_an_action", |b| {
        b.iter(|| {
            on = !on;
            machine.act(&coolant(on));
            machine.cycle(false);
            machine.status()
        })
    });
    group.finish();
}

criterion_group!(benches, bench_drive, bench_machine);
criterion_main!(benches);
