//! Tests of the limit monitor on setpoint streams as the runs feed it, and the test machine
//! the crate's unit tests share.

use kerf_motion::monitor::*;
use kerf_plan::{AxisLimits, MachineLimits};

/// A machine with X, Y, Z at velocity `v`, acceleration `a`, jerk `j`, tolerance 0.01 mm.
pub(crate) fn machine(period_s: f64, v: f64, a: f64, j: f64) -> MachineLimits {
    let axis = Some(AxisLimits {
        velocity_units_s: v,
        acceleration_units_s2: a,
        jerk_units_s3: j,
    });
    MachineLimits {
        axes: [axis, axis, axis, None, None, None],
        period_s,
        tolerance_mm: 0.01,
    }
}

/// `x(t) = offset + amp · sin(ω t)` on X at the period; Y and Z stay at `offset`.
fn sine(offset: f64, amp: f64, omega: f64, period_s: f64, n: usize) -> Vec<[f64; 6]> {
    (0..n)
        .map(|k| {
            let t = k as f64 * period_s;
            [
                offset + amp * (omega * t).sin(),
                offset,
                offset,
                0.0,
                0.0,
                0.0,
            ]
        })
        .collect()
}

/// The continuous peaks of the sine: `amp ωⁿ`; finite differences at the period
/// measure slightly less (`amp (2 sin(ωT/2)/T)ⁿ`).
fn peaks(amp: f64, omega: f64) -> [f64; 3] {
    [amp * omega, amp * omega.powi(2), amp * omega.powi(3)]
}

fn first_fault(m: &mut LimitMonitor, stream: &[[f64; 6]]) -> Option<LimitViolation> {
    stream.iter().find_map(|p| m.check(p).err())
}

#[test]
fn a_stream_at_its_limits_passes_wherever_it_runs() {
    // Limits equal to the sine's continuous peaks: the stream is exactly at 100 %.
    for (offset, period_s) in [
        (0.0, 1e-3),
        (-250.0, 2.5e-4),
        (1000.0, 1e-3),
        (9999.0, 6.25e-5),
        (-9999.0, 1e-2),
    ] {
        let (amp, omega) = (5.0, 20.0);
        let [v, a, j] = peaks(amp, omega);
        let limits = machine(period_s, v, a, j);
        let stream = sine(offset, amp, omega, period_s, (1.0 / period_s) as usize);
        // (The sine does not start at rest: nothing is assumed before it.)
        let mut m = LimitMonitor::new(&limits);
        assert_eq!(first_fault(&mut m, &stream), None, "offset {offset}");
        // The peaks read 100 %, within the rounding noise of 9,999 mm at 62.5 µs.
        let r = m.peak_ratios(0).unwrap();
        for q in r {
            assert!((0.97..=1.002).contains(&q), "offset {offset}: {r:?}");
        }
    }
}

#[test]
fn rounding_noise_of_far_positions_at_a_short_period_is_not_a_fault() {
    // 1 µm of motion at 9,999 mm, period 62.5 µs, jerk 1e-3 mm/s³ at the limit: one
    // ulp of 9,999 mm (1.8e-12 mm) over T³ (2.4e-13 s³) is already 7 mm/s³, so the
    // raw third differences are pure rounding noise far above the limit.
    let (amp, omega, period_s) = (1e-3, 1.0, 6.25e-5);
    let [v, a, j] = peaks(amp, omega);
    let limits = machine(period_s, v, a, j);
    let stream = sine(9999.0, amp, omega, period_s, 20_000);
    let raw_jerk = stream
        .windows(4)
        .map(|w| (w[3][0] - 3.0 * w[2][0] + 3.0 * w[1][0] - w[0][0]).abs() / period_s.powi(3))
        .fold(0.0, f64::max);
    assert!(raw_jerk > 100.0 * j, "the noise is real: {raw_jerk}");
    let mut m = LimitMonitor::new(&limits);
    assert_eq!(first_fault(&mut m, &stream), None);
    assert!(m.peak_ratios(0).unwrap()[2] <= LIMIT_MARGIN);
}

#[test]
fn a_two_percent_excess_is_a_fault_naming_the_quantity_and_the_first_setpoint() {
    let (amp, omega, period_s) = (5.0, 20.0, 1e-3);
    let [v, a, j] = peaks(amp, omega);
    let stream = sine(1000.0, amp, omega, period_s, 1000);
    for (q, limits) in [
        (
            Quantity::Velocity,
            machine(period_s, v / 1.02, a * 2.0, j * 2.0),
        ),
        (
            Quantity::Acceleration,
            machine(period_s, v * 2.0, a / 1.02, j * 2.0),
        ),
        (
            Quantity::Jerk,
            machine(period_s, v * 2.0, a * 2.0, j / 1.02),
        ),
    ] {
        let mut m = LimitMonitor::new(&limits);
        let f = first_fault(&mut m, &stream).unwrap_or_else(|| panic!("{q:?} not caught"));
        assert_eq!((f.axis, f.quantity), (0, q));
        assert!((1.01..1.021).contains(&f.ratio()), "{q:?}: {f:?}");
        // It is the first setpoint whose finite difference is beyond 1.01 × limit,
        // computed here independently from the stream.
        let limit = f.limit;
        let n = q as usize + 1;
        let first = (n..stream.len())
            .find(|&k| {
                let x = |i: usize| stream[k - i][0];
                let d = match n {
                    1 => x(0) - x(1),
                    2 => x(0) - 2.0 * x(1) + x(2),
                    _ => x(0) - 3.0 * x(1) + 3.0 * x(2) - x(3),
                };
                d.abs() / period_s.powi(n as i32) > 1.01 * limit
            })
            .unwrap();
        assert_eq!(f.sample, first as u64, "{q:?}");
    }
}

#[test]
fn a_jump_is_a_velocity_fault_at_the_setpoint_that_jumps() {
    // A teleport: at rest at the origin, then 4.14 mm in one 1 ms period on
    // a 1,000 mm/s machine (414 % of the velocity limit).
    let limits = machine(1e-3, 1000.0, 1e5, 1e7);
    let mut stream = vec![[0.0; 6]; 5];
    stream.extend(vec![[-1.0117, -4.0119, 0.0635, 0.0, 0.0, 0.0]; 5]);
    let mut m = LimitMonitor::at_rest(&limits, &[0.0; 6]);
    let f = first_fault(&mut m, &stream).unwrap();
    assert_eq!((f.sample, f.axis, f.quantity), (5, 1, Quantity::Velocity));
    assert!((f.ratio() - 4.0119).abs() < 1e-9, "{f:?}");
    assert_eq!(
        f.to_string(),
        "setpoint 5: Y velocity 401 % of the limit (1000)"
    );
    // A monitor that knows nothing before its first setpoint sees the same jump.
    let mut m = LimitMonitor::new(&limits);
    assert_eq!(first_fault(&mut m, &stream).map(|f| f.sample), Some(5));
    // A start away from the rest position is a jump too.
    let mut m = LimitMonitor::at_rest(&limits, &[0.0; 6]);
    assert!(m.check(&[1.0, 0.0, 0.0, 0.0, 0.0, 0.0]).is_err());
    // A non-finite position is a fault; an axis the machine lacks is not checked.
    let mut m = LimitMonitor::at_rest(&limits, &[0.0; 6]);
    assert!(m.check(&[0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0]).is_err());
    let mut m = LimitMonitor::at_rest(&limits, &[0.0; 6]);
    assert_eq!(m.check(&[0.0, 0.0, 0.0, 50.0, 0.0, 0.0]), Ok(()));
}

#[test]
fn acceleration_before_jerk_when_both_break() {
    // From rest, a step to a constant speed of 90 % of the velocity limit in one
    // period: velocity holds, acceleration and jerk do not; acceleration is reported.
    let limits = machine(1e-3, 100.0, 1000.0, 1e5);
    let mut m = LimitMonitor::at_rest(&limits, &[0.0; 6]);
    let f = m.check(&[0.09, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap_err();
    assert_eq!(f.quantity, Quantity::Acceleration);
    assert!((f.ratio() - 90.0).abs() < 1e-6, "{f:?}");
}
