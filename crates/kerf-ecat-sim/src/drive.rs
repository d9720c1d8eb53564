//! An emulated CiA 402 servo drive: CoE mailbox with its object dictionary, process data
//! packed and unpacked by the current PDO assignment (0x1C12 / 0x1C13) and mapping
//! (0x1600 / 0x1A00, writable in PRE-OP), and behind it `kerf_drive::sim::SimDrive`, which
//! takes one model step per process-data write in OP.
//!
//! Default mapping (the CiA 402 CSP default): RxPDO 0x1600 = 0x6040 controlword (16),
//! 0x607A target position (32); TxPDO 0x1A00 = 0x6041 statusword (16), 0x6064 position
//! actual (32), 0x606C velocity actual (32), 0x60F4 following error actual (32), 0x603F
//! error code (16), 0x60FD digital inputs (32).

use kerf_drive::cia402::Drive;
use kerf_drive::sim::{SimConfig, SimDrive};

use crate::al::AlState;
use crate::coe;
use crate::esc::Application;
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
        od.insert_record(0x1600, &RX_MAPPING, 4, Access::PreOpOnly);
        od.insert_record(0x1A00, &TX_MAPPING, 4, Access::PreOpOnly);
        od.insert_record(0x1C12, &[0x1600], 2, Access::PreOpOnly);
        od.insert_record(0x1C13, &[0x1A00], 2, Access::PreOpOnly);
        for (index, len, access) in [
            (0x6040u16, 2usize, Access::ReadWrite),
            (0x6041, 2, Access::ReadOnly),
            (0x6060, 1, Access::ReadWrite),
            (0x6061, 1, Access::ReadOnly),
            (0x607A, 4, Access::ReadWrite),
            (0x6064, 4, Access::ReadOnly),
            (0x606C, 4, Access::ReadOnly),
            (0x60F4, 4, Access::ReadOnly),
            (0x603F, 2, Access::ReadOnly),
            (0x60FD, 4, Access::ReadOnly),
        ] {
            od.insert(index, 0, &vec![0; len], access);
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
        };
        device.refresh_inputs();
        device
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

    fn refresh_inputs(&mut self) {
        let d = &self.drive;
        self.od.set(0x6041, 0, &d.statusword().to_le_bytes());
        self.od
            .set(0x6061, 0, &d.mode_of_operation_display().to_le_bytes());
        self.od
            .set(0x6064, 0, &d.position_actual_counts().to_le_bytes());
        self.od
            .set(0x606C, 0, &d.velocity_actual_counts_s().to_le_bytes());
        self.od
            .set(0x60F4, 0, &d.following_error_counts().to_le_bytes());
        self.od.set(0x603F, 0, &d.error_code().to_le_bytes());
    }
}

impl DriveDevice {
    /// One model step of the drive's own quick stop: controlword Quick stop (0x0002)
    /// with the target where the motor is.
    fn step_quick_stop(&mut self) {
        let here = self.drive.position_actual_counts();
        self.drive
            .write(kerf_drive::cia402::cw::QUICK_STOP_CMD, here);
        self.refresh_inputs();
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
        let pre_op = state == AlState::PreOp;
        let response = self.sdo.serve(&mut self.od, request, pre_op, |i, _, v| {
            if i == 0x6060 {
                mode = Some(v[0] as i8);
            }
        });
        if let Some(mode) = mode {
            self.drive.set_mode_of_operation(mode);
        }
        response
    }

    fn outputs(&mut self, data: &[u8], apply: bool, _now_ns: u64) {
        if !apply {
            return;
        }
        for (index, sub, range) in layout(&self.assigned_mapping(0x1C12)) {
            if let Some(bytes) = data.get(range) {
                self.od.set(index, sub, bytes);
            }
        }
        let controlword = self.od.get_u32(0x6040, 0) as u16;
        let target = self.od.get_u32(0x607A, 0) as i32;
        self.stopping_since_ns = None;
        self.drive.write(controlword, target);
        self.refresh_inputs();
    }

    fn watchdog_expired(&mut self, now_ns: u64) {
        self.stopping_since_ns = Some(now_ns);
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
        self.drive.inject_fault(error_code);
        true
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
        self.drive = SimDrive::new(config);
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
    use super::interpolation_period_ns;

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
}
