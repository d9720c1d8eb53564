//! Through ethercrab 0.7.1, unmodified, with the emulator's control on its standard input
//! and its `state` answers on its standard output: a drive whose motor jams (`stall`)
//! and is freed (`free`); a pulled cable (`mute`) that the process-data watchdog turns
//! into SAFE-OP with AL status code 0x001B and the drive's own quick stop, then the
//! MainDevice's acknowledge (AL control 0x0120) and OP again, and the drive enabled again.

mod netns;

use std::time::{Duration, Instant};

use ethercrab::subdevice_group::Op;
use ethercrab::{MainDevice, PduStorage, SubDeviceGroup, SubDeviceState};
use futures_lite::future::block_on;
use netns::{Control, Netns, field};

const MAX_SUBDEVICES: usize = 8;
const PDI_LEN: usize = 256;
/// Two drives and an I/O subdevice.
const SUBDEVICES: usize = 3;

type Group = SubDeviceGroup<MAX_SUBDEVICES, PDI_LEN, ethercrab::DefaultLock, Op>;

/// Drive 0's inputs: statusword, position actual, velocity actual, following error.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct DriveInputs {
    statusword: u16,
    position: i32,
    velocity: i32,
    following_error: i32,
}

/// One exchange writing drive 0's controlword and target; returns its inputs.
fn cycle(group: &Group, md: &MainDevice<'_>, controlword: u16, target: i32) -> DriveInputs {
    {
        let drive = group.subdevice(md, 0).expect("drive 0");
        let mut out = drive.outputs_raw_mut();
        out[0..2].copy_from_slice(&controlword.to_le_bytes());
        out[2..6].copy_from_slice(&target.to_le_bytes());
    }
    block_on(group.tx_rx(md)).expect("tx_rx");
    let drive = group.subdevice(md, 0).expect("drive 0");
    let i = drive.inputs_raw();
    let i32_at = |at: usize| i32::from_le_bytes([i[at], i[at + 1], i[at + 2], i[at + 3]]);
    DriveInputs {
        statusword: u16::from_le_bytes([i[0], i[1]]),
        position: i32_at(2),
        velocity: i32_at(6),
        following_error: i32_at(10),
    }
}

/// Shutdown, Switch on, Enable operation (after 0x00, which lets it leave Not ready).
fn enable(group: &Group, md: &MainDevice<'_>, target: i32) -> DriveInputs {
    let mut last = DriveInputs::default();
    for controlword in [0x0000, 0x0006, 0x0007, 0x000F, 0x000F] {
        last = cycle(group, md, controlword, target);
    }
    last
}

fn bring_up(
    storage: &'static PduStorage<16, { PduStorage::element_size(1100) }>,
) -> (MainDevice<'static>, Group) {
    let md = netns::maindevice(storage);
    let group =
        block_on(md.init_single_group::<MAX_SUBDEVICES, PDI_LEN>(ethercrab::std::ethercat_now))
            .expect("init to PRE-OP");
    let group = block_on(group.into_op(&md)).expect("PRE-OP -> OP");
    (md, group)
}

static STORAGE_STALL: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

#[derive(Debug, Default)]
struct StallSeen {
    moving: DriveInputs,
    /// `state` right after `stall 0`.
    state_stalled: Vec<String>,
    /// Each cycle after the stall: (target, inputs).
    jammed: Vec<(i32, DriveInputs)>,
    /// `state` after the jammed cycles.
    state_jammed: Vec<String>,
    /// `state` after `inputs 0 0x5A` and `free 0`.
    state_freed: Vec<String>,
    /// The motion after `free 0`: (target, inputs) of the last cycle.
    freed: (i32, DriveInputs),
}

fn run_stall(mut control: Control) -> StallSeen {
    let (md, group) = bring_up(&STORAGE_STALL);
    let mut seen = StallSeen::default();
    enable(&group, &md, 0);
    let mut target = 0;
    for _ in 0..200 {
        target += 20;
        seen.moving = cycle(&group, &md, 0x000F, target);
    }
    control.send("stall 0");
    seen.state_stalled = control.state(SUBDEVICES);
    for _ in 0..300 {
        target += 20;
        seen.jammed
            .push((target, cycle(&group, &md, 0x000F, target)));
    }
    seen.state_jammed = control.state(SUBDEVICES);
    // The MainDevice holds the target where the motor stuck, then it is freed and moves
    // on at 20 counts per cycle.
    let stuck = seen.jammed.last().expect("jammed cycles").1.position;
    target = stuck;
    for _ in 0..5 {
        cycle(&group, &md, 0x000F, target);
    }
    control.send("inputs 0 0x5A");
    control.send("free 0");
    seen.state_freed = control.state(SUBDEVICES);
    for _ in 0..200 {
        target += 20;
        seen.freed = (target, cycle(&group, &md, 0x000F, target));
    }
    seen
}

#[test]
fn a_jammed_drive_holds_its_position_while_its_following_error_grows_and_state_shows_it() {
    let mut ns = Netns::new();
    ns.start_emulator(&["--drives", "2", "--io", "1"]);
    let control = ns.take_emulator_control();
    let seen = ns.run_inside(move || run_stall(control));
    // Moving at 20 counts per cycle, one model period (1 ms) per cycle: 20 000 counts/s.
    assert!(
        (seen.moving.velocity - 20_000).abs() <= 200,
        "{:?}",
        seen.moving
    );
    // `state` after `stall 0`: one line per subdevice, drive 0 jammed, enabled.
    let line = &seen.state_stalled[0];
    assert!(line.starts_with("subdevice 0 kind=drive "), "{line}");
    assert_eq!(field(line, "stalled"), "1");
    assert_eq!(field(line, "cia402"), "operation_enabled");
    assert_eq!(field(line, "al"), "OP");
    assert_eq!(field(line, "velocity_counts_s"), "0");
    let stuck: i32 = field(line, "position_counts").parse().expect("a number");
    assert!(seen.state_stalled[1].starts_with("subdevice 1 kind=drive "));
    assert_eq!(field(&seen.state_stalled[1], "stalled"), "0");
    assert_eq!(
        field(&seen.state_stalled[1], "cia402"),
        "switch_on_disabled"
    );
    assert!(seen.state_stalled[2].starts_with("subdevice 2 kind=io "));
    // Every cycle after: the motor stays, velocity 0, the following error is the target
    // less where it stuck; statusword bit 13 beyond the 1000-count window; still
    // Operation enabled (0x27 under 0x6F).
    for (target, inputs) in &seen.jammed {
        assert_eq!((inputs.position, inputs.velocity), (stuck, 0), "{inputs:?}");
        assert_eq!(inputs.following_error, target - stuck, "{inputs:?}");
        assert_eq!(inputs.statusword & 0x006F, 0x0027, "{inputs:?}");
        assert_eq!(
            inputs.statusword & 0x2000 != 0,
            target - stuck > 1000,
            "{inputs:?}"
        );
    }
    let (last_target, last) = *seen.jammed.last().expect("jammed cycles");
    assert!(
        last_target - stuck > 5_000,
        "the error grew to {}",
        last_target - stuck
    );
    // `state` says what the process data says.
    let line = &seen.state_jammed[0];
    assert_eq!(field(line, "position_counts"), stuck.to_string());
    assert_eq!(
        field(line, "following_error_counts"),
        (last_target - stuck).to_string()
    );
    assert_eq!(
        field(line, "statusword"),
        format!("0x{:04X}", last.statusword)
    );
    assert_eq!(field(line, "error_code"), "0x0000");
    assert_eq!(field(line, "watchdog_trips"), "0");
    assert_eq!(field(line, "stopped_ms"), "-");
    // Freed, with the I/O inputs set.
    assert_eq!(field(&seen.state_freed[0], "stalled"), "0");
    assert_eq!(field(&seen.state_freed[2], "inputs"), "0x5A");
    assert_eq!(field(&seen.state_freed[2], "al"), "OP");
    let (target, inputs) = seen.freed;
    assert!((inputs.velocity - 20_000).abs() <= 200, "{inputs:?}");
    assert!((inputs.position - target).abs() <= 50, "{inputs:?}");
    assert_eq!(inputs.statusword & 0x006F, 0x0027, "{inputs:?}");
    assert!(ns.stop_emulator(), "the emulator exits cleanly on SIGTERM");
}

static STORAGE_ACK: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

#[derive(Debug, Default)]
struct AckSeen {
    moving: DriveInputs,
    /// `state` once every watchdog expired and drive 0 came to rest, while muted.
    state_tripped: Vec<String>,
    /// The subdevices' states in tx_rx's answer after `unmute`.
    states_after_unmute: Vec<SubDeviceState>,
    /// `state` after drive 0's acknowledge (0x14) alone.
    state_acknowledged: Vec<String>,
    /// The subdevices' states in tx_rx's answer after the requests for OP.
    states_back: Vec<SubDeviceState>,
    /// `state` back in OP.
    state_back: Vec<String>,
    /// Drive 0 enabled again where it stopped.
    re_enabled: DriveInputs,
    /// And moving again: (target, inputs).
    moving_again: (i32, DriveInputs),
}

/// Writes AL control of the subdevice at `index`.
fn al_control(group: &Group, md: &MainDevice<'_>, index: usize, value: u16) {
    let sd = group.subdevice(md, index).expect("subdevice");
    block_on(sd.register_write(0x0120u16, value)).expect("write AL control");
}

fn run_ack(mut control: Control) -> AckSeen {
    let (md, group) = bring_up(&STORAGE_ACK);
    let mut seen = AckSeen::default();
    enable(&group, &md, 0);
    let mut target = 0;
    for _ in 0..200 {
        target += 20;
        seen.moving = cycle(&group, &md, 0x000F, target);
    }
    // The cable is pulled: nothing reaches the line; its watchdogs (100 ms) expire and
    // drive 0 stops itself. The emulator answers `state` meanwhile.
    control.send("mute");
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let lines = control.state(SUBDEVICES);
        let tripped = lines.iter().all(|l| field(l, "watchdog_trips") == "1");
        if tripped && field(&lines[0], "stopped_ms") != "-" {
            seen.state_tripped = lines;
            break;
        }
        assert!(
            Instant::now() < deadline,
            "no watchdog expiry in 10 s: {lines:?}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    control.send("unmute");
    let deadline = Instant::now() + Duration::from_secs(10);
    while seen.states_after_unmute.is_empty() && Instant::now() < deadline {
        if let Ok(response) = block_on(group.tx_rx(&md)) {
            seen.states_after_unmute = response.subdevice_states.to_vec();
        }
    }
    // Drive 0: acknowledge in SAFE-OP (0x14), then OP (0x08); drive 1 and the I/O:
    // acknowledge and OP in one write (0x18).
    al_control(&group, &md, 0, 0x0014);
    seen.state_acknowledged = control.state(SUBDEVICES);
    al_control(&group, &md, 0, 0x0008);
    al_control(&group, &md, 1, 0x0018);
    al_control(&group, &md, 2, 0x0018);
    let deadline = Instant::now() + Duration::from_secs(10);
    while Instant::now() < deadline {
        // The target stays where the motor stopped (position actual, as a MainDevice
        // does while its drive is disabled).
        let stopped = cycle(&group, &md, 0x0000, target);
        target = stopped.position;
        let response = block_on(group.tx_rx(&md)).expect("tx_rx");
        seen.states_back = response.subdevice_states.to_vec();
        if seen.states_back.iter().all(|s| *s == SubDeviceState::Op) {
            break;
        }
    }
    seen.state_back = control.state(SUBDEVICES);
    seen.re_enabled = enable(&group, &md, target);
    for _ in 0..200 {
        target += 20;
        seen.moving_again = (target, cycle(&group, &md, 0x000F, target));
    }
    seen
}

#[test]
fn after_the_watchdog_an_acknowledge_brings_the_line_back_to_op_and_the_drive_enables_again() {
    let mut ns = Netns::new();
    ns.start_emulator(&["--drives", "2", "--io", "1"]);
    let control = ns.take_emulator_control();
    let seen = ns.run_inside(move || run_ack(control));
    assert!(
        (seen.moving.velocity - 20_000).abs() <= 200,
        "{:?}",
        seen.moving
    );
    // While muted: every subdevice dropped to SAFE-OP with the error indicator and
    // 0x001B (SyncManager watchdog).
    for line in &seen.state_tripped {
        assert_eq!(field(line, "al"), "SAFE-OP", "{line}");
        assert_eq!(field(line, "al_error"), "1", "{line}");
        assert_eq!(field(line, "al_code"), "0x001B", "{line}");
    }
    // Drive 0 stopped by its quick stop: 20 000 counts/s at 1e6 counts/s² takes 20 ms
    // (one more model period at most, for where the expiry fell in a period).
    let drive = &seen.state_tripped[0];
    let stopped_ms: f64 = field(drive, "stopped_ms").parse().expect("a number");
    assert!((20.0..=21.0).contains(&stopped_ms), "{drive}");
    assert_eq!(field(drive, "velocity_counts_s"), "0");
    assert_eq!(field(drive, "cia402"), "switch_on_disabled");
    // Drive 1 was never enabled: at rest at the expiry.
    assert_eq!(field(&seen.state_tripped[1], "stopped_ms"), "0.000");
    // ethercrab sees them in SAFE-OP once the cable is back.
    assert_eq!(seen.states_after_unmute, vec![SubDeviceState::SafeOp; 3]);
    // The acknowledge alone cleared drive 0's error and code; it stayed in SAFE-OP.
    let line = &seen.state_acknowledged[0];
    assert_eq!(
        (
            field(line, "al"),
            field(line, "al_error"),
            field(line, "al_code")
        ),
        ("SAFE-OP", "0", "0x0000"),
        "{line}"
    );
    assert_eq!(field(&seen.state_acknowledged[1], "al_error"), "1");
    // OP again, all of them, with no error; the watchdog count stays.
    assert_eq!(seen.states_back, vec![SubDeviceState::Op; 3]);
    for line in &seen.state_back {
        assert_eq!(field(line, "al"), "OP", "{line}");
        assert_eq!(field(line, "al_error"), "0", "{line}");
        assert_eq!(field(line, "al_code"), "0x0000", "{line}");
        assert_eq!(field(line, "watchdog_trips"), "1", "{line}");
    }
    // The drive behind came back in Switch on disabled (0x40 under 0x4F) and was enabled
    // again by its controlword, where it had stopped, then moved again.
    assert_eq!(field(&seen.state_back[0], "cia402"), "switch_on_disabled");
    assert_eq!(
        seen.re_enabled.statusword & 0x006F,
        0x0027,
        "{:?}",
        seen.re_enabled
    );
    let (target, inputs) = seen.moving_again;
    assert!((inputs.velocity - 20_000).abs() <= 200, "{inputs:?}");
    assert!((inputs.position - target).abs() <= 50, "{inputs:?}");
    assert!(ns.stop_emulator(), "the emulator exits cleanly on SIGTERM");
}
