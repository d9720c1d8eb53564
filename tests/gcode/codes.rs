//! LinuxCNC codes of issue 9 that the golden programs (tests/data/ngc/codes/) cannot show
//! against rs274: the ones Kerf refuses although rs274 accepts them (no Fanuc-style
//! subprograms, no UVW planes), rs274's word checks of M19, and what the events carry.
//! Expected values from the LinuxCNC manual (sections M19, M48–M53, M98/M99, G17.1) and
//! from rs274's messages for the same lines. The machine I/O codes M62–M68 (issue 28):
//! the goldens of tests/data/ngc/io and the front end's unit tests (`interp::io`).

use kerf_gcode::{Dialect, EventCode, Item};
use kerf_tests::*;

const D: Dialect = Dialect::LinuxCnc;

fn events(src: &str) -> Vec<Event> {
    items(D, src)
        .into_iter()
        .filter_map(|i| match i {
            Item::Event(e) => Some(e),
            Item::Move(_) => None,
        })
        .collect()
}

#[test]
fn fanuc_subprograms_and_uvw_planes_are_clear_errors() {
    for (line, col, words) in [
        (
            "M98 P100",
            1,
            &["M98 is not supported", "o-word subroutines"][..],
        ),
        ("M99", 1, &["M99 is not supported", "o-word subroutines"]),
        ("G17.1", 1, &["G17.1 is not supported", "U/V/W"]),
        ("G18.1 G0 X1", 1, &["G18.1 is not supported"]),
        ("G19.1", 1, &["G19.1 is not supported"]),
    ] {
        let src = format!("G21 G0 X5\n{line}\nM2\n");
        let out = run_bytes(D, Default::default(), src.as_bytes());
        let e = out.error.unwrap_or_else(|| panic!("{line}: accepted"));
        assert_diag(&e, 2, col, words);
        // Nothing of the refused block runs: only the rapid of line 1.
        assert_eq!(only_moves(&out.items).len(), 1, "{line}");
    }
}

/// Issue 28: the machine I/O codes are events that carry their words (the LinuxCNC
/// manual's M62–M68: P the digital output or input, E the analog one, L the wait mode, Q
/// the timeout or the analog value); the golden programs of tests/data/ngc/io compare
/// them with rs274.
#[test]
fn io_codes_are_events_with_their_words() {
    let ev =
        events("G21\nM62 P1\nM63 P1\nM64 P7\nM65 P7\nM66 P2 L3 Q4\nM66 E1\nM67 E0 Q5\nM68 E0 Q0\n");
    type Words = (EventCode, Option<f64>, Option<f64>, Option<f64>);
    let got: Vec<Words> = ev.iter().map(|e| (e.code, e.value, e.p, e.q)).collect();
    use EventCode::*;
    assert_eq!(
        got,
        [
            (M62, Some(1.0), None, None),
            (M63, Some(1.0), None, None),
            (M64, Some(7.0), None, None),
            (M65, Some(7.0), None, None),
            (M66, Some(2.0), Some(3.0), Some(4.0)),
            (M66Analog, Some(1.0), Some(0.0), None),
            (M67, Some(0.0), None, Some(5.0)),
            (M68, Some(0.0), None, Some(0.0)),
        ]
    );
    // The wait's result, offline (every simulated input off): input 2 never goes high.
    let e = events("G21\nM66 P2 L3 Q4\n(PRINT,#5399)\n");
    assert_eq!(e[1].text.as_deref(), Some("-1.000000"));
}

#[test]
fn m19_carries_its_angle_direction_and_wait() {
    let ev = events("G21\nM19 R90 Q2 P1\nM19\nM19 R360 P2\n");
    let m19: Vec<_> = ev.iter().filter(|e| e.code == EventCode::M19).collect();
    assert_eq!(m19.len(), 3);
    assert_eq!(
        (m19[0].value, m19[0].p, m19[0].q),
        (Some(90.0), Some(1.0), Some(2.0))
    );
    // Without words: angle 0, the shorter way (P0), no wait.
    assert_eq!(
        (m19[1].value, m19[1].p, m19[1].q),
        (Some(0.0), Some(0.0), None)
    );
    assert_eq!((m19[2].value, m19[2].p), (Some(360.0), Some(2.0)));
}

#[test]
fn m19_words_are_checked_as_rs274_checks_them() {
    for (line, col, msg) in [
        ("M19 R-30", 5, "R value must be within 0..360 with M19"),
        ("M19 R360.5", 5, "R value must be within 0..360 with M19"),
        ("M19 Q0", 5, "Q word with M19 requires a value > 0"),
        ("M19 P3", 5, "P value must be 0,1,or 2 with M19"),
        ("M19 P0.5", 5, "P value must be 0,1,or 2 with M19"),
        // M19 is in the spindle group with M3, M4 and M5.
        ("M19 R5 M5", 8, "two M codes used from same modal group"),
        ("M3 M19", 4, "two M codes used from same modal group"),
    ] {
        let e = error(D, &format!("G21\n{line}\n"));
        assert_diag(&e, 2, col, &[msg]);
    }
}

#[test]
fn m19_stops_the_spindle() {
    // rs274 (same program): ORIENT_SPINDLE, then "Spindle not turning in g86" (it prints
    // the cycle's first moves before the check; Kerf refuses the whole block).
    let e = error(D, "G21 F100\nM3 S100\nM19 R30\nG86 X1 Y1 Z-1 R1 P1\n");
    assert_diag_line(&e, 4, &["Spindle not turning in G86"]);
    assert!(error_free(
        D,
        "G21 F100\nM3 S100\nM19 R30\nM3\nG86 X1 Y1 Z-1 R1 P1\n"
    ));
}

fn error_free(d: Dialect, src: &str) -> bool {
    run(d, src).is_ok()
}

#[test]
fn override_controls_are_events_with_their_state() {
    let ev = events("G21\nM48\nM49\nM50\nM50 P0\nM51 P0\nM51 P2\nM52 P1\nM52 P0\nM53\nM53 P0\n");
    let got: Vec<(EventCode, Option<f64>)> = ev.iter().map(|e| (e.code, e.value)).collect();
    assert_eq!(
        got,
        vec![
            (EventCode::M48, None),
            (EventCode::M49, None),
            (EventCode::M50, Some(1.0)),
            (EventCode::M50, Some(0.0)),
            (EventCode::M51, Some(0.0)),
            (EventCode::M51, Some(1.0)),
            (EventCode::M52, Some(1.0)),
            (EventCode::M52, Some(0.0)),
            (EventCode::M53, Some(1.0)),
            (EventCode::M53, Some(0.0)),
        ]
    );
    // One modal group (rs274: "Two m codes used from same modal group").
    let e = error(D, "G21\nM48 M50\n");
    assert_diag(&e, 2, 5, &["two M codes used from same modal group"]);
    // A P word no code uses is still refused.
    let e = error(D, "G21\nM48 P1\n");
    assert_diag(&e, 2, 5, &["P word with no"]);
}

#[test]
fn the_end_of_file_rules() {
    let run = |src: &str| run_bytes(D, Default::default(), src.as_bytes());
    let out = run("G21 G0 X1\nG1 X2 F100\n");
    assert_diag(
        &out.error.expect("refused"),
        2,
        1,
        &["File ended with no percent sign or program end"],
    );
    assert_eq!(only_moves(&out.items).len(), 2);
    let out = run("%\nG21 G0 X1\n");
    assert_diag(
        &out.error.expect("refused"),
        2,
        1,
        &["File ended with no percent sign"],
    );
    let out = run("");
    assert_diag(
        &out.error.expect("refused"),
        1,
        1,
        &["File ended with no percent sign"],
    );
    let out = run("G21 G0 X1\n%\nG0 X5\nM2\n");
    assert_diag(
        &out.error.expect("refused"),
        2,
        1,
        &["Bad character '%' used"],
    );
    assert!(run("%\nG0 X1\n%\n").error.is_none());
    assert!(run("G0 X1\nM30\nG0 X5\n").error.is_none());
    // The other dialects keep their rule: the end of the file ends the program.
    let out = run_bytes(Dialect::Rockwell, Default::default(), b"G00 X1 ;\n");
    assert!(out.error.is_none());
}

#[track_caller]
fn near(got: Vec3, want: Vec3) {
    assert_point("point", got, want, 1e-12);
}

#[test]
fn an_end_on_the_start_ray_turns_a_whole_circle_then_reaches_the_end() {
    use kerf_gcode::Path;
    // LinuxCNC: the end angle equals the start angle about the programmed centre, so its
    // planner turns a whole circle, spiralling from radius 5 to 5.001. Kerf: the whole
    // circle at radius 5 about (5, 0), then the 0.001 mm radial line.
    let ms = moves(D, "G21 G17 F100\nG0 X10\nG2 X10.001 Y0 I-5 J0\n");
    assert_eq!(ms.len(), 3, "{ms:#?}");
    let Path::Arc(a) = &ms[1].path else {
        panic!("an arc: {:?}", ms[1])
    };
    near(a.center, v(5.0, 0.0, 0.0));
    near(a.start, v(10.0, 0.0, 0.0));
    near(a.end, v(10.0, 0.0, 0.0));
    assert!(
        (a.sweep_rad + std::f64::consts::TAU).abs() < 1e-12,
        "{}",
        a.sweep_rad
    );
    let Path::Line(l) = &ms[2].path else {
        panic!("a line: {:?}", ms[2])
    };
    near(l.start, v(10.0, 0.0, 0.0));
    near(l.end, v(10.001, 0.0, 0.0));
    assert_eq!((ms[2].line, ms[2].feed_mm_min), (3, Some(100.0)));
    // A helix keeps its climb on the turn; P adds turns.
    let ms = moves(D, "G21 G17 F100\nG0 X10\nG3 X9.999 Z2 I-5 J0 P2\n");
    let Path::Arc(a) = &ms[1].path else {
        panic!("an arc")
    };
    near(a.end, v(10.0, 0.0, 2.0));
    assert!((a.sweep_rad - 2.0 * std::f64::consts::TAU).abs() < 1e-12);
    near(ms[2].path.end(), v(9.999, 0.0, 2.0));
    // Other dialects keep their rule (the centre onto the chord's bisector: one arc).
    let ms = moves(
        Dialect::Sinumerik,
        "G17 G1 X10 F100\nG2 X10.001 Y0 I=AC(5) J=AC(0)\n",
    );
    assert_eq!(ms.len(), 2);
    // Refused where the split would be wrong: inverse time and cutter compensation.
    let e = error(D, "G21 G17 G0 X10\nG93 G2 X10.001 Y0 I-5 J0 F1\n");
    assert_diag(&e, 2, 19, &["inverse time (G93)"]);
}
