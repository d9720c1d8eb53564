//! Homing, jogging and the axes' switches as plain records: `[homing]` ([`HomingConfig`]),
//! `[jog]` ([`JogConfig`]) and, per axis, `[axes.*.homing]`, `[axes.*.limit_switches]`
//! and `[axes.*.sim]` ([`AxisSetup`], read with [`Config::axis_setups`]).
//!
//! Lengths are mm for X, Y, Z and degrees for A, B, C (`_units` in the names). Switch
//! inputs are the numbers of digital inputs of `[io]` (`M66 P<n>`): on a machine without
//! `[ethercat]` simulated inputs, with it bits of the bus.

use kerf_drive::MAX_AXES;

use crate::Config;
use crate::ranges::*;

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

/// `axes.*.homing.kind`: how an axis finds its machine coordinates. (`"drive"`, CiA 402
/// homing mode, is refused at load: not supported yet.)
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
}

impl HomingKind {
    /// Whether an axis of this kind is homed when the daemon starts (everything but
    /// [`HomingKind::Switch`]).
    pub fn homed_at_start(self) -> bool {
        self != HomingKind::Switch
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
    /// `search_velocity_mm_s` (`_deg_s`): signed, the sign is the direction of the
    /// search; magnitude above 0 and at most the axis's velocity.
    pub search_velocity_units_s: f64,
    /// `latch_velocity_mm_s` (`_deg_s`): signed, the same sign as the search (back off,
    /// then approach the edge again) or the opposite one (leave the switch, latching where
    /// it releases); magnitude above 0 and at most the search's.
    pub latch_velocity_units_s: f64,
    /// `search_distance_mm` (`_deg`): the longest search before the home switch is
    /// declared not found.
    pub search_distance_units: f64,
    /// `home_offset_mm` (`_deg`): the machine coordinate of the switch's latch point
    /// (kind [`HomingKind::Switch`]), or the machine coordinate of encoder position 0
    /// (kind [`HomingKind::Absolute`]).
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
    /// point in the search direction (the sign of
    /// [`AxisHoming::search_velocity_units_s`]); `None`: the operator sets the input
    /// (`kerf input`).
    pub home_switch_units: Option<f64>,
    /// `min_limit_mm` (`_deg`): the simulated min limit switch is active at and below
    /// this point.
    pub min_limit_units: Option<f64>,
    /// `max_limit_mm` (`_deg`): the simulated max limit switch is active at and above
    /// this point.
    pub max_limit_units: Option<f64>,
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
}
