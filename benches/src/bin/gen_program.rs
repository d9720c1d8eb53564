//! Writes a large generated LinuxCNC program (dense lines and arcs) to standard output.
//!
//! Usage: `gen_program --blocks N` or `gen_program --megabytes N`. Used to measure the
//! memory and throughput of `kerf plan` on a program far larger than memory would allow
//! if it were not streamed (see docs/PERFORMANCE.md).

use std::io::{self, BufWriter, Write};
use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (blocks, max_bytes) = match args.iter().map(String::as_str).collect::<Vec<_>>()[..] {
        ["--blocks", n] => match n.parse::<u64>() {
            Ok(n) => (n, u64::MAX),
            Err(_) => return usage(),
        },
        ["--megabytes", n] => match n.parse::<u64>() {
            Ok(n) => (u64::MAX, n.saturating_mul(1 << 20)),
            Err(_) => return usage(),
        },
        _ => return usage(),
    };
    let mut out = BufWriter::with_capacity(1 << 20, io::stdout().lock());
    let result = kerf_benches::write_program(&mut out, blocks, max_bytes).and_then(|r| {
        out.flush()?;
        Ok(r)
    });
    match result {
        Ok((blocks, bytes)) => {
            eprintln!("gen_program: wrote {blocks} blocks, {bytes} bytes");
            ExitCode::SUCCESS
        }
        Err(e) if e.kind() == io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("gen_program: error: {e}");
            ExitCode::from(2)
        }
    }
}

fn usage() -> ExitCode {
    eprintln!("usage: gen_program --blocks N | --megabytes N  (program on standard output)");
    ExitCode::from(2)
}
