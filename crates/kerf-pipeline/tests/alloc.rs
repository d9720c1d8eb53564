//! The motion core's `push()` and `step()` never allocate: a counting global allocator, armed around
//! millions of cycles of a long program with dense arcs, sharp corners, feed override
//! changes, hold/resume, zero override and an abort, on a mill and on fast machines.

mod common;
use common::*;
use kerf_geom::Vec3;
use kerf_motion::{MachineLimits, MotionCore, PlannedSegment, Setpoint, StepResult};
use kerf_plan::Planner;

use kerf_testkit::alloc::{Count, CountingAllocator};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// A closed program (starts and ends at the origin): a dense circle, a square with sharp
/// corners, a tangent arc, the helix of the fast-machine report, and a slow
/// exact-stop line, planned for `limits`.
fn closed_program(limits: MachineLimits) -> Vec<PlannedSegment> {
    // The helix of the fast-machine report, from rest at the origin (exact stops on both
    // sides): a failed solver call allocates its error text.
    let helix = kerf_geom::Arc {
        start: Vec3::zeros(),
        end: Vec3::new(-1.0117, -4.0119, 0.0635),
        center: Vec3::new(-1.5765, -1.7360, 0.0),
        axis: Vec3::z(),
        sweep_rad: 0.0,
    };
    let mut h = arc(3, Vec3::zeros(), helix.center, 0.0, 0.0, 3000.0);
    h.path = kerf_geom::Path::Arc(kerf_geom::Arc {
        sweep_rad: -sweep_between(&helix),
        ..helix
    });
    h.corner = kerf_geom::CornerMode::ExactStop;
    let mut back = line(3, helix.end, Vec3::zeros(), 3000.0);
    back.corner = kerf_geom::CornerMode::ExactStop;
    let mut moves = vec![h, back];
    moves.extend(polygon_circle(10.0, 3600, 6000.0));
    let sq = [
        Vec3::zeros(),
        Vec3::new(0.0, -5.0, 0.0),
        Vec3::new(5.0, -5.0, 1.0),
        Vec3::new(5.0, -10.0, 1.0),
        Vec3::new(0.0, -10.0, 0.0),
    ];
    for w in sq.windows(2) {
        moves.push(line(1, w[0], w[1], 3000.0));
    }
    moves.push(arc(
        2,
        sq[4],
        Vec3::new(0.0, -5.0, 0.0),
        std::f64::consts::PI,
        0.5,
        2000.0,
    ));
    let p = moves.last().unwrap().path.end();
    let mut back = line(4, p, Vec3::zeros(), 500.0);
    back.corner = kerf_geom::CornerMode::ExactStop;
    moves.push(back);
    let mut planner = Planner::new(limits);
    let mut out = Vec::new();
    for m in &moves {
        planner.push(m, &mut out).unwrap();
    }
    planner.finish(&mut out);
    out
}

/// The clockwise sweep from `a.start` to `a.end` about `a.center` in XY, in (0, 2π).
fn sweep_between(a: &kerf_geom::Arc) -> f64 {
    let (u, w) = (a.start - a.center, a.end - a.center);
    let ccw = w.y.atan2(w.x) - u.y.atan2(u.x);
    let cw = (-ccw).rem_euclid(std::f64::consts::TAU);
    if cw == 0.0 { std::f64::consts::TAU } else { cw }
}

/// Runs the closed program over and over for `cycles` with override changes, holds and
/// aborts, and returns the allocations counted inside `push`/`step`/the events.
fn allocations_while_running(limits: MachineLimits, cycles: u64) -> u64 {
    let program = closed_program(limits);
    let mut core = MotionCore::new(limits.period_s, 256);
    let mut sp = Setpoint::default();
    let mut next = 0usize;
    let mut moving = 0u64;
    let count = Count::start();
    for cycle in 0..cycles {
        while core.free() > 0 {
            if core.push(&program[next % program.len()]).is_err() {
                break;
            }
            next += 1;
        }
        match cycle % 50_000 {
            10_000 => core.set_feed_override(0.6),
            20_000 => core.hold(),
            23_000 => core.resume(),
            30_000 => core.set_feed_override(1.3),
            40_000 => core.set_feed_override(1.0),
            45_000 => core.set_feed_override(0.0),
            45_500 => core.set_feed_override(2.0),
            _ => {}
        }
        if core.step(&mut sp) == StepResult::Moving {
            moving += 1;
        }
    }
    // An abort in the middle of the motion: the stop and the dropped queue.
    core.abort();
    for _ in 0..100_000 {
        if core.step(&mut sp) == StepResult::Idle {
            break;
        }
    }
    let allocations = count.stop();
    assert!(core.is_idle(), "the abort should have stopped the core");
    assert!(
        moving > cycles / 2,
        "the core should have been moving ({moving})"
    );
    assert!(
        next > 4 * core.capacity(),
        "the queue should have turned over ({next} pushes)"
    );
    assert_eq!(core.plan_failures(), 0, "profile fallbacks");
    allocations
}

/// One test, so that no other test's allocations are counted: a mill, the fast machine
/// (where a failing solve would allocate its error message), and a fast machine with a
/// short period.
#[test]
fn push_and_step_never_allocate() {
    let mut fast = mill(1000.0, 100_000.0, 1e7, 0.01);
    assert_eq!(
        allocations_while_running(mill(200.0, 2000.0, 50000.0, 0.01), 2_000_000),
        0,
        "allocations in push/step on the mill"
    );
    assert_eq!(
        allocations_while_running(fast, 2_000_000),
        0,
        "allocations in push/step on the fast machine"
    );
    fast.period_s = 0.000_062_5;
    assert_eq!(
        allocations_while_running(fast, 2_000_000),
        0,
        "allocations in push/step at 62.5 us"
    );
}
