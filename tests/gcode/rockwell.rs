//! Rockwell Automation 9/Series mill (Fanuc style), from the 9/Series Mill Operation and
//! Programming Manual (seed 002: arcs in G17/G18/G19) and the DESIGN.md notes.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use kerf_tests::*;

const D: Dialect = Dialect::Rockwell;

fn o() -> Vec3 {
    v(0.0, 0.0, 0.0)
}

#[test]
fn semicolon_ends_a_block_and_is_not_a_comment() {
    // Two blocks on one source line: the text after `;` is executed, both moves carry line 1.
    let ms = moves(D, "G01 X10 F100 ; G01 Y10 ;\nX0 ;\n");
    assert_eq!(ms.len(), 3, "{ms:#?}");
    assert_feed_line(&ms[0], o(), v(10.0, 0.0, 0.0), 100.0);
    assert_feed_line(&ms[1], v(10.0, 0.0, 0.0), v(10.0, 10.0, 0.0), 100.0);
    assert_feed_line(&ms[2], v(10.0, 10.0, 0.0), v(0.0, 10.0, 0.0), 100.0);
    assert_eq!([ms[0].line, ms[1].line, ms[2].line], [1, 1, 2]);
}

#[test]
fn parenthesised_comments_and_block_numbers() {
    // [S] Comments in parentheses (Fanuc style).
    let ms = moves(
        D,
        "N10 G00 X5 (GO TO X5; NOT A BLOCK END) ;\nN20 G01 Y5 F50 ;\n",
    );
    assert_eq!(ms.len(), 2, "{ms:#?}");
    assert_rapid(&ms[0], o(), v(5.0, 0.0, 0.0));
    assert_feed_line(&ms[1], v(5.0, 0.0, 0.0), v(5.0, 5.0, 0.0), 50.0);
}

#[test]
fn rapids_lines_absolute_and_incremental() {
    let ms = moves(
        D,
        "G90 G00 X10 Y5 Z2 ;\nG01 Z-1 F100 ;\nG91 X5 Y5 ;\nG90 X0 ;\n",
    );
    assert_rapid(&ms[0], o(), v(10.0, 5.0, 2.0));
    assert_feed_line(&ms[1], v(10.0, 5.0, 2.0), v(10.0, 5.0, -1.0), 100.0);
    assert_feed_line(&ms[2], v(10.0, 5.0, -1.0), v(15.0, 10.0, -1.0), 100.0);
    assert_feed_line(&ms[3], v(15.0, 10.0, -1.0), v(0.0, 10.0, -1.0), 100.0);
}

#[test]
fn centre_words_are_always_incremental_from_the_start() {
    // Seed 002: "These values are always incremental regardless of the established
    // positioning mode (absolute or incremental)." In G90, I-10 J0 from (10,0) is the
    // centre (0,0), not (-10,0).
    let ms = moves(D, "G01 X10 F100 ;\nG90 G03 X0 Y10 I-10 J0 ;\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(0.0, 10.0, 0.0),
        o(),
        axis_g17(),
        FRAC_PI_2,
    );
    // In G91 the end point is incremental too, the centre still from the start.
    let ms = moves(D, "G01 X10 F100 ;\nG91 G03 X-10 Y10 I-10 J0 ;\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(0.0, 10.0, 0.0),
        o(),
        axis_g17(),
        FRAC_PI_2,
    );
}

#[test]
fn arcs_in_zx_and_yz_planes_with_seed_word_order() {
    // Seed 002: G18 {G02|G03} Z__ X__ {K__ I__}; G19 {G02|G03} Y__ Z__ {J__ K__}.
    // G18 about +Y: from +X to +Z the short way is clockwise (G02, -90°).
    let ms = moves(D, "G01 X10 F100 ;\nG18 G02 Z10 X0 K0 I-10 ;\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(0.0, 0.0, 10.0),
        o(),
        axis_g18(),
        -FRAC_PI_2,
    );
    // G19 about +X: from +Y to +Z is counter-clockwise (G03, +90°).
    let ms = moves(D, "G01 Y10 F100 ;\nG19 G03 Y0 Z10 J-10 K0 ;\n");
    assert_arc(
        &ms[1],
        v(0.0, 10.0, 0.0),
        v(0.0, 0.0, 10.0),
        o(),
        axis_g19(),
        FRAC_PI_2,
    );
}

#[test]
fn missing_plane_axis_word_keeps_the_current_location() {
    // Seed 002 CAUTION: an omitted axis word of the plane takes the current tool location.
    // From (10,0), `G03 Y10 J5` ends at (10,10) about the centre (10,5): a counter-clockwise
    // semicircle.
    let ms = moves(D, "G01 X10 F100 ;\nG03 Y10 J5 ;\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(10.0, 10.0, 0.0),
        v(10.0, 5.0, 0.0),
        axis_g17(),
        PI,
    );
}

#[test]
fn radius_arcs_positive_and_negative() {
    // Seed 002: R positive -> arc <= 180°, R negative -> arc > 180°.
    let cases = [
        ("G02 X10 Y10 R10", v(10.0, 0.0, 0.0), -FRAC_PI_2),
        ("G02 X10 Y10 R-10", v(0.0, 10.0, 0.0), -1.5 * PI),
        ("G03 X10 Y10 R10", v(0.0, 10.0, 0.0), FRAC_PI_2),
        ("G03 X10 Y10 R-10", v(10.0, 0.0, 0.0), 1.5 * PI),
    ];
    for (block, center, sweep) in cases {
        let ms = moves(D, &format!("F100 ;\n{block} ;\n"));
        assert_arc(&ms[0], o(), v(10.0, 10.0, 0.0), center, axis_g17(), sweep);
    }
}

#[test]
fn r_wins_over_ijk_in_the_same_block() {
    // [M] R and I/J/K in one block: R is used. I0 J10 alone would give the valid centre
    // (0,10) and a -270° arc; R10 gives the centre (10,0) and -90°.
    let ms = moves(D, "F100 ;\nG02 X10 Y10 I0 J10 R10 ;\n");
    assert_arc(
        &ms[0],
        o(),
        v(10.0, 10.0, 0.0),
        v(10.0, 0.0, 0.0),
        axis_g17(),
        -FRAC_PI_2,
    );
}

#[test]
fn full_circle_with_end_omitted_or_equal_to_start() {
    let ms = moves(D, "G01 X10 F100 ;\nG02 I-10 ;\nG03 X10 Y0 I-10 J0 ;\n");
    assert_eq!(ms.len(), 3);
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(10.0, 0.0, 0.0),
        o(),
        axis_g17(),
        -TAU,
    );
    assert_arc(
        &ms[2],
        v(10.0, 0.0, 0.0),
        v(10.0, 0.0, 0.0),
        o(),
        axis_g17(),
        TAU,
    );
}

#[test]
fn radius_arc_to_the_start_point_is_a_zero_arc_without_motion() {
    // [M] R with the end equal to the start is a 0° arc: no motion and no error.
    let ms = moves(D, "G01 X10 F100 ;\nG02 X10 Y0 R5 ;\nG01 X20 ;\n");
    for m in &ms {
        if m.line == 2 {
            let len = path_length(&m.path);
            assert!(
                len < 1e-12,
                "the R block must not move: {}",
                describe_move(m)
            );
        }
    }
    let last = ms.last().expect("moves");
    assert_feed_line(last, v(10.0, 0.0, 0.0), v(20.0, 0.0, 0.0), 100.0);
}

#[test]
fn helix_with_centre_or_radius() {
    // [M] G17 G02 X Y Z {I J | R} F.
    let ms = moves(D, "G01 X10 F100 ;\nG17 G02 X-10 Y0 Z-5 I-10 J0 F80 ;\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(-10.0, 0.0, -5.0),
        o(),
        axis_g17(),
        -PI,
    );
    assert_eq!(ms[1].feed_mm_min, Some(80.0));
    let ms = moves(D, "F100 ;\nG17 G03 X10 Y10 Z3 R10 ;\n");
    assert_arc(
        &ms[0],
        o(),
        v(10.0, 10.0, 3.0),
        v(0.0, 10.0, 0.0),
        axis_g17(),
        FRAC_PI_2,
    );
}

#[test]
fn feed_is_modal_across_arcs() {
    // Seed 002: "If omitted, the control will use the feedrate active prior to this block."
    let ms = moves(D, "G01 X10 F250 ;\nG03 X0 Y10 I-10 J0 ;\n");
    assert_eq!(ms[1].feed_mm_min, Some(250.0));
}

#[test]
fn inch_mode_g20() {
    // [?] Fanuc-style G20/G21 (not confirmed by the seed): positions and feed in inches.
    let ms = moves(D, "G20 ;\nG01 X1 Y1 F10 ;\nG21 ;\nG01 X0 F100 ;\n");
    assert_feed_line(&ms[0], o(), v(25.4, 25.4, 0.0), 254.0);
    assert_feed_line(&ms[1], v(25.4, 25.4, 0.0), v(0.0, 25.4, 0.0), 100.0);
}

#[test]
fn rotary_axes_are_carried() {
    let ms = moves(D, "G01 X10 B30 F100 ;\n");
    assert_eq!(ms[0].abc_deg, Some(([0.0; 3], [0.0, 30.0, 0.0])));
}

#[test]
fn events_in_program_order() {
    let its = items(
        D,
        "S800 M03 ;\nT5 M06 ;\nM08 ;\nG01 X1 F100 ;\nM09 ;\nM05 ;\nM30 ;\n",
    );
    let ev = only_events(&its);
    let codes: Vec<(&str, Option<f64>)> = ev.iter().map(|e| (e.code.as_str(), e.value)).collect();
    assert_eq!(
        codes,
        vec![
            ("S", Some(800.0)),
            ("M3", None),
            ("T", Some(5.0)),
            ("M6", None),
            ("M8", None),
            ("M9", None),
            ("M5", None),
            ("M30", None),
        ]
    );
    // The move sits between M08 and M09.
    let pos = its
        .iter()
        .position(|i| matches!(i, Item::Move(_)))
        .expect("a move");
    assert!(matches!(&its[pos - 1], Item::Event(e) if e.code == EventCode::M8));
    assert!(matches!(&its[pos + 1], Item::Event(e) if e.code == EventCode::M9));
}

#[test]
fn radius_too_small_is_an_error() {
    let d = error(D, "F100 ;\nG02 X20 Y0 R5 ;\n");
    assert_diag_line(&d, 2, &["radius too small to reach end point"]);
}

#[test]
fn end_point_far_off_the_circle_is_an_error() {
    let d = error(D, "G01 X10 F100 ;\nG03 X0 Y15 I-10 J0 ;\n");
    assert_eq!(d.line, 2, "{d}");
}

#[test]
fn cutter_compensation() {
    let zero = settings_with_tool(1, 0.0, 0.0);
    let with = moves_with(
        D,
        zero.clone(),
        "T1 M06 ;\nG41 D1 G01 X10 F100 ;\nG40 X0 ;\n",
    );
    let without = moves_with(D, zero, "T1 M06 ;\nG01 X10 F100 ;\nX0 ;\n");
    assert_same_moves("G41 with radius 0", &with, &without, TOL);
    let d = error_with(
        D,
        settings_with_tool(1, 0.0, 2.0),
        "T1 M06 ;\nG42 D1 G01 X10 F100 ;\n",
    );
    assert_diag(&d, 2, 1, &["cutter compensation"]);
}

#[test]
fn corner_modes_g61_g64_and_one_block_g09() {
    // Fanuc style: G61 exact stop mode, G64 cutting mode, G09 exact stop for one block.
    let ms = moves(
        D,
        "G01 X1 F100 ;\nG09 X2 ;\nX3 ;\nG61 X4 ;\nX5 ;\nG64 X6 ;\n",
    );
    assert_eq!(
        ms[0].corner,
        CornerMode::Blend {
            tolerance_mm: None,
            naive_cam_mm: None
        }
    );
    assert_eq!(ms[1].corner, CornerMode::ExactStop);
    assert_eq!(
        ms[2].corner,
        CornerMode::Blend {
            tolerance_mm: None,
            naive_cam_mm: None
        },
        "G09 is one block"
    );
    assert_eq!(ms[3].corner, CornerMode::ExactStop);
    assert_eq!(ms[4].corner, CornerMode::ExactStop, "G61 is modal");
    assert_eq!(
        ms[5].corner,
        CornerMode::Blend {
            tolerance_mm: None,
            naive_cam_mm: None
        }
    );
}

#[test]
fn dwell_x_is_the_time_not_a_move() {
    // G04 X1.5 dwells; the X there is the time, not the axis.
    for dwell in ["G04 X1.5 ;", "G04 P2 ;", "G04 ;"] {
        let ms = moves(D, &format!("G01 X1 F100 ;\n{dwell}\nG01 X2 ;\n"));
        assert_eq!(ms.len(), 2, "{dwell}: {ms:#?}");
        assert_feed_line(&ms[1], v(1.0, 0.0, 0.0), v(2.0, 0.0, 0.0), 100.0);
    }
}
