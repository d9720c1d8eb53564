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
    assert_eq!(mutated(line, |m| m.reserved[2] = 1), nz(Field::Reserved));
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
    assert_eq!(
        mutated(arc, |m| m.reserved[0] = u64::MAX),
        nz(Field::Reserved)
    );
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
    // Centre 0.01 mm below the start's plane (radius 10: 1e-3 relative).
    assert_eq!(
        mutated(arc, |m| m.center_mm[2] = -0.01),
        Reject::CenterOffPlane
    );
    // End at radius 10.001 (1e-4 relative).
    assert_eq!(
        mutated(arc, |m| m.end_mm[1] = 10.001),
        Reject::RadiusMismatch
    );
    // ...but 1e-8 relative is rounding and accepted, with the decoded end unchanged.
    let mut close = arc();
    close.end_mm[1] = 10.0 + 1e-7;
    assert!(Resolved::try_from(&close).is_ok());
    assert_eq!(mutated(arc, |m| m.sweep_rad = 0.0), Reject::ZeroSweep);
    // The quarter circle the other way round (-270°) is fine, -90° is not.
    let mut cw = arc();
    cw.sweep_rad = -1.5 * PI;
    assert!(Resolved::try_from(&cw).is_ok());
    assert_eq!(
        mutated(arc, |m| m.sweep_rad = -FRAC_PI_2),
        Reject::SweepMismatch
    );
    // A whole turn more is fine, an extra degree is not.
    let mut more = arc();
    more.sweep_rad = FRAC_PI_2 + 2.0 * PI;
    assert!(Resolved::try_from(&more).is_ok());
    assert_eq!(
        mutated(arc, |m| m.sweep_rad = FRAC_PI_2 + PI / 180.0),
        Reject::SweepMismatch
    );
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
        Reject::WrongVersion { found: 4 }.to_string(),
        "protocol version 4, expected 3"
    );
    assert_eq!(
        Reject::EventValueMissing(EventCode::T).to_string(),
        "event T needs a value"
    );
    assert_eq!(
        Reject::UnknownFlags(0x80).to_string(),
        "flag bits 0x80 are not defined for this message kind"
    );
}
