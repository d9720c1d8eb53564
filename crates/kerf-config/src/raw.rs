//! The file as TOML gives it: every key optional and spanned, so that the checker can
//! name the place of a bad value.

use std::collections::BTreeMap;

use serde::Deserialize;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawConfig {
    pub(crate) machine: Option<Spanned<String>>,
    #[serde(default)]
    pub(crate) daemon: RawDaemon,
    pub(crate) dialect: Option<Spanned<String>>,
    pub(crate) period_us: Option<Spanned<i64>>,
    pub(crate) tolerance_mm: Option<Spanned<f64>>,
    pub(crate) axes: RawAxes,
    #[serde(default)]
    pub(crate) gcode: RawGcode,
    #[serde(default)]
    pub(crate) work_offsets: RawWorkOffsets,
    #[serde(default)]
    pub(crate) tools: Vec<RawTool>,
    #[serde(default)]
    pub(crate) safety: RawSafety,
    pub(crate) ethercat: Option<Spanned<RawEthercat>>,
    #[serde(default)]
    pub(crate) io: RawIo,
    pub(crate) spindle: Option<Spanned<RawSpindle>>,
    #[serde(default)]
    pub(crate) coolant: RawCoolant,
    pub(crate) tool_changer: Option<Spanned<RawToolChanger>>,
    #[serde(default)]
    pub(crate) operator: RawOperator,
    #[serde(default)]
    pub(crate) homing: RawHoming,
    #[serde(default)]
    pub(crate) jog: RawJog,
    #[serde(default)]
    pub(crate) serve: RawServe,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawAxes {
    pub(crate) x: RawLinearAxis,
    pub(crate) y: RawLinearAxis,
    pub(crate) z: RawLinearAxis,
    pub(crate) a: Option<RawRotaryAxis>,
    pub(crate) b: Option<RawRotaryAxis>,
    pub(crate) c: Option<RawRotaryAxis>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawLinearAxis {
    pub(crate) velocity_mm_s: Spanned<f64>,
    pub(crate) acceleration_mm_s2: Spanned<f64>,
    pub(crate) jerk_mm_s3: Spanned<f64>,
    pub(crate) min_mm: Spanned<f64>,
    pub(crate) max_mm: Spanned<f64>,
    pub(crate) ferror_mm: Option<Spanned<f64>>,
    pub(crate) min_ferror_mm: Option<Spanned<f64>>,
    pub(crate) drive: Option<RawDrive>,
    pub(crate) homing: Option<RawLinearHoming>,
    pub(crate) limit_switches: Option<RawLimitSwitches>,
    pub(crate) sim: Option<Spanned<RawLinearSim>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawRotaryAxis {
    pub(crate) velocity_deg_s: Spanned<f64>,
    pub(crate) acceleration_deg_s2: Spanned<f64>,
    pub(crate) jerk_deg_s3: Spanned<f64>,
    pub(crate) min_deg: Spanned<f64>,
    pub(crate) max_deg: Spanned<f64>,
    pub(crate) ferror_deg: Option<Spanned<f64>>,
    pub(crate) min_ferror_deg: Option<Spanned<f64>>,
    pub(crate) drive: Option<RawDrive>,
    pub(crate) homing: Option<RawRotaryHoming>,
    pub(crate) limit_switches: Option<RawLimitSwitches>,
    pub(crate) sim: Option<Spanned<RawRotarySim>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawDrive {
    pub(crate) kind: Option<Spanned<String>>,
    pub(crate) counts_per_mm: Option<Spanned<f64>>,
    pub(crate) counts_per_deg: Option<Spanned<f64>>,
    pub(crate) direction: Option<Spanned<i64>>,
    pub(crate) bandwidth_hz: Option<Spanned<f64>>,
    pub(crate) damping: Option<Spanned<f64>>,
    pub(crate) inertia_ratio: Option<Spanned<f64>>,
    pub(crate) velocity_feed_forward: Option<Spanned<f64>>,
    pub(crate) substeps: Option<Spanned<i64>>,
    pub(crate) overcurrent_accel_counts_s2: Option<Spanned<f64>>,
    pub(crate) quick_stop_decel_counts_s2: Option<Spanned<f64>>,
    pub(crate) following_error_window_counts: Option<Spanned<i64>>,
    pub(crate) enable_timeout_ms: Option<Spanned<i64>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSafety {
    pub(crate) margin: Option<Spanned<f64>>,
    pub(crate) stall_cycles: Option<Spanned<i64>>,
    pub(crate) recorder_seconds: Option<Spanned<f64>>,
    pub(crate) dump_dir: Option<Spanned<String>>,
}

#[derive(Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawGcode {
    pub(crate) arc_tolerance_mm: Option<Spanned<f64>>,
    pub(crate) arc_tolerance_rel: Option<Spanned<f64>>,
    pub(crate) tool_table: Option<Spanned<String>>,
    pub(crate) subroutine_path: Option<Spanned<Vec<String>>>,
    pub(crate) max_loop_iterations: Option<Spanned<i64>>,
    pub(crate) block_delete: Option<bool>,
    pub(crate) g28_home_mm_deg: Option<Spanned<Vec<f64>>>,
    pub(crate) g30_home_mm_deg: Option<Spanned<Vec<f64>>>,
    pub(crate) parameter_file: Option<Spanned<String>>,
}

#[derive(Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawWorkOffsets {
    pub(crate) g54: Option<Spanned<Vec<f64>>>,
    pub(crate) g55: Option<Spanned<Vec<f64>>>,
    pub(crate) g56: Option<Spanned<Vec<f64>>>,
    pub(crate) g57: Option<Spanned<Vec<f64>>>,
    pub(crate) g58: Option<Spanned<Vec<f64>>>,
    pub(crate) g59: Option<Spanned<Vec<f64>>>,
    pub(crate) g59_1: Option<Spanned<Vec<f64>>>,
    pub(crate) g59_2: Option<Spanned<Vec<f64>>>,
    pub(crate) g59_3: Option<Spanned<Vec<f64>>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawDaemon {
    pub(crate) priority: Option<Spanned<i64>>,
    pub(crate) cpu: Option<Spanned<i64>>,
    pub(crate) cpu_latency_us: Option<Spanned<i64>>,
    pub(crate) queue_segments: Option<Spanned<i64>>,
    pub(crate) move_window: Option<Spanned<i64>>,
    pub(crate) state_file: Option<Spanned<String>>,
}

/// `true` for a machine name that can be part of a service name: ASCII letters, digits,
/// `-` and `_`, 1 to 64 characters.
pub fn valid_machine_name(name: &str) -> bool {
    (1..=64).contains(&name.len())
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawTool {
    pub(crate) number: Spanned<i64>,
    #[serde(default)]
    pub(crate) length_mm: Option<Spanned<f64>>,
    #[serde(default)]
    pub(crate) radius_mm: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawEthercat {
    pub(crate) interface: Spanned<String>,
    pub(crate) dc: Option<bool>,
    pub(crate) sync0_shift_ns: Option<Spanned<i64>>,
    pub(crate) max_missed_cycles: Option<Spanned<i64>>,
    pub(crate) watchdog_us: Option<Spanned<i64>>,
    pub(crate) state_timeout_ms: Option<Spanned<i64>>,
    pub(crate) sdo_timeout_ms: Option<Spanned<i64>>,
    pub(crate) dc_settle_timeout_ms: Option<Spanned<i64>>,
    #[serde(default)]
    pub(crate) drives: Vec<RawEcatDrive>,
    #[serde(default)]
    pub(crate) io: Vec<RawEcatIo>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawEcatDrive {
    pub(crate) axis: Spanned<String>,
    pub(crate) position: Spanned<i64>,
    pub(crate) vendor_id: Spanned<i64>,
    pub(crate) product_code: Spanned<i64>,
    pub(crate) revision: Option<Spanned<i64>>,
    pub(crate) mode: Option<Spanned<String>>,
    pub(crate) rx_pdo_index: Option<Spanned<i64>>,
    pub(crate) tx_pdo_index: Option<Spanned<i64>>,
    pub(crate) rx_pdo: Option<Spanned<Vec<RawPdoEntry>>>,
    pub(crate) tx_pdo: Option<Spanned<Vec<RawPdoEntry>>>,
    #[serde(default)]
    pub(crate) sdo: Vec<RawSdo>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawPdoEntry {
    pub(crate) index: Spanned<i64>,
    pub(crate) subindex: Spanned<i64>,
    pub(crate) bits: Spanned<i64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSdo {
    pub(crate) index: Spanned<i64>,
    pub(crate) subindex: Spanned<i64>,
    #[serde(rename = "type")]
    pub(crate) kind: Spanned<String>,
    pub(crate) value: Spanned<i64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawEcatIo {
    pub(crate) position: Spanned<i64>,
    pub(crate) vendor_id: Spanned<i64>,
    pub(crate) product_code: Spanned<i64>,
    pub(crate) revision: Option<Spanned<i64>>,
    #[serde(default)]
    pub(crate) sdo: Vec<RawSdo>,
    #[serde(default)]
    pub(crate) inputs: BTreeMap<String, Spanned<i64>>,
    #[serde(default)]
    pub(crate) outputs: BTreeMap<String, Spanned<i64>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawIo {
    #[serde(default)]
    pub(crate) digital_outputs: Vec<RawOutput>,
    #[serde(default)]
    pub(crate) digital_inputs: Vec<RawDigitalInput>,
    #[serde(default)]
    pub(crate) analog_outputs: Vec<RawOutput>,
    #[serde(default)]
    pub(crate) analog_inputs: Vec<RawAnalogInput>,
}

/// A digital or an analog output: the same keys.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawOutput {
    pub(crate) number: Spanned<i64>,
    pub(crate) name: Spanned<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawDigitalInput {
    pub(crate) number: Spanned<i64>,
    pub(crate) name: Spanned<String>,
    pub(crate) sim: Option<Spanned<bool>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawAnalogInput {
    pub(crate) number: Spanned<i64>,
    pub(crate) name: Spanned<String>,
    pub(crate) sim: Option<Spanned<f64>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSpindle {
    pub(crate) kind: Option<Spanned<String>>,
    pub(crate) max_rpm: Option<Spanned<f64>>,
    pub(crate) min_rpm: Option<Spanned<f64>>,
    pub(crate) acceleration_rpm_s: Option<Spanned<f64>>,
    pub(crate) at_speed_tolerance: Option<Spanned<f64>>,
    pub(crate) at_speed_timeout_s: Option<Spanned<f64>>,
    pub(crate) fault_out_of_band: Option<bool>,
    pub(crate) orient_timeout_s: Option<Spanned<f64>>,
    pub(crate) enable_output: Option<Spanned<String>>,
    pub(crate) reverse_output: Option<Spanned<String>>,
    pub(crate) speed_output: Option<Spanned<String>>,
    pub(crate) speed_output_scale: Option<Spanned<f64>>,
    pub(crate) at_speed_input: Option<Spanned<String>>,
    pub(crate) spin_up_s: Option<Spanned<f64>>,
    pub(crate) counts_per_rev: Option<Spanned<f64>>,
    pub(crate) off_at_end: Option<bool>,
    pub(crate) off_at_abort: Option<bool>,
    pub(crate) off_at_fault: Option<bool>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawCoolant {
    pub(crate) mist: Option<Spanned<String>>,
    pub(crate) flood: Option<Spanned<String>>,
    pub(crate) off_at_end: Option<bool>,
    pub(crate) off_at_abort: Option<bool>,
    pub(crate) off_at_fault: Option<bool>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawToolChanger {
    pub(crate) kind: Option<Spanned<String>>,
    pub(crate) number_output: Option<Spanned<String>>,
    pub(crate) change_output: Option<Spanned<String>>,
    pub(crate) changed_input: Option<Spanned<String>>,
    pub(crate) timeout_s: Option<Spanned<f64>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawOperator {
    pub(crate) optional_stop: Option<bool>,
    pub(crate) single_block: Option<bool>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawHoming {
    pub(crate) required: Option<bool>,
    pub(crate) unhomed_jog_pct: Option<Spanned<f64>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawJog {
    pub(crate) deadman_ms: Option<Spanned<i64>>,
    pub(crate) default_speed_pct: Option<Spanned<f64>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawServe {
    pub(crate) http: Option<Spanned<String>>,
    pub(crate) opcua: Option<Spanned<String>>,
    pub(crate) manufacturer: Option<Spanned<String>>,
    pub(crate) model: Option<Spanned<String>>,
    pub(crate) serial_number: Option<Spanned<String>>,
    pub(crate) control_token_sha256: Option<Spanned<String>>,
    pub(crate) opcua_certificate: Option<Spanned<String>>,
    pub(crate) opcua_private_key: Option<Spanned<String>>,
    pub(crate) opcua_pki_dir: Option<Spanned<String>>,
    pub(crate) opcua_users: Option<Spanned<Vec<RawOpcuaUser>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawOpcuaUser {
    pub(crate) name: Spanned<String>,
    pub(crate) password_hash: Spanned<String>,
    pub(crate) role: Spanned<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawLinearHoming {
    pub(crate) kind: Spanned<String>,
    pub(crate) switch: Option<Spanned<String>>,
    pub(crate) method: Option<Spanned<i64>>,
    pub(crate) search_velocity_mm_s: Option<Spanned<f64>>,
    pub(crate) latch_velocity_mm_s: Option<Spanned<f64>>,
    pub(crate) acceleration_mm_s2: Option<Spanned<f64>>,
    pub(crate) search_distance_mm: Option<Spanned<f64>>,
    pub(crate) home_offset_mm: Option<Spanned<f64>>,
    pub(crate) home_mm: Option<Spanned<f64>>,
    pub(crate) final_speed_mm_s: Option<Spanned<f64>>,
    pub(crate) sequence: Option<Spanned<i64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawRotaryHoming {
    pub(crate) kind: Spanned<String>,
    pub(crate) switch: Option<Spanned<String>>,
    pub(crate) method: Option<Spanned<i64>>,
    pub(crate) search_velocity_deg_s: Option<Spanned<f64>>,
    pub(crate) latch_velocity_deg_s: Option<Spanned<f64>>,
    pub(crate) acceleration_deg_s2: Option<Spanned<f64>>,
    pub(crate) search_distance_deg: Option<Spanned<f64>>,
    pub(crate) home_offset_deg: Option<Spanned<f64>>,
    pub(crate) home_deg: Option<Spanned<f64>>,
    pub(crate) final_speed_deg_s: Option<Spanned<f64>>,
    pub(crate) sequence: Option<Spanned<i64>>,
}

/// `[axes.*.homing]` of either kind of axis, its keys by role (the names
/// carry the axis's unit: `search_velocity_mm_s` or `search_velocity_deg_s`).
pub(crate) struct AxisHomingKeys<'r> {
    pub(crate) kind: &'r Spanned<String>,
    pub(crate) switch: Option<&'r Spanned<String>>,
    pub(crate) method: Option<&'r Spanned<i64>>,
    pub(crate) search_velocity: Option<&'r Spanned<f64>>,
    pub(crate) latch_velocity: Option<&'r Spanned<f64>>,
    pub(crate) acceleration: Option<&'r Spanned<f64>>,
    pub(crate) search_distance: Option<&'r Spanned<f64>>,
    pub(crate) home_offset: Option<&'r Spanned<f64>>,
    pub(crate) home: Option<&'r Spanned<f64>>,
    pub(crate) final_speed: Option<&'r Spanned<f64>>,
    pub(crate) sequence: Option<&'r Spanned<i64>>,
}

impl RawLinearHoming {
    pub(crate) fn keys(&self) -> AxisHomingKeys<'_> {
        AxisHomingKeys {
            kind: &self.kind,
            switch: self.switch.as_ref(),
            method: self.method.as_ref(),
            search_velocity: self.search_velocity_mm_s.as_ref(),
            latch_velocity: self.latch_velocity_mm_s.as_ref(),
            acceleration: self.acceleration_mm_s2.as_ref(),
            search_distance: self.search_distance_mm.as_ref(),
            home_offset: self.home_offset_mm.as_ref(),
            home: self.home_mm.as_ref(),
            final_speed: self.final_speed_mm_s.as_ref(),
            sequence: self.sequence.as_ref(),
        }
    }
}

impl RawRotaryHoming {
    pub(crate) fn keys(&self) -> AxisHomingKeys<'_> {
        AxisHomingKeys {
            kind: &self.kind,
            switch: self.switch.as_ref(),
            method: self.method.as_ref(),
            search_velocity: self.search_velocity_deg_s.as_ref(),
            latch_velocity: self.latch_velocity_deg_s.as_ref(),
            acceleration: self.acceleration_deg_s2.as_ref(),
            search_distance: self.search_distance_deg.as_ref(),
            home_offset: self.home_offset_deg.as_ref(),
            home: self.home_deg.as_ref(),
            final_speed: self.final_speed_deg_s.as_ref(),
            sequence: self.sequence.as_ref(),
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawLimitSwitches {
    pub(crate) min: Option<Spanned<String>>,
    pub(crate) max: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawLinearSim {
    pub(crate) start_mm: Option<Spanned<f64>>,
    pub(crate) home_switch_mm: Option<Spanned<f64>>,
    pub(crate) min_limit_mm: Option<Spanned<f64>>,
    pub(crate) max_limit_mm: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawRotarySim {
    pub(crate) start_deg: Option<Spanned<f64>>,
    pub(crate) home_switch_deg: Option<Spanned<f64>>,
    pub(crate) min_limit_deg: Option<Spanned<f64>>,
    pub(crate) max_limit_deg: Option<Spanned<f64>>,
}

/// `[axes.*.sim]` of either kind of axis, its keys by role.
pub(crate) struct AxisSimKeys<'r> {
    pub(crate) start: Option<&'r Spanned<f64>>,
    pub(crate) home_switch: Option<&'r Spanned<f64>>,
    pub(crate) min_limit: Option<&'r Spanned<f64>>,
    pub(crate) max_limit: Option<&'r Spanned<f64>>,
}

impl RawLinearSim {
    pub(crate) fn keys(&self) -> AxisSimKeys<'_> {
        AxisSimKeys {
            start: self.start_mm.as_ref(),
            home_switch: self.home_switch_mm.as_ref(),
            min_limit: self.min_limit_mm.as_ref(),
            max_limit: self.max_limit_mm.as_ref(),
        }
    }
}

impl RawRotarySim {
    pub(crate) fn keys(&self) -> AxisSimKeys<'_> {
        AxisSimKeys {
            start: self.start_deg.as_ref(),
            home_switch: self.home_switch_deg.as_ref(),
            min_limit: self.min_limit_deg.as_ref(),
            max_limit: self.max_limit_deg.as_ref(),
        }
    }
}

/// The homing, limit switch and simulation tables of one axis, whichever its kind.
pub(crate) struct AxisSwitchTables<'r> {
    pub(crate) homing: Option<AxisHomingKeys<'r>>,
    pub(crate) limit_switches: Option<&'r RawLimitSwitches>,
    /// The span of `[axes.*.sim]` and its keys.
    pub(crate) sim: Option<(std::ops::Range<usize>, AxisSimKeys<'r>)>,
}

impl RawLinearAxis {
    pub(crate) fn switch_tables(&self) -> AxisSwitchTables<'_> {
        AxisSwitchTables {
            homing: self.homing.as_ref().map(RawLinearHoming::keys),
            limit_switches: self.limit_switches.as_ref(),
            sim: self.sim.as_ref().map(|s| (s.span(), s.get_ref().keys())),
        }
    }
}

impl RawRotaryAxis {
    pub(crate) fn switch_tables(&self) -> AxisSwitchTables<'_> {
        AxisSwitchTables {
            homing: self.homing.as_ref().map(RawRotaryHoming::keys),
            limit_switches: self.limit_switches.as_ref(),
            sim: self.sim.as_ref().map(|s| (s.span(), s.get_ref().keys())),
        }
    }
}
