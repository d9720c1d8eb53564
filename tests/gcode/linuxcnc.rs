//! LinuxCNC / Tormach dialect, from the LinuxCNC G-code reference, the Tormach PCNC 770
//! manual (seed 001) and the rules in issue 2.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use kerf_tests::*;

const D: Dialect = Dialect::LinuxCnc;

fn o() -> Vec3 {
    v(0.0, 0.0, 0.0)
}

#[test]
fn rapids_and_feed_lines_with_modal_motion_and_feed() {
    let ms = moves(
        D,
        "G21 G90 G17\n\
         G0 X10 Y5 Z2\n\
         G1 Z-1 F100\n\
         G1 X20\n\
         Y15 F200\n\
         G0 Z5\n",
    );
    assert_eq!(ms.len(), 5, "{ms:#?}");
    assert_rapid(&ms[0], o(), v(10.0, 5.0, 2.0));
    assert_feed_line(&ms[1], v(10.0, 5.0, 2.0), v(10.0, 5.0, -1.0), 100.0);
    assert_feed_line(&ms[2], v(10.0, 5.0, -1.0), v(20.0, 5.0, -1.0), 100.0);
    // Motion mode and feed are modal: a bare `Y15` is a G1 move, F200 applies from its block.
    assert_feed_line(&ms[3], v(20.0, 5.0, -1.0), v(20.0, 15.0, -1.0), 200.0);
    assert_rapid(&ms[4], v(20.0, 15.0, -1.0), v(20.0, 15.0, 5.0));
    let lines: Vec<u32> = ms.iter().map(|m| m.line).collect();
    assert_eq!(lines, vec![2, 3, 4, 5, 6], "1-based source lines");
}

#[test]
fn incremental_g91_and_back_to_absolute() {
    let ms = moves(D, "G1 X10 Y10 F100\nG91 X5 Y-2\nZ-3\nG90 X0\n");
    assert_eq!(ms.len(), 4);
    assert_feed_line(&ms[0], o(), v(10.0, 10.0, 0.0), 100.0);
    assert_feed_line(&ms[1], v(10.0, 10.0, 0.0), v(15.0, 8.0, 0.0), 100.0);
    assert_feed_line(&ms[2], v(15.0, 8.0, 0.0), v(15.0, 8.0, -3.0), 100.0);
    assert_feed_line(&ms[3], v(15.0, 8.0, -3.0), v(0.0, 8.0, -3.0), 100.0);
}

#[test]
fn g17_centre_format_arcs_are_incremental_by_default() {
    let ms = moves(D, "G1 X10 F100\nG3 X0 Y10 I-10 J0\nG2 X10 Y0 I0 J-10\n");
    assert_eq!(ms.len(), 3);
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(0.0, 10.0, 0.0),
        o(),
        axis_g17(),
        FRAC_PI_2,
    );
    assert_arc(
        &ms[2],
        v(0.0, 10.0, 0.0),
        v(10.0, 0.0, 0.0),
        o(),
        axis_g17(),
        -FRAC_PI_2,
    );
    assert_eq!(ms[1].feed_mm_min, Some(100.0));
}

#[test]
fn g91_1_is_the_default_and_g90_1_makes_centres_absolute() {
    // With G90.1 the I J numbers are the centre itself; with G91.1 (the default) they are
    // offsets from the start point.
    let ms = moves(
        D,
        "G1 X10 Y5 F100\n\
         G90.1 G3 X0 Y15 I0 J5\n\
         G91.1 G2 X10 Y5 I0 J-10\n",
    );
    assert_arc(
        &ms[1],
        v(10.0, 5.0, 0.0),
        v(0.0, 15.0, 0.0),
        v(0.0, 5.0, 0.0),
        axis_g17(),
        FRAC_PI_2,
    );
    assert_arc(
        &ms[2],
        v(0.0, 15.0, 0.0),
        v(10.0, 5.0, 0.0),
        v(0.0, 5.0, 0.0),
        axis_g17(),
        -FRAC_PI_2,
    );
}

#[test]
fn centre_words_are_incremental_even_in_g91() {
    // G91 affects the end point; I J stay offsets from the start (G91.1).
    let ms = moves(D, "G1 X10 F100\nG91 G3 X-10 Y10 I-10 J0\n");
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
fn g18_arcs_turn_about_plus_y() {
    // G18 is the ZX plane, seen from +Y: Z to the right, X up. A positive rotation about +Y
    // takes +Z towards +X, so the short way from +X to +Z is clockwise (G2, sweep -90°)
    // and G3 between the same points goes the long way (+270°).
    let cw = moves(D, "G1 X10 F100\nG18 G2 X0 Z10 I-10 K0\n");
    assert_arc(
        &cw[1],
        v(10.0, 0.0, 0.0),
        v(0.0, 0.0, 10.0),
        o(),
        axis_g18(),
        -FRAC_PI_2,
    );
    let ccw = moves(D, "G1 X10 F100\nG18 G3 X0 Z10 I-10 K0\n");
    assert_arc(
        &ccw[1],
        v(10.0, 0.0, 0.0),
        v(0.0, 0.0, 10.0),
        o(),
        axis_g18(),
        1.5 * PI,
    );
}

#[test]
fn g19_arcs_turn_about_plus_x() {
    // G19 is the YZ plane seen from +X: a positive rotation about +X takes +Y towards +Z.
    let ccw = moves(D, "G1 Y10 F100\nG19 G3 Y0 Z10 J-10 K0\n");
    assert_arc(
        &ccw[1],
        v(0.0, 10.0, 0.0),
        v(0.0, 0.0, 10.0),
        o(),
        axis_g19(),
        FRAC_PI_2,
    );
    let cw = moves(D, "G1 Y10 F100\nG19 G2 Y0 Z10 J-10 K0\n");
    assert_arc(
        &cw[1],
        v(0.0, 10.0, 0.0),
        v(0.0, 0.0, 10.0),
        o(),
        axis_g19(),
        -1.5 * PI,
    );
}

#[test]
fn radius_format_sign_chooses_the_short_or_long_arc() {
    // From (0,0) to (10,10) with |R| = 10 the centre is (10,0) or (0,10). Tormach manual
    // (seed 001): positive R turns 180° or less, negative R 180° to 359.999°.
    let cases = [
        ("G2 X10 Y10 R10", v(10.0, 0.0, 0.0), -FRAC_PI_2),
        ("G2 X10 Y10 R-10", v(0.0, 10.0, 0.0), -1.5 * PI),
        ("G3 X10 Y10 R10", v(0.0, 10.0, 0.0), FRAC_PI_2),
        ("G3 X10 Y10 R-10", v(10.0, 0.0, 0.0), 1.5 * PI),
    ];
    for (block, center, sweep) in cases {
        let ms = moves(D, &format!("F100\n{block}\n"));
        assert_eq!(ms.len(), 1, "{block}");
        assert_arc(&ms[0], o(), v(10.0, 10.0, 0.0), center, axis_g17(), sweep);
    }
}

#[test]
fn radius_format_semicircle() {
    // A half-chord equal to the radius is exactly a semicircle, centred on the chord.
    let ms = moves(D, "F100\nG2 X20 R10\n");
    assert_arc(
        &ms[0],
        o(),
        v(20.0, 0.0, 0.0),
        v(10.0, 0.0, 0.0),
        axis_g17(),
        -PI,
    );
}

#[test]
fn radius_format_in_g18_and_g19() {
    // G18: from the origin to X10 Z10 with R10 the centre is (10,0,0) or (0,0,10). About
    // (10,0,0) the start vector is (-10,0,0) and the end (0,0,10): their cross product is
    // (0,100,0), +90° about +Y (counter-clockwise). The short clockwise arc therefore uses
    // the centre (0,0,10).
    let ms = moves(D, "F100\nG18 G2 X10 Z10 R10\n");
    assert_arc(
        &ms[0],
        o(),
        v(10.0, 0.0, 10.0),
        v(0.0, 0.0, 10.0),
        axis_g18(),
        -FRAC_PI_2,
    );
    // G19: from the origin to Y10 Z10, G3 R10: about centre (0,10,0) the start vector is
    // (0,-10,0) and the end (0,0,10): cross = (-10*10 - 0, 0, 0) = (-100,0,0), clockwise.
    // About (0,0,10): start (0,0,-10), end (0,10,0): cross = (0*0 - (-10)*10,0,0) = (+100,..).
    let ms = moves(D, "F100\nG19 G3 Y10 Z10 R10\n");
    assert_arc(
        &ms[0],
        o(),
        v(0.0, 10.0, 10.0),
        v(0.0, 0.0, 10.0),
        axis_g19(),
        FRAC_PI_2,
    );
}

#[test]
fn full_circles_in_centre_format() {
    // End point equal to the start, or all plane axis words omitted: a whole circle.
    let ms = moves(D, "G1 X10 F100\nG2 X10 Y0 I-10 J0\nG3 I-10\n");
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
fn p_word_adds_turns() {
    // P is the number of turns: P1 is the plain arc, each further turn adds a full circle.
    let ms = moves(
        D,
        "G1 X10 F100\n\
         G3 X0 Y10 I-10 P1\n\
         G2 X10 Y0 I0 J-10 P3\n\
         G3 I-10 P2\n",
    );
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(0.0, 10.0, 0.0),
        o(),
        axis_g17(),
        FRAC_PI_2,
    );
    assert_arc(
        &ms[2],
        v(0.0, 10.0, 0.0),
        v(10.0, 0.0, 0.0),
        o(),
        axis_g17(),
        -FRAC_PI_2 - 2.0 * TAU,
    );
    assert_arc(
        &ms[3],
        v(10.0, 0.0, 0.0),
        v(10.0, 0.0, 0.0),
        o(),
        axis_g17(),
        2.0 * TAU,
    );
}

#[test]
fn helices_in_all_three_planes() {
    // The axis word normal to the plane makes a helix: the centre stays in the plane of the
    // start, the end rises along the axis.
    let ms = moves(D, "G1 X10 F100\nG17 G3 X-10 Y0 Z5 I-10 J0\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(-10.0, 0.0, 5.0),
        o(),
        axis_g17(),
        PI,
    );

    let ms = moves(D, "G1 X10 F100\nG17 G3 X10 Y0 Z6 I-10 P3\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(10.0, 0.0, 6.0),
        o(),
        axis_g17(),
        3.0 * TAU,
    );

    let ms = moves(D, "G1 X10 F100\nG18 G2 X0 Z10 Y-4 I-10\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(0.0, -4.0, 10.0),
        o(),
        axis_g18(),
        -FRAC_PI_2,
    );

    let ms = moves(D, "G1 Y10 F100\nG19 G3 Y0 Z10 X7 J-10\n");
    assert_arc(
        &ms[1],
        v(0.0, 10.0, 0.0),
        v(7.0, 0.0, 10.0),
        o(),
        axis_g19(),
        FRAC_PI_2,
    );
}

#[test]
fn helix_points_rise_linearly_with_angle() {
    let ms = moves(D, "G1 X10 F100\nG3 X10 Y0 Z8 I-10 P2\n");
    let a = as_arc(&ms[1]);
    // Half-way through two turns the tool is back at +X, half-way up.
    assert_point("mid-point", arc_point(&a, 0.5), v(10.0, 0.0, 4.0), 1e-9);
    assert_point("quarter", arc_point(&a, 0.125), v(0.0, 10.0, 1.0), 1e-9);
    assert_close(
        "helix length",
        path_length(&ms[1].path),
        (8.0f64.powi(2) + (40.0 * PI).powi(2)).sqrt(),
        1e-9,
    );
}

#[test]
fn polar_lines_about_xy_zero() {
    // LinuxCNC: `@` distance and `^` angle (degrees, CCW from +X) about the XY zero of the
    // current coordinate system; Z still comes from the Z word.
    let ms = moves(D, "G1 @10 ^30 F100\n@10 ^90 Z-2\nG0 @5 ^180\n");
    assert_feed_line(&ms[0], o(), v(10.0 * deg(30.0).cos(), 5.0, 0.0), 100.0);
    assert_feed_line(&ms[1], ms[0].path.end(), v(0.0, 10.0, -2.0), 100.0);
    assert_rapid(&ms[2], v(0.0, 10.0, -2.0), v(-5.0, 0.0, -2.0));
}

#[test]
fn polar_incremental_adds_to_the_current_polar_position() {
    // LinuxCNC G-code reference, "Polar Coordinates": in G91 the distance and the angle are
    // added to the current position's distance and angle about XY zero, so repeating `^90`
    // walks round a square's corners while `@.5 ^90` spirals outwards.
    let ms = moves(D, "F100 G1 @10 ^90\nG91 ^90\n^90\n@5\n");
    assert_feed_line(&ms[0], o(), v(0.0, 10.0, 0.0), 100.0);
    assert_feed_line(&ms[1], v(0.0, 10.0, 0.0), v(-10.0, 0.0, 0.0), 100.0);
    assert_feed_line(&ms[2], v(-10.0, 0.0, 0.0), v(0.0, -10.0, 0.0), 100.0);
    assert_feed_line(&ms[3], v(0.0, -10.0, 0.0), v(0.0, -15.0, 0.0), 100.0);
}

#[test]
fn polar_is_relative_to_the_work_offset() {
    let mut s = Settings::default();
    s.work_offsets_mm[0] = [100.0, 50.0, 0.0];
    let ms = moves_with(D, s, "G1 @10 ^90 F100\n");
    assert_feed_line(&ms[0], o(), v(100.0, 60.0, 0.0), 100.0);
}

#[test]
fn inch_mode_converts_positions_centres_radii_and_feed() {
    let ms = moves(
        D,
        // G20 and G21 on lines of their own: in a block with them F is read in the unit
        // in force before the block (LinuxCNC's order of execution, see modal.rs).
        "G20\nG1 X1 Y2 F10\n\
         G3 X0 Y3 I-1 J0\n\
         G2 X1 Y4 R1\n\
         G21\nG1 X10 F100\n",
    );
    assert_feed_line(&ms[0], o(), v(25.4, 50.8, 0.0), 254.0);
    assert_arc(
        &ms[1],
        v(25.4, 50.8, 0.0),
        v(0.0, 76.2, 0.0),
        v(0.0, 50.8, 0.0),
        axis_g17(),
        FRAC_PI_2,
    );
    // From (0,3) to (1,4) in, R1, clockwise short: centre (0,4) in gives start vector (0,-1)
    // and end (1,0): cross = 0*0 - (-1)(1) = +1, counter-clockwise; so the centre is (1,3).
    assert_arc(
        &ms[2],
        v(0.0, 76.2, 0.0),
        v(25.4, 101.6, 0.0),
        v(25.4, 76.2, 0.0),
        axis_g17(),
        -FRAC_PI_2,
    );
    assert_feed_line(&ms[3], v(25.4, 101.6, 0.0), v(10.0, 101.6, 0.0), 100.0);
}

#[test]
fn work_offsets_g54_to_g59_3_come_from_settings() {
    let codes = [
        "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3",
    ];
    let mut s = Settings::default();
    for (i, off) in s.work_offsets_mm.iter_mut().enumerate() {
        let k = (i + 1) as f64;
        *off = [10.0 * k, -3.0 * k, 0.5 * k];
    }
    for (i, code) in codes.iter().enumerate() {
        let ms = moves_with(D, s.clone(), &format!("{code} G1 X1 Y2 Z3 F100\n"));
        let k = (i + 1) as f64;
        assert_feed_line(
            &ms[0],
            o(),
            v(1.0 + 10.0 * k, 2.0 - 3.0 * k, 3.0 + 0.5 * k),
            100.0,
        );
    }
}

#[test]
fn g54_is_active_at_start_and_offsets_switch_per_block() {
    let mut s = Settings::default();
    s.work_offsets_mm[0] = [100.0, 50.0, -10.0];
    s.work_offsets_mm[1] = [200.0, 0.0, 0.0];
    let ms = moves_with(
        D,
        s,
        "G1 X1 Y2 Z3 F100\n\
         G55 X1 Y2 Z3\n\
         G54 X0 Y0 Z0\n",
    );
    assert_feed_line(&ms[0], o(), v(101.0, 52.0, -7.0), 100.0);
    assert_feed_line(&ms[1], v(101.0, 52.0, -7.0), v(201.0, 2.0, 3.0), 100.0);
    assert_feed_line(&ms[2], v(201.0, 2.0, 3.0), v(100.0, 50.0, -10.0), 100.0);
}

#[test]
fn g90_1_centres_are_in_the_work_coordinate_system() {
    let mut s = Settings::default();
    s.work_offsets_mm[0] = [100.0, 0.0, 0.0];
    let ms = moves_with(D, s, "G1 X10 Y0 F100\nG90.1 G3 X0 Y10 I0 J0\n");
    assert_arc(
        &ms[1],
        v(110.0, 0.0, 0.0),
        v(100.0, 10.0, 0.0),
        v(100.0, 0.0, 0.0),
        axis_g17(),
        FRAC_PI_2,
    );
}

#[test]
fn g92_shifts_the_current_point_and_g92_1_clears_it() {
    // G92 X0 Y0 at (10,10) makes that point (0,0) of the program; the shift adds to the
    // active work offset (G54 here = (100,0,0)).
    let mut s = Settings::default();
    s.work_offsets_mm[0] = [100.0, 0.0, 0.0];
    let ms = moves_with(
        D,
        s,
        "G1 X10 Y10 F100\n\
         G92 X0 Y0\n\
         G1 X5 Y0\n\
         G92.1\n\
         G1 X5 Y0\n",
    );
    assert_eq!(ms.len(), 3, "G92 and G92.1 do not move: {ms:#?}");
    assert_feed_line(&ms[0], o(), v(110.0, 10.0, 0.0), 100.0);
    assert_feed_line(&ms[1], v(110.0, 10.0, 0.0), v(115.0, 10.0, 0.0), 100.0);
    assert_feed_line(&ms[2], v(115.0, 10.0, 0.0), v(105.0, 0.0, 0.0), 100.0);
}

#[test]
fn tool_length_offset_g43_h_and_g49() {
    let s = settings_with_tool(1, 25.0, 0.0);
    let ms = moves_with(
        D,
        s,
        "G43 H1\n\
         G0 Z10\n\
         G49\n\
         G0 Z10\n",
    );
    assert_eq!(ms.len(), 2);
    assert_rapid(&ms[0], o(), v(0.0, 0.0, 35.0));
    assert_rapid(&ms[1], v(0.0, 0.0, 35.0), v(0.0, 0.0, 10.0));
}

#[test]
fn g43_without_h_uses_the_loaded_tool() {
    let s = settings_with_tool(3, 12.5, 0.0);
    let ms = moves_with(D, s, "T3 M6\nG43\nG0 Z0\n");
    assert_rapid(&ms[0], o(), v(0.0, 0.0, 12.5));
}

#[test]
fn tool_missing_from_the_table_is_an_error() {
    // rs274: "Requested tool 7 not found in the tool table", for G43 H, T and M61 Q alike.
    for (src, col) in [("G43 H7\nG0 Z10\n", 5), ("T7 M6\n", 1), ("M61 Q7\n", 5)] {
        let s = settings_with_tool(1, 25.0, 0.0);
        assert_diag(
            &error_with(D, s, src),
            1,
            col,
            &["requested tool 7 not found in the tool table"],
        );
    }
}

#[test]
fn rotary_axes_are_carried_on_lines_and_arcs() {
    let ms = moves(
        D,
        "G1 X10 A90 F100\n\
         G3 X0 Y10 I-10 B45 C-30\n\
         G91 G1 A10\n\
         G20 G90 G1 X1 A0\n",
    );
    assert_eq!(ms[0].abc_deg, Some(([0.0, 0.0, 0.0], [90.0, 0.0, 0.0])));
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(0.0, 10.0, 0.0),
        o(),
        axis_g17(),
        FRAC_PI_2,
    );
    assert_eq!(ms[1].abc_deg, Some(([90.0, 0.0, 0.0], [90.0, 45.0, -30.0])));
    // A pure rotary move: no linear motion, A advances incrementally.
    assert_eq!(
        ms[2].abc_deg,
        Some(([90.0, 45.0, -30.0], [100.0, 45.0, -30.0]))
    );
    assert_point(
        "pure rotary move stays put",
        ms[2].path.end(),
        ms[2].path.start(),
        TOL,
    );
    // Rotary axes are degrees: G20 does not scale them.
    assert_eq!(
        ms[3].abc_deg,
        Some(([100.0, 45.0, -30.0], [0.0, 45.0, -30.0]))
    );
    assert_point("inch X", ms[3].path.end(), v(25.4, 10.0, 0.0), TOL);
}

#[test]
fn moves_without_rotary_words_keep_the_rotary_position() {
    let ms = moves(D, "G1 X10 A90 F100\nG1 X20\n");
    // Once the program uses a rotary axis, later moves either carry it unchanged or omit
    // it; they never move it back.
    if let Some((s, e)) = ms[1].abc_deg {
        assert_eq!(s, [90.0, 0.0, 0.0]);
        assert_eq!(e, [90.0, 0.0, 0.0]);
    }
}

#[test]
fn events_in_linuxcnc_order_of_execution() {
    // LinuxCNC "Order of Execution": S, T, M6, M3/M4/M5, M7/M8/M9 come before the motion of
    // their block; M0/M1/M2/M30 after it.
    let its = run_with(
        D,
        settings_with_tool(2, 0.0, 0.0),
        "M3 S1000\n\
         T2 M6\n\
         M8\n\
         G1 X1 F100 M0\n\
         M9\n\
         M4 S200\n\
         M5\n\
         M1\n\
         M30\n",
    )
    .expect("a valid program");
    let got: Vec<(u32, String, Option<f64>)> = its
        .iter()
        .map(|i| match i {
            Item::Event(e) => (e.line, e.code.as_str().to_string(), e.value),
            Item::Move(m) => (m.line, "move".to_string(), None),
        })
        .collect();
    let want: Vec<(u32, String, Option<f64>)> = [
        (1, "S", Some(1000.0)),
        (1, "M3", None),
        (2, "T", Some(2.0)),
        (2, "M6", None),
        (3, "M8", None),
        (4, "move", None),
        (4, "M0", None),
        (5, "M9", None),
        (6, "S", Some(200.0)),
        (6, "M4", None),
        (7, "M5", None),
        (8, "M1", None),
        (9, "M30", None),
    ]
    .iter()
    .map(|(l, c, v)| (*l, c.to_string(), *v))
    .collect();
    assert_eq!(got, want);
}

#[test]
fn m2_ends_the_program_after_its_block() {
    let its = items(D, "G1 X1 F100\nM2\n");
    let last = its.last().expect("items");
    match last {
        Item::Event(e) => assert_eq!(e.code, EventCode::M2),
        Item::Move(_) => panic!("M2 must be the last item"),
    }
}

#[test]
fn cutter_compensation_with_zero_radius_leaves_the_path_unchanged() {
    let s = settings_with_tool(1, 0.0, 0.0);
    let with = moves_with(
        D,
        s.clone(),
        "T1 M6\nG41 D1\nG1 X10 Y5 F100\nG40\nG42\nG1 X0\nG40\nG1 Y0\n",
    );
    let without = moves_with(D, s, "T1 M6\nG1 X10 Y5 F100\nG1 X0\nG1 Y0\n");
    assert_same_moves("G41/G42 with radius 0", &with, &without, TOL);
}

/// Runs a centre-format arc from (0,0) about `center` to `end` (all in the XY plane).
fn centre_arc(center: (f64, f64), end: (f64, f64), inch: bool) -> Result<Vec<Item>, Diagnostic> {
    let units = if inch { "G20" } else { "G21" };
    run(
        D,
        &format!(
            "{units} F100\nG3 X{} Y{} I{} J{}\n",
            end.0, end.1, center.0, center.1
        ),
    )
}

#[test]
fn centre_arc_radius_mismatch_rule_absolute_limit_100_t() {
    // |r1 - r2| > 100 t (2.828 mm) is rejected even when the relative error is tiny.
    // r1 = 10000, r2 = 10002.9: error 2.9 mm, 0.029 % -> rejected by the 100 t rule alone.
    let err = centre_arc((10000.0, 0.0), (20002.9, 0.0), false);
    assert!(
        err.is_err(),
        "2.9 mm radius difference must be rejected: {err:?}"
    );
    // r2 = 10002.8: error 2.8 mm < 2.828, 0.028 % < 0.1 % -> accepted.
    let ok = centre_arc((10000.0, 0.0), (20002.8, 0.0), false);
    let items = ok.unwrap_or_else(|e| panic!("2.8 mm on r = 10000 must be accepted: {e}"));
    let m = only_moves(&items);
    assert_point(
        "end point exact",
        m[0].path.end(),
        v(20002.8, 0.0, 0.0),
        1e-9,
    );
    assert_close("sweep", as_arc(&m[0]).sweep_rad, PI, 1e-3);
}

#[test]
fn centre_arc_radius_mismatch_rule_t_with_relative_error() {
    // r1 = 10: 0.03 mm (> t = 0.02828, 0.3 %) is rejected; 0.028 mm (< t) is accepted
    // although its relative error (0.28 %) is large.
    assert!(centre_arc((10.0, 0.0), (20.03, 0.0), false).is_err());
    let items = centre_arc((10.0, 0.0), (20.028, 0.0), false)
        .unwrap_or_else(|e| panic!("0.028 mm must be accepted: {e}"));
    let m = only_moves(&items);
    assert_point(
        "end point exact",
        m[0].path.end(),
        v(20.028, 0.0, 0.0),
        1e-9,
    );
}

#[test]
fn centre_arc_radius_mismatch_rule_relative_limit() {
    // r1 = 100: 0.09 mm is above t but only 0.09 % -> accepted; 0.11 mm is 0.11 % -> rejected.
    let items = centre_arc((100.0, 0.0), (200.09, 0.0), false)
        .unwrap_or_else(|e| panic!("0.09 mm on r = 100 must be accepted: {e}"));
    let m = only_moves(&items);
    assert_point(
        "end point exact",
        m[0].path.end(),
        v(200.09, 0.0, 0.0),
        1e-9,
    );
    assert!(centre_arc((100.0, 0.0), (200.11, 0.0), false).is_err());
}

#[test]
fn centre_arc_radius_mismatch_rule_in_inches_uses_0_002828_in() {
    // r1 = 1 in: 0.003 in (> 0.002828 in, 0.3 %) rejected; 0.0027 in accepted. 0.0027 in is
    // 0.06858 mm, which the millimetre tolerance would reject: the inch rule applies in G20.
    assert!(centre_arc((1.0, 0.0), (2.003, 0.0), true).is_err());
    let items = centre_arc((1.0, 0.0), (2.0027, 0.0), true)
        .unwrap_or_else(|e| panic!("0.0027 in on r = 1 in must be accepted: {e}"));
    let m = only_moves(&items);
    assert_point(
        "end point exact",
        m[0].path.end(),
        v(2.0027 * 25.4, 0.0, 0.0),
        1e-9,
    );
}

#[test]
fn centre_arc_rejection_message() {
    let d = centre_arc((10.0, 0.0), (20.5, 0.0), false).expect_err("0.5 mm on r = 10");
    assert_diag_line(&d, 2, &["radius", "differs"]);
}

#[test]
fn radius_format_short_of_half_chord_rule() {
    // Chord 20 mm: half chord 10. R 9.999 is short by 0.001 mm (<= 0.00127): accepted as a
    // semicircle centred on the chord; R 9.9985 is short by 0.0015 mm: rejected.
    let items = run(D, "F100\nG2 X20 R9.999\n").unwrap_or_else(|e| panic!("R9.999: {e}"));
    let m = only_moves(&items);
    let a = as_arc(&m[0]);
    assert_point("end point exact", a.end, v(20.0, 0.0, 0.0), 1e-12);
    assert_point("centre on the chord", a.center, v(10.0, 0.0, 0.0), 1e-3);
    assert_close("semicircle", a.sweep_rad, -PI, 1e-3);
    check_arc_geometry(&a, 1e-9);

    let d = error(D, "F100\nG2 X20 R9.9985\n");
    assert_diag_line(&d, 2, &["radius too small to reach end point"]);
}

#[test]
fn radius_format_cannot_make_a_full_circle() {
    // The start equals the end: there is no way to place the centre.
    let d = error(D, "F100\nG1 X5\nG2 X5 Y0 R5\n");
    assert_eq!(d.line, 3, "{d}");
}

#[test]
fn feed_move_without_feed_is_an_error() {
    // LinuxCNC: "Cannot do G1 with zero feed rate".
    let d = error(D, "G0 X1\nG1 X2\n");
    assert_diag_line(&d, 2, &["feed"]);
}

#[test]
fn parameters_expressions_and_o_words_are_read() {
    // The language itself is tested in `language.rs`; here only that each construct that
    // used to be refused now runs: #1 = 5, X[#1+2] = 7, the sub moves to Y#1 = 3.
    let ms = moves(
        D,
        "#1 = 5\nG1 X#1 F100\n#<depth> = 2\nG1 X[#1+#<depth>]\no100 sub\nG1 Y#1\no100 endsub\nO100 call [3]\n",
    );
    let ends: Vec<Vec3> = ms.iter().map(|m| as_line(m).end).collect();
    assert_eq!(
        ends,
        vec![v(5.0, 0.0, 0.0), v(7.0, 0.0, 0.0), v(7.0, 3.0, 0.0)]
    );
}

#[test]
fn sign_conventions_hold_for_every_plane_and_direction() {
    // A quarter arc from the first plane axis to the second one about the origin is +90°
    // about the plane normal for G3 (counter-clockwise) and -270° for G2.
    let cases = [
        (
            "G17",
            "X",
            "Y",
            "I",
            "J",
            v(10.0, 0.0, 0.0),
            v(0.0, 10.0, 0.0),
            axis_g17(),
        ),
        (
            "G18",
            "Z",
            "X",
            "K",
            "I",
            v(0.0, 0.0, 10.0),
            v(10.0, 0.0, 0.0),
            axis_g18(),
        ),
        (
            "G19",
            "Y",
            "Z",
            "J",
            "K",
            v(0.0, 10.0, 0.0),
            v(0.0, 0.0, 10.0),
            axis_g19(),
        ),
    ];
    for (plane, a1, a2, c1, c2, start, end, axis) in cases {
        for (g, sweep) in [("G3", FRAC_PI_2), ("G2", -1.5 * PI)] {
            let src = format!("G1 {a1}10 F100\n{plane} {g} {a1}0 {a2}10 {c1}-10 {c2}0\n");
            let ms = moves(D, &src);
            assert_arc(&ms[1], start, end, o(), axis, sweep);
        }
    }
}

#[test]
fn offsets_and_tool_lengths_are_millimetres_in_inch_mode() {
    // The work offsets and the tool table are configured in mm; G20 only changes how the
    // program's words are read.
    let mut s = settings_with_tool(1, 25.0, 0.0);
    s.work_offsets_mm[0] = [100.0, 0.0, 0.0];
    let ms = moves_with(D, s, "G20\nG43 H1\nG1 X1 Z1 F10\nG92 X0\nG1 X1\n");
    assert_feed_line(&ms[0], o(), v(125.4, 0.0, 50.4), 254.0);
    // G92 X0 at program X1 in: the shift is 1 in, so X1 is now 2 in from the G54 zero.
    assert_feed_line(&ms[1], v(125.4, 0.0, 50.4), v(150.8, 0.0, 50.4), 254.0);
}

#[test]
fn incremental_moves_ignore_offsets() {
    let mut s = Settings::default();
    s.work_offsets_mm[0] = [100.0, 0.0, 0.0];
    let ms = moves_with(D, s, "G1 X0 F100\nG91 X5\n");
    assert_feed_line(&ms[1], v(100.0, 0.0, 0.0), v(105.0, 0.0, 0.0), 100.0);
}

#[test]
fn feed_survives_rapids_and_arcs() {
    let ms = moves(D, "G1 X1 F100\nG0 X5\nG1 X6\nG2 X8 R1\n");
    assert_eq!(ms[2].feed_mm_min, Some(100.0));
    assert_eq!(ms[3].feed_mm_min, Some(100.0));
}

#[test]
fn corner_modes_g61_and_g64_p() {
    // LinuxCNC "G61, G61.1, G64": G61 exact stop; G64 blending, with P the path tolerance
    // in program units. Nothing programmed: blending within the configured default
    // (issue 3). Without Q the naive-CAM tolerance is P (rs274: SET_NAIVECAM_TOLERANCE
    // after G64 P0.02 is 0.02).
    let ms = moves(
        D,
        "G1 X1 F100\nG61 X2\nX3\nG64 P0.02 X4\nG64 X5\nG20 G64 P0.01 X6\n",
    );
    assert_eq!(
        ms[0].corner,
        CornerMode::Blend {
            tolerance_mm: None,
            naive_cam_mm: None
        }
    );
    assert_eq!(ms[1].corner, CornerMode::ExactStop);
    assert_eq!(ms[2].corner, CornerMode::ExactStop, "G61 is modal");
    match ms[3].corner {
        CornerMode::Blend {
            tolerance_mm: Some(t),
            naive_cam_mm: Some(q),
        } => {
            assert_close("G64 P0.02", t, 0.02, 1e-12);
            assert_close("G64 P0.02 naive CAM", q, 0.02, 1e-12);
        }
        c => panic!("G64 P0.02 gave {c:?}"),
    }
    assert_eq!(
        ms[4].corner,
        CornerMode::Blend {
            tolerance_mm: None,
            naive_cam_mm: None
        }
    );
    match ms[5].corner {
        CornerMode::Blend {
            tolerance_mm: Some(t),
            naive_cam_mm: Some(q),
        } => {
            assert_close("G64 P0.01 in", t, 0.254, 1e-12);
            assert_close("G64 P0.01 in, naive CAM", q, 0.254, 1e-12);
        }
        c => panic!("G20 G64 P0.01 gave {c:?}"),
    }
}

#[test]
fn several_m_codes_of_different_groups_in_one_block() {
    // M3 (spindle) and M8 (coolant) are in different modal groups: one block may hold both,
    // and the spindle starts before the coolant (order of execution).
    let ev = only_events(&items(D, "M8 M3 S500\n"));
    let codes: Vec<&str> = ev.iter().map(|e| e.code.as_str()).collect();
    assert_eq!(codes, ["S", "M3", "M8"]);
}

#[test]
fn two_m_codes_of_one_modal_group_are_an_error() {
    // LinuxCNC "Modal Groups": two M words of the same modal group on one line are an error
    // (M3/M4/M5 are group 7, M7/M8/M9 group 8).
    let d = error(D, "G1 X1 F100\nM3 M4 S100\n");
    assert_diag(&d, 2, 4, &["modal group"]);
    let d = error(D, "G1 X1 F100\nM8 M9\n");
    assert_diag(&d, 2, 4, &["modal group"]);
}

#[test]
fn nothing_runs_after_program_end() {
    // M2 and M30 end the program: later lines are not executed (and not checked).
    let its = items(D, "G1 X1 F100\nM30\nG1 X5\n#1 = 2\n");
    assert_eq!(its.len(), 2, "{}", describe_items(&its));
    let its = items(D, "M2\nG1 X5 F100\n");
    assert_eq!(its.len(), 1, "{}", describe_items(&its));
}

#[test]
fn nested_comments_are_an_error() {
    // LinuxCNC: comments do not nest; a `(` inside a comment is an error, not text to skip.
    let d = error(D, "G1 X1 F100\n(outer (inner) text)\n");
    assert_eq!(d.line, 2, "{d}");
}

#[test]
fn g92_applies_in_every_coordinate_system() {
    // LinuxCNC: the G92 offset is added to whichever coordinate system is active.
    let mut s = Settings::default();
    s.work_offsets_mm[1] = [200.0, 0.0, 0.0];
    let ms = moves_with(D, s, "G1 X10 F100\nG92 X0\nG55 G1 X1\n");
    assert_feed_line(&ms[1], v(10.0, 0.0, 0.0), v(211.0, 0.0, 0.0), 100.0);
}

#[test]
fn radius_format_with_turns_and_polar_in_inches() {
    // P adds whole turns in radius format too: the half circle from (10,0) to (-10,0) plus
    // one turn.
    let ms = moves(D, "G1 X10 F100\nG2 X-10 R10 P2\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(-10.0, 0.0, 0.0),
        o(),
        axis_g17(),
        -3.0 * PI,
    );
    // `@` is a length: G20 reads it in inches.
    let ms = moves(D, "G20\nG1 @1 ^90 F10\n");
    assert_feed_line(&ms[0], o(), v(0.0, 25.4, 0.0), 254.0);
}

#[test]
fn g40_with_a_tool_radius_is_fine() {
    // Only active compensation (G41/G42) with a non-zero radius is refused; cancelling it is
    // always allowed.
    let s = settings_with_tool(1, 0.0, 3.0);
    let ms = moves_with(D, s, "T1 M6\nG40 G1 X10 F100\n");
    assert_feed_line(&ms[0], o(), v(10.0, 0.0, 0.0), 100.0);
}

#[test]
fn dwell_with_a_motion_in_the_same_block_keeps_the_motion() {
    // G4 is non-modal and uses only P: the G1 X10 of the same block still moves, after the
    // dwell (LinuxCNC's order of execution), and the feed of the block applies.
    let ms = moves(D, "G1 X1 F100\nG4 P0.5 G1 X10 F200\nG4 P1\nG1 X12\n");
    assert_eq!(ms.len(), 3, "{ms:#?}");
    assert_feed_line(&ms[0], o(), v(1.0, 0.0, 0.0), 100.0);
    assert_feed_line(&ms[1], v(1.0, 0.0, 0.0), v(10.0, 0.0, 0.0), 200.0);
    assert_feed_line(&ms[2], v(10.0, 0.0, 0.0), v(12.0, 0.0, 0.0), 200.0);
    assert_eq!(ms[1].line, 2);
    // The dwell comes before the motion of its block, with its time in seconds.
    let its = items(D, "G1 X1 F100\nG4 P0.5 G1 X10 F200\nG4 P1\nG1 X12\n");
    let order: Vec<(u32, &str, Option<f64>)> = its
        .iter()
        .map(|i| match i {
            Item::Move(m) => (m.line, "move", None),
            Item::Event(e) => (e.line, e.code.as_str(), e.value),
        })
        .collect();
    assert_eq!(
        order,
        [
            (1, "move", None),
            (2, "G4", Some(0.5)),
            (2, "move", None),
            (3, "G4", Some(1.0)),
            (4, "move", None)
        ]
    );
    // The modal G1 takes the axis words of a G4 block too; an H word (G43) does not move.
    let ms = moves_with(
        D,
        settings_with_tool(1, 0.0, 0.0),
        "G1 X1 F100\nG4 P1 X5\nG43 H1 G4 P1\n",
    );
    assert_eq!(ms.len(), 2, "{ms:#?}");
    assert_feed_line(&ms[1], v(1.0, 0.0, 0.0), v(5.0, 0.0, 0.0), 100.0);
    // Without a motion mode, axis words with G4 are LinuxCNC's error.
    assert_diag(
        &error(D, "G4 P1 X5\n"),
        1,
        7,
        &["cannot use axis values without a G code that uses them"],
    );
}

#[test]
fn polar_words_measure_the_current_point_about_the_current_program_zero() {
    // LinuxCNC "Polar Coordinates": `@` and `^` are about the XY zero of the current
    // coordinate system; a missing one (or, in G91, the base of an incremental one) is the
    // current point's distance or angle measured about that zero, also after G92, G92.1,
    // G92.2, G92.3 or a G5x moved it. Positions below are machine mm, computed by hand.
    let head = "G21 G90 G17 F100\nG1 @10 ^0\n"; // to (10, 0)
    let run_tail = |tail: &str| moves(D, &format!("{head}{tail}"));

    // G92 X0 Y0 makes the current point the zero: its distance is 0, so `^90` stays put.
    let ms = run_tail("G92 X0 Y0\nG1 ^90\n");
    assert_eq!(ms.len(), 1, "{ms:?}");

    // G92 X5 Y0: zero at (5, 0), the point at 5 mm, 0°. `^90` -> (5, 5).
    let ms = run_tail("G92 X5 Y0\nG1 ^90\n");
    assert_feed_line(&ms[1], v(10.0, 0.0, 0.0), v(5.0, 5.0, 0.0), 100.0);
    // The same in G91: 5 mm + 0, 0° + 90°.
    let ms = run_tail("G92 X5 Y0\nG91 G1 ^90\n");
    assert_feed_line(&ms[1], v(10.0, 0.0, 0.0), v(5.0, 5.0, 0.0), 100.0);
    // G91 from the zero itself has no angle: LinuxCNC's error, on the polar line.
    let d = error(D, &format!("{head}G92 X0 Y0\nG91 G1 ^90\n"));
    assert_diag_line(
        &d,
        4,
        &["G91 motion with polar coordinates is indeterminate"],
    );

    // G92.1 puts the zero back at (0, 0): the point (5, 5) is at 5√2 mm, 45°.
    // `^0` -> (5√2, 0).
    let ms = run_tail("G92 X5 Y0\nG1 ^90\nG92.1\nG1 ^0\n");
    let r = 50f64.sqrt();
    assert_feed_line(&ms[2], v(5.0, 5.0, 0.0), v(r, 0.0, 0.0), 100.0);

    // G92.2 suspends (zero (0, 0): the point (10, 0) is at 10 mm, 0°; `^180` -> (-10, 0)),
    // G92.3 restores (zero (5, 0): the point is at 15 mm, 180°; `^90` -> (5, 15)).
    let ms = run_tail("G92 X5 Y0\nG92.2\nG1 ^180\nG92.3\nG1 ^90\n");
    assert_feed_line(&ms[1], v(10.0, 0.0, 0.0), v(-10.0, 0.0, 0.0), 100.0);
    assert_feed_line(&ms[2], v(-10.0, 0.0, 0.0), v(5.0, 15.0, 0.0), 100.0);
}

#[test]
fn polar_words_after_a_work_offset_change_and_a_tool_length() {
    // G55 at (0, 10): the point (10, 0) is at 10√2 mm, -45° about it. `@5` keeps -45°:
    // (5 cos -45°, 10 + 5 sin -45°). G43 moves Z only: the XY polar values stay.
    let mut s = settings_with_tool(1, 7.0, 0.0);
    s.work_offsets_mm[1] = [0.0, 10.0, 0.0];
    let ms = moves_with(D, s.clone(), "G21 G90 G17 F100\nG1 @10 ^0\nG55\nG1 @5\n");
    let h = 5.0 * 0.5f64.sqrt();
    assert_feed_line(&ms[1], v(10.0, 0.0, 0.0), v(h, 10.0 - h, 0.0), 100.0);
    // In G91 `^45` turns the point from -45° to 0° about (0, 10): (10√2, 10).
    let ms = moves_with(
        D,
        s.clone(),
        "G21 G90 G17 F100\nG1 @10 ^0\nG55\nG91 G1 ^45\n",
    );
    let r = 200f64.sqrt();
    assert_feed_line(&ms[1], v(10.0, 0.0, 0.0), v(r, 10.0, 0.0), 100.0);
    // G43 H1 (Z +7) then `^90`: 10 mm, 90° -> (0, 10), Z unchanged in the machine.
    let ms = moves_with(D, s, "G21 G90 G17 F100\nG1 @10 ^0\nG43 H1\nG1 ^90\n");
    assert_feed_line(&ms[1], v(10.0, 0.0, 0.0), v(0.0, 10.0, 0.0), 100.0);
}
