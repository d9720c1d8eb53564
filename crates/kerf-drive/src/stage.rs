//! The drive stage: everything the real-time cycle does with the drives after the motion
//! core's `step()`, in one call per period.
//!
//! A [`DriveStage`] owns one CiA 402 drive per axis (any [`Drive`]: the simulated one, a
//! fieldbus drive), its [`Scale`] and its [`Enabler`], the [`Safety`] layer above them and
//! the black-box [`Recorder`]. Each [`DriveStage::cycle`]:
//!
//! 1. reads what every drive reported in the last exchange (statusword, actual position,
//!    error code);
//! 2. runs each drive's enable sequencer;
//! 3. while enabling: holds every target at the drive's actual position; once every drive
//!    is in Operation enabled, rebuilds the safety layer at the actual positions and says
//!    so ([`StageOutput::enabled_at`]): the motion core starts from there, so no axis
//!    jumps;
//! 4. once enabled: gives the new setpoint (or none, a missed cycle) to the safety layer,
//!    and sends its verdict to the drives (a trip never reaches a drive: the quick stop
//!    does);
//! 5. records the cycle in the black box.
//!
//! Faults latch in the safety layer; [`DriveStage::request_reset`] starts a reset that
//! resets the drives' own faults, enables every drive again (each from where its motor
//! stands) and clears the latched fault only once its cause is gone.
//! [`DriveStage::request_dump`] copies the black box, a chunk per cycle, into a spare ring
//! that [`DriveStage::take_dump`] hands out; a trip dumps on its own once the quick stop
//! is at rest.
//!
//! **Homing by the drive** (CiA 402 homing mode 6): [`DriveStage::start_drive_homing`],
//! in the `homing` submodule.
//!
//! Nothing here allocates after [`DriveStage::new`].

use crate::cia402::Enabler;
use crate::cia402::{
    Drive, DriveState, EnablerStatus, MODE_CYCLIC_SYNC_POSITION, Request, Scale, cw,
};
use crate::recorder::{CycleRecord, Recorder};
use crate::safety::{
    Check, CycleInput, Fault, ResetRefused, Safety, SafetyConfig, SafetyConfigError, SafetyState,
};
use crate::{MAX_AXES, PerAxis};

mod homing;
pub use homing::DriveHoming;
use homing::HomingStep;

/// Records copied from the black box into a dump per cycle: a few microseconds of copying.
pub const DUMP_CHUNK: usize = 256;

/// One axis's drive as the stage holds it.
#[derive(Debug)]
pub struct AxisDrive<D> {
    /// The drive.
    pub drive: D,
    /// Its scale: counts per mm (or degree) and direction.
    pub scale: Scale,
    /// Timeout of each transition of its enable sequence, cycles.
    pub enable_timeout_cycles: u32,
}

/// What the stage is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// The drives are being enabled; no motion yet.
    Enabling,
    /// Every drive is enabled and the safety layer runs (its own state says whether a
    /// fault is latched).
    Active,
    /// A reset is in progress: drives' faults reset and drives enabled again.
    Resetting,
}

impl Phase {
    /// `enabling`, `active` or `resetting`.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Enabling => "enabling",
            Phase::Active => "active",
            Phase::Resetting => "resetting",
        }
    }
}

/// What one cycle gives the stage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StageInput {
    /// The motion core's new setpoint (X, Y, Z mm, A, B, C deg), or `None` for a missed
    /// cycle.
    pub setpoint: Option<PerAxis<f64>>,
    /// Program line of the setpoint (for fault reports).
    pub line: u32,
    /// Time of the cycle, s (for the black box).
    pub time_s: f64,
}

/// What one cycle did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StageOutput {
    /// The phase after this cycle.
    pub phase: Phase,
    /// The safety layer's state after this cycle.
    pub state: SafetyState,
    /// The position sent to each drive this cycle (the hold position while a drive is not
    /// enabled), units.
    pub command: PerAxis<f64>,
    /// The actual positions read this cycle, units.
    pub actual: PerAxis<f64>,
    /// The fault latched in this very cycle, if any.
    pub tripped: Option<Fault>,
    /// `Some(position)` in the cycle the drives became enabled (at start or after a
    /// reset): the motion core must rest there from now on.
    pub enabled_at: Option<PerAxis<f64>>,
    /// The outcome of a reset that ended in this cycle.
    pub reset: Option<Result<(), ResetRefused>>,
    /// Per axis, `Some(position)` in the cycle its drive's homing ended attained and the
    /// drive is back in cyclic synchronous position ([`DriveStage::start_drive_homing`]):
    /// the axis is at rest there, in the drive's new coordinates (units, machine = drive
    /// + offset); the motion core must rest the axis there from the next cycle.
    pub homed_by_drive: PerAxis<Option<f64>>,
}

/// Why a black-box dump was taken.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DumpReason {
    /// A fault tripped; the dump was taken once the quick stop was at rest.
    Fault(Fault),
    /// Asked for with [`DriveStage::request_dump`]; the caller's tag.
    Request(u64),
}

/// A dump of the black box, handed out by [`DriveStage::take_dump`]; give the ring back
/// with [`DriveStage::return_spare`] once written.
#[derive(Debug)]
pub struct Dump {
    /// Why it was taken.
    pub reason: DumpReason,
    /// The records (oldest first), in the spare ring.
    pub recorder: Box<Recorder>,
}

#[derive(Debug)]
struct DumpJob {
    reason: DumpReason,
    /// Ring index in the live recorder of the oldest record to copy.
    start: usize,
    /// Records to copy.
    total: usize,
    copied: usize,
    into: Box<Recorder>,
}

/// Where the drives' enable sequence stands during a reset, per axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum AxisReset {
    /// Left as it is (enabled throughout).
    Keep,
    /// Its drive's fault is being reset.
    FaultReset,
    /// Its drive is being enabled.
    Enable,
    /// Enabled again; its command was taken from its actual position.
    Done,
}

/// The drive stage of the real-time cycle. See the module documentation.
#[derive(Debug)]
pub struct DriveStage<D: Drive> {
    axes: PerAxis<Option<AxisDrive<D>>>,
    enablers: [Enabler; MAX_AXES],
    safety: Safety,
    config: SafetyConfig,
    phase: Phase,
    resets: [AxisReset; MAX_AXES],
    reset_pending: bool,
    recorder: Recorder,
    spare: Option<Box<Recorder>>,
    job: Option<DumpJob>,
    done: Option<Dump>,
    /// A dump is wanted (by a request or a trip) but the spare ring is out.
    wanted: Option<DumpReason>,
    /// A trip whose dump is taken once the quick stop is at rest.
    trip_dump: Option<Fault>,
    /// The command of the previous cycle (the one the drives have been tracking).
    previous_command: PerAxis<f64>,
    sequence: u64,
    disable: bool,
    error_codes: PerAxis<u16>,
    /// Per axis, the machine coordinate of the drive's position 0 (units): machine =
    /// drive + offset. 0 until homing (or an absolute encoder's configuration) sets it.
    offsets: PerAxis<f64>,
    /// Per axis, whether the soft limits are checked (off on an axis not homed yet).
    soft_limits: PerAxis<bool>,
    /// Per axis, its homing by its drive.
    homing: [HomingStep; MAX_AXES],
    /// A [`Check::DriveHoming`] fault latched by [`DriveStage::homing_step`], for the
    /// cycle's output.
    homing_trip: Option<Fault>,
    /// The command sent two cycles ago (to tell an axis at rest).
    older_command: PerAxis<f64>,
}

/// A stage that cannot be built.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum StageError {
    /// The safety configuration is refused.
    #[error(transparent)]
    Safety(#[from] SafetyConfigError),
    /// An axis has a drive but no safety configuration, or the other way round.
    #[error("axis {0}: a drive needs the axis's safety configuration, and the other way round")]
    Axes(char),
    /// A drive's actual position is not a number.
    #[error("axis {0}: the drive's actual position is not finite")]
    Position(char),
}

fn read_actual<D: Drive>(axes: &PerAxis<Option<AxisDrive<D>>>) -> PerAxis<f64> {
    let mut actual = [0.0; MAX_AXES];
    for (a, ax) in actual.iter_mut().zip(axes.iter()) {
        if let Some(ax) = ax {
            *a = ax.scale.to_units(ax.drive.position_actual_counts());
        }
    }
    actual
}

impl<D: Drive> DriveStage<D> {
    /// A stage over `axes` (X to C; `None` for an axis the machine does not have) with
    /// the safety layer `config` and a black box of `recorder_capacity` cycles (allocated
    /// here, twice: the live ring and the spare a dump is copied into). Sets every
    /// drive's mode of operation to cyclic synchronous position and starts enabling.
    pub fn new(
        mut axes: PerAxis<Option<AxisDrive<D>>>,
        config: SafetyConfig,
        recorder_capacity: usize,
    ) -> Result<Self, StageError> {
        let mut recorded = [false; MAX_AXES];
        for (i, (ax, cfg)) in axes.iter().zip(config.axes.iter()).enumerate() {
            if ax.is_some() != cfg.is_some() {
                return Err(StageError::Axes(kerf_geom::AXIS_NAMES[i]));
            }
            recorded[i] = ax.is_some();
        }
        let actual = read_actual(&axes);
        if let Some(i) = actual.iter().position(|a| !a.is_finite()) {
            return Err(StageError::Position(kerf_geom::AXIS_NAMES[i]));
        }
        let safety = Safety::new(config, actual)?;
        let mut enablers: [Enabler; MAX_AXES] = core::array::from_fn(|_| Enabler::new(1));
        for (e, ax) in enablers.iter_mut().zip(axes.iter_mut()) {
            if let Some(ax) = ax {
                ax.drive.set_mode_of_operation(MODE_CYCLIC_SYNC_POSITION);
                *e = Enabler::new(ax.enable_timeout_cycles.max(1));
                e.request(Request::Enable);
            }
        }
        Ok(Self {
            axes,
            enablers,
            safety,
            config,
            phase: Phase::Enabling,
            resets: [AxisReset::Keep; MAX_AXES],
            reset_pending: false,
            recorder: Recorder::with_capacity(recorder_capacity, recorded),
            spare: Some(Box::new(Recorder::with_capacity(
                recorder_capacity,
                recorded,
            ))),
            job: None,
            done: None,
            wanted: None,
            trip_dump: None,
            previous_command: actual,
            sequence: 0,
            disable: false,
            error_codes: [0; MAX_AXES],
            offsets: [0.0; MAX_AXES],
            soft_limits: [true; MAX_AXES],
            homing: [HomingStep::Off(DriveHoming::Idle); MAX_AXES],
            homing_trip: None,
            older_command: actual,
        })
    }

    /// Axis `axis`'s machine coordinate of the drive's position 0, units (machine = drive
    /// + offset).
    pub fn offset(&self, axis: usize) -> f64 {
        self.offsets.get(axis).copied().unwrap_or(0.0)
    }

    /// Sets axis `axis`'s offset before the drives are enabled (an absolute encoder's
    /// configured offset: its machine coordinates are known from the start). Returns
    /// whether it was taken (only while enabling, and only a finite offset).
    pub fn set_offset(&mut self, axis: usize, offset: f64) -> bool {
        if self.phase != Phase::Enabling || axis >= MAX_AXES || !offset.is_finite() {
            return false;
        }
        // The position held so far (the drive's, read at construction) moves with it.
        self.previous_command[axis] += offset - self.offsets[axis];
        self.offsets[axis] = offset;
        true
    }

    /// Shifts axis `axis`'s machine coordinates by `delta` (homing has latched where the
    /// machine's zero is): every position the stage and its safety layer hold moves with
    /// them, so nothing moves physically and no check sees a jump. Only with every drive
    /// enabled and no fault latched; returns whether it was done.
    pub fn shift_axis(&mut self, axis: usize, delta: f64) -> bool {
        if self.phase != Phase::Active || axis >= MAX_AXES || !delta.is_finite() {
            return false;
        }
        if !self.safety.shift(axis, delta) {
            return false;
        }
        self.offsets[axis] += delta;
        self.previous_command[axis] += delta;
        true
    }

    /// Checks axis `axis`'s soft limits (`on`) or not (an axis that is not homed: its
    /// machine coordinates mean nothing yet).
    pub fn set_soft_limits(&mut self, axis: usize, on: bool) {
        if axis < MAX_AXES {
            self.soft_limits[axis] = on;
            self.safety.set_soft_limits(axis, on);
        }
    }

    /// Latches a fault found by the machine's manual motion (homing found no switch edge,
    /// a hard limit switch is active) on axis `axis`; the quick stop follows as for any
    /// fault. `None` when a fault is already latched.
    pub fn trip_axis(
        &mut self,
        check: Check,
        axis: usize,
        value: f64,
        limit: f64,
        line: u32,
    ) -> Option<Fault> {
        let f = self.safety.trip(check, Some(axis), value, limit, line)?;
        self.trip_dump = Some(f);
        Some(f)
    }

    /// The phase.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// The safety layer.
    pub fn safety(&self) -> &Safety {
        &self.safety
    }

    /// The latched fault, if any.
    pub fn fault(&self) -> Option<&Fault> {
        self.safety.fault()
    }

    /// `true` while the motion core may run: every drive enabled, no fault latched.
    pub fn ready(&self) -> bool {
        self.phase == Phase::Active && self.safety.fault().is_none()
    }

    /// The position sent to the drives in the last cycle.
    pub fn command(&self) -> PerAxis<f64> {
        self.previous_command
    }

    /// The error code (0x603F) each drive reported in the last cycle.
    pub fn error_codes(&self) -> PerAxis<u16> {
        self.error_codes
    }

    /// The drive of axis `i` (0–5 = X–C), to read it (a test's view of a simulated motor).
    pub fn drive(&self, i: usize) -> Option<&D> {
        self.axes.get(i)?.as_ref().map(|a| &a.drive)
    }

    /// The drive of axis `i` (0–5 = X–C), e.g. to inject a fault into a simulated drive.
    pub fn drive_mut(&mut self, i: usize) -> Option<&mut D> {
        self.axes.get_mut(i)?.as_mut().map(|a| &mut a.drive)
    }

    /// The live black box.
    pub fn recorder(&self) -> &Recorder {
        &self.recorder
    }

    /// Asks for a reset of the latched fault; the outcome comes in
    /// [`StageOutput::reset`] of a later cycle (at once when there is nothing to reset or
    /// the quick stop is still moving).
    pub fn request_reset(&mut self) {
        self.reset_pending = true;
    }

    /// Asks for a dump of the black box as it stands now, tagged `tag`; it is ready in
    /// [`DriveStage::take_dump`] after about capacity / [`DUMP_CHUNK`] cycles (later if
    /// the spare ring is still out). A request while another is waiting replaces it.
    pub fn request_dump(&mut self, tag: u64) {
        self.wanted = Some(DumpReason::Request(tag));
    }

    /// A finished dump, if one is ready.
    pub fn take_dump(&mut self) -> Option<Dump> {
        self.done.take()
    }

    /// Gives back the ring of a dump once it was written (it becomes the spare again).
    pub fn return_spare(&mut self, recorder: Box<Recorder>) {
        self.spare = Some(recorder);
    }

    /// Asks every drive to power off (Switch on disabled, the brake holds): for a
    /// shutdown once the motion is at rest. [`DriveStage::disabled`] says when done.
    pub fn request_disable(&mut self) {
        self.disable = true;
        for (e, ax) in self.enablers.iter_mut().zip(self.axes.iter()) {
            if ax.is_some() {
                e.request(Request::Disable);
            }
        }
    }

    /// `true` once every drive is in Switch on disabled (or Fault) after
    /// [`DriveStage::request_disable`], or its disable timed out.
    pub fn disabled(&self) -> bool {
        self.disable
            && self.axes.iter().all(|ax| match ax {
                Some(ax) => matches!(
                    DriveState::from_statusword(ax.drive.statusword()),
                    Some(DriveState::SwitchOnDisabled | DriveState::Fault) | None
                ),
                None => true,
            })
    }

    /// Reads every drive and steps its enable sequence: the first part of a cycle.
    fn read_drives(&mut self) -> DriveReadings {
        let mut r = DriveReadings {
            actual: [0.0; MAX_AXES],
            drive_fault: [false; MAX_AXES],
            controlwords: [0u16; MAX_AXES],
            statuswords: [0u16; MAX_AXES],
            hold: [None; MAX_AXES],
            status: [None; MAX_AXES],
        };
        for (i, ax) in self.axes.iter().enumerate() {
            let Some(ax) = ax else { continue };
            let sw = ax.drive.statusword();
            let pos = ax.drive.position_actual_counts();
            r.actual[i] = ax.scale.to_units(pos) + self.offsets[i];
            let code = ax.drive.error_code();
            self.error_codes[i] = code;
            let out = self.enablers[i].cycle(sw, pos, code);
            r.statuswords[i] = sw;
            r.controlwords[i] = out.controlword;
            r.hold[i] = out.hold_target_counts;
            r.status[i] = Some(out.status);
            r.drive_fault[i] = matches!(
                DriveState::from_statusword(sw),
                Some(DriveState::Fault | DriveState::FaultReactionActive)
            );
        }
        r
    }

    /// Latches a fieldbus fault ([`Check::Fieldbus`]): `missed` cycles in a row without a
    /// complete exchange against the allowed `limit`. The quick stop starts as for any
    /// fault; the drives, out of reach, stop by their own watchdog. Returns the fault if
    /// latched now (not when another fault is latched already).
    pub fn trip_fieldbus(&mut self, missed: u32, limit: u32, line: u32) -> Option<Fault> {
        let f = self.safety.trip(
            Check::Fieldbus,
            None,
            f64::from(missed),
            f64::from(limit),
            line,
        )?;
        self.trip_dump = Some(f);
        Some(f)
    }

    /// The drives' feedback of the coming cycle is stale (a fieldbus exchange missed):
    /// see [`crate::safety::Safety::feedback_stale`].
    pub fn feedback_stale(&mut self) {
        self.safety.feedback_stale();
    }

    /// Latches [`Check::SubdeviceState`]: the subdevice at `position` left OP with the AL
    /// status code `code`. `None` when a fault is already latched.
    pub fn trip_subdevice(&mut self, position: u16, code: u16, line: u32) -> Option<Fault> {
        let f = self.safety.trip(
            Check::SubdeviceState,
            None,
            f64::from(position),
            f64::from(code),
            line,
        )?;
        self.trip_dump = Some(f);
        Some(f)
    }

    /// Latches a fault of the machine around the axes (the spindle, the tool changer:
    /// [`Check::SpindleAtSpeed`], [`Check::SpindleBand`], [`Check::SpindleOrient`],
    /// [`Check::ToolChange`]) with its value and limit; the axes stop on the quick stop as
    /// for any fault. `None` when a fault is already latched.
    pub fn trip_machine(
        &mut self,
        check: Check,
        value: f64,
        limit: f64,
        line: u32,
    ) -> Option<Fault> {
        let f = self.safety.trip(check, None, value, limit, line)?;
        self.trip_dump = Some(f);
        Some(f)
    }

    /// One cycle. See the module documentation. Allocation-free.
    pub fn cycle(&mut self, input: &StageInput) -> StageOutput {
        self.sequence += 1;
        let DriveReadings {
            actual,
            drive_fault,
            controlwords,
            statuswords,
            hold,
            status,
        } = self.read_drives();
        let mut tripped = None;
        let mut enabled_at = None;
        let mut reset = None;

        // Enabling at start: no check runs until every drive is enabled.
        if self.phase == Phase::Enabling && !self.disable {
            let all_enabled = status.iter().zip(self.axes.iter()).all(|(s, ax)| {
                ax.is_none() || matches!(s, Some(EnablerStatus::Done(DriveState::OperationEnabled)))
            });
            if all_enabled {
                // Infallible: the configuration was checked in `new` and the positions
                // are finite (a non-finite one keeps the stage enabling).
                if actual.iter().all(|a| a.is_finite())
                    && let Ok(s) = Safety::new(self.config, actual)
                {
                    self.safety = s;
                    for (i, on) in self.soft_limits.iter().enumerate() {
                        self.safety.set_soft_limits(i, *on);
                    }
                    self.phase = Phase::Active;
                    enabled_at = Some(actual);
                }
            } else if let Some((check, i, value, limit)) = self.enable_failure(&status) {
                tripped = self.safety.trip(check, Some(i), value, limit, input.line);
                self.phase = Phase::Active;
            }
        }

        // A reset started in this cycle is advanced from the next: this cycle's enabler
        // status was decided before the reset's requests (a drive that dropped out of
        // Operation enabled reads Dropped until its enabler starts again).
        let started = self.reset_pending;
        if self.reset_pending {
            self.reset_pending = false;
            reset = self.start_reset(&status);
        }
        if self.phase == Phase::Resetting
            && !started
            && let Some(r) = self.advance_reset(&status, &actual)
        {
            if r.is_ok() {
                // The motion core rests where the safety layer holds.
                enabled_at = Some(self.safety.command());
            }
            reset = Some(r);
        }

        // A drive that disabled itself while running trips (a drive fault trips in the
        // safety checks).
        if self.phase == Phase::Active && self.safety.fault().is_none() {
            for (i, s) in status.iter().enumerate() {
                if let Some(EnablerStatus::Dropped { .. }) = s
                    && !drive_fault[i]
                {
                    tripped = self
                        .safety
                        .trip(Check::DriveDisabled, Some(i), 1.0, 0.0, input.line);
                    break;
                }
            }
        }

        // Homing by the drive: its steps, then the axes whose drive moves on its own
        // follow their actual positions.
        let mut homed_by_drive = [None; MAX_AXES];
        let mut following = [false; MAX_AXES];
        let mut setpoint = input.setpoint;
        if self.phase != Phase::Enabling {
            for i in 0..MAX_AXES {
                following[i] = self.homing_step(i, statuswords[i], input.line);
                if let Some(f) = self.homing_trip.take() {
                    tripped = tripped.or(Some(f));
                }
                if following[i] {
                    self.safety.follow(i, actual[i]);
                    if let Some(sp) = setpoint.as_mut() {
                        sp[i] = actual[i];
                    }
                    if matches!(self.homing[i], HomingStep::Off(_)) {
                        // Ended in this cycle: back to the axis's own soft limits.
                        self.safety.set_soft_limits(i, self.soft_limits[i]);
                        if self.homing[i] == HomingStep::Off(DriveHoming::Attained) {
                            homed_by_drive[i] = Some(actual[i]);
                        }
                    } else {
                        self.safety.set_soft_limits(i, false);
                    }
                }
            }
        }

        let command = if self.phase == Phase::Enabling {
            actual
        } else {
            let verdict = self.safety.check(&CycleInput {
                setpoint,
                actual,
                drive_fault,
                line: input.line,
            });
            if verdict.tripped.is_some() {
                tripped = verdict.tripped;
            }
            verdict.command
        };
        if let Some(f) = tripped {
            self.trip_dump = Some(f);
        }
        if self.safety.fault().is_some() {
            // A fault interrupts every homing by a drive.
            for h in self.homing.iter_mut() {
                if matches!(h, HomingStep::Enter(_) | HomingStep::Run(_)) {
                    *h = HomingStep::Leave(DriveHoming::Interrupted, 0);
                }
            }
        }
        if let Some(f) = self.trip_dump
            && self.safety.state() == SafetyState::Stopped
        {
            self.trip_dump = None;
            self.wanted = Some(DumpReason::Fault(f));
        }

        // Exchange: the held actual position while a drive is not enabled.
        let mut sent = command;
        for (i, ax) in self.axes.iter_mut().enumerate() {
            let Some(ax) = ax else { continue };
            let offset = self.offsets[i];
            let target = match hold[i] {
                Some(counts) => {
                    sent[i] = ax.scale.to_units(counts) + offset;
                    counts
                }
                None => match ax.scale.to_counts(command[i] - offset) {
                    Ok(c) => c,
                    // Outside the 32-bit range: cannot be sent; the soft limits trip
                    // long before, so hold where the drive is.
                    Err(_) => ax.drive.position_actual_counts(),
                },
            };
            let controlword = match (self.homing[i], controlwords[i]) {
                // Only on an enabled drive (the enabler's Enable operation).
                (step, cw::ENABLE_OPERATION_CMD) => match step {
                    HomingStep::Off(_) | HomingStep::Enter(_) => cw::ENABLE_OPERATION_CMD,
                    HomingStep::Run(_) => cw::ENABLE_OPERATION_CMD | cw::HOMING_START,
                    HomingStep::Leave(DriveHoming::Attained, _) => cw::ENABLE_OPERATION_CMD,
                    HomingStep::Leave(..) => cw::ENABLE_OPERATION_CMD | cw::HALT,
                },
                (_, word) => word,
            };
            ax.drive.write(controlword, target);
        }

        let mut following_error = [0.0; MAX_AXES];
        for (e, (c, a)) in following_error
            .iter_mut()
            .zip(self.previous_command.iter().zip(actual.iter()))
        {
            *e = c - a;
        }
        self.recorder.record(&CycleRecord {
            sequence: self.sequence,
            time_s: input.time_s,
            commanded: sent,
            actual,
            following_error,
            controlword: controlwords,
            statusword: statuswords,
            state: self.safety.state(),
        });
        // After the record: a dump begun in this cycle holds it. The copy runs ahead of
        // the ring's overwriting (a chunk of records per cycle against one record).
        self.copy_dump_chunk();
        self.older_command = self.previous_command;
        self.previous_command = sent;
        for (i, f) in following.iter().enumerate() {
            if *f && matches!(self.homing[i], HomingStep::Off(_)) {
                // Its homing ended at rest in this cycle (its coordinates may have jumped).
                self.older_command[i] = sent[i];
            }
        }
        StageOutput {
            phase: self.phase,
            state: self.safety.state(),
            command: sent,
            actual,
            tripped,
            enabled_at,
            reset,
            homed_by_drive,
        }
    }

    /// The first axis whose enable sequence failed: (check, axis, value, limit): a drive
    /// in fault (value 1, limit 0, as the safety check reports it), or a transition that
    /// timed out or a statusword that does not decode (value and limit: the timeout in
    /// cycles).
    fn enable_failure(
        &self,
        status: &PerAxis<Option<EnablerStatus>>,
    ) -> Option<(Check, usize, f64, f64)> {
        for (i, s) in status.iter().enumerate() {
            let timeout = self.axes[i]
                .as_ref()
                .map_or(0.0, |a| f64::from(a.enable_timeout_cycles));
            match s {
                Some(EnablerStatus::Timeout { .. } | EnablerStatus::BadStatusword(_)) => {
                    return Some((Check::EnableTimeout, i, timeout, timeout));
                }
                Some(EnablerStatus::Fault { .. }) => return Some((Check::DriveFault, i, 1.0, 0.0)),
                _ => {}
            }
        }
        None
    }

    /// Starts a reset; `Some(outcome)` when it ends at once.
    fn start_reset(
        &mut self,
        status: &PerAxis<Option<EnablerStatus>>,
    ) -> Option<Result<(), ResetRefused>> {
        if self.safety.fault().is_none() {
            return Some(Ok(()));
        }
        if self.phase == Phase::Resetting {
            return None;
        }
        if self.safety.state() == SafetyState::QuickStop {
            let i = self
                .config
                .axes
                .iter()
                .position(|a| a.is_some())
                .unwrap_or(0);
            return Some(Err(ResetRefused::Moving(i)));
        }
        if let Some(i) = self
            .homing
            .iter()
            .position(|h| !matches!(h, HomingStep::Off(_)))
        {
            // A drive homing itself is still stopping (or not back in mode 8).
            return Some(Err(ResetRefused::Moving(i)));
        }
        for (i, ax) in self.axes.iter().enumerate() {
            let Some(ax) = ax else {
                self.resets[i] = AxisReset::Keep;
                continue;
            };
            let state = DriveState::from_statusword(ax.drive.statusword());
            self.resets[i] = match state {
                Some(DriveState::Fault | DriveState::FaultReactionActive) => {
                    self.enablers[i].request(Request::FaultReset);
                    AxisReset::FaultReset
                }
                Some(DriveState::OperationEnabled)
                    if !matches!(status[i], Some(EnablerStatus::Dropped { .. })) =>
                {
                    AxisReset::Keep
                }
                _ => {
                    self.enablers[i].request(Request::Enable);
                    AxisReset::Enable
                }
            };
        }
        self.phase = Phase::Resetting;
        None
    }

    /// One cycle of a reset; `Some(outcome)` when it ends.
    fn advance_reset(
        &mut self,
        status: &PerAxis<Option<EnablerStatus>>,
        actual: &PerAxis<f64>,
    ) -> Option<Result<(), ResetRefused>> {
        for i in 0..MAX_AXES {
            match (self.resets[i], status[i]) {
                (AxisReset::FaultReset, Some(EnablerStatus::Done(_))) => {
                    self.enablers[i].request(Request::Enable);
                    self.resets[i] = AxisReset::Enable;
                }
                (AxisReset::FaultReset, Some(EnablerStatus::Timeout { .. })) => {
                    self.enablers[i].request(Request::Disable);
                    return Some(self.end_reset(Err(ResetRefused::DriveFault(i))));
                }
                (AxisReset::Enable, Some(EnablerStatus::Done(DriveState::OperationEnabled))) => {
                    // Enabled where its motor stands (the enabler held the target there).
                    if !self.safety.rebase(i, actual[i]) {
                        return Some(self.end_reset(Err(ResetRefused::NotEnabled(i))));
                    }
                    self.resets[i] = AxisReset::Done;
                }
                (
                    AxisReset::Enable,
                    Some(
                        EnablerStatus::Timeout { .. }
                        | EnablerStatus::Fault { .. }
                        | EnablerStatus::Dropped { .. }
                        | EnablerStatus::BadStatusword(_),
                    ),
                ) => {
                    self.enablers[i].request(Request::Disable);
                    let refused = match status[i] {
                        Some(EnablerStatus::Fault { .. }) => ResetRefused::DriveFault(i),
                        _ => ResetRefused::NotEnabled(i),
                    };
                    return Some(self.end_reset(Err(refused)));
                }
                _ => {}
            }
        }
        if self
            .resets
            .iter()
            .all(|r| matches!(r, AxisReset::Keep | AxisReset::Done))
        {
            let outcome = self.safety.reset();
            return Some(self.end_reset(outcome));
        }
        None
    }

    fn end_reset(&mut self, outcome: Result<(), ResetRefused>) -> Result<(), ResetRefused> {
        self.phase = Phase::Active;
        self.resets = [AxisReset::Keep; MAX_AXES];
        outcome
    }

    /// Starts a wanted dump when the spare ring is in, and copies one chunk of a dump in
    /// progress; a finished dump waits in `done` (one at a time).
    fn copy_dump_chunk(&mut self) {
        if self.job.is_none()
            && self.done.is_none()
            && let Some(reason) = self.wanted
            && let Some(mut into) = self.spare.take()
        {
            self.wanted = None;
            into.clear();
            self.job = Some(DumpJob {
                reason,
                start: self.recorder.oldest_index(),
                total: self.recorder.len(),
                copied: 0,
                into,
            });
        }
        let Some(job) = self.job.as_mut() else {
            return;
        };
        let n = DUMP_CHUNK.min(job.total - job.copied);
        self.recorder
            .copy_into(job.start + job.copied, n, &mut job.into);
        job.copied += n;
        if job.copied == job.total
            && let Some(job) = self.job.take()
        {
            self.done = Some(Dump {
                reason: job.reason,
                recorder: job.into,
            });
        }
    }
}

/// What a cycle reads from the drives before it checks anything, per axis.
struct DriveReadings {
    /// Actual positions, mm or deg.
    actual: PerAxis<f64>,
    /// The drive reports Fault or Fault reaction active.
    drive_fault: PerAxis<bool>,
    /// The enable sequences' controlwords.
    controlwords: PerAxis<u16>,
    /// The drives' statuswords.
    statuswords: PerAxis<u16>,
    /// The target an enable sequence holds the drive at, counts.
    hold: PerAxis<Option<i32>>,
    /// The enable sequences' status.
    status: PerAxis<Option<EnablerStatus>>,
}
