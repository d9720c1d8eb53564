//! The real-time cycle allocates nothing: a counting global allocator counts every
//! allocation made on the cycle's thread while it runs `Cycle::run()` and publishes the
//! setpoint over iceoryx2 the way the daemon does (iceoryx2's `send_copy` allocates, so
//! the cycle hands the setpoint to the publisher thread of `kerfd::publish`
//! through a preallocated ring), for every cycle of whole programs: the example
//! part (with a hold and resume and two override changes), a dense polyline (aborted in
//! the middle), a dense polyline stopped by a drive fault injected in the middle (the
//! safety layer's quick stop, the black box copied out for the fault and on request, a
//! reset refused while the fault's cause persists, one accepted once it is gone, an
//! injected stall of the setpoint stream and its reset), and a last program after all
//! that, with a setpoint reader connecting in the middle of a program (as `kerf record`
//! does). The drive stage (simulated drives, safety layer, black box) runs in every cycle.
//! A second test runs the cycle through homing, jogs (the dead man's switch included), a
//! hard limit switch's fault, its reset and the jog off it.
//!
//! Only the cycle's thread counts (a thread-local flag), so the planning worker, which
//! allocates freely on its own thread, does not disturb the count.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;

mod common;

use kerf_config::Config;
use kerf_drive::safety::{Check, ResetRefused};
use kerf_drive::stage::DumpReason;
use kerf_proto::{MachineState, SetpointMsg};
use kerfd::worker::{
    Cycle, CycleCommand, DumpWriterRings, Injection, Planning, PlanningCounters, Refusal, Snapshot,
};

use kerf_testkit::alloc::{CountingAllocator, NOT_COUNTING, allocations, frees, set_phase};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// The phase of the thread that runs the cycle: `Cycle::run()`.
const PHASE_RUN: u8 = 1;
/// The phase of the thread that publishes (`SetpointOut::push`).
const PHASE_SEND: u8 = 2;

/// The example part shipped with Kerf.
fn part_program() -> String {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../config/examples/part.ngc"
    );
    std::fs::read_to_string(path).expect("config/examples/part.ngc is readable")
}

/// A dense CAM-style polyline: `n` chords of 0.1 to 0.2 mm along a spiral, from where the
/// machine is (`start`), at F3000 with a 0.01 mm tolerance (blended and smoothed).
fn dense_program(n: usize, start: [f64; 6]) -> String {
    let mut text = String::from("G21 G90 G17 G94 G64 P0.01 F3000\n");
    let (x0, y0) = (start[0], start[1]);
    for k in 1..=n {
        let a = k as f64 * 0.02;
        let r = 2.0 + 0.01 * k as f64 * 0.3;
        let x = x0 + r * a.cos() - 2.0;
        let y = y0 + r * a.sin();
        text += &format!("G1 X{x:.4} Y{y:.4}\n");
    }
    text += "M2\n";
    text
}

/// Feeds one program to the planning worker (see [`common::feed_program`]).
fn feed(planning: &mut Planning, config: &Config, id: u64, start: [f64; 6], text: &str) {
    common::feed_program(planning, config, id, start, text);
}

/// What the test does to the cycle while a program runs.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Script {
    /// Hold at program cycle 3000, resume after 300 cycles of holding; override 150 % at
    /// cycle 8000, 0 % at 9000, 60 % 300 cycles later.
    HoldResumeOverride,
    /// Abort at program cycle 3000.
    Abort,
    /// Nothing: run to the end; a setpoint reader connects at program cycle 1000.
    Plain,
    /// A lasting fault of the Y drive at program cycle 2000.
    DriveFault,
}

/// One counted cycle: `Cycle::run()` and the publish, then (not counted) the wait for the
/// setpoint at the reader.
fn counted_cycle(
    cycle: &mut Cycle,
    publisher: &mut kerfd::publish::SetpointOut,
    msg: &mut SetpointMsg,
    reader: &iceoryx2::port::subscriber::Subscriber<kerfd::ipc::Ipc, SetpointMsg, ()>,
    last_seq: &mut u64,
    received: &mut u64,
) -> kerfd::worker::CycleOutput {
    set_phase(PHASE_RUN);
    let out = cycle.run();
    set_phase(NOT_COUNTING);
    out.fill(msg, out.seq * 1_000_000);
    set_phase(PHASE_SEND);
    assert!(publisher.push(*msg), "the ring to the publisher has room");
    set_phase(NOT_COUNTING);
    // The cycle runs unclocked here, so it waits for each setpoint to arrive.
    let mut spins = 0u64;
    while *last_seq < out.seq {
        match reader.receive() {
            Ok(Some(sample)) => {
                assert_eq!(sample.seq, *last_seq + 1, "the reader missed a setpoint");
                *last_seq = sample.seq;
                *received += 1;
            }
            _ => {
                spins += 1;
                assert!(spins < 50_000_000, "setpoint {} never arrived", out.seq);
                std::thread::yield_now();
            }
        }
    }
    out
}

/// Takes the dumps out of the ring (their reasons) and gives their rings back, as the
/// control thread does.
fn take_dumps(rings: &mut DumpWriterRings, reasons: &mut Vec<DumpReason>, rows: &mut Vec<usize>) {
    while let Ok(d) = rings.dumps.pop() {
        reasons.push(d.reason);
        rows.push(d.recorder.len());
        rings.spares.push(d.recorder).expect("room for the ring");
    }
}

#[test]
fn the_cycle_and_its_publish_allocate_nothing_over_whole_programs() {
    let mut config = Config::from_toml_str(
        &kerf_testkit::config_text::without_homing(kerf_config::BUILTIN_TOML),
        "kerf.toml",
    )
    .expect("the bundled machine without homing");
    config.machine = format!("alloc_{}", std::process::id());
    let (items_tx, items_rx) = rtrb::RingBuffer::new(kerfd::PLANNED_RING);
    let (mut commands_tx, commands_rx) = rtrb::RingBuffer::<CycleCommand>::new(64);
    let (status_tx, mut status_rx) = rtrb::RingBuffer::<Snapshot>::new(256);
    let stop = Arc::new(AtomicBool::new(false));

    // The planning worker on its own thread; the test tells it where each program
    // starts (the machine position when the previous one ended).
    let (start_tx, start_rx) = mpsc::channel::<(u64, [f64; 6], String)>();
    let planning_thread = {
        let config = config.clone();
        let stop = stop.clone();
        std::thread::spawn(move || {
            let counters = PlanningCounters::default();
            let mut planning = Planning::new(&config, items_tx, stop, &counters);
            while let Ok((id, start, text)) = start_rx.recv() {
                feed(&mut planning, &config, id, start, &text);
            }
        })
    };

    let (mut publisher, helper) =
        kerfd::publish::spawn(&config.machine, None).expect("publisher thread");
    let node = kerfd::ipc::node(&format!("alloc-test-{}", std::process::id())).expect("node");
    let service = kerfd::ipc::open_setpoints(&node, &config.machine).expect("service");
    let early_reader = kerfd::ipc::setpoint_subscriber(&service).expect("subscriber");
    let mut late_reader = None;

    let (dump_rings, mut dump_writer) = kerfd::worker::dump_rings();
    let mut cycle = Cycle::new(
        &config,
        [0.0; 6],
        items_rx,
        commands_rx,
        status_tx,
        dump_rings,
    )
    .expect("the built-in machine's cycle");
    let mut msg = SetpointMsg::new();
    let mut cycles = 0u64;
    let mut received = 0u64;
    let mut last_seq = 0u64;
    let mut position = [0.0; 6];
    let mut max_override_seen = 0.0f64;
    let mut held_cycles = 0u64;

    let programs = [
        (1u64, Script::HoldResumeOverride),
        (2, Script::Abort),
        (3, Script::DriveFault),
        (4, Script::Plain),
    ];
    let mut dump_reasons = Vec::new();
    let mut dump_rows = Vec::new();
    for (id, script) in programs {
        let text = match script {
            Script::HoldResumeOverride => part_program(),
            Script::Abort | Script::DriveFault => dense_program(6000, position),
            Script::Plain => dense_program(3000, position),
        };
        start_tx
            .send((id, position, text))
            .expect("planning thread");
        let mut done: Option<Snapshot> = None;
        let mut holding_for = 0u64;
        let mut sent_hold = false;
        let mut sent_resume = false;
        let mut overrides = 0;
        let mut zero_from = 0u64;
        let mut last_program_cycle = 0u64;
        let mut guard = 0u64;
        while done.is_none() {
            guard += 1;
            assert!(guard < 2_000_000, "program {id} did not finish");
            let out = counted_cycle(
                &mut cycle,
                &mut publisher,
                &mut msg,
                &early_reader,
                &mut last_seq,
                &mut received,
            );
            cycles += 1;
            if let Some(r) = late_reader.as_ref() {
                let r: &iceoryx2::port::subscriber::Subscriber<_, SetpointMsg, ()> = r;
                while let Ok(Some(_)) = r.receive() {}
            }
            while let Ok(s) = status_rx.pop() {
                max_override_seen = max_override_seen.max(s.override_pct);
                if s.state == MachineState::Holding {
                    holding_for += 1;
                    held_cycles += 1;
                }
                if s.program_id == id && s.program_done {
                    done = Some(s);
                }
            }
            if out.program_id == id {
                last_program_cycle = out.program_cycle;
            }
            match script {
                Script::HoldResumeOverride => {
                    if !sent_hold && last_program_cycle >= 3000 {
                        commands_tx.push(CycleCommand::Hold).expect("command ring");
                        sent_hold = true;
                    }
                    if sent_hold && !sent_resume && holding_for >= 300 {
                        commands_tx
                            .push(CycleCommand::Resume)
                            .expect("command ring");
                        sent_resume = true;
                    }
                    if overrides == 0 && last_program_cycle >= 8000 {
                        commands_tx
                            .push(CycleCommand::Override(150.0))
                            .expect("command ring");
                        overrides = 1;
                    }
                    // 0 % (the core holds on the path: its own branch of the cycle),
                    // then 60 % after 300 cycles at rest.
                    if overrides == 1 && last_program_cycle >= 9000 {
                        commands_tx
                            .push(CycleCommand::Override(0.0))
                            .expect("command ring");
                        zero_from = last_program_cycle;
                        overrides = 2;
                    }
                    if overrides == 2 && last_program_cycle >= zero_from + 300 {
                        commands_tx
                            .push(CycleCommand::Override(60.0))
                            .expect("command ring");
                        overrides = 3;
                    }
                }
                Script::Abort => {
                    if !sent_hold && last_program_cycle >= 3000 {
                        commands_tx.push(CycleCommand::Abort).expect("command ring");
                        sent_hold = true;
                    }
                }
                Script::DriveFault => {
                    if !sent_hold && last_program_cycle >= 2000 {
                        commands_tx
                            .push(CycleCommand::Inject(Injection::DriveFault(1)))
                            .expect("command ring");
                        sent_hold = true;
                    }
                }
                Script::Plain => {
                    if late_reader.is_none() && last_program_cycle >= 1000 {
                        late_reader =
                            Some(kerfd::ipc::setpoint_subscriber(&service).expect("subscriber"));
                    }
                }
            }
        }
        let end = done.expect("finished");
        position = end.position;
        match script {
            Script::HoldResumeOverride => {
                assert!(sent_resume && overrides == 3, "the script ran");
                assert!(!end.aborted && end.refusal.is_none());
            }
            Script::Abort => assert!(end.aborted, "program 2 was aborted"),
            Script::DriveFault => {
                match end.refusal {
                    Some(Refusal::Safety(f)) => {
                        assert_eq!((f.check, f.axis), (Check::DriveFault, Some(1)));
                    }
                    other => panic!("program 3 ended with {other:?}"),
                }
                // After the quick stop: a dump, a reset refused while the drive's fault
                // persists, the cause removed, a reset accepted, an injected stall of the
                // stream at rest (it trips), a reset refused while it lasts and one
                // accepted after it.
                let script: [(u64, CycleCommand); 7] = [
                    (0, CycleCommand::Dump(7)),
                    (1, CycleCommand::Reset(8)),
                    (2, CycleCommand::Inject(Injection::ClearDriveFault(1))),
                    (3, CycleCommand::Reset(9)),
                    (4, CycleCommand::Inject(Injection::Stall(10))),
                    (5, CycleCommand::Reset(10)),
                    (6, CycleCommand::Reset(11)),
                ];
                let mut since_stall_reset = 0;
                let mut next = 0;
                let mut outcomes = Vec::new();
                let mut latest = end;
                let mut guard = 0;
                while next < script.len() || latest.reset.map(|r| r.0) != Some(11) {
                    guard += 1;
                    assert!(
                        guard < 100_000,
                        "the reset script did not finish: {outcomes:?}"
                    );
                    counted_cycle(
                        &mut cycle,
                        &mut publisher,
                        &mut msg,
                        &early_reader,
                        &mut last_seq,
                        &mut received,
                    );
                    cycles += 1;
                    take_dumps(&mut dump_writer, &mut dump_reasons, &mut dump_rows);
                    while let Ok(s) = status_rx.pop() {
                        if s.reset != latest.reset
                            && let Some(r) = s.reset
                        {
                            outcomes.push(r);
                        }
                        latest = s;
                    }
                    // Each step waits for the previous one's effect.
                    let ready = match next {
                        0 => latest.drives.state == kerf_drive::safety::SafetyState::Stopped,
                        1 => !dump_reasons.is_empty(),
                        2 => latest.reset.map(|r| r.0) == Some(8),
                        3 => true,
                        4 => latest.reset.map(|r| r.0) == Some(9),
                        5 => latest.drives.fault.is_some(),
                        6 => {
                            since_stall_reset += 1;
                            latest.reset.map(|r| r.0) == Some(10) && since_stall_reset > 20
                        }
                        _ => false,
                    };
                    if next < script.len() && ready {
                        commands_tx.push(script[next].1).expect("command ring");
                        next += 1;
                    }
                }
                assert_eq!(
                    outcomes,
                    vec![
                        (8, Err(ResetRefused::DriveFault(1))),
                        (9, Ok(())),
                        (10, Err(ResetRefused::StreamMissing)),
                        (11, Ok(()))
                    ]
                );
                // Wait for the dump asked for, then the next program starts where the
                // quick stop left the machine.
                while dump_reasons.len() < 2 {
                    counted_cycle(
                        &mut cycle,
                        &mut publisher,
                        &mut msg,
                        &early_reader,
                        &mut last_seq,
                        &mut received,
                    );
                    cycles += 1;
                    take_dumps(&mut dump_writer, &mut dump_reasons, &mut dump_rows);
                    while let Ok(s) = status_rx.pop() {
                        latest = s;
                    }
                }
                assert!(latest.drives.fault.is_none(), "the reset cleared the fault");
                position = latest.position;
            }
            Script::Plain => {
                assert!(!end.aborted && end.refusal.is_none());
                assert!(late_reader.is_some());
            }
        }
        // The program moved and finished at rest.
        let least = if matches!(script, Script::DriveFault) {
            2000
        } else {
            3000
        };
        assert!(
            last_program_cycle >= least,
            "program {id} ran {last_program_cycle} cycles"
        );
    }
    drop(start_tx);
    stop.store(true, Ordering::Release);
    planning_thread.join().expect("planning thread");

    assert!(held_cycles >= 300, "the hold took effect");
    // The fault's dump (taken once the quick stop was at rest), the one asked for, and
    // the stall's; each a full ring of the default 10 s.
    assert!(matches!(dump_reasons[0], DumpReason::Fault(f) if f.check == Check::DriveFault));
    assert!(dump_reasons.contains(&DumpReason::Request(7)));
    assert!(
        dump_rows.iter().all(|&n| n == config.recorder_capacity()),
        "{dump_rows:?}"
    );
    assert!(max_override_seen >= 149.0, "the override took effect");
    assert_eq!(received, cycles, "every setpoint was delivered");
    assert_eq!(publisher.dropped(), 0);
    let added = helper.finish().expect("the publisher thread ends");
    assert_eq!(
        added.count(),
        cycles,
        "the publisher thread published every setpoint"
    );
    let in_run = allocations(PHASE_RUN);
    let in_send = allocations(PHASE_SEND);
    let frees = frees(PHASE_RUN) + frees(PHASE_SEND);
    assert_eq!(
        (in_run, in_send, frees),
        (0, 0, 0),
        "allocations in Cycle::run, allocations in send_copy, frees, over {cycles} cycles"
    );
}

/// The phase of the thread that runs the cycle while the machine homes and jogs.
const PHASE_MANUAL: u8 = 3;

/// Homing (Z first, then X and Y together, on the bundled machine's simulated switches),
/// continuous jogs renewed and left to the dead man's switch, a step and a jog to a point,
/// a jog stopped by hand, a jog into a hard limit switch (moved inside the travel here),
/// its fault, the reset and the jog off the switch: no cycle allocates.
#[test]
fn the_cycle_allocates_nothing_while_the_machine_homes_and_jogs() {
    let text =
        kerf_config::BUILTIN_TOML.replacen("max_limit_mm = 505.0", "max_limit_mm = 300.0", 1);
    assert_ne!(
        text,
        kerf_config::BUILTIN_TOML,
        "Z's simulated upper limit switch moved"
    );
    let mut config = Config::from_toml_str(&text, "kerf.toml").expect("the bundled machine");
    config.machine = format!("alloc_manual_{}", std::process::id());
    let (_items_tx, items_rx) = rtrb::RingBuffer::new(16);
    let (mut commands, commands_rx) = rtrb::RingBuffer::<CycleCommand>::new(64);
    let (status_tx, mut status_rx) = rtrb::RingBuffer::<Snapshot>::new(1 << 16);
    let (dump_rings, _dump_writer) = kerfd::worker::dump_rings();
    let mut cycle = Cycle::new(
        &config,
        [0.0; 6],
        items_rx,
        commands_rx,
        status_tx,
        dump_rings,
    )
    .expect("the built-in machine's cycle");
    let mut last: Option<Snapshot> = None;
    let mut run = |cycle: &mut Cycle, n: usize, last: &mut Option<Snapshot>| {
        for _ in 0..n {
            set_phase(PHASE_MANUAL);
            let _ = cycle.run();
            set_phase(NOT_COUNTING);
            while let Ok(s) = status_rx.pop() {
                *last = Some(s);
            }
        }
    };
    run(&mut cycle, 200, &mut last);
    assert!(cycle.stage().ready(), "the drives enabled");
    commands.push(CycleCommand::Home(0b111)).unwrap();
    for _ in 0..200 {
        run(&mut cycle, 100, &mut last);
        if last.is_some_and(|s| s.manual.homed == 0b111 && s.manual.homing == 0) {
            break;
        }
    }
    let s = last.expect("a snapshot");
    assert_eq!(s.manual.homed, 0b111, "homed: {:?}", s.manual);
    use kerf_proto::Jog;
    let jog = |axis, jog, speed| CycleCommand::Jog { axis, jog, speed };
    // Continuous X+ renewed for a while, then silence: the dead man's switch stops it.
    for _ in 0..20 {
        commands.push(jog(0, Jog::Continuous(true), 50.0)).unwrap();
        run(&mut cycle, 30, &mut last);
    }
    run(&mut cycle, 1500, &mut last);
    // A step, a jog to a point, one stopped by hand.
    commands.push(jog(1, Jog::Step(-2.5), 20.0)).unwrap();
    run(&mut cycle, 1500, &mut last);
    commands.push(jog(2, Jog::To(-30.0), 0.0)).unwrap();
    run(&mut cycle, 3000, &mut last);
    commands
        .push(jog(1, Jog::Continuous(false), 100.0))
        .unwrap();
    run(&mut cycle, 50, &mut last);
    commands.push(CycleCommand::JogStop(1)).unwrap();
    run(&mut cycle, 1000, &mut last);
    // Z up into its limit switch at 300: the fault and the quick stop; the reset; the jog
    // off the switch.
    for _ in 0..150 {
        commands.push(jog(2, Jog::Continuous(true), 100.0)).unwrap();
        run(&mut cycle, 50, &mut last);
        if last.is_some_and(|s| s.drives.fault.is_some()) {
            break;
        }
    }
    let s = last.expect("a snapshot");
    assert_eq!(s.drives.fault.map(|f| f.check), Some(Check::HardLimit));
    run(&mut cycle, 1000, &mut last);
    commands.push(CycleCommand::Reset(7)).unwrap();
    run(&mut cycle, 200, &mut last);
    let s = last.expect("a snapshot");
    assert!(
        s.reset.is_some_and(|r| r.0 == 7 && r.1.is_ok()),
        "{:?}",
        s.reset
    );
    commands.push(jog(2, Jog::Step(-10.0), 20.0)).unwrap();
    run(&mut cycle, 2000, &mut last);
    let s = last.expect("a snapshot");
    assert!(s.drives.fault.is_none(), "{:?}", s.drives.fault);
    assert_eq!(s.manual.limit_released, 0, "off the switch");
    assert_eq!(
        allocations(PHASE_MANUAL),
        0,
        "the cycle allocated while homing and jogging"
    );
    assert_eq!(frees(PHASE_MANUAL), 0);
}
