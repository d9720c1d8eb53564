//! The motion's start before a full queue: a source whose planner is behind
//! ([`Poll::Planning`], the daemon's planner behind the moves it received) lets the motion
//! start once
//! it has handed over `START_LEAD_S` of motion and the core's lookahead has settled
//! (`MotionCore::lookahead_settled`). The claim is that this changes no setpoint: as long
//! as a settled section stays ahead of the motion, the run is bit for bit the one that
//! started with a full queue (`kerf sim`'s source never pends).
//!
//! Random programs and machines (fixed seed) are planned once and run twice through the
//! [`Interpolator`]: from a source that always has the next segment, and from one that
//! hands over nothing for a random number of cycles and then at most a random number of
//! segments a cycle (a slow planner). Every run whose slow source kept a settled section
//! ahead of the motion (checked before every cycle's feeding) must give the same
//! positions; the sweep must start early often and keep ahead in most of those runs, so
//! the property is really exercised.

mod common;
use common::*;
use kerf_geom::machine::InstantMachine;
use kerf_geom::{CornerMode, Move, PerAxis, Vec3};
use kerf_motion::{MachineLimits, MotionCore, PlannedSegment, Setpoint};
use kerf_pipeline::{Interpolator, OperatorEvent, Planned, Poll, START_LEAD_S, segment_time_s};
use kerf_plan::Planner;

fn random_limits(rng: &mut Rng) -> MachineLimits {
    let mut m = mill(100.0, 1000.0, 10000.0, rng.log(0.002, 0.05));
    m.period_s = [0.00025, 0.0005, 0.001, 0.002][rng.pick(4)];
    for ax in m.axes.iter_mut().take(3) {
        *ax = Some(kerf_motion::AxisLimits {
            velocity_units_s: rng.log(30.0, 500.0),
            acceleration_units_s2: rng.log(200.0, 5000.0),
            jerk_units_s3: rng.log(2000.0, 200_000.0),
        });
    }
    m
}

/// A program of a few kinds of code: dense smooth polylines (long merged sections), rough
/// polylines (a corner at every vertex, as noisy CAM code above the tolerance), long
/// lines and arcs, some exact stops.
fn random_program(rng: &mut Rng) -> Vec<Move> {
    let mut moves: Vec<Move> = Vec::new();
    let mut p = Vec3::zeros();
    let mut line_no = 1;
    let pieces = 2 + rng.pick(6);
    for _ in 0..pieces {
        let feed = rng.log(300.0, 12000.0);
        match rng.pick(4) {
            0 => {
                // A dense wave: 0.02 to 0.5 mm steps.
                let step = rng.log(0.02, 0.5);
                let (amp, wave) = (rng.range(0.0, 2.0), rng.log(2.0, 30.0));
                let n = 50 + rng.pick(400);
                let x0 = p.x;
                for _ in 0..n {
                    let x = p.x + step;
                    let q = Vec3::new(
                        x,
                        p.y,
                        amp * ((x - x0) * std::f64::consts::TAU / wave).sin(),
                    );
                    moves.push(line(line_no, p, q, feed));
                    p = q;
                    line_no += 1;
                }
            }
            1 => {
                // Rough: every vertex off the line by more than the tolerance.
                let step = rng.log(0.05, 1.0);
                let n = 20 + rng.pick(200);
                for k in 0..n {
                    let off = if k % 2 == 0 { 0.05 } else { -0.05 } * rng.range(0.5, 2.0);
                    let q = Vec3::new(p.x + step, p.y + off, p.z);
                    moves.push(line(line_no, p, q, feed));
                    p = q;
                    line_no += 1;
                }
            }
            2 => {
                let q = p + unit_vec(rng) * rng.log(1.0, 80.0);
                let mut mv = line(line_no, p, q, feed);
                if rng.pick(3) == 0 {
                    mv.corner = CornerMode::ExactStop;
                }
                moves.push(mv);
                p = q;
                line_no += 1;
            }
            _ => {
                let radial = unit_vec(rng) * rng.log(0.5, 20.0);
                let axis = Vec3::z();
                let radial = radial - axis * radial.dot(&axis);
                if radial.norm() < 0.1 {
                    continue;
                }
                let sweep = rng.range(0.3, 6.0) * rng.sign();
                let mv = arc_about(line_no, p, radial, axis, sweep, 0.0, feed);
                p = mv.path.end();
                moves.push(mv);
                line_no += 1;
            }
        }
    }
    moves
}

fn plan(moves: &[Move], limits: &MachineLimits) -> Vec<PlannedSegment> {
    let mut planner = Planner::new(*limits);
    let mut segs = Vec::new();
    for mv in moves {
        planner.push(mv, &mut segs).unwrap();
    }
    planner.finish(&mut segs);
    segs
}

/// How a run went.
struct Run {
    positions: Vec<PerAxis<f64>>,
    /// The motion started before the queue was full and before the source's end.
    early: bool,
    /// Before every cycle's feeding while the source had more, a settled section was
    /// ahead of the motion.
    kept_ahead: bool,
}

/// A source slower than the motion: nothing for the first `delay` cycles, then at most
/// `per_cycle` segments a cycle, and `answer` when it has nothing.
#[derive(Clone, Copy, Debug)]
struct Slow {
    delay: u64,
    per_cycle: usize,
    answer: Poll,
}

/// Runs `segs` on a queue of `capacity`, from `slow` or from a source that always has the
/// next segment; `events`: each applied before the motion's step number `.0`.
fn run(
    segs: &[PlannedSegment],
    period_s: f64,
    capacity: usize,
    slow: Option<Slow>,
    events: &[(usize, OperatorEvent)],
) -> Run {
    let mut interp = Interpolator::new(MotionCore::new(period_s, capacity));
    let mut machine = InstantMachine;
    let (mut next, mut cycle) = (0usize, 0u64);
    let mut out = Run {
        positions: Vec::new(),
        early: false,
        kept_ahead: true,
    };
    loop {
        if interp.started() && next < segs.len() && !interp.core().lookahead_settled() {
            out.kept_ahead = false;
        }
        let mut handed = 0;
        let was_started = interp.started();
        let started = interp
            .feed(
                || {
                    if next == segs.len() {
                        return Poll::End;
                    }
                    if let Some(s) = slow
                        && (cycle < s.delay || handed == s.per_cycle)
                    {
                        return s.answer;
                    }
                    handed += 1;
                    next += 1;
                    Poll::Ready(Planned::Segment(segs[next - 1], 0))
                },
                &mut machine,
            )
            .unwrap();
        cycle += 1;
        assert!(cycle < 50_000_000, "the run does not end");
        if !started {
            continue;
        }
        if !was_started {
            out.early = interp.core().queued() < capacity && !interp.source_ended();
            if out.early {
                let lead_s: f64 = segs[..next].iter().map(segment_time_s).sum();
                assert!(lead_s >= START_LEAD_S * (1.0 - 1e-12), "{lead_s}");
            }
        }
        for (at, e) in events {
            if out.positions.len() == *at {
                interp.apply(*e);
            }
        }
        let mut sp = Setpoint::default();
        interp.step(&mut sp);
        out.positions.push(sp.position);
        if interp.finished() {
            return out;
        }
    }
}

#[test]
fn a_start_before_the_queue_is_full_gives_the_setpoints_of_a_full_queue() {
    let cases: usize = env_number("KERF_EARLY_START_CASES").unwrap_or(120);
    let mut rng = Rng::seeded(31);
    let (mut early, mut compared, mut starved) = (0, 0, 0);
    for case in 0..cases {
        let limits = random_limits(&mut rng);
        let moves = random_program(&mut rng);
        let segs = plan(&moves, &limits);
        let capacity = [64, 256, 4096][rng.pick(3)];
        let slow = Slow {
            delay: rng.pick(2000) as u64,
            per_cycle: 1 + rng.pick(4),
            answer: Poll::Planning,
        };
        // An operator's feed override or hold and resume, early in the motion, in two
        // thirds of the cases.
        let at = rng.pick(3000);
        let events = match rng.pick(3) {
            0 => vec![(at, OperatorEvent::Override(rng.range(0.3, 2.0)))],
            1 => vec![
                (at, OperatorEvent::Hold),
                (at + 1 + rng.pick(1000), OperatorEvent::Resume),
            ],
            _ => vec![],
        };
        let full = run(&segs, limits.period_s, capacity, None, &events);
        assert!(
            !full.early,
            "case {case}: a source that never pends starts full"
        );
        let late = run(&segs, limits.period_s, capacity, Some(slow), &events);
        // A client that has not sent more (the planner idle) never starts it early.
        if case % 8 == 0 {
            let trickle = Slow {
                answer: Poll::Pending,
                ..slow
            };
            let r = run(&segs, limits.period_s, capacity, Some(trickle), &events);
            assert!(
                !r.early,
                "case {case}: started early while the source was idle"
            );
        }
        if !late.early {
            continue;
        }
        early += 1;
        if !late.kept_ahead {
            starved += 1;
            continue;
        }
        compared += 1;
        assert_eq!(
            late.positions.len(),
            full.positions.len(),
            "case {case}: {} segments, capacity {capacity}, slow {slow:?}, {events:?}: a different duration",
            segs.len()
        );
        if let Some(k) = (0..full.positions.len()).find(|&k| late.positions[k] != full.positions[k])
        {
            panic!(
                "case {case}: {} segments, capacity {capacity}, slow {slow:?}, {events:?}: setpoint {k} differs: {:?} against {:?}",
                segs.len(),
                late.positions[k],
                full.positions[k]
            );
        }
    }
    eprintln!("{cases} cases: {early} started early, {compared} compared, {starved} starved");
    assert!(
        early * 3 >= cases,
        "too few early starts: {early} of {cases}"
    );
    assert!(
        compared * 2 >= early,
        "too few runs kept ahead: {compared} of {early}"
    );
}
