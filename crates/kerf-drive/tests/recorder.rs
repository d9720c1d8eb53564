//! The black-box recorder: its size from seconds and period, the last N cycles kept in
//! order after wrap-around, a CSV that round-trips the values, and `record()` (with the
//! safety check beside it) allocation-free under a counting global allocator.

use kerf_drive::MAX_AXES;
use kerf_drive::recorder::{CycleRecord, DEFAULT_SECONDS, Recorder};
use kerf_drive::safety::{AxisSafety, CycleInput, Safety, SafetyConfig, SafetyState};
use kerf_geom::AxisLimits;

use kerf_testkit::alloc::{Count, CountingAllocator};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

const XYZ: [bool; MAX_AXES] = [true, true, true, false, false, false];

/// A record whose every field depends on `k` (positions with fractions that do not
/// round-trip through a short decimal form).
fn rec(k: u64) -> CycleRecord {
    let x = k as f64;
    CycleRecord {
        sequence: k,
        time_s: x * 0.001,
        commanded: [x / 3.0, -x / 7.0, x.sqrt(), 1.0 / (x + 1.0), 0.0, 0.0],
        actual: [
            x / 3.0 - 1e-5,
            -x / 7.0 + 2e-6,
            x.sqrt() * 0.999,
            0.5,
            0.0,
            0.0,
        ],
        following_error: [1e-5, -2e-6, x.sqrt() * 0.001, 0.0, 0.0, 0.0],
        controlword: [0x000f, 0x0002, k as u16, 0, 0, 0],
        statusword: [0x1237, 0x0217, 0x0008, 0, 0, 0],
        state: [
            SafetyState::Running,
            SafetyState::Holding,
            SafetyState::QuickStop,
            SafetyState::Stopped,
        ][(k % 4) as usize],
    }
}

#[test]
fn capacity_is_seconds_over_period() {
    // 10 s at 1 ms: 10 000 cycles; 2 s at 250 µs: 8000.
    let r = Recorder::new(DEFAULT_SECONDS, 0.001, XYZ).expect("size");
    assert_eq!(r.capacity(), 10_000);
    assert!(r.is_empty());
    assert_eq!(
        Recorder::new(2.0, 0.000_25, XYZ).expect("size").capacity(),
        8000
    );
    assert!(Recorder::new(0.0, 0.001, XYZ).is_err());
    assert!(Recorder::new(1.0, 0.0, XYZ).is_err());
    assert!(Recorder::new(f64::NAN, 0.001, XYZ).is_err());
}

#[test]
fn keeps_exactly_the_last_n_cycles_in_order_after_wrap_around() {
    let mut r = Recorder::with_capacity(5, XYZ);
    for k in 0..3 {
        r.record(&rec(k));
    }
    let seq: Vec<u64> = r.iter().map(|c| c.sequence).collect();
    assert_eq!(seq, [0, 1, 2]);
    for k in 3..12 {
        r.record(&rec(k));
    }
    assert_eq!(r.len(), 5);
    let kept: Vec<CycleRecord> = r.iter().copied().collect();
    let expected: Vec<CycleRecord> = (7..12).map(rec).collect();
    assert_eq!(kept, expected);
    r.clear();
    assert!(r.is_empty() && r.iter().next().is_none());
}

fn parse_word(s: &str) -> u16 {
    u16::from_str_radix(s.strip_prefix("0x").expect("0x prefix"), 16).expect("hex word")
}

#[test]
fn csv_names_its_columns_with_units_and_round_trips_the_values() {
    let mut r = Recorder::with_capacity(4, XYZ);
    for k in 0..9 {
        r.record(&rec(k));
    }
    let mut out = Vec::new();
    r.dump(&mut out).expect("dump");
    let text = String::from_utf8(out).expect("utf-8");
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some(
            "sequence,time_s,state,\
             x_cmd_mm,x_act_mm,x_ferror_mm,x_controlword,x_statusword,\
             y_cmd_mm,y_act_mm,y_ferror_mm,y_controlword,y_statusword,\
             z_cmd_mm,z_act_mm,z_ferror_mm,z_controlword,z_statusword"
        )
    );
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), 4);
    for (row, k) in rows.iter().zip(5..9) {
        let f: Vec<&str> = row.split(',').collect();
        assert_eq!(f.len(), 3 + 3 * 5);
        let want = rec(k);
        assert_eq!(f[0].parse::<u64>().expect("sequence"), want.sequence);
        assert_eq!(f[1].parse::<f64>().expect("time"), want.time_s);
        assert_eq!(f[2], want.state.name());
        for ax in 0..3 {
            let c = &f[3 + 5 * ax..8 + 5 * ax];
            assert_eq!(c[0].parse::<f64>().expect("cmd"), want.commanded[ax]);
            assert_eq!(c[1].parse::<f64>().expect("act"), want.actual[ax]);
            assert_eq!(
                c[2].parse::<f64>().expect("ferror"),
                want.following_error[ax]
            );
            assert_eq!(parse_word(c[3]), want.controlword[ax]);
            assert_eq!(parse_word(c[4]), want.statusword[ax]);
        }
    }
}

#[test]
fn rotary_axes_are_in_degrees() {
    let r = Recorder::with_capacity(1, [true, false, false, false, false, true]);
    assert_eq!(
        r.header(),
        "sequence,time_s,state,x_cmd_mm,x_act_mm,x_ferror_mm,x_controlword,x_statusword,\
         c_cmd_deg,c_act_deg,c_ferror_deg,c_controlword,c_statusword"
    );
}

#[test]
fn the_cycle_with_safety_and_recorder_does_not_allocate() {
    let ax = AxisSafety {
        limits: AxisLimits {
            velocity_units_s: 100.0,
            acceleration_units_s2: 1000.0,
            jerk_units_s3: 50_000.0,
        },
        min_limit_units: -500.0,
        max_limit_units: 500.0,
        ferror_units: 1.0,
        min_ferror_units: 0.1,
    };
    let cfg = SafetyConfig::new([Some(ax), Some(ax), Some(ax), None, None, None], 0.001);
    let mut safety = Safety::new(cfg, [0.0; MAX_AXES]).expect("config");
    let mut rec = Recorder::new(0.5, 0.001, XYZ).expect("size");
    let mut fault = [false; MAX_AXES];
    // The counter does count this thread's allocations.
    let count = Count::start();
    let probe = std::hint::black_box(vec![1u8; 16]);
    let probed = count.stop();
    drop(probe);
    assert!(probed >= 1);
    let count = Count::start();
    // Ramp, cruise, missed cycles, a drive fault, the quick stop, a refused and an
    // accepted reset, wrapping the ring twice.
    let mut x = 0.0f64;
    let mut base = [0.0; MAX_AXES];
    let mut ramp_from = 0u64;
    let mut resets = 0;
    for k in 0u64..1500 {
        let v_mm_s = ((k - ramp_from) as f64 * 0.5).min(50.0);
        fault[1] = (900..1000).contains(&k);
        // Two missed cycles (the motion core stalls with the stream, so it resumes
        // where it stopped).
        let setpoint = if (300..302).contains(&k) {
            None
        } else {
            x += v_mm_s * 0.001;
            let d = [x, 0.5 * x, -x, 0.0, 0.0, 0.0];
            Some(std::array::from_fn(|i| base[i] + d[i]))
        };
        let actual = safety.command();
        let verdict = safety.check(&CycleInput {
            setpoint,
            actual,
            drive_fault: fault,
            line: 10,
        });
        if k == 899 {
            assert!(safety.fault().is_none(), "no trip before the drive fault");
        }
        if (k == 950 || k == 1100) && safety.reset().is_ok() {
            // The motion core restarts from where the machine stopped, at rest.
            resets += 1;
            base = safety.command();
            x = 0.0;
            ramp_from = k + 1;
        }
        rec.record(&CycleRecord {
            sequence: k,
            time_s: k as f64 * 0.001,
            commanded: verdict.command,
            actual,
            following_error: std::array::from_fn(|i| verdict.command[i] - actual[i]),
            controlword: [0x000f; MAX_AXES],
            statusword: [0x1237; MAX_AXES],
            state: verdict.state,
        });
    }
    let in_cycle = count.stop();
    assert_eq!(in_cycle, 0, "allocations in the cycle");
    // The run did go through a fault and a reset (the counter was armed over them).
    assert!(
        rec.iter()
            .any(|r| r.state == SafetyState::Stopped || r.state == SafetyState::QuickStop)
    );
    assert_eq!(rec.len(), 500);
    // ... and the reset at cycle 1100 was accepted: the end runs again.
    assert_eq!(
        rec.iter().last().map(|r| r.state),
        Some(SafetyState::Running),
        "{:?}",
        safety.fault()
    );
    assert!(safety.fault().is_none());
    assert_eq!(resets, 1, "refused while stopping at 950, accepted at 1100");
}
