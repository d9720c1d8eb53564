//! An emulated CiA 402 servo drive: CoE mailbox with its object dictionary, process data
//! packed and unpacked by the current PDO assignment (0x1C12 / 0x1C13) and mapping
//! (0x1600 / 0x1A00, writable in PRE-OP), and behind it `kerf_drive::sim::SimDrive`, which
//! takes one model step per process-data write in OP.
//!
//! Default mapping (the CiA 402 CSP default): RxPDO 0x1600 = 0x6040 controlword (16),
//! 0x607A target position (32); TxPDO 0x1A00 = 0x6041 statusword (16), 0x6064 position
//! actual (32), 0x606C velocity actual (32), 0x60F4 following error actual (32), 0x603F
//! error code (16), 0x60FD digital inputs (32).
//!
//! The process-data watchdog: when it expires, the drive does its own quick stop (the
//! servo model's quick stop at its deceleration, one model period per period of host
//! time), then rests in Switch on disabled. The time from the expiry to the motor at rest
//! is kept ([`DriveSnapshot::stopped_after_ns`]): counted in model periods, so it does not
//! depend on the host's scheduling.
//!
//! A jammed motor ([`DriveDevice::set_stalled`], the emulator's `stall P`): the motor
//! stops dead where it is and no longer moves, whatever the drive commands; the power
//! state machine goes on as before. In Operation enabled the target keeps coming, so the
//! following error (0x60F4, target − position actual) grows with it, and statusword bit
//! 13 (following error) is set while it exceeds the servo model's window
//! (`SimConfig::following_error_window_counts`, 1000 counts by default), exactly as when
//! the motor merely lags. The drive does not trip a fault of its own for it: the servo
//! model has no following-error fault, only the bit, so the reaction is the MainDevice's.
//! A quick stop of a jammed drive ends at once (its motor is at rest). Freed (`free P`), the
//! motor turns again from where it stuck: if the drive is still enabled with a large
//! following error, the servo loop pulls it to the target in one cycle, and beyond
//! about 1600 counts of error (default tuning) that commands more than the overcurrent
//! limit and trips fault 0x2310, as a real drive released under a large error would.
//!
//! Cyclic synchronous velocity (mode 9, 0x6060 written in PRE-OP, as a spindle drive is
//! run): the power state machine is the servo model's, but the motor follows the target
//! velocity 0x60FF (counts/s) instead of a position. While Operation enabled its velocity
//! moves toward the target by at most [`DriveDevice::velocity_accel_counts_s2`] times the
//! period per model step (a ramp: [`DEFAULT_VELOCITY_ACCEL_COUNTS_S2`] unless set, the
//! emulator's `--velocity-accel`); in every other state (a quick stop, a fault, power
//! off) it runs down to rest at the same rate. The position actual integrates the
//! velocity, the following error is 0, statusword bit 12 (drive follows the command value)
//! is set while Operation enabled. A jammed motor stands still (velocity 0).
//!
//! Homing mode (6): the servo model's own homing (`kerf_drive::sim`'s homing, methods
//! 19–22, 35 and 37) with the parameters the MainDevice writes by SDO: method 0x6098,
//! speeds 0x6099:01 (search for the switch) and :02 (search for zero), acceleration
//! 0x609A, home offset 0x607C (a write takes effect at the next start of a homing). The
//! mode is 0x6060, written by SDO or, when the MainDevice maps it in the RxPDO, with every
//! exchange; controlword bit 4 starts the homing, statusword bits 10, 12 and 13 are the
//! homing's (attained, error; bit 13 is not the following error in this mode). The home
//! switch is where [`DriveDevice::set_home_switch`] puts it (the emulator's
//! `--home-switch`), in the motor's own frame; the drive's digital inputs 0x60FD show it
//! in bit 2 (home switch), as CiA 402 assigns it.

use kerf_drive::cia402::{
    Drive, DriveState, HOME_OFFSET_INDEX as HOME_OFFSET,
    HOMING_ACCELERATION_INDEX as HOMING_ACCELERATION, HOMING_METHOD_INDEX as HOMING_METHOD,
    HOMING_SPEEDS_INDEX as HOMING_SPEEDS, MODE_CYCLIC_SYNC_POSITION, MODE_HOMING, cw, sw,
};

/// Mode of operation 9: cyclic synchronous velocity.
pub const MODE_CYCLIC_SYNC_VELOCITY: i8 = 9;

/// The ramp of the motor's velocity in cyclic synchronous velocity unless set otherwise,
/// counts/s²: 1e6, e.g. 6000 rpm/s at 10000 counts per revolution.
pub const DEFAULT_VELOCITY_ACCEL_COUNTS_S2: f64 = 1.0e6;
use kerf_drive::sim::{SimConfig, SimDrive, SimHomingConfig};

/// Digital inputs (0x60FD) bit 2: the home switch.
pub const DIGITAL_INPUT_HOME_SWITCH: u32 = 1 << 2;

use crate::al::AlState;
use crate::coe;
use crate::esc::{AppSnapshot, Application};
use crate::od::{Access, Od};
use crate::sii::{Identity, Pdo, PdoEntry, SiiSpec, SmConfig, SmUsage};

/// Object 0x100A, manufacturer software version: longer than a mailbox on purpose, so
/// that reading it takes a segmented upload (160 bytes). ethercrab 0.7.1 cannot read it:
/// it decodes the upload-segment response's command specifier (0, CiA 301) as an invalid
/// value.
pub const SOFTWARE_VERSION: &str = "kerf-ecat-sim emulated CiA 402 drive: servo model kerf_drive::sim::SimDrive, \
CSP mode 8, one model step per process data write; this text is 160 bytes long.....";

/// Mailbox size each way, bytes.
pub const MAILBOX_LEN: u16 = 128;

/// Entries a PDO mapping object (0x1600, 0x1A00) can hold.
pub const MAPPING_CAPACITY: usize = 16;

const RX_MAPPING: [u32; 2] = [0x6040_0010, 0x607A_0020];
const TX_MAPPING: [u32; 6] = [
    0x6041_0010,
    0x6064_0020,
    0x606C_0020,
    0x60F4_0020,
    0x603F_0010,
    0x60FD_0020,
];

fn entries(mapping: &[u32]) -> Vec<PdoEntry> {
    mapping
        .iter()
        .map(|m| PdoEntry {
            index: (m >> 16) as u16,
            sub_index: (m >> 8) as u8,
            bit_len: *m as u8,
        })
        .collect()
}

fn mapping_bytes(mapping: &[u32]) -> u16 {
    mapping.iter().map(|m| u16::from(*m as u8)).sum::<u16>() / 8
}

/// The emulated drive.
#[derive(Debug)]
pub struct DriveDevice {
    sii: SiiSpec,
    od: Od,
    sdo: coe::SdoServer,
    drive: SimDrive,
    /// Set once the watchdog expired: the time of the last model step of the drive's own
    /// quick stop.
    stopping_since_ns: Option<u64>,
    /// Model steps of the quick stop since the watchdog last expired.
    quick_stop_steps: u64,
    /// From the watchdog's last expiry to the motor at rest, ns of model time.
    stopped_after_ns: Option<u64>,
    /// Where the motor is jammed (`set_stalled`), counts.
    stalled_at_counts: Option<i32>,
    /// A fault injected for the next model step.
    pending_fault: Option<u16>,
    /// In cyclic synchronous velocity: the ramp of the motor's velocity, counts/s².
    velocity_accel_counts_s2: f64,
    /// In cyclic synchronous velocity: the motor's velocity, counts/s.
    csv_velocity_counts_s: f64,
    /// In cyclic synchronous velocity: the motor's position, counts.
    csv_position_counts: f64,
}

/// What a drive shows, for the emulator's `state` command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DriveSnapshot {
    /// The CiA 402 power state.
    pub state: DriveState,
    /// The statusword (0x6041).
    pub statusword: u16,
    /// The error code (0x603F).
    pub error_code: u16,
    /// Position actual (0x6064), counts.
    pub position_counts: i32,
    /// Velocity actual (0x606C), counts/s.
    pub velocity_counts_s: i32,
    /// Following error actual (0x60F4), counts.
    pub following_error_counts: i32,
    /// The motor is jammed.
    pub stalled: bool,
    /// Model time from the process-data watchdog's last expiry to the motor at rest by
    /// the drive's own quick stop, ns; `None` when the watchdog has not expired or the
    /// motor is not at rest yet.
    pub stopped_after_ns: Option<u64>,
    /// The mode of operation (0x6061): 8 position, 9 velocity.
    pub mode: i8,
    /// The target velocity (0x60FF) last written, counts/s (used in mode 9).
    pub target_velocity_counts_s: i32,
    /// The home switch is active (0x60FD bit 2).
    pub home_switch: bool,
    /// The motor's position in its own frame (from power-up, before any homing redefined
    /// the drive's coordinates), counts, rounded.
    pub motor_counts: i32,
}

/// A fresh servo model like `drive` (configuration, mode of operation, power state and
/// error code) but with its motor at rest at `position_counts`. The power state is reached
/// by replaying the controlwords that lead to it, each with `position_counts` as the
/// target, so that the motor does not move on the way; `last_controlword` is the last one
/// replayed in the fault states, so that a fault reset still needs a rising edge of bit 7.
/// A quick stop in progress ends at once (the motor is at rest): Switch on disabled.
fn at_rest(drive: &SimDrive, position_counts: i32, last_controlword: u16) -> SimDrive {
    let mut config = *drive.config();
    config.initial_position_counts = f64::from(position_counts);
    let mut fresh = SimDrive::new(config);
    fresh.set_homing_config(*drive.homing_config());
    fresh.set_mode_of_operation(drive.mode_of_operation_display());
    let enable: &[u16] = &[
        cw::DISABLE_VOLTAGE,
        cw::SHUTDOWN,
        cw::SWITCH_ON_CMD,
        cw::ENABLE_OPERATION_CMD,
    ];
    let replay: &[u16] = match drive.state() {
        DriveState::NotReadyToSwitchOn => &[],
        DriveState::SwitchOnDisabled | DriveState::QuickStopActive => &enable[..1],
        DriveState::ReadyToSwitchOn => &enable[..2],
        DriveState::SwitchedOn => &enable[..3],
        DriveState::OperationEnabled => enable,
        DriveState::FaultReactionActive | DriveState::Fault => {
            fresh.inject_fault(drive.error_code());
            if drive.state() == DriveState::Fault {
                &[last_controlword, last_controlword]
            } else {
                &[last_controlword]
            }
        }
    };
    for &controlword in replay {
        fresh.write(controlword, position_counts);
    }
    fresh
}

impl DriveDevice {
    /// A drive with this identity and name, and this servo model.
    pub fn new(identity: Identity, name: &str, config: SimConfig) -> DriveDevice {
        let sii = SiiSpec {
            identity,
            alias: 0,
            name: name.into(),
            mailbox: Some((0x1000, MAILBOX_LEN, 0x1080, MAILBOX_LEN)),
            sync_managers: vec![
                SmConfig {
                    start: 0x1000,
                    len: MAILBOX_LEN,
                    control: 0x26,
                    usage: SmUsage::MailboxOut,
                },
                SmConfig {
                    start: 0x1080,
                    len: MAILBOX_LEN,
                    control: 0x22,
                    usage: SmUsage::MailboxIn,
                },
                SmConfig {
                    start: 0x1100,
                    len: mapping_bytes(&RX_MAPPING),
                    control: 0x64,
                    usage: SmUsage::Outputs,
                },
                SmConfig {
                    start: 0x1180,
                    len: mapping_bytes(&TX_MAPPING),
                    control: 0x20,
                    usage: SmUsage::Inputs,
                },
            ],
            fmmus: vec![1, 2, 3],
            tx_pdos: vec![Pdo {
                index: 0x1A00,
                sync_manager: 3,
                entries: entries(&TX_MAPPING),
            }],
            rx_pdos: vec![Pdo {
                index: 0x1600,
                sync_manager: 2,
                entries: entries(&RX_MAPPING),
            }],
        };
        let mut od = Od::default();
        od.insert(0x1000, 0, &0x0002_0192u32.to_le_bytes(), Access::ReadOnly);
        od.insert(0x1008, 0, name.as_bytes(), Access::ReadOnly);
        od.insert(0x100A, 0, SOFTWARE_VERSION.as_bytes(), Access::ReadOnly);
        let id = [
            identity.vendor_id,
            identity.product_code,
            identity.revision,
            identity.serial,
        ];
        od.insert_record(0x1018, &id, 4, Access::ReadOnly);
        // The mapping objects hold up to MAPPING_CAPACITY entries, as a drive's do: the
        // defaults, then free subindices.
        for (index, mapping) in [(0x1600, &RX_MAPPING[..]), (0x1A00, &TX_MAPPING[..])] {
            let mut entries = [0u32; MAPPING_CAPACITY];
            entries[..mapping.len()].copy_from_slice(mapping);
            od.insert_record(index, &entries, 4, Access::PreOpOnly);
            od.set(index, 0, &[mapping.len() as u8]);
        }
        od.insert_record(0x1C12, &[0x1600], 2, Access::PreOpOnly);
        od.insert_record(0x1C13, &[0x1A00], 2, Access::PreOpOnly);
        for (index, len, access) in [
            (0x6040u16, 2usize, Access::ReadWrite),
            (0x6041, 2, Access::ReadOnly),
            (0x6060, 1, Access::ReadWrite),
            (0x6061, 1, Access::ReadOnly),
            (0x607A, 4, Access::ReadWrite),
            (0x60FF, 4, Access::ReadWrite),
            (0x6064, 4, Access::ReadOnly),
            (0x606C, 4, Access::ReadOnly),
            (0x60F4, 4, Access::ReadOnly),
            (0x603F, 2, Access::ReadOnly),
            (0x60FD, 4, Access::ReadOnly),
        ] {
            od.insert(index, 0, &vec![0; len], access);
        }
        // The homing objects, at the servo model's defaults.
        let homing = *SimDrive::new(config).homing_config();
        od.insert(HOMING_SPEEDS, 0, &[2], Access::ReadOnly);
        for (index, sub, value) in [
            (HOMING_METHOD, 0, homing.method.to_le_bytes().to_vec()),
            (
                HOMING_SPEEDS,
                1,
                homing.search_speed_counts_s.to_le_bytes().to_vec(),
            ),
            (
                HOMING_SPEEDS,
                2,
                homing.zero_speed_counts_s.to_le_bytes().to_vec(),
            ),
            (
                HOMING_ACCELERATION,
                0,
                homing.acceleration_counts_s2.to_le_bytes().to_vec(),
            ),
            (
                HOME_OFFSET,
                0,
                homing.home_offset_counts.to_le_bytes().to_vec(),
            ),
        ] {
            od.insert(index, sub, &value, Access::ReadWrite);
        }
        od.insert(0x60C2, 0, &[2], Access::ReadOnly);
        od.insert(0x60C2, 1, &[1], Access::PreOpOnly);
        od.insert(0x60C2, 2, &[(-3i8) as u8], Access::PreOpOnly);
        let mut device = DriveDevice {
            sii,
            od,
            sdo: coe::SdoServer::new(MAILBOX_LEN),
            drive: SimDrive::new(config),
            stopping_since_ns: None,
            quick_stop_steps: 0,
            stopped_after_ns: None,
            stalled_at_counts: None,
            pending_fault: None,
            velocity_accel_counts_s2: DEFAULT_VELOCITY_ACCEL_COUNTS_S2,
            csv_velocity_counts_s: 0.0,
            csv_position_counts: 0.0,
        };
        device.refresh_inputs();
        device
    }

    /// The ramp of the motor's velocity in cyclic synchronous velocity, counts/s².
    pub fn velocity_accel_counts_s2(&self) -> f64 {
        self.velocity_accel_counts_s2
    }

    /// Sets the ramp of the motor's velocity in cyclic synchronous velocity, counts/s²
    /// (a value that is not a positive number is ignored).
    pub fn set_velocity_accel_counts_s2(&mut self, accel_counts_s2: f64) {
        if accel_counts_s2.is_finite() && accel_counts_s2 > 0.0 {
            self.velocity_accel_counts_s2 = accel_counts_s2;
        }
    }

    /// Places the home switch at `counts` in the motor's own frame (its position from
    /// power-up), active at and beyond it in the homing method's search direction; `None`
    /// takes it away.
    pub fn set_home_switch(&mut self, counts: Option<f64>) {
        let mut homing = *self.drive.homing_config();
        homing.home_switch_counts = counts;
        self.drive.set_homing_config(homing);
        self.refresh_inputs();
    }

    /// The servo model's homing parameters from the homing objects the MainDevice wrote
    /// (the home switch and the search limit stay the emulator's).
    fn homing_from_objects(&mut self) {
        let od = &self.od;
        let homing = SimHomingConfig {
            method: od.get_u32(HOMING_METHOD, 0) as u8 as i8,
            search_speed_counts_s: od.get_u32(HOMING_SPEEDS, 1),
            zero_speed_counts_s: od.get_u32(HOMING_SPEEDS, 2),
            acceleration_counts_s2: od.get_u32(HOMING_ACCELERATION, 0),
            home_offset_counts: od.get_u32(HOME_OFFSET, 0) as i32,
            ..*self.drive.homing_config()
        };
        self.drive.set_homing_config(homing);
    }

    /// Whether the drive runs in cyclic synchronous velocity.
    fn csv(&self) -> bool {
        self.drive.mode_of_operation_display() == MODE_CYCLIC_SYNC_VELOCITY
    }

    /// The motor's velocity, counts/s, in either mode.
    fn motor_velocity_counts_s(&self) -> f64 {
        if self.csv() {
            self.csv_velocity_counts_s
        } else {
            self.drive.motor_velocity_counts_s()
        }
    }

    /// The position actual the drive reports (0x6064), counts.
    fn position_actual_counts(&self) -> i32 {
        if self.csv() {
            saturate(self.csv_position_counts)
        } else {
            self.drive.position_actual_counts()
        }
    }

    /// The velocity actual the drive reports (0x606C), counts/s.
    fn velocity_actual_counts_s(&self) -> i32 {
        if self.csv() {
            saturate(self.csv_velocity_counts_s)
        } else {
            self.drive.velocity_actual_counts_s()
        }
    }

    /// One model period of the velocity-mode motor after the power state machine's step:
    /// toward the target velocity while Operation enabled, else toward rest, at most
    /// the ramp times the period; a jammed motor stands.
    fn csv_physics(&mut self) {
        let period_s = self.drive.config().period_ns as f64 * 1e-9;
        let target = if self.stalled_at_counts.is_some() {
            self.csv_velocity_counts_s = 0.0;
            return;
        } else if self.drive.state() == DriveState::OperationEnabled {
            f64::from(self.od.get_u32(0x60FF, 0) as i32)
        } else {
            0.0
        };
        let v = self.csv_velocity_counts_s;
        let dv = self.velocity_accel_counts_s2 * period_s;
        let next = if (target - v).abs() <= dv {
            target
        } else {
            v + dv * (target - v).signum()
        };
        self.csv_position_counts += 0.5 * (v + next) * period_s;
        // The position wraps as a 32-bit counter would.
        if self.csv_position_counts.abs() > f64::from(i32::MAX) {
            self.csv_position_counts -= self.csv_position_counts.signum() * 4_294_967_296.0;
        }
        self.csv_velocity_counts_s = next;
    }

    /// The servo model.
    pub fn drive(&self) -> &SimDrive {
        &self.drive
    }

    /// The servo model, mutably (fault injection).
    pub fn drive_mut(&mut self) -> &mut SimDrive {
        &mut self.drive
    }

    /// The mapping entries of the PDOs assigned to `assign` (0x1C12 or 0x1C13).
    fn assigned_mapping(&self, assign: u16) -> Vec<u32> {
        let mut out = Vec::new();
        for i in 1..=self.od.get_u32(assign, 0) as u8 {
            let pdo = self.od.get_u32(assign, i) as u16;
            for j in 1..=self.od.get_u32(pdo, 0) as u8 {
                out.push(self.od.get_u32(pdo, j));
            }
        }
        out
    }

    /// The following error the drive reports (0x60F4): the servo model's, or while the
    /// motor is jammed and the drive follows the target, the target less where the motor
    /// stuck.
    fn following_error_counts(&self) -> i32 {
        if self.csv() {
            return 0;
        }
        let follows = self.drive.state() == DriveState::OperationEnabled
            && self.drive.mode_of_operation_display() == MODE_CYCLIC_SYNC_POSITION;
        match self.stalled_at_counts {
            Some(at) if follows => (self.od.get_u32(0x607A, 0) as i32).saturating_sub(at),
            _ => self.drive.following_error_counts(),
        }
    }

    /// The statusword the drive reports (0x6041): the servo model's, with bit 13
    /// (following error) for the following error reported; in homing mode the servo
    /// model's as it is (bit 13 is the homing error there).
    fn statusword(&self) -> u16 {
        if self.drive.mode_of_operation_display() == MODE_HOMING {
            return self.drive.statusword();
        }
        let window = self.drive.config().following_error_window_counts;
        let beyond = self.following_error_counts().unsigned_abs() > window;
        let follows = self.csv() && self.drive.state() == DriveState::OperationEnabled;
        (self.drive.statusword() & !sw::FOLLOWING_ERROR)
            | if beyond { sw::FOLLOWING_ERROR } else { 0 }
            | if follows { sw::DRIVE_FOLLOWS_TARGET } else { 0 }
    }

    fn refresh_inputs(&mut self) {
        self.od.set(0x6041, 0, &self.statusword().to_le_bytes());
        let d = &self.drive;
        self.od
            .set(0x6061, 0, &d.mode_of_operation_display().to_le_bytes());
        self.od.set(0x603F, 0, &d.error_code().to_le_bytes());
        self.od
            .set(0x6064, 0, &self.position_actual_counts().to_le_bytes());
        self.od
            .set(0x606C, 0, &self.velocity_actual_counts_s().to_le_bytes());
        self.od
            .set(0x60F4, 0, &self.following_error_counts().to_le_bytes());
        let inputs = if self.drive.home_switch_active() {
            DIGITAL_INPUT_HOME_SWITCH
        } else {
            0
        };
        self.od.set(0x60FD, 0, &inputs.to_le_bytes());
    }

    /// Jams the motor where it is (`true`) or lets it turn again (`false`); see the
    /// module documentation.
    pub fn set_stalled(&mut self, stalled: bool) {
        match (stalled, self.stalled_at_counts) {
            (true, None) => {
                let here = self.drive.position_actual_counts();
                let last_controlword = self.od.get_u32(0x6040, 0) as u16;
                self.drive = at_rest(&self.drive, here, last_controlword);
                self.stalled_at_counts = Some(here);
                self.csv_velocity_counts_s = 0.0;
            }
            (false, Some(_)) => self.stalled_at_counts = None,
            _ => {}
        }
        self.refresh_inputs();
    }

    /// What the drive shows now.
    pub fn snapshot(&self) -> DriveSnapshot {
        DriveSnapshot {
            state: self.drive.state(),
            statusword: self.statusword(),
            error_code: self.drive.error_code(),
            position_counts: self.position_actual_counts(),
            velocity_counts_s: self.velocity_actual_counts_s(),
            following_error_counts: self.following_error_counts(),
            stalled: self.stalled_at_counts.is_some(),
            stopped_after_ns: self.stopped_after_ns,
            mode: self.drive.mode_of_operation_display(),
            target_velocity_counts_s: self.od.get_u32(0x60FF, 0) as i32,
            home_switch: self.drive.home_switch_active(),
            motor_counts: if self.csv() {
                saturate(self.csv_position_counts)
            } else {
                saturate(self.drive.motor_frame_position_counts())
            },
        }
    }

    /// One model step with this controlword and target: a jammed motor is held where it
    /// stuck (the model gets that position as its target, so its motor stays put), and an
    /// injected fault trips in this step.
    fn step(&mut self, controlword: u16, target_counts: i32) {
        if let Some(code) = self.pending_fault.take() {
            self.drive.inject_fault(code);
        }
        if self.csv() {
            // The servo model runs the power state machine, holding where it is.
            let here = self.drive.position_actual_counts();
            self.drive.write(controlword, here);
            self.csv_physics();
        } else {
            let target_counts = self.stalled_at_counts.unwrap_or(target_counts);
            self.drive.write(controlword, target_counts);
        }
        self.refresh_inputs();
    }
}

impl DriveDevice {
    /// One model step of the drive's own quick stop after the watchdog expired:
    /// controlword Quick stop (0x0002) with the target where the motor is; notes when the
    /// motor came to rest.
    fn step_quick_stop(&mut self) {
        let here = self.position_actual_counts();
        self.step(cw::QUICK_STOP_CMD, here);
        self.quick_stop_steps += 1;
        self.note_rest();
    }

    /// After the watchdog expired: the motor is at rest, and was not before.
    fn note_rest(&mut self) {
        if self.stopped_after_ns.is_none() && self.motor_velocity_counts_s() == 0.0 {
            let period_ns = self.drive.config().period_ns;
            self.stopped_after_ns = Some(self.quick_stop_steps.saturating_mul(period_ns));
        }
    }
}

/// `value` rounded to the nearest count, saturated to 32 bits (0 for NaN).
fn saturate(value: f64) -> i32 {
    let rounded = value.round();
    if rounded.is_nan() {
        0
    } else {
        rounded.clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
    }
}

/// Walks a mapping over process data bytes: (object index, subindex, byte range).
fn layout(mapping: &[u32]) -> Vec<(u16, u8, core::ops::Range<usize>)> {
    let mut at = 0usize;
    let mut out = Vec::new();
    for m in mapping {
        let len = usize::from(*m as u8) / 8;
        out.push(((m >> 16) as u16, (m >> 8) as u8, at..at + len));
        at += len;
    }
    out
}

impl Application for DriveDevice {
    fn sii(&self) -> &SiiSpec {
        &self.sii
    }

    fn process_data_len(&self) -> (u16, u16) {
        (
            mapping_bytes(&self.assigned_mapping(0x1C12)),
            mapping_bytes(&self.assigned_mapping(0x1C13)),
        )
    }

    fn mailbox(&mut self, request: &[u8], state: AlState) -> Option<Vec<u8>> {
        self.refresh_inputs();
        let mut mode = None;
        let mut homing = false;
        let pre_op = state == AlState::PreOp;
        let response = self.sdo.serve(&mut self.od, request, pre_op, |i, _, v| {
            if i == 0x6060 {
                mode = Some(v[0] as i8);
            }
            homing |= matches!(
                i,
                HOMING_METHOD | HOMING_SPEEDS | HOMING_ACCELERATION | HOME_OFFSET
            );
        });
        if let Some(mode) = mode {
            self.drive.set_mode_of_operation(mode);
        }
        if homing {
            self.homing_from_objects();
        }
        response
    }

    fn outputs(&mut self, data: &[u8], apply: bool, _now_ns: u64) {
        if !apply {
            return;
        }
        let mut mode_mapped = false;
        for (index, sub, range) in layout(&self.assigned_mapping(0x1C12)) {
            if let Some(bytes) = data.get(range) {
                self.od.set(index, sub, bytes);
                mode_mapped |= index == 0x6060;
            }
        }
        if mode_mapped {
            // The mode in the process data: the drive takes it with every exchange.
            self.drive
                .set_mode_of_operation(self.od.get_u32(0x6060, 0) as u8 as i8);
        }
        let controlword = self.od.get_u32(0x6040, 0) as u16;
        let target = self.od.get_u32(0x607A, 0) as i32;
        self.stopping_since_ns = None;
        self.step(controlword, target);
    }

    fn watchdog_expired(&mut self, now_ns: u64) {
        self.stopping_since_ns = Some(now_ns);
        self.quick_stop_steps = 0;
        self.stopped_after_ns = None;
        // A motor already at rest stopped at the expiry.
        self.note_rest();
        self.step_quick_stop();
    }

    fn tick(&mut self, now_ns: u64) {
        let Some(mut since) = self.stopping_since_ns else {
            return;
        };
        let period_ns = self.drive.config().period_ns.max(1);
        // One model period per period of time, as if the drive's own cycle went on.
        while now_ns.saturating_sub(since) >= period_ns {
            since += period_ns;
            self.step_quick_stop();
        }
        self.stopping_since_ns = Some(since);
    }

    fn inject_fault(&mut self, error_code: u16) -> bool {
        self.pending_fault = Some(error_code);
        true
    }

    fn set_stalled(&mut self, stalled: bool) -> bool {
        DriveDevice::set_stalled(self, stalled);
        true
    }

    fn snapshot(&self) -> AppSnapshot {
        AppSnapshot::Drive(DriveDevice::snapshot(self))
    }

    fn inputs(&mut self, data: &mut [u8]) {
        self.refresh_inputs();
        for (index, sub, range) in layout(&self.assigned_mapping(0x1C13)) {
            if let (Ok(value), Some(slot)) = (self.od.read(index, sub), data.get_mut(range)) {
                let n = value.len().min(slot.len());
                slot[..n].copy_from_slice(&value[..n]);
            }
        }
    }

    fn transition(&mut self, from: AlState, to: AlState) {
        // The interpolation period the master wrote in PRE-OP (0x60C2) becomes the servo
        // model's period, as a drive takes its cycle from it: one model period per
        // process-data write.
        if from != AlState::PreOp || to != AlState::SafeOp {
            return;
        }
        let value = u64::from(self.od.get_u32(0x60C2, 1) as u8);
        let exponent = i32::from(self.od.get_u32(0x60C2, 2) as u8 as i8);
        let Some(period_ns) = interpolation_period_ns(value, exponent) else {
            return;
        };
        if period_ns == self.drive.config().period_ns {
            return;
        }
        let mut config = *self.drive.config();
        config.period_ns = period_ns;
        config.initial_position_counts = self.drive.motor_position_counts();
        config.substeps = config.substeps.max(config.min_substeps());
        let mode = self.drive.mode_of_operation_display();
        let homing = *self.drive.homing_config();
        self.drive = SimDrive::new(config);
        self.drive.set_homing_config(homing);
        self.drive.set_mode_of_operation(mode);
        self.refresh_inputs();
    }
}

/// `value · 10^exponent` s in ns, where it is a whole number of ns from 1 ns to 1 s.
fn interpolation_period_ns(value: u64, exponent: i32) -> Option<u64> {
    let shift = exponent + 9;
    if value == 0 || !(0..=9).contains(&shift) {
        return None;
    }
    let ns = value.checked_mul(10u64.pow(shift as u32))?;
    (ns <= 1_000_000_000).then_some(ns)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drive() -> DriveDevice {
        let identity = Identity {
            vendor_id: 1,
            product_code: 2,
            revision: 3,
            serial: 4,
        };
        DriveDevice::new(identity, "test drive", SimConfig::default())
    }

    /// One process-data write in OP with the default mapping: controlword, target.
    fn cycle(d: &mut DriveDevice, controlword: u16, target_counts: i32) -> DriveSnapshot {
        let mut data = [0u8; 6];
        data[..2].copy_from_slice(&controlword.to_le_bytes());
        data[2..].copy_from_slice(&target_counts.to_le_bytes());
        Application::outputs(d, &data, true, 0);
        d.snapshot()
    }

    fn enable(d: &mut DriveDevice, target_counts: i32) -> DriveSnapshot {
        for controlword in [0x0000, 0x0006, 0x0007] {
            cycle(d, controlword, target_counts);
        }
        cycle(d, 0x000F, target_counts)
    }

    /// Enabled at 0 and moving at 20 counts per 1 ms cycle (20 000 counts/s) for 200
    /// cycles; returns the last target.
    fn moving(d: &mut DriveDevice) -> i32 {
        enable(d, 0);
        let mut target = 0;
        for _ in 0..200 {
            target += 20;
            cycle(d, 0x000F, target);
        }
        target
    }

    /// The inputs the MainDevice reads: statusword, position, velocity, following error.
    fn inputs(d: &mut DriveDevice) -> (u16, i32, i32, i32) {
        let mut data = [0u8; 20];
        Application::inputs(d, &mut data);
        let i32_at = |at: usize| i32::from_le_bytes(data[at..at + 4].try_into().unwrap());
        (
            u16::from_le_bytes([data[0], data[1]]),
            i32_at(2),
            i32_at(6),
            i32_at(10),
        )
    }

    #[test]
    fn a_jammed_motor_stays_while_the_target_moves_on_and_the_following_error_grows() {
        let mut d = drive();
        let mut target = moving(&mut d);
        let before = d.snapshot();
        assert_eq!(before.state, DriveState::OperationEnabled);
        assert!(
            (before.velocity_counts_s - 20_000).abs() <= 200,
            "{before:?}"
        );
        d.set_stalled(true);
        let at = d.snapshot();
        assert!(at.stalled);
        assert_eq!(at.position_counts, before.position_counts);
        assert_eq!(at.velocity_counts_s, 0);
        let stuck = at.position_counts;
        for n in 1..=100 {
            target += 20;
            let now = cycle(&mut d, 0x000F, target);
            assert_eq!(now.state, DriveState::OperationEnabled);
            assert_eq!((now.position_counts, now.velocity_counts_s), (stuck, 0));
            assert_eq!(now.following_error_counts, target - stuck, "cycle {n}");
            // Bit 13 once the error is beyond the 1000-count window.
            let bit_13 = now.statusword & 0x2000 != 0;
            assert_eq!(bit_13, target - stuck > 1000, "cycle {n}");
        }
        // The process data says the same.
        let (statusword, position, velocity, following_error) = inputs(&mut d);
        assert_eq!(statusword & 0x006F, 0x0027, "still Operation enabled");
        assert_ne!(statusword & 0x2000, 0);
        assert_eq!((position, velocity), (stuck, 0));
        assert_eq!(following_error, target - stuck);
    }

    #[test]
    fn a_freed_motor_follows_again_from_where_it_stuck() {
        let mut d = drive();
        moving(&mut d);
        d.set_stalled(true);
        let stuck = d.snapshot().position_counts;
        // The MainDevice holds the target where the motor is, then the motor is freed
        // and moves on at 20 counts per cycle.
        cycle(&mut d, 0x000F, stuck);
        d.set_stalled(false);
        assert!(!d.snapshot().stalled);
        let mut target = stuck;
        let mut last = d.snapshot();
        for _ in 0..200 {
            target += 20;
            last = cycle(&mut d, 0x000F, target);
        }
        assert_eq!(last.state, DriveState::OperationEnabled);
        assert!((last.velocity_counts_s - 20_000).abs() <= 200, "{last:?}");
        assert!((last.position_counts - target).abs() <= 50, "{last:?}");
    }

    #[test]
    fn freed_under_a_large_following_error_the_drive_lunges_or_trips_overcurrent() {
        // 2000 counts of error: the servo loop would command 2000 counts in one 1 ms
        // cycle, 2.0e6 counts/s of feed-forward, ~1.3e9 counts/s² (limit 1e9): 0x2310.
        let mut d = drive();
        moving(&mut d);
        d.set_stalled(true);
        let stuck = d.snapshot().position_counts;
        cycle(&mut d, 0x000F, stuck + 2000);
        d.set_stalled(false);
        let after = cycle(&mut d, 0x000F, stuck + 2000);
        assert_eq!(after.state, DriveState::FaultReactionActive, "{after:?}");
        assert_eq!(after.error_code, 0x2310);
        // 500 counts: the motor jumps on towards the target without a fault.
        let mut d = drive();
        moving(&mut d);
        d.set_stalled(true);
        let stuck = d.snapshot().position_counts;
        cycle(&mut d, 0x000F, stuck + 500);
        d.set_stalled(false);
        let mut last = d.snapshot();
        for _ in 0..100 {
            last = cycle(&mut d, 0x000F, stuck + 500);
        }
        assert_eq!(last.state, DriveState::OperationEnabled);
        assert!(
            (last.position_counts - (stuck + 500)).abs() <= 2,
            "{last:?}"
        );
    }

    #[test]
    fn jamming_keeps_the_power_state_the_mode_and_a_fault() {
        // Every state the controlword reaches, jammed, stays that state.
        for (controlwords, state) in [
            (&[][..], DriveState::NotReadyToSwitchOn),
            (&[0x0000][..], DriveState::SwitchOnDisabled),
            (&[0x0000, 0x0006][..], DriveState::ReadyToSwitchOn),
            (&[0x0000, 0x0006, 0x0007][..], DriveState::SwitchedOn),
            (
                &[0x0000, 0x0006, 0x0007, 0x000F][..],
                DriveState::OperationEnabled,
            ),
        ] {
            let mut d = drive();
            for &controlword in controlwords {
                cycle(&mut d, controlword, 0);
            }
            assert_eq!(d.snapshot().state, state);
            d.set_stalled(true);
            assert_eq!(d.snapshot().state, state);
        }
        // A fault stays a fault with its code, and a rising edge of bit 7 resets it.
        let mut d = drive();
        enable(&mut d, 0);
        assert!(Application::inject_fault(&mut d, 0x7500));
        cycle(&mut d, 0x000F, 0);
        let faulted = cycle(&mut d, 0x0000, 0);
        assert_eq!(
            (faulted.state, faulted.error_code),
            (DriveState::Fault, 0x7500)
        );
        d.set_stalled(true);
        let jammed = d.snapshot();
        assert_eq!(
            (jammed.state, jammed.error_code),
            (DriveState::Fault, 0x7500)
        );
        assert_eq!(cycle(&mut d, 0x0000, 0).state, DriveState::Fault);
        let reset = cycle(&mut d, 0x0080, 0);
        assert_eq!(
            (reset.state, reset.error_code),
            (DriveState::SwitchOnDisabled, 0)
        );
        // And a jammed drive can be enabled, without moving.
        let enabled = enable(&mut d, 0);
        assert_eq!(enabled.state, DriveState::OperationEnabled);
        assert_eq!(enabled.position_counts, 0);
    }

    #[test]
    fn after_the_watchdog_the_quick_stop_time_to_rest_is_kept() {
        let mut d = drive();
        moving(&mut d);
        // 20 000 counts/s at the quick-stop deceleration 1e6 counts/s²: 20 ms.
        let expiry_ns = 5_000_000_000;
        Application::watchdog_expired(&mut d, expiry_ns);
        assert_eq!(d.snapshot().stopped_after_ns, None);
        Application::tick(&mut d, expiry_ns + 10_000_000);
        assert_eq!(
            d.snapshot().stopped_after_ns,
            None,
            "still braking at 10 ms"
        );
        Application::tick(&mut d, expiry_ns + 30_000_000);
        let stopped = d.snapshot();
        assert_eq!(stopped.velocity_counts_s, 0);
        assert_eq!(stopped.state, DriveState::SwitchOnDisabled);
        let stopped_ns = stopped.stopped_after_ns.expect("at rest");
        assert!(
            (20_000_000..=21_000_000).contains(&stopped_ns),
            "{stopped_ns} ns"
        );
        // However late the loop ticks, the time is the model's.
        let mut late = drive();
        moving(&mut late);
        Application::watchdog_expired(&mut late, expiry_ns);
        Application::tick(&mut late, expiry_ns + 500_000_000);
        assert_eq!(late.snapshot().stopped_after_ns, Some(stopped_ns));
        // A drive at rest at the expiry stopped at once; a jammed one too.
        let mut idle = drive();
        enable(&mut idle, 0);
        Application::watchdog_expired(&mut idle, expiry_ns);
        assert_eq!(idle.snapshot().stopped_after_ns, Some(0));
        let mut jammed = drive();
        moving(&mut jammed);
        jammed.set_stalled(true);
        Application::watchdog_expired(&mut jammed, expiry_ns);
        assert_eq!(jammed.snapshot().stopped_after_ns, Some(0));
    }

    /// A drive mapped for cyclic synchronous velocity (controlword, target velocity) in
    /// mode 9, as the MainDevice configures a spindle drive in PRE-OP.
    fn velocity_drive() -> DriveDevice {
        let mut d = drive();
        d.od.insert_record(0x1600, &[0x6040_0010, 0x60FF_0020], 4, Access::PreOpOnly);
        d.drive_mut()
            .set_mode_of_operation(MODE_CYCLIC_SYNC_VELOCITY);
        d
    }

    #[test]
    fn in_velocity_mode_the_motor_ramps_to_the_target_velocity_and_back_to_rest() {
        let mut d = velocity_drive();
        // Enabled, then 500 000 counts/s commanded: at the default 1e6 counts/s² and a
        // 1 ms period the velocity gains 1000 counts/s per cycle, so 250 000 after 250
        // cycles and the target after 500, where it stays.
        let enabled = enable(&mut d, 0);
        assert_eq!(enabled.state, DriveState::OperationEnabled);
        assert_eq!(enabled.mode, 9);
        assert_ne!(
            enabled.statusword & 0x1000,
            0,
            "bit 12: follows the command"
        );
        let mut last = enabled;
        for n in 1..=600 {
            last = cycle(&mut d, 0x000F, 500_000);
            if n == 250 {
                assert_eq!(last.velocity_counts_s, 250_000);
            }
        }
        assert_eq!(last.velocity_counts_s, 500_000);
        assert_eq!(last.target_velocity_counts_s, 500_000);
        assert_eq!(last.following_error_counts, 0);
        // The position integrates the ramp (a triangle of 500 000 counts/s over 0.5 s:
        // 125 000 counts) and then 100 cycles at full speed (50 000 counts).
        assert_eq!(last.position_counts, 175_000);
        // The process data carries it: velocity actual at bytes 6..10.
        let (statusword, _, velocity, following_error) = inputs(&mut d);
        assert_eq!(statusword & 0x006F, 0x0027);
        assert_eq!((velocity, following_error), (500_000, 0));
        // Disable voltage: the drive is off and the motor runs down at the same rate.
        let off = cycle(&mut d, 0x0000, 500_000);
        assert_eq!(off.state, DriveState::SwitchOnDisabled);
        assert_eq!(off.velocity_counts_s, 499_000);
        for _ in 0..499 {
            last = cycle(&mut d, 0x0000, 500_000);
        }
        assert_eq!(last.velocity_counts_s, 0);
    }

    #[test]
    fn in_velocity_mode_a_reversal_passes_through_rest_and_the_ramp_can_be_set() {
        let mut d = velocity_drive();
        d.set_velocity_accel_counts_s2(2.0e6);
        d.set_velocity_accel_counts_s2(f64::NAN);
        assert_eq!(d.velocity_accel_counts_s2(), 2.0e6);
        enable(&mut d, 0);
        for _ in 0..100 {
            cycle(&mut d, 0x000F, 100_000);
        }
        // 2000 counts/s per cycle: at +100 000 after 50 cycles; to -100 000 takes 100.
        assert_eq!(d.snapshot().velocity_counts_s, 100_000);
        let mut seen_rest = false;
        for _ in 0..100 {
            let s = cycle(&mut d, 0x000F, -100_000);
            seen_rest |= s.velocity_counts_s == 0;
        }
        assert!(seen_rest);
        assert_eq!(d.snapshot().velocity_counts_s, -100_000);
        // A jammed spindle stands at once.
        d.set_stalled(true);
        assert_eq!(cycle(&mut d, 0x000F, -100_000).velocity_counts_s, 0);
    }

    #[test]
    fn in_velocity_mode_the_watchdog_stop_runs_the_motor_down_and_times_it() {
        let mut d = velocity_drive();
        enable(&mut d, 0);
        for _ in 0..200 {
            cycle(&mut d, 0x000F, 200_000);
        }
        // 200 000 counts/s at 1e6 counts/s²: 200 ms to rest.
        let expiry_ns = 1_000_000_000;
        Application::watchdog_expired(&mut d, expiry_ns);
        Application::tick(&mut d, expiry_ns + 300_000_000);
        let stopped = d.snapshot();
        assert_eq!(stopped.velocity_counts_s, 0);
        let ns = stopped.stopped_after_ns.expect("at rest");
        assert!((200_000_000..=201_000_000).contains(&ns), "{ns} ns");
    }

    #[test]
    fn interpolation_periods_are_value_times_a_power_of_ten_seconds() {
        // 1 · 10⁻³ s = 1 ms; 25 · 10⁻⁵ s = 250 µs; 4 · 10⁻³ s = 4 ms.
        assert_eq!(interpolation_period_ns(1, -3), Some(1_000_000));
        assert_eq!(interpolation_period_ns(25, -5), Some(250_000));
        assert_eq!(interpolation_period_ns(4, -3), Some(4_000_000));
        // Nothing, sub-nanosecond, or longer than a second is not a drive's cycle.
        assert_eq!(interpolation_period_ns(0, -3), None);
        assert_eq!(interpolation_period_ns(1, -10), None);
        assert_eq!(interpolation_period_ns(2, 0), None);
    }

    /// An expedited SDO download of `value` (1, 2 or 4 bytes) to `index:sub` in PRE-OP,
    /// as a MainDevice writes it; panics on an abort.
    fn sdo_write(d: &mut DriveDevice, index: u16, sub: u8, value: &[u8]) {
        let command = 0x23 | ((4 - value.len() as u8) << 2);
        let mut sdo = vec![command, index as u8, (index >> 8) as u8, sub];
        sdo.extend_from_slice(value);
        sdo.resize(8, 0);
        let mut m = 10u16.to_le_bytes().to_vec();
        m.extend_from_slice(&[0x00, 0x00, 0x00, 0x23, 0x00, 0x20]);
        m.extend_from_slice(&sdo);
        m.resize(usize::from(MAILBOX_LEN), 0);
        let out = Application::mailbox(d, &m, AlState::PreOp).expect("an answer");
        assert_eq!(out[8] & 0xE0, 0x60, "{index:#06x}:{sub} aborted: {out:?}");
    }

    /// One exchange with the mode in the process data (RxPDO: controlword, target
    /// position, modes of operation): the statusword, 0x60FD and the snapshot after it.
    fn cycle_in(d: &mut DriveDevice, controlword: u16, target: i32, mode: i8) -> DriveSnapshot {
        let mut data = [0u8; 7];
        data[..2].copy_from_slice(&controlword.to_le_bytes());
        data[2..6].copy_from_slice(&target.to_le_bytes());
        data[6] = mode as u8;
        Application::outputs(d, &data, true, 0);
        d.snapshot()
    }

    #[test]
    fn homing_mode_in_the_process_data_homes_on_the_switch_with_the_objects_written_by_sdo() {
        let mut d = drive();
        d.od.insert_record(
            0x1600,
            &[0x6040_0010, 0x607A_0020, 0x6060_0008],
            4,
            Access::PreOpOnly,
        );
        d.set_home_switch(Some(3000.0));
        // Method 19 (positive home switch), 20 000 counts/s to the switch, 2000 back
        // to its edge, 400 000 counts/s², home offset 1000 counts.
        sdo_write(&mut d, 0x6098, 0, &[19]);
        sdo_write(&mut d, 0x6099, 1, &20_000u32.to_le_bytes());
        sdo_write(&mut d, 0x6099, 2, &2_000u32.to_le_bytes());
        sdo_write(&mut d, 0x609A, 0, &400_000u32.to_le_bytes());
        sdo_write(&mut d, 0x607C, 0, &1000i32.to_le_bytes());
        for controlword in [0x0000, 0x0006, 0x0007, 0x000F] {
            cycle_in(&mut d, controlword, 0, MODE_CYCLIC_SYNC_POSITION);
        }
        assert!(!d.snapshot().home_switch);
        // Homing mode from the process data, then bit 4's rising edge starts it.
        let entered = cycle_in(&mut d, 0x000F, 0, MODE_HOMING);
        assert_eq!(entered.mode, MODE_HOMING);
        let mut last = entered;
        let mut saw_switch = false;
        let mut cycles = 0;
        while last.statusword & (1 << 12) == 0 {
            last = cycle_in(&mut d, 0x001F, 0, MODE_HOMING);
            saw_switch |= last.home_switch;
            assert_eq!(last.statusword & (1 << 13), 0, "homing error: {last:?}");
            cycles += 1;
            assert!(cycles < 10_000, "never attained: {last:?}");
        }
        assert!(saw_switch, "the switch never showed in the inputs");
        // At rest on the switch's edge, which now reads as the home offset.
        assert_eq!(last.statusword & (1 << 10), 1 << 10, "{last:?}");
        assert!((last.position_counts - 1000).abs() <= 1, "{last:?}");
        assert!((last.motor_counts - 3000).abs() <= 1, "{last:?}");
        let mut inputs = [0u8; 20];
        Application::inputs(&mut d, &mut inputs);
        let digital = u32::from_le_bytes(inputs[16..20].try_into().unwrap());
        assert_eq!(
            digital & DIGITAL_INPUT_HOME_SWITCH != 0,
            last.home_switch,
            "0x60FD bit 2"
        );
        // Back to cyclic synchronous position through the process data.
        let back = cycle_in(
            &mut d,
            0x000F,
            last.position_counts,
            MODE_CYCLIC_SYNC_POSITION,
        );
        assert_eq!(back.mode, MODE_CYCLIC_SYNC_POSITION);
        assert_eq!(back.state, DriveState::OperationEnabled);
    }
}
