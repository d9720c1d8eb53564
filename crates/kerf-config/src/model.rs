//! The validated configuration: plain records, nothing downstream re-checks them.

use kerf_geom::PerAxis;
use std::path::PathBuf;

use kerf_drive::MAX_AXES;
use kerf_drive::cia402::Scale;
use kerf_drive::sim::SimConfig;
use kerf_gcode::{Dialect, Tool};

use crate::homing::*;
use crate::machine::*;
use crate::ranges::*;
use crate::serve::ServeConfig;

/// The kind of drive behind an axis (`[axes.*.drive] kind`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriveKind {
    /// The simulated CiA 402 servo drive (`kerf_drive::sim`), `"sim"`.
    Sim,
    /// A CiA 402 servo drive on the EtherCAT bus (`"ethercat"`; every axis's drive when
    /// the file has `[ethercat]`, see [`Config::ethercat`]).
    Ethercat,
}

impl DriveKind {
    /// Whether the drive runs on its own clock, so that a cycle the daemon misses is a
    /// cycle the drive got no setpoint in. The simulated drive has no clock of its own:
    /// it advances one period per exchange; an EtherCAT drive runs on the bus's
    /// distributed clock (or its own) whether a frame came or not.
    pub fn keeps_time(self) -> bool {
        match self {
            DriveKind::Sim => false,
            DriveKind::Ethercat => true,
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
    pub(crate) fn with_scale(scale: Scale) -> AxisDrive {
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
    /// The CPU wake-up latency asked of the kernel while the daemon runs with real-time
    /// scheduling, µs (`/dev/cpu_dma_latency`; 0: idle CPUs poll).
    pub cpu_latency_us: u32,
    /// Motion core queue capacity, segments (the lookahead window).
    pub queue_segments: u32,
    /// Resolved moves in flight from a planner process (flow-control window).
    pub move_window: u32,
    /// `state_file`: where the daemon keeps the machine state that survives a restart
    /// (the tool in the spindle), written atomically; relative paths resolved against the
    /// configuration file's directory. `None`: [`Config::state_file`]'s default.
    pub state_file: Option<PathBuf>,
}

impl Default for DaemonConfig {
    fn default() -> Self {
        DaemonConfig {
            priority: DEFAULT_PRIORITY,
            cpu: None,
            cpu_latency_us: DEFAULT_CPU_LATENCY_US,
            queue_segments: DEFAULT_QUEUE_SEGMENTS,
            move_window: DEFAULT_MOVE_WINDOW,
            state_file: None,
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
    /// Which axes the machine has, X to C (X, Y and Z always).
    pub fn present(&self) -> [bool; 6] {
        [
            true,
            true,
            true,
            self.a.is_some(),
            self.b.is_some(),
            self.c.is_some(),
        ]
    }

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
    pub g28_home_mm_deg: PerAxis<f64>,
    /// `gcode.g30_home_mm_deg`: the G30 position at start.
    pub g30_home_mm_deg: PerAxis<f64>,
    /// `gcode.parameter_file`: LinuxCNC's persistent numbered parameters, read at program
    /// start ([`Config::program_settings`]) and written by `kerf run` after a program that
    /// ended normally.
    pub parameter_file: Option<PathBuf>,
    /// The drive side: `[axes.*.drive]`, `ferror_*`/`min_ferror_*`, `[safety]` (the
    /// daemon's drive stage is built from it).
    pub drive: DriveSide,
    /// `[ethercat]`: the bus the axes' drives are on; `None`: simulated drives.
    pub ethercat: Option<crate::ethercat::EthercatConfig>,
    /// `[io]`: the inputs and outputs programs use by number and the machine by name.
    pub io: IoConfig,
    /// `[spindle]`.
    pub spindle: SpindleConfig,
    /// `[coolant]`.
    pub coolant: CoolantConfig,
    /// `[tool_changer]`.
    pub tool_changer: ToolChanger,
    /// `[operator]`: the runtime switches at daemon start.
    pub operator: OperatorConfig,
    /// `[homing]`.
    pub homing: HomingConfig,
    /// `[jog]`.
    pub jog: JogConfig,
    /// `[serve]`.
    pub serve: ServeConfig,
    /// `[axes.*.homing]`, `[axes.*.limit_switches]`, `[axes.*.sim]`, X to C: read with
    /// [`Config::axis_setups`].
    pub(crate) setups: [Option<AxisSetup>; MAX_AXES],
}

impl Config {
    /// `[ethercat]`, when the machine's drives are on an EtherCAT bus (every axis's
    /// [`AxisDrive::kind`] is then [`DriveKind::Ethercat`]); `None` when the drives are
    /// simulated.
    pub fn ethercat(&self) -> Option<&crate::ethercat::EthercatConfig> {
        self.ethercat.as_ref()
    }
}
