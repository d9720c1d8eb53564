//! LinuxCNC offsets, reference positions and tool data: expected values from the LinuxCNC
//! manual's examples and from rs274's canonical calls for the same lines, worked out by
//! hand into machine millimetres (machine = G5x + R(program + G92) + tool offset).
//! The golden programs of tests/data/ngc/offsets/ cover the same codes against rs274.

use std::f64::consts::FRAC_PI_2;

use kerf_gcode::{Dialect, Interpreter, Settings, Tool};
use kerf_tests::*;

const D: Dialect = Dialect::LinuxCnc;

fn o() -> Vec3 {
    v(0.0, 0.0, 0.0)
}

/// The persistent parameters after running `src` to its end. The program is put between
/// `%` lines (a LinuxCNC program ends with M2/M30 or its closing `%`; M2 would select G54
/// again, the closing `%` changes nothing).
fn params_after(settings: Settings, src: &str) -> Vec<(u32, f64)> {
    let src = format!("%\n{src}\n%\n");
    let mut it = Interpreter::new(src.as_bytes(), D, settings);
    for item in it.by_ref() {
        if let Err(e) = item {
            panic!("program rejected: {e}\n{src}");
        }
    }
    it.persistent_parameters()
}

fn param(params: &[(u32, f64)], n: u32) -> f64 {
    params
        .iter()
        .find(|(k, _)| *k == n)
        .map(|(_, v)| *v)
        .unwrap_or_else(|| panic!("#{n} is not persistent"))
}

fn tool(number: u32, xyz: [f64; 3], radius_mm: f64) -> Tool {
    Tool {
        number,
        length_mm: xyz[2],
        radius_mm,
        offset_xy_mm: [xyz[0], xyz[1]],
        ..Tool::default()
    }
}

#[test]
fn g10_l2_sets_the_offset_of_the_named_system_in_its_parameters() {
    // Manual: "G10 L2 P1 X3.5 Y17.2": the origin of G54 becomes X=3.5 Y=17.2, other
    // coordinates unchanged; #5221.. hold it. Under G20 the values are inches.
    let ms = moves(
        D,
        "G10 L2 P1 X3.5 Y17.2\nG0 X0 Y0 Z1\nG10 L2 P2 Z2\nG55 G0 Z0\n",
    );
    assert_rapid(&ms[0], o(), v(3.5, 17.2, 1.0));
    // Only Z is named: X and Y stay where they are on the machine.
    assert_rapid(&ms[1], v(3.5, 17.2, 1.0), v(3.5, 17.2, 2.0));
    let p = params_after(Settings::default(), "G20 G10 L2 P3 X1 R30\nG10 L2 P0 Y1\n");
    assert_eq!(param(&p, 5261), 25.4);
    assert_eq!(param(&p, 5270), 30.0);
    assert_eq!(param(&p, 5222), 25.4, "P0 is the active system, G54");
}

#[test]
fn g10_l20_makes_the_current_point_read_the_given_coordinates() {
    // Manual: "G10 L20 P1 X1.5 (set the X axis current location in coordinate system 1 to
    // 1.5)". At machine X 4 the G54 X offset becomes 2.5 (rs274: SET_G5X_OFFSET(1, 2.5..)).
    let ms = moves(D, "G0 X4\nG10 L20 P1 X1.5\nG0 X0\n");
    assert_rapid(&ms[1], v(4.0, 0.0, 0.0), v(2.5, 0.0, 0.0));
    // With a G92 offset in effect (rs274: G92 X0 at 1, G10 L20 P1 X5 gives -5).
    let p = params_after(Settings::default(), "G0 X1\nG92 X0\nG10 L20 P1 X5\n");
    assert_eq!(param(&p, 5221), -5.0);
}

#[test]
fn g10_l2_r_rotates_lines_and_arcs_about_the_system_origin() {
    // R90 about G54's origin (10, 5): program (10, 0) is machine (10, 15); the arc from
    // there, centre program (0, 0), to program (0, 10) becomes an arc about (10, 5).
    let ms = moves(
        D,
        "G10 L2 P1 X10 Y5 R90\nG0 X10 Y0\nG3 X0 Y10 I-10 J0 F100\nG0 X0 Y0\n",
    );
    assert_rapid(&ms[0], o(), v(10.0, 15.0, 0.0));
    assert_arc(
        &ms[1],
        v(10.0, 15.0, 0.0),
        v(0.0, 5.0, 0.0),
        v(10.0, 5.0, 0.0),
        axis_g17(),
        FRAC_PI_2,
    );
    assert_rapid(&ms[2], v(0.0, 5.0, 0.0), v(10.0, 5.0, 0.0));
}

#[test]
fn g92_family_follows_linuxcnc_parameters() {
    // Manual G92: "suppose the current point is at X=4 ... G92 X7 ... This -3 is saved in
    // parameter 5211."
    let p = params_after(Settings::default(), "G0 X4\nG92 X7\n");
    assert_eq!((param(&p, 5210), param(&p, 5211)), (1.0, -3.0));
    // G92.2 turns the offset off and keeps #5211; G92.3 applies it again; G92.1 zeroes it.
    let ms = moves(
        D,
        "G0 X4\nG92 X7\nG92.2\nG0 X0\nG92.3\nG0 X7\nG92.1\nG92.3\nG0 X1\n",
    );
    assert_rapid(&ms[1], v(4.0, 0.0, 0.0), v(0.0, 0.0, 0.0));
    assert_rapid(&ms[2], v(0.0, 0.0, 0.0), v(4.0, 0.0, 0.0));
    assert_rapid(&ms[3], v(4.0, 0.0, 0.0), v(1.0, 0.0, 0.0));
    let p = params_after(Settings::default(), "G0 X4\nG92 X7\nG92.2\n");
    assert_eq!((param(&p, 5210), param(&p, 5211)), (0.0, -3.0));
    let p = params_after(Settings::default(), "G0 X4\nG92 X7\nG92.1\n");
    assert_eq!((param(&p, 5210), param(&p, 5211)), (0.0, 0.0));
    // Axes G92 does not name keep the offset in effect (rs274: G92 X0 Y0 at (1, 1), then
    // G92 X5 gives SET_G92_OFFSET(-4, 1)); G52 sets the offset itself.
    let p = params_after(Settings::default(), "G0 X1 Y1\nG92 X0 Y0\nG92 X5\n");
    assert_eq!((param(&p, 5211), param(&p, 5212)), (-4.0, 1.0));
    let p = params_after(Settings::default(), "G0 X1 Y1\nG92 X0 Y0\nG52 X3\n");
    assert_eq!((param(&p, 5211), param(&p, 5212)), (3.0, 1.0));
}

#[test]
fn g28_and_g30_go_through_the_intermediate_point_then_the_named_axes_home() {
    // Manual: "G28 Z2.5 (rapid to Z2.5 then to Z location specified in #5163)".
    let s = Settings {
        g28_home_mm_deg: [100.0, 50.0, 20.0, 0.0, 0.0, 0.0],
        g30_home_mm_deg: [-1.0, -2.0, -3.0, 0.0, 0.0, 0.0],
        ..Settings::default()
    };
    let ms = moves_with(D, s.clone(), "G0 X1 Y2 Z3\nG28 Z2.5\nG28\nG30 X0\n");
    assert_eq!(ms.len(), 6);
    assert_rapid(&ms[1], v(1.0, 2.0, 3.0), v(1.0, 2.0, 2.5));
    assert_rapid(&ms[2], v(1.0, 2.0, 2.5), v(1.0, 2.0, 20.0));
    assert_rapid(&ms[3], v(1.0, 2.0, 20.0), v(100.0, 50.0, 20.0));
    assert_rapid(&ms[4], v(100.0, 50.0, 20.0), v(0.0, 50.0, 20.0));
    assert_rapid(&ms[5], v(0.0, 50.0, 20.0), v(-1.0, 50.0, 20.0));
    // The CAM idiom `G91 G28 Z0`: no intermediate motion, Z home.
    let ms = moves_with(D, s.clone(), "G0 X1 Y2 Z3\nG91 G28 Z0\n");
    assert_eq!(ms.len(), 2);
    assert_rapid(&ms[1], v(1.0, 2.0, 3.0), v(1.0, 2.0, 20.0));
    // G28.1 / G30.1 store the current absolute position (machine coordinates).
    let p = params_after(s, "G10 L2 P1 X5\nG0 X1 Y2 Z3\nG28.1\nG0 X0\nG30.1\n");
    assert_eq!(
        [param(&p, 5161), param(&p, 5162), param(&p, 5163)],
        [6.0, 2.0, 3.0]
    );
    assert_eq!(
        [param(&p, 5181), param(&p, 5182), param(&p, 5183)],
        [5.0, 2.0, 3.0]
    );
}

#[test]
fn tool_offsets_apply_every_axis_of_the_entry() {
    let s = Settings {
        tools: vec![
            tool(1, [0.0, 0.0, 10.0], 3.0),
            tool(2, [1.0, 2.0, 20.0], 5.0),
        ],
        ..Settings::default()
    };
    // rs274: T2 M6 G43 gives USE_TOOL_LENGTH_OFFSET(1 2 20); program (0, 0, 0) is machine
    // (1, 2, 20). G43.2 H1 adds tool 1: (1, 2, 30). G43.1 Z4 replaces Z: (1, 2, 4). An
    // offset moves nothing by itself: an axis takes it when a move names it (rs274 shows
    // the unnamed Z's program coordinate change instead).
    let ms = moves_with(
        D,
        s.clone(),
        "T2 M6\nG43\nG0 X0 Y0 Z0\nG43.2 H1\nG0 X1\nG43.1 Z4\nG0 X0\nG49\nG0 Y0\n",
    );
    assert_rapid(&ms[0], o(), v(1.0, 2.0, 20.0));
    assert_rapid(&ms[1], v(1.0, 2.0, 20.0), v(2.0, 2.0, 20.0));
    assert_rapid(&ms[2], v(2.0, 2.0, 20.0), v(1.0, 2.0, 20.0));
    assert_rapid(&ms[3], v(1.0, 2.0, 20.0), v(1.0, 0.0, 20.0));
    // Manual G43.1: with tool 1 (Z 10) loaded and applied, "G43.1 Z0.250 (offset current
    // tool offset by 0.250 ...)": Z0 is then machine 0.25.
    let ms = moves_with(D, s.clone(), "T1 M6 G43\nG43.1 Z0.25\nG0 Z0\n");
    assert_rapid(&ms[0], o(), v(0.0, 0.0, 0.25));
    // Manual G10 L10: "T1 M6 G43 / G10 L10 P1 Z1.5 / G43": the current Z reads 1.5.
    let ms = moves_with(
        D,
        s.clone(),
        "G0 Z30\nT1 M6 G43\nG10 L10 P1 Z1.5\nG43\nG0 Z1.5\nG0 Z0\n",
    );
    // rs274 reads the point back after `T1 M6 G43` as program Z 30 (the new offset not
    // counted), so L10 makes the offset 38.5 and Z1.5 is machine 40: it prints
    // STRAIGHT_TRAVERSE(0, 0, 1.5) and (0, 0, 0), machine 40 and 38.5.
    assert_eq!(ms.len(), 3);
    assert_rapid(&ms[1], v(0.0, 0.0, 30.0), v(0.0, 0.0, 40.0));
    assert_rapid(&ms[2], v(0.0, 0.0, 40.0), v(0.0, 0.0, 38.5));
    // G10 L11 measures against G59.3 without G92 (rs274: with G59.3 Z0 and the tool at
    // machine Z 9, L11 P1 Z2 sets Z 7); G10 L1 sets the value itself.
    let ms = moves_with(
        D,
        s,
        "G10 L2 P1 Z5\nG92 Z0\nG0 Z9 X0\nG10 L11 P1 Z2\nG43 H1\nG0 X1 Z9\nG10 L1 P1 Z-1 R2\nG43 H1\nG0 X2 Z9\n",
    );
    // After G92 Z0 at machine 0, Z9 is machine 9; with Z offset 7 the same program Z9
    // is machine 16; with -1, machine 8.
    assert_rapid(&ms[1], v(0.0, 0.0, 9.0), v(1.0, 0.0, 16.0));
    assert_rapid(&ms[2], v(1.0, 0.0, 16.0), v(2.0, 0.0, 8.0));
}

#[test]
fn g53_moves_in_machine_coordinates() {
    // Manual G53: "G53 G0 X0 Y0 Z0 will move the axes to the home position even if the
    // currently selected coordinate system has offsets in effect."
    let s = Settings {
        work_offsets_mm: [[10.0, 20.0, 30.0]; 9],
        ..Settings::default()
    };
    let ms = moves_with(
        D,
        s,
        "G0 X1 Y1 Z1\nG92 X0\nG53 G0 X0 Y0 Z0\nG53 G1 X2 F100\n",
    );
    assert_rapid(&ms[1], v(11.0, 21.0, 31.0), o());
    assert_feed_line(&ms[2], o(), v(2.0, 0.0, 0.0), 100.0);
    // Under a rotated system the unnamed axes stay where they are on the machine (rs274:
    // R45, G0 X1, G53 G0 Y0 ends at machine (0.7071, 0)).
    let ms = moves(D, "G10 L2 P1 R45\nG0 X1\nG53 G0 Y0\n");
    let h = std::f64::consts::FRAC_1_SQRT_2;
    assert_rapid(&ms[1], v(h, h, 0.0), v(h, 0.0, 0.0));
}

#[test]
fn rotary_offsets_are_degrees() {
    let ms = moves(D, "G10 L2 P1 A10\nG0 A0\nG92 A5\nG0 A0\n");
    assert_eq!(ms[0].abc_deg, Some(([0.0; 3], [10.0, 0.0, 0.0])));
    assert_eq!(ms[1].abc_deg, Some(([10.0, 0.0, 0.0], [5.0, 0.0, 0.0])));
}

#[test]
fn parameters_restored_at_start_and_program_end_values() {
    // A parameter file that names G56 (#5220 = 3) with X offset #5261 = 7 starts there.
    let s = Settings {
        parameters: vec![(5220, 3.0), (5261, 7.0)],
        ..Settings::default()
    };
    let ms = moves_with(D, s.clone(), "G0 X1\n");
    assert_rapid(&ms[0], o(), v(8.0, 0.0, 0.0));
    // LinuxCNC's M2 selects G54 again: #5220 = 1 is what the file keeps.
    let p = params_after(s.clone(), "G0 X1\nM2\n");
    assert_eq!((param(&p, 5220), param(&p, 5261)), (1.0, 7.0));
    let p = params_after(s, "G0 X1\n");
    assert_eq!(param(&p, 5220), 3.0);
    // Settings fill the parameters: work offsets and stored positions.
    let s = Settings {
        work_offsets_mm: [[1.0, 2.0, 3.0]; 9],
        g30_home_mm_deg: [4.0, 5.0, 6.0, 7.0, 8.0, 9.0],
        ..Settings::default()
    };
    let p = params_after(s, "");
    assert_eq!(
        [param(&p, 5381), param(&p, 5382), param(&p, 5383)],
        [1.0, 2.0, 3.0]
    );
    assert_eq!(param(&p, 5186), 9.0);
    assert_eq!(p.len(), 9 + 9 + 11 + 9 * 10);
}

#[test]
fn offset_errors_in_linuxcncs_words() {
    let s = || Settings {
        tools: vec![tool(1, [0.0, 0.0, 10.0], 0.0)],
        ..Settings::default()
    };
    // (program, line, column, rs274's message)
    let cases: [(&str, u32, u32, &str); 16] = [
        (
            "G10 P1 X1\n",
            1,
            1,
            "Line with G10 does not have L0, L1, L10, L11, L2, or L20",
        ),
        (
            "G10 L3 P1 X1\n",
            1,
            5,
            "Line with G10 does not have L0, L1, L10, L11, L2, or L20",
        ),
        (
            "G10 L2 X1\n",
            1,
            1,
            "P value out of range (0-9) with G10 L2",
        ),
        (
            "G10 L2 P10 X1\n",
            1,
            8,
            "P value out of range (0-9) with G10 L2",
        ),
        ("G10 L1 P0 Z1\n", 1, 8, "P value out of range with G10 L1"),
        (
            "G10 L1 P9 Z1\n",
            1,
            8,
            "Requested tool 9 not found in the tool table",
        ),
        ("G10 L20 P1 R3 X1\n", 1, 12, "R not allowed in G10 L20"),
        ("G91 G53 G0 X1\n", 1, 5, "Cannot use g53 incremental"),
        ("G2 G53 X1 I1\n", 1, 4, "Must use g0 or g1 with g53"),
        (
            "G28 G0 X1\n",
            1,
            1,
            "Cannot use two g codes that both use axis values",
        ),
        (
            "G41\nG28\n",
            2,
            1,
            "Cannot use g28 or g30 with cutter radius comp",
        ),
        ("G92\n", 1, 1, "All axes missing with g52 or g92"),
        (
            "G43.2\n",
            1,
            1,
            "G43.2: No axes specified and H word missing",
        ),
        (
            "G43.2 H1 Z1\n",
            1,
            10,
            "G43.2: Can not have both H and axis words",
        ),
        (
            "M61\n",
            1,
            1,
            "Need non-negative Q-word to specify tool number with M61",
        ),
        (
            "G0 L2 X1\n",
            1,
            4,
            "L word with no G10, cutter compensation, canned cycle",
        ),
    ];
    for (src, line, col, message) in cases {
        let d = error_with(D, s(), src);
        assert_eq!((d.line, d.col), (line, col), "{src:?}: {}", d.message);
        assert!(d.message.starts_with(message), "{src:?}: {}", d.message);
    }
    // A refused block moves nothing.
    let r = run_with(D, s(), "G0 X1\nG28 G0 X5\nG0 X9\n");
    assert!(r.is_err());
}

/// `T1 M6 G43 H1` in one block moves as `T1 M6` then `G43 H1` (golden
/// `offsets/g43_after_m6`, where rs274 agrees): G43 moves nothing, so the next move without
/// Z keeps the machine Z. This is LinuxCNC's behaviour (after a tool change it reads its
/// position back as the machine position less the offsets now in force, the new tool length
/// included); the standalone rs274 differs for the one-block form only, as its canon stub
/// reads back the last printed program point (LinuxCNC's skeleton.ngc and mmount.ngc: the
/// harness reports them as mismatches, see docs/linuxcnc/harness.md).
#[test]
fn after_m6_the_point_is_read_back_as_rs274_reads_it() {
    let s = Settings {
        tools: vec![Tool {
            number: 1,
            length_mm: 12.9794,
            ..Tool::default()
        }],
        ..Settings::default()
    };
    // rs274 (tool 1 = 0.511 in): `T1 M6 G43 H1` then `G0 X1 Y1` prints
    // STRAIGHT_TRAVERSE(1, 1, 0): after the tool change it reads its point back from the
    // last point it printed, program Z 0, in which the new offset is not counted, so the
    // machine rises by the tool length. With G43 in the next block the point is read back
    // first, and G43 then changes the program Z (-0.511): the machine Z stays.
    let one = moves_with(
        D,
        s.clone(),
        "G20\nG53 G0 Z0\nT1 M6 G43 H1\nG0 X1 Y1\nG0 Z0.25\n",
    );
    let two = moves_with(D, s, "G20\nG53 G0 Z0\nT1 M6\nG43 H1\nG0 X1 Y1\nG0 Z0.25\n");
    // (G53 G0 Z0 from the origin moves nothing.)
    assert_eq!(one.len(), 2);
    assert_eq!(two.len(), 2);
    assert_rapid(&one[0], v(0.0, 0.0, 0.0), v(25.4, 25.4, 12.9794));
    assert_rapid(&two[0], v(0.0, 0.0, 0.0), v(25.4, 25.4, 0.0));
    // Z0.25 lands the tool tip 0.25" above zero either way.
    assert_rapid(
        &one[1],
        v(25.4, 25.4, 12.9794),
        v(25.4, 25.4, 6.35 + 12.9794),
    );
    assert_rapid(&two[1], v(25.4, 25.4, 0.0), v(25.4, 25.4, 6.35 + 12.9794));
}
