//! Prints the planned segments of a program on the CAM mill (`benches/cam-mill.toml`),
//! one per line: source line, kind, moves it stands for, length, design speed, path
//! acceleration and jerk, end cap. For finding where a program's time goes.
//!
//! `cargo run --release -p kerf-benches --bin seg_dump -- PROGRAM.ngc`

use anyhow::Context as _;
use kerf_geom::Curve;

fn main() -> anyhow::Result<()> {
    let path = std::env::args()
        .nth(1)
        .context("usage: seg_dump PROGRAM.ngc")?;
    let text = std::fs::read_to_string(&path).with_context(|| path.clone())?;
    let config = kerf_benches::measure::machine()?;
    let moves = kerf_benches::measure::programmed_moves(&path, &text, &config)?;
    let mut planner = kerf_plan::Planner::new(kerf::sim::machine_limits(&config));
    let mut out = Vec::new();
    for m in &moves {
        planner.push(m, &mut out)?;
    }
    planner.finish(&mut out);
    println!("line kind  moves length_mm v_max_mm_s accel_mm_s2 jerk_mm_s3 end_cap_mm_s");
    for s in &out {
        let kind = match s.curve {
            Curve::Line { .. } if s.blend => "lblnd",
            Curve::Line { .. } => "line",
            Curve::Helix(_) if s.blend => "ablnd",
            Curve::Helix(_) => "arc",
            Curve::Transition(_) if s.move_count > 1 => "piece",
            Curve::Transition(_) => "g2",
        };
        println!(
            "{:4} {:5} {:5} {:9.4} {:10.2} {:11.1} {:10.1} {:12.2}",
            s.line,
            kind,
            s.move_count,
            s.length_mm,
            s.v_max_mm_s,
            s.accel_mm_s2,
            s.jerk_mm_s3,
            s.end_cap_mm_s
        );
    }
    Ok(())
}
