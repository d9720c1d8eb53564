//! The machine configuration file (TOML): the one crate that knows it.
//!
//! - this module: the file read and checked once into a plain [`Config`] record;
//! - [`reference`]: the reference of every key (docs/CONFIG.md is generated from it);
//! - [`tooltable`]: LinuxCNC tool tables and parameter files;
//! - [`travel`]: the configured travel checked on the exact path before any motion;
//! - [`machine_limits`]: the motion core's view of the axes.
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

use std::io;
use std::ops::{Range, RangeInclusive};
use std::path::{Path, PathBuf};

use kerf_drive::MAX_AXES;
use kerf_drive::cia402::{Enabler, Scale};
use kerf_drive::safety::{AxisSafety, SafetyConfig};
use kerf_drive::sim::SimConfig;
use kerf_gcode::{Dialect, Settings, Tool};
use kerf_geom::{AxisLimits, MachineLimits};
use serde::Deserialize;
use toml::Spanned;

pub mod reference;
pub mod tooltable;
pub mod travel;

/// The bundled example configuration (`config/kerf.toml`), used when no `--config` is given.
pub const BUILTIN_TOML: &str = include_str!("../../../config/kerf.toml");

/// The name under which errors in [`BUILTIN_TOML`] are reported.
pub const BUILTIN_ORIGIN: &str = "<built-in config/kerf.toml>";

/// Default interpolation period when `period_us` is not given, microseconds.
pub const DEFAULT_PERIOD_US: u32 = 1000;

/// Default path tolerance when `tolerance_mm` is not given, mm.
pub const DEFAULT_TOLERANCE_MM: f64 = 0.01;

/// The longest period accepted, microseconds: beyond one second a "real-time" loop makes
/// no sense and the value is more likely a unit mistake (seconds or nanoseconds).
pub const MAX_PERIOD_US: u32 = 1_000_000;

/// The shortest period accepted, microseconds. EtherCAT masters commonly run 62.5 to 125 µs
/// cycles, and nothing shorter is meaningful for a PC-based interpolator; below about this
/// the finite differences of positions at the period are dominated by floating-point
/// rounding (at 1 µs the third difference of a clean profile reads 142 % of the jerk limit).
pub const MIN_PERIOD_US: u32 = 50;

// The accepted range of every machine number, inclusive at both ends. A value outside
// these ranges is not a machine but a typo or a unit mistake, and some of them make a run
// that can never finish (velocity 1e-300 mm/s) or whose arithmetic breaks down
// (acceleration 1e300 mm/s²). Rotary axes use the same numbers in degrees.

/// Axis velocity, mm/s (deg/s): from 0.001 mm/s (3.6 mm/h, slower than any feed a program
/// can ask for in a useful time) to 100,000 mm/s (6,000 m/min, beyond the fastest linear
/// motors).
pub const VELOCITY_RANGE: RangeInclusive<f64> = 0.001..=100_000.0;

/// Axis acceleration, mm/s² (deg/s²): from 0.01 mm/s² to 1e8 mm/s² (about 10,000 g, far
/// beyond any machine axis).
pub const ACCELERATION_RANGE: RangeInclusive<f64> = 0.01..=1e8;

/// Axis jerk, mm/s³ (deg/s³): from 1 mm/s³ to 1e12 mm/s³ (at a 50 µs period that jerk
/// reaches 1e8 mm/s² in 0.1 ms; higher values only mean "no jerk limit" and strain the
/// arithmetic of the profiles).
pub const JERK_RANGE: RangeInclusive<f64> = 1.0..=1e12;

/// Path tolerance (`tolerance_mm`) and absolute arc end-point tolerance
/// (`gcode.arc_tolerance_mm`), mm: from 1 nm (beyond any machine's resolution; smaller
/// values only make blends vanish in rounding) to 10 mm (a "tolerance" larger than that is
/// not a finishing path any more).
pub const TOLERANCE_RANGE_MM: RangeInclusive<f64> = 1e-6..=10.0;

/// Relative arc end-point tolerance (`gcode.arc_tolerance_rel`), a fraction of the radius:
/// up to 10 % (beyond that the program's arcs are not arcs at all).
pub const ARC_TOLERANCE_REL_RANGE: RangeInclusive<f64> = 1e-9..=0.1;

/// The largest magnitude of a travel limit, work offset or tool length or radius, mm
/// (degrees for rotary travel): one kilometre, larger than any machine bed.
pub const MAX_COORDINATE_MM: f64 = 1e6;

/// The machine name when the file gives none.
pub const DEFAULT_MACHINE: &str = "default";

/// Default real-time priority of the daemon's cycle thread (SCHED_FIFO, 1 to 99): above
/// the kernel's threaded interrupt handlers (50) and below the watchdog threads (99).
pub const DEFAULT_PRIORITY: u8 = 80;

/// Default capacity of the motion core's queue, segments: the lookahead window. `kerf sim`
/// uses the same number, so that the daemon's setpoints equal the simulator's.
pub const DEFAULT_QUEUE_SEGMENTS: u32 = 4096;

/// Accepted queue capacities, segments: below 16 the lookahead cannot reach full speed on
/// short moves; above 65,536 the core's memory (about 1 KiB per segment) serves nothing.
pub const QUEUE_SEGMENTS_RANGE: RangeInclusive<u32> = 16..=65_536;

/// Default number of resolved moves a planner process may have sent that the daemon has
/// not yet taken (the flow-control window of `kerf run`).
pub const DEFAULT_MOVE_WINDOW: u32 = 4096;

/// Accepted move windows.
pub const MOVE_WINDOW_RANGE: RangeInclusive<u32> = 16..=65_536;

/// The periods the daemon runs, microseconds: 125 µs (8 kHz) to 10 ms. `kerf sim`
/// accepts a wider range ([`MIN_PERIOD_US`] to [`MAX_PERIOD_US`]) for studies.
pub const DAEMON_PERIOD_RANGE_US: RangeInclusive<u32> = 125..=10_000;

// The drive side (`[axes.*.drive]`, the following-error keys of `[axes.*]`, `[safety]`).
// Read and validated here; the daemon's drive stage is built from them (docs/DRIVES.md).

/// Default drive scale when `counts_per_mm` / `counts_per_deg` is not given: 1000 counts
/// per mm (1 µm) or per degree.
pub const DEFAULT_COUNTS_PER_UNIT: f64 = 1000.0;

/// Accepted drive scales, counts per mm (per degree for rotary axes).
pub const COUNTS_PER_UNIT_RANGE: RangeInclusive<f64> = 1e-3..=1e9;

/// Accepted sim drive position loop bandwidths, Hz (with `damping` and the period, they
/// set the fewest `substeps` that keep the model stable and accurate: see
/// `SimConfig::min_substeps`; a configuration with fewer is refused).
pub const BANDWIDTH_RANGE_HZ: RangeInclusive<f64> = 0.1..=1000.0;

/// Accepted sim drive damping ratios.
pub const DAMPING_RANGE: RangeInclusive<f64> = 0.01..=10.0;

/// Accepted sim drive inertia ratios (the load's inertia over the inertia its position
/// loop was tuned for).
pub const INERTIA_RATIO_RANGE: RangeInclusive<f64> = 0.01..=100.0;

/// Accepted sim drive velocity feed-forward gains.
pub const VELOCITY_FEED_FORWARD_RANGE: RangeInclusive<f64> = 0.0..=1.0;

/// Accepted sim drive integration substeps per period.
pub const SUBSTEPS_RANGE: RangeInclusive<u32> = 1..=1000;

/// Accepted sim drive accelerations (overcurrent threshold, quick-stop deceleration),
/// counts/s².
pub const DRIVE_ACCELERATION_RANGE_COUNTS_S2: RangeInclusive<f64> = 1.0..=1e15;

/// Accepted sim drive following-error windows, counts.
pub const FOLLOWING_ERROR_WINDOW_RANGE_COUNTS: RangeInclusive<u32> = 1..=1_000_000_000;

/// Default timeout of each transition of the enable sequence, ms.
pub const DEFAULT_ENABLE_TIMEOUT_MS: u32 = 1000;

/// Accepted enable timeouts, ms.
pub const ENABLE_TIMEOUT_RANGE_MS: RangeInclusive<u32> = 1..=60_000;

/// Default following-error limit at maximum velocity (LinuxCNC `FERROR`), mm or deg.
pub const DEFAULT_FERROR_MM: f64 = 1.0;

/// Default following-error limit at rest (LinuxCNC `MIN_FERROR`), mm or deg.
pub const DEFAULT_MIN_FERROR_MM: f64 = 0.1;

/// Accepted following-error limits, mm or deg.
pub const FERROR_RANGE_MM: RangeInclusive<f64> = 1e-6..=1000.0;

/// Accepted plausibility margins (`safety.margin`), a fraction of the limits.
pub const MARGIN_RANGE: RangeInclusive<f64> = 0.0..=1.0;

/// Accepted `safety.stall_cycles`.
pub const STALL_CYCLES_RANGE: RangeInclusive<u32> = 1..=10_000;

/// Accepted black-box recorder lengths (`safety.recorder_seconds`), s: at most a minute
/// (at 125 µs that is 480,000 cycles, about 100 MB).
pub const RECORDER_SECONDS_RANGE: RangeInclusive<f64> = 0.1..=60.0;

/// The kind of drive behind an axis (`[axes.*.drive] kind`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriveKind {
    /// The simulated CiA 402 servo drive (`kerf_drive::sim`), `"sim"`.
    Sim,
}

impl DriveKind {
    /// Whether the drive runs on its own clock, so that a cycle the daemon misses is a
    /// cycle the drive got no setpoint in. The simulated drive has no clock of its own:
    /// it advances one period per exchange.
    pub fn keeps_time(self) -> bool {
        match self {
            DriveKind::Sim => false,
        }
    }
}

/// The drive side of one axis: `[axes.*.drive]` and the following-error keys of
/// `[axes.*]`. Lengths are mm for X, Y, Z and degrees for A, B, C.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisDrive {
    /// `kind`.
    pub kind: DriveKind,
    /// `counts_per_mm` (`counts_per_deg`) and `direction`.
    pub scale: Scale,
    /// The sim drive's tuning: `bandwidth_hz`, `damping`, `inertia_ratio`,
    /// `velocity_feed_forward`,
    /// `substeps`, `overcurrent_accel_counts_s2`, `quick_stop_decel_counts_s2`,
    /// `following_error_window_counts`. Its period and start position are not keys:
    /// [`Config::drive_configs`] sets them.
    pub sim: SimConfig,
    /// `enable_timeout_ms`: timeout of each transition of the enable sequence, ms.
    pub enable_timeout_ms: u32,
    /// `ferror_mm` (`ferror_deg`) of `[axes.*]`: following-error limit at v_max.
    pub ferror_mm_deg: f64,
    /// `min_ferror_mm` (`min_ferror_deg`) of `[axes.*]`: following-error limit at rest.
    pub min_ferror_mm_deg: f64,
}

impl AxisDrive {
    /// The defaults of an axis without `[axes.*.drive]` (those of [`SimConfig`]).
    fn with_scale(scale: Scale) -> AxisDrive {
        AxisDrive {
            kind: DriveKind::Sim,
            scale,
            sim: SimConfig::default(),
            enable_timeout_ms: DEFAULT_ENABLE_TIMEOUT_MS,
            ferror_mm_deg: DEFAULT_FERROR_MM,
            min_ferror_mm_deg: DEFAULT_MIN_FERROR_MM,
        }
    }
}

/// The drive side of the machine: one [`AxisDrive`] per axis the machine has, and
/// `[safety]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveSide {
    /// X, Y, Z, A, B, C; `None` for an axis the machine does not have.
    pub axes: [Option<AxisDrive>; MAX_AXES],
    /// `safety.margin`: allowed relative excess over the velocity and acceleration limits.
    pub margin: f64,
    /// `safety.stall_cycles`: consecutive missed cycles that trip.
    pub stall_cycles: u32,
    /// `safety.recorder_seconds`: length of the black-box recorder, s.
    pub recorder_seconds: f64,
}

/// What one axis's drive is built from ([`Config::drive_configs`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveSetup {
    /// The kind of drive.
    pub kind: DriveKind,
    /// Counts per mm or degree, and direction.
    pub scale: Scale,
    /// The simulated drive's parameters (for [`DriveKind::Sim`]), at the machine's period,
    /// initial position 0.
    pub sim: SimConfig,
    /// Timeout of each enable transition, cycles (`enable_timeout_ms` rounded up).
    pub enable_timeout_cycles: u32,
}

/// The daemon's own settings (`[daemon]`).
#[derive(Clone, Debug, PartialEq)]
pub struct DaemonConfig {
    /// SCHED_FIFO priority of the cycle thread, 1 to 99.
    pub priority: u8,
    /// CPU the cycle thread is pinned to, if any.
    pub cpu: Option<u32>,
    /// Motion core queue capacity, segments (the lookahead window).
    pub queue_segments: u32,
    /// Resolved moves in flight from a planner process (flow-control window).
    pub move_window: u32,
}

impl Default for DaemonConfig {
    fn default() -> Self {
        DaemonConfig {
            priority: DEFAULT_PRIORITY,
            cpu: None,
            queue_segments: DEFAULT_QUEUE_SEGMENTS,
            move_window: DEFAULT_MOVE_WINDOW,
        }
    }
}

/// Limits of a linear axis (X, Y, Z).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearAxis {
    /// Maximum speed, mm/s.
    pub velocity_mm_s: f64,
    /// Maximum acceleration, mm/s².
    pub acceleration_mm_s2: f64,
    /// Maximum jerk, mm/s³.
    pub jerk_mm_s3: f64,
    /// Lower travel limit, machine coordinates, mm.
    pub min_mm: f64,
    /// Upper travel limit, machine coordinates, mm.
    pub max_mm: f64,
}

/// Limits of a rotary axis (A, B, C).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RotaryAxis {
    /// Maximum speed, degrees/s.
    pub velocity_deg_s: f64,
    /// Maximum acceleration, degrees/s².
    pub acceleration_deg_s2: f64,
    /// Maximum jerk, degrees/s³.
    pub jerk_deg_s3: f64,
    /// Lower travel limit, degrees.
    pub min_deg: f64,
    /// Upper travel limit, degrees.
    pub max_deg: f64,
}

/// The machine's axes: X, Y and Z always, A, B and C when the machine has them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Axes {
    /// X axis.
    pub x: LinearAxis,
    /// Y axis.
    pub y: LinearAxis,
    /// Z axis.
    pub z: LinearAxis,
    /// A axis (rotary about X), if present.
    pub a: Option<RotaryAxis>,
    /// B axis (rotary about Y), if present.
    pub b: Option<RotaryAxis>,
    /// C axis (rotary about Z), if present.
    pub c: Option<RotaryAxis>,
}

impl Axes {
    /// The linear axes in X, Y, Z order.
    pub fn linear(&self) -> [LinearAxis; 3] {
        [self.x, self.y, self.z]
    }

    /// The rotary axes in A, B, C order (`None` where absent).
    pub fn rotary(&self) -> [Option<RotaryAxis>; 3] {
        [self.a, self.b, self.c]
    }
}

/// One entry of the tool table: the interpreter's [`Tool`] (offsets per axis, radius,
/// pocket, lathe data).
pub type ToolEntry = Tool;

/// The accepted `gcode.max_loop_iterations`: at least 1, at most 1e12 (a loop that runs
/// longer is not a program but a hang).
pub const MAX_LOOP_ITERATIONS_RANGE: RangeInclusive<u64> = 1..=1_000_000_000_000;

/// A validated machine configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// The machine's name: every iceoryx2 service of its daemon is named under
    /// `kerf/<machine>/` (ASCII letters, digits, `-`, `_`; 1 to 64 characters).
    pub machine: String,
    /// The daemon's settings.
    pub daemon: DaemonConfig,
    /// The machine control's dialect, if the file names one.
    pub dialect: Option<Dialect>,
    /// Interpolation period, microseconds ([`MIN_PERIOD_US`] to [`MAX_PERIOD_US`]).
    pub period_us: u32,
    /// Default path tolerance for corner blending, mm (within [`TOLERANCE_RANGE_MM`]).
    pub tolerance_mm: f64,
    /// Axis limits.
    pub axes: Axes,
    /// Absolute arc end-point tolerance for the dialects that make it a setting, mm.
    pub arc_tolerance_mm: f64,
    /// Relative arc end-point tolerance (fraction of the radius).
    pub arc_tolerance_rel: f64,
    /// Work offsets G54, G55, G56, G57, G58, G59, G59.1, G59.2, G59.3, mm.
    pub work_offsets_mm: [[f64; 3]; 9],
    /// The tool table: the `[[tools]]` entries, then those of `gcode.tool_table`.
    pub tools: Vec<ToolEntry>,
    /// `gcode.tool_table`: the LinuxCNC tool table file it was read from, if any
    /// (relative paths resolved against the configuration file's directory).
    pub tool_table: Option<PathBuf>,
    /// `gcode.subroutine_path`: directories searched for LinuxCNC subroutine files.
    pub subroutine_path: Vec<PathBuf>,
    /// `safety.dump_dir`: where the daemon writes black-box files (relative to the
    /// configuration file's directory); `None`: see [`Config::dump_dir`].
    pub dump_dir: Option<PathBuf>,
    /// `gcode.max_loop_iterations`: the bound on one LinuxCNC loop.
    pub max_loop_iterations: u64,
    /// `gcode.block_delete`: the block delete switch (off by default, as LinuxCNC starts:
    /// a block starting with `/` runs; on, it is skipped).
    pub block_delete: bool,
    /// `gcode.g28_home_mm_deg`: the G28 position at start, machine X Y Z mm, A B C deg.
    pub g28_home_mm_deg: [f64; 6],
    /// `gcode.g30_home_mm_deg`: the G30 position at start.
    pub g30_home_mm_deg: [f64; 6],
    /// `gcode.parameter_file`: LinuxCNC's persistent numbered parameters, read at program
    /// start ([`Config::program_settings`]) and written by `kerf run` after a program that
    /// ended normally.
    pub parameter_file: Option<PathBuf>,
    /// The drive side: `[axes.*.drive]`, `ferror_*`/`min_ferror_*`, `[safety]` (the
    /// daemon's drive stage is built from it).
    pub drive: DriveSide,
}

/// A 1-based place in a text file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextPosition {
    /// 1-based line.
    pub line: u32,
    /// 1-based column, in characters.
    pub col: u32,
}

/// Why a configuration could not be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{origin}: error: cannot read config: {source}")]
    Io {
        /// The file as named by the user.
        origin: String,
        /// The underlying error.
        source: io::Error,
    },
    /// The file is not valid TOML, has an unknown or missing key, or a value is out of range.
    #[error("{origin}:{}error: {message}", position_prefix(position))]
    Invalid {
        /// The file as named by the user.
        origin: String,
        /// Where in the file, when known.
        position: Option<TextPosition>,
        /// What is wrong, naming the key.
        message: String,
    },
}

fn position_prefix(position: &Option<TextPosition>) -> String {
    match position {
        Some(p) => format!("{}:{}: ", p.line, p.col),
        None => " ".to_string(),
    }
}

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

impl Config {
    /// The bundled example configuration (`config/kerf.toml`).
    pub fn builtin() -> Config {
        // The bundled file is checked by a unit test, so failing here would be a build
        // defect; falling back to the same numbers keeps the binary from ever panicking.
        Config::from_toml_str(BUILTIN_TOML, BUILTIN_ORIGIN).unwrap_or_else(|_| Config {
            machine: DEFAULT_MACHINE.to_string(),
            daemon: DaemonConfig::default(),
            dialect: None,
            period_us: DEFAULT_PERIOD_US,
            tolerance_mm: DEFAULT_TOLERANCE_MM,
            axes: Axes {
                x: FALLBACK_AXIS,
                y: FALLBACK_AXIS,
                z: FALLBACK_AXIS,
                a: None,
                b: None,
                c: None,
            },
            arc_tolerance_mm: Settings::default().arc_tolerance_mm,
            arc_tolerance_rel: Settings::default().arc_tolerance_rel,
            work_offsets_mm: [[0.0; 3]; 9],
            tools: Vec::new(),
            tool_table: None,
            subroutine_path: Vec::new(),
            dump_dir: None,
            max_loop_iterations: Settings::default().max_loop_iterations,
            block_delete: Settings::default().block_delete,
            g28_home_mm_deg: [0.0; 6],
            g30_home_mm_deg: [0.0; 6],
            parameter_file: None,
            drive: DriveSide {
                axes: {
                    let axis = Scale::new(DEFAULT_COUNTS_PER_UNIT, 1)
                        .ok()
                        .map(AxisDrive::with_scale);
                    [axis, axis, axis, None, None, None]
                },
                margin: kerf_drive::safety::DEFAULT_MARGIN,
                stall_cycles: kerf_drive::safety::DEFAULT_STALL_CYCLES,
                recorder_seconds: kerf_drive::recorder::DEFAULT_SECONDS,
            },
        })
    }

    /// Reads and validates the file at `path`; errors name the path as given.
    pub fn load(path: &Path) -> Result<Config, ConfigError> {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            origin: origin.clone(),
            source,
        })?;
        let dir = path.parent().unwrap_or(Path::new(""));
        Config::from_toml_str_in(&text, &origin, dir)
    }

    /// Parses and validates TOML text; `origin` names the text in error messages. The
    /// files it names (`gcode.tool_table`, ...) are relative to the current directory.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Config, ConfigError> {
        Config::from_toml_str_in(text, origin, Path::new(""))
    }

    /// Parses and validates TOML text whose relative file names are relative to `dir`.
    pub fn from_toml_str_in(text: &str, origin: &str, dir: &Path) -> Result<Config, ConfigError> {
        let raw: RawConfig = toml::from_str(text).map_err(|e| ConfigError::Invalid {
            origin: origin.to_string(),
            position: e.span().map(|s| position_of(text, s.start)),
            message: in_file_terms(text, &e),
        })?;
        let check = Checker { text, origin, dir };
        check.config(raw)
    }

    /// The settings of a program run: [`Config::settings`] with the parameters of
    /// `gcode.parameter_file` restored (a missing file restores nothing).
    pub fn program_settings(&self) -> Result<Settings, ConfigError> {
        let mut settings = self.settings();
        if let Some(path) = &self.parameter_file {
            settings.parameters =
                crate::tooltable::load_parameter_file(path, &path.display().to_string())?;
        }
        Ok(settings)
    }

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
                    min_limit: *min,
                    max_limit: *max,
                    ferror: drive.ferror_mm_deg,
                    min_ferror: drive.min_ferror_mm_deg,
                });
            }
        }
        SafetyConfig {
            axes,
            period_s: self.period_s(),
            margin: self.drive.margin,
            stall_cycles: self.drive.stall_cycles,
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
    /// shipped unit); else the system's temporary directory.
    pub fn dump_dir(&self) -> PathBuf {
        if let Some(d) = &self.dump_dir {
            return d.clone();
        }
        match std::env::var_os("STATE_DIRECTORY") {
            // systemd may list several, separated by colons: the first is ours.
            Some(dirs) if !dirs.is_empty() => {
                let dirs = dirs.to_string_lossy().into_owned();
                PathBuf::from(dirs.split(':').next().unwrap_or(&dirs))
            }
            _ => std::env::temp_dir(),
        }
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

    /// The settings the G-code interpreter needs from this configuration.
    pub fn settings(&self) -> Settings {
        Settings {
            work_offsets_mm: self.work_offsets_mm,
            tools: self.tools.clone(),
            arc_tolerance_mm: self.arc_tolerance_mm,
            arc_tolerance_rel: self.arc_tolerance_rel,
            subroutine_path: self.subroutine_path.clone(),
            max_loop_iterations: self.max_loop_iterations,
            block_delete: self.block_delete,
            g28_home_mm_deg: self.g28_home_mm_deg,
            g30_home_mm_deg: self.g30_home_mm_deg,
            ..Settings::default()
        }
    }
}

const FALLBACK_AXIS: LinearAxis = LinearAxis {
    velocity_mm_s: 100.0,
    acceleration_mm_s2: 1000.0,
    jerk_mm_s3: 25000.0,
    min_mm: -500.0,
    max_mm: 500.0,
};

/// A number for a message: plain where that reads well, else in exponent form, so that
/// 1e-300 is not printed with three hundred zeros.
fn number(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-4..1e7).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// The 1-based line and column of byte `offset` in `text`.
fn position_of(text: &str, offset: usize) -> TextPosition {
    let offset = offset.min(text.len());
    // A span may in principle end inside a multi-byte character; step back to a boundary
    // so slicing never panics.
    let mut offset = offset;
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.bytes().filter(|&b| b == b'\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let col = before[line_start..].chars().count() + 1;
    TextPosition {
        line: u32::try_from(line).unwrap_or(u32::MAX),
        col: u32::try_from(col).unwrap_or(u32::MAX),
    }
}

// serde's messages in the file's terms. The raw layout below is read by serde, whose
// messages speak Rust (`invalid type: floating point `1.5`, expected i64`, `missing field
// `z``). Every such message is translated here, for every key alike: the key is found from
// the error's place in the text, the expected value is said in words with the unit its key
// name carries, and the value found is quoted as written in the file.

/// `error`'s message in the file's terms.
fn in_file_terms(text: &str, error: &toml::de::Error) -> String {
    let message = error.message().trim_end();
    let Some(span) = error.span() else {
        return message.to_string();
    };
    let written = text
        .get(span.clone())
        .and_then(|v| v.lines().next())
        .map(|v| v.trim())
        .unwrap_or("");
    let written = if written.chars().count() > 40 {
        format!("{}...", written.chars().take(40).collect::<String>())
    } else {
        written.to_string()
    };
    if let Some(field) = between(message, "missing field `", "`") {
        // The span is the table the key is missing from.
        let key = join(&table_path_of(text, &span), field);
        return if TABLES.contains(&generic(&key).as_str()) {
            format!("missing table [{key}]")
        } else {
            format!("missing key `{key}`")
        };
    }
    if let Some(field) = between(message, "unknown field `", "`") {
        let key = key_path_at(text, span.start).unwrap_or_else(|| field.to_string());
        let expected = message
            .split_once(", expected ")
            .map(|(_, keys)| format!(" (known here: {})", keys.trim_start_matches("one of ")))
            .unwrap_or_default();
        return format!("unknown key `{key}`{expected}");
    }
    let expected = message
        .strip_prefix("invalid type: ")
        .or_else(|| message.strip_prefix("invalid value: "))
        .and_then(|m| m.split_once(", expected "))
        .map(|(_, expected)| expected);
    match (expected, key_path_at(text, span.start)) {
        (Some(expected), Some(key)) => {
            format!(
                "`{key}` must be {}, found {written}",
                expected_in_words(expected, &key)
            )
        }
        (None, Some(key)) => format!("`{key}`: {message}"),
        (_, None) => message.to_string(),
    }
}

/// The keys whose values are tables, with `*` for the rotary or linear axis name.
const TABLES: [&str; 9] = [
    "axes",
    "axes.x",
    "axes.y",
    "axes.z",
    "axes.*.drive",
    "daemon",
    "gcode",
    "work_offsets",
    "safety",
];

/// `key` with an axis table's name replaced by `*` when it is below it (`axes.x.drive`
/// becomes `axes.*.drive`).
fn generic(key: &str) -> String {
    let parts: Vec<&str> = key.split('.').collect();
    if parts.len() > 2 && parts[0] == "axes" {
        let mut parts = parts;
        parts[1] = "*";
        return parts.join(".");
    }
    key.to_string()
}

fn join(path: &str, key: &str) -> String {
    if path.is_empty() {
        key.to_string()
    } else {
        format!("{path}.{key}")
    }
}

/// The text between `start` and the next `end` after it, when `text` starts with `start`.
fn between<'t>(text: &'t str, start: &str, end: &str) -> Option<&'t str> {
    let rest = text.strip_prefix(start)?;
    rest.split_once(end).map(|(inside, _)| inside)
}

/// serde's expectation (`i64`, `f64`, `a string`, `a boolean`, `a sequence`, ...) in words,
/// with the unit the key's name ends with.
fn expected_in_words(expected: &str, key: &str) -> String {
    let last = key.rsplit('.').next().unwrap_or(key);
    let unit = unit_of(last);
    let integer = matches!(
        expected,
        "i8" | "i16" | "i32" | "i64" | "i128" | "u8" | "u16" | "u32" | "u64" | "u128" | "usize"
    ) || expected.contains("integer");
    if integer {
        return match unit {
            Some(unit) => format!("a whole number of {unit}"),
            None => "a whole number".to_string(),
        };
    }
    if matches!(expected, "f32" | "f64") || expected.contains("float") {
        return match unit {
            Some(unit) => format!("a number in {unit}"),
            None => "a number".to_string(),
        };
    }
    if expected.contains("string") {
        return "a string in double quotes".to_string();
    }
    if expected.contains("bool") {
        return "true or false".to_string();
    }
    if expected.contains("sequence") {
        return match unit {
            Some(unit) => format!("an array of numbers in {unit}, such as [0.0, 0.0, 0.0]"),
            None => "an array in brackets, such as [\"a\", \"b\"]".to_string(),
        };
    }
    if expected.contains("struct") || expected.contains("map") {
        return format!("a table ([{key}])");
    }
    expected.to_string()
}

/// The unit a key name ends with, in words (`period_us`: microseconds).
fn unit_of(key: &str) -> Option<&'static str> {
    const UNITS: [(&str, &str); 16] = [
        ("_mm_s3", "mm/s³"),
        ("_mm_s2", "mm/s²"),
        ("_mm_s", "mm/s"),
        ("_deg_s3", "degrees/s³"),
        ("_deg_s2", "degrees/s²"),
        ("_deg_s", "degrees/s"),
        ("_counts_s2", "counts/s²"),
        ("_mm_deg", "mm (degrees for A, B, C)"),
        ("_counts", "counts"),
        ("_cycles", "cycles"),
        ("_seconds", "seconds"),
        ("_us", "microseconds"),
        ("_ms", "milliseconds"),
        ("_hz", "Hz"),
        ("_mm", "mm"),
        ("_deg", "degrees"),
    ];
    UNITS
        .iter()
        .find(|(suffix, _)| key.ends_with(suffix))
        .map(|(_, unit)| *unit)
}

/// The dotted key (`axes.x.velocity_mm_s`, `tools[1].number`) whose key or value holds the
/// byte at `at`, the one with the shortest such span; `None` when the text does not parse.
///
/// A table opened by a header (`[axes.x]`) has the header as its span, not its keys, so
/// every key of the file is looked at, not only those inside a span that holds `at`.
fn key_path_at(text: &str, at: usize) -> Option<String> {
    fn visit(
        value: &toml::de::DeValue<'_>,
        path: &str,
        at: usize,
        best: &mut Option<(usize, String)>,
    ) {
        fn consider(
            span: std::ops::Range<usize>,
            path: &str,
            at: usize,
            best: &mut Option<(usize, String)>,
        ) {
            if span.contains(&at) && best.as_ref().is_none_or(|(len, _)| span.len() < *len) {
                *best = Some((span.len(), path.to_string()));
            }
        }
        match value {
            toml::de::DeValue::Table(table) => {
                for (key, value) in table.iter() {
                    let here = join(path, key.get_ref());
                    consider(key.span(), &here, at, best);
                    consider(value.span(), &here, at, best);
                    visit(value.get_ref(), &here, at, best);
                }
            }
            toml::de::DeValue::Array(items) => {
                for (i, item) in items.iter().enumerate() {
                    let here = format!("{path}[{i}]");
                    consider(item.span(), &here, at, best);
                    visit(item.get_ref(), &here, at, best);
                }
            }
            _ => {}
        }
    }
    let root = toml::de::DeTable::parse(text).ok()?;
    let mut best = None;
    visit(
        &toml::de::DeValue::Table(root.into_inner()),
        "",
        at,
        &mut best,
    );
    best.map(|(_, path)| path)
}

/// The dotted name of the table whose span is `span` (the top level: empty).
fn table_path_of(text: &str, span: &std::ops::Range<usize>) -> String {
    fn find(
        value: &toml::de::DeValue<'_>,
        span: &std::ops::Range<usize>,
        path: &str,
    ) -> Option<String> {
        match value {
            toml::de::DeValue::Table(table) => table.iter().find_map(|(key, value)| {
                let here = join(path, key.get_ref());
                if value.span() == *span && matches!(value.get_ref(), toml::de::DeValue::Table(_)) {
                    return Some(here);
                }
                find(value.get_ref(), span, &here)
            }),
            toml::de::DeValue::Array(items) => items.iter().enumerate().find_map(|(i, item)| {
                let here = format!("{path}[{i}]");
                if item.span() == *span {
                    return Some(here);
                }
                find(item.get_ref(), span, &here)
            }),
            _ => None,
        }
    }
    toml::de::DeTable::parse(text)
        .ok()
        .and_then(|root| find(&toml::de::DeValue::Table(root.into_inner()), span, ""))
        .unwrap_or_default()
}

// The raw file layout. Values that are range-checked are `Spanned` so that the error can
// point at the value, not only name the key.

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawConfig {
    machine: Option<Spanned<String>>,
    #[serde(default)]
    daemon: RawDaemon,
    dialect: Option<Spanned<String>>,
    period_us: Option<Spanned<i64>>,
    tolerance_mm: Option<Spanned<f64>>,
    axes: RawAxes,
    #[serde(default)]
    gcode: RawGcode,
    #[serde(default)]
    work_offsets: RawWorkOffsets,
    #[serde(default)]
    tools: Vec<RawTool>,
    #[serde(default)]
    safety: RawSafety,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawAxes {
    x: RawLinearAxis,
    y: RawLinearAxis,
    z: RawLinearAxis,
    a: Option<RawRotaryAxis>,
    b: Option<RawRotaryAxis>,
    c: Option<RawRotaryAxis>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLinearAxis {
    velocity_mm_s: Spanned<f64>,
    acceleration_mm_s2: Spanned<f64>,
    jerk_mm_s3: Spanned<f64>,
    min_mm: Spanned<f64>,
    max_mm: Spanned<f64>,
    ferror_mm: Option<Spanned<f64>>,
    min_ferror_mm: Option<Spanned<f64>>,
    drive: Option<RawDrive>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRotaryAxis {
    velocity_deg_s: Spanned<f64>,
    acceleration_deg_s2: Spanned<f64>,
    jerk_deg_s3: Spanned<f64>,
    min_deg: Spanned<f64>,
    max_deg: Spanned<f64>,
    ferror_deg: Option<Spanned<f64>>,
    min_ferror_deg: Option<Spanned<f64>>,
    drive: Option<RawDrive>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawDrive {
    kind: Option<Spanned<String>>,
    counts_per_mm: Option<Spanned<f64>>,
    counts_per_deg: Option<Spanned<f64>>,
    direction: Option<Spanned<i64>>,
    bandwidth_hz: Option<Spanned<f64>>,
    damping: Option<Spanned<f64>>,
    inertia_ratio: Option<Spanned<f64>>,
    velocity_feed_forward: Option<Spanned<f64>>,
    substeps: Option<Spanned<i64>>,
    overcurrent_accel_counts_s2: Option<Spanned<f64>>,
    quick_stop_decel_counts_s2: Option<Spanned<f64>>,
    following_error_window_counts: Option<Spanned<i64>>,
    enable_timeout_ms: Option<Spanned<i64>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawSafety {
    margin: Option<Spanned<f64>>,
    stall_cycles: Option<Spanned<i64>>,
    recorder_seconds: Option<Spanned<f64>>,
    dump_dir: Option<Spanned<String>>,
}

#[derive(Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGcode {
    arc_tolerance_mm: Option<Spanned<f64>>,
    arc_tolerance_rel: Option<Spanned<f64>>,
    tool_table: Option<Spanned<String>>,
    subroutine_path: Option<Spanned<Vec<String>>>,
    max_loop_iterations: Option<Spanned<i64>>,
    block_delete: Option<bool>,
    g28_home_mm_deg: Option<Spanned<Vec<f64>>>,
    g30_home_mm_deg: Option<Spanned<Vec<f64>>>,
    parameter_file: Option<Spanned<String>>,
}

#[derive(Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWorkOffsets {
    g54: Option<Spanned<Vec<f64>>>,
    g55: Option<Spanned<Vec<f64>>>,
    g56: Option<Spanned<Vec<f64>>>,
    g57: Option<Spanned<Vec<f64>>>,
    g58: Option<Spanned<Vec<f64>>>,
    g59: Option<Spanned<Vec<f64>>>,
    g59_1: Option<Spanned<Vec<f64>>>,
    g59_2: Option<Spanned<Vec<f64>>>,
    g59_3: Option<Spanned<Vec<f64>>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawDaemon {
    priority: Option<Spanned<i64>>,
    cpu: Option<Spanned<i64>>,
    queue_segments: Option<Spanned<i64>>,
    move_window: Option<Spanned<i64>>,
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
struct RawTool {
    number: Spanned<i64>,
    #[serde(default)]
    length_mm: Option<Spanned<f64>>,
    #[serde(default)]
    radius_mm: Option<Spanned<f64>>,
}

/// Validation with access to the source text, so that errors carry line and column.
struct Checker<'a> {
    text: &'a str,
    origin: &'a str,
    /// The directory relative file names are resolved against.
    dir: &'a Path,
}

impl Checker<'_> {
    fn error(&self, span: Range<usize>, message: String) -> ConfigError {
        ConfigError::Invalid {
            origin: self.origin.to_string(),
            position: Some(position_of(self.text, span.start)),
            message,
        }
    }

    /// A value within `range` (inclusive; NaN is never within), in `unit`.
    fn within(
        &self,
        key: &str,
        unit: &str,
        range: RangeInclusive<f64>,
        value: &Spanned<f64>,
    ) -> Result<f64, ConfigError> {
        let v = *value.get_ref();
        if range.contains(&v) {
            Ok(v)
        } else {
            Err(self.error(
                value.span(),
                format!(
                    "`{key}` must be between {} and {} {unit}, found {}",
                    number(*range.start()),
                    number(*range.end()),
                    number(v)
                ),
            ))
        }
    }

    /// A coordinate-like value: finite and at most [`MAX_COORDINATE_MM`] in magnitude.
    fn coordinate(&self, key: &str, unit: &str, value: &Spanned<f64>) -> Result<f64, ConfigError> {
        self.within(key, unit, -MAX_COORDINATE_MM..=MAX_COORDINATE_MM, value)
    }

    /// A travel range: both ends within ±[`MAX_COORDINATE_MM`] and `min < max`.
    fn range(
        &self,
        keys: (&str, &str),
        unit: &str,
        min: &Spanned<f64>,
        max: &Spanned<f64>,
    ) -> Result<(f64, f64), ConfigError> {
        let lo = self.coordinate(keys.0, unit, min)?;
        let hi = self.coordinate(keys.1, unit, max)?;
        if lo < hi {
            Ok((lo, hi))
        } else {
            Err(self.error(
                max.span(),
                format!(
                    "`{}` ({hi}) must be greater than `{}` ({lo})",
                    keys.1, keys.0
                ),
            ))
        }
    }

    fn linear(&self, name: &str, raw: &RawLinearAxis) -> Result<LinearAxis, ConfigError> {
        let key = |k: &str| format!("axes.{name}.{k}");
        let (min_mm, max_mm) = self.range(
            (&key("min_mm"), &key("max_mm")),
            "mm",
            &raw.min_mm,
            &raw.max_mm,
        )?;
        Ok(LinearAxis {
            velocity_mm_s: self.within(
                &key("velocity_mm_s"),
                "mm/s",
                VELOCITY_RANGE,
                &raw.velocity_mm_s,
            )?,
            acceleration_mm_s2: self.within(
                &key("acceleration_mm_s2"),
                "mm/s²",
                ACCELERATION_RANGE,
                &raw.acceleration_mm_s2,
            )?,
            jerk_mm_s3: self.within(&key("jerk_mm_s3"), "mm/s³", JERK_RANGE, &raw.jerk_mm_s3)?,
            min_mm,
            max_mm,
        })
    }

    fn rotary(
        &self,
        name: &str,
        raw: &Option<RawRotaryAxis>,
    ) -> Result<Option<RotaryAxis>, ConfigError> {
        let Some(raw) = raw else { return Ok(None) };
        let key = |k: &str| format!("axes.{name}.{k}");
        let (min_deg, max_deg) = self.range(
            (&key("min_deg"), &key("max_deg")),
            "deg",
            &raw.min_deg,
            &raw.max_deg,
        )?;
        Ok(Some(RotaryAxis {
            velocity_deg_s: self.within(
                &key("velocity_deg_s"),
                "deg/s",
                VELOCITY_RANGE,
                &raw.velocity_deg_s,
            )?,
            acceleration_deg_s2: self.within(
                &key("acceleration_deg_s2"),
                "deg/s²",
                ACCELERATION_RANGE,
                &raw.acceleration_deg_s2,
            )?,
            jerk_deg_s3: self.within(
                &key("jerk_deg_s3"),
                "deg/s³",
                JERK_RANGE,
                &raw.jerk_deg_s3,
            )?,
            min_deg,
            max_deg,
        }))
    }

    fn offset(&self, key: &str, raw: &Option<Spanned<Vec<f64>>>) -> Result<[f64; 3], ConfigError> {
        let Some(raw) = raw else {
            return Ok([0.0; 3]);
        };
        match raw.get_ref().as_slice() {
            &[x, y, z] if [x, y, z].iter().all(|v| v.abs() <= MAX_COORDINATE_MM) => Ok([x, y, z]),
            _ => Err(self.error(
                raw.span(),
                format!(
                    "`work_offsets.{key}` must be three numbers [x, y, z] between {} and {} mm",
                    number(-MAX_COORDINATE_MM),
                    number(MAX_COORDINATE_MM)
                ),
            )),
        }
    }

    /// A whole number within `range`.
    fn integer(
        &self,
        key: &str,
        what: &str,
        range: RangeInclusive<u32>,
        value: &Spanned<i64>,
    ) -> Result<u32, ConfigError> {
        match u32::try_from(*value.get_ref()) {
            Ok(v) if range.contains(&v) => Ok(v),
            _ => Err(self.error(
                value.span(),
                format!(
                    "`{key}` must be {what} from {} to {}, found {}",
                    range.start(),
                    range.end(),
                    value.get_ref()
                ),
            )),
        }
    }

    /// An optional number within `range`, or `default`.
    fn within_or(
        &self,
        key: &str,
        unit: &str,
        range: RangeInclusive<f64>,
        value: &Option<Spanned<f64>>,
        default: f64,
    ) -> Result<f64, ConfigError> {
        match value {
            None => Ok(default),
            Some(v) => self.within(key, unit, range, v),
        }
    }

    /// An optional whole number within `range`, or `default`.
    fn integer_or(
        &self,
        key: &str,
        what: &str,
        range: RangeInclusive<u32>,
        value: &Option<Spanned<i64>>,
        default: u32,
    ) -> Result<u32, ConfigError> {
        match value {
            None => Ok(default),
            Some(v) => self.integer(key, what, range, v),
        }
    }

    /// The drive side of axis `name`: `[axes.NAME.drive]` and the following-error keys
    /// (`ferror`, `min_ferror`, spanned), in `unit` (`mm` or `deg`); `travel` is the axis's
    /// travel range, which must fit in the drive's 32-bit counts.
    fn axis_drive(
        &self,
        name: &str,
        unit: &str,
        raw: &Option<RawDrive>,
        ferror: (&Option<Spanned<f64>>, &Option<Spanned<f64>>),
        travel: (f64, f64),
    ) -> Result<AxisDrive, ConfigError> {
        let empty = RawDrive::default();
        let raw = raw.as_ref().unwrap_or(&empty);
        let key = |k: &str| format!("axes.{name}.drive.{k}");
        let kind = match &raw.kind {
            None => DriveKind::Sim,
            Some(k) if k.get_ref() == "sim" => DriveKind::Sim,
            Some(k) => {
                return Err(self.error(
                    k.span(),
                    format!(
                        "`{}` must be \"sim\" (the only drive kind so far), found `{}`",
                        key("kind"),
                        k.get_ref()
                    ),
                ));
            }
        };
        // The scale key carries the axis's unit; the other one is a mistake worth naming.
        let (scale_key, wrong) = if unit == "mm" {
            ("counts_per_mm", &raw.counts_per_deg)
        } else {
            ("counts_per_deg", &raw.counts_per_mm)
        };
        if let Some(w) = wrong {
            return Err(self.error(
                w.span(),
                format!(
                    "axis {name} is measured in {unit}: its scale is `{}`",
                    key(scale_key)
                ),
            ));
        }
        let scale_raw = if unit == "mm" {
            &raw.counts_per_mm
        } else {
            &raw.counts_per_deg
        };
        let counts_per_unit = self.within_or(
            &key(scale_key),
            &format!("counts/{unit}"),
            COUNTS_PER_UNIT_RANGE,
            scale_raw,
            DEFAULT_COUNTS_PER_UNIT,
        )?;
        let reach = travel.0.abs().max(travel.1.abs()) * counts_per_unit;
        if reach > f64::from(i32::MAX) {
            let message = format!(
                "`{}` = {} puts the travel limit {} {unit} at {} counts, beyond the drive's 32-bit position ({})",
                key(scale_key),
                number(counts_per_unit),
                number(travel.0.abs().max(travel.1.abs())),
                number(reach),
                i32::MAX
            );
            return Err(match scale_raw {
                Some(v) => self.error(v.span(), message),
                None => ConfigError::Invalid {
                    origin: self.origin.to_string(),
                    position: None,
                    message,
                },
            });
        }
        let direction = match &raw.direction {
            None => 1,
            Some(d) if matches!(*d.get_ref(), 1 | -1) => *d.get_ref() as i32,
            Some(d) => {
                return Err(self.error(
                    d.span(),
                    format!(
                        "`{}` must be +1 or -1, found {}",
                        key("direction"),
                        d.get_ref()
                    ),
                ));
            }
        };
        let scale = Scale::new(counts_per_unit, direction).map_err(|e| ConfigError::Invalid {
            origin: self.origin.to_string(),
            position: scale_raw
                .as_ref()
                .map(|v| position_of(self.text, v.span().start)),
            message: format!("`{}`: {e}", key(scale_key)),
        })?;
        let mut d = AxisDrive::with_scale(scale);
        d.kind = kind;
        d.sim.bandwidth_hz = self.within_or(
            &key("bandwidth_hz"),
            "Hz",
            BANDWIDTH_RANGE_HZ,
            &raw.bandwidth_hz,
            d.sim.bandwidth_hz,
        )?;
        d.sim.damping = self.within_or(
            &key("damping"),
            "(damping ratio)",
            DAMPING_RANGE,
            &raw.damping,
            d.sim.damping,
        )?;
        d.sim.inertia_ratio = self.within_or(
            &key("inertia_ratio"),
            "(load inertia over the tuned inertia)",
            INERTIA_RATIO_RANGE,
            &raw.inertia_ratio,
            d.sim.inertia_ratio,
        )?;
        d.sim.velocity_feed_forward = self.within_or(
            &key("velocity_feed_forward"),
            "(gain)",
            VELOCITY_FEED_FORWARD_RANGE,
            &raw.velocity_feed_forward,
            d.sim.velocity_feed_forward,
        )?;
        d.sim.substeps = self.integer_or(
            &key("substeps"),
            "a number of steps per period",
            SUBSTEPS_RANGE,
            &raw.substeps,
            d.sim.substeps,
        )?;
        d.sim.overcurrent_accel_counts_s2 = self.within_or(
            &key("overcurrent_accel_counts_s2"),
            "counts/s²",
            DRIVE_ACCELERATION_RANGE_COUNTS_S2,
            &raw.overcurrent_accel_counts_s2,
            d.sim.overcurrent_accel_counts_s2,
        )?;
        d.sim.quick_stop_decel_counts_s2 = self.within_or(
            &key("quick_stop_decel_counts_s2"),
            "counts/s²",
            DRIVE_ACCELERATION_RANGE_COUNTS_S2,
            &raw.quick_stop_decel_counts_s2,
            d.sim.quick_stop_decel_counts_s2,
        )?;
        d.sim.following_error_window_counts = self.integer_or(
            &key("following_error_window_counts"),
            "a number of counts",
            FOLLOWING_ERROR_WINDOW_RANGE_COUNTS,
            &raw.following_error_window_counts,
            d.sim.following_error_window_counts,
        )?;
        d.enable_timeout_ms = self.integer_or(
            &key("enable_timeout_ms"),
            "a time in ms",
            ENABLE_TIMEOUT_RANGE_MS,
            &raw.enable_timeout_ms,
            d.enable_timeout_ms,
        )?;
        let ferror_key = format!("axes.{name}.ferror_{unit}");
        let min_ferror_key = format!("axes.{name}.min_ferror_{unit}");
        d.ferror_mm_deg = self.within_or(
            &ferror_key,
            unit,
            FERROR_RANGE_MM,
            ferror.0,
            DEFAULT_FERROR_MM,
        )?;
        d.min_ferror_mm_deg = self.within_or(
            &min_ferror_key,
            unit,
            FERROR_RANGE_MM,
            ferror.1,
            DEFAULT_MIN_FERROR_MM,
        )?;
        if d.min_ferror_mm_deg > d.ferror_mm_deg {
            let message = format!(
                "`{min_ferror_key}` ({}) must be at most `{ferror_key}` ({})",
                number(d.min_ferror_mm_deg),
                number(d.ferror_mm_deg)
            );
            let span = ferror.1.as_ref().or(ferror.0.as_ref()).map(|v| v.span());
            return Err(match span {
                Some(span) => self.error(span, message),
                None => ConfigError::Invalid {
                    origin: self.origin.to_string(),
                    position: None,
                    message,
                },
            });
        }
        Ok(d)
    }

    /// The drive side: every axis's drive and `[safety]`.
    fn drive_side(&self, raw: &RawConfig, axes: &Axes) -> Result<DriveSide, ConfigError> {
        let mut out = [None; MAX_AXES];
        let linear = [
            ("x", &raw.axes.x, axes.x),
            ("y", &raw.axes.y, axes.y),
            ("z", &raw.axes.z, axes.z),
        ];
        for (i, (name, r, a)) in linear.into_iter().enumerate() {
            out[i] = Some(self.axis_drive(
                name,
                "mm",
                &r.drive,
                (&r.ferror_mm, &r.min_ferror_mm),
                (a.min_mm, a.max_mm),
            )?);
        }
        let rotary = [
            ("a", &raw.axes.a, axes.a),
            ("b", &raw.axes.b, axes.b),
            ("c", &raw.axes.c, axes.c),
        ];
        for (i, (name, r, a)) in rotary.into_iter().enumerate() {
            if let (Some(r), Some(a)) = (r, a) {
                out[3 + i] = Some(self.axis_drive(
                    name,
                    "deg",
                    &r.drive,
                    (&r.ferror_deg, &r.min_ferror_deg),
                    (a.min_deg, a.max_deg),
                )?);
            }
        }
        let s = &raw.safety;
        Ok(DriveSide {
            axes: out,
            margin: self.within_or(
                "safety.margin",
                "(fraction of the limits)",
                MARGIN_RANGE,
                &s.margin,
                kerf_drive::safety::DEFAULT_MARGIN,
            )?,
            stall_cycles: self.integer_or(
                "safety.stall_cycles",
                "a number of cycles",
                STALL_CYCLES_RANGE,
                &s.stall_cycles,
                kerf_drive::safety::DEFAULT_STALL_CYCLES,
            )?,
            recorder_seconds: self.within_or(
                "safety.recorder_seconds",
                "s",
                RECORDER_SECONDS_RANGE,
                &s.recorder_seconds,
                kerf_drive::recorder::DEFAULT_SECONDS,
            )?,
        })
    }

    fn daemon(&self, raw: &RawDaemon) -> Result<DaemonConfig, ConfigError> {
        let d = DaemonConfig::default();
        let priority = match &raw.priority {
            None => d.priority,
            Some(p) => self.integer("daemon.priority", "a SCHED_FIFO priority", 1..=99, p)? as u8,
        };
        let cpu = match &raw.cpu {
            None => None,
            Some(c) => Some(self.integer("daemon.cpu", "a CPU number", 0..=4095, c)?),
        };
        let queue_segments = match &raw.queue_segments {
            None => d.queue_segments,
            Some(q) => self.integer(
                "daemon.queue_segments",
                "a number of segments",
                QUEUE_SEGMENTS_RANGE,
                q,
            )?,
        };
        let move_window = match &raw.move_window {
            None => d.move_window,
            Some(w) => self.integer(
                "daemon.move_window",
                "a number of moves",
                MOVE_WINDOW_RANGE,
                w,
            )?,
        };
        Ok(DaemonConfig {
            priority,
            cpu,
            queue_segments,
            move_window,
        })
    }

    fn config(&self, raw: RawConfig) -> Result<Config, ConfigError> {
        let machine = match &raw.machine {
            None => DEFAULT_MACHINE.to_string(),
            Some(m) if valid_machine_name(m.get_ref()) => m.get_ref().clone(),
            Some(m) => {
                return Err(self.error(
                    m.span(),
                    format!(
                        "`machine` must be 1 to 64 ASCII letters, digits, `-` or `_` (it names the daemon's services), found `{}`",
                        m.get_ref()
                    ),
                ));
            }
        };
        let daemon = self.daemon(&raw.daemon)?;
        let dialect = match &raw.dialect {
            None => None,
            Some(name) => Some(Dialect::from_name(name.get_ref()).ok_or_else(|| {
                let known: Vec<&str> = Dialect::ALL.iter().map(|d| d.name()).collect();
                self.error(
                    name.span(),
                    format!(
                        "unknown dialect `{}` in `dialect`, expected one of: {} (or tormach)",
                        name.get_ref(),
                        known.join(", ")
                    ),
                )
            })?),
        };

        let period_us = match &raw.period_us {
            None => DEFAULT_PERIOD_US,
            Some(p) => match u32::try_from(*p.get_ref()) {
                Ok(v) if (MIN_PERIOD_US..=MAX_PERIOD_US).contains(&v) => v,
                _ => {
                    return Err(self.error(
                        p.span(),
                        format!(
                            "`period_us` must be between {MIN_PERIOD_US} and {MAX_PERIOD_US} µs, found {}",
                            p.get_ref()
                        ),
                    ));
                }
            },
        };

        let tolerance_mm = match &raw.tolerance_mm {
            None => DEFAULT_TOLERANCE_MM,
            Some(t) => self.within("tolerance_mm", "mm", TOLERANCE_RANGE_MM, t)?,
        };

        let axes = Axes {
            x: self.linear("x", &raw.axes.x)?,
            y: self.linear("y", &raw.axes.y)?,
            z: self.linear("z", &raw.axes.z)?,
            a: self.rotary("a", &raw.axes.a)?,
            b: self.rotary("b", &raw.axes.b)?,
            c: self.rotary("c", &raw.axes.c)?,
        };
        let mut drive = self.drive_side(&raw, &axes)?;
        // The simulated drives' integration: without `substeps`, enough for their
        // bandwidth and damping at this period (at least the default); a number given
        // that is too small is refused where the drives run (`Config::check_drives`).
        let given = |d: Option<&RawDrive>| d.is_some_and(|d| d.substeps.is_some());
        let raw_substeps = [
            given(raw.axes.x.drive.as_ref()),
            given(raw.axes.y.drive.as_ref()),
            given(raw.axes.z.drive.as_ref()),
            given(raw.axes.a.as_ref().and_then(|a| a.drive.as_ref())),
            given(raw.axes.b.as_ref().and_then(|a| a.drive.as_ref())),
            given(raw.axes.c.as_ref().and_then(|a| a.drive.as_ref())),
        ];
        for (i, d) in drive.axes.iter_mut().enumerate() {
            let Some(d) = d else { continue };
            let sim = SimConfig {
                period_ns: u64::from(period_us) * 1000,
                ..d.sim
            };
            if !raw_substeps[i] {
                d.sim.substeps = d.sim.substeps.max(sim.min_substeps());
            }
        }
        let dump_dir = match &raw.safety.dump_dir {
            None => None,
            Some(d) if d.get_ref().is_empty() => {
                return Err(self.error(
                    d.span(),
                    "`safety.dump_dir` must name a directory, found an empty string".to_string(),
                ));
            }
            Some(d) => Some(self.dir.join(d.get_ref())),
        };

        let defaults = Settings::default();
        let arc_tolerance_mm = match &raw.gcode.arc_tolerance_mm {
            None => defaults.arc_tolerance_mm,
            Some(t) => self.within("gcode.arc_tolerance_mm", "mm", TOLERANCE_RANGE_MM, t)?,
        };
        let arc_tolerance_rel = match &raw.gcode.arc_tolerance_rel {
            None => defaults.arc_tolerance_rel,
            Some(t) => self.within(
                "gcode.arc_tolerance_rel",
                "(fraction of the radius)",
                ARC_TOLERANCE_REL_RANGE,
                t,
            )?,
        };

        let w = &raw.work_offsets;
        let work_offsets_mm = [
            self.offset("g54", &w.g54)?,
            self.offset("g55", &w.g55)?,
            self.offset("g56", &w.g56)?,
            self.offset("g57", &w.g57)?,
            self.offset("g58", &w.g58)?,
            self.offset("g59", &w.g59)?,
            self.offset("g59_1", &w.g59_1)?,
            self.offset("g59_2", &w.g59_2)?,
            self.offset("g59_3", &w.g59_3)?,
        ];

        let mut tools: Vec<ToolEntry> = Vec::with_capacity(raw.tools.len());
        for t in &raw.tools {
            let number = match u32::try_from(*t.number.get_ref()) {
                Ok(n) => n,
                Err(_) => {
                    return Err(self.error(
                        t.number.span(),
                        format!(
                            "`tools.number` must be a tool number from 0 to {}, found {}",
                            u32::MAX,
                            t.number.get_ref()
                        ),
                    ));
                }
            };
            if tools.iter().any(|e| e.number == number) {
                return Err(self.error(
                    t.number.span(),
                    format!("tool {number} is listed twice in `tools`"),
                ));
            }
            let length_mm = match &t.length_mm {
                None => 0.0,
                Some(l) => self.coordinate("tools.length_mm", "mm", l)?,
            };
            let radius_mm = match &t.radius_mm {
                None => 0.0,
                Some(r) => self.within("tools.radius_mm", "mm", 0.0..=MAX_COORDINATE_MM, r)?,
            };
            tools.push(ToolEntry {
                number,
                length_mm,
                radius_mm,
                ..ToolEntry::default()
            });
        }

        let g = &raw.gcode;
        let tool_table = g.tool_table.as_ref().map(|f| self.dir.join(f.get_ref()));
        if let (Some(path), Some(f)) = (&tool_table, &g.tool_table) {
            let table = crate::tooltable::load_tool_table(path, &path.display().to_string())
                .map_err(|e| match e {
                    ConfigError::Io { source, .. } => self.error(
                        f.span(),
                        format!(
                            "cannot read `gcode.tool_table` {}: {source}",
                            path.display()
                        ),
                    ),
                    e => e,
                })?;
            for t in table {
                if tools.iter().any(|e| e.number == t.number) {
                    return Err(self.error(
                        f.span(),
                        format!(
                            "tool {} is both in `tools` and in `gcode.tool_table`",
                            t.number
                        ),
                    ));
                }
                tools.push(t);
            }
        }
        let subroutine_path = match &g.subroutine_path {
            None => Vec::new(),
            Some(list) => list.get_ref().iter().map(|d| self.dir.join(d)).collect(),
        };
        let max_loop_iterations = match &g.max_loop_iterations {
            None => defaults.max_loop_iterations,
            Some(n) => match u64::try_from(*n.get_ref()) {
                Ok(v) if MAX_LOOP_ITERATIONS_RANGE.contains(&v) => v,
                _ => {
                    return Err(self.error(
                        n.span(),
                        format!(
                            "`gcode.max_loop_iterations` must be from {} to {}, found {}",
                            MAX_LOOP_ITERATIONS_RANGE.start(),
                            MAX_LOOP_ITERATIONS_RANGE.end(),
                            n.get_ref()
                        ),
                    ));
                }
            },
        };
        let block_delete = g.block_delete.unwrap_or(defaults.block_delete);
        let g28_home_mm_deg = self.home("gcode.g28_home_mm_deg", &g.g28_home_mm_deg)?;
        let g30_home_mm_deg = self.home("gcode.g30_home_mm_deg", &g.g30_home_mm_deg)?;
        let parameter_file = g
            .parameter_file
            .as_ref()
            .map(|f| self.dir.join(f.get_ref()));

        Ok(Config {
            machine,
            daemon,
            dialect,
            period_us,
            tolerance_mm,
            axes,
            arc_tolerance_mm,
            arc_tolerance_rel,
            work_offsets_mm,
            tools,
            tool_table,
            subroutine_path,
            dump_dir,
            max_loop_iterations,
            block_delete,
            g28_home_mm_deg,
            g30_home_mm_deg,
            parameter_file,
            drive,
        })
    }

    /// A stored position: `[x, y, z]` (mm) or `[x, y, z, a, b, c]` (mm, degrees).
    fn home(&self, key: &str, raw: &Option<Spanned<Vec<f64>>>) -> Result<[f64; 6], ConfigError> {
        let Some(raw) = raw else {
            return Ok([0.0; 6]);
        };
        let v = raw.get_ref();
        if matches!(v.len(), 3 | 6) && v.iter().all(|x| x.abs() <= MAX_COORDINATE_MM) {
            let mut out = [0.0; 6];
            out[..v.len()].copy_from_slice(v);
            return Ok(out);
        }
        Err(self.error(
            raw.span(),
            format!(
                "`{key}` must be [x, y, z] or [x, y, z, a, b, c] (mm, degrees) between {} and {}",
                number(-MAX_COORDINATE_MM),
                number(MAX_COORDINATE_MM)
            ),
        ))
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
mod tests {
    use super::*;

    const MINIMAL: &str = r#"
[axes.x]
velocity_mm_s = 100
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10000.0
min_mm = -10.0
max_mm = 10.0
[axes.y]
velocity_mm_s = 100.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10000.0
min_mm = -10.0
max_mm = 10.0
[axes.z]
velocity_mm_s = 100.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10000.0
min_mm = -10.0
max_mm = 10.0
"#;

    fn err(text: &str) -> String {
        match Config::from_toml_str(text, "m.toml") {
            Ok(_) => panic!("expected an error for:\n{text}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn builtin_config_is_valid_and_is_the_documented_mill() {
        let c = Config::from_toml_str(BUILTIN_TOML, BUILTIN_ORIGIN).expect("bundled config");
        assert_eq!(c.dialect, Some(Dialect::LinuxCnc));
        assert_eq!(c.period_us, 1000);
        assert_eq!(c.tolerance_mm, 0.01);
        assert_eq!(c.axes.x.velocity_mm_s, 200.0);
        assert_eq!(c.axes.x.acceleration_mm_s2, 2000.0);
        assert_eq!(c.axes.x.jerk_mm_s3, 50000.0);
        assert_eq!((c.axes.x.min_mm, c.axes.x.max_mm), (-1000.0, 1000.0));
        assert_eq!(c.axes.a, None);
        assert_eq!(Config::builtin(), c);
    }

    #[test]
    fn minimal_config_takes_documented_defaults() {
        let c = Config::from_toml_str(MINIMAL, "m.toml").unwrap();
        assert_eq!(c.dialect, None);
        assert_eq!(c.period_us, 1000);
        assert_eq!(c.tolerance_mm, 0.01);
        // An integer where a float is expected is accepted as the same number.
        assert_eq!(c.axes.x.velocity_mm_s, 100.0);
        assert_eq!(c.arc_tolerance_mm, 0.02828);
        assert_eq!(c.arc_tolerance_rel, 0.001);
        assert_eq!(c.work_offsets_mm, [[0.0; 3]; 9]);
        assert!(c.tools.is_empty());
    }

    #[test]
    fn unknown_top_level_key_is_named_with_its_place() {
        let text = format!("dialect = \"fagor\"\nperiod_ms = 1\n{MINIMAL}");
        let e = err(&text);
        assert!(e.starts_with("m.toml:2:1: error: "), "{e}");
        assert!(e.contains("period_ms"), "{e}");
    }

    #[test]
    fn unknown_axis_key_is_named() {
        let text = MINIMAL.replace(
            "jerk_mm_s3 = 10000.0\nmin_mm = -10.0\nmax_mm = 10.0\n[axes.y]",
            "jerk_mm_s3 = 10000.0\nmin_mm = -10.0\nmax_mm = 10.0\nfeed_mm_s = 3.0\n[axes.y]",
        );
        let e = err(&text);
        assert!(e.contains("feed_mm_s"), "{e}");
        // The unknown key is on line 8 of the text (MINIMAL starts with an empty line).
        assert!(e.starts_with("m.toml:8:"), "{e}");
    }

    #[test]
    fn unknown_axis_table_is_named() {
        let text = format!("{MINIMAL}[axes.u]\nvelocity_mm_s = 1.0\n");
        let e = err(&text);
        assert!(e.contains("unknown key `axes.u`"), "{e}");
    }

    /// Every key of the file, each in its table (the values are valid).
    const EVERY_KEY: &str = r#"machine = "m1"
dialect = "fagor"
period_us = 1000
tolerance_mm = 0.01
[axes.x]
velocity_mm_s = 100.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10000.0
min_mm = -10.0
max_mm = 10.0
ferror_mm = 1.0
min_ferror_mm = 0.1
[axes.x.drive]
kind = "sim"
counts_per_mm = 1000.0
direction = 1
bandwidth_hz = 50.0
damping = 1.0
velocity_feed_forward = 1.0
substeps = 20
overcurrent_accel_counts_s2 = 1e9
quick_stop_decel_counts_s2 = 1e6
following_error_window_counts = 1000
enable_timeout_ms = 100
[axes.y]
velocity_mm_s = 100.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10000.0
min_mm = -10.0
max_mm = 10.0
[axes.z]
velocity_mm_s = 100.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10000.0
min_mm = -10.0
max_mm = 10.0
[axes.c]
velocity_deg_s = 360.0
acceleration_deg_s2 = 3600.0
jerk_deg_s3 = 90000.0
min_deg = -720.0
max_deg = 720.0
ferror_deg = 1.0
min_ferror_deg = 0.1
[axes.c.drive]
counts_per_deg = 100.0
[safety]
margin = 0.05
stall_cycles = 100
recorder_seconds = 1.0
[daemon]
priority = 80
cpu = 1
queue_segments = 4096
move_window = 1024
[gcode]
arc_tolerance_mm = 0.02
arc_tolerance_rel = 0.001
subroutine_path = ["subs"]
max_loop_iterations = 1000
block_delete = true
g28_home_mm_deg = [0.0, 0.0, 0.0]
g30_home_mm_deg = [0.0, 0.0, 0.0]
[work_offsets]
g54 = [0.0, 0.0, 0.0]
g55 = [0.0, 0.0, 0.0]
g56 = [0.0, 0.0, 0.0]
g57 = [0.0, 0.0, 0.0]
g58 = [0.0, 0.0, 0.0]
g59 = [0.0, 0.0, 0.0]
g59_1 = [0.0, 0.0, 0.0]
g59_2 = [0.0, 0.0, 0.0]
g59_3 = [0.0, 0.0, 0.0]
[[tools]]
number = 1
length_mm = 0.0
radius_mm = 0.0
"#;

    /// A value of every key replaced by one of a wrong type is refused naming the key, in
    /// words and units, with the value as written, at the value's place; never in serde's
    /// Rust terms.
    #[test]
    fn every_type_error_names_the_key_and_the_expected_value_in_the_files_terms() {
        Config::from_toml_str(EVERY_KEY, "m.toml").expect("EVERY_KEY is valid");
        let mut table = String::new();
        let mut checked = 0;
        for (i, line) in EVERY_KEY.lines().enumerate() {
            if let Some(header) = line.strip_prefix("[[").and_then(|l| l.strip_suffix("]]")) {
                table = format!("{header}[0].");
                continue;
            }
            if let Some(header) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
                table = format!("{header}.");
                continue;
            }
            let Some((key, value)) = line.split_once(" = ") else {
                continue;
            };
            let wrong = if value.starts_with('"') || value.starts_with('[') {
                "1.5"
            } else if value == "true" {
                "1"
            } else {
                "\"1.5\""
            };
            let wrong_line = format!("{key} = {wrong}");
            let text: Vec<&str> = EVERY_KEY
                .lines()
                .enumerate()
                .map(|(j, l)| if j == i { wrong_line.as_str() } else { l })
                .collect();
            let text = text.join("\n");
            let e = err(&text);
            let place = format!("m.toml:{}:{}: error: ", i + 1, key.len() + 4);
            let expected = format!("{place}`{table}{key}` must be ");
            assert!(e.starts_with(&expected), "{key} = {wrong}: {e}");
            assert!(
                e.ends_with(&format!(", found {wrong}")),
                "{key} = {wrong}: {e}"
            );
            for rust in [
                "invalid type",
                "expected",
                "i64",
                "f64",
                "sequence",
                "field",
            ] {
                assert!(!e.contains(rust), "{key} = {wrong}: {e}");
            }
            checked += 1;
        }
        // 4 top-level keys, 7 + 11 of X and its drive, 5 of Y, 5 of Z, 7 + 1 of C and its
        // drive, 3 of [safety], 4 of [daemon], 7 of [gcode], 9 work offsets, 3 of a tool.
        assert_eq!(checked, 66);
        // The messages of some keys in full: the unit comes from the key's name.
        let e = err(&EVERY_KEY.replacen("period_us = 1000", "period_us = 1.5", 1));
        assert_eq!(
            e,
            "m.toml:3:13: error: `period_us` must be a whole number of microseconds, found 1.5"
        );
        let e = err(&EVERY_KEY.replacen("jerk_deg_s3 = 90000.0", "jerk_deg_s3 = \"fast\"", 1));
        assert!(
            e.ends_with("`axes.c.jerk_deg_s3` must be a number in degrees/s³, found \"fast\""),
            "{e}"
        );
        let e = err(&EVERY_KEY.replacen("block_delete = true", "block_delete = 1", 1));
        assert!(
            e.ends_with("`gcode.block_delete` must be true or false, found 1"),
            "{e}"
        );
        let e = err(&EVERY_KEY.replacen("machine = \"m1\"", "machine = m1", 1));
        assert!(e.contains("error: "), "a syntax error stays one: {e}");
    }

    #[test]
    fn missing_keys_and_tables_are_named_with_their_table() {
        let e = err(&EVERY_KEY.replacen("max_mm = 10.0\nferror_mm", "ferror_mm", 1));
        assert_eq!(e, "m.toml:5:1: error: missing key `axes.x.max_mm`");
        let e = err("period_us = 1000\n");
        assert_eq!(e, "m.toml:1:1: error: missing table [axes]");
        let e = err(&format!("{MINIMAL}[[tools]]\nlength_mm = 1.0\n"));
        assert!(e.ends_with("error: missing key `tools[0].number`"), "{e}");
    }

    #[test]
    fn missing_required_axis_is_reported() {
        let text = MINIMAL.split("[axes.z]").next().unwrap();
        let e = err(text);
        assert!(e.contains("error: missing table [axes.z]"), "{e}");
    }

    #[test]
    fn non_positive_limit_points_at_the_value() {
        let text = MINIMAL.replacen(
            "acceleration_mm_s2 = 1000.0",
            "acceleration_mm_s2 = -5.0",
            1,
        );
        let e = err(&text);
        // Line 4, after `acceleration_mm_s2 = ` (21 characters).
        assert!(e.starts_with("m.toml:4:22: error: "), "{e}");
        assert!(e.contains("axes.x.acceleration_mm_s2"), "{e}");
        assert!(e.contains("-5"), "{e}");
    }

    #[test]
    fn zero_jerk_and_infinite_velocity_are_rejected() {
        let e = err(&MINIMAL.replacen("jerk_mm_s3 = 10000.0", "jerk_mm_s3 = 0", 1));
        assert!(e.contains("axes.x.jerk_mm_s3"), "{e}");
        let e = err(&MINIMAL.replacen("velocity_mm_s = 100.0", "velocity_mm_s = inf", 1));
        assert!(e.contains("axes.y.velocity_mm_s"), "{e}");
        let e = err(&MINIMAL.replacen("velocity_mm_s = 100.0", "velocity_mm_s = nan", 1));
        assert!(e.contains("axes.y.velocity_mm_s"), "{e}");
    }

    #[test]
    fn min_must_be_below_max() {
        let e = err(&MINIMAL.replacen("max_mm = 10.0", "max_mm = -10.0", 1));
        assert!(e.contains("axes.x.max_mm"), "{e}");
        assert!(e.contains("axes.x.min_mm"), "{e}");
        let e = err(&MINIMAL.replacen("min_mm = -10.0", "min_mm = 10.0", 1));
        assert!(e.contains("greater than"), "{e}");
    }

    #[test]
    fn period_must_be_positive() {
        for bad in ["0", "-1000", "5000000000"] {
            let e = err(&format!("period_us = {bad}\n{MINIMAL}"));
            assert!(e.starts_with("m.toml:1:13: error: "), "{e}");
            assert!(e.contains("period_us"), "{e}");
        }
        let e = err(&format!("period_us = 1.5\n{MINIMAL}"));
        assert!(e.starts_with("m.toml:1:"), "{e}");
    }

    /// Every key of `[axes.x.drive]`, at its default.
    const DRIVE_X: &str = "[axes.x.drive]\nkind = \"sim\"\ncounts_per_mm = 1000.0\ndirection = 1\nbandwidth_hz = 50.0\ndamping = 1.0\ninertia_ratio = 1.0\nvelocity_feed_forward = 1.0\nsubsteps = 20\novercurrent_accel_counts_s2 = 1e9\nquick_stop_decel_counts_s2 = 1e6\nfollowing_error_window_counts = 1000\nenable_timeout_ms = 1000\n";

    /// MINIMAL with every optional table, so that any key can be set by [`with_key`].
    fn full() -> String {
        let minimal = MINIMAL.replacen(
            "max_mm = 10.0\n",
            "max_mm = 10.0\nferror_mm = 1.0\nmin_ferror_mm = 0.1\n",
            1,
        );
        format!(
            "{minimal}{DRIVE_X}[axes.c]\nvelocity_deg_s = 360.0\nacceleration_deg_s2 = 3600.0\njerk_deg_s3 = 90000.0\nmin_deg = -720.0\nmax_deg = 720.0\nferror_deg = 1.0\nmin_ferror_deg = 0.1\n[axes.c.drive]\ncounts_per_deg = 1000.0\n[safety]\nmargin = 0.05\nstall_cycles = 3\nrecorder_seconds = 10.0\n[gcode]\narc_tolerance_mm = 0.02828\narc_tolerance_rel = 0.001\n[work_offsets]\ng54 = [0.0, 0.0, 0.0]\n[[tools]]\nnumber = 1\nlength_mm = 0.0\nradius_mm = 0.0\n"
        )
    }

    /// [`full`] with `key = value` in `table` (`""`: the top level), and the 1-based line
    /// and column where the value starts.
    /// The full example with `key = value` in `table` is a valid configuration.
    fn assert_accepted(table: &str, key: &str, value: &str) {
        let (text, _) = with_key(table, key, value);
        if let Err(e) = Config::from_toml_str(&text, "m.toml") {
            panic!("{key} = {value} must be accepted: {e}");
        }
    }

    fn with_key(table: &str, key: &str, value: &str) -> (String, String) {
        let text = full();
        let (text, at) = if table.is_empty() {
            (format!("{key} = {value}\n{text}"), 0)
        } else {
            let header = text.find(&format!("[{table}]")).expect("table");
            let line = header + text[header..].find(&format!("\n{key} = ")).expect("key") + 1;
            let end = line + text[line..].find('\n').unwrap();
            (
                format!("{}{key} = {value}{}", &text[..line], &text[end..]),
                line,
            )
        };
        let line_no = text[..at].matches('\n').count() + 1;
        let place = format!("m.toml:{line_no}:{}: error: ", key.len() + 4);
        (text, place)
    }

    /// Every machine number is accepted at both ends of its documented range and rejected
    /// just outside them, with the key, the unit and the range in the message and the
    /// value's place in the file.
    #[test]
    fn every_number_has_a_range_checked_on_both_sides() {
        // (table, key, in range, out of range, the range as the message must state it)
        type Case<'a> = (&'a str, &'a str, &'a [&'a str], &'a [&'a str], &'a str);
        let cases: &[Case] = &[
            (
                "axes.x",
                "velocity_mm_s",
                &["0.001", "100000"],
                &["0.000999", "100000.01", "1e-300", "0", "-1", "inf", "nan"],
                "between 0.001 and 100000 mm/s",
            ),
            (
                "axes.y",
                "acceleration_mm_s2",
                &["0.01", "1e8"],
                &["0.0099", "1.00001e8"],
                "between 0.01 and 1e8 mm/s²",
            ),
            (
                "axes.z",
                "jerk_mm_s3",
                &["1", "1e12"],
                &["0.999", "1.00001e12"],
                "between 1 and 1e12 mm/s³",
            ),
            (
                "axes.c",
                "velocity_deg_s",
                &["0.001", "100000"],
                &["0.000999", "100000.01"],
                "between 0.001 and 100000 deg/s",
            ),
            (
                "axes.c",
                "acceleration_deg_s2",
                &["0.01", "1e8"],
                &["0.0099", "1.00001e8"],
                "between 0.01 and 1e8 deg/s²",
            ),
            (
                "axes.c",
                "jerk_deg_s3",
                &["1", "1e12"],
                &["0.999", "1.00001e12"],
                "between 1 and 1e12 deg/s³",
            ),
            (
                "axes.x",
                "min_mm",
                &["-1e6"],
                &["-1000000.01", "-inf", "nan"],
                "between -1000000 and 1000000 mm",
            ),
            (
                "axes.x",
                "max_mm",
                &["1e6"],
                &["1000000.01", "inf"],
                "between -1000000 and 1000000 mm",
            ),
            (
                "axes.c",
                "min_deg",
                &["-1e6"],
                &["-1000000.01"],
                "between -1000000 and 1000000 deg",
            ),
            (
                "axes.c",
                "max_deg",
                &["1e6"],
                &["1000000.01"],
                "between -1000000 and 1000000 deg",
            ),
            (
                "",
                "tolerance_mm",
                &["1e-6", "10"],
                &["9.9e-7", "10.001", "0", "nan"],
                "between 1e-6 and 10 mm",
            ),
            (
                "gcode",
                "arc_tolerance_mm",
                &["1e-6", "10"],
                &["9.9e-7", "10.001", "-0.1"],
                "between 1e-6 and 10 mm",
            ),
            (
                "gcode",
                "arc_tolerance_rel",
                &["1e-9", "0.1"],
                &["9.9e-10", "0.1001", "inf"],
                "between 1e-9 and 0.1",
            ),
            (
                "tools",
                "length_mm",
                &["-1e6", "1e6"],
                &["-1000000.01", "1000000.01", "nan"],
                "between -1000000 and 1000000 mm",
            ),
            (
                "tools",
                "radius_mm",
                &["0", "1e6"],
                &["-0.001", "1000000.01", "inf"],
                "between 0 and 1000000 mm",
            ),
            (
                "axes.x.drive",
                "counts_per_mm",
                &["1e-3", "1e8"],
                &["9.9e-4", "0", "-1000", "1.1e9", "nan"],
                "between 0.001 and 1e9 counts/mm",
            ),
            (
                "axes.c.drive",
                "counts_per_deg",
                &["1e-3", "1e6"],
                &["9.9e-4", "1.1e9", "inf"],
                "between 0.001 and 1e9 counts/deg",
            ),
            (
                "axes.x.drive",
                "bandwidth_hz",
                &["0.1", "1000"],
                &["0.09", "1000.1", "nan"],
                "between 0.1 and 1000 Hz",
            ),
            (
                "axes.x.drive",
                "damping",
                &["0.01", "10"],
                &["0.0099", "10.1", "-1"],
                "between 0.01 and 10 (damping ratio)",
            ),
            (
                "axes.x.drive",
                "inertia_ratio",
                &["0.01", "100"],
                &["0.0099", "100.1", "nan"],
                "between 0.01 and 100 (load inertia over the tuned inertia)",
            ),
            (
                "axes.x.drive",
                "velocity_feed_forward",
                &["0", "1"],
                &["-0.01", "1.01", "nan"],
                "between 0 and 1 (gain)",
            ),
            (
                "axes.x.drive",
                "overcurrent_accel_counts_s2",
                &["1", "1e15"],
                &["0.99", "1.1e15", "inf"],
                "between 1 and 1e15 counts/s²",
            ),
            (
                "axes.x.drive",
                "quick_stop_decel_counts_s2",
                &["1", "1e15"],
                &["0.99", "1.1e15", "-5"],
                "between 1 and 1e15 counts/s²",
            ),
            (
                "axes.x",
                "ferror_mm",
                &["0.1", "1000"],
                &["9.9e-7", "1000.1", "nan"],
                "between 1e-6 and 1000 mm",
            ),
            (
                "axes.x",
                "min_ferror_mm",
                &["1e-6", "1"],
                &["0", "9.9e-7", "1000.1"],
                "between 1e-6 and 1000 mm",
            ),
            (
                "axes.c",
                "ferror_deg",
                &["0.1", "1000"],
                &["9.9e-7", "1000.1"],
                "between 1e-6 and 1000 deg",
            ),
            (
                "axes.c",
                "min_ferror_deg",
                &["1e-6", "1"],
                &["0", "1000.1"],
                "between 1e-6 and 1000 deg",
            ),
            (
                "safety",
                "margin",
                &["0", "1"],
                &["-0.01", "1.01", "nan"],
                "between 0 and 1 (fraction of the limits)",
            ),
            (
                "safety",
                "recorder_seconds",
                &["0.1", "60"],
                &["0.09", "60.1", "inf"],
                "between 0.1 and 60 s",
            ),
        ];
        for &(table, key, good, bad, range) in cases {
            for value in good {
                assert_accepted(table, key, value);
            }
            for value in bad {
                let (text, place) = with_key(table, key, value);
                let e = err(&text);
                assert!(
                    e.starts_with(&place),
                    "{key} = {value}: {e} (expected at {place})"
                );
                let full_key = if table.is_empty() {
                    key.to_string()
                } else {
                    format!("{table}.{key}")
                };
                assert!(e.contains(&format!("`{full_key}`")), "{e}");
                assert!(e.contains(range), "{key} = {value}: {e}");
            }
        }
    }

    #[test]
    fn a_tiny_limit_is_named_with_its_exponent() {
        let (text, place) = with_key("axes.x", "velocity_mm_s", "1e-300");
        let e = err(&text);
        assert_eq!(
            e,
            format!(
                "{place}`axes.x.velocity_mm_s` must be between 0.001 and 100000 mm/s, found 1e-300"
            )
        );
    }

    #[test]
    fn period_has_a_lower_bound_of_50_us() {
        for ok in ["50", "62", "1000000"] {
            let (text, _) = with_key("", "period_us", ok);
            let c = Config::from_toml_str(&text, "m.toml").unwrap();
            assert_eq!(c.period_us.to_string(), ok);
        }
        for bad in ["49", "10", "1", "1000001"] {
            let (text, place) = with_key("", "period_us", bad);
            let e = err(&text);
            assert_eq!(
                e,
                format!("{place}`period_us` must be between 50 and 1000000 µs, found {bad}")
            );
        }
    }

    #[test]
    fn work_offsets_are_bounded() {
        let (text, _) = with_key("work_offsets", "g54", "[1e6, -1e6, 0]");
        let c = Config::from_toml_str(&text, "m.toml").unwrap();
        assert_eq!(c.work_offsets_mm[0], [1e6, -1e6, 0.0]);
        for bad in ["[1000000.01, 0, 0]", "[0, -inf, 0]", "[0, 0, nan]"] {
            let (text, place) = with_key("work_offsets", "g54", bad);
            let e = err(&text);
            assert!(e.starts_with(&place), "{e}");
            assert!(e.contains("`work_offsets.g54`"), "{e}");
            assert!(e.contains("between -1000000 and 1000000 mm"), "{e}");
        }
    }

    #[test]
    fn tolerance_must_be_positive() {
        let e = err(&format!("tolerance_mm = 0.0\n{MINIMAL}"));
        assert!(e.contains("tolerance_mm"), "{e}");
    }

    #[test]
    fn unknown_dialect_lists_the_known_ones() {
        let e = err(&format!("dialect = \"fanuc\"\n{MINIMAL}"));
        assert!(e.starts_with("m.toml:1:11: error: "), "{e}");
        assert!(e.contains("fanuc"), "{e}");
        assert!(e.contains("sinumerik"), "{e}");
    }

    #[test]
    fn dialect_alias_tormach_is_linuxcnc() {
        let c = Config::from_toml_str(&format!("dialect = \"tormach\"\n{MINIMAL}"), "m").unwrap();
        assert_eq!(c.dialect, Some(Dialect::LinuxCnc));
    }

    #[test]
    fn syntax_error_has_a_position() {
        let e = err("period_us = = 3\n");
        assert!(e.starts_with("m.toml:1:"), "{e}");
    }

    #[test]
    fn rotary_axis_is_read_in_degrees() {
        let text = format!(
            "{MINIMAL}[axes.c]\nvelocity_deg_s = 360.0\nacceleration_deg_s2 = 3600.0\njerk_deg_s3 = 90000.0\nmin_deg = -720.0\nmax_deg = 720.0\n"
        );
        let c = Config::from_toml_str(&text, "m").unwrap();
        let axis = c.axes.c.unwrap();
        assert_eq!(axis.velocity_deg_s, 360.0);
        assert_eq!((axis.min_deg, axis.max_deg), (-720.0, 720.0));
        assert_eq!(c.axes.rotary(), [None, None, Some(axis)]);
        // Linear keys on a rotary axis are a mistake worth naming.
        let e = err(&text.replace("velocity_deg_s", "velocity_mm_s"));
        assert!(e.contains("velocity_mm_s"), "{e}");
    }

    #[test]
    fn settings_carry_offsets_tools_and_arc_tolerances() {
        let text = format!(
            "{MINIMAL}[gcode]\narc_tolerance_mm = 0.05\narc_tolerance_rel = 0.002\n[work_offsets]\ng55 = [1.0, -2.0, 3.5]\ng59_3 = [0, 0, -7]\n[[tools]]\nnumber = 3\nlength_mm = 42.5\n[[tools]]\nnumber = 7\nradius_mm = 3.0\n"
        );
        let s = Config::from_toml_str(&text, "m").unwrap().settings();
        assert_eq!(s.arc_tolerance_mm, 0.05);
        assert_eq!(s.arc_tolerance_rel, 0.002);
        assert_eq!(s.work_offsets_mm[0], [0.0, 0.0, 0.0]);
        assert_eq!(s.work_offsets_mm[1], [1.0, -2.0, 3.5]);
        assert_eq!(s.work_offsets_mm[8], [0.0, 0.0, -7.0]);
        assert_eq!(s.tools.len(), 2);
        assert_eq!(
            (
                s.tools[0].number,
                s.tools[0].length_mm,
                s.tools[0].radius_mm
            ),
            (3, 42.5, 0.0)
        );
        assert_eq!(
            (
                s.tools[1].number,
                s.tools[1].length_mm,
                s.tools[1].radius_mm
            ),
            (7, 0.0, 3.0)
        );
    }

    #[test]
    fn bad_offsets_and_tools_are_rejected() {
        let e = err(&format!("{MINIMAL}[work_offsets]\ng54 = [1.0, 2.0]\n"));
        assert!(e.contains("work_offsets.g54"), "{e}");
        let e = err(&format!("{MINIMAL}[work_offsets]\ng60 = [1.0, 2.0, 3.0]\n"));
        assert!(e.contains("g60"), "{e}");
        let e = err(&format!(
            "{MINIMAL}[[tools]]\nnumber = 1\n[[tools]]\nnumber = 1\n"
        ));
        assert!(e.contains("tool 1 is listed twice"), "{e}");
        let e = err(&format!("{MINIMAL}[[tools]]\nnumber = -1\n"));
        assert!(e.contains("tools.number"), "{e}");
        let e = err(&format!(
            "{MINIMAL}[[tools]]\nnumber = 2\nradius_mm = -1.0\n"
        ));
        assert!(e.contains("tools.radius_mm"), "{e}");
        let e = err(&format!(
            "{MINIMAL}[[tools]]\nnumber = 2\ndiameter_mm = 1.0\n"
        ));
        assert!(e.contains("diameter_mm"), "{e}");
    }

    #[test]
    fn missing_file_names_the_file() {
        let e = Config::load(Path::new("/nonexistent/kerf.toml")).unwrap_err();
        let s = e.to_string();
        assert!(
            s.starts_with("/nonexistent/kerf.toml: error: cannot read config"),
            "{s}"
        );
    }

    #[test]
    fn positions_count_characters_not_bytes() {
        assert_eq!(position_of("ab\ncd", 4), TextPosition { line: 2, col: 2 });
        assert_eq!(position_of("é=1", 2), TextPosition { line: 1, col: 2 });
        assert_eq!(position_of("x", 99), TextPosition { line: 1, col: 2 });
    }

    #[test]
    fn machine_name_and_daemon_table_default_and_are_checked() {
        let c = Config::from_toml_str(MINIMAL, "m.toml").unwrap();
        assert_eq!(c.machine, "default");
        assert_eq!(
            c.daemon,
            DaemonConfig {
                priority: 80,
                cpu: None,
                queue_segments: 4096,
                move_window: 4096,
            }
        );
        let c = Config::from_toml_str(
            &format!(
                "machine = \"mill-2_a\"\n{MINIMAL}[daemon]\npriority = 90\ncpu = 3\nqueue_segments = 16\nmove_window = 65536\n"
            ),
            "m.toml",
        )
        .unwrap();
        assert_eq!(c.machine, "mill-2_a");
        assert_eq!(
            c.daemon,
            DaemonConfig {
                priority: 90,
                cpu: Some(3),
                queue_segments: 16,
                move_window: 65536,
            }
        );
        for bad in ["", "a/b", "mill 2", "é", &"x".repeat(65)] {
            let e = err(&format!("machine = \"{bad}\"\n{MINIMAL}"));
            assert!(
                e.starts_with("m.toml:1:11: error: `machine` must be"),
                "{bad}: {e}"
            );
        }
        for (key, value) in [
            ("priority", "0"),
            ("priority", "100"),
            ("cpu", "-1"),
            ("queue_segments", "15"),
            ("queue_segments", "65537"),
            ("move_window", "8"),
        ] {
            let e = err(&format!("{MINIMAL}[daemon]\n{key} = {value}\n"));
            assert!(e.contains(key), "{key} = {value}: {e}");
        }
        let e = err(&format!("{MINIMAL}[daemon]\nperiod_us = 250\n"));
        assert!(e.contains("period_us"), "{e}");
    }

    /// A fresh directory for one test's files.
    fn temp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("kerf-config-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        dir
    }

    #[test]
    fn gcode_files_and_limits_are_read_relative_to_the_config_file() {
        let dir = temp_dir("gcode");
        std::fs::write(dir.join("tool.tbl"), "T3 P3 X0.5 Z42.5 D6 ;drill\nT4 Z-1\n")
            .expect("write");
        std::fs::write(dir.join("kerf.var"), "5161\t10\n5220\t2\n5241\t-3.5\n").expect("write");
        let text = format!(
            "{MINIMAL}[gcode]\ntool_table = \"tool.tbl\"\nsubroutine_path = [\"subs\", \"/opt/ngc\"]\n\
             max_loop_iterations = 5000\nblock_delete = true\ng28_home_mm_deg = [1, 2, 3]\n\
             g30_home_mm_deg = [4, 5, 6, 7, 8, 9]\nparameter_file = \"kerf.var\"\n\
             [[tools]]\nnumber = 1\nlength_mm = 2.0\n"
        );
        let path = dir.join("kerf.toml");
        std::fs::write(&path, text).expect("write");
        let c = Config::load(&path).expect("valid config");
        assert_eq!(c.tool_table, Some(dir.join("tool.tbl")));
        let numbers: Vec<u32> = c.tools.iter().map(|t| t.number).collect();
        assert_eq!(numbers, [1, 3, 4]);
        assert_eq!(c.tools[1].offsets_mm_deg(), [0.5, 0.0, 42.5, 0.0, 0.0, 0.0]);
        assert_eq!(c.tools[1].radius_mm, 3.0);
        assert_eq!(c.tools[1].pocket, 3);
        assert_eq!(
            c.subroutine_path,
            [dir.join("subs"), PathBuf::from("/opt/ngc")]
        );
        assert_eq!(c.max_loop_iterations, 5000);
        assert_eq!(c.g28_home_mm_deg, [1.0, 2.0, 3.0, 0.0, 0.0, 0.0]);
        assert_eq!(c.g30_home_mm_deg, [4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
        let s = c.program_settings().expect("parameter file");
        assert_eq!(s.parameters, [(5161, 10.0), (5220, 2.0), (5241, -3.5)]);
        assert_eq!(s.max_loop_iterations, 5000);
        assert!(c.block_delete && s.block_delete);
        assert!(!Config::builtin().settings().block_delete, "off by default");
        assert_eq!(s.subroutine_path, c.subroutine_path);
        assert_eq!(s.g30_home_mm_deg, c.g30_home_mm_deg);
        assert_eq!(s.tools.len(), 3);
        // The restored parameters take effect: #5220 = 2 starts the program in G55, whose
        // X offset #5241 is -3.5 mm.
        let items: Vec<kerf_gcode::Item> =
            kerf_gcode::Interpreter::new(&b"G0 X1\nM2\n"[..], Dialect::LinuxCnc, s)
                .collect::<Result<_, _>>()
                .expect("valid program");
        let kerf_gcode::Item::Move(m) = &items[0] else {
            panic!("a move")
        };
        assert_eq!(m.path.end(), kerf_gcode::Vec3::new(-2.5, 0.0, 0.0));
        std::fs::remove_dir_all(&dir).expect("clean up");
    }

    #[test]
    fn gcode_file_and_limit_errors() {
        let dir = temp_dir("gcode-errors");
        std::fs::write(dir.join("bad.tbl"), "T1 Z1\nT2 Zq\n").expect("write");
        std::fs::write(dir.join("dup.tbl"), "T1 Z1\n").expect("write");
        let load = |extra: &str| {
            let path = dir.join("kerf.toml");
            std::fs::write(&path, format!("{MINIMAL}{extra}")).expect("write");
            Config::load(&path)
                .map(|_| ())
                .expect_err(extra)
                .to_string()
        };
        let e = load("[gcode]\ntool_table = \"bad.tbl\"\n");
        assert_eq!(
            e,
            format!(
                "{}:2:4: error: `Zq` is not a letter followed by a number",
                dir.join("bad.tbl").display()
            )
        );
        let e = load("[gcode]\ntool_table = \"missing.tbl\"\n");
        assert!(e.contains("cannot read `gcode.tool_table`"), "{e}");
        let e = load("[gcode]\ntool_table = \"dup.tbl\"\n[[tools]]\nnumber = 1\n");
        assert!(
            e.contains("tool 1 is both in `tools` and in `gcode.tool_table`"),
            "{e}"
        );
        for (extra, key) in [
            ("max_loop_iterations = 0", "gcode.max_loop_iterations"),
            ("g28_home_mm_deg = [1, 2]", "gcode.g28_home_mm_deg"),
            ("g30_home_mm_deg = [1, 2, 3, 4]", "gcode.g30_home_mm_deg"),
            ("g28_home = [1, 2, 3]", "unknown key `gcode.g28_home`"),
        ] {
            let e = err(&format!("{MINIMAL}[gcode]\n{extra}\n"));
            assert!(e.contains(key), "{extra}: {e}");
        }
        std::fs::remove_dir_all(&dir).expect("clean up");
    }

    /// The whole-number keys of the drive side: both ends accepted, just outside refused
    /// with the key, what it counts and the range.
    #[test]
    fn drive_integers_are_range_checked() {
        type Case<'a> = (&'a str, &'a str, &'a [&'a str], &'a [&'a str], &'a str);
        let cases: &[Case] = &[
            (
                "axes.x.drive",
                "substeps",
                &["1", "1000"],
                &["0", "1001", "-1"],
                "a number of steps per period from 1 to 1000",
            ),
            (
                "axes.x.drive",
                "following_error_window_counts",
                &["1", "1000000000"],
                &["0", "1000000001"],
                "a number of counts from 1 to 1000000000",
            ),
            (
                "axes.x.drive",
                "enable_timeout_ms",
                &["1", "60000"],
                &["0", "60001"],
                "a time in ms from 1 to 60000",
            ),
            (
                "safety",
                "stall_cycles",
                &["1", "10000"],
                &["0", "10001", "-3"],
                "a number of cycles from 1 to 10000",
            ),
        ];
        for &(table, key, good, bad, range) in cases {
            for value in good {
                assert_accepted(table, key, value);
            }
            for value in bad {
                let (text, place) = with_key(table, key, value);
                assert_eq!(
                    err(&text),
                    format!("{place}`{table}.{key}` must be {range}, found {value}")
                );
            }
        }
        for (value, direction) in [("1", 1), ("+1", 1), ("-1", -1)] {
            let (text, _) = with_key("axes.x.drive", "direction", value);
            let c = Config::from_toml_str(&text, "m.toml").unwrap();
            assert_eq!(c.drive_configs()[0].unwrap().scale.direction(), direction);
        }
        for value in ["0", "2", "-2"] {
            let (text, place) = with_key("axes.x.drive", "direction", value);
            assert_eq!(
                err(&text),
                format!("{place}`axes.x.drive.direction` must be +1 or -1, found {value}")
            );
        }
    }

    #[test]
    fn drive_side_defaults() {
        let c = Config::from_toml_str(MINIMAL, "m.toml").unwrap();
        let d = c.drive.axes[0].unwrap();
        assert_eq!(d.kind, DriveKind::Sim);
        assert_eq!(
            (d.scale.counts_per_unit(), d.scale.direction()),
            (1000.0, 1)
        );
        assert_eq!(
            (
                d.sim.bandwidth_hz,
                d.sim.damping,
                d.sim.velocity_feed_forward
            ),
            (50.0, 1.0, 1.0)
        );
        assert_eq!(d.sim.substeps, 20);
        assert_eq!(
            (
                d.sim.overcurrent_accel_counts_s2,
                d.sim.quick_stop_decel_counts_s2
            ),
            (1e9, 1e6)
        );
        assert_eq!(d.sim.following_error_window_counts, 1000);
        assert_eq!(d.enable_timeout_ms, 1000);
        assert_eq!((d.ferror_mm_deg, d.min_ferror_mm_deg), (1.0, 0.1));
        assert_eq!(c.drive.axes[1], Some(d));
        assert_eq!(c.drive.axes[2], Some(d));
        assert_eq!(&c.drive.axes[3..], &[None, None, None]);
        assert_eq!(
            (
                c.drive.margin,
                c.drive.stall_cycles,
                c.drive.recorder_seconds
            ),
            (0.05, 3, 10.0)
        );
        // The sim drive's defaults are those of the simulated drive itself.
        let setups = c.drive_configs();
        let x = setups[0].unwrap();
        assert_eq!(x.sim, SimConfig::default());
        assert_eq!(x.enable_timeout_cycles, 1000);
        assert!(setups[3..].iter().all(Option::is_none));
        assert_eq!(c.recorder_capacity(), 10_000);
        assert_eq!(c.recorder_axes(), [true, true, true, false, false, false]);
        // The keys of `full` are the defaults too.
        assert_eq!(
            Config::from_toml_str(&full(), "m.toml").unwrap().drive.axes[0],
            Some(d)
        );
        // The bundled example has the same drive side.
        assert_eq!(
            Config::builtin().drive.axes[0].map(|a| a.sim.bandwidth_hz),
            Some(50.0)
        );
    }

    #[test]
    fn built_drive_and_safety_configs_carry_the_files_values() {
        let text = format!(
            "period_us = 2000\n{}[axes.x.drive]\nkind = \"sim\"\ncounts_per_mm = 800.0\ndirection = -1\nbandwidth_hz = 20.0\ndamping = 0.7\ninertia_ratio = 1.5\nvelocity_feed_forward = 0.5\nsubsteps = 40\novercurrent_accel_counts_s2 = 5e8\nquick_stop_decel_counts_s2 = 2e5\nfollowing_error_window_counts = 77\nenable_timeout_ms = 3\n[axes.b]\nvelocity_deg_s = 90.0\nacceleration_deg_s2 = 900.0\njerk_deg_s3 = 9000.0\nmin_deg = -30.0\nmax_deg = 120.0\nferror_deg = 2.0\nmin_ferror_deg = 0.5\n[axes.b.drive]\ncounts_per_deg = 3600.0\n[safety]\nmargin = 0.1\nstall_cycles = 7\nrecorder_seconds = 2.5\n",
            MINIMAL.replacen(
                "max_mm = 10.0\n",
                "max_mm = 10.0\nferror_mm = 0.4\nmin_ferror_mm = 0.02\n",
                1
            )
        );
        let c = Config::from_toml_str(&text, "m.toml").unwrap();
        let setups = c.drive_configs();
        let x = setups[0].unwrap();
        assert_eq!(x.kind, DriveKind::Sim);
        assert_eq!(
            (x.scale.counts_per_unit(), x.scale.direction()),
            (800.0, -1)
        );
        assert_eq!(
            x.sim,
            SimConfig {
                period_ns: 2_000_000,
                bandwidth_hz: 20.0,
                damping: 0.7,
                inertia_ratio: 1.5,
                velocity_feed_forward: 0.5,
                substeps: 40,
                overcurrent_accel_counts_s2: 5e8,
                quick_stop_decel_counts_s2: 2e5,
                following_error_window_counts: 77,
                initial_position_counts: 0.0,
            }
        );
        // 3 ms at 2 ms per cycle: rounded up to 2 cycles.
        assert_eq!(x.enable_timeout_cycles, 2);
        let b = setups[4].unwrap();
        assert_eq!(
            (b.scale.counts_per_unit(), b.scale.direction()),
            (3600.0, 1)
        );
        assert_eq!(b.sim.bandwidth_hz, 50.0);
        assert!(setups[3].is_none() && setups[5].is_none());
        // The scale converts as the file says: -1 direction, 800 counts/mm.
        assert_eq!(x.scale.to_counts(1.5), Ok(-1200));

        let s = c.safety_config();
        assert_eq!(s.period_s, 0.002);
        assert_eq!((s.margin, s.stall_cycles), (0.1, 7));
        assert_eq!(
            s.axes[0],
            Some(AxisSafety {
                limits: AxisLimits {
                    velocity_units_s: 100.0,
                    acceleration_units_s2: 1000.0,
                    jerk_units_s3: 10000.0,
                },
                min_limit: -10.0,
                max_limit: 10.0,
                ferror: 0.4,
                min_ferror: 0.02,
            })
        );
        assert_eq!(
            s.axes[1].map(|a| (a.ferror, a.min_ferror)),
            Some((1.0, 0.1))
        );
        assert_eq!(
            s.axes[4],
            Some(AxisSafety {
                limits: AxisLimits {
                    velocity_units_s: 90.0,
                    acceleration_units_s2: 900.0,
                    jerk_units_s3: 9000.0,
                },
                min_limit: -30.0,
                max_limit: 120.0,
                ferror: 2.0,
                min_ferror: 0.5,
            })
        );
        assert!(s.axes[3].is_none() && s.axes[5].is_none());
        // LinuxCNC's rule on the configured values: 0.4 mm at 100 mm/s, 0.02 at rest.
        assert_eq!(s.axes[0].unwrap().ferror_limit(100.0), 0.4);
        assert_eq!(s.axes[0].unwrap().ferror_limit(0.0), 0.02);
        assert!(kerf_drive::safety::Safety::new(s, [0.0; MAX_AXES]).is_ok());

        // 2.5 s at 2 ms: 1250 cycles, as the recorder itself sizes it.
        assert_eq!(c.recorder_capacity(), 1250);
        assert_eq!(c.recorder_axes(), [true, true, true, false, true, false]);
        let recorder =
            kerf_drive::recorder::Recorder::new(2.5, c.period_s(), c.recorder_axes()).unwrap();
        assert_eq!(recorder.capacity(), c.recorder_capacity());
    }

    #[test]
    fn a_sim_drive_whose_model_would_diverge_is_refused_with_the_substeps_it_needs() {
        // 1000 Hz, ζ 10 at 1 ms: ωh(ωh + 4ζ) ≤ 2 needs ωh ≤ −20 + √402 = 0.0499, so
        // h ≤ 7.94 µs: 126 substeps. At 20 substeps the index is 12.7.
        let load = |t: &str| Config::from_toml_str(t, "m.toml").expect("kerf sim accepts it");
        let e = load(&format!(
            "{MINIMAL}[axes.y.drive]\nbandwidth_hz = 1000.0\ndamping = 10.0\nsubsteps = 20\n"
        ))
        .check_drives()
        .unwrap_err();
        assert!(
            e.contains("`axes.y.drive.substeps` = 20 is too few") && e.contains("use at least 126"),
            "{e}"
        );
        let ok = format!(
            "{MINIMAL}[axes.y.drive]\nbandwidth_hz = 1000.0\ndamping = 10.0\nsubsteps = 126\n"
        );
        assert_eq!(load(&ok).check_drives(), Ok(()));
        // A longer period needs more.
        let e = load(&format!(
            "period_us = 4000\n{MINIMAL}[axes.x.drive]\nbandwidth_hz = 200.0\nsubsteps = 4\n"
        ))
        .check_drives()
        .unwrap_err();
        assert!(e.contains("`axes.x.drive.substeps` = 4 is too few"), "{e}");
        // Without `substeps`, enough are taken: the 1000 Hz drive gets 126.
        let c = load(&format!(
            "{MINIMAL}[axes.y.drive]\nbandwidth_hz = 1000.0\ndamping = 10.0\n"
        ));
        assert_eq!(c.drive.axes[1].unwrap().sim.substeps, 126);
        assert_eq!(c.check_drives(), Ok(()));
    }

    #[test]
    fn the_dump_dir_is_relative_to_the_configuration() {
        let c = Config::from_toml_str_in(
            &format!("{MINIMAL}[safety]\ndump_dir = \"bb\"\n"),
            "/etc/kerf/m.toml",
            Path::new("/etc/kerf"),
        )
        .expect("valid");
        assert_eq!(c.dump_dir(), PathBuf::from("/etc/kerf/bb"));
        let c = Config::from_toml_str(
            &format!("{MINIMAL}[safety]\ndump_dir = \"/var/x\"\n"),
            "m.toml",
        )
        .expect("valid");
        assert_eq!(c.dump_dir(), PathBuf::from("/var/x"));
        let e = err(&format!("{MINIMAL}[safety]\ndump_dir = \"\"\n"));
        assert!(e.contains("`safety.dump_dir` must name a directory"), "{e}");
    }

    #[test]
    fn drive_side_mistakes_are_named() {
        let (text, place) = with_key("axes.x.drive", "kind", "\"ethercat\"");
        assert_eq!(
            err(&text),
            format!(
                "{place}`axes.x.drive.kind` must be \"sim\" (the only drive kind so far), found `ethercat`"
            )
        );
        // Unknown keys, in each new table.
        for (extra, key) in [
            (
                "[axes.x.drive]\nbandwidth = 10.0\n",
                "axes.x.drive.bandwidth",
            ),
            ("[axes.y.drive]\ninertia = 1.0\n", "axes.y.drive.inertia"),
            ("[safety]\nmargin_percent = 5\n", "safety.margin_percent"),
            ("[safety]\nferror_mm = 1.0\n", "safety.ferror_mm"),
        ] {
            let e = err(&format!("{MINIMAL}{extra}"));
            assert!(e.contains(&format!("unknown key `{key}`")), "{extra}: {e}");
        }
        let e = err(&MINIMAL.replacen("max_mm = 10.0\n", "max_mm = 10.0\nferror = 1.0\n", 1));
        assert!(e.contains("unknown key `axes.x.ferror`"), "{e}");
        // The scale key of the other kind of axis.
        let e = err(&format!(
            "{MINIMAL}[axes.z.drive]\ncounts_per_deg = 100.0\n"
        ));
        assert!(
            e.contains("axis z is measured in mm: its scale is `axes.z.drive.counts_per_mm`"),
            "{e}"
        );
        let c_axis = "[axes.c]\nvelocity_deg_s = 360.0\nacceleration_deg_s2 = 3600.0\njerk_deg_s3 = 90000.0\nmin_deg = -720.0\nmax_deg = 720.0\n";
        let e = err(&format!(
            "{MINIMAL}{c_axis}[axes.c.drive]\ncounts_per_mm = 100.0\n"
        ));
        assert!(
            e.contains("its scale is `axes.c.drive.counts_per_deg`"),
            "{e}"
        );
        let e = err(&format!("{MINIMAL}{c_axis}ferror_mm = 1.0\n"));
        assert!(e.contains("unknown key `axes.c.ferror_mm`"), "{e}");
        // A travel that does not fit in 32-bit counts: ±10 mm at 3e8 counts/mm.
        let e = err(&format!("{MINIMAL}[axes.x.drive]\ncounts_per_mm = 3e8\n"));
        assert!(e.starts_with("m.toml:21:17: error: `axes.x.drive.counts_per_mm` = 3e8 puts the travel limit 10 mm at 3e9 counts"), "{e}");
        assert!(
            e.contains("3e9 counts, beyond the drive's 32-bit position (2147483647)"),
            "{e}"
        );
        // min_ferror above ferror.
        let e = err(&MINIMAL.replacen(
            "max_mm = 10.0\n",
            "max_mm = 10.0\nferror_mm = 0.5\nmin_ferror_mm = 0.6\n",
            1,
        ));
        assert!(
            e.contains("`axes.x.min_ferror_mm` (0.6) must be at most `axes.x.ferror_mm` (0.5)"),
            "{e}"
        );
        let e = err(&MINIMAL.replacen("max_mm = 10.0\n", "max_mm = 10.0\nferror_mm = 0.05\n", 1));
        assert!(
            e.contains("`axes.x.min_ferror_mm` (0.1) must be at most `axes.x.ferror_mm` (0.05)"),
            "{e}"
        );
    }
}
