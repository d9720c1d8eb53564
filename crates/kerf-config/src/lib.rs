//! The machine configuration file (TOML): the one crate that knows it.
//!
//! - this module: the file read and checked once into a plain [`Config`] record;
//! - [`reference`](mod@reference): the reference of every key (docs/CONFIG.md is generated from it);
//! - [`tooltable`]: LinuxCNC tool tables and parameter files; the machine's own copies,
//!   which `kerf run`, `mdi`, `offset` and `tool` keep ([`Config::machine_parameter_file`]);
//! - [`travel`]: the configured travel checked on the exact path before any motion;
//! - [`machine_limits`]: the motion core's view of the axes;
//! - [`ethercat`]: the EtherCAT bus (`[ethercat]`), when the machine's drives are on one;
//! - the machine's functions besides the axes: [`IoConfig`] (`[io]`), [`SpindleConfig`],
//!   [`CoolantConfig`], [`ToolChanger`], [`OperatorConfig`], and [`MachineCaps`]
//!   ([`Config::machine_check`]), what a program may command;
//! - homing, jogging and the axes' switches: [`HomingConfig`] (`[homing]`), [`JogConfig`]
//!   (`[jog]`), and per axis [`AxisSetup`] ([`Config::axis_setups`]).
//!
//! A machine builder writes one file per machine; `config/kerf.toml` in the repository is a
//! commented 3-axis mill example and is compiled into the binary as the default
//! ([`Config::builtin`]). The file is read once, validated completely, and turned into a
//! plain [`Config`] record; nothing downstream re-checks it.
//!
//! Design decisions:
//! - Unknown keys are an error that names the key: a misspelt limit silently falling back
//!   to a default is how a machine gets driven past what its axes can take.
//! - Every error names the file, and the line and column where TOML gives a place, in the
//!   same `FILE:LINE:COL: error: MESSAGE` shape as program errors.
//! - Every quantity carries its unit in the key and in the field name (`jerk_mm_s3`).
#![deny(missing_docs)]
#![forbid(unsafe_code)]

mod check;
mod error;
mod homing;
mod load;
mod machine;
mod model;
mod ranges;
mod raw;
mod serve;
mod state_files;
mod toml_words;
mod views;

pub mod ethercat;
pub mod reference;
pub mod tooltable;
pub mod travel;

use std::path::Path;

use kerf_geom::{AxisLimits, MachineLimits};

pub use error::{ConfigError, TextPosition};
pub use homing::*;
pub use machine::*;
pub use model::*;
pub use ranges::*;
pub use raw::valid_machine_name;
pub use serve::*;
pub use state_files::{SYSTEM_STATE_DIRECTORY, ToolFileError};

/// The bundled example configuration (`config/kerf.toml`), used when no `--config` is given.
pub const BUILTIN_TOML: &str = include_str!("../../../config/kerf.toml");

/// The name under which errors in [`BUILTIN_TOML`] are reported.
pub const BUILTIN_ORIGIN: &str = "<built-in config/kerf.toml>";

/// Where every command looks for the machine configuration when `--config` is not given.
pub const SYSTEM_CONFIG: &str = "/etc/kerf/kerf.toml";

/// The configuration every command uses: `path` when given, else [`SYSTEM_CONFIG`] when
/// that file exists, else the built-in example. Returns it with the name of where it came
/// from.
pub fn load_default(path: Option<&Path>) -> Result<(Config, String), ConfigError> {
    match path {
        Some(p) => Ok((Config::load(p)?, p.display().to_string())),
        None if Path::new(SYSTEM_CONFIG).exists() => Ok((
            Config::load(Path::new(SYSTEM_CONFIG))?,
            SYSTEM_CONFIG.to_string(),
        )),
        None => Ok((Config::builtin(), BUILTIN_ORIGIN.to_string())),
    }
}

/// The motion core's view of a configuration.
pub fn machine_limits(config: &Config) -> MachineLimits {
    let mut axes = [None; 6];
    for (i, l) in config.axes.linear().iter().enumerate() {
        axes[i] = Some(AxisLimits {
            velocity_units_s: l.velocity_mm_s,
            acceleration_units_s2: l.acceleration_mm_s2,
            jerk_units_s3: l.jerk_mm_s3,
        });
    }
    for (i, r) in config.axes.rotary().iter().enumerate() {
        axes[3 + i] = r.map(|r| AxisLimits {
            velocity_units_s: r.velocity_deg_s,
            acceleration_units_s2: r.acceleration_deg_s2,
            jerk_units_s3: r.jerk_deg_s3,
        });
    }
    MachineLimits {
        axes,
        period_s: config.period_us as f64 * 1e-6,
        tolerance_mm: config.tolerance_mm,
    }
}

/// The machine name a configuration file's text gives (`machine`, else
/// [`DEFAULT_MACHINE`]), read without checking the rest of the file and without reading
/// the files it names; `None` when the text is not TOML or `machine` is not a string.
/// For a client that must find another user's daemon from its configuration alone.
pub fn machine_name(text: &str) -> Option<String> {
    let table: toml::Table = toml::from_str(text).ok()?;
    match table.get("machine") {
        Some(toml::Value::String(m)) => Some(m.clone()),
        Some(_) => None,
        None => Some(DEFAULT_MACHINE.to_string()),
    }
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_ethercat;
#[cfg(test)]
mod tests_ethercat_objects;
#[cfg(test)]
mod tests_homing;
#[cfg(test)]
mod tests_machine;
#[cfg(test)]
mod tests_serve;
