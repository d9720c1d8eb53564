//! Exact path geometry for Kerf.
//!
//! This crate owns the canonical description of a programmed move ([`Move`]) and the
//! geometry of the paths it follows ([`Path`]: straight lines, circular arcs and helices),
//! and the other items of a resolved program ([`Event`], [`Item`]), so that the G-code
//! front end and the shared-memory protocol share them without depending on each other.
//! It also owns the types that cross from the planner to the motion core: the planned
//! segment ([`PlannedSegment`]) and the machine's limits ([`MachineLimits`]).
//! It knows nothing of G-code dialects, planning or time: the G-code front end produces
//! [`Move`]s, the planner and the motion core consume them.
//!
//! Design decisions:
//! - All lengths are millimetres in absolute machine coordinates; rotary axes are degrees.
//!   Units are converted once, in the front end, never here.
//! - An arc is stored by its exact defining data (start, end, centre, unit axis, signed
//!   sweep) rather than by sampled points, so that every consumer evaluates the same curve.
//!   A helix is an arc whose end differs from the start along the axis; the axial motion
//!   is proportional to the swept angle.
//! - Curvature-continuous transitions ([`Transition`], quintic Hermite curves with an
//!   arc-length table) are built by the planner between moves whose curvature jumps;
//!   [`Curve`] evaluates them like lines and arcs, at arc length, without allocation.
//! - `sweep_rad` is signed about `axis` by the right-hand rule and includes whole turns, so
//!   a full circle has `|sweep_rad| = 2π` and its start equals its end.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

use nalgebra::Vector3;

/// A point or direction in machine space, millimetres.
pub type Vec3 = Vector3<f64>;

/// The most axes a machine has: X, Y, Z, A, B, C.
pub const MAX_AXES: usize = 6;

/// One value per axis, in the order X, Y, Z, A, B, C (lengths in mm for X, Y, Z and
/// degrees for A, B, C unless the name says otherwise): the index is the axis.
pub type PerAxis<T> = [T; MAX_AXES];

/// A straight segment from `start` to `end`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Line {
    /// Start point, mm.
    pub start: Vec3,
    /// End point, mm.
    pub end: Vec3,
}

/// A circular arc or helix.
///
/// The circle lies in the plane through `start` normal to `axis`; `center` lies in that
/// plane. The end point may be displaced from that plane along `axis` (a helix); the
/// displacement grows linearly with the swept angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Arc {
    /// Start point, mm.
    pub start: Vec3,
    /// End point, mm.
    pub end: Vec3,
    /// Centre of the circle, in the plane of `start`, mm.
    pub center: Vec3,
    /// Unit normal of the plane (G17 +Z, G18 +Y, G19 +X).
    pub axis: Vec3,
    /// Signed swept angle about `axis` (right-hand rule; G3 positive, G2 negative),
    /// including whole turns, radians.
    pub sweep_rad: f64,
}

/// The geometric path of one move.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Path {
    /// A straight line.
    Line(Line),
    /// A circular arc or helix.
    Arc(Arc),
}

/// How the motion at the end of a move joins the next one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CornerMode {
    /// Come to a stop at the end of the move (LinuxCNC G61, G9-style exact stop).
    ExactStop,
    /// Blend into the next move within a path tolerance. `None` means the configured
    /// default tolerance (LinuxCNC G64 without P).
    Blend {
        /// Maximum distance from the programmed path, mm.
        tolerance_mm: Option<f64>,
        /// LinuxCNC's naive-CAM tolerance (`G64 Q`, or `P` when Q is absent), mm: within
        /// it LinuxCNC merges short collinear segments. Carried for the planner (also on
        /// the wire, `MoveMsg::naive_cam_mm`), which does not use it yet; `None` = off.
        naive_cam_mm: Option<f64>,
    },
}

/// One resolved move in absolute machine coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Move {
    /// 1-based source line of the block that programmed the move.
    pub line: u32,
    /// `true` for a rapid (G0): it runs at the axis limits and `feed_mm_min` is `None`.
    pub rapid: bool,
    /// The path, in mm.
    pub path: Path,
    /// Programmed feed along the path, mm/min; `None` for rapids.
    pub feed_mm_min: Option<f64>,
    /// Rotary axes A, B, C at start and end, degrees, when the program uses them. They move
    /// proportionally with the path.
    pub abc_deg: Option<([f64; 3], [f64; 3])>,
    /// How this move joins the next.
    pub corner: CornerMode,
}

impl Path {
    /// Start point of the path.
    pub fn start(&self) -> Vec3 {
        match self {
            Path::Line(l) => l.start,
            Path::Arc(a) => a.start,
        }
    }

    /// End point of the path.
    pub fn end(&self) -> Vec3 {
        match self {
            Path::Line(l) => l.end,
            Path::Arc(a) => a.end,
        }
    }
}

impl Arc {
    /// Radius of the circle, mm (distance from `center` to `start`).
    pub fn radius(&self) -> f64 {
        (self.start - self.center).norm()
    }
}

mod curve;
mod limits;
pub mod machine;
mod program;
pub mod quintic;
pub mod ramp;
mod segment;
mod transition;
pub use curve::{Curve, CurvePoint, Helix, line_distance};
pub use limits::{
    AXIS_NAMES, AxisLimits, MAX_FEED_OVERRIDE, MachineLimits, POSITION_ROUNDING_ULPS,
};
pub use program::{Event, EventCode, Item};
pub use segment::{
    MERGE_ABOVE, MERGE_RATIO, MERGE_RATIO_JERK, MERGE_RATIO_SLOWER, MERGE_RATIO_SPEED,
    MERGE_RATIO_WEAKER, MERGE_SHORT_SHARE, MergeKind, PlannedSegment, conservative_limits,
    entry_speed, limits_merge, limits_merge_into, limits_merge_weaker, poly5, rotary_derivatives,
    speeds_merge_into, weaker_merge_keeps_lookahead,
};
pub use transition::{ARC_MID_RELATIVE, ARC_TABLE_RELATIVE, TABLE_POINTS, Transition};
