//! Multi-process tests of the daemon `kerfd` and the commands that talk to it (`kerf run`,
//! `status`, `hold`, `resume`, `abort`, `override`, `record`), with the built binaries.
//!
//! Every test writes its own machine configuration (a copy of `config/kerf.toml` with a
//! machine name unique to the test and this process) into its own directory, so the
//! iceoryx2 services (`kerf/<machine>/…`) of tests running in parallel never meet. Child
//! processes live in [`Proc`] guards that stop them (SIGTERM, then SIGKILL) and reap them
//! on drop; the directories are removed on drop.
//!
//! No assertion is about wall-clock time: status is polled with generous time-outs only so
//! that a broken daemon fails the test instead of hanging it. What is asserted is measured
//! from the outputs: the recorded setpoint streams (compared with `kerf sim`'s CSV, and
//! checked against the machine's limits by finite differences and against the programmed
//! path by a nearest-distance search), the status the daemon reports and the commands' exit
//! codes and messages.
//!
//! This file holds the shared set-up and checks; the tests are in `daemon/`, by theme
//! (`streams`, `control`, `failures`, `start`), one test binary.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Output, Stdio};
use std::time::{Duration, Instant};

use kerf_config::Config;
use kerf_gcode::{Dialect, Interpreter, Item, Settings};
use kerf_geom::{CornerMode, Curve, Move, Vec3};
use kerf_motion::monitor::LimitMonitor;
use serde_json::Value;

const KERF: &str = env!("CARGO_BIN_EXE_kerf");
mod common;
use common::{Proc, kerfd, read_text};

/// Upper bound on any wait, so that a broken daemon fails a test instead of hanging it.
const PATIENCE: Duration = Duration::from_secs(30);

/// How often status is polled.
const POLL: Duration = Duration::from_millis(10);

/// Room for rounding in the path check, mm.
const PATH_ROUNDING_MM: f64 = 1e-6;

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

/// One test's machine: a scratch directory with its configuration file.
struct Env {
    dir: PathBuf,
    config_path: PathBuf,
    config: Config,
    machine: String,
}

impl Env {
    /// A machine named `t<pid>_<tag>`, with `edits` (pairs of text to find and replace)
    /// applied to the bundled configuration.
    fn new(tag: &str, edits: &[(&str, &str)]) -> Env {
        let machine = format!("t{}_{tag}", std::process::id());
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
            .join("kerf-daemon-tests")
            .join(&machine);
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let mut text = kerf_testkit::config_text::without_homing(
            &fs::read_to_string(root.join("config/kerf.toml")).unwrap(),
        );
        let mut all = vec![("machine = \"default\"", format!("machine = \"{machine}\""))];
        for (from, to) in edits {
            all.push((from, to.to_string()));
        }
        for (from, to) in all {
            assert!(text.contains(from), "config/kerf.toml has no `{from}`");
            text = text.replacen(from, &to, 1);
        }
        let config_path = dir.join("kerf.toml");
        fs::write(&config_path, text).unwrap();
        let config = Config::load(&config_path).unwrap();
        assert_eq!(config.machine, machine);
        Env {
            dir,
            config_path,
            config,
            machine,
        }
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

    /// `kerf SUBCOMMAND --config C ARGS…`, to completion.
    ///
    /// A command that has not exited after [`PATIENCE`] is killed and the test fails,
    /// rather than hang: a `kerf status` that waited without end inside iceoryx2 (see
    /// `a_service_segment_left_empty_by_a_killed_creator_stops_nothing`) once held a whole
    /// CI run until it was stopped.
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

    /// Starts `kerfd` and waits until `kerf status` answers.
    fn start_daemon(&self, name: &str) -> Proc {
        self.start_daemon_with(name, &[])
    }

    /// Starts `kerfd --config C EXTRA…` and waits until `kerf status` answers.
    fn start_daemon_with(&self, name: &str, extra: &[&str]) -> Proc {
        let mut args = vec!["--config", self.config_arg()];
        args.extend_from_slice(extra);
        let mut d = spawn(name, &self.dir, kerfd(), &args);
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
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8(out.stdout).unwrap();
        serde_json::from_str(text.trim()).unwrap_or_else(|e| panic!("not JSON ({e}): {text}"))
    }

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

    /// Waits until the daemon has run `extra` more cycles (so that a recorder has taken
    /// everything up to now).
    fn wait_cycles(&self, extra: u64) {
        let start = cycles(&self.status());
        self.wait_status("cycles to pass", |s| cycles(s) >= start + extra);
    }

    /// Starts `kerf record` into `name` and waits until it writes rows.
    fn start_record(&self, name: &str) -> (Proc, PathBuf) {
        let out = self.path(name);
        let mut p = spawn(
            &format!("record-{name}"),
            &self.dir,
            KERF,
            &[
                "record",
                "--config",
                self.config_arg(),
                "--out",
                out.to_str().unwrap(),
            ],
        );
        let deadline = Instant::now() + PATIENCE;
        while read_text(&out).lines().count() < 2 {
            if let Some(status) = p.try_wait() {
                panic!("kerf record exited at start ({status}): {}", p.stderr());
            }
            assert!(Instant::now() < deadline, "kerf record wrote no rows");
            std::thread::sleep(POLL);
        }
        (p, out)
    }

    /// `kerf run --config C [--record F] PROGRAM`, in the background.
    fn spawn_run(&self, name: &str, program: &Path, record: Option<&Path>) -> Proc {
        let mut args = vec!["run", "--config", self.config_arg()];
        if let Some(r) = record {
            args.push("--record");
            args.push(r.to_str().unwrap());
        }
        args.push(program.to_str().unwrap());
        spawn(name, &self.dir, KERF, &args)
    }

    /// `kerf run`, to completion; asserts exit 0.
    fn run_ok(&self, name: &str, program: &Path, record: Option<&Path>) {
        let mut p = self.spawn_run(name, program, record);
        let status = wait(&mut p, 2);
        assert!(
            status.success(),
            "kerf run {name} failed ({status}): {}",
            p.stderr()
        );
    }

    /// `kerf sim --config C PROGRAM --out name`: the CSV.
    fn sim(&self, program: &Path, name: &str) -> PathBuf {
        let out = self.path(name);
        let o = self.kerf(
            "sim",
            &[program.to_str().unwrap(), "--out", out.to_str().unwrap()],
        );
        assert!(
            o.status.success(),
            "kerf sim failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        out
    }

    /// The resolved moves of `program` started at `start`.
    fn moves(&self, program: &str, start: [f64; 6]) -> Vec<Move> {
        let mut settings: Settings = self.config.settings();
        settings.start_mm_deg = start;
        Interpreter::new(program.as_bytes(), Dialect::LinuxCnc, settings)
            .filter_map(|item| match item.unwrap() {
                Item::Move(m) => Some(m),
                Item::Event(_) => None,
            })
            .collect()
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

fn position(s: &Value) -> [f64; 6] {
    let p = &s["position"];
    [
        p["x"].as_f64().unwrap(),
        p["y"].as_f64().unwrap(),
        p["z"].as_f64().unwrap(),
        0.0,
        0.0,
        0.0,
    ]
}

fn moved(s: &Value) -> bool {
    position(s) != [0.0; 6]
}

// ---------------------------------------------------------------------------------------
// Recorded streams
// ---------------------------------------------------------------------------------------

/// One CSV row: `t,x,y,z,line,feed_mm_s`.
#[derive(Clone, Debug)]
struct Row {
    t: f64,
    position: [f64; 6],
    line: u32,
    feed_mm_s: f64,
    /// Everything after `t` exactly as written.
    rest: String,
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
                position: [num(f[1]), num(f[2]), num(f[3]), 0.0, 0.0, 0.0],
                line: f[4].parse().unwrap_or_else(|_| panic!("{path:?}: {l}")),
                feed_mm_s: num(f[5]),
                rest: l[f[0].len() + 1..].to_string(),
            }
        })
        .collect()
}

/// Every row's positions are finite and pass the per-axis velocity, acceleration and
/// jerk limits (finite differences at the period, 1 % margin plus rounding) from rest at
/// the first row; `t` advances by one period per row.
fn check_limits(env: &Env, rows: &[Row], what: &str) {
    assert!(!rows.is_empty(), "{what}: no rows");
    let limits = kerf_config::machine_limits(&env.config);
    let period_s = limits.period_s;
    let mut monitor = LimitMonitor::at_rest(&limits, &rows[0].position);
    for (i, r) in rows.iter().enumerate() {
        assert!(
            r.position.iter().all(|v| v.is_finite()) && r.feed_mm_s.is_finite(),
            "{what}: row {i} not finite: {r:?}"
        );
        if let Err(v) = monitor.check(&r.position) {
            panic!("{what}: row {i} (t = {}): {v}", r.t);
        }
        let expected_t = (i as f64) * period_s + rows[0].t;
        assert!(
            (r.t - expected_t).abs() < 1e-6,
            "{what}: row {i} at t = {}, expected {expected_t}",
            r.t
        );
    }
}

/// The largest path tolerance of the moves: their G64 P, or the configured default.
fn path_tolerance(env: &Env, moves: &[Move]) -> f64 {
    moves
        .iter()
        .map(|m| match m.corner {
            CornerMode::ExactStop => 0.0,
            CornerMode::Blend { tolerance_mm, .. } => {
                tolerance_mm.unwrap_or(env.config.tolerance_mm)
            }
        })
        .fold(0.0, f64::max)
}

/// Every recorded position lies within the path tolerance (plus rounding) of the
/// programmed moves: nearest distance over a window of moves around the last match, and
/// over all moves where the window finds none close enough.
fn check_path(env: &Env, rows: &[Row], moves: &[Move], what: &str) {
    assert!(!moves.is_empty(), "{what}: no moves");
    let tol = path_tolerance(env, moves) + PATH_ROUNDING_MM;
    let curves: Vec<Curve> = moves.iter().map(|m| Curve::from_path(&m.path)).collect();
    let nearest = |p: &Vec3, range: std::ops::Range<usize>| -> (f64, usize) {
        range
            .map(|i| (curves[i].distance_to(p), i))
            .fold((f64::INFINITY, 0), |a, b| if b.0 < a.0 { b } else { a })
    };
    let mut hint: usize = 0;
    let mut last: Option<[f64; 6]> = None;
    for (i, r) in rows.iter().enumerate() {
        if last == Some(r.position) {
            continue;
        }
        last = Some(r.position);
        let p = Vec3::new(r.position[0], r.position[1], r.position[2]);
        let window = hint.saturating_sub(32)..(hint + 128).min(curves.len());
        let (mut d, mut at) = nearest(&p, window);
        if d > tol {
            (d, at) = nearest(&p, 0..curves.len());
        }
        assert!(
            d <= tol,
            "{what}: row {i} {:?} is {d} mm from the path (tolerance {tol})",
            r.position
        );
        hint = at;
    }
}

/// Both checks.
fn check_stream(env: &Env, path: &Path, moves: &[Move], what: &str) -> Vec<Row> {
    let rows = read_csv(path);
    check_limits(env, &rows, what);
    check_path(env, &rows, moves, what);
    rows
}

/// Index of the first row whose position differs from the first row's.
fn first_moving(rows: &[Row]) -> usize {
    rows.iter()
        .position(|r| r.position != rows[0].position)
        .expect("no motion")
}

/// The `kerf record` stream holds the simulated program: after the rows at rest before
/// the program's first moving row, its rows equal `kerf sim`'s in the position, line and
/// feed columns, then it stays at the end.
fn assert_record_matches_sim(recorded: &[Row], sim: &[Row], what: &str) {
    let r0 = first_moving(recorded);
    let s0 = first_moving(sim);
    for r in &recorded[..r0] {
        assert_eq!(
            r.position, sim[0].position,
            "{what}: rest before the program"
        );
    }
    let n = sim.len() - s0;
    assert!(
        recorded.len() > r0 + n,
        "{what}: the recording ({} rows, motion from row {r0}) ends before the program's {n} rows",
        recorded.len()
    );
    for i in 0..n {
        assert_eq!(
            recorded[r0 + i].rest,
            sim[s0 + i].rest,
            "{what}: program row {} (sim t = {})",
            s0 + i,
            sim[s0 + i].t
        );
    }
    let end = sim.last().unwrap().position;
    for r in &recorded[r0 + n..] {
        assert_eq!(r.position, end, "{what}: after the program");
        assert_eq!(r.feed_mm_s, 0.0, "{what}: after the program");
    }
}

/// Stops `kerf record` with SIGINT; asserts it exits 0 (no gap).
fn stop_record(mut p: Proc) {
    p.signal("INT");
    let status = wait(&mut p, 1);
    assert!(
        status.success(),
        "kerf record failed ({status}): {}",
        p.stderr()
    );
}

// ---------------------------------------------------------------------------------------
// Programs
// ---------------------------------------------------------------------------------------

/// Lines, arcs and a helix; ends at the origin (about 2 s of motion).
const PART: &str = "G21 G90 G17 G64 P0.01
G1 X20 Y0 F6000
G1 Y20
G2 X40 Y20 I10 J0
G3 X40 Y40 I0 J10
G1 X0 Y40 Z-2
G2 X0 Y40 Z-4 I0 J-10
G0 Z5
G0 X0 Y0
G0 Z0
M2
";

/// Exact stops, a default-tolerance blend, a dwell and rapids; ends at the origin.
const POCKET: &str = "G21 G90 G61
G0 X10 Y10 Z2
G1 Z-1 F1200
G64
G1 X30 F4000
G1 Y30
G1 X10
G1 Y10
G4 P0.2
G0 Z5
G0 X0 Y0 Z0
M2
";

/// Long straight lines at 50 mm/s (room for a 150 % override); ends at the origin.
const LINES: &str = "G21 G90 G64 P0.01
G1 X60 F3000
G1 Y5
G1 X0
G1 Y10
G1 X60
G0 X0 Y0
M2
";

/// Dense CAM-style code: zig-zag passes over a surface of short G1 moves with
/// four-decimal coordinates, `G64 P0.01`, F3000; ends at the origin.
fn cam_program(passes: usize, steps: usize, step_mm: f64, feed_mm_min: f64) -> String {
    let z = |x: f64, y: f64| 0.4 * (x / 4.0).sin() * (y / 3.0 + 0.5).cos();
    let mut p = format!(
        "G21 G90 G17 G64 P0.01\nG1 X0 Y0 Z{:.4} F{feed_mm_min}\n",
        z(0.0, 0.0)
    );
    for pass in 0..passes {
        let y = pass as f64 * 1.5;
        if pass > 0 {
            let x = if pass % 2 == 1 {
                steps as f64 * step_mm
            } else {
                0.0
            };
            p.push_str(&format!("G1 X{x:.4} Y{y:.4} Z{:.4}\n", z(x, y)));
        }
        for k in 1..=steps {
            let i = if pass % 2 == 0 { k } else { steps - k };
            let x = i as f64 * step_mm;
            p.push_str(&format!("G1 X{x:.4} Y{y:.4} Z{:.4}\n", z(x, y)));
        }
    }
    p.push_str("G0 Z5\nG0 X0 Y0\nG0 Z0\nM2\n");
    p
}

// The tests, by theme.
#[path = "daemon/control.rs"]
mod control;
#[path = "daemon/failures.rs"]
mod failures;
#[path = "daemon/start.rs"]
mod start;
#[path = "daemon/streams.rs"]
mod streams;
