//! Each `Reject` reason, provoked by mutating one valid message; the expected reason is
//! written by hand from the protocol's rules.

use std::f64::consts::{FRAC_PI_2, PI};

use kerf_gcode::{Event, EventCode};
use kerf_geom::{Arc, CornerMode, Line, Move, Path, Vec3};
use kerf_proto::*;

fn line() -> MoveMsg {
    MoveMsg::from_move(
        5,
        1,
        &Move {
            line: 3,
            rapid: false,
            path: Path::Line(Line {
                start: Vec3::new(0.0, 0.0, 0.0),
                end: Vec3::new(10.0, 0.0, 0.0),
            }),
            feed_mm_min: Some(600.0),
            abc_deg: None,
            corner: CornerMode::Blend {
                tolerance_mm: Some(0.01),
                naive_cam_mm: None,
            },
        },
    )
}

/// A quarter circle of radius 10 about the origin, from +X to +Y, rising 2 mm.
fn arc() -> MoveMsg {
    MoveMsg::from_move(
        5,
        2,
        &Move {
            line: 4,
            rapid: false,
            path: Path::Arc(Arc {
                start: Vec3::new(10.0, 0.0, 0.0),
                end: Vec3::new(0.0, 10.0, 2.0),
                center: Vec3::new(0.0, 0.0, 0.0),
                axis: Vec3::new(0.0, 0.0, 1.0),
                sweep_rad: FRAC_PI_2,
            }),
            feed_mm_min: Some(300.0),
            abc_deg: Some(([0.0; 3], [10.0, 0.0, 0.0])),
            corner: CornerMode::ExactStop,
        },
    )
}

fn event(code: EventCode, value: Option<f64>) -> MoveMsg {
    MoveMsg::from_event(5, 3, &Event::new(9, code, value))
}

fn reason(m: &MoveMsg) -> Reject {
    Resolved::try_from(m).expect_err("the mutated message must be refused")
}

fn mutated(base: fn() -> MoveMsg, f: impl FnOnce(&mut MoveMsg)) -> Reject {
    let mut m = base();
    assert!(Resolved::try_from(&m).is_ok(), "the base message is valid");
    f(&mut m);
    reason(&m)
}

#[test]
fn valid_messages_decode() {
    for m in [
        line(),
        arc(),
        event(EventCode::S, Some(1000.0)),
        event(EventCode::M5, None),
        event(EventCode::G4, Some(0.0)),
        MoveMsg::begin(5, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0], 0),
        MoveMsg::end(5, 0),
    ] {
        Resolved::try_from(&m).unwrap_or_else(|e| panic!("{m:?}: {e}"));
    }
    // A full circle: start = end, two turns.
    let mut full = arc();
    full.end_mm = full.start_mm;
    full.sweep_rad = -4.0 * PI;
    assert!(Resolved::try_from(&full).is_ok());
}

#[test]
fn envelope() {
    assert_eq!(
        mutated(line, |m| m.version = 1),
        Reject::WrongVersion { found: 1 }
    );
    assert_eq!(
        mutated(line, |m| m.version = 0),
        Reject::WrongVersion { found: 0 }
    );
    assert_eq!(mutated(line, |m| m.kind = 0), Reject::UnknownKind(0));
    assert_eq!(mutated(line, |m| m.kind = 6), Reject::UnknownKind(6));
    assert_eq!(mutated(line, |m| m.program_id = 0), Reject::ProgramIdZero);
    assert_eq!(
        mutated(line, |m| m.flags |= 1 << 7),
        Reject::UnknownFlags(1 << 7)
    );
    // Defined bits that this kind does not use.
    assert_eq!(
        mutated(line, |m| m.flags |= FLAG_EVENT_VALUE),
        Reject::UnknownFlags(FLAG_EVENT_VALUE)
    );
    assert_eq!(
        mutated(|| event(EventCode::M3, None), |m| m.flags |= FLAG_RAPID),
        Reject::UnknownFlags(FLAG_RAPID)
    );
    assert_eq!(
        mutated(|| MoveMsg::end(5, 3), |m| m.flags = FLAG_ABC),
        Reject::UnknownFlags(FLAG_ABC)
    );
}

#[test]
fn reserved_and_unused_fields_must_be_zero() {
    let nz = |field| Reject::NonzeroReserved { field };
    assert_eq!(mutated(line, |m| m.reserved = 1), nz(Field::Reserved));
    // The naive-CAM tolerance only with FLAG_NAIVE_CAM, which an exact stop may not have.
    assert_eq!(
        mutated(line, |m| m.naive_cam_mm = 0.1),
        nz(Field::NaiveCamMm)
    );
    assert_eq!(
        mutated(arc, |m| m.flags |= FLAG_NAIVE_CAM),
        Reject::UnknownFlags(FLAG_NAIVE_CAM)
    );
    assert_eq!(
        mutated(line, |m| {
            m.flags |= FLAG_NAIVE_CAM;
            m.naive_cam_mm = -0.1;
        }),
        Reject::NegativeTolerance
    );
    assert_eq!(mutated(arc, |m| m.reserved = u64::MAX), nz(Field::Reserved));
    // A line carries no arc data.
    assert_eq!(mutated(line, |m| m.center_mm[1] = 1.0), nz(Field::CenterMm));
    assert_eq!(mutated(line, |m| m.axis[2] = 1.0), nz(Field::Axis));
    assert_eq!(mutated(line, |m| m.sweep_rad = 1.0), nz(Field::SweepRad));
    // -0.0 is not all-zero bits.
    assert_eq!(mutated(line, |m| m.sweep_rad = -0.0), nz(Field::SweepRad));
    // Without FLAG_ABC the rotary fields are unused.
    assert_eq!(
        mutated(line, |m| m.abc_end_deg[0] = 1.0),
        nz(Field::AbcEndDeg)
    );
    assert_eq!(
        mutated(line, |m| m.abc_start_deg[2] = 1.0),
        nz(Field::AbcStartDeg)
    );
    // A rapid has no feed.
    assert_eq!(
        mutated(line, |m| m.flags |= FLAG_RAPID),
        nz(Field::FeedMmMin)
    );
    // Tolerance only with CORNER_BLEND_TOLERANCE.
    assert_eq!(
        mutated(line, |m| m.corner = CORNER_BLEND_DEFAULT),
        nz(Field::ToleranceMm)
    );
    assert_eq!(mutated(line, |m| m.count = 1), nz(Field::Count));
    assert_eq!(
        mutated(line, |m| m.event_code = EVENT_M3),
        nz(Field::EventCode)
    );
    assert_eq!(
        mutated(line, |m| m.event_value = 1.0),
        nz(Field::EventValue)
    );
    // Events carry no geometry, corner or feed.
    let m3 = || event(EventCode::M3, None);
    assert_eq!(
        mutated(m3, |m| m.corner = CORNER_EXACT_STOP),
        nz(Field::Corner)
    );
    assert_eq!(mutated(m3, |m| m.feed_mm_min = 100.0), nz(Field::FeedMmMin));
    assert_eq!(mutated(m3, |m| m.start_mm[0] = 1.0), nz(Field::StartMm));
    assert_eq!(mutated(m3, |m| m.end_mm[0] = 1.0), nz(Field::EndMm));
    assert_eq!(mutated(m3, |m| m.event_value = 2.0), nz(Field::EventValue));
    // BEGIN and END have no source line; END has no position.
    assert_eq!(
        mutated(|| MoveMsg::begin(5, [0.0; 6], 3), |m| m.line = 1),
        nz(Field::Line)
    );
    assert_eq!(
        mutated(|| MoveMsg::end(5, 3), |m| m.start_mm[2] = 1.0),
        nz(Field::StartMm)
    );
    assert_eq!(
        mutated(|| MoveMsg::end(5, 3), |m| m.abc_start_deg[0] = 1.0),
        nz(Field::AbcStartDeg)
    );
    assert_eq!(
        mutated(|| MoveMsg::begin(5, [0.0; 6], 3), |m| m.end_mm[0] = 1.0),
        nz(Field::EndMm)
    );
}

#[test]
fn numbers_must_be_finite() {
    let nf = |field| Reject::NonFinite { field };
    assert_eq!(
        mutated(line, |m| m.start_mm[0] = f64::NAN),
        nf(Field::StartMm)
    );
    assert_eq!(
        mutated(line, |m| m.end_mm[2] = f64::INFINITY),
        nf(Field::EndMm)
    );
    assert_eq!(
        mutated(line, |m| m.feed_mm_min = f64::INFINITY),
        nf(Field::FeedMmMin)
    );
    assert_eq!(
        mutated(line, |m| m.tolerance_mm = f64::NAN),
        nf(Field::ToleranceMm)
    );
    assert_eq!(
        mutated(arc, |m| m.center_mm[1] = f64::NEG_INFINITY),
        nf(Field::CenterMm)
    );
    assert_eq!(mutated(arc, |m| m.axis[0] = f64::NAN), nf(Field::Axis));
    assert_eq!(
        mutated(arc, |m| m.sweep_rad = f64::INFINITY),
        nf(Field::SweepRad)
    );
    assert_eq!(
        mutated(arc, |m| m.abc_start_deg[1] = f64::NAN),
        nf(Field::AbcStartDeg)
    );
    assert_eq!(
        mutated(arc, |m| m.abc_end_deg[2] = f64::NAN),
        nf(Field::AbcEndDeg)
    );
    assert_eq!(
        mutated(
            || event(EventCode::S, Some(100.0)),
            |m| m.event_value = f64::NAN
        ),
        nf(Field::EventValue)
    );
    assert_eq!(
        mutated(
            || MoveMsg::begin(5, [0.0; 6], 0),
            |m| m.abc_start_deg[2] = f64::INFINITY
        ),
        nf(Field::AbcStartDeg)
    );
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        assert_eq!(
            mutated(|| MoveMsg::begin(5, [0.0; 6], 0), |m| m.start_mm[1] = bad),
            nf(Field::StartMm)
        );
        // The naive-CAM tolerance of a blending move (no generator sets it today).
        assert_eq!(
            mutated(naive_cam_line, |m| m.naive_cam_mm = bad),
            nf(Field::NaiveCamMm)
        );
    }
}

/// The blending line with LinuxCNC's naive-CAM tolerance (G64 P0.01 Q0.005).
fn naive_cam_line() -> MoveMsg {
    let mut m = line();
    m.flags |= FLAG_NAIVE_CAM;
    m.naive_cam_mm = 0.005;
    m
}

#[test]
fn moves() {
    assert_eq!(mutated(line, |m| m.line = 0), Reject::LineZero);
    assert_eq!(
        mutated(|| event(EventCode::M8, None), |m| m.line = 0),
        Reject::LineZero
    );
    assert_eq!(mutated(arc, |m| m.corner = 0), Reject::UnknownCorner(0));
    assert_eq!(mutated(arc, |m| m.corner = 4), Reject::UnknownCorner(4));
    assert_eq!(
        mutated(line, |m| m.tolerance_mm = -0.001),
        Reject::NegativeTolerance
    );
    assert_eq!(mutated(line, |m| m.feed_mm_min = 0.0), Reject::BadFeed);
    assert_eq!(mutated(arc, |m| m.feed_mm_min = -100.0), Reject::BadFeed);
}

#[test]
fn arcs() {
    // |axis| = 1.001.
    assert_eq!(mutated(arc, |m| m.axis[2] = 1.001), Reject::AxisNotUnit);
    assert_eq!(
        mutated(arc, |m| m.axis = [0.0, 0.0, 0.0]),
        Reject::AxisNotUnit
    );
    // Centre at the start point.
    assert_eq!(
        mutated(arc, |m| m.center_mm = [10.0, 0.0, 0.0]),
        Reject::ZeroRadius
    );
    // Centre 0.01 mm below the start's plane; the tolerance at these coordinates is
    // 1e-6 mm plus 2^-46 × 15.7 mm (the path length, the largest number).
    let tol = 1e-6 + 10.0 * FRAC_PI_2 / 2f64.powi(46);
    let (off, t) = off_plane(mutated(arc, |m| m.center_mm[2] = -0.01));
    assert!(
        (off - 0.01).abs() < 1e-15 && (t - tol).abs() < 1e-18,
        "{off} {t}"
    );
    // 2 µm off the plane is refused, 0.5 µm is not.
    let (off, _) = off_plane(mutated(arc, |m| m.center_mm[2] = -2e-6));
    assert!((off - 2e-6).abs() < 1e-15);
    let mut near = arc();
    near.center_mm[2] = 5e-7;
    assert!(Resolved::try_from(&near).is_ok());
    // End at radius 10.001: 0.001 mm from where the sweep leads.
    let (off, _) = end_off(mutated(arc, |m| m.end_mm[1] = 10.001));
    assert!((off - 0.001).abs() < 1e-12, "{off}");
    // ...but 0.1 µm is within the tolerance and accepted, with the decoded end unchanged.
    let mut close = arc();
    close.end_mm[1] = 10.0 + 1e-7;
    match Resolved::try_from(&close) {
        Ok(Resolved::Move(Move {
            path: Path::Arc(a), ..
        })) => assert_eq!(a.end, Vec3::new(0.0, 10.0 + 1e-7, 2.0)),
        other => panic!("{other:?}"),
    }
    assert_eq!(mutated(arc, |m| m.sweep_rad = 0.0), Reject::ZeroSweep);
    // The quarter circle the other way round (-270°) is fine, -90° is not: it leads to
    // (0, -10), 20 mm from the end.
    let mut cw = arc();
    cw.sweep_rad = -1.5 * PI;
    assert!(Resolved::try_from(&cw).is_ok());
    let (off, _) = end_off(mutated(arc, |m| m.sweep_rad = -FRAC_PI_2));
    assert!((off - 20.0).abs() < 1e-12, "{off}");
    // A whole turn more is fine, an extra degree is not: 2 · 10 · sin(0.5°) = 0.1745 mm.
    let mut more = arc();
    more.sweep_rad = FRAC_PI_2 + 2.0 * PI;
    assert!(Resolved::try_from(&more).is_ok());
    let (off, _) = end_off(mutated(arc, |m| m.sweep_rad = FRAC_PI_2 + PI / 180.0));
    assert!((off - 20.0 * (PI / 360.0).sin()).abs() < 1e-12, "{off}");
    // Moving the end along the axis changes the rise, not the agreement.
    let mut higher = arc();
    higher.end_mm[2] = 7.0;
    assert!(Resolved::try_from(&higher).is_ok());
}

fn end_off(r: Reject) -> (f64, f64) {
    match r {
        Reject::EndMismatch { off_mm, tol_mm } => (off_mm, tol_mm),
        other => panic!("expected EndMismatch, got {other:?}"),
    }
}

fn off_plane(r: Reject) -> (f64, f64) {
    match r {
        Reject::CenterOffPlane { off_mm, tol_mm } => (off_mm, tol_mm),
        other => panic!("expected CenterOffPlane, got {other:?}"),
    }
}

/// A feed arc item with these numbers.
fn arc_msg(start: Vec3, end: Vec3, center: Vec3, axis: Vec3, sweep_rad: f64) -> MoveMsg {
    MoveMsg::from_move(
        5,
        2,
        &Move {
            line: 4,
            rapid: false,
            path: Path::Arc(Arc {
                start,
                end,
                center,
                axis,
                sweep_rad,
            }),
            feed_mm_min: Some(300.0),
            abc_deg: None,
            corner: CornerMode::ExactStop,
        },
    )
}

/// The protocol's arc tolerance, written out from docs/PROTOCOL.md: 1e-6 mm + 2^-46 × the
/// largest of the coordinates' magnitudes and the path length r·|θ|.
fn spec_tolerance_mm(start: Vec3, end: Vec3, center: Vec3, radius: f64, sweep: f64) -> f64 {
    let m = [start, end, center]
        .iter()
        .flat_map(|p| p.iter().map(|c| c.abs()))
        .fold(radius * sweep.abs(), f64::max);
    1e-6 + m / 2f64.powi(46)
}

/// The arc of radius `r` about a centre placed `r` from `start` along -e1, sweeping
/// `sweep` about `axis` and rising `rise`: its end, written about the start (no
/// cancellation of huge numbers): start + r (e1 (cos θ − 1) + e2 sin θ) + axis · rise.
fn arc_end(start: Vec3, e1: Vec3, axis: Vec3, r: f64, sweep: f64, rise: f64) -> Vec3 {
    let e2 = axis.cross(&e1);
    let half = (0.5 * sweep).sin();
    start + (e1 * (-2.0 * half * half) + e2 * sweep.sin()) * r + axis * rise
}

#[test]
fn sweep_and_end_that_disagree_by_90_mm_at_radius_1e8_are_refused() {
    // The centre 1e8 mm (then 1e10 mm) away on +Y, the end 10 mm from the start along
    // the circle, the sweep 9e-7 rad larger than the end's angle. The sweep leads
    // 2 r sin(4.5e-7) further: 90 mm at 1e8 (9000 mm at 1e10), far beyond the arc
    // tolerance although the angles differ by less than 1e-6 rad: a tolerance on the
    // angle alone would let it through.
    for (r, expected_mm) in [(1e8f64, 90.0), (1e10, 9000.0)] {
        let theta = 10.0 / r;
        let start = Vec3::zeros();
        let center = Vec3::new(0.0, r, 0.0);
        let end = arc_end(start, Vec3::new(0.0, -1.0, 0.0), Vec3::z(), r, theta, 0.0);
        assert!((end.norm() - 10.0).abs() < 1e-9);
        let good = arc_msg(start, end, center, Vec3::z(), theta);
        assert!(
            Resolved::try_from(&good).is_ok(),
            "r {r}: the consistent arc"
        );
        let bad = arc_msg(start, end, center, Vec3::z(), theta + 9e-7);
        let reason = Resolved::try_from(&bad).expect_err("inconsistent");
        let (off, tol) = end_off(reason);
        let exact = 2.0 * r * 4.5e-7f64.sin();
        assert!((exact - expected_mm).abs() < 1e-6);
        assert!((off - exact).abs() < 1e-6 * expected_mm, "r {r}: {off} mm");
        assert!(
            (tol - (1e-6 + r / 2f64.powi(46))).abs() < 1e-18,
            "r {r}: {tol}"
        );
        if r == 1e8 {
            assert_eq!(
                reason.to_string(),
                "arc end_mm is 90.000 mm from the point its sweep_rad leads to (tolerance \
                 2.4e-6 mm): sweep_rad and end_mm disagree"
            );
        }
    }
}

/// Axes to try: the three planes' normals and two tilted ones.
fn axes() -> [Vec3; 5] {
    [
        Vec3::z(),
        Vec3::y(),
        -Vec3::x(),
        Vec3::new(1.0, 2.0, 2.0) / 3.0,
        Vec3::new(-0.6, 0.0, 0.8),
    ]
}

/// A unit vector normal to `axis`, turned by `phase` about it.
fn radial_dir(axis: Vec3, phase: f64) -> Vec3 {
    let helper = if axis.x.abs() < 0.9 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let u = (helper - axis * helper.dot(&axis)).normalize();
    u * phase.cos() + axis.cross(&u) * phase.sin()
}

#[test]
fn consistent_arcs_at_any_radius_and_sweep_are_accepted() {
    // Radii 1e-3 … 1e12 mm (every half decade), starts near the origin (the centre up to
    // 1e12 mm away), sweeps from 1e-6 rad to 50 turns either way, planar and helical, in
    // five planes. The sweep is kept to a path of at most 1e6 mm, so that the positions
    // stay on a machine.
    let mut accepted = 0;
    for decade in 0..=30 {
        let r = 1e-3 * 10f64.powf(decade as f64 * 0.5);
        for (i, axis) in axes().into_iter().enumerate() {
            for (j, sweep) in [1e-6, 0.3, -2.5, 7.0, -100.0 * PI, 100.0 * PI + 0.7]
                .into_iter()
                .enumerate()
            {
                if r * sweep.abs() > 1e6 {
                    continue;
                }
                for rise in [0.0, -3.5] {
                    let e1 = radial_dir(axis, 0.37 * (i + j) as f64);
                    let start = Vec3::new(12.5, -40.25, 3.0);
                    let center = start - e1 * r;
                    let end = arc_end(start, e1, axis, r, sweep, rise);
                    let m = arc_msg(start, end, center, axis, sweep);
                    match Resolved::try_from(&m) {
                        Ok(_) => accepted += 1,
                        Err(e) => panic!("r {r}, axis {axis:?}, sweep {sweep}: {e}"),
                    }
                }
            }
        }
    }
    assert!(accepted > 1000, "{accepted}");
}

#[test]
fn disagreement_within_half_the_tolerance_is_accepted_and_twice_it_refused() {
    // From consistent arcs at radii 1e-3 … 1e12 mm, the end is moved along the circle
    // (a change of the sweep's end angle) or off it (radially), by 0.5 and by 2 times
    // the tolerance computed from the protocol's formula.
    let mut checked = 0;
    for decade in 0..=15 {
        let r = 1e-3 * 10f64.powi(decade);
        for (i, axis) in axes().into_iter().enumerate() {
            for sweep in [0.8, -4.0, 31.0 * PI + 0.2] {
                if r * sweep.abs() > 1e6 {
                    continue;
                }
                let e1 = radial_dir(axis, 1.1 * i as f64);
                let start = Vec3::new(-7.0, 3.25, 100.0);
                let center = start - e1 * r;
                let rise = 2.0;
                let end = arc_end(start, e1, axis, r, sweep, rise);
                let tol = spec_tolerance_mm(start, end, center, r, sweep);
                // The unit directions at the end: along the circle and away from its centre.
                let radial = (e1 * sweep.cos() + axis.cross(&e1) * sweep.sin()).normalize();
                let along = axis.cross(&radial);
                for dir in [along, radial, -radial] {
                    for (factor, ok) in [(0.5, true), (2.0, false)] {
                        let moved = end + dir * (factor * tol);
                        let m = arc_msg(start, moved, center, axis, sweep);
                        let what = format!("r {r}, axis {axis:?}, sweep {sweep}, x{factor}");
                        match Resolved::try_from(&m) {
                            Ok(_) => assert!(ok, "{what}: accepted"),
                            Err(e) => {
                                assert!(!ok, "{what}: {e}");
                                let (off, t) = end_off(e);
                                assert!((off / t - 2.0).abs() < 0.05, "{what}: {off} of {t}");
                            }
                        }
                        checked += 1;
                    }
                }
            }
        }
    }
    assert!(checked > 300, "{checked}");
}

#[test]
fn arc_tolerance_is_the_protocol_formula() {
    // At 100 mm coordinates the rounding term is 1.4e-12 mm; at 7.04e7 mm it equals the
    // absolute term.
    assert_eq!(ARC_END_TOL_MM, 1e-6);
    assert_eq!(ARC_ROUNDING_REL, 2f64.powi(-46));
    let a = Arc {
        start: Vec3::new(100.0, 0.0, 0.0),
        end: Vec3::new(0.0, 100.0, 0.0),
        center: Vec3::zeros(),
        axis: Vec3::z(),
        sweep_rad: FRAC_PI_2,
    };
    // The path length, 157 mm, is the largest number.
    let t = arc_tolerance_mm(&a);
    assert!(
        (t - (1e-6 + 100.0 * FRAC_PI_2 / 2f64.powi(46))).abs() < 1e-20,
        "{t}"
    );
    let far = Arc {
        center: Vec3::new(0.0, 0.0, 0.0),
        start: Vec3::new(7.0368744177664e7, 0.0, 0.0),
        end: Vec3::new(7.0368744177664e7, 1e-3, 0.0),
        axis: Vec3::z(),
        sweep_rad: 1e-3 / 7.0368744177664e7,
    };
    assert!((arc_tolerance_mm(&far) - 2e-6).abs() < 1e-18);
}

/// The radius in the tolerance is the start's distance from the centre *normal to the
/// axis*: a centre 1e9 mm off the start's plane (an arc the plane check refuses) does not
/// make the radius 1e9, so the largest number is the centre's coordinate, 1e9 mm.
#[test]
fn arc_tolerance_takes_the_radius_normal_to_the_axis() {
    let off = Arc {
        start: Vec3::zeros(),
        end: Vec3::new(2.0, 0.0, 0.0),
        center: Vec3::new(1.0, 0.0, 1e9),
        axis: Vec3::z(),
        sweep_rad: 1.0,
    };
    let t = arc_tolerance_mm(&off);
    assert_eq!(t, 1e-6 + 1e9 / 2f64.powi(46), "{t}");
}

/// A NaN anywhere makes the tolerance NaN (so that every "within" check refuses), also
/// when it comes from overflowing intermediate values: coordinates at ±1e308 along the
/// axis make the radius NaN.
#[test]
fn arc_tolerance_is_nan_when_the_radius_overflows() {
    let huge = Arc {
        start: Vec3::new(1e308, 0.0, 0.0),
        end: Vec3::new(1e308, 0.0, 0.0),
        center: Vec3::new(-1e308, 0.0, 0.0),
        axis: Vec3::x(),
        sweep_rad: 1.0,
    };
    assert!(arc_tolerance_mm(&huge).is_nan());
}

#[test]
fn events() {
    assert_eq!(
        mutated(|| event(EventCode::M3, None), |m| m.event_code = 0),
        Reject::UnknownEventCode(0)
    );
    assert_eq!(
        mutated(|| event(EventCode::M3, None), |m| m.event_code = 99),
        Reject::UnknownEventCode(99)
    );
    assert_eq!(
        mutated(
            || event(EventCode::S, Some(900.0)),
            |m| {
                m.flags = 0;
                m.event_value = 0.0;
            }
        ),
        Reject::EventValueMissing(EventCode::S)
    );
    assert_eq!(
        mutated(
            || event(EventCode::G4, Some(1.0)),
            |m| {
                m.flags = 0;
                m.event_value = 0.0;
            }
        ),
        Reject::EventValueMissing(EventCode::G4)
    );
    assert_eq!(
        mutated(
            || event(EventCode::M30, None),
            |m| m.flags = FLAG_EVENT_VALUE
        ),
        Reject::EventValueUnexpected(EventCode::M30)
    );
    assert_eq!(
        mutated(|| event(EventCode::G4, Some(1.0)), |m| m.event_value = -0.5),
        Reject::NegativeDwell
    );
    // The P (L) and Q words: M66 may carry both, M67 needs a Q, M3 takes neither.
    let mut m66 = Event::new(7, EventCode::M66, Some(2.0));
    m66.p = Some(3.0);
    m66.q = Some(1.5);
    let msg = MoveMsg::from_event(1, 1, &m66);
    assert_eq!(msg.flags, FLAG_EVENT_VALUE | FLAG_EVENT_P | FLAG_EVENT_Q);
    assert_eq!(
        Resolved::try_from(&msg),
        Ok(Resolved::Event(m66)),
        "M66 P2 L3 Q1.5 crosses whole"
    );
    let m67 = || {
        let mut e = Event::new(9, EventCode::M67, Some(0.0));
        e.q = Some(4.5);
        MoveMsg::from_event(5, 3, &e)
    };
    assert_eq!(
        mutated(m67, |m| {
            m.flags &= !FLAG_EVENT_Q;
            m.event_q = 0.0;
        }),
        Reject::EventQ(EventCode::M67, true)
    );
    assert_eq!(
        mutated(
            || event(EventCode::M3, None),
            |m| {
                m.flags |= FLAG_EVENT_Q;
                m.event_q = 1.0;
            }
        ),
        Reject::EventQ(EventCode::M3, false)
    );
    assert_eq!(
        mutated(
            || event(EventCode::M3, None),
            |m| {
                m.flags |= FLAG_EVENT_P;
                m.event_p = 1.0;
            }
        ),
        Reject::EventPUnexpected(EventCode::M3)
    );
    assert_eq!(
        mutated(|| event(EventCode::M3, None), |m| m.event_q = 1.0),
        Reject::NonzeroReserved {
            field: Field::EventQ
        }
    );
}

#[test]
fn reasons_read_as_plain_words() {
    assert_eq!(
        Reject::NonFinite {
            field: Field::SweepRad
        }
        .to_string(),
        "field sweep_rad is not a finite number"
    );
    assert_eq!(
        Reject::WrongVersion { found: 3 }.to_string(),
        "protocol version 3, expected 6"
    );
    assert_eq!(
        Reject::EventValueMissing(EventCode::T).to_string(),
        "event T needs a value"
    );
    assert_eq!(
        Reject::CenterOffPlane {
            off_mm: 0.01,
            tol_mm: 1.0000022e-6
        }
        .to_string(),
        "arc center_mm is 0.010 mm from the plane of its start point (tolerance 1.0e-6 mm)"
    );
    assert_eq!(
        Reject::EndMismatch {
            off_mm: 2.5e-6,
            tol_mm: 1.2e-6
        }
        .to_string(),
        "arc end_mm is 2.5e-6 mm from the point its sweep_rad leads to (tolerance 1.2e-6 mm): \
         sweep_rad and end_mm disagree"
    );
    assert_eq!(
        Reject::UnknownFlags(0x80).to_string(),
        "flag bits 0x80 are not defined for this message kind"
    );
}
