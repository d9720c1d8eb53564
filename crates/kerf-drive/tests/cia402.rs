//! CiA 402 decoding, scaling and the master-side enable sequence. Expected values come
//! from the standard's tables (IEC 61800-7-201 / CiA 402 part 2), not from the code.

use kerf_drive::cia402::{
    Cia402Error, Drive, DriveCommand, DriveState, Enabler, EnablerStatus, Request, Scale,
    is_fault_reset_edge,
};
use kerf_drive::sim::{SimConfig, SimDrive};

/// The standard's statusword table, written out: for each state, the bits that decide
/// (x = don't care) as a string, bit 15 first. Every pattern of the deciding bits 0-3,
/// 5, 6 is enumerated below and checked against this table.
const TABLE: [(&str, DriveState); 8] = [
    ("xxxxxxxxx0xx0000", DriveState::NotReadyToSwitchOn),
    ("xxxxxxxxx1xx0000", DriveState::SwitchOnDisabled),
    ("xxxxxxxxx01x0001", DriveState::ReadyToSwitchOn),
    ("xxxxxxxxx01x0011", DriveState::SwitchedOn),
    ("xxxxxxxxx01x0111", DriveState::OperationEnabled),
    ("xxxxxxxxx00x0111", DriveState::QuickStopActive),
    ("xxxxxxxxx0xx1111", DriveState::FaultReactionActive),
    ("xxxxxxxxx0xx1000", DriveState::Fault),
];

fn matches_pattern(word: u16, pattern: &str) -> bool {
    pattern.chars().enumerate().all(|(i, c)| {
        let bit = (word >> (15 - i)) & 1;
        match c {
            '0' => bit == 0,
            '1' => bit == 1,
            _ => true,
        }
    })
}

#[test]
fn every_statusword_decodes_as_the_standard_table_says() {
    // All 65536 words: the decoded state is the table's row, or none when no row fits.
    for word in 0..=u16::MAX {
        let expected: Vec<DriveState> = TABLE
            .iter()
            .filter(|(p, _)| matches_pattern(word, p))
            .map(|(_, s)| *s)
            .collect();
        assert!(expected.len() <= 1, "table rows overlap for {word:#06x}");
        assert_eq!(
            DriveState::from_statusword(word),
            expected.first().copied(),
            "statusword {word:#06x}"
        );
    }
    // And some literal words a drive sends (voltage enabled, remote, bits 12/13 set).
    assert_eq!(
        DriveState::from_statusword(0x0250),
        Some(DriveState::SwitchOnDisabled)
    );
    assert_eq!(
        DriveState::from_statusword(0x0231),
        Some(DriveState::ReadyToSwitchOn)
    );
    assert_eq!(
        DriveState::from_statusword(0x0233),
        Some(DriveState::SwitchedOn)
    );
    assert_eq!(
        DriveState::from_statusword(0x1237),
        Some(DriveState::OperationEnabled)
    );
    assert_eq!(
        DriveState::from_statusword(0x0217),
        Some(DriveState::QuickStopActive)
    );
    assert_eq!(
        DriveState::from_statusword(0x021F),
        Some(DriveState::FaultReactionActive)
    );
    assert_eq!(DriveState::from_statusword(0x0218), Some(DriveState::Fault));
    // Undefined: bit 6 with bit 0 set.
    assert_eq!(DriveState::from_statusword(0x0041), None);
}

#[test]
fn statusword_bits_of_each_state_decode_back() {
    for (_, state) in TABLE {
        assert_eq!(
            DriveState::from_statusword(state.statusword_bits()),
            Some(state)
        );
    }
}

#[test]
fn controlword_commands_decode_as_the_standard_table_says() {
    // Command table: Shutdown 0xxx x110, Switch on 0xxx 0111, Enable operation
    // 0xxx 1111, Disable voltage 0xxx xx0x, Quick stop 0xxx x01x.
    assert_eq!(
        DriveCommand::from_controlword(0x0006),
        Some(DriveCommand::Shutdown)
    );
    assert_eq!(
        DriveCommand::from_controlword(0x000E),
        Some(DriveCommand::Shutdown)
    );
    assert_eq!(
        DriveCommand::from_controlword(0x0007),
        Some(DriveCommand::SwitchOn)
    );
    assert_eq!(
        DriveCommand::from_controlword(0x000F),
        Some(DriveCommand::EnableOperation)
    );
    assert_eq!(
        DriveCommand::from_controlword(0x0000),
        Some(DriveCommand::DisableVoltage)
    );
    assert_eq!(
        DriveCommand::from_controlword(0x000D),
        Some(DriveCommand::DisableVoltage)
    );
    assert_eq!(
        DriveCommand::from_controlword(0x0002),
        Some(DriveCommand::QuickStop)
    );
    assert_eq!(
        DriveCommand::from_controlword(0x000B),
        Some(DriveCommand::QuickStop)
    );
    // Bits 4-6 and 8-15 do not change the command.
    assert_eq!(
        DriveCommand::from_controlword(0x017F),
        Some(DriveCommand::EnableOperation)
    );
    // Bit 7 set: no command of the table.
    assert_eq!(DriveCommand::from_controlword(0x008F), None);
    assert!(is_fault_reset_edge(0x0000, 0x0080));
    assert!(!is_fault_reset_edge(0x0080, 0x0080));
    assert!(!is_fault_reset_edge(0x0080, 0x0000));
}

#[test]
fn scale_converts_both_ways_with_half_count_rounding() {
    let x = Scale::new(1000.0, 1).expect("valid scale");
    assert_eq!(x.to_counts(12.3456), Ok(12346));
    assert_eq!(x.to_counts(-12.3456), Ok(-12346));
    // Half a count rounds away from zero on both sides.
    assert_eq!(x.to_counts(0.0005), Ok(1));
    assert_eq!(x.to_counts(-0.0005), Ok(-1));
    assert!((x.to_units(12346) - 12.346).abs() < 1e-12);
    let a = Scale::new(10_000.0 / 360.0, -1).expect("valid scale");
    assert_eq!(a.to_counts(90.0), Ok(-2500));
    assert!((a.to_units(-2500) - 90.0).abs() < 1e-9);
    // Round trip within half a count.
    for i in -1000..1000 {
        let p = f64::from(i) * 0.01234567;
        let back = x.to_units(x.to_counts(p).expect("in range"));
        assert!((back - p).abs() <= 0.5 / 1000.0 + 1e-12);
    }
    assert_eq!(x.to_counts(3.0e6), Err(Cia402Error::OutOfRange(3.0e6)));
    assert!(x.to_counts(f64::NAN).is_err());
    assert!(Scale::new(0.0, 1).is_err());
    assert!(Scale::new(f64::INFINITY, 1).is_err());
    assert!(Scale::new(100.0, 0).is_err());
}

#[test]
fn timeout_in_cycles_rounds_up() {
    assert_eq!(Enabler::timeout_cycles_for(100_000_000, 1_000_000), 100);
    assert_eq!(Enabler::timeout_cycles_for(100_500_000, 1_000_000), 101);
    assert_eq!(Enabler::timeout_cycles_for(0, 1_000_000), 1);
}

/// Runs the master cycle (read, decide, write) against a drive; returns the statuses
/// seen, one per cycle, and the last output's hold target.
fn run<D: Drive>(
    drive: &mut D,
    enabler: &mut Enabler,
    cycles: usize,
    setpoint_counts: i32,
) -> Vec<EnablerStatus> {
    let mut seen = Vec::new();
    for _ in 0..cycles {
        let out = enabler.cycle(
            drive.statusword(),
            drive.position_actual_counts(),
            drive.error_code(),
        );
        let target = out.hold_target_counts.unwrap_or(setpoint_counts);
        drive.write(out.controlword, target);
        seen.push(out.status);
    }
    seen
}

fn sim_at(position_counts: f64) -> SimDrive {
    SimDrive::new(SimConfig {
        initial_position_counts: position_counts,
        ..SimConfig::default()
    })
}

#[test]
fn enable_from_switch_on_disabled_takes_three_transitions() {
    let mut drive = sim_at(1234.0);
    // Transition 1 (initialisation) on the first exchange.
    drive.write(0, 0);
    assert_eq!(drive.state(), DriveState::SwitchOnDisabled);
    let mut enabler = Enabler::new(10);
    enabler.request(Request::Enable);
    let seen = run(&mut drive, &mut enabler, 4, 1234);
    // Transitions 2, 3, 4: Shutdown, Switch on, Enable operation, one per cycle; the
    // fourth cycle sees Operation enabled.
    assert_eq!(
        seen,
        vec![
            EnablerStatus::InProgress(DriveState::SwitchOnDisabled),
            EnablerStatus::InProgress(DriveState::ReadyToSwitchOn),
            EnablerStatus::InProgress(DriveState::SwitchedOn),
            EnablerStatus::Done(DriveState::OperationEnabled),
        ]
    );
}

#[test]
fn enable_does_not_jump_the_target_equals_the_actual_position() {
    let mut drive = sim_at(-98_765.4);
    let mut enabler = Enabler::new(10);
    enabler.request(Request::Enable);
    // The master's own setpoint is far away; the enabler must hold the target at the
    // actual position until the drive is enabled.
    let mut target_at_enable = None;
    for _ in 0..10 {
        let actual = drive.position_actual_counts();
        let out = enabler.cycle(drive.statusword(), actual, drive.error_code());
        // The master's own setpoint is 0, ~98 765 counts away.
        let target = out.hold_target_counts.unwrap_or(0);
        if out.status == EnablerStatus::Done(DriveState::OperationEnabled) {
            break;
        }
        if out.controlword == 0x000F && target_at_enable.is_none() {
            target_at_enable = Some((target, actual));
        }
        drive.write(out.controlword, target);
    }
    let (target, actual) = target_at_enable.expect("enable operation was sent");
    assert_eq!(target, actual);
    assert_eq!(actual, -98_765);
    assert_eq!(drive.state(), DriveState::OperationEnabled);
    // The motor did not move by more than the rounding of the initial position (the
    // loop stops before the master's setpoint 0 would be written).
    assert!((drive.motor_position_counts() + 98_765.4).abs() < 1.0);
}

/// A drive that never answers: its statusword stays Switch on disabled.
struct DeadDrive;
impl Drive for DeadDrive {
    fn write(&mut self, _controlword: u16, _target_position_counts: i32) {}
    fn set_mode_of_operation(&mut self, _mode: i8) {}
    fn mode_of_operation_display(&self) -> i8 {
        8
    }
    fn statusword(&self) -> u16 {
        0x0250
    }
    fn position_actual_counts(&self) -> i32 {
        0
    }
    fn velocity_actual_counts_s(&self) -> i32 {
        0
    }
    fn following_error_counts(&self) -> i32 {
        0
    }
    fn error_code(&self) -> u16 {
        0
    }
}

#[test]
fn enable_times_out_when_the_drive_does_not_answer() {
    let mut drive = DeadDrive;
    let mut enabler = Enabler::new(5);
    enabler.request(Request::Enable);
    let seen = run(&mut drive, &mut enabler, 8, 0);
    // Cycles 0-4 wait in Switch on disabled, the sixth (5 cycles later) times out, and
    // the timeout stays.
    for status in &seen[..5] {
        assert_eq!(
            *status,
            EnablerStatus::InProgress(DriveState::SwitchOnDisabled)
        );
    }
    for status in &seen[5..] {
        assert_eq!(
            *status,
            EnablerStatus::Timeout {
                state: DriveState::SwitchOnDisabled
            }
        );
    }
    // A new request starts again.
    enabler.request(Request::Enable);
    let seen = run(&mut drive, &mut enabler, 1, 0);
    assert_eq!(
        seen[0],
        EnablerStatus::InProgress(DriveState::SwitchOnDisabled)
    );
}

#[test]
fn fault_needs_a_reset_and_the_reset_is_an_edge() {
    let mut drive = sim_at(0.0);
    let mut enabler = Enabler::new(10);
    enabler.request(Request::Enable);
    run(&mut drive, &mut enabler, 5, 0);
    assert_eq!(drive.state(), DriveState::OperationEnabled);
    drive.inject_fault(0x5432);
    let seen = run(&mut drive, &mut enabler, 20, 0);
    assert_eq!(
        seen.last(),
        Some(&EnablerStatus::Fault { error_code: 0x5432 })
    );
    assert_eq!(drive.state(), DriveState::Fault);
    enabler.request(Request::FaultReset);
    let seen = run(&mut drive, &mut enabler, 4, 0);
    assert_eq!(
        seen.last(),
        Some(&EnablerStatus::Done(DriveState::SwitchOnDisabled))
    );
    assert_eq!(drive.error_code(), 0);
    enabler.request(Request::Enable);
    let seen = run(&mut drive, &mut enabler, 4, 0);
    assert_eq!(
        seen.last(),
        Some(&EnablerStatus::Done(DriveState::OperationEnabled))
    );
}

#[test]
fn fault_reset_is_refused_while_the_cause_persists() {
    let mut drive = sim_at(0.0);
    let mut enabler = Enabler::new(10);
    drive.set_fault_cause(Some(0x4310));
    run(&mut drive, &mut enabler, 4, 0);
    assert_eq!(drive.state(), DriveState::Fault);
    enabler.request(Request::FaultReset);
    let seen = run(&mut drive, &mut enabler, 15, 0);
    assert_eq!(
        seen.last(),
        Some(&EnablerStatus::Timeout {
            state: DriveState::Fault
        })
    );
    drive.set_fault_cause(None);
    enabler.request(Request::FaultReset);
    let seen = run(&mut drive, &mut enabler, 4, 0);
    assert_eq!(
        seen.last(),
        Some(&EnablerStatus::Done(DriveState::SwitchOnDisabled))
    );
}

#[test]
fn quick_stop_request_ends_in_switch_on_disabled() {
    let mut drive = sim_at(0.0);
    let mut enabler = Enabler::new(1000);
    enabler.request(Request::Enable);
    run(&mut drive, &mut enabler, 5, 0);
    enabler.request(Request::QuickStop);
    let seen = run(&mut drive, &mut enabler, 3, 0);
    assert_eq!(
        seen.last(),
        Some(&EnablerStatus::Done(DriveState::SwitchOnDisabled))
    );
}

#[test]
fn a_drive_that_drops_out_is_not_enabled_again_without_a_new_request() {
    let mut drive = sim_at(500.0);
    let mut enabler = Enabler::new(10);
    enabler.request(Request::Enable);
    let seen = run(&mut drive, &mut enabler, 5, 500);
    assert_eq!(
        seen.last(),
        Some(&EnablerStatus::Done(DriveState::OperationEnabled))
    );
    // Something else shuts the drive down (transition 8).
    drive.write(0x0006, 500);
    assert_eq!(drive.state(), DriveState::ReadyToSwitchOn);
    let seen = run(&mut drive, &mut enabler, 10, 500);
    for status in &seen {
        assert_eq!(
            *status,
            EnablerStatus::Dropped {
                state: DriveState::ReadyToSwitchOn
            }
        );
    }
    assert_ne!(drive.state(), DriveState::OperationEnabled);
    // A new request enables it again.
    enabler.request(Request::Enable);
    let seen = run(&mut drive, &mut enabler, 4, 500);
    assert_eq!(
        seen.last(),
        Some(&EnablerStatus::Done(DriveState::OperationEnabled))
    );
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    fn request_strategy() -> impl Strategy<Value = Option<Request>> {
        prop_oneof![
            6 => Just(None),
            1 => Just(Some(Request::Enable)),
            1 => Just(Some(Request::Disable)),
            1 => Just(Some(Request::QuickStop)),
            1 => Just(Some(Request::FaultReset)),
        ]
    }

    proptest! {
        /// Whatever the requests and faults, the drive enters Operation enabled only in a
        /// cycle whose target is the actual position read in that cycle (no jump), and
        /// leaves Fault only after a fault reset request.
        #[test]
        fn enabling_never_jumps_and_faults_need_a_reset(
            initial_counts in -1.0e6f64..1.0e6,
            timeout_cycles in 1u32..20,
            steps in prop::collection::vec(
                (request_strategy(), prop::bool::weighted(0.03), -5000i32..5000),
                1..200,
            ),
        ) {
            let mut drive = sim_at(initial_counts);
            let mut enabler = Enabler::new(timeout_cycles);
            let mut reset_requested = false;
            for (request, fault, offset) in steps {
                if let Some(request) = request {
                    enabler.request(request);
                    reset_requested |= request == Request::FaultReset;
                }
                if fault {
                    drive.inject_fault(0x1234);
                }
                let before = drive.state();
                let actual = drive.position_actual_counts();
                let out = enabler.cycle(drive.statusword(), actual, drive.error_code());
                // The master's setpoint, once enabled: near the actual position.
                let target = out.hold_target_counts.unwrap_or(actual.saturating_add(offset / 100));
                drive.write(out.controlword, target);
                let after = drive.state();
                if after == DriveState::OperationEnabled && before != DriveState::OperationEnabled {
                    prop_assert_eq!(target, actual);
                }
                if before == DriveState::Fault && after != DriveState::Fault {
                    prop_assert!(reset_requested);
                    prop_assert_eq!(enabler.current_request(), Request::FaultReset);
                }
            }
        }
    }
}
