//! `kerf-ecat-sim`: the emulated EtherCAT network on a Linux interface. See the library's
//! documentation for the default identities.
//!
//! Control on standard input, one command per line:
//! - `mute` stops answering frames (a pulled cable), `unmute` answers again;
//! - `fault P CODE` trips a fault with error code CODE (e.g. 0x2310) in the drive at
//!   position P (0 first);
//! - `inputs N BITS` sets the input bits of the N-th I/O subdevice (0 first).
//!
//! SIGTERM or SIGINT ends it cleanly.

use std::io::BufRead;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::Parser;
use kerf_ecat_sim::socket::RawSocket;
use kerf_ecat_sim::{NetworkSpec, build};

fn parse_u32(text: &str) -> Result<u32, String> {
    let parsed = match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => u32::from_str_radix(&hex.replace('_', ""), 16),
        None => text.replace('_', "").parse(),
    };
    parsed.map_err(|e| format!("{text:?} is not a 32-bit number: {e}"))
}

/// Emulated EtherCAT network: CiA 402 drives, then digital I/O subdevices, answering
/// EtherCAT frames on INTERFACE. Defaults: vendor id 0x00004B52; drives product code
/// 0x00000402, serials 0x1001, 0x1002, …, name "Kerf CiA402 drive"; I/O product code
/// 0x00000010, serials 0x2001, …, name "Kerf digital I/O", 8 inputs and 8 outputs;
/// revision 0x00010000. Standard input, one command a line: "mute" stops answering,
/// "unmute" answers again, "fault P CODE" trips a fault in the drive at position P,
/// "inputs N BITS" sets the N-th I/O subdevice's input bits.
#[derive(Debug, Parser)]
#[command(name = "kerf-ecat-sim", version)]
struct Args {
    /// Network interface to answer on.
    #[arg(long)]
    interface: String,
    /// Number of CiA 402 drives.
    #[arg(long, default_value_t = 1)]
    drives: u16,
    /// Number of digital I/O subdevices.
    #[arg(long, default_value_t = 0)]
    io: u16,
    /// Vendor id of every subdevice.
    #[arg(long, value_parser = parse_u32, default_value = "0x00004B52")]
    vendor_id: u32,
    /// Product code of the drives.
    #[arg(long, value_parser = parse_u32, default_value = "0x00000402")]
    product_code: u32,
    /// Product code of the I/O subdevices.
    #[arg(long, value_parser = parse_u32, default_value = "0x00000010")]
    io_product_code: u32,
    /// Revision of every subdevice.
    #[arg(long, value_parser = parse_u32, default_value = "0x00010000")]
    revision: u32,
    /// The subdevice at this position (0 first; repeatable) refuses SAFE-OP with AL status
    /// code 0x001D, invalid output configuration.
    #[arg(long, value_name = "POSITION")]
    refuse_safe_op: Vec<u16>,
    /// The line's one oscillator runs PPM parts per million fast against the host's
    /// CLOCK_MONOTONIC (negative: slow; at most 10000 either way). Every subdevice's
    /// local clock, and so the reference clock's system time (0x0910), gains PPM µs per
    /// second on the host; the subdevices do not drift against each other.
    #[arg(
        long,
        value_name = "PPM",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    dc_drift_ppm: f64,
}

/// Carries out one control command from standard input.
fn control(
    command: &str,
    network: &mut kerf_ecat_sim::network::Network,
    handles: &[kerf_ecat_sim::io::IoHandle],
    muted: &mut bool,
) -> Result<(), String> {
    let words: Vec<&str> = command.split_whitespace().collect();
    let index = |text: &str| text.parse::<usize>().map_err(|e| format!("{text:?}: {e}"));
    match words.as_slice() {
        ["mute"] => *muted = true,
        ["unmute"] => *muted = false,
        ["fault", position, code] => {
            let code = u16::try_from(parse_u32(code)?).map_err(|e| e.to_string())?;
            if !network.inject_fault(index(position)?, code) {
                return Err(format!("no drive at position {position}"));
            }
        }
        ["inputs", n, bits] => {
            let handle = handles
                .get(index(n)?)
                .ok_or_else(|| format!("no I/O subdevice number {n}"))?;
            handle.set_inputs(u64::from(parse_u32(bits)?));
        }
        _ => {
            return Err(
                "unknown command (mute, unmute, fault POSITION CODE, inputs N BITS)".into(),
            );
        }
    }
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let count = usize::from(args.drives) + usize::from(args.io);
    if let Some(bad) = args
        .refuse_safe_op
        .iter()
        .find(|p| usize::from(**p) >= count)
    {
        anyhow::bail!("--refuse-safe-op {bad}: the line has only {count} subdevice(s)");
    }
    if args.dc_drift_ppm.is_nan() || args.dc_drift_ppm.abs() > kerf_ecat_sim::dc::MAX_DRIFT_PPM {
        anyhow::bail!(
            "--dc-drift-ppm {}: the drift must be a number from -{max} to {max}",
            args.dc_drift_ppm,
            max = kerf_ecat_sim::dc::MAX_DRIFT_PPM
        );
    }
    let spec = NetworkSpec {
        drives: args.drives,
        io: args.io,
        vendor_id: args.vendor_id,
        drive_product_code: args.product_code,
        io_product_code: args.io_product_code,
        revision: args.revision,
        refuse_safe_op: args.refuse_safe_op.clone(),
        dc_drift_ppm: args.dc_drift_ppm,
        ..NetworkSpec::default()
    };
    let (mut network, handles) = build(&spec);
    let signals = kerf_rt::Signals::install().context("installing signal handlers")?;
    let mut socket = RawSocket::open(&args.interface, Duration::from_millis(1))
        .with_context(|| format!("opening a raw socket on {}", args.interface))?;
    let (control_tx, control_rx) = mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in std::io::stdin().lock().lines().map_while(Result::ok) {
            if control_tx.send(line.trim().to_owned()).is_err() {
                break;
            }
        }
    });
    eprintln!(
        "kerf-ecat-sim: {} drive(s), {} I/O subdevice(s) on {}",
        args.drives, args.io, args.interface
    );
    let start = Instant::now();
    let mut muted = false;
    let mut buffer = vec![0u8; 2048];
    while signals.stop_requested().is_none() {
        while let Ok(command) = control_rx.try_recv() {
            match control(&command, &mut network, &handles, &mut muted) {
                Ok(()) => eprintln!("kerf-ecat-sim: done: {command}"),
                Err(e) => eprintln!("kerf-ecat-sim: {command:?} refused: {e}"),
            }
        }
        let now_ns = start.elapsed().as_nanos() as u64;
        network.tick(now_ns);
        let Some(len) = socket.recv(&mut buffer).context("receiving")? else {
            continue;
        };
        let frame = &mut buffer[..len];
        // A frame already processed (ours, coming back as we send it) has the locally
        // administered bit of its source address set.
        if len < 14 || frame[6] & 0x02 != 0 || muted {
            continue;
        }
        let now_ns = start.elapsed().as_nanos() as u64;
        match network.process(frame, now_ns) {
            Ok(()) => socket.send(frame).context("sending")?,
            Err(e) => eprintln!("kerf-ecat-sim: frame ignored: {e}"),
        }
    }
    eprintln!("kerf-ecat-sim: stopped");
    Ok(())
}
