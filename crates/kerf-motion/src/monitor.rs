//! The last line of defence: a per-axis limit check on the setpoint stream itself.
//!
//! [`LimitMonitor`] checks every setpoint against the velocity, acceleration and jerk
//! limits it was planned for, by finite differences of the positions at the period, and
//! reports the first one that breaks a limit. It is fixed-size and allocation-free, so the
//! daemon's output stage can run it in the real-time cycle; `kerf sim` runs it on every
//! row.

use kerf_geom::MachineLimits;
use kerf_geom::PerAxis;

/// Allowed excess over a limit before [`LimitMonitor`] reports a fault: 1 %, the margin
/// the invariants are stated with (finite differences at the period see a jerk-limited
/// profile's corners slightly rounded or sharpened).
pub const LIMIT_MARGIN: f64 = 1.01;

pub use kerf_geom::POSITION_ROUNDING_ULPS;

/// What a limit check measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    /// First difference of the positions over the period.
    Velocity,
    /// Second difference over the period squared.
    Acceleration,
    /// Third difference over the period cubed.
    Jerk,
}

impl Quantity {
    /// `"velocity"`, `"acceleration"` or `"jerk"`.
    pub fn name(self) -> &'static str {
        match self {
            Quantity::Velocity => "velocity",
            Quantity::Acceleration => "acceleration",
            Quantity::Jerk => "jerk",
        }
    }
}

/// A setpoint that broke a limit, as [`LimitMonitor`] measured it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LimitViolation {
    /// Index of the offending setpoint among those given to [`LimitMonitor::check`]
    /// (0 = the first).
    pub sample: u64,
    /// Axis index (0–5 = X, Y, Z, A, B, C).
    pub axis: usize,
    /// Which limit.
    pub quantity: Quantity,
    /// |finite difference|, units/sⁿ (infinite for a non-finite position).
    pub value: f64,
    /// The configured limit, units/sⁿ.
    pub limit: f64,
    /// The rounding allowance that was granted on top of [`LIMIT_MARGIN`], units/sⁿ.
    pub allowance: f64,
}

impl LimitViolation {
    /// `value / limit`.
    pub fn ratio(&self) -> f64 {
        self.value / self.limit
    }
}

impl std::fmt::Display for LimitViolation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "setpoint {}: {} {} {:.0} % of the limit ({})",
            self.sample,
            kerf_geom::AXIS_NAMES[self.axis],
            self.quantity.name(),
            self.ratio() * 100.0,
            self.limit
        )
    }
}

/// The last line of defence: checks every setpoint of a stream against the per-axis
/// velocity, acceleration and jerk limits it was planned for, by finite differences of the
/// positions at the period (the measure the invariants are stated in), and reports the
/// first setpoint that breaks one. Fixed size, no allocation, bounded work per call: the
/// daemon's output stage can run it in the cycle.
///
/// A setpoint breaks a limit `L` when the n-th difference `|Δⁿx| / Tⁿ` exceeds
/// `LIMIT_MARGIN · L + allowanceₙ`, where the rounding allowance is derived as follows.
/// Each position is a computed double of magnitude about `M` (the largest |x| among the
/// n + 1 positions involved, or the configured [`LimitMonitor::with_position_scale`] if
/// larger, because a point near zero on an arc far from it is computed from values of the
/// arc's magnitude); it carries a rounding error `|δ| ≤ E = POSITION_ROUNDING_ULPS · ε · M`
/// (`ε·M` bounds one ulp of `M`). The n-th difference has binomial weights whose absolute
/// values sum to `2ⁿ`, so the errors add up to at most `2ⁿ E`; evaluating the difference
/// itself rounds at most once per operation on operands below `2ⁿ M`, about `(n + 1) 2ⁿ ε M`
/// more; dividing by `Tⁿ` is exact to a relative ε. Hence
///
/// `allowanceₙ = 2ⁿ (POSITION_ROUNDING_ULPS + n + 1) · ε · M / Tⁿ`.
///
/// At 1 ms and 1,000 mm that is 5e-10 mm/s, 1e-6 mm/s² and 2e-3 mm/s³: invisible. It only
/// matters at very short periods (at 1 µs the jerk allowance is 2e6 mm/s³ at 1,000 mm,
/// which is what rounding alone produces there), and a real 2 % excess at ordinary periods
/// and limits is far above it.
///
/// The peaks it reports ([`LimitMonitor::peak_ratios`]) are the measured ratios, except that
/// a ratio above [`LIMIT_MARGIN`] is reduced by the allowance (down to the margin at most),
/// so a stream the monitor passes never shows a peak above [`LIMIT_MARGIN`].
#[derive(Clone, Copy, Debug)]
pub struct LimitMonitor {
    /// Velocity, acceleration and jerk limit per axis; `None` for an axis the machine
    /// does not have (not checked).
    limits: [Option<[f64; 3]>; 6],
    /// `1/T`, `1/T²`, `1/T³`.
    inv_period: [f64; 3],
    /// `allowanceₙ / M` for n = 1, 2, 3.
    noise: [f64; 3],
    /// Lower bound of `M` per axis.
    scale: PerAxis<f64>,
    /// The last four positions, newest first.
    hist: [PerAxis<f64>; 4],
    /// How many of `hist` are valid.
    len: usize,
    /// Setpoints checked so far.
    samples: u64,
    /// Peak ratio per axis and quantity (see [`LimitMonitor::peak_ratios`]).
    peaks: [[f64; 3]; 6],
}

impl LimitMonitor {
    /// A monitor for `limits` that knows nothing of the motion before the first setpoint
    /// (velocity is checked from the second setpoint on, acceleration from the third,
    /// jerk from the fourth).
    pub fn new(limits: &MachineLimits) -> Self {
        let t = limits.period_s;
        let mut axes = [None; 6];
        for (i, a) in limits.axes.iter().enumerate() {
            axes[i] = a.map(|a| [a.velocity_units_s, a.acceleration_units_s2, a.jerk_units_s3]);
        }
        let mut noise = [0.0; 3];
        for (k, n) in noise.iter_mut().enumerate() {
            let order = (k + 1) as i32;
            *n = 2f64.powi(order) * (POSITION_ROUNDING_ULPS + order as f64 + 1.0) * f64::EPSILON
                / t.powi(order);
        }
        LimitMonitor {
            limits: axes,
            inv_period: [1.0 / t, 1.0 / (t * t), 1.0 / (t * t * t)],
            noise,
            scale: [0.0; 6],
            hist: [[0.0; 6]; 4],
            len: 0,
            samples: 0,
            peaks: [[0.0; 3]; 6],
        }
    }

    /// A monitor for a stream that starts at rest at `position` (as `kerf sim` and the
    /// daemon do): the first setpoint is already checked against this rest.
    pub fn at_rest(limits: &MachineLimits, position: &PerAxis<f64>) -> Self {
        let mut m = LimitMonitor::new(limits);
        m.hist = [*position; 4];
        m.len = 4;
        m
    }

    /// Raises the magnitude `M` of the rounding allowance to at least `scale[i]` on axis
    /// `i` (the largest |coordinate| of the machine's travel is a good choice: the
    /// geometry a position is computed from lies there).
    pub fn with_position_scale(mut self, scale: PerAxis<f64>) -> Self {
        for (s, v) in self.scale.iter_mut().zip(scale) {
            *s = v.abs();
        }
        self
    }

    /// The rounding allowance of the n-th difference (1 = velocity … 3 = jerk) at
    /// magnitude `magnitude`, units/sⁿ.
    pub fn allowance(&self, quantity: Quantity, magnitude: f64) -> f64 {
        self.noise[quantity as usize] * magnitude
    }

    /// Checks the next setpoint's positions (X, Y, Z mm; A, B, C degrees). Returns the
    /// violation with the lowest derivative that this setpoint breaks (velocity before
    /// acceleration before jerk; of several axes, the one with the largest ratio), and
    /// then keeps going if called again.
    pub fn check(&mut self, position: &PerAxis<f64>) -> Result<(), LimitViolation> {
        self.hist.copy_within(0..3, 1);
        self.hist[0] = *position;
        self.len = (self.len + 1).min(4);
        let sample = self.samples;
        self.samples += 1;
        let mut worst: Option<LimitViolation> = None;
        for axis in 0..6 {
            let Some(limit) = self.limits[axis] else {
                continue;
            };
            let h = |k: usize| self.hist[k][axis];
            if !h(0).is_finite() {
                return Err(LimitViolation {
                    sample,
                    axis,
                    quantity: Quantity::Velocity,
                    value: f64::INFINITY,
                    limit: limit[0],
                    allowance: 0.0,
                });
            }
            let mut magnitude = self.scale[axis];
            for k in 0..self.len {
                magnitude = magnitude.max(h(k).abs());
            }
            for (q, quantity) in [Quantity::Velocity, Quantity::Acceleration, Quantity::Jerk]
                .into_iter()
                .enumerate()
            {
                if self.len < q + 2 {
                    break;
                }
                let diff = match quantity {
                    Quantity::Velocity => h(0) - h(1),
                    Quantity::Acceleration => h(0) - 2.0 * h(1) + h(2),
                    Quantity::Jerk => h(0) - 3.0 * h(1) + 3.0 * h(2) - h(3),
                };
                let value = diff.abs() * self.inv_period[q];
                let allowance = self.noise[q] * magnitude;
                let raw = value / limit[q];
                let ratio = (value - allowance) / limit[q];
                // The peak is the measured ratio; only where that is beyond the margin is
                // the allowance taken off (down to the margin at most).
                let shown = if raw <= LIMIT_MARGIN {
                    raw
                } else {
                    ratio.max(LIMIT_MARGIN)
                };
                let peak = &mut self.peaks[axis][q];
                *peak = peak.max(shown);
                if ratio > LIMIT_MARGIN {
                    let v = LimitViolation {
                        sample,
                        axis,
                        quantity,
                        value,
                        limit: limit[q],
                        allowance,
                    };
                    worst = match worst {
                        Some(w)
                            if (w.quantity as usize) < q
                                || (w.quantity == quantity && w.ratio() >= v.ratio()) =>
                        {
                            Some(w)
                        }
                        _ => Some(v),
                    };
                }
            }
        }
        match worst {
            Some(v) => Err(v),
            None => Ok(()),
        }
    }

    /// Setpoints checked so far.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// The largest velocity, acceleration and jerk of axis `i` seen so far as fractions of
    /// its limits, where a fraction above [`LIMIT_MARGIN`] is taken less the rounding
    /// allowance, down to the margin at most (`None` for an axis the machine does not
    /// have).
    pub fn peak_ratios(&self, axis: usize) -> Option<[f64; 3]> {
        self.limits[axis].map(|_| self.peaks[axis])
    }
}
