//! `push()` and `step()` never allocate: a counting global allocator, armed around
//! millions of cycles of a long program with dense arcs, sharp corners, feed override
//! changes and hold/resume.

mod common;
use common::*;
use kerf_geom::Vec3;
use kerf_motion::{MotionCore, PlannedSegment, Setpoint, StepResult};
use kerf_plan::Planner;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

struct Counting;

static ARMED: AtomicBool = AtomicBool::new(false);
static COUNT: AtomicU64 = AtomicU64::new(0);

// SAFETY: every call is forwarded unchanged to the system allocator; the counter is only
// an atomic increment.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if ARMED.load(Ordering::Relaxed) {
            COUNT.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if ARMED.load(Ordering::Relaxed) {
            COUNT.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// A closed program (starts and ends at the origin): a dense circle, a square with sharp
/// corners, a tangent arc, and a slow exact-stop line.
fn closed_program() -> Vec<PlannedSegment> {
    let limits = mill(200.0, 2000.0, 50000.0, 0.01);
    let mut moves = polygon_circle(10.0, 3600, 6000.0);
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
    let mut back = line(3, p, Vec3::zeros(), 500.0);
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

#[test]
fn push_and_step_never_allocate() {
    let limits = mill(200.0, 2000.0, 50000.0, 0.01);
    let program = closed_program();
    let mut core = MotionCore::new(limits, 4096);
    let mut sp = Setpoint::default();
    let mut next = 0usize;
    let mut moving = 0u64;
    let cycles = 2_000_000u64;
    ARMED.store(true, Ordering::SeqCst);
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
            _ => {}
        }
        if core.step(&mut sp) == StepResult::Moving {
            moving += 1;
        }
    }
    ARMED.store(false, Ordering::SeqCst);
    let allocations = COUNT.load(Ordering::SeqCst);
    assert!(
        moving > cycles / 2,
        "the core should have been moving ({moving})"
    );
    assert!(
        next > 10_000,
        "the queue should have turned over ({next} pushes)"
    );
    assert_eq!(core.plan_failures(), 0, "profile fallbacks");
    assert_eq!(allocations, 0, "allocations in push/step");
}
