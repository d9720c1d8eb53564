//! LinuxCNC canned cycles (G73, G81–G89, G98/G99, L, G91, planes). Expected values come
//! from the LinuxCNC manual's examples (section "G80-G89 Canned Cycles") or from the
//! canonical calls of LinuxCNC's interpreter rs274 for the same program (quoted beside the
//! test), never from Kerf. The golden programs in `tests/data/ngc/cycles/` hold the same
//! checks for the rs274 differential harness.

use proptest::prelude::*;
use proptest::test_runner::{RngSeed, TestRunner};

use kerf_tests::*;

const D: Dialect = Dialect::LinuxCnc;

/// The items of a program, moves and events, as a compact list: `R(x,y,z)` rapid,
/// `F(x,y,z)@feed` feed, events by name (`G4=0.5`).
fn trace(items: &[Item]) -> Vec<String> {
    items
        .iter()
        .map(|it| match it {
            Item::Move(m) => {
                let e = as_line(m).end;
                let p = format!("({},{},{})", r4(e.x), r4(e.y), r4(e.z));
                match m.feed_mm_min {
                    None => format!("R{p}"),
                    Some(f) => format!("F{p}@{}", r4(f)),
                }
            }
            Item::Event(e) => match e.value {
                Some(v) if e.code == EventCode::G4 => format!("G4={}", r4(v)),
                _ => e.code.as_str().to_string(),
            },
        })
        .collect()
}

/// Rounds to 1e-4 (the precision rs274 prints) and prints without trailing zeros.
fn r4(x: f64) -> String {
    let r = (x * 1e4).round() / 1e4;
    let r = if r == 0.0 { 0.0 } else { r };
    format!("{r}")
}

/// The trace of a program's items from `line` on.
fn trace_from(src: &str, line: u32) -> Vec<String> {
    let its: Vec<Item> = items(D, src)
        .into_iter()
        .filter(|i| item_line(i) >= line)
        .collect();
    trace(&its)
}

fn strs(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

#[test]
fn manual_g81_example_1_absolute() {
    // Manual, G81 example 1: from (1, 2, 3), G90 G98 G81 X4 Y5 Z1.5 R2.8: rapid to (4, 5)
    // at Z3, rapid to Z2.8, feed to Z1.5, rapid to Z3 (OLD_Z).
    let src = "G21 G0 X1 Y2 Z3\nF10\nG90 G98 G81 X4 Y5 Z1.5 R2.8\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&["R(4,5,3)", "R(4,5,2.8)", "F(4,5,1.5)@10", "R(4,5,3)"])
    );
}

#[test]
fn manual_g81_example_2_incremental_repeats() {
    // Manual, G81 example 2: from (1, 2, 3), G91 G98 G81 X4 Y5 Z-0.6 R1.8 L3: clear Z is
    // 4.8 (= 1.8 + 3), the bottom 4.2; a preliminary rapid to Z4.8, then three holes at
    // (5, 7), (9, 12), (13, 17).
    let src = "G20 G0 X1 Y2 Z3\nF10\nG91 G98 G81 X4 Y5 Z-0.6 R1.8 L3\n";
    let want: Vec<String> = [
        "R(1,2,4.8)",
        "R(5,7,4.8)",
        "F(5,7,4.2)@10",
        "R(5,7,4.8)",
        "R(9,12,4.8)",
        "F(9,12,4.2)@10",
        "R(9,12,4.8)",
        "R(13,17,4.8)",
        "F(13,17,4.2)@10",
        "R(13,17,4.8)",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    // In inches: scale the expected numbers.
    let got: Vec<String> = trace_from(src, 3);
    let inch = |s: &str| -> String {
        // Parse "R(x,y,z)" / "F(x,y,z)@f" and scale x, y, z (and the feed) by 25.4.
        let (kind, rest) = s.split_at(1);
        let (pt, feed) = match rest.split_once('@') {
            Some((p, f)) => (p, Some(f)),
            None => (rest, None),
        };
        let nums: Vec<f64> = pt
            .trim_matches(|c| c == '(' || c == ')')
            .split(',')
            .map(|n| n.parse::<f64>().expect("number") * INCH_MM)
            .collect();
        let mut out = format!("{kind}({},{},{})", r4(nums[0]), r4(nums[1]), r4(nums[2]));
        if let Some(f) = feed {
            out += &format!("@{}", r4(f.parse::<f64>().expect("feed") * INCH_MM));
        }
        out
    };
    let want: Vec<String> = want.iter().map(|s| inch(s)).collect();
    assert_eq!(got, want);
}

#[test]
fn g99_retracts_to_r_and_g98_to_the_initial_level() {
    // rs274: G0 Z10, G99 G81 X10 Y10 Z-5 R2 retracts to 2; then G98 X20 retracts to 10.
    let src = "G21 G0 Z10\nF100\nG99 G81 X10 Y10 Z-5 R2\nG98 X20\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&[
            "R(10,10,10)",
            "R(10,10,2)",
            "F(10,10,-5)@100",
            "R(10,10,2)",
            // The first repeat of the G98 block starts at the current level, R (rs274).
            "R(20,10,10)",
            "R(20,10,2)",
            "F(20,10,-5)@100",
            "R(20,10,10)",
        ])
    );
}

#[test]
fn rs274_retracts_to_r_when_neither_g98_nor_g99_is_programmed() {
    // rs274 (standalone, no INI start-up code) starts in G99.
    let src = "G21 G0 Z5\nF100\nG81 X1 Y1 Z-1 R1\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&["R(1,1,5)", "R(1,1,1)", "F(1,1,-1)@100", "R(1,1,1)"])
    );
}

#[test]
fn r_above_the_initial_level_comes_first_and_is_the_clearance() {
    // Manual example 3: the initial Z below R adds a preliminary rapid to R.
    let src = "G21 G0 X0 Y0 Z0\nF10\nG90 G98 G81 X4 Y5 Z1.5 R2.8\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&["R(0,0,2.8)", "R(4,5,2.8)", "F(4,5,1.5)@10", "R(4,5,2.8)"])
    );
}

#[test]
fn a_cycle_continues_over_blocks_with_sticky_r_and_z() {
    let src = "G21 G0 Z10\nF100\nG99 G81 X1 Y1 Z-2 R1\nX2\nY2 Z-3\nG80\nG0 X0\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&[
            "R(1,1,10)",
            "R(1,1,1)",
            "F(1,1,-2)@100",
            "R(1,1,1)",
            "R(2,1,1)",
            "F(2,1,-2)@100",
            "R(2,1,1)",
            "R(2,2,1)",
            "F(2,2,-3)@100",
            "R(2,2,1)",
            "R(0,2,1)",
        ])
    );
    // A block without axis words does nothing in cycle mode; the cycle words in it have
    // no use then (rs274's errors).
    let its = items(D, "G21 G0 Z10\nF100\nG81 X1 Z-2 R1\nF200\n");
    assert_eq!(only_moves(&its).last().map(|m| m.line), Some(3));
    let pre = "G21 G0 Z10\nS100 M3 F100\nG82 X1 Z-2 R1 P1\n";
    for (word, msg) in [
        ("R3", "R word with no g code that uses it"),
        ("L2", "L word with no G10"),
        ("P1", "P word with no G2 G3 G4"),
        ("I1", "I word with no G2"),
    ] {
        let d = error(D, &format!("{pre}{word}\n"));
        assert_diag(&d, 4, 1, &[msg]);
    }
}

#[test]
fn g82_dwells_at_the_bottom_and_keeps_p() {
    let src = "G21 G0 Z5\nF100\nG98 G82 X5 Y5 Z-2 R1 P0.5\nX15\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&[
            "R(5,5,5)",
            "R(5,5,1)",
            "F(5,5,-2)@100",
            "G4=0.5",
            "R(5,5,5)",
            "R(15,5,5)",
            "R(15,5,1)",
            "F(15,5,-2)@100",
            "G4=0.5",
            "R(15,5,5)",
        ])
    );
    let its = items(D, "G21 G0 Z5\nF100\nG82 X5 Y5 Z-2 R1 P0.5\n");
    let dwell = only_events(&its)
        .into_iter()
        .find(|e| e.code == EventCode::G4)
        .expect("a dwell event");
    assert_eq!((dwell.line, dwell.value), (3, Some(0.5)));
}

#[test]
fn g73_breaks_chips_with_a_0_254_mm_back_off() {
    // rs274 for G73 X2 Z-3 R2 Q1 from Z3 (G98): pecks to 1, 0, -1, -2 with a rapid up by
    // 0.254 mm after each, then to -3 and out to 3.
    let src = "G21 G0 X2 Z3\nF100\nG98 G73 X2 Z-3 R2 Q1\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&[
            "R(2,0,2)",
            "F(2,0,1)@100",
            "R(2,0,1.254)",
            "F(2,0,0)@100",
            "R(2,0,0.254)",
            "F(2,0,-1)@100",
            "R(2,0,-0.746)",
            "F(2,0,-2)@100",
            "R(2,0,-1.746)",
            "F(2,0,-3)@100",
            "R(2,0,3)",
        ])
    );
}

#[test]
fn g83_pecks_out_to_r_and_back_to_0_254_mm_above_the_last_depth() {
    // rs274 for G83 X3 Z-3 R2 Q1.1 from (3, 0, 3) (G98).
    let src = "G21 G0 X3 Z3\nF100\nG98 G83 X3 Z-3 R2 Q1.1\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&[
            "R(3,0,2)",
            "F(3,0,0.9)@100",
            "R(3,0,2)",
            "R(3,0,1.154)",
            "F(3,0,-0.2)@100",
            "R(3,0,2)",
            "R(3,0,0.054)",
            "F(3,0,-1.3)@100",
            "R(3,0,2)",
            "R(3,0,-1.046)",
            "F(3,0,-2.4)@100",
            "R(3,0,2)",
            "R(3,0,-2.146)",
            "F(3,0,-3)@100",
            "R(3,0,3)",
        ])
    );
}

#[test]
fn peck_back_off_is_0_010_inch_in_g20() {
    // G20: the back-off is 0.010 in (0.254 mm, exact). G73 Z-0.3 R0 Q0.1 from Z0.5 (G99).
    let src = "G20 G0 Z0.5\nF4\nG99 G73 X0 Z-0.3 R0 Q0.1\n";
    let ms = only_moves(&items(D, src));
    let z: Vec<f64> = ms.iter().map(|m| as_line(m).end.z / INCH_MM).collect();
    let want = [0.5, 0.0, -0.1, -0.09, -0.2, -0.19, -0.3, 0.0];
    assert_eq!(z.len(), want.len(), "{}", describe_items(&items(D, src)));
    for (g, w) in z.iter().zip(want) {
        assert_close("Z (in)", *g, w, 1e-9);
    }
}

#[test]
fn g85_feeds_out_to_r_then_rapids_and_g89_dwells_then_feeds_out() {
    // rs274 2.9: G85 feeds back to R, then rapids to the clearance level.
    let src = "G21 G0 Z3\nF100\nG98 G85 X4 Y2 Z-3 R2\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&[
            "R(4,2,3)",
            "R(4,2,2)",
            "F(4,2,-3)@100",
            "F(4,2,2)@100",
            "R(4,2,3)"
        ])
    );
    // Another cycle code needs R again.
    let d = error(D, "G21 G0 Z3\nF100\nG98 G85 X4 Y2 Z-3 R2\nG89 X7 P0.4\n");
    assert_diag(&d, 4, 1, &["R clearance plane unspecified in cycle"]);
    let src = "G21 G0 Z3\nF100\nG98 G89 X7 Y2 Z-3 R2 P0.4\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&[
            "R(7,2,3)",
            "R(7,2,2)",
            "F(7,2,-3)@100",
            "G4=0.4",
            "F(7,2,3)@100"
        ])
    );
}

#[test]
fn g86_stops_the_spindle_rapids_out_and_restarts_it_in_its_direction() {
    let src = "G21 G0 Z3\nS600 M4 F40\nG98 G86 X5 Y2 Z-3 R2 P0.2\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&[
            "R(5,2,3)",
            "R(5,2,2)",
            "F(5,2,-3)@40",
            "G4=0.2",
            "M5",
            "R(5,2,3)",
            "M4",
        ])
    );
    let d = error(D, "G21 G0 Z3\nF40\nG86 X5 Y2 Z-3 R2 P0.2\n");
    assert_diag(&d, 3, 1, &["Spindle not turning in g86"]);
    // The failing block gives nothing: the rapid to Z3 is the last item.
    let out = run(D, "G21 G0 Z3\nF40\nM5\nG88 X5 Y2 Z-3 R2 P0.2\n");
    assert!(out.is_err());
}

#[test]
fn g87_back_bores_as_rs274_emits_it() {
    // rs274 for G87 X8 Z-3 R2 I1 J2 K-1 from (7, 2, 3), G98, spindle clockwise.
    let src = "G21 G0 X7 Y2 Z3\nS500 M3 F100\nG98 G87 X8 Z-3 R2 I1 J2 K-1\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&[
            "R(8,2,3)",
            "R(8,2,2)",
            "R(9,4,2)",
            "M5",
            "M19",
            "R(9,4,-3)",
            "R(8,2,-3)",
            "M3",
            "F(8,2,-1)@100",
            "F(8,2,-3)@100",
            "M5",
            "M19",
            "R(9,4,-3)",
            "R(9,4,3)",
            "R(8,2,3)",
            "M3",
        ])
    );
    let d = error(D, "G21 G0 Z3\nS500 M3 F100\nG87 X8 Z-3 R2 I1 J2\n");
    assert_diag(&d, 3, 1, &["K word missing with g87"]);
}

#[test]
fn g88_stops_for_a_manual_retract() {
    // rs274: feed, DWELL, STOP_SPINDLE_TURNING, PROGRAM_STOP, START_SPINDLE_CLOCKWISE. Kerf
    // adds the operator's manual retract after the stop as a rapid to the clearance level,
    // so that its moves stay continuous.
    let src = "G21 G0 Z10\nS700 M3 F45\nG98 G88 X5 Y5 Z-7 R2 P0.3\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&[
            "R(5,5,10)",
            "R(5,5,2)",
            "F(5,5,-7)@45",
            "G4=0.3",
            "M5",
            "M0",
            "R(5,5,10)",
            "M3",
        ])
    );
}

#[test]
fn cycles_in_g18_drill_along_y_and_in_g19_along_x() {
    // rs274: G18 G81 X3 Z0 R1 Y-1 from (0, 0, 3): up to Y1, to X3 Z0, feed to Y-1.
    let src = "G21 G0 Z3\nF100\nG18 G81 X3 Z0 R1 Y-1\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&["R(0,1,3)", "R(3,1,0)", "F(3,-1,0)@100", "R(3,1,0)"])
    );
    let src = "G21 G0 X3\nF100\nG19 G98 G81 Y4 Z5 X-2 R1\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&["R(3,4,5)", "R(1,4,5)", "F(-2,4,5)@100", "R(3,4,5)"])
    );
    let d = error(D, "G21 G0 X3\nF100\nG19 G81 Y4 Z5 X2 R1\n");
    assert_diag(&d, 3, 5, &["R less than x in cycle in yz plane"]);
    let d = error(D, "G21 G0 Y3\nF100\nG18 G81 X4 Z5 R1\n");
    assert_diag(&d, 3, 5, &["Y value unspecified in xz plane canned cycle"]);
}

#[test]
fn l_repeats_in_absolute_mode_drill_the_same_hole_again() {
    let src = "G21 G0 Z6\nF100\nG99 G81 X4 Y3 Z-2 R1 L2\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&[
            "R(4,3,6)",
            "R(4,3,1)",
            "F(4,3,-2)@100",
            "R(4,3,1)",
            "F(4,3,-2)@100",
            "R(4,3,1)",
        ])
    );
}

#[test]
fn incremental_continuation_measures_r_from_the_initial_level() {
    // rs274: after G91 G98 G81 X4 Y5 Z-0.6 R1.8 L3 from Z3, a block `X1 Y0` measures R
    // from the initial level 3 again (R at 4.8), and `G99 X1 R0 L2` puts R at 3.
    let src = "G21 G0 X1 Y2 Z3\nF10\nG91 G98 G81 X4 Y5 Z-0.6 R1.8 L3\nX1 Y0\nG99 X1 R0 L2\n";
    assert_eq!(
        trace_from(src, 4),
        strs(&[
            "R(14,17,4.8)",
            "F(14,17,4.2)@10",
            "R(14,17,4.8)",
            "R(15,17,4.8)",
            "R(15,17,3)",
            "F(15,17,2.4)@10",
            "R(15,17,3)",
            "R(16,17,3)",
            "F(16,17,2.4)@10",
            "R(16,17,3)",
        ])
    );
}

#[test]
fn the_initial_level_survives_a_cycle_change_and_g80_forgets_it() {
    // rs274: G0 Z3, G99 G81 X1 Z-1 R1 (ends at Z1); with `F50` between, the G98 block
    // retracts to the initial level 3, first with a slanted rapid from (1, 0, 1); with
    // G80 between, the initial level is the current Z1.
    let with = |mid: &str| {
        format!("G21 F100 S100 M3\nG0 Z3\nG99 G81 X1 Z-1 R1\n{mid}\nG98 G81 X2 Z-1 R1\n")
    };
    assert_eq!(
        trace_from(&with("F50"), 5),
        strs(&["R(2,0,3)", "R(2,0,1)", "F(2,0,-1)@50", "R(2,0,3)"])
    );
    assert_eq!(
        trace_from(&with("G80"), 5),
        strs(&["R(2,0,1)", "F(2,0,-1)@100", "R(2,0,1)"])
    );
    assert_eq!(
        trace_from(&with("G0"), 5),
        strs(&["R(2,0,1)", "F(2,0,-1)@100", "R(2,0,1)"])
    );
}

#[test]
fn polar_words_place_the_hole_in_g17() {
    // rs274: from (3, 4, 3), G81 @5 ^30 drills at (4.3301, 2.5); under G91, `@1` adds 1 to
    // the radius of (3, 4) before each repeat: (3.6, 4.8), (4.2, 5.6).
    let src = "G21 G0 X3 Y4 Z3\nF100\nG99 G81 @5 ^30 Z-1 R1\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&[
            "R(4.3301,2.5,3)",
            "R(4.3301,2.5,1)",
            "F(4.3301,2.5,-1)@100",
            "R(4.3301,2.5,1)"
        ])
    );
    let src = "G21 G0 X3 Y4 Z3\nF100\nG99 G91 G81 @1 Z-1 R1 L2\n";
    assert_eq!(
        trace_from(src, 3),
        strs(&[
            "R(3,4,4)",
            "R(3.6,4.8,4)",
            "F(3.6,4.8,3)@100",
            "R(3.6,4.8,4)",
            "R(4.2,5.6,4)",
            "F(4.2,5.6,3)@100",
            "R(4.2,5.6,4)",
        ])
    );
    let d = error(D, "G21 G0 Z3\nF100\nG91 G81 ^10 Z-1 R1\n");
    assert_diag(
        &d,
        3,
        9,
        &["Incremental motion with polar coordinates is indeterminate when at the origin"],
    );
    let d = error(D, "G21 G0 Z3\nF100\nG81 @5 X1 Z-1 R1\n");
    assert_diag(
        &d,
        3,
        8,
        &["Cannot specify both polar coordinate and X word"],
    );
}

#[test]
fn cycle_moves_are_exact_stops_and_start_where_the_last_ended() {
    let src =
        "G21 G64 G0 Z10\nS1000 M3 F100\nG98 G83 X1 Y1 Z-9 R1 Q2 L2\nG91 G73 X2 Z-5 R-8 Q1.5 L3\n";
    let ms = moves(D, src);
    assert_continuous(&ms, v(0.0, 0.0, 0.0));
    for m in ms.iter().filter(|m| m.line >= 3) {
        assert_eq!(m.corner, CornerMode::ExactStop, "{}", describe_move(m));
    }
}

#[test]
fn errors_in_linuxcnc_words() {
    let pre = "G21 G0 Z5\nS100 M3 F100\n";
    let cases: [(&str, u32, &str); 21] = [
        ("G81 X1 Z2 R1", 1, "R less than z in cycle in xy plane"),
        ("G81 X1 Z-1", 1, "R clearance plane unspecified in cycle"),
        (
            "G81 X1 R1",
            1,
            "Z value unspecified in xy plane canned cycle",
        ),
        ("G83 X1 Z-1 R1", 1, "Q word missing with g83"),
        ("G73 X1 Z-1 R1", 1, "Q word missing with g73"),
        ("G83 X1 Z-1 R1 Q0", 15, "Negative or zero q value used"),
        ("G83 X1 Z-1 R1 Q-2", 15, "Negative or zero q value used"),
        ("G82 X1 Z-1 R1", 1, "Dwell time p word missing with g82"),
        ("G89 X1 Z-1 R1", 1, "Dwell time p word missing with g89"),
        ("G81 X1 Z-1 R1 L0", 15, "Cannot do zero repeats of cycle"),
        ("G81 X1 Z-1 R1 L-2", 15, "Negative l word used"),
        ("G81 X1 Z-1 R1 L1.5", 15, "Non integer value for integer"),
        ("G81 X1 Z-1 R1 A5", 15, "Cannot put an a in canned cycle"),
        ("G81 R1 L2", 1, "All axes missing with motion code"),
        ("G80 X1", 1, "Cannot use axis values with g80"),
        ("G0 X1 L2", 7, "L word with no G10"),
        ("G81 X1 Z-1 R1 P1", 15, "P word with no G2 G3 G4"),
        ("G81 X1 Z-1 R1 Q1", 15, "Q word with no G5, G10, G64, G73"),
        ("G81 X1 Z-1 R1 I1", 15, "I word with no G2, G3"),
        ("G82 X1 Z-1 R1 P-0.5", 15, "Negative P word used"),
        ("G53 G81 X1 Z-1 R1", 1, "must use G0 or G1 with G53"),
    ];
    for (block, col, msg) in cases {
        let d = error(D, &format!("{pre}{block}\n"));
        assert_diag(&d, 3, col, &[msg]);
    }
    // Kerf's bound on one block (rs274 has none): a million pecks is refused.
    let d = error(D, &format!("{pre}G83 X1 Z-1000 R0 Q0.001\n"));
    assert_diag(
        &d,
        3,
        1,
        &["more than 100000 moves and events in one block"],
    );
    let d = error(D, "G21 G0 Z5\nG81 X1 Z-1 R1\n");
    assert_diag(&d, 2, 1, &["Cannot feed with zero feed rate"]);
    let settings = Settings {
        tools: vec![Tool {
            number: 1,
            length_mm: 0.0,
            radius_mm: 0.0,
            ..Tool::default()
        }],
        ..Settings::default()
    };
    let d = error_with(D, settings, "G21 T1 M6 F100\nG41 G0 X1 Z5\nG81 X1 Z-1 R1\n");
    assert_diag(
        &d,
        3,
        1,
        &["Cannot use canned cycles with cutter compensation on"],
    );
}

#[test]
fn spindle_synchronised_cycles_are_refused() {
    for code in ["G33", "G33.1", "G74", "G76", "G84"] {
        let d = error(D, &format!("G21 F100\n{code} X1 Z-1 R1\n"));
        assert_diag(
            &d,
            2,
            1,
            &[&format!(
                "{code} is not supported: needs spindle synchronisation"
            )],
        );
    }
}

#[test]
fn a_failing_cycle_block_gives_nothing() {
    // The preliminary moves of a block that then fails are not emitted (rs274 prints
    // them before its error; Kerf's blocks are atomic).
    let src = "G21 G0 Z5\nF100\nG86 X3 Z-1 R1 P1\n";
    let out = run_bytes(D, Settings::default(), src.as_bytes());
    assert_eq!(out.items.len(), 1, "{}", describe_items(&out.items));
    let d = out.error.expect("an error");
    assert_diag(&d, 3, 1, &["Spindle not turning in g86"]);
}

/// One random cycle block and its start, for the property test.
#[derive(Debug, Clone)]
struct Case {
    kind: usize,
    plane: usize,
    g99: bool,
    incremental: bool,
    start: [f64; 3],
    a: f64,
    b: f64,
    r: f64,
    depth: f64,
    q: f64,
    l: u32,
    k_frac: f64,
}

fn case() -> impl Strategy<Value = Case> {
    (
        (0usize..9, 0usize..3, any::<bool>(), any::<bool>()),
        prop::array::uniform3(-50.0f64..50.0),
        (-50.0f64..50.0, -50.0f64..50.0, -20.0f64..20.0),
        (0.0f64..30.0, 0.05f64..10.0, 1u32..5, 0.0f64..1.0),
    )
        .prop_map(
            |((kind, plane, g99, incremental), start, (a, b, r), (depth, q, l, k_frac))| Case {
                kind,
                plane,
                g99,
                incremental,
                start,
                a: (a * 1000.0).round() / 1000.0,
                b: (b * 1000.0).round() / 1000.0,
                r: (r * 1000.0).round() / 1000.0,
                depth: (depth * 1000.0).round() / 1000.0,
                q: (q * 1000.0).round() / 1000.0 + 0.001,
                l,
                k_frac,
            },
        )
}

#[test]
fn random_valid_cycle_blocks_stay_between_the_bottom_and_the_clearance_level() {
    let config = ProptestConfig {
        cases: 1500,
        rng_seed: RngSeed::Fixed(0x6379_636c_6573),
        failure_persistence: None,
        ..ProptestConfig::default()
    };
    let mut runner = TestRunner::new(config);
    let result = runner.run(&case(), |c| {
        let codes = [
            "G73", "G81", "G82", "G83", "G85", "G86", "G87", "G88", "G89",
        ];
        let code = codes[c.kind];
        // Plane: (G code, in-plane words, drilling axis word, drilling axis index).
        let (pg, wa, wb, ww, w) = [
            ("G17", 'X', 'Y', 'Z', 2),
            ("G18", 'Z', 'X', 'Y', 1),
            ("G19", 'Y', 'Z', 'X', 0),
        ][c.plane];
        let ijk = ['I', 'J', 'K'];
        let [sx, sy, sz] = c.start;
        // The levels in absolute terms (machine = program: no offsets): R from the
        // initial level in G91, the bottom `depth` below R.
        let initial = c.start[w];
        let r_abs = if c.incremental { initial + c.r } else { c.r };
        let bottom = r_abs - c.depth;
        let (r_word, z_word) = if c.incremental {
            (c.r, -c.depth)
        } else {
            (r_abs, bottom)
        };
        let mut block = format!(
            "{} {} {code} {wa}{} {wb}{} {ww}{z_word} R{r_word} L{}",
            if c.g99 { "G99" } else { "G98" },
            if c.incremental { "G91" } else { "G90" },
            c.a,
            c.b,
            c.l
        );
        if matches!(code, "G73" | "G83") {
            block += &format!(" Q{}", c.q);
        }
        if matches!(code, "G82" | "G86" | "G88" | "G89") {
            block += " P0.1";
        }
        if code == "G87" {
            // Offsets in the plane and the top of the back bore between bottom and R.
            let middle = bottom + c.k_frac * c.depth;
            let mid_word = if c.incremental {
                middle - bottom
            } else {
                middle
            };
            let axes = [(0usize, 1.5), (1, -2.0), (2, 0.0)];
            for (i, off) in axes {
                let val = if i == w { mid_word } else { off };
                block += &format!(" {}{val}", ijk[i]);
            }
        }
        let src = format!("G21 G90 G17 G0 X{sx} Y{sy} Z{sz}\nS1000 M3 F200\n{pg}\n{block}\nM2\n");
        let out = run_bytes(D, Settings::default(), src.as_bytes());
        if let Some(e) = &out.error {
            return Err(TestCaseError::fail(format!("rejected: {e}\n{src}")));
        }
        // A peck backs off 0.254 mm from its depth: with Q under 0.254 mm the first back-off
        // rises above R (R − Q + 0.254), as in rs274.
        let peck_top = if matches!(code, "G73" | "G83") {
            r_abs - c.q + 0.254
        } else {
            f64::NEG_INFINITY
        };
        let top = r_abs.max(initial).max(peck_top);
        let r_top = r_abs.max(peck_top);
        let ms: Vec<Move> = only_moves(&out.items)
            .into_iter()
            .filter(|m| m.line == 4)
            .collect();
        prop_assert!(!ms.is_empty(), "no moves\n{src}");
        let eps = 1e-9;
        let mut reached_r = false;
        // The start may lie anywhere (even below the bottom): only where the moves go counts.
        for m in &ms {
            let l = as_line(m);
            let p = l.end;
            prop_assert!(p[w] >= bottom - eps, "below the bottom: {p:?}\n{src}");
            prop_assert!(p[w] <= top + eps, "above the clearance: {p:?}\n{src}");
            if c.g99 && reached_r && code != "G87" {
                prop_assert!(p[w] <= r_top + eps, "G99 above R: {p:?}\n{src}");
            }
            if (l.end[w] - r_abs).abs() < eps {
                reached_r = true;
            }
        }
        Ok(())
    });
    if let Err(e) = result {
        panic!("{e}");
    }
}
