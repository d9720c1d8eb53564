//! Prints the CAM benchmark table of issue 11 (docs/PERFORMANCE.md, "CAM code against the
//! feed and the time-optimal bound"): every program of the generated corpus run through
//! Kerf's planner and motion core on the small mill of `benches/cam-mill.toml`, against
//! the time at the programmed feed and two time-optimal lower bounds: acceleration-limited
//! (`kerf_benches::bound`) and jerk-limited (`kerf_benches::jerk`).
//!
//! Usage: `cargo run --release -p kerf-benches --bin cam_table [--no-jerk] [NAME_PART]`
//! (only the programs whose name contains NAME_PART; `--no-jerk` leaves out the
//! jerk-limited bound of `kerf_benches::jerk`, nearly all of the whole table's 45 s: under
//! 1 s without it), or `--write DIR` to write the programs as `.ngc` files into DIR (to
//! run them with `kerf sim --config benches/cam-mill.toml`), or `--bound-speeds NAME` to
//! print the jerk-limited bound's path speed along the program named NAME as CSV lines
//! `s_mm,speed_mm_s` (compared with `kerf sim`'s setpoints by `benches/speed_bins.py`), or
//! `--pointwise [--largest] [--period-us N] [NAME_PART]` to run the point-wise prototype
//! (`kerf_benches::pointwise`) on the exact path and on the planner's segments of each
//! program (about 10 s for the whole corpus; `--largest` with the search for the largest
//! admissible jerk each period, about 25 s), or `--pointwise-raise [--largest] [SEED]
//! [CASES]` to check whether the prototype is monotonic in the limits on swept machines.

use std::process::ExitCode;

use anyhow::Context as _;
use kerf_benches::{cam, measure, pointwise};

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("cam_table: error: {e:#}");
            ExitCode::from(1)
        }
    }
}

fn run() -> anyhow::Result<()> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let with_jerk = !args.iter().any(|a| a == "--no-jerk");
    args.retain(|a| a != "--no-jerk");
    let corpus = cam::corpus();
    if let [flag, dir] = &args[..]
        && flag == "--write"
    {
        for p in &corpus {
            let file = std::path::Path::new(dir).join(format!("{}.ngc", p.name.replace(' ', "_")));
            std::fs::write(&file, &p.text)
                .with_context(|| format!("writing {}", file.display()))?;
            println!("{}", file.display());
        }
        return Ok(());
    }
    let config = measure::machine()?;
    if let [flag, name] = &args[..]
        && flag == "--bound-speeds"
    {
        let program = corpus
            .iter()
            .find(|p| &p.name == name)
            .with_context(|| format!("no program named {name:?} in the corpus"))?;
        let bound = measure::jerk_bound(program, &config)?;
        println!("s_mm,speed_mm_s");
        for (s_mm, v_mm_s) in bound.s_mm.iter().zip(&bound.speed_mm_s) {
            println!("{s_mm},{v_mm_s}");
        }
        return Ok(());
    }
    if let Some(flag) = args.first()
        && flag == "--pointwise-raise"
    {
        let (search, rest) = search_flag(&args[1..]);
        let number = |i: usize, default: u64| -> anyhow::Result<u64> {
            rest.get(i).map_or(Ok(default), |v| {
                v.parse()
                    .with_context(|| format!("--pointwise-raise wants whole numbers, not {v:?}"))
            })
        };
        return raise_sweep(number(0, 1)?, number(1, 20)?, search);
    }
    if let Some(flag) = args.first()
        && flag == "--pointwise"
    {
        let (search, mut rest) = search_flag(&args[1..]);
        let mut period_s = None;
        if let [flag, us, tail @ ..] = rest
            && flag == "--period-us"
        {
            let us: f64 = us
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite() && *v > 0.0)
                .with_context(|| format!("--period-us wants a positive number, not {us:?}"))?;
            period_s = Some(us * 1e-6);
            rest = tail;
        }
        let filter = rest.first().map(String::as_str).unwrap_or("");
        return pointwise_table(&corpus, &config, period_s, search, filter);
    }
    let filter = args.first().map(String::as_str).unwrap_or("");
    let mut rows = Vec::new();
    for p in corpus.iter().filter(|p| p.name.contains(filter)) {
        rows.push(measure::measure(p, &config, with_jerk)?);
    }
    println!(
        "Machine: benches/cam-mill.toml (X/Y 200 mm/s, 2000 mm/s², 50000 mm/s³; \
         Z 100 mm/s, 1000 mm/s², 20000 mm/s³; period 1 ms; tolerance 0.01 mm)\n"
    );
    print!("{}", measure::table(&rows));
    Ok(())
}

/// Prints the table of the point-wise prototype (`kerf_benches::pointwise`) on the
/// programs whose name contains `filter`: on the exact path and on the planner's
/// segments (planned at the configuration's period), run at `period_s` (else the
/// configuration's) with `search`.
fn pointwise_table(
    corpus: &[cam::CamProgram],
    config: &kerf_config::Config,
    period_s: Option<f64>,
    search: pointwise::Search,
    filter: &str,
) -> anyhow::Result<()> {
    let mut limits = kerf_config::machine_limits(config);
    if let Some(period_s) = period_s {
        limits.period_s = period_s;
    }
    let machine = measure::jerk_machine(config);
    println!(
        "| program | path | time | fallbacks | peak v / a / j | µs per cycle | checks per cycle | most in a cycle | points | stops | gap |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for p in corpus.iter().filter(|p| p.name.contains(filter)) {
        let moves = measure::programmed_moves(&p.name, &p.text, config)?;
        let segments = measure::planned_segments(&p.name, &moves, config)?;
        for (path, grid) in [
            (
                "exact",
                pointwise::Grid::from_pieces(&p.pieces, &machine, POINTWISE_DS_MM),
            ),
            (
                "planned",
                pointwise::Grid::from_segments(&segments, &limits, POINTWISE_DS_MM),
            ),
        ] {
            let run = grid.run_with(&limits, search);
            println!(
                "| {} | {path} | {:.3} s{} | {} | {:.3} / {:.3} / {:.3} | {:.0} | {:.0} | {} | {} | {} | {:.0e} mm |",
                p.name,
                run.time_s,
                if run.stuck { " (stuck)" } else { "" },
                run.fallbacks,
                run.peaks[0],
                run.peaks[1],
                run.peaks[2],
                run.us_per_cycle,
                run.checks_per_cycle,
                run.most_checks,
                run.points,
                run.stops,
                run.gap_mm
            );
        }
    }
    Ok(())
}

/// The point-wise prototype's search: `--largest` at the head of `args` (taken off) for
/// the full search, else the candidates'.
fn search_flag(args: &[String]) -> (pointwise::Search, &[String]) {
    match args {
        [flag, rest @ ..] if flag == "--largest" => (pointwise::Search::Largest, rest),
        _ => (pointwise::Search::Candidates, args),
    }
}

/// Whether the point-wise prototype is monotonic in the limits, as Kerf's core is
/// (kerf-pipeline's `monotonic` property: raising one limit never makes a program more
/// than 1 % and a period slower), over [`kerf_benches::swept::raise_sweep`]. Prints every
/// case that slowed by more than that, and a summary line.
fn raise_sweep(seed: u64, cases: u64, search: pointwise::Search) -> anyhow::Result<()> {
    let runs = kerf_benches::swept::raise_sweep(seed, cases, search, POINTWISE_DS_MM)
        .map_err(anyhow::Error::msg)?;
    let mut worst = 1.0f64;
    let mut slower = 0;
    for r in &runs {
        let [before, after] = r.times_s;
        worst = worst.max(after / before);
        if r.slower() {
            slower += 1;
            println!(
                "case {} {} (period {} s, feed {:.1}): {} of axis {} x{:.2}: {before:.4} s -> \
                 {after:.4} s ({:+.1} %)",
                r.case,
                r.path,
                r.period_s,
                r.feed_mm_s,
                ["velocity", "acceleration", "jerk"][r.which],
                r.axis,
                r.factor,
                100.0 * (after / before - 1.0)
            );
        }
    }
    println!(
        "{search:?}: {slower} of {} runs slower by more than 1 % and a period; worst {:+.1} %",
        runs.len(),
        100.0 * (worst - 1.0)
    );
    Ok(())
}

/// Grid spacing of the point-wise prototype, mm: a corner blend within 0.01 mm is a few
/// hundredths of a millimetre long.
const POINTWISE_DS_MM: f64 = 0.002;
