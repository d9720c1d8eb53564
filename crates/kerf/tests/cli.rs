//! End-to-end tests of the `kerf` binary: the `kerf plan` JSON contract, standard input,
//! error format and exit codes, configuration errors and dialect selection.
//!
//! Expected values are worked out by hand from the programs (and the controls' manuals),
//! never copied from the program's output.

use std::f64::consts::{FRAC_PI_2, PI};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use serde_json::Value;

const KERF: &str = env!("CARGO_BIN_EXE_kerf");

/// The workspace root, where `config/` lives.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A scratch file unique to this test.
fn scratch(name: &str, contents: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("kerf-cli-tests");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    path
}

fn kerf(args: &[&str]) -> Output {
    Command::new(KERF).args(args).output().unwrap()
}

fn kerf_stdin(args: &[&str], input: &str) -> Output {
    let mut child = Command::new(KERF)
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let input = input.to_owned();
    // Writing on another thread keeps a large input from deadlocking against our reading.
    let writer = std::thread::spawn(move || {
        let _ = stdin.write_all(input.as_bytes());
    });
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap();
    out
}

fn stdout_lines(out: &Output) -> Vec<Value> {
    String::from_utf8(out.stdout.clone())
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON ({e}): {l}")))
        .collect()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn triple(v: &Value) -> [f64; 3] {
    let a = v.as_array().unwrap_or_else(|| panic!("not an array: {v}"));
    assert_eq!(a.len(), 3, "{v}");
    [
        a[0].as_f64().unwrap(),
        a[1].as_f64().unwrap(),
        a[2].as_f64().unwrap(),
    ]
}

fn assert_close(actual: [f64; 3], expected: [f64; 3], what: &str) {
    for i in 0..3 {
        assert!(
            (actual[i] - expected[i]).abs() < 1e-9,
            "{what}: {actual:?} != {expected:?}"
        );
    }
}

/// A short LinuxCNC program whose moves are easy to work out by hand.
const SIMPLE: &str = "\
G21 G90 G17
G0 X10 Y0 Z5
G1 Z-1 F300
G3 X0 Y10 I-10 J0 F600
G2 X10 Y0 I0 J-10
S12000
M3
M5
M2
";

fn check_simple(items: &[Value]) {
    assert_eq!(items.len(), 8, "{items:?}");

    // Line 2: a rapid from the origin.
    let rapid = &items[0];
    assert_eq!(rapid["type"], "line");
    assert_eq!(rapid["line"], 2);
    assert_eq!(rapid["rapid"], true);
    assert_close(triple(&rapid["start"]), [0.0, 0.0, 0.0], "rapid start");
    assert_close(triple(&rapid["end"]), [10.0, 0.0, 5.0], "rapid end");
    assert!(rapid["feed_mm_min"].is_null());
    assert!(rapid.get("abc_start").is_none(), "no rotary axes in use");

    // Line 3: the plunge at F300.
    let plunge = &items[1];
    assert_eq!(plunge["type"], "line");
    assert_eq!(plunge["line"], 3);
    assert_eq!(plunge["rapid"], false);
    assert_close(triple(&plunge["start"]), [10.0, 0.0, 5.0], "plunge start");
    assert_close(triple(&plunge["end"]), [10.0, 0.0, -1.0], "plunge end");
    assert_eq!(plunge["feed_mm_min"].as_f64(), Some(300.0));

    // Line 4: a quarter circle counter-clockwise about the origin: +90° about +Z.
    let ccw = &items[2];
    assert_eq!(ccw["type"], "arc");
    assert_eq!(ccw["line"], 4);
    assert_close(triple(&ccw["start"]), [10.0, 0.0, -1.0], "G3 start");
    assert_close(triple(&ccw["end"]), [0.0, 10.0, -1.0], "G3 end");
    assert_close(triple(&ccw["center"]), [0.0, 0.0, -1.0], "G3 centre");
    assert_close(triple(&ccw["axis"]), [0.0, 0.0, 1.0], "G3 axis");
    assert!((ccw["sweep_rad"].as_f64().unwrap() - FRAC_PI_2).abs() < 1e-12);
    assert_eq!(ccw["feed_mm_min"].as_f64(), Some(600.0));
    assert!(ccw.get("rapid").is_none(), "arcs have no rapid field");

    // Line 5: the same quarter back, clockwise: -90° about +Z, feed still modal.
    let cw = &items[3];
    assert_eq!(cw["type"], "arc");
    assert_eq!(cw["line"], 5);
    assert_close(triple(&cw["start"]), [0.0, 10.0, -1.0], "G2 start");
    assert_close(triple(&cw["end"]), [10.0, 0.0, -1.0], "G2 end");
    assert_close(triple(&cw["center"]), [0.0, 0.0, -1.0], "G2 centre");
    assert!((cw["sweep_rad"].as_f64().unwrap() + FRAC_PI_2).abs() < 1e-12);
    assert_eq!(cw["feed_mm_min"].as_f64(), Some(600.0));

    // Lines 6-9: events in program order.
    let events: Vec<(u64, &str, Option<f64>)> = items[4..]
        .iter()
        .map(|e| {
            assert_eq!(e["type"], "event");
            (
                e["line"].as_u64().unwrap(),
                e["code"].as_str().unwrap(),
                e["value"].as_f64(),
            )
        })
        .collect();
    assert_eq!(
        events,
        vec![
            (6, "S", Some(12000.0)),
            (7, "M3", None),
            (8, "M5", None),
            (9, "M2", None)
        ]
    );
    for e in &items[4..] {
        assert!(e.get("value").is_some(), "value is always present: {e}");
    }
}

#[test]
fn plan_prints_the_documented_json_lines() {
    let program = scratch("simple.ngc", SIMPLE);
    let out = kerf(&["plan", program.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(stderr(&out), "");
    check_simple(&stdout_lines(&out));
}

#[test]
fn plan_reads_standard_input_for_dash() {
    let out = kerf_stdin(&["plan", "-"], SIMPLE);
    assert!(out.status.success(), "{}", stderr(&out));
    check_simple(&stdout_lines(&out));
    // The same program from a file gives the same bytes.
    let program = scratch("simple-stdin.ngc", SIMPLE);
    let from_file = kerf(&["plan", program.to_str().unwrap()]);
    assert_eq!(out.stdout, from_file.stdout);
}

#[test]
fn program_error_names_file_line_and_column_and_stops_output() {
    // Line 3 asks for a 1 mm radius to reach a point 10 mm away: no such arc exists.
    let text = "G21 G90 G17 F100\nG1 X1 Y0\nG2 X11 Y0 R1\nG1 X20\n";
    let program = scratch("bad-radius.ngc", text);
    let name = program.to_str().unwrap();
    let out = kerf(&["plan", name]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    let prefix = format!("{name}:3:");
    assert!(err.starts_with(&prefix), "{err}");
    assert!(err.contains(": error: "), "{err}");
    assert_eq!(err.lines().count(), 1, "one line: {err}");
    // The column is a positive number.
    let col: u32 = err[prefix.len()..]
        .split(':')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(col >= 1, "{err}");
    // Only the move of line 2 came out, and nothing from line 3 or after.
    let items = stdout_lines(&out);
    assert_eq!(items.len(), 1, "{items:?}");
    assert_eq!(items[0]["line"], 2);
    assert_close(triple(&items[0]["end"]), [1.0, 0.0, 0.0], "accepted move");
}

#[test]
fn program_error_on_stdin_is_named_stdin() {
    let out = kerf_stdin(&["plan", "-"], "G1 X1 F100\nG1 X2\nG2 X12 R1\n");
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(err.starts_with("<stdin>:3:"), "{err}");
    assert_eq!(stdout_lines(&out).len(), 2);
}

#[test]
fn missing_program_is_an_error_naming_it() {
    let out = kerf(&["plan", "/nonexistent/part.ngc"]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(err.starts_with("/nonexistent/part.ngc: error: "), "{err}");
    assert!(out.stdout.is_empty());
}

#[test]
fn unknown_config_key_names_the_key_and_place() {
    let config = std::fs::read_to_string(root().join("config/kerf.toml"))
        .unwrap()
        .replacen(
            "jerk_mm_s3 = 50000.0",
            "jerk_mm_s3 = 50000.0\nvelocty_mm_s = 3.0",
            1,
        );
    let config = scratch("typo.toml", &config);
    let program = scratch("typo.ngc", SIMPLE);
    let name = config.to_str().unwrap();
    let out = kerf(&["plan", "--config", name, program.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(err.starts_with(&format!("{name}:")), "{err}");
    assert!(err.contains("velocty_mm_s"), "{err}");
    assert!(err.contains("error:"), "{err}");
    assert!(
        out.stdout.is_empty(),
        "nothing is planned with a bad config"
    );
}

#[test]
fn missing_config_file_is_an_error() {
    let program = scratch("noconf.ngc", SIMPLE);
    let out = kerf(&[
        "plan",
        "--config",
        "/nonexistent/kerf.toml",
        program.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).starts_with("/nonexistent/kerf.toml: error: "),
        "{}",
        stderr(&out)
    );
}

#[test]
fn bundled_config_is_the_default() {
    let program = scratch("default-config.ngc", SIMPLE);
    let explicit = kerf(&[
        "plan",
        "--config",
        root().join("config/kerf.toml").to_str().unwrap(),
        program.to_str().unwrap(),
    ]);
    let implicit = kerf(&["plan", program.to_str().unwrap()]);
    assert!(explicit.status.success(), "{}", stderr(&explicit));
    assert_eq!(explicit.stdout, implicit.stdout);
}

/// Sinumerik radius format: `CR=` is its radius word (R is an arithmetic parameter there).
/// A semicircle of radius 5 clockwise from the origin to X10 has its centre at X5.
const SINUMERIK_SEMICIRCLE: &str = "G17 G90 F100\nG2 X10 Y0 CR=5\n";

fn assert_sinumerik_semicircle(out: &Output) {
    assert!(out.status.success(), "{}", stderr(out));
    let items = stdout_lines(out);
    assert_eq!(items.len(), 1, "{items:?}");
    let arc = &items[0];
    assert_eq!(arc["type"], "arc");
    assert_eq!(arc["line"], 2);
    assert_close(triple(&arc["center"]), [5.0, 0.0, 0.0], "CR= centre");
    assert_close(triple(&arc["end"]), [10.0, 0.0, 0.0], "CR= end");
    assert!((arc["sweep_rad"].as_f64().unwrap() + PI).abs() < 1e-9);
}

#[test]
fn dialect_follows_unambiguous_extension() {
    let mpf = scratch("semi.mpf", SINUMERIK_SEMICIRCLE);
    assert_sinumerik_semicircle(&kerf(&["plan", mpf.to_str().unwrap()]));
    let spf = scratch("semi.spf", SINUMERIK_SEMICIRCLE);
    assert_sinumerik_semicircle(&kerf(&["plan", spf.to_str().unwrap()]));
}

/// Heidenhain TNC ISO: a `%NAME G71 *` header and `*` block ends.
const HEIDENHAIN_ISO: &str = "%KERF G71 *\nN10 G01 X+10 Y+0 F100 *\nN20 G00 Z+5 *\n";

#[test]
fn heidenhain_extension_applies_only_to_iso_files() {
    for ext in ["h", "i"] {
        let program = scratch(&format!("iso.{ext}"), HEIDENHAIN_ISO);
        let out = kerf(&["plan", program.to_str().unwrap()]);
        assert!(out.status.success(), "{}", stderr(&out));
        let items = stdout_lines(&out);
        assert_eq!(items.len(), 2, "{items:?}");
        assert_eq!(items[0]["line"], 2);
        assert_close(triple(&items[0]["end"]), [10.0, 0.0, 0.0], "G01 end");
        assert_eq!(items[0]["feed_mm_min"].as_f64(), Some(100.0));
        assert_eq!(items[1]["rapid"], true);
        assert_close(triple(&items[1]["end"]), [10.0, 0.0, 5.0], "G00 end");
    }
    // The same text under an extension that names no control is read as LinuxCNC, which
    // has no `*` block end.
    let program = scratch("iso.nc", HEIDENHAIN_ISO);
    assert_eq!(
        kerf(&["plan", program.to_str().unwrap()]).status.code(),
        Some(2)
    );
    // A conversational (plain language) `.h` program is not ISO: the extension does not
    // choose Heidenhain ISO for it, and LinuxCNC rejects it on its first line.
    let program = scratch(
        "conversational.h",
        "0 BEGIN PGM KERF MM\n1 L X+10 R0 F100\n",
    );
    let out = kerf(&["plan", program.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).starts_with(&format!("{}:1:", program.display())),
        "{}",
        stderr(&out)
    );
}

#[test]
fn unknown_extension_defaults_to_linuxcnc() {
    // LinuxCNC has no `CR=` word, so the same text is an error there.
    let nc = scratch("semi.nc", SINUMERIK_SEMICIRCLE);
    let out = kerf(&["plan", nc.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).starts_with(&format!("{}:2:", nc.display())),
        "{}",
        stderr(&out)
    );
}

#[test]
fn dialect_option_and_config_choose_when_the_extension_does_not() {
    let nc = scratch("semi-opt.nc", SINUMERIK_SEMICIRCLE);
    assert_sinumerik_semicircle(&kerf(&[
        "plan",
        "--dialect",
        "sinumerik",
        nc.to_str().unwrap(),
    ]));
    // Standard input has no extension either.
    assert_sinumerik_semicircle(&kerf_stdin(
        &["plan", "--dialect", "SINUMERIK", "-"],
        SINUMERIK_SEMICIRCLE,
    ));

    let config = std::fs::read_to_string(root().join("config/kerf.toml"))
        .unwrap()
        .replacen("dialect = \"linuxcnc\"", "dialect = \"sinumerik\"", 1);
    let config = scratch("sinumerik.toml", &config);
    let config = config.to_str().unwrap();
    assert_sinumerik_semicircle(&kerf(&["plan", "--config", config, nc.to_str().unwrap()]));

    // The extension of a LinuxCNC file beats the machine's configured dialect...
    let ngc = scratch("semi.ngc", SINUMERIK_SEMICIRCLE);
    let out = kerf(&["plan", "--config", config, ngc.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    // ...and `--dialect` beats the extension.
    assert_sinumerik_semicircle(&kerf(&[
        "plan",
        "--config",
        config,
        "--dialect",
        "sinumerik",
        ngc.to_str().unwrap(),
    ]));
}

#[test]
fn unknown_dialect_option_is_a_usage_error() {
    let out = kerf(&["plan", "--dialect", "fanuc", "-"]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(err.contains("fanuc") && err.contains("heidenhain"), "{err}");
}

#[test]
fn floats_round_trip_through_the_output() {
    // Coordinates that are not exactly representable: the printed numbers must parse back
    // to the very same doubles the program text denotes.
    let x = "0.1";
    let y = "0.33333333333333331";
    let z = "-12.345678901234567";
    let f = "1234.5678";
    let program = scratch("floats.ngc", &format!("G21 G90\nG1 X{x} Y{y} Z{z} F{f}\n"));
    let out = kerf(&["plan", program.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8(out.stdout).unwrap();
    // Take the numbers from the raw text so no JSON library rounding is involved.
    let end = text
        .split("\"end\":[")
        .nth(1)
        .unwrap()
        .split(']')
        .next()
        .unwrap();
    let end: Vec<f64> = end.split(',').map(|s| s.parse().unwrap()).collect();
    let expected: Vec<f64> = [x, y, z].iter().map(|s| s.parse().unwrap()).collect();
    for (a, e) in end.iter().zip(&expected) {
        assert_eq!(a.to_bits(), e.to_bits(), "{text}");
    }
    let feed = text
        .split("\"feed_mm_min\":")
        .nth(1)
        .unwrap()
        .split('}')
        .next()
        .unwrap();
    assert_eq!(feed.parse::<f64>().unwrap(), 1234.5678);
}

#[test]
fn bundled_example_part_plans_into_a_continuous_path() {
    let part = root().join("config/examples/part.ngc");
    let out = kerf(&["plan", part.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let items = stdout_lines(&out);
    let mut position = [0.0; 3];
    let mut moves = 0;
    let mut arcs = 0;
    let mut helix_turns = 0.0;
    let mut last_line = 0;
    for item in &items {
        let line = item["line"].as_u64().unwrap();
        assert!(line >= last_line, "program order: {item}");
        last_line = line;
        if item["type"] == "event" {
            continue;
        }
        moves += 1;
        // Every move starts where the previous one ended, the first at the origin.
        assert_close(triple(&item["start"]), position, "continuity");
        position = triple(&item["end"]);
        if item["type"] == "arc" {
            arcs += 1;
            let (s, c, a) = (
                triple(&item["start"]),
                triple(&item["center"]),
                triple(&item["axis"]),
            );
            let in_plane: f64 = (0..3).map(|i| (c[i] - s[i]) * a[i]).sum();
            assert!(
                in_plane.abs() < 1e-9,
                "centre in the plane of the start: {item}"
            );
            let sweep = item["sweep_rad"].as_f64().unwrap();
            if sweep.abs() > 2.0 * PI {
                helix_turns += sweep / (2.0 * PI);
            }
        }
    }
    // The part has 5 arcs (a two-turn helix and four pocket corners), ends at X0 Y0 Z25.
    assert_eq!(arcs, 5);
    assert!(
        (helix_turns - 2.0).abs() < 1e-9,
        "helix turns {helix_turns}"
    );
    assert!(moves > 50);
    assert_close(position, [0.0, 0.0, 25.0], "end of program");
    assert_eq!(items.last().unwrap()["code"], "M30");
}

#[test]
fn closed_output_pipe_ends_quietly() {
    // A program long enough that the output cannot fit in a pipe buffer.
    let mut text = String::from("G21 G90 F1000\n");
    for i in 0..200_000 {
        text.push_str(&format!("G1 X{} Y{}\n", i % 100, i % 37));
    }
    let program = scratch("long.ngc", &text);
    let mut child = Command::new(KERF)
        .args(["plan", program.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut reader = BufReader::new(child.stdout.take().unwrap());
    let mut first = String::new();
    reader.read_line(&mut first).unwrap();
    assert!(first.starts_with("{\"type\":\"line\""), "{first}");
    drop(reader);
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert_eq!(stderr(&out), "");
}

/// The rows of a `kerf sim` CSV: header and numbers.
fn read_csv(path: &Path) -> (String, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_string();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse::<f64>().unwrap()).collect())
        .collect();
    (header, rows)
}

/// Runs `kerf sim [args] PROGRAM --out <scratch>/NAME.csv`, which must succeed, and returns
/// the CSV's header and rows.
fn sim_rows(name: &str, program: &Path, args: &[&str]) -> (String, Vec<Vec<f64>>) {
    let csv = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("kerf-cli-tests/{name}.csv"));
    let mut all = vec!["sim"];
    all.extend_from_slice(args);
    all.extend([program.to_str().unwrap(), "--out", csv.to_str().unwrap()]);
    let out = kerf(&all);
    assert!(out.status.success(), "{name}: {}", stderr(&out));
    read_csv(&csv)
}

/// 10 mm along X at F600 (10 mm/s) on the bundled mill (X: 200 mm/s, 2000 mm/s²).
const TEN_MM_AT_F600: &str = "G21 G90 G17\nG1 X10 F600\n";

#[test]
fn sim_writes_one_row_per_period_from_the_origin_to_the_end_point() {
    let program = scratch("sim-line.ngc", TEN_MM_AT_F600);
    let csv = Path::new(env!("CARGO_TARGET_TMPDIR")).join("kerf-cli-tests/sim-line.csv");
    let out = kerf(&[
        "sim",
        program.to_str().unwrap(),
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let summary = String::from_utf8(out.stdout).unwrap();
    assert!(summary.starts_with("duration "), "{summary}");
    assert_eq!(summary.lines().count(), 1, "{summary}");

    let (header, rows) = read_csv(&csv);
    assert_eq!(header, "t,x,y,z,line,feed_mm_s");
    assert_eq!(
        &rows[0][..4],
        &[0.0, 0.0, 0.0, 0.0],
        "starts at t = 0 at the origin"
    );
    // The bundled period is 1000 µs.
    for (i, row) in rows.iter().enumerate() {
        assert!(
            (row[0] - i as f64 * 0.001).abs() < 1e-9,
            "row {i}: t = {}",
            row[0]
        );
    }
    let last = rows.last().unwrap();
    assert_eq!(
        &last[1..4],
        &[10.0, 0.0, 0.0],
        "ends exactly at the programmed point"
    );
    // 10 mm at 10 mm/s takes at least 1 s; the jerk-limited start and stop at 2000 mm/s²
    // and 50000 mm/s³ add only milliseconds, so well under 1.1 s.
    let duration_s = last[0];
    assert!((1.0..1.1).contains(&duration_s), "{duration_s}");
    // The programmed feed is never exceeded (finite differences of X at the period).
    for pair in rows.windows(2) {
        let v_mm_s = (pair[1][1] - pair[0][1]) / 0.001;
        assert!((-1e-9..=10.0 * 1.01).contains(&v_mm_s), "{v_mm_s} mm/s");
    }
}

#[test]
fn sim_feed_override_scales_the_feed() {
    let program = scratch("sim-override.ngc", TEN_MM_AT_F600);
    let csv = Path::new(env!("CARGO_TARGET_TMPDIR")).join("kerf-cli-tests/sim-override.csv");
    let out = kerf(&[
        "sim",
        "--override",
        "50",
        program.to_str().unwrap(),
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let (_, rows) = read_csv(&csv);
    // At 50 % the 10 mm take at least 2 s.
    let duration_s = rows.last().unwrap()[0];
    assert!((2.0..2.2).contains(&duration_s), "{duration_s}");

    let out = kerf(&[
        "sim",
        "--override",
        "250",
        program.to_str().unwrap(),
        "--out",
        "x.csv",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("250"), "{}", stderr(&out));
}

#[test]
fn sim_rejects_a_path_outside_the_travel_before_any_motion() {
    // The bundled mill's Y travel is ±1000 mm; widen X to ±3000 mm so only Y matters.
    let config = std::fs::read_to_string(root().join("config/kerf.toml")).unwrap();
    let config = config.replacen(
        "min_mm = -1000.0\nmax_mm = 1000.0\n\n[axes.y]",
        "min_mm = -3000.0\nmax_mm = 3000.0\n\n[axes.y]",
        1,
    );
    assert!(
        config.contains("3000"),
        "the X table changed: fix this test"
    );
    let config = scratch("sim-travel.toml", &config);
    let csv = Path::new(env!("CARGO_TARGET_TMPDIR")).join("kerf-cli-tests/sim-travel.csv");
    let sim = |name: &str| {
        let _ = std::fs::remove_file(&csv);
        kerf(&[
            "sim",
            "--config",
            config.to_str().unwrap(),
            name,
            "--out",
            csv.to_str().unwrap(),
        ])
    };

    // G3 from (-5, 0) to (2005, 0) about (1000, 0) runs counter-clockwise through the
    // bottom of the circle, (1000, -1005): both end points are inside the travel, the
    // middle of the arc is not.
    let program = scratch(
        "sim-travel.ngc",
        "G21 G90 G17\nG0 X-5 Y0\nG3 X2005 Y0 I1005 J0 F600\n",
    );
    let name = program.to_str().unwrap();
    let out = sim(name);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(
        err.starts_with(&format!("{name}:3:1: error: Y -1005")),
        "{err}"
    );
    assert!(err.contains("travel"), "{err}");
    assert!(!csv.exists(), "no output for a rejected program");
    assert!(out.stdout.is_empty());

    // Clockwise, the same arc bulges upwards to Y 1005: rejected as well.
    let program = scratch(
        "sim-travel-cw.ngc",
        "G21 G90 G17\nG0 X-5 Y0\nG2 X2005 Y0 I1005 J0 F600\n",
    );
    let err = stderr(&sim(program.to_str().unwrap()));
    assert!(err.contains(":3:1: error: Y 1005"), "{err}");

    // A radius-10 arc at the same place stays inside.
    let program = scratch(
        "sim-travel-ok.ngc",
        "G21 G90 G17\nG0 X990 Y0\nG3 X1010 Y0 I10 J0 F6000\n",
    );
    let out = sim(program.to_str().unwrap());
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(csv.exists());
}

#[test]
fn sim_plot_writes_an_svg_image() {
    let program = scratch(
        "sim-plot.ngc",
        "G21 G90 G17\nG1 X10 F600\nG3 X0 Y10 I-10 J0\n",
    );
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("kerf-cli-tests");
    let (csv, svg) = (dir.join("sim-plot.csv"), dir.join("sim-plot.svg"));
    let out = kerf(&[
        "sim",
        program.to_str().unwrap(),
        "--out",
        csv.to_str().unwrap(),
        "--plot",
        svg.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let image = std::fs::read_to_string(&svg).unwrap();
    assert!(
        image.starts_with("<svg"),
        "{}",
        &image[..image.len().min(200)]
    );
    assert!(image.trim_end().ends_with("</svg>"));
    // The CSV is the same with or without a plot.
    let plain = dir.join("sim-plot-plain.csv");
    let out = kerf(&[
        "sim",
        program.to_str().unwrap(),
        "--out",
        plain.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(std::fs::read(&csv).unwrap(), std::fs::read(&plain).unwrap());
}

#[test]
fn sim_program_error_names_the_place() {
    let program = scratch("sim-bad.ngc", "G1 X1 F100\nG2 X12 R1\n");
    let name = program.to_str().unwrap();
    let out = kerf(&["sim", name, "--out", "/nonexistent/never.csv"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).starts_with(&format!("{name}:2:")),
        "{}",
        stderr(&out)
    );
}

/// The dense circle as CAM writes it: r = 10 mm through the origin, 3,600 lines at
/// F6000, vertices rounded to `decimals`.
fn cam_circle(decimals: usize) -> String {
    let mut text = String::from("G21 G90 G17 G64 F6000\n");
    for k in 1..=3600 {
        let a = 2.0 * std::f64::consts::PI * k as f64 / 3600.0;
        let (x, y) = (10.0 - 10.0 * a.cos(), 10.0 * a.sin());
        text.push_str(&format!("G1 X{x:.decimals$} Y{y:.decimals$}\n"));
    }
    text
}

#[test]
fn sim_runs_the_cam_rounded_dense_circle_at_the_feed() {
    // The limits allow about 0.72 s (0.63 s at 100 mm/s plus the jerk-limited start and
    // stop); rounded vertices must not turn into curvature noise that slows it down.
    for decimals in [3, 4, 6] {
        let name = format!("sim-circle-{decimals}");
        let program = scratch(&format!("{name}.ngc"), &cam_circle(decimals));
        let (header, rows) = sim_rows(&name, &program, &[]);
        assert_eq!(header, "t,x,y,z,line,feed_mm_s");
        let last = rows.last().unwrap();
        assert!(last[0] < 0.80, "{decimals} decimals: {} s", last[0]);
        assert_eq!(&last[1..4], &[0.0, 0.0, 0.0], "ends on the last vertex");
        // Every setpoint within the 0.01 mm tolerance of the polygon, checked here against
        // the vertices as printed; the `line` column advances through the program.
        let pts: Vec<[f64; 2]> = std::iter::once([0.0, 0.0])
            .chain(
                String::from_utf8_lossy(&std::fs::read(&program).unwrap())
                    .lines()
                    .skip(1)
                    .map(|l| {
                        let mut w = l.split(' ').skip(1);
                        let x: f64 = w.next().unwrap()[1..].parse().unwrap();
                        let y: f64 = w.next().unwrap()[1..].parse().unwrap();
                        [x, y]
                    }),
            )
            .collect();
        let mut prev_line = 0.0;
        for row in &rows {
            let line = row[4];
            assert!(
                line >= prev_line,
                "line column goes back: {line} after {prev_line}"
            );
            prev_line = line;
            // The move on source line L runs from vertex L-2 to L-1; search around it.
            let k = (line as usize).saturating_sub(2);
            let d = (k.saturating_sub(3)..(k + 4).min(pts.len() - 1))
                .map(|i| seg_distance([row[1], row[2]], pts[i], pts[i + 1]))
                .fold(f64::INFINITY, f64::min);
            assert!(
                d <= 0.01,
                "{decimals} decimals: {d} mm off at t = {}",
                row[0]
            );
        }
        assert_eq!(prev_line, 3601.0);
    }
}

fn seg_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((p[0] - a[0] - t * dx).powi(2) + (p[1] - a[1] - t * dy).powi(2)).sqrt()
}

#[test]
fn sim_override_above_100_speeds_up_arcs_too() {
    // A full circle of radius 10 mm at F3000 (50 mm/s): the centripetal acceleration at
    // 100 mm/s is 1000 mm/s², well within the bundled mill, so 150 % runs at 75 mm/s and
    // 200 % at 100 mm/s.
    let program = scratch(
        "sim-override-arc.ngc",
        "G21 G90 G17 G64 F3000\nG2 X0 Y0 I10 J0\n",
    );
    let mut durations = Vec::new();
    for pct in ["100", "150", "200"] {
        let name = format!("sim-override-arc-{pct}");
        let (_, rows) = sim_rows(&name, &program, &["--override", pct]);
        let peak = rows.iter().map(|r| r[5]).fold(0.0, f64::max);
        let want = 50.0 * pct.parse::<f64>().unwrap() / 100.0;
        assert!(
            peak > 0.99 * want && peak <= want * (1.0 + 1e-9),
            "{pct} %: peak {peak} mm/s"
        );
        durations.push(rows.last().unwrap()[0]);
    }
    // 62.8 mm at 50, 75 and 100 mm/s plus the ramps.
    assert!(
        durations[0] > 1.25 && durations[1] < 0.95 && durations[2] < 0.8,
        "{durations:?}"
    );
}

#[test]
fn sim_of_the_pocket_is_the_same_in_all_five_dialects() {
    // The pocket written for each control resolves to the same moves (to rounding), so the
    // setpoints agree row for row: same times, positions and feeds within 1e-9.
    let mut all = Vec::new();
    for (dialect, file) in [
        ("linuxcnc", "linuxcnc/pocket.ngc"),
        ("rockwell", "rockwell/pocket.nc"),
        ("sinumerik", "sinumerik/pocket.mpf"),
        ("heidenhain", "heidenhain/pocket.h"),
        ("fagor", "fagor/pocket.pim"),
    ] {
        let program = root().join("tests/data/programs").join(file);
        let name = format!("sim-pocket-{dialect}");
        all.push((
            dialect,
            sim_rows(&name, &program, &["--dialect", dialect]).1,
        ));
    }
    let (_, reference) = &all[0];
    assert!(reference.len() > 10_000);
    for (dialect, rows) in &all[1..] {
        assert_eq!(rows.len(), reference.len(), "{dialect}");
        for (a, b) in rows.iter().zip(reference) {
            assert_eq!(a[0], b[0], "{dialect}: time");
            for c in [1, 2, 3, 5] {
                assert!(
                    (a[c] - b[c]).abs() < 1e-9,
                    "{dialect} at t = {}: {a:?} {b:?}",
                    a[0]
                );
            }
        }
    }
}

#[test]
fn sim_of_the_example_part_follows_the_planned_moves_within_the_limits() {
    // Two commands cross-checked: every row `kerf sim` writes for the bundled part lies
    // within its G64 P0.01 tolerance of the moves `kerf plan` prints for it, the axes stay
    // within the bundled limits (200 mm/s, 2000 mm/s², 50000 mm/s³) by finite differences
    // at the 1 ms period (within 1 %), and the last row is the end of the last move.
    use kerf_geom::{Arc, Curve, Line, Path as GeomPath, Vec3};
    let part = root().join("config/examples/part.ngc");
    let out = kerf(&["plan", part.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v3 = |v: &Value| {
        let [x, y, z] = triple(v);
        Vec3::new(x, y, z)
    };
    let moves: Vec<Curve> = stdout_lines(&out)
        .iter()
        .filter_map(|m| match m["type"].as_str() {
            Some("line") => Some(Curve::from_path(&GeomPath::Line(Line {
                start: v3(&m["start"]),
                end: v3(&m["end"]),
            }))),
            Some("arc") => Some(Curve::from_path(&GeomPath::Arc(Arc {
                start: v3(&m["start"]),
                end: v3(&m["end"]),
                center: v3(&m["center"]),
                axis: v3(&m["axis"]),
                sweep_rad: m["sweep_rad"].as_f64().unwrap(),
            }))),
            _ => None,
        })
        .collect();
    assert!(moves.len() > 20);
    let (_, rows) = sim_rows("sim-part", &part, &[]);
    for row in &rows {
        let p = Vec3::new(row[1], row[2], row[3]);
        // The distance to the path is to its nearest move (the pocket retraces its own
        // moves, so a search that only advances can lock onto a later one).
        let d = moves
            .iter()
            .map(|m| m.distance_to(&p))
            .fold(f64::INFINITY, f64::min);
        assert!(d <= 0.01 + 1e-9, "t = {}: {d} mm off the path", row[0]);
    }
    let t = 0.001;
    let limits = [200.0, 2000.0, 50000.0];
    for w in rows.windows(4) {
        for axis in 1..4 {
            let x = |i: usize| w[i][axis];
            let v = (x(3) - x(2)) / t;
            let a = (x(3) - 2.0 * x(2) + x(1)) / (t * t);
            let j = (x(3) - 3.0 * x(2) + 3.0 * x(1) - x(0)) / (t * t * t);
            for (value, limit) in [v, a, j].iter().zip(limits) {
                assert!(
                    value.abs() <= 1.01 * limit,
                    "t = {}: axis {axis}: {value} vs {limit}",
                    w[3][0]
                );
            }
        }
    }
    let end = moves.last().unwrap().end();
    assert_eq!(&rows.last().unwrap()[1..4], &[end.x, end.y, end.z]);
}
