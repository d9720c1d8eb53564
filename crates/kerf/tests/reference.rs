//! The user reference: the example program of every dialect (config/examples/part.*), the
//! `kerf plan` JSON Schema (docs/plan.schema.json) checked against real output, the
//! `kerf sim` CSV columns of docs/OUTPUTS.md, and the shell completions and man pages
//! generated from the binaries.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

const KERF: &str = env!("CARGO_BIN_EXE_kerf");
mod common;
use common::kerfd;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn scratch_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("kerf-reference-tests")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn run(program: &str, args: &[&str]) -> Output {
    let out = Command::new(program).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{program} {args:?}: {}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// The example part in each dialect, with the `--dialect` the README shows for it (only
/// Rockwell's `.nc` does not name its control).
const EXAMPLES: [(&str, &[&str]); 5] = [
    ("part.ngc", &[]),
    ("part.nc", &["--dialect", "rockwell"]),
    ("part.mpf", &[]),
    ("part.i", &[]),
    ("part.pim", &[]),
];

fn example(name: &str) -> String {
    root()
        .join("config/examples")
        .join(name)
        .display()
        .to_string()
}

fn plan_lines(file: &str, dialect: &[&str]) -> Vec<Value> {
    let mut args = vec!["plan"];
    args.extend_from_slice(dialect);
    args.push(file);
    let out = run(KERF, &args);
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{file}: {e}: {l}")))
        .collect()
}

// ---------------------------------------------------------------------------------------
// A validator for the subset of JSON Schema (2020-12) that docs/plan.schema.json uses. It
// refuses any keyword it does not implement, so the schema cannot say more than is checked.
// ---------------------------------------------------------------------------------------

const ANNOTATIONS: [&str; 4] = ["$schema", "title", "description", "$defs"];

fn type_matches(name: &str, v: &Value) -> bool {
    match name {
        "object" => v.is_object(),
        "array" => v.is_array(),
        "string" => v.is_string(),
        "boolean" => v.is_boolean(),
        "null" => v.is_null(),
        "number" => v.is_number(),
        "integer" => v.as_f64().is_some_and(|x| x.fract() == 0.0),
        other => panic!("schema: unknown type {other}"),
    }
}

/// The errors of `v` against `schema` (empty: valid), each with its JSON pointer.
fn validate(root: &Value, schema: &Value, v: &Value, at: &str) -> Vec<String> {
    let mut errors = Vec::new();
    let obj = schema.as_object().expect("schema: a schema is an object");
    for (key, rule) in obj {
        let fail = |errors: &mut Vec<String>, what: String| errors.push(format!("{at}: {what}"));
        match key.as_str() {
            k if ANNOTATIONS.contains(&k) => {}
            "$ref" => {
                let path = rule.as_str().unwrap();
                let pointer = path.strip_prefix('#').expect("schema: local $ref only");
                let target = root.pointer(pointer).expect("schema: $ref resolves");
                errors.extend(validate(root, target, v, at));
            }
            "oneOf" | "anyOf" => {
                let passing = rule
                    .as_array()
                    .unwrap()
                    .iter()
                    .filter(|s| validate(root, s, v, at).is_empty())
                    .count();
                let ok = if key == "oneOf" {
                    passing == 1
                } else {
                    passing >= 1
                };
                if !ok {
                    fail(
                        &mut errors,
                        format!("{passing} of the {key} alternatives match"),
                    );
                }
            }
            "type" => {
                let ok = match rule {
                    Value::String(t) => type_matches(t, v),
                    Value::Array(ts) => ts.iter().any(|t| type_matches(t.as_str().unwrap(), v)),
                    _ => panic!("schema: bad type"),
                };
                if !ok {
                    fail(&mut errors, format!("{v} is not of type {rule}"));
                }
            }
            "const" => {
                if v != rule {
                    fail(&mut errors, format!("{v} is not {rule}"));
                }
            }
            "enum" => {
                if !rule.as_array().unwrap().contains(v) {
                    fail(&mut errors, format!("{v} is not one of the enum"));
                }
            }
            "minimum" | "maximum" | "exclusiveMinimum" => {
                if let (Some(x), Some(bound)) = (v.as_f64(), rule.as_f64()) {
                    let ok = match key.as_str() {
                        "minimum" => x >= bound,
                        "maximum" => x <= bound,
                        _ => x > bound,
                    };
                    if !ok {
                        fail(&mut errors, format!("{x} breaks {key} {bound}"));
                    }
                }
            }
            "minItems" | "maxItems" => {
                if let Some(items) = v.as_array() {
                    let n = rule.as_u64().unwrap() as usize;
                    let ok = if key == "minItems" {
                        items.len() >= n
                    } else {
                        items.len() <= n
                    };
                    if !ok {
                        fail(
                            &mut errors,
                            format!("{} items break {key} {n}", items.len()),
                        );
                    }
                }
            }
            "items" => {
                if let Some(items) = v.as_array() {
                    for (i, item) in items.iter().enumerate() {
                        errors.extend(validate(root, rule, item, &format!("{at}/{i}")));
                    }
                }
            }
            "properties" => {
                if let Some(fields) = v.as_object() {
                    for (name, sub) in rule.as_object().unwrap() {
                        if let Some(field) = fields.get(name) {
                            errors.extend(validate(root, sub, field, &format!("{at}/{name}")));
                        }
                    }
                }
            }
            "required" => {
                if let Some(fields) = v.as_object() {
                    for name in rule.as_array().unwrap() {
                        if !fields.contains_key(name.as_str().unwrap()) {
                            fail(&mut errors, format!("missing {name}"));
                        }
                    }
                }
            }
            "additionalProperties" => {
                assert_eq!(rule, &Value::Bool(false), "schema: only `false` supported");
                let known = obj.get("properties").and_then(Value::as_object);
                if let Some(fields) = v.as_object() {
                    for name in fields.keys() {
                        if !known.is_some_and(|k| k.contains_key(name)) {
                            fail(&mut errors, format!("unexpected key {name}"));
                        }
                    }
                }
            }
            other => panic!("schema keyword {other} is not implemented by this validator"),
        }
    }
    errors
}

fn schema() -> Value {
    let text = std::fs::read_to_string(root().join("docs/plan.schema.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn is_valid(v: &Value) -> bool {
    let schema = schema();
    validate(&schema, &schema, v, "").is_empty()
}

/// Real `kerf plan` output of the example programs and of the test programs of every
/// dialect matches the schema line for line, and every kind of line the schema describes
/// occurs (rapids, feed lines, arcs, events).
#[test]
fn plan_output_of_every_dialect_matches_the_schema() {
    let schema = schema();
    let mut programs: Vec<(String, Vec<&str>)> = EXAMPLES
        .iter()
        .map(|(name, d)| (example(name), d.to_vec()))
        .collect();
    programs.push((example("quickstart.ngc"), vec![]));
    for (dir, dialect) in [
        ("linuxcnc", "linuxcnc"),
        ("rockwell", "rockwell"),
        ("sinumerik", "sinumerik"),
        ("heidenhain", "heidenhain"),
        ("fagor", "fagor"),
    ] {
        let dir = root().join("tests/data/programs").join(dir);
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            programs.push((path.display().to_string(), vec!["--dialect", dialect]));
        }
    }
    let mut kinds = BTreeSet::new();
    let mut codes = BTreeSet::new();
    for (file, dialect) in &programs {
        let lines = plan_lines(file, dialect);
        for (i, line) in lines.iter().enumerate() {
            let errors = validate(&schema, &schema, line, "");
            assert!(errors.is_empty(), "{file} line {i}: {line}: {errors:?}");
            let kind = line["type"].as_str().unwrap();
            kinds.insert(
                match (kind, line.get("rapid")) {
                    ("line", Some(Value::Bool(true))) => "rapid",
                    ("line", _) => "feed_line",
                    (other, _) => other,
                }
                .to_string(),
            );
            if kind == "event" {
                codes.insert(line["code"].as_str().unwrap().to_string());
            }
        }
    }
    assert_eq!(
        kinds.into_iter().collect::<Vec<_>>(),
        ["arc", "event", "feed_line", "rapid"]
    );
    for code in ["M3", "M5", "M6", "M8", "M9", "M30", "S", "T"] {
        assert!(codes.contains(code), "no {code} event in {codes:?}");
    }
}

/// The schema refuses what `kerf plan` never prints, so the test above is not vacuous.
#[test]
fn the_schema_refuses_malformed_lines() {
    let ok = r#"{"type":"line","line":3,"rapid":false,"start":[0.0,0.0,0.0],"end":[1.0,0.0,0.0],"feed_mm_min":300.0}"#;
    let ok: Value = serde_json::from_str(ok).unwrap();
    assert!(is_valid(&ok));
    let broken = |edit: &dyn Fn(&mut Value)| -> Value {
        let mut v = ok.clone();
        edit(&mut v);
        v
    };
    // A rapid has no feed; a feed line has one.
    assert!(!is_valid(&broken(&|v| v["rapid"] = Value::Bool(true))));
    assert!(!is_valid(&broken(&|v| v["feed_mm_min"] = Value::Null)));
    assert!(!is_valid(&broken(&|v| v["feed_mm_min"] = 0.0.into())));
    assert!(!is_valid(&broken(&|v| v["line"] = 0.into())));
    assert!(!is_valid(&broken(
        &|v| v["end"] = serde_json::json!([1.0, 0.0])
    )));
    assert!(!is_valid(&broken(&|v| v["extra"] = 1.into())));
    let mut without_start = ok.clone();
    without_start.as_object_mut().unwrap().remove("start");
    assert!(!is_valid(&without_start));
    assert!(!is_valid(&broken(&|v| v["type"] = "spline".into())));
    let event: Value =
        serde_json::from_str(r#"{"type":"event","line":5,"code":"M101","value":3.0,"q":-4.5}"#)
            .unwrap();
    assert!(is_valid(&event));
    let mut unknown = event.clone();
    unknown["code"] = "M200".into();
    assert!(!is_valid(&unknown));
}

/// Consecutive arcs about the same centre and axis that continue each other (the two
/// one-turn helix blocks of the dialects without a turn count) as one arc, so that the
/// parts compare move for move with LinuxCNC's `G3 ... P2`.
fn merged_moves(lines: &[Value]) -> Vec<Value> {
    let mut out: Vec<Value> = Vec::new();
    for line in lines.iter().filter(|l| l["type"] != "event") {
        let mut line = line.clone();
        line.as_object_mut().unwrap().remove("line");
        if let Some(prev) = out.last_mut()
            && prev["type"] == "arc"
            && line["type"] == "arc"
            && prev["center"][0] == line["center"][0]
            && prev["center"][1] == line["center"][1]
            && prev["axis"] == line["axis"]
            && prev["feed_mm_min"] == line["feed_mm_min"]
            && prev["end"] == line["start"]
        {
            prev["end"] = line["end"].clone();
            let sweep = prev["sweep_rad"].as_f64().unwrap() + line["sweep_rad"].as_f64().unwrap();
            prev["sweep_rad"] = sweep.into();
            continue;
        }
        out.push(line);
    }
    out
}

fn close(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            (x.as_f64().unwrap() - y.as_f64().unwrap()).abs() < 1e-9
        }
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(p, q)| close(p, q))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len() && x.iter().all(|(k, p)| y.get(k).is_some_and(|q| close(p, q)))
        }
        _ => a == b,
    }
}

/// The example part is the same part in all five dialects: the same moves (helix blocks
/// merged as above) and the same spindle, coolant and tool events, in the same order.
#[test]
fn the_example_part_is_the_same_in_every_dialect() {
    let reference = plan_lines(&example("part.ngc"), &[]);
    let reference_moves = merged_moves(&reference);
    // By hand from part.ngc: 3 moves to the stock, 17 facing passes, a retract, 3 moves
    // for the helical entry (the helix one arc), 13 for the contour, a retract, 4 holes of
    // 3 moves and 2 rapids home.
    assert_eq!(reference_moves.len(), 52, "{reference_moves:#?}");
    // The events in order, those before the first move (the set-up: tool, spindle,
    // coolant; Heidenhain's tool call `T1 G17 S8000` gives S before T) sorted.
    let events = |lines: &[Value]| -> Vec<String> {
        let first_move = lines.iter().position(|l| l["type"] != "event").unwrap();
        let name = |l: &Value| format!("{}={}", l["code"], l["value"]);
        let mut setup: Vec<String> = lines[..first_move].iter().map(name).collect();
        setup.sort();
        let rest = lines[first_move..].iter().filter(|l| l["type"] == "event");
        setup.into_iter().chain(rest.map(name)).collect()
    };
    for (name, dialect) in &EXAMPLES[1..] {
        let lines = plan_lines(&example(name), dialect);
        let moves = merged_moves(&lines);
        assert_eq!(moves.len(), reference_moves.len(), "{name}");
        for (i, (a, b)) in moves.iter().zip(&reference_moves).enumerate() {
            assert!(
                close(a, b),
                "{name}: move {i}: {a} differs from part.ngc's {b}"
            );
        }
        // Heidenhain's tool call `T1 G17 S8000` has no M6; the others write `T1 M6`.
        let strip_m6 = |e: Vec<String>| -> Vec<String> {
            e.into_iter().filter(|c| !c.starts_with("\"M6\"")).collect()
        };
        assert_eq!(
            strip_m6(events(&lines)),
            strip_m6(events(&reference)),
            "{name}"
        );
    }
}

/// The `kerf sim` columns as docs/OUTPUTS.md's table lists them, joined as the header of a
/// program with (`rotary`) or without rotary axes.
fn documented_csv_header(rotary: bool) -> String {
    let doc = std::fs::read_to_string(root().join("docs/OUTPUTS.md")).unwrap();
    let columns: Vec<&str> = doc
        .lines()
        .filter_map(|l| l.strip_prefix("| `"))
        .filter_map(|l| l.split_once('`').map(|(name, _)| name))
        .filter(|name| rotary || !["a", "b", "c"].contains(name))
        .collect();
    assert!(columns.len() >= 6, "{columns:?}");
    columns.join(",")
}

/// Each example runs with `kerf sim` as the README shows, and all five give the same
/// setpoints (positions and feed of every period), whatever the source lines.
#[test]
fn every_example_runs_in_kerf_sim_with_the_same_setpoints() {
    let dir = scratch_dir("sim");
    let mut reference: Option<Vec<Vec<f64>>> = None;
    for (name, dialect) in EXAMPLES {
        let csv = dir.join(format!("{name}.csv"));
        let mut args = vec!["sim"];
        args.extend_from_slice(dialect);
        let file = example(name);
        let csv_arg = csv.display().to_string();
        args.extend([file.as_str(), "--out", csv_arg.as_str()]);
        let out = run(KERF, &args);
        let summary = String::from_utf8(out.stdout).unwrap();
        assert!(summary.starts_with("duration "), "{name}: {summary}");
        let text = std::fs::read_to_string(&csv).unwrap();
        let mut rows = text.lines();
        assert_eq!(
            rows.next(),
            Some(documented_csv_header(false).as_str()),
            "{name}"
        );
        // t, x, y, z and feed: every column but the source line.
        let rows: Vec<Vec<f64>> = rows
            .map(|r| {
                let cells: Vec<f64> = r.split(',').map(|c| c.parse().unwrap()).collect();
                vec![cells[0], cells[1], cells[2], cells[3], cells[5]]
            })
            .collect();
        // The part ends at the origin, 25 mm up, after more than a minute of motion.
        let last = rows.last().unwrap();
        assert!(last[0] > 60.0, "{name}: {last:?}");
        assert!(
            (last[1].abs() + last[2].abs() + (last[3] - 25.0).abs()) < 1e-9,
            "{name}"
        );
        match &reference {
            None => reference = Some(rows),
            Some(reference) => {
                assert_eq!(rows.len(), reference.len(), "{name}: number of periods");
                for (i, (a, b)) in rows.iter().zip(reference).enumerate() {
                    let worst = a
                        .iter()
                        .zip(b)
                        .map(|(p, q)| (p - q).abs())
                        .fold(0.0, f64::max);
                    assert!(
                        worst < 1e-6,
                        "{name}: row {i}: {a:?} against part.ngc {b:?}"
                    );
                }
            }
        }
    }
}

/// `kerf completions SHELL` and `kerfd --completions SHELL` print scripts that name every
/// visible subcommand and option; `kerf man` writes a page per command, `kerfd`'s too
/// (the daemon does not carry the man-page generator, and refuses `--man`).
#[test]
fn completions_and_man_pages_come_from_the_binaries() {
    let subcommands = [
        "plan",
        "sim",
        "run",
        "status",
        "mdi",
        "offset",
        "tool",
        "jog",
        "home",
        "hold",
        "resume",
        "optional-stop",
        "single-block",
        "block-delete",
        "spindle-override",
        "input",
        "abort",
        "override",
        "record",
        "serve",
        "reset",
        "dump",
        "plot",
        "ethercat",
    ];
    let help = String::from_utf8(run(KERF, &["--help"]).stdout).unwrap();
    for sub in subcommands {
        assert!(
            help.contains(&format!("  {sub} ")),
            "{sub} not in kerf --help"
        );
    }
    // The packaging commands stay out of the user's help.
    assert!(
        !help.contains("completions") && !help.contains("  man "),
        "{help}"
    );

    for shell in ["bash", "zsh", "fish"] {
        let script = String::from_utf8(run(KERF, &["completions", shell]).stdout).unwrap();
        for word in subcommands
            .iter()
            .chain(&["--dialect", "--override", "--plot"])
        {
            let word = if shell == "fish" {
                word.trim_start_matches("--")
            } else {
                word
            };
            assert!(script.contains(word), "{shell}: {word} missing");
        }
        match shell {
            "zsh" => assert!(script.starts_with("#compdef kerf"), "{script}"),
            "fish" => assert!(script.contains("complete -c kerf"), "{script}"),
            _ => assert!(script.contains("complete -F _kerf"), "{script}"),
        }
        let daemon = String::from_utf8(run(kerfd(), &["--completions", shell]).stdout).unwrap();
        assert!(daemon.contains("config"), "{shell}: {daemon}");
        for hidden in ["test-faults", "completions", "--man", "-l man"] {
            assert!(!daemon.contains(hidden), "{shell}: hidden {hidden} offered");
        }
        assert!(
            !script.contains("completions"),
            "{shell}: hidden subcommand offered"
        );
    }

    let dir = scratch_dir("man");
    let dir_arg = dir.display().to_string();
    run(KERF, &["man", &dir_arg]);
    let refused = Command::new(kerfd())
        .args(["--man", &dir_arg])
        .output()
        .unwrap();
    assert!(!refused.status.success(), "kerfd --man accepted");
    let mut pages: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    pages.sort();
    let mut expected: Vec<String> = subcommands.iter().map(|s| format!("kerf-{s}.1")).collect();
    expected.extend(["kerf.1".to_string(), "kerfd.1".to_string()]);
    expected.sort();
    assert_eq!(pages, expected);
    let sim = std::fs::read_to_string(dir.join("kerf-sim.1")).unwrap();
    assert!(sim.starts_with(".ie"), "{sim}");
    assert!(sim.contains(".TH KERF-SIM 1"), "{sim}");
    assert!(sim.contains("\\-\\-override"), "{sim}");
    assert!(
        sim.contains("kerf sim"),
        "synopsis names the whole command: {sim}"
    );
    let kerfd = std::fs::read_to_string(dir.join("kerfd.1")).unwrap();
    assert!(kerfd.contains("\\-\\-config"), "{kerfd}");
    assert!(!kerfd.contains("test\\-faults"), "{kerfd}");
}
