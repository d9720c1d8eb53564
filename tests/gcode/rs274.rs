//! Issue 9: every golden program in `tests/data/ngc/**/NAME.ngc` runs through Kerf and is
//! compared with `NAME.canon`, the canonical calls LinuxCNC's own interpreter rs274 printed
//! for it (`tests/rs274/golden.sh`; `NAME.err` when rs274 refused it, `NAME.tbl` for its
//! tools). The programs are found by walking the directory. What is compared and with what
//! tolerance: `tests/rs274.rs` and `docs/linuxcnc/harness.md`.

use kerf_tests::rs274::{Verdict, check_golden, goldens};
use kerf_tests::v;

#[test]
fn every_golden_program_resolves_as_rs274_does() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/ngc");
    let all = goldens(&dir).unwrap_or_else(|e| panic!("{e}"));
    assert!(!all.is_empty(), "no golden programs in {}", dir.display());
    let mut failures = Vec::new();
    for g in &all {
        let name = g
            .ngc
            .strip_prefix(&dir)
            .unwrap_or(&g.ngc)
            .display()
            .to_string();
        match check_golden(g) {
            Ok(v) if v.golden_ok() => {}
            Ok(Verdict::Mismatch(why)) => failures.push(format!("{name}: mismatch: {why}")),
            Ok(Verdict::KerfRefuses { diag }) => {
                failures.push(format!("{name}: rs274 accepts it, Kerf refuses: {diag}"))
            }
            Ok(Verdict::Rs274Refuses { rs274, kerf }) => {
                failures.push(format!("{name}: rs274 refuses it ({rs274}), Kerf {kerf}"))
            }
            Ok(other) => failures.push(format!("{name}: {other:?}")),
            Err(e) => failures.push(format!("{name}: {e}")),
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} golden programs differ from rs274:\n\n{}",
        failures.len(),
        all.len(),
        failures.join("\n\n")
    );
}

/// The comparison bites: moving the end of any one move of an accepted golden by 0.01 in
/// rs274's output, or turning one of its arcs the other way, is a mismatch.
#[test]
fn a_changed_canon_move_is_a_mismatch() {
    use kerf_tests::rs274::{compare, load_golden, run_kerf_with};
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/ngc/basic");
    let mut mutants = 0;
    for g in goldens(&dir).unwrap_or_else(|e| panic!("{e}")) {
        if g.err.is_some() {
            continue;
        }
        let l = load_golden(&g).unwrap_or_else(|e| panic!("{e}"));
        let (src, canon) = (l.src, l.canon);
        let kerf = run_kerf_with(&src, l.settings);
        assert!(matches!(
            compare(&src, &kerf, &canon, None),
            Verdict::Same { .. }
        ));
        let lines: Vec<&str> = canon.lines().collect();
        for (i, l) in lines.iter().enumerate() {
            let Some(open) = l.find("STRAIGHT_FEED(").or_else(|| l.find("ARC_FEED(")) else {
                continue;
            };
            let args_at = l[open..].find('(').expect("call") + open + 1;
            let comma = l[args_at..].find(',').expect("args") + args_at;
            let first: f64 = l[args_at..comma].trim().parse().expect("number");
            let mut variants = vec![format!(
                "{}{:.4}{}",
                &l[..args_at],
                first + 0.01,
                &l[comma..]
            )];
            if l.contains("ARC_FEED(") {
                let fields: Vec<&str> = l[args_at..].split(", ").collect();
                let rot: i32 = fields[4].trim().parse().expect("rotation");
                let flipped = fields
                    .iter()
                    .enumerate()
                    .map(|(k, f)| {
                        if k == 4 {
                            (-rot).to_string()
                        } else {
                            f.to_string()
                        }
                    })
                    .collect::<Vec<_>>()
                    .join(", ");
                variants.push(format!("{}{}", &l[..args_at], flipped));
            }
            for variant in variants {
                let mut changed = lines.clone();
                changed[i] = &variant;
                let text = changed.join("\n");
                let v = compare(&src, &kerf, &text, None);
                assert!(
                    matches!(v, Verdict::Mismatch(_)),
                    "{}: canon line {} changed to {variant} still compares as {v:?}",
                    g.ngc.display(),
                    i + 1
                );
                mutants += 1;
            }
        }
    }
    assert!(mutants > 50, "only {mutants} mutants");
}

/// The canon conventions, with positions worked out by hand: a G18 arc is printed
/// (Z, X) with Y as its axis; offsets printed under G20 are inches and stay valid after
/// G21; G92 applies before the XY rotation, G5x after it; G95 feeds are per revolution.
#[test]
fn canon_conventions_by_hand() {
    use kerf_tests::canon::{CanonItem, parse};
    use std::f64::consts::PI;
    let text = "\
    1 N..... USE_LENGTH_UNITS(CANON_UNITS_MM)
    2 N..... SET_FEED_RATE(100.0000)
    3 N..... SELECT_PLANE(CANON_PLANE_XZ)
    4 N..... ARC_FEED(0.0000, 10.0000, 0.0000, 5.0000, -1, 0.0000, 0.0000, 0.0000, 0.0000)
    5 N..... USE_LENGTH_UNITS(CANON_UNITS_INCHES)
    6 N..... SET_G5X_OFFSET(1, 1.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)
    7 N..... USE_LENGTH_UNITS(CANON_UNITS_MM)
    8 N..... SET_XY_ROTATION(90.0000)
    9 N..... SET_G92_OFFSET(2.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)
   10 N..... STRAIGHT_TRAVERSE(1.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)
   11 N..... SET_FEED_MODE(0, 1)
   12 N..... SET_FEED_RATE(0.1000)
   13 N..... SET_SPINDLE_SPEED(0, 1000.0000)
   14 N..... STRAIGHT_FEED(1.0000, 1.0000, 0.0000, 0.0000, 0.0000, 0.0000)
";
    let items = parse(text).expect("canon");
    let CanonItem::Move(arc) = &items[0] else {
        panic!("{items:?}")
    };
    let a = arc.arc.expect("an arc");
    assert!((arc.end_mm - v(10.0, 0.0, 0.0)).norm() < 1e-9);
    assert!((a.center_mm - v(5.0, 0.0, 0.0)).norm() < 1e-9);
    assert!((a.axis - v(0.0, 1.0, 0.0)).norm() < 1e-9);
    assert!((a.sweep_rad + PI).abs() < 1e-9);
    // X = 1 + 2 (G92) = 3, turned 90° to (0, 3), plus the G5x 25.4 along X.
    let CanonItem::Move(rapid) = &items[1] else {
        panic!("{items:?}")
    };
    assert!(
        (rapid.end_mm - v(25.4, 3.0, 0.0)).norm() < 1e-9,
        "{rapid:?}"
    );
    assert_eq!(rapid.feed_mm_min, None);
    let CanonItem::Move(feed) = &items[3] else {
        panic!("{items:?}")
    };
    assert!((feed.end_mm - v(24.4, 3.0, 0.0)).norm() < 1e-9, "{feed:?}");
    assert!((feed.feed_mm_min.expect("feed") - 100.0).abs() < 1e-9);
}
