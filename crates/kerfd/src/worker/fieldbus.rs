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
//!
//! The machine around the axes on the bus (allocation-free too):
//!
//! - its digital outputs and inputs (`[io]` entries with a bus bit, a named bit of an
//!   `[[ethercat.io]]` subdevice): [`Fieldbus::send_machine`] (or
//!   [`Fieldbus::write_outputs`]) copies the machine's output word into the subdevices'
//!   output bits before the exchange; [`Fieldbus::receive_machine`] (or
//!   [`Fieldbus::read_inputs`]) gives the machine the input bits of the last complete
//!   exchange, before the machine's cycle. An incomplete exchange leaves the inputs as
//!   they were.
//! - the spindle's drive (`axis = "s"`, CiA 402 cyclic synchronous velocity, mode 9 set at
//!   bring-up): its own enable sequence ([`kerf_drive::cia402::Enabler`], the axes'),
//!   enabled with the axes and powered off with them at a shutdown; while enabled its
//!   target velocity is the machine's velocity setpoint, `rpm × counts_per_rev / 60`
//!   counts/s (0 otherwise), and its velocity actual goes back to the machine as rpm. A
//!   fault of the drive, an enable transition that times out or the drive leaving
//!   Operation enabled on its own is reported once ([`SpindleTrip`]) for the cycle to
//!   latch; the drive stage's next reset resets the drive's fault and enables it again.

use std::time::Duration;

use kerf_config::Config;
use kerf_drive::cia402::{Drive, DriveState, Enabler, EnablerStatus, Request};
use kerf_drive::machine::{ANALOG_IO, Machine};
use kerf_drive::safety::Check;
use kerf_drive::sim::SimDrive;
use kerf_drive::stage::{DriveStage, Phase};
use kerf_ethercat::al::{ERROR_FLAG, OP, SAFE_OP, STATE_BITS};
use kerf_ethercat::bus::{Bus, MAX_SUBDEVICES, Outcome, outcome};
use kerf_ethercat::claim::{Claim, Holder};
use kerf_ethercat::image::{DriveImage, SpindleImage};
use kerf_ethercat::iomap::IoMap;

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

/// A failure of the spindle's drive on the bus, reported once for the cycle to latch
/// (see [`SpindleTrip::check`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpindleTrip {
    /// The drive reports a fault (statusword bit 3), with its error code (0x603F; 0 when
    /// not mapped).
    Fault {
        /// The error code.
        error_code: u16,
    },
    /// A transition of its enable sequence did not happen within the timeout, or its
    /// statusword does not decode.
    NotEnabled {
        /// The timeout of each transition, cycles.
        timeout_cycles: u32,
    },
    /// It left Operation enabled on its own (not into a fault).
    Disabled,
}

impl SpindleTrip {
    /// The safety check it latches, `spindle_drive`, with its value and limit: a fault
    /// is its error code against 0, a timeout the timeout in cycles against 1, a drop-out
    /// 0 against 2.
    pub fn check(self) -> (Check, f64, f64) {
        match self {
            SpindleTrip::Fault { error_code } => (Check::SpindleDrive, f64::from(error_code), 0.0),
            SpindleTrip::NotEnabled { timeout_cycles } => {
                (Check::SpindleDrive, f64::from(timeout_cycles), 1.0)
            }
            SpindleTrip::Disabled => (Check::SpindleDrive, 0.0, 2.0),
        }
    }
}

/// The spindle's drive on the bus: its process image, enable sequence and scale.
#[derive(Debug)]
struct BusSpindle {
    image: SpindleImage,
    enabler: Enabler,
    counts_per_rev: f64,
    timeout_cycles: u32,
    /// A failure was reported and not yet reset.
    tripped: bool,
    /// An exchange has brought its inputs.
    read: bool,
}

impl BusSpindle {
    fn new(image: SpindleImage, counts_per_rev: f64, timeout_cycles: u32) -> BusSpindle {
        let mut enabler = Enabler::new(timeout_cycles.max(1));
        enabler.request(Request::Enable);
        BusSpindle {
            image,
            enabler,
            counts_per_rev,
            timeout_cycles: timeout_cycles.max(1),
            tripped: false,
            read: false,
        }
    }

    /// The target velocity for `rpm`, counts/s, rounded and saturated to 32 bits (0 for
    /// a value that is not a number).
    fn counts_s(&self, rpm: f64) -> i32 {
        let counts = (rpm * self.counts_per_rev / 60.0).round();
        if counts.is_nan() {
            0
        } else {
            counts.clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
        }
    }

    /// The velocity actual of the last exchange, rpm.
    fn actual_rpm(&self) -> f64 {
        f64::from(self.image.velocity_actual_counts_s()) * 60.0 / self.counts_per_rev
    }

    /// One cycle of the enable sequence with the drive stage in `phase` (`disabled`: the
    /// axes were powered off for a shutdown): writes the controlword and the target
    /// velocity (`setpoint_rpm` while enabled) into the image; a new failure comes back.
    fn step(&mut self, phase: Phase, disabled: bool, setpoint_rpm: f64) -> Option<SpindleTrip> {
        let statusword = self.image.statusword();
        if disabled {
            self.enabler.request(Request::Disable);
        } else if phase == Phase::Resetting && self.tripped {
            // The drive stage's reset: the drive's fault reset first, then enable.
            self.tripped = false;
            let faulted = matches!(
                DriveState::from_statusword(statusword),
                Some(DriveState::Fault | DriveState::FaultReactionActive)
            );
            self.enabler.request(if faulted {
                Request::FaultReset
            } else {
                Request::Enable
            });
        }
        let mut out = self.enabler.cycle(statusword, 0, self.image.error_code());
        if self.enabler.current_request() == Request::FaultReset
            && matches!(out.status, EnablerStatus::Done(_))
        {
            self.enabler.request(Request::Enable);
            out = self.enabler.cycle(statusword, 0, self.image.error_code());
        }
        let enabled = self.enabler.current_request() == Request::Enable
            && out.status == EnablerStatus::Done(DriveState::OperationEnabled);
        let target = if enabled {
            self.counts_s(setpoint_rpm)
        } else {
            0
        };
        self.image.write(out.controlword, target);
        if disabled || self.tripped || !self.read {
            return None;
        }
        let trip = match out.status {
            EnablerStatus::Fault { error_code } => SpindleTrip::Fault { error_code },
            EnablerStatus::Timeout { .. } | EnablerStatus::BadStatusword(_) => {
                SpindleTrip::NotEnabled {
                    timeout_cycles: self.timeout_cycles,
                }
            }
            EnablerStatus::Dropped { .. } => SpindleTrip::Disabled,
            EnablerStatus::InProgress(_) | EnablerStatus::Done(_) => return None,
        };
        self.tripped = true;
        Some(trip)
    }
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
    /// The machine's digital inputs and outputs on the bus.
    io: IoMap,
    /// The digital inputs of the last complete exchange (bit n: `[io]` input n).
    inputs: u64,
    /// The spindle's drive, when the bus has one.
    spindle: Option<BusSpindle>,
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
        let spindle_image = Bus::spindle_image(ec).map_err(|e| format!("spindle drive: {e}"))?;
        let spindle = match (spindle_image, &config.spindle.kind) {
            (Some(image), kerf_config::SpindleKind::Drive(d)) => {
                // The axes' enable timeout (they share `[drive] enable_timeout_ms`).
                let timeout_cycles = config
                    .drive_configs()
                    .iter()
                    .flatten()
                    .map(|d| d.enable_timeout_cycles)
                    .max()
                    .unwrap_or(1);
                Some(BusSpindle::new(image, d.counts_per_rev, timeout_cycles))
            }
            _ => None,
        };
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
            io: IoMap::of(config),
            inputs: 0,
            spindle,
        }))
    }

    /// Writes the machine's digital outputs (bit n: `[io]` output n) into the output bits
    /// of the I/O subdevices, sent by the next [`Fieldbus::exchange`].
    pub fn write_outputs(&mut self, digital_outputs: u64) {
        self.bus.write_io(&self.io, digital_outputs);
    }

    /// The machine's digital inputs (bit n: `[io]` input n) as the last complete exchange
    /// brought them (0 before the first).
    pub fn read_inputs(&self) -> u64 {
        self.inputs
    }

    /// The spindle drive's velocity actual of the last complete exchange, rpm; `None`
    /// without a spindle drive on the bus or before its first exchange.
    pub fn spindle_actual_rpm(&self) -> Option<f64> {
        self.spindle
            .as_ref()
            .filter(|s| s.read)
            .map(BusSpindle::actual_rpm)
    }

    /// The target velocity and controlword the spindle drive gets at the next exchange
    /// (counts/s, controlword); `None` without a spindle drive.
    pub fn spindle_command(&self) -> Option<(i32, u16)> {
        self.spindle
            .as_ref()
            .map(|s| (s.image.target_velocity_counts_s(), s.image.controlword()))
    }

    /// Before the exchange, after the cycle's actions: the machine's outputs into the I/O
    /// subdevices' bits, and the spindle drive's enable sequence one step with the drive
    /// stage (enabled with the axes, reset with them, powered off at a shutdown) and its
    /// target velocity from the machine's setpoint. Returns a failure of the spindle drive
    /// to latch (once until the drive stage's next reset).
    pub fn send_machine(
        &mut self,
        machine: &Machine,
        stage: &DriveStage<MachineDrive>,
    ) -> Option<SpindleTrip> {
        self.write_outputs(machine.io().digital_outputs);
        let spindle = self.spindle.as_mut()?;
        let trip = spindle.step(
            stage.phase(),
            stage.disabled(),
            machine.spindle_velocity_setpoint_rpm(),
        );
        self.bus.write_spindle(&spindle.image);
        trip
    }

    /// Before the machine's cycle: the inputs of the last complete exchange and the
    /// spindle drive's speed into the machine.
    pub fn receive_machine(&self, machine: &mut Machine) {
        if !self.io.is_empty() {
            // Analog inputs are not on the bus (the configuration refuses them there):
            // the zeros are ignored as inputs that do not exist.
            machine.set_bus_inputs(self.inputs, &[0.0; ANALOG_IO]);
        }
        if let Some(rpm) = self.spindle_actual_rpm() {
            machine.set_spindle_actual_rpm(rpm);
        }
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
            self.inputs = self.bus.read_io(&self.io);
            if let Some(s) = self.spindle.as_mut() {
                self.bus.read_spindle(&mut s.image);
                s.read = true;
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

#[cfg(test)]
mod tests {
    use super::*;
    use kerf_config::ethercat::{DriveMode, Pdo};
    use kerf_ethercat::pdo::SpindleLayout;

    /// A spindle drive at 10000 counts/rev with an enable timeout of 5 cycles.
    fn spindle() -> BusSpindle {
        let layout =
            SpindleLayout::new(&Pdo::default_rx(DriveMode::Csv), &Pdo::default_tx()).unwrap();
        BusSpindle::new(SpindleImage::new(layout, 9), 10_000.0, 5)
    }

    /// The drive answers with `statusword`, velocity actual `velocity` and `error_code`
    /// (the default TxPDO: statusword at 0, velocity actual at 6, error code at 14).
    fn answer(s: &mut BusSpindle, statusword: u16, velocity: i32, error_code: u16) {
        let mut input = [0u8; 20];
        input[..2].copy_from_slice(&statusword.to_le_bytes());
        input[6..10].copy_from_slice(&velocity.to_le_bytes());
        input[14..16].copy_from_slice(&error_code.to_le_bytes());
        s.image.read_inputs(&input);
        s.read = true;
    }

    #[test]
    fn the_spindle_is_enabled_then_follows_the_setpoint_in_counts_per_second() {
        let mut s = spindle();
        // CiA 402 enable: Switch on disabled → Shutdown (6), Ready → Switch on (7),
        // Switched on → Enable operation (15); the target stays 0 until enabled.
        for (statusword, controlword) in [(0x0250, 0x0006), (0x0231, 0x0007), (0x0233, 0x000F)] {
            answer(&mut s, statusword, 0, 0);
            assert_eq!(s.step(Phase::Active, false, 6000.0), None);
            assert_eq!(
                (s.image.controlword(), s.image.target_velocity_counts_s()),
                (controlword, 0)
            );
        }
        // Enabled: 6000 rpm × 10000 / 60 = 1 000 000 counts/s; M4 at 1500 rpm: -250 000.
        answer(&mut s, 0x1237, 0, 0);
        assert_eq!(s.step(Phase::Active, false, 6000.0), None);
        assert_eq!(s.image.target_velocity_counts_s(), 1_000_000);
        assert_eq!(s.step(Phase::Active, false, -1500.0), None);
        assert_eq!(s.image.target_velocity_counts_s(), -250_000);
        // Its velocity actual back as rpm: 500 000 counts/s is 3000 rpm.
        answer(&mut s, 0x1237, 500_000, 0);
        assert_eq!(s.actual_rpm(), 3000.0);
    }

    #[test]
    fn a_spindle_fault_is_reported_once_and_the_reset_clears_and_enables_it() {
        let mut s = spindle();
        answer(&mut s, 0x1237, 0, 0);
        s.enabler.request(Request::Enable);
        for sw in [0x0250, 0x0231, 0x0233, 0x1237] {
            answer(&mut s, sw, 0, 0);
            s.step(Phase::Active, false, 1000.0);
        }
        // Fault (0x0218: fault, voltage enabled) with error code 0x4310.
        answer(&mut s, 0x0218, 0, 0x4310);
        assert_eq!(
            s.step(Phase::Active, false, 1000.0),
            Some(SpindleTrip::Fault { error_code: 0x4310 })
        );
        assert_eq!(s.image.target_velocity_counts_s(), 0);
        assert_eq!(s.step(Phase::Active, false, 1000.0), None, "reported once");
        assert_eq!(
            SpindleTrip::Fault { error_code: 0x4310 }.check(),
            (Check::SpindleDrive, 17168.0, 0.0)
        );
        // The drive stage resets: bit 7 low, then a rising edge.
        assert_eq!(s.step(Phase::Resetting, false, 0.0), None);
        assert_eq!(s.image.controlword() & 0x0080, 0);
        assert_eq!(s.step(Phase::Resetting, false, 0.0), None);
        assert_eq!(s.image.controlword() & 0x0080, 0x0080);
        // Out of the fault: enabled again.
        for (statusword, controlword) in [(0x0250, 0x0006), (0x0231, 0x0007), (0x0233, 0x000F)] {
            answer(&mut s, statusword, 0, 0);
            assert_eq!(s.step(Phase::Active, false, 0.0), None);
            assert_eq!(s.image.controlword(), controlword);
        }
        // A shutdown powers it off without a report.
        answer(&mut s, 0x1237, 0, 0);
        assert_eq!(s.step(Phase::Active, true, 0.0), None);
        assert_eq!(s.image.controlword(), 0x0000);
    }

    #[test]
    fn a_spindle_that_does_not_enable_or_drops_out_is_reported() {
        let mut s = spindle();
        // Stuck in Switch on disabled for more than 5 cycles.
        let mut trip = None;
        for _ in 0..8 {
            answer(&mut s, 0x0250, 0, 0);
            trip = trip.or(s.step(Phase::Enabling, false, 0.0));
        }
        assert_eq!(trip, Some(SpindleTrip::NotEnabled { timeout_cycles: 5 }));
        let mut s = spindle();
        for sw in [0x0250, 0x0231, 0x0233, 0x1237] {
            answer(&mut s, sw, 0, 0);
            s.step(Phase::Active, false, 0.0);
        }
        answer(&mut s, 0x0250, 0, 0);
        assert_eq!(
            s.step(Phase::Active, false, 0.0),
            Some(SpindleTrip::Disabled)
        );
        assert_eq!(
            SpindleTrip::NotEnabled { timeout_cycles: 5 }.check(),
            (Check::SpindleDrive, 5.0, 1.0)
        );
        assert_eq!(
            SpindleTrip::Disabled.check(),
            (Check::SpindleDrive, 0.0, 2.0)
        );
    }
}
