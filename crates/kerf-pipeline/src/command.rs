//! Operator commands a run applies between cycles: hold, resume, abort, feed override.

/// An input event applied before a given cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OperatorEvent {
    /// Feed hold.
    Hold,
    /// Resume after a hold.
    Resume,
    /// Abort: stop on the path and drop the queue.
    Abort,
    /// Feed override factor (1.0 = 100 %).
    Override(f64),
}
