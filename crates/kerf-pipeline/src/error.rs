//! Why a run or the interpolator stopped early ([`RunError`]).

use kerf_motion::monitor::LimitViolation;
use kerf_plan::PlanError;

/// Why a run stopped early.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum RunError {
    /// A move could not be planned.
    Plan(PlanError),
    /// The planner produced a segment the core rejected (a bug).
    Rejected {
        /// Source line.
        line: u32,
    },
    /// A setpoint broke a limit ([`LimitMonitor`](kerf_motion::monitor::LimitMonitor)); the
    /// run stopped at it (runs with a monitor only, see [`run_stream`](crate::run_stream)).
    Fault(LimitViolation),
}

impl std::fmt::Display for RunError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RunError::Plan(e) => e.fmt(f),
            RunError::Rejected { line } => write!(f, "line {line}: segment rejected"),
            RunError::Fault(v) => v.fmt(f),
        }
    }
}

impl std::error::Error for RunError {}

impl From<PlanError> for RunError {
    fn from(e: PlanError) -> Self {
        RunError::Plan(e)
    }
}
