//! Prints the planned segments of a program, one per line (a debugging aid):
//! `cargo run --release -p kerf --example segments -- PROGRAM [DIALECT]` (the machine is
//! the bundled config, or the file named by `KERF_CONFIG`; `KERF_OVERRIDE` in % sets the design override).

use kerf_config::Config;
use kerf_config::machine_limits;
use kerf_gcode::{Dialect, Interpreter, Item};
use kerf_plan::Planner;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).ok_or("usage: segments PROGRAM [DIALECT]")?;
    let config = match std::env::var("KERF_CONFIG") {
        Ok(path) => Config::load(std::path::Path::new(&path)).map_err(|e| format!("{e}"))?,
        Err(_) => Config::builtin(),
    };
    let dialect = match args.get(2) {
        Some(d) => Dialect::from_name(d).ok_or("unknown dialect")?,
        None => Dialect::LinuxCnc,
    };
    let file = std::io::BufReader::new(std::fs::File::open(path)?);
    let limits = machine_limits(&config);
    let mut planner = Planner::new(limits);
    if let Some(f) = std::env::var("KERF_OVERRIDE")
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
    {
        planner.set_design_override(f / 100.0);
    }
    let mut out = Vec::new();
    let interp = Interpreter::new(file, dialect, config.settings());
    for item in interp {
        if let Item::Move(m) = item.map_err(|d| format!("{d:?}"))? {
            planner.push(&m, &mut out)?;
        }
    }
    planner.finish(&mut out);
    use std::io::Write;
    let mut stdout = std::io::stdout().lock();
    for s in &out {
        // Corner blends, smoothed pieces (several moves) and G2 transitions apart.
        let kind = match s.curve {
            kerf_geom::Curve::Line { .. } if s.blend => "lblend",
            kerf_geom::Curve::Line { .. } => "line",
            kerf_geom::Curve::Helix(_) if s.blend => "ablend",
            kerf_geom::Curve::Helix(_) => "arc",
            kerf_geom::Curve::Transition(_) if s.move_count > 1 => "piece",
            kerf_geom::Curve::Transition(_) => "g2",
        };
        let vcs = constant_speed_mm_s(s, &limits);
        let written = writeln!(
            stdout,
            "{kind:8} line {:5} index {:5} moves {:4} len {:8.4} v {:7.2} a {:8.1} j {:9.1} cap {:7.2} vcs {vcs:7.2}",
            s.line,
            s.move_index,
            s.move_count,
            s.length_mm,
            s.v_max_mm_s,
            s.accel_mm_s2,
            s.jerk_mm_s3,
            s.end_cap_mm_s
        );
        if written.is_err() {
            // The reader went away (`| head`).
            break;
        }
    }
    Ok(())
}

/// The highest speed at which the segment's geometry could be run at constant speed with
/// every axis within its velocity, acceleration and jerk (the axis derivatives along the
/// path times v, v² and v³; derivatives by differences every 0.01 mm or less): what its
/// shape allows with no speed change, to compare with its design speed `v`.
fn constant_speed_mm_s(seg: &kerf_geom::PlannedSegment, limits: &kerf_geom::MachineLimits) -> f64 {
    let len = seg.length_mm;
    if len <= 0.0 {
        return 0.0;
    }
    let h = 0.01_f64.min(len / 8.0);
    let n = ((len / h).ceil() as usize).max(2);
    let at = |s: f64| {
        let mut q = [0.0; 6];
        seg.position_at(s.clamp(0.0, len), &mut q);
        q
    };
    let mut best = f64::INFINITY;
    for k in 0..=n {
        let s = (len * k as f64 / n as f64).clamp(2.0 * h, len - 2.0 * h);
        let (m2, m1, q0, p1, p2) = (
            at(s - 2.0 * h),
            at(s - h),
            at(s),
            at(s + h),
            at(s + 2.0 * h),
        );
        for (i, axis) in limits.axes.iter().enumerate() {
            let Some(axis) = axis else { continue };
            let d1 = ((p1[i] - m1[i]) / (2.0 * h)).abs();
            let d2 = ((p1[i] - 2.0 * q0[i] + m1[i]) / (h * h)).abs();
            let d3 = ((p2[i] - 2.0 * p1[i] + 2.0 * m1[i] - m2[i]) / (2.0 * h * h * h)).abs();
            best = best
                .min(axis.velocity_units_s / d1)
                .min((axis.acceleration_units_s2 / d2).sqrt())
                .min((axis.jerk_units_s3 / d3).cbrt());
        }
    }
    best
}
