//! The file as TOML gives it: every key optional and spanned, so that the checker can
//! name the place of a bad value.

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
    pub(crate) queue_segments: Option<Spanned<i64>>,
    pub(crate) move_window: Option<Spanned<i64>>,
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
