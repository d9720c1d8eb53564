//! [`MoveMsg`]: one program item on the moves service, its encoding from the interpreter's
//! types and its validating decoding into [`Resolved`].

use iceoryx2::prelude::ZeroCopySend;
use kerf_geom::{Arc, CornerMode, Line, Move, Path, Vec3};
use kerf_geom::{Event, EventCode};

use crate::{AXES, PROTOCOL_VERSION};

/// Message kind: start of a program (see [`MoveMsg::begin`]).
pub const KIND_BEGIN: u32 = 1;
/// Message kind: a straight line (feed move or rapid).
pub const KIND_LINE: u32 = 2;
/// Message kind: a circular arc or helix.
pub const KIND_ARC: u32 = 3;
/// Message kind: a non-motion event (M code, S, T, dwell).
pub const KIND_EVENT: u32 = 4;
/// Message kind: end of a program (see [`MoveMsg::end`]).
pub const KIND_END: u32 = 5;

/// Flag (lines and arcs): the move is a rapid; `feed_mm_min` must be zero.
pub const FLAG_RAPID: u32 = 1 << 0;
/// Flag (lines and arcs): `abc_start_deg` and `abc_end_deg` hold the rotary axes;
/// without it they must be zero.
pub const FLAG_ABC: u32 = 1 << 1;
/// Flag (events): `event_value` holds the event's value; without it it must be zero.
pub const FLAG_EVENT_VALUE: u32 = 1 << 2;
/// Flag (blending lines and arcs): `naive_cam_mm` holds LinuxCNC's naive-CAM tolerance
/// (G64 Q); without it it must be zero. Not allowed with [`CORNER_EXACT_STOP`].
pub const FLAG_NAIVE_CAM: u32 = 1 << 3;

/// Corner mode: exact stop at the end of the move.
pub const CORNER_EXACT_STOP: u32 = 1;
/// Corner mode: blend within the daemon's configured default tolerance.
pub const CORNER_BLEND_DEFAULT: u32 = 2;
/// Corner mode: blend within `tolerance_mm`.
pub const CORNER_BLEND_TOLERANCE: u32 = 3;

/// Event code M0 (program stop).
pub const EVENT_M0: u32 = 1;
/// Event code M1 (optional program stop).
pub const EVENT_M1: u32 = 2;
/// Event code M2 (program end).
pub const EVENT_M2: u32 = 3;
/// Event code M30 (program end and rewind).
pub const EVENT_M30: u32 = 4;
/// Event code M3 (spindle clockwise).
pub const EVENT_M3: u32 = 5;
/// Event code M4 (spindle counter-clockwise).
pub const EVENT_M4: u32 = 6;
/// Event code M5 (spindle stop).
pub const EVENT_M5: u32 = 7;
/// Event code M6 (tool change).
pub const EVENT_M6: u32 = 8;
/// Event code M7 (mist coolant on).
pub const EVENT_M7: u32 = 9;
/// Event code M8 (flood coolant on).
pub const EVENT_M8: u32 = 10;
/// Event code M9 (coolant off).
pub const EVENT_M9: u32 = 11;
/// Event code S (spindle speed, value rpm).
pub const EVENT_S: u32 = 12;
/// Event code T (tool select, value tool number).
pub const EVENT_T: u32 = 13;
/// Event code G4 (dwell, value seconds).
pub const EVENT_G4: u32 = 14;
/// Pallet change pause (LinuxCNC M60): a program pause like M0.
pub const EVENT_M60: u32 = 15;
/// Operator message (`(MSG, ...)`); the text stays with the planner process.
pub const EVENT_MSG: u32 = 16;
/// Debug message (`(DEBUG, ...)`); the text stays with the planner process.
pub const EVENT_DEBUG: u32 = 17;
/// Print message (`(PRINT, ...)`); the text stays with the planner process.
pub const EVENT_PRINT: u32 = 18;
/// Spindle orientation (LinuxCNC M19, and ORIENT_SPINDLE of G87 back boring); value: the
/// angle, degrees.
pub const EVENT_M19: u32 = 19;
/// Feed and spindle overrides enabled (LinuxCNC M48).
pub const EVENT_M48: u32 = 20;
/// Feed and spindle overrides disabled (LinuxCNC M49).
pub const EVENT_M49: u32 = 21;
/// Feed override control (LinuxCNC M50); value 1 enabled, 0 disabled.
pub const EVENT_M50: u32 = 22;
/// Spindle speed override control (LinuxCNC M51); value 1 enabled, 0 disabled.
pub const EVENT_M51: u32 = 23;
/// Adaptive feed control (LinuxCNC M52); value 1 enabled, 0 disabled.
pub const EVENT_M52: u32 = 24;
/// Feed stop control (LinuxCNC M53); value 1 enabled, 0 disabled.
pub const EVENT_M53: u32 = 25;
/// LinuxCNC log call (`LOGOPEN`, `LOGAPPEND`, `LOG`, `LOGCLOSE`); the text (the call) stays
/// with the planner process.
pub const EVENT_LOG: u32 = 26;
/// User M code M100 (LinuxCNC); M100 + n is `EVENT_USER_M100 + n`; value: its P word.
pub const EVENT_USER_M100: u32 = 100;
/// User M code M199, the last one.
pub const EVENT_USER_M199: u32 = 199;

/// Allowed deviation of `|axis|` from 1 (absolute).
pub const AXIS_UNIT_TOL: f64 = 1e-9;
/// The absolute part of the arc tolerance, mm: how far `end_mm` may lie from the point
/// that `start_mm`, `center_mm`, `axis` and `sweep_rad` lead to (see [`arc_tolerance_mm`]).
/// The interpreter's arcs agree to rounding (about 1e-13 mm at ordinary coordinates); one
/// micrometre leaves room for planners that compute arcs in other ways while refusing
/// data that disagree by a visible amount of path, at any radius.
pub const ARC_END_TOL_MM: f64 = 1e-6;
/// The relative part of the arc tolerance, 2^-46: the rounding of the arc's numbers
/// themselves, 64 units in the last place of the largest one (1.4e-12 mm at 100 mm; it
/// reaches [`ARC_END_TOL_MM`] only beyond 7e7 mm).
pub const ARC_ROUNDING_REL: f64 = 1.0 / 70_368_744_177_664.0;
/// Smallest arc radius accepted, mm (the geometry degenerates below it).
pub const ARC_MIN_RADIUS_MM: f64 = 1e-12;

/// One program item on the moves service: BEGIN, line, arc/helix, event or END.
///
/// Plain old data: every bit pattern is a valid value, meaning comes from the `u32`
/// constants (`KIND_*`, `FLAG_*`, `CORNER_*`, `EVENT_*`). Fields a kind does not use, and
/// `reserved`, must be zero (all bits: `-0.0` is not zero). Lengths are mm in absolute
/// machine coordinates, rotary axes degrees. The layout is specified byte for byte in
/// `docs/PROTOCOL.md`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[type_name("kerf.MoveMsg.v3")]
pub struct MoveMsg {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// `KIND_*`.
    pub kind: u32,
    /// The program this item belongs to; never 0.
    pub program_id: u64,
    /// BEGIN 0, the n-th item n, END (number of items + 1).
    pub seq: u64,
    /// 1-based source line (moves and events); 0 for BEGIN and END.
    pub line: u32,
    /// `FLAG_*` bits allowed for the kind.
    pub flags: u32,
    /// `CORNER_*` (moves); 0 otherwise.
    pub corner: u32,
    /// `EVENT_*` (events); 0 otherwise.
    pub event_code: u32,
    /// Feed along the path, mm/min (feed moves, > 0); 0 for rapids and non-moves.
    pub feed_mm_min: f64,
    /// Blend tolerance, mm (>= 0) with [`CORNER_BLEND_TOLERANCE`]; 0 otherwise.
    pub tolerance_mm: f64,
    /// Moves: start point, mm. BEGIN: the X, Y, Z the program starts from.
    pub start_mm: [f64; 3],
    /// Moves: end point, mm.
    pub end_mm: [f64; 3],
    /// Arcs: centre, in the plane through the start normal to `axis`, mm.
    pub center_mm: [f64; 3],
    /// Arcs: unit normal of the arc's plane.
    pub axis: [f64; 3],
    /// Arcs: signed swept angle about `axis` (right-hand rule), whole turns included, rad.
    pub sweep_rad: f64,
    /// Moves with [`FLAG_ABC`]: A, B, C at the start, degrees. BEGIN: the A, B, C the
    /// program starts from.
    pub abc_start_deg: [f64; 3],
    /// Moves with [`FLAG_ABC`]: A, B, C at the end, degrees.
    pub abc_end_deg: [f64; 3],
    /// Events with [`FLAG_EVENT_VALUE`]: S rpm, T tool number, G4 seconds.
    pub event_value: f64,
    /// BEGIN: number of items that will follow (0 = unknown). END: number of items sent.
    pub count: u64,
    /// Blending moves with [`FLAG_NAIVE_CAM`]: LinuxCNC's naive-CAM tolerance, mm (>= 0).
    pub naive_cam_mm: f64,
    /// Must be zero.
    pub reserved: [u64; 3],
}

/// A field of [`MoveMsg`], as named by a [`Reject`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[allow(missing_docs)]
pub enum Field {
    Line,
    Flags,
    Corner,
    EventCode,
    FeedMmMin,
    ToleranceMm,
    StartMm,
    EndMm,
    CenterMm,
    Axis,
    SweepRad,
    AbcStartDeg,
    AbcEndDeg,
    EventValue,
    Count,
    NaiveCamMm,
    Reserved,
}

impl Field {
    /// The field's name in [`MoveMsg`] and `docs/PROTOCOL.md`.
    pub fn as_str(self) -> &'static str {
        match self {
            Field::Line => "line",
            Field::Flags => "flags",
            Field::Corner => "corner",
            Field::EventCode => "event_code",
            Field::FeedMmMin => "feed_mm_min",
            Field::ToleranceMm => "tolerance_mm",
            Field::StartMm => "start_mm",
            Field::EndMm => "end_mm",
            Field::CenterMm => "center_mm",
            Field::Axis => "axis",
            Field::SweepRad => "sweep_rad",
            Field::AbcStartDeg => "abc_start_deg",
            Field::AbcEndDeg => "abc_end_deg",
            Field::EventValue => "event_value",
            Field::Count => "count",
            Field::NaiveCamMm => "naive_cam_mm",
            Field::Reserved => "reserved",
        }
    }
}

impl std::fmt::Display for Field {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A distance in a message: "90.000 mm" above a micrometre, "2.8e-6 mm" below.
struct Mm(f64);

impl std::fmt::Display for Mm {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0.abs() >= 1e-3 {
            write!(f, "{:.3} mm", self.0)
        } else {
            write!(f, "{:.1e} mm", self.0)
        }
    }
}

/// A tolerance in a message, two significant digits: "1.4e-6".
struct Tol(f64);

impl std::fmt::Display for Tol {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:.1e}", self.0)
    }
}

/// Why a [`MoveMsg`] was refused. The checks run in the order of the variants below (first
/// the envelope, then the fields the kind does not use, then finiteness, then meaning), and
/// the first failing one is reported.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum Reject {
    /// `version` is not [`PROTOCOL_VERSION`].
    #[error("protocol version {found}, expected {PROTOCOL_VERSION}")]
    WrongVersion {
        /// The version found.
        found: u32,
    },
    /// `kind` is none of the `KIND_*` constants.
    #[error("unknown message kind {0}")]
    UnknownKind(u32),
    /// `program_id` is 0.
    #[error("program id 0 (reserved for \"no program\")")]
    ProgramIdZero,
    /// `flags` has bits that are not defined for this kind.
    #[error("flag bits {0:#x} are not defined for this message kind")]
    UnknownFlags(u32),
    /// `reserved`, or a field this kind (or its flags) does not use, is not zero.
    #[error("field {field} must be zero in this message")]
    NonzeroReserved {
        /// The field.
        field: Field,
    },
    /// A number the message uses is NaN or infinite.
    #[error("field {field} is not a finite number")]
    NonFinite {
        /// The field.
        field: Field,
    },
    /// A move or event has source line 0.
    #[error("source line 0 (lines are counted from 1)")]
    LineZero,
    /// `corner` is none of the `CORNER_*` constants.
    #[error("unknown corner mode {0}")]
    UnknownCorner(u32),
    /// The blend tolerance (or the naive-CAM tolerance) is negative.
    #[error("negative blend tolerance")]
    NegativeTolerance,
    /// A feed move has a feed of zero or less.
    #[error("feed move with a feed of zero or less")]
    BadFeed,
    /// An arc's axis is not of unit length (within [`AXIS_UNIT_TOL`]).
    #[error("arc axis is not a unit vector")]
    AxisNotUnit,
    /// An arc's start lies on its centre (radius below [`ARC_MIN_RADIUS_MM`]).
    #[error("arc radius is zero")]
    ZeroRadius,
    /// An arc's centre is farther from the plane through its start normal to the axis
    /// than the arc tolerance ([`arc_tolerance_mm`]).
    #[error(
        "arc center_mm is {} from the plane of its start point (tolerance {} mm)",
        Mm(*off_mm),
        Tol(*tol_mm)
    )]
    CenterOffPlane {
        /// The centre's distance from the start's plane, mm.
        off_mm: f64,
        /// The arc tolerance, mm.
        tol_mm: f64,
    },
    /// An arc sweeps no angle.
    #[error("arc sweeps a zero angle")]
    ZeroSweep,
    /// `end_mm` is farther from the point `sweep_rad` leads to than the arc tolerance
    /// ([`arc_tolerance_mm`]): the fields disagree about where the arc ends.
    #[error(
        "arc end_mm is {} from the point its sweep_rad leads to (tolerance {} mm): \
         sweep_rad and end_mm disagree",
        Mm(*off_mm),
        Tol(*tol_mm)
    )]
    EndMismatch {
        /// The distance between `end_mm` and the point the sweep leads to, mm (NaN when it
        /// could not be computed).
        off_mm: f64,
        /// The arc tolerance, mm.
        tol_mm: f64,
    },
    /// `event_code` is none of the `EVENT_*` constants.
    #[error("unknown event code {0}")]
    UnknownEventCode(u32),
    /// An S, T or G4 event without a value.
    #[error("event {} needs a value", .0.as_str())]
    EventValueMissing(EventCode),
    /// An M-code event with a value.
    #[error("event {} takes no value", .0.as_str())]
    EventValueUnexpected(EventCode),
    /// A dwell of negative time.
    #[error("negative dwell time")]
    NegativeDwell,
}

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

/// The `EVENT_*` code of an event code.
pub fn event_code_to_u32(code: EventCode) -> u32 {
    match code {
        EventCode::M0 => EVENT_M0,
        EventCode::M1 => EVENT_M1,
        EventCode::M2 => EVENT_M2,
        EventCode::M30 => EVENT_M30,
        EventCode::M3 => EVENT_M3,
        EventCode::M4 => EVENT_M4,
        EventCode::M5 => EVENT_M5,
        EventCode::M6 => EVENT_M6,
        EventCode::M7 => EVENT_M7,
        EventCode::M8 => EVENT_M8,
        EventCode::M9 => EVENT_M9,
        EventCode::S => EVENT_S,
        EventCode::T => EVENT_T,
        EventCode::G4 => EVENT_G4,
        EventCode::M60 => EVENT_M60,
        EventCode::M19 => EVENT_M19,
        EventCode::M48 => EVENT_M48,
        EventCode::M49 => EVENT_M49,
        EventCode::M50 => EVENT_M50,
        EventCode::M51 => EVENT_M51,
        EventCode::M52 => EVENT_M52,
        EventCode::M53 => EVENT_M53,
        EventCode::Msg => EVENT_MSG,
        EventCode::Debug => EVENT_DEBUG,
        EventCode::Print => EVENT_PRINT,
        EventCode::Log => EVENT_LOG,
        EventCode::User(n) => EVENT_USER_M100 + u32::from(n.min(99)),
    }
}

/// The event code of an `EVENT_*` value, `None` for any other.
pub fn event_code_from_u32(code: u32) -> Option<EventCode> {
    Some(match code {
        EVENT_M0 => EventCode::M0,
        EVENT_M1 => EventCode::M1,
        EVENT_M2 => EventCode::M2,
        EVENT_M30 => EventCode::M30,
        EVENT_M3 => EventCode::M3,
        EVENT_M4 => EventCode::M4,
        EVENT_M5 => EventCode::M5,
        EVENT_M6 => EventCode::M6,
        EVENT_M7 => EventCode::M7,
        EVENT_M8 => EventCode::M8,
        EVENT_M9 => EventCode::M9,
        EVENT_S => EventCode::S,
        EVENT_T => EventCode::T,
        EVENT_G4 => EventCode::G4,
        EVENT_M60 => EventCode::M60,
        EVENT_M19 => EventCode::M19,
        EVENT_M48 => EventCode::M48,
        EVENT_M49 => EventCode::M49,
        EVENT_M50 => EventCode::M50,
        EVENT_M51 => EventCode::M51,
        EVENT_M52 => EventCode::M52,
        EVENT_M53 => EventCode::M53,
        EVENT_MSG => EventCode::Msg,
        EVENT_DEBUG => EventCode::Debug,
        EVENT_PRINT => EventCode::Print,
        EVENT_LOG => EventCode::Log,
        c @ EVENT_USER_M100..=EVENT_USER_M199 => EventCode::User((c - EVENT_USER_M100) as u8),
        _ => return None,
    })
}

fn arr(v: &Vec3) -> [f64; 3] {
    [v.x, v.y, v.z]
}

fn vec(a: &[f64; 3]) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}

impl Default for MoveMsg {
    fn default() -> Self {
        MoveMsg::zeroed()
    }
}

impl MoveMsg {
    /// All fields zero (not a valid message: the version is 0).
    pub const fn zeroed() -> MoveMsg {
        MoveMsg {
            version: 0,
            kind: 0,
            program_id: 0,
            seq: 0,
            line: 0,
            flags: 0,
            corner: 0,
            event_code: 0,
            feed_mm_min: 0.0,
            tolerance_mm: 0.0,
            start_mm: [0.0; 3],
            end_mm: [0.0; 3],
            center_mm: [0.0; 3],
            axis: [0.0; 3],
            sweep_rad: 0.0,
            abc_start_deg: [0.0; 3],
            abc_end_deg: [0.0; 3],
            event_value: 0.0,
            count: 0,
            naive_cam_mm: 0.0,
            reserved: [0; 3],
        }
    }

    fn header(kind: u32, program_id: u64, seq: u64) -> MoveMsg {
        MoveMsg {
            version: PROTOCOL_VERSION,
            kind,
            program_id,
            seq,
            ..MoveMsg::zeroed()
        }
    }

    /// The BEGIN message of program `program_id` (sequence number 0): the machine position
    /// the program starts from (X, Y, Z mm, A, B, C degrees) and the number of items that
    /// will follow (0 if unknown).
    pub fn begin(program_id: u64, start_mm_deg: [f64; AXES], total_items: u64) -> MoveMsg {
        let mut m = MoveMsg::header(KIND_BEGIN, program_id, 0);
        m.start_mm = [start_mm_deg[0], start_mm_deg[1], start_mm_deg[2]];
        m.abc_start_deg = [start_mm_deg[3], start_mm_deg[4], start_mm_deg[5]];
        m.count = total_items;
        m
    }

    /// The END message of program `program_id` after `items` items (sequence number
    /// `items + 1`).
    pub fn end(program_id: u64, items: u64) -> MoveMsg {
        let mut m = MoveMsg::header(KIND_END, program_id, items.saturating_add(1));
        m.count = items;
        m
    }

    /// Item `seq` (1-based) of program `program_id`: a line, arc or helix. Encodes the move
    /// as it is; whether it is valid is for the receiver's [`TryFrom`] to decide.
    pub fn from_move(program_id: u64, seq: u64, mv: &Move) -> MoveMsg {
        let mut m = MoveMsg::header(KIND_LINE, program_id, seq);
        m.line = mv.line;
        if mv.rapid {
            m.flags |= FLAG_RAPID;
        }
        m.feed_mm_min = mv.feed_mm_min.unwrap_or(0.0);
        match mv.corner {
            CornerMode::ExactStop => m.corner = CORNER_EXACT_STOP,
            CornerMode::Blend {
                tolerance_mm,
                naive_cam_mm,
            } => {
                match tolerance_mm {
                    None => m.corner = CORNER_BLEND_DEFAULT,
                    Some(t) => {
                        m.corner = CORNER_BLEND_TOLERANCE;
                        m.tolerance_mm = t;
                    }
                }
                if let Some(q) = naive_cam_mm {
                    m.flags |= FLAG_NAIVE_CAM;
                    m.naive_cam_mm = q;
                }
            }
        }
        match &mv.path {
            Path::Line(l) => {
                m.start_mm = arr(&l.start);
                m.end_mm = arr(&l.end);
            }
            Path::Arc(a) => {
                m.kind = KIND_ARC;
                m.start_mm = arr(&a.start);
                m.end_mm = arr(&a.end);
                m.center_mm = arr(&a.center);
                m.axis = arr(&a.axis);
                m.sweep_rad = a.sweep_rad;
            }
        }
        if let Some((s, e)) = mv.abc_deg {
            m.flags |= FLAG_ABC;
            m.abc_start_deg = s;
            m.abc_end_deg = e;
        }
        m
    }

    /// Item `seq` (1-based) of program `program_id`: a non-motion event.
    pub fn from_event(program_id: u64, seq: u64, ev: &Event) -> MoveMsg {
        let mut m = MoveMsg::header(KIND_EVENT, program_id, seq);
        m.line = ev.line;
        m.event_code = event_code_to_u32(ev.code);
        if let Some(v) = ev.value {
            m.flags |= FLAG_EVENT_VALUE;
            m.event_value = v;
        }
        m
    }

    /// Item `seq` (1-based) of program `program_id`.
    pub fn from_item(program_id: u64, seq: u64, item: &kerf_geom::Item) -> MoveMsg {
        match item {
            kerf_geom::Item::Move(mv) => MoveMsg::from_move(program_id, seq, mv),
            kerf_geom::Item::Event(ev) => MoveMsg::from_event(program_id, seq, ev),
        }
    }
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

/// The arc tolerance for an arc of radius `radius_mm` (the start's distance from the
/// centre normal to the axis): `ARC_END_TOL_MM + ARC_ROUNDING_REL × m`, `m` the largest
/// magnitude among the coordinates of start, end and centre and the path length
/// `radius_mm · |sweep_rad|`. NaN when a number is NaN.
fn tolerance_for(a: &Arc, radius_mm: f64) -> f64 {
    let mut largest = radius_mm * a.sweep_rad.abs();
    for p in [&a.start, &a.end, &a.center] {
        for &c in p.iter() {
            // Written so that a NaN anywhere makes the result NaN (`f64::max` drops it).
            if largest.is_nan() || c.is_nan() {
                return f64::NAN;
            }
            largest = largest.max(c.abs());
        }
    }
    ARC_END_TOL_MM + ARC_ROUNDING_REL * largest
}

/// The arc tolerance of `a`, mm (docs/PROTOCOL.md, "One arc, in millimetres"):
/// `ARC_END_TOL_MM + ARC_ROUNDING_REL × m`, where `m` is the largest magnitude among the
/// coordinates of `start`, `end` and `center` and the path length `r · |sweep_rad|`, `r`
/// being the start's distance from the centre normal to the axis. It bounds both the
/// distance of `end` from the point the sweep leads to and the centre's distance from the
/// start's plane. NaN when a number is NaN; infinite when the path length overflows
/// (such an arc is refused).
pub fn arc_tolerance_mm(a: &Arc) -> f64 {
    let axis = a.axis.try_normalize(0.0).unwrap_or_else(Vec3::zeros);
    let u = a.start - a.center;
    let radius_mm = (u - axis * u.dot(&axis)).norm();
    tolerance_for(a, radius_mm)
}

/// Checks the arc's geometry in millimetres of path (docs/PROTOCOL.md, "One arc, in
/// millimetres"); all inputs are finite. Every check is written as "within" (a comparison
/// that is false for NaN, then negated) so that a NaN from overflowing intermediate values
/// (huge coordinates) refuses the arc.
fn check_arc(a: &Arc) -> Result<(), Reject> {
    let norm = a.axis.norm();
    let unit = (norm - 1.0).abs() <= AXIS_UNIT_TOL;
    if !unit {
        return Err(Reject::AxisNotUnit);
    }
    let axis = a.axis / norm;
    let u = a.start - a.center;
    let along = u.dot(&axis);
    let u = u - axis * along;
    let radius_mm = u.norm();
    let has_radius = radius_mm >= ARC_MIN_RADIUS_MM;
    if !has_radius {
        return Err(Reject::ZeroRadius);
    }
    let tol_mm = tolerance_for(a, radius_mm);
    let plane_off_mm = along.abs();
    let in_plane = plane_off_mm <= tol_mm;
    if !in_plane {
        return Err(Reject::CenterOffPlane {
            off_mm: plane_off_mm,
            tol_mm,
        });
    }
    if a.sweep_rad == 0.0 {
        return Err(Reject::ZeroSweep);
    }
    // q − start = r (e1 (cos θ − 1) + e2 sin θ) + a h, with cos θ − 1 = −2 sin²(θ/2) so
    // that a small angle on a huge radius keeps its precision; compared with end − start
    // rather than q with end, so that coordinates far from the origin lose nothing either.
    let e1 = u / radius_mm;
    let e2 = axis.cross(&e1);
    let theta = a.sweep_rad;
    let half_sin = (0.5 * theta).sin();
    let cos_minus_1 = -2.0 * half_sin * half_sin;
    let chord = a.end - a.start;
    let lead = (e1 * cos_minus_1 + e2 * theta.sin()) * radius_mm + axis * chord.dot(&axis);
    let off_mm = (lead - chord).norm();
    // An infinite tolerance (a path length beyond f64) accepts nothing.
    let agree = off_mm <= tol_mm && tol_mm < f64::INFINITY;
    if !agree {
        return Err(Reject::EndMismatch { off_mm, tol_mm });
    }
    Ok(())
}

impl TryFrom<&MoveMsg> for Resolved {
    type Error = Reject;

    fn try_from(m: &MoveMsg) -> Result<Resolved, Reject> {
        use Field as F;
        if m.version != PROTOCOL_VERSION {
            return Err(Reject::WrongVersion { found: m.version });
        }
        let is_move = m.kind == KIND_LINE || m.kind == KIND_ARC;
        let allowed_flags = match m.kind {
            KIND_BEGIN | KIND_END => 0,
            KIND_LINE | KIND_ARC if m.corner == CORNER_EXACT_STOP => FLAG_RAPID | FLAG_ABC,
            KIND_LINE | KIND_ARC => FLAG_RAPID | FLAG_ABC | FLAG_NAIVE_CAM,
            KIND_EVENT => FLAG_EVENT_VALUE,
            other => return Err(Reject::UnknownKind(other)),
        };
        if m.program_id == 0 {
            return Err(Reject::ProgramIdZero);
        }
        if m.flags & !allowed_flags != 0 {
            return Err(Reject::UnknownFlags(m.flags & !allowed_flags));
        }
        let rapid = m.flags & FLAG_RAPID != 0;
        let abc = m.flags & FLAG_ABC != 0;
        let has_value = m.flags & FLAG_EVENT_VALUE != 0;
        let naive_cam = m.flags & FLAG_NAIVE_CAM != 0;

        // Fields the kind does not use must be zero.
        m.reserved
            .iter()
            .try_for_each(|&r| zero_u(r, F::Reserved))?;
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

        match m.kind {
            KIND_BEGIN => {
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
            KIND_END => Ok(Resolved::End {
                program_id: m.program_id,
                items: m.count,
            }),
            KIND_EVENT => {
                if has_value {
                    finite_f(m.event_value, F::EventValue)?;
                }
                if m.line == 0 {
                    return Err(Reject::LineZero);
                }
                let code = event_code_from_u32(m.event_code)
                    .ok_or(Reject::UnknownEventCode(m.event_code))?;
                let needs_value = matches!(
                    code,
                    EventCode::S
                        | EventCode::T
                        | EventCode::G4
                        | EventCode::M50
                        | EventCode::M51
                        | EventCode::M52
                        | EventCode::M53
                );
                let may_have_value =
                    needs_value || matches!(code, EventCode::User(_) | EventCode::M19);
                match (needs_value, has_value) {
                    (true, false) => return Err(Reject::EventValueMissing(code)),
                    (false, true) if may_have_value => {}
                    (false, true) => return Err(Reject::EventValueUnexpected(code)),
                    _ => {}
                }
                if code == EventCode::G4 && m.event_value < 0.0 {
                    return Err(Reject::NegativeDwell);
                }
                Ok(Resolved::Event(Event::new(
                    m.line,
                    code,
                    has_value.then_some(m.event_value),
                )))
            }
            _ => {
                // A line or an arc.
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
                if m.line == 0 {
                    return Err(Reject::LineZero);
                }
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
                if !rapid && m.feed_mm_min <= 0.0 {
                    return Err(Reject::BadFeed);
                }
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
                Ok(Resolved::Move(Move {
                    line: m.line,
                    rapid,
                    path,
                    feed_mm_min: (!rapid).then_some(m.feed_mm_min),
                    abc_deg: abc.then_some((m.abc_start_deg, m.abc_end_deg)),
                    corner,
                }))
            }
        }
    }
}
