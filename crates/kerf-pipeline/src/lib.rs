//! Kerf's planning pipeline: moves → [`Planner`] → [`MotionCore`] → a setpoint sink.
//!
//! `kerf sim` and the daemon `kerfd` run the same code here, so that the daemon's
//! setpoints equal the simulator's cycle for cycle:
//!
//! - [`Interpolator`] is the per-cycle step both run: it takes planned items from a source
//!   ([`Poll`]) while the motion core's queue has room, rests at dwells, drops the rest of
//!   the program after an abort, and steps the core one period. It never allocates, so the
//!   daemon calls it on its real-time thread with a lock-free ring as the source; the
//!   simulator calls it in virtual time with a source that blocks until the planning
//!   thread has the next item (it is never [`Poll::Pending`]).
//! - Motion starts once the queue is full, or the program has been received to its end
//!   (or to a dwell, where the motion must stop anyway): with a planner that keeps up,
//!   the core then sees the same segments at every cycle in both. A daemon whose planner
//!   is behind starts earlier, once the lookahead has settled: segments queued later then
//!   change nothing of the motion ahead (see [`Interpolator::feed`]).
//! - [`plan_input`] is the planning step both planning threads run: a move is planned; at
//!   a stop or dwell the path ends at rest.
//! - [`Sink`] consumes setpoints: the CSV writer of `kerf sim`, the daemon's publisher.
//!
//! The offline runs ([`run`], [`run_stream`], [`run_planned`]) also measure what the
//! invariants are about: per-axis peak velocity, acceleration and jerk by finite
//! differences of the setpoints, and the distance of every setpoint from the programmed
//! moves.
//!
//! [`Planner`]: kerf_plan::Planner
//! [`MotionCore`]: kerf_motion::MotionCore
#![forbid(unsafe_code)]

/// Programmed moves the daemon's tracker holds (without allocating) per segment of its
/// motion queue, and the offline runs' tracker as well, so that both take the same
/// segments at the same cycles (see [`tracked_moves`]). Smoothed pieces of dense CAM code
/// can stand for more moves each than this on average; the tracker is then full before
/// the queue, and the queue counts as full ([`Poll::Full`]: the motion starts, and takes
/// more as it passes the moves).
pub const TRACKED_MOVES_PER_SEGMENT: usize = 16;

/// Programmed moves tracked beyond [`TRACKED_MOVES_PER_SEGMENT`] per segment: room for
/// the moves kept behind the running segment and for smoothed pieces of many moves even on
/// a short queue: the running piece and the next one at least, each of at most
/// [`kerf_plan::MAX_PIECE_MOVES`] moves (and the move after it), so that the next piece is
/// always queued before the running one ends and the motion never stops between them for
/// the tracker's sake.
pub const TRACKED_MOVES_EXTRA: usize = 4096;

const _: () = assert!(
    TRACKED_MOVES_EXTRA
        >= 2 * (kerf_plan::MAX_PIECE_MOVES as usize + 1) + 2 * tracker::MOVES_KEPT_BEHIND,
    "the tracker holds two pieces"
);

/// The tracker's capacity for a motion queue of `queue_segments` segments: 69,632 moves
/// for the default 4,096.
pub fn tracked_moves(queue_segments: usize) -> usize {
    queue_segments
        .saturating_mul(TRACKED_MOVES_PER_SEGMENT)
        .saturating_add(TRACKED_MOVES_EXTRA)
}

mod actions;
mod command;
mod error;
mod input;
mod interpolator;
mod measure;
mod plan_step;
mod runner;
mod runs;
mod sink;
mod tracker;

#[cfg(test)]
mod tests;

pub use actions::{ActionOrder, ProgramActions};
pub use command::OperatorEvent;
pub use error::RunError;
pub use input::{Input, dwell_periods, plan_input};
pub use interpolator::{Interpolator, Planned, Poll, START_LEAD_S, SYNCED_ACTIONS, segment_time_s};
pub use measure::{AxisPeak, Summary};
pub use runner::RunOptions;
pub use runs::{run, run_parallel, run_planned, run_stream};
pub use sink::{Sink, cycle_time_s};
pub use tracker::{Taking, Tracker};
