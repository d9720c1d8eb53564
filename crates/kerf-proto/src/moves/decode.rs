//! Checking a [`MoveMsg`] and turning it into a [`Resolved`] program item: the rules of
//! docs/PROTOCOL.md for one message alone, in the order of [`Reject`]'s variants, the first
//! one broken refusing the message.

use kerf_geom::{Arc, CornerMode, Event, EventCode, Line, Move, Path, Vec3};

use super::arc::check_arc;
use super::event_codes::event_code_from_u32;
use crate::{
    AXES, CORNER_BLEND_DEFAULT, CORNER_BLEND_TOLERANCE, CORNER_EXACT_STOP, FLAG_ABC, FLAG_EVENT_P,
    FLAG_EVENT_Q, FLAG_EVENT_VALUE, FLAG_NAIVE_CAM, FLAG_RAPID, Field, KIND_ARC, KIND_BEGIN,
    KIND_END, KIND_EVENT, KIND_LINE, MoveMsg, PROTOCOL_VERSION, Reject,
};

/// A validated [`MoveMsg`].
#[derive(Clone, Debug, PartialEq)]
pub enum Resolved {
    /// Start of program `program_id`.
    Begin {
        /// The program.
        program_id: u64,
        /// The machine position the program starts from: X, Y, Z mm, A, B, C degrees.
        start_mm_deg: [f64; AXES],
        /// Number of items that will follow, 0 if unknown.
        total_items: u64,
    },
    /// A line, arc or helix.
    Move(Move),
    /// A non-motion event.
    Event(Event),
    /// End of program `program_id`.
    End {
        /// The program.
        program_id: u64,
        /// Number of items sent between BEGIN and END.
        items: u64,
    },
}

/// The `FLAG_*` bits of a message whose flags are allowed for its kind.
#[derive(Clone, Copy)]
struct Flags {
    /// [`FLAG_RAPID`].
    rapid: bool,
    /// [`FLAG_ABC`].
    abc: bool,
    /// [`FLAG_EVENT_VALUE`].
    has_value: bool,
    /// [`FLAG_NAIVE_CAM`].
    naive_cam: bool,
    /// [`FLAG_EVENT_P`].
    has_p: bool,
    /// [`FLAG_EVENT_Q`].
    has_q: bool,
}

impl TryFrom<&MoveMsg> for Resolved {
    type Error = Reject;

    fn try_from(m: &MoveMsg) -> Result<Resolved, Reject> {
        check_version(m)?;
        let allowed_flags = allowed_flags(m)?;
        check_program_id(m)?;
        let flags = check_flags(m, allowed_flags)?;
        check_unused_zero(m, flags)?;
        match m.kind {
            KIND_BEGIN => resolve_begin(m),
            KIND_END => Ok(Resolved::End {
                program_id: m.program_id,
                items: m.count,
            }),
            KIND_EVENT => resolve_event(m, flags),
            _ => resolve_move(m, flags),
        }
    }
}

/// The version differs: [`Reject::WrongVersion`].
fn check_version(m: &MoveMsg) -> Result<(), Reject> {
    if m.version != PROTOCOL_VERSION {
        return Err(Reject::WrongVersion { found: m.version });
    }
    Ok(())
}

/// The `FLAG_*` bits allowed for the message's kind (no naive-CAM tolerance with an exact
/// stop); an unknown kind is [`Reject::UnknownKind`].
fn allowed_flags(m: &MoveMsg) -> Result<u32, Reject> {
    Ok(match m.kind {
        KIND_BEGIN | KIND_END => 0,
        KIND_LINE | KIND_ARC if m.corner == CORNER_EXACT_STOP => FLAG_RAPID | FLAG_ABC,
        KIND_LINE | KIND_ARC => FLAG_RAPID | FLAG_ABC | FLAG_NAIVE_CAM,
        KIND_EVENT => FLAG_EVENT_VALUE | FLAG_EVENT_P | FLAG_EVENT_Q,
        other => return Err(Reject::UnknownKind(other)),
    })
}

/// `program_id` is 0: [`Reject::ProgramIdZero`].
fn check_program_id(m: &MoveMsg) -> Result<(), Reject> {
    if m.program_id == 0 {
        return Err(Reject::ProgramIdZero);
    }
    Ok(())
}

/// A flag bit not allowed for the kind is [`Reject::UnknownFlags`]; otherwise the flags.
fn check_flags(m: &MoveMsg, allowed_flags: u32) -> Result<Flags, Reject> {
    if m.flags & !allowed_flags != 0 {
        return Err(Reject::UnknownFlags(m.flags & !allowed_flags));
    }
    Ok(Flags {
        rapid: m.flags & FLAG_RAPID != 0,
        abc: m.flags & FLAG_ABC != 0,
        has_value: m.flags & FLAG_EVENT_VALUE != 0,
        naive_cam: m.flags & FLAG_NAIVE_CAM != 0,
        has_p: m.flags & FLAG_EVENT_P != 0,
        has_q: m.flags & FLAG_EVENT_Q != 0,
    })
}

/// `reserved`, and every field the kind (or its flags) does not use, must be zero (all
/// bits): [`Reject::NonzeroReserved`], naming the first such field (`reserved` first, then
/// in the order of the layout).
fn check_unused_zero(m: &MoveMsg, flags: Flags) -> Result<(), Reject> {
    use Field as F;
    let Flags {
        rapid,
        abc,
        has_value,
        naive_cam,
        has_p,
        has_q,
    } = flags;
    let is_move = m.kind == KIND_LINE || m.kind == KIND_ARC;
    zero_u(m.reserved, F::Reserved)?;
    let begin_end = m.kind == KIND_BEGIN || m.kind == KIND_END;
    if begin_end {
        zero_u(m.line.into(), F::Line)?;
    }
    if !is_move {
        zero_u(m.corner.into(), F::Corner)?;
    }
    if m.kind != KIND_EVENT {
        zero_u(m.event_code.into(), F::EventCode)?;
    }
    if !is_move || rapid {
        zero_f(m.feed_mm_min, F::FeedMmMin)?;
    }
    if !is_move || m.corner != CORNER_BLEND_TOLERANCE {
        zero_f(m.tolerance_mm, F::ToleranceMm)?;
    }
    if !is_move && m.kind != KIND_BEGIN {
        zero_a(&m.start_mm, F::StartMm)?;
    }
    if !is_move {
        zero_a(&m.end_mm, F::EndMm)?;
    }
    if m.kind != KIND_ARC {
        zero_a(&m.center_mm, F::CenterMm)?;
        zero_a(&m.axis, F::Axis)?;
        zero_f(m.sweep_rad, F::SweepRad)?;
    }
    if !(m.kind == KIND_BEGIN || is_move && abc) {
        zero_a(&m.abc_start_deg, F::AbcStartDeg)?;
    }
    if !(is_move && abc) {
        zero_a(&m.abc_end_deg, F::AbcEndDeg)?;
    }
    if !has_value {
        zero_f(m.event_value, F::EventValue)?;
    }
    if !begin_end {
        zero_u(m.count, F::Count)?;
    }
    if !naive_cam {
        zero_f(m.naive_cam_mm, F::NaiveCamMm)?;
    }
    if !has_p {
        zero_f(m.event_p, F::EventP)?;
    }
    if !has_q {
        zero_f(m.event_q, F::EventQ)?;
    }
    Ok(())
}

/// BEGIN: the start position must be finite ([`Reject::NonFinite`]).
fn resolve_begin(m: &MoveMsg) -> Result<Resolved, Reject> {
    use Field as F;
    finite_a(&m.start_mm, F::StartMm)?;
    finite_a(&m.abc_start_deg, F::AbcStartDeg)?;
    let [x, y, z] = m.start_mm;
    let [a, b, c] = m.abc_start_deg;
    Ok(Resolved::Begin {
        program_id: m.program_id,
        start_mm_deg: [x, y, z, a, b, c],
        total_items: m.count,
    })
}

/// An event: a finite value, line >= 1, a known code ([`Reject::UnknownEventCode`]), a
/// value exactly when the code takes one, no negative dwell ([`Reject::NegativeDwell`]).
fn resolve_event(m: &MoveMsg, flags: Flags) -> Result<Resolved, Reject> {
    use Field as F;
    let Flags {
        has_value,
        has_p,
        has_q,
        ..
    } = flags;
    if has_value {
        finite_f(m.event_value, F::EventValue)?;
    }
    if has_p {
        finite_f(m.event_p, F::EventP)?;
    }
    if has_q {
        finite_f(m.event_q, F::EventQ)?;
    }
    check_line(m)?;
    let code = event_code_from_u32(m.event_code).ok_or(Reject::UnknownEventCode(m.event_code))?;
    check_event_value(code, has_value)?;
    check_event_words(code, has_p, has_q)?;
    if code == EventCode::G4 && m.event_value < 0.0 {
        return Err(Reject::NegativeDwell);
    }
    let mut event = Event::new(m.line, code, has_value.then_some(m.event_value));
    event.p = has_p.then_some(m.event_p);
    event.q = has_q.then_some(m.event_q);
    Ok(Resolved::Event(event))
}

/// M19 and M66 may have a P (L) word, no other event ([`Reject::EventPUnexpected`]); M67
/// and M68 must have a Q word, M19, M66 and the user M codes may have one, no other event
/// ([`Reject::EventQ`]).
fn check_event_words(code: EventCode, has_p: bool, has_q: bool) -> Result<(), Reject> {
    use EventCode as C;
    let may_p = matches!(code, C::M19 | C::M66 | C::M66Analog);
    if has_p && !may_p {
        return Err(Reject::EventPUnexpected(code));
    }
    let needs_q = matches!(code, C::M67 | C::M68);
    let may_q = needs_q || may_p || matches!(code, C::User(_));
    match (needs_q, may_q, has_q) {
        (true, _, false) => Err(Reject::EventQ(code, true)),
        (_, false, true) => Err(Reject::EventQ(code, false)),
        _ => Ok(()),
    }
}

/// A move or event has line 0: [`Reject::LineZero`].
fn check_line(m: &MoveMsg) -> Result<(), Reject> {
    if m.line == 0 {
        return Err(Reject::LineZero);
    }
    Ok(())
}

/// S, T, G4, M50 to M53 and M62 to M68 (the output or input number) must have a value ([`Reject::EventValueMissing`]); M19 and the
/// user M codes may have one; the other codes take none ([`Reject::EventValueUnexpected`]).
fn check_event_value(code: EventCode, has_value: bool) -> Result<(), Reject> {
    let needs_value = matches!(
        code,
        EventCode::S
            | EventCode::T
            | EventCode::G4
            | EventCode::M50
            | EventCode::M51
            | EventCode::M52
            | EventCode::M53
            | EventCode::M62
            | EventCode::M63
            | EventCode::M64
            | EventCode::M65
            | EventCode::M66
            | EventCode::M66Analog
            | EventCode::M67
            | EventCode::M68
    );
    let may_have_value = needs_value || matches!(code, EventCode::User(_) | EventCode::M19);
    match (needs_value, has_value) {
        (true, false) => return Err(Reject::EventValueMissing(code)),
        (false, true) if may_have_value => {}
        (false, true) => return Err(Reject::EventValueUnexpected(code)),
        _ => {}
    }
    Ok(())
}

/// A line or an arc: every number finite, line >= 1, a known corner mode without a
/// negative tolerance, a positive feed ([`Reject::BadFeed`]) unless a rapid, and an arc's
/// geometry consistent.
fn resolve_move(m: &MoveMsg, flags: Flags) -> Result<Resolved, Reject> {
    let Flags {
        rapid,
        abc,
        naive_cam,
        ..
    } = flags;
    check_move_finite(m)?;
    check_line(m)?;
    let corner = corner_mode(m, naive_cam)?;
    if !rapid && m.feed_mm_min <= 0.0 {
        return Err(Reject::BadFeed);
    }
    let path = move_path(m)?;
    Ok(Resolved::Move(Move {
        line: m.line,
        rapid,
        path,
        feed_mm_min: (!rapid).then_some(m.feed_mm_min),
        abc_deg: abc.then_some((m.abc_start_deg, m.abc_end_deg)),
        corner,
    }))
}

/// Every number a move uses is finite: [`Reject::NonFinite`], naming the first one that is
/// not (in the order of the layout).
fn check_move_finite(m: &MoveMsg) -> Result<(), Reject> {
    use Field as F;
    finite_f(m.feed_mm_min, F::FeedMmMin)?;
    finite_f(m.tolerance_mm, F::ToleranceMm)?;
    finite_a(&m.start_mm, F::StartMm)?;
    finite_a(&m.end_mm, F::EndMm)?;
    finite_a(&m.center_mm, F::CenterMm)?;
    finite_a(&m.axis, F::Axis)?;
    finite_f(m.sweep_rad, F::SweepRad)?;
    finite_a(&m.abc_start_deg, F::AbcStartDeg)?;
    finite_a(&m.abc_end_deg, F::AbcEndDeg)?;
    finite_f(m.naive_cam_mm, F::NaiveCamMm)?;
    Ok(())
}

/// The corner mode: an unknown one is [`Reject::UnknownCorner`]; a negative naive-CAM
/// tolerance (checked first) or blend tolerance is [`Reject::NegativeTolerance`].
fn corner_mode(m: &MoveMsg, naive_cam: bool) -> Result<CornerMode, Reject> {
    let naive_cam_mm = if naive_cam {
        if m.naive_cam_mm < 0.0 {
            return Err(Reject::NegativeTolerance);
        }
        Some(m.naive_cam_mm)
    } else {
        None
    };
    let corner = match m.corner {
        CORNER_EXACT_STOP => CornerMode::ExactStop,
        CORNER_BLEND_DEFAULT => CornerMode::Blend {
            tolerance_mm: None,
            naive_cam_mm,
        },
        CORNER_BLEND_TOLERANCE => {
            if m.tolerance_mm < 0.0 {
                return Err(Reject::NegativeTolerance);
            }
            CornerMode::Blend {
                tolerance_mm: Some(m.tolerance_mm),
                naive_cam_mm,
            }
        }
        other => return Err(Reject::UnknownCorner(other)),
    };
    Ok(corner)
}

/// The move's path: a line, or an arc whose geometry agrees ([`check_arc`]).
fn move_path(m: &MoveMsg) -> Result<Path, Reject> {
    let start = vec(&m.start_mm);
    let end = vec(&m.end_mm);
    let path = if m.kind == KIND_ARC {
        let a = Arc {
            start,
            end,
            center: vec(&m.center_mm),
            axis: vec(&m.axis),
            sweep_rad: m.sweep_rad,
        };
        check_arc(&a)?;
        Path::Arc(a)
    } else {
        Path::Line(Line { start, end })
    };
    Ok(path)
}

fn vec(a: &[f64; 3]) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}

/// Requires `v` (all bits) zero.
fn zero_f(v: f64, field: Field) -> Result<(), Reject> {
    if v.to_bits() == 0 {
        Ok(())
    } else {
        Err(Reject::NonzeroReserved { field })
    }
}

fn zero_a(v: &[f64; 3], field: Field) -> Result<(), Reject> {
    v.iter().try_for_each(|&x| zero_f(x, field))
}

fn zero_u(v: u64, field: Field) -> Result<(), Reject> {
    if v == 0 {
        Ok(())
    } else {
        Err(Reject::NonzeroReserved { field })
    }
}

fn finite_f(v: f64, field: Field) -> Result<(), Reject> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(Reject::NonFinite { field })
    }
}

fn finite_a(v: &[f64; 3], field: Field) -> Result<(), Reject> {
    v.iter().try_for_each(|&x| finite_f(x, field))
}
