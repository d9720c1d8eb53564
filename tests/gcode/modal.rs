//! LinuxCNC modal state (issue 9): order of execution inside a block, feed modes
//! G93/G94/G95, path control G61/G61.1/G64 P Q, M70–M73, program stops and user M codes,
//! and, in every dialect, blocks that Kerf cannot execute completely being errors.
//!
//! Expected values come from the LinuxCNC manual and from rs274's canonical calls for the
//! golden programs in `tests/data/ngc/modal/` (quoted next to each assertion), never from
//! Kerf. rs274 prints positions and feeds in program units: inches are converted here by
//! hand (× 25.4).

use std::f64::consts::PI;

use kerf_tests::*;

const D: Dialect = Dialect::LinuxCnc;

fn golden(name: &str) -> String {
    let path = data_dir().join("ngc/modal").join(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn assert_feeds(what: &str, ms: &[Move], want: &[Option<f64>]) {
    assert_eq!(ms.len(), want.len(), "{what}: {}", describe_moves(ms));
    for (i, (m, w)) in ms.iter().zip(want).enumerate() {
        match (m.feed_mm_min, w) {
            (Some(g), Some(w)) => assert_close(&format!("{what}: feed of move {i}"), g, *w, 1e-9),
            (g, w) => assert_eq!(g, *w, "{what}: feed of move {i}"),
        }
    }
}

fn describe_moves(ms: &[Move]) -> String {
    ms.iter().map(describe_move).collect::<Vec<_>>().join("\n")
}

fn codes(items: &[Item]) -> Vec<String> {
    items
        .iter()
        .map(|i| match i {
            Item::Move(m) => format!("move{}", m.line),
            Item::Event(e) => e.code.as_str().to_string(),
        })
        .collect()
}

// ---------------------------------------------------------------------------------------
// Order of execution

#[test]
fn f_is_set_before_the_units_of_its_block() {
    // order_feed_units.canon: SET_FEED_RATE(40) before USE_LENGTH_UNITS(INCHES), so F40
    // is 40 mm/min; SET_FEED_RATE(2) before USE_LENGTH_UNITS(MM), so that F2 is 2 in/min.
    let ms = moves(D, &golden("order_feed_units.ngc"));
    assert_feed_line(&ms[0], v(0.0, 0.0, 0.0), v(25.4, 0.0, 0.0), 40.0);
    assert_feed_line(&ms[1], v(25.4, 0.0, 0.0), v(50.8, 0.0, 0.0), 40.0);
    assert_feed_line(&ms[2], v(50.8, 0.0, 0.0), v(60.0, 0.0, 0.0), 2.0 * 25.4);
    assert_feed_line(&ms[3], v(60.0, 0.0, 0.0), v(70.0, 0.0, 0.0), 2.0 * 25.4);
    assert_feed_line(&ms[4], v(70.0, 0.0, 0.0), v(80.0, 0.0, 0.0), 100.0);
    assert_eq!(ms.len(), 5);
}

#[test]
fn one_block_runs_in_linuxcnc_order() {
    // order_block.canon, line 4: SET_FEED_RATE(10), SET_SPINDLE_SPEED(500), SELECT_TOOL(1),
    // CHANGE_TOOL(1), START_SPINDLE_CLOCKWISE, FLOOD_ON, DWELL(0.5), SELECT_PLANE(XZ),
    // USE_LENGTH_UNITS(INCHES), G54, incremental, STRAIGHT_FEED(1, 0, -1) in inches.
    let mut s = Settings::default();
    s.tools.push(Tool {
        number: 1,
        length_mm: 10.0,
        radius_mm: 3.0,
        ..Tool::default()
    });
    let items = run_with(D, s, &golden("order_block.ngc")).expect("valid program");
    let line4: Vec<&Item> = items.iter().filter(|i| item_line(i) == 4).collect();
    let names: Vec<String> = line4
        .iter()
        .map(|i| match i {
            Item::Move(_) => "move".to_string(),
            Item::Event(e) => e.code.as_str().to_string(),
        })
        .collect();
    assert_eq!(names, ["S", "T", "M6", "M3", "M8", "G4", "move"]);
    let ms = only_moves(&items);
    // G55 G0 X0 Y0 from the origin moves nothing (zero offsets): not emitted.
    assert_feed_line(&ms[0], v(0.0, 0.0, 0.0), v(25.4, 0.0, -25.4), 10.0);
    assert_feed_line(&ms[1], v(25.4, 0.0, -25.4), v(50.8, 0.0, -25.4), 10.0);
    // Line 6: F200 is read in inches (SET_FEED_RATE(200) before USE_LENGTH_UNITS(MM)),
    // the move is absolute in mm; events M5 then M9 before it.
    assert_feed_line(&ms[2], v(50.8, 0.0, -25.4), v(50.0, 0.0, 0.0), 200.0 * 25.4);
    // G17 is back: ARC_FEED(60, 0, 55, 0, -1) about Z.
    assert_arc(
        &ms[3],
        v(50.0, 0.0, 0.0),
        v(60.0, 0.0, 0.0),
        v(55.0, 0.0, 0.0),
        axis_g17(),
        -PI,
    );
    let line6: Vec<String> = codes(&items)
        .into_iter()
        .zip(&items)
        .filter(|(_, i)| item_line(i) == 6)
        .map(|(c, _)| c)
        .collect();
    assert_eq!(line6, ["M5", "M9", "move6"]);
}

#[test]
fn m70_saves_the_state_after_f_and_before_the_g_codes_of_its_block() {
    // Manual, order of execution: F, S, ..., M3, then M70, and G20/G91 only after it.
    // `M70 G20 F7` saves G21 and F7 (save_restore.canon: the later M72 changes the units
    // back to mm and sets no feed).
    let ms = moves(D, "G21 G90 F100\nM70 G20 G91 F7\nG1 X1\nM72\nG1 X20\n");
    assert_feed_line(&ms[0], v(0.0, 0.0, 0.0), v(25.4, 0.0, 0.0), 7.0);
    assert_feed_line(&ms[1], v(25.4, 0.0, 0.0), v(20.0, 0.0, 0.0), 7.0);
    // F and S run before M72: the restored values win (rs274: SET_FEED_RATE(50),
    // SET_SPINDLE_SPEED(500), then SET_FEED_RATE(100), SET_SPINDLE_SPEED(1000)).
    let items = items_of("G21 F100 S1000\nM70\nF50 S500 M72\nG1 X1\n");
    let line3: Vec<Option<f64>> = only_events(&items)
        .into_iter()
        .filter(|e| e.line == 3)
        .map(|e| e.value)
        .collect();
    assert_eq!(line3, [Some(500.0), Some(1000.0)]);
    assert_eq!(only_moves(&items)[0].feed_mm_min, Some(100.0));
    // M72 before the block's G codes: `M72 G91` ends incremental.
    let ms = moves(D, "G21 G90 F100\nM70\nM72 G91 G1 X1\nX1\n");
    assert_feed_line(&ms[0], v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), 100.0);
    assert_feed_line(&ms[1], v(1.0, 0.0, 0.0), v(2.0, 0.0, 0.0), 100.0);
}

// ---------------------------------------------------------------------------------------
// Feed modes

#[test]
fn inverse_time_feed_is_the_length_times_f() {
    // feed_inverse_time.canon: SET_FEED_RATE 20, 2.5, 47.1239 (5π·3), 16.4845, 0.1
    // (the least rate), 0.4251 in/min, then G94 F10 in/min.
    let ms = moves(D, &golden("feed_inverse_time.ngc"));
    let helix = (5.0 * PI).hypot(5.0);
    let short_inch = (25.4 - 20.001) / 25.4 * 2.0;
    assert_feeds(
        "G93",
        &ms,
        &[
            None,
            Some(20.0),
            Some(2.5),
            None,
            Some(15.0 * PI),
            Some(helix),
            Some(0.1),
            Some(short_inch * 25.4),
            Some(254.0),
        ],
    );
    assert_close("rs274 arc rate", 15.0 * PI, 47.1239, 1e-4);
    assert_close("rs274 helix rate", helix, 16.4845, 1e-4);
    assert_close("rs274 inch rate", short_inch, 0.4251, 1e-4);
}

#[test]
fn inverse_time_needs_f_on_every_feed_move() {
    // rs274: "F word missing with inverse time g1 move" (f.ngc); rapids need none.
    let d = error(D, "G93 G1 X1 F2\nG0 X5\nG1 X2\n");
    assert_diag(&d, 3, 1, &["F word missing with inverse time G1 move"]);
    let d = error(D, "G93 G1 X1 F2\nG2 X3 R1\n");
    assert_diag(&d, 2, 1, &["F word missing with inverse time arc move"]);
    // A rotary-only move: degrees times F (rs274: G93 G1 A10 F2 gives SET_FEED_RATE(20)).
    let ms = moves(D, "G93 G1 A10 F2\n");
    assert_close(
        "rotary inverse time",
        ms[0].feed_mm_min.unwrap_or(0.0),
        20.0,
        1e-12,
    );
}

#[test]
fn feed_per_revolution_uses_the_commanded_spindle_speed() {
    // feed_per_rev.canon: F0.1 mm/rev at S1000, then S2000, F0.05; M5 does not matter;
    // F0.002 is set before G20 (mm/rev); G94 F10 in/min.
    let ms = moves(D, &golden("feed_per_rev.ngc"));
    assert_feeds(
        "G95",
        &ms,
        &[
            Some(100.0),
            Some(100.0),
            Some(200.0),
            Some(100.0),
            Some(100.0),
            Some(4.0),
            Some(254.0),
        ],
    );
}

#[test]
fn feed_mode_errors_are_linuxcncs() {
    // rs274 l.ngc: "Cannot feed with zero spindle speed in feed per rev mode".
    let d = error(D, "G95 S0 G1 X1 F1\n");
    assert_diag(
        &d,
        1,
        8,
        &["Cannot feed with zero spindle speed in feed per rev mode"],
    );
    let d = error(D, "G95 G1 X1 F1\n");
    assert_diag(&d, 1, 5, &["zero spindle speed"]);
    // Any G93/G94/G95 sets the feed rate to zero (rs274 j.ngc: F100, G94, G1 X1 is
    // "Cannot do g1 with zero feed rate").
    let d = error(D, "F100\nG94\nG1 X1\n");
    assert_diag(&d, 3, 1, &["Cannot do G1 with zero feed rate"]);
    let d = error(D, "S100 F100\nG95\nG1 X1\n");
    assert_diag(&d, 3, 1, &["Cannot do G1 with zero feed rate"]);
    // rs274: "Negative f word used".
    let d = error(D, "G94 F-1\n");
    assert_diag(&d, 1, 5, &["Negative F word used"]);
    // G94 F in one block: the mode first, then F.
    let ms = moves(D, "G94 F100 G1 X1\n");
    assert_eq!(ms[0].feed_mm_min, Some(100.0));
}

// ---------------------------------------------------------------------------------------
// Path control

#[test]
fn g64_p_and_q_are_carried_with_the_moves() {
    // path_control.canon: G61 EXACT_PATH, G61.1 EXACT_STOP (Kerf stops for both);
    // G64: CONTINUOUS 0 and naive CAM 0 (Kerf: the configured default, no naive CAM);
    // G64 P0.05: 0.05 and 0.05; G64 P0.05 Q0.01: 0.05 and 0.01; G64 Q0.02: P 0, naive
    // 0.02; G20 G64 P0.001 Q0.0005 in inches.
    let ms = moves(D, &golden("path_control.ngc"));
    let blend = |t: Option<f64>, q: Option<f64>| CornerMode::Blend {
        tolerance_mm: t,
        naive_cam_mm: q,
    };
    let want = [
        blend(None, None),
        CornerMode::ExactStop,
        CornerMode::ExactStop,
        blend(None, None),
        blend(Some(0.05), Some(0.05)),
        blend(Some(0.05), Some(0.01)),
        blend(None, Some(0.02)),
    ];
    assert_eq!(ms.len(), 8);
    for (i, w) in want.iter().enumerate() {
        assert_eq!(ms[i].corner, *w, "move {i}");
    }
    match ms[7].corner {
        CornerMode::Blend {
            tolerance_mm: Some(t),
            naive_cam_mm: Some(q),
        } => {
            assert_close("P in inches", t, 0.0254, 1e-12);
            assert_close("Q in inches", q, 0.0127, 1e-12);
        }
        c => panic!("G20 G64 P Q gave {c:?}"),
    }
}

// ---------------------------------------------------------------------------------------
// M70–M73

fn save_restore_items() -> Vec<Item> {
    run(D, &golden("save_restore.ngc")).expect("valid program")
}

#[test]
fn m72_restores_units_distance_plane_feed_and_spindle() {
    // save_restore.canon: STRAIGHT_FEED 10; 1.3937 in (X +1 in, G91, F5 mm/min); after
    // M72 20 mm at F100; Y 1 in at F7; 20 mm at F7; after M73 and G91 X+1 at F3, M72:
    // absolute 30 at F7; 40 at F7.
    let items = save_restore_items();
    let ms = only_moves(&items);
    assert_feed_line(&ms[0], v(0.0, 0.0, 0.0), v(10.0, 0.0, 0.0), 100.0);
    assert_feed_line(&ms[1], v(10.0, 0.0, 0.0), v(35.4, 0.0, 0.0), 5.0);
    assert_feed_line(&ms[2], v(35.4, 0.0, 0.0), v(20.0, 0.0, 0.0), 100.0);
    assert_feed_line(&ms[3], v(20.0, 0.0, 0.0), v(20.0, 25.4, 0.0), 7.0);
    assert_feed_line(&ms[4], v(20.0, 25.4, 0.0), v(20.0, 20.0, 0.0), 7.0);
    assert_feed_line(&ms[5], v(20.0, 20.0, 0.0), v(21.0, 20.0, 0.0), 3.0);
    assert_feed_line(&ms[6], v(21.0, 20.0, 0.0), v(30.0, 20.0, 0.0), 7.0);
    assert_feed_line(&ms[7], v(30.0, 20.0, 0.0), v(40.0, 20.0, 0.0), 7.0);
    // G64 P0.1 is back after the G61.
    assert_eq!(
        ms[2].corner,
        CornerMode::Blend {
            tolerance_mm: Some(0.1),
            naive_cam_mm: Some(0.1)
        }
    );
    assert_eq!(ms[1].corner, CornerMode::ExactStop);
}

#[test]
fn m72_restores_spindle_and_coolant_as_rs274_does() {
    // save_restore.canon at the first M72 (line 7): SET_SPINDLE_SPEED(1000),
    // START_SPINDLE_CLOCKWISE, no coolant call (flood was on and stays on; mist, turned
    // on since, stays on). Line 20 (M72 after M9, M70, M7): MIST_OFF FLOOD_OFF. Line 23
    // (M72 after M70, M9 M5): START_SPINDLE_CLOCKWISE only.
    let items = save_restore_items();
    let events_of = |line: u32| -> Vec<(String, Option<f64>)> {
        only_events(&items)
            .into_iter()
            .filter(|e| e.line == line)
            .map(|e| (e.code.as_str().to_string(), e.value))
            .collect()
    };
    assert_eq!(
        events_of(7),
        [("S".to_string(), Some(1000.0)), ("M3".to_string(), None)]
    );
    assert_eq!(events_of(11), []);
    assert_eq!(events_of(20), [("M9".to_string(), None)]);
    assert_eq!(events_of(23), [("M3".to_string(), None)]);
    // rs274 u.ngc runs: saved M8 and now M7 gives FLOOD_ON only; saved M7 and M8 with
    // nothing on gives MIST_ON FLOOD_ON.
    let ev = |src: &str| -> Vec<String> {
        only_events(&items_of(src))
            .into_iter()
            .filter(|e| e.line == 5)
            .map(|e| e.code.as_str().to_string())
            .collect()
    };
    assert_eq!(ev("M8\nM70\nM9\nM7\nM72\n"), ["M8"]);
    assert_eq!(ev("M7\nM8\nM70\nM9\nM72\n"), ["M7", "M8"]);
    assert_eq!(ev("M3 S100\nM70\nM4\nM5\nM72\n"), ["M3"]);
    // No S before M70 is speed 0 (rs274: SET_SPINDLE_SPEED(0) at the M72).
    let restored: Vec<(String, Option<f64>)> =
        only_events(&items_of("G21\nM70\nS300\nG4 P0\nM72\n"))
            .into_iter()
            .filter(|e| e.line == 5)
            .map(|e| (e.code.as_str().to_string(), e.value))
            .collect();
    assert_eq!(restored, [("S".to_string(), Some(0.0))]);
}

fn items_of(src: &str) -> Vec<Item> {
    run(D, src).expect("valid program")
}

#[test]
fn m72_applies_the_tool_length_offset_anew() {
    // save_restore_tool_length.canon: USE_TOOL_LENGTH_OFFSET 10, 0, then 10 again at
    // M72; program Z stays 1.
    let s = settings_with_tool(1, 10.0, 3.0);
    let ms = moves_with(D, s, &golden("save_restore_tool_length.ngc"));
    let zs: Vec<f64> = ms.iter().map(|m| m.path.end().z).collect();
    assert_eq!(ms.len(), 3, "{}", describe_moves(&ms));
    assert_close("G43", zs[0], 11.0, 1e-12);
    assert_close("G49", zs[1], 1.0, 1e-12);
    assert_close("M72", zs[2], 11.0, 1e-12);
}

#[test]
fn m72_without_a_saved_state_is_an_error() {
    // rs274: "Cannot restore context from invalid stack frame - missing M70/M73?"
    let d = error(D, "G1 X1 F10\nM72\n");
    assert_diag(
        &d,
        2,
        1,
        &["Cannot restore context from invalid stack frame - missing M70/M73?"],
    );
    // M71 invalidates it.
    let d = error(D, "M70\nM71\nM72\n");
    assert_diag(&d, 3, 1, &["missing M70/M73"]);
    // M73 in the main program saves like M70 (rs274 h.ngc: M72 restores it) and the
    // program's end does not restore it.
    let ms = moves(D, "G21 F100\nM73\nG20 F5\nM72\nG1 X1\nM73\nG20\nM2\n");
    assert_feed_line(&ms[0], v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), 100.0);
}

#[test]
fn m70_to_m73_share_the_spindle_group() {
    // rs274: "Two m codes used from same modal group" for M3 M70 and M70 M72; M7 M70
    // and M6 M70 are fine.
    for (src, col) in [("M3 M70\n", 4), ("M70 M72\n", 5), ("M73 M71\n", 5)] {
        let d = error(D, src);
        assert_diag(&d, 1, col, &["two M codes used from same modal group"]);
    }
    assert!(run(D, "M7 M70\nM6 M70\n").is_ok());
    // rs274 refuses M7 M8 in one block too.
    let d = error(D, "M7 M8\n");
    assert_diag(&d, 1, 4, &["two M codes used from same modal group"]);
}

// ---------------------------------------------------------------------------------------
// Stops and user M codes

#[test]
fn m0_m1_m60_stop_after_the_motion() {
    // stops.canon: STRAIGHT_FEED then PROGRAM_STOP, OPTIONAL_PROGRAM_STOP, PALLET_SHUTTLE
    // PROGRAM_STOP.
    let items = run(D, &golden("stops.ngc")).expect("valid program");
    assert_eq!(
        codes(&items),
        ["move3", "M0", "move4", "M1", "move5", "M60", "M2"]
    );
    // M60 and M0 are one group (rs274: "Two m codes used from same modal group").
    let d = error(D, "M60 M0\n");
    assert_diag(&d, 1, 5, &["two M codes used from same modal group"]);
}

#[test]
fn user_m_codes_are_events_with_p_and_q() {
    // Manual: M100–M199 run after the coolant and before the dwell, with P and Q.
    // One P serves both the user code and the dwell.
    let items = items_of("M101 G4 P3 Q-4.5 M8\nM199\n");
    let evs = only_events(&items);
    let names: Vec<&str> = evs.iter().map(|e| e.code.as_str()).collect();
    assert_eq!(names, ["M8", "M101", "G4", "M199"]);
    assert_eq!(evs[1].code, EventCode::User(1));
    assert_eq!((evs[1].value, evs[1].q), (Some(3.0), Some(-4.5)));
    assert_eq!(evs[2].value, Some(3.0));
    assert_eq!(evs[3].code, EventCode::User(99));
    assert_eq!((evs[3].value, evs[3].q), (None, None));
    // P and Q belong to the user code (rs274: "P word with no G2 ... or user M code to
    // use it"): a Q without one is still an error.
    let d = error(D, "G1 X1 F1 Q2\n");
    assert_diag(
        &d,
        1,
        10,
        &[
            "Q word with no G5, G10, G64, G73, G76, G83, M19, M66, M67, M68 or user M code that uses it",
        ],
    );
    // One user code per block (rs274: M100 M101 is "Two m codes used from same modal
    // group"); M200 is unknown.
    let d = error(D, "M100 M101\n");
    assert_diag(&d, 1, 6, &["two M codes used from same modal group"]);
    let d = error(D, "M200\n");
    assert_diag(&d, 1, 1, &["unknown M code M200"]);
    // Only LinuxCNC knows them.
    let d = error(Dialect::Rockwell, "M100 ;\n");
    assert_diag(&d, 1, 1, &["unknown M code M100"]);
}

// ---------------------------------------------------------------------------------------
// Blocks are executed completely or refused

#[test]
fn linuxcnc_words_no_code_uses_are_errors() {
    // Each message as rs274 gives it, in Kerf's words.
    let cases = [
        // rs274: "Cannot use two g codes that both use axis values".
        (
            "G1 G92 X0 F10\n",
            4,
            "Cannot use two g codes that both use axis values",
        ),
        // rs274: "R word with no g code that uses it".
        ("G92 X0 R5\n", 8, "R word with no g code that uses it"),
        // rs274: "H word with no G43 or G76 to use it".
        ("G49 H1\n", 5, "H word with no G43 to use it"),
        // rs274: "D word with no G41, G41.1, G42, G42.1 ... to use it".
        ("G1 X1 D1 F10\n", 7, "D word with no G41 or G42 to use it"),
        // rs274: "J word missing in absolute center arc".
        (
            "G1 X10 F10\nG90.1 G3 X0 Y-10 I0\n",
            7,
            "J word missing in absolute center arc",
        ),
    ];
    for (src, col, msg) in cases {
        let d = error(D, src);
        assert!(
            d.col == col && d.message.contains(msg),
            "{src:?}: got {d}, want col {col} {msg:?}"
        );
    }
}

#[test]
fn other_dialects_refuse_words_they_would_drop() {
    let zero = settings_with_tool(1, 0.0, 0.0);
    let radius = settings_with_tool(1, 0.0, 2.0);
    let cases: Vec<(Dialect, Settings, &str, u32, u32, &str)> = vec![
        // Rockwell: P is the G04 dwell only, Q no code uses, D only with G41/G42, H with G49.
        (
            Dialect::Rockwell,
            Settings::default(),
            "G01 X1 F100 P5 ;\n",
            1,
            13,
            "P word",
        ),
        (
            Dialect::Rockwell,
            Settings::default(),
            "G01 X1 F100 Q5 ;\n",
            1,
            13,
            "Q word",
        ),
        (
            Dialect::Rockwell,
            Settings::default(),
            "D1 G01 X1 F100 ;\n",
            1,
            1,
            "D word with no G41 or G42",
        ),
        (
            Dialect::Rockwell,
            Settings::default(),
            "G49 H1 ;\n",
            1,
            5,
            "H word",
        ),
        // Sinumerik: H auxiliary functions go to the machine's logic; D selects the
        // tool's offsets (here a 2 mm radius Kerf would not apply).
        (
            Dialect::Sinumerik,
            Settings::default(),
            "G1 X1 F100 H2\n",
            1,
            12,
            "H auxiliary functions are not supported",
        ),
        (
            Dialect::Sinumerik,
            radius.clone(),
            "T1 D1\n",
            1,
            4,
            "tool offsets (D) are not supported",
        ),
        // Fagor: the same D rule; G30 takes I/J only.
        (
            Dialect::Fagor,
            radius,
            "T1 D1\n",
            1,
            4,
            "tool offsets (D) are not supported",
        ),
        (
            Dialect::Fagor,
            Settings::default(),
            "G30 X5\n",
            1,
            5,
            "X word with G30",
        ),
        // Heidenhain: L belongs to G99; a G99 block holds no axes; a blank form block
        // holds no M codes.
        (
            Dialect::Heidenhain,
            Settings::default(),
            "N10 G01 X+1 L5 F100 *\n",
            1,
            13,
            "L word with no G99",
        ),
        (
            Dialect::Heidenhain,
            Settings::default(),
            "N10 G99 T1 L+0 R+2 X+5 *\n",
            1,
            20,
            "X word in a tool definition",
        ),
        (
            Dialect::Heidenhain,
            Settings::default(),
            "N10 G30 G17 X+0 Y+0 Z-20 M3 *\n",
            1,
            26,
            "blank form",
        ),
    ];
    for (d, s, src, line, col, msg) in cases {
        let e = error_with(d, s, src);
        assert!(
            e.line == line && e.col == col && e.message.contains(msg),
            "{d:?} {src:?}: got {e}, want {line}:{col} {msg:?}"
        );
    }
    // Sinumerik, Heidenhain and Fagor apply the called tool's length: Kerf does not, so a
    // call of a tool with a length is refused (a zero length is fine).
    for (d, src, col) in [
        (Dialect::Sinumerik, "G1 X1 F100\nT1\n", 1),
        (Dialect::Fagor, "G1 X1 F100\nT1 M6\n", 1),
    ] {
        let e = error_with(d, settings_with_tool(1, 50.0, 0.0), src);
        assert!(
            e.line == 2 && e.col == col && e.message.contains("tool length compensation"),
            "{d:?}: {e}"
        );
    }
    let e = error(
        Dialect::Heidenhain,
        "%A G71 *\nG99 T1 L+10 R+0 *\nT1 G17 *\n",
    );
    assert!(
        e.line == 3 && e.message.contains("tool length compensation"),
        "{e}"
    );
    assert!(
        run(
            Dialect::Heidenhain,
            "%A G71 *\nG99 T1 L+0 R+0 *\nT1 G17 *\n"
        )
        .is_ok()
    );
    // D0, or D1 with a tool without offsets, changes nothing and is accepted.
    assert!(run_with(Dialect::Sinumerik, zero.clone(), "T1 D1\nD0\n").is_ok());
    assert!(run_with(Dialect::Fagor, zero, "T1 D1\n").is_ok());
    // A Heidenhain G99 block's M code still runs.
    let items = items_of_dialect(Dialect::Heidenhain, "N10 G99 T1 L+0 R+0 M30 *\n");
    assert_eq!(codes(&items), ["M30"]);
}

fn items_of_dialect(d: Dialect, src: &str) -> Vec<Item> {
    run(d, src).expect("valid program")
}

#[test]
fn g90_1_and_g91_1_arc_centres() {
    // arc_distance.canon: ARC_FEED(0, -10, 0, 0, -1) about (0,0); (-10, 0) about (0,0)
    // from J10 incremental; (0, -10) about (0, 0) counter-clockwise.
    let ms = moves(D, &golden("arc_distance.ngc"));
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(0.0, -10.0, 0.0),
        v(0.0, 0.0, 0.0),
        axis_g17(),
        -PI / 2.0,
    );
    assert_arc(
        &ms[2],
        v(0.0, -10.0, 0.0),
        v(-10.0, 0.0, 0.0),
        v(0.0, 0.0, 0.0),
        axis_g17(),
        -PI / 2.0,
    );
    assert_arc(
        &ms[3],
        v(-10.0, 0.0, 0.0),
        v(0.0, -10.0, 0.0),
        v(0.0, 0.0, 0.0),
        axis_g17(),
        PI / 2.0,
    );
}

#[test]
fn block_delete_and_unsupported_modal_codes() {
    // Manual 11.4.2.1: `/` first on a line deletes the block when the switch is on.
    let on = Settings {
        block_delete: true,
        ..Default::default()
    };
    let ms = moves_with(D, on.clone(), "G1 X1 F10\n/G1 X5\nG1 X2\n");
    assert_eq!(ms.len(), 2);
    assert_feed_line(&ms[1], v(1.0, 0.0, 0.0), v(2.0, 0.0, 0.0), 10.0);
    // rs274: "Bad character '/' used" in the middle of a line.
    let d = error(D, "G1 X2 /Y3 F10\n");
    assert_eq!((d.line, d.col), (1, 7), "{d}");
    // rs274: spaces may come first, a comment or an N word may not ("Bad character '/'").
    assert_eq!(moves_with(D, on, " /G1 X5 F10\n").len(), 0);
    for (src, col) in [("(c) /G1 X1 F1\n", 5), ("N10 /G1 X1 F1\n", 5)] {
        let d = error(D, src);
        assert_eq!((d.line, d.col), (1, col), "{src:?}: {d}");
    }
    // Constant surface speed is refused.
    let d = error(D, "G96 S100\n");
    assert_diag(&d, 1, 1, &["G96", "not supported"]);
}

#[test]
fn m6_runs_before_g43_in_one_block() {
    // rs274 (T1 length 10): `T1 M6 G43 G1 X1 Z0` is CHANGE_TOOL(1), then
    // USE_TOOL_LENGTH_OFFSET(0 0 10), then STRAIGHT_FEED(1, 0, 0): the new tool's length.
    let ms = moves_with(
        D,
        settings_with_tool(1, 10.0, 3.0),
        "G21 F100\nT1 M6 G43 G1 X1 Z0\n",
    );
    assert_feed_line(&ms[0], v(0.0, 0.0, 0.0), v(1.0, 0.0, 10.0), 100.0);
}
