//! Homing, jogging and the axes' switches as plain records: `[homing]` ([`HomingConfig`]),
//! `[jog]` ([`JogConfig`]) and, per axis, `[axes.*.homing]`, `[axes.*.limit_switches]`
//! and `[axes.*.sim]` ([`AxisSetup`], read with [`Config::axis_setups`]).
//!
//! Lengths are mm for X, Y, Z and degrees for A, B, C (`_units` in the names). Switch
//! inputs are the numbers of digital inputs of `[io]` (`M66 P<n>`): on a machine without
//! `[ethercat]` simulated inputs, with it bits of the bus.

use kerf_drive::MAX_AXES;
use kerf_drive::cia402::homing_method;
use kerf_drive::sim::SimHomingConfig;

use crate::ranges::*;
use crate::{Config, DriveKind};

/// `[homing]`: what homing means for the machine as a whole.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomingConfig {
    /// `required`: programs and MDI are refused until every axis is homed.
    pub required: bool,
    /// `unhomed_jog_pct`: the jog speed cap of an axis that is not homed, percent of its
    /// velocity (its soft limits do not apply yet).
    pub unhomed_jog_pct: f64,
}

impl Default for HomingConfig {
    fn default() -> Self {
        HomingConfig {
            required: DEFAULT_HOMING_REQUIRED,
            unhomed_jog_pct: DEFAULT_UNHOMED_JOG_PCT,
        }
    }
}

/// `[jog]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JogConfig {
    /// `deadman_ms`: a continuous jog stops (on a jerk-limited ramp) when its request is
    /// not renewed within this, ms.
    pub deadman_ms: u32,
    /// `default_speed_pct`: the speed of a jog without `--speed`, percent of the axis's
    /// velocity.
    pub default_speed_pct: f64,
}

impl Default for JogConfig {
    fn default() -> Self {
        JogConfig {
            deadman_ms: DEFAULT_DEADMAN_MS,
            default_speed_pct: DEFAULT_JOG_SPEED_PCT,
        }
    }
}

/// `axes.*.homing.kind`: how an axis finds its machine coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum HomingKind {
    /// `"none"` (and an axis without `[axes.*.homing]`): homed at start, its machine
    /// coordinates are the drive's from power-up, as Kerf did before homing existed.
    #[default]
    None,
    /// `"switch"`: Kerf searches the home switch, latches its edge and moves to `home`.
    Switch,
    /// `"absolute"`: an absolute encoder; homed at start without motion, machine
    /// coordinate = encoder position + `home_offset`.
    Absolute,
    /// `"drive"`: the drive homes itself in CiA 402 homing mode (6) with `method`
    /// (0x6098), the speeds (0x6099), `acceleration` (0x609A) and `home_offset` (0x607C);
    /// its home position then reads `home_offset`, and Kerf moves the axis to `home`.
    Drive,
}

impl HomingKind {
    /// Whether an axis of this kind is homed when the daemon starts (everything but
    /// [`HomingKind::Switch`] and [`HomingKind::Drive`]).
    pub fn homed_at_start(self) -> bool {
        !matches!(self, HomingKind::Switch | HomingKind::Drive)
    }
}

/// One axis's `[axes.*.homing]`. The keys of a kind that does not use them keep the
/// harmless values of [`AxisHoming::default`] (0, `None`).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct AxisHoming {
    /// `kind`.
    pub kind: HomingKind,
    /// `switch`: the number of the home switch's digital input in `[io]` (kind
    /// [`HomingKind::Switch`] only).
    pub switch_input: Option<u32>,
    /// `method` (kind [`HomingKind::Drive`]): the CiA 402 homing method (0x6098); 0 for
    /// the other kinds.
    pub drive_method: i8,
    /// `search_velocity_mm_s` (`_deg_s`): kind [`HomingKind::Switch`]: signed, the sign is
    /// the direction of the search; magnitude above 0 and at most the axis's velocity.
    /// Kind [`HomingKind::Drive`]: the speed during the search for the switch (0x6099:01),
    /// above 0 (the method gives the direction); 0 when not given (methods 35 and 37).
    pub search_velocity_units_s: f64,
    /// `latch_velocity_mm_s` (`_deg_s`): kind [`HomingKind::Switch`]: signed, the same
    /// sign as the search (back off, then approach the edge again) or the opposite one
    /// (leave the switch, latching where it releases); magnitude above 0 and at most the
    /// search's. Kind [`HomingKind::Drive`]: the speed during the search for zero
    /// (0x6099:02), above 0 and at most the search's; 0 when not given.
    pub latch_velocity_units_s: f64,
    /// `acceleration_mm_s2` (`_deg_s2`, kind [`HomingKind::Drive`]): the homing
    /// acceleration (0x609A), by default the axis's; 0 for the other kinds.
    pub acceleration_units_s2: f64,
    /// `search_distance_mm` (`_deg`): the longest search before the home switch is
    /// declared not found (kind [`HomingKind::Drive`]: the simulated drive's search limit;
    /// on EtherCAT the drive's own applies).
    pub search_distance_units: f64,
    /// `home_offset_mm` (`_deg`): the machine coordinate of the switch's latch point
    /// (kind [`HomingKind::Switch`]), of encoder position 0 (kind
    /// [`HomingKind::Absolute`]), or of the drive's home position (kind
    /// [`HomingKind::Drive`]: the home offset 0x607C, which the drive's position actual
    /// value reads there).
    pub home_offset_units: f64,
    /// `home_mm` (`_deg`): where the axis goes after homing, within its travel.
    pub home_units: f64,
    /// `final_speed_mm_s` (`_deg_s`): the speed of the move to `home_units`.
    pub final_speed_units_s: f64,
    /// `sequence`: `kerf home --all` homes sequence 0 first, then 1, ...; axes with the
    /// same number home together.
    pub sequence: u32,
}

/// One axis's `[axes.*.limit_switches]`: the hard limit switches' digital inputs in
/// `[io]`, by number.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct LimitSwitches {
    /// `min`: the switch at the lower end of the travel.
    pub min_input: Option<u32>,
    /// `max`: the switch at the upper end of the travel.
    pub max_input: Option<u32>,
}

/// One axis's `[axes.*.sim]`: the simulated machine behind a simulated drive, in the
/// drive's own frame (the position it counts from power-up, in mm or degrees: the
/// machine coordinate before homing). All defaults without the table and with
/// `[ethercat]` (where the table is refused).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct SimAxis {
    /// `start_mm` (`start_deg`): the motor's position at power-up.
    pub start_units: f64,
    /// `home_switch_mm` (`_deg`): the simulated home switch is active at and beyond this
    /// point in the search direction (kind [`HomingKind::Switch`]: the sign of
    /// [`AxisHoming::search_velocity_units_s`]; `None`: the operator sets the input with
    /// `kerf input`). Kind [`HomingKind::Drive`]: the switch wired to the simulated drive,
    /// active beyond this point in the method's search direction in the drive's counts
    /// (increasing for methods 19 and 20, decreasing for 21 and 22); `None`: no switch, the
    /// drive's search ends in a homing error.
    pub home_switch_units: Option<f64>,
    /// `min_limit_mm` (`_deg`): the simulated min limit switch is active at and below
    /// this point.
    pub min_limit_units: Option<f64>,
    /// `max_limit_mm` (`_deg`): the simulated max limit switch is active at and above
    /// this point.
    pub max_limit_units: Option<f64>,
}

/// The homing objects of an axis homed by its drive (kind [`HomingKind::Drive`]) in the
/// drive's units, as a master writes them by SDO before the homing
/// ([`Config::drive_homing_objects`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DriveHomingObjects {
    /// 0x6098, homing method.
    pub method: i8,
    /// 0x6099:01, speed during the search for the switch, counts/s (0: `search_velocity`
    /// not given, not written).
    pub search_speed_counts_s: u32,
    /// 0x6099:02, speed during the search for zero, counts/s (0: not given, not written).
    pub zero_speed_counts_s: u32,
    /// 0x609A, homing acceleration, counts/s².
    pub acceleration_counts_s2: u32,
    /// 0x607C, home offset, counts (with the scale's direction).
    pub home_offset_counts: i32,
}

/// What the daemon reads about one axis's homing, limit switches and simulated machine
/// ([`Config::axis_setups`]).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct AxisSetup {
    /// `[axes.*.homing]`.
    pub homing: AxisHoming,
    /// `[axes.*.limit_switches]`.
    pub limit_switches: LimitSwitches,
    /// `[axes.*.sim]`.
    pub sim: SimAxis,
}

impl Config {
    /// Each axis's homing, limit switches and simulated machine, X to C (`None` where the
    /// machine has no axis).
    pub fn axis_setups(&self) -> [Option<AxisSetup>; MAX_AXES] {
        self.setups
    }

    /// The homing objects axis `axis` (0 X to 5 C) is homed with by its drive, in its
    /// counts: `None` unless its `[axes.*.homing]` is of kind "drive". On EtherCAT the
    /// daemon writes them by SDO (0x6098, 0x6099:01/02 when not 0, 0x609A, 0x607C). Speeds
    /// and acceleration are |value| × counts per unit, rounded, at least 1 when given; the
    /// offset goes through the axis's scale (its direction included), so that the home
    /// position's machine coordinate is `home_offset_mm`. (The checks at load keep every
    /// value within its object's type.)
    pub fn drive_homing_objects(&self, axis: usize) -> Option<DriveHomingObjects> {
        let setup = self.setups.get(axis).copied().flatten()?;
        let drive = self.drive.axes.get(axis).copied().flatten()?;
        let h = setup.homing;
        if h.kind != HomingKind::Drive {
            return None;
        }
        let cpu = drive.scale.counts_per_unit();
        let rate = |v: f64| -> u32 {
            if v == 0.0 {
                0
            } else {
                // Range-checked at load: within u32.
                (v.abs() * cpu).round().clamp(1.0, f64::from(u32::MAX)) as u32
            }
        };
        Some(DriveHomingObjects {
            method: h.drive_method,
            search_speed_counts_s: rate(h.search_velocity_units_s),
            zero_speed_counts_s: rate(h.latch_velocity_units_s),
            acceleration_counts_s2: rate(h.acceleration_units_s2),
            home_offset_counts: drive.scale.to_counts(h.home_offset_units).unwrap_or(0),
        })
    }

    /// The configuration with each EtherCAT drive's homing objects filled in (for the
    /// axes homed by their drive): what the daemon writes at bring-up.
    pub(crate) fn with_drive_homing_on_the_bus(mut self) -> Config {
        let objects: Vec<Option<DriveHomingObjects>> = match &self.ethercat {
            None => return self,
            Some(bus) => bus
                .drives
                .iter()
                .map(|d| self.drive_homing_objects(d.axis_index))
                .collect(),
        };
        if let Some(bus) = &mut self.ethercat {
            for (drive, homing) in bus.drives.iter_mut().zip(objects) {
                drive.homing = homing;
            }
        }
        self
    }

    /// The simulated drive's homing configuration for axis `axis` (0 X to 5 C): `None`
    /// unless its `[axes.*.homing]` is of kind "drive" and its drive is simulated. The
    /// objects of [`Config::drive_homing_objects`]; the home switch of `[axes.*.sim]`
    /// (`home_switch_mm`, a position in the drive's own frame) in counts of the motor's
    /// frame (through the scale, unrounded); the search limit `search_distance_mm` in
    /// counts. Set it on the drive with `kerf_drive::sim::SimDrive::set_homing_config`.
    pub fn sim_homing(&self, axis: usize) -> Option<SimHomingConfig> {
        let objects = self.drive_homing_objects(axis)?;
        let setup = self.setups.get(axis).copied().flatten()?;
        let drive = self.drive.axes.get(axis).copied().flatten()?;
        if drive.kind != DriveKind::Sim {
            return None;
        }
        let cpu = drive.scale.counts_per_unit();
        let direction = f64::from(drive.scale.direction());
        Some(SimHomingConfig {
            method: objects.method,
            search_speed_counts_s: objects.search_speed_counts_s,
            zero_speed_counts_s: objects.zero_speed_counts_s,
            acceleration_counts_s2: objects.acceleration_counts_s2,
            home_offset_counts: objects.home_offset_counts,
            home_switch_counts: setup.sim.home_switch_units.map(|s| direction * cpu * s),
            search_limit_counts: setup.homing.search_distance_units * cpu,
        })
    }
}

/// Whether homing method `method` moves the axis (all but 35 and 37, whose home position
/// is the current one).
pub(crate) fn drive_method_moves(method: i8) -> bool {
    !matches!(
        method,
        homing_method::CURRENT_POSITION | homing_method::CURRENT_POSITION_35
    )
}
