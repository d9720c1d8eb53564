//! Fagor 8070, from the 8070 programming manual (seed 000: 6.3.3 polar arcs with R, Q, I, J
//! and G91 Q360) and the DESIGN.md notes.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use kerf_tests::*;

const D: Dialect = Dialect::Fagor;

fn o() -> Vec3 {
    v(0.0, 0.0, 0.0)
}

#[test]
fn seed_q360_program() {
    // tests/data/programs/fagor/seed_q360.pim, computed by hand:
    // line 3: G01 R10 Q0 -> (10,0) at F500.
    // line 4: G03 G91 Q360 -> whole circle about the polar origin (no I J), +2π.
    // line 5: G90 G03 Q90 -> to (0,10) about the polar origin, +π/2.
    // line 6: G02 Q0 I0 J-10 -> centre (0,10) + (0,-10) = (0,0), to (10,0), -π/2.
    // line 7: M30.
    let src = std::fs::read_to_string(data_dir().join("programs/fagor/seed_q360.pim"))
        .expect("seed_q360.pim");
    let its = items(D, &src);
    let ms = only_moves(&its);
    assert_eq!(ms.len(), 4, "{}", describe_items(&its));
    assert_feed_line(&ms[0], o(), v(10.0, 0.0, 0.0), 500.0);
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(10.0, 0.0, 0.0),
        o(),
        axis_g17(),
        TAU,
    );
    assert_arc(
        &ms[2],
        v(10.0, 0.0, 0.0),
        v(0.0, 10.0, 0.0),
        o(),
        axis_g17(),
        FRAC_PI_2,
    );
    assert_arc(
        &ms[3],
        v(0.0, 10.0, 0.0),
        v(10.0, 0.0, 0.0),
        o(),
        axis_g17(),
        -FRAC_PI_2,
    );
    assert_eq!(
        ms.iter().map(|m| m.line).collect::<Vec<_>>(),
        vec![3, 4, 5, 6]
    );
    let ev = only_events(&its);
    assert_eq!(ev.len(), 1);
    assert_eq!((ev[0].line, ev[0].code), (7, EventCode::M30));
}

#[test]
fn g90_q360_is_the_angle_360_not_a_whole_circle() {
    // Seed 000: "Programming a 360º angle in G90 means programming an arc where the target
    // point forms a 360º angle with the horizontal going through the polar origin." From
    // 90° counter-clockwise to 360° is 270°.
    let ms = moves(D, "G01 R10 Q90 F100\nG03 Q360\n");
    assert_feed_line(&ms[0], o(), v(0.0, 10.0, 0.0), 100.0);
    assert_arc(
        &ms[1],
        v(0.0, 10.0, 0.0),
        v(10.0, 0.0, 0.0),
        o(),
        axis_g17(),
        1.5 * PI,
    );
}

#[test]
fn polar_lines_with_modal_and_incremental_r_and_q() {
    // Seed 000: an omitted R or Q keeps its last value; in G91 Q adds to the angle of the
    // previous point about the polar origin, R to its radius.
    let ms = moves(
        D,
        "G01 R10 Q30 F100\n\
         Q90\n\
         G91 Q90\n\
         R5\n\
         G90 R5\n",
    );
    assert_feed_line(&ms[0], o(), v(10.0 * deg(30.0).cos(), 5.0, 0.0), 100.0);
    assert_feed_line(&ms[1], ms[0].path.end(), v(0.0, 10.0, 0.0), 100.0);
    assert_feed_line(&ms[2], v(0.0, 10.0, 0.0), v(-10.0, 0.0, 0.0), 100.0);
    assert_feed_line(&ms[3], v(-10.0, 0.0, 0.0), v(-15.0, 0.0, 0.0), 100.0);
    assert_feed_line(&ms[4], v(-15.0, 0.0, 0.0), v(-5.0, 0.0, 0.0), 100.0);
}

#[test]
fn polar_rapid_with_z() {
    let ms = moves(D, "G00 R20 Q180 Z5\n");
    assert_rapid(&ms[0], o(), v(-20.0, 0.0, 5.0));
}

#[test]
fn polar_arc_with_centre_away_from_the_polar_origin() {
    // The end point is polar about the polar origin (part zero); I J give the centre from
    // the start. From (20,0): end R10 Q0 = (10,0), centre (20,0) + (-5,0) = (15,0): a
    // counter-clockwise half circle.
    let ms = moves(D, "G01 X20 Y0 F100\nG03 R10 Q0 I-5 J0\n");
    assert_arc(
        &ms[1],
        v(20.0, 0.0, 0.0),
        v(10.0, 0.0, 0.0),
        v(15.0, 0.0, 0.0),
        axis_g17(),
        PI,
    );
}

#[test]
fn centre_words_are_incremental_and_ignore_g90_g91() {
    let ms = moves(D, "G01 X10 F100\nG90 G03 X0 Y10 I-10 J0\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(0.0, 10.0, 0.0),
        o(),
        axis_g17(),
        FRAC_PI_2,
    );
    let ms = moves(D, "G01 X10 F100\nG91 G03 X-10 Y10 I-10 J0\n");
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
fn full_circle_with_end_omitted_or_equal() {
    let ms = moves(D, "G01 X10 F100\nG02 I-10\nG03 X10 Y0 I-10 J0\n");
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
fn radius_arcs_plus_and_minus() {
    let cases = [
        ("G02 X10 Y10 R10", v(10.0, 0.0, 0.0), -FRAC_PI_2),
        ("G02 X10 Y10 R-10", v(0.0, 10.0, 0.0), -1.5 * PI),
        ("G03 X10 Y10 R10", v(0.0, 10.0, 0.0), FRAC_PI_2),
        ("G03 X10 Y10 R-10", v(10.0, 0.0, 0.0), 1.5 * PI),
    ];
    for (block, center, sweep) in cases {
        let ms = moves(D, &format!("F100\n{block}\n"));
        assert_arc(&ms[0], o(), v(10.0, 10.0, 0.0), center, axis_g17(), sweep);
    }
}

#[test]
fn radius_cannot_make_a_full_circle() {
    // [M] R cannot program a full circle.
    let d = error(D, "G01 X10 F100\nG02 X10 Y0 R5\n");
    assert_eq!(d.line, 2, "{d}");
}

#[test]
fn arcs_in_g18_and_g19_and_polar_arc_in_g18() {
    let ms = moves(D, "G01 X10 F100\nG18 G02 X0 Z10 I-10 K0\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(0.0, 0.0, 10.0),
        o(),
        axis_g18(),
        -FRAC_PI_2,
    );
    let ms = moves(D, "G01 Y10 F100\nG19 G03 Y0 Z10 J-10 K0\n");
    assert_arc(
        &ms[1],
        v(0.0, 10.0, 0.0),
        v(0.0, 0.0, 10.0),
        o(),
        axis_g19(),
        FRAC_PI_2,
    );
    // Seed 000: in G18 the centre is I K. The polar angle is measured from the plane's
    // abscissa; for G18 (ZX) that is Z, so Q90 points along +X. From (Z10) about the origin
    // to Q90: a quarter turn from +Z to +X, +90° about +Y.
    let ms = moves(D, "G18\nG01 Z10 F100\nG03 R10 Q90 I0 K-10\n");
    assert_arc(
        &ms[1],
        v(0.0, 0.0, 10.0),
        v(10.0, 0.0, 0.0),
        o(),
        axis_g18(),
        FRAC_PI_2,
    );
}

#[test]
fn helix() {
    let ms = moves(D, "G01 X10 F100\nG03 X-10 Y0 Z-6 I-10 J0\n");
    assert_arc(
        &ms[1],
        v(10.0, 0.0, 0.0),
        v(-10.0, 0.0, -6.0),
        o(),
        axis_g17(),
        PI,
    );
}

#[test]
fn inch_g70_and_metric_g71() {
    // [S] G70 inch / G71 mm.
    let ms = moves(D, "G70\nG01 X1 Y2 F10\nG71\nG01 X0 F100\n");
    assert_point("inch end", ms[0].path.end(), v(25.4, 50.8, 0.0), TOL);
    assert_feed_line(&ms[1], v(25.4, 50.8, 0.0), v(0.0, 50.8, 0.0), 100.0);
}

#[test]
fn syntax_header_comments_and_long_block_numbers() {
    // [S] `%name` header, `;` comments, N up to 4294967295.
    let ms = moves(
        D,
        "%PART\n; comment line\nN4294967295 G01 X5 F100 ; trailing comment X99\nN1 Y5\n",
    );
    assert_eq!(ms.len(), 2);
    assert_feed_line(&ms[0], o(), v(5.0, 0.0, 0.0), 100.0);
    assert_feed_line(&ms[1], v(5.0, 0.0, 0.0), v(5.0, 5.0, 0.0), 100.0);
    assert_eq!(ms[0].line, 3);
}

#[test]
fn rotary_axes_are_carried() {
    let ms = moves(D, "G01 X10 C90 F100\n");
    assert_eq!(ms[0].abc_deg, Some(([0.0; 3], [0.0, 0.0, 90.0])));
}

#[test]
fn events_in_program_order() {
    let its = items(D, "T3 M6\nS900 M4\nM8\nG01 X1 F100\nM9\nM5\nM2\n");
    let codes: Vec<&str> = its
        .iter()
        .map(|i| match i {
            Item::Event(e) => e.code.as_str(),
            Item::Move(_) => "move",
        })
        .collect();
    assert_eq!(
        codes,
        ["T", "M6", "S", "M4", "M8", "move", "M9", "M5", "M2"]
    );
}

#[test]
fn radius_too_small_and_end_off_circle_are_errors() {
    let d = error(D, "F100\nG02 X20 Y0 R5\n");
    assert_diag_line(&d, 2, &["radius too small to reach end point"]);
    let d = error(D, "G01 X10 F100\nG03 X0 Y15 I-10 J0\n");
    assert_eq!(d.line, 2, "{d}");
}

#[test]
fn cutter_compensation() {
    let zero = settings_with_tool(1, 0.0, 0.0);
    let with = moves_with(D, zero.clone(), "T1 M6\nG41 G01 X10 F100\nG40 X0\n");
    let without = moves_with(D, zero, "T1 M6\nG01 X10 F100\nX0\n");
    assert_same_moves("G41 with radius 0", &with, &without, TOL);
    let d = error_with(
        D,
        settings_with_tool(1, 0.0, 2.0),
        "T1 M6\nG42 G01 X10 F100\n",
    );
    assert_diag(&d, 2, 1, &["cutter compensation"]);
}

#[test]
fn arc_end_point_tolerance_is_configurable() {
    let src = "G01 X10 F100\nG03 X0 Y10.5 I-10 J0\n";
    assert!(
        run(D, src).is_err(),
        "0.5 mm on r = 10 is outside the default tolerance"
    );
    let loose = Settings {
        arc_tolerance_mm: 1.0,
        ..Settings::default()
    };
    let items = run_with(D, loose, src).unwrap_or_else(|e| panic!("tolerance 1 mm: {e}"));
    let m = only_moves(&items);
    assert_point("end point exact", m[1].path.end(), v(0.0, 10.5, 0.0), 1e-9);
    assert!(run(D, "G01 X10 F100\nG03 X0 Y10.01 I-10 J0\n").is_ok());
}

#[test]
fn polar_origin_is_part_zero_by_default() {
    // [M] The polar origin defaults to part zero: moving first does not change it.
    let ms = moves(D, "G01 X30 Y30 F100\nG01 R10 Q0\n");
    assert_feed_line(&ms[1], v(30.0, 30.0, 0.0), v(10.0, 0.0, 0.0), 100.0);
}

#[test]
fn dwell_k_makes_no_motion() {
    // G04 K is a dwell in seconds: K is not the centre word there, and nothing moves.
    let ms = moves(D, "G01 X1 F100\nG04 K1.5\nG01 X2\n");
    assert_eq!(ms.len(), 2, "{ms:#?}");
    assert_feed_line(&ms[1], v(1.0, 0.0, 0.0), v(2.0, 0.0, 0.0), 100.0);
}

#[test]
fn polar_values_are_measured_again_after_part_zero_moves() {
    // [M] Without G30 the polar origin is part zero; a missing R or Q keeps the value of
    // the last point about the polar origin. After G55 (part zero at (0, 10)) the point
    // (10, 0) is at 10√2 mm, -45° about the new part zero, so `Q90` -> (0, 10 + 10√2) and,
    // in G91, `Q45` -> (10√2, 10). By hand, machine mm.
    let mut s = Settings::default();
    s.work_offsets_mm[1] = [0.0, 10.0, 0.0];
    let r = 200f64.sqrt();
    let ms = moves_with(D, s.clone(), "G01 R10 Q0 F100\nG55\nG01 Q90\n");
    assert_feed_line(&ms[1], v(10.0, 0.0, 0.0), v(0.0, 10.0 + r, 0.0), 100.0);
    let ms = moves_with(D, s.clone(), "G01 R10 Q0 F100\nG55\nG91 G01 Q45\n");
    assert_feed_line(&ms[1], v(10.0, 0.0, 0.0), v(r, 10.0, 0.0), 100.0);
    // `R5` keeps the angle -45°: (5 cos -45°, 10 + 5 sin -45°).
    let ms = moves_with(D, s, "G01 R10 Q0 F100\nG55\nG01 R5\n");
    let h = 5.0 * 0.5f64.sqrt();
    assert_feed_line(&ms[1], v(10.0, 0.0, 0.0), v(h, 10.0 - h, 0.0), 100.0);
}
