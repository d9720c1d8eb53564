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
        let mut rest = &args[1..];
        let mut search = pointwise::Search::Candidates;
        if let [flag, tail @ ..] = rest
            && flag == "--largest"
        {
            search = pointwise::Search::Largest;
            rest = tail;
        }
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
        let mut rest = &args[1..];
        let mut search = pointwise::Search::Candidates;
        if let [flag, tail @ ..] = rest
            && flag == "--largest"
        {
            search = pointwise::Search::Largest;
            rest = tail;
        }
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
                pointwise::Grid::from_segments(&segments, &machine, POINTWISE_DS_MM),
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

/// Draws from [0, 1) (a 64-bit linear congruential generator, the high bits), as the
/// point-wise prototype's tests do.
struct Draw(u64);

impl Draw {
    fn unit(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

/// Whether the point-wise prototype is monotonic in the limits, as Kerf's core is
/// (kerf-pipeline's `monotonic` property: raising one limit never makes a program more
/// than 1 % and a period slower): `cases` machines drawn from `seed` as in its swept
/// test (every other one at 250 µs), three paths each (corners, a reversal, a helix),
/// one axis's velocity, acceleration or jerk raised 1.1 to 3-fold. Prints every case
/// that slowed by more than that, and a summary line.
fn raise_sweep(seed: u64, cases: u64, search: pointwise::Search) -> anyhow::Result<()> {
    use kerf_benches::bound::{BoundMachine, Piece, Shape};
    use kerf_benches::jerk::JerkMachine;
    use kerf_geom::{AxisLimits, MachineLimits, Vec3};
    let line = |a: [f64; 3], b: [f64; 3], feed_mm_s: f64| Piece {
        shape: Shape::Line {
            start: Vec3::from(a),
            end: Vec3::from(b),
        },
        feed_mm_s,
    };
    // A helix about Z from the origin: radius 1.5 mm, 1.25 turns, 1 mm a turn.
    let helix = |feed_mm_s: f64| Piece {
        shape: Shape::Arc {
            center: Vec3::new(-1.5, 0.0, 0.0),
            e1: Vec3::x(),
            e2: Vec3::y(),
            radius_mm: 1.5,
            from_rad: 0.0,
            to_rad: 1.25 * std::f64::consts::TAU,
            axial_per_rad: Vec3::new(0.0, 0.0, 1.0 / std::f64::consts::TAU),
        },
        feed_mm_s,
    };
    let machine = |v: [f64; 3], a: [f64; 3], j: [f64; 3], tolerance_mm: f64, period_s: f64| {
        let mut axes = [None; 6];
        for (i, axis) in axes.iter_mut().take(3).enumerate() {
            *axis = Some(AxisLimits {
                velocity_units_s: v[i],
                acceleration_units_s2: a[i],
                jerk_units_s3: j[i],
            });
        }
        (
            JerkMachine {
                base: BoundMachine {
                    velocity_mm_s: v,
                    acceleration_mm_s2: a,
                    tolerance_mm,
                },
                jerk_mm_s3: j,
            },
            MachineLimits {
                axes,
                period_s,
                tolerance_mm,
            },
        )
    };
    let mut draw = Draw(seed);
    let (mut runs, mut slower) = (0u64, 0u64);
    let mut worst = 1.0f64;
    for case in 0..cases {
        let v = [0, 1, 2].map(|_| draw.range(50.0, 300.0));
        let a = [0, 1, 2].map(|_| draw.range(300.0, 3000.0));
        let j = [0, 1, 2].map(|_| draw.range(5_000.0, 80_000.0));
        let tolerance = draw.range(0.005, 0.05);
        let feed = draw.range(20.0, 150.0);
        let axis = ((draw.unit() * 3.0) as usize).min(2);
        let which = ((draw.unit() * 3.0) as usize).min(2);
        let factor = draw.range(1.1, 3.0);
        let period_s = if case % 2 == 1 { 0.00025 } else { 0.001 };
        let mut raised = [v, a, j];
        raised[which][axis] *= factor;
        let paths = [
            (
                "corners",
                vec![
                    line([0.0; 3], [3.0, 0.0, 0.0], feed),
                    line([3.0, 0.0, 0.0], [3.0, 2.0, 0.5], feed),
                    line([3.0, 2.0, 0.5], [1.0, 3.0, 0.5], feed),
                ],
            ),
            (
                "reversal",
                vec![
                    line([0.0; 3], [2.0, 1.0, 0.0], feed),
                    line([2.0, 1.0, 0.0], [0.0, 0.0, 0.0], feed),
                ],
            ),
            ("helix", vec![helix(feed)]),
        ];
        for (name, pieces) in paths {
            let mut times = [0.0; 2];
            for (k, [vv, aa, jj]) in [[v, a, j], raised].into_iter().enumerate() {
                let (m, limits) = machine(vv, aa, jj, tolerance, period_s);
                let run = pointwise::Grid::from_pieces(&pieces, &m, POINTWISE_DS_MM)
                    .run_with(&limits, search);
                anyhow::ensure!(
                    !run.stuck && run.fallbacks == 0,
                    "case {case} {name}: stuck or fell back"
                );
                times[k] = run.time_s;
            }
            runs += 1;
            worst = worst.max(times[1] / times[0]);
            if times[1] > 1.01 * times[0] + period_s {
                slower += 1;
                println!(
                    "case {case} {name} (period {period_s} s, feed {feed:.1}): {} of axis {axis} \
                     x{factor:.2}: {:.4} s -> {:.4} s ({:+.1} %)",
                    ["velocity", "acceleration", "jerk"][which],
                    times[0],
                    times[1],
                    100.0 * (times[1] / times[0] - 1.0)
                );
            }
        }
    }
    println!(
        "{search:?}: {slower} of {runs} runs slower by more than 1 % and a period; worst {:+.1} %",
        100.0 * (worst - 1.0)
    );
    Ok(())
}

/// Grid spacing of the point-wise prototype, mm: a corner blend within 0.01 mm is a few
/// hundredths of a millimetre long.
const POINTWISE_DS_MM: f64 = 0.002;
