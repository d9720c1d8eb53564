//! The CAM benchmark table: each program of [`crate::cam::corpus`] run through Kerf
//! (`kerf sim`'s planner and motion core), against the time at the programmed feed and
//! the time-optimal lower bound ([`crate::bound`]).

use std::fmt::Write as _;

use kerf::sim::{SimError, SimOptions};
use kerf_config::{Config, ConfigError};
use kerf_gcode::{Dialect, Interpreter, Item};
use kerf_geom::{Move, Path, PlannedSegment, Vec3};
use kerf_plan::Planner;

use crate::bound::{self, BoundMachine};
use crate::cam::CamProgram;
use crate::jerk::{self, JerkError, JerkMachine};

/// The machine of issue 11 (`benches/cam-mill.toml`): X/Y 200 mm/s, 2,000 mm/s²,
/// 50,000 mm/s³; Z 100 mm/s, 1,000 mm/s², 20,000 mm/s³; 1 ms; tolerance 0.01 mm.
pub const MACHINE_TOML: &str = include_str!("../cam-mill.toml");

/// Sample spacing of the lower bound, mm.
pub const BOUND_DS_MM: f64 = 0.005;

/// Sample spacing of the jerk-limited bound, mm (its cone program grows with the
/// samples), widened on long paths to [`JERK_SAMPLES`] samples (the rasters at 0.02 mm:
/// raster A 3.2246 s, at 0.01 mm 3.2280 s, at 0.005 mm 3.2298 s).
pub const JERK_DS_MM: f64 = 0.01;
/// Samples of the jerk-limited bound at most (about; every piece has at least 16).
pub const JERK_SAMPLES: f64 = 6000.0;

/// Why a program could not be measured.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MeasureError {
    /// The machine configuration was refused.
    #[error("machine configuration: {0}")]
    Config(#[from] ConfigError),
    /// The program was refused by the G-code front end.
    #[error("{name}: line {line}: {message}")]
    Program {
        /// Program name.
        name: String,
        /// Line of the error.
        line: u32,
        /// What was wrong.
        message: String,
    },
    /// The simulation failed (a limit broken, a move that cannot be planned).
    #[error("{name}: {source}")]
    Sim {
        /// Program name.
        name: String,
        /// The failure.
        source: SimError,
    },
    /// The jerk-limited bound could not be computed.
    #[error("{name}: jerk-limited bound: {source}")]
    Jerk {
        /// Program name.
        name: String,
        /// The failure.
        source: JerkError,
    },
    /// The planner refused a move.
    #[error("{name}: planning: {source}")]
    Plan {
        /// Program name.
        name: String,
        /// The failure.
        source: kerf_plan::PlanError,
    },
    /// The run did not end at the program's end point.
    #[error("{name}: the run ended at {end:?}, not at the program's end {expected:?}")]
    WrongEnd {
        /// Program name.
        name: String,
        /// Where the last setpoint was, mm.
        end: [f64; 3],
        /// Where the program ends, mm.
        expected: [f64; 3],
    },
}

/// The machine of [`MACHINE_TOML`].
pub fn machine() -> Result<Config, MeasureError> {
    Ok(Config::from_toml_str(
        MACHINE_TOML,
        "benches/cam-mill.toml",
    )?)
}

/// The bound's view of a configuration: the linear axes' velocity and acceleration
/// limits and the default tolerance (the corpus programs set the same, `G64 P0.01`).
pub fn bound_machine(config: &Config) -> BoundMachine {
    let axes = config.axes.linear();
    BoundMachine {
        velocity_mm_s: axes.map(|a| a.velocity_mm_s),
        acceleration_mm_s2: axes.map(|a| a.acceleration_mm_s2),
        tolerance_mm: config.tolerance_mm,
    }
}

/// The jerk-limited bound's view of a configuration: [`bound_machine`] and the
/// linear axes' jerk limits.
pub fn jerk_machine(config: &Config) -> JerkMachine {
    JerkMachine {
        base: bound_machine(config),
        jerk_mm_s3: config.axes.linear().map(|a| a.jerk_mm_s3),
    }
}

/// The moves of a program text, resolved as `kerf sim` resolves them.
pub fn programmed_moves(
    name: &str,
    text: &str,
    config: &Config,
) -> Result<Vec<Move>, MeasureError> {
    let settings = config.program_settings()?;
    let mut moves = Vec::new();
    for item in Interpreter::new(text.as_bytes(), Dialect::LinuxCnc, settings) {
        match item {
            Ok(Item::Move(m)) => moves.push(m),
            Ok(Item::Event(_)) => {}
            Err(d) => {
                return Err(MeasureError::Program {
                    name: name.to_string(),
                    line: d.line,
                    message: d.message,
                });
            }
        }
    }
    Ok(moves)
}

/// The segments the planner makes of `moves` on the machine of `config`, as the motion
/// core receives them.
pub fn planned_segments(
    name: &str,
    moves: &[Move],
    config: &Config,
) -> Result<Vec<PlannedSegment>, MeasureError> {
    let mut planner = Planner::new(kerf_config::machine_limits(config));
    let mut out = Vec::new();
    for m in moves {
        planner
            .push(m, &mut out)
            .map_err(|source| MeasureError::Plan {
                name: name.to_string(),
                source,
            })?;
    }
    planner.finish(&mut out);
    Ok(out)
}

/// Unit tangents of a move at `n + 1` evenly spaced points, and its length, mm.
fn tangents(m: &Move, n: usize) -> (Vec<Vec3>, f64) {
    match &m.path {
        Path::Line(l) => {
            let d = l.end - l.start;
            let len = d.norm();
            let t = if len > 0.0 { d / len } else { d };
            (vec![t; n + 1], len)
        }
        Path::Arc(a) => {
            let h = (a.end - a.start).dot(&a.axis);
            let r0 = a.start - a.center;
            let len = (r0.norm() * a.sweep_rad).hypot(h);
            let ts = (0..=n)
                .map(|k| {
                    let phi = a.sweep_rad * k as f64 / n as f64;
                    let (s, c) = phi.sin_cos();
                    let d = (a.axis.cross(&r0) * c - r0 * s) * a.sweep_rad + a.axis * h;
                    d.normalize()
                })
                .collect();
            (ts, len)
        }
    }
}

/// The speed a move may run at with direction `t`: its feed (axis limits for a rapid) and
/// no axis above its velocity limit.
fn speed_cap(m: &Move, t: &Vec3, machine: &BoundMachine) -> f64 {
    let mut v = match m.feed_mm_min {
        Some(f) if !m.rapid => f / 60.0,
        _ => f64::INFINITY,
    };
    for i in 0..3 {
        if t[i].abs() > 0.0 {
            v = v.min(machine.velocity_mm_s[i] / t[i].abs());
        }
    }
    v
}

/// Intervals an arc is cut into for its feed time and feed.
const ARC_INTERVALS: usize = 64;

/// Per move: its time at the programmed feed (length over the feed, capped by the axis
/// velocity limits along the move's direction; arcs by the midpoint rule over 64
/// intervals), s, and the lowest such speed along it, mm/s.
pub fn feed_times(moves: &[Move], machine: &BoundMachine) -> Vec<(f64, f64)> {
    moves
        .iter()
        .map(|m| match m.path {
            Path::Line(_) => {
                let (t, len) = tangents(m, 0);
                let v = speed_cap(m, &t[0], machine);
                (len / v, v)
            }
            Path::Arc(_) => {
                let n = ARC_INTERVALS;
                let (ts, len) = tangents(m, 2 * n);
                let (mut time, mut low) = (0.0, f64::INFINITY);
                for k in 0..n {
                    let v = speed_cap(m, &ts[2 * k + 1], machine);
                    time += len / n as f64 / v;
                    low = low.min(v);
                }
                (time, low)
            }
        })
        .collect()
}

/// What Kerf did with a program.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KerfRun {
    /// Periods from the start to rest times the period, s.
    pub time_s: f64,
    /// Periods stepped.
    pub cycles: u64,
    /// Periods whose path speed was below half the feed of the move being run (its
    /// programmed feed capped by the axis velocity limits along it).
    pub below_half_feed: u64,
    /// Largest distance of a setpoint from the programmed moves, mm.
    pub max_deviation_mm: f64,
}

/// Runs `moves` through the planner and motion core of `kerf sim` on the machine of
/// `config` (`kerf::sim::simulate_with`, the daemon's queue capacity; every setpoint is
/// checked against the limits), counting periods below half the feed.
pub fn run_kerf(name: &str, moves: &[Move], config: &Config) -> Result<KerfRun, MeasureError> {
    let machine = bound_machine(config);
    let feeds: Vec<f64> = feed_times(moves, &machine)
        .into_iter()
        .map(|(_, v)| v)
        .collect();
    let limits = kerf_config::machine_limits(config);
    let options = SimOptions {
        queue_capacity: config.daemon.queue_segments as usize,
        ..SimOptions::default()
    };
    let mut below = 0u64;
    let summary = kerf::sim::simulate_with(moves, &limits, &options, |t, sp| {
        let feed = feeds
            .get(sp.move_index as usize)
            .copied()
            .unwrap_or(f64::INFINITY);
        if t > 0.0 && sp.feed_mm_s < 0.5 * feed {
            below += 1;
        }
    })
    .map_err(|source| MeasureError::Sim {
        name: name.to_string(),
        source,
    })?;
    if let Some(last) = moves.last() {
        let e = last.path.end();
        let p = summary.raw.last.position;
        if (Vec3::new(p[0], p[1], p[2]) - e).norm() > 1e-6 {
            return Err(MeasureError::WrongEnd {
                name: name.to_string(),
                end: [p[0], p[1], p[2]],
                expected: [e.x, e.y, e.z],
            });
        }
    }
    Ok(KerfRun {
        time_s: summary.duration_s,
        cycles: summary.raw.cycles,
        below_half_feed: below,
        max_deviation_mm: summary.max_deviation_mm,
    })
}

/// One row of the table.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Program name.
    pub name: String,
    /// Lines of the program.
    pub lines: usize,
    /// Σ length / min(F, axis velocity limits along the move), s.
    pub feed_time_s: f64,
    /// The acceleration-limited time-optimal traversal of the exact path, s.
    pub bound_s: f64,
    /// The jerk-limited lower bound on the exact path ([`crate::jerk`]), s, when asked
    /// for.
    pub jerk_s: Option<f64>,
    /// Kerf's run.
    pub kerf: KerfRun,
}

/// The jerk-limited lower bound of `program` on the machine of `config`
/// ([`jerk::jerk_lower_bound`]), sampled as in the table: every [`JERK_DS_MM`], at most
/// [`JERK_SAMPLES`] samples.
pub fn jerk_bound(program: &CamProgram, config: &Config) -> Result<jerk::JerkBound, MeasureError> {
    let length_mm: f64 = program.pieces.iter().map(|p| p.shape.length_mm()).sum();
    let ds_mm = JERK_DS_MM.max(length_mm / JERK_SAMPLES);
    jerk::jerk_lower_bound(&program.pieces, &jerk_machine(config), ds_mm).map_err(|source| {
        MeasureError::Jerk {
            name: program.name.clone(),
            source,
        }
    })
}

/// Measures one program on the machine of `config`, with the jerk-limited bound when
/// `with_jerk` (up to a few seconds a program in a release build).
pub fn measure(
    program: &CamProgram,
    config: &Config,
    with_jerk: bool,
) -> Result<Row, MeasureError> {
    let moves = programmed_moves(&program.name, &program.text, config)?;
    let machine = bound_machine(config);
    let feed_time_s = feed_times(&moves, &machine).iter().map(|(t, _)| t).sum();
    let bound_s = bound::lower_bound(&program.pieces, &machine, BOUND_DS_MM).time_s;
    let jerk_s = if with_jerk {
        Some(jerk_bound(program, config)?.time_s)
    } else {
        None
    };
    let kerf = run_kerf(&program.name, &moves, config)?;
    Ok(Row {
        name: program.name.clone(),
        lines: program.lines(),
        feed_time_s,
        bound_s,
        jerk_s,
        kerf,
    })
}

/// The table as Markdown (with the jerk-limited bound's columns when every row has it).
pub fn table(rows: &[Row]) -> String {
    let with_jerk = !rows.is_empty() && rows.iter().all(|r| r.jerk_s.is_some());
    let mut out = String::new();
    out.push_str("| program | lines | feed time | lower bound |");
    if with_jerk {
        out.push_str(" jerk bound |");
    }
    out.push_str(" Kerf | Kerf/feed | Kerf/bound |");
    if with_jerk {
        out.push_str(" Kerf/jerk bound |");
    }
    out.push_str(" cycles < ½ feed | max dev |\n|---|---:|---:|---:|");
    if with_jerk {
        out.push_str("---:|---:|");
    }
    out.push_str("---:|---:|---:|---:|---:|\n");
    for r in rows {
        let below = r.kerf.below_half_feed as f64 / r.kerf.cycles.max(1) as f64;
        let _ = write!(
            out,
            "| {} | {} | {:.3} s | {:.3} s |",
            r.name, r.lines, r.feed_time_s, r.bound_s
        );
        if let (true, Some(j)) = (with_jerk, r.jerk_s) {
            let _ = write!(out, " {j:.3} s |");
        }
        let _ = write!(
            out,
            " {:.3} s | {:.2} | {:.2} |",
            r.kerf.time_s,
            r.kerf.time_s / r.feed_time_s,
            r.kerf.time_s / r.bound_s
        );
        if let (true, Some(j)) = (with_jerk, r.jerk_s) {
            let _ = write!(out, " {:.2} |", r.kerf.time_s / j);
        }
        let _ = writeln!(
            out,
            " {:.0} % | {:.4} mm |",
            below * 100.0,
            r.kerf.max_deviation_mm
        );
    }
    out
}
