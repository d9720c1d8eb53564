//! The configuration file's tests: every key's checks and errors.

use std::path::PathBuf;

use kerf_drive::MAX_AXES;
use kerf_drive::safety::AxisSafety;
use kerf_drive::sim::SimConfig;
use kerf_gcode::Dialect;

use super::*;
use crate::toml_words::position_of;

const MINIMAL: &str = r#"
[axes.x]
velocity_mm_s = 100
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10000.0
min_mm = -10.0
max_mm = 10.0
[axes.y]
velocity_mm_s = 100.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10000.0
min_mm = -10.0
max_mm = 10.0
[axes.z]
velocity_mm_s = 100.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10000.0
min_mm = -10.0
max_mm = 10.0
"#;

fn err(text: &str) -> String {
    match Config::from_toml_str(text, "m.toml") {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn builtin_config_is_valid_and_is_the_documented_mill() {
    let c = Config::from_toml_str(BUILTIN_TOML, BUILTIN_ORIGIN).expect("bundled config");
    assert_eq!(c.dialect, Some(Dialect::LinuxCnc));
    assert_eq!(c.period_us, 1000);
    assert_eq!(c.tolerance_mm, 0.01);
    assert_eq!(c.axes.x.velocity_mm_s, 200.0);
    assert_eq!(c.axes.x.acceleration_mm_s2, 2000.0);
    assert_eq!(c.axes.x.jerk_mm_s3, 50000.0);
    assert_eq!((c.axes.x.min_mm, c.axes.x.max_mm), (-1000.0, 1000.0));
    assert_eq!(c.axes.a, None);
    assert_eq!(Config::builtin(), c);
}

#[test]
fn minimal_config_takes_documented_defaults() {
    let c = Config::from_toml_str(MINIMAL, "m.toml").unwrap();
    assert_eq!(c.dialect, None);
    assert_eq!(c.period_us, 1000);
    assert_eq!(c.tolerance_mm, 0.01);
    // An integer where a float is expected is accepted as the same number.
    assert_eq!(c.axes.x.velocity_mm_s, 100.0);
    assert_eq!(c.arc_tolerance_mm, 0.02828);
    assert_eq!(c.arc_tolerance_rel, 0.001);
    assert_eq!(c.work_offsets_mm, [[0.0; 3]; 9]);
    assert!(c.tools.is_empty());
}

#[test]
fn unknown_top_level_key_is_named_with_its_place() {
    let text = format!("dialect = \"fagor\"\nperiod_ms = 1\n{MINIMAL}");
    let e = err(&text);
    assert!(e.starts_with("m.toml:2:1: error: "), "{e}");
    assert!(e.contains("period_ms"), "{e}");
}

#[test]
fn unknown_axis_key_is_named() {
    let text = MINIMAL.replace(
        "jerk_mm_s3 = 10000.0\nmin_mm = -10.0\nmax_mm = 10.0\n[axes.y]",
        "jerk_mm_s3 = 10000.0\nmin_mm = -10.0\nmax_mm = 10.0\nfeed_mm_s = 3.0\n[axes.y]",
    );
    let e = err(&text);
    assert!(e.contains("feed_mm_s"), "{e}");
    // The unknown key is on line 8 of the text (MINIMAL starts with an empty line).
    assert!(e.starts_with("m.toml:8:"), "{e}");
}

#[test]
fn unknown_axis_table_is_named() {
    let text = format!("{MINIMAL}[axes.u]\nvelocity_mm_s = 1.0\n");
    let e = err(&text);
    assert!(e.contains("unknown key `axes.u`"), "{e}");
}

/// Every key of the file, each in its table (the values are valid).
const EVERY_KEY: &str = r#"machine = "m1"
dialect = "fagor"
period_us = 1000
tolerance_mm = 0.01
[axes.x]
velocity_mm_s = 100.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10000.0
min_mm = -10.0
max_mm = 10.0
ferror_mm = 1.0
min_ferror_mm = 0.1
[axes.x.drive]
kind = "sim"
counts_per_mm = 1000.0
direction = 1
bandwidth_hz = 50.0
damping = 1.0
velocity_feed_forward = 1.0
substeps = 20
overcurrent_accel_counts_s2 = 1e9
quick_stop_decel_counts_s2 = 1e6
following_error_window_counts = 1000
enable_timeout_ms = 100
[axes.y]
velocity_mm_s = 100.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10000.0
min_mm = -10.0
max_mm = 10.0
[axes.z]
velocity_mm_s = 100.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10000.0
min_mm = -10.0
max_mm = 10.0
[axes.c]
velocity_deg_s = 360.0
acceleration_deg_s2 = 3600.0
jerk_deg_s3 = 90000.0
min_deg = -720.0
max_deg = 720.0
ferror_deg = 1.0
min_ferror_deg = 0.1
[axes.c.drive]
counts_per_deg = 100.0
[safety]
margin = 0.05
stall_cycles = 100
recorder_seconds = 1.0
[daemon]
priority = 80
cpu = 1
queue_segments = 4096
move_window = 1024
state_file = "state.toml"
[gcode]
arc_tolerance_mm = 0.02
arc_tolerance_rel = 0.001
subroutine_path = ["subs"]
max_loop_iterations = 1000
block_delete = true
g28_home_mm_deg = [0.0, 0.0, 0.0]
g30_home_mm_deg = [0.0, 0.0, 0.0]
[work_offsets]
g54 = [0.0, 0.0, 0.0]
g55 = [0.0, 0.0, 0.0]
g56 = [0.0, 0.0, 0.0]
g57 = [0.0, 0.0, 0.0]
g58 = [0.0, 0.0, 0.0]
g59 = [0.0, 0.0, 0.0]
g59_1 = [0.0, 0.0, 0.0]
g59_2 = [0.0, 0.0, 0.0]
g59_3 = [0.0, 0.0, 0.0]
[[tools]]
number = 1
length_mm = 0.0
radius_mm = 0.0
[[io.digital_outputs]]
number = 0
name = "change"
[[io.digital_inputs]]
number = 0
name = "changed"
sim = true
[[io.analog_outputs]]
number = 0
name = "tool_number"
[[io.analog_inputs]]
number = 0
name = "force"
sim = 0.5
[spindle]
kind = "drive"
max_rpm = 24000.0
min_rpm = 100.0
acceleration_rpm_s = 8000.0
at_speed_tolerance = 0.02
at_speed_timeout_s = 10.0
fault_out_of_band = true
orient_timeout_s = 5.0
counts_per_rev = 10000.0
off_at_end = true
off_at_abort = true
off_at_fault = true
[coolant]
off_at_end = true
off_at_abort = true
off_at_fault = true
[tool_changer]
kind = "automatic"
number_output = "tool_number"
change_output = "change"
changed_input = "changed"
timeout_s = 30.0
[operator]
optional_stop = true
single_block = true
"#;

/// A value of every key replaced by one of a wrong type is refused naming the key, in
/// words and units, with the value as written, at the value's place; never in serde's
/// Rust terms.
#[test]
fn every_type_error_names_the_key_and_the_expected_value_in_the_files_terms() {
    Config::from_toml_str(EVERY_KEY, "m.toml").expect("EVERY_KEY is valid");
    let mut table = String::new();
    let mut checked = 0;
    for (i, line) in EVERY_KEY.lines().enumerate() {
        if let Some(header) = line.strip_prefix("[[").and_then(|l| l.strip_suffix("]]")) {
            table = format!("{header}[0].");
            continue;
        }
        if let Some(header) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            table = format!("{header}.");
            continue;
        }
        let Some((key, value)) = line.split_once(" = ") else {
            continue;
        };
        let wrong = if value.starts_with('"') || value.starts_with('[') {
            "1.5"
        } else if value == "true" {
            "1"
        } else {
            "\"1.5\""
        };
        let wrong_line = format!("{key} = {wrong}");
        let text: Vec<&str> = EVERY_KEY
            .lines()
            .enumerate()
            .map(|(j, l)| if j == i { wrong_line.as_str() } else { l })
            .collect();
        let text = text.join("\n");
        let e = err(&text);
        let place = format!("m.toml:{}:{}: error: ", i + 1, key.len() + 4);
        let expected = format!("{place}`{table}{key}` must be ");
        assert!(e.starts_with(&expected), "{key} = {wrong}: {e}");
        assert!(
            e.ends_with(&format!(", found {wrong}")),
            "{key} = {wrong}: {e}"
        );
        for rust in [
            "invalid type",
            "expected",
            "i64",
            "f64",
            "sequence",
            "field",
        ] {
            assert!(!e.contains(rust), "{key} = {wrong}: {e}");
        }
        checked += 1;
    }
    // 4 top-level keys, 7 + 11 of X and its drive, 5 of Y, 5 of Z, 7 + 1 of C and its
    // drive, 3 of [safety], 5 of [daemon], 7 of [gcode], 9 work offsets, 3 of a tool,
    // 2 + 3 + 2 + 3 of [io], 12 of [spindle], 3 of [coolant], 5 of [tool_changer], 2 of
    // [operator].
    assert_eq!(checked, 67 + 10 + 12 + 3 + 5 + 2);
    // The messages of some keys in full: the unit comes from the key's name.
    let e = err(&EVERY_KEY.replacen("period_us = 1000", "period_us = 1.5", 1));
    assert_eq!(
        e,
        "m.toml:3:13: error: `period_us` must be a whole number of microseconds, found 1.5"
    );
    let e = err(&EVERY_KEY.replacen("jerk_deg_s3 = 90000.0", "jerk_deg_s3 = \"fast\"", 1));
    assert!(
        e.ends_with("`axes.c.jerk_deg_s3` must be a number in degrees/s³, found \"fast\""),
        "{e}"
    );
    let e = err(&EVERY_KEY.replacen("block_delete = true", "block_delete = 1", 1));
    assert!(
        e.ends_with("`gcode.block_delete` must be true or false, found 1"),
        "{e}"
    );
    let e = err(&EVERY_KEY.replacen("machine = \"m1\"", "machine = m1", 1));
    assert!(e.contains("error: "), "a syntax error stays one: {e}");
}

#[test]
fn missing_keys_and_tables_are_named_with_their_table() {
    let e = err(&EVERY_KEY.replacen("max_mm = 10.0\nferror_mm", "ferror_mm", 1));
    assert_eq!(e, "m.toml:5:1: error: missing key `axes.x.max_mm`");
    let e = err("period_us = 1000\n");
    assert_eq!(e, "m.toml:1:1: error: missing table [axes]");
    let e = err(&format!("{MINIMAL}[[tools]]\nlength_mm = 1.0\n"));
    assert!(e.ends_with("error: missing key `tools[0].number`"), "{e}");
}

#[test]
fn missing_required_axis_is_reported() {
    let text = MINIMAL.split("[axes.z]").next().unwrap();
    let e = err(text);
    assert!(e.contains("error: missing table [axes.z]"), "{e}");
}

#[test]
fn non_positive_limit_points_at_the_value() {
    let text = MINIMAL.replacen(
        "acceleration_mm_s2 = 1000.0",
        "acceleration_mm_s2 = -5.0",
        1,
    );
    let e = err(&text);
    // Line 4, after `acceleration_mm_s2 = ` (21 characters).
    assert!(e.starts_with("m.toml:4:22: error: "), "{e}");
    assert!(e.contains("axes.x.acceleration_mm_s2"), "{e}");
    assert!(e.contains("-5"), "{e}");
}

#[test]
fn zero_jerk_and_infinite_velocity_are_rejected() {
    let e = err(&MINIMAL.replacen("jerk_mm_s3 = 10000.0", "jerk_mm_s3 = 0", 1));
    assert!(e.contains("axes.x.jerk_mm_s3"), "{e}");
    let e = err(&MINIMAL.replacen("velocity_mm_s = 100.0", "velocity_mm_s = inf", 1));
    assert!(e.contains("axes.y.velocity_mm_s"), "{e}");
    let e = err(&MINIMAL.replacen("velocity_mm_s = 100.0", "velocity_mm_s = nan", 1));
    assert!(e.contains("axes.y.velocity_mm_s"), "{e}");
}

#[test]
fn min_must_be_below_max() {
    let e = err(&MINIMAL.replacen("max_mm = 10.0", "max_mm = -10.0", 1));
    assert!(e.contains("axes.x.max_mm"), "{e}");
    assert!(e.contains("axes.x.min_mm"), "{e}");
    let e = err(&MINIMAL.replacen("min_mm = -10.0", "min_mm = 10.0", 1));
    assert!(e.contains("greater than"), "{e}");
}

#[test]
fn period_must_be_positive() {
    for bad in ["0", "-1000", "5000000000"] {
        let e = err(&format!("period_us = {bad}\n{MINIMAL}"));
        assert!(e.starts_with("m.toml:1:13: error: "), "{e}");
        assert!(e.contains("period_us"), "{e}");
    }
    let e = err(&format!("period_us = 1.5\n{MINIMAL}"));
    assert!(e.starts_with("m.toml:1:"), "{e}");
}

/// Every key of `[axes.x.drive]`, at its default.
const DRIVE_X: &str = "[axes.x.drive]\nkind = \"sim\"\ncounts_per_mm = 1000.0\ndirection = 1\nbandwidth_hz = 50.0\ndamping = 1.0\ninertia_ratio = 1.0\nvelocity_feed_forward = 1.0\nsubsteps = 20\novercurrent_accel_counts_s2 = 1e9\nquick_stop_decel_counts_s2 = 1e6\nfollowing_error_window_counts = 1000\nenable_timeout_ms = 1000\n";

/// MINIMAL with every optional table, so that any key can be set by [`with_key`].
fn full() -> String {
    let minimal = MINIMAL.replacen(
        "max_mm = 10.0\n",
        "max_mm = 10.0\nferror_mm = 1.0\nmin_ferror_mm = 0.1\n",
        1,
    );
    format!(
        "{minimal}{DRIVE_X}[axes.c]\nvelocity_deg_s = 360.0\nacceleration_deg_s2 = 3600.0\njerk_deg_s3 = 90000.0\nmin_deg = -720.0\nmax_deg = 720.0\nferror_deg = 1.0\nmin_ferror_deg = 0.1\n[axes.c.drive]\ncounts_per_deg = 1000.0\n[safety]\nmargin = 0.05\nstall_cycles = 3\nrecorder_seconds = 10.0\n[gcode]\narc_tolerance_mm = 0.02828\narc_tolerance_rel = 0.001\n[work_offsets]\ng54 = [0.0, 0.0, 0.0]\n[[tools]]\nnumber = 1\nlength_mm = 0.0\nradius_mm = 0.0\n"
    )
}

/// [`full`] with `key = value` in `table` (`""`: the top level), and the 1-based line
/// and column where the value starts.
/// The full example with `key = value` in `table` is a valid configuration.
fn assert_accepted(table: &str, key: &str, value: &str) {
    let (text, _) = with_key(table, key, value);
    if let Err(e) = Config::from_toml_str(&text, "m.toml") {
        panic!("{key} = {value} must be accepted: {e}");
    }
}

fn with_key(table: &str, key: &str, value: &str) -> (String, String) {
    let text = full();
    let (text, at) = if table.is_empty() {
        (format!("{key} = {value}\n{text}"), 0)
    } else {
        let header = text.find(&format!("[{table}]")).expect("table");
        let line = header + text[header..].find(&format!("\n{key} = ")).expect("key") + 1;
        let end = line + text[line..].find('\n').unwrap();
        (
            format!("{}{key} = {value}{}", &text[..line], &text[end..]),
            line,
        )
    };
    let line_no = text[..at].matches('\n').count() + 1;
    let place = format!("m.toml:{line_no}:{}: error: ", key.len() + 4);
    (text, place)
}

/// Every machine number is accepted at both ends of its documented range and rejected
/// just outside them, with the key, the unit and the range in the message and the
/// value's place in the file.
#[test]
fn every_number_has_a_range_checked_on_both_sides() {
    // (table, key, in range, out of range, the range as the message must state it)
    type Case<'a> = (&'a str, &'a str, &'a [&'a str], &'a [&'a str], &'a str);
    let cases: &[Case] = &[
        (
            "axes.x",
            "velocity_mm_s",
            &["0.001", "100000"],
            &["0.000999", "100000.01", "1e-300", "0", "-1", "inf", "nan"],
            "between 0.001 and 100000 mm/s",
        ),
        (
            "axes.y",
            "acceleration_mm_s2",
            &["0.01", "1e8"],
            &["0.0099", "1.00001e8"],
            "between 0.01 and 1e8 mm/s²",
        ),
        (
            "axes.z",
            "jerk_mm_s3",
            &["1", "1e12"],
            &["0.999", "1.00001e12"],
            "between 1 and 1e12 mm/s³",
        ),
        (
            "axes.c",
            "velocity_deg_s",
            &["0.001", "100000"],
            &["0.000999", "100000.01"],
            "between 0.001 and 100000 deg/s",
        ),
        (
            "axes.c",
            "acceleration_deg_s2",
            &["0.01", "1e8"],
            &["0.0099", "1.00001e8"],
            "between 0.01 and 1e8 deg/s²",
        ),
        (
            "axes.c",
            "jerk_deg_s3",
            &["1", "1e12"],
            &["0.999", "1.00001e12"],
            "between 1 and 1e12 deg/s³",
        ),
        (
            "axes.x",
            "min_mm",
            &["-1e6"],
            &["-1000000.01", "-inf", "nan"],
            "between -1000000 and 1000000 mm",
        ),
        (
            "axes.x",
            "max_mm",
            &["1e6"],
            &["1000000.01", "inf"],
            "between -1000000 and 1000000 mm",
        ),
        (
            "axes.c",
            "min_deg",
            &["-1e6"],
            &["-1000000.01"],
            "between -1000000 and 1000000 deg",
        ),
        (
            "axes.c",
            "max_deg",
            &["1e6"],
            &["1000000.01"],
            "between -1000000 and 1000000 deg",
        ),
        (
            "",
            "tolerance_mm",
            &["1e-6", "10"],
            &["9.9e-7", "10.001", "0", "nan"],
            "between 1e-6 and 10 mm",
        ),
        (
            "gcode",
            "arc_tolerance_mm",
            &["1e-6", "10"],
            &["9.9e-7", "10.001", "-0.1"],
            "between 1e-6 and 10 mm",
        ),
        (
            "gcode",
            "arc_tolerance_rel",
            &["1e-9", "0.1"],
            &["9.9e-10", "0.1001", "inf"],
            "between 1e-9 and 0.1",
        ),
        (
            "tools",
            "length_mm",
            &["-1e6", "1e6"],
            &["-1000000.01", "1000000.01", "nan"],
            "between -1000000 and 1000000 mm",
        ),
        (
            "tools",
            "radius_mm",
            &["0", "1e6"],
            &["-0.001", "1000000.01", "inf"],
            "between 0 and 1000000 mm",
        ),
        (
            "axes.x.drive",
            "counts_per_mm",
            &["1e-3", "1e8"],
            &["9.9e-4", "0", "-1000", "1.1e9", "nan"],
            "between 0.001 and 1e9 counts/mm",
        ),
        (
            "axes.c.drive",
            "counts_per_deg",
            &["1e-3", "1e6"],
            &["9.9e-4", "1.1e9", "inf"],
            "between 0.001 and 1e9 counts/deg",
        ),
        (
            "axes.x.drive",
            "bandwidth_hz",
            &["0.1", "1000"],
            &["0.09", "1000.1", "nan"],
            "between 0.1 and 1000 Hz",
        ),
        (
            "axes.x.drive",
            "damping",
            &["0.01", "10"],
            &["0.0099", "10.1", "-1"],
            "between 0.01 and 10 (damping ratio)",
        ),
        (
            "axes.x.drive",
            "inertia_ratio",
            &["0.01", "100"],
            &["0.0099", "100.1", "nan"],
            "between 0.01 and 100 (load inertia over the tuned inertia)",
        ),
        (
            "axes.x.drive",
            "velocity_feed_forward",
            &["0", "1"],
            &["-0.01", "1.01", "nan"],
            "between 0 and 1 (gain)",
        ),
        (
            "axes.x.drive",
            "overcurrent_accel_counts_s2",
            &["1", "1e15"],
            &["0.99", "1.1e15", "inf"],
            "between 1 and 1e15 counts/s²",
        ),
        (
            "axes.x.drive",
            "quick_stop_decel_counts_s2",
            &["1", "1e15"],
            &["0.99", "1.1e15", "-5"],
            "between 1 and 1e15 counts/s²",
        ),
        (
            "axes.x",
            "ferror_mm",
            &["0.1", "1000"],
            &["9.9e-7", "1000.1", "nan"],
            "between 1e-6 and 1000 mm",
        ),
        (
            "axes.x",
            "min_ferror_mm",
            &["1e-6", "1"],
            &["0", "9.9e-7", "1000.1"],
            "between 1e-6 and 1000 mm",
        ),
        (
            "axes.c",
            "ferror_deg",
            &["0.1", "1000"],
            &["9.9e-7", "1000.1"],
            "between 1e-6 and 1000 deg",
        ),
        (
            "axes.c",
            "min_ferror_deg",
            &["1e-6", "1"],
            &["0", "1000.1"],
            "between 1e-6 and 1000 deg",
        ),
        (
            "safety",
            "margin",
            &["0", "1"],
            &["-0.01", "1.01", "nan"],
            "between 0 and 1 (fraction of the limits)",
        ),
        (
            "safety",
            "recorder_seconds",
            &["0.1", "60"],
            &["0.09", "60.1", "inf"],
            "between 0.1 and 60 s",
        ),
    ];
    for &(table, key, good, bad, range) in cases {
        for value in good {
            assert_accepted(table, key, value);
        }
        for value in bad {
            let (text, place) = with_key(table, key, value);
            let e = err(&text);
            assert!(
                e.starts_with(&place),
                "{key} = {value}: {e} (expected at {place})"
            );
            let full_key = if table.is_empty() {
                key.to_string()
            } else {
                format!("{table}.{key}")
            };
            assert!(e.contains(&format!("`{full_key}`")), "{e}");
            assert!(e.contains(range), "{key} = {value}: {e}");
        }
    }
}

#[test]
fn a_tiny_limit_is_named_with_its_exponent() {
    let (text, place) = with_key("axes.x", "velocity_mm_s", "1e-300");
    let e = err(&text);
    assert_eq!(
        e,
        format!(
            "{place}`axes.x.velocity_mm_s` must be between 0.001 and 100000 mm/s, found 1e-300"
        )
    );
}

#[test]
fn period_has_a_lower_bound_of_50_us() {
    for ok in ["50", "62", "1000000"] {
        let (text, _) = with_key("", "period_us", ok);
        let c = Config::from_toml_str(&text, "m.toml").unwrap();
        assert_eq!(c.period_us.to_string(), ok);
    }
    for bad in ["49", "10", "1", "1000001"] {
        let (text, place) = with_key("", "period_us", bad);
        let e = err(&text);
        assert_eq!(
            e,
            format!("{place}`period_us` must be between 50 and 1000000 µs, found {bad}")
        );
    }
}

#[test]
fn work_offsets_are_bounded() {
    let (text, _) = with_key("work_offsets", "g54", "[1e6, -1e6, 0]");
    let c = Config::from_toml_str(&text, "m.toml").unwrap();
    assert_eq!(c.work_offsets_mm[0], [1e6, -1e6, 0.0]);
    for bad in ["[1000000.01, 0, 0]", "[0, -inf, 0]", "[0, 0, nan]"] {
        let (text, place) = with_key("work_offsets", "g54", bad);
        let e = err(&text);
        assert!(e.starts_with(&place), "{e}");
        assert!(e.contains("`work_offsets.g54`"), "{e}");
        assert!(e.contains("between -1000000 and 1000000 mm"), "{e}");
    }
}

#[test]
fn tolerance_must_be_positive() {
    let e = err(&format!("tolerance_mm = 0.0\n{MINIMAL}"));
    assert!(e.contains("tolerance_mm"), "{e}");
}

#[test]
fn unknown_dialect_lists_the_known_ones() {
    let e = err(&format!("dialect = \"fanuc\"\n{MINIMAL}"));
    assert!(e.starts_with("m.toml:1:11: error: "), "{e}");
    assert!(e.contains("fanuc"), "{e}");
    assert!(e.contains("sinumerik"), "{e}");
}

#[test]
fn dialect_alias_tormach_is_linuxcnc() {
    let c = Config::from_toml_str(&format!("dialect = \"tormach\"\n{MINIMAL}"), "m").unwrap();
    assert_eq!(c.dialect, Some(Dialect::LinuxCnc));
}

#[test]
fn syntax_error_has_a_position() {
    let e = err("period_us = = 3\n");
    assert!(e.starts_with("m.toml:1:"), "{e}");
}

#[test]
fn rotary_axis_is_read_in_degrees() {
    let text = format!(
        "{MINIMAL}[axes.c]\nvelocity_deg_s = 360.0\nacceleration_deg_s2 = 3600.0\njerk_deg_s3 = 90000.0\nmin_deg = -720.0\nmax_deg = 720.0\n"
    );
    let c = Config::from_toml_str(&text, "m").unwrap();
    let axis = c.axes.c.unwrap();
    assert_eq!(axis.velocity_deg_s, 360.0);
    assert_eq!((axis.min_deg, axis.max_deg), (-720.0, 720.0));
    assert_eq!(c.axes.rotary(), [None, None, Some(axis)]);
    // Linear keys on a rotary axis are a mistake worth naming.
    let e = err(&text.replace("velocity_deg_s", "velocity_mm_s"));
    assert!(e.contains("velocity_mm_s"), "{e}");
}

#[test]
fn settings_carry_offsets_tools_and_arc_tolerances() {
    let text = format!(
        "{MINIMAL}[gcode]\narc_tolerance_mm = 0.05\narc_tolerance_rel = 0.002\n[work_offsets]\ng55 = [1.0, -2.0, 3.5]\ng59_3 = [0, 0, -7]\n[[tools]]\nnumber = 3\nlength_mm = 42.5\n[[tools]]\nnumber = 7\nradius_mm = 3.0\n"
    );
    let s = Config::from_toml_str(&text, "m").unwrap().settings();
    assert_eq!(s.arc_tolerance_mm, 0.05);
    assert_eq!(s.arc_tolerance_rel, 0.002);
    assert_eq!(s.work_offsets_mm[0], [0.0, 0.0, 0.0]);
    assert_eq!(s.work_offsets_mm[1], [1.0, -2.0, 3.5]);
    assert_eq!(s.work_offsets_mm[8], [0.0, 0.0, -7.0]);
    assert_eq!(s.tools.len(), 2);
    assert_eq!(
        (
            s.tools[0].number,
            s.tools[0].length_mm,
            s.tools[0].radius_mm
        ),
        (3, 42.5, 0.0)
    );
    assert_eq!(
        (
            s.tools[1].number,
            s.tools[1].length_mm,
            s.tools[1].radius_mm
        ),
        (7, 0.0, 3.0)
    );
}

#[test]
fn bad_offsets_and_tools_are_rejected() {
    let e = err(&format!("{MINIMAL}[work_offsets]\ng54 = [1.0, 2.0]\n"));
    assert!(e.contains("work_offsets.g54"), "{e}");
    let e = err(&format!("{MINIMAL}[work_offsets]\ng60 = [1.0, 2.0, 3.0]\n"));
    assert!(e.contains("g60"), "{e}");
    let e = err(&format!(
        "{MINIMAL}[[tools]]\nnumber = 1\n[[tools]]\nnumber = 1\n"
    ));
    assert!(e.contains("tool 1 is listed twice"), "{e}");
    let e = err(&format!("{MINIMAL}[[tools]]\nnumber = -1\n"));
    assert!(e.contains("tools.number"), "{e}");
    let e = err(&format!(
        "{MINIMAL}[[tools]]\nnumber = 2\nradius_mm = -1.0\n"
    ));
    assert!(e.contains("tools.radius_mm"), "{e}");
    let e = err(&format!(
        "{MINIMAL}[[tools]]\nnumber = 2\ndiameter_mm = 1.0\n"
    ));
    assert!(e.contains("diameter_mm"), "{e}");
}

#[test]
fn missing_file_names_the_file() {
    let e = Config::load(Path::new("/nonexistent/kerf.toml")).unwrap_err();
    let s = e.to_string();
    assert!(
        s.starts_with("/nonexistent/kerf.toml: error: cannot read config"),
        "{s}"
    );
}

#[test]
fn positions_count_characters_not_bytes() {
    assert_eq!(position_of("ab\ncd", 4), TextPosition { line: 2, col: 2 });
    assert_eq!(position_of("é=1", 2), TextPosition { line: 1, col: 2 });
    assert_eq!(position_of("x", 99), TextPosition { line: 1, col: 2 });
}

#[test]
fn machine_name_and_daemon_table_default_and_are_checked() {
    let c = Config::from_toml_str(MINIMAL, "m.toml").unwrap();
    assert_eq!(c.machine, "default");
    assert_eq!(
        c.daemon,
        DaemonConfig {
            priority: 80,
            cpu: None,
            cpu_latency_us: 0,
            queue_segments: 4096,
            move_window: 4096,
            state_file: None,
        }
    );
    let c = Config::from_toml_str_in(
        &format!(
            "machine = \"mill-2_a\"\n{MINIMAL}[daemon]\npriority = 90\ncpu = 3\ncpu_latency_us = 75\nqueue_segments = 16\nmove_window = 65536\nstate_file = \"state/m.toml\"\n"
        ),
        "m.toml",
        Path::new("/etc/kerf"),
    )
    .unwrap();
    assert_eq!(c.machine, "mill-2_a");
    assert_eq!(
        c.daemon,
        DaemonConfig {
            priority: 90,
            cpu: Some(3),
            cpu_latency_us: 75,
            queue_segments: 16,
            move_window: 65536,
            // Relative to the configuration's directory.
            state_file: Some(PathBuf::from("/etc/kerf/state/m.toml")),
        }
    );
    for bad in ["", "a/b", "mill 2", "é", &"x".repeat(65)] {
        let e = err(&format!("machine = \"{bad}\"\n{MINIMAL}"));
        assert!(
            e.starts_with("m.toml:1:11: error: `machine` must be"),
            "{bad}: {e}"
        );
    }
    for (key, value) in [
        ("priority", "0"),
        ("priority", "100"),
        ("cpu", "-1"),
        ("cpu_latency_us", "-1"),
        ("cpu_latency_us", "1000001"),
        ("queue_segments", "15"),
        ("queue_segments", "65537"),
        ("move_window", "8"),
    ] {
        let e = err(&format!("{MINIMAL}[daemon]\n{key} = {value}\n"));
        assert!(e.contains(key), "{key} = {value}: {e}");
    }
    let e = err(&format!("{MINIMAL}[daemon]\nstate_file = \"\"\n"));
    assert!(
        e.ends_with("error: `daemon.state_file` must name a file, found an empty string"),
        "{e}"
    );
    let e = err(&format!("{MINIMAL}[daemon]\nperiod_us = 250\n"));
    assert!(e.contains("period_us"), "{e}");
}

/// A fresh directory for one test's files.
fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("kerf-config-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

#[test]
fn gcode_files_and_limits_are_read_relative_to_the_config_file() {
    let dir = temp_dir("gcode");
    std::fs::write(dir.join("tool.tbl"), "T3 P3 X0.5 Z42.5 D6 ;drill\nT4 Z-1\n").expect("write");
    std::fs::write(dir.join("kerf.var"), "5161\t10\n5220\t2\n5241\t-3.5\n").expect("write");
    let text = format!(
        "{MINIMAL}[gcode]\ntool_table = \"tool.tbl\"\nsubroutine_path = [\"subs\", \"/opt/ngc\"]\n\
         max_loop_iterations = 5000\nblock_delete = true\ng28_home_mm_deg = [1, 2, 3]\n\
         g30_home_mm_deg = [4, 5, 6, 7, 8, 9]\nparameter_file = \"kerf.var\"\n\
         [[tools]]\nnumber = 1\nlength_mm = 2.0\n"
    );
    let path = dir.join("kerf.toml");
    std::fs::write(&path, text).expect("write");
    let c = Config::load(&path).expect("valid config");
    assert_eq!(c.tool_table, Some(dir.join("tool.tbl")));
    let numbers: Vec<u32> = c.tools.iter().map(|t| t.number).collect();
    assert_eq!(numbers, [1, 3, 4]);
    assert_eq!(c.tools[1].offsets_mm_deg(), [0.5, 0.0, 42.5, 0.0, 0.0, 0.0]);
    assert_eq!(c.tools[1].radius_mm, 3.0);
    assert_eq!(c.tools[1].pocket, 3);
    assert_eq!(
        c.subroutine_path,
        [dir.join("subs"), PathBuf::from("/opt/ngc")]
    );
    assert_eq!(c.max_loop_iterations, 5000);
    assert_eq!(c.g28_home_mm_deg, [1.0, 2.0, 3.0, 0.0, 0.0, 0.0]);
    assert_eq!(c.g30_home_mm_deg, [4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    let s = c.program_settings().expect("parameter file");
    assert_eq!(s.parameters, [(5161, 10.0), (5220, 2.0), (5241, -3.5)]);
    assert_eq!(s.max_loop_iterations, 5000);
    assert!(c.block_delete && s.block_delete);
    assert!(!Config::builtin().settings().block_delete, "off by default");
    assert_eq!(s.subroutine_path, c.subroutine_path);
    assert_eq!(s.g30_home_mm_deg, c.g30_home_mm_deg);
    assert_eq!(s.tools.len(), 3);
    // The restored parameters take effect: #5220 = 2 starts the program in G55, whose
    // X offset #5241 is -3.5 mm.
    let items: Vec<kerf_gcode::Item> =
        kerf_gcode::Interpreter::new(&b"G0 X1\nM2\n"[..], Dialect::LinuxCnc, s)
            .collect::<Result<_, _>>()
            .expect("valid program");
    let kerf_gcode::Item::Move(m) = &items[0] else {
        panic!("a move")
    };
    assert_eq!(m.path.end(), kerf_gcode::Vec3::new(-2.5, 0.0, 0.0));
    std::fs::remove_dir_all(&dir).expect("clean up");
}

#[test]
fn gcode_file_and_limit_errors() {
    let dir = temp_dir("gcode-errors");
    std::fs::write(dir.join("bad.tbl"), "T1 Z1\nT2 Zq\n").expect("write");
    std::fs::write(dir.join("dup.tbl"), "T1 Z1\n").expect("write");
    let load = |extra: &str| {
        let path = dir.join("kerf.toml");
        std::fs::write(&path, format!("{MINIMAL}{extra}")).expect("write");
        Config::load(&path)
            .map(|_| ())
            .expect_err(extra)
            .to_string()
    };
    let e = load("[gcode]\ntool_table = \"bad.tbl\"\n");
    assert_eq!(
        e,
        format!(
            "{}:2:4: error: `Zq` is not a letter followed by a number",
            dir.join("bad.tbl").display()
        )
    );
    let e = load("[gcode]\ntool_table = \"missing.tbl\"\n");
    assert!(e.contains("cannot read `gcode.tool_table`"), "{e}");
    let e = load("[gcode]\ntool_table = \"dup.tbl\"\n[[tools]]\nnumber = 1\n");
    assert!(
        e.contains("tool 1 is both in `tools` and in `gcode.tool_table`"),
        "{e}"
    );
    for (extra, key) in [
        ("max_loop_iterations = 0", "gcode.max_loop_iterations"),
        ("g28_home_mm_deg = [1, 2]", "gcode.g28_home_mm_deg"),
        ("g30_home_mm_deg = [1, 2, 3, 4]", "gcode.g30_home_mm_deg"),
        ("g28_home = [1, 2, 3]", "unknown key `gcode.g28_home`"),
    ] {
        let e = err(&format!("{MINIMAL}[gcode]\n{extra}\n"));
        assert!(e.contains(key), "{extra}: {e}");
    }
    std::fs::remove_dir_all(&dir).expect("clean up");
}

/// The whole-number keys of the drive side: both ends accepted, just outside refused
/// with the key, what it counts and the range.
#[test]
fn drive_integers_are_range_checked() {
    type Case<'a> = (&'a str, &'a str, &'a [&'a str], &'a [&'a str], &'a str);
    let cases: &[Case] = &[
        (
            "axes.x.drive",
            "substeps",
            &["1", "1000"],
            &["0", "1001", "-1"],
            "a number of steps per period from 1 to 1000",
        ),
        (
            "axes.x.drive",
            "following_error_window_counts",
            &["1", "1000000000"],
            &["0", "1000000001"],
            "a number of counts from 1 to 1000000000",
        ),
        (
            "axes.x.drive",
            "enable_timeout_ms",
            &["1", "60000"],
            &["0", "60001"],
            "a time in ms from 1 to 60000",
        ),
        (
            "safety",
            "stall_cycles",
            &["1", "10000"],
            &["0", "10001", "-3"],
            "a number of cycles from 1 to 10000",
        ),
    ];
    for &(table, key, good, bad, range) in cases {
        for value in good {
            assert_accepted(table, key, value);
        }
        for value in bad {
            let (text, place) = with_key(table, key, value);
            assert_eq!(
                err(&text),
                format!("{place}`{table}.{key}` must be {range}, found {value}")
            );
        }
    }
    for (value, direction) in [("1", 1), ("+1", 1), ("-1", -1)] {
        let (text, _) = with_key("axes.x.drive", "direction", value);
        let c = Config::from_toml_str(&text, "m.toml").unwrap();
        assert_eq!(c.drive_configs()[0].unwrap().scale.direction(), direction);
    }
    for value in ["0", "2", "-2"] {
        let (text, place) = with_key("axes.x.drive", "direction", value);
        assert_eq!(
            err(&text),
            format!("{place}`axes.x.drive.direction` must be +1 or -1, found {value}")
        );
    }
}

#[test]
fn drive_side_defaults() {
    let c = Config::from_toml_str(MINIMAL, "m.toml").unwrap();
    let d = c.drive.axes[0].unwrap();
    assert_eq!(d.kind, DriveKind::Sim);
    assert_eq!(
        (d.scale.counts_per_unit(), d.scale.direction()),
        (1000.0, 1)
    );
    assert_eq!(
        (
            d.sim.bandwidth_hz,
            d.sim.damping,
            d.sim.velocity_feed_forward
        ),
        (50.0, 1.0, 1.0)
    );
    assert_eq!(d.sim.substeps, 20);
    assert_eq!(
        (
            d.sim.overcurrent_accel_counts_s2,
            d.sim.quick_stop_decel_counts_s2
        ),
        (1e9, 1e6)
    );
    assert_eq!(d.sim.following_error_window_counts, 1000);
    assert_eq!(d.enable_timeout_ms, 1000);
    assert_eq!((d.ferror_mm_deg, d.min_ferror_mm_deg), (1.0, 0.1));
    assert_eq!(c.drive.axes[1], Some(d));
    assert_eq!(c.drive.axes[2], Some(d));
    assert_eq!(&c.drive.axes[3..], &[None, None, None]);
    assert_eq!(
        (
            c.drive.margin,
            c.drive.stall_cycles,
            c.drive.recorder_seconds
        ),
        (0.05, 3, 10.0)
    );
    // The sim drive's defaults are those of the simulated drive itself.
    let setups = c.drive_configs();
    let x = setups[0].unwrap();
    assert_eq!(x.sim, SimConfig::default());
    assert_eq!(x.enable_timeout_cycles, 1000);
    assert!(setups[3..].iter().all(Option::is_none));
    assert_eq!(c.recorder_capacity(), 10_000);
    assert_eq!(c.recorder_axes(), [true, true, true, false, false, false]);
    // The keys of `full` are the defaults too.
    assert_eq!(
        Config::from_toml_str(&full(), "m.toml").unwrap().drive.axes[0],
        Some(d)
    );
    // The bundled example has the same drive side.
    assert_eq!(
        Config::builtin().drive.axes[0].map(|a| a.sim.bandwidth_hz),
        Some(50.0)
    );
}

#[test]
fn built_drive_and_safety_configs_carry_the_files_values() {
    let text = format!(
        "period_us = 2000\n{}[axes.x.drive]\nkind = \"sim\"\ncounts_per_mm = 800.0\ndirection = -1\nbandwidth_hz = 20.0\ndamping = 0.7\ninertia_ratio = 1.5\nvelocity_feed_forward = 0.5\nsubsteps = 40\novercurrent_accel_counts_s2 = 5e8\nquick_stop_decel_counts_s2 = 2e5\nfollowing_error_window_counts = 77\nenable_timeout_ms = 3\n[axes.b]\nvelocity_deg_s = 90.0\nacceleration_deg_s2 = 900.0\njerk_deg_s3 = 9000.0\nmin_deg = -30.0\nmax_deg = 120.0\nferror_deg = 2.0\nmin_ferror_deg = 0.5\n[axes.b.drive]\ncounts_per_deg = 3600.0\n[safety]\nmargin = 0.1\nstall_cycles = 7\nrecorder_seconds = 2.5\n",
        MINIMAL.replacen(
            "max_mm = 10.0\n",
            "max_mm = 10.0\nferror_mm = 0.4\nmin_ferror_mm = 0.02\n",
            1
        )
    );
    let c = Config::from_toml_str(&text, "m.toml").unwrap();
    let setups = c.drive_configs();
    let x = setups[0].unwrap();
    assert_eq!(x.kind, DriveKind::Sim);
    assert_eq!(
        (x.scale.counts_per_unit(), x.scale.direction()),
        (800.0, -1)
    );
    assert_eq!(
        x.sim,
        SimConfig {
            period_ns: 2_000_000,
            bandwidth_hz: 20.0,
            damping: 0.7,
            inertia_ratio: 1.5,
            velocity_feed_forward: 0.5,
            substeps: 40,
            overcurrent_accel_counts_s2: 5e8,
            quick_stop_decel_counts_s2: 2e5,
            following_error_window_counts: 77,
            initial_position_counts: 0.0,
        }
    );
    // 3 ms at 2 ms per cycle: rounded up to 2 cycles.
    assert_eq!(x.enable_timeout_cycles, 2);
    let b = setups[4].unwrap();
    assert_eq!(
        (b.scale.counts_per_unit(), b.scale.direction()),
        (3600.0, 1)
    );
    assert_eq!(b.sim.bandwidth_hz, 50.0);
    assert!(setups[3].is_none() && setups[5].is_none());
    // The scale converts as the file says: -1 direction, 800 counts/mm.
    assert_eq!(x.scale.to_counts(1.5), Ok(-1200));

    let s = c.safety_config();
    assert_eq!(s.period_s, 0.002);
    assert_eq!((s.margin, s.stall_cycles), (0.1, 7));
    assert_eq!(
        s.axes[0],
        Some(AxisSafety {
            limits: AxisLimits {
                velocity_units_s: 100.0,
                acceleration_units_s2: 1000.0,
                jerk_units_s3: 10000.0,
            },
            min_limit_units: -10.0,
            max_limit_units: 10.0,
            ferror_units: 0.4,
            min_ferror_units: 0.02,
        })
    );
    assert_eq!(
        s.axes[1].map(|a| (a.ferror_units, a.min_ferror_units)),
        Some((1.0, 0.1))
    );
    assert_eq!(
        s.axes[4],
        Some(AxisSafety {
            limits: AxisLimits {
                velocity_units_s: 90.0,
                acceleration_units_s2: 900.0,
                jerk_units_s3: 9000.0,
            },
            min_limit_units: -30.0,
            max_limit_units: 120.0,
            ferror_units: 2.0,
            min_ferror_units: 0.5,
        })
    );
    assert!(s.axes[3].is_none() && s.axes[5].is_none());
    // LinuxCNC's rule on the configured values: 0.4 mm at 100 mm/s, 0.02 at rest.
    assert_eq!(s.axes[0].unwrap().ferror_limit_units(100.0), 0.4);
    assert_eq!(s.axes[0].unwrap().ferror_limit_units(0.0), 0.02);
    assert!(kerf_drive::safety::Safety::new(s, [0.0; MAX_AXES]).is_ok());

    // 2.5 s at 2 ms: 1250 cycles, as the recorder itself sizes it.
    assert_eq!(c.recorder_capacity(), 1250);
    assert_eq!(c.recorder_axes(), [true, true, true, false, true, false]);
    let recorder =
        kerf_drive::recorder::Recorder::new(2.5, c.period_s(), c.recorder_axes()).unwrap();
    assert_eq!(recorder.capacity(), c.recorder_capacity());
}

#[test]
fn a_sim_drive_whose_model_would_diverge_is_refused_with_the_substeps_it_needs() {
    // 1000 Hz, ζ 10 at 1 ms: ωh(ωh + 4ζ) ≤ 2 needs ωh ≤ −20 + √402 = 0.0499, so
    // h ≤ 7.94 µs: 126 substeps. At 20 substeps the index is 12.7.
    let load = |t: &str| Config::from_toml_str(t, "m.toml").expect("kerf sim accepts it");
    let e = load(&format!(
        "{MINIMAL}[axes.y.drive]\nbandwidth_hz = 1000.0\ndamping = 10.0\nsubsteps = 20\n"
    ))
    .check_drives()
    .unwrap_err();
    assert!(
        e.contains("`axes.y.drive.substeps` = 20 is too few") && e.contains("use at least 126"),
        "{e}"
    );
    let ok =
        format!("{MINIMAL}[axes.y.drive]\nbandwidth_hz = 1000.0\ndamping = 10.0\nsubsteps = 126\n");
    assert_eq!(load(&ok).check_drives(), Ok(()));
    // A longer period needs more.
    let e = load(&format!(
        "period_us = 4000\n{MINIMAL}[axes.x.drive]\nbandwidth_hz = 200.0\nsubsteps = 4\n"
    ))
    .check_drives()
    .unwrap_err();
    assert!(e.contains("`axes.x.drive.substeps` = 4 is too few"), "{e}");
    // Without `substeps`, enough are taken: the 1000 Hz drive gets 126.
    let c = load(&format!(
        "{MINIMAL}[axes.y.drive]\nbandwidth_hz = 1000.0\ndamping = 10.0\n"
    ));
    assert_eq!(c.drive.axes[1].unwrap().sim.substeps, 126);
    assert_eq!(c.check_drives(), Ok(()));
}

#[test]
fn the_dump_dir_is_relative_to_the_configuration() {
    let c = Config::from_toml_str_in(
        &format!("{MINIMAL}[safety]\ndump_dir = \"bb\"\n"),
        "/etc/kerf/m.toml",
        Path::new("/etc/kerf"),
    )
    .expect("valid");
    assert_eq!(c.dump_dir(), PathBuf::from("/etc/kerf/bb"));
    let c = Config::from_toml_str(
        &format!("{MINIMAL}[safety]\ndump_dir = \"/var/x\"\n"),
        "m.toml",
    )
    .expect("valid");
    assert_eq!(c.dump_dir(), PathBuf::from("/var/x"));
    let e = err(&format!("{MINIMAL}[safety]\ndump_dir = \"\"\n"));
    assert!(e.contains("`safety.dump_dir` must name a directory"), "{e}");
}

#[test]
fn drive_side_mistakes_are_named() {
    let (text, place) = with_key("axes.x.drive", "kind", "\"servo\"");
    assert_eq!(
        err(&text),
        format!("{place}`axes.x.drive.kind` must be \"sim\" or \"ethercat\", found `servo`")
    );
    // Unknown keys, in each new table.
    for (extra, key) in [
        (
            "[axes.x.drive]\nbandwidth = 10.0\n",
            "axes.x.drive.bandwidth",
        ),
        ("[axes.y.drive]\ninertia = 1.0\n", "axes.y.drive.inertia"),
        ("[safety]\nmargin_percent = 5\n", "safety.margin_percent"),
        ("[safety]\nferror_mm = 1.0\n", "safety.ferror_mm"),
    ] {
        let e = err(&format!("{MINIMAL}{extra}"));
        assert!(e.contains(&format!("unknown key `{key}`")), "{extra}: {e}");
    }
    let e = err(&MINIMAL.replacen("max_mm = 10.0\n", "max_mm = 10.0\nferror = 1.0\n", 1));
    assert!(e.contains("unknown key `axes.x.ferror`"), "{e}");
    // The scale key of the other kind of axis.
    let e = err(&format!(
        "{MINIMAL}[axes.z.drive]\ncounts_per_deg = 100.0\n"
    ));
    assert!(
        e.contains("axis z is measured in mm: its scale is `axes.z.drive.counts_per_mm`"),
        "{e}"
    );
    let c_axis = "[axes.c]\nvelocity_deg_s = 360.0\nacceleration_deg_s2 = 3600.0\njerk_deg_s3 = 90000.0\nmin_deg = -720.0\nmax_deg = 720.0\n";
    let e = err(&format!(
        "{MINIMAL}{c_axis}[axes.c.drive]\ncounts_per_mm = 100.0\n"
    ));
    assert!(
        e.contains("its scale is `axes.c.drive.counts_per_deg`"),
        "{e}"
    );
    let e = err(&format!("{MINIMAL}{c_axis}ferror_mm = 1.0\n"));
    assert!(e.contains("unknown key `axes.c.ferror_mm`"), "{e}");
    // A travel that does not fit in 32-bit counts: ±10 mm at 3e8 counts/mm.
    let e = err(&format!("{MINIMAL}[axes.x.drive]\ncounts_per_mm = 3e8\n"));
    assert!(e.starts_with("m.toml:21:17: error: `axes.x.drive.counts_per_mm` = 3e8 puts the travel limit 10 mm at 3e9 counts"), "{e}");
    assert!(
        e.contains("3e9 counts, beyond the drive's 32-bit position (2147483647)"),
        "{e}"
    );
    // min_ferror above ferror.
    let e = err(&MINIMAL.replacen(
        "max_mm = 10.0\n",
        "max_mm = 10.0\nferror_mm = 0.5\nmin_ferror_mm = 0.6\n",
        1,
    ));
    assert!(
        e.contains("`axes.x.min_ferror_mm` (0.6) must be at most `axes.x.ferror_mm` (0.5)"),
        "{e}"
    );
    let e = err(&MINIMAL.replacen("max_mm = 10.0\n", "max_mm = 10.0\nferror_mm = 0.05\n", 1));
    assert!(
        e.contains("`axes.x.min_ferror_mm` (0.1) must be at most `axes.x.ferror_mm` (0.05)"),
        "{e}"
    );
}

/// The largest travel that fits the drive's 32-bit position is accepted: ±4 mm at
/// 536,870,911.75 counts/mm is exactly 2,147,483,647 counts; one count/mm more is not.
#[test]
fn a_travel_of_exactly_the_32_bit_range_is_accepted() {
    let text = MINIMAL.replacen(
        "min_mm = -10.0\nmax_mm = 10.0\n",
        "min_mm = -4.0\nmax_mm = 4.0\n",
        1,
    );
    assert_ne!(text, MINIMAL);
    let fits = format!("{text}[axes.x.drive]\ncounts_per_mm = 536870911.75\n");
    assert!(Config::from_toml_str(&fits, "m.toml").is_ok());
    let e = err(&format!(
        "{text}[axes.x.drive]\ncounts_per_mm = 536870912.75\n"
    ));
    assert!(e.contains("beyond the drive's 32-bit position"), "{e}");
}

/// Without `substeps`, a simulated drive's integration is sized for the configured
/// period: 1000 Hz, ζ 10 needs h ≤ 7.94 µs (see above), so at `period_us = 5000` at
/// least 5000 / 7.94 → 630 substeps, and the drives' own check accepts the machine.
#[test]
fn substeps_are_sized_for_the_configured_period() {
    let c = Config::from_toml_str(
        &format!(
            "period_us = 5000\n{MINIMAL}[axes.y.drive]\nbandwidth_hz = 1000.0\ndamping = 10.0\n"
        ),
        "m.toml",
    )
    .expect("valid");
    let substeps = c.drive.axes[1].expect("a drive on Y").sim.substeps;
    assert!((630..=640).contains(&substeps), "{substeps}");
    assert!(c.check_drives().is_ok());
}
