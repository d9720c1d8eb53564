//! The machine's drives as the cycle holds them: simulated ([`SimDrive`]) or on EtherCAT
//! ([`DriveImage`], the mirror of the drive's process data), and the EtherCAT bus the
//! cycle exchanges once per period with its supervision.
//!
//! Order in a cycle: the drive stage reads the drives (the inputs of the last exchange),
//! checks and writes their outputs; then the bus sends the outputs and brings back the
//! inputs for the next cycle: one period of transport delay, as every master has.
//! A cycle whose exchange does not come back complete (no answer within half a period,
//! a working counter short, or a subdevice no longer in OP) counts as missed; more than
//! `max_missed_cycles` in a row latch [`kerf_drive::safety::Check::Fieldbus`]. A
//! subdevice that leaves OP latches [`kerf_drive::safety::Check::SubdeviceState`] at once,
//! with its AL status code (read in that cycle: one more frame).
//!
//! With distributed clocks every exchange measures the cycle start's offset from its
//! place before SYNC0 ([`kerf_ethercat::dc::PhaseLock`]); the cycle thread moves its next
//! deadline by the correction ([`Fieldbus::take_correction_ns`]); the offsets are kept in
//! a histogram for the status and the exit summary.
//!
//! A reset while the bus is not fully in OP first brings it back ([`Fieldbus::recover`]):
//! one step per cycle, beside the cyclic exchange: each subdevice out of OP has its error
//! acknowledged and is asked for SAFE-OP, then OP. Allocation-free.

use std::time::Duration;

use kerf_config::Config;
use kerf_drive::cia402::Drive;
use kerf_drive::sim::SimDrive;
use kerf_drive::stage::DriveStage;
use kerf_ethercat::al::{ERROR_FLAG, OP, SAFE_OP, STATE_BITS};
use kerf_ethercat::bus::{Bus, MAX_SUBDEVICES, Outcome, outcome};
use kerf_ethercat::claim::{Claim, Holder};
use kerf_ethercat::image::DriveImage;

use crate::timing::{Histogram, Percentiles};

/// One axis's drive.
#[derive(Debug)]
pub enum MachineDrive {
    /// A simulated drive in the daemon.
    Sim(SimDrive),
    /// A drive on the EtherCAT bus.
    Ethercat(DriveImage),
}

impl Drive for MachineDrive {
    fn write(&mut self, controlword: u16, target_position_counts: i32) {
        match self {
            MachineDrive::Sim(d) => d.write(controlword, target_position_counts),
            MachineDrive::Ethercat(d) => d.write(controlword, target_position_counts),
        }
    }

    fn set_mode_of_operation(&mut self, mode: i8) {
        match self {
            MachineDrive::Sim(d) => d.set_mode_of_operation(mode),
            MachineDrive::Ethercat(d) => d.set_mode_of_operation(mode),
        }
    }

    fn mode_of_operation_display(&self) -> i8 {
        match self {
            MachineDrive::Sim(d) => d.mode_of_operation_display(),
            MachineDrive::Ethercat(d) => d.mode_of_operation_display(),
        }
    }

    fn statusword(&self) -> u16 {
        match self {
            MachineDrive::Sim(d) => d.statusword(),
            MachineDrive::Ethercat(d) => d.statusword(),
        }
    }

    fn position_actual_counts(&self) -> i32 {
        match self {
            MachineDrive::Sim(d) => d.position_actual_counts(),
            MachineDrive::Ethercat(d) => d.position_actual_counts(),
        }
    }

    fn velocity_actual_counts_s(&self) -> i32 {
        match self {
            MachineDrive::Sim(d) => d.velocity_actual_counts_s(),
            MachineDrive::Ethercat(d) => d.velocity_actual_counts_s(),
        }
    }

    fn following_error_counts(&self) -> i32 {
        match self {
            MachineDrive::Sim(d) => d.following_error_counts(),
            MachineDrive::Ethercat(d) => d.following_error_counts(),
        }
    }

    fn error_code(&self) -> u16 {
        match self {
            MachineDrive::Sim(d) => d.error_code(),
            MachineDrive::Ethercat(d) => d.error_code(),
        }
    }
}

/// Exchange counters of the bus since the start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusCounters {
    /// Cycles exchanged completely.
    pub complete: u64,
    /// Cycles whose frame did not come back in time.
    pub lost: u64,
    /// Cycles whose working counter was short (a subdevice did not take part).
    pub short: u64,
    /// Cycles in which a subdevice was not in OP (it left OP on its own: its watchdog or
    /// an error of its own).
    pub not_op: u64,
    /// The most consecutive incomplete cycles seen.
    pub longest_gap: u32,
}

/// The distributed clocks as the status shows them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DcReport {
    /// The last cycle's offset of its start from `sync0_shift_ns` before SYNC0, ns
    /// (positive = late).
    pub offset_ns: i64,
    /// The distribution of |offset| over the cycles since the bus came up.
    pub offset_abs: Percentiles,
    /// Cycles measured.
    pub samples: u64,
}

/// The bus as the status shows it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusReport {
    /// Subdevices on the bus (positions 0 to `subdevices - 1`).
    pub subdevices: u16,
    /// Each subdevice's AL state (1 INIT, 2 PRE-OP, 3 BOOT, 4 SAFE-OP, 8 OP; 0 unknown),
    /// by position, as the last exchange that came back saw it.
    pub states: [u8; MAX_SUBDEVICES],
    /// Each subdevice's AL status code, by position, as last read (when it left OP or
    /// during a reset's recovery); 0 = none.
    pub al_codes: [u16; MAX_SUBDEVICES],
    /// The exchange counters.
    pub counters: BusCounters,
    /// The distributed clocks, when used.
    pub dc: Option<DcReport>,
    /// Whether a reset is bringing the bus back to OP.
    pub recovering: bool,
}

/// What a reset's bus recovery came to, when it is over.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Recovered {
    /// Every subdevice is in OP and the exchange is complete: the drives may be reset.
    Done,
    /// The bus did not come back; why.
    Refused(kerf_drive::safety::ResetRefused),
}

/// A reset's recovery in progress.
#[derive(Clone, Copy, Debug)]
struct Recovery {
    /// Cycles it has run.
    cycles: u64,
}

/// The EtherCAT bus of the cycle, in OP, with its supervision.
#[derive(Debug)]
pub struct Fieldbus {
    bus: Bus,
    /// The claim on the interface, released after the bus (declared after it).
    _claim: Claim,
    expected_wkc: u16,
    timeout: Duration,
    max_missed: u32,
    missed_in_row: u32,
    /// Exchanges in a row whose frame did not come back.
    lost_in_row: u32,
    /// The inputs of the last exchange are not this cycle's (see [`Fieldbus::inputs_stale`]).
    stale: bool,
    counters: BusCounters,
    states: [u8; MAX_SUBDEVICES],
    al_codes: [u16; MAX_SUBDEVICES],
    /// A subdevice out of OP has tripped the fault (once per leaving).
    left_op: bool,
    dc_offsets: Option<Histogram>,
    correction_ns: i64,
    recovery: Option<Recovery>,
    /// Cycles a recovery may take: `state_timeout_ms`.
    recovery_cycles: u64,
    state_timeout_ms: u32,
    period_ns: u64,
}

impl Fieldbus {
    /// Brings the bus of `config` up to OP; `None` when the configuration has no
    /// `[ethercat]` table. Runs on the cycle thread right before its first period: from
    /// OP on the drives' process-data watchdog expects a frame every period.
    pub fn start(config: &Config) -> Result<Option<Fieldbus>, String> {
        let Some(ec) = config.ethercat() else {
            return Ok(None);
        };
        let period_ns = u64::from(config.period_us) * 1000;
        // The interface is the daemon's while it runs: commissioning commands and a second
        // daemon are refused, naming it.
        let claim = Claim::take(&ec.interface, Holder::Daemon).map_err(|e| e.to_string())?;
        let bus = Bus::bring_up(ec, period_ns, &claim).map_err(|e| e.to_string())?;
        Ok(Some(Fieldbus {
            expected_wkc: bus.expected_working_counter(),
            _claim: claim,
            dc_offsets: bus.first_cycle_start_ns().map(|_| Histogram::new()),
            bus,
            // Half a period for the frame's round trip: the cycle must still compute and
            // sleep to its next period.
            timeout: Duration::from_nanos(period_ns / 2),
            max_missed: ec.max_missed_cycles,
            missed_in_row: 0,
            lost_in_row: 0,
            stale: false,
            counters: BusCounters::default(),
            states: [OP; MAX_SUBDEVICES],
            al_codes: [0; MAX_SUBDEVICES],
            left_op: false,
            correction_ns: 0,
            recovery: None,
            recovery_cycles: (u64::from(ec.state_timeout_ms) * 1_000_000 / period_ns).max(1),
            state_timeout_ms: ec.state_timeout_ms,
            period_ns,
        }))
    }

    /// With distributed clocks, the host time at which the cycle's clock must start (the
    /// bring-up left the bus locked onto SYNC0 for it).
    pub fn first_cycle_start_ns(&self) -> Option<u64> {
        self.bus.first_cycle_start_ns()
    }

    /// The correction of the next cycle's start from the last exchange, ns (0 without
    /// distributed clocks); taken once.
    pub fn take_correction_ns(&mut self) -> i64 {
        std::mem::take(&mut self.correction_ns)
    }

    /// The bus as the status shows it.
    pub fn report(&self) -> BusReport {
        BusReport {
            subdevices: u16::try_from(self.bus.len()).unwrap_or(u16::MAX),
            states: self.states,
            al_codes: self.al_codes,
            counters: self.counters,
            dc: self.dc_offsets.as_ref().map(|h| DcReport {
                offset_ns: self.bus.dc_offset_ns().unwrap_or(0),
                offset_abs: h.percentiles(),
                samples: h.count(),
            }),
            recovering: self.recovery.is_some(),
        }
    }

    /// Whether every subdevice was in OP at the last exchange that came back.
    fn all_op(&self) -> bool {
        self.states[..self.bus.len()].iter().all(|s| *s == OP)
    }

    /// Whether a reset must first bring the bus back: an exchange incomplete, or a
    /// subdevice out of OP.
    pub fn needs_recovery(&self) -> bool {
        self.failing() || !self.all_op()
    }

    /// Starts a reset's recovery of the bus ([`Fieldbus::recover`] runs it).
    pub fn start_recovery(&mut self) {
        self.recovery = Some(Recovery { cycles: 0 });
    }

    /// One step of a reset's recovery, after this cycle's exchange: `None` while it goes
    /// on (or when none runs). Asks at most one subdevice per cycle for a state, so that the
    /// cycle keeps its time.
    pub fn recover(&mut self) -> Option<Recovered> {
        let recovery = self.recovery.as_mut()?;
        recovery.cycles += 1;
        let cycles = recovery.cycles;
        if !self.failing() && self.all_op() {
            self.recovery = None;
            self.left_op = false;
            self.al_codes = [0; MAX_SUBDEVICES];
            return Some(Recovered::Done);
        }
        // A bus that does not answer at all is not waited for: its cable or power first.
        let silent = self.lost_in_row > self.max_missed;
        if cycles > self.recovery_cycles || (silent && cycles > u64::from(self.max_missed) + 1) {
            self.recovery = None;
            let refusal = match self.first_not_op() {
                Some(position) if self.lost_in_row == 0 => {
                    kerf_drive::safety::ResetRefused::SubdeviceState {
                        position,
                        state: kerf_ethercat::al::state_name(self.states[usize::from(position)]),
                        code: self.al_codes[usize::from(position)],
                        timeout_ms: self.state_timeout_ms,
                    }
                }
                _ => kerf_drive::safety::ResetRefused::Fieldbus(
                    u32::try_from(cycles * self.period_ns / 1_000_000).unwrap_or(u32::MAX),
                ),
            };
            return Some(Recovered::Refused(refusal));
        }
        // Every other cycle: the status read of one subdevice out of OP, then the request
        // its status calls for (acknowledge into SAFE-OP, or OP).
        if self.lost_in_row > 0 || !cycles.is_multiple_of(2) {
            return None;
        }
        let position = self.first_not_op()?;
        let timeout = self.timeout / 2;
        if let Some((al_status, code)) = self.bus.status_of(position, timeout) {
            let i = usize::from(position);
            self.states[i] = al_status & STATE_BITS;
            if code != 0 {
                self.al_codes[i] = code;
            }
            let wanted = if al_status & ERROR_FLAG != 0 || al_status & STATE_BITS != SAFE_OP {
                SAFE_OP
            } else {
                OP
            };
            self.bus.request_state(position, wanted, timeout);
        }
        None
    }

    fn first_not_op(&self) -> Option<u16> {
        self.states[..self.bus.len()]
            .iter()
            .position(|s| *s != OP)
            .and_then(|p| u16::try_from(p).ok())
    }

    /// Whether the last exchange was incomplete.
    pub fn failing(&self) -> bool {
        self.missed_in_row > 0
    }

    /// Whether the drives' inputs the coming cycle reads are stale: the last cycle's
    /// exchange did not happen or did not come back complete.
    pub fn inputs_stale(&self) -> bool {
        self.stale
    }

    /// A cycle without an exchange (a missed period's catch-up): the next inputs are stale.
    pub fn skipped(&mut self) {
        self.stale = true;
    }

    /// The counters so far.
    pub fn counters(&self) -> BusCounters {
        self.counters
    }

    /// Exchanges the process data of `stage`'s EtherCAT drives in the cycle that was to
    /// start at `start_ns` (host `CLOCK_MONOTONIC`). Returns what trips, if anything.
    pub fn exchange(
        &mut self,
        stage: &mut DriveStage<MachineDrive>,
        start_ns: u64,
    ) -> Option<BusTrip> {
        for axis in 0..kerf_drive::MAX_AXES {
            if let Some(MachineDrive::Ethercat(image)) = stage.drive_mut(axis) {
                self.bus.write_outputs(axis, image);
            }
        }
        let mut trip = None;
        let result = self.bus.tx_rx_at(start_ns, self.timeout);
        if let Ok(e) = &result {
            self.lost_in_row = 0;
            let n = self.bus.len().min(MAX_SUBDEVICES);
            self.states[..n].copy_from_slice(&e.states[..n]);
            if let (Some(sample), Some(h)) = (e.dc, self.dc_offsets.as_mut()) {
                h.record(sample.offset_ns.unsigned_abs());
                self.correction_ns = sample.correction_ns;
            }
        }
        let complete = match outcome(&result, self.expected_wkc) {
            Outcome::Complete => true,
            Outcome::NotOp(position) => {
                self.counters.not_op += 1;
                if !self.left_op && self.recovery.is_none() {
                    self.left_op = true;
                    // Why it left: its AL status code, one more frame in this cycle (the
                    // machine is stopping; the cycle may run long).
                    let code = self
                        .bus
                        .status_of(position, self.timeout / 2)
                        .map_or(0, |(_, code)| code);
                    self.al_codes[usize::from(position)] = code;
                    trip = Some(BusTrip::LeftOp { position, code });
                }
                false
            }
            Outcome::Short => {
                self.counters.short += 1;
                false
            }
            Outcome::Lost => {
                self.counters.lost += 1;
                self.lost_in_row = self.lost_in_row.saturating_add(1);
                false
            }
        };
        self.stale = !complete;
        if complete {
            self.counters.complete += 1;
            self.missed_in_row = 0;
            for axis in 0..kerf_drive::MAX_AXES {
                if let Some(MachineDrive::Ethercat(image)) = stage.drive_mut(axis) {
                    self.bus.read_inputs(axis, image);
                }
            }
            return None;
        }
        self.missed_in_row = self.missed_in_row.saturating_add(1);
        self.counters.longest_gap = self.counters.longest_gap.max(self.missed_in_row);
        trip.or_else(|| {
            (self.missed_in_row > self.max_missed).then_some(BusTrip::Missed {
                in_row: self.missed_in_row,
                limit: self.max_missed,
            })
        })
    }
}

/// What the bus's supervision trips.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BusTrip {
    /// More incomplete exchanges in a row than allowed.
    Missed {
        /// Incomplete exchanges in a row.
        in_row: u32,
        /// `max_missed_cycles`.
        limit: u32,
    },
    /// A subdevice left OP.
    LeftOp {
        /// Its ring position.
        position: u16,
        /// Its AL status code (0 when it could not be read).
        code: u16,
    },
}
