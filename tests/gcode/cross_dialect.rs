//! The same part written for all five controls must resolve to the same moves.
//!
//! The part (tests/data/programs/<dialect>/pocket.*) has lines, counter-clockwise and
//! clockwise arcs in centre and radius format (R+ and R-), a full circle, a helix, polar
//! lines and a polar arc where the dialect has them (Cartesian equivalents elsewhere). The
//! expected moves are computed by hand below; every dialect is compared with them and with
//! each other.

use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::io::BufReader;

use kerf_tests::*;

fn pocket_src(d: Dialect) -> String {
    let path = data_dir()
        .join("programs")
        .join(d.name())
        .join(format!("pocket.{}", extension(d)));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn line(rapid: bool, start: Vec3, end: Vec3, feed: Option<f64>) -> Move {
    Move {
        line: 0,
        rapid,
        path: Path::Line(Line { start, end }),
        feed_mm_min: feed,
        abc_deg: None,
        corner: CornerMode::ExactStop,
    }
}

fn arc(start: Vec3, end: Vec3, center: Vec3, sweep_rad: f64, feed: f64) -> Move {
    Move {
        line: 0,
        rapid: false,
        path: Path::Arc(Arc {
            start,
            end,
            center,
            axis: axis_g17(),
            sweep_rad,
        }),
        feed_mm_min: Some(feed),
        abc_deg: None,
        corner: CornerMode::ExactStop,
    }
}

/// The pocket, by hand.
fn expected() -> Vec<Move> {
    let f = Some(300.0);
    let s60 = 20.0 * deg(60.0).sin();
    vec![
        line(true, v(0.0, 0.0, 0.0), v(10.0, 0.0, 5.0), None),
        line(false, v(10.0, 0.0, 5.0), v(10.0, 0.0, -1.0), Some(200.0)),
        line(false, v(10.0, 0.0, -1.0), v(30.0, 0.0, -1.0), f),
        // Centre format, counter-clockwise quarter about (30,10).
        arc(
            v(30.0, 0.0, -1.0),
            v(40.0, 10.0, -1.0),
            v(30.0, 10.0, -1.0),
            FRAC_PI_2,
            300.0,
        ),
        line(false, v(40.0, 10.0, -1.0), v(40.0, 30.0, -1.0), f),
        // R+10 counter-clockwise: the short arc about (30,30).
        arc(
            v(40.0, 30.0, -1.0),
            v(30.0, 40.0, -1.0),
            v(30.0, 30.0, -1.0),
            FRAC_PI_2,
            300.0,
        ),
        line(false, v(30.0, 40.0, -1.0), v(10.0, 40.0, -1.0), f),
        // R-10 counter-clockwise from (10,40) to (0,30): the long arc about (0,40), 270°.
        arc(
            v(10.0, 40.0, -1.0),
            v(0.0, 30.0, -1.0),
            v(0.0, 40.0, -1.0),
            1.5 * PI,
            300.0,
        ),
        // Clockwise quarter about (0,20).
        arc(
            v(0.0, 30.0, -1.0),
            v(10.0, 20.0, -1.0),
            v(0.0, 20.0, -1.0),
            -FRAC_PI_2,
            300.0,
        ),
        // Clockwise full circle about (20,20).
        arc(
            v(10.0, 20.0, -1.0),
            v(10.0, 20.0, -1.0),
            v(20.0, 20.0, -1.0),
            -TAU,
            300.0,
        ),
        // Helical half turn down to Z-3.
        arc(
            v(10.0, 20.0, -1.0),
            v(30.0, 20.0, -3.0),
            v(20.0, 20.0, -1.0),
            PI,
            300.0,
        ),
        // Polar lines about (0,0): 20 mm at 60°, then at 90°.
        line(false, v(30.0, 20.0, -3.0), v(10.0, s60, -3.0), f),
        line(false, v(10.0, s60, -3.0), v(0.0, 20.0, -3.0), f),
        // Polar arc about (0,0) from 90° to 180°.
        arc(
            v(0.0, 20.0, -3.0),
            v(-20.0, 0.0, -3.0),
            v(0.0, 0.0, -3.0),
            FRAC_PI_2,
            300.0,
        ),
        line(true, v(-20.0, 0.0, -3.0), v(-20.0, 0.0, 5.0), None),
    ]
}

#[test]
fn every_dialect_matches_the_hand_computed_pocket() {
    let want = expected();
    let mut failures = Vec::new();
    for d in Dialect::ALL {
        let src = pocket_src(d);
        let out = run_bytes(d, Settings::default(), src.as_bytes());
        if let Some(e) = out.error {
            failures.push(format!("{}: rejected: {e}", d.name()));
            continue;
        }
        let got = only_moves(&out.items);
        let r = std::panic::catch_unwind(|| {
            assert_same_moves(d.name(), &got, &want, 1e-9);
            assert_continuous(&got, v(0.0, 0.0, 0.0));
            for m in &got {
                if let Path::Arc(a) = m.path {
                    check_arc_geometry(&a, 1e-9);
                }
            }
        });
        if let Err(p) = r {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            failures.push(msg);
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

#[test]
fn every_dialect_matches_linuxcnc_on_the_pocket() {
    let reference = moves(Dialect::LinuxCnc, &pocket_src(Dialect::LinuxCnc));
    for d in Dialect::ALL {
        let got = moves(d, &pocket_src(d));
        assert_same_moves(&format!("{} vs linuxcnc", d.name()), &got, &reference, 1e-9);
    }
}

#[test]
fn program_end_event_is_the_last_item() {
    for d in Dialect::ALL {
        let its = items(d, &pocket_src(d));
        let last = its.last().expect("items");
        assert!(
            matches!(last, Item::Event(e) if e.code == EventCode::M2 || e.code == EventCode::M30),
            "{}: last item {last:?}",
            d.name()
        );
    }
}

/// Every valid fixture program of every dialect, with its dialect.
fn fixtures() -> Vec<(Dialect, String, String)> {
    let mut out = Vec::new();
    for d in Dialect::ALL {
        let dir = data_dir().join("programs").join(d.name());
        for p in files_with_ext(&dir, extension(d)) {
            let src = std::fs::read_to_string(&p).expect("fixture");
            out.push((d, p.display().to_string(), src));
        }
    }
    assert!(out.len() >= 7, "fixtures missing: {}", out.len());
    out
}

#[test]
fn fixtures_are_accepted_and_well_formed() {
    for (d, name, src) in fixtures() {
        let out = run_bytes(d, Settings::default(), src.as_bytes());
        assert!(out.error.is_none(), "{name}: {:?}", out.error);
        let ms = only_moves(&out.items);
        assert_continuous(&ms, v(0.0, 0.0, 0.0));
        // Sampling each arc: it starts and ends where it says, and every sample is at the
        // same distance from the axis through the centre.
        for m in &ms {
            if let Path::Arc(a) = m.path {
                check_arc_geometry(&a, 1e-9);
                assert_point(&format!("{name}: t=0"), arc_point(&a, 0.0), a.start, 1e-9);
                assert_point(&format!("{name}: t=1"), arc_point(&a, 1.0), a.end, 1e-9);
                let r = {
                    let d = a.start - a.center;
                    (d - a.axis * d.dot(&a.axis)).norm()
                };
                for k in 1..16 {
                    let p = arc_point(&a, k as f64 / 16.0) - a.center;
                    let radial = (p - a.axis * p.dot(&a.axis)).norm();
                    assert_close(&format!("{name}: sample {k} radius"), radial, r, 1e-9);
                }
            }
        }
        let lines = src.lines().count() as u32;
        let mut last_line = 0;
        for it in &out.items {
            let l = item_line(it);
            assert!(l >= 1 && l <= lines, "{name}: line {l} out of 1..={lines}");
            assert!(l >= last_line, "{name}: items out of source order");
            last_line = l;
        }
    }
}

#[test]
fn reading_through_a_one_byte_buffer_gives_the_same_items() {
    for (d, name, src) in fixtures() {
        let whole = run_bytes(d, Settings::default(), src.as_bytes());
        let reader = BufReader::with_capacity(1, src.as_bytes());
        let tiny = run_reader(d, Settings::default(), reader, src.len());
        assert_eq!(
            describe_items(&whole.items),
            describe_items(&tiny.items),
            "{name}"
        );
        assert_eq!(whole.error, tiny.error, "{name}");
    }
}

#[test]
fn crlf_line_ends_give_the_same_items() {
    for (d, name, src) in fixtures() {
        let lf = run_bytes(d, Settings::default(), src.as_bytes());
        let crlf_src = src.replace('\n', "\r\n");
        let crlf = run_bytes(d, Settings::default(), crlf_src.as_bytes());
        assert_eq!(
            describe_items(&lf.items),
            describe_items(&crlf.items),
            "{name}"
        );
        assert!(crlf.error.is_none(), "{name}: {:?}", crlf.error);
    }
}

#[test]
fn words_are_case_insensitive() {
    for (d, name, src) in fixtures() {
        let upper = run_bytes(d, Settings::default(), src.as_bytes());
        let lower_src = src.to_lowercase();
        let lower = run_bytes(d, Settings::default(), lower_src.as_bytes());
        assert!(
            lower.error.is_none(),
            "{name} in lower case: {:?}",
            lower.error
        );
        assert_eq!(
            describe_items(&upper.items),
            describe_items(&lower.items),
            "{name}"
        );
    }
}

#[test]
fn inch_part_matches_metric_part_in_every_dialect() {
    // A square with a centre arc and a radius arc, in inches and scaled by 25.4 in mm. F is
    // left out of the comparison because the dialects differ in whether the inch code
    // scales it (Sinumerik G70 does not).
    let inch = [
        (
            Dialect::LinuxCnc,
            "G20\nG1 X1 Y0 F10\nG3 X2 Y1 I0 J1\nG2 X3 Y2 R1\nG0 X0 Y0\n",
        ),
        (
            Dialect::Rockwell,
            "G20 ;\nG01 X1 Y0 F10 ;\nG03 X2 Y1 I0 J1 ;\nG02 X3 Y2 R1 ;\nG00 X0 Y0 ;\n",
        ),
        (
            Dialect::Sinumerik,
            "G70\nG1 X1 Y0 F10\nG3 X2 Y1 I0 J1\nG2 X3 Y2 CR=1\nG0 X0 Y0\n",
        ),
        (
            Dialect::Heidenhain,
            "%IN G70 *\nN10 G01 X+1 Y+0 F10 *\nN20 I+1 J+1 *\nN30 G03 X+2 Y+1 *\nN40 G02 X+3 Y+2 R+1 *\nN50 G00 X+0 Y+0 *\nN60 %IN G70 *\n",
        ),
        (
            Dialect::Fagor,
            "G70\nG01 X1 Y0 F10\nG03 X2 Y1 I0 J1\nG02 X3 Y2 R1\nG00 X0 Y0\n",
        ),
    ];
    let mm = moves(
        Dialect::LinuxCnc,
        "G21\nG1 X25.4 Y0 F254\nG3 X50.8 Y25.4 I0 J25.4\nG2 X76.2 Y50.8 R25.4\nG0 X0 Y0\n",
    );
    let strip = |ms: Vec<Move>| -> Vec<Move> {
        ms.into_iter()
            .map(|mut m| {
                m.feed_mm_min = m.feed_mm_min.map(|_| 1.0);
                m
            })
            .collect()
    };
    let mm = strip(mm);
    for (d, src) in inch {
        let got = strip(moves(d, src));
        assert_same_moves(&format!("{} inch", d.name()), &got, &mm, 1e-9);
    }
}
