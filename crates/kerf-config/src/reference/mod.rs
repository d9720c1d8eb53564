//! The configuration reference, docs/CONFIG.md, generated from the definitions that
//! validate the file: the ranges and defaults are the constants the checker uses (and the
//! defaults of the structures it fills), the units come from the key names as in its error
//! messages. Tests check that docs/CONFIG.md is exactly [`markdown`]'s output, and that the
//! keys listed here are exactly the keys the parser accepts, table by table.

use std::fmt::Write as _;
use std::ops::RangeInclusive;

use kerf_drive::sim::SimConfig;
use kerf_gcode::Dialect;

use crate::toml_words::{number, unit_of};
use crate::*;

mod ethercat;
mod homing;
mod machine;

/// One key of the configuration file.
#[derive(Clone, Debug)]
pub struct KeyDoc {
    /// The dotted key, `*` standing for an axis (`axes.*.velocity_mm_s`).
    pub key: &'static str,
    /// The default when the key is absent, in the file's terms (`required` when it must be
    /// given).
    pub default: String,
    /// The accepted values.
    pub range: String,
    /// What the key does.
    pub meaning: &'static str,
}

fn f(v: f64) -> String {
    number(v)
}

fn rf(r: RangeInclusive<f64>) -> String {
    format!("{} to {}", number(*r.start()), number(*r.end()))
}

fn ri<T: std::fmt::Display>(r: RangeInclusive<T>) -> String {
    format!("{} to {}", r.start(), r.end())
}

fn k(key: &'static str, default: String, range: String, meaning: &'static str) -> KeyDoc {
    KeyDoc {
        key,
        default,
        range,
        meaning,
    }
}

/// Every key of the configuration file, in the order of docs/CONFIG.md.
///
/// The rows in page order (over 400 lines): a reader checks a key against the page by
/// finding it here. The axes' homing, limit switch and simulation tables follow the axes'
/// drive rows; the bus, the machine's functions, then homing and jogging come last.
pub fn keys() -> Vec<KeyDoc> {
    let req = || "required".to_string();
    let none = || "none".to_string();
    let sim = SimConfig::default();
    let daemon = DaemonConfig::default();
    let gcode = kerf_gcode::Settings::default();
    let coord = || format!("±{}", number(MAX_COORDINATE_MM));
    let dialects = Dialect::ALL
        .iter()
        .map(|d| d.name())
        .collect::<Vec<_>>()
        .join(", ");
    let dialects = format!("{dialects} (or tormach)");
    let mut all = vec![
        k(
            "machine",
            format!("\"{DEFAULT_MACHINE}\""),
            "1 to 64 ASCII letters, digits, `-`, `_`".into(),
            "Name of the machine: the daemon's services are `kerf/<machine>/…`, so two machines (or test runs) on one PC never meet.",
        ),
        k(
            "dialect",
            "by extension, else linuxcnc".into(),
            dialects,
            "The control whose G-code this machine's programs are written in; `--dialect` and an unambiguous file extension take precedence.",
        ),
        k(
            "period_us",
            DEFAULT_PERIOD_US.to_string(),
            format!(
                "{} (daemon: {})",
                ri(MIN_PERIOD_US..=MAX_PERIOD_US),
                ri(DAEMON_PERIOD_RANGE_US)
            ),
            "Interpolation period: one setpoint per axis per period.",
        ),
        k(
            "tolerance_mm",
            f(DEFAULT_TOLERANCE_MM),
            rf(TOLERANCE_RANGE_MM),
            "Path tolerance for corner blends and smoothing, unless the program sets one (LinuxCNC `G64 P`).",
        ),
        k(
            "axes",
            req(),
            "table".into(),
            "The machine's axes: `[axes.x]`, `[axes.y]`, `[axes.z]` required, `[axes.a]`, `[axes.b]`, `[axes.c]` optional.",
        ),
        k(
            "axes.x",
            req(),
            "table".into(),
            "The linear axes X, Y and Z (`[axes.x]`, `[axes.y]`, `[axes.z]`), each with the keys `axes.*` below.",
        ),
        k(
            "axes.*.velocity_mm_s",
            req(),
            rf(VELOCITY_RANGE),
            "Velocity limit of a linear axis.",
        ),
        k(
            "axes.*.acceleration_mm_s2",
            req(),
            rf(ACCELERATION_RANGE),
            "Acceleration limit of a linear axis.",
        ),
        k(
            "axes.*.jerk_mm_s3",
            req(),
            rf(JERK_RANGE),
            "Jerk limit of a linear axis.",
        ),
        k(
            "axes.*.min_mm",
            req(),
            coord(),
            "Lower end of the travel, machine coordinates; below `max_mm`.",
        ),
        k(
            "axes.*.max_mm",
            req(),
            coord(),
            "Upper end of the travel, machine coordinates.",
        ),
        k(
            "axes.*.ferror_mm",
            f(DEFAULT_FERROR_MM),
            rf(FERROR_RANGE_MM),
            "Following-error limit at full speed (drive side).",
        ),
        k(
            "axes.*.min_ferror_mm",
            f(DEFAULT_MIN_FERROR_MM),
            rf(FERROR_RANGE_MM),
            "Following-error limit at rest; not above `ferror_mm`.",
        ),
        k(
            "axes.a",
            none(),
            "table".into(),
            "Rotary axes A, B and C (`[axes.a]`, `[axes.b]`, `[axes.c]`), optional, each with the keys `axes.*` in degrees below.",
        ),
        k(
            "axes.*.velocity_deg_s",
            req(),
            rf(VELOCITY_RANGE),
            "Velocity limit of a rotary axis.",
        ),
        k(
            "axes.*.acceleration_deg_s2",
            req(),
            rf(ACCELERATION_RANGE),
            "Acceleration limit of a rotary axis.",
        ),
        k(
            "axes.*.jerk_deg_s3",
            req(),
            rf(JERK_RANGE),
            "Jerk limit of a rotary axis.",
        ),
        k(
            "axes.*.min_deg",
            req(),
            coord(),
            "Lower end of a rotary axis's travel.",
        ),
        k(
            "axes.*.max_deg",
            req(),
            coord(),
            "Upper end of a rotary axis's travel.",
        ),
        k(
            "axes.*.ferror_deg",
            f(DEFAULT_FERROR_MM),
            rf(FERROR_RANGE_MM),
            "Following-error limit at full speed (rotary axis).",
        ),
        k(
            "axes.*.min_ferror_deg",
            f(DEFAULT_MIN_FERROR_MM),
            rf(FERROR_RANGE_MM),
            "Following-error limit at rest (rotary axis).",
        ),
        k(
            "axes.*.drive",
            "a simulated drive".into(),
            "table".into(),
            "The axis's drive (`[axes.x.drive]`, ...), keys below; docs/DRIVES.md explains the model.",
        ),
        k(
            "axes.*.drive.kind",
            "\"sim\"; \"ethercat\" with [ethercat]".into(),
            "\"sim\" or \"ethercat\"".into(),
            "Drive kind: the simulated drive, or the axis's `[[ethercat.drives]]` (every axis's with [ethercat], none without); the simulated drive's tuning keys below are refused for an EtherCAT drive.",
        ),
        k(
            "axes.*.drive.counts_per_mm",
            f(DEFAULT_COUNTS_PER_UNIT),
            rf(COUNTS_PER_UNIT_RANGE),
            "Position scale of a linear axis's drive, counts per mm; the travel must fit the drive's 32-bit position.",
        ),
        k(
            "axes.*.drive.counts_per_deg",
            f(DEFAULT_COUNTS_PER_UNIT),
            rf(COUNTS_PER_UNIT_RANGE),
            "Position scale of a rotary axis's drive, counts per degree.",
        ),
        k(
            "axes.*.drive.direction",
            "1".into(),
            "1 or -1".into(),
            "Counting direction of the drive relative to the axis.",
        ),
        k(
            "axes.*.drive.bandwidth_hz",
            f(sim.bandwidth_hz),
            rf(BANDWIDTH_RANGE_HZ),
            "Position-loop bandwidth of the simulated servo.",
        ),
        k(
            "axes.*.drive.damping",
            f(sim.damping),
            rf(DAMPING_RANGE),
            "Damping ratio of the simulated servo.",
        ),
        k(
            "axes.*.drive.inertia_ratio",
            f(sim.inertia_ratio),
            rf(INERTIA_RATIO_RANGE),
            "Load inertia of the simulated servo over the inertia its loop was tuned for.",
        ),
        k(
            "axes.*.drive.velocity_feed_forward",
            f(sim.velocity_feed_forward),
            rf(VELOCITY_FEED_FORWARD_RANGE),
            "Velocity feed-forward gain of the simulated servo.",
        ),
        k(
            "axes.*.drive.substeps",
            "enough for the bandwidth at the period".into(),
            ri(SUBSTEPS_RANGE),
            "Integration steps of the servo model per period; the daemon refuses too few for a stable model.",
        ),
        k(
            "axes.*.drive.overcurrent_accel_counts_s2",
            f(sim.overcurrent_accel_counts_s2),
            rf(DRIVE_ACCELERATION_RANGE_COUNTS_S2),
            "Acceleration beyond which the simulated drive faults with overcurrent.",
        ),
        k(
            "axes.*.drive.quick_stop_decel_counts_s2",
            f(sim.quick_stop_decel_counts_s2),
            rf(DRIVE_ACCELERATION_RANGE_COUNTS_S2),
            "Deceleration of the drive's own quick stop.",
        ),
        k(
            "axes.*.drive.following_error_window_counts",
            sim.following_error_window_counts.to_string(),
            ri(FOLLOWING_ERROR_WINDOW_RANGE_COUNTS),
            "The drive's own following-error window.",
        ),
        k(
            "axes.*.drive.enable_timeout_ms",
            DEFAULT_ENABLE_TIMEOUT_MS.to_string(),
            ri(ENABLE_TIMEOUT_RANGE_MS),
            "Time the drive may take to become enabled.",
        ),
    ];
    all.extend(homing::axis_keys());
    all.extend(vec![
        k(
            "daemon",
            "all defaults".into(),
            "table".into(),
            "The interpolator daemon `kerfd` (and `kerf run --embedded`).",
        ),
        k(
            "daemon.priority",
            daemon.priority.to_string(),
            "1 to 99".into(),
            "SCHED_FIFO priority of the real-time cycle thread.",
        ),
        k(
            "daemon.cpu",
            "not pinned".into(),
            "a CPU number from 0".into(),
            "CPU to pin the cycle thread to, normally an isolated one.",
        ),
        k(
            "daemon.cpu_latency_us",
            daemon.cpu_latency_us.to_string(),
            ri(CPU_LATENCY_RANGE_US),
            "The CPU wake-up latency, µs, that `kerfd` asks of the kernel while it runs with real-time scheduling (PM QoS through /dev/cpu_dma_latency, as root; refused otherwise, with a warning): idle CPUs use no idle state that takes longer to leave. 0 keeps idle CPUs polling, so that the threads outside the cycle (the control thread answering a request, the client waiting for the answer) wake at once instead of after the exit from a deep C-state or, in a virtual machine, a halt; the cost is idle CPUs that never sleep (power and heat). 1000000 asks nothing of the CPUs.",
        ),
        k(
            "daemon.queue_segments",
            daemon.queue_segments.to_string(),
            ri(QUEUE_SEGMENTS_RANGE),
            "Capacity of the motion core's segment queue, the lookahead window (`kerf sim` uses it too).",
        ),
        k(
            "daemon.move_window",
            daemon.move_window.to_string(),
            ri(MOVE_WINDOW_RANGE),
            "Resolved moves a planner process may send that the daemon has not taken yet.",
        ),
        k(
            "daemon.state_file",
            format!(
                "$STATE_DIRECTORY/{DEFAULT_STATE_FILE_NAME}, else /var/lib/kerf when it exists, else the temporary directory"
            ),
            "a file name".into(),
            "Where the daemon keeps the machine state that survives a restart (the tool in the spindle), written atomically when it changes; relative to the configuration's directory. By default in the machine's state directory, named after the machine: systemd's STATE_DIRECTORY (/var/lib/kerf under the shipped unit), else /var/lib/kerf when it exists (so that the operator's `kerf` commands find the same files), else the temporary directory (it then survives a restart of the daemon but not of the computer). Offsets, tool lengths and, for absolute encoders, the homed state survive too (the parameter file, the tool table, the configuration); an axis homed on a switch is unhomed again after a restart.",
        ),
        k(
            "gcode",
            "all defaults".into(),
            "table".into(),
            "Interpreter settings.",
        ),
        k(
            "gcode.arc_tolerance_mm",
            f(gcode.arc_tolerance_mm),
            rf(TOLERANCE_RANGE_MM),
            "Absolute arc end-point tolerance (Sinumerik, Heidenhain, Fagor).",
        ),
        k(
            "gcode.arc_tolerance_rel",
            f(gcode.arc_tolerance_rel),
            rf(ARC_TOLERANCE_REL_RANGE),
            "Arc end-point tolerance relative to the radius (Sinumerik, Heidenhain, Fagor).",
        ),
        k(
            "gcode.tool_table",
            none(),
            "a file name".into(),
            "LinuxCNC tool table file (tool.tbl format, mm), relative to the configuration's directory; its tools add to `[[tools]]`. `kerf tool touch-off` writes it (atomically). Without it the machine keeps MACHINE.tbl in its state directory (see `daemon.state_file`), whose entries replace `[[tools]]` entries of the same number; `kerf plan` and `kerf sim` read only a configured file.",
        ),
        k(
            "gcode.subroutine_path",
            "[]".into(),
            "an array of directories".into(),
            "LinuxCNC: directories searched in order for `NAME.ngc` of an `o<NAME> call` (after the program's own directory).",
        ),
        k(
            "gcode.max_loop_iterations",
            gcode.max_loop_iterations.to_string(),
            ri(MAX_LOOP_ITERATIONS_RANGE),
            "LinuxCNC: most iterations of one loop before the program is refused as endless.",
        ),
        k(
            "gcode.block_delete",
            gcode.block_delete.to_string(),
            "true or false".into(),
            "The block delete switch: on, a block starting with `/` is skipped.",
        ),
        k(
            "gcode.g28_home_mm_deg",
            "zero".into(),
            format!("3 or 6 numbers, each {}", coord()),
            "LinuxCNC G28 stored position, machine [x, y, z] or [x, y, z, a, b, c].",
        ),
        k(
            "gcode.g30_home_mm_deg",
            "zero".into(),
            format!("3 or 6 numbers, each {}", coord()),
            "LinuxCNC G30 stored position.",
        ),
        k(
            "gcode.parameter_file",
            none(),
            "a file name".into(),
            "LinuxCNC numbered parameter file (.var format), read at the start of every program, written (atomically) by `kerf run` after a program that changed it and ended normally, by `kerf mdi` and by `kerf offset set`. Without it the machine keeps MACHINE.var in its state directory (see `daemon.state_file`), which `kerf plan` and `kerf sim` do not read.",
        ),
        k(
            "work_offsets",
            "all zero".into(),
            "table".into(),
            "Work offsets of the coordinate systems.",
        ),
        k(
            "work_offsets.g54",
            "zero".into(),
            format!("3 or 6 numbers, each {}", coord()),
            "G54 offset, [x, y, z] mm (and [a, b, c] degrees); likewise `g55` ... `g59`, `g59_1`, `g59_2`, `g59_3` below.",
        ),
        k(
            "work_offsets.g55",
            "zero".into(),
            "as g54".into(),
            "G55 offset.",
        ),
        k(
            "work_offsets.g56",
            "zero".into(),
            "as g54".into(),
            "G56 offset.",
        ),
        k(
            "work_offsets.g57",
            "zero".into(),
            "as g54".into(),
            "G57 offset.",
        ),
        k(
            "work_offsets.g58",
            "zero".into(),
            "as g54".into(),
            "G58 offset.",
        ),
        k(
            "work_offsets.g59",
            "zero".into(),
            "as g54".into(),
            "G59 offset.",
        ),
        k(
            "work_offsets.g59_1",
            "zero".into(),
            "as g54".into(),
            "LinuxCNC G59.1 offset.",
        ),
        k(
            "work_offsets.g59_2",
            "zero".into(),
            "as g54".into(),
            "LinuxCNC G59.2 offset.",
        ),
        k(
            "work_offsets.g59_3",
            "zero".into(),
            "as g54".into(),
            "LinuxCNC G59.3 offset.",
        ),
        k(
            "tools",
            "no tools".into(),
            "array of tables".into(),
            "Tool table entries (`[[tools]]`); LinuxCNC refuses a tool that is not listed, the other dialects take its length as zero.",
        ),
        k(
            "tools.number",
            req(),
            "a whole number from 0".into(),
            "Tool number (T word); each at most once.",
        ),
        k(
            "tools.length_mm",
            "0".into(),
            coord(),
            "Tool length offset (G43).",
        ),
        k(
            "tools.radius_mm",
            "0".into(),
            format!("0 to {}", number(MAX_COORDINATE_MM)),
            "Tool radius (LinuxCNC G41/G42; elsewhere non-zero makes G41/G42 an error).",
        ),
        k(
            "safety",
            "all defaults".into(),
            "table".into(),
            "The daemon's drive-side safety checks.",
        ),
        k(
            "safety.margin",
            f(kerf_drive::safety::DEFAULT_MARGIN),
            rf(MARGIN_RANGE),
            "Allowance above the axis limits before the drive-side check trips, as a fraction.",
        ),
        k(
            "safety.stall_cycles",
            kerf_drive::safety::DEFAULT_STALL_CYCLES.to_string(),
            ri(STALL_CYCLES_RANGE),
            "Consecutive missed cycles that trip the stall check.",
        ),
        k(
            "safety.recorder_seconds",
            f(kerf_drive::recorder::DEFAULT_SECONDS),
            rf(RECORDER_SECONDS_RANGE),
            "Length of the black-box recording (`kerf dump`).",
        ),
        k(
            "safety.dump_dir",
            "$STATE_DIRECTORY, else the temporary directory".into(),
            "a directory".into(),
            "Where the daemon writes black-box files, relative to the configuration's directory.",
        ),
    ]);
    all.extend(ethercat::keys());
    all.extend(machine::keys());
    all.extend(homing::keys());
    all.extend(homing::serve_keys());
    all
}

/// docs/CONFIG.md.
pub fn markdown() -> String {
    let mut out = String::new();
    out.push_str(
        "# Configuration reference\n\n\
         <!-- Generated from crates/kerf-config/src/reference.rs; do not edit. After a change run\n     \
         KERF_BLESS=1 cargo test -p kerf-config --lib reference -->\n\n\
         The machine configuration is a TOML file: `--config FILE`, else `/etc/kerf/kerf.toml`\n\
         when it exists, else the built-in example [config/kerf.toml](../config/kerf.toml),\n\
         which comments every key. Unknown keys are errors. Units are part of the key names\n\
         (`_mm_s`: mm/s, `_us`: microseconds); `*` stands for an axis (`x`, `y`, `z`, or `a`,\n\
         `b`, `c`). The keys of an array of tables (`[[tools]]`, `[[ethercat.drives]]`) are\n\
         listed under its name (`tools.number`). Ranges are inclusive. The ranges and\n\
         defaults below are the constants the configuration checker uses.\n\n\
         | key | unit | default | accepted | meaning |\n|---|---|---|---|---|\n",
    );
    for key in keys() {
        let last = key.key.rsplit('.').next().unwrap_or(key.key);
        let unit = match unit_of(last) {
            Some(u) => u,
            None if last.starts_with('g') && key.key.starts_with("work_offsets") => {
                "mm (degrees for A, B, C)"
            }
            None => "—",
        };
        let _ = writeln!(
            out,
            "| `{}` | {} | {} | {} | {} |",
            key.key, unit, key.default, key.range, key.meaning
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raw::*;
    use serde::de::DeserializeOwned;
    use std::collections::BTreeSet;

    fn doc_path() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/CONFIG.md")
    }

    /// docs/CONFIG.md is what the definitions generate (`KERF_BLESS=1` rewrites it).
    #[test]
    fn docs_config_md_is_generated_from_the_definitions() {
        let want = markdown();
        if std::env::var_os("KERF_BLESS").is_some() {
            std::fs::write(doc_path(), &want).unwrap();
        }
        let have = std::fs::read_to_string(doc_path()).unwrap_or_default();
        assert!(
            have == want,
            "docs/CONFIG.md is out of date: run KERF_BLESS=1 cargo test -p kerf-config --lib reference"
        );
    }

    /// The fields a raw table accepts, from the parser's own "unknown field" message.
    fn accepted<T: DeserializeOwned>() -> BTreeSet<String> {
        let error = match toml::from_str::<T>("kerf_probe_key = 1\n") {
            Ok(_) => panic!("the probe key was accepted"),
            Err(e) => e.message().to_string(),
        };
        let list = error
            .split_once("expected")
            .map(|(_, rest)| rest)
            .unwrap_or_else(|| panic!("{error}"));
        list.split('`')
            .skip(1)
            .step_by(2)
            .map(str::to_string)
            .collect()
    }

    /// The documented keys directly below `table` (`""`: the top level).
    fn documented(table: &str) -> BTreeSet<String> {
        keys()
            .iter()
            .filter_map(|k| {
                let (parent, last) = k.key.rsplit_once('.').unwrap_or(("", k.key));
                (parent == table).then(|| last.to_string())
            })
            .collect()
    }

    /// Every key the parser accepts is documented, and every documented key is accepted,
    /// table by table (the axis tables with `*`; `x`/`a` stand for all three of a kind).
    #[test]
    fn every_accepted_key_is_documented_and_no_other() {
        let top = accepted::<RawConfig>();
        assert_eq!(documented(""), top);
        let axes: BTreeSet<String> = accepted::<RawAxes>();
        assert_eq!(
            axes,
            ["x", "y", "z", "a", "b", "c"]
                .map(String::from)
                .into_iter()
                .collect()
        );
        assert_eq!(
            documented("axes"),
            ["x", "a"].map(String::from).into_iter().collect()
        );
        let mut axis_keys = accepted::<RawLinearAxis>();
        axis_keys.extend(accepted::<RawRotaryAxis>());
        assert_eq!(documented("axes.*"), axis_keys);
        assert_eq!(documented("axes.*.drive"), accepted::<RawDrive>());
        let mut homing_keys = accepted::<RawLinearHoming>();
        homing_keys.extend(accepted::<RawRotaryHoming>());
        assert_eq!(documented("axes.*.homing"), homing_keys);
        assert_eq!(
            documented("axes.*.limit_switches"),
            accepted::<RawLimitSwitches>()
        );
        let mut sim_keys = accepted::<RawLinearSim>();
        sim_keys.extend(accepted::<RawRotarySim>());
        assert_eq!(documented("axes.*.sim"), sim_keys);
        assert_eq!(documented("homing"), accepted::<RawHoming>());
        assert_eq!(documented("jog"), accepted::<RawJog>());
        assert_eq!(documented("serve"), accepted::<RawServe>());
        assert_eq!(documented("daemon"), accepted::<RawDaemon>());
        assert_eq!(documented("gcode"), accepted::<RawGcode>());
        assert_eq!(documented("work_offsets"), accepted::<RawWorkOffsets>());
        assert_eq!(documented("tools"), accepted::<RawTool>());
        assert_eq!(documented("safety"), accepted::<RawSafety>());
        assert_eq!(documented("ethercat"), accepted::<RawEthercat>());
        assert_eq!(documented("ethercat.drives"), accepted::<RawEcatDrive>());
        assert_eq!(
            documented("ethercat.drives.rx_pdo"),
            accepted::<RawPdoEntry>()
        );
        assert_eq!(documented("ethercat.drives.sdo"), accepted::<RawSdo>());
        assert_eq!(documented("ethercat.io"), accepted::<RawEcatIo>());
        assert_eq!(documented("io"), accepted::<RawIo>());
        assert_eq!(documented("io.digital_outputs"), accepted::<RawOutput>());
        assert_eq!(documented("io.analog_outputs"), accepted::<RawOutput>());
        assert_eq!(
            documented("io.digital_inputs"),
            accepted::<RawDigitalInput>()
        );
        assert_eq!(documented("io.analog_inputs"), accepted::<RawAnalogInput>());
        assert_eq!(documented("spindle"), accepted::<RawSpindle>());
        assert_eq!(documented("coolant"), accepted::<RawCoolant>());
        assert_eq!(documented("tool_changer"), accepted::<RawToolChanger>());
        assert_eq!(documented("operator"), accepted::<RawOperator>());
    }

    /// The documented defaults are what a configuration without the keys gets.
    #[test]
    fn documented_defaults_are_the_parsed_defaults() {
        let minimal = "[axes.x]\nvelocity_mm_s = 100.0\nacceleration_mm_s2 = 1000.0\njerk_mm_s3 = 100000.0\nmin_mm = 0.0\nmax_mm = 100.0\n\
                       [axes.y]\nvelocity_mm_s = 100.0\nacceleration_mm_s2 = 1000.0\njerk_mm_s3 = 100000.0\nmin_mm = 0.0\nmax_mm = 100.0\n\
                       [axes.z]\nvelocity_mm_s = 100.0\nacceleration_mm_s2 = 1000.0\njerk_mm_s3 = 100000.0\nmin_mm = 0.0\nmax_mm = 100.0\n";
        let config = Config::from_toml_str(minimal, "minimal").unwrap();
        let doc: std::collections::HashMap<&str, String> =
            keys().into_iter().map(|k| (k.key, k.default)).collect();
        assert_eq!(doc["period_us"], config.period_us.to_string());
        assert_eq!(doc["tolerance_mm"], number(config.tolerance_mm));
        assert_eq!(doc["machine"], format!("\"{}\"", config.machine));
        assert_eq!(doc["daemon.priority"], config.daemon.priority.to_string());
        assert_eq!(
            doc["daemon.queue_segments"],
            config.daemon.queue_segments.to_string()
        );
        assert_eq!(
            doc["daemon.move_window"],
            config.daemon.move_window.to_string()
        );
        assert_eq!(config.daemon.state_file, None);
        assert!(doc["daemon.state_file"].contains(DEFAULT_STATE_FILE_NAME));
        // The machine's functions: a simulated drive spindle, no coolant, a manual tool
        // changer, the switches as LinuxCNC starts.
        let s = &config.spindle;
        assert!(
            matches!(s.kind, SpindleKind::Drive(d) if number(d.counts_per_rev) == doc["spindle.counts_per_rev"] && !d.on_bus)
        );
        assert_eq!(doc["spindle.max_rpm"], number(s.max_rpm));
        assert_eq!(doc["spindle.min_rpm"], number(s.min_rpm));
        assert_eq!(
            doc["spindle.acceleration_rpm_s"],
            number(s.acceleration_rpm_s)
        );
        assert_eq!(
            doc["spindle.at_speed_tolerance"],
            number(s.at_speed_tolerance)
        );
        assert_eq!(
            doc["spindle.at_speed_timeout_s"],
            number(s.at_speed_timeout_s)
        );
        assert_eq!(doc["spindle.orient_timeout_s"], number(s.orient_timeout_s));
        assert_eq!(
            doc["spindle.fault_out_of_band"],
            s.fault_out_of_band.to_string()
        );
        for (key, v) in [
            ("spindle.off_at_end", s.off_at_end),
            ("spindle.off_at_abort", s.off_at_abort),
            ("spindle.off_at_fault", s.off_at_fault),
            ("coolant.off_at_end", config.coolant.off_at_end),
            ("coolant.off_at_abort", config.coolant.off_at_abort),
            ("coolant.off_at_fault", config.coolant.off_at_fault),
            ("operator.optional_stop", config.operator.optional_stop),
            ("operator.single_block", config.operator.single_block),
        ] {
            assert_eq!(doc[key], v.to_string(), "{key}");
        }
        assert_eq!(
            (&config.coolant.mist, &config.coolant.flood),
            (&None, &None)
        );
        assert_eq!(config.tool_changer, ToolChanger::Manual);
        assert_eq!(doc["tool_changer.kind"], "\"manual\"");
        assert_eq!(config.io, IoConfig::default());
        // Homing and jogging: homing required (every axis of kind "none", homed at
        // start), the jog settings, every axis without switches or a simulated machine.
        assert_eq!(doc["homing.required"], config.homing.required.to_string());
        assert_eq!(
            doc["homing.unhomed_jog_pct"],
            number(config.homing.unhomed_jog_pct)
        );
        assert_eq!(doc["jog.deadman_ms"], config.jog.deadman_ms.to_string());
        assert_eq!(
            doc["jog.default_speed_pct"],
            number(config.jog.default_speed_pct)
        );
        assert_eq!(doc["axes.*.homing"], "kind \"none\"");
        for setup in &config.axis_setups()[..3] {
            let s = setup.expect("X, Y and Z");
            assert_eq!(s.homing.kind, HomingKind::None);
            assert_eq!(s.limit_switches, LimitSwitches::default());
            assert_eq!(number(s.sim.start_units), doc["axes.*.sim.start_mm"]);
            assert_eq!(s.sim.home_switch_units, None);
        }
        assert_eq!(config.axis_setups()[3..], [None, None, None]);
    }
}
