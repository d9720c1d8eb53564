//! Exit 0 means the program ran to its end: the `kerf` binary refuses, with exit code 2 and
//! one `error:` line before any motion, every input that would make a run that cannot
//! finish or is not a machine (feed override 0, a negative dwell, limits outside their
//! ranges, a period too short to mean anything), and a normal run still exits 0 at the
//! program's end point.
//!
//! Expected places and numbers are worked out by hand from the inputs, never copied from
//! the program's output.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const KERF: &str = env!("CARGO_BIN_EXE_kerf");

/// The workspace root, where `config/` lives.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn scratch_dir() -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("kerf-exit-rules-tests");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A scratch file unique to this test.
fn scratch(name: &str, contents: &str) -> PathBuf {
    let path = scratch_dir().join(name);
    std::fs::write(&path, contents).unwrap();
    path
}

/// A CSV path in the scratch directory that does not exist yet.
fn fresh_csv(name: &str) -> PathBuf {
    let path = scratch_dir().join(name);
    let _ = std::fs::remove_file(&path);
    path
}

fn kerf(args: &[&str]) -> Output {
    Command::new(KERF).args(args).output().unwrap()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The rows of a CSV written by `kerf sim`, as numbers (the header is checked).
fn csv_rows(path: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t,x,y,z,line,feed_mm_s"));
    lines
        .map(|l| l.split(',').map(|v| v.parse::<f64>().unwrap()).collect())
        .collect()
}

/// Asserts the run was refused (exit code 2), printed no summary, and wrote no setpoint
/// rows: either no CSV at all or one without rows.
fn assert_refused_without_motion(out: &Output, csv: &Path) {
    assert_eq!(out.status.code(), Some(2), "stderr: {}", stderr(out));
    assert!(stdout(out).is_empty(), "no summary: {}", stdout(out));
    if csv.exists() {
        let text = std::fs::read_to_string(csv).unwrap();
        assert!(text.lines().count() <= 1, "no setpoint rows: {text}");
    }
}

/// `kerf sim --override PCT PROGRAM --out CSV` on the bundled configuration.
fn sim_with_override(program: &Path, csv: &Path, pct: &str) -> Output {
    kerf(&[
        "sim",
        "--override",
        pct,
        program.to_str().unwrap(),
        "--out",
        csv.to_str().unwrap(),
    ])
}

/// 1 mm along X at F600 (10 mm/s) on the bundled mill.
const ONE_MM_AT_F600: &str = "G21 G90 G17\nG1 X1 F600\nM2\n";

#[test]
fn override_zero_is_refused_before_any_motion() {
    let program = scratch("override-0.ngc", ONE_MM_AT_F600);
    for zero in ["0", "0%", "0.0", "-0"] {
        let csv = fresh_csv("override-0.csv");
        let out = sim_with_override(&program, &csv, zero);
        assert_refused_without_motion(&out, &csv);
        let err = stderr(&out);
        assert!(err.starts_with("error: "), "{err}");
        assert!(err.contains("--override 0 would hold the machine"), "{err}");
        assert!(err.contains("never finish"), "{err}");
    }
}

#[test]
fn out_of_range_overrides_are_parsed_as_values_and_named() {
    let program = scratch("override-bad.ngc", ONE_MM_AT_F600);
    for bad in ["-5", "-0.5", "200.5", "0.05", "1e-300", "nan", "abc"] {
        let csv = fresh_csv("override-bad.csv");
        let out = sim_with_override(&program, &csv, bad);
        assert_refused_without_motion(&out, &csv);
        let err = stderr(&out);
        assert!(!err.contains("unexpected argument"), "{bad}: {err}");
        assert!(
            err.contains(&format!("`{bad}` is not a feed override")),
            "{bad}: {err}"
        );
        assert!(err.contains("0.1 to 200 percent"), "{bad}: {err}");
    }
}

#[test]
fn small_and_full_overrides_still_run_to_the_end_point() {
    // 1 mm at 10 mm/s: at 12.5 % the feed is 1.25 mm/s, so the move takes at least 0.8 s;
    // at 200 % the axis limits allow 20 mm/s, so at least 0.05 s.
    let program = scratch("override-ok.ngc", ONE_MM_AT_F600);
    for (pct, min_s, feed_mm_s) in [("12.5", 0.8, 1.25), ("200%", 0.05, 20.0)] {
        let csv = fresh_csv("override-ok.csv");
        let out = sim_with_override(&program, &csv, pct);
        assert_eq!(out.status.code(), Some(0), "{pct}: {}", stderr(&out));
        let rows = csv_rows(&csv);
        let last = rows.last().unwrap();
        assert_eq!(&last[1..4], &[1.0, 0.0, 0.0], "{pct}: ends at X1");
        assert!(last[0] >= min_s, "{pct}: {} s", last[0]);
        for pair in rows.windows(2) {
            let v_mm_s = (pair[1][1] - pair[0][1]) / 0.001;
            assert!(v_mm_s <= feed_mm_s * 1.01, "{pct}: {v_mm_s} mm/s");
        }
    }
}

#[test]
fn the_smallest_override_is_accepted_by_the_argument_check() {
    // 0.1 % passes the argument check: with an unreadable program the run fails on the
    // program, not on the override.
    let csv = fresh_csv("override-min.csv");
    let out = kerf(&[
        "sim",
        "--override",
        "0.1",
        "/nonexistent/program.ngc",
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(
        err.starts_with("/nonexistent/program.ngc: error: cannot read program"),
        "{err}"
    );
}

/// The bundled configuration with the first `key = ...` line replaced by `key = value`,
/// and the `LINE:COL` of the value in it.
fn config_with(key: &str, old: &str, value: &str) -> (String, String) {
    let base = kerf_testkit::config_text::without_homing(
        &std::fs::read_to_string(root().join("config/kerf.toml")).unwrap(),
    );
    let from = format!("\n{key} = {old}\n");
    let at = base.find(&from).expect("key in the bundled config") + 1;
    let text = base.replacen(&from, &format!("\n{key} = {value}\n"), 1);
    let line = text[..at].matches('\n').count() + 1;
    (text, format!("{line}:{}", key.len() + 4))
}

#[test]
fn a_tiny_velocity_limit_is_refused_naming_the_key_and_range() {
    // The run would never finish at 1e-300 mm/s.
    let (text, place) = config_with("velocity_mm_s", "200.0", "1e-300");
    let config = scratch("tiny-velocity.toml", &text);
    let program = scratch("tiny-velocity.ngc", ONE_MM_AT_F600);
    let csv = fresh_csv("tiny-velocity.csv");
    let out = kerf(&[
        "sim",
        "--config",
        config.to_str().unwrap(),
        program.to_str().unwrap(),
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert_refused_without_motion(&out, &csv);
    assert_eq!(
        stderr(&out),
        format!(
            "{}:{place}: error: `axes.x.velocity_mm_s` must be between 0.001 and 100000 mm/s, found 1e-300\n",
            config.display()
        )
    );
    // `kerf plan` reads the same configuration and refuses it too.
    let out = kerf(&[
        "plan",
        "--config",
        config.to_str().unwrap(),
        program.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stdout(&out).is_empty());
}

#[test]
fn a_period_under_50_us_is_refused() {
    let program = scratch("period.ngc", ONE_MM_AT_F600);
    for (period, accepted) in [("10", false), ("49", false), ("50", true)] {
        let (text, place) = config_with("period_us", "1000", period);
        let config = scratch("period.toml", &text);
        let csv = fresh_csv("period.csv");
        let out = kerf(&[
            "sim",
            "--config",
            config.to_str().unwrap(),
            program.to_str().unwrap(),
            "--out",
            csv.to_str().unwrap(),
        ]);
        if accepted {
            assert_eq!(out.status.code(), Some(0), "{period}: {}", stderr(&out));
            // One row per 50 µs period.
            let rows = csv_rows(&csv);
            assert!((rows[1][0] - 50e-6).abs() < 1e-12, "{}", rows[1][0]);
            assert_eq!(&rows.last().unwrap()[1..4], &[1.0, 0.0, 0.0]);
        } else {
            assert_refused_without_motion(&out, &csv);
            assert_eq!(
                stderr(&out),
                format!(
                    "{}:{place}: error: `period_us` must be between 50 and 1000000 µs, found {period}\n",
                    config.display()
                )
            );
        }
    }
}

#[test]
fn a_negative_dwell_is_refused_at_the_word() {
    // Line 3, column 4: the P of `G4 P-1`.
    let program = scratch("dwell.ngc", "G21 G90 G17\nG1 X1 F600\nG4 P-1\nG1 X2\nM2\n");
    let csv = fresh_csv("dwell.csv");
    let out = kerf(&[
        "sim",
        program.to_str().unwrap(),
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert_refused_without_motion(&out, &csv);
    assert_eq!(
        stderr(&out),
        format!("{}:3:4: error: Negative P word used\n", program.display())
    );
    // `kerf plan` prints the move before the dwell block and nothing after it.
    let out = kerf(&["plan", program.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let printed = stdout(&out);
    assert_eq!(printed.lines().count(), 1, "{printed}");
    assert!(printed.contains("\"line\":2"), "{printed}");
    assert_eq!(
        stderr(&out),
        format!("{}:3:4: error: Negative P word used\n", program.display())
    );
}

#[test]
fn a_dwell_run_still_exits_0_at_the_end_point() {
    let program = scratch(
        "dwell-ok.ngc",
        "G21 G90 G17\nG1 X1 F600\nG4 P0.5\nG1 X2\nM2\n",
    );
    let csv = fresh_csv("dwell-ok.csv");
    let out = kerf(&[
        "sim",
        program.to_str().unwrap(),
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(stdout(&out).starts_with("duration "), "{}", stdout(&out));
    let rows = csv_rows(&csv);
    assert_eq!(&rows[0][..4], &[0.0, 0.0, 0.0, 0.0]);
    assert_eq!(&rows.last().unwrap()[1..4], &[2.0, 0.0, 0.0]);
    // 2 mm at 10 mm/s: at least 0.2 s.
    assert!(rows.last().unwrap()[0] >= 0.2);
}
