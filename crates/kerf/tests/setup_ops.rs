//! Multi-process tests of setting up a job (issue 29): MDI lines (`kerf mdi`, one-shot and
//! a session fed through a pipe), the work offsets (`kerf offset set/show`), tool length
//! touch-off (`kerf tool touch-off`), the DRO of `kerf status`, and the machine state kept
//! across a daemon restart.
//!
//! Every test has its own machine (a copy of `config/kerf.toml` named after the test and
//! this process) and its own state directory (`STATE_DIRECTORY`, given to the daemon and
//! to every `kerf`): the machine's parameter file, tool table and state file are in the
//! test's scratch directory, never in the temporary directory's shared defaults. What is
//! asserted is what a user sees: the setpoints `--record` writes, `kerf status --json`,
//! `kerf offset show --json`, the files, the exit codes and messages. Expected values come
//! from the G-code and the offsets the test sets.

use std::fs;
use std::io::Write;
use std::path::Path;
use std::process::{Output, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

const KERF: &str = env!("CARGO_BIN_EXE_kerf");
mod common;
use common::{MACHINE_PATIENCE as PATIENCE, MachineEnv, Proc};

/// Room for rounding when a position is compared with a computed one, mm.
const EPS_MM: f64 = 1e-6;

/// The bundled machine's path tolerance (config/kerf.toml `tolerance_mm`).
const TOLERANCE_MM: f64 = 0.01;

fn stderr_of(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// One test's machine (see [`MachineEnv`]: its state directory is its scratch directory),
/// with the commands these tests use.
struct Env {
    m: MachineEnv,
}

impl std::ops::Deref for Env {
    type Target = MachineEnv;

    fn deref(&self) -> &MachineEnv {
        &self.m
    }
}

impl Env {
    fn new(tag: &str) -> Env {
        Env {
            m: MachineEnv::new("kerf-setup-ops-tests", "m", tag, false),
        }
    }

    /// `kerf …`, asserted to exit 0; its standard output.
    fn kerf_ok(&self, sub: &[&str], args: &[&str]) -> String {
        String::from_utf8(self.m.kerf_ok(sub, args).stdout).unwrap()
    }

    fn mdi(&self, line: &str, extra: &[&str]) -> String {
        let mut args = extra.to_vec();
        args.push(line);
        self.kerf_ok(&["mdi"], &args)
    }

    fn offsets(&self) -> Value {
        let text = self.kerf_ok(&["offset", "show"], &["--json"]);
        serde_json::from_str(text.trim()).unwrap_or_else(|e| panic!("not JSON ({e}): {text}"))
    }

    /// `kerf run --record CSV PROGRAM` with the program's text.
    fn run_recorded(&self, name: &str, program: &str, extra: &[&str]) -> Vec<[f64; 3]> {
        let file = self.write(&format!("{name}.prog"), program);
        let csv = self.path(&format!("{name}.csv"));
        let mut args = extra.to_vec();
        args.extend(["--record", csv.to_str().unwrap(), file.to_str().unwrap()]);
        self.kerf_ok(&["run"], &args);
        positions(&csv)
    }

    /// `kerf mdi --record CSV LINE`.
    fn mdi_recorded(&self, name: &str, line: &str, extra: &[&str]) -> Vec<[f64; 3]> {
        let csv = self.path(&format!("{name}.csv"));
        let mut args = extra.to_vec();
        args.extend(["--record", csv.to_str().unwrap()]);
        self.mdi(line, &args);
        positions(&csv)
    }
}

impl Drop for Env {
    fn drop(&mut self) {
        if std::thread::panicking() && std::env::var_os("KERF_TEST_KEEP").is_some() {
            eprintln!("kept {}", self.dir.display());
            return;
        }
        let _ = fs::remove_dir_all(&self.dir);
    }
}

/// The positions of a recording (`t,x,y,z,line,feed_mm_s`), row by row.
fn positions(csv: &Path) -> Vec<[f64; 3]> {
    let text = fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t,x,y,z,line,feed_mm_s"), "{csv:?}");
    lines
        .map(|l| {
            let f: Vec<f64> = l
                .split(',')
                .map(|x| x.parse().unwrap_or_else(|_| panic!("{csv:?}: {l}")))
                .collect();
            [f[1], f[2], f[3]]
        })
        .collect()
}

fn xyz(v: &Value) -> [f64; 3] {
    ["x", "y", "z"].map(|k| {
        v[k].as_f64()
            .unwrap_or_else(|| panic!("{k} is not a number in {v}"))
    })
}

fn assert_near(got: [f64; 3], want: [f64; 3], what: &str) {
    assert!(
        got.iter().zip(want).all(|(g, w)| (g - w).abs() <= EPS_MM),
        "{what}: {got:?}, expected {want:?}"
    );
}

/// The recorded path without the rows at rest at its end (a program's end at rest may
/// take cycles a line's does not).
fn trimmed(mut rows: Vec<[f64; 3]>) -> Vec<[f64; 3]> {
    while rows.len() > 1 && rows[rows.len() - 1] == rows[rows.len() - 2] {
        rows.pop();
    }
    rows
}

/// The same line in every dialect: as MDI and as a one-line program from the same
/// machine state give the same setpoints.
#[test]
fn mdi_lines_give_the_setpoints_of_the_same_line_in_a_program_in_every_dialect() {
    let env = Env::new("dialects");
    let _daemon = env.start_daemon("kerfd");
    let cases: [(&str, &str, &str); 5] = [
        ("linuxcnc", "G1 X10 Y5 Z-2 F600", "M2\n"),
        ("rockwell", "G1 X10 Y5 Z-2 F600", "M2\n"),
        ("sinumerik", "G1 X10 Y5 Z-2 F600", "M30\n"),
        ("heidenhain", "G01 X+10 Y+5 Z-2 F600 *", ""),
        ("fagor", "G1 X10 Y5 Z-2 F600", "M30\n"),
    ];
    for (dialect, line, end) in cases {
        let back = || env.mdi("G0 X3 Y4 Z1", &["--dialect", "linuxcnc"]);
        back();
        let mdi = env.mdi_recorded(&format!("mdi-{dialect}"), line, &["--dialect", dialect]);
        assert_near(*mdi.last().unwrap(), [10.0, 5.0, -2.0], dialect);
        back();
        let program = env.run_recorded(
            &format!("run-{dialect}"),
            &format!("{line}\n{end}"),
            &["--dialect", dialect],
        );
        let (mdi, program) = (trimmed(mdi), trimmed(program));
        assert_eq!(
            mdi[0],
            [3.0, 4.0, 1.0],
            "{dialect}: starts where the machine was"
        );
        assert_eq!(mdi, program, "{dialect}: MDI and program setpoints differ");
    }
}

/// Touch-off of G54 where an MDI move left the machine, then a program: its setpoints
/// are the program's coordinates plus the offset; `kerf offset show` and the DRO agree.
#[test]
fn offset_set_puts_the_program_where_the_offset_says() {
    let env = Env::new("offset");
    let _daemon = env.start_daemon("kerfd");
    env.mdi("G0 X12.5 Y-7 Z-3", &[]);
    let out = env.kerf_ok(&["offset", "set"], &["G54", "X0", "Y0", "Z0"]);
    assert!(
        out.starts_with("G54 offset: X 12.5000 Y -7.0000 Z -3.0000"),
        "{out}"
    );
    let offsets = env.offsets();
    assert_eq!(offsets["active"], "G54");
    assert_near(
        xyz(&offsets["systems"][0]),
        [12.5, -7.0, -3.0],
        "offset show G54",
    );
    assert_near(xyz(&offsets["systems"][1]), [0.0; 3], "offset show G55");
    let s = env.status();
    assert_eq!(s["dro"]["system"], "G54", "{s}");
    assert_near(
        xyz(&s["dro"]["work"]),
        [0.0; 3],
        "DRO at the touched-off point",
    );

    // A program: every setpoint is on its path shifted by the offset.
    let rows = env.run_recorded("part", "G0 X1 Y2\nG1 Z-1 F300\nG1 X4\nM2\n", &[]);
    let path = [
        [12.5, -7.0, -3.0],
        [13.5, -5.0, -3.0],
        [13.5, -5.0, -4.0],
        [16.5, -5.0, -4.0],
    ];
    assert_near(*rows.last().unwrap(), path[3], "program end");
    for p in &rows {
        let d = path
            .windows(2)
            .map(|w| segment_distance(*p, w[0], w[1]))
            .fold(f64::INFINITY, f64::min);
        // Corners may be blended within the configured path tolerance.
        assert!(
            d <= TOLERANCE_MM + EPS_MM,
            "setpoint {p:?} is {d} mm off the offset path"
        );
    }
    let s = env.status();
    assert_near(
        xyz(&s["dro"]["work"]),
        [4.0, 2.0, -1.0],
        "DRO after the program",
    );
    let text = env.kerf_ok(&["status"], &[]);
    assert!(text.contains("work G54 X 4.000 Y 2.000 Z -1.000"), "{text}");

    // G55 with the same point: a one-shot MDI selects it, and it persists. (The options
    // may follow the axis words, as the README writes them: `--config` after `X100`.)
    let out = env
        .command(
            env!("CARGO_BIN_EXE_kerf"),
            &[
                "offset",
                "set",
                "G55",
                "X100",
                "--config",
                env.config_path.to_str().unwrap(),
            ],
        )
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "kerf offset set G55 X100 --config …: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    env.mdi("G55", &[]);
    let offsets = env.offsets();
    assert_eq!(offsets["active"], "G55");
    assert!((offsets["systems"][1]["x"].as_f64().unwrap() - (16.5 - 100.0)).abs() < EPS_MM);
    // Cleared: zero again.
    env.kerf_ok(&["offset", "set"], &["G54", "--clear"]);
    assert_near(xyz(&env.offsets()["systems"][0]), [0.0; 3], "cleared G54");

    // While a program moves, offsets, touch-off and MDI are refused with the reason.
    let long = env.write("long.ngc", "G1 X900 F100\nM2\n");
    let config = env.config_path.to_str().unwrap().to_string();
    let run_args = ["run", "--config", config.as_str(), long.to_str().unwrap()];
    let mut run = Proc::start("kerf-run-long", &env.dir, env.command(KERF, &run_args));
    let deadline = Instant::now() + PATIENCE;
    while env.status()["state"] != "running" {
        assert!(run.try_wait().is_none(), "kerf run ended: {}", run.stderr());
        assert!(Instant::now() < deadline, "the program never ran");
        std::thread::sleep(Duration::from_millis(10));
    }
    for (sub, args) in [
        (&["offset", "set"][..], &["G54", "X0"][..]),
        (&["tool", "touch-off"][..], &["1", "--z", "0"][..]),
        (&["mdi"][..], &["G0 X0"][..]),
    ] {
        let o = env.kerf(sub, args);
        assert_eq!(o.status.code(), Some(2), "{sub:?}");
        assert!(
            stderr_of(&o).contains("is busy with another program"),
            "{sub:?}: {}",
            stderr_of(&o)
        );
    }
    assert_near(
        xyz(&env.offsets()["systems"][0]),
        [0.0; 3],
        "G54 untouched while busy",
    );
    env.kerf_ok(&["abort"], &[]);
    run.wait_within(PATIENCE);
}

/// Tool touch-off against the G54 zero surface, then G43: Z lands where the length says.
#[test]
fn tool_touch_off_then_g43_puts_z_where_the_length_says() {
    let env = Env::new("touchoff");
    let _daemon = env.start_daemon("kerfd");
    // The reference surface at machine Z -50 is G54 Z0.
    env.mdi("G0 X0 Y0 Z-50", &[]);
    env.kerf_ok(&["offset", "set"], &["G54", "Z0"]);
    // Tool 1's tip touches the same surface with the spindle 20 mm higher, at machine
    // Z -30: the tool is 20 mm longer than the one G54 was touched off with.
    env.mdi("G53 G0 Z-30", &[]);
    let out = env.kerf_ok(&["tool", "touch-off"], &["1", "--z", "0"]);
    assert!(out.contains("T1 P0 Z20 D0"), "{out}");
    let table = fs::read_to_string(env.path(&format!("{}.tbl", env.machine))).unwrap();
    assert_eq!(table, "T1 P0 Z20 D0\n");
    let show = env.kerf_ok(&["tool", "show"], &[]);
    assert!(show.starts_with("T1 P0 Z20 D0\n"), "{show}");
    // With G43 H1, G54 Z5 is 5 mm above the surface for the tool's tip: the spindle is at
    // machine -50 + 20 + 5.
    let rows = env.run_recorded("g43", "G43 H1\nG0 Z5\nM2\n", &[]);
    assert_near(*rows.last().unwrap(), [0.0, 0.0, -25.0], "G43 H1 G0 Z5");
    // A tool not in the table is refused, naming it.
    let o = env.kerf(&["tool", "touch-off"], &["7", "--z", "0"]);
    assert!(!o.status.success());
    assert!(
        stderr_of(&o).contains("tool 7 is not in the machine's tool table"),
        "{}",
        stderr_of(&o)
    );
}

/// Offsets and the tool in the spindle survive a daemon restart; the DRO after it
/// takes them into account.
#[test]
fn a_daemon_restart_keeps_offsets_and_the_tool_in_the_spindle() {
    let env = Env::new("restart");
    let mut daemon = env.start_daemon("kerfd-1");
    env.mdi("G0 X20 Y10 Z-5", &[]);
    env.kerf_ok(&["offset", "set"], &["G54", "X0", "Y0", "Z0"]);
    env.mdi("T1 M6", &[]);
    assert_eq!(env.status()["tool"]["in_spindle"], 1);
    daemon.signal("TERM");
    daemon.wait_within(PATIENCE);
    let _daemon = env.start_daemon("kerfd-2");
    let s = env.status();
    assert_eq!(s["tool"]["in_spindle"], 1, "{s}");
    assert_near(
        xyz(&env.offsets()["systems"][0]),
        [20.0, 10.0, -5.0],
        "G54 after restart",
    );
    // The simulated drives start at 0 again: the DRO reads 0 minus the offset.
    let machine = xyz(&s["position"]);
    let work = xyz(&s["dro"]["work"]);
    assert_near(
        work,
        [machine[0] - 20.0, machine[1] - 10.0, machine[2] + 5.0],
        "DRO after restart",
    );
    // A program after the restart runs at the offset.
    let rows = env.run_recorded("after", "G0 X1 Y1 Z1\nM2\n", &[]);
    assert_near(
        *rows.last().unwrap(),
        [21.0, 11.0, -4.0],
        "program at the kept offset",
    );
}

/// An MDI error names `mdi:1:COL` and nothing moves; the one-shot exits non-zero.
#[test]
fn an_mdi_error_names_its_column_and_nothing_moves() {
    let env = Env::new("error");
    let _daemon = env.start_daemon("kerfd");
    env.mdi("G0 X1 Y2 Z3", &[]);
    let before = env.status();
    // G2 at column 10 is a second motion code in the block, in every dialect's words.
    for dialect in ["linuxcnc", "sinumerik"] {
        let o = env.kerf(&["mdi"], &["--dialect", dialect, "G0 X5 Y5 G2"]);
        assert_eq!(o.status.code(), Some(2), "{dialect}");
        let err = stderr_of(&o);
        assert!(err.starts_with("mdi:1:10: error: "), "{dialect}: {err}");
    }
    // Out of the travel: refused before motion too.
    let o = env.kerf(&["mdi"], &["G0 X5000"]);
    assert!(!o.status.success());
    assert!(
        stderr_of(&o).starts_with("mdi:1:1: error: "),
        "{}",
        stderr_of(&o)
    );
    let after = env.status();
    assert_eq!(
        after["program_id"], before["program_id"],
        "a program was sent"
    );
    assert_near(xyz(&after["position"]), [1.0, 2.0, 3.0], "nothing moved");
}

/// A session fed through a pipe runs its lines in order with the modal state carried:
/// G91 then X1 twice is +2; a failing line is reported with its number and column and
/// the session goes on, then exits non-zero.
#[test]
fn an_mdi_session_carries_the_modal_state_from_line_to_line() {
    let env = Env::new("session");
    let _daemon = env.start_daemon("kerfd");
    env.mdi("G0 X1 Y1 Z1", &[]);
    let mut child = env
        .command(
            KERF,
            &["mdi", "--config", env.config_path.to_str().unwrap()],
        )
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(b"G91 G0 X1\n\nY2 &\nX1\nG90 G10 L20 P1 X0\nM2\nG0 X1 &\n")
        .unwrap();
    let deadline = Instant::now() + PATIENCE;
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("kerf mdi did not end");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert_eq!(status.code(), Some(2), "{err}");
    // Blank lines are not counted; the numbers go on after M2.
    assert!(err.contains("mdi:2:4: error: "), "{err}");
    assert!(err.contains("mdi:6:7: error: "), "{err}");
    assert!(err.contains("2 of 6 MDI lines failed"), "{err}");
    let s = env.status();
    assert_near(xyz(&s["position"]), [3.0, 1.0, 1.0], "G91 X1 twice");
    // The G10 line's offset was written: X reads 0 there.
    assert_near(
        xyz(&env.offsets()["systems"][0]),
        [3.0, 0.0, 0.0],
        "G10 L20 of the session",
    );
}

/// Distance from `p` to the segment `a`–`b`.
fn segment_distance(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let ap = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let len2: f64 = ab.iter().map(|v| v * v).sum();
    let t = if len2 == 0.0 {
        0.0
    } else {
        (ap.iter().zip(&ab).map(|(u, v)| u * v).sum::<f64>() / len2).clamp(0.0, 1.0)
    };
    (0..3)
        .map(|i| (a[i] + t * ab[i] - p[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}
