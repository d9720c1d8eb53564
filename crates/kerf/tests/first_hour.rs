//! End-to-end tests of what a new user meets in the first hour with the `kerf` binary:
//! outputs that a failed run leaves alone, `-` for standard output, the dialect chosen from
//! a Fagor `.pim` file and the note when a dialect was assumed, negative feed overrides
//! refused with the range, configuration type errors in the file's terms, and a note for a
//! program without motion.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

const KERF: &str = env!("CARGO_BIN_EXE_kerf");

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A directory of its own for each test, emptied first.
fn dir(test: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("kerf-first-hour")
        .join(test);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn kerf(args: &[&str]) -> Output {
    Command::new(KERF)
        .args(args)
        .stdin(Stdio::null())
        .output()
        .unwrap()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn names_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A straight move of 10 mm at 600 mm/min, and a different one of 20 mm.
const TEN: &str = "G21 G90\nG1 X10 F600\nM2\n";
const TWENTY: &str = "G21 G90\nG1 X20 F600\nM2\n";

#[test]
fn a_failed_sim_leaves_the_previous_outputs_as_they_were() {
    let d = dir("failed-sim");
    let ten = d.join("ten.ngc");
    let twenty = d.join("twenty.ngc");
    std::fs::write(&ten, TEN).unwrap();
    std::fs::write(&twenty, TWENTY).unwrap();
    let csv = d.join("x.csv");
    let svg = d.join("x.svg");
    let (csv_arg, svg_arg) = (csv.to_str().unwrap(), svg.to_str().unwrap());
    let ok = kerf(&[
        "sim",
        ten.to_str().unwrap(),
        "--out",
        csv_arg,
        "--plot",
        svg_arg,
    ]);
    assert_eq!(ok.status.code(), Some(0), "{}", stderr(&ok));
    let (csv_before, svg_before) = (std::fs::read(&csv).unwrap(), std::fs::read(&svg).unwrap());
    // The last row of the first run ends at X10.
    let last = String::from_utf8(csv_before.clone()).unwrap();
    assert_eq!(last.lines().last().unwrap().split(',').nth(1), Some("10.0"));

    // The plot cannot be created: exit 2, and the CSV of the first run is untouched.
    let missing = d.join("no-such-dir").join("x.svg");
    let failed = kerf(&[
        "sim",
        twenty.to_str().unwrap(),
        "--out",
        csv_arg,
        "--plot",
        missing.to_str().unwrap(),
    ]);
    assert_eq!(failed.status.code(), Some(2));
    let err = stderr(&failed);
    assert!(
        err.starts_with(&format!("{}: error: cannot create", missing.display())),
        "{err}"
    );
    assert!(std::fs::read(&csv).unwrap() == csv_before, "x.csv changed");

    // The program cannot be run (outside the travel): nothing changes either.
    let far = d.join("far.ngc");
    std::fs::write(&far, "G21 G90\nG1 X5000 F600\nM2\n").unwrap();
    let failed = kerf(&[
        "sim",
        far.to_str().unwrap(),
        "--out",
        csv_arg,
        "--plot",
        svg_arg,
    ]);
    assert_eq!(failed.status.code(), Some(2));
    assert!(std::fs::read(&csv).unwrap() == csv_before, "x.csv changed");
    assert!(std::fs::read(&svg).unwrap() == svg_before, "x.svg changed");

    // No temporary file is left beside the targets.
    assert_eq!(
        names_in(&d),
        ["far.ngc", "ten.ngc", "twenty.ngc", "x.csv", "x.svg"]
    );

    // A run that succeeds replaces both: its CSV ends at X20.
    let ok = kerf(&[
        "sim",
        twenty.to_str().unwrap(),
        "--out",
        csv_arg,
        "--plot",
        svg_arg,
    ]);
    assert_eq!(ok.status.code(), Some(0), "{}", stderr(&ok));
    let text = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(text.lines().last().unwrap().split(',').nth(1), Some("20.0"));
    assert_eq!(
        names_in(&d),
        ["far.ngc", "ten.ngc", "twenty.ngc", "x.csv", "x.svg"]
    );
}

#[test]
fn sim_out_dash_writes_the_csv_to_standard_output() {
    let d = dir("out-dash");
    let program = d.join("ten.ngc");
    std::fs::write(&program, TEN).unwrap();
    let csv = d.join("ten.csv");
    let to_file = kerf(&[
        "sim",
        program.to_str().unwrap(),
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(to_file.status.code(), Some(0), "{}", stderr(&to_file));
    let summary = String::from_utf8(to_file.stdout).unwrap();
    assert!(summary.starts_with("duration "), "{summary}");

    let out = Command::new(KERF)
        .current_dir(&d)
        .args(["sim", "ten.ngc", "--out", "-"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    // The same bytes as the file; the summary moves to standard error.
    assert!(
        out.stdout == std::fs::read(&csv).unwrap(),
        "stdout differs from the file"
    );
    assert_eq!(stderr(&out), summary);
    assert!(!d.join("-").exists(), "a file named `-` was written");
}

#[test]
fn fagor_pim_programs_are_read_as_fagor() {
    // The project's Fagor pocket, with its G71 (metric, not LinuxCNC's lathe cycle).
    let pim = root().join("tests/data/programs/fagor/pocket.pim");
    let out = kerf(&["plan", pim.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let by_option = kerf(&["plan", "--dialect", "fagor", pim.to_str().unwrap()]);
    assert!(!out.stdout.is_empty());
    assert!(out.stdout == by_option.stdout);
}

#[test]
fn an_error_in_a_dialect_assumed_by_default_says_so() {
    let d = dir("assumed");
    // The Fagor pocket under a name that says nothing about its control.
    let text =
        std::fs::read_to_string(root().join("tests/data/programs/fagor/pocket.pim")).unwrap();
    let program = d.join("pocket.txt");
    std::fs::write(&program, &text).unwrap();
    let name = program.to_str().unwrap();
    for command in ["plan", "sim"] {
        let mut args = vec![command, name];
        if command == "sim" {
            args.extend(["--out", "-"]);
        }
        let out = kerf(&args);
        assert_eq!(out.status.code(), Some(2));
        let err = stderr(&out);
        let lines: Vec<&str> = err.lines().collect();
        assert_eq!(lines.len(), 2, "{err}");
        // `G71` is on line 3 of the pocket.
        assert!(lines[0].starts_with(&format!("{name}:3:")), "{err}");
        assert!(lines[0].contains(": error: "), "{err}");
        assert!(
            lines[1].starts_with("note: read as linuxcnc (the default)"),
            "{err}"
        );
        assert!(lines[1].contains("--dialect"), "{err}");
        assert!(lines[1].contains("`dialect` in the configuration"), "{err}");
    }
    // A dialect somebody chose gets no note: the option, the configuration.
    let out = kerf(&["plan", "--dialect", "linuxcnc", name]);
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(stderr(&out).lines().count(), 1, "{}", stderr(&out));
    let config = std::fs::read_to_string(root().join("config/kerf.toml")).unwrap();
    let config_path = d.join("kerf.toml");
    std::fs::write(&config_path, config).unwrap();
    let out = kerf(&["plan", "--config", config_path.to_str().unwrap(), name]);
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(stderr(&out).lines().count(), 1, "{}", stderr(&out));
    // And the option fixes it.
    let out = kerf(&["plan", "--dialect", "fagor", name]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
}

#[test]
fn negative_feed_overrides_are_refused_with_the_range() {
    let d = dir("override");
    let program = d.join("ten.ngc");
    std::fs::write(&program, TEN).unwrap();
    let csv = d.join("x.csv");
    for value in ["-5", "-5%", "-.5", "-inf"] {
        let out = kerf(&[
            "sim",
            program.to_str().unwrap(),
            "--out",
            csv.to_str().unwrap(),
            "--override",
            value,
        ]);
        assert_eq!(out.status.code(), Some(2), "{value}");
        let err = stderr(&out);
        assert!(!err.contains("unexpected argument"), "{value}: {err}");
        assert!(err.contains("must be 0.1 to 200"), "{value}: {err}");
        // The live override is refused before any daemon is asked.
        let out = kerf(&["override", value]);
        assert_eq!(out.status.code(), Some(2), "{value}");
        let err = stderr(&out);
        assert!(!err.contains("unexpected argument"), "{value}: {err}");
        assert!(err.contains("must be 0 to 200"), "{value}: {err}");
    }
    assert!(!csv.exists());
}

#[test]
fn a_program_without_motion_says_so() {
    let d = dir("no-motion");
    for (file, text) in [
        ("empty.ngc", "%\n%\n"),
        ("comments.ngc", "(only a comment)\n; and another\nM2\n"),
    ] {
        let program = d.join(file);
        std::fs::write(&program, text).unwrap();
        let name = program.to_str().unwrap();
        let csv = d.join("x.csv");
        let out = kerf(&["sim", name, "--out", csv.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
        assert_eq!(stderr(&out), format!("note: no motion in {name}\n"));
        // Standard output of `kerf plan` stays JSON lines: the note is on standard error.
        let out = kerf(&["plan", name]);
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
        let json = String::from_utf8(out.stdout.clone()).unwrap();
        assert!(!json.contains("\"type\":\"line\""), "{json}");
        assert_eq!(stderr(&out), format!("note: no motion in {name}\n"));
    }
    // A program with motion gets no note.
    let program = d.join("ten.ngc");
    std::fs::write(&program, TEN).unwrap();
    let out = kerf(&["sim", program.to_str().unwrap(), "--out", "-"]);
    assert!(!stderr(&out).contains("no motion"), "{}", stderr(&out));
}

/// `kerf run --embedded` on a machine of its own, waited for at most a minute (a run that
/// hangs fails the test instead of hanging it; no assertion is about time).
fn run_embedded(d: &Path, tag: &str, args: &[&str]) -> Output {
    let machine = format!("fh{}_{tag}", std::process::id());
    let config = std::fs::read_to_string(root().join("config/kerf.toml"))
        .unwrap()
        .replacen(
            "machine = \"default\"",
            &format!("machine = \"{machine}\""),
            1,
        );
    let config_path = d.join(format!("{tag}.toml"));
    std::fs::write(&config_path, config).unwrap();
    let mut child = Command::new(KERF)
        .args([
            "run",
            "--embedded",
            "--config",
            config_path.to_str().unwrap(),
        ])
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    child.wait_with_output().unwrap()
}

#[test]
fn run_records_to_standard_output_and_notes_a_program_without_motion() {
    let d = dir("run");
    let program = d.join("ten.ngc");
    std::fs::write(&program, TEN).unwrap();
    let name = program.to_str().unwrap();
    let sim = kerf(&["sim", name, "--out", "-"]);
    assert_eq!(sim.status.code(), Some(0), "{}", stderr(&sim));
    let run = run_embedded(&d, "dash", &["--record", "-", name]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    // The daemon's setpoints of the program are `kerf sim`'s rows.
    assert!(
        run.stdout == sim.stdout,
        "kerf run --record - differs from kerf sim --out -"
    );
    assert!(!d.join("-").exists(), "a file named `-` was written");

    let empty = d.join("empty.ngc");
    std::fs::write(&empty, "(nothing)\nM2\n").unwrap();
    let name = empty.to_str().unwrap();
    let run = run_embedded(&d, "empty", &[name]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    // The embedded machine is switched on unhomed: it homes first, and says so.
    let err = stderr(&run);
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(
        lines.first().copied(),
        Some("kerf: the machine is not homed: homing every axis first"),
        "{err}"
    );
    assert_eq!(lines[lines.len() - 2], "kerf: homed XYZ", "{err}");
    assert_eq!(lines[lines.len() - 1], format!("note: no motion in {name}"));
}

#[test]
fn configuration_type_errors_name_the_key_in_the_files_terms() {
    let d = dir("config");
    let program = d.join("ten.ngc");
    std::fs::write(&program, TEN).unwrap();
    // The axes' tables without their homing subtables, so that the Z table can be cut
    // whole.
    let bundled = kerf_testkit::config_text::without_homing(
        &std::fs::read_to_string(root().join("config/kerf.toml")).unwrap(),
    );
    let line_of = |needle: &str| bundled.lines().position(|l| l == needle).unwrap() + 1;
    let cases = [
        (
            "period_us = 1000",
            "period_us = 1.5",
            format!(
                "{}:13: error: `period_us` must be a whole number of microseconds, found 1.5",
                line_of("period_us = 1000")
            ),
        ),
        (
            "[axes.z]",
            "[axes.w]",
            format!("{}:7: error: unknown key `axes.w`", line_of("[axes.z]")),
        ),
    ];
    for (from, to, expected) in cases {
        let config = d.join("kerf.toml");
        std::fs::write(&config, bundled.replacen(from, to, 1)).unwrap();
        let out = kerf(&[
            "plan",
            "--config",
            config.to_str().unwrap(),
            program.to_str().unwrap(),
        ]);
        assert_eq!(out.status.code(), Some(2));
        let err = stderr(&out);
        assert!(
            err.starts_with(&format!("{}:{expected}", config.display())),
            "{err}"
        );
    }
    // Without the Z table at all.
    let config = d.join("kerf.toml");
    let cut = bundled.find("[axes.z]").unwrap();
    let rest = &bundled[cut..];
    let end = rest.find("\n\n").unwrap();
    std::fs::write(&config, format!("{}{}", &bundled[..cut], &rest[end..])).unwrap();
    let out = kerf(&[
        "plan",
        "--config",
        config.to_str().unwrap(),
        program.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains(": error: missing table [axes.z]"),
        "{}",
        stderr(&out)
    );
}
