//! Siemens Sinumerik 840D, from the Programming and Operating Manual (Milling) (seed 003:
//! G70/G71/G700/G710 and the poles G110/G111/G112 with RP/AP) and the DESIGN.md notes
//! (I/J/K, `=AC()`, CR=, TURN=, alarm 14040).

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use kerf_tests::*;

const D: Dialect = Dialect::Sinumerik;

fn o() -> Vec3 {
    v(0.0, 0.0, 0.0)
}

#[test]
fn lines_rapids_comments_and_block_numbers() {
    let ms = moves(
        D,
        "; a Sinumerik program\n\
         N10 G90 G0 X10 Y5 Z2 ; rapid\n\
         N20 G1 Z-1 F100\n\
         N30 G91 X5 Y5\n\
         N40 G90 X0\n",
    );
    assert_eq!(ms.len(), 4);
    assert_rapid(&ms[0], o(), v(10.0, 5.0, 2.0));
    assert_feed_line(&ms[1], v(10.0, 5.0, 2.0), v(10.0, 5.0, -1.0), 100.0);
    assert_feed_line(&ms[2], v(10.0, 5.0, -1.0), v(15.0, 10.0, -1.0), 100.0);
    assert_feed_line(&ms[3], v(15.0, 10.0, -1.0), v(0.0, 10.0, -1.0), 100.0);
    assert_eq!(ms[0].line, 2);
}

#[test]
fn ac_and_ic_on_end_points() {
    // X=IC(..) is incremental in G90, X=AC(..) absolute in G91.
    let ms = moves(D, "G90 G1 X10 F100\nX=IC(5)\nG91 Y=AC(7)\n");
    assert_feed_line(&ms[1], v(10.0, 0.0, 0.0), v(15.0, 0.0, 0.0), 100.0);
    assert_feed_line(&ms[2], v(15.0, 0.0, 0.0), v(15.0, 7.0, 0.0), 100.0);
}

#[test]
fn centre_words_are_incremental_regardless_of_g90_g91() {
    let ms = moves(D, "G1 X10 F100\nG90 G3 X0 Y10 I-10 J0\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(0.0, 10.0, 0.0),
        o(),
        axis_g17(),
        FRAC_PI_2,
    );
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
fn centre_words_with_ac_are_absolute() {
    let ms = moves(D, "G1 X10 Y5 F100\nG3 X0 Y15 I=AC(0) J=AC(5)\n");
    assert_arc(
        &ms[1],
        v(10.0, 5.0, 0.0),
        v(0.0, 15.0, 0.0),
        v(0.0, 5.0, 0.0),
        axis_g17(),
        FRAC_PI_2,
    );
    // Mixed: I absolute, J incremental (J0 = the start's Y).
    let ms = moves(D, "G1 X10 Y5 F100\nG2 X20 Y15 I=AC(20) J0\n");
    // Centre (20,5): start vector (-10,0), end (0,10): cross = -100, clockwise -90°.
    assert_arc(
        &ms[1],
        v(10.0, 5.0, 0.0),
        v(20.0, 15.0, 0.0),
        v(20.0, 5.0, 0.0),
        axis_g17(),
        -FRAC_PI_2,
    );
    let ms = moves(D, "G1 X10 F100\nG3 X0 Y10 I=IC(-10) J=IC(0)\n");
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
fn arcs_in_g18_and_g19() {
    let ms = moves(D, "G1 X10 F100\nG18 G2 X0 Z10 I-10 K0\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(0.0, 0.0, 10.0),
        o(),
        axis_g18(),
        -FRAC_PI_2,
    );
    let ms = moves(D, "G1 Y10 F100\nG19 G3 Y0 Z10 J-10 K0\n");
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
fn cr_radius_format_with_sign() {
    // CR=+ : arc up to 180°, CR=- : more than 180°.
    let cases = [
        ("G2 X10 Y10 CR=10", v(10.0, 0.0, 0.0), -FRAC_PI_2),
        ("G2 X10 Y10 CR=-10", v(0.0, 10.0, 0.0), -1.5 * PI),
        ("G3 X10 Y10 CR=+10", v(0.0, 10.0, 0.0), FRAC_PI_2),
        ("G3 X10 Y10 CR=-10", v(10.0, 0.0, 0.0), 1.5 * PI),
    ];
    for (block, center, sweep) in cases {
        let ms = moves(D, &format!("F100\n{block}\n"));
        assert_arc(&ms[0], o(), v(10.0, 10.0, 0.0), center, axis_g17(), sweep);
    }
}

#[test]
fn cr_cannot_make_a_full_circle() {
    // [M] CR= cannot program a full circle (alarm 14040).
    let d = error(D, "G1 X10 F100\nG2 X10 Y0 CR=5\n");
    assert_eq!(d.line, 2, "{d}");
}

#[test]
fn full_circle_is_centre_without_end_point() {
    let ms = moves(D, "F100\nG3 I10\nG2 J-10\n");
    assert_arc(&ms[0], o(), o(), v(10.0, 0.0, 0.0), axis_g17(), TAU);
    assert_arc(&ms[1], o(), o(), v(0.0, -10.0, 0.0), axis_g17(), -TAU);
}

#[test]
fn turn_adds_full_circles() {
    // [M] TURN=n: n additional full circles.
    let ms = moves(D, "G1 X10 F100\nG3 X0 Y10 I-10 J0 TURN=2\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(0.0, 10.0, 0.0),
        o(),
        axis_g17(),
        FRAC_PI_2 + 2.0 * TAU,
    );
    let ms = moves(D, "G1 X10 F100\nG2 I-10 TURN=1\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(10.0, 0.0, 0.0),
        o(),
        axis_g17(),
        -2.0 * TAU,
    );
}

#[test]
fn helix_with_turn() {
    let ms = moves(D, "G1 X10 F100\nG17 G3 X-10 Y0 Z8 I-10 J0 TURN=1\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(-10.0, 0.0, 8.0),
        o(),
        axis_g17(),
        3.0 * PI,
    );
    // A third of the way round (π of 3π) the tool is at (-10,0) and a third of the way up.
    let a = as_arc(&ms[1]);
    assert_point(
        "a third",
        arc_point(&a, 1.0 / 3.0),
        v(-10.0, 0.0, 8.0 / 3.0),
        1e-9,
    );
}

#[test]
fn polar_lines_about_poles_g111_g110_g112() {
    // Seed 003 and [M]: G111 sets the pole absolutely, G110 relative to the last programmed
    // position, G112 relative to the last pole. RP and AP are modal; AP=IC() adds to the
    // last angle.
    let ms = moves(
        D,
        "N10 G111 X10 Y10\n\
         N20 G1 RP=5 AP=0 F100\n\
         N30 AP=90\n\
         N40 AP=IC(90)\n\
         N50 RP=2\n\
         N60 G110 X5 Y0\n\
         N70 G1 RP=3 AP=0\n\
         N80 G112 X-3 Y5\n\
         N90 G1 RP=5 AP=-90\n",
    );
    assert_eq!(ms.len(), 6, "pole definitions do not move: {ms:#?}");
    assert_feed_line(&ms[0], o(), v(15.0, 10.0, 0.0), 100.0);
    assert_feed_line(&ms[1], v(15.0, 10.0, 0.0), v(10.0, 15.0, 0.0), 100.0);
    assert_feed_line(&ms[2], v(10.0, 15.0, 0.0), v(5.0, 10.0, 0.0), 100.0);
    assert_feed_line(&ms[3], v(5.0, 10.0, 0.0), v(8.0, 10.0, 0.0), 100.0);
    // G110 X5 Y0: pole = (8,10) + (5,0) = (13,10).
    assert_feed_line(&ms[4], v(8.0, 10.0, 0.0), v(16.0, 10.0, 0.0), 100.0);
    // G112 X-3 Y5: pole = (13,10) + (-3,5) = (10,15).
    assert_feed_line(&ms[5], v(16.0, 10.0, 0.0), v(10.0, 10.0, 0.0), 100.0);
    assert_eq!(ms[5].line, 9);
}

#[test]
fn pole_definition_ignores_g91() {
    // [M] G110/G111/G112 are not affected by G90/G91: G111 stays absolute in G91.
    let ms = moves(D, "G1 X20 Y20 F100\nG91 G111 X10 Y10\nG90 G1 RP=5 AP=0\n");
    assert_feed_line(&ms[1], v(20.0, 20.0, 0.0), v(15.0, 10.0, 0.0), 100.0);
}

#[test]
fn polar_with_third_axis_is_a_cylinder_coordinate() {
    // Seed 003: the axis normal to the plane may be given with RP/AP.
    let ms = moves(D, "G111 X0 Y0\nG1 RP=10 AP=90 Z-3 F100\n");
    assert_feed_line(&ms[0], o(), v(0.0, 10.0, -3.0), 100.0);
}

#[test]
fn polar_circles_about_the_pole() {
    // G2/G3 AP= RP=: the pole is the centre, RP the radius, AP the end angle.
    let ms = moves(
        D,
        "G111 X10 Y10\n\
         G1 RP=5 AP=0 F100\n\
         G3 AP=90\n\
         G2 AP=0 RP=5\n",
    );
    assert_eq!(ms.len(), 3);
    assert_arc(
        &ms[1],
        v(15.0, 10.0, 0.0),
        v(10.0, 15.0, 0.0),
        v(10.0, 10.0, 0.0),
        axis_g17(),
        FRAC_PI_2,
    );
    assert_arc(
        &ms[2],
        v(10.0, 15.0, 0.0),
        v(15.0, 10.0, 0.0),
        v(10.0, 10.0, 0.0),
        axis_g17(),
        -FRAC_PI_2,
    );
}

#[test]
fn g70_converts_geometry_but_not_the_feed() {
    // Seed 003: G70/G71 affect positions, I/J/K, CR and RP, not F; G700/G710 also F.
    let ms = moves(
        D,
        "N10 G70 G1 X1 F100\n\
         N20 G71 G1 X10\n\
         N30 G700 G1 X2 F10\n\
         N40 G710 G1 X0 F300\n",
    );
    assert_feed_line(&ms[0], o(), v(25.4, 0.0, 0.0), 100.0);
    assert_feed_line(&ms[1], v(25.4, 0.0, 0.0), v(10.0, 0.0, 0.0), 100.0);
    assert_feed_line(&ms[2], v(10.0, 0.0, 0.0), v(50.8, 0.0, 0.0), 254.0);
    assert_feed_line(&ms[3], v(50.8, 0.0, 0.0), o(), 300.0);
}

#[test]
fn g70_converts_centres_radii_and_polar_radius() {
    let ms = moves(
        D,
        "G70 G1 X1 Y0 F100\n\
         G3 X0 Y1 I-1 J0\n\
         G2 X1 Y0 CR=1\n\
         G111 X0 Y0\n\
         G1 RP=2 AP=90\n",
    );
    let inch = INCH_MM;
    assert_arc(
        &ms[1],
        v(inch, 0.0, 0.0),
        v(0.0, inch, 0.0),
        o(),
        axis_g17(),
        FRAC_PI_2,
    );
    // From (0,1) to (1,0) in, CR=1, clockwise short: the centre is the origin.
    assert_arc(
        &ms[2],
        v(0.0, inch, 0.0),
        v(inch, 0.0, 0.0),
        o(),
        axis_g17(),
        -FRAC_PI_2,
    );
    assert_feed_line(&ms[3], v(inch, 0.0, 0.0), v(0.0, 2.0 * inch, 0.0), 100.0);
}

#[test]
fn rotary_axes_are_carried() {
    let ms = moves(D, "G1 X10 A45 C-90 F100\n");
    assert_eq!(ms[0].abc_deg, Some(([0.0; 3], [45.0, 0.0, -90.0])));
}

#[test]
fn events_in_program_order() {
    let its = items(D, "T1 M6\nS1200 M3\nM8\nG1 X1 F100\nM9\nM5\nM30\n");
    let codes: Vec<&str> = its
        .iter()
        .map(|i| match i {
            Item::Event(e) => e.code.as_str(),
            Item::Move(_) => "move",
        })
        .collect();
    assert_eq!(
        codes,
        ["T", "M6", "S", "M3", "M8", "move", "M9", "M5", "M30"]
    );
    let ev = only_events(&its);
    assert_eq!(ev[0].value, Some(1.0));
    assert_eq!(ev[2].value, Some(1200.0));
}

#[test]
fn r_parameters_and_arithmetic_are_not_supported() {
    let d = error(D, "G1 X1 F100\nR1=10\n");
    assert_diag(&d, 2, 1, &["not supported"]);
    let d = error(D, "G1 X=R1 F100\n");
    assert_diag(&d, 1, 6, &["not supported"]);
}

#[test]
fn arc_end_point_tolerance_is_configurable() {
    // r = 10 from (0,0) about (10,0); the end is off the circle by `off` mm.
    let prog = |off: f64| format!("F100\nG3 X{} Y0 I10 J0\n", 20.0 + off);
    // Well inside the default tolerance, and far outside it.
    assert!(
        run(D, &prog(0.01)).is_ok(),
        "0.01 mm on r = 10 is within the default tolerance"
    );
    assert!(
        run(D, &prog(0.5)).is_err(),
        "0.5 mm on r = 10 is outside the default tolerance"
    );
    // A larger absolute tolerance accepts it.
    let loose = Settings {
        arc_tolerance_mm: 1.0,
        ..Settings::default()
    };
    let items = run_with(D, loose, &prog(0.5)).unwrap_or_else(|e| panic!("tolerance 1 mm: {e}"));
    let m = only_moves(&items);
    assert_point("end point exact", m[0].path.end(), v(20.5, 0.0, 0.0), 1e-9);
    // So does a larger relative tolerance (10 % of 10 mm).
    let rel = Settings {
        arc_tolerance_mm: 0.01,
        arc_tolerance_rel: 0.1,
        ..Settings::default()
    };
    assert!(
        run_with(D, rel, &prog(0.5)).is_ok(),
        "10 % of r = 10 mm covers 0.5 mm"
    );
}

#[test]
fn cutter_compensation() {
    let zero = settings_with_tool(1, 0.0, 0.0);
    let with = moves_with(D, zero.clone(), "T1 M6\nG41 G1 X10 F100\nG40 X0\n");
    let without = moves_with(D, zero, "T1 M6\nG1 X10 F100\nX0\n");
    assert_same_moves("G41 with radius 0", &with, &without, TOL);
    let d = error_with(
        D,
        settings_with_tool(1, 0.0, 2.0),
        "T1 M6\nG42 G1 X10 F100\n",
    );
    assert_diag(&d, 2, 1, &["cutter compensation"]);
}

#[test]
fn corner_modes_g60_g64_and_one_block_g9() {
    // Sinumerik: G60 exact stop (modal), G64 continuous-path mode, G9 exact stop for one
    // block.
    let ms = moves(D, "G1 X1 F100\nG9 X2\nX3\nG60 X4\nX5\nG64 X6\n");
    assert_eq!(ms[1].corner, CornerMode::ExactStop);
    assert_ne!(ms[2].corner, CornerMode::ExactStop, "G9 is one block");
    assert_eq!(ms[3].corner, CornerMode::ExactStop);
    assert_eq!(ms[4].corner, CornerMode::ExactStop, "G60 is modal");
    assert!(matches!(ms[5].corner, CornerMode::Blend { .. }));
}

#[test]
fn cr_and_turn_in_other_planes() {
    // G19 about +X from (Y0,Z0) to (Y10,Z10), CR=10 counter-clockwise short: centre (0,0,10)
    // (see the LinuxCNC G19 case); G18 full circle with TURN=1 about +Y.
    let ms = moves(D, "F100\nG19 G3 Y10 Z10 CR=10\n");
    assert_arc(
        &ms[0],
        o(),
        v(0.0, 10.0, 10.0),
        v(0.0, 0.0, 10.0),
        axis_g19(),
        FRAC_PI_2,
    );
    let ms = moves(D, "G1 X10 F100\nG18 G2 I-10 TURN=1\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(10.0, 0.0, 0.0),
        o(),
        axis_g18(),
        -2.0 * TAU,
    );
}

#[test]
fn polar_arc_with_incremental_angle() {
    // AP=IC() also works on circles about the pole.
    let ms = moves(D, "G111 X0 Y0\nG1 RP=10 AP=0 F100\nG3 AP=IC(270)\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(0.0, -10.0, 0.0),
        o(),
        axis_g17(),
        1.5 * PI,
    );
}

#[test]
fn turn_range_is_0_to_999() {
    // [M] TURN= takes 0..=999 additional turns.
    let ms = moves(D, "G1 X10 F100\nG2 I-10 TURN=999\nG3 X0 Y10 I-10 TURN=0\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(10.0, 0.0, 0.0),
        o(),
        axis_g17(),
        -1000.0 * TAU,
    );
    assert_arc(
        &ms[2],
        v(10.0, 0.0, 0.0),
        v(0.0, 10.0, 0.0),
        o(),
        axis_g17(),
        FRAC_PI_2,
    );
}

#[test]
fn without_a_pole_the_workpiece_zero_is_the_pole() {
    // Sinumerik: if no pole has been defined, the zero of the current workpiece coordinate
    // system is the pole.
    let ms = moves(D, "G1 X5 Y5 F100\nG1 RP=10 AP=90\n");
    assert_feed_line(&ms[1], v(5.0, 5.0, 0.0), v(0.0, 10.0, 0.0), 100.0);
}

#[test]
fn dwell_f_and_s_are_the_dwell_not_the_feed_or_the_spindle_speed() {
    // "G4 F.." is a dwell in seconds and "G4 S.." one in spindle revolutions; the feed and
    // spindle speed programmed before stay valid after the dwell block.
    let its = items(D, "S1000 M3\nG1 X1 F100\nG4 F2.5\nG4 S30\nG1 X2\n");
    let ms = only_moves(&its);
    assert_eq!(ms.len(), 2, "{ms:#?}");
    assert_feed_line(&ms[1], v(1.0, 0.0, 0.0), v(2.0, 0.0, 0.0), 100.0);
    let speeds: Vec<Option<f64>> = only_events(&its)
        .iter()
        .filter(|e| e.code.as_str() == "S")
        .map(|e| e.value)
        .collect();
    assert_eq!(speeds, [Some(1000.0)]);
    // The dwells themselves: 2.5 s, and 30 revolutions at 1000 rpm = 1.8 s, in order
    // between the two moves.
    let order: Vec<String> = its
        .iter()
        .map(|i| match i {
            Item::Move(m) => format!("move {}", m.line),
            Item::Event(e) => format!("{} {:?}", e.code.as_str(), e.value),
        })
        .collect();
    assert_eq!(
        order,
        [
            "S Some(1000.0)",
            "M3 None",
            "move 2",
            "G4 Some(2.5)",
            "G4 Some(1.8)",
            "move 5"
        ]
    );
    // Revolutions without a spindle speed cannot be timed.
    assert_diag(
        &error(D, "G1 X1 F100\nG4 S30\n"),
        2,
        4,
        &["G4 S", "no spindle speed S programmed"],
    );
}
