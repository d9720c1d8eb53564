//! The ranges and defaults the configuration checker uses: the one place each limit of a
//! key is written (docs/CONFIG.md is generated from these constants).

use std::ops::RangeInclusive;

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

/// Default CPU wake-up latency the daemon asks of the kernel while it runs, µs (PM QoS,
/// `/dev/cpu_dma_latency`): 0 keeps idle CPUs polling, so that the threads outside the
/// cycle (the control thread, its clients) wake without the exit from a deep idle state.
pub const DEFAULT_CPU_LATENCY_US: u32 = 0;

/// Accepted CPU wake-up latencies, µs: no idle state takes a second to leave, so the
/// largest asks nothing of the CPUs.
pub const CPU_LATENCY_RANGE_US: RangeInclusive<u32> = 0..=1_000_000;

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

/// The accepted `gcode.max_loop_iterations`: at least 1, at most 1e12 (a loop that runs
/// longer is not a program but a hang).
pub const MAX_LOOP_ITERATIONS_RANGE: RangeInclusive<u64> = 1..=1_000_000_000_000;

// The EtherCAT bus (`[ethercat]`, docs/CONFIG.md; the fieldbus side reads
// [`crate::ethercat::EthercatConfig`]).

/// Default `ethercat.dc`: distributed clocks on (SYNC0 at the period).
pub const DEFAULT_ETHERCAT_DC: bool = true;

/// Default `ethercat.max_missed_cycles`: the third bad cycle in a row latches the fault.
pub const DEFAULT_MAX_MISSED_CYCLES: u32 = 2;

/// Accepted `ethercat.max_missed_cycles`: a single lost frame never faults, and a bus
/// silent for more than 1000 cycles (125 ms at 8 kHz, 10 s at 100 Hz) is not supervised.
pub const MAX_MISSED_CYCLES_RANGE: RangeInclusive<u32> = 1..=1000;

/// The ESC's process-data watchdog unit, µs: the watchdog divider (register 0x0400) at its
/// default 2498 counts ((2498 + 2) × 40 ns).
pub const WATCHDOG_UNIT_US: u32 = 100;

/// Default `ethercat.watchdog_us`: 20 ms, at least two periods at the longest period the
/// daemon runs (10 ms).
pub const DEFAULT_WATCHDOG_US: u32 = 20_000;

/// The longest `ethercat.watchdog_us`: 0xFFFF watchdog units (register 0x0420 is 16 bits).
pub const MAX_WATCHDOG_US: u32 = 0xFFFF * WATCHDOG_UNIT_US;

/// The shortest `ethercat.watchdog_us`, in periods: a watchdog shorter than two periods
/// expires on one late frame.
pub const MIN_WATCHDOG_PERIODS: u32 = 2;

/// Default `ethercat.state_timeout_ms`: each EtherCAT state change of a subdevice (INIT,
/// PRE-OP, SAFE-OP, OP).
pub const DEFAULT_STATE_TIMEOUT_MS: u32 = 5000;

/// Default `ethercat.sdo_timeout_ms`: the answer to one SDO request.
pub const DEFAULT_SDO_TIMEOUT_MS: u32 = 1000;

/// Default `ethercat.dc_settle_timeout_ms`: the distributed clocks settling after they are
/// configured.
pub const DEFAULT_DC_SETTLE_TIMEOUT_MS: u32 = 5000;

/// Accepted bring-up timeouts (`ethercat.*_timeout_ms`), ms.
pub const BRING_UP_TIMEOUT_RANGE_MS: RangeInclusive<u32> = 1..=60_000;

/// Accepted ring positions: EtherCAT addresses 65,535 subdevices at most.
pub const RING_POSITION_RANGE: RangeInclusive<u32> = 0..=65_534;

/// Most entries in one PDO mapping (`rx_pdo`, `tx_pdo`).
pub const MAX_PDO_ENTRIES: usize = 64;

/// Most bytes in one drive's PDO (one SyncManager): a sanity bound far above the CiA 402
/// objects a drive needs; a drive that takes fewer refuses at bring-up with an SDO abort.
pub const MAX_PDO_BYTES: usize = 256;

/// Accepted RxPDO mapping objects (`rx_pdo_index`).
pub const RX_PDO_INDEX_RANGE: RangeInclusive<u32> = 0x1600..=0x17FF;

/// Accepted TxPDO mapping objects (`tx_pdo_index`).
pub const TX_PDO_INDEX_RANGE: RangeInclusive<u32> = 0x1A00..=0x1BFF;

/// Accepted bit numbers of an I/O subdevice's named inputs and outputs: 256 bytes of each.
pub const IO_BIT_RANGE: RangeInclusive<u32> = 0..=2047;

// The machine's functions besides the axes (`[io]`, `[spindle]`, `[coolant]`,
// `[tool_changer]`, `[operator]`; `crate::machine`).

/// Accepted numbers of a digital input or output (`io.digital_*.number`): LinuxCNC's
/// motion module has at most 64 of each (`M62`-`M66` `P`).
pub const DIGITAL_IO_NUMBER_RANGE: RangeInclusive<u32> = 0..=63;

/// Accepted numbers of an analog input or output (`io.analog_*.number`): LinuxCNC's
/// motion module has at most 16 of each (`M66` / `M67` / `M68` `E`).
pub const ANALOG_IO_NUMBER_RANGE: RangeInclusive<u32> = 0..=15;

/// Accepted start values of a simulated analog input (`io.analog_inputs.sim`).
pub const ANALOG_VALUE_RANGE: RangeInclusive<f64> = -1e9..=1e9;

/// Accepted spindle speeds (`spindle.max_rpm`, `spindle.min_rpm`), rpm: up to a million
/// (beyond the fastest air-bearing spindles).
pub const SPINDLE_RPM_RANGE: RangeInclusive<f64> = 0.001..=1e6;

/// Default `spindle.max_rpm`.
pub const DEFAULT_SPINDLE_MAX_RPM: f64 = 24_000.0;

/// Default `spindle.min_rpm`.
pub const DEFAULT_SPINDLE_MIN_RPM: f64 = 0.0;

/// Accepted spindle accelerations (`spindle.acceleration_rpm_s`), rpm/s.
pub const SPINDLE_ACCELERATION_RANGE_RPM_S: RangeInclusive<f64> = 0.1..=1e7;

/// Default `spindle.acceleration_rpm_s`: 0 to 24,000 rpm in 3 s.
pub const DEFAULT_SPINDLE_ACCELERATION_RPM_S: f64 = 8000.0;

/// Accepted `spindle.at_speed_tolerance`, a fraction of the commanded speed (LinuxCNC's
/// at-speed band, typically a few percent).
pub const AT_SPEED_TOLERANCE_RANGE: RangeInclusive<f64> = 0.001..=0.5;

/// Default `spindle.at_speed_tolerance`: 2 %.
pub const DEFAULT_AT_SPEED_TOLERANCE: f64 = 0.02;

/// Accepted machine waits and their timeouts (`spindle.at_speed_timeout_s`,
/// `spindle.orient_timeout_s`, `tool_changer.timeout_s`), s: up to an hour.
pub const MACHINE_TIMEOUT_RANGE_S: RangeInclusive<f64> = 0.01..=3600.0;

/// Default `spindle.at_speed_timeout_s`.
pub const DEFAULT_AT_SPEED_TIMEOUT_S: f64 = 10.0;

/// Default `spindle.orient_timeout_s` (`M19` without `Q`).
pub const DEFAULT_ORIENT_TIMEOUT_S: f64 = 5.0;

/// Accepted `spindle.spin_up_s`, s.
pub const SPIN_UP_RANGE_S: RangeInclusive<f64> = 0.0..=3600.0;

/// Default `spindle.spin_up_s`: the time after a speed change at which a spindle without
/// `at_speed_input` counts as at speed.
pub const DEFAULT_SPIN_UP_S: f64 = 3.0;

/// Accepted `spindle.speed_output_scale`, analog output units per rpm.
pub const SPEED_OUTPUT_SCALE_RANGE: RangeInclusive<f64> = 1e-12..=1e6;

/// Accepted `spindle.counts_per_rev`: the spindle drive's velocity counts per revolution.
pub const SPINDLE_COUNTS_PER_REV_RANGE: RangeInclusive<f64> = 1e-3..=1e9;

/// Default `spindle.counts_per_rev`.
pub const DEFAULT_SPINDLE_COUNTS_PER_REV: f64 = 10_000.0;

/// Default `tool_changer.timeout_s`: the automatic changer's handshake.
pub const DEFAULT_TOOL_CHANGE_TIMEOUT_S: f64 = 30.0;

/// Default `operator.optional_stop`: on, `M1` pauses (LinuxCNC's default).
pub const DEFAULT_OPTIONAL_STOP: bool = true;

/// Default `operator.single_block`: off.
pub const DEFAULT_SINGLE_BLOCK: bool = false;

/// The name of `daemon.state_file` by default, in `$STATE_DIRECTORY` (the shipped systemd
/// unit's /var/lib/kerf) or the temporary directory: `MACHINE` is the machine's name, so
/// that machines on one computer (and tests) keep their own.
pub const DEFAULT_STATE_FILE_NAME: &str = "MACHINE.state.toml";

// Homing, jogging and the axes' switches (`[homing]`, `[jog]`, `[axes.*.homing]`,
// `[axes.*.limit_switches]`, `[axes.*.sim]`; `crate::homing`). Rotary axes use the same
// numbers in degrees.

/// Default `homing.required`: programs and MDI are refused until every axis is homed.
pub const DEFAULT_HOMING_REQUIRED: bool = true;

/// Accepted `homing.unhomed_jog_pct`, percent of an axis's velocity: an unhomed axis has
/// no soft limits yet, so its jog speed is capped; 100 % lifts the cap.
pub const UNHOMED_JOG_PCT_RANGE: RangeInclusive<f64> = 1.0..=100.0;

/// Default `homing.unhomed_jog_pct` (LinuxCNC's usual reduced jog speed before homing).
pub const DEFAULT_UNHOMED_JOG_PCT: f64 = 10.0;

/// Accepted `jog.deadman_ms`: at most 2 s of motion after a client vanished, at least
/// 20 ms (a client renews every few tens of milliseconds; shorter would stop a healthy
/// jog on one late renewal).
pub const DEADMAN_RANGE_MS: RangeInclusive<u32> = 20..=2000;

/// Default `jog.deadman_ms`.
pub const DEFAULT_DEADMAN_MS: u32 = 100;

/// Accepted `jog.default_speed_pct`, percent of an axis's velocity.
pub const JOG_SPEED_PCT_RANGE: RangeInclusive<f64> = 0.1..=100.0;

/// Default `jog.default_speed_pct`: a jog without `--speed` at a quarter of the axis's
/// velocity.
pub const DEFAULT_JOG_SPEED_PCT: f64 = 25.0;

/// Default `axes.*.homing.search_distance_mm`, in travels (`max_mm` - `min_mm`): from
/// anywhere in the travel a search that long passes the far end, with margin for a
/// machine that starts a little outside it.
pub const DEFAULT_SEARCH_DISTANCE_TRAVELS: f64 = 1.5;

/// The longest `axes.*.homing.search_distance_mm`, mm (deg): beyond 1.5 times the widest
/// travel ([`MAX_COORDINATE_MM`] at both ends), so every default fits.
pub const MAX_SEARCH_DISTANCE_MM: f64 = 1e7;

/// Default `axes.*.homing.home_offset_mm`: the switch's latch point is machine 0.
pub const DEFAULT_HOME_OFFSET_MM: f64 = 0.0;

/// Default `axes.*.homing.home_mm`: the axis goes to machine 0 after homing (refused
/// when 0 is outside the travel and the key is not given).
pub const DEFAULT_HOME_MM: f64 = 0.0;

/// Accepted `axes.*.homing.sequence` (LinuxCNC `HOME_SEQUENCE`): `kerf home --all` homes
/// sequence 0 first, then 1, ...; axes with the same number home together.
pub const HOMING_SEQUENCE_RANGE: RangeInclusive<u32> = 0..=9;

/// Default `axes.*.homing.sequence`.
pub const DEFAULT_HOMING_SEQUENCE: u32 = 0;

/// Default `axes.*.sim.start_mm`: the simulated motor is at 0 of its own frame at
/// power-up, as the simulated drive always was.
pub const DEFAULT_SIM_START_MM: f64 = 0.0;

/// Accepted `axes.*.homing.method` of kind "drive" on an EtherCAT drive: the CiA 402
/// homing methods (0x6098). On a simulated drive only those it supports
/// (`kerf_drive::sim::SUPPORTED_METHODS`).
pub const DRIVE_HOMING_METHOD_RANGE: RangeInclusive<i8> = 1..=37;

/// Default `axes.*.homing.final_speed_mm_s` of kind "drive" without a search velocity
/// (methods 35 and 37, which do not move), percent of the axis's velocity.
pub const DEFAULT_DRIVE_FINAL_SPEED_PCT: f64 = 10.0;
