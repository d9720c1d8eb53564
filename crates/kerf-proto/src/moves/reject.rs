//! Why a [`MoveMsg`] was refused ([`Reject`]), naming the [`Field`] at fault.
//!
//! [`MoveMsg`]: crate::MoveMsg

use kerf_geom::EventCode;

use crate::{Field, PROTOCOL_VERSION};

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
///
/// [`MoveMsg`]: crate::MoveMsg
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
    ///
    /// [`AXIS_UNIT_TOL`]: crate::AXIS_UNIT_TOL
    #[error("arc axis is not a unit vector")]
    AxisNotUnit,
    /// An arc's start lies on its centre (radius below [`ARC_MIN_RADIUS_MM`]).
    ///
    /// [`ARC_MIN_RADIUS_MM`]: crate::ARC_MIN_RADIUS_MM
    #[error("arc radius is zero")]
    ZeroRadius,
    /// An arc's centre is farther from the plane through its start normal to the axis
    /// than the arc tolerance ([`arc_tolerance_mm`]).
    ///
    /// [`arc_tolerance_mm`]: crate::arc_tolerance_mm
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
    ///
    /// [`arc_tolerance_mm`]: crate::arc_tolerance_mm
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
    /// An event that takes no P (L) word has one in `event_p`.
    #[error("event {} takes no P or L word", .0.as_str())]
    EventPUnexpected(EventCode),
    /// An event that must have a Q word lacks it, or one that takes none has one.
    #[error("event {} {}", .0.as_str(), if *.1 { "needs a Q word" } else { "takes no Q word" })]
    EventQ(EventCode, bool),
    /// A dwell of negative time.
    #[error("negative dwell time")]
    NegativeDwell,
}
