//! `kerfd`: the real-time interpolator daemon of one machine, in the foreground.
//!
//! It reads the machine configuration (`--config FILE`, else `/etc/kerf/kerf.toml` when it
//! exists, else the built-in example), creates the machine's iceoryx2 services
//! (`kerf/<machine>/…`), runs the cycle at the configured period, and tells systemd when
//! it is ready (`Type=notify`) and that it is alive (the watchdog is fed only while the
//! cycle advances). SIGTERM and SIGINT bring the motion to a jerk-limited stop on the
//! path, then it exits 0.
//!
//! Logs go to standard error, one line per event; under systemd, journald stores them.
//! Exit codes: 0 after a requested stop, 1 when it cannot start or a thread failed.
#![forbid(unsafe_code)]

use std::process::ExitCode;
use std::time::Duration;

use clap::{CommandFactory, Parser};
use kerfd::cli::Args;

/// How often the main thread looks at signals and feeds the watchdog.
const SUPERVISE_EVERY: Duration = Duration::from_millis(20);

fn main() -> ExitCode {
    let args = Args::parse();
    if let Some(code) = packaging(&args) {
        return code;
    }
    // journald adds the time; a terminal gets it from us.
    let under_journal = std::env::var_os("JOURNAL_STREAM").is_some();
    let builder = tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_target(false)
        .with_ansi(!under_journal);
    if under_journal {
        builder.without_time().init();
    } else {
        builder.init();
    }
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            tracing::error!("{e}");
            ExitCode::from(1)
        }
    }
}

/// `--completions`: generated from the clap definition ([`kerfd::cli`]), so that the
/// package's copy matches the binary. (The man page is written by `kerf man DIR`.)
fn packaging(args: &Args) -> Option<ExitCode> {
    use std::io::Write;
    let shell = args.completions?;
    let mut out = Vec::new();
    kerfd::cli::write_completions(Args::command(), shell, &mut out);
    Some(match std::io::stdout().lock().write_all(&out) {
        Ok(()) => ExitCode::SUCCESS,
        Err(_) => ExitCode::from(1),
    })
}

fn run(args: &Args) -> Result<(), String> {
    let (config, origin) =
        kerf_config::load_default(args.config.as_deref()).map_err(|e| e.to_string())?;
    let signals =
        kerf_rt::Signals::install().map_err(|e| format!("cannot install signal handlers: {e}"))?;
    if args.test_faults {
        tracing::warn!("--test-faults: the control service accepts injected faults (tests only)");
    }
    if let Some(cpu) = config.daemon.cpu
        && let Err(e) = kerf_rt::avoid_cpu(cpu as usize)
    {
        tracing::warn!("cannot keep the main thread off the cycle's CPU {cpu}: {e}");
    }
    let daemon = kerfd::start_with(&config, true, args.test_faults).map_err(|e| e.to_string())?;
    let rt = daemon.rt();
    if rt.rt {
        tracing::info!(
            "real-time scheduling and locked memory in effect{}",
            match rt.cpu_latency_us {
                Some(us) => format!(", CPU wake-up latency {us} µs"),
                None => String::new(),
            }
        );
        if rt.cpu_latency_us.is_none() {
            tracing::warn!("{}", rt.messages.join("; "));
        }
    } else {
        // Once, then the status says `rt: false`.
        tracing::warn!(
            "running without real-time guarantees: {}",
            rt.messages.join("; ")
        );
    }
    tracing::info!(
        "machine `{}` ready ({origin}, period {} µs, services kerf/{}/…)",
        daemon.machine(),
        config.period_us,
        daemon.machine()
    );
    let _ = kerf_rt::notify_ready();
    let mut watchdog = kerf_rt::Watchdog::new();
    let mut stopping = false;
    loop {
        std::thread::sleep(SUPERVISE_EVERY);
        let _ = watchdog.feed(daemon.cycles());
        if !stopping && let Some(signal) = signals.stop_requested() {
            tracing::info!("signal {signal}: stopping on the path");
            let _ = kerf_rt::notify_stopping();
            daemon.shutdown();
            stopping = true;
        }
        if daemon.finished() {
            break;
        }
    }
    daemon.join().map_err(|e| e.to_string())?;
    if !stopping {
        return Err("the daemon stopped without being asked to".into());
    }
    tracing::info!("stopped");
    Ok(())
}
