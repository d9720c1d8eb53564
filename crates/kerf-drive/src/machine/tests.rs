//! The machine model's tests. Expected times and speeds are worked out by hand from the
//! configuration (1 ms period unless said otherwise).

use kerf_geom::machine::{Action, ActionKind, Gate, MachineIo, PauseCode, SpindleDir, WaitMode};
use proptest::prelude::*;

use super::*;

// Counts allocations of the threads that arm it (`no_allocation_in_cycle_or_act`); the
// other tests of this binary are not counted.
#[global_allocator]
static ALLOCATOR: kerf_testkit::alloc::CountingAllocator = kerf_testkit::alloc::CountingAllocator;

const PERIOD_S: f64 = 0.001;

fn sim_spindle() -> SpindleConfig {
    SpindleConfig {
        kind: SpindleKind::Drive { simulated: true },
        max_rpm: 24000.0,
        min_rpm: 0.0,
        acceleration_rpm_s: 8000.0,
        at_speed_tolerance: 0.02,
        at_speed_timeout_s: 10.0,
        fault_out_of_band: true,
        orient_timeout_s: 5.0,
        off: OffPolicy::default(),
    }
}

/// 8 digital outputs and inputs, 4 analog outputs and inputs, simulated.
fn io() -> IoConfig {
    IoConfig::counts(8, 8, 4, 4)
}

fn config_with(spindle: Option<SpindleConfig>) -> MachineConfig {
    MachineConfig {
        spindle,
        io: io(),
        ..MachineConfig::new(PERIOD_S)
    }
}

fn machine(config: MachineConfig) -> Machine {
    Machine::new(config).unwrap()
}

fn action(kind: ActionKind) -> Action {
    Action { line: 7, kind }
}

fn act(m: &mut Machine, kind: ActionKind) -> Gate {
    m.act(&action(kind))
}

fn spindle(dir: SpindleDir, rpm: f64) -> ActionKind {
    ActionKind::Spindle { dir, rpm }
}

/// Acts `kind` as the interpolator does: now (k = 0), then once per cycle after
/// `cycle(feeding)`, with `each(k, m)` before the act of cycle k. The k of the act that
/// was done, or `None` within `max` cycles.
fn run(
    m: &mut Machine,
    kind: ActionKind,
    max: u64,
    feeding: bool,
    mut each: impl FnMut(u64, &mut Machine),
) -> Option<u64> {
    let a = action(kind);
    for k in 0..=max {
        if k > 0 {
            m.cycle(feeding);
        }
        each(k, m);
        if m.act(&a) == Gate::Done {
            return Some(k);
        }
    }
    None
}

fn status_spindle(m: &Machine) -> SpindleStatus {
    m.status().spindle.unwrap()
}

fn actual(m: &Machine) -> f64 {
    status_spindle(m).actual_rpm.unwrap()
}

/// Runs cycles until the simulated spindle is at speed; the cycles it took.
fn spin_up(m: &mut Machine, rpm: f64) -> u64 {
    assert_eq!(act(m, spindle(SpindleDir::Cw, rpm)), Gate::Done);
    run(m, ActionKind::WaitAtSpeed, 100_000, false, |_, _| {}).unwrap()
}

// --- the spindle ---

#[test]
fn sim_spindle_ramps_to_speed_in_the_hand_computed_time() {
    // 0 → 12000 rpm at 8000 rpm/s: 1.5 s = 1500 cycles (8 rpm per cycle). Within 2 %
    // (±240 rpm) from 11760 rpm: 11760 / 8 = 1470 cycles (on the band's edge: ±1).
    let mut m = machine(config_with(Some(sim_spindle())));
    assert_eq!(act(&mut m, spindle(SpindleDir::Cw, 12000.0)), Gate::Done);
    assert!(!status_spindle(&m).at_speed);
    let k = run(&mut m, ActionKind::WaitAtSpeed, 5000, false, |_, _| {}).unwrap();
    assert!((1469..=1471).contains(&k), "at speed after {k} cycles");
    assert!(status_spindle(&m).at_speed);
    let mut full = None;
    for c in k + 1..3000 {
        m.cycle(false);
        if actual(&m) == 12000.0 && full.is_none() {
            full = Some(c);
        }
    }
    let full = full.unwrap();
    assert!(
        (1499..=1501).contains(&full),
        "full speed after {full} cycles"
    );
    let s = status_spindle(&m);
    assert_eq!(s.dir, SpindleDir::Cw);
    assert_eq!(s.commanded_rpm, 12000.0);
    assert_eq!(m.spindle_velocity_setpoint_rpm(), 12000.0);
}

#[test]
fn at_speed_band_off_the_edge() {
    // ±1.5 %: from 11820 rpm, 11820 / 8 = 1477.5: the first cycle at speed is 1478.
    let mut m = machine(config_with(Some(SpindleConfig {
        at_speed_tolerance: 0.015,
        ..sim_spindle()
    })));
    assert_eq!(spin_up(&mut m, 12000.0), 1478);
    assert_eq!(actual(&m), 11824.0);
}

#[test]
fn reversal_passes_through_zero() {
    // +12000 → −6000 rpm: 18000 / 8 = 2250 cycles; through 0 after 1500; within 2 % of
    // 6000 (120 rpm) from −5880: (12000 + 5880) / 8 = 2235 cycles.
    let mut m = machine(config_with(Some(sim_spindle())));
    for _ in 0..2000 {
        m.cycle(false);
    }
    spin_up(&mut m, 12000.0);
    for _ in 0..100 {
        m.cycle(false);
    }
    assert_eq!(actual(&m), 12000.0);
    assert_eq!(act(&mut m, spindle(SpindleDir::Ccw, 6000.0)), Gate::Done);
    let mut previous = actual(&m);
    let mut at_speed = None;
    for c in 1..=3000u64 {
        m.cycle(false);
        let now = actual(&m);
        assert!(now <= previous, "the speed falls monotonically");
        previous = now;
        if c == 1500 {
            assert_eq!(now, 0.0);
        }
        if at_speed.is_none() && status_spindle(&m).at_speed {
            at_speed = Some(c);
        }
    }
    assert_eq!(at_speed, Some(2235));
    assert_eq!(actual(&m), -6000.0);
}

#[test]
fn override_applies_while_enabled_and_clamps() {
    let mut m = machine(config_with(Some(SpindleConfig {
        max_rpm: 20000.0,
        min_rpm: 500.0,
        ..sim_spindle()
    })));
    act(&mut m, spindle(SpindleDir::Cw, 12000.0));
    m.set_spindle_override_pct(50.0);
    assert_eq!(status_spindle(&m).commanded_rpm, 6000.0);
    assert_eq!(status_spindle(&m).override_pct, 50.0);
    // M51 P0: the programmed speed.
    let off = ActionKind::Overrides {
        feed: None,
        spindle: Some(false),
    };
    act(&mut m, off);
    assert_eq!(status_spindle(&m).commanded_rpm, 12000.0);
    assert!(!status_spindle(&m).override_enabled);
    assert!(m.feed_override_enabled());
    // M48: back to 50 %; 250 % is clamped to 200 %, 24000 rpm to max 20000.
    act(
        &mut m,
        ActionKind::Overrides {
            feed: Some(true),
            spindle: Some(true),
        },
    );
    assert_eq!(status_spindle(&m).commanded_rpm, 6000.0);
    m.set_spindle_override_pct(250.0);
    assert_eq!(status_spindle(&m).override_pct, 200.0);
    assert_eq!(status_spindle(&m).commanded_rpm, 20000.0);
    // 1 % of 12000 = 120 rpm, raised to min 500; 0 % stops it.
    m.set_spindle_override_pct(1.0);
    assert_eq!(status_spindle(&m).commanded_rpm, 500.0);
    m.set_spindle_override_pct(0.0);
    assert_eq!(status_spindle(&m).commanded_rpm, 0.0);
    // Nothing to wait for at 0 rpm.
    assert_eq!(act(&mut m, ActionKind::WaitAtSpeed), Gate::Done);
    // The feed override enable is kept for the cycle.
    act(
        &mut m,
        ActionKind::Overrides {
            feed: Some(false),
            spindle: None,
        },
    );
    assert!(!m.status().feed_override_enabled);
}

#[test]
fn at_speed_timeout_faults_and_stops_the_spindle() {
    // 1000 rpm/s toward 12000 rpm: within 2 % only after 11.76 s; the 10 s timeout
    // comes first, at 10000 rpm.
    let mut m = machine(config_with(Some(SpindleConfig {
        acceleration_rpm_s: 1000.0,
        ..sim_spindle()
    })));
    act(&mut m, spindle(SpindleDir::Cw, 12000.0));
    let mut shown = false;
    let done = run(&mut m, ActionKind::WaitAtSpeed, 10_000, false, |k, m| {
        if k == 5000 {
            shown = m.pause().map(|p| p.reason) == Some(PauseReason::AtSpeed);
        }
    });
    assert!(shown, "the wait shows in the status");
    assert_eq!(done, None);
    let fault = m.fault().unwrap();
    assert_eq!(
        fault,
        MachineFault::SpindleNotAtSpeed {
            line: 7,
            commanded_rpm: 12000.0,
            actual_rpm: Some(10000.0),
            waited_s: 10.0,
        }
    );
    assert_eq!(
        fault.to_string(),
        "spindle not at speed after 10.0 s: commanded 12000 rpm, actual 10000 rpm (feed move at line 7)"
    );
    assert_eq!(fault.name(), "spindle_not_at_speed");
    // Spindle off, the wait forgotten, every action waits until the reset.
    assert_eq!(status_spindle(&m).dir, SpindleDir::Off);
    assert_eq!(m.pause(), None);
    let coolant = ActionKind::Coolant {
        mist: true,
        flood: false,
    };
    assert_eq!(act(&mut m, coolant), Gate::Wait);
    assert!(!m.status().coolant.mist);
    m.reset();
    assert_eq!(m.fault(), None);
    assert_eq!(act(&mut m, coolant), Gate::Done);
    assert!(m.status().coolant.mist);
}

#[test]
fn out_of_band_faults_only_while_feeding() {
    // ±2.5 % of 12000 = 300 rpm; stalled, the speed falls 8 rpm per cycle: 296 off after
    // 37 cycles (in band), 304 after 38 (out).
    let config = config_with(Some(SpindleConfig {
        at_speed_tolerance: 0.025,
        ..sim_spindle()
    }));
    let mut m = machine(config);
    spin_up(&mut m, 12000.0);
    for _ in 0..100 {
        m.cycle(true);
    }
    assert_eq!(m.fault(), None);
    m.inject_spindle_stall(true);
    for c in 1..=38 {
        m.cycle(true);
        assert_eq!(m.fault().is_some(), c == 38, "cycle {c}");
    }
    let fault = m.fault().unwrap();
    assert_eq!(
        fault,
        MachineFault::SpindleOutOfBand {
            commanded_rpm: 12000.0,
            actual_rpm: Some(11696.0),
            tolerance: 0.025,
        }
    );
    assert_eq!(
        fault.to_string(),
        "spindle left its speed band (±2.5 %) while feeding: commanded 12000 rpm, actual 11696 rpm"
    );

    // Not feeding: the stall goes unnoticed until the motion feeds.
    let mut m = machine(config);
    spin_up(&mut m, 12000.0);
    m.inject_spindle_stall(true);
    for _ in 0..3000 {
        m.cycle(false);
    }
    assert_eq!(actual(&m), 0.0);
    assert_eq!(m.fault(), None);
    m.cycle(true);
    assert!(matches!(
        m.fault(),
        Some(MachineFault::SpindleOutOfBand {
            actual_rpm: Some(0.0),
            ..
        })
    ));
    // The fault switched it off.
    assert_eq!(status_spindle(&m).commanded_rpm, 0.0);

    // Without fault_out_of_band: never.
    let mut m = machine(config_with(Some(SpindleConfig {
        fault_out_of_band: false,
        ..sim_spindle()
    })));
    spin_up(&mut m, 12000.0);
    m.inject_spindle_stall(true);
    for _ in 0..3000 {
        m.cycle(true);
    }
    assert_eq!(m.fault(), None);
}

#[test]
fn a_speed_change_while_feeding_is_no_fault() {
    let mut m = machine(config_with(Some(sim_spindle())));
    spin_up(&mut m, 12000.0);
    m.set_spindle_override_pct(50.0);
    for _ in 0..2000 {
        m.cycle(true);
    }
    assert_eq!(m.fault(), None);
    assert_eq!(actual(&m), 6000.0);
    // At speed again at 6000 rpm: out of band is a fault once more.
    m.inject_spindle_stall(true);
    for _ in 0..100 {
        m.cycle(true);
    }
    assert!(m.fault().is_some());
}

#[test]
fn fieldbus_spindle_drive_gets_the_ramp_and_reports_its_speed() {
    let mut m = machine(config_with(Some(SpindleConfig {
        kind: SpindleKind::Drive { simulated: false },
        ..sim_spindle()
    })));
    act(&mut m, spindle(SpindleDir::Ccw, 1000.0));
    for _ in 0..10 {
        m.cycle(false);
    }
    assert_eq!(m.spindle_velocity_setpoint_rpm(), -80.0);
    assert_eq!(actual(&m), 0.0, "no speed reported yet");
    m.set_spindle_actual_rpm(-985.0);
    assert!(status_spindle(&m).at_speed, "within 2 % of 1000");
    assert_eq!(actual(&m), -985.0);
}

fn outputs_spindle(at_speed_input: Option<u8>) -> SpindleConfig {
    SpindleConfig {
        kind: SpindleKind::Outputs(SpindleOutputs {
            enable_output: 0,
            reverse_output: Some(1),
            speed_output: Some(0),
            speed_units_per_rpm: 10.0 / 24000.0,
            at_speed_input,
            spin_up_s: 1.5,
        }),
        ..sim_spindle()
    }
}

#[test]
fn outputs_spindle_switches_its_outputs() {
    let mut m = machine(config_with(Some(outputs_spindle(None))));
    act(&mut m, spindle(SpindleDir::Ccw, 12000.0));
    let io = m.io();
    assert!(io.digital_output(0) && io.digital_output(1));
    assert_eq!(io.analog_output(0), 5.0);
    assert_eq!(status_spindle(&m).actual_rpm, None);
    // No at-speed input: at speed spin_up_s = 1.5 s after the change.
    assert_eq!(
        run(&mut m, ActionKind::WaitAtSpeed, 5000, false, |_, _| {}),
        Some(1500)
    );
    act(&mut m, spindle(SpindleDir::Cw, 12000.0));
    assert!(m.io().digital_output(0) && !m.io().digital_output(1));
    act(&mut m, spindle(SpindleDir::Off, 12000.0));
    assert!(!m.io().digital_output(0));
    assert_eq!(m.io().analog_output(0), 0.0);
}

#[test]
fn outputs_spindle_at_speed_input() {
    // Simulated: the at-speed input comes on spin_up_s after the change; a stall drops
    // it, which is a fault while feeding.
    let mut m = machine(config_with(Some(outputs_spindle(Some(3)))));
    assert_eq!(spin_up(&mut m, 12000.0), 1500);
    assert!(m.io().digital_input(3));
    assert!(matches!(
        m.set_input_digital(3, false),
        Err(InputError::Simulated { input: 3, .. })
    ));
    m.inject_spindle_stall(true);
    m.cycle(true);
    let fault = m.fault().unwrap();
    assert_eq!(fault.to_string(), {
        "spindle left its speed band (±2.0 %) while feeding: commanded 12000 rpm, no at-speed signal"
    });

    // From the fieldbus: believed from the second cycle after the change.
    let mut m = machine(MachineConfig {
        io: IoConfig {
            simulated_inputs: false,
            ..io()
        },
        ..config_with(Some(outputs_spindle(Some(3))))
    });
    act(&mut m, spindle(SpindleDir::Cw, 12000.0));
    m.set_bus_inputs(1 << 3, &[0.0; ANALOG_IO]);
    let k = run(&mut m, ActionKind::WaitAtSpeed, 100, false, |_, _| {});
    assert_eq!(k, Some(2));
}

#[test]
fn orient_stops_then_settles() {
    // From 12000 rpm: at rest after 1500 cycles, oriented 0.2 s (200 cycles) later.
    let mut m = machine(config_with(Some(sim_spindle())));
    spin_up(&mut m, 12000.0);
    for _ in 0..100 {
        m.cycle(false);
    }
    let orient = ActionKind::Orient {
        angle_deg: 90.0,
        mode: 0,
        timeout_s: f64::INFINITY,
    };
    let mut reason = None;
    let k = run(&mut m, orient, 10_000, false, |k, m| {
        if k == 10 {
            reason = m.pause().map(|p| p.reason);
        }
    });
    assert_eq!(k, Some(1700));
    assert_eq!(reason, Some(PauseReason::Orient));
    let s = status_spindle(&m);
    assert!(s.oriented);
    assert_eq!(s.dir, SpindleDir::Off);
    // The next spindle command clears it.
    act(&mut m, spindle(SpindleDir::Cw, 1000.0));
    assert!(!status_spindle(&m).oriented);
}

#[test]
fn orient_timeout_faults() {
    let mut m = machine(config_with(Some(sim_spindle())));
    spin_up(&mut m, 12000.0);
    let orient = ActionKind::Orient {
        angle_deg: 0.0,
        mode: 0,
        timeout_s: 1.0,
    };
    assert_eq!(run(&mut m, orient, 1000, false, |_, _| {}), None);
    let fault = m.fault().unwrap();
    assert_eq!(
        fault,
        MachineFault::OrientTimeout {
            line: 7,
            timeout_s: 1.0
        }
    );
    assert_eq!(
        fault.to_string(),
        "spindle orient (M19) not done within 1.0 s (line 7)"
    );
    // Without Q the configured 5 s bound it.
    let mut m = machine(config_with(Some(SpindleConfig {
        acceleration_rpm_s: 100.0,
        ..sim_spindle()
    })));
    act(&mut m, spindle(SpindleDir::Cw, 12000.0));
    for _ in 0..100_000 {
        m.cycle(false);
    }
    let orient = ActionKind::Orient {
        angle_deg: 0.0,
        mode: 0,
        timeout_s: f64::INFINITY,
    };
    assert_eq!(run(&mut m, orient, 5000, false, |_, _| {}), None);
    assert!(matches!(
        m.fault(),
        Some(MachineFault::OrientTimeout { timeout_s, .. }) if timeout_s == 5.0
    ));
}

// --- coolant and outputs ---

#[test]
fn coolant_and_outputs_set_the_image() {
    let mut m = machine(MachineConfig {
        coolant: CoolantConfig {
            mist: Some(CoolantOutput {
                output: 4,
                off: OffPolicy::default(),
            }),
            flood: Some(CoolantOutput {
                output: 5,
                off: OffPolicy::default(),
            }),
        },
        ..config_with(None)
    });
    act(
        &mut m,
        ActionKind::Coolant {
            mist: true,
            flood: true,
        },
    );
    assert_eq!(m.io().digital_outputs, 0b11_0000);
    act(
        &mut m,
        ActionKind::Coolant {
            mist: false,
            flood: true,
        },
    );
    assert_eq!(m.io().digital_outputs, 0b10_0000);
    assert_eq!(
        m.status().coolant,
        CoolantStatus {
            mist: false,
            flood: true
        }
    );
    let digital = |output, on| ActionKind::Digital {
        output,
        on,
        sync: kerf_geom::machine::Sync::WithMotion,
    };
    assert_eq!(act(&mut m, digital(2, true)), Gate::Done);
    assert!(m.io().digital_output(2));
    // Output 60 does not exist: ignored.
    assert_eq!(act(&mut m, digital(60, true)), Gate::Done);
    assert!(!m.io().digital_output(60));
    act(&mut m, digital(2, false));
    assert!(!m.io().digital_output(2));
    let analog = |output, value| ActionKind::Analog {
        output,
        value,
        sync: kerf_geom::machine::Sync::Immediate,
    };
    act(&mut m, analog(3, 1.5));
    assert_eq!(m.io().analog_output(3), 1.5);
    act(&mut m, analog(9, 2.0));
    assert_eq!(m.io().analog_outputs[9], 0.0);
}

// --- waits on an input (M66) ---

fn wait_input(mode: WaitMode, timeout_s: f64) -> ActionKind {
    ActionKind::WaitInput {
        input: 2,
        analog: false,
        mode,
        timeout_s,
    }
}

fn last_value(m: &Machine) -> f64 {
    m.status().last_input.unwrap().value
}

/// Runs an M66 on digital input 2 (Q 1 s) with the input at `initial`, switched at each
/// of the cycles in `switch_at`; the cycle the wait ended, and its result.
fn m66(mode: WaitMode, initial: bool, switch_at: &[u64]) -> (Option<u64>, f64) {
    let mut m = machine(config_with(None));
    m.set_input_digital(2, initial).unwrap();
    let mut on = initial;
    let k = run(&mut m, wait_input(mode, 1.0), 2000, false, |k, m| {
        if switch_at.contains(&k) {
            on = !on;
            m.set_input_digital(2, on).unwrap();
        }
    });
    (k, last_value(&m))
}

#[test]
fn m66_immediate_reads_at_once() {
    let mut m = machine(config_with(None));
    m.set_input_digital(2, true).unwrap();
    assert_eq!(
        act(&mut m, wait_input(WaitMode::Immediate, 0.0)),
        Gate::Done
    );
    assert_eq!(
        m.status().last_input,
        Some(InputResult {
            line: 7,
            value: 1.0,
            seq: 1
        })
    );
    m.set_input_digital(2, false).unwrap();
    act(&mut m, wait_input(WaitMode::Immediate, 0.0));
    assert_eq!(m.status().last_input.unwrap().seq, 2);
    assert_eq!(last_value(&m), 0.0);
    // An analog input (any mode reads at once).
    m.set_input_analog(1, 3.25).unwrap();
    let analog = ActionKind::WaitInput {
        input: 1,
        analog: true,
        mode: WaitMode::High,
        timeout_s: 5.0,
    };
    assert_eq!(act(&mut m, analog), Gate::Done);
    assert_eq!(last_value(&m), 3.25);
    assert_eq!(m.status().last_input.unwrap().seq, 3);
}

#[test]
fn m66_rise_needs_off_then_on() {
    // On at the start: off at 100, on again at 200.
    assert_eq!(m66(WaitMode::Rise, true, &[100, 200]), (Some(200), 1.0));
    // Off at the start: on at 50.
    assert_eq!(m66(WaitMode::Rise, false, &[50]), (Some(50), 1.0));
    // Stays on: the 1 s timeout after 1000 cycles, -1.
    assert_eq!(m66(WaitMode::Rise, true, &[]), (Some(1000), -1.0));
}

#[test]
fn m66_fall_needs_on_then_off() {
    assert_eq!(m66(WaitMode::Fall, false, &[100, 200]), (Some(200), 0.0));
    assert_eq!(m66(WaitMode::Fall, true, &[50]), (Some(50), 0.0));
    assert_eq!(m66(WaitMode::Fall, false, &[]), (Some(1000), -1.0));
    // An on-off pulse after the timeout is too late.
    assert_eq!(
        m66(WaitMode::Fall, false, &[1200, 1300]),
        (Some(1000), -1.0)
    );
}

#[test]
fn m66_high_and_low_wait_for_the_level() {
    assert_eq!(m66(WaitMode::High, true, &[]), (Some(0), 1.0));
    assert_eq!(m66(WaitMode::High, false, &[300]), (Some(300), 1.0));
    assert_eq!(m66(WaitMode::High, false, &[]), (Some(1000), -1.0));
    assert_eq!(m66(WaitMode::Low, false, &[]), (Some(0), 0.0));
    assert_eq!(m66(WaitMode::Low, true, &[999]), (Some(999), 0.0));
    assert_eq!(m66(WaitMode::Low, true, &[1001]), (Some(1000), -1.0));
}

#[test]
fn m66_wait_shows_and_q0_checks_once() {
    let mut m = machine(config_with(None));
    assert_eq!(act(&mut m, wait_input(WaitMode::High, 1.0)), Gate::Wait);
    assert_eq!(
        m.pause().map(|p| p.reason),
        Some(PauseReason::WaitInput {
            input: 2,
            analog: false,
            mode: WaitMode::High
        })
    );
    assert_eq!(m.status().last_input, None);
    // Cancelled (abort): forgotten, no result.
    m.cancel(&action(wait_input(WaitMode::High, 1.0)));
    assert_eq!(m.pause(), None);
    assert_eq!(m.status().last_input, None);
    // Q0 with a wait: one check, then -1.
    assert_eq!(act(&mut m, wait_input(WaitMode::High, 0.0)), Gate::Done);
    assert_eq!(last_value(&m), -1.0);
}

// --- pauses ---

#[test]
fn program_stop_waits_for_cycle_start() {
    let mut m = machine(config_with(None));
    assert!(!m.resume(), "nothing waits");
    let stop = ActionKind::Pause(PauseCode::ProgramStop);
    for _ in 0..100 {
        assert_eq!(act(&mut m, stop), Gate::Wait);
        m.cycle(false);
    }
    let info = m.pause().unwrap();
    assert_eq!(info.reason, PauseReason::ProgramStop);
    assert_eq!(info.line, 7);
    assert!((info.waited_s - 0.1).abs() < 1e-12);
    assert!(info.reason.needs_cycle_start());
    assert!(m.resume());
    assert!(!m.resume(), "once");
    assert_eq!(m.pause(), None);
    assert_eq!(act(&mut m, stop), Gate::Done);
    assert_eq!(m.pause(), None);
}

#[test]
fn optional_stop_only_with_the_switch() {
    let mut m = machine(config_with(None));
    let m1 = ActionKind::Pause(PauseCode::OptionalStop);
    assert_eq!(act(&mut m, m1), Gate::Done);
    assert_eq!(m.pause(), None);
    m.set_optional_stop(true);
    assert!(m.status().switches.optional_stop);
    assert_eq!(act(&mut m, m1), Gate::Wait);
    assert_eq!(m.pause().unwrap().reason, PauseReason::OptionalStop);
    // Switched off during the pause: the pause stays until cycle start.
    m.set_optional_stop(false);
    assert_eq!(act(&mut m, m1), Gate::Wait);
    assert!(m.resume());
    assert_eq!(act(&mut m, m1), Gate::Done);
    // The configured default.
    let m2 = machine(MachineConfig {
        switches: Switches {
            optional_stop: true,
            single_block: true,
            block_delete: true,
        },
        ..config_with(None)
    });
    assert_eq!(
        m2.switches(),
        Switches {
            optional_stop: true,
            single_block: true,
            block_delete: true
        }
    );
}

#[test]
fn pallet_change_and_single_block_pause() {
    let mut m = machine(config_with(None));
    for (code, reason) in [
        (PauseCode::PalletChange, PauseReason::PalletChange),
        (PauseCode::SingleBlock, PauseReason::SingleBlock),
    ] {
        assert_eq!(act(&mut m, ActionKind::Pause(code)), Gate::Wait);
        assert_eq!(m.pause().unwrap().reason, reason);
        assert!(m.resume());
        assert_eq!(act(&mut m, ActionKind::Pause(code)), Gate::Done);
    }
    m.set_single_block(true);
    m.set_block_delete(true);
    let s = m.status().switches;
    assert!(s.single_block && s.block_delete && !s.optional_stop);
}

#[test]
fn cancel_ends_the_pause_of_that_action_only() {
    let mut m = machine(config_with(None));
    let stop = ActionKind::Pause(PauseCode::ProgramStop);
    assert_eq!(act(&mut m, stop), Gate::Wait);
    m.cancel(&Action {
        line: 8,
        kind: stop,
    });
    assert!(m.pause().is_some(), "another action: no effect");
    m.cancel(&action(stop));
    assert_eq!(m.pause(), None);
    assert!(!m.resume());
    // The same pause acted again (the next program) pauses anew.
    assert_eq!(act(&mut m, stop), Gate::Wait);
    m.end_program(EndCause::Abort);
    assert_eq!(m.pause(), None);
}

// --- tool changes ---

#[test]
fn manual_tool_change_stops_the_spindle_and_waits_for_cycle_start() {
    let mut m = machine(config_with(Some(sim_spindle())));
    spin_up(&mut m, 12000.0);
    for _ in 0..100 {
        m.cycle(false);
    }
    let change = ActionKind::ToolChange { tool: 3 };
    let mut reasons = [None; 2];
    // At rest 12000 / 8 = 1500 cycles after the stop; then the operator's pause.
    let k = run(&mut m, change, 5000, false, |k, m| {
        if k == 1499 {
            reasons[0] = m.pause().map(|p| p.reason);
        }
        if k == 1600 {
            reasons[1] = m.pause().map(|p| p.reason);
            assert!(m.resume());
        }
    });
    assert_eq!(reasons[0], Some(PauseReason::SpindleStop { tool: 3 }));
    assert_eq!(reasons[1], Some(PauseReason::ToolChange { tool: 3 }));
    assert_eq!(k, Some(1600));
    assert_eq!(m.status().tool_in_spindle, 3);
    assert_eq!(status_spindle(&m).dir, SpindleDir::Off);
}

#[test]
fn change_to_the_tool_in_the_spindle_is_done_at_once() {
    let mut m = machine(MachineConfig {
        tool_in_spindle: 4,
        ..config_with(Some(sim_spindle()))
    });
    spin_up(&mut m, 12000.0);
    assert_eq!(act(&mut m, ActionKind::ToolChange { tool: 4 }), Gate::Done);
    assert_eq!(
        status_spindle(&m).dir,
        SpindleDir::Cw,
        "the spindle turns on"
    );
    // No changer: done without a change.
    let mut m = machine(MachineConfig {
        tool_changer: ToolChanger::None,
        ..config_with(None)
    });
    assert_eq!(act(&mut m, ActionKind::ToolChange { tool: 2 }), Gate::Done);
    assert_eq!(m.tool_in_spindle(), 0);
    // Manual without a spindle: the pause at once; tool 0 empties the spindle.
    let mut m = machine(MachineConfig {
        tool_in_spindle: 5,
        ..config_with(None)
    });
    assert_eq!(act(&mut m, ActionKind::ToolChange { tool: 0 }), Gate::Wait);
    assert_eq!(
        m.pause().unwrap().reason,
        PauseReason::ToolChange { tool: 0 }
    );
    m.resume();
    assert_eq!(act(&mut m, ActionKind::ToolChange { tool: 0 }), Gate::Done);
    assert_eq!(m.tool_in_spindle(), 0);
}

fn automatic(simulated_inputs: bool) -> MachineConfig {
    MachineConfig {
        tool_changer: ToolChanger::Automatic(AutomaticChanger {
            number_output: 0,
            change_output: 5,
            changed_input: 6,
            timeout_s: 10.0,
            sim_change_s: DEFAULT_SIM_CHANGE_S,
        }),
        io: IoConfig {
            simulated_inputs,
            ..io()
        },
        ..config_with(None)
    }
}

#[test]
fn automatic_tool_change_handshake_with_the_simulated_changer() {
    let mut m = machine(automatic(true));
    let t7 = ActionKind::ToolChange { tool: 7 };
    let t8 = ActionKind::ToolChange { tool: 8 };
    assert_eq!(act(&mut m, t7), Gate::Wait);
    assert_eq!(m.io().analog_output(0), 7.0);
    assert!(m.io().digital_output(5), "request on");
    assert_eq!(
        m.pause().unwrap().reason,
        PauseReason::ToolChanging { tool: 7 }
    );
    assert!(!m.resume(), "no cycle start needed");
    // The simulated changer answers 2 s (2000 cycles) after the request.
    let k = run(&mut m, t7, 5000, false, |_, _| {});
    assert_eq!(k, Some(2000));
    assert!(!m.io().digital_output(5), "request off");
    assert_eq!(m.tool_in_spindle(), 7);
    // The next change in the same cycle: the answer of the last one is still on, so the
    // request waits until it has gone (one cycle), then 2 s.
    assert_eq!(act(&mut m, t8), Gate::Wait);
    assert!(!m.io().digital_output(5));
    let k = run(&mut m, t8, 5000, false, |_, _| {});
    assert_eq!(k, Some(2001));
    assert_eq!(m.tool_in_spindle(), 8);
    assert!(matches!(
        m.set_input_digital(6, true),
        Err(InputError::Simulated { input: 6, .. })
    ));
}

#[test]
fn automatic_tool_change_timeout_faults() {
    let mut m = machine(automatic(false));
    let t7 = ActionKind::ToolChange { tool: 7 };
    assert_eq!(run(&mut m, t7, 10_000, false, |_, _| {}), None);
    let fault = m.fault().unwrap();
    assert_eq!(
        fault,
        MachineFault::ToolChangeTimeout {
            line: 7,
            tool: 7,
            changed_input: 6,
            waited_s: 10.0
        }
    );
    assert_eq!(
        fault.to_string(),
        "tool change to T7 not done after 10.0 s: the tool changer did not answer on digital input 6 (line 7)"
    );
    assert!(!m.io().digital_output(5), "request off");
    assert_eq!(m.tool_in_spindle(), 0);

    // The fieldbus's answer.
    let mut m = machine(automatic(false));
    let k = run(&mut m, t7, 10_000, false, |k, m| {
        if k == 300 {
            m.set_bus_inputs(1 << 6, &[0.0; ANALOG_IO]);
        }
    });
    assert_eq!(k, Some(300));
    assert_eq!(m.tool_in_spindle(), 7);
}

#[test]
fn cancelled_tool_change_drops_the_request_and_keeps_the_tool() {
    let mut m = machine(MachineConfig {
        tool_in_spindle: 2,
        ..automatic(true)
    });
    let t7 = ActionKind::ToolChange { tool: 7 };
    assert_eq!(run(&mut m, t7, 500, false, |_, _| {}), None);
    assert!(m.io().digital_output(5));
    m.cancel(&action(t7));
    assert!(!m.io().digital_output(5));
    assert_eq!(m.pause(), None);
    assert_eq!(m.tool_in_spindle(), 2);
}

// --- end of program, abort, fault ---

fn with_coolant(flood_off: OffPolicy, spindle_off: OffPolicy) -> MachineConfig {
    MachineConfig {
        coolant: CoolantConfig {
            mist: Some(CoolantOutput {
                output: 4,
                off: OffPolicy::default(),
            }),
            flood: Some(CoolantOutput {
                output: 5,
                off: flood_off,
            }),
        },
        ..config_with(Some(SpindleConfig {
            off: spindle_off,
            ..sim_spindle()
        }))
    }
}

fn start_all(m: &mut Machine) {
    spin_up(m, 12000.0);
    act(
        m,
        ActionKind::Coolant {
            mist: true,
            flood: true,
        },
    );
}

#[test]
fn program_end_switches_off_per_policy() {
    let mut m = machine(with_coolant(OffPolicy::default(), OffPolicy::default()));
    start_all(&mut m);
    act(
        &mut m,
        ActionKind::Overrides {
            feed: Some(false),
            spindle: Some(false),
        },
    );
    assert_eq!(act(&mut m, ActionKind::ProgramEnd), Gate::Done);
    assert_eq!(status_spindle(&m).dir, SpindleDir::Off);
    assert_eq!(m.status().coolant, CoolantStatus::default());
    assert_eq!(m.io().digital_outputs, 0);
    // M2 enables the overrides (M48).
    assert!(m.feed_override_enabled() && status_spindle(&m).override_enabled);

    // Flood stays on at the end, the spindle too.
    let keep = OffPolicy {
        at_end: false,
        ..OffPolicy::default()
    };
    let mut m = machine(with_coolant(keep, keep));
    start_all(&mut m);
    act(&mut m, ActionKind::ProgramEnd);
    assert_eq!(status_spindle(&m).dir, SpindleDir::Cw);
    assert_eq!(
        m.status().coolant,
        CoolantStatus {
            mist: false,
            flood: true
        }
    );
    assert_eq!(m.io().digital_outputs, 1 << 5);
}

#[test]
fn abort_and_fault_switch_off_per_policy() {
    let keep_at_abort = OffPolicy {
        at_abort: false,
        ..OffPolicy::default()
    };
    let mut m = machine(with_coolant(OffPolicy::default(), keep_at_abort));
    start_all(&mut m);
    assert_eq!(
        act(&mut m, ActionKind::Pause(PauseCode::ProgramStop)),
        Gate::Wait
    );
    m.end_program(EndCause::Abort);
    assert_eq!(m.pause(), None);
    assert_eq!(status_spindle(&m).dir, SpindleDir::Cw, "kept at abort");
    assert_eq!(m.status().coolant, CoolantStatus::default());
    m.end_program(EndCause::Fault);
    assert_eq!(status_spindle(&m).dir, SpindleDir::Off);

    let keep_at_fault = OffPolicy {
        at_fault: false,
        ..OffPolicy::default()
    };
    let mut m = machine(with_coolant(keep_at_fault, OffPolicy::default()));
    start_all(&mut m);
    m.end_program(EndCause::Fault);
    assert_eq!(
        m.status().coolant,
        CoolantStatus {
            mist: false,
            flood: true
        }
    );
}

// --- I/O ---

#[test]
fn simulated_inputs_are_checked() {
    let mut m = machine(config_with(None));
    assert_eq!(
        m.set_input_digital(8, true),
        Err(InputError::NoDigitalInput(8))
    );
    assert_eq!(
        m.set_input_analog(4, 1.0),
        Err(InputError::NoAnalogInput(4))
    );
    assert!(matches!(
        m.set_input_analog(0, f64::NAN),
        Err(InputError::NotFinite { input: 0, .. })
    ));
    m.set_input_digital(7, true).unwrap();
    m.set_input_analog(3, -2.5).unwrap();
    assert_eq!(m.status().io.digital_inputs, 1 << 7);
    assert_eq!(m.status().io.analog_inputs[3], -2.5);

    let mut m = machine(MachineConfig {
        io: IoConfig {
            simulated_inputs: false,
            ..io()
        },
        ..config_with(None)
    });
    assert_eq!(m.set_input_digital(1, true), Err(InputError::NotSimulated));
    // The fieldbus: bits of inputs that do not exist are dropped.
    let mut analog = [0.0; ANALOG_IO];
    analog[1] = 4.0;
    analog[9] = 9.0;
    m.set_bus_inputs(u64::MAX, &analog);
    assert_eq!(m.io().digital_inputs, 0xff);
    assert_eq!(m.io().analog_input(1), 4.0);
    assert_eq!(m.io().analog_input(9), 0.0);
}

#[test]
fn initial_inputs_and_config_checks() {
    let mut initial = [0.0; ANALOG_IO];
    initial[2] = 1.25;
    let m = machine(MachineConfig {
        io: IoConfig {
            initial_digital_inputs: 0b1_0000_0101,
            initial_analog_inputs: initial,
            ..io()
        },
        ..config_with(None)
    });
    assert_eq!(m.io().digital_inputs, 0b101, "input 8 does not exist");
    assert_eq!(m.io().analog_input(2), 1.25);

    let bad = MachineConfig {
        coolant: CoolantConfig {
            mist: Some(CoolantOutput {
                output: 9,
                off: OffPolicy::default(),
            }),
            flood: None,
        },
        ..config_with(None)
    };
    assert_eq!(
        Machine::new(bad).unwrap_err(),
        MachineConfigError::NoDigitalOutput {
            what: "mist coolant",
            output: 9
        }
    );
    let twice = MachineConfig {
        coolant: CoolantConfig {
            mist: Some(CoolantOutput {
                output: 5,
                off: OffPolicy::default(),
            }),
            flood: None,
        },
        ..automatic(true)
    };
    assert_eq!(
        Machine::new(twice).unwrap_err(),
        MachineConfigError::OutputTwice {
            what: "tool changer change request",
            analog: false,
            output: 5,
        }
    );
    assert!(matches!(
        Machine::new(MachineConfig::new(0.0)),
        Err(MachineConfigError::Period(_))
    ));
    let slow = config_with(Some(SpindleConfig {
        acceleration_rpm_s: 0.0,
        ..sim_spindle()
    }));
    assert!(matches!(
        Machine::new(slow),
        Err(MachineConfigError::Value { .. })
    ));
}

// --- real time ---

#[test]
fn no_allocation_in_cycle_or_act() {
    let mut m = machine(MachineConfig {
        tool_changer: ToolChanger::Automatic(AutomaticChanger {
            number_output: 0,
            change_output: 3,
            changed_input: 6,
            timeout_s: 10.0,
            sim_change_s: 0.5,
        }),
        ..with_coolant(OffPolicy::default(), OffPolicy::default())
    });
    let kinds = [
        spindle(SpindleDir::Cw, 12000.0),
        ActionKind::WaitAtSpeed,
        ActionKind::Coolant {
            mist: true,
            flood: true,
        },
        wait_input(WaitMode::Rise, 0.05),
        ActionKind::Pause(PauseCode::ProgramStop),
        ActionKind::ToolChange { tool: 3 },
        ActionKind::Orient {
            angle_deg: 0.0,
            mode: 0,
            timeout_s: 10.0,
        },
        ActionKind::ProgramEnd,
    ];
    let count = kerf_testkit::alloc::Count::start();
    for kind in kinds {
        let a = action(kind);
        for _ in 0..10_000 {
            m.cycle(true);
            m.resume();
            let _ = m.status();
            if m.act(&a) == Gate::Done {
                break;
            }
        }
    }
    m.end_program(EndCause::Abort);
    let allocations = count.stop();
    assert_eq!(m.fault(), None);
    assert_eq!(m.tool_in_spindle(), 3);
    assert_eq!(allocations, 0);
}

// --- properties ---

#[derive(Clone, Copy, Debug)]
enum Command {
    Spindle(SpindleDir, f64),
    Override(f64),
    OverrideEnabled(bool),
    Stall(bool),
}

fn command() -> impl Strategy<Value = Command> {
    let dir = prop_oneof![
        Just(SpindleDir::Off),
        Just(SpindleDir::Cw),
        Just(SpindleDir::Ccw)
    ];
    prop_oneof![
        (dir, 0.0..30000.0f64).prop_map(|(d, r)| Command::Spindle(d, r)),
        (0.0..250.0f64).prop_map(Command::Override),
        any::<bool>().prop_map(Command::OverrideEnabled),
        any::<bool>().prop_map(Command::Stall),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// Whatever is commanded, the simulated drive's speed changes by at most
    /// acceleration × period per cycle, and stays within ±max_rpm.
    #[test]
    fn sim_spindle_never_exceeds_its_acceleration(
        accel in 100.0..20000.0f64,
        steps in proptest::collection::vec((command(), 1u32..400), 1..30),
    ) {
        let config = config_with(Some(SpindleConfig {
            acceleration_rpm_s: accel,
            min_rpm: 100.0,
            fault_out_of_band: false,
            ..sim_spindle()
        }));
        let mut m = machine(config);
        let limit = accel * PERIOD_S * (1.0 + 1e-12);
        let mut previous = actual(&m);
        for (c, cycles) in steps {
            match c {
                Command::Spindle(dir, rpm) => {
                    act(&mut m, spindle(dir, rpm));
                }
                Command::Override(pct) => m.set_spindle_override_pct(pct),
                Command::OverrideEnabled(on) => {
                    act(&mut m, ActionKind::Overrides { feed: None, spindle: Some(on) });
                }
                Command::Stall(on) => m.inject_spindle_stall(on),
            }
            for _ in 0..cycles {
                m.cycle(false);
                let now = actual(&m);
                prop_assert!((now - previous).abs() <= limit, "{previous} → {now}");
                prop_assert!(now.abs() <= 24000.0);
                previous = now;
            }
        }
    }
}
