//! How far planning stays ahead of real time on CAM code: for every program of the CAM
//! corpus (`kerf_benches::cam`, on the small mill of `benches/cam-mill.toml`), the
//! planner's cost per programmed move (`kerf_pipeline::plan_input` into a
//! `kerf_plan::Planner`, then `finish`: what the daemon's planning thread does per move,
//! without the transport) against the motion time of the same program (`kerf sim`'s), as
//! a real-time factor: motion time / planning time. The daemon starves when the factor
//! falls to 1; the target is at least 20.
//!
//! Usage: `cargo run --release -p kerf-benches --bin plan_rate [NAME_PART]`. Each program
//! is planned 5 times; the fastest run counts (the others carry the machine's noise).

use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context as _;
use kerf_benches::{cam, measure};
use kerf_pipeline::{Input, plan_input};
use kerf_plan::Planner;

/// Moves of the non-repeating surface.
const NOISY_SEGMENTS: usize = 20_000;
/// Moves of the non-repeating surface with noise above the tolerance.
const ROUGH_SEGMENTS: usize = 5_000;

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("plan_rate: error: {e:#}");
            ExitCode::from(1)
        }
    }
}

fn run() -> anyhow::Result<()> {
    let filter = std::env::args().nth(1).unwrap_or_default();
    let config = measure::machine()?;
    let limits = kerf_config::machine_limits(&config);
    println!(
        "| program | moves | planning, µs per move | planning total | motion time | real-time factor |"
    );
    println!("|---|---:|---:|---:|---:|---:|");
    // The corpus, and a surface whose moves never repeat (the memos cannot help).
    let mut programs: Vec<(String, String)> = cam::corpus()
        .into_iter()
        .map(|p| (p.name, p.text))
        .collect();
    programs.push((
        "noisy surface 20000 (non-repeating)".to_string(),
        cam::noisy_surface(NOISY_SEGMENTS, 1, 0.002),
    ));
    // Noise above the tolerance: every vertex a real corner.
    programs.push((
        "rough surface 5000 (non-repeating, noise 0.02 mm)".to_string(),
        cam::noisy_surface(ROUGH_SEGMENTS, 1, 0.02),
    ));
    for (name, text) in programs.iter().filter(|(n, _)| n.contains(&filter)) {
        let moves = measure::programmed_moves(name, text, &config)?;
        let motion = measure::run_kerf(name, &moves, &config)?;
        let mut best_s = f64::INFINITY;
        let mut segments = 0usize;
        for _ in 0..5 {
            let mut planner = Planner::new(limits);
            let mut buf = Vec::new();
            let mut count = 0usize;
            let start = Instant::now();
            for m in &moves {
                plan_input(&mut planner, &Input::Move(*m), &mut buf)
                    .with_context(|| format!("planning {name}"))?;
                count += buf.len();
                buf.clear();
            }
            planner.finish(&mut buf);
            count += buf.len();
            best_s = best_s.min(start.elapsed().as_secs_f64());
            segments = count;
        }
        assert!(segments > 0, "{name}: nothing planned");
        println!(
            "| {} | {} | {:.2} | {:.2} ms | {:.3} s | {:.0}× |",
            name,
            moves.len(),
            best_s * 1e6 / moves.len() as f64,
            best_s * 1e3,
            motion.time_s,
            motion.time_s / best_s
        );
    }
    Ok(())
}
