//! **Homing by the drive** (CiA 402 homing mode 6, for an axis whose drive homes itself):
//! [`DriveStage::start_drive_homing`] asks for it on one axis at rest. From the next cycle
//! the stage sets the drive's mode to 6 with controlword bit 4 low, once the drive shows
//! mode 6 raises bit 4 (the start), and reads statusword bits 10, 12 and 13 each cycle
//! ([`DriveStage::drive_homing`]). Meanwhile the axis's setpoint is not used: its
//! command, and everything the safety layer holds for it, follow its actual position
//! ([`crate::safety::Safety::follow`]), its soft limits are off, and the other axes run as
//! ever. When the drive reports homing completed (it has redefined its coordinates: the
//! home position reads the home offset), the stage sets the mode back to 8 with the
//! target at the actual position and, once the drive shows mode 8, reports the axis's
//! new position in [`super::StageOutput::homed_by_drive`]: the motion core must rest the axis
//! there. A homing error (bit 13) latches [`Check::DriveHoming`]; a fault latched while a
//! drive homes interrupts it (bit 4 low, halt): the drive is taken back to mode 8 once it
//! reports rest, and a reset waits for that.

use super::{DriveStage, Phase};
use crate::MAX_AXES;
use crate::cia402::{Drive, DriveState, HomingStatus, MODE_CYCLIC_SYNC_POSITION, MODE_HOMING, sw};
use crate::safety::Check;

/// Where an axis's homing by its drive stands ([`DriveStage::drive_homing`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriveHoming {
    /// None asked for since the stage was built.
    Idle,
    /// The drive is in homing mode: homing, or stopping after it attained before the
    /// stage has it back in cyclic synchronous position.
    Running,
    /// The last homing ended attained: the drive redefined its coordinates and is back in
    /// cyclic synchronous position.
    Attained,
    /// The last homing ended in an error: the drive reported one (statusword bit 13; a
    /// [`Check::DriveHoming`] fault is latched), did not take homing mode within its
    /// enable timeout, or left Operation enabled. The drive's error code (0x603F, 0 when
    /// it gives none).
    Error(u16),
    /// The last homing was interrupted by a fault latched elsewhere (the drive was halted).
    Interrupted,
}

/// The stage's own sequence of an axis's homing by its drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum HomingStep {
    /// Not in homing mode; the outcome of the last homing.
    Off(DriveHoming),
    /// Asked for: mode 6 with bit 4 low, waiting for the mode display (cycles waited).
    Enter(u32),
    /// Bit 4 high, for this many cycles.
    Run(u32),
    /// Ended with this outcome, the drive still in homing mode: bit 4 low (and halt
    /// unless attained) until it reports rest, then mode 8 until the display shows it;
    /// for this many cycles.
    Leave(DriveHoming, u32),
}

impl<D: Drive> DriveStage<D> {
    /// Starts the homing of axis `axis` by its drive (CiA 402 homing mode 6, with the
    /// method and parameters the drive was given: by SDO on a fieldbus,
    /// [`crate::sim::SimDrive::set_homing_config`] on a simulated drive): from the next
    /// cycle the stage switches the drive to homing mode and raises controlword bit 4.
    /// Only with every drive enabled, no fault latched, the axis's drive not homing
    /// already, and the axis at rest (its last two commands equal). Refused with the
    /// reason otherwise. Follow it with [`DriveStage::drive_homing`] and
    /// [`super::StageOutput::homed_by_drive`].
    pub fn start_drive_homing(&mut self, axis: usize) -> Result<(), &'static str> {
        if axis >= MAX_AXES || self.axes[axis].is_none() {
            return Err("the machine has no drive on that axis");
        }
        if self.phase != Phase::Active {
            return Err("the drives are not all enabled");
        }
        if self.safety.fault().is_some() {
            return Err("a fault is latched: reset it first");
        }
        if !matches!(self.homing[axis], HomingStep::Off(_)) {
            return Err("the axis's drive is homing already");
        }
        if self.previous_command[axis] != self.older_command[axis] {
            return Err("the axis is moving");
        }
        self.homing[axis] = HomingStep::Enter(0);
        Ok(())
    }

    /// Where axis `axis`'s homing by its drive stands (read each cycle after
    /// [`DriveStage::cycle`]); [`DriveHoming::Idle`] for an axis without a drive.
    pub fn drive_homing(&self, axis: usize) -> DriveHoming {
        match self.homing.get(axis) {
            None | Some(HomingStep::Off(DriveHoming::Idle)) => DriveHoming::Idle,
            Some(HomingStep::Off(o)) => *o,
            Some(HomingStep::Enter(_) | HomingStep::Run(_)) => DriveHoming::Running,
            Some(HomingStep::Leave(DriveHoming::Attained, _)) => DriveHoming::Running,
            Some(HomingStep::Leave(o, _)) => *o,
        }
    }

    /// Whether axis `axis`'s drive is in the stage's homing sequence (from
    /// [`DriveStage::start_drive_homing`] until the drive is back in cyclic synchronous
    /// position): its setpoint is not used meanwhile.
    pub fn drive_homing_active(&self, axis: usize) -> bool {
        !matches!(self.homing.get(axis), None | Some(HomingStep::Off(_)))
    }

    /// One cycle of axis `i`'s homing by its drive, from its statusword read this cycle:
    /// sets its mode of operation, advances its step, latches [`Check::DriveHoming`] on a
    /// homing error (into `homing_trip`). Returns whether the axis follows its actual
    /// position this cycle (its drive is in the homing sequence, or left it in this
    /// cycle).
    pub(super) fn homing_step(&mut self, i: usize, statusword: u16, line: u32) -> bool {
        let step = self.homing[i];
        if matches!(step, HomingStep::Off(_)) {
            return false;
        }
        let Some(ax) = self.axes[i].as_mut() else {
            self.homing[i] = HomingStep::Off(DriveHoming::Idle);
            return false;
        };
        let timeout = ax.enable_timeout_cycles.max(1);
        // Statuswords that left the drive before the last controlword reached it.
        let delay = u32::try_from(self.config.feedback_delay_cycles).unwrap_or(1);
        let code = ax.drive.error_code();
        let display = ax.drive.mode_of_operation_display();
        let enabled = DriveState::from_statusword(statusword) == Some(DriveState::OperationEnabled);
        if !enabled {
            // A drive fault, a drop-out, a disable: the homing ends; the safety layer
            // trips on the drive's own state. The drive takes mode 8 back at rest.
            ax.drive.set_mode_of_operation(MODE_CYCLIC_SYNC_POSITION);
            self.homing[i] = HomingStep::Off(match step {
                HomingStep::Leave(o, _) => o,
                _ => DriveHoming::Error(code),
            });
            return true;
        }
        let status = HomingStatus::from_statusword(statusword);
        let mut failed = None;
        let mut next = match step {
            HomingStep::Off(o) => HomingStep::Off(o),
            HomingStep::Enter(0) => {
                ax.drive.set_mode_of_operation(MODE_HOMING);
                HomingStep::Enter(1)
            }
            HomingStep::Enter(_) if display == MODE_HOMING => HomingStep::Run(0),
            HomingStep::Enter(n) if n > timeout => {
                failed = Some(0);
                HomingStep::Leave(DriveHoming::Error(0), 0)
            }
            HomingStep::Enter(n) => HomingStep::Enter(n + 1),
            // Statuswords older than the start's edge are not its answer.
            HomingStep::Run(n) if n < delay || display != MODE_HOMING => HomingStep::Run(n + 1),
            HomingStep::Run(n) => match status {
                HomingStatus::Completed => HomingStep::Leave(DriveHoming::Attained, 0),
                HomingStatus::ErrorMoving | HomingStatus::ErrorAtRest | HomingStatus::Reserved => {
                    failed = Some(code);
                    HomingStep::Leave(DriveHoming::Error(code), 0)
                }
                // Not started within the timeout.
                HomingStatus::Idle if n > timeout => {
                    failed = Some(code);
                    HomingStep::Leave(DriveHoming::Error(code), 0)
                }
                // Not started yet (a drive may take a few cycles), or on its way.
                _ => HomingStep::Run(n + 1),
            },
            HomingStep::Leave(o, n) => HomingStep::Leave(o, n.saturating_add(1)),
        };
        if let HomingStep::Leave(outcome, n) = next {
            // At rest: out of homing mode, or bit 10 in a statusword that answers the
            // controlword that ended the homing (a completed homing is at rest at once).
            let answered = n >= delay || outcome == DriveHoming::Attained;
            let at_rest =
                display != MODE_HOMING || (answered && statusword & sw::TARGET_REACHED != 0);
            if at_rest {
                ax.drive.set_mode_of_operation(MODE_CYCLIC_SYNC_POSITION);
                if ax.drive.mode_of_operation_display() == MODE_CYCLIC_SYNC_POSITION {
                    next = HomingStep::Off(outcome);
                }
            }
        }
        self.homing[i] = next;
        if let Some(code) = failed {
            self.homing_trip =
                self.safety
                    .trip(Check::DriveHoming, Some(i), f64::from(code), 0.0, line);
        }
        true
    }
}
