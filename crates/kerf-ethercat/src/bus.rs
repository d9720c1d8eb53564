//! The bus: bring-up from kerf.toml's `[ethercat]` table to OP, and the cyclic exchange.
//!
//! Bring-up, in the order of ETG.1020 and of the drive manuals:
//! 1. scan the ring and read every subdevice's SII (ethercrab's `init`, to PRE-OP);
//! 2. compare every position's identity with the configuration and refuse, listing found
//!    against expected, on any difference ([`crate::identity::compare`]);
//! 3. in PRE-OP, per subdevice: the configured start-up SDOs in order; for a drive, the
//!    PDO mapping (mapping object entries, then the assignment 0x1C12/0x1C13), the mode
//!    of operation 0x6060 and the interpolation period 0x60C2 = the cycle period; the
//!    process-data watchdog (register 0x0420);
//! 4. SAFE-OP (process data sized from the PDO assignment), then OP.
//!
//! Every refusal names the subdevice, its position and what failed; an SDO abort is shown
//! with its code in words, as ethercrab decodes them (ETG.1000.6).
//!
//! The pump runs on the calling thread: bring-up and the cyclic exchange are driven by the
//! thread that owns the `Bus`, with no executor or helper thread (see [`crate::pump`]).

use std::time::Duration;

use ethercrab::subdevice_group::{Op, PreOp};
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, SubDeviceGroup, Timeouts};
use kerf_config::ethercat::{EthercatConfig, Pdo, SdoValue, SdoWrite};
use thiserror::Error;

use crate::identity::{Expected, Found, compare};
use crate::image::DriveImage;
use crate::pdo::{
    DriveLayout, INTERPOLATION_PERIOD, LayoutError, MODES_OF_OPERATION, SM2_ASSIGNMENT,
    SM3_ASSIGNMENT, interpolation_period,
};
use crate::pump::{Pump, PumpError};
use crate::socket::RawSocket;

/// Most subdevices on one bus.
pub const MAX_SUBDEVICES: usize = 32;
/// Most bytes of process data (inputs and outputs) on one bus.
pub const MAX_PDI_BYTES: usize = 2048;
/// Frames in flight at most.
const MAX_FRAMES: usize = 16;
/// Bytes of datagram data per frame.
const FRAME_DATA: usize = PduStorage::element_size(1100);
/// The SyncManager watchdog time register (ETG.1000.4, units of the watchdog divider).
const SM_WATCHDOG_REGISTER: u16 = 0x0420;
/// The axes' letters, by index.
const AXIS_LETTERS: [char; 6] = ['X', 'Y', 'Z', 'A', 'B', 'C'];

type Storage = PduStorage<MAX_FRAMES, FRAME_DATA>;
/// The bus's group of subdevices, in state `S` (PRE-OP by default).
pub(crate) type Group<S = PreOp> =
    SubDeviceGroup<MAX_SUBDEVICES, MAX_PDI_BYTES, ethercrab::DefaultLock, S>;

/// Why the bus did not come up.
#[derive(Debug, Error)]
pub enum BringUpError {
    /// The interface could not be opened.
    #[error("EtherCAT interface {interface}: {source}")]
    Interface {
        /// The interface.
        interface: String,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The frames did not go round in a step.
    #[error("{step}: {source}")]
    Pump {
        /// The step.
        step: String,
        /// What happened.
        #[source]
        source: PumpError,
    },
    /// ethercrab reported an error in a step.
    #[error("{step}: {source}")]
    Step {
        /// The step, naming the subdevice where there is one.
        step: String,
        /// ethercrab's error (an SDO abort carries its code in words).
        #[source]
        source: ethercrab::error::Error,
    },
    /// The bus does not hold what the configuration says.
    #[error("the EtherCAT bus differs from the configuration:\n  {}", .lines.join("\n  "))]
    Mismatch {
        /// One line per differing position.
        lines: Vec<String>,
    },
    /// A drive's PDO mapping lacks what the control needs.
    #[error("{name} (position {position}): {source}")]
    Layout {
        /// The drive.
        name: String,
        /// Its position.
        position: u16,
        /// What is wrong.
        #[source]
        source: LayoutError,
    },
    /// The period cannot be written as the drives' interpolation period.
    #[error(
        "the cycle period of {period_ns} ns is not 1 to 255 times a power of ten seconds, so it cannot be the drives' interpolation period (0x60C2)"
    )]
    Period {
        /// The period.
        period_ns: u64,
    },
}

/// What one cyclic exchange brought back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Exchange {
    /// The working counter of the process data.
    pub working_counter: u16,
    /// The ring position of the first subdevice not in OP (it left OP: a watchdog, an
    /// error of its own), if any.
    pub not_op: Option<u16>,
}

/// One drive on the bus.
#[derive(Debug, Clone, Copy)]
struct BusDrive {
    /// Index of the subdevice in the group (ring order = position).
    group_index: usize,
    /// The axis it drives.
    axis: usize,
}

/// A running bus in OP.
pub struct Bus {
    maindevice: MainDevice<'static>,
    group: Group<Op>,
    pump: Pump,
    drives: Vec<BusDrive>,
    found: Vec<Found>,
}

impl std::fmt::Debug for Bus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bus")
            .field("found", &self.found)
            .field("pump", &self.pump)
            .finish_non_exhaustive()
    }
}

/// The name of a drive in messages: "X drive".
pub fn drive_name(axis: usize) -> String {
    format!("{} drive", AXIS_LETTERS.get(axis).copied().unwrap_or('?'))
}

/// Every subdevice the configuration expects, with its name for messages.
pub fn expected(config: &EthercatConfig) -> Vec<Expected> {
    let drives = config.drives.iter().map(|d| Expected {
        position: d.position,
        name: drive_name(d.axis_index),
        identity: d.identity,
    });
    let io = config.io.iter().map(|io| Expected {
        position: io.position,
        name: "I/O".to_owned(),
        identity: io.identity,
    });
    drives.chain(io).collect()
}

/// Opens the interface and the MainDevice. The storage for frames lives as long as the
/// process: a few tens of kB, once per bus opened.
pub(crate) fn open(
    interface: &str,
    timeouts: Timeouts,
) -> Result<(MainDevice<'static>, Pump), BringUpError> {
    let socket = RawSocket::open(interface).map_err(|source| BringUpError::Interface {
        interface: interface.to_owned(),
        source,
    })?;
    let storage: &'static Storage = Box::leak(Box::new(Storage::new()));
    let (tx, rx, pdu_loop) = storage.try_split().map_err(|()| BringUpError::Step {
        step: "frame storage".to_owned(),
        source: ethercrab::error::Error::Internal,
    })?;
    let maindevice = MainDevice::new(pdu_loop, timeouts, MainDeviceConfig::default());
    Ok((maindevice, Pump::new(socket, tx, rx)))
}

/// Runs one bring-up step on the pump: `timeout` bounds it even where ethercrab's own
/// timeouts would not.
pub(crate) fn run<T, F>(
    pump: &mut Pump,
    step: impl Fn() -> String,
    future: F,
    timeout: Duration,
) -> Result<T, BringUpError>
where
    F: Future<Output = Result<T, ethercrab::error::Error>>,
{
    pump.block_on(future, timeout)
        .map_err(|source| BringUpError::Pump {
            step: step(),
            source,
        })?
        .map_err(|source| BringUpError::Step {
            step: step(),
            source,
        })
}

pub(crate) fn scan_group(
    maindevice: &MainDevice<'static>,
    pump: &mut Pump,
    timeout: Duration,
) -> Result<Group<PreOp>, BringUpError> {
    run(
        pump,
        || "scanning the bus".to_owned(),
        maindevice.init_single_group::<MAX_SUBDEVICES, MAX_PDI_BYTES>(ethercrab::std::ethercat_now),
        timeout,
    )
}

/// Scans the bus on `interface` and reads every subdevice's identity, leaving the bus in
/// PRE-OP (the `kerf ethercat scan` view).
pub fn scan(interface: &str) -> Result<Vec<Found>, BringUpError> {
    let timeouts = Timeouts::default();
    let (maindevice, mut pump) = open(interface, timeouts)?;
    let group = scan_group(&maindevice, &mut pump, timeouts.state_transition * 2)?;
    Ok(found_of(&group, &maindevice))
}

pub(crate) fn found_of(group: &Group<PreOp>, maindevice: &MainDevice<'static>) -> Vec<Found> {
    group
        .iter(maindevice)
        .enumerate()
        .map(|(i, s)| {
            let id = s.identity();
            Found {
                position: u16::try_from(i).unwrap_or(u16::MAX),
                name: s.name().to_owned(),
                vendor_id: id.vendor_id,
                product_code: id.product_id,
                revision: id.revision,
                serial: id.serial,
            }
        })
        .collect()
}

impl Bus {
    /// Brings the bus of `config` to OP for a cycle of `period_ns`; see the module's steps.
    pub fn bring_up(config: &EthercatConfig, period_ns: u64) -> Result<Bus, BringUpError> {
        let timeouts = Timeouts {
            state_transition: Duration::from_millis(u64::from(config.state_timeout_ms)),
            mailbox_response: Duration::from_millis(u64::from(config.sdo_timeout_ms)),
            ..Timeouts::default()
        };
        // The pump's own bound on a step: twice ethercrab's, so ethercrab's error (which
        // says more) comes first.
        let state_bound = timeouts.state_transition * 2;
        let sdo_bound = timeouts.mailbox_response * 2;
        let (maindevice, mut pump) = open(&config.interface, timeouts)?;
        let group = scan_group(&maindevice, &mut pump, state_bound)?;
        let found = found_of(&group, &maindevice);
        compare(&found, &expected(config)).map_err(|lines| BringUpError::Mismatch { lines })?;
        let period = interpolation_period(period_ns).ok_or(BringUpError::Period { period_ns })?;
        let watchdog = config.watchdog_intervals();

        let mut drives = Vec::new();
        for e in expected(config) {
            let at = |what: String| format!("{} (position {}): {what}", e.name, e.position);
            let handle = group
                .subdevice(&maindevice, usize::from(e.position))
                .map_err(|source| BringUpError::Step {
                    step: at("not found".to_owned()),
                    source,
                })?;
            let drive = config.drives.iter().find(|d| d.position == e.position);
            let io = config.io.iter().find(|io| io.position == e.position);
            let sdo: &[SdoWrite] = match (drive, io) {
                (Some(d), _) => &d.sdo,
                (None, Some(io)) => &io.sdo,
                (None, None) => &[],
            };
            for write in sdo {
                let step = || {
                    at(format!(
                        "start-up SDO {:#06x}:{}",
                        write.index, write.subindex
                    ))
                };
                run(&mut pump, step, sdo_write(&handle, *write), sdo_bound)?;
            }
            let Some(drive) = drive else { continue };
            DriveLayout::new(&drive.rx_pdo, &drive.tx_pdo).map_err(|source| {
                BringUpError::Layout {
                    name: e.name.clone(),
                    position: e.position,
                    source,
                }
            })?;
            for write in drive_writes(
                &drive.rx_pdo,
                &drive.tx_pdo,
                drive.mode.mode_of_operation(),
                period,
            ) {
                let step = || at(format!("SDO {:#06x}:{}", write.index, write.subindex));
                run(&mut pump, step, sdo_write(&handle, write), sdo_bound)?;
            }
            run(
                &mut pump,
                || at("process-data watchdog (register 0x0420)".to_owned()),
                handle.register_write(SM_WATCHDOG_REGISTER, watchdog),
                sdo_bound,
            )?;
            drives.push(BusDrive {
                group_index: usize::from(e.position),
                axis: drive.axis_index,
            });
        }

        let group = run(
            &mut pump,
            || "PRE-OP to SAFE-OP".to_owned(),
            group.into_safe_op(&maindevice),
            state_bound,
        )?;
        let group = run(
            &mut pump,
            || "SAFE-OP to OP".to_owned(),
            group.into_op(&maindevice),
            state_bound,
        )?;
        Ok(Bus {
            maindevice,
            group,
            pump,
            drives,
            found,
        })
    }

    /// The subdevices found, in ring order.
    pub fn found(&self) -> &[Found] {
        &self.found
    }

    /// The images of the drives of `config`, indexed by axis.
    pub fn drive_images(config: &EthercatConfig) -> Result<Vec<Option<DriveImage>>, LayoutError> {
        let mut images = vec![None; kerf_drive::MAX_AXES];
        for d in &config.drives {
            if let Some(slot) = images.get_mut(d.axis_index) {
                *slot = Some(DriveImage::new(
                    DriveLayout::new(&d.rx_pdo, &d.tx_pdo)?,
                    d.mode.mode_of_operation(),
                ));
            }
        }
        Ok(images)
    }

    /// Writes `image`'s outputs into the process data of the drive of `axis` (sent by the
    /// next [`Bus::tx_rx`]); nothing when the bus has no drive for it.
    pub fn write_outputs(&self, axis: usize, image: &DriveImage) {
        if let Some(d) = self.drives.iter().find(|d| d.axis == axis)
            && let Ok(sub) = self.group.subdevice(&self.maindevice, d.group_index)
        {
            image.write_outputs(sub.io_raw_mut().outputs());
        }
    }

    /// Reads the inputs of the drive of `axis` from the last exchange into `image`.
    pub fn read_inputs(&self, axis: usize, image: &mut DriveImage) {
        if let Some(d) = self.drives.iter().find(|d| d.axis == axis)
            && let Ok(sub) = self.group.subdevice(&self.maindevice, d.group_index)
        {
            image.read_inputs(sub.io_raw().inputs());
        }
    }

    /// One exchange of the whole process data (one LRW where it fits a frame, with every
    /// subdevice's AL status read in the same frame), waiting at most `timeout` for it to
    /// come back.
    pub fn tx_rx(&mut self, timeout: Duration) -> Result<Exchange, PumpError> {
        let response = self
            .pump
            .block_on(self.group.tx_rx(&self.maindevice), timeout)?
            .map_err(PumpError::Frame)?;
        let not_op = response
            .subdevice_states
            .iter()
            .position(|s| *s != ethercrab::SubDeviceState::Op)
            .and_then(|i| u16::try_from(i).ok());
        Ok(Exchange {
            working_counter: response.working_counter,
            not_op,
        })
    }

    /// One cyclic exchange with `images` indexed by axis: their outputs written, the
    /// process data exchanged, their inputs read. Returns the working counter.
    pub fn exchange(
        &mut self,
        images: &mut [Option<DriveImage>],
        timeout: Duration,
    ) -> Result<u16, PumpError> {
        for (axis, image) in images.iter().enumerate() {
            if let Some(image) = image {
                self.write_outputs(axis, image);
            }
        }
        let wkc = self.tx_rx(timeout)?.working_counter;
        for (axis, image) in images.iter_mut().enumerate() {
            if let Some(image) = image {
                self.read_inputs(axis, image);
            }
        }
        Ok(wkc)
    }

    /// The working counter of a complete exchange: per subdevice 1 for its inputs read and
    /// 2 for its outputs written, as a logical read-write (LRW) counts them.
    pub fn expected_working_counter(&self) -> u16 {
        self.group
            .iter(&self.maindevice)
            .map(|s| {
                let io = s.io_raw();
                u16::from(!io.inputs().is_empty()) + 2 * u16::from(!io.outputs().is_empty())
            })
            .sum()
    }
}

/// The SDO writes that configure a drive in PRE-OP: for each direction the assignment
/// cleared, the mapping object's count cleared, its entries, its count, the assignment of
/// that one mapping object; then the mode of operation and the interpolation period.
pub fn drive_writes(rx: &Pdo, tx: &Pdo, mode: i8, period: (u8, i8)) -> Vec<SdoWrite> {
    let mut writes = Vec::new();
    let w = |index, subindex, value| SdoWrite {
        index,
        subindex,
        value,
    };
    for (assignment, pdo) in [(SM2_ASSIGNMENT, rx), (SM3_ASSIGNMENT, tx)] {
        writes.push(w(assignment, 0, SdoValue::U8(0)));
        writes.push(w(pdo.index, 0, SdoValue::U8(0)));
        for (i, entry) in pdo.entries.iter().enumerate() {
            let subindex = u8::try_from(i + 1).unwrap_or(u8::MAX);
            writes.push(w(pdo.index, subindex, SdoValue::U32(entry.mapping_value())));
        }
        let count = u8::try_from(pdo.entries.len()).unwrap_or(u8::MAX);
        writes.push(w(pdo.index, 0, SdoValue::U8(count)));
        writes.push(w(assignment, 1, SdoValue::U16(pdo.index)));
        writes.push(w(assignment, 0, SdoValue::U8(1)));
    }
    writes.push(w(MODES_OF_OPERATION, 0, SdoValue::I8(mode)));
    writes.push(w(INTERPOLATION_PERIOD, 1, SdoValue::U8(period.0)));
    writes.push(w(INTERPOLATION_PERIOD, 2, SdoValue::I8(period.1)));
    writes
}

pub(crate) async fn sdo_write<S>(
    handle: &ethercrab::SubDeviceRef<'_, S>,
    write: SdoWrite,
) -> Result<(), ethercrab::error::Error>
where
    S: std::ops::Deref<Target = ethercrab::SubDevice>,
{
    let (i, s) = (write.index, write.subindex);
    match write.value {
        SdoValue::U8(v) => handle.sdo_write(i, s, v).await,
        SdoValue::U16(v) => handle.sdo_write(i, s, v).await,
        SdoValue::U32(v) => handle.sdo_write(i, s, v).await,
        SdoValue::I8(v) => handle.sdo_write(i, s, v).await,
        SdoValue::I16(v) => handle.sdo_write(i, s, v).await,
        SdoValue::I32(v) => handle.sdo_write(i, s, v).await,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerf_config::ethercat::DriveMode;

    #[test]
    fn a_csp_drive_is_configured_as_its_manual_lists_the_writes() {
        let writes = drive_writes(
            &Pdo::default_rx(DriveMode::Csp),
            &Pdo::default_tx(),
            8,
            (1, -3),
        );
        let as_tuples: Vec<(u16, u8, SdoValue)> = writes
            .iter()
            .map(|w| (w.index, w.subindex, w.value))
            .collect();
        use SdoValue::*;
        let expected = vec![
            (0x1C12, 0, U8(0)),
            (0x1600, 0, U8(0)),
            (0x1600, 1, U32(0x6040_0010)),
            (0x1600, 2, U32(0x607A_0020)),
            (0x1600, 0, U8(2)),
            (0x1C12, 1, U16(0x1600)),
            (0x1C12, 0, U8(1)),
            (0x1C13, 0, U8(0)),
            (0x1A00, 0, U8(0)),
            (0x1A00, 1, U32(0x6041_0010)),
            (0x1A00, 2, U32(0x6064_0020)),
            (0x1A00, 3, U32(0x606C_0020)),
            (0x1A00, 4, U32(0x60F4_0020)),
            (0x1A00, 5, U32(0x603F_0010)),
            (0x1A00, 6, U32(0x60FD_0020)),
            (0x1A00, 0, U8(6)),
            (0x1C13, 1, U16(0x1A00)),
            (0x1C13, 0, U8(1)),
            (0x6060, 0, I8(8)),
            (0x60C2, 1, U8(1)),
            (0x60C2, 2, I8(-3)),
        ];
        assert_eq!(as_tuples, expected);
    }

    #[test]
    fn drives_are_named_by_their_axis() {
        assert_eq!(drive_name(0), "X drive");
        assert_eq!(drive_name(5), "C drive");
    }
}
