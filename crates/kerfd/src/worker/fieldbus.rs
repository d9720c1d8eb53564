//! The machine's drives as the cycle holds them: simulated ([`SimDrive`]) or on EtherCAT
//! ([`DriveImage`], the mirror of the drive's process data), and the EtherCAT bus the
//! cycle exchanges once per period with its supervision.
//!
//! Order in a cycle: the drive stage reads the drives (the inputs of the last exchange),
//! checks and writes their outputs; then the bus sends the outputs and brings back the
//! inputs for the next cycle: one period of transport delay, as every master has.
//! A cycle whose exchange does not come back complete (no answer within half a period,
//! a working counter short, or a subdevice no longer in OP) counts as missed; more than `max_missed_cycles` in a row
//! latch [`kerf_drive::safety::Check::Fieldbus`]. Allocation-free.

use std::time::Duration;

use kerf_config::Config;
use kerf_drive::cia402::Drive;
use kerf_drive::sim::SimDrive;
use kerf_drive::stage::DriveStage;
use kerf_ethercat::bus::Bus;
use kerf_ethercat::image::DriveImage;

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

/// The EtherCAT bus of the cycle, in OP, with its supervision.
#[derive(Debug)]
pub struct Fieldbus {
    bus: Bus,
    expected_wkc: u16,
    timeout: Duration,
    max_missed: u32,
    missed_in_row: u32,
    counters: BusCounters,
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
        let bus = Bus::bring_up(ec, period_ns).map_err(|e| e.to_string())?;
        Ok(Some(Fieldbus {
            expected_wkc: bus.expected_working_counter(),
            bus,
            // Half a period for the frame's round trip: the cycle must still compute and
            // sleep to its next period.
            timeout: Duration::from_nanos(period_ns / 2),
            max_missed: ec.max_missed_cycles,
            missed_in_row: 0,
            counters: BusCounters::default(),
        }))
    }

    /// Whether the last exchange was incomplete.
    pub fn failing(&self) -> bool {
        self.missed_in_row > 0
    }

    /// The counters so far.
    pub fn counters(&self) -> BusCounters {
        self.counters
    }

    /// Exchanges the process data of `stage`'s EtherCAT drives. Returns the number of
    /// incomplete cycles in a row once it is above the limit (the caller trips), else
    /// `None`.
    pub fn exchange(&mut self, stage: &mut DriveStage<MachineDrive>) -> Option<(u32, u32)> {
        for axis in 0..kerf_drive::MAX_AXES {
            if let Some(MachineDrive::Ethercat(image)) = stage.drive_mut(axis) {
                self.bus.write_outputs(axis, image);
            }
        }
        let complete = match self.bus.tx_rx(self.timeout) {
            Ok(e) if e.not_op.is_some() => {
                self.counters.not_op += 1;
                false
            }
            Ok(e) if e.working_counter == self.expected_wkc => true,
            Ok(_) => {
                self.counters.short += 1;
                false
            }
            Err(_) => {
                self.counters.lost += 1;
                false
            }
        };
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
        (self.missed_in_row > self.max_missed).then_some((self.missed_in_row, self.max_missed))
    }
}
