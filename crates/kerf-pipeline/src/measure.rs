//! What the offline runs measure from the setpoints ([`Summary`]): per-axis peaks by
//! finite differences, the distance from the programmed moves, and the limit monitor's
//! first fault.

use kerf_geom::Move;
use kerf_geom::PerAxis;
use kerf_motion::Setpoint;
use kerf_motion::monitor::{LimitMonitor, LimitViolation};
use kerf_plan::MachineLimits;

use crate::{Taking, Tracker};

/// Peak per-axis values by finite differences of the setpoints.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxisPeak {
    /// Peak |velocity|, units/s.
    pub velocity: f64,
    /// Peak |acceleration|, units/s².
    pub acceleration: f64,
    /// Peak |jerk|, units/s³.
    pub jerk: f64,
}

/// What a run measured.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Summary {
    /// Cycles stepped (rows after the one at t = 0).
    pub cycles: u64,
    /// Duration, s (cycles × period).
    pub duration_s: f64,
    /// Peaks per axis X, Y, Z, A, B, C.
    pub peaks: [AxisPeak; 6],
    /// Largest distance of a setpoint from the programmed moves, mm.
    pub max_deviation_mm: f64,
    /// `true` if any move drove a rotary axis.
    pub rotary_used: bool,
    /// Final setpoint.
    pub last: Setpoint,
    /// Profile calculations that needed a fallback.
    pub plan_failures: u64,
    /// `true` if a non-finite value was ever produced.
    pub saw_nan: bool,
}

impl Summary {
    /// Peak as a fraction of the limit for axis `i` (velocity, acceleration, jerk).
    pub fn fractions(&self, limits: &MachineLimits, i: usize) -> Option<[f64; 3]> {
        let l = limits.axes[i]?;
        let p = self.peaks[i];
        Some([
            p.velocity / l.velocity_units_s,
            p.acceleration / l.acceleration_units_s2,
            p.jerk / l.jerk_units_s3,
        ])
    }
}

/// What the offline runs measure from the setpoints (the daemon does not).
pub(crate) struct Measure<'a> {
    period_s: f64,
    hist: [PerAxis<f64>; 4],
    hist_len: usize,
    pub(crate) summary: Summary,
    /// The programmed moves, for the deviation check and the line being passed.
    tracker: Tracker,
    /// Checks every setpoint, when the run has one.
    pub(crate) monitor: Option<&'a mut LimitMonitor>,
    /// The first setpoint that broke a limit: the run stops there.
    pub(crate) fault: Option<LimitViolation>,
}

impl Measure<'_> {
    /// Nothing measured yet, setpoints `period_s` apart, a tracker of `tracked_moves`
    /// moves (the daemon's, see [`crate::TRACKED_MOVES_PER_SEGMENT`]); no monitor.
    pub(crate) fn new(period_s: f64, tracked_moves: usize) -> Self {
        Measure {
            period_s,
            hist: [[0.0; 6]; 4],
            hist_len: 0,
            summary: Summary::default(),
            tracker: Tracker::with_capacity(tracked_moves),
            monitor: None,
            fault: None,
        }
    }

    /// Measures a setpoint (and names the move it is passing, see [`Tracker::track`]).
    pub(crate) fn record(&mut self, sp: &mut Setpoint) {
        if sp.position.iter().any(|v| !v.is_finite()) || !sp.feed_mm_s.is_finite() {
            self.summary.saw_nan = true;
        }
        self.hist.rotate_right(1);
        self.hist[0] = sp.position;
        self.hist_len = (self.hist_len + 1).min(4);
        let t = self.period_s;
        for i in 0..6 {
            let h = |k: usize| self.hist[k][i];
            let p = &mut self.summary.peaks[i];
            if self.hist_len >= 2 {
                p.velocity = p.velocity.max(((h(0) - h(1)) / t).abs());
            }
            if self.hist_len >= 3 {
                p.acceleration = p
                    .acceleration
                    .max(((h(0) - 2.0 * h(1) + h(2)) / (t * t)).abs());
            }
            if self.hist_len >= 4 {
                p.jerk = p
                    .jerk
                    .max(((h(0) - 3.0 * h(1) + 3.0 * h(2) - h(3)) / (t * t * t)).abs());
            }
        }
        if let Some(d) = self.tracker.track(sp) {
            self.summary.max_deviation_mm = self.summary.max_deviation_mm.max(d);
        }
        self.summary.last = *sp;
    }

    /// What to do with the next programmed move (as the daemon's cycle does).
    pub(crate) fn taking(&self, queue_empty: bool, aborted: bool) -> Taking {
        self.tracker.taking(queue_empty, aborted)
    }

    /// Takes the next programmed move as `taking` says (not [`Taking::Wait`]): tracked for
    /// the deviation check, or passed.
    pub(crate) fn take_move(&mut self, mv: &Move, taking: Taking) {
        if let Some((s, e)) = mv.abc_deg
            && s != e
        {
            self.summary.rotary_used = true;
        }
        if taking == Taking::Track {
            self.tracker.add(mv);
        }
    }

    /// Checks a setpoint with the monitor, if any; keeps the first fault.
    pub(crate) fn check(&mut self, sp: &Setpoint) {
        if let Some(m) = self.monitor.as_mut()
            && let Err(v) = m.check(&sp.position)
        {
            self.fault.get_or_insert(v);
        }
    }
}
