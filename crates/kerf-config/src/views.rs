//! What the daemon's parts read off a configuration: the safety layer's and the drives'
//! settings, the black box, the period.

use std::path::{Path, PathBuf};

use kerf_drive::MAX_AXES;
use kerf_drive::cia402::Enabler;
use kerf_drive::safety::{AxisSafety, SafetyConfig};
use kerf_drive::sim::SimConfig;

use crate::toml_words::number;

use crate::*;

impl Config {
    /// The cycle period, s.
    pub fn period_s(&self) -> f64 {
        f64::from(self.period_us) * 1e-6
    }

    /// The configuration of the safety layer: per axis the limits of `[axes.*]`, the soft
    /// limits `min_mm`/`max_mm` (`min_deg`/`max_deg`), `ferror_*` and `min_ferror_*`; the
    /// period; `safety.margin` and `safety.stall_cycles`.
    pub fn safety_config(&self) -> SafetyConfig {
        let mut axes = [None; MAX_AXES];
        let linear = self.axes.linear().map(|l| {
            Some((
                AxisLimits {
                    velocity_units_s: l.velocity_mm_s,
                    acceleration_units_s2: l.acceleration_mm_s2,
                    jerk_units_s3: l.jerk_mm_s3,
                },
                l.min_mm,
                l.max_mm,
            ))
        });
        let rotary = self.axes.rotary().map(|r| {
            r.map(|r| {
                (
                    AxisLimits {
                        velocity_units_s: r.velocity_deg_s,
                        acceleration_units_s2: r.acceleration_deg_s2,
                        jerk_units_s3: r.jerk_deg_s3,
                    },
                    r.min_deg,
                    r.max_deg,
                )
            })
        });
        for (i, axis) in linear.iter().chain(rotary.iter()).enumerate() {
            if let (Some((limits, min, max)), Some(drive)) = (axis, &self.drive.axes[i]) {
                axes[i] = Some(AxisSafety {
                    limits: *limits,
                    min_limit_units: *min,
                    max_limit_units: *max,
                    ferror_units: drive.ferror_mm_deg,
                    min_ferror_units: drive.min_ferror_mm_deg,
                });
            }
        }
        SafetyConfig {
            axes,
            period_s: self.period_s(),
            margin: self.drive.margin,
            stall_cycles: self.drive.stall_cycles,
            // On EtherCAT the frame that carries a command brings back the inputs of the
            // cycle before.
            feedback_delay_cycles: usize::from(self.ethercat.is_some()),
        }
    }

    /// What each axis's drive is built from, X to C (`None` where the machine has no axis).
    pub fn drive_configs(&self) -> [Option<DriveSetup>; MAX_AXES] {
        let period_ns = u64::from(self.period_us) * 1000;
        self.drive.axes.map(|axis| {
            axis.map(|d| DriveSetup {
                kind: d.kind,
                scale: d.scale,
                sim: SimConfig {
                    period_ns,
                    initial_position_counts: 0.0,
                    ..d.sim
                },
                enable_timeout_cycles: Enabler::timeout_cycles_for(
                    u64::from(d.enable_timeout_ms) * 1_000_000,
                    period_ns,
                ),
            })
        })
    }

    /// The axes the black-box recorder writes (those the machine has), X to C.
    pub fn recorder_axes(&self) -> [bool; MAX_AXES] {
        self.drive.axes.map(|a| a.is_some())
    }

    /// Where the daemon writes black-box files: `safety.dump_dir` when set; else the
    /// directory systemd gives the service (`$STATE_DIRECTORY`, `/var/lib/kerf` with the
    /// shipped unit), else /var/lib/kerf when it exists; else the system's temporary
    /// directory.
    pub fn dump_dir(&self) -> PathBuf {
        if let Some(d) = &self.dump_dir {
            return d.clone();
        }
        state_directory()
    }

    /// `daemon.state_file`, or by default `MACHINE.state.toml` (the machine's name) in
    /// the state directory: `$STATE_DIRECTORY`, else /var/lib/kerf when it exists (the
    /// shipped systemd unit's), else the temporary directory.
    pub fn state_file(&self) -> PathBuf {
        if let Some(f) = &self.daemon.state_file {
            return f.clone();
        }
        state_directory().join(DEFAULT_STATE_FILE_NAME.replace("MACHINE", &self.machine))
    }

    /// Checks what only the daemon's drive side needs: each simulated drive's `substeps`
    /// keep its model accurate and stable at this period
    /// (`kerf_drive::sim::SimConfig::stability_index` at most 2). `kerf sim`, which runs
    /// no drives, accepts a configuration this refuses.
    pub fn check_drives(&self) -> Result<(), String> {
        for (i, setup) in self.drive_configs().iter().enumerate() {
            let Some(d) = setup else { continue };
            if d.kind == DriveKind::Sim && d.sim.stability_index() > 2.0 {
                return Err(format!(
                    "`axes.{}.drive.substeps` = {} is too few for `bandwidth_hz` = {} and `damping` = {} at `period_us` = {}: the simulated drive's model would not be accurate or would diverge; use at least {}",
                    kerf_geom::AXIS_NAMES[i].to_ascii_lowercase(),
                    d.sim.substeps,
                    number(d.sim.bandwidth_hz),
                    number(d.sim.damping),
                    self.period_us,
                    d.sim.min_substeps()
                ));
            }
        }
        Ok(())
    }

    /// The black-box recorder's capacity, cycles: `safety.recorder_seconds` over the
    /// period, rounded to the nearest (at least 1).
    pub fn recorder_capacity(&self) -> usize {
        // Both factors are range-checked: at most 60 s / 50 µs = 1.2 million cycles.
        ((self.drive.recorder_seconds / self.period_s()).round() as usize).max(1)
    }
}

/// The machine's state directory, shared by the daemon and the `kerf` commands: the first
/// of systemd's `$STATE_DIRECTORY`; else `/var/lib/kerf` when it is a directory (the
/// shipped unit's `StateDirectory`, so that an operator's `kerf` finds the files the
/// service keeps); else the temporary directory.
pub(crate) fn state_directory() -> PathBuf {
    match std::env::var_os("STATE_DIRECTORY") {
        // systemd may list several, separated by colons: the first is ours.
        Some(dirs) if !dirs.is_empty() => {
            let dirs = dirs.to_string_lossy().into_owned();
            PathBuf::from(dirs.split(':').next().unwrap_or(&dirs))
        }
        _ if Path::new(SYSTEM_STATE_DIRECTORY).is_dir() => PathBuf::from(SYSTEM_STATE_DIRECTORY),
        _ => std::env::temp_dir(),
    }
}
