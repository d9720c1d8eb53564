//! The daemon's real-time cycle with its drive side (simulated CiA 402 drives, the safety
//! layer, the black box), run deterministically without a clock or shared memory: the
//! planning worker and `Cycle::run()` exchange items through their rings, one call per
//! period.
//!
//! Measured from what the drives were sent and what they report (the positions of each
//! cycle and the black box's actual positions), never from the stage's own verdicts:
//! - real programs at full feed on well-tuned drives, over a sweep of machines (limits,
//!   drive bandwidth, scale and direction): the following error stays within LinuxCNC's
//!   limit max(MIN_FERROR, FERROR·|v|/v_max) computed here from the commands, and nothing
//!   trips;
//! - a badly tuned drive trips the following-error check in the middle of the example
//!   part: the program ends there, refused; the axes come to rest; the next program is
//!   refused without moving until a reset; after the reset it runs from where the
//!   axes stopped.

mod common;

use kerf_config::Config;
use kerf_drive::safety::Check;
use kerfd::worker::{Cycle, CycleCommand, CycleOutput, Planning, Refusal, Snapshot};

/// The programs: the bundled examples and the LinuxCNC test programs.
fn programs() -> Vec<(String, String)> {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    let mut out = Vec::new();
    for dir in ["config/examples", "tests/data/programs/linuxcnc"] {
        let mut names: Vec<_> = std::fs::read_dir(format!("{root}/{dir}"))
            .expect("the program directory")
            .map(|e| e.expect("entry").path())
            .filter(|p| p.extension().is_some_and(|e| e == "ngc"))
            .collect();
        names.sort();
        for p in names {
            let text = std::fs::read_to_string(&p).expect("readable");
            out.push((p.display().to_string(), text));
        }
    }
    assert!(out.len() >= 4, "{out:?}");
    out
}

struct Machine {
    cycle: Cycle,
    planning: Planning,
    commands: rtrb::Producer<CycleCommand>,
    status: rtrb::Consumer<Snapshot>,
    config: Config,
    last: Option<Snapshot>,
    next_id: u64,
}

impl Machine {
    fn new(config: Config) -> Machine {
        // A ring large enough for a whole program, so that one thread can plan it all
        // before the cycle runs.
        let w = common::wire(&config, 1 << 20);
        Machine {
            cycle: w.cycle,
            planning: w.planning,
            commands: w.commands,
            status: w.status,
            config,
            last: None,
            next_id: 1,
        }
    }

    /// One cycle; at a pause that waits for the operator (a program stop, a manual tool
    /// change), cycle start is pressed at once, as `kerf sim` assumes.
    fn run(&mut self) -> CycleOutput {
        let out = self.cycle.run();
        while let Ok(s) = self.status.pop() {
            self.last = Some(s);
        }
        if self.last.is_some_and(|s| s.waits_for_operator()) {
            let _ = self.commands.push(CycleCommand::Resume);
        }
        out
    }

    /// Runs until the drives are enabled; the machine's position.
    fn enable(&mut self) -> [f64; 6] {
        for _ in 0..50 {
            let out = self.run();
            if self.cycle.stage().ready() {
                return out.setpoint.position;
            }
        }
        panic!("the drives did not enable");
    }

    /// Plans `text` from `start` into the ring, as the daemon's planning thread does.
    fn send(&mut self, text: &str, start: [f64; 6]) -> u64 {
        let id = self.next_id;
        self.next_id += 1;
        common::feed_program(&mut self.planning, &self.config, id, start, text);
        id
    }

    /// Runs program `id` to its end: the positions sent each cycle and the actual
    /// positions the drives reported (from the black box's newest record), per cycle.
    fn run_program(&mut self, id: u64) -> (Vec<[f64; 6]>, Vec<[f64; 6]>, Snapshot) {
        let (mut sent, mut actual) = (Vec::new(), Vec::new());
        for _ in 0..5_000_000 {
            let out = self.run();
            sent.push(out.setpoint.position);
            let rec = self.cycle.stage().recorder().iter().last().copied();
            actual.push(rec.expect("recorded").actual);
            if let Some(s) = self.last
                && s.program_id == id
                && s.program_done
            {
                return (sent, actual, s);
            }
        }
        panic!("program {id} did not end");
    }
}

/// The largest ratio, over every cycle and axis, of |command of the cycle before −
/// actual| to max(min_ferror, ferror·|v|/v_max), v the step of that command.
fn worst_ferror_ratio(config: &Config, sent: &[[f64; 6]], actual: &[[f64; 6]]) -> f64 {
    let period = config.period_s();
    let axes = config.axes.linear();
    let mut worst = 0.0f64;
    for k in 2..sent.len() {
        for (i, ax) in axes.iter().enumerate() {
            let drive = config.drive.axes[i].expect("a drive");
            let v = (sent[k - 1][i] - sent[k - 2][i]) / period;
            let limit = drive
                .min_ferror_mm_deg
                .max(drive.ferror_mm_deg * v.abs() / ax.velocity_mm_s);
            let err = (sent[k - 1][i] - actual[k][i]).abs();
            worst = worst.max(err / limit);
        }
    }
    worst
}

fn machine_variant(
    accel_scale: f64,
    bandwidth_hz: f64,
    counts_per_mm: f64,
    direction: i32,
) -> Config {
    let mut c = Config::from_toml_str(
        &kerf_testkit::config_text::without_homing(kerf_config::BUILTIN_TOML),
        "kerf.toml",
    )
    .expect("the bundled machine without homing");
    for ax in [&mut c.axes.x, &mut c.axes.y, &mut c.axes.z] {
        ax.acceleration_mm_s2 *= accel_scale;
        ax.jerk_mm_s3 *= accel_scale;
    }
    for d in c.drive.axes.iter_mut().flatten() {
        d.sim.bandwidth_hz = bandwidth_hz;
        d.scale = kerf_drive::cia402::Scale::new(counts_per_mm, direction).expect("scale");
    }
    c
}

#[test]
fn well_tuned_drives_follow_real_programs_within_the_following_error_limit() {
    let programs = programs();
    // (acceleration and jerk × , bandwidth Hz, counts/mm, direction): the lag of a full
    // feed-forward drive is a/ωn², from 0.005 to 0.03 mm here, under MIN_FERROR 0.1.
    let machines = [
        (1.0, 50.0, 1000.0, 1),
        (0.5, 40.0, 200.0, -1),
        (2.5, 100.0, 5000.0, 1),
    ];
    for (scale, bw, counts, dir) in machines {
        let config = machine_variant(scale, bw, counts, dir);
        let mut m = Machine::new(config.clone());
        let mut at = m.enable();
        for (name, text) in &programs {
            let id = m.send(text, at);
            let (sent, actual, end) = m.run_program(id);
            let what = format!("{name} on ({scale}, {bw} Hz, {counts}/mm, {dir})");
            assert!(end.refusal.is_none(), "{what}: {:?}", end.refusal);
            assert!(end.drives.fault.is_none(), "{what}: {:?}", end.drives.fault);
            let moved = sent.windows(2).any(|w| w[0] != w[1]);
            assert!(moved, "{what}: nothing moved");
            let worst = worst_ferror_ratio(&config, &sent, &actual);
            assert!(
                worst < 0.5,
                "{what}: following error at {worst} of its limit"
            );
            at = end.position;
        }
    }
}

#[test]
fn a_badly_tuned_drive_trips_mid_program_and_nothing_moves_until_reset() {
    // 2 Hz: a lag of a/ωn² = 2000 / 158 ≈ 13 mm at full acceleration, far beyond 0.1.
    let config = machine_variant(1.0, 2.0, 1000.0, 1);
    let mut m = Machine::new(config.clone());
    let at = m.enable();
    let (_, part) = programs()
        .into_iter()
        .find(|(n, _)| n.ends_with("part.ngc"))
        .expect("the example part");
    let id = m.send(&part, at);
    let (sent, _, end) = m.run_program(id);
    let f = match end.refusal {
        Some(Refusal::Safety(f)) => f,
        other => panic!("{other:?}"),
    };
    assert_eq!(f.check, Check::FollowingError);
    assert!(f.value > f.limit && f.line > 0, "{f:?}");
    // It tripped during the motion, well before the program's end.
    assert!(sent.len() > 10, "{}", sent.len());
    // Let the quick stop end; the machine holds still from then on.
    let mut rest = m.run().setpoint.position;
    for _ in 0..2000 {
        rest = m.run().setpoint.position;
    }
    let stopped = m.last.expect("status").drives.state;
    assert_eq!(stopped, kerf_drive::safety::SafetyState::Stopped);
    // The next program is refused and moves nothing.
    let id2 = m.send("G21 G90 G1 X1 F600\nM2\n", rest);
    let (sent2, _, end2) = m.run_program(id2);
    assert!(
        matches!(end2.refusal, Some(Refusal::Faulted(_))),
        "{:?}",
        end2.refusal
    );
    assert!(sent2.iter().all(|p| *p == rest));
    // A reset (the stop is over, the drives follow at rest) clears it; the program then
    // runs from where the axes stopped.
    m.commands.push(CycleCommand::Reset(1)).expect("room");
    for _ in 0..100 {
        m.run();
    }
    let s = m.last.expect("status");
    assert_eq!(s.reset, Some((1, Ok(()))));
    assert!(s.drives.fault.is_none());
    let id3 = m.send("G21 G91 G1 X1 F60\nM2\n", s.position);
    let (sent3, _, end3) = m.run_program(id3);
    assert!(end3.refusal.is_none(), "{:?}", end3.refusal);
    let last = sent3.last().unwrap();
    assert!((last[0] - (s.position[0] + 1.0)).abs() < 1e-9);
}

/// A trip of the safety layer on the very cycle in which a program's motion ended belongs
/// to that program (issue 25: the inconsistent arc's last setpoint snapped back and tripped,
/// and the program was reported finished). One cycle later it is no longer the program's.
#[test]
fn a_trip_on_the_cycle_a_program_ends_is_that_programs_and_one_after_it_is_not() {
    let config = machine_variant(1.0, 50.0, 1000.0, 1);
    let program = "G21 G90 G1 X5 F600\nM2\n";
    // The program's length in cycles, from a clean run.
    let mut m = Machine::new(config.clone());
    let at = m.enable();
    let id = m.send(program, at);
    let (sent, _, end) = m.run_program(id);
    assert_eq!(end.refusal, None);
    let cycles = sent.len();
    assert!(cycles > 10, "{cycles}");
    // The same again, with a 1 mm step injected into the setpoint of cycle `at_cycle`
    // (1-based from the program's first call): a velocity trip on that cycle.
    let trip_at = |at_cycle: usize| -> Snapshot {
        let mut m = Machine::new(config.clone());
        let at = m.enable();
        let id = m.send(program, at);
        for k in 1..=cycles + 5 {
            if k == at_cycle {
                let step = kerfd::worker::Injection::Step(0, 1.0);
                m.commands.push(CycleCommand::Inject(step)).expect("room");
            }
            m.run();
        }
        let s = m.last.expect("status");
        assert_eq!(s.program_id, id);
        assert!(s.program_done);
        assert!(s.drives.fault.is_some(), "no trip at cycle {at_cycle}");
        s
    };
    for at_cycle in [cycles - 1, cycles] {
        let s = trip_at(at_cycle);
        assert!(
            matches!(s.refusal, Some(Refusal::Safety(_))),
            "a trip at cycle {at_cycle} of {cycles}: {:?}",
            s.refusal
        );
    }
    let s = trip_at(cycles + 1);
    assert_eq!(s.refusal, None, "a trip after the program's end");
}

/// Periods in which no cycle ran are counted in every later setpoint, so that a consumer
/// sees them (issue 25: a missed deadline was invisible in `seq`).
#[test]
fn missed_periods_are_counted_in_the_setpoints() {
    let mut m = Machine::new(machine_variant(1.0, 50.0, 1000.0, 1));
    let first = m.run();
    assert_eq!(first.missed_periods, 0);
    m.cycle.missed(5);
    let out = m.run();
    assert_eq!(out.missed_periods, 5);
    assert_eq!(out.seq, first.seq + 1, "seq counts cycles run");
    m.cycle.missed(1);
    let mut msg = kerf_proto::SetpointMsg::new();
    m.run().fill(&mut msg, 0);
    assert_eq!(msg.missed_periods, 6);
}
