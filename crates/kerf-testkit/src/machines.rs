//! Test machines.

use kerf_geom::{AxisLimits, MachineLimits};

/// A mill with the same limits on X, Y and Z (mm/s, mm/s², mm/s³), no rotary axes, a
/// 1 ms period and path tolerance `tolerance_mm`.
pub fn mill_with(v_mm_s: f64, a_mm_s2: f64, j_mm_s3: f64, tolerance_mm: f64) -> MachineLimits {
    let l = AxisLimits {
        velocity_units_s: v_mm_s,
        acceleration_units_s2: a_mm_s2,
        jerk_units_s3: j_mm_s3,
    };
    MachineLimits {
        axes: [Some(l), Some(l), Some(l), None, None, None],
        period_s: 0.001,
        tolerance_mm,
    }
}

/// The planner tests' mill: 200 mm/s, 2,000 mm/s², 50,000 mm/s³ on X, Y, Z; 1 ms; 0.01 mm.
pub fn mill() -> MachineLimits {
    mill_with(200.0, 2000.0, 50_000.0, 0.01)
}
