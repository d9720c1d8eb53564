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

use std::time::Duration;

use ethercrab::subdevice_group::{DcConfiguration, HasDc, HasPdi, NoDc, Op, PreOp};
use ethercrab::{
    DcSync, MainDevice, MainDeviceConfig, PduStorage, RegisterAddress, SubDeviceGroup,
    SubDeviceState, Timeouts,
};
use kerf_config::ethercat::{EthercatConfig, Pdo, SdoValue, SdoWrite};
use thiserror::Error;

use crate::claim::Claim;
use crate::dc::PhaseLock;
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
/// A subdevice's clock has settled when its system time difference (0x092C) is within
/// this, ns.
pub const SETTLED_NS: u32 = 1_000;
/// The AL control register (ETG.1000.4): the state requested, bit 4 acknowledges an error.
const AL_CONTROL_REGISTER: u16 = 0x0120;
/// AL control's error acknowledge bit.
const AL_ACKNOWLEDGE: u16 = 0x0010;
/// The system time difference register of a subdevice's clock (ETG.1000.4).
const DC_DIFFERENCE_REGISTER: u16 = 0x092C;
/// Cycles in a row the host's cycle must stay locked before the bus goes to SAFE-OP.
const LOCKED_CYCLES: u32 = 100;
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

/// One cycle's measurement of the distributed clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DcSample {
    /// The cycle start's offset from where it should be, ns (positive = late).
    pub offset_ns: i64,
    /// What to add to the next cycle's start, ns.
    pub correction_ns: i64,
}

/// An AL state (the low four bits of the AL status) by its name: "SAFE-OP".
pub fn state_name(al_status: u8) -> &'static str {
    match al_status & 0x0F {
        1 => "INIT",
        2 => "PRE-OP",
        3 => "BOOT",
        4 => "SAFE-OP",
        8 => "OP",
        _ => "an unknown state",
    }
}

/// The state of a subdevice in words, "+ error" when its error flag is set.
pub fn state_text(al_status: u8) -> String {
    let state = state_name(al_status);
    if al_status & 0x10 != 0 {
        format!("{state} + error")
    } else {
        state.to_owned()
    }
}

/// An AL status code (register 0x0134) in words, as ETG.1000.6 names it:
/// "0x001B (sync manager watchdog)".
pub fn al_code_text(code: u16) -> String {
    use ethercrab::EtherCrabWireRead;
    match ethercrab::AlStatusCode::unpack_from_slice(&code.to_le_bytes()) {
        Ok(ethercrab::AlStatusCode::Unknown(_)) | Err(_) => format!("{code:#06x}"),
        Ok(c) => format!("{code:#06x} ({})", words_of(&c)),
    }
}

/// ethercrab's name of a code, in lower case words ("SyncManagerWatchdog" becomes "sync
/// manager watchdog").
fn words_of(code: &ethercrab::AlStatusCode) -> String {
    let name = format!("{code:?}");
    let mut words = String::new();
    for (i, c) in name.chars().enumerate() {
        if c.is_ascii_uppercase() && i > 0 {
            words.push(' ');
        }
        words.push(c.to_ascii_lowercase());
    }
    words
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

        let names = names_by_position(config, &group, &maindevice);
        let mut bus = if config.dc {
            Bus::clocked(config, period_ns, maindevice, pump, group, &drives, names)?
        } else {
            let step = run(
                &mut pump,
                || "PRE-OP to SAFE-OP".to_owned(),
                group.into_safe_op(&maindevice),
                state_bound,
            );
            let group = Bus::named(&maindevice, &mut pump, &names, step)?;
            let step = run(
                &mut pump,
                || "SAFE-OP to OP".to_owned(),
                group.into_op(&maindevice),
                state_bound,
            );
            let group = Bus::named(&maindevice, &mut pump, &names, step)?;
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
            let status = read_status(maindevice, pump, *address);
            if let Some((al_status, code)) = status
                && (al_status & 0x10 != 0 || code != 0)
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

    /// Steps 4 and 5 with distributed clocks: SYNC0 on every drive, the clocks settled and
    /// the host's cycle locked onto SYNC0, then SAFE-OP and OP while cycling.
    fn clocked(
        config: &EthercatConfig,
        period_ns: u64,
        maindevice: MainDevice<'static>,
        mut pump: Pump,
        mut group: Group<PreOp>,
        drives: &[BusDrive],
        names: Vec<(String, u16)>,
    ) -> Result<Bus, BringUpError> {
        let state_bound = Duration::from_millis(u64::from(config.state_timeout_ms)) * 2;
        for (position, mut sub) in group.iter_mut(&maindevice).enumerate() {
            if !drives.iter().any(|d| d.group_index == position) {
                continue;
            }
            if !sub.dc_support().any() {
                return Err(BringUpError::NoClock {
                    name: names[position].0.clone(),
                    position: u16::try_from(position).unwrap_or(u16::MAX),
                });
            }
            sub.set_dc_sync(DcSync::Sync0);
        }
        let group = run(
            &mut pump,
            || "process data image".to_owned(),
            group.into_pre_op_pdi(&maindevice),
            state_bound,
        )?;
        let group = run(
            &mut pump,
            || "distributed clocks: SYNC0".to_owned(),
            group.configure_dc_sync(
                &maindevice,
                DcConfiguration {
                    // SYNC0 starts once the clocks have had time to settle.
                    start_delay: Duration::from_millis(100),
                    sync0_period: Duration::from_nanos(period_ns),
                    sync0_shift: Duration::ZERO,
                },
            ),
            state_bound,
        )?;
        let mut lock = PhaseLock::new(period_ns, u64::from(config.sync0_shift_ns));
        let mut clock = kerf_rt::PeriodicClock::new(period_ns)
            .map_err(|_| BringUpError::Period { period_ns })?;
        let timeout = Duration::from_nanos(period_ns / 2);
        let settle_ms = config.dc_settle_timeout_ms;
        let settle_cycles = u64::from(settle_ms) * 1_000_000 / period_ns;
        // Settle: every subdevice's clock within SETTLED_NS of the reference's, and the
        // host's cycle within a tenth of a period of its place in LOCKED_CYCLES measured
        // cycles in a row.
        let mut locked = 0u32;
        let mut cycle = 0u64;
        let mut worst_clock: Option<(usize, i64)> = None;
        let mut last_offset = None;
        loop {
            if cycle > settle_cycles {
                let what = match (worst_clock, last_offset) {
                    (Some((position, difference)), _) => format!(
                        "{} (position {position}) differs from the reference clock by {difference} ns (at most {SETTLED_NS} ns allowed)",
                        names[position].0
                    ),
                    (None, Some(offset)) => format!(
                        "the cycle does not keep its place before SYNC0: last offset {:.1} µs (a tenth of the period allowed; see docs/ETHERCAT.md on preparing the NIC)",
                        offset as f64 / 1000.0
                    ),
                    (None, None) => "no frame came back".to_owned(),
                };
                return Err(BringUpError::Unsettled {
                    timeout_ms: settle_ms,
                    what,
                });
            }
            cycle += 1;
            let tick = clock.wait_next();
            let measured = cycle_dc(
                &maindevice,
                &mut pump,
                &group,
                &mut lock,
                tick.deadline_ns,
                timeout,
            );
            // A round trip too long to measure, or a frame lost, gives no verdict (the
            // cyclic supervision, not the settling, is about lost frames).
            if let Ok((_, Some(sample))) = measured {
                clock.shift_next(sample.correction_ns);
                last_offset = Some(sample.offset_ns);
                let in_place = sample.offset_ns.unsigned_abs() < period_ns / 10;
                locked = if in_place { locked + 1 } else { 0 };
            }
            if locked >= LOCKED_CYCLES && cycle.is_multiple_of(10) {
                worst_clock = worst_difference(&maindevice, &mut pump, &group, drives);
                if worst_clock.is_none() {
                    break;
                }
            }
        }
        let step = run(
            &mut pump,
            || "PRE-OP to SAFE-OP".to_owned(),
            group.into_safe_op(&maindevice),
            state_bound,
        );
        let group = Bus::named(&maindevice, &mut pump, &names, step)?;
        let group = run(
            &mut pump,
            || "SAFE-OP to OP".to_owned(),
            group.request_into_op(&maindevice),
            state_bound,
        )?;
        // Cycle until every subdevice is in OP: the drives go to OP only with frames
        // arriving in time for SYNC0.
        // The same clock as the settling: its deadlines passed during the state change
        // are skipped, and the next keeps the phase the loop found.
        let op_cycles = u64::from(config.state_timeout_ms) * 1_000_000 / period_ns;
        for cycle in 0.. {
            let tick = clock.wait_next();
            let (all_op, sample) = match cycle_dc(
                &maindevice,
                &mut pump,
                &group,
                &mut lock,
                tick.deadline_ns,
                timeout,
            ) {
                Ok((all_op, sample)) => (all_op, sample),
                Err(_) => (false, None),
            };
            if let Some(sample) = sample {
                clock.shift_next(sample.correction_ns);
            }
            if all_op {
                break;
            }
            if cycle > op_cycles {
                let step: Result<(), BringUpError> = Err(BringUpError::Step {
                    step: "SAFE-OP to OP".to_owned(),
                    source: ethercrab::error::Error::Timeout(
                        ethercrab::error::TimeoutError::StateTransition,
                    ),
                });
                Bus::named(&maindevice, &mut pump, &names, step)?;
            }
        }
        let first = clock.next_deadline_ns();
        Ok(Bus {
            maindevice,
            group: Cyclic::Clocked(group),
            pump,
            drives: Vec::new(),
            found: Vec::new(),
            names,
            lock: Some((lock, first)),
        })
    }

    /// With distributed clocks, the host time (`CLOCK_MONOTONIC`, ns) at which the cycle's
    /// clock must start so that it begins locked onto SYNC0; `None` without.
    pub fn first_cycle_start_ns(&self) -> Option<u64> {
        self.lock.map(|(_, first)| first)
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
        let sub = subdevice_of(&self.group, &self.maindevice, usize::from(position))?;
        let status = self
            .pump
            .block_on(
                async {
                    let state = sub.register_read::<u8>(RegisterAddress::AlStatus).await?;
                    let code = sub
                        .register_read::<u16>(RegisterAddress::AlStatusCode)
                        .await?;
                    Ok::<_, ethercrab::error::Error>((state, code))
                },
                timeout,
            )
            .ok()?;
        status.ok()
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
                let (exchange, _) = cycle_dc_exchange(
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

/// One exchange with distributed clocks on a group in any state with process data: the
/// outcome and whether every subdevice is in OP. The phase lock takes the measurement.
fn cycle_dc_exchange<S: HasPdi>(
    maindevice: &MainDevice<'static>,
    pump: &mut Pump,
    group: &Group<S, HasDc>,
    lock: &mut PhaseLock,
    start_ns: u64,
    timeout: Duration,
) -> Result<(Exchange, bool), PumpError> {
    let sent_ns = kerf_rt::now_ns();
    let response = pump
        .block_on(group.tx_rx_dc(maindevice), timeout)?
        .map_err(PumpError::Frame)?;
    let received_ns = kerf_rt::now_ns();
    let sample = lock
        .update(
            start_ns,
            sent_ns,
            received_ns,
            response.extra.dc_system_time,
        )
        .map(|(offset_ns, correction_ns)| DcSample {
            offset_ns,
            correction_ns,
        });
    let all_op = response.all_op();
    let exchange = exchange_of(response.working_counter, &response.subdevice_states, sample);
    Ok((exchange, all_op))
}

/// [`cycle_dc_exchange`] for bring-up: whether all are in OP, and the clock's sample.
fn cycle_dc<S: HasPdi>(
    maindevice: &MainDevice<'static>,
    pump: &mut Pump,
    group: &Group<S, HasDc>,
    lock: &mut PhaseLock,
    start_ns: u64,
    timeout: Duration,
) -> Result<(bool, Option<DcSample>), PumpError> {
    let (exchange, all_op) = cycle_dc_exchange(maindevice, pump, group, lock, start_ns, timeout)?;
    Ok((all_op, exchange.dc))
}

/// The drive (other than the reference) whose clock differs most from the reference's
/// beyond [`SETTLED_NS`]
/// (register 0x092C: bits 0–30 the difference, bit 31 its sign), if any; a drive that does
/// not answer counts as unsettled.
fn worst_difference<S: HasPdi>(
    maindevice: &MainDevice<'static>,
    pump: &mut Pump,
    group: &Group<S, HasDc>,
    drives: &[BusDrive],
) -> Option<(usize, i64)> {
    let mut worst: Option<(usize, i64)> = None;
    // ethercrab's reference clock: the first subdevice in ring order with a clock.
    let reference = group
        .iter(maindevice)
        .find(|s| s.dc_support().any())
        .map(|s| s.configured_address());
    for d in drives {
        let Ok(sub) = group.subdevice(maindevice, d.group_index) else {
            continue;
        };
        // The reference clock is what the others follow: its own difference register is
        // not steered and means nothing.
        if reference == Some(sub.configured_address()) {
            continue;
        }
        let read = pump.block_on(
            sub.register_read::<u32>(DC_DIFFERENCE_REGISTER),
            Duration::from_millis(100),
        );
        let difference = match read {
            Ok(Ok(raw)) => {
                let magnitude = i64::from(raw & 0x7FFF_FFFF);
                if raw & 0x8000_0000 != 0 {
                    -magnitude
                } else {
                    magnitude
                }
            }
            _ => i64::MAX,
        };
        if difference.unsigned_abs() > u64::from(SETTLED_NS)
            && worst.is_none_or(|(_, w)| difference.unsigned_abs() > w.unsigned_abs())
        {
            worst = Some((d.group_index, difference));
        }
    }
    worst
}

/// The AL status and AL status code of the subdevice at `position`, read by its
/// configured address (outside any group); `None` without an answer.
fn read_status(
    maindevice: &MainDevice<'static>,
    pump: &mut Pump,
    address: u16,
) -> Option<(u8, u16)> {
    // Right after a refused transition the first read may find the answer to the
    // transition's last frame (dropped in flight at its timeout) in its place: three tries.
    let mut read = |register: RegisterAddress| {
        (0..3).find_map(|_| {
            pump.block_on(
                ethercrab::Command::fprd(address, register.into()).receive::<u16>(maindevice),
                Duration::from_millis(200),
            )
            .ok()?
            .ok()
        })
    };
    let state = read(RegisterAddress::AlStatus)?;
    let code = read(RegisterAddress::AlStatusCode)?;
    Some(((state & 0xFF) as u8, code))
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
