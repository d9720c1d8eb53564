//! LinuxCNC cutter radius compensation (G40, G41, G42, G41.1, G42.1), checked against the
//! moves LinuxCNC's own interpreter prints for the same programs. The expected values are
//! rs274's canonical calls (tests/rs274/canon.sh, four decimals: the programs of
//! tests/data/ngc/comp/ and the ones written here were run through it), so positions are
//! compared to 5e-5 mm; the property test at the end measures the compensated path itself.

use std::cell::RefCell;
use std::f64::consts::TAU;

use proptest::prelude::*;
use proptest::test_runner::{RngSeed, TestRunner};

use kerf_tests::*;

const D: Dialect = Dialect::LinuxCnc;
/// rs274 prints four decimals.
const PRINTED: f64 = 5.1e-5;
/// Arc centres: where LinuxCNC's compensated arc starts off its circle (a corner within its
/// 0.05 rad tolerance) it spirals; Kerf moves the centre onto the chord's bisector, by less
/// than the radius difference (r·(1 − cos 0.05) < 0.0013·r).
const CENTRE_MM: f64 = 2e-3;

/// The tools of tests/data/ngc/comp/*.tbl: T1 Ø10, T2 Ø4, T3 Ø25.4 (mm).
fn tools() -> Settings {
    let t = |number, dia: f64| Tool {
        number,
        length_mm: 0.0,
        radius_mm: dia / 2.0,
        ..Tool::default()
    };
    Settings {
        tools: vec![t(1, 10.0), t(2, 4.0), t(3, 25.4)],
        ..Settings::default()
    }
}

fn program(name: &str) -> String {
    let path = data_dir().join("ngc/comp").join(format!("{name}.ngc"));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// What rs274 printed for one move: a line to `end`, or an arc to `end` about `center`
/// (in the XY plane; `ccw` its direction).
enum Want {
    Feed(f64, f64, f64),
    Rapid(f64, f64, f64),
    Arc(f64, f64, f64, f64, bool, f64),
}
use Want::*;

fn check_moves(what: &str, ms: &[Move], want: &[Want]) {
    assert_eq!(
        ms.len(),
        want.len(),
        "{what}: move count\n{}",
        ms.iter().map(describe_move).collect::<Vec<_>>().join("\n")
    );
    for (i, (m, w)) in ms.iter().zip(want).enumerate() {
        let what = format!("{what}: move {}", i + 1);
        match *w {
            Feed(x, y, z) | Rapid(x, y, z) => {
                assert_eq!(m.rapid, matches!(w, Rapid(..)), "{what}: rapid");
                let l = as_line(m);
                assert_point(&what, l.end, v(x, y, z), PRINTED);
            }
            Arc(x, y, cx, cy, ccw, z) => {
                let a = as_arc(m);
                assert_point(&what, a.end, v(x, y, z), PRINTED);
                assert_close(&format!("{what} centre x"), a.center[0], cx, CENTRE_MM);
                assert_close(&format!("{what} centre y"), a.center[1], cy, CENTRE_MM);
                assert_eq!(a.sweep_rad > 0.0, ccw, "{what}: direction");
                check_arc_geometry(&a, 1e-9);
            }
        }
    }
    assert_continuous(ms, ms.first().map_or(v(0.0, 0.0, 0.0), |m| m.path.start()));
}

#[test]
fn g41_rectangle_entry_outside_corners_inside_corner_and_exit() {
    let ms = moves_with(D, tools(), &program("lines_g41"));
    check_moves(
        "lines_g41",
        &ms,
        &[
            Rapid(-20.0, -20.0, 0.0),
            // Entry: one radius from X0 Y0, normal to the entry direction.
            Feed(-3.5355, 3.5355, 0.0),
            // Outside corner: an arc about the programmed corner.
            Arc(0.0, 5.0, 0.0, 0.0, false, 0.0),
            // Inside corners: the lines end where the offset lines meet.
            Feed(45.0, 5.0, 0.0),
            Feed(45.0, 25.0, 0.0),
            Feed(35.0, 25.0, 0.0),
            Feed(35.0, 20.0, 0.0),
            Arc(30.0, 15.0, 30.0, 20.0, false, 0.0),
            Feed(5.0, 15.0, 0.0),
            Feed(5.0, 0.0, 0.0),
            // Exit after G40: straight to the programmed point.
            Rapid(-20.0, -20.0, 0.0),
        ],
    );
}

#[test]
fn g42_rapid_entry_acute_corners_and_z_moves_held_at_the_corner() {
    let ms = moves_with(D, tools(), &program("lines_g42"));
    check_moves(
        "lines_g42",
        &ms,
        &[
            Rapid(-10.0, 0.0, 5.0),
            Rapid(0.0, -2.0, 5.0),
            Feed(0.0, -2.0, -1.0),
            Arc(0.4851, -1.9403, 0.0, 0.0, true, -1.0),
            Feed(40.4851, 8.0597, -1.0),
            Arc(41.1094, 11.6641, 40.0, 10.0, true, -1.0),
            Feed(11.1094, 31.6641, -1.0),
            Feed(11.1094, 31.6641, 2.0),
            Feed(11.1094, 31.6641, -1.0),
            Arc(8.1026, 30.6325, 10.0, 30.0, true, -1.0),
            Feed(-1.8974, 0.6325, -1.0),
            // A G0 corner is a straight traverse, not an arc.
            Rapid(-1.9403, 0.4851, -1.0),
            Rapid(-6.9403, -19.5149, -1.0),
            Rapid(-10.0, -30.0, -1.0),
        ],
    );
}

#[test]
fn arcs_line_arc_and_arc_arc_corners_inside_and_outside_of_arcs() {
    let ms = moves_with(D, tools(), &program("arcs"));
    check_moves(
        "arcs",
        &ms,
        &[
            Rapid(-10.0, -10.0, 0.0),
            // rs274: STRAIGHT_FEED(-1.4142, 1.4142, ...), i.e. 2 mm along the diagonal.
            Feed(-std::f64::consts::SQRT_2, std::f64::consts::SQRT_2, 0.0),
            Arc(0.0, 2.0, 0.0, 0.0, false, 0.0),
            Feed(20.0, 2.0, 0.0),
            Arc(22.0, 0.0, 20.0, 0.0, false, 0.0),
            Arc(38.0, 0.0, 30.0, 0.0, true, 0.0),
            Arc(58.0, 8.9443, 50.0, 0.0, false, 0.0),
            Feed(58.0, 30.0, 0.0),
            Arc(40.0, 48.0, 40.0, 30.0, true, 0.0),
            Feed(10.9545, 48.0, 0.0),
            Arc(2.0, 18.1181, 0.0, 35.0, false, 0.0),
            Feed(2.0, 0.0, 0.0),
            Feed(-10.0, -10.0, 0.0),
        ],
    );
}

#[test]
fn arc_entry_moves_the_centre_and_arc_to_line_inside_corner() {
    let ms = moves_with(D, tools(), &program("arc_entry"));
    check_moves(
        "arc_entry",
        &ms,
        &[
            Rapid(0.0, -30.0, 0.0),
            Arc(-28.0, 0.0, 2.0714, 0.0, false, 0.0),
            Feed(-28.0, 18.0, 0.0),
            Feed(10.0, 18.0, 0.0),
            Feed(20.0, 40.0, 0.0),
        ],
    );
}

#[test]
fn g41_1_and_g42_1_take_the_diameter_and_a_negative_one_swaps_the_side() {
    let ms = moves_with(D, tools(), &program("g41_1"));
    check_moves(
        "g41_1",
        // rs274 also prints the zero-length `G0 X0 Y0` from the origin; Kerf does not.
        &ms,
        &[
            Feed(17.0, 3.0, 0.0),
            Feed(17.0, 17.0, 0.0),
            Feed(0.0, 17.0, 0.0),
            Rapid(-10.0, -10.0, 0.0),
            Feed(-2.1213, 2.1213, 0.0),
            Arc(0.0, 3.0, 0.0, 0.0, false, 0.0),
            Feed(17.0, 3.0, 0.0),
            Feed(17.0, 20.0, 0.0),
            Rapid(0.0, -20.0, 0.0),
        ],
    );
}

#[test]
fn inch_program_uses_the_table_radius_in_mm_and_g41_1_diameter_in_inches() {
    let ms = moves_with(D, tools(), &program("inch"));
    let i = |x: f64| x * INCH_MM;
    // rs274 prints inches to four decimals: 0.00005 in.
    let tol = 5.1e-5 * INCH_MM;
    let want = [
        (-1.0, -1.0),
        (-0.3536, 0.3536),
        (0.0, 0.5),
        (1.5, 0.5),
        (1.5, 1.0),
        (0.0, 1.0),
        (-1.0, -1.0),
        (-0.0884, 0.0884),
        (-0.0303, 0.1213),
        (1.9697, 0.6213),
        (2.0, 0.625),
        (2.0, 1.375),
        (-1.0, -1.0),
    ];
    assert_eq!(
        ms.len(),
        want.len(),
        "{}",
        ms.iter().map(describe_move).collect::<Vec<_>>().join("\n")
    );
    for (k, (m, &(x, y))) in ms.iter().zip(&want).enumerate() {
        assert_point(
            &format!("inch move {}", k + 1),
            m.path.end(),
            v(i(x), i(y), 0.0),
            tol,
        );
    }
}

#[test]
fn g18_compensates_in_the_zx_plane() {
    let ms = moves_with(D, tools(), &program("xz"));
    let ends: Vec<Vec3> = ms.iter().map(|m| m.path.end()).collect();
    let want = [
        v(0.0, 0.0, 10.0),
        v(8.5858, 0.0, -std::f64::consts::SQRT_2), // rs274: (8.5858, 0, -1.4142)
        v(10.0, 0.0, -2.0),
        v(18.1678, 0.0, -2.0),
        v(28.0, 0.0, -11.8322),
        v(28.0, 0.0, -20.0),
        v(40.0, 0.0, -30.0),
    ];
    assert_eq!(ends.len(), want.len());
    for (k, (g, w)) in ends.iter().zip(&want).enumerate() {
        assert_point(&format!("xz move {}", k + 1), *g, *w, PRINTED);
    }
    // rs274: ARC_FEED(-11.8322, 28.0000, 0.0000, 30.0000, -1, ...): Z and X of the end,
    // then of the centre.
    let a = as_arc(&ms[4]);
    assert_close("xz arc centre x", a.center[0], 30.0, PRINTED);
    assert_close("xz arc centre z", a.center[2], 0.0, PRINTED);
    assert!(a.sweep_rad < 0.0);
    assert_eq!(a.axis, axis_g18());
}

#[test]
fn events_stay_behind_the_held_move_as_linuxcnc_queues_them() {
    let items = run_with(D, tools(), &program("events")).unwrap();
    let order: Vec<String> = items
        .iter()
        .map(|it| match it {
            Item::Move(m) => {
                let e = m.path.end();
                format!("move {:.4} {:.4}", e[0], e[1])
            }
            Item::Event(e) => e.code.as_str().to_string(),
        })
        .collect();
    // rs274: SET_SPINDLE_SPEED, START_SPINDLE_CLOCKWISE, FLOOD_ON and DWELL come after
    // the feed to (25, 5) that was held when they were read; M0 releases the held move.
    let want = [
        "T",
        "M6",
        "move -20.0000 0.0000",
        "move 0.0000 5.0000",
        "move 25.0000 5.0000",
        "S",
        "M3",
        "M8",
        "G4",
        "move 25.0000 30.0000",
        "M0",
        "move -0.0000 25.0000",
        "M5",
        "M9",
        "move -20.0000 40.0000",
        "M2",
    ];
    let want: Vec<String> = want.iter().map(|s| s.to_string()).collect();
    let norm = |v: &[String]| {
        v.iter()
            .map(|s| s.replace("-0.0000", "0.0000"))
            .collect::<Vec<_>>()
    };
    assert_eq!(norm(&order), norm(&want));
}

#[test]
fn a_held_move_is_dropped_at_a_closing_percent_as_in_linuxcnc() {
    let ms = moves_with(D, tools(), &program("percent_end"));
    check_moves("percent_end", &ms, &[Feed(18.8197, 5.0, 0.0)]);
}

#[test]
fn end_of_file_without_m2_is_refused_and_the_held_move_does_not_run() {
    // rs274 refuses a file without M2 or `%` ("File ended with no percent sign or program
    // end", at its last line) after the moves it has run; the move that compensation
    // holds back is not among them.
    let with_m2 = moves_with(D, tools(), "G21 F100\nT1 M6\nG41 G1 X20 Y0\nX40 Y10\nM2\n");
    let src = "G21 F100\nT1 M6\nG41 G1 X20 Y0\nX40 Y10\n";
    let out = run_bytes(D, tools(), src.as_bytes());
    let e = out.error.expect("refused");
    assert_diag(
        &e,
        4,
        1,
        &["File ended with no percent sign or program end"],
    );
    let before = only_moves(&out.items);
    assert_eq!(before.len(), 1);
    assert_same_moves("before the end of file", &before, &with_m2[..1], TOL);
}

#[test]
fn after_g40_words_refer_to_the_programmed_point_and_the_move_starts_at_the_tool() {
    let ms = moves_with(D, tools(), &program("exit_reference"));
    check_moves(
        "exit_reference",
        &ms,
        &[
            Rapid(-20.0, 0.0, 0.0),
            Feed(0.0, 5.0, 0.0),
            Feed(30.0, 5.0, 0.0),
            // `G1 X50` after G40: Y is the programmed 0, not the compensated 5.
            Feed(50.0, 0.0, 0.0),
            Feed(55.0, 5.0, 0.0),
            Feed(45.9010, 25.0, 0.0),
            Feed(20.0, 25.0, 0.0),
            // `G40 Y50`: X is the programmed 20.
            Feed(20.0, 50.0, 0.0),
        ],
    );
    // The exit move starts where the compensated move ended.
    assert_point("exit start", ms[3].path.start(), v(30.0, 5.0, 0.0), PRINTED);
}

#[test]
fn program_end_checks_the_held_arc_and_an_empty_queue_keeps_its_last_front() {
    let out = run_bytes(D, tools(), program("err_stop_gouge").as_bytes());
    let diag = out.error.expect("err_stop_gouge accepted");
    assert_diag_line(
        &diag,
        8,
        &["Arc move in concave corner cannot be reached by the tool without gouging"],
    );
    check_moves(
        "err_stop_gouge",
        &only_moves(&out.items),
        &[Rapid(-30.0, -30.0, 0.0), Feed(-4.2627, -1.4343, 0.0)],
    );
    // After M1 nothing is held; at the next inside corner LinuxCNC computes the corner from
    // the stale front of its queue, moves nothing, and starts the arc where the tool is, off
    // its circle: rs274 prints ARC_FEED(-24.4662, -2.9572, -6.1252, -24.8497, 1, ...) from
    // (6.4906, 4.9420), a spiral from radius 32.35 to 28.56. Kerf refuses that block.
    // Not a golden of the rs274 harness: Kerf refuses it on purpose (rs274's spiral).
    let stale_front = "(M1 releases the held arc; at the next corner nothing is held and LinuxCNC still reads that arc as its queue front)\n\
G21 G17 G90 F100\n\
T2 M6\n\
G0 X-30 Y-30\n\
G41\n\
G1 X0 Y0\n\
G2 X6.58 Y2.944 R9.816\n\
M1\n\
G3 X-29.619 Y-5.306 R30.56\n\
G2 X10.91 Y-32.702 R36.57\n\
G40 G0 X-30 Y-30\n\
M2\n\
";
    let out = run_bytes(D, tools(), stale_front.as_bytes());
    let diag = out.error.expect("stale_front accepted");
    assert_diag_line(&diag, 9, &["spiral", "not support"]);
    check_moves(
        "stale_front",
        &only_moves(&out.items),
        &[
            Rapid(-30.0, -30.0, 0.0),
            Feed(-std::f64::consts::SQRT_2, std::f64::consts::SQRT_2, 0.0),
            Arc(6.4906, 4.9420, 7.0189, -6.8622, false, 0.0),
        ],
    );
}

/// Programs rs274 refuses: its message, the line, and the moves it printed before.
#[test]
fn linuxcnc_errors_with_comp() {
    let cases: [(&str, u32, &str, usize); 11] = [
        (
            "err_concave",
            8,
            "Straight feed in concave corner cannot be reached by the tool without gouging",
            4,
        ),
        (
            "err_arc_radius",
            7,
            "Tool radius not less than arc radius with comp",
            3,
        ),
        (
            "err_plane",
            3,
            "Cutter radius compensation allowed only in XY, XZ planes",
            0,
        ),
        ("err_g53", 5, "Cannot use g53 with cutter radius comp", 1),
        (
            "err_entry",
            3,
            "Length of cutter compensation entry move is not greater than the tool radius",
            0,
        ),
        (
            "err_arc_after_g40",
            6,
            "The move just after exiting cutter compensation mode must be straight, not an arc",
            2,
        ),
        (
            "err_on_when_on",
            4,
            "Cannot turn cutter radius comp on when on",
            0,
        ),
        (
            "err_tool",
            2,
            "Requested tool 7 not found in the tool table",
            0,
        ),
        (
            "err_plane_change",
            4,
            "Cannot change planes with cutter radius compensation on",
            0,
        ),
        (
            "err_m6",
            4,
            "Cannot change tools with cutter radius compensation on",
            0,
        ),
        ("err_entry", 3, "entry move", 0),
    ];
    for (name, line, message, moves_before) in cases {
        let out = run_bytes(D, tools(), program(name).as_bytes());
        let diag = out.error.unwrap_or_else(|| panic!("{name}: accepted"));
        assert_diag_line(&diag, line, &[message]);
        assert_eq!(
            only_moves(&out.items).len(),
            moves_before,
            "{name}: moves before the error"
        );
    }
}

#[test]
fn other_errors_with_comp_on() {
    let cases = [
        (
            "G55\n",
            "Cannot change coordinate systems with cutter radius compensation on",
        ),
        (
            "G92 X0\n",
            "Cannot change axis offsets with cutter radius comp",
        ),
        (
            "G43 H1\n",
            "Cannot change tool offset with cutter radius compensation on",
        ),
        (
            "G41.1 D2 G1 X40\n",
            "Cannot turn cutter radius comp on when on",
        ),
    ];
    for (block, message) in cases {
        let src = format!("G21 F100\nT1 M6\nG41 G1 X20 Y0\n{block}M2\n");
        let d = error_with(D, tools(), &src);
        assert_diag_line(&d, 4, &[message]);
    }
    let d = error_with(D, tools(), "G21 F100\nG41 D1.5 G1 X20\n");
    assert_diag_line(&d, 2, &["G41 requires D word to be a whole number"]);
    let d = error_with(D, tools(), "G21 F100\nG42.1 G1 X20\n");
    assert_diag_line(&d, 2, &["G42.1 with no D word"]);
    let d = error_with(D, tools(), "G21 F100\nG41.1 D4 L3 G1 X20\n");
    assert_diag_line(&d, 2, &["G41.1 with L word, but plane is not G18"]);
    let d = error_with(D, tools(), "G21 F100\nG1 X1 D1\n");
    assert_diag_line(&d, 2, &["D word with no G41"]);
    // Other dialects keep refusing a non-zero radius.
    let d = error_with(Dialect::Rockwell, tools(), "T1 M06\nG41 G01 X10 F100\n");
    assert_diag_line(&d, 2, &["cutter compensation not supported"]);
}

/// A random convex polygon programmed as an outside profile (G41 clockwise or G42
/// counter-clockwise) with a random tool radius: every compensated line lies at exactly
/// the tool radius from the programmed edge its block follows, on the outer side and
/// parallel to it, and every corner arc turns about the programmed corner at that radius.
#[test]
fn outside_profile_of_a_convex_polygon_stays_one_radius_from_every_edge() {
    let config = ProptestConfig {
        cases: 400,
        rng_seed: RngSeed::Fixed(0x6341_3432),
        failure_persistence: None,
        ..ProptestConfig::default()
    };
    let mut runner = TestRunner::new(config);
    let checked = RefCell::new(0usize);
    let strategy = (
        prop::collection::vec(0.0f64..1.0, 3..12),
        5.0f64..200.0,
        0.01f64..1.0,
        any::<bool>(),
    );
    let result = runner.run(&strategy, |(gaps, size_mm, radius_frac, left)| {
        // Corners on a circle at increasing angles (every gap at least a few degrees):
        // a convex polygon, counter-clockwise.
        let total: f64 = gaps.iter().map(|g| g + 0.15).sum();
        let mut a = 0.0f64;
        let mut pts: Vec<(f64, f64)> = Vec::new();
        for g in &gaps {
            let r = (size_mm * 1e4).round() / 1e4;
            pts.push((
                ((r * a.cos()) * 1e4).round() / 1e4,
                ((r * a.sin()) * 1e4).round() / 1e4,
            ));
            a += TAU * (g + 0.15) / total;
        }
        if left {
            pts.reverse();
        }
        let radius = ((size_mm * radius_frac) * 1e4).round() / 1e4;
        let n = pts.len();
        // Start on the backward extension of the first edge, so that the entry move runs
        // into it; close the polygon, then leave with G40.
        let (p0, p1) = (pts[0], pts[1]);
        let len = ((p1.0 - p0.0).powi(2) + (p1.1 - p0.1).powi(2)).sqrt();
        let back = (
            p0.0 - (p1.0 - p0.0) / len * size_mm,
            p0.1 - (p1.1 - p0.1) / len * size_mm,
        );
        let mut src = format!(
            "G21 G17 G90 F500\nG0 X{:.6} Y{:.6}\n{} D{:.4} G1 X{:.4} Y{:.4}\n",
            back.0,
            back.1,
            if left { "G41.1" } else { "G42.1" },
            2.0 * radius,
            p0.0,
            p0.1
        );
        let first_edge_line = 3u32;
        for k in 1..=n {
            let p = pts[k % n];
            src.push_str(&format!("X{:.4} Y{:.4}\n", p.0, p.1));
        }
        src.push_str(&format!(
            "G40 G0 X{:.6} Y{:.6}\nM2\n",
            back.0 * 2.0,
            back.1 * 2.0
        ));
        let ms = moves(D, &src);
        let tol = 1e-9 * size_mm.max(1.0) * 100.0;
        let mut lines_seen = 0;
        for m in &ms {
            // Block first_edge_line + k follows the edge from corner k to corner k+1.
            let Some(k) = m.line.checked_sub(first_edge_line + 1) else {
                continue;
            };
            let k = k as usize;
            if k >= n {
                continue;
            }
            let (a, b) = (pts[k], pts[(k + 1) % n]);
            let (dx, dy) = (b.0 - a.0, b.1 - a.1);
            let l = (dx * dx + dy * dy).sqrt();
            // Signed distance, positive to the left of the edge.
            let dist = |p: Vec3| (dx * (p[1] - a.1) - dy * (p[0] - a.0)) / l;
            let want = if left { radius } else { -radius };
            match m.path {
                Path::Line(seg) => {
                    lines_seen += 1;
                    prop_assert!(
                        (dist(seg.start) - want).abs() < tol,
                        "{src}\nstart of {seg:?} at {} from edge {k}",
                        dist(seg.start)
                    );
                    prop_assert!(
                        (dist(seg.end) - want).abs() < tol,
                        "{src}\nend of {seg:?} at {} from edge {k}",
                        dist(seg.end)
                    );
                    let (sx, sy) = (seg.end[0] - seg.start[0], seg.end[1] - seg.start[1]);
                    prop_assert!(
                        sx * dx + sy * dy > 0.0,
                        "{src}\n{seg:?} runs against edge {k}"
                    );
                }
                Path::Arc(arc) => {
                    prop_assert!(
                        (arc.center[0] - a.0).abs() < tol && (arc.center[1] - a.1).abs() < tol,
                        "{src}\ncorner arc {arc:?} not about corner {k}"
                    );
                    let r0 = ((arc.start[0] - a.0).powi(2) + (arc.start[1] - a.1).powi(2)).sqrt();
                    let r1 = ((arc.end[0] - a.0).powi(2) + (arc.end[1] - a.1).powi(2)).sqrt();
                    prop_assert!(
                        (r0 - radius).abs() < tol && (r1 - radius).abs() < tol,
                        "{src}\ncorner arc radius {r0} {r1}"
                    );
                    prop_assert!((arc.sweep_rad > 0.0) != left, "{src}\ncorner arc direction");
                }
            }
        }
        prop_assert_eq!(lines_seen, n, "{}: one compensated line per edge", src);
        *checked.borrow_mut() += 1;
        Ok(())
    });
    if let Err(e) = result {
        panic!("{e}");
    }
    assert_eq!(*checked.borrow(), 400);
}
