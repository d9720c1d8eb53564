//! Supervision through ethercrab 0.7.1: I/O inputs set from outside reach the process
//! data, an injected drive fault shows in the statusword and error code and is reset, and
//! when the emulator stops answering (a pulled cable) the drive's process-data watchdog
//! stops it by itself and drops it to SAFE-OP with AL status code 0x001B.

mod netns;

use std::io::Write;
use std::process::ChildStdin;
use std::time::{Duration, Instant};

use ethercrab::subdevice_group::Op;
use ethercrab::{MainDevice, PduStorage, SubDeviceGroup, SubDeviceState, std::ethercat_now};
use futures_lite::future::block_on;
use netns::Netns;

const MAX_SUBDEVICES: usize = 8;
const PDI_LEN: usize = 256;

static STORAGE: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

type Group = SubDeviceGroup<MAX_SUBDEVICES, PDI_LEN, ethercrab::DefaultLock, Op>;

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct DriveInputs {
    statusword: u16,
    position: i32,
    velocity: i32,
    error_code: u16,
}

/// Drive 0's inputs from the last exchange.
fn drive_inputs(group: &Group, md: &MainDevice<'_>) -> DriveInputs {
    let drive = group.subdevice(md, 0).expect("drive 0");
    let i = drive.inputs_raw();
    DriveInputs {
        statusword: u16::from_le_bytes([i[0], i[1]]),
        position: i32::from_le_bytes([i[2], i[3], i[4], i[5]]),
        velocity: i32::from_le_bytes([i[6], i[7], i[8], i[9]]),
        error_code: u16::from_le_bytes([i[14], i[15]]),
    }
}

/// Sets drive 0's controlword and target for the next exchange.
fn set_outputs(group: &Group, md: &MainDevice<'_>, controlword: u16, target: i32) {
    let drive = group.subdevice(md, 0).expect("drive 0");
    let mut out = drive.outputs_raw_mut();
    out[0..2].copy_from_slice(&controlword.to_le_bytes());
    out[2..6].copy_from_slice(&target.to_le_bytes());
}

/// One exchange writing drive 0's controlword and target; returns its inputs.
fn cycle(group: &Group, md: &MainDevice<'_>, controlword: u16, target: i32) -> DriveInputs {
    set_outputs(group, md, controlword, target);
    block_on(group.tx_rx(md)).expect("tx_rx");
    drive_inputs(group, md)
}

fn enable(group: &Group, md: &MainDevice<'_>, target: i32) -> DriveInputs {
    let mut last = DriveInputs::default();
    for controlword in [0x0000, 0x0006, 0x0007, 0x000F, 0x000F] {
        last = cycle(group, md, controlword, target);
    }
    last
}

#[derive(Debug, Default)]
struct Seen {
    io_inputs: u8,
    enabled: DriveInputs,
    faulted: DriveInputs,
    re_enabled: DriveInputs,
    moving: DriveInputs,
    after_watchdog: DriveInputs,
    states_after: Vec<SubDeviceState>,
    al_code_after: u16,
}

fn run(mut control: ChildStdin) -> Seen {
    let md = netns::maindevice(&STORAGE);
    let group = block_on(md.init_single_group::<MAX_SUBDEVICES, PDI_LEN>(ethercat_now))
        .expect("init to PRE-OP");
    let group = block_on(group.into_op(&md)).expect("PRE-OP -> OP");
    let mut seen = Seen::default();
    let deadline = || Instant::now() + Duration::from_secs(10);

    // I/O inputs set through the emulator's control.
    writeln!(control, "inputs 0 0xA5").expect("control");
    let until = deadline();
    while Instant::now() < until && seen.io_inputs != 0xA5 {
        block_on(group.tx_rx(&md)).expect("tx_rx");
        seen.io_inputs = group.subdevice(&md, 1).expect("I/O").inputs_raw()[0];
    }

    seen.enabled = enable(&group, &md, 0);
    // An injected overcurrent fault.
    writeln!(control, "fault 0 0x2310").expect("control");
    let until = deadline();
    while Instant::now() < until {
        seen.faulted = cycle(&group, &md, 0x000F, 0);
        if seen.faulted.statusword & 0x004F == 0x0008 {
            break;
        }
    }
    // Fault reset (rising edge of bit 7), then enable again.
    cycle(&group, &md, 0x0000, 0);
    cycle(&group, &md, 0x0080, 0);
    seen.re_enabled = enable(&group, &md, 0);
    // Move at 20 counts per cycle for 300 cycles.
    let mut target = 0;
    for _ in 0..300 {
        target += 20;
        seen.moving = cycle(&group, &md, 0x000F, target);
    }
    // The cable is pulled: the motion goes on until exchanges time out (the emulator
    // reads its control asynchronously), then the drive's watchdog runs out.
    writeln!(control, "mute").expect("control");
    let mut timeouts_seen = 0;
    let until = deadline();
    while Instant::now() < until && timeouts_seen < 3 {
        target += 20;
        set_outputs(&group, &md, 0x000F, target);
        match block_on(group.tx_rx(&md)) {
            Ok(_) if timeouts_seen == 0 => seen.moving = drive_inputs(&group, &md),
            Ok(_) => {}
            Err(_) => timeouts_seen += 1,
        }
    }
    writeln!(control, "unmute").expect("control");
    let until = deadline();
    while Instant::now() < until {
        if let Ok(response) = block_on(group.tx_rx(&md)) {
            seen.states_after = response.subdevice_states.to_vec();
            break;
        }
    }
    seen.after_watchdog = drive_inputs(&group, &md);
    {
        let drive = group.subdevice(&md, 0).expect("drive 0");
        // With the AL error indicator set, ethercrab reports the status code as an error.
        seen.al_code_after = match block_on(drive.status()) {
            Err(ethercrab::error::Error::SubDevice(code)) => u16::from(code),
            other => panic!("expected the AL status code as an error, got {other:?}"),
        };
    }
    seen
}

#[test]
fn inputs_faults_and_the_process_data_watchdog_work_through_ethercrab() {
    let mut ns = Netns::new();
    ns.start_emulator(&["--drives", "1", "--io", "1"]);
    let control = ns.take_emulator_stdin();
    let seen = ns.run_inside(move || run(control));
    assert_eq!(seen.io_inputs, 0xA5);
    // CiA 402 decoding: Operation enabled 0x27 under mask 0x6F; Fault 0x08 under 0x4F.
    assert_eq!(
        seen.enabled.statusword & 0x006F,
        0x0027,
        "{:?}",
        seen.enabled
    );
    assert_eq!(
        seen.faulted.statusword & 0x004F,
        0x0008,
        "{:?}",
        seen.faulted
    );
    assert_eq!(seen.faulted.error_code, 0x2310);
    assert_eq!(
        seen.re_enabled.statusword & 0x006F,
        0x0027,
        "{:?}",
        seen.re_enabled
    );
    assert_eq!(seen.re_enabled.error_code, 0);
    // 20 counts per 1 ms cycle: 20 000 counts/s.
    assert!(
        (seen.moving.velocity - 20_000).abs() <= 200,
        "velocity while moving: {:?}",
        seen.moving
    );
    // After the watchdog: SAFE-OP with 0x001B; the drive stopped itself by its quick stop
    // (decelerating at 1e6 counts/s² from 20 000 counts/s takes v²/2a = 200 counts) and
    // went on to Switch on disabled (0x40 under mask 0x4F).
    // Both subdevices enable the watchdog in their output SyncManager (control bit 6), so
    // the I/O subdevice drops to SAFE-OP too.
    assert_eq!(
        seen.states_after,
        vec![SubDeviceState::SafeOp, SubDeviceState::SafeOp]
    );
    assert_eq!(seen.al_code_after, 0x001B);
    assert_eq!(
        seen.after_watchdog.statusword & 0x004F,
        0x0040,
        "{:?}",
        seen.after_watchdog
    );
    assert_eq!(seen.after_watchdog.velocity, 0);
    let travel = seen.after_watchdog.position - seen.moving.position;
    assert!(
        (150..=260).contains(&travel),
        "quick-stop travel {travel} counts, expected about 200"
    );
    assert!(ns.stop_emulator(), "the emulator exits cleanly on SIGTERM");
}
