//! Measures the wake-up latency of the `kerfd` cycle clock on this machine.
//!
//! ```text
//! cargo run --release -p kerf-rt --example cycle_latency -- [--period-us US]... [--cycles N]
//!     [--rt] [--no-fifo] [--priority P] [--cpu C]
//! ```
//!
//! Runs `PeriodicClock` for N cycles (default 10 000) at each period (default 1000 µs and
//! 250 µs, i.e. 1 kHz and 4 kHz) and prints the wake-up latency percentiles and the overrun
//! count. With `--rt` the measuring thread first calls `rt_setup` (SCHED_FIFO at `--priority`,
//! default 80, or none with `--no-fifo`; pinned to `--cpu` if given; memory locked; timer
//! slack 1 ns) and the report says what took effect.
//! The cycle does nothing but record its latency in a preallocated buffer.

use std::process::ExitCode;

use kerf_rt::{PeriodicClock, RtConfig, rt_setup};

struct Args {
    periods_us: Vec<u64>,
    cycles: usize,
    rt: bool,
    fifo: bool,
    priority: u8,
    cpu: Option<usize>,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        periods_us: Vec::new(),
        cycles: 10_000,
        rt: false,
        fifo: true,
        priority: 80,
        cpu: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        let mut value = |name: &str| it.next().ok_or(format!("{name} needs a value"));
        match arg.as_str() {
            "--period-us" => args.periods_us.push(
                value("--period-us")?
                    .parse()
                    .map_err(|e| format!("--period-us: {e}"))?,
            ),
            "--cycles" => {
                args.cycles = value("--cycles")?
                    .parse()
                    .map_err(|e| format!("--cycles: {e}"))?
            }
            "--rt" => args.rt = true,
            "--no-fifo" => args.fifo = false,
            "--priority" => {
                args.priority = value("--priority")?
                    .parse()
                    .map_err(|e| format!("--priority: {e}"))?
            }
            "--cpu" => args.cpu = Some(value("--cpu")?.parse().map_err(|e| format!("--cpu: {e}"))?),
            "-h" | "--help" => {
                return Err(
                    "usage: cycle_latency [--period-us US]... [--cycles N] [--rt] \
                            [--no-fifo] [--priority P] [--cpu C]"
                        .to_owned(),
                );
            }
            other => return Err(format!("unknown argument {other:?} (try --help)")),
        }
    }
    if args.periods_us.is_empty() {
        args.periods_us = vec![1000, 250];
    }
    if args.cycles == 0 {
        return Err("--cycles must be at least 1".to_owned());
    }
    Ok(args)
}

/// The value at quantile `q` of sorted data (nearest rank).
fn quantile(sorted: &[u64], q: f64) -> u64 {
    let rank = (q * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

fn run(args: &Args) -> Result<(), String> {
    if args.rt {
        let report = rt_setup(&RtConfig {
            priority: args.fifo.then_some(args.priority),
            cpu: args.cpu,
            prefault_stack_bytes: 256 * 1024,
        })
        .map_err(|e| e.to_string())?;
        println!(
            "rt_setup: mlocked={} fifo={} affinity={} timer_slack={}",
            report.mlocked, report.fifo, report.affinity, report.timer_slack
        );
        for message in &report.messages {
            println!("rt_setup: {message}");
        }
    } else {
        println!("rt_setup: not called (normal scheduler, memory not locked)");
    }
    println!("period_us  cycles  p50_us  p99_us  p99.9_us  max_us  overruns");
    for &period_us in &args.periods_us {
        let mut latencies_ns = vec![0u64; args.cycles];
        let mut clock =
            PeriodicClock::new(period_us.saturating_mul(1000)).map_err(|e| e.to_string())?;
        for slot in latencies_ns.iter_mut() {
            *slot = clock.wait_next().latency_ns;
        }
        latencies_ns.sort_unstable();
        let us = |ns: u64| ns as f64 / 1000.0;
        println!(
            "{:>9}  {:>6}  {:>6.1}  {:>6.1}  {:>8.1}  {:>6.1}  {:>8}",
            period_us,
            args.cycles,
            us(quantile(&latencies_ns, 0.5)),
            us(quantile(&latencies_ns, 0.99)),
            us(quantile(&latencies_ns, 0.999)),
            us(quantile(&latencies_ns, 1.0)),
            clock.overruns()
        );
    }
    Ok(())
}

fn main() -> ExitCode {
    match parse_args().and_then(|args| run(&args)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("cycle_latency: {message}");
            ExitCode::FAILURE
        }
    }
}
