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

// ---------------------------------------------------------------------------------------
// Tests
// ---------------------------------------------------------------------------------------

#[test]
fn run_record_and_kerf_record_equal_kerf_sim() {
    let env = Env::new("rec", &[]);
    let _daemon = env.start_daemon("kerfd");
    let cam = cam_program(5, 600, 0.05, 3000.0);
    assert!(cam.lines().count() > 3000);
    for (name, text) in [("part", PART), ("pocket", POCKET), ("cam", cam.as_str())] {
        let program = env.write(&format!("{name}.ngc"), text);
        let sim = env.sim(&program, &format!("{name}-sim.csv"));
        let (record, recorded) = env.start_record(&format!("{name}-record.csv"));
        let run_csv = env.path(&format!("{name}-run.csv"));
        env.run_ok(name, &program, Some(&run_csv));
        env.wait_cycles(300);
        stop_record(record);

        let sim_bytes = fs::read(&sim).unwrap();
        let run_bytes = fs::read(&run_csv).unwrap();
        assert!(
            sim_bytes == run_bytes,
            "{name}: kerf run --record differs from kerf sim ({} and {} bytes)",
            run_bytes.len(),
            sim_bytes.len()
        );
        let moves = env.moves(text, [0.0; 6]);
        let sim_rows = check_stream(&env, &sim, &moves, &format!("{name} sim"));
        let rec_rows = check_stream(&env, &recorded, &moves, &format!("{name} record"));
        assert_record_matches_sim(&rec_rows, &sim_rows, name);
        let s = env.status();
        assert_eq!(state(&s), "idle", "{s}");
        assert_eq!(program_end(&s), "finished", "{s}");
    }
}

#[test]
fn hold_resume_override_and_abort_mid_program() {
    let env = Env::new("ctl", &[]);
    let _daemon = env.start_daemon("kerfd");

    // Refusals on an idle daemon.
    let hold = env.kerf("hold", &[]);
    assert!(!hold.status.success(), "hold when idle was accepted");
    let resume = env.kerf("resume", &[]);
    assert!(!resume.status.success(), "resume when idle was accepted");
    let over = env.kerf("override", &["250"]);
    assert!(!over.status.success(), "override 250 was accepted");
    assert_eq!(env.status()["override_pct"].as_f64(), Some(100.0));

    let (record, recorded) = env.start_record("record.csv");
    let mut moves = Vec::new();

    // Hold, then resume.
    let part = env.write("part.ngc", PART);
    moves.extend(env.moves(PART, [0.0; 6]));
    let mut run = env.spawn_run("run-hold", &part, None);
    env.wait_status("motion", |s| state(s) == "running" && moved(s));
    let o = env.kerf("hold", &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // At rest on hold: the same position over at least ten cycles.
    let mut before: Option<Value> = None;
    let held = env.wait_status("rest on hold", |s| {
        let rest = state(s) == "holding"
            && before
                .as_ref()
                .is_some_and(|b| position(b) == position(s) && cycles(s) >= cycles(b) + 10);
        before = Some(s.clone());
        rest
    });
    assert_eq!(program_end(&held), "running", "{held}");
    // A second planner process is turned away while the program holds.
    let o = env.kerf("run", &[env.write("other.ngc", LINES).to_str().unwrap()]);
    assert!(!o.status.success(), "a second kerf run was accepted");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("busy"), "{err}");
    let o = env.kerf("resume", &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let status = wait(&mut run, 1);
    assert!(status.success(), "{}", run.stderr());
    let s = env.status();
    assert_eq!(program_end(&s), "finished", "{s}");
    assert_eq!(position(&s), [0.0; 6]);

    // Override 50 %, then 150 %.
    let lines = env.write("lines.ngc", LINES);
    moves.extend(env.moves(LINES, [0.0; 6]));
    let lines_csv = env.path("lines-run.csv");
    let mut run = env.spawn_run("run-override", &lines, Some(&lines_csv));
    env.wait_status("motion", |s| state(s) == "running" && moved(s));
    assert!(env.kerf("override", &["50"]).status.success());
    let s = env.wait_status("override 50", |s| s["override_pct"].as_f64() == Some(50.0));
    assert_eq!(program_end(&s), "running", "{s}");
    env.wait_cycles(200);
    // 0 % stands still on the path until raised again.
    assert!(env.kerf("override", &["0"]).status.success());
    let mut before: Option<Value> = None;
    env.wait_status("rest at 0 %", |s| {
        let rest = before
            .as_ref()
            .is_some_and(|b| position(b) == position(s) && cycles(s) >= cycles(b) + 10);
        before = Some(s.clone());
        rest
    });
    assert!(env.kerf("override", &["150"]).status.success());
    let s = env.wait_status("override 150", |s| {
        s["override_pct"].as_f64() == Some(150.0)
    });
    assert_eq!(program_end(&s), "running", "{s}");
    let status = wait(&mut run, 1);
    assert!(status.success(), "{}", run.stderr());
    assert!(env.kerf("override", &["100"]).status.success());

    // Abort, then the next program.
    let cam = cam_program(4, 600, 0.05, 3000.0);
    let cam_path = env.write("cam.ngc", &cam);
    moves.extend(env.moves(&cam, [0.0; 6]));
    let mut run = env.spawn_run("run-abort", &cam_path, None);
    env.wait_status("motion", |s| state(s) == "running" && moved(s));
    let o = env.kerf("abort", &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let status = wait(&mut run, 1);
    assert!(!status.success(), "kerf run exited 0 after an abort");
    assert!(run.stderr().contains("aborted"), "{}", run.stderr());
    let s = env.wait_status("rest after the abort", |s| state(s) != "running");
    assert_eq!(state(&s), "idle", "{s}");
    assert_eq!(program_end(&s), "aborted", "{s}");
    let stop = position(&s);
    assert!(stop != [0.0; 6], "the abort came after the motion began");
    let o = env.kerf("hold", &[]);
    assert!(!o.status.success(), "hold after the abort was accepted");
    moves.extend(env.moves(PART, stop));
    env.run_ok("run-after-abort", &part, None);
    let s = env.status();
    assert_eq!(program_end(&s), "finished", "{s}");
    assert_eq!(state(&s), "idle", "{s}");
    env.wait_cycles(300);
    stop_record(record);

    let rows = check_stream(&env, &recorded, &moves, "record");
    // The hold stood still on the path in the middle of the first program.
    let first = first_moving(&rows);
    let longest_rest_mid_program = rows[first..]
        .windows(2)
        .take_while(|w| !(w[0].position == [0.0; 6] && w[1].position == [0.0; 6]))
        .fold((0usize, 0usize), |(run, best), w| {
            if w[0].position == w[1].position {
                (run + 1, best.max(run + 1))
            } else {
                (0, best)
            }
        })
        .1;
    assert!(
        longest_rest_mid_program >= 10,
        "no stop on hold in the recording ({longest_rest_mid_program} rows)"
    );
    // On the G1 lines (2 to 6) at F3000, the 150 % override ran faster than the
    // programmed 50 mm/s, and no faster than 75 mm/s.
    let lines_rows = read_csv(&lines_csv);
    let max_feed = lines_rows
        .iter()
        .filter(|r| (2..=6).contains(&r.line))
        .map(|r| r.feed_mm_s)
        .fold(0.0, f64::max);
    assert!(max_feed > 50.0 * 1.01, "max feed {max_feed} mm/s");
    assert!(max_feed <= 75.0 * 1.01, "max feed {max_feed} mm/s");
    check_stream(
        &env,
        &lines_csv,
        &env.moves(LINES, [0.0; 6]),
        "lines --record",
    );
}

#[test]
fn planner_killed_mid_stream() {
    // A small motion queue and window, so that the planner process is still streaming
    // (held back by flow control) when it is killed.
    let env = Env::new(
        "pk",
        &[
            ("queue_segments = 4096", "queue_segments = 64"),
            ("move_window = 4096", "move_window = 64"),
        ],
    );
    let _daemon = env.start_daemon("kerfd");
    let (record, recorded) = env.start_record("record.csv");
    let long = cam_program(20, 1000, 0.05, 6000.0);
    let total_moves = env.moves(&long, [0.0; 6]).len() as u64;
    let program = env.write("long.ngc", &long);
    let mut run = env.spawn_run("run", &program, None);
    let s = env.wait_status("motion", |s| state(s) == "running" && moved(s));
    assert!(
        s["moves_received"].as_u64().unwrap() + 1000 < total_moves,
        "the planner was not streaming any more: {s}"
    );
    run.signal("KILL");
    let _ = wait(&mut run, 1);

    let mut states = Vec::new();
    let s = env.wait_status("rest after the planner died", |s| {
        states.push(state(s).to_string());
        program_end(s) != "running"
    });
    assert_eq!(program_end(&s), "refused", "{s}");
    let fault = s["fault"].as_str().unwrap_or("");
    assert!(fault.contains("planner process"), "{s}");
    let s = env.wait_status("idle", |s| state(s) != "running" && state(s) != "starved");
    assert_eq!(state(&s), "idle", "{s}");
    for st in &states {
        assert!(
            ["running", "starved", "idle"].contains(&st.as_str()),
            "state {st} while coming to rest: {states:?}"
        );
    }
    // At rest at the end of a programmed move.
    let stop = position(&s);
    let all_moves = env.moves(&long, [0.0; 6]);
    let at_move_end = all_moves.iter().any(|m| {
        let e = m.path.end();
        (e.x - stop[0]).abs() < 1e-6 && (e.y - stop[1]).abs() < 1e-6 && (e.z - stop[2]).abs() < 1e-6
    });
    assert!(at_move_end, "stopped at {stop:?}, not at the end of a move");

    // The next program starts where the machine is.
    let next = env.write("next.ngc", LINES);
    env.run_ok("next", &next, None);
    let s = env.status();
    assert_eq!(program_end(&s), "finished", "{s}");
    env.wait_cycles(300);
    stop_record(record);
    let mut moves = all_moves;
    moves.extend(env.moves(LINES, stop));
    check_stream(&env, &recorded, &moves, "record");
}

#[test]
fn daemon_killed_then_restarted_without_clean_up() {
    let env = Env::new("dk", &[]);
    let mut daemon = env.start_daemon("kerfd");
    let (mut record, recorded) = env.start_record("record.csv");
    let cam = cam_program(4, 600, 0.05, 3000.0);
    let program = env.write("cam.ngc", &cam);
    let mut run = env.spawn_run("run", &program, None);
    env.wait_status("motion", |s| state(s) == "running" && moved(s));
    daemon.signal("KILL");
    let _ = wait(&mut daemon, 1);
    let status = wait(&mut run, 1);
    assert!(!status.success(), "kerf run exited 0 after the daemon died");
    let err = run.stderr();
    assert!(
        err.contains("stopped") && err.contains(&env.machine),
        "{err}"
    );
    // The recorder sees the stream stall (not a gap) and stops.
    let status = wait(&mut record, 1);
    assert!(!status.success());
    assert!(!record.stderr().contains("lost"), "{}", record.stderr());
    let rows = read_csv(&recorded);
    check_limits(&env, &rows, "record before the kill");
    check_path(
        &env,
        &rows,
        &env.moves(&cam, [0.0; 6]),
        "record before the kill",
    );

    // A new daemon with the same configuration, no clean-up in between.
    let mut daemon = env.start_daemon("kerfd-again");
    let s = env.status();
    assert_eq!(state(&s), "idle", "{s}");
    let (record, recorded) = env.start_record("record-again.csv");
    let part = env.write("part.ngc", PART);
    let run_csv = env.path("run-again.csv");
    env.run_ok("run-again", &part, Some(&run_csv));
    env.wait_cycles(300);
    stop_record(record);
    let sim = env.sim(&part, "part-sim.csv");
    assert!(fs::read(&sim).unwrap() == fs::read(&run_csv).unwrap());
    check_stream(&env, &recorded, &env.moves(PART, [0.0; 6]), "record again");
    // SIGINT at rest: exit 0.
    daemon.signal("INT");
    let status = wait(&mut daemon, 1);
    assert!(status.success(), "kerfd: {status}: {}", daemon.stderr());
}

/// Turns a valid move message into a bad one.
type Spoil = fn(&mut kerf_proto::MoveMsg);

/// A program published straight into the moves service: BEGIN at the machine's position,
/// one valid line, then `bad` (a message made from a second line), then END.
fn inject(env: &Env, program_id: u64, bad: impl FnOnce(&mut kerf_proto::MoveMsg)) -> [f64; 3] {
    let start = position(&env.status());
    let text = "G21 G90 G64 P0.01\nG1 X12 Y3 F3000\nG1 X20 Y10\nM2\n";
    let moves = env.moves(text, start);
    assert_eq!(moves.len(), 2);
    let node = kerfd::ipc::node(&format!("test-{}-{program_id}", std::process::id())).unwrap();
    let service = kerfd::ipc::open_moves(&node, &env.machine).unwrap();
    let publisher = kerfd::ipc::move_publisher(&service).unwrap();
    let mut second = kerf_proto::MoveMsg::from_move(program_id, 2, &moves[1]);
    bad(&mut second);
    for msg in [
        kerf_proto::MoveMsg::begin(program_id, start, 0),
        kerf_proto::MoveMsg::from_move(program_id, 1, &moves[0]),
        second,
        kerf_proto::MoveMsg::end(program_id, 2),
    ] {
        publisher.send_copy(msg).unwrap();
    }
    // The publisher stays until the daemon has ended the program (a vanished sender is
    // a fault of its own).
    env.wait_status("the injected program to end", |s| {
        s["program_id"].as_u64() == Some(program_id) && program_end(s) != "running"
    });
    let e = moves[0].path.end();
    [e.x, e.y, e.z]
}

#[test]
fn malformed_and_non_finite_moves_are_refused() {
    let env = Env::new("inj", &[]);
    let _daemon = env.start_daemon("kerfd");
    let (record, recorded) = env.start_record("record.csv");
    let mut moves = Vec::new();
    let base = (std::process::id() as u64) << 20;
    let cases: [(&str, Spoil); 6] = [
        ("non-finite end", |m| m.end_mm[1] = f64::NAN),
        ("wrong version", |m| m.version = 999),
        ("unknown kind", |m| m.kind = 77),
        ("outside the travel", |m| m.end_mm[0] = 5000.0),
        ("zero feed", |m| m.feed_mm_min = 0.0),
        ("sequence gap", |m| m.seq = 5),
    ];
    for (n, (what, bad)) in cases.into_iter().enumerate() {
        let before = env.status();
        let start = position(&before);
        moves.extend(env.moves("G21 G90 G64 P0.01\nG1 X12 Y3 F3000\nM2\n", start));
        let id = base + n as u64 + 1;
        let valid_end = inject(&env, id, bad);
        let s = env.wait_status("rest", |s| state(s) != "running");
        assert_eq!(program_end(&s), "refused", "{what}: {s}");
        assert!(
            s["rejected"].as_u64().unwrap() > before["rejected"].as_u64().unwrap(),
            "{what}: {s}"
        );
        assert!(
            s["fault"].as_str().is_some_and(|f| !f.is_empty()),
            "{what}: {s}"
        );
        let p = position(&s);
        for i in 0..3 {
            assert!(
                (p[i] - valid_end[i]).abs() < 1e-9,
                "{what}: at rest at {p:?}, not at the end of the valid line {valid_end:?}"
            );
        }
        // The next normal program runs.
        let back = env.write(&format!("back{n}.ngc"), "G21 G90\nG1 X0 Y0 Z0 F3000\nM2\n");
        moves.extend(env.moves("G21 G90\nG1 X0 Y0 Z0 F3000\nM2\n", p));
        env.run_ok(&format!("back{n}"), &back, None);
        let s = env.status();
        assert_eq!(program_end(&s), "finished", "{what}: {s}");
        assert_eq!(position(&s), [0.0; 6], "{what}");
    }
    env.wait_cycles(300);
    stop_record(record);
    let text = read_text(&recorded);
    assert!(
        !text.to_ascii_lowercase().contains("nan"),
        "NaN in the recording"
    );
    check_stream(&env, &recorded, &moves, "record");
}

#[test]
fn programs_back_to_back() {
    let env = Env::new("b2b", &[]);
    let _daemon = env.start_daemon("kerfd");
    let (record, recorded) = env.start_record("record.csv");
    let mut moves = Vec::new();

    // The first ends at the origin: the second records exactly as kerf sim.
    let part = env.write("part.ngc", PART);
    let pocket = env.write("pocket.ngc", POCKET);
    let part_csv = env.path("part-run.csv");
    let pocket_csv = env.path("pocket-run.csv");
    env.run_ok("part", &part, Some(&part_csv));
    env.run_ok("pocket", &pocket, Some(&pocket_csv));
    moves.extend(env.moves(PART, [0.0; 6]));
    moves.extend(env.moves(POCKET, [0.0; 6]));
    for (program, text, csv) in [(&part, PART, &part_csv), (&pocket, POCKET, &pocket_csv)] {
        let sim = env.sim(program, "sim.csv");
        assert!(
            fs::read(&sim).unwrap() == fs::read(csv).unwrap(),
            "{program:?}: kerf run --record differs from kerf sim"
        );
        check_stream(&env, csv, &env.moves(text, [0.0; 6]), "--record");
    }

    // The first ends elsewhere: the second starts there.
    let away = "G21 G90 G64 P0.01\nG1 X10 Y5 Z-1 F4000\nG2 X20 Y5 I5 J0\nM2\n";
    let away_path = env.write("away.ngc", away);
    env.run_ok("away", &away_path, None);
    moves.extend(env.moves(away, [0.0; 6]));
    let s = env.status();
    let here = position(&s);
    assert!(
        (here[0] - 20.0).abs() < 1e-9 && (here[1] - 5.0).abs() < 1e-9,
        "{s}"
    );
    let lines_csv = env.path("lines-run.csv");
    let lines = env.write("lines.ngc", LINES);
    env.run_ok("lines", &lines, Some(&lines_csv));
    moves.extend(env.moves(LINES, here));
    let lines_rows = read_csv(&lines_csv);
    assert_eq!(lines_rows[0].position, here);
    check_limits(&env, &lines_rows, "lines --record");
    check_path(&env, &lines_rows, &env.moves(LINES, here), "lines --record");

    env.wait_cycles(300);
    stop_record(record);
    check_stream(&env, &recorded, &moves, "record");
}

/// `kerf run --embedded --record run.csv PROGRAM` on `env`'s machine, which must succeed
/// with setpoints byte for byte `kerf sim`'s (`sim.csv`); the recorded file.
fn embedded_run_equal_to_sim(env: &Env, program: &Path) -> PathBuf {
    let run_csv = env.path("run.csv");
    let mut run = spawn(
        "run",
        &env.dir,
        KERF,
        &[
            "run",
            "--embedded",
            "--config",
            env.config_arg(),
            "--record",
            run_csv.to_str().unwrap(),
            program.to_str().unwrap(),
        ],
    );
    let status = wait(&mut run, 2);
    assert!(status.success(), "{}", run.stderr());
    let sim = env.sim(program, "sim.csv");
    assert!(
        fs::read(&sim).unwrap() == fs::read(&run_csv).unwrap(),
        "the daemon's setpoints differ from kerf sim's"
    );
    run_csv
}

#[test]
fn embedded_run_equals_kerf_sim() {
    let env = Env::new("emb", &[]);
    let program = env.write("part.ngc", PART);
    let run_csv = embedded_run_equal_to_sim(&env, &program);
    check_stream(
        &env,
        &run_csv,
        &env.moves(PART, [0.0; 6]),
        "--embedded --record",
    );
    // The daemon lived in that process only.
    assert_eq!(env.kerf("status", &[]).status.code(), Some(1));
}

#[test]
fn sigterm_stops_on_the_path_then_exits_0() {
    let env = Env::new("term", &[]);
    let mut daemon = env.start_daemon("kerfd");
    let (mut record, recorded) = env.start_record("record.csv");
    let program = env.write("lines.ngc", LINES);
    let mut run = env.spawn_run("run", &program, None);
    // At speed on the first line.
    env.wait_status("speed", |s| state(s) == "running" && position(s)[0] > 20.0);
    daemon.signal("TERM");
    let status = wait(&mut daemon, 1);
    assert!(status.success(), "kerfd: {status}: {}", daemon.stderr());
    let status = wait(&mut run, 1);
    assert!(
        !status.success(),
        "kerf run exited 0 though the daemon stopped"
    );
    // The recorder sees the stream end (no gap) and stops.
    let _ = wait(&mut record, 1);
    assert!(!record.stderr().contains("lost"), "{}", record.stderr());
    let rows = check_stream(&env, &recorded, &env.moves(LINES, [0.0; 6]), "record");
    // Stopped before the program's end (the origin), and at rest.
    let last = rows.last().unwrap();
    assert!(last.position != [0.0; 6], "{last:?}");
    let before = &rows[rows.len() - 2];
    let step_mm = (0..3)
        .map(|i| (last.position[i] - before.position[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    let speed_mm_s = step_mm / (env.config.period_us as f64 * 1e-6);
    assert!(
        speed_mm_s < 0.5,
        "still moving at {speed_mm_s} mm/s: {last:?}"
    );
}

#[test]
fn status_without_and_with_a_daemon() {
    let env = Env::new("st", &[]);
    // Every command that talks to a daemon: exit 1, naming the machine and how to start
    // a daemon.
    let program = env.write("part.ngc", PART);
    let program = program.to_str().unwrap();
    for (subcommand, args) in [
        ("status", &[][..]),
        ("status", &["--json"]),
        ("hold", &[]),
        ("resume", &[]),
        ("abort", &[]),
        ("override", &["50"]),
        ("run", &[program]),
        ("record", &["--out", "/dev/null", "--cycles", "1"]),
    ] {
        let o = env.kerf(subcommand, args);
        assert_eq!(o.status.code(), Some(1), "{subcommand} {args:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains(&env.machine) && err.contains("kerfd"),
            "{subcommand} {args:?}: {err}"
        );
    }

    let _daemon = env.start_daemon("kerfd");
    let s = env.status();
    assert_eq!(s["machine"].as_str(), Some(env.machine.as_str()));
    assert_eq!(state(&s), "idle");
    assert_eq!(s["line"].as_u64(), Some(0));
    assert_eq!(position(&s), [0.0; 6]);
    assert_eq!(s["override_pct"].as_f64(), Some(100.0));
    assert_eq!(s["queued_moves"].as_u64(), Some(0));
    assert_eq!(s["queued_s"].as_f64(), Some(0.0));
    // The daemon answers once its cycle runs (every port is up by then), and it keeps
    // running.
    let first = cycles(&s);
    assert!(first > 0, "{s}");
    env.wait_status("cycles", |s| cycles(s) > first);
    assert!(s["overruns"].as_u64().is_some());
    assert!(s["rt"].is_boolean());
    assert!(s["fault"].is_null());
    assert_eq!(s["program_id"].as_u64(), Some(0));
    assert_eq!(s["program_done"].as_bool(), Some(false));
    assert_eq!(program_end(&s), "none");
    assert_eq!(s["moves_received"].as_u64(), Some(0));
    assert_eq!(
        s["window_items"].as_u64(),
        Some(u64::from(env.config.daemon.move_window))
    );
    assert_eq!(s["rejected"].as_u64(), Some(0));
    assert_eq!(s["period_us"].as_f64(), Some(1000.0));
    let o = env.kerf("status", &[]);
    assert!(o.status.success());
    let line = String::from_utf8_lossy(&o.stdout);
    assert!(
        line.starts_with(&format!("{}: idle", env.machine)),
        "{line}"
    );
}

#[test]
fn a_period_outside_the_daemons_range_is_refused_before_anything_starts() {
    for period in ["50", "100", "20000"] {
        let env = Env::new(
            &format!("period{period}"),
            &[("period_us = 1000", &format!("period_us = {period}"))],
        );
        let out = Command::new(kerfd())
            .args(["--config", env.config_arg()])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "period {period}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("period_us") && err.contains("125 to 10000"),
            "period {period}: {err}"
        );
        // Nothing was created: no daemon answers for the machine.
        assert_eq!(env.kerf("status", &[]).status.code(), Some(1));
    }
}

#[test]
fn an_ethercat_bus_that_cannot_be_opened_is_refused_at_start() {
    // The example bus on `eth1`, which this machine does not have (or which is no EtherCAT
    // bus): the daemon names the interface and exits before serving anything.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let example = root.join("config/ethercat-example.toml");
    let out = Command::new(kerfd())
        .args(["--config", example.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("EtherCAT interface eth1"), "{err}");
}

#[test]
fn a_configuration_that_does_not_load_is_named() {
    let out = Command::new(kerfd())
        .args(["--config", "/nonexistent/kerf.toml"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("/nonexistent/kerf.toml"), "{err}");
}

#[test]
fn a_second_daemon_or_an_embedded_run_for_the_same_machine_is_refused() {
    let env = Env::new("twice", &[]);
    let _first = env.start_daemon("kerfd");
    let out = Command::new(kerfd())
        .args(["--config", env.config_arg()])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("already running") && err.contains(&env.machine),
        "{err}"
    );
    let program = env.write("part.ngc", PART);
    let out = env.kerf("run", &["--embedded", program.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("already running"), "{err}");
    // The first one still serves.
    assert!(env.kerf("status", &[]).status.success());
}

#[test]
fn a_daemon_killed_while_it_starts_leaves_nothing_that_stops_the_next() {
    let env = Env::new("startkill", &[]);
    // SIGKILL at staggered moments of the start-up: some before, some while, some after
    // the services are created.
    for i in 0..24u64 {
        let mut d = spawn(
            "kerfd-killed",
            &env.dir,
            kerfd(),
            &["--config", env.config_arg()],
        );
        std::thread::sleep(Duration::from_millis(2 + 4 * i));
        d.signal("KILL");
        wait(&mut d, 1);
    }
    // Files a killed creator left count as abandoned after 100 ms.
    std::thread::sleep(kerfd::ipc::UNFINISHED_AFTER * 2);
    let _daemon = env.start_daemon("kerfd");
    let program = env.write("short.ngc", "G21 G90\nG1 X2 Y1 F3000\nG0 X0 Y0\nM2\n");
    env.run_ok("run", &program, None);
}

#[test]
fn a_service_segment_left_empty_by_a_killed_creator_stops_nothing() {
    // A process killed between creating a service's shared-memory segment and sizing it
    // leaves the segment empty and write-only. iceoryx2 waits without end when it opens
    // one, and every process that creates a node opens the segments of dead nodes'
    // services to clean up after them: every later `kerf` command hung (a daemon test
    // that kills starting daemons left one, and another test's `kerf status` hung in CI).
    // Made here on purpose: a serving daemon's control service's dynamic segment emptied
    // as a killed creator leaves it, and the daemon killed.
    use iceoryx2::prelude::SemanticString as _;
    use std::os::unix::fs::PermissionsExt;
    let env = Env::new("emptyseg", &[]);
    let mut daemon = env.start_daemon("kerfd");
    // The segment is named after the service's unique id (`unique_value · 2⁶⁴ +
    // payload_value`), which its static file records.
    let services = iceoryx2::prelude::Config::global_config()
        .global
        .service_dir();
    let services = PathBuf::from(String::from_utf8_lossy(services.as_bytes()).into_owned());
    let wanted = format!("service_name = \"kerf/{}/control\"", env.machine);
    let id = fs::read_dir(&services)
        .unwrap()
        .flatten()
        .find_map(|e| {
            let text = fs::read_to_string(e.path()).ok()?;
            text.lines().any(|l| l == wanted).then_some(())?;
            let value = |key: &str| -> Option<u128> {
                let line = text.lines().find(|l| l.starts_with(key))?;
                line.split('=').nth(1)?.trim().parse().ok()
            };
            Some((value("unique_value")? << 64) + value("payload_value")?)
        })
        .expect("the control service's static file");
    let segment = fs::read_dir("/dev/shm")
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| {
            let name = p.file_name().unwrap().to_string_lossy();
            name.starts_with("iox2_") && name.ends_with(&format!("_{id}.dynamic"))
        })
        .expect("the control service's dynamic segment");
    fs::OpenOptions::new()
        .write(true)
        .open(&segment)
        .unwrap()
        .set_len(0)
        .unwrap();
    fs::set_permissions(&segment, fs::Permissions::from_mode(0o200)).unwrap();
    // Emptied while its daemon lives (which may die of it), so that no other process has
    // it mapped: every process that cleans up after dead nodes maps their segments, and
    // emptying one under it would be a SIGBUS there. Then the daemon dies.
    daemon.signal("KILL");
    let _ = wait(&mut daemon, 1);
    // `kerf status` says that no daemon answers (within `Env::kerf`'s patience) and the
    // segment is gone.
    let out = env.kerf("status", &[]);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("no kerfd answers"));
    assert!(!segment.exists(), "{segment:?} is still there");
    // A new daemon starts and runs a program.
    let _daemon = env.start_daemon("kerfd-again");
    let program = env.write("short.ngc", "G21 G90\nG1 X2 Y1 F3000\nG0 X0 Y0\nM2\n");
    env.run_ok("run", &program, None);
}

#[test]
fn run_keeps_linuxcnc_persistent_parameters_in_the_parameter_file() {
    // `[gcode] parameter_file`: read at program start, written by `kerf run` after a
    // program that ended normally (LinuxCNC's .var file). `kerf sim` never writes it.
    let env = Env::new(
        "var",
        &[(
            "# parameter_file = \"kerf.var\"",
            "parameter_file = \"kerf.var\"",
        )],
    );
    let var = env.path("kerf.var");
    let _daemon = env.start_daemon("kerfd");
    let first = env.write(
        "store.ngc",
        "G21 G90\nG10 L2 P2 X3\nG0 X1 Y2\nG28.1\nG0 X0 Y0\nM2\n",
    );
    let sim_csv = env.path("store.csv");
    let o = env.kerf(
        "sim",
        &[first.to_str().unwrap(), "--out", sim_csv.to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!var.exists(), "kerf sim wrote the parameter file");
    env.run_ok("run", &first, None);
    let text = read_text(&var);
    assert!(
        text.starts_with("5161\t1.000000\n5162\t2.000000\n5163\t0.000000\n"),
        "{text}"
    );
    assert!(text.contains("\n5220\t1.000000\n"), "{text}");
    assert!(text.contains("\n5241\t3.000000\n"), "{text}");
    // The next program starts with the stored G28 position and the G55 offset.
    let second = env.write("home.ngc", "G21 G90\nG28\nG55 G0 Y0\nM2\n");
    env.run_ok("run2", &second, None);
    let p = position(&env.status());
    assert!((p[0] - 1.0).abs() < 1e-6 && p[1].abs() < 1e-6, "{p:?}");
}

/// `kerf plot INPUT --out SVG`, to completion.
fn env_plot(input: &Path, svg: &Path) -> Output {
    Command::new(KERF)
        .arg("plot")
        .arg(input)
        .arg("--out")
        .arg(svg)
        .stdin(Stdio::null())
        .output()
        .unwrap()
}

/// Sends a fault injection through the control service (accepted by `kerfd --test-faults`
/// only); the daemon's answer.
fn inject_fault(env: &Env, injection: kerfd::worker::Injection) -> kerf_proto::Response {
    let mut client = kerf::client::Client::connect(&env.machine).expect("the daemon answers");
    let code = injection.code().expect("a code for the injection");
    client
        .request(kerf_proto::ControlCommand::Inject { code })
        .expect("an answer")
}

#[test]
fn a_drive_fault_injected_mid_program_is_latched_reported_dumped_and_reset() {
    use kerfd::worker::Injection;
    let env = Env::new(
        "fault",
        &[(
            "[daemon]",
            "[safety]\ndump_dir = \"blackbox\"\nrecorder_seconds = 2.0\n[daemon]",
        )],
    );
    let _daemon = env.start_daemon_with("kerfd", &["--test-faults"]);
    let program = env.write("cam.ngc", &cam_program(20, 200, 0.5, 3000.0));
    let mut run = env.spawn_run("run", &program, None);
    env.wait_status("the program to move", |s| {
        state(s) == "running" && s["line"].as_u64().unwrap_or(0) > 20
    });
    let r = inject_fault(&env, Injection::DriveFault(1));
    assert_eq!(r.reason, kerf_proto::REASON_OK, "{}", r.message());

    // `kerf run` fails and says why.
    let status = wait(&mut run, 2);
    assert_eq!(status.code(), Some(2), "{}", run.stderr());
    let err = run.stderr();
    assert!(
        err.contains("the safety layer stopped the machine")
            && err.contains("drive_fault on axis Y: the drive reports error 0x4310")
            && err.contains("black box: "),
        "{err}"
    );

    // Latched, reported with the check, axis, value, line and the black-box file.
    let s = env.wait_status("the fault's black box", |s| s["safety"]["dump"].is_string());
    assert_eq!(state(&s), "fault");
    assert_eq!(s["drives"], "stopped");
    let safety = &s["safety"];
    assert_eq!(safety["check"], "drive_fault");
    assert_eq!(safety["axis"], "y");
    assert_eq!(safety["drive_error_code"], 0x4310);
    assert!(safety["line"].as_u64().unwrap() > 20, "{s}");
    let text = String::from_utf8(env.kerf("status", &[]).stdout).unwrap();
    assert!(
        text.contains("fault: drive_fault on axis Y") && text.contains("black box: "),
        "{text}"
    );
    // The black box: 2 s of cycles, the motion before the trip and the stop to rest.
    let dump = PathBuf::from(safety["dump"].as_str().unwrap());
    assert!(
        dump.starts_with(env.dir.join("blackbox").canonicalize().unwrap()),
        "{dump:?}"
    );
    let csv = read_text(&dump);
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(
        &header[..5],
        &["sequence", "time_s", "state", "x_cmd_mm", "x_act_mm"]
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    // Consecutive cycles, the last 2 s of them (or all since the start, if fewer).
    let seq: Vec<u64> = rows.iter().map(|r| r[0].parse().unwrap()).collect();
    assert!(seq.windows(2).all(|w| w[1] == w[0] + 1));
    assert!(
        rows.len() == 2000 || (rows.len() < 2000 && seq[0] == 1),
        "{}",
        rows.len()
    );
    assert!(rows.iter().all(|r| r.len() == header.len()));
    assert!(rows.iter().any(|r| r[2] == "running"));
    assert_eq!(rows.last().unwrap()[2], "stopped");
    let moving = rows
        .windows(2)
        .filter(|w| w[0][2] == "running" && w[0][3] != w[1][3])
        .count();
    assert!(moving > 10, "the X axis moved before the trip");

    // Nothing runs while the fault is latched.
    let refused = env.kerf("run", &[program.to_str().unwrap()]);
    assert_eq!(refused.status.code(), Some(2));
    let msg = String::from_utf8_lossy(&refused.stderr);
    assert!(msg.contains("is in fault"), "{msg}");
    // A reset is refused while the drive's fault persists …
    let reset = env.kerf("reset", &[]);
    assert_eq!(reset.status.code(), Some(2));
    let msg = String::from_utf8_lossy(&reset.stderr);
    assert!(
        msg.contains("the drive of axis Y still reports a fault"),
        "{msg}"
    );
    assert_eq!(env.status()["safety"]["check"], "drive_fault");
    // … and accepted once it is gone.
    let r = inject_fault(&env, Injection::ClearDriveFault(1));
    assert_eq!(r.reason, kerf_proto::REASON_OK, "{}", r.message());
    let reset = env.kerf("reset", &[]);
    assert!(
        reset.status.success(),
        "{}",
        String::from_utf8_lossy(&reset.stderr)
    );
    let s = env.status();
    assert_eq!(
        (state(&s), &s["safety"], &s["drives"]),
        ("idle", &Value::Null, &Value::from("running"))
    );

    // `kerf dump` copies the black box to a file of the user's.
    let out = env.path("box.csv");
    let dumped = env.kerf("dump", &["--out", out.to_str().unwrap()]);
    assert!(
        dumped.status.success(),
        "{}",
        String::from_utf8_lossy(&dumped.stderr)
    );
    let csv = read_text(&out);
    assert!(csv.starts_with("sequence,time_s,state,x_cmd_mm"), "{csv}");
    assert!(csv.lines().count() > 100, "{}", csv.lines().count());
    // `kerf plot` draws the fault's black box: X, Y, Z, each commanded against actual
    // and the following error, the stop shaded.
    let svg = env.path("fault.svg");
    let plotted = env_plot(&dump, &svg);
    assert!(
        plotted.status.success(),
        "{}",
        String::from_utf8_lossy(&plotted.stderr)
    );
    let svg = read_text(&svg);
    assert_eq!(svg.matches(r#"class="envelope""#).count(), 9);
    assert!(svg.contains("Y: following error") && svg.contains("#f6d0d0"));

    // And the machine runs programs again, from where the quick stop left it.
    let short = env.write("short.ngc", "G21 G91 G1 X1 Y1 F600\nM2\n");
    env.run_ok("after", &short, None);
    assert_eq!(program_end(&env.status()), "finished");
}

#[test]
fn fault_injection_is_refused_without_test_faults() {
    let env = Env::new("noinj", &[]);
    let _daemon = env.start_daemon("kerfd");
    let r = inject_fault(&env, kerfd::worker::Injection::DriveFault(0));
    assert_eq!(r.reason, kerf_proto::REASON_NOT_ALLOWED);
    assert!(r.message().contains("--test-faults"), "{}", r.message());
    let s = env.status();
    assert_eq!((state(&s), &s["safety"]), ("idle", &Value::Null));
}

#[test]
fn run_record_keeps_the_setpoints_up_to_a_safety_trip() {
    use kerfd::worker::Injection;
    let env = Env::new(
        "triprec",
        &[(
            "[daemon]",
            "[safety]\ndump_dir = \"blackbox\"\nrecorder_seconds = 1.0\n[daemon]",
        )],
    );
    let _daemon = env.start_daemon_with("kerfd", &["--test-faults"]);
    let text = cam_program(4, 200, 0.5, 3000.0);
    let program = env.write("cam.ngc", &text);
    let sim_csv = env.sim(&program, "sim.csv");
    let sim = read_csv(&sim_csv);
    // A recording of a failed run is the diagnosis: it replaces what was there.
    let csv = env.path("run.csv");
    fs::write(&csv, "an older recording\n").unwrap();
    let mut run = env.spawn_run("run", &program, Some(&csv));
    env.wait_status("the program to move", |s| {
        state(s) == "running" && s["line"].as_u64().unwrap_or(0) > 20
    });
    // A 1 mm step of Y on its way to the drive: a velocity trip (the setpoint never
    // reaches the drive; the quick stop does).
    let r = inject_fault(&env, Injection::Step(1, Injection::STEP_MM));
    assert_eq!(r.reason, kerf_proto::REASON_OK, "{}", r.message());

    let status = wait(&mut run, 2);
    assert_eq!(status.code(), Some(2), "{}", run.stderr());
    let err = run.stderr();
    assert!(
        err.contains("the safety layer stopped the machine") && err.contains("velocity on axis Y"),
        "{err}"
    );
    assert!(!err.contains("recording"), "{err}");
    let s = env.wait_status("the fault's black box", |s| s["safety"]["dump"].is_string());
    assert_eq!(s["safety"]["check"], "velocity", "{s}");

    // Every row of the program up to the trip: the header, the row at t = 0, then one per
    // cycle. Up to the cycle before the trip, the same bytes as `kerf sim`'s CSV (the
    // daemon = sim up to the trip). The last row is the cycle of the trip as the stream
    // published it: the line being run, the position the drives got (the first step of the
    // quick stop, within the limits) and no feed (the motion core rests where the drives
    // stop).
    let rows = read_csv(&csv);
    assert!(rows.len() > 100, "{} rows", rows.len());
    assert!(
        rows.len() < sim.len(),
        "{} rows of {}",
        rows.len(),
        sim.len()
    );
    let (trip, before) = rows.split_last().unwrap();
    let (recorded, simulated) = (read_text(&csv), read_text(&sim_csv));
    let recorded = recorded.lines().collect::<Vec<_>>();
    let simulated = simulated.lines().collect::<Vec<_>>();
    let n = recorded.len() - 1;
    assert!(recorded[..n] == simulated[..n], "the rows before the trip");
    let at_trip = &sim[before.len()];
    assert_eq!(trip.t, at_trip.t);
    assert_eq!((trip.line, trip.feed_mm_s), (at_trip.line, 0.0));
    assert_ne!(trip.position, at_trip.position);
    check_limits(&env, &rows, "the recording up to the trip");
    assert_eq!(
        trip.line as u64,
        s["safety"]["line"].as_u64().unwrap(),
        "{s}"
    );
}

/// An abort while `kerf run` is still streaming a program much longer than the daemon's
/// window and queue ends the program for everyone at once (issue 25): the daemon says
/// aborted, takes nothing more of it, and `kerf run` stops sending and exits 2.
#[test]
fn an_abort_while_kerf_run_still_streams_ends_the_program_for_the_client() {
    let env = Env::new(
        "abort_stream",
        &[
            ("queue_segments = 4096", "queue_segments = 64"),
            ("move_window = 4096", "move_window = 64"),
        ],
    );
    let _daemon = env.start_daemon("kerfd");
    // 600 exact-stop steps of 0.5 mm: a minute of motion, far more than 64 + 64 items
    // (`kerf run` simulates the whole program before it sends it: kept short for that).
    let mut program = String::from("G21 G90 G61\n");
    for k in 0..600 {
        let x = if k % 2 == 0 { 0.5 } else { 0.0 };
        program.push_str(&format!("G1 X{x} F600\n"));
    }
    program.push_str("M2\n");
    let path = env.write("long.ngc", &program);
    let mut run = env.spawn_run("run-long", &path, None);
    env.wait_status("motion", |s| state(s) == "running" && moved(s));
    let o = env.kerf("abort", &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let status = wait(&mut run, 1);
    assert_eq!(status.code(), Some(2), "{}", run.stderr());
    assert!(run.stderr().contains("aborted"), "{}", run.stderr());
    let s = env.wait_status("rest after the abort", |s| state(s) != "running");
    assert_eq!(program_end(&s), "aborted", "{s}");
    assert_eq!(state(&s), "idle", "{s}");
    // Nothing more of it is taken or moves (what `kerf run` sent before it saw the abort
    // was taken and dropped).
    let received = s["moves_received"].as_u64().unwrap();
    env.wait_cycles(200);
    let later = env.status();
    assert_eq!(later["moves_received"].as_u64().unwrap(), received);
    assert_eq!(position(&later), position(&s));
    assert!(received <= 601, "{received} items of a 601-item program");
}

/// A dense CAM surface whose smoothed pieces each stand for many programmed moves fills
/// the daemon's move tracker (16 moves per queued segment and 4,096 more) before its
/// motion queue: the queue then counts as full and the motion starts (it used to wait for
/// a full queue that could never come, the machine "running" without moving), and the
/// setpoints are still `kerf sim`'s. A 16-segment queue and 0.005 mm steps make it show
/// on a short program.
#[test]
fn a_dense_surface_whose_pieces_outnumber_the_tracker_starts_and_equals_kerf_sim() {
    let env = Env::new(
        "tracker",
        &[("queue_segments = 4096", "queue_segments = 16")],
    );
    let mut text = String::from("G21 G90 G17 G94 G64 P0.01 F3000\n");
    for k in 1..=20_000 {
        let x = f64::from(k) * 0.005;
        text += &format!("G1 X{x:.4} Z{:.4}\n", 0.5 * (x / 4.0).sin());
    }
    text += "M2\n";
    let program = env.write("surface.ngc", &text);
    embedded_run_equal_to_sim(&env, &program);
}

/// A straight line of 30,000 programmed moves (steps of 0.1 µm, 3 mm) on a 16-segment
/// queue, whose tracker holds 4,352 moves: the planner's pieces stand for at most
/// `MAX_PIECE_MOVES` moves each, so the tracker always holds the running piece and the
/// next, and the motion runs through without stopping (a 2 mm piece of 20,000 moves used
/// to stop the motion at its end, X2, waiting for room in the tracker, and the daemon
/// restarted a cycle or two later than `kerf sim`, depending on how far the planning
/// thread had sent the next piece's moves). The daemon's setpoints equal `kerf sim`'s, and
/// each names the line of a move that passes within 1 µm of it, from the program's text.
#[test]
fn a_line_of_more_moves_than_the_tracker_holds_runs_through_as_in_kerf_sim() {
    let env = Env::new(
        "untracked",
        &[("queue_segments = 4096", "queue_segments = 16")],
    );
    let capacity = kerf_pipeline::tracked_moves(16);
    let steps = 30_000;
    let step_mm = 0.0001;
    assert!(steps > 4 * capacity, "the line outnumbers the tracker");
    let mut text = String::from("G21 G90 G17 G94 G64 P0.01 F3000\n");
    for k in 1..=steps {
        text += &format!("G1 X{:.4}\n", k as f64 * step_mm);
    }
    text += "M2\n";
    let program = env.write("steps.ngc", &text);
    let rows = read_csv(&embedded_run_equal_to_sim(&env, &program));
    let last = rows.last().unwrap();
    assert!((last.position[0] - 3.0).abs() < 1e-9, "ends at {last:?}");
    // Move k (line k + 1) runs from X (k - 1)·step to X k·step.
    for row in &rows[1..] {
        let x = row.position[0];
        let k = f64::from(row.line) - 1.0;
        assert!(
            (k - 1.0) * step_mm - 1e-6 <= x && x <= k * step_mm + 1e-6,
            "line {} named at X{x}",
            row.line
        );
    }
    // Moving from the first row that moves to the end, never at rest in between.
    let first = rows.iter().position(|r| r.position[0] > 0.0).unwrap();
    let end = rows.iter().position(|r| r.position[0] == 3.0).unwrap();
    for pair in rows[first - 1..=end].windows(2) {
        assert!(
            pair[1].position[0] > pair[0].position[0],
            "at rest at X{} ({} s)",
            pair[1].position[0],
            pair[1].t
        );
    }
}

/// The CPUs a thread of process `pid` whose name starts with `name` may run on
/// (`Cpus_allowed_list` of /proc/PID/task/TID/status), one entry per such thread.
fn threads_cpus(pid: u32, name: &str) -> Vec<String> {
    let mut found = Vec::new();
    for task in fs::read_dir(format!("/proc/{pid}/task")).unwrap() {
        let dir = task.unwrap().path();
        let comm = read_text(&dir.join("comm"));
        if comm.trim().starts_with(name) {
            let status = read_text(&dir.join("status"));
            let cpus = status
                .lines()
                .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))
                .unwrap_or_else(|| panic!("no Cpus_allowed_list for {comm}"));
            found.push(cpus.trim().to_owned());
        }
    }
    found
}

/// `daemon.cpu` and `daemon.cpu_latency_us` as the running process shows them: the cycle
/// (and its publishing helper) on the configured CPU, the control and planning threads
/// off it, and, as root, the CPU wake-up latency request held open in
/// /dev/cpu_dma_latency and named in the log (as another user, the log says why not).
#[test]
fn kerfd_keeps_its_other_threads_off_the_cycles_cpu_and_holds_its_latency_request() {
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    assert!(
        cpus >= 2,
        "this test needs two CPUs (one for the cycle); this machine has {cpus}"
    );
    let env = Env::new("cpus", &[("# cpu = 3", "cpu = 1")]);
    let daemon = env.start_daemon("kerfd");
    let pid = daemon.pid();
    assert_eq!(threads_cpus(pid, "kerfd-cycle"), ["1"]);
    for name in ["kerfd-control", "kerfd-planning"] {
        let sets = threads_cpus(pid, name);
        assert_eq!(sets.len(), 1, "{name}: {sets:?}");
        let allowed: Vec<usize> = sets[0]
            .split(',')
            .flat_map(|r| match r.split_once('-') {
                Some((a, b)) => (a.parse::<usize>().unwrap()..=b.parse().unwrap()).collect(),
                None => vec![r.parse::<usize>().unwrap()],
            })
            .collect();
        assert!(
            !allowed.is_empty() && !allowed.contains(&1),
            "{name} may run on CPUs {} (the cycle's is 1)",
            sets[0]
        );
    }
    let root = std::os::unix::fs::MetadataExt::uid(&fs::metadata("/proc/self").unwrap()) == 0;
    let held = fs::read_dir(format!("/proc/{pid}/fd"))
        .unwrap()
        .filter_map(|e| fs::read_link(e.unwrap().path()).ok())
        .any(|target| target == Path::new("/dev/cpu_dma_latency"));
    let log = daemon.stderr();
    if root {
        assert!(held, "kerfd holds no /dev/cpu_dma_latency open: {log}");
        assert!(log.contains("CPU wake-up latency 0 µs"), "{log}");
    } else {
        assert!(!held);
        assert!(log.contains("CPU wake-up latency of 0 µs refused"), "{log}");
    }
}
