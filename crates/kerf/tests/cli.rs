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
/// Writes a test program. A LinuxCNC program (`.ngc`, Kerf's default dialect) must end
/// with M2/M30 or its closing `%` ("File ended with no percent sign or program end"): one
/// written without gets an `M2` line at its end.
fn scratch(name: &str, contents: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("kerf-cli-tests");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, ended(name, contents)).unwrap();
    path
}

/// `contents` with an `M2` line at its end when it is a LinuxCNC program (`.ngc`) without
/// a program end.
fn ended(name: &str, contents: &str) -> String {
    let last = contents
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("");
    let has_end = ["M2", "M30", "%"].contains(&last.trim());
    if name.ends_with(".ngc") && !has_end {
        let sep = if contents.is_empty() || contents.ends_with('\n') {
            ""
        } else {
            "\n"
        };
        format!("{contents}{sep}M2\n")
    } else {
        contents.to_string()
    }
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
    // (The M2 that `scratch` ends an `.ngc` file with is not part of the semicircle.)
    let items: Vec<_> = stdout_lines(out)
        .into_iter()
        .filter(|i| i["code"] != "M2")
        .collect();
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
    // (Without its homing tables: `kerf sim` does not home, and X's table is then one.)
    let config = kerf_testkit::config_text::without_homing(
        &std::fs::read_to_string(root().join("config/kerf.toml")).unwrap(),
    );
    // The first travel in the file is X's.
    let config = config.replacen(
        "min_mm = -1000.0\nmax_mm = 1000.0\n",
        "min_mm = -3000.0\nmax_mm = 3000.0\n",
        1,
    );
    assert!(
        config.contains("min_mm = -3000.0"),
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

    // `.png` (any case) gives a PNG image, and the same CSV.
    let (png_csv, png) = (dir.join("sim-plot-png.csv"), dir.join("sim-plot.PNG"));
    let out = kerf(&[
        "sim",
        program.to_str().unwrap(),
        "--out",
        png_csv.to_str().unwrap(),
        "--plot",
        png.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let image = std::fs::read(&png).unwrap();
    assert!(image.starts_with(b"\x89PNG\r\n\x1a\n"), "{:?}", &image[..8]);
    assert_eq!(
        std::fs::read(&png_csv).unwrap(),
        std::fs::read(&plain).unwrap()
    );

    // `--plot -`: the SVG alone on standard output (the summary goes to standard error).
    let out = kerf(&[
        "sim",
        program.to_str().unwrap(),
        "--out",
        plain.to_str().unwrap(),
        "--plot",
        "-",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        out.stdout == std::fs::read(&svg).unwrap(),
        "stdout is not the SVG"
    );
    assert!(stderr(&out).starts_with("duration "), "{}", stderr(&out));
}

#[test]
fn sim_plot_of_another_format_is_refused_before_the_run() {
    // The program would fail too (outside the travel): the plot's name is checked first,
    // and nothing is written.
    let program = scratch("sim-plot-jpg.ngc", "G21 G90\nG1 X5000 F600\n");
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("kerf-cli-tests");
    let (csv, jpg) = (dir.join("sim-plot-jpg.csv"), dir.join("sim-plot.jpg"));
    let out = kerf(&[
        "sim",
        program.to_str().unwrap(),
        "--out",
        csv.to_str().unwrap(),
        "--plot",
        jpg.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert_eq!(
        err,
        format!(
            "{}: error: the plot format is chosen by the file name, which must end in .svg or .png\n",
            jpg.display()
        )
    );
    assert!(!csv.exists() && !jpg.exists());
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
        let a = 2.0 * PI * k as f64 / 3600.0;
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
                    .filter(|l| l.starts_with('G'))
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

// ---------------------------------------------------------------------------------------
// Issue 7: the limit check on every setpoint, the planned path inside the travel, and the
// two streaming passes of `kerf sim`.
// ---------------------------------------------------------------------------------------

/// The fast machine: 1 ms, 0.01 mm, and on X, Y, Z 1,000 mm/s, 100,000 mm/s²,
/// 10,000,000 mm/s³, travel ±10,000 mm.
const FAST_MACHINE: &str = "period_us = 1000\ntolerance_mm = 0.01\n\
    [axes.x]\nvelocity_mm_s = 1000\nacceleration_mm_s2 = 100000\njerk_mm_s3 = 10000000\nmin_mm = -10000\nmax_mm = 10000\n\
    [axes.y]\nvelocity_mm_s = 1000\nacceleration_mm_s2 = 100000\njerk_mm_s3 = 10000000\nmin_mm = -10000\nmax_mm = 10000\n\
    [axes.z]\nvelocity_mm_s = 1000\nacceleration_mm_s2 = 100000\njerk_mm_s3 = 10000000\nmin_mm = -10000\nmax_mm = 10000\n";

/// Runs `kerf sim` and returns the output and the CSV's rows if one was written.
fn sim_any(name: &str, program: &Path, args: &[&str]) -> (Output, Option<Vec<Vec<f64>>>) {
    let csv = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("kerf-cli-tests/{name}.csv"));
    let _ = std::fs::remove_file(&csv);
    let mut all = vec!["sim"];
    all.extend_from_slice(args);
    all.extend([program.to_str().unwrap(), "--out", csv.to_str().unwrap()]);
    let out = kerf(&all);
    let rows = csv.exists().then(|| read_csv(&csv).1);
    (out, rows)
}

/// The summary's percentages (`X v 95% a 95% j 96%; ...`), all of them.
fn summary_percentages(summary: &str) -> Vec<f64> {
    summary
        .split([';', ' '])
        .filter_map(|w| w.strip_suffix('%'))
        .map(|p| p.parse::<f64>().unwrap())
        .collect()
}

/// Velocity, acceleration and jerk of column `axis` at row `k` by finite differences at
/// `period_s`, with the machine at rest at row 0's position before t = 0.
fn differences(rows: &[Vec<f64>], axis: usize, k: usize, period_s: f64) -> [f64; 3] {
    let x = |i: usize| {
        if i <= k {
            rows[k - i][axis]
        } else {
            rows[0][axis]
        }
    };
    [
        (x(0) - x(1)) / period_s,
        (x(0) - 2.0 * x(1) + x(2)) / period_s.powi(2),
        (x(0) - 3.0 * x(1) + 3.0 * x(2) - x(3)) / period_s.powi(3),
    ]
}

#[test]
fn sim_on_the_fast_machine_either_holds_the_limits_or_stops_at_the_first_fault() {
    // The reproducer: the helix once ran as a 4.14 mm jump in one period with exit
    // 0. Whatever the motion core does with it, exit 0 must mean that every row is within
    // the limits (1 % by finite differences from the CSV) and the summary shows at most
    // 101 %; a fault must be exit 2 with one line naming the time, axis and ratio of the
    // CSV's last row, and every earlier row within the limits.
    let config = scratch("fast.toml", FAST_MACHINE);
    let program = scratch(
        "fast-helix.ngc",
        "G21 G90 G17 F3000\nG2 X-1.0117 Y-4.0119 Z0.0635 I-1.5765 J-1.7360\nM2\n",
    );
    let (out, rows) = sim_any(
        "fast-helix",
        &program,
        &["--config", config.to_str().unwrap()],
    );
    let rows = rows.expect("the CSV is written up to the fault");
    let limits = [1000.0, 100000.0, 1e7];
    let within = |k: usize| {
        (1..4).all(|axis| {
            let d = differences(&rows, axis, k, 0.001);
            (0..3).all(|q| d[q].abs() <= 1.01 * limits[q] + 1e-6 * limits[q])
        })
    };
    match out.status.code() {
        Some(0) => {
            assert!((0..rows.len()).all(within), "exit 0 with a limit broken");
            let summary = String::from_utf8(out.stdout.clone()).unwrap();
            let p = summary_percentages(&summary);
            assert_eq!(p.len(), 9, "{summary}");
            assert!(p.iter().all(|&p| p <= 101.0), "{summary}");
            let last = rows.last().unwrap();
            assert_eq!(&last[1..4], &[-1.0117, -4.0119, 0.0635]);
        }
        Some(2) => {
            let err = stderr(&out);
            assert_eq!(err.lines().count(), 1, "{err}");
            assert!(out.stdout.is_empty(), "no summary after a fault");
            // `NAME: error: setpoint at t = T s (line L): AXIS QUANTITY P % of the limit
            // (KEY = LIMIT)`
            let prefix = format!("{}: error: setpoint at t = ", program.display());
            let rest = err.strip_prefix(&prefix).unwrap_or_else(|| panic!("{err}"));
            let (t, rest) = rest
                .split_once(" s (line 2): ")
                .unwrap_or_else(|| panic!("{err}"));
            let words: Vec<&str> = rest.split_whitespace().collect();
            let axis = match words[0] {
                "X" => 1,
                "Y" => 2,
                "Z" => 3,
                other => panic!("axis {other}: {err}"),
            };
            let (q, key) = match words[1] {
                "velocity" => (0, "(velocity_mm_s"),
                "acceleration" => (1, "(acceleration_mm_s2"),
                "jerk" => (2, "(jerk_mm_s3"),
                other => panic!("quantity {other}: {err}"),
            };
            let percent: f64 = words[2].parse().unwrap();
            assert_eq!(&words[3..8], &["%", "of", "the", "limit", key], "{err}");
            let last = rows.last().unwrap();
            assert_eq!(
                last[0],
                t.parse::<f64>().unwrap(),
                "the CSV ends at the fault"
            );
            let k = rows.len() - 1;
            let measured = differences(&rows, axis, k, 0.001)[q].abs() / limits[q] * 100.0;
            assert!(
                (measured - percent).abs() <= 0.5 + 1e-6 * measured,
                "{err}: measured {measured} %"
            );
            assert!(percent > 101.0, "{err}");
            assert!(
                (0..k).all(within),
                "an earlier row broke a limit unreported"
            );
        }
        other => panic!("exit {other:?}: {}", stderr(&out)),
    }
}

#[test]
fn sim_summary_never_shows_more_than_101_percent_on_success() {
    // The bundled part and a fast-machine polyline: successful runs, every figure ≤ 101 %.
    let config = scratch("fast-poly.toml", FAST_MACHINE);
    let poly = scratch(
        "fast-poly.ngc",
        "G21 G90 G17 F6000\nG1 X10 Y1\nG1 X20 Y-1\nG1 X30 Y2\nG3 X40 Y2 R5\nG1 Z-3\nG0 X0 Y0 Z0\n",
    );
    let part = root().join("config/examples/part.ngc");
    for (name, program, args) in [
        ("summary-part", part.as_path(), vec![]),
        (
            "summary-fast",
            poly.as_path(),
            vec!["--config", config.to_str().unwrap()],
        ),
    ] {
        let (out, _) = sim_any(name, program, &args);
        if out.status.code() == Some(0) {
            let summary = String::from_utf8(out.stdout).unwrap();
            let p = summary_percentages(&summary);
            assert_eq!(p.len(), 9, "{summary}");
            assert!(p.iter().all(|&p| p <= 101.0), "{name}: {summary}");
        } else {
            // A fault is reported as such, never as a success.
            assert_eq!(out.status.code(), Some(2), "{name}");
            assert!(stderr(&out).contains("of the limit"), "{}", stderr(&out));
        }
    }
}

/// The bundled config (without its homing tables: `kerf sim` does not home) with X travel
/// `-1000 ..= x_max_mm`.
fn config_with_x_max(name: &str, x_max_mm: f64) -> PathBuf {
    let config = kerf_testkit::config_text::without_homing(
        &std::fs::read_to_string(root().join("config/kerf.toml")).unwrap(),
    );
    // The first travel in the file is X's.
    let changed = config.replacen(
        "min_mm = -1000.0\nmax_mm = 1000.0\n",
        &format!("min_mm = -1000.0\nmax_mm = {x_max_mm:?}\n"),
        1,
    );
    assert_ne!(changed, config, "the X table changed: fix this test");
    scratch(name, &changed)
}

/// Runs a program whose programmed moves touch X = 1000 on the bundled mill (travel
/// ±1000 mm): either it is refused before motion naming `line` with the planned path's
/// excess, and with a wider travel its setpoints really pass X 1000 by about that much;
/// or it runs and no setpoint passes X 1000.
fn assert_inside_or_refused(name: &str, text: &str, line: usize) {
    let program = scratch(&format!("{name}.ngc"), text);
    let (out, rows) = sim_any(name, &program, &[]);
    match out.status.code() {
        Some(0) => {
            let max_x = rows.unwrap().iter().map(|r| r[1]).fold(f64::MIN, f64::max);
            assert!(max_x <= 1000.0 + 1e-9, "{name}: setpoints reach X {max_x}");
        }
        Some(2) => {
            let err = stderr(&out);
            let prefix = format!("{}:{line}:1: error: the ", program.display());
            assert!(err.starts_with(&prefix), "{name}: {err}");
            assert!(
                err.contains("leaves the X travel (max_mm = 1000) by "),
                "{name}: {err}"
            );
            let hint = err.trim_end().rsplit("; ").next().unwrap();
            assert!(
                hint == "lower the tolerance (G64 P) or move the corner inside"
                    || hint == "lower the tolerance (G64 P) or move the path inside",
                "{name}: {err}"
            );
            assert!(rows.is_none(), "{name}: no CSV for a refused program");
            assert!(out.stdout.is_empty());
            let by: f64 = err
                .split("by ")
                .nth(1)
                .and_then(|r| r.split(' ').next())
                .unwrap()
                .parse()
                .unwrap();
            // The same program with room beyond X 1000: the setpoints pass it, by at
            // most the stated amount (the planned curve's farthest point; the setpoints
            // sample it) and by more than a tenth of it.
            let wide = config_with_x_max(&format!("{name}-wide.toml"), 1001.0);
            let (out, rows) = sim_any(
                &format!("{name}-wide"),
                &program,
                &["--config", wide.to_str().unwrap()],
            );
            assert!(out.status.success(), "{}", stderr(&out));
            let over = rows.unwrap().iter().map(|r| r[1]).fold(f64::MIN, f64::max) - 1000.0;
            assert!(
                over > 0.1 * by && over <= 1.05 * by + 5e-4,
                "{name}: setpoints pass X 1000 by {over} mm, the message says {by}"
            );
        }
        other => panic!("{name}: exit {other:?}: {}", stderr(&out)),
    }
}

#[test]
fn sim_corner_blend_at_the_travel_limit_stays_inside_or_is_refused() {
    // A square with two corners on X = 1000 (stops at 90°), and shallow 5° and 10° kinks
    // whose vertex is on X = 1000 and whose second line runs along it: the G2 corner blend
    // ends tangent to the limit and may bulge past it.
    assert_inside_or_refused(
        "travel-square",
        "G21 G90 G17 G64 F3000\nG1 X980 Y0\nG1 X1000 Y0\nG1 X1000 Y20\nG1 X980 Y20\nG1 X980 Y0\n",
        4,
    );
    for (name, deg) in [("travel-kink-5", 5.0f64), ("travel-kink-10", 10.0)] {
        let a = deg.to_radians();
        let text = format!(
            "G21 G90 G17 G64 F3000\nG0 X{:.4} Y{:.4}\nG1 X1000 Y0\nG1 X1000 Y20\n",
            1000.0 - 20.0 * a.sin(),
            -20.0 * a.cos()
        );
        assert_inside_or_refused(name, &text, 4);
    }
}

#[test]
fn sim_smoothed_cam_polyline_touching_the_travel_limit_stays_inside_or_is_refused() {
    // CAM-like: a quarter circle of radius 10 mm in 0.2 mm steps (3 decimals) that becomes
    // tangent to X = 1000, then 20 mm of points along X = 1000; smoothed into quintics.
    let mut text = String::from("G21 G90 G17 G64 F3000\nG0 X990 Y-20\n");
    let n = (10.0 * FRAC_PI_2 / 0.2) as usize;
    for k in 1..=n {
        let a = -FRAC_PI_2 + FRAC_PI_2 * k as f64 / n as f64;
        text += &format!(
            "G1 X{:.3} Y{:.3}\n",
            990.0 + 10.0 * a.cos(),
            -10.0 + 10.0 * a.sin()
        );
    }
    for k in 1..=100 {
        text += &format!("G1 X1000 Y{:.3}\n", -10.0 + 0.2 * k as f64);
    }
    // The line named is among the moves near where the curve meets X = 1000: the last
    // of the arc's points or the first few along the limit.
    let program = scratch("travel-cam.ngc", &text);
    let (out, _) = sim_any("travel-cam-probe", &program, &[]);
    let line = match out.status.code() {
        Some(2) => {
            let err = stderr(&out);
            let rest = err
                .strip_prefix(&format!("{}:", program.display()))
                .unwrap();
            let line: usize = rest.split(':').next().unwrap().parse().unwrap();
            assert!((n + 2 - 5..=n + 2 + 20).contains(&line), "{err}");
            line
        }
        _ => 0,
    };
    assert_inside_or_refused("travel-cam", &text, line);
    // A programmed move outside still fails as before, naming its own line.
    let outside = text.replacen("G0 X990 Y-20\n", "G0 X1000.5 Y-20\n", 1);
    let program = scratch("travel-cam-out.ngc", &outside);
    let (out, rows) = sim_any("travel-cam-out", &program, &[]);
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(
        stderr(&out),
        format!(
            "{}:2:1: error: X 1000.5 mm is outside the travel of the X axis (-1000 mm to 1000 mm)\n",
            program.display()
        )
    );
    assert!(rows.is_none());
}

#[test]
fn sim_reads_standard_input_twice_through_a_spool_with_the_same_output() {
    let text = cam_circle(3);
    let program = scratch("stdin-circle.ngc", &text);
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("kerf-cli-tests");
    let (from_file, from_stdin) = (dir.join("stdin-file.csv"), dir.join("stdin-pipe.csv"));
    let a = kerf(&[
        "sim",
        program.to_str().unwrap(),
        "--out",
        from_file.to_str().unwrap(),
    ]);
    assert!(a.status.success(), "{}", stderr(&a));
    let b = kerf_stdin(
        &["sim", "-", "--out", from_stdin.to_str().unwrap()],
        &ended("stdin.ngc", &text),
    );
    assert!(b.status.success(), "{}", stderr(&b));
    assert_eq!(a.stdout, b.stdout, "the same summary");
    assert_eq!(
        std::fs::read(&from_file).unwrap(),
        std::fs::read(&from_stdin).unwrap()
    );
    // An error on standard input is still named `<stdin>` with its place.
    let out = kerf_stdin(
        &["sim", "-", "--out", from_stdin.to_str().unwrap()],
        "G1 X1 F100\nG2 X12 R1\n",
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).starts_with("<stdin>:2:"), "{}", stderr(&out));
}

/// The rows at rest at exactly `p` (x, y), in runs of consecutive rows: (first row, count).
fn rests_at(rows: &[Vec<f64>], p: [f64; 2]) -> Vec<(usize, usize)> {
    let mut runs: Vec<(usize, usize)> = Vec::new();
    for (k, r) in rows.iter().enumerate() {
        if r[1] == p[0] && r[2] == p[1] {
            match runs.last_mut() {
                Some((first, n)) if *first + *n == k => *n += 1,
                _ => runs.push((k, 1)),
            }
        }
    }
    runs
}

#[test]
fn sim_dwells_at_an_exact_stop_for_the_programmed_time_in_every_dialect() {
    // A square corner at (10, 0) with a 0.5 s dwell between the two lines: the machine
    // must reach the corner exactly (no blend across the dwell), rest there for 500
    // periods of 1 ms, then go on. Without the dwell the corner is blended.
    let programs = [
        (
            "dwell.ngc",
            "G21 G90 G17 G64\nG1 X10 F600\nG4 P0.5\nG1 Y10\nM2\n",
        ),
        (
            "dwell.mpf",
            "G71 G90 G17 G64\nG1 X10 F600\nG4 F0.5\nG1 Y10\nM30\n",
        ),
        (
            "dwell_r.nc",
            "G21 G90 G17\nG1 X10 F600\nG04 X0.5\nG1 Y10\nM2\n",
        ),
        (
            "dwell.h",
            "%D G71 *\nG01 X+10 F600 *\nG04 F0.5 *\nG01 Y+10 *\nN99 %D G71 *\n",
        ),
        (
            "dwell.pim",
            "G71 G90 G17\nG01 X10 F600\nG04 K0.5\nG01 Y10\nM30\n",
        ),
    ];
    for (name, text) in programs {
        let program = scratch(name, text);
        let dialect = match name {
            "dwell_r.nc" => vec!["--dialect", "rockwell"],
            "dwell.pim" => vec!["--dialect", "fagor"],
            _ => vec![],
        };
        let (_, rows) = sim_rows(name, &program, &dialect);
        let rests = rests_at(&rows, [10.0, 0.0]);
        assert_eq!(rests.len(), 1, "{name}: {rests:?}");
        let (first, count) = rests[0];
        // Arrival row, 500 dwell periods, and the row the next move starts from.
        assert!((501..=502).contains(&count), "{name}: rested {count} rows");
        assert!(first > 900, "{name}: reached the corner at row {first}");
        let last = rows.last().unwrap();
        assert_eq!([last[1], last[2]], [10.0, 10.0], "{name}: end");
    }
    // The rest is the dwell's: the same corner without it does not rest there.
    let program = scratch("no_dwell.ngc", "G21 G90 G17 G64\nG1 X10 F600\nG1 Y10\nM2\n");
    let (_, rows) = sim_rows("no_dwell", &program, &[]);
    assert!(
        rests_at(&rows, [10.0, 0.0]).iter().all(|r| r.1 < 3),
        "rested without a dwell"
    );
}

#[test]
fn sim_stops_exactly_where_the_spindle_changes() {
    // M5 between two lines: the control waits for the motion before it stops the spindle,
    // so the corner is not blended: every setpoint lies on one of the two lines. A tool
    // selection (T) does not stop the motion, and the corner is blended.
    // The second line turns by 26.6° towards (20, 5), a corner the planner blends.
    let on_the_lines = |rows: &[Vec<f64>]| {
        rows.iter().all(|r| {
            let (x, y) = (r[1], r[2]);
            y.abs() <= 1e-9 || (x >= 10.0 && (y - (x - 10.0) / 2.0).abs() <= 1e-9)
        })
    };
    let program = scratch(
        "m5.ngc",
        "G21 G90 G17 G64\nG1 X10 F600\nM5\nG1 X20 Y5\nM2\n",
    );
    let (_, rows) = sim_rows("m5", &program, &[]);
    assert!(on_the_lines(&rows), "M5: the corner was blended");
    // T1: the bundled config's tool table holds tool 1 (LinuxCNC refuses other tools).
    let program = scratch(
        "t1.ngc",
        "G21 G90 G17 G64\nG1 X10 F600\nT1\nG1 X20 Y5\nM2\n",
    );
    let (_, rows) = sim_rows("t1", &program, &[]);
    assert!(!on_the_lines(&rows), "T1: the corner should be blended");
}

/// `--out` naming a device or a pipe writes into it: the temporary file renamed over the
/// target, right for a regular file, would replace `/dev/null` with a regular file when
/// run as root (it did). A FIFO stands in for the device here (replacing the real
/// `/dev/null` would break everything after a failure).
#[test]
fn sim_out_to_a_pipe_writes_into_it_and_leaves_it_a_pipe() {
    use std::os::unix::fs::FileTypeExt;
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("kerf-cli-tests");
    std::fs::create_dir_all(&dir).unwrap();
    let fifo = dir.join("out.fifo");
    let _ = std::fs::remove_file(&fifo);
    let made = Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo runs");
    assert!(made.success());
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read_to_string(&fifo).unwrap())
    };
    let program = scratch("fifo.ngc", "G21 G90 G1 X2 F600\nM2\n");
    let out = kerf(&[
        "sim",
        program.to_str().unwrap(),
        "--out",
        fifo.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    // Checked before joining the reader, which waits for a writer that never came if
    // the pipe was replaced.
    let kind = std::fs::symlink_metadata(&fifo).unwrap().file_type();
    assert!(kind.is_fifo(), "the pipe was replaced: {kind:?}");
    let text = reader.join().unwrap();
    assert!(text.starts_with("t,x,y,z,line,feed_mm_s\n"), "{text}");
    assert!(text.lines().count() > 10, "{text}");
    std::fs::remove_file(&fifo).unwrap();
}
