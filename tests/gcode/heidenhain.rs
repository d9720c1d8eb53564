//! Heidenhain TNC in ISO programming, from the TNC 410 ISO manual (seed 004: G10/G11 polar
//! lines, G12/G13/G15 polar circles, the N120..N200 example) and the DESIGN.md notes.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use kerf_tests::*;

const D: Dialect = Dialect::Heidenhain;

fn o() -> Vec3 {
    v(0.0, 0.0, 0.0)
}

/// Wraps blocks in a `%NAME G71 *` program, one block per line after the header.
fn prog(blocks: &str) -> String {
    format!("%TEST G71 *\n{blocks}N9999 %TEST G71 *\n")
}

fn seed_program() -> String {
    std::fs::read_to_string(data_dir().join("programs/heidenhain/seed_polar.h"))
        .expect("tests/data/programs/heidenhain/seed_polar.h")
}

#[test]
fn seed_example_n120_to_n200() {
    // Seed 004, computed by hand:
    // N120 pole (45,45).
    // N130 G11 R30 H0 -> (75,45), F300, M3.       (G42 with tool radius 0: path unchanged)
    // N140 H+60 -> (45 + 30 cos 60°, 45 + 30 sin 60°) = (60, 45 + 15√3).
    // N150 G91 H+60 -> H = 120° -> (30, 45 + 15√3).
    // N160 G90 H+180 -> (15, 45).
    // N180 pole (25,25).
    // N190 G11 R20 H0 -> (45,25), F250, M3.
    // N200 G13 H+180 -> counter-clockwise half circle about (25,25) to (5,25).
    let its = items(D, &seed_program());
    let ms = only_moves(&its);
    assert_eq!(ms.len(), 6, "{}", describe_items(&its));
    let h = 45.0 + 15.0 * 3.0f64.sqrt();
    assert_feed_line(&ms[0], o(), v(75.0, 45.0, 0.0), 300.0);
    assert_feed_line(&ms[1], v(75.0, 45.0, 0.0), v(60.0, h, 0.0), 300.0);
    assert_feed_line(&ms[2], v(60.0, h, 0.0), v(30.0, h, 0.0), 300.0);
    assert_feed_line(&ms[3], v(30.0, h, 0.0), v(15.0, 45.0, 0.0), 300.0);
    assert_feed_line(&ms[4], v(15.0, 45.0, 0.0), v(45.0, 25.0, 0.0), 250.0);
    assert_arc(
        &ms[5],
        v(45.0, 25.0, 0.0),
        v(5.0, 25.0, 0.0),
        v(25.0, 25.0, 0.0),
        axis_g17(),
        PI,
    );
    assert_eq!(ms[5].feed_mm_min, Some(250.0));
    let lines: Vec<u32> = ms.iter().map(|m| m.line).collect();
    assert_eq!(lines, vec![3, 4, 5, 6, 8, 9]);
    let ev: Vec<(u32, &str)> = only_events(&its)
        .iter()
        .map(|e| (e.line, e.code.as_str()))
        .collect();
    assert_eq!(ev, vec![(3, "M3"), (8, "M3")]);
}

#[test]
fn polar_circles_incremental_multi_turn_and_last_direction() {
    // Continues the seed example at (5,25), pole (25,25), angle 180°.
    let src = seed_program().replace(
        "N99999999 %SEED G71 *\n",
        "N210 G91 G13 H+720 *\n\
         N220 G91 G12 H-90 *\n\
         N230 G15 H-90 *\n\
         N240 G12 H-450 *\n\
         N250 G90 G13 H+90 *\n\
         N99999999 %SEED G71 *\n",
    );
    let ms = moves(D, &src);
    assert_eq!(ms.len(), 11);
    let c = v(25.0, 25.0, 0.0);
    // G91 H+720: two whole turns counter-clockwise, back at the start.
    assert_arc(
        &ms[6],
        v(5.0, 25.0, 0.0),
        v(5.0, 25.0, 0.0),
        c,
        axis_g17(),
        2.0 * TAU,
    );
    // G91 G12 H-90: a quarter turn clockwise, from 180° to 90°.
    assert_arc(
        &ms[7],
        v(5.0, 25.0, 0.0),
        v(25.0, 45.0, 0.0),
        c,
        axis_g17(),
        -FRAC_PI_2,
    );
    // G15: the last programmed direction (clockwise), from 90° to 0°.
    assert_arc(
        &ms[8],
        v(25.0, 45.0, 0.0),
        v(45.0, 25.0, 0.0),
        c,
        axis_g17(),
        -FRAC_PI_2,
    );
    // G91 G12 H-450: one and a quarter turns clockwise, to -90°.
    assert_arc(
        &ms[9],
        v(45.0, 25.0, 0.0),
        v(25.0, 5.0, 0.0),
        c,
        axis_g17(),
        -2.5 * PI,
    );
    // G90 G13 H+90 after several turns: absolute H is the end point (crate doc), reached
    // from the tool's position (270°) counter-clockwise: +180°, not wound up.
    assert_arc(
        &ms[10],
        v(25.0, 5.0, 0.0),
        v(25.0, 45.0, 0.0),
        c,
        axis_g17(),
        PI,
    );
}

#[test]
fn polar_rapid_g10_and_negative_angles() {
    // Seed 004: H > 0 counter-clockwise from the angle reference axis, H < 0 clockwise.
    let ms = moves(
        D,
        &prog("N10 I+10 J+0 *\nN20 G10 R+5 H-90 *\nN30 G11 R+5 H+90 F100 *\n"),
    );
    assert_rapid(&ms[0], o(), v(10.0, -5.0, 0.0));
    assert_feed_line(&ms[1], v(10.0, -5.0, 0.0), v(10.0, 5.0, 0.0), 100.0);
}

#[test]
fn centre_block_sets_centre_without_motion_absolute_and_incremental() {
    // [M] `I J` alone: circle centre and pole, no motion; in G91 relative to the last
    // programmed position.
    let ms = moves(
        D,
        &prog(
            "N10 G01 X+10 Y+0 F100 *\n\
             N20 I+0 J+0 *\n\
             N30 G03 X+0 Y+10 *\n\
             N40 G91 I+0 J-10 *\n\
             N50 G90 G02 X+10 Y+0 *\n",
        ),
    );
    assert_eq!(ms.len(), 3, "{ms:#?}");
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
    assert_eq!(ms[1].line, 4);
}

#[test]
fn full_circle_when_end_equals_start() {
    let ms = moves(
        D,
        &prog("N10 G01 X+10 Y+0 F100 *\nN20 I+0 J+0 *\nN30 G02 X+10 Y+0 *\nN40 G03 X+10 Y+0 *\n"),
    );
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
fn centre_is_also_the_pole_and_the_pole_the_centre() {
    // One `I J` block serves both a polar line and a centre arc.
    let ms = moves(
        D,
        &prog("N10 I+5 J+5 *\nN20 G11 R+5 H+0 F100 *\nN30 G03 X+5 Y+10 *\n"),
    );
    assert_feed_line(&ms[0], o(), v(10.0, 5.0, 0.0), 100.0);
    assert_arc(
        &ms[1],
        v(10.0, 5.0, 0.0),
        v(5.0, 10.0, 0.0),
        v(5.0, 5.0, 0.0),
        axis_g17(),
        FRAC_PI_2,
    );
}

#[test]
fn g29_makes_the_last_position_the_pole() {
    let ms = moves(
        D,
        &prog("N10 G01 X+20 Y+20 F100 *\nN20 G29 *\nN30 G11 R+5 H+0 *\n"),
    );
    assert_feed_line(&ms[1], v(20.0, 20.0, 0.0), v(25.0, 20.0, 0.0), 100.0);
}

#[test]
fn radius_arcs_r_plus_and_r_minus() {
    let cases = [
        ("G02 X+10 Y+10 R+10", v(10.0, 0.0, 0.0), -FRAC_PI_2),
        ("G02 X+10 Y+10 R-10", v(0.0, 10.0, 0.0), -1.5 * PI),
        ("G03 X+10 Y+10 R+10", v(0.0, 10.0, 0.0), FRAC_PI_2),
        ("G03 X+10 Y+10 R-10", v(10.0, 0.0, 0.0), 1.5 * PI),
    ];
    for (block, center, sweep) in cases {
        let ms = moves(D, &prog(&format!("N10 F100 *\nN20 {block} *\n")));
        assert_arc(&ms[0], o(), v(10.0, 10.0, 0.0), center, axis_g17(), sweep);
    }
}

#[test]
fn full_circle_with_radius_is_two_half_circles() {
    // [M] A full circle with R needs two half circles.
    let ms = moves(
        D,
        &prog("N10 F100 *\nN20 G02 X+20 Y+0 R+10 *\nN30 G02 X+0 Y+0 R+10 *\n"),
    );
    assert_arc(
        &ms[0],
        o(),
        v(20.0, 0.0, 0.0),
        v(10.0, 0.0, 0.0),
        axis_g17(),
        -PI,
    );
    assert_arc(
        &ms[1],
        v(20.0, 0.0, 0.0),
        o(),
        v(10.0, 0.0, 0.0),
        axis_g17(),
        -PI,
    );
}

#[test]
fn helix_with_centre() {
    let ms = moves(
        D,
        &prog("N10 G01 X+10 Y+0 F100 *\nN20 I+0 J+0 *\nN30 G03 X-10 Y+0 Z-4 *\n"),
    );
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(-10.0, 0.0, -4.0),
        o(),
        axis_g17(),
        PI,
    );
}

#[test]
fn arcs_in_g18_and_g19() {
    // The centre block names the two plane axes: I K in G18, J K in G19.
    let ms = moves(
        D,
        &prog("N10 G01 X+10 F100 *\nN20 G18 *\nN30 I+0 K+0 *\nN40 G02 X+0 Z+10 *\n"),
    );
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(0.0, 0.0, 10.0),
        o(),
        axis_g18(),
        -FRAC_PI_2,
    );
    let ms = moves(
        D,
        &prog("N10 G01 Y+10 F100 *\nN20 G19 *\nN30 J+0 K+0 *\nN40 G03 Y+0 Z+10 *\n"),
    );
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
fn g90_g91_switch_per_axis_inside_a_block() {
    // [M] `G02 G91 X+5 G90 Y-5`: each axis word takes the mode written before it.
    let ms = moves(
        D,
        &prog("N10 G01 X+10 Y+10 F100 *\nN20 G01 G91 X+5 G90 Y+7 *\n"),
    );
    assert_feed_line(&ms[1], v(10.0, 10.0, 0.0), v(15.0, 7.0, 0.0), 100.0);
}

#[test]
fn inch_program_header_g70() {
    let ms = moves(
        D,
        "%INCH G70 *\nN10 G01 X+1 Y+2 F10 *\nN20 G00 Z+0.5 *\nN30 %INCH G70 *\n",
    );
    assert_point("end", ms[0].path.end(), v(25.4, 50.8, 0.0), TOL);
    assert_rapid(&ms[1], v(25.4, 50.8, 0.0), v(25.4, 50.8, 12.7));
}

#[test]
fn blocks_end_with_star_and_lines_count_from_the_header() {
    let ms = moves(
        D,
        "%P G71 *\nN10 G00 X+1 *\nN20 G01 Y+1 F100 *\nN30 %P G71 *\n",
    );
    assert_eq!(ms.len(), 2);
    assert_eq!([ms[0].line, ms[1].line], [2, 3]);
}

#[test]
fn tool_call_and_machine_functions_are_events() {
    // TNC ISO tool call: `T1 G17 S2000` (tool 1, spindle axis Z, 2000 rpm).
    let its = items(
        D,
        &prog("N10 T1 G17 S2000 *\nN20 G00 X+1 M3 *\nN30 M5 *\nN40 M30 *\n"),
    );
    let ev = only_events(&its);
    let first: Vec<(&str, Option<f64>)> = ev
        .iter()
        .filter(|e| e.line == 2)
        .map(|e| (e.code.as_str(), e.value))
        .collect();
    assert!(first.contains(&("T", Some(1.0))), "{first:?}");
    assert!(first.contains(&("S", Some(2000.0))), "{first:?}");
    let rest: Vec<&str> = ev
        .iter()
        .filter(|e| e.line > 2)
        .map(|e| e.code.as_str())
        .collect();
    assert_eq!(rest, ["M3", "M5", "M30"]);
}

#[test]
fn arc_without_a_centre_is_an_error() {
    let d = error(D, &prog("N10 G01 X+10 F100 *\nN20 G02 X+0 Y+10 *\n"));
    assert_eq!(d.line, 3, "{d}");
}

#[test]
fn arc_end_point_off_the_circle_is_an_error() {
    let d = error(
        D,
        &prog("N10 G01 X+10 F100 *\nN20 I+0 J+0 *\nN30 G03 X+0 Y+12 *\n"),
    );
    assert_eq!(d.line, 4, "{d}");
}

#[test]
fn cutter_compensation() {
    let zero = settings_with_tool(1, 0.0, 0.0);
    let with = moves_with(
        D,
        zero.clone(),
        &prog("N10 T1 G17 *\nN20 G01 G41 X+10 F100 *\nN30 G40 X+0 *\n"),
    );
    let without = moves_with(
        D,
        zero,
        &prog("N10 T1 G17 *\nN20 G01 X+10 F100 *\nN30 X+0 *\n"),
    );
    assert_same_moves("G41 with radius 0", &with, &without, TOL);
    let d = error_with(
        D,
        settings_with_tool(1, 0.0, 2.0),
        &prog("N10 T1 G17 *\nN20 G01 G42 X+10 F100 *\n"),
    );
    assert_diag(&d, 3, 9, &["cutter compensation"]);
}

#[test]
fn arc_end_point_tolerance_is_configurable() {
    // r = 10 about the origin; the end is 0.5 mm off the circle.
    let src = prog("N10 G01 X+10 F100 *\nN20 I+0 J+0 *\nN30 G03 X+0 Y+10.5 *\n");
    assert!(
        run(D, &src).is_err(),
        "0.5 mm on r = 10 is outside the default tolerance"
    );
    let loose = Settings {
        arc_tolerance_mm: 1.0,
        ..Settings::default()
    };
    let items = run_with(D, loose, &src).unwrap_or_else(|e| panic!("tolerance 1 mm: {e}"));
    let m = only_moves(&items);
    assert_point("end point exact", m[1].path.end(), v(0.0, 10.5, 0.0), 1e-9);
    let ok = prog("N10 G01 X+10 F100 *\nN20 I+0 J+0 *\nN30 G03 X+0 Y+10.01 *\n");
    assert!(
        run(D, &ok).is_ok(),
        "0.01 mm on r = 10 is within the default tolerance"
    );
}

#[test]
fn per_axis_modes_on_an_arc_and_the_last_mode_stays() {
    // [M] `G02 G91 X+5 G90 Y-5`: X incremental, Y absolute. From the origin about (5,0) to
    // (5,-5): the start is at 180°, the end at 270°; clockwise that is -270°. The mode last
    // written in the block (G90) stays active for the next block.
    let ms = moves(
        D,
        &prog("N10 I+5 J+0 *\nN20 G02 G91 X+5 G90 Y-5 F100 *\nN30 G01 X+1 *\n"),
    );
    assert_arc(
        &ms[0],
        o(),
        v(5.0, -5.0, 0.0),
        v(5.0, 0.0, 0.0),
        axis_g17(),
        -1.5 * PI,
    );
    assert_feed_line(&ms[1], v(5.0, -5.0, 0.0), v(1.0, -5.0, 0.0), 100.0);
}

#[test]
fn polar_angle_limits_are_inclusive() {
    // Seed 004: G10/G11 H from -360° to +360°; G12/G13/G15 H from -5400° to +5400°.
    let ms = moves(
        D,
        &prog("N10 I+0 J+0 *\nN20 G11 R+10 H-360 F100 *\nN30 G91 G13 H+5400 *\n"),
    );
    assert_feed_line(&ms[0], o(), v(10.0, 0.0, 0.0), 100.0);
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(10.0, 0.0, 0.0),
        o(),
        axis_g17(),
        15.0 * TAU,
    );
}

#[test]
fn polar_line_with_the_tool_axis() {
    // A polar line may also move the tool axis: the end point is (pole + R at H, Z).
    let ms = moves(D, &prog("N10 I+0 J+0 *\nN20 G11 R+10 H+90 Z-5 F100 *\n"));
    assert_feed_line(&ms[0], o(), v(0.0, 10.0, -5.0), 100.0);
}

#[test]
fn dwell_f_is_the_dwell_time_not_the_feed() {
    let ms = moves(
        D,
        "%C G71 *\nN10 G01 X+1 F100 *\nN20 G04 F2 *\nN30 G01 X+2 *\nN40 %C G71 *\n",
    );
    assert_eq!(ms.len(), 2, "{ms:#?}");
    assert_feed_line(&ms[1], v(1.0, 0.0, 0.0), v(2.0, 0.0, 0.0), 100.0);
}

#[test]
fn polar_circle_absolute_angle_beyond_360_names_a_point() {
    // Seed 004: H (-5400°..+5400°) is the angular position of the end point; H+540 is the
    // point at 180°. Kerf's documented choice: from 0° counter-clockwise that is a half
    // circle (several turns are written with G91 H).
    let ms = moves(
        D,
        &prog("N10 I+0 J+0 *\nN20 G11 R+10 H+0 F100 *\nN30 G13 H+540 *\n"),
    );
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(-10.0, 0.0, 0.0),
        o(),
        axis_g17(),
        PI,
    );
}

#[test]
fn a_word_before_the_first_g90_g91_of_its_block_keeps_the_modal_mode() {
    // [M] `G02 G91 X+5 G90 Y-5`: a word takes the mode written before it in the block; a
    // word before the block's first G90/G91 has none written before it, so it takes the
    // modal mode (the one in force when the block starts). By hand:
    // N10 G90 (modal) X+10 Y+10 -> (10, 10).
    // N20 X+20 under the modal G90 -> X 20; G91 then Y+5 -> Y 15: (20, 15). G91 stays.
    // N30 X+5 under the modal G91 -> X 25; G90 then Y+7 -> Y 7: (25, 7). G90 stays.
    // N40 I+1 under the modal G90 (pole at X 1), G91 then J+2 -> Y 7 + 2 = 9: pole (1, 9);
    //     G91 stays. N50 G90 G11 R+3 H+0 -> (4, 9).
    let ms = moves(
        D,
        &prog(
            "N10 G00 X+10 Y+10 *\n\
             N20 G00 X+20 G91 Y+5 *\n\
             N30 G01 X+5 G90 Y+7 F100 *\n\
             N40 I+1 G91 J+2 *\n\
             N50 G90 G11 R+3 H+0 *\n",
        ),
    );
    assert_eq!(ms.len(), 4, "{ms:?}");
    assert_rapid(&ms[0], o(), v(10.0, 10.0, 0.0));
    assert_rapid(&ms[1], v(10.0, 10.0, 0.0), v(20.0, 15.0, 0.0));
    assert_feed_line(&ms[2], v(20.0, 15.0, 0.0), v(25.0, 7.0, 0.0), 100.0);
    assert_feed_line(&ms[3], v(25.0, 7.0, 0.0), v(4.0, 9.0, 0.0), 100.0);
}

#[test]
fn absolute_polar_circle_angle_does_not_depend_on_how_the_start_was_reached() {
    // The start (10, 0) about the pole (0, 0) is reached three ways: `G11 R+10 H-360`,
    // `G11 R+10 H+0` and `G01 X+10 Y+0`. The arc that follows depends only on that point,
    // H and the direction (crate doc, Heidenhain: absolute H is the end point's angular
    // position; the arc is shorter than one turn, or a whole turn back to the start).
    let starts = [
        "G11 R+10 H-360 F600 *",
        "G11 R+10 H+0 F600 *",
        "G01 X+10 Y+0 F600 *",
    ];
    let p5 = v(10.0 * deg(5.0).cos(), 10.0 * deg(5.0).sin(), 0.0);
    let a = v(10.0, 0.0, 0.0);
    // (arc block, end point, signed sweep), by hand.
    let cases = [
        ("G13 H+5 *", p5, deg(5.0)),         // 0° -> 5° counter-clockwise
        ("G13 H+365 *", p5, deg(5.0)),       // 365° is the point at 5°
        ("G13 H-355 *", p5, deg(5.0)),       // so is -355°
        ("G12 H+5 *", p5, -deg(355.0)),      // clockwise from 0° to 5°
        ("G13 H+720 *", a, TAU),             // the start point itself: one full circle
        ("G12 H-360 *", a, -TAU),            // the same, clockwise
        ("G91 G13 H+365 *", p5, deg(365.0)), // G91: the swept angle itself
    ];
    for start in starts {
        for (arc, end, sweep) in cases {
            let src = prog(&format!("N10 I+0 J+0 *\nN20 {start}\nN30 {arc}\n"));
            let ms = moves(D, &src);
            assert_eq!(ms.len(), 2, "{src}");
            let m = &ms[1];
            let got = as_arc(m);
            assert_close(
                &format!("{start} / {arc}: sweep"),
                got.sweep_rad,
                sweep,
                1e-9,
            );
            assert_arc(m, a, end, o(), axis_g17(), sweep);
        }
    }
}

#[test]
fn absolute_polar_circle_from_a_negative_start_angle() {
    // By hand: G11 R+10 H-10 puts the tool at -10° (= 350°) about (0, 0).
    // G12 H-20: clockwise from -10° to -20°, -10°. G13 H+350 from -20° (= 340°): 10°.
    // G13 H-10 from 350°: the start point itself, one full circle.
    let ms = moves(
        D,
        &prog(
            "N10 I+0 J+0 *\n\
             N20 G11 R+10 H-10 F600 *\n\
             N30 G12 H-20 *\n\
             N40 G13 H+350 *\n\
             N50 G13 H-10 *\n",
        ),
    );
    let at = |a: f64| v(10.0 * deg(a).cos(), 10.0 * deg(a).sin(), 0.0);
    assert_arc(&ms[1], at(-10.0), at(-20.0), o(), axis_g17(), -deg(10.0));
    assert_arc(&ms[2], at(-20.0), at(-10.0), o(), axis_g17(), deg(10.0));
    assert_arc(&ms[3], at(-10.0), at(-10.0), o(), axis_g17(), TAU);
}
