//! `kerf ethercat`: commissioning the EtherCAT bus without the daemon (the scan, SDO reads
//! and writes), on the interface given or the configuration's `[ethercat] interface`.
//! Each command claims the interface first ([`kerf_ethercat::claim`]) and is refused,
//! naming the holder, while the daemon or another command holds it.

use std::io::Write;
use std::path::PathBuf;

use clap::{Args, Subcommand};
use kerf_ethercat::claim::{Claim, Holder};
use kerf_ethercat::commission::{
    SdoType, exchange_round_trips, scan_detail, sdo_read, sdo_write, value_text,
};

use crate::{Failure, load_config};

#[derive(Args)]
pub struct EthercatArgs {
    #[command(subcommand)]
    command: EthercatCommand,
}

#[derive(Subcommand)]
enum EthercatCommand {
    /// List every subdevice on the bus: position, name, vendor, product, revision, serial,
    /// state, distributed-clock support, mailbox protocols and (over CoE) the PDO
    /// assignment and mapping. Leaves the bus in PRE-OP.
    Scan(BusArgs),
    /// Read or write one object of one subdevice over CoE (SDO).
    Sdo(SdoArgs),
    /// Bring the configuration's bus to OP with every drive disabled (nothing moves) and
    /// time N cyclic exchanges at the configuration's period: the round trip's p50, p99,
    /// p99.9 and maximum, and the frames lost. For choosing and preparing a NIC.
    Exchange(ExchangeArgs),
}

#[derive(Args)]
struct ExchangeArgs {
    /// Machine configuration (TOML) with the `[ethercat]` table. Without it:
    /// /etc/kerf/kerf.toml if present, else the built-in example machine.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Exchanges to time.
    #[arg(long, default_value_t = 10_000)]
    cycles: u32,
}

#[derive(Args)]
struct BusArgs {
    /// The network interface of the bus. Without it: `[ethercat] interface` of the
    /// configuration.
    #[arg(long, value_name = "IF")]
    interface: Option<String>,
    /// Machine configuration (TOML) whose `[ethercat] interface` is used. Without it:
    /// /etc/kerf/kerf.toml if present, else the built-in example machine.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
}

#[derive(Args)]
struct SdoArgs {
    #[command(subcommand)]
    op: SdoOp,
}

#[derive(Subcommand)]
enum SdoOp {
    /// Read an object and print its value.
    Read(SdoTarget),
    /// Write a value to an object.
    Write {
        #[command(flatten)]
        target: SdoTarget,
        /// The value: decimal, or hex with 0x; range-checked against the type.
        #[arg(allow_hyphen_values = true)]
        value: String,
    },
}

#[derive(Args)]
struct SdoTarget {
    #[command(flatten)]
    bus: BusArgs,
    /// Ring position of the subdevice, 0 for the first after the MainDevice.
    #[arg(long)]
    position: u16,
    /// The object, INDEX:SUBINDEX in hex (e.g. 6060:00 or 0x607a:0).
    #[arg(value_name = "INDEX:SUBINDEX")]
    object: String,
    /// The CoE type: u8, u16, u32, i8, i16 or i32.
    #[arg(long = "type", value_name = "TYPE")]
    kind: String,
}

fn interface(bus: &BusArgs) -> Result<String, Failure> {
    if let Some(i) = &bus.interface {
        return Ok(i.clone());
    }
    let config = load_config(bus.config.as_deref())?;
    config.ethercat().map(|e| e.interface.clone()).ok_or_else(|| {
        Failure::Error(
            "error: no EtherCAT interface: give --interface IF, or a configuration with an `[ethercat]` table".to_owned(),
        )
    })
}

/// `6060:00`, `0x607A:0` → (0x6060, 0).
fn object(text: &str) -> Result<(u16, u8), Failure> {
    let bad = || {
        Failure::Error(format!(
            "error: {text:?} is not an object INDEX:SUBINDEX in hex, e.g. 6060:00"
        ))
    };
    let (index, subindex) = text.split_once(':').ok_or_else(bad)?;
    let hex = |s: &str| {
        s.trim_start_matches("0x")
            .trim_start_matches("0X")
            .to_owned()
    };
    let index = u16::from_str_radix(&hex(index), 16).map_err(|_| bad())?;
    let subindex = u8::from_str_radix(&hex(subindex), 16).map_err(|_| bad())?;
    Ok((index, subindex))
}

fn kind(name: &str) -> Result<SdoType, Failure> {
    SdoType::from_name(name).ok_or_else(|| {
        Failure::Error(format!(
            "error: type {name:?} is not one of u8, u16, u32, i8, i16, i32"
        ))
    })
}

/// The interface for this command, or why not: the daemon or another command holds it.
/// Held until the command ends: no frame of it goes out before.
fn claim(interface: &str) -> Result<Claim, Failure> {
    Claim::take(interface, Holder::Commissioning)
        .map_err(|e| Failure::Exit(1, format!("error: {e}")))
}

fn bus_failure(interface: &str, e: impl std::fmt::Display) -> Failure {
    let mut message = format!("error: EtherCAT on {interface}: {e}");
    if message.contains("Operation not permitted") {
        message.push_str(" (a raw socket needs root or CAP_NET_RAW)");
    }
    Failure::Exit(1, message)
}

/// Runs `kerf ethercat ...`.
pub fn run(args: &EthercatArgs) -> Result<(), Failure> {
    match &args.command {
        EthercatCommand::Scan(bus) => {
            let interface = interface(bus)?;
            let claim = claim(&interface)?;
            let entries = scan_detail(&claim).map_err(|e| bus_failure(&interface, e))?;
            let mut out = std::io::stdout().lock();
            writeln!(out, "{} subdevice(s) on {interface}", entries.len())?;
            for e in &entries {
                writeln!(out, "{}", e.text())?;
            }
            Ok(())
        }
        EthercatCommand::Exchange(args) => {
            let config = load_config(args.config.as_deref())?;
            let Some(bus) = config.ethercat() else {
                return Err(Failure::Error(
                    "error: the configuration has no `[ethercat]` table".to_owned(),
                ));
            };
            let period_ns = u64::from(config.period_us) * 1000;
            let claim = claim(&bus.interface)?;
            let r = exchange_round_trips(&claim, bus, period_ns, args.cycles)
                .map_err(|e| bus_failure(&bus.interface, e))?;
            let us = |ns: u64| ns as f64 / 1000.0;
            writeln!(
                std::io::stdout().lock(),
                "{} exchanges at {} µs on {}: round trip p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs; {} lost, {} short working counters, {} with a subdevice out of OP",
                args.cycles,
                config.period_us,
                bus.interface,
                us(r.quantile_ns(0.5)),
                us(r.quantile_ns(0.99)),
                us(r.quantile_ns(0.999)),
                us(r.quantile_ns(1.0)),
                r.lost,
                r.short,
                r.not_op
            )?;
            Ok(())
        }
        EthercatCommand::Sdo(SdoArgs { op: SdoOp::Read(t) }) => {
            let interface = interface(&t.bus)?;
            let (index, subindex) = object(&t.object)?;
            let kind = kind(&t.kind)?;
            let claim = claim(&interface)?;
            let value = sdo_read(&claim, t.position, index, subindex, kind)
                .map_err(|e| bus_failure(&interface, e))?;
            writeln!(std::io::stdout().lock(), "{}", value_text(value))?;
            Ok(())
        }
        EthercatCommand::Sdo(SdoArgs {
            op: SdoOp::Write { target: t, value },
        }) => {
            let interface = interface(&t.bus)?;
            let (index, subindex) = object(&t.object)?;
            let value = kind(&t.kind)?
                .parse(value)
                .map_err(|e| Failure::Error(format!("error: {e}")))?;
            let claim = claim(&interface)?;
            sdo_write(&claim, t.position, index, subindex, value)
                .map_err(|e| bus_failure(&interface, e))?;
            Ok(())
        }
    }
}
