//! The simulated drive against physics and the standard's state machine. Expected values
//! come from second-order system theory, the move's own kinematics, and the standard's
//! transition table (written out here), never from the code under test.

use kerf_drive::cia402::{Drive, DriveState};
use kerf_drive::sim::{ERROR_OVERCURRENT, SimConfig, SimDrive};
use proptest::prelude::*;

const PERIOD_NS: u64 = 1_000_000;
const PERIOD_S: f64 = 1e-3;

/// Powers a drive up to Operation enabled with the target at the actual position.
fn enabled(config: SimConfig) -> SimDrive {
    let mut drive = SimDrive::new(config);
    for controlword in [0x0000, 0x0006, 0x0007, 0x000F] {
        let actual = drive.position_actual_counts();
        drive.write(controlword, actual);
    }
    assert_eq!(drive.state(), DriveState::OperationEnabled);
    drive
}

/// A quintic (minimum-jerk) move of `distance` over `duration_s`: position at `t`.
fn quintic(distance: f64, duration_s: f64, t_s: f64) -> f64 {
    let tau = (t_s / duration_s).clamp(0.0, 1.0);
    distance * (10.0 * tau.powi(3) - 15.0 * tau.powi(4) + 6.0 * tau.powi(5))
}

/// Runs the quintic move cyclically; returns the largest |following error| in counts.
fn max_following_error(config: SimConfig, distance: f64, duration_s: f64) -> f64 {
    let mut drive = enabled(config);
    let mut worst: f64 = 0.0;
    let cycles = (duration_s / PERIOD_S) as usize + 500;
    for k in 1..=cycles {
        let target = quintic(distance, duration_s, k as f64 * PERIOD_S).round() as i32;
        drive.write(0x000F, target);
        assert_eq!(drive.state(), DriveState::OperationEnabled);
        worst = worst.max(f64::from(drive.following_error_counts()).abs());
    }
    worst
}

#[test]
fn well_tuned_drive_follows_a_jerk_limited_move_within_the_derived_bound() {
    // 100 mm at 1000 counts/mm in 1 s: peak acceleration of the quintic is
    // 10/sqrt(3) · D / T² (at tau = 1/2 ± 1/(2 sqrt 3)).
    let distance = 100_000.0;
    let duration_s = 1.0;
    let peak_accel = 10.0 / 3f64.sqrt() * distance / (duration_s * duration_s);
    let config = SimConfig {
        period_ns: PERIOD_NS,
        bandwidth_hz: 50.0,
        damping: 1.0,
        velocity_feed_forward: 1.0,
        ..SimConfig::default()
    };
    let omega = 2.0 * std::f64::consts::PI * config.bandwidth_hz;
    // With full feed-forward, e'' + 2ζω e' + ω² e = a(t): e is a(t)/ω² filtered by a
    // unit-gain second-order low pass, whose impulse response is non-negative at ζ = 1
    // (L1 norm 1), so |e| <= max|a| / ω². Plus one count of rounding (target, actual).
    let bound = peak_accel / (omega * omega) + 1.0;
    let worst = max_following_error(config, distance, duration_s);
    assert!(worst <= bound, "following error {worst} > bound {bound}");
    // And the error is real: near the quasi-static a/ω² at the acceleration peak.
    assert!(
        worst >= 0.7 * (bound - 1.0),
        "following error {worst} too small"
    );
}

#[test]
fn low_bandwidth_drive_shows_a_large_following_error() {
    let distance = 100_000.0;
    let duration_s = 1.0;
    let peak_accel = 10.0 / 3f64.sqrt() * distance;
    let good_omega = 2.0 * std::f64::consts::PI * 50.0;
    let good_bound = peak_accel / (good_omega * good_omega) + 1.0;
    let config = SimConfig {
        bandwidth_hz: 2.0,
        damping: 1.0,
        ..SimConfig::default()
    };
    let worst = max_following_error(config, distance, duration_s);
    // 25 times less bandwidth: 625 times the quasi-static error.
    assert!(
        worst > 100.0 * good_bound,
        "following error {worst} not large against {good_bound}"
    );
}

/// Step response without feed-forward: largest overshoot as a fraction of the step.
fn step_overshoot(damping: f64) -> f64 {
    let config = SimConfig {
        bandwidth_hz: 5.0,
        damping,
        velocity_feed_forward: 0.0,
        substeps: 20,
        overcurrent_accel_counts_s2: f64::INFINITY,
        ..SimConfig::default()
    };
    let mut drive = enabled(config);
    let step = 100_000.0;
    let mut peak: f64 = 0.0;
    for _ in 0..8000 {
        drive.write(0x000F, step as i32);
        peak = peak.max(drive.motor_position_counts());
    }
    // Settled at the target.
    assert!((drive.motor_position_counts() - step).abs() < 1.0);
    (peak - step) / step
}

#[test]
fn step_overshoot_follows_the_second_order_formula() {
    for damping in [0.1, 0.2, 0.4, 0.6, 0.8] {
        let expected = (-damping * std::f64::consts::PI / (1.0 - damping * damping).sqrt()).exp();
        let measured = step_overshoot(damping);
        assert!(
            (measured - expected).abs() < 0.01,
            "ζ = {damping}: overshoot {measured}, expected {expected}"
        );
    }
    // Critically damped: no overshoot.
    assert!(step_overshoot(1.0) < 1e-6);
}

#[test]
fn overcurrent_trips_fault_and_needs_a_reset() {
    // A step of 1000 counts at 50 Hz asks ω² · 1000 ≈ 9.9e7 counts/s² at once.
    let config = SimConfig {
        overcurrent_accel_counts_s2: 1.0e7,
        ..SimConfig::default()
    };
    let mut drive = enabled(config);
    drive.write(0x000F, 1000);
    assert_eq!(
        DriveState::from_statusword(drive.statusword()),
        Some(DriveState::FaultReactionActive)
    );
    assert_eq!(drive.error_code(), ERROR_OVERCURRENT);
    drive.write(0x000F, 0);
    assert_eq!(
        DriveState::from_statusword(drive.statusword()),
        Some(DriveState::Fault)
    );
    // Commands do not leave Fault.
    for controlword in [0x000F, 0x0006, 0x0007, 0x0000, 0x0002] {
        drive.write(controlword, 0);
        assert_eq!(drive.state(), DriveState::Fault, "after {controlword:#06x}");
    }
    // The rising edge of bit 7 does.
    drive.write(0x0080, 0);
    assert_eq!(
        DriveState::from_statusword(drive.statusword()),
        Some(DriveState::SwitchOnDisabled)
    );
    assert_eq!(drive.error_code(), 0);
    // A fault while bit 7 is held high: holding it is no new edge.
    drive.inject_fault(ERROR_OVERCURRENT);
    for _ in 0..5 {
        drive.write(0x0080, 0);
    }
    assert_eq!(drive.state(), DriveState::Fault);
    drive.write(0x0000, 0);
    drive.write(0x0080, 0);
    assert_eq!(drive.state(), DriveState::SwitchOnDisabled);
}

#[test]
fn injected_fault_latches() {
    let mut drive = enabled(SimConfig::default());
    drive.inject_fault(0x7500);
    drive.write(0x000F, 0);
    drive.write(0x000F, 0);
    for _ in 0..100 {
        drive.write(0x000F, 0);
    }
    assert_eq!(drive.state(), DriveState::Fault);
    assert_eq!(drive.error_code(), 0x7500);
}

#[test]
fn quick_stop_ramps_to_rest_over_the_kinematic_distance() {
    let decel = 2.0e5;
    let config = SimConfig {
        quick_stop_decel_counts_s2: decel,
        ..SimConfig::default()
    };
    let mut drive = enabled(config);
    // Cruise at 50 000 counts/s (50 counts per period) until settled.
    let speed = 50_000.0;
    let mut target = 0.0;
    for _ in 0..2000 {
        target += speed * PERIOD_S;
        drive.write(0x000F, target as i32);
    }
    let v0 = drive.motor_velocity_counts_s();
    assert!((v0 - speed).abs() < 1.0, "cruise velocity {v0}");
    let x0 = drive.motor_position_counts();
    let mut cycles = 0;
    while drive.state() != DriveState::SwitchOnDisabled {
        drive.write(0x0002, (target + 1e6) as i32); // the target is ignored
        cycles += 1;
        assert!(cycles < 10_000, "quick stop never completed");
    }
    // v²/(2a) = 6250 counts, over v/a = 0.25 s.
    let distance = drive.motor_position_counts() - x0;
    let expected = v0 * v0 / (2.0 * decel);
    assert!(
        (distance - expected).abs() < 0.01 * expected,
        "{distance} vs {expected}"
    );
    assert!(
        (cycles as f64 - v0 / decel / PERIOD_S).abs() <= 1.0,
        "{cycles} cycles"
    );
    assert_eq!(drive.velocity_actual_counts_s(), 0);
}

/// The standard's transitions (IEC 61800-7-201, figure of the power state machine):
/// 1-12, 14, 15 and 13 (any state to Fault reaction active). 16 is not possible with
/// quick stop option code 2, which the sim drive uses.
fn standard_allows(from: DriveState, to: DriveState) -> bool {
    use DriveState::*;
    from == to
        || to == FaultReactionActive
        || matches!(
            (from, to),
            (NotReadyToSwitchOn, SwitchOnDisabled)
                | (SwitchOnDisabled, ReadyToSwitchOn)
                | (ReadyToSwitchOn, SwitchedOn)
                | (SwitchedOn, OperationEnabled)
                | (OperationEnabled, SwitchedOn)
                | (SwitchedOn, ReadyToSwitchOn)
                | (ReadyToSwitchOn, SwitchOnDisabled)
                | (OperationEnabled, ReadyToSwitchOn)
                | (OperationEnabled, SwitchOnDisabled)
                | (SwitchedOn, SwitchOnDisabled)
                | (OperationEnabled, QuickStopActive)
                | (QuickStopActive, SwitchOnDisabled)
                | (FaultReactionActive, Fault)
                | (Fault, SwitchOnDisabled)
        )
}

fn controlword_strategy() -> impl Strategy<Value = u16> {
    prop_oneof![
        prop::sample::select(vec![
            0x0000u16, 0x0002, 0x0006, 0x0007, 0x000F, 0x0080, 0x008F, 0x0100, 0x010F
        ]),
        any::<u16>(),
    ]
}

proptest! {
    #[test]
    fn any_controlword_sequence_makes_only_allowed_transitions(
        steps in prop::collection::vec(
            (controlword_strategy(), -200_000i32..200_000, prop::bool::weighted(0.02)),
            1..300,
        )
    ) {
        let mut drive = SimDrive::new(SimConfig {
            overcurrent_accel_counts_s2: 5.0e8,
            ..SimConfig::default()
        });
        let mut state = DriveState::from_statusword(drive.statusword());
        prop_assert_eq!(state, Some(DriveState::NotReadyToSwitchOn));
        for (controlword, target, fault) in steps {
            if fault {
                drive.inject_fault(0x1000);
            }
            drive.write(controlword, target);
            let next = DriveState::from_statusword(drive.statusword());
            prop_assert!(next.is_some(), "undecodable statusword {:#06x}", drive.statusword());
            let (from, to) = (state.unwrap_or(DriveState::Fault), next.unwrap_or(DriveState::Fault));
            prop_assert!(standard_allows(from, to), "{:?} -> {:?} on {:#06x}", from, to, controlword);
            // Fault is left only by a fault reset (bit 7 set in this word).
            if from == DriveState::Fault && to != DriveState::Fault {
                prop_assert!(controlword & 0x0080 != 0);
            }
            state = next;
        }
    }
}

/// The stability index says when the servo model's integration diverges: a step response
/// (without feed-forward) settles with the index below 4 and grows without bound above
/// it; `min_substeps` keeps it at most 2.
#[test]
fn the_stability_index_tells_a_diverging_model() {
    use kerf_drive::cia402::{Drive, DriveState as S};
    let run = |cfg: SimConfig| -> f64 {
        let mut d = SimDrive::new(cfg);
        for c in [0u16, 0x06, 0x07, 0x0F] {
            d.write(c, 0);
        }
        assert_eq!(d.state(), S::OperationEnabled);
        for _ in 0..2000 {
            d.write(0x0F, 1000);
        }
        // The error at the end, relative to the step; infinite when the model blew up
        // (its acceleration became NaN, which the drive reports as a fault).
        let end = (d.motor_position_counts() - 1000.0).abs() / 1000.0;
        if d.state() == S::OperationEnabled && end.is_finite() {
            end
        } else {
            f64::INFINITY
        }
    };
    for (bandwidth_hz, damping, substeps) in [
        (200.0, 1.0, 1),
        (1000.0, 10.0, 20),
        (50.0, 0.7, 1),
        (400.0, 2.0, 3),
    ] {
        let cfg = SimConfig {
            bandwidth_hz,
            damping,
            substeps,
            velocity_feed_forward: 0.0,
            overcurrent_accel_counts_s2: f64::INFINITY,
            ..SimConfig::default()
        };
        let index = cfg.stability_index();
        let end = run(cfg);
        if index < 3.5 {
            assert!(
                end < 1e-3,
                "{bandwidth_hz} Hz ζ {damping} ×{substeps}: index {index}, error {end}"
            );
        } else if index > 4.5 {
            assert!(
                end > 1.0,
                "{bandwidth_hz} Hz ζ {damping} ×{substeps}: index {index}, error {end}"
            );
        }
        let fixed = SimConfig {
            substeps: cfg.min_substeps(),
            ..cfg
        };
        assert!(fixed.stability_index() <= 2.0 + 1e-9);
        assert!(run(fixed) < 1e-3, "{fixed:?}");
    }
}

/// A load heavier or lighter than the loop was tuned for: under a constant acceleration A
/// with full velocity feed-forward, the motor obeys ρ·ë = −ωn²·e − 2ζωn·ė + ρ·A (e the
/// error, ρ the inertia ratio), so the error settles at ρ·A/ωn²: twice the inertia, twice
/// the lag.
#[test]
fn the_following_error_under_acceleration_grows_with_the_inertia_ratio() {
    let a_counts_s2 = 2.0e6; // 2000 mm/s² at 1000 counts/mm
    for ratio in [0.5, 1.0, 3.0] {
        let cfg = SimConfig {
            period_ns: PERIOD_NS,
            bandwidth_hz: 40.0,
            inertia_ratio: ratio,
            ..SimConfig::default()
        };
        let mut drive = enabled(cfg);
        // Accelerate for 0.3 s (long after the transient of a 40 Hz loop), then read the
        // lag between the target and the motor.
        let mut lag = 0.0;
        for k in 1..=300 {
            let t = k as f64 * PERIOD_S;
            let target = 0.5 * a_counts_s2 * t * t;
            drive.write(0x000F, target.round() as i32);
            lag = target - drive.motor_position_counts();
        }
        let omega = 2.0 * std::f64::consts::PI * 40.0;
        let expected = ratio * a_counts_s2 / (omega * omega);
        assert!(
            (lag - expected).abs() < 0.03 * expected + 1.0,
            "ρ {ratio}: lag {lag} counts, expected {expected}"
        );
    }
}
