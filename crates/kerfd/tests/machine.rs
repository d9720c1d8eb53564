//! The machine around the axes in the daemon's cycle, measured from what the cycle sends
//! out every period: the setpoint (its position and line) and the machine's output image
//! and spindle (`Cycle::machine`), cycle by cycle. The planning worker and the cycle run
//! in one thread here, as in `drives.rs`, so every test is deterministic.
//!
//! - an output synchronised with the motion (M62) switches in the cycle of the first
//!   setpoint of the next move, an immediate one (M64) before the motion gets there;
//! - a feed move never moves before the spindle is at speed, a rapid before it does;
//! - a pause (M0) holds the machine where it is, exactly as long as nobody presses cycle
//!   start, and the motion after it is the same whenever it is pressed;
//! - an M66 wait ends when the input comes on, or after its Q time with -1;
//! - single block pauses at the end of every block;
//! - the automatic tool changer's handshake, and a spindle that stalls while feeding is a
//!   fault that stops the program and switches the spindle off.

use std::sync::atomic::Ordering;

use kerf_config::Config;
use kerf_drive::machine::PauseReason;
use kerf_geom::machine::SpindleDir;
use kerf_proto::MachineState;
use kerfd::worker::{
    Cycle, CycleCommand, CycleOutput, Injection, Planning, PlanningCounters, Snapshot,
};

mod common;

/// The bundled machine (1 kHz; simulated spindle at 8000 rpm/s, 2 % band; automatic
/// changer answering in 2 s), with its own state file so that no other test's tool leaks
/// in.
fn config(extra: &str) -> Config {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/kerf.toml");
    // Not about homing: every axis counts as homed at start.
    let mut text =
        kerf_testkit::config_text::without_homing(&std::fs::read_to_string(root).unwrap());
    let state = std::env::temp_dir().join(format!(
        "kerfd-machine-test-{}-{}.state",
        std::process::id(),
        rand_tag()
    ));
    let _ = std::fs::remove_file(&state);
    text = text.replacen(
        "move_window = 4096",
        &format!("move_window = 4096\nstate_file = \"{}\"", state.display()),
        1,
    );
    text.push_str(extra);
    Config::from_toml_str(&text, "kerf.toml").expect("the test machine")
}

/// A tag unique to each call in this process.
fn rand_tag() -> u64 {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    NEXT.fetch_add(1, Ordering::Relaxed)
}

struct Machine {
    cycle: Cycle,
    planning: Planning,
    commands: rtrb::Producer<CycleCommand>,
    status: rtrb::Consumer<Snapshot>,
    config: Config,
    counters: PlanningCounters,
    last: Option<Snapshot>,
    /// Every cycle's output and the machine as it was sent out with it.
    log: Vec<Row>,
}

/// One cycle as the outside sees it.
#[derive(Clone, Copy, Debug)]
struct Row {
    out: CycleOutput,
    state: MachineState,
    outputs: u64,
    spindle_rpm: f64,
    at_speed: bool,
    pause: Option<PauseReason>,
}

impl Machine {
    fn new(config: Config) -> Machine {
        let w = common::wire(&config, 1 << 16);
        let mut m = Machine {
            cycle: w.cycle,
            planning: w.planning,
            commands: w.commands,
            status: w.status,
            config,
            counters: w.counters,
            last: None,
            log: Vec::new(),
        };
        for _ in 0..50 {
            m.run();
            if m.cycle.stage().ready() {
                m.log.clear();
                return m;
            }
        }
        panic!("the drives did not enable");
    }

    fn run(&mut self) -> Row {
        let out = self.cycle.run();
        while let Ok(s) = self.status.pop() {
            self.last = Some(s);
        }
        let status = self.cycle.machine().status();
        let spindle = status.spindle;
        let row = Row {
            out,
            state: self.last.map_or(MachineState::Idle, |s| s.state),
            outputs: status.io.digital_outputs,
            spindle_rpm: spindle.and_then(|s| s.actual_rpm).unwrap_or(0.0),
            at_speed: spindle.is_some_and(|s| s.at_speed),
            pause: status.pause.map(|p| p.reason),
        };
        self.log.push(row);
        row
    }

    fn command(&mut self, c: CycleCommand) {
        self.commands.push(c).expect("room for a command");
    }

    /// Plans `text` (LinuxCNC) from where the machine stands, as program `id`.
    fn send(&mut self, id: u64, text: &str) {
        let start = self
            .log
            .last()
            .map_or([0.0; 6], |r| r.out.setpoint.position);
        common::feed_program(&mut self.planning, &self.config, id, start, text);
    }

    /// Runs until program `id` is over; at a pause that waits for the operator, cycle
    /// start is pressed after `pause_cycles` cycles.
    fn finish(&mut self, id: u64, pause_cycles: u64) -> Snapshot {
        let mut paused_for = 0;
        for _ in 0..2_000_000 {
            self.run();
            let Some(s) = self.last else { continue };
            if s.program_id == id && s.program_done {
                return s;
            }
            if s.waits_for_operator() {
                paused_for += 1;
                if paused_for > pause_cycles {
                    paused_for = 0;
                    self.command(CycleCommand::Resume);
                }
            }
        }
        panic!("program {id} did not end");
    }
}

fn moving(a: &Row, b: &Row) -> bool {
    a.out.setpoint.position != b.out.setpoint.position
}

#[test]
fn an_output_with_the_motion_switches_with_the_next_moves_first_setpoint_and_an_immediate_one_before()
 {
    let mut m = Machine::new(config(""));
    m.send(
        1,
        "G21 G90 G64\nG1 X10 F3000\nM62 P2\nG1 X20\nM64 P3\nG1 X20 Y10\nM2\n",
    );
    m.finish(1, 0);
    let log = &m.log;
    let on = |bit: u32| {
        log.iter()
            .position(|r| r.outputs & (1 << bit) != 0)
            .expect("the output came on")
    };
    // M62 P2: with the first setpoint of line 4, and not one before.
    let k = on(2);
    assert_eq!(
        log[k].out.setpoint.line, 4,
        "the switching cycle is on line 4"
    );
    assert_ne!(log[k - 1].out.setpoint.line, 4, "the cycle before is not");
    // M64 P3: when the motion takes it, long before line 4's move ends and line 6 begins.
    let k3 = on(3);
    assert!(k3 < k, "M64 came on at cycle {k3}, after M62's {k}");
    assert!(log[k3].out.setpoint.position[0] < 10.0);
    // M2 leaves the outputs as they are (only the spindle and coolant go off).
    assert_eq!(log.last().unwrap().outputs & 0b1100, 0b1100);
}

#[test]
fn a_feed_move_waits_for_the_spindle_a_rapid_does_not() {
    let mut m = Machine::new(config(""));
    m.send(1, "G21 G90\nS12000 M3\nG0 X5\nG1 X15 F1200\nM5\nM2\n");
    m.finish(1, 0);
    let log = &m.log;
    let first_moving = |line: u32| {
        (1..log.len())
            .find(|&i| log[i].out.setpoint.line == line && moving(&log[i - 1], &log[i]))
            .expect("the line moved")
    };
    let rapid = first_moving(3);
    let feed = first_moving(4);
    // The rapid starts while the spindle still ramps up (12000 rpm at 8000 rpm/s: 1.5 s).
    assert!(!log[rapid].at_speed, "the rapid waited for the spindle");
    assert!(log[rapid].spindle_rpm < 12000.0 * 0.98);
    // The feed move's first moving setpoint has the spindle at speed, and every one after.
    for r in &log[feed..] {
        if r.out.setpoint.line == 4 && r.out.setpoint.feed_mm_s > 0.0 {
            assert!(r.at_speed, "a feed setpoint at {} rpm", r.spindle_rpm);
            assert!((r.spindle_rpm - 12000.0).abs() <= 12000.0 * 0.02);
        }
    }
    // It waited at rest, reporting what for, until then (not longer than the ramp needs
    // after the rapid: the band is reached at 98 % of 12000 rpm, 1.47 s from the start).
    let waited = &log[rapid..feed];
    assert!(waited.iter().any(|r| r.pause == Some(PauseReason::AtSpeed)));
    assert!(feed <= 1470 + 2, "the feed began at cycle {feed}");
    // M5 stops the spindle; M2 leaves it stopped.
    assert_eq!(
        m.cycle.machine().status().spindle.unwrap().dir,
        SpindleDir::Off
    );
}

#[test]
fn a_program_stop_holds_until_cycle_start_and_the_motion_after_it_does_not_change() {
    let program = "G21 G90 G64\nG1 X10 Y5 F3000\nM0\nG1 X20 Y0\nG2 X30 Y0 R5\nM2\n";
    let run = |wait: u64| {
        let mut m = Machine::new(config(""));
        m.send(1, program);
        let s = m.finish(1, wait);
        assert!(s.refusal.is_none() && !s.aborted);
        m.log
    };
    let quick = run(0);
    let slow = run(700);
    assert_eq!(slow.len(), quick.len() + 700);
    let paused: Vec<usize> = (0..slow.len())
        .filter(|&i| slow[i].state == MachineState::Paused)
        .collect();
    // Paused from rest at the end of line 2 until cycle start, and nowhere else.
    let (a, b) = (paused[0], *paused.last().unwrap());
    assert_eq!(b - a + 1, paused.len(), "one pause");
    assert!(paused.len() >= 700);
    for r in &slow[a..=b] {
        assert_eq!(r.out.setpoint.position, [10.0, 5.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(r.pause, Some(PauseReason::ProgramStop));
    }
    // Before and after the pause the positions are the quick run's, cycle for cycle.
    let pos = |l: &[Row]| {
        l.iter()
            .map(|r| r.out.setpoint.position)
            .collect::<Vec<_>>()
    };
    assert_eq!(pos(&slow[..a]), pos(&quick[..a]));
    assert_eq!(pos(&slow[a + 700..]), pos(&quick[a..]));
}

#[test]
fn an_input_wait_ends_when_the_input_comes_on_or_after_its_time_with_minus_one() {
    // Digital input 5: not simulated on at start.
    let extra = "";
    let mut m = Machine::new(config(extra));
    // Input 1 (door_closed) starts on: L4 waits for it to go off.
    m.send(1, "G21 G90\nG1 X5 F3000\nM66 P1 L4 Q10\nG1 X0\nM2\n");
    let mut waited = 0;
    for _ in 0..200_000 {
        let r = m.run();
        if r.pause
            .is_some_and(|p| matches!(p, PauseReason::WaitInput { input: 1, .. }))
        {
            waited += 1;
            if waited == 300 {
                m.command(CycleCommand::SetInput {
                    analog: false,
                    index: 1,
                    value: 0.0,
                });
            }
        }
        if m.last.is_some_and(|s| s.program_done) {
            break;
        }
    }
    // It waited until the input went off (two cycles: the command, then the wait sees
    // it), then went on.
    assert!((300..=302).contains(&waited), "waited {waited} cycles");
    let result = m.cycle.machine().status().last_input.expect("a result");
    assert_eq!((result.line, result.value), (3, 0.0));
    assert_eq!(m.last.unwrap().input_result_program, 1);
    // Input 0 (part_present) is on and stays on: L2 (a falling edge) times out after Q.
    let mut m = Machine::new(config(extra));
    m.send(2, "G21 G90\nM66 P0 L2 Q0.25\nM2\n");
    m.finish(2, 0);
    let waited = m
        .log
        .iter()
        .filter(|r| matches!(r.pause, Some(PauseReason::WaitInput { .. })))
        .count();
    assert!(
        (250..=251).contains(&waited),
        "waited {waited} cycles for 0.25 s"
    );
    let result = m.cycle.machine().status().last_input.expect("a result");
    assert_eq!(result.value, -1.0);
}

#[test]
fn single_block_pauses_at_the_end_of_every_block() {
    let mut m = Machine::new(config(""));
    m.counters.single_block.store(true, Ordering::Release);
    m.command(CycleCommand::Switch(kerf_proto::Switch::SingleBlock, true));
    m.send(1, "G21 G90 G64\nG1 X5 F3000\nG1 X5 Y5\nG1 X0 Y5\nM2\n");
    let s = m.finish(1, 10);
    assert!(s.refusal.is_none());
    let mut pauses = Vec::new();
    for (i, r) in m.log.iter().enumerate() {
        if r.pause == Some(PauseReason::SingleBlock)
            && m.log[i - 1].pause != Some(PauseReason::SingleBlock)
        {
            pauses.push(r.out.setpoint.position);
        }
    }
    // After the first line's modal codes nothing moves; then after each move's block.
    let ends: Vec<[f64; 6]> = pauses.iter().copied().filter(|p| *p != [0.0; 6]).collect();
    assert_eq!(
        ends,
        [
            [5.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            [5.0, 5.0, 0.0, 0.0, 0.0, 0.0],
            [0.0, 5.0, 0.0, 0.0, 0.0, 0.0]
        ]
    );
}

#[test]
fn the_automatic_changer_handshakes_and_the_tool_is_in_the_spindle() {
    let mut m = Machine::new(config(""));
    m.send(1, "G21 G90\nT1 M6\nM2\n");
    m.finish(1, 0);
    let status = m.cycle.machine().status();
    assert_eq!(status.tool_in_spindle, 1);
    // The request (output 4) was on for the simulated changer's 2 s, then off again.
    let on = m.log.iter().filter(|r| r.outputs & (1 << 4) != 0).count();
    assert!((2000..=2003).contains(&on), "request on for {on} cycles");
    assert_eq!(m.log.last().unwrap().outputs & (1 << 4), 0);
    assert_eq!(status.io.analog_outputs[1], 1.0, "the tool number output");
    // The tool already in the spindle: no handshake.
    m.log.clear();
    m.send(2, "G21 G90\nT1 M6\nM2\n");
    m.finish(2, 0);
    assert!(m.log.iter().all(|r| r.outputs & (1 << 4) == 0));
}

#[test]
fn a_spindle_that_stalls_while_feeding_stops_the_program_and_is_switched_off() {
    let mut m = Machine::new(config(""));
    m.send(1, "G21 G90\nS6000 M3\nG1 X50 F600\nM2\n");
    let mut stalled = false;
    for _ in 0..200_000 {
        let r = m.run();
        if !stalled && r.out.setpoint.line == 3 && r.out.setpoint.position[0] > 5.0 {
            m.command(CycleCommand::Inject(Injection::SpindleStall(true)));
            stalled = true;
        }
        if m.last.is_some_and(|s| s.program_done) {
            break;
        }
    }
    let s = m.last.unwrap();
    let fault = s.drives.fault.expect("a latched fault");
    assert_eq!(fault.check, kerf_drive::safety::Check::SpindleBand);
    assert_eq!(fault.line, 3);
    assert!(matches!(s.refusal, Some(kerfd::worker::Refusal::Safety(_))));
    // The axes stopped short of the end, the spindle command went to 0.
    assert!(m.log.last().unwrap().out.setpoint.position[0] < 50.0);
    let spindle = m.cycle.machine().status().spindle.unwrap();
    assert_eq!(spindle.commanded_rpm, 0.0);
}

/// The bundled part in each of the five dialects, with a program stop and an optional stop
/// written after its coolant line in the dialect's own form: every one pauses twice (the
/// optional-stop switch is on), changes to tool 1, never feeds before the spindle is at
/// 8000 rpm, cuts with flood coolant on, and ends with the spindle and coolant off.
#[test]
fn the_bundled_part_runs_with_its_stops_tool_spindle_and_coolant_in_every_dialect() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/examples");
    let mut ends = Vec::new();
    use kerf_gcode::Dialect as D;
    for (file, dialect) in [
        ("part.ngc", D::LinuxCnc),
        ("part.nc", D::Rockwell),
        ("part.mpf", D::Sinumerik),
        ("part.pim", D::Fagor),
        ("part.i", D::Heidenhain),
    ] {
        let path = std::path::Path::new(dir).join(file);
        let text = std::fs::read_to_string(&path).unwrap();
        // "N50 M8" becomes "N50 M8", "N50 M0", "N50 M1"; likewise "M8 *" and "M8".
        let coolant = text.lines().find(|l| l.contains("M8")).expect("an M8 line");
        let stops = format!(
            "{coolant}\n{}\n{}",
            coolant.replacen("M8", "M0", 1),
            coolant.replacen("M8", "M1", 1)
        );
        let text = text.replacen(coolant, &stops, 1);
        let mut m = Machine::new(config(""));
        let start = [0.0; 6];
        common::feed_program_in(&mut m.planning, &m.config, 1, start, &text, dialect);
        let s = m.finish(1, 20);
        assert!(s.refusal.is_none() && !s.aborted, "{file}: {:?}", s.refusal);
        let mut pauses = Vec::new();
        let mut before = None;
        for r in &m.log {
            if let Some(p @ (PauseReason::ProgramStop | PauseReason::OptionalStop)) = r.pause
                && before != r.pause
            {
                pauses.push(p);
            }
            before = r.pause;
        }
        assert_eq!(
            pauses,
            [PauseReason::ProgramStop, PauseReason::OptionalStop],
            "{file}"
        );
        let status = m.cycle.machine().status();
        assert_eq!(status.tool_in_spindle, 1, "{file}");
        // Every feed setpoint: spindle at speed at 8000 rpm, flood on (output 1).
        let mut fed = 0;
        for r in &m.log {
            if r.out.setpoint.feed_mm_s > 0.0 && !r.out.setpoint.rapid {
                fed += 1;
                assert!(r.at_speed, "{file}: feeding at {} rpm", r.spindle_rpm);
                assert!((r.spindle_rpm - 8000.0).abs() <= 160.0, "{file}");
                assert_ne!(r.outputs & 0b10, 0, "{file}: feeding without flood");
            }
        }
        assert!(fed > 1000, "{file}: {fed} feed cycles");
        // M30: spindle and coolant off.
        assert_eq!(status.spindle.unwrap().dir, SpindleDir::Off, "{file}");
        assert!(!status.coolant.flood, "{file}");
        ends.push(m.log.last().unwrap().out.setpoint.position);
    }
    // The same part: the same end in every dialect.
    assert!(ends.windows(2).all(|w| w[0] == w[1]), "{ends:?}");
}

/// A hold during a pause holds; one cycle start ends both; an override changed during the
/// pause applies to the motion after it.
#[test]
fn hold_and_override_during_a_pause_behave_as_an_operator_expects() {
    let mut m = Machine::new(config(""));
    m.send(1, "G21 G90\nG1 X5 F3000\nM0\nG1 X50 F3000\nM2\n");
    // Run into the pause.
    for _ in 0..100_000 {
        if m.run().pause == Some(PauseReason::ProgramStop) {
            break;
        }
    }
    m.command(CycleCommand::Hold);
    m.command(CycleCommand::Override(50.0));
    for _ in 0..50 {
        m.run();
    }
    assert_eq!(
        m.last.unwrap().state,
        MachineState::Holding,
        "held during the pause"
    );
    assert_eq!(m.log.last().unwrap().out.setpoint.position[0], 5.0);
    m.command(CycleCommand::Resume);
    let s = m.finish(1, u64::MAX);
    assert!(s.refusal.is_none() && !s.aborted);
    // After the pause the move ran at half its 50 mm/s: never faster than 25 mm/s, and
    // at 25 mm/s for most of it.
    let after: Vec<f64> = m
        .log
        .iter()
        .filter(|r| r.out.setpoint.line == 4)
        .map(|r| r.out.setpoint.feed_mm_s)
        .collect();
    let peak = after.iter().copied().fold(0.0, f64::max);
    assert!((peak - 25.0).abs() < 1e-6, "peak feed {peak} mm/s");
    assert_eq!(m.log.last().unwrap().out.setpoint.position[0], 50.0);
}
