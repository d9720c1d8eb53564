//! `kerf-ecat-sim`: the emulated EtherCAT network on a Linux interface. See the library's
//! documentation for the default identities.
//!
//! Control on standard input, one command per line (see `--help` and the library's
//! documentation): `mute`, `unmute`, `fault P CODE`, `leave-op P CODE`, `stall P`, `free P`,
//! `inputs N BITS`, `state`. Standard output carries only the answers to `state`
//! ([`kerf_ecat_sim::report`]); everything else goes to standard error.
//!
//! SIGTERM or SIGINT ends it cleanly.

use std::io::{BufRead, Write};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::Parser;
use kerf_ecat_sim::io::IoHandle;
use kerf_ecat_sim::network::Network;
use kerf_ecat_sim::report;
use kerf_ecat_sim::socket::RawSocket;
use kerf_ecat_sim::switches::{SwitchInput, Switches};
use kerf_ecat_sim::{HomeSwitch, NetworkSpec, SafeOpRefusal, build};

fn parse_u32(text: &str) -> Result<u32, String> {
    let parsed = match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => u32::from_str_radix(&hex.replace('_', ""), 16),
        None => text.replace('_', "").parse(),
    };
    parsed.map_err(|e| format!("{text:?} is not a 32-bit number: {e}"))
}

/// `P` or `P:CODE`, CODE in hexadecimal (`0x` optional), 0x001D by default.
fn parse_refusal(text: &str) -> Result<SafeOpRefusal, String> {
    let (position, code) = match text.split_once(':') {
        Some((position, code)) => {
            let hex = code.strip_prefix("0x").or_else(|| code.strip_prefix("0X"));
            let code = u16::from_str_radix(hex.unwrap_or(code), 16)
                .map_err(|e| format!("AL status code {code:?} is not 4 hex digits: {e}"))?;
            (position, code)
        }
        None => (text, kerf_ecat_sim::al::CODE_INVALID_OUTPUT_CONFIG),
    };
    let position = position
        .parse()
        .map_err(|e| format!("position {position:?}: {e}"))?;
    Ok(SafeOpRefusal {
        position,
        al_status_code: code,
    })
}

/// `P:COUNTS`: a drive's ring position and a position in counts (decimal, may be
/// negative).
fn parse_home_switch(text: &str) -> Result<HomeSwitch, String> {
    let (position, counts) = text
        .split_once(':')
        .ok_or_else(|| format!("{text:?} is not POSITION:COUNTS"))?;
    let position = position
        .parse()
        .map_err(|e| format!("position {position:?}: {e}"))?;
    let counts: f64 = counts
        .parse()
        .map_err(|e| format!("counts {counts:?}: {e}"))?;
    if !counts.is_finite() {
        return Err(format!("counts {counts} is not a position"));
    }
    Ok(HomeSwitch { position, counts })
}

/// Emulated EtherCAT network: CiA 402 drives, then digital I/O subdevices, answering
/// EtherCAT frames on INTERFACE.
///
/// Defaults: vendor id 0x00004B52; drives product code 0x00000402, serials 0x1001,
/// 0x1002, …, name "Kerf CiA402 drive"; I/O product code 0x00000010, serials 0x2001, …,
/// name "Kerf digital I/O", 8 inputs and 8 outputs; revision 0x00010000.
///
/// Standard input, one command a line (P: ring position, 0 first, and N decimal; CODE
/// and BITS decimal or 0x hex):
///   mute            stop answering frames (a pulled cable)
///   unmute          answer again
///   fault P CODE    trip a fault with error code CODE (0x603F) in the drive at P
///   leave-op P CODE the subdevice at P leaves OP by an error of its own: SAFE-OP with
///                   the error flag and AL status code CODE; a drive stops itself
///   stall P         jam the motor of the drive at P: it stays where it is while the
///                   target moves on, so the following error (0x60F4) grows and
///                   statusword bit 13 is set beyond the 1000-count window; velocity 0;
///                   no fault of its own
///   free P          let it turn again (enabled under a large following error it pulls
///                   to the target and may trip overcurrent 0x2310)
///   inputs N BITS   set the input bits of the N-th I/O subdevice (0 first)
///   state           print one line per subdevice to standard output, e.g.
///     subdevice 0 kind=drive al=OP al_error=0 al_code=0x0000 watchdog_trips=0
///       cia402=operation_enabled statusword=0x1237 error_code=0x0000 position_counts=123
///       velocity_counts_s=0 following_error_counts=0 stalled=0 stopped_ms=- mode=8
///       target_velocity_counts_s=0 home_switch=0 motor_counts=123
///     subdevice 1 kind=io al=SAFE-OP al_error=1 al_code=0x001B watchdog_trips=1
///       inputs=0xA5 outputs=0x00
///                   (each on one line). stopped_ms: from the last process-data watchdog
///                   expiry to the motor at rest by the drive's quick stop, model time,
///                   "-" until then. mode: 8 position, 9 velocity (a spindle
///                   drive: its motor follows target_velocity_counts_s, 0x60FF, on a
///                   ramp, see --velocity-accel). Nothing else is ever printed to standard output;
///                   messages go to standard error.
///
/// Process-data watchdog (100 ms unless the MainDevice sets another): without output
/// writes in OP, a subdevice drops to SAFE-OP with the error indicator and AL status code
/// 0x001B, and a drive stops itself by its quick stop. AL control 0x0120 = 0x14
/// (acknowledge) then 0x08, or 0x18 at once, returns it to OP; its drive is then in
/// Switch on disabled and its controlword enables it again.
#[derive(Debug, Parser)]
#[command(name = "kerf-ecat-sim", version, verbatim_doc_comment)]
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
    /// The subdevice at POSITION (0 first; repeatable) refuses PRE-OP -> SAFE-OP with AL
    /// status code CODE (hexadecimal, 0x optional; default 0x001D, invalid output
    /// configuration): it stays in PRE-OP with the error indicator, 0x0134 = CODE.
    #[arg(long, value_name = "POSITION[:CODE]", value_parser = parse_refusal)]
    refuse_safe_op: Vec<SafeOpRefusal>,
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
    /// In cyclic synchronous velocity (mode 9, written to 0x6060 by the MainDevice, as
    /// for a spindle drive) a drive's motor velocity ramps toward the target velocity
    /// (0x60FF) at A counts/s², and runs down to rest at A when not enabled.
    #[arg(long, value_name = "A", default_value_t = kerf_ecat_sim::drive::DEFAULT_VELOCITY_ACCEL_COUNTS_S2)]
    velocity_accel: f64,
    /// The drive at POSITION (0 first; repeatable) has a home switch at COUNTS in its
    /// motor's own frame (counts from power-up), active at and beyond it in the search
    /// direction of the homing method the MainDevice writes (0x6098: positive for 19 and
    /// 20, negative for 21 and 22). It homes on it in homing mode (6) and shows it in its
    /// digital inputs (0x60FD bit 2).
    #[arg(long, value_name = "POSITION:COUNTS", value_parser = parse_home_switch, allow_hyphen_values = true)]
    home_switch: Vec<HomeSwitch>,
    /// A switch on the machine wired to an I/O terminal (repeatable): input BIT of the
    /// IO-th I/O subdevice (0 first) is active while the motor of the drive at ring
    /// position DRIVE is at or above (`>=`) or at or below (`<=`) COUNTS, in the motor's
    /// own frame (counts from power-up). A home or limit switch that follows the axis;
    /// set after each exchange, read by the MainDevice in the next. The other input bits
    /// are those `inputs N BITS` sets.
    #[arg(long, value_name = "IO:BIT:DRIVE:>=COUNTS", value_parser = SwitchInput::parse, allow_hyphen_values = true)]
    switch: Vec<SwitchInput>,
}

/// Carries out one control command from standard input; the answer to `state` goes to
/// `out`.
fn control(
    command: &str,
    network: &mut Network,
    handles: &[IoHandle],
    switches: &mut Switches,
    muted: &mut bool,
    out: &mut impl Write,
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
        ["leave-op", position, code] => {
            let code = u16::try_from(parse_u32(code)?).map_err(|e| e.to_string())?;
            if !network.fail_out_of_op(index(position)?, code) {
                return Err(format!("no subdevice at position {position}"));
            }
        }
        [verb @ ("stall" | "free"), position] => {
            if !network.set_stalled(index(position)?, *verb == "stall") {
                return Err(format!("no drive at position {position}"));
            }
        }
        ["inputs", n, bits] => {
            let n = index(n)?;
            if n >= handles.len() {
                return Err(format!("no I/O subdevice number {n}"));
            }
            switches.command(n, u64::from(parse_u32(bits)?));
            switches.apply(network, handles);
        }
        ["state"] => {
            let mut text = String::new();
            report::write_state(&mut text, network).map_err(|e| e.to_string())?;
            out.write_all(text.as_bytes())
                .and_then(|()| out.flush())
                .map_err(|e| format!("writing to standard output: {e}"))?;
        }
        _ => {
            return Err(
                "unknown command (mute, unmute, fault POSITION CODE, leave-op POSITION CODE, \
                 stall POSITION, free POSITION, inputs N BITS, state)"
                    .into(),
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
        .find(|r| usize::from(r.position) >= count)
    {
        anyhow::bail!(
            "--refuse-safe-op {}: the line has only {count} subdevice(s)",
            bad.position
        );
    }
    if let Some(bad) = args.home_switch.iter().find(|h| h.position >= args.drives) {
        anyhow::bail!(
            "--home-switch {}:{}: the line has only {} drive(s), at positions 0 to {}",
            bad.position,
            bad.counts,
            args.drives,
            args.drives.saturating_sub(1)
        );
    }
    if let Some(bad) = args
        .switch
        .iter()
        .find(|s| s.io >= args.io || s.drive >= args.drives)
    {
        anyhow::bail!(
            "--switch {}:{}:{}:{}{}: the line has {} I/O subdevice(s) and {} drive(s)",
            bad.io,
            bad.bit,
            bad.drive,
            if bad.above { ">=" } else { "<=" },
            bad.counts,
            args.io,
            args.drives
        );
    }
    if args.dc_drift_ppm.is_nan() || args.dc_drift_ppm.abs() > kerf_ecat_sim::dc::MAX_DRIFT_PPM {
        anyhow::bail!(
            "--dc-drift-ppm {}: the drift must be a number from -{max} to {max}",
            args.dc_drift_ppm,
            max = kerf_ecat_sim::dc::MAX_DRIFT_PPM
        );
    }
    if !(args.velocity_accel.is_finite() && args.velocity_accel > 0.0) {
        anyhow::bail!(
            "--velocity-accel {}: the ramp must be a number above 0 (counts/s²)",
            args.velocity_accel
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
        velocity_accel_counts_s2: args.velocity_accel,
        home_switches: args.home_switch.clone(),
        ..NetworkSpec::default()
    };
    let (mut network, handles) = build(&spec);
    let mut switches = Switches::new(args.switch.clone(), handles.len());
    switches.apply(&network, &handles);
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
        // The watchdogs and the models step only when no frame waits: a frame that
        // reached the interface in time counts as in time, even when this process was
        // not scheduled for longer than the watchdog (a busy machine, not a late
        // MainDevice). A MainDevice that stops sending leaves nothing waiting, and the
        // watchdog expires as on a real subdevice.
        if !socket.pending().context("polling")? {
            network.tick(start.elapsed().as_nanos() as u64);
        }
        while let Ok(command) = control_rx.try_recv() {
            let mut stdout = std::io::stdout().lock();
            match control(
                &command,
                &mut network,
                &handles,
                &mut switches,
                &mut muted,
                &mut stdout,
            ) {
                Ok(()) => eprintln!("kerf-ecat-sim: done: {command}"),
                Err(e) => eprintln!("kerf-ecat-sim: {command:?} refused: {e}"),
            }
        }
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
            Ok(()) => {
                socket.send(frame).context("sending")?;
                switches.apply(&network, &handles);
            }
            Err(e) => eprintln!("kerf-ecat-sim: frame ignored: {e}"),
        }
    }
    eprintln!("kerf-ecat-sim: stopped");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_refusal_is_a_position_and_an_optional_hex_code() {
        let refusal = |position, al_status_code| SafeOpRefusal {
            position,
            al_status_code,
        };
        assert_eq!(parse_refusal("2"), Ok(refusal(2, 0x001D)));
        assert_eq!(parse_refusal("1:0x0035"), Ok(refusal(1, 0x0035)));
        assert_eq!(parse_refusal("1:001E"), Ok(refusal(1, 0x001E)));
        assert_eq!(parse_refusal("0:1b"), Ok(refusal(0, 0x001B)));
        assert!(parse_refusal("x").is_err());
        assert!(parse_refusal("1:").is_err());
        assert!(parse_refusal("1:0x10000").is_err());
        assert!(parse_refusal("1:zz").is_err());
    }
}
