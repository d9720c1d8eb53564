//! Multi-process tests of what a part program commands besides the axes (issue 28), through
//! the daemon `kerfd` and the commands that talk to it: program pauses (`M0`, `M1` with the
//! optional-stop switch), `kerf resume`, single block, `M66` waits answered through
//! `#5399`, outputs and coolant, the simulated spindle drive and its at-speed wait, tool
//! changes and the tool kept over a daemon restart, programs refused before motion, run
//! from line, and an abort during a pause.
//!
//! As in `daemon.rs`: every test writes its own machine configuration (a copy of
//! `config/kerf.toml` with a machine name unique to the test and this process, and its own
//! state file) into its own directory; child processes live in [`Proc`] guards; nothing is
//! asserted about wall-clock time. What is asserted is measured from the outputs: `kerf
//! status --json`, the setpoints `kerf run --record` writes (times relative to the
//! program's cycles) and the commands' exit codes and messages. The expected values come
//! from the programs and the configuration (positions from the G-code, the spindle's ramp
//! from `acceleration_rpm_s`, its band from `at_speed_tolerance`).

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Output};
use std::time::{Duration, Instant};

use serde_json::Value;

const KERF: &str = env!("CARGO_BIN_EXE_kerf");
mod common;
use common::{Proc, kerfd};

/// Upper bound on any wait, so that a broken daemon fails a test instead of hanging it.
const PATIENCE: Duration = Duration::from_secs(30);

/// How often status is polled.
const POLL: Duration = Duration::from_millis(10);

/// Room for rounding when a position is compared with a programmed one, mm.
const EPS_MM: f64 = 1e-6;

/// The bundled machine's simulated spindle drive (config/kerf.toml, `[spindle]`).
const SPINDLE_ACCEL_RPM_S: f64 = 8000.0;
const AT_SPEED_BAND: f64 = 0.02;

// ---------------------------------------------------------------------------------------
// Processes and scratch directories
// ---------------------------------------------------------------------------------------

/// Starts `program ARGS` with its output in the scratch directory `dir`.
fn spawn(name: &str, dir: &Path, program: &str, args: &[&str]) -> Proc {
    let mut command = Command::new(program);
    command.args(args);
    Proc::start(name, dir, command)
}

/// Waits for `p` to exit (panics after [`PATIENCE`] times `factor`).
fn wait(p: &mut Proc, factor: u32) -> ExitStatus {
    p.wait_within(PATIENCE * factor)
}

fn stderr_of(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// One test's machine: a scratch directory with its configuration file and state file.
struct Env {
    dir: PathBuf,
    config_path: PathBuf,
}

impl Env {
    /// A machine named `m<pid>_<tag>`, with `edits` (pairs of text to find and replace,
    /// each at its first occurrence) applied to the bundled configuration, and its state
    /// file in the scratch directory.
    fn new(tag: &str, edits: &[(&str, &str)]) -> Env {
        let machine = format!("m{}_{tag}", std::process::id());
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
            .join("kerf-machine-ops-tests")
            .join(&machine);
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let mut text = kerf_testkit::config_text::without_homing(
            &fs::read_to_string(root.join("config/kerf.toml")).unwrap(),
        );
        let mut all = vec![
            ("machine = \"default\"", format!("machine = \"{machine}\"")),
            (
                "# state_file = \"/var/lib/kerf/default.state.toml\"",
                "state_file = \"state.toml\"".to_string(),
            ),
        ];
        for (from, to) in edits {
            all.push((from, to.to_string()));
        }
        for (from, to) in all {
            assert!(text.contains(from), "config/kerf.toml has no `{from}`");
            text = text.replacen(from, &to, 1);
        }
        let config_path = dir.join("kerf.toml");
        fs::write(&config_path, text).unwrap();
        Env { dir, config_path }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    fn config_arg(&self) -> &str {
        self.config_path.to_str().unwrap()
    }

    fn write(&self, name: &str, text: &str) -> PathBuf {
        let p = self.path(name);
        fs::write(&p, text).unwrap();
        p
    }

    /// `kerf SUBCOMMAND --config C ARGS…`, to completion (killed, and the test failed,
    /// after [`PATIENCE`]).
    fn kerf(&self, subcommand: &str, args: &[&str]) -> Output {
        static RUNS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let name = format!("kerf-{subcommand}-{n}");
        let mut args_all = vec![subcommand, "--config", self.config_arg()];
        args_all.extend_from_slice(args);
        let mut p = spawn(&name, &self.dir, KERF, &args_all);
        let status = wait(&mut p, 1);
        let out = Output {
            status,
            stdout: fs::read(&p.stdout).unwrap(),
            stderr: fs::read(&p.stderr).unwrap(),
        };
        let _ = fs::remove_file(&p.stdout);
        let _ = fs::remove_file(&p.stderr);
        out
    }

    /// `kerf SUBCOMMAND …`, asserted to exit 0.
    fn kerf_ok(&self, subcommand: &str, args: &[&str]) {
        let o = self.kerf(subcommand, args);
        assert!(
            o.status.success(),
            "kerf {subcommand} {args:?} failed ({}): {}",
            o.status,
            stderr_of(&o)
        );
    }

    /// Starts `kerfd --config C` and waits until `kerf status` answers.
    fn start_daemon(&self, name: &str) -> Proc {
        let mut d = spawn(name, &self.dir, kerfd(), &["--config", self.config_arg()]);
        let deadline = Instant::now() + PATIENCE;
        loop {
            if let Some(status) = d.try_wait() {
                panic!("kerfd exited at start ({status}): {}", d.stderr());
            }
            if self.kerf("status", &[]).status.success() {
                return d;
            }
            assert!(
                Instant::now() < deadline,
                "kerfd never answered: {}",
                d.stderr()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// `kerf status --json`, parsed.
    fn status(&self) -> Value {
        let out = self.kerf("status", &["--json"]);
        assert!(
            out.status.success(),
            "kerf status failed: {}",
            stderr_of(&out)
        );
        let text = String::from_utf8(out.stdout).unwrap();
        serde_json::from_str(text.trim()).unwrap_or_else(|e| panic!("not JSON ({e}): {text}"))
    }

    /// Polls the status until `done` holds; panics after [`PATIENCE`], or as soon as `run`
    /// (the `kerf run` that should still be running) has exited.
    fn wait_status_while(
        &self,
        run: &mut Proc,
        what: &str,
        mut done: impl FnMut(&Value) -> bool,
    ) -> Value {
        let deadline = Instant::now() + PATIENCE;
        loop {
            let s = self.status();
            if done(&s) {
                return s;
            }
            if let Some(status) = run.try_wait() {
                panic!(
                    "waiting for {what}: kerf run exited ({status}); status: {s}; its stderr: {}",
                    run.stderr()
                );
            }
            assert!(Instant::now() < deadline, "waiting for {what}; status: {s}");
            std::thread::sleep(POLL);
        }
    }

    /// Waits until the program pauses for `reason` (while `run` runs).
    fn wait_pause(&self, run: &mut Proc, reason: &str) -> Value {
        self.wait_status_while(run, &format!("a pause for {reason}"), |s| {
            s["pause"]["reason"] == reason
        })
    }

    /// Two status polls at least ten cycles apart that show the same position and the same
    /// pause: the machine rests in the pause. The later one.
    fn rest_in_pause(&self, run: &mut Proc, reason: &str) -> Value {
        let mut before: Option<Value> = None;
        self.wait_status_while(run, &format!("rest in the pause for {reason}"), |s| {
            assert_eq!(s["pause"]["reason"], reason, "the pause ended: {s}");
            let rest = before.as_ref().is_some_and(|b| {
                position(b) == position(s)
                    && cycles(s) >= cycles(b) + 10
                    && b["pause"] == s["pause"]
            });
            before = Some(s.clone());
            rest
        })
    }

    /// Waits until `needle` appears in `p`'s standard error (while it runs, or after).
    fn wait_stderr(&self, p: &mut Proc, needle: &str) {
        let deadline = Instant::now() + PATIENCE;
        loop {
            if p.stderr().contains(needle) {
                return;
            }
            if p.try_wait().is_some() {
                // It has exited: its standard error is complete.
                assert!(
                    p.stderr().contains(needle),
                    "no `{needle}` in: {}",
                    p.stderr()
                );
                return;
            }
            assert!(
                Instant::now() < deadline,
                "no `{needle}` in: {}",
                p.stderr()
            );
            std::thread::sleep(POLL);
        }
    }

    /// `kerf run --config C EXTRA… PROGRAM`, in the background.
    fn spawn_run(&self, name: &str, program: &Path, extra: &[&str]) -> Proc {
        let mut args = vec!["run", "--config", self.config_arg()];
        args.extend_from_slice(extra);
        args.push(program.to_str().unwrap());
        spawn(name, &self.dir, KERF, &args)
    }

    /// `kerf run`, to completion; asserts exit 0 and returns its standard error.
    fn run_ok(&self, name: &str, program: &Path, extra: &[&str]) -> String {
        let mut p = self.spawn_run(name, program, extra);
        let status = wait(&mut p, 2);
        assert!(
            status.success(),
            "kerf run {name} failed ({status}): {}",
            p.stderr()
        );
        p.stderr()
    }
}

impl Drop for Env {
    fn drop(&mut self) {
        // `KERF_TEST_KEEP=1` keeps a failed test's files (logs, recordings) to look at.
        if std::thread::panicking() && std::env::var_os("KERF_TEST_KEEP").is_some() {
            eprintln!("kept {}", self.dir.display());
            return;
        }
        let _ = fs::remove_dir_all(&self.dir);
    }
}

fn cycles(s: &Value) -> u64 {
    s["cycles"].as_u64().unwrap()
}

fn state(s: &Value) -> &str {
    s["state"].as_str().unwrap()
}

fn program_end(s: &Value) -> &str {
    s["program_end"].as_str().unwrap()
}

fn position(s: &Value) -> [f64; 3] {
    let p = &s["position"];
    [
        p["x"].as_f64().unwrap(),
        p["y"].as_f64().unwrap(),
        p["z"].as_f64().unwrap(),
    ]
}

fn near(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
    a.iter().zip(b.iter()).all(|(p, q)| (p - q).abs() <= tol)
}

fn assert_at(s: &Value, expected: [f64; 3], what: &str) {
    assert!(
        near(position(s), expected, EPS_MM),
        "{what}: at {:?}, expected {expected:?}; status: {s}",
        position(s)
    );
}

fn f64_of(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("{v} is not a number"))
}

/// The idle machine after a program that ended at its end: no pause.
fn assert_finished(s: &Value) {
    assert_eq!(state(s), "idle", "{s}");
    assert_eq!(program_end(s), "finished", "{s}");
    assert_eq!(s["pause"], Value::Null, "{s}");
}

// ---------------------------------------------------------------------------------------
// Recorded streams
// ---------------------------------------------------------------------------------------

/// One CSV row: `t,x,y,z,line,feed_mm_s`.
#[derive(Clone, Debug)]
struct Row {
    t: f64,
    position: [f64; 3],
    line: u32,
    feed_mm_s: f64,
}

fn read_csv(path: &Path) -> Vec<Row> {
    let text = fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t,x,y,z,line,feed_mm_s"), "{path:?}");
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 6, "{path:?}: {l}");
            let num = |s: &str| -> f64 { s.parse().unwrap_or_else(|_| panic!("{path:?}: {l}")) };
            Row {
                t: num(f[0]),
                position: [num(f[1]), num(f[2]), num(f[3])],
                line: f[4].parse().unwrap_or_else(|_| panic!("{path:?}: {l}")),
                feed_mm_s: num(f[5]),
            }
        })
        .collect()
}

/// The first row of `line` whose position differs from the row before it.
fn first_moving_row_of(rows: &[Row], line: u32) -> Option<&Row> {
    rows.windows(2)
        .find(|w| w[1].line == line && w[1].position != w[0].position)
        .map(|w| &w[1])
}

/// The last row of `line` whose position differs from the row before it.
fn last_moving_row_of(rows: &[Row], line: u32) -> Option<&Row> {
    rows.windows(2)
        .rev()
        .find(|w| w[1].line == line && w[1].position != w[0].position)
        .map(|w| &w[1])
}

/// Distance from `p` to the segment `a`–`b`.
fn segment_distance(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let ap = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let len2 = ab.iter().map(|v| v * v).sum::<f64>();
    let t = if len2 == 0.0 {
        0.0
    } else {
        (ap.iter().zip(&ab).map(|(u, v)| u * v).sum::<f64>() / len2).clamp(0.0, 1.0)
    };
    let d: f64 = (0..3)
        .map(|i| (a[i] + t * ab[i] - p[i]).powi(2))
        .sum::<f64>();
    d.sqrt()
}

/// Distance from `p` to the polyline through `points`.
fn polyline_distance(p: [f64; 3], points: &[[f64; 3]]) -> f64 {
    if points.len() == 1 {
        return segment_distance(p, points[0], points[0]);
    }
    points
        .windows(2)
        .map(|w| segment_distance(p, w[0], w[1]))
        .fold(f64::INFINITY, f64::min)
}

// ---------------------------------------------------------------------------------------
// Program pauses and single block
// ---------------------------------------------------------------------------------------

/// The pause sentence `kerf run` prints for an M0 at `line`.
fn m0_sentence(line: u32) -> String {
    format!("kerf: paused at line {line} (M0, program stop): `kerf resume` to continue")
}

#[test]
fn m0_pauses_at_rest_until_cycle_start() {
    let env = Env::new("m0", &[]);
    let _daemon = env.start_daemon("kerfd");

    // Nothing to resume on an idle machine.
    let o = env.kerf("resume", &[]);
    assert!(
        !o.status.success(),
        "resume on an idle machine was accepted"
    );
    assert!(
        stderr_of(&o).contains("nothing to resume"),
        "{}",
        stderr_of(&o)
    );

    // Line 3 is the M0; it comes after the move of line 2 has ended at X2 Y1.
    let program = env.write(
        "m0.ngc",
        "G21 G90 G64 P0.01\nG1 X2 Y1 F3000\nM0\nG1 X3 Y3\nM2\n",
    );
    let mut run = env.spawn_run("run", &program, &[]);
    let s = env.wait_pause(&mut run, "program_stop");
    assert_eq!(state(&s), "paused", "{s}");
    assert_eq!(s["pause"]["line"], 3, "{s}");
    assert_eq!(s["pause"]["waits_for_operator"], true, "{s}");
    assert_eq!(program_end(&s), "running", "{s}");
    let rest = env.rest_in_pause(&mut run, "program_stop");
    assert_eq!(state(&rest), "paused", "{rest}");
    assert_at(&rest, [2.0, 1.0, 0.0], "paused at the M0");
    // `kerf run` waits in the pause and has said so.
    env.wait_stderr(&mut run, &m0_sentence(3));
    assert!(run.try_wait().is_none(), "kerf run exited in the pause");
    let text = String::from_utf8(env.kerf("status", &[]).stdout).unwrap();
    assert!(text.contains("paused"), "kerf status: {text}");

    env.kerf_ok("resume", &[]);
    let status = wait(&mut run, 1);
    assert!(
        status.success(),
        "kerf run failed ({status}): {}",
        run.stderr()
    );
    let s = env.status();
    assert_finished(&s);
    assert_at(&s, [3.0, 3.0, 0.0], "at the program's end");
    assert_eq!(
        run.stderr().matches(&m0_sentence(3)).count(),
        1,
        "the pause is told once: {}",
        run.stderr()
    );

    // Nothing to resume once the program has ended.
    let o = env.kerf("resume", &[]);
    assert!(!o.status.success(), "resume after the program was accepted");
    assert!(
        stderr_of(&o).contains("nothing to resume"),
        "{}",
        stderr_of(&o)
    );
}

#[test]
fn m1_pauses_only_while_the_optional_stop_switch_is_on() {
    let env = Env::new("m1", &[]);
    let _daemon = env.start_daemon("kerfd");
    // The bundled machine starts with the switch on ([operator] optional_stop = true).
    assert_eq!(env.status()["switches"]["optional_stop"], true);
    let program = env.write(
        "m1.ngc",
        "G21 G90 G64 P0.01\nG1 X2 Y1 F3000\nM1\nG1 X3 Y3\nM2\n",
    );

    env.kerf_ok("optional-stop", &["off"]);
    assert_eq!(env.status()["switches"]["optional_stop"], false);
    let err = env.run_ok("run-off", &program, &[]);
    assert!(
        !err.contains("paused"),
        "a pause with the switch off: {err}"
    );
    let s = env.status();
    assert_finished(&s);
    assert_at(&s, [3.0, 3.0, 0.0], "at the end");

    env.kerf_ok("optional-stop", &["on"]);
    assert_eq!(env.status()["switches"]["optional_stop"], true);
    let mut run = env.spawn_run("run-on", &program, &[]);
    env.wait_pause(&mut run, "optional_stop");
    let s = env.rest_in_pause(&mut run, "optional_stop");
    assert_eq!(state(&s), "paused", "{s}");
    assert_eq!(s["pause"]["line"], 3, "{s}");
    assert_at(&s, [2.0, 1.0, 0.0], "paused at the M1");
    env.wait_stderr(
        &mut run,
        "kerf: paused at line 3 (M1, optional stop): `kerf resume` to continue",
    );
    env.kerf_ok("resume", &[]);
    let status = wait(&mut run, 1);
    assert!(
        status.success(),
        "kerf run failed ({status}): {}",
        run.stderr()
    );
    let s = env.status();
    assert_finished(&s);
    assert_at(&s, [3.0, 3.0, 0.0], "at the end");
}

#[test]
fn single_block_pauses_after_each_block() {
    let env = Env::new("sb", &[]);
    let _daemon = env.start_daemon("kerfd");
    // Three blocks, each a move (the modal words on the first), then the program end.
    let program = env.write(
        "sb.ngc",
        "G21 G90 G64 P0.01 G1 X1 F3000\nG1 Y1\nG1 X0\nM2\n",
    );
    let ends = [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    assert_eq!(env.status()["switches"]["single_block"], false);
    env.kerf_ok("single-block", &["on"]);
    assert_eq!(env.status()["switches"]["single_block"], true);

    let mut run = env.spawn_run("run", &program, &[]);
    // Every pause until the program ends: (line, position at rest).
    let mut pauses: Vec<(u64, [f64; 3])> = Vec::new();
    let deadline = Instant::now() + PATIENCE * 2;
    loop {
        assert!(Instant::now() < deadline, "single block: pauses {pauses:?}");
        if let Some(status) = run.try_wait() {
            assert!(
                status.success(),
                "kerf run failed ({status}): {}",
                run.stderr()
            );
            break;
        }
        let s = env.status();
        if s["pause"]["reason"] == "single_block" {
            let s = env.rest_in_pause(&mut run, "single_block");
            assert_eq!(state(&s), "paused", "{s}");
            assert_eq!(s["pause"]["waits_for_operator"], true, "{s}");
            let line = s["pause"]["line"].as_u64().unwrap();
            pauses.push((line, position(&s)));
            env.kerf_ok("resume", &[]);
            // Past this pause before the next look.
            env.wait_status_while(&mut run, "the pause to end", |t| {
                t["pause"] != s["pause"] || program_end(t) != "running"
            });
        } else if !s["pause"].is_null() {
            panic!("an unexpected pause: {s}");
        }
        std::thread::sleep(POLL);
    }
    // After each block: 1, 2 and 3 (before the M2 of line 4), each at the block's end.
    let lines: Vec<u64> = pauses.iter().map(|p| p.0).collect();
    assert_eq!(lines, [1, 2, 3], "single block paused at {pauses:?}");
    for ((_, at), end) in pauses.iter().zip(ends) {
        assert!(near(*at, end, EPS_MM), "{pauses:?}");
    }
    for (line, _) in &pauses {
        assert!(
            run.stderr()
                .contains(&format!("kerf: paused after line {line} (single block)")),
            "{}",
            run.stderr()
        );
    }
    let s = env.status();
    assert_finished(&s);
    assert_at(&s, ends[2], "at the end");

    // Off again: the same program runs through without a pause.
    env.kerf_ok("single-block", &["off"]);
    assert_eq!(env.status()["switches"]["single_block"], false);
    let err = env.run_ok("run-off", &program, &[]);
    assert!(!err.contains("paused"), "{err}");
    assert_finished(&env.status());
}

#[test]
fn abort_during_a_pause_ends_the_program_and_switches_spindle_and_coolant_off() {
    let env = Env::new("abortp", &[]);
    let _daemon = env.start_daemon("kerfd");
    let program = env.write(
        "abort.ngc",
        "G21 G90\nS6000 M3\nM8\nG0 X1\nM0\nG1 X2 F3000\nM2\n",
    );
    let mut run = env.spawn_run("run", &program, &[]);
    env.wait_pause(&mut run, "program_stop");
    let s = env.rest_in_pause(&mut run, "program_stop");
    assert_at(&s, [1.0, 0.0, 0.0], "paused at the M0");
    assert_eq!(s["pause"]["line"], 5, "{s}");
    assert_eq!(s["spindle"]["dir"], 1, "{s}");
    assert_eq!(f64_of(&s["spindle"]["commanded_rpm"]), 6000.0, "{s}");
    assert_eq!(s["coolant"]["flood"], true, "{s}");

    env.kerf_ok("abort", &[]);
    let status = wait(&mut run, 1);
    assert!(!status.success(), "kerf run exited 0 after an abort");
    assert!(run.stderr().contains("aborted"), "{}", run.stderr());
    let s = env.status();
    assert_eq!(program_end(&s), "aborted", "{s}");
    assert_eq!(state(&s), "idle", "{s}");
    assert_eq!(s["pause"], Value::Null, "{s}");
    assert_at(&s, [1.0, 0.0, 0.0], "where the abort left it");
    // [spindle] off_at_abort and [coolant] off_at_abort.
    assert_eq!(s["spindle"]["dir"], 0, "{s}");
    assert_eq!(f64_of(&s["spindle"]["commanded_rpm"]), 0.0, "{s}");
    assert_eq!(s["coolant"]["flood"], false, "{s}");
    assert_eq!(s["coolant"]["mist"], false, "{s}");
    assert_eq!(
        s["io"]["digital_outputs"].as_u64().unwrap() & 0b10,
        0,
        "the flood output (1) is still on: {s}"
    );
    // The spindle runs down to rest.
    env.wait_status("the spindle to stop", |s| {
        f64_of(&s["spindle"]["actual_rpm"]) == 0.0
    });
    // Nothing is paused any more.
    let o = env.kerf("resume", &[]);
    assert!(!o.status.success(), "resume after the abort was accepted");
    assert!(
        stderr_of(&o).contains("nothing to resume"),
        "{}",
        stderr_of(&o)
    );
}

impl Env {
    /// Polls the status until `done` holds (panics after [`PATIENCE`]).
    fn wait_status(&self, what: &str, mut done: impl FnMut(&Value) -> bool) -> Value {
        let deadline = Instant::now() + PATIENCE;
        loop {
            let s = self.status();
            if done(&s) {
                return s;
            }
            assert!(Instant::now() < deadline, "waiting for {what}; status: {s}");
            std::thread::sleep(POLL);
        }
    }
}

// ---------------------------------------------------------------------------------------
// Inputs, outputs and coolant
// ---------------------------------------------------------------------------------------

/// A digital input of the test machine, off at start.
const TEST_INPUT: u32 = 20;

/// The bundled configuration with digital input [`TEST_INPUT`] added (simulated, off).
const ADD_INPUT: (&str, &str) = (
    "{ number = 2, name = \"tool_changed\" },",
    "{ number = 2, name = \"tool_changed\" },\n    { number = 20, name = \"test_in\", sim = false },",
);

/// `M66 P20 L3 Q<timeout>` (wait for the input to be high), then a branch on `#5399`: the
/// "if" side ends at X2 Y0, the "else" side at X0 Y2.
fn m66_program(timeout_s: f64) -> String {
    format!(
        "G21 G90 G64 P0.01
M66 P{TEST_INPUT} L3 Q{timeout_s}
o100 if [#5399 EQ 1]
  G1 X2 Y0 F3000
o100 else
  G1 X0 Y2 F3000
o100 endif
M2
"
    )
}

#[test]
fn m66_waits_for_the_input_and_5399_takes_the_branch() {
    let env = Env::new("m66", &[ADD_INPUT]);
    let _daemon = env.start_daemon("kerfd");
    let input = TEST_INPUT.to_string();
    assert_eq!(
        env.status()["io"]["digital_inputs"].as_u64().unwrap() & (1 << TEST_INPUT),
        0
    );

    // The input comes on while the program waits for it: the "if" branch.
    let program = env.write("m66-wait.ngc", &m66_program(20.0));
    let mut run = env.spawn_run("run-on", &program, &[]);
    let s = env.wait_pause(&mut run, "wait_input");
    assert_eq!(s["pause"]["line"], 2, "{s}");
    assert_eq!(s["pause"]["value"], TEST_INPUT, "{s}");
    assert_eq!(s["pause"]["waits_for_operator"], false, "{s}");
    // Waiting: nothing has moved.
    assert_at(&s, [0.0, 0.0, 0.0], "waiting on the input");
    env.kerf_ok("input", &[&input, "on"]);
    let status = wait(&mut run, 1);
    assert!(
        status.success(),
        "kerf run failed ({status}): {}",
        run.stderr()
    );
    let s = env.status();
    assert_finished(&s);
    assert_at(&s, [2.0, 0.0, 0.0], "the if branch's end");
    assert_eq!(
        s["io"]["digital_inputs"].as_u64().unwrap() & (1 << TEST_INPUT),
        1 << TEST_INPUT,
        "{s}"
    );
    assert_eq!(f64_of(&s["input_result"]["value"]), 1.0, "{s}");
    assert_eq!(s["input_result"]["line"], 2, "{s}");

    // The input stays off: after Q0.5 s the wait times out, #5399 = -1, the "else" branch.
    env.kerf_ok("input", &[&input, "off"]);
    env.wait_status("the input off", |s| {
        s["io"]["digital_inputs"].as_u64().unwrap() & (1 << TEST_INPUT) == 0
    });
    let program = env.write("m66-timeout.ngc", &m66_program(0.5));
    let csv = env.path("timeout.csv");
    env.run_ok("run-off", &program, &["--record", csv.to_str().unwrap()]);
    let s = env.status();
    assert_finished(&s);
    assert_at(&s, [0.0, 2.0, 0.0], "the else branch's end");
    assert_eq!(f64_of(&s["input_result"]["value"]), -1.0, "{s}");
    // The else branch's move (line 6) started only after the 0.5 s timeout.
    let rows = read_csv(&csv);
    let first = first_moving_row_of(&rows, 6).expect("line 6 moves");
    assert!(
        first.t >= 0.5 - 0.01,
        "the else branch moved at t = {}",
        first.t
    );
    // Before it, at rest where the last program ended, the rows name no line of this
    // program but the M66's (2), or none (0): line 4, the if branch, never ran.
    for r in rows.iter().take_while(|r| r.t < first.t) {
        assert_eq!(r.position, [2.0, 0.0, 0.0], "{r:?}");
        assert!(
            r.line == 0 || r.line == 2,
            "a row while waiting on the input names line {}: {r:?}",
            r.line
        );
    }
}

#[test]
fn outputs_and_coolant_are_switched_and_m2_switches_coolant_off() {
    let env = Env::new("io", &[]);
    let _daemon = env.start_daemon("kerfd");
    let s = env.status();
    assert_eq!(s["io"]["digital_outputs"], 0, "{s}");
    assert_eq!(s["coolant"]["flood"], false, "{s}");
    // Flood is digital output 1 ([coolant] flood = "flood"), clamp output 2, laser_power
    // analog output 0. M67 applies with the next move (line 5).
    let program = env.write(
        "io.ngc",
        "G21 G90\nM8\nM64 P2\nM67 E0 Q3.5\nG1 X1 F3000\nM0\nG1 X0\nM2\n",
    );
    let mut run = env.spawn_run("run", &program, &[]);
    env.wait_pause(&mut run, "program_stop");
    let s = env.rest_in_pause(&mut run, "program_stop");
    assert_at(&s, [1.0, 0.0, 0.0], "paused at the M0");
    assert_eq!(s["coolant"]["flood"], true, "{s}");
    assert_eq!(s["coolant"]["mist"], false, "{s}");
    assert_eq!(
        s["io"]["digital_outputs"].as_u64().unwrap(),
        (1 << 1) | (1 << 2),
        "outputs 1 (flood) and 2 (M64 P2): {s}"
    );
    let analog = s["io"]["analog_outputs"].as_array().unwrap();
    assert_eq!(analog.len(), 16, "{s}");
    assert_eq!(f64_of(&analog[0]), 3.5, "{s}");
    let text = String::from_utf8(env.kerf("status", &[]).stdout).unwrap();
    assert!(text.contains("coolant: flood"), "{text}");
    assert!(text.contains("outputs on: 1,2"), "{text}");

    env.kerf_ok("resume", &[]);
    let status = wait(&mut run, 1);
    assert!(
        status.success(),
        "kerf run failed ({status}): {}",
        run.stderr()
    );
    let s = env.status();
    assert_finished(&s);
    // [coolant] off_at_end: M2 switches the flood output off.
    assert_eq!(s["coolant"]["flood"], false, "{s}");
    assert_eq!(
        s["io"]["digital_outputs"].as_u64().unwrap() & (1 << 1),
        0,
        "the flood output after M2: {s}"
    );
}

// ---------------------------------------------------------------------------------------
// Spindle
// ---------------------------------------------------------------------------------------

#[test]
fn feed_moves_wait_for_the_spindle_at_speed_and_the_override_changes_its_speed() {
    let env = Env::new("spindle", &[]);
    let _daemon = env.start_daemon("kerfd");
    // Line 2: a rapid; line 3 starts the spindle; line 4, a rapid, does not wait for it;
    // line 5, the first feed move, waits until it is at speed; line 6 is 3 s of feed.
    let program = env.write(
        "spindle.ngc",
        "G21 G90 G64 P0.01
G0 X1
S12000 M3
G0 X2
G1 X4 F600
G1 X34
M2
",
    );
    let csv = env.path("spindle.csv");
    let mut run = env.spawn_run("run", &program, &["--record", csv.to_str().unwrap()]);

    // While the spindle ramps up, the program waits for it at line 5.
    let mut ramping = Vec::new();
    let s = env.wait_status_while(&mut run, "the spindle at speed", |s| {
        if s["spindle"]["at_speed"] == false && s["spindle"]["dir"] == 1 {
            ramping.push(s.clone());
        }
        s["spindle"]["dir"] == 1 && s["spindle"]["at_speed"] == true
    });
    assert_eq!(f64_of(&s["spindle"]["programmed_rpm"]), 12000.0, "{s}");
    assert_eq!(f64_of(&s["spindle"]["commanded_rpm"]), 12000.0, "{s}");
    let actual = f64_of(&s["spindle"]["actual_rpm"]);
    assert!(
        (actual - 12000.0).abs() <= AT_SPEED_BAND * 12000.0,
        "at speed at {actual} rpm: {s}"
    );
    assert!(!ramping.is_empty(), "no status during the 1.5 s ramp");
    assert!(
        ramping
            .iter()
            .any(|r| r["pause"]["reason"] == "spindle_at_speed" && r["pause"]["line"] == 5),
        "no wait for at-speed at line 5 seen: {:?}",
        ramping.last()
    );
    for r in &ramping {
        // Below speed, nothing of the feed moves has moved.
        assert!(
            position(r)[0] <= 2.0 + EPS_MM,
            "a feed move ran below speed: {r}"
        );
        assert_eq!(r["spindle"]["at_speed"], false);
    }

    // The spindle override while the feed runs: half the speed.
    env.wait_status_while(&mut run, "the feed move of line 6", |s| s["line"] == 6);
    env.kerf_ok("spindle-override", &["50"]);
    let s = env.wait_status_while(&mut run, "the override", |s| {
        f64_of(&s["spindle"]["override_pct"]) == 50.0
    });
    assert_eq!(f64_of(&s["spindle"]["commanded_rpm"]), 6000.0, "{s}");
    assert_eq!(f64_of(&s["spindle"]["programmed_rpm"]), 12000.0, "{s}");
    let s = env.wait_status_while(&mut run, "the spindle at 6000 rpm", |s| {
        (f64_of(&s["spindle"]["actual_rpm"]) - 6000.0).abs() <= AT_SPEED_BAND * 6000.0
            && s["spindle"]["at_speed"] == true
    });
    assert_eq!(program_end(&s), "running", "{s}");
    let status = wait(&mut run, 1);
    assert!(
        status.success(),
        "kerf run failed ({status}): {}",
        run.stderr()
    );
    let s = env.status();
    assert_finished(&s);
    assert_at(&s, [34.0, 0.0, 0.0], "at the end");
    // [spindle] off_at_end.
    assert_eq!(s["spindle"]["dir"], 0, "{s}");
    assert_eq!(f64_of(&s["spindle"]["commanded_rpm"]), 0.0, "{s}");

    // From the recording: the rapid of line 4 starts as soon as the rapid of line 2 has
    // ended (no wait), the feed of line 5 only once the spindle can have reached the band
    // from rest: 12000 * (1 - 0.02) / 8000 rpm/s = 1.47 s after the M3.
    let rows = read_csv(&csv);
    let rapid_end = last_moving_row_of(&rows, 2).expect("line 2 moves").t;
    let rapid_start = first_moving_row_of(&rows, 4).expect("line 4 moves").t;
    let feed_start = first_moving_row_of(&rows, 5).expect("line 5 moves").t;
    let ramp_s = 12000.0 * (1.0 - AT_SPEED_BAND) / SPINDLE_ACCEL_RPM_S;
    assert!(
        rapid_start - rapid_end < 0.05,
        "the rapid after M3 waited: line 2 ended at {rapid_end} s, line 4 began at {rapid_start} s"
    );
    assert!(
        feed_start - rapid_end >= ramp_s - 0.01,
        "the feed began {} s after the M3, before the spindle could be at speed ({ramp_s} s)",
        feed_start - rapid_end
    );
    // And not much later than at speed plus the rapid's own time.
    let rapid_s = last_moving_row_of(&rows, 4).unwrap().t - rapid_start;
    assert!(
        feed_start - rapid_end <= ramp_s.max(rapid_s) + 0.2,
        "the feed began {} s after the M3 (ramp {ramp_s} s)",
        feed_start - rapid_end
    );
}

// ---------------------------------------------------------------------------------------
// Tool changes
// ---------------------------------------------------------------------------------------

/// Comments out the automatic changer's keys of the bundled configuration.
const NO_AUTOMATIC_KEYS: [(&str, &str); 4] = [
    (
        "number_output = \"tool_number\"",
        "# number_output = \"tool_number\"",
    ),
    (
        "change_output = \"tool_change\"",
        "# change_output = \"tool_change\"",
    ),
    (
        "changed_input = \"tool_changed\"",
        "# changed_input = \"tool_changed\"",
    ),
    ("timeout_s = 30.0", "# timeout_s = 30.0"),
];

#[test]
fn manual_tool_change_pauses_and_the_tool_survives_a_daemon_restart() {
    let mut edits = vec![
        ("kind = \"automatic\"", "kind = \"manual\""),
        (
            "[[tools]]\nnumber = 1",
            "[[tools]]\nnumber = 3\nlength_mm = 45.2\nradius_mm = 0.0\n\n[[tools]]\nnumber = 1",
        ),
    ];
    edits.extend(NO_AUTOMATIC_KEYS);
    let env = Env::new("manual", &edits);
    let mut daemon = env.start_daemon("kerfd");
    let s = env.status();
    assert_eq!(s["tool"]["changer"], "manual", "{s}");
    assert_eq!(s["tool"]["in_spindle"], 0, "{s}");

    let program = env.write("tool.ngc", "G21 G90\nG0 X1\nT3 M6\nG0 X2\nM2\n");
    let mut run = env.spawn_run("run", &program, &[]);
    env.wait_pause(&mut run, "tool_change");
    let s = env.rest_in_pause(&mut run, "tool_change");
    assert_eq!(state(&s), "paused", "{s}");
    assert_eq!(s["pause"]["line"], 3, "{s}");
    assert_eq!(s["pause"]["value"], 3, "{s}");
    assert_eq!(s["pause"]["waits_for_operator"], true, "{s}");
    let text = s["pause"]["text"].as_str().unwrap();
    assert!(text.contains("T3"), "{text}");
    assert!(text.contains("45.2"), "the tool's length: {text}");
    assert_at(&s, [1.0, 0.0, 0.0], "paused for the tool");
    assert_eq!(s["tool"]["in_spindle"], 0, "before the confirmation: {s}");
    env.wait_stderr(&mut run, "kerf: paused at line 3 (M6): ");

    env.kerf_ok("resume", &[]);
    let status = wait(&mut run, 1);
    assert!(
        status.success(),
        "kerf run failed ({status}): {}",
        run.stderr()
    );
    let s = env.status();
    assert_finished(&s);
    assert_at(&s, [2.0, 0.0, 0.0], "at the end");
    assert_eq!(s["tool"]["in_spindle"], 3, "{s}");
    assert_eq!(f64_of(&s["tool"]["length_mm"]), 45.2, "{s}");
    assert!(
        env.path("state.toml").is_file(),
        "no state file in the test's directory"
    );

    // Killed without a chance to save anything: the tool was kept when it changed.
    daemon.signal("KILL");
    let _ = wait(&mut daemon, 1);
    drop(daemon);
    let _daemon = env.start_daemon("kerfd-again");
    let s = env.status();
    assert_eq!(s["tool"]["in_spindle"], 3, "after the restart: {s}");
    assert_eq!(f64_of(&s["tool"]["length_mm"]), 45.2, "{s}");
}

#[test]
fn m6_without_a_tool_changer_is_refused_before_motion() {
    let mut edits = vec![("kind = \"automatic\"", "kind = \"none\"")];
    edits.extend(NO_AUTOMATIC_KEYS);
    let env = Env::new("nochanger", &edits);
    let _daemon = env.start_daemon("kerfd");
    assert_eq!(env.status()["tool"]["changer"], "none");
    let program = env.write("tool.ngc", "G21 G90\nG0 X1\nT1 M6\nG0 X2\nM2\n");
    let o = env.kerf("run", &[program.to_str().unwrap()]);
    assert!(!o.status.success(), "M6 without a changer was accepted");
    let err = stderr_of(&o);
    assert!(
        err.contains(&format!("{}:3:", program.display())) && err.contains(": error: "),
        "{err}"
    );
    assert!(err.contains("M6"), "{err}");
    let s = env.status();
    assert_at(&s, [0.0, 0.0, 0.0], "after the refusal");
    assert_eq!(program_end(&s), "none", "a program was started: {s}");
}

// ---------------------------------------------------------------------------------------
// Refused before motion
// ---------------------------------------------------------------------------------------

#[test]
fn programs_asking_what_the_machine_lacks_are_refused_before_motion() {
    // The test machine has no mist coolant.
    let env = Env::new("refuse", &[("mist = \"mist\"", "# mist = \"mist\"")]);
    let _daemon = env.start_daemon("kerfd");
    for (name, code, words) in [
        ("output", "M62 P40", ["M62", "40"]),
        ("mist", "M7", ["M7", "mist"]),
        ("speed", "S99999 M3", ["99999", "24000"]),
    ] {
        // The bad block is line 3, after a move that must not run.
        let program = env.write(
            &format!("{name}.ngc"),
            &format!("G21 G90\nG1 X1 F3000\n{code}\nG1 X2\nM2\n"),
        );
        let o = env.kerf("run", &[program.to_str().unwrap()]);
        assert!(!o.status.success(), "{name}: `{code}` was accepted");
        let err = stderr_of(&o);
        assert!(
            err.contains(&format!("{}:3:1: error: ", program.display())),
            "{name}: {err}"
        );
        for w in words {
            assert!(err.contains(w), "{name}: no `{w}` in: {err}");
        }
        let s = env.status();
        assert_at(&s, [0.0, 0.0, 0.0], name);
        assert_eq!(
            program_end(&s),
            "none",
            "{name}: a program was started: {s}"
        );
        assert_eq!(state(&s), "idle", "{name}: {s}");
    }
}

// ---------------------------------------------------------------------------------------
// Run from line
// ---------------------------------------------------------------------------------------

/// A pocket with a tool, spindle and coolant; starts and ends at the origin.
const FROM_LINE_PROGRAM: &str = "G21 G90 G64 P0.01
T1 M6
S8000 M3
M8
G0 X5 Y5 Z2
G1 Z-1 F1200
G1 X15 F3000
G1 Y15
G1 X5
G1 Y5
G0 Z2
G0 X0 Y0 Z0
M2
";

/// The line run from, and where it starts (the end of line 7).
const FROM_LINE: u32 = 8;
const FROM_LINE_START: [f64; 3] = [15.0, 5.0, -1.0];

/// The test machine's Z travel is shortened to 20 mm above zero, so that the approach's
/// retract to the top of the travel is short.
const SHORT_Z: (&str, &str) = (
    "min_mm = -500.0\nmax_mm = 500.0",
    "min_mm = -50.0\nmax_mm = 20.0",
);
const Z_TOP_MM: f64 = 20.0;

/// The configuration's default path tolerance (`tolerance_mm`), mm.
const TOLERANCE_MM: f64 = 0.01;

#[test]
fn run_from_line_approaches_safely_and_follows_the_full_runs_path() {
    let env = Env::new("fromline", &[SHORT_Z]);
    let _daemon = env.start_daemon("kerfd");
    let program = env.write("pocket.ngc", FROM_LINE_PROGRAM);

    let full_csv = env.path("full.csv");
    env.run_ok("full", &program, &["--record", full_csv.to_str().unwrap()]);
    let s = env.status();
    assert_finished(&s);
    assert_at(&s, [0.0; 3], "the full run's end");
    assert_eq!(s["tool"]["in_spindle"], 1, "{s}");

    // Run from line 8, watching the status: spindle and coolant before the cut.
    let from_csv = env.path("from.csv");
    let n = FROM_LINE.to_string();
    let mut run = env.spawn_run(
        "from",
        &program,
        &["--from-line", &n, "--record", from_csv.to_str().unwrap()],
    );
    let mut seen = Vec::new();
    let deadline = Instant::now() + PATIENCE * 2;
    let status = loop {
        if let Some(status) = run.try_wait() {
            break status;
        }
        assert!(
            Instant::now() < deadline,
            "kerf run --from-line did not end"
        );
        seen.push(env.status());
        std::thread::sleep(POLL);
    };
    assert!(
        status.success(),
        "kerf run --from-line failed ({status}): {}",
        run.stderr()
    );
    let s = env.status();
    assert_finished(&s);
    assert_at(&s, [0.0; 3], "the from-line run's end");
    // Below the part's surface (Z < 0: the last of the approach and the cuts), the
    // spindle turns clockwise at speed at 8000 rpm and the flood is on.
    let below: Vec<&Value> = seen
        .iter()
        .filter(|s| program_end(s) == "running" && position(s)[2] < -EPS_MM)
        .collect();
    assert!(!below.is_empty(), "no status seen below Z0");
    for s in &below {
        assert_eq!(s["spindle"]["dir"], 1, "{s}");
        assert_eq!(f64_of(&s["spindle"]["commanded_rpm"]), 8000.0, "{s}");
        assert_eq!(s["spindle"]["at_speed"], true, "{s}");
        assert_eq!(s["coolant"]["flood"], true, "{s}");
    }
    // Restored before the first cut: seen on, above the start of line 8, before any
    // status shows the cut of line 8 (Y beyond 5).
    let first_cut = seen
        .iter()
        .position(|s| position(s)[1] > FROM_LINE_START[1] + EPS_MM)
        .expect("a status during the cut");
    assert!(
        seen[..first_cut].iter().any(|s| {
            s["spindle"]["dir"] == 1
                && f64_of(&s["spindle"]["commanded_rpm"]) == 8000.0
                && s["coolant"]["flood"] == true
        }),
        "spindle and flood were not seen on before the cut"
    );
    // No tool change: tool 1 was in the spindle already.
    assert!(
        seen.iter().all(|s| s["pause"]["reason"] != "tool_changing"),
        "the approach changed the tool that was in the spindle"
    );

    let full = read_csv(&full_csv);
    let from = read_csv(&from_csv);
    // Both start at the origin and end at the same place.
    assert_eq!(full[0].position, [0.0; 3]);
    assert_eq!(from[0].position, [0.0; 3]);
    let (full_end, from_end) = (full.last().unwrap(), from.last().unwrap());
    assert!(
        near(full_end.position, from_end.position, 1e-9),
        "{full_end:?} {from_end:?}"
    );
    // The approach: the rows up to the last one before the cut of line 8 (Y beyond 5)
    // begins, which stands at the start of line 8 (an exact stop: the sampled setpoints
    // come within a micrometre of the corner).
    let reached = from
        .iter()
        .position(|r| r.position[1] > FROM_LINE_START[1] + 1e-9)
        .expect("the from-line run cuts along Y")
        - 1;
    assert!(
        near(from[reached].position, FROM_LINE_START, 1e-5),
        "the cut began at {:?}, not at the start of line 8",
        from[reached]
    );
    let approach = &from[..reached];
    assert!(
        approach.iter().skip(1).all(|r| r.line == FROM_LINE),
        "approach rows of other lines"
    );
    // Safe: X and Y move only at the top of the Z travel; it never goes below the start;
    // the last 5 mm down are at line 8's feed, F3000 = 50 mm/s (1 % for rounding).
    for r in approach {
        let [x, y, z] = r.position;
        let at_origin = x.abs() < 1e-9 && y.abs() < 1e-9;
        let above_start =
            (x - FROM_LINE_START[0]).abs() < 1e-9 && (y - FROM_LINE_START[1]).abs() < 1e-9;
        assert!(
            at_origin || above_start || (z - Z_TOP_MM).abs() < 1e-9,
            "the approach moves in X/Y below the top of the travel: {r:?}"
        );
        assert!(z >= FROM_LINE_START[2] - 1e-9, "below the start: {r:?}");
        if above_start && z < FROM_LINE_START[2] + 5.0 - 1e-6 {
            assert!(r.feed_mm_s <= 50.0 * 1.01, "the last 5 mm too fast: {r:?}");
        }
    }
    assert!(
        approach
            .iter()
            .any(|r| (r.position[2] - Z_TOP_MM).abs() < 1e-9),
        "the approach never retracted to the top"
    );
    // From the start of line 8 on, the from-line run lies on the full run's path of lines
    // 8 and later (within the tolerance of the full run's corner blend at line 8's start,
    // plus 0.01 mm).
    let path: Vec<[f64; 3]> = full
        .iter()
        .filter(|r| r.line >= FROM_LINE)
        .map(|r| r.position)
        .collect();
    assert!(path.len() > 100, "the full run's rows of line 8 on");
    let tol = 0.01 + TOLERANCE_MM;
    let mut worst = (0.0f64, 0usize);
    for (i, r) in from[reached..].iter().enumerate() {
        let d = polyline_distance(r.position, &path);
        if d > worst.0 {
            worst = (d, reached + i);
        }
    }
    assert!(
        worst.0 <= tol,
        "row {} of the from-line run ({:?}) is {} mm from the full run's path",
        worst.1,
        from[worst.1],
        worst.0
    );
    // And it covers that path: the full run's rows of line 8 on are near the from run's.
    let from_path: Vec<[f64; 3]> = from[reached..].iter().map(|r| r.position).collect();
    for p in path.iter().step_by(20) {
        let d = polyline_distance(*p, &from_path);
        assert!(
            d <= tol,
            "the full run's {p:?} is {d} mm from the from-line run"
        );
    }

    // A line beyond the program is refused, naming it.
    let o = env.kerf("run", &["--from-line", "9999", program.to_str().unwrap()]);
    assert!(!o.status.success(), "--from-line 9999 was accepted");
    let err = stderr_of(&o);
    assert!(err.contains("9999") && err.contains("error"), "{err}");
    let s = env.status();
    assert_at(&s, [0.0; 3], "after the refusal");
}

/// A `kerf run` that goes away while its program waits at a pause: the program (all of it
/// sent) stays paused, `kerf resume` continues it, and the daemon runs it to its end.
#[test]
fn a_pause_survives_the_kerf_run_that_sent_the_program() {
    let env = Env::new("gone", &[]);
    let _daemon = env.start_daemon("kerfd");
    let program = env.write("gone.ngc", "G21 G90\nG1 X2 F3000\nM0\nG1 X4 Y2\nM2\n");
    let mut run = env.spawn_run("run", &program, &[]);
    env.wait_pause(&mut run, "program_stop");
    run.signal("KILL");
    let killed = wait(&mut run, 1);
    assert!(!killed.success(), "kerf run ended by itself: {killed}");
    // Still paused at the M0, with nobody attached.
    let s = env.status();
    assert_eq!(state(&s), "paused", "{s}");
    assert_eq!(s["pause"]["line"], 3, "{s}");
    assert_at(&s, [2.0, 0.0, 0.0], "paused at the M0");
    env.kerf_ok("resume", &[]);
    let deadline = Instant::now() + PATIENCE;
    let s = loop {
        let s = env.status();
        if program_end(&s) != "running" {
            break s;
        }
        assert!(Instant::now() < deadline, "the program did not end: {s}");
        std::thread::sleep(POLL);
    };
    assert_finished(&s);
    assert_at(&s, [4.0, 2.0, 0.0], "at the program's end");
}
