//! The drive stage measured from what it sends and records, with simulated drives and a
//! simulated clock (one call per period, no wall clock): the enable sequence and its
//! timeout, a well-tuned drive following jerk-limited motion, a following-error trip,
//! a stalled stream, plausibility and soft-limit violations injected below the motion
//! core, a drive fault on one axis stopping all, resets refused while the cause persists,
//! and the black-box dump.
//!
//! The motion given to the stage is the minimum-jerk quintic
//! x(t) = x0 + D·(10u³ − 15u⁴ + 6u⁵), u = t/Tm, whose peaks are 1.875·D/Tm (velocity),
//! 5.7735·D/Tm² (acceleration) and 60·D/Tm³ (jerk): a trajectory chosen by hand, not
//! produced by the code under test.

use kerf_drive::MAX_AXES;
use kerf_drive::cia402::{Drive, DriveState, cw};
use kerf_drive::recorder::CycleRecord;
use kerf_drive::safety::{AxisSafety, Check, ResetRefused, SafetyConfig, SafetyState};
use kerf_drive::sim::{ERROR_OVERCURRENT, SimConfig, SimDrive};
use kerf_drive::stage::{AxisDrive, DriveStage, DumpReason, Phase, StageInput, StageOutput};
use kerf_geom::AxisLimits;
use proptest::prelude::*;

const PERIOD_NS: u64 = 1_000_000;
const T: f64 = 0.001;

fn limits(v: f64, a: f64, j: f64) -> AxisLimits {
    AxisLimits {
        velocity_units_s: v,
        acceleration_units_s2: a,
        jerk_units_s3: j,
    }
}

fn safety_axis(l: AxisLimits) -> AxisSafety {
    AxisSafety {
        limits: l,
        min_limit_units: -500.0,
        max_limit_units: 500.0,
        ferror_units: 1.0,
        min_ferror_units: 0.1,
    }
}

fn sim(bandwidth_hz: f64, counts_per_mm: f64, start_mm: f64) -> SimConfig {
    SimConfig {
        period_ns: PERIOD_NS,
        bandwidth_hz,
        initial_position_counts: (start_mm * counts_per_mm).round(),
        ..SimConfig::default()
    }
}

/// A drive that cannot be switched on (no mains voltage, say): Switch on and Enable
/// operation are answered as Shutdown, so it stays in Ready to switch on.
struct Stuck {
    inner: SimDrive,
    stuck: bool,
}

impl Drive for Stuck {
    fn write(&mut self, controlword: u16, target: i32) {
        let word = if self.stuck && controlword & cw::SWITCH_ON != 0 {
            cw::SHUTDOWN
        } else {
            controlword
        };
        self.inner.write(word, target);
    }
    fn set_mode_of_operation(&mut self, mode: i8) {
        self.inner.set_mode_of_operation(mode);
    }
    fn mode_of_operation_display(&self) -> i8 {
        self.inner.mode_of_operation_display()
    }
    fn statusword(&self) -> u16 {
        self.inner.statusword()
    }
    fn position_actual_counts(&self) -> i32 {
        self.inner.position_actual_counts()
    }
    fn velocity_actual_counts_s(&self) -> i32 {
        self.inner.velocity_actual_counts_s()
    }
    fn following_error_counts(&self) -> i32 {
        self.inner.following_error_counts()
    }
    fn error_code(&self) -> u16 {
        self.inner.error_code()
    }
}

/// A stage of three axes X, Y, Z with the same limits and drives.
struct Rig<D: Drive> {
    stage: DriveStage<D>,
    cycle: u64,
    outputs: Vec<StageOutput>,
}

fn rig(l: AxisLimits, drive: impl Fn(usize) -> AxisDrive<SimDrive>) -> Rig<SimDrive> {
    rig_of(l, drive, 3)
}

fn rig_of<D: Drive>(l: AxisLimits, drive: impl Fn(usize) -> AxisDrive<D>, stall: u32) -> Rig<D> {
    let ax = Some(safety_axis(l));
    let mut cfg = SafetyConfig::new([ax, ax, ax, None, None, None], T);
    cfg.stall_cycles = stall;
    let axes = [
        Some(drive(0)),
        Some(drive(1)),
        Some(drive(2)),
        None,
        None,
        None,
    ];
    Rig {
        stage: DriveStage::new(axes, cfg, 2000).expect("a valid stage"),
        cycle: 0,
        outputs: Vec::new(),
    }
}

fn sim_drive(
    bandwidth_hz: f64,
    counts_per_mm: f64,
    start: [f64; 3],
) -> impl Fn(usize) -> AxisDrive<SimDrive> {
    move |i| AxisDrive {
        drive: SimDrive::new(sim(bandwidth_hz, counts_per_mm, start[i])),
        scale: kerf_drive::cia402::Scale::new(counts_per_mm, 1).unwrap(),
        enable_timeout_cycles: 50,
    }
}

impl<D: Drive> Rig<D> {
    fn step(&mut self, setpoint: Option<[f64; 3]>) -> StageOutput {
        self.cycle += 1;
        let sp = setpoint.map(|p| [p[0], p[1], p[2], 0.0, 0.0, 0.0]);
        let out = self.stage.cycle(&StageInput {
            setpoint: sp,
            line: self.cycle as u32,
            time_s: self.cycle as f64 * T,
        });
        self.outputs.push(out);
        out
    }

    /// Runs until the drives are enabled; the position the motion starts from.
    fn enable(&mut self) -> [f64; 3] {
        for _ in 0..20 {
            let out = self.step(None);
            if let Some(p) = out.enabled_at {
                return [p[0], p[1], p[2]];
            }
        }
        panic!("the drives did not enable");
    }

    fn sent(&self) -> Vec<[f64; 3]> {
        self.outputs
            .iter()
            .map(|o| [o.command[0], o.command[1], o.command[2]])
            .collect()
    }
}

/// The quintic from `x0` over `d` (per axis) in `tm` seconds, at time `t`.
fn quintic(x0: [f64; 3], d: [f64; 3], tm: f64, t: f64) -> [f64; 3] {
    let u = (t / tm).clamp(0.0, 1.0);
    let s = u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
    [x0[0] + d[0] * s, x0[1] + d[1] * s, x0[2] + d[2] * s]
}

/// The shortest duration of the quintic over the largest |d| within the limits.
fn quintic_time(d: f64, l: &AxisLimits) -> f64 {
    let d = d.abs();
    (1.875 * d / l.velocity_units_s)
        .max((5.7735 * d / l.acceleration_units_s2).sqrt())
        .max((60.0 * d / l.jerk_units_s3).cbrt())
}

/// Per-axis velocity, acceleration and jerk of a series of positions by finite
/// differences, each within 1.01 × its limit.
fn assert_within_limits(xs: &[[f64; 3]], l: &AxisLimits, what: &str) {
    assert_axes_within_limits(xs, &[0, 1, 2], l, what);
}

fn assert_axes_within_limits(xs: &[[f64; 3]], axes: &[usize], l: &AxisLimits, what: &str) {
    for k in 3..xs.len() {
        for &i in axes {
            let (x0, x1, x2, x3) = (xs[k - 3][i], xs[k - 2][i], xs[k - 1][i], xs[k][i]);
            let v = (x3 - x2) / T;
            let a = (x3 - 2.0 * x2 + x1) / (T * T);
            let j = (x3 - 3.0 * x2 + 3.0 * x1 - x0) / (T * T * T);
            assert!(v.abs() <= 1.01 * l.velocity_units_s, "{what}: v {v} at {k}");
            assert!(
                a.abs() <= 1.01 * l.acceleration_units_s2,
                "{what}: a {a} at {k}"
            );
            assert!(j.abs() <= 1.01 * l.jerk_units_s3, "{what}: j {j} at {k}");
        }
    }
}

#[test]
fn the_drives_enable_where_their_motors_stand_and_nothing_moves_meanwhile() {
    let start = [12.3456, -7.5, 300.0];
    let l = limits(100.0, 1000.0, 50_000.0);
    let mut r = rig(l, sim_drive(50.0, 1000.0, start));
    let mut enabled = None;
    let mut cycles = 0;
    while enabled.is_none() {
        let out = r.step(None);
        cycles += 1;
        assert!(cycles < 20);
        assert_eq!(out.phase == Phase::Enabling, out.enabled_at.is_none());
        // While enabling, every target is the motor's own position (to the count).
        for (c, s) in out.command.iter().zip(start.iter()) {
            assert!((c - s).abs() <= 0.5e-3, "{out:?}");
        }
        enabled = out.enabled_at;
    }
    // Not ready → Switch on disabled → Ready → Switched on → Operation enabled: four
    // exchanges, the fifth cycle sees it.
    assert_eq!(cycles, 5);
    let at = enabled.unwrap();
    for i in 0..3 {
        assert!((at[i] - start[i]).abs() <= 0.5e-3);
        let d = r.stage.drive_mut(i).unwrap();
        assert_eq!(d.state(), DriveState::OperationEnabled);
        assert!((d.motor_position_counts() - (start[i] * 1000.0).round()).abs() < 1e-9);
    }
    assert!(r.stage.ready());
    // Holding the position keeps it, to the count.
    for _ in 0..100 {
        let out = r.step(Some([at[0], at[1], at[2]]));
        assert_eq!(out.state, SafetyState::Running);
        assert_eq!(&out.command[..3], &at[..3]);
    }
}

#[test]
fn an_enable_that_times_out_latches_a_fault_until_the_drive_can_enable() {
    let l = limits(100.0, 1000.0, 50_000.0);
    let drive = |i: usize| AxisDrive {
        drive: Stuck {
            inner: SimDrive::new(sim(50.0, 1000.0, 1.0)),
            stuck: i == 2,
        },
        scale: kerf_drive::cia402::Scale::new(1000.0, 1).unwrap(),
        enable_timeout_cycles: 5,
    };
    let mut r = rig_of(l, drive, 3);
    let mut fault = None;
    for _ in 0..30 {
        let out = r.step(None);
        if let Some(f) = out.tripped {
            fault = Some(f);
            break;
        }
    }
    let f = fault.expect("the enable timed out");
    assert_eq!((f.check, f.axis), (Check::EnableTimeout, Some(2)));
    assert!(!r.stage.ready());
    // Reset refused while the drive still cannot enable.
    r.stage.request_reset();
    let outcome = (0..100).find_map(|_| r.step(Some([1.0; 3])).reset);
    assert_eq!(outcome, Some(Err(ResetRefused::NotEnabled(2))));
    // Mains back: the reset enables it and clears the fault, from where it stands.
    r.stage.drive_mut(2).unwrap().stuck = false;
    r.stage.request_reset();
    let mut at = None;
    let outcome = (0..100).find_map(|_| {
        let out = r.step(Some([1.0; 3]));
        at = at.or(out.enabled_at);
        out.reset
    });
    assert_eq!(outcome, Some(Ok(())));
    assert_eq!(&at.unwrap()[..3], &[1.0, 1.0, 1.0]);
    assert!(r.stage.ready());
    // Nothing moved at any time.
    for p in r.sent() {
        assert_eq!(p, [1.0; 3]);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// A well-tuned drive (full velocity feed-forward, ζ = 1) lags a motion of peak
    /// acceleration A by about A/ωn²; with that below half of `min_ferror` the stage never
    /// trips on jerk-limited motion at the axis limits, and the recorded following error
    /// stays below A/ωn² (with 50 % room for the transients) plus one count.
    #[test]
    fn a_well_tuned_drive_follows_motion_at_the_limits(
        bandwidth_hz in 20.0f64..200.0,
        counts_per_mm in prop::sample::select(vec![100.0, 1000.0, 10_000.0]),
        a_max in 200.0f64..8000.0,
        v_max in 50.0f64..400.0,
        j_max in 5_000.0f64..200_000.0,
        d in prop::array::uniform3(-80.0f64..80.0),
    ) {
        let omega = 2.0 * std::f64::consts::PI * bandwidth_hz;
        let lag = a_max / (omega * omega);
        prop_assume!(lag + 1.0 / counts_per_mm <= 0.05);
        let l = limits(v_max, a_max, j_max);
        let mut r = rig(l, sim_drive(bandwidth_hz, counts_per_mm, [0.0; 3]));
        let x0 = r.enable();
        let dmax = d.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let tm = quintic_time(dmax, &l) * 1.001;
        let n = (tm / T).ceil() as usize + 200;
        for k in 1..=n {
            let out = r.step(Some(quintic(x0, d, tm, k as f64 * T)));
            prop_assert!(out.tripped.is_none(), "{:?}", out.tripped);
        }
        let worst = r
            .stage
            .recorder()
            .iter()
            .flat_map(|rec: &CycleRecord| rec.following_error[..3].to_vec())
            .fold(0.0f64, |m, e| m.max(e.abs()));
        prop_assert!(worst <= 1.5 * lag + 1.0 / counts_per_mm, "worst {} lag {}", worst, lag);
    }
}

#[test]
fn a_low_bandwidth_drive_trips_the_following_error_check() {
    let l = limits(200.0, 2000.0, 50_000.0);
    let mut r = rig(l, sim_drive(3.0, 1000.0, [0.0; 3]));
    let x0 = r.enable();
    let d = [60.0, 0.0, 0.0];
    let tm = quintic_time(60.0, &l);
    let mut tripped = None;
    for k in 1..=((tm / T) as usize + 500) {
        let out = r.step(Some(quintic(x0, d, tm, k as f64 * T)));
        if out.tripped.is_some() {
            tripped = out.tripped;
            break;
        }
    }
    let f = tripped.expect("the slow drive trips");
    assert_eq!((f.check, f.axis), (Check::FollowingError, Some(0)));
    // The limit is LinuxCNC's: max(min_ferror, ferror · |v| / v_max), v the step of the
    // commands the drive was tracking (the two before the trip).
    let sent = r.sent();
    let k = sent.len() - 1;
    let v = (sent[k - 1][0] - sent[k - 2][0]) / T;
    let expected = (0.1f64).max(1.0 * v.abs() / 200.0);
    assert!(
        (f.limit - expected).abs() < 1e-9,
        "{} vs {expected}",
        f.limit
    );
    assert!(f.value > f.limit);
    // Every axis then ramps to rest within its limits.
    for _ in 0..400 {
        r.step(None);
    }
    assert_eq!(r.stage.safety().state(), SafetyState::Stopped);
    assert_within_limits(&sent[k - 3..], &l, "the ramp");
    let sent = r.sent();
    assert_within_limits(&sent[k - 3..], &l, "the quick stop");
    let last = sent[sent.len() - 1];
    assert_eq!(last, sent[sent.len() - 2]);
}

#[test]
fn a_missing_stream_is_held_then_quick_stopped() {
    let l = limits(100.0, 1000.0, 50_000.0);
    let mut r = rig(l, sim_drive(80.0, 1000.0, [0.0; 3]));
    let x0 = r.enable();
    // A slow steady feed of 0.5 mm/s along X (from rest: 500 mm/s² for one period).
    let at = |k: usize| [x0[0] + 0.0005 * k as f64, x0[1], x0[2]];
    for k in 1..=100 {
        r.step(Some(at(k)));
    }
    // Two missed cycles: held at the last setpoint.
    for _ in 0..2 {
        let out = r.step(None);
        assert_eq!(out.state, SafetyState::Holding);
        assert_eq!(out.command[0], at(100)[0]);
        assert!(out.tripped.is_none());
    }
    // The stream resumes: running again.
    for k in 101..=150 {
        let out = r.step(Some(at(k)));
        assert_eq!(out.state, SafetyState::Running, "cycle {k}");
    }
    // Three missed cycles in a row trip on the third.
    assert!(r.step(None).tripped.is_none());
    assert!(r.step(None).tripped.is_none());
    let f = r.step(None).tripped.expect("the stall trips");
    assert_eq!(
        (f.check, f.axis, f.value, f.limit),
        (Check::StreamStall, None, 3.0, 3.0)
    );
    let held = r.sent().last().copied().unwrap();
    assert_eq!(held[0], at(150)[0]);
    for k in 151..200 {
        let out = r.step(Some(at(k)));
        assert_eq!(&out.command[..3], &held[..]);
    }
}

#[test]
fn a_setpoint_step_injected_below_the_motion_core_never_reaches_a_drive() {
    let l = limits(200.0, 2000.0, 50_000.0);
    let mut r = rig(l, sim_drive(60.0, 1000.0, [0.0; 3]));
    let x0 = r.enable();
    let d = [40.0, -30.0, 10.0];
    let tm = quintic_time(40.0, &l);
    let mut bad = None;
    for k in 1..=((tm / T) as usize) {
        let mut p = quintic(x0, d, tm, k as f64 * T);
        if k == 200 {
            p[1] += 0.5; // half a millimetre in one period: 500 mm/s
            bad = Some(p);
        }
        let out = r.step(Some(p));
        if k == 200 {
            let f = out.tripped.expect("the step trips");
            assert_eq!((f.check, f.axis), (Check::Velocity, Some(1)));
            // −150 mm/s or so of the quintic plus 500 mm/s of the step.
            assert!(f.value > f.limit && (f.limit - 210.0).abs() < 1e-9, "{f:?}");
            assert_ne!(out.command[1], bad.unwrap()[1]);
        }
    }
    for _ in 0..300 {
        r.step(None);
    }
    let sent = r.sent();
    // From the trip on, a jerk-limited stop of every axis, to rest.
    let trip = r.outputs.iter().position(|o| o.tripped.is_some()).unwrap();
    assert_within_limits(&sent[trip - 3..], &l, "the quick stop after a step");
    assert_eq!(r.stage.safety().state(), SafetyState::Stopped);
}

#[test]
fn a_setpoint_beyond_the_soft_limit_never_reaches_a_drive() {
    let l = limits(200.0, 2000.0, 50_000.0);
    let ax = Some(AxisSafety {
        max_limit_units: 10.0,
        ..safety_axis(l)
    });
    let cfg = SafetyConfig::new([ax, ax, ax, None, None, None], T);
    let drive = sim_drive(60.0, 1000.0, [0.0; 3]);
    let mut r = Rig {
        stage: DriveStage::new(
            [
                Some(drive(0)),
                Some(drive(1)),
                Some(drive(2)),
                None,
                None,
                None,
            ],
            cfg,
            1000,
        )
        .unwrap(),
        cycle: 0,
        outputs: Vec::new(),
    };
    let x0 = r.enable();
    let d = [12.0, 0.0, 0.0];
    let tm = quintic_time(12.0, &l);
    let mut tripped = None;
    for k in 1..=((tm / T) as usize + 300) {
        let p = quintic(x0, d, tm, k as f64 * T);
        let out = r.step(Some(p));
        if out.tripped.is_some() {
            tripped = tripped.or(out.tripped);
        }
        // Never beyond the limit: the setpoint is refused once the axis could no
        // longer stop before it, and the quick stop ends inside.
        assert!(out.command[0] <= 10.0, "{p:?} {out:?}");
    }
    let f = tripped.expect("crossing the soft limit trips");
    assert_eq!(
        (f.check, f.axis, f.limit),
        (Check::SoftLimit, Some(0), 10.0)
    );
    assert!(f.value > 10.0);
    assert_eq!(r.stage.safety().state(), SafetyState::Stopped);
    let sent = r.sent();
    let at = r.outputs.iter().position(|o| o.tripped.is_some()).unwrap();
    assert_within_limits(&sent[at - 3..], &l, "the stop before the soft limit");
}

#[test]
fn a_drive_fault_on_one_axis_stops_all_and_reset_waits_for_its_cause() {
    let l = limits(200.0, 2000.0, 50_000.0);
    let mut r = rig(l, sim_drive(60.0, 1000.0, [0.0; 3]));
    let x0 = r.enable();
    let d = [50.0, 40.0, -20.0];
    let tm = quintic_time(50.0, &l);
    let mut trip = None;
    for k in 1..=((tm / T) as usize) {
        if k == 150 {
            // A lasting cause (over temperature, say): the drive faults and refuses a
            // fault reset while it lasts.
            r.stage
                .drive_mut(1)
                .unwrap()
                .set_fault_cause(Some(ERROR_OVERCURRENT));
        }
        let out = r.step(Some(quintic(x0, d, tm, k as f64 * T)));
        if let Some(f) = out.tripped {
            trip = Some((r.outputs.len() - 1, f));
            break;
        }
    }
    let (at, f) = trip.expect("the drive fault trips");
    assert_eq!((f.check, f.axis), (Check::DriveFault, Some(1)));
    assert_eq!(r.stage.error_codes()[1], ERROR_OVERCURRENT);
    for _ in 0..400 {
        r.step(Some([0.0; 3]));
    }
    assert_eq!(r.stage.safety().state(), SafetyState::Stopped);
    // X and Z ramp to rest within their limits; Y's drive is off in Fault.
    let sent = r.sent();
    // (Y's target is its braked motor's position from the trip on.)
    assert_axes_within_limits(&sent[at - 3..], &[0, 2], &l, "the quick stop of the others");
    assert_eq!(r.stage.drive_mut(1).unwrap().state(), DriveState::Fault);
    for i in [0, 2] {
        assert_eq!(
            r.stage.drive_mut(i).unwrap().state(),
            DriveState::OperationEnabled
        );
    }
    // The cause persists: refused.
    let held = r.stage.command();
    let hold = [held[0], held[1], held[2]];
    r.stage.request_reset();
    let outcome = (0..200).find_map(|_| r.step(Some(hold)).reset);
    assert_eq!(outcome, Some(Err(ResetRefused::DriveFault(1))));
    assert!(r.stage.fault().is_some());
    // The cause is gone: Y is reset and enabled where its motor stands, the fault clears.
    r.stage.drive_mut(1).unwrap().set_fault_cause(None);
    r.stage.request_reset();
    let mut at_reset = None;
    let outcome = (0..200).find_map(|_| {
        let out = r.step(Some(hold));
        at_reset = at_reset.or(out.enabled_at);
        out.reset
    });
    assert_eq!(outcome, Some(Ok(())));
    let at_reset = at_reset.expect("the core is told where to rest");
    let y_motor = r.stage.drive_mut(1).unwrap().motor_position_counts() / 1000.0;
    assert!(
        (at_reset[1] - y_motor).abs() <= 0.5e-3,
        "{at_reset:?} {y_motor}"
    );
    assert_eq!((at_reset[0], at_reset[2]), (hold[0], hold[2]));
    assert!(r.stage.ready());
    // The stream continues from there, running.
    let from = [at_reset[0], at_reset[1], at_reset[2]];
    for _ in 0..50 {
        let out = r.step(Some(from));
        assert_eq!(out.state, SafetyState::Running);
        assert!(out.tripped.is_none());
    }
}

#[test]
fn a_dump_is_the_black_box_as_it_stood_when_asked() {
    let l = limits(200.0, 2000.0, 50_000.0);
    let mut r = rig(l, sim_drive(60.0, 1000.0, [0.0; 3]));
    let x0 = r.enable();
    let d = [30.0, 20.0, 5.0];
    let tm = quintic_time(30.0, &l);
    // More cycles than the ring holds (2,000), so that it has wrapped.
    for k in 1..=2500 {
        r.step(Some(quintic(x0, d, tm, k as f64 * T)));
    }
    r.stage.request_dump(42);
    // The dump begins in the next cycle: the ring as it stands after that cycle.
    r.step(Some(quintic(x0, d, tm, 2501.0 * T)));
    let expected: Vec<CycleRecord> = r.stage.recorder().iter().copied().collect();
    assert_eq!(expected.len(), 2000);
    let mut dump = None;
    for k in 2502..=2600 {
        r.step(Some(quintic(x0, d, tm, k as f64 * T)));
        if let Some(got) = r.stage.take_dump() {
            dump = Some(got);
            break;
        }
    }
    let dump = dump.expect("the dump is ready within capacity / chunk cycles");
    assert_eq!(dump.reason, DumpReason::Request(42));
    let got: Vec<CycleRecord> = dump.recorder.iter().copied().collect();
    assert_eq!(got, expected);
    // The last record is the cycle the copy began in; the ring went on meanwhile.
    assert_eq!(got.last().unwrap().sequence, 2506);
    assert!(r.stage.recorder().iter().last().unwrap().sequence > 2505);
    // A second dump waits for the ring to come back.
    let end = quintic(x0, d, tm, 10.0);
    r.stage.request_dump(43);
    for _ in 0..50 {
        r.step(Some(end));
        assert!(r.stage.take_dump().is_none());
    }
    r.stage.return_spare(dump.recorder);
    let again = (0..50).find_map(|_| {
        r.step(Some(end));
        r.stage.take_dump()
    });
    assert_eq!(again.map(|d| d.reason), Some(DumpReason::Request(43)));
}

#[test]
fn a_trip_dumps_the_black_box_once_the_quick_stop_is_at_rest() {
    let l = limits(200.0, 2000.0, 50_000.0);
    let mut r = rig(l, sim_drive(60.0, 1000.0, [0.0; 3]));
    let x0 = r.enable();
    let d = [50.0, 0.0, 0.0];
    let tm = quintic_time(50.0, &l);
    for k in 1..=200 {
        r.step(Some(quintic(x0, d, tm, k as f64 * T)));
    }
    r.stage
        .drive_mut(0)
        .unwrap()
        .inject_fault(ERROR_OVERCURRENT);
    let mut dump = None;
    for k in 201..700 {
        r.step(Some(quintic(x0, d, tm, k as f64 * T)));
        if let Some(got) = r.stage.take_dump() {
            dump = Some(got);
            break;
        }
    }
    let dump = dump.expect("a dump after the trip");
    let DumpReason::Fault(f) = dump.reason else {
        panic!("{:?}", dump.reason)
    };
    assert_eq!((f.check, f.axis), (Check::DriveFault, Some(0)));
    let rows: Vec<&CycleRecord> = dump.recorder.iter().collect();
    // It holds the motion before the trip and the whole stop, ending at rest.
    assert!(rows.iter().any(|c| c.state == SafetyState::Running));
    assert_eq!(rows.last().unwrap().state, SafetyState::Stopped);
    assert!(rows.iter().any(|c| c.state == SafetyState::QuickStop) || rows.len() > 1);
}

#[test]
fn reset_with_nothing_latched_is_accepted_at_once() {
    let l = limits(100.0, 1000.0, 50_000.0);
    let mut r = rig(l, sim_drive(50.0, 1000.0, [0.0; 3]));
    let x0 = r.enable();
    r.stage.request_reset();
    assert_eq!(r.step(Some(x0)).reset, Some(Ok(())));
}

#[test]
fn a_drive_that_disables_itself_trips() {
    let l = limits(100.0, 1000.0, 50_000.0);
    let drive = |_: usize| AxisDrive {
        drive: Stuck {
            inner: SimDrive::new(sim(50.0, 1000.0, 0.0)),
            stuck: false,
        },
        scale: kerf_drive::cia402::Scale::new(1000.0, 1).unwrap(),
        enable_timeout_cycles: 50,
    };
    let mut r = rig_of(l, drive, 3);
    let x0 = r.enable();
    for _ in 0..10 {
        r.step(Some(x0));
    }
    // The drive drops out of Operation enabled (its enable input went away, say).
    r.stage.drive_mut(0).unwrap().inner.write(cw::SHUTDOWN, 0);
    let f = (0..5)
        .find_map(|_| r.step(Some(x0)).tripped)
        .expect("it trips");
    assert_eq!((f.check, f.axis), (Check::DriveDisabled, Some(0)));
    let _ = MAX_AXES;
}

#[test]
fn a_drive_that_disabled_itself_is_enabled_again_by_a_reset() {
    // As after a fieldbus watchdog: the drive left Operation enabled on its own, the
    // fault latched, and a reset must bring it back where it stands.
    let l = limits(100.0, 1000.0, 50_000.0);
    let mut r = rig(l, sim_drive(50.0, 1000.0, [1.0, 2.0, 3.0]));
    let x0 = r.enable();
    for _ in 0..10 {
        r.step(Some(x0));
    }
    r.stage.drive_mut(1).unwrap().write(cw::SHUTDOWN, 2000);
    let f = (0..5)
        .find_map(|_| r.step(Some(x0)).tripped)
        .expect("it trips");
    assert_eq!((f.check, f.axis), (Check::DriveDisabled, Some(1)));
    for _ in 0..50 {
        r.step(Some(x0));
    }
    r.stage.request_reset();
    let outcome = (0..200)
        .find_map(|_| r.step(Some(x0)).reset)
        .expect("the reset ends");
    assert_eq!(outcome, Ok(()));
    assert_eq!(
        DriveState::from_statusword(r.stage.drive_mut(1).unwrap().statusword()),
        Some(DriveState::OperationEnabled)
    );
}
