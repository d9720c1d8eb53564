//! The bus: bring-up from kerf.toml's `[ethercat]` table to OP, and the cyclic exchange.
//!
//! Bring-up, in the order of ETG.1020 and of the drive manuals:
//! 1. scan the ring and read every subdevice's SII (ethercrab's `init`, to PRE-OP);
//! 2. compare every position's identity with the configuration and refuse, listing found
//!    against expected, on any difference ([`crate::identity::compare`]);
//! 3. in PRE-OP, per subdevice: the configured start-up SDOs in order; for a drive, the
//!    PDO mapping (mapping object entries, then the assignment 0x1C12/0x1C13), the mode
//!    of operation 0x6060 and the interpolation period 0x60C2 = the cycle period; for a
//!    drive that homes itself, its homing objects (0x6098, 0x6099, 0x609A, 0x607C,
//!    [`homing_writes`]); the process-data watchdog (register 0x0420);
//! 4. with distributed clocks (`dc = true`): every drive set to run on SYNC0, SYNC0
//!    programmed at the cycle period, and the bus cycled until every subdevice's clock
//!    agrees with the reference's (register 0x092C within [`SETTLED_NS`]) and the host's
//!    cycle is locked onto SYNC0 ([`crate::dc::PhaseLock`]), within `dc_settle_timeout_ms`;
//! 5. SAFE-OP (process data sized from the PDO assignment), then OP (with distributed
//!    clocks while cycling, so that the drives see SYNC0 and frames together).
//!
//! Every refusal names the subdevice, its position and what failed; an SDO abort is shown
//! with its code in words, as ethercrab decodes them (ETG.1000.6).
//!
//! The pump runs on the calling thread: bring-up and the cyclic exchange are driven by the
//! thread that owns the `Bus`, with no executor or helper thread (see [`crate::pump`]).

mod clocked;
mod configure;

use std::time::Duration;

use ethercrab::subdevice_group::{HasDc, NoDc, Op, PreOp};
use ethercrab::{
    MainDevice, MainDeviceConfig, PduStorage, SubDeviceGroup, SubDeviceState, Timeouts,
};
use kerf_config::ethercat::{DriveMode, EthercatConfig, SPINDLE_AXIS_INDEX, SdoWrite};
use thiserror::Error;

pub use clocked::SETTLED_NS;
pub(crate) use configure::sdo_write;
pub use configure::{drive_writes, homing_writes};

use crate::al::{
    AL_ACKNOWLEDGE, AL_CONTROL_REGISTER, ERROR_FLAG, al_code_text, read_status, state_text,
};
use crate::claim::Claim;
use crate::dc::PhaseLock;
use crate::identity::{Expected, Found, compare};
use crate::image::{DriveImage, SpindleImage};
use crate::iomap::IoMap;
use crate::pdo::{DriveLayout, LayoutError, SpindleLayout, interpolation_period};
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
/// The bus's group of subdevices, in state `S` (PRE-OP by default), with distributed
/// clocks configured (`D` = [`HasDc`]) or not.
pub(crate) type Group<S = PreOp, D = NoDc> =
    SubDeviceGroup<MAX_SUBDEVICES, MAX_PDI_BYTES, ethercrab::DefaultLock, S, D>;

/// The group in OP, cycled with or without distributed clocks.
enum Cyclic {
    Free(Group<Op>),
    Clocked(Group<Op, HasDc>),
}

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
    /// A drive cannot run on SYNC0.
    #[error(
        "{name} (position {position}) has no distributed clock: it cannot run on SYNC0; set `ethercat.dc = false` or use a drive with DC"
    )]
    NoClock {
        /// The drive.
        name: String,
        /// Its position.
        position: u16,
    },
    /// The clocks did not settle in time.
    #[error("distributed clocks did not settle within {timeout_ms} ms: {what}")]
    Unsettled {
        /// `dc_settle_timeout_ms`.
        timeout_ms: u32,
        /// What was still off.
        what: String,
    },
    /// A subdevice did not reach a state.
    #[error("{name} (position {position}) stopped in {state}: AL status code {code}")]
    State {
        /// The subdevice.
        name: String,
        /// Its position.
        position: u16,
        /// The state it is in (with "+ error" when its error flag is set).
        state: String,
        /// Its AL status code in words.
        code: String,
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
    /// Every subdevice's state (AL status: 1 INIT, 2 PRE-OP, 3 BOOT, 4 SAFE-OP, 8 OP), by
    /// position; the first [`Bus::len`] are the bus's.
    pub states: [u8; MAX_SUBDEVICES],
    /// With distributed clocks: the offset of the cycle's start from `sync0_shift_ns`
    /// before SYNC0 (positive = late), and the correction of the next start, ns; `None`
    /// also when the frame's round trip was too long to measure it
    /// ([`PhaseLock::update`]).
    pub dc: Option<DcSample>,
}

/// What one exchange came to, for the supervision.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Back in time, every subdevice in OP and taking part.
    Complete,
    /// Back, but the subdevice at this position is not in OP.
    NotOp(u16),
    /// Back with a working counter short of the bus's: a subdevice did not take part.
    Short,
    /// Not back in time.
    Lost,
}

/// Classifies an exchange's result against the bus's complete working counter
/// ([`Bus::expected_working_counter`]).
pub fn outcome(result: &Result<Exchange, PumpError>, expected_working_counter: u16) -> Outcome {
    match result {
        Ok(Exchange {
            not_op: Some(position),
            ..
        }) => Outcome::NotOp(*position),
        Ok(e) if e.working_counter == expected_working_counter => Outcome::Complete,
        Ok(_) => Outcome::Short,
        Err(_) => Outcome::Lost,
    }
}

/// One cycle's measurement of the distributed clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DcSample {
    /// The cycle start's offset from where it should be, ns (positive = late).
    pub offset_ns: i64,
    /// What to add to the next cycle's start, ns.
    pub correction_ns: i64,
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
    group: Cyclic,
    pump: Pump,
    drives: Vec<BusDrive>,
    found: Vec<Found>,
    /// The names of the subdevices by position, for messages, and their configured
    /// station addresses.
    names: Vec<(String, u16)>,
    /// With distributed clocks: the loop that keeps the host's cycle on SYNC0, and the
    /// host time of the first cycle start it computed.
    lock: Option<(PhaseLock, u64)>,
}

impl std::fmt::Debug for Bus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bus")
            .field("found", &self.found)
            .field("pump", &self.pump)
            .finish_non_exhaustive()
    }
}

/// The name of a drive in messages: "X drive", "spindle drive".
pub fn drive_name(axis: usize) -> String {
    if axis == SPINDLE_AXIS_INDEX {
        return "spindle drive".to_owned();
    }
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

/// ethercrab's timeouts for every bring-up and commissioning step, its defaults but for
/// the EEPROM: ethercrab bounds each SII read's whole polling loop, frames included, by
/// it, and its default of 10 ms fails a healthy subdevice whenever the host stalls that
/// long (a busy machine without real-time scheduling).
pub(crate) fn timeouts() -> Timeouts {
    Timeouts {
        eeprom: Duration::from_millis(200),
        ..Timeouts::default()
    }
}

/// Opens the interface and the MainDevice. The storage for frames lives as long as the
/// process: a few tens of kB, once per bus opened.
pub(crate) fn open(
    claim: &Claim,
    timeouts: Timeouts,
) -> Result<(MainDevice<'static>, Pump), BringUpError> {
    let interface = claim.interface();
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
pub fn scan(claim: &Claim) -> Result<Vec<Found>, BringUpError> {
    let timeouts = timeouts();
    let (maindevice, mut pump) = open(claim, timeouts)?;
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
    /// `claim` is the caller's claim on the configuration's interface, held as long as the
    /// bus runs (the caller keeps it, so that no other program sends frames on it).
    pub fn bring_up(
        config: &EthercatConfig,
        period_ns: u64,
        claim: &Claim,
    ) -> Result<Bus, BringUpError> {
        if claim.interface() != config.interface {
            return Err(BringUpError::Interface {
                interface: config.interface.clone(),
                source: std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    format!("not claimed: the claim held is on {}", claim.interface()),
                ),
            });
        }
        let timeouts = Timeouts {
            state_transition: Duration::from_millis(u64::from(config.state_timeout_ms)),
            mailbox_response: Duration::from_millis(u64::from(config.sdo_timeout_ms)),
            ..timeouts()
        };
        // The pump's own bound on a step: twice ethercrab's, so ethercrab's error (which
        // says more) comes first.
        let state_bound = timeouts.state_transition * 2;
        let sdo_bound = timeouts.mailbox_response * 2;
        let (maindevice, mut pump) = open(claim, timeouts)?;
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
            let layout = match drive.mode {
                DriveMode::Csp => DriveLayout::new(&drive.rx_pdo, &drive.tx_pdo).map(|_| ()),
                DriveMode::Csv => SpindleLayout::new(&drive.rx_pdo, &drive.tx_pdo).map(|_| ()),
            };
            layout.map_err(|source| BringUpError::Layout {
                name: e.name.clone(),
                position: e.position,
                source,
            })?;
            let writes = drive_writes(
                &drive.rx_pdo,
                &drive.tx_pdo,
                drive.mode.mode_of_operation(),
                period,
            );
            for write in writes
                .into_iter()
                .chain(homing_writes(drive.homing.as_ref()))
            {
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

        let names = names_by_position(config, &group, &maindevice);
        let mut bus = if config.dc {
            Bus::clocked(config, period_ns, maindevice, pump, group, &drives, names)?
        } else {
            let group = transition(
                &maindevice,
                &mut pump,
                &names,
                "PRE-OP to SAFE-OP",
                group.into_safe_op(&maindevice),
                state_bound,
            )?;
            let group = transition(
                &maindevice,
                &mut pump,
                &names,
                "SAFE-OP to OP",
                group.into_op(&maindevice),
                state_bound,
            )?;
            Bus {
                maindevice,
                group: Cyclic::Free(group),
                pump,
                drives: Vec::new(),
                found: Vec::new(),
                names,
                lock: None,
            }
        };
        bus.drives = drives;
        bus.found = found;
        Ok(bus)
    }

    /// A failed state change says where it stopped: the first subdevice not in the state
    /// wanted, its state and its AL status code in words (ethercrab itself only says that
    /// the change timed out).
    fn named<T>(
        maindevice: &MainDevice<'static>,
        pump: &mut Pump,
        names: &[(String, u16)],
        step: Result<T, BringUpError>,
    ) -> Result<T, BringUpError> {
        let Err(error) = step else { return step };
        for (position, (name, address)) in names.iter().enumerate() {
            let Ok(position) = u16::try_from(position) else {
                break;
            };
            let status = read_status(maindevice, pump, *address, Duration::from_millis(200), 3);
            if let Some((al_status, code)) = status
                && (al_status & ERROR_FLAG != 0 || code != 0)
            {
                return Err(BringUpError::State {
                    name: name.clone(),
                    position,
                    state: state_text(al_status),
                    code: al_code_text(code),
                });
            }
        }
        Err(error)
    }

    /// With distributed clocks, the host time (`CLOCK_MONOTONIC`, ns) at which the cycle's
    /// clock must start so that it begins locked onto SYNC0; `None` without.
    pub fn first_cycle_start_ns(&self) -> Option<u64> {
        self.lock.map(|(_, first)| first)
    }

    /// With distributed clocks, the last offset measured of the cycle start from its place
    /// before SYNC0, ns (positive = late); `None` without.
    pub fn dc_offset_ns(&self) -> Option<i64> {
        self.lock.map(|(lock, _)| lock.last_offset_ns())
    }

    /// Subdevices on the bus.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether the bus has no subdevice (never, once up).
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// The name of the subdevice at `position` in messages ("Y drive", "I/O").
    pub fn name(&self, position: u16) -> &str {
        self.names
            .get(usize::from(position))
            .map_or("subdevice", |(name, _)| name.as_str())
    }

    /// Reads the AL status (state, error flag) and the AL status code of the subdevice at
    /// `position`: one frame's round trip, outside the cycle's exchange (after a subdevice
    /// left OP). `None` when no answer came within `timeout`.
    pub fn status_of(&mut self, position: u16, timeout: Duration) -> Option<(u8, u16)> {
        let address = self.names.get(usize::from(position))?.1;
        read_status(&self.maindevice, &mut self.pump, address, timeout, 1)
    }

    /// Asks the subdevice at `position` for `state` (2 PRE-OP, 4 SAFE-OP, 8 OP),
    /// acknowledging its error: one frame's round trip. Whether it answered.
    pub fn request_state(&mut self, position: u16, state: u8, timeout: Duration) -> bool {
        let Some(sub) = subdevice_of(&self.group, &self.maindevice, usize::from(position)) else {
            return false;
        };
        let control = u16::from(state) | AL_ACKNOWLEDGE;
        matches!(
            self.pump
                .block_on(sub.register_write(AL_CONTROL_REGISTER, control), timeout),
            Ok(Ok(_))
        )
    }

    /// The subdevices found, in ring order.
    pub fn found(&self) -> &[Found] {
        &self.found
    }

    /// The images of the axes' drives of `config`, indexed by axis (X to C; the
    /// spindle's is [`Bus::spindle_image`]).
    pub fn drive_images(config: &EthercatConfig) -> Result<Vec<Option<DriveImage>>, LayoutError> {
        let mut images = vec![None; kerf_drive::MAX_AXES];
        for d in config.drives.iter().filter(|d| d.mode == DriveMode::Csp) {
            if let Some(slot) = images.get_mut(d.axis_index) {
                *slot = Some(DriveImage::new(
                    DriveLayout::new(&d.rx_pdo, &d.tx_pdo)?,
                    d.mode.mode_of_operation(),
                ));
            }
        }
        Ok(images)
    }

    /// The image of the spindle's drive of `config` (`axis = "s"`, cyclic synchronous
    /// velocity), if the bus has one.
    pub fn spindle_image(config: &EthercatConfig) -> Result<Option<SpindleImage>, LayoutError> {
        config
            .spindle_drive()
            .map(|d| {
                Ok(SpindleImage::new(
                    SpindleLayout::new(&d.rx_pdo, &d.tx_pdo)?,
                    d.mode.mode_of_operation(),
                ))
            })
            .transpose()
    }

    /// Writes the spindle image's outputs into the spindle drive's process data (sent by
    /// the next [`Bus::tx_rx`]); nothing when the bus has no spindle drive.
    pub fn write_spindle(&self, image: &SpindleImage) {
        let Some(d) = self.drives.iter().find(|d| d.axis == SPINDLE_AXIS_INDEX) else {
            return;
        };
        if let Some(sub) = subdevice_of(&self.group, &self.maindevice, d.group_index) {
            image.write_outputs(sub.io_raw_mut().outputs());
        }
    }

    /// Reads the spindle drive's inputs from the last exchange into `image`.
    pub fn read_spindle(&self, image: &mut SpindleImage) {
        let Some(d) = self.drives.iter().find(|d| d.axis == SPINDLE_AXIS_INDEX) else {
            return;
        };
        if let Some(sub) = subdevice_of(&self.group, &self.maindevice, d.group_index) {
            image.read_inputs(sub.io_raw().inputs());
        }
    }

    /// Writes the machine's `digital_outputs` (bit n: `[io]` output n) into the output bits
    /// `map` links them to (sent by the next [`Bus::tx_rx`]). Allocation-free.
    pub fn write_io(&self, map: &IoMap, digital_outputs: u64) {
        for &position in map.output_positions() {
            if let Some(sub) = subdevice_of(&self.group, &self.maindevice, usize::from(position)) {
                map.write_outputs(position, digital_outputs, sub.io_raw_mut().outputs());
            }
        }
    }

    /// The machine's digital inputs (bit n: `[io]` input n) as the last exchange brought
    /// them from the input bits `map` links them to; inputs not on the bus read as off.
    /// Allocation-free.
    pub fn read_io(&self, map: &IoMap) -> u64 {
        let mut inputs = 0;
        for &position in map.input_positions() {
            if let Some(sub) = subdevice_of(&self.group, &self.maindevice, usize::from(position)) {
                map.read_inputs(position, sub.io_raw().inputs(), &mut inputs);
            }
        }
        inputs
    }

    /// Writes `image`'s outputs into the process data of the drive of `axis` (sent by the
    /// next [`Bus::tx_rx`]); nothing when the bus has no drive for it.
    pub fn write_outputs(&self, axis: usize, image: &DriveImage) {
        let Some(d) = self.drives.iter().find(|d| d.axis == axis) else {
            return;
        };
        if let Some(sub) = subdevice_of(&self.group, &self.maindevice, d.group_index) {
            image.write_outputs(sub.io_raw_mut().outputs());
        }
    }

    /// Reads the inputs of the drive of `axis` from the last exchange into `image`.
    pub fn read_inputs(&self, axis: usize, image: &mut DriveImage) {
        let Some(d) = self.drives.iter().find(|d| d.axis == axis) else {
            return;
        };
        if let Some(sub) = subdevice_of(&self.group, &self.maindevice, d.group_index) {
            image.read_inputs(sub.io_raw().inputs());
        }
    }

    /// One exchange of the whole process data (one LRW where it fits a frame, with every
    /// subdevice's AL status read in the same frame; with distributed clocks also the
    /// reference's system time), waiting at most `timeout` for it to come back.
    /// The cycle is taken to have started now; see [`Bus::tx_rx_at`].
    pub fn tx_rx(&mut self, timeout: Duration) -> Result<Exchange, PumpError> {
        self.tx_rx_at(kerf_rt::now_ns(), timeout)
    }

    /// [`Bus::tx_rx`] in a cycle that was to start at `start_ns` (host `CLOCK_MONOTONIC`):
    /// with distributed clocks, the offset and the next start's correction are measured
    /// against it.
    pub fn tx_rx_at(&mut self, start_ns: u64, timeout: Duration) -> Result<Exchange, PumpError> {
        match &self.group {
            Cyclic::Free(group) => {
                let response = self
                    .pump
                    .block_on(group.tx_rx(&self.maindevice), timeout)?
                    .map_err(PumpError::Frame)?;
                Ok(exchange_of(
                    response.working_counter,
                    &response.subdevice_states,
                    None,
                ))
            }
            Cyclic::Clocked(group) => {
                let Some((lock, _)) = self.lock.as_mut() else {
                    return Err(PumpError::Frame(ethercrab::error::Error::Internal));
                };
                let (exchange, _) = clocked::cycle_dc_exchange(
                    &self.maindevice,
                    &mut self.pump,
                    group,
                    lock,
                    start_ns,
                    timeout,
                )?;
                Ok(exchange)
            }
        }
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
        let count =
            |inputs: usize, outputs: usize| u16::from(inputs > 0) + 2 * u16::from(outputs > 0);
        match &self.group {
            Cyclic::Free(g) => g
                .iter(&self.maindevice)
                .map(|s| count(s.io_raw().inputs().len(), s.io_raw().outputs().len()))
                .sum(),
            Cyclic::Clocked(g) => g
                .iter(&self.maindevice)
                .map(|s| count(s.io_raw().inputs().len(), s.io_raw().outputs().len()))
                .sum(),
        }
    }
}

/// Runs a state change of the group ([`run`]); a failure names the subdevice that stopped
/// ([`Bus::named`]).
pub(crate) fn transition<T, F>(
    maindevice: &MainDevice<'static>,
    pump: &mut Pump,
    names: &[(String, u16)],
    step: &str,
    future: F,
    bound: Duration,
) -> Result<T, BringUpError>
where
    F: Future<Output = Result<T, ethercrab::error::Error>>,
{
    let result = run(pump, || step.to_owned(), future, bound);
    Bus::named(maindevice, pump, names, result)
}

/// The subdevice at group index `index` of `group`, whichever way it is cycled.
fn subdevice_of<'a>(
    group: &'a Cyclic,
    maindevice: &'a MainDevice<'static>,
    index: usize,
) -> Option<
    ethercrab::SubDeviceRef<'a, ethercrab::SubDevicePdi<'a, MAX_PDI_BYTES, ethercrab::DefaultLock>>,
> {
    match group {
        Cyclic::Free(g) => g.subdevice(maindevice, index),
        Cyclic::Clocked(g) => g.subdevice(maindevice, index),
    }
    .ok()
}

/// The names of the subdevices by position: the configuration's ("X drive", "I/O"), else
/// "subdevice"; with their configured station addresses.
fn names_by_position(
    config: &EthercatConfig,
    group: &Group<PreOp>,
    maindevice: &MainDevice<'static>,
) -> Vec<(String, u16)> {
    let mut names: Vec<(String, u16)> = group
        .iter(maindevice)
        .map(|s| ("subdevice".to_owned(), s.configured_address()))
        .collect();
    for e in expected(config) {
        if let Some(n) = names.get_mut(usize::from(e.position)) {
            n.0 = e.name;
        }
    }
    names
}

/// An exchange's outcome from ethercrab's response.
fn exchange_of(working_counter: u16, states: &[SubDeviceState], dc: Option<DcSample>) -> Exchange {
    let mut by_position = [0u8; MAX_SUBDEVICES];
    for (slot, state) in by_position.iter_mut().zip(states) {
        *slot = u8::from(*state);
    }
    let not_op = states
        .iter()
        .position(|s| *s != SubDeviceState::Op)
        .and_then(|i| u16::try_from(i).ok());
    Exchange {
        working_counter,
        not_op,
        states: by_position,
        dc,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drives_are_named_by_their_axis() {
        assert_eq!(drive_name(0), "X drive");
        assert_eq!(drive_name(5), "C drive");
        assert_eq!(drive_name(SPINDLE_AXIS_INDEX), "spindle drive");
    }
}
