//! The layout of [`MoveMsg`] (specified byte for byte in `docs/PROTOCOL.md`) and the
//! constants that give its `kind`, `flags` and `corner` fields their meaning; the names
//! of its fields ([`Field`]).

use iceoryx2::prelude::ZeroCopySend;

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
/// Flag (events): `event_p` holds the event's P or L word (M19 the direction mode, M66 the
/// wait mode); without it it must be zero.
pub const FLAG_EVENT_P: u32 = 1 << 4;
/// Flag (events): `event_q` holds the event's Q word (M19 and M66 the timeout, M67 and
/// M68 the value, user M codes their Q); without it it must be zero.
pub const FLAG_EVENT_Q: u32 = 1 << 5;

/// Corner mode: exact stop at the end of the move.
pub const CORNER_EXACT_STOP: u32 = 1;
/// Corner mode: blend within the daemon's configured default tolerance.
pub const CORNER_BLEND_DEFAULT: u32 = 2;
/// Corner mode: blend within `tolerance_mm`.
pub const CORNER_BLEND_TOLERANCE: u32 = 3;

/// One program item on the moves service: BEGIN, line, arc/helix, event or END.
///
/// Plain old data: every bit pattern is a valid value, meaning comes from the `u32`
/// constants (`KIND_*`, `FLAG_*`, `CORNER_*`, `EVENT_*`). Fields a kind does not use, and
/// `reserved`, must be zero (all bits: `-0.0` is not zero). Lengths are mm in absolute
/// machine coordinates, rotary axes degrees. The layout is specified byte for byte in
/// `docs/PROTOCOL.md`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[type_name("kerf.MoveMsg.v6")]
pub struct MoveMsg {
    /// [`PROTOCOL_VERSION`].
    ///
    /// [`PROTOCOL_VERSION`]: crate::PROTOCOL_VERSION
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
    /// Events with [`FLAG_EVENT_P`]: M19 the direction mode (P), M66 the wait mode (L).
    pub event_p: f64,
    /// Events with [`FLAG_EVENT_Q`]: the Q word.
    pub event_q: f64,
    /// Must be zero.
    pub reserved: u64,
}

/// A field of [`MoveMsg`], as named by a [`Reject`](crate::Reject).
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
    EventP,
    EventQ,
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
            Field::EventP => "event_p",
            Field::EventQ => "event_q",
            Field::Reserved => "reserved",
        }
    }
}

impl std::fmt::Display for Field {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
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
            event_p: 0.0,
            event_q: 0.0,
            reserved: 0,
        }
    }
}
