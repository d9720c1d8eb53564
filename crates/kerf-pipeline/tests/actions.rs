//! The program's actions in the per-cycle step, measured from the setpoints: an output
//! synchronised with the motion switches in the cycle of the first setpoint of the next
//! move, an immediate one when the motion takes it, a pause holds the machine at rest for
//! exactly the cycles the machine makes it wait and nothing else changes, an abort during
//! a pause cancels it.
//!
//! The programs are planned here with the public pieces both planning threads use
//! (`Planner`, `plan_input`, `ActionOrder`), and run by a bare loop around the
//! `Interpolator` with a machine of the test's own that records in which cycle it was
//! handed what.

mod common;
use common::*;
use kerf_geom::machine::{Action, ActionKind, Gate, MachineIo, PauseCode, Sync};
use kerf_geom::{Move, Vec3};
use kerf_motion::{MachineLimits, MotionCore, Setpoint};
use kerf_pipeline::{ActionOrder, Input, Interpolator, OperatorEvent, Planned, Poll, plan_input};
use kerf_plan::Planner;

/// The planned items of `inputs`, in the order the daemon's planning thread sends them.
fn planned(inputs: &[Input], limits: &MachineLimits) -> Vec<Planned> {
    let mut planner = Planner::new(*limits);
    let mut order = ActionOrder::new();
    let mut buf = Vec::new();
    let mut out = Vec::new();
    let drain = |buf: &mut Vec<_>, order: &mut ActionOrder, out: &mut Vec<Planned>| {
        for s in buf.drain(..) {
            out.extend(order.before(&s));
            out.push(Planned::Segment(s, 0));
        }
    };
    for input in inputs {
        if order.take_held(input) {
            continue;
        }
        plan_input(&mut planner, input, &mut buf).unwrap();
        if let Input::Move(_) = input {
            order.moved();
        }
        drain(&mut buf, &mut order, &mut out);
        order.after(input, &mut out);
    }
    planner.finish(&mut buf);
    drain(&mut buf, &mut order, &mut out);
    out.extend(order.release());
    out
}

/// A machine that records the cycle of every action it is handed and keeps each pause
/// waiting for `pause_cycles` cycles.
struct Recorder {
    cycle: u64,
    pause_cycles: u64,
    waited: u64,
    handed: Vec<(u64, Action)>,
    cancelled: Vec<Action>,
}

impl Recorder {
    fn new(pause_cycles: u64) -> Self {
        Recorder {
            cycle: 0,
            pause_cycles,
            waited: 0,
            handed: Vec::new(),
            cancelled: Vec::new(),
        }
    }
}

impl MachineIo for Recorder {
    fn act(&mut self, action: &Action) -> Gate {
        self.handed.push((self.cycle, *action));
        if let ActionKind::Pause(_) = action.kind {
            if self.waited < self.pause_cycles {
                self.waited += 1;
                return Gate::Wait;
            }
            self.waited = 0;
        }
        Gate::Done
    }

    fn cancel(&mut self, action: &Action) {
        self.cancelled.push(*action);
    }
}

/// Runs `items` to the end; the setpoints from cycle 1 on (index 0 is cycle 1). `events`
/// are applied before the step of their cycle.
fn run(
    items: Vec<Planned>,
    limits: &MachineLimits,
    machine: &mut Recorder,
    events: &[(u64, OperatorEvent)],
) -> Vec<Setpoint> {
    let mut items = items.into_iter();
    let mut interp = Interpolator::new(MotionCore::new(limits.period_s, 64));
    let mut out = Vec::new();
    while !interp.finished() {
        machine.cycle += 1;
        assert!(machine.cycle < 1_000_000, "the run does not end");
        interp
            .feed(
                || match items.next() {
                    Some(p) => Poll::Ready(p),
                    None => Poll::End,
                },
                machine,
            )
            .unwrap();
        for (_, e) in events.iter().filter(|(c, _)| *c == machine.cycle) {
            interp.apply(*e);
        }
        let mut sp = Setpoint::default();
        interp.step(&mut sp);
        interp.fire_synced(machine);
        out.push(sp);
    }
    out
}

fn action(line: u32, kind: ActionKind) -> Input {
    Input::Action(Action { line, kind })
}

fn digital(line: u32, sync: Sync) -> Input {
    action(
        line,
        ActionKind::Digital {
            output: 1,
            on: true,
            sync,
        },
    )
}

/// Three blended feed moves along X, then up Y: lines 1, 3 and 4.
fn moves() -> [Move; 3] {
    let a = Vec3::zeros();
    let b = Vec3::new(10.0, 0.0, 0.0);
    let c = Vec3::new(20.0, 0.0, 0.0);
    let d = Vec3::new(20.0, 10.0, 0.0);
    [
        line(1, a, b, 3000.0),
        line(3, b, c, 3000.0),
        line(4, c, d, 3000.0),
    ]
}

#[test]
fn an_output_with_the_motion_switches_with_the_first_setpoint_of_the_next_move() {
    let limits = mill(100.0, 1000.0, 20_000.0, 0.01);
    let [m1, m3, m4] = moves();
    let inputs = [
        Input::Move(m1),
        digital(2, Sync::WithMotion),
        Input::Move(m3),
        Input::Move(m4),
    ];
    let mut machine = Recorder::new(0);
    let sp = run(planned(&inputs, &limits), &limits, &mut machine, &[]);
    let fired: Vec<u64> = machine
        .handed
        .iter()
        .filter(|(_, a)| matches!(a.kind, ActionKind::Digital { .. }))
        .map(|(c, _)| *c)
        .collect();
    assert_eq!(fired.len(), 1, "handed once: {:?}", machine.handed);
    let k = fired[0] as usize;
    // The move of line 1 and its blend end before x = 10; the cycle the output switches
    // in is the first whose setpoint is past them, on line 3, and the one before is not.
    assert_eq!(
        sp[k - 1].line,
        3,
        "the switching cycle's setpoint is on the next move"
    );
    assert_ne!(
        sp[k - 2].line,
        3,
        "the cycle before is still on the first move"
    );
    assert!(
        sp[k - 1].position[0] > 10.0 - limits.tolerance_mm,
        "x {}",
        sp[k - 1].position[0]
    );
    // Nothing stopped: the speed never drops to zero between the moves.
    let moving = sp[..k + 5].iter().skip(5).all(|s| s.feed_mm_s > 0.0);
    assert!(moving, "the output does not stop the motion");
}

#[test]
fn an_immediate_output_switches_when_the_motion_takes_it_ahead_of_the_moves_before() {
    let limits = mill(100.0, 1000.0, 20_000.0, 0.01);
    let [m1, m3, m4] = moves();
    let inputs = [
        Input::Move(m1),
        Input::Move(m3),
        digital(3, Sync::Immediate),
        Input::Move(m4),
    ];
    let mut machine = Recorder::new(0);
    let sp = run(planned(&inputs, &limits), &limits, &mut machine, &[]);
    let (cycle, _) = machine.handed[0];
    // The queue holds the whole program at once: the output is taken in the first cycle,
    // while the first move has not even started.
    assert_eq!(cycle, 1);
    assert!(sp[0].position[0] < 1.0);
}

#[test]
fn a_pause_rests_exactly_the_cycles_it_waits_and_changes_nothing_else() {
    let limits = mill(100.0, 1000.0, 20_000.0, 0.01);
    let [m1, m3, m4] = moves();
    let stop = action(2, ActionKind::Pause(PauseCode::ProgramStop));
    let inputs = [Input::Move(m1), stop, Input::Move(m3), Input::Move(m4)];
    let items = planned(&inputs, &limits);
    let mut instant = Recorder::new(0);
    let base = run(items.clone(), &limits, &mut instant, &[]);
    let wait = 250;
    let mut paused = Recorder::new(wait);
    let sp = run(items, &limits, &mut paused, &[]);
    assert_eq!(sp.len(), base.len() + wait as usize);
    // The pause begins where the motion came to rest at the end of line 1.
    let first = paused.handed[0].0 as usize;
    let rest = &sp[first - 1..first - 1 + wait as usize];
    assert!(
        rest.iter()
            .all(|s| s.position == [10.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    );
    assert!(rest.iter().all(|s| s.feed_mm_s == 0.0));
    // Before and after it, the setpoints are the run without a wait's, bit for bit.
    assert_eq!(sp[..first - 1], base[..first - 1]);
    assert_eq!(sp[first - 1 + wait as usize..], base[first - 1..]);
    // Asked once per cycle while it waited, and once more when it was done.
    assert_eq!(paused.handed.len() as u64, wait + 1);
}

#[test]
fn an_abort_during_a_pause_cancels_it_and_ends_the_program_at_rest() {
    let limits = mill(100.0, 1000.0, 20_000.0, 0.01);
    let [m1, m3, m4] = moves();
    let stop = action(2, ActionKind::Pause(PauseCode::ProgramStop));
    let inputs = [Input::Move(m1), stop, Input::Move(m3), Input::Move(m4)];
    let items = planned(&inputs, &limits);
    let mut probe = Recorder::new(u64::MAX);
    // Find the pause's first cycle, then abort well inside it.
    let mut instant = Recorder::new(0);
    run(items.clone(), &limits, &mut instant, &[]);
    let pause_at = instant.handed[0].0;
    let sp = run(
        items,
        &limits,
        &mut probe,
        &[(pause_at + 100, OperatorEvent::Abort)],
    );
    assert_eq!(probe.cancelled.len(), 1);
    assert!(matches!(probe.cancelled[0].kind, ActionKind::Pause(_)));
    let last = sp.last().unwrap();
    assert_eq!(last.position, [10.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    // The abort's cycle steps at rest; the next drops the pause and ends the program.
    assert_eq!(sp.len() as u64, pause_at + 101);
}

#[test]
fn outputs_synchronised_with_moves_that_never_start_are_dropped_by_an_abort() {
    let limits = mill(100.0, 1000.0, 20_000.0, 0.01);
    let [m1, m3, m4] = moves();
    let inputs = [
        Input::Move(m1),
        Input::Move(m3),
        digital(4, Sync::WithMotion),
        Input::Move(m4),
    ];
    let mut machine = Recorder::new(0);
    // An abort in the first move's fifth cycle: the motion stops on line 1 or 3.
    run(
        planned(&inputs, &limits),
        &limits,
        &mut machine,
        &[(5, OperatorEvent::Abort)],
    );
    assert!(machine.handed.is_empty(), "{:?}", machine.handed);
}
