//! Homing by the drive (CiA 402 homing mode 6) measured from what a master sees: the
//! positions and statuswords of simulated drives, cycle by cycle, through the drive
//! stage (and a bare drive for the profile's own rules).
//!
//! - methods 35 and 37 set the position actual value to the home offset without motion;
//! - methods 19 to 22 with the home switch at random places find it: the drive comes to
//!   rest at the switch's edge (within a count, in its old coordinates), approached at the
//!   zero speed in the method's direction, and reads the home offset there (within a
//!   count); the speeds and the acceleration of its own motion stay within 0x6099 and
//!   0x609A; the other axes keep exactly their commands; afterwards the axis follows
//!   cyclic synchronous targets from its new coordinates;
//! - no switch: the error bit, a latched fault naming the axis, the motion stopped within
//!   the search limit plus its stop, and a reset accepted once the drive is back in mode 8;
//! - an unsupported method, a fault elsewhere while a drive homes, and the refusals of a
//!   start;
//! - no allocation in a cycle, whole homings included.
//!
//! The switch positions, offsets and speeds are the test's own numbers; the expected
//! values come from them, in counts, never from the code under test.

use kerf_drive::MAX_AXES;
use kerf_drive::cia402::{
    Drive, DriveState, MODE_CYCLIC_SYNC_POSITION, MODE_HOMING, Scale, cw, homing_method, sw,
};
use kerf_drive::safety::{AxisSafety, Check, SafetyConfig, SafetyState};
use kerf_drive::sim::{ERROR_OVERCURRENT, SimConfig, SimDrive, SimHomingConfig};
use kerf_drive::stage::{AxisDrive, DriveHoming, DriveStage, Phase, StageInput, StageOutput};
use kerf_geom::AxisLimits;
use kerf_testkit::alloc::{Count, CountingAllocator};
use proptest::prelude::*;

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

const PERIOD_NS: u64 = 1_000_000;
const T: f64 = 0.001;

/// The axes' limits for the safety layer (X's own motion while its drive homes is the
/// drive's; Y and Z move within these).
fn safety_axis() -> AxisSafety {
    AxisSafety {
        limits: AxisLimits {
            velocity_units_s: 100.0,
            acceleration_units_s2: 2000.0,
            jerk_units_s3: 100_000.0,
        },
        min_limit_units: -500.0,
        max_limit_units: 500.0,
        ferror_units: 1.0,
        min_ferror_units: 0.1,
    }
}

/// One machine: X's scale and drive tuning; Y and Z as X's scale with direction +1.
#[derive(Clone, Copy, Debug)]
struct Machine {
    counts_per_mm: f64,
    direction: i32,
    bandwidth_hz: f64,
    damping: f64,
    /// The motors' positions at power-up, counts.
    start_counts: [f64; 3],
}

/// What the master saw in one cycle: X's statusword and mode display as read before the
/// cycle (what the stage reads), and the cycle's output.
#[derive(Clone, Copy, Debug)]
struct Sample {
    statusword: u16,
    mode: i8,
    out: StageOutput,
}

struct Rig {
    stage: DriveStage<SimDrive>,
    m: Machine,
    cycle: u64,
    log: Vec<Sample>,
    /// Y's motion ([`y_motion`]): where it started, and the cycles it has run.
    y: (f64, u64),
}

fn rig(m: Machine, homing: SimHomingConfig) -> Rig {
    let ax = Some(safety_axis());
    let cfg = SafetyConfig::new([ax, ax, ax, None, None, None], T);
    let drive = |i: usize| {
        let mut d = SimDrive::new(SimConfig {
            period_ns: PERIOD_NS,
            bandwidth_hz: m.bandwidth_hz,
            damping: m.damping,
            initial_position_counts: m.start_counts[i],
            ..SimConfig::default()
        });
        if i == 0 {
            d.set_homing_config(homing);
        }
        Some(AxisDrive {
            drive: d,
            scale: Scale::new(m.counts_per_mm, if i == 0 { m.direction } else { 1 }).unwrap(),
            enable_timeout_cycles: 50,
        })
    };
    let axes = [drive(0), drive(1), drive(2), None, None, None];
    Rig {
        stage: DriveStage::new(axes, cfg, 1000).expect("a valid stage"),
        m,
        cycle: 0,
        log: Vec::new(),
        y: (0.0, 0),
    }
}

impl Rig {
    fn step(&mut self, setpoint: Option<[f64; 3]>) -> StageOutput {
        self.cycle += 1;
        let x = self.stage.drive(0).unwrap();
        let (statusword, mode) = (x.statusword(), x.mode_of_operation_display());
        let out = self.stage.cycle(&StageInput {
            setpoint: setpoint.map(|p| [p[0], p[1], p[2], 0.0, 0.0, 0.0]),
            line: self.cycle as u32,
            time_s: self.cycle as f64 * T,
        });
        self.log.push(Sample {
            statusword,
            mode,
            out,
        });
        out
    }

    /// Runs until the drives are enabled; where they stand.
    fn enable(&mut self) -> [f64; 3] {
        for _ in 0..20 {
            if let Some(p) = self.step(None).enabled_at {
                return [p[0], p[1], p[2]];
            }
        }
        panic!("the drives did not enable");
    }

    /// X's position in its drive's counts, from a position in mm.
    fn x_counts(&self, mm: f64) -> f64 {
        f64::from(self.m.direction) * mm * self.m.counts_per_mm
    }
}

/// Y's motion while X homes: a slow cosine of 2.5 mm around `y0` (7.9 mm/s, 25 mm/s²).
fn y_motion(y0: f64, k: u64) -> f64 {
    y0 + 1.25 * (1.0 - (std::f64::consts::PI * k as f64 * T).cos())
}

/// Starts X's drive homing and runs until it has ended (the drive back in mode 8), with
/// Y moving and Z held, X's setpoint a constant that the stage must not use. Asserts
/// that Y and Z get exactly their setpoints while no fault is latched. Returns the index
/// in the log of the cycle that started it.
fn home_x(r: &mut Rig, from: [f64; 3], max_cycles: u64) -> usize {
    r.stage
        .start_drive_homing(0)
        .expect("the start is accepted");
    let started = r.log.len();
    r.y = (from[1], 0);
    for k in 1..=max_cycles {
        r.y.1 += 1;
        let sp = [from[0] + 123.0, y_motion(r.y.0, r.y.1), from[2]];
        let out = r.step(Some(sp));
        if r.stage.fault().is_none() {
            assert_eq!(out.command[1], sp[1], "Y keeps its command (cycle {k})");
            assert_eq!(out.command[2], sp[2], "Z keeps its command (cycle {k})");
        }
        if !r.stage.drive_homing_active(0) {
            return started;
        }
    }
    panic!(
        "the drive homing did not end within {max_cycles} cycles: {:?}",
        r.stage.drive_homing(0)
    );
}

/// X's actual positions in counts of its drive, from `from` on in the log.
fn x_counts_log(r: &Rig, from: usize) -> Vec<f64> {
    r.log[from..]
        .iter()
        .map(|s| r.x_counts(s.out.actual[0]))
        .collect()
}

fn machine(counts_per_mm: f64, direction: i32, start_counts: f64) -> Machine {
    Machine {
        counts_per_mm,
        direction,
        bandwidth_hz: 50.0,
        damping: 1.0,
        start_counts: [start_counts, 2000.0, -3000.0],
    }
}

#[test]
fn methods_35_and_37_set_the_position_to_the_offset_without_motion() {
    for (method, direction, start, offset) in [
        (homing_method::CURRENT_POSITION, 1, 12_345.0, -4_000),
        (homing_method::CURRENT_POSITION, -1, -777.0, 250_000),
        (homing_method::CURRENT_POSITION_35, 1, 0.0, 17),
        (homing_method::CURRENT_POSITION_35, -1, 99_999.0, 0),
    ] {
        let m = machine(1000.0, direction, start);
        let mut r = rig(
            m,
            SimHomingConfig {
                method,
                home_offset_counts: offset,
                ..SimHomingConfig::default()
            },
        );
        let p0 = r.enable();
        assert_eq!(r.x_counts(p0[0]), start);
        let started = home_x(&mut r, p0, 100);
        assert_eq!(r.stage.drive_homing(0), DriveHoming::Attained);
        assert!(r.stage.fault().is_none());
        let xs = x_counts_log(&r, started);
        // The readings: the old position until the new one, which is the offset; nothing
        // in between, and the motor never moved (the new frame is the old plus a constant).
        let jump = xs.iter().position(|&c| c != start).expect("a new position");
        assert!(xs[..jump].iter().all(|&c| c == start), "{xs:?}");
        assert!(xs[jump..].iter().all(|&c| c == f64::from(offset)), "{xs:?}");
        // The master saw homing mode and then bits 12 and 10 with the new position.
        let s = r.log[started + jump];
        assert_eq!(s.mode, MODE_HOMING);
        assert_eq!(
            s.statusword & (sw::HOMING_ATTAINED | sw::HOMING_ERROR | sw::TARGET_REACHED),
            sw::HOMING_ATTAINED | sw::TARGET_REACHED,
            "{:#06x}",
            s.statusword
        );
        let homed = r
            .log
            .iter()
            .find_map(|s| s.out.homed_by_drive[0])
            .expect("reported");
        assert_eq!(
            homed,
            f64::from(direction) * f64::from(offset) / 1000.0,
            "method {method}"
        );
        assert_eq!(
            r.stage.drive(0).unwrap().mode_of_operation_display(),
            MODE_CYCLIC_SYNC_POSITION
        );
        follows_csp_after(&mut r, homed);
    }
}

/// After homing, X follows a 2 mm move in cyclic synchronous position from `homed`,
/// with Y going on and Z held: its actual position ends within 0.01 mm of the target, no
/// fault.
fn follows_csp_after(r: &mut Rig, homed: f64) {
    let held = r.stage.command();
    let tm = 0.2;
    let n = (tm / T) as u64;
    for k in 1..=n + 200 {
        let u = (k as f64 * T / tm).min(1.0);
        let s = u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
        r.y.1 += 1;
        let y = y_motion(r.y.0, r.y.1);
        let out = r.step(Some([homed + 2.0 * s, y, held[2]]));
        assert!(out.tripped.is_none(), "{:?}", out.tripped);
    }
    let last = r.log.last().unwrap().out;
    assert!(
        (last.actual[0] - (homed + 2.0)).abs() < 0.01,
        "{} against {}",
        last.actual[0],
        homed + 2.0
    );
    assert_eq!(r.stage.safety().state(), SafetyState::Running);
}

/// The direction in which method `method` crosses the switch edge it latches: +1 or -1.
fn latch_direction(method: i8) -> f64 {
    match method {
        19 | 22 => -1.0,
        20 | 21 => 1.0,
        _ => unreachable!(),
    }
}

/// One switch homing on X with these numbers (mm and mm/s where named so; the switch in
/// the motor's own frame); every assertion of the module's list for methods 19 to 22.
#[allow(clippy::too_many_arguments)]
fn switch_homing(
    method: i8,
    counts_per_mm: f64,
    direction: i32,
    start_mm: f64,
    switch_mm: f64,
    search_mm_s: f64,
    zero_mm_s: f64,
    accel_mm_s2: f64,
    offset_mm: f64,
    bandwidth_hz: f64,
    damping: f64,
) {
    let cpm = counts_per_mm;
    let start = (start_mm * cpm).round();
    let switch = switch_mm * cpm;
    let search = (search_mm_s * cpm).round();
    let zero = (zero_mm_s * cpm).round();
    let accel = (accel_mm_s2 * cpm).round();
    let offset = (offset_mm * cpm).round();
    let m = Machine {
        bandwidth_hz,
        damping,
        ..machine(cpm, direction, start)
    };
    let limit = 60.0 * cpm;
    let mut r = rig(
        m,
        SimHomingConfig {
            method,
            search_speed_counts_s: search as u32,
            zero_speed_counts_s: zero as u32,
            acceleration_counts_s2: accel as u32,
            home_offset_counts: offset as i32,
            home_switch_counts: Some(switch),
            search_limit_counts: limit,
        },
    );
    let p0 = r.enable();
    let started = home_x(&mut r, p0, 200_000);
    let what = format!(
        "method {method}, {cpm} counts/mm, direction {direction}, start {start}, switch {switch}, speeds {search}/{zero}, accel {accel}, offset {offset}"
    );
    assert_eq!(r.stage.drive_homing(0), DriveHoming::Attained, "{what}");
    assert!(r.stage.fault().is_none(), "{what}: {:?}", r.stage.fault());
    assert!(r.log.iter().all(|s| s.out.tripped.is_none()), "{what}");
    // A few cycles more at rest there (Y going on).
    let homed = r.log.last().unwrap().out.homed_by_drive[0].expect("reported at the end");
    let z = r.stage.command()[2];
    for _ in 0..3 {
        r.y.1 += 1;
        let y = y_motion(r.y.0, r.y.1);
        r.step(Some([homed, y, z]));
    }

    // The new coordinates arrive with bits 12 and 10; before them the old ones.
    let xs = x_counts_log(&r, started);
    let jump = r.log[started..]
        .iter()
        .position(|s| s.out.homed_by_drive[0].is_some())
        .expect("reported");
    let s = r.log[started + jump];
    assert_eq!(s.mode, MODE_HOMING, "{what}");
    assert_eq!(
        s.statusword & (sw::HOMING_ATTAINED | sw::HOMING_ERROR | sw::TARGET_REACHED),
        sw::HOMING_ATTAINED | sw::TARGET_REACHED,
        "{what}"
    );
    // At rest at the switch's edge in the old coordinates, the offset in the new ones.
    let old = &xs[..jump];
    let rest = old[old.len() - 1];
    assert!((rest - switch).abs() <= 1.0, "{what}: rests at {rest}");
    // And still there, reading the offset (the motor did not move with the coordinates).
    for c in &xs[jump..jump + 3] {
        assert!((c - offset).abs() <= 1.0, "{what}: reads {c}");
    }
    assert_eq!(s.out.homed_by_drive[0], Some(homed));
    assert!((r.x_counts(homed) - offset).abs() <= 1.0, "{what}: {homed}");

    // The drive's own motion within 0x6099 and 0x609A, from the sampled positions: speed
    // over one period, acceleration over a window of w periods (a count of rounding
    // at each sample).
    let w = 10;
    for k in 1..old.len() {
        let v = (old[k] - old[k - 1]).abs() / T;
        assert!(v <= search * 1.001 + 1.0 / T, "{what}: speed {v} at {k}");
    }
    let wt = w as f64 * T;
    for k in w..old.len().saturating_sub(w) {
        let a = (old[k + w] - 2.0 * old[k] + old[k - w]).abs() / (wt * wt);
        assert!(
            a <= accel * 1.01 + 2.0 / (wt * wt),
            "{what}: acceleration {a} at {k}"
        );
    }
    // The edge approached at the zero speed in the method's direction: the last time the
    // axis moved at about the zero speed (over 20 periods: a count of rounding is
    // 1/20 count per period), it moved that way. (The return to the edge after the
    // latch's stop peaks at 1/√2 of the zero speed.)
    let w = 20;
    let wt = w as f64 * T;
    let slow = (w..old.len())
        .rev()
        .map(|k| (old[k] - old[k - w]) / wt)
        .find(|v| v.abs() >= 0.85 * zero && v.abs() <= zero * 1.01 + 1.0 / wt)
        .expect("a run at the zero speed");
    assert_eq!(slow.signum(), latch_direction(method), "{what}: {slow}");
    // And it went through the switch's active side (beyond the edge in the method's
    // search direction: positive for 19, 20).
    let search_direction = if method <= 20 { 1.0 } else { -1.0 };
    assert!(
        old.iter().any(|&c| (c - switch) * search_direction > 0.0),
        "{what}: never on the switch"
    );

    follows_csp_after(&mut r, homed);
}

#[test]
fn methods_19_to_22_find_switches_on_either_side_of_the_start() {
    // Each method from inactive and from active starts, both directions of counting.
    let mut n = 0;
    for method in 19..=22i8 {
        for (start_mm, switch_mm) in [(-6.0, 4.25), (4.0, -5.5), (1.3, 0.0), (-1.2, 0.1)] {
            let direction = if n % 2 == 0 { 1 } else { -1 };
            n += 1;
            switch_homing(
                method, 1000.0, direction, start_mm, switch_mm, 20.0, 2.0, 500.0, -12.5, 50.0, 1.0,
            );
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn methods_19_to_22_find_the_switch_wherever_it_is(
        method in 19..=22i8,
        fine in any::<bool>(),
        negative in any::<bool>(),
        start_mm in -10.0..10.0f64,
        switch_mm in -10.0..10.0f64,
        // At least a millimetre from the start: a run at the zero speed to see.
        gap_mm in 1.0..4.0f64,
        search_mm_s in 10.0..50.0f64,
        zero_ratio in 0.05..0.3f64,
        // The stop from the search speed, which sets the acceleration: the run at the
        // zero speed after a back-off is then long enough to be seen.
        stop_mm in 0.5..4.0f64,
        offset_mm in -100.0..100.0f64,
        bandwidth_hz in 30.0..120.0f64,
        damping in 0.7..1.5f64,
    ) {
        let switch_mm = if (switch_mm - start_mm).abs() < 1.0 {
            start_mm + gap_mm.copysign(switch_mm - start_mm)
        } else {
            switch_mm
        };
        switch_homing(
            method,
            if fine { 10_000.0 } else { 1000.0 },
            if negative { -1 } else { 1 },
            start_mm,
            switch_mm,
            search_mm_s,
            (zero_ratio * search_mm_s).max(0.5),
            search_mm_s * search_mm_s / (2.0 * stop_mm),
            offset_mm,
            bandwidth_hz,
            damping,
        );
    }
}

#[test]
fn no_switch_within_the_search_limit_is_an_error_and_a_fault_naming_the_axis() {
    for (method, direction) in [(20i8, 1), (21, -1), (19, -1), (22, 1)] {
        let m = machine(1000.0, direction, 500.0);
        let (search, accel, limit) = (20_000.0, 400_000.0, 8_000.0);
        let mut r = rig(
            m,
            SimHomingConfig {
                method,
                search_speed_counts_s: search as u32,
                zero_speed_counts_s: 2_000,
                acceleration_counts_s2: accel as u32,
                home_offset_counts: 0,
                home_switch_counts: None,
                search_limit_counts: limit,
            },
        );
        let p0 = r.enable();
        let started = home_x(&mut r, p0, 20_000);
        assert_eq!(r.stage.drive_homing(0), DriveHoming::Error(0), "{method}");
        let f = *r.stage.fault().expect("a latched fault");
        assert_eq!((f.check, f.axis), (Check::DriveHoming, Some(0)));
        assert!(f.to_string().contains("drive_homing on axis X"), "{f}");
        assert_eq!(Check::DriveHoming.code(), 20);
        let tripped: Vec<_> = r.log.iter().filter_map(|s| s.out.tripped).collect();
        assert_eq!(tripped, [f]);
        // The master saw bit 13 (with bit 10 once at rest).
        let errors: Vec<u16> = r.log[started..]
            .iter()
            .filter(|s| s.mode == MODE_HOMING && s.statusword & sw::HOMING_ERROR != 0)
            .map(|s| s.statusword)
            .collect();
        assert!(!errors.is_empty());
        assert!(errors.iter().any(|w| w & sw::TARGET_REACHED != 0));
        // It travelled the limit, then stopped within its stop; nothing moves after.
        let xs = x_counts_log(&r, started);
        let travel = xs.iter().map(|c| (c - 500.0).abs()).fold(0.0, f64::max);
        let stop = search * search / (2.0 * accel);
        assert!(
            travel >= limit && travel <= limit + stop + 2.0,
            "{method}: travel {travel}"
        );
        assert_eq!(
            r.stage.drive(0).unwrap().mode_of_operation_display(),
            MODE_CYCLIC_SYNC_POSITION
        );
        // Everything comes to rest; the reset is then accepted.
        let held = r.stage.command();
        for _ in 0..500 {
            r.step(Some([held[0], held[1], held[2]]));
        }
        let xs = x_counts_log(&r, r.log.len() - 100);
        assert!(xs.iter().all(|&c| (c - xs[0]).abs() <= 1.0), "{xs:?}");
        assert_eq!(r.stage.safety().state(), SafetyState::Stopped);
        let held = r.stage.command();
        r.stage.request_reset();
        let outcome = (0..100).find_map(|_| r.step(Some([held[0], held[1], held[2]])).reset);
        assert_eq!(outcome, Some(Ok(())), "{method}");
        assert!(r.stage.ready());
    }
}

#[test]
fn an_unsupported_method_is_an_error_at_once_without_motion() {
    for method in [1i8, 17, 34, 36, -1] {
        let m = machine(1000.0, 1, 4321.0);
        let mut r = rig(
            m,
            SimHomingConfig {
                method,
                home_switch_counts: Some(0.0),
                ..SimHomingConfig::default()
            },
        );
        let p0 = r.enable();
        let started = home_x(&mut r, p0, 100);
        assert_eq!(r.stage.drive_homing(0), DriveHoming::Error(0), "{method}");
        assert_eq!(
            r.stage.fault().map(|f| (f.check, f.axis)),
            Some((Check::DriveHoming, Some(0)))
        );
        assert!(x_counts_log(&r, started).iter().all(|&c| c == 4321.0));
        let first = r.log[started..]
            .iter()
            .find(|s| s.mode == MODE_HOMING && s.statusword & sw::HOMING_ERROR != 0)
            .expect("bit 13");
        assert_ne!(first.statusword & sw::TARGET_REACHED, 0, "at rest");
    }
}

#[test]
fn a_fault_elsewhere_interrupts_the_homing_and_the_drive_stops_on_its_own_ramp() {
    let (search, accel) = (30_000.0, 300_000.0);
    let m = machine(1000.0, 1, 0.0);
    let mut r = rig(
        m,
        SimHomingConfig {
            method: homing_method::POSITIVE_SWITCH_RISING,
            search_speed_counts_s: search as u32,
            zero_speed_counts_s: 3_000,
            acceleration_counts_s2: accel as u32,
            home_offset_counts: 0,
            home_switch_counts: Some(200_000.0),
            search_limit_counts: 1e6,
        },
    );
    let p0 = r.enable();
    r.stage.start_drive_homing(0).unwrap();
    let started = r.log.len();
    for _ in 0..300 {
        r.step(Some(p0));
    }
    assert_eq!(r.stage.drive_homing(0), DriveHoming::Running);
    // Cruising at the search speed.
    let xs = x_counts_log(&r, r.log.len() - 3);
    assert!(((xs[2] - xs[1]) / T - search).abs() <= 1.0 / T, "{xs:?}");
    r.stage
        .drive_mut(1)
        .unwrap()
        .set_fault_cause(Some(ERROR_OVERCURRENT));
    let mut at = None;
    for k in 0..1000 {
        let out = r.step(Some(p0));
        if out.tripped.is_some() {
            at = Some(r.log.len() - 1);
        }
        if k > 10 && !r.stage.drive_homing_active(0) {
            break;
        }
    }
    let at = at.expect("the drive fault trips");
    assert_eq!(r.stage.fault().map(|f| f.check), Some(Check::DriveFault));
    assert_eq!(r.stage.drive_homing(0), DriveHoming::Interrupted);
    assert!(!r.stage.drive_homing_active(0));
    // X stopped at the homing acceleration: it travels no more than the stop from the
    // search speed (and a period at speed while the halt reaches the drive).
    let xs = x_counts_log(&r, at);
    let stop = search * search / (2.0 * accel) + search * T + 2.0;
    assert!(xs.last().unwrap() - xs[0] <= stop, "{xs:?}");
    let w = 10;
    let wt = w as f64 * T;
    for k in w..xs.len() - w {
        let a = (xs[k + w] - 2.0 * xs[k] + xs[k - w]).abs() / (wt * wt);
        assert!(a <= accel * 1.01 + 2.0 / (wt * wt), "a {a} at {k}");
    }
    assert_eq!(
        r.stage.drive(0).unwrap().mode_of_operation_display(),
        MODE_CYCLIC_SYNC_POSITION
    );
    // Not attained: the switch was never reached, and the coordinates are the old ones.
    assert!(
        r.log[started..]
            .iter()
            .all(|s| s.out.homed_by_drive[0].is_none())
    );
    assert!(r.x_counts(r.log.last().unwrap().out.actual[0]) < 200_000.0);
}

#[test]
fn a_start_is_refused_with_the_reason() {
    let m = machine(1000.0, 1, 0.0);
    let mut r = rig(m, SimHomingConfig::default());
    assert_eq!(
        r.stage.start_drive_homing(0),
        Err("the drives are not all enabled")
    );
    let p0 = r.enable();
    assert_eq!(
        r.stage.start_drive_homing(4),
        Err("the machine has no drive on that axis")
    );
    assert_eq!(
        r.stage.start_drive_homing(MAX_AXES),
        Err("the machine has no drive on that axis")
    );
    // Moving: the last two commands differ.
    r.step(Some(p0));
    r.step(Some([p0[0] + 0.001, p0[1], p0[2]]));
    assert_eq!(r.stage.start_drive_homing(0), Err("the axis is moving"));
    r.step(Some([p0[0] + 0.001, p0[1], p0[2]]));
    assert_eq!(r.stage.start_drive_homing(0), Ok(()));
    assert_eq!(r.stage.drive_homing(0), DriveHoming::Running);
    assert_eq!(
        r.stage.start_drive_homing(0),
        Err("the axis's drive is homing already")
    );
    // Y may start while X homes.
    assert_eq!(r.stage.start_drive_homing(1), Ok(()));
    let x = [p0[0] + 0.001, p0[1], p0[2]];
    for _ in 0..10 {
        r.step(Some(x));
    }
    assert_eq!(r.stage.drive_homing(0), DriveHoming::Attained);
    assert_eq!(r.stage.drive_homing(1), DriveHoming::Attained);
    assert_eq!(r.stage.drive_homing(2), DriveHoming::Idle);
    // Both reported in the same cycle.
    let both = r
        .log
        .iter()
        .find(|s| s.out.homed_by_drive[0].is_some())
        .unwrap();
    assert_eq!(both.out.homed_by_drive[..3], [Some(0.0), Some(0.0), None]);
    // A latched fault refuses.
    r.stage
        .drive_mut(2)
        .unwrap()
        .inject_fault(ERROR_OVERCURRENT);
    for _ in 0..5 {
        r.step(Some([0.0, 0.0, p0[2]]));
    }
    assert!(r.stage.fault().is_some());
    assert_eq!(
        r.stage.start_drive_homing(0),
        Err("a fault is latched: reset it first")
    );
    assert_eq!(r.stage.phase(), Phase::Active);
}

/// A bare simulated drive: enabled by hand, as a master would.
fn enabled_drive(homing: SimHomingConfig) -> SimDrive {
    let mut d = SimDrive::new(SimConfig::default());
    d.set_homing_config(homing);
    for word in [
        cw::DISABLE_VOLTAGE,
        cw::SHUTDOWN,
        cw::SWITCH_ON_CMD,
        cw::ENABLE_OPERATION_CMD,
    ] {
        d.write(word, 0);
    }
    assert_eq!(d.state(), DriveState::OperationEnabled);
    d
}

#[test]
fn the_drive_leaves_homing_mode_only_at_rest_and_halt_interrupts() {
    let homing = SimHomingConfig {
        method: homing_method::NEGATIVE_SWITCH_RISING,
        search_speed_counts_s: 10_000,
        zero_speed_counts_s: 1_000,
        acceleration_counts_s2: 100_000,
        home_offset_counts: 0,
        home_switch_counts: Some(-50_000.0),
        search_limit_counts: 1e6,
    };
    let mut d = enabled_drive(homing);
    d.set_mode_of_operation(MODE_HOMING);
    assert_eq!(d.mode_of_operation_display(), MODE_HOMING);
    // Before a start: bit 10 (not started), no 12 or 13.
    d.write(cw::ENABLE_OPERATION_CMD, 0);
    assert_eq!(
        d.statusword() & (sw::TARGET_REACHED | sw::HOMING_ATTAINED | sw::HOMING_ERROR),
        sw::TARGET_REACHED
    );
    let start = cw::ENABLE_OPERATION_CMD | cw::HOMING_START;
    for _ in 0..200 {
        d.write(start, 0);
    }
    assert_eq!(d.statusword() & sw::TARGET_REACHED, 0, "in progress");
    let p = d.position_actual_counts();
    assert!(p < -100, "moving toward the negative switch: {p}");
    // Asked for mode 8 while moving: it stays in 6 and keeps homing.
    d.set_mode_of_operation(MODE_CYCLIC_SYNC_POSITION);
    d.write(start, 0);
    assert_eq!(d.mode_of_operation_display(), MODE_HOMING);
    assert!(d.position_actual_counts() < p);
    // Halt: it stops at the homing acceleration (10 000²/(2·100 000) = 500 counts), then
    // shows bit 10 (interrupted, at rest) and takes mode 8.
    let at = d.position_actual_counts();
    let mut n = 0;
    while d.mode_of_operation_display() == MODE_HOMING {
        d.write(start | cw::HALT, at);
        n += 1;
        assert!(n < 1000, "never at rest");
    }
    let stopped = d.position_actual_counts();
    assert!(
        (at - stopped) <= 500 + 10 + 2,
        "stopped {} counts on",
        at - stopped
    );
    // In csp from there: it follows targets.
    for k in 1..=100 {
        d.write(cw::ENABLE_OPERATION_CMD, stopped + 10 * k);
    }
    for _ in 0..100 {
        d.write(cw::ENABLE_OPERATION_CMD, stopped + 1000);
    }
    assert!((d.position_actual_counts() - (stopped + 1000)).abs() <= 1);
    assert_ne!(d.statusword() & sw::DRIVE_FOLLOWS_TARGET, 0);
}

#[test]
fn a_cycle_never_allocates_through_whole_drive_homings() {
    let m = machine(1000.0, -1, 3000.0);
    let mut r = rig(
        m,
        SimHomingConfig {
            method: homing_method::POSITIVE_SWITCH_RISING,
            search_speed_counts_s: 40_000,
            zero_speed_counts_s: 4_000,
            acceleration_counts_s2: 800_000,
            home_offset_counts: -1_000,
            home_switch_counts: Some(9_000.0),
            search_limit_counts: 30_000.0,
        },
    );
    let p0 = r.enable();
    let probe = Count::start();
    let v = std::hint::black_box(vec![1u8; 8]);
    assert!(probe.stop() >= 1, "the counter counts");
    drop(v);
    let mut stage = r.stage;
    let mut attained = 0;
    let mut errors = 0;
    let mut restarted = Err("no reset");
    let mut resetting = false;
    let count = Count::start();
    // An attained homing, then (the switch gone) a failed one, its fault and reset,
    // then homing again with method 37.
    let mut sp = [p0[0], p0[1], p0[2], 0.0, 0.0, 0.0];
    let started = stage.start_drive_homing(0).is_ok();
    for k in 0..20_000u32 {
        let out = stage.cycle(&StageInput {
            setpoint: Some(sp),
            line: k,
            time_s: f64::from(k) * T,
        });
        if let Some(p) = out.homed_by_drive[0] {
            sp[0] = p;
            attained += 1;
            if attained == 1
                && let Some(d) = stage.drive_mut(0)
            {
                d.set_homing_config(SimHomingConfig {
                    method: homing_method::POSITIVE_SWITCH_RISING,
                    home_switch_counts: None,
                    search_limit_counts: 5_000.0,
                    ..*d.homing_config()
                });
                let _ = stage.start_drive_homing(0);
            }
        }
        if out.tripped.is_some() {
            errors += 1;
        }
        if out.reset.is_some() {
            resetting = false;
        }
        if stage.fault().is_some() && !stage.drive_homing_active(0) && !resetting {
            sp = stage.command();
            stage.request_reset();
            resetting = true;
        }
        if let Some(Ok(())) = out.reset
            && let Some(d) = stage.drive_mut(0)
        {
            d.set_homing_config(SimHomingConfig {
                method: homing_method::CURRENT_POSITION,
                ..*d.homing_config()
            });
            sp = stage.command();
            restarted = stage.start_drive_homing(0);
        }
    }
    let allocations = count.stop();
    assert!(started);
    assert_eq!(restarted, Ok(()));
    assert_eq!(allocations, 0, "allocations in the cycle");
    assert_eq!((attained, errors), (2, 1));
    assert_eq!(stage.drive_homing(0), DriveHoming::Attained);
}

#[test]
fn the_homing_status_is_decoded_from_bits_13_12_and_10_as_cia_402_tabulates_them() {
    use kerf_drive::cia402::HomingStatus::{self, *};
    // (statusword, status): Operation enabled 0x0237 with bits 13, 12, 10 as the table.
    for (word, status) in [
        (0x0237u16, InProgress),
        (0x0637, Idle),
        (0x1237, AttainedMoving),
        (0x1637, Completed),
        (0x2237, ErrorMoving),
        (0x2637, ErrorAtRest),
        (0x3237, Reserved),
        (0x3637, Reserved),
    ] {
        assert_eq!(HomingStatus::from_statusword(word), status, "{word:#06x}");
        assert_eq!(
            HomingStatus::from_statusword(0x0237 | status.statusword_bits()),
            status
        );
    }
    assert_eq!(
        (cw::HOMING_START, sw::HOMING_ATTAINED, sw::HOMING_ERROR),
        (0x0010, 0x1000, 0x2000)
    );
    assert_eq!((MODE_HOMING, MODE_CYCLIC_SYNC_POSITION), (6, 8));
    use kerf_drive::cia402::*;
    assert_eq!(
        (
            HOMING_METHOD_INDEX,
            HOMING_SPEEDS_INDEX,
            HOMING_SPEED_SWITCH_SUBINDEX,
            HOMING_SPEED_ZERO_SUBINDEX,
            HOMING_ACCELERATION_INDEX,
            HOME_OFFSET_INDEX
        ),
        (0x6098, 0x6099, 1, 2, 0x609A, 0x607C)
    );
}
