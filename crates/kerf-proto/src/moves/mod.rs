//! [`MoveMsg`]: one program item on the moves service, its encoding from the program's
//! types and its validating decoding into [`Resolved`].

mod arc;
mod decode;
mod encode;
mod event_codes;
mod layout;
mod reject;

pub use arc::{
    ARC_END_TOL_MM, ARC_MIN_RADIUS_MM, ARC_ROUNDING_REL, AXIS_UNIT_TOL, arc_tolerance_mm,
};
pub use decode::Resolved;
pub use event_codes::*;
pub use layout::*;
pub use reject::Reject;
