//! The machine around the axes on EtherCAT: the spindle's CiA 402 drive in cyclic
//! synchronous velocity and the machine's digital inputs and outputs on an I/O terminal,
//! run by `kerfd` on the emulated network `kerf-ecat-sim` (X, Y, Z drives at positions 0
//! to 2, the spindle's drive at 3, the terminal at 4; see `Bench::machine`). Each test
//! asserts what a user sees: the emulated subdevices' own account (the emulator's
//! `state`: the spindle drive's target and actual velocity, the terminal's output bits),
//! `kerf status --json`, and the setpoints `kerf run --record` wrote.
//!
//! Needs root and iproute2 (CI runs as root); the namespace fixture fails the test, with
//! the reason, where it cannot make a namespace. Build the binaries first:
//! `cargo build -p kerfd -p kerf -p kerf-ecat-sim`.

use std::fs;
use std::io::Read as _;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;
mod ethercat_bench;
use ethercat_bench::{Bench, KERF, PATIENCE};

/// The spindle drive's velocity counts per revolution (`Bench::machine`).
const COUNTS_PER_REV: f64 = 10_000.0;

/// The emulated spindle motor's ramp in this test, counts/s²: 500 000 counts/s² at 10000
/// counts per revolution is 50 rev/s², 3000 rpm/s: four times slower than the machine's
/// own setpoint ramp (`acceleration_rpm_s` = 12000), so that the spindle's actual speed,
/// not its setpoint, decides when it is at speed.
const SPINDLE_ACCEL_COUNTS_S2: f64 = 500_000.0;

/// The bench's cycle period, s (`period_us = 4000`): the emulated drives step once per
/// exchange, every 4 ms.
const PERIOD_S: f64 = 0.004;

/// Line by line (1-based): the spindle at 6000 rpm clockwise, flood coolant, a 20 mm
/// feed move at 300 mm/min (4 s), spindle and coolant off, the end.
const PART: &str = "G21 G90 G94 G17\n\
S6000 M3\n\
M8\n\
G1 X20 F300\n\
M5\n\
M9\n\
M2\n";

/// The feed move's line in [`PART`].
const FEED_LINE: u64 = 4;

/// [`PART`] with the program's own outputs and a wait on an input, line by line: the
/// spindle, flood coolant, the clamp output on with the next move (M62), the feed move,
/// the clamp off and the blast on at once (M65, M64), a wait for the door-closed input
/// (input 4, L3: until on, Q5: 5 s), the blast off, spindle and coolant off, the end.
/// M62/M63 switch with the motion (the clamp on with the feed move, off when it ends);
/// M64/M65 at once, when the motion takes them: after the dwell, which holds back what
/// follows it (an M64 right after the move would switch while the move still runs, as
/// LinuxCNC's does).
const PART_IO: &str = "G21 G90 G94 G17\n\
S6000 M3\n\
M8\n\
M62 P2\n\
G1 X20 F300\n\
M63 P2\n\
G4 P0.1\n\
M64 P3\n\
M66 P4 L3 Q5\n\
M65 P3\n\
M5\n\
M9\n\
M2\n";

/// The feed move's line in [`PART_IO`].
const IO_FEED_LINE: u64 = 5;
/// The wait's line in [`PART_IO`].
const WAIT_LINE: u64 = 9;

/// The value of `field` in an emulator `state` line, as a number.
fn number(line: &str, field: &str) -> i64 {
    Bench::field(line, field)
        .parse()
        .unwrap_or_else(|e| panic!("{field} in {line}: {e}"))
}

/// The I/O terminal's output bits in an emulator `state` line (`outputs=0x21`).
fn outputs(line: &str) -> u64 {
    let hex = Bench::field(line, "outputs");
    u64::from_str_radix(hex.trim_start_matches("0x"), 16).expect("hex outputs")
}

/// `kerf status --json` polled until `done` holds, while `run` (a `kerf run`) goes on:
/// fails with its output if it ends first.
fn status_while_running(
    bench: &Bench,
    run: &mut std::process::Child,
    what: &str,
    done: impl Fn(&serde_json::Value) -> bool,
) -> serde_json::Value {
    let deadline = Instant::now() + PATIENCE;
    loop {
        let s = bench.status();
        if done(&s) {
            return s;
        }
        if let Some(exit) = run.try_wait().unwrap() {
            let mut text = String::new();
            if let Some(mut pipe) = run.stdout.take() {
                let _ = pipe.read_to_string(&mut text);
            }
            if let Some(mut pipe) = run.stderr.take() {
                let _ = pipe.read_to_string(&mut text);
            }
            panic!("kerf run ended ({exit}) before {what}: {text}\nstatus: {s}");
        }
        assert!(Instant::now() < deadline, "never {what}: {s}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Waits until the daemon has enabled the drives (the spindle's too) and is idle.
fn idle(bench: &mut Bench) {
    bench.status_until("idle", |s| s["state"] == "idle" && s["drives"] == "running");
    let deadline = Instant::now() + PATIENCE;
    loop {
        let state = bench.emulator_state();
        if Bench::field(&state[3], "cia402") == "operation_enabled" {
            assert_eq!(Bench::field(&state[3], "mode"), "9", "{}", state[3]);
            return;
        }
        assert!(
            Instant::now() < deadline,
            "the spindle drive was never enabled: {}",
            state[3]
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Starts `kerf run --record run.csv` of `program` (written to part.ngc) on `bench`'s
/// daemon; returns the child and the record's path.
fn start_run(bench: &Bench, program: &str) -> (std::process::Child, std::path::PathBuf) {
    let path = bench.dir.join("part.ngc");
    fs::write(&path, program).unwrap();
    let record = bench.dir.join("run.csv");
    let run = Command::new(KERF)
        .args(["run", "--record", record.to_str().unwrap()])
        .arg(&path)
        .args(["--config", bench.config.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    (run, record)
}

/// Checks the middle of the feed move at `feed_line` (X between 4 and 16 of 20 mm): the
/// spindle drive turns at the commanded 6000 rpm, 6000 × 10000 / 60 = 1 000 000 counts/s,
/// target and actual, and `kerf status` says so; the terminal's output bits are
/// `terminal_outputs`, the machine's output word `digital_outputs`.
fn check_feeding(
    bench: &mut Bench,
    run: &mut std::process::Child,
    feed_line: u64,
    terminal_outputs: u64,
    digital_outputs: u64,
) {
    let status = status_while_running(bench, run, "in the middle of the feed move", |s| {
        s["line"] == feed_line
            && s["position"]["x"]
                .as_f64()
                .is_some_and(|x| x > 4.0 && x < 16.0)
    });
    let state = bench.emulator_state();
    let spindle = &state[3];
    assert_eq!(
        number(spindle, "target_velocity_counts_s"),
        1_000_000,
        "{spindle}"
    );
    assert_eq!(number(spindle, "velocity_counts_s"), 1_000_000, "{spindle}");
    assert_eq!(outputs(&state[4]), terminal_outputs, "{}", state[4]);
    let actual = status["spindle"]["actual_rpm"]
        .as_f64()
        .expect("actual_rpm");
    assert!((actual - 6000.0).abs() < 1.0, "{status}");
    assert_eq!(status["spindle"]["at_speed"], true, "{status}");
    assert_eq!(status["io"]["digital_outputs"], digital_outputs, "{status}");
}

/// After the program's M5, M9 and M2 (`run` waited for): every output off, the spindle's
/// target down to 0 and its motor at rest; and the feed move
/// at `feed_line` did not start before the spindle was at speed: the emulated motor
/// needs 6000 × 0.98 / 3000 = 1.96 s from rest into the 2 % band, while the machine's
/// setpoint ramp alone would be there after 5880 / 12000 = 0.49 s. The first setpoint
/// off X = 0 comes after 1.96 s of program time, and not much later (a few periods of
/// transport: the setpoint out, the drive's answer back).
fn check_end(
    bench: &mut Bench,
    run: std::process::Child,
    record: &std::path::Path,
    feed_line: u64,
) {
    let out = run.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "kerf run: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let state = bench.emulator_state();
    assert_eq!(outputs(&state[4]), 0, "{}", state[4]);
    // The machine ramps the setpoint down at 12000 rpm/s (0.5 s), the motor follows at
    // its own 3000 rpm/s.
    let deadline = Instant::now() + PATIENCE;
    loop {
        let spindle = bench.emulator_state()[3].clone();
        let target = number(&spindle, "target_velocity_counts_s");
        let actual = number(&spindle, "velocity_counts_s");
        assert!((0..=1_000_000).contains(&target), "{spindle}");
        if target == 0 && actual == 0 {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "the spindle never stopped: {spindle}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let status = bench.status_until("the spindle at rest in the status", |s| {
        s["spindle"]["actual_rpm"] == 0.0
    });
    assert_eq!(status["io"]["digital_outputs"], 0, "{status}");

    let text = fs::read_to_string(record).unwrap();
    let mut rows = text.lines();
    assert_eq!(rows.next(), Some("t,x,y,z,line,feed_mm_s"));
    let first_move = rows
        .map(|r| {
            r.split(',')
                .map(|v| v.parse::<f64>().unwrap())
                .collect::<Vec<_>>()
        })
        .find(|r| r[1] != 0.0)
        .expect("the feed move in the record");
    let at_speed_s = 6000.0 * 0.98 / (SPINDLE_ACCEL_COUNTS_S2 * 60.0 / COUNTS_PER_REV);
    assert!(
        first_move[0] >= at_speed_s && first_move[0] <= at_speed_s + 10.0 * PERIOD_S,
        "the feed move started at {} s, the spindle at speed at {at_speed_s} s",
        first_move[0]
    );
    assert_eq!(first_move[4], feed_line as f64);
}

#[test]
fn the_spindle_drive_and_the_coolant_output_of_a_part_run_on_the_bus_and_inputs_come_in() {
    let mut bench = Bench::machine("machine", "", SPINDLE_ACCEL_COUNTS_S2);
    let _daemon = bench.daemon();
    idle(&mut bench);
    let state = bench.emulator_state();
    assert_eq!(outputs(&state[4]), 0, "{}", state[4]);
    assert_eq!(number(&state[3], "target_velocity_counts_s"), 0);

    // The terminal's input bits 0 and 1 are the machine's inputs 0 (part_present) and
    // 4 (door_closed).
    bench.emulator_says("inputs 0 0x03");
    bench.status_until("inputs 0 and 4 on", |s| {
        s["io"]["digital_inputs"] == 0b1_0001
    });
    bench.emulator_says("inputs 0 0x02");
    bench.status_until("input 4 alone on", |s| {
        s["io"]["digital_inputs"] == 0b1_0000
    });

    // The feed move runs with the spindle at speed and the flood (output 1) on the
    // terminal's output bit 0.
    let (mut run, record) = start_run(&bench, PART);
    check_feeding(&mut bench, &mut run, FEED_LINE, 0b1, 0b10);
    check_end(&mut bench, run, &record, FEED_LINE);
}

#[test]
fn a_part_switches_bus_outputs_and_waits_on_a_bus_input() {
    let mut bench = Bench::machine("machineio", "", SPINDLE_ACCEL_COUNTS_S2);
    let _daemon = bench.daemon();
    idle(&mut bench);
    let (mut run, record) = start_run(&bench, PART_IO);
    // While feeding: the flood (output 1, bit 0) and the clamp (output 2, bit 1,
    // switched with the move's start) on.
    check_feeding(&mut bench, &mut run, IO_FEED_LINE, 0b11, 0b110);
    // At the wait: the clamp off, the blast (output 3, bit 5) on; the program waits for
    // the door until the terminal's input bit 1 (input 4) comes on.
    let status = status_while_running(&bench, &mut run, "waiting for the door", |s| {
        s["pause"]["reason"] == "wait_input" && s["pause"]["line"] == WAIT_LINE
    });
    assert_eq!(status["io"]["digital_inputs"], 0, "{status}");
    assert_eq!(status["io"]["digital_outputs"], 0b1010, "{status}");
    let state = bench.emulator_state();
    assert_eq!(outputs(&state[4]), 0b10_0001, "{}", state[4]);
    bench.emulator_says("inputs 0 0x03");
    check_end(&mut bench, run, &record, IO_FEED_LINE);
    // The wait ended on the input (#5399 = 1), not on its timeout.
    let status = bench.status();
    assert_eq!(status["io"]["digital_inputs"], 0b1_0001, "{status}");
    assert_eq!(status["input_result"]["value"], 1.0, "{status}");
    assert_eq!(status["input_result"]["line"], WAIT_LINE, "{status}");
}

#[test]
fn a_spindle_drive_missing_from_the_bus_is_refused_by_name() {
    // The ring has the three axes' drives and the terminal, but no fourth drive.
    let bench = Bench::machine_on("nospindle", &["--drives", "3", "--io", "1"]);
    let (status, stderr) = bench.daemon_refused();
    assert_eq!(status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains(
            "position 3: found \"Kerf digital I/O\" vendor 0x00004b52 product 0x00000010 revision 0x00010000, expected spindle drive vendor 0x00004b52 product 0x00000402 any revision"
        ),
        "{stderr}"
    );
    assert!(
        stderr.contains("position 4: nothing found, expected I/O"),
        "{stderr}"
    );
}

#[test]
fn a_fault_of_the_spindle_drive_latches_and_a_reset_enables_it_again() {
    let mut bench = Bench::machine("spfault", "", SPINDLE_ACCEL_COUNTS_S2);
    let _daemon = bench.daemon();
    idle(&mut bench);
    // The drive trips over-temperature (0x4310) on its own.
    bench.emulator_says("fault 3 0x4310");
    let status = bench.status_until("the spindle drive's fault", |s| {
        s["safety"]["check"] == "spindle_drive"
    });
    assert_eq!(
        status["safety"]["axis"],
        serde_json::Value::Null,
        "{status}"
    );
    assert_eq!(
        status["safety"]["value"].as_f64(),
        Some(f64::from(0x4310)),
        "{status}"
    );
    assert_eq!(status["safety"]["limit"].as_f64(), Some(0.0), "{status}");
    assert!(
        status["fault"]
            .as_str()
            .is_some_and(|f| f.contains("the spindle drive reports error 0x4310")),
        "{status}"
    );
    assert_eq!(Bench::field(&bench.emulator_state()[3], "cia402"), "fault");
    let out = bench.kerf(&["reset"]);
    assert!(
        out.status.success(),
        "reset refused: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    bench.status_until("idle", |s| s["state"] == "idle" && s["fault"].is_null());
    let deadline = Instant::now() + PATIENCE;
    loop {
        let line = bench.emulator_state()[3].clone();
        if Bench::field(&line, "cia402") == "operation_enabled" {
            assert_eq!(Bench::field(&line, "error_code"), "0x0000", "{line}");
            break;
        }
        assert!(Instant::now() < deadline, "never enabled again: {line}");
        std::thread::sleep(Duration::from_millis(20));
    }
}
