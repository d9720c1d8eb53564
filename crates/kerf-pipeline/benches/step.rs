//! Benchmarks of the motion core.
//!
//! - `step/queue_1000`: one `step()` with about 1,000 segments queued (dense circle plus
//!   corners), refilling the queue as it drains. Besides criterion's mean, a separate pass
//!   times every single call and prints the p50/p99/p99.9/worst, which is what a real-time
//!   loop cares about.
//! - `sim/circle_3600`: the whole offline pipeline (plan + core) on the 3,600-line circle of
//!   radius 10 mm at F6000 with 2,000 mm/s² and 50,000 mm/s³; the printed ratio is
//!   simulated time over wall time.
// criterion_main! writes this bench's `main`, without a doc comment.
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use kerf_geom::{CornerMode, Line, Move, Path, Vec3};
use kerf_motion::{MotionCore, PlannedSegment, Setpoint};
use kerf_pipeline::{RunOptions, run};
use kerf_plan::Planner;

use kerf_testkit::machines::mill;

fn circle(n: usize) -> Vec<Move> {
    let r = 10.0;
    let center = Vec3::new(r, 0.0, 0.0);
    let pt = |k: usize| {
        if k.is_multiple_of(n) {
            return Vec3::zeros();
        }
        let th = std::f64::consts::PI + std::f64::consts::TAU * k as f64 / n as f64;
        center + Vec3::new(r * th.cos(), r * th.sin(), 0.0)
    };
    (0..n)
        .map(|k| Move {
            line: k as u32 + 1,
            rapid: false,
            path: Path::Line(Line {
                start: pt(k),
                end: pt(k + 1),
            }),
            feed_mm_min: Some(6000.0),
            abc_deg: None,
            corner: CornerMode::Blend {
                tolerance_mm: None,
                naive_cam_mm: None,
            },
        })
        .collect()
}

/// A closed program: the dense circle, then a zig-zag back to the origin.
fn program() -> Vec<PlannedSegment> {
    let mut moves = circle(3600);
    let mut p = Vec3::zeros();
    for k in 0..40 {
        let q = if k == 39 {
            Vec3::zeros()
        } else {
            Vec3::new(-0.5 * (k % 2) as f64, -0.25 * k as f64, 0.0)
        };
        moves.push(Move {
            line: 4000 + k,
            rapid: false,
            path: Path::Line(Line { start: p, end: q }),
            feed_mm_min: Some(3000.0),
            abc_deg: None,
            corner: CornerMode::Blend {
                tolerance_mm: None,
                naive_cam_mm: None,
            },
        });
        p = q;
    }
    let mut planner = Planner::new(mill());
    let mut out = Vec::new();
    for m in &moves {
        planner.push(m, &mut out).unwrap();
    }
    planner.finish(&mut out);
    out
}

struct Feeder {
    core: MotionCore,
    program: Vec<PlannedSegment>,
    next: usize,
}

impl Feeder {
    fn new() -> Self {
        let mut f = Feeder {
            core: MotionCore::new(mill().period_s, 1000),
            program: program(),
            next: 0,
        };
        f.refill();
        f
    }
    fn refill(&mut self) {
        while self.core.free() > 0 {
            let seg = self.program[self.next % self.program.len()];
            if self.core.push(&seg).is_err() {
                break;
            }
            self.next += 1;
        }
    }
}

/// Times every call of a deterministic run twice; a call slow in both passes is slow by
/// its work, one slow in a single pass was preempted.
fn step_times() -> Vec<u64> {
    let mut f = Feeder::new();
    let mut sp = Setpoint::default();
    let n = 1_000_000;
    let mut times = Vec::with_capacity(n);
    for _ in 0..n {
        f.refill();
        let t0 = Instant::now();
        black_box(f.core.step(&mut sp));
        times.push(t0.elapsed().as_nanos() as u64);
    }
    times
}

/// Times every `push` while a core with 1,000 slots runs the program for a while.
fn push_times() -> Vec<u64> {
    let mut f = Feeder::new();
    let mut sp = Setpoint::default();
    let mut times = Vec::with_capacity(1_000_000);
    for _ in 0..300_000 {
        while f.core.free() > 0 {
            let seg = f.program[f.next % f.program.len()];
            let t0 = Instant::now();
            let r = f.core.push(&seg);
            times.push(t0.elapsed().as_nanos() as u64);
            if r.is_err() {
                break;
            }
            f.next += 1;
        }
        black_box(f.core.step(&mut sp));
    }
    times
}

fn percentiles() {
    let mut pushes = push_times();
    pushes.sort_unstable();
    let n = pushes.len();
    println!(
        "push() into 1000 slots, {n} calls: p50 {} ns, p99 {} ns, p99.9 {} ns, worst {} ns",
        pushes[n / 2],
        pushes[n * 99 / 100],
        pushes[n * 999 / 1000],
        pushes[n - 1]
    );
    let first = step_times();
    let second = step_times();
    let n = first.len();
    // The per-call cost is the smaller of the two passes.
    let mut times: Vec<u64> = first.iter().zip(&second).map(|(a, b)| *a.min(b)).collect();
    times.sort_unstable();
    let mut raw = first.clone();
    raw.sort_unstable();
    let q = |v: &Vec<u64>, p: f64| v[((n as f64 * p) as usize).min(n - 1)];
    println!(
        "step() with 1000 queued, {n} calls: p50 {} ns, p99 {} ns, p99.9 {} ns, worst {} ns (single pass worst {} ns)",
        q(&times, 0.5),
        q(&times, 0.99),
        q(&times, 0.999),
        times[n - 1],
        raw[n - 1]
    );
    let moves = circle(3600);
    let t0 = Instant::now();
    let mut planner = Planner::new(mill());
    let mut out = Vec::new();
    for m in &moves {
        planner.push(m, &mut out).unwrap();
    }
    planner.finish(&mut out);
    let plan_s = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let mut core = MotionCore::new(mill().period_s, 4096);
    for seg in &out {
        core.push(seg).unwrap();
    }
    let push_s = t0.elapsed().as_secs_f64();
    println!(
        "circle 3600 lines: planning {:.3} ms, pushing {:.3} ms",
        plan_s * 1e3,
        push_s * 1e3
    );
    let t0 = Instant::now();
    let s = run(moves, &mill(), &RunOptions::default(), |_, _| {}).unwrap();
    let wall = t0.elapsed().as_secs_f64();
    println!(
        "circle 3600 lines: motion {:.3} s, simulated in {:.3} ms = {:.0}x real time",
        s.duration_s,
        wall * 1e3,
        s.duration_s / wall
    );
}

fn benches(c: &mut Criterion) {
    percentiles();
    let mut f = Feeder::new();
    let mut sp = Setpoint::default();
    c.bench_function("step/queue_1000", |b| {
        b.iter(|| {
            f.refill();
            black_box(f.core.step(&mut sp))
        })
    });
    let moves = circle(3600);
    c.bench_function("sim/circle_3600", |b| {
        b.iter(|| {
            run(
                moves.iter().copied(),
                &mill(),
                &RunOptions::default(),
                |_, _| {},
            )
            .unwrap()
            .duration_s
        })
    });
}

criterion_group!(step, benches);
criterion_main!(step);
