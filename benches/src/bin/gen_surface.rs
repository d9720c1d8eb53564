//! Writes a non-repeating dense finishing raster (`kerf_benches::cam::noisy_surface`) to
//! standard output: planning's cost on code whose shapes never repeat, and the daemon
//! keeping up with it (docs/PERFORMANCE.md).
//!
//! Usage: `gen_surface --segments N [--seed S] [--noise-mm MM]` (seed 1, noise 0.002 mm
//! unless given).

use std::io::{self, Write};
use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut segments = None;
    let mut seed = 1u64;
    let mut noise_mm = 0.002f64;
    let mut it = args.iter();
    while let Some(flag) = it.next() {
        let value = it.next().map(String::as_str);
        let ok = match (flag.as_str(), value) {
            ("--segments", Some(v)) => v.parse().map(|n| segments = Some(n)).is_ok(),
            ("--seed", Some(v)) => v.parse().map(|s| seed = s).is_ok(),
            ("--noise-mm", Some(v)) => v
                .parse::<f64>()
                .ok()
                .filter(|n| n.is_finite() && *n >= 0.0)
                .map(|n| noise_mm = n)
                .is_some(),
            _ => false,
        };
        if !ok {
            return usage();
        }
    }
    let Some(segments) = segments else {
        return usage();
    };
    let text = kerf_benches::cam::noisy_surface(segments, seed, noise_mm);
    match io::stdout().lock().write_all(text.as_bytes()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.kind() == io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("gen_surface: error: {e}");
            ExitCode::from(2)
        }
    }
}

fn usage() -> ExitCode {
    eprintln!(
        "usage: gen_surface --segments N [--seed S] [--noise-mm MM]  (program on standard output)"
    );
    ExitCode::from(2)
}
