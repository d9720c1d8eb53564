//! Unit tests of the interpreter against values worked out by hand from the manuals.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use crate::{Diagnostic, Dialect, EventCode, Interpreter, Item, Move, Path, Settings, Tool, Vec3};

/// Runs `src`; a LinuxCNC program, which must end with M2/M30 or its closing `%`, is given
/// an `M2` line at its end (after the program's own end it is never read).
fn run_with(d: Dialect, src: &str, settings: Settings) -> Result<Vec<Item>, Diagnostic> {
    if d == Dialect::LinuxCnc {
        let sep = if src.is_empty() || src.ends_with('\n') {
            ""
        } else {
            "\n"
        };
        let ended = format!("{src}{sep}M2\n");
        let added_line = u32::try_from(ended.lines().count()).unwrap_or(u32::MAX);
        let mut items: Vec<Item> =
            Interpreter::new(ended.as_bytes(), d, settings).collect::<Result<_, _>>()?;
        if let Some(Item::Event(e)) = items.last()
            && e.code == EventCode::M2
            && e.line == added_line
        {
            items.pop();
        }
        return Ok(items);
    }
    Interpreter::new(src.as_bytes(), d, settings).collect()
}

fn run(d: Dialect, src: &str) -> Vec<Item> {
    match run_with(d, src, Settings::default()) {
        Ok(items) => items,
        Err(e) => panic!("{d:?}: unexpected error {e}\n{src}"),
    }
}

fn moves(d: Dialect, src: &str) -> Vec<Move> {
    run(d, src)
        .into_iter()
        .filter_map(|i| match i {
            Item::Move(m) => Some(m),
            Item::Event(_) => None,
        })
        .collect()
}

fn error(d: Dialect, src: &str) -> Diagnostic {
    match run_with(d, src, Settings::default()) {
        Ok(items) => panic!("{d:?}: expected an error, got {items:?}"),
        Err(e) => e,
    }
}

fn v(x: f64, y: f64, z: f64) -> Vec3 {
    Vec3::new(x, y, z)
}

#[track_caller]
fn near(a: Vec3, b: Vec3) {
    assert!((a - b).norm() < 1e-9, "{a:?} != {b:?}");
}

#[track_caller]
fn line_to(m: &Move, end: Vec3) {
    match m.path {
        Path::Line(l) => near(l.end, end),
        Path::Arc(a) => panic!("expected a line to {end:?}, got {a:?}"),
    }
}

#[track_caller]
fn arc_of(m: &Move) -> kerf_geom::Arc {
    match m.path {
        Path::Arc(a) => a,
        Path::Line(l) => panic!("expected an arc, got {l:?}"),
    }
}

#[test]
fn heidenhain_seed_polar_example() {
    // TNC 410 ISO manual, polar lines and circles: pole 45,45; R30 at 0°, 60°, +60° (G91),
    // 180°; then pole 25,25, R20 at 0°, and G13 to H+180 about the pole.
    let src = "%SEED G71 *\nN120 I+45 J+45 *\nN130 G11 G42 R+30 H+0 F300 M3 *\nN140 H+60 *\n\
               N150 G91 H+60 *\nN160 G90 H+180 *\nN180 I+25 J+25 *\n\
               N190 G11 G42 R+20 H+0 F250 M3 *\nN200 G13 H+180 *\nN99999 %SEED G71 *\n";
    let items = run(Dialect::Heidenhain, src);
    let s3 = 3f64.sqrt();
    let m: Vec<Move> = items
        .iter()
        .filter_map(|i| {
            if let Item::Move(m) = i {
                Some(*m)
            } else {
                None
            }
        })
        .collect();
    assert_eq!(m.len(), 6);
    line_to(&m[0], v(75.0, 45.0, 0.0));
    assert_eq!(m[0].feed_mm_min, Some(300.0));
    line_to(&m[1], v(45.0 + 15.0, 45.0 + 15.0 * s3, 0.0));
    line_to(&m[2], v(45.0 - 15.0, 45.0 + 15.0 * s3, 0.0));
    line_to(&m[3], v(15.0, 45.0, 0.0));
    line_to(&m[4], v(45.0, 25.0, 0.0));
    let a = arc_of(&m[5]);
    near(a.start, v(45.0, 25.0, 0.0));
    near(a.end, v(5.0, 25.0, 0.0));
    near(a.center, v(25.0, 25.0, 0.0));
    assert!((a.sweep_rad - PI).abs() < 1e-12);
    assert_eq!(m[5].feed_mm_min, Some(250.0));
    // M3 comes before the motion of its block.
    assert!(matches!(&items[0], Item::Event(e) if e.code == EventCode::M3 && e.line == 3));
    assert!(matches!(items[1], Item::Move(m) if m.line == 3));
}

#[test]
fn heidenhain_multi_turn_and_incremental_polar_circles() {
    let src = "%P G71 *\nI+0 J+0 *\nG11 R+10 H+0 F100 *\nG91 G13 H+720 Z-2 *\nG12 G91 H-90 *\nG12 G91 H+90 *\n";
    let d = Dialect::Heidenhain;
    let e = error(d, src);
    assert_eq!((e.line, e.col), (6, 9), "{e}");
    let m = moves(d, &src[..src.len() - "G12 G91 H+90 *\n".len()]);
    let a = arc_of(&m[1]);
    assert!((a.sweep_rad - 2.0 * TAU).abs() < 1e-12);
    near(a.end, v(10.0, 0.0, -2.0));
    let a = arc_of(&m[2]);
    assert!((a.sweep_rad + FRAC_PI_2).abs() < 1e-12);
    near(a.end, v(0.0, -10.0, -2.0));
}

#[test]
fn heidenhain_per_axis_distance_mode_and_centre() {
    // Start at 10,0; centre 0,0; G02 G91 X+5 G90 Y-5: X is incremental (15? no: 10-? ) —
    // X+5 incremental from 10 is 15, which is not on the circle; use X-10 G90 Y-10 instead.
    let src = "%P G71 *\nG00 X+10 Y+0 *\nI+0 J+0 *\nG02 G91 X-10 G90 Y-10 F100 *\n";
    let m = moves(Dialect::Heidenhain, src);
    let a = arc_of(&m[1]);
    near(a.end, v(0.0, -10.0, 0.0));
    assert!((a.sweep_rad + FRAC_PI_2).abs() < 1e-12);
}

#[test]
fn fagor_seed_polar_arcs() {
    let src = "%demo\nG90 G17 G01 X10 Y0 F1000\nG91 G03 Q360\nG90 G02 R10 Q-90\n\
               G30 I10 J10\nG01 R5 Q0\nG03 G91 Q90\nN4294967295 M30\n";
    let m = moves(Dialect::Fagor, src);
    let a = arc_of(&m[1]);
    assert!((a.sweep_rad - TAU).abs() < 1e-12);
    near(a.end, v(10.0, 0.0, 0.0));
    near(a.center, v(0.0, 0.0, 0.0));
    let a = arc_of(&m[2]);
    assert!((a.sweep_rad + FRAC_PI_2).abs() < 1e-12);
    near(a.end, v(0.0, -10.0, 0.0));
    line_to(&m[3], v(15.0, 10.0, 0.0));
    let a = arc_of(&m[4]);
    near(a.center, v(10.0, 10.0, 0.0));
    near(a.end, v(10.0, 15.0, 0.0));
    assert!((a.sweep_rad - FRAC_PI_2).abs() < 1e-12);
}

#[test]
fn sinumerik_units_poles_and_turns() {
    let d = Dialect::Sinumerik;
    // G70: positions in inch, F stays mm/min; G700: F in inch/min too.
    let m = moves(d, "G70 G1 X1 F100\nG700 X2 F10\n");
    line_to(&m[0], v(25.4, 0.0, 0.0));
    assert_eq!(m[0].feed_mm_min, Some(100.0));
    assert_eq!(m[1].feed_mm_min, Some(254.0));
    // Pole at 10,10 (G111), RP/AP lines and a circle about the pole.
    let m = moves(
        d,
        "G111 X10 Y10\nG1 RP=5 AP=0 F100\nAP=IC(90)\nG3 AP=180\nG2 AP=IC(-90) TURN=1\n",
    );
    line_to(&m[0], v(15.0, 10.0, 0.0));
    line_to(&m[1], v(10.0, 15.0, 0.0));
    let a = arc_of(&m[2]);
    near(a.center, v(10.0, 10.0, 0.0));
    near(a.end, v(5.0, 10.0, 0.0));
    assert!((a.sweep_rad - FRAC_PI_2).abs() < 1e-12);
    let a = arc_of(&m[3]);
    near(a.end, v(10.0, 15.0, 0.0));
    assert!((a.sweep_rad + FRAC_PI_2 + TAU).abs() < 1e-12);
    // After a pole change RP/AP must be programmed again.
    let e = error(d, "G1 RP=5 AP=0 F100\nG110 X0\nAP=10\n");
    assert_eq!(e.line, 3);
    // CR= cannot make a full circle; I=AC() is absolute.
    let e = error(d, "G1 X10 F100\nG2 X10 CR=5\n");
    assert!(e.message.contains("full circle"), "{e}");
    let m = moves(d, "G1 X10 F100\nG2 X20 I=AC(15) J=AC(0)\n");
    near(arc_of(&m[1]).center, v(15.0, 0.0, 0.0));
}

#[test]
fn linuxcnc_arcs_turns_and_planes() {
    let d = Dialect::LinuxCnc;
    let m = moves(d, "G21 F100\nG1 X10\nG2 X10 Y0 I-10 P3 Z-3\n");
    let a = arc_of(&m[1]);
    assert!((a.sweep_rad + 3.0 * TAU).abs() < 1e-12);
    near(a.end, v(10.0, 0.0, -3.0));
    near(a.center, v(0.0, 0.0, 0.0));
    // G18: from +X to +Z about the origin, seen from +Y that is clockwise (G2).
    let m = moves(d, "F100 G1 X10\nG18 G2 X0 Z10 I-10\n");
    let a = arc_of(&m[1]);
    assert_eq!(a.axis, v(0.0, 1.0, 0.0));
    assert!((a.sweep_rad + FRAC_PI_2).abs() < 1e-12);
    // G19 G3 from +Y to +Z: counter-clockwise seen from +X.
    let m = moves(d, "F100 G1 Y10\nG19 G3 Y0 Z10 J-10\n");
    let a = arc_of(&m[1]);
    assert_eq!(a.axis, v(1.0, 0.0, 0.0));
    assert!((a.sweep_rad - FRAC_PI_2).abs() < 1e-12);
    // G90.1: absolute centre.
    let m = moves(d, "F100 G1 X10\nG90.1 G3 X-10 I0 J0\n");
    assert!((arc_of(&m[1]).sweep_rad - PI).abs() < 1e-12);
}

#[test]
fn linuxcnc_arc_tolerance_rule() {
    let d = Dialect::LinuxCnc;
    // r1 = 10, r2 = 10.02: 0.02 mm < t = 0.02828 mm: accepted and made exact.
    let m = moves(d, "F100 G1 X10\nG3 X0 Y10.02 I-10\n");
    let a = arc_of(&m[1]);
    assert!(((a.start - a.center).norm() - (a.end - a.center).norm()).abs() < 1e-12);
    // r1 = 10, r2 = 10.04: above t and 0.4 % > 0.1 %: rejected.
    let e = error(d, "F100 G1 X10\nG3 X0 Y10.04 I-10\n");
    assert_eq!((e.line, e.col), (2, 14));
    assert!(e.message.starts_with("radius to end of arc differs"), "{e}");
    // r1 = 100, r2 = 100.05: above t but 0.05 % < 0.1 %: accepted.
    moves(d, "F100 G1 X100\nG3 X0 Y100.05 I-100\n");
    // Above 100 t = 2.828 mm: rejected even when relatively small.
    error(d, "F100 G1 X10000\nG3 X0 Y10003 I-10000\n");
    // Radius format: 0.001 mm short of half the chord is a semicircle, 0.002 is an error.
    let m = moves(d, "F100 G2 X10 R4.999\n");
    assert!((arc_of(&m[0]).sweep_rad + PI).abs() < 1e-12);
    let e = error(d, "F100 G2 X10 R4.998\n");
    assert_eq!(e.message, "arc radius too small to reach end point");
}

#[test]
fn linuxcnc_errors_name_the_word() {
    let d = Dialect::LinuxCnc;
    let cases: [(&str, u32, &str); 10] = [
        (
            "G17 G2 X1 Y1 K1 F10",
            14,
            "K word given for arc in XY plane",
        ),
        ("G2 X10 R5 I5 F10", 8, "mixed radius and centre format"),
        ("G1 X1", 1, "Cannot do G1 with zero feed rate"),
        ("G1 X1 F10 X2", 11, "word X repeated"),
        ("G1 G0 X1", 4, "two G codes used from same modal group"),
        ("G12 X1", 1, "unknown G code G12"),
        (
            "G95 G1 X1 F1",
            5,
            "Cannot feed with zero spindle speed in feed per rev mode",
        ),
        ("G1 X#<a> F1", 5, "Named parameter #<a> not defined"),
        (
            "G2 X10 R5 F10\nG2 X10 R5",
            8,
            "current point same as end point of arc",
        ),
        (
            "G1 X1 F1 (unclosed",
            10,
            "unclosed comment: '(' without ')'",
        ),
    ];
    for (src, col, msg) in cases {
        let e = error(d, src);
        assert_eq!((e.col, e.message.as_str()), (col, msg), "{src}");
    }
    assert_eq!(
        error(d, "F1\nG1 X1\n\nG1 X1e3").to_string(),
        "4:6: error: E word with no G70, G76, M66, M67 or M68 to use it"
    );
    // The other dialects have no E word.
    assert_eq!(
        error(Dialect::Rockwell, "F1\nG1 X1e3").to_string(),
        "2:6: error: unknown word E"
    );
}

#[test]
fn a_refused_m_code_is_named_before_any_other_error_of_its_block() {
    let d = Dialect::LinuxCnc;
    for (src, col, code) in [
        ("X1 X2 M98 P100", 7, "M98"),
        ("U1 M99", 4, "M99"),
        ("M3 M5 M98", 7, "M98"),
        ("M0 M1 M2 M3 M5 M6 M7 M8 M9 M99", 28, "M99"),
        ("M0.5 M98", 6, "M98"),
        ("M99 M98", 1, "M99"),
    ] {
        let e = error(d, src);
        assert_eq!(e.col, col, "{src}: {e}");
        assert!(
            e.message.starts_with(&format!("{code} is not supported")),
            "{src}: {e}"
        );
    }
    assert_eq!(error(d, "X1 X2 M3").message, "word X repeated");
}

#[test]
fn nothing_after_a_failing_block() {
    // Rockwell: `;` ends a block; the first block of the line is produced, the failing
    // second one and everything after it is not.
    let mut it = Interpreter::new(
        "G01 X1 F100 ; G02 X2 Y1 K1 ; G01 X3 ;\nG01 X4 ;\n".as_bytes(),
        Dialect::Rockwell,
        Settings::default(),
    );
    assert!(matches!(it.next(), Some(Ok(Item::Move(_)))));
    let e = it.next().unwrap().unwrap_err();
    assert_eq!((e.line, e.col), (1, 25));
    assert!(it.next().is_none());
    assert!(it.next().is_none());
}

#[test]
fn rockwell_radius_rules() {
    let d = Dialect::Rockwell;
    // R with end = start: a 0° arc, no motion and no error.
    let m = moves(d, "G01 X10 F100 ; G02 X10 Y0 R5 ; G01 X20 ;");
    assert_eq!(m.len(), 2);
    // R wins over I J K.
    let m = moves(d, "G01 X10 F100 ; G02 X20 Y0 R5 I99 J99 ;");
    near(arc_of(&m[1]).center, v(15.0, 0.0, 0.0));
    // I J K always incremental, also under G90; full circle with the end omitted.
    let m = moves(d, "G90 G01 X10 F100 ; G03 I-10 ;");
    let a = arc_of(&m[1]);
    near(a.center, v(0.0, 0.0, 0.0));
    assert!((a.sweep_rad - TAU).abs() < 1e-12);
}

#[test]
fn events_in_execution_order_and_end_of_program() {
    // LinuxCNC refuses a tool that is not in the tool table.
    let mut settings = Settings::default();
    settings.tools.push(Tool {
        number: 3,
        ..Tool::default()
    });
    let items = run_with(
        Dialect::LinuxCnc,
        "G1 X1 F100 M0 M8 T3 M6 S1200 M3\nM30\nG1 X5\n",
        settings,
    )
    .expect("a valid program");
    let codes: Vec<&str> = items
        .iter()
        .map(|i| match i {
            Item::Event(e) => e.code.as_str(),
            Item::Move(_) => "move",
        })
        .collect();
    assert_eq!(codes, ["S", "T", "M6", "M3", "M8", "move", "M0", "M30"]);
    assert!(matches!(&items[0], Item::Event(e) if e.value == Some(1200.0)));
    assert!(matches!(&items[1], Item::Event(e) if e.value == Some(3.0)));
}

#[test]
fn offsets_tools_and_cutter_compensation() {
    let mut s = Settings::default();
    s.work_offsets_mm[1] = [100.0, 50.0, 0.0];
    s.tools.push(Tool {
        number: 2,
        length_mm: 30.0,
        radius_mm: 0.0,
        ..Tool::default()
    });
    s.tools.push(Tool {
        number: 3,
        length_mm: 0.0,
        radius_mm: 5.0,
        ..Tool::default()
    });
    let items = run_with(
        Dialect::LinuxCnc,
        "G55 G0 X1 Y1\nT2 M6 G43\nG0 Z0\nG92 X0 Y0\nG0 X1\nG92.1\nG53 G0 X0 Y0\n",
        s.clone(),
    )
    .unwrap();
    let m: Vec<Move> = items
        .iter()
        .filter_map(|i| {
            if let Item::Move(m) = i {
                Some(*m)
            } else {
                None
            }
        })
        .collect();
    line_to(&m[0], v(101.0, 51.0, 0.0));
    line_to(&m[1], v(101.0, 51.0, 30.0));
    line_to(&m[2], v(102.0, 51.0, 30.0));
    line_to(&m[3], v(0.0, 0.0, 30.0));
    // A non-zero tool radius under G41/G42 is refused outside LinuxCNC (which
    // compensates: tests/gcode/comp.rs); a zero one keeps the path.
    let e = run_with(Dialect::Rockwell, "T3 M6\nG41 G1 X1 F1\n", s.clone()).unwrap_err();
    assert_eq!((e.line, e.col), (2, 1));
    assert!(e.message.starts_with("cutter compensation not supported"));
    assert!(run_with(Dialect::LinuxCnc, "T2 M6\nG41 G1 X1 F1\n", s).is_ok());
}

#[test]
fn rotary_axes_ride_along() {
    let m = moves(
        Dialect::LinuxCnc,
        "F100 G1 X1\nG1 X2 A90\nG91 G3 X-1 Y1 I-1 B10\n",
    );
    assert_eq!(m[0].abc_deg, None);
    assert_eq!(m[1].abc_deg, Some(([0.0; 3], [90.0, 0.0, 0.0])));
    assert_eq!(m[2].abc_deg, Some(([90.0, 0.0, 0.0], [90.0, 10.0, 0.0])));
}

#[test]
fn the_same_part_in_all_five_dialects() {
    // A 20 mm square with a quarter-circle corner of radius 10, at F500.
    let programs = [
        (
            Dialect::LinuxCnc,
            "G21 G90 G17 F500\nG1 X20\nG1 Y10\nG3 X10 Y20 I-10 J0\nG1 X0\nG1 Y0\nM30\n",
        ),
        (
            Dialect::Rockwell,
            "G21 G90 G17 F500 ; G01 X20 ; Y10 ;\nG03 X10 Y20 R10 ; G01 X0 ; Y0 ; M30 ;\n",
        ),
        (
            Dialect::Sinumerik,
            "G71 G90 G17 F500\nG1 X20\nY10\nG3 X10 Y20 CR=10\nG1 X0\nY0\nM30\n",
        ),
        (
            Dialect::Heidenhain,
            "%SQ G71 *\nG01 G90 X+20 F500 *\nY+10 *\nI+10 J+10 *\nG03 X+10 Y+20 *\nG01 X+0 *\nY+0 *\nM30 *\n%SQ G71 *\n",
        ),
        (
            Dialect::Fagor,
            "%sq\nG71 G90 G17 F500\nG01 X20\nY10\nG03 X10 Y20 I-10 J0\nG01 X0\nY0\nM30\n",
        ),
    ];
    let reference = moves(programs[0].0, programs[0].1);
    assert_eq!(reference.len(), 5);
    for (d, src) in programs {
        let m = moves(d, src);
        assert_eq!(m.len(), reference.len(), "{d:?}");
        for (a, b) in m.iter().zip(&reference) {
            assert_eq!(a.feed_mm_min, b.feed_mm_min, "{d:?}");
            near(a.path.start(), b.path.start());
            near(a.path.end(), b.path.end());
            if let (Path::Arc(x), Path::Arc(y)) = (a.path, b.path) {
                near(x.center, y.center);
                assert!((x.sweep_rad - y.sweep_rad).abs() < 1e-12, "{d:?}");
            }
        }
    }
}

#[test]
fn dialect_names_and_paths() {
    use std::path::Path as FsPath;
    for d in Dialect::ALL {
        assert_eq!(Dialect::from_name(d.name()), Some(d));
    }
    assert_eq!(Dialect::from_name("TorMach"), Some(Dialect::LinuxCnc));
    assert_eq!(Dialect::from_name("fanuc"), None);
    assert_eq!(
        Dialect::from_path(FsPath::new("a.NGC"), b""),
        Some(Dialect::LinuxCnc)
    );
    assert_eq!(
        Dialect::from_path(FsPath::new("a.spf"), b""),
        Some(Dialect::Sinumerik)
    );
    assert_eq!(
        Dialect::from_path(FsPath::new("a.h"), b"%PART G71 *\nN10 G00 X+0 *"),
        Some(Dialect::Heidenhain)
    );
    assert_eq!(
        Dialect::from_path(FsPath::new("a.h"), b"0 BEGIN PGM PART MM\n"),
        None
    );
    assert_eq!(
        Dialect::from_path(FsPath::new("a.h"), b"#include <stdio.h>\n"),
        None
    );
    assert_eq!(Dialect::from_path(FsPath::new("a.nc"), b"G0 X1"), None);
    // Fagor's milling programs, whatever their first bytes.
    assert_eq!(
        Dialect::from_path(FsPath::new("pocket.PIM"), b"G71 G90\n"),
        Some(Dialect::Fagor)
    );
    assert_eq!(Dialect::from_path(FsPath::new("a.tap"), b"G0 X1"), None);
    assert_eq!(
        Dialect::from_path(FsPath::new("a.h"), b"/**\n * A C header.\n */\n"),
        None
    );
    assert_eq!(
        Dialect::from_path(FsPath::new("A.I"), b"N10 G00 G90 X+0 *\n"),
        Some(Dialect::Heidenhain)
    );
}

/// A fixed-seed xorshift generator: the fuzz tests need no extra dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
}

#[test]
fn random_bytes_and_mutations_never_panic() {
    let seeds = [
        "G21 G90 F100\nG1 X10 Y5\nG2 X0 Y0 I-5 J-2.5 P2\nG0 @5 ^30\nM30\n",
        "G01 X1 F100 ; G02 X2 Y1 I1 ; G03 R5 X0 ;\n",
        "G111 X1 Y1\nG1 RP=5 AP=IC(30) F10\nG2 X=AC(3) I=IC(1) TURN=2\nG70 G3 CR=-4 X0\n",
        "%P G71 *\nI+1 J+1 *\nG11 R+3 H+10 F10 *\nG13 G91 H+400 *\nG02 X+0 Y+0 R-2 *\n",
        "%f\nG30 I1 J1\nG01 R5 Q30 F10\nG91 G03 Q360\nG02 X1 Y1 R3\n",
        "G20 G55 T1 M6 G43 H1 G0 X1\nG92 X0 Y0\nG53 G0 Z0\nG18 G3 X1 Z1 I1 K0 F5\nG92.2\nG92.3\nG64 P0.1 G61.1\n",
        "%H G70 *\nG99 T2 L+1 R+0 *\nT2 G17 *\nI+5 J+5 *\nG10 R+5 H+0 *\nG12 H-5000 Z+1 F5 *\nG15 G91 H-10 *\nG29 *\nG05 X+1 Y+1 *\n",
        "G17 G112 RP=1 AP=45\nG0 RP=2 AP=0\nG2 AP=IC(90) TURN=3\nG700 F1 G1 X=IC(1)\nG19 G3 Y1 Z1 CR=1\n",
        "G06 G03 X1 Y1 I0 J0 F5\nG18 G30 I1 K1\nG02 Q90 R2\nG91 G01 R1 Q-30\n",
    ];
    let alphabet = b"GXYZIJKRPHQFMST@^#[]()*;%/=.+-0123456789 \n\tACNO\x00\xff\xc3";
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    // More rounds on demand for a longer local fuzzing session.
    let rounds: usize = std::env::var("KERF_FUZZ_ROUNDS")
        .ok()
        .and_then(|r| r.parse().ok())
        .unwrap_or(3000);
    for round in 0..rounds {
        let d = Dialect::ALL[round % 5];
        let mut bytes: Vec<u8> = seeds[round % seeds.len()].as_bytes().to_vec();
        for _ in 0..(rng.next() % 8) {
            let i = (rng.next() as usize) % (bytes.len() + 1);
            let c = alphabet[(rng.next() as usize) % alphabet.len()];
            match rng.next() % 3 {
                0 => bytes.insert(i, c),
                1 if i < bytes.len() => bytes[i] = c,
                _ if i < bytes.len() => {
                    bytes.remove(i);
                }
                _ => {}
            }
        }
        if round % 7 == 0 {
            bytes = (0..(rng.next() % 200)).map(|_| rng.next() as u8).collect();
        }
        let mut it = Interpreter::new(bytes.as_slice(), d, Settings::default());
        let mut errored = false;
        for _ in 0..10_000 {
            match it.next() {
                None => break,
                Some(Err(_)) => errored = true,
                Some(Ok(Item::Move(m))) => {
                    assert!(!errored, "an item after an error");
                    let (s, e) = (m.path.start(), m.path.end());
                    assert!(s.iter().chain(e.iter()).all(|x| x.is_finite()));
                }
                Some(Ok(_)) => assert!(!errored),
            }
        }
    }
}

#[test]
fn moves_chain_from_the_origin() {
    for (d, src) in [
        (Dialect::LinuxCnc, "G0 X1 Y2 Z3\nG1 X4 F10\nG2 X6 Y2 I1\n"),
        (Dialect::Fagor, "G00 X1 Y2 Z3\nG01 X4 F10\nG02 X6 Y2 I1\n"),
    ] {
        let m = moves(d, src);
        near(m[0].path.start(), Vec3::zeros());
        for w in m.windows(2) {
            assert_eq!(w[0].path.end(), w[1].path.start());
        }
    }
}

#[test]
fn heidenhain_tool_definition_and_compensation() {
    let d = Dialect::Heidenhain;
    // G99 with a zero radius: G41/G42 keep the programmed path.
    let m = moves(
        d,
        "%A G71 *\nG99 T1 L+0 R+0 *\nT1 G17 S1000 *\nG01 G42 X+10 F100 *\n",
    );
    line_to(&m[0], v(10.0, 0.0, 0.0));
    // A real radius would need compensation, which is refused.
    let e = error(
        d,
        "%A G71 *\nG99 T1 L+0 R+5 *\nT1 G17 *\nG01 G42 X+10 F100 *\n",
    );
    assert_eq!((e.line, e.col), (4, 5));
    // Blank-form blocks (G30/G31) carry no motion; G29 makes the last position the pole.
    let m = moves(
        d,
        "%A G71 *\nG30 G17 X+0 Y+0 Z-40 *\nG31 G90 X+100 Y+100 Z+0 *\nG00 X+20 Y+0 *\nG29 *\nG00 X+30 *\nG11 R+5 H+90 F10 *\n",
    );
    assert_eq!(m.len(), 3);
    line_to(&m[2], v(20.0, 5.0, 0.0));
}

#[test]
fn fagor_absolute_centre_and_radius_arcs() {
    let d = Dialect::Fagor;
    // G06: I J absolute for this block only.
    let m = moves(
        d,
        "G01 X10 Y0 F100\nG06 G03 X0 Y10 I0 J0\nG02 X10 Y0 I0 J-10\n",
    );
    near(arc_of(&m[1]).center, v(0.0, 0.0, 0.0));
    near(arc_of(&m[2]).center, v(0.0, 0.0, 0.0));
    // X Y R is a radius arc; I J K are not affected by G91.
    let m = moves(d, "G01 X10 F100\nG02 X20 Y0 R5\nG91 G03 X-10 I-5\n");
    near(arc_of(&m[1]).center, v(15.0, 0.0, 0.0));
    near(arc_of(&m[2]).center, v(15.0, 0.0, 0.0));
    near(arc_of(&m[2]).end, v(10.0, 0.0, 0.0));
}

#[test]
fn syntax_of_each_dialect() {
    // LinuxCNC: spaces inside words and numbers, comments of both kinds, % delimiters.
    let m = moves(
        Dialect::LinuxCnc,
        "%\nG 1 X 1 0.5 (c) F 100 ; tail\n%\nG1 X99\n",
    );
    assert_eq!(m.len(), 1);
    line_to(&m[0], v(10.5, 0.0, 0.0));
    // Sinumerik: main block numbers, `;` comments and `X=` values.
    let m = moves(
        Dialect::Sinumerik,
        "%_N_A_MPF\n:10 G1 X=5 F100 ; note\nN20 Y-.5\n",
    );
    line_to(&m[1], v(5.0, -0.5, 0.0));
    // Block delete (switch on) in a Rockwell line skips only its block.
    let on = Settings {
        block_delete: true,
        ..Settings::default()
    };
    let m: Vec<Move> = run_with(Dialect::Rockwell, "G01 F100 X1 ; /X2 ; X3 ;\n", on)
        .expect("valid")
        .into_iter()
        .filter_map(|i| match i {
            Item::Move(m) => Some(m),
            Item::Event(_) => None,
        })
        .collect();
    assert_eq!(m.len(), 2);
    line_to(&m[1], v(3.0, 0.0, 0.0));
    // Invalid bytes are errors at their column, never panics.
    let e = error(Dialect::LinuxCnc, "G1 X1 F1\nG1 X2 (\u{e9}t\u{e9}) \u{1}\n");
    assert_eq!((e.line, e.col), (2, 15), "columns count bytes");
    let e = Interpreter::new(
        &b"G1 X1 F1\nG1\x00 X2\n"[..],
        Dialect::LinuxCnc,
        Settings::default(),
    )
    .find_map(Result::err)
    .unwrap();
    assert_eq!(
        (e.line, e.col, e.message.as_str()),
        (2, 3, "NUL byte in program")
    );
    let e = Interpreter::new(
        &b"G1 X1 F1 (\xff)\n"[..],
        Dialect::LinuxCnc,
        Settings::default(),
    )
    .find_map(Result::err)
    .unwrap();
    assert_eq!((e.line, e.col), (1, 11));
}

#[test]
fn a_byte_order_mark_is_ignored() {
    let m = moves(Dialect::LinuxCnc, "\u{feff}G1 X1 F1\n");
    line_to(&m[0], v(1.0, 0.0, 0.0));
    let e = error(Dialect::LinuxCnc, "\u{feff}G1 X1 Q1\n");
    assert_eq!(e.col, 10, "columns still count the mark's bytes");
}

#[test]
fn line_length_is_bounded() {
    let long = format!("G1 X1 F1 ({})\nG1 X2\n", "a".repeat(crate::MAX_LINE_BYTES));
    let e = error(Dialect::LinuxCnc, &long);
    assert_eq!(e.line, 1);
    assert!(e.message.starts_with("line longer than"));
}

#[test]
fn random_word_programs_never_panic() {
    // Programs built from valid-looking words with random values reach the resolution code
    // far more often than byte mutations do.
    let rounds: usize = std::env::var("KERF_FUZZ_ROUNDS")
        .ok()
        .and_then(|r| r.parse().ok())
        .unwrap_or(2000);
    let words: [&[&str]; 5] = [
        &[
            "G0", "G1", "G2", "G3", "G17", "G18", "G19", "G20", "G21", "G90", "G91", "G90.1",
            "G91.1", "G92", "G92.1", "G43", "G49", "G53", "G54", "G59.3", "G61", "G64", "G41",
            "G40", "G4", "G80", "M3", "M6", "M30", "T", "H", "D", "X", "Y", "Z", "A", "I", "J",
            "K", "R", "P", "Q", "F", "S", "@", "^",
        ],
        &[
            "G00", "G01", "G02", "G03", "G17", "G18", "G19", "G20", "G21", "G90", "G91", "G09",
            "G61", "G64", "G43", "X", "Y", "Z", "B", "I", "J", "K", "R", "F", ";", "M5",
        ],
        &[
            "G0", "G1", "G2", "G3", "G17", "G18", "G19", "G70", "G71", "G700", "G710", "G90",
            "G91", "G110", "G111", "G112", "G60", "G64", "X", "Y", "Z", "C", "I", "J", "K", "CR=",
            "TURN=", "RP=", "AP=", "AP=IC(", "X=AC(", "I=IC(", "F",
        ],
        &[
            "G00", "G01", "G02", "G03", "G05", "G10", "G11", "G12", "G13", "G15", "G17", "G18",
            "G19", "G29", "G70", "G71", "G90", "G91", "G99", "G42", "X", "Y", "Z", "I", "J", "K",
            "R", "H", "L", "T", "F", "*",
        ],
        &[
            "G00", "G01", "G02", "G03", "G05", "G06", "G07", "G17", "G18", "G19", "G30", "G70",
            "G71", "G90", "G91", "X", "Y", "Z", "A", "I", "J", "K", "R", "Q", "F",
        ],
    ];
    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
    let mut src = String::new();
    let (mut moves, mut arcs) = (0usize, 0usize);
    for round in 0..rounds {
        let di = round % 5;
        src.clear();
        src.push_str(
            [
                "G1 F100\n",
                "G01 F100 ;\n",
                "G1 F100\n",
                "%P G71 *\nG01 F100 *\nI+1 J+1 *\n",
                "G01 F100\n",
            ][di],
        );
        for _ in 0..(1 + rng.next() % 12) {
            for _ in 0..(1 + rng.next() % 3) {
                let w = words[di][(rng.next() as usize) % words[di].len()];
                src.push_str(w);
                if !w.starts_with(['G', 'M']) && w != ";" && w != "*" {
                    let value = match rng.next() % 6 {
                        0 => 0.0,
                        1 => 360.0 * ((rng.next() % 21) as f64 - 10.0),
                        2 => (rng.next() % 2000) as f64 / 100.0 - 10.0,
                        3 => 1e-9,
                        4 => (rng.next() % 10) as f64,
                        _ => -((rng.next() % 100) as f64),
                    };
                    src.push_str(&format!("{value}"));
                    if w.ends_with('(') {
                        src.push(')');
                    }
                }
                src.push(' ');
            }
            src.push('\n');
        }
        let mut errored = false;
        for item in Interpreter::new(src.as_bytes(), Dialect::ALL[di], Settings::default()) {
            match item {
                Err(_) => errored = true,
                Ok(Item::Move(m)) => {
                    assert!(!errored);
                    moves += 1;
                    if let Path::Arc(a) = m.path {
                        arcs += 1;
                        assert!(a.sweep_rad.is_finite() && a.sweep_rad != 0.0, "{src}");
                        let r1 = (a.start - a.center).norm();
                        let mut e = a.end;
                        let w = a.axis.iamax();
                        e[w] = a.start[w];
                        let r2 = (e - a.center).norm();
                        assert!((r1 - r2).abs() < 1e-6 * r1.max(1.0), "{src}\n{a:?}");
                    }
                }
                Ok(_) => assert!(!errored),
            }
        }
    }
    // The generator must reach the geometry code, not only the error paths.
    assert!(
        moves > rounds / 5 && arcs > rounds / 100,
        "{moves} moves, {arcs} arcs"
    );
}

#[test]
fn the_tool_in_the_spindle_at_start_is_the_current_tool() {
    // LinuxCNC G43 without H applies the current tool's length: with tool 2 (25 mm) in
    // the spindle when the program starts, Z0 is 25 mm higher in machine coordinates.
    let tools = vec![Tool {
        number: 2,
        length_mm: 25.0,
        ..Tool::default()
    }];
    let loaded = Settings {
        tools: tools.clone(),
        tool_in_spindle: Some(2),
        ..Settings::default()
    };
    let items = run_with(
        Dialect::LinuxCnc,
        "G21 G43\nG0 Z0\n(DEBUG, #5400)\n",
        loaded,
    )
    .unwrap();
    // #5400, the tool in the spindle, is 2.
    assert!(
        matches!(&items[1], Item::Event(e) if e.text.as_deref() == Some(" 2.000000")),
        "{items:?}"
    );
    let Some(Item::Move(m)) = items.first() else {
        panic!("{items:?}")
    };
    near(m.path.end(), v(0.0, 0.0, 25.0));
    // With an empty spindle there is no length to apply.
    let empty = Settings {
        tools,
        ..Settings::default()
    };
    let items = run_with(Dialect::LinuxCnc, "G21 G43\nG0 Z1\n", empty).unwrap();
    let Some(Item::Move(m)) = items.first() else {
        panic!("{items:?}")
    };
    near(m.path.end(), v(0.0, 0.0, 1.0));
}
